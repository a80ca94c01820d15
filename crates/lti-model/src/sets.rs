//! Convex sets 𝒳, 𝒰, 𝒴, 𝒲 with in-place Euclidean projection and membership.
//!
//! Projectable sets ([`Set`]: the whole space, boxes with ±∞ bounds, Cartesian products)
//! implement [`Projection`]; projections are exact, in place and allocation-free, which is
//! what makes PG/FISTA iterates feasible (Assumption 5). A [`Polytope`] {x : Gx ≤ h} offers
//! membership and violation only: its Euclidean projection is itself a QP, so solvers use
//! polytopes as general constraints Gz ∈ 𝒞 instead.

use faer::{Mat, MatRef};

use crate::error::{ModelError, Result};
use crate::matrix::{check_finite, check_shape};

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
/// use lti_model::{BoxSet, Projection, ConvexSet};
/// let b = BoxSet::new(vec![-1.0, f64::NEG_INFINITY], vec![1.0, 0.0]).unwrap();
/// let mut x = [3.0, 2.0];
/// b.project(&mut x);
/// assert_eq!(x, [1.0, 0.0]);
/// assert!(b.contains(&x, 0.0));
/// ```
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
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
        let invalid = |reason: String| ModelError::InvalidSet {
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
    /// Writes the box as a polytope {x : Gx ≤ h}, one row per finite bound.
    pub fn to_polytope(&self) -> Polytope {
        let n = self.lower.len();
        let mut rows: Vec<(usize, f64, f64)> = Vec::new();
        for i in 0..n {
            if self.upper[i].is_finite() {
                rows.push((i, 1.0, self.upper[i]));
            }
            if self.lower[i].is_finite() {
                rows.push((i, -1.0, -self.lower[i]));
            }
        }
        let g = Mat::from_fn(
            rows.len(),
            n,
            |r, j| if rows[r].0 == j { rows[r].1 } else { 0.0 },
        );
        let h = rows.iter().map(|r| r.2).collect();
        Polytope { g, h }
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

/// A projectable convex set: ℝⁿ, a box, or a Cartesian product of such sets.
///
/// ```
/// use lti_model::{BoxSet, Set, Projection};
/// let s = Set::Product(vec![Set::Whole(1), Set::Box(BoxSet::symmetric(&[0.5]).unwrap())]);
/// let mut x = [10.0, 10.0];
/// s.project(&mut x);
/// assert_eq!(x, [10.0, 0.5]);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum Set {
    /// The whole space ℝⁿ.
    Whole(usize),
    /// A box with possibly infinite bounds.
    Box(BoxSet),
    /// Cartesian product; the blocks are stacked in order.
    Product(Vec<Set>),
}

impl Set {
    /// The equivalent box (every set of this enum is a box with possibly infinite bounds).
    pub fn to_box(&self) -> BoxSet {
        match self {
            Set::Whole(n) => BoxSet::whole(*n),
            Set::Box(b) => b.clone(),
            Set::Product(parts) => {
                let (mut lower, mut upper) = (Vec::new(), Vec::new());
                for p in parts {
                    let b = p.to_box();
                    lower.extend_from_slice(b.lower());
                    upper.extend_from_slice(b.upper());
                }
                BoxSet { lower, upper }
            }
        }
    }
}

impl ConvexSet for Set {
    fn dim(&self) -> usize {
        match self {
            Set::Whole(n) => *n,
            Set::Box(b) => b.dim(),
            Set::Product(parts) => parts.iter().map(ConvexSet::dim).sum(),
        }
    }
    fn violation(&self, x: &[f64]) -> f64 {
        match self {
            Set::Whole(_) => {
                if x.iter().any(|v| v.is_nan()) {
                    f64::INFINITY
                } else {
                    0.0
                }
            }
            Set::Box(b) => b.violation(x),
            Set::Product(parts) => {
                let mut off = 0;
                let mut v = 0.0_f64;
                for p in parts {
                    let d = p.dim();
                    v = v.max(p.violation(&x[off..off + d]));
                    off += d;
                }
                v
            }
        }
    }
}

impl Projection for Set {
    fn project(&self, x: &mut [f64]) {
        match self {
            Set::Whole(_) => {}
            Set::Box(b) => b.project(x),
            Set::Product(parts) => {
                let mut off = 0;
                for p in parts {
                    let d = p.dim();
                    p.project(&mut x[off..off + d]);
                    off += d;
                }
            }
        }
    }
}

/// Polytope {x : Gx ≤ h}: membership and violation, for use as a general constraint.
///
/// ```
/// use faer::mat;
/// use lti_model::{Polytope, ConvexSet};
/// let p = Polytope::new(mat![[1.0, 1.0]], vec![1.0]).unwrap();
/// assert!(p.contains(&[0.5, 0.5], 0.0));
/// assert!(!p.contains(&[1.0, 1.0], 1e-9));
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Polytope {
    g: Mat<f64>,
    h: Vec<f64>,
}

impl Polytope {
    /// Validated polytope: G is m × n, h has m entries, all finite.
    pub fn new(g: Mat<f64>, h: Vec<f64>) -> Result<Self> {
        check_shape("G", g.as_ref(), h.len(), g.ncols())?;
        check_finite("G", g.as_ref())?;
        crate::matrix::check_finite_slice("h", &h)?;
        Ok(Self { g, h })
    }
    /// G.
    pub fn g(&self) -> MatRef<'_, f64> {
        self.g.as_ref()
    }
    /// h.
    pub fn h(&self) -> &[f64] {
        &self.h
    }
}

impl ConvexSet for Polytope {
    fn dim(&self) -> usize {
        self.g.ncols()
    }
    fn violation(&self, x: &[f64]) -> f64 {
        let mut v = 0.0_f64;
        for i in 0..self.g.nrows() {
            let mut gx = 0.0;
            for j in 0..self.g.ncols() {
                gx += self.g[(i, j)] * x[j];
            }
            if gx.is_nan() {
                return f64::INFINITY;
            }
            v = v.max(gx - self.h[i]);
        }
        v
    }
}
