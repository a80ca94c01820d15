//! Hand-off of the propagated start-up to Theorem R at t = T (docs/theory.md, "Regional ISS
//! with an active start-up", step 3).
//!
//! X_T is a zonotope c + Gε (the start-up's forms placed in the lifted layout). From T on,
//! while no row is active the loop is X_{t+1} = 𝔸X_t + 𝔹_w w_t (Lemma R1), so at t = T + s a
//! row is c_i𝔸^sX_T + Σ_{k<s}c_i𝔸^k𝔹_w w_{t−1−k}. For s < S its range over the set is exact:
//! the zonotope's interval of c_i𝔸^sX_T widened by Σ_{k<s}‖c_i𝔸^k𝔹_w‖_* (each w in the
//! noise set, independent). For s ≥ S, in a Stein metric P with λ = ‖P^½𝔸P^{−½}‖ < 1:
//! |c_i𝔸^sX_T| ≤ n_i‖P^½𝔸^SX_T‖ ≤ n_i(‖P^½𝔸^Sc‖ + Σ_balls r‖P^½𝔸^SG_ball‖_F +
//! Σ_intervals ‖P^½𝔸^Sg_j‖) and the forced part is at most Σ_{k<S}‖c_i𝔸^k𝔹_w‖_* +
//! n_i b w̄ λ^S/(1 − λ) — Theorem R with 𝕄υ replaced by the zonotope. If every row stays in
//! its bounds at every s, induction on s (as in Theorem R's proof) shows no constraint is
//! active from T on and the loop is linear, ISS with rate λ.

use faer::Mat;

use super::lifted::RegionalModel;
use super::metric::{metric, stein};
use super::model::{ModelError, RowLabel};
use super::startup::WSet;
use super::zonotope::Space;

/// The row that binds (the largest value/bound ratio) and the verdict.
#[derive(Debug, Clone)]
pub(crate) struct HandOff {
    /// Every row within its bounds from T on.
    pub holds: bool,
    /// The binding row, its step s after T (None: the metric's tail beyond S), its reach and
    /// the bound on that side.
    pub binding: RowLabel,
    pub at: Option<usize>,
    pub reach: f64,
    pub bound: f64,
    /// λ of the metric used for the tail.
    pub lambda: f64,
}

fn dual(w: &WSet, g: impl Fn(usize) -> f64, nw: usize) -> f64 {
    match w {
        WSet::Box(h) => (0..nw).map(|j| g(j).abs() * h[j]).sum(),
        WSet::Ball(r) => r * (0..nw).map(|j| g(j) * g(j)).sum::<f64>().sqrt(),
    }
}

/// The ball radius containing the per-step noise set (w̄).
fn w_bar(w: &WSet) -> f64 {
    match w {
        WSet::Box(h) => h.iter().map(|x| x * x).sum::<f64>().sqrt(),
        WSet::Ball(r) => *r,
    }
}

