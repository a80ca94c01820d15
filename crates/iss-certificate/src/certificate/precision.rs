//! Theorem 1 in a given precision (issue 36): the rounding of the estimator's arithmetic as
//! an extra input with its own gain (docs/theory.md, "Certified f32: rounding as an input").
//!
//! Per window length m the K-step rounding model of the method
//! (`lure::global::StepRounding`, built on [`qp_iter::rounding`]: projected gradient, V-FISTA
//! where its incremental storage exists, ADMM and the Jacobi variants) gives
//! ‖zᴷ − z*‖ ≤ φ_u,m(K)‖z⁰ − z*‖ + β_z‖z*‖ + β_θ‖θ‖ + c_d towards the optimum of the exact
//! data, in ‖D⁻¹·‖ for the Jacobi variants (× d_max into z's norm). Then:
//!
//! 1. K computed iterations contract with φ_u(K) = max_m κ(D_m)φ_u,m(φ(K)/κ(D_m), K)
//!    (projected gradient: max_m (r_m + a_m)ᴷ) and add at most g_d‖θ_t‖ + c_d
//!    ([`ScalarCertificate::rounding_gain`], [`ScalarCertificate::rounding_offset`];
//!    ‖z*‖ ≤ o_m + L_Φ‖θ‖); the premise is q_m < 1 in every window (it fails where u·κ(H) is
//!    not small: the exact reason names the window).
//! 2. Props. 1 and 3 with φ → φ_u and φL_Φ → φ_uL_Φ + g_d in every data gain
//!    ([`crate::analysis::IssAnalysis::at_perturbed`]), plus the rounding of x̂'s
//!    propagation through the window, ‖r_t‖ ≤ ρ_z‖zᴷ_t‖ + ρ_u‖u window‖, which enters e_t
//!    with gain k_r and adds a self-loop s on e: the certified condition is
//!    1 − s − sg1 − sg2 − sg3 > 0.
//!
//! So K_min(f32) ≥ K_min(f64), equal when u's effect is below the margin's resolution, and
//! the constant terms (q₀, the rounded box bounds) leave an offset in the lim-sup bounds.
//!
//! [`DeviationBound`] is the per-step bound on ‖x̂_f32 − x̂_f64‖ of two estimators fed the same
//! (u, y), computable along a trajectory from ‖θ_t‖ alone; the tests compare it with
//! `mhe_embedded` runs.

use faer::{Mat, MatRef};
use qp_iter::Method;
use qp_iter::rounding::{
    AdmmRounding, F32_UNIT_ROUNDOFF, F64_UNIT_ROUNDOFF, IterationRounding, abs_norm_bound,
    admm_rounding, gamma, iteration_rounding,
};
#[cfg(feature = "serde")]
use serde::Serialize;

use super::{ClosedLoopCertificate, VoidReason};
use crate::lure::global::{PrecisionVoid, StepRounding};
use closed_loop::scenario::ResolvedScenario;
use closed_loop::sim::ClosedLoopError;
use lti_model::LtiSystem;

/// The scalar type the estimator runs in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Scalar {
    /// IEEE binary64: the certificate as computed (its rounding is the trajectory checks'
    /// floor, [`super::rounding_floor`]).
    F64,
    /// IEEE binary32, u = 2⁻²⁴.
    F32,
}

impl Scalar {
    /// The unit round-off u.
    pub fn unit_roundoff(self) -> f64 {
        match self {
            Scalar::F64 => F64_UNIT_ROUNDOFF,
            Scalar::F32 => F32_UNIT_ROUNDOFF,
        }
    }
}

/// ‖M‖₂ bounded above by √(‖M‖₁‖M‖_∞) (rigorous, unlike a computed SVD).
fn norm_bound(m: MatRef<'_, f64>) -> f64 {
    abs_norm_bound(m.nrows(), m.ncols(), |i, j| m[(i, j)])
}

/// Rounding of x̂'s propagation through a window of length m in `mhe_embedded`'s order
/// (x⁺ = Ax + Bu + Ew¹, each product summed from 0, then added in that order):
/// ‖fl(x̂) − x̂(z)‖ ≤ from_z‖z‖ + from_u‖u window‖.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct PropagationRounding {
    /// Coefficient of ‖zᴷ‖.
    pub from_z: f64,
    /// Coefficient of ‖(u_{t−m}, …, u_{t−1})‖.
    pub from_u: f64,
    /// ‖Ψ_m‖ bound: x̂(z) = Ψ_m z + Υ_m u (the exact propagation's gain from z).
    pub psi: f64,
    /// ‖Υ_m‖ bound (its gain from the u window).
    pub upsilon: f64,
}

pub(crate) fn propagation_rounding(sys: &LtiSystem, m: usize, u: f64) -> PropagationRounding {
    let (nx, nu, nw1) = (sys.nx(), sys.nu(), sys.nw1());
    let (na, nb, ne) = (
        norm_bound(sys.a()),
        norm_bound(sys.b()),
        norm_bound(sys.e()),
    );
    // |A|, |B|, |E| have the same √(‖·‖₁‖·‖_∞) bound as A, B, E.
    // Per term: the stored entry and the stored input (2), the product (1), the row sum
    // (≤ n), the additions into x⁺ (≤ 3).
    let g = gamma(nx.max(nu).max(nw1) + 6, u);
    // Linear recursions in (‖z‖, ‖u‖): X_j ≥ ‖computed x̂_j‖, R_j ≥ ‖its error‖.
    let (mut xz, mut xu) = (1.0f64, 0.0f64);
    let (mut rz, mut ru) = (0.0f64, 0.0f64);
    for _ in 0..m {
        let (lz, lu) = (g * (na * xz + ne), g * (na * xu + nb));
        rz = na * rz + lz;
        ru = na * ru + lu;
        xz = na * xz + ne + lz;
        xu = na * xu + nb + lu;
    }
    // Ψ_m = [A^m, A^{m−1}E, …, E] on (x₀, w¹_0, …) and Υ_m = [A^{m−1}B, …, B]:
    // ‖Ψ_m z‖ ≤ (Σ blocks' norms²)^{1/2}‖z‖ (Cauchy–Schwarz over the blocks).
    let mut pow = Mat::<f64>::identity(nx, nx);
    let (mut psi2, mut ups2) = (0.0f64, 0.0f64);
    for _ in 0..m {
        psi2 += norm_bound((&pow * sys.e()).as_ref()).powi(2);
        ups2 += norm_bound((&pow * sys.b()).as_ref()).powi(2);
        pow = sys.a() * &pow;
    }
    psi2 += norm_bound(pow.as_ref()).powi(2);
    PropagationRounding {
        from_z: rz,
        from_u: ru,
        psi: psi2.sqrt(),
        upsilon: ups2.sqrt(),
    }
}

