#![doc = include_str!("../README.md")]
//!
//! ## Contents
//!
//! Alg. 1 of Yang–Manzie–Pu as a simulation (plant + sub-optimal MHE + controller) and the
//! ISS analysis of Section III: every constant of Lemma 1, Props. 1–3 and Theorem 1, the
//! small-gain conditions (sg1)–(sg3), and the smallest certified iteration budget K.
//!
//! - [`analysis`]: Theorem 1's arithmetic (C₁…C₆, gains, slopes, premises, K_min).
//! - [`scenario`]: the scenario file (composing each layer's settings), resolved once
//!   ([`ResolvedScenario`]) and turned into a ready loop ([`ResolvedScenario::build_loop`]).
//! - [`sim`]: Alg. 1 as a simulation ([`ClosedLoop`]) of any estimator, controller and
//!   disturbance.
//! - [`linear`]: ρ_lin(K) and K_lin, the exact linear stability boundary where no constraint
//!   is active (the lifted LTI system of Alg. 1).
//! - [`bounded`]: the one bounded rule of every run (first failing step and signal).
//! - [`coverage`]: which certificate a configuration (method, K_e, controller, K_c) is
//!   under, and its verdict there (one decision for reproduce, sweeps and plots).
//! - [`plan`]: which K to simulate for a certificate, and the verdict.
//! - [`record`]: the per-step [`Trace`] of a run (with the MHE records), JSON output.
//! - [`gamma13`]: γ₁,₃ of Assumption 4 for the MPC on any plant (family bound by the
//!   S-procedure, partial and full free-set enumeration, typed void reasons, user values).

pub mod analysis;
pub mod baseline;
pub mod bounded;
pub mod budget;
pub mod certificate;
pub mod coverage;
pub mod gamma13;
pub mod joint;
pub mod linear;
pub mod plan;
pub mod record;
pub mod regional;
pub mod scenario;
pub mod sim;
pub mod small_gain;
pub mod sweep;

pub use record::{MheStep, MheTrace, Trace};
pub use scenario::{
    ControllerChoice, LoopOptions, ResolvedScenario, Scenario, ScenarioController,
    ScenarioEstimator, ScenarioLoop,
};
pub use sim::{ClosedLoop, ClosedLoopError};
