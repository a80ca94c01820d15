//! What Theorem 1 guarantees, not only that it holds: the certified asymptotic gains
//!
//!   lim sup_t ‖x_t‖ ≤ g_x·w̄,  lim sup_t ε_t ≤ g_ε·w̄,  lim sup_t ‖e_t‖ ≤ g_e·w̄,
//!
//! w̄ ≥ sup_t ‖w_t‖₂ (w = (w¹, w²), every w_t ∈ 𝒲), for the closed loop at a K that Theorem 1
//! certifies, and the measured counterparts of one simulated run ([`MeasuredGains`]).
//! Derivation and proof: docs/theory.md, "Certified asymptotic gains".
//!
//! ## The comparison system of lim sups
//! Theorem 1 (ρ(Γ) < 1 with every premise) makes every signal bounded, so the lim sups
//! X = lim sup‖x_t‖, Ɛ = lim sup ε_t, E = lim sup‖e_t‖ are finite. The one-step and M-step
//! inequalities behind Props. 1–3 hold at every t > M + 1 with the window full (σ_t = 0
//! there: the mended Lemma 1's σ_t has finite support t ≤ M); taking lim sup of each
//! (lim sup of a sum ≤ sum of lim sups, a shifted sequence has the same lim sup) gives
//!
//! - plant (Assumption 4 in its one-step form, metric S): X ≤ γ₁,₃E + γ₁ʷw̄;
//! - Prop. 1 (eq. (lemma 2 5)): Ɛ ≤ φƐ + C₁X + C₂E + C₃ʷw̄, i.e.
//!   Ɛ ≤ γ₂,₁X + γ₂,₃E + γ₂ʷw̄ (C₃ʷ = C₃‖F‖);
//! - Prop. 2 (the M-step inequality, ρ^M = 6η^M, W = ‖e‖²_P):
//!   lim sup W ≤ ρ^M lim sup W + 2H̄Ɛ² + 6λ̄(Q)S_η w̄², S_η = Σ_{j=1}^{M} η^{j−1}, hence
//!   E ≤ a_ε Ɛ + a_w w̄ with a_ε = √(2Λ^H̄_P/(1 − ρ^M)), a_w = √(6Λ^Q_P S_η/(1 − ρ^M)).
//!
//! So s = (X, Ɛ, E) satisfies s ≤ Γ̃s + g̃w̄ with Γ̃ ≥ 0; a_ε ≤ C_ε = γ₃,₂ and a_w ≤ C_w = γ₃ʷ,
//! so Γ̃ ≤ Γ (Theorem 1's gain matrix) entrywise and ρ(Γ̃) ≤ ρ(Γ) < 1. Then I − Γ̃ is a
//! nonsingular M-matrix, (I − Γ̃)⁻¹ ≥ 0, and s ≤ (I − Γ̃)⁻¹g̃w̄: that is (g_x, g_ε, g_e)
//! ([`AsymptoticGains`]). The same argument with Theorem 1's own gains and w-gains
//! (rows of Props. 1 and 3 as printed) gives the larger [`AsymptoticGains::theorem1`],
//! reported beside it.
//!
//! ## When it is void
//! Exactly when Theorem 1 does not certify ISS at that K ([`AsymptoticVoid`]): a premise
//! fails, or K is below K_min (det(I − Γ) ≤ 0). Without the global boundedness the lim sups
//! may be infinite and s ≤ Γ̃s + g̃w̄ says nothing. With a user-supplied γ₁,₃ the plant's gain
//! from w¹, γ₁ʷ, is not known, and the bound is void with that reason.

#[cfg(feature = "serde")]
use serde::Serialize;

use crate::analysis::IssAnalysis;
use crate::budget::NotComputed;
use crate::certificate::{ClosedLoopCertificate, SolverCertificate};
use crate::outcome::{Gamma1wUnknown, VoidReason};
use crate::small_gain::GainMatrix;
use closed_loop::record::Trace;
use lti_model::numfmt::sig4;
use qp_iter::Method;

/// Node names of the comparison systems, in order: x, ε, e.
pub const NODES: [&str; 3] = ["x", "epsilon", "e"];

