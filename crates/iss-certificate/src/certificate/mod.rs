//! The closed-loop ISS certificate of Theorem 1 for a scenario: every constant, where it
//! comes from, the premises, and the smallest certified K per solver.
//!
//! [`certify_closed_loop`] assembles the inputs of [`crate::analysis::IssAnalysis`]:
//!
//! | constant | source |
//! | --- | --- |
//! | P, η, λ(P), λ̄(Q) | [`lti_model::ioss::certify`] (LMI (2)), or the scenario's P verified |
//! | H̄ | [`mhe_core::MheProblem::h_bar`] (ε in condensed coordinates) |
//! | L_Φ | [`mhe_core::MheProblem::lipschitz_certified`], sampled estimate beside it |
//! | L_π | tightest certified bound of [`mpc_core::lipschitz_report_for`], sampled beside it |
//! | γ₁,₃ | [`crate::gamma13::gamma13_report`]: certified, or user-supplied ("not verified", refuted by the sampled lower estimate if below it) |
//! | φ(K) | each solver's certificate, worst rate and prefactor over the window lengths m = 0..M |
//!
//! The controller analysed is the exact MPC (the paper's setting). A violated premise makes
//! a solver's certificate void: `k_min` is `None` and `void_reasons` says why; a K is never
//! computed from a void bound. A verdict the analysis budget cut short is not void:
//! `not_computed` says which phase, its estimate and the budget that computes it.
//!
//! [`check_trajectory`] evaluates the trajectory inequalities of Prop. 1 (ε_t) and Prop. 3
//! (e_t) on a simulated trace with the reported constants, both sides computed from the trace,
//! above a rounding floor derived from the quantities' scale and the operation count
//! ([`rounding_floor`]: a measured ε_t of 1e-14 against a bound of 1e-21 is rounding, not a
//! contradiction).
//!
//! ## The virtual disturbance σ_t (Lemma 1)
//! For t ≤ M the paper bounds the jump of z* while the window grows by L_Φσ_t with
//! σ_t = (1 − η⁻¹)‖H_t‖ + ‖A‖ + ‖B‖ + ‖C‖ + 2, whose first term is negative for η < 1 as
//! printed; we use |1 − η⁻¹|‖H_t‖ (the magnitude the proof needs) with H_t the paper's weight
//! of eq. (10). σ_t = 0 for t > M. This term is the least rigorous step of the paper
//! (it invokes Hager's Lipschitz theorem for a change of the constraint matrices); the
//! trajectory check reports it as part of the right-hand side, not as a verified bound.

mod certify;
pub mod lemma1;
pub mod precision;
mod rounding;
mod trajectory;

use lti_model::ioss;
use qp_iter::{Certificate, Method};
#[cfg(feature = "serde")]
use serde::Serialize;

use crate::analysis::{GainsAtK, IssAnalysis};
pub use crate::gamma13::{Gamma13Report, Gamma13Source};
pub use crate::outcome::{IossFailure, VoidReason};
pub use certify::{
    CertificateTimes, ComputedParts, certify_closed_loop, certify_closed_loop_timed,
    certify_closed_loop_with,
};
pub use rounding::{UNIT_ROUNDOFF, gamma_n, rounding_floor};
pub use trajectory::{
    InequalityCheck, TrajectoryCheck, analysis_with_sampled_l_phi, check_trajectory,
};

/// Settings of [`certify_closed_loop`].
#[derive(Debug, Clone, PartialEq)]
pub struct CertificateOptions {
    /// Solvers to certify (default: the four named methods, then the same four on the
    /// Jacobi-scaled problem, which keep K_min small at long horizons: docs/theory.md,
    /// "Preconditioned maps").
    pub solvers: Vec<Method>,
    /// γ₁,₃ source.
    pub gamma13: Gamma13Source,
    /// Seed of every sampled estimate.
    pub seed: u64,
    /// Random pairs for the sampled L_Φ and L_π (0 skips both: they are reported as 0 over
    /// 0 pairs, and no K_min is computed with the sampled L_Φ).
    pub lipschitz_pairs: usize,
    /// Injected error sequences per magnitude for the sampled γ₁,₃ (0 skips it).
    pub gamma13_sequences: usize,
    /// Cap on the number of saturable input variables for the γ₁,₃ free-set enumeration
    /// (above it the polynomial bound alone is used, and the skip is reported).
    pub enumeration_max_vars: usize,
    /// Largest K searched for K_min.
    pub k_max: usize,
    /// Budget (estimated single-core seconds) of an optional analysis phase: the γ₁,₃
    /// free-set enumeration is skipped beyond it ([`crate::budget`]; scenario key
    /// `certificate.phase_seconds`).
    pub phase_seconds: f64,
    /// Budget (estimated seconds) of the global loop certificate (Theorem L3 and its f32 form
    /// L3u; [`crate::lure::global_outcome::global_section`]) computed with the certificate;
    /// None: not computed, and the verdicts are Theorem 1's and the joint certificate's
    /// alone. [`crate::coverage::verdict_options`] sets it to `certificate.phase_seconds`.
    pub global_seconds: Option<f64>,
}

impl Default for CertificateOptions {
    fn default() -> Self {
        Self {
            solvers: Method::ALL.to_vec(),
            gamma13: Gamma13Source::Certified,
            seed: 0,
            lipschitz_pairs: 200,
            gamma13_sequences: 30,
            enumeration_max_vars: 20,
            k_max: 1 << 24,
            phase_seconds: crate::budget::DEFAULT_PHASE_SECONDS,
            global_seconds: None,
        }
    }
}

