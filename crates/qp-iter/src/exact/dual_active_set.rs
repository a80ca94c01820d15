//! An exact solver for strictly convex QPs with a box and general rows: the dual active-set
//! method of Goldfarb and Idnani.
//!
//! minimise ½zᵀHz + qᵀz subject to l ≤ z ≤ u and l_G ≤ Gz ≤ u_G, H ≻ 0,
//!
//! each of the n + m rows a_r (e_r for the box, a row of G) a two-sided inequality (±∞
//! allowed per side; l = u is an equality, never dropped once active). The method starts at
//! the unconstrained minimiser −H⁻¹q (dual feasible, all multipliers zero) and adds the most
//! violated constraint one at a time, dropping active constraints whose multiplier would turn
//! negative, so every step keeps dual feasibility and increases the dual objective. It is
//! finite and exact, and it **proves infeasibility**: a violated constraint that can be
//! reached neither by a primal step (its normal lies in the span of the active normals) nor
//! by dropping an active inequality makes the QP infeasible ([`DualActiveSetStatus::Infeasible`]).
//!
//! **Factorisation.** With H = LLᵀ and J = L⁻ᵀ (so JᵀHJ = I), the active normals N satisfy
//! JᵀN = [R; 0] with R upper triangular. Adding a constraint appends a column to R and
//! rotates columns of J (Givens); dropping one removes a column of R and restores the
//! triangle by Givens rotations of rows of R and columns of J: O(n²) per change. With H = I
//! ([`DualActiveSet::identity`], a Euclidean projection) no factorisation is needed, and the
//! method starts from the box clamp of −q with the violated bounds already active (J a
//! signed permutation, R = I): the state the method would reach by adding those bounds one
//! by one, built in O(n²) instead of O(k·n²).
//!
//! **Steps** (for the constraint nᵀz ≥ b being added, s = nᵀz − b < 0, d = Jᵀn, d₂ its part
//! beyond the active columns): primal direction z_dir = J₂d₂, dual direction r = R⁻¹d₁;
//! full step t₂ = −s/‖d₂‖², partial step t₁ = min over active inequalities with r_k > 0 of
//! u_k/r_k; t = min(t₁, t₂). t = ∞ is infeasibility.
//!
//! Every call after construction is allocation-free. A solution is returned with its
//! stationarity residual and largest violation ([`DualActiveSetInfo`]), computed from the
//! data, not from the factors.
//!
//! ## Reference
//! D. Goldfarb, A. Idnani, "A numerically stable dual method for solving strictly convex
//! quadratic programs", Math. Programming 27 (1983) 1–33; the update formulas follow
//! QuadProg (Turlach) and eiQuadProg (Di Gaspero).

use faer::{MatRef, Side};

use crate::error::{QpError, Result};

/// Settings of [`DualActiveSet`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DualActiveSetSettings {
    /// Relative feasibility tolerance: a side is violated when it misses its bound by more
    /// than tol·(1 + |bound|). In (0, 1).
    pub tol: f64,
    /// A constraint's normal counts as dependent on the active normals when the part of
    /// Jᵀn outside their span is below `dependence`·‖Jᵀn‖. In (0, 1).
    pub dependence: f64,
    /// Largest number of primal or dual steps per call. `None`: 10·(n + m) + 50.
    pub max_iter: Option<usize>,
}

impl Default for DualActiveSetSettings {
    fn default() -> Self {
        Self {
            tol: 1e-11,
            dependence: 1e-11,
            max_iter: None,
        }
    }
}

/// A row of the constraints (also in [`crate::QpError::Infeasible`]).
pub use crate::error::ConstraintRow;

pub use super::parametric_dual::ParametricDualActiveSet;

