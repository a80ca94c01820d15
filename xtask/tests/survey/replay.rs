//! Replay lines: the exported C replay program (the double integrator, ADMM-PR at its
//! certified K, built with the host's cc) fed `j` valid lines and then one generated line.
//! The oracle, from the program's documented contract (strict parsing: exactly n_u + n_y
//! finite numbers, comma-separated, blanks around them, nothing else, at most 8 191 bytes):
//! a line the generator built malformed exits 1 with a message naming its line number and
//! prints no estimate for it; a line built well formed is accepted (exit 0, one more
//! estimate). Blank lines are skipped (no estimate, not an error).

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use proptest::prelude::*;

use crate::{Tally, draw, runner, scratch};

const XTASK: &str = env!("CARGO_BIN_EXE_xtask");
/// n_u + n_y of the double integrator.
const COUNT: usize = 2;

/// How the generated line is built.
#[derive(Debug, Clone)]
enum Line {
    /// Well formed: accepted.
    Good(String),
    /// Blank: skipped.
    Blank(String),
    /// Malformed: refused naming the line.
    Bad(String),
}

fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        (-1e6f64..1e6).prop_map(|v| format!("{v}")),
        (-1e3f64..1e3).prop_map(|v| format!("{v:e}")),
        (0i64..1000).prop_map(|v| format!("{v}")),
        (0i64..1000).prop_map(|v| format!("+{v}.")),
        (0i64..1000).prop_map(|v| format!("-.{v}")),
    ]
}

fn blanks() -> impl Strategy<Value = String> {
    proptest::sample::select(vec!["", " ", "\t", "  ", " \t "]).prop_map(str::to_string)
}

fn good() -> impl Strategy<Value = Line> {
    (
        proptest::collection::vec((blanks(), number(), blanks()), COUNT),
        blanks(),
    )
        .prop_map(|(cells, tail)| {
            let body: Vec<String> = cells.iter().map(|(a, n, b)| format!("{a}{n}{b}")).collect();
            Line::Good(format!("{}{tail}", body.join(",")))
        })
}

fn not_a_number() -> impl Strategy<Value = String> {
    proptest::sample::select(vec![
        "nan", "NaN", "inf", "-inf", "Infinity", "1e999", "-1e400", "x", "1,", "--1", "1e", "e5",
        "0x", "1..2", "\"1\"", "1 2", "", "1;2",
    ])
    .prop_map(str::to_string)
}

fn bad() -> impl Strategy<Value = Line> {
    prop_oneof![
        // Wrong count.
        proptest::collection::vec(number(), 0..6)
            .prop_filter("not the right count", |v| v.len() != COUNT && !v.is_empty())
            .prop_map(|v| Line::Bad(v.join(","))),
        // One cell not a finite number.
        (number(), not_a_number(), any::<bool>()).prop_map(|(n, x, first)| Line::Bad(if first {
            format!("{x},{n}")
        } else {
            format!("{n},{x}")
        })),
        // Separators and trailing text.
        (
            number(),
            number(),
            proptest::sample::select(vec![";", " ", ",,", "|"])
        )
            .prop_map(|(a, b, s)| Line::Bad(format!("{a}{s}{b}"))),
        (
            number(),
            number(),
            proptest::sample::select(vec![",", ", x", " #c", ",0"])
        )
            .prop_map(|(a, b, t)| Line::Bad(format!("{a},{b}{t}"))),
        // Longer than 8 191 bytes.
        (8192usize..9000).prop_map(|n| Line::Bad(format!("1,{}", " ".repeat(n)))),
    ]
}

fn line() -> impl Strategy<Value = Line> {
    prop_oneof![
        4 => bad(),
        2 => good(),
        1 => blanks().prop_map(Line::Blank),
    ]
}

/// Exports and builds the replay once; `None` (and a note) when `make`/`cc` are missing.
fn build(dir: &Path) -> Option<PathBuf> {
    let scenario = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/double-integrator.toml"
    );
    let art = dir.join("art");
    let out = Command::new(XTASK)
        .args([
            "export",
            "--scenario",
            scenario,
            "--method",
            "admm-pr",
            "--out",
        ])
        .arg(&art)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "export: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let made = Command::new("make")
        .current_dir(&art)
        .args(["-s", "replay"])
        .output()
        .ok()?;
    made.status.success().then(|| art.join("replay"))
}

pub fn survey(seed: u64, n: usize) -> Tally {
    let mut tally = Tally::default();
    if n == 0 {
        return tally;
    }
    let dir = scratch("replay");
    let Some(replay) = build(&dir) else {
        tally.finding("the exported replay could not be built with make and cc".into());
        return tally;
    };
    let mut rn = runner(seed, 6);
    let valid = "0.5,0.25\n";
    for _ in 0..n {
        let (j, case) = draw(&mut rn, &(0usize..4, line()));
        let mut input = valid.repeat(j);
        let text = match &case {
            Line::Good(s) | Line::Blank(s) | Line::Bad(s) => s.clone(),
        };
        input.push_str(&text);
        input.push('\n');
        let lineno = j + 1;
        let mut child = Command::new(&replay)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // A refusal may close the pipe before the whole input is written.
        let _ = child.stdin.take().unwrap().write_all(input.as_bytes());
        let out = child.wait_with_output().unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        let estimates = stdout.lines().count();
        tally.cases += 1;
        let why = match &case {
            Line::Bad(_) => {
                let named = stderr.contains(&format!("line {lineno}:"));
                if out.status.code() == Some(1) && named && estimates == 1 + j {
                    tally.refused += 1;
                    None
                } else {
                    Some(format!(
                        "malformed line {lineno} not refused as documented (exit {:?}, {estimates} \
                         estimates, stderr {stderr:?})",
                        out.status.code()
                    ))
                }
            }
            Line::Good(_) | Line::Blank(_) => {
                let want = 1 + j + usize::from(matches!(case, Line::Good(_)));
                if out.status.success() && estimates == want {
                    tally.accepted += 1;
                    None
                } else {
                    Some(format!(
                        "well-formed line {lineno} not accepted (exit {:?}, {estimates} estimates \
                         for {want}, stderr {stderr:?})",
                        out.status.code()
                    ))
                }
            }
        };
        if let Some(why) = why {
            tally.finding(format!("{why}\n--- line: {:.200}", format!("{text:?}")));
        }
    }
    tally
}
