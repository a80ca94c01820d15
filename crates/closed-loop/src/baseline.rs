//! A baseline estimator run beside the MHE on the same data: the Kalman filter of the same
//! weights (or any [`Estimator`]) filters the u_t, y_t of a recorded closed-loop run.
//!
//! The baseline does not close the loop: it sees exactly the inputs and measurements the
//! MHE saw (the same disturbance draws, the same plant trajectory), so its error
//! e^b_t = x_t − x̂^b_t is comparable with the MHE's step by step. Its run is judged by the
//! one bounded rule ([`crate::bounded`], signal e): a filter whose error leaves
//! 1000·(1 + ‖e^b_0‖ + w̄_t) (w̄_t = max_{s ≤ t} ‖w_s‖ of the recorded draws), or becomes
//! non-finite, or whose update fails, is reported as diverged.
//!
//! **The Kalman filter of the MHE's weights** ([`kalman_for_mhe`]). The MHE cost (9) is
//! 2η^{M_t}‖x̂ − x̄‖²_P + Σ_i η^{i−1}(2‖ŵ‖²_Q + ‖ŷ − y‖²_R); read as −2 log of a Gaussian
//! posterior (the weight of a quadratic is the inverse covariance), it is the model
//! x₀ ~ N(x̄₀, (2P)⁻¹), w ~ N(0, (2Q)⁻¹), y = Cx + Fw² + v with v ~ N(0, R⁻¹), discounted by
//! η. The baseline is the *standard* (λ = 1, time-varying gain) filter of that model:
//! Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹, Σ_v = R⁻¹ — what a user compares an MHE with.
//! `mhe_core::KalmanFilter::matching_mhe` is its fading-memory twin (λ = η), which equals
//! the unconstrained MHE for t ≤ M (tests of `mhe-core`).

use faer::Mat;
use faer::linalg::solvers::DenseSolveCore;
use lti_model::LtiSystem;
use mhe_core::{Estimator, KalmanFilter, MheError};
#[cfg(feature = "serde")]
use serde::Serialize;

use crate::bounded::{DEFAULT_BOUNDED_FACTOR, Divergence, first_unbounded_in};
use crate::record::{Trace, norm2};

/// A baseline estimator's run over a recorded trace.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct BaselineRun {
    /// x̂^b_t per step (t = 0..completed), each n_x long.
    pub x_hat: Vec<Vec<f64>>,
    /// ‖x_t − x̂^b_t‖ per step.
    pub e_norms: Vec<f64>,
    /// The estimator's error, if an estimate or an update failed (the run stops there).
    pub error: Option<String>,
    /// Where the bounded rule (signal e) failed first, if it did.
    pub divergence: Option<Divergence>,
}

impl BaselineRun {
    /// Diverged: the bounded rule failed or the estimator stopped.
    pub fn diverged(&self) -> bool {
        self.divergence.is_some()
    }
    /// sup_t ‖e^b_t‖ over the steps whose error is a number (None for an empty run; a NaN
    /// step is skipped: `divergence` names where the filter failed).
    pub fn sup_norm_e(&self) -> Option<f64> {
        self.e_norms.iter().copied().reduce(f64::max)
    }
    /// Mean ‖e^b_t‖ over the last quarter of the steps (as [`Trace::tail_mean_e`]).
    pub fn tail_mean_e(&self) -> Option<f64> {
        let n = self.e_norms.len();
        let start = n - n / 4;
        (n > 0 && start < n).then(|| {
            let tail = &self.e_norms[start..];
            tail.iter().sum::<f64>() / tail.len() as f64
        })
    }
}

/// Runs `est` over the inputs and measurements of `trace`: at each recorded t,
/// x̂^b_t = `est.estimate()`, then `est.push(u_t, y_t)`. The bounded rule's scale is the
/// baseline's own ‖e^b_0‖ and the run's disturbance w̄_t. Allocates the result only (the estimator's step is its own).
pub fn run_on_trace<E: Estimator>(est: &mut E, trace: &Trace) -> BaselineRun {
    let mut x_hat = Vec::with_capacity(trace.len());
    let mut e_norms = Vec::with_capacity(trace.len());
    let mut error = None;
    for t in 0..trace.len() {
        let (Some(x), Some(u), Some(y)) = (trace.x(t), trace.u(t), trace.y(t)) else {
            break;
        };
        match est.estimate() {
            Ok(xh) => {
                let e: Vec<f64> = x.iter().zip(xh).map(|(a, b)| a - b).collect();
                e_norms.push(norm2(&e));
                x_hat.push(xh.to_vec());
            }
            Err(e) => {
                error = Some(format!("t = {t}: {e}"));
                break;
            }
        }
        if let Err(e) = est.push(u, y) {
            error = Some(format!("t = {t}: {e}"));
            break;
        }
    }
    let e0 = e_norms.first().copied().unwrap_or(0.0);
    let stopped = error.is_some();
    let divergence = first_unbounded_in(
        &e_norms,
        &[],
        &[],
        &[],
        trace.w_norms(),
        if e0.is_finite() { e0 } else { 0.0 },
        0.0,
        DEFAULT_BOUNDED_FACTOR,
        stopped,
    );
    BaselineRun {
        x_hat,
        e_norms,
        error,
        divergence,
    }
}

/// The standard Kalman filter of the MHE's weights (module docs): prior x̄₀ = `prior`,
/// Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹, Σ_v = R⁻¹, λ = 1.
///
/// Errors: P, Q, R not symmetric positive definite or of the wrong size (naming them).
pub fn kalman_for_mhe(
    sys: &LtiSystem,
    prior: &[f64],
    p: &Mat<f64>,
    q: &Mat<f64>,
    r: &Mat<f64>,
) -> Result<KalmanFilter, MheError> {
    let nw = sys.nw();
    lti_model::matrix::check_positive_definite("P", p.as_ref(), sys.nx())?;
    lti_model::matrix::check_positive_definite("Q", q.as_ref(), nw)?;
    lti_model::matrix::check_positive_definite("R", r.as_ref(), sys.ny())?;
    let inv = |m: &Mat<f64>, scale: f64| -> Mat<f64> {
        let x = m.partial_piv_lu().inverse();
        let n = m.nrows();
        Mat::from_fn(n, n, |i, j| 0.5 * (x[(i, j)] + x[(j, i)]) / scale)
    };
    KalmanFilter::new(sys, prior, inv(p, 2.0), inv(q, 2.0), inv(r, 1.0))
}
