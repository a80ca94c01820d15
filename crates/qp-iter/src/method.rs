//! The one list of iteration maps Φ: [`Method`] names a method and its parameters (what a
//! scenario, a sweep, a certificate or a plot refers to), [`MethodMap`] is the map built
//! for a problem, dispatching to the concrete method **once per run**
//! ([`IterationMap::run_steps`]), never per iteration.
//!
//! Adding a method is one new file with its [`IterationMap`] implementation and one arm in
//! each `match` of this file (the compiler lists them); nothing above `qp-iter` changes.
//! `docs/architecture.md` lists the places.
//!
//! ## File format
//! A method is written as its name — `"pg"` (step 2/(L + μ)), `"fista"`, `"admm"` (ρ = √(μL),
//! α = 1) or `"admm-pr"` (ρ = √(μL), α = 2, Peaceman–Rachford) — or as a table with its
//! parameters: `{ method = "pg", step = 0.05 }`, `{ method = "admm", rho = 2.0, alpha = 1.6 }`.
//!
//! ```
//! use qp_iter::method::Method;
//! let m: Method = "admm-pr".parse().unwrap();
//! assert_eq!(m, Method::ADMM_PR);
//! assert_eq!(m.to_string(), "admm-pr");
//! let custom = Method::admm(Some(2.0), 1.5).unwrap();
//! assert_eq!(custom.to_string(), "admm(rho=2,alpha=1.5)");
//! ```

use std::borrow::Cow;
use std::fmt;
use std::str::FromStr;

use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::admm::{Admm, AdmmParams, AdmmState, Penalty};
use crate::admm_general::{AdmmSplit, AdmmSplitState};
use crate::certificate::Certificate;
use crate::error::{QpError, Result};
use crate::fista::{Fista, FistaState};
use crate::pg::{PgState, ProjectedGradient, StepRule};
use crate::problem::ParametricQp;
use crate::scaled::{Scaled, ScaledState, jacobi_scaling};
use crate::{IterationMap, RunResult, run_fixed};

/// The family of an iteration map and its parameters (the method without its scaling).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MethodKind {
    /// Projected gradient with a step rule ([`ProjectedGradient`]).
    Pg(StepRule),
    /// V-FISTA, the accelerated projected gradient for strongly convex problems ([`Fista`]).
    Fista,
    /// ADMM with penalty ρ and relaxation α ([`Admm`]).
    Admm(AdmmParams),
}

/// How the QP is scaled before the map runs on it ([`crate::scaled`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scaling {
    /// The problem as given.
    #[default]
    None,
    /// z = Dy with D = diag(H)^{−½} (unit diagonal of DHD): removes the η^{−M} growth of
    /// κ(H) of the MHE's QP; the certificate's prefactor gains κ(D), its rate improves.
    Jacobi,
}

/// An iteration map Φ of Assumption 5 with its parameters and scaling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Method {
    /// The family and its parameters.
    pub kind: MethodKind,
    /// The diagonal scaling of the problem it runs on.
    pub scaling: Scaling,
}

impl Method {
    const fn plain(kind: MethodKind) -> Self {
        Method {
            kind,
            scaling: Scaling::None,
        }
    }
    /// `"pg"`: projected gradient with the optimal constant step 2/(L + μ).
    pub const PG: Method = Method::plain(MethodKind::Pg(StepRule::Optimal));
    /// `"fista"`.
    pub const FISTA: Method = Method::plain(MethodKind::Fista);
    /// `"admm"`: ρ = √(μL), α = 1.
    pub const ADMM: Method = Method::plain(MethodKind::Admm(AdmmParams {
        penalty: Penalty::Optimal,
        relaxation: 1.0,
    }));
    /// `"admm-pr"`: ρ = √(μL), α = 2 (Peaceman–Rachford): the certified rate
    /// δ = (√κ − 1)/(√κ + 1) instead of (1 + δ)/2, so about half the K of `"admm"`.
    pub const ADMM_PR: Method = Method::plain(MethodKind::Admm(AdmmParams {
        penalty: Penalty::Optimal,
        relaxation: 2.0,
    }));
    /// The named methods, in the order reports list them.
    pub const PRESETS: [Method; 4] = [Method::PG, Method::FISTA, Method::ADMM, Method::ADMM_PR];
    /// The named methods on the Jacobi-scaled problem (`"pg-jacobi"`, …).
    pub const JACOBI_PRESETS: [Method; 4] = [
        Method::PG.with_scaling(Scaling::Jacobi),
        Method::FISTA.with_scaling(Scaling::Jacobi),
        Method::ADMM.with_scaling(Scaling::Jacobi),
        Method::ADMM_PR.with_scaling(Scaling::Jacobi),
    ];

