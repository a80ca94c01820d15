//! A ready closed loop from a resolved scenario: the sub-optimal MHE with the scenario's
//! (or the run's) method Φ and K, the controller of the run, the scenario's disturbance.
//!
//! The method list is `qp_iter::Method`; the estimator is one type for every method
//! ([`ScenarioEstimator`] = `MheEstimator<MethodMap>`, dispatching once per K-iteration
//! run), so adding a method touches nothing here.

use lti_model::ModelError;
use lti_model::disturbance::{Disturbance, Gaussian, TruncatedNormal, UniformBox, Zero};
use lti_model::spec::NoiseKind;
use mhe_core::{MheEstimator, MheRecord};
use mpc_core::{Controller, ExactMpc, MpcError, SaturatedLqr, SuboptimalMpc};
use qp_iter::{Method, MethodMap};

use super::{ResolvedScenario, Scenario};
use crate::sim::{ClosedLoop, ClosedLoopError, Result};

/// The controller π of a run built from a scenario.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ControllerChoice {
    /// The exact MPC (the paper's setting): a warm-started, KKT-verified active-set solve
    /// each step ([`ExactMpc`]), allocation-free.
    ExactMpc,
    /// The MPC solved with `iterations` = K_c warm-started iterations of `method`.
    SuboptimalMpc {
        /// K_c (≥ 1 and within `qp_iter::MAX_ITERATIONS` by its type).
        iterations: qp_iter::Iterations,
        /// Φ of the MPC.
        method: Method,
    },
    /// u = Π_𝒰(−K_lqr x̂) with the DARE gain of the scenario's MPC weights.
    SaturatedLqr,
}

impl ControllerChoice {
    /// K_c = `k_c` warm-started iterations of `method`; K_c = 0 or K_c above
    /// `qp_iter::MAX_ITERATIONS` is [`ClosedLoopError::OutOfRange`] naming `controller
    /// iterations` (a search over K_c builds its controllers with it).
    ///
    /// ```
    /// use closed_loop::scenario::ControllerChoice;
    /// use qp_iter::Method;
    /// let c = ControllerChoice::suboptimal(20, Method::PG).unwrap();
    /// assert!(matches!(c, ControllerChoice::SuboptimalMpc { iterations, .. } if iterations.get() == 20));
    /// assert!(ControllerChoice::suboptimal(0, Method::PG).is_err());
    /// ```
    pub fn suboptimal(k_c: usize, method: Method) -> Result<Self> {
        let iterations =
            qp_iter::Iterations::new(k_c).map_err(|_| ClosedLoopError::OutOfRange {
                name: "controller iterations",
                value: k_c as f64,
                range: "integers 1 ..= 10⁷ (qp_iter::MAX_ITERATIONS)",
            })?;
        Ok(Self::SuboptimalMpc { iterations, method })
    }
}

/// What a run changes of the scenario's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopOptions {
    /// Φ of the MHE.
    pub method: Method,
    /// K ≥ 1 iterations of Φ per time step.
    pub iterations: qp_iter::Iterations,
    /// Also solve every ℙ_t exactly (warm-started active set) and record ε_t.
    pub exact_mhe_solve: bool,
    /// The controller.
    pub controller: ControllerChoice,
    /// Seed of the disturbance generator.
    pub seed: u64,
    /// Horizon T ≥ 1.
    pub steps: usize,
}

impl LoopOptions {
    /// These options with K = `k` iterations of Φ per step; K = 0 or K above
    /// `qp_iter::MAX_ITERATIONS` is [`ClosedLoopError::OutOfRange`] naming `iterations` (a
    /// search over K builds its options with it).
    ///
    /// ```
    /// use closed_loop::scenario::{LoopOptions, Scenario};
    /// let sc = Scenario::from_file(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenarios/case-study.toml")).unwrap();
    /// let opts = LoopOptions::from_scenario(&sc).unwrap().with_iterations(40).unwrap();
    /// assert_eq!(opts.iterations.get(), 40);
    /// assert!(opts.with_iterations(0).is_err());
    /// ```
    pub fn with_iterations(self, k: usize) -> Result<Self> {
        let iterations = qp_iter::Iterations::new(k).map_err(|_| ClosedLoopError::OutOfRange {
            name: "iterations",
            value: k as f64,
            range: "integers 1 ..= 10⁷ (qp_iter::MAX_ITERATIONS)",
        })?;
        Ok(Self { iterations, ..self })
    }

