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
use iss_certificate::coverage::Applicable;
use iss_certificate::plan::{KSource, RunOutcome, plan_runs};
use lti_model::BoxSet;
use lti_model::matrix::to_rows;
use qp_iter::Method;
use serde::Serialize;

use crate::figures::{self, Chart, HLine, Legend, Pattern, Series};
use crate::output::OutputSet;
use crate::provenance::{Provenance, workspace_root};

mod charts;
mod document;
mod gains;
mod joint;
mod linear;
pub(crate) mod numfmt;
mod regional;
mod summary;
mod trace_csv;
mod work;

use charts::charts;
pub use document::*;
use linear::{LinearEntry, linear_entries};
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

/// The t of Fig. 2(c) when `--fig2c-t` is not given: 6 for the presets (the paper's), else
/// M + 1 (the first step whose window is full and whose prior is the scheme's own estimate;
/// 6 for the paper's M = 5), within the simulated steps.
pub fn default_fig2c_t(preset: Option<Preset>, scenario: &Scenario) -> usize {
    let last = scenario.simulation.steps.saturating_sub(1);
    match (preset, &scenario.mhe) {
        (Some(_), _) | (None, None) => FIG2C_T.min(last),
        (None, Some(m)) => (m.horizon + 1).min(last),
    }
}

/// The shipped case-study scenarios.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// The paper's M = 5, η = 0.8, K = 652 (certificate void: 6·0.8⁵ ≥ 1).
    Paper,
    /// The nearest parameters satisfying every premise (M = 9), simulated at K_min.
    Certified,
}

impl Preset {
    /// Both presets, in the order `reproduce` runs them.
    pub const ALL: [Preset; 2] = [Preset::Paper, Preset::Certified];

    /// `"paper"` or `"certified"` (also the output subdirectory).
    pub fn name(self) -> &'static str {
        match self {
            Preset::Paper => "paper",
            Preset::Certified => "certified",
        }
    }

    /// The scenario file, relative to the workspace root.
    pub fn scenario_file(self) -> &'static str {
        match self {
            Preset::Paper => "scenarios/case-study.toml",
            Preset::Certified => "scenarios/case-study-certified.toml",
        }
    }

    /// A job for this preset writing into `out_root/<name>`.
    pub fn job(self, out_root: &Path) -> Job {
        Job {
            label: self.name().to_string(),
            preset: Some(self),
            scenario: workspace_root().join(self.scenario_file()),
            out: out_root.join(self.name()),
        }
    }
}

/// One scenario to reproduce and where its files go.
#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    /// Name used in the outputs (`"paper"`, `"certified"`, or the file stem).
    pub label: String,
    /// The preset, if the scenario is one.
    pub preset: Option<Preset>,
    /// Scenario file.
    pub scenario: PathBuf,
    /// Output directory (created).
    pub out: PathBuf,
}

/// Sampling and search settings (defaults: those of the shipped results).
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Random pairs of the sampled L_Φ and L_π.
    pub lipschitz_pairs: usize,
    /// Injected error sequences per magnitude for the sampled γ₁,₃ (0 skips it).
    pub gamma13_sequences: usize,
    /// Cap on N·n_u for the free-set enumerations (γ₁,₃, L_π).
    pub enumeration_max_vars: usize,
    /// γ₁,₃ from the certified enumeration or supplied.
    pub gamma13: Gamma13Source,
    /// Largest K searched for K_min.
    pub k_max: usize,
    /// The small K simulated next to the scenario's K when the certificate is void.
    pub small_k: usize,
    /// Write the SVG figures.
    pub figures: bool,
    /// The t of Fig. 2(c) (`--fig2c-t`); None: [`default_fig2c_t`].
    pub fig2c_t: Option<usize>,
    /// Print each work line when it happens (stdout) and show progress on stderr; the lines
    /// are in [`Outcome::log`] either way.
    pub live: bool,
    /// `--sim-k-cap`: the largest computed K_min that is simulated (None: no cap beyond the
    /// work limit).
    pub sim_k_cap: Option<usize>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            lipschitz_pairs: 200,
            gamma13_sequences: 30,
            enumeration_max_vars: 20,
            gamma13: Gamma13Source::Certified,
            k_max: 1 << 24,
            small_k: 5,
            figures: true,
            fig2c_t: None,
            live: false,
            sim_k_cap: None,
        }
    }
}

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

struct Run {
    summary: RunSummary,
    trace: Trace,
    /// The Kalman baseline on the same u_t, y_t (None when it could not be built).
    kalman: Option<closed_loop::baseline::BaselineRun>,
}

