//! Matrix equations: the matrix exponential and zero-order-hold discretisation, the
//! discrete algebraic Riccati equation (the MPC terminal cost, design notes §4) and the
//! discrete Lyapunov equation.
//!
//! Every solver validates its input (shapes, finiteness, symmetry, definiteness), checks
//! the residual of the equation it claims to have solved and returns
//! [`ModelError::Numerical`] naming the routine when it cannot certify the answer. These
//! run once at setup on small dense matrices, so they use faer's allocating high-level API.
//!
//! ## Reference
//!
//! - N. J. Higham, "The scaling and squaring method for the matrix exponential revisited",
//!   SIAM J. Matrix Anal. Appl. 26(4), 2005 (Padé(13) with θ₁₃).
//! - E. K.-W. Chu, H.-Y. Fan, W.-W. Lin, C.-S. Wang, "Structure-preserving algorithms for
//!   periodic discrete-time algebraic Riccati equations", Int. J. Control 77(8), 2004
//!   (the doubling iteration used by [`dare`]).

use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef, Side};

use crate::error::{ModelError, Result};
use crate::matrix::{
    SYMMETRY_TOL, asymmetry, check_finite, check_positive_definite, check_shape, symmetrize,
};
use crate::system::spectral_radius;

/// Relative tolerance of the residual checks: a solution X is accepted when the max-abs
/// residual is at most `RESIDUAL_RTOL · scale`, where `scale` bounds the magnitude of the
/// terms of the equation (so the test is invariant to scaling the data).
pub const RESIDUAL_RTOL: f64 = 1e-9;

/// Dimension up to which [`dlyap`] solves the n²×n² Kronecker system directly; above it,
/// Smith doubling is used (O(n³) per step instead of O(n⁶) once).
pub const DLYAP_KRONECKER_MAX_N: usize = 40;

/// Maximum number of doubling steps of [`dare`] and of Smith's method in [`dlyap`]. Each step
/// squares the contraction, so 64 steps cover spectral radii up to 1 − 1e-15.
const MAX_DOUBLING_STEPS: usize = 64;

fn numerical(routine: &str, reason: impl Into<String>) -> ModelError {
    ModelError::Numerical {
        routine: routine.to_string(),
        reason: reason.into(),
    }
}

/// Rejects an empty (0 × 0) state matrix: the equations below need n ≥ 1.
fn check_nonempty(name: &str, m: MatRef<'_, f64>) -> Result<()> {
    if m.nrows() == 0 {
        return Err(ModelError::Shape {
            name: name.to_string(),
            expected_rows: 1,
            expected_cols: 1,
            actual_rows: 0,
            actual_cols: m.ncols(),
        });
    }
    Ok(())
}

/// Square, finite, symmetric (to [`SYMMETRY_TOL`] relative) and, if `psd`, positive
/// semidefinite up to roundoff. Returns the symmetrised matrix.
fn check_symmetric(name: &str, m: MatRef<'_, f64>, n: usize, psd: bool) -> Result<Mat<f64>> {
    check_shape(name, m, n, n)?;
    check_finite(name, m)?;
    let scale = m.norm_max().max(1.0);
    let asym = asymmetry(m);
    if asym > SYMMETRY_TOL * scale {
        return Err(ModelError::NotSymmetric {
            name: name.to_string(),
            asymmetry: asym,
        });
    }
    let s = symmetrize(m);
    if psd && n > 0 {
        let (lo, _) = crate::matrix::sym_extreme_eigenvalues(name, s.as_ref())?;
        if lo < -1e-12 * scale * n as f64 {
            return Err(ModelError::NotPositiveDefinite {
                name: name.to_string(),
                min_eigenvalue: lo,
            });
        }
    }
    Ok(s)
}

