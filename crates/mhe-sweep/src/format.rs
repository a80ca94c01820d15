//! The sweep's file formats, writing and reading: the CSV rows and headers of `runs.csv`
//! and `points.csv`, the fingerprint, the point files (`points/pNNNNN.csv`) with their
//! full validation, atomic writes under unique temporary names, and [`Table`] to read a
//! CSV back.
//!
//! A point file is a line `# suboptimal-mhe sweep point v2 <fingerprint>`, the point's
//! rows of `runs.csv` (no header), a line `=`, its row of `points.csv`, and a line
//! `# fnv1a <16 hex digits>`: the checksum of everything before it. Before a point file is
//! reused (resume, merge) every cell is checked against the point and the sweep
//! ([`PointFile::validate`]), then the checksum: a file cut, edited (even below the printed
//! digits of the summary) or copied from another point is refused with its path and line,
//! never copied into the outputs.

pub(super) use closed_loop::metrics::csv_text;
use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::config::Point;
use super::error::{Result, io_err, point_file_err};
use super::seeds::fnv1a;
use super::summary::{PointSummary, SweepRun};
use super::theory::TheoryAtK;
use closed_loop::metrics::{Metric, QUANTILES};
use qp_iter::Method;

/// The file in `points/` recording the settings behind the fingerprint (a line with the
/// fingerprint, a line with the canonical settings text), so a refused directory can say
/// what differs.
pub(super) const SETTINGS_FILE: &str = "settings.txt";

/// The text of [`SETTINGS_FILE`].
pub(super) fn settings_text(fingerprint: &str, canonical: &str) -> String {
    format!("{fingerprint}\n{canonical}\n")
}

/// What differs between the settings of [`SETTINGS_FILE`] (`recorded`, its text) and this
/// sweep's (`fingerprint`, `canonical`): `; settings that differ: k = [..] there, [..] here`,
/// `; the scenario file differs` when the settings agree, or empty when nothing is known.
pub(super) fn settings_diff(recorded: &str, fingerprint: &str, canonical: &str) -> String {
    let mut lines = recorded.lines();
    let (Some(found), Some(old)) = (lines.next(), lines.next()) else {
        return String::new();
    };
    if found == fingerprint {
        return String::new();
    }
    let pairs = |text: &str| -> Vec<(String, String)> {
        text.split(';')
            .map(|kv| match kv.split_once('=') {
                Some((k, v)) => (k.to_string(), v.to_string()),
                None => (kv.to_string(), String::new()),
            })
            .collect()
    };
    let (old, new) = (pairs(old), pairs(canonical));
    let mut keys: Vec<&str> = old.iter().chain(&new).map(|(k, _)| k.as_str()).collect();
    keys.dedup();
    let mut seen = Vec::new();
    let mut diffs = Vec::new();
    for k in keys {
        if seen.contains(&k) {
            continue;
        }
        seen.push(k);
        let get = |list: &[(String, String)]| {
            list.iter()
                .find(|(kk, _)| kk == k)
                .map_or("(none)".to_string(), |(_, v)| v.clone())
        };
        let (a, b) = (get(&old), get(&new));
        if a != b {
            diffs.push(format!("{k} = {a} there, {b} here"));
        }
    }
    if diffs.is_empty() {
        "; the settings agree, so the scenario file differs".to_string()
    } else {
        format!("; settings that differ: {}", diffs.join(", "))
    }
}

/// First line of every point file (followed by the fingerprint).
const POINT_FILE_MAGIC: &str = "# suboptimal-mhe sweep point v2";
/// The first line of a point file written before the checksum line (refused by name).
const POINT_FILE_MAGIC_V1: &str = "# suboptimal-mhe sweep point v1";
/// Last line of every point file (followed by the FNV-1a checksum of the text before it).
const POINT_FILE_CHECKSUM: &str = "# fnv1a";
/// Line separating the run rows from the summary row in a point file.
const POINT_FILE_SEPARATOR: &str = "=";

// ---------------------------------------------------------------------------------------
// CSV rows
// ---------------------------------------------------------------------------------------

/// Text for a CSV cell: a number, or empty for none.
fn cell(v: Option<f64>) -> String {
    v.map(|x| format!("{x}")).unwrap_or_default()
}

