//! The integration-test binary of `mpc-core` (allocation counting lives in `tests/alloc.rs`).
#![allow(clippy::unwrap_used)]

mod common;
mod constrained;
mod errors;
mod exact;
mod free_sets;
mod lipschitz;
mod lqr;
mod psd_weight;
mod suboptimal;
