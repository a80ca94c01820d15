//! The one integration-test binary of `mhe-core` (the allocation test is separate:
//! it installs a counting global allocator).
#![allow(clippy::unwrap_used)]

mod common;

mod bookkeeping;
// Checked against an uncondensed Clarabel solve: with the `clarabel` feature (default).
#[cfg(feature = "clarabel")]
mod constrained;
mod convergence;
mod errors;
#[cfg(feature = "clarabel")]
mod exact;
mod kalman;
mod problem;
mod structured;
mod units;
