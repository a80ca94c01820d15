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
pub mod detectable;
pub mod error;
pub mod exact;
pub mod free_sets;
pub mod lipschitz;
pub mod lqr;
pub mod robust_norm;
pub mod settings;
pub mod suboptimal;

pub use condensed::{
    CondensedMpc, MpcConfig, OUTPUT_CONSTRAINED_VOID_REASON, STATE_CONSTRAINED_VOID_REASON,
    Terminal,
};
pub use error::{MpcError, Result};
pub use exact::{ExactBackend, ExactMpc};
pub use free_sets::{FreeSetSummary, LocalGains};
pub use lipschitz::{
    ENUMERATION_MAX_VARS, LIPSCHITZ_PATTERN_FAMILIES, LipschitzCertificate, LipschitzReport,
    SampledLipschitz, lipschitz_report_for, lipschitz_report_with, lipschitz_sampled,
};
pub use lqr::SaturatedLqr;
/// The iteration maps Φ this crate runs (`qp_iter::Method`, `qp_iter::pg`, …), re-exported so
/// that a user needs no separate `qp-iter` dependency.
pub use qp_iter;
pub use robust_norm::{WorstCaseNorm, worst_case_norm};
pub use settings::{MpcBuilder, MpcSettings, RawMpc};
pub use suboptimal::{SuboptimalMpc, WarmStart};

/// The controller trait and what a controller applied (their own crate, `loop-traits`, so
/// that a user's controller needs no QP solver); re-exported here.
pub use loop_traits::{ControlStatus, Controller, MpcFallback};

/// Validates the arguments of `Controller::control` without allocating.
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