    /// The same method on a differently scaled problem.
    pub const fn with_scaling(self, scaling: Scaling) -> Self {
        Method {
            kind: self.kind,
            scaling,
        }
    }

    /// Projected gradient with a fixed step α > 0 (`None`: the optimal step 2/(L + μ)).
    pub fn pg(step: Option<f64>) -> Result<Self> {
        let m = Method::plain(MethodKind::Pg(
            step.map_or(StepRule::Optimal, StepRule::Fixed),
        ));
        m.validate()?;
        Ok(m)
    }

    /// ADMM with penalty ρ > 0 (`None`: ρ = √(μL)) and relaxation α ∈ (0, 2].
    pub fn admm(rho: Option<f64>, alpha: f64) -> Result<Self> {
        let m = Method::plain(MethodKind::Admm(AdmmParams {
            penalty: rho.map_or(Penalty::Optimal, Penalty::Fixed),
            relaxation: alpha,
        }));
        m.validate()?;
        Ok(m)
    }

    /// Checks the parameters without a problem (the maps check them again at setup).
    pub fn validate(&self) -> Result<()> {
        let bad = |name: &str, value: f64, reason: &str| {
            Err(QpError::Parameter {
                name: name.into(),
                value,
                reason: reason.into(),
            })
        };
        match self.kind {
            MethodKind::Pg(StepRule::Fixed(a)) if !(a > 0.0 && a.is_finite()) => {
                bad("step", a, "the step must be positive and finite")
            }
            MethodKind::Admm(p) => {
                if let Penalty::Fixed(r) = p.penalty {
                    if !(r > 0.0 && r.is_finite()) {
                        return bad("rho", r, "the ADMM penalty must be positive and finite");
                    }
                }
                if !(p.relaxation > 0.0 && p.relaxation <= 2.0) {
                    return bad(
                        "alpha",
                        p.relaxation,
                        "the ADMM relaxation must lie in (0, 2] (1 = plain ADMM)",
                    );
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// The method's name: `"pg"`, `"fista"`, `"admm"`, `"admm-pr"` for the named methods
    /// (`"pg-jacobi"`, … on the Jacobi-scaled problem), otherwise the family with its
    /// parameters (`"admm(rho=2,alpha=1.5)"`, `"pg(step=0.1,scaling=jacobi)"`).
    pub fn name(&self) -> Cow<'static, str> {
        let base: Cow<'static, str> = match self.kind {
            MethodKind::Pg(StepRule::Optimal) => "pg".into(),
            MethodKind::Pg(StepRule::InverseL) => "pg(step=1/L)".into(),
            MethodKind::Pg(StepRule::Fixed(a)) => format!("pg(step={})", short(a)).into(),
            MethodKind::Fista => "fista".into(),
            MethodKind::Admm(p) => match (p.penalty, p.relaxation) {
                (Penalty::Optimal, 1.0) => "admm".into(),
                (Penalty::Optimal, 2.0) => "admm-pr".into(),
                (Penalty::Optimal, a) => format!("admm(alpha={})", short(a)).into(),
                (Penalty::Fixed(r), a) => {
                    format!("admm(rho={},alpha={})", short(r), short(a)).into()
                }
            },
        };
        match self.scaling {
            Scaling::None => base,
            Scaling::Jacobi => match base.strip_suffix(')') {
                Some(head) => format!("{head},scaling=jacobi)").into(),
                None => format!("{base}-jacobi").into(),
            },
        }
    }

    /// The family name of the map (`"pg"`, `"fista"`, `"admm"`), what
    /// [`IterationMap::name`] reports.
    pub fn family(&self) -> &'static str {
        match self.kind {
            MethodKind::Pg(_) => "pg",
            MethodKind::Fista => "fista",
            MethodKind::Admm(_) => "admm",
        }
    }

    /// Builds Φ for `qp` (allocates: setup).
    pub fn build(&self, qp: ParametricQp) -> Result<MethodMap> {
        let kind = self.kind;
        let plain = move |qp: ParametricQp| -> Result<MethodMap> {
            Ok(match kind {
                MethodKind::Pg(rule) => MethodMap::Pg(ProjectedGradient::new(qp, rule)?),
                MethodKind::Fista => MethodMap::Fista(Fista::new(qp)),
                // With general rows ADMM splits on [I; G]z (no certificate, measured
                // violation: `admm_general`).
                MethodKind::Admm(params) if qp.general().is_some() => {
                    MethodMap::AdmmSplit(AdmmSplit::new(qp, params)?)
                }
                MethodKind::Admm(params) => MethodMap::Admm(Admm::new(qp, params)?),
            })
        };
        match self.scaling {
            Scaling::None => plain(qp),
            Scaling::Jacobi => {
                let d = jacobi_scaling(&qp);
                Ok(MethodMap::Scaled(Box::new(Scaled::new(qp, d, plain)?)))
            }
        }
    }

    /// The certificate φ(K) this method has on `qp` (builds the map once).
    pub fn certificate_for(&self, qp: ParametricQp) -> Result<Certificate> {
        Ok(self.build(qp)?.certificate().clone())
    }
}

impl Default for Method {
    /// Projected gradient with step 2/(L + μ), the certified default.
    fn default() -> Self {
        Method::PG
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

impl FromStr for Method {
    type Err = QpError;
    /// One of the names `"pg"`, `"fista"`, `"admm"`, `"admm-pr"`, each optionally with
    /// `-jacobi` (the same method on the Jacobi-scaled problem).
    fn from_str(s: &str) -> Result<Self> {
        let (base, scaling) = match s.strip_suffix("-jacobi") {
            Some(b) => (b, Scaling::Jacobi),
            None => (s, Scaling::None),
        };
        let m = match base {
            "pg" => Method::PG,
            "fista" => Method::FISTA,
            "admm" => Method::ADMM,
            "admm-pr" => Method::ADMM_PR,
            _ => return Err(QpError::UnknownMethod { name: s.into() }),
        };
        Ok(m.with_scaling(scaling))
    }
}

// ---------------------------------------------------------------------------------------
// Serde: a name, or a table with the parameters.
// ---------------------------------------------------------------------------------------

#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct MethodTable {
    method: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    step: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rho: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    alpha: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    scaling: Option<Scaling>,
}

impl MethodTable {
    fn into_method(self) -> std::result::Result<Method, String> {
        let family = self.method.as_str();
        let only = |allowed: &[&str]| -> std::result::Result<(), String> {
            for (key, given) in [
                ("step", self.step.is_some()),
                ("rho", self.rho.is_some()),
                ("alpha", self.alpha.is_some()),
            ] {
                if given && !allowed.contains(&key) {
                    return Err(format!("`{key}` is not a parameter of `{family}`"));
                }
            }
            Ok(())
        };
        let m = match family {
            "pg" => {
                only(&["step"])?;
                Method::pg(self.step)
            }
            "fista" => {
                only(&[])?;
                Ok(Method::FISTA)
            }
            "admm" | "admm-pr" => {
                only(&["rho", "alpha"])?;
                let default_alpha = if family == "admm" { 1.0 } else { 2.0 };
                Method::admm(self.rho, self.alpha.unwrap_or(default_alpha))
            }
            other => return Err(QpError::UnknownMethod { name: other.into() }.to_string()),
        };
        m.map(|m| m.with_scaling(self.scaling.unwrap_or_default()))
            .map_err(|e| e.to_string())
    }
}

impl Serialize for Method {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        if Method::PRESETS.contains(self) || Method::JACOBI_PRESETS.contains(self) {
            return s.serialize_str(&self.name());
        }
        let mut table = MethodTable {
            method: self.family().into(),
            step: None,
            rho: None,
            alpha: None,
            scaling: (self.scaling != Scaling::None).then_some(self.scaling),
        };
        match self.kind {
            MethodKind::Pg(StepRule::Fixed(a)) => table.step = Some(a),
            MethodKind::Pg(_) | MethodKind::Fista => {}
            MethodKind::Admm(p) => {
                table.rho = match p.penalty {
                    Penalty::Fixed(r) => Some(r),
                    Penalty::Optimal => None,
                };
                table.alpha = Some(p.relaxation);
            }
        }
        table.serialize(s)
    }
}

impl<'de> Deserialize<'de> for Method {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Method;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(
                    "a method name (\"pg\", \"fista\", \"admm\", \"admm-pr\", each optionally \
                     with \"-jacobi\") or a table { method = \"…\", step / rho / alpha / scaling = … }",
                )
            }
            fn visit_str<E: de::Error>(self, v: &str) -> std::result::Result<Method, E> {
                v.parse().map_err(|e: QpError| E::custom(e))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> std::result::Result<Method, A::Error> {
                let table = MethodTable::deserialize(de::value::MapAccessDeserializer::new(map))?;
                table.into_method().map_err(de::Error::custom)
            }
        }
        d.deserialize_any(V)
    }
}