/// The rounding of one window length m.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct WindowRounding {
    /// Window length m.
    pub m: usize,
    /// The iteration's model (rate r_m, a_m, b_m, c_m).
    pub iteration: IterationRounding,
    /// x̂'s propagation.
    pub propagation: PropagationRounding,
    /// Certified L_Φ of this window (‖z*(θ) − z*(θ')‖ ≤ L‖θ − θ'‖).
    pub l_phi: f64,
    /// o_m ≥ ‖z*_m(0)‖ ([`super::lemma1::origin_offset`]).
    pub origin_offset: f64,
}

/// One window length m with a model `T` of its computed iteration, L_Φ, ‖z*(0)‖ and x̂'s
/// propagation rounding.
struct Window<T> {
    m: usize,
    model: T,
    propagation: PropagationRounding,
    l_phi: f64,
    origin_offset: f64,
}

/// Every window of the scenario's MHE with `model` of its QP, or the first reason (naming
/// the window) a model, L_Φ or ‖z*(0)‖ is missing.
fn per_window<T>(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    u: f64,
    model: impl Fn(&qp_iter::ParametricQp) -> Result<T, String>,
) -> Result<Result<Vec<Window<T>>, String>, ClosedLoopError> {
    let problem = resolved.mhe_problem()?;
    let sys = problem.system();
    let mut out = Vec::new();
    for (m, w) in problem.windows().iter().enumerate() {
        let model = match model(w.qp()) {
            Ok(r) => r,
            Err(e) => return Ok(Err(format!("window m = {m}: {e}"))),
        };
        let l_phi = cert
            .l_phi
            .per_window
            .get(m)
            .map_or(f64::NAN, |p| p.0)
            .max(1.0);
        let origin_offset = cert
            .lemma1_origin_offsets
            .get(m)
            .copied()
            .unwrap_or(f64::NAN);
        if !(l_phi.is_finite() && origin_offset.is_finite()) {
            return Ok(Err(format!(
                "window m = {m}: L_Φ or ‖z*(0)‖ has no finite certified bound"
            )));
        }
        out.push(Window {
            m,
            model,
            propagation: propagation_rounding(sys, m, u),
            l_phi,
            origin_offset,
        });
    }
    Ok(Ok(out))
}

/// The per-window one-step models of projected gradient (`solver`) on the scenario's MHE in
/// unit round-off `u`, or why the rounding is not covered (the first reason): what
/// [`DeviationBound`] tracks. Theorem 1 itself takes every method's K-step model.
pub fn window_roundings(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    solver: Method,
    u: f64,
) -> Result<Result<Vec<WindowRounding>, String>, ClosedLoopError> {
    let windows = per_window(resolved, cert, u, |qp| {
        iteration_rounding(&solver, qp, u).map_err(|e| e.to_string())
    })?;
    Ok(windows.map(|ws| {
        ws.into_iter()
            .map(|w| WindowRounding {
                m: w.m,
                iteration: w.model,
                propagation: w.propagation,
                l_phi: w.l_phi,
                origin_offset: w.origin_offset,
            })
            .collect()
    }))
}

/// Why Theorem 1 with the rounding folded in certifies no K for a solver in a scalar type.
/// Serialised as its sentence.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum ScalarVoid {
    /// The solver has no entry in the closed-loop certificate.
    NotCertified {
        /// The solver asked for.
        solver: Method,
    },
    /// f64: Theorem 1 itself is void (no rounding folded in).
    Theorem1 {
        /// Its reasons.
        reasons: Vec<VoidReason>,
    },
    /// The f64 certificate is void already.
    VoidInF64 {
        /// Its reasons.
        reasons: Vec<VoidReason>,
    },
    /// The time-shifted warm start rounds its model step: only the paper's is covered.
    ShiftedWarmStart,
    /// The MPC law is not 0 at x = 0, so ‖u‖ ≤ L_π‖x̂‖ of the fold does not hold.
    MpcNotZeroAtOrigin,
    /// The rounding model of a window cannot be computed (its sentence).
    NotCovered {
        /// Why, naming the window.
        why: String,
    },
    /// Rounding breaks the contraction in a window (r + a ≥ 1).
    ContractionBroken {
        /// The window m.
        window: usize,
        /// Its rate r.
        rate: f64,
        /// The rounding's a.
        rounding: f64,
    },
    /// No K up to the search limit satisfies the small-gain condition with the rounding.
    NoK {
        /// Largest K searched.
        k_max: usize,
        /// g_d: the rounding's gain into ε.
        rounding_gain: f64,
        /// φ(K)L_Φ at the f64 K_min (None without one).
        phi_l_phi: Option<f64>,
        /// x̂'s self-loop gain s on e at `k_max`.
        self_loop: f64,
    },
}