/// Checks every full-window row of `model` from X_T (`x_t`, a form over `space`) on:
/// `exact` steps exactly, the rest by the metric at rate μ = ρ + f(1 − ρ).
pub(crate) fn hand_off(
    model: &RegionalModel,
    space: &Space,
    x_t: &Mat<f64>,
    w: &WSet,
    exact: usize,
    rho: f64,
) -> Result<HandOff, ModelError> {
    let rows = model.rows.to_vecs();
    if rows.is_empty() {
        return Err(ModelError::NotCovered(
            "no constraint row to hand off".into(),
        ));
    }
    if !(rho < 1.0) {
        return Err(ModelError::NotCovered(format!(
            "ρ_lin = {rho:.6} ≥ 1: the full-window loop is not stable at this K"
        )));
    }
    let (n, nw) = (model.a.nrows(), model.bw.ncols());
    let mu = rho + 0.25 * (1.0 - rho);
    let p = stein(model.a.as_ref(), mu)
        .ok_or_else(|| ModelError::NotCovered("the Stein metric did not converge".into()))?;
    let mt = metric(p.as_ref())
        .ok_or_else(|| ModelError::NotCovered("the Stein metric is ill conditioned".into()))?;
    let pa = &mt.half * &model.a * &mt.neg_half;
    let lambda = pa.singular_values().ok().map_or(f64::INFINITY, |s| s[0]);
    if !(lambda < 1.0) {
        return Err(ModelError::NotCovered(format!(
            "the metric's rate λ = {lambda:.6} is not below 1"
        )));
    }
    let pb = &mt.half * &model.bw;
    let b = pb.singular_values().ok().map_or(f64::INFINITY, |s| s[0]);
    let x = space.widen(x_t.as_ref());
    let nr = rows.len();
    let c = Mat::from_fn(nr, n, |i, j| rows[i][j]);
    let mut y = x.clone(); // 𝔸^s X_T
    let mut bs = model.bw.clone(); // 𝔸^s 𝔹_w
    let mut forced = vec![0.0; nr]; // Σ_{k<s}‖c_i𝔸^k𝔹_w‖_*
    let mut worst = (0usize, Some(0usize), 0.0_f64, 1.0_f64, f64::NEG_INFINITY);
    fn note(
        worst: &mut (usize, Option<usize>, f64, f64, f64),
        (i, at, reach, bound): (usize, Option<usize>, f64, f64),
    ) {
        let ratio = reach / bound;
        if ratio > worst.4 {
            *worst = (i, at, reach, bound, ratio);
        }
    }
    let (lower, upper) = (&model.rows.lower, &model.rows.upper);
    for s_done in 0..exact {
        let v = &c * &y;
        let cb = &c * &bs;
        for i in 0..nr {
            let (lo, hi) = space.interval(v.as_ref(), i);
            let (lo, hi) = (lo - forced[i], hi + forced[i]);
            if upper[i].is_finite() {
                note(&mut worst, (i, Some(s_done), hi, upper[i]));
            }
            if lower[i].is_finite() {
                note(&mut worst, (i, Some(s_done), -lo, -lower[i]));
            }
            forced[i] += dual(w, |j| cb[(i, j)], nw);
        }
        y = &model.a * &y;
        bs = &model.a * &bs;
        if worst.4 > 1.0 {
            // A row leaves its bounds over the set: this T does not hand off.
            break;
        }
    }
    // Tail: ‖P^½𝔸^S X_T‖ bounded over the zonotope (balls by Frobenius, a sound bound).
    if worst.4 > 1.0 {
        let (i, at, reach, bound, _) = worst;
        return Ok(HandOff {
            holds: false,
            binding: model.rows.labels[i],
            at,
            reach,
            bound,
            lambda,
        });
    }
    let px = &mt.half * &y;
    let col = |j: usize| (0..n).map(|i| px[(i, j)] * px[(i, j)]).sum::<f64>();
    let mut r = col(0).sqrt();
    let mut in_ball = vec![false; space.count()];
    for &(first, len, radius) in space.balls() {
        r += radius * (first..first + len).map(|j| col(1 + j)).sum::<f64>().sqrt();
        in_ball[first..first + len]
            .iter_mut()
            .for_each(|b| *b = true);
    }
    r += (0..space.count())
        .filter(|&j| !in_ball[j])
        .map(|j| col(1 + j).sqrt())
        .sum::<f64>();
    let tail_w =
        b * w_bar(w) * lambda.powi(i32::try_from(exact).unwrap_or(i32::MAX)) / (1.0 - lambda);
    let cn = &c * &mt.neg_half;
    for i in 0..nr {
        let ni = (0..n).map(|j| cn[(i, j)] * cn[(i, j)]).sum::<f64>().sqrt();
        let reach = ni * (r + tail_w) + forced[i];
        note(&mut worst, (i, None, reach, upper[i].min(-lower[i])));
    }
    let (i, at, reach, bound, ratio) = worst;
    Ok(HandOff {
        holds: ratio <= 1.0,
        binding: model.rows.labels[i],
        at,
        reach,
        bound,
        lambda,
    })
}
