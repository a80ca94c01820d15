//! Which certificate a configuration is under, and its verdict at (K_e, K_c): the one
//! decision behind `reproduce`'s `certified`, the sweep's `certified` column (1-D and 2-D),
//! the thresholds and the heat maps.
//!
//! A configuration is (MHE method, K_e, controller, K_c) on a scenario. [`covering`] decides
//! from its structure which certificate can speak about it:
//!
//! | configuration | certificate |
//! | --- | --- |
//! | exact MPC, the paper's warm start Σ_t | Theorem 1 ([`crate::certificate`]) |
//! | K_c-iteration MPC, the paper's warm start Σ_t | the joint certificate ([`crate::joint`]) |
//! | a time-shifted MHE warm start | none: outside the analysis |
//! | the saturated LQR | none: L_π and γ₁,₃ are the MPC's |
//!
//! A certificate that applies may still be *void* (a premise fails, e.g. L_Φ with bounded
//! 𝒳 / 𝒴 in the MHE: general rows, where the ADMM split is feasible only in the limit) —
//! its own void reasons say why. [`Applicable`] holds what the covering certificate needs to
//! give a verdict at any pair ([`Applicable::at`]). Another certificate (e.g. a regional one)
//! is one more arm of [`CertificateKind`], [`covering`] and [`Applicable`].
//!
//! Every command asks the same two functions, so they cannot disagree (issue 37): the
//! certificate is computed with [`verdict_options`] (the user's γ₁,₃ and the sample that can
//! refute it, the scenario's budget), and a configuration — method, K_e, controller with its
//! K_c, scalar, and the scenario's warm start — gets its verdict from [`verdict`]. f32 is
//! covered where Theorem 1 with the f32 rounding folded in certifies K
//! ([`crate::certificate::precision::certify_scalar`], docs/theory.md "Certified f32") or the
//! global loop certificate in f32 does; with the K_c-iteration MPC, where the joint
//! certificate with both maps' rounding folded in does ([`crate::joint::joint_rounding`],
//! docs/theory.md "The joint certificate in f32").

use mhe_core::WarmStart;
use qp_iter::Method;
#[cfg(feature = "serde")]
use serde::Serialize;

use crate::analysis::IssAnalysis;
use crate::budget::NotComputed;
use crate::certificate::precision::ScalarVoid;
use crate::certificate::{
    CertificateOptions, ClosedLoopCertificate, Gamma13Source, SolverCertificate,
};
use crate::joint::{JointAnalysis, JointOptions, certify_joint};
use crate::lure::global_outcome::MethodGlobal;

mod global;
mod reason;
use crate::outcome::VoidReason;
use closed_loop::scenario::{ControllerChoice, ResolvedScenario, Scenario};
use global::f32_verdict;
pub use global::{ChainWhy, GlobalWhy, global_of, with_global};

/// The certificates a configuration can be under. `#[non_exhaustive]`: a caller outside this
/// crate names them through [`CertificateKind::name`] / [`CertificateKind::title`], which
/// this crate matches exhaustively.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum CertificateKind {
    /// Theorem 1: the sub-optimal MHE with the exact MPC.
    Theorem1,
    /// The joint certificate: the sub-optimal MHE with the K_c-iteration MPC.
    Joint,
    /// The global loop certificate (Theorem L3; in f32 Theorem L3u): the sub-optimal MHE with
    /// the exact MPC, every K ≥ K_glob ([`crate::lure::global_outcome`]).
    Global,
    /// The iteration chain (Theorem L3b, f64, pg and pg-jacobi; Theorem L3c, fista and
    /// fista-jacobi): the K it was checked at
    /// and certified, that K only ([`crate::lure::chain_outcome`]).
    Chain,
}

impl CertificateKind {
    /// `"theorem1"`, `"joint"`, `"global"` or `"chain"` (the `certificate` column and key).
    pub fn name(self) -> &'static str {
        match self {
            CertificateKind::Theorem1 => "theorem1",
            CertificateKind::Joint => "joint",
            CertificateKind::Global => "global",
            CertificateKind::Chain => "chain",
        }
    }

    /// `"Theorem 1"`, `"joint MPC + MHE"` or the global certificate's name (the reports' words).
    pub fn title(self) -> &'static str {
        match self {
            CertificateKind::Theorem1 => "Theorem 1",
            CertificateKind::Joint => "joint MPC + MHE",
            CertificateKind::Global => "the global loop certificate (Theorem L3)",
            CertificateKind::Chain => "the iteration chain (Theorem L3b; L3c for FISTA)",
        }
    }
}

