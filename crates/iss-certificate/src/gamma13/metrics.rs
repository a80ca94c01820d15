//! Candidate metrics S ≻ 0 for the contraction certificate, and the robust Riccati metric
//! (docs/theory.md, "The certificate on any plant", steps 4–5).
//!
//! The certificate is sound for **any** S ≻ 0 (each candidate is evaluated by the
//! S-procedure); the candidates only decide how tight it is:
//!
//! - `identity`; `dare-terminal` (P_f, the LQR value function); `open-loop-lyapunov`
//!   (AᵀSA − S + I = 0, A Schur); `closed-loop-lyapunov`, `saturated-lyapunov`,
//!   `midpoint-lyapunov` (the same for A + BK_lin, A + BK_sat, A + BK_mid);
//! - `dare-R×ρ`: the DARE of (A, B, Q_c, ρR_c), ρ ∈ {10⁻², 10⁻¹, 10, 10², 10³}, which moves
//!   from the LQR metric (ρ = 1) towards the open-loop one (ρ → ∞);
//! - `robust-riccati(λ)`: the minimal solution of the bounded-real Riccati equation
//!   S = ÃᵀSÃ + ÃᵀSU(I − UᵀSU)⁻¹UᵀSÃ + ṼᵀṼ + εI, Ã = A_mid/λ, Ṽ = V/λ, the metric in which
//!   the whole family A_mid + UΔV, ‖Δ‖ ≤ 1, contracts with factor λ (τ = 1 in the
//!   S-procedure). λ is bisected down to the smallest value at which the fixed-point
//!   iteration converges, then a few values between it and 1 are offered.

use faer::{Mat, MatRef, Side};
use lti_model::system::spectral_radius;
use mpc_core::CondensedMpc;

/// One metric S with S^{±½} and its extreme eigenvalues.
#[derive(Debug, Clone)]
pub(crate) struct Metric {
    pub name: String,
    pub half: Mat<f64>,
    pub neg_half: Mat<f64>,
    pub lmin: f64,
    pub lmax: f64,
}

/// S^{±½} from an eigen-decomposition; None unless S is finite and positive definite.
pub(crate) fn metric(name: impl Into<String>, s: MatRef<'_, f64>) -> Option<Metric> {
    let evd = lti_model::matrix::symmetrize(s)
        .self_adjoint_eigen(Side::Lower)
        .ok()?;
    let (u, d) = (evd.U(), evd.S().column_vector());
    let n = s.nrows();
    let lmin = (0..n).map(|i| d[i]).fold(f64::INFINITY, f64::min);
    let lmax = (0..n).map(|i| d[i]).fold(0.0, f64::max);
    // Reject numerically singular metrics: S^{−½} would amplify round-off beyond use.
    if !(lmin > 1e-13 * lmax) || !lmax.is_finite() {
        return None;
    }
    // d_k^p once per k (the products below are unchanged, bit for bit).
    let build = |p: f64| {
        let dp: Vec<f64> = (0..n).map(|k| d[k].powf(p)).collect();
        Mat::from_fn(n, n, |i, j| {
            (0..n).map(|k| u[(i, k)] * dp[k] * u[(j, k)]).sum()
        })
    };
    Some(Metric {
        name: name.into(),
        half: build(0.5),
        neg_half: build(-0.5),
        lmin,
        lmax,
    })
}

/// The closed-loop family A + BK(M), 0 ⪯ M ⪯ I, in norm-bounded form A_mid + UΔV.
#[derive(Debug, Clone)]
pub(crate) struct Family {
    /// A + BK_mid.
    pub a_mid: Mat<f64>,
    /// BK_mid.
    pub bk_mid: Mat<f64>,
    /// U = B·L̂ (n_x × n_u), L̂L̂ᵀ = ¼GGᵀ.
    pub u: Mat<f64>,
    /// V = R̂ (n_x × n_x), R̂ᵀR̂ = RᵀR.
    pub v: Mat<f64>,
    /// A + BK_lin (M = 0, the unconstrained law).
    pub a_lin: Mat<f64>,
    /// BK_lin.
    pub bk_lin: Mat<f64>,
    /// A + BK_sat (M = I, every saturable variable saturated).
    pub a_sat: Mat<f64>,
    /// s.
    pub saturable: usize,
}

impl Family {
    /// The family of `gains` on the plant of `mpc`.
    pub(crate) fn from_gains(
        mpc: &CondensedMpc,
        gains: &mpc_core::LocalGains,
    ) -> mpc_core::Result<Self> {
        let (l_hat, r_hat) = gains.spread()?;
        let (a, b) = (mpc.system().a(), mpc.system().b());
        let bk_mid = b * gains.k_mid();
        let bk_lin = b * &gains.k_lin;
        Ok(Self {
            a_mid: a + &bk_mid,
            a_lin: a + &bk_lin,
            a_sat: a + b * gains.k_sat(),
            u: b * &l_hat,
            v: r_hat,
            bk_mid,
            bk_lin,
            saturable: gains.s(),
        })
    }

    /// The single family of every local gain ([`CondensedMpc::local_gains`]).
    pub(crate) fn new(mpc: &CondensedMpc) -> mpc_core::Result<Self> {
        Self::from_gains(mpc, &mpc.local_gains()?)
    }
}

/// Largest number of fixed-point iterations per robust Riccati solve.
const RICCATI_MAX_ITER: usize = 4000;

