//! A closed loop built from Rust values, and its certificate in one call.
//!
//! [`LoopModel::builder`] takes the plant ([`LtiSystem`]) and, through typed methods, the
//! sets 𝒳, 𝒰, 𝒴, 𝒲 (boxes; omitted = the whole space), the MHE ([`MheSettings::builder`]:
//! M, η, K, Q, R, P, Φ), the MPC (required: Theorem 1 needs its L_π and γ₁,₃) and w̄.
//! [`certify`] answers "is my K certified?" ([`Certificate::verdict`], the one verdict rule
//! of [`crate::coverage::verdict`]) and gives K_min per method ([`Certificate::k_min`]).
//!
//! The model is validated by the same checks as a scenario file (shapes, finiteness,
//! positive definite weights, η ∈ [0, 1), the size limits of docs/limits.md), all before
//! anything large is allocated, and the certificate is the one of
//! [`crate::certificate::certify_closed_loop`]: a TOML scenario with the same values gives
//! the same certificate, bit for bit. Errors ([`ModelBuildError`]) name the Rust item the
//! value came from (`MheBuilder::eta`, `LoopModelBuilder::input_box`), not a file key.
//!
//! ```
//! use iss_certificate::{CertifyOptions, LoopModel, Method, MheSettings, certify};
//! use lti_model::{LtiSystem, faer::mat};
//! let plant = LtiSystem::new(mat![[0.9]], mat![[1.0]], mat![[1.0]]).unwrap();
//! let model = LoopModel::builder(plant)
//!     .input_box(&[-1.0], &[1.0])
//!     .mhe(MheSettings::builder().horizon(4).eta(0.5).iterations(30))
//!     .mpc_horizon(5)
//!     .build()
//!     .unwrap();
//! let cert = certify(&model, &CertifyOptions::default().with_methods(vec![Method::PG])).unwrap();
//! let k_min = cert.k_min(Method::PG).expect("certified");
//! assert_eq!(cert.verdict(Method::PG, k_min).certified.as_str(), "yes");
//! assert_eq!(cert.verdict(Method::PG, k_min - 1).certified.as_str(), "no");
//!
//! let err = LoopModel::builder(LtiSystem::new(mat![[0.9]], mat![[1.0]], mat![[1.0]]).unwrap())
//!     .mhe(MheSettings::builder().horizon(4).eta(1.2).iterations(30))
//!     .mpc_horizon(5)
//!     .build()
//!     .unwrap_err();
//! assert!(err.to_string().starts_with("MheBuilder::eta: is 1.2, but η must lie in [0, 1)"));
//! ```

use std::sync::Arc;

use closed_loop::scenario::{
    CertificateSettings, ControllerChoice, MAX_PHASE_SECONDS, ResolvedScenario, Scenario,
};
use closed_loop::sim::ClosedLoopError;
use lti_model::spec::names::PLANT_NAMES;
use lti_model::spec::plant::{
    RawBox, RawPlant, RawSets, RawSimulation, validate_noise, validate_plant, validate_sets,
    validate_simulation,
};
use lti_model::spec::{Bounds, MatrixSpec, Table};
use lti_model::{LtiSystem, ModelError};
use mhe_core::MheBuilder;
use mhe_core::builder::MHE_NAMES;
use mpc_core::settings::MPC_NAMES;

pub use mhe_core::MheSettings;
pub use mpc_core::settings::MpcSettings;
pub use qp_iter::Method;

use crate::asymptotic::{AsymptoticGains, AsymptoticVoid, certified_gains};
use crate::certificate::{ClosedLoopCertificate, certify_closed_loop};
use crate::coverage::{Configuration, PairVerdict, Scalar, verdict, verdict_options};

/// Why a [`LoopModel`] (or [`CertifyOptions`]) was refused, or its certificate could not be
/// computed. Every message names the Rust item the value came from and says how to fix it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ModelBuildError {
    /// A value that breaks a requirement of the analysis (a shape, a non-finite entry, a
    /// weight that is not positive definite, η ∉ [0, 1), a size beyond docs/limits.md).
    #[error("{field}: {problem}")]
    Invalid {
        /// The Rust item the value came from (`MheBuilder::eta`, `LtiSystem::a`,
        /// `LoopModelBuilder::input_box`, `CertifyOptions::gamma13`).
        field: String,
        /// What is wrong and how to fix it.
        problem: String,
    },
    /// A part the certificate needs was not given.
    #[error("{part} is missing: {why}")]
    Missing {
        /// The builder method that gives it.
        part: &'static str,
        /// Why the certificate needs it.
        why: &'static str,
    },
    /// The model is valid but an analysis step failed numerically (e.g. the MPC's Riccati
    /// equation has no stabilising solution); the message names the values behind it.
    #[error("the certificate could not be computed: {problem}")]
    Certificate {
        /// What failed, with the Rust items it depends on.
        problem: String,
    },
}

