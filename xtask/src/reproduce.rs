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
//! 5. a text summary with the constants next to the paper's published values.
//!
//! Before each simulation it says what it simulates and how much work that is
//! ([`work::Work`]); a simulation beyond the work limit is refused (the scenario's K) or
//! skipped with the reason (the computed K_min), never run silently for hours.
//!
//! Output layout and JSON schemas: docs/reproduce-output.md.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario, Scenario};
use closed_loop::{ClosedLoopError, Trace};
use iss_certificate::analysis::Premise;
use iss_certificate::certificate::{
    CertificateOptions, ClosedLoopCertificate, Gamma13Source, SolverCertificate, TrajectoryCheck,
    analysis_with_sampled_l_phi, certify_closed_loop_timed, check_trajectory,
};
use iss_certificate::coverage::{Applicable, verdict_options};
use iss_certificate::plan::{KSource, RunOutcome, plan_runs};
use lti_model::BoxSet;
use lti_model::matrix::to_rows;
use qp_iter::Method;
use serde::Serialize;

use crate::figures::{self, Chart, HLine, Legend, Pattern, Series};
use crate::output::OutputSet;
use crate::provenance::{Provenance, workspace_root};

mod charts;
mod comparison;
mod document;
mod gains;
mod job;
mod joint;
mod linear;
pub(crate) mod numfmt;
mod regional;
mod runs;
mod summary;
mod trace_csv;
mod work;

use charts::charts;
use comparison::{comparison, fmt_opt, short_reason};
pub use document::*;
pub use job::*;
use linear::{LinearEntry, linear_entries};
use runs::{Run, simulate};
use summary::summarize;
pub use work::Work;

/// `format` of certificate.json.
pub const CERTIFICATE_FORMAT: &str = "suboptimal-mhe/closed-loop-certificate";
/// `format` of trace.json.
pub const TRACE_FORMAT: &str = "suboptimal-mhe/closed-loop-trace";
/// `format_version` of both files; bumped on any incompatible change.
pub const FORMAT_VERSION: u32 = 1;
/// Time step of the ŵ² panel of the presets (the paper's Fig. 2(c) shows t = 6).
pub const FIG2C_T: usize = 6;

