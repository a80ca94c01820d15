//! Reading finished point files back (resume) and assembling them into `runs.csv` and
//! `points.csv` (and `kalman.csv` from the shards' parts, `kalman_parts.rs`), from one
//! output directory or from several shard directories (merge).
//!
//! Every point file is validated in full before anything is written ([`Sweep::finished_points`]);
//! two directories that hold different results for one point are a conflict naming both
//! files; `runs.csv` and `points.csv` are assembled in memory ([`Assembled`]) and either
//! written here (to temporary names, renamed only when both are complete) or handed to the
//! caller, which commits them in one set with its own files (`xtask sweep`).

use std::collections::BTreeMap;
use std::collections::btree_map::Entry;
use std::fs;
use std::path::{Path, PathBuf};

use super::error::{Result, SweepError, io_err, point_file_err};
use super::format::{
    PointFile, PointFileRules, SETTINGS_FILE, commit, point_file_name, points_header, runs_header,
    settings_diff, settings_text, write_atomic, write_temp,
};
use super::kalman_parts::{assemble_kalman, copy_parts};
use super::run::{Progress, Staged, Sweep, SweepReport, take_lock};
use super::seeds::run_seed;

impl Sweep {
    /// Reads the finished point files in `dir/points` of this sweep: index → file. Each
    /// file is checked in full ([`PointFile`] format, fingerprint, every row and cell
    /// against its point); a file of another fingerprint or a malformed one is an error
    /// naming it. `*.tmp` leftovers of a killed run are ignored; a directory without
    /// `points/` has no finished points.
    pub fn finished_points(&self, dir: &Path) -> Result<BTreeMap<usize, PointFile>> {
        let pdir = dir.join("points");
        let mut out = BTreeMap::new();
        if !pdir.is_dir() {
            return Ok(out);
        }
        let cfg = self.config();
        let rules = PointFileRules {
            metrics: &cfg.metrics,
            seeds: cfg.seeds,
            steps: self.steps(),
            two_d: cfg.is_2d(),
        };
        for p in self.points() {
            let path = pdir.join(point_file_name(p.index));
            if !path.is_file() {
                continue;
            }
            let f = PointFile::read(&path)?;
            if f.fingerprint != self.fingerprint() {
                let detail = fs::read_to_string(pdir.join(SETTINGS_FILE))
                    .map(|t| settings_diff(&t, self.fingerprint(), self.canonical()))
                    .unwrap_or_default();
                return Err(SweepError::Fingerprint {
                    path,
                    found: f.fingerprint,
                    expected: self.fingerprint().to_string(),
                    detail,
                });
            }
            let seed_of = |r| run_seed(self.base_seed(), p, r, cfg.common_random_numbers);
            f.validate(&path, p, &rules, &seed_of)?;
            f.check_theory(&self.theory_at(p), &rules)
                .and_then(|()| f.check_sealed())
                .map_err(|problem| point_file_err(&path, problem))?;
            out.insert(p.index, f);
        }
        Ok(out)
    }
}

/// A validated point file and where it was found.
#[derive(Debug)]
struct Found {
    path: PathBuf,
    /// Index of its directory in the list read.
    dir: usize,
    file: PointFile,
}

/// The point files of `dirs`, in that order of precedence; the same point in two
/// directories is accepted only with the same results (timing aside).
fn collect(sweep: &Sweep, dirs: &[&Path]) -> Result<BTreeMap<usize, Found>> {
    let mut files: BTreeMap<usize, Found> = BTreeMap::new();
    for (di, d) in dirs.iter().enumerate() {
        for (i, file) in sweep.finished_points(d)? {
            let path = d.join("points").join(point_file_name(i));
            match files.entry(i) {
                Entry::Vacant(v) => {
                    v.insert(Found {
                        path,
                        dir: di,
                        file,
                    });
                }
                Entry::Occupied(o) => {
                    let cfg = sweep.config();
                    if !o.get().file.same_results(&file, &cfg.metrics, cfg.is_2d()) {
                        return Err(SweepError::Conflict {
                            point: i,
                            first: o.get().path.clone(),
                            second: path,
                        });
                    }
                }
            }
        }
    }
    Ok(files)
}

