//! An exact, allocation-free solver for strictly convex box QPs: the primal active-set
//! method (Nocedal–Wright, *Numerical Optimization*, 2nd ed., Alg. 16.3) specialised to
//! bounds, warm-started from the previous working set (or from a point the caller supplies,
//! [`ActiveSetSolver::warm_start`]).
//!
//! minimise ½zᵀHz + qᵀz subject to l ≤ z ≤ u, H ≻ 0.
//!
//! Why it exists: the exact MPC law π(x̂) = u*₀(x̂) is evaluated once per closed-loop step,
//! and analysis runs solve every MHE problem ℙ_t exactly to record ε_t. Clarabel (an
//! interior-point method) needs ≈ 150 µs for the case study's 20-variable QP; consecutive
//! problems share H and the box and differ only in q, so their optimal active sets differ
//! little, and a working-set method started from the last one usually finishes in a few
//! subspace solves on a cached Cholesky factor.
//!
//! Each iteration, for the working set W (variables held at a bound) and the free set F:
//!
//! 1. the subspace minimiser ẑ: ẑ_W = z_W, H_FF ẑ_F = −(q_F + H_FW z_W), with the
//!    Cholesky factor of H_FF and the right-hand side both kept up to date as W changes;
//! 2. if ẑ violates a bound, step z ← z + α(ẑ − z) with the largest feasible α ∈ [0, 1) and
//!    add the first blocking bound to W;
//! 3. otherwise z ← ẑ and the multipliers λ_i = ±(Hz + q)_i of W are checked; if all are
//!    ≥ −tol, z is optimal, else the most negative one leaves W.
//!
//! **The factor.** A bound entering or leaving W changes F by one variable; the factor of
//! H_FF is then *updated* (a row appended, or a row removed and the triangle restored by
//! Givens rotations: O(|F|²) instead of O(|F|³), Golub & Van Loan §6.5.4), and kept across
//! calls (not across [`ActiveSetSolver::reset`]). At the start of a call it is brought to
//! the call's free set by the same updates, or recomputed from H when that is cheaper (many
//! changes), after
//! [`ActiveSetSettings::max_updates`] updates since the last fresh factorisation, and
//! whenever an update reports numerical trouble.
//!
//! Every accepted solution passes an explicit KKT check on z and g = Hz + q computed from
//! the problem data (not from the factor): multipliers ≥ −tol·scale and natural residual
//! ‖z − Π_Z(z − g)‖_∞ ≤ tol·scale. If the check fails on an updated factor, the factor is
//! recomputed from H and the iteration continues; a run that does not finish in `max_iter`
//! subspace solves (cycling under degeneracy is possible in theory) or fails the check on a
//! fresh factor is a typed [`QpError::NotConverged`], so a caller can fall back to
//! [`crate::reference`] ([`ExactSolver`] does).

use super::free_factor::{FactorBreakdown, FreeFactor, dot};
use crate::error::{QpError, Result};
use crate::problem::ParametricQp;

pub use super::fallback::ExactSolver;

/// Settings of [`ActiveSetSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActiveSetSettings {
    /// Relative KKT tolerance: multipliers ≥ −tol·scale and the natural residual
    /// ≤ tol·scale, scale = 1 + ‖q‖_∞ + ‖Hz‖_∞. In (0, 1).
    pub tol: f64,
    /// Largest number of subspace solves per call (≥ 1). `None`: 10·n + 50.
    pub max_iter: Option<usize>,
    /// Largest number of updates of the Cholesky factor of H_FF (one variable entering or
    /// leaving the free set) since its last fresh factorisation; the next change after that
    /// recomputes it from H. `Some(0)`: recompute at every change of the working set (no
    /// updates). `None`: n.
    pub max_updates: Option<usize>,
}

impl Default for ActiveSetSettings {
    fn default() -> Self {
        Self {
            tol: 1e-10,
            max_iter: None,
            max_updates: None,
        }
    }
}

/// Where a variable sits in the working set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Bound {
    Free,
    Lower,
    Upper,
    /// l_i = u_i: never leaves the working set, multiplier of either sign.
    Fixed,
}

