//! The library outcomes of version 1: one record per library outcome type, field order
//! = key order (written from the library types by a script, then reviewed).

use serde::Serialize;

use super::Method;

/// Where and how a run first left the bounded rule.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Divergence {
    /// The first step at which a limit failed.
    pub t: usize,
    /// The signal.
    pub signal: Signal,
    /// Its value at t (NaN or ±∞ when non-finite; for a stopped run, the last recorded value).
    pub value: Option<f64>,
    /// The limit it exceeded (∞ for "must be finite").
    pub limit: Option<f64>,
    /// The run stopped early at t (the loop caught a non-finite signal).
    pub stopped: bool,
}

/// The signal whose limit failed first.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Signal {
    /// The estimation error e_t = x_t − x̂_t.
    E,
    /// The plant state x_t.
    X,
    /// The MHE's sub-optimality ε_t.
    Epsilon,
    /// The applied input u_t.
    U,
}

/// Constants and gains of Props. 1 and 3 at one K.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct GainsAtK {
    /// Iteration budget K.
    pub k: usize,
    /// φ(K).
    pub phi: Option<f64>,
    /// C₁(K) = 2φL_Φ(1 + M(‖C‖ + L_π)), eq. (c1).
    pub c1: Option<f64>,
    /// C₂(K) = 2φL_Φ(1 + M L_π), eq. (c2).
    pub c2: Option<f64>,
    /// C₃(K) = 2φL_Φ M, eq. (c3): the coefficient of one unit of change in the u or y data.
    /// The joint certificate's input error δ enters the u data with this coefficient.
    pub c3: Option<f64>,
    /// C₃ʷ(K) = C₃‖F‖₂: the w-coefficient of Prop. 1's one-step bound
    /// (‖y_a − y_b‖ ≤ ‖C‖(‖x_a‖ + ‖x_b‖) + ‖F‖(‖w_a‖ + ‖w_b‖)); the paper's C₃ assumes F = I.
    pub c3w: Option<f64>,
    /// C_e(K), eq. (c4).
    pub c_e: Option<f64>,
    /// C_w(K), eq. (c5) with C₃ʷ in place of C₃.
    pub c_w: Option<f64>,
    /// C_ε(K), eq. (c6).
    pub c_eps: Option<f64>,
    /// γ₂,₁ = C₁/(1 − φ) (Prop. 1).
    pub gamma21: Option<f64>,
    /// γ₂,₃ = C₂/(1 − φ) (Prop. 1).
    pub gamma23: Option<f64>,
    /// γ₂ʷ = C₃ʷ/(1 − φ) (Prop. 1; C₃ʷ = C₃‖F‖).
    pub gamma2w: Option<f64>,
    /// γ₂^σ = φL_Φ/(1 − φ) (Prop. 1).
    pub gamma2sigma: Option<f64>,
    /// γ₃,₁ = √(2Λ^H̄_P) C₁ (Prop. 3).
    pub gamma31: Option<f64>,
    /// γ₃,₂ = C_ε (Prop. 3).
    pub gamma32: Option<f64>,
    /// γ₃ʷ = C_w (Prop. 3).
    pub gamma3w: Option<f64>,
    /// γ₃^σ = √(2Λ^H̄_P) φ L_Φ (Prop. 3).
    pub gamma3sigma: Option<f64>,
    /// Slope of γ₁,₃ ∘ γ₃,₁ (sg1).
    pub sg1: Option<f64>,
    /// Slope of γ₂,₃ ∘ γ₃,₂ (sg2).
    pub sg2: Option<f64>,
    /// Slope of γ₁,₃ ∘ γ₃,₂ ∘ γ₂,₁ (sg3).
    pub sg3: Option<f64>,
    /// The paper's conditions as printed: every slope (sg1)–(sg3) < 1 (the small-gain theorem
    /// for max-form estimates; necessary, not sufficient for the sum-form estimates of
    /// Props. 1 and 3, see `crate::small_gain`).
    pub paper_conditions: bool,
    /// 1 − (sg1 + sg2 + sg3) = det(I − Γ) of the three-node gain matrix (every cycle passes
    /// through e): positive iff ρ(Γ) < 1, the small-gain condition of the sum-form
    /// estimates. The certified ISS margin (> 0 iff certified at this K).
    pub margin: Option<f64>,
    /// All premises hold and ρ(Γ) < 1 (margin > 0, which implies every slope < 1).
    pub certified: bool,
}

/// Theorem 1 evaluated for one set of inputs.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct IssAnalysis {
    /// The inputs.
    pub inputs: IssInputs,
    /// ρ = 6^{1/M} η (ρ^M = 6η^M, Prop. 3).
    pub rho: Option<f64>,
    /// Λ^P_P = λ_max(P)/λ_min(P).
    pub lambda_pp: Option<f64>,
    /// Λ^Q_P = λ_max(Q)/λ_min(P).
    pub lambda_qp: Option<f64>,
    /// Λ^H̄_P = H̄/λ_min(P).
    pub lambda_hp: Option<f64>,
    /// L_Φ used in the constants: max(L_Φ, 1) (Lemma 1 requires L_Φ > 1).
    pub l_phi_used: Option<f64>,
    /// Premises with pass/fail and margins.
    pub premises: Vec<Premise>,
}

