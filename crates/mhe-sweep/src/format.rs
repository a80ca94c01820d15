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
use super::error::{Result, io_err};
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

// Point files: their own module (format/point_file.rs).
mod point_file;
pub(super) use point_file::PointFileRules;
pub(super) use point_file::metric_domain_violation;
pub use point_file::{PointFile, point_file_name};

pub use super::table::Table;

#[cfg(test)]
#[path = "format_tests.rs"]
mod tests;
