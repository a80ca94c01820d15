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
    /// Per row, max_{s<S} of the row's value at t = M + s under the worst admissible
    /// realization for that row and step ([`Attained`]): a lower bound on the true worst case.
    pub attained: Vec<Attained>,
}

/// A value of one full-window row that an admissible realization reaches (module docs).
///
/// At t = M + s the row is g·υ + Σ_{k<s} c𝔸^k𝔹_w w_{t−1−k} with g = c𝔸^s𝕄; choosing x₀ − x₀ⁿᵒᵐ
/// along ±(g_x + g_p), the prior error along ±g_p, each w_j on the face of the disturbance set
/// that maximises ±g_{w_j}·w_j and each later w the same way (the sign that of the nominal
/// value) makes every term add up: the value is |g_nom| + r_x‖g_x + g_p‖ + r_e‖g_p‖ +
/// w̄Σ_j‖g_{w_j}‖_* + w̄Σ_{k<s}‖c𝔸^k𝔹_w‖_*, exactly. Every such realization lies in the user's
/// set, so if the value exceeds the row's bound, the linear loop leaves the row's bound at t —
/// and the real loop, which equals the linear one until a first row activates (Lemma R1),
/// activates a constraint at t or before: no region on which no constraint is active can
/// contain the user's set at this K.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Attained {
    /// The value.
    pub value: f64,
    /// s = t − M.
    pub step: usize,
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
    let mut attained = vec![Attained::default(); rows];
    // Σ_{k<s}‖c𝔸^k𝔹_w‖_* per row: the forced response's worst case at t = M + s.
    let mut forced = vec![0.0; rows];
    let mut m = model.start_map.clone();
    let mut ab = model.bw.clone();
    for s in 0..steps {
        let mut i = 0;
        for b in &model.rows.blocks {
            let g = b * &m;
            let gb = b * &ab;
            for r in 0..g.nrows() {
                let gx = |j: usize| g[(r, j)] + g[(r, nx + j)];
                let center: f64 = (0..nx).map(|j| gx(j) * o.x0_nominal[j]).sum();
                let (cx, cp) = (seg(gx, 0, nx), seg(|j| g[(r, j)], nx, nx));
                let wsum: f64 = (0..big_m)
                    .map(|t| o.w_support(|j| g[(r, j)], 2 * nx + t * nw, nw))
                    .sum();
                nominal[i] = f64::max(nominal[i], center.abs());
                x[i] = f64::max(x[i], cx);
                p[i] = f64::max(p[i], cp);
                w[i] = f64::max(w[i], wsum);
                let value = center.abs()
                    + o.x0_radius * cx
                    + o.prior_error * cp
                    + o.w_bar * (wsum + forced[i]);
                if value > attained[i].value {
                    attained[i] = Attained { value, step: s };
                }
                forced[i] += o.w_support(|j| gb[(r, j)], 0, nw);
                i += 1;
            }
        }
        m = &model.a * &m;
        ab = &model.a * &ab;
    }
    FreeReach {
        steps,
        nominal,
        x,
        p,
        w,
        shifted: m,
        attained,
    }
}