/// Errors of `reproduce` beyond those of the scenario (which name their key).
#[derive(Debug, Clone, PartialEq)]
pub enum ReproduceError {
    /// `--fig2c-t` outside the simulated steps.
    Fig2cTime {
        /// The t asked for.
        t: usize,
        /// T of the scenario.
        steps: usize,
    },
    /// The scenario's K and T ask for more work than one simulation may do.
    WorkLimit {
        /// The refused simulation.
        work: Work,
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
            Self::WorkLimit { work } => write!(
                f,
                "mhe.iterations = {} with simulation.steps = {}: {} (docs/limits.md); lower \
                 mhe.iterations or simulation.steps",
                work.k,
                work.steps,
                work.excess()
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

/// The cost (9) as the MHE minimises it (docs/reproduce-output.md repeats it).
pub const MHE_COST: &str = "V = 2·η^{M_t}·‖x̂_{t−M_t} − prior‖²_P + Σ_{i=1}^{M_t} η^{i−1}·(2‖ŵ_{t−i}‖²_Q + \
     ‖C x̂_{t−i} + F ŵ²_{t−i} − y_{t−i}‖²_R), x̂_{j+1} = A x̂_j + B u_j + E ŵ¹_j, ŵ_j ∈ 𝒲, \
     M_t = min(M, t); variables z = (x̂_{t−M_t}, ŵ_{t−M_t}, …, ŵ_{t−1})";

fn relative(path: &Path) -> String {
    path.strip_prefix(workspace_root())
        .unwrap_or(path)
        .display()
        .to_string()
}

/// Runs one job: certificate, simulations, trajectory check, files, summary.
///
/// Errors: unreadable or invalid scenario (the error is a [`lti_model::ModelError`] naming
/// the key), a scenario without `[mhe]`/`[mpc]` (a [`ClosedLoopError`]), I/O. A void
/// certificate is not an error.
pub fn run_job(job: &Job, settings: &Settings) -> Result<Outcome> {
    let scenario = Scenario::from_file(&job.scenario)
        .with_context(|| format!("invalid scenario `{}`", job.scenario.display()))?;
    let spec = scenario
        .mhe
        .as_ref()
        .ok_or(ClosedLoopError::MissingSection { section: "mhe" })
        .with_context(|| format!("scenario `{}`", job.scenario.display()))?;
    if scenario.mpc.is_none() {
        return Err(ClosedLoopError::MissingSection { section: "mpc" })
            .with_context(|| format!("scenario `{}`", job.scenario.display()));
    }
    let solver: Method = spec.method;
    let seed = scenario.noise.seed;
    // Checked before the certificate (which can take minutes): the t of Fig. 2(c), and the
    // work of the scenario's own K (always simulated).
    let steps = scenario.simulation.steps;
    let fig2c_t = settings
        .fig2c_t
        .unwrap_or_else(|| default_fig2c_t(job.preset, &scenario));
    if fig2c_t >= steps {
        return Err(ReproduceError::Fig2cTime { t: fig2c_t, steps })
            .with_context(|| format!("scenario `{}`", job.scenario.display()));
    }
    if let Some(work) = Work::of(&scenario, spec.iterations).filter(|w| !w.within_limit()) {
        return Err(ReproduceError::WorkLimit { work })
            .with_context(|| format!("scenario `{}`", job.scenario.display()));
    }
    let mut log = Vec::new();
    let mut say = |line: String| {
        if settings.live {
            outln!("{line}");
        }
        log.push(line);
    };
    // γ₁,₃: the command line's value, else the scenario's `certificate.gamma13`, else computed.
    let cli_gamma13 = match settings.gamma13 {
        Gamma13Source::User(g) => Some(g),
        Gamma13Source::Certified => None,
    };
    // The four named methods, plain and Jacobi-scaled (long horizons: the scaled maps keep
    // K_min near its short-horizon value), and the scenario's own method when it is another
    // one (custom parameters): it is the one simulated at its K_min.
    let mut solvers = CertificateOptions::default().solvers;
    if !solvers.contains(&solver) {
        solvers.push(solver);
    }
    // The options that decide the verdict are every command's (`verdict_options`: a user
    // γ₁,₃ is tested by the same sample as in `export` and the sweep); the sampled
    // estimates beside the certified values are reproduce's own.
    let verdict = verdict_options(&scenario, solvers, cli_gamma13);
    let opts = CertificateOptions {
        lipschitz_pairs: settings.lipschitz_pairs,
        gamma13_sequences: if verdict.gamma13 == Gamma13Source::Certified {
            settings.gamma13_sequences
        } else {
            verdict.gamma13_sequences
        },
        enumeration_max_vars: settings.enumeration_max_vars,
        k_max: settings.k_max,
        ..verdict
    };
    let resolved = scenario.clone().resolve().with_context(|| {
        format!(
            "cannot set up the scenario `{}` for the certificate",
            job.scenario.display()
        )
    })?;
    say(format!(
        "[{}] computing the certificate of Theorem 1 for {} …",
        job.label,
        opts.solvers
            .iter()
            .map(|m| m.name())
            .collect::<Vec<_>>()
            .join(", ")
    ));
    if settings.live {
        budget_lines(&scenario, resolved.mpc().ok(), &opts);
    }
    let t0 = std::time::Instant::now();
    let (cert, times) = certify_closed_loop_timed(&resolved, &opts).with_context(|| {
        format!(
            "cannot compute the certificate of `{}`",
            job.scenario.display()
        )
    })?;
    say(format!(
        "  done in {} s (MHE constants {} s, L_Φ sampling {} s, L_π {} s, γ₁,₃ {} s, \
         Theorem 1 {} s; wall time)",
        numfmt::num(t0.elapsed().as_secs_f64()),
        numfmt::num(times.mhe_constants_s),
        numfmt::num(times.l_phi_sampling_s),
        numfmt::num(times.l_pi_s),
        numfmt::num(times.gamma13_s),
        numfmt::num(times.theorem1_s),
    ));
    let own = cert.solver(solver);
    say(format!(
        "[{}] computing the linear stability boundary ρ_lin(K) of each method …",
        job.label
    ));
    let t0 = std::time::Instant::now();
    let linear = linear_entries(&resolved, &cert, solver, opts.phase_seconds, settings.live);
    say(format!(
        "  done in {} s; searching K_reg, the regional certificate's smallest K, of each method \
         (estimated work within `certificate.phase_seconds` = {} s, split over the {} methods) …",
        numfmt::num(t0.elapsed().as_secs_f64()),
        numfmt::num(opts.phase_seconds),
        cert.solvers.len()
    ));
    let t0 = std::time::Instant::now();
    let regional = regional::regional_entries(&resolved, &cert, &linear);
    say(format!(
        "  done in {} s",
        numfmt::num(t0.elapsed().as_secs_f64())
    ));

    // The K-iteration MPC (`mpc.iterations`): the joint certificate decides the runs.
    let joint_cert = joint::joint_certificate(&resolved, &cert, solver)?;
    let own_controller = LoopOptions::from_scenario(&scenario)?.controller;
    // The certificate covering the scenario's configuration (iss_certificate::coverage): the
    // same decision as the sweeps' `certified` column.
    let applicable = Applicable::new(&resolved, &cert, solver, own_controller);
    let not_covered = match &applicable {
        Applicable::Uncovered(reason) => Some(reason.clone()),
        _ => None,
    };
    let at_scenario = applicable.at(
        spec.iterations,
        match own_controller {
            ControllerChoice::SuboptimalMpc { iterations, .. } => Some(iterations),
            _ => None,
        },
    );
    if let Some(r) = &not_covered {
        say(format!("[{}] NOT CERTIFIED: {r}", job.label));
    }
    let plan: Vec<(usize, ControllerChoice, KSource)> = match &joint_cert {
        Some(j) => {
            say(format!(
                "[{}] joint MPC + MHE certificate: cheapest certified pair (K_e, K_c) = {}",
                job.label,
                j.region
                    .cheapest
                    .map_or_else(|| "none".to_string(), |p| format!("({}, {})", p.k_e, p.k_c))
            ));
            let mut plan = Vec::new();
            if let Some(p) = j.region.cheapest {
                let at_pair = ControllerChoice::SuboptimalMpc {
                    iterations: p.k_c,
                    method: j.mpc_method,
                };
                plan.push((p.k_e, at_pair, KSource::ComputedKMin));
            }
            if !plan
                .iter()
                .any(|(k, c, _)| *k == spec.iterations && *c == own_controller)
            {
                plan.push((spec.iterations, own_controller, KSource::Scenario));
            }
            plan
        }
        None => plan_runs(spec.iterations, own.and_then(|s| s.k_min), settings.small_k)
            .into_iter()
            .map(|(k, source)| (k, ControllerChoice::ExactMpc, source))
            .collect(),
    };

    // Simulations (skipped when LMI (2) is infeasible: the MHE needs a P), each announced
    // with its work; one beyond the limit (only a computed K_min can be: the scenario's K
    // was checked above) is skipped with the reason.
    let mut runs: Vec<Run> = Vec::new();
    let mut skipped_runs = Vec::new();
    if cert.ioss.is_some() || spec.p.is_some() {
        for (k, controller, source) in plan {
            // A K_min above --sim-k-cap, or any run beyond the work limit, is skipped.
            let work = Work::of(&scenario, k);
            let skip = match (settings.sim_k_cap, &work) {
                (Some(cap), _) if k > cap && source == KSource::ComputedKMin => Some(format!(
                    "K_min = {k} is above --sim-k-cap {cap}; raise the cap (or drop the flag) to simulate it"
                )),
                (_, Some(w)) if !w.within_limit() => Some(format!(
                    "{}; lower simulation.steps to simulate it",
                    w.excess()
                )),
                _ => None,
            };
            if let Some(reason) = skip {
                say(format!(
                    "not simulating {} at K = {k}: {reason}",
                    solver.name()
                ));
                skipped_runs.push(SkippedRun {
                    k,
                    k_source: source,
                    reason,
                });
                continue;
            }
            if let Some(w) = &work {
                say(w.line(solver, source));
            }
            let t0 = std::time::Instant::now();
            let run = simulate(&resolved, solver, k, controller, source, settings.live)?;
            let secs = t0.elapsed().as_secs_f64();
            say(format!(
                "  done in {} s ({} iterations/s)",
                numfmt::num(secs),
                numfmt::num(k as f64 * run.trace.len() as f64 / secs.max(1e-9))
            ));
            runs.push(run);
        }
    }

    // Props. 1 and 3 on the K_min run.
    let kmin_run = runs
        .iter()
        .find(|r| r.summary.k_source == KSource::ComputedKMin);
    let joint_report = match &joint_cert {
        Some(j) => Some(joint::check(
            &resolved,
            &cert,
            j,
            kmin_run.map(|r| &r.trace),
            spec_k_c(&scenario),
        )?),
        None => None,
    };
    let trajectory_check = match (own, kmin_run) {
        _ if joint_report.is_some() => TrajectoryReport {
            ran: false,
            reason: Some(
                "the controller is the K-iteration MPC: Props. 1 and 3 assume the exact MPC; \
                 the joint check (joint.trajectory) evaluates them with the δ terms"
                    .into(),
            ),
            solver: solver.name().into(),
            k: kmin_run.map(|r| r.summary.k),
            seed,
            steps: kmin_run.map_or(0, |r| r.trace.len()),
            certified_l_phi: None,
            sampled_l_phi: None,
            passed: joint_report
                .as_ref()
                .and_then(|j| j.trajectory.as_ref())
                // Exit code 3 only for a violated inequality; a divergence or a stopped run
                // is its own verdict (exit code 4, `Outcome::diverged`).
                .map(|t| t.inequalities_hold()),
        },
        (Some(sc), Some(run)) => {
            let k = run.summary.k;
            let certified = check_trajectory(&cert, &sc.analysis, k, &run.trace);
            let sampled = check_trajectory(
                &cert,
                &analysis_with_sampled_l_phi(&cert, sc),
                k,
                &run.trace,
            );
            // Exit code 3 only for a violated inequality (issue 37 item 3): a divergence or
            // a stopped run is its own verdict (exit code 4, `Outcome::diverged`).
            let passed = certified.as_ref().map(TrajectoryCheck::inequalities_hold);
            TrajectoryReport {
                ran: certified.is_some(),
                reason: certified
                    .is_none()
                    .then(|| "ε_t was not recorded (exact MHE solve off)".to_string()),
                solver: solver.name().into(),
                k: Some(k),
                seed: run.summary.seed,
                steps: run.trace.len(),
                certified_l_phi: certified,
                sampled_l_phi: sampled,
                passed,
            }
        }
        _ => TrajectoryReport {
            ran: false,
            reason: Some(match own {
                Some(sc) if sc.k_min.is_some() => format!(
                    "the simulation at K_min = {} was not run: {}",
                    sc.k_min.unwrap_or(0),
                    skipped_runs
                        .iter()
                        .find(|r| r.k_source == KSource::ComputedKMin)
                        .map_or("no simulation (LMI (2) gave no P)", |r| r.reason.as_str())
                ),
                Some(sc) => match &sc.not_computed {
                    Some(nc) => format!(
                        "the certificate of {} is {nc}: there is no certified K to check",
                        solver.name()
                    ),
                    None => format!(
                        "the certificate of {} is void ({}): there is no certified K to check",
                        solver.name(),
                        short_reason(sc)
                    ),
                },
                None => "the scenario's solver was not certified".into(),
            }),
            solver: solver.name().into(),
            k: None,
            seed,
            steps: 0,
            certified_l_phi: None,
            sampled_l_phi: None,
            passed: None,
        },
    };

    // A configuration no certificate covers has nothing to contradict.
    let mut trajectory_check = trajectory_check;
    if let Some(r) = &not_covered {
        trajectory_check.passed = None;
        trajectory_check.reason = Some(format!(
            "not certified: {r} (the inequalities are evaluated for reference only)"
        ));
    }

    say(if runs.is_empty() {
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
    // Every file is staged and renamed into place only when all are written
    // (crate::output): a failed rerun leaves the previous complete output.
    let mut set = OutputSet::new(&job.out)?;
    let provenance = Provenance::collect();
    let scenario_record = ScenarioRecord {
        name: scenario.name.clone(),
        description: scenario.description.clone(),
        path: relative(&job.scenario),
        text: scenario.source.clone(),
    };
    let mut files: Vec<PathBuf> = Vec::new();

    // trace.json
    if !runs.is_empty() {
        let doc = trace_document(job, &resolved, &scenario_record, &provenance, &runs)?;
        let path = set.add(
            "trace.json",
            serde_json::to_string(&doc)
                .context("cannot serialise the trace")?
                .as_bytes(),
        )?;
        files.push(path);
        let path = set.add(
            "trace.csv",
            trace_csv::trace_csv(&runs, &scenario.sets.disturbance).as_bytes(),
        )?;
        files.push(path);
    }
    // Figures.
    let mut figure_notes = Vec::new();
    if settings.figures && !runs.is_empty() {
        let (figs, notes) = charts(&scenario, &runs, fig2c_t);
        figure_notes.extend(notes);
        for (name, fig) in figs {
            // A figure without drawable data (e.g. ε_t ≡ 0 on a log axis) is reported,
            // not fatal: the JSON files hold the numbers.
            let rendered = match fig.render() {
                Ok(r) => r,
                Err(e) => {
                    figure_notes.push(format!("{name} not written: {e}"));
                    continue;
                }
            };
            let path = set.add(&name, rendered.svg.as_bytes())?;
            if rendered.dropped > 0 {
                figure_notes.push(format!(
                    "{name}: {} point(s) ≤ 0 or non-finite not drawn",
                    rendered.dropped
                ));
            }
            files.push(path);
        }
    }
    say(format!(
        "  done in {} s",
        numfmt::num(t0.elapsed().as_secs_f64())
    ));
    let cert_path = job.out.join("certificate.json");
    files.push(cert_path.clone());

    let asymptotic_gains = gains::report(&cert, &regional, &runs, solver, not_covered.as_deref());
    let document = CertificateDocument {
        format: CERTIFICATE_FORMAT.into(),
        format_version: FORMAT_VERSION,
        preset: job.preset,
        label: job.label.clone(),
        scenario: scenario_record,
        provenance,
        host: HostInfo::collect(),
        settings: SettingsRecord {
            sampling_seed: seed,
            lipschitz_pairs: settings.lipschitz_pairs,
            gamma13_sequences: settings.gamma13_sequences,
            enumeration_max_vars: settings.enumeration_max_vars,
            k_max: settings.k_max,
            small_k: settings.small_k,
            fig2c_t,
            sim_k_cap: settings.sim_k_cap,
        },
        solver: solver.name().into(),
        scenario_iterations: spec.iterations,
        certified: match &applicable {
            Applicable::Theorem1 { k_min, .. } => k_min.is_some(),
            Applicable::Joint { .. } => {
                applicable.void_reasons().is_empty()
                    && joint_cert
                        .as_ref()
                        .is_some_and(|j| j.region.cheapest.is_some())
            }
            Applicable::Uncovered(_) => false,
        },
        certificate_applies: applicable.kind(),
        not_covered,
        at_scenario,
        scenario_iterations_match_k_min: own.and_then(|s| s.k_min).map(|k| k == spec.iterations),
        solvers: cert
            .solvers
            .iter()
            .map(|s| SolverSummary::new(s, solver, &scenario, own_controller))
            .collect(),
        // The paper's published constants belong to its case study: shown for the two presets
        // only, never beside a user's plant.
        paper_comparison: if job.preset.is_some() {
            comparison(&cert, solver)
        } else {
            Vec::new()
        },
        runs: runs.iter().map(|r| r.summary.clone()).collect(),
        skipped_runs,
        trajectory_check,
        joint: joint_report,
        linear,
        regional,
        asymptotic_gains,
        files: files
            .iter()
            .map(|p| p.strip_prefix(&job.out).unwrap_or(p).display().to_string())
            .collect(),
        figure_notes: figure_notes.clone(),
        certificate: cert,
    };
    let previous = previous_files(&cert_path);
    set.add(
        "certificate.json",
        (serde_json::to_string_pretty(&document).context("cannot serialise the certificate")?
            + "\n")
            .as_bytes(),
    )?;
    set.commit_replacing(&previous)?;
    let summary = summarize(&document, &files, &figure_notes);
    Ok(Outcome {
        document,
        summary,
        log,
    })
}

/// K_c of the scenario's MPC (`mpc.iterations`, 0 for the exact MPC).
fn spec_k_c(scenario: &Scenario) -> usize {
    scenario
        .mpc
        .as_ref()
        .and_then(|m| m.iterations)
        .unwrap_or(0)
}

/// Exit code when a simulation contradicts the certificate: an inequality of Props. 1–3
/// fails beyond the rounding floor with the certificate's constants. Nothing else.
pub const EXIT_CONTRADICTED: u8 = 3;
/// Exit code when a simulated run diverged (the bounded rule of [`closed_loop::bounded`])
/// or stopped early, and no inequality was violated; the verdict's first sentence says
/// where and when.
pub const EXIT_DIVERGED: u8 = 4;

/// `cargo xtask reproduce`: runs the jobs, prints each summary. Exit code 0,
/// [`EXIT_CONTRADICTED`] when a certified trajectory check fails, [`EXIT_DIVERGED`] when a
/// run diverged or stopped otherwise; errors (1) for bad input.
pub fn main(
    preset: Option<Preset>,
    scenario: Option<PathBuf>,
    out: Option<PathBuf>,
    gamma13: Option<f64>,
    fig2c_t: Option<usize>,
    sim_k_cap: Option<usize>,
) -> Result<std::process::ExitCode> {
    if sim_k_cap == Some(0) {
        anyhow::bail!("--sim-k-cap 0: the cap must be ≥ 1 (K = 0 iterations is no estimator)");
    }
    let mut settings = Settings {
        fig2c_t,
        live: true,
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
        let outcome = run_job(&job, &settings)?;
        outln!();
        outln!("{}", outcome.summary);
        outln!(
            "({} done in {:.1} s)\n",
            job.label,
            t0.elapsed().as_secs_f64()
        );
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
mod tests;
#[cfg(test)]
mod truth_tests;
