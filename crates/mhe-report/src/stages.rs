//! The stages of [`crate::report`]: prepare (check the scenario, the options of its
//! certificate), plan (certify, decide the runs), simulate with the analysis (ρ_lin, K_reg)
//! beside it on its own thread, check (Props. 1 and 3, or the joint check), gains. Each stage takes what the previous one produced; none re-reads or
//! recomputes it.

use std::time::Instant;

use closed_loop::ClosedLoopError;
use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario, Scenario};
use iss_certificate::certificate::{
    CertificateOptions, ClosedLoopCertificate, Gamma13Source, SolverCertificate, TrajectoryCheck,
    analysis_with_sampled_l_phi, certify_closed_loop_timed, check_trajectory,
};
use iss_certificate::coverage::{Applicable, PairVerdict, verdict_options};
use iss_certificate::joint::JointCertificate;
use iss_certificate::plan::{KSource, plan_runs};
use lti_model::numfmt::sig4;
use qp_iter::Method;

use crate::joint::{self, JointReport};
use crate::linear::{LinearEntry, linear_entries};
use crate::runs::{Run, simulate};
use crate::{Observer, Options, Report, ReportError, Timings, Work, regional, short_reason};

/// A simulation of the plan that was not run.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct SkippedRun {
    /// Its K.
    pub k: usize,
    /// Why this K was planned.
    pub k_source: KSource,
    /// Why it was not run.
    pub reason: String,
}

/// Props. 1 and 3 evaluated on the K_min run.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct TrajectoryReport {
    /// The check ran (a K_min exists and ε_t was recorded).
    pub ran: bool,
    /// Why it did not run.
    pub reason: Option<String>,
    /// Method of the run.
    pub solver: String,
    /// K of the run (K_min) and of the constants.
    pub k: Option<usize>,
    /// Seed of the run.
    pub seed: u64,
    /// Steps evaluated.
    pub steps: usize,
    /// With the certificate's constants (certified L_Φ).
    pub certified_l_phi: Option<TrajectoryCheck>,
    /// The same constants with the sampled L_Φ (informative, not a certificate).
    pub sampled_l_phi: Option<TrajectoryCheck>,
    /// Both inequalities hold at every t with the certified constants.
    pub passed: Option<bool>,
}

/// One simulation the certificates decided: K, the controller, and why this K.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct PlannedRun {
    /// Iterations K of the MHE.
    pub k: usize,
    /// The controller.
    pub controller: ControllerChoice,
    /// Why this K.
    pub source: KSource,
}

/// The work log: each line to the observer and kept for [`Report::log`].
struct Log<'a> {
    observer: &'a dyn Observer,
    lines: Vec<String>,
}

impl Log<'_> {
    fn say(&mut self, line: String) {
        self.observer.line(&line);
        self.lines.push(line);
    }
}

