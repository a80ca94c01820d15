//! Slice math shared by every crate: Euclidean norms and distances of plain `&[f64]`
//! vectors (the one copy; summation in index order, so results are reproducible bit for
//! bit). Matrices as row-major vectors: [`crate::matrix::row_major`].

/// ‖v‖₂.
///
/// ```
/// assert_eq!(lti_model::vecmath::norm2(&[3.0, 4.0]), 5.0);
/// ```
#[inline]
pub fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// ‖a − b‖₂ over the common length.
///
/// ```
/// assert_eq!(lti_model::vecmath::dist2(&[1.0, 1.0], &[4.0, 5.0]), 5.0);
/// ```
#[inline]
pub fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}
