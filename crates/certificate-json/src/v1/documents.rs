//! The two documents and the tool records they hold (filled by `cargo xtask`).

use serde::Serialize;

use super::*;

/// The JSON document `certify` writes (docs/certificate-json.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IossCertificate {
    /// Always `FORMAT`.
    pub format: String,
    /// Always `FORMAT_VERSION`.
    pub format_version: u32,
    /// True iff P ≻ 0 and λ_max(LMI matrix) ≤ tolerance.
    pub passed: bool,
    /// Why the check failed (`null` when passed).
    pub failure: Option<String>,
    /// A suggestion after a failure (e.g. the smallest feasible η), else `null`.
    pub hint: Option<String>,
    /// Scenario name and path.
    pub scenario: IossScenario,
    /// Git revision, tool version, compiler, time.
    pub provenance: Provenance,
    /// A, C, B̄, D̄ and the dimensions.
    pub system: IossSystem,
    /// η, Q, R and their sources.
    pub inputs: IossInputs,
    /// P and the LMI check; `null` if no P exists (LMI infeasible).
    pub certificate: Option<IossReport>,
    /// Always `TOLERANCE_RULE`.
    pub tolerance_rule: String,
    /// L_π of the scenario's MPC (Assumption 3): certified bounds and a sampled estimate;
    /// `null` when the scenario has no `[mpc]` section or the MPC it describes is not
    /// supported (then `controller_lipschitz_skipped` says why). Not part of the LMI
    /// pass/fail.
    pub controller_lipschitz: Option<LipschitzReport>,
    /// Why L_π was not computed although the scenario has an `[mpc]` section (e.g. state
    /// constraints in the MPC); `null` otherwise. A part of the scenario the LMI does not
    /// need never blocks its check.
    pub controller_lipschitz_skipped: Option<String>,
    /// Which closed-loop certificate covers the scenario's configuration (its method, warm
    /// start and controller: `iss_certificate::coverage::covering`, the decision `reproduce`,
    /// `sweep` and `export` make), or why none does; `null` without `[mhe]`. `certify` checks
    /// LMI (2) only: the verdict at K is `reproduce`'s.
    pub closed_loop: Option<Coverage>,
    /// `certify --loop`: per method K_lin, Theorem 1's K_min and the global loop
    /// certificate's K_glob (or what binds); `null` without `--loop`.
    pub loop_methods: Option<LoopSection>,
}

/// The parameters of LMI (2) and where each came from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IossInputs {
    /// η.
    pub eta: Option<f64>,
    /// `"scenario mhe.eta"` or `"--eta"`.
    pub eta_source: String,
    /// Q (n_w × n_w).
    pub q: Vec<Vec<Option<f64>>>,
    /// R (n_y × n_y).
    pub r: Vec<Vec<Option<f64>>>,
    /// `"scenario mhe.q, mhe.r"` or `"identity (no [mhe] section)"`.
    pub weights_source: String,
    /// `"computed"`, `"scenario mhe.p"` or `"--p-file <path>"`.
    pub p_source: String,
}

/// The plant's dimensions, written as flat fields `nx`, `nu`, `ny`, `nw1`, `nw2` into both
/// JSON documents (certificate and reproduce).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlantDims {
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
    /// n_y.
    pub ny: usize,
    /// n_w1 (entries of w¹).
    pub nw1: usize,
    /// n_w2 (entries of w²).
    pub nw2: usize,
}

/// The scenario the certificate is for.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IossScenario {
    /// `name` of the scenario.
    pub name: String,
    /// Path the scenario was read from, as given.
    pub path: String,
}

/// The plant data that enters LMI (2).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IossSystem {
    /// n_x, n_u, n_y, n_w1, n_w2.
    #[serde(flatten)]
    pub dims: PlantDims,
    /// A (n_x × n_x).
    pub a: Vec<Vec<Option<f64>>>,
    /// C (n_y × n_x).
    pub c: Vec<Vec<Option<f64>>>,
    /// B̄ = [E, 0] (n_x × n_w).
    pub b_bar: Vec<Vec<Option<f64>>>,
    /// D̄ = [0, F] (n_y × n_w).
    pub d_bar: Vec<Vec<Option<f64>>>,
}

