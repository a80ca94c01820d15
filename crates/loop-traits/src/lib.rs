#![doc = include_str!("../README.md")]
//!
//! ## Contents
//!
//! - [`Estimator`]: the state estimator of Alg. 1 (steps 1–3), implemented by
//!   `mhe_core::MheEstimator` and `mhe_core::KalmanFilter`.
//! - [`Controller`]: the state-feedback law π of Assumption 3, implemented by the MPCs and the
//!   saturated LQR of `mpc-core`.
//! - [`ControlStatus`], [`MpcFallback`], [`ConstraintRow`]: what a controller applied at one
//!   step, and which constraint row made a state-constrained MPC infeasible.

/// A state estimator that closed-loop code can compose: x̂_{t|t} from u and y up to t − 1.
///
/// Protocol per time step t: `estimate()` (uses data up to t − 1), then `push(u_t, y_t)`
/// with the input applied and the measurement taken at t, which advances t.
///
/// A user's estimator (a Luenberger observer, a particle filter, …) implements this with
/// its own error type; the closed loop, the sweep and the trajectory checks run it like the
/// built-in sub-optimal MHE and Kalman filter of `mhe-core`.
pub trait Estimator {
    /// Why an estimate or a push failed (the estimator's own error type).
    type Error: std::error::Error + Send + Sync + 'static;
    /// The estimate x̂_{t|t} at the current t (calling it twice at the same t gives the same
    /// result).
    fn estimate(&mut self) -> Result<&[f64], Self::Error>;
    /// Appends (u_t, y_t) and advances t. On error nothing changes.
    fn push(&mut self, u: &[f64], y: &[f64]) -> Result<(), Self::Error>;
    /// State dimension n_x.
    fn nx(&self) -> usize;
}

/// A state-feedback law u = π(x̂) (the controller of Assumption 3).
///
/// Implementations validate `x_hat` (length n_x, finite) and `u` (length n_u) on every
/// call and return their error naming the argument; `u` is left unchanged on error.
///
/// A user's controller implements this with its own error type; the closed loop and the
/// sweep run it like the MPCs and the saturated LQR of `mpc-core`.
pub trait Controller: std::fmt::Debug {
    /// Why a control computation failed (the controller's own error type).
    type Error: std::error::Error + Send + Sync + 'static;
    /// Writes π(x̂) into `u`.
    fn control(&mut self, x_hat: &[f64], u: &mut [f64]) -> Result<(), Self::Error>;
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
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case", tag = "status"))]
#[non_exhaustive]
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
        constraint: Option<ConstraintRow>,
        /// What was applied instead.
        fallback: MpcFallback,
    },
}

/// What an infeasible state-constrained MPC applies (documented per controller).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum MpcFallback {
    /// u*₀ of the input-constrained MPC (the state rows dropped): `mpc_core::ExactMpc`.
    InputOnlyMpc,
    /// The first block of the warm start — for the shifting rules the previous plan's next
    /// input; Π_𝒰(0) after a cold start: `mpc_core::SuboptimalMpc`.
    ShiftedPlan,
}

impl MpcFallback {
    /// The snake_case name files write (`"input_only_mpc"`, `"shifted_plan"`): the same as its
    /// serde form, without needing the `serde` feature.
    ///
    /// ```
    /// use loop_traits::MpcFallback;
    /// // serde's `rename_all = "snake_case"` of each variant's name.
    /// for f in [MpcFallback::InputOnlyMpc, MpcFallback::ShiftedPlan] {
    ///     let mut snake = String::new();
    ///     for (i, c) in format!("{f:?}").chars().enumerate() {
    ///         if c.is_ascii_uppercase() && i > 0 {
    ///             snake.push('_');
    ///         }
    ///         snake.push(c.to_ascii_lowercase());
    ///     }
    ///     assert_eq!(f.name(), snake);
    /// }
    /// ```
    pub fn name(self) -> &'static str {
        match self {
            MpcFallback::InputOnlyMpc => "input_only_mpc",
            MpcFallback::ShiftedPlan => "shifted_plan",
        }
    }
}

/// A row of a QP's constraints: a bound of the box (z_i) or a row of G.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum ConstraintRow {
    /// l_i ≤ z_i ≤ u_i.
    Box(usize),
    /// The i-th row of l_G ≤ Gz ≤ u_G.
    General(usize),
}

impl std::fmt::Display for ConstraintRow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConstraintRow::Box(i) => write!(f, "box row {i} (z_{i})"),
            ConstraintRow::General(i) => write!(f, "general row {i} ((Gz)_{i})"),
        }
    }
}
