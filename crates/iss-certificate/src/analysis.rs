//! The ISS certificate of Theorem 1: constants C₁…C₆(K) of the appendix, the gains of
//! Props. 1 and 3, the small-gain slopes (sg1)–(sg3) and the smallest certified K.
//!
//! Everything here is scalar arithmetic on constants computed elsewhere (the δ-IOSS P, H̄,
//! L_Φ, L_π, φ(K), γ₁,₃), kept separate so it can be checked by hand (see the tests).
//! All gains of the paper are linear (γ(s) = g·s), so each small-gain condition
//! γ_a ∘ γ_b ∘ …(s) < s for all s > 0 is "product of slopes < 1".
//!
//! ## Sum-form estimates: the cycle conditions are not enough
//! Props. 1 and 3 bound ε and e by *sums* of gains. For sum-form estimates the small-gain
//! condition is ρ(Γ) < 1 for the gain matrix Γ, not "every cycle below 1" (the theorem for
//! max-form estimates; [`crate::small_gain`] has a three-node counterexample). On this graph
//! every cycle passes through e, so ρ(Γ) < 1 ⇔ det(I − Γ) = 1 − sg1 − sg2 − sg3 > 0. We
//! certify with that sum (its margin is [`GainsAtK::margin`]) and report the paper's
//! conditions beside it ([`GainsAtK::paper_conditions`]).
//!
//! ## Premises (checked, never assumed)
//! - ρ < 1 with ρ^M = 6η^M (Prop. 3 sums geometric series in √ρ); the paper's own case study
//!   (M = 5, η = 0.8) violates it: 6·0.8⁵ ≈ 1.97.
//! - φ(K) < 1 (Assumption 5; Prop. 1 divides by 1 − φ(K)).
//! - L_Φ > 1 (Lemma 1 states L_Φ > 1; a certified bound below 1 is raised to 1, which keeps
//!   it a valid Lipschitz bound).
//! - LMI (2) feasible (P ≻ 0), controller ISS with a finite linear gain γ₁,₃ (Assumption 4),
//!   φ(K) certified in the coordinates ε_t is measured in (eq. 11).
//!
//! A violated premise makes the certificate void: [`IssAnalysis::k_min`] is `None`, and each
//! [`Premise`] says by how much it fails and what would fix it.

#[cfg(feature = "serde")]
use serde::Serialize;

/// Scalar inputs of Theorem 1.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
pub struct IssInputs {
    /// MHE horizon M ≥ 1.
    pub horizon: usize,
    /// η ∈ [0, 1) of Assumption 2.
    pub eta: f64,
    /// λ_min(P), λ_max(P) of the δ-IOSS certificate.
    pub p_min: f64,
    /// λ_max(P).
    pub p_max: f64,
    /// λ_max(Q).
    pub q_max: f64,
    /// H̄ = sup_t λ_max(H_t) in the coordinates ε_t is measured in (Prop. 2).
    pub h_bar: f64,
    /// L_Φ of Lemma 1 (before raising to 1).
    pub l_phi: f64,
    /// L_π of Assumption 3.
    pub l_pi: f64,
    /// ‖C‖₂.
    pub c_norm: f64,
    /// ‖F‖₂ (y = Cx + Fw²): the measurement noise enters the MHE's data through F, so every
    /// gain from w through the window data carries it (C₃ʷ = C₃‖F‖).
    pub f_norm: f64,
    /// γ₁,₃ slope of Assumption 4 (gain from estimation error to state).
    pub gamma13: f64,
    /// φ(K) = prefactor · rateᴷ.
    pub phi_rate: f64,
    /// Prefactor of φ(K).
    pub phi_prefactor: f64,
    /// Whether the solver's certificate bounds ‖zᴷ − z*‖ in the coordinates of ε_t with a
    /// feasible iterate (eq. 11 as is).
    pub phi_fits_eq11: bool,
    /// Whether LMI (2) was certified for (η, P, Q, R).
    pub lmi_certified: bool,
}

