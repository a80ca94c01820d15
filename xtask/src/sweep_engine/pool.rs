//! Executing a sweep on one pool of worker threads: the theory (certificate, ρ_lin, joint
//! boundary) and every run of every point as tasks of one list, in the order and by the
//! policy of `schedule.rs`; each point file written by the worker that finishes the point's
//! last run (once the theory it needs is there), the task times recorded.
//!
//! Determinism: a run's result depends on (point, run) only — a worker restarts the
//! point's loop with [`ScenarioLoop::reseed`], equivalent to a fresh build — and results are
//! stored by (point, run), so which worker ran what changes nothing in the outputs.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::time::Instant;

use super::config::Point;
use super::error::{Result, SweepError};
use super::format::{PointFile, point_file_name};
use super::region::Staircase;
use super::run::{Progress, Sweep, run_cost, simulate};
use super::schedule::{ScheduleReport, TaskKind, TaskTime, thread_cpu_s};
use super::seeds::run_seed;
use super::theory::{LinearEntry, LinearSide, SolverTheory, certified_boundary};
use super::theory::{solver_linear, solver_theory};
use super::{ControllerChoice, Method};
use closed_loop::metrics::RunMetrics;
use closed_loop::scenario::ScenarioLoop;

/// What a task computes.
#[derive(Debug, Clone, Copy)]
enum Job {
    /// Theorem 1 for every solver: one certificate (its constants L_Φ, L_π, γ₁,₃ are
    /// shared by the solvers and are most of its time, so one task per solver would
    /// compute them once per solver).
    Certificate,
    /// ρ_lin for entry `i` of (solver, K_c) pairs.
    Linear(usize, Method, Option<usize>, ControllerChoice),
    /// The joint boundary of `solvers[i]`.
    Boundary(usize),
    /// Run `run` of `todo[slot]`.
    Run { slot: usize, run: usize },
}

/// The theory's results as they arrive, and the points that wait for them.
#[derive(Debug, Default)]
struct TheoryState {
    left: usize,
    certificates: Option<Vec<(Method, SolverTheory)>>,
    certificate_task: bool,
    linear: Vec<Option<LinearEntry>>,
    boundaries: Vec<Option<(Method, Staircase)>>,
    /// Finished points whose file waits for the theory.
    pending: Vec<usize>,
}

/// What the pool did.
#[derive(Debug)]
pub(super) struct PoolOutcome {
    /// The point files written now, by point index.
    pub files: BTreeMap<usize, PointFile>,
    /// Closed-loop steps simulated.
    pub steps: u64,
    /// The measured schedule.
    pub schedule: ScheduleReport,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

struct Shared<'a> {
    sweep: &'a Sweep,
    todo: &'a [&'a Point],
    jobs: Vec<(Job, u64)>,
    next: AtomicUsize,
    abort: AtomicBool,
    error: Mutex<Option<SweepError>>,
    results: Vec<OnceLock<RunMetrics>>,
    remaining: Vec<AtomicUsize>,
    theory: Mutex<TheoryState>,
    theory_ready: AtomicBool,
    files: Mutex<BTreeMap<usize, PointFile>>,
    steps: AtomicU64,
    pdir: &'a Path,
    progress: &'a dyn Progress,
    clock: Instant,
}

impl Sweep {
    /// The task list: the theory not computed yet, then every run of `todo` longest first
    /// (cost T·(K + 50), ties by point index then run index), each with its cost estimate.
    fn jobs(&self, todo: &[&Point]) -> (Vec<(Job, u64)>, TheoryState) {
        let cfg = self.config();
        let mut jobs = Vec::new();
        let mut st = TheoryState::default();
        if self.theory.get().is_none() && cfg.certificate && !cfg.is_2d() {
            st.certificate_task = true;
            jobs.push((Job::Certificate, 0));
        }
        if self.linear.get().is_none() && cfg.linear {
            let controllers: Vec<(Option<usize>, ControllerChoice)> = match &cfg.k_c_grid {
                None => vec![(None, cfg.controller)],
                Some(g) => g
                    .iter()
                    .map(|&k_c| (Some(k_c), cfg.controller_for(Some(k_c))))
                    .collect(),
            };
            for &s in &cfg.solvers {
                for &(k_c, c) in &controllers {
                    jobs.push((Job::Linear(st.linear.len(), s, k_c, c), 0));
                    st.linear.push(None);
                }
            }
        }
        if self.certified.get().is_none() && cfg.is_2d() {
            st.boundaries = vec![None; cfg.solvers.len()];
            jobs.extend((0..cfg.solvers.len()).map(|i| (Job::Boundary(i), 0)));
        }
        st.left = jobs.len();
        let mut runs: Vec<(Job, u64)> = todo
            .iter()
            .enumerate()
            .flat_map(|(slot, p)| {
                let cost = run_cost(p.k + p.k_c.unwrap_or(0), self.steps());
                (0..cfg.seeds).map(move |run| (Job::Run { slot, run }, cost))
            })
            .collect();
        // Stable: equal costs keep point order, then run order.
        runs.sort_by_key(|r| std::cmp::Reverse(r.1));
        jobs.extend(runs);
        (jobs, st)
    }

