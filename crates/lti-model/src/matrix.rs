//! Small dense-matrix helpers shared by the crates: validation (shape, finiteness,
//! symmetry, definiteness) and symmetric eigenvalues.
//!
//! These run at setup time on small matrices, so they use faer's high-level API.

use faer::{Mat, MatRef, Side};

use crate::error::{ModelError, Result};

/// Builds a matrix from row-major nested rows, checking that all rows have one length.
///
/// ```
/// let a = lti_model::matrix::from_rows("A", &[vec![1.0, 2.0], vec![3.0, 4.0]]).unwrap();
/// assert_eq!(a[(1, 0)], 3.0);
/// ```
pub fn from_rows(name: &str, rows: &[Vec<f64>]) -> Result<Mat<f64>> {
    let nrows = rows.len();
    let ncols = rows.first().map_or(0, Vec::len);
    for r in rows {
        if r.len() != ncols {
            return Err(ModelError::Shape {
                name: name.to_string(),
                expected_rows: nrows,
                expected_cols: ncols,
                actual_rows: nrows,
                actual_cols: r.len(),
            });
        }
    }
    let m = Mat::from_fn(nrows, ncols, |i, j| rows[i][j]);
    check_finite(name, m.as_ref())?;
    Ok(m)
}

/// Builds a column vector (n × 1 matrix) from a slice.
pub fn col(v: &[f64]) -> Mat<f64> {
    Mat::from_fn(v.len(), 1, |i, _| v[i])
}

/// Checks that `m` has shape `rows × cols`.
pub fn check_shape(name: &str, m: MatRef<'_, f64>, rows: usize, cols: usize) -> Result<()> {
    Ok(qp_iter::matrix::check_shape(name, m, rows, cols)?)
}

/// Checks that a vector has length `n`.
pub fn check_len(name: &str, v: &[f64], n: usize) -> Result<()> {
    Ok(qp_iter::matrix::check_len(name, v, n)?)
}

/// Checks that every entry of `m` is finite.
pub fn check_finite(name: &str, m: MatRef<'_, f64>) -> Result<()> {
    Ok(qp_iter::matrix::check_finite(name, m)?)
}

/// Checks that every entry of a vector is finite.
pub fn check_finite_slice(name: &str, v: &[f64]) -> Result<()> {
    Ok(qp_iter::matrix::check_finite_slice(name, v)?)
}

/// The one copy of these lives with the QP data checks of `qp-iter`.
pub use qp_iter::matrix::{SYMMETRY_TOL, asymmetry, row_major, symmetrize};

/// Eigenvalues of a symmetric matrix in nondecreasing order (the lower triangle is read).
///
/// Returns `ModelError::Numerical` if the eigensolver does not converge (it does not for
/// finite input in practice, but no panic is reachable).
pub fn sym_eigenvalues(name: &str, m: MatRef<'_, f64>) -> Result<Vec<f64>> {
    Ok(qp_iter::matrix::sym_eigenvalues(name, m)?)
}

/// Extreme eigenvalues (λ_min, λ_max) of a symmetric matrix.
pub fn sym_extreme_eigenvalues(name: &str, m: MatRef<'_, f64>) -> Result<(f64, f64)> {
    Ok(qp_iter::matrix::sym_extreme_eigenvalues(name, m)?)
}

/// Validates a weight matrix: `n × n`, finite, symmetric (to [`SYMMETRY_TOL`] relative)
/// and positive definite. Returns (λ_min, λ_max).
///
/// ```
/// use faer::Mat;
/// let q = Mat::<f64>::identity(3, 3);
/// let (lo, hi) = lti_model::matrix::check_positive_definite("Q", q.as_ref(), 3).unwrap();
/// assert!((lo - 1.0).abs() < 1e-12 && (hi - 1.0).abs() < 1e-12);
/// ```
pub fn check_positive_definite(name: &str, m: MatRef<'_, f64>, n: usize) -> Result<(f64, f64)> {
    Ok(qp_iter::matrix::check_positive_definite(name, m, n)?)
}

/// Spectral norm ‖M‖₂ (largest singular value).
pub fn spectral_norm(m: MatRef<'_, f64>) -> f64 {
    if m.nrows() == 0 || m.ncols() == 0 {
        return 0.0;
    }
    // ‖M‖₂² = λ_max(MᵀM); avoids a failure mode of the SVD path on tiny inputs.
    let mtm = m.transpose() * m;
    sym_extreme_eigenvalues("MᵀM", mtm.as_ref()).map_or(f64::NAN, |(_, hi)| hi.max(0.0).sqrt())
}

