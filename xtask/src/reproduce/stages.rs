//! The four stages of [`super::run_job`]: plan (read the scenario, certify, decide the runs),
//! simulate, check (Props. 1 and 3, or the joint check), render (files and summaries).
//! Each stage takes what the previous one produced; none re-reads or recomputes it.

use super::*;
use iss_certificate::coverage::{CertificateKind, PairVerdict};
use iss_certificate::joint::JointCertificate;
use joint::JointReport;

/// The work lines of a job: printed as they happen when the command is verbose and live
/// (`-v`), kept in [`Outcome::log`] and `summary.md` either way.
pub(super) struct Log {
    print: bool,
    pub(super) lines: Vec<String>,
}

impl Log {
    pub(super) fn new(settings: &Settings) -> Self {
        Self {
            print: settings.live && settings.verbose,
            lines: Vec::new(),
        }
    }

    pub(super) fn say(&mut self, line: String) {
        if self.print {
            outln!("{line}");
        }
        self.lines.push(line);
    }
}

/// The scenario, read and checked, with the options of its certificate.
pub(super) struct Prepared {
    pub(super) scenario: Scenario,
    pub(super) resolved: ResolvedScenario,
    /// `mhe.method`.
    pub(super) solver: Method,
    /// `mhe.iterations`.
    pub(super) iterations: usize,
    /// `mhe.p` was given (the MHE has a P even when LMI (2) fails).
    pub(super) has_p: bool,
    pub(super) fig2c_t: usize,
    pub(super) opts: CertificateOptions,
}

/// Reads and checks the scenario and everything that is cheap to refuse (Fig. 2(c)'s t, the
/// work of the scenario's own K) before the certificate, which can take minutes.
pub(super) fn prepare(job: &Job, settings: &Settings) -> Result<Prepared> {
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
    let (solver, iterations, has_p) = (spec.method(), spec.iterations().get(), spec.p().is_some());
    let steps = scenario.simulation.steps;
    let fig2c_t = settings
        .fig2c_t
        .unwrap_or_else(|| default_fig2c_t(job.preset, &scenario));
    if fig2c_t >= steps {
        return Err(ReproduceError::Fig2cTime { t: fig2c_t, steps })
            .with_context(|| format!("scenario `{}`", job.scenario.display()));
    }
    if let Some(work) = Work::of(&scenario, iterations).filter(|w| !w.within_limit()) {
        return Err(ReproduceError::WorkLimit { work })
            .with_context(|| format!("scenario `{}`", job.scenario.display()));
    }
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
    Ok(Prepared {
        scenario,
        resolved,
        solver,
        iterations,
        has_p,
        fig2c_t,
        opts,
    })
}

/// The certificates of the scenario and the runs they decide.
pub(super) struct Plan {
    pub(super) cert: ClosedLoopCertificate,
    pub(super) linear: Vec<LinearEntry>,
    pub(super) regional: Vec<regional::RegionalEntry>,
    pub(super) joint_cert: Option<JointCertificate>,
    pub(super) own_controller: ControllerChoice,
    pub(super) applicable: Applicable,
    pub(super) not_covered: Option<String>,
    pub(super) at_scenario: PairVerdict,
    /// (K, controller, why) of each simulation, in order.
    pub(super) runs: Vec<(usize, ControllerChoice, KSource)>,
}

