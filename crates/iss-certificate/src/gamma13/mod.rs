//! γ₁,₃ of Assumption 4: the gain from estimation error e to state x of the closed loop
//! x⁺ = Ax + Bπ(x + e) + w¹ under the box-constrained condensed MPC π. Derivations in
//! docs/theory.md, "The certificate on any plant".
//!
//! ## Contraction over the local gains (certified)
//! π(x) = E₀Π^H_{𝒰^N}(−H⁻¹Fx) is continuous and piecewise affine; along any segment,
//! π(x) − π(x') = K̄(x − x') with K̄ in the convex hull of the local gains K_𝔽, and that hull
//! lies in the family {K(M) = K_lin + G·M·R : 0 ⪯ M ⪯ I_s} ([`mpc_core::free_sets`]; only
//! the s saturable variables can leave the free set). For a metric S ≻ 0 let
//!
//! - λ_S ≥ sup_M ‖A + BK(M)‖_S (‖M‖_S = ‖S^{½}MS^{−½}‖₂), and
//! - g_S ≥ sup_M ‖S^{½}BK(M)‖₂,
//!
//! both computed by the S-procedure ([`mpc_core::robust_norm`]: exact over the family, one
//! scalar search, polynomial in N·n_u). With f(x) = Ax + Bπ(x), f(0) = 0 (0 ∈ 𝒰):
//!
//! x⁺ = f(x) + B(π(x + e) − π(x)) + Ew¹ ⇒ ‖x⁺‖_S ≤ λ_S‖x‖_S + g_S‖e‖ + ‖S^{½}E‖₂‖w¹‖.
//!
//! If λ_S < 1, Assumption 4 holds with β₁(s, g) = √(λ̄(S)/λ(S))·λ_S^g·s,
//! **γ₁,₃ = g_S / (√λ(S)(1 − λ_S))**, γ₁ʷ = ‖S^{½}E‖₂/(√λ(S)(1 − λ_S)) (Lohmiller & Slotine,
//! Automatica 34(6), 1998, specialised to piecewise-affine laws). The candidate metrics are
//! listed in `metrics.rs`; the smallest γ₁,₃ wins.
//!
//! The family is tightened by a partial enumeration ([`mpc_core::free_sets`]): the
//! saturation pattern of the first k input blocks is fixed (2^{|𝒫_k|} families, k as large
//! as [`GAMMA13_PATTERN_FAMILIES`] allows) and only the later blocks are relaxed; λ_S and g_S
//! are the smaller of the single-family and the partial-enumeration bounds. When 2^s is
//! affordable (s ≤ `max_vars`) the same figures are also taken over the 2^s free sets only
//! (the vertex maximum, never above the families'); with 𝒰 = ℝ^{n_u} (s = 0) the law is
//! linear and γ₁,₃ = Σ_k ‖(A + BK_lin)^k BK_lin‖₂ (impulse response, with a certified tail
//! bound) is used as well.
//!
//! ## Void reasons
//! A certificate that cannot exist says why ([`Gamma13Void`]): 0 ∉ 𝒰; the dynamics with every
//! bounded input saturated do not contract (with 𝒰 bounded and |λ(A)| > 1 no global gain
//! exists at all); no metric found; a user value refuted by simulation.

mod enumerate;
mod metrics;
mod plan;
mod report;
mod sampled;

pub use plan::{Gamma13Chunk, Gamma13Plan, Gamma13Stage};
pub use report::{
    Gamma13Report, Gamma13Source, gamma13_report, gamma13_report_budgeted, gamma13_report_with,
};
pub use sampled::{Gamma13Sampled, gamma13_sampled};

use faer::Mat;
use lti_model::matrix::spectral_norm;
use lti_model::numfmt::sig4;
use lti_model::spectral::Stability;
use mpc_core::{CondensedMpc, MpcError, worst_case_norm};
use rayon::prelude::*;
#[cfg(feature = "serde")]
use serde::Serialize;

