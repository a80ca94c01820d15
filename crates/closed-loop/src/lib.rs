#![doc = include_str!("../README.md")]
//!
//! ## Contents
//!
//! Alg. 1 of Yang–Manzie–Pu as a simulation (plant + sub-optimal MHE + controller), the
//! scenario file that composes each layer's settings, and Monte-Carlo runs of any closed
//! loop. The ISS analysis of Section III (Theorem 1's certificate, K_min, K_lin) is the
//! crate `iss-certificate`, one layer above; the sweep engine (files, locks, merge) is
//! `cargo xtask sweep`.
//!
//! - [`scenario`]: the scenario file (composing each layer's settings), resolved once
//!   ([`ResolvedScenario`]) and turned into a ready loop ([`ResolvedScenario::build_loop`]).
//! - [`sim`]: Alg. 1 as a simulation ([`ClosedLoop`]) of any estimator, controller and
//!   disturbance.
//! - [`bounded`]: the one bounded rule of every run (first failing step and signal).
//! - [`monte_carlo`]: runs of any estimator and controller (a user's own, with its own
//!   error type), seeded per run, with the per-run [`metrics`] and the bounded rule.
//! - [`record`]: the per-step [`Trace`] of a run (with the MHE records), JSON output.

pub mod baseline;
pub mod bounded;
pub mod metrics;
pub mod monte_carlo;
pub mod record;
pub mod scenario;
pub mod sim;

pub use record::{MheStep, MheTrace, Trace};
pub use scenario::{
    ControllerChoice, LoopOptions, ResolvedScenario, Scenario, ScenarioController,
    ScenarioEstimator, ScenarioLoop,
};
pub use sim::{ClosedLoop, ClosedLoopError};
