//! K iterations of Φ on one window: load θ, warm-start from z⁰, step K times, return zᴷ.
//!
//! Each function repeats the portable path of `qp_iter` (`kernel/portable.rs` and the maps'
//! `load`/`warm_start`/`step`/`iterate`) operation for operation; a change there must be
//! mirrored here and in the exported C (`xtask/src/export/c/mhe.c`), and the equivalence
//! tests fail until it is.

use crate::data::{Method, Window};
use crate::scalar::{Scalar, clamp};

/// Slots of the work vectors.
const Z: usize = 0;
const Q: usize = 2;
/// Number of work vectors.
pub(crate) const SLOTS: usize = 6;

/// y[..n] = Hx for H stored by columns (j·n + i): y = Σⱼ xⱼ H[:, j], each row summed from
/// 0 in column order, as `qp_iter::kernel::portable::matvec_columns`.
#[inline]
fn matvec<S: Scalar>(h: &[S], n: usize, x: &[S], y: &mut [S]) {
    let y = &mut y[..n];
    for yi in y.iter_mut() {
        *yi = S::ZERO;
    }
    for (col, &xj) in h.chunks_exact(n).zip(&x[..n]) {
        for (yi, &c) in y.iter_mut().zip(col) {
            *yi = *yi + c * xj;
        }
    }
}

/// y[..n] = Hx: the dense H, or the window's structured product (on the scaled problem
/// D H_c D, as the std map's `DiagonalScaled` operator) with `wa`, `wb` as its workspaces.
#[inline]
fn hessian<S: Scalar>(w: &Window<'_, S>, x: &[S], y: &mut [S], wa: &mut [S], wb: &mut [S]) {
    match w.structured {
        Some(st) => st.apply(w.scaling, x, y, wa, wb),
        None => matvec(w.h, w.n, x, y),
    }
}

/// q = q₀ + Fθ, each row summed from q₀ᵢ in θ order (`ParametricQp::linear_term`).
#[inline]
fn linear_term<S: Scalar>(w: &Window<'_, S>, theta: &[S], q: &mut [S]) {
    let nt = w.n_theta;
    for i in 0..w.n {
        let mut acc = w.q0[i];
        for (a, b) in w.f[i * nt..(i + 1) * nt].iter().zip(theta) {
            acc = acc + *a * *b;
        }
        q[i] = acc;
    }
}

/// Runs K iterations of `method` on window `w` for θ from z⁰ (in z; `None`: the cold
/// start Π_Z(0), as the std maps' `cold_start`) and writes zᴷ (in z) into `out[..n]`.
/// `v` holds the [`SLOTS`] work vectors, each of length ≥ n (slices, so the const-size
/// estimators and the runtime-size one share this one sequence of operations).
pub(crate) fn run<S: Scalar>(
    method: Method,
    w: &Window<'_, S>,
    theta: &[S],
    z0: Option<&[S]>,
    iterations: usize,
    mut v: [&mut [S]; SLOTS],
    out: &mut [S],
) {
    let n = w.n;
    if n == 0 {
        return;
    }
    let (lo, hi) = (w.lower, w.upper);
    // load: q = q₀ + Fθ (the scaled problem's F and q₀ give D q directly).
    linear_term(w, theta, v[Q]);
    // warm start: y⁰ = D⁻¹z⁰ on a scaled problem; cold start: Π(0) in the coordinates
    // the method runs in (the box of the scaled problem when scaled).
    match z0 {
        None => {
            for i in 0..n {
                v[Z][i] = clamp(S::ZERO, lo[i], hi[i]);
            }
        }
        Some(z0) if w.scaling.is_empty() => v[Z][..n].copy_from_slice(&z0[..n]),
        Some(z0) => {
            for i in 0..n {
                v[Z][i] = z0[i] / w.scaling[i];
            }
        }
    }
    match method {
        Method::Pg => {
            let [z, wa, q, wb, hz, _] = &mut v;
            for _ in 0..iterations {
                hessian(w, z, hz, wa, wb);
                for i in 0..n {
                    let x = z[i] - w.step * (hz[i] + q[i]);
                    z[i] = clamp(x, lo[i], hi[i]);
                }
            }
        }
        Method::Fista => {
            let [z, y, q, wa, hy, wb] = &mut v;
            y[..n].copy_from_slice(&z[..n]);
            for k in 0..iterations {
                // The first step after a warm start is the plain PG step (β = 0).
                let b = if k == 0 { S::ZERO } else { w.momentum };
                hessian(w, y, hy, wa, wb);
                if w.structured.is_some() {
                    // The std map's structured branch writes the momentum step as
                    // y⁺ = (1 + β)x⁺ − βx (the dense kernel as x⁺ + β(x⁺ − x)).
                    let b1 = S::ONE + b;
                    for i in 0..n {
                        let x = clamp(y[i] - w.step * (hy[i] + q[i]), lo[i], hi[i]);
                        y[i] = b1 * x - b * z[i];
                        z[i] = x;
                    }
                } else {
                    for i in 0..n {
                        let x = clamp(y[i] - w.step * (hy[i] + q[i]), lo[i], hi[i]);
                        y[i] = x + b * (x - z[i]);
                        z[i] = x;
                    }
                }
            }
        }
        Method::Admm => {
            let [z, s, q, mq, t, y] = &mut v;
            matvec(w.m_inv, n, q, mq);
            // Gradient dual y⁰ = −(Hz⁰ + q), s = z⁰ + y⁰/ρ, t = 2Π(s) − s.
            matvec(w.h, n, z, y);
            for i in 0..n {
                y[i] = -(y[i] + q[i]);
            }
            for i in 0..n {
                s[i] = z[i] + w.inv_rho * y[i];
                t[i] = S::TWO * clamp(s[i], lo[i], hi[i]) - s[i];
            }
            let a = w.relaxation;
            for _ in 0..iterations {
                matvec(w.m_rho, n, t, z);
                for i in 0..n {
                    z[i] = z[i] - mq[i];
                    let vv = clamp(s[i], lo[i], hi[i]);
                    let ww = a * z[i] + (s[i] - a * vv);
                    t[i] = S::TWO * clamp(ww, lo[i], hi[i]) - ww;
                    s[i] = ww;
                }
            }
            // The iterate is v = Π(s).
            for i in 0..n {
                z[i] = clamp(s[i], lo[i], hi[i]);
            }
        }
    }
    // The iterate in z = D y.
    let z = &v[Z];
    if w.scaling.is_empty() {
        out[..n].copy_from_slice(&z[..n]);
    } else {
        for i in 0..n {
            out[i] = w.scaling[i] * z[i];
        }
    }
}
