//! Issue 23 (hardening II) on the binary: closed and full output streams, outputs replaced
//! as a set (a write that fails after N bytes, injected with `SUBOPTIMAL_MHE_FAULT_WRITE_BYTES`,
//! leaves the previous complete output), special input paths, `--out` checked before any
//! work, point files checked for meaning, and an unreadable shard meta.
#![allow(clippy::unwrap_used)]

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
const FAULT_ENV: &str = "SUBOPTIMAL_MHE_FAULT_WRITE_BYTES";

fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("xtask-harden")
        .join(name);
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

fn case_study() -> String {
    format!("{ROOT}/scenarios/case-study.toml")
}

/// A tiny sweep: 2 K × 1 solver × 2 seeds, T = 8, no certificate (a second or two).
fn tiny_config(dir: &Path) -> PathBuf {
    let path = dir.join("tiny.toml");
    fs::write(
        &path,
        format!(
            "scenario = \"{ROOT}/scenarios/case-study-certified.toml\"\nname = \"tiny\"\n\
             k = [1, 5]\nsolvers = [\"pg\"]\nseeds = 2\nsteps = 8\nbase_seed = 3\n\
             certificate = false\n"
        ),
    )
    .unwrap();
    path
}

fn run(args: &[&str], env: Option<(&str, &str)>) -> Output {
    let mut c = Command::new(crate::shared::xtask_bin());
    c.args(args);
    if let Some((k, v)) = env {
        c.env(k, v);
    }
    c.output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Every regular file of `dir` (not recursive) with its bytes, sorted by name.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = fs::read_dir(dir)
        .unwrap()
        .flatten()
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

fn names(snap: &[(String, Vec<u8>)]) -> Vec<&str> {
    snap.iter().map(|(n, _)| n.as_str()).collect()
}

#[test]
fn a_full_or_closed_stdout_is_exit_4_with_the_files_written() {
    let dir = scratch("streams");
    let json = dir.join("cert.json");
    let full = fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .unwrap();
    let o = Command::new(crate::shared::xtask_bin())
        .args(["certify", "--scenario", &case_study(), "--json"])
        .arg(&json)
        .stdout(Stdio::from(full))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(5), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("stdout could not be written"),
        "{}",
        stderr(&o)
    );
    let v: serde_json::Value = serde_json::from_str(&fs::read_to_string(&json).unwrap()).unwrap();
    assert!(v.get("passed").is_some());
    // A pipe whose reader is gone: the sweep still writes meta.json and its plots.
    let out = dir.join("sweep");
    let mut child = Command::new(crate::shared::xtask_bin())
        .args(["sweep", "--config"])
        .arg(tiny_config(&dir))
        .arg("--out")
        .arg(&out)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(5));
    let files = snapshot(&out);
    let files = names(&files);
    for f in ["meta.json", "runs.csv", "points.csv", "bounded.svg"] {
        assert!(files.contains(&f), "{f} missing: {files:?}");
    }
}

#[test]
fn special_input_paths_are_refused_without_blocking() {
    let dir = scratch("paths");
    let fifo = dir.join("fifo.toml");
    let made = Command::new("mkfifo").arg(&fifo).status();
    let mut paths: Vec<(PathBuf, &str)> = vec![
        (PathBuf::from("/dev/zero"), "character device"),
        (PathBuf::from("/dev/null"), "character device"),
        (dir.clone(), "a directory"),
    ];
    if made.is_ok_and(|s| s.success()) {
        paths.push((fifo, "FIFO"));
    }
    for (p, what) in &paths {
        for args in [
            vec!["certify", "--scenario"],
            vec!["sweep", "--config"],
            vec!["certify", "--scenario", &case_study(), "--p-file"],
        ] {
            let started = Instant::now();
            let o = Command::new(crate::shared::xtask_bin())
                .args(&args)
                .arg(p)
                .stdin(Stdio::null())
                .output()
                .unwrap();
            assert!(
                started.elapsed() < Duration::from_secs(20),
                "{args:?} {p:?} blocked"
            );
            assert_eq!(o.status.code(), Some(1), "{args:?} {p:?}: {}", stderr(&o));
            let e = stderr(&o);
            assert!(
                e.contains(what) && e.contains("not a regular file"),
                "{args:?}: {e}"
            );
        }
    }
}

