//! The linear boundary, the regional certificate, LMI (2) and the Lipschitz reports.

use serde::Serialize;

#[allow(unused_imports)]
use super::*;

/// ρ_lin on a K grid for one solver, with K_lin and every unstable K.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct LinearReport {
    /// Φ of the MHE.
    pub solver: Method,
    /// dim X of the lifted system.
    pub dim: usize,
    /// (K, ρ_lin(K)) for every K of the grid, ascending.
    pub rho_lin: Vec<(usize, Option<f64>)>,
    /// K_lin: the smallest grid K from which ρ_lin < 1 on the whole grid above (None if
    /// ρ_lin ≥ 1 at the largest K).
    pub k_lin: Option<usize>,
    /// Every grid K with ρ_lin(K) ≥ 1 (ρ_lin need not be monotone in K).
    pub unstable_ks: Vec<usize>,
}

/// Why a run was made at its K (exhaustive: the tool words each source).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum KSource {
    /// The computed K_min of Theorem 1.
    ComputedKMin,
    /// The scenario's `mhe.iterations`.
    Scenario,
    /// A small K for comparison.
    Small,
    /// A library variant this schema version does not name, by its Rust name (the library of
    /// this version produces none; a reader treats it as "not certified").
    Other(String),
}

/// What the rows free of K (t = 0, the MHE's first inner iterates at t = 1) allow at any K:
/// no K's region can contain a set beyond these (necessary, not sufficient).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct KFreeLimits {
    /// The largest factor s such that (s·x0_radius, s·prior_error, s·w̄) keeps every row free
    /// of K within its bound (∞: any; 0: the nominal point alone passes one).
    pub scale: Option<f64>,
    /// The largest x0_radius with the user's prior_error and w̄ (0: none).
    pub max_x0_radius: Option<f64>,
    /// The largest prior_error with the user's x0_radius and w̄.
    pub max_prior_error: Option<f64>,
    /// The largest w̄ with the user's x0_radius and prior_error.
    pub max_w_bar: Option<f64>,
}

/// The binding row of a region, with its figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Limit {
    /// Which constraint.
    pub row: RowLabel,
    /// Its bound min(u, −l) (full-window rows) or the bound it reaches (start-up rows).
    pub bound: Option<f64>,
    /// The certified bound on the largest value the row takes over the user's set (full
    /// window: its reach in Theorem R; start-up: |center| + deviation).
    pub reach: Option<f64>,
    /// A value of the row that an admissible realization of the user's set reaches in the
    /// linear loop (≤ `reach`; equal for start-up rows): the true worst case lies in
    /// [attained, reach]. Above `bound`, a constraint certainly activates (theory.md,
    /// Theorem R, "the witness").
    pub attained: Option<f64>,
    /// The step t at which `attained` is reached.
    pub attained_at: usize,
}

