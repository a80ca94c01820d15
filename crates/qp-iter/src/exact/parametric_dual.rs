//! Goldfarb–Idnani for a parametric problem ([`ParametricDualActiveSet`]): the data
//! q₀ + Fθ and the rows' bounds l₀ − Eθ, u₀ − Eθ formed per θ without allocating, solved by
//! [`DualActiveSet`]. Re-exported as `qp_iter::dual_active_set::ParametricDualActiveSet`.

use super::dual_active_set::{DualActiveSet, DualActiveSetInfo, DualActiveSetSettings};
use crate::error::Result;
use crate::problem::ParametricQp;

/// The exact solve of a [`ParametricQp`] with its general constraints by [`DualActiveSet`]:
/// forms q = q₀ + Fθ and the bounds l₀ − Eθ, u₀ − Eθ for θ, allocation-free per call.
///
/// ```
/// use faer::{mat, Mat};
/// use qp_iter::BoxSet;
/// use qp_iter::ParametricQp;
/// use qp_iter::problem::GeneralConstraints;
/// use qp_iter::dual_active_set::{ParametricDualActiveSet, DualActiveSetStatus};
/// // min ½‖z‖² − θᵀz s.t. z₀ + z₁ ≤ 1 − θ₀.
/// let qp = ParametricQp::new(Mat::identity(2, 2), vec![0.0; 2], -Mat::<f64>::identity(2, 2),
///     BoxSet::whole(2)).unwrap()
///     .with_general(GeneralConstraints::new(mat![[1.0, 1.0]], mat![[1.0, 0.0]],
///         vec![f64::NEG_INFINITY], vec![1.0]).unwrap()).unwrap();
/// let mut s = ParametricDualActiveSet::new(&qp, Default::default()).unwrap();
/// let info = s.solve(&[0.5, 1.5]).unwrap();
/// assert_eq!(info.status, DualActiveSetStatus::Optimal);
/// // z₀ + z₁ ≤ 0.5: z* = (0.5, 1.5) − ¾(1, 1).
/// assert!((s.z()[0] + 0.25).abs() < 1e-14 && (s.z()[1] - 0.75).abs() < 1e-14);
/// ```
#[derive(Debug, Clone)]
pub struct ParametricDualActiveSet {
    qp: ParametricQp,
    solver: DualActiveSet,
    q: Vec<f64>,
    g_lo: Vec<f64>,
    g_hi: Vec<f64>,
}

impl ParametricDualActiveSet {
    /// Sets the solver up for `qp` (factorises H once).
    pub fn new(qp: &ParametricQp, settings: DualActiveSetSettings) -> Result<Self> {
        let n = qp.n();
        let empty = faer::Mat::<f64>::zeros(0, n);
        let g = qp.general().map_or(empty.as_ref(), |gc| gc.g());
        let solver = DualActiveSet::new(qp.h(), g, settings)?;
        let m = solver.m();
        Ok(Self {
            qp: qp.clone(),
            solver,
            q: vec![0.0; n],
            g_lo: vec![0.0; m],
            g_hi: vec![0.0; m],
        })
    }

    /// Solves for θ (length n_θ, finite; checked).
    pub fn solve(&mut self, theta: &[f64]) -> Result<DualActiveSetInfo> {
        self.qp.check_theta(theta)?;
        self.qp.linear_term(theta, &mut self.q);
        if let Some(gc) = self.qp.general() {
            gc.bounds(theta, &mut self.g_lo, &mut self.g_hi);
        }
        let z = self.qp.zset();
        Ok(self
            .solver
            .solve(&self.q, z.lower(), z.upper(), &self.g_lo, &self.g_hi))
    }

    /// The last iterate.
    pub fn z(&self) -> &[f64] {
        self.solver.z()
    }
    /// Signed multipliers (box rows, then G rows) of the last solution.
    pub fn multipliers(&self) -> &[f64] {
        self.solver.multipliers()
    }
    /// The objective ½zᵀHz + qᵀz of the last iterate.
    pub fn objective(&self) -> f64 {
        self.solver.objective()
    }
    /// The problem.
    pub fn problem(&self) -> &ParametricQp {
        &self.qp
    }
}
