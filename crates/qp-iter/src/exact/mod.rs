//! The exact solvers, references for the iteration maps (ε_t = ‖z_t^K − z*_t‖ in analysis
//! runs, the exact MPC, the checks of every certificate):
//!
//! | module | solves | used for |
//! | --- | --- | --- |
//! | [`active_set`] | a strictly convex QP over a box, primal active set with a warm-started free set and an updated Cholesky factor of H_FF (allocation-free per solve) | the exact MHE beside the K-iteration one; [`active_set::ExactSolver`] falls back in order |
//! | [`dual_active_set`] | general rows l ≤ Gz ≤ u (and a box): Goldfarb–Idnani, typed infeasibility | the exact MPC with state constraints, projections onto general sets |
//! | [`reference`](mod@reference) | any QP of the crate, by Clarabel (interior point) | the independent answer the tests compare with; the last fallback (cargo feature `clarabel`, on by default) |
//!
//! The crate root re-exports each module under its old path (`qp_iter::active_set`, …).

pub mod active_set;
pub mod dual_active_set;
mod fallback;
mod free_factor;
mod parametric_dual;
#[cfg(feature = "clarabel")]
pub mod reference;