/// Injected error sequences per magnitude that test a user-supplied γ₁,₃ (the sampled lower
/// estimate that refutes it when it exceeds the value). One number for every command: a
/// different sample could refute a value in one command and not in another.
pub const USER_GAMMA13_SEQUENCES: usize = 30;

/// The options of [`crate::certificate::certify_closed_loop`] that decide every verdict, for
/// `solvers` on `scenario`: γ₁,₃ is the user's (`cli_gamma13`, else the scenario's
/// `certificate.gamma13`) tested by [`USER_GAMMA13_SEQUENCES`] sampled sequences per magnitude
/// with the scenario's seed, else the certified one; the budget is the scenario's
/// `certificate.phase_seconds`, which also budgets the global loop certificate computed with
/// it (the verdict's second certificate). The sampled estimates that decide nothing (L_Φ, L_π, and
/// γ₁,₃ beside a certified value) are skipped; a command that reports them raises
/// `lipschitz_pairs` / `gamma13_sequences` (the latter only without a user γ₁,₃).
pub fn verdict_options(
    scenario: &Scenario,
    solvers: Vec<Method>,
    cli_gamma13: Option<f64>,
) -> CertificateOptions {
    let user = cli_gamma13.or(scenario.certificate.gamma13);
    CertificateOptions {
        solvers,
        gamma13: user.map_or(Gamma13Source::Certified, Gamma13Source::User),
        seed: scenario.noise.seed,
        lipschitz_pairs: 0,
        gamma13_sequences: if user.is_some() {
            USER_GAMMA13_SEQUENCES
        } else {
            0
        },
        phase_seconds: scenario.certificate.phase_seconds(),
        global_seconds: Some(scenario.certificate.phase_seconds()),
        ..CertificateOptions::default()
    }
}

/// The arithmetic of a configuration.
pub use crate::certificate::precision::Scalar;

/// One configuration whose verdict a command states.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Configuration {
    /// The MHE's method.
    pub method: Method,
    /// Iterations K_e of the MHE per step.
    pub k_e: usize,
    /// The controller (its K_c for the K_c-iteration MPC).
    pub controller: ControllerChoice,
    /// The arithmetic.
    pub scalar: Scalar,
}

/// The verdict on `config` for `resolved` (its warm start and constraints come from the
/// scenario), from the closed-loop certificate `cert` computed with [`verdict_options`]
/// (with `config.method` among its solvers): the one decision behind `reproduce`'s
/// `certified`, the sweep's `certified` column and `export`'s `MHE_CERTIFIED`.
pub fn verdict(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    config: &Configuration,
) -> PairVerdict {
    let k_c = match config.controller {
        ControllerChoice::SuboptimalMpc { iterations, .. } => Some(iterations.get()),
        _ => None,
    };
    let applicable = Applicable::new(resolved, cert, config.method, config.controller);
    let v = applicable.at_alone(config.k_e, k_c);
    let v = match (config.scalar, &applicable) {
        (Scalar::F64, _) => v,
        (
            Scalar::F32,
            Applicable::Joint {
                analysis, k_max, ..
            },
        ) => global::joint_f32_verdict(resolved, cert, config, analysis, *k_max, v),
        (Scalar::F32, _) => f32_verdict(resolved, cert, config, v),
    };
    with_global(v, applicable.global(), config.k_e, config.scalar)
}

