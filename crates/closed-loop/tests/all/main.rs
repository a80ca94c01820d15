//! closed-loop integration tests (one binary).
#![allow(clippy::unwrap_used)]

mod analysis;
mod certificate;
mod linear;
mod sim;
mod sweep;