/// L_Φ figures.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct LPhiReport {
    /// max_m certified bound (used in the certificate); None when there is no MHE problem
    /// (LMI (2) gave no P). JSON: null then.
    pub certified: Option<f64>,
    /// max_m sampled estimate (a lower bound on the true constant); None as `certified`.
    pub sampled: Option<f64>,
    /// Per window length m = 0..M: (certified, sampled).
    pub per_window: Vec<(f64, f64)>,
    /// Why fewer pairs than `lipschitz_pairs` were sampled (the analysis budget,
    /// [`crate::budget::l_phi_sampling_pairs`]); omitted when every pair was sampled.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub pairs_reduced: Option<crate::budget::PairsReduced>,
}

/// Certificate of one solver Φ.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct SolverCertificate {
    /// The solver.
    pub solver: Method,
    /// φ(K) = prefactor · rateᴷ, worst over window lengths.
    pub phi_rate: f64,
    /// Prefactor of φ(K).
    pub phi_prefactor: f64,
    /// Whether every window's certificate fits eq. (11).
    pub fits_eq11: bool,
    /// The per-window certificates (m = 0..M).
    pub per_window: Vec<Certificate>,
    /// Theorem 1 with these constants (premises included).
    pub analysis: IssAnalysis,
    /// Smallest certified K (None when void or beyond `k_max`).
    pub k_min: Option<usize>,
    /// Constants and slopes at K_min.
    pub at_k_min: Option<GainsAtK>,
    /// Why there is no K_min (empty when there is one, and when it was not computed).
    pub void_reasons: Vec<VoidReason>,
    /// No K_min, and not void either: the analysis budget stopped a phase whose result
    /// could change the verdict (the γ₁,₃ free-set enumeration; issue 37 item 6). The
    /// verdict is "not computed within the budget", with the `certificate.phase_seconds`
    /// that computes it. Omitted otherwise.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub not_computed: Option<crate::budget::NotComputed>,
    /// K_min with the *sampled* L_Φ in place of the certified bound — not a certificate,
    /// reported to show how much of K_min is due to L_Φ's conservatism.
    pub k_min_with_sampled_l_phi: Option<usize>,
}

/// Parameters near the scenario's that satisfy ρ < 1.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct NearestParameters {
    /// Smallest M with 6η^M < 1 at the scenario's η.
    pub min_horizon_at_eta: Option<usize>,
    /// η must be below 6^{−1/M} at the scenario's M.
    pub eta_sup_at_horizon: f64,
}

/// Everything [`certify_closed_loop`] computes.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct ClosedLoopCertificate {
    /// Scenario name.
    pub scenario: String,
    /// MHE horizon M.
    pub horizon: usize,
    /// η.
    pub eta: f64,
    /// ρ = 6^{1/M}η.
    pub rho: f64,
    /// The δ-IOSS certificate (None when LMI (2) is infeasible).
    pub ioss: Option<ioss::IossReport>,
    /// Why LMI (2) failed (None when it holds).
    pub ioss_failure: Option<IossFailure>,
    /// λ_min(P) of the δ-IOSS certificate (None when LMI (2) gave no P).
    pub p_min: Option<f64>,
    /// λ_max(P) (None as `p_min`).
    pub p_max: Option<f64>,
    /// λ_max(Q).
    pub q_max: f64,
    /// H̄ (None when the MHE could not be built: LMI (2) gave no P).
    pub h_bar: Option<f64>,
    /// ‖C‖₂.
    pub c_norm: f64,
    /// L_Φ.
    pub l_phi: LPhiReport,
    /// L_π report (certified, enumerated, sampled).
    pub l_pi: mpc_core::LipschitzReport,
    /// L_π used (tightest certified bound).
    pub l_pi_used: f64,
    /// γ₁,₃.
    pub gamma13: Gamma13Report,
    /// One certificate per solver.
    pub solvers: Vec<SolverCertificate>,
    /// Nearest parameters satisfying ρ < 1.
    pub nearest: NearestParameters,
    /// ‖H_t‖₂ of the paper's weight (eq. 10) per window length m = 0..M, for σ_t.
    pub h_paper_norms: Vec<f64>,
    /// ‖A‖₂ + ‖B‖₂ + ‖C‖₂ + 2: the model part of σ_t.
    pub sigma_model_part: f64,
    /// o_m ≥ ‖z*_m(0)‖ per window length m = 0..M (0 when 0 ∈ Z): the offsets of the mended
    /// Lemma 1 for t ≤ M ([`lemma1`]), which replaces the paper's σ_t in the trajectory checks.
    pub lemma1_origin_offsets: Vec<f64>,
    /// The global loop certificate per solver (f64 and f32), computed when
    /// [`CertificateOptions::global_seconds`] is set: the second certificate of the one
    /// verdict ([`crate::coverage::verdict`]). Serialised by `certificate_json`, not here.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub global: Option<crate::lure::global_outcome::GlobalSection>,
}

impl ClosedLoopCertificate {
    /// The certificate of one solver.
    pub fn solver(&self, solver: Method) -> Option<&SolverCertificate> {
        self.solvers.iter().find(|s| s.solver == solver)
    }

    /// The paper's σ_t of Lemma 1 (module doc): |1 − η⁻¹|‖H_t‖ + ‖A‖ + ‖B‖ + ‖C‖ + 2 for
    /// t ≤ M, else 0. Reported for comparison only: it does not scale with the data, so the
    /// checks use the mended, data-dependent σ_t of [`lemma1::sigma`] (issue 27).
    pub fn sigma(&self, t: usize) -> f64 {
        if t > self.horizon {
            return 0.0;
        }
        let h = self
            .h_paper_norms
            .get(t.min(self.horizon))
            .copied()
            .unwrap_or(f64::NAN);
        (1.0 - 1.0 / self.eta).abs() * h + self.sigma_model_part
    }
}
