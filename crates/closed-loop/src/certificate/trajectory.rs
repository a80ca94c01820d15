//! The certificate against a simulated trace: the inequalities of Props. 1 and 3 with the
//! reported constants.

use serde::Serialize;

use super::*;
use crate::analysis::IssInputs;
use crate::record::Trace;

/// Result of [`check_trajectory`] for one proposition.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InequalityCheck {
    /// The inequality held at every t.
    pub holds: bool,
    /// max over t ≥ 1 of lhs/rhs (≤ 1 when it holds; t = 0 is trivially tight for Prop. 1).
    pub worst_ratio: f64,
    /// Time of the worst ratio.
    pub worst_t: usize,
    /// First t where it failed, if any.
    pub first_violation: Option<usize>,
}

impl InequalityCheck {
    /// Nothing evaluated yet (holds vacuously).
    pub fn new() -> Self {
        Self {
            holds: true,
            worst_ratio: 0.0,
            worst_t: 0,
            first_violation: None,
        }
    }

    /// Evaluates lhs ≤ rhs at t (relative tolerance 1e-12 for rounding; NaN fails). t = 0
    /// is checked but never the worst ratio (it is an identity or trivially tight).
    pub fn record(&mut self, t: usize, lhs: f64, rhs: f64) {
        let ratio = if rhs > 0.0 {
            lhs / rhs
        } else if lhs > 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
        if t > 0 && ratio > self.worst_ratio {
            self.worst_ratio = ratio;
            self.worst_t = t;
        }
        let tol = rhs.abs() * 1e-12 + 1e-14;
        if (lhs > rhs + tol || lhs.is_nan() || rhs.is_nan()) && self.first_violation.is_none() {
            self.holds = false;
            self.first_violation = Some(t);
        }
    }
}

impl Default for InequalityCheck {
    fn default() -> Self {
        Self::new()
    }
}

/// Prop. 1 and Prop. 3 evaluated on a trace.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrajectoryCheck {
    /// ‖ε_t‖ ≤ φᵗε₀ + γ₂,₁‖x‖ + γ₂,₃‖e‖ + γ₂ʷ‖w‖ + γ₂^σ‖σ‖ (sups over [0, t−1]; σ over
    /// [0, t], the data-dependent σ_t of [`super::lemma1`]).
    pub prop1: InequalityCheck,
    /// ‖e_t‖ ≤ C_e√ρᵗ‖e₀‖ + √(2Λ^H̄_P)C₁‖x‖ + C_ε‖ε‖ + C_w‖w‖ + √(2Λ^H̄_P)φL_Φ‖σ‖.
    pub prop3: InequalityCheck,
}

/// Evaluates the trajectory inequalities of Props. 1 and 3 at budget `k` with the constants
/// of `analysis` (from the certificate) on a trace recorded with the exact MHE solve on.
///
/// Returns `None` when the trace has no ε_t (exact solve off).
pub fn check_trajectory(
    cert: &ClosedLoopCertificate,
    analysis: &IssAnalysis,
    k: usize,
    trace: &Trace,
) -> Option<TrajectoryCheck> {
    let eps: Vec<f64> = trace.epsilons().collect::<Option<Vec<f64>>>()?;
    let g = analysis.at(k);
    let n = trace.len().min(eps.len());
    let (xs, es, ws) = (trace.x_norms(), trace.e_norms(), trace.w_norms());
    let sqrt_rho = analysis.rho.sqrt();
    let a = (2.0 * analysis.lambda_hp).sqrt();
    let mut p1 = InequalityCheck::new();
    let mut p3 = InequalityCheck::new();
    let (mut sx, mut se, mut sw, mut seps, mut ssig) =
        (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    for t in 0..n {
        if t > 0 {
            sx = sx.max(xs[t - 1]);
            se = se.max(es[t - 1]);
            sw = sw.max(ws[t - 1]);
            seps = seps.max(eps[t - 1]);
        }
        // σ_t of the mended Lemma 1 enters at step t itself (Prop. 1, Case 1).
        ssig = ssig.max(super::lemma1::sigma(
            trace,
            t,
            &cert.lemma1_origin_offsets,
            analysis.l_phi_used,
        )?);
        let ti = i32::try_from(t).unwrap_or(i32::MAX);
        let rhs1 = g.phi.powi(ti) * eps[0]
            + g.gamma21 * sx
            + g.gamma23 * se
            + g.gamma2w * sw
            + g.gamma2sigma * ssig;
        p1.record(t, eps[t], rhs1);
        let rhs3 = g.c_e * sqrt_rho.powi(ti) * es[0]
            + a * g.c1 * sx
            + g.c_eps * seps
            + g.c_w * sw
            + g.gamma3sigma * ssig;
        p3.record(t, es[t], rhs3);
    }
    Some(TrajectoryCheck {
        prop1: p1,
        prop3: p3,
    })
}

/// The analysis with L_Φ replaced by the sampled estimate (for the "sampled L_Φ" check).
pub fn analysis_with_sampled_l_phi(
    cert: &ClosedLoopCertificate,
    solver: &SolverCertificate,
) -> IssAnalysis {
    IssAnalysis::new(IssInputs {
        l_phi: cert.l_phi.sampled,
        ..solver.analysis.inputs.clone()
    })
}