/// How a call of [`DualActiveSet`] ended.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case", tag = "status"))]
#[non_exhaustive]
pub enum DualActiveSetStatus {
    /// The minimiser (within the tolerances; see [`DualActiveSetInfo`]).
    Optimal,
    /// The constraints have no common point: `constraint` was violated by `violation`
    /// (in its own units) and could be reached neither by a primal step nor by dropping an
    /// active inequality.
    Infeasible {
        /// The constraint that could not be added.
        constraint: ConstraintRow,
        /// How far the last iterate missed it.
        violation: f64,
    },
    /// The step limit was reached (cycling under degeneracy; not seen in the tests).
    MaxIterations,
}

/// Outcome of one call.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct DualActiveSetInfo {
    /// How the call ended.
    pub status: DualActiveSetStatus,
    /// Primal and dual steps taken.
    pub iterations: usize,
    /// Active constraints at the end.
    pub active: usize,
    /// ‖Hz + q − Aᵀλ‖_∞ at the returned z (A = [I; G], λ the signed multipliers).
    pub stationarity: f64,
    /// The largest violation of any bound by the returned z (0 if feasible).
    pub violation: f64,
    /// 1 + ‖q‖_∞ + ‖Hz‖_∞: the scale the residuals are relative to.
    pub scale: f64,
}

impl DualActiveSetInfo {
    /// Optimal with stationarity and violation both ≤ `tol`·scale.
    pub fn is_verified(&self, tol: f64) -> bool {
        self.status == DualActiveSetStatus::Optimal
            && self.stationarity <= tol * self.scale
            && self.violation <= tol * self.scale
    }
}

const INACTIVE: u8 = 0;
const LOWER: u8 = 1;
const UPPER: u8 = 2;

/// The Goldfarb–Idnani solver for fixed H and G; q and the bounds change per call.
///
/// ```
/// use faer::mat;
/// use qp_iter::dual_active_set::{DualActiveSet, DualActiveSetSettings, DualActiveSetStatus};
/// // Project (2, 2) onto {z ≥ 0, z₀ + z₁ ≤ 1}: H = I, q = −(2, 2) → z* = (½, ½).
/// let g = mat![[1.0, 1.0]];
/// let mut s = DualActiveSet::identity(2, g.as_ref(), DualActiveSetSettings::default()).unwrap();
/// let inf = f64::INFINITY;
/// let info = s.solve(&[-2.0, -2.0], &[0.0, 0.0], &[inf, inf], &[-inf], &[1.0]);
/// assert_eq!(info.status, DualActiveSetStatus::Optimal);
/// assert!((s.z()[0] - 0.5).abs() < 1e-15 && (s.z()[1] - 0.5).abs() < 1e-15);
/// assert!((s.multipliers()[2] + 1.5).abs() < 1e-14); // upper side of the G row: λ = −1.5
/// // z₀ + z₁ ≤ −1 with z ≥ 0 is infeasible, and says so.
/// let info = s.solve(&[-2.0, -2.0], &[0.0, 0.0], &[inf, inf], &[-inf], &[-1.0]);
/// assert!(matches!(info.status, DualActiveSetStatus::Infeasible { .. }));
/// ```
#[derive(Debug, Clone)]
pub struct DualActiveSet {
    n: usize,
    m: usize,
    /// H row-major (empty for H = I).
    h: Vec<f64>,
    /// L⁻ᵀ column-major (empty for H = I).
    j0: Vec<f64>,
    /// G row-major.
    g: Vec<f64>,
    /// ‖G_r‖₂ per row.
    g_norm: Vec<f64>,
    settings: DualActiveSetSettings,
    max_iter: usize,
    // Workspace (n + m rows: the box first, then G).
    lo: Vec<f64>,
    hi: Vec<f64>,
    j: Vec<f64>,
    r: Vec<f64>,
    x: Vec<f64>,
    d: Vec<f64>,
    zdir: Vec<f64>,
    rdir: Vec<f64>,
    /// Active constraints (row, side) in R's column order, plus the one being added.
    active: Vec<(usize, u8)>,
    /// Multipliers ≥ 0 of `active` (any sign for equalities).
    u: Vec<f64>,
    row_state: Vec<u8>,
    /// Signed multipliers per row at the last solution: Hz + q = Aᵀλ.
    lam: Vec<f64>,
    grad: Vec<f64>,
    q: Vec<f64>,
    iq: usize,
}

