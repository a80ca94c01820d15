//! The per-step records of one run in `trace.json` (`runs[i].trace`): this schema's own
//! types, filled from [`closed_loop::Trace`]'s accessors, so the library's trace can grow
//! (or change its storage) without changing the file. The keys and their order are those
//! the library's former serialisation wrote (pinned by a test against it).

use closed_loop::Trace;
use closed_loop::record::MheStep;
use serde::Serialize;

/// n_x, n_u, n_y, dim w¹, dim w² of the run's plant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct TraceDims {
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
    /// n_y.
    pub ny: usize,
    /// dim w¹.
    pub nw1: usize,
    /// dim w².
    pub nw2: usize,
}

/// The run's statistics over its recorded steps ([`closed_loop::Trace`]'s methods of the
/// same names).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TraceSummary {
    /// sup_t ‖e_t‖.
    pub sup_norm_e: f64,
    /// sup_t ‖x_t‖ (x_T included).
    pub sup_norm_x: f64,
    /// sup_t ‖w_t‖.
    pub sup_norm_w: f64,
    /// Mean ‖e_t‖ over the last quarter.
    pub tail_mean_e: Option<f64>,
    /// Mean ‖x_t‖ over the last quarter.
    pub tail_mean_x: Option<f64>,
    /// Mean ‖w_t‖ over the last quarter.
    pub tail_mean_w: Option<f64>,
    /// Mean ε_t over the last quarter (steps with ε_t).
    pub tail_mean_epsilon: Option<f64>,
}

/// The estimator's record of one step (`mhe_core::MheRecord`'s quantities); stage j of a
/// window is time t − M_t + j, sequences are arrays of stages, oldest first.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MheStepRecord<'a> {
    /// t.
    pub t: usize,
    /// M_t.
    pub window: usize,
    /// The prior x̄_{t−M_t}.
    pub prior: &'a [f64],
    /// u over the window.
    pub u: Vec<&'a [f64]>,
    /// y over the window.
    pub y: Vec<&'a [f64]>,
    /// x̂ᴷ_{t−M_t|t}.
    pub x_start_k: &'a [f64],
    /// ŵᴷ = (ŵ¹, ŵ²) over the window.
    pub w_k: Vec<&'a [f64]>,
    /// x̂ᴷ_{t|t}.
    pub x_hat: &'a [f64],
    /// x̂*_{t−M_t|t} (exact solve on).
    pub x_start_exact: Option<&'a [f64]>,
    /// ŵ* over the window (exact solve on).
    pub w_exact: Option<Vec<&'a [f64]>>,
    /// x̂*_{t|t} (exact solve on).
    pub x_hat_exact: Option<&'a [f64]>,
    /// ε_t = ‖zᴷ_t − z*_t‖₂ (exact solve on).
    pub epsilon: Option<f64>,
    /// ‖z⁰_t − z*_t‖₂ (exact solve on).
    pub initial_error: Option<f64>,
    /// The cost (9) at the K-th iterate.
    pub cost_k: f64,
    /// The cost at the exact optimum (exact solve on).
    pub cost_exact: Option<f64>,
    /// The K-th iterate's largest constraint violation.
    pub violation: f64,
    /// Iterations run.
    pub iterations: usize,
    /// How the iteration ended (`completed`, `converged`, `max_iterations`, `non_finite`, …).
    pub status: &'static str,
}

/// A flat sequence of `width`-long stages as an array of stages (none when `width` is 0).
fn stages(v: &[f64], width: usize) -> Vec<&[f64]> {
    if width == 0 {
        Vec::new()
    } else {
        v.chunks_exact(width).collect()
    }
}

impl<'a> MheStepRecord<'a> {
    /// The record of `s`, whose plant has n_u = `nu`, n_y = `ny` and dim w = `nw` (the
    /// widths of its window's stages).
    fn new(s: MheStep<'a>, (nu, ny, nw): (usize, usize, usize)) -> Self {
        Self {
            t: s.t(),
            window: s.window(),
            prior: s.prior(),
            u: stages(s.u_flat(), nu),
            y: stages(s.y_flat(), ny),
            x_start_k: s.x_start_k(),
            w_k: stages(s.w_k_flat(), nw),
            x_hat: s.x_hat(),
            x_start_exact: s.x_start_exact(),
            w_exact: s.w_exact_flat().map(|w| stages(w, nw)),
            x_hat_exact: s.x_hat_exact(),
            epsilon: s.epsilon(),
            initial_error: s.initial_error(),
            cost_k: s.cost_k(),
            cost_exact: s.cost_exact(),
            violation: s.violation(),
            iterations: s.iterations(),
            status: s.status().name(),
        }
    }
}