impl std::fmt::Display for ScalarVoid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use lti_model::numfmt::sig4;
        match self {
            Self::NotCertified { solver } => {
                write!(f, "`{}` is not among the certified solvers", solver.name())
            }
            Self::Theorem1 { reasons } => f.write_str(&VoidReason::join(reasons)),
            Self::VoidInF64 { reasons } => {
                write!(f, "void in f64 already: {}", VoidReason::join(reasons))
            }
            Self::ShiftedWarmStart => f.write_str(
                "the shifted warm start rounds its model step; only the paper's warm start \
                 (an exact copy of zᴷ) is covered",
            ),
            Self::MpcNotZeroAtOrigin => f.write_str(
                "the MPC law is not 0 at x = 0 (a linear term or an input box excluding 0): the \
                 bound ‖u‖ ≤ L_π‖x̂‖ of the fold does not hold",
            ),
            Self::NotCovered { why } => write!(f, "not covered: {why}"),
            Self::ContractionBroken {
                window,
                rate,
                rounding,
            } => write!(
                f,
                "void: rounding breaks the contraction in window m = {window} (the exact rate \
                 r = {} plus the rounding's {} is ≥ 1; for projected gradient 1 − r ≈ 2/κ(H) is \
                 below (n + 5)·u·(1 + α‖|H|‖)): improve the conditioning (a shorter horizon, \
                 the Jacobi scaling) or run in f64",
                sig4(*rate),
                sig4(*rounding)
            ),
            Self::NoK {
                k_max,
                rounding_gain,
                phi_l_phi,
                self_loop,
            } => write!(
                f,
                "void: with the rounding folded in no K ≤ {k_max} satisfies \
                 1 − s − sg1 − sg2 − sg3 > 0: the rounding enters ε with gain g_d = {} per \
                 unit of ‖θ_t‖ (the window's magnitude), against φ(K)L_Φ = {} at the f64 \
                 K_min, and x̂'s propagation adds a self-loop s = {} on e; Theorem 1's \
                 gains leave no room for it (run in f64, or tighten the rounding model)",
                sig4(*rounding_gain),
                // No f64 K_min prints as sig4(NaN), as before the reason was typed.
                sig4(phi_l_phi.unwrap_or(f64::NAN)),
                sig4(*self_loop)
            ),
        }
    }
}

#[cfg(feature = "serde")]
impl Serialize for ScalarVoid {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// What Theorem 1 certifies for one solver in one scalar type.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct ScalarCertificate {
    /// The scalar type.
    pub scalar: Scalar,
    /// The solver.
    pub solver: Method,
    /// The smallest certified K in this scalar (None: `reason` says why).
    pub k_min: Option<usize>,
    /// The f64 certificate's K_min (the certificate as computed), for comparison.
    pub k_min_f64: Option<usize>,
    /// max_m q_m: the rate of the computed iteration (projected gradient: r_m + a_m; 0 for
    /// f64).
    pub perturbed_rate: f64,
    /// φ_u(K_min): the computed iteration's factor on ‖z⁰ − z*‖ in z's Euclidean norm at K_min
    /// (and every K ≥ K_min; projected gradient: qᴷ), when certified in a rounded scalar.
    pub phi_u: Option<f64>,
    /// g_d: the rounding's gain from ‖θ_t‖ into ε_t (0 for f64).
    pub rounding_gain: f64,
    /// c_d: its constant part (the lim-sup of ε gains c_d/(1 − φ_u(K))).
    pub rounding_offset: f64,
    /// The rounding's self-loop gain on e at K_min (x̂'s propagation), when certified.
    pub self_loop: Option<f64>,
    /// The certified margin 1 − s − sg1 − sg2 − sg3 at K_min.
    pub margin: Option<f64>,
    /// Why there is no K_min (None when there is one).
    pub reason: Option<ScalarVoid>,
}

impl ScalarCertificate {
    /// Whether this scalar is certified at iteration budget K (K ≥ K_min): the verdict the
    /// export and the coverage table use for (method, K, scalar).
    pub fn covers(&self, k: usize) -> bool {
        self.k_min.is_some_and(|m| k >= m)
    }
}

/// The rounding's constants of Theorem 1 (docs/theory.md, "Certified f32", steps 3–4), from
/// every window's K-step model (`lure::global::StepRounding`: projected gradient, V-FISTA,
/// ADMM and the Jacobi variants), in z's Euclidean norm. Also the MHE side of the joint
/// certificate in f32 ([`crate::joint`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Fold {
    /// Per window: the K-step model and κ(D_m) = d_max/d_min (1 without a scaling), the
    /// factor from the model's norm ‖D⁻¹·‖ to the Euclidean one on the start.
    windows: Vec<(StepRounding, f64)>,
    /// max_m q_m: the computed iteration's rate.
    q: f64,
    pub(crate) g_d: f64,
    pub(crate) c_d: f64,
    rho_z: f64,
    rho_u: f64,
    l_phi: f64,
}

/// Theorem 1's gains at K with the rounding folded in (docs/theory.md, "Certified f32",
/// steps 3–4): Props. 1 and 3 with φ → φ_u and φL_Φ → φ_uL_Φ + g_d, plus x̂'s propagation
/// rounding into e.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Folded {
    /// φ_u(K).
    pub(crate) phi: f64,
    /// The perturbed gains (`IssAnalysis::at_perturbed`).
    pub(crate) gains: crate::analysis::GainsAtK,
    /// γ₃,₁ and γ₃,₂ with the propagation's rounding.
    pub(crate) gamma31: f64,
    pub(crate) gamma32: f64,
    /// The self-loop s on e.
    pub(crate) self_loop: f64,
    /// k_r(ρ_zL_Φ(1 + u) + ρ_u): the rounding's gain from ‖θ_t‖ into e (per unit of each
    /// θ entry's norm: the u window's entries bring the MPC's input error with it).
    pub(crate) theta_gain: f64,
}