/// A nonnegative comparison system s ≤ Γs + g·w̄ on the nodes (x, ε, e) and its solution.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct ComparisonSystem {
    /// Γ, row-major: `matrix[i][j]` is the gain from node j into node i ([`NODES`]).
    pub matrix: [[f64; 3]; 3],
    /// g: the gain from w̄ into each node.
    pub input: [f64; 3],
    /// ρ(Γ) (< 1 whenever a solution is reported).
    pub spectral_radius: f64,
    /// (I − Γ)⁻¹g: (g_x, g_ε, g_e).
    pub gains: [f64; 3],
}

impl ComparisonSystem {
    /// Solves s = (I − Γ)⁻¹g when ρ(Γ) < 1 (None otherwise, or for a negative or non-finite
    /// entry). I − Γ is then a nonsingular M-matrix: elimination without pivoting has
    /// positive pivots and the solution is ≥ 0.
    pub fn solve(matrix: [[f64; 3]; 3], input: [f64; 3]) -> Option<Self> {
        if input.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return None;
        }
        let mut g = GainMatrix::new(3);
        for (i, row) in matrix.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                g.set(i, j, *v);
            }
        }
        if !g.is_contracting() {
            return None;
        }
        let mut m = [[0.0; 4]; 3];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = f64::from(u8::from(i == j)) - matrix[i][j];
            }
            m[i][3] = input[i];
        }
        for p in 0..3 {
            let piv = m[p][p];
            if !(piv > 0.0) {
                return None;
            }
            for i in p + 1..3 {
                let f = m[i][p] / piv;
                for j in p..4 {
                    m[i][j] -= f * m[p][j];
                }
            }
        }
        let mut s = [0.0; 3];
        for i in (0..3).rev() {
            let tail: f64 = (i + 1..3).map(|j| m[i][j] * s[j]).sum();
            s[i] = ((m[i][3] - tail) / m[i][i]).max(0.0);
        }
        Some(Self {
            matrix,
            input,
            spectral_radius: g.spectral_radius(),
            gains: s,
        })
    }
}

/// The certified asymptotic gains of Theorem 1 at one K (module docs).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct AsymptoticGains {
    /// The iteration budget K.
    pub k: usize,
    /// φ(K).
    pub phi: f64,
    /// g_x: lim sup‖x_t‖ ≤ g_x·w̄.
    pub gain_x: f64,
    /// g_ε: lim sup ε_t ≤ g_ε·w̄.
    pub gain_epsilon: f64,
    /// g_e: lim sup‖e_t‖ ≤ g_e·w̄.
    pub gain_e: f64,
    /// The lim-sup comparison system Γ̃, g̃ whose solution the three gains are.
    pub limsup: ComparisonSystem,
    /// The same argument with Theorem 1's gain matrix Γ (γ₁,₃, γ₂,₁, γ₂,₃, γ₃,₁, γ₃,₂) and
    /// w-gains (γ₁ʷ, γ₂ʷ, γ₃ʷ = C_w): a larger, equally valid bound, for comparison.
    pub theorem1: ComparisonSystem,
    /// a_w = √(6Λ^Q_P S_η/(1 − ρ^M)): the direct gain from w̄ to lim sup‖e‖ (Prop. 2).
    pub e_from_w: f64,
    /// a_ε = √(2Λ^H̄_P/(1 − ρ^M)): the gain from lim sup ε to lim sup‖e‖ (Prop. 2).
    pub e_from_epsilon: f64,
    /// γ₁,₃ used (Assumption 4).
    pub gamma13: f64,
    /// γ₁ʷ used (Assumption 4, the same estimate as γ₁,₃).
    pub gamma1w: f64,
}

