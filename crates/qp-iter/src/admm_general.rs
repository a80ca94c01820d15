//! ADMM with the split on [I; G]z for min ½zᵀHz + qᵀz s.t. l ≤ z ≤ u, l_G ≤ Gz ≤ u_G
//! (OSQP's iteration, without its σ-regularisation, since H ≻ 0).
//!
//! With A = [I; G] (n + m rows), the split w = Az ∈ [l, u] × [l_G, u_G], the unscaled
//! multiplier y of Az − w = 0, penalty ρ and relaxation α, one step is
//!
//! x⁺ = (H + ρAᵀA)⁻¹(Aᵀ(ρw − y) − q),  ŵ = αAx⁺ + (1 − α)w,
//! w⁺ = Π(ŵ + y/ρ),  y⁺ = y + ρ(ŵ − w⁺),
//!
//! with (H + ρAᵀA)⁻¹ = (H + ρ(I + GᵀG))⁻¹ formed once at setup. The bounds of the G rows
//! move with θ (l₀ − Eθ, u₀ − Eθ) and are loaded by [`IterationMap::load`].
//!
//! **Returned iterate**: x ([`IterationMap::iterate`]). It satisfies the constraints only
//! in the limit; [`IterationMap::violation`] is its measured violation
//! max(l − Ax, Ax − u) for the loaded bounds (design trap 7), never hidden.
//!
//! **No certificate.** Giselsson–Boyd's linear rate for ADMM (the one [`crate::admm`] uses
//! for the box, where A = I) requires the split matrix A to be surjective (full row rank);
//! A = [I; G] has n + m > n rows and rank n, so it is not, and no a-priori linear rate
//! follows. The iterate is moreover infeasible before convergence, so Assumption 5 fails
//! twice. The certificate is reported **void** with that reason: rate 1, prefactor ∞,
//! `fits_eq11 = false`. For α ∈ (0, 2) the map converges (ADMM on a convex QP), which the
//! tests check against Goldfarb–Idnani; α = 2 (`"admm-pr"`) is Peaceman–Rachford, whose
//! convergence this splitting does not guarantee (it is slow on some random instances).
//!
//! ## Reference
//! B. Stellato et al., "OSQP: an operator splitting solver for quadratic programs",
//! Math. Prog. Comp. 12 (2020), Alg. 1; P. Giselsson, S. Boyd, IEEE TAC 62(2), 2017
//! (the surjectivity premise of the linear rate).

use faer::{Mat, Side};

use crate::IterationMap;
use crate::admm::AdmmParams;
use crate::certificate::{BoundedQuantity, CertNorm, Certificate};
use crate::error::Result;
use crate::problem::ParametricQp;

/// The reason the certificate of [`AdmmSplit`] is void (also its premise).
pub const VOID_REASON: &str = "ADMM split on [I; G]z: Giselsson–Boyd's linear rate needs the split \
     matrix [I; G] to be surjective, and with general rows it is not (n + m rows, rank n), so there \
     is no a-priori linear rate; the returned x is feasible only in the limit (violation measured, \
     design trap 7). Use PG or FISTA, whose projection onto Z ∩ {l ≤ Gz ≤ u} is exact";

/// ADMM on [I; G]z with a fixed penalty (see the module documentation).
#[derive(Debug, Clone)]
pub struct AdmmSplit {
    qp: ParametricQp,
    rho: f64,
    alpha: f64,
    /// (H + ρ(I + GᵀG))⁻¹ row-major.
    m_inv: Vec<f64>,
    cert: Certificate,
}

/// State of [`AdmmSplit`].
#[derive(Debug, Clone)]
pub struct AdmmSplitState {
    x: Vec<f64>,
    /// Split variable w (n + m).
    w: Vec<f64>,
    /// Multiplier y (n + m): Hx + q + Aᵀy = 0 at the optimum.
    y: Vec<f64>,
    q: Vec<f64>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// Workspace: ρw − y (n + m), then Ax (n + m); right-hand side (n).
    t: Vec<f64>,
    rhs: Vec<f64>,
}

