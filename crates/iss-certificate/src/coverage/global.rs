//! The verdict's second certificate and its scalar: the global loop certificate combined with
//! Theorem 1's verdict ([`with_global`]), and Theorem 1 in f32 ([`f32_verdict`]).

use closed_loop::scenario::{ControllerChoice, ResolvedScenario};
use qp_iter::Method;

use super::{CertificateKind, Certified, Configuration, F32Void, PairReason, PairVerdict, Scalar};
use crate::certificate::{CertificateOptions, ClosedLoopCertificate};
use crate::lure::chain_outcome::{ChainCheck, ChainOutcome, MethodChain};
use crate::lure::global_outcome::{GlobalOutcome, MethodGlobal, PrecisionOutcome};

/// The one verdict of two certificates at K_e: `v` (Theorem 1's, in `scalar`) and the global
/// loop certificate `global` in `scalar` (None: not computed or not modelling the
/// configuration). Certified when either covers K_e, and the verdict names which (Theorem 1
/// first); K_min is the smaller floor of the two. When neither covers: a known K_glob above
/// K_e is a plain "no"; a global search the budget stopped makes a void or not-computed `v`
/// not computed and says so (a "no" stays a plain "no"); a global certificate proved absent
/// (or not modelled in this scalar) leaves a void `v` void naming both reasons, and any
/// other `v` as it is (its outcome is reported beside: certificate.json, `certify --loop`).
///
/// Then the iteration chain (Theorem L3b, f64 only: it has no rounding input), which speaks
/// at the K it was checked at and nowhere else (it is not monotone in K;
/// `with_chain`): certified there makes the verdict `yes` (`chain`), and the floor
/// `k_min` is the smallest certified K of the three.
pub fn with_global(
    v: PairVerdict,
    global: Option<&MethodGlobal>,
    k_e: usize,
    scalar: Scalar,
) -> PairVerdict {
    let Some(g) = global else { return v };
    let v = with_l3(v, g, k_e, scalar);
    match (scalar, g.chain.as_ref().and_then(ChainOutcome::chain)) {
        (Scalar::F64, Some(chain)) => with_chain(v, chain, k_e),
        _ => v,
    }
}

/// The chain's part of [`with_global`] on the verdict `v` of Theorem 1 and Theorem L3 at K_e:
/// - certified by either: `v`, its floor lowered to K_chain if smaller;
/// - the chain certified K_e: `yes` (`chain`);
/// - the chain's search at K_e was stopped by the budget: `not_computed`, naming
///   `certificate.phase_seconds`;
/// - the chain was not checked at K_e and certifies a smaller K: `not_computed` (nothing
///   decided K_e; the sentence says how to check it) — never "void", never extrapolated;
/// - otherwise `v` with the floor; a void `v` becomes `no` when the chain certifies some K
///   (the method is not void), with the chain's sentence where K_e is above that K.
pub fn with_chain(v: PairVerdict, chain: &MethodChain, k_e: usize) -> PairVerdict {
    let k_chain = chain.k_chain();
    let k_min = match (v.k_min, k_chain) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    if v.certified.is_certified() {
        return PairVerdict { k_min, ..v };
    }
    let why = |check: Option<ChainCheck>, then: Option<PairReason>| {
        Some(PairReason::Chain(ChainWhy {
            k: k_e,
            k_chain,
            check,
            then: then.map(Box::new),
        }))
    };
    let at = chain.at(k_e);
    match at {
        Some(ChainCheck::Certified(_)) => PairVerdict {
            certificate: Some(CertificateKind::Chain),
            certified: Certified::Yes,
            k_min,
            margin: None,
            reason: None,
        },
        Some(c @ ChainCheck::NotComputed { .. }) => PairVerdict {
            certified: Certified::NotComputed,
            k_min,
            reason: why(Some(c.clone()), v.reason.clone()),
            ..v
        },
        None if k_chain.is_some_and(|kc| kc < k_e) => PairVerdict {
            certified: Certified::NotComputed,
            k_min,
            margin: None,
            reason: why(None, v.reason.clone()),
            ..v
        },
        _ => {
            let below_chain = k_chain.is_some_and(|kc| k_e < kc);
            let chain_lowest = k_chain.is_some() && k_min == k_chain && v.k_min != k_min;
            match (v.certified, k_chain) {
                (Certified::Void, Some(_)) => PairVerdict {
                    certificate: Some(CertificateKind::Chain),
                    certified: Certified::No,
                    k_min,
                    margin: None,
                    reason: if below_chain {
                        None
                    } else {
                        why(at.cloned(), None)
                    },
                },
                (Certified::No, _) if chain_lowest && below_chain => PairVerdict {
                    certificate: Some(CertificateKind::Chain),
                    k_min,
                    margin: None,
                    ..v
                },
                // Checked at K without a certificate (or not checked, above K_chain): the
                // floor is named by the certificate that gives it.
                (Certified::No, Some(_)) if !below_chain => PairVerdict {
                    certificate: if chain_lowest {
                        Some(CertificateKind::Chain)
                    } else {
                        v.certificate
                    },
                    // A margin is the named certificate's: the chain's is not a verdict field.
                    margin: if chain_lowest { None } else { v.margin },
                    k_min,
                    reason: why(at.cloned(), v.reason.clone()),
                    ..v
                },
                _ => PairVerdict { k_min, ..v },
            }
        }
    }
}

