//! An exact, allocation-free solver for small strictly convex box QPs: the primal
//! active-set method (Nocedal–Wright, *Numerical Optimization*, 2nd ed., Alg. 16.3)
//! specialised to bounds, warm-started from the previous working set.
//!
//! minimise ½zᵀHz + qᵀz subject to l ≤ z ≤ u, H ≻ 0.
//!
//! Why it exists: the exact MPC law π(x̂) = u*₀(x̂) is evaluated once per closed-loop step.
//! Clarabel (an interior-point method) needs ≈ 150 µs for the case study's 20-variable QP;
//! consecutive MPC problems share H and the box and differ only in q, so their optimal active
//! sets rarely change, and a working-set method started from the last one usually finishes
//! with one subspace solve on a cached Cholesky factor (a few hundred nanoseconds).
//!
//! Each iteration, for the working set W (variables held at a bound) and the free set F:
//!
//! 1. the subspace minimiser ẑ: ẑ_W = z_W, H_FF ẑ_F = −(q_F + H_FW z_W) (Cholesky of H_FF,
//!    cached while W does not change);
//! 2. if ẑ violates a bound, step z ← z + α(ẑ − z) with the largest feasible α ∈ [0, 1) and
//!    add the first blocking bound to W;
//! 3. otherwise z ← ẑ and the multipliers λ_i = ±(Hz + q)_i of W are checked; if all are
//!    ≥ −tol, z is optimal, else the most negative one leaves W.
//!
//! Every accepted solution passes an explicit KKT check (natural residual
//! ‖z − Π_Z(z − (Hz + q))‖_∞ ≤ tol·scale) before it is returned; a run that does not finish
//! in `max_iter` subspace solves (cycling under degeneracy is possible in theory) is a typed
//! [`QpError::NotConverged`], so a caller can fall back to [`crate::reference`].

use crate::error::{QpError, Result};
use crate::problem::ParametricQp;
use crate::reference::{ReferenceSettings, ReferenceSolver};

/// Settings of [`ActiveSetSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActiveSetSettings {
    /// Relative KKT tolerance: multipliers ≥ −tol·scale and the natural residual
    /// ≤ tol·scale, scale = 1 + ‖q‖_∞ + ‖Hz‖_∞. In (0, 1).
    pub tol: f64,
    /// Largest number of subspace solves per call (≥ 1). `None`: 10·n + 50.
    pub max_iter: Option<usize>,
}

impl Default for ActiveSetSettings {
    fn default() -> Self {
        Self {
            tol: 1e-10,
            max_iter: None,
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
pub struct ActiveSetInfo {
    /// Subspace solves used (1 when the previous working set was optimal).
    pub iterations: usize,
    /// Cholesky factorisations of H_FF computed (0 when the cached factor was reused).
    pub factorizations: usize,
    /// Number of variables held at a bound at the solution.
    pub active: usize,
    /// Natural residual ‖z − Π_Z(z − (Hz + q))‖_∞ of the returned z.
    pub kkt_residual: f64,
}

/// Primal active-set solver for min ½zᵀHz + (q₀ + Fθ)ᵀz over a box, set up once for a
/// [`ParametricQp`]; every call after [`ActiveSetSolver::new`] is allocation-free and
/// warm-starts from the previous call's solution and working set.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::BoxSet;
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
    /// Linear term q of the current call.
    q: Vec<f64>,
    /// Current iterate (always feasible).
    z: Vec<f64>,
    /// Subspace minimiser.
    zhat: Vec<f64>,
    /// Hz + q at the solution.
    g: Vec<f64>,
    state: Vec<Bound>,
    /// Indices of the free set F, ascending.
    free: Vec<usize>,
    /// The free set the cached factor belongs to (`None`: no valid factor).
    factor_free: Vec<usize>,
    factor_valid: bool,
    /// Row-major lower Cholesky factor of H_FF (stride |F|).
    chol: Vec<f64>,
    rhs: Vec<f64>,
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
            q: qp.q0().to_vec(),
            z: vec![0.0; n],
            zhat: vec![0.0; n],
            g: vec![0.0; n],
            state: vec![Bound::Free; n],
            free: Vec::with_capacity(n),
            factor_free: Vec::with_capacity(n),
            factor_valid: false,
            chol: vec![0.0; n * n],
            rhs: vec![0.0; n],
            lam_l: vec![0.0; n],
            lam_u: vec![0.0; n],
        };
        s.reset();
        Ok(s)
    }

