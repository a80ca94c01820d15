//! One candidate metric's certificate (Theorem R of `docs/theory.md`): the impulse response of
//! every row, then per metric the rate, the rows' reach over the user's set (the exact steps of
//! `reach.rs`, the metric beyond), the certified scale and radii, the limiting row and the
//! witness. `mod.rs` picks the best candidate and adds the start-up rows.

use faer::{Mat, MatRef};
use lti_model::matrix::spectral_norm;

use super::lifted::RegionalModel;
use super::model::Rows;
use super::{Limit, RegionalOptions, metric, reach};

fn row_norms(rows: &Rows, neg_half: MatRef<'_, f64>) -> Vec<f64> {
    let mut out = Vec::with_capacity(rows.labels.len());
    for b in &rows.blocks {
        let prod = b * neg_half;
        for i in 0..prod.nrows() {
            out.push(
                (0..prod.ncols())
                    .map(|j| prod[(i, j)].powi(2))
                    .sum::<f64>()
                    .sqrt(),
            );
        }
    }
    out
}

pub(super) struct Candidate {
    /// Largest s with (s·r_x, s·r_e, s·w̄) certified by the full-window rows.
    pub(super) scale: f64,
    /// Largest r_x, r_e, w̄ by the full-window rows (the other two at the user's values).
    pub(super) max_x: f64,
    pub(super) max_p: f64,
    pub(super) max_w: f64,
    pub(super) name: String,
    pub(super) metric: metric::Metric,
    pub(super) x_read_norm: f64,
    pub(super) e_read_norm: f64,
    pub(super) rate: f64,
    pub(super) b: f64,
    pub(super) radius: f64,
    pub(super) limit: Option<Limit>,
    pub(super) nominal: f64,
    pub(super) a_x: f64,
    pub(super) a_p: f64,
    pub(super) a_w: f64,
    pub(super) gain_x: f64,
    pub(super) gain_e: f64,
    /// Per full-window row, its reach over the user's set (see [`RegionalDetail::reach`]).
    pub(super) reach: Vec<f64>,
    /// The full-window row with the largest attained value against its bound.
    pub(super) witness: Option<Limit>,
}

/// The disturbance's exact contribution to every full-window row and readout: with
/// X_t = X_t^{free} + X_t^{w} (superposition, valid while every row is inactive) and
/// X_t^{w} = Σ_{k≥0} 𝔸^k𝔹_w w_{t−1−k}, |cX_t^{w}| ≤ w̄Σ_k‖c𝔸^k𝔹_w‖. The sum is taken to T
/// terms here; [`evaluate`] adds the certified tail ‖cP^{−½}‖bλ^T/(1 − λ).
pub(super) struct Impulse {
    pub(super) terms: i32,
    pub(super) rows: Vec<f64>,
    pub(super) x: f64,
    pub(super) e: f64,
}

pub(super) fn impulse(model: &RegionalModel, t: usize, o: &RegionalOptions) -> Impulse {
    let (n, nw) = (model.a.nrows(), model.bw.ncols());
    let mut ib = Mat::<f64>::zeros(n, nw * t);
    let mut cur = model.bw.clone();
    for k in 0..t {
        for j in 0..nw {
            for i in 0..n {
                ib[(i, k * nw + j)] = cur[(i, j)];
            }
        }
        cur = &model.a * &cur;
    }
    let sum_norms = |prod: &Mat<f64>, i: usize| -> f64 {
        (0..t)
            .map(|k| o.w_support(|j| prod[(i, j)], k * nw, nw))
            .sum()
    };
    let mut rows = Vec::with_capacity(model.rows.labels.len());
    for b in &model.rows.blocks {
        let prod = b * &ib;
        for i in 0..prod.nrows() {
            rows.push(sum_norms(&prod, i));
        }
    }
    let read = |m: &Mat<f64>| -> f64 {
        // ‖·‖₂ of each k-block of m·[𝔹_w, 𝔸𝔹_w, …] (spectral, not row-wise).
        let prod = m * &ib;
        (0..t)
            .map(|k| spectral_norm(prod.as_ref().subcols(k * nw, nw)))
            .sum()
    };
    Impulse {
        terms: t as i32,
        rows,
        x: read(&model.x_read),
        e: read(&model.e_read),
    }
}

/// sup over the user's set of ‖M X‖_P for M = 𝕄 (X_M, reported) or M = 𝔸^S𝕄 (the free
/// response after the S exact steps), as [nominal, a_x, a_p, a_w]: nominal + r_x a_x +
/// r_e a_p + w̄ a_w.
fn set_parts(
    model: &RegionalModel,
    half: faer::MatRef<'_, f64>,
    m: &Mat<f64>,
    o: &RegionalOptions,
) -> [f64; 4] {
    let (nx, nw) = (model.nx, model.nw);
    let pm = half * m;
    let mxp = Mat::from_fn(pm.nrows(), nx, |i, j| pm[(i, j)] + pm[(i, nx + j)]);
    let x0 = Mat::from_fn(nx, 1, |i, _| o.x0_nominal[i]);
    let a_w: f64 = (0..model.layout.horizon)
        .map(|t| spectral_norm(pm.as_ref().subcols(2 * nx + t * nw, nw)))
        .sum();
    [
        spectral_norm((&mxp * &x0).as_ref()),
        spectral_norm(mxp.as_ref()),
        spectral_norm(pm.as_ref().subcols(nx, nx)),
        a_w,
    ]
}