/// Why the iteration chain does not certify K (the chain's part of [`PairReason::Chain`]).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ChainWhy {
    /// The K asked for.
    pub k: usize,
    /// The smallest K the chain certified, if any.
    pub k_chain: Option<usize>,
    /// The chain's answer at K (None: not checked at K).
    pub check: Option<ChainCheck>,
    /// The verdict's reason without the chain, if any.
    pub then: Option<Box<PairReason>>,
}

impl std::fmt::Display for ChainWhy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(then) = &self.then {
            write!(f, "{then}; ")?;
        }
        f.write_str("the iteration chain (Theorem L3b; L3c for FISTA): ")?;
        match &self.check {
            Some(c) => c.fmt(f)?,
            None => write!(
                f,
                "not checked at K = {} (it is checked at mhe.iterations and scanned from K = 1 to its first certified K; set mhe.iterations = {} to check this K)",
                self.k, self.k
            )?,
        }
        match self.k_chain {
            Some(kc) => write!(f, "; it certifies K = {kc} (not monotone in K)"),
            None => Ok(()),
        }
    }
}

/// Theorem L3's part of [`with_global`] (before the chain).
fn with_l3(v: PairVerdict, g: &MethodGlobal, k_e: usize, scalar: Scalar) -> PairVerdict {
    let (k_glob, not_computed, why) = match scalar {
        Scalar::F64 => (
            g.exact.k_glob(),
            g.exact.is_not_computed(),
            GlobalWhy::Exact(g.exact.clone()),
        ),
        Scalar::F32 => (
            g.f32.k_glob(),
            g.f32.is_not_computed(),
            GlobalWhy::F32(g.f32.clone()),
        ),
    };
    // Theorem 1's floor counts only where it speaks (yes/no at this scalar).
    let own = match v.certified {
        Certified::Yes | Certified::No => v.k_min,
        Certified::Void | Certified::NotComputed => None,
    };
    let k_min = match (own, k_glob) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    if v.certified.is_certified() {
        return PairVerdict { k_min, ..v };
    }
    match k_glob {
        Some(kg) if k_e >= kg => PairVerdict {
            certificate: Some(CertificateKind::Global),
            certified: Certified::Yes,
            k_min,
            margin: None,
            reason: None,
        },
        Some(kg) => {
            let theorem1_lower = own.is_some_and(|a| a <= kg);
            PairVerdict {
                certificate: if theorem1_lower {
                    v.certificate
                } else {
                    Some(CertificateKind::Global)
                },
                certified: Certified::No,
                k_min,
                margin: if theorem1_lower { v.margin } else { None },
                reason: None,
            }
        }
        // A "no" stays a plain "no" (Theorem 1's floor is known; the global outcome is
        // reported per method beside it).
        None if not_computed && !v.certified.is_below_floor() => PairVerdict {
            certified: Certified::NotComputed,
            reason: Some(PairReason::Global {
                then: v.reason.clone().map(Box::new),
                global: why,
            }),
            ..v
        },
        // Neither certificate has a K: the verdict names both reasons (Theorem 1's and the
        // global certificate's in this scalar: proved absent, or not modelled — e.g. f32 for
        // a method without a rounding model), so a refusal never cites Theorem 1 alone.
        None if v.certified == Certified::Void
            && !matches!(why, GlobalWhy::F32(PrecisionOutcome::NotAsked)) =>
        {
            PairVerdict {
                reason: Some(PairReason::Global {
                    then: v.reason.clone().map(Box::new),
                    global: why,
                }),
                ..v
            }
        }
        None => v,
    }
}