/// The `solver` cell of a method: its name ([`Method::name`]) with the commas of a method
/// table's parameters written `;` (`admm(rho=2;alpha=1.5)`), so the files need no quoting
/// and every reader splits a row at its commas. Names of different methods stay different
/// (no method name holds a `;`).
pub fn solver_label(m: &Method) -> String {
    csv_text(&m.name())
}

/// The identity columns of a row: `point,k,solver,scale`, with `k_c` after `k` in a 2-D
/// sweep (a 1-D sweep's files are unchanged, so old files and tools keep working).
fn identity_header(two_d: bool) -> &'static str {
    if two_d {
        "point,k,k_c,solver,scale"
    } else {
        "point,k,solver,scale"
    }
}

/// Header of `runs.csv` for the kept metrics (`two_d`: a 2-D sweep, with the `k_c` column).
pub fn runs_header(metrics: &[Metric], two_d: bool) -> String {
    let mut h = format!("{},run,seed,steps", identity_header(two_d));
    for m in metrics {
        h.push(',');
        h.push_str(m.name());
    }
    h.push_str(",bounded,converged,error,w_outside,wall_ms");
    h
}

/// Header of `points.csv` for the kept metrics (`two_d`: a 2-D sweep, with the `k_c`
/// column).
pub fn points_header(metrics: &[Metric], two_d: bool) -> String {
    let mut h = format!(
        "{},runs,bounded_fraction,converged_fraction",
        identity_header(two_d)
    );
    for m in metrics {
        for (_, q) in QUANTILES {
            let _ = write!(h, ",{}_{q}", m.name());
        }
        let _ = write!(h, ",{}_max", m.name());
    }
    h.push_str(",phi,sg1,sg2,sg3,margin_cert,certified,k_min_cert,void_reason");
    h.push_str(
        ",rho_lin,k_lin,linear_note,k_reg,regional_note,w_outside_runs,w_outside_total,wall_ms",
    );
    h
}

fn point_prefix(p: &Point) -> String {
    let solver = solver_label(&p.solver);
    match p.k_c {
        None => format!("{},{},{solver},{}", p.index, p.k, p.scale),
        Some(k_c) => format!("{},{},{k_c},{solver},{}", p.index, p.k, p.scale),
    }
}

pub(super) fn run_row(p: &Point, run: &SweepRun, metrics: &[Metric]) -> String {
    let r = &run.metrics;
    let mut s = point_prefix(p);
    let _ = write!(s, ",{},{},{}", r.run, r.seed, r.steps);
    for &m in metrics {
        s.push(',');
        s.push_str(&cell(r.get(m)));
    }
    let _ = write!(
        s,
        ",{},{},{},{},{}",
        u8::from(r.bounded),
        u8::from(r.converged),
        r.error,
        run.w_outside,
        r.wall_ms
    );
    s
}

pub(super) fn point_row(p: &Point, s: &PointSummary) -> String {
    let mut out = point_prefix(p);
    let _ = write!(
        out,
        ",{},{},{}",
        s.runs, s.bounded_fraction, s.converged_fraction
    );
    for (_, q) in &s.quantiles {
        for v in q {
            out.push(',');
            out.push_str(&cell(*v));
        }
    }
    out.push(',');
    out.push_str(&theory_cells(&s.theory));
    let _ = write!(
        out,
        ",{},{},{}",
        s.w_outside_runs, s.w_outside_total, s.wall_ms
    );
    out
}

/// The theory columns of a summary row (`phi` … `regional_note`), as [`point_row`] writes
/// them: a point file read back is checked against them ([`PointFile::check_theory`]).
pub(super) fn theory_cells(th: &TheoryAtK) -> String {
    let sl = th.slopes;
    format!(
        "{},{},{},{},{},{},{},{},{},{},{},{},{}",
        cell(th.phi),
        cell(sl.map(|v| v[0])),
        cell(sl.map(|v| v[1])),
        cell(sl.map(|v| v[2])),
        cell(th.margin),
        th.certified,
        th.k_min.map(|k| k.to_string()).unwrap_or_default(),
        th.void_reason,
        cell(th.rho_lin),
        th.k_lin.map(|k| k.to_string()).unwrap_or_default(),
        th.linear_note,
        th.k_reg.map(|k| k.to_string()).unwrap_or_default(),
        th.regional_note,
    )
}

