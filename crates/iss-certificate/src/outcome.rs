//! Typed outcomes: why a certificate is void, why LMI (2) failed, why an optional
//! computation was skipped. Each is an enum with its numbers as fields and a
//! [`std::fmt::Display`] that is the sentence the reports print; JSON carries that sentence
//! (the `certificate.json` schema stays a list of strings), so a caller decides by matching
//! the variant, never by searching the text.

use lti_model::numfmt::sig4;
#[cfg(feature = "serde")]
use serde::{Serialize, Serializer};

use crate::gamma13::Gamma13Void;

/// Serialises a value as its `Display` sentence (the JSON form of the typed outcomes).
#[cfg(feature = "serde")]
fn as_sentence<T: std::fmt::Display, S: Serializer>(v: &T, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(v)
}

/// Why a certificate (Theorem 1 for one solver, or the joint (K_e, K_c) region) is void, or
/// a note on its region. Serialised as the sentence of its `Display`.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum VoidReason {
    /// L_Φ of Lemma 1 has no certified value for this MHE (e.g. a bounded 𝒳 or 𝒴: the
    /// constraint matrices change with the data); the reason from mhe-core.
    LPhiUndefined {
        /// Why (mhe-core's sentence).
        reason: &'static str,
    },
    /// L_π and γ₁,₃ have no certified value for this controller (state or output
    /// constraints in the MPC); the reason from mpc-core.
    ControllerUndefined {
        /// Why (mpc-core's sentence).
        reason: &'static str,
    },
    /// A premise of Theorem 1 fails.
    PremiseFails {
        /// The premise's short name (`"rho < 1"`).
        premise: String,
        /// Where the paper needs it.
        needed_by: String,
        /// The value tested.
        value: f64,
        /// What to change (None: no advice; printed as nothing).
        fix: Option<crate::analysis::PremiseFix>,
    },
    /// A premise could not be evaluated because one it depends on failed.
    PremiseNotEvaluated {
        /// The premise's short name.
        premise: String,
        /// Why: the premise that failed.
        because: NotEvaluated,
    },
    /// The premise "gamma13 finite" fails for a typed reason of the γ₁,₃ analysis.
    Gamma13 {
        /// The premise's short name (`"gamma13 finite"`).
        premise: String,
        /// Why no γ₁,₃ exists.
        void: Gamma13Void,
    },
    /// The premises hold but no K up to the search limit satisfies the small-gain condition.
    NoK {
        /// Largest K searched (`CertificateOptions::k_max`).
        k_max: usize,
    },
    /// The joint premises hold but no pair (K_e, K_c) up to the limit makes ρ(Γ) < 1.
    NoPair {
        /// Largest K_e and K_c searched.
        k_max: usize,
        /// ρ(Γ) at K_e = K_c = `k_max`.
        spectral_radius: f64,
    },
    /// The joint region's boundary has more corners than are listed (the region is not
    /// empty: the list of corners is cut).
    BoundaryCut {
        /// Corners listed (at most 4096, the joint region's `MAX_CORNERS`).
        max_corners: usize,
    },
}

impl VoidReason {
    /// The reasons as one sentence, `"; "` between them (the reports' form).
    pub fn join(reasons: &[VoidReason]) -> String {
        let mut s = String::new();
        for (i, r) in reasons.iter().enumerate() {
            if i > 0 {
                s.push_str("; ");
            }
            s.push_str(&r.to_string());
        }
        s
    }
}

impl std::fmt::Display for VoidReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::LPhiUndefined { reason } => write!(f, "L_Φ (Lemma 1): {reason}"),
            Self::ControllerUndefined { reason } => write!(f, "L_π, γ₁,₃: {reason}"),
            Self::PremiseFails {
                premise,
                needed_by,
                value,
                fix,
            } => {
                write!(f, "{premise} fails ({needed_by} = {}): ", sig4(*value))?;
                match fix {
                    Some(fix) => fix.fmt(f),
                    None => Ok(()),
                }
            }
            Self::PremiseNotEvaluated { premise, because } => {
                write!(f, "{premise} not evaluated (because {because})")
            }
            Self::Gamma13 { premise, void } => write!(f, "{premise} fails: {void}"),
            Self::NoK { k_max } => {
                write!(f, "no K ≤ {k_max} satisfies sg1 + sg2 + sg3 < 1 (ρ(Γ) < 1)")
            }
            Self::NoPair {
                k_max,
                spectral_radius,
            } => write!(
                f,
                "no pair with K_e, K_c ≤ {k_max} makes ρ(Γ) < 1 (at K_e = K_c = {k_max}: ρ(Γ) = \
                 {})",
                sig4(*spectral_radius)
            ),
            Self::BoundaryCut { max_corners } => write!(
                f,
                "the boundary has more than {max_corners} corners: the list is cut there"
            ),
        }
    }
}