use metrics::{Family, Metric};

/// One candidate metric S and its contraction figures.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct MetricResult {
    /// Which S (`"identity"`, `"dare-terminal"`, `"open-loop-lyapunov"`, `"robust-riccati(λ=…)"`, …).
    pub metric: String,
    /// λ_S = sup over the family of ‖A + BK(M)‖_S (S-procedure).
    pub contraction: f64,
    /// g_S = sup over the family of ‖S^{½}BK(M)‖₂ (S-procedure); ∞ (not computed) when
    /// λ_S ≥ 1.
    pub input_gain: f64,
    /// max over the 2^s free sets of ‖A + BK_𝔽‖_S (when enumerated; a lower bound ≥ 1 once
    /// it reaches 1, because the enumeration drops the metric there).
    pub contraction_enumerated: Option<f64>,
    /// max over the 2^s free sets of ‖S^{½}BK_𝔽‖₂ (when enumerated and the metric contracts
    /// there; None when the enumeration dropped it at λ ≥ 1).
    pub input_gain_enumerated: Option<f64>,
    /// √(λ̄(S)/λ(S)): prefactor of β₁.
    pub condition_sqrt: f64,
    /// γ₁,₃ = g_S/(√λ(S)(1 − λ_S)) from the family, or ∞ when λ_S ≥ 1.
    pub gamma13_polynomial: f64,
    /// The same from the enumerated figures (when enumerated).
    pub gamma13_enumerated: Option<f64>,
    /// min of the two: this metric's certified γ₁,₃.
    pub gamma13: f64,
    /// γ₁ʷ = ‖S^{½}E‖₂/(√λ(S)(1 − λ_S)) for the λ_S used in `gamma13`, or ∞ (w¹ enters as
    /// Ew¹; with the paper's E = I this is √(λ̄(S)/λ(S))/(1 − λ_S)).
    pub gamma1w: f64,
    /// ‖S^{½}B‖₂: how an additive input error d (x⁺ = Ax + Bπ(x + e) + Bd + w¹) enters.
    pub input_matrix_gain: f64,
    /// γ₁,₄ = ‖S^{½}B‖₂/(√λ(S)(1 − λ_S)) with the λ_S of `gamma13`: the gain from d to x
    /// in the same estimate as γ₁,₃ (the sub-optimal MPC's error, [`crate::joint`]), or ∞.
    pub gamma14: f64,
    /// Why gains of this metric are not computed (null in JSON) because it does not contract
    /// (λ_S ≥ 1); None when every figure is computed.
    pub not_computed: Option<NoContraction>,
}

/// Why gains of a metric S are not computed: it does not contract (λ_S ≥ 1) over the family
/// 0 ⪯ M ⪯ I, over the free sets, or both. Serialised as its sentence.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum NoContraction {
    /// λ_S ≥ 1 over the family, but λ < 1 over the free sets: only the enumerated figures
    /// are computed.
    FamilyOnly {
        /// λ_S over the family.
        contraction: f64,
        /// λ over the free sets (< 1).
        enumerated: f64,
    },
    /// λ ≥ 1 over the free sets (the enumeration stops there): nothing is computed.
    Enumerated {
        /// λ_S over the family.
        contraction: f64,
        /// The lower bound ≥ 1 reached over the free sets.
        enumerated: f64,
    },
    /// λ_S ≥ 1 over the family, free sets not enumerated: nothing is computed.
    Family {
        /// λ_S over the family.
        contraction: f64,
    },
}

impl NoContraction {
    /// Why `c`'s gains are not computed; None when its metric contracts wherever it was
    /// evaluated.
    fn of(c: &MetricResult) -> Option<Self> {
        let contraction = c.contraction;
        let enumerated = c.contraction_enumerated;
        if contraction < 1.0 && enumerated.is_none_or(|l| l < 1.0) {
            return None;
        }
        Some(match enumerated {
            Some(l) if l < 1.0 => Self::FamilyOnly {
                contraction,
                enumerated: l,
            },
            Some(l) => Self::Enumerated {
                contraction,
                enumerated: l,
            },
            None => Self::Family { contraction },
        })
    }
}