/// The fingerprint of a sweep: FNV-1a of the canonical settings text and the scenario's
/// text, as 16 hex digits. Stored in every point file.
pub(super) fn fingerprint(canonical: &str, scenario_text: &str) -> String {
    let mut text = String::with_capacity(canonical.len() + 1 + scenario_text.len());
    text.push_str(canonical);
    text.push('\n');
    text.push_str(scenario_text);
    format!("{:016x}", fnv1a(text.as_bytes()))
}

// ---------------------------------------------------------------------------------------
// Atomic writes
// ---------------------------------------------------------------------------------------

/// Counter of the temporary names of this process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A temporary name beside `path`, unique to this process and call:
/// `NAME.<pid>.<counter>.tmp`.
pub(super) fn temp_path(path: &Path) -> PathBuf {
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!("{name}.{}.{n}.tmp", std::process::id()))
}

/// The writer's pid of a name made by [`temp_path`] (None for any other name).
pub(super) fn temp_owner(file_name: &str) -> Option<u32> {
    let rest = file_name.strip_suffix(".tmp")?;
    let (rest, counter) = rest.rsplit_once('.')?;
    let (_, pid) = rest.rsplit_once('.')?;
    counter.parse::<u64>().ok()?;
    pid.parse().ok()
}

/// Writes `text` to a fresh temporary name beside `path`, flushed and synced; returns the
/// temporary path (rename it with [`commit`]).
pub(super) fn write_temp(path: &Path, text: &str) -> Result<PathBuf> {
    let tmp = temp_path(path);
    let written = fs::File::create(&tmp)
        .map_err(io_err("create", &tmp))
        .and_then(|mut f| {
            f.write_all(text.as_bytes())
                .and_then(|()| f.sync_all())
                .map_err(io_err("write", &tmp))
        });
    if written.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    written.map(|()| tmp)
}

/// Renames a temporary file written by [`write_temp`] to its final name.
pub(super) fn commit(tmp: &Path, path: &Path) -> Result<()> {
    fs::rename(tmp, path).map_err(|e| {
        let _ = fs::remove_file(tmp);
        io_err("rename a finished file to", path)(e)
    })
}

/// Replaces `path` by `text` atomically (temporary file, synced, renamed): a reader sees
/// the old file or the new one, never a part.
pub(super) fn write_atomic(path: &Path, text: &str) -> Result<()> {
    let tmp = write_temp(path, text)?;
    commit(&tmp, path)
}

// ---------------------------------------------------------------------------------------
// Point files
// ---------------------------------------------------------------------------------------

/// The content of one finished point file.
#[derive(Debug, Clone, PartialEq)]
pub struct PointFile {
    /// Fingerprint of the sweep that wrote it.
    pub fingerprint: String,
    /// Its rows of `runs.csv`.
    pub run_rows: Vec<String>,
    /// Its row of `points.csv`.
    pub point_row: String,
    /// Read back with a checksum line that does not match its text: an edit the cell checks
    /// cannot see (a run cell changed below the summary's printed digits, an optional cell
    /// emptied). [`PointFile::check_sealed`] refuses it after the cell and theory checks,
    /// which name the line and column of any edit they do see.
    pub(super) edited: bool,
}

/// Name of the point file of point `index`.
pub fn point_file_name(index: usize) -> String {
    format!("p{index:05}.csv")
}

/// What a valid cell holds.
#[derive(Debug, Clone, PartialEq)]
enum Cell {
    /// Exactly this text (the point's identity, the run index, the seed).
    Is(String),
    /// An integer 0 ≤ n ≤ max.
    UpTo(usize),
    /// A finite number ≥ 0 (the wall times).
    NonNegative,
    /// A number ≥ 0 (`inf` and `NaN` included), or empty.
    NonNegativeOrEmpty,
    /// A number or empty (not available).
    NumberOrEmpty,
    /// An integer or empty.
    IntegerOrEmpty,
    /// One of these words.
    OneOf(&'static [&'static str]),
    /// Any text without a comma (the error and void-reason columns).
    Text,
}

/// What the point files of one sweep must hold, and how to check one.
#[derive(Debug, Clone, Copy)]
pub(super) struct PointFileRules<'a> {
    /// The kept metrics (they fix the columns).
    pub metrics: &'a [Metric],
    /// Runs per point.
    pub seeds: usize,
    /// Horizon T (no run has more steps).
    pub steps: usize,
    /// A 2-D sweep (the `k_c` column).
    pub two_d: bool,
}

