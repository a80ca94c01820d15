//! Per-run metrics of a closed-loop run (the columns of a sweep's `runs.csv` and of
//! [`monte_carlo`](crate::monte_carlo::monte_carlo)), the bounded rule, and quantiles.

use std::str::FromStr;

use crate::record::Trace;
use crate::sim::ClosedLoopError;

/// Default bound factor: a run is *bounded* when it completed and
/// [`crate::bounded::first_unbounded`] finds no failing step (‖x_t‖ ≤ 1000·(1 + ‖x₀‖ + w̄_t),
/// ‖e_t‖ ≤ 1000·(1 + ‖e₀‖ + w̄_t), e₀ = x₀ − x̂₀, ε_t ≤ 1000·(1 + ‖e₀‖ + ε₀ + w̄_t), u finite;
/// w̄_t = max_{s ≤ t} ‖w_s‖, the run's own disturbance).
pub const DEFAULT_BOUNDED_FACTOR: f64 = crate::bounded::DEFAULT_BOUNDED_FACTOR;
/// Quantile levels of `points.csv` (5 %, 50 %, 95 %), next to the maximum.
pub const QUANTILES: [(f64, &str); 3] = [(0.05, "q05"), (0.5, "q50"), (0.95, "q95")];

/// A per-run metric that can be kept (`metrics = [...]` in the config). The identity
/// columns, `bounded`, `error` and `wall_ms` are always written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Metric {
    /// sup_t ‖e_t‖ (`sup_e`).
    SupE,
    /// sup_t ‖x_t‖, x_T included (`sup_x`).
    SupX,
    /// Mean of ‖e_t‖ over the last quarter of the horizon (`tail_mean_e`).
    TailMeanE,
    /// ‖e_{T−1}‖ (`final_e`).
    FinalE,
    /// Mean of ‖x_t‖ over the last quarter (`tail_mean_x`).
    TailMeanX,
    /// ‖x_T‖ (`final_x`).
    FinalX,
    /// sup_t ‖w_t‖ (`sup_w`).
    SupW,
    /// sup_t ε_t (`sup_eps`; needs `exact_mhe_solve = true`).
    SupEps,
    /// sup‖e‖ / sup‖w‖ (`gain_e`; empty when w ≡ 0).
    GainE,
    /// sup‖x‖ / sup‖w‖ (`gain_x`; empty when w ≡ 0).
    GainX,
    /// Last-quarter mean of ‖e_t‖ / sup‖w‖ (`tail_gain_e`): the gain once the initial
    /// error has decayed (sup‖e‖ is usually ‖e₀‖, whatever K).
    TailGainE,
    /// Last-quarter mean of ‖x_t‖ / sup‖w‖ (`tail_gain_x`).
    TailGainX,
    /// Largest violation of the input box 𝒰 by u_t (`input_violation`; 0 expected).
    InputViolation,
    /// Largest violation of Z by the MHE iterate zᴷ_t (`mhe_violation`; 0 for PG/FISTA).
    MheViolation,
}

impl Metric {
    /// Every metric, in column order.
    pub const ALL: [Metric; 14] = [
        Metric::SupE,
        Metric::SupX,
        Metric::TailMeanE,
        Metric::FinalE,
        Metric::TailMeanX,
        Metric::FinalX,
        Metric::SupW,
        Metric::SupEps,
        Metric::GainE,
        Metric::GainX,
        Metric::TailGainE,
        Metric::TailGainX,
        Metric::InputViolation,
        Metric::MheViolation,
    ];

    /// The column name.
    pub fn name(self) -> &'static str {
        match self {
            Metric::SupE => "sup_e",
            Metric::SupX => "sup_x",
            Metric::TailMeanE => "tail_mean_e",
            Metric::FinalE => "final_e",
            Metric::TailMeanX => "tail_mean_x",
            Metric::FinalX => "final_x",
            Metric::SupW => "sup_w",
            Metric::SupEps => "sup_eps",
            Metric::GainE => "gain_e",
            Metric::GainX => "gain_x",
            Metric::TailGainE => "tail_gain_e",
            Metric::TailGainX => "tail_gain_x",
            Metric::InputViolation => "input_violation",
            Metric::MheViolation => "mhe_violation",
        }
    }
}

impl FromStr for Metric {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        Metric::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Metric::ALL.iter().map(|m| m.name()).collect();
                format!("unknown metric `{s}`; use any of {}", names.join(", "))
            })
    }
}

