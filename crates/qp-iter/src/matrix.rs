//! Setup-time checks of dense problem data (shape, finiteness, symmetry, definiteness) and
//! the row-major copy the kernels start from. `lti_model::matrix` offers the same checks
//! with its own error type (it calls these).

use faer::{Mat, MatRef, Side};

use crate::error::DataError;

/// Result of the checks.
type Result<T> = std::result::Result<T, DataError>;

/// Checks that `m` has shape `rows × cols`.
pub fn check_shape(name: &str, m: MatRef<'_, f64>, rows: usize, cols: usize) -> Result<()> {
    if m.nrows() != rows || m.ncols() != cols {
        return Err(DataError::Shape {
            name: name.to_string(),
            expected_rows: rows,
            expected_cols: cols,
            actual_rows: m.nrows(),
            actual_cols: m.ncols(),
        });
    }
    Ok(())
}

/// Checks that a vector has length `n`.
pub fn check_len(name: &str, v: &[f64], n: usize) -> Result<()> {
    if v.len() != n {
        return Err(DataError::Shape {
            name: name.to_string(),
            expected_rows: n,
            expected_cols: 1,
            actual_rows: v.len(),
            actual_cols: 1,
        });
    }
    Ok(())
}

/// Checks that every entry of `m` is finite.
pub fn check_finite(name: &str, m: MatRef<'_, f64>) -> Result<()> {
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            let value = m[(i, j)];
            if !value.is_finite() {
                return Err(DataError::NonFinite {
                    name: name.to_string(),
                    row: i,
                    col: j,
                    value,
                });
            }
        }
    }
    Ok(())
}

/// Checks that every entry of a vector is finite.
pub fn check_finite_slice(name: &str, v: &[f64]) -> Result<()> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(DataError::NonFinite {
            name: name.to_string(),
            row: i,
            col: 0,
            value: v[i],
        }),
        None => Ok(()),
    }
}

/// Largest |m_ij − m_ji|.
pub fn asymmetry(m: MatRef<'_, f64>) -> f64 {
    let mut worst = 0.0_f64;
    for i in 0..m.nrows() {
        for j in 0..i {
            worst = worst.max((m[(i, j)] - m[(j, i)]).abs());
        }
    }
    worst
}

/// Returns (M + Mᵀ)/2.
pub fn symmetrize(m: MatRef<'_, f64>) -> Mat<f64> {
    Mat::from_fn(m.nrows(), m.ncols(), |i, j| 0.5 * (m[(i, j)] + m[(j, i)]))
}

/// Eigenvalues of a symmetric matrix in nondecreasing order (the lower triangle is read).
///
/// Returns `DataError::Numerical` if the eigensolver does not converge (it does not for
/// finite input in practice, but no panic is reachable).
pub fn sym_eigenvalues(name: &str, m: MatRef<'_, f64>) -> Result<Vec<f64>> {
    if m.nrows() == 0 {
        return Ok(Vec::new());
    }
    let s = symmetrize(m);
    s.self_adjoint_eigenvalues(Side::Lower)
        .map_err(|e| DataError::Numerical {
            routine: format!("symmetric eigenvalues of `{name}`"),
            reason: format!("{e:?}"),
        })
}

/// Extreme eigenvalues (λ_min, λ_max) of a symmetric matrix.
pub fn sym_extreme_eigenvalues(name: &str, m: MatRef<'_, f64>) -> Result<(f64, f64)> {
    let ev = sym_eigenvalues(name, m)?;
    match (ev.first(), ev.last()) {
        (Some(&lo), Some(&hi)) => Ok((lo, hi)),
        _ => Ok((0.0, 0.0)),
    }
}

/// Relative tolerance on asymmetry used when validating weights: |M − Mᵀ| ≤ tol·max(1, |M|_max).
pub const SYMMETRY_TOL: f64 = 1e-10;

/// Validates a weight matrix: `n × n`, finite, symmetric (to [`SYMMETRY_TOL`] relative)
/// and positive definite. Returns (λ_min, λ_max).
///
/// ```
/// use faer::Mat;
/// let q = Mat::<f64>::identity(3, 3);
/// let (lo, hi) = qp_iter::matrix::check_positive_definite("Q", q.as_ref(), 3).unwrap();
/// assert!((lo - 1.0).abs() < 1e-12 && (hi - 1.0).abs() < 1e-12);
/// ```
pub fn check_positive_definite(name: &str, m: MatRef<'_, f64>, n: usize) -> Result<(f64, f64)> {
    check_shape(name, m, n, n)?;
    check_finite(name, m)?;
    let scale = m.norm_max().max(1.0);
    let asym = asymmetry(m);
    if asym > SYMMETRY_TOL * scale {
        return Err(DataError::NotSymmetric {
            name: name.to_string(),
            asymmetry: asym,
        });
    }
    let (lo, hi) = sym_extreme_eigenvalues(name, m)?;
    if !(lo > 0.0) {
        return Err(DataError::NotPositiveDefinite {
            name: name.to_string(),
            min_eigenvalue: lo,
        });
    }
    Ok((lo, hi))
}

/// The entries of `m` row by row in one vector (the layout of the hot loops' kernels).
///
/// ```
/// let m = faer::mat![[1.0, 2.0], [3.0, 4.0]];
/// assert_eq!(qp_iter::matrix::row_major(m.as_ref()), vec![1.0, 2.0, 3.0, 4.0]);
/// ```
pub fn row_major(m: MatRef<'_, f64>) -> Vec<f64> {
    let (r, c) = (m.nrows(), m.ncols());
    (0..r * c).map(|k| m[(k / c, k % c)]).collect()
}