// ---------------------------------------------------------------------------------------
// The dispatching map
// ---------------------------------------------------------------------------------------

/// Φ built for one problem: one of the concrete maps, chosen by a [`Method`].
///
/// As an [`IterationMap`] it dispatches per call; [`IterationMap::run_steps`] (what
/// [`run_fixed`] uses) dispatches once and then runs the concrete map's steps in a loop, so
/// K iterations cost one branch, not K.
#[derive(Debug, Clone)]
pub enum MethodMap {
    /// Projected gradient.
    Pg(ProjectedGradient),
    /// FISTA.
    Fista(Fista),
    /// ADMM.
    Admm(Admm),
    /// ADMM split on [I; G]z, for a problem with general rows (void certificate).
    AdmmSplit(AdmmSplit),
    /// One of the above on the diagonally scaled problem ([`crate::scaled`]).
    Scaled(Box<Scaled<MethodMap>>),
}

/// The state of a [`MethodMap`]: the state of its concrete map.
#[derive(Debug)]
pub enum MethodState {
    /// Of projected gradient.
    Pg(PgState),
    /// Of FISTA.
    Fista(FistaState),
    /// Of ADMM.
    Admm(AdmmState),
    /// Of ADMM split on [I; G]z.
    AdmmSplit(AdmmSplitState),
    /// Of a scaled map.
    Scaled(Box<ScaledState<MethodState>>),
}

