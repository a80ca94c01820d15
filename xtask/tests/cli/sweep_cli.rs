//! `cargo xtask sweep` / `sweep-merge` as a user runs them: a sweep killed mid-run loses no
//! finished point and resumes to the same output as an uninterrupted run; shards merged
//! with `sweep-merge` give the same files; bad input exits with an error, never a panic.
#![allow(clippy::unwrap_used)]

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use xtask::sweep_engine::{Sweep, SweepConfig, Table};

const SCENARIO: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenarios/case-study-certified.toml"
);

fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("xtask-sweep")
        .join(name);
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

/// 2 solvers × 6 K, 10 seeds, T = 40; the certificate off (seconds) to keep it short.
fn config(dir: &Path, file: &str, body: &str) -> PathBuf {
    let path = dir.join(file);
    fs::write(&path, format!("scenario = \"{SCENARIO}\"\n{body}")).unwrap();
    path
}

const SMALL: &str = "name = \"kill\"\nk = [1, 3, 10, 30, 100, 300]\nsolvers = [\"pg\", \"fista\"]\n\
                     seeds = 10\nsteps = 40\nbase_seed = 5\ncertificate = false\n";

fn xtask(args: &[&str]) -> Output {
    Command::new(crate::shared::xtask_bin())
        .args(args)
        .output()
        .unwrap()
}

fn text(p: &Path) -> String {
    Table::parse(&fs::read_to_string(p).unwrap())
        .unwrap()
        .without_timing()
}

fn point_files(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = fs::read_dir(dir.join("points")) else {
        return Vec::new();
    };
    rd.map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect()
}

fn ok(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

#[test]
fn killed_sweep_resumes_to_the_uninterrupted_result() {
    let d = scratch("kill");
    let cfg = config(&d, "sweep.toml", SMALL);
    let killed = d.join("killed");
    let mut child = Command::new(crate::shared::xtask_bin())
        .args(["sweep", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(&killed)
        .args(["--threads", "1"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Kill it as soon as two points are finished.
    let start = Instant::now();
    while point_files(&killed).len() < 2 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "finished before the kill"
        );
        assert!(start.elapsed() < Duration::from_secs(300), "no point file");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let present = point_files(&killed).len();
    assert!((2..12).contains(&present), "{present} point files");
    assert!(
        !killed.join("runs.csv").exists(),
        "assembled before the kill?"
    );
    // Every point file present is complete and belongs to this sweep.
    let sweep = Sweep::new(SweepConfig::from_file(&cfg).unwrap()).unwrap();
    let finished = sweep.finished_points(&killed).unwrap();
    assert_eq!(finished.len(), present);
    assert!(finished.values().all(|f| f.run_rows.len() == 10));

    // Resume (another thread count) and compare with an uninterrupted run.
    let out = ok(&xtask(&[
        "sweep",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        killed.to_str().unwrap(),
        "--threads",
        "2",
    ]));
    assert!(
        out.contains(&format!(
            "points: {} computed, {present} skipped",
            12 - present
        )),
        "{out}"
    );
    assert!(out.contains("total wall time:") && out.contains("steps/s per thread"));
    let whole = d.join("whole");
    ok(&xtask(&[
        "sweep",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        whole.to_str().unwrap(),
        "--threads",
        "1",
    ]));
    for f in ["runs.csv", "points.csv"] {
        assert_eq!(text(&killed.join(f)), text(&whole.join(f)), "{f}");
    }
    // The outputs: CSVs, plots, meta.json with the provenance.
    for f in ["error.svg", "state.svg", "bounded.svg", "meta.json"] {
        assert!(whole.join(f).is_file(), "{f}");
    }
    let meta: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(whole.join("meta.json")).unwrap()).unwrap();
    assert_eq!(meta["base_seed"], 5);
    assert_eq!(meta["run"]["threads"], 1);
    for key in [
        "git_revision",
        "rustc",
        "host",
        "start_utc",
        "end_utc",
        "config_toml",
    ] {
        assert!(!meta[key].is_null(), "{key}");
    }

    // Two shards into their own directories, merged: the same files again.
    let shards: Vec<PathBuf> = (1..=2).map(|i| d.join(format!("shard{i}"))).collect();
    for (i, s) in shards.iter().enumerate() {
        let out = ok(&xtask(&[
            "sweep",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            s.to_str().unwrap(),
            "--threads",
            "1",
            "--shard",
            &format!("{}/2", i + 1),
        ]));
        assert!(out.contains("points: 6 computed"), "{out}");
        assert!(s.join(format!("meta.shard-{}-of-2.json", i + 1)).is_file());
    }
    let merged = d.join("merged");
    ok(&xtask(&[
        "sweep-merge",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
        shards[0].to_str().unwrap(),
        shards[1].to_str().unwrap(),
    ]));
    for f in ["runs.csv", "points.csv"] {
        assert_eq!(text(&merged.join(f)), text(&whole.join(f)), "{f}");
    }
    assert!(merged.join("error.svg").is_file() && merged.join("meta.json").is_file());
}

/// Runs `xtask sweep` and expects a clean error (exit 1, message, no panic, an OS error
/// printed at most once); returns stderr.
/// Checks that the files `meta.json` lists under `run.files` are in `dir` with the size and
/// FNV-1a hash it records: the directory holds one complete set (issue 23).
fn check_manifest(dir: &Path) {
    let meta: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(dir.join("meta.json")).unwrap()).unwrap();
    let files = meta["run"]["files"].as_array().unwrap();
    assert!(files.len() >= 3, "{files:?}");
    for f in files {
        let name = f["file"].as_str().unwrap();
        let bytes = fs::read(dir.join(name)).unwrap();
        let hash = bytes.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
        });
        assert_eq!(bytes.len() as u64, f["bytes"].as_u64().unwrap(), "{name}");
        assert_eq!(
            format!("{hash:016x}"),
            f["fnv1a64"].as_str().unwrap(),
            "{name}"
        );
    }
}