/// The four stages, in order.
pub(crate) fn run(
    scenario: Scenario,
    options: &Options,
    observer: &dyn Observer,
) -> Result<Report, ReportError> {
    let p = prepare(scenario, options)?;
    let mut log = Log {
        observer,
        lines: Vec::new(),
    };
    let mut timings = Timings::default();
    let plan = plan(options, &p, &mut log, &mut timings)?;
    // ρ_lin and K_reg read the certificate only, the simulations the certificate and the
    // plan: they run side by side (each deterministic on its own, so no result depends on
    // it). Both show their lines as they happen; the report's log keeps the stage order.
    let at = log.lines.len();
    let (analysis, simulated) = std::thread::scope(|s| {
        let analysis = s.spawn(|| analyse(options, &p, &plan.cert, observer));
        let simulated = simulate_runs(options, &p, &plan, &mut log, &mut timings);
        match analysis.join() {
            Ok(a) => (a, simulated),
            Err(panic) => std::panic::resume_unwind(panic),
        }
    });
    let (runs, skipped_runs) = simulated?;
    let Analysis {
        linear,
        regional,
        f32,
        lines,
        linear_s,
        regional_s,
        f32_s,
    } = analysis;
    log.lines.splice(at..at, lines);
    timings.linear_s = linear_s;
    timings.regional_s = regional_s;
    timings.f32_s = f32_s;
    let (trajectory_check, joint) = check(&p, &plan, &runs, &skipped_runs)?;
    let gains = crate::gains::report(
        &plan.cert,
        &regional,
        &runs,
        p.solver,
        plan.not_covered.as_deref(),
    );
    Ok(Report {
        paper_comparison: crate::paper_comparison(&plan.cert, p.solver),
        scenario: p.scenario,
        resolved: p.resolved,
        solver: p.solver,
        iterations: p.iterations,
        certificate_options: p.opts,
        certificate: plan.cert,
        linear,
        regional,
        f32,
        joint_certificate: plan.joint_cert,
        controller: plan.own_controller,
        applicable: plan.applicable,
        not_covered: plan.not_covered,
        at_scenario: plan.at_scenario,
        planned: plan.runs,
        runs,
        skipped_runs,
        trajectory_check,
        joint,
        gains,
        timings,
        log: log.lines,
    })
}

/// The scenario, checked, with the options of its certificate.
struct Prepared {
    scenario: Scenario,
    resolved: ResolvedScenario,
    /// `mhe.method`.
    solver: Method,
    /// `mhe.iterations`.
    iterations: usize,
    /// `mhe.p` was given (the MHE has a P even when LMI (2) fails).
    has_p: bool,
    opts: CertificateOptions,
}