impl std::fmt::Display for NoContraction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Self::FamilyOnly {
                contraction,
                enumerated,
            } => write!(
                f,
                "λ_S = {} ≥ 1 over the family 0 ⪯ M ⪯ I: input_gain and gamma13_polynomial are \
                 not computed; over the free sets λ = {} < 1 gives the enumerated figures",
                sig4(contraction),
                sig4(enumerated)
            ),
            Self::Enumerated {
                contraction,
                enumerated,
            } => write!(
                f,
                "the metric does not contract (λ_S = {} ≥ 1 over the family, ≥ {} over the \
                 free sets): input_gain, input_gain_enumerated, gamma13 and gamma1w are not \
                 computed",
                sig4(contraction),
                sig4(enumerated)
            ),
            Self::Family { contraction } => write!(
                f,
                "the metric does not contract (λ_S = {} ≥ 1): input_gain, gamma13 and gamma1w \
                 are not computed",
                sig4(contraction)
            ),
        }
    }
}

#[cfg(feature = "serde")]
impl Serialize for NoContraction {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Which bound gave the certified γ₁,₃.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Gamma13Method {
    /// The S-procedure over the whole family 0 ⪯ M ⪯ I (any size).
    Polynomial,
    /// The maximum over the 2^s free sets (small s).
    Enumerated,
    /// 𝒰 = ℝ^{n_u}: the impulse-response sum of the linear closed loop.
    Linear,
}

/// Why no γ₁,₃ is available: a typed reason with a [`std::fmt::Display`] sentence.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(tag = "kind", rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Gamma13Void {
    /// 0 ∉ 𝒰: π(0) need not be 0, so the origin is not an equilibrium.
    OriginOutsideInputSet,
    /// With every bounded input saturated, x⁺ = A_sat·x + const with ρ(A_sat) ≥ 1; A_sat = A
    /// when 𝒰 is bounded. Every local-gain family contains this gain, so no metric contracts;
    /// with 𝒰 bounded and ρ(A) > 1 no global gain exists at all (the unstable mode grows from
    /// large states whatever u ∈ 𝒰).
    SaturatedDynamicsNotStable {
        /// ρ(A_sat) = max |λ|.
        spectral_radius: f64,
        /// Every input component has two finite bounds (so A_sat = A).
        input_bounded: bool,
        /// ρ(A_sat) = 1 exactly (every eigenvalue in the closed unit disc, some on the circle:
        /// Jordan chains allowed), decided from the structure of A_sat
        /// (`lti_model::spectral::classify`), not from rounded eigenvalue moduli.
        marginal: bool,
    },
    /// Every candidate metric has λ_S ≥ 1.
    NoContractingMetric {
        /// The smallest λ_S found.
        best_contraction: f64,
        /// The metric that achieved it.
        metric: String,
        /// Whether the 2^s free sets were enumerated (else the family bounds only).
        enumerated: bool,
        /// Leading input blocks enumerated exactly in the family bound.
        pattern_blocks: usize,
    },
    /// The MPC has state constraints: the analysis assumes box-constrained inputs only
    /// (issue 15), so no certified γ₁,₃ exists.
    StateConstrainedMpc,
    /// The MPC has output constraints C x_k ∈ 𝒴_c (`mpc.output`) and no state constraints:
    /// the same box-input-only analysis does not apply, so no certified γ₁,₃ exists.
    OutputConstrainedMpc,
    /// No metric contracts by the family bound, and the free-set enumeration that could
    /// find one was not run for the analysis budget: not computed, not void (issue 37).
    NotComputedWithinBudget {
        /// The smallest λ_S of the family bounds.
        best_contraction: f64,
        /// The skipped enumeration, its estimate and the budget.
        not_computed: crate::budget::NotComputed,
    },
    /// A user value below the sampled lower estimate: provably not a valid γ₁,₃.
    UserValueRefuted {
        /// The value supplied.
        user: f64,
        /// The sampled lower estimate that exceeds it.
        sampled_lower: f64,
    },
}