/// Recorded next to every output so a result can be traced to the code that made it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Provenance {
    /// Name of the program that wrote the file.
    pub tool: String,
    /// Its version (the workspace version).
    pub tool_version: String,
    /// `git rev-parse HEAD` of the workspace, or `"unknown"` outside a git checkout.
    pub git_revision: String,
    /// True if tracked files differ from `git_revision`; `null` if git is unavailable.
    pub git_dirty: Option<bool>,
    /// `rustc --version` of the compiler on PATH, if any.
    pub rustc: Option<String>,
    /// Seconds since the Unix epoch when the file was written.
    pub created_unix: u64,
}

/// certificate.json (docs/reproduce-output.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Certificate {
    /// `CERTIFICATE_FORMAT`.
    pub format: String,
    /// `FORMAT_VERSION`.
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
    /// start: `iss_certificate::coverage`): `"theorem1"`, `"joint"`, or null when none does.
    pub certificate_applies: Option<CertificateKind>,
    /// Why no certificate covers the configuration (null when one does); `certified` is
    /// then false whatever Theorem 1's constants give.
    pub not_covered: Option<String>,
    /// The covering certificate's verdict at the scenario's own pair (`mhe.iterations`,
    /// `mpc.iterations`): the same function the sweeps' `certified` column calls.
    pub at_scenario: PairVerdict,
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
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint: Option<JointReport>,
    /// The exact linear stability boundary per method (exact MPC): ρ_lin(K) on a log grid,
    /// K_lin and every K with ρ_lin ≥ 1 (ρ_lin < 1 is necessary for local asymptotic stability of
    /// the origin when no constraint is active there; `iss_certificate::linear`).
    pub linear: Vec<LinearEntry>,
    /// K_reg of each method (`iss_certificate::regional`): the smallest K whose region
    /// contains the scenario's own uncertainty, searched up to K_min, with the region there
    /// (the certified rate and gains) — or the certificate at the largest K tried and the
    /// constraint that limits it (issue 27).
    pub regional: Vec<RegionalEntry>,
    /// What the certificate guarantees: Theorem 1's certified asymptotic gains (and the
    /// regional ones) per method at K_min, and per run the certified bound next to the
    /// measured gains (`iss_certificate::asymptotic`, issue 27).
    pub asymptotic_gains: GainsReport,
    /// Constants next to the paper's published values.
    pub paper_comparison: Vec<ComparisonRow>,
    /// Files written, relative to the output directory.
    pub files: Vec<String>,
    /// Figures not written or with points left out, and why.
    pub figure_notes: Vec<String>,
    /// The sample period as a budget (`plant.sample_time` given): per method at its smallest
    /// certified K (the one verdict's floor: K_min, K_glob or K_chain) the
    /// predicted instructions per step on the Cortex-M4F and M7 and whether it fits T_s
    /// (`mhe_budget`, docs/embedded.md), as the tool renders it. Omitted without T_s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub budget: Option<serde_json::Value>,
}

/// One row of the constants table (ours vs the paper's published values).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComparisonRow {
    /// Quantity.
    pub quantity: String,
    /// Ours, for the stand-in plant.
    pub ours: String,
    /// The paper's, for its own plant (not printed in the paper).
    pub paper: String,
}

/// The machine a result was produced on.
#[derive(Debug, Clone, PartialEq, Serialize)]
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

/// The Kalman baseline of one run (`closed_loop::baseline`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KalmanSummary {
    /// `"standard, Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹, Σ_v = R⁻¹"`.
    pub weights: String,
    /// Steps filtered.
    pub completed: usize,
    /// sup_t ‖x_t − x̂^KF_t‖.
    pub sup_norm_e: Option<f64>,
    /// Mean ‖x_t − x̂^KF_t‖ over the last quarter.
    pub tail_mean_e: Option<f64>,
    /// The filter left the bounded rule (signal e) or stopped.
    pub diverged: bool,
    /// Where, if it did.
    pub divergence: Option<Divergence>,
    /// The filter's error (construction or update), if any.
    pub error: Option<String>,
}

