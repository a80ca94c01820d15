//! `cargo xtask sweep` and `cargo xtask sweep-merge`: argument handling, the progress bar,
//! `meta.json` and the SVG plots. The sweep itself (runs, seeds, shards, point files,
//! resume, CSV assembly) is `closed_loop::sweep`, unit-tested there.

use std::fmt::Write as _;
use std::io::IsTerminal as _;
use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, anyhow, bail};
use closed_loop::sweep::{
    Point, Progress, RunOptions, Shard, Sweep, SweepConfig, SweepReport, Table, merge_point_dirs,
};
use indicatif::{ProgressBar, ProgressStyle};
use plotters::prelude::*;
use serde_json::json;

use crate::provenance::{Provenance, workspace_root};

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
    /// Worker threads of the rayon pool [default: all logical CPUs].
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
        self.0
            .set_message(format!("done: K = {} {}", p.k, p.solver));
    }
    fn notice(&self, message: &str) {
        self.0.suspend(|| eprintln!("note: {message}"));
    }
}

/// The [`Progress`] of `sweep-merge`: no bar, only the notices.
struct Notices;

impl Progress for Notices {
    fn notice(&self, message: &str) {
        eprintln!("note: {message}");
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
    let cfg = SweepConfig::from_file(config)?;
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
    json!({
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
            "seed(point, run r) = splitmix64(splitmix64(base_seed ^ splitmix64(fnv1a(\"K/solver/scale_bits\"))) ^ r)"
        },
        "k_grid": cfg.k_grid,
        "solvers": cfg.solvers.iter().map(|s| s.name()).collect::<Vec<_>>(),
        "seeds": cfg.seeds,
        "scales": sweep.points().iter().map(|p| p.scale).fold(Vec::<f64>::new(), |mut v, s| { if !v.contains(&s) { v.push(s); } v }),
        "steps": sweep.steps(),
        "exact_mhe_solve": cfg.exact_mhe_solve,
        "controller": format!("{:?}", cfg.controller),
        "metrics": cfg.metrics.iter().map(|m| m.name()).collect::<Vec<_>>(),
        "bounded_rule": format!("completed, finite, and sup_t ‖x_t‖ ≤ {}·(1 + ‖x₀‖)", cfg.bounded_factor),
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
    })
}

fn write_json(path: &Path, v: &serde_json::Value) -> Result<()> {
    let text = serde_json::to_string_pretty(v)?;
    std::fs::write(path, text + "\n").with_context(|| format!("cannot write `{}`", path.display()))
}

/// `cargo xtask sweep`.
/// `--threads` may be at most this many per logical CPU.
const MAX_THREADS_PER_CORE: usize = 4;

pub fn sweep(args: &SweepArgs) -> Result<()> {
    let start = unix_now();
    let clock = Instant::now();
    // Parse the shard before any work: a bad spec is a typed error, not a late surprise.
    let shard = args.shard.as_deref().map(str::parse::<Shard>).transpose()?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let max_threads = MAX_THREADS_PER_CORE * cores;
    let threads = match args.threads {
        Some(0) => bail!("--threads must be ≥ 1"),
        Some(n) if n > max_threads => bail!(
            "--threads {n} is more than {MAX_THREADS_PER_CORE} per core ({cores} cores here: at most \
             {max_threads}); runs are CPU-bound, so more threads only add memory and switching"
        ),
        Some(n) => n,
        None => cores,
    };
    let (config_text, sweep) = load(&args.config)?;
    let out = args.out.clone().unwrap_or_else(|| {
        workspace_root()
            .join("target/sweeps")
            .join(&sweep.config().name)
    });
    println!(
        "sweep `{}`: {} points ({} K × {} solvers × {} scales) × {} seeds, T = {}, {} threads{} → {}",
        sweep.config().name,
        sweep.points().len(),
        sweep.config().k_grid.len(),
        sweep.config().solvers.len(),
        sweep.points().len() / (sweep.config().k_grid.len() * sweep.config().solvers.len()).max(1),
        sweep.config().seeds,
        sweep.steps(),
        threads,
        shard.map(|s| format!(", shard {s}")).unwrap_or_default(),
        out.display()
    );
    let bar = Bar(progress_bar());
    let report = sweep.run(
        &RunOptions {
            out_dir: out.clone(),
            threads,
            shard,
        },
        &bar,
    )?;
    bar.0.finish_and_clear();
    if report.computed > 0 {
        println!("certificate: {}", theory_summary(&sweep));
    }
    let plots = if report.assembled {
        plot_all(&sweep, &out)?
    } else {
        Vec::new()
    };
    let end = unix_now();
    let extra = json!({
        "threads": threads,
        "shard": shard.map(|s| s.to_string()),
        "points_computed": report.computed,
        "points_skipped_resumed": report.skipped,
        "closed_loop_steps": report.steps_simulated,
        "runs_wall_s": report.runs_wall_s,
        "steps_per_second_per_thread": report.steps_per_second_per_thread(),
        "plots": plots,
    });
    let meta_name = match shard {
        Some(s) => format!("meta.shard-{}-of-{}.json", s.index, s.count),
        None => "meta.json".into(),
    };
    write_json(
        &out.join(&meta_name),
        &meta(&sweep, &args.config, &config_text, (start, end), extra),
    )?;
    print_summary(
        &report,
        clock.elapsed().as_secs_f64(),
        &out,
        &meta_name,
        &plots,
    );
    Ok(())
}

