//! `cargo xtask reproduce`: the case study of Section IV of Yang–Manzie–Pu on the stand-in
//! plant, end to end, for one scenario (a preset or a user's file):
//!
//! 1. the closed-loop certificate of Theorem 1 for every solver
//!    ([`iss_certificate::certificate::certify_closed_loop`]): premises with margins, K_min or
//!    the reasons it is void;
//! 2. Alg. 1 simulated with the scenario's solver, the exact MPC and the exact MHE solve on
//!    (for ε_t), at the computed K_min when the certificate holds, at the scenario's K, and
//!    at a small K for comparison when it is void;
//! 3. the trajectory inequalities of Props. 1 and 3 on the K_min run, with the certified
//!    L_Φ and with the sampled L_Φ;
//! 4. `certificate.json`, `trace.json`, `trace.csv` and the SVG figures (Fig. 2 analogues,
//!    every state with its estimate, inputs and outputs with their bounds, norms);
//! 5. a summary that fits a screen ([`screen`]: one table and the verdict), and with `-v`
//!    the long summary with the constants next to the paper's published values; both and the
//!    work log in `summary.md`.
//!
//! Before each simulation it says what it simulates and how much work that is
//! ([`work::Work`]); a simulation beyond the work limit is refused (the scenario's K) or
//! skipped with the reason (the computed K_min), never run silently for hours.
//!
//! Output layout and JSON schemas: docs/reproduce-output.md.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use closed_loop::ClosedLoopError;
use closed_loop::scenario::Scenario;
use iss_certificate::analysis::Premise;
use iss_certificate::certificate::{
    CertificateOptions, ClosedLoopCertificate, Gamma13Source, TrajectoryCheck,
};
use iss_certificate::plan::{KSource, RunOutcome};
use lti_model::BoxSet;
use serde::Serialize;

use crate::output::OutputSet;
use crate::provenance::{Provenance, workspace_root};

mod document;
mod gains;
mod job;
mod joint;
mod json_v1;
pub(crate) mod numfmt;
mod regional;
mod screen;
mod stages;
mod summary;
mod trace_csv;
mod work;

pub use document::*;
pub use job::*;
use mhe_report::Run;
use mhe_report::linear::LinearEntry;
pub use mhe_report::{
    ComparisonRow, KalmanSummary, RunSummary, SkippedRun, TrajectoryReport,
    paper_comparison as comparison,
};
use summary::summarize;

/// `format` of certificate.json (its schema is `certificate_json::v1`).
pub const CERTIFICATE_FORMAT: &str = certificate_json::v1::CERTIFICATE_FORMAT;
/// `format_version` of both files; bumped on any incompatible change.
pub const FORMAT_VERSION: u32 = certificate_json::v1::CERTIFICATE_FORMAT_VERSION;
/// Time step of the ŵ² panel of the presets (the paper's Fig. 2(c) shows t = 6).
pub const FIG2C_T: usize = 6;

/// Errors of `reproduce` beyond those of the scenario (which name their key) and of the
/// library ([`mhe_report::ReportError`]: the work limit, the certificate).
#[derive(Debug, Clone, PartialEq)]
pub enum ReproduceError {
    /// `--fig2c-t` outside the simulated steps.
    Fig2cTime {
        /// The t asked for.
        t: usize,
        /// T of the scenario.
        steps: usize,
    },
}

impl std::fmt::Display for ReproduceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Fig2cTime { t, steps } => write!(
                f,
                "--fig2c-t {t}: Fig. 2(c) needs a simulated step, t ∈ 0..={} \
                 (simulation.steps = {steps})",
                steps.saturating_sub(1)
            ),
        }
    }
}

impl std::error::Error for ReproduceError {}

