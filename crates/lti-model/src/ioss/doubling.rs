//! The maximal solution of LMI (2) for η > 0 at any scale: balancing and weight
//! normalisation (congruences that leave μ(P) invariant), the structure-preserving doubling
//! algorithm on the filter form of the Riccati equation, and a margin against rounding
//! (module doc of [`crate::ioss`], "Construction at any scale").

use faer::linalg::solvers::{DenseSolveCore, Solve};
use faer::{Mat, MatRef};

use crate::error::Result;
use crate::matrix::{sym_extreme_eigenvalues, symmetrize};
use crate::system::LtiSystem;

/// Doubling steps at most: each squares the closed-loop contraction, so 64 steps resolve a
/// closed-loop spectral radius up to 1 − 1e-15.
const MAX_DOUBLING_STEPS: usize = 64;

/// Parlett–Reinsch sweeps of the state balancing at most.
const BALANCE_SWEEPS: usize = 40;

/// A diagonal change of coordinates x = T x̃, w = D_w w̃, ỹ = D_y y applied to the data
/// of LMI (2): Ã = T⁻¹AT, Ẽ = T⁻¹ E D_w¹, C̃ = D_y C T, F̃ = D_y F D_w², Q̃ = D_w Q D_w,
/// R̃ = D_y⁻¹ R D_y⁻¹. LMI (2) of the scaled data is the congruence of LMI (2) of the
/// original by diag(T, D_w) with P̃ = T P T, so μ(P) is the same and P = T⁻¹ P̃ T⁻¹.
pub(super) struct Scaled {
    pub sys: LtiSystem,
    pub q: Mat<f64>,
    pub r: Mat<f64>,
    /// The diagonal of T.
    pub t: Vec<f64>,
}

impl Scaled {
    /// P = T⁻¹ P̃ T⁻¹ in the user's coordinates.
    pub fn unscale(&self, p: MatRef<'_, f64>) -> Mat<f64> {
        let t = &self.t;
        symmetrize(Mat::from_fn(p.nrows(), p.ncols(), |i, j| p[(i, j)] / (t[i] * t[j])).as_ref())
    }
}

/// The nearest power of two (exact scaling: no rounding is introduced by it).
fn pow2(v: f64) -> f64 {
    if v.is_finite() && v > 0.0 {
        2f64.powi(v.log2().round().clamp(-1000.0, 1000.0) as i32)
    } else {
        1.0
    }
}

/// Normalises Q and R to unit diagonal (D_w = diag(Q)^{-½}, D_y = diag(R)^{½}) and balances
/// the states: T makes, for every state i, the norm of row i of [Ã, Ẽ] equal to the norm of
/// column i of [Ã; C̃] (off-diagonal of Ã only), to a power of two (Parlett–Reinsch).
pub(super) fn balance(sys: &LtiSystem, q: MatRef<'_, f64>, r: MatRef<'_, f64>) -> Result<Scaled> {
    let (nx, nw1, nw2, ny) = (sys.nx(), sys.nw1(), sys.nw2(), sys.ny());
    let dw: Vec<f64> = (0..nw1 + nw2)
        .map(|i| pow2(1.0 / q[(i, i)].sqrt()))
        .collect();
    let dy: Vec<f64> = (0..ny).map(|i| pow2(r[(i, i)].sqrt())).collect();
    let e = Mat::from_fn(nx, nw1, |i, j| sys.e()[(i, j)] * dw[j]);
    let c = Mat::from_fn(ny, nx, |i, j| sys.c()[(i, j)] * dy[i]);
    let mut a = sys.a().to_owned();
    let mut e = e;
    let mut c = c;
    let mut t = vec![1.0; nx];
    for _ in 0..BALANCE_SWEEPS {
        let mut changed = false;
        for i in 0..nx {
            let mut row = 0.0;
            let mut column = 0.0;
            for k in 0..nx {
                if k != i {
                    row += a[(i, k)] * a[(i, k)];
                    column += a[(k, i)] * a[(k, i)];
                }
            }
            for k in 0..nw1 {
                row += e[(i, k)] * e[(i, k)];
            }
            for k in 0..ny {
                column += c[(k, i)] * c[(k, i)];
            }
            if !(row > 0.0 && column > 0.0) {
                continue;
            }
            // x_i = f x̃_i: row i of Ã, Ẽ divides by f, column i of Ã, C̃ multiplies by f.
            let f = pow2((row / column).sqrt().sqrt());
            if f == 1.0 {
                continue;
            }
            changed = true;
            t[i] *= f;
            for k in 0..nx {
                a[(i, k)] /= f;
                a[(k, i)] *= f;
            }
            for k in 0..nw1 {
                e[(i, k)] /= f;
            }
            for k in 0..ny {
                c[(k, i)] *= f;
            }
        }
        if !changed {
            break;
        }
    }
    let f = Mat::from_fn(ny, nw2, |i, j| sys.f()[(i, j)] * dy[i] * dw[nw1 + j]);
    let b = Mat::from_fn(nx, sys.nu(), |i, j| sys.b()[(i, j)] / t[i]);
    let scaled_sys = LtiSystem::with_disturbance(a, b, c, e, f)?;
    let nw = nw1 + nw2;
    let q_s = symmetrize(Mat::from_fn(nw, nw, |i, j| dw[i] * q[(i, j)] * dw[j]).as_ref());
    let r_s = symmetrize(Mat::from_fn(ny, ny, |i, j| r[(i, j)] / (dy[i] * dy[j])).as_ref());
    Ok(Scaled {
        sys: scaled_sys,
        q: q_s,
        r: r_s,
        t,
    })
}

