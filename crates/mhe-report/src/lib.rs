//! The case study of Section IV of Yang–Manzie–Pu (arXiv 2304.06216) as a library call: one
//! scenario in, one typed [`Report`] out — the same numbers `cargo xtask reproduce` prints
//! and writes to `certificate.json`.
//!
//! [`report`] runs four stages, each on what the previous one produced:
//!
//! 1. **plan**: the closed-loop certificate of Theorem 1 for every method
//!    ([`iss_certificate::certificate::certify_closed_loop_timed`]), the linear stability
//!    boundary ρ_lin(K) ([`linear`]), K_reg of the regional certificate ([`regional`]), the
//!    joint MPC + MHE certificate when the MPC runs K_c iterations ([`joint`]), and the
//!    simulations they decide ([`iss_certificate::plan::plan_runs`]);
//! 2. **simulate**: Alg. 1 at each planned K with the exact MHE solve on (for ε_t) and the
//!    Kalman baseline on the same data ([`Run`]); a run beyond the work limit ([`Work`]) or
//!    above [`Options::sim_k_cap`] is skipped with the reason ([`SkippedRun`]);
//! 3. **check**: the trajectory inequalities of Props. 1 and 3 on the K_min run
//!    ([`TrajectoryReport`]), or the joint check;
//! 4. **gains**: the certified asymptotic gains next to the measured ones ([`gains`]) and
//!    the constants beside the paper's published values ([`paper_comparison`]).
//!
//! Rendering (the terminal summary, certificate.json, trace.csv) is the tool's, except the
//! figures: with the feature `figures`, `figures` draws the paper's Fig. 2 analogues and the
//! component grids from [`Report::runs`] as SVG text. The work log ([`Report::log`]) and progress go to an [`Observer`].
//!
//! ```no_run
//! use closed_loop::scenario::Scenario;
//!
//! let scenario = Scenario::from_file("scenarios/case-study-certified.toml")?;
//! let report = mhe_report::report(scenario, &mhe_report::Options::default(), &mhe_report::Quiet)?;
//! let k_min = report.certificate.solver(report.solver).and_then(|s| s.k_min);
//! println!("K_min = {k_min:?}, runs: {}", report.runs.len());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use closed_loop::ClosedLoopError;
use closed_loop::scenario::{ControllerChoice, ResolvedScenario, Scenario};
use iss_certificate::certificate::{CertificateOptions, CertificateTimes, ClosedLoopCertificate};
use iss_certificate::coverage::{Applicable, PairVerdict};
use iss_certificate::joint::JointCertificate;
use iss_certificate::plan::KSource;
use qp_iter::Method;

mod comparison;
#[cfg(feature = "figures")]
pub mod figures;
pub mod gains;
pub mod ioss;
pub mod joint;
pub mod linear;
pub mod regional;
mod runs;
mod stages;
mod verdicts;
mod work;

pub use comparison::{ComparisonRow, paper_comparison, short_reason};
pub use runs::{KalmanSummary, Run, RunSummary, kalman_baseline};
pub use stages::{PlannedRun, SkippedRun, TrajectoryReport};
pub use verdicts::{F32Entry, SolverSummary};
pub use work::{MAX_SIMULATION_ITERATIONS, MAX_SIMULATION_WORK, Work};

/// Sampling, search and simulation settings (defaults: those of the shipped results). The
/// seed of every sampled estimate and of the simulations is the scenario's `noise.seed`.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Name in the work log's lines (`"[label] computing …"`).
    pub label: String,
    /// Random pairs of the sampled L_Φ and L_π.
    pub lipschitz_pairs: usize,
    /// Injected error sequences per magnitude for the sampled γ₁,₃ (0 skips it).
    pub gamma13_sequences: usize,
    /// Cap on N·n_u for the free-set enumerations (γ₁,₃, L_π).
    pub enumeration_max_vars: usize,
    /// γ₁,₃ from the certified enumeration or supplied (else the scenario's
    /// `certificate.gamma13`, else computed).
    pub gamma13: iss_certificate::certificate::Gamma13Source,
    /// Largest K searched for K_min.
    pub k_max: usize,
    /// The small K simulated next to the scenario's K when the certificate is void.
    pub small_k: usize,
    /// The largest computed K_min that is simulated (None: no cap beyond the work limit).
    pub sim_k_cap: Option<usize>,
    /// Worker threads of the parallel phases (ρ_lin, K_reg, the certificate's sampling):
    /// None runs on rayon's global pool; the results do not depend on the count.
    pub threads: Option<usize>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            label: "scenario".into(),
            lipschitz_pairs: 200,
            gamma13_sequences: 30,
            enumeration_max_vars: 20,
            gamma13: iss_certificate::certificate::Gamma13Source::Certified,
            k_max: 1 << 24,
            small_k: 5,
            sim_k_cap: None,
            threads: None,
        }
    }
}