/// The keys of the loop's own sections and the [`LoopModelBuilder`] / [`CertifyOptions`]
/// items that set them, and the whole sections as a Rust caller calls them.
const LOOP_NAMES: [(&str, &str); 14] = [
    ("sets.state", "LoopModelBuilder::state_box"),
    ("sets.input", "LoopModelBuilder::input_box"),
    ("sets.output", "LoopModelBuilder::output_box"),
    ("sets.disturbance", "LoopModelBuilder::disturbance_box"),
    ("simulation.x0", "LoopModelBuilder::initial_state"),
    ("simulation.prior", "LoopModelBuilder::prior"),
    ("certificate.w_bar", "LoopModelBuilder::w_bar"),
    ("certificate.gamma13", "CertifyOptions::gamma13"),
    ("certificate.phase_seconds", "CertifyOptions::phase_seconds"),
    ("[plant]", "the plant (LtiSystem)"),
    ("[sets]", "the sets (LoopModelBuilder::*_box)"),
    ("[mhe]", "the MHE (LoopModelBuilder::mhe)"),
    ("[mpc]", "the MPC (LoopModelBuilder::mpc)"),
    ("[simulation]", "the initial state and prior"),
];

/// Every table a loop model's errors are named by, the loop's own first (its
/// `simulation.prior` is [`LoopModelBuilder::prior`], not the estimator's argument).
const TABLES: [&lti_model::spec::names::Names; 4] =
    [&LOOP_NAMES, &MHE_NAMES, &MPC_NAMES, &PLANT_NAMES];

/// The Rust item of a scenario key (`mhe.eta` → `MheBuilder::eta`; a longer key such as
/// `sets.input.lower` keeps its tail; a whole section by its type).
fn rust_field(key: &str) -> String {
    match key {
        "plant" => "LtiSystem".into(),
        "mhe" => "MheBuilder".into(),
        "mpc" => "MpcBuilder".into(),
        other => lti_model::spec::names::rust_field(other, &TABLES),
    }
}

/// `text` with every scenario key and section replaced by its Rust name.
fn rust_text(text: &str) -> String {
    lti_model::spec::names::rust_text(text, &TABLES)
}

/// A validation failure of the scenario machinery, named by the Rust item.
fn from_model(e: ModelError) -> ModelBuildError {
    match e {
        ModelError::Scenario { key, problem } => ModelBuildError::Invalid {
            field: rust_field(&key),
            problem: rust_text(&problem),
        },
        // Already named by a builder (`MheBuilder::build`, `MpcBuilder::build`).
        ModelError::Invalid { field, problem } => ModelBuildError::Invalid {
            field,
            problem: rust_text(&problem),
        },
        other => ModelBuildError::Certificate {
            problem: rust_text(&other.to_string()),
        },
    }
}

/// A failure of resolving or certifying a valid model, named by the Rust items.
fn from_closed_loop(e: ClosedLoopError) -> ModelBuildError {
    match e {
        ClosedLoopError::Model(m)
        | ClosedLoopError::Mhe(mhe_core::MheError::Model(m))
        | ClosedLoopError::Mpc(mpc_core::MpcError::Model(m)) => from_model(m),
        other => ModelBuildError::Certificate {
            problem: rust_text(&other.to_string()),
        },
    }
}

/// The MPC of a model: the exact MPC with default weights at a horizon, or full settings.
#[derive(Debug)]
enum MpcPart {
    Horizon(usize),
    Settings(Box<mpc_core::MpcBuilder>),
}

/// Builder of a [`LoopModel`] ([`LoopModel::builder`]); nothing is checked until
/// [`LoopModelBuilder::build`].
#[derive(Debug)]
pub struct LoopModelBuilder {
    plant: LtiSystem,
    name: String,
    state: Option<RawBox>,
    input: Option<RawBox>,
    output: Option<RawBox>,
    disturbance: Option<RawBox>,
    x0: Option<Vec<f64>>,
    prior: Option<Vec<f64>>,
    mhe: Option<MheBuilder>,
    mpc: Option<MpcPart>,
    w_bar: Option<f64>,
}

