//! δ-IOSS certificate (Assumption 2, LMI (2)).
//!
//! Implementation in progress: signatures are fixed, bodies land next.

use faer::{Mat, MatRef};
use serde::Serialize;

use crate::error::{ModelError, Result};
use crate::system::LtiSystem;

/// Default tolerance on the largest eigenvalue of the LMI matrix, relative to
/// max(1, ‖P‖, ‖Q‖, ‖R‖).
pub const LMI_TOL: f64 = 1e-9;

/// A verified solution P of LMI (2) for (A, C, η, Q, R).
#[derive(Debug, Clone)]
pub struct IossCertificate {
    /// P ≻ 0 of LMI (2); W_δ(x, x') = ‖x − x'‖²_P (eq. 3).
    pub p: Mat<f64>,
    /// Decay rate η ∈ [0, 1).
    pub eta: f64,
    /// Disturbance weight Q, (n_w1 + n_w2) square.
    pub q: Mat<f64>,
    /// Output weight R, n_y square.
    pub r: Mat<f64>,
    /// λ_min(P).
    pub p_min_eigenvalue: f64,
    /// λ_max(P).
    pub p_max_eigenvalue: f64,
    /// Largest eigenvalue of the LMI matrix (≤ tolerance when the certificate is valid).
    pub lmi_max_eigenvalue: f64,
    /// Tolerance the LMI check used.
    pub lmi_tolerance: f64,
    /// How P was obtained (`"riccati-value-iteration"`, `"user"`).
    pub method: String,
    /// Iterations of the construction (0 for a user-supplied P).
    pub iterations: usize,
}

/// JSON form of [`IossCertificate`] (matrices as row-major nested arrays).
#[derive(Debug, Clone, Serialize)]
pub struct IossReport {
    /// P.
    pub p: Vec<Vec<f64>>,
    /// η.
    pub eta: f64,
    /// Q.
    pub q: Vec<Vec<f64>>,
    /// R.
    pub r: Vec<Vec<f64>>,
    /// λ_min(P).
    pub p_min_eigenvalue: f64,
    /// λ_max(P).
    pub p_max_eigenvalue: f64,
    /// Largest eigenvalue of the LMI matrix.
    pub lmi_max_eigenvalue: f64,
    /// Tolerance used for the LMI check.
    pub lmi_tolerance: f64,
    /// All eigenvalues of the LMI matrix, ascending.
    pub lmi_eigenvalues: Vec<f64>,
    /// Construction method.
    pub method: String,
    /// Iterations of the construction.
    pub iterations: usize,
}

/// Computes P ≻ 0 satisfying LMI (2), or `ModelError::LmiInfeasible` saying why not.
pub fn certify(sys: &LtiSystem, eta: f64, q: MatRef<'_, f64>, r: MatRef<'_, f64>) -> Result<IossCertificate> {
    let _ = (sys, eta, q, r);
    Err(ModelError::LmiInfeasible { reason: "not implemented yet".into() })
}

/// Verifies a user-supplied P against LMI (2).
pub fn verify(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
) -> Result<IossCertificate> {
    let _ = (sys, eta, q, r, p);
    Err(ModelError::LmiInfeasible { reason: "not implemented yet".into() })
}

/// The LMI matrix of (2) for a given P (⪯ 0 iff P certifies δ-IOSS with (η, Q, R)).
pub fn lmi_matrix(sys: &LtiSystem, eta: f64, q: MatRef<'_, f64>, r: MatRef<'_, f64>, p: MatRef<'_, f64>) -> Mat<f64> {
    let _ = (sys, eta, q, r, p);
    Mat::zeros(0, 0)
}
