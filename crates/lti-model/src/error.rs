//! The one error type of `lti-model`: bad input and infeasible certificates.
//!
//! Every variant names the offending field (a matrix name such as `"A"`, or a scenario key
//! such as `"mhe.q"`) so a user can find and fix it. Numerical *outcomes* of iterative
//! routines that can legitimately fail to converge are reported as errors only at setup
//! time; nothing here is raised from a hot path.

/// Errors raised by `lti-model` constructors, certificates and scenario parsing.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
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
    /// The δ-IOSS certificate (Assumption 2, LMI (2)) fails: no P ≻ 0 exists for the data,
    /// or the P at hand does not satisfy LMI (2). `cause` says which condition fails and by
    /// how much.
    #[error("the δ-IOSS certificate (Assumption 2, LMI (2)) fails: {cause}")]
    LmiInfeasible {
        /// Which condition fails, with the measured numbers.
        cause: LmiFailure,
    },
    /// An iterative matrix-equation solver (Riccati, Lyapunov, expm) failed.
    #[error("{routine} failed: {reason}")]
    Numerical {
        /// The routine (`"DARE"`, `"Lyapunov"`, ...).
        routine: String,
        /// What happened and what to try.
        reason: String,
    },
    /// A value given through a Rust builder was refused: the checks of the scenario file,
    /// named by the Rust item the value came from (`ModelError::for_rust`, feature `spec`).
    #[error("{field}: {problem}")]
    Invalid {
        /// The Rust item (`MheBuilder::eta`, `LtiSystem::a`, `MpcBuilder::r`).
        field: String,
        /// What is wrong and how to fix it.
        problem: String,
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

/// `qp-iter`'s data errors (its matrix checks and [`crate::BoxSet`]) are the same cases
/// here, field for field.
impl From<qp_iter::DataError> for ModelError {
    fn from(e: qp_iter::DataError) -> Self {
        use qp_iter::DataError as D;
        match e {
            D::Shape {
                name,
                expected_rows,
                expected_cols,
                actual_rows,
                actual_cols,
            } => Self::Shape {
                name,
                expected_rows,
                expected_cols,
                actual_rows,
                actual_cols,
            },
            D::NonFinite {
                name,
                row,
                col,
                value,
            } => Self::NonFinite {
                name,
                row,
                col,
                value,
            },
            D::NotSymmetric { name, asymmetry } => Self::NotSymmetric { name, asymmetry },
            D::NotPositiveDefinite {
                name,
                min_eigenvalue,
            } => Self::NotPositiveDefinite {
                name,
                min_eigenvalue,
            },
            D::InvalidSet { name, reason } => Self::InvalidSet { name, reason },
            D::Numerical { routine, reason } => Self::Numerical { routine, reason },
            other => Self::Numerical {
                routine: "qp-iter".into(),
                reason: other.to_string(),
            },
        }
    }
}

/// Why the δ-IOSS certificate of Assumption 2 fails (the payload of
/// [`ModelError::LmiInfeasible`]). Every variant carries the measured quantities; the
/// messages say how to fix the data or where to supply P (scenario key `mhe.p`,
/// `cargo xtask certify --p-file`).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum LmiFailure {
    /// (A, C) has an unobservable mode with |λ| ≥ √η. LMI (2) restricted to x in that mode
    /// and w = 0 reads |λ|²‖x‖²_P ≤ η‖x‖²_P, so no P ≻ 0 exists, whatever E, Q, R.
    UnobservableMode {
        /// Spectral radius of A on the unobservable subspace of (A, C).
        modulus: f64,
        /// The η asked for.
        eta: f64,
    },
    /// η = 0 needs A x = 0 for every x with C x = 0 ((★) at w = 0 reads ‖Ax‖²_P ≤ 0 there),
    /// and A does not vanish on ker C.
    ZeroEtaNeedsDeadbeat {
        /// ‖A N‖₂ for an orthonormal basis N of ker C.
        gain: f64,
    },
    /// The extremal (maximal) solution of the Riccati equation is numerically singular
    /// although no unobservable mode is slower than √η: η is at the numerical feasibility
    /// boundary.
    SingularExtremalSolution {
        /// λ_min of the extremal solution.
        min_eigenvalue: f64,
        /// λ_max of the extremal solution.
        max_eigenvalue: f64,
        /// The floor ρ on λ_min(P)/λ_max(P).
        min_ratio: f64,
        /// The η asked for.
        eta: f64,
    },
    /// P has a diagonal entry that is not positive, so it is not positive definite (and
    /// its Jacobi scaling does not exist).
    PNonPositiveDiagonal {
        /// Row and column of the entry (0-based).
        index: usize,
        /// P(index, index).
        value: f64,
    },
    /// P is numerically singular relative to its own size: λ_min(P̂) ≤ ρ·λ_max(P̂) for the
    /// Jacobi-scaled P̂ = diag(P)^{−½}·P·diag(P)^{−½} (invariant under changes of the
    /// states' units).
    PNumericallySingular {
        /// λ_min(P̂).
        min_eigenvalue: f64,
        /// λ_max(P̂).
        max_eigenvalue: f64,
        /// The floor ρ on λ_min(P̂)/λ_max(P̂).
        min_ratio: f64,
    },
    /// P violates LMI (2) beyond the relative tolerance: μ(P) > τ, with μ the largest
    /// generalised eigenvalue of the LMI matrix J relative to the sum S of its terms
    /// (`lti_model::ioss` module doc, "Verification").
    Violated {
        /// μ(P) = max vᵀJv / vᵀSv ∈ [−1, 1].
        relative_violation: f64,
        /// τ.
        tolerance: f64,
        /// λ_max(J), unscaled (for reference; the test is on μ).
        lmi_max_eigenvalue: f64,
    },
}

