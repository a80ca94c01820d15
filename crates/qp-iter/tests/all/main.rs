//! Integration tests of `qp-iter` (one binary): certificates, method behaviour, the
//! Clarabel reference and input validation. The allocation test is `tests/alloc.rs`
//! (its global allocator must not count this binary's work).
#![allow(clippy::unwrap_used)]

mod active_set;
mod behaviour;
mod certificates;
mod common;
mod errors;
mod general;
mod general_maps;
mod premise;
mod reference;
mod scaled;
