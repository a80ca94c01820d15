//! Exact reference solution z* through Clarabel (interior point), for ε_t, tests and
//! baselines. Never used in a hot loop.
//!
//! The QP min ½zᵀHz + qᵀz s.t. l ≤ z ≤ u is passed to Clarabel as P = triu(H) (CSC),
//! one row of `A z + s = b, s ≥ 0` per *finite* bound (z_i ≤ u_i: row e_iᵀ, b = u_i;
//! z_i ≥ l_i: row −e_iᵀ, b = −l_i). The solver is built once per [`ParametricQp`] with
//! `presolve_enable(false)` and `verbose(false)`, so a new θ only overwrites q
//! (`update_q`) before the next solve.
//!
//! **Polishing** (on by default): Clarabel's answer at tight tolerance is accurate to about
//! 1e-9 relative, which is not enough to test φ(K) bounds down to 1e-9. The reference then
//! guesses the active set from Clarabel's slacks and multipliers, solves the reduced
//! equality system H_FF z_F = −(q_F + H_FA z_A) with a Cholesky factorisation, and keeps
//! the polished point only if it satisfies the KKT conditions (primal feasibility,
//! multiplier signs) to `polish_tol`; otherwise Clarabel's point is returned as is.
//! Either way [`ReferenceSolution::kkt_residual`] reports the natural residual
//! ‖z − Π_Z(z − (Hz + q))‖_∞, an independent check of optimality.
//!
//! **General rows** ([`crate::problem::GeneralConstraints`]): each finite side of
//! l₀ − Eθ ≤ Gz ≤ u₀ − Eθ is one more row of `A` (G_r or −G_r), its `b` recomputed for each θ
//! (`update_b`). The polish then solves the KKT system [H Aᵀ_W; A_W 0] of the guessed active
//! rows W (box and G) by LU, and the residual reported is the larger of the stationarity
//! ‖Hz + q − λ_box − Gᵀλ_G‖_∞ and the largest violation. A primal-infeasible problem is
//! [`QpError::Infeasible`].

/// The Clarabel crate this module is built on, for callers that build a reference problem by
/// hand (the uncondensed MHE and MPC checks) with the same version.
pub use clarabel;

use crate::Projection;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use faer::{Mat, Side};

use crate::error::{QpError, Result};
use crate::problem::ParametricQp;

/// The nonzeros of a dense matrix in Clarabel's CSC form; `upper_only` keeps i ≤ j (the upper
/// triangle Clarabel takes for P). For tests and references that build a QP by hand (the
/// uncondensed MHE and MPC checks).
///
/// ```
/// let m = faer::mat![[2.0, 1.0], [1.0, 0.0]];
/// let p = qp_iter::reference::dense_to_csc(m.as_ref(), true);
/// assert_eq!((p.colptr, p.rowval, p.nzval), (vec![0, 1, 2], vec![0, 0], vec![2.0, 1.0]));
/// ```
pub fn dense_to_csc(m: faer::MatRef<'_, f64>, upper_only: bool) -> CscMatrix<f64> {
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            if (!upper_only || i <= j) && m[(i, j)] != 0.0 {
                rowval.push(i);
                nzval.push(m[(i, j)]);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(m.nrows(), m.ncols(), colptr, rowval, nzval)
}

/// Settings of [`ReferenceSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceSettings {
    /// Clarabel's `tol_gap_abs`, `tol_gap_rel` and `tol_feas`.
    pub tol: f64,
    /// Clarabel's `max_iter`.
    pub max_iter: u32,
    /// Refine Clarabel's point by an active-set solve (kept only if it passes the KKT check).
    pub polish: bool,
    /// Relative tolerance of the KKT check that accepts a polished point.
    pub polish_tol: f64,
}

impl Default for ReferenceSettings {
    fn default() -> Self {
        Self {
            tol: 1e-11,
            max_iter: 200,
            polish: true,
            polish_tol: 1e-9,
        }
    }
}

