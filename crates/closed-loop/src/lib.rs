//! # closed-loop
//!
//! Alg. 1 of Yang–Manzie–Pu as a simulation (plant + sub-optimal MHE + controller) and the
//! ISS analysis of Section III: every constant of Lemma 1, Props. 1–3 and Theorem 1, the
//! small-gain conditions (sg1)–(sg3), and the smallest certified iteration budget K.
//!
//! - [`analysis`]: Theorem 1's arithmetic (C₁…C₆, gains, slopes, premises, K_min).
//! - [`sim`]: Alg. 1 as a simulation ([`ClosedLoop`]) and the case-study builder
//!   ([`build_case_study`]).
//! - [`record`]: the per-step [`Trace`] of a run (with the MHE records), JSON output.
//! - [`gamma13`]: γ₁,₃ of Assumption 4 for the MPC on any plant (family bound by the
//!   S-procedure, partial and full free-set enumeration, typed void reasons, user values).

pub mod analysis;
pub mod certificate;
pub mod gamma13;
pub mod record;
pub mod sim;
pub mod sweep;

pub use record::{MheStep, MheTrace, Trace};
pub use sim::{
    CaseStudyLoop, CaseStudyOptions, ClosedLoop, ClosedLoopError, ControllerChoice, Solver,
    build_case_study,
};
