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
    F32_UNIT_ROUNDOFF, F64_UNIT_ROUNDOFF, IterationRounding, abs_norm_bound, gamma,
    iteration_rounding,
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
/// unit round-off `u`, or why the rounding is not covered (the first reason), with each
/// window's propagation rounding, L_Φ and o_m. Theorem 1 itself takes every method's K-step
/// model, and [`DeviationBound`] builds its own one-step models (PG, V-FISTA and ADMM, plain or scaled).
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

mod deviation;
pub use deviation::DeviationBound;
