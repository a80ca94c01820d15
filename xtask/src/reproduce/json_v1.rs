//! `From<&tool record>` for the documents of `certificate_json::v1` (the records are filled
//! here; the schema is the crate's).

use certificate_json::v1;

impl From<&crate::reproduce::document::CertificateDocument> for v1::Certificate {
    fn from(l: &crate::reproduce::document::CertificateDocument) -> Self {
        Self {
            format: l.format.to_string(),
            format_version: l.format_version,
            preset: l.preset.as_ref().map(v1::Preset::from),
            label: l.label.to_string(),
            scenario: l.scenario.clone(),
            provenance: v1::Provenance::from(&l.provenance),
            host: l.host.clone(),
            settings: l.settings.clone(),
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
            paper_comparison: l
                .paper_comparison
                .iter()
                .map(v1::ComparisonRow::from)
                .collect(),
            files: l.files.iter().map(ToString::to_string).collect(),
            figure_notes: l.figure_notes.iter().map(ToString::to_string).collect(),
            budget: (l.budget.as_ref()).and_then(|b| serde_json::to_value(b).ok()),
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