/// Scalar inputs of Theorem 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct IssInputs {
    /// MHE horizon M ≥ 1.
    pub horizon: usize,
    /// η ∈ [0, 1) of Assumption 2.
    pub eta: Option<f64>,
    /// λ_min(P), λ_max(P) of the δ-IOSS certificate.
    pub p_min: Option<f64>,
    /// λ_max(P).
    pub p_max: Option<f64>,
    /// λ_max(Q).
    pub q_max: Option<f64>,
    /// H̄ = sup_t λ_max(H_t) in the coordinates ε_t is measured in (Prop. 2).
    pub h_bar: Option<f64>,
    /// L_Φ of Lemma 1 (before raising to 1).
    pub l_phi: Option<f64>,
    /// L_π of Assumption 3.
    pub l_pi: Option<f64>,
    /// ‖C‖₂.
    pub c_norm: Option<f64>,
    /// ‖F‖₂ (y = Cx + Fw²): the measurement noise enters the MHE's data through F, so every
    /// gain from w through the window data carries it (C₃ʷ = C₃‖F‖).
    pub f_norm: Option<f64>,
    /// γ₁,₃ slope of Assumption 4 (gain from estimation error to state).
    pub gamma13: Option<f64>,
    /// φ(K) = prefactor · rateᴷ.
    pub phi_rate: Option<f64>,
    /// Prefactor of φ(K).
    pub phi_prefactor: Option<f64>,
    /// Whether the solver's certificate bounds ‖zᴷ − z*‖ in the coordinates of ε_t with a
    /// feasible iterate (eq. 11 as is).
    pub phi_fits_eq11: bool,
    /// Whether LMI (2) was certified for (η, P, Q, R).
    pub lmi_certified: bool,
}

/// One premise of Theorem 1, evaluated.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Premise {
    /// Short name, e.g. `"rho < 1"`.
    pub name: String,
    /// Where the paper needs it.
    pub needed_by: String,
    /// Whether it holds.
    pub holds: bool,
    /// The value tested.
    pub value: Option<f64>,
    /// Signed margin (positive when it holds), e.g. 1 − ρ.
    pub margin: Option<f64>,
    /// What to change when it fails (empty when it holds or was not evaluated).
    pub fix: String,
    /// Set when the premise could not be evaluated because a premise it depends on failed
    /// (e.g. φ and L_Φ are properties of the MHE's QP, which is built from P of LMI (2)):
    /// the reason, naming that premise. The premise then counts as not holding, and its own
    /// advice is not given (one failure, one reason).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_evaluated: Option<String>,
}

/// The certified asymptotic gains of Theorem 1 at one K (module docs).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct AsymptoticGains {
    /// The iteration budget K.
    pub k: usize,
    /// φ(K).
    pub phi: Option<f64>,
    /// g_x: lim sup‖x_t‖ ≤ g_x·w̄.
    pub gain_x: Option<f64>,
    /// g_ε: lim sup ε_t ≤ g_ε·w̄.
    pub gain_epsilon: Option<f64>,
    /// g_e: lim sup‖e_t‖ ≤ g_e·w̄.
    pub gain_e: Option<f64>,
    /// The lim-sup comparison system Γ̃, g̃ whose solution the three gains are.
    pub limsup: ComparisonSystem,
    /// The same argument with Theorem 1's gain matrix Γ (γ₁,₃, γ₂,₁, γ₂,₃, γ₃,₁, γ₃,₂) and
    /// w-gains (γ₁ʷ, γ₂ʷ, γ₃ʷ = C_w): a larger, equally valid bound, for comparison.
    pub theorem1: ComparisonSystem,
    /// a_w = √(6Λ^Q_P S_η/(1 − ρ^M)): the direct gain from w̄ to lim sup‖e‖ (Prop. 2).
    pub e_from_w: Option<f64>,
    /// a_ε = √(2Λ^H̄_P/(1 − ρ^M)): the gain from lim sup ε to lim sup‖e‖ (Prop. 2).
    pub e_from_epsilon: Option<f64>,
    /// γ₁,₃ used (Assumption 4).
    pub gamma13: Option<f64>,
    /// γ₁ʷ used (Assumption 4, the same estimate as γ₁,₃).
    pub gamma1w: Option<f64>,
}

