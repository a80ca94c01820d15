//! The one error type of `lti-model`: bad input and infeasible certificates.
//!
//! Every variant names the offending field (a matrix name such as `"A"`, or a scenario key
//! such as `"mhe.q"`) so a user can find and fix it. Numerical *outcomes* of iterative
//! routines that can legitimately fail to converge are reported as errors only at setup
//! time; nothing here is raised from a hot path.

/// Errors raised by `lti-model` constructors, certificates and scenario parsing.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// A matrix or vector has the wrong shape.
    #[error(
        "`{name}` has shape {actual_rows}x{actual_cols}, expected {expected_rows}x{expected_cols}"
    )]
    Shape {
        /// Name of the matrix or vector (paper symbol or scenario key).
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
    /// A weight that must be symmetric is not.
    #[error("`{name}` is not symmetric (max |M - Mᵀ| = {asymmetry:e}); pass a symmetric matrix")]
    NotSymmetric {
        /// Name of the matrix.
        name: String,
        /// Largest absolute entry of M − Mᵀ.
        asymmetry: f64,
    },
    /// A weight that must be positive definite is not.
    #[error(
        "`{name}` is not positive definite (smallest eigenvalue {min_eigenvalue:e}); use a symmetric matrix with positive eigenvalues"
    )]
    NotPositiveDefinite {
        /// Name of the matrix.
        name: String,
        /// Its smallest eigenvalue.
        min_eigenvalue: f64,
    },
    /// A scalar parameter is outside its admissible range.
    #[error("`{name}` = {value} is out of range: must lie in {range}")]
    OutOfRange {
        /// Name of the parameter (e.g. `"eta"`).
        name: String,
        /// The value given.
        value: f64,
        /// Human-readable admissible range, e.g. `"[0, 1)"`.
        range: String,
    },
    /// A set is empty or malformed (e.g. a box with lower > upper).
    #[error("set `{name}` is invalid: {reason}")]
    InvalidSet {
        /// Name of the set.
        name: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The δ-IOSS LMI (Assumption 2) has no positive definite solution for the data.
    #[error("the δ-IOSS LMI (Assumption 2) is infeasible: {reason}")]
    LmiInfeasible {
        /// Why: undetectable pair, η too small, a supplied P that violates the LMI, ...
        reason: String,
    },
    /// An iterative matrix-equation solver (Riccati, Lyapunov, expm) failed.
    #[error("{routine} failed: {reason}")]
    Numerical {
        /// The routine (`"DARE"`, `"Lyapunov"`, ...).
        routine: String,
        /// What happened and what to try.
        reason: String,
    },
    /// A scenario file could not be parsed or validated.
    #[error("scenario: key `{key}`: {problem}")]
    Scenario {
        /// Dotted key path inside the TOML file (e.g. `"mhe.eta"`), or `"<file>"`.
        key: String,
        /// What is wrong and how to fix it.
        problem: String,
    },
}

impl ModelError {
    /// Prefixes the field name of a shape / finiteness / weight error with `prefix.`
    /// so that errors raised on a matrix inside a scenario name the scenario key.
    #[must_use]
    pub fn in_context(self, prefix: &str) -> Self {
        let join = |n: String| {
            if prefix.is_empty() {
                n
            } else {
                format!("{prefix}.{n}")
            }
        };
        match self {
            Self::Shape {
                name,
                expected_rows,
                expected_cols,
                actual_rows,
                actual_cols,
            } => Self::Shape {
                name: join(name),
                expected_rows,
                expected_cols,
                actual_rows,
                actual_cols,
            },
            Self::NonFinite {
                name,
                row,
                col,
                value,
            } => Self::NonFinite {
                name: join(name),
                row,
                col,
                value,
            },
            Self::NotSymmetric { name, asymmetry } => Self::NotSymmetric {
                name: join(name),
                asymmetry,
            },
            Self::NotPositiveDefinite {
                name,
                min_eigenvalue,
            } => Self::NotPositiveDefinite {
                name: join(name),
                min_eigenvalue,
            },
            Self::OutOfRange { name, value, range } => Self::OutOfRange {
                name: join(name),
                value,
                range,
            },
            Self::InvalidSet { name, reason } => Self::InvalidSet {
                name: join(name),
                reason,
            },
            other => other,
        }
    }
}

/// Result alias for `lti-model`.
pub type Result<T> = std::result::Result<T, ModelError>;