#[cold]
#[inline(never)]
fn foreign_state() -> ! {
    // A programming error of the caller (a state made by a map of another method), never
    // reachable from data: states come from `MethodMap::new_state` of the same map.
    panic!("MethodMap: the state was created by a map of another method")
}

/// `$body` with `$m` the concrete map and `$s` its state.
macro_rules! with_pair {
    ($map:expr, $state:expr, |$m:ident, $s:ident| $body:expr) => {
        match ($map, $state) {
            (MethodMap::Pg($m), MethodState::Pg($s)) => $body,
            (MethodMap::Fista($m), MethodState::Fista($s)) => $body,
            (MethodMap::Admm($m), MethodState::Admm($s)) => $body,
            (MethodMap::AdmmSplit($m), MethodState::AdmmSplit($s)) => $body,
            (MethodMap::Scaled($m), MethodState::Scaled($s)) => $body,
            _ => foreign_state(),
        }
    };
}

/// `$body` with `$m` the concrete map.
macro_rules! with_map {
    ($map:expr, |$m:ident| $body:expr) => {
        match $map {
            MethodMap::Pg($m) => $body,
            MethodMap::Fista($m) => $body,
            MethodMap::Admm($m) => $body,
            MethodMap::AdmmSplit($m) => $body,
            MethodMap::Scaled($m) => $body,
        }
    };
}

