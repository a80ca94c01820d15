//! Setup-time errors of `qp-iter`. Numerical outcomes of a run are a [`crate::RunStatus`].

/// Errors raised when building a problem or an iteration map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum QpError {
    /// Invalid matrix / vector / set data (shape, NaN, not symmetric, not PD, empty box).
    #[error(transparent)]
    Data(#[from] DataError),
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
        constraint: Option<ConstraintRow>,
    },
    /// The exact reference solver (Clarabel) did not solve the problem.
    #[error("reference solver: {status}")]
    Reference {
        /// Clarabel's status.
        status: String,
    },
}

/// Invalid problem data: what [`crate::ParametricQp`], [`crate::BoxSet`] and the
/// [`crate::matrix`] checks reject, each naming the offending matrix, vector or set
/// (`lti_model::ModelError` converts from it variant by variant).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DataError {
    /// A matrix or vector has the wrong shape.
    #[error(
        "`{name}` has shape {actual_rows}x{actual_cols}, expected {expected_rows}x{expected_cols}"
    )]
    Shape {
        /// Name of the matrix or vector.
        name: String,
        /// Expected number of rows.
        expected_rows: usize,
        /// Expected number of columns.
        expected_cols: usize,
        /// Actual number of rows.
        actual_rows: usize,
        /// Actual number of columns.
        actual_cols: usize,
    },
    /// A matrix or vector contains NaN or ±∞.
    #[error(
        "`{name}` has a non-finite entry {value} at ({row}, {col}); all entries must be finite"
    )]
    NonFinite {
        /// Name of the matrix or vector.
        name: String,
        /// Row of the first offending entry.
        row: usize,
        /// Column of the first offending entry.
        col: usize,
        /// The offending value.
        value: f64,
    },
    /// A matrix that must be symmetric is not.
    #[error("`{name}` is not symmetric (max |M - Mᵀ| = {asymmetry:e}); pass a symmetric matrix")]
    NotSymmetric {
        /// Name of the matrix.
        name: String,
        /// Largest absolute entry of M − Mᵀ.
        asymmetry: f64,
    },
    /// A matrix that must be positive definite is not.
    #[error(
        "`{name}` is not positive definite (smallest eigenvalue {min_eigenvalue:e}); use a symmetric matrix with positive eigenvalues"
    )]
    NotPositiveDefinite {
        /// Name of the matrix.
        name: String,
        /// Its smallest eigenvalue.
        min_eigenvalue: f64,
    },
    /// A set is empty or malformed (e.g. a box with lower > upper).
    #[error("set `{name}` is invalid: {reason}")]
    InvalidSet {
        /// Name of the set.
        name: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A factorisation or eigenvalue routine failed at setup.
    #[error("{routine} failed: {reason}")]
    Numerical {
        /// The routine.
        routine: String,
        /// What happened and what to try.
        reason: String,
    },
}

/// A row of a QP's constraints: a bound of the box (z_i) or a row of G (the row an exact
/// solver could not meet).
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

/// Result alias for `qp-iter`.
pub type Result<T> = std::result::Result<T, QpError>;