/// Whether some K of `sc`'s method is certified for the scenario's configuration (its warm
/// start and `controller`) — by Theorem 1's entry `sc` (a K_min) or by the global loop
/// certificate of `cert` (a K_glob, or a K the iteration chain certified; [`global_of`]): the per-solver `certified` of
/// `reproduce`'s certificate.json, and exactly "the verdict at the smaller floor is `yes`".
/// False when nothing covers the configuration, whatever the floors say.
pub fn solver_certified(
    scenario: &Scenario,
    cert: &ClosedLoopCertificate,
    sc: &SolverCertificate,
    controller: ControllerChoice,
) -> bool {
    let covered = matches!(
        covering(scenario, sc.solver, controller),
        Coverage::Covered(_)
    );
    covered
        && (sc.k_min.is_some()
            || global_of(cert, sc.solver, controller).is_some_and(MethodGlobal::certifies_some_k))
}

/// Which certificate covers a configuration, or why none does. `#[non_exhaustive]`: callers
/// decide through [`Coverage::covers`] and [`Coverage::uncovered_reason`], matched
/// exhaustively here, so a new variant is decided in this crate, not by a caller's wildcard.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Coverage {
    /// This certificate applies (it may still be void for these parameters).
    Covered(CertificateKind),
    /// No certificate covers the configuration: the reason names the scenario key.
    Uncovered(Uncovered),
}

/// Why no certificate covers a configuration. Serialised as its sentence.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Uncovered {
    /// The time-shifted MHE warm start (Lemma 1 and Prop. 1 assume the paper's Σ_t).
    ShiftedWarmStart,
    /// The saturated LQR controller (L_π and γ₁,₃ are the MPC's).
    SaturatedLqr,
    /// The closed-loop certificate has no entry for the method.
    NoEntry {
        /// The MHE's method.
        method: Method,
    },
    /// The scenario's MPC cannot be built (its error's sentence).
    NoMpc {
        /// The error.
        error: String,
    },
    /// The joint certificate cannot be computed (its error's sentence).
    NoJoint {
        /// The error.
        error: String,
    },
}

impl std::fmt::Display for Uncovered {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::ShiftedWarmStart => f.write_str(
                "mhe.warm_start = \"shifted\" is not covered by the analysis (Lemma 1 and Prop. \
                 1 assume the paper's warm start Σ_t); set mhe.warm_start = \"paper\" for a \
                 certificate",
            ),
            Self::SaturatedLqr => f.write_str(
                "the controller is the saturated LQR: the certificates are for the MPC (its L_π \
                 and γ₁,₃); use the exact or the K_c-iteration MPC for a certificate",
            ),
            Self::NoEntry { method } => write!(f, "the certificate has no entry for {method}"),
            Self::NoMpc { error } => write!(f, "no MPC: {error}"),
            Self::NoJoint { error } => write!(f, "no joint certificate: {error}"),
        }
    }
}

#[cfg(feature = "serde")]
impl Serialize for Uncovered {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Why an f32 loop is void (the f32 part of [`PairReason::F32`]).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum F32Void {
    /// The joint certificate with both maps' f32 rounding folded in has no K_e at this K_c.
    JointNoPair {
        /// The MPC's K_c.
        k_c: usize,
        /// The largest K_e searched.
        k_max: usize,
        /// ρ(Γ) at (K_e, K_c) = (k_max, k_c).
        spectral_radius: f64,
        /// The smallest K_c certified with K_e = k_max (None: none ≤ k_max — the MHE's
        /// rounding binds whatever the MPC does, as in Theorem 1 in f32).
        k_c_floor: Option<usize>,
    },
    /// The f64 certificate is void or does not apply.
    NotCovered,
    /// The rounding model cannot be computed (its error's sentence).
    RoundingModel {
        /// The error.
        error: String,
    },
    /// Theorem 1 with the f32 rounding folded in is void.
    Void(ScalarVoid),
    /// No K is certified with the f32 rounding (no reason recorded).
    NoK,
}

impl std::fmt::Display for F32Void {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::JointNoPair {
                k_c,
                k_max,
                spectral_radius,
                k_c_floor,
            } => {
                write!(
                    f,
                    "the joint certificate with both maps' f32 rounding folded in certifies no \
                     K_e ≤ {k_max} with K_c = {k_c} (ρ(Γ) = {} at K_e = {k_max}); ",
                    lti_model::numfmt::sig4(*spectral_radius)
                )?;
                match k_c_floor {
                    Some(kf) => write!(f, "raise K_c to at least {kf} (its floor in f32)"),
                    None => f.write_str(
                        "no K_c helps: the MHE's rounding leaves no room, as in Theorem 1 in \
                         f32 (run in f64)",
                    ),
                }
            }
            Self::NotCovered => {
                f.write_str("not covered: the f64 certificate is void or does not apply")
            }
            Self::RoundingModel { error } => {
                write!(f, "the rounding model cannot be computed: {error}")
            }
            Self::Void(why) => why.fmt(f),
            Self::NoK => f.write_str("no K certified with the f32 rounding"),
        }
    }
}