/// The regional certificate at one K.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct RegionalCertificate {
    /// Φ of the MHE.
    pub method: String,
    /// K.
    pub k: usize,
    /// dim X.
    pub dim: usize,
    /// ρ_lin(K).
    pub rho_lin: Option<f64>,
    /// The metric chosen (the evaluated candidate with the largest margin).
    pub metric: String,
    /// λ = ‖𝔸‖_P: the certified decay rate per step.
    pub rate: Option<f64>,
    /// b = ‖P^{½}𝔹_w‖₂.
    pub disturbance_gain: Option<f64>,
    /// The largest ‖X_M‖_P for which no full-window row activates at the user's w̄:
    /// min_c (bound_c − w̄h̃_c)/‖P^{−½}cᵀ‖ (theory.md, Theorem R).
    pub radius: Option<f64>,
    /// The full-window row that limits the user's set (largest reach / bound).
    pub radius_limit: Option<Limit>,
    /// sup over the user's set of ‖X_M‖_P.
    pub initial_radius: Option<f64>,
    /// bw̄/(1 − λ): a bound on ‖X_t^{w}‖_P, the disturbance's part of the lifted state in
    /// the metric (reported; the row conditions use the tighter per-row sums).
    pub invariant_radius: Option<f64>,
    /// Every start-up row holds over the user's set.
    pub startup_holds: bool,
    /// The start-up row with the smallest slack.
    pub startup_limit: Option<Limit>,
    /// S: the steps after M over which every full-window row's free response was taken
    /// exactly (Theorem R; the metric bounds the rest; 0 when the budget left none).
    pub exact_steps: usize,
    /// A row of step t = 0 that an admissible realization drives past its bound. Step 0 does
    /// not depend on K: the MHE's window-0 problem (the prior alone) is solved by its warm
    /// start, the prior, so every iterate of every Φ is the prior and x̂₀ = x̄₀ at every K; so
    /// this refutes the set at every K, not only at this one (theory.md, Theorem R, "the
    /// witness").
    pub refuted_at_start: Option<Limit>,
    /// T: the impulse terms summed exactly (the metric's tail bounds the rest; fewer than the
    /// 10⁻⁹ decay length only when the budget left no more).
    pub impulse_terms: usize,
    /// How many of the candidate metrics (`options.rate_fractions`) were evaluated: all that
    /// the budget admits, or one when a witness refutes the set at this K.
    pub metrics_evaluated: usize,
    /// The row (full window or start-up) that an admissible realization of the user's set
    /// drives farthest past its bound in the linear loop, when one is driven past it: then a
    /// constraint certainly activates and no region on which none is active contains the set
    /// at this K (theory.md, Theorem R, "the witness").
    pub witness: Option<Limit>,
    /// Number of constraint rows (full window, start-up).
    pub rows: (usize, usize),
    /// The user's set lies in the certified region.
    pub contains: bool,
    /// The largest factor s such that (s·x0_radius, s·prior_error, s·w̄) is still certified
    /// (the nominal x₀ kept); ≥ 1 iff `contains` (∞ if the set is a point and certified).
    pub margin: Option<f64>,
    /// The largest x0_radius certified with the user's prior_error and w̄ (0 if none).
    pub max_x0_radius: Option<f64>,
    /// The largest prior_error certified with the user's x0_radius and w̄.
    pub max_prior_error: Option<f64>,
    /// The largest w̄ certified with the user's x0_radius and prior_error.
    pub max_w_bar: Option<f64>,
    /// ‖x_read P^{−½}‖: ‖x_t‖ ≤ this·‖X_t‖_P.
    pub x_read_norm: Option<f64>,
    /// ‖e_read P^{−½}‖: ‖e_t‖ ≤ this·‖X_t‖_P.
    pub e_read_norm: Option<f64>,
    /// Certified asymptotic gain from w̄ to sup‖x_t‖: ‖x_read P^{−½}‖·b/(1 − λ).
    pub gain_x: Option<f64>,
    /// Certified asymptotic gain from w̄ to sup‖e_t‖.
    pub gain_e: Option<f64>,
    /// The user's set.
    pub options: RegionalOptions,
}

/// The user's uncertainty and the search settings.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct RegionalOptions {
    /// Nominal x₀ (`simulation.x0`).
    pub x0_nominal: Vec<Option<f64>>,
    /// ‖x₀ − x₀_nominal‖ ≤ this (`certificate.x0_radius`).
    pub x0_radius: Option<f64>,
    /// ‖x̄₀ − x₀‖ ≤ this (`certificate.prior_error`).
    pub prior_error: Option<f64>,
    /// ‖w_t‖₂ ≤ this (`certificate.w_bar`).
    pub w_bar: Option<f64>,
    /// The per-step disturbance set's shape. `Some(r)`: the box |w_i| ≤ (w̄/‖r‖₂)·r_i — at the
    /// default w̄ = ‖r‖₂ the scenario's own noise box, inside the ball ‖w‖₂ ≤ w̄ and up to
    /// √n_w times smaller in a row's worst case; `None`: the ball (`certificate.w_bar`).
    pub w_box: Option<Vec<Option<f64>>>,
    /// Candidate metrics: λ = ρ_lin + (1 − ρ_lin)·f for each f here (Stein equation with
    /// Q = I at the rate λ).
    pub rate_fractions: Vec<Option<f64>>,
    /// Estimated single-core seconds one certificate (or one K_reg search) may take
    /// (`certificate.phase_seconds`; `regional/cost.rs` estimates each stage before it runs).
    pub phase_seconds: Option<f64>,
}

/// What a constraint row constrains.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RowKind {
    /// A component of the point the MHE's projection acts on (box Z = 𝒳 × 𝒲^m).
    MheBox,
    /// A general row of the MHE (𝒳 / 𝒴 on propagated states or outputs).
    MheGeneral,
    /// A row of the MPC's input sequence (exact MPC: −H⁻¹Fx̂ ∈ 𝒰^N, then its predicted-state
    /// rows; K_c-iteration MPC: the point inner iterate `iterate` projects) or of the
    /// saturated LQR.
    Input,
    /// A variant this version of the schema does not know (its Rust name).
    #[serde(untagged)]
    Other(String),
}

