//! Executing a sweep on one pool of worker threads: the theory (the task graph of
//! `graph.rs`: the certificate's pieces, ρ_lin, the per-solver theory) and every run of every point as tasks of one list, in the order and by the
//! policy of `schedule.rs`; each point file written by the worker that finishes the point's
//! last run (once the theory it needs is there), the task times recorded.
//!
//! Determinism: a run's result depends on (point, run) only — a worker restarts the
//! point's loop with [`ScenarioLoop::reseed`], equivalent to a fresh build — and results are
//! stored by (point, run), so which worker ran what changes nothing in the outputs.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, MutexGuard, OnceLock};
use std::time::Instant;

use super::config::Point;
use super::error::{Result, SweepError};
use super::format::{PointFile, point_file_name};
use super::graph::TheoryGraph;
use super::run::{Progress, Sweep, run_cost, simulate};
use super::schedule::{ScheduleReport, TaskKind, TaskTime, thread_cpu_s};
use super::seeds::run_seed;
use super::summary::SweepRun;
use closed_loop::scenario::ScenarioLoop;

/// What a task computes.
#[derive(Debug, Clone, Copy)]
enum Job {
    /// Task `i` of the theory graph.
    Theory(usize),
    /// Run `run` of `todo[slot]`.
    Run { slot: usize, run: usize },
}

/// The theory tasks' readiness (`schedule.rs`: a free worker takes the first ready task).
#[derive(Debug, Default)]
struct Ready {
    /// Inputs not done yet, per theory task.
    inputs_left: Vec<usize>,
    /// The theory tasks that need each one.
    needed_by: Vec<Vec<usize>>,
    taken: Vec<bool>,
    /// Theory tasks not taken yet.
    open: usize,
    /// Theory tasks not finished yet.
    left: usize,
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
    graph: TheoryGraph<'a>,
    n_theory: usize,
    next_run: AtomicUsize,
    /// Theory tasks not taken yet (read without the lock: 0 means only runs are left).
    theory_open: AtomicUsize,
    ready: Mutex<Ready>,
    finished: Condvar,
    abort: AtomicBool,
    error: Mutex<Option<SweepError>>,
    results: Vec<OnceLock<SweepRun>>,
    remaining: Vec<AtomicUsize>,
    theory_ready: AtomicBool,
    files: Mutex<BTreeMap<usize, PointFile>>,
    steps: AtomicU64,
    pdir: &'a Path,
    progress: &'a dyn Progress,
    clock: Instant,
}