impl std::fmt::Display for Gamma13Void {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::StateConstrainedMpc => f.write_str(mpc_core::STATE_CONSTRAINED_VOID_REASON),
            Self::OutputConstrainedMpc => f.write_str(mpc_core::OUTPUT_CONSTRAINED_VOID_REASON),
            Self::OriginOutsideInputSet => write!(
                f,
                "0 ∉ 𝒰: the MPC law need not vanish at x = 0, so 0 is not an equilibrium of \
                 x⁺ = Ax + Bπ(x) and Assumption 4 (ISS about 0) cannot hold; use an input set \
                 that contains 0"
            ),
            Self::SaturatedDynamicsNotStable {
                spectral_radius: r,
                input_bounded: true,
                marginal: false,
            } => write!(
                f,
                "A has |λ| = {r:.3} ≥ 1 and 𝒰 is bounded: no global ISS gain from e to x exists \
                 (Assumption 4 cannot hold globally)"
            ),
            Self::SaturatedDynamicsNotStable {
                spectral_radius: r,
                input_bounded: true,
                marginal: true,
            } => write!(
                f,
                "A has |λ| = {r:.3} ≥ 1 (marginally stable) and 𝒰 is bounded: with every input \
                 saturated x⁺ = Ax + const does not contract, so no metric certifies a global \
                 gain from e to x (Assumption 4 cannot be certified globally)"
            ),
            Self::SaturatedDynamicsNotStable {
                spectral_radius: r,
                input_bounded: false,
                ..
            } => write!(
                f,
                "with every bounded input saturated, A + BK_sat has |λ| = {r:.3} ≥ 1: the local \
                 gains include one that does not contract, so no contraction metric exists \
                 (global ISS is not excluded; supply γ₁,₃ if you know one)"
            ),
            Self::NoContractingMetric {
                best_contraction,
                metric,
                enumerated,
                pattern_blocks,
            } => {
                write!(
                    f,
                    "no metric found in which every local gain contracts (best λ_S = \
                     {}, metric {metric}; ",
                    sig4(*best_contraction)
                )?;
                if *enumerated {
                    write!(f, "all free sets enumerated)")
                } else {
                    write!(
                        f,
                        "S-procedure over 0 ⪯ Π ⪯ I with the first {pattern_blocks} input \
                         block(s) enumerated)"
                    )
                }
            }
            Self::NotComputedWithinBudget {
                best_contraction,
                not_computed,
            } => write!(
                f,
                "{not_computed}; by the family bound alone no metric contracts (best λ_S = {}), \
                 and the enumeration decides whether one does",
                sig4(*best_contraction)
            ),
            Self::UserValueRefuted {
                user,
                sampled_lower,
            } => write!(
                f,
                "user-supplied γ₁,₃ = {user} is provably wrong: a simulated error sequence gives \
                 sup‖x‖/sup‖e‖ = {} > {user}; the certificate is not computed \
                 with it",
                lti_model::numfmt::sig4(*sampled_lower)
            ),
        }
    }
}

/// A computation that was not run, and why (never a silent cap).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct SkippedComputation {
    /// What was not computed.
    pub computation: String,
    /// Why, and what is used instead.
    pub reason: crate::outcome::SkipReason,
}

impl std::fmt::Display for SkippedComputation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} skipped: {}", self.computation, self.reason)
    }
}