/// What one closed-loop run recorded. Metrics of a run that stopped early (a non-finite
/// signal) are +∞ for the norms and gains (it diverged), and `error` says why.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RunMetrics {
    /// Run index r (0-based) at its point.
    pub run: usize,
    /// The disturbance seed of the run (a sweep's `run_seed`, or [`monte_carlo_seed`](crate::monte_carlo::monte_carlo_seed)).
    pub seed: u64,
    /// Steps completed (T unless the run stopped).
    pub steps: usize,
    /// Values of [`Metric::ALL`], in that order (`None` = not available, an empty cell).
    pub values: [Option<f64>; 14],
    /// Completed and within the bounded rule ([`crate::bounded`]): sup‖x‖ ≤
    /// bounded_factor·(1 + ‖x₀‖), sup‖e‖ ≤ bounded_factor·(1 + ‖e₀‖), ε and u likewise.
    pub bounded: bool,
    /// Bounded, and over the last quarter the errors and states are back at the
    /// disturbance level ([`converged`]): what "stable" looks like in a run, which
    /// `bounded` alone does not say (a saturated loop can stay bounded without settling).
    pub converged: bool,
    /// Why the run stopped early (empty if it did not).
    pub error: String,
    /// Wall time of the run in milliseconds (timing: differs between runs of a sweep).
    pub wall_ms: f64,
}

impl RunMetrics {
    /// The value of `m`.
    pub fn get(&self, m: Metric) -> Option<f64> {
        self.values[m as usize]
    }
}

/// Largest violation of the box [lower, upper] by any u_t of the trace.
fn input_violation(trace: &Trace, lower: &[f64], upper: &[f64]) -> f64 {
    let mut worst = 0.0f64;
    for t in 0..trace.len() {
        if let Some(u) = trace.u(t) {
            for ((&ui, &lo), &hi) in u.iter().zip(lower).zip(upper) {
                let v = (lo - ui).max(ui - hi);
                if v > worst || v.is_nan() {
                    worst = v;
                }
            }
        }
    }
    worst
}

/// Summarises a trace (complete or stopped) into the metrics of one run.
pub fn run_metrics(
    trace: &Trace,
    x0: &[f64],
    input_box: (&[f64], &[f64]),
    bounded_factor: f64,
    stop: Option<&ClosedLoopError>,
) -> ([Option<f64>; 14], bool) {
    let diverged = stop.is_some();
    let inf_if = |v: f64| if diverged { f64::INFINITY } else { v };
    let sup_e = inf_if(trace.sup_norm_e());
    let sup_x = inf_if(trace.sup_norm_x());
    let sup_w = trace.sup_norm_w();
    let tail = |v: Option<f64>| v.map(inf_if);
    let (tail_e, tail_x) = (tail(trace.tail_mean_e()), tail(trace.tail_mean_x()));
    let final_e = trace.e_norms().last().copied().map(inf_if);
    let final_x = (!trace.is_empty())
        .then(|| trace.x_norms().last().copied())
        .flatten()
        .map(inf_if);
    let sup_eps = {
        let mut s: Option<f64> = None;
        for e in trace.epsilons().flatten() {
            s = Some(s.map_or(e, |m: f64| if e > m || e.is_nan() { e } else { m }));
        }
        s
    };
    let gain = |num: f64| (sup_w > 0.0).then(|| num / sup_w);
    let mhe_violation = trace.mhe().map(|m| {
        (0..trace.len())
            .filter_map(|t| m.step(t).map(|s| s.violation()))
            .fold(0.0f64, |a, v| if v > a || v.is_nan() { v } else { a })
    });
    let values = [
        Some(sup_e),
        Some(sup_x),
        tail_e,
        final_e,
        tail_x,
        final_x,
        Some(sup_w),
        sup_eps,
        gain(sup_e),
        gain(sup_x),
        tail_e.and_then(gain),
        tail_x.and_then(gain),
        Some(input_violation(trace, input_box.0, input_box.1)),
        mhe_violation,
    ];
    // The one bounded rule (crate::bounded): e, x, ε and u against their own initial scale
    // and the run's disturbance; any early stop counts as unbounded.
    let bounded =
        !diverged && crate::bounded::first_unbounded(trace, x0, bounded_factor, false).is_none();
    (values, bounded)
}

/// Factor F of the converged rule ([`converged`]): the tail may exceed the run's
/// disturbance level w̄ = sup_t ‖w_t‖ by F (a stable loop with a good estimator sits at a
/// few w̄; the Kalman baseline's `tail_gain_*` in `kalman.csv` give the plant's own level).
pub const CONVERGED_FACTOR: f64 = 100.0;
/// Relative floor δ of the converged rule: a tail below δ·(1 + ‖·₀‖) counts as converged
/// whatever w̄ (a noise-free run decays to 0, never "to the level" 0).
pub const CONVERGED_FLOOR: f64 = 1e-3;

