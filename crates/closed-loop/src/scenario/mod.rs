//! TOML scenario files: the composition of plant, sets, noise and simulation
//! (`lti_model::spec`), the MHE settings (`mhe_core::settings`) and the MPC settings
//! (`mpc_core::settings`); each layer parses and validates its own sections, this module
//! composes them. [`Scenario::resolve`] turns a scenario into a [`ResolvedScenario`] once
//! (P of LMI (2), the MHE configuration, the MPC), shared by the certificate, the
//! simulation, `reproduce` and the sweep.
//!
//! Parsing runs in two stages. First the text is deserialised into `Raw*`
//! mirror structs (every table `deny_unknown_fields`, every key optional) through
//! `serde_path_to_error`, so a type error names the dotted key it happened at. Then
//! [`Scenario`] is built from the raw structs, checking every shape against the plant and
//! every weight for symmetry and positive definiteness. Every failure is a
//! [`lti_model::ModelError::Scenario`] whose `key` is the dotted TOML key (`"mhe.q"`), `"<toml>"`
//! for a syntax error or `"<file>"` for an I/O error, and whose `problem` says what is
//! wrong and how to fix it. The full format is documented in `docs/scenario-format.md`.
//!
//! ```
//! use closed_loop::scenario::Scenario;
//! let s = Scenario::from_toml_str(r#"
//!     name = "double-integrator"
//!     [plant]
//!     a = [[1.0, 0.1], [0.0, 1.0]]
//!     b = [[0.005], [0.1]]
//!     c = [[1.0, 0.0]]
//!     [sets]
//!     input = { lower = [-1], upper = [1] }
//! "#).unwrap();
//! assert_eq!((s.plant.nx(), s.plant.nu(), s.plant.ny()), (2, 1, 1));
//! assert!(s.sets.state.is_whole());
//! assert_eq!(s.sets.input.upper(), &[1.0]);
//!
//! let err = Scenario::from_toml_str("name = \"x\"\n[plant]\na = [[1.0]]\nc = [[1.0]]\nd = 1")
//!     .unwrap_err();
//! match err {
//!     lti_model::ModelError::Scenario { key, .. } => assert_eq!(key, "plant.d"),
//!     other => panic!("{other}"),
//! }
//! ```

mod build;
mod noise;
mod resolve;

use std::path::Path;

use lti_model::spec::format::{self, Table, key_error};
use lti_model::spec::plant::{
    RawNoise, RawPlant, RawSets, RawSimulation, raw_sections, validate_noise, validate_plant,
    validate_sample_time, validate_sets, validate_simulation,
};
use lti_model::spec::{NoiseSpec, ScenarioSets, SimulationSpec};
use lti_model::{LtiSystem, Result};
use mhe_core::settings::{MheSettings, RawMhe};
use mpc_core::settings::{MpcSettings, RawMpc};
use serde::{Deserialize, Serialize};

pub use build::{
    ControllerChoice, LoopOptions, ScenarioController, ScenarioEstimator, ScenarioLoop,
    scenario_disturbance,
};
pub use noise::draws_outside;
pub use resolve::ResolvedScenario;

// ---------------------------------------------------------------------------------------
// Typed, validated scenario
// ---------------------------------------------------------------------------------------

/// A validated scenario: everything needed to set up a run of Alg. 1.
///
/// Built by [`Scenario::from_toml_str`] / [`Scenario::from_file`]; all dimensions are
/// consistent with [`Scenario::plant`].
#[derive(Debug, Clone)]
pub struct Scenario {
    /// Scenario name (`name`), used to label outputs.
    pub name: String,
    /// Free-text description (`description`).
    pub description: Option<String>,
    /// The plant of eq. (1) (`[plant]`).
    pub plant: LtiSystem,
    /// The sample period T_s in seconds (`plant.sample_time`), if the scenario gives one:
    /// the time budget of one estimator step on a target (`mhe_budget`).
    pub sample_time: Option<f64>,
    /// The constraint sets 𝒳, 𝒰, 𝒴, 𝒲 (`[sets]`).
    pub sets: ScenarioSets,
    /// How the true disturbance w_t is drawn (`[noise]`).
    pub noise: NoiseSpec,
    /// Initial state, prior and length of a run (`[simulation]`).
    pub simulation: SimulationSpec,
    /// MHE settings (`[mhe]`), if the scenario has them.
    pub mhe: Option<MheSettings>,
    /// MPC settings (`[mpc]`), if the scenario has them.
    pub mpc: Option<MpcSettings>,
    /// Certificate settings (`[certificate]`).
    pub certificate: CertificateSettings,
    /// The verbatim text this scenario was parsed from (`None` if it was built in code), so
    /// that a run can record exactly what it used, comments included.
    pub source: Option<String>,
}

