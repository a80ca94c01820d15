//! One simulation of Alg. 1 as `reproduce` records it: the run at a K with its summary and
//! trace, and the Kalman baseline on the same inputs and outputs.

use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario};
use closed_loop::{ClosedLoopError, Trace};
use iss_certificate::plan::KSource;
use qp_iter::Method;

use crate::{Observer, ReportError};

/// A simulated run with its Kalman baseline.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Run {
    /// What it did.
    pub summary: RunSummary,
    /// Every step.
    pub trace: Trace,
    /// The Kalman baseline on the same u_t, y_t (None when it could not be built).
    pub kalman: Option<closed_loop::baseline::BaselineRun>,
}

/// What one simulation did.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RunSummary {
    /// Short name (`"K=652"`).
    pub label: String,
    /// Iterations K of Φ per step.
    pub k: usize,
    /// Why this K.
    pub k_source: KSource,
    /// Φ of the MHE.
    pub solver: String,
    /// `"exact MPC"`, or `"MPC <method> with K_c = <K_c>"` for the K-iteration MPC.
    pub controller: String,
    /// ε_t recorded (exact MHE solve on).
    pub exact_mhe_solve: bool,
    /// Disturbance seed.
    pub seed: u64,
    /// T requested.
    pub steps: usize,
    /// Steps completed (< T only after an error).
    pub completed: usize,
    /// The step error, if the run stopped early (e.g. a diverged loop).
    pub error: Option<String>,
    /// The run left the bounded rule ([`closed_loop::bounded`], the sweep's: ‖e‖, ‖x‖, ε
    /// within 1000 times their initial scale, u finite) or stopped on a non-finite signal.
    pub diverged: bool,
    /// The first step at which it did (None when bounded).
    pub diverged_at: Option<usize>,
    /// The signal that failed first there: `"e"`, `"x"`, `"epsilon"` or `"u"`.
    pub signal: Option<closed_loop::bounded::Signal>,
    /// The failure itself: t, signal, value, the limit, and whether the loop stopped there
    /// (None when bounded).
    pub divergence: Option<closed_loop::bounded::Divergence>,
    /// Steps at which the MPC was infeasible (state constraints) and applied its fallback
    /// (`trace.csv` has the status per step).
    pub mpc_infeasible_steps: usize,
    /// sup_t ‖e_t‖.
    pub sup_norm_e: f64,
    /// sup_t ‖x_t‖.
    pub sup_norm_x: f64,
    /// ‖x_T‖.
    pub final_norm_x: f64,
    /// Mean ‖e_t‖ over the last quarter.
    pub tail_mean_e: Option<f64>,
    /// Mean ‖x_t‖ over the last quarter.
    pub tail_mean_x: Option<f64>,
    /// Mean ε_t over the last quarter.
    pub tail_mean_epsilon: Option<f64>,
    /// Steps whose simulated draw w_t lies outside 𝒲 (`sets.disturbance`, the set the MHE
    /// and the certificate assume): the ISS statement is not claimed from the first of them
    /// on (`closed_loop::scenario::draws_outside`).
    pub w_outside: usize,
    /// The first such step.
    pub w_outside_first: Option<usize>,
    /// The Kalman filter of the MHE's weights on the same u_t, y_t
    /// (`closed_loop::baseline::kalman_for_mhe`); None when it could not be built (the
    /// reason is in `kalman_error`).
    pub kalman: Option<KalmanSummary>,
}

/// The Kalman baseline of one run (`closed_loop::baseline`).
#[derive(Debug, Clone, Default)]
#[non_exhaustive]
pub struct KalmanSummary {
    /// `"standard, Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹, Σ_v = R⁻¹"`.
    pub weights: String,
    /// Steps filtered.
    pub completed: usize,
    /// sup_t ‖x_t − x̂^KF_t‖.
    pub sup_norm_e: Option<f64>,
    /// Mean ‖x_t − x̂^KF_t‖ over the last quarter.
    pub tail_mean_e: Option<f64>,
    /// The filter left the bounded rule (signal e) or stopped.
    pub diverged: bool,
    /// Where, if it did.
    pub divergence: Option<closed_loop::bounded::Divergence>,
    /// The filter's error (construction or update), if any.
    pub error: Option<String>,
}

/// The Kalman filter of the MHE's weights run on `trace` (module `closed_loop::baseline`).
/// A trace shorter than `simulation.steps` (the run stopped early) has no tail: the
/// filter's `tail_mean_e` is then `None` (issue 37 item 9), not the mean of a cut run.
pub fn kalman_baseline(
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
                sup_norm_e: None,
                tail_mean_e: None,
                diverged: false,
                divergence: None,
                error: Some(format!("not built: {e}")),
            }),
        ),
    }
}

/// Simulates at K = `k` step by step, telling `observer` the progress.
pub(crate) fn simulate(
    resolved: &ResolvedScenario,
    solver: Method,
    k: usize,
    controller: ControllerChoice,
    source: KSource,
    observer: &dyn Observer,
) -> Result<Run, ReportError> {
    let scenario = resolved.scenario();
    let opts = LoopOptions {
        method: solver,
        iterations: qp_iter::Iterations::ONE,
        exact_mhe_solve: true,
        controller,
        seed: scenario.noise.seed,
        steps: scenario.simulation.steps,
    }
    .with_iterations(k)
    .map_err(|source| ReportError::Loop { k, source })?;
    let mut cl = resolved
        .build_loop(&opts)
        .map_err(|source| ReportError::Loop { k, source })?;
    // Step by step (as `run` does) so that progress can be shown; the first step error stops
    // the run and is its result.
    observer.simulation_started(&format!("{} K = {k}", solver.name()), opts.steps);
    let mut error = None;
    let mut stopped_non_finite = false;
    while cl.t() < cl.steps() {
        if let Err(e) = cl.step() {
            stopped_non_finite = matches!(e, ClosedLoopError::NonFinite { .. });
            error = Some(e.to_string());
            break;
        }
        observer.simulation_progress(cl.t());
    }
    observer.simulation_finished();
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