impl MethodMap {
    /// K = `k` steps of Φ and the status of the iterate, dispatched once
    /// (equivalent to [`run_fixed`]).
    pub fn run_fixed(&self, state: &mut MethodState, k: usize) -> RunResult {
        run_fixed(self, state, k)
    }
}

impl IterationMap for MethodMap {
    type State = MethodState;

    fn name(&self) -> &'static str {
        with_map!(self, |m| m.name())
    }
    fn problem(&self) -> &ParametricQp {
        with_map!(self, |m| m.problem())
    }
    fn new_state(&self) -> MethodState {
        match self {
            MethodMap::Pg(m) => MethodState::Pg(m.new_state()),
            MethodMap::Fista(m) => MethodState::Fista(m.new_state()),
            MethodMap::Admm(m) => MethodState::Admm(m.new_state()),
            MethodMap::AdmmSplit(m) => MethodState::AdmmSplit(m.new_state()),
            MethodMap::Scaled(m) => MethodState::Scaled(Box::new(m.new_state())),
        }
    }
    fn load(&self, state: &mut MethodState, theta: &[f64]) {
        with_pair!(self, state, |m, s| m.load(s, theta))
    }
    fn warm_start(&self, state: &mut MethodState, z0: &[f64], dual: Option<&[f64]>) {
        with_pair!(self, state, |m, s| m.warm_start(s, z0, dual))
    }
    fn cold_start(&self, state: &mut MethodState) {
        with_pair!(self, state, |m, s| m.cold_start(s))
    }
    fn step(&self, state: &mut MethodState) {
        with_pair!(self, state, |m, s| m.step(s))
    }
    fn run_steps(&self, state: &mut MethodState, k: usize) {
        with_pair!(self, state, |m, s| m.run_steps(s, k))
    }
    fn iterate<'s>(&self, state: &'s MethodState) -> &'s [f64] {
        with_pair!(self, state, |m, s| m.iterate(s))
    }
    fn dual<'s>(&self, state: &'s MethodState) -> Option<&'s [f64]> {
        with_pair!(self, state, |m, s| m.dual(s))
    }
    fn violation(&self, state: &MethodState) -> f64 {
        with_pair!(self, state, |m, s| m.violation(s))
    }
    fn certificate(&self) -> &Certificate {
        with_map!(self, |m| m.certificate())
    }
    fn matvecs_per_step(&self) -> usize {
        with_map!(self, |m| m.matvecs_per_step())
    }
}

/// A parameter in a method's name: exact (it round-trips, the name identifies the method)
/// and short: `1.5`, and `1e-300` rather than 300 digits.
fn short(x: f64) -> String {
    if x != 0.0 && !(1e-4..1e15).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn names_round_trip_through_serde() {
        for m in Method::PRESETS {
            let s = serde_json::to_string(&m).unwrap();
            assert_eq!(s, format!("\"{m}\""));
            assert_eq!(serde_json::from_str::<Method>(&s).unwrap(), m);
        }
        for m in [
            Method::pg(Some(0.05)).unwrap(),
            Method::admm(Some(2.0), 1.5).unwrap(),
            Method::admm(None, 1.2).unwrap(),
        ] {
            let s = serde_json::to_string(&m).unwrap();
            assert_eq!(serde_json::from_str::<Method>(&s).unwrap(), m, "{s}");
        }
    }

    #[test]
    fn bad_tables_name_the_parameter() {
        for (text, needle) in [
            (r#"{"method":"pg","rho":1.0}"#, "`rho`"),
            (r#"{"method":"admm","alpha":3.0}"#, "alpha"),
            (r#"{"method":"admm","rho":-1.0}"#, "rho"),
            (r#"{"method":"newton"}"#, "newton"),
            (r#""newton""#, "newton"),
            (r#"{"method":"pg","typo":1.0}"#, "typo"),
        ] {
            let e = serde_json::from_str::<Method>(text)
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
    }
}
