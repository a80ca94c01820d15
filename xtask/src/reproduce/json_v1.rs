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
            runs: l.runs.iter().map(v1::RunSummary::from).collect(),
            skipped_runs: l.skipped_runs.iter().map(v1::SkippedRun::from).collect(),
            trajectory_check: v1::TrajectoryReport::from(&l.trajectory_check),
            joint: l.joint.as_ref().map(v1::JointReport::from),
            linear: l.linear.iter().map(v1::LinearEntry::from).collect(),
            regional: l.regional.iter().map(v1::RegionalEntry::from).collect(),
            asymptotic_gains: v1::GainsReport::from(&l.asymptotic_gains),
            paper_comparison: l.paper_comparison.iter().map(v1::ComparisonRow::from).collect(),
            files: l.files.iter().map(ToString::to_string).collect(),
            figure_notes: l.figure_notes.iter().map(ToString::to_string).collect(),
            budget: (l.budget.as_ref()).and_then(|b| serde_json::to_value(b).ok()),
        }
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







impl From<&crate::reproduce::job::Preset> for v1::Preset {
    fn from(l: &crate::reproduce::job::Preset) -> Self {
        match l {
            crate::reproduce::job::Preset::Paper => Self::Paper,
            crate::reproduce::job::Preset::Certified => Self::Certified,
        }
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
