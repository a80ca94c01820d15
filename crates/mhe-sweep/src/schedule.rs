//! The sweep's scheduling policy, its measured task times and a replay of them.
//!
//! **Policy.** One pool of `threads` workers runs one list of tasks: first the theory, as a
//! graph of small tasks (`graph.rs`: γ₁,₃'s plan and its ≤ 64 enumeration chunks, L_π's
//! ≤ 32 enumeration chunks, ρ_lin per solver and K_c, the certificate's assembly, the
//! theory of each solver), each ready once its inputs are done; then every run of every
//! point, ordered longest first by the estimate [`run_cost`](super::run_cost) = T·(K + 50)
//! (ties: point index, then run index). A free worker takes the first *ready* task of the
//! list: a ready theory task if there is one, else the next run (one shared atomic
//! counter), else it waits for a theory task to finish. A worker keeps the loop of the
//! point it ran last and builds a new one when it takes a run of another point (the *build*
//! time of a task).
//!
//! **Replay.** [`ScheduleReport::replay`] pushes the measured task times through the same
//! policy for another worker count: the simulated worker that is free first (lowest index
//! on a tie) takes the first task of the list whose inputs have finished by then (it idles
//! until the next input finishes when only waiting theory tasks are left); a run task costs
//! its measured time without its build, plus the point's mean measured build time when the
//! simulated worker last ran another point; the measured help with a theory task's own
//! parallel parts (`help_s`, rayon pieces run between tasks) is shared evenly by the
//! workers other than the first before they take their first task.
//! Assumptions (docs/sweeps.md, "Scaling"): a task takes as long on any worker count as it
//! took when measured (no memory-bandwidth, cache, turbo or SMT effects), dispatch costs
//! nothing, and the serial part is the measured one.

#[cfg(feature = "serde")]
use serde::Serialize;

/// What one task of the list computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum TaskKind {
    /// γ₁,₃'s plan: families, candidate metrics, their S-procedure figures.
    Gamma13Plan,
    /// One mask chunk of γ₁,₃'s free-set enumeration.
    Gamma13Enumeration,
    /// One mask chunk of L_π's free-set enumeration.
    LPiEnumeration,
    /// ρ_lin(K) of one solver (and K_c in a 2-D sweep).
    Linear,
    /// The certificate assembled from its pieces (L_Φ, Theorem 1 per solver).
    Certificate,
    /// The certificate covering one solver (and its (K_e, K_c) staircase in a 2-D sweep).
    Solver,
    /// K_reg of one solver (per distinct uncertainty of the scales): the regional
    /// certificate's search.
    Regional,
    /// One run of one point.
    Run,
}

impl TaskKind {
    /// Every kind, in the order of the list.
    pub const ALL: [TaskKind; 8] = [
        TaskKind::Gamma13Plan,
        TaskKind::Gamma13Enumeration,
        TaskKind::LPiEnumeration,
        TaskKind::Linear,
        TaskKind::Certificate,
        TaskKind::Solver,
        TaskKind::Regional,
        TaskKind::Run,
    ];

    /// The name written in `tasks.csv`.
    pub fn name(self) -> &'static str {
        match self {
            TaskKind::Gamma13Plan => "gamma13_plan",
            TaskKind::Gamma13Enumeration => "gamma13_enumeration",
            TaskKind::LPiEnumeration => "l_pi_enumeration",
            TaskKind::Linear => "linear",
            TaskKind::Certificate => "certificate",
            TaskKind::Solver => "solver",
            TaskKind::Regional => "regional",
            TaskKind::Run => "run",
        }
    }
}

/// One executed task: what it was and how long it took.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct TaskTime {
    /// What the task computed.
    pub kind: TaskKind,
    /// The point of a run task (its index in the sweep).
    pub point: Option<usize>,
    /// The run index of a run task.
    pub run: Option<usize>,
    /// The tasks whose results it needs (positions in [`ScheduleReport::tasks`]): it is
    /// ready once they are done. Empty for runs.
    pub after: Vec<usize>,
    /// The scheduler's cost estimate, T·(K + 50) (0 for theory tasks).
    pub cost: u64,
    /// The worker that ran it.
    pub worker: usize,
    /// When it started, seconds after the pool started.
    pub start_s: f64,
    /// Its wall time on the worker (build, run, and any point file it wrote).
    pub busy_s: f64,
    /// Of which building the point's loop (0 when the worker had it).
    pub build_s: f64,
    /// The worker thread's CPU time during the task (None where the platform has no
    /// per-thread CPU clock): below `busy_s` when other processes took the core.
    pub cpu_s: Option<f64>,
}