/// Every point of the sweep has a file in `files` (by point index), or the first missing one.
fn check_complete<V>(sweep: &Sweep, files: &BTreeMap<usize, V>) -> Result<()> {
    let total = sweep.points().len();
    if files.len() < total {
        let first = sweep
            .points()
            .iter()
            .map(|p| p.index)
            .find(|i| !files.contains_key(i))
            .unwrap_or(0);
        return Err(SweepError::Incomplete {
            missing: total - files.len(),
            total,
            first,
        });
    }
    Ok(())
}

/// The text of `runs.csv`, `points.csv` (and `kalman.csv`) of an assembled sweep.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Assembled {
    /// `runs.csv`.
    pub runs: String,
    /// `points.csv`.
    pub points: String,
    /// `kalman.csv`: the Kalman-filter baseline (`estimators = ["mhe", "kalman"]`), when asked.
    pub kalman: Option<String>,
}

impl Assembled {
    /// Writes both into `out`: to temporary names first, renamed only when both are
    /// written (a caller with more files to write stages these with them instead).
    pub fn write(&self, out: &Path) -> Result<()> {
        let (runs_path, points_path) = (out.join("runs.csv"), out.join("points.csv"));
        let runs_tmp = write_temp(&runs_path, &self.runs)?;
        let points_tmp = write_temp(&points_path, &self.points).inspect_err(|_| {
            let _ = fs::remove_file(&runs_tmp);
        })?;
        commit(&runs_tmp, &runs_path).inspect_err(|_| {
            let _ = fs::remove_file(&points_tmp);
        })?;
        commit(&points_tmp, &points_path)?;
        match &self.kalman {
            Some(k) => super::format::write_atomic(&out.join("kalman.csv"), k),
            None => Ok(()),
        }
    }
}

/// `runs.csv` and `points.csv` from point files already validated and in memory (a
/// sweep's own: those it found at the start and those it wrote), covering every point.
pub(super) fn assemble_files(
    sweep: &Sweep,
    files: &BTreeMap<usize, PointFile>,
) -> Result<Assembled> {
    check_complete(sweep, files)?;
    Ok(assemble_texts(sweep, files.values()))
}

/// `runs.csv` and `points.csv` from point files in point order.
fn assemble_texts<'a>(sweep: &Sweep, files: impl Iterator<Item = &'a PointFile>) -> Assembled {
    let metrics = &sweep.config().metrics;
    let two_d = sweep.config().is_2d();
    let mut runs = runs_header(metrics, two_d);
    runs.push('\n');
    let mut points = points_header(metrics, two_d);
    points.push('\n');
    for f in files {
        for r in &f.run_rows {
            runs.push_str(r);
            runs.push('\n');
        }
        points.push_str(&f.point_row);
        points.push('\n');
    }
    Assembled {
        runs,
        points,
        kalman: None,
    }
}

/// Validates `files` (every point present) and assembles them, with `kalman.csv` from the
/// shards' parts in `dirs` when the sweep runs the Kalman baseline. Returns the tables and
/// the Kalman parts to copy into `dirs[0]` ([`assemble_kalman`]).
fn assemble_found(
    sweep: &Sweep,
    files: &BTreeMap<usize, Found>,
    dirs: &[&Path],
) -> Result<(Assembled, Vec<(PathBuf, String)>)> {
    check_complete(sweep, files)?;
    let mut tables = assemble_texts(sweep, files.values().map(|f| &f.file));
    let mut copies = Vec::new();
    if sweep.config().kalman {
        let (text, c) = assemble_kalman(sweep, dirs)?;
        tables.kalman = Some(text);
        copies = c;
    }
    Ok((tables, copies))
}