/// The estimated work of each analysis phase, on stderr before the certificate is computed
/// (iss_certificate::budget; docs/limits.md). A closed stderr is ignored.
fn budget_lines(
    scenario: &Scenario,
    mpc: Option<&mpc_core::CondensedMpc>,
    opts: &CertificateOptions,
) {
    use std::io::Write;
    let phases = iss_certificate::budget::estimate_phases(scenario, mpc, opts, 2000);
    let mut err = std::io::stderr().lock();
    let _ = writeln!(
        err,
        "  analysis estimates (seconds of one core; an optional phase beyond {} s is skipped, \
         scenario key `certificate.phase_seconds`):",
        iss_certificate::budget::secs(opts.phase_seconds)
    );
    for p in phases {
        let _ = writeln!(
            err,
            "    {:<30} ≈ {:>8} s ({} multiply-adds)  {}{}",
            p.phase,
            iss_certificate::budget::secs(p.seconds),
            iss_certificate::budget::sci(p.work),
            if p.runs { "" } else { "[skipped] " },
            p.detail
        );
    }
}

fn relative(path: &Path) -> String {
    path.strip_prefix(workspace_root())
        .unwrap_or(path)
        .display()
        .to_string()
}

/// Runs one job: read the scenario, the library's report ([`mhe_report::report`]:
/// certificate, simulations, trajectory check), then the files and summaries.
///
/// Errors: unreadable or invalid scenario (the error is a [`lti_model::ModelError`] naming
/// the key), a scenario without `[mhe]`/`[mpc]` (a [`ClosedLoopError`]), I/O. A void
/// certificate is not an error.
pub fn run_job(job: &Job, settings: &Settings) -> Result<Outcome> {
    let (scenario, fig2c_t) = stages::read(job, settings)?;
    let console = work::Console::new(settings);
    let report = mhe_report::report(scenario, &settings.options(&job.label), &console)
        .map_err(|e| stages::with_scenario(e, job))?;
    let log = stages::Log::continued(settings, report.log.clone());
    render(job, settings, report, fig2c_t, log)
}

/// Writes every file (staged, renamed into place only when all are written:
/// crate::output, so a failed rerun leaves the previous complete output) and the summaries.
fn render(
    job: &Job,
    settings: &Settings,
    report: mhe_report::Report,
    fig2c_t: usize,
    mut log: stages::Log,
) -> Result<Outcome> {
    let runs = &report.runs;
    log.say(if runs.is_empty() {
        format!(
            "[{}] nothing was simulated; writing certificate.json to {} …",
            job.label,
            job.out.display()
        )
    } else if settings.figures {
        format!(
            "[{}] writing trace.json, trace.csv and the figures to {} …",
            job.label,
            job.out.display()
        )
    } else {
        format!(
            "[{}] writing trace.json and trace.csv to {} …",
            job.label,
            job.out.display()
        )
    });
    let t0 = std::time::Instant::now();
    let mut set = OutputSet::new(&job.out)?;
    let provenance = Provenance::collect();
    let record = ScenarioRecord {
        name: report.scenario.name.clone(),
        description: report.scenario.description.clone(),
        path: relative(&job.scenario),
        text: report.scenario.source.clone(),
    };
    let (mut files, figure_notes) = stages::write_traces(
        job,
        settings,
        &report,
        fig2c_t,
        runs,
        &record,
        &provenance,
        &mut set,
    )?;
    log.say(format!(
        "  done in {} s",
        numfmt::num(t0.elapsed().as_secs_f64())
    ));
    let cert_path = job.out.join("certificate.json");
    files.push(cert_path.clone());
    let document = stages::document(
        job,
        settings,
        report,
        fig2c_t,
        record,
        provenance,
        &files,
        figure_notes,
    );
    let previous = previous_files(&cert_path);
    set.add(
        "certificate.json",
        (serde_json::to_string_pretty(&certificate_json::v1::Certificate::from(&document))
            .context("cannot serialise the certificate")?
            + "\n")
            .as_bytes(),
    )?;
    let summary = summarize(&document, &files, &document.figure_notes);
    // summary.md: the long summary and the work log, so nothing the terminal leaves out
    // without -v is lost. Not in certificate.json's `files` (it is rendered from that file).
    let markdown = format!(
        "# reproduce `{}`\n\n```text\n{}\n\n{}```\n\n## Work log\n\n```text\n{}\n```\n",
        job.label,
        screen::screen(&document, &job.out),
        summary,
        log.lines.join("\n")
    );
    set.add(SUMMARY_FILE, markdown.as_bytes())?;
    set.commit_replacing(&previous)?;
    let screen = screen::screen(&document, &job.out);
    Ok(Outcome {
        document,
        summary,
        screen,
        log: log.lines,
    })
}