impl DualActiveSet {
    /// Sets the solver up for H (n × n, symmetric positive definite) and G (m × n).
    /// Factorises H once.
    pub fn new(
        h: MatRef<'_, f64>,
        g: MatRef<'_, f64>,
        settings: DualActiveSetSettings,
    ) -> Result<Self> {
        let n = h.nrows();
        crate::matrix::check_positive_definite("H", h, n)?;
        let mut s = Self::identity(n, g, settings)?;
        let llt = h
            .to_owned()
            .llt(Side::Lower)
            .map_err(|e| crate::DataError::Numerical {
                routine: "Cholesky factorisation of H (dual active set)".into(),
                reason: format!("{e:?}; H must be positive definite"),
            })?;
        let l = llt.L();
        // J = L⁻ᵀ: solve Lᵀ J = I column by column (back substitution).
        let mut j0 = vec![0.0; n * n];
        for k in 0..n {
            let col = &mut j0[k * n..(k + 1) * n];
            for i in (0..=k).rev() {
                let mut v = if i == k { 1.0 } else { 0.0 };
                for p in i + 1..=k {
                    v -= l[(p, i)] * col[p];
                }
                col[i] = v / l[(i, i)];
            }
        }
        if j0.iter().any(|v| !v.is_finite()) {
            return Err(crate::DataError::Numerical {
                routine: "inverse Cholesky factor of H (dual active set)".into(),
                reason: "non-finite entries; H is numerically singular".into(),
            }
            .into());
        }
        s.h = crate::matrix::row_major(h);
        s.j0 = j0;
        Ok(s)
    }

    /// The solver for H = I: a Euclidean projection onto the constraints (no factorisation).
    pub fn identity(n: usize, g: MatRef<'_, f64>, settings: DualActiveSetSettings) -> Result<Self> {
        for (name, v) in [("tol", settings.tol), ("dependence", settings.dependence)] {
            if !(v > 0.0 && v < 1.0) {
                return Err(QpError::Parameter {
                    name: name.into(),
                    value: v,
                    reason: "the dual active-set tolerances must lie in (0, 1), e.g. 1e-11".into(),
                });
            }
        }
        if settings.max_iter == Some(0) {
            return Err(QpError::Parameter {
                name: "max_iter".into(),
                value: 0.0,
                reason: "at least one step is needed; use None for 10·(n + m) + 50".into(),
            });
        }
        crate::matrix::check_shape("G", g, g.nrows(), n)?;
        crate::matrix::check_finite("G", g)?;
        Ok(Self::identity_validated(n, g, settings))
    }

    /// [`DualActiveSet::identity`] for settings and a G already validated (a
    /// [`crate::problem::GeneralConstraints`] with the default settings).
    pub(crate) fn identity_validated(
        n: usize,
        g: MatRef<'_, f64>,
        settings: DualActiveSetSettings,
    ) -> Self {
        let m = g.nrows();
        let rows = crate::matrix::row_major(g);
        let g_norm = (0..m)
            .map(|i| {
                rows[i * n..(i + 1) * n]
                    .iter()
                    .map(|v| v * v)
                    .sum::<f64>()
                    .sqrt()
            })
            .collect();
        let nr = n + m;
        Self {
            n,
            m,
            h: Vec::new(),
            j0: Vec::new(),
            g: rows,
            g_norm,
            settings,
            max_iter: settings.max_iter.unwrap_or(10 * nr + 50),
            lo: vec![0.0; nr],
            hi: vec![0.0; nr],
            j: vec![0.0; n * n],
            r: vec![0.0; n * n],
            x: vec![0.0; n],
            d: vec![0.0; n],
            zdir: vec![0.0; n],
            rdir: vec![0.0; n + 1],
            active: vec![(0, INACTIVE); n + 1],
            u: vec![0.0; n + 1],
            row_state: vec![INACTIVE; nr],
            lam: vec![0.0; nr],
            grad: vec![0.0; n],
            q: vec![0.0; n],
            iq: 0,
        }
    }

