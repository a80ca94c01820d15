//! The per-point summary over the runs of a sweep point: quantiles of the kept metrics and
//! the bounded fraction and the draws outside 𝒲 beside the certificate at K (the columns of
//! `points.csv`).

use closed_loop::metrics::{Metric, QUANTILES, RunMetrics, quantile_sorted};

use super::theory::TheoryAtK;

/// One run of a sweep point: its metrics and how many of its disturbance draws left 𝒲.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct SweepRun {
    /// The run's metrics (a row of `runs.csv`).
    pub metrics: RunMetrics,
    /// Steps t whose simulated draw w_t lies outside 𝒲 (`sets.disturbance`), counted from
    /// the run's trace after it ended ([`closed_loop::scenario::draws_outside`]): column
    /// `w_outside`, 0 ≤ `w_outside` ≤ `steps`.
    pub w_outside: usize,
}

/// One row of `points.csv` (besides the identity columns).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct PointSummary {
    /// Runs at the point.
    pub runs: usize,
    /// Fraction of bounded runs.
    pub bounded_fraction: f64,
    /// Fraction of converged runs (bounded and back at the disturbance level over the last
    /// quarter, [`closed_loop::metrics::converged`]); ≤ `bounded_fraction`.
    pub converged_fraction: f64,
    /// Per kept metric: (q05, q50, q95, max) over the runs that have it.
    pub quantiles: Vec<(Metric, [Option<f64>; 4])>,
    /// The certificate at K.
    pub theory: TheoryAtK,
    /// Runs with at least one draw outside 𝒲 (their ISS bound is not claimed by the
    /// certificate).
    pub w_outside_runs: usize,
    /// Draws outside 𝒲, summed over the runs.
    pub w_outside_total: usize,
    /// Sum of the runs' wall times (ms).
    pub wall_ms: f64,
}

/// Summarises the runs of a point.
pub fn summarise(runs: &[SweepRun], metrics: &[Metric], theory: TheoryAtK) -> PointSummary {
    let counts: Vec<usize> = runs.iter().map(|r| r.w_outside).collect();
    let runs: Vec<&RunMetrics> = runs.iter().map(|r| &r.metrics).collect();
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
    let fraction = |n: usize| {
        if runs.is_empty() {
            0.0
        } else {
            n as f64 / runs.len() as f64
        }
    };
    PointSummary {
        runs: runs.len(),
        bounded_fraction: fraction(runs.iter().filter(|r| r.bounded).count()),
        converged_fraction: fraction(runs.iter().filter(|r| r.converged).count()),
        quantiles,
        theory,
        w_outside_runs: counts.iter().filter(|&&n| n > 0).count(),
        w_outside_total: counts.iter().sum(),
        wall_ms: runs.iter().map(|r| r.wall_ms).sum(),
    }
}
