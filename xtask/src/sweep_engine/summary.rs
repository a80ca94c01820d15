//! The per-point summary over the runs of a sweep point: quantiles of the kept metrics and
//! the bounded fraction beside the certificate at K (the columns of `points.csv`).

use closed_loop::metrics::{Metric, QUANTILES, RunMetrics, quantile_sorted};

use super::theory::TheoryAtK;

/// One row of `points.csv` (besides the identity columns).
#[derive(Debug, Clone, PartialEq)]
pub struct PointSummary {
    /// Runs at the point.
    pub runs: usize,
    /// Fraction of bounded runs.
    pub bounded_fraction: f64,
    /// Per kept metric: (q05, q50, q95, max) over the runs that have it.
    pub quantiles: Vec<(Metric, [Option<f64>; 4])>,
    /// The certificate at K.
    pub theory: TheoryAtK,
    /// Sum of the runs' wall times (ms).
    pub wall_ms: f64,
}

/// Summarises the runs of a point.
pub fn summarise(runs: &[RunMetrics], metrics: &[Metric], theory: TheoryAtK) -> PointSummary {
    let quantiles = metrics
        .iter()
        .map(|&m| {
            let mut v: Vec<f64> = runs.iter().filter_map(|r| r.get(m)).collect();
            v.sort_by(f64::total_cmp);
            let q = |p| quantile_sorted(&v, p);
            (
                m,
                [
                    q(QUANTILES[0].0),
                    q(QUANTILES[1].0),
                    q(QUANTILES[2].0),
                    v.last().copied(),
                ],
            )
        })
        .collect();
    let bounded = runs.iter().filter(|r| r.bounded).count();
    PointSummary {
        runs: runs.len(),
        bounded_fraction: if runs.is_empty() {
            0.0
        } else {
            bounded as f64 / runs.len() as f64
        },
        quantiles,
        theory,
        wall_ms: runs.iter().map(|r| r.wall_ms).sum(),
    }
}