/// A premise of Theorem 1 that fails, with the value tested (a void verdict without
/// recorded reasons).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ViolatedPremise {
    /// The premise's short name.
    pub premise: String,
    /// The value tested.
    pub value: f64,
}

/// Why a pair is not certified ([`PairVerdict::reason`]). Serialised as its sentence.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum PairReason {
    /// Nothing covers the configuration.
    Uncovered(Uncovered),
    /// The covering certificate is void whatever the pair.
    Void(Vec<VoidReason>),
    /// The analysis budget cut the verdict.
    NotComputed(NotComputed),
    /// Premises of Theorem 1 fail (no reasons recorded).
    Violated(Vec<ViolatedPremise>),
    /// The joint certificate was asked without K_c.
    NeedsKc,
    /// An f32 loop is void; `then` is the f64 verdict's reason, if any.
    F32 {
        /// Why f32 is void.
        why: F32Void,
        /// The f64 verdict's reason.
        then: Option<Box<PairReason>>,
    },
    /// Theorem 1's verdict (`then`) and the global loop certificate's outcome: stopped by
    /// the budget, or (Theorem 1 void) proved absent or not modelled in the verdict's scalar
    /// ([`with_global`]).
    Global {
        /// Theorem 1's (or the f32) reason, if any.
        then: Option<Box<PairReason>>,
        /// The global certificate's outcome.
        global: GlobalWhy,
    },
    /// The iteration chain at K: not checked there, or budget-stopped, or none found there
    /// while it certifies another K ([`ChainWhy`]).
    Chain(ChainWhy),
    /// K is below the f32 K_min (Theorem 1 with the f32 rounding folded in).
    BelowF32KMin {
        /// The K asked for.
        k: usize,
        /// The f32 K_min.
        k_min: usize,
    },
}

/// [`PairVerdict::reason`] as JSON: its sentence, `""` when there is none (the schema).
#[cfg(feature = "serde")]
fn reason_sentence<S: serde::Serializer>(r: &Option<PairReason>, s: S) -> Result<S::Ok, S::Error> {
    match r {
        Some(r) => s.collect_str(r),
        None => s.serialize_str(""),
    }
}

impl Coverage {
    /// The covering certificate (None: nothing covers the configuration).
    pub fn covers(&self) -> Option<CertificateKind> {
        match self {
            Coverage::Covered(kind) => Some(*kind),
            Coverage::Uncovered(_) => None,
        }
    }

    /// Why nothing covers the configuration (None: covered).
    pub fn uncovered_reason(&self) -> Option<&Uncovered> {
        match self {
            Coverage::Covered(_) => None,
            Coverage::Uncovered(why) => Some(why),
        }
    }
}

/// Decides which certificate covers the MHE `method` with `controller` on `scenario`
/// (K_e and K_c do not change the decision, only the verdict).
pub fn covering(scenario: &Scenario, _method: Method, controller: ControllerChoice) -> Coverage {
    if scenario
        .mhe
        .as_ref()
        .is_some_and(|m| m.warm_start() == WarmStart::Shifted)
    {
        return Coverage::Uncovered(Uncovered::ShiftedWarmStart);
    }
    match controller {
        ControllerChoice::ExactMpc => Coverage::Covered(CertificateKind::Theorem1),
        ControllerChoice::SuboptimalMpc { .. } => Coverage::Covered(CertificateKind::Joint),
        ControllerChoice::SaturatedLqr => Coverage::Uncovered(Uncovered::SaturatedLqr),
    }
}