/// What one simulation did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSummary {
    /// Short name (`"K=652"`).
    pub label: String,
    /// Iterations K of Φ per step.
    pub k: usize,
    /// Why this K.
    pub k_source: KSource,
    /// Φ of the MHE.
    pub solver: String,
    /// `"exact MPC"`, or `"MPC <method> with K_c = <K_c>"` for the K-iteration MPC.
    pub controller: String,
    /// ε_t recorded (exact MHE solve on).
    pub exact_mhe_solve: bool,
    /// Disturbance seed.
    pub seed: u64,
    /// T requested.
    pub steps: usize,
    /// Steps completed (< T only after an error).
    pub completed: usize,
    /// The step error, if the run stopped early (e.g. a diverged loop).
    pub error: Option<String>,
    /// The run left the bounded rule (`closed_loop::bounded`, the sweep's: ‖e‖, ‖x‖, ε
    /// within 1000 times their initial scale, u finite) or stopped on a non-finite signal.
    pub diverged: bool,
    /// The first step at which it did (None when bounded).
    pub diverged_at: Option<usize>,
    /// The signal that failed first there: `"e"`, `"x"`, `"epsilon"` or `"u"`.
    pub signal: Option<Signal>,
    /// The failure itself: t, signal, value, the limit, and whether the loop stopped there
    /// (None when bounded).
    pub divergence: Option<Divergence>,
    /// Steps at which the MPC was infeasible (state constraints) and applied its fallback
    /// (`trace.csv` has the status per step).
    pub mpc_infeasible_steps: usize,
    /// sup_t ‖e_t‖.
    pub sup_norm_e: Option<f64>,
    /// sup_t ‖x_t‖.
    pub sup_norm_x: Option<f64>,
    /// ‖x_T‖.
    pub final_norm_x: Option<f64>,
    /// Mean ‖e_t‖ over the last quarter.
    pub tail_mean_e: Option<f64>,
    /// Mean ‖x_t‖ over the last quarter.
    pub tail_mean_x: Option<f64>,
    /// Mean ε_t over the last quarter.
    pub tail_mean_epsilon: Option<f64>,
    /// Steps whose simulated draw w_t lies outside 𝒲 (`sets.disturbance`, the set the MHE
    /// and the certificate assume): the ISS statement is not claimed from the first of them
    /// on (`closed_loop::scenario::draws_outside`).
    pub w_outside: usize,
    /// The first such step.
    pub w_outside_first: Option<usize>,
    /// The Kalman filter of the MHE's weights on the same u_t, y_t
    /// (`closed_loop::baseline::kalman_for_mhe`); None when it could not be built (the
    /// reason is in `kalman_error`).
    pub kalman: Option<KalmanSummary>,
}

/// The scenario as read.
#[derive(Debug, Clone, PartialEq, Serialize)]
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

/// The settings as recorded.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SettingsRecord {
    /// Seed of every sampled estimate (the scenario's `noise.seed`).
    pub sampling_seed: u64,
    /// See `Settings`.
    pub lipschitz_pairs: usize,
    /// See `Settings`.
    pub gamma13_sequences: usize,
    /// See `Settings`.
    pub enumeration_max_vars: usize,
    /// See `Settings`.
    pub k_max: usize,
    /// See `Settings`.
    pub small_k: usize,
    /// The t of Fig. 2(c) (`--fig2c-t`, or the default).
    pub fig2c_t: usize,
    /// `--sim-k-cap` (null: none).
    pub sim_k_cap: Option<usize>,
}

/// A simulation of the plan that was not run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SkippedRun {
    /// Its K.
    pub k: usize,
    /// Why this K was planned.
    pub k_source: KSource,
    /// Why it was not run.
    pub reason: String,
}

