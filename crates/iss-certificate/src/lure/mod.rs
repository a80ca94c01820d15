//! One certificate for the whole loop: the closed loop as a Lur'e system (issue 35).
//!
//! A projection onto a box is the identity minus a dead-zone, and both are slope-restricted
//! in [0, 1]; every method of `qp-iter` is then a linear system in feedback with
//! sector-bounded channels, and a quadratic storage function with multipliers on the
//! channels gives an LMI (docs/theory.md, "One certificate for the whole loop: a Lur'e
//! system (issue 35)").
//!
//! This module implements the **inner level**: for a method on one window's QP, a rate ρ_in
//! and prefactor c with ‖zᴷ − z*‖ ≤ φ_iqc(K)‖z⁰ − z*‖, φ_iqc(K) = c·ρ_inᴷ⁻ᵏ⁰ — the same
//! quantity, norm and premise as the method's own φ(K) of eq. (11), so that
//! min(φ(K), φ_iqc(K)) is again a sound φ(K) ([`InnerRate::phi_min`]). The LMI is solved by
//! a small pure-Rust barrier method (`lure::sdp`), and every returned storage matrix and
//! multiplier is re-checked independently (Jacobi eigenvalues with a margin above the
//! rounding of the terms) before a rate is reported.
//!
//! [`loop_level`] implements the **loop level** (Theorem L2): global ISS of the
//! sample-to-sample loop with every clamp of every inner iteration as a slope-[0, 1]
//! channel, from a chain of storages — today for loops given by their matrices and small
//! enough for the dense solver (docs/theory.md §3). [`scenario`] builds that loop from a
//! shipped scenario (the PG family with an unconstrained controller) and computes the
//! frozen-slope radius, a necessary condition for any loop certificate at K.

pub mod chain_outcome;
pub mod global;
pub mod global_outcome;
mod inner;
pub mod loop_level;
mod no_global;
pub mod scenario;
mod sdp;

use qp_iter::{Certificate, IterationMap, Method, MethodMap, ParametricQp};
#[cfg(feature = "serde")]
use serde::Serialize;

/// Why no inner rate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LureError {
    /// μ = λ_min(H) is not above the rounding of the eigenvalue computation: the QP is not
    /// (certifiably) strongly convex, and no linear rate exists for it.
    #[error(
        "the window's QP is not certifiably strongly convex (μ = {mu:e}, rounding allowance {allowance:e}): \
         no linear rate; raise the MHE weights (mhe.q, mhe.r, mhe.p) so that H ≻ 0"
    )]
    NotStronglyConvex {
        /// λ_min(H) as computed.
        mu: f64,
        /// The rounding allowance subtracted from it.
        allowance: f64,
    },
    /// The LMI is infeasible for every ρ < 1 (or its solution failed the independent
    /// check): this method's step has no certified rate on this QP.
    #[error(
        "{method}: the rate LMI certifies no ρ < 1 on this QP (step parameters outside the \
         certified range; choose the method's default parameters)"
    )]
    NoRate {
        /// The method.
        method: String,
    },
    /// The method is not a single block-structured map this module covers.
    #[error("{method}: no inner rate ({why})")]
    Unsupported {
        /// The method.
        method: String,
        /// Why.
        why: &'static str,
    },
    /// Building the method on the QP failed.
    #[error(transparent)]
    Qp(#[from] qp_iter::QpError),
}

/// The inner-level certificate of one method on one QP:
/// ‖zᴷ − z*‖ ≤ φ_iqc(K)‖z⁰ − z*‖ with φ_iqc(K) = `start` for K < `lag`, else
/// `prefactor`·`rate`^(K − `lag`).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct InnerRate {
    /// The method's name.
    pub method: String,
    /// ρ_in: the certified rate of the method's block state.
    pub rate: f64,
    /// c: everything that multiplies ρ_inᴷ⁻ᵏ⁰ (storage conditioning, the start map, κ(D)).
    pub prefactor: f64,
    /// k₀: steps before the rate applies (FISTA's restart step: 1).
    pub lag: usize,
    /// φ_iqc(K) for K < k₀.
    pub start: f64,
    /// The relative margin −λ_max(M)/scale(M) of the rate LMI in the independent check.
    pub lmi_margin: f64,
    /// The block storage matrix P̃ (row-major, m × m with m = 1 or 2).
    pub storage: Vec<f64>,
    /// The channel multipliers (gradient or resolvent sector, projection).
    pub multipliers: Vec<f64>,
}

