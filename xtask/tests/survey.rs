//! The generated-input dishonesty survey (issue 37, "Done when"): cases of five kinds —
//! scenario files, the verdicts of configurations on generated tiny plants, sweep configs,
//! point files and `export` arguments — each checked by an *honesty oracle*, not only for
//! "no panic":
//!
//! - **scenario files** ([`scenarios`]): a refusal names a user key; a value the generator
//!   knows is out of range (η ∉ [0, 1), a weight not positive definite, a non-finite
//!   number, a count ≤ 0, an unknown key, a bad method parameter) is refused; an accepted
//!   file satisfies the invariants the library documents (checked here independently:
//!   Cholesky of Q, R, P, R_c; η; finiteness); the LMI (2) verdict is the same when q and r
//!   are scaled together by 10⁻¹²…10¹² (units); "infeasible" never beside a feasible η ≤
//!   the user's; every case within a time bound (refused before anything large);
//! - **verdicts** ([`verdicts`]): on generated tiny plants, the one verdict
//!   (`coverage::verdict`, what `reproduce`, `sweep`, `export` and `certify` call) is
//!   monotone in K, "yes" exactly from K_min on, agrees with the per-solver `certified` of
//!   certificate.json, never "yes" for a shifted warm start or the saturated LQR, f32 "yes"
//!   only where f64 is, "void" never with a budget cause and "not computed" only with one;
//! - **sweep configs** ([`sweeps`]): a refusal names a user key; a value the generator knows
//!   is bad is refused;
//! - **point files** ([`points`]): a cell edited to another value in a finished point file is
//!   refused (naming the file) — a resume or a merge never reuses a result that is not the
//!   one computed, including the theory columns (`certified`, `k_min_cert`, …);
//! - **export arguments** ([`export_args`], through the binary): a bad argument is refused
//!   with a message naming the flag, before the certificate (under a second on a preset
//!   whose certificate takes seconds), and nothing is written;
//! - **replay lines** ([`replay`], `survey_full` only: it exports and builds the C replay
//!   with cc): a malformed input line exits 1 naming its line number with no estimate for
//!   it; a well-formed one is accepted; a blank one skipped.
//!
//! The seed is `SURVEY_SEED` (default 37), printed with the per-kind counts and times; a
//! case that fails an oracle is printed whole (its kind, input and what was dishonest).
//! `survey_sample` (≈ 2 000 cases) runs in the default suite; `survey_full` (≥ 10⁵ cases)
//! is `#[ignore]`d: `cargo test --release -p xtask --test survey -- --ignored survey_full
//! --nocapture` (docs/testing.md has the measured counts and time).
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "survey/export_args.rs"]
mod export_args;
mod generate;
#[path = "survey/points.rs"]
mod points;
#[path = "survey/replay.rs"]
mod replay;
#[path = "survey/scenarios.rs"]
mod scenarios;
#[path = "survey/sweeps.rs"]
mod sweeps;
#[path = "survey/verdicts.rs"]
mod verdicts;

use std::path::{Path, PathBuf};
use std::time::Instant;

use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

/// Counts and findings of one kind.
#[derive(Debug, Default)]
pub struct Tally {
    /// Cases generated and checked.
    pub cases: usize,
    /// Cases refused with a typed error (the expected outcome of a bad input).
    pub refused: usize,
    /// Cases accepted (and then checked for honesty).
    pub accepted: usize,
    /// Every oracle failure: the case and why it is dishonest or accepted-bad.
    pub findings: Vec<String>,
    /// Wall time of the kind.
    pub seconds: f64,
}

impl Tally {
    /// Records an oracle failure (the first 50 in full; the rest counted).
    pub fn finding(&mut self, what: String) {
        self.findings.push(what);
    }
}

/// A runner with the survey's seed and a stream number (each kind its own stream, so the
/// cases of one kind do not change when another kind's count does).
pub fn runner(seed: u64, stream: u8) -> TestRunner {
    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&seed.to_le_bytes());
    bytes[8] = stream;
    TestRunner::new_with_rng(
        Config {
            failure_persistence: None,
            ..Config::default()
        },
        TestRng::from_seed(RngAlgorithm::ChaCha, &bytes),
    )
}

/// One value drawn from `s`.
pub fn draw<S: Strategy>(runner: &mut TestRunner, s: &S) -> S::Value {
    s.new_tree(runner)
        .expect("a strategy of the generator")
        .current()
}

/// A fresh scratch directory under the test target directory.
pub fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("survey")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Case counts of one survey run.
struct Plan {
    scenarios: usize,
    verdict_plants: usize,
    sweeps: usize,
    points: usize,
    export_args: usize,
    replay_lines: usize,
}

fn seed() -> u64 {
    std::env::var("SURVEY_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(37)
}

fn run(plan: &Plan) {
    let seed = seed();
    let started = Instant::now();
    let mut kinds: Vec<(&str, Tally)> = Vec::new();
    let mut timed = |name: &'static str, f: &dyn Fn() -> Tally| {
        let t0 = Instant::now();
        let mut t = f();
        t.seconds = t0.elapsed().as_secs_f64();
        eprintln!(
            "survey seed {seed}: {name}: {} cases ({} refused, {} accepted) in {:.1} s, {} findings",
            t.cases,
            t.refused,
            t.accepted,
            t.seconds,
            t.findings.len()
        );
        kinds.push((name, t));
    };
    timed("scenario files", &|| {
        scenarios::survey(seed, plan.scenarios)
    });
    timed("verdicts", &|| verdicts::survey(seed, plan.verdict_plants));
    timed("sweep configs", &|| sweeps::survey(seed, plan.sweeps));
    timed("point files", &|| points::survey(seed, plan.points));
    timed("export arguments", &|| {
        export_args::survey(seed, plan.export_args)
    });
    timed("replay lines", &|| replay::survey(seed, plan.replay_lines));
    let total: usize = kinds.iter().map(|(_, t)| t.cases).sum();
    let found: usize = kinds.iter().map(|(_, t)| t.findings.len()).sum();
    eprintln!(
        "survey seed {seed}: {total} cases in {:.1} s, {found} findings",
        started.elapsed().as_secs_f64()
    );
    let mut report = String::new();
    for (name, t) in &kinds {
        for f in t.findings.iter().take(30) {
            report.push_str(&format!("[{name}] {f}\n\n"));
        }
        if t.findings.len() > 30 {
            report.push_str(&format!("[{name}] … {} more\n", t.findings.len() - 30));
        }
    }
    assert!(
        found == 0,
        "{found} dishonest or accepted-bad cases (seed {seed}):\n{report}"
    );
}

/// The default-suite sample: about 2 000 cases (≈ 20 s in debug).
#[test]
fn survey_sample() {
    run(&Plan {
        scenarios: 1_500,
        verdict_plants: 3,
        sweeps: 300,
        points: 300,
        export_args: 12,
        // The replay needs an export (a certificate) and cc: in survey_full only.
        replay_lines: 0,
    });
}

/// The full survey: ≥ 10⁵ cases (docs/testing.md: counts and time).
#[test]
#[ignore = "the full survey (≥ 10⁵ cases, minutes in release); run with --ignored survey_full"]
fn survey_full() {
    run(&Plan {
        scenarios: 70_000,
        verdict_plants: 200,
        sweeps: 15_000,
        points: 15_000,
        export_args: 600,
        replay_lines: 10_000,
    });
}