fn print_summary(report: &SweepReport, wall: f64, out: &Path, meta: &str, plots: &[String]) {
    println!(
        "points: {} computed, {} skipped (finished before)",
        report.computed, report.skipped
    );
    println!(
        "closed-loop steps: {} in {:.2} s of runs on {} threads = {:.0} steps/s per thread",
        report.steps_simulated,
        report.runs_wall_s,
        report.threads,
        report.steps_per_second_per_thread()
    );
    if report.assembled {
        println!(
            "wrote {}/{{runs.csv, points.csv, {meta}}} and {} plots",
            out.display(),
            plots.len()
        );
    } else {
        println!(
            "shard done: point files in {}/points, {meta}; assemble with `cargo xtask sweep-merge`",
            out.display()
        );
    }
    println!("total wall time: {wall:.2} s");
}

/// `cargo xtask sweep-merge`.
pub fn merge(args: &MergeArgs) -> Result<()> {
    let start = unix_now();
    let (config_text, sweep) = load(&args.config)?;
    let inputs: Vec<&Path> = if args.inputs.is_empty() {
        vec![args.out.as_path()]
    } else {
        args.inputs.iter().map(PathBuf::as_path).collect()
    };
    let n = merge_point_dirs(&sweep, &inputs, &args.out, &Notices)?;
    let plots = plot_all(&sweep, &args.out)?;
    // Keep the shards' own meta files for the record.
    let mut shards = Vec::new();
    for d in &inputs {
        if let Ok(rd) = std::fs::read_dir(d) {
            let mut names: Vec<PathBuf> = rd
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| n.starts_with("meta.shard-"))
                })
                .collect();
            names.sort();
            for p in names {
                if let Some(v) = std::fs::read_to_string(&p)
                    .ok()
                    .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
                {
                    shards.push(json!({"file": p.display().to_string(), "meta": v}));
                }
            }
        }
    }
    let extra = json!({
        "merged_from": inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
        "shard_meta": shards,
        "plots": plots,
    });
    write_json(
        &args.out.join("meta.json"),
        &meta(
            &sweep,
            &args.config,
            &config_text,
            (start, unix_now()),
            extra,
        ),
    )?;
    println!(
        "merged {n} points from {} directories into {}/{{runs.csv, points.csv, meta.json}} and {} plots",
        inputs.len(),
        args.out.display(),
        plots.len()
    );
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Plots
// ---------------------------------------------------------------------------------------

/// One solver's curve at one scale.
#[derive(Debug, Clone, PartialEq)]
struct Curve {
    solver: String,
    /// (K, q05, q50, q95) or (K, value) for the bounded fraction (lo = mid = hi).
    points: Vec<(f64, f64, f64, f64)>,
    k_min: Option<f64>,
    void_reason: Option<String>,
}

const COLORS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

fn color_of(solver: &str) -> RGBColor {
    match solver {
        "pg" => COLORS[0],
        "fista" => COLORS[1],
        "admm" => COLORS[2],
        _ => COLORS[3],
    }
}

/// Curves of `metric` (quantile columns) or of the bounded fraction (`metric = None`) for
/// one scale, grouped by solver in order of appearance.
fn curves(table: &Table, scale: &str, metric: Option<&str>) -> Vec<Curve> {
    let mut out: Vec<Curve> = Vec::new();
    for row in 0..table.rows.len() {
        if table.text(row, "scale") != Some(scale) {
            continue;
        }
        let Some(solver) = table.text(row, "solver") else {
            continue;
        };
        let Some(k) = table.number(row, "k") else {
            continue;
        };
        let vals = match metric {
            Some(m) => (
                table.number(row, &format!("{m}_q05")),
                table.number(row, &format!("{m}_q50")),
                table.number(row, &format!("{m}_q95")),
            ),
            None => {
                let f = table.number(row, "bounded_fraction");
                (f, f, f)
            }
        };
        let idx = match out.iter().position(|c| c.solver == solver) {
            Some(i) => i,
            None => {
                let void = (table.text(row, "certified") == Some("void"))
                    .then(|| table.text(row, "void_reason").unwrap_or("").to_string());
                out.push(Curve {
                    solver: solver.to_string(),
                    points: Vec::new(),
                    k_min: table.number(row, "k_min_cert"),
                    void_reason: void,
                });
                out.len() - 1
            }
        };
        if let (Some(lo), Some(mid), Some(hi)) = vals {
            out[idx].points.push((k, lo, mid, hi));
        }
    }
    out
}