/// Result of [`gamma13_certified`].
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Gamma13Certificate {
    /// Certified γ₁,₃: the smallest over metrics and methods; ∞ when void.
    pub gamma13: f64,
    /// The bound that gave it (None when void).
    pub method: Option<Gamma13Method>,
    /// The metric that gave it (None when void).
    pub metric: Option<String>,
    /// Leading input blocks whose saturation pattern is enumerated exactly in the family
    /// bound (partial enumeration; 0: the single family).
    pub pattern_blocks: usize,
    /// Number of families of the partial enumeration (0 when `pattern_blocks` = 0).
    pub pattern_families: usize,
    /// Smallest γ₁,₃ over metrics from the family bounds (∞ if none contracts).
    pub gamma13_polynomial: f64,
    /// Smallest γ₁,₃ over the enumerated metrics from the free-set maxima (when enumerated).
    pub gamma13_enumerated: Option<f64>,
    /// Impulse-response γ₁,₃ of the linear law (when s = 0 and the loop is stable).
    pub gamma13_linear: Option<f64>,
    /// γ₁,₄: the gain from an additive input error d to x in the *same* estimate as
    /// `gamma13` (same metric, or the impulse response Σ‖A_clᵏB‖₂ for the linear law); ∞
    /// when void. Used by the joint MPC + MHE certificate ([`crate::joint`]).
    pub gamma14: f64,
    /// γ₁ʷ of the same estimate (∞ when void).
    pub gamma1w: f64,
    /// β₁(s, t) = `beta_prefactor`·`beta_rate`ᵗ·s of the same estimate (None when void;
    /// JSON null).
    pub beta_prefactor: Option<f64>,
    /// See `beta_prefactor`.
    pub beta_rate: Option<f64>,
    /// Every candidate's figures.
    pub candidates: Vec<MetricResult>,
    /// N·n_u.
    pub variables: usize,
    /// s, the saturable variables.
    pub saturable: usize,
    /// Free sets enumerated (2^s when `enumerated`, else 0).
    pub free_sets: u64,
    /// Whether the free sets were enumerated.
    pub enumerated: bool,
    /// Why there is no γ₁,₃ (None when certified).
    pub void: Option<Gamma13Void>,
    /// Computations not run, with the reason.
    pub skipped: Vec<SkippedComputation>,
    /// The free-set enumeration skipped for the analysis budget (not for the cap on s): a
    /// verdict the enumeration could change is "not computed within the budget", not void.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub over_budget: Option<crate::budget::NotComputed>,
}

fn void_certificate(
    variables: usize,
    saturable: usize,
    void: Gamma13Void,
    skipped: Vec<SkippedComputation>,
) -> Gamma13Certificate {
    Gamma13Certificate {
        gamma13: f64::INFINITY,
        method: None,
        metric: None,
        pattern_blocks: 0,
        pattern_families: 0,
        gamma13_polynomial: f64::INFINITY,
        gamma13_enumerated: None,
        gamma13_linear: None,
        gamma14: f64::INFINITY,
        gamma1w: f64::INFINITY,
        beta_prefactor: None,
        beta_rate: None,
        candidates: Vec::new(),
        variables,
        saturable,
        free_sets: 0,
        enumerated: false,
        void: Some(void),
        skipped,
        over_budget: None,
    }
}

/// λ_S over the family for metric `m` (S-procedure).
fn family_contraction(fam: &Family, m: &Metric) -> Result<f64, MpcError> {
    let (h, nh) = (&m.half, &m.neg_half);
    Ok(worst_case_norm(
        (h * &fam.a_mid * nh).as_ref(),
        (h * &fam.u).as_ref(),
        (&fam.v * nh).as_ref(),
    )?
    .bound)
}

/// g_S over the family for metric `m` (S-procedure).
fn family_input_gain(fam: &Family, m: &Metric) -> Result<f64, MpcError> {
    let h = &m.half;
    Ok(worst_case_norm(
        (h * &fam.bk_mid).as_ref(),
        (h * &fam.u).as_ref(),
        fam.v.as_ref(),
    )?
    .bound)
}