/// Why there is no certified asymptotic gain at a K. Every reason is typed; JSON carries
/// the sentences of their `Display`.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(tag = "kind", rename_all = "snake_case"))]
#[non_exhaustive]
pub enum AsymptoticVoid {
    /// Theorem 1 is void for this method: a premise fails, or a constant does not exist for
    /// the scenario, or no K up to the search limit is certified (the certificate's
    /// `void_reasons`).
    Void {
        /// The reasons, as in the certificate's `void_reasons`.
        reasons: Vec<VoidReason>,
    },
    /// The analysis budget (`certificate.phase_seconds`) stopped the certificate of this
    /// method: not proved void, not computed.
    NotComputed {
        /// The phase cut, its estimate and the budget that computes it.
        not_computed: NotComputed,
    },
    /// The method was not certified at all (not among `CertifyOptions::methods`).
    NotCertified {
        /// The method asked for.
        #[cfg_attr(feature = "serde", serde(serialize_with = "as_display"))]
        method: Method,
    },
    /// The premises hold but the small-gain condition fails at this K (K below K_min).
    SmallGainFails {
        /// The K asked for.
        k: usize,
        /// The smallest certified K, if any.
        k_min: Option<usize>,
        /// 1 − (sg1 + sg2 + sg3) at K (≤ 0 unless φ(K) ≥ 1, when it means nothing).
        margin: f64,
        /// φ(K).
        phi: f64,
    },
    /// γ₁ʷ, Assumption 4's gain from w¹ to x, is not known (a user-supplied γ₁,₃).
    NoGamma1w {
        /// Why.
        reason: Gamma1wUnknown,
    },
}

/// Serialises a value as its `Display` sentence.
#[cfg(feature = "serde")]
fn as_display<T: std::fmt::Display, S: serde::Serializer>(v: &T, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(v)
}

impl std::fmt::Display for AsymptoticVoid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Void { reasons } => {
                write!(f, "Theorem 1 is void: {}", VoidReason::join(reasons))
            }
            Self::NotComputed { not_computed } => write!(f, "Theorem 1 is {not_computed}"),
            Self::NotCertified { method } => write!(
                f,
                "{method} is not among CertifyOptions::methods: certify it to get its gains"
            ),
            Self::SmallGainFails {
                k,
                k_min,
                margin,
                phi,
            } => write!(
                f,
                "Theorem 1 does not certify K = {k} ({}){}",
                if *phi >= 1.0 {
                    format!("φ(K) = {} ≥ 1", sig4(*phi))
                } else {
                    format!(
                        "φ(K) = {}, 1 − (sg1 + sg2 + sg3) = {} ≤ 0",
                        sig4(*phi),
                        sig4(*margin)
                    )
                },
                match k_min {
                    Some(m) => format!("; it certifies K ≥ K_min = {m}"),
                    None => String::new(),
                }
            ),
            Self::NoGamma1w { reason } => write!(f, "{reason}"),
        }
    }
}

impl std::error::Error for AsymptoticVoid {}

/// Largest K searched when a void reason names K_min (the certificate's default `k_max`).
const K_MIN_SEARCH: usize = 1 << 24;

/// Σ_{j=1}^{M} η^{j−1}.
fn s_eta(m: usize, eta: f64) -> f64 {
    (0..m).map(|j| eta.powi(j as i32)).sum()
}

/// The certified asymptotic gains of Theorem 1 at K with the analysis's constants and the
/// plant's γ₁ʷ (module docs), or why there are none: void exactly when Theorem 1 does not
/// certify ISS at K, or γ₁ʷ is not finite.
pub fn asymptotic_gains(
    analysis: &IssAnalysis,
    gamma1w: f64,
    k: usize,
) -> Result<AsymptoticGains, AsymptoticVoid> {
    if !analysis.premises_hold() {
        return Err(AsymptoticVoid::Void {
            reasons: analysis
                .violated()
                .iter()
                .map(|p| p.void_reason())
                .collect(),
        });
    }
    let g = analysis.at(k);
    if !g.certified {
        return Err(AsymptoticVoid::SmallGainFails {
            k,
            k_min: analysis.k_min(K_MIN_SEARCH),
            margin: g.margin,
            phi: g.phi,
        });
    }
    if !(gamma1w.is_finite() && gamma1w >= 0.0) {
        return Err(AsymptoticVoid::NoGamma1w {
            reason: Gamma1wUnknown::NotFinite { gamma1w },
        });
    }
    let i = &analysis.inputs;
    let m = i.horizon.max(1);
    let rho_m = analysis.rho.powi(m as i32);
    let e_from_epsilon = (2.0 * analysis.lambda_hp / (1.0 - rho_m)).sqrt();
    let e_from_w = (6.0 * analysis.lambda_qp * s_eta(m, i.eta) / (1.0 - rho_m)).sqrt();
    let g13 = i.gamma13;
    let limsup_matrix = [
        [0.0, 0.0, g13],
        [g.gamma21, 0.0, g.gamma23],
        [0.0, e_from_epsilon, 0.0],
    ];
    let limsup_input = [gamma1w, g.gamma2w, e_from_w];
    let theorem1_matrix = [
        [0.0, 0.0, g13],
        [g.gamma21, 0.0, g.gamma23],
        [g.gamma31, g.gamma32, 0.0],
    ];
    let theorem1_input = [gamma1w, g.gamma2w, g.gamma3w];
    let small_gain_fails = || AsymptoticVoid::SmallGainFails {
        k,
        k_min: analysis.k_min(K_MIN_SEARCH),
        margin: g.margin,
        phi: g.phi,
    };
    // Theorem 1 certifies ρ(Γ) < 1, and Γ̃ ≤ Γ: neither solve can fail then, except through
    // rounding at a margin of a few ulps, which is reported as the small-gain failure it is.
    let theorem1 =
        ComparisonSystem::solve(theorem1_matrix, theorem1_input).ok_or_else(small_gain_fails)?;
    let limsup =
        ComparisonSystem::solve(limsup_matrix, limsup_input).ok_or_else(small_gain_fails)?;
    Ok(AsymptoticGains {
        k,
        phi: g.phi,
        gain_x: limsup.gains[0],
        gain_epsilon: limsup.gains[1],
        gain_e: limsup.gains[2],
        limsup,
        theorem1,
        e_from_w,
        e_from_epsilon,
        gamma13: g13,
        gamma1w,
    })
}

