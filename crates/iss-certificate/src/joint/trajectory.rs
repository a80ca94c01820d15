//! Every inequality of the joint proof evaluated on a simulated trace, both sides from the
//! trace, with the reported constants (like [`crate::certificate::check_trajectory`]).

#[cfg(feature = "serde")]
use serde::Serialize;

use super::gains::JointAnalysis;
use crate::certificate::{ClosedLoopCertificate, InequalityCheck};
use closed_loop::record::Trace;

/// The four subsystem estimates and the one-step inequality of δ_t on one trace.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct JointTrajectoryCheck {
    /// ‖x_t‖ ≤ β₁(‖x₀‖, t) + γ₁,₃‖e‖ + γ₁,₄‖δ‖ + γ₁ʷ‖w‖ (sups over [0, t−1]).
    pub plant: InequalityCheck,
    /// Prop. 1 with the δ term: ‖ε_t‖ ≤ φ_eᵗε₀ + γ₂,₁‖x‖ + γ₂,₃‖e‖ + γ₂ʷ‖w‖ + γ₂,₄‖δ‖ + γ₂^σ‖σ‖.
    pub prop1: InequalityCheck,
    /// Prop. 3 with the δ term: ‖e_t‖ ≤ C_e√ρᵗ‖e₀‖ + √(2Λ^H̄_P)C₁‖x‖ + C_ε‖ε‖ + C_w‖w‖ + γ₃,₄‖δ‖ + γ₃^σ‖σ‖.
    pub prop3: InequalityCheck,
    /// δ_t ≤ φ_c(ωδ_{t−1} + ωL_U‖x̂_{t−1}‖ + L_U‖x̂_t‖) (t ≥ 1), δ₀ ≤ φ_c L_U‖x̂₀‖.
    pub delta_step: InequalityCheck,
    /// δ_t ≤ (φ_cω)ᵗδ₀ + γ₄,₁ sup_{0…t}‖x‖ + γ₄,₃ sup_{0…t}‖e‖.
    pub delta: InequalityCheck,
    /// max_t ‖u_t − π(x̂_t)‖/δ_t − 1 ≤ 0: the applied input error is bounded by δ_t (d_t is the
    /// first block of Uᴷᶜ_t − U*(x̂_t)).
    pub input_error: InequalityCheck,
    /// Where the run first left the bounded rule ([`closed_loop::bounded`]; None: bounded).
    pub divergence: Option<closed_loop::bounded::Divergence>,
}

impl JointTrajectoryCheck {
    /// Every inequality held at every t and the run stayed bounded.
    pub fn holds(&self) -> bool {
        self.inequalities_hold() && self.divergence.is_none()
    }

    /// Every inequality held at every t (a divergence is a separate verdict, exit code 4).
    pub fn inequalities_hold(&self) -> bool {
        [
            &self.plant,
            &self.prop1,
            &self.prop3,
            &self.delta_step,
            &self.delta,
            &self.input_error,
        ]
        .iter()
        .all(|c| c.holds)
    }
}

