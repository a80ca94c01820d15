//! The constrained MHE against a Kalman filter on the same disturbance draws (issue 15).
//!
//! For each seed the scenario's loop (its MHE with the state/output sets, its MPC) and the
//! same loop with a fading-memory Kalman filter of the MHE's weights in place of the MHE
//! (`mhe_core::KalmanFilter::matching_mhe`: the unconstrained counterpart of the MHE's cost)
//! run on identical disturbances. Printed: mean ‖e_t‖ over all steps and over the last
//! quarter, how often the true state and the estimates leave 𝒳, and the MPC's infeasible
//! steps.
//!
//! ```text
//! cargo run --release -p closed-loop --example constrained_vs_kalman -- \
//!     scenarios/mass-chain-state-box.toml scenarios/mass-chain-state-box-tight.toml 200
//! ```

use closed_loop::record::Trace;
use closed_loop::scenario::{LoopOptions, Scenario, scenario_disturbance};
use closed_loop::sim::ClosedLoop;
use mhe_core::KalmanFilter;
use rayon::prelude::*;

/// Per-run figures.
#[derive(Debug, Clone, Copy, Default)]
struct RunFigures {
    mean_e: f64,
    tail_e: f64,
    /// Steps where the true x_t ∉ 𝒳 (beyond 1e-9).
    x_outside: usize,
    /// Largest box violation of an estimate x̂_t.
    xhat_violation: f64,
    /// MPC steps that were infeasible (a fallback was applied).
    infeasible: usize,
    steps: usize,
    completed: bool,
    /// The step at which the run left the bounded rule (`closed_loop::bounded`), if it did.
    diverged: Option<usize>,
}

fn box_violation(v: &[f64], lo: &[f64], hi: &[f64]) -> f64 {
    v.iter()
        .zip(lo.iter().zip(hi))
        .map(|(x, (l, u))| (l - x).max(x - u).max(0.0))
        .fold(0.0, f64::max)
}

/// The run's figures; `stopped_early`: the loop stopped before T on a step error.
fn figures(
    trace: &Trace,
    x0: &[f64],
    lo: &[f64],
    hi: &[f64],
    completed: bool,
    stopped_early: bool,
) -> RunFigures {
    let e = trace.e_norms();
    let n = e.len();
    let tail = &e[n - n / 4..];
    let mut f = RunFigures {
        mean_e: e.iter().sum::<f64>() / n.max(1) as f64,
        tail_e: tail.iter().sum::<f64>() / tail.len().max(1) as f64,
        infeasible: trace.infeasible_steps().count(),
        steps: n,
        completed,
        diverged: closed_loop::bounded::first_unbounded(
            trace,
            x0,
            closed_loop::bounded::DEFAULT_BOUNDED_FACTOR,
            stopped_early,
        )
        .map(|d| d.t),
        ..RunFigures::default()
    };
    for t in 0..trace.len() {
        if let Some(x) = trace.x(t) {
            if box_violation(x, lo, hi) > 1e-9 {
                f.x_outside += 1;
            }
        }
        if let Some(xh) = trace.x_hat(t) {
            f.xhat_violation = f.xhat_violation.max(box_violation(xh, lo, hi));
        }
    }
    f
}

/// One line per estimator. Error statistics are over the bounded runs only: a diverged run
/// (the bounded rule of `closed_loop::bounded`) is counted as diverged, never averaged in
/// (a mean of 7.7·10²² says nothing but "diverged").
fn summarise(name: &str, runs: &[RunFigures]) {
    let ok: Vec<&RunFigures> = runs.iter().filter(|r| r.diverged.is_none()).collect();
    let n = ok.len() as f64;
    let mean = |g: fn(&RunFigures) -> f64| ok.iter().map(|r| g(r)).sum::<f64>() / n;
    let steps: usize = runs.iter().map(|r| r.steps).sum();
    let diverged: Vec<usize> = runs.iter().filter_map(|r| r.diverged).collect();
    let verdict = if diverged.is_empty() {
        "all bounded".to_string()
    } else {
        format!(
            "DIVERGED in {} of {} runs (earliest at t = {})",
            diverged.len(),
            runs.len(),
            diverged.iter().min().copied().unwrap_or(0)
        )
    };
    if ok.is_empty() {
        println!(
            "  {name:<10} completed {:>3}/{}  {verdict}: no error statistics",
            runs.iter().filter(|r| r.completed).count(),
            runs.len()
        );
        return;
    }
    println!(
        "  {name:<10} completed {:>3}/{}  {verdict}  over the {} bounded runs: mean ‖e‖ {:.5}  tail ‖e‖ {:.5}  x ∉ 𝒳 {:.2} % of steps  max x̂ violation {:.1e}  MPC infeasible {} of {steps} steps",
        runs.iter().filter(|r| r.completed).count(),
        runs.len(),
        ok.len(),
        mean(|r| r.mean_e),
        mean(|r| r.tail_e),
        100.0 * runs.iter().map(|r| r.x_outside).sum::<usize>() as f64 / steps.max(1) as f64,
        runs.iter().map(|r| r.xhat_violation).fold(0.0, f64::max),
        runs.iter().map(|r| r.infeasible).sum::<usize>(),
    );
}

