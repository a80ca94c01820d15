//! Monte-Carlo runs of any closed loop: a user's estimator or controller (any
//! [`Estimator`] / [`Controller`] with its own error type) gets the same per-run metrics, the
//! same bounded rule and the same seeding as the scenario sweep.

use std::time::Instant;

use lti_model::disturbance::Disturbance;
use mhe_core::Estimator;
use mpc_core::Controller;
use rayon::prelude::*;

use crate::metrics::{RunMetrics, csv_text, run_metrics};
use crate::sim::{ClosedLoop, ClosedLoopError};

/// SplitMix64's output function (Steele, Lea, Flood 2014): a bijective 64-bit mixer (the
/// seeds of runs: a function of the configuration only, stable across platforms).
pub fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seed of run r of [`monte_carlo`]: a function of (base seed, r) only, so results do
/// not depend on the thread count.
pub fn monte_carlo_seed(base_seed: u64, run: usize) -> u64 {
    splitmix64(base_seed ^ splitmix64(run as u64))
}

/// Settings of [`monte_carlo`]: [`MonteCarlo::new`] with the default bounded rule, changed
/// by the `with_*` methods (new settings will not break your code).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct MonteCarlo<'a> {
    /// Number of runs.
    pub runs: usize,
    /// Base seed; run r gets [`monte_carlo_seed`]`(base_seed, r)`.
    pub base_seed: u64,
    /// 𝒰 as (lower, upper), for the input-violation metric.
    pub input_box: (&'a [f64], &'a [f64]),
    /// The bounded rule's factor c (see [`crate::metrics::DEFAULT_BOUNDED_FACTOR`]).
    pub bounded_factor: f64,
}

impl<'a> MonteCarlo<'a> {
    /// `runs` runs seeded from `base_seed`, with 𝒰 = `input_box` (lower, upper) for the
    /// input-violation metric and the default bounded factor
    /// ([`crate::metrics::DEFAULT_BOUNDED_FACTOR`]).
    pub fn new(runs: usize, base_seed: u64, input_box: (&'a [f64], &'a [f64])) -> Self {
        Self {
            runs,
            base_seed,
            input_box,
            bounded_factor: crate::metrics::DEFAULT_BOUNDED_FACTOR,
        }
    }

    /// The bounded rule's factor c.
    #[must_use]
    pub fn with_bounded_factor(mut self, bounded_factor: f64) -> Self {
        self.bounded_factor = bounded_factor;
        self
    }
}

/// Runs `settings.runs` closed loops built by `make(seed)` on the current rayon pool and
/// returns their metrics in run order (the columns of `runs.csv`). A run that stops is a
/// result (its `error` says where and why), not an error; only a failed `make` is, and its
/// error is returned as the factory gave it: `make` may return its own error type `Err`
/// (a user's enum, [`ClosedLoopError`], `Box<dyn Error + Send + Sync>`, …), which only has
/// to be `Send`. When several runs fail to build, the error of the lowest-numbered one is
/// returned (whatever the thread count).
///
/// ```
/// use closed_loop::scenario::{LoopOptions, Scenario};
/// use closed_loop::monte_carlo::{MonteCarlo, monte_carlo};
/// let text = "name = \"s\"\n[plant]\na = [[0.5]]\nb = [[1.0]]\nc = [[1.0]]\n\
///     [sets]\ninput = { lower = -1, upper = 1 }\ndisturbance = { lower = -0.1, upper = 0.1 }\n\
///     [simulation]\nx0 = [1.0]\nsteps = 20\n[mhe]\nhorizon = 3\neta = 0.8\niterations = 10\n\
///     [mpc]\nhorizon = 5\n";
/// let resolved = Scenario::from_toml_str(text).unwrap().resolve().unwrap();
/// let sc = resolved.scenario();
/// let input_box = (sc.sets.input.lower(), sc.sets.input.upper());
/// let settings = MonteCarlo::new(4, 7, input_box).with_bounded_factor(1e3);
/// let runs = monte_carlo(&settings, |seed| {
///     let mut o = LoopOptions::from_scenario(sc)?;
///     o.seed = seed;
///     resolved.build_loop(&o)
/// }).unwrap();
/// assert!(runs.iter().all(|r| r.bounded && r.steps == 20));
/// ```
pub fn monte_carlo<E, C, D, F, Err>(
    settings: &MonteCarlo<'_>,
    make: F,
) -> Result<Vec<RunMetrics>, Err>
where
    E: Estimator + Send,
    C: Controller + Send,
    D: Disturbance + Send,
    F: Fn(u64) -> Result<ClosedLoop<E, C, D>, Err> + Sync,
    Err: Send,
{
    (0..settings.runs)
        .into_par_iter()
        .with_max_len(1)
        .map(|r| {
            let seed = monte_carlo_seed(settings.base_seed, r);
            let mut lp = make(seed)?;
            let start = Instant::now();
            let stop = lp.run().err();
            Ok(finish_run(
                &lp,
                r,
                seed,
                stop,
                start,
                settings.input_box,
                settings.bounded_factor,
            ))
        })
        .collect::<Vec<_>>()
        .into_iter()
        .collect()
}

/// The metrics of a finished (or stopped) run: shared by the scenario sweep and
/// [`monte_carlo`].
pub fn finish_run<E: Estimator, C: Controller, D: Disturbance>(
    lp: &ClosedLoop<E, C, D>,
    run: usize,
    seed: u64,
    stop: Option<ClosedLoopError>,
    start: Instant,
    input_box: (&[f64], &[f64]),
    bounded_factor: f64,
) -> RunMetrics {
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let trace = lp.trace();
    let (values, bounded) = run_metrics(
        trace,
        lp.initial_state(),
        input_box,
        bounded_factor,
        stop.as_ref(),
    );
    RunMetrics {
        run,
        seed,
        steps: trace.len(),
        values,
        bounded,
        converged: bounded && crate::metrics::converged(trace, stop.is_some()),
        error: stop.map(|e| csv_text(&e.to_string())).unwrap_or_default(),
        wall_ms,
    }
}
