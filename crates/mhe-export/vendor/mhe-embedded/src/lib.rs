//! The certified sub-optimal MHE (Alg. 1 of the paper) for microcontrollers: `#![no_std]`,
//! no allocation, no dependencies beyond `core`.
//!
//! One [`Mhe::estimate`] is the estimator step of `mhe_core::MheEstimator`: the window
//! grows for t < M, the prior x̄ comes from a ring buffer of past estimates, the warm start
//! Σ_t, exactly K iterations of the certified method (projected gradient, V-FISTA, ADMM with
//! ρ and α, each optionally on the Jacobi-scaled problem), then x̂ₖ_{t−M_t|t} propagated
//! through the window to x̂_{t|t}. Every buffer is an array sized by const generics; the
//! problem data (ℙ_t for every window length, the model) is borrowed, normally from
//! `static` arrays that `cargo xtask export` generates.
//!
//! [`MheRt`] is the same estimator with the sizes read from the problem at run time and
//! every buffer in one caller-owned slice (the same operations in the same order, so the
//! same bits): what a host uses to replay the board's f32 arithmetic without compiling the
//! sizes in (the Python package's `dtype="float32"`).
//!
//! [`Mpc`] is the K_c-iteration MPC of the same loop (`mpc_core::SuboptimalMpc` with the
//! shift-and-repeat warm start): per call θ = x̂, K_c iterations of its method on the
//! condensed QP over the box 𝒰^N (the same kernel as the estimator's windows), u = the first
//! block of Uᴷᶜ; together they run the loop of the joint MPC + MHE certificate.
//!
//! A long PG or FISTA window (n_z past the std estimator's crossover) carries
//! [`Structured`] factors instead of H: H_c z through the dynamics in the std structured
//! product's order, as `mhe_core::structured` (the exporter stores A, E, C, F, 4Q, 2R once and
//! 4η^m P, η^{m−1−j} per window).
//!
//! **Bit identity.** The data are the std build's own numbers (H, F, q₀, the bounds, α, β,
//! ρ(H + ρI)⁻¹ and (H + ρI)⁻¹, the Jacobi d), and every operation here is the one the std
//! estimator performs on the portable kernel (`qp_iter::kernel::Kernel::portable`), in the
//! same order: products summed column by column from 0, no fused multiply–add, the same
//! clamp. So with `T = f64` the estimates equal the std `MheEstimator`'s on that kernel bit
//! for bit (the workspace's `xtask/src/export/tests.rs` and `tests_mpc.rs`), and the
//! exported C does the same operations. Against the AVX2 + FMA kernel the difference is
//! rounding only (measured in the tests).
//!
//! ```
//! use mhe_embedded::{Method, Mhe, Problem, WarmStart, Window};
//! // n_x = 1, n_u = 0, n_y = 1, w = (w¹, w²) ∈ ℝ², M = 1: windows m = 0 (n = 1) and
//! // m = 1 (n = 3), data made up for the example (the exporter writes real ones).
//! static W0: Window<'static, f64> = Window {
//!     n: 1, n_theta: 1, h: &[2.0], m_rho: &[], m_inv: &[], q0: &[0.0], f: &[-2.0],
//!     lower: &[f64::NEG_INFINITY], upper: &[f64::INFINITY], scaling: &[],
//!     step: 0.5, momentum: 0.0, inv_rho: 0.0, relaxation: 0.0, structured: None,
//! };
//! static W1: Window<'static, f64> = Window {
//!     n: 3, n_theta: 2,
//!     h: &[3.0, 0.0, 1.0, 0.0, 2.0, 0.0, 1.0, 0.0, 3.0],
//!     m_rho: &[], m_inv: &[], q0: &[0.0; 3], f: &[-1.6, 0.0, 0.0, 0.0, 0.0, -2.0],
//!     lower: &[f64::NEG_INFINITY, -0.1, -0.1], upper: &[f64::INFINITY, 0.1, 0.1],
//!     scaling: &[], step: 0.4, momentum: 0.0, inv_rho: 0.0, relaxation: 0.0,
//!     structured: None,
//! };
//! static WINDOWS: [Window<'static, f64>; 2] = [W0, W1];
//! static P: Problem<'static, f64> = Problem {
//!     nx: 1, nu: 0, ny: 1, nw1: 1, nw2: 1, horizon: 1, iterations: 20,
//!     method: Method::Pg, warm_start: WarmStart::Paper,
//!     a: &[0.9], b: &[], e: &[1.0], windows: &WINDOWS,
//! };
//! // Buffers: NX, NU, NY, M, NZ = NX + M·n_w, NTH = NX + M·(NU + NY).
//! let mut mhe = Mhe::<f64, 1, 0, 1, 1, 3, 2>::new(&P, [0.5]).unwrap();
//! assert_eq!(mhe.estimate(), &[0.5]); // t = 0: the prior
//! mhe.push(&[], &[1.0]).unwrap();
//! assert!(mhe.push(&[], &[f64::NAN]).is_err()); // refused, nothing changed
//! assert!(mhe.estimate()[0].is_finite());
//! ```
//!
//! The MPC (made-up data: N = 2, n_u = n_x = 1, U ∈ [−1, 1]²):
//!
//! ```
//! use mhe_embedded::{Method, Mpc, MpcProblem, Window};
//! static QP: Window<'static, f64> = Window {
//!     n: 2, n_theta: 1, h: &[4.0, 1.0, 1.0, 2.0], m_rho: &[], m_inv: &[], q0: &[0.0, 0.0],
//!     f: &[3.0, 1.0], lower: &[-1.0, -1.0], upper: &[1.0, 1.0], scaling: &[],
//!     step: 0.3, momentum: 0.0, inv_rho: 0.0, relaxation: 0.0,
//!     structured: None,
//! };
//! static MPC: MpcProblem<'static, f64> =
//!     MpcProblem { nx: 1, nu: 1, horizon: 2, iterations: 30, method: Method::Pg, qp: QP };
//! // Buffers: NX, NU, NSEQ = N·NU.
//! let mut mpc = Mpc::<f64, 1, 1, 2>::new(&MPC).unwrap();
//! let u = mpc.control(&[2.0]).unwrap(); // cold start, then K_c = 30 PG steps
//! assert_eq!(u, &[-1.0]);                // saturated: the unconstrained u₀ is −10/7
//! assert!(mpc.control(&[f64::NAN]).is_err());
//! ```

#![no_std]

mod data;
mod estimator;
mod mpc;
mod qp;
mod runtime;
mod scalar;
mod structured;

pub use data::{DataError, Method, Problem, WarmStart, Window};
pub use estimator::{Mhe, PushError};
pub use mpc::{Mpc, MpcError, MpcProblem};
pub use runtime::{MheRt, PushErrorRt};
pub use scalar::Scalar;
pub use structured::{Structured, SumOrder};
