//! The rounding floor of the trajectory checks: how far below which a measured ε_t or e_t is
//! floating-point rounding, not a quantity the certificate's right-hand side can bound.
//!
//! ε_t = ‖zᴷ_t − z*_t‖ is the difference of two computed vectors: zᴷ_t after K applications
//! of the iteration map (each a matrix–vector product with inner products of length n_z),
//! z*_t from the exact solve (a factorisation whose entries are inner products of length at
//! most n_z, n_z of them). Every entry of each is thus the result of at most
//! N_t = (K + n_z)·n_z multiply–adds, and Higham's bound for such a computation
//! (Accuracy and Stability of Numerical Algorithms, §3.1) is γ_N = N·u/(1 − N·u) relative to
//! the magnitudes involved, u = 2⁻⁵³. The floor of ε_t is therefore
//!
//! floor_ε(t) = γ_{N_t}·(‖zᴷ_t‖ + ‖z*_t‖),
//!
//! and the floor of ‖e_t‖ = ‖x_t − x̂_t‖ (x̂_t from zᴷ_t through M_t propagation steps, each
//! with inner products of length n_x + n_u + n_w) is
//!
//! floor_e(t) = γ_{N_t + M_t(n_x + n_u + n_w)}·(‖x_t‖ + ‖x̂_t‖).
//!
//! These are worst-case bounds, independent of the conditioning of the QP (a measured ε_t
//! below them is indistinguishable from 0). The checks pass `lhs ≤ rhs + floor` and count the
//! steps that needed the floor; `lhs > rhs + floor` is a contradiction.

use closed_loop::record::Trace;

/// Unit round-off of f64, u = 2⁻⁵³.
pub const UNIT_ROUNDOFF: f64 = f64::EPSILON / 2.0;

/// γ_n = n·u/(1 − n·u) (∞ when n·u ≥ 1).
///
/// ```
/// use iss_certificate::certificate::gamma_n;
/// assert!((gamma_n(1000) - 1000.0 * 2f64.powi(-53)).abs() < 1e-25);
/// assert_eq!(gamma_n(usize::MAX), f64::INFINITY);
/// ```
pub fn gamma_n(n: usize) -> f64 {
    let nu = n as f64 * UNIT_ROUNDOFF;
    if nu >= 1.0 {
        f64::INFINITY
    } else {
        nu / (1.0 - nu)
    }
}

fn norm_of(parts: &[&[f64]]) -> f64 {
    parts
        .iter()
        .flat_map(|p| p.iter())
        .map(|v| v * v)
        .sum::<f64>()
        .sqrt()
}

/// (floor_ε(t), floor_e(t)) of the module docs for step `t` of `trace` at K = `k`
/// iterations; (0, 0) when the step has no MHE record with the exact solve.
pub fn rounding_floor(trace: &Trace, t: usize, k: usize) -> (f64, f64) {
    let Some(step) = trace.mhe_step(t) else {
        return (0.0, 0.0);
    };
    let (Some(xs), Some(ws)) = (step.x_start_exact(), step.w_exact_flat()) else {
        return (0.0, 0.0);
    };
    let (xk, wk) = (step.x_start_k(), step.w_k_flat());
    let n_z = xk.len() + wk.len();
    let n = (k + n_z).saturating_mul(n_z);
    let floor_eps = gamma_n(n) * (norm_of(&[xk, wk]) + norm_of(&[xs, ws]));
    let (nx, nu, _, _) = trace.dims();
    let per_stage = nx + nu + wk.len() / step.window().max(1);
    let n_e = n.saturating_add(step.window().saturating_mul(per_stage));
    let x = trace.x(t).map_or(0.0, |v| norm_of(&[v]));
    let xh = trace.x_hat(t).map_or(0.0, |v| norm_of(&[v]));
    (floor_eps, gamma_n(n_e) * (x + xh))
}
