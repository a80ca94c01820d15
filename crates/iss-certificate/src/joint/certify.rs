//! The joint certificate of a resolved scenario, and the replay that measures δ_t on a trace.

use mpc_core::{CondensedMpc, Controller, ExactMpc, MpcError, SuboptimalMpc, WarmStart};
use qp_iter::{IterationMap, Method};
#[cfg(feature = "serde")]
use serde::Serialize;

use super::gains::{JointAnalysis, JointGains, JointInputs, JointRounding, MpcMapInputs};
use super::region::JointRegion;
use crate::certificate::ClosedLoopCertificate;
use crate::certificate::precision::ScalarVoid;
use crate::lure::global::{PrecisionVoid, StepRounding};
use closed_loop::record::Trace;
use closed_loop::scenario::ResolvedScenario;
use closed_loop::sim::ClosedLoopError;

/// Settings of [`certify_joint`].
#[derive(Debug, Clone, PartialEq)]
pub struct JointOptions {
    /// Largest K_e and K_c searched.
    pub k_max: usize,
    /// Cost per MHE and per MPC iteration (t_e, t_c) for the cheapest pair; `None`: the
    /// multiply–adds of one iteration (n² per matrix–vector product of each map).
    pub cost: Option<(f64, f64)>,
    /// The MPC's warm start.
    pub warm_start: WarmStart,
}

impl Default for JointOptions {
    fn default() -> Self {
        Self {
            k_max: 1 << 24,
            cost: None,
            warm_start: WarmStart::default(),
        }
    }
}

/// The joint certificate for one MHE method and one MPC method.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct JointCertificate {
    /// The MHE's method Φ_e.
    pub mhe_method: Method,
    /// The MPC's method Φ_c.
    pub mpc_method: Method,
    /// The MPC's warm start rule.
    pub warm_start: String,
    /// What `region.cost_per_iteration` measures.
    pub cost_model: String,
    /// The four-node analysis (inputs, premises).
    pub analysis: JointAnalysis,
    /// Certified region, Pareto front and cheapest pair.
    pub region: JointRegion,
    /// Gains at the cheapest pair.
    pub at_cheapest: Option<JointGains>,
    /// β₁ = (prefactor, rate) of the plant estimate (for the trajectory checks); None when
    /// γ₁,₃ is void.
    pub plant_beta: Option<(f64, f64)>,
    /// γ₁ʷ of the plant estimate.
    pub gamma1w: f64,
}

impl JointCertificate {
    /// The same certificate for the loop run in a rounded scalar: the analysis with
    /// `rounding` folded in ([`JointAnalysis::with_rounding`]), its region and cheapest pair
    /// recomputed with the same costs and K range.
    pub fn with_rounding(self, rounding: JointRounding) -> Self {
        let analysis = self.analysis.with_rounding(rounding);
        let (t_e, t_c) = self.region.cost_per_iteration;
        let region = analysis.region(self.region.k_max, t_e, t_c);
        let at_cheapest = region.cheapest.map(|p| analysis.at(p.k_e, p.k_c));
        Self {
            analysis,
            region,
            at_cheapest,
            ..self
        }
    }
}

/// ω = ‖W‖₂ of a warm start on an N-stage sequence: shift-and-repeat-last √2 (N ≥ 2; it
/// copies u_{N−1} twice), shift-and-zero 1 (0 for N = 1, with 0 ∈ 𝒰), the previous
/// sequence 1, a cold start 0 (U⁰ = Π_𝒰(0) = 0).
///
/// ```
/// use iss_certificate::joint::warm_start_gain;
/// use mpc_core::WarmStart;
/// assert_eq!(warm_start_gain(WarmStart::ShiftRepeatLast, 10), 2f64.sqrt());
/// assert_eq!(warm_start_gain(WarmStart::Cold, 10), 0.0);
/// ```
pub fn warm_start_gain(warm: WarmStart, horizon: usize) -> f64 {
    match warm {
        WarmStart::ShiftRepeatLast if horizon >= 2 => std::f64::consts::SQRT_2,
        WarmStart::ShiftRepeatLast | WarmStart::Previous => 1.0,
        WarmStart::ShiftZero if horizon >= 2 => 1.0,
        WarmStart::ShiftZero | WarmStart::Cold => 0.0,
    }
}