#[test]
fn out_is_checked_before_any_work() {
    let dir = scratch("out");
    let file = dir.join("a-file");
    fs::write(&file, "x").unwrap();
    let f = file.display().to_string();
    for args in [
        vec!["reproduce", "--preset", "certified", "--out", &f],
        vec![
            "certify",
            "--scenario",
            &case_study(),
            "--json",
            dir.to_str().unwrap(),
        ],
    ] {
        let started = Instant::now();
        let o = run(&args, None);
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        // Refused in well under the certificate's time.
        assert!(started.elapsed() < Duration::from_secs(5), "{args:?}");
        let e = stderr(&o);
        assert!(e.contains("--out") || e.contains("--json"), "{e}");
    }
    let cfg = tiny_config(&dir);
    let o = run(
        &["sweep", "--config", cfg.to_str().unwrap(), "--out", &f],
        None,
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("not a directory"), "{}", stderr(&o));
}

/// A rerun whose writes fail after N bytes (a full disk) leaves the previous complete
/// output, for several N; with room it replaces the set.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_a_failed_rerun_leaves_the_previous_complete_output() {
    let dir = scratch("atomic");
    // reproduce, five times: of the paper preset with `[certificate] phase_seconds = 0.5`
    // (3.8 s a run instead of 23: the global loop certificate and the γ₁,₃ enumeration say
    // "not computed" at once), its files the same set the preset writes, in `rep/paper/`.
    let text = fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/case-study.toml"),
    )
    .unwrap();
    let paper = dir.join("paper.toml");
    fs::write(
        &paper,
        format!("{text}\n[certificate]\nphase_seconds = 0.5\n"),
    )
    .unwrap();
    let paper = paper.to_str().unwrap();
    let out = dir.join("rep");
    let o = run(
        &[
            "reproduce",
            "--scenario",
            paper,
            "--out",
            out.to_str().unwrap(),
        ],
        None,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let before = snapshot(&out.join("paper"));
    let total: usize = before.iter().map(|(_, b)| b.len()).sum();
    // Not `total - 1`: the rerun's timings in certificate.json (and so its size) differ from
    // the first run's by a few bytes; 200 bytes short of the total is the last file's write.
    for n in [0, 1000, total / 2, total - 200] {
        let o = run(
            &[
                "reproduce",
                "--scenario",
                paper,
                "--out",
                out.to_str().unwrap(),
            ],
            Some((FAULT_ENV, &n.to_string())),
        );
        assert_eq!(o.status.code(), Some(1), "N = {n}");
        assert!(
            stderr(&o).contains("previous output is intact"),
            "{}",
            stderr(&o)
        );
        assert_eq!(snapshot(&out.join("paper")), before, "N = {n}");
    }
    // sweep, then sweep-merge of two shards
    let cfg = tiny_config(&dir);
    let c = cfg.to_str().unwrap();
    let sw = dir.join("sweep");
    let s = sw.to_str().unwrap();
    assert!(
        run(&["sweep", "--config", c, "--out", s], None)
            .status
            .success()
    );
    let before = snapshot(&sw);
    for n in [0, 5000, 40_000] {
        let o = run(
            &["sweep", "--config", c, "--out", s],
            Some((FAULT_ENV, &n.to_string())),
        );
        assert_eq!(o.status.code(), Some(1), "N = {n}: {}", stderr(&o));
        let after = snapshot(&sw);
        assert_eq!(names(&after), names(&before), "N = {n}");
        // meta.json records times: everything else is byte for byte the previous run's.
        for ((name, a), (_, b)) in after.iter().zip(&before) {
            assert!(a == b, "N = {n}: {name} changed");
        }
    }
    let (s1, s2, m) = (dir.join("s1"), dir.join("s2"), dir.join("merged"));
    for (i, d) in [(1, &s1), (2, &s2)] {
        let shard = format!("{i}/2");
        let o = run(
            &[
                "sweep",
                "--config",
                c,
                "--out",
                d.to_str().unwrap(),
                "--shard",
                &shard,
            ],
            None,
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let merge = |env| {
        run(
            &[
                "sweep-merge",
                "--config",
                c,
                "--out",
                m.to_str().unwrap(),
                s1.to_str().unwrap(),
                s2.to_str().unwrap(),
            ],
            env,
        )
    };
    assert!(merge(None).status.success());
    let before = snapshot(&m);
    let o = merge(Some((FAULT_ENV, "3000")));
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(snapshot(&m), before);
    // An unreadable (here: cut) shard meta is refused, naming it.
    let meta = s2.join("meta.shard-2-of-2.json");
    let text = fs::read(&meta).unwrap();
    fs::write(&meta, &text[..text.len() / 2]).unwrap();
    let o = merge(None);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("meta.shard-2-of-2.json") && e.contains("not valid JSON"),
        "{e}"
    );
    assert_eq!(snapshot(&m), before);
}

/// Edited point files are refused on resume, naming the file, the row, the cell and the
/// fix; the original is accepted again.
#[test]
fn point_files_are_checked_for_meaning() {
    let dir = scratch("meaning");
    let cfg = tiny_config(&dir);
    let c = cfg.to_str().unwrap();
    let out = dir.join("o");
    let s = out.to_str().unwrap();
    assert!(
        run(&["sweep", "--config", c, "--out", s], None)
            .status
            .success()
    );
    let file = out.join("points").join("p00001.csv");
    let original = fs::read_to_string(&file).unwrap();
    let lines: Vec<&str> = original.lines().collect();
    let runs_header = fs::read_to_string(out.join("runs.csv")).unwrap();
    let runs_header: Vec<&str> = runs_header.lines().next().unwrap().split(',').collect();
    let points_header = fs::read_to_string(out.join("points.csv")).unwrap();
    let points_header: Vec<&str> = points_header.lines().next().unwrap().split(',').collect();
    let edit = |line: usize, header: &[&str], column: &str, value: &str| -> String {
        let c = header.iter().position(|h| *h == column).unwrap();
        let mut ls: Vec<String> = lines.iter().map(|l| (*l).to_string()).collect();
        let mut cells: Vec<String> = ls[line].split(',').map(str::to_string).collect();
        cells[c] = value.to_string();
        ls[line] = cells.join(",");
        ls.join("\n") + "\n"
    };
    // The summary row; the checksum line (`# fnv1a …`) follows it.
    let summary = lines.len() - 2;
    let cases = [
        (
            edit(summary, &points_header, "bounded_fraction", "2"),
            "bounded_fraction",
        ),
        (
            edit(summary, &points_header, "bounded_fraction", "0.5"),
            "bounded_fraction",
        ),
        (edit(1, &runs_header, "sup_e", "NaN"), "sup_e"),
        (edit(1, &runs_header, "sup_e", "-1"), "sup_e"),
        (
            edit(summary, &points_header, "sup_e_q50", "inf"),
            "sup_e_q50",
        ),
        // A run's sup_e above the point's: the recomputed quantiles and maximum differ.
        (edit(1, &runs_header, "sup_e", "1e300"), "sup_e_q"),
    ];
    for (text, column) in cases {
        fs::write(&file, &text).unwrap();
        let o = run(&["sweep", "--config", c, "--out", s], None);
        assert_eq!(o.status.code(), Some(1), "{column}");
        let e = stderr(&o);
        assert!(
            e.contains("p00001.csv") && e.contains(column) && e.contains("delete it"),
            "{column}: {e}"
        );
    }
    fs::write(&file, &original).unwrap();
    assert!(
        run(&["sweep", "--config", c, "--out", s], None)
            .status
            .success()
    );
}

/// Issue 37 item 14: `--help > /dev/full` and runs with stdout closed (`>&-`) exited 0 (clap
/// printed the help and ignored the error; the Rust runtime reopens a closed stdout on
/// /dev/null). Both are now exit code 5, the documented code for an unwritable stream; a
/// readable help still exits 0.
#[test]
fn help_or_a_run_into_a_full_or_closed_stdout_is_exit_5() {
    let full = || {
        fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    for args in [
        &["--help"][..],
        &["certify", "--help"][..],
        &["--version"][..],
    ] {
        let o = Command::new(crate::shared::xtask_bin())
            .args(args)
            .stdout(Stdio::from(full()))
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(5), "{args:?}: {}", stderr(&o));
        let o = Command::new(crate::shared::xtask_bin())
            .args(args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        assert!(!o.stdout.is_empty());
    }
    // stdout closed by the shell.
    for cmd in [
        "\"$0\" --help >&-".to_string(),
        format!("\"$0\" certify --scenario '{}' >&-", case_study()),
    ] {
        let o = Command::new("sh")
            .arg("-c")
            .arg(&cmd)
            .arg(crate::shared::xtask_bin())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(5), "{cmd}: {}", stderr(&o));
        assert!(stderr(&o).contains("stdout was closed"), "{}", stderr(&o));
    }
    // A usage error keeps its own code (2) whatever stdout is.
    let o = Command::new(crate::shared::xtask_bin())
        .arg("--no-such-flag")
        .stdout(Stdio::from(full()))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}