/// Evaluates the joint inequalities at (K_e, K_c) on `trace` (recorded with the exact MHE
/// solve on, so ε_t is known). `delta[t]` = δ_t = ‖Uᴷᶜ_t − U*(x̂_t)‖ and `input_error[t]` =
/// ‖u_t − π(x̂_t)‖, computed by the caller with an exact MPC (see
/// [`crate::joint::delta_series`]). `beta` = (prefactor, rate) and `gamma1w` of the plant
/// estimate (the γ₁,₃ certificate's).
///
/// Returns `None` when the trace has no ε_t, the series are shorter than the trace, or β₁ is
/// unknown (`beta` None: γ₁,₃ void).
#[allow(clippy::too_many_arguments)]
pub fn check_joint_trajectory(
    cert: &ClosedLoopCertificate,
    analysis: &JointAnalysis,
    k_e: usize,
    k_c: usize,
    trace: &Trace,
    delta: &[f64],
    input_error: &[f64],
    beta: Option<(f64, f64)>,
    gamma1w: f64,
) -> Option<JointTrajectoryCheck> {
    let beta = beta?;
    let eps: Vec<f64> = trace.epsilons().collect::<Option<Vec<f64>>>()?;
    let n = trace.len().min(eps.len());
    if delta.len() < n || input_error.len() < n {
        return None;
    }
    let g = analysis.at(k_e, k_c);
    let m = &g.mhe;
    let mpc = &analysis.inputs.mpc;
    let (xs, es, ws) = (trace.x_norms(), trace.e_norms(), trace.w_norms());
    let xh: Vec<f64> = (0..n)
        .map(|t| trace.x_hat(t).map_or(f64::NAN, lti_model::vecmath::norm2))
        .collect();
    let sqrt_rho = analysis.theorem1.rho.sqrt();
    let a = (2.0 * analysis.theorem1.lambda_hp).sqrt();
    let mut out = JointTrajectoryCheck {
        plant: InequalityCheck::new(),
        prop1: InequalityCheck::new(),
        prop3: InequalityCheck::new(),
        delta_step: InequalityCheck::new(),
        delta: InequalityCheck::new(),
        input_error: InequalityCheck::new(),
        divergence: trace.x(0).and_then(|x0| {
            closed_loop::bounded::first_unbounded(
                trace,
                x0,
                closed_loop::bounded::DEFAULT_BOUNDED_FACTOR,
                false,
            )
        }),
    };
    // Sups over [0, t−1] (s_*) and over [0, t] (x_now, e_now).
    let (mut sx, mut se, mut sw, mut seps, mut ssig, mut sd) =
        (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    let (mut x_now, mut e_now) = (0.0_f64, 0.0_f64);
    for t in 0..n {
        if t > 0 {
            sx = sx.max(xs[t - 1]);
            se = se.max(es[t - 1]);
            sw = sw.max(ws[t - 1]);
            seps = seps.max(eps[t - 1]);
            sd = sd.max(delta[t - 1]);
        }
        // σ_t of the mended Lemma 1 enters at step t itself (Prop. 1, Case 1).
        ssig = ssig.max(crate::certificate::lemma1::sigma(
            trace,
            t,
            &cert.lemma1_origin_offsets,
            analysis.theorem1.l_phi_used,
        )?);
        x_now = x_now.max(xs[t]);
        e_now = e_now.max(es[t]);
        let ti = i32::try_from(t).unwrap_or(i32::MAX);
        let rhs_plant =
            beta.0 * beta.1.powi(ti) * xs[0] + g.gamma13 * se + g.gamma14 * sd + gamma1w * sw;
        out.plant.record(t, xs[t], rhs_plant);
        let rhs1 = m.phi.powi(ti) * eps[0]
            + m.gamma21 * sx
            + m.gamma23 * se
            + m.gamma2w * sw
            + g.gamma24 * sd
            + m.gamma2sigma * ssig;
        let (floor_eps, floor_e) = crate::certificate::rounding_floor(trace, t, k_e);
        out.prop1.record_with_floor(t, eps[t], rhs1, floor_eps);
        let rhs3 = m.c_e * sqrt_rho.powi(ti) * es[0]
            + a * m.c1 * sx
            + m.c_eps * seps
            + m.c_w * sw
            + g.gamma34 * sd
            + m.gamma3sigma * ssig;
        out.prop3.record_with_floor(t, es[t], rhs3, floor_e);
        let step_rhs = if t == 0 {
            g.phi_c * mpc.l_u * xh[0]
        } else {
            g.phi_c
                * (mpc.warm_gain * delta[t - 1]
                    + mpc.warm_gain * mpc.l_u * xh[t - 1]
                    + mpc.l_u * xh[t])
        };
        out.delta_step.record(t, delta[t], step_rhs);
        let rhs_d = g.delta_rate.powi(ti) * delta[0] + g.gamma41 * x_now + g.gamma43 * e_now;
        out.delta.record(t, delta[t], rhs_d);
        out.input_error.record(t, input_error[t], delta[t]);
    }
    Some(out)
}