    /// Runs the theory and every run of `todo` on `threads` workers, writing each point's
    /// file into `pdir` as it finishes.
    pub(super) fn execute(
        &self,
        todo: &[&Point],
        threads: usize,
        pdir: &Path,
        progress: &dyn Progress,
    ) -> Result<PoolOutcome> {
        let (jobs, theory) = self.jobs(todo);
        let seeds = self.config().seeds;
        let ready = theory.left == 0;
        let sh = Shared {
            sweep: self,
            todo,
            next: AtomicUsize::new(0),
            abort: AtomicBool::new(false),
            error: Mutex::new(None),
            results: (0..todo.len() * seeds).map(|_| OnceLock::new()).collect(),
            remaining: (0..todo.len()).map(|_| AtomicUsize::new(seeds)).collect(),
            theory: Mutex::new(theory),
            theory_ready: AtomicBool::new(ready),
            files: Mutex::new(BTreeMap::new()),
            steps: AtomicU64::new(0),
            pdir,
            progress,
            clock: Instant::now(),
            jobs,
        };
        let mut times: Vec<Option<TaskTime>> = vec![None; sh.jobs.len()];
        // A rayon pool whose every thread runs one worker loop (`broadcast`): the theory's
        // own parallel parts (γ₁,₃ enumeration, ρ_lin per K) then run on the calling worker
        // (and on workers that ran out of tasks), not on a second pool competing for cores.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("sweep-{i}"))
            .build()
            .map_err(|e| SweepError::Threads(e.to_string()))?;
        let mut help_s = 0.0;
        for (mine, help) in pool.broadcast(|ctx| sh.worker(ctx.index())) {
            help_s += help;
            for (i, t) in mine {
                times[i] = Some(t);
            }
        }
        let pool_wall_s = sh.clock.elapsed().as_secs_f64();
        if let Some(e) = lock(&sh.error).take() {
            return Err(e);
        }
        Ok(PoolOutcome {
            files: std::mem::take(&mut *lock(&sh.files)),
            steps: sh.steps.load(Ordering::Relaxed),
            schedule: ScheduleReport {
                threads,
                pool_wall_s,
                help_s,
                tasks: times.into_iter().flatten().collect(),
            },
        })
    }
}