#[cfg(feature = "serde")]
impl Serialize for VoidReason {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        as_sentence(self, s)
    }
}

/// Why a premise of Theorem 1 was not evaluated: a premise it depends on failed (one
/// failure, one reason). Serialised as its sentence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum NotEvaluated {
    /// LMI (2) fails, and the premise is a property of the MHE's QP, which is built from
    /// P of LMI (2) (φ, L_Φ, H̄).
    LmiFails,
}

impl std::fmt::Display for NotEvaluated {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::LmiFails => f.write_str(
                "\"LMI (2) feasible\" fails: the MHE's QP, its solver certificate φ, L_Φ and H̄ \
                 are built from P",
            ),
        }
    }
}

#[cfg(feature = "serde")]
impl Serialize for NotEvaluated {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        as_sentence(self, s)
    }
}

/// Why γ₁ʷ (Assumption 4's gain from w¹ to x) is unknown, so no asymptotic bound on ‖x‖
/// (hence on ε and ‖e‖) exists. Serialised as its sentence.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Gamma1wUnknown {
    /// The value given is not a finite non-negative number.
    NotFinite {
        /// The value given.
        gamma1w: f64,
    },
    /// γ₁,₃ is user-supplied, and comes without γ₁ʷ.
    UserSupplied {
        /// The user's γ₁,₃.
        gamma13: f64,
        /// Where it came from (the certificate's `gamma13.source`).
        source: String,
    },
    /// γ₁,₃ was not computed, so neither was γ₁ʷ.
    NotComputed,
}

impl std::fmt::Display for Gamma1wUnknown {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotFinite { gamma1w } => write!(
                f,
                "γ₁ʷ = {} (Assumption 4's gain from w¹ to x) is not a finite number",
                sig4(*gamma1w)
            ),
            Self::UserSupplied { gamma13, source } => write!(
                f,
                "γ₁,₃ = {} is user-supplied ({source}): Assumption 4's gain from w¹ to x (γ₁ʷ) \
                 is not known with it, and the asymptotic bound on ‖x‖ (hence on ε and ‖e‖) \
                 needs it; drop the user value to have γ₁,₃ and γ₁ʷ certified",
                sig4(*gamma13)
            ),
            Self::NotComputed => f.write_str("γ₁,₃ was not computed, so neither was γ₁ʷ"),
        }
    }
}

#[cfg(feature = "serde")]
impl Serialize for Gamma1wUnknown {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        as_sentence(self, s)
    }
}

/// Why LMI (2) (δ-IOSS, Assumption 2) gave no certificate: the model's typed error.
/// Serialised as its sentence.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct IossFailure {
    /// The error of [`lti_model::ioss::certify`] (or of verifying the scenario's P).
    pub error: lti_model::ModelError,
}

impl std::fmt::Display for IossFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.error.fmt(f)
    }
}

#[cfg(feature = "serde")]
impl Serialize for IossFailure {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        as_sentence(self, s)
    }
}