/// A nonnegative comparison system s ≤ Γs + g·w̄ on the nodes (x, ε, e) and its solution.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct ComparisonSystem {
    /// Γ, row-major: `matrix[i][j]` is the gain from node j into node i (`NODES`).
    pub matrix: Vec<Vec<Option<f64>>>,
    /// g: the gain from w̄ into each node.
    pub input: Vec<Option<f64>>,
    /// ρ(Γ) (< 1 whenever a solution is reported).
    pub spectral_radius: Option<f64>,
    /// (I − Γ)⁻¹g: (g_x, g_ε, g_e).
    pub gains: Vec<Option<f64>>,
}

/// The measured counterparts of `AsymptoticGains` on one simulated run.
///
/// The estimator: with w̄_run = sup_{0 ≤ t < T}‖w_t‖₂ (the run's own disturbance level) and
/// the tail t ≥ ⌊T/2⌋, ĝ_e = sup_{t ≥ T/2}‖e_t‖/w̄_run and ĝ_x = sup_{t ≥ T/2}‖x_t‖/w̄_run (x_T
/// included). The true asymptotic gain γ_e = sup over disturbance sequences in 𝒲 of
/// lim sup‖e_t‖/‖w‖_∞ is at least this run's lim sup‖e_t‖/w̄_run; once the transient has
/// decayed by T/2, the tail sup is a sample of that lim sup (one sequence, a finite window),
/// so ĝ ≤ γ ≤ g (certified) — a lower estimate. While the transient has not decayed, the tail
/// sup can exceed it (the certified bound is asymptotic), which the whole-run sups beside it
/// help to see.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct MeasuredGains {
    /// Steps T of the run.
    pub steps: usize,
    /// First step of the tail, ⌊T/2⌋.
    pub tail_from: usize,
    /// w̄_run = sup_t ‖w_t‖₂ over the whole run.
    pub w_sup: Option<f64>,
    /// sup_{t ≥ T/2}‖e_t‖.
    pub e_tail_sup: Option<f64>,
    /// sup_{t ≥ T/2}‖x_t‖ (x_T included).
    pub x_tail_sup: Option<f64>,
    /// sup_{t ≥ T/2} ε_t (None when ε_t was not recorded).
    pub epsilon_tail_sup: Option<f64>,
    /// sup_t ‖e_t‖ over the whole run.
    pub e_sup: Option<f64>,
    /// sup_t ‖x_t‖ over the whole run.
    pub x_sup: Option<f64>,
    /// ĝ_e = e_tail_sup / w_sup (None when w_sup = 0: no disturbance, no gain to measure).
    pub gain_e: Option<f64>,
    /// ĝ_x = x_tail_sup / w_sup.
    pub gain_x: Option<f64>,
    /// ĝ_ε = epsilon_tail_sup / w_sup.
    pub gain_epsilon: Option<f64>,
    /// sup_t‖e_t‖ / w_sup over the whole run (transient included).
    pub gain_e_whole_run: Option<f64>,
    /// sup_t‖x_t‖ / w_sup over the whole run (transient included).
    pub gain_x_whole_run: Option<f64>,
}

/// A result the analysis budget stopped (issue 37 item 6): *not computed within the
/// budget*, never "void" — a void certificate is a proof that no K works, this is not. The
/// estimate is the one the phase was skipped by (its plan, before it ran), so raising
/// `certificate.phase_seconds` to `NotComputed::raise_to` runs it.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct NotComputed {
    /// The phase that was not run (`"γ₁,₃ free-set enumeration"`).
    pub phase: String,
    /// Its estimated seconds of one core (from the dimensions, before it ran).
    pub needed_seconds: Option<f64>,
    /// The budget it exceeded (`certificate.phase_seconds`).
    pub budget_seconds: Option<f64>,
}

/// Everything `certify_closed_loop` computes.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct ClosedLoopCertificate {
    /// Scenario name.
    pub scenario: String,
    /// MHE horizon M.
    pub horizon: usize,
    /// η.
    pub eta: Option<f64>,
    /// ρ = 6^{1/M}η.
    pub rho: Option<f64>,
    /// The δ-IOSS certificate (None when LMI (2) is infeasible).
    pub ioss: Option<IossReport>,
    /// Why LMI (2) failed (None when it holds).
    pub ioss_failure: Option<String>,
    /// λ_min(P), λ_max(P), λ_max(Q).
    pub p_min: Option<f64>,
    /// λ_max(P).
    pub p_max: Option<f64>,
    /// λ_max(Q).
    pub q_max: Option<f64>,
    /// H̄ (NaN when the MHE could not be built).
    pub h_bar: Option<f64>,
    /// ‖C‖₂.
    pub c_norm: Option<f64>,
    /// L_Φ.
    pub l_phi: LPhiReport,
    /// L_π report (certified, enumerated, sampled).
    pub l_pi: LipschitzReport,
    /// L_π used (tightest certified bound).
    pub l_pi_used: Option<f64>,
    /// γ₁,₃.
    pub gamma13: Gamma13Report,
    /// One certificate per solver.
    pub solvers: Vec<SolverCertificate>,
    /// Nearest parameters satisfying ρ < 1.
    pub nearest: NearestParameters,
    /// ‖H_t‖₂ of the paper's weight (eq. 10) per window length m = 0..M, for σ_t.
    pub h_paper_norms: Vec<Option<f64>>,
    /// ‖A‖₂ + ‖B‖₂ + ‖C‖₂ + 2: the model part of σ_t.
    pub sigma_model_part: Option<f64>,
    /// o_m ≥ ‖z*_m(0)‖ per window length m = 0..M (0 when 0 ∈ Z): the offsets of the mended
    /// Lemma 1 for t ≤ M (`lemma1`), which replaces the paper's σ_t in the trajectory checks.
    pub lemma1_origin_offsets: Vec<Option<f64>>,
}

