#![allow(clippy::unwrap_used)]
//! `cargo xtask export` as a process, end to end against `cargo xtask reproduce`: the
//! certified preset reproduced on the portable kernel (`QP_ITER_KERNEL=portable`), the C
//! artefact exported for the K its trace.csv ran (with the MPC at the joint certificate's
//! floor), built with the host's cc, and the replay fed with trace.csv's u and y columns:
//! its output equals trace.csv's xhat columns bit for bit. The loop program runs; a K_c
//! below the joint floor is refused.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn xtask() -> Command {
    Command::new(crate::shared::xtask_bin())
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn scratch(name: &str) -> PathBuf {
    let dir = root().join("target").join("export-cli-tests").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn pipe(program: &Path, input: &str) -> String {
    let mut child = Command::new(program)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{} failed", program.display());
    String::from_utf8(out.stdout).unwrap()
}

/// The header and the rows of trace.csv's run with `k` (None: its first run).
fn run_rows(trace: &str, k: Option<&str>) -> (Vec<String>, Vec<Vec<String>>) {
    let mut lines = trace.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    let k = k.map_or_else(|| rows[0][0].clone(), String::from);
    let rows: Vec<Vec<String>> = rows.into_iter().filter(|r| r[0] == k).collect();
    assert!(!rows.is_empty(), "trace.csv has no run with k = {k}");
    (header, rows)
}

fn first_run(trace: &str) -> (Vec<String>, Vec<Vec<String>>) {
    run_rows(trace, None)
}

fn join(r: &[String], cols: &[usize]) -> String {
    cols.iter()
        .map(|&i| r[i].as_str())
        .collect::<Vec<_>>()
        .join(",")
}

fn columns(header: &[String], prefix: &str) -> Vec<usize> {
    (0..header.len())
        .filter(|&i| {
            header[i]
                .strip_prefix(prefix)
                .is_some_and(|rest| !rest.is_empty() && rest.chars().all(|c| c.is_ascii_digit()))
        })
        .collect()
}

fn bits(line: &str) -> Vec<u64> {
    line.split(',')
        .map(|v| v.trim().parse::<f64>().unwrap().to_bits())
        .collect()
}

#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_replay_of_the_exported_c_reproduces_trace_csv_bit_for_bit() {
    let dir = scratch("certified");
    let scenario = root().join("scenarios/case-study-certified.toml");
    // `xtask reproduce` on the portable kernel, shared with the golden test: its certified
    // preset is this scenario file (`Preset::scenario_file`), and the preset changes only the
    // Fig. 2(c) time, not the runs of trace.csv.
    let out = crate::shared::reproduce();
    let trace = std::fs::read_to_string(out.join("certified").join("trace.csv")).unwrap();
    let (header, rows) = first_run(&trace);
    let k = rows[0][0].clone();
    let art = dir.join("art");
    let printed = run_ok(
        xtask()
            .args(["export", "--scenario"])
            .arg(&scenario)
            .arg("--out")
            .arg(&art)
            .args([
                "--lang",
                "c",
                "--method",
                "pg",
                "--k",
                &k,
                "--kc",
                "certified",
            ]),
    );
    assert!(printed.contains("certified"), "{printed}");
    let cert: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(art.join("certificate.json")).unwrap())
            .unwrap();
    assert_eq!(cert["iterations"].to_string(), k);
    assert_eq!(cert["mpc"]["certified"], true);
    assert_eq!(cert["mpc"]["iterations"], cert["mpc"]["k_c_min"]);
    assert_eq!(cert["loop_certified"], true);
    assert_eq!(cert["mpc"]["joint"]["mpc_method"], cert["mpc"]["method"]);
    run_ok(
        Command::new("make")
            .current_dir(&art)
            .args(["-s", "replay", "loop"]),
    );
    // The replay: (u_t, y_t) of each row in, x̂ out; line t = row t's xhat.
    let (cu, cy, cx) = (
        columns(&header, "u"),
        columns(&header, "y"),
        columns(&header, "xhat"),
    );
    let input: String = rows
        .iter()
        .map(|r| {
            cu.iter()
                .chain(&cy)
                .map(|&i| r[i].as_str())
                .collect::<Vec<_>>()
                .join(",")
                + "\n"
        })
        .collect();
    let got = pipe(&art.join("replay"), &input);
    let got: Vec<&str> = got.lines().collect();
    assert_eq!(got.len(), rows.len() + 1);
    for (t, r) in rows.iter().enumerate() {
        let xhat = cx
            .iter()
            .map(|&i| r[i].as_str())
            .collect::<Vec<_>>()
            .join(",");
        assert_eq!(
            bits(got[t]),
            bits(&xhat),
            "row {t}: the replay differs from trace.csv"
        );
    }
    // The loop program: y in, x̂ and u out (the trace ran the exact MPC, so only the shape
    // is checked here; tests in src/export compare the loop with the std loop bit for bit).
    let input: String = rows
        .iter()
        .map(|r| {
            cy.iter()
                .map(|&i| r[i].as_str())
                .collect::<Vec<_>>()
                .join(",")
                + "\n"
        })
        .collect();
    let got = pipe(&art.join("loop"), &input);
    let got: Vec<&str> = got.lines().collect();
    assert_eq!(got.len(), rows.len() + 1);
    for l in got {
        let v = bits(l);
        assert_eq!(v.len(), cx.len() + cu.len());
        assert!(v.iter().all(|b| f64::from_bits(*b).is_finite()));
    }
}

