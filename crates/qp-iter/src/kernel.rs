//! Dense kernels for the hot loop: y = H x for a small square H stored row-major.
//!
//! This is the single place to optimise per-iteration cost (SIMD with run-time CPU
//! detection); every method's step calls it.

/// y = H x, H n × n row-major in `h` (length n²). Allocation-free.
#[inline]
pub fn matvec(h: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
    debug_assert_eq!(h.len(), n * n);
    debug_assert!(x.len() >= n && y.len() >= n);
    for (i, yi) in y.iter_mut().enumerate().take(n) {
        let row = &h[i * n..(i + 1) * n];
        let mut acc = 0.0;
        for (a, b) in row.iter().zip(x) {
            acc += a * b;
        }
        *yi = acc;
    }
}