impl InnerRate {
    /// φ_iqc(K).
    pub fn phi(&self, k: usize) -> f64 {
        if k < self.lag {
            return self.start;
        }
        let e = i32::try_from(k - self.lag).unwrap_or(i32::MAX);
        self.prefactor * self.rate.powi(e)
    }

    /// min(φ(K), φ_iqc(K)): both bound the same quantity in the same norm, so their minimum
    /// is a sound φ(K) for eq. (11).
    pub fn phi_min(&self, cert: &Certificate, k: usize) -> f64 {
        cert.phi(k).min(self.phi(k))
    }

    /// The smallest K ≤ `k_max` with φ_iqc(K) < `level` (None beyond `k_max`).
    pub fn first_below(&self, level: f64, k_max: usize) -> Option<usize> {
        first_k(|k| self.phi(k) < level, k_max)
    }
}

/// The smallest K ≤ `k_max` with `ok(K)`, for a predicate that is monotone in K from
/// some K on (a doubling search, then bisection).
pub fn first_k(ok: impl Fn(usize) -> bool, k_max: usize) -> Option<usize> {
    if ok(0) {
        return Some(0);
    }
    let mut hi = 1usize;
    while !ok(hi) {
        if hi >= k_max {
            return None;
        }
        hi = (hi * 2).min(k_max);
    }
    let mut lo = hi / 2; // !ok(lo)
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if ok(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(hi)
}

/// The spectrum bounds [μ, L] of H widened by the rounding of the eigenvalue solver
/// (16·n·ε·L each way), so the sector constraints hold for the exact H.
pub(crate) fn widened(qp: &ParametricQp) -> Result<(f64, f64), LureError> {
    let (mu, l) = (qp.mu(), qp.l());
    let allowance = 16.0 * qp.n().max(1) as f64 * f64::EPSILON * l.abs();
    let lo = mu - allowance;
    if !(lo > 0.0) || !l.is_finite() {
        return Err(LureError::NotStronglyConvex { mu, allowance });
    }
    Ok((lo, l + allowance))
}

/// Which map, with its parameters, on spectrum bounds [μ, L] (already widened).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InnerMap {
    /// Projected gradient with step α.
    Pg {
        /// α.
        step: f64,
    },
    /// V-FISTA with momentum β and step s after one projected-gradient step with step s.
    Fista {
        /// β.
        momentum: f64,
        /// s (1/L in `qp-iter`).
        step: f64,
    },
    /// ADMM (relaxed Douglas–Rachford) with penalty ρ and relaxation α, started with the
    /// gradient dual y⁰ = −(Hz⁰ + q).
    Admm {
        /// ρ.
        penalty: f64,
        /// α.
        relaxation: f64,
    },
}