fn raw_box(lower: &[f64], upper: &[f64]) -> Option<RawBox> {
    Some(RawBox {
        lower: Some(Bounds::Each(lower.to_vec())),
        upper: Some(Bounds::Each(upper.to_vec())),
    })
}

impl LoopModelBuilder {
    /// A name for the certificate's outputs (default `"loop-model"`).
    pub fn name(mut self, name: &str) -> Self {
        self.name = name.to_string();
        self
    }
    /// 𝒳 = {lower ≤ x ≤ upper} (n_x bounds each, ±∞ allowed, containing 0; default ℝ^{n_x}).
    pub fn state_box(mut self, lower: &[f64], upper: &[f64]) -> Self {
        self.state = raw_box(lower, upper);
        self
    }
    /// 𝒰 (n_u bounds each, containing 0; default ℝ^{n_u}).
    pub fn input_box(mut self, lower: &[f64], upper: &[f64]) -> Self {
        self.input = raw_box(lower, upper);
        self
    }
    /// 𝒴 of the MHE (n_y bounds each, containing 0; default ℝ^{n_y}).
    pub fn output_box(mut self, lower: &[f64], upper: &[f64]) -> Self {
        self.output = raw_box(lower, upper);
        self
    }
    /// 𝒲 for w = (w¹, w²) (n_w = n_w1 + n_w2 bounds each, containing 0; default ℝ^{n_w}).
    pub fn disturbance_box(mut self, lower: &[f64], upper: &[f64]) -> Self {
        self.disturbance = raw_box(lower, upper);
        self
    }
    /// The true initial state x₀ ∈ 𝒳 (default 0): with the prior it sets the ball
    /// 2·max(‖x₀‖, ‖x̄₀‖, 1) the sampled Lipschitz estimates cover.
    pub fn initial_state(mut self, x0: &[f64]) -> Self {
        self.x0 = Some(x0.to_vec());
        self
    }
    /// The MHE's initial prior x̄₀ (default 0).
    pub fn prior(mut self, prior: &[f64]) -> Self {
        self.prior = Some(prior.to_vec());
        self
    }
    /// The MHE: M, η, K and optionally Q, R, P, Φ, the warm start ([`MheSettings::builder`];
    /// required).
    pub fn mhe(mut self, mhe: MheBuilder) -> Self {
        self.mhe = Some(mhe);
        self
    }
    /// The exact MPC with horizon N, Q_c = I, R_c = I and the DARE terminal cost (the
    /// paper's controller). Use [`LoopModelBuilder::mpc`] for other weights.
    pub fn mpc_horizon(mut self, horizon: usize) -> Self {
        self.mpc = Some(MpcPart::Horizon(horizon));
        self
    }
    /// The MPC (required: Theorem 1 uses its L_π and γ₁,₃) as a builder
    /// (`MpcSettings::builder().horizon(10).r(&r_c)`; validated by
    /// [`LoopModelBuilder::build`], errors naming `MpcBuilder::r`, …). With `iterations`
    /// set it is the K_c-iteration MPC, under the joint certificate ([`crate::joint`]).
    pub fn mpc(mut self, settings: mpc_core::MpcBuilder) -> Self {
        self.mpc = Some(MpcPart::Settings(Box::new(settings)));
        self
    }
    /// w̄ ≥ 0, a bound on ‖w_t‖₂ at every t (default: the largest ‖w‖₂ over a bounded 𝒲):
    /// what the certified gains multiply ([`Certificate::gains`]).
    pub fn w_bar(mut self, w_bar: f64) -> Self {
        self.w_bar = Some(w_bar);
        self
    }

