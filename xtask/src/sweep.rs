//! `cargo xtask sweep` and `cargo xtask sweep-merge`: argument handling, the progress bar,
//! `meta.json` and the SVG plot files (line plots over K for a 1-D sweep, heat maps over
//! (K_e, K_c) for a 2-D one: chosen and drawn by `mhe_sweep::plots`). The sweep itself (runs, seeds, shards, point files,
//! resume, CSV assembly) is `closed_loop::sweep`, unit-tested there.

use std::fmt::Write as _;
use std::io::IsTerminal as _;
use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, anyhow, bail};
use indicatif::{ProgressBar, ProgressStyle};
use lti_model::numfmt::sig4;
use serde_json::json;
use xtask::sweep_engine::{
    Assembled, PairThresholds, Point, Progress, RunOptions, Shard, Sweep, SweepConfig, SweepReport,
    Table, Thresholds, merge_staged, pair_thresholds_markdown, thresholds_markdown,
};

use crate::output::{OutputSet, check_out_dir};
use crate::provenance::{Provenance, workspace_root};

mod timing;
// `cargo xtask sweep-merge`: the shards' sets checked and merged.
mod merge;
mod records;
pub use merge::merge;
use mhe_plots::shorten;

/// Arguments of `cargo xtask sweep`.
#[derive(Debug, Clone, clap::Args)]
pub struct SweepArgs {
    /// The sweep config (TOML; docs/sweeps.md).
    #[arg(long, value_name = "FILE.toml")]
    pub config: PathBuf,
    /// Output directory [default: target/sweeps/<name> in the workspace]. Rerunning into
    /// the same directory resumes: finished points are skipped.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Worker threads of the pool [default: all logical CPUs].
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Run only shard I of N (1 ≤ I ≤ N; points with index mod N = I − 1); assemble the
    /// shards with `sweep-merge`.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
}

/// Arguments of `cargo xtask sweep-merge`.
#[derive(Debug, Clone, clap::Args)]
pub struct MergeArgs {
    /// The sweep config the shards ran.
    #[arg(long, value_name = "FILE.toml")]
    pub config: PathBuf,
    /// Where to assemble runs.csv, points.csv, meta.json and the plots.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Shard output directories [default: DIR itself, when every shard wrote there].
    #[arg(value_name = "SHARD_DIR")]
    pub inputs: Vec<PathBuf>,
}

/// A progress bar in cost units (T·(K + 50) per run) so the ETA follows the expensive K,
/// drawn only when stderr is a terminal.
struct Bar(ProgressBar);

impl Progress for Bar {
    fn start(&self, points: usize, runs: u64, cost: u64, skipped: usize) {
        // Elapsed time and ETA from here (after the certificate), not from the bar's creation.
        self.0.reset();
        self.0.set_length(cost.max(1));
        self.0.set_message(format!("{points} points, {runs} runs"));
        if skipped > 0 {
            self.0.println(format!(
                "resuming: {skipped} points finished before are skipped"
            ));
        }
    }
    fn run_done(&self, cost: u64) {
        self.0.inc(cost);
    }
    fn point_done(&self, p: &Point) {
        let k_c = p.k_c.map(|k| format!(" K_c = {k}")).unwrap_or_default();
        self.0
            .set_message(format!("done: K = {}{k_c} {}", p.k, p.solver));
    }
    fn notice(&self, message: &str) {
        self.0.suspend(|| errln!("note: {message}"));
    }
}

/// The [`Progress`] of `sweep-merge`: no bar, only the notices.
struct Notices;

impl Progress for Notices {
    fn notice(&self, message: &str) {
        errln!("note: {message}");
    }
}

fn progress_bar() -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(1);
    if let Ok(style) = ProgressStyle::with_template(
        "{elapsed_precise} [{bar:40}] {percent:>3}% ETA {eta_precise}  {msg}",
    ) {
        bar.set_style(style);
    }
    bar
}

