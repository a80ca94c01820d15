//! Theorem 1's outcomes: the closed-loop certificate, its premises, gains, trajectory
//! checks and the verdict at a pair.

use serde::Serialize;

#[allow(unused_imports)]
use super::*;

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
    /// The global loop certificate (Theorem L3; Theorem L3u in f32): every K ≥ K_glob.
    Global,
    /// The iteration chain (Theorem L3b, f64): the K it was checked at and certified.
    Chain,
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
