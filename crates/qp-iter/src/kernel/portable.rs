//! The portable path: plain Rust on the padded layout, what the baseline target (SSE2)
//! vectorises itself. Each step is the product y = Σⱼ xⱼ H[:, j] into an output buffer,
//! then one row-local loop for the step's update (two passes, where the AVX2 path fuses
//! them into one).

use super::clamp_nan_propagating;

/// y[..ld] = Σⱼ xⱼ h[j ld .. (j+1) ld], j < n (= Hx for H stored by columns with leading
/// dimension ld = [`super::padded_len`]`(n)`, as in [`super::PaddedSymmetric`]):
/// element-wise, so the baseline target vectorises it without reassociating sums.
pub(super) fn matvec_columns(h: &[f64], n: usize, ld: usize, x: &[f64], y: &mut [f64]) {
    let y = &mut y[..ld];
    y.fill(0.0);
    for (col, &xj) in h.chunks_exact(ld).zip(&x[..n]) {
        for (yi, &c) in y.iter_mut().zip(col) {
            *yi += c * xj;
        }
    }
}

/// Projected-gradient step on rows 0 .. ld (ld as in [`matvec_columns`]).
pub(super) fn pg_step(
    h: &[f64],
    n: usize,
    ld: usize,
    z: &[f64],
    q: &[f64],
    alpha: f64,
    lower: &[f64],
    upper: &[f64],
    out: &mut [f64],
) {
    // `out` holds Hz first, then z⁺ row by row.
    matvec_columns(h, n, ld, z, out);
    for i in 0..ld {
        let v = z[i] - alpha * (out[i] + q[i]);
        out[i] = clamp_nan_propagating(v, lower[i], upper[i]);
    }
}

/// FISTA step on rows 0 .. ld.
pub(super) fn fista_step(
    h: &[f64],
    n: usize,
    ld: usize,
    y: &[f64],
    q: &[f64],
    alpha: f64,
    lower: &[f64],
    upper: &[f64],
    beta: f64,
    z: &mut [f64],
    y_next: &mut [f64],
) {
    // `y_next` holds Hy first, then y⁺ row by row.
    matvec_columns(h, n, ld, y, y_next);
    for i in 0..ld {
        let x = clamp_nan_propagating(y[i] - alpha * (y_next[i] + q[i]), lower[i], upper[i]);
        y_next[i] = x + beta * (x - z[i]);
        z[i] = x;
    }
}

/// The ADMM step on the DR variable s (see `Kernel::admm_dr_step_padded`), rows 0 .. ld.
pub(super) fn admm_dr_step(
    m: &[f64],
    n: usize,
    ld: usize,
    t: &[f64],
    mq: &[f64],
    a: f64,
    lower: &[f64],
    upper: &[f64],
    z: &mut [f64],
    s: &mut [f64],
    t_next: &mut [f64],
) {
    // `z` holds Mt first, then Mt − m_q.
    matvec_columns(m, n, ld, t, z);
    for i in 0..ld {
        z[i] -= mq[i];
        let v = clamp_nan_propagating(s[i], lower[i], upper[i]);
        let w = a * z[i] + (s[i] - a * v);
        t_next[i] = 2.0 * clamp_nan_propagating(w, lower[i], upper[i]) - w;
        s[i] = w;
    }
}