fn unix_now() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// `YYYY-MM-DDTHH:MM:SSZ` for seconds since the epoch (proleptic Gregorian, UTC).
fn iso_utc(unix: f64) -> String {
    let secs = unix.max(0.0) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Days to civil date (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// Host name, CPU model and logical CPUs (best effort; unknowns recorded as such).
fn host() -> serde_json::Value {
    let read = |p: &str| {
        std::fs::read_to_string(p)
            .ok()
            .map(|s| s.trim().to_string())
    };
    let name = read("/proc/sys/kernel/hostname")
        .or_else(|| read("/etc/hostname"))
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_else(|| "unknown".into());
    let cpu = read("/proc/cpuinfo").and_then(|s| {
        s.lines()
            .find(|l| l.starts_with("model name"))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_string())
    });
    json!({
        "name": name,
        "cpu": cpu,
        "logical_cpus": std::thread::available_parallelism().map_or(0, |n| n.get()),
        "os": std::env::consts::OS,
        "arch": std::env::consts::ARCH,
    })
}

fn load(config: &Path) -> Result<(String, Sweep)> {
    let text = lti_model::spec::format::read_limited(config)
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("cannot read the sweep config `{}`", config.display()))?;
    let cfg = SweepConfig::from_file(config)
        .with_context(|| format!("in the sweep config `{}`", config.display()))?;
    let sweep = Sweep::new(cfg)?;
    Ok((text, sweep))
}

fn meta(
    sweep: &Sweep,
    config_path: &Path,
    config_text: &str,
    times: (f64, f64),
    extra: serde_json::Value,
) -> serde_json::Value {
    let cfg = sweep.config();
    let prov = Provenance::collect();
    let mut v = json!({
        "format": "suboptimal-mhe/sweep-meta",
        "format_version": 1,
        "name": cfg.name,
        "config_path": config_path.display().to_string(),
        "config_toml": config_text,
        "scenario_path": cfg.scenario.display().to_string(),
        "scenario_name": sweep.scenario().name,
        "fingerprint": sweep.fingerprint(),
        "base_seed": sweep.base_seed(),
        "seed_rule": if cfg.common_random_numbers {
            "seed(run r) = splitmix64(splitmix64(base_seed ^ splitmix64(0)) ^ r), the same at every point (common random numbers)"
        } else {
            if cfg.is_2d() {
                "seed(point, run r) = splitmix64(splitmix64(base_seed ^ splitmix64(fnv1a(\"K/solver/scale_bits/K_c\"))) ^ r)"
            } else {
                "seed(point, run r) = splitmix64(splitmix64(base_seed ^ splitmix64(fnv1a(\"K/solver/scale_bits\"))) ^ r)"
            }
        },
        "k_grid": cfg.k_grid,
        "k_c_grid": cfg.k_c_grid,
        "cost": cfg.k_c_grid.as_ref().map(|_| json!({
            "t_e": cfg.cost.t_e,
            "t_c": cfg.cost.t_c,
            "rule": "cost(K_e, K_c) = K_e·t_e + K_c·t_c (config `cost`; default 1:1 counts iterations, not time)",
        })),
        "solvers": cfg.solvers.iter().map(|s| s.name()).collect::<Vec<_>>(),
        "seeds": cfg.seeds,
        "scales": sweep.points().iter().map(|p| p.scale).fold(Vec::<f64>::new(), |mut v, s| { if !v.contains(&s) { v.push(s); } v }),
        "steps": sweep.steps(),
        "exact_mhe_solve": cfg.exact_mhe_solve,
        "controller": format!("{:?}", cfg.controller),
        "metrics": cfg.metrics.iter().map(|m| m.name()).collect::<Vec<_>>(),
        "bounded_rule": format!("completed, finite, sup_t ‖x_t‖ ≤ {f}·(1 + ‖x₀‖) and sup_t ‖e_t‖ ≤ {f}·(1 + ‖e₀‖)", f = cfg.bounded_factor),
        "converged_rule": format!(
            "bounded, and over the last quarter of the steps mean ‖e_t‖ ≤ {f}·w̄ + {d:e}·(1 + ‖e₀‖) and mean ‖x_t‖ ≤ {f}·w̄ + {d:e}·(1 + ‖x₀‖), w̄ = sup_t ‖w_t‖ of the run",
            f = closed_loop::metrics::CONVERGED_FACTOR,
            d = closed_loop::metrics::CONVERGED_FLOOR
        ),
        "points": sweep.points().len(),
        "git_revision": prov.git_revision,
        "git_dirty": prov.git_dirty,
        "rustc": prov.rustc,
        "tool_version": prov.tool_version,
        "host": host(),
        "command": std::env::args().collect::<Vec<_>>(),
        "start_unix": times.0,
        "end_unix": times.1,
        "start_utc": iso_utc(times.0),
        "end_utc": iso_utc(times.1),
        "wall_s": times.1 - times.0,
        "run": extra,
    });
    if !cfg.is_2d() {
        // A 1-D sweep's meta.json keeps the keys it always had.
        if let Some(obj) = v.as_object_mut() {
            obj.remove("k_c_grid");
            obj.remove("cost");
        }
    }
    v
}

