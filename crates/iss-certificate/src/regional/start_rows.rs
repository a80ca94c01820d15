//! The start-up rows over the user's set (x0_radius, prior_error, w̄ scale linearly in them):
//! the rows free of K checked once before any K ([`k_free_check`]), and the start-up check and
//! witness every K's certificate reuses.

#[cfg(feature = "serde")]
use serde::Serialize;

use super::{Limit, ModelError, RegionalOptions, RegionalVoid, RowLabel, lifted, model, reach};

/// ‖·‖ of a sub-vector of a row.
fn seg(c: &[f64], from: usize, len: usize) -> f64 {
    c[from..from + len]
        .iter()
        .map(|v| v * v)
        .sum::<f64>()
        .sqrt()
}

/// The start-up rows' linear data: for each row (center, coefficient of x0_radius, of
/// prior_error, of w̄, bound on the side that binds).
pub(super) fn startup_terms(
    rows: &model::Rows,
    (nx, nw, big_m): (usize, usize, usize),
    o: &RegionalOptions,
) -> Vec<(f64, f64, f64, f64, f64, f64)> {
    let mut out = Vec::with_capacity(rows.labels.len());
    let mut i = 0;
    for b in &rows.blocks {
        for r in 0..b.nrows() {
            let c: Vec<f64> = (0..b.ncols()).map(|j| b[(r, j)]).collect();
            let (l, u) = (rows.lower[i], rows.upper[i]);
            i += 1;
            let cxp: Vec<f64> = (0..nx).map(|k| c[k] + c[nx + k]).collect();
            let center: f64 = cxp.iter().zip(&o.x0_nominal).map(|(a, b)| a * b).sum();
            let ax = cxp.iter().map(|v| v * v).sum::<f64>().sqrt();
            let ap = seg(&c, nx, nx);
            let aw: f64 = (0..big_m)
                .map(|t| o.w_support(|j| c[j], 2 * nx + t * nw, nw))
                .sum();
            out.push((center, ax, ap, aw, l, u));
        }
    }
    out
}

/// The start-up rows over the user's set: whether all hold, the largest scale of the set that
/// keeps them within their bounds with its binding row, and the largest single radius (the
/// other two at the user's values).
pub(super) struct StartupCheck {
    pub(super) holds: bool,
    pub(super) scale: f64,
    pub(super) limit: Option<Limit>,
    pub(super) max_x: f64,
    pub(super) max_p: f64,
    pub(super) max_w: f64,
}

pub(super) fn startup_check(
    rows: &model::Rows,
    terms: &[(f64, f64, f64, f64, f64, f64)],
    o: &RegionalOptions,
) -> StartupCheck {
    let mut c = StartupCheck {
        holds: true,
        scale: f64::INFINITY,
        limit: None,
        max_x: f64::INFINITY,
        max_p: f64::INFINITY,
        max_w: f64::INFINITY,
    };
    for (i, &(center, ax, ap, aw, l, u)) in terms.iter().enumerate() {
        let dev = o.x0_radius * ax + o.prior_error * ap + o.w_bar * aw;
        let s = scale_limit(center, dev, l, u);
        if center + dev > u || center - dev < l {
            c.holds = false;
        }
        let slack = (u - center).min(center - l);
        // The largest radius with coefficient a, the rest of the set fixed: a row that does
        // not depend on it (a = 0) limits nothing if it holds and everything if it does not.
        let one = |a: f64, rest: f64| {
            if slack < 0.0 {
                f64::NEG_INFINITY
            } else {
                reach::ratio_limit(slack - rest, a)
            }
        };
        c.max_x = c.max_x.min(one(ax, o.prior_error * ap + o.w_bar * aw));
        c.max_p = c.max_p.min(one(ap, o.x0_radius * ax + o.w_bar * aw));
        c.max_w = c.max_w.min(one(aw, o.x0_radius * ax + o.prior_error * ap));
        if s < c.scale {
            c.scale = s;
            let reach = center.abs() + dev;
            let label = rows.labels[i];
            c.limit = Some(Limit {
                row: label,
                bound: if center >= 0.0 { u } else { -l },
                reach,
                attained: reach,
                attained_at: label.step.unwrap_or(0),
            });
        }
    }
    c
}

