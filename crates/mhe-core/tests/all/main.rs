//! The one integration-test binary of `mhe-core` (the allocation test is separate:
//! it installs a counting global allocator).
#![allow(clippy::unwrap_used)]

mod common;

mod bookkeeping;
mod constrained;
mod convergence;
mod errors;
mod exact;
mod kalman;
mod problem;
mod structured;
mod units;