/// One premise of Theorem 1, evaluated.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Premise {
    /// Short name, e.g. `"rho < 1"`.
    pub name: String,
    /// Where the paper needs it.
    pub needed_by: String,
    /// Whether it holds.
    pub holds: bool,
    /// The value tested.
    pub value: f64,
    /// Signed margin (positive when it holds), e.g. 1 − ρ; None when not evaluated (JSON
    /// null).
    pub margin: Option<f64>,
    /// What to change when it fails (None when it holds, was not evaluated, or has no
    /// advice); JSON: its sentence, or "" for None.
    #[cfg_attr(feature = "serde", serde(serialize_with = "fix_text"))]
    pub fix: Option<PremiseFix>,
    /// Set when the premise could not be evaluated because a premise it depends on failed
    /// (e.g. φ and L_Φ are properties of the MHE's QP, which is built from P of LMI (2)):
    /// the reason, naming that premise. The premise then counts as not holding, and its own
    /// advice is not given (one failure, one reason).
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub not_evaluated: Option<crate::outcome::NotEvaluated>,
}

/// What would make a failed premise of Theorem 1 hold; `Display` is the advice printed.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum PremiseFix {
    /// ρ = 6^{1/M}η ≥ 1: a longer horizon or a smaller η.
    RhoAtLeastOne {
        /// η.
        eta: f64,
        /// M.
        horizon: usize,
    },
    /// LMI (2) has no P ≻ 0.
    LmiInfeasible,
    /// The solver's certificate does not bound ‖zᴷ − z*‖ as eq. (11) needs.
    PhiNotEq11,
    /// The certified rate is ≥ 1 (no method known: see [`PremiseFix::MethodDoesNotContract`]).
    PhiRateAtLeastOne,
    /// The certified rate of `method` is ≥ 1, with that method's own fix ([`phi_rate_fix`]).
    MethodDoesNotContract {
        /// Φ.
        method: qp_iter::Method,
        /// Whether the MHE has general rows (state or output bounds).
        general_rows: bool,
    },
    /// No ISS gain γ₁,₃ from e to x was established.
    Gamma13Unknown,
    /// γ₁,₃ cannot be established, for this typed reason.
    Gamma13(crate::gamma13::Gamma13Void),
    /// A constant (`name`: "L_Phi", "L_U", …) is not a finite non-negative number.
    NotFinite {
        /// The constant's name.
        name: String,
    },
    /// The joint certificate: no gain γ₁,₄ from the MPC's input error to x.
    Gamma14Unknown,
    /// The joint certificate: the MPC method's certificate does not fit eq. (11).
    MpcPhiNotEq11,
    /// The joint certificate: the MPC method does not contract.
    MpcPhiRateAtLeastOne,
    /// The joint certificate: U*(0) ≠ 0.
    MpcOriginNotFixed,
    /// The joint certificate: the warm start's gain is not finite.
    WarmGainNotFinite,
}

impl std::fmt::Display for PremiseFix {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::RhoAtLeastOne { eta, horizon } => f.write_str(&rho_fix(*eta, *horizon)),
            Self::LmiInfeasible => f.write_str("no P ≻ 0 satisfies LMI (2): see the δ-IOSS error"),
            Self::PhiNotEq11 => f.write_str(
                "the solver's certificate bounds another quantity or its iterate may be \
                 infeasible: use PG or FISTA",
            ),
            Self::PhiRateAtLeastOne => f.write_str(
                "the solver's certified rate is ≥ 1 (it does not contract): see the method's \
                 own fix (`phi_rate_fix`)",
            ),
            Self::MethodDoesNotContract {
                method,
                general_rows,
            } => f.write_str(&phi_rate_fix(*method, *general_rows)),
            Self::Gamma13Unknown => f.write_str(
                "no ISS gain from e to x could be established: supply γ₁,₃ or change the \
                 controller",
            ),
            Self::Gamma13(v) => v.fmt(f),
            Self::NotFinite { name } => write!(f, "{name} is not a finite non-negative number"),
            Self::Gamma14Unknown => f.write_str(
                "no gain from the MPC's input error to x in the estimate of γ₁,₃: a user-supplied \
                 γ₁,₃ gives none (let the certificate compute γ₁,₃), or no metric contracts",
            ),
            Self::MpcPhiNotEq11 => f.write_str(
                "the MPC method's certificate bounds another quantity or norm: use pg or fista \
                 (or a -jacobi variant) for the MPC",
            ),
            Self::MpcPhiRateAtLeastOne => {
                f.write_str("the MPC's method does not contract: reduce its step size")
            }
            Self::MpcOriginNotFixed => f.write_str(
                "0 ∉ 𝒰 or the MPC's QP has a constant linear term: widen sets.input to contain 0",
            ),
            Self::WarmGainNotFinite => {
                f.write_str("the warm start's gain is not a finite non-negative number")
            }
        }
    }
}

