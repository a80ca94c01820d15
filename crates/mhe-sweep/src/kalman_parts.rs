//! The Kalman baseline of a sharded sweep: every shard writes its rows of `kalman.csv` to a
//! part file, `points/kalman.shard-I-of-N.csv`, and a merge assembles `kalman.csv` from the
//! parts of every directory it reads ([`assemble_kalman`]).
//!
//! A part file is a line `# suboptimal-mhe sweep kalman part v1 <fingerprint> shard I/N`,
//! the header of `kalman.csv` and the shard's rows (row j = s·seeds + r of scale index s and
//! run r when j mod N = I − 1; see `baseline.rs`). It is written atomically (unique
//! temporary name, synced, renamed) and checked in full before a merge uses it: the
//! fingerprint, the header, every row's scale, run, seed, step count, bounded flag, metric
//! domains and `w_outside` ≤ `steps`. Two parts holding different rows for one (scale, run)
//! are a conflict naming both files, and a row no part holds is refused naming the part
//! file that should hold it.

use std::collections::BTreeMap;
use std::collections::btree_map::Entry;
use std::fs;
use std::path::{Path, PathBuf};

use super::baseline::{KalmanRow, kalman_csv, kalman_header, kalman_rows, scale_points};
use super::error::{Result, SweepError, io_err};
use super::format::{metric_domain_violation, write_atomic};
use super::run::Sweep;
use super::seeds::{Shard, run_seed};
use closed_loop::metrics::Metric;

/// First line of every part file (followed by the fingerprint and the shard).
const PART_MAGIC: &str = "# suboptimal-mhe sweep kalman part v1";

/// The name of shard `s`'s part file (in `points/`).
pub fn kalman_part_name(s: Shard) -> String {
    format!("kalman.shard-{}-of-{}.csv", s.index, s.count)
}

/// The shard of a part file's name (None for any other name).
fn part_shard(file_name: &str) -> Option<Shard> {
    let spec = file_name
        .strip_prefix("kalman.shard-")?
        .strip_suffix(".csv")?;
    let (i, n) = spec.split_once("-of-")?;
    format!("{i}/{n}").parse().ok()
}