/// L_Φ figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct LPhiReport {
    /// max_m certified bound (used in the certificate).
    pub certified: Option<f64>,
    /// max_m sampled estimate (a lower bound on the true constant).
    pub sampled: Option<f64>,
    /// Per window length m = 0..M: (certified, sampled).
    pub per_window: Vec<(Option<f64>, Option<f64>)>,
    /// Why fewer pairs than `lipschitz_pairs` were sampled (the analysis budget,
    /// `crate::budget::l_phi_sampling_pairs`); omitted when every pair was sampled.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pairs_reduced: Option<String>,
}

/// Parameters near the scenario's that satisfy ρ < 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct NearestParameters {
    /// Smallest M with 6η^M < 1 at the scenario's η.
    pub min_horizon_at_eta: Option<usize>,
    /// η must be below 6^{−1/M} at the scenario's M.
    pub eta_sup_at_horizon: Option<f64>,
}

/// Certificate of one solver Φ.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct SolverCertificate {
    /// The solver.
    pub solver: Method,
    /// φ(K) = prefactor · rateᴷ, worst over window lengths.
    pub phi_rate: Option<f64>,
    /// Prefactor of φ(K).
    pub phi_prefactor: Option<f64>,
    /// Whether every window's certificate fits eq. (11).
    pub fits_eq11: bool,
    /// The per-window certificates (m = 0..M).
    pub per_window: Vec<IterationCertificate>,
    /// Theorem 1 with these constants (premises included).
    pub analysis: IssAnalysis,
    /// Smallest certified K (None when void or beyond `k_max`).
    pub k_min: Option<usize>,
    /// Constants and slopes at K_min.
    pub at_k_min: Option<GainsAtK>,
    /// Why there is no K_min (empty when there is one, and when it was not computed).
    pub void_reasons: Vec<String>,
    /// No K_min, and not void either: the analysis budget stopped a phase whose result
    /// could change the verdict (the γ₁,₃ free-set enumeration; issue 37 item 6). The
    /// verdict is "not computed within the budget", with the `certificate.phase_seconds`
    /// that computes it. Omitted otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_computed: Option<NotComputed>,
    /// K_min with the *sampled* L_Φ in place of the certified bound — not a certificate,
    /// reported to show how much of K_min is due to L_Φ's conservatism.
    pub k_min_with_sampled_l_phi: Option<usize>,
}

/// Result of `check_trajectory` for one proposition.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct InequalityCheck {
    /// The inequality held at every t.
    pub holds: bool,
    /// max over t ≥ 1 of lhs/rhs (≤ 1 when it holds; t = 0 is trivially tight for Prop. 1).
    pub worst_ratio: Option<f64>,
    /// Time of the worst ratio.
    pub worst_t: usize,
    /// First t where it failed, if any.
    pub first_violation: Option<usize>,
    /// Steps at which lhs exceeded rhs but not rhs + the rounding floor
    /// (`super::rounding_floor`): the measured side was floating-point rounding there.
    pub within_rounding_floor: usize,
    /// Largest rounding floor used at such a step (0 when none).
    pub max_rounding_floor: Option<f64>,
}

/// Prop. 1 and Prop. 3 evaluated on a trace.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct TrajectoryCheck {
    /// ‖ε_t‖ ≤ φᵗε₀ + γ₂,₁‖x‖ + γ₂,₃‖e‖ + γ₂ʷ‖w‖ + γ₂^σ‖σ‖ (sups over [0, t−1]; σ over
    /// [0, t], the data-dependent σ_t of `super::lemma1`).
    pub prop1: InequalityCheck,
    /// ‖e_t‖ ≤ C_e√ρᵗ‖e₀‖ + √(2Λ^H̄_P)C₁‖x‖ + C_ε‖ε‖ + C_w‖w‖ + √(2Λ^H̄_P)φL_Φ‖σ‖.
    pub prop3: InequalityCheck,
    /// Where the run first left the bounded rule (`closed_loop::bounded`; None: bounded).
    pub divergence: Option<Divergence>,
}

