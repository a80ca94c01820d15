//! A scenario resolved once: P of LMI (2) (computed, or the file's P verified), the MHE
//! configuration built on it, the MHE sets and the condensed MPC. The certificate, the
//! simulation, `reproduce` and the sweep all take a [`ResolvedScenario`], so K, M and P
//! are read and computed once per scenario, and a parameter flows one way:
//! file → [`super::Scenario`] → [`ResolvedScenario`] → kernels.

use lti_model::ModelError;
use lti_model::ioss::{self, IossCertificate};
use lti_model::spec::format::key_error;
use std::sync::{Arc, OnceLock};

use mhe_core::{MheConfig, MheError, MheProblem, MheSets};
use mpc_core::CondensedMpc;

use super::Scenario;
use crate::sim::{ClosedLoopError, Result};

/// A validated scenario with everything derived from it that every consumer shares.
#[derive(Debug, Clone)]
pub struct ResolvedScenario {
    scenario: Scenario,
    /// Assumption 2: the δ-IOSS certificate of P, or why there is none. `None` without
    /// an `[mhe]` section.
    ioss: Option<std::result::Result<IossCertificate, ModelError>>,
    /// The estimator configuration (P included; K as in the file). `None` without `[mhe]`
    /// or without a P (LMI (2) infeasible).
    mhe: Option<MheConfig>,
    mhe_sets: MheSets,
    /// ℙ_t for m = 0..M with the resolved P, built once on first use and shared by every
    /// estimator and the certificate.
    mhe_problem: OnceLock<std::result::Result<Arc<MheProblem>, ClosedLoopError>>,
    /// The condensed MPC of `[mpc]` (`None` without that section).
    mpc: Option<CondensedMpc>,
}

impl ResolvedScenario {
    /// Resolves `scenario`: solves LMI (2) for P when `[mhe]` gives none (or verifies the
    /// given P), and builds the condensed MPC when `[mpc]` is present.
    ///
    /// Errors only for bad input (a weight, a set or a dimension the components refuse); an
    /// infeasible LMI is recorded ([`ResolvedScenario::ioss`]) and reported when an MHE is
    /// needed ([`ResolvedScenario::mhe_config`]).
    pub fn new(scenario: Scenario) -> Result<Self> {
        let sys = &scenario.plant;
        let (ioss, mhe) = match &scenario.mhe {
            None => (None, None),
            Some(s) => {
                let (q, r) = (s.q().as_ref(), s.r().as_ref());
                let outcome = match &s.p() {
                    Some(p) => ioss::verify(sys, s.eta(), q, r, p.as_ref()),
                    None => ioss::certify(sys, s.eta(), q, r),
                };
                let user_p = s.p().is_some();
                let outcome = match outcome {
                    Ok(c) => Ok(c),
                    Err(
                        e @ (ModelError::LmiInfeasible { .. }
                        | ModelError::Numerical { .. }
                        | ModelError::NotPositiveDefinite { .. }),
                    ) => Err(name_lmi_keys(e, user_p)),
                    Err(e) => return Err(MheError::from(name_lmi_keys(e, user_p)).into()),
                };
                // The file's P is used as given (verified or not: the certificate reports
                // it); otherwise the LMI's P, when there is one.
                let p = match (s.p(), &outcome) {
                    (Some(p), _) => Some(p.clone()),
                    (None, Ok(c)) => Some(c.p.clone()),
                    (None, Err(_)) => None,
                };
                let mhe = p.map(|p| {
                    MheConfig::new(
                        s.horizon(),
                        s.eta(),
                        p,
                        s.q().clone(),
                        s.r().clone(),
                        s.iterations(),
                    )
                    .with_warm_start(s.warm_start())
                });
                (Some(outcome), mhe)
            }
        };
        let mpc = match &scenario.mpc {
            Some(s) => Some(s.build(sys, &scenario.sets)?),
            None => None,
        };
        let mhe_sets = MheSets::from_scenario(&scenario.sets);
        Ok(Self {
            scenario,
            ioss,
            mhe,
            mhe_sets,
            mhe_problem: OnceLock::new(),
            mpc,
        })
    }

