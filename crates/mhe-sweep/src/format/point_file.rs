//! Point files (`points/pNNNNN.csv`): writing, parsing and the full validation of a file
//! before a resume or a merge reuses it (cells, meaning, theory columns, checksum).

use std::fmt::Write as _;
use std::fs;
use std::path::Path;

use super::super::config::Point;
use super::super::error::{Result, io_err, point_file_err};
use super::super::seeds::fnv1a;
use super::super::theory::TheoryAtK;
use super::{cell, point_prefix, points_header, runs_header, theory_cells, write_atomic};
use closed_loop::metrics::{Metric, QUANTILES};

/// First line of every point file (followed by the fingerprint).
const POINT_FILE_MAGIC: &str = "# suboptimal-mhe sweep point v2";
/// The first line of a point file written before the checksum line (refused by name).
const POINT_FILE_MAGIC_V1: &str = "# suboptimal-mhe sweep point v1";
/// Last line of every point file (followed by the FNV-1a checksum of the text before it).
const POINT_FILE_CHECKSUM: &str = "# fnv1a";
/// Line separating the run rows from the summary row in a point file.
const POINT_FILE_SEPARATOR: &str = "=";

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
    pub(crate) edited: bool,
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
pub(crate) struct PointFileRules<'a> {
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
        cells.push(Cell::OneOf(&["yes", "no", "void", "not_computed"]));
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
pub(crate) fn metric_domain_violation(m: Metric, v: f64, completed: bool) -> Option<&'static str> {
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

/// What the run rows of a point file add up to ([`PointFile::check_meaning`]).
struct RunTally {
    /// Each kept metric's values over the runs that have it.
    values: Vec<Vec<f64>>,
    /// Runs with `bounded = 1`.
    bounded: usize,
    /// Runs with `converged = 1`.
    converged: usize,
    /// The runs' wall times summed in run order.
    wall_ms: f64,
    /// Runs with a draw outside 𝒲.
    outside_runs: usize,
    /// Draws outside 𝒲 over all runs.
    outside_total: usize,
}

impl PointFile {
    pub(crate) fn render(&self) -> String {
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
    pub(crate) fn read(path: &Path) -> Result<Self> {
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
    pub(crate) fn validate(
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
    pub(crate) fn check_sealed(&self) -> std::result::Result<(), String> {
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
        let tally = self.check_runs(rules)?;
        self.check_summary(rules, tally)
    }

    /// The run rows' part of [`PointFile::check_meaning`]: every cell's meaning, and the
    /// tallies the summary row must equal.
    fn check_runs(&self, rules: &PointFileRules<'_>) -> std::result::Result<RunTally, String> {
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
        Ok(RunTally {
            values,
            bounded,
            converged,
            wall_ms,
            outside_runs,
            outside_total,
        })
    }

    /// The summary row's part of [`PointFile::check_meaning`]: equal, cell for cell, to the
    /// one recomputed from the run rows' tallies.
    fn check_summary(
        &self,
        rules: &PointFileRules<'_>,
        tally: RunTally,
    ) -> std::result::Result<(), String> {
        let RunTally {
            mut values,
            bounded,
            converged,
            wall_ms,
            outside_runs,
            outside_total,
        } = tally;
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
    pub(crate) fn check_theory(
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
    pub(crate) fn same_results(&self, other: &Self, metrics: &[Metric], two_d: bool) -> bool {
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
    pub(crate) fn write_atomic(&self, path: &Path) -> Result<()> {
        write_atomic(path, &self.render())
    }
}
