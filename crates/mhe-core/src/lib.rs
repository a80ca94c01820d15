#![doc = include_str!("../README.md")]
//!
//! ## Contents
//!
//! The moving horizon estimator of Yang, Manzie, Pu (arXiv 2304.06216), Section II-B
//! (eqs. 8–10) and Alg. 1 steps 1–3: the MHE problem ℙ_t as a parametric QP, solved with
//! exactly K warm-started iterations of any iteration map Φ ([`qp_iter::IterationMap`]),
//! optionally also exactly (`qp_iter::active_set`) to record ε_t; and a Kalman filter baseline.
//!
//! - [`MheProblem`] / [`MheWindow`]: ℙ_t for every window length m = 0..M, with H_c, F_c,
//!   the paper's H_t, T, z̃_t, the weight matrix W_m, H̄ and L_Φ (certified and sampled).
//! - [`MheEstimator`]: Alg. 1 steps 1–3 (prior ring buffer, Σ_t warm start, Υ buffers),
//!   allocation-free per step (the exact solve for ε_t included); fills an [`MheRecord`].
//! - [`KalmanFilter`]: predictor-form Kalman filter, with fading memory for the exact
//!   comparison with the MHE.
//! - [`Estimator`]: the trait closed-loop code composes (both estimators implement it).
//!
//! ## Conventions (the closed-loop ISS analysis depends on them)
//!
//! **Time and window.** t is the number of (u, y) pairs pushed so far. The window at time
//! t has length M_t = min(M, t) and uses u_{t−M_t}, …, u_{t−1} and y_{t−M_t}, …, y_{t−1}
//! (trap 2). The estimate x̂_{t|t} is the last state of the window propagated through the
//! model, x̂_{i+1} = A x̂_i + B u_i + E ŵ¹_i. At t = 0 only the prior term remains and
//! x̂_{0|0} is the prior (its P-norm projection onto 𝒳, which is the prior itself since 𝒳
//! must be ℝ^{n_x}, see below).
//!
//! **Condensed coordinates.** The decision vector is
//! z_t = (x̂_{t−M_t|t}, ŵ_{t−M_t|t}, …, ŵ_{t−1|t}), ŵ_i = (ŵ¹_i, ŵ²_i) ∈ ℝ^{n_w1+n_w2}
//! (the paper: n_w1 = n_x, n_w2 = n_y; trap 4). ŷ is eliminated: ŷ_i = C x̂_i + F ŵ²_i.
//! The parameter is θ_t = (x^prior_{t−M_t}, u_{t−M_t..t−1}, y_{t−M_t..t−1}); advancing the
//! window only reloads θ. Index layout: [`problem::WindowLayout`].
//!
//! **Cost.** Eq. (9): V_MHE = 2η^{M_t}‖x̂_{t−M_t} − prior‖²_P +
//! Σ_{i=1}^{M_t} η^{i−1}(2‖ŵ_{t−i}‖²_Q + ‖ŷ_{t−i} − y_{t−i}‖²_R). With T, S mapping
//! (z, θ) to the paper's z_t of eq. (10) (which contains ŷ; trap 5) and Z̃ mapping θ to
//! z̃_t, V_MHE = ‖Tz + Sθ − Z̃θ‖²_{H_t}, so the QP handed to Φ is
//! min ½zᵀH_c z + (q₀ + F_cθ)ᵀz over z ∈ Z with
//! H_c = 2TᵀH_tT, F_c = 2TᵀH_t(S − Z̃), q₀ = 0.
//!
//! **Where ε, φ(K), L_Φ and H̄ live.** All in condensed coordinates, Euclidean norm:
//! ε_t = ‖zᴷ_t − z*_t‖₂ (the quantity φ(K) of the maps is certified for, since the maps run
//! on exactly this QP), L_Φ is the Lipschitz constant of θ ↦ z*(θ) from Euclidean θ to
//! Euclidean z, and the weight matrix is W_m = H_c/2 = TᵀH_tT, so
//! V_MHE(zᴷ) ≤ 2‖zᴷ − z*‖²_{W_m} + 2V_MHE(z*) (the step of Prop. 2) and
//! H̄ = sup_m λ_max(W_m) ([`MheProblem::h_bar`]). Note that θ contains u (the paper's z̃_t
//! does not): Lemma 1's ‖z̃_{t−1} − z̃_t‖ becomes ‖θ_{t−1} − θ_t‖ here.
//!
//! **Constraints.** ŵ ∈ 𝒲 (box) and x̂_{t−M_t|t} ∈ 𝒳 (box) form the box Z of the QP.
//! x̂_i ∈ 𝒳 for the later stages and ŷ_i ∈ 𝒴 are general rows l₀ − Eθ ≤ Gz ≤ u₀ − Eθ of
//! the QP (G, E from the prediction matrices; [`qp_iter::GeneralConstraints`]): PG and FISTA
//! project onto them exactly (certificate unchanged), ADMM splits on them (void
//! certificate, measured violation in `MheRecord::violation`), and the exact solve for ε_t
//! uses the same rows (Goldfarb–Idnani). Their bounds move with the inputs in θ, so the
//! certified L_Φ of Lemma 1 is void (+∞, [`problem::LIPSCHITZ_VOID_REASON`]); the sampled
//! estimate is still reported.
//!
//! **Prior (trap 1).** For t ≤ M the prior is the initial x̄₀; for t > M it is
//! x̂ᴷ_{t−M|t−M}, the estimate the estimator itself returned M steps earlier (ring buffer
//! of the last M estimates).
//!
//! **Warm start Σ_t (trap 3).** z⁰_0 = x̄₀. For 1 ≤ t ≤ M (the window grows from t − 1 to
//! t) z⁰_t = (zᴷ_{t−1}, 0): the previous variables keep their meaning (same window start)
//! and one whole stage ŵ of n_w zeros is appended. For t > M, z⁰_t = zᴷ_{t−1} unchanged
//! (Σ = I, the certified default, [`WarmStart::Paper`]). [`WarmStart::Shifted`] (an
//! extension, not covered by the analysis) drops the oldest stage, propagates x̂ one step
//! with the estimated ŵ¹, and zero-fills the newest stage. The warm start carries no dual
//! (`warm_start(z⁰, None)`), the setting ADMM's eq. (11) certificate covers.
//!
//! ## Certified L_Φ (Lemma 1, trap 8)
//! With q(θ) = q₀ + F_cθ, the minimiser is z*(θ) = argmin_{z∈Z} ½‖z + H_c⁻¹q(θ)‖²_{H_c}
//! (the two objectives differ by a constant), i.e. the H_c-weighted projection of
//! −H_c⁻¹q(θ) onto the convex set Z. Projections onto a closed convex set are
//! non-expansive in the norm that defines them, so
//! ‖z*(a) − z*(b)‖_{H_c} ≤ ‖H_c⁻¹F_c(a − b)‖_{H_c} = ‖H_c^{−1/2}F_c(a − b)‖₂
//! ≤ ‖H_c^{−1/2}F_c‖₂‖a − b‖₂, and ‖v‖₂ ≤ ‖v‖_{H_c}/√λ_min(H_c) gives
//! L_Φ(m) = ‖H_c^{−1/2}F_c‖₂/√λ_min(H_c) ([`MheWindow::lipschitz_certified`]); the
//! sampled estimate ([`MheWindow::sample_lipschitz`]) is reported next to it.
//!
//! ## Kalman filter comparison
//! With 𝒲 = ℝ^{n_w} and exact solves, for t ≤ M the MHE *is* the η-discounted
//! full-information estimator, whose estimate equals that of
//! [`KalmanFilter::matching_mhe`] (fading memory λ = η, Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹,
//! Σ_v = R⁻¹; derivation in [`kalman`]). For t > M they differ: the MHE's arrival cost is
//! 2η^M‖x̂_{t−M} − x̂ᴷ_{t−M|t−M}‖²_P (its own old estimate with the fixed weight P), while
//! the filter carries the exact arrival cost (mean and information it propagated itself).
//! The MHE then equals the matching filter *restarted* at t − M from (x̂ᴷ_{t−M|t−M}, (2P)⁻¹)
//! and run over the window; the difference to the un-restarted filter is bounded, not zero.

pub mod builder;
pub mod error;
pub mod estimator;
pub mod kalman;
pub mod memory;
pub mod problem;
pub mod record;
pub mod settings;
pub mod structured;

pub use builder::MheBuilder;
pub use error::{MheError, Result};
pub use estimator::{Estimator, MheConfig, MheEstimator, WarmStart};
pub use kalman::KalmanFilter;
pub use problem::{
    LipschitzEstimate, LipschitzSampling, MheProblem, MheSets, MheWeights, MheWindow,
};
/// The iteration maps Φ this crate runs (`qp_iter::Method`, `qp_iter::pg`, …), re-exported so
/// that a user needs no separate `qp-iter` dependency.
pub use qp_iter;
pub use qp_iter::Method;
pub use record::MheRecord;
pub use settings::{MheSettings, RawMhe};

#[cfg(test)]
mod send_sync {
    fn assert_send<T: Send>() {}
    fn assert_sync<T: Sync>() {}
    #[test]
    fn types_are_send() {
        assert_send::<crate::MheEstimator<qp_iter::pg::ProjectedGradient>>();
        assert_send::<crate::KalmanFilter>();
        assert_sync::<crate::MheProblem>();
        assert_send::<crate::MheRecord>();
    }
}
