//! Firmware robustness of the exported C (issue 36): the step counter cannot overflow, a
//! non-finite (u, y) is refused with the state unchanged, an uncertified artefact does not
//! compile without the opt-in, the FP-contraction guard and the self-test, strict replay
//! and loop parsing.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use qp_iter::Method;

use super::tests::{
    artefact, bits, case, parse_replay, record_self_test, replay_input, run_program, run_std,
    scratch_dir, write_files,
};
use super::tests_mpc::LoopCase;
use super::*;
use extract::portable_estimator;

/// The case study's C export for PG (uncertified test banner), with the self-test recorded.
fn pg_export(tag: &str) -> (PathBuf, super::tests::Case) {
    let c = case("case-study-certified.toml", None);
    let (mut p, art) = artefact(&c, Method::PG, ScalarKind::F64);
    record_self_test(&c, Method::PG, &mut p);
    let dir = scratch_dir(&format!("firmware-{tag}"));
    write_files(&dir, Lang::C, &p, None, &art);
    (dir, c)
}

/// `cc` with the artefact's strict flags plus `extra`, building `out` from `srcs`.
fn cc(dir: &Path, out: &str, srcs: &[&str], extra: &[&str]) -> Output {
    Command::new("cc")
        .current_dir(dir)
        .args(["-O2", "-std=c99", "-ffp-contract=off", "-fno-fast-math"])
        .args(["-Wall", "-Wextra", "-Werror", "-o", out])
        .args(extra)
        .args(srcs)
        .arg("-lm")
        .output()
        .unwrap()
}