/// Why an optional computation was not run, and what is used instead. Serialised as its
/// sentence.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum SkipReason {
    /// The γ₁,₃ free-set enumeration: more saturable input variables than the cap.
    OverVariableCap {
        /// Saturable input variables s.
        saturable: usize,
        /// The cap (`enumeration_max_vars`, at most 30).
        cap: usize,
        /// Leading input blocks enumerated in the family bound used instead.
        depth: usize,
    },
    /// The γ₁,₃ free-set enumeration: its estimate is beyond the analysis budget
    /// (`certificate.phase_seconds`).
    OverBudget {
        /// Saturable input variables s (2^s free sets).
        saturable: usize,
        /// Metrics enumerated.
        metrics: usize,
        /// State dimension n_x.
        n_x: usize,
        /// Estimated multiply-adds.
        work: f64,
        /// Estimated single-core seconds.
        seconds: f64,
        /// The budget per phase (seconds).
        budget_seconds: f64,
        /// Leading input blocks enumerated in the family bound used instead.
        depth: usize,
    },
    /// The sampled lower estimate of γ₁,₃: no injected sequences were requested.
    NoSequences {
        /// A user-supplied γ₁,₃ is therefore not checked.
        user_value_unchecked: bool,
    },
}

impl SkipReason {
    /// Whether the analysis budget (`certificate.phase_seconds`) is why it was skipped.
    pub fn is_budget(&self) -> bool {
        matches!(self, Self::OverBudget { .. })
    }
}

impl std::fmt::Display for SkipReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::OverVariableCap {
                saturable: s,
                cap,
                depth,
            } => write!(
                f,
                "{s} saturable input variables > cap {cap} (2^{s} free sets); the S-procedure \
                 bound over 0 ⪯ Π ⪯ I with the first {depth} input block(s) enumerated is used"
            ),
            Self::OverBudget {
                saturable: s,
                metrics,
                n_x,
                work,
                seconds,
                budget_seconds,
                depth,
            } => write!(
                f,
                "2^{s} free sets × {metrics} metric(s) at n_x = {n_x}: estimated {} multiply-adds, \
                 ≈ {} s > the analysis budget of {} s per phase (scenario key \
                 `certificate.phase_seconds`); the S-procedure bound over 0 ⪯ Π ⪯ I with \
                 the first {depth} input block(s) enumerated is used",
                crate::budget::sci(*work),
                crate::budget::secs(*seconds),
                crate::budget::secs(*budget_seconds),
            ),
            Self::NoSequences {
                user_value_unchecked: true,
            } => f.write_str(
                "no injected sequences requested (gamma13_sequences = 0), so the user value \
                 is not checked",
            ),
            Self::NoSequences {
                user_value_unchecked: false,
            } => f.write_str("no injected sequences requested (gamma13_sequences = 0)"),
        }
    }
}

#[cfg(feature = "serde")]
impl Serialize for SkipReason {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        as_sentence(self, s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sentences are today's (the JSON and the golden files carry them unchanged).
    #[test]
    fn sentences_and_json() {
        let r = VoidReason::PremiseFails {
            premise: "rho < 1".into(),
            needed_by: "Prop. 2".into(),
            value: 1.25,
            fix: Some(crate::analysis::PremiseFix::LmiInfeasible),
        };
        assert_eq!(
            r.to_string(),
            "rho < 1 fails (Prop. 2 = 1.25): no P ≻ 0 satisfies LMI (2): see the δ-IOSS error"
        );
        let n = VoidReason::NoK { k_max: 7 };
        #[cfg(feature = "serde")]
        assert_eq!(
            serde_json::to_string(&vec![r.clone(), n.clone()]).expect("serialisable"),
            "[\"rho < 1 fails (Prop. 2 = 1.25): no P ≻ 0 satisfies LMI (2): see the δ-IOSS \
             error\",\
             \"no K ≤ 7 satisfies sg1 + sg2 + sg3 < 1 (ρ(Γ) < 1)\"]"
        );
        assert_eq!(
            VoidReason::join(&[r, n]),
            "rho < 1 fails (Prop. 2 = 1.25): no P ≻ 0 satisfies LMI (2): see the δ-IOSS error; \
             no K ≤ 7 satisfies sg1 + sg2 + sg3 < 1 (ρ(Γ) < 1)"
        );
        assert_eq!(VoidReason::join(&[]), "");
        let b = SkipReason::OverBudget {
            saturable: 24,
            metrics: 3,
            n_x: 4,
            work: 1e12,
            seconds: 500.0,
            budget_seconds: 60.0,
            depth: 1,
        };
        assert!(b.is_budget());
        assert!(b.to_string().contains("`certificate.phase_seconds`"));
        assert!(
            !SkipReason::NoSequences {
                user_value_unchecked: false
            }
            .is_budget()
        );
    }
}
