//! One simulation of Alg. 1 as `reproduce` records it: the run at a K with its summary and
//! trace, and the Kalman baseline on the same inputs and outputs.

use super::*;

/// A simulated run with its Kalman baseline.
pub(super) struct Run {
    pub(super) summary: RunSummary,
    pub(super) trace: Trace,
    /// The Kalman baseline on the same u_t, y_t (None when it could not be built).
    pub(super) kalman: Option<closed_loop::baseline::BaselineRun>,
}

/// The Kalman filter of the MHE's weights run on `trace` (module `closed_loop::baseline`).
/// A trace shorter than `simulation.steps` (the run stopped early) has no tail: the
/// filter's `tail_mean_e` is then `None` (issue 37 item 9), not the mean of a cut run.
pub(super) fn kalman_baseline(
    resolved: &ResolvedScenario,
    trace: &Trace,
) -> (
    Option<closed_loop::baseline::BaselineRun>,
    Option<KalmanSummary>,
) {
    let scenario = resolved.scenario();
    let weights = "standard (λ = 1), Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹, Σ_v = R⁻¹".to_string();
    let built = resolved
        .mhe_config()
        .map_err(|e| e.to_string())
        .and_then(|cfg| {
            closed_loop::baseline::kalman_for_mhe(
                &scenario.plant,
                &scenario.simulation.prior,
                &cfg.p,
                &cfg.q,
                &cfg.r,
            )
            .map_err(|e| e.to_string())
        });
    match built {
        Ok(mut kf) => {
            let run = closed_loop::baseline::run_on_trace(&mut kf, trace);
            let full = trace.len() >= scenario.simulation.steps;
            let summary = KalmanSummary {
                weights,
                completed: run.e_norms.len(),
                sup_norm_e: run.sup_norm_e(),
                tail_mean_e: run.tail_mean_e().filter(|_| full),
                diverged: run.diverged(),
                divergence: run.divergence,
                error: run.error.clone(),
            };
            (Some(run), Some(summary))
        }
        Err(e) => (
            None,
            Some(KalmanSummary {
                weights,
                completed: 0,
                sup_norm_e: f64::NAN,
                tail_mean_e: None,
                diverged: false,
                divergence: None,
                error: Some(format!("not built: {e}")),
            }),
        ),
    }
}

/// Simulates at K = `k` step by step, with [`work::Progress`] on stderr when `live`.
pub(super) fn simulate(
    resolved: &ResolvedScenario,
    solver: Method,
    k: usize,
    controller: ControllerChoice,
    source: KSource,
    live: bool,
) -> Result<Run> {
    let scenario = resolved.scenario();
    let opts = LoopOptions {
        method: solver,
        iterations: k,
        exact_mhe_solve: true,
        controller,
        seed: scenario.noise.seed,
        steps: scenario.simulation.steps,
    };
    let mut cl = resolved
        .build_loop(&opts)
        .with_context(|| format!("cannot set up the closed loop at K = {k}"))?;
    // Step by step (as `run` does) so that progress can be shown; the first step error stops
    // the run and is its result.
    let mut progress = work::Progress::new(format!("{} K = {k}", solver.name()), opts.steps, live);
    let mut error = None;
    let mut stopped_non_finite = false;
    while cl.t() < cl.steps() {
        if let Err(e) = cl.step() {
            stopped_non_finite = matches!(e, ClosedLoopError::NonFinite { .. });
            error = Some(e.to_string());
            break;
        }
        progress.update(cl.t());
    }
    progress.finish();
    let trace = cl.into_trace();
    let len = trace.len();
    let outside = closed_loop::scenario::draws_outside(&trace, &scenario.sets.disturbance);
    let (kalman, kalman_summary) = kalman_baseline(resolved, &trace);
    // The sweep's bounded rule, applied by the library to this run.
    let divergence = closed_loop::bounded::first_unbounded(
        &trace,
        &scenario.simulation.x0,
        closed_loop::bounded::DEFAULT_BOUNDED_FACTOR,
        stopped_non_finite,
    );
    let summary = RunSummary {
        label: format!("K={k}"),
        k,
        k_source: source,
        solver: solver.name().to_string(),
        controller: match controller {
            ControllerChoice::SuboptimalMpc { iterations, method } => {
                format!("MPC {method} with K_c = {iterations}")
            }
            _ => "exact MPC".into(),
        },
        exact_mhe_solve: true,
        seed: opts.seed,
        steps: opts.steps,
        completed: len,
        error,
        diverged: divergence.is_some(),
        diverged_at: divergence.map(|d| d.t),
        signal: divergence.map(|d| d.signal),
        divergence,
        mpc_infeasible_steps: trace.infeasible_steps().count(),
        sup_norm_e: trace.sup_norm_e(),
        sup_norm_x: trace.sup_norm_x(),
        final_norm_x: trace.x_norms().last().copied().unwrap_or(f64::NAN),
        // A run that stopped early has no tail (its last quarter is not the steady state).
        tail_mean_e: trace.tail_mean_e().filter(|_| len >= opts.steps),
        tail_mean_x: trace.tail_mean_x().filter(|_| len >= opts.steps),
        tail_mean_epsilon: trace.tail_mean_epsilon().filter(|_| len >= opts.steps),
        w_outside: outside.len(),
        w_outside_first: outside.first().copied(),
        kalman: kalman_summary,
    };
    Ok(Run {
        summary,
        trace,
        kalman,
    })
}
