#![doc = include_str!("../README.md")]
//!
//! ## Contents
//!
//! Constrained linear time-invariant plants for sub-optimal moving horizon estimation
//! (Yang, Manzie, Pu, arXiv 2304.06216, Section II):
//!
//! - [`LtiSystem`]: eq. (1), x⁺ = Ax + Bu + w¹, y = Cx + w², validated at construction;
//!   observability and detectability checks.
//! - [`sets`]: 𝒳, 𝒰, 𝒴, 𝒲 as convex sets with exact in-place projections.
//! - [`disturbance`]: seeded disturbance models (uniform on a box, Gaussian).
//! - [`riccati`]: zero-order-hold discretisation, DARE (MPC terminal cost) and discrete
//!   Lyapunov equations, each verified by its residual.
//! - [`ioss`]: the δ-IOSS certificate of Assumption 2: find or verify P ≻ 0 satisfying
//!   LMI (2) for given (A, C, η, Q, R), and the smallest feasible η.
//! - `spec` (feature `spec`): the scenario-file format every layer parses its settings
//!   with, and the plant-level sections (`[plant]`, `[sets]`, `[noise]`, `[simulation]`).
//!
//! Every fallible constructor returns [`ModelError`], whose variants name the offending
//! matrix or scenario key.

pub mod disturbance;
pub mod error;
pub mod ioss;
pub mod matrix;
pub mod numfmt;
pub mod presets;
pub mod riccati;
pub mod sets;
#[cfg(feature = "spec")]
pub mod spec;
pub mod spectral;
pub mod system;
pub mod vecmath;
pub mod work_count;

pub use error::{LmiFailure, ModelError, Result};
/// The linear algebra crate of every matrix in the API (`faer::Mat`), re-exported so that a
/// user's `faer` is the same version.
pub use faer;
pub use sets::{BoxSet, ConvexSet, Polytope, Projection, Set};
pub use system::LtiSystem;