impl Fold {
    /// Theorem 1's gains of `a` at K with this rounding (unit round-off `u`).
    pub(crate) fn at(&self, a: &crate::analysis::IssAnalysis, k: usize, u: f64) -> Folded {
        let phi = self.phi_u(a.phi(k), k);
        let g = a.at_perturbed(k, phi, self.g_d);
        let i = &a.inputs;
        let m = i.horizon as f64;
        // e-terms of (lemma 3 last): coefficient √(2Λ^H̄_P)·(φL_Φ + g_d)·2(M L_π + 1).
        let s_e =
            (2.0 * a.lambda_hp).sqrt() * (phi * a.l_phi_used + self.g_d) * 2.0 * (m * i.l_pi + 1.0);
        let kappa_r = 1.0 + a.lambda_pp.sqrt() / (1.0 - a.rho.powi(i.horizon as i32).sqrt());
        let k_r = (1.0 + s_e) * kappa_r;
        // ‖r_t‖ ≤ ρ_z(o + L‖θ̃‖ + ε_t) + ρ_u‖θ‖; ‖θ‖ ≤ (1 + M(‖C‖ + L_π))‖x‖ + (1 + M L_π)‖e‖
        // + M‖F‖‖w‖ (π(0) = 0).
        let theta_gain = (self.rho_z * self.l_phi * (1.0 + u) + self.rho_u) * k_r;
        Folded {
            phi,
            gamma31: g.gamma31 + theta_gain * (1.0 + m * (i.c_norm + i.l_pi)),
            gamma32: g.gamma32 + k_r * self.rho_z,
            self_loop: theta_gain * (1.0 + m * i.l_pi),
            theta_gain,
            gains: g,
        }
    }