/// Outcome of one [`ActiveSetSolver`] call.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct ActiveSetInfo {
    /// Subspace solves used (1 when the previous working set was optimal).
    pub iterations: usize,
    /// Fresh Cholesky factorisations of H_FF computed (0 when the cached factor was reused
    /// or updated).
    pub factorizations: usize,
    /// Updates of the factor (one variable entering or leaving the free set), at the start
    /// of the call and during it.
    pub updates: usize,
    /// Number of variables held at a bound at the solution.
    pub active: usize,
    /// Natural residual ‖z − Π_Z(z − (Hz + q))‖_∞ of the returned z.
    pub kkt_residual: f64,
}

/// Factorisation and update counts of one call.
#[derive(Debug, Clone, Copy, Default)]
struct Counts {
    factorizations: usize,
    updates: usize,
}

/// Primal active-set solver for min ½zᵀHz + (q₀ + Fθ)ᵀz over a box, set up once for a
/// [`ParametricQp`]; every call after [`ActiveSetSolver::new`] is allocation-free and
/// warm-starts from the previous call's solution and working set.
///
/// ```
/// use faer::{mat, Mat};
/// use qp_iter::BoxSet;
/// use qp_iter::ParametricQp;
/// use qp_iter::active_set::{ActiveSetSettings, ActiveSetSolver};
/// let qp = ParametricQp::new(mat![[4.0, 1.0], [1.0, 1.0]], vec![-2.0, -4.0],
///     Mat::identity(2, 2), BoxSet::symmetric(&[2.0, 2.0]).unwrap()).unwrap();
/// let mut s = ActiveSetSolver::new(&qp, ActiveSetSettings::default()).unwrap();
/// let info = s.solve(&[0.0, 0.0]).unwrap();
/// // z₁ is clipped at its upper bound 2 with multiplier 2, then 4z₀ + 2 − 2 = 0.
/// assert!(s.z()[0].abs() < 1e-15 && s.z()[1] == 2.0);
/// assert!((s.upper_multipliers()[1] - 2.0).abs() < 1e-14 && info.kkt_residual < 1e-14);
/// // A new θ (q = (−3, −3)): warm-started from the working set {z₁ = 2}, one subspace solve.
/// let info = s.solve(&[-1.0, 1.0]).unwrap();
/// assert!((s.z()[0] - 0.25).abs() < 1e-15 && info.iterations == 1);
/// ```
#[derive(Debug, Clone)]
pub struct ActiveSetSolver {
    qp: ParametricQp,
    settings: ActiveSetSettings,
    max_iter: usize,
    max_updates: usize,
    /// Linear term q of the current call.
    q: Vec<f64>,
    /// Current iterate (always feasible).
    z: Vec<f64>,
    /// Subspace minimiser.
    zhat: Vec<f64>,
    /// Hz + q (on W only during the iteration, everywhere at the solution).
    g: Vec<f64>,
    state: Vec<Bound>,
    /// Cholesky factor of H_FF, F in factor order.
    factor: FreeFactor,
    /// −(q_F + H_FW z_W) in factor order (first |F| entries), kept up to date with W.
    rhs: Vec<f64>,
    /// Solve workspace (factor order).
    work: Vec<f64>,
    /// z with the free entries zeroed (workspace for a fresh right-hand side).
    z_w: Vec<f64>,
    lam_l: Vec<f64>,
    lam_u: Vec<f64>,
}

impl ActiveSetSolver {
    /// Sets up the solver (allocates its workspace once). The first call starts from the
    /// projection of 0 onto Z.
    ///
    /// Errors: [`QpError::Parameter`] for `tol` ∉ (0, 1) or `max_iter = Some(0)`.
    pub fn new(qp: &ParametricQp, settings: ActiveSetSettings) -> Result<Self> {
        if !(settings.tol > 0.0 && settings.tol < 1.0) {
            return Err(QpError::Parameter {
                name: "tol".into(),
                value: settings.tol,
                reason: "the active-set KKT tolerance must lie in (0, 1), e.g. 1e-10".into(),
            });
        }
        if let Some(gc) = qp.general() {
            return Err(QpError::Parameter {
                name: "G".into(),
                value: gc.m() as f64,
                reason: "the primal active set solves box QPs only; use \
                         `dual_active_set::ParametricDualActiveSet` (or `ExactSolver`) for general rows"
                    .into(),
            });
        }
        let n = qp.n();
        let max_iter = match settings.max_iter {
            Some(0) => {
                return Err(QpError::Parameter {
                    name: "max_iter".into(),
                    value: 0.0,
                    reason: "at least one subspace solve is needed; use None for 10·n + 50".into(),
                });
            }
            Some(m) => m,
            None => 10 * n + 50,
        };
        let mut s = Self {
            qp: qp.clone(),
            settings,
            max_iter,
            max_updates: settings.max_updates.unwrap_or(n),
            q: qp.q0().to_vec(),
            z: vec![0.0; n],
            zhat: vec![0.0; n],
            g: vec![0.0; n],
            state: vec![Bound::Free; n],
            factor: FreeFactor::new(n),
            rhs: vec![0.0; n],
            work: vec![0.0; n],
            z_w: vec![0.0; n],
            lam_l: vec![0.0; n],
            lam_u: vec![0.0; n],
        };
        s.reset();
        Ok(s)
    }