/// A premise's fix as the JSON of before the type: its sentence, or "" for none.
#[cfg(feature = "serde")]
fn fix_text<S: serde::Serializer>(fix: &Option<PremiseFix>, s: S) -> Result<S::Ok, S::Error> {
    match fix {
        Some(f) => s.collect_str(f),
        None => s.serialize_str(""),
    }
}

/// Premises built from P of LMI (2): not evaluated when LMI (2) fails.
const NEEDS_P: [&str; 4] = [
    "phi fits eq. (11)",
    "phi rate < 1",
    "L_Phi finite",
    "H_bar finite",
];

impl Premise {
    /// A premise with no dependency problem (`not_evaluated` = None).
    pub fn evaluated(
        name: impl Into<String>,
        needed_by: impl Into<String>,
        holds: bool,
        value: f64,
        margin: f64,
        fix: Option<PremiseFix>,
    ) -> Self {
        Self {
            name: name.into(),
            needed_by: needed_by.into(),
            holds,
            value,
            margin: Some(margin),
            fix,
            not_evaluated: None,
        }
    }

    /// The sentence a void certificate gives for this premise: "NAME fails (NEEDED_BY =
    /// VALUE): FIX", or "NAME not evaluated (because …)".
    pub fn void_reason(&self) -> crate::outcome::VoidReason {
        use crate::outcome::VoidReason;
        match &self.not_evaluated {
            Some(why) => VoidReason::PremiseNotEvaluated {
                premise: self.name.clone(),
                because: *why,
            },
            None => VoidReason::PremiseFails {
                premise: self.name.clone(),
                needed_by: self.needed_by.clone(),
                value: self.value,
                fix: self.fix.clone(),
            },
        }
    }
}

/// Constants and gains of Props. 1 and 3 at one K.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct GainsAtK {
    /// Iteration budget K.
    pub k: usize,
    /// φ(K).
    pub phi: f64,
    /// C₁(K) = 2φL_Φ(1 + M(‖C‖ + L_π)), eq. (c1).
    pub c1: f64,
    /// C₂(K) = 2φL_Φ(1 + M L_π), eq. (c2).
    pub c2: f64,
    /// C₃(K) = 2φL_Φ M, eq. (c3): the coefficient of one unit of change in the u or y data.
    /// The joint certificate's input error δ enters the u data with this coefficient.
    pub c3: f64,
    /// C₃ʷ(K) = C₃‖F‖₂: the w-coefficient of Prop. 1's one-step bound
    /// (‖y_a − y_b‖ ≤ ‖C‖(‖x_a‖ + ‖x_b‖) + ‖F‖(‖w_a‖ + ‖w_b‖)); the paper's C₃ assumes F = I.
    pub c3w: f64,
    /// C_e(K), eq. (c4).
    pub c_e: f64,
    /// C_w(K), eq. (c5) with C₃ʷ in place of C₃.
    pub c_w: f64,
    /// C_ε(K), eq. (c6).
    pub c_eps: f64,
    /// γ₂,₁ = C₁/(1 − φ) (Prop. 1).
    pub gamma21: f64,
    /// γ₂,₃ = C₂/(1 − φ) (Prop. 1).
    pub gamma23: f64,
    /// γ₂ʷ = C₃ʷ/(1 − φ) (Prop. 1; C₃ʷ = C₃‖F‖).
    pub gamma2w: f64,
    /// γ₂^σ = φL_Φ/(1 − φ) (Prop. 1).
    pub gamma2sigma: f64,
    /// γ₃,₁ = √(2Λ^H̄_P) C₁ (Prop. 3).
    pub gamma31: f64,
    /// γ₃,₂ = C_ε (Prop. 3).
    pub gamma32: f64,
    /// γ₃ʷ = C_w (Prop. 3).
    pub gamma3w: f64,
    /// γ₃^σ = √(2Λ^H̄_P) φ L_Φ (Prop. 3).
    pub gamma3sigma: f64,
    /// Slope of γ₁,₃ ∘ γ₃,₁ (sg1).
    pub sg1: f64,
    /// Slope of γ₂,₃ ∘ γ₃,₂ (sg2).
    pub sg2: f64,
    /// Slope of γ₁,₃ ∘ γ₃,₂ ∘ γ₂,₁ (sg3).
    pub sg3: f64,
    /// The paper's conditions as printed: every slope (sg1)–(sg3) < 1 (the small-gain theorem
    /// for max-form estimates; necessary, not sufficient for the sum-form estimates of
    /// Props. 1 and 3, see [`crate::small_gain`]).
    pub paper_conditions: bool,
    /// 1 − (sg1 + sg2 + sg3) = det(I − Γ) of the three-node gain matrix (every cycle passes
    /// through e): positive iff ρ(Γ) < 1, the small-gain condition of the sum-form
    /// estimates. The certified ISS margin (> 0 iff certified at this K).
    pub margin: f64,
    /// All premises hold and ρ(Γ) < 1 (margin > 0, which implies every slope < 1).
    pub certified: bool,
}