/// The measured schedule of a [`Sweep::run`](super::Sweep::run).
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct ScheduleReport {
    /// Workers of the pool.
    pub threads: usize,
    /// Wall time from the pool's start to the last worker's end.
    pub pool_wall_s: f64,
    /// Time workers spent between tasks on pieces of a theory task's own parallel parts
    /// (the γ₁,₃ enumeration), summed over workers; busy, but in no task.
    pub help_s: f64,
    /// Every task, in list (scheduling) order.
    pub tasks: Vec<TaskTime>,
}

/// A replay's prediction for one worker count.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Prediction {
    /// Workers.
    pub threads: usize,
    /// Predicted wall time of the pool.
    pub pool_wall_s: f64,
    /// Predicted Σ busy / (threads × pool wall) (the builds the replay adds count as busy).
    pub efficiency: f64,
    /// Loop builds of the replayed schedule.
    pub builds: usize,
}

impl ScheduleReport {
    /// Σ of the tasks' busy times and the help time.
    pub fn busy_s(&self) -> f64 {
        self.tasks.iter().map(|t| t.busy_s).sum::<f64>() + self.help_s
    }
    /// Σ of the tasks' CPU times (None when a task's is not measurable).
    pub fn cpu_s(&self) -> Option<f64> {
        self.tasks.iter().map(|t| t.cpu_s).sum()
    }
    /// Σ of the build times.
    pub fn build_s(&self) -> f64 {
        self.tasks.iter().map(|t| t.build_s).sum()
    }
    /// Loop builds.
    pub fn builds(&self) -> usize {
        self.tasks.iter().filter(|t| t.build_s > 0.0).count()
    }
    /// Measured efficiency Σ busy / (threads × pool wall) (0 without tasks).
    pub fn efficiency(&self) -> f64 {
        if self.pool_wall_s > 0.0 && self.threads > 0 {
            self.busy_s() / (self.threads as f64 * self.pool_wall_s)
        } else {
            0.0
        }
    }
    /// Σ busy of the tasks of each kind, in the order of [`TaskKind::ALL`] (kinds without
    /// tasks left out).
    pub fn busy_by_kind(&self) -> Vec<(TaskKind, usize, f64)> {
        TaskKind::ALL
            .into_iter()
            .map(|k| {
                let of: Vec<&TaskTime> = self.tasks.iter().filter(|t| t.kind == k).collect();
                (k, of.len(), of.iter().map(|t| t.busy_s).sum())
            })
            .filter(|(_, n, _)| *n > 0)
            .collect()
    }
    /// The longest chain of theory tasks through their inputs (the sum of the measured busy
    /// times along it): a lower bound on the pool's wall time at any thread count.
    pub fn critical_path_s(&self) -> f64 {
        let mut end = vec![0.0f64; self.tasks.len()];
        let mut best = 0.0f64;
        for (i, t) in self.tasks.iter().enumerate() {
            let ready = t
                .after
                .iter()
                .filter_map(|&d| end.get(d).copied())
                .fold(0.0, f64::max);
            end[i] = ready + t.busy_s;
            best = best.max(end[i]);
        }
        best
    }
    /// The longest task's busy time.
    pub fn longest_task_s(&self) -> f64 {
        self.tasks.iter().map(|t| t.busy_s).fold(0.0, f64::max)
    }

    /// Replays the measured task times through the scheduler's policy on `threads`
    /// workers (module docs: policy and assumptions).
    pub fn replay(&self, threads: usize) -> Prediction {
        self.replay_tasks(threads, |_| true)
    }

    /// [`ScheduleReport::replay`] of the run tasks alone: how the runs balance, without the
    /// theory's tasks (whose one certificate task is a sequential chain that bounds the
    /// makespan on many threads).
    pub fn replay_runs(&self, threads: usize) -> Prediction {
        self.replay_tasks(threads, |t| t.kind == TaskKind::Run)
    }