impl Sweep {
    /// The theory graph of what is not computed yet (`graph.rs`) and every run of `todo`
    /// longest first (cost T·(K + 50), ties by point index then run index), each with its
    /// cost estimate; the theory that needs no task is stored at once.
    fn jobs<'a>(&'a self, todo: &[&Point]) -> (Vec<(Job, u64)>, TheoryGraph<'a>) {
        let cfg = self.config();
        let (graph, ready) = TheoryGraph::new(
            self.resolved(),
            cfg,
            self.theory.get().is_none() && (cfg.certificate || cfg.is_2d()),
            self.linear.get().is_none() && cfg.linear,
            self.certified.get().is_none() && cfg.is_2d(),
            (self.regional.get().is_none() && self.regional_unavailable().is_none())
                .then(|| self.theory.get().map(Vec::as_slice)),
        );
        self.store(ready);
        let mut jobs: Vec<(Job, u64)> =
            (0..graph.jobs.len()).map(|i| (Job::Theory(i), 0)).collect();
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
        (jobs, graph)
    }

    /// Stores what the theory graph computed in the sweep's caches.
    fn store(&self, r: super::graph::TheoryResults) {
        if let Some(v) = r.theory {
            let _ = self.theory.set(v);
        }
        if let Some(v) = r.linear {
            let _ = self.linear.set(v);
        }
        if let Some(v) = r.boundaries {
            let _ = self.certified.set(v);
        }
        if let Some(v) = r.regional {
            let _ = self.regional.set(v);
        }
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
        let (jobs, graph) = self.jobs(todo);
        let seeds = self.config().seeds;
        let n_theory = graph.jobs.len();
        let mut ready = Ready {
            inputs_left: graph.jobs.iter().map(|(_, d)| d.len()).collect(),
            needed_by: vec![Vec::new(); n_theory],
            taken: vec![false; n_theory],
            open: n_theory,
            left: n_theory,
            pending: Vec::new(),
        };
        for (i, (_, deps)) in graph.jobs.iter().enumerate() {
            for &d in deps {
                ready.needed_by[d].push(i);
            }
        }
        let sh = Shared {
            sweep: self,
            todo,
            n_theory,
            next_run: AtomicUsize::new(0),
            theory_open: AtomicUsize::new(n_theory),
            ready: Mutex::new(ready),
            finished: Condvar::new(),
            abort: AtomicBool::new(false),
            error: Mutex::new(None),
            results: (0..todo.len() * seeds).map(|_| OnceLock::new()).collect(),
            remaining: (0..todo.len()).map(|_| AtomicUsize::new(seeds)).collect(),
            theory_ready: AtomicBool::new(n_theory == 0),
            files: Mutex::new(BTreeMap::new()),
            steps: AtomicU64::new(0),
            pdir,
            progress,
            clock: Instant::now(),
            graph,
            jobs,
        };
        let mut times: Vec<Option<TaskTime>> = vec![None; sh.jobs.len()];
        // A rayon pool whose every thread runs one worker loop (`broadcast`): a theory
        // task's own parallel parts (the γ₁,₃ plan's figures per metric) then run on the
        // calling worker (and on workers between two tasks), not on a second pool competing
        // for cores.
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
            if self.progress.cancelled() {
                lock(&self.error).get_or_insert(SweepError::Cancelled);
                self.abort.store(true, Ordering::Relaxed);
                // Wake the workers waiting for a theory task.
                let _ready = lock(&self.ready);
                self.finished.notify_all();
                break;
            }
            let Some(i) = self.next_task() else {
                break;
            };
            let (job, cost) = self.jobs[i];
            // The CPU-clock reads (system calls) are inside the timed interval: a process
            // switch at their return counts in the task, not between tasks.
            let start = Instant::now();
            let cpu = thread_cpu_s();
            let mut build_s = 0.0;
            let (kind, point, run, after) = match job {
                Job::Theory(t) => {
                    let (j, deps) = &self.graph.jobs[t];
                    (j.kind(), None, None, deps.clone())
                }
                Job::Run { slot, run } => (
                    TaskKind::Run,
                    Some(self.todo[slot].index),
                    Some(run),
                    Vec::new(),
                ),
            };
            let res = match job {
                Job::Run { slot, run } => self.run(slot, run, cost, &mut lp, &mut build_s),
                Job::Theory(t) => self.theory_task(t),
            };
            let cpu_s = thread_cpu_s().zip(cpu).map(|(end, start)| end - start);
            let busy_s = start.elapsed().as_secs_f64();
            if let Err(e) = res {
                lock(&self.error).get_or_insert(e);
                self.abort.store(true, Ordering::Relaxed);
                // Wake the workers waiting for a theory task.
                let _ready = lock(&self.ready);
                self.finished.notify_all();
            }
            mine.push((
                i,
                TaskTime {
                    kind,
                    point,
                    run,
                    after,
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
        let disturbance = &sweep.scenario().sets.disturbance;
        let m =
            simulate(l, run, seed, input, disturbance, cfg.bounded_factor).map_err(|source| {
                SweepError::Setup {
                    point: p.to_string(),
                    source,
                }
            })?;
        self.steps
            .fetch_add(m.metrics.steps as u64, Ordering::Relaxed);
        let _ = self.results[slot * cfg.seeds + run].set(m);
        self.progress.run_done(cost);
        if self.remaining[slot].fetch_sub(1, Ordering::AcqRel) == 1 {
            if !self.theory_ready.load(Ordering::Acquire) {
                let mut st = lock(&self.ready);
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

    /// The first ready task of the list (module docs of `schedule.rs`): a ready theory
    /// task, else the next run, else (only theory tasks waiting for inputs left) the first
    /// that becomes ready; None when nothing is left.
    fn next_task(&self) -> Option<usize> {
        let next_run = || {
            let r = self.next_run.fetch_add(1, Ordering::Relaxed);
            (self.n_theory + r < self.jobs.len()).then_some(self.n_theory + r)
        };
        if self.theory_open.load(Ordering::Acquire) == 0 {
            return next_run();
        }
        let mut q = lock(&self.ready);
        loop {
            if q.open == 0 || self.abort.load(Ordering::Relaxed) {
                drop(q);
                return next_run();
            }
            if let Some(t) = (0..self.n_theory).find(|&t| !q.taken[t] && q.inputs_left[t] == 0) {
                q.taken[t] = true;
                q.open -= 1;
                self.theory_open.store(q.open, Ordering::Release);
                return Some(t);
            }
            if let Some(r) = next_run() {
                return Some(r);
            }
            q = self
                .finished
                .wait(q)
                .unwrap_or_else(std::sync::PoisonError::into_inner);
        }
    }

    fn theory_task(&self, t: usize) -> Result<()> {
        self.graph.run(t);
        let pending = {
            let mut q = lock(&self.ready);
            let needed_by = std::mem::take(&mut q.needed_by[t]);
            for d in needed_by {
                q.inputs_left[d] -= 1;
            }
            q.left -= 1;
            self.finished.notify_all();
            if q.left > 0 {
                return Ok(());
            }
            self.sweep.store(self.graph.results());
            self.theory_ready.store(true, Ordering::Release);
            std::mem::take(&mut q.pending)
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
        let runs: Vec<SweepRun> = self.results[slot * seeds..(slot + 1) * seeds]
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