/// Checks what is cheap to refuse (the sections, the work of the scenario's own K) before
/// the certificate, which can take minutes, and sets up its options.
fn prepare(scenario: Scenario, settings: &Options) -> Result<Prepared, ReportError> {
    let spec =
        scenario
            .mhe
            .as_ref()
            .ok_or(ReportError::Scenario(ClosedLoopError::MissingSection {
                section: "mhe",
            }))?;
    if scenario.mpc.is_none() {
        return Err(ReportError::Scenario(ClosedLoopError::MissingSection {
            section: "mpc",
        }));
    }
    let (solver, iterations, has_p) = (spec.method(), spec.iterations().get(), spec.p().is_some());
    if let Some(work) = Work::of(&scenario, iterations).filter(|w| !w.within_limit()) {
        return Err(ReportError::WorkLimit { work });
    }
    // γ₁,₃: the command line's value, else the scenario's `certificate.gamma13`, else computed.
    let cli_gamma13 = match settings.gamma13 {
        Gamma13Source::User(g) => Some(g),
        // Certified (or a source added later): computed, not the user's.
        _ => None,
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
    let resolved = scenario.clone().resolve().map_err(ReportError::Resolve)?;
    Ok(Prepared {
        scenario,
        resolved,
        solver,
        iterations,
        has_p,
        opts,
    })
}

/// The certificates of the scenario and the runs they decide.
struct Plan {
    cert: ClosedLoopCertificate,
    joint_cert: Option<JointCertificate>,
    own_controller: ControllerChoice,
    applicable: Applicable,
    not_covered: Option<String>,
    at_scenario: PairVerdict,
    /// Each simulation, in order.
    runs: Vec<PlannedRun>,
}

/// Theorem 1's certificate, the joint certificate when the MPC is the K-iteration one, the
/// certificate covering the scenario, and the runs they decide (K_lin and K_reg are not
/// needed for them: [`analyse`] runs beside the simulations).
fn plan(
    settings: &Options,
    p: &Prepared,
    log: &mut Log<'_>,
    timings: &mut Timings,
) -> Result<Plan, ReportError> {
    let opts = &p.opts;
    log.say(format!(
        "[{}] computing the certificates (Theorem 1, the global loop certificate, the iteration chain) for {} …",
        settings.label,
        opts.solvers
            .iter()
            .map(|m| m.name())
            .collect::<Vec<_>>()
            .join(", ")
    ));
    log.observer
        .certifying(&p.scenario, p.resolved.mpc().ok(), opts);
    let t0 = Instant::now();
    let (cert, times) =
        certify_closed_loop_timed(&p.resolved, opts).map_err(ReportError::Certificate)?;
    timings.certificate = times;
    timings.certificate_s = t0.elapsed().as_secs_f64();
    log.say(format!(
        "  done in {} s (MHE constants {} s, L_Φ sampling {} s, L_π {} s, γ₁,₃ {} s, \
         Theorem 1 {} s, the global loop certificate {} s; wall time)",
        sig4(t0.elapsed().as_secs_f64()),
        sig4(times.mhe_constants_s),
        sig4(times.l_phi_sampling_s),
        sig4(times.l_pi_s),
        sig4(times.gamma13_s),
        sig4(times.theorem1_s),
        sig4(times.global_s),
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
            ControllerChoice::SuboptimalMpc { iterations, .. } => Some(iterations.get()),
            _ => None,
        },
    );
    if let Some(r) = &not_covered {
        log.say(format!("[{}] NOT CERTIFIED: {r}", settings.label));
    }
    let runs = run_plan(settings, p, &cert, joint_cert.as_ref(), own_controller, log);
    Ok(Plan {
        cert,
        joint_cert,
        own_controller,
        applicable,
        not_covered,
        at_scenario,
        runs,
    })
}

/// ρ_lin per method, K_reg and the f32 verdicts, with the lines of their work log and
/// their wall times.
struct Analysis {
    linear: Vec<LinearEntry>,
    regional: Vec<regional::RegionalEntry>,
    f32: Vec<crate::F32Entry>,
    lines: Vec<String>,
    linear_s: f64,
    regional_s: f64,
    f32_s: f64,
}

/// The linear stability boundary ρ_lin(K) of each method, then K_reg (which reads it), with
/// their own log (run beside the simulations).
fn analyse(
    settings: &Options,
    p: &Prepared,
    cert: &ClosedLoopCertificate,
    observer: &dyn Observer,
) -> Analysis {
    let phase_seconds = p.opts.phase_seconds;
    let mut log = Log {
        observer,
        lines: Vec::new(),
    };
    log.say(format!(
        "[{}] computing the linear stability boundary ρ_lin(K) of each method …",
        settings.label
    ));
    let t0 = Instant::now();
    let linear = linear_entries(&p.resolved, cert, p.solver, phase_seconds, observer);
    let linear_s = t0.elapsed().as_secs_f64();
    log.say(format!(
        "  done in {} s; searching K_reg, the regional certificate's smallest K, of each method \
         (estimated work within `certificate.phase_seconds` = {} s, split over the {} methods) …",
        sig4(linear_s),
        sig4(phase_seconds),
        cert.solvers.len()
    ));
    let t0 = Instant::now();
    let regional = regional::regional_entries(&p.resolved, cert, &linear);
    let regional_s = t0.elapsed().as_secs_f64();
    log.say(format!(
        "  done in {} s; the smallest K certified in f32 of each method (Theorem 1 with the \
         f32 rounding folded in, and Theorem L3u) …",
        sig4(regional_s)
    ));
    let t0 = Instant::now();
    let controller = LoopOptions::from_scenario(&p.scenario)
        .map_or(ControllerChoice::ExactMpc, |o| o.controller);
    let f32 = crate::F32Entry::all(&p.resolved, cert, controller, p.iterations);
    let f32_s = t0.elapsed().as_secs_f64();
    log.say(format!("  done in {} s", sig4(f32_s)));
    Analysis {
        linear,
        regional,
        f32,
        lines: log.lines,
        linear_s,
        regional_s,
        f32_s,
    }
}

/// The simulations: with the joint certificate, its cheapest pair and the scenario's own;
/// else K_min (when certified), the scenario's K and a small K (when void).
fn run_plan(
    settings: &Options,
    p: &Prepared,
    cert: &ClosedLoopCertificate,
    joint_cert: Option<&JointCertificate>,
    own_controller: ControllerChoice,
    log: &mut Log<'_>,
) -> Vec<PlannedRun> {
    let Some(j) = joint_cert else {
        let k_min = cert.solver(p.solver).and_then(|s| s.k_min);
        return plan_runs(p.iterations, k_min, settings.small_k)
            .into_iter()
            .map(|(k, source)| PlannedRun {
                k,
                controller: ControllerChoice::ExactMpc,
                source,
            })
            .collect();
    };
    log.say(format!(
        "[{}] joint MPC + MHE certificate: cheapest certified pair (K_e, K_c) = {}",
        settings.label,
        j.region
            .cheapest
            .map_or_else(|| "none".to_string(), |p| format!("({}, {})", p.k_e, p.k_c))
    ));
    let mut plan = Vec::new();
    // The certificate's K_c lies in 1 ..= its search cap, so it is an iteration budget.
    if let Some((pair, at_pair)) = j.region.cheapest.and_then(|pair| {
        let c = ControllerChoice::suboptimal(pair.k_c, j.mpc_method).ok()?;
        Some((pair, c))
    }) {
        plan.push(PlannedRun {
            k: pair.k_e,
            controller: at_pair,
            source: KSource::ComputedKMin,
        });
    }
    if !plan
        .iter()
        .any(|r| r.k == p.iterations && r.controller == own_controller)
    {
        plan.push(PlannedRun {
            k: p.iterations,
            controller: own_controller,
            source: KSource::Scenario,
        });
    }
    plan
}

/// Runs the planned simulations (none when LMI (2) is infeasible and the file has no P: the
/// MHE needs one), each announced with its work; a computed K_min above `--sim-k-cap` or
/// any run beyond the work limit (only a computed K_min can be: the scenario's K was checked
/// in [`prepare`]) is skipped with the reason.
fn simulate_runs(
    settings: &Options,
    p: &Prepared,
    plan: &Plan,
    log: &mut Log<'_>,
    timings: &mut Timings,
) -> Result<(Vec<Run>, Vec<SkippedRun>), ReportError> {
    let mut runs: Vec<Run> = Vec::new();
    let mut skipped_runs = Vec::new();
    if plan.cert.ioss.is_none() && !p.has_p {
        return Ok((runs, skipped_runs));
    }
    let solver = p.solver;
    for &PlannedRun {
        k,
        controller,
        source,
    } in &plan.runs
    {
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
        let t0 = Instant::now();
        let run = simulate(&p.resolved, solver, k, controller, source, log.observer)?;
        let secs = t0.elapsed().as_secs_f64();
        timings.simulations_s.push(secs);
        log.say(format!(
            "  done in {} s ({} iterations/s)",
            sig4(secs),
            sig4(k as f64 * run.trace.len() as f64 / secs.max(1e-9))
        ));
        runs.push(run);
    }
    Ok((runs, skipped_runs))
}

/// Props. 1 and 3 on the K_min run (or the joint check with the K-iteration MPC); a
/// configuration no certificate covers has nothing to contradict.
fn check(
    p: &Prepared,
    plan: &Plan,
    runs: &[Run],
    skipped_runs: &[SkippedRun],
) -> Result<(TrajectoryReport, Option<JointReport>), ReportError> {
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
                // is its own verdict (exit code 4, `Report::diverged`).
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
            // a stopped run is its own verdict (exit code 4, `Report::diverged`).
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

/// K_c of the scenario's MPC (`mpc.iterations`, 0 for the exact MPC).
fn spec_k_c(scenario: &Scenario) -> usize {
    scenario
        .mpc
        .as_ref()
        .and_then(|m| m.iterations())
        .map_or(0, qp_iter::Iterations::get)
}