impl AdmmSplit {
    /// Sets ADMM up for `qp` (with or without general rows): validates ρ and α and forms
    /// (H + ρ(I + GᵀG))⁻¹ once.
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use qp_iter::BoxSet;
    /// use qp_iter::{IterationMap, ParametricQp, run_fixed};
    /// use qp_iter::admm::AdmmParams;
    /// use qp_iter::admm_general::AdmmSplit;
    /// use qp_iter::problem::GeneralConstraints;
    /// // Project (2, 2) onto z₀ + z₁ ≤ 1: z* = (½, ½).
    /// let qp = ParametricQp::new(Mat::identity(2, 2), vec![-2.0, -2.0], Mat::zeros(2, 0),
    ///     BoxSet::whole(2)).unwrap()
    ///     .with_general(GeneralConstraints::new(mat![[1.0, 1.0]], Mat::zeros(1, 0),
    ///         vec![f64::NEG_INFINITY], vec![1.0]).unwrap()).unwrap();
    /// let admm = AdmmSplit::new(qp, AdmmParams::default()).unwrap();
    /// let mut s = admm.new_state();
    /// admm.load(&mut s, &[]);
    /// run_fixed(&admm, &mut s, 200);
    /// assert!((admm.iterate(&s)[0] - 0.5).abs() < 1e-9 && admm.violation(&s) < 1e-9);
    /// assert!(!admm.certificate().fits_eq11 && admm.certificate().rate >= 1.0);
    /// ```
    pub fn new(qp: ParametricQp, params: AdmmParams) -> Result<Self> {
        let (rho, alpha) = params.resolve(&qp)?;
        let n = qp.n();
        let h = qp.h();
        let mut k = Mat::from_fn(n, n, |i, j| h[(i, j)] + if i == j { rho } else { 0.0 });
        if let Some(gc) = qp.general() {
            let g = gc.g();
            for i in 0..n {
                for j in 0..n {
                    let mut acc = 0.0;
                    for r in 0..gc.m() {
                        acc += g[(r, i)] * g[(r, j)];
                    }
                    k[(i, j)] += rho * acc;
                }
            }
        }
        let llt = k
            .llt(Side::Lower)
            .map_err(|e| crate::DataError::Numerical {
                routine: "Cholesky factorisation of H + ρ(I + GᵀG) (ADMM setup)".into(),
                reason: format!("{e:?}; H must be positive definite and ρ positive"),
            })?;
        let inv = faer::linalg::solvers::Solve::solve(&llt, Mat::<f64>::identity(n, n));
        let m_inv: Vec<f64> = (0..n * n)
            .map(|p| {
                let (i, j) = (p / n, p % n);
                0.5 * (inv[(i, j)] + inv[(j, i)])
            })
            .collect();
        if m_inv.iter().any(|v| !v.is_finite()) {
            return Err(crate::DataError::Numerical {
                routine: "inverse of H + ρ(I + GᵀG) (ADMM setup)".into(),
                reason: "non-finite entries; scale H or G, or change ρ".into(),
            }
            .into());
        }
        let cert = Certificate {
            rate: 1.0,
            prefactor: f64::INFINITY,
            quantity: BoundedQuantity::IterateDistance,
            norm: CertNorm::Euclidean,
            fits_eq11: false,
            premise: format!("ρ = {rho:.6e}, α = {alpha}; void: {VOID_REASON}"),
            source: "none (Giselsson & Boyd, IEEE TAC 62(2) 2017, need a surjective split matrix)"
                .into(),
        };
        Ok(Self {
            qp,
            rho,
            alpha,
            m_inv,
            cert,
        })
    }

    /// The penalty ρ.
    pub fn rho(&self) -> f64 {
        self.rho
    }

    fn m(&self) -> usize {
        self.qp.general().map_or(0, |g| g.m())
    }

    /// (Ax)_r for row r of A = [I; G].
    #[inline]
    fn a_row(&self, r: usize, x: &[f64]) -> f64 {
        let n = self.qp.n();
        match self.qp.general() {
            Some(gc) if r >= n => gc.row_dot(r - n, x),
            _ => x[r],
        }
    }

    /// The split variable w (n + m).
    pub fn split<'s>(&self, s: &'s AdmmSplitState) -> &'s [f64] {
        &s.w
    }

    /// The whole iteration state (x, w, y) into `out` (length n + 2(n + m)), e.g. for a
    /// linearisation.
    pub fn state_vector(&self, s: &AdmmSplitState, out: &mut [f64]) {
        let (n, nr) = (self.qp.n(), self.qp.n() + self.m());
        out[..n].copy_from_slice(&s.x);
        out[n..n + nr].copy_from_slice(&s.w);
        out[n + nr..n + 2 * nr].copy_from_slice(&s.y);
    }

    /// Sets (x, w, y) from a vector of length n + 2(n + m) (the inverse of
    /// [`AdmmSplit::state_vector`]).
    pub fn set_state_vector(&self, s: &mut AdmmSplitState, v: &[f64]) {
        let (n, nr) = (self.qp.n(), self.qp.n() + self.m());
        s.x.copy_from_slice(&v[..n]);
        s.w.copy_from_slice(&v[n..n + nr]);
        s.y.copy_from_slice(&v[n + nr..n + 2 * nr]);
    }
}

impl IterationMap for AdmmSplit {
    type State = AdmmSplitState;

