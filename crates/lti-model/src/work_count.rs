//! Counts of the computations a scenario needs once — P of LMI (2), the `[mhe]` settings'
//! validation (M, η, K of the file), the MHE problem ℙ_t, the condensed MPC — and of the
//! estimators built (each checks its own K), in this process.
//!
//! They are the evidence behind "K, M and P are validated and computed once per scenario":
//! `cargo xtask reproduce` prints them on stderr when `SUBOPTIMAL_MHE_COUNT_WORK` is set,
//! and a test compares them with the number of scenarios and runs. Relaxed atomic
//! increments, once per setup (never in a per-step path).
//!
//! ```
//! use lti_model::work_count::{Work, count, record};
//! let before = count(Work::LmiSolve);
//! record(Work::LmiSolve);
//! assert!(count(Work::LmiSolve) > before);
//! ```

use core::sync::atomic::{AtomicUsize, Ordering};

/// A once-per-scenario (or once-per-estimator) computation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Work {
    /// P of LMI (2) computed, or a user's P verified (`lti_model::ioss`).
    LmiSolve,
    /// The `[mhe]` settings read and validated (horizon M, η, K, weights).
    MheSettingsValidated,
    /// The MHE problem ℙ_t (every window m = 0..M) built.
    MheProblemBuilt,
    /// The condensed MPC built.
    MpcBuilt,
    /// An MHE estimator built on a shared ℙ_t (checks its K).
    EstimatorBuilt,
}

impl Work {
    /// Every counted computation, in output order.
    pub const ALL: [Work; 5] = [
        Work::LmiSolve,
        Work::MheSettingsValidated,
        Work::MheProblemBuilt,
        Work::MpcBuilt,
        Work::EstimatorBuilt,
    ];

    /// The name printed in the count line.
    pub fn name(self) -> &'static str {
        match self {
            Work::LmiSolve => "lmi_solves",
            Work::MheSettingsValidated => "mhe_settings",
            Work::MheProblemBuilt => "mhe_problems",
            Work::MpcBuilt => "mpc_builds",
            Work::EstimatorBuilt => "estimators",
        }
    }
}

static COUNTS: [AtomicUsize; 5] = [const { AtomicUsize::new(0) }; 5];

/// Counts one `w`.
pub fn record(w: Work) {
    COUNTS[w as usize].fetch_add(1, Ordering::Relaxed);
}

/// How many `w` this process has done so far.
pub fn count(w: Work) -> usize {
    COUNTS[w as usize].load(Ordering::Relaxed)
}

/// `name=count` for every [`Work`], space-separated (the line `reproduce` prints).
pub fn summary() -> String {
    Work::ALL
        .iter()
        .map(|&w| format!("{}={}", w.name(), count(w)))
        .collect::<Vec<_>>()
        .join(" ")
}