/// Theorem 1 evaluated for one set of inputs.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct IssAnalysis {
    /// The inputs.
    pub inputs: IssInputs,
    /// ρ = 6^{1/M} η (ρ^M = 6η^M, Prop. 3).
    pub rho: f64,
    /// Λ^P_P = λ_max(P)/λ_min(P).
    pub lambda_pp: f64,
    /// Λ^Q_P = λ_max(Q)/λ_min(P).
    pub lambda_qp: f64,
    /// Λ^H̄_P = H̄/λ_min(P).
    pub lambda_hp: f64,
    /// L_Φ used in the constants: max(L_Φ, 1) (Lemma 1 requires L_Φ > 1).
    pub l_phi_used: f64,
    /// Premises with pass/fail and margins.
    pub premises: Vec<Premise>,
}

/// Largest η with 6η^M < 1 for horizon M: η < 6^{−1/M}.
pub fn eta_sup_for_horizon(m: usize) -> f64 {
    6f64.powf(-1.0 / m as f64)
}

/// Smallest horizon M with 6η^M < 1, i.e. M > ln 6 / ln(1/η) (None for η ≥ 1; 1 for η = 0).
pub fn min_horizon_for_eta(eta: f64) -> Option<usize> {
    if !(0.0..1.0).contains(&eta) {
        return None;
    }
    (1..100_000).find(|&m| 6.0 * eta.powi(m as i32) < 1.0)
}

/// The K-independent premises of Theorem 1 at ρ = 6^{1/M}η; those built from P are not
/// evaluated when LMI (2) fails (one failure, one reason).
fn premises(inputs: &IssInputs, rho: f64, m: usize) -> Vec<Premise> {
    let mut premises = vec![
        Premise::evaluated(
            "rho < 1",
            "Prop. 3 (ρ^M = 6η^M; geometric series in √ρ)",
            rho < 1.0,
            rho,
            1.0 - rho,
            (!(rho < 1.0)).then_some(PremiseFix::RhoAtLeastOne {
                eta: inputs.eta,
                horizon: m,
            }),
        ),
        Premise::evaluated(
            "LMI (2) feasible",
            "Assumption 2",
            inputs.lmi_certified && inputs.p_min > 0.0,
            inputs.p_min,
            inputs.p_min,
            (!inputs.lmi_certified).then_some(PremiseFix::LmiInfeasible),
        ),
        Premise::evaluated(
            "phi fits eq. (11)",
            "Assumption 5 (‖zᴷ − z*‖ ≤ φ(K)‖z⁰ − z*‖, feasible zᴷ)",
            inputs.phi_fits_eq11,
            if inputs.phi_fits_eq11 { 1.0 } else { 0.0 },
            if inputs.phi_fits_eq11 { 1.0 } else { -1.0 },
            (!inputs.phi_fits_eq11).then_some(PremiseFix::PhiNotEq11),
        ),
        Premise::evaluated(
            "phi rate < 1",
            "Assumption 5 (φ ∈ 𝓛)",
            inputs.phi_rate < 1.0 && inputs.phi_rate >= 0.0 && inputs.phi_prefactor.is_finite(),
            inputs.phi_rate,
            1.0 - inputs.phi_rate,
            // NaN: no advice, as before the type (the text was given for `!(rate < 1)`).
            (!(inputs.phi_rate < 1.0)).then_some(PremiseFix::PhiRateAtLeastOne),
        ),
        Premise::evaluated(
            "gamma13 finite",
            "Assumption 4 (ISS of the controlled system w.r.t. e)",
            inputs.gamma13.is_finite() && inputs.gamma13 >= 0.0,
            inputs.gamma13,
            if inputs.gamma13.is_finite() {
                1.0
            } else {
                -1.0
            },
            (!inputs.gamma13.is_finite()).then_some(PremiseFix::Gamma13Unknown),
        ),
    ];
    for (name, v) in [
        ("L_Phi", inputs.l_phi),
        ("L_pi", inputs.l_pi),
        ("H_bar", inputs.h_bar),
        ("norm C", inputs.c_norm),
        ("norm F", inputs.f_norm),
    ] {
        let ok = v.is_finite() && v >= 0.0;
        premises.push(Premise::evaluated(
            format!("{name} finite"),
            "Lemma 1 / Assumption 3 / Prop. 2",
            ok,
            v,
            if ok { 1.0 } else { -1.0 },
            (!ok).then(|| PremiseFix::NotFinite { name: name.into() }),
        ));
    }
    if !inputs.lmi_certified {
        for p in premises.iter_mut() {
            if NEEDS_P.contains(&p.name.as_str()) {
                p.holds = false;
                p.margin = None;
                p.fix = None;
                p.not_evaluated = Some(crate::outcome::NotEvaluated::LmiFails);
            }
        }
    }
    premises
}

