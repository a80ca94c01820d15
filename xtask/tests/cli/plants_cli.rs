#![allow(clippy::unwrap_used)]
//! Issue 25, item 3 ("one failure, one reason") as a process: when LMI (2) has no P,
//! `reproduce` says only what it did and wrote, and the premises that need P are "not
//! evaluated (because …)" instead of failing with advice of their own.

use std::process::Command;

const UNDETECTABLE: &str = r#"
name = "undetectable"
[plant]
a = [[1.1, 0.0], [0.0, 0.5]]
b = [[1.0], [1.0]]
c = [[0.0, 1.0]]
[sets]
disturbance = { lower = -0.1, upper = 0.1 }
[simulation]
x0 = [1.0, 1.0]
steps = 20
[mhe]
horizon = 10
eta = 0.8
iterations = 10
[mpc]
horizon = 5
"#;

#[test]
fn nothing_simulated_is_reported_as_such() {
    let dir = crate::test_dir::test_dir("plants", "undetectable");
    let scenario = dir.join("undetectable.toml");
    std::fs::write(&scenario, UNDETECTABLE).unwrap();
    let out = Command::new(crate::shared::xtask_bin())
        // -v: the work lines (what was written) are printed only then.
        .args(["reproduce", "-v", "--scenario"])
        .arg(&scenario)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(!text.contains("seed 0, T = 0"), "{text}");
    assert!(!text.contains("writing trace.json"), "{text}");
    assert!(
        text.contains("nothing was simulated; writing certificate.json"),
        "{text}"
    );
    assert!(text.contains("not evaluated"), "{text}");
    for wrong in [
        "use PG or FISTA",
        "reduce the step size",
        "is not a finite non-negative number",
        "max_iterations",
        "ioss::",
    ] {
        assert!(!text.contains(wrong), "`{wrong}` in:\n{text}");
    }
}