impl PointFileRules<'_> {
    /// The run-row cells of run `r` at point `p` whose seed is `seed`, with the column names.
    fn run_cells(&self, p: &Point, r: usize, seed: u64) -> Vec<(String, Cell)> {
        let names = runs_header(self.metrics, self.two_d);
        let mut cells = identity_cells(p);
        cells.push(Cell::Is(r.to_string()));
        cells.push(Cell::Is(seed.to_string()));
        cells.push(Cell::UpTo(self.steps));
        cells.extend(self.metrics.iter().map(|_| Cell::NumberOrEmpty));
        // bounded, converged (converged ⇒ bounded, checked below)
        cells.push(Cell::OneOf(&["0", "1"]));
        cells.push(Cell::OneOf(&["0", "1"]));
        cells.push(Cell::Text);
        // w_outside: at most one draw per step (checked against the row's `steps` below).
        cells.push(Cell::UpTo(self.steps));
        cells.push(Cell::NonNegative);
        names.split(',').map(str::to_string).zip(cells).collect()
    }

    /// The summary-row cells of point `p`, with the column names.
    fn summary_cells(&self, p: &Point) -> Vec<(String, Cell)> {
        let names = points_header(self.metrics, self.two_d);
        let mut cells = identity_cells(p);
        cells.push(Cell::Is(self.seeds.to_string()));
        // bounded_fraction, converged_fraction (recomputed from the run rows below)
        cells.push(Cell::NonNegative);
        cells.push(Cell::NonNegative);
        cells.extend((0..4 * self.metrics.len()).map(|_| Cell::NumberOrEmpty));
        // phi, sg1, sg2, sg3 (≥ 0), margin_cert (1 − ρ(Γ), any sign)
        cells.extend((0..4).map(|_| Cell::NonNegativeOrEmpty));
        cells.push(Cell::NumberOrEmpty);
        cells.push(Cell::OneOf(&["yes", "no", "void"]));
        cells.push(Cell::IntegerOrEmpty);
        cells.push(Cell::Text);
        // rho_lin (a spectral radius, ≥ 0), k_lin, linear_note
        cells.push(Cell::NonNegativeOrEmpty);
        cells.push(Cell::IntegerOrEmpty);
        cells.push(Cell::Text);
        // k_reg, regional_note
        cells.push(Cell::IntegerOrEmpty);
        cells.push(Cell::Text);
        // w_outside_runs, w_outside_total (recomputed from the run rows below)
        cells.push(Cell::UpTo(self.seeds));
        cells.push(Cell::UpTo(self.seeds.saturating_mul(self.steps)));
        // wall_ms: the sum of the runs' (checked below)
        cells.push(Cell::NonNegative);
        names.split(',').map(str::to_string).zip(cells).collect()
    }
}

fn identity_cells(p: &Point) -> Vec<Cell> {
    point_prefix(p)
        .split(',')
        .map(|c| Cell::Is(c.to_string()))
        .collect()
}