/// A chart description (data only) and its rendering.
struct BandChart<'a> {
    title: String,
    y_label: &'a str,
    log_y: bool,
    curves: Vec<Curve>,
    notes: Vec<String>,
}

/// A tick label with at most 3 significant digits and no float noise (0.6, 1000, 2.5e-5).
fn tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    let digits = (2 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn shorten(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        s.chars().take(n).collect::<String>() + "…"
    }
}

impl BandChart<'_> {
    /// Drops what a log axis cannot show, notes the K_min lines and void certificates.
    fn prepare(&mut self) {
        let mut dropped = 0;
        for c in &mut self.curves {
            let before = c.points.len();
            let log_y = self.log_y;
            c.points.retain(|&(_, lo, mid, hi)| {
                [lo, mid, hi]
                    .iter()
                    .all(|v| v.is_finite() && (!log_y || *v > 0.0))
            });
            dropped += before - c.points.len();
        }
        if dropped > 0 {
            self.notes.push(format!(
                "{dropped} points not drawn (non-finite{})",
                if self.log_y {
                    " or ≤ 0 on the log axis"
                } else {
                    ""
                }
            ));
        }
        let (k_lo, k_hi) = self.k_range();
        for c in &self.curves {
            match (&c.void_reason, c.k_min) {
                (Some(r), _) => self.notes.push(format!(
                    "{}: certificate void, no K_min line ({})",
                    c.solver,
                    shorten(r, 90)
                )),
                (None, Some(k)) if k < k_lo || k > k_hi => self.notes.push(format!(
                    "{}: certified K_min = {k} lies outside the K grid",
                    c.solver
                )),
                (None, None) => self.notes.push(format!(
                    "{}: no certified K within the search range",
                    c.solver
                )),
                _ => {}
            }
        }
    }

    fn k_range(&self) -> (f64, f64) {
        let ks = self
            .curves
            .iter()
            .flat_map(|c| c.points.iter().map(|p| p.0));
        let (lo, hi) = ks.fold((f64::INFINITY, 0.0f64), |(a, b), k| (a.min(k), b.max(k)));
        if lo.is_finite() {
            (lo, hi)
        } else {
            (1.0, 10.0)
        }
    }

    fn render(&self, path: &Path) -> Result<()> {
        let err = |e: &dyn std::fmt::Display| anyhow!("plot `{}`: {e}", path.display());
        let note_h = 18 * self.notes.len() as u32;
        let root = SVGBackend::new(path, (900, 540 + note_h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let (upper, lower) = root.split_vertically(540);
        let (k_lo, k_hi) = self.k_range();
        let x = (k_lo / 1.25)..(k_hi * 1.25);
        let ys = self
            .curves
            .iter()
            .flat_map(|c| c.points.iter().flat_map(|p| [p.1, p.3]));
        let (y_min, y_max) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
        let (y_min, y_max) = if y_min.is_finite() {
            (y_min, y_max)
        } else {
            (1.0, 10.0)
        };
        let mut builder = ChartBuilder::on(&upper);
        builder
            .caption(&self.title, ("sans-serif", 17))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(74);
        macro_rules! draw {
            ($chart:expr, $y_lo:expr, $y_hi:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc("K (iterations of Φ per MHE step, log scale)")
                    .y_desc(self.y_label)
                    .x_label_formatter(&|x: &f64| tick(*x))
                    .y_label_formatter(&|y: &f64| tick(*y))
                    .draw()
                    .map_err(|e| err(&e))?;
                for c in &self.curves {
                    let col = color_of(&c.solver);
                    if c.points.iter().any(|p| p.1 != p.3) {
                        let mut poly: Vec<(f64, f64)> =
                            c.points.iter().map(|p| (p.0, p.1)).collect();
                        poly.extend(c.points.iter().rev().map(|p| (p.0, p.3)));
                        chart
                            .draw_series(std::iter::once(Polygon::new(
                                poly,
                                col.mix(0.18).filled(),
                            )))
                            .map_err(|e| err(&e))?;
                    }
                    chart
                        .draw_series(LineSeries::new(
                            c.points.iter().map(|p| (p.0, p.2)),
                            col.stroke_width(2),
                        ))
                        .map_err(|e| err(&e))?
                        .label(c.solver.as_str())
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 22, y)], col.stroke_width(2))
                        });
                    chart
                        .draw_series(
                            c.points
                                .iter()
                                .map(|p| Circle::new((p.0, p.2), 3, col.filled())),
                        )
                        .map_err(|e| err(&e))?;
                    if let (None, Some(k)) = (&c.void_reason, c.k_min) {
                        if k >= k_lo && k <= k_hi {
                            chart
                                .draw_series(DashedLineSeries::new(
                                    vec![(k, $y_lo), (k, $y_hi)],
                                    8,
                                    5,
                                    col.stroke_width(2),
                                ))
                                .map_err(|e| err(&e))?
                                .label(format!("certified K_min({}) = {k}", c.solver))
                                .legend(move |(x, y)| {
                                    PathElement::new(
                                        vec![(x, y), (x + 6, y), (x + 11, y), (x + 17, y)],
                                        col.stroke_width(1),
                                    )
                                });
                        }
                    }
                }
                chart
                    .configure_series_labels()
                    .position(if self.log_y {
                        SeriesLabelPosition::UpperRight
                    } else {
                        SeriesLabelPosition::LowerRight
                    })
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .draw()
                    .map_err(|e| err(&e))?;
            }};
        }
        if self.log_y {
            let (lo, hi) = (y_min / 1.5, y_max * 1.5);
            let chart = builder
                .build_cartesian_2d(x.clone().log_scale(), (lo..hi).log_scale())
                .map_err(|e| err(&e))?;
            draw!(chart, lo, hi);
        } else {
            let (lo, hi) = (y_min.min(0.0), y_max.max(1.0) * 1.05);
            let chart = builder
                .build_cartesian_2d(x.clone().log_scale(), lo..hi)
                .map_err(|e| err(&e))?;
            draw!(chart, lo, hi);
        }
        for (i, n) in self.notes.iter().enumerate() {
            lower
                .draw_text(
                    n,
                    &("sans-serif", 13).into_text_style(&lower),
                    (14, 18 * i as i32),
                )
                .map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
        Ok(())
    }
}