/// [`assemble`] for a caller that holds the lock of `out`.
pub(super) fn assemble_locked(sweep: &Sweep, dirs: &[&Path], out: &Path) -> Result<usize> {
    let files = collect(sweep, dirs)?;
    let (tables, _) = assemble_found(sweep, &files, dirs)?;
    tables.write(out)?;
    Ok(files.len())
}

/// Writes `runs.csv` and `points.csv` into `out` from the point files found in `dirs`
/// (each a sweep output directory with a `points/` folder), after validating every file:
/// every point must be present, and a point found in two directories must have the same
/// results there (the first listed is used). Takes the lock of `out`. Returns the number
/// of points.
pub fn assemble(
    sweep: &Sweep,
    dirs: &[&Path],
    out: &Path,
    progress: &dyn Progress,
) -> Result<usize> {
    fs::create_dir_all(out).map_err(io_err("create the output directory", out))?;
    let _lock = take_lock(out, None, progress)?;
    assemble_locked(sweep, dirs, out)
}

/// Whether two paths name the same directory.
fn same_dir(a: &Path, b: &Path) -> bool {
    match (fs::canonicalize(a), fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// Assembles a sweep from the point files of several (shard) output directories into
/// `out` (its own `points/` gets a copy of every point file, so `out` is a complete
/// sweep directory that a rerun recognises as finished).
///
/// Every directory listed must be a sweep output directory (with `points/`); the files
/// already in `out` count as one more directory, read first. Every file is validated,
/// two different copies of one point are a conflict naming both, and nothing is written
/// before all points are present and valid. Takes the lock of `out`.
pub fn merge_point_dirs(
    sweep: &Sweep,
    dirs: &[&Path],
    out: &Path,
    progress: &dyn Progress,
) -> Result<usize> {
    let (n, staged) = merge_staged(sweep, dirs, out, progress)?;
    if let Some(a) = &staged.outputs {
        a.write(out)?;
    }
    Ok(n)
}

/// [`merge_point_dirs`] without writing `runs.csv` and `points.csv`: the point files are
/// copied into `out/points`, and the two tables are returned with the lock of `out` held
/// (see [`Sweep::run_staged`]). Returns the number of points.
pub fn merge_staged(
    sweep: &Sweep,
    dirs: &[&Path],
    out: &Path,
    progress: &dyn Progress,
) -> Result<(usize, Staged)> {
    if let Some(d) = dirs.iter().find(|d| !d.join("points").is_dir()) {
        return Err(SweepError::NotASweepDir {
            path: d.to_path_buf(),
        });
    }
    let pdir = out.join("points");
    fs::create_dir_all(&pdir).map_err(io_err("create the output directory", &pdir))?;
    let lock = take_lock(out, None, progress)?;
    let mut all = vec![out];
    all.extend(dirs.iter().copied().filter(|d| !same_dir(d, out)));
    let files = collect(sweep, &all)?;
    // Every table assembled (every file checked) before anything is written.
    let (outputs, kalman_copies) = assemble_found(sweep, &files, &all)?;
    write_atomic(
        &pdir.join(SETTINGS_FILE),
        &settings_text(sweep.fingerprint(), sweep.canonical()),
    )?;
    for (&i, f) in &files {
        if f.dir != 0 {
            f.file.write_atomic(&pdir.join(point_file_name(i)))?;
        }
    }
    copy_parts(&kalman_copies)?;
    let staged = Staged {
        report: SweepReport {
            computed: files.len(),
            skipped: 0,
            steps_simulated: 0,
            wall_s: 0.0,
            runs_wall_s: 0.0,
            threads: 0,
            assembled: true,
            schedule: Default::default(),
        },
        outputs: Some(outputs),
        _lock: lock,
    };
    Ok((files.len(), staged))
}