/// Checks one row against its cells; `what` names the row (`line 4 (run 2)`).
fn check_row(row: &str, cells: &[(String, Cell)], what: &str) -> std::result::Result<(), String> {
    let got: Vec<&str> = row.split(',').collect();
    if got.len() != cells.len() {
        return Err(format!(
            "{what} has {} cells, a row of this sweep has {} (cut or edited)",
            got.len(),
            cells.len()
        ));
    }
    // The identity cells (`point,k[,k_c],solver,scale`) are the leading `Is` cells.
    let n_id = cells
        .iter()
        .take_while(|(name, _)| !matches!(name.as_str(), "run" | "runs"))
        .count();
    let identity = got.iter().take(n_id).copied().collect::<Vec<_>>().join(",");
    for (c, (&value, (name, cell))) in got.iter().zip(cells).enumerate() {
        let ok = match cell {
            Cell::Is(want) => value == want,
            Cell::UpTo(max) => value.parse::<usize>().is_ok_and(|n| n <= *max),
            Cell::NonNegative => value
                .parse::<f64>()
                .is_ok_and(|v| v.is_finite() && v >= 0.0),
            Cell::NonNegativeOrEmpty => {
                value.is_empty() || value.parse::<f64>().is_ok_and(|v| v.is_nan() || v >= 0.0)
            }
            Cell::NumberOrEmpty => value.is_empty() || value.parse::<f64>().is_ok(),
            Cell::IntegerOrEmpty => value.is_empty() || value.parse::<usize>().is_ok(),
            Cell::OneOf(words) => words.contains(&value),
            Cell::Text => true,
        };
        if ok {
            continue;
        }
        return Err(match cell {
            Cell::Is(want) if c < n_id => {
                let expected: Vec<&str> = cells
                    .iter()
                    .take(n_id)
                    .map(|(_, k)| match k {
                        Cell::Is(w) => w.as_str(),
                        _ => "",
                    })
                    .collect();
                let names: Vec<&str> = cells.iter().take(n_id).map(|(n, _)| n.as_str()).collect();
                format!(
                    "{what} is a row of point `{identity}` ({}), but this file is \
                     point `{}` (column `{name}` should be `{want}`), as if copied from another \
                     point's file",
                    names.join(","),
                    expected.join(",")
                )
            }
            Cell::Is(want) => format!("{what}, column `{name}`: `{value}`, expected `{want}`"),
            Cell::UpTo(max) => {
                format!("{what}, column `{name}`: `{value}` is not an integer from 0 to {max}")
            }
            Cell::NumberOrEmpty => {
                format!("{what}, column `{name}`: `{value}` is not a number")
            }
            Cell::NonNegative => {
                format!("{what}, column `{name}`: `{value}` is not a finite number ≥ 0")
            }
            Cell::NonNegativeOrEmpty => {
                format!("{what}, column `{name}`: `{value}` is not a number ≥ 0")
            }
            Cell::IntegerOrEmpty => {
                format!("{what}, column `{name}`: `{value}` is not an integer")
            }
            Cell::OneOf(words) => format!(
                "{what}, column `{name}`: `{value}` is none of {}",
                words.join(", ")
            ),
            Cell::Text => format!("{what}, column `{name}`: `{value}`"),
        });
    }
    Ok(())
}

/// Two differing cells for a message: numbers with 4 significant digits, unless that hides
/// the difference (then as written).
fn short_pair(a: &str, b: &str) -> (String, String) {
    let short = |t: &str| match t.parse::<f64>() {
        Ok(v) if v.is_finite() && t.len() > 8 => format!("{v:.3e}"),
        _ => t.to_string(),
    };
    let (sa, sb) = (short(a), short(b));
    if sa == sb {
        (a.to_string(), b.to_string())
    } else {
        (sa, sb)
    }
}

/// Why value `v` of metric `m` is outside its domain (None: inside). Every metric is ≥ 0.
/// The norms (`sup_e`, `sup_x`, `tail_mean_*`, `final_*`, `sup_w`) of a completed run are
/// finite (a signal beyond `DIVERGED_MAGNITUDE` stops the run) and +∞ after a stop; a gain
/// may be +∞ (a tiny `sup_w`); `sup_eps` and the violations record NaN from a failed solve.
pub(super) fn metric_domain_violation(m: Metric, v: f64, completed: bool) -> Option<&'static str> {
    let norm = matches!(
        m,
        Metric::SupE
            | Metric::SupX
            | Metric::TailMeanE
            | Metric::FinalE
            | Metric::TailMeanX
            | Metric::FinalX
            | Metric::SupW
    );
    let nan_ok = matches!(
        m,
        Metric::SupEps | Metric::InputViolation | Metric::MheViolation
    );
    if v.is_nan() {
        return (!nan_ok)
            .then_some("is not a number (NaN), but this metric is a norm or a gain ≥ 0");
    }
    if v < 0.0 {
        return Some("is negative, but this metric is ≥ 0");
    }
    if norm && completed && !v.is_finite() {
        return Some(
            "is not finite, but the run completed (a run whose signals grow beyond 1e154 stops with an error)",
        );
    }
    None
}

/// A row without its `wall_*` cells (names from `header`).
fn without_timing<'a>(row: &'a str, header: &str) -> Vec<&'a str> {
    row.split(',')
        .zip(header.split(','))
        .filter(|(_, h)| !h.starts_with("wall_"))
        .map(|(c, _)| c)
        .collect()
}

