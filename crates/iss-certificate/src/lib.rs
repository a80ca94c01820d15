#![doc = include_str!("../README.md")]
//!
//! ## Contents
//!
//! The ISS analysis of Section III of Yang–Manzie–Pu for the closed loop that
//! `closed-loop` simulates: every constant of Lemma 1, Props. 1–3 and Theorem 1, the
//! small-gain conditions (sg1)–(sg3), the smallest certified iteration budget K, and the
//! exact linear boundary K_lin below which no certificate can go.
//!
//! - [`model`]: a loop built from Rust values ([`LoopModel`]) and its certificate in one
//!   call ([`certify`]): K_min per method and the verdict at any K.
//! - [`certificate`]: Theorem 1 for a resolved scenario ([`certificate::certify_closed_loop`]):
//!   every premise with its margin, K_min per method.
//! - [`analysis`]: Theorem 1's arithmetic (C₁…C₆, gains, slopes, premises, K_min).
//! - [`asymptotic`]: what Theorem 1 guarantees: the certified asymptotic gains
//!   lim sup‖x‖ ≤ g_x·w̄, lim sup ε ≤ g_ε·w̄, lim sup‖e‖ ≤ g_e·w̄, and the measured ones of a run.
//! - [`small_gain`]: the sum-form small-gain conditions and their cycles.
//! - [`gamma13`]: γ₁,₃ of Assumption 4 for the MPC on any plant (family bound by the
//!   S-procedure, partial and full free-set enumeration, typed void reasons, user values).
//! - [`joint`]: sub-optimal MPC and MHE together (the 4×4 gain matrix, the (K_e, K_c) region).
//! - [`linear`]: ρ_lin(K) and K_lin, the exact linear stability boundary where no constraint
//!   is active (the lifted LTI system of Alg. 1).
//! - [`lure`]: the closed loop as a Lur'e system (issue 35): the inner level, a
//!   per-method rate ρ_in from a small LMI, φ_iqc(K) beside φ(K); and the loop level
//!   (`lure::loop_level`, Theorem L2) for loops small enough for its dense solver.
//! - [`regional`]: regional ISS from the lifted loop (a sublevel set on which no constraint
//!   is active).
//! - [`coverage`]: which certificate a configuration (method, K_e, controller, K_c) is
//!   under, and its verdict there (one decision for reproduce, sweeps and plots).
//! - [`plan`]: which K to simulate for a certificate, and the verdict.
//! - [`budget`]: the cost estimate and the budget of every optional analysis phase.
//! - [`outcome`]: typed void reasons, LMI (2) failures and skipped computations (match the
//!   variant; the `Display` is the reports' sentence and the JSON string).

pub mod analysis;
pub mod asymptotic;
pub mod budget;
pub mod certificate;
pub mod coverage;
pub mod gamma13;
pub mod joint;
pub mod linear;
pub mod lure;
pub mod model;
pub mod outcome;
pub mod plan;
pub mod regional;
pub mod small_gain;

pub use model::{
    Certificate, CertifyOptions, LoopModel, LoopModelBuilder, Method, MheSettings, ModelBuildError,
    MpcSettings, certify,
};
