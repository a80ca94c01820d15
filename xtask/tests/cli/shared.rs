#![allow(clippy::unwrap_used)]
//! Runs that several tests of this binary check, computed once per process (`OnceLock`)
//! instead of once per test (docs/testing.md, "Session 17"). Each test keeps its assertions;
//! only the run they read is shared.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The `xtask` binary these tests run: the build of the same profile (`.ci/run` and the README
/// test in release), or `XTASK_BIN` when set — e.g. a release build under `cargo test` without
/// `--release`, where the spawned runs' numerics take a fraction of the opt-level-1 time; the
/// outputs are the same (no fast-math: the bits do not depend on the optimisation level).
/// A path that is not a file panics here, before any test reads a stale or missing binary.
pub fn xtask_bin() -> PathBuf {
    match std::env::var_os("XTASK_BIN") {
        Some(p) => {
            let p = PathBuf::from(p);
            assert!(p.is_file(), "XTASK_BIN={} is not a file", p.display());
            p
        }
        None => PathBuf::from(env!("CARGO_BIN_EXE_xtask")),
    }
}

/// One run of `xtask sweep --config sweeps/smoke-2d.toml --threads 2`, the 2-D smoke sweep
/// over (K_e, K_c): `golden::long_smoke_2d_sweep_outputs_match_the_golden_files` compares its
/// tables with the golden files, `sweep_cli::long_two_d_sweep_writes_heat_maps_and_pair_thresholds`
/// checks its terminal output, plots and meta.json, then resumes it. 53 CPU s in the test
/// profile, once instead of twice.
#[derive(Debug)]
pub struct Smoke2d {
    /// The command's standard output.
    pub stdout: String,
    /// Its `--out` directory (the sweep_cli test resumes the sweep in it).
    pub out: PathBuf,
    /// Copies of `points.csv` and `runs.csv` taken right after the run, before any test
    /// touches `out`: what the golden test compares.
    pub points: PathBuf,
    pub runs: PathBuf,
}

/// The smoke sweep's config file, by absolute path.
pub const SMOKE_2D: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../sweeps/smoke-2d.toml");

/// `xtask sweep` on the 2-D smoke sweep into `out`, from the workspace root, with the
/// portable kernel: the golden files hold its bits (the AVX2 path rounds differently), and a
/// resume compares the point files with the same kernel's theory.
pub fn smoke_2d_command(out: &Path) -> Command {
    let mut c = Command::new(xtask_bin());
    c.env("QP_ITER_KERNEL", "portable")
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .args(["sweep", "--config", SMOKE_2D, "--threads", "2", "--out"])
        .arg(out);
    c
}

/// The shared run of the 2-D smoke sweep (computed by the first caller).
pub fn smoke_2d() -> &'static Smoke2d {
    static RUN: OnceLock<Smoke2d> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("xtask-shared/smoke-2d");
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let out = dir.join("out");
        let o = smoke_2d_command(&out).output().unwrap();
        assert!(
            o.status.success(),
            "xtask sweep smoke-2d: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let (points, runs) = (dir.join("points.csv"), dir.join("runs.csv"));
        fs::copy(out.join("points.csv"), &points).unwrap();
        fs::copy(out.join("runs.csv"), &runs).unwrap();
        Smoke2d {
            stdout: String::from_utf8(o.stdout).unwrap(),
            out,
            points,
            runs,
        }
    })
}

/// One run of `xtask reproduce` (both presets, the portable kernel, the work counts on)
/// into a directory of this test binary: `golden::long_reproduce_outputs_match_the_golden_files`
/// compares both presets' JSON with the golden files,
/// `export_cli::long_replay_of_the_exported_c_reproduces_trace_csv_bit_for_bit` replays the
/// certified preset's trace.csv, `reproduce_cli::long_reproduce_computes_k_m_and_p_once_per_scenario`
/// reads the work counts on its stderr. Once instead of three times (38 CPU s each in the test
/// profile: docs/testing.md, "Session 19"). Nobody writes into it: a test that needs to change
/// it copies it.
#[derive(Debug)]
pub struct Reproduce {
    /// The `--out` directory.
    pub out: PathBuf,
    /// The command's standard error (with the `work:` line of `SUBOPTIMAL_MHE_COUNT_WORK`).
    pub stderr: String,
}

/// The shared run of `xtask reproduce` (computed by the first caller).
pub fn reproduce_run() -> &'static Reproduce {
    static RUN: OnceLock<Reproduce> = OnceLock::new();
    RUN.get_or_init(|| {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("xtask-shared/reproduce");
        let _ = fs::remove_dir_all(&out);
        let o = Command::new(xtask_bin())
            // The golden files hold the portable kernel's bits (the AVX2 path rounds
            // differently), and the exported C replays them bit for bit.
            .env("QP_ITER_KERNEL", "portable")
            // Only adds the `work:` line to stderr (xtask's main): the files are unchanged.
            .env("SUBOPTIMAL_MHE_COUNT_WORK", "1")
            .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
            .arg("reproduce")
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "xtask reproduce: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        Reproduce {
            out,
            stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
        }
    })
}

/// The shared run's `--out` directory.
pub fn reproduce() -> &'static Path {
    &reproduce_run().out
}