/// Operator 1-norm ‖M‖₁ = max_j Σ_i |m_ij|.
fn norm_one(m: MatRef<'_, f64>) -> f64 {
    (0..m.ncols())
        .map(|j| (0..m.nrows()).map(|i| m[(i, j)].abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

fn is_finite(m: MatRef<'_, f64>) -> bool {
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_finite()))
}

/// Solves M Y = rhs by LU with partial pivoting; errors (naming `routine`) if M is
/// numerically singular or the solution is not finite.
fn lu_solve(
    routine: &str,
    what: &str,
    m: MatRef<'_, f64>,
    rhs: MatRef<'_, f64>,
) -> Result<Mat<f64>> {
    let n = m.nrows();
    if n == 0 {
        return Ok(Mat::zeros(0, rhs.ncols()));
    }
    let lu = m.partial_piv_lu();
    let u = lu.U();
    let umax = u.norm_max();
    let umin = (0..n)
        .map(|i| u[(i, i)].abs())
        .fold(f64::INFINITY, f64::min);
    if !(umin > f64::EPSILON * n as f64 * umax) {
        return Err(numerical(
            routine,
            format!(
                "{what} is numerically singular (smallest LU pivot {umin:e}, largest entry {umax:e})"
            ),
        ));
    }
    let y = lu.solve(rhs);
    if !is_finite(y.as_ref()) {
        return Err(numerical(
            routine,
            format!("solving with {what} produced non-finite values"),
        ));
    }
    Ok(y)
}

/// Padé(13) coefficients b₀…b₁₃ (Higham 2005, Table 2.3 numerators).
const PADE13: [f64; 14] = [
    64_764_752_532_480_000.0,
    32_382_376_266_240_000.0,
    7_771_770_303_897_600.0,
    1_187_353_796_428_800.0,
    129_060_195_264_000.0,
    10_559_470_521_600.0,
    670_442_572_800.0,
    33_522_128_640.0,
    1_323_241_920.0,
    40_840_800.0,
    960_960.0,
    16_380.0,
    182.0,
    1.0,
];

/// θ₁₃: the largest ‖A‖₁ for which Padé(13) meets double precision backward error.
const THETA13: f64 = 5.371_920_351_148_152;

/// Matrix exponential e^A by scaling and squaring with the Padé(13) approximant.
///
/// A is scaled by 2^{−s} so that ‖A‖₁ ≤ θ₁₃, the [13/13] Padé approximant r(A·2^{−s}) is
/// formed and squared s times. Backward stable in exact arithmetic for the scaled problem
/// (Higham 2005); relative accuracy near 1e-14 for moderate ‖A‖.
///
/// Errors: `Shape` (`"A"` not square), `NonFinite` (`"A"`), `Numerical` (`"expm"`) if the
/// result overflows f64.
///
/// ```
/// use faer::mat;
/// let e = lti_model::riccati::expm(mat![[0.0, 1.0], [-1.0, 0.0]].as_ref()).unwrap();
/// assert!((e[(0, 0)] - 1f64.cos()).abs() < 1e-14 && (e[(0, 1)] - 1f64.sin()).abs() < 1e-14);
/// ```
pub fn expm(a: MatRef<'_, f64>) -> Result<Mat<f64>> {
    let n = a.nrows();
    check_shape("A", a, n, n)?;
    check_finite("A", a)?;
    if n == 0 {
        return Ok(Mat::zeros(0, 0));
    }
    let norm = norm_one(a);
    if !norm.is_finite() {
        return Err(numerical(
            "expm",
            "‖A‖₁ overflows f64; scale A (e.g. the sampling time) down",
        ));
    }
    // s = max(0, ⌈log₂(‖A‖₁/θ₁₃)⌉) ≤ 1022 because ‖A‖₁ ≤ f64::MAX, so 2^{−s} is a normal
    // number and the squaring loop below is short.
    let s = if norm > THETA13 {
        (norm / THETA13).log2().ceil().clamp(0.0, 1022.0) as i32
    } else {
        0
    };
    let scale = 2f64.powi(-s);
    let a = Mat::from_fn(n, n, |i, j| a[(i, j)] * scale);

    let b = &PADE13;
    let id = Mat::<f64>::identity(n, n);
    let a2 = &a * &a;
    let a4 = &a2 * &a2;
    let a6 = &a4 * &a2;
    let lin = |c6: f64, c4: f64, c2: f64, c0: f64| -> Mat<f64> {
        Mat::from_fn(n, n, |i, j| {
            c6 * a6[(i, j)] + c4 * a4[(i, j)] + c2 * a2[(i, j)] + c0 * id[(i, j)]
        })
    };
    // U = A[A6(b13 A6 + b11 A4 + b9 A2) + b7 A6 + b5 A4 + b3 A2 + b1 I]
    let u_inner = &a6 * lin(b[13], b[11], b[9], 0.0) + lin(b[7], b[5], b[3], b[1]);
    let u = &a * &u_inner;
    // V = A6(b12 A6 + b10 A4 + b8 A2) + b6 A6 + b4 A4 + b2 A2 + b0 I
    let v = &a6 * lin(b[12], b[10], b[8], 0.0) + lin(b[6], b[4], b[2], b[0]);
    let p = &v + &u;
    let q = &v - &u;
    let mut r = lu_solve("expm", "the Padé denominator V − U", q.as_ref(), p.as_ref())?;
    for _ in 0..s {
        r = &r * &r;
        if !is_finite(r.as_ref()) {
            return Err(numerical(
                "expm",
                format!(
                    "e^A overflows f64 (‖A‖₁ = {norm:e}); scale A (e.g. a smaller sampling time) down"
                ),
            ));
        }
    }
    Ok(r)
}

/// Zero-order-hold discretisation of ẋ = A_c x + B_c u with sampling time T = `ts`:
/// A = e^{A_c T}, B = ∫₀ᵀ e^{A_c s} ds · B_c, both read off
/// exp([[A_c, B_c], [0, 0]]·T) = [[A, B], [0, I]] (no inverse of A_c needed).
///
/// Errors: `Shape` (`"A_c"` not square, `"B_c"` with the wrong number of rows),
/// `NonFinite` (`"A_c"`, `"B_c"`), `OutOfRange` (`"ts"` not in (0, ∞)), `Numerical`
/// from [`expm`].
///
/// ```
/// use faer::mat;
/// // double integrator: A = [[1, T], [0, 1]], B = [[T²/2], [T]]
/// let (a, b) = lti_model::riccati::zoh(
///     mat![[0.0, 1.0], [0.0, 0.0]].as_ref(), mat![[0.0], [1.0]].as_ref(), 0.5).unwrap();
/// assert!((a[(0, 1)] - 0.5).abs() < 1e-15 && (b[(0, 0)] - 0.125).abs() < 1e-15);
/// ```
pub fn zoh(a_c: MatRef<'_, f64>, b_c: MatRef<'_, f64>, ts: f64) -> Result<(Mat<f64>, Mat<f64>)> {
    let n = a_c.nrows();
    check_nonempty("A_c", a_c)?;
    check_shape("A_c", a_c, n, n)?;
    check_shape("B_c", b_c, n, b_c.ncols())?;
    check_finite("A_c", a_c)?;
    check_finite("B_c", b_c)?;
    if !(ts > 0.0 && ts.is_finite()) {
        return Err(ModelError::OutOfRange {
            name: "ts".into(),
            value: ts,
            range: "(0, ∞), finite".into(),
        });
    }
    let m = b_c.ncols();
    let block = Mat::from_fn(n + m, n + m, |i, j| match (i < n, j < n) {
        (true, true) => a_c[(i, j)] * ts,
        (true, false) => b_c[(i, j - n)] * ts,
        _ => 0.0,
    });
    if !is_finite(block.as_ref()) {
        return Err(ModelError::OutOfRange {
            name: "ts".into(),
            value: ts,
            range: "(0, ∞) with A_c·ts and B_c·ts finite".into(),
        });
    }
    let e = expm(block.as_ref())?;
    let a = e.as_ref().submatrix(0, 0, n, n).to_owned();
    let b = e.as_ref().submatrix(0, n, n, m).to_owned();
    Ok((a, b))
}

/// Validated (A, B, Q, R) of a DARE: returns (n, m, Q sym, R sym).
fn check_dare_data(
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
) -> Result<(Mat<f64>, Mat<f64>)> {
    let n = a.nrows();
    check_nonempty("A", a)?;
    check_shape("A", a, n, n)?;
    check_shape("B", b, n, b.ncols())?;
    check_finite("A", a)?;
    check_finite("B", b)?;
    let m = b.ncols();
    let q = check_symmetric("Q", q, n, true)?;
    check_shape("R", r, m, m)?;
    if m > 0 {
        check_positive_definite("R", r, m)?;
    }
    Ok((q, symmetrize(r)))
}

/// K = (R + BᵀXB)⁻¹ BᵀXA, with R + BᵀXB factored by Cholesky (it is PD when R ≻ 0, X ⪰ 0).
fn lqr_gain_from(
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    x: MatRef<'_, f64>,
) -> Result<Mat<f64>> {
    let m = b.ncols();
    if m == 0 {
        return Ok(Mat::zeros(0, a.nrows()));
    }
    let btx = b.transpose() * x;
    let s = symmetrize((r + &btx * b).as_ref());
    let rhs = &btx * a;
    match s.llt(Side::Lower) {
        Ok(llt) => {
            let k = llt.solve(&rhs);
            if is_finite(k.as_ref()) {
                Ok(k)
            } else {
                Err(numerical("DARE", "the gain (R + BᵀXB)⁻¹BᵀXA is not finite"))
            }
        }
        Err(_) => Err(numerical(
            "DARE",
            "R + BᵀXB is not positive definite for the computed X",
        )),
    }
}

/// Max-abs residual of the DARE, max_ij |AᵀXA − AᵀXB(R + BᵀXB)⁻¹BᵀXA + Q − X|_ij.
///
/// Errors: `Shape`/`NonFinite` naming `"A"`, `"B"`, `"Q"`, `"R"`, `"X"`; `Numerical`
/// (`"DARE residual"`) if R + BᵀXB is singular.
///
/// ```
/// use faer::mat;
/// use lti_model::riccati::{dare, residual_dare};
/// let (a, b, q, r) = (mat![[1.1]], mat![[1.0]], mat![[1.0]], mat![[1.0]]);
/// let x = dare(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref()).unwrap();
/// assert!(residual_dare(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref(), x.as_ref()).unwrap() < 1e-12);
/// ```
pub fn residual_dare(
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    x: MatRef<'_, f64>,
) -> Result<f64> {
    let n = a.nrows();
    check_shape("A", a, n, n)?;
    check_shape("B", b, n, b.ncols())?;
    let m = b.ncols();
    check_shape("Q", q, n, n)?;
    check_shape("R", r, m, m)?;
    check_shape("X", x, n, n)?;
    for (name, mat) in [("A", a), ("B", b), ("Q", q), ("R", r), ("X", x)] {
        check_finite(name, mat)?;
    }
    let xa = x * a;
    let btxa = b.transpose() * &xa;
    let s = r + b.transpose() * x * b;
    let corr = lu_solve("DARE residual", "R + BᵀXB", s.as_ref(), btxa.as_ref())?;
    let res = a.transpose() * &xa - btxa.transpose() * &corr + q - x;
    Ok(res.norm_max())
}

/// Stabilizing solution of the DARE and its gain; the worker behind [`dare`] and
/// [`dlqr_gain`].
fn dare_impl(
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    q_in: MatRef<'_, f64>,
    r_in: MatRef<'_, f64>,
) -> Result<(Mat<f64>, Mat<f64>)> {
    let (q, r) = check_dare_data(a, b, q_in, r_in)?;
    let n = a.nrows();
    let m = b.ncols();
    let id = Mat::<f64>::identity(n, n);

    // G₀ = B R⁻¹ Bᵀ (R ≻ 0 was checked, so Cholesky succeeds).
    let mut g = if m == 0 {
        Mat::zeros(n, n)
    } else {
        let llt = r
            .llt(Side::Lower)
            .map_err(|_| numerical("DARE", "Cholesky factorisation of R failed"))?;
        let rinv_bt = llt.solve(b.transpose());
        symmetrize((b * &rinv_bt).as_ref())
    };
    let mut ak = a.to_owned();
    let mut h = q.clone();
    let not_stabilizable = "the doubling iteration diverges: (A, B) is not stabilizable, or (A, Q) has \
                            an unstable mode that Q does not see (not detectable); check B and use Q ≻ 0";
    let mut converged = false;
    for _ in 0..MAX_DOUBLING_STEPS {
        // W = I + G_k H_k; A_{k+1} = A_k W⁻¹ A_k, G_{k+1} = G_k + A_k W⁻¹ G_k A_kᵀ,
        // H_{k+1} = H_k + A_kᵀ H_k W⁻¹ A_k.
        let w = &id + &g * &h;
        let mut rhs = Mat::zeros(n, 2 * n);
        rhs.as_mut().submatrix_mut(0, 0, n, n).copy_from(&ak);
        rhs.as_mut().submatrix_mut(0, n, n, n).copy_from(&g);
        let y = lu_solve(
            "DARE",
            "I + G_k H_k (doubling step)",
            w.as_ref(),
            rhs.as_ref(),
        )
        .map_err(|_| numerical("DARE", not_stabilizable))?;
        let w_a = y.as_ref().submatrix(0, 0, n, n);
        let w_g = y.as_ref().submatrix(0, n, n, n);
        let a_next = &ak * w_a;
        let g_next = symmetrize((&g + &ak * w_g * ak.transpose()).as_ref());
        let h_next = symmetrize((&h + ak.transpose() * &h * w_a).as_ref());
        if !(is_finite(a_next.as_ref()) && is_finite(g_next.as_ref()) && is_finite(h_next.as_ref()))
            || a_next.norm_max() > 1e150
        {
            return Err(numerical("DARE", not_stabilizable));
        }
        let change = (&h_next - &h).norm_max();
        let scale = h_next.norm_max().max(1.0);
        ak = a_next;
        g = g_next;
        h = h_next;
        if change <= 4.0 * f64::EPSILON * scale || ak.norm_max() <= f64::EPSILON * 1e-3 {
            converged = true;
            break;
        }
    }
    let x = h;
    let k = lqr_gain_from(a, b, r.as_ref(), x.as_ref())?;
    let closed = a - b * &k;
    let rho = spectral_radius(closed.as_ref())?;
    if !(rho < 1.0) {
        return Err(numerical(
            "DARE",
            format!(
                "no stabilizing solution: the closed loop A − BK has spectral radius {rho} ≥ 1; \
                 (A, B) is not stabilizable, or (A, Q) has an unstable mode that Q does not see \
                 (not detectable); check B and use Q ≻ 0"
            ),
        ));
    }
    let res = residual_dare(a, b, q.as_ref(), r.as_ref(), x.as_ref())?;
    let xa_norm = x.norm_max() * (1.0 + a.norm_max() * a.norm_max() * n as f64);
    let tol = RESIDUAL_RTOL * xa_norm.max(q.norm_max()).max(1.0);
    if !(res <= tol) {
        let why = if converged {
            ""
        } else {
            " (the doubling iteration did not converge)"
        };
        return Err(numerical(
            "DARE",
            format!(
                "residual {res:e} exceeds {tol:e}{why}: the problem is ill-conditioned \
                 (closed-loop spectral radius {rho}); rescale A, B, Q, R"
            ),
        ));
    }
    Ok((x, k))
}

/// Stabilizing solution X ⪰ 0 of the discrete algebraic Riccati equation
/// X = AᵀXA − AᵀXB(R + BᵀXB)⁻¹BᵀXA + Q: the infinite-horizon LQR cost-to-go, used as the
/// MPC terminal cost.
///
/// Solved by the structure-preserving doubling algorithm (quadratic convergence), then
/// verified: the residual must be small and A − BK Schur (spectral radius < 1).
///
/// ## Requirements
///
/// A n×n, B n×m finite; Q n×n symmetric ⪰ 0; R m×m symmetric ≻ 0; (A, B) stabilizable
/// and (A, Q) detectable (Q ≻ 0 suffices). Violations give `Shape`, `NonFinite`,
/// `NotSymmetric`, `NotPositiveDefinite` (naming the matrix) or `Numerical` (`"DARE"`).
///
/// ```
/// use faer::mat;
/// // scalar a = 2, b = q = r = 1: x² − 4x − 1 = 0, x = 2 + √5
/// let x = lti_model::riccati::dare(
///     mat![[2.0]].as_ref(), mat![[1.0]].as_ref(), mat![[1.0]].as_ref(), mat![[1.0]].as_ref()).unwrap();
/// assert!((x[(0, 0)] - (2.0 + 5f64.sqrt())).abs() < 1e-12);
/// ```
pub fn dare(
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
) -> Result<Mat<f64>> {
    dare_impl(a, b, q, r).map(|(x, _)| x)
}

/// Discrete LQR: (K, X) with X the stabilizing DARE solution ([`dare`]) and
/// K = (R + BᵀXB)⁻¹BᵀXA, so u = −Kx minimises Σ xᵀQx + uᵀRu and A − BK is Schur.
///
/// ```
/// use faer::mat;
/// use lti_model::system::spectral_radius;
/// let (a, b) = (mat![[1.0, 0.1], [0.0, 1.0]], mat![[0.005], [0.1]]);
/// let (k, _x) = lti_model::riccati::dlqr_gain(
///     a.as_ref(), b.as_ref(), faer::Mat::<f64>::identity(2, 2).as_ref(), mat![[0.1]].as_ref()).unwrap();
/// assert!(spectral_radius((&a - &b * &k).as_ref()).unwrap() < 1.0);
/// ```
pub fn dlqr_gain(
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
) -> Result<(Mat<f64>, Mat<f64>)> {
    dare_impl(a, b, q, r).map(|(x, k)| (k, x))
}

/// Max-abs residual of the discrete Lyapunov equation, max_ij |AᵀXA − X + Q|_ij.
///
/// Errors: `Shape`/`NonFinite` naming `"A"`, `"Q"` or `"X"`.
///
/// ```
/// use faer::mat;
/// use lti_model::riccati::residual_dlyap;
/// // a = 0.5, q = 3: x = q / (1 − a²) = 4
/// assert_eq!(residual_dlyap(mat![[0.5]].as_ref(), mat![[3.0]].as_ref(), mat![[4.0]].as_ref()).unwrap(), 0.0);
/// ```
pub fn residual_dlyap(a: MatRef<'_, f64>, q: MatRef<'_, f64>, x: MatRef<'_, f64>) -> Result<f64> {
    let n = a.nrows();
    check_shape("A", a, n, n)?;
    check_shape("Q", q, n, n)?;
    check_shape("X", x, n, n)?;
    for (name, mat) in [("A", a), ("Q", q), ("X", x)] {
        check_finite(name, mat)?;
    }
    let res = a.transpose() * x * a - x + q;
    Ok(res.norm_max())
}

/// Solution X of the discrete Lyapunov equation AᵀXA − X + Q = 0 (X = Σ_k (Aᵀ)ᵏQAᵏ).
///
/// For n ≤ [`DLYAP_KRONECKER_MAX_N`] the n² linear system (I − Aᵀ⊗Aᵀ) vec X = vec Q is
/// solved by LU with partial pivoting; above it, Smith doubling X ← X + AₖᵀXAₖ, Aₖ₊₁ = Aₖ²
/// is used. The residual is checked either way.
///
/// ## Requirements
///
/// A n×n finite and Schur (spectral radius < 1; otherwise the solution is not unique or
/// not ⪰ 0 and `Numerical` (`"Lyapunov"`) is returned); Q n×n finite and symmetric. X ⪰ 0
/// when Q ⪰ 0.
///
/// ```
/// use faer::mat;
/// let x = lti_model::riccati::dlyap(mat![[0.5]].as_ref(), mat![[3.0]].as_ref()).unwrap();
/// assert!((x[(0, 0)] - 4.0).abs() < 1e-14);
/// ```
pub fn dlyap(a: MatRef<'_, f64>, q: MatRef<'_, f64>) -> Result<Mat<f64>> {
    let n = a.nrows();
    check_nonempty("A", a)?;
    check_shape("A", a, n, n)?;
    check_finite("A", a)?;
    let q = check_symmetric("Q", q, n, false)?;
    let rho = spectral_radius(a)?;
    if !(rho < 1.0) {
        return Err(numerical(
            "Lyapunov",
            format!(
                "A has spectral radius {rho} ≥ 1 (not Schur), so AᵀXA − X + Q = 0 has no unique \
                 positive semidefinite solution; stabilise A first"
            ),
        ));
    }
    let x = if n <= DLYAP_KRONECKER_MAX_N {
        dlyap_kronecker(a, q.as_ref())?
    } else {
        dlyap_smith(a, q.as_ref())?
    };
    let x = symmetrize(x.as_ref());
    let res = residual_dlyap(a, q.as_ref(), x.as_ref())?;
    let a_norm = a.norm_max() * n as f64;
    let tol = RESIDUAL_RTOL
        * (x.norm_max() * (1.0 + a_norm * a_norm))
            .max(q.norm_max())
            .max(1.0);
    if !(res <= tol) {
        return Err(numerical(
            "Lyapunov",
            format!(
                "residual {res:e} exceeds {tol:e}: A is too close to instability (spectral radius {rho})"
            ),
        ));
    }
    Ok(x)
}

/// (I − Aᵀ⊗Aᵀ) vec X = vec Q, column-major vec: row i + n·j, column k + n·l has
/// δ_ik δ_jl − A_ki A_lj.
fn dlyap_kronecker(a: MatRef<'_, f64>, q: MatRef<'_, f64>) -> Result<Mat<f64>> {
    let n = a.nrows();
    let nn = n * n;
    let m = Mat::from_fn(nn, nn, |row, col| {
        let (i, j) = (row % n, row / n);
        let (k, l) = (col % n, col / n);
        let delta = if row == col { 1.0 } else { 0.0 };
        delta - a[(k, i)] * a[(l, j)]
    });
    let rhs = Mat::from_fn(nn, 1, |row, _| q[(row % n, row / n)]);
    let v = lu_solve("Lyapunov", "I − Aᵀ⊗Aᵀ", m.as_ref(), rhs.as_ref())?;
    Ok(Mat::from_fn(n, n, |i, j| v[(i + n * j, 0)]))
}

/// Smith doubling: X₀ = Q, A₀ = A; X_{k+1} = X_k + A_kᵀ X_k A_k, A_{k+1} = A_k².
/// After k steps X_k = Σ_{i < 2^k} (Aᵀ)ⁱ Q Aⁱ.
fn dlyap_smith(a: MatRef<'_, f64>, q: MatRef<'_, f64>) -> Result<Mat<f64>> {
    let mut x = q.to_owned();
    let mut ak = a.to_owned();
    for _ in 0..MAX_DOUBLING_STEPS {
        let inc = ak.transpose() * &x * &ak;
        x += &inc;
        ak = &ak * &ak;
        if !is_finite(x.as_ref()) {
            return Err(numerical("Lyapunov", "Smith iteration overflowed"));
        }
        if inc.norm_max() <= f64::EPSILON * x.norm_max().max(f64::MIN_POSITIVE) {
            return Ok(x);
        }
    }
    Err(numerical(
        "Lyapunov",
        format!(
            "Smith doubling did not converge in {MAX_DOUBLING_STEPS} steps: A is too close to instability"
        ),
    ))
}