/// The certificates a configuration can be under (exhaustive on purpose, as `Applicable`).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CertificateKind {
    /// Theorem 1: the sub-optimal MHE with the exact MPC.
    Theorem1,
    /// The joint certificate: the sub-optimal MHE with the K_c-iteration MPC.
    Joint,
    /// A library variant this schema version does not name, by its Rust name (the library of
    /// this version produces none; a reader treats it as "not certified").
    Other(String),
}

/// `yes`, `no`, `void` or `not_computed` at a pair. Exhaustive on purpose: a verdict the
/// caller does not know must not fall into a default arm (export refuses on anything but yes).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Certified {
    /// The certificate holds at this pair.
    Yes,
    /// It applies and its premises hold, but not at this pair (too few iterations).
    No,
    /// No certificate at any pair: a premise fails, or none covers the configuration.
    Void,
    /// The analysis budget (`certificate.phase_seconds`) cut the verdict: not proved void,
    /// not computed (the reason names the phase and the budget that would compute it).
    NotComputed,
    /// A library variant this schema version does not name, by its Rust name (the library of
    /// this version produces none; a reader treats it as "not certified").
    Other(String),
}

/// Which certificate covers a configuration, or why none does: covered or not, exhaustive on
/// purpose.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Coverage {
    /// This certificate applies (it may still be void for these parameters).
    Covered(CertificateKind),
    /// No certificate covers the configuration: the reason names the scenario key.
    Uncovered(String),
    /// A library variant this schema version does not name, by its Rust name (the library of
    /// this version produces none; a reader treats it as "not certified").
    Other(String),
}

/// The verdict at one pair (K_e, K_c).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct PairVerdict {
    /// The covering certificate (None: uncovered).
    pub certificate: Option<CertificateKind>,
    /// The verdict.
    pub certified: Certified,
    /// Smallest certified K_e at this K_c (Theorem 1: K_min; joint: at the pair's K_c).
    pub k_min: Option<usize>,
    /// The certified margin at the pair (1 − ρ(Γ)); None where undefined.
    pub margin: Option<f64>,
    /// Why void (empty otherwise).
    pub reason: String,
}

/// Result of `gamma13_certified`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Gamma13Certificate {
    /// Certified γ₁,₃: the smallest over metrics and methods; ∞ when void.
    pub gamma13: Option<f64>,
    /// The bound that gave it (None when void).
    pub method: Option<Gamma13Method>,
    /// The metric that gave it (None when void).
    pub metric: Option<String>,
    /// Leading input blocks whose saturation pattern is enumerated exactly in the family
    /// bound (partial enumeration; 0: the single family).
    pub pattern_blocks: usize,
    /// Number of families of the partial enumeration (0 when `pattern_blocks` = 0).
    pub pattern_families: usize,
    /// Smallest γ₁,₃ over metrics from the family bounds (∞ if none contracts).
    pub gamma13_polynomial: Option<f64>,
    /// Smallest γ₁,₃ over the enumerated metrics from the free-set maxima (when enumerated).
    pub gamma13_enumerated: Option<f64>,
    /// Impulse-response γ₁,₃ of the linear law (when s = 0 and the loop is stable).
    pub gamma13_linear: Option<f64>,
    /// γ₁,₄: the gain from an additive input error d to x in the *same* estimate as
    /// `gamma13` (same metric, or the impulse response Σ‖A_clᵏB‖₂ for the linear law); ∞
    /// when void. Used by the joint MPC + MHE certificate (`crate::joint`).
    pub gamma14: Option<f64>,
    /// γ₁ʷ of the same estimate (∞ when void).
    pub gamma1w: Option<f64>,
    /// β₁(s, t) = `beta_prefactor`·`beta_rate`ᵗ·s of the same estimate (NaN when void).
    pub beta_prefactor: Option<f64>,
    /// See `beta_prefactor`.
    pub beta_rate: Option<f64>,
    /// Every candidate's figures.
    pub candidates: Vec<MetricResult>,
    /// N·n_u.
    pub variables: usize,
    /// s, the saturable variables.
    pub saturable: usize,
    /// Free sets enumerated (2^s when `enumerated`, else 0).
    pub free_sets: u64,
    /// Whether the free sets were enumerated.
    pub enumerated: bool,
    /// Why there is no γ₁,₃ (None when certified).
    pub void: Option<Gamma13Void>,
    /// Computations not run, with the reason.
    pub skipped: Vec<SkippedComputation>,
    /// The free-set enumeration skipped for the analysis budget (not for the cap on s): a
    /// verdict the enumeration could change is "not computed within the budget", not void.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub over_budget: Option<NotComputed>,
}

/// Which bound gave the certified γ₁,₃.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Gamma13Method {
    /// The S-procedure over the whole family 0 ⪯ M ⪯ I (any size).
    Polynomial,
    /// The maximum over the 2^s free sets (small s).
    Enumerated,
    /// 𝒰 = ℝ^{n_u}: the impulse-response sum of the linear closed loop.
    Linear,
    /// A variant this version of the schema does not know (its Rust name).
    #[serde(untagged)]
    Other(String),
}

