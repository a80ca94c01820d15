//! The exact projection of projected gradient and FISTA onto Z ∩ {l ≤ Gz ≤ u} when the
//! problem has general rows ([`crate::problem::GeneralConstraints`]).
//!
//! Π(x) = argmin ½‖z − x‖² over the box and the rows, with the bounds l₀ − Eθ, u₀ − Eθ of
//! the loaded θ: a QP with H = I, solved exactly by Goldfarb–Idnani
//! ([`crate::dual_active_set::DualActiveSet::identity`], no factorisation). The projection
//! onto any closed convex set is non-expansive and z* is a fixed point of the projected
//! step, so the certificates of [`crate::pg`] and [`crate::fista`] hold unchanged, and every
//! iterate is feasible (to the solver's tolerance, reported by
//! [`crate::IterationMap::violation`]).
//!
//! **Cost.** The gradient step is the dense kernel without the clamp (bounds ±∞), followed
//! by one projection. Fast path (exact): the box clamp, kept if it satisfies every row —
//! O(n·m). Otherwise Goldfarb–Idnani: O(n²) to reset J = I, then per added constraint (box
//! bounds included) O(n²) and per pass over the rows O(n·m). Measured against the box-only step in `benches/`
//! (`general_projection`). The structured Hessian operator is not used with general rows.
//!
//! **Infeasible bounds.** If the rows have no common point with the box for this θ, the
//! projection does not exist: the iterate is set to NaN (so the drivers report
//! [`crate::RunStatus::NonFinite`]) and [`ProjectionState::infeasible`] names the row.

use crate::dual_active_set::{
    ConstraintRow, DualActiveSet, DualActiveSetSettings, DualActiveSetStatus,
};
use crate::kernel::AlignedVec;
use crate::problem::ParametricQp;

/// Setup data: the template solver (cloned into each state) and ±∞ bounds for the
/// unclamped gradient step of the kernels.
#[derive(Debug, Clone)]
pub(crate) struct GeneralProjection {
    template: DualActiveSet,
    pub(crate) free_lo: AlignedVec,
    pub(crate) free_hi: AlignedVec,
}

/// Per-state projection workspace and its statistics.
#[derive(Debug, Clone)]
pub struct ProjectionState {
    solver: DualActiveSet,
    g_lo: Vec<f64>,
    g_hi: Vec<f64>,
    mq: Vec<f64>,
    /// A padded buffer for FISTA's unprojected point.
    pub(crate) w: AlignedVec,
    infeasible: Option<ConstraintRow>,
    projections: usize,
    steps: usize,
    /// Projections answered by the box clamp (no row violated).
    fast: usize,
}

impl ProjectionState {
    /// The row the last projection could not meet (the loaded bounds are infeasible).
    pub fn infeasible(&self) -> Option<ConstraintRow> {
        self.infeasible
    }
    /// Projections computed, those answered by the box clamp alone, and the
    /// Goldfarb–Idnani steps the others took, since the state was made.
    pub fn counts(&self) -> (usize, usize, usize) {
        (self.projections, self.fast, self.steps)
    }
}

impl GeneralProjection {
    /// `None` for a box-only problem.
    pub(crate) fn new(qp: &ParametricQp, ld: usize) -> Option<Self> {
        let gc = qp.general()?;
        // G was validated by `GeneralConstraints`, the default settings are valid.
        let template =
            DualActiveSet::identity_validated(qp.n(), gc.g(), DualActiveSetSettings::default());
        Some(Self {
            template,
            free_lo: AlignedVec::padded(&vec![f64::NEG_INFINITY; ld]),
            free_hi: AlignedVec::padded(&vec![f64::INFINITY; ld]),
        })
    }

    /// A state with the bounds of θ = 0 (allocates: setup).
    pub(crate) fn new_state(&self, qp: &ParametricQp, ld: usize) -> ProjectionState {
        let (n, m) = (qp.n(), self.template.m());
        let mut s = ProjectionState {
            solver: self.template.clone(),
            g_lo: vec![0.0; m],
            g_hi: vec![0.0; m],
            mq: vec![0.0; n],
            w: AlignedVec::zeros(ld),
            infeasible: None,
            projections: 0,
            steps: 0,
            fast: 0,
        };
        let zero = vec![0.0; qp.n_theta()];
        self.load(qp, &mut s, &zero);
        s
    }

    /// The row bounds l₀ − Eθ, u₀ − Eθ for θ (allocation-free).
    #[inline]
    pub(crate) fn load(&self, qp: &ParametricQp, s: &mut ProjectionState, theta: &[f64]) {
        if let Some(gc) = qp.general() {
            gc.bounds(theta, &mut s.g_lo, &mut s.g_hi);
        }
    }

    /// x ← Π(x) in place (allocation-free); NaN and a recorded row if infeasible.
    #[inline]
    pub(crate) fn project(&self, qp: &ParametricQp, s: &mut ProjectionState, x: &mut [f64]) {
        for (m, v) in s.mq.iter_mut().zip(x.iter()) {
            *m = -v;
        }
        self.project_mq(qp, s, x);
    }

    /// x ← argmin ½‖z‖² + mqᵀz (= Π(−mq)).
    #[inline]
    fn project_mq(&self, qp: &ParametricQp, s: &mut ProjectionState, x: &mut [f64]) {
        // Fast path, exact: the box clamp is the projection onto Z; if it also satisfies
        // every row, it is the projection onto the intersection (a smaller set).
        qp.project(x);
        if let Some(gc) = qp.general() {
            let tol = self.template.settings().tol;
            let feasible = (0..gc.m()).all(|r| {
                let g = gc.row_dot(r, x);
                let (lo, hi) = (s.g_lo[r], s.g_hi[r]);
                g >= lo - tol * (1.0 + lo.abs()) && g <= hi + tol * (1.0 + hi.abs())
            });
            if feasible {
                s.infeasible = None;
                s.projections += 1;
                s.fast += 1;
                return;
            }
        }
        let z = qp.zset();
        let info = s
            .solver
            .solve(&s.mq, z.lower(), z.upper(), &s.g_lo, &s.g_hi);
        s.projections += 1;
        s.steps += info.iterations;
        match info.status {
            DualActiveSetStatus::Infeasible { constraint, .. } => {
                s.infeasible = Some(constraint);
                x.fill(f64::NAN);
            }
            _ => {
                s.infeasible = None;
                x.copy_from_slice(s.solver.z());
            }
        }
    }

    /// The largest violation of the box and the loaded rows by z.
    pub(crate) fn violation(&self, qp: &ParametricQp, s: &ProjectionState, z: &[f64]) -> f64 {
        let mut v = box_violation(qp, z);
        if let Some(gc) = qp.general() {
            v = v.max(gc.violation(z, &s.g_lo, &s.g_hi));
        }
        v
    }
}

/// max_i max(l_i − z_i, z_i − u_i, 0) (NaN if z has a NaN).
pub(crate) fn box_violation(qp: &ParametricQp, z: &[f64]) -> f64 {
    let mut v = 0.0f64;
    for ((zi, l), u) in z.iter().zip(qp.zset().lower()).zip(qp.zset().upper()) {
        if zi.is_nan() {
            return f64::NAN;
        }
        v = v.max(l - zi).max(zi - u);
    }
    v
}
