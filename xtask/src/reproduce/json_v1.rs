//! `From<&tool record>` for the documents of `certificate_json::v1` (the records are filled
//! here; the schema is the crate's).

use certificate_json::v1;
use certificate_json::v1::num;

impl From<&crate::reproduce::document::CertificateDocument> for v1::Certificate {
    fn from(l: &crate::reproduce::document::CertificateDocument) -> Self {
        Self {
            format: l.format.to_string(),
            format_version: l.format_version,
            preset: l.preset.as_ref().map(v1::Preset::from),
            label: l.label.to_string(),
            scenario: v1::ScenarioRecord::from(&l.scenario),
            provenance: v1::Provenance::from(&l.provenance),
            host: v1::HostInfo::from(&l.host),
            settings: v1::SettingsRecord::from(&l.settings),
            solver: l.solver.to_string(),
            scenario_iterations: l.scenario_iterations,
            certified: l.certified,
            certificate_applies: l
                .certificate_applies
                .as_ref()
                .map(v1::CertificateKind::from),
            not_covered: l.not_covered.as_ref().map(ToString::to_string),
            at_scenario: v1::PairVerdict::from(&l.at_scenario),
            scenario_iterations_match_k_min: l.scenario_iterations_match_k_min,
            solvers: l.solvers.iter().map(v1::SolverSummary::from).collect(),
            certificate: v1::ClosedLoopCertificate::from(&l.certificate),
            runs: l.runs.iter().map(run_summary).collect(),
            skipped_runs: l.skipped_runs.iter().map(skipped_run).collect(),
            trajectory_check: trajectory_report(&l.trajectory_check),
            joint: l.joint.as_ref().map(joint_report),
            linear: l.linear.iter().map(linear_entry).collect(),
            regional: l.regional.iter().map(regional_entry).collect(),
            asymptotic_gains: gains_report(&l.asymptotic_gains),
            paper_comparison: l.paper_comparison.iter().map(comparison_row).collect(),
            files: l.files.iter().map(ToString::to_string).collect(),
            figure_notes: l.figure_notes.iter().map(ToString::to_string).collect(),
            budget: (l.budget.as_ref()).and_then(|b| serde_json::to_value(b).ok()),
        }
    }
}

/// `v1::ComparisonRow` of the library's record (a function: both types are other crates').
pub(super) fn comparison_row(l: &mhe_report::ComparisonRow) -> v1::ComparisonRow {
    v1::ComparisonRow {
        quantity: l.quantity.to_string(),
        ours: l.ours.to_string(),
        paper: l.paper.to_string(),
    }
}

impl From<&crate::reproduce::document::HostInfo> for v1::HostInfo {
    fn from(l: &crate::reproduce::document::HostInfo) -> Self {
        Self {
            hostname: l.hostname.as_ref().map(ToString::to_string),
            os: l.os.to_string(),
            arch: l.arch.to_string(),
            cpus: l.cpus,
        }
    }
}

/// `v1::KalmanSummary` of the library's record (a function: both types are other crates').
pub(super) fn kalman_summary(l: &mhe_report::KalmanSummary) -> v1::KalmanSummary {
    v1::KalmanSummary {
        weights: l.weights.to_string(),
        completed: l.completed,
        sup_norm_e: num(l.sup_norm_e),
        tail_mean_e: l.tail_mean_e.and_then(num),
        diverged: l.diverged,
        divergence: l.divergence.as_ref().map(v1::Divergence::from),
        error: l.error.as_ref().map(ToString::to_string),
    }
}

/// `v1::RunSummary` of the library's record (a function: both types are other crates').
pub(super) fn run_summary(l: &mhe_report::RunSummary) -> v1::RunSummary {
    v1::RunSummary {
        label: l.label.to_string(),
        k: l.k,
        k_source: v1::KSource::from(&l.k_source),
        solver: l.solver.to_string(),
        controller: l.controller.to_string(),
        exact_mhe_solve: l.exact_mhe_solve,
        seed: l.seed,
        steps: l.steps,
        completed: l.completed,
        error: l.error.as_ref().map(ToString::to_string),
        diverged: l.diverged,
        diverged_at: l.diverged_at,
        signal: l.signal.as_ref().map(v1::Signal::from),
        divergence: l.divergence.as_ref().map(v1::Divergence::from),
        mpc_infeasible_steps: l.mpc_infeasible_steps,
        sup_norm_e: num(l.sup_norm_e),
        sup_norm_x: num(l.sup_norm_x),
        final_norm_x: num(l.final_norm_x),
        tail_mean_e: l.tail_mean_e.and_then(num),
        tail_mean_x: l.tail_mean_x.and_then(num),
        tail_mean_epsilon: l.tail_mean_epsilon.and_then(num),
        w_outside: l.w_outside,
        w_outside_first: l.w_outside_first,
        kalman: l.kalman.as_ref().map(kalman_summary),
    }
}