    /// Forgets the working set: the next call starts from z = Π_Z(0).
    pub fn reset(&mut self) {
        self.z.fill(0.0);
        self.qp.project(&mut self.z);
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
        self.factor_valid = false;
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
        lti_model::matrix::check_len("q", q, self.qp.n())?;
        lti_model::matrix::check_finite_slice("q", q)?;
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
        let mut factorizations = 0;
        for it in 1..=self.max_iter {
            self.collect_free();
            if !(self.factor_valid && self.factor_free == self.free) {
                if let Err((pivot, var)) = self.factorize() {
                    return Err(QpError::NotConverged {
                        solver: "active set",
                        iterations: it,
                        reason: format!(
                            "H_FF is not numerically positive definite (pivot {pivot:.3e} at variable {var})"
                        ),
                    });
                }
                factorizations += 1;
            }
            self.subspace_minimiser();
            if self.zhat.iter().any(|v| !v.is_finite()) {
                self.factor_valid = false;
                return Err(QpError::NotConverged {
                    solver: "active set",
                    iterations: it,
                    reason: "the subspace minimiser is not finite (H_FF numerically singular)"
                        .into(),
                });
            }
            if let Some((i, alpha, bound)) = self.blocking() {
                for j in 0..n {
                    if self.state[j] == Bound::Free {
                        self.z[j] += alpha * (self.zhat[j] - self.z[j]);
                    }
                }
                let (lo, up) = (self.qp.zset().lower(), self.qp.zset().upper());
                self.z[i] = if bound == Bound::Lower { lo[i] } else { up[i] };
                self.state[i] = bound;
                // Keep z feasible against rounding in the step.
                self.qp.project(&mut self.z);
                continue;
            }
            self.z.copy_from_slice(&self.zhat);
            self.qp.project(&mut self.z);
            let scale = self.gradient_and_scale();
            let tol = self.settings.tol * scale;
            if let Some(drop) = self.most_negative_multiplier(tol) {
                self.state[drop] = Bound::Free;
                continue;
            }
            self.multipliers();
            let kkt_residual = self.natural_residual();
            if kkt_residual > tol {
                self.factor_valid = false;
                return Err(QpError::NotConverged {
                    solver: "active set",
                    iterations: it,
                    reason: format!(
                        "KKT check failed: natural residual {kkt_residual:.3e} > {tol:.3e}"
                    ),
                });
            }
            let active = self.state.iter().filter(|s| **s != Bound::Free).count();
            return Ok(ActiveSetInfo {
                iterations: it,
                factorizations,
                active,
                kkt_residual,
            });
        }
        // Leave a consistent state: the next call restarts from scratch.
        self.reset();
        Err(QpError::NotConverged {
            solver: "active set",
            iterations: self.max_iter,
            reason: "iteration limit reached (degenerate cycling?); raise max_iter or use the Clarabel reference".into(),
        })
    }

    fn collect_free(&mut self) {
        self.free.clear();
        for (i, s) in self.state.iter().enumerate() {
            if *s == Bound::Free {
                self.free.push(i);
            }
        }
    }

    /// Cholesky H_FF = LLᵀ into `chol` (row-major, stride |F|); on failure, the pivot and
    /// the variable it belongs to.
    fn factorize(&mut self) -> std::result::Result<(), (f64, usize)> {
        let n = self.qp.n();
        let h = self.qp.h_row_major();
        let nf = self.free.len();
        self.factor_valid = false;
        let l = &mut self.chol[..nf * nf];
        for a in 0..nf {
            let ia = self.free[a];
            for b in 0..=a {
                l[a * nf + b] = h[ia * n + self.free[b]];
            }
        }
        for j in 0..nf {
            let row_j = &l[j * nf..j * nf + j];
            let d = l[j * nf + j] - dot(row_j, row_j);
            if !(d > 0.0 && d.is_finite()) {
                return Err((d, self.free[j]));
            }
            let d = d.sqrt();
            l[j * nf + j] = d;
            for i in j + 1..nf {
                let (top, bottom) = l.split_at_mut(i * nf);
                let row_j = &top[j * nf..j * nf + j];
                let row_i = &mut bottom[..nf];
                row_i[j] = (row_i[j] - dot(&row_i[..j], row_j)) / d;
            }
        }
        self.factor_free.clear();
        self.factor_free.extend_from_slice(&self.free);
        self.factor_valid = true;
        Ok(())
    }

    /// ẑ_W = z_W, ẑ_F = −H_FF⁻¹(q_F + H_FW z_W).
    fn subspace_minimiser(&mut self) {
        let n = self.qp.n();
        let h = self.qp.h_row_major();
        let nf = self.free.len();
        for (a, &i) in self.free.iter().enumerate() {
            let row = &h[i * n..(i + 1) * n];
            let mut s = self.q[i];
            for (j, st) in self.state.iter().enumerate() {
                if *st != Bound::Free {
                    s += row[j] * self.z[j];
                }
            }
            self.rhs[a] = -s;
        }
        let l = &self.chol[..nf * nf];
        let y = &mut self.rhs[..nf];
        // L y = b.
        for a in 0..nf {
            y[a] = (y[a] - dot(&l[a * nf..a * nf + a], &y[..a])) / l[a * nf + a];
        }
        // Lᵀ x = y.
        for a in (0..nf).rev() {
            let mut s = y[a];
            for b in a + 1..nf {
                s -= l[b * nf + a] * y[b];
            }
            y[a] = s / l[a * nf + a];
        }
        self.zhat.copy_from_slice(&self.z);
        for (a, &i) in self.free.iter().enumerate() {
            self.zhat[i] = y[a];
        }
    }