/// Outcome of [`maximal_covariance`].
pub(super) enum Doubling {
    /// X = P*⁻¹ of the maximal solution, after `steps` doubling steps.
    Converged { x: Mat<f64>, steps: usize },
    /// The iteration produced non-finite values or a singular I + G H (no stabilising
    /// solution: η at or beyond the boundary).
    Failed,
    /// No convergence in the allowed steps.
    NotConverged { steps: usize },
}

/// The maximal P* of LMI (2) in covariance form X = P*⁻¹, η > 0: the stabilising solution
/// of the filter Riccati equation
///
/// X = ÂXÂᵀ + Ŵ − ÂXC̃ᵀ(C̃XC̃ᵀ + V)⁻¹C̃XÂᵀ,
///
/// Ã = A/√η, C̃ = C/√η, W = B̄Q⁻¹B̄ᵀ, V = R⁻¹ + D̄Q⁻¹D̄ᵀ, S = B̄Q⁻¹D̄ᵀ, Â = Ã − SV⁻¹C̃,
/// Ŵ = W − SV⁻¹Sᵀ — the fixed point of the covariance recursion of the module doc, whose
/// iterates from X = 0 the doubling algorithm produces at steps 1, 2, 4, 8, … (Chu, Fan,
/// Lin, Wang 2004), so it converges quadratically where the value iteration converges
/// linearly with the closed-loop rate.
pub(super) fn maximal_covariance(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    max_steps: usize,
) -> Doubling {
    let (nx, ny) = (sys.nx(), sys.ny());
    let s_eta = eta.sqrt();
    let (bbar, dbar) = (sys.b_bar(), sys.d_bar());
    let q_inv = q.to_owned().partial_piv_lu().inverse();
    let r_inv = r.to_owned().partial_piv_lu().inverse();
    let w = symmetrize((&bbar * &q_inv * bbar.transpose()).as_ref());
    let v = symmetrize((&r_inv + &dbar * &q_inv * dbar.transpose()).as_ref());
    let s = &bbar * &q_inv * dbar.transpose();
    let c_t = Mat::from_fn(ny, nx, |i, j| sys.c()[(i, j)] / s_eta);
    let v_lu = v.partial_piv_lu();
    let v_inv = v_lu.inverse();
    let a_t = Mat::from_fn(nx, nx, |i, j| sys.a()[(i, j)] / s_eta);
    let a_hat = &a_t - &s * &v_inv * &c_t;
    let w_hat = symmetrize((&w - &s * &v_inv * s.transpose()).as_ref());
    // Control-form doubling on the dual: A₀ = Âᵀ, G₀ = C̃ᵀV⁻¹C̃, H₀ = Ŵ; H_k → X.
    let mut ak = a_hat.transpose().to_owned();
    let mut g = symmetrize((c_t.transpose() * &v_inv * &c_t).as_ref());
    let mut h = w_hat;
    let id = Mat::<f64>::identity(nx, nx);
    let finite = |m: &Mat<f64>| m.norm_max().is_finite();
    for step in 1..=max_steps.min(MAX_DOUBLING_STEPS) {
        let wk = &id + &g * &h;
        let lu = wk.partial_piv_lu();
        let w_a = lu.solve(&ak);
        let w_g = lu.solve(&g);
        if !(finite(&w_a) && finite(&w_g)) {
            return Doubling::Failed;
        }
        let a_next = &ak * &w_a;
        let g_next = symmetrize((&g + &ak * &w_g * ak.transpose()).as_ref());
        let h_next = symmetrize((&h + ak.transpose() * &h * &w_a).as_ref());
        if !(finite(&a_next) && finite(&g_next) && finite(&h_next)) || a_next.norm_max() > 1e150 {
            return Doubling::Failed;
        }
        let change = (&h_next - &h).norm_max();
        let scale = h_next.norm_max();
        ak = a_next;
        g = g_next;
        h = h_next;
        if change <= 4.0 * f64::EPSILON * scale || ak.norm_max() <= f64::EPSILON * 1e-3 {
            return Doubling::Converged { x: h, steps: step };
        }
    }
    Doubling::NotConverged {
        steps: max_steps.min(MAX_DOUBLING_STEPS),
    }
}

/// P̃ = X⁻¹, or None if X is not positive definite in floating point (P = +∞ on a
/// direction: E does not reach every state).
pub(super) fn invert_covariance(x: &Mat<f64>) -> Result<Option<Mat<f64>>> {
    let (lo, hi) = sym_extreme_eigenvalues("X", x.as_ref())?;
    if !(hi > 0.0 && lo > f64::EPSILON * hi) {
        return Ok(None);
    }
    let p = x.partial_piv_lu().inverse();
    Ok(p.norm_max().is_finite().then(|| symmetrize(p.as_ref())))
}