impl From<&crate::reproduce::document::ScenarioRecord> for v1::ScenarioRecord {
    fn from(l: &crate::reproduce::document::ScenarioRecord) -> Self {
        Self {
            name: l.name.to_string(),
            description: l.description.as_ref().map(ToString::to_string),
            path: l.path.to_string(),
            text: l.text.as_ref().map(ToString::to_string),
        }
    }
}

impl From<&crate::reproduce::document::SettingsRecord> for v1::SettingsRecord {
    fn from(l: &crate::reproduce::document::SettingsRecord) -> Self {
        Self {
            sampling_seed: l.sampling_seed,
            lipschitz_pairs: l.lipschitz_pairs,
            gamma13_sequences: l.gamma13_sequences,
            enumeration_max_vars: l.enumeration_max_vars,
            k_max: l.k_max,
            small_k: l.small_k,
            fig2c_t: l.fig2c_t,
            sim_k_cap: l.sim_k_cap,
        }
    }
}

/// `v1::SkippedRun` of the library's record (a function: both types are other crates').
pub(super) fn skipped_run(l: &mhe_report::SkippedRun) -> v1::SkippedRun {
    v1::SkippedRun {
        k: l.k,
        k_source: v1::KSource::from(&l.k_source),
        reason: l.reason.to_string(),
    }
}

impl From<&crate::reproduce::document::SolverSummary> for v1::SolverSummary {
    fn from(l: &crate::reproduce::document::SolverSummary) -> Self {
        Self {
            solver: l.solver.to_string(),
            simulated: l.simulated,
            certified: l.certified,
            k_min: l.k_min,
            void_reasons: l.void_reasons.iter().map(ToString::to_string).collect(),
            not_computed: l.not_computed.as_ref().map(v1::NotComputed::from),
            premises: l.premises.iter().map(v1::Premise::from).collect(),
            phi_rate: num(l.phi_rate),
            phi_prefactor: num(l.phi_prefactor),
            margin_at_k_min: l.margin_at_k_min.and_then(num),
            k_min_with_sampled_l_phi: l.k_min_with_sampled_l_phi,
        }
    }
}

/// `v1::TrajectoryReport` of the library's record (a function: both types are other crates').
pub(super) fn trajectory_report(l: &mhe_report::TrajectoryReport) -> v1::TrajectoryReport {
    v1::TrajectoryReport {
        ran: l.ran,
        reason: l.reason.as_ref().map(ToString::to_string),
        solver: l.solver.to_string(),
        k: l.k,
        seed: l.seed,
        steps: l.steps,
        certified_l_phi: l.certified_l_phi.as_ref().map(v1::TrajectoryCheck::from),
        sampled_l_phi: l.sampled_l_phi.as_ref().map(v1::TrajectoryCheck::from),
        passed: l.passed,
    }
}

/// `v1::CertifiedBound` of the library's record (a function: both types are other crates').
pub(super) fn certified_bound(l: &mhe_report::gains::CertifiedBound) -> v1::CertifiedBound {
    v1::CertifiedBound {
        gain_x: num(l.gain_x),
        gain_epsilon: num(l.gain_epsilon),
        gain_e: num(l.gain_e),
        bound_x: num(l.bound_x),
        bound_epsilon: num(l.bound_epsilon),
        bound_e: num(l.bound_e),
    }
}

/// `v1::GainsReport` of the library's record (a function: both types are other crates').
pub(super) fn gains_report(l: &mhe_report::gains::GainsReport) -> v1::GainsReport {
    v1::GainsReport {
        meaning: l.meaning.to_string(),
        methods: l.methods.iter().map(method_gains).collect(),
        runs: l.runs.iter().map(run_gains).collect(),
    }
}