/// The text summary in the output directory (the screen table, the long summary, the work
/// log), written with every job.
pub const SUMMARY_FILE: &str = "summary.md";

/// What the command prints on stdout for one finished job: the screen summary with the
/// job's wall time (after the long summary with `verbose`), and a blank line.
fn printed(outcome: &Outcome, secs: f64, verbose: bool) -> String {
    let long = if verbose {
        format!("\n{}\n", outcome.summary)
    } else {
        String::new()
    };
    format!("{long}{} ({secs:.1} s)\n", outcome.screen)
}

/// Exit code when a simulation contradicts the certificate: an inequality of Props. 1–3
/// fails beyond the rounding floor with the certificate's constants. Nothing else.
pub const EXIT_CONTRADICTED: u8 = 3;
/// Exit code when a simulated run diverged (the bounded rule of [`closed_loop::bounded`])
/// or stopped early, and no inequality was violated; the verdict's first sentence says
/// where and when.
pub const EXIT_DIVERGED: u8 = 4;

/// `cargo xtask reproduce`: runs the jobs, prints each screen summary (with `verbose`, the
/// work lines and the long summary before it). Exit code 0,
/// [`EXIT_CONTRADICTED`] when a certified trajectory check fails, [`EXIT_DIVERGED`] when a
/// run diverged or stopped otherwise; errors (1) for bad input.
pub fn main(
    preset: Option<Preset>,
    scenario: Option<PathBuf>,
    out: Option<PathBuf>,
    gamma13: Option<f64>,
    fig2c_t: Option<usize>,
    sim_k_cap: Option<usize>,
    verbose: bool,
) -> Result<std::process::ExitCode> {
    if sim_k_cap == Some(0) {
        anyhow::bail!("--sim-k-cap 0: the cap must be ≥ 1 (K = 0 iterations is no estimator)");
    }
    let mut settings = Settings {
        fig2c_t,
        live: true,
        verbose,
        sim_k_cap,
        ..Settings::default()
    };
    if let Some(g) = gamma13 {
        if !(g.is_finite() && g > 0.0) {
            anyhow::bail!("--gamma13 {g}: γ₁,₃ must be a finite number > 0");
        }
        // The scenario's limits for `certificate.gamma13` (docs/limits.md).
        if let Err(lti_model::ModelError::Scenario { problem, .. }) =
            lti_model::spec::format::check_scale("--gamma13", g)
        {
            anyhow::bail!("--gamma13 {problem}");
        }
        settings.gamma13 = Gamma13Source::User(g);
    }
    let jobs = jobs(preset, scenario, out);
    // The output directories are checked before any work (the certificate can take minutes).
    for job in &jobs {
        crate::output::check_out_dir(&job.out, "--out")?;
    }
    let mut contradicted = false;
    let mut diverged = false;
    for job in jobs {
        let t0 = std::time::Instant::now();
        if !verbose {
            // One line of progress per job (cargo's "Compiling …"); -v prints each phase.
            errln!("[{}] certifying, simulating and checking …", job.label);
        }
        let outcome = run_job(&job, &settings)?;
        outln!("{}", printed(&outcome, t0.elapsed().as_secs_f64(), verbose));
        contradicted |= outcome.contradicted();
        diverged |= outcome.diverged();
    }
    Ok(if contradicted {
        errln!(
            "error: a simulation at the certified K violates Prop. 1 or 3 with the certificate's constants"
        );
        std::process::ExitCode::from(EXIT_CONTRADICTED)
    } else if diverged {
        errln!(
            "a simulated run diverged or stopped (bounded rule: ‖e‖, ‖x‖, ε within \
             1000·(1 + initial scale + max_{{s ≤ t}} ‖w_s‖); see the verdict and \
             `runs[].diverged_at` in certificate.json)"
        );
        std::process::ExitCode::from(EXIT_DIVERGED)
    } else {
        std::process::ExitCode::SUCCESS
    })
}

#[cfg(test)]
mod screen_tests;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod truth_tests;