/// The Kalman filter of the MHE's weights run on `trace` (module `closed_loop::baseline`).
fn kalman_baseline(
    resolved: &ResolvedScenario,
    trace: &Trace,
) -> (
    Option<closed_loop::baseline::BaselineRun>,
    Option<KalmanSummary>,
) {
    let scenario = resolved.scenario();
    let weights = "standard (λ = 1), Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹, Σ_v = R⁻¹".to_string();
    let built = resolved
        .mhe_config()
        .map_err(|e| e.to_string())
        .and_then(|cfg| {
            closed_loop::baseline::kalman_for_mhe(
                &scenario.plant,
                &scenario.simulation.prior,
                &cfg.p,
                &cfg.q,
                &cfg.r,
            )
            .map_err(|e| e.to_string())
        });
    match built {
        Ok(mut kf) => {
            let run = closed_loop::baseline::run_on_trace(&mut kf, trace);
            let summary = KalmanSummary {
                weights,
                completed: run.e_norms.len(),
                sup_norm_e: run.sup_norm_e(),
                tail_mean_e: run.tail_mean_e(),
                diverged: run.diverged(),
                divergence: run.divergence,
                error: run.error.clone(),
            };
            (Some(run), Some(summary))
        }
        Err(e) => (
            None,
            Some(KalmanSummary {
                weights,
                completed: 0,
                sup_norm_e: f64::NAN,
                tail_mean_e: None,
                diverged: false,
                divergence: None,
                error: Some(format!("not built: {e}")),
            }),
        ),
    }
}

/// Simulates at K = `k` step by step, with [`work::Progress`] on stderr when `live`.
fn simulate(
    resolved: &ResolvedScenario,
    solver: Method,
    k: usize,
    controller: ControllerChoice,
    source: KSource,
    live: bool,
) -> Result<Run> {
    let scenario = resolved.scenario();
    let opts = LoopOptions {
        method: solver,
        iterations: k,
        exact_mhe_solve: true,
        controller,
        seed: scenario.noise.seed,
        steps: scenario.simulation.steps,
    };
    let mut cl = resolved
        .build_loop(&opts)
        .with_context(|| format!("cannot set up the closed loop at K = {k}"))?;
    // Step by step (as `run` does) so that progress can be shown; the first step error stops
    // the run and is its result.
    let mut progress = work::Progress::new(format!("{} K = {k}", solver.name()), opts.steps, live);
    let mut error = None;
    let mut stopped_non_finite = false;
    while cl.t() < cl.steps() {
        if let Err(e) = cl.step() {
            stopped_non_finite = matches!(e, ClosedLoopError::NonFinite { .. });
            error = Some(e.to_string());
            break;
        }
        progress.update(cl.t());
    }
    progress.finish();
    let trace = cl.into_trace();
    let len = trace.len();
    let outside = closed_loop::scenario::draws_outside(&trace, &scenario.sets.disturbance);
    let (kalman, kalman_summary) = kalman_baseline(resolved, &trace);
    // The sweep's bounded rule, applied by the library to this run.
    let divergence = closed_loop::bounded::first_unbounded(
        &trace,
        &scenario.simulation.x0,
        closed_loop::bounded::DEFAULT_BOUNDED_FACTOR,
        stopped_non_finite,
    );
    let summary = RunSummary {
        label: format!("K={k}"),
        k,
        k_source: source,
        solver: solver.name().to_string(),
        controller: match controller {
            ControllerChoice::SuboptimalMpc { iterations, method } => {
                format!("MPC {method} with K_c = {iterations}")
            }
            _ => "exact MPC".into(),
        },
        exact_mhe_solve: true,
        seed: opts.seed,
        steps: opts.steps,
        completed: len,
        error,
        diverged: divergence.is_some(),
        diverged_at: divergence.map(|d| d.t),
        signal: divergence.map(|d| d.signal),
        divergence,
        mpc_infeasible_steps: trace.infeasible_steps().count(),
        sup_norm_e: trace.sup_norm_e(),
        sup_norm_x: trace.sup_norm_x(),
        final_norm_x: trace.x_norms().last().copied().unwrap_or(f64::NAN),
        tail_mean_e: trace.tail_mean_e(),
        tail_mean_x: trace.tail_mean_x(),
        tail_mean_epsilon: trace.tail_mean_epsilon(),
        w_outside: outside.len(),
        w_outside_first: outside.first().copied(),
        kalman: kalman_summary,
    };
    Ok(Run {
        summary,
        trace,
        kalman,
    })
}

fn fmt_opt(v: Option<usize>) -> String {
    v.map_or_else(|| "none".to_string(), |k| k.to_string())
}