/// Why no γ₁,₃ is available: a typed reason with a `std::fmt::Display` sentence.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Gamma13Void {
    /// 0 ∉ 𝒰: π(0) need not be 0, so the origin is not an equilibrium.
    OriginOutsideInputSet,
    /// With every bounded input saturated, x⁺ = A_sat·x + const with ρ(A_sat) ≥ 1; A_sat = A
    /// when 𝒰 is bounded. Every local-gain family contains this gain, so no metric contracts;
    /// with 𝒰 bounded and ρ(A) > 1 no global gain exists at all (the unstable mode grows from
    /// large states whatever u ∈ 𝒰).
    SaturatedDynamicsNotStable {
        /// ρ(A_sat) = max |λ|.
        spectral_radius: Option<f64>,
        /// Every input component has two finite bounds (so A_sat = A).
        input_bounded: bool,
        /// ρ(A_sat) = 1 exactly (every eigenvalue in the closed unit disc, some on the circle:
        /// Jordan chains allowed), decided from the structure of A_sat
        /// (`lti_model::spectral::classify`), not from rounded eigenvalue moduli.
        marginal: bool,
    },
    /// Every candidate metric has λ_S ≥ 1.
    NoContractingMetric {
        /// The smallest λ_S found.
        best_contraction: Option<f64>,
        /// The metric that achieved it.
        metric: String,
        /// Whether the 2^s free sets were enumerated (else the family bounds only).
        enumerated: bool,
        /// Leading input blocks enumerated exactly in the family bound.
        pattern_blocks: usize,
    },
    /// The MPC has state constraints: the analysis assumes box-constrained inputs only
    /// (issue 15), so no certified γ₁,₃ exists.
    StateConstrainedMpc,
    /// The MPC has output constraints C x_k ∈ 𝒴_c (`mpc.output`) and no state constraints:
    /// the same box-input-only analysis does not apply, so no certified γ₁,₃ exists.
    OutputConstrainedMpc,
    /// No metric contracts by the family bound, and the free-set enumeration that could
    /// find one was not run for the analysis budget: not computed, not void (issue 37).
    NotComputedWithinBudget {
        /// The smallest λ_S of the family bounds.
        best_contraction: Option<f64>,
        /// The skipped enumeration, its estimate and the budget.
        not_computed: NotComputed,
    },
    /// A user value below the sampled lower estimate: provably not a valid γ₁,₃.
    UserValueRefuted {
        /// The value supplied.
        user: Option<f64>,
        /// The sampled lower estimate that exceeds it.
        sampled_lower: Option<f64>,
    },
    /// A reason this version of the schema does not know (its sentence).
    #[serde(untagged)]
    Other(String),
}

/// One candidate metric S and its contraction figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct MetricResult {
    /// Which S (`"identity"`, `"dare-terminal"`, `"open-loop-lyapunov"`, `"robust-riccati(λ=…)"`, …).
    pub metric: String,
    /// λ_S = sup over the family of ‖A + BK(M)‖_S (S-procedure).
    pub contraction: Option<f64>,
    /// g_S = sup over the family of ‖S^{½}BK(M)‖₂ (S-procedure); ∞ (not computed) when
    /// λ_S ≥ 1.
    pub input_gain: Option<f64>,
    /// max over the 2^s free sets of ‖A + BK_𝔽‖_S (when enumerated; a lower bound ≥ 1 once
    /// it reaches 1, because the enumeration drops the metric there).
    pub contraction_enumerated: Option<f64>,
    /// max over the 2^s free sets of ‖S^{½}BK_𝔽‖₂ (when enumerated and the metric contracts
    /// there; None when the enumeration dropped it at λ ≥ 1).
    pub input_gain_enumerated: Option<f64>,
    /// √(λ̄(S)/λ(S)): prefactor of β₁.
    pub condition_sqrt: Option<f64>,
    /// γ₁,₃ = g_S/(√λ(S)(1 − λ_S)) from the family, or ∞ when λ_S ≥ 1.
    pub gamma13_polynomial: Option<f64>,
    /// The same from the enumerated figures (when enumerated).
    pub gamma13_enumerated: Option<f64>,
    /// min of the two: this metric's certified γ₁,₃.
    pub gamma13: Option<f64>,
    /// γ₁ʷ = ‖S^{½}E‖₂/(√λ(S)(1 − λ_S)) for the λ_S used in `gamma13`, or ∞ (w¹ enters as
    /// Ew¹; with the paper's E = I this is √(λ̄(S)/λ(S))/(1 − λ_S)).
    pub gamma1w: Option<f64>,
    /// ‖S^{½}B‖₂: how an additive input error d (x⁺ = Ax + Bπ(x + e) + Bd + w¹) enters.
    pub input_matrix_gain: Option<f64>,
    /// γ₁,₄ = ‖S^{½}B‖₂/(√λ(S)(1 − λ_S)) with the λ_S of `gamma13`: the gain from d to x
    /// in the same estimate as γ₁,₃ (the sub-optimal MPC's error, `crate::joint`), or ∞.
    pub gamma14: Option<f64>,
    /// Why gains of this metric are not computed (null in JSON) because it does not contract
    /// (λ_S ≥ 1); None when every figure is computed.
    pub not_computed: Option<String>,
}