    /// The scenario's own settings: `[mhe]` method and K, `[noise]` seed, `[simulation]`
    /// steps, the exact MPC (or K_c iterations of `mpc.method` when `mpc.iterations` is set),
    /// exact MHE solve off.
    pub fn from_scenario(scenario: &Scenario) -> Result<Self> {
        let mhe = scenario
            .mhe
            .as_ref()
            .ok_or(ClosedLoopError::MissingSection { section: "mhe" })?;
        Ok(Self {
            method: mhe.method(),
            iterations: mhe.iterations(),
            exact_mhe_solve: false,
            controller: match scenario
                .mpc
                .as_ref()
                .and_then(|m| m.iterations().map(|k| (k, m)))
            {
                Some((iterations, m)) => ControllerChoice::SuboptimalMpc {
                    iterations,
                    method: m.method(),
                },
                None => ControllerChoice::ExactMpc,
            },
            seed: scenario.noise.seed,
            steps: scenario.simulation.steps,
        })
    }
}

/// The MHE of a scenario run: one type for every method.
pub type ScenarioEstimator = MheEstimator<MethodMap>;

/// The controller of a scenario run.
#[derive(Debug)]
// Built once per run and stepped in place (never moved in the loop), so variant sizes
// do not matter for speed; boxing them would add an indirection per step instead.
#[allow(clippy::large_enum_variant)]
pub enum ScenarioController {
    /// Exact MPC (active set, Clarabel fallback; boxed, it is large).
    Exact(Box<ExactMpc>),
    /// Sub-optimal MPC with K_c iterations of a method.
    Suboptimal(SuboptimalMpc<MethodMap>),
    /// Saturated LQR.
    SaturatedLqr(SaturatedLqr),
}

impl ScenarioController {
    /// Forgets the MPC's warm start (the sub-optimal MPC's iterate, the exact MPC's working
    /// set; no-op for the saturated LQR), so a reused controller behaves like a new one.
    pub fn reset(&mut self) {
        match self {
            ScenarioController::Exact(c) => c.reset(),
            ScenarioController::Suboptimal(c) => c.reset(),
            ScenarioController::SaturatedLqr(_) => {}
        }
    }
}

impl Controller for ScenarioController {
    type Error = MpcError;
    fn control(&mut self, x_hat: &[f64], u: &mut [f64]) -> mpc_core::Result<()> {
        match self {
            ScenarioController::Exact(c) => c.control(x_hat, u),
            ScenarioController::Suboptimal(c) => c.control(x_hat, u),
            ScenarioController::SaturatedLqr(c) => c.control(x_hat, u),
        }
    }
    fn nu(&self) -> usize {
        match self {
            ScenarioController::Exact(c) => c.nu(),
            ScenarioController::Suboptimal(c) => c.nu(),
            ScenarioController::SaturatedLqr(c) => c.nu(),
        }
    }
    fn nx(&self) -> usize {
        match self {
            ScenarioController::Exact(c) => c.nx(),
            ScenarioController::Suboptimal(c) => c.nx(),
            ScenarioController::SaturatedLqr(c) => c.nx(),
        }
    }
    fn status(&self) -> mpc_core::ControlStatus {
        match self {
            ScenarioController::Exact(c) => c.status(),
            ScenarioController::Suboptimal(c) => c.status(),
            ScenarioController::SaturatedLqr(c) => c.status(),
        }
    }
}