    fn new(windows: Vec<Window<StepRounding>>) -> Self {
        let (mut q, mut g_d, mut c_d, mut rho_z, mut rho_u, mut l_phi) =
            (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut models = Vec::with_capacity(windows.len());
        for w in windows {
            let st = &w.model;
            // ‖D⁻¹(zᴷ − z*)‖ ≤ φ_u‖D⁻¹(z⁰ − z*)‖ + β_z‖z*‖ + β_θ‖θ‖ + c_d with z* = z*(θ) of the
            // exact data (β_θ counts θ's rounding to the scalar) and ‖z*‖ ≤ o_m + L_Φ‖θ‖;
            // × d_max into z's norm (d = 1 without a scaling).
            let (d_max, kappa) = match st {
                StepRounding::Jacobi(j) => (j.d_max, j.d_max / j.d_min),
                _ => (1.0, 1.0),
            };
            q = q.max(st.perturbed_rate());
            g_d = g_d.max(d_max * (st.beta_z() * w.l_phi + st.beta_theta()));
            c_d = c_d.max(d_max * (st.beta_z() * w.origin_offset + st.offset_d()));
            rho_z = rho_z.max(w.propagation.from_z);
            rho_u = rho_u.max(w.propagation.from_u);
            l_phi = l_phi.max(w.l_phi);
            models.push((w.model, kappa));
        }
        Self {
            windows: models,
            q,
            g_d,
            c_d,
            rho_z,
            rho_u,
            l_phi,
        }
    }

    /// φ_u(K) in z's Euclidean norm, non-increasing in K, from Theorem 1's φ(K) = `phi_k`:
    /// per window κ(D_m)·φ_u,m(φ(K)/κ(D_m), K) — Theorem 1's φ(K) ≥ κ(D_m)·c_m r_mᴷ, the
    /// window's own bound converted from ‖D⁻¹·‖ (docs/theory.md, "Preconditioned maps"), so
    /// φ(K)/κ(D_m) bounds the scaled map's K steps.
    fn phi_u(&self, phi_k: f64, k: usize) -> f64 {
        self.windows
            .iter()
            .map(|(st, kappa)| kappa * st.phi_u(phi_k / kappa, k))
            .fold(0.0, f64::max)
    }
}

/// Margin and self-loop of Theorem 1 at K with the rounding folded in (module docs, step 2).
/// Returns (certified at K, margin, self-loop s).
fn margin_at(a: &crate::analysis::IssAnalysis, fold: &Fold, k: usize, u: f64) -> (bool, f64, f64) {
    let f = fold.at(a, k, u);
    let i = &a.inputs;
    let sg1 = i.gamma13 * f.gamma31;
    let sg2 = f.gains.gamma23 * f.gamma32;
    let sg3 = i.gamma13 * f.gamma32 * f.gains.gamma21;
    let margin = 1.0 - f.self_loop - sg1 - sg2 - sg3;
    let ok = a.premises_hold() && (0.0..1.0).contains(&f.phi) && margin > 0.0 && margin.is_finite();
    (ok, margin, f.self_loop)
}

/// The MHE's rounding model at unit round-off `u` for `solver` (every window's K-step model
/// folded into Theorem 1's constants), or why it does not exist: the part of
/// [`certify_rounded`] that does not depend on K, shared with the joint certificate in f32.
pub(crate) fn mhe_fold(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    solver: Method,
    u: f64,
) -> Result<Result<Fold, ScalarVoid>, ClosedLoopError> {
    let Some(sc) = cert.solver(solver) else {
        return Ok(Err(ScalarVoid::NotCertified { solver }));
    };
    if sc.k_min.is_none() {
        let reasons = sc.void_reasons.clone();
        return Ok(Err(ScalarVoid::VoidInF64 { reasons }));
    }
    if resolved.mhe_config()?.warm_start != mhe_core::WarmStart::Paper {
        return Ok(Err(ScalarVoid::ShiftedWarmStart));
    }
    if !mpc_vanishes_at_origin(resolved)? {
        return Ok(Err(ScalarVoid::MpcNotZeroAtOrigin));
    }
    let model = |qp: &qp_iter::ParametricQp| {
        StepRounding::for_qp(solver, qp, u).map_err(|e| match e {
            PrecisionVoid::NotCovered { why } => why,
            other => other.to_string(),
        })
    };
    let windows = match per_window(resolved, cert, u, model)? {
        Ok(w) => w,
        Err(why) => return Ok(Err(ScalarVoid::NotCovered { why })),
    };
    if let Some(w) = windows.iter().find(|w| !(w.model.perturbed_rate() < 1.0)) {
        let (rate, rounding) = w.model.rate_and_rounding();
        return Ok(Err(ScalarVoid::ContractionBroken {
            window: w.m,
            rate,
            rounding,
        }));
    }
    Ok(Ok(Fold::new(windows)))
}

/// Whether the MPC's law is 0 at x = 0 (q₀ = 0, 0 in the input box, no general rows): the
/// bound ‖u‖ ≤ L_π‖x̂‖ the fold needs.
fn mpc_vanishes_at_origin(resolved: &ResolvedScenario) -> Result<bool, ClosedLoopError> {
    let qp = resolved.mpc()?.qp();
    let z = qp.zset();
    Ok(qp.general().is_none()
        && qp.q0().iter().all(|v| *v == 0.0)
        && z.lower()
            .iter()
            .zip(z.upper())
            .all(|(l, h)| *l <= 0.0 && *h >= 0.0))
}

/// Theorem 1 for `solver` in `scalar` (module docs). f64 returns the certificate as
/// computed; f32 folds the rounding model in ([`certify_rounded`] at u = 2⁻²⁴), or says
/// exactly why it cannot.
///
/// Errors only when the scenario has no MHE or MPC (as [`super::certify_closed_loop`]).
pub fn certify_scalar(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    solver: Method,
    scalar: Scalar,
    k_max: usize,
) -> Result<ScalarCertificate, ClosedLoopError> {
    if scalar == Scalar::F32 {
        return certify_rounded(resolved, cert, solver, F32_UNIT_ROUNDOFF, k_max);
    }
    let sc = cert.solver(solver);
    let k_min_f64 = sc.and_then(|s| s.k_min);
    Ok(ScalarCertificate {
        scalar,
        solver,
        k_min: k_min_f64,
        k_min_f64,
        perturbed_rate: 0.0,
        phi_u: None,
        rounding_gain: 0.0,
        rounding_offset: 0.0,
        self_loop: None,
        margin: sc.and_then(|s| s.at_k_min.as_ref()).map(|g| g.margin),
        reason: match sc {
            None => Some(ScalarVoid::NotCertified { solver }),
            Some(s) => s.k_min.is_none().then(|| ScalarVoid::Theorem1 {
                reasons: s.void_reasons.clone(),
            }),
        },
    })
}

/// Theorem 1 with the rounding model at unit round-off `u` folded in (module docs): f32 is
/// `u` = 2⁻²⁴; `u` = 2⁻⁵³ shows what folding f64's own rounding in would cost (nothing, on
/// the shipped scenarios: the same K_min). `scalar` of the result is F32 when u is f32's,
/// else F64.
pub fn certify_rounded(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    solver: Method,
    u: f64,
    k_max: usize,
) -> Result<ScalarCertificate, ClosedLoopError> {
    let scalar = if u == F32_UNIT_ROUNDOFF {
        Scalar::F32
    } else {
        Scalar::F64
    };
    let sc = cert.solver(solver);
    let k_min_f64 = sc.and_then(|s| s.k_min);
    let out = ScalarCertificate {
        scalar,
        solver,
        k_min: None,
        k_min_f64,
        perturbed_rate: 0.0,
        phi_u: None,
        rounding_gain: 0.0,
        rounding_offset: 0.0,
        self_loop: None,
        margin: None,
        reason: None,
    };
    let void = |mut out: ScalarCertificate, why: ScalarVoid| {
        out.reason = Some(why);
        Ok(out)
    };
    let fold = match mhe_fold(resolved, cert, solver, u)? {
        Ok(f) => f,
        Err(why) => return void(out, why),
    };
    let Some(sc) = sc else {
        return void(out, ScalarVoid::NotCertified { solver });
    };
    let mut out = ScalarCertificate {
        perturbed_rate: fold.q,
        rounding_gain: fold.g_d,
        rounding_offset: fold.c_d,
        ..out
    };
    let a = &sc.analysis;
    let certified = |k: usize| margin_at(a, &fold, k, u).0;
    let k0 = k_min_f64.unwrap_or(1).max(1);
    // The margin increases with K: every gain increases with φ_u(K), which is non-increasing
    // (`Fold::phi_u`: each window's model bounds every K' ≥ K).
    let (limit, _, s) = margin_at(a, &fold, k_max, u);
    if !limit {
        let why = ScalarVoid::NoK {
            k_max,
            rounding_gain: fold.g_d,
            phi_l_phi: k_min_f64.map(|k| sc.analysis.phi(k) * sc.analysis.l_phi_used),
            self_loop: s,
        };
        return void(out, why);
    }
    let (mut lo, mut hi) = (k0 - 1, k0);
    while !certified(hi) {
        lo = hi;
        hi = (hi * 2).min(k_max);
    }
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if certified(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let (_, margin, s) = margin_at(a, &fold, hi, u);
    out.k_min = Some(hi);
    out.margin = Some(margin);
    out.self_loop = Some(s);
    out.phi_u = Some(fold.phi_u(a.phi(hi), hi));
    Ok(out)
}

/// The per-step bound on ‖x̂_f32,t − x̂_f64,t‖ of two estimators (same method, K, data) fed
/// the same (u_t, y_t), the f32 one with its data rounded once: docs/theory.md,
/// "Certified f32", step 5, for projected gradient and (session 28) ADMM, each plain or
/// Jacobi-scaled (tracked in the scaled coordinates y = D⁻¹z). Call
/// [`DeviationBound::step`] once per t with ‖θ_t‖ and the u window's norm of the f64 run; it
/// returns the bound at t.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct DeviationBound {
    windows: Vec<DeviationWindow>,
    k: usize,
    horizon: usize,
    t: usize,
    /// ‖D⁻¹(zᴷ_32 − zᴷ_64)‖ bound at t − 1 (D of window min(t − 1, M)).
    z_dev: f64,
    /// ‖D⁻¹(zᴷ_64 − z*)‖ and ‖D⁻¹z*‖ bounds at t − 1.
    eps64: f64,
    z_star: f64,
    /// Deviation bounds of x̂ so far.
    history: Vec<f64>,
}

/// One window of [`DeviationBound`]: both scalars' models of the method on the QP the
/// build runs (the scaled one for a Jacobi variant), its scaling, x̂'s propagation rounding
/// in both scalars, L_Φ and o_m.
#[derive(Debug, Clone)]
struct DeviationWindow {
    kernel: DeviationKernel,
    /// The Jacobi scaling d (empty: none, D = I), as the f64 build holds it.
    scaling: Vec<f64>,
    p32: PropagationRounding,
    p64: PropagationRounding,
    l_phi: f64,
    origin_offset: f64,
}

/// The method's one-step models in f32 and f64.
#[derive(Debug, Clone)]
enum DeviationKernel {
    /// Projected gradient: zᵏ⁺¹ = Π(zᵏ − α(Hzᵏ + q)).
    Pg(IterationRounding, IterationRounding),
    /// ADMM (relaxed Douglas–Rachford on s) with its relaxation α.
    Admm(AdmmRounding, AdmmRounding, f64),
}

/// Relative slack on ‖D⁻¹z*‖ ≤ ‖z*‖/d_min for the scaled problem the build holds (its data
/// computed in f64 from the original window's; its optimum differs from D⁻¹z* by f64's
/// rounding times κ, far below this where the f32 contraction holds: u₃₂κ(H) < 1).
const SCALED_OPTIMUM_SLACK: f64 = 1e-6;

/// min_i d_i and max_i d_i of a scaling (1, 1 without one).
fn scaling_extremes(d: &[f64]) -> (f64, f64) {
    if d.is_empty() {
        return (1.0, 1.0);
    }
    (
        d.iter().copied().fold(f64::INFINITY, f64::min),
        d.iter().copied().fold(0.0, f64::max),
    )
}

/// `solver`'s one-step model in precision `u` on the QP its map runs on (the scaled one for
/// a Jacobi variant), with that scaling (empty without one).
fn deviation_model(
    solver: Method,
    qp: &qp_iter::ParametricQp,
    u: f64,
) -> Result<(DeviationHalf, Vec<f64>), String> {
    let plain = solver.with_scaling(qp_iter::Scaling::None);
    let half = |qp: &qp_iter::ParametricQp| -> Result<DeviationHalf, String> {
        match plain.kind {
            qp_iter::MethodKind::Pg(_) => iteration_rounding(&plain, qp, u)
                .map(DeviationHalf::Pg)
                .map_err(|e| e.to_string()),
            qp_iter::MethodKind::Admm(p) => admm_rounding(&plain, qp, u)
                .map(|a| DeviationHalf::Admm(a, p.relaxation))
                .map_err(|e| e.to_string()),
            _ => Err(format!(
                "the per-step deviation bound is derived for projected gradient and ADMM \
                 (plain and Jacobi-scaled), not {}",
                solver.name()
            )),
        }
    };
    if solver.scaling == qp_iter::Scaling::None {
        return Ok((half(qp)?, Vec::new()));
    }
    let map = solver.build(qp.clone()).map_err(|e| e.to_string())?;
    let qp_iter::MethodMap::Scaled(s) = &map else {
        return Err("internal: a Jacobi method without a scaling".into());
    };
    let h = half(qp_iter::IterationMap::problem(s.inner()))?;
    let d = s.scaling().to_vec();
    let (d_min, d_max) = scaling_extremes(&d);
    if !(d_min > 0.0 && d_max.is_finite()) {
        return Err("the Jacobi scaling is not positive and finite".into());
    }
    Ok((h, d))
}

/// One scalar's model of one window (the half of a [`DeviationKernel`]).
enum DeviationHalf {
    Pg(IterationRounding),
    Admm(AdmmRounding, f64),
}

impl DeviationBound {
    /// The tracker for `solver` (projected gradient or ADMM, plain or Jacobi-scaled) at
    /// K = `k`, or why the rounding is not covered.
    pub fn new(
        resolved: &ResolvedScenario,
        cert: &ClosedLoopCertificate,
        solver: Method,
        k: usize,
    ) -> Result<Result<Self, String>, ClosedLoopError> {
        if resolved.mhe_config()?.warm_start != mhe_core::WarmStart::Paper {
            return Ok(Err("only the paper's warm start is covered".into()));
        }
        let w32 = match per_window(resolved, cert, F32_UNIT_ROUNDOFF, |qp| {
            deviation_model(solver, qp, F32_UNIT_ROUNDOFF)
        })? {
            Ok(w) => w,
            Err(e) => return Ok(Err(e)),
        };
        let w64 = match per_window(resolved, cert, F64_UNIT_ROUNDOFF, |qp| {
            deviation_model(solver, qp, F64_UNIT_ROUNDOFF)
        })? {
            Ok(w) => w,
            Err(e) => return Ok(Err(e)),
        };
        let mut windows = Vec::with_capacity(w32.len());
        for (a, b) in w32.into_iter().zip(w64) {
            let ((h32, scaling), (h64, _)) = (a.model, b.model);
            let kernel = match (h32, h64) {
                (DeviationHalf::Pg(i32r), DeviationHalf::Pg(i64r)) => {
                    if !i32r.contracts() {
                        return Ok(Err(format!("window m = {}: r + a ≥ 1 in f32", a.m)));
                    }
                    DeviationKernel::Pg(i32r, i64r)
                }
                (DeviationHalf::Admm(a32, alpha), DeviationHalf::Admm(a64, _)) => {
                    if !(a32.perturbed_rate() < 1.0 && a64.perturbed_rate() < 1.0) {
                        return Ok(Err(format!("window m = {}: r + a ≥ 1 in f32", a.m)));
                    }
                    DeviationKernel::Admm(a32, a64, alpha)
                }
                _ => return Ok(Err("internal: the two scalars' models differ".into())),
            };
            windows.push(DeviationWindow {
                kernel,
                scaling,
                p32: a.propagation,
                p64: b.propagation,
                l_phi: b.l_phi,
                origin_offset: b.origin_offset,
            });
        }
        Ok(Ok(Self {
            horizon: windows.len() - 1,
            windows,
            k,
            t: 0,
            z_dev: 0.0,
            eps64: 0.0,
            z_star: 0.0,
            history: Vec::new(),
        }))
    }