impl Scenario {
    /// Parses and validates a scenario from TOML text.
    pub fn from_toml_str(text: &str) -> Result<Self> {
        let raw: RawScenario = format::parse(text)?;
        let mut scenario = validate(raw)?;
        scenario.source = Some(text.to_string());
        Ok(scenario)
    }

    /// Reads, parses and validates a scenario file. I/O errors have key `"<file>"`.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = format::read_limited(path)?;
        Self::from_toml_str(&text)
    }

    /// Canonical TOML of the validated scenario: every default made explicit, matrices as
    /// rows, comments dropped. Parsing it gives back an equal scenario.
    pub fn to_toml_string(&self) -> Result<String> {
        let raw = RawScenario::from_typed(self);
        toml::to_string(&raw)
            .map_err(|e| key_error("<toml>", format!("cannot serialise the scenario: {e}")))
    }
}

/// Default `certificate.phase_seconds`: the estimated seconds of one core an optional
/// analysis phase of the certificate may take before it is skipped.
pub const DEFAULT_PHASE_SECONDS: f64 = 10.0;

/// Largest accepted `certificate.phase_seconds` (about 11 days).
pub const MAX_PHASE_SECONDS: f64 = 1e6;

/// The `[certificate]` section: inputs of Theorem 1's certificate the user may supply.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CertificateSettings {
    /// γ₁,₃ of Assumption 4 given by the user (`certificate.gamma13`), reported as
    /// "user-supplied, not verified" and refuted when the sampled lower estimate exceeds it;
    /// `None`: computed.
    pub gamma13: Option<f64>,
    /// Regional certificate (`iss_certificate::regional`): the true x₀ lies within this
    /// Euclidean distance of `simulation.x0` (`certificate.x0_radius`; `None`: 0).
    pub x0_radius: Option<f64>,
    /// Regional certificate: ‖prior − x₀‖ ≤ this (`certificate.prior_error`; `None`: the
    /// scenario's own ‖simulation.prior − simulation.x0‖).
    pub prior_error: Option<f64>,
    /// Regional certificate: ‖w_t‖₂ ≤ this at every t (`certificate.w_bar`; `None`: the
    /// largest ‖w‖₂ of the noise the scenario draws, `sets.disturbance` × `noise.scale`).
    pub w_bar: Option<f64>,
    /// The analysis budget (`certificate.phase_seconds`: estimated single-core seconds one
    /// optional phase may take — the γ₁,₃ free-set enumeration, ρ_lin; `iss_certificate::budget`);
    /// `None`: the default
    /// [`DEFAULT_PHASE_SECONDS`].
    pub phase_seconds: Option<f64>,
}

impl CertificateSettings {
    /// The budget in force: `certificate.phase_seconds` or the default.
    pub fn phase_seconds(&self) -> f64 {
        self.phase_seconds.unwrap_or(DEFAULT_PHASE_SECONDS)
    }
}

/// Serde mirror of `[certificate]`.
#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawCertificate {
    #[serde(skip_serializing_if = "Option::is_none")]
    gamma13: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    x0_radius: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    prior_error: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    w_bar: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    phase_seconds: Option<f64>,
}