/// γ₁ʷ of the scenario's certificate: the certified γ₁,₃ estimate's gain from w¹ (∞ when
/// void), or why it is unknown (a user-supplied γ₁,₃ comes without one).
pub fn gamma1w_of(cert: &ClosedLoopCertificate) -> Result<f64, AsymptoticVoid> {
    match (&cert.gamma13.certified, cert.gamma13.user) {
        (Some(c), None) => Ok(c.gamma1w),
        (_, Some(user)) => Err(AsymptoticVoid::NoGamma1w {
            reason: Gamma1wUnknown::UserSupplied {
                gamma13: user,
                source: cert.gamma13.source.clone(),
            },
        }),
        (None, None) => Err(AsymptoticVoid::NoGamma1w {
            reason: Gamma1wUnknown::NotComputed,
        }),
    }
}

/// [`asymptotic_gains`] of one solver of a scenario's certificate at K.
pub fn certified_gains(
    cert: &ClosedLoopCertificate,
    solver: &SolverCertificate,
    k: usize,
) -> Result<AsymptoticGains, AsymptoticVoid> {
    // No K_min: void for the certificate's reasons (a failed premise, a constant that does
    // not exist for this scenario, or no K up to the search limit).
    let Some(k_min) = solver.k_min else {
        // Cut by the budget: not computed, never "void".
        return Err(match &solver.not_computed {
            Some(nc) => AsymptoticVoid::NotComputed {
                not_computed: nc.clone(),
            },
            None => AsymptoticVoid::Void {
                reasons: solver.void_reasons.clone(),
            },
        });
    };
    let analysis = &solver.analysis;
    let g = analysis.at(k);
    if k < k_min || !g.certified {
        return Err(AsymptoticVoid::SmallGainFails {
            k,
            k_min: Some(k_min),
            margin: g.margin,
            phi: g.phi,
        });
    }
    asymptotic_gains(analysis, gamma1w_of(cert)?, k)
}