/// `v` as pretty JSON text with a final newline.
fn json_text(v: &serde_json::Value) -> Result<String> {
    Ok(serde_json::to_string_pretty(v)? + "\n")
}

/// Stages `runs.csv` and `points.csv` (when assembled), then what `stage` adds (the
/// plots, `tasks.csv`, and last the meta file), in one [`OutputSet`] and commits it: every
/// file is on disk under a temporary name before the first is renamed into place, so a
/// failure or a kill before the commit leaves the previous complete output, and the meta
/// file, renamed last, lists every other file of the set with its size and hash
/// ([`OutputSet::manifest`]). Returns the table of `points.csv` passed to `stage`.
fn write_set(
    out: &Path,
    outputs: Option<&Assembled>,
    stage: impl FnOnce(&mut OutputSet, Option<&Table>) -> Result<()>,
) -> Result<()> {
    let mut set = OutputSet::new(out)?;
    let table = match outputs {
        Some(a) => {
            set.add("runs.csv", a.runs.as_bytes())?;
            set.add("points.csv", a.points.as_bytes())?;
            if let Some(k) = &a.kalman {
                set.add("kalman.csv", k.as_bytes())?;
            }
            Some(Table::parse(&a.points).map_err(|e| anyhow!("points.csv: {e}"))?)
        }
        None => None,
    };
    stage(&mut set, table.as_ref())?;
    set.commit()?;
    Ok(())
}

/// `cargo xtask sweep`.
/// `--threads` may be at most this many per logical CPU.
const MAX_THREADS_PER_CORE: usize = 4;

