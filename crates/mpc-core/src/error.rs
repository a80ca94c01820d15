//! The one error type of `mpc-core`: bad setup data and bad controller input.
//!
//! Setup errors (weights, shapes, horizon) are raised by constructors. The only errors a
//! [`crate::Controller::control`] call can raise are about its arguments (length,
//! finiteness) or a solver failure of the exact MPC; those variants carry `&'static str`
//! names so that raising them does not allocate.

use lti_model::ModelError;
use qp_iter::QpError;

/// Errors raised by `mpc-core`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MpcError {
    /// Invalid matrix / set data from `lti-model` checks; the variant names the field
    /// (`"Q_c"`, `"R_c"`, `"P_f"`, `"input_set"`, ...).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The condensed QP or an iteration map could not be built.
    #[error(transparent)]
    Qp(#[from] QpError),
    /// The prediction horizon N must be at least 1.
    #[error("horizon `N` = {value} is invalid: the MPC needs N ≥ 1")]
    Horizon {
        /// The horizon given.
        value: usize,
    },
    /// A weight that must be positive semidefinite is not.
    #[error(
        "`{name}` is not positive semidefinite (smallest eigenvalue {min_eigenvalue:e}); use a symmetric matrix with nonnegative eigenvalues"
    )]
    NotPositiveSemidefinite {
        /// Name of the weight (`"Q_c"`, `"P_f"`).
        name: &'static str,
        /// Its smallest eigenvalue.
        min_eigenvalue: f64,
    },
    /// Q_c is singular and (A, Q_c^½) is not detectable: a mode of A that Q_c does not see
    /// does not decay, so the DARE terminal cost has no stabilising solution and the MPC's
    /// cost does not penalise that mode ([`crate::detectable`]).
    #[error(
        "`Q_c` ⪰ 0 is allowed when (A, Q_c^½) is detectable, but the mode {mode} of A is not \
         seen by Q_c and does not decay (|λ| ≥ 1); weigh one of those state components \
         (a positive diagonal entry of Q_c there), or use Q_c ≻ 0"
    )]
    NotDetectable {
        /// The undetectable mode (eigenvalue, modulus, state components).
        mode: crate::detectable::UndetectableMode,
    },
    /// A vector passed to a controller or analysis routine has the wrong length.
    #[error("`{name}` has length {actual}, expected {expected}")]
    Dimension {
        /// Name of the argument (`"x_hat"`, `"u"`).
        name: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        actual: usize,
    },
    /// A vector passed to a controller has a NaN or ±∞ entry.
    #[error("`{name}` has a non-finite entry {value} at index {index}; all entries must be finite")]
    NonFinite {
        /// Name of the argument (`"x_hat"`).
        name: &'static str,
        /// Index of the first offending entry.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A feature this crate does not offer (yet), with the reason and the alternative.
    #[error("unsupported: {feature}: {reason}")]
    Unsupported {
        /// What was asked for.
        feature: &'static str,
        /// Why it is not available and what to do instead.
        reason: &'static str,
    },
    /// An iteration map handed to [`crate::SuboptimalMpc`] was built for another QP.
    #[error("iteration map does not match the condensed MPC: {what}")]
    MapMismatch {
        /// Which datum differs (dimension, H, F or the box).
        what: String,
    },
    /// The K-iteration solver produced a NaN or ±∞ iterate (the controller state was reset).
    #[error("the K-iteration MPC produced a non-finite input sequence; the warm start was reset")]
    NonFiniteIterate,
    /// The exact solver (active set, then Clarabel) did not return a solution: the MPC's QP
    /// is too ill-conditioned for them (the scenario keys that shape it are named).
    #[error(
        "exact MPC solve failed: {status}; the MPC QP is too ill-conditioned to solve in f64 — \
         its conditioning comes from `plant.a`, `plant.b` (an unstable or badly scaled plant \
         grows like ρ(A)^N), `mpc.horizon`, `mpc.q` and `mpc.r`: rescale the plant, shorten \
         `mpc.horizon` or balance the weights"
    )]
    Solver {
        /// Clarabel's status or the reason.
        status: String,
    },
    /// A numeric parameter of an analysis routine is out of range.
    #[error("parameter `{name}` = {value} is invalid: {reason}")]
    Parameter {
        /// Parameter name.
        name: &'static str,
        /// Value given.
        value: f64,
        /// What is required.
        reason: &'static str,
    },
    /// A scenario lacks a section this crate needs.
    #[error("scenario has no `[{section}]` section; add one (see docs/scenario-format.md)")]
    MissingSection {
        /// The section name (`"mpc"`).
        section: &'static str,
    },
}

/// Result alias for `mpc-core`.
pub type Result<T> = std::result::Result<T, MpcError>;

/// Checks that `v` has length `n` (allocation-free, also on error).
pub(crate) fn check_len(name: &'static str, v: &[f64], n: usize) -> Result<()> {
    if v.len() == n {
        Ok(())
    } else {
        Err(MpcError::Dimension {
            name,
            expected: n,
            actual: v.len(),
        })
    }
}

/// Checks that every entry of `v` is finite (allocation-free, also on error).
pub(crate) fn check_finite(name: &'static str, v: &[f64]) -> Result<()> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(MpcError::NonFinite {
            name,
            index,
            value: v[index],
        }),
        None => Ok(()),
    }
}

/// Bad set or matrix data from `qp-iter` (e.g. `BoxSet::new`) is a model error here.
impl From<qp_iter::DataError> for MpcError {
    fn from(e: qp_iter::DataError) -> Self {
        Self::Model(e.into())
    }
}