    /// max_i d_prev,i/d_i over the previous window's variables: ‖D⁻¹(v, 0)‖ ≤ this ×
    /// ‖D_prev⁻¹v‖ (the paper's warm start embeds zᴷ_{t−1} as (zᴷ_{t−1}, 0) while the window
    /// grows, and copies it once it is full: 1 there).
    fn carry(&self, prev: usize, m: usize) -> f64 {
        let (dp, d) = (&self.windows[prev].scaling, &self.windows[m].scaling);
        if prev == m || d.is_empty() {
            return 1.0;
        }
        dp.iter().zip(d).map(|(a, b)| a / b).fold(0.0, f64::max)
    }

    /// The bound on ‖x̂_f32,t − x̂_f64,t‖ at the next t, from ‖θ_t‖ (the f64 run's window
    /// data: prior, u and y) and the norm of its u window.
    pub fn step(&mut self, theta_norm: f64, u_window_norm: f64) -> f64 {
        let u32 = F32_UNIT_ROUNDOFF;
        let m = self.t.min(self.horizon);
        let w = &self.windows[m];
        // The scaling's extremes and the relative errors γ₂ of y⁰ = z⁰/d̃ and z = d̃·y in each
        // scalar (0 without a scaling: the copies are exact).
        let scaled = !w.scaling.is_empty();
        let (d_min, d_max) = scaling_extremes(&w.scaling);
        let (g32, g64) = if scaled {
            (gamma(2, u32), gamma(2, F64_UNIT_ROUNDOFF))
        } else {
            (0.0, 0.0)
        };
        let carry = if self.t == 0 {
            1.0
        } else {
            self.carry(self.t.min(self.horizon + 1) - 1, m)
        };
        // ‖D⁻¹z*_t‖ (Euclidean ‖z*‖ ≤ o + L_Φ‖θ‖; the scaled problem's optimum within the
        // slack).
        let z_star = if scaled {
            (w.origin_offset + w.l_phi * theta_norm) / d_min * (1.0 + SCALED_OPTIMUM_SLACK)
        } else {
            w.origin_offset + w.l_phi * theta_norm
        };
        // The f64 run: ‖D⁻¹(z⁰ − z*)‖ ≤ carry·‖D⁻¹(zᴷ_{t−1} − z*_{t−1})‖ + carry·‖D⁻¹z*_{t−1}‖
        // + ‖D⁻¹z*_t‖ (any window change; at t = 0, z⁰ = (prior, 0) with ‖prior‖ ≤ ‖θ_0‖),
        // then y⁰'s rounded division.
        let e0 = if self.t == 0 {
            theta_norm / d_min + z_star
        } else {
            carry * (self.eps64 + self.z_star) + z_star
        };
        let e0 = e0 + g64 * (e0 + z_star);
        // The data: the prior differs by the deviation M steps back, u and y by rounding.
        let prior_dev = if self.t > self.horizon {
            self.history[self.t - self.horizon]
        } else {
            0.0
        };
        let d_theta = prior_dev + u32 * theta_norm;
        // y⁰'s deviation: the carried one and both rounded divisions
        // (‖D⁻¹z⁰_32‖ ≤ ‖D⁻¹z⁰_64‖ + carry·Z, ‖D⁻¹z⁰_64‖ ≤ ‖y*‖ + e0).
        let carried = carry * self.z_dev;
        let start = carried + g32 * (z_star + e0 + carried) + g64 * (z_star + e0);
        let run = Run {
            k: self.k,
            theta: theta_norm,
            d_theta,
            z_star,
            e0,
            start,
        };
        // (‖yᴷ_32 − yᴷ_64‖, ‖yᴷ_64 − y*‖) after K steps and the output.
        let (y_dev, eps64) = match &w.kernel {
            DeviationKernel::Pg(i32r, i64r) => run.pg(i32r, i64r),
            DeviationKernel::Admm(a32, a64, alpha) => run.admm(a32, a64, *alpha),
        };
        // z = d̃·y in each scalar: ‖D⁻¹(z₃₂ − z₆₄)‖ ≤ Δ_K + γ₂‖y₃₂‖ + γ₂‖y₆₄‖.
        let y_norm64 = z_star + eps64;
        let z_dev = y_dev + g32 * (y_norm64 + y_dev) + g64 * y_norm64;
        // x̂ = Ψ_m zᴷ + Υ_m u, each computed with its propagation rounding; Euclidean
        // ‖z‖ ≤ d_max‖D⁻¹z‖.
        let z_norm64 = d_max * (1.0 + g64) * y_norm64;
        let z_dev_e = d_max * z_dev;
        let (p32, p64) = (&w.p32, &w.p64);
        let x_dev = p32.psi * z_dev_e
            + p32.upsilon * u32 * u_window_norm
            + p32.from_z * (z_norm64 + z_dev_e)
            + p32.from_u * u_window_norm * (1.0 + u32)
            + p64.from_z * z_norm64
            + p64.from_u * u_window_norm;
        // zᴷ_64 = fl(d·yᴷ_64): ‖D⁻¹(zᴷ_64 − z*)‖ ≤ ‖yᴷ − y*‖ + γ₂‖yᴷ‖ for the next step's start.
        self.eps64 = eps64 + g64 * y_norm64;
        self.z_star = z_star;
        self.z_dev = z_dev;
        self.history.push(x_dev);
        self.t += 1;
        x_dev
    }
}

/// One step's quantities in the model's norm ([`DeviationBound::step`]).
struct Run {
    k: usize,
    /// ‖θ_t‖ and ‖θ̃_t − θ_t‖.
    theta: f64,
    d_theta: f64,
    /// ‖y*‖, the f64 run's ‖y⁰ − y*‖, and ‖y⁰_32 − y⁰_64‖.
    z_star: f64,
    e0: f64,
    start: f64,
}

impl Run {
    fn k(&self) -> i32 {
        i32::try_from(self.k).unwrap_or(i32::MAX)
    }