    /// The first bound hit on the segment z → ẑ: (index, α, which bound), or `None` if ẑ
    /// is feasible. Ties go to the smallest index.
    fn blocking(&self) -> Option<(usize, f64, Bound)> {
        let (lo, up) = (self.qp.zset().lower(), self.qp.zset().upper());
        let mut best: Option<(usize, f64, Bound)> = None;
        for &i in &self.free {
            let (zi, zh) = (self.z[i], self.zhat[i]);
            let (ratio, bound) = if zh < lo[i] {
                ((lo[i] - zi) / (zh - zi), Bound::Lower)
            } else if zh > up[i] {
                ((up[i] - zi) / (zh - zi), Bound::Upper)
            } else {
                continue;
            };
            let ratio = ratio.clamp(0.0, 1.0);
            if best.is_none_or(|(_, a, _)| ratio < a) {
                best = Some((i, ratio, bound));
            }
        }
        best
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

#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let chunks = a.len() / 4;
    for c in 0..chunks {
        for k in 0..4 {
            acc[k] += a[4 * c + k] * b[4 * c + k];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for k in 4 * chunks..a.len() {
        s += a[k] * b[k];
    }
    s
}

/// An exact solve that cannot stop without an answer: [`ActiveSetSolver`] first, Clarabel
/// ([`ReferenceSolver`], default settings, built on first use) when the active-set method
/// stops without a verified optimum. What `mpc-core`'s exact MPC and `mhe-core`'s ε_t use.
///
/// Allocation-free while the active set succeeds (every case-study test run); a fallback
/// allocates (Clarabel) and is counted by [`ExactSolver::fallbacks`].
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::BoxSet;
/// use qp_iter::ParametricQp;
/// use qp_iter::active_set::ExactSolver;
/// let qp = ParametricQp::new(mat![[4.0, 1.0], [1.0, 1.0]], vec![-2.0, -4.0],
///     Mat::identity(2, 2), BoxSet::symmetric(&[2.0, 2.0]).unwrap()).unwrap();
/// let mut s = ExactSolver::new(&qp).unwrap();
/// let z = s.solve(&[-1.0, 1.0]).unwrap();
/// assert!((z[0] - 0.25).abs() < 1e-15 && z[1] == 2.0);
/// assert_eq!(s.fallbacks(), 0);
/// ```
#[derive(Debug)]
pub struct ExactSolver {
    active: ActiveSetSolver,
    fallback: Option<Box<ReferenceSolver>>,
    fallbacks: usize,
    /// The last solution (the active set's, or Clarabel's after a fallback).
    z: Vec<f64>,
    last_info: Option<ActiveSetInfo>,
}

impl ExactSolver {
    /// Active set with [`ActiveSetSettings::default`].
    pub fn new(qp: &ParametricQp) -> Result<Self> {
        Self::with_settings(qp, ActiveSetSettings::default())
    }

    /// Active set with the given settings.
    pub fn with_settings(qp: &ParametricQp, settings: ActiveSetSettings) -> Result<Self> {
        Ok(Self {
            active: ActiveSetSolver::new(qp, settings)?,
            fallback: None,
            fallbacks: 0,
            z: vec![0.0; qp.n()],
            last_info: None,
        })
    }

    /// z*(θ). Errors: θ of the wrong length or not finite ([`QpError::Model`]); Clarabel
    /// failing after an active-set failure ([`QpError::Reference`]).
    pub fn solve(&mut self, theta: &[f64]) -> Result<&[f64]> {
        self.last_info = None;
        match self.active.solve(theta) {
            Ok(info) => {
                self.z.copy_from_slice(self.active.z());
                self.last_info = Some(info);
            }
            Err(QpError::NotConverged { .. }) => {
                self.fallbacks += 1;
                self.active.reset();
                let reference = match &mut self.fallback {
                    Some(r) => r,
                    slot => slot.insert(Box::new(ReferenceSolver::new(
                        self.active.problem(),
                        ReferenceSettings::default(),
                    )?)),
                };
                let sol = reference.solve(theta)?;
                self.z.copy_from_slice(&sol.z);
            }
            Err(e) => return Err(e),
        }
        Ok(&self.z)
    }

    /// Forgets the warm start: the next call starts as a fresh solver's does.
    pub fn reset(&mut self) {
        self.active.reset();
        self.last_info = None;
    }

    /// The last solution.
    pub fn z(&self) -> &[f64] {
        &self.z
    }

    /// Calls the active set could not finish (solved by Clarabel instead).
    pub fn fallbacks(&self) -> usize {
        self.fallbacks
    }

    /// Iterations of the last call (`None` after a fallback).
    pub fn last_info(&self) -> Option<ActiveSetInfo> {
        self.last_info
    }

    /// The problem.
    pub fn problem(&self) -> &ParametricQp {
        self.active.problem()
    }
}