/// One step t of a run: the plant's signals, the estimate, the error and the MHE record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepRecord<'a> {
    /// t.
    pub t: usize,
    /// x_t.
    pub x: &'a [f64],
    /// u_t.
    pub u: &'a [f64],
    /// y_t.
    pub y: &'a [f64],
    /// w_t = (w¹_t, w²_t).
    pub w: &'a [f64],
    /// x̂_t.
    pub x_hat: &'a [f64],
    /// e_t = x̂_t − x_t.
    pub e: &'a [f64],
    /// ‖e_t‖₂.
    pub e_norm: f64,
    /// ‖x_t‖₂.
    pub x_norm: f64,
    /// ‖w_t‖₂.
    pub w_norm: f64,
    /// The estimator's record (null when the loop did not capture one).
    pub mhe: Option<MheStepRecord<'a>>,
}

/// `runs[i].trace` of trace.json: one run's dimensions, statistics, final state and steps.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TraceRecord<'a> {
    /// The plant's dimensions.
    pub dims: TraceDims,
    /// The horizon T the run was built for.
    pub steps: usize,
    /// Steps completed (≤ T; fewer when the run stopped on an error).
    pub len: usize,
    /// Statistics over the completed steps.
    pub summary: TraceSummary,
    /// x_len, the state after the last step.
    pub x_final: &'a [f64],
    /// Steps 0..len.
    pub records: Vec<StepRecord<'a>>,
}

impl<'a> From<&'a Trace> for TraceRecord<'a> {
    fn from(tr: &'a Trace) -> Self {
        let (nx, nu, ny, nw) = tr.dims();
        let nw1 = tr.nw1();
        let row = |v: Option<&'a [f64]>| v.unwrap_or(&[]);
        let widths = tr.mhe().map(|m| {
            let d = m.dims();
            (d.nu, d.ny, d.nw())
        });
        let records = (0..tr.len())
            .map(|t| StepRecord {
                t,
                x: row(tr.x(t)),
                u: row(tr.u(t)),
                y: row(tr.y(t)),
                w: row(tr.w(t)),
                x_hat: row(tr.x_hat(t)),
                e: row(tr.e(t)),
                e_norm: tr.e_norms()[t],
                x_norm: tr.x_norms()[t],
                w_norm: tr.w_norms()[t],
                mhe: (tr.mhe_step(t).zip(widths)).map(|(s, w)| MheStepRecord::new(s, w)),
            })
            .collect();
        Self {
            dims: TraceDims {
                nx,
                nu,
                ny,
                nw1,
                nw2: nw - nw1,
            },
            steps: tr.steps(),
            len: tr.len(),
            summary: TraceSummary {
                sup_norm_e: tr.sup_norm_e(),
                sup_norm_x: tr.sup_norm_x(),
                sup_norm_w: tr.sup_norm_w(),
                tail_mean_e: tr.tail_mean_e(),
                tail_mean_x: tr.tail_mean_x(),
                tail_mean_w: tr.tail_mean_w(),
                tail_mean_epsilon: tr.tail_mean_epsilon(),
            },
            x_final: row(tr.x(tr.len())),
            records,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use closed_loop::scenario::{ControllerChoice, LoopOptions, Scenario};

    /// The records write exactly what `closed_loop::Trace`'s serialisation (which trace.json
    /// used before them) writes: the same keys in the same order, the same numbers, with the
    /// exact MHE solve on (every optional field filled) and off (nulls).
    #[test]
    fn records_write_the_bytes_of_the_library_serialisation() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../scenarios/case-study.toml"
        );
        let scenario = Scenario::from_file(path).expect("the case study reads");
        let mut options = LoopOptions::from_scenario(&scenario).expect("it has [mhe]");
        options = options.with_iterations(3).expect("K is in range");
        options.steps = 12;
        options.controller = ControllerChoice::ExactMpc;
        let resolved = scenario.resolve().expect("the case study resolves");
        for exact in [true, false] {
            options.exact_mhe_solve = exact;
            let mut run = resolved.build_loop(&options).expect("the loop builds");
            let trace = run.run().expect("12 steps run");
            assert!(trace.mhe_step(11).is_some_and(|s| s.window() > 1));
            let ours = serde_json::to_string(&TraceRecord::from(trace)).expect("serialises");
            assert_eq!(
                ours,
                trace.to_json().expect("serialises"),
                "exact = {exact}"
            );
        }
    }
}