pub fn sweep(args: &SweepArgs) -> Result<()> {
    let start = unix_now();
    let clock = Instant::now();
    // Parse the shard before any work: a bad spec is a typed error, not a late surprise.
    let shard = args.shard.as_deref().map(str::parse::<Shard>).transpose()?;
    let threads = thread_count(args.threads)?;
    // --out is checked before the config is resolved (the certificate can take minutes).
    if let Some(out) = &args.out {
        check_out_dir(out, "--out")?;
    }
    let (config_text, sweep) = load(&args.config)?;
    let out = args.out.clone().unwrap_or_else(|| {
        workspace_root()
            .join("target/sweeps")
            .join(&sweep.config().name)
    });
    check_out_dir(&out, "--out")?;
    announce(&sweep, threads, shard, &out);
    let bar = Bar(progress_bar());
    // runs.csv and points.csv come back unwritten, with the directory's lock held: they are
    // committed in one set with the plots and meta.json (`write_set`).
    let staged = sweep.run_staged(
        &RunOptions {
            out_dir: out.clone(),
            threads,
            shard,
        },
        &bar,
    )?;
    let report = &staged.report;
    bar.0.finish_and_clear();
    if report.computed > 0 {
        outln!("certificate: {}", theory_summary(&sweep));
    }
    let meta_name = match shard {
        Some(s) => format!("meta.shard-{}-of-{}.json", s.index, s.count),
        None => "meta.json".into(),
    };
    let written = write_outputs(
        args,
        &sweep,
        &config_text,
        &staged,
        (shard, threads),
        (start, clock),
        &out,
        &meta_name,
    )?;
    let (thresholds, pairs, plots) = (&written.thresholds, &written.pairs, &written.plots);
    print_thresholds(&sweep, thresholds, pairs);
    print_summary(
        report,
        clock.elapsed().as_secs_f64(),
        &out,
        &meta_name,
        plots,
        sweep.config().kalman,
    );
    for line in timing::schedule_lines(report, written.serial_s, written.wall) {
        outln!("{line}");
    }
    Ok(())
}

/// `--threads`, checked: at least 1, at most [`MAX_THREADS_PER_CORE`] per core; the number of
/// cores without it.
fn thread_count(threads: Option<usize>) -> Result<usize> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let max_threads = MAX_THREADS_PER_CORE * cores;
    Ok(match threads {
        Some(0) => bail!("--threads must be ≥ 1"),
        Some(n) if n > max_threads => bail!(
            "--threads {n} is more than {MAX_THREADS_PER_CORE} per core ({cores} cores here: at most \
             {max_threads}); runs are CPU-bound, so more threads only add memory and switching"
        ),
        Some(n) => n,
        None => cores,
    })
}

/// The first line: what the sweep runs, on how many threads, into which directory.
fn announce(sweep: &Sweep, threads: usize, shard: Option<Shard>, out: &Path) {
    let cfg = sweep.config();
    let n_k_c = cfg.k_c_grid.as_ref().map_or(1, Vec::len);
    outln!(
        "sweep `{}`: {} points ({} K{} × {} solvers × {} scales) × {} seeds, T = {}, {} threads{} → {}",
        cfg.name,
        sweep.points().len(),
        cfg.k_grid.len(),
        cfg.k_c_grid
            .as_ref()
            .map(|g| format!(" × {} K_c", g.len()))
            .unwrap_or_default(),
        cfg.solvers.len(),
        sweep.points().len() / (cfg.k_grid.len() * n_k_c * cfg.solvers.len()).max(1),
        cfg.seeds,
        sweep.steps(),
        threads,
        shard.map(|s| format!(", shard {s}")).unwrap_or_default(),
        out.display()
    );
}

/// What [`write_outputs`] computed for the end-of-run lines.
struct Written {
    plots: Vec<String>,
    thresholds: Vec<Thresholds>,
    pairs: Vec<PairThresholds>,
    /// The command's wall time outside the pool, and in all, when meta.json was written.
    serial_s: f64,
    wall: f64,
}