    /// The settings.
    pub fn settings(&self) -> DualActiveSetSettings {
        self.settings
    }
    /// Number of variables n.
    pub fn n(&self) -> usize {
        self.n
    }
    /// Number of general rows m.
    pub fn m(&self) -> usize {
        self.m
    }
    /// The last iterate (the minimiser after [`DualActiveSetStatus::Optimal`]).
    pub fn z(&self) -> &[f64] {
        &self.x
    }
    /// Signed multipliers of the n box rows then the m rows of G at the last solution:
    /// Hz + q = λ_box + Gᵀλ_G, λ_r > 0 where the lower side is active, < 0 the upper side.
    pub fn multipliers(&self) -> &[f64] {
        &self.lam
    }
    /// Objective ½zᵀHz + qᵀz of the last iterate.
    pub fn objective(&self) -> f64 {
        let mut v = 0.0;
        for i in 0..self.n {
            v += self.x[i] * (0.5 * self.hz(i) + self.q[i]);
        }
        v
    }

    fn hz(&self, i: usize) -> f64 {
        if self.h.is_empty() {
            self.x[i]
        } else {
            let n = self.n;
            self.h[i * n..(i + 1) * n]
                .iter()
                .zip(&self.x)
                .map(|(a, b)| a * b)
                .sum()
        }
    }

    /// a_r·x.
    #[inline]
    fn row_dot(&self, r: usize, x: &[f64]) -> f64 {
        if r < self.n {
            x[r]
        } else {
            let (n, k) = (self.n, r - self.n);
            self.g[k * n..(k + 1) * n]
                .iter()
                .zip(x)
                .map(|(a, b)| a * b)
                .sum()
        }
    }

    /// s = nᵀx − b for (row, side).
    #[inline]
    fn slack(&self, r: usize, side: u8) -> f64 {
        let ax = self.row_dot(r, &self.x);
        if side == LOWER {
            ax - self.lo[r]
        } else {
            self.hi[r] - ax
        }
    }

    /// Solves with linear term q, box [`box_lo`, `box_hi`] and general bounds
    /// [`g_lo`, `g_hi`] (lengths n, n, m, m; ±∞ allowed, lower ≤ upper). Allocation-free.
    pub fn solve(
        &mut self,
        q: &[f64],
        box_lo: &[f64],
        box_hi: &[f64],
        g_lo: &[f64],
        g_hi: &[f64],
    ) -> DualActiveSetInfo {
        let (n, m) = (self.n, self.m);
        debug_assert!(q.len() == n && box_lo.len() == n && box_hi.len() == n);
        debug_assert!(g_lo.len() == m && g_hi.len() == m);
        self.q.copy_from_slice(q);
        self.lo[..n].copy_from_slice(box_lo);
        self.hi[..n].copy_from_slice(box_hi);
        self.lo[n..].copy_from_slice(g_lo);
        self.hi[n..].copy_from_slice(g_hi);
        let (status, iterations) = self.run();
        self.finish(status, iterations)
    }