/// Theorem 1's certificate, K_lin, K_reg, the joint certificate when the MPC is the
/// K-iteration one, the certificate covering the scenario, and the runs they decide.
pub(super) fn plan(job: &Job, settings: &Settings, p: &Prepared, log: &mut Log) -> Result<Plan> {
    let opts = &p.opts;
    log.say(format!(
        "[{}] computing the certificate of Theorem 1 for {} …",
        job.label,
        opts.solvers
            .iter()
            .map(|m| m.name())
            .collect::<Vec<_>>()
            .join(", ")
    ));
    if settings.live && settings.verbose {
        budget_lines(&p.scenario, p.resolved.mpc().ok(), opts);
    }
    let t0 = std::time::Instant::now();
    let (cert, times) = certify_closed_loop_timed(&p.resolved, opts).with_context(|| {
        format!(
            "cannot compute the certificate of `{}`",
            job.scenario.display()
        )
    })?;
    log.say(format!(
        "  done in {} s (MHE constants {} s, L_Φ sampling {} s, L_π {} s, γ₁,₃ {} s, \
         Theorem 1 {} s; wall time)",
        numfmt::num(t0.elapsed().as_secs_f64()),
        numfmt::num(times.mhe_constants_s),
        numfmt::num(times.l_phi_sampling_s),
        numfmt::num(times.l_pi_s),
        numfmt::num(times.gamma13_s),
        numfmt::num(times.theorem1_s),
    ));
    log.say(format!(
        "[{}] computing the linear stability boundary ρ_lin(K) of each method …",
        job.label
    ));
    let t0 = std::time::Instant::now();
    let linear = linear_entries(
        &p.resolved,
        &cert,
        p.solver,
        opts.phase_seconds,
        settings.live,
    );
    log.say(format!(
        "  done in {} s; searching K_reg, the regional certificate's smallest K, of each method \
         (estimated work within `certificate.phase_seconds` = {} s, split over the {} methods) …",
        numfmt::num(t0.elapsed().as_secs_f64()),
        numfmt::num(opts.phase_seconds),
        cert.solvers.len()
    ));
    let t0 = std::time::Instant::now();
    let regional = regional::regional_entries(&p.resolved, &cert, &linear);
    log.say(format!(
        "  done in {} s",
        numfmt::num(t0.elapsed().as_secs_f64())
    ));

    // The K-iteration MPC (`mpc.iterations`): the joint certificate decides the runs.
    let joint_cert = joint::joint_certificate(&p.resolved, &cert, p.solver)?;
    let own_controller = LoopOptions::from_scenario(&p.scenario)?.controller;
    // The certificate covering the scenario's configuration (iss_certificate::coverage): the
    // same decision as the sweeps' `certified` column.
    let applicable = Applicable::new(&p.resolved, &cert, p.solver, own_controller);
    let not_covered = applicable.uncovered_reason().map(ToString::to_string);
    let at_scenario = applicable.at(
        p.iterations,
        match own_controller {
            ControllerChoice::SuboptimalMpc { iterations, .. } => Some(iterations),
            _ => None,
        },
    );
    if let Some(r) = &not_covered {
        log.say(format!("[{}] NOT CERTIFIED: {r}", job.label));
    }
    let runs = run_plan(
        job,
        settings,
        p,
        &cert,
        joint_cert.as_ref(),
        own_controller,
        log,
    );
    Ok(Plan {
        cert,
        linear,
        regional,
        joint_cert,
        own_controller,
        applicable,
        not_covered,
        at_scenario,
        runs,
    })
}

/// The simulations: with the joint certificate, its cheapest pair and the scenario's own;
/// else K_min (when certified), the scenario's K and a small K (when void).
fn run_plan(
    job: &Job,
    settings: &Settings,
    p: &Prepared,
    cert: &ClosedLoopCertificate,
    joint_cert: Option<&JointCertificate>,
    own_controller: ControllerChoice,
    log: &mut Log,
) -> Vec<(usize, ControllerChoice, KSource)> {
    let Some(j) = joint_cert else {
        let k_min = cert.solver(p.solver).and_then(|s| s.k_min);
        return plan_runs(p.iterations, k_min, settings.small_k)
            .into_iter()
            .map(|(k, source)| (k, ControllerChoice::ExactMpc, source))
            .collect();
    };
    log.say(format!(
        "[{}] joint MPC + MHE certificate: cheapest certified pair (K_e, K_c) = {}",
        job.label,
        j.region
            .cheapest
            .map_or_else(|| "none".to_string(), |p| format!("({}, {})", p.k_e, p.k_c))
    ));
    let mut plan = Vec::new();
    if let Some(pair) = j.region.cheapest {
        let at_pair = ControllerChoice::SuboptimalMpc {
            iterations: pair.k_c,
            method: j.mpc_method,
        };
        plan.push((pair.k_e, at_pair, KSource::ComputedKMin));
    }
    if !plan
        .iter()
        .any(|(k, c, _)| *k == p.iterations && *c == own_controller)
    {
        plan.push((p.iterations, own_controller, KSource::Scenario));
    }
    plan
}