    /// Projected gradient: Δ_{k+1} ≤ (r + a₃₂)Δ_k + s_θΔθ + (a₃₂ + a₆₄)R + b₃₂(‖θ‖ + Δθ)
    /// + b₆₄‖θ‖ + c₃₂ + c₆₄, R ≥ every f64 iterate's norm.
    fn pg(&self, i32r: &IterationRounding, i64r: &IterationRounding) -> (f64, f64) {
        let (theta, d_theta) = (self.theta, self.d_theta);
        let q64 = i64r.perturbed_rate();
        let d64 = i64r.additive(self.k, self.z_star, theta);
        let eps64 = q64.powi(self.k()) * self.e0 + d64;
        // Every f64 iterate of this step: ‖y_k‖ ≤ ‖y*‖ + ‖y⁰ − y*‖ + d.
        let r_max = self.z_star + self.e0 + d64;
        let q = i32r.perturbed_rate();
        let forcing = i32r.theta_sensitivity * d_theta
            + (i32r.a + i64r.a) * r_max
            + i32r.b * (theta + d_theta)
            + i64r.b * theta
            + i32r.c
            + i64r.c;
        let qk = q.powi(self.k());
        (qk * self.start + (1.0 - qk) / (1.0 - q) * forcing, eps64)
    }