/// A scenario's loop: the MHE with any method, the scenario controller, a boxed
/// disturbance (one virtual call per step, no allocation).
pub type ScenarioLoop = ClosedLoop<ScenarioEstimator, ScenarioController, Box<dyn Disturbance>>;

/// The scenario's true disturbance w_t, seeded with `seed`: μ + uniform on `noise.scale`·𝒲,
/// Gaussian N(μ, `scale²·covariance`), the truncated normal N(μ, `scale²·covariance`)
/// conditioned on `noise.truncate`, or zero (μ = `noise.mean`, default 0). A zero scale
/// gives w ≡ μ. The simulated law need not respect 𝒲, which stays the set the MHE and the
/// certificate assume; [`crate::scenario::draws_outside`] counts the draws that leave it.
///
/// Errors: uniform noise on an unbounded 𝒲 (`InvalidSet` naming `"W"`).
pub fn scenario_disturbance(scenario: &Scenario, seed: u64) -> Result<Box<dyn Disturbance>> {
    let nw = scenario.plant.nw();
    let noise = &scenario.noise;
    let mean: Vec<f64> = (0..nw).map(|i| noise.mean_at(i)).collect();
    if noise.kind == NoiseKind::Zero || noise.scale == 0.0 {
        // scale multiplies the random part only: w ≡ μ (a zero-width box) with a mean offset.
        return Ok(if mean.iter().all(|m| *m == 0.0) {
            Box::new(Zero(nw))
        } else {
            Box::new(UniformBox::new(mean.clone(), mean, seed)?)
        });
    }
    Ok(match noise.kind {
        NoiseKind::Zero => Box::new(Zero(nw)),
        NoiseKind::TruncatedNormal => {
            let (Some(cov), Some(set)) = (noise.covariance.as_ref(), noise.truncate.as_ref())
            else {
                return Err(ModelError::Scenario {
                    key: "noise.covariance".into(),
                    problem: "a truncated normal needs a covariance and a truncation box".into(),
                }
                .into());
            };
            let std: Vec<f64> = (0..nw).map(|i| noise.scale * cov[(i, i)].sqrt()).collect();
            Box::new(
                TruncatedNormal::new(mean, std, set.lower().to_vec(), set.upper().to_vec(), seed)
                    .map_err(|e| ModelError::Scenario {
                    key: "noise.truncate".into(),
                    problem: e.to_string(),
                })?,
            )
        }
        NoiseKind::Uniform => {
            let (lower, upper) =
                noise
                    .uniform_box(&scenario.sets.disturbance)
                    .ok_or_else(|| ModelError::Scenario {
                        key: "noise.kind".into(),
                        problem: "uniform noise needs the box 𝒲 of `sets.disturbance`".into(),
                    })?;
            Box::new(UniformBox::new(lower, upper, seed)?)
        }
        NoiseKind::Gaussian => {
            let cov = noise
                .scaled_covariance()
                .ok_or_else(|| ModelError::Scenario {
                    key: "noise.covariance".into(),
                    problem: "Gaussian noise needs a covariance".into(),
                })?;
            // scale²·covariance may underflow for a tiny scale (a sweep's `scales` reach
            // here without the scenario's checks): name the scale, not the internal matrix.
            Box::new(
                Gaussian::new(mean, cov, seed).map_err(|e| ModelError::Scenario {
                    key: "noise.scale".into(),
                    problem: format!(
                        "is {:e}: the Gaussian's covariance scale²·`noise.covariance` is not \
                         usable ({e}); use a larger scale, or 0 for no disturbance",
                        noise.scale
                    ),
                })?,
            )
        }
    })
}

fn record_hook(e: &ScenarioEstimator) -> Option<&MheRecord> {
    Some(e.last_record())
}