    fn name(&self) -> &'static str {
        "admm"
    }
    fn problem(&self) -> &ParametricQp {
        &self.qp
    }
    fn new_state(&self) -> AdmmSplitState {
        let (n, m) = (self.qp.n(), self.m());
        let mut s = AdmmSplitState {
            x: vec![0.0; n],
            w: vec![0.0; n + m],
            y: vec![0.0; n + m],
            q: self.qp.q0().to_vec(),
            lo: vec![0.0; n + m],
            hi: vec![0.0; n + m],
            t: vec![0.0; n + m],
            rhs: vec![0.0; n],
        };
        s.lo[..n].copy_from_slice(self.qp.zset().lower());
        s.hi[..n].copy_from_slice(self.qp.zset().upper());
        if let Some(gc) = self.qp.general() {
            s.lo[n..].copy_from_slice(gc.lower());
            s.hi[n..].copy_from_slice(gc.upper());
        }
        self.cold_start(&mut s);
        s
    }
    fn load(&self, s: &mut AdmmSplitState, theta: &[f64]) {
        self.qp.linear_term(theta, &mut s.q);
        if let Some(gc) = self.qp.general() {
            let n = self.qp.n();
            let (lo, hi) = (&mut s.lo[n..], &mut s.hi[n..]);
            gc.bounds(theta, lo, hi);
        }
    }
    /// x = z⁰, w = Π(Az⁰), y the given dual (length n + m, or n: the G part zero) or
    /// the gradient dual y_box = −(Hz⁰ + q), y_G = 0 (stationary for x = z⁰).
    fn warm_start(&self, s: &mut AdmmSplitState, z0: &[f64], dual: Option<&[f64]>) {
        let n = self.qp.n();
        s.x.copy_from_slice(z0);
        for r in 0..s.w.len() {
            s.w[r] = self.a_row(r, z0).clamp(s.lo[r], s.hi[r]);
        }
        s.y.fill(0.0);
        match dual {
            Some(y) => {
                let k = y.len().min(s.y.len());
                s.y[..k].copy_from_slice(&y[..k]);
            }
            None => {
                let h = self.qp.h_row_major();
                for i in 0..n {
                    let hz: f64 = h[i * n..(i + 1) * n]
                        .iter()
                        .zip(z0)
                        .map(|(a, b)| a * b)
                        .sum();
                    s.y[i] = -(hz + s.q[i]);
                }
            }
        }
    }
    fn cold_start(&self, s: &mut AdmmSplitState) {
        let mut z = std::mem::take(&mut s.rhs);
        z.fill(0.0);
        self.qp.project(&mut z);
        self.warm_start(s, &z, None);
        s.rhs = z;
    }
    fn step(&self, s: &mut AdmmSplitState) {
        let (n, nr) = (self.qp.n(), s.w.len());
        for r in 0..nr {
            s.t[r] = self.rho * s.w[r] - s.y[r];
        }
        // rhs = t_box + Gᵀt_G − q.
        for i in 0..n {
            s.rhs[i] = s.t[i] - s.q[i];
        }
        if let Some(gc) = self.qp.general() {
            let g = gc.g_row_major();
            for k in 0..gc.m() {
                let tk = s.t[n + k];
                for (ri, a) in s.rhs.iter_mut().zip(&g[k * n..(k + 1) * n]) {
                    *ri += a * tk;
                }
            }
        }
        for i in 0..n {
            s.x[i] = self.m_inv[i * n..(i + 1) * n]
                .iter()
                .zip(&s.rhs)
                .map(|(a, b)| a * b)
                .sum();
        }
        let (a, ir) = (self.alpha, 1.0 / self.rho);
        for r in 0..nr {
            let ax = self.a_row(r, &s.x);
            let what = a * ax + (1.0 - a) * s.w[r];
            let v = what + ir * s.y[r];
            // NaN-preserving clamp, as the other maps.
            let wn = if v < s.lo[r] {
                s.lo[r]
            } else if v > s.hi[r] {
                s.hi[r]
            } else {
                v
            };
            s.y[r] += self.rho * (what - wn);
            s.w[r] = wn;
        }
    }
    fn iterate<'s>(&self, s: &'s AdmmSplitState) -> &'s [f64] {
        &s.x
    }
    fn dual<'s>(&self, s: &'s AdmmSplitState) -> Option<&'s [f64]> {
        Some(&s.y)
    }
    /// max over the rows of A = [I; G] of max(lo − Ax, Ax − hi) with the loaded bounds.
    fn violation(&self, s: &AdmmSplitState) -> f64 {
        let mut v = 0.0f64;
        for r in 0..s.w.len() {
            let ax = self.a_row(r, &s.x);
            if ax.is_nan() {
                return f64::NAN;
            }
            v = v.max(s.lo[r] - ax).max(ax - s.hi[r]);
        }
        v
    }
    fn certificate(&self) -> &Certificate {
        &self.cert
    }
}

/// ξ = (x, w, y), n + 2(n + m) entries, set and read through
/// [`AdmmSplit::set_state_vector`] / [`AdmmSplit::state_vector`]; the step does not read x
/// (zero columns), the iterate is x.
impl crate::linearise::Linearise for AdmmSplit {
    fn lift_dim(&self) -> usize {
        let n = self.problem().n();
        n + 2 * (n + self.problem().general().map_or(0, |g| g.m()))
    }
    fn start_probe(&self, st: &mut AdmmSplitState, z0: &[f64], theta: &[f64], xi: &mut [f64]) {
        self.load(st, theta);
        self.warm_start(st, z0, None);
        self.state_vector(st, xi);
    }
    fn step_probe(&self, st: &mut AdmmSplitState, xi: &[f64], theta: &[f64], out: &mut [f64]) {
        self.load(st, theta);
        self.set_state_vector(st, xi);
        self.step(st);
        self.state_vector(st, out);
    }
    fn readout(&self) -> faer::Mat<f64> {
        crate::linearise::leading_identity(self.problem().n(), self.lift_dim())
    }
}