    /// Validates every value (the checks of a scenario file, in the same order, before
    /// anything large is allocated), solves LMI (2) for P when the MHE gives none, and
    /// builds the MPC. Errors name the Rust item ([`ModelBuildError`]).
    pub fn build(self) -> Result<LoopModel, ModelBuildError> {
        let to_rows =
            |m: faer::MatRef<'_, f64>| Some(MatrixSpec::Rows(lti_model::matrix::to_rows(m)));
        let p = &self.plant;
        let raw_plant = RawPlant {
            a: to_rows(p.a()),
            b: to_rows(p.b()),
            c: to_rows(p.c()),
            e: to_rows(p.e()),
            f: to_rows(p.f()),
            sample_time: None,
        };
        let plant = validate_plant(Some(&raw_plant)).map_err(from_model)?;
        let raw_sets = RawSets {
            state: self.state.map(Table),
            input: self.input.map(Table),
            output: self.output.map(Table),
            disturbance: self.disturbance.map(Table),
        };
        let (sets, disturbance_given) =
            validate_sets(Some(&raw_sets), &plant).map_err(from_model)?;
        // The disturbance a simulation of the model draws (uniform on a bounded 𝒲, else
        // none): the certificate does not use it, so an unbounded 𝒲 is not refused here.
        let bounded = (sets.disturbance.lower().iter())
            .chain(sets.disturbance.upper())
            .all(|b| b.is_finite());
        let noise = validate_noise(None, &sets, disturbance_given && bounded, plant.nw())
            .map_err(from_model)?;
        let raw_sim = RawSimulation {
            x0: self.x0,
            prior: self.prior,
            steps: None,
        };
        let simulation = validate_simulation(Some(&raw_sim), &plant, &sets).map_err(from_model)?;
        let mhe = self.mhe.ok_or(ModelBuildError::Missing {
            part: "LoopModelBuilder::mhe",
            why: "the certificate is of the MHE's iterations; give \
                  .mhe(MheSettings::builder().horizon(10).eta(0.8).iterations(50))",
        })?;
        // The builder's own checks (no sets), then the scenario's (with them), exactly as a
        // file's [mhe] is validated.
        let mhe = mhe.build(&plant).map_err(|e| match e {
            mhe_core::MheError::Model(m) => from_model(m),
            other => ModelBuildError::Certificate {
                problem: rust_text(&other.to_string()),
            },
        })?;
        let mhe = MheSettings::from_raw_with_sets(&mhe.to_raw(), &plant, Some(&sets))
            .map_err(from_model)?;
        let raw_mpc = match self.mpc.ok_or(ModelBuildError::Missing {
            part: "LoopModelBuilder::mpc",
            why: "Theorem 1 bounds the loop with the MPC's L_π and γ₁,₃; give .mpc_horizon(10) \
                  for the exact MPC or .mpc(settings)",
        })? {
            MpcPart::Horizon(n) => mpc_core::settings::RawMpc {
                horizon: Some(n),
                ..Default::default()
            },
            MpcPart::Settings(s) => s.into_raw(),
        };
        let mpc = MpcSettings::from_raw(&raw_mpc, &plant).map_err(from_model)?;
        if let Some(w) = self.w_bar
            && !(w.is_finite() && w >= 0.0)
        {
            return Err(ModelBuildError::Invalid {
                field: "LoopModelBuilder::w_bar".into(),
                problem: format!("is {w}; w̄ bounds ‖w_t‖₂ and must be a finite number ≥ 0"),
            });
        }
        let controller = match mpc.iterations() {
            Some(iterations) => ControllerChoice::SuboptimalMpc {
                iterations,
                method: mpc.method(),
            },
            None => ControllerChoice::ExactMpc,
        };
        let scenario = Scenario {
            name: self.name,
            description: None,
            plant,
            sample_time: None,
            sets,
            noise,
            simulation,
            mhe: Some(mhe),
            mpc: Some(mpc),
            certificate: CertificateSettings {
                w_bar: self.w_bar,
                ..CertificateSettings::default()
            },
            source: None,
        };
        let resolved = scenario.resolve().map_err(from_closed_loop)?;
        Ok(LoopModel {
            resolved: Arc::new(resolved),
            controller,
        })
    }
}

/// A validated closed loop (plant, sets, MHE, MPC, w̄) with P of LMI (2) and the MPC
/// resolved once; [`certify`] computes its certificate.
#[derive(Debug, Clone)]
pub struct LoopModel {
    resolved: Arc<ResolvedScenario>,
    controller: ControllerChoice,
}

impl LoopModel {
    /// A builder on the plant x⁺ = Ax + Bu + Ew¹, y = Cx + Fw² ([`LoopModelBuilder`]).
    pub fn builder(plant: LtiSystem) -> LoopModelBuilder {
        LoopModelBuilder {
            plant,
            name: "loop-model".into(),
            state: None,
            input: None,
            output: None,
            disturbance: None,
            x0: None,
            prior: None,
            mhe: None,
            mpc: None,
            w_bar: None,
        }
    }