/// `yes`, `no`, `void` or `not_computed` at a pair.
///
/// `#[non_exhaustive]`, and safe so: a caller outside this crate cannot match it without a
/// wildcard arm, so it decides through [`Certified::is_certified`] and
/// [`Certified::is_below_floor`], which this crate matches exhaustively. A new variant then
/// does not compile here until it is decided, and cannot reach a caller as "certified": that
/// is a compile-time property (no runtime test can build an unknown variant), which is why
/// the tool never compares against [`Certified::Yes`] in a wildcard match.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum Certified {
    /// The certificate holds at this pair.
    Yes,
    /// It applies and its premises hold, but not at this pair (too few iterations).
    No,
    /// No certificate at any pair: a premise fails, or none covers the configuration.
    Void,
    /// The analysis budget (`certificate.phase_seconds`) cut the verdict: not proved void,
    /// not computed (the reason names the phase and the budget that would compute it).
    NotComputed,
}

/// [`Certified::as_str`].
impl std::fmt::Display for Certified {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Certified {
    /// `"yes"`, `"no"`, `"void"` or `"not_computed"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Certified::Yes => "yes",
            Certified::No => "no",
            Certified::Void => "void",
            Certified::NotComputed => "not_computed",
        }
    }

    /// Whether the certificate holds at the pair: true for [`Certified::Yes`] only. The one
    /// test behind `export`'s refusal and every "certified" a command prints.
    pub fn is_certified(self) -> bool {
        match self {
            Certified::Yes => true,
            Certified::No | Certified::Void | Certified::NotComputed => false,
        }
    }

    /// Whether the certificate applies and holds, but not at this pair: too few iterations
    /// ([`Certified::No`]; `PairVerdict::k_min` is the floor when known). False for a
    /// certified, void or not-computed verdict.
    pub fn is_below_floor(self) -> bool {
        match self {
            Certified::No => true,
            Certified::Yes | Certified::Void | Certified::NotComputed => false,
        }
    }
}

/// The verdict at one pair (K_e, K_c).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct PairVerdict {
    /// The covering certificate (None: uncovered).
    pub certificate: Option<CertificateKind>,
    /// The verdict.
    pub certified: Certified,
    /// Smallest certified K_e at this K_c (Theorem 1: K_min; joint: at the pair's K_c).
    pub k_min: Option<usize>,
    /// The certified margin at the pair (1 − ρ(Γ)); None where undefined.
    pub margin: Option<f64>,
    /// Why not certified (None when certified, and for a plain "no": too few iterations).
    /// JSON: its sentence, `""` for None.
    #[cfg_attr(feature = "serde", serde(serialize_with = "reason_sentence"))]
    pub reason: Option<PairReason>,
}

impl PairVerdict {
    /// [`PairVerdict::reason`]'s sentence, empty when there is none (the reports' and the
    /// CSV's form).
    pub fn reason_text(&self) -> String {
        self.reason
            .as_ref()
            .map_or_else(String::new, ToString::to_string)
    }
}

/// What the covering certificate needs to give a verdict at any pair. `#[non_exhaustive]`:
/// callers get verdicts from [`Applicable::at`] and decide with [`Applicable::may_certify`]
/// and [`Applicable::uncovered_reason`], matched exhaustively here.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub enum Applicable {
    /// Theorem 1 for the method.
    Theorem1 {
        /// Its analysis.
        analysis: Box<IssAnalysis>,
        /// K_min (None: void or beyond the search range).
        k_min: Option<usize>,
        /// Why void whatever K (empty when the premises hold).
        void_reasons: Vec<VoidReason>,
        /// The budget cut the verdict (None: computed).
        not_computed: Option<NotComputed>,
        /// The global loop certificate of the method with this controller (None: not
        /// computed, or computed for another controller): [`with_global`] combines it.
        global: Option<Box<MethodGlobal>>,
    },
    /// The joint certificate of the method with the MPC's method.
    Joint {
        /// Its four-node analysis.
        analysis: Box<JointAnalysis>,
        /// Largest K_e searched for K_min.
        k_max: usize,
        /// Why void whatever the pair (empty when the premises hold).
        void_reasons: Vec<VoidReason>,
    },
    /// Nothing covers the configuration.
    Uncovered(Uncovered),
}