/// Block-diagonal matrix of the given blocks.
pub fn block_diag(blocks: &[MatRef<'_, f64>]) -> Mat<f64> {
    let n: usize = blocks.iter().map(|b| b.nrows()).sum();
    let m: usize = blocks.iter().map(|b| b.ncols()).sum();
    let mut out = Mat::zeros(n, m);
    let (mut r, mut c) = (0, 0);
    for b in blocks {
        out.as_mut()
            .submatrix_mut(r, c, b.nrows(), b.ncols())
            .copy_from(b);
        r += b.nrows();
        c += b.ncols();
    }
    out
}

/// The rows of `m` as nested vectors (for JSON and TOML).
pub fn to_rows(m: MatRef<'_, f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect()
}

/// Largest k for which [`sym_lambda_max`] uses the cyclic Jacobi rotations: about 4k³
/// multiply-adds per sweep and 6–10 sweeps, against ≈ 4k³/3 for the tridiagonal reduction of
/// the dense eigenvalues; below this size Jacobi's allocation-free loop wins.
pub const JACOBI_MAX_DIM: usize = 24;

/// Largest eigenvalue of a symmetric k × k matrix stored row-major in `g` (overwritten):
/// [`sym_lambda_max_in_place`] up to [`JACOBI_MAX_DIM`], the dense symmetric eigenvalues
/// (faer, backward stable: error ≤ c·k·ε‖g‖) above; +∞ if those fail (the safe side for
/// the upper bounds it feeds: a NaN would vanish under `max`).
///
/// ```
/// let mut g = vec![0.0; 30 * 30];
/// for i in 0..30 {
///     g[i * 30 + i] = i as f64;
/// }
/// assert!((lti_model::matrix::sym_lambda_max(&mut g, 30) - 29.0).abs() < 1e-12);
/// ```
pub fn sym_lambda_max(g: &mut [f64], k: usize) -> f64 {
    if k <= JACOBI_MAX_DIM {
        return sym_lambda_max_in_place(g, k);
    }
    let m = MatRef::from_row_major_slice(&g[..k * k], k, k);
    match m.self_adjoint_eigenvalues(Side::Lower) {
        Ok(ev) if ev.iter().all(|v| v.is_finite()) => {
            ev.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        }
        _ => f64::INFINITY,
    }
}

/// Largest eigenvalue of a symmetric k × k matrix stored row-major in `g` (overwritten),
/// by cyclic Jacobi rotations: accurate to machine precision and allocation-free, for the
/// many tiny eigenproblems of active-set enumerations. Returns −∞ for k = 0.
///
/// ```
/// let mut g = [2.0, 1.0, 1.0, 2.0];
/// assert!((lti_model::matrix::sym_lambda_max_in_place(&mut g, 2) - 3.0).abs() < 1e-14);
/// ```
pub fn sym_lambda_max_in_place(g: &mut [f64], k: usize) -> f64 {
    sym_lambda_max_above(g, k, f64::NEG_INFINITY).unwrap_or(f64::NEG_INFINITY)
}

/// [`sym_lambda_max_in_place`] for a running maximum: None as soon as a Gershgorin bound of
/// the (rotated) matrix, with a 10⁻¹² relative allowance far above the rotations' rounding,
/// shows λ_max ≤ `floor`; otherwise Some(λ_max), bit for bit the value
/// [`sym_lambda_max_in_place`] returns. An enumeration's maximum over many free sets stops
/// most eigenproblems after a sweep or two (perf, session 21: the full Jacobi was 20 % of the
/// case study's `reproduce`).
///
/// ```
/// let mut g = [2.0, 1.0, 1.0, 2.0];
/// assert_eq!(lti_model::matrix::sym_lambda_max_above(&mut g, 2, 3.5), None);
/// let mut g = [2.0, 1.0, 1.0, 2.0];
/// let top = lti_model::matrix::sym_lambda_max_above(&mut g, 2, 2.5).unwrap();
/// assert!((top - 3.0).abs() < 1e-14);
/// ```
pub fn sym_lambda_max_above(g: &mut [f64], k: usize, floor: f64) -> Option<f64> {
    // max_i (g_ii + Σ_{j≠i} |g_ij|) plus 10⁻¹² of max_i Σ_j |g_ij| ≥ ‖g‖₂.
    let bound = |g: &[f64]| {
        let (mut top, mut scale) = (f64::NEG_INFINITY, 0.0_f64);
        for i in 0..k {
            let row = &g[i * k..(i + 1) * k];
            let abs: f64 = row.iter().map(|v| v.abs()).sum();
            top = top.max(row[i] + (abs - row[i].abs()));
            scale = scale.max(abs);
        }
        top + 1e-12 * scale
    };
    for _sweep in 0..100 {
        if floor > f64::NEG_INFINITY && bound(g) <= floor {
            return None;
        }
        let mut off = 0.0;
        for p in 0..k {
            for q in p + 1..k {
                off += g[p * k + q] * g[p * k + q];
            }
        }
        let diag: f64 = (0..k).map(|i| g[i * k + i] * g[i * k + i]).sum();
        if off <= 1e-30 * diag.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..k {
            for q in p + 1..k {
                let apq = g[p * k + q];
                if apq == 0.0 {
                    continue;
                }
                let (app, aqq) = (g[p * k + p], g[q * k + q]);
                let theta = (aqq - app) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * c;
                for r in 0..k {
                    let (grp, grq) = (g[r * k + p], g[r * k + q]);
                    g[r * k + p] = c * grp - sn * grq;
                    g[r * k + q] = sn * grp + c * grq;
                }
                for r in 0..k {
                    let (gpr, gqr) = (g[p * k + r], g[q * k + r]);
                    g[p * k + r] = c * gpr - sn * gqr;
                    g[q * k + r] = sn * gpr + c * gqr;
                }
            }
        }
    }
    let top = (0..k)
        .map(|i| g[i * k + i])
        .fold(f64::NEG_INFINITY, f64::max);
    (top > floor || floor == f64::NEG_INFINITY).then_some(top)
}
