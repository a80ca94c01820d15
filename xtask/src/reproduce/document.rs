//! The documents `reproduce` writes (`certificate.json`, `trace.json`) and its outcome:
//! plain serialisable records, filled in by `run_job` (docs/reproduce-output.md).

use super::*;

/// The scenario as read.
#[derive(Debug, Clone, Serialize)]
pub struct ScenarioRecord {
    /// `name`.
    pub name: String,
    /// `description`.
    pub description: Option<String>,
    /// Path, relative to the workspace when inside it.
    pub path: String,
    /// The file's text, verbatim (comments included).
    pub text: Option<String>,
}

/// The machine a result was produced on.
#[derive(Debug, Clone)]
pub struct HostInfo {
    /// Host name, if it could be read.
    pub hostname: Option<String>,
    /// `std::env::consts::OS`.
    pub os: String,
    /// `std::env::consts::ARCH`.
    pub arch: String,
    /// Available parallelism (logical CPUs usable by this process).
    pub cpus: Option<usize>,
}

impl HostInfo {
    pub(super) fn collect() -> Self {
        let hostname = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .or_else(|_| std::fs::read_to_string("/etc/hostname"))
            .ok()
            .map(|s| s.trim().to_string())
            .or_else(|| std::env::var("HOSTNAME").ok())
            .filter(|s| !s.is_empty());
        Self {
            hostname,
            os: std::env::consts::OS.to_string(),
            arch: std::env::consts::ARCH.to_string(),
            cpus: std::thread::available_parallelism().ok().map(|n| n.get()),
        }
    }
}

/// The settings as recorded.
#[derive(Debug, Clone)]
pub struct SettingsRecord {
    /// Seed of every sampled estimate (the scenario's `noise.seed`).
    pub sampling_seed: u64,
    /// See [`Settings`].
    pub lipschitz_pairs: usize,
    /// See [`Settings`].
    pub gamma13_sequences: usize,
    /// See [`Settings`].
    pub enumeration_max_vars: usize,
    /// See [`Settings`].
    pub k_max: usize,
    /// See [`Settings`].
    pub small_k: usize,
    /// The t of Fig. 2(c) (`--fig2c-t`, or the default).
    pub fig2c_t: usize,
    /// `--sim-k-cap` (null: none).
    pub sim_k_cap: Option<usize>,
}

/// One solver's verdict, flattened for readers of the JSON.
#[derive(Debug, Clone)]
pub struct SolverSummary {
    /// `"pg"`, `"fista"`, `"admm"`, `"admm-pr"`.
    pub solver: String,
    /// Whether this is the scenario's `[mhe] solver` (the one simulated).
    pub simulated: bool,
    /// Theorem 1 certifies ISS for some K (K_min exists) and a certificate covers the
    /// scenario's configuration (false for a shifted warm start or the saturated LQR:
    /// `iss_certificate::coverage::solver_certified`).
    pub certified: bool,
    /// Smallest certified K; null when void.
    pub k_min: Option<usize>,
    /// Why there is no K_min (empty when there is one, and when it was not computed).
    pub void_reasons: Vec<String>,
    /// Not certified and not void: the analysis budget stopped the phase that decides it
    /// (phase, estimated seconds, budget; docs/reproduce-output.md). Omitted otherwise.
    pub not_computed: Option<iss_certificate::budget::NotComputed>,
    /// Every premise with pass/fail, value, margin and fix.
    pub premises: Vec<Premise>,
    /// φ(K) = prefactor · rateᴷ.
    pub phi_rate: f64,
    /// Prefactor of φ(K).
    pub phi_prefactor: f64,
    /// 1 − (sg1 + sg2 + sg3) = det(I − Γ) at K_min, > 0 iff ρ(Γ) < 1 (null when void).
    pub margin_at_k_min: Option<f64>,
    /// K_min with the sampled L_Φ instead of the certified bound (not a certificate).
    pub k_min_with_sampled_l_phi: Option<usize>,
}