/// Theorem 1's verdict at K from its analysis, K_min, void reasons and budget cut: the one
/// rule behind [`Applicable::at`] and the sweep's columns. Void when a premise fails (its
/// reasons, or the violated premises themselves when none was recorded); not computed when
/// the budget cut the analysis and nothing else voids it; else yes or no at K.
pub fn theorem1_at(
    analysis: &IssAnalysis,
    k_min: Option<usize>,
    void_reasons: &[VoidReason],
    not_computed: Option<&NotComputed>,
    k_e: usize,
) -> PairVerdict {
    let verdict = |certified, reason: PairReason| PairVerdict {
        certificate: Some(CertificateKind::Theorem1),
        certified,
        k_min: None,
        margin: None,
        reason: Some(reason),
    };
    if k_min.is_none() && !void_reasons.is_empty() {
        return verdict(Certified::Void, PairReason::Void(void_reasons.to_vec()));
    }
    if let (None, Some(why)) = (k_min, not_computed) {
        return verdict(Certified::NotComputed, PairReason::NotComputed(why.clone()));
    }
    let violated = analysis.violated();
    if k_min.is_none() && !violated.is_empty() {
        let premises = violated
            .iter()
            .map(|p| ViolatedPremise {
                premise: p.name.clone(),
                value: p.value,
            })
            .collect();
        return verdict(Certified::Void, PairReason::Violated(premises));
    }
    let g = analysis.at(k_e);
    PairVerdict {
        certificate: Some(CertificateKind::Theorem1),
        certified: if g.certified {
            Certified::Yes
        } else {
            Certified::No
        },
        k_min,
        margin: (g.phi < 1.0 && g.phi.is_finite()).then_some(g.margin),
        reason: None,
    }
}

impl Applicable {
    /// The certificate covering `method` with `controller` on `resolved`, evaluated from the
    /// closed-loop certificate `cert` (computed for the scenario with `method` among its
    /// solvers).
    pub fn new(
        resolved: &ResolvedScenario,
        cert: &ClosedLoopCertificate,
        method: Method,
        controller: ControllerChoice,
    ) -> Self {
        let scenario = resolved.scenario();
        let kind = match covering(scenario, method, controller) {
            Coverage::Uncovered(r) => return Applicable::Uncovered(r),
            Coverage::Covered(k) => k,
        };
        let Some(sc) = cert.solver(method) else {
            return Applicable::Uncovered(Uncovered::NoEntry { method });
        };
        match (kind, controller) {
            (CertificateKind::Joint, ControllerChoice::SuboptimalMpc { method: mpc_m, .. }) => {
                let mpc = match resolved.mpc() {
                    Ok(m) => m,
                    Err(e) => {
                        let error = e.to_string();
                        return Applicable::Uncovered(Uncovered::NoMpc { error });
                    }
                };
                let plant = &scenario.plant;
                let n_e = plant.nx() + cert.horizon * (plant.nx() + plant.ny());
                let opts = JointOptions::default();
                match certify_joint(cert, mpc, n_e, method, mpc_m, &opts) {
                    Ok(j) => {
                        // The structural reasons of Theorem 1's constants (L_Φ with general
                        // rows, L_π with state constraints) void the joint certificate too;
                        // its premises are the joint analysis' own.
                        let mut void_reasons: Vec<VoidReason> = sc
                            .void_reasons
                            .iter()
                            .filter(|r| {
                                matches!(
                                    r,
                                    VoidReason::LPhiUndefined { .. }
                                        | VoidReason::ControllerUndefined { .. }
                                )
                            })
                            .cloned()
                            .collect();
                        for r in &j.region.void_reasons {
                            if !void_reasons.contains(r) {
                                void_reasons.push(r.clone());
                            }
                        }
                        Applicable::Joint {
                            analysis: Box::new(j.analysis),
                            k_max: opts.k_max,
                            void_reasons,
                        }
                    }
                    Err(e) => Applicable::Uncovered(Uncovered::NoJoint {
                        error: e.to_string(),
                    }),
                }
            }
            _ => Applicable::Theorem1 {
                analysis: Box::new(sc.analysis.clone()),
                k_min: sc.k_min,
                void_reasons: sc.void_reasons.clone(),
                not_computed: sc.not_computed.clone(),
                global: global_of(cert, method, controller).map(|m| Box::new(m.clone())),
            },
        }
    }