/// The global loop certificate's outcome in the verdict's scalar (the global part of
/// [`PairReason::Global`]).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum GlobalWhy {
    /// In exact arithmetic (f64).
    Exact(GlobalOutcome),
    /// In f32.
    F32(PrecisionOutcome),
}

impl std::fmt::Display for GlobalWhy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Exact(o) => o.fmt(f),
            Self::F32(o) => o.fmt(f),
        }
    }
}

/// The global loop certificate of `method` in `cert` when it speaks for `controller` (the
/// section was computed for the scenario's own controller, and models the exact MPC only
/// here): what [`super::Applicable::new`] combines with Theorem 1, and what reports show beside it.
pub fn global_of(
    cert: &ClosedLoopCertificate,
    method: Method,
    controller: ControllerChoice,
) -> Option<&MethodGlobal> {
    if controller != ControllerChoice::ExactMpc {
        return None;
    }
    cert.global
        .as_ref()
        .filter(|g| g.controller == controller)
        .and_then(|g| g.method(method))
}

/// The f32 verdict from the f64 one `v`: Theorem 1 with the f32 rounding folded in
/// ([`crate::certificate::precision::certify_scalar`]); the joint certificate has no rounding
/// model here ([`joint_f32_verdict`] has it). A void f32 verdict has no floor: the f64 K_min
/// is not a K certified in f32, and `export --k certified` reads the floor.
pub(super) fn f32_verdict(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    config: &Configuration,
    v: PairVerdict,
) -> PairVerdict {
    let void = |why: F32Void, v: PairVerdict| PairVerdict {
        certified: Certified::Void,
        k_min: None,
        margin: None,
        reason: Some(PairReason::F32 {
            why,
            then: v.reason.map(Box::new),
        }),
        ..v
    };
    if v.certified == Certified::Void || v.certificate != Some(CertificateKind::Theorem1) {
        return void(F32Void::NotCovered, v);
    }
    let sc = match crate::certificate::precision::certify_scalar(
        resolved,
        cert,
        config.method,
        Scalar::F32,
        CertificateOptions::default().k_max,
    ) {
        Ok(sc) => sc,
        Err(e) => {
            let error = e.to_string();
            return void(F32Void::RoundingModel { error }, v);
        }
    };
    match sc.k_min {
        Some(k_min) if config.k_e >= k_min => PairVerdict {
            certified: Certified::Yes,
            k_min: Some(k_min),
            margin: None,
            reason: None,
            ..v
        },
        Some(k_min) => PairVerdict {
            certified: Certified::No,
            k_min: Some(k_min),
            margin: None,
            reason: Some(PairReason::BelowF32KMin {
                k: config.k_e,
                k_min,
            }),
            ..v
        },
        None => void(sc.reason.map_or(F32Void::NoK, F32Void::Void), v),
    }
}