    /// Forgets the working set and the cached factor: the next call starts from
    /// z = Π_Z(0) and computes the results a fresh solver would, bit for bit (the factor
    /// updates make the last bits of z* depend on the path since the last fresh
    /// factorisation, so a restarted Monte-Carlo run must not inherit them).
    pub fn reset(&mut self) {
        self.z.fill(0.0);
        self.qp.project(&mut self.z);
        self.set_state_from_z();
        self.factor.invalidate();
    }

    /// The next call starts from z = Π_Z(`z0`) with the working set {i : z_i at a bound}
    /// (e.g. a neighbouring problem's solution, shifted) instead of the previous call's.
    /// Only the start changes: the answer is the same unique minimiser.
    ///
    /// Errors: `z0` of the wrong length or not finite ([`QpError::Data`]); nothing changes.
    pub fn warm_start(&mut self, z0: &[f64]) -> Result<()> {
        crate::matrix::check_len("z0", z0, self.qp.n())?;
        crate::matrix::check_finite_slice("z0", z0)?;
        self.z.copy_from_slice(z0);
        self.qp.project(&mut self.z);
        self.set_state_from_z();
        Ok(())
    }

    fn set_state_from_z(&mut self) {
        let (lo, up) = (self.qp.zset().lower(), self.qp.zset().upper());
        for i in 0..self.z.len() {
            self.state[i] = if lo[i] == up[i] {
                Bound::Fixed
            } else if self.z[i] == lo[i] {
                Bound::Lower
            } else if self.z[i] == up[i] {
                Bound::Upper
            } else {
                Bound::Free
            };
        }
    }

    /// The problem this solver was set up for.
    pub fn problem(&self) -> &ParametricQp {
        &self.qp
    }

    /// Solves for parameters θ (q = q₀ + Fθ; length n_θ, finite).
    pub fn solve(&mut self, theta: &[f64]) -> Result<ActiveSetInfo> {
        self.qp.check_theta(theta)?;
        let mut q = std::mem::take(&mut self.q);
        self.qp.linear_term(theta, &mut q);
        self.q = q;
        self.solve_loaded()
    }

    /// Solves for a given linear term q (length n, finite).
    pub fn solve_q(&mut self, q: &[f64]) -> Result<ActiveSetInfo> {
        crate::matrix::check_len("q", q, self.qp.n())?;
        crate::matrix::check_finite_slice("q", q)?;
        self.q.copy_from_slice(q);
        self.solve_loaded()
    }

    /// The minimiser z* of the last successful call.
    pub fn z(&self) -> &[f64] {
        &self.z
    }

    /// Multipliers λ_l ≥ 0 of z ≥ l at the last solution (Hz + q = λ_l − λ_u).
    pub fn lower_multipliers(&self) -> &[f64] {
        &self.lam_l
    }

    /// Multipliers λ_u ≥ 0 of z ≤ u at the last solution.
    pub fn upper_multipliers(&self) -> &[f64] {
        &self.lam_u
    }

    /// Objective ½zᵀHz + qᵀz at the last solution.
    pub fn objective(&self) -> f64 {
        self.qp.objective(&self.q, &self.z)
    }