/// Full-window row `i` as a limit: its bound, the reach `reach` and what the exact steps
/// attained there.
fn row_limit(model: &RegionalModel, free: &reach::FreeReach, i: usize, reach: f64) -> Limit {
    let attained = free.attained[i];
    Limit {
        row: model.rows.labels[i],
        bound: model.rows.upper[i].min(-model.rows.lower[i]),
        reach,
        attained: attained.value,
        attained_at: model.layout.horizon + attained.step,
    }
}

pub(super) fn evaluate(
    model: &RegionalModel,
    imp: &Impulse,
    free: &reach::FreeReach,
    p: &metric::Metric,
    name: String,
    o: &RegionalOptions,
) -> Candidate {
    let (half, neg) = (p.half.as_ref(), p.neg_half.as_ref());
    let rate = spectral_norm((half * &model.a * neg).as_ref());
    let b = spectral_norm((half * &model.bw).as_ref());
    let norms = row_norms(&model.rows, neg);
    let tail = if rate < 1.0 {
        b * rate.powi(imp.terms) / (1.0 - rate)
    } else {
        f64::INFINITY
    };
    let parts = |m: &Mat<f64>| set_parts(model, half, m, o);
    let [nominal, a_x, a_p, a_w] = parts(&model.start_map);
    let after = if free.steps == 0 {
        [nominal, a_x, a_p, a_w]
    } else {
        parts(&free.shifted)
    };
    let x_read_norm = spectral_norm((&model.x_read * neg).as_ref());
    let e_read_norm = spectral_norm((&model.e_read * neg).as_ref());
    // Per full-window row: for s < S the exact worst case A_i(s) (reach.rs); for s ≥ S the
    // metric's bound n_c·r(𝔸^S𝕄) plus the disturbance's whole w̄·h̃_c, h̃_c = h_c + n_c·tail.
    let (mut radius, mut scale) = (f64::INFINITY, f64::INFINITY);
    let (mut max_x, mut max_p, mut max_w) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut limit = None;
    let mut reach = vec![0.0; norms.len()];
    let mut witness: Option<(f64, usize)> = None;
    for (i, nc) in norms.iter().enumerate() {
        let bound = model.rows.upper[i].min(-model.rows.lower[i]);
        let h = imp.rows[i] + nc * tail;
        if *nc == 0.0 && h == 0.0 {
            continue;
        }
        let slack = bound - o.w_bar * h;
        radius = radius.min(if *nc > 0.0 {
            slack / nc
        } else if slack >= 0.0 {
            f64::INFINITY
        } else {
            f64::NEG_INFINITY
        });
        let [n_t, x_t, p_t, w_t] = after.map(|a| nc * a);
        let tail_var = o.x0_radius * x_t + o.prior_error * p_t + o.w_bar * (w_t + h);
        let attained = free.attained[i];
        reach[i] = attained.value.max(n_t + tail_var);
        let ratio = attained.value / bound;
        if witness.is_none_or(|(r, _)| ratio > r) {
            witness = Some((ratio, i));
        }
        let room = bound - n_t;
        let tail_limit = |num: f64, den: f64| {
            if room < 0.0 {
                f64::NEG_INFINITY
            } else {
                reach::ratio_limit(num, den)
            }
        };
        let s_i = tail_limit(room, tail_var).min(free.scale[i]);
        if s_i < scale {
            scale = s_i;
            limit = Some(row_limit(model, free, i, reach[i]));
        }
        max_x = max_x
            .min(tail_limit(
                room - o.prior_error * p_t - o.w_bar * (w_t + h),
                x_t,
            ))
            .min(free.max_x[i]);
        max_p = max_p
            .min(tail_limit(
                room - o.x0_radius * x_t - o.w_bar * (w_t + h),
                p_t,
            ))
            .min(free.max_p[i]);
        max_w = max_w
            .min(tail_limit(
                room - o.x0_radius * x_t - o.prior_error * p_t,
                w_t + h,
            ))
            .min(free.max_w[i]);
    }
    Candidate {
        scale,
        max_x,
        max_p,
        max_w,
        name,
        metric: p.clone(),
        x_read_norm,
        e_read_norm,
        rate,
        b,
        radius,
        limit,
        nominal,
        a_x,
        a_p,
        a_w,
        gain_x: imp.x + x_read_norm * tail,
        gain_e: imp.e + e_read_norm * tail,
        witness: witness.map(|(_, i)| row_limit(model, free, i, reach[i])),
        reach,
    }
}

impl Candidate {
    /// Largest s with (s·r_x, s·r_e, s·w̄) certified by the full-window rows.
    pub(super) fn full_scale(&self, _o: &RegionalOptions) -> f64 {
        if self.rate < 1.0 {
            self.scale
        } else {
            f64::NEG_INFINITY
        }
    }
}
