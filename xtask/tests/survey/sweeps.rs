//! Sweep configs: a refusal names a user key, a value the generator knows is bad is
//! refused (at parse, or at the latest when the sweep is set up, before any run).

use std::time::Instant;

use qp_iter::Method;
use xtask::sweep_engine::{Sweep, SweepConfig};

use crate::generate::{
    Bad, SWEEP_KEYS, SweepCase, SweepEdit, chain, names_user_key, sweep_case, write_sweep_scenarios,
};
use crate::{Tally, draw, runner, scratch};

/// Longest a config may take to parse (and, when it must be refused, to set up).
const CASE_SECONDS: f64 = 2.0;

pub fn survey(seed: u64, n: usize) -> Tally {
    let mut tally = Tally::default();
    let dir = scratch("sweeps");
    write_sweep_scenarios(&dir).unwrap();
    let mut rn = runner(seed, 3);
    let strategy = sweep_case();
    let paths = [
        dir.join("config.toml").display().to_string(),
        dir.display().to_string(),
    ];
    for _ in 0..n {
        let case = draw(&mut rn, &strategy);
        let text = String::from_utf8_lossy(&case.bytes()).into_owned();
        let t0 = Instant::now();
        tally.cases += 1;
        let named = |msg: String| -> Result<(), String> {
            let p: Vec<&str> = paths.iter().map(String::as_str).collect();
            if names_user_key(&msg, &p) || msg.starts_with("sweep config is not valid TOML") {
                Ok(())
            } else {
                Err(format!("the refusal names no user key: {msg}"))
            }
        };
        let outcome = match SweepConfig::from_toml_str(&text, &dir) {
            Err(e) => named(chain(&e)).map(|()| true),
            Ok(cfg) => match must_refuse(&case) {
                None => Ok(false),
                // Bad: it must at least fail when the sweep is set up.
                Some(why) => match Sweep::new(cfg) {
                    Err(e) => named(chain(&e)).map(|()| true),
                    Ok(_) => Err(format!("accepted-bad: {why} was accepted")),
                },
            },
        };
        match outcome {
            Ok(true) => tally.refused += 1,
            Ok(false) => tally.accepted += 1,
            Err(why) => tally.finding(format!(
                "{why}\n--- case {case:?}\n--- config:\n{text:.1500}"
            )),
        }
        let took = t0.elapsed().as_secs_f64();
        if took > CASE_SECONDS {
            tally.finding(format!("took {took:.2} s\n--- config:\n{text:.1500}"));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    tally
}

/// Why the generator's edit must be refused, if it must.
fn must_refuse(case: &SweepCase) -> Option<String> {
    let SweepCase::AlmostValid(_, edit) = case else {
        return None;
    };
    let bad_positive = |v: f64| !(v.is_finite() && v > 0.0);
    match edit {
        SweepEdit::BadK(kind) => Some(format!("k (bad list or range {kind})")),
        SweepEdit::Solver(name) if name.parse::<Method>().is_err() => {
            Some(format!("solvers = [\"{name}\"]"))
        }
        SweepEdit::Seeds(v) if *v <= 0 || *v > 10_000_000 => Some(format!("seeds = {v}")),
        SweepEdit::Steps(v) if *v <= 0 || *v > 100_000 => Some(format!("steps = {v}")),
        // docs/sweeps.md: scales ≥ 0 (0 gives w ≡ 0).
        SweepEdit::Scale(v) if !(v.is_finite() && *v >= 0.0) => Some(format!("scales = [1, {v}]")),
        SweepEdit::ScenarioPath(kind) => Some(format!("scenario path case {kind}")),
        SweepEdit::Metrics(kind) => Some(format!("metrics case {kind}")),
        SweepEdit::BoundedFactor(v) if bad_positive(*v) => Some(format!("bounded_factor = {v}")),
        SweepEdit::Controller(kind @ 1..=3) => Some(format!("controller case {kind}")),
        SweepEdit::Unknown(name) => Some(format!("an unknown key `{name}`")),
        SweepEdit::Replace(k, Bad::Float(v) | Bad::Entry(_, v)) if v.is_nan() => {
            Some(format!("{} = NaN", SWEEP_KEYS[*k]))
        }
        _ => None,
    }
}