/// The advice of a failed "rho < 1" ([`PremiseFix::RhoAtLeastOne`]): the horizon or the η
/// that makes 6η^M < 1.
fn rho_fix(eta: f64, m: usize) -> String {
    let m_min = min_horizon_for_eta(eta).map_or("none".to_string(), |m| m.to_string());
    format!(
        "6η^M = {} ≥ 1. Increase the horizon to M ≥ {m_min} at η = {eta}, or lower η below \
         6^(-1/M) = {} at M = {m} (η must stay feasible for LMI (2))",
        lti_model::numfmt::sig4(6.0 * eta.powi(m as i32)),
        // Rounded down: the number shown is itself below the bound, so η below it is below
        // the bound.
        lti_model::numfmt::sig4_below(eta_sup_for_horizon(m)),
    )
}

/// Why [`IssAnalysis::try_new`] refused its inputs: a value that is no number, named by its
/// field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum IssInputError {
    /// A field is NaN: Theorem 1 has no premise that can read it (±∞ is read, e.g. an
    /// unbounded γ₁,₃ fails its premise "gamma13 finite").
    #[error(
        "IssInputs::{field} is NaN; give the computed constant (±∞ where it is unbounded:          the premise that reads it then fails with its reason)"
    )]
    NaN {
        /// The field (`"q_max"`, `"gamma13"`, …).
        field: &'static str,
    },
    /// The horizon is 0 (M ≥ 1).
    #[error("IssInputs::horizon is 0; the MHE horizon M must be at least 1")]
    ZeroHorizon,
}

impl IssInputs {
    /// The scalar fields with their names, in declaration order.
    fn scalars(&self) -> [(&'static str, f64); 12] {
        [
            ("eta", self.eta),
            ("p_min", self.p_min),
            ("p_max", self.p_max),
            ("q_max", self.q_max),
            ("h_bar", self.h_bar),
            ("l_phi", self.l_phi),
            ("l_pi", self.l_pi),
            ("c_norm", self.c_norm),
            ("f_norm", self.f_norm),
            ("gamma13", self.gamma13),
            ("phi_rate", self.phi_rate),
            ("phi_prefactor", self.phi_prefactor),
        ]
    }
}

impl IssAnalysis {
    /// [`IssAnalysis::new`] for constants a caller computed: refuses a NaN field and M = 0
    /// with an error naming the field, where `new` (the certificate's own path, which
    /// writes NaN for a constant it could not compute) lets the premises fail.
    pub fn try_new(inputs: IssInputs) -> Result<Self, IssInputError> {
        if inputs.horizon == 0 {
            return Err(IssInputError::ZeroHorizon);
        }
        if let Some((field, _)) = inputs.scalars().into_iter().find(|(_, v)| v.is_nan()) {
            return Err(IssInputError::NaN { field });
        }
        Ok(Self::new(inputs))
    }