#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_a_k_c_below_the_joint_floor_is_refused() {
    let dir = scratch("refused");
    let out = xtask()
        .args(["export", "--scenario"])
        .arg(root().join("scenarios/case-study-certified.toml"))
        .arg("--out")
        .arg(dir.join("art"))
        .args(["--method", "pg", "--kc", "1"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("below the joint certificate's floor")
            && stderr.contains("--allow-uncertified"),
        "{stderr}"
    );
    assert!(!dir.join("art").join("mhe_data.c").exists());
}

/// The loop program against `reproduce`'s trace.csv of a scenario whose controller is the
/// K_c-iteration MPC (the certified preset with `mpc.iterations = 99`, the joint floor of its
/// FISTA MPC at K = 243): fed the y columns of the scenario's own run (K = 243, K_c = 99) it
/// prints that run's xhat and u columns bit for bit.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_loop_of_the_exported_c_reproduces_trace_csv_of_a_k_c_iteration_mpc_run() {
    let dir = scratch("loop");
    let text = std::fs::read_to_string(root().join("scenarios/case-study-certified.toml")).unwrap();
    assert!(text.contains("terminal = \"dare\""));
    let text = text.replacen(
        "terminal = \"dare\"",
        "terminal = \"dare\"\niterations = 99\nmethod = \"fista\"",
        1,
    );
    let scenario = dir.join("case-study-certified-kc.toml");
    std::fs::write(&scenario, text).unwrap();
    let out = dir.join("reproduce");
    run_ok(
        xtask()
            .env("QP_ITER_KERNEL", "portable")
            .args(["reproduce", "--scenario"])
            .arg(&scenario)
            .arg("--out")
            .arg(&out),
    );
    let trace =
        std::fs::read_to_string(out.join("case-study-certified-kc").join("trace.csv")).unwrap();
    let (header, rows) = run_rows(&trace, Some("243"));
    let art = dir.join("art");
    run_ok(
        xtask()
            .args(["export", "--scenario"])
            .arg(&scenario)
            .arg("--out")
            .arg(&art)
            .args(["--lang", "c", "--method", "pg", "--k", "243"]),
    );
    let cert: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(art.join("certificate.json")).unwrap())
            .unwrap();
    // K_c is the scenario's (mpc.iterations), certified at (243, 99).
    assert_eq!(cert["mpc"]["iterations"], 99);
    assert_eq!(cert["mpc"]["method"], "fista");
    assert_eq!(cert["loop_certified"], true);
    run_ok(Command::new("make").current_dir(&art).args(["-s", "loop"]));
    let (cu, cy, cx) = (
        columns(&header, "u"),
        columns(&header, "y"),
        columns(&header, "xhat"),
    );
    let input: String = rows.iter().map(|r| join(r, &cy) + "\n").collect();
    let got = pipe(&art.join("loop"), &input);
    let got: Vec<&str> = got.lines().collect();
    assert_eq!(got.len(), rows.len() + 1);
    for (t, r) in rows.iter().enumerate() {
        let expected = join(r, &cx) + "," + &join(r, &cu);
        assert_eq!(
            bits(got[t]),
            bits(&expected),
            "row {t}: the loop differs from trace.csv's xhat and u"
        );
    }
}

