//! Convex sets 𝒳, 𝒰, 𝒴, 𝒲 with in-place Euclidean projection and membership.
//!
//! Projectable sets ([`Set`]: the whole space, boxes with ±∞ bounds, Cartesian products)
//! implement [`Projection`]; projections are exact, in place and allocation-free, which is
//! what makes PG/FISTA iterates feasible (Assumption 5). A [`Polytope`] {x : Gx ≤ h} offers
//! membership and violation only: its Euclidean projection is itself a QP, so solvers use
//! polytopes as general constraints Gz ∈ 𝒞 instead.

use faer::{Mat, MatRef};

use crate::error::Result;
use crate::matrix::{check_finite, check_shape};

/// The set traits and the box live in `qp-iter` (the feasible set of its QPs) and are the
/// same types here.
pub use qp_iter::sets::{BoxSet, ConvexSet, Projection};

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
                BoxSet::product(&parts.iter().map(Set::to_box).collect::<Vec<_>>())
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
    /// The box as a polytope {x : Gx ≤ h}, one row per finite bound.
    pub fn from_box(b: &BoxSet) -> Self {
        let n = b.dim();
        let mut rows: Vec<(usize, f64, f64)> = Vec::new();
        for i in 0..n {
            if b.upper()[i].is_finite() {
                rows.push((i, 1.0, b.upper()[i]));
            }
            if b.lower()[i].is_finite() {
                rows.push((i, -1.0, -b.lower()[i]));
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