/// z* and the box multipliers: Hz* + q + λ_u − λ_l = 0, λ_l, λ_u ≥ 0 (zero for infinite bounds).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ReferenceSolution {
    /// The minimiser z*.
    pub z: Vec<f64>,
    /// Multipliers λ_l ≥ 0 of z ≥ l.
    pub lower_multipliers: Vec<f64>,
    /// Multipliers λ_u ≥ 0 of z ≤ u.
    pub upper_multipliers: Vec<f64>,
    /// Objective ½z*ᵀHz* + qᵀz*.
    pub objective: f64,
    /// Interior-point iterations Clarabel used.
    pub iterations: u32,
    /// True if the active-set polish was accepted.
    pub polished: bool,
    /// Natural residual ‖z − Π_Z(z − (Hz + q))‖_∞ of the returned z (0 at the exact optimum);
    /// with general rows max(stationarity, violation) (see the module docs).
    pub kkt_residual: f64,
    /// Signed multipliers of the rows of G (λ > 0: lower side active, < 0: upper side):
    /// Hz* + q = λ_l − λ_u + Gᵀλ_G. Empty without general rows.
    pub general_multipliers: Vec<f64>,
}

impl ReferenceSolution {
    /// The multiplier y* = λ_u − λ_l = −(Hz* + q) of the splitting z = v (ADMM's dual).
    pub fn dual(&self) -> Vec<f64> {
        self.upper_multipliers
            .iter()
            .zip(&self.lower_multipliers)
            .map(|(u, l)| u - l)
            .collect()
    }
}

/// Clarabel set up once for a [`ParametricQp`]; re-solves for new θ by updating q.
///
/// ```
/// use faer::{mat, Mat};
/// use qp_iter::BoxSet;
/// use qp_iter::ParametricQp;
/// use qp_iter::reference::{ReferenceSolver, ReferenceSettings};
/// let qp = ParametricQp::new(mat![[4.0, 1.0], [1.0, 1.0]], vec![-2.0, -4.0],
///     Mat::identity(2, 2), BoxSet::symmetric(&[2.0, 2.0]).unwrap()).unwrap();
/// let mut r = ReferenceSolver::new(&qp, ReferenceSettings::default()).unwrap();
/// let s = r.solve(&[0.0, 0.0]).unwrap();
/// assert!(s.z[0].abs() < 1e-12 && (s.z[1] - 2.0).abs() < 1e-12);
/// assert!((s.upper_multipliers[1] - 2.0).abs() < 1e-9 && s.kkt_residual < 1e-12);
/// // New θ (q = q₀ + θ = (−3, −3)): z₁ still clipped at 2, then 4z₀ + 2 − 3 = 0.
/// let s = r.solve(&[-1.0, 1.0]).unwrap();
/// assert!((s.z[0] - 0.25).abs() < 1e-12 && (s.z[1] - 2.0).abs() < 1e-12);
/// assert!((s.upper_multipliers[1] - 0.75).abs() < 1e-9);
/// ```
pub struct ReferenceSolver {
    qp: ParametricQp,
    solver: DefaultSolver<f64>,
    /// For each constraint row: (variable index, is upper bound).
    rows: Vec<(usize, bool)>,
    /// For each row after the box's: (row of G, is upper bound).
    g_rows: Vec<(usize, bool)>,
    /// b of the box rows, then of the G rows (recomputed per θ).
    b: Vec<f64>,
    /// l₀ − Eθ and u₀ − Eθ of the current θ.
    g_lo: Vec<f64>,
    g_hi: Vec<f64>,
    settings: ReferenceSettings,
    q: Vec<f64>,
}

impl std::fmt::Debug for ReferenceSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReferenceSolver")
            .field("n", &self.qp.n())
            .field("constraint_rows", &self.rows.len())
            .field("settings", &self.settings)
            .finish_non_exhaustive()
    }
}

fn clarabel_error(what: &str, e: impl std::fmt::Display) -> QpError {
    QpError::Reference {
        status: format!("{what}: {e}"),
    }
}

/// tol in (0, 1), polish_tol positive and finite.
fn check_settings(settings: &ReferenceSettings) -> Result<()> {
    if !(settings.tol > 0.0 && settings.tol < 1.0) {
        return Err(QpError::Parameter {
            name: "tol".into(),
            value: settings.tol,
            reason: "the reference tolerance must lie in (0, 1)".into(),
        });
    }
    if !(settings.polish_tol > 0.0 && settings.polish_tol.is_finite()) {
        return Err(QpError::Parameter {
            name: "polish_tol".into(),
            value: settings.polish_tol,
            reason: "the polish tolerance must be positive and finite".into(),
        });
    }
    Ok(())
}

