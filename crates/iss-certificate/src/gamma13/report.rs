//! The γ₁,₃ that enters the certificate: certified ([`super::gamma13_certified`]) or
//! supplied by the user, with the sampled lower estimate beside it.
//!
//! A user value is reported as "user-supplied, not verified": sampling can refute a γ₁,₃,
//! never prove one. If the sampled lower estimate exceeds it, the value is provably not a
//! valid gain ([`Gamma13Void::UserValueRefuted`]) and the certificate is not computed with
//! it (`used` = ∞).

use mpc_core::{CondensedMpc, ExactMpc, MpcError};
#[cfg(feature = "serde")]
use serde::Serialize;

use super::{
    Gamma13Certificate, Gamma13Sampled, Gamma13Void, SkippedComputation,
    gamma13_certified_budgeted, gamma13_sampled,
};

/// Where γ₁,₃ comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Gamma13Source {
    /// Certified by contraction over the MPC's local gains ([`crate::gamma13`]).
    Certified,
    /// Supplied by the user (e.g. from another method): reported as "user-supplied, not
    /// verified", refuted when the sampled lower estimate exceeds it.
    User(f64),
}

/// Text of [`Gamma13Report::source`] for a user value.
pub const USER_SOURCE: &str = "user-supplied, not verified";

/// Magnitudes of the injected error sequences of the sampled lower estimate.
pub const SAMPLED_MAGNITUDES: [f64; 4] = [0.01, 0.1, 1.0, 10.0];

/// Steps per injected sequence of the sampled lower estimate.
pub const SAMPLED_STEPS: usize = 40;

/// γ₁,₃ figures of the certificate.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Gamma13Report {
    /// The value used in the certificate (∞ when void).
    pub used: f64,
    /// `"certified"` or `"user-supplied, not verified"`.
    pub source: String,
    /// The user's value, when supplied.
    pub user: Option<f64>,
    /// The contraction certificate (when computed).
    pub certified: Option<Gamma13Certificate>,
    /// Sampled lower estimate (when computed).
    pub sampled: Option<Gamma13Sampled>,
    /// Why `used` is ∞ (None otherwise).
    pub void: Option<Gamma13Void>,
    /// Computations not run, with the reason.
    pub skipped: Vec<SkippedComputation>,
}

/// γ₁,₃ for the certificate: `source`, the sampled lower estimate with `sequences`
/// sequences per magnitude (0 skips it, and the skip is recorded), `seed`, and the
/// enumeration cap `max_vars` of [`super::gamma13_certified`].
///
/// Errors: `Parameter` for a user value that is negative or not finite; errors of the
/// certificate and of the exact MPC.
pub fn gamma13_report(
    mpc: &CondensedMpc,
    source: Gamma13Source,
    sequences: usize,
    seed: u64,
    max_vars: usize,
) -> Result<Gamma13Report, MpcError> {
    gamma13_report_budgeted(mpc, source, sequences, seed, max_vars, f64::INFINITY)
}

/// [`gamma13_report`] whose free-set enumeration is skipped (and the skip reported) when its
/// estimated time exceeds `phase_seconds` ([`super::gamma13_certified_budgeted`]).
pub fn gamma13_report_budgeted(
    mpc: &CondensedMpc,
    source: Gamma13Source,
    sequences: usize,
    seed: u64,
    max_vars: usize,
    phase_seconds: f64,
) -> Result<Gamma13Report, MpcError> {
    gamma13_report_with(mpc, source, sequences, seed, |mpc| {
        gamma13_certified_budgeted(
            mpc,
            max_vars,
            super::GAMMA13_PATTERN_FAMILIES,
            phase_seconds,
        )
    })
}

