//! Certificates of convergence φ(K) (Assumption 5, eq. (11)).

#[cfg(feature = "serde")]
use serde::Serialize;

/// Which quantity a certificate bounds.
///
/// Exhaustive on purpose: certificate-json's conversion names each variant, so a new
/// quantity is a schema decision the compiler asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum BoundedQuantity {
    /// ‖zᴷ − z*‖ ≤ φ(K)‖z⁰ − z*‖: exactly eq. (11).
    IterateDistance,
    /// A splitting / auxiliary variable of the method (e.g. ADMM's v = z + u/ρ), not z itself.
    SplittingVariable,
    /// f(zᴷ) − f* (an objective gap), not a distance.
    ObjectiveGap,
}

/// The norm the bound holds in.
///
/// Exhaustive on purpose: certificate-json's conversion names each variant, so a new
/// norm is a schema decision the compiler asks for.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum CertNorm {
    /// The Euclidean norm of the problem's coordinates (the one eq. (11) uses).
    Euclidean,
    /// A weighted or scaled norm, described in words (e.g. "‖·‖ in the ρ-scaled metric").
    Other(String),
}

/// φ(K) = prefactor · rateᴷ for the stated quantity and norm.
///
/// `fits_eq11` is true only when the bound is on ‖zᴷ − z*‖ in the Euclidean norm of
/// the problem coordinates *and* the K-th iterate is feasible, i.e. when it can be used as
/// φ(K) in the paper's Assumption 5 as is.
///
/// ```
/// use qp_iter::{Certificate, BoundedQuantity, CertNorm};
/// let c = Certificate {
///     rate: 0.98, prefactor: 1.0,
///     quantity: BoundedQuantity::IterateDistance, norm: CertNorm::Euclidean,
///     fits_eq11: true,
///     premise: "H ≻ 0, step 1/L".into(), source: "textbook".into(),
/// };
/// assert!((c.phi(2) - 0.9604).abs() < 1e-12);
/// assert_eq!(c.min_iterations(0.5), Some(35)); // 0.98^35 ≈ 0.4931
/// ```
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
// Not #[non_exhaustive]: a user's own method (the `Method` trait) builds its certificate with a
// struct literal, as the example above does.
pub struct Certificate {
    /// Linear rate r ∈ [0, 1).
    pub rate: f64,
    /// Prefactor c ≥ 0 (1 for the plain gradient bounds).
    pub prefactor: f64,
    /// What is bounded.
    pub quantity: BoundedQuantity,
    /// In which norm.
    pub norm: CertNorm,
    /// Usable as φ(K) in eq. (11) as is (see the type's documentation).
    pub fits_eq11: bool,
    /// Premise under which the bound holds.
    pub premise: String,
    /// Where the bound comes from (paper, theorem).
    pub source: String,
}

impl Certificate {
    /// φ(K) = prefactor · rateᴷ.
    pub fn phi(&self, k: usize) -> f64 {
        let k = i32::try_from(k).unwrap_or(i32::MAX);
        self.prefactor * self.rate.powi(k)
    }

    /// Smallest K with φ(K) ≤ `accuracy` (None if the rate is not < 1 or accuracy ≤ 0).
    pub fn min_iterations(&self, accuracy: f64) -> Option<usize> {
        if !(self.rate < 1.0) || !(accuracy > 0.0) || !self.rate.is_finite() {
            return None;
        }
        if self.prefactor <= accuracy {
            return Some(0);
        }
        if self.rate <= 0.0 {
            return Some(1);
        }
        // c rᴷ ≤ ε  ⇔  K ≥ ln(ε/c)/ln r.
        let k = ((accuracy / self.prefactor).ln() / self.rate.ln()).ceil();
        let mut k = if k.is_finite() && k >= 0.0 {
            k as usize
        } else {
            return None;
        };
        // Guard the floating-point boundary in both directions.
        while k > 0 && self.phi(k - 1) <= accuracy {
            k -= 1;
        }
        while self.phi(k) > accuracy {
            k += 1;
        }
        Some(k)
    }
}