    fn solve_loaded(&mut self) -> Result<ActiveSetInfo> {
        let n = self.qp.n();
        let mut counts = Counts::default();
        let qmax = self.q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if let Err(e) = self.sync_factor(&mut counts) {
            return Err(self.breakdown(1, e));
        }
        // After a failed KKT check on an updated factor, one more try on a fresh one.
        let mut refreshed = false;
        for it in 1..=self.max_iter {
            self.subspace_minimiser();
            if self.zhat.iter().any(|v| !v.is_finite()) {
                self.factor.invalidate();
                return Err(QpError::NotConverged {
                    solver: "active set",
                    iterations: it,
                    reason: "the subspace minimiser is not finite (H_FF numerically singular)"
                        .into(),
                });
            }
            if let Some((i, alpha, bound)) = self.blocking() {
                for &j in self.factor.order() {
                    self.z[j] += alpha * (self.zhat[j] - self.z[j]);
                }
                let (lo, up) = (self.qp.zset().lower(), self.qp.zset().upper());
                self.z[i] = if bound == Bound::Lower { lo[i] } else { up[i] };
                self.state[i] = bound;
                // Keep z feasible against rounding in the step.
                self.qp.project(&mut self.z);
                if let Err(e) = self.leave_free(i, &mut counts) {
                    return Err(self.breakdown(it, e));
                }
                continue;
            }
            self.z.copy_from_slice(&self.zhat);
            self.qp.project(&mut self.z);
            // Cheap test first: the gradient on W only, and the scale with (Hz)_F ≈ −q_F
            // (g_F = 0 at the subspace minimiser up to rounding). It only decides the path.
            let scale = self.working_gradient_and_scale(qmax);
            if let Some(drop) = self.most_negative_multiplier(self.settings.tol * scale) {
                if let Err(e) = self.enter_free(drop, &mut counts) {
                    return Err(self.breakdown(it, e));
                }
                continue;
            }
            // The check of the answer: g and the scale from the data.
            let scale = self.gradient_and_scale();
            let tol = self.settings.tol * scale;
            if let Some(drop) = self.most_negative_multiplier(tol) {
                if let Err(e) = self.enter_free(drop, &mut counts) {
                    return Err(self.breakdown(it, e));
                }
                continue;
            }
            self.multipliers();
            let kkt_residual = self.natural_residual();
            if kkt_residual > tol {
                if !refreshed && self.factor.updates() > 0 {
                    refreshed = true;
                    if let Err(e) = self.refactor(&mut counts) {
                        return Err(self.breakdown(it, e));
                    }
                    continue;
                }
                self.factor.invalidate();
                return Err(QpError::NotConverged {
                    solver: "active set",
                    iterations: it,
                    reason: format!(
                        "KKT check failed: natural residual {kkt_residual:.3e} > {tol:.3e}"
                    ),
                });
            }
            let active = n - self.factor.len();
            return Ok(ActiveSetInfo {
                iterations: it,
                factorizations: counts.factorizations,
                updates: counts.updates,
                active,
                kkt_residual,
            });
        }
        // Leave a consistent state: the next call restarts from scratch.
        self.reset();
        self.factor.invalidate();
        Err(QpError::NotConverged {
            solver: "active set",
            iterations: self.max_iter,
            reason: "iteration limit reached (degenerate cycling?); raise max_iter or use the Clarabel reference".into(),
        })
    }

    /// The error for a fresh factorisation that failed (H_FF not numerically PD).
    fn breakdown(&mut self, it: usize, e: FactorBreakdown) -> QpError {
        self.factor.invalidate();
        QpError::NotConverged {
            solver: "active set",
            iterations: it,
            reason: format!(
                "H_FF is not numerically positive definite (pivot {:.3e} at variable {})",
                e.pivot, e.var
            ),
        }
    }

    /// Fresh factor of H_FF for the current free set (ascending) and a fresh right-hand side.
    fn refactor(&mut self, counts: &mut Counts) -> std::result::Result<(), FactorBreakdown> {
        let state = &self.state;
        let free = (0..state.len()).filter(|&i| state[i] == Bound::Free);
        self.factor.factorize(self.qp.h_row_major(), free)?;
        counts.factorizations += 1;
        self.fresh_rhs();
        Ok(())
    }