/// Commits runs.csv, points.csv, the thresholds, plots, tasks.csv and meta.json in one set
/// (`write_set`).
#[allow(clippy::too_many_arguments)]
fn write_outputs(
    args: &SweepArgs,
    sweep: &Sweep,
    config_text: &str,
    staged: &xtask::sweep_engine::Staged,
    (shard, threads): (Option<Shard>, usize),
    (start, clock): (f64, Instant),
    out: &Path,
    meta_name: &str,
) -> Result<Written> {
    let report = &staged.report;
    let tasks_name = match shard {
        Some(s) => format!("tasks.shard-{}-of-{}.csv", s.index, s.count),
        None => "tasks.csv".into(),
    };
    let mut plots = Vec::new();
    let mut thresholds = Vec::new();
    let mut pairs = Vec::new();
    let (mut serial_s, mut wall) = (0.0, 0.0);
    write_set(out, staged.outputs.as_ref(), |set, table| {
        if let Some(table) = table {
            (thresholds, pairs) = sweep.all_thresholds(table);
            plots = draw(sweep, set, table, &pairs)?;
        }
        let end = unix_now();
        // Serial time: the command's wall time outside the pool (setup, checks, assembly,
        // thresholds, plots; meta.json and tasks.csv take milliseconds).
        wall = clock.elapsed().as_secs_f64();
        serial_s = (wall - report.schedule.pool_wall_s).max(0.0);
        if !report.schedule.tasks.is_empty() {
            set.add(&tasks_name, report.schedule.tasks_csv().as_bytes())?;
        }
        let extra = json!({
            "threads": threads,
            "shard": shard.map(|s| s.to_string()),
            "points_computed": report.computed,
            "points_skipped_resumed": report.skipped,
            "closed_loop_steps": report.steps_simulated,
            "runs_wall_s": report.runs_wall_s,
            "steps_per_second_per_thread": report.steps_per_second_per_thread(),
            "schedule": timing::schedule_json(report, serial_s, wall, &tasks_name),
            "plots": plots,
            "thresholds": records::thresholds(&thresholds),
            "files": set.manifest(),
        });
        let extra = with_2d(sweep, extra, &pairs);
        let text = json_text(&meta(sweep, &args.config, config_text, (start, end), extra))?;
        set.add(meta_name, text.as_bytes())?;
        Ok(())
    })?;
    Ok(Written {
        plots,
        thresholds,
        pairs,
        serial_s,
        wall,
    })
}

/// The end-of-run lines (numbers with at most 4 significant digits, [`sig4`]; `kalman`:
/// the sweep runs the Kalman baseline).
fn print_summary(
    report: &SweepReport,
    wall: f64,
    out: &Path,
    meta: &str,
    plots: &[String],
    kalman: bool,
) {
    outln!(
        "points: {} computed, {} skipped (finished before)",
        report.computed,
        report.skipped
    );
    outln!(
        "closed-loop steps: {} in {} s of runs on {} threads = {} steps/s per thread",
        report.steps_simulated,
        sig4(report.runs_wall_s),
        report.threads,
        sig4(report.steps_per_second_per_thread())
    );
    if report.assembled {
        outln!(
            "wrote {}/{{runs.csv, points.csv, {}{meta}}} and {} plots",
            out.display(),
            if kalman { "kalman.csv, " } else { "" },
            plots.len()
        );
    } else {
        outln!(
            "shard done: point files in {}/points{}, {meta}; assemble with `cargo xtask sweep-merge`",
            out.display(),
            if kalman {
                " (with its part of kalman.csv)"
            } else {
                ""
            }
        );
    }
    outln!("total wall time: {} s", sig4(wall));
}

/// Stages the plots of an assembled sweep (`mhe_sweep::plots`: line plots over K for 1-D,
/// heat maps for 2-D) in `set`; returns the file names.
fn draw(
    sweep: &Sweep,
    set: &mut OutputSet,
    table: &Table,
    pairs: &[PairThresholds],
) -> Result<Vec<String>> {
    let mut written = Vec::new();
    for (name, svg) in xtask::sweep_engine::plots::draw(sweep, table, pairs)? {
        set.add(&name, svg.as_bytes())?;
        written.push(name);
    }
    Ok(written)
}

