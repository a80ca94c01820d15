//! closed-loop integration tests (one binary).
#![allow(clippy::unwrap_used)]

mod analysis;
mod sim;
mod sweep;