/// What the rows free of K (t = 0, the MHE's first inner iterates at t = 1) allow at any K:
/// no K's region can contain a set beyond these (necessary, not sufficient).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct KFreeLimits {
    /// The largest factor s such that (s·x0_radius, s·prior_error, s·w̄) keeps every row free
    /// of K within its bound (∞: any; 0: the nominal point alone passes one).
    pub scale: f64,
    /// The largest x0_radius with the user's prior_error and w̄ (0: none).
    pub max_x0_radius: f64,
    /// The largest prior_error with the user's x0_radius and w̄.
    pub max_prior_error: f64,
    /// The largest w̄ with the user's x0_radius and prior_error.
    pub max_w_bar: f64,
}

/// The start-up row accepted by `keep` that an admissible realization drives past its bound by
/// the largest factor, from the start-up rows' terms.
pub(super) fn start_witness(
    rows: &model::Rows,
    terms: &[(f64, f64, f64, f64, f64, f64)],
    o: &RegionalOptions,
    keep: impl Fn(&RowLabel) -> bool,
) -> Option<Limit> {
    let mut at_start: Option<Limit> = None;
    for (i, &(center, ax, ap, aw, l, u)) in terms.iter().enumerate() {
        let label = rows.labels[i];
        let dev = o.x0_radius * ax + o.prior_error * ap + o.w_bar * aw;
        if !keep(&label) || !(center + dev > u || center - dev < l) {
            continue;
        }
        // The side an admissible realization passes by the larger factor.
        let (value, bound) = if (center + dev) / u.abs() >= (dev - center) / l.abs() {
            (center + dev, u)
        } else {
            (dev - center, -l)
        };
        if at_start
            .as_ref()
            .is_none_or(|a| value / bound > a.attained / a.bound)
        {
            at_start = Some(Limit {
                row: label,
                bound,
                reach: value,
                attained: value,
                attained_at: label.step.unwrap_or(0),
            });
        }
    }
    at_start
}

/// The rows that do not depend on K (`lifted::k_free_rows`: step 0, and the MHE's first inner
/// iterates at step 1), built at `k` = the first K the method admits, over the user's set: the
/// witness among them (it refutes every K) and the largest set they admit ([`KFreeLimits`]).
pub(crate) fn k_free_check(
    pieces: &model::Pieces,
    k: usize,
    o: &RegionalOptions,
) -> Result<(Option<Limit>, KFreeLimits), RegionalVoid> {
    check_nominal(pieces, o)?;
    let rows = lifted::k_free_rows(pieces, k).map_err(ModelError::from)?;
    let d = pieces.windows[0].layout.dims;
    let terms = startup_terms(&rows, (d.nx, d.nw(), pieces.horizon), o);
    let c = startup_check(&rows, &terms, o);
    let clamp = |v: f64| if v.is_nan() { 0.0 } else { v.max(0.0) };
    let limits = KFreeLimits {
        scale: clamp(c.scale),
        max_x0_radius: clamp(c.max_x),
        max_prior_error: clamp(c.max_p),
        max_w_bar: clamp(c.max_w),
    };
    Ok((start_witness(&rows, &terms, o, |_| true), limits))
}

pub(super) fn check_nominal(
    pieces: &model::Pieces,
    o: &RegionalOptions,
) -> Result<(), RegionalVoid> {
    if o.x0_nominal.len() != pieces.a.nrows() {
        return Err(RegionalVoid::Options(format!(
            "x0_nominal has {} entries, the plant {} states",
            o.x0_nominal.len(),
            pieces.a.nrows()
        )));
    }
    Ok(())
}

/// max s ≥ 0 with center ± s·dev inside [l, u] (dev ≥ 0); −∞ if the center is outside.
fn scale_limit(center: f64, dev: f64, l: f64, u: f64) -> f64 {
    let slack = (u - center).min(center - l);
    if slack < 0.0 {
        f64::NEG_INFINITY
    } else if dev > 0.0 {
        slack / dev
    } else {
        f64::INFINITY
    }
}