impl PointFile {
    pub(super) fn render(&self) -> String {
        let mut s = format!("{POINT_FILE_MAGIC} {}\n", self.fingerprint);
        for r in &self.run_rows {
            s.push_str(r);
            s.push('\n');
        }
        s.push_str(POINT_FILE_SEPARATOR);
        s.push('\n');
        s.push_str(&self.point_row);
        s.push('\n');
        let digest = fnv1a(s.as_bytes());
        let _ = writeln!(s, "{POINT_FILE_CHECKSUM} {digest:016x}");
        s
    }

    /// Parses a point file's text (checks the magic line, the separator and the end; the
    /// cells are checked before a resume or a merge reuses the file).
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let bad = |problem: &str| point_file_err(path, problem);
        let mut lines = text.lines();
        let first = lines.next().ok_or_else(|| bad("empty"))?;
        if first.starts_with(POINT_FILE_MAGIC_V1) {
            return Err(bad(
                "written by an older version (point file v1, without the checksum line)",
            ));
        }
        let fingerprint = first
            .strip_prefix(POINT_FILE_MAGIC)
            .map(str::trim)
            .filter(|f| !f.is_empty())
            .ok_or_else(|| bad("no header line"))?
            .to_string();
        let mut run_rows = Vec::new();
        let mut point_row = None;
        for line in lines.by_ref() {
            if line == POINT_FILE_SEPARATOR {
                point_row = lines.next();
                break;
            }
            run_rows.push(line.to_string());
        }
        let point_row = point_row.ok_or_else(|| bad("no summary row"))?.to_string();
        let checksum = lines
            .next()
            .ok_or_else(|| bad("no checksum line after the summary row (cut)"))?;
        let stored = checksum
            .strip_prefix(POINT_FILE_CHECKSUM)
            .map(str::trim)
            .filter(|h| h.len() == 16)
            .and_then(|h| u64::from_str_radix(h, 16).ok())
            .ok_or_else(|| {
                bad("the line after the summary row is not `# fnv1a <16 hex digits>`")
            })?;
        if lines.next().is_some() {
            return Err(bad("text after the checksum line"));
        }
        if !text.ends_with('\n') {
            return Err(bad("truncated (no final line break)"));
        }
        // The checksum covers every byte before its own line.
        let body = &text[..text.len() - checksum.len() - 1];
        Ok(Self {
            fingerprint,
            run_rows,
            point_row,
            edited: fnv1a(body.as_bytes()) != stored,
        })
    }

    /// Reads and parses a point file (bytes that are not UTF-8 text are a malformed file,
    /// not an I/O error).
    pub(super) fn read(path: &Path) -> Result<Self> {
        let bytes = fs::read(path).map_err(io_err("read the point file", path))?;
        let text = String::from_utf8(bytes).map_err(|e| {
            point_file_err(
                path,
                format!(
                    "not a text file (invalid UTF-8 at byte {})",
                    e.utf8_error().valid_up_to()
                ),
            )
        })?;
        Self::parse(&text, path)
    }

    /// Checks every row of the file of point `p` cell by cell: the column count, the
    /// point's identity (index, K, solver, scale: a file copied from another point fails
    /// here), the run indices and seeds (`seed_of(r)`), and that every number parses.
    /// Errors name `path`, the line and the column.
    pub(super) fn validate(
        &self,
        path: &Path,
        p: &Point,
        rules: &PointFileRules<'_>,
        seed_of: &dyn Fn(usize) -> u64,
    ) -> Result<()> {
        if self.run_rows.len() != rules.seeds {
            return Err(point_file_err(
                path,
                format!(
                    "{} run rows, the sweep has {} seeds per point",
                    self.run_rows.len(),
                    rules.seeds
                ),
            ));
        }
        for (r, row) in self.run_rows.iter().enumerate() {
            // Line 1 is the fingerprint line.
            let what = format!("line {} (run {r})", r + 2);
            check_row(row, &rules.run_cells(p, r, seed_of(r)), &what)
                .map_err(|problem| point_file_err(path, problem))?;
        }
        let what = format!("line {} (summary row)", self.run_rows.len() + 3);
        check_row(&self.point_row, &rules.summary_cells(p), &what)
            .map_err(|problem| point_file_err(path, problem))?;
        self.check_meaning(rules)
            .map_err(|problem| point_file_err(path, problem))
    }

    /// The last check before a point file is reused (after [`PointFile::validate`] and
    /// [`PointFile::check_theory`], whose errors name the line and the column): its checksum
    /// line matches its text, so an edit every cell check passes (a run cell changed below
    /// the summary's printed digits, an optional cell emptied) is refused too.
    pub(super) fn check_sealed(&self) -> std::result::Result<(), String> {
        if self.edited {
            return Err(
                "its checksum line does not match its text: edited after it was \
                        written (every cell is well formed, so the change is below the \
                        printed digits or an optional cell emptied)"
                    .into(),
            );
        }
        Ok(())
    }

    /// Checks what the (well-formed) cells mean: every metric in its domain (≥ 0; the norms
    /// of a completed run finite; NaN only where the run records it for a failed solve),
    /// `bounded = 1` only for a completed run, `w_outside` ≤ the run's `steps`, and the
    /// summary row equal, cell for cell, to the one recomputed from the run rows
    /// ([`summarise`](super::summary::summarise)'s rule: bounded fraction, quantiles,
    /// maximum, runs with draws outside 𝒲 and their total).
    fn check_meaning(&self, rules: &PointFileRules<'_>) -> std::result::Result<(), String> {
        let rh = runs_header(rules.metrics, rules.two_d);
        let names: Vec<&str> = rh.split(',').collect();
        let col = |name: &str| names.iter().position(|n| *n == name).unwrap_or(usize::MAX);
        let (c_bounded, c_converged, c_error) = (col("bounded"), col("converged"), col("error"));
        let (c_steps, c_outside, c_wall) = (col("steps"), col("w_outside"), col("wall_ms"));
        let mut values: Vec<Vec<f64>> = vec![Vec::new(); rules.metrics.len()];
        let (mut bounded, mut converged) = (0usize, 0usize);
        let mut wall_ms = 0.0f64;
        let (mut outside_runs, mut outside_total) = (0usize, 0usize);
        for (r, row) in self.run_rows.iter().enumerate() {
            let cells: Vec<&str> = row.split(',').collect();
            let what = format!("line {} (run {r})", r + 2);
            let completed = cells.get(c_error).is_some_and(|e| e.is_empty());
            if cells.get(c_bounded) == Some(&"1") {
                if !completed {
                    return Err(format!(
                        "{what}, column `bounded`: `1`, but the run stopped (column `error` is \
                         not empty), and a stopped run is never bounded"
                    ));
                }
                bounded += 1;
            }
            if cells.get(c_converged) == Some(&"1") {
                if cells.get(c_bounded) != Some(&"1") {
                    return Err(format!(
                        "{what}, column `converged`: `1`, but column `bounded` is `0`; a \
                         converged run is bounded"
                    ));
                }
                converged += 1;
            }
            // Cells of the form checked (`check_row`): integers.
            let int = |c: usize| cells.get(c).and_then(|t| t.parse::<usize>().ok());
            wall_ms += cells
                .get(c_wall)
                .and_then(|t| t.parse::<f64>().ok())
                .unwrap_or(f64::NAN);
            if let (Some(steps), Some(outside)) = (int(c_steps), int(c_outside)) {
                if outside > steps {
                    return Err(format!(
                        "{what}, column `w_outside`: `{outside}` draws outside 𝒲, but the run \
                         has {steps} steps (column `steps`), one draw per step"
                    ));
                }
                outside_runs += usize::from(outside > 0);
                outside_total += outside;
            }
            if completed && int(c_steps) != Some(rules.steps) {
                return Err(format!(
                    "{what}, column `steps`: `{}`, but the run completed (column `error` is \
                     empty), so it has the sweep's T = {} steps",
                    cells.get(c_steps).copied().unwrap_or(""),
                    rules.steps
                ));
            }
            for (i, &m) in rules.metrics.iter().enumerate() {
                let text = cells.get(col(m.name())).copied().unwrap_or("");
                if text.is_empty() {
                    // Every run, completed or stopped, has these (`run_metrics`): an empty
                    // cell is an edit that the quantiles would not show.
                    if matches!(
                        m,
                        Metric::SupE | Metric::SupX | Metric::SupW | Metric::InputViolation
                    ) {
                        return Err(format!(
                            "{what}, column `{}`: empty, but every run has this metric",
                            m.name()
                        ));
                    }
                    continue;
                }
                let v: f64 = text.parse().unwrap_or(f64::NAN);
                if let Some(rule) = metric_domain_violation(m, v, completed) {
                    return Err(format!("{what}, column `{}`: `{text}` {rule}", m.name()));
                }
                values[i].push(v);
            }
        }
        // The summary row recomputed from the run rows, compared cell by cell.
        let ph = points_header(rules.metrics, rules.two_d);
        let summary: Vec<&str> = self.point_row.split(',').collect();
        let pcol = |name: &str| {
            ph.split(',')
                .position(|n| n == name)
                .and_then(|c| summary.get(c).copied())
                .unwrap_or("")
        };
        let runs = self.run_rows.len();
        let fraction = |n: usize| {
            if runs == 0 {
                0.0f64.to_string()
            } else {
                (n as f64 / runs as f64).to_string()
            }
        };
        let mut expected = vec![
            ("bounded_fraction".to_string(), fraction(bounded)),
            ("converged_fraction".to_string(), fraction(converged)),
        ];
        for (i, &m) in rules.metrics.iter().enumerate() {
            let v = &mut values[i];
            v.sort_by(f64::total_cmp);
            let q = |p| cell(closed_loop::metrics::quantile_sorted(v, p));
            for (p, name) in QUANTILES {
                expected.push((format!("{}_{name}", m.name()), q(p)));
            }
            expected.push((format!("{}_max", m.name()), cell(v.last().copied())));
        }
        expected.push(("w_outside_runs".to_string(), outside_runs.to_string()));
        expected.push(("w_outside_total".to_string(), outside_total.to_string()));
        // `summarise` sums the runs' wall times in run order; `{}` round-trips an f64.
        expected.push(("wall_ms".to_string(), wall_ms.to_string()));
        let line = runs + 3;
        for (name, want) in expected {
            let got = pcol(&name);
            if got != want {
                let (g, w) = short_pair(got, &want);
                return Err(format!(
                    "line {line} (summary row), column `{name}`: `{g}`, but the run rows \
                     (lines 2–{}) give `{w}`; the file was edited",
                    runs + 1
                ));
            }
        }
        Ok(())
    }

    /// Checks the theory columns of the summary row (`phi` … `regional_note`: the verdict,
    /// K_min, ρ_lin, K_lin, K_reg and their notes) against `theory`, this sweep's own for the
    /// point ([`super::run::Sweep::theory_at`]): a resume or a merge reuses the row, so a
    /// verdict in it must be the one computed, never an edited one.
    pub(super) fn check_theory(
        &self,
        theory: &TheoryAtK,
        rules: &PointFileRules<'_>,
    ) -> std::result::Result<(), String> {
        let ph = points_header(rules.metrics, rules.two_d);
        let names: Vec<&str> = ph.split(',').collect();
        let got: Vec<&str> = self.point_row.split(',').collect();
        let want_text = theory_cells(theory);
        let want: Vec<&str> = want_text.split(',').collect();
        let first = names.iter().position(|n| *n == "phi").unwrap_or(0);
        let line = self.run_rows.len() + 3;
        for (i, w) in want.iter().enumerate() {
            let g = got.get(first + i).copied().unwrap_or("");
            if g != *w {
                let name = names.get(first + i).copied().unwrap_or("?");
                let (g, w) = short_pair(g, w);
                return Err(format!(
                    "line {line} (summary row), column `{name}`: `{g}`, but this sweep's \
                     certificate and analyses give `{w}`; the file was edited"
                ));
            }
        }
        Ok(())
    }

    /// Whether two (valid) files of one point hold the same results, the `wall_*` timing
    /// columns aside: a point computed twice gives the same results, not the same times.
    pub(super) fn same_results(&self, other: &Self, metrics: &[Metric], two_d: bool) -> bool {
        let (rh, ph) = (runs_header(metrics, two_d), points_header(metrics, two_d));
        self.fingerprint == other.fingerprint
            && self.run_rows.len() == other.run_rows.len()
            && self
                .run_rows
                .iter()
                .zip(&other.run_rows)
                .all(|(a, b)| without_timing(a, &rh) == without_timing(b, &rh))
            && without_timing(&self.point_row, &ph) == without_timing(&other.point_row, &ph)
    }

    /// Writes the file atomically (unique temporary name, synced, renamed).
    pub(super) fn write_atomic(&self, path: &Path) -> Result<()> {
        write_atomic(path, &self.render())
    }
}

pub use super::table::Table;

#[cfg(test)]
#[path = "format_tests.rs"]
mod tests;