    fn run(&mut self) -> (DualActiveSetStatus, usize) {
        let n = self.n;
        // J = L⁻ᵀ (or I), R empty, x = −JJᵀq.
        if self.j0.is_empty() {
            self.j.fill(0.0);
            for i in 0..n {
                self.j[i * n + i] = 1.0;
            }
            for i in 0..n {
                self.x[i] = -self.q[i];
            }
        } else {
            self.j.copy_from_slice(&self.j0);
            for k in 0..n {
                self.d[k] = dot(&self.j[k * n..(k + 1) * n], &self.q);
            }
            self.x.fill(0.0);
            for k in 0..n {
                let dk = self.d[k];
                for (xi, jik) in self.x.iter_mut().zip(&self.j[k * n..(k + 1) * n]) {
                    *xi -= jik * dk;
                }
            }
        }
        self.iq = 0;
        self.row_state.fill(INACTIVE);
        if self.j0.is_empty() {
            self.start_at_box_clamp();
        }
        // A zero row of G constrains nothing but its bounds: 0 ∉ [lo, hi] is infeasible
        // whatever z (no step can reach it).
        for k in 0..self.m {
            let r = self.n + k;
            let miss = self.lo[r].max(-self.hi[r]);
            if self.g_norm[k] == 0.0 && miss > self.settings.tol * (1.0 + miss.abs()) {
                return (
                    DualActiveSetStatus::Infeasible {
                        constraint: ConstraintRow::General(k),
                        violation: miss,
                    },
                    0,
                );
            }
        }
        let mut iter = 0;
        loop {
            // Step 1: the most violated constraint (distance to its hyperplane).
            let Some((ip, side)) = self.most_violated() else {
                return (DualActiveSetStatus::Optimal, iter);
            };
            let iq = self.iq;
            self.active[iq] = (ip, side);
            self.u[iq] = 0.0;
            let mut s_ip = self.slack(ip, side);
            loop {
                iter += 1;
                if iter > self.max_iter {
                    return (DualActiveSetStatus::MaxIterations, iter - 1);
                }
                let iq = self.iq;
                self.compute_d(ip, side);
                let dsq: f64 = self.d.iter().map(|v| v * v).sum();
                let d2sq: f64 = self.d[iq..].iter().map(|v| v * v).sum();
                self.compute_z();
                self.compute_r();
                // Partial step t₁: the active inequality whose multiplier reaches 0 first.
                let mut t1 = f64::INFINITY;
                let mut drop = usize::MAX;
                for k in 0..iq {
                    let (row, _) = self.active[k];
                    if self.lo[row] == self.hi[row] {
                        continue; // an equality is never dropped
                    }
                    if self.rdir[k] > 0.0 {
                        let t = self.u[k] / self.rdir[k];
                        if t < t1 {
                            t1 = t;
                            drop = k;
                        }
                    }
                }
                let dep = self.settings.dependence;
                let t2 = if d2sq > dep * dep * dsq && d2sq > 0.0 {
                    (-s_ip / d2sq).max(0.0)
                } else {
                    f64::INFINITY
                };
                let t = t1.min(t2);
                if t == f64::INFINITY {
                    return (
                        DualActiveSetStatus::Infeasible {
                            constraint: self.row_name(ip),
                            violation: -s_ip,
                        },
                        iter,
                    );
                }
                for k in 0..iq {
                    self.u[k] -= t * self.rdir[k];
                }
                self.u[iq] += t;
                if t2 == f64::INFINITY {
                    // Dual step only: drop the blocking constraint, try again.
                    self.delete(drop);
                    continue;
                }
                for (xi, zi) in self.x.iter_mut().zip(&self.zdir) {
                    *xi += t * zi;
                }
                if t2 <= t1 {
                    // Full step: the constraint becomes active.
                    self.add();
                    self.row_state[ip] = side;
                    break;
                }
                self.delete(drop);
                s_ip = self.slack(ip, side);
            }
        }
    }