fn print_thresholds(sweep: &Sweep, thresholds: &[Thresholds], pairs: &[PairThresholds]) {
    if sweep.config().is_2d() {
        if !pairs.is_empty() {
            let c = sweep.config().cost;
            outln!(
                "2-D thresholds (a region holds a pair when its criterion holds at every grid pair with K_e and K_c at least as large; cost K_e·{} + K_c·{}{}):",
                c.t_e,
                c.t_c,
                if c == xtask::sweep_engine::IterationCost::default() {
                    ", the default 1:1 — iterations, not time"
                } else {
                    ""
                }
            );
            outln!("{}", pair_thresholds_markdown(pairs).trim_end_matches('\n'));
        }
    } else if !thresholds.is_empty() {
        outln!(
            "thresholds (K_lin: ρ_lin < 1 from here on the grid; K_reg: the regional certificate's smallest K; K_emp: every run bounded from here on; K_cert: the smallest K the one verdict certifies (Theorem 1, Theorem L3 from K_glob on, the iteration chain at the K it checked, or the joint certificate with a K_c-iteration MPC; not a threshold: points.csv `certified` says which grid K are)):"
        );
        outln!("{}", thresholds_markdown(thresholds).trim_end_matches('\n'));
    }
}

/// `meta.json`'s `run` with the 2-D thresholds and the joint certificate's boundary (a 1-D
/// sweep's `run` is unchanged).
fn with_2d(
    sweep: &Sweep,
    mut extra: serde_json::Value,
    pairs: &[PairThresholds],
) -> serde_json::Value {
    if !sweep.config().is_2d() {
        return extra;
    }
    let certified: Vec<serde_json::Value> = sweep
        .certified_boundaries()
        .iter()
        .map(|(m, st)| {
            if st.is_empty() {
                json!({ "solver": m.to_string(), "status": "not computed" })
            } else {
                json!({ "solver": m.to_string(), "status": "computed", "staircase": st })
            }
        })
        .collect();
    if let Some(obj) = extra.as_object_mut() {
        obj.insert(
            "pair_thresholds".into(),
            json!(records::pair_thresholds(pairs)),
        );
        obj.insert("certified_boundary".into(), json!(certified));
    }
    extra
}

/// A one-line description of a sweep's theory per solver, for the terminal.
pub fn theory_summary(sweep: &Sweep) -> String {
    if sweep.config().is_2d() {
        let computed = sweep
            .certified_boundaries()
            .iter()
            .filter(|(_, st)| !st.is_empty())
            .count();
        return if computed == 0 {
            "the joint (K_e, K_c) certificate could not be computed (xtask::sweep_engine::certified_boundary); Theorem 1's columns are void for the sub-optimal MPC".to_string()
        } else {
            format!(
                "the joint (K_e, K_c) certificate's region for {computed} of {} solvers (drawn on the heat maps)",
                sweep.config().solvers.len()
            )
        };
    }
    let mut s = String::new();
    for p in sweep
        .config()
        .solvers
        .iter()
        .filter_map(|sv| sweep.points().iter().find(|p| p.solver == *sv))
    {
        let t = sweep.theory_at(p);
        let _ = write!(
            s,
            "{}: {}, {}, {}; ",
            p.solver,
            match (t.certified, t.k_min) {
                ("void", _) => format!("void ({})", shorten(&t.void_reason, 60)),
                (_, Some(k)) => format!("smallest certified K = {k}"),
                _ => "no certified K".into(),
            },
            match (t.k_lin, t.linear_note.is_empty()) {
                (Some(k), _) => format!("K_lin = {k}"),
                (None, true) => "ρ_lin ≥ 1 at the largest K".into(),
                (None, false) => shorten(&t.linear_note, 60),
            },
            match t.k_reg {
                Some(k) => format!("K_reg = {k}"),
                None => format!("no K_reg ({})", shorten(&t.regional_note, 60)),
            }
        );
    }
    s
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn iso_dates() {
        assert_eq!(iso_utc(0.0), "1970-01-01T00:00:00Z");
        // 2000-02-29 12:34:56 UTC = 951827696 (leap day of a century leap year).
        assert_eq!(iso_utc(951_827_696.0), "2000-02-29T12:34:56Z");
        assert_eq!(iso_utc(1_700_000_000.0), "2023-11-14T22:13:20Z");
    }
}