impl CertificateSettings {
    fn from_raw(raw: Option<&RawCertificate>) -> Result<Self> {
        let gamma13 = raw.and_then(|r| r.gamma13);
        if let Some(g) = gamma13 {
            if !(g.is_finite() && g > 0.0) {
                return Err(key_error(
                    "certificate.gamma13",
                    format!("is {g}; γ₁,₃ must be a finite number > 0 (or omit it to compute it)"),
                ));
            }
            format::check_scale("certificate.gamma13", g)?;
        }
        let phase_seconds = raw.and_then(|r| r.phase_seconds);
        if let Some(w) = phase_seconds {
            let max = MAX_PHASE_SECONDS;
            if !(w.is_finite() && w > 0.0 && w <= max) {
                return Err(key_error(
                    "certificate.phase_seconds",
                    format!(
                        "is {w}; the analysis budget (estimated seconds per optional phase) \
                         must be in (0, {max:e}] (default {}; omit it for the default)",
                        DEFAULT_PHASE_SECONDS
                    ),
                ));
            }
        }
        let radius = |key: &str, v: Option<f64>| -> Result<Option<f64>> {
            match v {
                Some(r) if !(r.is_finite() && r >= 0.0) => Err(key_error(
                    key,
                    format!("is {r}; it must be a finite number ≥ 0 (or omit it)"),
                )),
                other => Ok(other),
            }
        };
        Ok(Self {
            gamma13,
            phase_seconds,
            x0_radius: radius("certificate.x0_radius", raw.and_then(|r| r.x0_radius))?,
            prior_error: radius("certificate.prior_error", raw.and_then(|r| r.prior_error))?,
            w_bar: radius("certificate.w_bar", raw.and_then(|r| r.w_bar))?,
        })
    }
}

// ---------------------------------------------------------------------------------------
// Raw (serde) mirror of the file
// ---------------------------------------------------------------------------------------

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    #[serde(skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    description: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    plant: Option<Table<RawPlant>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    sets: Option<Table<RawSets>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    noise: Option<Table<RawNoise>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    simulation: Option<Table<RawSimulation>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mhe: Option<Table<RawMhe>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mpc: Option<Table<RawMpc>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    certificate: Option<Table<RawCertificate>>,
}

fn validate(raw: RawScenario) -> Result<Scenario> {
    let name = raw.name.clone().ok_or_else(|| {
        key_error(
            "name",
            "is required but missing; add a top-level `name = \"my-scenario\"`",
        )
    })?;
    if name.trim().is_empty() {
        return Err(key_error(
            "name",
            "is empty; give the scenario a name, e.g. `name = \"case-study\"`",
        ));
    }
    let plant = validate_plant(raw.plant.as_deref())?;
    let sample_time = validate_sample_time(raw.plant.as_deref())?;
    let (sets, disturbance_given) = validate_sets(raw.sets.as_deref(), &plant)?;
    let noise = validate_noise(raw.noise.as_deref(), &sets, disturbance_given, plant.nw())?;
    let simulation = validate_simulation(raw.simulation.as_deref(), &plant, &sets)?;

    let mhe = raw
        .mhe
        .as_ref()
        .map(|m| MheSettings::from_raw_with_sets(m, &plant, Some(&sets)))
        .transpose()?;
    let mpc = raw
        .mpc
        .as_ref()
        .map(|m| MpcSettings::from_raw(m, &plant))
        .transpose()?;

    Ok(Scenario {
        name,
        description: raw.description,
        plant,
        sample_time,
        sets,
        noise,
        simulation,
        mhe,
        mpc,
        certificate: CertificateSettings::from_raw(raw.certificate.as_deref())?,
        source: None,
    })
}

impl RawScenario {
    fn from_typed(s: &Scenario) -> Self {
        let (mut plant, sets, noise, simulation) =
            raw_sections(&s.plant, &s.sets, &s.noise, &s.simulation);
        plant.sample_time = s.sample_time;
        RawScenario {
            name: Some(s.name.clone()),
            description: s.description.clone(),
            plant: Some(Table(plant)),
            sets: Some(Table(sets)),
            noise: Some(Table(noise)),
            simulation: Some(Table(simulation)),
            mhe: s.mhe.as_ref().map(|m| Table(m.to_raw())),
            mpc: s.mpc.as_ref().map(|m| Table(m.to_raw())),
            certificate: {
                let c = &s.certificate;
                (c.gamma13.is_some()
                    || c.x0_radius.is_some()
                    || c.prior_error.is_some()
                    || c.w_bar.is_some()
                    || c.phase_seconds.is_some())
                .then_some(Table(RawCertificate {
                    gamma13: c.gamma13,
                    x0_radius: c.x0_radius,
                    prior_error: c.prior_error,
                    w_bar: c.w_bar,
                    phase_seconds: c.phase_seconds,
                }))
            },
        }
    }
}