    fn replay_tasks(&self, threads: usize, keep: impl Fn(&TaskTime) -> bool) -> Prediction {
        let threads = threads.max(1);
        // Mean measured build time per point.
        let mut builds: std::collections::BTreeMap<usize, (f64, usize)> = Default::default();
        for t in &self.tasks {
            if let (Some(p), true) = (t.point, t.build_s > 0.0) {
                let e = builds.entry(p).or_insert((0.0, 0));
                e.0 += t.build_s;
                e.1 += 1;
            }
        }
        let build_of = |p: usize| builds.get(&p).map_or(0.0, |&(s, n)| s / n as f64);
        // Worker state: free at, current point.
        let mut free = vec![0.0f64; threads];
        // The help with a theory task's parallel parts: done by the workers other than the
        // first, shared evenly; on one worker, by that worker.
        let help = if self
            .tasks
            .iter()
            .any(|t| keep(t) && t.kind != TaskKind::Run)
        {
            self.help_s
        } else {
            0.0
        };
        if threads == 1 {
            free[0] = help;
        } else {
            for f in free.iter_mut().skip(1) {
                *f = help / (threads - 1) as f64;
            }
        }
        let mut current: Vec<Option<usize>> = vec![None; threads];
        let (mut busy, mut n_builds) = (help, 0);
        // When each task finished in the replay (None: not started, or not kept — an input
        // that is not kept counts as done at 0).
        let mut end: Vec<Option<f64>> = self
            .tasks
            .iter()
            .map(|t| if keep(t) { None } else { Some(0.0) })
            .collect();
        let mut waiting: Vec<usize> = (0..self.tasks.len())
            .filter(|&i| keep(&self.tasks[i]) && self.tasks[i].kind != TaskKind::Run)
            .collect();
        let mut runs = (0..self.tasks.len())
            .filter(|&i| keep(&self.tasks[i]) && self.tasks[i].kind == TaskKind::Run)
            .peekable();
        loop {
            // The first free worker (lowest index on a tie), as a shared counter gives.
            let (w, at) = free
                .iter()
                .enumerate()
                .fold(
                    (0, f64::INFINITY),
                    |best, (i, &f)| {
                        if f < best.1 { (i, f) } else { best }
                    },
                );
            let done_by = |d: &usize| end.get(*d).copied().flatten().is_some_and(|e| e <= at);
            let pick = match waiting
                .iter()
                .position(|&i| self.tasks[i].after.iter().all(done_by))
            {
                Some(pos) => Some(waiting.remove(pos)),
                None => runs.next(),
            };
            let Some(i) = pick else {
                if waiting.is_empty() {
                    break;
                }
                // Only theory tasks whose inputs are running are left: wait for the next
                // input to finish.
                let next = end
                    .iter()
                    .flatten()
                    .copied()
                    .filter(|&e| e > at)
                    .fold(f64::INFINITY, f64::min);
                if !next.is_finite() {
                    break; // an input that never runs (a failed sweep): stop
                }
                free[w] = next;
                continue;
            };
            let t = &self.tasks[i];
            let mut d = t.busy_s - t.build_s;
            if let Some(p) = t.point {
                if current[w] != Some(p) {
                    d += build_of(p);
                    n_builds += 1;
                    current[w] = Some(p);
                }
            }
            busy += d;
            free[w] = at + d;
            end[i] = Some(at + d);
        }
        let wall = free
            .iter()
            .copied()
            .chain(end.iter().flatten().copied())
            .fold(0.0, f64::max);
        Prediction {
            threads,
            pool_wall_s: wall,
            efficiency: if wall > 0.0 {
                busy / (threads as f64 * wall)
            } else {
                0.0
            },
            builds: n_builds,
        }
    }

    /// The task list as CSV (header + one row per task, in list order).
    pub fn tasks_csv(&self) -> String {
        let mut s =
            String::from("order,kind,point,run,cost,worker,start_s,busy_s,build_s,cpu_s,after\n");
        let opt = |v: Option<usize>| v.map(|v| v.to_string()).unwrap_or_default();
        for (i, t) in self.tasks.iter().enumerate() {
            s.push_str(&format!(
                "{i},{},{},{},{},{},{:.6},{:.6},{:.6},{},{}\n",
                t.kind.name(),
                opt(t.point),
                opt(t.run),
                t.cost,
                t.worker,
                t.start_s,
                t.busy_s,
                t.build_s,
                t.cpu_s.map_or_else(String::new, |c| format!("{c:.6}")),
                t.after
                    .iter()
                    .map(|d| d.to_string())
                    .collect::<Vec<_>>()
                    .join(" ")
            ));
        }
        s
    }
}

