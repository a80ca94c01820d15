//! closed-loop integration tests (one binary).
#![allow(clippy::unwrap_used)]

mod analysis;
mod certificate;
mod gamma13;
mod plants;
mod sim;
mod sweep;
