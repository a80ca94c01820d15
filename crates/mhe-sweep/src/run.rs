//! The run loop: a [`Sweep`] (the config, the scenario resolved once, the points, the
//! theory) runs the theory and every run of every point on one worker pool (`pool.rs`),
//! writes each finished point file at once and assembles the outputs.
//!
//! This file (with the config parser for `solvers` and `controller`) is where the sweep
//! meets the simulation of `closed_loop::sim`: building the case-study loop of a point and
//! running it per seed.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Instant;

use closed_loop::scenario::{ResolvedScenario, Scenario};

use super::config::{Point, SweepConfig};
use super::error::{Result, SweepError, config_err, io_err};
use super::format::Table;
use super::format::{self, PointFile, point_row, run_row, temp_path};
use super::lock::OutputLock;
use super::merge::{Assembled, assemble_files};
use super::region::{PairThresholds, Staircase, pair_thresholds};
use super::regional::{RegionalPlan, RegionalSide, theorem1_k_min};
use super::schedule::ScheduleReport;
use super::seeds::Shard;
use super::summary::{SweepRun, summarise};
use super::theory::LinearEntry;
use super::theory::{
    LinearSide, SolverTheory, TheoryAtK, joint_staircase, solver_linear, solver_theory,
};
use super::thresholds::{Thresholds, thresholds};
use super::{ControllerChoice, Method};
use closed_loop::scenario::{LoopOptions, ScenarioLoop, draws_outside};
use closed_loop::sim::ClosedLoopError;

/// How to run a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOptions {
    /// Output directory (created if needed).
    pub out_dir: PathBuf,
    /// Worker threads ≥ 1 of the pool.
    pub threads: usize,
    /// Run only this shard's points (and do not assemble).
    pub shard: Option<Shard>,
}

/// Progress reports of a running sweep (the xtask draws a bar from them). All methods
/// default to doing nothing.
pub trait Progress: Sync {
    /// Called once before any run: `points` to run (after skipping finished ones), their
    /// `runs`, their total `cost` (T·(K + 50) per run, see [`run_cost`]) and how many
    /// points were skipped because their file exists.
    fn start(&self, points: usize, runs: u64, cost: u64, skipped: usize) {
        let _ = (points, runs, cost, skipped);
    }
    /// Called after each run with its cost.
    fn run_done(&self, cost: u64) {
        let _ = cost;
    }
    /// Called after a point file was written.
    fn point_done(&self, point: &Point) {
        let _ = point;
    }
    /// Called with a line the user should see that is not an error (a stale lock of a
    /// killed sweep taken over).
    fn notice(&self, message: &str) {
        let _ = message;
    }
    /// Polled by every worker between two tasks: `true` stops the sweep — no new task
    /// starts, the running ones finish, and [`Sweep::run`] returns
    /// [`crate::SweepError::Cancelled`] (point files already written stay valid, so a rerun
    /// resumes). The Python binding sets it on Ctrl-C.
    fn cancelled(&self) -> bool {
        false
    }
}

/// A [`Progress`] that reports nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;
impl Progress for NoProgress {}

/// Relative cost of one run for progress and ETA: T·(K + 50) (the 50 stands for the
/// per-step work outside the K iterations, mainly the controller; a 2-D sweep passes
/// K_e + K_c as K).
pub fn run_cost(k: usize, steps: usize) -> u64 {
    (steps as u64).saturating_mul(k as u64 + 50)
}

/// What a finished [`Sweep::run`] did.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct SweepReport {
    /// Points computed now.
    pub computed: usize,
    /// Points skipped because their file existed (resume).
    pub skipped: usize,
    /// Closed-loop steps simulated now.
    pub steps_simulated: u64,
    /// Wall time of this call in seconds.
    pub wall_s: f64,
    /// Wall time of the pool (the runs, the theory computed beside them and the point files
    /// written as they finish; without the setup and the assembly).
    pub runs_wall_s: f64,
    /// Threads used.
    pub threads: usize,
    /// Whether `runs.csv` and `points.csv` (and `kalman.csv` with the Kalman baseline) were
    /// assembled (false for a shard, which writes its part of `kalman.csv` to
    /// `points/kalman.shard-I-of-N.csv`).
    pub assembled: bool,
    /// Every task's measured time and the replay of them (`schedule.rs`); empty when
    /// nothing was computed.
    pub schedule: ScheduleReport,
}