fn comparison(cert: &ClosedLoopCertificate, solver: Method) -> Vec<ComparisonRow> {
    let sc = cert.solver(solver);
    let phi = sc.map_or_else(
        || "not computed".to_string(),
        |s| {
            format!(
                "{}·{}^K ({})",
                numfmt::num(s.phi_prefactor),
                numfmt::rate(s.phi_rate),
                s.solver.name()
            )
        },
    );
    let g = &cert.gamma13;
    let gamma_sampled = g.sampled.as_ref().map_or(String::new(), |s| {
        format!("; sampled ≥ {}", numfmt::num(s.gamma13_lower))
    });
    let k = match sc {
        Some(s) => match s.k_min {
            Some(k) => format!("K_min = {k} ({})", s.solver.name()),
            None => format!("none: void ({})", short_reason(s)),
        },
        None => "not computed".into(),
    };
    vec![
        ComparisonRow {
            quantity: "ρ = 6^(1/M)·η".into(),
            ours: format!(
                "{} (M = {}, η = {})",
                numfmt::num(cert.rho),
                cert.horizon,
                numfmt::num(cert.eta)
            ),
            paper: format!(
                "{} (not printed; from M = 5, η = 0.8)",
                numfmt::num(6f64.powf(0.2) * 0.8)
            ),
        },
        ComparisonRow {
            quantity: "φ(K)".into(),
            ours: phi,
            paper: "0.98^K (partial gradient)".into(),
        },
        ComparisonRow {
            quantity: "L_Φ".into(),
            ours: format!(
                "{} certified; sampled {}",
                numfmt::num(cert.l_phi.certified),
                numfmt::num(cert.l_phi.sampled)
            ),
            paper: "5.32 (sample-based)".into(),
        },
        ComparisonRow {
            quantity: "γ₁,₃".into(),
            ours: format!(
                "{} {}{gamma_sampled}{}",
                numfmt::num(g.used),
                g.source,
                // The enumeration replaced by the polynomial bound for the analysis budget.
                if g.skipped
                    .iter()
                    .any(|k| k.reason.contains("certificate.phase_seconds"))
                {
                    " (S-procedure bound: the free-set enumeration is beyond the analysis \
                     budget, key `certificate.phase_seconds`)"
                } else {
                    ""
                }
            ),
            paper: "28.8 (method of their journal paper)".into(),
        },
        ComparisonRow {
            quantity: "L_π".into(),
            ours: format!(
                "{} certified; sampled {}",
                numfmt::num(cert.l_pi_used),
                numfmt::num(cert.l_pi.sampled.estimate)
            ),
            paper: "2.65 (sample-based)".into(),
        },
        ComparisonRow {
            quantity: "K".into(),
            ours: k,
            paper: "652 (from (sg1)–(sg3))".into(),
        },
    ]
}