/// (λ_S, g_S) for metric `m`: the smaller of the single-family bound and the maximum over
/// the partial enumeration's families (both sound). A running maximum that reaches the
/// single-family value can no longer win and stops; g_S is not computed (∞) when λ_S ≥ 1.
fn metric_figures(fam: &Family, patterns: &[Family], m: &Metric) -> Result<(f64, f64), MpcError> {
    let mut lam = family_contraction(fam, m)?;
    if !patterns.is_empty() {
        let mut worst = 0.0_f64;
        for f in patterns {
            worst = worst.max(family_contraction(f, m)?);
            if worst >= lam {
                break;
            }
        }
        lam = lam.min(worst);
    }
    if lam >= 1.0 {
        return Ok((lam, f64::INFINITY));
    }
    let mut gin = family_input_gain(fam, m)?;
    if !patterns.is_empty() {
        let mut worst = 0.0_f64;
        for f in patterns {
            worst = worst.max(family_input_gain(f, m)?);
            if worst >= gin {
                break;
            }
        }
        gin = gin.min(worst);
    }
    Ok((lam, gin))
}

/// The λ_S behind a candidate's `gamma13`: the free-set maximum when that gave it, else the
/// family bound.
fn used_contraction(c: &MetricResult) -> f64 {
    match (c.contraction_enumerated, c.gamma13_enumerated) {
        (Some(l), Some(e)) if e <= c.gamma13_polynomial => l,
        _ => c.contraction,
    }
}

/// (γ₁,₃, γ₁ʷ) of one metric: g_S/(√λ(S)(1 − λ_S)) and ‖S^{½}E‖₂/(√λ(S)(1 − λ_S)), where
/// `noise_gain` = ‖S^{½}E‖₂ (w¹ enters as Ew¹; the paper's E = I gives √λ̄(S)).
fn gammas(lam: f64, gin: f64, m: &Metric, noise_gain: f64) -> (f64, f64) {
    if lam < 1.0 {
        (
            gin / (m.lmin.sqrt() * (1.0 - lam)),
            noise_gain / (m.lmin.sqrt() * (1.0 - lam)),
        )
    } else {
        (f64::INFINITY, f64::INFINITY)
    }
}

/// γ₁,₃ = Σ_{k≥0} ‖A_clᵏ·BK‖₂ (`input` = BK; with `input` = B it is γ₁,₄) for the linear
/// law, summed until a certified tail bound
/// (from a metric with λ_S < 1) is below 10⁻⁸ of the sum; None if that takes > 10⁶ terms.
fn impulse_response_gain(fam: &Family, input: &Mat<f64>, m: &Metric, lam: f64) -> Option<f64> {
    let a = &fam.a_lin;
    let mut term = input.clone(); // A_clᵏ·(BK or B)
    let mut sum = 0.0;
    for _ in 0..1_000_000usize {
        let tail = lti_model::matrix::spectral_norm((&m.half * &term).as_ref())
            / (m.lmin.sqrt() * (1.0 - lam));
        if tail <= 1e-8 * sum {
            return Some((sum + tail) * (1.0 + 1e-10));
        }
        sum += lti_model::matrix::spectral_norm(term.as_ref());
        term = a * &term;
    }
    None
}

/// Estimated work (multiply-adds) of the free-set enumeration of [`gamma13_certified`] with
/// `metrics` metrics: 2^s free sets, each a Cholesky factorisation and n_x solves of the free
/// block (nf ≤ N·n_u: nf³/6 + 2nf²n_x) and per metric three n_x × n_x products and two
/// symmetric eigenvalue bounds (≈ 26 n_x³ with the eigen-solve's sweeps); ∞ when s > 62.
///
/// ```
/// # use faer::{mat, Mat};
/// # use lti_model::{BoxSet, LtiSystem};
/// # use mpc_core::{CondensedMpc, MpcConfig};
/// let sys = LtiSystem::new(mat![[0.9, 0.1], [0.0, 0.8]], mat![[0.0], [0.1]], mat![[1.0, 0.0]]).unwrap();
/// let mpc = CondensedMpc::new(&sys, MpcConfig::new(4, Mat::identity(2, 2), mat![[0.1]],
///     BoxSet::symmetric(&[1.0]).unwrap())).unwrap();
/// let w = iss_certificate::gamma13::enumeration_work(&mpc, 3);
/// assert!(w > 16.0 && w < 1e6); // 2^4 free sets of a 4-variable QP, n_x = 2
/// ```
pub fn enumeration_work(mpc: &CondensedMpc, metrics: usize) -> f64 {
    let s = mpc.saturable().len();
    if s > 62 {
        return f64::INFINITY;
    }
    let (n, nx) = (mpc.qp().n() as f64, mpc.nx() as f64);
    let per_set = n.powi(3) / 6.0 + 2.0 * n * n * nx + metrics as f64 * 26.0 * nx.powi(3);
    (1u64 << s) as f64 * per_set
}