impl SweepReport {
    /// Closed-loop steps per second per thread of this call's runs.
    pub fn steps_per_second_per_thread(&self) -> f64 {
        if self.runs_wall_s > 0.0 {
            self.steps_simulated as f64 / self.runs_wall_s / self.threads as f64
        } else {
            0.0
        }
    }
}

/// A sweep ready to run: the config, the scenario (with P of LMI (2) computed once), the
/// points and the theoretical side.
#[derive(Debug)]
pub struct Sweep {
    config: SweepConfig,
    resolved: ResolvedScenario,
    steps: usize,
    base_seed: u64,
    points: Vec<Point>,
    fingerprint: String,
    canonical: String,
    pub(super) theory: OnceLock<Vec<(Method, SolverTheory)>>,
    pub(super) linear: OnceLock<LinearSide>,
    pub(super) certified: OnceLock<Vec<(Method, Staircase)>>,
    pub(super) regional: OnceLock<RegionalSide>,
}

impl Sweep {
    /// Loads the scenario, computes P of LMI (2) once (when the scenario does not give
    /// it) and checks that a loop can be built for every solver.
    pub fn new(config: SweepConfig) -> Result<Self> {
        let path = config.scenario.clone();
        let text = lti_model::spec::format::read_limited(&path).map_err(|source| {
            SweepError::Scenario {
                path: path.clone(),
                source,
            }
        })?;
        let original = Scenario::from_toml_str(&text).map_err(|source| SweepError::Scenario {
            path: path.clone(),
            source,
        })?;
        if original.mhe.is_none() {
            return Err(config_err(
                "scenario",
                format!(
                    "`{}` has no [mhe] section; a sweep needs one",
                    path.display()
                ),
            ));
        }
        // P of LMI (2), the MHE configuration and the MPC: resolved once for every point.
        let resolved = original.resolve().map_err(|source| SweepError::Setup {
            point: "(scenario)".into(),
            source,
        })?;
        // ℙ_t built once here, so every point's clone shares it (an error surfaces per
        // point, with its key, when the loop is built).
        let _ = resolved.mhe_problem();
        if let Some(Err(source)) = resolved.ioss() {
            if resolved
                .scenario()
                .mhe
                .as_ref()
                .is_some_and(|m| m.p().is_none())
            {
                return Err(SweepError::Scenario {
                    path: path.clone(),
                    source: source.clone(),
                });
            }
        }
        let scenario = resolved.scenario();
        let steps = config.steps.unwrap_or(scenario.simulation.steps);
        let base_seed = config.base_seed.unwrap_or(scenario.noise.seed);
        let points = config.points_with(scenario.noise.scale);
        let scales: Vec<f64> = config
            .scales
            .clone()
            .unwrap_or_else(|| vec![scenario.noise.scale]);
        let canonical = config.canonical(steps, base_seed, &scales);
        let fingerprint = format::fingerprint(&canonical, &text);
        let sweep = Self {
            config,
            resolved,
            steps,
            base_seed,
            points,
            fingerprint,
            canonical,
            theory: OnceLock::new(),
            linear: OnceLock::new(),
            certified: OnceLock::new(),
            regional: OnceLock::new(),
        };
        // Fail early (before any output) if a point cannot be set up.
        for &solver in &sweep.config.solvers {
            if let Some(p) = sweep.points.iter().find(|p| p.solver == solver) {
                sweep.build(p)?;
            }
        }
        Ok(sweep)
    }

