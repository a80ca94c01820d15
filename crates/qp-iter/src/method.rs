//! The one list of iteration maps Φ: [`Method`] names a method and its parameters (what a
//! scenario, a sweep, a certificate or a plot refers to), [`MethodMap`] is the map built
//! for a problem, dispatching to the concrete method **once per run**
//! ([`IterationMap::run_steps`]), never per iteration.
//!
//! Adding a method is one new file and one line of the list below (`method_list!`): the
//! file holds the map with its [`IterationMap`], [`Linearise`] and [`Family`]
//! implementations (names, parameters, validation, build); the enums, the parsing of names
//! and tables, the naming and every dispatch are generated from the list, so nothing else
//! in this crate or above it changes. The test-only `Trial` arm (`method/trial_method.rs`)
//! is such a method; `docs/architecture.md` shows its diff.
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

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use crate::admm::{AdmmParams, Penalty};
use crate::certificate::Certificate;
use crate::error::{QpError, Result};
use crate::linearise::Linearise;
use crate::pg::StepRule;
use crate::problem::ParametricQp;
use crate::scaled::{Scaled, ScaledState, jacobi_scaling};
use crate::{IterationMap, RunResult, run_fixed};

#[cfg(feature = "serde")]
mod serde_impl;
#[cfg(test)]
mod trial_method;

/// What a method family's own file tells the method list: its names and parameters in
/// files, their validation, and how to build its map. Implemented beside the map
/// (`pg.rs`, `fista.rs`, `admm.rs`); [`MethodKind`], [`MethodMap`], [`MethodState`], the
/// parsing and the dispatch are generated from the one list in this file.
pub trait Family: IterationMap + Linearise + Sized {
    /// The family's parameters (the payload of its [`MethodKind`] arm).
    type Params: Copy + PartialEq + fmt::Debug + Send + Sync + 'static;
    /// The family name in files and reports; also the first of [`Family::PRESETS`].
    const NAME: &'static str;
    /// Names that stand for preset parameters (`"admm-pr"`), the first being
    /// [`Family::NAME`] with the family's default parameters.
    const PRESETS: &'static [(&'static str, Self::Params)];
    /// The parameter keys of the table form (`{ method = "admm", rho = 2 }`).
    const KEYS: &'static [&'static str];
    /// The parameters of a table: `base` are those of the table's `method` name, `key`
    /// reads a key of [`Family::KEYS`] (validated afterwards by [`Family::validate`]).
    fn with_keys(base: Self::Params, key: &dyn Fn(&str) -> Option<f64>) -> Self::Params;
    /// The keys that describe `p` in the table form (omitted keys take the default).
    fn keys_of(p: &Self::Params) -> Vec<(&'static str, f64)>;
    /// Checks the parameters without a problem (the map checks them again at setup).
    fn validate(p: &Self::Params) -> Result<()>;
    /// Builds Φ for `qp` (allocates: setup).
    fn build(p: &Self::Params, qp: ParametricQp) -> Result<MethodMap>;
    /// The name of `p`: a preset's name, else `family(key=value,…)`.
    fn describe(p: &Self::Params) -> Cow<'static, str> {
        if let Some((name, _)) = Self::PRESETS.iter().find(|(_, q)| q == p) {
            return (*name).into();
        }
        let keys: Vec<String> = Self::keys_of(p)
            .iter()
            .map(|(k, v)| format!("{k}={}", short(*v)))
            .collect();
        format!("{}({})", Self::NAME, keys.join(",")).into()
    }
}