/// Minimal solution of S = ÃᵀSÃ + ÃᵀSU(I − UᵀSU)⁻¹UᵀSÃ + ṼᵀṼ + εI (module docs) by the
/// monotone fixed-point iteration from S₀ = ṼᵀṼ + εI; None if I − UᵀSU loses definiteness,
/// the iterates blow up, or they do not converge within [`RICCATI_MAX_ITER`].
pub(crate) fn robust_riccati(fam: &Family, lambda: f64, eps: f64) -> Option<Mat<f64>> {
    let n = fam.a_mid.nrows();
    let r = fam.u.ncols();
    let at = &fam.a_mid * (1.0 / lambda);
    let q =
        fam.v.transpose() * &fam.v * (1.0 / (lambda * lambda)) + Mat::<f64>::identity(n, n) * eps;
    let q_scale = q.norm_max();
    let mut s = q.clone();
    for _ in 0..RICCATI_MAX_ITER {
        let sa = &s * &at;
        let mut next = at.transpose() * &sa + &q;
        if r > 0 {
            let su = &s * &fam.u;
            let m = Mat::<f64>::identity(r, r) - fam.u.transpose() * &su;
            let llt = lti_model::matrix::symmetrize(m.as_ref())
                .llt(Side::Lower)
                .ok()?;
            let utsa = su.transpose() * &at; // UᵀSÃ
            let x = faer::linalg::solvers::Solve::solve(&llt, &utsa);
            next += utsa.transpose() * &x;
        }
        let next = lti_model::matrix::symmetrize(next.as_ref());
        let scale = next.norm_max();
        if !scale.is_finite() || scale > 1e12 * q_scale {
            return None;
        }
        let diff = (&next - &s).norm_max();
        s = next;
        if diff <= 1e-12 * scale {
            return Some(s);
        }
    }
    None
}

/// Every candidate metric (module docs). Infeasible candidates (a non-Schur matrix, a
/// singular DARE solution, a divergent Riccati iteration) are left out.
pub(crate) fn candidates(mpc: &CondensedMpc, fam: &Family) -> Vec<Metric> {
    let sys = mpc.system();
    let nx = mpc.nx();
    let eye = Mat::<f64>::identity(nx, nx);
    let mut out: Vec<Metric> = Vec::new();
    out.extend(metric("identity", eye.as_ref()));
    out.extend(metric("dare-terminal", mpc.terminal_weight().as_ref()));
    let lyap = |name: &str, a: MatRef<'_, f64>, out: &mut Vec<Metric>| {
        if let Ok(s) = lti_model::riccati::dlyap(a, eye.as_ref()) {
            out.extend(metric(name, s.as_ref()));
        }
    };
    lyap("open-loop-lyapunov", sys.a(), &mut out);
    lyap("closed-loop-lyapunov", fam.a_lin.as_ref(), &mut out);
    if fam.saturable > 0 {
        if (&fam.a_sat - sys.a()).norm_max() > 1e-12 * sys.a().norm_max().max(1.0) {
            lyap("saturated-lyapunov", fam.a_sat.as_ref(), &mut out);
        }
        lyap("midpoint-lyapunov", fam.a_mid.as_ref(), &mut out);
    }
    for rho in [1e-2, 1e-1, 1e1, 1e2, 1e3] {
        let r = mpc.r_c() * rho;
        if let Ok(s) = lti_model::riccati::dare(sys.a(), sys.b(), mpc.q_c().as_ref(), r.as_ref()) {
            out.extend(metric(format!("dare-R×{rho}"), s.as_ref()));
        }
    }
    out.extend(robust_riccati_candidates(fam));
    out
}

/// Robust Riccati metrics: bisect the smallest λ at which [`robust_riccati`] converges,
/// then offer λ* + (1 − λ*)·{0.02, 0.1, 0.3, 0.6}.
fn robust_riccati_candidates(fam: &Family) -> Vec<Metric> {
    let rho = |m: &Mat<f64>| spectral_radius(m.as_ref()).unwrap_or(f64::INFINITY);
    // Necessary for any metric: every member contracts, in particular the three below.
    let lo = rho(&fam.a_mid).max(rho(&fam.a_lin)).max(rho(&fam.a_sat));
    if !(lo < 1.0) {
        return Vec::new();
    }
    let vtv = fam.v.transpose() * &fam.v;
    let v_scale = vtv.norm_max();
    let eps_for = |lambda: f64| {
        if v_scale > 0.0 {
            1e-4 * v_scale / (lambda * lambda)
        } else {
            1.0
        }
    };
    let feasible = |lambda: f64| robust_riccati(fam, lambda, eps_for(lambda)).is_some();
    let top = 1.0 - 1e-9;
    if !feasible(top) {
        return Vec::new();
    }
    let (mut a, mut b) = (lo, top);
    for _ in 0..24 {
        let mid = 0.5 * (a + b);
        if feasible(mid) {
            b = mid;
        } else {
            a = mid;
        }
        if b - a <= 1e-4 * (1.0 - b) {
            break;
        }
    }
    let star = b;
    let mut out = Vec::new();
    for f in [0.02, 0.1, 0.3, 0.6] {
        let lambda = star + (1.0 - star) * f;
        if let Some(s) = robust_riccati(fam, lambda, eps_for(lambda)) {
            out.extend(metric(format!("robust-riccati(λ={lambda:.4})"), s.as_ref()));
        }
    }
    out
}