    /// The configuration.
    pub fn config(&self) -> &SweepConfig {
        &self.config
    }
    /// The scenario as read.
    pub fn scenario(&self) -> &Scenario {
        self.resolved.scenario()
    }
    /// The scenario resolved once (P of LMI (2), the MHE configuration, the MPC).
    pub fn resolved(&self) -> &ResolvedScenario {
        &self.resolved
    }
    /// Every point of the sweep, in output order.
    pub fn points(&self) -> &[Point] {
        &self.points
    }
    /// Horizon T of every run.
    pub fn steps(&self) -> usize {
        self.steps
    }
    /// Base seed of the run seeds.
    pub fn base_seed(&self) -> u64 {
        self.base_seed
    }
    /// Hash of the config's result-relevant settings and the scenario text; stored in
    /// every point file.
    pub fn fingerprint(&self) -> &str {
        &self.fingerprint
    }
    /// The canonical text of the settings that enter the fingerprint (recorded in
    /// `points/settings.txt`, so that a directory of another sweep is refused naming what
    /// differs).
    pub fn canonical(&self) -> &str {
        &self.canonical
    }
    /// The theoretical side per solver (computed on first use: the certificate takes a
    /// moment and a resumed or merged sweep may not need it).
    pub fn theory(&self) -> &[(Method, SolverTheory)] {
        self.theory.get_or_init(|| {
            // The certificate covering (solver, controller) (iss_certificate::coverage): Theorem 1
            // for the exact MPC, the joint one for the K_c-iteration MPC (1-D or 2-D).
            if self.config.certificate || self.config.is_2d() {
                solver_theory(&self.resolved, &self.config.solvers, self.config.controller)
            } else {
                let reason = "not computed (certificate = false in the sweep config)";
                self.config
                    .solvers
                    .iter()
                    .map(|&s| (s, SolverTheory::Unavailable(reason.into())))
                    .collect()
            }
        })
    }
    /// The linear side per solver (and per K_c in a 2-D sweep): ρ_lin(K) on the K grid and
    /// K_lin (computed on first use, like [`Sweep::theory`]).
    pub fn linear(&self) -> &LinearSide {
        self.linear.get_or_init(|| {
            let controllers = self.config.grid_controllers();
            if self.config.linear {
                solver_linear(&self.resolved, &self.config.solvers, &controllers, |_| {
                    self.config.k_grid.clone()
                })
            } else {
                let reason = "not computed (linear = false in the sweep config)";
                LinearSide(
                    self.config
                        .solvers
                        .iter()
                        .flat_map(|&solver| {
                            controllers.iter().map(move |&(k_c, _)| LinearEntry {
                                solver,
                                k_c,
                                report: Err(reason.to_string()),
                            })
                        })
                        .collect(),
                )
            }
        })
    }

    /// The disturbance scales of the sweep (`scales`, or the scenario's `noise.scale`).
    pub(super) fn scales(&self) -> Vec<f64> {
        self.config
            .scales
            .clone()
            .unwrap_or_else(|| vec![self.scenario().noise.scale])
    }