fn warm_name(w: WarmStart) -> &'static str {
    match w {
        WarmStart::ShiftRepeatLast => "shift-repeat-last",
        WarmStart::ShiftZero => "shift-zero",
        WarmStart::Previous => "previous",
        WarmStart::Cold => "cold",
    }
}

/// The joint certificate of the loop "MHE with `mhe_method`, MPC with `mpc_method`" on the
/// scenario `cert` was computed for (`cert` must contain `mhe_method`).
///
/// `mhe_variables` is the size of the MHE's full window (for the default cost model).
///
/// Errors: `mhe_method` not in `cert`; the MPC's map cannot be built.
pub fn certify_joint(
    cert: &ClosedLoopCertificate,
    mpc: &CondensedMpc,
    mhe_variables: usize,
    mhe_method: Method,
    mpc_method: Method,
    opts: &JointOptions,
) -> Result<JointCertificate, ClosedLoopError> {
    let sc = cert
        .solver(mhe_method)
        .ok_or_else(|| ClosedLoopError::OutOfRange {
            name: "joint certificate: MHE method",
            value: f64::NAN,
            range: "a method the closed-loop certificate was computed for",
        })?;
    let phi_c = mpc_method
        .certificate_for(mpc.qp().clone())
        .map_err(MpcError::Qp)?;
    let qp = mpc.qp();
    let zset = qp.zset();
    let origin_fixed = qp.q0().iter().all(|v| *v == 0.0)
        && zset.lower().iter().all(|l| *l <= 0.0)
        && zset.upper().iter().all(|u| *u >= 0.0);
    let g13 = cert.gamma13.certified.as_ref();
    // γ₁,₄ exists only in the estimate that gave the γ₁,₃ actually used.
    let same_estimate = g13.is_some_and(|c| c.gamma13 == cert.gamma13.used);
    let gamma14 = if same_estimate {
        g13.map_or(f64::INFINITY, |c| c.gamma14)
    } else {
        f64::INFINITY
    };
    let (plant_beta, gamma1w) = g13.map_or((None, f64::INFINITY), |c| {
        (c.beta_prefactor.zip(c.beta_rate), c.gamma1w)
    });
    let inputs = JointInputs {
        mhe: sc.analysis.inputs.clone(),
        gamma14,
        mpc: MpcMapInputs {
            l_u: cert.l_pi.certified.sequence,
            phi_rate: phi_c.rate,
            phi_prefactor: phi_c.prefactor,
            phi_fits_eq11: phi_c.fits_eq11,
            warm_gain: warm_start_gain(opts.warm_start, mpc.horizon()),
            warm_start: warm_name(opts.warm_start).into(),
            origin_fixed,
        },
    };
    let analysis = JointAnalysis::new(inputs);
    let (cost, cost_model) = match opts.cost {
        Some(c) => (c, "supplied cost per iteration (t_e, t_c)".to_string()),
        None => {
            // Matrix–vector products per step depend on the method only: count them on
            // the MPC's QP for both.
            let mv = |m: Method| -> Result<f64, ClosedLoopError> {
                Ok(m.build(qp.clone())
                    .map_err(MpcError::Qp)?
                    .matvecs_per_step() as f64)
            };
            let (ne, nc) = (mhe_variables as f64, qp.n() as f64);
            (
                (ne * ne * mv(mhe_method)?, nc * nc * mv(mpc_method)?),
                "multiply–adds of one dense iteration: n² per matrix–vector product, the MHE \
                 at the full window (n_x + M(n_x + n_y) variables) and the MPC (N·n_u)"
                    .to_string(),
            )
        }
    };
    let region = analysis.region(opts.k_max, cost.0, cost.1);
    let at_cheapest = region.cheapest.map(|p| analysis.at(p.k_e, p.k_c));
    Ok(JointCertificate {
        mhe_method,
        mpc_method,
        warm_start: warm_name(opts.warm_start).into(),
        cost_model,
        analysis,
        region,
        at_cheapest,
        plant_beta,
        gamma1w,
    })
}