/// What a caller sees while [`report`] works: the work log's lines as they happen, the
/// analysis options before the certificate, and progress. Every method does nothing by
/// default; [`Quiet`] is the observer that shows nothing. Called from two threads at once
/// (the ρ_lin and K_reg analysis runs beside the simulations) and from worker threads
/// (`linear_progress`), hence `Sync`.
pub trait Observer: Sync {
    /// One line of the work log (also in [`Report::log`]).
    fn line(&self, _line: &str) {}
    /// The certificate is about to be computed with `opts` (e.g. to print the estimated
    /// work of each phase: `iss_certificate::budget::estimate_phases`).
    fn certifying(
        &self,
        _scenario: &Scenario,
        _mpc: Option<&mpc_core::CondensedMpc>,
        _opts: &CertificateOptions,
    ) {
    }
    /// `done` of `total` (method, K) eigenvalue problems of ρ_lin, `elapsed_s` seconds after
    /// the phase started.
    fn linear_progress(&self, _done: usize, _total: usize, _elapsed_s: f64) {}
    /// A simulation of `steps` steps labelled `label` (e.g. `"PG K = 243"`) starts.
    fn simulation_started(&self, _label: &str, _steps: usize) {}
    /// `done` steps of the current simulation are finished.
    fn simulation_progress(&self, _done: usize) {}
    /// The current simulation ended (finished or stopped).
    fn simulation_finished(&self) {}
}

/// The observer that shows nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Quiet;

impl Observer for Quiet {}

