#![doc = include_str!("../README.md")]
//!
//! ## Contents
//!
//! Iteration maps Φ for parametric QPs (Assumption 5 of Yang–Manzie–Pu, eq. (11)):
//!
//! minimise ½ zᵀHz + (q₀ + Fθ)ᵀz subject to z ∈ Z (a box with ±∞ bounds) and, optionally,
//! l₀ − Eθ ≤ Gz ≤ u₀ − Eθ ([`GeneralConstraints`]).
//!
//! - [`ParametricQp`]: validated problem data (H ≻ 0 symmetric, shapes, finite entries).
//! - [`IterationMap`]: the algorithm object Φ (setup data only, `Send + Sync`) with a
//!   separate [`IterationMap::State`] holding iterates, momentum, duals and the loaded
//!   linear term. Loading θ, warm/cold starting and stepping allocate nothing.
//! - [`Certificate`]: rate, prefactor, bounded quantity and norm, so that
//!   φ(K) = prefactor · rateᴷ and the smallest K for a given accuracy are exact functions.
//! - Drivers [`run_fixed`] (exactly K steps) and [`run_until`] (to a tolerance, with an
//!   observer) live outside the trait.
//! - [`kernel`]: the dense kernels every step runs (padded column layout, one fused pass
//!   over the matrix per step, AVX2 + FMA chosen at run time, else a portable path).
//!
//! This crate knows parametric QPs only: never A, B or C.

pub mod admm;
pub mod admm_general;
pub mod certificate;
pub mod driver;
pub mod error;
pub mod exact;
pub mod fista;
pub mod general_projection;
pub mod iterations;
pub mod kernel;
pub mod linearise;
pub mod matrix;
pub mod method;
pub mod operator;
pub mod pg;
pub mod problem;
pub mod rounding;
pub mod scaled;
pub mod sets;

pub use certificate::{BoundedQuantity, CertNorm, Certificate};
pub use driver::{RunResult, RunStatus, run_fixed, run_until};
pub use error::{ConstraintRow, DataError, QpError, Result};
#[cfg(feature = "clarabel")]
pub use exact::reference;
pub use exact::{active_set, dual_active_set};
pub use iterations::{Iterations, IterationsError};
pub use linearise::Linearise;
pub use method::{Family, Method, MethodKind, MethodMap, MethodState, Scaling};
pub use problem::{GeneralConstraints, ParametricQp};
pub use sets::{BoxSet, ConvexSet, Projection};

/// The largest iteration budget (K of the MHE, K_c of the MPC) any scenario, sweep or
/// command accepts: each time step runs K iterations, and a K beyond it is not practical
/// to run. The one limit behind `mhe.iterations`, `mpc.iterations`, a sweep's `k` and
/// `k_c`.
pub const MAX_ITERATIONS: usize = 10_000_000;

/// The iteration map Φ of Assumption 5: z^{k+1} = Φ(z^k, θ).
///
/// The implementor holds setup data only (H, step sizes, factorisations, the certificate)
/// and is shared by reference across threads. Everything that changes during a solve
/// lives in [`IterationMap::State`], created once by [`IterationMap::new_state`].
///
/// None of `load`, `warm_start`, `cold_start`, `step` and `iterate` allocates.
pub trait IterationMap: Send + Sync + std::fmt::Debug {
    /// Per-solve state: iterate, auxiliary sequences, loaded linear term.
    type State: Send + std::fmt::Debug;

    /// Short method name (`"pg"`, `"fista"`, `"admm"`).
    fn name(&self) -> &'static str;

    /// The problem this map was set up for.
    fn problem(&self) -> &ParametricQp;

    /// A fresh state (allocates; call once at setup). Its linear term is q₀ (θ = 0) and
    /// its iterate is the cold start.
    fn new_state(&self) -> Self::State;

    /// Loads parameters: linear term q = q₀ + Fθ. Keeps the current iterate.
    ///
    /// `theta.len()` must equal [`ParametricQp::n_theta`] (debug-asserted; hot path).
    fn load(&self, state: &mut Self::State, theta: &[f64]);

    /// Warm start from a primal point `z0` (and a dual, for methods that carry one).
    /// Resets auxiliary sequences (e.g. FISTA momentum).
    fn warm_start(&self, state: &mut Self::State, z0: &[f64], dual: Option<&[f64]>);

    /// Cold start: the projection of 0 onto Z, duals zero, momentum reset.
    fn cold_start(&self, state: &mut Self::State);

    /// One application of Φ.
    fn step(&self, state: &mut Self::State);
    /// `k` applications of Φ. A dispatching map ([`MethodMap`]) overrides it to choose the
    /// concrete method once for all `k` steps.
    fn run_steps(&self, state: &mut Self::State, k: usize) {
        for _ in 0..k {
            self.step(state);
        }
    }

    /// The current iterate z^k (the point the certificate speaks about, and the one a
    /// caller should use: feasible for PG and FISTA; see each method for ADMM).
    fn iterate<'s>(&self, state: &'s Self::State) -> &'s [f64];

    /// The dual iterate, for methods that carry one.
    fn dual<'s>(&self, _state: &'s Self::State) -> Option<&'s [f64]> {
        None
    }

    /// The largest violation of the constraints (the box and, with general rows, the rows
    /// with the loaded θ's bounds) by [`IterationMap::iterate`]: 0 for a feasible iterate
    /// (PG, FISTA, box-only ADMM's v), the measured premise failure of Assumption 5 for a
    /// method feasible only in the limit (ADMM split on general rows, design trap 7).
    fn violation(&self, state: &Self::State) -> f64 {
        general_projection::box_violation(self.problem(), self.iterate(state))
    }

    /// The certified contraction φ(K) of eq. (11) for this map.
    fn certificate(&self) -> &Certificate;

    /// Runs the map's dense steps on `kernel` instead of the detected one
    /// ([`kernel::Kernel::portable`]: the arithmetic that `mhe-embedded` and the C of
    /// `cargo xtask export` reproduce bit for bit). Maps without a dense kernel ignore it.
    fn set_kernel(&mut self, _kernel: kernel::Kernel) {}

    /// Number of matrix–vector products (or triangular-solve pairs) one step performs.
    fn matvecs_per_step(&self) -> usize {
        1
    }
}
