//! The schedule of a sweep in `meta.json` and on the terminal: serial time, the pool's
//! measured efficiency, and the replay of the measured task times for other thread counts
//! (`xtask::sweep_engine::ScheduleReport`; model and assumptions in docs/sweeps.md,
//! "Scaling").

use lti_model::numfmt::sig4;
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

/// The schedule's lines for the end of the sweep (numbers with at most 4 significant
/// digits, [`sig4`]).
pub fn schedule_lines(report: &SweepReport, serial_s: f64, wall_s: f64) -> Vec<String> {
    let s = &report.schedule;
    if s.tasks.is_empty() {
        return vec![format!(
            "serial time {} s (nothing to compute)",
            sig4(serial_s)
        )];
    }
    let busy = s.busy_s();
    let kinds: Vec<String> = s
        .busy_by_kind()
        .iter()
        .map(|(k, n, b)| format!("{n} {} {} s", k.name(), sig4(*b)))
        .collect();
    let mut lines = vec![
        format!(
            "schedule: {} tasks ({}), Σ busy {} s (thread CPU {} s), pool {} s on {} threads: efficiency {} %",
            s.tasks.len(),
            kinds.join(", "),
            sig4(busy),
            s.cpu_s().map_or_else(|| "not measured".to_string(), sig4),
            sig4(s.pool_wall_s),
            s.threads,
            sig4(100.0 * s.efficiency())
        ),
        format!(
            "serial time {} s = {} % of the wall time {} s",
            sig4(serial_s),
            sig4(if wall_s > 0.0 {
                100.0 * serial_s / wall_s
            } else {
                0.0
            }),
            sig4(wall_s)
        ),
    ];
    let preds: Vec<String> = PREDICT_AT
        .iter()
        .map(|&n| {
            let p = s.replay(n);
            format!(
                "{n} threads {} s ({} %)",
                sig4(p.pool_wall_s),
                sig4(100.0 * p.efficiency)
            )
        })
        .collect();
    lines.push(format!(
        "replay of these task times (pool wall, efficiency): {}",
        preds.join(", ")
    ));
    lines.push(format!(
        "longest task {} s, longest chain of theory tasks (a bound on the pool wall at any thread count) {} s",
        sig4(s.longest_task_s()),
        sig4(s.critical_path_s())
    ));
    let runs: Vec<String> = PREDICT_AT
        .iter()
        .map(|&n| {
            let p = s.replay_runs(n);
            format!(
                "{n}: {} s ({} %)",
                sig4(p.pool_wall_s),
                sig4(100.0 * p.efficiency)
            )
        })
        .collect();
    lines.push(format!(
        "replay of the run tasks alone: {}",
        runs.join(", ")
    ));
    lines
}