/// One solver's verdict, flattened for readers of the JSON.
#[derive(Debug, Clone, PartialEq, Serialize)]
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
    /// The global loop certificate's K_glob (Theorem L3, docs/theory.md §4): every K ≥ it is
    /// certified in f64; null: `global.outcome` says why.
    pub k_glob: Option<usize>,
    /// K_glob in f32 (Theorem L3u); null: `global.f32_outcome` says why.
    pub k_glob_f32: Option<usize>,
    /// The smallest K certified in f32 by the one verdict: Theorem 1 with the f32 rounding
    /// folded in, or `k_glob_f32` (what `export --scalar f32 --k certified` exports); null:
    /// `f32_reason` says why.
    pub k_f32: Option<usize>,
    /// Why no K is certified in f32 (`""` when `k_f32` is set).
    pub f32_reason: String,
    /// K_chain: the smallest K the iteration chain certified (Theorem L3b, L3c for FISTA;
    /// f64, pg, fista and their Jacobi variants; that K only, the chain is not monotone); null: `global.chain` says why.
    pub k_chain: Option<usize>,
    /// The global loop certificate of this method (null: not computed with the certificate,
    /// or the controller is not the exact MPC).
    pub global: Option<GlobalRecord>,
    /// Why there is no K_min (empty when there is one, and when it was not computed).
    pub void_reasons: Vec<String>,
    /// Not certified and not void: the analysis budget stopped the phase that decides it
    /// (phase, estimated seconds, budget; docs/reproduce-output.md). Omitted otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_computed: Option<NotComputed>,
    /// Every premise with pass/fail, value, margin and fix.
    pub premises: Vec<Premise>,
    /// φ(K) = prefactor · rateᴷ.
    pub phi_rate: Option<f64>,
    /// Prefactor of φ(K).
    pub phi_prefactor: Option<f64>,
    /// 1 − (sg1 + sg2 + sg3) = det(I − Γ) at K_min, > 0 iff ρ(Γ) < 1 (null when void).
    pub margin_at_k_min: Option<f64>,
    /// K_min with the sampled L_Φ instead of the certified bound (not a certificate).
    pub k_min_with_sampled_l_phi: Option<usize>,
}

/// The global loop certificate of one method (`iss_certificate::lure::global_outcome`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GlobalRecord {
    /// The f64 outcome's sentence ("K_glob = …", or why none: what binds, or "not computed
    /// within the budget").
    pub outcome: String,
    /// φ*: the largest certified φ (null without a certificate).
    pub phi_star: Option<f64>,
    /// The LMI's margin in the independent check.
    pub margin: Option<f64>,
    /// ρ of ‖X⁺‖²_P ≤ ρ²‖X‖²_P + γ²‖w‖².
    pub rho: Option<f64>,
    /// γ.
    pub gamma: Option<f64>,
    /// lim sup ‖x_t‖ ≤ gain_x·w̄.
    pub gain_x: Option<f64>,
    /// lim sup ‖x_t − x̂_t‖ ≤ gain_e·w̄.
    pub gain_e: Option<f64>,
    /// The f32 outcome's sentence (Theorem L3u).
    pub f32_outcome: String,
    /// The ISS offset of f32's rounding (null without an f32 certificate).
    pub f32_offset: Option<f64>,
    /// The iteration chain (Theorem L3b, L3c for FISTA; null: the method is not pg, fista or their
    /// Jacobi variants).
    pub chain: Option<ChainRecord>,
}

/// The iteration chain of one method (`iss_certificate::lure::chain_outcome`): the K it was
/// checked at and each answer; it certifies those K only (not monotone in K).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChainRecord {
    /// The smallest certified K (null: none of the K checked).
    pub k_chain: Option<usize>,
    /// The K checked, ascending.
    pub checked: Vec<usize>,
    /// The K certified, ascending.
    pub certified: Vec<usize>,
    /// One sentence per K checked (in the order checked), or why the chain does not apply.
    pub outcomes: Vec<String>,
    /// How the scan K = 1, 2, … ended (`"certified"`, `"cap"` or `"stopped"`; `"none"`:
    /// not applicable).
    pub scan: String,
    /// The LMI's margin in the independent check at K_chain.
    pub margin: Option<f64>,
    /// ρ of the certificate at K_chain.
    pub rho: Option<f64>,
    /// γ of the certificate at K_chain.
    pub gamma: Option<f64>,
    /// The method's budget (estimated single-core seconds, `certificate.phase_seconds`).
    pub budget_seconds: Option<f64>,
}