    /// Brings the cached factor to the current free set: by updates when few variables
    /// differ and the update budget allows, else by a fresh factorisation. Then a fresh
    /// right-hand side.
    fn sync_factor(&mut self, counts: &mut Counts) -> std::result::Result<(), FactorBreakdown> {
        if !self.factor.is_valid() {
            return self.refactor(counts);
        }
        let n = self.qp.n();
        let removals = self
            .factor
            .order()
            .iter()
            .filter(|&&i| self.state[i] != Bound::Free)
            .count();
        let nf_new = (0..n).filter(|&i| self.state[i] == Bound::Free).count();
        let additions = nf_new + removals - self.factor.len();
        let changes = removals + additions;
        // An update costs ≈ |F|² flops, a factorisation ≈ |F|³/3.
        if changes > 0
            && (3 * changes > nf_new.max(self.factor.len())
                || self.factor.updates() + changes > self.max_updates)
        {
            return self.refactor(counts);
        }
        let h = self.qp.h_row_major();
        let mut a = self.factor.len();
        while a > 0 {
            a -= 1;
            let i = self.factor.order()[a];
            if self.state[i] != Bound::Free {
                if self.factor.remove(i).is_err() {
                    return self.refactor(counts);
                }
                counts.updates += 1;
            }
        }
        for i in 0..n {
            if self.state[i] == Bound::Free && !self.factor.contains(i) {
                if self.factor.append(h, i).is_err() {
                    return self.refactor(counts);
                }
                counts.updates += 1;
            }
        }
        self.fresh_rhs();
        Ok(())
    }

    /// rhs_a = −(q_i + Σ_{j∈W} h_ij z_j) for i = order[a]: by columns of W when W is
    /// small (|W|·|F| flops), else by rows (|F|·n).
    fn fresh_rhs(&mut self) {
        let n = self.qp.n();
        let h = self.qp.h_row_major();
        let order = self.factor.order();
        let nf = order.len();
        if 4 * (n - nf) <= n {
            for (r, &i) in self.rhs[..nf].iter_mut().zip(order) {
                *r = -self.q[i];
            }
            for j in 0..n {
                let v = self.z[j];
                if self.state[j] == Bound::Free || v == 0.0 {
                    continue;
                }
                // h_ij = h_ji: row j of H.
                let h_j = &h[j * n..(j + 1) * n];
                for (r, &i) in self.rhs[..nf].iter_mut().zip(order) {
                    *r -= h_j[i] * v;
                }
            }
            return;
        }
        for j in 0..n {
            self.z_w[j] = if self.state[j] == Bound::Free {
                0.0
            } else {
                self.z[j]
            };
        }
        for (a, &i) in order.iter().enumerate() {
            self.rhs[a] = -(self.q[i] + dot(&h[i * n..(i + 1) * n], &self.z_w));
        }
    }

    /// Variable `i` (free in the factor) has just been put on a bound (state and z set):
    /// remove it from the factor and move its term to the right-hand side.
    fn leave_free(
        &mut self,
        i: usize,
        counts: &mut Counts,
    ) -> std::result::Result<(), FactorBreakdown> {
        if self.factor.updates() >= self.max_updates {
            return self.refactor(counts);
        }
        let p = match self.factor.remove(i) {
            Ok(p) => p,
            Err(_) => return self.refactor(counts),
        };
        counts.updates += 1;
        let nf = self.factor.len();
        self.rhs.copy_within(p + 1..nf + 1, p);
        let n = self.qp.n();
        let h_i = &self.qp.h_row_major()[i * n..(i + 1) * n];
        let v = self.z[i];
        for (r, &j) in self.rhs[..nf].iter_mut().zip(self.factor.order()) {
            *r -= h_i[j] * v;
        }
        Ok(())
    }

    /// Variable `i` (on a bound) leaves the working set: append it to the factor and take
    /// its term out of the right-hand side.
    fn enter_free(
        &mut self,
        i: usize,
        counts: &mut Counts,
    ) -> std::result::Result<(), FactorBreakdown> {
        self.state[i] = Bound::Free;
        if self.factor.updates() >= self.max_updates {
            return self.refactor(counts);
        }
        let n = self.qp.n();
        let h = self.qp.h_row_major();
        if self.factor.append(h, i).is_err() {
            return self.refactor(counts);
        }
        counts.updates += 1;
        let nf = self.factor.len() - 1;
        let h_i = &h[i * n..(i + 1) * n];
        let v = self.z[i];
        for (r, &j) in self.rhs[..nf].iter_mut().zip(self.factor.order()) {
            *r += h_i[j] * v;
        }
        let mut s = self.q[i];
        for j in 0..n {
            if self.state[j] != Bound::Free {
                s += h_i[j] * self.z[j];
            }
        }
        self.rhs[nf] = -s;
        Ok(())
    }

