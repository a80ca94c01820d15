//! The free response's exact reach on every full-window row (Theorem R, step 2 of
//! `docs/theory.md`).
//!
//! For t ≥ M and while no row is active, X_t = 𝔸^s X_M + Σ_{k<s}𝔸^k𝔹_w w_{t−1−k} with
//! s = t − M and X_M = 𝕄υ. Over the user's set — υ = υ₀ + (δ, δ + ε, w₀, …, w_{M−1}) with
//! υ₀ = (x̂₀, x̂₀, 0), ‖δ‖ ≤ r_x, ‖ε‖ ≤ r_e, every w in w̄𝒟 — row c's worst case at step s is
//! exactly A(s) = |g_nom| + r_x‖g_x + g_p‖ + r_e‖g_p‖ + w̄(Σ_j‖g_{w_j}‖_* + Σ_{k<s}‖c𝔸^k𝔹_w‖_*)
//! with g = c𝔸^s𝕄 split by υ's blocks (g_x the sum of the x₀ and x̄₀ blocks, g_nom = g_x·x̂₀)
//! and ‖·‖_* the dual norm of one step's disturbance set (`RegionalOptions::w_support`). This
//! module takes A(s) at every s < S, with the scales of the set that keep it within the row's
//! bound. Beyond S the metric bounds the rest: |c𝔸^s X_M| ≤ ‖P^{−½}cᵀ‖·‖P^{½}𝔸^S X_M‖ for
//! s ≥ S, so [`FreeReach::shifted`] = 𝔸^S𝕄 is kept for the candidate metrics (`evaluate` in
//! `mod.rs`), and the forced part by its whole sum h̃.
//!
//! Against the metric bound alone (‖P^{−½}cᵀ‖·‖X_M‖_P at every s), which the Cauchy–Schwarz
//! step loosens by up to the metric's condition number, the steps s < S are the linear loop's
//! own worst case.

use faer::Mat;

use super::RegionalOptions;
use super::lifted::RegionalModel;

/// Per full-window row, what the exact steps s < S give: the largest value an admissible
/// realization reaches ([`Attained`], exact: the worst case of each step), and the largest
/// scale of the user's set — together and one radius at a time — that keeps every exact step
/// within the row's bound.
pub(crate) struct FreeReach {
    /// S: the steps taken exactly.
    pub steps: usize,
    /// 𝔸^S𝕄, for the metric's bound on s ≥ S.
    pub shifted: Mat<f64>,
    /// Per row, max_{s<S} A_i(s) (theory.md, Theorem R).
    pub attained: Vec<Attained>,
    /// Per row, the largest σ with A_i(s) at (σr_x, σr_e, σw̄) within the bound for every
    /// s < S (+∞ when S = 0, −∞ when the nominal value alone is beyond it).
    pub scale: Vec<f64>,
    /// Per row, the largest x0_radius (the other two at the user's values) within the bound
    /// at every s < S.
    pub max_x: Vec<f64>,
    /// The same for prior_error.
    pub max_p: Vec<f64>,
    /// The same for w̄.
    pub max_w: Vec<f64>,
}

/// num/den for den > 0; ±∞ by the sign of num otherwise (den = 0: the constraint does not
/// depend on the quantity).
pub(crate) fn ratio_limit(num: f64, den: f64) -> f64 {
    if den > 0.0 {
        num / den
    } else if num >= 0.0 {
        f64::INFINITY
    } else {
        f64::NEG_INFINITY
    }
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

/// The exact reach of the free response over S steps (module docs). The steps stop after the
/// first s at which an admissible realization takes a row past its bound (the witness, see
/// [`Attained`]): the set is then refuted at this K, and the metric bounds the steps after
/// it as it bounds those after S. `FreeReach::steps` is the number taken.
pub(crate) fn free_reach(model: &RegionalModel, o: &RegionalOptions, steps: usize) -> FreeReach {
    let (nx, nw) = (model.nx, model.nw);
    let big_m = model.layout.horizon;
    let rows = model.rows.labels.len();
    let inf = vec![f64::INFINITY; rows];
    let (mut scale, mut max_x, mut max_p, mut max_w) = (inf.clone(), inf.clone(), inf.clone(), inf);
    let mut attained = vec![Attained::default(); rows];
    // Σ_{k<s}‖c𝔸^k𝔹_w‖_* per row: the forced response's worst case at t = M + s.
    let mut forced = vec![0.0; rows];
    let mut m = model.start_map.clone();
    let mut ab = model.bw.clone();
    let mut taken = 0;
    while taken < steps {
        let s = taken;
        let mut refuted = false;
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
                let (c0, cw) = (center.abs(), wsum + forced[i]);
                let dev = o.x0_radius * cx + o.prior_error * cp + o.w_bar * cw;
                let value = c0 + dev;
                if value > attained[i].value {
                    attained[i] = Attained { value, step: s };
                }
                // A_i(s) at a scaled set: c0 + σ·dev ≤ bound, one affine constraint per s.
                let bound = model.rows.upper[i].min(-model.rows.lower[i]);
                refuted |= value > bound;
                let room = bound - c0;
                let limit = |num: f64, den: f64| {
                    if room < 0.0 {
                        f64::NEG_INFINITY
                    } else {
                        ratio_limit(num, den)
                    }
                };
                scale[i] = scale[i].min(limit(room, dev));
                max_x[i] = max_x[i].min(limit(room - o.prior_error * cp - o.w_bar * cw, cx));
                max_p[i] = max_p[i].min(limit(room - o.x0_radius * cx - o.w_bar * cw, cp));
                max_w[i] = max_w[i].min(limit(room - o.x0_radius * cx - o.prior_error * cp, cw));
                forced[i] += o.w_support(|j| gb[(r, j)], 0, nw);
                i += 1;
            }
        }
        m = &model.a * &m;
        ab = &model.a * &ab;
        taken += 1;
        if refuted {
            break;
        }
    }
    FreeReach {
        steps: taken,
        shifted: m,
        attained,
        scale,
        max_x,
        max_p,
        max_w,
    }
}