/// `v1::MethodGains` of the library's record (a function: both types are other crates').
pub(super) fn method_gains(l: &mhe_report::gains::MethodGains) -> v1::MethodGains {
    v1::MethodGains {
        solver: l.solver.to_string(),
        k_min: l.k_min,
        theorem1: l.theorem1.as_ref().map(v1::AsymptoticGains::from),
        theorem1_void: l.theorem1_void.as_ref().map(ToString::to_string),
        regional: l.regional.as_ref().map(regional_gains),
        regional_void: l.regional_void.as_ref().map(ToString::to_string),
    }
}

/// `v1::RegionalGains` of the library's record (a function: both types are other crates').
pub(super) fn regional_gains(l: &mhe_report::gains::RegionalGains) -> v1::RegionalGains {
    v1::RegionalGains {
        k: l.k,
        gain_x: num(l.gain_x),
        gain_e: num(l.gain_e),
        contains: l.contains,
        w_bar: num(l.w_bar),
    }
}

/// `v1::RunGains` of the library's record (a function: both types are other crates').
pub(super) fn run_gains(l: &mhe_report::gains::RunGains) -> v1::RunGains {
    v1::RunGains {
        label: l.label.to_string(),
        k: l.k,
        controller: l.controller.to_string(),
        w_bar: l.w_bar.and_then(num),
        certified: l.certified.as_ref().map(certified_bound),
        certified_void: l.certified_void.as_ref().map(ToString::to_string),
        measured: l.measured.as_ref().map(v1::MeasuredGains::from),
    }
}

impl From<&crate::reproduce::job::Preset> for v1::Preset {
    fn from(l: &crate::reproduce::job::Preset) -> Self {
        match l {
            crate::reproduce::job::Preset::Paper => Self::Paper,
            crate::reproduce::job::Preset::Certified => Self::Certified,
        }
    }
}

/// `v1::JointReport` of the library's record (a function: both types are other crates').
pub(super) fn joint_report(l: &mhe_report::joint::JointReport) -> v1::JointReport {
    v1::JointReport {
        scenario_k_c: l.scenario_k_c,
        certificate: v1::JointCertificate::from(&l.certificate),
        trajectory: l.trajectory.as_ref().map(v1::JointTrajectoryCheck::from),
        replay_mismatch: l.replay_mismatch.and_then(num),
        reason: l.reason.as_ref().map(ToString::to_string),
    }
}

/// `v1::LinearEntry` of the library's record (a function: both types are other crates').
pub(super) fn linear_entry(l: &mhe_report::linear::LinearEntry) -> v1::LinearEntry {
    v1::LinearEntry {
        solver: l.solver.to_string(),
        report: l.report.as_ref().map(v1::LinearReport::from),
        error: l.error.as_ref().map(ToString::to_string),
    }
}

/// `v1::RegionalEntry` of the library's record (a function: both types are other crates').
pub(super) fn regional_entry(l: &mhe_report::regional::RegionalEntry) -> v1::RegionalEntry {
    v1::RegionalEntry {
        solver: l.solver.to_string(),
        k_lin: l.k_lin,
        k_lin_not_computed: l.k_lin_not_computed.as_ref().map(ToString::to_string),
        k_min: l.k_min,
        k_reg: l.k_reg,
        search_max: l.search_max,
        search_max_reason: l.search_max_reason.to_string(),
        k: l.k,
        certificate: l.certificate.as_ref().map(v1::RegionalCertificate::from),
        tried: l.tried.iter().map(tried_k).collect(),
        void: l.void.as_ref().map(ToString::to_string),
        refuted_every_k: l.refuted_every_k.as_ref().map(v1::Limit::from),
        k_free: l.k_free.as_ref().map(v1::KFreeLimits::from),
        uncertainty: l.uncertainty.as_ref().map(v1::RegionalOptions::from),
        at_two_k_lin: l.at_two_k_lin.as_ref().map(v1::ProbeNote::from),
    }
}

/// `v1::TriedK` of the library's record (a function: both types are other crates').
pub(super) fn tried_k(l: &mhe_report::regional::TriedK) -> v1::TriedK {
    v1::TriedK {
        k: l.k,
        margin: num(l.margin),
        contains: l.contains,
    }
}

impl From<&crate::provenance::Provenance> for v1::Provenance {
    fn from(l: &crate::provenance::Provenance) -> Self {
        Self {
            tool: l.tool.to_string(),
            tool_version: l.tool_version.to_string(),
            git_revision: l.git_revision.to_string(),
            git_dirty: l.git_dirty,
            rustc: l.rustc.as_ref().map(ToString::to_string),
            created_unix: l.created_unix,
        }
    }
}