/// The inner rate of `map` for every QP whose Hessian has its spectrum in [μ, L]
/// (and any closed convex Z with an exact projection).
pub fn inner_rate_for(name: &str, map: InnerMap, mu: f64, l: f64) -> Result<InnerRate, LureError> {
    if !(mu > 0.0) || !(l >= mu) || !l.is_finite() {
        return Err(LureError::NotStronglyConvex { mu, allowance: 0.0 });
    }
    let no_rate = || LureError::NoRate {
        method: name.to_string(),
    };
    let pack = |c: &inner::RateCertificate, prefactor: f64, lag: usize, start: f64| InnerRate {
        method: name.to_string(),
        rate: c.rho,
        prefactor,
        lag,
        start,
        lmi_margin: c.margin,
        storage: c.p.a.clone(),
        multipliers: c.lambda.clone(),
    };
    // Every map is invariant under H → H/L with the step scaled by L (ADMM's penalty by
    // 1/L): the LMI is solved on the spectrum [μ/L, 1], where its entries are O(1).
    let mu_n = mu / l;
    match map {
        InnerMap::Pg { step } => {
            let c = inner::pg_step(step * l, mu_n, 1.0)
                .best_rate()
                .ok_or_else(no_rate)?;
            Ok(pack(&c, 1.0, 0, 1.0))
        }
        InnerMap::Fista { momentum, step } => {
            let c = inner::fista_step(momentum, step * l, mu_n, 1.0)
                .best_rate()
                .ok_or_else(no_rate)?;
            // ξ₀ = (e, e) after the restart step, which contracts by max|1 − s·λ|;
            // ‖e_x‖² ≤ (P̃⁻¹)₁₁·V and V₀ = 𝟙ᵀP̃𝟙‖e_{x₀}‖².
            let p = &c.p.a;
            let det = p[0] * p[3] - p[1] * p[2];
            let inv11 = p[3] / det;
            let ones = p[0] + p[1] + p[2] + p[3];
            let first = (1.0 - step * mu).abs().max((1.0 - step * l).abs());
            let prefactor = (ones * inv11).sqrt() * first * (1.0 + 8.0 * f64::EPSILON);
            if !(prefactor.is_finite() && det > 0.0) {
                return Err(no_rate());
            }
            Ok(pack(&c, prefactor, 1, 1.0))
        }
        InnerMap::Admm {
            penalty,
            relaxation,
        } => {
            let c = inner::admm_step(penalty / l, relaxation, mu_n, 1.0)
                .best_rate()
                .ok_or_else(no_rate)?;
            // ‖vᴷ − z*‖ ≤ ‖sᴷ − s*‖ and s⁰ − s* = (I − H/ρ)(z⁰ − z*).
            let start = (1.0 - mu / penalty).abs().max((1.0 - l / penalty).abs())
                * (1.0 + 8.0 * f64::EPSILON);
            Ok(pack(&c, start, 0, start))
        }
    }
}

/// The inner rate of `method` on `qp` (the window's QP): the map `qp-iter` runs, with its
/// own step parameters, and on the Jacobi-scaled problem for the `-jacobi` variants (the
/// prefactor then gains κ(D), as `qp_iter::scaled` explains).
pub fn inner_rate(qp: &ParametricQp, method: Method) -> Result<InnerRate, LureError> {
    let map = method.build(qp.clone())?;
    rate_of_map(&map, &method.name())
}

fn rate_of_map(map: &MethodMap, name: &str) -> Result<InnerRate, LureError> {
    let (mu, l) = widened(map.problem())?;
    match map {
        MethodMap::Pg(m) => inner_rate_for(name, InnerMap::Pg { step: m.alpha() }, mu, l),
        MethodMap::Fista(m) => inner_rate_for(
            name,
            InnerMap::Fista {
                momentum: m.momentum(),
                step: m.step_size(),
            },
            mu,
            l,
        ),
        MethodMap::Admm(m) => inner_rate_for(
            name,
            InnerMap::Admm {
                penalty: m.rho(),
                relaxation: m.relaxation(),
            },
            mu,
            l,
        ),
        MethodMap::Scaled(s) => {
            let mut r = rate_of_map(s.inner(), name)?;
            let kd = s.kappa_d() * (1.0 + 4.0 * f64::EPSILON);
            r.prefactor *= kd;
            r.start *= kd;
            Ok(r)
        }
        MethodMap::AdmmSplit(_) => Err(LureError::Unsupported {
            method: name.to_string(),
            why: "ADMM split on general rows: its iterate is feasible only in the limit",
        }),
        #[allow(unreachable_patterns)]
        _ => Err(LureError::Unsupported {
            method: name.to_string(),
            why: "a map this module does not model",
        }),
    }
}
