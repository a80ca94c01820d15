//! The global loop certificate per method (`certify --loop`, docs/theory.md §4): flat
//! records whose keys are the same for every outcome (a number that does not apply is
//! `null`), so a reader needs no variant logic. These records also read back
//! (`Deserialize`): a tool can load the section it wrote.

use serde::{Deserialize, Serialize};

/// `loop_methods` of the certify document: one row per method (filled by the tool, as the
/// other document records).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoopSection {
    /// The budget of the global φ* searches (estimated seconds of one core).
    pub global_seconds: Option<f64>,
    /// Wall-clock seconds of the section (K_lin, Theorem 1, the global certificate).
    pub elapsed_seconds: Option<f64>,
    /// One row per method (the eight presets).
    pub methods: Vec<LoopMethod>,
}

/// One method's three answers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoopMethod {
    /// The method's name (`"pg"`, `"admm-pr-jacobi"`, …).
    pub method: String,
    /// K_lin: the smallest grid K from which ρ_lin(K) < 1 (necessary), or `null`.
    pub k_lin: Option<usize>,
    /// Why `k_lin` is `null`.
    pub k_lin_note: Option<String>,
    /// Theorem 1's K_min, or `null`.
    pub theorem1_k_min: Option<usize>,
    /// Why `theorem1_k_min` is `null`.
    pub k_min_note: Option<String>,
    /// The global loop certificate.
    pub global: GlobalLoopOutcome,
    /// K_chain: the smallest K the iteration chain certified (Theorem L3b, PG and FISTA with their Jacobi variants;
    /// that K only), or `null`.
    #[serde(default)]
    pub k_chain: Option<usize>,
    /// The iteration chain's outcome as a sentence (the K checked), `null` for methods it does
    /// not model.
    #[serde(default)]
    pub chain: Option<String>,
}

/// The global loop certificate of one method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct GlobalLoopOutcome {
    /// `"certified"`, `"phi_ball_binds"`, `"optimum_binds"`, `"linear_unstable"`,
    /// `"impossible"`, `"search_failed"`, `"not_computed"` or `"not_applicable"`.
    pub verdict: String,
    /// The outcome as a sentence (what binds, with its numbers).
    pub reason: String,
    /// K_glob (every K ≥ it is certified), or `null`.
    pub k_glob: Option<usize>,
    /// φ*: the largest certified φ (also when the φ-ball binds).
    pub phi_star: Option<f64>,
    /// φ(K_glob) of the method; φ(k_max) when the φ-ball binds.
    pub phi_at_k: Option<f64>,
    /// The largest K scanned when the φ-ball binds.
    pub k_max: Option<usize>,
    /// −λ_max(LMI)/Σ scale of the independent check (of the box-free loop for
    /// `optimum_binds`).
    pub margin: Option<f64>,
    /// ρ of the certificate.
    pub rho: Option<f64>,
    /// γ of the certificate.
    pub gamma: Option<f64>,
    /// lim sup ‖x_t‖ ≤ gain_x·w̄.
    pub gain_x: Option<f64>,
    /// lim sup ‖x_t − x̂_t‖ ≤ gain_e·w̄.
    pub gain_e: Option<f64>,
    /// ρ of the exact-MHE linear loop (`linear_unstable`, `search_failed`).
    pub rho_lin: Option<f64>,
    /// The estimate of the φ* searches (`not_computed`).
    pub estimate_seconds: Option<f64>,
    /// The budget (`not_computed`).
    pub budget_seconds: Option<f64>,
}
