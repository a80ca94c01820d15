//! [`SweepError`], the one error type of the sweep.
//!
//! A variant that wraps another error returns it from [`std::error::Error::source`] and
//! does not repeat its text in its own message, so a chain printed with anyhow's `{:#}`
//! names every cause once.

use std::path::{Path, PathBuf};

use closed_loop::sim::ClosedLoopError;

/// What can go wrong in a sweep: bad configuration (naming the key), bad shard spec,
/// unusable output directory, files of another configuration or corrupt ones, another
/// writer in the output directory, or a setup error of the closed loop.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SweepError {
    /// A configuration key is missing, has the wrong type or an invalid value.
    #[error("sweep config: `{key}`: {problem}")]
    Config {
        /// The full key path (`k.points`, `solvers[1]`, `controller.iterations`).
        key: String,
        /// What is wrong and how to fix it.
        problem: String,
    },
    /// The configuration is not valid TOML.
    #[error("sweep config is not valid TOML: {0}")]
    Toml(String),
    /// A shard spec other than `I/N` with 1 ≤ I ≤ N.
    #[error("shard `{spec}`: {problem}; write I/N with 1 ≤ I ≤ N, e.g. `2/4`")]
    Shard {
        /// The spec given.
        spec: String,
        /// What is wrong.
        problem: String,
    },
    /// [`crate::Progress::cancelled`] returned `true`: stopped between tasks (the point
    /// files written so far are kept; a rerun resumes from them).
    #[error("the sweep was cancelled (the finished point files are kept; rerun to resume)")]
    Cancelled,
    /// `threads` = 0 or the rayon pool could not start.
    #[error("threads: {0}")]
    Threads(String),
    /// A file or directory could not be read or written.
    #[error("cannot {action} `{path}`")]
    Io {
        /// What was attempted (`"create the output directory"`, …).
        action: &'static str,
        /// The path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The scenario file is invalid.
    #[error("scenario `{path}`")]
    Scenario {
        /// The scenario path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: lti_model::ModelError,
    },
    /// The case-study loop could not be built for a point.
    #[error("cannot set up the closed loop for {point}")]
    Setup {
        /// The point (`K = …, solver = …, scale = …`).
        point: String,
        /// The cause.
        #[source]
        source: ClosedLoopError,
    },
    /// The output directory holds point files of a different configuration.
    #[error(
        "`{path}` was written by a different sweep configuration or scenario (fingerprint {found}, \
         this sweep {expected}{detail}); use another --out directory or delete the old one"
    )]
    Fingerprint {
        /// The point file.
        path: PathBuf,
        /// Its fingerprint.
        found: String,
        /// This sweep's fingerprint.
        expected: String,
        /// What differs, when the directory records the settings it was written with
        /// (`; settings that differ: k_c = [1, 5] there, [1, 2] here`), else empty.
        detail: String,
    },
    /// A point file is malformed (cut, edited, copied from another point, not text).
    #[error(
        "point file `{path}` is malformed: {problem}; delete it and rerun the sweep (or its shard) \
         to recompute the point"
    )]
    PointFile {
        /// The file.
        path: PathBuf,
        /// What is wrong (the row and column where it applies).
        problem: String,
    },
    /// Two directories of a merge hold different results for one point.
    #[error(
        "point {point} has two different point files, `{first}` and `{second}` (they differ in more \
         than the wall_* timing columns); delete the wrong one, or both and rerun the point"
    )]
    Conflict {
        /// The point index.
        point: usize,
        /// The file found first (in the order of the directories).
        first: PathBuf,
        /// The other file.
        second: PathBuf,
    },
    /// A directory to merge is not a sweep output directory.
    #[error(
        "`{path}` is not a sweep output directory (it has no `points/` folder); check the path of \
         the shard directory"
    )]
    NotASweepDir {
        /// The directory given.
        path: PathBuf,
    },
    /// Another live process writes into the output directory.
    #[error(
        "`{dir}` is being written by another sweep ({holder}); wait for it to finish, or delete \
         `{lock}` if no sweep is running there"
    )]
    Locked {
        /// The output directory.
        dir: PathBuf,
        /// Who holds it: `pid N`, `pid N on host H`, `pid N, shard I/N`, or `pid unknown`.
        holder: String,
        /// The lock file.
        lock: PathBuf,
    },
    /// A part of the Kalman baseline of a sharded sweep (`points/kalman.shard-I-of-N.csv`)
    /// is missing, malformed, or disagrees with another one.
    #[error("Kalman baseline part `{path}`: {problem}")]
    KalmanPart {
        /// The part file (for a missing one: the name it should have, under `points/`).
        path: PathBuf,
        /// What is wrong (the line and column where it applies) and the fix.
        problem: String,
    },
    /// Assembling needs every point, and some are missing.
    #[error(
        "{missing} of {total} points have no point file (first missing: point {first}); run the \
         missing shards (or rerun the sweep to resume) before assembling"
    )]
    Incomplete {
        /// Number of missing points.
        missing: usize,
        /// Number of points of the sweep.
        total: usize,
        /// Index of the first missing point.
        first: usize,
    },
}

/// Result alias of the sweep.
pub type Result<T> = std::result::Result<T, SweepError>;

pub(super) fn config_err(key: impl Into<String>, problem: impl Into<String>) -> SweepError {
    SweepError::Config {
        key: key.into(),
        problem: problem.into(),
    }
}

pub(super) fn io_err(
    action: &'static str,
    path: &Path,
) -> impl FnOnce(std::io::Error) -> SweepError + use<> {
    let path = path.to_path_buf();
    move |source| SweepError::Io {
        action,
        path,
        source,
    }
}

pub(super) fn point_file_err(path: &Path, problem: impl Into<String>) -> SweepError {
    SweepError::PointFile {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}