    /// Evaluates the constants that do not depend on K and checks the premises. A NaN
    /// input (the certificate's "not computed") fails the premises that read it; use
    /// [`IssAnalysis::try_new`] for a typed error instead.
    pub fn new(inputs: IssInputs) -> Self {
        let m = inputs.horizon.max(1);
        let rho = 6f64.powf(1.0 / m as f64) * inputs.eta;
        let premises = premises(&inputs, rho, m);
        Self {
            rho,
            lambda_pp: inputs.p_max / inputs.p_min,
            lambda_qp: inputs.q_max / inputs.p_min,
            lambda_hp: inputs.h_bar / inputs.p_min,
            l_phi_used: inputs.l_phi.max(1.0),
            inputs,
            premises,
        }
    }

    /// Whether every K-independent premise holds.
    pub fn premises_hold(&self) -> bool {
        self.premises.iter().all(|p| p.holds)
    }

    /// The premises that fail.
    pub fn violated(&self) -> Vec<&Premise> {
        self.premises.iter().filter(|p| !p.holds).collect()
    }

    /// φ(K) = prefactor · rateᴷ.
    pub fn phi(&self, k: usize) -> f64 {
        self.inputs.phi_prefactor
            * self
                .inputs
                .phi_rate
                .powi(i32::try_from(k).unwrap_or(i32::MAX))
    }

    /// All constants, gains and slopes at K (computed even when premises fail, for
    /// display; `certified` is false then).
    pub fn at(&self, k: usize) -> GainsAtK {
        self.at_perturbed(k, self.phi(k), 0.0)
    }

    /// [`IssAnalysis::at`] with φ(K) replaced by `phi` and every φ(K)·L_Φ that multiplies a
    /// data term (C₁, C₂, C₃, C_e, C_w, C_ε; not the σ-gains) replaced by φL_Φ + `extra`:
    /// Theorem 1 for an iteration whose K-step bound is ‖zᴷ − z*‖ ≤ φ‖z⁰ − z*‖ plus
    /// extra·‖θ‖ and a constant (the rounding model of issue 36, [`crate::certificate::precision`];
    /// docs/theory.md, "Certified f32"). `at_perturbed(k, self.phi(k), 0.0)` is `at(k)`.
    pub fn at_perturbed(&self, k: usize, phi: f64, extra: f64) -> GainsAtK {
        let i = &self.inputs;
        let m = i.horizon as f64;
        let lp = self.l_phi_used;
        // Each `k·φ·L_Φ + k·extra` keeps `at`'s association, so extra = 0 is bit for bit.
        let lpi = i.l_pi;
        let sr = self.rho.sqrt();
        let c1 = (2.0 * phi * lp + 2.0 * extra) * (1.0 + m * (i.c_norm + lpi));
        let c2 = (2.0 * phi * lp + 2.0 * extra) * (1.0 + m * lpi);
        let c3 = (2.0 * phi * lp + 2.0 * extra) * m;
        let c3w = c3 * i.f_norm;
        let a = (3.0 * self.lambda_pp * self.lambda_hp).sqrt();
        let sum: f64 = (1..i.horizon).map(|j| sr.powi(-(1 + j as i32))).sum();
        let c_e = (2.0 * a * phi * lp + 2.0 * a * extra)
            * (sr.powi(-(i.horizon as i32)) + lpi / sr)
            + (4.0 * a * phi * lp + 4.0 * a * extra) * lpi * sum
            + (6.0 * self.lambda_pp).sqrt()
            + (2.0 * a * phi * lp + 2.0 * a * extra)
                * (lpi + 1.0)
                * sr.powi(-(i.horizon as i32) - 1);
        let inv1 = 1.0 / (1.0 - sr);
        let c_w = (2.0 * self.lambda_hp).sqrt() * c3w
            + (6.0 * self.lambda_qp).sqrt() * inv1
            + (4.0 * (3.0 * self.lambda_hp * self.lambda_qp).sqrt() * phi * lp
                + 4.0 * (3.0 * self.lambda_hp * self.lambda_qp).sqrt() * extra)
                * (lpi * m + 1.0)
                * inv1;
        let inv_m = 1.0 / (1.0 - self.rho.powi(i.horizon as i32).sqrt());
        let c_eps = (2.0 * self.lambda_hp).sqrt() * phi
            + (2.0 * self.lambda_hp).sqrt() * inv_m
            + (4.0 * self.lambda_hp * phi * lp + 4.0 * self.lambda_hp * extra)
                * (lpi * m + 1.0)
                * inv_m;
        let one_minus_phi = 1.0 - phi;
        let gamma21 = c1 / one_minus_phi;
        let gamma23 = c2 / one_minus_phi;
        let gamma2w = c3w / one_minus_phi;
        let gamma2sigma = phi * lp / one_minus_phi;
        let gamma31 = (2.0 * self.lambda_hp).sqrt() * c1;
        let gamma32 = c_eps;
        let gamma3w = c_w;
        let gamma3sigma = (2.0 * self.lambda_hp).sqrt() * phi * lp;
        let sg1 = i.gamma13 * gamma31;
        let sg2 = gamma23 * gamma32;
        let sg3 = i.gamma13 * gamma32 * gamma21;
        let worst = sg1.max(sg2).max(sg3);
        let paper_conditions = worst < 1.0;
        // det(I − Γ) for Γ with γ₁,₃, γ₂,₁, γ₂,₃, γ₃,₁, γ₃,₂: 1 − sg1 − sg2 − sg3; with I − Γ's
        // other leading minors equal to 1 it is the whole M-matrix test (small_gain.rs).
        let margin = 1.0 - (sg1 + sg2 + sg3);
        let certified =
            self.premises_hold() && (0.0..1.0).contains(&phi) && margin > 0.0 && margin.is_finite();
        GainsAtK {
            k,
            phi,
            c1,
            c2,
            c3,
            c3w,
            c_e,
            c_w,
            c_eps,
            gamma21,
            gamma23,
            gamma2w,
            gamma2sigma,
            gamma31,
            gamma32,
            gamma3w,
            gamma3sigma,
            sg1,
            sg2,
            sg3,
            paper_conditions,
            margin,
            certified,
        }
    }