    /// H = I: the state GI reaches after adding the violated box bounds, built directly in
    /// O(n²) instead of O(k·n²): x = clamp(−q), J = [s_p e_{i_p} | e_free] (a signed
    /// permutation, orthogonal), R = I_k, multipliers u_p = s_p(x_i − (−q)_i) ≥ 0 — the
    /// minimiser over {z_i = bound_i, i active} with dual-feasible multipliers, exactly
    /// GI's invariant.
    fn start_at_box_clamp(&mut self) {
        let n = self.n;
        let tol = self.settings.tol;
        let mut k = 0;
        for i in 0..n {
            let x0 = self.x[i];
            let (lo, hi) = (self.lo[i], self.hi[i]);
            let side = if lo.is_finite() && lo - x0 > tol * (1.0 + lo.abs()) {
                LOWER
            } else if hi.is_finite() && x0 - hi > tol * (1.0 + hi.abs()) {
                UPPER
            } else {
                continue;
            };
            let (bound, sign) = if side == LOWER { (lo, 1.0) } else { (hi, -1.0) };
            self.x[i] = bound;
            self.active[k] = (i, side);
            self.u[k] = sign * (bound - x0);
            self.row_state[i] = side;
            k += 1;
        }
        if k == 0 {
            return;
        }
        // J: the active coordinates first (signed), then the free ones; R = I_k.
        self.j.fill(0.0);
        for p in 0..k {
            let (i, side) = self.active[p];
            self.j[p * n + i] = if side == LOWER { 1.0 } else { -1.0 };
            for q in 0..=p {
                self.r[p * n + q] = if q == p { 1.0 } else { 0.0 };
            }
        }
        let mut col = k;
        for i in 0..n {
            if self.row_state[i] == INACTIVE {
                self.j[col * n + i] = 1.0;
                col += 1;
            }
        }
        self.iq = k;
    }

    fn row_name(&self, r: usize) -> ConstraintRow {
        if r < self.n {
            ConstraintRow::Box(r)
        } else {
            ConstraintRow::General(r - self.n)
        }
    }

    fn most_violated(&self) -> Option<(usize, u8)> {
        let tol = self.settings.tol;
        let mut best: Option<(usize, u8, f64)> = None;
        for r in 0..self.n + self.m {
            if self.row_state[r] != INACTIVE {
                continue;
            }
            let norm = if r < self.n {
                1.0
            } else {
                self.g_norm[r - self.n]
            };
            if norm == 0.0 {
                continue; // a zero row: 0 ∈ [lo, hi] was checked at the start
            }
            let ax = self.row_dot(r, &self.x);
            let (lo, hi) = (self.lo[r], self.hi[r]);
            for (side, miss, bound) in [(LOWER, lo - ax, lo), (UPPER, ax - hi, hi)] {
                if bound.is_finite() && miss > tol * (1.0 + bound.abs()) {
                    let score = miss / norm;
                    if best.is_none_or(|(_, _, b)| score > b) {
                        best = Some((r, side, score));
                    }
                }
            }
        }
        best.map(|(r, s, _)| (r, s))
    }

    /// d = Jᵀn for the normal n of (row, side).
    fn compute_d(&mut self, row: usize, side: u8) {
        let n = self.n;
        let sign = if side == LOWER { 1.0 } else { -1.0 };
        if row < n {
            for k in 0..n {
                self.d[k] = sign * self.j[k * n + row];
            }
        } else {
            let g = &self.g[(row - n) * n..(row - n + 1) * n];
            for k in 0..n {
                self.d[k] = sign * dot(&self.j[k * n..(k + 1) * n], g);
            }
        }
    }

    /// z = J₂d₂ (columns iq.. of J).
    fn compute_z(&mut self) {
        let n = self.n;
        self.zdir.fill(0.0);
        for k in self.iq..n {
            let dk = self.d[k];
            for (zi, jik) in self.zdir.iter_mut().zip(&self.j[k * n..(k + 1) * n]) {
                *zi += jik * dk;
            }
        }
    }

    /// r = R⁻¹d₁ (back substitution on the iq × iq triangle).
    fn compute_r(&mut self) {
        let n = self.n;
        for i in (0..self.iq).rev() {
            let mut v = self.d[i];
            for k in i + 1..self.iq {
                v -= self.r[k * n + i] * self.rdir[k];
            }
            self.rdir[i] = v / self.r[i * n + i];
        }
    }

