//! Sub-optimal MPC and sub-optimal MHE certified together (the paper's future work).
//!
//! Both optimisers are truncated: the MHE runs K_e iterations of Φ_e per step (Alg. 1) and
//! the MPC K_c iterations of Φ_c, warm-started from its previous sequence. The loop is four
//! interconnected subsystems (docs/theory.md, "Sub-optimal MPC and MHE together"):
//!
//! | node | subsystem | estimate |
//! | --- | --- | --- |
//! | 1 | plant x under the *applied* input u = π(x̂) + d, ‖d_t‖ ≤ δ_t | Assumption 4 with γ₁,₃ and γ₁,₄ |
//! | 2 | the MHE's ε_t | Prop. 1 with γ₂,₄ = C₃/(1 − φ_e) |
//! | 3 | the estimation error e_t | Prop. 3 with γ₃,₄ = √(2Λ^H̄_P)C₃ |
//! | 4 | the MPC's δ_t = ‖Uᴷᶜ_t − U*(x̂_t)‖ | γ₄,₁ = γ₄,₃ = φ_c L_U (1 + ω)/(1 − φ_c ω) |
//!
//! with L_U the Lipschitz constant of x ↦ U*(x) (the whole sequence) and ω = ‖W‖₂ of the
//! warm start W (√2 for shift-and-repeat, 1 for shift-and-zero or the previous sequence, 0
//! for a cold start). The small-gain condition is ρ(Γ) < 1 of the 4 × 4 gain matrix (the
//! estimates are sums, [`crate::small_gain`]); the product around every simple cycle is
//! reported beside it. Every gain is non-decreasing in φ_e(K_e) and φ_c(K_c), so the
//! certified set of (K_e, K_c) is an up-set: [`JointAnalysis::k_c_min`] bisects, and the
//! region is a staircase ([`JointAnalysis::region`]).
//!
//! In f32 ([`joint_rounding`], [`JointAnalysis::with_rounding`]) both maps carry their
//! K-step rounding models: the MHE's as in Theorem 1 in f32 (φ_u, the data gain g_d, x̂'s
//! propagation into e with a self-loop), the MPC's as Φ_u(K_c) and an input
//! B_zL_U + B_θ from ‖x̂‖ into δ, plus constants (ISS up to an offset).

mod certify;
mod gains;
mod region;
mod seeds;
mod trajectory;

pub use certify::{
    DeltaSeries, JointCertificate, JointOptions, certify_joint, delta_series, joint_rounding,
    warm_start_gain,
};
pub use gains::{JointAnalysis, JointGains, JointInputs, JointRounding, MpcMapInputs, NODE_NAMES};
pub use region::{JointRegion, RegionPoint};
pub use seeds::{SeedChecks, check_on_seeds};
pub use trajectory::{JointTrajectoryCheck, check_joint_trajectory};
