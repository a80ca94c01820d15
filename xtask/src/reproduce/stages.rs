//! The tool's stages of [`super::run_job`] around the library's ([`mhe_report::report`]:
//! certify, simulate, check): read the scenario, then render (files and summaries) from
//! the report. None re-reads or recomputes what the library computed.

use super::*;
use mhe_report::{Report, ReportError};

/// The work lines of a job: printed as they happen when the command is verbose and live
/// (`-v`), kept in [`Outcome::log`] and `summary.md` either way.
pub(super) struct Log {
    print: bool,
    pub(super) lines: Vec<String>,
}

impl Log {
    /// The log of the library's stages, continued (its lines were printed as they happened).
    pub(super) fn continued(settings: &Settings, lines: Vec<String>) -> Self {
        Self {
            print: settings.live && settings.verbose,
            lines,
        }
    }

    pub(super) fn say(&mut self, line: String) {
        if self.print {
            outln!("{line}");
        }
        self.lines.push(line);
    }
}

/// Reads the scenario and refuses what is the tool's to refuse (the sections, Fig. 2(c)'s t)
/// before the library's stages ([`mhe_report::report`]), which can take minutes; returns it
/// with Fig. 2(c)'s t.
pub(super) fn read(job: &Job, settings: &Settings) -> Result<(Scenario, usize)> {
    let scenario = Scenario::from_file(&job.scenario)
        .with_context(|| format!("invalid scenario `{}`", job.scenario.display()))?;
    if scenario.mhe.is_none() {
        return Err(ClosedLoopError::MissingSection { section: "mhe" })
            .with_context(|| format!("scenario `{}`", job.scenario.display()));
    }
    if scenario.mpc.is_none() {
        return Err(ClosedLoopError::MissingSection { section: "mpc" })
            .with_context(|| format!("scenario `{}`", job.scenario.display()));
    }
    let steps = scenario.simulation.steps;
    let fig2c_t = settings
        .fig2c_t
        .unwrap_or_else(|| default_fig2c_t(job.preset, &scenario));
    if fig2c_t >= steps {
        return Err(ReproduceError::Fig2cTime { t: fig2c_t, steps })
            .with_context(|| format!("scenario `{}`", job.scenario.display()));
    }
    Ok((scenario, fig2c_t))
}

/// The library's error with the context the command names the scenario file in (the inner
/// error kept as the chain's typed cause).
pub(super) fn with_scenario(e: ReportError, job: &Job) -> anyhow::Error {
    let path = job.scenario.display();
    match e {
        ReportError::Scenario(inner) => {
            anyhow::Error::new(inner).context(format!("scenario `{path}`"))
        }
        e @ ReportError::WorkLimit { .. } => {
            anyhow::Error::new(e).context(format!("scenario `{path}`"))
        }
        ReportError::Resolve(inner) => anyhow::Error::new(inner).context(format!(
            "cannot set up the scenario `{path}` for the certificate"
        )),
        ReportError::Certificate(inner) => {
            anyhow::Error::new(inner).context(format!("cannot compute the certificate of `{path}`"))
        }
        ReportError::ClosedLoop(inner) => anyhow::Error::new(inner),
        e => anyhow::Error::new(e),
    }
}

/// Writes trace.json, trace.csv and the figures into `set`; returns their paths and the
/// figure notes.
pub(super) fn write_traces(
    job: &Job,
    settings: &Settings,
    p: &Report,
    fig2c_t: usize,
    runs: &[Run],
    record: &ScenarioRecord,
    provenance: &Provenance,
    set: &mut OutputSet,
) -> Result<(Vec<PathBuf>, Vec<String>)> {
    let mut files = Vec::new();
    let mut figure_notes = Vec::new();
    if runs.is_empty() {
        return Ok((files, figure_notes));
    }
    let provenance = certificate_json::v1::Provenance::from(provenance);
    let header = certificate_json::v1::TraceHeader {
        preset: job.preset.as_ref().map(certificate_json::v1::Preset::from),
        label: &job.label,
        scenario: record,
        provenance: &provenance,
    };
    let doc = certificate_json::v1::TraceDocument::new(header, &p.resolved, runs)?;
    files.push(
        set.add(
            "trace.json",
            serde_json::to_string(&doc)
                .context("cannot serialise the trace")?
                .as_bytes(),
        )?,
    );
    files.push(set.add(
        "trace.csv",
        trace_csv::trace_csv(runs, &p.scenario.sets.disturbance).as_bytes(),
    )?);
    if !settings.figures {
        return Ok((files, figure_notes));
    }
    // A figure without drawable data (e.g. ε_t ≡ 0 on a log axis) is a note, not fatal:
    // the JSON files hold the numbers.
    let drawn = mhe_report::figures::render(&p.scenario, runs, fig2c_t);
    figure_notes.extend(drawn.notes);
    for (name, svg) in drawn.files {
        files.push(set.add(&name, svg.as_bytes())?);
    }
    Ok((files, figure_notes))
}

/// certificate.json's document from the report.
pub(super) fn document(
    job: &Job,
    settings: &Settings,
    report: Report,
    fig2c_t: usize,
    record: ScenarioRecord,
    provenance: Provenance,
    files: &[PathBuf],
    figure_notes: Vec<String>,
) -> CertificateDocument {
    let (solver, scenario) = (report.solver, &report.scenario);
    let solvers = report.solver_summaries();
    let (certified, matches) = (report.certified(), report.iterations_match_k_min());
    // Each method at its cheapest certified step: the one verdict's smallest K (K_min, K_glob
    // or K_chain), the K the summary's verdict line names.
    let budget = mhe_export::budget::reproduce(
        scenario,
        &(solvers.iter())
            .map(|s| {
                let k = report.smallest_certified_k(s.solver);
                (s.solver.name().to_string(), k)
            })
            .collect::<Vec<_>>(),
    );
    CertificateDocument {
        format: CERTIFICATE_FORMAT.into(),
        format_version: FORMAT_VERSION,
        preset: job.preset,
        label: job.label.clone(),
        scenario: record,
        provenance,
        host: host_info(),
        settings: SettingsRecord {
            sampling_seed: scenario.noise.seed,
            lipschitz_pairs: settings.lipschitz_pairs,
            gamma13_sequences: settings.gamma13_sequences,
            enumeration_max_vars: settings.enumeration_max_vars,
            k_max: settings.k_max,
            small_k: settings.small_k,
            fig2c_t,
            sim_k_cap: settings.sim_k_cap,
        },
        solver: solver.name().into(),
        scenario_iterations: report.iterations,
        certified,
        certificate_applies: report.applicable.kind(),
        not_covered: report.not_covered,
        at_scenario: report.at_scenario,
        scenario_iterations_match_k_min: matches,
        solvers,
        budget,
        // The paper's published constants belong to its case study: shown for the two presets
        // only, never beside a user's plant.
        paper_comparison: if job.preset.is_some() {
            report.paper_comparison
        } else {
            Vec::new()
        },
        runs: report.runs.iter().map(|r| r.summary.clone()).collect(),
        skipped_runs: report.skipped_runs,
        trajectory_check: report.trajectory_check,
        joint: report.joint,
        linear: report.linear,
        regional: report.regional,
        asymptotic_gains: report.gains,
        files: files
            .iter()
            .map(|f| f.strip_prefix(&job.out).unwrap_or(f).display().to_string())
            .collect(),
        figure_notes,
        certificate: report.certificate,
    }
}