/// Runs the planned simulations (none when LMI (2) is infeasible and the file has no P: the
/// MHE needs one), each announced with its work; a computed K_min above `--sim-k-cap` or
/// any run beyond the work limit (only a computed K_min can be: the scenario's K was checked
/// in [`prepare`]) is skipped with the reason.
pub(super) fn simulate_runs(
    settings: &Settings,
    p: &Prepared,
    plan: &Plan,
    log: &mut Log,
) -> Result<(Vec<Run>, Vec<SkippedRun>)> {
    let mut runs: Vec<Run> = Vec::new();
    let mut skipped_runs = Vec::new();
    if plan.cert.ioss.is_none() && !p.has_p {
        return Ok((runs, skipped_runs));
    }
    let solver = p.solver;
    for &(k, controller, source) in &plan.runs {
        let work = Work::of(&p.scenario, k);
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
            log.say(format!(
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
            log.say(w.line(solver, source));
        }
        let t0 = std::time::Instant::now();
        let run = simulate(&p.resolved, solver, k, controller, source, settings.live)?;
        let secs = t0.elapsed().as_secs_f64();
        log.say(format!(
            "  done in {} s ({} iterations/s)",
            numfmt::num(secs),
            numfmt::num(k as f64 * run.trace.len() as f64 / secs.max(1e-9))
        ));
        runs.push(run);
    }
    Ok((runs, skipped_runs))
}

/// Props. 1 and 3 on the K_min run (or the joint check with the K-iteration MPC); a
/// configuration no certificate covers has nothing to contradict.
pub(super) fn check(
    p: &Prepared,
    plan: &Plan,
    runs: &[Run],
    skipped_runs: &[SkippedRun],
) -> Result<(TrajectoryReport, Option<JointReport>)> {
    let (cert, solver) = (&plan.cert, p.solver);
    let seed = p.scenario.noise.seed;
    let own = cert.solver(solver);
    let kmin_run = runs
        .iter()
        .find(|r| r.summary.k_source == KSource::ComputedKMin);
    let joint_report = match &plan.joint_cert {
        Some(j) => Some(joint::check(
            &p.resolved,
            cert,
            j,
            kmin_run.map(|r| &r.trace),
            spec_k_c(&p.scenario),
        )?),
        None => None,
    };
    let not_run = |reason: String, k: Option<usize>, steps: usize| TrajectoryReport {
        ran: false,
        reason: Some(reason),
        solver: solver.name().into(),
        k,
        seed,
        steps,
        certified_l_phi: None,
        sampled_l_phi: None,
        passed: None,
    };
    let mut trajectory_check = match (own, kmin_run) {
        _ if joint_report.is_some() => TrajectoryReport {
            passed: joint_report
                .as_ref()
                .and_then(|j| j.trajectory.as_ref())
                // Exit code 3 only for a violated inequality; a divergence or a stopped run
                // is its own verdict (exit code 4, `Outcome::diverged`).
                .map(|t| t.inequalities_hold()),
            ..not_run(
                "the controller is the K-iteration MPC: Props. 1 and 3 assume the exact MPC; \
                 the joint check (joint.trajectory) evaluates them with the δ terms"
                    .into(),
                kmin_run.map(|r| r.summary.k),
                kmin_run.map_or(0, |r| r.trace.len()),
            )
        },
        (Some(sc), Some(run)) => {
            let k = run.summary.k;
            let certified = check_trajectory(cert, &sc.analysis, k, &run.trace);
            let sampled =
                check_trajectory(cert, &analysis_with_sampled_l_phi(cert, sc), k, &run.trace);
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
        _ => not_run(no_check_reason(own, solver, skipped_runs), None, 0),
    };
    if let Some(r) = &plan.not_covered {
        trajectory_check.passed = None;
        trajectory_check.reason = Some(format!(
            "not certified: {r} (the inequalities are evaluated for reference only)"
        ));
    }
    Ok((trajectory_check, joint_report))
}

/// Why the trajectory check did not run when no K_min run exists.
fn no_check_reason(
    own: Option<&SolverCertificate>,
    solver: Method,
    skipped_runs: &[SkippedRun],
) -> String {
    match own {
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
    }
}

/// Writes trace.json, trace.csv and the figures into `set`; returns their paths and the
/// figure notes.
pub(super) fn write_traces(
    job: &Job,
    settings: &Settings,
    p: &Prepared,
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
    let doc = trace_document(job, &p.resolved, record, provenance, runs)?;
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
    let (figs, notes) = charts(&p.scenario, runs, p.fig2c_t);
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
    Ok((files, figure_notes))
}

/// certificate.json's document from the stages' results.
#[allow(clippy::too_many_arguments)]
pub(super) fn document(
    job: &Job,
    settings: &Settings,
    p: &Prepared,
    plan: Plan,
    runs: &[Run],
    skipped_runs: Vec<SkippedRun>,
    checks: (TrajectoryReport, Option<JointReport>),
    record: ScenarioRecord,
    provenance: Provenance,
    files: &[PathBuf],
    figure_notes: Vec<String>,
) -> CertificateDocument {
    let (trajectory_check, joint_report) = checks;
    let Plan {
        cert,
        linear,
        regional,
        joint_cert,
        own_controller,
        applicable,
        not_covered,
        at_scenario,
        ..
    } = plan;
    let (solver, scenario) = (p.solver, &p.scenario);
    let own = cert.solver(solver);
    let asymptotic_gains = gains::report(&cert, &regional, runs, solver, not_covered.as_deref());
    let solvers: Vec<SolverSummary> = (cert.solvers.iter())
        .map(|s| SolverSummary::new(s, solver, scenario, own_controller))
        .collect();
    let budget = crate::budget::reproduce(
        scenario,
        &(solvers.iter())
            .map(|s| (s.solver.clone(), s.k_min))
            .collect::<Vec<_>>(),
    );
    CertificateDocument {
        format: CERTIFICATE_FORMAT.into(),
        format_version: FORMAT_VERSION,
        preset: job.preset,
        label: job.label.clone(),
        scenario: record,
        provenance,
        host: HostInfo::collect(),
        settings: SettingsRecord {
            sampling_seed: scenario.noise.seed,
            lipschitz_pairs: settings.lipschitz_pairs,
            gamma13_sequences: settings.gamma13_sequences,
            enumeration_max_vars: settings.enumeration_max_vars,
            k_max: settings.k_max,
            small_k: settings.small_k,
            fig2c_t: p.fig2c_t,
            sim_k_cap: settings.sim_k_cap,
        },
        solver: solver.name().into(),
        scenario_iterations: p.iterations,
        // The library decides whether some pair can be certified; Theorem 1's K_min says
        // so, any other certificate needs the joint region's cheapest pair as well.
        certified: applicable.may_certify()
            && (applicable.kind() == Some(CertificateKind::Theorem1)
                || joint_cert
                    .as_ref()
                    .is_some_and(|j| j.region.cheapest.is_some())),
        certificate_applies: applicable.kind(),
        not_covered,
        at_scenario,
        scenario_iterations_match_k_min: own.and_then(|s| s.k_min).map(|k| k == p.iterations),
        solvers,
        budget,
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
            .map(|f| f.strip_prefix(&job.out).unwrap_or(f).display().to_string())
            .collect(),
        figure_notes,
        certificate: cert,
    }
}
