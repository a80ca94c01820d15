//! `Progress::cancelled`: a sweep stops between tasks with `SweepError::Cancelled`, and the
//! point files it finished stay valid (a rerun resumes from them).

use mhe_sweep::{Point, Progress, RunOptions, Sweep, SweepConfig, SweepError};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Cancels once `after` runs have finished.
struct CancelAfter {
    after: usize,
    runs: AtomicUsize,
    points: AtomicUsize,
}

impl Progress for CancelAfter {
    fn run_done(&self, _cost: u64) {
        self.runs.fetch_add(1, Ordering::Relaxed);
    }
    fn point_done(&self, _point: &Point) {
        self.points.fetch_add(1, Ordering::Relaxed);
    }
    fn cancelled(&self) -> bool {
        self.runs.load(Ordering::Relaxed) >= self.after
    }
}

fn config() -> SweepConfig {
    let scenario = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenarios/case-study-certified.toml")
        .display()
        .to_string()
        .replace('\\', "/");
    let text = format!(
        "name = \"cancel\"\nscenario = \"{scenario}\"\nk = [1, 4, 25]\nsolvers = [\"pg\"]\n\
         seeds = 3\nsteps = 8\nbase_seed = 5\ncertificate = false\n"
    );
    SweepConfig::from_toml_str(&text, Path::new(".")).expect("a valid config")
}

#[test]
fn a_cancelled_sweep_stops_between_tasks_and_a_rerun_resumes() {
    let sweep = Sweep::new(config()).expect("builds");
    let dir = std::env::temp_dir().join(format!("mhe-sweep-cancel-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let opts = RunOptions {
        out_dir: dir.clone(),
        threads: 1,
        shard: None,
    };
    let total = sweep.points().len() * 3;
    // Cancelled at once: nothing runs.
    let p = CancelAfter {
        after: 0,
        runs: AtomicUsize::new(0),
        points: AtomicUsize::new(0),
    };
    let e = sweep.run(&opts, &p).expect_err("cancelled");
    assert!(matches!(e, SweepError::Cancelled), "{e}");
    assert_eq!(p.runs.load(Ordering::Relaxed), 0);
    // Cancelled after 4 runs (one worker): exactly 4 ran, one point (3 seeds) was written.
    let p = CancelAfter {
        after: 4,
        runs: AtomicUsize::new(0),
        points: AtomicUsize::new(0),
    };
    let e = sweep.run(&opts, &p).expect_err("cancelled");
    assert!(matches!(e, SweepError::Cancelled), "{e}");
    assert_eq!(p.runs.load(Ordering::Relaxed), 4);
    assert!(p.runs.load(Ordering::Relaxed) < total);
    // Not cancelled: resumes, skipping the finished point.
    let p = CancelAfter {
        after: usize::MAX,
        runs: AtomicUsize::new(0),
        points: AtomicUsize::new(0),
    };
    let report = sweep.run(&opts, &p).expect("completes");
    assert!(report.skipped >= 1, "{report:?}");
    assert!(dir.join("runs.csv").is_file() && dir.join("points.csv").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}