/// Which constraint a row is.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct RowLabel {
    /// The kind.
    pub kind: RowKind,
    /// Start-up step t < M, or `None` for the full-window steps t ≥ M.
    pub step: Option<usize>,
    /// Inner iteration j (0 for the input rows).
    pub iterate: usize,
    /// Component of the constrained vector.
    pub index: usize,
}

/// One simple cycle of the gain graph and the product of its gains.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Cycle {
    /// Nodes i₀, i₁, …, i_{L−1}: i₀ takes input from i₁, i₁ from i₂, …, i_{L−1} from i₀
    /// (the smallest node first).
    pub nodes: Vec<usize>,
    /// γ_{i₀,i₁}·γ_{i₁,i₂}·…·γ_{i_{L−1},i₀}.
    pub gain: Option<f64>,
}

/// JSON form of `IossCertificate` (matrices as row-major nested arrays).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct IossReport {
    /// P.
    pub p: Vec<Vec<Option<f64>>>,
    /// η.
    pub eta: Option<f64>,
    /// Q.
    pub q: Vec<Vec<Option<f64>>>,
    /// R.
    pub r: Vec<Vec<Option<f64>>>,
    /// λ_min(P).
    pub p_min_eigenvalue: Option<f64>,
    /// λ_max(P).
    pub p_max_eigenvalue: Option<f64>,
    /// ρ: P must have λ_min(P) > ρ·λ_max(P).
    pub p_min_ratio: Option<f64>,
    /// Largest eigenvalue of the LMI matrix J (unscaled).
    pub lmi_max_eigenvalue: Option<f64>,
    /// μ(P) = max vᵀJv/vᵀSv; null when P is not positive definite.
    pub lmi_relative_violation: Option<f64>,
    /// τ: P passes when μ(P) ≤ τ.
    pub lmi_relative_tolerance: Option<f64>,
    /// All eigenvalues of J, ascending.
    pub lmi_eigenvalues: Vec<Option<f64>>,
    /// Construction method.
    pub method: String,
    /// Iterations of the construction.
    pub iterations: usize,
}

/// What the regional certificate says at one K the caller asked about (`reproduce` asks
/// about 2·K_lin, the issue's target): whether its region contains the scenario's set, and
/// which row limits it there and by how much.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct ProbeNote {
    /// The K.
    pub k: usize,
    /// The region at K contains the scenario's uncertainty.
    pub contains: bool,
    /// The largest certified scale of the scenario's set at K (null: void there).
    pub margin: Option<f64>,
    /// The limiting row(s) and the certified scale, or the void reason.
    pub note: String,
}

/// The certified L_π of the box-constrained condensed MPC and its ingredients.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct LipschitzCertificate {
    /// (b) ‖E₀H^{−1/2}‖₂·‖H^{−1/2}F‖₂: a certified L_π from two norms (≥ `polynomial`).
    pub first_block: Option<f64>,
    /// (a) ‖H^{−1/2}F‖₂/√λ_min(H): also bounds ‖U*(x) − U*(x')‖₂ / ‖x − x'‖.
    pub sequence: Option<f64>,
    /// c = ‖H^{−1/2}F‖₂.
    pub h_inv_sqrt_f: Option<f64>,
    /// ‖E₀H^{−1/2}‖₂ = √λ_max([H⁻¹]₀₀).
    pub e0_h_inv_sqrt: Option<f64>,
    /// λ_min(H).
    pub h_min_eigenvalue: Option<f64>,
    /// ‖E₀H⁻¹F‖₂, the gain of the unconstrained law; a lower bound on L_π when
    /// `origin_interior` holds.
    pub unconstrained_gain: Option<f64>,
    /// 0 lies in the interior of 𝒰 (every lower bound < 0 < every upper bound).
    pub origin_interior: bool,
    /// L_poly ≥ sup_{0 ⪯ M ⪯ I} ‖K_lin + G·M·R‖₂ over the family, or over the partial
    /// enumeration's families (module docs, "Polynomial bound"); equals `unconstrained_gain`
    /// when nothing can saturate.
    pub polynomial: Option<f64>,
    /// s, the number of saturable QP variables (finite bound on at least one side).
    pub saturable: usize,
}