/// A staged (not yet committed) file of the output set in `dir`: `runs.csv.<pid>.<n>.tmp`
/// (`early`), or a plot's or `meta.json`'s, staged after the tables (`!early`).
fn staged(dir: &Path, early: bool) -> bool {
    fs::read_dir(dir).is_ok_and(|rd| {
        rd.flatten().any(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.ends_with(".tmp")
                && if early {
                    n.starts_with("runs.csv.") || n.starts_with("points.csv.")
                } else {
                    n.contains(".svg.") || n.starts_with("meta.json.")
                }
        })
    })
}

/// `runs.csv`, `points.csv`, the plots and `meta.json` are committed as one set: a rerun
/// killed (SIGKILL) while it stages them — the tables, or the plots and `meta.json` after
/// them — leaves the previous set, whose files all match its `meta.json` (before issue 23's
/// fix the library had already replaced `runs.csv` and `points.csv` when the plots were
/// drawn); a final rerun completes it.
#[test]
fn killed_while_writing_the_outputs_leaves_one_complete_set() {
    let d = scratch("kill-commit");
    let cfg = config(&d, "sweep.toml", SMALL);
    let out = d.join("out");
    let args = [
        "sweep",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    ok(&xtask(&args));
    check_manifest(&out);
    let mut killed = [0, 0];
    for trial in 0..24 {
        // One point recomputed: its wall_ms, so runs.csv and points.csv change.
        let files = point_files(&out);
        fs::remove_file(&files[trial % files.len()]).unwrap();
        // The temporaries of the previous killed trial (the next sweep would remove them
        // too) must not be taken for this one's.
        for e in fs::read_dir(&out).unwrap().flatten() {
            if e.file_name().to_string_lossy().ends_with(".tmp") {
                let _ = fs::remove_file(e.path());
            }
        }
        let early = trial % 2 == 0;
        let mut child = Command::new(crate::shared::xtask_bin())
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let start = Instant::now();
        loop {
            if child.try_wait().unwrap().is_some() {
                break; // finished before a staged file was seen
            }
            if staged(&out, early) {
                child.kill().unwrap();
                child.wait().unwrap();
                killed[usize::from(!early)] += 1;
                break;
            }
            assert!(
                start.elapsed() < Duration::from_secs(300),
                "trial {trial} hangs"
            );
        }
        check_manifest(&out);
    }
    assert!(
        killed[0] + killed[1] >= 2,
        "killed while staging: {killed:?}"
    );
    ok(&xtask(&args));
    check_manifest(&out);
    assert_eq!(point_files(&out).len(), 12);
}

fn expect_error(args: &[&str], needle: &str) -> String {
    let out = xtask(args);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
    assert!(stderr.contains("error:"), "{stderr}");
    assert!(
        stderr.contains(needle),
        "{args:?}: `{needle}` not in {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        stderr.matches("os error").count() <= 1,
        "cause repeated: {stderr}"
    );
    stderr
}

#[test]
fn bad_input_exits_with_an_error_not_a_panic() {
    let d = scratch("bad");
    let body = |k: &str, solvers: &str, seeds: &str| {
        format!(
            "name = \"bad\"\nk = {k}\nsolvers = {solvers}\nseeds = {seeds}\ncertificate = false\nsteps = 2\n"
        )
    };
    let cases = [
        (body("[1]", "[\"pg\", \"newton\"]", "2"), "solvers[1]"),
        (body("[]", "[\"pg\"]", "2"), "`k`"),
        (body("[1, 0]", "[\"pg\"]", "2"), "k[1]"),
        (body("[1]", "[\"pg\"]", "-3"), "`seeds`"),
        (
            format!("{}\nspeed = 3\n", body("[1]", "[\"pg\"]", "2")),
            "`speed`",
        ),
    ];
    for (i, (b, needle)) in cases.iter().enumerate() {
        let sub = d.join(format!("case{i}"));
        fs::create_dir_all(&sub).unwrap();
        let cfg = config(&sub, "sweep.toml", b);
        expect_error(
            &[
                "sweep",
                "--config",
                cfg.to_str().unwrap(),
                "--out",
                sub.to_str().unwrap(),
            ],
            needle,
        );
    }
    let good = config(&d, "good.toml", &body("[1]", "[\"pg\"]", "1"));
    let good = good.to_str().unwrap();
    // A shard spec with I > N.
    expect_error(
        &["sweep", "--config", good, "--shard", "3/2"],
        "shard `3/2`",
    );
    expect_error(&["sweep", "--config", good, "--threads", "0"], "--threads");
    // An output directory that cannot be created (below a regular file).
    let file = d.join("plain-file");
    fs::write(&file, "x").unwrap();
    let out = file.join("out");
    let stderr = expect_error(
        &["sweep", "--config", good, "--out", out.to_str().unwrap()],
        "cannot create the output directory",
    );
    assert_eq!(stderr.matches("os error").count(), 1, "{stderr}");
    // A missing config file.
    expect_error(
        &["sweep", "--config", "/nonexistent/sweep.toml"],
        "sweep.toml",
    );
    // Merging an incomplete set of shards.
    let half = d.join("half");
    ok(&xtask(&[
        "sweep",
        "--config",
        good,
        "--out",
        half.to_str().unwrap(),
        "--shard",
        "1/1",
    ]));
    let two = config(&d, "two.toml", &body("[1, 2]", "[\"pg\"]", "1"));
    let two_dir = d.join("two");
    ok(&xtask(&[
        "sweep",
        "--config",
        two.to_str().unwrap(),
        "--out",
        two_dir.to_str().unwrap(),
        "--shard",
        "2/2",
    ]));
    let out = xtask(&[
        "sweep-merge",
        "--config",
        two.to_str().unwrap(),
        "--out",
        d.join("m").to_str().unwrap(),
        two_dir.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    // Shard 1 never ran: its meta is missing, which the merge names before the points.
    assert!(
        stderr.contains("meta.shard-1-of-2.json is missing") && stderr.contains("shard 1/2"),
        "{stderr}"
    );
    // With that meta present (shard 1 cut short), the missing points are named.
    let meta = two_dir.join("meta.shard-2-of-2.json");
    let text = fs::read_to_string(&meta).unwrap();
    fs::write(
        two_dir.join("meta.shard-1-of-2.json"),
        text.replace("\"2/2\"", "\"1/2\""),
    )
    .unwrap();
    let out = xtask(&[
        "sweep-merge",
        "--config",
        two.to_str().unwrap(),
        "--out",
        d.join("m").to_str().unwrap(),
        two_dir.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("1 of 2 points have no point file"),
        "{stderr}"
    );
}

/// A sweep config whose single point takes long (it is killed, never finished).
const LONG: &str = "name = \"long\"\nk = [5000]\nsolvers = [\"pg\"]\nseeds = 100000\nsteps = 40\n\
                    certificate = false\n";

#[test]
fn a_second_writer_is_refused_and_a_stale_lock_taken_over() {
    let d = scratch("lock");
    let cfg = config(&d, "long.toml", LONG);
    let cfg = cfg.to_str().unwrap();
    let out = d.join("out");
    let lock = out.join(".lock");
    let mut first = Command::new(crate::shared::xtask_bin())
        .args([
            "sweep",
            "--config",
            cfg,
            "--out",
            out.to_str().unwrap(),
            "--threads",
            "1",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let pid = first.id();
    let start = Instant::now();
    while fs::read_to_string(&lock).map_or(true, |t| !t.starts_with(&format!("{pid}\n"))) {
        assert!(first.try_wait().unwrap().is_none(), "the first sweep ended");
        assert!(start.elapsed() < Duration::from_secs(300), "no lock file");
        std::thread::sleep(Duration::from_millis(5));
    }
    // A second sweep into the same directory while the first runs.
    let second = xtask(&["sweep", "--config", cfg, "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert_eq!(second.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!("is being written by another sweep (pid {pid})")),
        "{stderr}"
    );
    assert!(
        first.try_wait().unwrap().is_none(),
        "the first sweep was disturbed"
    );
    // Kill the first: its lock stays behind, stale. The next writer (a merge here, which
    // then fails: no point is finished) takes it over, says so, and releases it.
    first.kill().unwrap();
    first.wait().unwrap();
    assert!(lock.is_file());
    let merge = xtask(&[
        "sweep-merge",
        "--config",
        cfg,
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&merge.stderr);
    assert_eq!(merge.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("took over the stale lock") && stderr.contains(&format!("pid {pid}")),
        "{stderr}"
    );
    assert!(
        stderr.contains("1 of 1 points have no point file"),
        "{stderr}"
    );
    assert!(!lock.exists(), "lock not released after the error");
}

#[test]
fn corrupt_point_files_and_missing_shard_dirs_are_named() {
    let d = scratch("corrupt");
    let cfg = config(
        &d,
        "two.toml",
        "name = \"two\"\nk = [1, 2]\nsolvers = [\"pg\"]\nseeds = 2\nsteps = 3\ncertificate = false\n",
    );
    let cfg = cfg.to_str().unwrap();
    let out = d.join("out");
    let out_s = out.to_str().unwrap();
    ok(&xtask(&["sweep", "--config", cfg, "--out", out_s]));
    // Random bytes in a point file: named, with the fix, not an I/O message.
    // Seeded bytes (SplitMix64 of 0, 1, 2, …).
    let bytes: Vec<u8> = (0..125u64)
        .flat_map(|i| closed_loop::monte_carlo::splitmix64(i).to_le_bytes())
        .collect();
    assert!(String::from_utf8(bytes.clone()).is_err());
    fs::write(out.join("points/p00001.csv"), &bytes).unwrap();
    let stderr = expect_error(
        &["sweep", "--config", cfg, "--out", out_s],
        "points/p00001.csv",
    );
    assert!(stderr.contains("delete it and rerun"), "{stderr}");
    assert!(!stderr.contains("stream did not contain"), "{stderr}");
    // A shard directory that does not exist is named.
    let missing = d.join("nonexistent");
    let stderr = expect_error(
        &[
            "sweep-merge",
            "--config",
            cfg,
            "--out",
            d.join("m").to_str().unwrap(),
            missing.to_str().unwrap(),
        ],
        "is not a sweep output directory",
    );
    assert!(stderr.contains(missing.to_str().unwrap()), "{stderr}");
}

/// `--threads` is capped at a few per core (issue 14: 100 000 threads were spawned), and a
/// config that is an endless stream is refused without reading it all.
#[test]
fn thread_count_and_input_size_are_bounded() {
    let d = scratch("limits");
    let cfg = config(
        &d,
        "t.toml",
        "name = \"t\"\nk = [1]\nsolvers = [\"pg\"]\nseeds = 1\ncertificate = false\nsteps = 2\n",
    );
    let out = d.join("out");
    let stderr = expect_error(
        &[
            "sweep",
            "--config",
            cfg.to_str().unwrap(),
            "--threads",
            "100000",
            "--out",
            out.to_str().unwrap(),
        ],
        "--threads 100000",
    );
    assert!(stderr.contains("per core"), "{stderr}");
    expect_error(&["sweep", "--config", "/dev/zero"], "MiB");
}

/// A 2-D sweep over (K_e, K_c) through the binary: heat maps instead of the line plots, the
/// 2-D thresholds printed and in meta.json, the joint certificate's boundary (no certified pair
/// on this small grid: FISTA's K_e floor is 5 896 > 100, ADMM's certificate is void),
/// a rerun that resumes everything, and a K_c grid without the sub-optimal MPC refused.
/// The first run is shared with `golden::long_smoke_2d_sweep_outputs_match_the_golden_files`
/// (`crate::shared::smoke_2d`: the same command, once per test binary).
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_two_d_sweep_writes_heat_maps_and_pair_thresholds() {
    let d = scratch("two-d");
    let run = crate::shared::smoke_2d();
    let (stdout, out) = (run.stdout.clone(), run.out.clone());
    assert!(
        stdout.contains("(3 K × 3 K_c × 2 solvers × 1 scales)"),
        "{stdout}"
    );
    assert!(stdout.contains("2-D thresholds"), "{stdout}");
    assert!(stdout.contains("none certified on its grid"), "{stdout}");
    for solver in ["fista", "admm"] {
        for map in ["bounded", "error", "rho-lin"] {
            let svg = fs::read_to_string(out.join(format!("heatmap-{map}-{solver}.svg"))).unwrap();
            assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
            assert!(
                svg.contains("certified: no pair on the grid"),
                "{map} {solver}"
            );
        }
    }
    assert!(
        !out.join("error.svg").exists(),
        "no line plots over K in 2-D"
    );
    let meta: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("meta.json")).unwrap()).unwrap();
    assert_eq!(meta["k_c_grid"], serde_json::json!([1, 5, 20]));
    assert_eq!(meta["cost"]["t_e"], 1.0);
    let pairs = meta["run"]["pair_thresholds"].as_array().unwrap();
    assert_eq!(pairs.len(), 2);
    for p in pairs {
        assert_eq!(p["k_c_grid"], serde_json::json!([1, 5, 20]));
        assert!(p["empirical_boundary"].as_array().unwrap().len() == 3);
        assert!(p["cheapest_certified"].is_null());
    }
    let cert = meta["run"]["certified_boundary"].as_array().unwrap();
    for c in cert {
        assert_eq!(c["status"], "computed");
        let st = c["staircase"].as_array().unwrap();
        assert_eq!(st.len(), 3, "one entry per K_e of the grid");
        assert!(st.iter().all(|e| e[1].is_null()), "{st:?}");
    }
    // Per-K_c thresholds (each K_c a curve over K_e) are stored too.
    let th = meta["run"]["thresholds"].as_array().unwrap();
    assert_eq!(th.len(), 2 * 3);
    assert!(th.iter().all(|t| t["k_c"].is_u64()));
    let again = ok(&crate::shared::smoke_2d_command(&out).output().unwrap());
    assert!(again.contains("0 computed, 18 skipped"), "{again}");
    // The k_c column is the only change to the file layout.
    let points = fs::read_to_string(out.join("points.csv")).unwrap();
    assert!(points.starts_with("point,k,k_c,solver,scale,runs,bounded_fraction,"));
    // A K_c grid with the exact MPC is an input error naming k_c.
    let bad = config(
        &d,
        "bad.toml",
        "name = \"bad\"\nk = [1]\nk_c = [1, 2]\nsolvers = [\"pg\"]\nseeds = 1\n",
    );
    expect_error(
        &[
            "sweep",
            "--config",
            bad.to_str().unwrap(),
            "--out",
            d.join("bad").to_str().unwrap(),
        ],
        "`k_c`: a K_c grid needs the sub-optimal MPC",
    );
}

/// A tiny sweep body: 2 K × the given solvers, 2 seeds, T = 8, no certificate.
fn tiny(solvers: &str) -> String {
    format!(
        "name = \"tiny\"\nk = [1, 5]\nsolvers = [{solvers}]\nseeds = 2\nsteps = 8\n\
         base_seed = 3\ncertificate = false\n"
    )
}

/// Issue 37 item 10: a method given as a table with parameters (docs/sweeps.md) has a
/// comma in its name; its `solver` cell is written `admm(rho=2;alpha=1.5)`, so the sweep
/// assembles, resumes (every point file accepted) and merges its shards.
#[test]
fn a_method_table_sweeps_resumes_and_merges() {
    let dir = scratch("method-table");
    let cfg = config(
        &dir,
        "m.toml",
        &tiny(r#""pg", { method = "admm", rho = 2.0, alpha = 1.5 }"#),
    );
    let c = cfg.to_str().unwrap();
    let out = dir.join("o");
    let o = out.to_str().unwrap();
    ok(&xtask(&["sweep", "--config", c, "--out", o]));
    let points = Table::parse(&fs::read_to_string(out.join("points.csv")).unwrap()).unwrap();
    assert_eq!(points.rows.len(), 4);
    assert_eq!(points.text(2, "solver"), Some("admm(rho=2;alpha=1.5)"));
    let runs = Table::parse(&fs::read_to_string(out.join("runs.csv")).unwrap()).unwrap();
    assert_eq!(runs.rows.len(), 8);
    // Resume: every point file is valid, nothing is recomputed.
    let again = ok(&xtask(&["sweep", "--config", c, "--out", o]));
    assert!(again.contains("0 computed, 4 skipped"), "{again}");
    // Shards and a merge give the unsharded tables.
    let (s1, s2, m) = (dir.join("s1"), dir.join("s2"), dir.join("m"));
    for (i, d) in [(1, &s1), (2, &s2)] {
        let shard = format!("{i}/2");
        let d = d.to_str().unwrap();
        ok(&xtask(&[
            "sweep", "--config", c, "--out", d, "--shard", &shard,
        ]));
    }
    let (s1, s2, m) = (
        s1.to_str().unwrap(),
        s2.to_str().unwrap(),
        m.to_str().unwrap(),
    );
    ok(&xtask(&["sweep-merge", "--config", c, "--out", m, s1, s2]));
    for f in ["runs.csv", "points.csv"] {
        assert_eq!(text(&dir.join("m").join(f)), text(&out.join(f)), "{f}");
    }
}

/// Issue 37 item 12: every field of a resumed point file is checked — a completed run's
/// `steps` is T, wall times are finite and ≥ 0 (the summary's the runs' sum), `converged`
/// implies `bounded`, the fractions are the run rows', the gains and ρ_lin ≥ 0 — and an
/// edited file is refused naming the file, the line and the column.
#[test]
fn a_resumed_point_file_is_checked_field_by_field() {
    let dir = scratch("resume-fields");
    let cfg = config(&dir, "t.toml", &tiny("\"pg\""));
    let c = cfg.to_str().unwrap();
    let out = dir.join("o");
    let o = out.to_str().unwrap();
    ok(&xtask(&["sweep", "--config", c, "--out", o]));
    let file = out.join("points").join("p00001.csv");
    let original = fs::read_to_string(&file).unwrap();
    let lines: Vec<&str> = original.lines().collect();
    let header = |f: &str| -> Vec<String> {
        let t = fs::read_to_string(out.join(f)).unwrap();
        t.lines()
            .next()
            .unwrap()
            .split(',')
            .map(str::to_string)
            .collect()
    };
    let (rh, ph) = (header("runs.csv"), header("points.csv"));
    // Line 1 the fingerprint, 2–3 the runs, 4 `=`, 5 the summary (1-based, as in messages).
    let edit = |edits: &[(usize, &str, &str)]| -> String {
        let mut ls: Vec<String> = lines.iter().map(|l| (*l).to_string()).collect();
        for &(line, column, value) in edits {
            let h = if line == 5 { &ph } else { &rh };
            let c = h.iter().position(|n| n == column).unwrap();
            let mut cells: Vec<String> = ls[line - 1].split(',').map(str::to_string).collect();
            cells[c] = value.to_string();
            ls[line - 1] = cells.join(",");
        }
        ls.join("\n") + "\n"
    };
    let cases: Vec<(String, &str)> = vec![
        (
            edit(&[(2, "steps", "3")]),
            "line 2 (run 0), column `steps`: `3`, but the run completed",
        ),
        (
            edit(&[(2, "wall_ms", "-5")]),
            "line 2 (run 0), column `wall_ms`: `-5` is not a finite number ≥ 0",
        ),
        (
            edit(&[(3, "wall_ms", "inf")]),
            "line 3 (run 1), column `wall_ms`: `inf` is not a finite number ≥ 0",
        ),
        (
            edit(&[(5, "wall_ms", "-5")]),
            "line 5 (summary row), column `wall_ms`: `-5` is not a finite number ≥ 0",
        ),
        (
            edit(&[(5, "wall_ms", "123456")]),
            "line 5 (summary row), column `wall_ms`",
        ),
        (
            edit(&[(2, "bounded", "0"), (2, "converged", "1")]),
            "line 2 (run 0), column `converged`: `1`, but column `bounded` is `0`",
        ),
        (
            edit(&[(2, "converged", "2")]),
            "line 2 (run 0), column `converged`: `2` is none of 0, 1",
        ),
        (
            edit(&[(5, "converged_fraction", "0.25")]),
            "line 5 (summary row), column `converged_fraction`",
        ),
        (
            edit(&[(5, "rho_lin", "-1")]),
            "line 5 (summary row), column `rho_lin`: `-1` is not a number ≥ 0",
        ),
        (
            edit(&[(5, "phi", "-0.5")]),
            "line 5 (summary row), column `phi`: `-0.5` is not a number ≥ 0",
        ),
    ];
    for (edited, needle) in cases {
        fs::write(&file, &edited).unwrap();
        let out = xtask(&["sweep", "--config", c, "--out", o]);
        let e = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(out.status.code(), Some(1), "{needle}: {e}");
        assert!(
            e.contains("p00001.csv") && e.contains(needle) && e.contains("delete it"),
            "`{needle}` not in: {e}"
        );
    }
    fs::write(&file, &original).unwrap();
    let again = ok(&xtask(&["sweep", "--config", c, "--out", o]));
    assert!(again.contains("0 computed, 2 skipped"), "{again}");
}

/// Issue 37 item 12: `sweep-merge` takes exactly one sharding's metas — a missing
/// `meta.shard-1-of-2.json`, a stray `meta.shard-1-of-3.json`, a duplicate or a renamed
/// one is refused naming the file, and nothing is written.
#[test]
fn merge_requires_exactly_the_shards_of_one_run() {
    let dir = scratch("shard-set");
    let cfg = config(&dir, "t.toml", &tiny("\"pg\""));
    let c = cfg.to_str().unwrap();
    let (s1, s2, m) = (dir.join("s1"), dir.join("s2"), dir.join("m"));
    for (i, d) in [(1, &s1), (2, &s2)] {
        let shard = format!("{i}/2");
        ok(&xtask(&[
            "sweep",
            "--config",
            c,
            "--out",
            d.to_str().unwrap(),
            "--shard",
            &shard,
        ]));
    }
    let merge = || {
        xtask(&[
            "sweep-merge",
            "--config",
            c,
            "--out",
            m.to_str().unwrap(),
            s1.to_str().unwrap(),
            s2.to_str().unwrap(),
        ])
    };
    let meta1 = s1.join("meta.shard-1-of-2.json");
    let meta2 = s2.join("meta.shard-2-of-2.json");
    let text1 = fs::read(&meta1).unwrap();
    let refused = |needles: &[&str]| {
        let o = merge();
        let e = String::from_utf8_lossy(&o.stderr).to_string();
        assert_eq!(o.status.code(), Some(1), "{needles:?}: {e}");
        for n in needles {
            assert!(e.contains(n), "`{n}` not in: {e}");
        }
        assert!(
            !m.join("points.csv").exists(),
            "{needles:?}: wrote points.csv"
        );
    };
    fs::remove_file(&meta1).unwrap();
    refused(&["meta.shard-1-of-2.json is missing from every input directory"]);
    fs::write(&meta1, &text1).unwrap();
    let stray = s2.join("meta.shard-1-of-3.json");
    fs::write(&stray, &text1).unwrap();
    refused(&["meta.shard-1-of-3.json", "shard 1 of 3", "stray"]);
    fs::remove_file(&stray).unwrap();
    let twice = s2.join("meta.shard-1-of-2.json");
    fs::write(&twice, &text1).unwrap();
    refused(&["shard 1 of 2 is there twice"]);
    fs::remove_file(&twice).unwrap();
    // A meta renamed to another shard's name: its `shard` field says which it is.
    let text2 = fs::read(&meta2).unwrap();
    fs::write(&meta2, &text1).unwrap();
    refused(&["meta.shard-2-of-2.json", "does not record shard 2/2"]);
    fs::write(&meta2, &text2).unwrap();
    ok(&merge());
    assert!(m.join("points.csv").exists());
}

/// Issue 37 item 8: "bounded" is not "stable". On the open-loop unstable cart-pendulum
/// (𝒲 rarely active, the input unconstrained but the MHE's ŵ boxed) PG at K = 1 and ADMM
/// α = 2 at K = 25 have ρ_lin ≫ 1 (1.14 and 75) and every run stays bounded, but none
/// converges to the disturbance level; ADMM α = 2 at K = 2000 (ρ_lin < 1) converges.
#[test]
fn bounded_runs_above_rho_lin_one_do_not_converge() {
    let dir = scratch("converged");
    let scenario = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/cart-pendulum.toml"
    );
    let path = dir.join("cp.toml");
    fs::write(
        &path,
        format!(
            "scenario = \"{scenario}\"\nname = \"cp\"\nk = [1, 25, 2000]\n\
             solvers = [\"pg\", \"admm-pr\"]\nseeds = 4\nsteps = 150\nbase_seed = 11\n\
             certificate = false\n"
        ),
    )
    .unwrap();
    let out = dir.join("o");
    ok(&xtask(&[
        "sweep",
        "--config",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    let p = Table::parse(&fs::read_to_string(out.join("points.csv")).unwrap()).unwrap();
    let row = |k: &str, solver: &str| {
        (0..p.rows.len())
            .find(|&r| p.text(r, "k") == Some(k) && p.text(r, "solver") == Some(solver))
            .unwrap()
    };
    for (k, solver, rho_above, converged) in [
        ("1", "pg", 1.1, 0.0),
        ("25", "admm-pr", 10.0, 0.0),
        ("2000", "admm-pr", 0.0, 1.0),
    ] {
        let r = row(k, solver);
        let rho = p.number(r, "rho_lin").unwrap();
        assert!(rho > rho_above, "{solver} K = {k}: ρ_lin = {rho}");
        assert_eq!(
            p.number(r, "bounded_fraction"),
            Some(1.0),
            "{solver} K = {k}"
        );
        assert_eq!(
            p.number(r, "converged_fraction"),
            Some(converged),
            "{solver} K = {k}"
        );
    }
    let runs = Table::parse(&fs::read_to_string(out.join("runs.csv")).unwrap()).unwrap();
    for r in 0..runs.rows.len() {
        let converged = runs.text(r, "converged") == Some("1");
        assert!(!converged || runs.text(r, "bounded") == Some("1"));
    }
}
