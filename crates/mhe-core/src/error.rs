//! The one error type of `mhe-core`: bad configuration and bad input.
//!
//! Every variant names the offending field so a user can find and fix it. Numerical
//! outcomes of the K iterations (e.g. a non-finite iterate) are a status in the
//! [`crate::MheRecord`], never an error.

/// Errors raised when setting up an estimator or feeding it data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MheError {
    /// Invalid matrix / vector / set data (shape, NaN, not symmetric, not positive definite),
    /// raised by the `lti-model` validators; the field is named inside.
    #[error(transparent)]
    Model(#[from] lti_model::ModelError),
    /// Building the parametric QP or the iteration map Φ failed.
    #[error(transparent)]
    Qp(#[from] qp_iter::QpError),
    /// A scalar or integer parameter is outside its admissible range.
    #[error("`{name}` = {value} is out of range: must lie in {range}")]
    OutOfRange {
        /// Field name (`"horizon"`, `"eta"`, `"iterations"`).
        name: &'static str,
        /// The value given.
        value: f64,
        /// Admissible range, e.g. `"[0, 1)"`.
        range: &'static str,
    },
    /// A vector passed to the estimator has the wrong length.
    #[error("`{name}` has length {actual}, expected {expected}")]
    Length {
        /// Field name (`"u"`, `"y"`, `"prior"`).
        name: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        actual: usize,
    },
    /// A vector passed to the estimator has a NaN or infinite entry.
    #[error(
        "`{name}` has a non-finite entry {value} at index {index}; inputs and measurements must be finite"
    )]
    NonFinite {
        /// Field name (`"u"`, `"y"`, `"prior"`).
        name: &'static str,
        /// Index of the first offending entry.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A feature of the paper's problem (8) that this implementation does not cover.
    #[error("unsupported: {what}; {hint}")]
    Unsupported {
        /// What was asked for.
        what: String,
        /// How to get a supported problem.
        hint: String,
    },
    /// The condensed Hessian H_c of a window is (numerically) singular, so ℙ_t is not
    /// strongly convex and neither z* nor φ(K) is well defined.
    #[error(
        "the MHE problem with window length {window} is not strongly convex: λ_min(H_c) = {min_eigenvalue:e}, \
         λ_max(H_c) = {max_eigenvalue:e}; use η > 0 (η = 0 drops the prior and all but the newest stage) or weights that make \
         x̂ observable from the window"
    )]
    NotStronglyConvex {
        /// Window length m.
        window: usize,
        /// λ_min(H_c).
        min_eigenvalue: f64,
        /// λ_max(H_c).
        max_eigenvalue: f64,
    },
    /// A filter update produced a non-finite value or lost positive definiteness (the
    /// estimator is left unchanged).
    #[error("numerical failure at t = {t}: {reason}")]
    Numerical {
        /// Time step.
        t: usize,
        /// What failed.
        reason: String,
    },
    /// The exact reference solve of ℙ_t (Clarabel) failed.
    #[error("exact solve of the MHE problem at t = {t} failed: {reason}")]
    Reference {
        /// Time step.
        t: usize,
        /// Solver status or error.
        reason: String,
    },
}

/// Result alias for `mhe-core`.
pub type Result<T> = std::result::Result<T, MheError>;

/// Bad set or matrix data from `qp-iter` (e.g. `BoxSet::new`) is a model error here.
impl From<qp_iter::DataError> for MheError {
    fn from(e: qp_iter::DataError) -> Self {
        Self::Model(e.into())
    }
}
