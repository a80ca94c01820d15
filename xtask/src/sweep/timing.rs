//! The schedule of a sweep in `meta.json` and on the terminal: serial time, the pool's
//! measured efficiency, and the replay of the measured task times for other thread counts
//! (`xtask::sweep_engine::ScheduleReport`; model and assumptions in docs/sweeps.md,
//! "Scaling").

use serde_json::json;
use xtask::sweep_engine::{Prediction, SweepReport};

/// Thread counts the replay predicts (1 and 2 check the model against measured walls).
pub const PREDICT_AT: [usize; 4] = [1, 2, 16, 64];

/// `meta.json`'s `run.schedule`: `serial_s` is the command's wall time outside the pool,
/// `wall_s` the whole command's.
pub fn schedule_json(
    report: &SweepReport,
    serial_s: f64,
    wall_s: f64,
    tasks_file: &str,
) -> serde_json::Value {
    let s = &report.schedule;
    let busy = s.busy_s();
    let with_serial = |threads: usize, pool: f64| {
        let wall = serial_s + pool;
        if wall > 0.0 {
            busy / (threads as f64 * wall)
        } else {
            0.0
        }
    };
    let predicted: Vec<serde_json::Value> = PREDICT_AT
        .iter()
        .map(|&n| {
            let p: Prediction = s.replay(n);
            let r = s.replay_runs(n);
            json!({
                "threads": n,
                "pool_wall_s": p.pool_wall_s,
                "wall_s": serial_s + p.pool_wall_s,
                "efficiency": p.efficiency,
                "efficiency_with_serial": with_serial(n, p.pool_wall_s),
                "builds": p.builds,
                "runs_only": {
                    "pool_wall_s": r.pool_wall_s,
                    "efficiency": r.efficiency,
                },
            })
        })
        .collect();
    json!({
        "policy": "one pool: the theory as a task graph (a task ready when its inputs are done), then every run longest first by T·(K + 50); a free worker takes the first ready task (docs/sweeps.md, Scaling)",
        "threads": s.threads,
        "wall_s": wall_s,
        "serial_s": serial_s,
        "serial_fraction": if wall_s > 0.0 { serial_s / wall_s } else { 0.0 },
        "pool_wall_s": s.pool_wall_s,
        "tasks": s.tasks.len(),
        "tasks_file": if s.tasks.is_empty() { None } else { Some(tasks_file) },
        "busy_s": busy,
        "cpu_s": s.cpu_s(),
        "help_s": s.help_s,
        "builds": s.builds(),
        "build_s": s.build_s(),
        "longest_task_s": s.longest_task_s(),
        "critical_path_s": s.critical_path_s(),
        "busy_by_kind": s.busy_by_kind().iter().map(|(k, n, b)| json!({"kind": k.name(), "tasks": n, "busy_s": b})).collect::<Vec<_>>(),
        "efficiency": s.efficiency(),
        "efficiency_with_serial": with_serial(s.threads, s.pool_wall_s),
        "predicted": predicted,
    })
}

/// The schedule's lines for the end of the sweep.
pub fn schedule_lines(report: &SweepReport, serial_s: f64, wall_s: f64) -> Vec<String> {
    let s = &report.schedule;
    if s.tasks.is_empty() {
        return vec![format!("serial time {serial_s:.2} s (nothing to compute)")];
    }
    let busy = s.busy_s();
    let kinds: Vec<String> = s
        .busy_by_kind()
        .iter()
        .map(|(k, n, b)| format!("{n} {} {b:.2} s", k.name()))
        .collect();
    let mut lines = vec![
        format!(
            "schedule: {} tasks ({}), Σ busy {busy:.2} s (thread CPU {:.2} s), pool {:.2} s on {} threads: efficiency {:.1} %",
            s.tasks.len(),
            kinds.join(", "),
            s.cpu_s(),
            s.pool_wall_s,
            s.threads,
            100.0 * s.efficiency()
        ),
        format!(
            "serial time {serial_s:.3} s = {:.2} % of the wall time {wall_s:.2} s",
            if wall_s > 0.0 {
                100.0 * serial_s / wall_s
            } else {
                0.0
            }
        ),
    ];
    let preds: Vec<String> = PREDICT_AT
        .iter()
        .map(|&n| {
            let p = s.replay(n);
            format!(
                "{n} threads {:.2} s ({:.1} %)",
                p.pool_wall_s,
                100.0 * p.efficiency
            )
        })
        .collect();
    lines.push(format!(
        "replay of these task times (pool wall, efficiency): {}",
        preds.join(", ")
    ));
    lines.push(format!(
        "longest task {:.3} s, longest chain of theory tasks (a bound on the pool wall at any thread count) {:.3} s",
        s.longest_task_s(),
        s.critical_path_s()
    ));
    let runs: Vec<String> = PREDICT_AT
        .iter()
        .map(|&n| {
            let p = s.replay_runs(n);
            format!(
                "{n}: {:.2} s ({:.1} %)",
                p.pool_wall_s,
                100.0 * p.efficiency
            )
        })
        .collect();
    lines.push(format!(
        "replay of the run tasks alone: {}",
        runs.join(", ")
    ));
    lines
}