    /// Smallest K at which sg1 + sg2 + sg3 < 1 (hence each of (sg1)–(sg3)) and φ(K) < 1, or `None` when a premise fails
    /// (a void certificate never yields a K) or no K up to `k_max` works.
    ///
    /// Every slope is increasing in φ(K) and φ is decreasing in K, so "certified at K" is
    /// monotone in K and a doubling + bisection search is exact.
    pub fn k_min(&self, k_max: usize) -> Option<usize> {
        if !self.premises_hold() {
            return None;
        }
        if self.at(0).certified {
            return Some(0);
        }
        let mut hi = 1usize;
        while !self.at(hi).certified {
            if hi >= k_max {
                return None;
            }
            hi = (hi * 2).min(k_max);
        }
        let mut lo = hi / 2; // not certified (or 0, checked above)
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if self.at(mid).certified {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Some(hi)
    }
}

/// The fix of a failed "phi rate < 1" for `method` (issue 37 item 13: "reduce the step size"
/// was offered for ADMM, which has no step): what sets each family's certified rate, and the
/// method to switch to. `general_rows`: the MHE's QP has general rows (finite state or output
/// bounds), where ADMM runs on a split with no certified rate.
pub fn phi_rate_fix(method: qp_iter::Method, general_rows: bool) -> String {
    let name = method.name();
    match method.family() {
        "pg" => format!(
            "{name} does not contract at its step: the certified rate needs a step in \
             (0, 2/L); drop `step` from mhe.method for the optimal 2/(L + μ), or use fista"
        ),
        "fista" => format!(
            "{name} has no parameter that sets its rate (V-FISTA with the problem's L and μ): \
             use pg or admm, or improve the conditioning of the MHE's weights"
        ),
        "admm" if general_rows => format!(
            "{name} runs on the split [I; G]z when the MHE has state or output bounds (general \
             rows), and that split has no certified rate whatever its penalty ρ and relaxation \
             α: use pg or fista (their certificate holds with the bounds), or remove the \
             finite bounds of sets.state / sets.output"
        ),
        "admm" => format!(
            "{name}'s rate is set by its penalty ρ and relaxation α (it has no step size): use \
             ρ = √(μL), the default (`mhe.method = \"admm\"` or \"admm-pr\" without `rho`), \
             α ∈ (0, 2), or use pg or fista"
        ),
        _ => format!("{name} does not contract: use pg or fista"),
    }
}