    /// The model as a scenario (write it with [`Scenario::to_toml_string`] to run
    /// `cargo xtask certify|reproduce` on it).
    pub fn scenario(&self) -> &Scenario {
        self.resolved.scenario()
    }

    /// The resolved loop (P, ℙ_t, the condensed MPC) the certificate is computed on.
    pub fn resolved(&self) -> &ResolvedScenario {
        &self.resolved
    }

    /// K, the MHE's iterations per step.
    pub fn iterations(&self) -> usize {
        self.scenario()
            .mhe
            .as_ref()
            .map_or(0, |m| m.iterations().get())
    }

    /// w̄: the given bound, else the largest ‖w‖₂ over 𝒲 (`None` when 𝒲 is unbounded).
    pub fn w_bar(&self) -> Option<f64> {
        let sc = self.scenario();
        sc.certificate.w_bar.or_else(|| {
            let d = &sc.sets.disturbance;
            let sq: f64 = d
                .lower()
                .iter()
                .zip(d.upper())
                .map(|(l, u)| l.abs().max(u.abs()).powi(2))
                .sum();
            sq.is_finite().then(|| sq.sqrt())
        })
    }
}

/// Settings of [`certify`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct CertifyOptions {
    /// The MHE methods Φ to certify (default: the four named methods and their
    /// Jacobi-scaled forms, as `cargo xtask certify`).
    pub methods: Vec<Method>,
    /// γ₁,₃ of Assumption 4 given by the user ("not verified"; refuted when a sampled lower
    /// estimate exceeds it). `None`: certified by the analysis.
    pub gamma13: Option<f64>,
    /// Estimated single-core seconds an optional analysis phase may take before it is
    /// skipped and its verdict reported "not computed" ([`crate::budget`]; `None`: the
    /// default [`crate::budget::DEFAULT_PHASE_SECONDS`]).
    pub phase_seconds: Option<f64>,
    /// Seed of every sampled estimate (a scenario file's `noise.seed`; default 0).
    pub seed: u64,
}

impl Default for CertifyOptions {
    fn default() -> Self {
        Self {
            methods: Method::ALL.to_vec(),
            gamma13: None,
            phase_seconds: None,
            seed: 0,
        }
    }
}

impl CertifyOptions {
    /// These options with `methods` certified.
    #[must_use]
    pub fn with_methods(mut self, methods: Vec<Method>) -> Self {
        self.methods = methods;
        self
    }
    /// These options with a user-supplied γ₁,₃.
    #[must_use]
    pub fn with_gamma13(mut self, gamma13: f64) -> Self {
        self.gamma13 = Some(gamma13);
        self
    }
    /// These options with the seed of the sampled estimates.
    #[must_use]
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }
    /// These options with the analysis budget `seconds` per optional phase.
    #[must_use]
    pub fn with_phase_seconds(mut self, seconds: f64) -> Self {
        self.phase_seconds = Some(seconds);
        self
    }

    fn check(&self) -> Result<(), ModelBuildError> {
        let invalid = |field: &str, problem: String| ModelBuildError::Invalid {
            field: field.into(),
            problem,
        };
        if self.methods.is_empty() {
            return Err(invalid(
                "CertifyOptions::methods",
                "is empty; name at least one method, e.g. vec![Method::PG]".into(),
            ));
        }
        if let Some(g) = self.gamma13
            && !(g.is_finite() && g > 0.0)
        {
            return Err(invalid(
                "CertifyOptions::gamma13",
                format!("is {g}; γ₁,₃ must be a finite number > 0 (or None to compute it)"),
            ));
        }
        if let Some(s) = self.phase_seconds
            && !(s.is_finite() && s > 0.0 && s <= MAX_PHASE_SECONDS)
        {
            return Err(invalid(
                "CertifyOptions::phase_seconds",
                format!(
                    "is {s}; the analysis budget must be in (0, {MAX_PHASE_SECONDS:e}] seconds \
                     (None: the default)"
                ),
            ));
        }
        Ok(())
    }
}

/// The certificate of a [`LoopModel`]: Theorem 1 per method, and the verdict at any K.
#[derive(Debug, Clone)]
pub struct Certificate {
    model: LoopModel,
    closed_loop: ClosedLoopCertificate,
}