fn part_err(path: &Path, problem: impl Into<String>) -> SweepError {
    SweepError::KalmanPart {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}

/// A part file that cannot be used as it is: `problem` and the fix.
fn corrupt(path: &Path, shard: Shard, problem: impl std::fmt::Display) -> SweepError {
    part_err(
        path,
        format!(
            "{problem}; delete it and rerun that shard (`--shard {shard}`) into its directory to \
             rewrite it"
        ),
    )
}

/// Computes shard `shard`'s rows of the Kalman baseline and writes its part file into
/// `pdir` (the shard's `points/`) atomically.
pub(super) fn write_kalman_part(sweep: &Sweep, shard: Shard, pdir: &Path) -> Result<()> {
    let rows = kalman_rows(sweep, &|j| shard.owns(j))?;
    let text = format!(
        "{PART_MAGIC} {} shard {shard}\n{}",
        sweep.fingerprint(),
        kalman_csv(&rows)
    );
    write_atomic(&pdir.join(kalman_part_name(shard)), &text)
}

/// A part file read and checked: its rows by (scale index, run).
struct Part {
    path: PathBuf,
    shard: Shard,
    rows: Vec<KalmanRow>,
}

/// Reads and checks the part file `path` of shard `shard` (named so) against `sweep`.
fn read_part(sweep: &Sweep, path: &Path, shard: Shard) -> Result<Part> {
    let bytes = fs::read(path).map_err(io_err("read the Kalman part", path))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        corrupt(
            path,
            shard,
            format!(
                "not a text file (invalid UTF-8 at byte {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })?;
    if !text.ends_with('\n') {
        return Err(corrupt(path, shard, "truncated (no final line break)"));
    }
    let mut lines = text.lines();
    let first = lines.next().unwrap_or("");
    let words: Vec<&str> = first
        .strip_prefix(PART_MAGIC)
        .map(|r| r.split_whitespace().collect())
        .unwrap_or_default();
    let [fingerprint, "shard", spec] = words[..] else {
        return Err(corrupt(
            path,
            shard,
            format!("line 1 is not `{PART_MAGIC} <fingerprint> shard I/N`"),
        ));
    };
    if fingerprint != sweep.fingerprint() {
        return Err(SweepError::Fingerprint {
            path: path.to_path_buf(),
            found: fingerprint.to_string(),
            expected: sweep.fingerprint().to_string(),
            detail: String::new(),
        });
    }
    if spec.parse::<Shard>().ok() != Some(shard) {
        return Err(corrupt(
            path,
            shard,
            format!("line 1 says shard {spec}, the file name shard {shard} (renamed?)"),
        ));
    }
    let header = kalman_header();
    if lines.next() != Some(header.as_str()) {
        return Err(corrupt(
            path,
            shard,
            "line 2 is not the header of kalman.csv of this version",
        ));
    }
    let names: Vec<&str> = header.split(',').collect();
    let scales: Vec<String> = scale_points(sweep)
        .iter()
        .map(|p| p.scale.to_string())
        .collect();
    let mut rows: Vec<KalmanRow> = Vec::new();
    for (i, row) in lines.enumerate() {
        let line = i + 3;
        let key = check_row(sweep, shard, &names, &scales, row)
            .map_err(|problem| corrupt(path, shard, format!("line {line}: {problem}")))?;
        if rows.iter().any(|(s, r, _)| (*s, *r) == key) {
            return Err(corrupt(
                path,
                shard,
                format!(
                    "line {line}: a second row of scale index {}, run {}",
                    key.0, key.1
                ),
            ));
        }
        rows.push((key.0, key.1, row.to_string()));
    }
    Ok(Part {
        path: path.to_path_buf(),
        shard,
        rows,
    })
}

/// Checks one row of a part of `shard`; returns its (scale index, run).
fn check_row(
    sweep: &Sweep,
    shard: Shard,
    names: &[&str],
    scales: &[String],
    row: &str,
) -> std::result::Result<(usize, usize), String> {
    let cells: Vec<&str> = row.split(',').collect();
    if cells.len() != names.len() {
        return Err(format!(
            "{} cells, a row of kalman.csv has {} (cut or edited)",
            cells.len(),
            names.len()
        ));
    }
    let cell = |name: &str| {
        names
            .iter()
            .position(|n| *n == name)
            .map_or("", |c| cells[c])
    };
    let bad = |name: &str, why: &str| format!("column `{name}`: `{}` {why}", cell(name));
    if cell("estimator") != "kalman" {
        return Err(bad("estimator", "is not `kalman`"));
    }
    let s = scales
        .iter()
        .position(|t| t == cell("scale"))
        .ok_or_else(|| {
            bad(
                "scale",
                &format!("is none of the sweep's scales ({})", scales.join(", ")),
            )
        })?;
    let seeds = sweep.config().seeds;
    let r = cell("run")
        .parse::<usize>()
        .ok()
        .filter(|&r| r < seeds)
        .ok_or_else(|| bad("run", &format!("is not an integer from 0 to {}", seeds - 1)))?;
    if !shard.owns(s * seeds + r) {
        return Err(format!(
            "scale {}, run {r} is not a row of shard {shard} (row {} belongs to shard {}/{})",
            scales[s],
            s * seeds + r,
            (s * seeds + r) % shard.count + 1,
            shard.count
        ));
    }
    let points = scale_points(sweep);
    let cfg = sweep.config();
    let seed = run_seed(sweep.base_seed(), points[s], r, cfg.common_random_numbers);
    if cell("seed") != seed.to_string() {
        return Err(bad("seed", &format!("is not this run's seed {seed}")));
    }
    let steps = cell("steps")
        .parse::<usize>()
        .ok()
        .filter(|&n| n <= sweep.steps())
        .ok_or_else(|| {
            bad(
                "steps",
                &format!("is not an integer from 0 to T = {}", sweep.steps()),
            )
        })?;
    let completed = cell("error").is_empty();
    match cell("bounded") {
        "0" => {}
        "1" if completed => {}
        "1" => {
            return Err(bad(
                "bounded",
                "but the run stopped (column `error` is not empty)",
            ));
        }
        _ => return Err(bad("bounded", "is neither 0 nor 1")),
    }
    for m in Metric::ALL {
        let text = cell(m.name());
        if text.is_empty() {
            continue;
        }
        let v: f64 = text.parse().map_err(|_| bad(m.name(), "is not a number"))?;
        if let Some(rule) = metric_domain_violation(m, v, completed) {
            return Err(bad(m.name(), rule));
        }
    }
    let outside = cell("w_outside").parse::<usize>().ok();
    if outside.is_none_or(|n| n > steps) {
        return Err(bad(
            "w_outside",
            &format!("is not an integer from 0 to the run's {steps} steps (one draw per step)"),
        ));
    }
    Ok((s, r))
}

/// The part files in `dir/points`, by name (none without `points/`).
fn parts_in(dir: &Path) -> Result<Vec<(PathBuf, Shard)>> {
    let pdir = dir.join("points");
    if !pdir.is_dir() {
        return Ok(Vec::new());
    }
    let rd = fs::read_dir(&pdir).map_err(io_err("list the directory", &pdir))?;
    let mut out: Vec<(PathBuf, Shard)> = rd
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_str()?.to_string();
            Some((e.path(), part_shard(&name)?))
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

/// `kalman.csv` assembled from the part files in the `points/` of `dirs` (read in that
/// order): every part checked, two different rows for one (scale, run) a conflict, every
/// row present. Returns the text and the part files of `dirs[1..]` that `dirs[0]` lacks
/// (a merge copies them there, so its output directory can be merged again).
pub(super) fn assemble_kalman(
    sweep: &Sweep,
    dirs: &[&Path],
) -> Result<(String, Vec<(PathBuf, String)>)> {
    let mut rows: BTreeMap<(usize, usize), (String, PathBuf)> = BTreeMap::new();
    let mut counts: Vec<usize> = Vec::new();
    let mut copies = Vec::new();
    for (di, d) in dirs.iter().enumerate() {
        for (path, shard) in parts_in(d)? {
            let part = read_part(sweep, &path, shard)?;
            if !counts.contains(&part.shard.count) {
                counts.push(part.shard.count);
            }
            for (s, r, row) in part.rows {
                match rows.entry((s, r)) {
                    Entry::Vacant(v) => {
                        v.insert((row, part.path.clone()));
                    }
                    Entry::Occupied(o) if o.get().0 != row => {
                        return Err(part_err(
                            &part.path,
                            format!(
                                "its row of scale index {s}, run {r} differs from the one in `{}`; \
                                 delete the wrong part and rerun its shard",
                                o.get().1.display()
                            ),
                        ));
                    }
                    Entry::Occupied(_) => {}
                }
            }
            let name = kalman_part_name(part.shard);
            if di > 0 && !dirs[0].join("points").join(&name).exists() {
                copies.push((
                    dirs[0].join("points").join(name),
                    fs::read_to_string(&part.path)
                        .map_err(io_err("read the Kalman part", &part.path))?,
                ));
            }
        }
    }
    let seeds = sweep.config().seeds;
    let points = scale_points(sweep);
    for (s, p) in points.iter().enumerate() {
        for r in 0..seeds {
            if rows.contains_key(&(s, r)) {
                continue;
            }
            let j = s * seeds + r;
            // The part that should hold the row: of the sharding the parts found use.
            let n = counts.first().copied().unwrap_or(1);
            let owner = Shard {
                index: j % n + 1,
                count: n,
            };
            let where_ = dirs
                .iter()
                .map(|d| format!("`{}`", d.display()))
                .collect::<Vec<_>>()
                .join(", ");
            return Err(part_err(
                &Path::new("points").join(kalman_part_name(owner)),
                format!(
                    "missing: no directory merged ({where_}) has the Kalman row of scale {}, \
                     run {r}; rerun that shard (`--shard {owner}`) with `estimators = [\"mhe\", \
                     \"kalman\"]` into its directory, then merge again",
                    p.scale
                ),
            ));
        }
    }
    let rows: Vec<KalmanRow> = rows
        .into_iter()
        .map(|((s, r), (row, _))| (s, r, row))
        .collect();
    Ok((kalman_csv(&rows), copies))
}

/// Copies the part files `assemble_kalman` found only in other directories.
pub(super) fn copy_parts(copies: &[(PathBuf, String)]) -> Result<()> {
    for (path, text) in copies {
        write_atomic(path, text)?;
    }
    Ok(())
}