/// The f32 verdict of the joint certificate (the K_c-iteration MPC) from its f64 one `v`:
/// the same four-node analysis with both maps' f32 rounding folded in
/// ([`crate::joint::joint_rounding`], docs/theory.md "The joint certificate in f32"); its
/// floor is the smallest K_e certified in f32 at the configuration's K_c.
pub(super) fn joint_f32_verdict(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    config: &Configuration,
    analysis: &crate::joint::JointAnalysis,
    k_max: usize,
    v: PairVerdict,
) -> PairVerdict {
    let void = |why: F32Void| PairVerdict {
        certified: Certified::Void,
        k_min: None,
        margin: None,
        reason: Some(PairReason::F32 {
            why,
            then: v.reason.clone().map(Box::new),
        }),
        ..v.clone()
    };
    let ControllerChoice::SuboptimalMpc {
        iterations: k_c,
        method: mpc_method,
    } = config.controller
    else {
        return void(F32Void::NotCovered);
    };
    let k_c = k_c.get();
    if v.certified == Certified::Void {
        return void(F32Void::NotCovered);
    }
    let rounding = match crate::joint::joint_rounding(
        resolved,
        cert,
        config.method,
        mpc_method,
        Scalar::F32.unit_roundoff(),
    ) {
        Ok(Ok(r)) => r,
        Ok(Err(why)) => return void(F32Void::Void(why)),
        Err(e) => {
            let error = e.to_string();
            return void(F32Void::RoundingModel { error });
        }
    };
    let a = analysis.clone().with_rounding(rounding);
    let Some(k_min) = a.k_e_min(k_c, k_max) else {
        let spectral_radius = a.at(k_max, k_c).spectral_radius;
        return void(F32Void::JointNoPair {
            k_c,
            k_max,
            spectral_radius,
            k_c_floor: a.k_c_min(k_max, k_max),
        });
    };
    let g = a.at(config.k_e, k_c);
    PairVerdict {
        certified: if g.certified {
            Certified::Yes
        } else {
            Certified::No
        },
        k_min: Some(k_min),
        margin: g.margin.is_finite().then_some(g.margin),
        reason: None,
        ..v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lure::global::PrecisionVoid;
    use crate::lure::global_outcome::{Gains, GlobalK, PrecisionK};

    fn exact(k_glob: usize) -> GlobalOutcome {
        GlobalOutcome::Certified(GlobalK {
            k_glob,
            phi_star: 0.25,
            phi_at_k: 0.2,
            margin: 1e-9,
            rho: 0.99,
            gamma: 10.0,
            gain_x: 1.0,
            gain_e: 1.0,
            gains: Gains::Refined {
                gain_x_at_phi_star: 2.0,
            },
        })
    }

    fn f32_at(k_glob: usize) -> PrecisionOutcome {
        PrecisionOutcome::Certified(PrecisionK {
            unit_roundoff: 6e-8,
            k_glob,
            phi_star: 0.25,
            offset: 1e-6,
            rho: 0.99,
            gamma: 10.0,
            margin: 1e-9,
        })
    }

    fn global(exact: GlobalOutcome, f32: PrecisionOutcome) -> MethodGlobal {
        MethodGlobal {
            method: Method::PG,
            exact,
            f32,
            chain: None,
        }
    }

    fn theorem1(certified: Certified, k_min: Option<usize>) -> PairVerdict {
        PairVerdict {
            certificate: Some(CertificateKind::Theorem1),
            certified,
            k_min,
            margin: None,
            reason: (certified == Certified::Void).then(|| {
                PairReason::Void(vec![crate::outcome::VoidReason::NoK { k_max: 1 << 24 }])
            }),
        }
    }

    /// Theorem 1 void, K_glob = 13: K = 13 is certified by the global certificate, K = 12 is
    /// a "no" with the floor 13 (the case study's PG).
    #[test]
    fn the_global_certificate_covers_where_theorem1_is_void() {
        let g = global(exact(13), f32_at(13));
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 13, Scalar::F64);
        assert_eq!(v.certified, Certified::Yes);
        assert_eq!(v.certificate, Some(CertificateKind::Global));
        assert_eq!(v.k_min, Some(13));
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 12, Scalar::F64);
        assert_eq!(v.certified, Certified::No);
        assert_eq!(v.k_min, Some(13));
        assert_eq!(v.reason, None);
    }

    /// Theorem 1 covers K: it is named, and K_min is the smaller floor of the two.
    #[test]
    fn theorem1_is_named_first_and_k_min_is_the_smaller_floor() {
        let g = global(exact(13), f32_at(13));
        let v = with_global(
            theorem1(Certified::Yes, Some(243)),
            Some(&g),
            243,
            Scalar::F64,
        );
        assert_eq!(v.certificate, Some(CertificateKind::Theorem1));
        assert_eq!((v.certified, v.k_min), (Certified::Yes, Some(13)));
        // Below both floors, Theorem 1's smaller floor keeps its name.
        let g = global(exact(500), f32_at(500));
        let v = with_global(
            theorem1(Certified::No, Some(243)),
            Some(&g),
            100,
            Scalar::F64,
        );
        assert_eq!(v.certificate, Some(CertificateKind::Theorem1));
        assert_eq!((v.certified, v.k_min), (Certified::No, Some(243)));
    }

    /// Neither certificate has a K: a void verdict names both reasons — Theorem 1's and the
    /// global certificate's in the verdict's scalar (an f32 export of FISTA on a user's plant
    /// cited Theorem 1 alone, not that f32 has no rounding model of FISTA); "not searched" adds
    /// nothing; a "no" keeps its own reason.
    #[test]
    fn a_void_verdict_names_the_global_reason_too() {
        let binds = GlobalOutcome::OptimumBinds {
            margin_without_boxes: 2e-6,
        };
        let g = global(binds, PrecisionOutcome::NotAsked);
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 5, Scalar::F64);
        assert_eq!(v.certified, Certified::Void);
        let why = v.reason_text();
        assert!(why.contains("the global loop certificate: "), "{why}");
        assert!(why.contains(&g.exact.to_string()), "{why}");
        assert!(
            why.contains(&theorem1(Certified::Void, None).reason_text()),
            "{why}"
        );
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 5, Scalar::F32);
        assert_eq!(
            v.reason_text(),
            theorem1(Certified::Void, None).reason_text()
        );
        let fista = PrecisionOutcome::Unsupported {
            reason: "FISTA: no rounding bound is derived (use pg)".into(),
        };
        let g = global(exact(13), fista);
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 20, Scalar::F32);
        assert_eq!(v.certified, Certified::Void);
        assert!(
            v.reason_text().contains("no rounding bound"),
            "{}",
            v.reason_text()
        );
        let v = with_global(
            theorem1(Certified::No, Some(300)),
            Some(&g),
            20,
            Scalar::F32,
        );
        assert_eq!(v.reason, None);
    }

    /// f32 reads the f32 outcome: refused where the f32 global certificate is void even if
    /// the f64 one covers K.
    #[test]
    fn f32_uses_the_f32_global_certificate() {
        let void = PrecisionOutcome::Void(PrecisionVoid::ContractionBroken {
            window: 9,
            rate: 0.99,
            rounding: 0.02,
        });
        let g = global(exact(13), void);
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 20, Scalar::F32);
        assert_eq!(v.certified, Certified::Void);
        let g = global(exact(13), f32_at(15));
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 14, Scalar::F32);
        assert_eq!((v.certified, v.k_min), (Certified::No, Some(15)));
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 15, Scalar::F32);
        assert!(v.certified.is_certified());
    }

    /// A global search the budget stopped: a void Theorem 1 verdict becomes "not computed",
    /// naming the key; a "no" stays a plain "no".
    #[test]
    fn a_budget_stopped_search_is_not_computed_and_names_the_key() {
        let nc = GlobalOutcome::NotComputed {
            n_zeta: 235,
            estimate_seconds: 40.0,
            budget_seconds: 10.0,
        };
        let g = global(nc.clone(), PrecisionOutcome::NoExact(Box::new(nc)));
        for scalar in [Scalar::F64, Scalar::F32] {
            let v = with_global(theorem1(Certified::Void, None), Some(&g), 13, scalar);
            assert_eq!(v.certified, Certified::NotComputed);
            let why = v.reason_text();
            assert!(why.contains("certificate.phase_seconds"), "{why}");
            assert!(why.contains("not computed within the budget"), "{why}");
        }
        let v = with_global(
            theorem1(Certified::No, Some(243)),
            Some(&g),
            13,
            Scalar::F64,
        );
        assert_eq!((v.certified, v.k_min), (Certified::No, Some(243)));
        assert_eq!(v.reason, None);
    }

    fn chained(chain: Vec<ChainCheck>) -> MethodGlobal {
        use crate::lure::chain_outcome::ChainScanEnd;
        let mut g = global(exact(13), f32_at(13));
        g.chain = Some(ChainOutcome::Checked(MethodChain {
            checks: chain,
            scan: ChainScanEnd::Certified { k: 1 },
            budget_seconds: 10.0,
        }));
        g
    }

    fn chain_yes(k: usize) -> ChainCheck {
        ChainCheck::Certified(crate::lure::chain_outcome::ChainK {
            k,
            margin: 4e-9,
            rho: 0.9999,
            gamma: 4e3,
            gain_x: 1.0,
            gain_e: 1.0,
        })
    }

    /// The case study's PG: Theorem 1 void, K_glob = 13, the chain certified K = 1 (and was
    /// checked nowhere else). K = 1 is `yes` by the chain, the floor is 1; K = 5 was not
    /// checked: not computed, saying so (never void, never extrapolated); K = 13 is Theorem
    /// L3's; f32 ignores the chain (no rounding input).
    #[test]
    fn the_chain_certifies_only_the_k_it_checked() {
        let g = chained(vec![chain_yes(1)]);
        let t1 = || theorem1(Certified::Void, None);
        let v = with_global(t1(), Some(&g), 1, Scalar::F64);
        assert_eq!(v.certified, Certified::Yes);
        assert_eq!(v.certificate, Some(CertificateKind::Chain));
        assert_eq!(v.k_min, Some(1));
        let v = with_global(t1(), Some(&g), 5, Scalar::F64);
        assert_eq!(v.certified, Certified::NotComputed);
        assert_eq!(v.k_min, Some(1));
        let why = v.reason_text();
        assert!(why.contains("not checked at K = 5"), "{why}");
        assert!(why.contains("mhe.iterations = 5"), "{why}");
        let v = with_global(t1(), Some(&g), 13, Scalar::F64);
        assert_eq!(
            (v.certified, v.certificate, v.k_min),
            (Certified::Yes, Some(CertificateKind::Global), Some(1))
        );
        let v = with_global(t1(), Some(&g), 1, Scalar::F32);
        assert_eq!((v.certified, v.k_min), (Certified::No, Some(13)));
    }

    /// A K the chain checked without a certificate below K_chain is a plain "no" with the
    /// chain's floor; a K whose search the budget stopped is not computed, naming the key.
    #[test]
    fn the_chain_below_its_floor_and_under_the_budget() {
        let refuted = ChainCheck::NotCertified {
            k: 1,
            rho_reached: Some(1.2),
        };
        let stopped = ChainCheck::NotComputed {
            k: 4,
            solves: 900,
            per_solve: 0.01,
            budget_seconds: 10.0,
        };
        let g = chained(vec![refuted, chain_yes(2), stopped]);
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 1, Scalar::F64);
        assert_eq!((v.certified, v.k_min), (Certified::No, Some(2)));
        assert_eq!(v.certificate, Some(CertificateKind::Chain));
        assert_eq!(v.reason, None);
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 4, Scalar::F64);
        assert_eq!(v.certified, Certified::NotComputed);
        let why = v.reason_text();
        assert!(why.contains("certificate.phase_seconds"), "{why}");
        // Checked above its floor without a certificate (ρ_lin(K) ≥ 1 there): a plain "no"
        // whose floor, 2, is the chain's and is named so — not Theorem L3's, whose K_glob
        // is 13 (a user's 2-state plant printed "the smallest certified K is 2 (the global
        // loop certificate (Theorem L3); K_glob = 14)").
        let unstable = ChainCheck::LinearlyUnstable {
            k: 5,
            rho_lin: 1.04,
        };
        let g5 = chained(vec![chain_yes(2), unstable]);
        let v = with_global(theorem1(Certified::Void, None), Some(&g5), 5, Scalar::F64);
        assert_eq!((v.certified, v.k_min), (Certified::No, Some(2)));
        assert_eq!(v.certificate, Some(CertificateKind::Chain));
        let why = v.reason_text();
        assert!(why.contains("1.04"), "{why}");
        // Without the chain the same K = 1 is Theorem L3's plain "no" at the floor 13.
        let mut g = g;
        g.chain = None;
        let v = with_global(theorem1(Certified::Void, None), Some(&g), 1, Scalar::F64);
        assert_eq!((v.certified, v.k_min), (Certified::No, Some(13)));
    }
}