impl Certificate {
    /// Is `k` iterations of `method` per step certified for this loop? The one verdict rule
    /// ([`crate::coverage::verdict`]): `yes`, `no` (too few iterations), `void` (a premise
    /// fails: the reason says which, or `method` was not among [`CertifyOptions::methods`])
    /// or `not_computed` (the analysis budget stopped a phase).
    pub fn verdict(&self, method: Method, k: usize) -> PairVerdict {
        let config = Configuration {
            method,
            k_e: k,
            controller: self.model.controller,
            scalar: Scalar::F64,
        };
        verdict(self.model.resolved(), &self.closed_loop, &config)
    }

    /// The smallest certified K of `method` under Theorem 1 (`None`: void, not computed
    /// within the budget, or not certified; [`Certificate::verdict`] says which).
    pub fn k_min(&self, method: Method) -> Option<usize> {
        self.closed_loop.solver(method).and_then(|s| s.k_min)
    }

    /// K_glob of `method` under the global loop certificate (Theorem L3, docs/theory.md §4):
    /// every K ≥ K_glob is certified by it (`None`: it certifies no K for this loop, does not
    /// model its controller, or was not computed within the budget). The verdict is `yes`
    /// from the smaller of [`Certificate::k_min`] and this on.
    pub fn k_glob(&self, method: Method) -> Option<usize> {
        crate::coverage::global_of(&self.closed_loop, method, self.model.controller)
            .and_then(|g| g.exact.k_glob())
    }

    /// K_chain of `method` under the iteration chain (Theorem L3b, L3c for FISTA,
    /// docs/theory.md §4b, §4c; pg, fista and their Jacobi variants, f64): the smallest K the chain checked and certified. The chain covers only
    /// the K it checked ([`Certificate::verdict`] says `not_computed` at a K it did not check),
    /// so this is a floor of the verdict, not a threshold (`None`: not PG/FISTA or a Jacobi variant, nothing
    /// certified, or not computed within the budget).
    pub fn k_chain(&self, method: Method) -> Option<usize> {
        crate::coverage::global_of(&self.closed_loop, method, self.model.controller)
            .and_then(|g| g.k_chain())
    }

    /// K_min of every certified method, in the order of [`CertifyOptions::methods`].
    pub fn k_mins(&self) -> impl Iterator<Item = (Method, Option<usize>)> + '_ {
        self.closed_loop.solvers.iter().map(|s| (s.solver, s.k_min))
    }

    /// "Is my K certified?" for every certified method: K_min and the verdict at `k`
    /// ([`Certificate::verdict`]), in the order of [`CertifyOptions::methods`].
    pub fn verdicts(
        &self,
        k: usize,
    ) -> impl Iterator<Item = (Method, Option<usize>, PairVerdict)> + '_ {
        self.k_mins()
            .map(move |(method, k_min)| (method, k_min, self.verdict(method, k)))
    }

    /// What Theorem 1 guarantees at K for `method`: lim sup‖e_t‖ ≤ g_e·w̄,
    /// lim sup‖x_t‖ ≤ g_x·w̄ (w̄: [`LoopModel::w_bar`]).
    pub fn gains(&self, method: Method, k: usize) -> Result<AsymptoticGains, AsymptoticVoid> {
        match self.closed_loop.solver(method) {
            Some(s) => certified_gains(&self.closed_loop, s, k),
            None => Err(AsymptoticVoid::NotCertified { method }),
        }
    }

    /// The model certified.
    pub fn model(&self) -> &LoopModel {
        &self.model
    }

    /// Every constant, premise and margin ([`ClosedLoopCertificate`]).
    pub fn closed_loop(&self) -> &ClosedLoopCertificate {
        &self.closed_loop
    }
}

/// Theorem 1's certificate of `model` for `options.methods`, with the options every
/// command uses for its verdicts ([`crate::coverage::verdict_options`]): the same
/// certificate as [`certify_closed_loop`] on the scenario file with the same values.
///
/// Errors: a bad option, or a numerical failure of an analysis step; a violated premise is
/// not an error (the verdict is `void`, with the reason).
pub fn certify(
    model: &LoopModel,
    options: &CertifyOptions,
) -> Result<Certificate, ModelBuildError> {
    options.check()?;
    let mut opts = verdict_options(model.scenario(), options.methods.clone(), options.gamma13);
    if let Some(s) = options.phase_seconds {
        opts.phase_seconds = s;
    }
    opts.seed = options.seed;
    let closed_loop = certify_closed_loop(model.resolved(), &opts).map_err(from_closed_loop)?;
    Ok(Certificate {
        model: model.clone(),
        closed_loop,
    })
}