/// Issue 37, item 11: every bad argument fails before the certificate (which takes seconds
/// on the certified preset), with an error naming the flag; an existing file, or a
/// directory that holds something other than an export, is refused as `--out` (export
/// replaces its `--out` as a whole and never deletes what it did not write).
#[test]
fn bad_arguments_fail_before_the_certificate_naming_the_flag() {
    let dir = scratch("bad-arguments");
    let file = dir.join("a-file");
    std::fs::write(&file, "keep me").unwrap();
    let foreign = dir.join("foreign");
    std::fs::create_dir_all(&foreign).unwrap();
    std::fs::write(foreign.join("notes.txt"), "keep me").unwrap();
    let out = dir.join("art");
    let (o, f, g) = (
        out.to_str().unwrap(),
        file.to_str().unwrap(),
        foreign.to_str().unwrap(),
    );
    let cases: [(&[&str], &str); 7] = [
        (&["--out", o, "--k", "0"], "--k 0"),
        (&["--out", o, "--kc", "0"], "--kc 0"),
        (&["--out", o, "--method", "nope"], "--method nope"),
        (&["--out", o, "--mpc-method", "nope"], "--mpc-method nope"),
        // The certified preset has no mpc.iterations: without --kc no MPC is exported.
        (&["--out", o, "--mpc-method", "pg"], "--mpc-method pg"),
        (&["--out", f], "--out"),
        (&["--out", g], "--out"),
    ];
    for (args, flag) in cases {
        let t0 = std::time::Instant::now();
        let res = xtask()
            .args(["export", "--scenario"])
            .arg(root().join("scenarios/case-study-certified.toml"))
            .args(args)
            .output()
            .unwrap();
        let (stdout, stderr) = (
            String::from_utf8_lossy(&res.stdout),
            String::from_utf8_lossy(&res.stderr),
        );
        assert_eq!(res.status.code(), Some(1), "{args:?}: {stdout}{stderr}");
        assert!(stderr.contains(flag), "{args:?}: {stderr}");
        assert!(
            !stdout.contains("computing the certificate"),
            "{args:?}: checked after the certificate\n{stdout}"
        );
        eprintln!("{args:?}: {:.2} s", t0.elapsed().as_secs_f64());
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep me");
    assert_eq!(
        std::fs::read_to_string(foreign.join("notes.txt")).unwrap(),
        "keep me"
    );
    assert!(!out.exists());
}

/// Issue 37, item 11: an `--out` reused across exports holds the new export only (no source
/// of the old K beside the new certificate, no stray file); a refused export leaves the
/// earlier one as it was. The double integrator (seconds).
#[test]
fn a_reused_out_is_replaced_as_a_set() {
    let dir = scratch("replace");
    let scenario = root().join("scenarios/double-integrator.toml");
    let art = dir.join("art");
    let export = |extra: &[&str]| {
        xtask()
            .args(["export", "--scenario"])
            .arg(&scenario)
            .arg("--out")
            .arg(&art)
            .args(extra)
            .output()
            .unwrap()
    };
    let res = export(&["--lang", "c", "--k", "300"]);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    assert!(art.join("mhe.c").exists());
    std::fs::write(art.join("stale.txt"), "from the first export").unwrap();
    let res = export(&["--lang", "rust", "--k", "certified"]);
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let cert: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(art.join("certificate.json")).unwrap())
            .unwrap();
    let k_min = cert["k_min"].as_u64().unwrap();
    assert_eq!(cert["iterations"], k_min);
    assert!(k_min < 300);
    assert!(art.join("Cargo.toml").exists());
    for gone in ["mhe.c", "mhe_data.h", "Makefile", "stale.txt"] {
        assert!(
            !art.join(gone).exists(),
            "{gone} of the first export remains"
        );
    }
    // No temporary sibling is left behind.
    let siblings: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(siblings, vec!["art".to_string()]);
    // A refused export (K below K_min) leaves the earlier one untouched.
    let before = std::fs::read_to_string(art.join("certificate.json")).unwrap();
    let res = export(&["--lang", "c", "--k", "1"]);
    assert_eq!(res.status.code(), Some(1));
    assert_eq!(
        std::fs::read_to_string(art.join("certificate.json")).unwrap(),
        before
    );
    assert!(!art.join("mhe.c").exists());
}

/// `--survey` writes nothing and prints per method the K `--k certified` would export, or
/// why none: here thermal-rod-m30, whose every export the size limit refuses before the
/// certificate (so the test takes no certificate time; mhe-export's tests_survey checks the
/// survey's K against the export's). `--survey` takes no `--out`; the export of the same
/// scenario is refused naming `mhe.horizon`, before its certificate.
#[test]
fn survey_writes_nothing_and_the_size_limit_refuses_by_name() {
    let dir = scratch("survey");
    let scenario = root().join("scenarios/thermal-rod-m30.toml");
    let out = run_ok(
        xtask()
            .current_dir(&dir)
            .args(["export", "--survey", "--scenario"])
            .arg(&scenario),
    );
    let doc: serde_json::Value = serde_json::from_str(&out).unwrap();
    let methods = doc["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 8);
    for m in methods {
        for scalar in ["f64", "f32"] {
            assert_eq!(m[scalar]["verdict"], "refused", "{m}");
            assert!(m[scalar]["k"].is_null());
            let reason = m[scalar]["reason"].as_str().unwrap();
            assert!(reason.starts_with("`mhe.horizon` = 30:"), "{reason}");
        }
    }
    assert_eq!(doc["sample_time"], 2.0);
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "wrote files");
    let both = xtask()
        .args(["export", "--survey", "--out"])
        .arg(dir.join("x"))
        .arg("--scenario")
        .arg(&scenario)
        .output()
        .unwrap();
    assert!(!both.status.success());
    assert!(String::from_utf8_lossy(&both.stderr).contains("--out"));
    let big = xtask()
        .args(["export", "--k", "certified", "--scenario"])
        .arg(&scenario)
        .arg("--out")
        .arg(dir.join("big"))
        .output()
        .unwrap();
    assert!(!big.status.success());
    let err = String::from_utf8_lossy(&big.stderr);
    assert!(
        err.contains("`mhe.horizon` = 30") && err.contains("n_z = 710"),
        "{err}"
    );
    // Refused before the certificate (whose progress line goes to stdout).
    assert!(!String::from_utf8_lossy(&big.stdout).contains("computing"));
    assert!(!dir.join("big").exists());
}