    /// Appends the constraint whose d was computed last: rotates d[iq..] onto d[iq] (and
    /// the columns of J with it), then R's column iq = d[..=iq].
    fn add(&mut self) {
        let n = self.n;
        let iq = self.iq;
        for jj in (iq + 1..n).rev() {
            let (a, b) = (self.d[jj - 1], self.d[jj]);
            let h = a.hypot(b);
            if h == 0.0 {
                continue;
            }
            let (c, s) = (a / h, b / h);
            self.d[jj - 1] = h;
            self.d[jj] = 0.0;
            let (left, right) = self.j.split_at_mut(jj * n);
            rotate(&mut left[(jj - 1) * n..], &mut right[..n], c, s);
        }
        for i in 0..=iq {
            self.r[iq * n + i] = self.d[i];
        }
        self.iq += 1;
    }

    /// Removes the active constraint at position `k` (R's column k), shifting the later
    /// ones (including the one being added, at position iq) and restoring the triangle.
    fn delete(&mut self, k: usize) {
        let n = self.n;
        let iq = self.iq;
        let (row, _) = self.active[k];
        self.row_state[row] = INACTIVE;
        for p in k..iq {
            self.active[p] = self.active[p + 1];
            self.u[p] = self.u[p + 1];
        }
        for p in k..iq - 1 {
            let (a, b) = self.r.split_at_mut((p + 1) * n);
            a[p * n..p * n + n].copy_from_slice(&b[..n]);
        }
        self.iq -= 1;
        let iq = self.iq;
        for jj in k..iq {
            let (a, b) = (self.r[jj * n + jj], self.r[jj * n + jj + 1]);
            let h = a.hypot(b);
            if h == 0.0 {
                continue;
            }
            let (c, s) = (a / h, b / h);
            self.r[jj * n + jj] = h;
            self.r[jj * n + jj + 1] = 0.0;
            for col in jj + 1..iq {
                let (x, y) = (self.r[col * n + jj], self.r[col * n + jj + 1]);
                self.r[col * n + jj] = c * x + s * y;
                self.r[col * n + jj + 1] = -s * x + c * y;
            }
            let (left, right) = self.j.split_at_mut((jj + 1) * n);
            rotate(&mut left[jj * n..], &mut right[..n], c, s);
        }
    }

    /// Multipliers per row, stationarity and violation from the data.
    fn finish(&mut self, status: DualActiveSetStatus, iterations: usize) -> DualActiveSetInfo {
        let n = self.n;
        self.lam.fill(0.0);
        if status == DualActiveSetStatus::Optimal {
            for k in 0..self.iq {
                let (row, side) = self.active[k];
                self.lam[row] = if side == LOWER { self.u[k] } else { -self.u[k] };
            }
        }
        let (mut qmax, mut hzmax) = (0.0f64, 0.0f64);
        for i in 0..n {
            let hz = self.hz(i);
            qmax = qmax.max(self.q[i].abs());
            hzmax = hzmax.max(hz.abs());
            self.grad[i] = hz + self.q[i] - self.lam[i];
        }
        for k in 0..self.m {
            let l = self.lam[n + k];
            if l != 0.0 {
                for (gi, a) in self.grad.iter_mut().zip(&self.g[k * n..(k + 1) * n]) {
                    *gi -= l * a;
                }
            }
        }
        let stationarity = self.grad.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let mut violation = 0.0f64;
        for r in 0..n + self.m {
            let ax = self.row_dot(r, &self.x);
            violation = violation.max(self.lo[r] - ax).max(ax - self.hi[r]);
        }
        if self.x.iter().any(|v| !v.is_finite()) {
            violation = f64::INFINITY;
        }
        DualActiveSetInfo {
            status,
            iterations,
            active: self.iq,
            stationarity,
            violation,
            scale: 1.0 + qmax + hzmax,
        }
    }
}

#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// (a, b) ← (c·a + s·b, −s·a + c·b) on the first n entries of two columns.
#[inline]
fn rotate(a: &mut [f64], b: &mut [f64], c: f64, s: f64) {
    for (x, y) in a.iter_mut().zip(b.iter_mut()) {
        let (p, q) = (*x, *y);
        *x = c * p + s * q;
        *y = -s * p + c * q;
    }
}
