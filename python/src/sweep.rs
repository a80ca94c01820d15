//! `sweep(config, out_dir, threads)`: `mhe_sweep::Sweep::run` into `out_dir` on a thread of
//! its own while the calling (main) thread polls `Python::check_signals`; Ctrl-C sets the
//! flag the workers poll between tasks (`Progress::cancelled`), the sweep stops, and
//! `KeyboardInterrupt` is raised. Finished point files are kept (a rerun resumes).

use mhe_sweep::{Progress, RunOptions, Sweep, SweepConfig, SweepError};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// The flag a Ctrl-C sets.
struct Cancel(AtomicBool);

impl Progress for Cancel {
    fn cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

fn sweep_err(e: &SweepError) -> PyErr {
    let mut msg = e.to_string();
    let mut src = std::error::Error::source(e);
    while let Some(s) = src {
        msg.push_str(&format!(": {s}"));
        src = s.source();
    }
    match e {
        SweepError::Config { .. } | SweepError::Toml(_) | SweepError::Threads(_) => {
            crate::InputError::new_err(msg)
        }
        SweepError::Scenario { .. } => crate::ScenarioError::new_err(msg),
        _ => crate::MheError::new_err(msg),
    }
}

/// Runs the sweep of `config` (a file path, or TOML text with `base_dir` for its relative
/// paths) into `out_dir`; returns the paths of runs.csv and points.csv.
#[pyfunction]
#[pyo3(signature = (config, out_dir, threads=1, is_text=false, base_dir=None))]
pub(crate) fn sweep_run(
    py: Python<'_>,
    config: &str,
    out_dir: PathBuf,
    threads: usize,
    is_text: bool,
    base_dir: Option<PathBuf>,
) -> PyResult<(PathBuf, PathBuf)> {
    let cfg = if is_text {
        SweepConfig::from_toml_str(config, &base_dir.unwrap_or_else(|| PathBuf::from(".")))
    } else {
        SweepConfig::from_file(config)
    }
    .map_err(|e| sweep_err(&e))?;
    let sweep = py
        .detach(move || Sweep::new(cfg))
        .map_err(|e| sweep_err(&e))?;
    let opts = RunOptions {
        out_dir: out_dir.clone(),
        threads,
        shard: None,
    };
    let cancel = Cancel(AtomicBool::new(false));
    let result = std::thread::scope(|s| -> PyResult<_> {
        let h = s.spawn(|| sweep.run(&opts, &cancel));
        loop {
            if h.is_finished() {
                return h
                    .join()
                    .map_err(|_| crate::MheError::new_err("the sweep panicked"));
            }
            if let Err(e) = py.check_signals() {
                cancel.0.store(true, Ordering::Relaxed);
                // The running tasks finish (one run or theory task each), then the pool ends.
                let _ = py.detach(|| h.join());
                return Err(e);
            }
            py.detach(|| std::thread::sleep(Duration::from_millis(20)));
        }
    })?;
    result.map_err(|e| sweep_err(&e))?;
    Ok((out_dir.join("runs.csv"), out_dir.join("points.csv")))
}