    /// The scenario as parsed.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// Assumption 2's outcome: the certificate of P (computed from LMI (2), or the file's P
    /// verified) or the reason there is none; `None` without `[mhe]`.
    pub fn ioss(&self) -> Option<&std::result::Result<IossCertificate, ModelError>> {
        self.ioss.as_ref()
    }

    /// The MHE configuration with P (K as in the file, exact solve off).
    ///
    /// Errors: no `[mhe]` section; no P (LMI (2) infeasible: the reason).
    pub fn mhe_config(&self) -> Result<&MheConfig> {
        match (&self.mhe, &self.ioss) {
            (Some(cfg), _) => Ok(cfg),
            (None, Some(Err(e))) => Err(MheError::from(e.clone()).into()),
            (None, _) => Err(ClosedLoopError::MissingSection { section: "mhe" }),
        }
    }

    /// ℙ_t for every window length m = 0..M with the resolved P (H_c, F_c, L_Φ, …): built
    /// once, on first use, and shared by every estimator ([`ResolvedScenario::estimator`])
    /// and the certificate.
    ///
    /// Errors: as [`ResolvedScenario::mhe_config`], and a window that is not strongly
    /// convex (named by its scenario key).
    pub fn mhe_problem(&self) -> Result<&Arc<MheProblem>> {
        let built = self.mhe_problem.get_or_init(|| {
            let cfg = self.mhe_config()?;
            let sc = &self.scenario;
            MheProblem::new(&sc.plant, cfg.horizon, &cfg.weights(), &self.mhe_sets)
                .map(Arc::new)
                .map_err(|e| match &sc.mhe {
                    // Name the scenario key behind a window that is not strongly convex.
                    Some(settings) => settings.explain(&sc.plant, e).into(),
                    None => e.into(),
                })
        });
        built.as_ref().map_err(Clone::clone)
    }

    /// 𝒳, 𝒴, 𝒲 as the MHE uses them.
    pub fn mhe_sets(&self) -> &MheSets {
        &self.mhe_sets
    }

    /// The condensed MPC. Errors: no `[mpc]` section.
    pub fn mpc(&self) -> Result<&CondensedMpc> {
        self.mpc
            .as_ref()
            .ok_or(ClosedLoopError::MissingSection { section: "mpc" })
    }

    /// Sets `noise.scale` (what a sweep varies per point). The only setting that may change
    /// after resolution: nothing resolved depends on the disturbance's size.
    pub fn set_noise_scale(&mut self, scale: f64) {
        self.scenario.noise.scale = scale;
    }

    /// The radius of the ball the sampled Lipschitz estimates cover, 2·max(‖x₀‖, ‖prior‖, 1):
    /// where the closed loop starts.
    pub fn sampling_radius(&self) -> f64 {
        self.scenario.sampling_radius()
    }
}

/// A failure of LMI (2) other than infeasibility (whose causes name their keys) comes from
/// the numbers of the plant and the weights: name the keys they come from, so that no
/// internal symbol (`LMI matrix`, `R`) is the only name in the message.
fn name_lmi_keys(e: ModelError, user_p: bool) -> ModelError {
    match e {
        ModelError::LmiInfeasible { .. } | ModelError::Scenario { .. } => e,
        ModelError::NotPositiveDefinite { .. } if user_p => key_error(
            "mhe.p",
            format!("{e}; LMI (2) needs the given P positive definite relative to its size"),
        ),
        other => key_error(
            "mhe",
            format!(
                "LMI (2) of Assumption 2 could not be solved for the data of `plant.a`, \
                 `plant.c`, `plant.e`, `plant.f`, `mhe.q`, `mhe.r` at `mhe.eta`: {other}; rescale \
                 the model towards entries of similar size, or give P (`mhe.p`)"
            ),
        ),
    }
}

impl super::Scenario {
    /// 2·max(‖x₀‖, ‖prior‖, 1): the ball the sampled Lipschitz estimates (L_Φ, L_π) cover,
    /// where the closed loop starts.
    pub fn sampling_radius(&self) -> f64 {
        let norm = lti_model::vecmath::norm2;
        let sim = &self.simulation;
        2.0 * norm(&sim.x0).max(norm(&sim.prior)).max(1.0)
    }

    /// [`ResolvedScenario::new`] on this scenario.
    pub fn resolve(self) -> Result<ResolvedScenario> {
        ResolvedScenario::new(self)
    }
}