    /// The covering certificate (None: uncovered).
    pub fn kind(&self) -> Option<CertificateKind> {
        match self {
            Applicable::Theorem1 { .. } => Some(CertificateKind::Theorem1),
            Applicable::Joint { .. } => Some(CertificateKind::Joint),
            Applicable::Uncovered(_) => None,
        }
    }

    /// Why nothing covers the configuration (None: a certificate applies).
    pub fn uncovered_reason(&self) -> Option<&Uncovered> {
        match self {
            Applicable::Uncovered(why) => Some(why),
            Applicable::Theorem1 { .. } | Applicable::Joint { .. } => None,
        }
    }

    /// Whether some pair can be certified: Theorem 1 with a K_min or the global loop
    /// certificate with a K_glob; the joint certificate when no reason voids it whatever the
    /// pair (its region then says which pairs); never when uncovered.
    pub fn may_certify(&self) -> bool {
        match self {
            Applicable::Theorem1 { k_min, global, .. } => {
                k_min.is_some() || global.as_ref().is_some_and(|g| g.certifies_some_k())
            }
            Applicable::Joint { void_reasons, .. } => void_reasons.is_empty(),
            Applicable::Uncovered(_) => false,
        }
    }

    /// Void whatever the pair (uncovered, or a premise fails).
    pub fn void_reasons(&self) -> Vec<String> {
        match self {
            Applicable::Theorem1 {
                void_reasons,
                k_min,
                ..
            } => {
                if k_min.is_some() {
                    Vec::new()
                } else {
                    void_reasons.iter().map(ToString::to_string).collect()
                }
            }
            Applicable::Joint { void_reasons, .. } => {
                void_reasons.iter().map(ToString::to_string).collect()
            }
            Applicable::Uncovered(r) => vec![r.to_string()],
        }
    }

    /// The global loop certificate combined with Theorem 1's verdicts (None: none).
    pub fn global(&self) -> Option<&MethodGlobal> {
        match self {
            Applicable::Theorem1 { global, .. } => global.as_deref(),
            Applicable::Joint { .. } | Applicable::Uncovered(_) => None,
        }
    }

    /// The verdict at (K_e, K_c) in f64, of every certificate that applies ([`with_global`]);
    /// `k_c` is ignored by Theorem 1 (the exact MPC) and required by the joint certificate
    /// (None there: void, "no K_c").
    pub fn at(&self, k_e: usize, k_c: Option<usize>) -> PairVerdict {
        with_global(self.at_alone(k_e, k_c), self.global(), k_e, Scalar::F64)
    }

    /// The covering certificate's own verdict at (K_e, K_c), without the global one.
    fn at_alone(&self, k_e: usize, k_c: Option<usize>) -> PairVerdict {
        let kind = self.kind();
        let void = |reason: PairReason| PairVerdict {
            certificate: kind,
            certified: Certified::Void,
            k_min: None,
            margin: None,
            reason: Some(reason),
        };
        match self {
            Applicable::Uncovered(r) => void(PairReason::Uncovered(r.clone())),
            Applicable::Theorem1 {
                analysis,
                k_min,
                void_reasons,
                not_computed,
                ..
            } => theorem1_at(analysis, *k_min, void_reasons, not_computed.as_ref(), k_e),
            Applicable::Joint {
                analysis,
                k_max,
                void_reasons,
            } => {
                if !void_reasons.is_empty() {
                    return void(PairReason::Void(void_reasons.clone()));
                }
                let Some(k_c) = k_c else {
                    return void(PairReason::NeedsKc);
                };
                let g = analysis.at(k_e, k_c);
                PairVerdict {
                    certificate: kind,
                    certified: if g.certified {
                        Certified::Yes
                    } else {
                        Certified::No
                    },
                    k_min: analysis.k_e_min(k_c, *k_max),
                    margin: g.margin.is_finite().then_some(g.margin),
                    reason: None,
                }
            }
        }
    }
}