/// Props. 1 and 3 evaluated on the K_min run.
#[derive(Debug, Clone, PartialEq, Serialize)]
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

/// g·w̄ for one run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CertifiedBound {
    /// The certificate of the gains: `theorem1`, `global` (Theorem L3, K ≥ K_glob) or
    /// `chain` (the iteration chain at the run's K); g_ε is Theorem 1's only.
    pub certificate: CertificateKind,
    /// g_x.
    pub gain_x: Option<f64>,
    /// g_ε.
    pub gain_epsilon: Option<f64>,
    /// g_e.
    pub gain_e: Option<f64>,
    /// lim sup‖x_t‖ ≤ g_x·w̄.
    pub bound_x: Option<f64>,
    /// lim sup ε_t ≤ g_ε·w̄.
    pub bound_epsilon: Option<f64>,
    /// lim sup‖e_t‖ ≤ g_e·w̄.
    pub bound_e: Option<f64>,
}

/// `asymptotic_gains` of certificate.json.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GainsReport {
    /// What the numbers mean, in one sentence.
    pub meaning: String,
    /// Per method at its K_min: Theorem 1's certified gains and the regional ones.
    pub methods: Vec<MethodGains>,
    /// Per simulated run (same order as `runs`): the certified bound at the run's K next to
    /// the measured gains.
    pub runs: Vec<RunGains>,
}

/// One method's certified asymptotic gains at its K_min.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodGains {
    /// The method.
    pub solver: String,
    /// Its K_min (null when Theorem 1 is void).
    pub k_min: Option<usize>,
    /// Theorem 1's gains at K_min (`iss_certificate::asymptotic::AsymptoticGains`): g_x,
    /// g_ε, g_e and the comparison systems; null when void.
    pub theorem1: Option<AsymptoticGains>,
    /// Why there are none (null when there are).
    pub theorem1_void: Option<String>,
    /// The regional certificate's gains at the K of the regional entry (K_reg, or the largest K
    /// its search tried; null when it has none).
    pub regional: Option<RegionalGains>,
    /// Why there are none.
    pub regional_void: Option<String>,
}

/// The regional certificate's gains (`iss_certificate::regional::RegionalCertificate`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegionalGains {
    /// The K they are certified at.
    pub k: usize,
    /// lim sup‖x_t‖ ≤ gain_x·w̄ inside the region.
    pub gain_x: Option<f64>,
    /// lim sup‖e_t‖ ≤ gain_e·w̄ inside the region.
    pub gain_e: Option<f64>,
    /// The region contains the scenario's own uncertainty (x0_radius, prior_error, w̄): only
    /// then do these gains speak for the scenario's runs.
    pub contains: bool,
    /// The w̄ of the region.
    pub w_bar: Option<f64>,
}

/// One run's certified bound and measured gains.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunGains {
    /// The run's label (`"K=243"`).
    pub label: String,
    /// Its K.
    pub k: usize,
    /// Its controller.
    pub controller: String,
    /// sup_t‖w_t‖ of the run, the w̄ of the bounds below (null for an empty run).
    pub w_bar: Option<f64>,
    /// Theorem 1's bounds at the run's K with w̄ = `w_bar` (null when void).
    pub certified: Option<CertifiedBound>,
    /// Why there is no certified bound for this run.
    pub certified_void: Option<String>,
    /// The measured gains (`iss_certificate::asymptotic::MeasuredGains`: tail sups over
    /// t ≥ T/2 and whole-run sups, each also per unit of `w_bar`); null for an empty run.
    pub measured: Option<MeasuredGains>,
}

/// The shipped case-study scenarios.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// The paper's M = 5, η = 0.8, K = 652 (certificate void: 6·0.8⁵ ≥ 1).
    Paper,
    /// The nearest parameters satisfying every premise (M = 9), simulated at K_min.
    Certified,
}