    /// Why the sweep has no K_reg (None: it is computed): `certificate = false`.
    pub(super) fn regional_unavailable(&self) -> Option<&'static str> {
        if !self.config.certificate {
            Some("not computed (certificate = false in the sweep config)")
        } else {
            None
        }
    }

    /// K_reg per solver and scale ([`super::k_reg_outcome`]: the smallest K whose regional
    /// certificate contains the scenario's uncertainty at that scale, searched up to the
    /// solver's K_min), or why there is none (computed on first use, like
    /// [`Sweep::theory`]).
    pub fn regional(&self) -> &RegionalSide {
        self.regional.get_or_init(|| {
            let scales = self.scales();
            if let Some(note) = self.regional_unavailable() {
                return RegionalSide::unavailable(&self.config.solvers, &scales, note);
            }
            let plan = RegionalPlan::new(
                &self.resolved,
                &self.config.solvers,
                &scales,
                self.config.controller,
                self.config.k_c_grid.as_deref(),
            );
            let results: Vec<(Option<usize>, String)> = plan
                .searches
                .iter()
                .enumerate()
                .map(|(i, search)| {
                    let k_min = self
                        .theory()
                        .iter()
                        .find(|(s, _)| *s == search.solver)
                        .and_then(|(_, t)| theorem1_k_min(t));
                    plan.run(&self.resolved, i, k_min)
                })
                .collect();
            plan.side(|i| results.get(i).cloned())
        })
    }

    /// The joint certificate's region of (K_e, K_c) per MHE solver of a 2-D sweep, as a
    /// staircase (K_e, smallest certified K_c or None) on the K_e grid: the hook
    /// [`certified_boundary`](super::certified_boundary) (empty = not computed). Empty for a
    /// 1-D sweep.
    pub fn certified_boundaries(&self) -> &[(Method, Staircase)] {
        self.certified.get_or_init(|| {
            if !self.config.is_2d() {
                return Vec::new();
            }
            // The same analysis as the points' `certified` column (`theory_at`).
            self.theory()
                .iter()
                .map(|(s, t)| (*s, joint_staircase(t, &self.config.k_grid)))
                .collect()
        })
    }

    /// The thresholds of an assembled sweep from its `points.csv` (`table`): per solver and
    /// scale (and K_c: each K_c a curve over K_e, [`thresholds`](crate::thresholds)), and for
    /// a 2-D sweep the regions and cheapest pairs of (K_e, K_c) with the joint certificate's
    /// boundary ([`pair_thresholds`](crate::pair_thresholds); empty for a 1-D sweep).
    pub fn all_thresholds(&self, table: &Table) -> (Vec<Thresholds>, Vec<PairThresholds>) {
        let certified: Vec<(String, Staircase)> = self
            .certified_boundaries()
            .iter()
            .map(|(m, st)| (m.to_string(), st.clone()))
            .collect();
        let pairs = if self.config.is_2d() {
            pair_thresholds(table, self.config.cost, &certified)
        } else {
            Vec::new()
        };
        (thresholds(table), pairs)
    }

    /// The certificate's and the linear analysis' columns for a point.
    pub fn theory_at(&self, p: &Point) -> TheoryAtK {
        let mut t = self
            .theory()
            .iter()
            .find(|(s, _)| *s == p.solver)
            .map(|(_, t)| t.at_pair(p.k, self.k_c_at(p)))
            .unwrap_or_else(|| {
                SolverTheory::Unavailable("no analysis for this solver".into()).at(p.k)
            });
        self.linear().fill(p.solver, p.k_c, p.k, &mut t);
        self.regional()
            .fill(p.solver, p.scale, self.k_c_at(p), &mut t);
        t
    }

    /// K_c of the controller at point `p` (None: the exact MPC or another controller).
    fn k_c_at(&self, p: &Point) -> Option<usize> {
        match self.config.controller_at(p) {
            Ok(ControllerChoice::SuboptimalMpc { iterations, .. }) => Some(iterations.get()),
            _ => None,
        }
    }

    pub(super) fn build(&self, p: &Point) -> Result<ScenarioLoop> {
        // A clone shares the MHE problem built once in `Sweep::new` (an `Arc`).
        let mut resolved = self.resolved.clone();
        resolved.set_noise_scale(p.scale);
        let opts = self.config.controller_at(p).and_then(|controller| {
            LoopOptions {
                method: p.solver,
                iterations: qp_iter::Iterations::ONE,
                exact_mhe_solve: self.config.exact_mhe_solve,
                controller,
                seed: 0,
                steps: self.steps,
            }
            .with_iterations(p.k)
        });
        opts.and_then(|opts| resolved.build_loop(&opts))
            .map_err(|source| SweepError::Setup {
                point: p.to_string(),
                source,
            })
    }

    /// The point file of a computed point.
    pub fn point_file(&self, p: &Point, runs: &[SweepRun]) -> PointFile {
        let metrics = &self.config.metrics;
        let summary = summarise(runs, metrics, self.theory_at(p));
        PointFile {
            fingerprint: self.fingerprint.clone(),
            run_rows: runs.iter().map(|r| run_row(p, r, metrics)).collect(),
            point_row: point_row(p, &summary),
            edited: false,
        }
    }

    /// Runs the sweep (or a shard of it) into `opts.out_dir`: takes the directory's lock
    /// (see `lock.rs`: one writer per directory, or per shard), checks every point file
    /// already there in full, skips those points, writes each finished point file at once,
    /// and (unsharded) assembles `runs.csv` and `points.csv`.
    pub fn run(&self, opts: &RunOptions, progress: &dyn Progress) -> Result<SweepReport> {
        let staged = self.run_staged(opts, progress)?;
        if let Some(a) = &staged.outputs {
            a.write(&opts.out_dir)?;
        }
        Ok(staged.report)
    }

    /// [`Sweep::run`] without writing `runs.csv` and `points.csv`: their text is returned
    /// (unsharded) with the directory's lock still held, so the caller writes them in one
    /// set with its own files (`xtask sweep`: the plots, `meta.json`, `tasks.csv`, committed
    /// together by `output::OutputSet`) before another sweep may write the directory.
    pub fn run_staged(&self, opts: &RunOptions, progress: &dyn Progress) -> Result<Staged> {
        let started = Instant::now();
        if opts.threads == 0 {
            return Err(SweepError::Threads("--threads must be ≥ 1".into()));
        }
        let pdir = opts.out_dir.join("points");
        fs::create_dir_all(&pdir).map_err(io_err("create the output directory", &pdir))?;
        let lock = take_lock(&opts.out_dir, opts.shard, progress)?;
        if opts.shard.is_none() {
            lock.remove_dead_temps(&[opts.out_dir.as_path(), pdir.as_path()]);
        }
        // Probe writability before spending any compute.
        let probe = temp_path(&pdir.join(".write-probe"));
        fs::write(&probe, b"probe").map_err(io_err("write into the output directory", &pdir))?;
        let _ = fs::remove_file(&probe);
        let done = self.finished_points(&opts.out_dir)?;
        // The directory holds this sweep's points (or none): record its settings.
        format::write_atomic(
            &pdir.join(format::SETTINGS_FILE),
            &format::settings_text(&self.fingerprint, &self.canonical),
        )?;
        let todo: Vec<&Point> = self
            .points
            .iter()
            .filter(|p| opts.shard.is_none_or(|s| s.owns(p.index)))
            .filter(|p| !done.contains_key(&p.index))
            .collect();
        let skipped = self
            .points
            .iter()
            .filter(|p| opts.shard.is_none_or(|s| s.owns(p.index)))
            .count()
            - todo.len();
        let seeds = self.config.seeds as u64;
        progress.start(
            todo.len(),
            todo.len() as u64 * seeds,
            todo.iter()
                .map(|p| run_cost(p.k + p.k_c.unwrap_or(0), self.steps))
                .sum::<u64>()
                * seeds,
            skipped,
        );
        // No nested parallelism inside a run.
        faer::set_global_parallelism(faer::Par::Seq);
        // The theory and every run as tasks of one pool (`pool.rs`, `schedule.rs`).
        let outcome = if todo.is_empty() {
            None
        } else {
            Some(self.execute(&todo, opts.threads, &pdir, progress)?)
        };
        let computed = todo.len();
        let (steps_done, schedule, mut files) = match outcome {
            Some(o) => (o.steps, o.schedule, o.files),
            None => (0, ScheduleReport::default(), BTreeMap::new()),
        };
        let runs_wall_s = schedule.pool_wall_s;
        let assembled = opts.shard.is_none();
        let outputs = if assembled {
            // Every point file is in memory: the ones found (validated above) and the ones
            // written now.
            files.extend(done);
            let mut tables = assemble_files(self, &files)?;
            if self.config.kalman {
                tables.kalman = Some(super::baseline::kalman_text(self)?);
            }
            Some(tables)
        } else {
            // A shard's rows of kalman.csv go to its part file, assembled by a merge.
            if let (Some(shard), true) = (opts.shard, self.config.kalman) {
                super::kalman_parts::write_kalman_part(self, shard, &pdir)?;
            }
            None
        };
        Ok(Staged {
            report: SweepReport {
                computed,
                skipped,
                steps_simulated: steps_done,
                wall_s: started.elapsed().as_secs_f64(),
                runs_wall_s,
                threads: opts.threads,
                assembled,
                schedule,
            },
            outputs,
            _lock: lock,
        })
    }
}

