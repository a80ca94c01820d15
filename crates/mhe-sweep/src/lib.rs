#![doc = include_str!("../README.md")]
//!
//! # The engine
//!
//! A run is one closed loop of a [`ResolvedScenario::build_loop`](closed_loop::scenario::ResolvedScenario::build_loop)
//! with its own disturbance draw; its metrics are a [`RunMetrics`], the point's quantiles of
//! them beside the certificate at that K a [`PointSummary`].
//!
//! ## Determinism
//! - The seed of run r at a point is [`run_seed`]`(base_seed, point, r)`: a SplitMix64 hash
//!   of those values only. By default (`common_random_numbers = true`) the point does not
//!   enter, so run r sees the same disturbance sequence at every K and solver (differences
//!   along a curve come from K, not from the draw).
//! - Runs are tasks of one pool of `threads` workers (with the certificate and ρ_lin as
//!   tasks beside them, longest first: `schedule.rs`); each worker restarts a loop of
//!   its own with [`ScenarioLoop::reseed`](closed_loop::scenario::ScenarioLoop::reseed), which is equivalent to a fresh build. faer's
//!   global parallelism is set to sequential (no nested pools inside a run).
//! - Every output value is a function of the configuration and the scenario only, except
//!   the timing columns, all named `wall_*`.
//!
//! ## Files (in the output directory)
//! - `points/pNNNNN.csv`: one file per finished point (its run rows and its summary row),
//!   written to a unique temporary name and renamed, so a file that exists is complete. A
//!   rerun checks every point file in full and skips the points whose file exists (resume);
//!   a killed sweep loses only the points in flight. A file that is cut, edited, copied
//!   from another point or of another configuration is refused, naming it.
//! - `runs.csv`, `points.csv`: assembled from the point files in point order
//!   ([`assemble`]), replaced atomically once every point file is validated; shards
//!   (`--shard I/N`) only write point files (and, with the Kalman baseline, their part of
//!   `kalman.csv`: `points/kalman.shard-I-of-N.csv`), and [`merge_point_dirs`] assembles
//!   them.
//! - `.lock` (`.lock.shard-I-of-N` for a shard): the pid of the sweep writing the
//!   directory; a second writer is refused, a stale lock of a killed sweep taken over.
//!
//! ## Layout
//! | file | job |
//! | --- | --- |
//! | `config.rs` | [`SweepConfig`] (serde + key paths), its validation, the [`Point`] grid |
//! | `grid.rs` | the budget grids `k` and `k_c` (lists or [`log_spaced`] ranges) |
//! | `seeds.rs` | [`run_seed`], [`Shard`] |
//! | `summary.rs` | [`PointSummary`]: quantiles of the runs' [`RunMetrics`] (from `closed_loop::metrics`) beside the certificate at K |
//! | `thresholds.rs` | K_lin, K_emp, K_cert per solver from `points.csv` ([`thresholds`]) |
//! | `regional.rs` | K_reg per solver and scale (the regional certificate's search, shared with `reproduce`), and why there is none ([`RegionalSide`], [`k_reg_outcome`]) |
//! | `region.rs` | 2-D sweeps: the empirical and linear regions of (K_e, K_c), their staircases and cheapest pairs ([`pair_thresholds`]) |
//! | `theory.rs` | the certificate's and the linear analysis' columns per point ([`SolverTheory`], [`TheoryAtK`], [`LinearSide`]); the joint certificate's hook [`certified_boundary`] |
//! | `format.rs` | CSV rows and headers, fingerprint, point files (writing, reading, validation), [`Table`] |
//! | `run.rs` | [`Sweep`], the run loop, [`Progress`]: the only contact with the simulation |
//! | `pool.rs` | the theory and every run as tasks of one worker pool, point files written as points finish |
//! | `schedule.rs` | the scheduling policy, the measured task times ([`ScheduleReport`]) and their replay for other thread counts |
//! | `merge.rs` | resume reading, [`assemble`], [`merge_point_dirs`] |
//! | `baseline.rs` | the Kalman baseline's runs (`kalman.csv`) |
//! | `kalman_parts.rs` | a shard's part of `kalman.csv`, checked and assembled by a merge |
//! | `lock.rs` | one writer per output directory |
//! | `error.rs` | [`SweepError`] |
//! | `plots.rs` | feature `plots`: the SVG plots of an assembled sweep from `points.csv` (band charts over K, (K_e, K_c) heat maps; drawn by `mhe-plots`) |
//!
//! Column reference: `docs/sweeps.md`.

mod baseline;
mod config;
mod error;
mod format;
mod graph;
mod grid;
mod kalman_parts;
mod lock;
mod merge;
#[cfg(feature = "plots")]
pub mod plots;
mod pool;
mod region;
mod regional;
mod run;
mod schedule;
mod seeds;
mod summary;
mod table;
mod theory;
mod thresholds;

// The two types of `closed_loop::sim` a sweep's data carries (Φ of a point, the controller),
// imported once here; `run.rs` holds the rest of the coupling to the simulation.
use closed_loop::scenario::ControllerChoice;
use qp_iter::Method;

pub use baseline::kalman_header;
pub use closed_loop::metrics::{
    DEFAULT_BOUNDED_FACTOR, Metric, QUANTILES, RunMetrics, quantile_sorted, run_metrics,
};
pub use config::{MAX_K, MAX_SEEDS, MAX_STEPS, Point, SweepConfig};
pub use error::{Result, SweepError};
pub use format::{PointFile, Table, point_file_name, points_header, runs_header};
pub use graph::L_PI_CHUNKS;
pub use iss_certificate::linear::log_spaced;
pub use kalman_parts::kalman_part_name;
pub use merge::{Assembled, assemble, merge_point_dirs, merge_staged};
pub use region::{
    IterationCost, Pair, PairThresholds, Staircase, cheapest_pair, pair_thresholds,
    pair_thresholds_markdown, staircase, staircase_text, up_set,
};
pub use regional::{
    KRegOutcome, ProbeNote, REGIONAL_MAX_K_NZ, REGIONAL_SEARCH_CAP, RegionalEntry, RegionalPlan,
    RegionalSearch, RegionalSide, k_reg_outcome, limit_text, row_text, search_max, theorem1_k_min,
    window_size,
};
pub use run::{NoProgress, Progress, RunOptions, Staged, Sweep, SweepReport, run_cost};
pub use schedule::{Prediction, ScheduleReport, TaskKind, TaskTime};
pub use seeds::{Shard, run_seed, splitmix64};
pub use summary::{PointSummary, SweepRun, summarise};
pub use theory::{
    LinearEntry, LinearSide, SolverTheory, TheoryAtK, certified_boundary, joint_staircase,
    solver_linear, solver_theory,
};
pub use thresholds::{SETTLE_TOLERANCE, Thresholds, thresholds, thresholds_markdown};