impl SolverSummary {
    /// The entry of `sc`; `certified` is [`iss_certificate::coverage::solver_certified`]'s
    /// verdict for the scenario's configuration (false when no certificate covers it, e.g. a
    /// shifted warm start, whatever K_min says).
    pub(super) fn new(
        sc: &SolverCertificate,
        simulated: Method,
        scenario: &closed_loop::scenario::Scenario,
        controller: closed_loop::scenario::ControllerChoice,
    ) -> Self {
        Self {
            solver: sc.solver.name().to_string(),
            simulated: sc.solver == simulated,
            certified: iss_certificate::coverage::solver_certified(scenario, sc, controller),
            k_min: sc.k_min,
            void_reasons: sc.void_reasons.iter().map(ToString::to_string).collect(),
            not_computed: sc.not_computed.clone(),
            premises: sc.analysis.premises.clone(),
            phi_rate: sc.phi_rate,
            phi_prefactor: sc.phi_prefactor,
            margin_at_k_min: sc.at_k_min.as_ref().map(|g| g.margin),
            k_min_with_sampled_l_phi: sc.k_min_with_sampled_l_phi,
        }
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
    pub solvers: Vec<SolverSummary>,
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
    /// The sample period as a budget (`plant.sample_time` given): per method at K_min the
    /// predicted instructions per step on the Cortex-M4F at 168 MHz and the M7 at 480 MHz
    /// and whether it fits T_s (`mhe_budget`, docs/embedded.md). Omitted without T_s.
    pub budget: Option<mhe_export::budget::ReproduceBudget>,
}

/// A box with ±∞ bounds written as null.
#[derive(Debug, Clone, Serialize)]
pub struct BoxRecord {
    /// Lower bounds (null = −∞).
    pub lower: Vec<Option<f64>>,
    /// Upper bounds (null = +∞).
    pub upper: Vec<Option<f64>>,
}

impl BoxRecord {
    pub(super) fn new(b: &BoxSet) -> Self {
        let f = |v: &[f64]| v.iter().map(|a| a.is_finite().then_some(*a)).collect();
        Self {
            lower: f(b.lower()),
            upper: f(b.upper()),
        }
    }
}

/// Plant of eq. (1).
#[derive(Debug, Clone, Serialize)]
pub struct ModelRecord {
    /// n_x, n_u, n_y, dim w¹, dim w².
    #[serde(flatten)]
    pub dims: crate::certify::PlantDims,
    /// A.
    pub a: Vec<Vec<f64>>,
    /// B.
    pub b: Vec<Vec<f64>>,
    /// C.
    pub c: Vec<Vec<f64>>,
    /// E (w¹ → x⁺).
    pub e: Vec<Vec<f64>>,
    /// F (w² → y).
    pub f: Vec<Vec<f64>>,
}

/// 𝒳, 𝒰, 𝒴, 𝒲.
#[derive(Debug, Clone, Serialize)]
pub struct SetsRecord {
    /// 𝒳.
    pub state: BoxRecord,
    /// 𝒰.
    pub input: BoxRecord,
    /// 𝒴.
    pub output: BoxRecord,
    /// 𝒲 (w = (w¹, w²)).
    pub disturbance: BoxRecord,
}

/// The MHE problem's data (cost (9)).
#[derive(Debug, Clone, Serialize)]
pub struct MheInfo {
    /// M.
    pub horizon: usize,
    /// η.
    pub eta: f64,
    /// P (computed from LMI (2) unless the scenario gives it).
    pub p: Vec<Vec<f64>>,
    /// Q.
    pub q: Vec<Vec<f64>>,
    /// R.
    pub r: Vec<Vec<f64>>,
    /// `"computed from LMI (2)"` or `"scenario mhe.p"`.
    pub p_source: String,
    /// Warm start rule.
    pub warm_start: String,
    /// The cost, written out.
    pub cost: String,
}

/// The MPC's data.
#[derive(Debug, Clone, Serialize)]
pub struct MpcInfo {
    /// N.
    pub horizon: usize,
    /// Q_c.
    pub q_c: Vec<Vec<f64>>,
    /// R_c.
    pub r_c: Vec<Vec<f64>>,
    /// P_f (DARE).
    pub terminal_weight: Vec<Vec<f64>>,
}

/// One simulation in trace.json.
#[derive(Debug, Serialize)]
pub struct TraceRun<'a> {
    /// Summary (same as in certificate.json).
    #[serde(flatten)]
    pub summary: certificate_json::v1::RunSummary,
    /// Per step records.
    pub trace: &'a Trace,
    /// The Kalman baseline's estimates x̂^KF_t and error norms on the same data.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kalman: Option<&'a closed_loop::baseline::BaselineRun>,
}

/// trace.json (docs/reproduce-output.md).
#[derive(Debug, Serialize)]
pub struct TraceDocument<'a> {
    /// [`TRACE_FORMAT`].
    pub format: &'static str,
    /// [`FORMAT_VERSION`].
    pub format_version: u32,
    /// The preset, if any.
    pub preset: Option<Preset>,
    /// The job label.
    pub label: &'a str,
    /// The scenario.
    pub scenario: &'a ScenarioRecord,
    /// Provenance.
    pub provenance: &'a Provenance,
    /// Plant.
    pub model: ModelRecord,
    /// Sets.
    pub sets: SetsRecord,
    /// MHE data.
    pub mhe: MheInfo,
    /// MPC data.
    pub mpc: MpcInfo,
    /// x₀.
    pub x0: &'a [f64],
    /// x̄₀.
    pub prior: &'a [f64],
    /// The runs.
    pub runs: Vec<TraceRun<'a>>,
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

pub(super) fn trace_document<'a>(
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
            p_source: if spec.p().is_some() {
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
                summary: super::json_v1::run_summary(&r.summary),
                trace: &r.trace,
                kalman: r.kalman.as_ref(),
            })
            .collect(),
    })
}