    /// ẑ_W = z_W, ẑ_F = H_FF⁻¹ rhs.
    fn subspace_minimiser(&mut self) {
        let nf = self.factor.len();
        let x = &mut self.work[..nf];
        x.copy_from_slice(&self.rhs[..nf]);
        self.factor.solve_in_place(x);
        self.zhat.copy_from_slice(&self.z);
        for (&i, &v) in self.factor.order().iter().zip(x.iter()) {
            self.zhat[i] = v;
        }
    }

    /// The first bound hit on the segment z → ẑ: (index, α, which bound), or `None` if ẑ
    /// is feasible. Ties go to the smallest index.
    fn blocking(&self) -> Option<(usize, f64, Bound)> {
        let (lo, up) = (self.qp.zset().lower(), self.qp.zset().upper());
        let mut best: Option<(usize, f64, Bound)> = None;
        for &i in self.factor.order() {
            let (zi, zh) = (self.z[i], self.zhat[i]);
            let (ratio, bound) = if zh < lo[i] {
                ((lo[i] - zi) / (zh - zi), Bound::Lower)
            } else if zh > up[i] {
                ((up[i] - zi) / (zh - zi), Bound::Upper)
            } else {
                continue;
            };
            let ratio = ratio.clamp(0.0, 1.0);
            if best.is_none_or(|(j, a, _)| ratio < a || (ratio == a && i < j)) {
                best = Some((i, ratio, bound));
            }
        }
        best
    }

    /// g_W = (Hz + q)_W; returns the scale estimate 1 + ‖q‖_∞ + max(‖(Hz)_W‖_∞, ‖q_F‖_∞).
    fn working_gradient_and_scale(&mut self, qmax: f64) -> f64 {
        let n = self.qp.n();
        let h = self.qp.h_row_major();
        let mut hzmax = 0.0f64;
        for i in 0..n {
            if self.state[i] == Bound::Free {
                hzmax = hzmax.max(self.q[i].abs());
            } else {
                let hz = dot(&h[i * n..(i + 1) * n], &self.z);
                self.g[i] = hz + self.q[i];
                hzmax = hzmax.max(hz.abs());
            }
        }
        1.0 + qmax + hzmax
    }

    /// g = Hz + q; returns the KKT scale 1 + ‖q‖_∞ + ‖Hz‖_∞.
    fn gradient_and_scale(&mut self) -> f64 {
        let n = self.qp.n();
        let h = self.qp.h_row_major();
        let (mut qmax, mut hzmax) = (0.0f64, 0.0f64);
        for i in 0..n {
            let hz = dot(&h[i * n..(i + 1) * n], &self.z);
            self.g[i] = hz + self.q[i];
            qmax = qmax.max(self.q[i].abs());
            hzmax = hzmax.max(hz.abs());
        }
        1.0 + qmax + hzmax
    }

    /// The working-set index whose multiplier is most negative (below −tol), if any.
    fn most_negative_multiplier(&self, tol: f64) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for (i, s) in self.state.iter().enumerate() {
            let lam = match s {
                Bound::Lower => self.g[i],
                Bound::Upper => -self.g[i],
                Bound::Free | Bound::Fixed => continue,
            };
            if lam < -tol && best.is_none_or(|(_, b)| lam < b) {
                best = Some((i, lam));
            }
        }
        best.map(|(i, _)| i)
    }

    fn multipliers(&mut self) {
        for (i, s) in self.state.iter().enumerate() {
            let g = self.g[i];
            let (l, u) = match s {
                Bound::Free => (0.0, 0.0),
                Bound::Lower => (g.max(0.0), 0.0),
                Bound::Upper => (0.0, (-g).max(0.0)),
                Bound::Fixed => (g.max(0.0), (-g).max(0.0)),
            };
            self.lam_l[i] = l;
            self.lam_u[i] = u;
        }
    }

    fn natural_residual(&self) -> f64 {
        let (lo, up) = (self.qp.zset().lower(), self.qp.zset().upper());
        let mut r = 0.0f64;
        for i in 0..self.z.len() {
            let t = (self.z[i] - self.g[i]).clamp(lo[i], up[i]);
            r = r.max((self.z[i] - t).abs());
        }
        r
    }
}