/// The plotted metrics: (column, file stem, title, y label).
const PLOTS: [(&str, &str, &str, &str); 9] = [
    (
        "tail_mean_e",
        "error",
        "estimation error ‖e_t‖, mean over the last quarter",
        "‖e‖ (last-quarter mean)",
    ),
    (
        "tail_mean_x",
        "state",
        "state ‖x_t‖, mean over the last quarter",
        "‖x‖ (last-quarter mean)",
    ),
    ("sup_e", "error-sup", "sup_t ‖e_t‖", "sup ‖e‖"),
    ("sup_x", "state-sup", "sup_t ‖x_t‖", "sup ‖x‖"),
    (
        "gain_e",
        "gain-e",
        "empirical gain sup‖e‖ / sup‖w‖",
        "sup‖e‖ / sup‖w‖",
    ),
    (
        "gain_x",
        "gain-x",
        "empirical gain sup‖x‖ / sup‖w‖",
        "sup‖x‖ / sup‖w‖",
    ),
    (
        "tail_gain_e",
        "tail-gain-e",
        "empirical gain after the transient: last-quarter mean ‖e‖ / sup‖w‖",
        "last-quarter ‖e‖ / sup‖w‖",
    ),
    (
        "tail_gain_x",
        "tail-gain-x",
        "empirical gain after the transient: last-quarter mean ‖x‖ / sup‖w‖",
        "last-quarter ‖x‖ / sup‖w‖",
    ),
    (
        "sup_eps",
        "epsilon",
        "sup_t ε_t = ‖zᴷ − z*‖ (exact solve)",
        "sup ε",
    ),
];