impl Shared<'_> {
    fn worker(&self, w: usize) -> (Vec<(usize, TaskTime)>, f64) {
        let mut mine = Vec::new();
        let mut help_s = 0.0;
        // The loop of the point this worker ran last: (slot, loop).
        let mut lp: Option<(usize, ScenarioLoop)> = None;
        while !self.abort.load(Ordering::Relaxed) {
            // Between tasks, help with the pending pieces of a theory task's own parallel
            // parts (the γ₁,₃ enumeration's `par_iter` on another worker).
            let h = Instant::now();
            let mut helped = false;
            while let Some(rayon::Yield::Executed) = rayon::yield_now() {
                helped = true;
            }
            if helped {
                help_s += h.elapsed().as_secs_f64();
            }
            let i = self.next.fetch_add(1, Ordering::Relaxed);
            let Some(&(job, cost)) = self.jobs.get(i) else {
                break;
            };
            // The CPU-clock reads (system calls) are inside the timed interval: a process
            // switch at their return counts in the task, not between tasks.
            let start = Instant::now();
            let cpu = thread_cpu_s();
            let mut build_s = 0.0;
            let (kind, point, run) = match job {
                Job::Certificate => (TaskKind::Certificate, None, None),
                Job::Linear(..) => (TaskKind::Linear, None, None),
                Job::Boundary(_) => (TaskKind::Boundary, None, None),
                Job::Run { slot, run } => (TaskKind::Run, Some(self.todo[slot].index), Some(run)),
            };
            let res = match job {
                Job::Run { slot, run } => self.run(slot, run, cost, &mut lp, &mut build_s),
                theory => self.theory_task(theory),
            };
            let cpu_s = thread_cpu_s() - cpu;
            let busy_s = start.elapsed().as_secs_f64();
            if let Err(e) = res {
                lock(&self.error).get_or_insert(e);
                self.abort.store(true, Ordering::Relaxed);
            }
            mine.push((
                i,
                TaskTime {
                    kind,
                    point,
                    run,
                    cost,
                    worker: w,
                    start_s: (start - self.clock).as_secs_f64(),
                    busy_s,
                    build_s,
                    cpu_s,
                },
            ));
        }
        (mine, help_s)
    }

    fn run(
        &self,
        slot: usize,
        run: usize,
        cost: u64,
        lp: &mut Option<(usize, ScenarioLoop)>,
        build_s: &mut f64,
    ) -> Result<()> {
        let sweep = self.sweep;
        let p = self.todo[slot];
        let cfg = sweep.config();
        let l = match lp {
            Some((s, l)) if *s == slot => l,
            _ => {
                *lp = None; // free the previous point's loop first
                let t = Instant::now();
                let l = sweep.build(p)?;
                *build_s = t.elapsed().as_secs_f64();
                &mut lp.insert((slot, l)).1
            }
        };
        let input = (
            sweep.scenario().sets.input.lower(),
            sweep.scenario().sets.input.upper(),
        );
        let seed = run_seed(sweep.base_seed(), p, run, cfg.common_random_numbers);
        let m = simulate(l, run, seed, input, cfg.bounded_factor).map_err(|source| {
            SweepError::Setup {
                point: p.to_string(),
                source,
            }
        })?;
        self.steps.fetch_add(m.steps as u64, Ordering::Relaxed);
        let _ = self.results[slot * cfg.seeds + run].set(m);
        self.progress.run_done(cost);
        if self.remaining[slot].fetch_sub(1, Ordering::AcqRel) == 1 {
            if !self.theory_ready.load(Ordering::Acquire) {
                let mut st = lock(&self.theory);
                // Checked again under the lock: the theory may have finished meanwhile.
                if !self.theory_ready.load(Ordering::Acquire) {
                    st.pending.push(slot);
                    return Ok(());
                }
            }
            self.write_point(slot)?;
        }
        Ok(())
    }

    fn theory_task(&self, job: Job) -> Result<()> {
        let sweep = self.sweep;
        let cfg = sweep.config();
        let resolved = sweep.resolved();
        let mut out_cert = None;
        let mut out_linear = None;
        let mut out_boundary = None;
        match job {
            Job::Certificate => {
                out_cert = Some(solver_theory(resolved, &cfg.solvers, cfg.controller));
            }
            Job::Linear(i, s, k_c, c) => {
                let grid = cfg.k_grid.clone();
                out_linear = solver_linear(resolved, &[s], &[(k_c, c)], |_| grid.clone())
                    .0
                    .into_iter()
                    .next()
                    .map(|e| (i, e));
            }
            Job::Boundary(i) => {
                let s = cfg.solvers[i];
                let st = certified_boundary(resolved, s, cfg.controller, &cfg.k_grid);
                out_boundary = Some((i, (s, st)));
            }
            Job::Run { .. } => return Ok(()),
        }
        let pending = {
            let mut st = lock(&self.theory);
            if out_cert.is_some() {
                st.certificates = out_cert;
            }
            if let Some((i, e)) = out_linear {
                st.linear[i] = Some(e);
            }
            if let Some((i, b)) = out_boundary {
                st.boundaries[i] = Some(b);
            }
            st.left -= 1;
            if st.left > 0 {
                return Ok(());
            }
            if let Some(v) = st.certificates.take().filter(|_| st.certificate_task) {
                let _ = sweep.theory.set(v);
            }
            if !st.linear.is_empty() {
                let v = std::mem::take(&mut st.linear).into_iter().flatten();
                let _ = sweep.linear.set(LinearSide(v.collect()));
            }
            if !st.boundaries.is_empty() {
                let v = std::mem::take(&mut st.boundaries).into_iter().flatten();
                let _ = sweep.certified.set(v.collect());
            }
            self.theory_ready.store(true, Ordering::Release);
            std::mem::take(&mut st.pending)
        };
        for slot in pending {
            self.write_point(slot)?;
        }
        Ok(())
    }

    /// Writes the file of a point whose runs are all done.
    fn write_point(&self, slot: usize) -> Result<()> {
        let p = self.todo[slot];
        let seeds = self.sweep.config().seeds;
        let runs: Vec<RunMetrics> = self.results[slot * seeds..(slot + 1) * seeds]
            .iter()
            .filter_map(|c| c.get().cloned())
            .collect();
        let file = self.sweep.point_file(p, &runs);
        file.write_atomic(&self.pdir.join(point_file_name(p.index)))?;
        self.progress.point_done(p);
        lock(&self.files).insert(p.index, file);
        Ok(())
    }
}
