//! The free response's exact reach on every full-window row (Theorem R, step 2 of
//! `docs/theory.md`).
//!
//! For t ≥ M and while no row is active, X_t = 𝔸^s X_M + X_t^w with s = t − M and
//! X_M = 𝕄υ. Over the user's set — υ = υ₀ + (δ, δ + ε, w₀, …, w_{M−1}) with υ₀ = (x̂₀, x̂₀, 0),
//! ‖δ‖ ≤ r_x, ‖ε‖ ≤ r_e, ‖w_j‖ ≤ w̄ — the free part of row c at step s is exactly
//! |c𝔸^s𝕄υ₀| + r_x‖g_x‖ + r_e‖g_p‖ + w̄Σ_j‖g_{w_j}‖_* in its worst case, with g = c𝔸^s𝕄 split by
//! υ's blocks (g_x the sum of the x₀ and x̄₀ blocks) and ‖·‖_* the dual norm of one step's
//! disturbance set (`RegionalOptions::w_support`: the box's weighted ℓ₁ or the ball's ℓ₂). This module takes those four numbers at
//! every s < S and keeps, per row, the largest of each. Beyond S the metric bounds the rest:
//! |c𝔸^s X_M| ≤ ‖P^{−½}cᵀ‖·‖P^{½}𝔸^S X_M‖ for s ≥ S, so [`FreeReach::shifted`] = 𝔸^S𝕄 is
//! kept for the candidate metrics (`evaluate` in `mod.rs`).
//!
//! Against the metric bound alone (‖P^{−½}cᵀ‖·‖X_M‖_P at every s), which the Cauchy–Schwarz
//! step loosens by up to the metric's condition number, this is the linear loop's own worst
//! case up to one step: the four maxima may be reached at different s.

use faer::Mat;

use super::RegionalOptions;
use super::lifted::RegionalModel;

/// Per full-window row, the largest value over s < S of each part of the free response.
pub(crate) struct FreeReach {
    /// S: the steps taken exactly.
    pub steps: usize,
    /// max_s |c𝔸^s𝕄υ₀|: the nominal x₀ with an exact prior.
    pub nominal: Vec<f64>,
    /// max_s ‖g_x‖ (per unit of x0_radius).
    pub x: Vec<f64>,
    /// max_s ‖g_p‖ (per unit of prior_error).
    pub p: Vec<f64>,
    /// max_s Σ_j‖g_{w_j}‖ (per unit of w̄ in the first M steps).
    pub w: Vec<f64>,
    /// 𝔸^S𝕄, for the metric's bound on s ≥ S.
    pub shifted: Mat<f64>,
}

fn seg(g: impl Fn(usize) -> f64, from: usize, len: usize) -> f64 {
    (from..from + len).map(|j| g(j).powi(2)).sum::<f64>().sqrt()
}

/// The exact reach of the free response over S steps (module docs).
pub(crate) fn free_reach(model: &RegionalModel, o: &RegionalOptions, steps: usize) -> FreeReach {
    let (nx, nw) = (model.nx, model.nw);
    let big_m = model.layout.horizon;
    let rows = model.rows.labels.len();
    let (mut nominal, mut x, mut p, mut w) = (
        vec![0.0; rows],
        vec![0.0; rows],
        vec![0.0; rows],
        vec![0.0; rows],
    );
    let mut m = model.start_map.clone();
    for _ in 0..steps {
        let mut i = 0;
        for b in &model.rows.blocks {
            let g = b * &m;
            for r in 0..g.nrows() {
                let gx = |j: usize| g[(r, j)] + g[(r, nx + j)];
                let center: f64 = (0..nx).map(|j| gx(j) * o.x0_nominal[j]).sum();
                nominal[i] = f64::max(nominal[i], center.abs());
                x[i] = f64::max(x[i], seg(gx, 0, nx));
                p[i] = f64::max(p[i], seg(|j| g[(r, j)], nx, nx));
                let wsum: f64 = (0..big_m)
                    .map(|t| o.w_support(|j| g[(r, j)], 2 * nx + t * nw, nw))
                    .sum();
                w[i] = f64::max(w[i], wsum);
                i += 1;
            }
        }
        m = &model.a * &m;
    }
    FreeReach {
        steps,
        nominal,
        x,
        p,
        w,
        shifted: m,
    }
}
