//! Setup-time errors of `qp-iter`. Numerical outcomes of a run are a [`crate::RunStatus`].

/// Errors raised when building a problem or an iteration map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum QpError {
    /// Invalid matrix / vector / set data (shape, NaN, not symmetric, not PD, empty box).
    #[error(transparent)]
    Model(#[from] lti_model::ModelError),
    /// A method name other than the named methods of [`crate::method::Method`].
    #[error(
        "unknown method `{name}`; use one of {known} (each optionally with \"-jacobi\"), or a table {{ method = \"…\", … }} with its parameters"
    )]
    UnknownMethod {
        /// The name given.
        name: String,
        /// The names the method list knows, quoted and comma-separated.
        known: String,
    },
    /// A method parameter is invalid (step size, penalty, tolerance).
    #[error("parameter `{name}` = {value} is invalid: {reason}")]
    Parameter {
        /// Parameter name.
        name: String,
        /// Value given.
        value: f64,
        /// What is required.
        reason: String,
    },
    /// An exact solver stopped without a verified optimum (iteration limit, a failed KKT
    /// check or a numerically singular subproblem).
    #[error("{solver} solver did not converge after {iterations} iterations: {reason}")]
    NotConverged {
        /// Which solver (`"active set"`).
        solver: &'static str,
        /// Iterations used.
        iterations: usize,
        /// What went wrong, and what to do.
        reason: String,
    },
    /// The constraints have no common point (box and general rows for this θ).
    #[error(
        "{solver}: the constraints are infeasible ({detail}); loosen the bounds of the sets involved"
    )]
    Infeasible {
        /// Which solver detected it.
        solver: &'static str,
        /// Which constraint could not be met, or the solver's status.
        detail: String,
        /// The row the dual active set could not add (`None` from Clarabel).
        constraint: Option<crate::dual_active_set::ConstraintRow>,
    },
    /// The exact reference solver (Clarabel) did not solve the problem.
    #[error("reference solver: {status}")]
    Reference {
        /// Clarabel's status.
        status: String,
    },
}

/// Result alias for `qp-iter`.
pub type Result<T> = std::result::Result<T, QpError>;