/// Writes the SVG plots of an assembled sweep directory from its `points.csv`; returns
/// the file names.
pub fn plot_all(sweep: &Sweep, dir: &Path) -> Result<Vec<String>> {
    let path = dir.join("points.csv");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read `{}`", path.display()))?;
    let table = Table::parse(&text).map_err(|e| anyhow!("`{}`: {e}", path.display()))?;
    let mut scales: Vec<String> = Vec::new();
    for r in 0..table.rows.len() {
        if let Some(s) = table.text(r, "scale") {
            if !scales.iter().any(|x| x == s) {
                scales.push(s.to_string());
            }
        }
    }
    let cfg = sweep.config();
    let mut written = Vec::new();
    for scale in &scales {
        let suffix = if scales.len() > 1 {
            format!("-scale{scale}")
        } else {
            String::new()
        };
        let sub = format!(
            "{} · T = {} · {} seeds · w scale {scale} · band 5–95 %, line median",
            cfg.name,
            sweep.steps(),
            cfg.seeds
        );
        for (col, stem, title, y_label) in PLOTS {
            if table.column(&format!("{col}_q50")).is_none() {
                continue;
            }
            let mut chart = BandChart {
                title: title.to_string(),
                y_label,
                log_y: true,
                curves: curves(&table, scale, Some(col)),
                notes: vec![sub.clone()],
            };
            chart.prepare();
            let name = format!("{stem}{suffix}.svg");
            chart.render(&dir.join(&name))?;
            written.push(name);
        }
        let mut chart = BandChart {
            title: "fraction of bounded runs".to_string(),
            y_label: "bounded fraction",
            log_y: false,
            curves: curves(&table, scale, None),
            notes: vec![
                sub.replace(" · band 5–95 %, line median", ""),
                format!(
                    "bounded: completed, finite, sup‖x‖ ≤ {}·(1 + ‖x₀‖)",
                    cfg.bounded_factor
                ),
            ],
        };
        chart.prepare();
        let name = format!("bounded{suffix}.svg");
        chart.render(&dir.join(&name))?;
        written.push(name);
    }
    Ok(written)
}

/// A one-line description of a sweep's theory per solver, for the terminal.
pub fn theory_summary(sweep: &Sweep) -> String {
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
            "{}: {}; ",
            p.solver,
            match (t.certified, t.k_min) {
                ("void", _) => format!("void ({})", shorten(&t.void_reason, 60)),
                (_, Some(k)) => format!("K_min = {k}"),
                _ => "no K_min".into(),
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
    fn tick_labels() {
        assert_eq!(tick(0.6000000000000001), "0.6");
        assert_eq!(tick(1000.0), "1000");
        assert_eq!(tick(10.0), "10");
        assert_eq!(tick(0.125), "0.125");
        assert_eq!(tick(0.1234), "0.123");
        assert_eq!(tick(2.5e-5), "2.5e-5");
        assert_eq!(tick(0.0), "0");
    }

    #[test]
    fn iso_dates() {
        assert_eq!(iso_utc(0.0), "1970-01-01T00:00:00Z");
        // 2000-02-29 12:34:56 UTC = 951827696 (leap day of a century leap year).
        assert_eq!(iso_utc(951_827_696.0), "2000-02-29T12:34:56Z");
        assert_eq!(iso_utc(1_700_000_000.0), "2023-11-14T22:13:20Z");
    }

    #[test]
    fn curves_group_by_solver_and_note_void() {
        let t = Table::parse(
            "point,k,solver,scale,bounded_fraction,sup_e_q05,sup_e_q50,sup_e_q95,k_min_cert,certified,void_reason\n\
             0,1,pg,1,1,1,2,3,5,no,\n1,10,pg,1,1,0.5,1,2,5,yes,\n2,1,admm,1,0.5,inf,inf,inf,,void,rho < 1 fails\n",
        )
        .unwrap();
        let c = curves(&t, "1", Some("sup_e"));
        assert_eq!(c.len(), 2);
        assert_eq!(
            c[0].points,
            vec![(1.0, 1.0, 2.0, 3.0), (10.0, 0.5, 1.0, 2.0)]
        );
        assert_eq!(c[0].k_min, Some(5.0));
        assert_eq!(c[1].void_reason.as_deref(), Some("rho < 1 fails"));
        let mut chart = BandChart {
            title: "t".into(),
            y_label: "y",
            log_y: true,
            curves: c,
            notes: Vec::new(),
        };
        chart.prepare();
        assert!(chart.curves[1].points.is_empty(), "∞ cannot be drawn");
        assert!(chart.notes.iter().any(|n| n.contains("1 points not drawn")));
        assert!(
            chart
                .notes
                .iter()
                .any(|n| n.contains("admm: certificate void"))
        );
        let dir = std::env::temp_dir().join(format!("xtask-sweep-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        chart.render(&dir.join("t.svg")).unwrap();
        let svg = std::fs::read_to_string(dir.join("t.svg")).unwrap();
        assert!(svg.contains("<svg") && svg.contains("certified K_min(pg) = 5"));
        let b = curves(&t, "1", None);
        assert_eq!(b[1].points, vec![(1.0, 0.5, 0.5, 0.5)]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