/// Both L_π figures for one MPC (what `cargo xtask certify` prints).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct LipschitzReport {
    /// The certified bound and its ingredients.
    pub certified: LipschitzCertificate,
    /// The sampled estimate with the exact MPC.
    pub sampled: SampledLipschitz,
    /// L_enum (the enumerated bound, ≤ `certified.polynomial`), if the number of saturable
    /// variables s ≤ `ENUMERATION_MAX_VARS`.
    pub enumerated: Option<f64>,
    /// Why L_enum was not computed (None when it was): a named reason, never a silent cap.
    pub enumeration_skipped: Option<String>,
    /// ‖K‖₂ of the saturated LQR for the same (A, B, Q_c, R_c, 𝒰), for comparison.
    pub saturated_lqr: Option<f64>,
    /// Why no certified L_π exists (state constraints:
    /// `crate::STATE_CONSTRAINED_VOID_REASON`); then `LipschitzReport::l_pi` is +∞ and
    /// `certified` describes the input-constrained relaxation only. (Omitted from the
    /// serialised report when absent.)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub void_reason: Option<String>,
}

/// Result of `lipschitz_sampled`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct SampledLipschitz {
    /// max ‖π(x) − π(x')‖/‖x − x'‖ over the pairs (a lower bound on L_π).
    pub estimate: Option<f64>,
    /// The pair attaining the maximum.
    pub worst_x: Vec<Option<f64>>,
    /// Its partner.
    pub worst_x_prime: Vec<Option<f64>>,
    /// Number of pairs (ratios) evaluated.
    pub pairs: usize,
    /// Number of evaluations of π.
    pub evaluations: usize,
    /// Segments on which a switch of π was located by bisection.
    pub switches_located: usize,
    /// Seed of the ChaCha8 generator.
    pub seed: u64,
    /// Sampling radius r.
    pub radius: Option<f64>,
    /// Close-pair distance δ = 10⁻³r.
    pub delta: Option<f64>,
}

/// Which quantity a certificate bounds.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundedQuantity {
    /// ‖zᴷ − z*‖ ≤ φ(K)‖z⁰ − z*‖: exactly eq. (11).
    IterateDistance,
    /// A splitting / auxiliary variable of the method (e.g. ADMM's v = z + u/ρ), not z itself.
    SplittingVariable,
    /// f(zᴷ) − f* (an objective gap), not a distance.
    ObjectiveGap,
}

/// The norm the bound holds in.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CertNorm {
    /// The Euclidean norm of the problem's coordinates (the one eq. (11) uses).
    Euclidean,
    /// A weighted or scaled norm, described in words (e.g. "‖·‖ in the ρ-scaled metric").
    Other(String),
}

/// φ(K) = prefactor · rateᴷ for the stated quantity and norm.
///
/// `fits_eq11` is true only when the bound is on ‖zᴷ − z*‖ in the Euclidean norm of
/// the problem coordinates *and* the K-th iterate is feasible, i.e. when it can be used as
/// φ(K) in the paper's Assumption 5 as is.
///
/// ```
/// use qp_iter::{Certificate, BoundedQuantity, CertNorm};
/// let c = Certificate {
/// rate: 0.98, prefactor: 1.0,
/// quantity: BoundedQuantity::IterateDistance, norm: CertNorm::Euclidean,
/// fits_eq11: true,
/// premise: "H ≻ 0, step 1/L".into(), source: "textbook".into(),
/// };
/// assert!((c.phi(2) - 0.9604).abs() < 1e-12);
/// assert_eq!(c.min_iterations(0.5), Some(35)); // 0.98^35 ≈ 0.4931
/// ```
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct IterationCertificate {
    /// Linear rate r ∈ [0, 1).
    pub rate: Option<f64>,
    /// Prefactor c ≥ 0 (1 for the plain gradient bounds).
    pub prefactor: Option<f64>,
    /// What is bounded.
    pub quantity: BoundedQuantity,
    /// In which norm.
    pub norm: CertNorm,
    /// Usable as φ(K) in eq. (11) as is (see the type's documentation).
    pub fits_eq11: bool,
    /// Premise under which the bound holds.
    pub premise: String,
    /// Where the bound comes from (paper, theorem).
    pub source: String,
}