/// Whether the loop stopped before T: a step error (a non-finite signal, or a component
/// that failed). The bounded rule then reports the run diverged at that step.
fn stopped_early<E, C, D>(cl: &ClosedLoop<E, C, D>) -> bool
where
    E: mhe_core::Estimator,
    C: mpc_core::Controller,
    D: lti_model::disturbance::Disturbance,
{
    cl.t() < cl.steps()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let runs: u64 = args.last().and_then(|a| a.parse().ok()).unwrap_or(200);
    let files: Vec<&String> = args.iter().filter(|a| a.ends_with(".toml")).collect();
    for path in files {
        let t0 = std::time::Instant::now();
        let resolved = Scenario::from_file(path)?.resolve()?;
        let sc = resolved.scenario();
        let base = LoopOptions::from_scenario(sc)?;
        let (lo, hi) = (sc.sets.state.lower(), sc.sets.state.upper());
        let mhe_cfg = resolved.mhe_config()?;
        let spec = sc.mhe.as_ref().ok_or("the scenario has no [mhe]")?;
        println!(
            "{path}: {runs} seeds, T = {}, MHE {} K = {}, the same controller and disturbances in both rows",
            base.steps, base.method, base.iterations
        );
        let results: Vec<Result<(RunFigures, RunFigures), String>> = (0..runs)
            .into_par_iter()
            .map(|seed| {
                let mut o = base;
                o.seed = seed;
                let mut mhe_loop = resolved.build_loop(&o).map_err(|e| e.to_string())?;
                let mhe_run = mhe_loop.run().map(|_| ());
                let mhe = figures(
                    mhe_loop.trace(),
                    &sc.simulation.x0,
                    lo,
                    hi,
                    mhe_run.is_ok(),
                    stopped_early(&mhe_loop),
                );
                let kf = KalmanFilter::matching_mhe(
                    &sc.plant,
                    &sc.simulation.prior,
                    spec.eta(),
                    &mhe_cfg.p,
                    &mhe_cfg.q,
                    &mhe_cfg.r,
                )
                .map_err(|e| e.to_string())?;
                let mut kf_loop = ClosedLoop::new(
                    sc.plant.clone(),
                    kf,
                    resolved
                        .controller(o.controller)
                        .map_err(|e| e.to_string())?,
                    scenario_disturbance(sc, seed).map_err(|e| e.to_string())?,
                    &sc.simulation.x0,
                    o.steps,
                )
                .map_err(|e| e.to_string())?;
                let kf_run = kf_loop.run().map(|_| ());
                let kalman = figures(
                    kf_loop.trace(),
                    &sc.simulation.x0,
                    lo,
                    hi,
                    kf_run.is_ok(),
                    stopped_early(&kf_loop),
                );
                Ok((mhe, kalman))
            })
            .collect();
        let mut mhe = Vec::new();
        let mut kalman = Vec::new();
        for r in results {
            let (m, k) = r?;
            mhe.push(m);
            kalman.push(k);
        }
        summarise("MHE", &mhe);
        summarise("Kalman", &kalman);
        // A diverged run loses the comparison; two diverged runs are a tie (not counted).
        let wins = mhe
            .iter()
            .zip(&kalman)
            .filter(|(m, k)| match (m.diverged, k.diverged) {
                (None, None) => m.mean_e < k.mean_e,
                (None, Some(_)) => true,
                _ => false,
            })
            .count();
        println!(
            "  MHE's mean ‖e‖ below the Kalman filter's on {wins} of {runs} seeds (a diverged run loses)  [{:.1?}]",
            t0.elapsed()
        );
    }
    Ok(())
}