impl ResolvedScenario {
    /// The MHE of this scenario with `method` and K = `k` (P as resolved).
    pub fn estimator(
        &self,
        method: Method,
        k: qp_iter::Iterations,
        exact_solve: bool,
    ) -> Result<ScenarioEstimator> {
        let cfg = self.mhe_config()?;
        let sc = self.scenario();
        MheEstimator::from_problem(
            self.mhe_problem()?.clone(),
            k,
            cfg.warm_start,
            exact_solve,
            &sc.simulation.prior,
            |qp| method.build(qp),
        )
        .map_err(Into::into)
    }

    /// The controller π of `choice` for this scenario.
    pub fn controller(&self, choice: ControllerChoice) -> Result<ScenarioController> {
        let sc = self.scenario();
        let spec = sc
            .mpc
            .as_ref()
            .ok_or(ClosedLoopError::MissingSection { section: "mpc" })?;
        Ok(match choice {
            ControllerChoice::SaturatedLqr => ScenarioController::SaturatedLqr(
                SaturatedLqr::new(
                    &sc.plant,
                    spec.q().as_ref(),
                    spec.r().as_ref(),
                    sc.sets.input.clone(),
                )
                .map_err(|e| spec.explain(&sc.plant, e))?,
            ),
            ControllerChoice::ExactMpc => {
                ScenarioController::Exact(Box::new(ExactMpc::new(self.mpc()?)?))
            }
            ControllerChoice::SuboptimalMpc { iterations, method } => {
                let mpc = self.mpc()?;
                let map = method.build(mpc.qp().clone()).map_err(MpcError::Qp)?;
                ScenarioController::Suboptimal(SuboptimalMpc::new(
                    mpc,
                    map,
                    iterations.get(),
                    mpc_core::WarmStart::default(),
                )?)
            }
        })
    }

    /// A ready closed loop (needs `[mhe]` and `[mpc]`): the scenario's plant, sets, x₀,
    /// prior, MHE weights with the resolved P and warm-start rule, with the method, K,
    /// exact-solve flag, controller, seed and T of `options`. MHE records are captured.
    ///
    /// Errors: a missing section, no P (LMI (2) infeasible), a bad
    /// disturbance set, and every construction error of the components.
    ///
    /// ```no_run
    /// use closed_loop::scenario::{ControllerChoice, LoopOptions, Scenario};
    /// let resolved = Scenario::from_file("scenarios/case-study.toml").unwrap().resolve().unwrap();
    /// let mut opts = LoopOptions::from_scenario(resolved.scenario()).unwrap();
    /// opts.method = qp_iter::Method::PG;
    /// opts.iterations = qp_iter::Iterations::new(652).unwrap();
    /// opts.controller = ControllerChoice::ExactMpc;
    /// let mut cl = resolved.build_loop(&opts).unwrap();
    /// let trace = cl.run().unwrap();
    /// println!("sup ‖e‖ = {}", trace.sup_norm_e());
    /// ```
    pub fn build_loop(&self, options: &LoopOptions) -> Result<ScenarioLoop> {
        if options.steps == 0 {
            return Err(ClosedLoopError::ZeroSteps);
        }
        let estimator =
            self.estimator(options.method, options.iterations, options.exact_mhe_solve)?;
        let ctrl = self.controller(options.controller)?;
        let sc = self.scenario();
        let disturbance = scenario_disturbance(sc, options.seed)?;
        let m = self.mhe_config()?.horizon;
        ClosedLoop::new(
            sc.plant.clone(),
            estimator,
            ctrl,
            disturbance,
            &sc.simulation.x0,
            options.steps,
        )?
        .with_mhe_records(record_hook, m)
    }
}

impl ScenarioLoop {
    /// Restarts the run at t = 0 with a new disturbance seed (for Monte-Carlo runs): the
    /// MHE restarts from its initial prior, the sub-optimal MPC cold-starts, and every
    /// buffer is kept (allocation-free).
    pub fn reseed(&mut self, seed: u64) -> Result<()> {
        self.restart_with_prior(|est, ctrl, dist, prior| {
            est.reset(prior)?;
            ctrl.reset();
            dist.reseed(seed);
            Ok(())
        })
    }
}