/// The measured counterparts of [`AsymptoticGains`] on one simulated run.
///
/// The estimator: with w̄_run = sup_{0 ≤ t < T}‖w_t‖₂ (the run's own disturbance level) and
/// the tail t ≥ ⌊T/2⌋, ĝ_e = sup_{t ≥ T/2}‖e_t‖/w̄_run and ĝ_x = sup_{t ≥ T/2}‖x_t‖/w̄_run (x_T
/// included). The true asymptotic gain γ_e = sup over disturbance sequences in 𝒲 of
/// lim sup‖e_t‖/‖w‖_∞ is at least this run's lim sup‖e_t‖/w̄_run; once the transient has
/// decayed by T/2, the tail sup is a sample of that lim sup (one sequence, a finite window),
/// so ĝ ≤ γ ≤ g (certified) — a lower estimate. While the transient has not decayed, the tail
/// sup can exceed it (the certified bound is asymptotic), which the whole-run sups beside it
/// help to see.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct MeasuredGains {
    /// Steps T of the run.
    pub steps: usize,
    /// First step of the tail, ⌊T/2⌋.
    pub tail_from: usize,
    /// w̄_run = sup_t ‖w_t‖₂ over the whole run.
    pub w_sup: f64,
    /// sup_{t ≥ T/2}‖e_t‖.
    pub e_tail_sup: f64,
    /// sup_{t ≥ T/2}‖x_t‖ (x_T included).
    pub x_tail_sup: f64,
    /// sup_{t ≥ T/2} ε_t (None when ε_t was not recorded).
    pub epsilon_tail_sup: Option<f64>,
    /// sup_t ‖e_t‖ over the whole run.
    pub e_sup: f64,
    /// sup_t ‖x_t‖ over the whole run.
    pub x_sup: f64,
    /// ĝ_e = e_tail_sup / w_sup (None when w_sup = 0: no disturbance, no gain to measure).
    pub gain_e: Option<f64>,
    /// ĝ_x = x_tail_sup / w_sup.
    pub gain_x: Option<f64>,
    /// ĝ_ε = epsilon_tail_sup / w_sup.
    pub gain_epsilon: Option<f64>,
    /// sup_t‖e_t‖ / w_sup over the whole run (transient included).
    pub gain_e_whole_run: Option<f64>,
    /// sup_t‖x_t‖ / w_sup over the whole run (transient included).
    pub gain_x_whole_run: Option<f64>,
}

impl MeasuredGains {
    /// The estimator of the type's docs on `trace` (None for an empty trace).
    pub fn from_trace(trace: &Trace) -> Option<Self> {
        let n = trace.len();
        if n == 0 {
            return None;
        }
        let from = n / 2;
        let sup = |v: &[f64]| v.iter().copied().fold(0.0_f64, f64::max);
        let (es, xs, ws) = (trace.e_norms(), trace.x_norms(), trace.w_norms());
        let w_sup = sup(ws);
        let epsilon_tail_sup = trace
            .epsilons()
            .skip(from)
            .collect::<Option<Vec<f64>>>()
            .map(|v| sup(&v));
        let per_w = |v: f64| (w_sup > 0.0).then(|| v / w_sup);
        let (e_tail_sup, x_tail_sup) = (sup(&es[from..]), sup(&xs[from..]));
        let (e_sup, x_sup) = (sup(es), sup(xs));
        Some(Self {
            steps: n,
            tail_from: from,
            w_sup,
            e_tail_sup,
            x_tail_sup,
            epsilon_tail_sup,
            e_sup,
            x_sup,
            gain_e: per_w(e_tail_sup),
            gain_x: per_w(x_tail_sup),
            gain_epsilon: epsilon_tail_sup.and_then(per_w),
            gain_e_whole_run: per_w(e_sup),
            gain_x_whole_run: per_w(x_sup),
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn solve_matches_the_closed_form_and_refuses_rho_at_least_one() {
        // s_x = γ13 s_e + g0, s_ε = γ21 s_x + γ23 s_e + g1, s_e = a s_ε + g2.
        let (g13, g21, g23, a) = (2.0, 0.1, 0.05, 1.5);
        let (g0, g1, g2) = (3.0, 0.2, 4.0);
        let m = [[0.0, 0.0, g13], [g21, 0.0, g23], [0.0, a, 0.0]];
        let s = ComparisonSystem::solve(m, [g0, g1, g2]).unwrap();
        let se = (a * (g21 * g0 + g1) + g2) / (1.0 - a * (g21 * g13 + g23));
        assert!((s.gains[2] - se).abs() <= 1e-14 * se);
        assert!((s.gains[0] - (g13 * se + g0)).abs() <= 1e-13 * s.gains[0]);
        assert!(s.spectral_radius < 1.0);
        // The loop gain a(γ21γ13 + γ23) = 1.5·0.25 = 0.375; scale a to reach 1.
        let m = [[0.0, 0.0, g13], [g21, 0.0, g23], [0.0, 4.0, 0.0]];
        assert!(ComparisonSystem::solve(m, [g0, g1, g2]).is_none());
        let m = [[0.0, 0.0, g13], [g21, 0.0, g23], [0.0, 3.9, 0.0]];
        assert!(ComparisonSystem::solve(m, [g0, g1, g2]).is_some());
    }
}
