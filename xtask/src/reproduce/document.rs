//! The documents `reproduce` writes (`certificate.json`, `trace.json`) and its outcome:
//! plain serialisable records, filled in by `run_job` (docs/reproduce-output.md).

use super::*;

pub use certificate_json::v1::{HostInfo, ScenarioRecord, SettingsRecord};

/// The machine this process runs on (host name if it can be read, OS, architecture, CPUs).
pub(super) fn host_info() -> HostInfo {
    let hostname = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| std::fs::read_to_string("/etc/hostname"))
        .ok()
        .map(|s| s.trim().to_string())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .filter(|s| !s.is_empty());
    HostInfo {
        hostname,
        os: std::env::consts::OS.to_string(),
        arch: std::env::consts::ARCH.to_string(),
        cpus: std::thread::available_parallelism().ok().map(|n| n.get()),
    }
}

/// certificate.json (docs/reproduce-output.md).
#[derive(Debug, Clone)]
pub struct CertificateDocument {
    /// [`CERTIFICATE_FORMAT`].
    pub format: String,
    /// [`FORMAT_VERSION`].
    pub format_version: u32,
    /// The preset, if any.
    pub preset: Option<Preset>,
    /// The job label.
    pub label: String,
    /// The scenario.
    pub scenario: ScenarioRecord,
    /// Git revision, tool, compiler, time.
    pub provenance: Provenance,
    /// The machine.
    pub host: HostInfo,
    /// Sampling settings and seed.
    pub settings: SettingsRecord,
    /// The scenario's solver (the one simulated).
    pub solver: String,
    /// `mhe.iterations` of the scenario.
    pub scenario_iterations: usize,
    /// The scenario's solver has a K_min.
    pub certified: bool,
    /// The certificate covering the scenario's configuration (method, controller, warm
    /// start: [`iss_certificate::coverage`]): `"theorem1"`, `"joint"`, or null when none does.
    pub certificate_applies: Option<iss_certificate::coverage::CertificateKind>,
    /// Why no certificate covers the configuration (null when one does); `certified` is
    /// then false whatever Theorem 1's constants give.
    pub not_covered: Option<String>,
    /// The covering certificate's verdict at the scenario's own pair (`mhe.iterations`,
    /// `mpc.iterations`): the same function the sweeps' `certified` column calls.
    pub at_scenario: iss_certificate::coverage::PairVerdict,
    /// `scenario_iterations == k_min` of the scenario's solver (null when void).
    pub scenario_iterations_match_k_min: Option<bool>,
    /// Per solver: premises, K_min or reasons.
    pub solvers: Vec<mhe_report::SolverSummary>,
    /// Everything `certify_closed_loop` computed.
    pub certificate: ClosedLoopCertificate,
    /// The simulations.
    pub runs: Vec<RunSummary>,
    /// Simulations of the plan not run, and why (beyond the work limit).
    pub skipped_runs: Vec<SkippedRun>,
    /// Props. 1/3 on the K_min run.
    pub trajectory_check: TrajectoryReport,
    /// The joint MPC + MHE certificate and its trajectory check (only when the scenario's
    /// controller is the K-iteration MPC, `mpc.iterations`).
    pub joint: Option<mhe_report::joint::JointReport>,
    /// The exact linear stability boundary per method (exact MPC): ρ_lin(K) on a log grid,
    /// K_lin and every K with ρ_lin ≥ 1 (ρ_lin < 1 is necessary for local asymptotic stability of
    /// the origin when no constraint is active there; `iss_certificate::linear`).
    pub linear: Vec<LinearEntry>,
    /// K_reg of each method (`iss_certificate::regional`): the smallest K whose region
    /// contains the scenario's own uncertainty, searched up to K_min, with the region there
    /// (the certified rate and gains) — or the certificate at the largest K tried and the
    /// constraint that limits it (issue 27).
    pub regional: Vec<mhe_report::regional::RegionalEntry>,
    /// What the certificate guarantees: Theorem 1's certified asymptotic gains (and the
    /// regional ones) per method at K_min, and per run the certified bound next to the
    /// measured gains (`iss_certificate::asymptotic`, issue 27).
    pub asymptotic_gains: mhe_report::gains::GainsReport,
    /// Constants next to the paper's published values.
    pub paper_comparison: Vec<ComparisonRow>,
    /// Files written, relative to the output directory.
    pub files: Vec<String>,
    /// Figures not written or with points left out, and why.
    pub figure_notes: Vec<String>,
    /// The sample period as a budget (`plant.sample_time` given): per method at its smallest
    /// certified K (the one verdict's floor: K_min, K_glob or K_chain) the
    /// predicted instructions per step on the Cortex-M4F at 168 MHz and the M7 at 480 MHz
    /// and whether it fits T_s (`mhe_budget`, docs/embedded.md). Omitted without T_s.
    pub budget: Option<mhe_export::budget::ReproduceBudget>,
}

/// Result of one job.
#[derive(Debug)]
pub struct Outcome {
    /// certificate.json's content.
    pub document: CertificateDocument,
    /// The long text summary (printed with `-v`; in summary.md).
    pub summary: String,
    /// The summary that fits a screen: one table and the verdict (printed by default).
    pub screen: String,
    /// What was done, line by line, as it happened (the work lines; printed live with
    /// [`Settings::live`] and [`Settings::verbose`], which is how `-v` shows them; always in
    /// summary.md: this copy is for callers that run quietly, such as the tests).
    #[cfg_attr(not(test), allow(dead_code))]
    pub log: Vec<String>,
}

impl Outcome {
    /// The certified trajectory check ran and failed: the simulation contradicts the
    /// certificate.
    pub fn contradicted(&self) -> bool {
        self.document.trajectory_check.passed == Some(false)
    }

    /// A simulated run left the bounded rule ([`closed_loop::bounded`]) or stopped early
    /// on an error: exit code 4 unless an inequality was violated.
    pub fn diverged(&self) -> bool {
        self.document
            .runs
            .iter()
            .any(|r| r.diverged || r.error.is_some())
    }
}

/// The files of the previous run in a directory, from its `certificate.json` (`files`):
/// those the new set does not replace are removed when it is committed.
pub(super) fn previous_files(cert_path: &Path) -> Vec<String> {
    let Ok(text) = lti_model::spec::format::read_limited(cert_path) else {
        return Vec::new();
    };
    serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| {
            v.get("files")?.as_array().map(|a| {
                a.iter()
                    .filter_map(|f| f.as_str().map(str::to_string))
                    .collect()
            })
        })
        .unwrap_or_default()
}