/// CPU time of the calling thread in seconds (None where not available).
pub(super) fn thread_cpu_s() -> Option<f64> {
    #[cfg(target_os = "linux")]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `ts` is a valid, writable timespec; the clock id is a constant.
        let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
        if rc == 0 {
            return Some(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(point: usize, busy: f64, build: f64) -> TaskTime {
        TaskTime {
            kind: TaskKind::Run,
            point: Some(point),
            run: Some(0),
            after: Vec::new(),
            cost: 1,
            worker: 0,
            start_s: 0.0,
            busy_s: busy,
            build_s: build,
            cpu_s: Some(busy),
        }
    }

    #[test]
    fn replay_is_list_scheduling_with_builds() {
        // One point, four runs of 1 s of which the first carried a 0.5 s build.
        let r = ScheduleReport {
            threads: 1,
            pool_wall_s: 4.0,
            help_s: 0.0,
            tasks: vec![
                run(0, 1.5, 0.5),
                run(0, 1.0, 0.0),
                run(0, 1.0, 0.0),
                run(0, 1.0, 0.0),
            ],
        };
        assert!((r.efficiency() - 4.5 / 4.0).abs() < 1e-12);
        let one = r.replay(1);
        assert_eq!((one.pool_wall_s, one.builds), (4.5, 1));
        // Two workers: each builds once (0.5) and runs two tasks: 2.5 s.
        let two = r.replay(2);
        assert_eq!((two.pool_wall_s, two.builds), (2.5, 2));
        assert!((two.efficiency - 1.0).abs() < 1e-12);
        // More workers than tasks: the makespan is one build + one run.
        let many = r.replay(8);
        assert_eq!((many.pool_wall_s, many.builds), (1.5, 4));
        assert!((many.efficiency - 6.0 / 12.0).abs() < 1e-12);
    }

    #[test]
    fn replay_shares_the_help_among_the_other_workers() {
        // A 4 s certificate (worker 0) whose parallel part took 2 s of another worker's
        // time, then four 1 s runs of four points.
        let mut tasks = vec![TaskTime {
            kind: TaskKind::Certificate,
            point: None,
            run: None,
            ..run(0, 4.0, 0.0)
        }];
        tasks.extend((0..4).map(|p| run(p, 1.0, 0.0)));
        let r = ScheduleReport {
            threads: 2,
            pool_wall_s: 5.0,
            help_s: 2.0,
            tasks,
        };
        assert_eq!(r.busy_s(), 10.0);
        // One worker does everything: 10 s. Two: worker 1 helps 2 s, then runs 3 tasks
        // (5 s); worker 0 runs the certificate and one run (5 s).
        assert_eq!(r.replay(1).pool_wall_s, 10.0);
        assert_eq!(r.replay(2).pool_wall_s, 5.0);
        assert!((r.replay(2).efficiency - 1.0).abs() < 1e-12);
        // The runs alone carry no help.
        assert_eq!(r.replay_runs(2).pool_wall_s, 2.0);
    }

    #[test]
    fn replay_waits_for_a_task_s_inputs() {
        // A 1 s plan, two 1 s chunks after it, a 0.5 s assembly after both, four 1 s runs.
        let theory = |kind, busy, after: Vec<usize>| TaskTime {
            kind,
            point: None,
            run: None,
            after,
            ..run(0, busy, 0.0)
        };
        let mut tasks = vec![
            theory(TaskKind::Gamma13Plan, 1.0, vec![]),
            theory(TaskKind::Gamma13Enumeration, 1.0, vec![0]),
            theory(TaskKind::Gamma13Enumeration, 1.0, vec![0]),
            theory(TaskKind::Certificate, 0.5, vec![1, 2]),
        ];
        tasks.extend((0..4).map(|p| run(p, 1.0, 0.0)));
        let r = ScheduleReport {
            threads: 1,
            pool_wall_s: 7.5,
            help_s: 0.0,
            tasks,
        };
        assert_eq!(r.critical_path_s(), 2.5);
        assert_eq!(r.replay(1).pool_wall_s, 7.5);
        // Two workers: a run beside the plan, the chunks side by side, then the assembly
        // on one worker and the three runs left: 2.5 | 2 + 1, then 3.5 and 4.
        assert_eq!(r.replay(2).pool_wall_s, 4.0);
        // Four: the plan beside three runs, the chunks beside the last run, one worker
        // idles until the chunks end, then the assembly: the critical path.
        let four = r.replay(4);
        assert_eq!(four.pool_wall_s, 2.5);
        assert!((four.efficiency - 7.5 / 10.0).abs() < 1e-12);
        // The runs alone: 4 × 1 s.
        assert_eq!(r.replay_runs(4).pool_wall_s, 1.0);
    }

    #[test]
    fn replay_takes_tasks_in_list_order() {
        // Longest first on two workers: 3 | 2 + 1 → 3 s. Shortest first: 1 | 2, then 3 on
        // the worker free at 1 → 4 s.
        let mk = |d: &[f64]| ScheduleReport {
            threads: 1,
            pool_wall_s: 6.0,
            help_s: 0.0,
            tasks: d.iter().enumerate().map(|(i, &b)| run(i, b, 0.0)).collect(),
        };
        assert_eq!(mk(&[3.0, 2.0, 1.0]).replay(2).pool_wall_s, 3.0);
        assert_eq!(mk(&[1.0, 2.0, 3.0]).replay(2).pool_wall_s, 4.0);
    }
}
