//! γ₁,₃ and the joint MPC + MHE certificate.

use serde::Serialize;

#[allow(unused_imports)]
use super::*;

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
#[non_exhaustive]
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
    /// The rounding's self-loop on e in a rounded scalar (Γ's diagonal entry at e; 0 in
    /// exact arithmetic).
    pub self_loop: Option<f64>,
    /// The constant the rounding adds to δ's bound, C_d/(1 − Φ_uω) (0 in exact arithmetic):
    /// the certificate is then ISS up to this offset.
    pub delta_offset: Option<f64>,
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
