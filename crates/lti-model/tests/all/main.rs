//! The one integration-test binary of `lti-model` (one binary per crate keeps link time down).
#![allow(clippy::unwrap_used)]

mod disturbance;
mod ioss;
mod ioss_any_e;
mod ioss_relative;
mod ioss_scale;
mod ioss_units;
mod names;
mod numerics;
mod sets;
mod spectral;
mod system;