/// The joint certificate and its trajectory check, as written to certificate.json (`joint`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointReport {
    /// K_c of the scenario (`mpc.iterations`).
    pub scenario_k_c: usize,
    /// The certificate: region, Pareto front, cheapest pair, gains there.
    pub certificate: JointCertificate,
    /// Every inequality on the run at the cheapest pair (None when it did not run).
    pub trajectory: Option<JointTrajectoryCheck>,
    /// max_t ‖u_t(replay) − u_t(trace)‖ of the δ replay (0: δ_t is the loop's own).
    pub replay_mismatch: Option<f64>,
    /// Why the check did not run (None when it ran).
    pub reason: Option<String>,
}

/// ρ_lin of one method, or why it has none.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinearEntry {
    /// The method.
    pub solver: String,
    /// The report (null when the analysis does not apply).
    pub report: Option<LinearReport>,
    /// Why there is no report (e.g. 0 on a bound of a box: no inactive neighbourhood).
    pub error: Option<String>,
}

/// One method's K_reg and regional certificate, or why there is none.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegionalEntry {
    /// The method.
    pub solver: String,
    /// K_lin of `linear[]` (null: none on the grid, or not computed — then
    /// `k_lin_not_computed` says why), for the ratios.
    pub k_lin: Option<usize>,
    /// Why ρ_lin, hence K_lin, was not computed for this method (the `error` of its
    /// `linear[]` entry: above n_z = 128 only the scenario's method, the budget, …); omitted
    /// when it was computed, so a null `k_lin` without it means "none on the grid".
    #[serde(skip_serializing_if = "Option::is_none")]
    pub k_lin_not_computed: Option<String>,
    /// Theorem 1's K_min (null: void or beyond its search range): it caps the search.
    pub k_min: Option<usize>,
    /// K_reg: the smallest K the search found whose region contains the scenario's own
    /// uncertainty (null: `void` says why).
    pub k_reg: Option<usize>,
    /// The largest K the search could try: min(K_min, or 2000 without one; ⌊200 000/n_z⌋).
    pub search_max: usize,
    /// Why `search_max` is that K.
    pub search_max_reason: String,
    /// The K `certificate` was evaluated at: K_reg, or the largest K tried when there is
    /// none (null: nothing evaluated).
    pub k: Option<usize>,
    /// The regional certificate at `k` (null when it could not be evaluated there).
    pub certificate: Option<RegionalCertificate>,
    /// Every K the search evaluated, ascending.
    pub tried: Vec<TriedK>,
    /// Why there is no K_reg (null when there is one): the void reason, or which constraint
    /// limits the region at the largest K tried and by how much.
    pub void: Option<String>,
    /// The step-0 row an admissible realization drives past its bound, when one does: no K
    /// has a region (step 0 does not depend on K; `void` says so).
    pub refuted_every_k: Option<Limit>,
    /// What the rows free of K (t = 0, the MHE's first inner iterates at t = 1) allow at any K:
    /// `{scale, max_x0_radius, max_prior_error, max_w_bar}`; no K's region contains a set
    /// beyond it (null: the search did not run).
    pub k_free: Option<KFreeLimits>,
    /// The scenario's uncertainty the search was for (null when it has none: `void` says why).
    pub uncertainty: Option<RegionalOptions>,
    /// The certificate at K = 2·K_lin, the issue's target, when the search evaluated it (it
    /// asks for it as a bisection point: `iss_certificate::regional::k_reg_probing`): with
    /// K_reg above 2·K_lin, which row limits the region there and by how much.
    pub at_two_k_lin: Option<ProbeNote>,
}

/// One K the search evaluated.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TriedK {
    /// K.
    pub k: usize,
    /// The largest certified scale of the scenario's uncertainty at K (capped just below 1
    /// when the region does not contain it; null: void at K, or ∞ when `contains`).
    pub margin: Option<f64>,
    /// The region at K contains the scenario's uncertainty.
    pub contains: bool,
}