fn short_reason(s: &SolverCertificate) -> String {
    let names: Vec<&str> = s
        .analysis
        .violated()
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    if names.is_empty() {
        "no K satisfies sg1 + sg2 + sg3 < 1".into()
    } else {
        format!("{} fails", names.join(", "))
    }
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
    let gamma13 = match (settings.gamma13, scenario.certificate.gamma13) {
        (Gamma13Source::User(g), _) => Gamma13Source::User(g),
        (_, Some(g)) => Gamma13Source::User(g),
        (source, None) => source,
    };
    // The four named methods, plain and Jacobi-scaled (long horizons: the scaled maps keep
    // K_min near its short-horizon value), and the scenario's own method when it is another
    // one (custom parameters): it is the one simulated at its K_min.
    let mut solvers = CertificateOptions::default().solvers;
    if !solvers.contains(&solver) {
        solvers.push(solver);
    }
    let opts = CertificateOptions {
        solvers,
        gamma13,
        seed,
        lipschitz_pairs: settings.lipschitz_pairs,
        gamma13_sequences: settings.gamma13_sequences,
        enumeration_max_vars: settings.enumeration_max_vars,
        k_max: settings.k_max,
        phase_seconds: scenario.certificate.phase_seconds(),
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
                .map(|t| {
                    t.holds()
                        && kmin_run
                            .is_some_and(|r| r.summary.error.is_none() && !r.summary.diverged)
                }),
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
            let passed = certified.as_ref().map(|c| {
                c.prop1.holds
                    && c.prop3.holds
                    && run.summary.error.is_none()
                    && !run.summary.diverged
            });
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
                Some(sc) => format!(
                    "the certificate of {} is void ({}): there is no certified K to check",
                    solver.name(),
                    short_reason(sc)
                ),
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
            .map(|s| SolverSummary::new(s, solver))
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

/// Exit code when a simulation contradicts the certificate (Prop. 1/3 check failed beyond
/// the rounding floor, or the run at the certified K diverged).
pub const EXIT_CONTRADICTED: u8 = 3;
/// Exit code when a simulated run diverged (the bounded rule of [`closed_loop::bounded`])
/// and no certificate was contradicted: the loop is not certified at that K, and it blew up.
pub const EXIT_DIVERGED: u8 = 4;

/// The jobs of a command line: one preset, a user scenario, or both presets (default).
pub fn jobs(preset: Option<Preset>, scenario: Option<PathBuf>, out: Option<PathBuf>) -> Vec<Job> {
    let out = out.unwrap_or_else(|| workspace_root().join("target/reproduce"));
    match (preset, scenario) {
        (_, Some(path)) => {
            let label = path.file_stem().map_or_else(
                || "scenario".to_string(),
                |s| s.to_string_lossy().into_owned(),
            );
            vec![Job {
                out: out.join(&label),
                label,
                preset: None,
                scenario: path,
            }]
        }
        (Some(p), None) => vec![p.job(&out)],
        (None, None) => Preset::ALL.iter().map(|p| p.job(&out)).collect(),
    }
}

/// `cargo xtask reproduce`: runs the jobs, prints each summary. Exit code 0,
/// [`EXIT_CONTRADICTED`] when a certified trajectory check fails, [`EXIT_DIVERGED`] when a
/// run diverged otherwise; errors (1) for bad input.
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
            "a simulated run diverged (bounded rule: ‖e‖, ‖x‖, ε within 1000·(1 + initial scale); \
             see the verdict and `runs[].diverged_at` in certificate.json)"
        );
        std::process::ExitCode::from(EXIT_DIVERGED)
    } else {
        std::process::ExitCode::SUCCESS
    })
}

/// The files of the previous run in a directory, from its `certificate.json` (`files`):
/// those the new set does not replace are removed when it is committed.
fn previous_files(cert_path: &Path) -> Vec<String> {
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

fn trace_document<'a>(
    job: &'a Job,
    resolved: &'a ResolvedScenario,
    record: &'a ScenarioRecord,
    provenance: &'a Provenance,
    runs: &'a [Run],
) -> Result<TraceDocument<'a>> {
    let scenario = resolved.scenario();
    let sys = &scenario.plant;
    let spec = scenario
        .mhe
        .as_ref()
        .ok_or(ClosedLoopError::MissingSection { section: "mhe" })?;
    let mpc = resolved.mpc()?;
    // The P the estimator used: the scenario's, or the maximal solution of LMI (2).
    let cfg = resolved.mhe_config()?;
    let m = |x: faer::MatRef<'_, f64>| to_rows(x);
    Ok(TraceDocument {
        format: TRACE_FORMAT,
        format_version: FORMAT_VERSION,
        preset: job.preset,
        label: &job.label,
        scenario: record,
        provenance,
        model: ModelRecord {
            dims: crate::certify::PlantDims::of(sys),
            a: m(sys.a()),
            b: m(sys.b()),
            c: m(sys.c()),
            e: m(sys.e()),
            f: m(sys.f()),
        },
        sets: SetsRecord {
            state: BoxRecord::new(&scenario.sets.state),
            input: BoxRecord::new(&scenario.sets.input),
            output: BoxRecord::new(&scenario.sets.output),
            disturbance: BoxRecord::new(&scenario.sets.disturbance),
        },
        mhe: MheInfo {
            horizon: cfg.horizon,
            eta: cfg.eta,
            p: m(cfg.p.as_ref()),
            q: m(cfg.q.as_ref()),
            r: m(cfg.r.as_ref()),
            p_source: if spec.p.is_some() {
                "scenario mhe.p".into()
            } else {
                "computed from LMI (2)".into()
            },
            warm_start: format!("{:?}", cfg.warm_start).to_lowercase(),
            cost: MHE_COST.into(),
        },
        mpc: MpcInfo {
            horizon: mpc.horizon(),
            q_c: m(mpc.q_c().as_ref()),
            r_c: m(mpc.r_c().as_ref()),
            terminal_weight: m(mpc.terminal_weight().as_ref()),
        },
        x0: &scenario.simulation.x0,
        prior: &scenario.simulation.prior,
        runs: runs
            .iter()
            .map(|r| TraceRun {
                summary: &r.summary,
                trace: &r.trace,
                kalman: r.kalman.as_ref(),
            })
            .collect(),
    })
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod truth_tests;
