//! The certificate against a simulated trace: the inequalities of Props. 1 and 3 with the
//! reported constants.

#[cfg(feature = "serde")]
use serde::Serialize;

use super::*;
use crate::analysis::IssInputs;
use closed_loop::record::Trace;

/// Result of [`check_trajectory`] for one proposition.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct InequalityCheck {
    /// The inequality held at every t.
    pub holds: bool,
    /// max over t ≥ 1 of lhs/rhs (≤ 1 when it holds; t = 0 is trivially tight for Prop. 1).
    pub worst_ratio: f64,
    /// Time of the worst ratio.
    pub worst_t: usize,
    /// First t where it failed, if any.
    pub first_violation: Option<usize>,
    /// Steps at which lhs exceeded rhs but not rhs + the rounding floor
    /// ([`super::rounding_floor`]): the measured side was floating-point rounding there.
    pub within_rounding_floor: usize,
    /// Largest rounding floor used at such a step (0 when none).
    pub max_rounding_floor: f64,
}

impl InequalityCheck {
    /// Nothing evaluated yet (holds vacuously).
    pub fn new() -> Self {
        Self {
            holds: true,
            worst_ratio: 0.0,
            worst_t: 0,
            first_violation: None,
            within_rounding_floor: 0,
            max_rounding_floor: 0.0,
        }
    }

    /// Evaluates lhs ≤ rhs at t (relative tolerance 1e-12 for rounding; NaN fails). t = 0
    /// is checked but never the worst ratio (it is an identity or trivially tight).
    pub fn record(&mut self, t: usize, lhs: f64, rhs: f64) {
        self.record_with_floor(t, lhs, rhs, 0.0);
    }

    /// [`InequalityCheck::record`] with a rounding floor (`floor` ≥ 0, [`super::rounding_floor`]):
    /// lhs ≤ rhs + floor holds; a step that needs the floor is counted, and a step with
    /// lhs > rhs + floor is a violation.
    pub fn record_with_floor(&mut self, t: usize, lhs: f64, rhs: f64, floor: f64) {
        let floor = if floor.is_finite() && floor > 0.0 {
            floor
        } else {
            0.0
        };
        let tol = |r: f64| r.abs() * 1e-12 + 1e-14;
        if floor > 0.0 && lhs > rhs + tol(rhs) && lhs <= rhs + floor + tol(rhs + floor) {
            self.within_rounding_floor += 1;
            self.max_rounding_floor = self.max_rounding_floor.max(floor);
        }
        // The floor is part of the right-hand side: the ratio is lhs/(rhs + floor).
        self.record_plain(t, lhs, rhs + floor);
    }

    fn record_plain(&mut self, t: usize, lhs: f64, rhs: f64) {
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
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct TrajectoryCheck {
    /// ‖ε_t‖ ≤ φᵗε₀ + γ₂,₁‖x‖ + γ₂,₃‖e‖ + γ₂ʷ‖w‖ + γ₂^σ‖σ‖ (sups over [0, t−1]; σ over
    /// [0, t], the data-dependent σ_t of [`super::lemma1`]).
    pub prop1: InequalityCheck,
    /// ‖e_t‖ ≤ C_e√ρᵗ‖e₀‖ + √(2Λ^H̄_P)C₁‖x‖ + C_ε‖ε‖ + C_w‖w‖ + √(2Λ^H̄_P)φL_Φ‖σ‖.
    pub prop3: InequalityCheck,
    /// Where the run first left the bounded rule ([`closed_loop::bounded`]; None: bounded).
    pub divergence: Option<closed_loop::bounded::Divergence>,
}

impl TrajectoryCheck {
    /// Both inequalities held at every t and the run stayed bounded.
    pub fn holds(&self) -> bool {
        self.inequalities_hold() && self.divergence.is_none()
    }

    /// Both inequalities held at every t (beyond the rounding floor): the one question whose
    /// "no" contradicts the certificate (`reproduce` exit code 3). A divergence is a separate
    /// verdict (exit code 4), not a violated inequality.
    pub fn inequalities_hold(&self) -> bool {
        self.prop1.holds && self.prop3.holds
    }
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
        let (floor_eps, floor_e) = super::rounding::rounding_floor(trace, t, k);
        p1.record_with_floor(t, eps[t], rhs1, floor_eps);
        let rhs3 = g.c_e * sqrt_rho.powi(ti) * es[0]
            + a * g.c1 * sx
            + g.c_eps * seps
            + g.c_w * sw
            + g.gamma3sigma * ssig;
        p3.record_with_floor(t, es[t], rhs3, floor_e);
    }
    let divergence = trace.x(0).and_then(|x0| {
        closed_loop::bounded::first_unbounded(
            trace,
            x0,
            closed_loop::bounded::DEFAULT_BOUNDED_FACTOR,
            false,
        )
    });
    Some(TrajectoryCheck {
        prop1: p1,
        prop3: p3,
        divergence,
    })
}

/// The analysis with L_Φ replaced by the sampled estimate (for the "sampled L_Φ" check).
pub fn analysis_with_sampled_l_phi(
    cert: &ClosedLoopCertificate,
    solver: &SolverCertificate,
) -> IssAnalysis {
    IssAnalysis::new(IssInputs {
        l_phi: cert.l_phi.sampled.unwrap_or(f64::NAN),
        ..solver.analysis.inputs.clone()
    })
}