/// Clarabel's P = triu(H), every entry kept (structural zeros too) so the pattern is fixed.
fn upper_triangle(qp: &ParametricQp) -> CscMatrix<f64> {
    let n = qp.n();
    let h = qp.h();
    let mut colptr = Vec::with_capacity(n + 1);
    let (mut rowval, mut nzval) = (Vec::new(), Vec::new());
    colptr.push(0);
    for j in 0..n {
        for i in 0..=j {
            rowval.push(i);
            nzval.push(h[(i, j)]);
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(n, n, colptr, rowval, nzval)
}

impl ReferenceSolver {
    /// Builds Clarabel's data for `qp` (q = q₀) and validates `settings`.
    pub fn new(qp: &ParametricQp, settings: ReferenceSettings) -> Result<Self> {
        check_settings(&settings)?;
        let n = qp.n();
        let p = upper_triangle(qp);
        // A: one row per finite bound, grouped by column.
        let (lo, up) = (qp.zset().lower(), qp.zset().upper());
        let mut rows = Vec::new();
        let mut b = Vec::new();
        let mut a_colptr = vec![0];
        let (mut a_rowval, mut a_nzval) = (Vec::new(), Vec::new());
        for j in 0..n {
            if up[j].is_finite() {
                a_rowval.push(rows.len());
                a_nzval.push(1.0);
                rows.push((j, true));
                b.push(up[j]);
            }
            if lo[j].is_finite() {
                a_rowval.push(rows.len());
                a_nzval.push(-1.0);
                rows.push((j, false));
                b.push(-lo[j]);
            }
            a_colptr.push(a_rowval.len());
        }
        // G rows: one per finite side of l₀ ≤ Gz ≤ u₀ (the side's finiteness does not
        // change with θ), placed after the box rows.
        let mut g_rows = Vec::new();
        let (mut g_lo, mut g_hi) = (Vec::new(), Vec::new());
        let mut a_dense: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        if let Some(gc) = qp.general() {
            let g = gc.g();
            for r in 0..gc.m() {
                for (upper, bound) in [(true, gc.upper()[r]), (false, gc.lower()[r])] {
                    if bound.is_finite() {
                        let row = rows.len() + g_rows.len();
                        let sign = if upper { 1.0 } else { -1.0 };
                        for (j, col) in a_dense.iter_mut().enumerate() {
                            col.push((row, sign * g[(r, j)]));
                        }
                        g_rows.push((r, upper));
                        b.push(if upper { bound } else { -bound });
                    }
                }
            }
            g_lo = gc.lower().to_vec();
            g_hi = gc.upper().to_vec();
        }
        if !g_rows.is_empty() {
            // Merge the G entries into the CSC columns (box rows first in each column).
            let (mut cp, mut rv, mut nz) = (vec![0], Vec::new(), Vec::new());
            for (j, extra) in a_dense.iter().enumerate() {
                for k in a_colptr[j]..a_colptr[j + 1] {
                    rv.push(a_rowval[k]);
                    nz.push(a_nzval[k]);
                }
                for &(r, v) in extra {
                    rv.push(r);
                    nz.push(v);
                }
                cp.push(rv.len());
            }
            a_colptr = cp;
            a_rowval = rv;
            a_nzval = nz;
        }
        let m = rows.len() + g_rows.len();
        let a = CscMatrix::new(m, n, a_colptr, a_rowval, a_nzval);
        let cones = if m > 0 {
            vec![SupportedConeT::NonnegativeConeT(m)]
        } else {
            Vec::new()
        };
        let clarabel_settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .presolve_enable(false)
            .input_sparse_dropzeros(false)
            .tol_gap_abs(settings.tol)
            .tol_gap_rel(settings.tol)
            .tol_feas(settings.tol)
            .max_iter(settings.max_iter)
            .max_threads(1)
            .build()
            .map_err(|e| clarabel_error("settings", e))?;
        let q = qp.q0().to_vec();
        let solver = DefaultSolver::new(&p, &q, &a, &b, &cones, clarabel_settings)
            .map_err(|e| clarabel_error("setup", e))?;
        Ok(Self {
            qp: qp.clone(),
            solver,
            rows,
            g_rows,
            b,
            g_lo,
            g_hi,
            settings,
            q,
        })
    }

    /// Solves for parameters θ (q = q₀ + Fθ, general bounds l₀ − Eθ, u₀ − Eθ). θ must have
    /// length n_θ and be finite.
    pub fn solve(&mut self, theta: &[f64]) -> Result<ReferenceSolution> {
        self.qp.check_theta(theta)?;
        self.qp.linear_term(theta, &mut self.q);
        if let Some(gc) = self.qp.general() {
            gc.bounds(theta, &mut self.g_lo, &mut self.g_hi);
            let nb = self.rows.len();
            for (k, &(r, upper)) in self.g_rows.iter().enumerate() {
                self.b[nb + k] = if upper { self.g_hi[r] } else { -self.g_lo[r] };
            }
            self.solver
                .update_b(&self.b)
                .map_err(|e| clarabel_error("update_b", e))?;
        }
        self.solve_loaded()
    }

    /// Solves for a given linear term q (length n, finite); general bounds of the last θ
    /// (θ = 0 before the first [`ReferenceSolver::solve`]).
    pub fn solve_q(&mut self, q: &[f64]) -> Result<ReferenceSolution> {
        crate::matrix::check_len("q", q, self.qp.n())?;
        crate::matrix::check_finite_slice("q", q)?;
        self.q.copy_from_slice(q);
        self.solve_loaded()
    }

    fn solve_loaded(&mut self) -> Result<ReferenceSolution> {
        self.solver
            .update_q(&self.q)
            .map_err(|e| clarabel_error("update_q", e))?;
        self.solver.solve();
        let sol = &self.solver.solution;
        if matches!(
            sol.status,
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible
        ) {
            return Err(QpError::Infeasible {
                solver: "Clarabel",
                detail: format!("{:?} after {} iterations", sol.status, sol.iterations),
                constraint: None,
            });
        }
        if sol.status != SolverStatus::Solved {
            return Err(QpError::Reference {
                status: format!(
                    "Clarabel returned {:?} after {} iterations",
                    sol.status, sol.iterations
                ),
            });
        }
        let n = self.qp.n();
        let mut lam_l = vec![0.0; n];
        let mut lam_u = vec![0.0; n];
        for (r, &(j, upper)) in self.rows.iter().enumerate() {
            if upper {
                lam_u[j] = sol.z[r];
            } else {
                lam_l[j] = sol.z[r];
            }
        }
        let mut z = sol.x.clone();
        let iterations = sol.iterations;
        let mut polished = false;
        if !self.g_rows.is_empty() {
            let nb = self.rows.len();
            let mut lam_g = vec![0.0; self.g_lo.len()];
            for (k, &(r, upper)) in self.g_rows.iter().enumerate() {
                lam_g[r] += if upper { -sol.z[nb + k] } else { sol.z[nb + k] };
            }
            let mut lam_box: Vec<f64> = lam_l.iter().zip(&lam_u).map(|(l, u)| l - u).collect();
            if self.settings.polish {
                if let Some((zp, lb, lg)) = self.polish_general(&z, &lam_box, &lam_g) {
                    z = zp;
                    lam_box = lb;
                    lam_g = lg;
                    polished = true;
                }
            }
            let objective = self.qp.objective(&self.q, &z);
            let kkt_residual = self.general_residual(&z, &lam_box, &lam_g);
            return Ok(ReferenceSolution {
                z,
                lower_multipliers: lam_box.iter().map(|v| v.max(0.0)).collect(),
                upper_multipliers: lam_box.iter().map(|v| (-v).max(0.0)).collect(),
                objective,
                iterations,
                polished,
                kkt_residual,
                general_multipliers: lam_g,
            });
        }
        if self.settings.polish {
            if let Some((zp, lp, up)) = self.polish(&self.q, &z, &lam_l, &lam_u) {
                z = zp;
                lam_l = lp;
                lam_u = up;
                polished = true;
            }
        }
        let objective = self.qp.objective(&self.q, &z);
        let kkt_residual = self.natural_residual(&self.q, &z);
        Ok(ReferenceSolution {
            z,
            lower_multipliers: lam_l,
            upper_multipliers: lam_u,
            objective,
            iterations,
            polished,
            kkt_residual,
            general_multipliers: Vec::new(),
        })
    }

    /// max(‖Hz + q − λ_box − Gᵀλ_G‖_∞, largest violation) for signed multipliers.
    fn general_residual(&self, z: &[f64], lam_box: &[f64], lam_g: &[f64]) -> f64 {
        let mut g = self.gradient(&self.q, z);
        for (gi, l) in g.iter_mut().zip(lam_box) {
            *gi -= l;
        }
        let mut viol = 0.0f64;
        for ((zi, l), u) in z
            .iter()
            .zip(self.qp.zset().lower())
            .zip(self.qp.zset().upper())
        {
            viol = viol.max(l - zi).max(zi - u);
        }
        if let Some(gc) = self.qp.general() {
            let gm = gc.g();
            for (r, &l) in lam_g.iter().enumerate() {
                for (j, gj) in g.iter_mut().enumerate() {
                    *gj -= l * gm[(r, j)];
                }
            }
            viol = viol.max(gc.violation(z, &self.g_lo, &self.g_hi));
        }
        g.iter().fold(viol, |a, v| a.max(v.abs()))
    }

    /// Polish with general rows: the KKT system of the guessed active rows, solved by LU;
    /// `None` unless the result is feasible with multipliers of the right signs.
    fn polish_general(
        &self,
        z: &[f64],
        lam_box: &[f64],
        lam_g: &[f64],
    ) -> Option<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        let gc = self.qp.general()?;
        let n = self.qp.n();
        let (lo, up) = (self.qp.zset().lower(), self.qp.zset().upper());
        // Active rows (index < n: box, else G), with the bound they hold.
        let mut act: Vec<(usize, f64)> = Vec::new();
        for i in 0..n {
            let l = lam_box[i];
            if lo[i] == up[i] || (l > 0.0 && l > z[i] - lo[i]) {
                act.push((i, lo[i]));
            } else if l < 0.0 && -l > up[i] - z[i] {
                act.push((i, up[i]));
            }
        }
        for r in 0..gc.m() {
            let gz = gc.row_dot(r, z);
            let (l, glo, ghi) = (lam_g[r], self.g_lo[r], self.g_hi[r]);
            if glo == ghi || (l > 0.0 && l > gz - glo) {
                act.push((n + r, glo));
            } else if l < 0.0 && -l > ghi - gz {
                act.push((n + r, ghi));
            }
        }
        let k = act.len();
        let h = self.qp.h();
        let gm = gc.g();
        let arow = |a: usize, j: usize| {
            let (r, _) = act[a];
            if r < n {
                if r == j { 1.0 } else { 0.0 }
            } else {
                gm[(r - n, j)]
            }
        };
        let kkt = Mat::from_fn(n + k, n + k, |i, j| match (i < n, j < n) {
            (true, true) => h[(i, j)],
            (true, false) => -arow(j - n, i),
            (false, true) => arow(i - n, j),
            (false, false) => 0.0,
        });
        let rhs = Mat::from_fn(
            n + k,
            1,
            |i, _| if i < n { -self.q[i] } else { act[i - n].1 },
        );
        let sol = faer::linalg::solvers::Solve::solve(&kkt.partial_piv_lu(), rhs);
        if (0..n + k).any(|i| !sol[(i, 0)].is_finite()) {
            return None;
        }
        let zp: Vec<f64> = (0..n).map(|i| sol[(i, 0)]).collect();
        let mut lb = vec![0.0; n];
        let mut lg = vec![0.0; gc.m()];
        for (a, &(r, bound)) in act.iter().enumerate() {
            let l = sol[(n + a, 0)];
            let (rlo, rhi) = if r < n {
                (lo[r], up[r])
            } else {
                (self.g_lo[r - n], self.g_hi[r - n])
            };
            // Sign: λ ≥ 0 at a lower bound, ≤ 0 at an upper one (free for equalities).
            let lam = if rlo == rhi {
                l
            } else if bound == rlo {
                if l < -1e-9 * (1.0 + l.abs()) {
                    return None;
                }
                l.max(0.0)
            } else {
                if l > 1e-9 * (1.0 + l.abs()) {
                    return None;
                }
                l.min(0.0)
            };
            if r < n {
                lb[r] = lam;
            } else {
                lg[r - n] = lam;
            }
        }
        let scale = 1.0
            + zp.iter().map(|v| v.abs()).fold(0.0, f64::max)
            + self.q.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let res = self.general_residual(&zp, &lb, &lg);
        (res <= self.settings.polish_tol * scale).then_some((zp, lb, lg))
    }

    /// ‖z − Π_Z(z − (Hz + q))‖_∞.
    pub fn natural_residual(&self, q: &[f64], z: &[f64]) -> f64 {
        let g = self.gradient(q, z);
        let mut t: Vec<f64> = z.iter().zip(&g).map(|(z, g)| z - g).collect();
        self.qp.zset().project(&mut t);
        z.iter()
            .zip(&t)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    }

    fn gradient(&self, q: &[f64], z: &[f64]) -> Vec<f64> {
        let n = self.qp.n();
        let h = self.qp.h_row_major();
        (0..n)
            .map(|i| {
                h[i * n..(i + 1) * n]
                    .iter()
                    .zip(z)
                    .map(|(a, b)| a * b)
                    .sum::<f64>()
                    + q[i]
            })
            .collect()
    }

    /// Active-set refinement; `None` if the guessed active set fails the KKT check.
    fn polish(
        &self,
        q: &[f64],
        z: &[f64],
        lam_l: &[f64],
        lam_u: &[f64],
    ) -> Option<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        let n = self.qp.n();
        let (lo, up) = (self.qp.zset().lower(), self.qp.zset().upper());
        // Active where the multiplier exceeds the slack (OSQP's rule).
        let mut fixed: Vec<Option<f64>> = vec![None; n];
        for i in 0..n {
            if lo[i] == up[i] {
                fixed[i] = Some(lo[i]);
            } else if up[i].is_finite() && lam_u[i] > up[i] - z[i] {
                fixed[i] = Some(up[i]);
            } else if lo[i].is_finite() && lam_l[i] > z[i] - lo[i] {
                fixed[i] = Some(lo[i]);
            }
        }
        let free: Vec<usize> = (0..n).filter(|&i| fixed[i].is_none()).collect();
        let mut zp: Vec<f64> = (0..n).map(|i| fixed[i].unwrap_or(0.0)).collect();
        if !free.is_empty() {
            let h = self.qp.h();
            let nf = free.len();
            let hff = Mat::from_fn(nf, nf, |a, b| h[(free[a], free[b])]);
            let rhs = Mat::from_fn(nf, 1, |a, _| {
                let i = free[a];
                -(q[i]
                    + (0..n)
                        .filter_map(|j| fixed[j].map(|v| h[(i, j)] * v))
                        .sum::<f64>())
            });
            let llt = hff.llt(Side::Lower).ok()?;
            let sol = faer::linalg::solvers::Solve::solve(&llt, rhs);
            for (a, &i) in free.iter().enumerate() {
                zp[i] = sol[(a, 0)];
            }
        }
        // KKT check, scaled by the data.
        let g = self.gradient(q, &zp);
        let scale = 1.0
            + zp.iter().map(|v| v.abs()).fold(0.0, f64::max)
            + g.iter().map(|v| v.abs()).fold(0.0, f64::max)
            + q.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let tol = self.settings.polish_tol * scale;
        let mut lp = vec![0.0; n];
        let mut upm = vec![0.0; n];
        for i in 0..n {
            if !zp[i].is_finite() || zp[i] < lo[i] - tol || zp[i] > up[i] + tol {
                return None;
            }
            match fixed[i] {
                None => {
                    if g[i].abs() > tol {
                        return None;
                    }
                }
                Some(v) if v == up[i] && lo[i] != up[i] => {
                    // Hz + q + λ_u = 0 ⇒ λ_u = −g ≥ 0.
                    if -g[i] < -tol {
                        return None;
                    }
                    upm[i] = (-g[i]).max(0.0);
                }
                Some(_) if lo[i] == up[i] => {
                    if g[i] > 0.0 {
                        lp[i] = g[i];
                    } else {
                        upm[i] = -g[i];
                    }
                }
                Some(_) => {
                    if g[i] < -tol {
                        return None;
                    }
                    lp[i] = g[i].max(0.0);
                }
            }
        }
        // Clip tiny infeasibilities of the linear solve.
        self.qp.zset().project(&mut zp);
        Some((zp, lp, upm))
    }
}