/// The rounding of the loop "MHE with `mhe_method`, MPC with `mpc_method`" on `resolved`
/// run in unit round-off `u` (docs/theory.md, "The joint certificate in f32"): the MHE's
/// fold of Theorem 1 in that precision and the MPC's K-step model on its QP (in the
/// portable kernel's order, with its data rounded once), or why either is missing (the
/// MPC's reason names it). [`JointAnalysis::with_rounding`] takes it.
///
/// Errors only when the scenario has no MHE or MPC.
pub fn joint_rounding(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    mhe_method: Method,
    mpc_method: Method,
    u: f64,
) -> Result<Result<JointRounding, ScalarVoid>, ClosedLoopError> {
    let mhe = match crate::certificate::precision::mhe_fold(resolved, cert, mhe_method, u)? {
        Ok(f) => f,
        Err(why) => return Ok(Err(why)),
    };
    let mpc = resolved.mpc()?;
    let why = |s: String| {
        Ok(Err(ScalarVoid::NotCovered {
            why: format!("the MPC ({}): {s}", mpc_method.name()),
        }))
    };
    let st = match StepRounding::for_qp(mpc_method, mpc.qp(), u) {
        Ok(st) => st,
        Err(PrecisionVoid::NotCovered { why: w }) => return why(w),
        Err(other) => return why(other.to_string()),
    };
    if !(st.perturbed_rate() < 1.0) {
        let (rate, rounding) = st.rate_and_rounding();
        return why(format!(
            "its computed iteration does not contract: rate {} + rounding {} ≥ 1",
            lti_model::numfmt::sig4(rate),
            lti_model::numfmt::sig4(rounding)
        ));
    }
    let (mpc_d_max, mpc_kappa) = match &st {
        StepRounding::Jacobi(j) => (j.d_max, j.d_max / j.d_min),
        _ => (1.0, 1.0),
    };
    Ok(Ok(JointRounding {
        u,
        mhe,
        mpc: st,
        mpc_kappa,
        mpc_d_max,
    }))
}

/// δ_t = ‖Uᴷᶜ_t − U*(x̂_t)‖ and ‖u_t − π(x̂_t)‖ along a trace, by replaying the sub-optimal
/// MPC on the trace's estimates x̂_t (deterministic: the same map, K_c and warm start give
/// the same Uᴷᶜ_t) and solving the exact MPC at each x̂_t.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct DeltaSeries {
    /// δ_t.
    pub delta: Vec<f64>,
    /// ‖u_t − π(x̂_t)‖ with u_t from the trace.
    pub input_error: Vec<f64>,
    /// max_t ‖u_t(replay) − u_t(trace)‖: 0 when the replay reproduces the applied inputs.
    pub replay_mismatch: f64,
}

/// Replays the sub-optimal MPC (`mpc_method`, `k_c`, `warm`) on the estimates of `trace`.
///
/// Errors: the MPC's map or the exact MPC fails.
pub fn delta_series(
    mpc: &CondensedMpc,
    mpc_method: Method,
    k_c: usize,
    warm: WarmStart,
    trace: &Trace,
) -> Result<DeltaSeries, ClosedLoopError> {
    let map = mpc_method.build(mpc.qp().clone()).map_err(MpcError::Qp)?;
    let mut sub = SuboptimalMpc::new(mpc, map, k_c, warm)?;
    let mut exact = ExactMpc::new(mpc)?;
    let nu = mpc.nu();
    let mut u = vec![0.0; nu];
    let mut out = DeltaSeries {
        delta: Vec::with_capacity(trace.len()),
        input_error: Vec::with_capacity(trace.len()),
        replay_mismatch: 0.0,
    };
    for t in 0..trace.len() {
        let (Some(xh), Some(ut)) = (trace.x_hat(t), trace.u(t)) else {
            break;
        };
        sub.control(xh, &mut u)?;
        let star = exact.solve(xh)?;
        let seq = sub.input_sequence();
        out.delta.push(lti_model::vecmath::dist2(seq, star));
        out.input_error
            .push(lti_model::vecmath::dist2(ut, &star[..nu]));
        out.replay_mismatch = out.replay_mismatch.max(lti_model::vecmath::dist2(&u, ut));
    }
    Ok(out)
}