/// A computation that was not run, and why (never a silent cap).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct SkippedComputation {
    /// What was not computed.
    pub computation: String,
    /// Why, and what is used instead.
    pub reason: String,
}

/// γ₁,₃ figures of the certificate.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Gamma13Report {
    /// The value used in the certificate (∞ when void).
    pub used: Option<f64>,
    /// `"certified"` or `"user-supplied, not verified"`.
    pub source: String,
    /// The user's value, when supplied.
    pub user: Option<f64>,
    /// The contraction certificate (when computed).
    pub certified: Option<Gamma13Certificate>,
    /// Sampled lower estimate (when computed).
    pub sampled: Option<Gamma13Sampled>,
    /// Why `used` is ∞ (None otherwise).
    pub void: Option<Gamma13Void>,
    /// Computations not run, with the reason.
    pub skipped: Vec<SkippedComputation>,
}

/// Result of `gamma13_sampled`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Gamma13Sampled {
    /// max over sequences of sup‖x_t‖/sup‖e_t‖ (a lower bound on any valid linear γ₁,₃).
    pub gamma13_lower: Option<f64>,
    /// Number of injected sequences.
    pub sequences: usize,
    /// Steps per sequence.
    pub steps: usize,
    /// Seed.
    pub seed: u64,
}

/// The joint certificate for one MHE method and one MPC method.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct JointCertificate {
    /// The MHE's method Φ_e.
    pub mhe_method: Method,
    /// The MPC's method Φ_c.
    pub mpc_method: Method,
    /// The MPC's warm start rule.
    pub warm_start: String,
    /// What `region.cost_per_iteration` measures.
    pub cost_model: String,
    /// The four-node analysis (inputs, premises).
    pub analysis: JointAnalysis,
    /// Certified region, Pareto front and cheapest pair.
    pub region: JointRegion,
    /// Gains at the cheapest pair.
    pub at_cheapest: Option<JointGains>,
    /// β₁ = (prefactor, rate) and γ₁ʷ of the plant estimate (for the trajectory checks).
    pub plant_beta: (Option<f64>, Option<f64>),
    /// γ₁ʷ of the plant estimate.
    pub gamma1w: Option<f64>,
}

/// The four-node small-gain analysis (module docs of `crate::joint`).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct JointAnalysis {
    /// The inputs.
    pub inputs: JointInputs,
    /// Theorem 1's analysis of the MHE side (constants of Props. 1 and 3).
    pub theorem1: IssAnalysis,
    /// Every K-independent premise: Theorem 1's and the MPC side's.
    pub premises: Vec<Premise>,
}

/// Gains, cycles and the verdict at one pair (K_e, K_c).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct JointGains {
    /// MHE iterations per step.
    pub k_e: usize,
    /// MPC iterations per step.
    pub k_c: usize,
    /// Props. 1 and 3 at K_e (C₁…C₆, γ₂,·, γ₃,·; its `margin` is Theorem 1's, not this one).
    pub mhe: GainsAtK,
    /// φ_c(K_c).
    pub phi_c: Option<f64>,
    /// φ_c(K_c)·ω: the contraction of δ_t (must be < 1).
    pub delta_rate: Option<f64>,
    /// γ₁,₃ (e → x).
    pub gamma13: Option<f64>,
    /// γ₁,₄ (δ → x).
    pub gamma14: Option<f64>,
    /// γ₂,₄ = C₃/(1 − φ_e) (δ → ε).
    pub gamma24: Option<f64>,
    /// γ₃,₄ = √(2Λ^H̄_P)·C₃ (δ → e).
    pub gamma34: Option<f64>,
    /// γ₄,₁ = φ_c L_U (1 + ω)/(1 − φ_c ω) (x → δ).
    pub gamma41: Option<f64>,
    /// γ₄,₃ = γ₄,₁ (e → δ).
    pub gamma43: Option<f64>,
    /// Γ row-major (4 × 4, row i: gains into node i; nodes `NODE_NAMES`).
    pub matrix: Vec<Option<f64>>,
    /// Every simple cycle and its gain.
    pub cycles: Vec<Cycle>,
    /// Every cycle gain < 1 (the max-form condition; necessary).
    pub cycles_hold: bool,
    /// ρ(Γ).
    pub spectral_radius: Option<f64>,
    /// 1 − ρ(Γ): the certified margin (> 0 iff certified, premises holding).
    pub margin: Option<f64>,
    /// Premises hold, φ_e(K_e) < 1, φ_c ω < 1 and ρ(Γ) < 1.
    pub certified: bool,
}