/// [`gamma13_report_budgeted`] with the certified γ₁,₃ supplied by `certified` (called only
/// for [`Gamma13Source::Certified`] without state constraints; it must return what
/// [`gamma13_certified_budgeted`] returns, e.g. from a [`super::Gamma13Plan`] whose stages
/// ran elsewhere).
pub fn gamma13_report_with(
    mpc: &CondensedMpc,
    source: Gamma13Source,
    sequences: usize,
    seed: u64,
    certified: impl FnOnce(&CondensedMpc) -> Result<Gamma13Certificate, MpcError>,
) -> Result<Gamma13Report, MpcError> {
    let mut report = match source {
        Gamma13Source::User(g) => {
            if !(g.is_finite() && g >= 0.0) {
                return Err(MpcError::Parameter {
                    name: "gamma13 (user-supplied)",
                    value: g,
                    reason: "γ₁,₃ must be finite and ≥ 0",
                });
            }
            Gamma13Report {
                used: g,
                source: USER_SOURCE.into(),
                user: Some(g),
                certified: None,
                sampled: None,
                void: None,
                skipped: Vec::new(),
            }
        }
        // State or output constraints: the certified analysis (box-constrained inputs) does
        // not apply.
        Gamma13Source::Certified if mpc.certificate_void_reason().is_some() => Gamma13Report {
            used: f64::INFINITY,
            source: "certified".into(),
            user: None,
            void: Some(if mpc.has_state_constraints() {
                Gamma13Void::StateConstrainedMpc
            } else {
                Gamma13Void::OutputConstrainedMpc
            }),
            skipped: Vec::new(),
            certified: None,
            sampled: None,
        },
        Gamma13Source::Certified => {
            let c = certified(mpc)?;
            Gamma13Report {
                used: c.gamma13,
                source: "certified".into(),
                user: None,
                void: c.void.clone(),
                skipped: c.skipped.clone(),
                certified: Some(c),
                sampled: None,
            }
        }
    };
    if sequences > 0 {
        let mut exact = ExactMpc::new(mpc)?;
        let s = gamma13_sampled(
            &mut exact,
            mpc.system(),
            &SAMPLED_MAGNITUDES,
            sequences,
            SAMPLED_STEPS,
            seed,
        )?;
        if let Some(user) = report.user {
            // Relative 1e-9 for the exact solver's accuracy.
            if s.gamma13_lower > user * (1.0 + 1e-9) + 1e-12 {
                report.void = Some(Gamma13Void::UserValueRefuted {
                    user,
                    sampled_lower: s.gamma13_lower,
                });
                report.used = f64::INFINITY;
            }
        }
        report.sampled = Some(s);
    } else {
        report.skipped.push(SkippedComputation {
            computation: "sampled lower estimate of γ₁,₃".into(),
            reason: crate::outcome::SkipReason::NoSequences {
                user_value_unchecked: report.user.is_some(),
            },
        });
    }
    Ok(report)
}

impl std::fmt::Display for Gamma13Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "γ₁,₃ (Assumption 4): ")?;
        match (&self.void, &self.certified) {
            // Stopped by the budget: not void (its sentence says "not computed").
            (Some(v @ Gamma13Void::NotComputedWithinBudget { .. }), _) => write!(f, "{v}")?,
            (Some(v), _) => write!(f, "void: {v}")?,
            (None, Some(c)) => write!(
                f,
                "{} ({}, {:?}, metric {})",
                lti_model::numfmt::sig4(self.used),
                self.source,
                c.method,
                c.metric.as_deref().unwrap_or("-")
            )?,
            (None, None) => write!(f, "{} ({})", self.used, self.source)?,
        }
        if let Some(c) = &self.certified {
            write!(
                f,
                "\n  family bound (S-procedure, {} saturable of {} variables) {}",
                c.saturable,
                c.variables,
                lti_model::numfmt::sig4(c.gamma13_polynomial)
            )?;
            if let Some(e) = c.gamma13_enumerated {
                write!(
                    f,
                    "\n  enumerated over {} free sets     {}",
                    c.free_sets,
                    lti_model::numfmt::sig4(e)
                )?;
            }
            if let Some(l) = c.gamma13_linear {
                write!(
                    f,
                    "\n  linear law, impulse response     {}",
                    lti_model::numfmt::sig4(l)
                )?;
            }
        }
        if let Some(s) = &self.sampled {
            write!(
                f,
                "\n  sampled lower estimate ≥ {} ({} sequences × {} steps, seed {})",
                lti_model::numfmt::sig4(s.gamma13_lower),
                s.sequences,
                s.steps,
                s.seed
            )?;
        }
        for s in &self.skipped {
            write!(f, "\n  {s}")?;
        }
        Ok(())
    }
}