impl std::fmt::Display for LmiFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Self::UnobservableMode { modulus, eta } => {
                let sqrt_eta = eta.sqrt();
                write!(
                    f,
                    "(A, C) has an unobservable mode with |λ| = {} ≥ √η = {}; LMI (2) needs \
                     every unobservable mode to decay faster than √η. ",
                    crate::numfmt::sig4(modulus),
                    crate::numfmt::sig4(sqrt_eta)
                )?;
                if modulus < 1.0 {
                    write!(
                        f,
                        "The pair is detectable: any η > {} (= |λ|²) may be feasible (scenario \
                         key `mhe.eta`).",
                        crate::numfmt::sig4(modulus * modulus)
                    )
                } else {
                    write!(
                        f,
                        "The pair is not detectable, so no η ∈ [0, 1) works: change C (scenario key \
                         `plant.c`: add a sensor that sees the mode)."
                    )
                }
            }
            Self::ZeroEtaNeedsDeadbeat { gain } => write!(
                f,
                "η = 0 needs A x = 0 for every x with C x = 0 (the output must fix the next state), \
                 but ‖A on ker C‖ = {}: use η > 0 (scenario key `mhe.eta`)",
                crate::numfmt::sig4(gain)
            ),
            Self::SingularExtremalSolution {
                min_eigenvalue,
                max_eigenvalue,
                min_ratio,
                eta,
            } => write!(
                f,
                "the extremal solution of the Riccati equation of LMI (2) is numerically singular \
                 (λ_min(P)/λ_max(P) = {:.3e} ≤ {min_ratio:.0e}; λ_min = {min_eigenvalue:.3e}, \
                 λ_max = {max_eigenvalue:.3e}) although no unobservable mode is slower than √η: \
                 at η = {eta} LMI (2) has no P that is resolvable in f64; use a larger η (scenario \
                 key `mhe.eta`), or supply P (scenario key `mhe.p`, `cargo xtask certify --p-file`)",
                ratio(min_eigenvalue, max_eigenvalue)
            ),
            Self::PNonPositiveDiagonal { index, value } => write!(
                f,
                "P is not positive definite: its diagonal entry ({index}, {index}) is {value:e} \
                 (≤ 0); supply a P ≻ 0 (scenario key `mhe.p`, `--p-file`) or omit it to have \
                 the maximal P computed"
            ),
            Self::PNumericallySingular {
                min_eigenvalue,
                max_eigenvalue,
                min_ratio,
            } => write!(
                f,
                "P is numerically singular relative to its size: λ_min(P̂)/λ_max(P̂) = {:.3e} ≤ {min_ratio:.0e} \
                 for P̂ = diag(P)^(-1/2)·P·diag(P)^(-1/2) (λ_min = {min_eigenvalue:.3e}, \
                 λ_max = {max_eigenvalue:.3e}); supply a P ≻ 0 whose \
                 smallest eigenvalue is resolvable in f64 (scenario key `mhe.p`, `--p-file`)",
                ratio(min_eigenvalue, max_eigenvalue)
            ),
            Self::Violated {
                relative_violation,
                tolerance,
                lmi_max_eigenvalue,
            } => write!(
                f,
                "P violates LMI (2): relative violation μ = max vᵀJv/vᵀSv = {relative_violation:.3e} > τ = \
                 {tolerance:.0e} (λ_max of the LMI matrix J = {lmi_max_eigenvalue:.3e}); fix P \
                 (scenario key `mhe.p`, `--p-file`) or omit it to have the maximal P computed"
            ),
        }
    }
}

fn ratio(lo: f64, hi: f64) -> f64 {
    if hi > 0.0 { lo / hi } else { f64::NAN }
}

/// Result alias for `lti-model`.
pub type Result<T> = std::result::Result<T, ModelError>;