    /// ADMM (docs/theory.md, "ADMM in f32"): s⁰ = (I − H/ρ)z⁰ − q(θ)/ρ exactly, so the
    /// starts differ by ≤ c₀‖Δy⁰‖ + s_θΔθ + both start roundings; the exact step is
    /// r-Lipschitz on s and α·s_θ-Lipschitz in θ (‖αMF‖ ≤ α‖|F|‖/ρ, M = (H + ρI)⁻¹ ⪯ I/ρ),
    /// each computed step adds a‖s‖ + b‖θ‖ + c; the output clamps on the rounded boxes add
    /// u‖bounds‖ each.
    fn admm(&self, a32: &AdmmRounding, a64: &AdmmRounding, alpha: f64) -> (f64, f64) {
        let (theta, d_theta) = (self.theta, self.d_theta);
        let c0 = a64.start;
        // The f64 run against the exact one from the exact s⁰ (Δ₀ ≤ a₀‖y⁰‖ + b₀‖θ‖ + c₀′,
        // Δ_{k+1} ≤ qΔ_k + a(c₀rᵏe₀ + ‖s*‖) + b‖θ‖ + c), ‖s*‖ ≤ c₀‖y*‖ + ‖q‖/ρ.
        let s_star = c0 * self.z_star + a64.s_theta * theta + a64.s_c;
        let y0_64 = self.z_star + self.e0;
        let q64 = a64.perturbed_rate();
        let d64 = a64.a0 * y0_64
            + a64.b0 * theta
            + a64.c0
            + (a64.a * (c0 * self.e0 + s_star) + a64.b * theta + a64.c) / (1.0 - q64);
        // ‖vᴷ − y*‖ ≤ ‖sᴷ − s*‖ + u‖bounds‖ (Π is 1-Lipschitz, y* = Π(s*)).
        let eps64 = a64.rate.powi(self.k()) * c0 * self.e0 + d64 + a64.output;
        // Every f64 iterate: ‖s_k‖ ≤ ‖s*‖ + c₀e₀ + Δ.
        let r_s = s_star + c0 * self.e0 + d64;
        let start = c0 * self.start
            + a64.s_theta * d_theta
            + a32.a0 * (y0_64 + self.start)
            + a32.b0 * (theta + d_theta)
            + a32.c0
            + a64.a0 * y0_64
            + a64.b0 * theta
            + a64.c0;
        let q = a32.perturbed_rate();
        let forcing = alpha * a64.s_theta * d_theta
            + (a32.a + a64.a) * r_s
            + a32.b * (theta + d_theta)
            + a64.b * theta
            + a32.c
            + a64.c;
        let qk = q.powi(self.k());
        let s_dev = qk * start + (1.0 - qk) / (1.0 - q) * forcing;
        (s_dev + a32.output + a64.output, eps64)
    }
}