/// A finished sweep (or merge) whose `runs.csv` and `points.csv` are not written yet
/// ([`Sweep::run_staged`], [`super::merge_staged`]): dropping it releases the output
/// directory's lock.
#[derive(Debug)]
#[non_exhaustive]
pub struct Staged {
    /// What the run did (for a merge: the points assembled in `computed`).
    pub report: SweepReport,
    /// `runs.csv` and `points.csv` (None for a shard, which does not assemble).
    pub outputs: Option<Assembled>,
    pub(super) _lock: OutputLock,
}

/// Takes the lock of `dir` (the whole directory, or one shard) and reports a stale lock
/// of a killed sweep that was taken over.
pub(super) fn take_lock(
    dir: &Path,
    shard: Option<Shard>,
    progress: &dyn Progress,
) -> Result<OutputLock> {
    let (lock, stale) = OutputLock::acquire(dir, shard)?;
    if let Some(h) = stale {
        progress.notice(&format!(
            "took over the stale lock of `{}` ({}, no longer running: a sweep there was killed)",
            dir.display(),
            h.describe()
        ));
    }
    Ok(lock)
}

/// Runs `lp` once with `seed` (restarting it first) and returns its metrics and the count
/// of its draws outside 𝒲 (`disturbance`), both from the trace after the run (the steps
/// themselves allocate nothing for either).
pub(super) fn simulate(
    lp: &mut ScenarioLoop,
    run: usize,
    seed: u64,
    input_box: (&[f64], &[f64]),
    disturbance: &lti_model::BoxSet,
    bounded_factor: f64,
) -> std::result::Result<SweepRun, ClosedLoopError> {
    let start = Instant::now();
    lp.reseed(seed)?;
    let stop = lp.run().err();
    let metrics =
        closed_loop::monte_carlo::finish_run(lp, run, seed, stop, start, input_box, bounded_factor);
    let w_outside = draws_outside(lp.trace(), disturbance).len();
    Ok(SweepRun { metrics, w_outside })
}