/// Why [`report`] could not produce a [`Report`]. A void certificate, a diverged run or a
/// violated inequality is a result, not an error.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// The scenario lacks a section the report needs (`[mhe]`, `[mpc]`).
    #[error(transparent)]
    Scenario(ClosedLoopError),
    /// The scenario's K and T ask for more work than one simulation may do.
    #[error(
        "mhe.iterations = {} with simulation.steps = {}: {} (docs/limits.md); lower \
         mhe.iterations or simulation.steps",
        work.k,
        work.steps,
        work.excess()
    )]
    WorkLimit {
        /// The refused simulation.
        work: Work,
    },
    /// The scenario could not be set up for the certificate (P, the MPC, …).
    #[error(transparent)]
    Resolve(ClosedLoopError),
    /// The certificate of Theorem 1 could not be computed.
    #[error(transparent)]
    Certificate(ClosedLoopError),
    /// The joint MPC + MHE certificate could not be computed.
    #[error("cannot compute the joint MPC + MHE certificate")]
    Joint(#[source] ClosedLoopError),
    /// The closed loop at K could not be built.
    #[error("cannot set up the closed loop at K = {k}")]
    Loop {
        /// The K of the run.
        k: usize,
        /// Why.
        #[source]
        source: ClosedLoopError,
    },
    /// Another failure of the loop (the MPC of the joint check, the δ replay).
    #[error(transparent)]
    ClosedLoop(#[from] ClosedLoopError),
    /// [`Options::threads`] could not start a pool.
    #[error("cannot start {threads} worker threads: {reason}")]
    Threads {
        /// The count asked for.
        threads: usize,
        /// The pool's error.
        reason: String,
    },
}

/// Wall time of each phase, seconds (the results do not depend on them).
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct Timings {
    /// The certificate of Theorem 1, with its parts.
    pub certificate: CertificateTimes,
    /// Its wall time as the report measured it.
    pub certificate_s: f64,
    /// ρ_lin of every method.
    pub linear_s: f64,
    /// K_reg of every method.
    pub regional_s: f64,
    /// The f32 verdict of every method (Theorem 1 with the f32 rounding folded in).
    pub f32_s: f64,
    /// Each simulation, in the order of [`Report::runs`].
    pub simulations_s: Vec<f64>,
}

/// Everything one scenario's case study computed.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Report {
    /// The scenario as given.
    pub scenario: Scenario,
    /// It, resolved (P, the MPC): what the runs and the certificate used.
    pub resolved: ResolvedScenario,
    /// `mhe.method`, the method simulated.
    pub solver: Method,
    /// `mhe.iterations`.
    pub iterations: usize,
    /// The options of the certificate (the verdict's, with the report's sampling).
    pub certificate_options: CertificateOptions,
    /// Theorem 1's certificate for every method.
    pub certificate: ClosedLoopCertificate,
    /// ρ_lin(K) and K_lin per method.
    pub linear: Vec<linear::LinearEntry>,
    /// K_reg per method.
    pub regional: Vec<regional::RegionalEntry>,
    /// The one verdict in f32 per method (the smallest K certified in f32, or why none).
    pub f32: Vec<verdicts::F32Entry>,
    /// The joint certificate (the K_c-iteration MPC only).
    pub joint_certificate: Option<JointCertificate>,
    /// The scenario's own controller.
    pub controller: ControllerChoice,
    /// The certificate covering the scenario's configuration
    /// ([`iss_certificate::coverage`]).
    pub applicable: Applicable,
    /// Why none covers it (None when one does).
    pub not_covered: Option<String>,
    /// The covering certificate's verdict at the scenario's own pair.
    pub at_scenario: PairVerdict,
    /// The simulations the certificates decided, in order.
    pub planned: Vec<PlannedRun>,
    /// The simulations run.
    pub runs: Vec<Run>,
    /// The planned simulations not run, and why.
    pub skipped_runs: Vec<SkippedRun>,
    /// Props. 1 and 3 on the K_min run.
    pub trajectory_check: TrajectoryReport,
    /// The joint certificate's check (the K_c-iteration MPC only).
    pub joint: Option<joint::JointReport>,
    /// Certified asymptotic gains and the measured ones.
    pub gains: gains::GainsReport,
    /// The constants next to the paper's published values (meaningful for the paper's
    /// case study only).
    pub paper_comparison: Vec<ComparisonRow>,
    /// Wall time of each phase.
    pub timings: Timings,
    /// The work log, line by line.
    pub log: Vec<String>,
}

impl Report {
    /// The certified trajectory check ran and failed: a simulation contradicts the
    /// certificate.
    pub fn contradicted(&self) -> bool {
        self.trajectory_check.passed == Some(false)
    }

    /// A simulated run left the bounded rule ([`closed_loop::bounded`]) or stopped early.
    pub fn diverged(&self) -> bool {
        self.runs
            .iter()
            .any(|r| r.summary.diverged || r.summary.error.is_some())
    }

    /// The simulation of the K chosen for `source` (e.g. the computed K_min), if it ran.
    pub fn run_at(&self, source: KSource) -> Option<&Run> {
        self.runs.iter().find(|r| r.summary.k_source == source)
    }
}

/// The case study of `scenario`: certificate, simulations, checks and gains (module docs).
///
/// Errors: a scenario without `[mhe]` or `[mpc]`, a scenario K beyond the work limit, a
/// scenario that cannot be resolved or certified ([`ReportError`]). A void certificate is a
/// result.
pub fn report(
    scenario: Scenario,
    options: &Options,
    observer: &dyn Observer,
) -> Result<Report, ReportError> {
    match options.threads {
        None => stages::run(scenario, options, observer),
        Some(threads) => rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| ReportError::Threads {
                threads,
                reason: e.to_string(),
            })?
            .install(|| stages::run(scenario, options, observer)),
    }
}
