//! Quadratic Lyapunov metrics of the lifted matrix and their square roots.

use faer::{Mat, MatRef, Side};

/// P^{±½} of a symmetric positive definite P (None unless finite and well conditioned).
#[derive(Debug, Clone)]
pub(crate) struct Metric {
    pub half: Mat<f64>,
    pub neg_half: Mat<f64>,
}

pub(crate) fn metric(p: MatRef<'_, f64>) -> Option<Metric> {
    let evd = lti_model::matrix::symmetrize(p)
        .self_adjoint_eigen(Side::Lower)
        .ok()?;
    let (u, d) = (evd.U(), evd.S().column_vector());
    let n = p.nrows();
    let lmin = (0..n).map(|i| d[i]).fold(f64::INFINITY, f64::min);
    let lmax = (0..n).map(|i| d[i]).fold(0.0, f64::max);
    if !(lmin > 1e-13 * lmax) || !lmax.is_finite() {
        return None;
    }
    let build = |e: f64| {
        let scaled = Mat::from_fn(n, n, |i, k| u[(i, k)] * d[k].powf(e));
        &scaled * u.transpose()
    };
    Some(Metric {
        half: build(0.5),
        neg_half: build(-0.5),
    })
}

/// P = Σ_k (Aᵀ/λ)ᵏ(A/λ)ᵏ, the solution of (A/λ)ᵀP(A/λ) − P + I = 0, by doubling
/// (P ← P + A_jᵀPA_j, A_j ← A_j²); None unless ρ(A) < λ numerically (the series converges).
/// In its metric ‖A‖_P ≤ λ√(1 − 1/λ̄(P)) < λ.
pub(crate) fn stein(a: MatRef<'_, f64>, lambda: f64) -> Option<Mat<f64>> {
    let n = a.nrows();
    let mut ak = a * faer::Scale(1.0 / lambda);
    let mut p = Mat::<f64>::identity(n, n);
    for _ in 0..64 {
        let add = ak.transpose() * &p * &ak;
        p += &add;
        let size = ak.norm_max();
        if !size.is_finite() || !p.norm_max().is_finite() || size > 1e150 {
            return None;
        }
        if size < 1e-14 {
            return Some(lti_model::matrix::symmetrize(p.as_ref()));
        }
        ak = &ak * &ak;
    }
    None
}