fn assert_built(o: &Output, what: &str) {
    assert!(
        o.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Runs `program` on `input`: (exit code, stdout, stderr).
fn run_raw(program: &Path, input: &[u8]) -> (Option<i32>, String, String) {
    use std::io::Write;
    let mut child = Command::new(program)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The program may exit before reading everything (a refused line): ignore EPIPE.
    let _ = child.stdin.take().unwrap().write_all(input);
    let o = child.wait_with_output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

const ALLOW: &str = "-DMHE_ALLOW_UNCERTIFIED";

/// A replay whose counter is set to LONG_MAX once the window is full (as after 2^63 − 1
/// steps, or 2^31 − 1 on a 32-bit long): the estimates still equal the std estimator's bit
/// for bit (the old counter overflowed to a negative t and indexed the windows with it).
#[test]
fn c_step_counter_started_near_the_limit_saturates() {
    let (dir, c) = pg_export("counter");
    std::fs::write(dir.join("counter.c"), COUNTER_C).unwrap();
    let o = cc(
        &dir,
        "counter",
        &["mhe.c", "mhe_data.c", "counter.c"],
        &[ALLOW, "-fwrapv"],
    );
    assert_built(&o, "counter.c");
    let got = parse_replay(&run_program(
        &mut Command::new(dir.join("counter")),
        &replay_input(&c.traj),
    ));
    let mut est = portable_estimator(&c.resolved, Method::PG, c.k).unwrap();
    assert_eq!(bits(&got), bits(&run_std(&mut est, &c.traj)));
}

const COUNTER_C: &str = r#"#include <limits.h>
#include <stdio.h>
#include "mhe.h"
#include "parse.h"
static mhe_state s;
static void show(const mhe_real *x) {
    int i;
    for (i = 0; i < MHE_NX; i++) printf(i ? ",%.17g" : "%.17g", (double)x[i]);
    printf("\n");
}
int main(void) {
    static char line[MHE_LINE_MAX];
    double v[MHE_NU + MHE_NY];
    mhe_real u[MHE_NU_BUF], y[MHE_NY];
    long lineno = 0;
    int i;
    mhe_reset(&s, mhe_exported_prior);
    show(mhe_estimate(&s));
    while (mhe_read_line("counter", line, ++lineno) == 1) {
        if (mhe_parse_line("counter", line, lineno, MHE_NU + MHE_NY, "u then y", v) != 0) return 1;
        for (i = 0; i < MHE_NU; i++) u[i] = (mhe_real)v[i];
        for (i = 0; i < MHE_NY; i++) y[i] = (mhe_real)v[MHE_NU + i];
        if (lineno == MHE_M + 2) s.t = LONG_MAX;
        if (mhe_push(&s, u, y) != MHE_OK) return 1;
        show(mhe_estimate(&s));
    }
    return 0;
}
"#;

/// NaN or ±∞ in u or y: mhe_push returns MHE_E_NONFINITE and the state is byte for byte
/// what it was; a finite pair is accepted afterwards.
#[test]
fn c_push_refuses_a_non_finite_pair_and_keeps_the_state() {
    let (dir, _) = pg_export("nonfinite");
    std::fs::write(dir.join("nonfinite.c"), NONFINITE_C).unwrap();
    let o = cc(
        &dir,
        "nonfinite",
        &["mhe.c", "mhe_data.c", "nonfinite.c"],
        &[ALLOW],
    );
    assert_built(&o, "nonfinite.c");
    let (code, out, err) = run_raw(&dir.join("nonfinite"), b"");
    assert_eq!(code, Some(0), "{out}{err}");
    assert_eq!(out.trim(), "refused 4, state unchanged");
}

const NONFINITE_C: &str = r#"#include <math.h>
#include <stdio.h>
#include <string.h>
#include "mhe.h"
static mhe_state s, snap;
int main(void) {
    mhe_real u[MHE_NU_BUF], y[MHE_NY];
    const mhe_real bad[2] = {NAN, -INFINITY};
    int k, i, refused = 0;
    for (i = 0; i < MHE_NU_BUF; i++) u[i] = (mhe_real)0.01;
    for (i = 0; i < MHE_NY; i++) y[i] = (mhe_real)0.1;
    mhe_reset(&s, mhe_exported_prior);
    for (k = 0; k < MHE_M + 3; k++) {
        if (mhe_push(&s, u, y) != MHE_OK) return 2;
        mhe_estimate(&s);
    }
    memcpy(&snap, &s, sizeof s);
    for (k = 0; k < 2; k++) {
        y[MHE_NY - 1] = bad[k];
        if (mhe_push(&s, u, y) != MHE_E_NONFINITE) return 3;
        if (memcmp(&snap, &s, sizeof s) != 0) return 4;
        refused++;
        y[MHE_NY - 1] = (mhe_real)0.1;
        u[0] = bad[k];
        if (MHE_NU > 0 && mhe_push(&s, u, y) != MHE_E_NONFINITE) return 5;
        if (memcmp(&snap, &s, sizeof s) != 0) return 6;
        refused += MHE_NU > 0;
        u[0] = (mhe_real)0.01;
    }
    if (mhe_push(&s, u, y) != MHE_OK) return 7;
    printf("refused %d, state unchanged\n", refused);
    return 0;
}
"#;

/// An uncertified artefact stops at `#error` unless MHE_ALLOW_UNCERTIFIED is defined; a
/// certified one builds without it.
#[test]
fn c_uncertified_artefact_needs_the_opt_in() {
    let (dir, c) = pg_export("uncertified-guard");
    let srcs = ["mhe.c", "mhe_data.c", "replay.c"];
    let o = cc(&dir, "replay", &srcs, &[]);
    assert!(!o.status.success(), "an uncertified artefact compiled");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("UNCERTIFIED") && err.contains("MHE_ALLOW_UNCERTIFIED"),
        "{err}"
    );
    assert_built(&cc(&dir, "replay", &srcs, &[ALLOW]), "with the opt-in");
    // The same data marked certified build without it.
    let (mut p, mut art) = artefact(&c, Method::PG, ScalarKind::F64);
    record_self_test(&c, Method::PG, &mut p);
    art.certified = true;
    let dir = scratch_dir("firmware-certified-guard");
    write_files(&dir, Lang::C, &p, None, &art);
    assert_built(&cc(&dir, "replay", &srcs, &[]), "a certified artefact");
    // An uncertified MPC stops the build too, even with a certified estimator.
    let l = LoopCase::new("case-study-certified.toml", 125);
    let (p, m) = l.data(Method::PG);
    let mut art = super::tests::exported_artefact(&l.path, &l.resolved, l.mhe, l.k_e, Some(125));
    art.certified = true;
    let dir = scratch_dir("firmware-uncertified-mpc");
    write_files(&dir, Lang::C, &p, Some(&m), &art);
    let o = cc(
        &dir,
        "loop",
        &["mhe.c", "mhe_data.c", "mpc.c", "loop.c"],
        &[],
    );
    assert!(!o.status.success(), "an uncertified MPC compiled");
}

/// GCC's GNU mode contracts a·b + c into an FMA on an FMA target; the pragma in mhe.c turns
/// that off, so such a build still reproduces the std estimator bit for bit (and passes the
/// self-test). Reassociated sums (what -ffast-math does, part of it allowed past the
/// `#error`) fail the self-test, and the replay exits 1 before reading any input; plain
/// -ffast-math does not compile.
#[test]
fn c_fp_contraction_is_off_and_the_self_test_catches_reassociation() {
    let (dir, c) = pg_export("fp-flags");
    let srcs = ["mhe.c", "mhe_data.c", "replay.c"];
    let input = replay_input(&c.traj);
    let mut est = portable_estimator(&c.resolved, Method::PG, c.k).unwrap();
    let expected = bits(&run_std(&mut est, &c.traj));
    let gnu = |out: &str, flags: &[&str]| {
        Command::new("cc")
            .current_dir(&dir)
            .args(["-std=gnu99", ALLOW, "-o", out])
            .args(flags)
            .args(srcs)
            .arg("-lm")
            .output()
            .unwrap()
    };
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("fma") {
        assert_built(&gnu("replay-fma", &["-O2", "-mfma"]), "gnu99 -O2 -mfma");
        let (code, out, err) = run_raw(&dir.join("replay-fma"), input.as_bytes());
        assert_eq!(code, Some(0), "{err}");
        assert_eq!(bits(&parse_replay(&out)), expected, "FMA contraction");
    }
    let assoc = [
        "-O3",
        "-fassociative-math",
        "-fno-signed-zeros",
        "-fno-trapping-math",
    ];
    assert_built(&gnu("replay-assoc", &assoc), "reassociation");
    let (code, out, err) = run_raw(&dir.join("replay-assoc"), input.as_bytes());
    assert_eq!(code, Some(1), "{out}");
    assert!(err.contains("self-test failed at step"), "{err}");
    assert!(out.is_empty(), "{out}");
    let o = gnu("replay-fast", &["-O2", "-ffast-math"]);
    assert!(!o.status.success(), "-ffast-math compiled");
    assert!(String::from_utf8_lossy(&o.stderr).contains("fast-math"));
}

/// Every malformed line exits 1 naming it, for the replay and the loop.
#[test]
fn c_replay_and_loop_parse_strictly() {
    let (dir, _) = pg_export("parse");
    assert_built(
        &cc(
            &dir,
            "replay",
            &["mhe.c", "mhe_data.c", "replay.c"],
            &[ALLOW],
        ),
        "replay",
    );
    // n_u = 2, n_y = 1: three numbers per line.
    let good = "0.1,0.2,0.3\n";
    let long = format!("0.1,0.2,{}1\n", "0".repeat(8200));
    let cases: [(&str, String); 7] = [
        ("trailing garbage", format!("{good}0.1,0.2,0.3abc\n")),
        ("extra number", format!("{good}0.1,0.2,0.3,0.4\n")),
        ("missing number", format!("{good}0.1,0.2\n")),
        ("NaN", format!("{good}0.1,nan,0.3\n")),
        ("infinity", format!("{good}0.1,0.2,inf\n")),
        ("empty field", format!("{good}0.1,,0.3\n")),
        ("line over 8191 bytes", format!("{good}{long}")),
    ];
    for (what, input) in &cases {
        let (code, _, err) = run_raw(&dir.join("replay"), input.as_bytes());
        assert_eq!(code, Some(1), "{what}: {err}");
        assert!(err.contains("replay: line 2:"), "{what}: {err}");
    }
    let (code, out, err) = run_raw(
        &dir.join("replay"),
        format!("{good} 0.1 , 0.2,0.3\n").as_bytes(),
    );
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(out.lines().count(), 3);
    // The loop (n_y = 1).
    let l = LoopCase::new("case-study-certified.toml", 125);
    let (p, m) = l.data(Method::PG);
    let art = super::tests::exported_artefact(&l.path, &l.resolved, l.mhe, l.k_e, Some(125));
    let dir = scratch_dir("firmware-parse-loop");
    write_files(&dir, Lang::C, &p, Some(&m), &art);
    assert_built(
        &cc(
            &dir,
            "loop",
            &["mhe.c", "mhe_data.c", "mpc.c", "loop.c"],
            &[ALLOW],
        ),
        "loop",
    );
    for (what, input) in [
        ("trailing garbage", "0.3\n0.3abc\n".to_string()),
        ("extra number", "0.3\n0.3,0.4\n".into()),
        ("NaN", "0.3\nNaN\n".into()),
        (
            "line over 8191 bytes",
            format!("0.3\n{}1\n", "0".repeat(8200)),
        ),
    ] {
        let (code, _, err) = run_raw(&dir.join("loop"), input.as_bytes());
        assert_eq!(code, Some(1), "{what}: {err}");
        assert!(err.contains("loop: line 2:"), "{what}: {err}");
    }
}

/// The exported Rust replay refuses what the C one refuses, and an invalid-UTF-8 line is an
/// error naming it (it used to end the input silently with exit 0). An uncertified Rust
/// artefact builds only with `--features allow-uncertified`.
#[test]
fn rust_replay_parses_strictly() {
    let c = case("case-study-certified.toml", None);
    let (p, art) = artefact(&c, Method::PG, ScalarKind::F64);
    let dir = scratch_dir("firmware-rust-parse");
    write_files(&dir, Lang::Rust, &p, None, &art);
    let target = super::tests::workspace_root()
        .join("target")
        .join("export-tests-target");
    // The test artefact is uncertified: it stops at compile_error! without the opt-in.
    let o = Command::new(env!("CARGO"))
        .current_dir(&dir)
        .env("CARGO_TARGET_DIR", &target)
        .args(["build", "--quiet", "--offline", "--bin", "replay"])
        .output()
        .unwrap();
    assert!(!o.status.success(), "an uncertified Rust artefact built");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("UNCERTIFIED") && err.contains("allow-uncertified"),
        "{err}"
    );
    let status = Command::new(env!("CARGO"))
        .current_dir(&dir)
        .env("CARGO_TARGET_DIR", &target)
        .args(["build", "--quiet", "--offline", "--bin", "replay"])
        .args(["--features", "allow-uncertified"])
        .status()
        .unwrap();
    assert!(status.success(), "cargo build failed in {}", dir.display());
    // Copied: another test rebuilds the same target directory's replay.
    let replay = dir.join("replay-bin");
    std::fs::copy(target.join("debug").join("replay"), &replay).unwrap();
    let good = b"0.1,0.2,0.3\n".to_vec();
    let with = |bad: &[u8]| [good.as_slice(), bad].concat();
    for (what, input) in [
        ("invalid UTF-8", with(b"0.1,0.2,\xff0.3\n")),
        ("trailing garbage", with(b"0.1,0.2,0.3abc\n")),
        ("extra number", with(b"0.1,0.2,0.3,0.4\n")),
        ("NaN", with(b"0.1,NaN,0.3\n")),
        ("infinity", with(b"0.1,0.2,inf\n")),
    ] {
        let (code, _, err) = run_raw(&replay, &input);
        assert_eq!(code, Some(1), "{what}: {err}");
        assert!(err.contains("replay: line 2:"), "{what}: {err}");
    }
    let (code, out, err) = run_raw(&replay, &with(b"\n 0.1 , 0.2,0.3\n"));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(out.lines().count(), 3);
}

/// Two estimators in one program: the case study's PG export with `--prefix est_a` and its
/// FISTA export with the default names link together, and each equals its std estimator
/// bit for bit (without the prefix every symbol is defined twice).
#[test]
fn c_two_prefixed_estimators_link_into_one_firmware() {
    let c = case("case-study-certified.toml", None);
    let root = scratch_dir("firmware-prefix");
    for (sub, method) in [("a", Method::PG), ("b", Method::FISTA)] {
        let (mut p, mut art) = artefact(&c, method, ScalarKind::F64);
        record_self_test(&c, method, &mut p);
        art.certified = true;
        let dir = root.join(sub);
        write_files(&dir, Lang::C, &p, None, &art);
        if sub == "a" {
            c_gen::apply_prefix(&dir, "est_a").unwrap();
        }
    }
    assert!(root.join("a/est_a.h").exists() && root.join("a/est_a_data.c").exists());
    assert!(!root.join("a/mhe.c").exists());
    std::fs::write(root.join("two.c"), TWO_C).unwrap();
    let srcs = [
        "a/est_a.c",
        "a/est_a_data.c",
        "b/mhe.c",
        "b/mhe_data.c",
        "two.c",
    ];
    assert_built(&cc(&root, "two", &srcs, &[]), "two estimators");
    let out = run_program(&mut Command::new(root.join("two")), &replay_input(&c.traj));
    let rows = parse_replay(&out);
    for (k, method) in [(0, Method::PG), (1, Method::FISTA)] {
        let mut est = portable_estimator(&c.resolved, method, c.k).unwrap();
        let expected = bits(&run_std(&mut est, &c.traj));
        let got: Vec<Vec<f64>> = rows
            .iter()
            .map(|r| r[k * 4..(k + 1) * 4].to_vec())
            .collect();
        assert_eq!(bits(&got), expected, "{}", method.name());
    }
    assert!(
        c_gen::check_prefix("Bad-name").is_err()
            && c_gen::check_prefix("mhe_a").is_err()
            && c_gen::check_prefix("pend2").is_ok()
    );
}

const TWO_C: &str = r#"#include <stdio.h>
#include "a/est_a.h"
#include "b/mhe.h"
#include "b/parse.h"
static est_a_state sa;
static mhe_state sb;
static void show(const est_a_real *a, const mhe_real *b) {
    int i;
    for (i = 0; i < EST_A_NX; i++) printf(i ? ",%.17g" : "%.17g", (double)a[i]);
    for (i = 0; i < MHE_NX; i++) printf(",%.17g", (double)b[i]);
    printf("\n");
}
int main(void) {
    static char line[MHE_LINE_MAX];
    double v[MHE_NU + MHE_NY];
    est_a_real ua[EST_A_NU_BUF], ya[EST_A_NY];
    mhe_real ub[MHE_NU_BUF], yb[MHE_NY];
    long lineno = 0;
    int i;
    if (est_a_self_test(&sa) != 0 || mhe_self_test(&sb) != 0) return 1;
    est_a_reset(&sa, est_a_exported_prior);
    mhe_reset(&sb, mhe_exported_prior);
    show(est_a_estimate(&sa), mhe_estimate(&sb));
    while (mhe_read_line("two", line, ++lineno) == 1) {
        if (mhe_parse_line("two", line, lineno, MHE_NU + MHE_NY, "u then y", v) != 0) return 1;
        for (i = 0; i < MHE_NU; i++) ua[i] = ub[i] = v[i];
        for (i = 0; i < MHE_NY; i++) ya[i] = yb[i] = v[MHE_NU + i];
        if (est_a_push(&sa, ua, ya) != EST_A_OK || mhe_push(&sb, ub, yb) != MHE_OK) return 1;
        show(est_a_estimate(&sa), mhe_estimate(&sb));
    }
    return 0;
}
"#;

/// The README's memory layout is the compiled data: its flash rows add up to the constants
/// of `mhe_data.o` (host cc; its `.rodata`, to within 1 KiB: the prior and a few scalars;
/// the windows' pointer descriptors are relocated data, not counted), and it gives the linker changes for an STM32F405 and an
/// STM32H743 and, for Rust, the Cortex-M build steps (issue 36's README items).
#[test]
fn readme_memory_layout_is_the_compiled_data_and_names_the_boards() {
    let (dir, c) = pg_export("readme");
    let (mut p, art) = artefact(&c, Method::PG, ScalarKind::F64);
    record_self_test(&c, Method::PG, &mut p);
    let text = c_gen::firmware_readme(&p, None, &art, Lang::C);
    let flash: usize = (text.lines())
        .filter(|l| l.contains("| flash"))
        .map(|l| {
            let cell = l.split('|').nth(3).unwrap().trim();
            cell.split_whitespace()
                .next()
                .unwrap()
                .parse::<usize>()
                .unwrap()
        })
        .sum();
    let o = Command::new("cc")
        .current_dir(&dir)
        .args([
            "-O2",
            "-std=c99",
            "-c",
            ALLOW,
            "-o",
            "mhe_data.o",
            "mhe_data.c",
        ])
        .output()
        .unwrap();
    assert_built(&o, "mhe_data.o");
    let size = Command::new("size")
        .current_dir(&dir)
        .args(["-A", "mhe_data.o"])
        .output()
        .unwrap();
    let data: usize = (String::from_utf8_lossy(&size.stdout).lines())
        .filter(|l| l.starts_with(".rodata"))
        .map(|l| {
            l.split_whitespace()
                .nth(1)
                .unwrap()
                .parse::<usize>()
                .unwrap()
        })
        .sum();
    assert!(
        flash <= data && data <= flash + 1024,
        "README flash rows {flash} B, mhe_data.o {data} B"
    );
    for needle in [
        "## Memory layout",
        "STM32F405",
        "LENGTH = 1024K",
        "STM32H743",
        "LENGTH = 2048K",
        "-ffp-contract=off",
        "saturates",
        "MHE_E_NONFINITE",
    ] {
        assert!(text.contains(needle), "README lacks {needle}");
    }
    assert!(!text.contains("## Rust on Cortex-M"));
    let rust = c_gen::firmware_readme(&p, None, &art, Lang::Rust);
    assert!(rust.contains("## Rust on Cortex-M") && rust.contains("thumbv7em-none-eabihf"));
}