/// Family budget of the partial enumeration (module docs): the saturation patterns of the
/// leading input blocks are enumerated while 2^{|𝒫_k|} ≤ this.
pub const GAMMA13_PATTERN_FAMILIES: u64 = 16;

/// Certified γ₁,₃ (module docs) with the default pattern budget
/// [`GAMMA13_PATTERN_FAMILIES`]. `max_vars` caps s for the free-set enumeration (at most 30;
/// 2^s small solves); above it the family bounds alone are used and the skip is recorded.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{BoxSet, LtiSystem};
/// use mpc_core::{CondensedMpc, MpcConfig};
/// let sys = LtiSystem::new(mat![[0.9, 0.1], [0.0, 0.8]], mat![[0.0], [0.1]], mat![[1.0, 0.0]]).unwrap();
/// let mpc = CondensedMpc::new(&sys, MpcConfig::new(4, Mat::identity(2, 2), mat![[0.1]],
///     BoxSet::symmetric(&[1.0]).unwrap())).unwrap();
/// let c = iss_certificate::gamma13::gamma13_certified(&mpc, 20).unwrap();
/// assert!(c.enumerated && c.gamma13.is_finite() && c.void.is_none());
/// assert!(c.gamma13_enumerated.unwrap() <= c.gamma13_polynomial * (1.0 + 1e-9));
/// ```
pub fn gamma13_certified(
    mpc: &CondensedMpc,
    max_vars: usize,
) -> Result<Gamma13Certificate, MpcError> {
    gamma13_certified_with(mpc, max_vars, GAMMA13_PATTERN_FAMILIES)
}

/// [`gamma13_certified`] with a family budget `pattern_families` for the partial
/// enumeration (1: the single family only).
pub fn gamma13_certified_with(
    mpc: &CondensedMpc,
    max_vars: usize,
    pattern_families: u64,
) -> Result<Gamma13Certificate, MpcError> {
    gamma13_certified_budgeted(mpc, max_vars, pattern_families, f64::INFINITY)
}

/// [`gamma13_certified_with`] with a time budget for the free-set enumeration: when its
/// estimated time ([`enumeration_work`] at [`crate::budget::SCALAR_RATE`]) exceeds
/// `phase_seconds`, the enumeration is not run, the polynomial bound alone is used and the
/// skip says so (with the estimate, the budget and the scenario key
/// `certificate.phase_seconds` that raises it).
pub fn gamma13_certified_budgeted(
    mpc: &CondensedMpc,
    max_vars: usize,
    pattern_families: u64,
    phase_seconds: f64,
) -> Result<Gamma13Certificate, MpcError> {
    match Gamma13Plan::start(mpc, max_vars, pattern_families, phase_seconds)? {
        Gamma13Stage::Done(c) => Ok(*c),
        Gamma13Stage::Plan(plan) => {
            // One chunk per task (in order), so the result does not depend on the thread
            // count.
            let chunks = (0..plan.chunks())
                .into_par_iter()
                .map(|i| plan.chunk(i))
                .collect();
            plan.finish(chunks)
        }
    }
}

#[cfg(test)]
mod tests;