/// Whether a run *converged* to the disturbance level: it completed (`stopped` false),
/// and over the last quarter of its steps (the steps of [`Trace::tail_mean_e`])
/// mean ‖e_t‖ ≤ F·w̄ + δ·(1 + ‖e₀‖) and mean ‖x_t‖ ≤ F·w̄ + δ·(1 + ‖x₀‖), with
/// w̄ = sup_t ‖w_t‖ of the run, F = [`CONVERGED_FACTOR`], δ = [`CONVERGED_FLOOR`].
/// A sweep counts it only among the bounded runs (`converged ⇒ bounded`).
///
/// ```
/// use closed_loop::metrics::converged_norms;
/// // Decays to the noise level 0.01: converged; settles at 5 with w̄ = 0.01: not.
/// assert!(converged_norms(&[1.0, 0.1, 0.02, 0.01], &[1.0, 0.1, 0.02, 0.01, 0.01], 0.01));
/// assert!(!converged_norms(&[1.0, 5.0, 5.0, 5.0], &[1.0, 5.0, 5.0, 5.0, 5.0], 0.01));
/// ```
pub fn converged(trace: &Trace, stopped: bool) -> bool {
    !stopped && converged_norms(trace.e_norms(), trace.x_norms(), trace.sup_norm_w())
}

/// [`converged`] on the norms: ‖e_t‖ for t < T, ‖x_t‖ for t ≤ T (x_T is not in the tail,
/// as in [`Trace::tail_mean_x`]), and w̄. False for an empty run or a non-finite tail.
pub fn converged_norms(e: &[f64], x: &[f64], w_bar: f64) -> bool {
    let len = e.len();
    if len == 0 || x.len() < len {
        return false;
    }
    let start = len - len.div_ceil(4);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (tail_e, tail_x) = (mean(&e[start..len]), mean(&x[start..len]));
    let level = |first: f64| CONVERGED_FACTOR * w_bar + CONVERGED_FLOOR * (1.0 + first);
    tail_e.is_finite() && tail_x.is_finite() && tail_e <= level(e[0]) && tail_x <= level(x[0])
}

/// A free text as one CSV cell: separators, quotes and line breaks replaced (the `error`
/// column of a run, void reasons).
pub fn csv_text(s: &str) -> String {
    s.chars()
        .map(|c| match c {
            ',' => ';',
            '"' => '\'',
            '\n' | '\r' => ' ',
            c => c,
        })
        .collect()
}

/// Type-7 (linear interpolation) quantile of sorted values; `None` for no values.
///
/// ```
/// use closed_loop::metrics::quantile_sorted;
/// assert_eq!(quantile_sorted(&[1.0, 2.0, 3.0, 4.0, 5.0], 0.5), Some(3.0));
/// assert_eq!(quantile_sorted(&[0.0, 10.0], 0.05), Some(0.5));
/// assert_eq!(quantile_sorted(&[], 0.5), None);
/// ```
pub fn quantile_sorted(sorted: &[f64], q: f64) -> Option<f64> {
    let n = sorted.len();
    if n == 0 {
        return None;
    }
    let h = (n - 1) as f64 * q.clamp(0.0, 1.0);
    let lo = h.floor() as usize;
    let hi = h.ceil().min((n - 1) as f64) as usize;
    let (a, b) = (sorted[lo], sorted[hi]);
    if lo == hi || a == b {
        return Some(a);
    }
    Some(a + (h - lo as f64) * (b - a))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn quantiles_match_numpy_linear() {
        // numpy.quantile([3, 1, 4, 1, 5, 9, 2, 6], [0.05, 0.5, 0.95]) = [1.0, 3.5, 7.95]
        let mut v = [3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0, 6.0];
        v.sort_by(f64::total_cmp);
        assert_eq!(quantile_sorted(&v, 0.05), Some(1.0));
        assert_eq!(quantile_sorted(&v, 0.5), Some(3.5));
        let q95 = quantile_sorted(&v, 0.95).unwrap();
        assert!((q95 - 7.95).abs() < 1e-12, "{q95}");
        // +∞ (a diverged run) sorts last and is the maximum.
        let mut w = [f64::INFINITY, 1.0, 2.0];
        w.sort_by(f64::total_cmp);
        assert_eq!(w.last(), Some(&f64::INFINITY));
    }
}