/// Inputs of the joint certificate.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct JointInputs {
    /// Theorem 1's inputs for the MHE side (φ_e of the MHE's map).
    pub mhe: IssInputs,
    /// γ₁,₄: gain from the MPC's input error d to x, from the same estimate as γ₁,₃.
    pub gamma14: Option<f64>,
    /// The MPC side.
    pub mpc: MpcMapInputs,
}

/// Constants of the sub-optimal MPC (node 4).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct MpcMapInputs {
    /// L_U: Lipschitz constant of x ↦ U*(x), the whole optimal input sequence.
    pub l_u: Option<f64>,
    /// φ_c(K) = prefactor · rateᴷ of the MPC's iteration map.
    pub phi_rate: Option<f64>,
    /// Prefactor of φ_c.
    pub phi_prefactor: Option<f64>,
    /// φ_c bounds ‖Uᴷ − U*‖ in the Euclidean norm with a feasible iterate (eq. (11) for the
    /// MPC's QP).
    pub phi_fits_eq11: bool,
    /// ω = ‖W‖₂ of the warm start U⁰_t = W Uᴷᶜ_{t−1}.
    pub warm_gain: Option<f64>,
    /// The warm start rule, for display.
    pub warm_start: String,
    /// U*(0) = 0 (0 ∈ 𝒰^N and the MPC's QP has no constant linear term).
    pub origin_fixed: bool,
}

/// The certified region {(K_e, K_c) : certified} (an up-set: every larger pair is certified).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct JointRegion {
    /// Largest K_e and K_c searched.
    pub k_max: usize,
    /// Smallest K_e certified with some K_c ≤ `k_max` (the limit of an exact MPC).
    pub k_e_floor: Option<usize>,
    /// Smallest K_c certified with some K_e ≤ `k_max` (the limit of an exact MHE).
    pub k_c_floor: Option<usize>,
    /// The corners of the staircase boundary, K_e increasing, K_c decreasing: (K_e, K_c) is
    /// certified, (K_e − 1, K_c) and (K_e, K_c − 1) are not. These are the Pareto-optimal
    /// pairs.
    pub pareto: Vec<RegionPoint>,
    /// Cost per MHE iteration t_e and per MPC iteration t_c used for `cheapest`.
    pub cost_per_iteration: (Option<f64>, Option<f64>),
    /// The pair minimising K_e·t_e + K_c·t_c (a Pareto corner; the smallest K_e on ties).
    pub cheapest: Option<RegionPoint>,
    /// Why the region is empty (empty when it is not).
    pub void_reasons: Vec<String>,
}

/// One pair (K_e, K_c).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct RegionPoint {
    /// MHE iterations per step.
    pub k_e: usize,
    /// MPC iterations per step.
    pub k_c: usize,
}

/// The four subsystem estimates and the one-step inequality of δ_t on one trace.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct JointTrajectoryCheck {
    /// ‖x_t‖ ≤ β₁(‖x₀‖, t) + γ₁,₃‖e‖ + γ₁,₄‖δ‖ + γ₁ʷ‖w‖ (sups over [0, t−1]).
    pub plant: InequalityCheck,
    /// Prop. 1 with the δ term: ‖ε_t‖ ≤ φ_eᵗε₀ + γ₂,₁‖x‖ + γ₂,₃‖e‖ + γ₂ʷ‖w‖ + γ₂,₄‖δ‖ + γ₂^σ‖σ‖.
    pub prop1: InequalityCheck,
    /// Prop. 3 with the δ term: ‖e_t‖ ≤ C_e√ρᵗ‖e₀‖ + √(2Λ^H̄_P)C₁‖x‖ + C_ε‖ε‖ + C_w‖w‖ + γ₃,₄‖δ‖ + γ₃^σ‖σ‖.
    pub prop3: InequalityCheck,
    /// δ_t ≤ φ_c(ωδ_{t−1} + ωL_U‖x̂_{t−1}‖ + L_U‖x̂_t‖) (t ≥ 1), δ₀ ≤ φ_c L_U‖x̂₀‖.
    pub delta_step: InequalityCheck,
    /// δ_t ≤ (φ_cω)ᵗδ₀ + γ₄,₁ sup_{0…t}‖x‖ + γ₄,₃ sup_{0…t}‖e‖.
    pub delta: InequalityCheck,
    /// max_t ‖u_t − π(x̂_t)‖/δ_t − 1 ≤ 0: the applied input error is bounded by δ_t (d_t is the
    /// first block of Uᴷᶜ_t − U*(x̂_t)).
    pub input_error: InequalityCheck,
    /// Where the run first left the bounded rule (`closed_loop::bounded`; None: bounded).
    pub divergence: Option<Divergence>,
}

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
    /// μ(P) = max vᵀJv/vᵀSv; null (NaN) when P is not positive definite.
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
