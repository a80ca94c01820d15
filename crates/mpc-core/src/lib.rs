#![doc = include_str!("../README.md")]
//!
//! ## Contents
//!
//! The controller π of Yang–Manzie–Pu (arXiv 2304.06216), Assumptions 3–4: an
//! input-constrained condensed linear MPC, exact or with K warm-started iterations of any
//! iteration map Φ, a saturated LQR, and the Lipschitz constant L_π of Assumption 3
//! (a certified upper bound and a sampled estimate).
//!
//! - [`CondensedMpc`] / [`MpcConfig`]: the MPC as a [`qp_iter::ParametricQp`] with θ = x̂.
//! - [`Controller`]: x̂ ↦ u, shared with `closed-loop`; implemented by [`ExactMpc`]
//!   (the paper's setting: an exact active-set solve each call, Clarabel as fallback and
//!   reference), [`SuboptimalMpc`] (K iterations of Φ)
//!   and [`SaturatedLqr`].
//! - [`free_sets`]: what can saturate, the free-set enumeration and the family
//!   K(M) = K_lin + G·M·R, 0 ⪯ M ⪯ I, that contains every local gain of the law;
//!   [`robust_norm`]: worst-case norms over that family (S-procedure, no SDP solver).
//! - [`lipschitz`]: L_π certified (L_poly over the family for any size, bound (b); the
//!   enumerated L_enum over the 2^s free sets when s ≤ 30) and sampled (seeded pairs, exact MPC);
//!   [`lipschitz_report_for`] gathers both for an MPC (what `cargo xtask certify` prints).
//!
//! The MPC uses the nominal model (w = 0) and input constraints only; see
//! [`MpcConfig::state_set`] for state constraints.

pub mod condensed;
pub mod error;
pub mod exact;
pub mod free_sets;
pub mod lipschitz;
pub mod lqr;
pub mod robust_norm;
pub mod settings;
pub mod suboptimal;

pub use condensed::{CondensedMpc, MpcConfig, STATE_CONSTRAINED_VOID_REASON, Terminal};
pub use error::{MpcError, Result};
pub use exact::{ExactBackend, ExactMpc};
pub use free_sets::{FreeSetSummary, LocalGains};
pub use lipschitz::{
    ENUMERATION_MAX_VARS, LIPSCHITZ_PATTERN_FAMILIES, LipschitzCertificate, LipschitzReport,
    SampledLipschitz, lipschitz_report_for, lipschitz_sampled,
};
pub use lqr::SaturatedLqr;
/// The iteration maps Φ this crate runs (`qp_iter::Method`, `qp_iter::pg`, …), re-exported so
/// that a user needs no separate `qp-iter` dependency.
pub use qp_iter;
pub use robust_norm::{WorstCaseNorm, worst_case_norm};
pub use settings::{MpcSettings, RawMpc};
pub use suboptimal::{SuboptimalMpc, WarmStart};

/// A state-feedback law u = π(x̂) (the controller of Assumption 3).
///
/// Implementations validate `x_hat` (length n_x, finite) and `u` (length n_u) on every
/// call and return [`MpcError::Dimension`] / [`MpcError::NonFinite`] naming the argument;
/// `u` is left unchanged on error. [`SuboptimalMpc`], [`SaturatedLqr`] and [`ExactMpc`]
/// with its default active-set backend allocate nothing per call after construction
/// (errors included); [`ExactMpc`] with the Clarabel backend (or fallback) does.
///
/// A user's controller implements this with its own error type; the closed loop and the
/// sweep run it like the built-in ones.
pub trait Controller: std::fmt::Debug {
    /// Why a control computation failed (the controller's own error type).
    type Error: std::error::Error + Send + Sync + 'static;
    /// Writes π(x̂) into `u`.
    fn control(&mut self, x_hat: &[f64], u: &mut [f64]) -> std::result::Result<(), Self::Error>;
    /// Input dimension n_u.
    fn nu(&self) -> usize;
    /// State dimension n_x.
    fn nx(&self) -> usize;
    /// What the last successful [`Controller::control`] applied (a state-constrained MPC
    /// can be infeasible and apply a fallback). The default: the law as designed.
    fn status(&self) -> ControlStatus {
        ControlStatus::Applied { violation: 0.0 }
    }
}

/// What a controller applied at one step.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case", tag = "status")]
pub enum ControlStatus {
    /// The law as designed: the exact optimum, or K iterations whose plan violates the
    /// constraints by `violation` (0 for PG / FISTA; ADMM on state rows is feasible only in
    /// the limit).
    Applied {
        /// The largest violation of 𝒰^N and of the state rows by the plan.
        violation: f64,
    },
    /// The state-constrained MPC has no feasible plan at this x̂; `fallback` was applied.
    Infeasible {
        /// The row the exact solver could not meet (None when not identified).
        constraint: Option<qp_iter::dual_active_set::ConstraintRow>,
        /// What was applied instead.
        fallback: MpcFallback,
    },
}

/// What an infeasible state-constrained MPC applies (documented per controller).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MpcFallback {
    /// u*₀ of the input-constrained MPC (the state rows dropped): [`ExactMpc`].
    InputOnlyMpc,
    /// The first block of the warm start — for the shifting rules the previous plan's next
    /// input; Π_𝒰(0) after a cold start: [`SuboptimalMpc`].
    ShiftedPlan,
}

/// Validates the arguments of [`Controller::control`] without allocating.
pub(crate) fn check_io(x_hat: &[f64], u: &[f64], nx: usize, nu: usize) -> Result<()> {
    error::check_len("x_hat", x_hat, nx)?;
    error::check_len("u", u, nu)?;
    error::check_finite("x_hat", x_hat)
}

#[cfg(test)]
mod send_sync {
    fn is_send<T: Send>() {}
    fn is_sync<T: Sync>() {}
    #[test]
    fn controllers_are_send() {
        is_send::<crate::SaturatedLqr>();
        is_sync::<crate::SaturatedLqr>();
        is_send::<crate::SuboptimalMpc<qp_iter::pg::ProjectedGradient>>();
        is_send::<crate::SuboptimalMpc<qp_iter::fista::Fista>>();
        is_send::<crate::ExactMpc>();
        is_sync::<crate::CondensedMpc>();
    }
}