/// Generates, from one list of families (and of maps a family may build besides its
/// own), the enums [`MethodKind`], [`MethodMap`], [`MethodState`] and every dispatch: the
/// [`IterationMap`] and [`Linearise`] impls of [`MethodMap`] and the family lookups behind
/// parsing, naming, validating and building a [`Method`]. A new method is its file and one
/// line of the list.
macro_rules! method_list {
    (
        families { $( $(#[doc = $fdoc:literal])* $(#[cfg($fcfg:meta)])? $fam:ident => $fmap:ty ),* $(,)? }
        maps { $( $(#[doc = $mdoc:literal])* $(#[cfg($mcfg:meta)])? $extra:ident => $emap:ty ),* $(,)? }
    ) => {
        /// The family of an iteration map and its parameters (the method without its
        /// scaling).
        #[derive(Debug, Clone, Copy, PartialEq)]
        #[non_exhaustive]
        pub enum MethodKind {
            $( $(#[doc = $fdoc])* $(#[cfg($fcfg)])? $fam(<$fmap as Family>::Params), )*
        }

        /// Φ built for one problem: one of the concrete maps, chosen by a [`Method`].
        ///
        /// As an [`IterationMap`] it dispatches per call; [`IterationMap::run_steps`] (what
        /// [`run_fixed`] uses) dispatches once and then runs the concrete map's steps in a
        /// loop, so K iterations cost one branch, not K.
        #[derive(Debug, Clone)]
        #[non_exhaustive]
        pub enum MethodMap {
            $( $(#[doc = $fdoc])* $(#[cfg($fcfg)])? $fam($fmap), )*
            $( $(#[doc = $mdoc])* $(#[cfg($mcfg)])? $extra($emap), )*
            /// One of the above on the diagonally scaled problem ([`crate::scaled`]).
            Scaled(Box<Scaled<MethodMap>>),
        }

        /// The state of a [`MethodMap`]: the state of its concrete map.
        #[derive(Debug)]
        #[non_exhaustive]
        pub enum MethodState {
            $( $(#[doc = $fdoc])* $(#[cfg($fcfg)])? $fam(<$fmap as IterationMap>::State), )*
            $( $(#[doc = $mdoc])* $(#[cfg($mcfg)])? $extra(<$emap as IterationMap>::State), )*
            /// Of a scaled map.
            Scaled(Box<ScaledState<MethodState>>),
        }

        impl MethodKind {
            fn family(&self) -> &'static str {
                match self { $( $(#[cfg($fcfg)])? MethodKind::$fam(_) => <$fmap as Family>::NAME, )* }
            }
            fn describe(&self) -> Cow<'static, str> {
                match self { $( $(#[cfg($fcfg)])? MethodKind::$fam(p) => <$fmap as Family>::describe(p), )* }
            }
            fn validate(&self) -> Result<()> {
                match self { $( $(#[cfg($fcfg)])? MethodKind::$fam(p) => <$fmap as Family>::validate(p), )* }
            }
            fn build(&self, qp: ParametricQp) -> Result<MethodMap> {
                match self { $( $(#[cfg($fcfg)])? MethodKind::$fam(p) => <$fmap as Family>::build(p, qp), )* }
            }
            /// The table keys and values (the serialised form of a non-preset method).
            #[cfg(feature = "serde")]
            fn keys(&self) -> Vec<(&'static str, f64)> {
                match self { $( $(#[cfg($fcfg)])? MethodKind::$fam(p) => <$fmap as Family>::keys_of(p), )* }
            }
            /// The family with the parameters of the preset `name` and its table keys.
            fn preset(name: &str) -> Option<(MethodKind, &'static [&'static str], PresetParams)> {
                $( $(#[cfg($fcfg)])? {
                    if let Some((_, p)) = <$fmap as Family>::PRESETS.iter().find(|(n, _)| *n == name) {
                        let with: PresetParams = |kind, key| match kind {
                            MethodKind::$fam(p) => MethodKind::$fam(<$fmap as Family>::with_keys(p, key)),
                            #[allow(unreachable_patterns)]
                            other => other,
                        };
                        return Some((MethodKind::$fam(*p), <$fmap as Family>::KEYS, with));
                    }
                } )*
                None
            }
            /// Every preset name, in list order (for messages).
            fn preset_names() -> Vec<&'static str> {
                let mut names = Vec::new();
                $( $(#[cfg($fcfg)])? names.extend(<$fmap as Family>::PRESETS.iter().map(|(n, _)| *n)); )*
                names
            }
        }

        impl IterationMap for MethodMap {
            type State = MethodState;

            fn name(&self) -> &'static str {
                match self {
                    $( $(#[cfg($fcfg)])? MethodMap::$fam(m) => m.name(), )*
                    $( $(#[cfg($mcfg)])? MethodMap::$extra(m) => m.name(), )*
                    MethodMap::Scaled(m) => m.name(),
                }
            }
            fn problem(&self) -> &ParametricQp {
                match self {
                    $( $(#[cfg($fcfg)])? MethodMap::$fam(m) => m.problem(), )*
                    $( $(#[cfg($mcfg)])? MethodMap::$extra(m) => m.problem(), )*
                    MethodMap::Scaled(m) => m.problem(),
                }
            }
            fn new_state(&self) -> MethodState {
                match self {
                    $( $(#[cfg($fcfg)])? MethodMap::$fam(m) => MethodState::$fam(m.new_state()), )*
                    $( $(#[cfg($mcfg)])? MethodMap::$extra(m) => MethodState::$extra(m.new_state()), )*
                    MethodMap::Scaled(m) => MethodState::Scaled(Box::new(m.new_state())),
                }
            }
            fn load(&self, state: &mut MethodState, theta: &[f64]) {
                match (self, state) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.load(s, theta), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.load(s, theta), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.load(s, theta),
                    _ => foreign_state(),
                }
            }
            fn warm_start(&self, state: &mut MethodState, z0: &[f64], dual: Option<&[f64]>) {
                match (self, state) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.warm_start(s, z0, dual), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.warm_start(s, z0, dual), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.warm_start(s, z0, dual),
                    _ => foreign_state(),
                }
            }
            fn cold_start(&self, state: &mut MethodState) {
                match (self, state) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.cold_start(s), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.cold_start(s), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.cold_start(s),
                    _ => foreign_state(),
                }
            }
            fn step(&self, state: &mut MethodState) {
                match (self, state) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.step(s), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.step(s), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.step(s),
                    _ => foreign_state(),
                }
            }
            fn run_steps(&self, state: &mut MethodState, k: usize) {
                match (self, state) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.run_steps(s, k), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.run_steps(s, k), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.run_steps(s, k),
                    _ => foreign_state(),
                }
            }
            fn iterate<'s>(&self, state: &'s MethodState) -> &'s [f64] {
                match (self, state) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.iterate(s), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.iterate(s), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.iterate(s),
                    _ => foreign_state(),
                }
            }
            fn dual<'s>(&self, state: &'s MethodState) -> Option<&'s [f64]> {
                match (self, state) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.dual(s), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.dual(s), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.dual(s),
                    _ => foreign_state(),
                }
            }
            fn violation(&self, state: &MethodState) -> f64 {
                match (self, state) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.violation(s), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.violation(s), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.violation(s),
                    _ => foreign_state(),
                }
            }
            fn certificate(&self) -> &Certificate {
                match self {
                    $( $(#[cfg($fcfg)])? MethodMap::$fam(m) => m.certificate(), )*
                    $( $(#[cfg($mcfg)])? MethodMap::$extra(m) => m.certificate(), )*
                    MethodMap::Scaled(m) => m.certificate(),
                }
            }
            fn set_kernel(&mut self, kernel: crate::kernel::Kernel) {
                match self {
                    $( $(#[cfg($fcfg)])? MethodMap::$fam(m) => m.set_kernel(kernel), )*
                    $( $(#[cfg($mcfg)])? MethodMap::$extra(m) => m.set_kernel(kernel), )*
                    MethodMap::Scaled(m) => m.set_kernel(kernel),
                }
            }
            fn matvecs_per_step(&self) -> usize {
                match self {
                    $( $(#[cfg($fcfg)])? MethodMap::$fam(m) => m.matvecs_per_step(), )*
                    $( $(#[cfg($mcfg)])? MethodMap::$extra(m) => m.matvecs_per_step(), )*
                    MethodMap::Scaled(m) => m.matvecs_per_step(),
                }
            }
        }

        /// The dispatching map linearises as the concrete method it holds.
        impl Linearise for MethodMap {
            fn lift_dim(&self) -> usize {
                match self {
                    $( $(#[cfg($fcfg)])? MethodMap::$fam(m) => m.lift_dim(), )*
                    $( $(#[cfg($mcfg)])? MethodMap::$extra(m) => m.lift_dim(), )*
                    MethodMap::Scaled(m) => m.lift_dim(),
                }
            }
            fn start_steps(&self) -> usize {
                match self {
                    $( $(#[cfg($fcfg)])? MethodMap::$fam(m) => m.start_steps(), )*
                    $( $(#[cfg($mcfg)])? MethodMap::$extra(m) => m.start_steps(), )*
                    MethodMap::Scaled(m) => m.start_steps(),
                }
            }
            fn start_probe(&self, st: &mut MethodState, z0: &[f64], theta: &[f64], xi: &mut [f64]) {
                match (self, st) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.start_probe(s, z0, theta, xi), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.start_probe(s, z0, theta, xi), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.start_probe(s, z0, theta, xi),
                    _ => foreign_state(),
                }
            }
            fn step_probe(&self, st: &mut MethodState, xi: &[f64], theta: &[f64], out: &mut [f64]) {
                match (self, st) {
                    $( $(#[cfg($fcfg)])? (MethodMap::$fam(m), MethodState::$fam(s)) => m.step_probe(s, xi, theta, out), )*
                    $( $(#[cfg($mcfg)])? (MethodMap::$extra(m), MethodState::$extra(s)) => m.step_probe(s, xi, theta, out), )*
                    (MethodMap::Scaled(m), MethodState::Scaled(s)) => m.step_probe(s, xi, theta, out),
                    _ => foreign_state(),
                }
            }
            fn readout(&self) -> faer::Mat<f64> {
                match self {
                    $( $(#[cfg($fcfg)])? MethodMap::$fam(m) => m.readout(), )*
                    $( $(#[cfg($mcfg)])? MethodMap::$extra(m) => m.readout(), )*
                    MethodMap::Scaled(m) => m.readout(),
                }
            }
        }
    };
}

// ---------------------------------------------------------------------------------------
// The list
// ---------------------------------------------------------------------------------------

method_list! {
    families {
        /// Projected gradient with a step rule ([`crate::pg::ProjectedGradient`]).
        Pg => crate::pg::ProjectedGradient,
        /// V-FISTA, the accelerated projected gradient for strongly convex problems
        /// ([`crate::fista::Fista`]).
        Fista => crate::fista::Fista,
        /// ADMM with penalty ρ and relaxation α ([`crate::admm::Admm`]); on a problem with
        /// general rows it builds [`crate::admm_general::AdmmSplit`].
        Admm => crate::admm::Admm,
        /// The trial method of `docs/architecture.md` ("Adding a method"): test builds only.
        #[cfg(test)]
        Trial => trial_method::Richardson,
    }
    maps {
        /// ADMM split on [I; G]z, for a problem with general rows (void certificate).
        AdmmSplit => crate::admm_general::AdmmSplit,
    }
}

/// Applies a table's keys to a preset's parameters (generated per family).
type PresetParams = fn(MethodKind, &dyn Fn(&str) -> Option<f64>) -> MethodKind;

#[cold]
#[inline(never)]
fn foreign_state() -> ! {
    // A programming error of the caller (a state made by a map of another method), never
    // reachable from data: states come from `MethodMap::new_state` of the same map.
    panic!("MethodMap: the state was created by a map of another method")
}

// ---------------------------------------------------------------------------------------
// Method: a family, its parameters and its scaling
// ---------------------------------------------------------------------------------------

/// How the QP is scaled before the map runs on it ([`crate::scaled`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
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
    pub const FISTA: Method = Method::plain(MethodKind::Fista(()));
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
    /// Every named method, in the order reports, certificates and coverage tables list
    /// them: the four [`Method::PRESETS`], then the four [`Method::JACOBI_PRESETS`]. The one
    /// list of the eight methods; use it instead of repeating them.
    ///
    /// ```
    /// use qp_iter::Method;
    /// let names: Vec<String> = Method::ALL.iter().map(|m| m.to_string()).collect();
    /// assert_eq!(names[..4], ["pg", "fista", "admm", "admm-pr"]);
    /// assert_eq!(names[4], "pg-jacobi");
    /// ```
    pub const ALL: [Method; 8] = [
        Method::PRESETS[0],
        Method::PRESETS[1],
        Method::PRESETS[2],
        Method::PRESETS[3],
        Method::JACOBI_PRESETS[0],
        Method::JACOBI_PRESETS[1],
        Method::JACOBI_PRESETS[2],
        Method::JACOBI_PRESETS[3],
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
        self.kind.validate()
    }

    /// The method's name: `"pg"`, `"fista"`, `"admm"`, `"admm-pr"` for the named methods
    /// (`"pg-jacobi"`, … on the Jacobi-scaled problem), otherwise the family with its
    /// parameters (`"admm(rho=2,alpha=1.5)"`, `"pg(step=0.1,scaling=jacobi)"`).
    pub fn name(&self) -> Cow<'static, str> {
        let base = self.kind.describe();
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
        self.kind.family()
    }

    /// The family names in list order (what plots colour by).
    pub fn families() -> Vec<&'static str> {
        let mut out: Vec<&'static str> = Vec::new();
        for name in MethodKind::preset_names() {
            if let Some((kind, _, _)) = MethodKind::preset(name) {
                if !out.contains(&kind.family()) {
                    out.push(kind.family());
                }
            }
        }
        out
    }

    /// Builds Φ for `qp` (allocates: setup).
    pub fn build(&self, qp: ParametricQp) -> Result<MethodMap> {
        let kind = self.kind;
        match self.scaling {
            Scaling::None => kind.build(qp),
            Scaling::Jacobi => {
                let d = jacobi_scaling(&qp);
                Ok(MethodMap::Scaled(Box::new(Scaled::new(
                    qp,
                    d,
                    move |qp| kind.build(qp),
                )?)))
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

fn unknown(name: &str) -> QpError {
    QpError::UnknownMethod {
        name: name.into(),
        known: MethodKind::preset_names()
            .iter()
            .map(|n| format!("\"{n}\""))
            .collect::<Vec<_>>()
            .join(", "),
    }
}

impl FromStr for Method {
    type Err = QpError;
    /// A preset name (`"pg"`, `"fista"`, `"admm"`, `"admm-pr"`), optionally with `-jacobi`
    /// (the same method on the Jacobi-scaled problem).
    fn from_str(s: &str) -> Result<Self> {
        let (base, scaling) = match s.strip_suffix("-jacobi") {
            Some(b) => (b, Scaling::Jacobi),
            None => (s, Scaling::None),
        };
        match MethodKind::preset(base) {
            Some((kind, _, _)) => Ok(Method { kind, scaling }),
            None => Err(unknown(s)),
        }
    }
}

impl MethodMap {
    /// The map with its dense steps on `kernel` ([`IterationMap::set_kernel`]). With
    /// [`crate::kernel::Kernel::portable`] the steps are the plain-Rust loops that
    /// `mhe-embedded` and the C that `cargo xtask export` writes repeat operation for
    /// operation (no FMA, the same summation order), so their estimates agree bit for bit.
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use qp_iter::BoxSet;
    /// use qp_iter::{Method, ParametricQp};
    /// use qp_iter::kernel::Kernel;
    /// let qp = ParametricQp::new(mat![[2.0, 0.0], [0.0, 1.0]], vec![-2.0, -4.0],
    ///     Mat::zeros(2, 0), BoxSet::symmetric(&[2.0, 2.0]).unwrap()).unwrap();
    /// let map = Method::FISTA.build(qp).unwrap().with_kernel(Kernel::portable());
    /// # let _ = map;
    /// ```
    pub fn with_kernel(mut self, kernel: crate::kernel::Kernel) -> Self {
        self.set_kernel(kernel);
        self
    }

    /// K = `k` steps of Φ and the status of the iterate, dispatched once
    /// (equivalent to [`run_fixed`]).
    pub fn run_fixed(&self, state: &mut MethodState, k: usize) -> RunResult {
        run_fixed(self, state, k)
    }
}

/// A parameter in a method's name: exact (it round-trips, the name identifies the method)
/// and short: `1.5`, and `1e-300` rather than 300 digits.
pub(crate) fn short(x: f64) -> String {
    if x != 0.0 && !(1e-4..1e15).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}
