//! # closed-loop
//!
//! Alg. 1 of Yang–Manzie–Pu as a simulation (plant + sub-optimal MHE + controller) and the
//! ISS analysis of Section III: every constant of Lemma 1, Props. 1–3 and Theorem 1, the
//! small-gain conditions (sg1)–(sg3), and the smallest certified iteration budget K.
//!
//! - [`analysis`]: Theorem 1's arithmetic (C₁…C₆, gains, slopes, premises, K_min).

pub mod analysis;
