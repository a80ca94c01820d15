//! Convex sets with in-place Euclidean projection and membership: the feasible set Z of a
//! [`crate::ParametricQp`] is a [`BoxSet`] with ±∞ bounds. `lti-model` re-exports these
//! (its 𝒳, 𝒰, 𝒴, 𝒲 are the same types) and adds products and polytopes.

use crate::error::DataError;

/// Result of the set constructors.
type Result<T> = std::result::Result<T, DataError>;

/// A closed convex subset of ℝⁿ with a membership test.
pub trait ConvexSet: Send + Sync + std::fmt::Debug {
    /// Ambient dimension n.
    fn dim(&self) -> usize;
    /// Largest constraint violation of `x` (0 inside the set); ∞-norm style, in the units of x.
    fn violation(&self, x: &[f64]) -> f64;
    /// `x` lies in the set up to `tol`.
    fn contains(&self, x: &[f64], tol: f64) -> bool {
        x.len() == self.dim() && self.violation(x) <= tol
    }
}

/// A convex set with an exact Euclidean projection computed in place.
pub trait Projection: ConvexSet {
    /// Replaces `x` by argmin_{y ∈ set} ‖y − x‖₂. Allocation-free.
    fn project(&self, x: &mut [f64]);
}

/// Box {x : l ≤ x ≤ u} with l_i ∈ [−∞, ∞), u_i ∈ (−∞, ∞] and l ≤ u.
///
/// ```
/// use qp_iter::{BoxSet, ConvexSet, Projection};
/// let b = BoxSet::new(vec![-1.0, f64::NEG_INFINITY], vec![1.0, 0.0]).unwrap();
/// let mut x = [3.0, 2.0];
/// b.project(&mut x);
/// assert_eq!(x, [1.0, 0.0]);
/// assert!(b.contains(&x, 0.0));
/// ```
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct BoxSet {
    lower: Vec<f64>,
    upper: Vec<f64>,
}

impl BoxSet {
    /// Validated box: equal lengths, no NaN, l_i < ∞, u_i > −∞, l ≤ u.
    pub fn new(lower: Vec<f64>, upper: Vec<f64>) -> Result<Self> {
        Self::named("box", lower, upper)
    }

    /// As [`BoxSet::new`], with the set's name used in errors (e.g. `"sets.input"`).
    pub fn named(name: &str, lower: Vec<f64>, upper: Vec<f64>) -> Result<Self> {
        let invalid = |reason: String| DataError::InvalidSet {
            name: name.to_string(),
            reason,
        };
        if lower.len() != upper.len() {
            return Err(invalid(format!(
                "lower has {} entries but upper has {}",
                lower.len(),
                upper.len()
            )));
        }
        for (i, (&l, &u)) in lower.iter().zip(&upper).enumerate() {
            if l.is_nan() || u.is_nan() {
                return Err(invalid(format!("bound {i} is NaN")));
            }
            if l == f64::INFINITY || u == f64::NEG_INFINITY {
                return Err(invalid(format!(
                    "bound {i} makes the set empty (lower {l}, upper {u})"
                )));
            }
            if l > u {
                return Err(invalid(format!(
                    "lower[{i}] = {l} > upper[{i}] = {u}: the box is empty"
                )));
            }
        }
        Ok(Self { lower, upper })
    }

    /// Symmetric box [−r, r]ⁿ.
    pub fn symmetric(radius: &[f64]) -> Result<Self> {
        Self::new(radius.iter().map(|r| -r).collect(), radius.to_vec())
    }

    /// The whole space ℝⁿ as a box with infinite bounds.
    pub fn whole(n: usize) -> Self {
        Self {
            lower: vec![f64::NEG_INFINITY; n],
            upper: vec![f64::INFINITY; n],
        }
    }

    /// Lower bounds l.
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }
    /// Upper bounds u.
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }
    /// True if every bound is infinite (the box is ℝⁿ).
    pub fn is_whole(&self) -> bool {
        self.lower.iter().all(|l| *l == f64::NEG_INFINITY)
            && self.upper.iter().all(|u| *u == f64::INFINITY)
    }
    /// Largest |bound| over finite bounds (0 if none): the radius used for 𝒲-type bounds.
    pub fn max_abs_finite_bound(&self) -> f64 {
        self.lower
            .iter()
            .chain(&self.upper)
            .filter(|b| b.is_finite())
            .map(|b| b.abs())
            .fold(0.0, f64::max)
    }
    /// The Cartesian product of boxes (blocks stacked in order): always a valid box.
    ///
    /// ```
    /// use qp_iter::BoxSet;
    /// let b = BoxSet::product(&[BoxSet::whole(1), BoxSet::symmetric(&[2.0]).unwrap()]);
    /// assert_eq!(b.lower(), [f64::NEG_INFINITY, -2.0]);
    /// ```
    pub fn product(parts: &[BoxSet]) -> Self {
        let (mut lower, mut upper) = (Vec::new(), Vec::new());
        for p in parts {
            lower.extend_from_slice(&p.lower);
            upper.extend_from_slice(&p.upper);
        }
        Self { lower, upper }
    }
}

impl ConvexSet for BoxSet {
    fn dim(&self) -> usize {
        self.lower.len()
    }
    fn violation(&self, x: &[f64]) -> f64 {
        let mut v = 0.0_f64;
        for ((xi, l), u) in x.iter().zip(&self.lower).zip(&self.upper) {
            v = v.max(l - xi).max(xi - u);
        }
        if x.iter().any(|xi| xi.is_nan()) {
            return f64::INFINITY;
        }
        v
    }
}

impl Projection for BoxSet {
    #[inline]
    fn project(&self, x: &mut [f64]) {
        // `clamp` keeps NaN as NaN (max/min would silently turn it into a bound and hide a
        // numerical failure); bounds are validated l ≤ u, non-NaN, so it cannot panic.
        for ((xi, l), u) in x.iter_mut().zip(&self.lower).zip(&self.upper) {
            *xi = xi.clamp(*l, *u);
        }
    }
}
