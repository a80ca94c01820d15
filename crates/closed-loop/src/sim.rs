//! Alg. 1 of Yang–Manzie–Pu as a simulation: plant + estimator + controller + disturbance.
//!
//! [`ClosedLoop`] composes any [`Estimator`] (the sub-optimal MHE of `mhe-core`, a Kalman
//! filter, or a user's own), any [`Controller`] (`mpc-core`'s exact or sub-optimal MPC,
//! saturated LQR, or a user's own) and any [`Disturbance`] around the plant
//! [`LtiSystem`] of eq. (1). One step t is
//!
//! 1. x̂_t = `estimator.estimate()` — Alg. 1 step 1 (K iterations of Φ inside the MHE),
//!    from u and y up to t − 1 (the window at t uses y_{t−M_t..t−1});
//! 2. u_t = π(x̂_t) = `controller.control(x̂_t)` — step 4;
//! 3. w_t = (w¹_t, w²_t) drawn from the disturbance;
//! 4. y_t = C x_t + F w²_t (measured at t) and x_{t+1} = A x_t + B u_t + E w¹_t — eq. (1);
//! 5. `estimator.push(u_t, y_t)` — steps 2–3 (warm start Σ_t, prior, Υ), t ← t + 1.
//!
//! This is `mhe-core`'s timing convention: y_t enters the estimator after x̂_t was computed,
//! so x̂_t never uses y_t.
//!
//! **Capturing the MHE record without the traits knowing about MHE.** The loop can be
//! given a *record hook*, a plain function pointer `fn(&E) -> Option<&MheRecord>` called
//! right after step 1 ([`ClosedLoop::with_mhe_records`]). If it returns a record, the loop
//! copies it into preallocated storage of the [`Trace`] (no allocation). For an
//! [`MheEstimator`] use [`ClosedLoop::new_mhe`], which installs
//! [`MheEstimator::last_record`] as the hook; a user estimator that is not an MHE needs
//! nothing. A hook, unlike a trait method, keeps [`Estimator`] free of MHE types and
//! needs no trait implementation from users.
//!
//! **Allocation.** After construction a step allocates nothing provided the estimator and
//! the controller do not: true for `MheEstimator` (its exact solve for ε_t included),
//! `SuboptimalMpc`, `SaturatedLqr` and `ExactMpc` with its default active-set backend; not
//! for `ExactMpc`'s Clarabel backend or a Clarabel fallback. Errors are the exception:
//! they are built once, when the run stops.
//!
//! **Case study.** [`build_case_study`] turns a [`Scenario`] (e.g. `scenarios/case-study.toml`)
//! into a ready [`CaseStudyLoop`], dispatching over the solvers with enums.

use std::fmt;
use std::str::FromStr;

use lti_model::disturbance::{Disturbance, Gaussian, UniformBox, Zero};
use lti_model::scenario::{MheSolver, NoiseKind, Scenario};
use lti_model::{LtiSystem, ModelError};
use mhe_core::problem::Dims;
use mhe_core::{Estimator, MheConfig, MheError, MheEstimator, MheProblem, MheRecord, MheSets};
use mpc_core::{CondensedMpc, Controller, ExactMpc, MpcError, SaturatedLqr, SuboptimalMpc};
use qp_iter::admm::{Admm, AdmmParams};
use qp_iter::fista::Fista;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{Certificate, IterationMap};

use crate::record::{CaptureError, Trace};

/// Errors of the closed-loop simulation: bad setup (at construction) or a failed step
/// (naming the step t and the cause). After a step error the loop is stopped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClosedLoopError {
    /// T = 0.
    #[error("the horizon `steps` (T) is 0: a closed-loop run needs T ≥ 1 steps")]
    ZeroSteps,
    /// Two components disagree on a dimension.
    #[error(
        "dimension mismatch: {what} is {actual}, but the plant has {expected}; build every component for the same plant"
    )]
    Dimension {
        /// Which dimension of which component (`"estimator n_x"`, `"controller n_u"`,
        /// `"disturbance dim"` (n_w), `"x0 length"`, `"MHE record n_y"`, …).
        what: &'static str,
        /// The plant's value.
        expected: usize,
        /// The component's value.
        actual: usize,
    },
    /// x₀ has a NaN or infinite entry.
    #[error(
        "`x0` has a non-finite entry {value} at index {index}; the initial state must be finite"
    )]
    NonFiniteInitialState {
        /// Index of the entry.
        index: usize,
        /// The entry.
        value: f64,
    },
    /// `with_mhe_records` was called after the run started.
    #[error(
        "MHE records must be enabled before the first step (the loop is at t = {t}); enable them right after construction"
    )]
    AlreadyStarted {
        /// Current step.
        t: usize,
    },
    /// The estimator failed at step t.
    #[error("step t = {t}: the estimator failed: {source}")]
    Estimator {
        /// Step.
        t: usize,
        /// Cause.
        source: MheError,
    },
    /// The controller failed at step t.
    #[error("step t = {t}: the controller failed: {source}")]
    Controller {
        /// Step.
        t: usize,
        /// Cause.
        source: MpcError,
    },
    /// The estimator returned an estimate of the wrong length.
    #[error("step t = {t}: the estimator returned {actual} entries, expected n_x = {expected}")]
    EstimateLength {
        /// Step.
        t: usize,
        /// n_x.
        expected: usize,
        /// Length returned.
        actual: usize,
    },
    /// A signal of the loop became NaN or infinite.
    #[error(
        "step t = {t}: `{name}` has a non-finite entry {value} at index {index}; the closed loop diverged \
         (for the MHE: a larger K, a certified step size, or a smaller disturbance)"
    )]
    NonFinite {
        /// Step.
        t: usize,
        /// Which signal: `"x_hat"` (estimate), `"u"`, `"w"`, `"y"`, `"x_next"` (plant).
        name: &'static str,
        /// Index of the entry.
        index: usize,
        /// The entry.
        value: f64,
    },
    /// The MHE record returned by the hook does not fit the storage.
    #[error(
        "step t = {t}: the MHE record has window length {window}, beyond the storage for \
         windows up to {capacity}; pass the estimator's horizon M as `max_window`"
    )]
    RecordCapacity {
        /// Step.
        t: usize,
        /// Window length of the record.
        window: usize,
        /// Longest window the storage holds.
        capacity: usize,
    },
    /// The hook returned a record for other plant dimensions than at construction.
    #[error(
        "step t = {t}: the MHE record's plant dimensions differ from the plant's; the record hook must return \
         the record of this loop's estimator"
    )]
    RecordDims {
        /// Step.
        t: usize,
    },
    /// All T steps have run.
    #[error("the run already completed all T = {steps} steps")]
    Finished {
        /// T.
        steps: usize,
    },
    /// A previous step failed; the loop does not continue from a half-done step.
    #[error("the run stopped at step t = {t} after an error; restart or build a new loop")]
    Stopped {
        /// The step that failed.
        t: usize,
    },
    /// Invalid model, set or scenario data (setup).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The estimator could not be built (setup).
    #[error(transparent)]
    Mhe(#[from] MheError),
    /// The controller could not be built (setup).
    #[error(transparent)]
    Mpc(#[from] MpcError),
    /// The scenario lacks a section the case study needs.
    #[error("scenario has no `[{section}]` section; add one (see docs/scenario-format.md)")]
    MissingSection {
        /// `"mhe"` or `"mpc"`.
        section: &'static str,
    },
    /// A solver name other than `pg`, `fista`, `admm`, `admm-pr`.
    #[error("unknown solver `{name}`; use \"pg\", \"fista\", \"admm\" or \"admm-pr\"")]
    UnknownSolver {
        /// The name given.
        name: String,
    },
    /// An integer or scalar option is out of range.
    #[error("`{name}` = {value} is out of range: must lie in {range}")]
    OutOfRange {
        /// Option name (`"iterations"`, `"controller iterations"`).
        name: &'static str,
        /// Value given.
        value: f64,
        /// Admissible range.
        range: &'static str,
    },
}

/// Result alias for `closed-loop`.
pub type Result<T> = std::result::Result<T, ClosedLoopError>;

/// The record hook: returns the MHE record of the estimate just computed, if the estimator
/// has one. See the module docs.
pub type RecordHook<E> = for<'a> fn(&'a E) -> Option<&'a MheRecord>;

/// The record hook for [`MheEstimator`].
pub fn mhe_record_hook<M: IterationMap>(est: &MheEstimator<M>) -> Option<&MheRecord> {
    Some(est.last_record())
}

fn check_finite(t: usize, name: &'static str, v: &[f64]) -> Result<()> {
    match v.iter().position(|a| !a.is_finite()) {
        None => Ok(()),
        Some(index) => Err(ClosedLoopError::NonFinite {
            t,
            name,
            index,
            value: v[index],
        }),
    }
}

fn check_dim(what: &'static str, expected: usize, actual: usize) -> Result<()> {
    if expected == actual {
        Ok(())
    } else {
        Err(ClosedLoopError::Dimension {
            what,
            expected,
            actual,
        })
    }
}

/// Alg. 1 in closed loop with the plant: see the module docs for one step.
///
/// ```
/// use closed_loop::sim::ClosedLoop;
/// use faer::{mat, Mat};
/// use lti_model::{BoxSet, LtiSystem, disturbance::UniformBox};
/// use mhe_core::{MheConfig, MheEstimator, MheSets, WarmStart};
/// use mpc_core::SaturatedLqr;
/// use qp_iter::pg::{ProjectedGradient, StepRule};
/// let sys = LtiSystem::new(mat![[0.9, 0.1], [0.0, 0.8]], mat![[0.0], [1.0]], mat![[1.0, 0.0]]).unwrap();
/// let w_box = BoxSet::symmetric(&[0.05; 3]).unwrap();
/// let cfg = MheConfig {
///     horizon: 3, eta: 0.8, p: Mat::identity(2, 2), q: Mat::identity(3, 3), r: mat![[1.0]],
///     iterations: 20, warm_start: WarmStart::Paper, exact_solve: true,
/// };
/// let mhe = MheEstimator::new(&sys, &MheSets::with_disturbance(&sys, w_box.clone()), &cfg,
///     &[0.0, 0.0], |qp| ProjectedGradient::new(qp, StepRule::Optimal)).unwrap();
/// let lqr = SaturatedLqr::new(&sys, Mat::identity(2, 2).as_ref(), mat![[0.1]].as_ref(),
///     BoxSet::symmetric(&[1.0]).unwrap()).unwrap();
/// let noise = UniformBox::from_box(&w_box, 7).unwrap();
/// let mut cl = ClosedLoop::new_mhe(sys, mhe, lqr, noise, &[1.0, -1.0], 20).unwrap();
/// let trace = cl.run().unwrap();
/// assert_eq!(trace.len(), 20);
/// assert!(trace.sup_norm_w() <= 0.05 * 3f64.sqrt());
/// assert!(trace.mhe_step(10).unwrap().epsilon().is_some()); // exact solve on: ε_t recorded
/// ```
#[derive(Debug)]
pub struct ClosedLoop<E: Estimator, C: Controller, D: Disturbance> {
    plant: LtiSystem,
    estimator: E,
    controller: C,
    disturbance: D,
    steps: usize,
    t: usize,
    stopped: Option<usize>,
    x0: Vec<f64>,
    x: Vec<f64>,
    x_next: Vec<f64>,
    x_hat: Vec<f64>,
    u: Vec<f64>,
    y: Vec<f64>,
    w: Vec<f64>,
    hook: Option<RecordHook<E>>,
    trace: Trace,
}

impl<E: Estimator, C: Controller, D: Disturbance> ClosedLoop<E, C, D> {
    /// A loop of `steps` = T ≥ 1 steps from x₀, without MHE records.
    ///
    /// Checks once: T ≥ 1, x₀ (length n_x, finite), the estimator's n_x, the controller's
    /// n_x and n_u, and the disturbance's dimension n_w = n_w1 + n_w2 against the plant.
    /// (The estimator's n_u and n_y are not visible through [`Estimator`]; for an MHE they
    /// are checked by [`ClosedLoop::with_mhe_records`], otherwise the first `push` reports
    /// them as an estimator error at t = 0.)
    pub fn new(
        plant: LtiSystem,
        estimator: E,
        controller: C,
        disturbance: D,
        x0: &[f64],
        steps: usize,
    ) -> Result<Self> {
        if steps == 0 {
            return Err(ClosedLoopError::ZeroSteps);
        }
        let (nx, nu, ny, nw) = (plant.nx(), plant.nu(), plant.ny(), plant.nw());
        check_dim("x0 length", nx, x0.len())?;
        if let Some(index) = x0.iter().position(|a| !a.is_finite()) {
            return Err(ClosedLoopError::NonFiniteInitialState {
                index,
                value: x0[index],
            });
        }
        check_dim("estimator n_x", nx, estimator.nx())?;
        check_dim("controller n_x", nx, controller.nx())?;
        check_dim("controller n_u", nu, controller.nu())?;
        check_dim("disturbance dim (n_w = n_w1 + n_w2)", nw, disturbance.dim())?;
        let mut trace = Trace::new(nx, nu, ny, plant.nw1(), nw, steps);
        trace.set_initial_state(x0);
        Ok(Self {
            plant,
            estimator,
            controller,
            disturbance,
            steps,
            t: 0,
            stopped: None,
            x0: x0.to_vec(),
            x: x0.to_vec(),
            x_next: vec![0.0; nx],
            x_hat: vec![0.0; nx],
            u: vec![0.0; nu],
            y: vec![0.0; ny],
            w: vec![0.0; nw],
            hook: None,
            trace,
        })
    }

    /// Captures the estimator's MHE record every step through `hook`, into storage for
    /// windows of up to `max_window` stages (the estimator's horizon M). Call before the
    /// first step.
    ///
    /// If the hook returns a record now, its plant dimensions are checked against the
    /// plant (`"MHE record n_u"`, …).
    pub fn with_mhe_records(mut self, hook: RecordHook<E>, max_window: usize) -> Result<Self> {
        if self.t > 0 {
            return Err(ClosedLoopError::AlreadyStarted { t: self.t });
        }
        let dims = Dims::of(&self.plant);
        if let Some(rec) = hook(&self.estimator) {
            let r = rec.dims();
            check_dim("MHE record n_x", dims.nx, r.nx)?;
            check_dim("MHE record n_u", dims.nu, r.nu)?;
            check_dim("MHE record n_y", dims.ny, r.ny)?;
            check_dim("MHE record n_w1", dims.nw1, r.nw1)?;
            check_dim("MHE record n_w2", dims.nw2, r.nw2)?;
        }
        self.trace.enable_mhe(dims, max_window);
        self.hook = Some(hook);
        Ok(self)
    }

    /// Runs step t (see the module docs) and returns t.
    ///
    /// Errors: [`ClosedLoopError::Finished`] after T steps, [`ClosedLoopError::Stopped`]
    /// after an earlier error, otherwise the step's error naming t (the loop then stops;
    /// the trace keeps the steps before t).
    pub fn step(&mut self) -> Result<usize> {
        if let Some(t) = self.stopped {
            return Err(ClosedLoopError::Stopped { t });
        }
        let t = self.t;
        if t >= self.steps {
            return Err(ClosedLoopError::Finished { steps: self.steps });
        }
        match self.step_inner(t) {
            Ok(()) => {
                self.t += 1;
                Ok(t)
            }
            Err(e) => {
                self.stopped = Some(t);
                Err(e)
            }
        }
    }

    fn step_inner(&mut self, t: usize) -> Result<()> {
        // 1. x̂_t from u, y up to t − 1.
        let nx = self.x.len();
        let x_hat = self
            .estimator
            .estimate()
            .map_err(|source| ClosedLoopError::Estimator { t, source })?;
        if x_hat.len() != nx {
            return Err(ClosedLoopError::EstimateLength {
                t,
                expected: nx,
                actual: x_hat.len(),
            });
        }
        self.x_hat.copy_from_slice(x_hat);
        // Captured before the finiteness check, so a failing step leaves its record.
        if let (Some(hook), Some(store)) = (self.hook, self.trace.mhe_mut()) {
            if let Some(rec) = hook(&self.estimator) {
                store.capture(t, rec).map_err(|e| match e {
                    CaptureError::Window(window) => ClosedLoopError::RecordCapacity {
                        t,
                        window,
                        capacity: store.max_window(),
                    },
                    CaptureError::Dims(_) => ClosedLoopError::RecordDims { t },
                })?;
            }
        }
        check_finite(t, "x_hat", &self.x_hat)?;
        // 2. u_t = π(x̂_t).
        self.controller
            .control(&self.x_hat, &mut self.u)
            .map_err(|source| ClosedLoopError::Controller { t, source })?;
        check_finite(t, "u", &self.u)?;
        // 3. w_t.
        self.disturbance.sample(&mut self.w);
        check_finite(t, "w", &self.w)?;
        // 4. y_t = C x_t + F w²_t, x_{t+1} = A x_t + B u_t + E w¹_t.
        self.plant
            .step(&self.x, &self.u, &self.w, &mut self.x_next, &mut self.y);
        check_finite(t, "y", &self.y)?;
        check_finite(t, "x_next", &self.x_next)?;
        // 5. Steps 2–3 of Alg. 1 inside the estimator.
        self.estimator
            .push(&self.u, &self.y)
            .map_err(|source| ClosedLoopError::Estimator { t, source })?;
        self.trace
            .push_step(&self.x_hat, &self.u, &self.y, &self.w, &self.x_next);
        std::mem::swap(&mut self.x, &mut self.x_next);
        Ok(())
    }

    /// Runs the remaining steps up to T and returns the trace.
    pub fn run(&mut self) -> Result<&Trace> {
        while self.t < self.steps {
            self.step()?;
        }
        if let Some(t) = self.stopped {
            return Err(ClosedLoopError::Stopped { t });
        }
        Ok(&self.trace)
    }

    /// Rewinds to t = 0 and x₀, keeping every buffer, after `reset` has reset the
    /// components (e.g. the estimator's prior, the controller's warm start, the
    /// disturbance seed). Allocation-free if `reset` is.
    pub fn restart<F>(&mut self, reset: F) -> Result<()>
    where
        F: FnOnce(&mut E, &mut C, &mut D) -> Result<()>,
    {
        reset(
            &mut self.estimator,
            &mut self.controller,
            &mut self.disturbance,
        )?;
        self.t = 0;
        self.stopped = None;
        self.x.copy_from_slice(&self.x0);
        self.trace.clear();
        self.trace.set_initial_state(&self.x0);
        Ok(())
    }

    /// The next step to run (= number of completed steps).
    pub fn t(&self) -> usize {
        self.t
    }
    /// The horizon T.
    pub fn steps(&self) -> usize {
        self.steps
    }
    /// True when all T steps have run.
    pub fn is_finished(&self) -> bool {
        self.t >= self.steps
    }
    /// The true state x_t at the current t.
    pub fn state(&self) -> &[f64] {
        &self.x
    }
    /// The initial state x₀.
    pub fn initial_state(&self) -> &[f64] {
        &self.x0
    }
    /// The records so far.
    pub fn trace(&self) -> &Trace {
        &self.trace
    }
    /// Consumes the loop, returning the trace.
    pub fn into_trace(self) -> Trace {
        self.trace
    }
    /// The plant of eq. (1).
    pub fn plant(&self) -> &LtiSystem {
        &self.plant
    }
    /// The estimator.
    pub fn estimator(&self) -> &E {
        &self.estimator
    }
    /// The controller π.
    pub fn controller(&self) -> &C {
        &self.controller
    }
    /// The disturbance model.
    pub fn disturbance(&self) -> &D {
        &self.disturbance
    }
}

impl<M: IterationMap, C: Controller, D: Disturbance> ClosedLoop<MheEstimator<M>, C, D> {
    /// [`ClosedLoop::new`] with the MHE record captured every step
    /// ([`mhe_record_hook`], windows up to the estimator's horizon M).
    pub fn new_mhe(
        plant: LtiSystem,
        estimator: MheEstimator<M>,
        controller: C,
        disturbance: D,
        x0: &[f64],
        steps: usize,
    ) -> Result<Self> {
        let m = estimator.config().horizon;
        Self::new(plant, estimator, controller, disturbance, x0, steps)?
            .with_mhe_records(mhe_record_hook::<M>, m)
    }
}

// ---------------------------------------------------------------------------------------
// Case study: enum dispatch over the solvers, built from a scenario.
// ---------------------------------------------------------------------------------------

/// The iteration map Φ: projected gradient (step 2/(L + μ)), FISTA, or ADMM (default
/// parameters, or over-relaxed to α = 2: Peaceman–Rachford).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Solver {
    /// Projected gradient with the optimal constant step 2/(L + μ) (`"pg"`).
    Pg,
    /// V-FISTA (`"fista"`).
    Fista,
    /// ADMM with [`AdmmParams::default`] (`"admm"`: ρ = √(μL), α = 1).
    Admm,
    /// ADMM with ρ = √(μL) and relaxation α = 2 (`"admm-pr"`, Peaceman–Rachford): the
    /// certified rate δ = (√κ − 1)/(√κ + 1) instead of (1 + δ)/2, so about half the K.
    #[serde(rename = "admm-pr")]
    AdmmPr,
}

impl Solver {
    /// `"pg"`, `"fista"`, `"admm"` or `"admm-pr"`.
    pub fn name(self) -> &'static str {
        match self {
            Solver::Pg => "pg",
            Solver::Fista => "fista",
            Solver::Admm => "admm",
            Solver::AdmmPr => "admm-pr",
        }
    }

    /// Every solver, in the order reports list them.
    pub const ALL: [Solver; 4] = [Solver::Pg, Solver::Fista, Solver::Admm, Solver::AdmmPr];

    /// ADMM's parameters for the two ADMM variants (`None` for PG and FISTA).
    pub fn admm_params(self) -> Option<AdmmParams> {
        match self {
            Solver::Admm => Some(AdmmParams::default()),
            Solver::AdmmPr => Some(AdmmParams {
                relaxation: 2.0,
                ..AdmmParams::default()
            }),
            Solver::Pg | Solver::Fista => None,
        }
    }
}

impl Solver {
    /// The certificate φ(K) of this solver on `qp`, built exactly as the case-study
    /// estimator builds its maps (PG with step 2/(L+μ), V-FISTA, ADMM with default penalty).
    pub fn certificate_for(
        self,
        qp: qp_iter::ParametricQp,
    ) -> qp_iter::Result<qp_iter::Certificate> {
        Ok(match self {
            Solver::Pg => ProjectedGradient::new(qp, StepRule::Optimal)?
                .certificate()
                .clone(),
            Solver::Fista => Fista::new(qp).certificate().clone(),
            Solver::Admm | Solver::AdmmPr => Admm::new(qp, self.admm_params_or_default())?
                .certificate()
                .clone(),
        })
    }

    fn admm_params_or_default(self) -> AdmmParams {
        self.admm_params().unwrap_or_default()
    }
}

impl fmt::Display for Solver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Solver {
    type Err = ClosedLoopError;
    /// ```
    /// use closed_loop::sim::Solver;
    /// assert_eq!("fista".parse::<Solver>().unwrap(), Solver::Fista);
    /// assert!("newton".parse::<Solver>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "pg" => Ok(Solver::Pg),
            "fista" => Ok(Solver::Fista),
            "admm" => Ok(Solver::Admm),
            "admm-pr" => Ok(Solver::AdmmPr),
            other => Err(ClosedLoopError::UnknownSolver { name: other.into() }),
        }
    }
}

impl From<MheSolver> for Solver {
    fn from(s: MheSolver) -> Self {
        match s {
            MheSolver::ProjectedGradient => Solver::Pg,
            MheSolver::Fista => Solver::Fista,
            MheSolver::Admm => Solver::Admm,
            MheSolver::AdmmPr => Solver::AdmmPr,
        }
    }
}

/// The controller π of a case-study run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControllerChoice {
    /// The exact MPC (the paper's setting): a warm-started, KKT-verified active-set solve
    /// each step ([`ExactMpc`]), allocation-free.
    ExactMpc,
    /// The MPC solved with `iterations` = K_c ≥ 1 warm-started iterations of `solver`.
    SuboptimalMpc {
        /// K_c.
        iterations: usize,
        /// Φ of the MPC.
        solver: Solver,
    },
    /// u = Π_𝒰(−K_lqr x̂) with the DARE gain of the scenario's MPC weights.
    SaturatedLqr,
}

/// Options of [`build_case_study`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CaseStudyOptions {
    /// Φ of the MHE.
    pub solver: Solver,
    /// K ≥ 1 iterations of Φ per time step.
    pub iterations: usize,
    /// Also solve every ℙ_t exactly (warm-started active set) and record ε_t.
    pub exact_mhe_solve: bool,
    /// The controller.
    pub controller: ControllerChoice,
    /// Seed of the disturbance generator.
    pub seed: u64,
    /// Horizon T ≥ 1.
    pub steps: usize,
}

impl CaseStudyOptions {
    /// The scenario's own settings: `[mhe]` solver and K, `[noise]` seed,
    /// `[simulation]` steps, the exact MPC, exact MHE solve off.
    pub fn from_scenario(scenario: &Scenario) -> Result<Self> {
        let mhe = scenario
            .mhe
            .as_ref()
            .ok_or(ClosedLoopError::MissingSection { section: "mhe" })?;
        Ok(Self {
            solver: mhe.solver.into(),
            iterations: mhe.iterations,
            exact_mhe_solve: false,
            controller: ControllerChoice::ExactMpc,
            seed: scenario.noise.seed,
            steps: scenario.simulation.steps,
        })
    }
}

/// The case study's estimator: the sub-optimal MHE with one of the three maps.
#[derive(Debug)]
pub enum CaseStudyEstimator {
    /// Φ = projected gradient.
    Pg(MheEstimator<ProjectedGradient>),
    /// Φ = FISTA.
    Fista(MheEstimator<Fista>),
    /// Φ = ADMM (α = 1).
    Admm(MheEstimator<Admm>),
    /// Φ = ADMM with α = 2 (Peaceman–Rachford).
    AdmmPr(MheEstimator<Admm>),
}

macro_rules! each_mhe {
    ($self:expr, $e:ident => $body:expr) => {
        match $self {
            CaseStudyEstimator::Pg($e) => $body,
            CaseStudyEstimator::Fista($e) => $body,
            CaseStudyEstimator::Admm($e) => $body,
            CaseStudyEstimator::AdmmPr($e) => $body,
        }
    };
}

impl CaseStudyEstimator {
    /// Which Φ.
    pub fn solver(&self) -> Solver {
        match self {
            CaseStudyEstimator::Pg(_) => Solver::Pg,
            CaseStudyEstimator::Fista(_) => Solver::Fista,
            CaseStudyEstimator::Admm(_) => Solver::Admm,
            CaseStudyEstimator::AdmmPr(_) => Solver::AdmmPr,
        }
    }
    /// The record of the last estimate.
    pub fn last_record(&self) -> &MheRecord {
        each_mhe!(self, e => e.last_record())
    }
    /// ℙ_t for every window length.
    pub fn problem(&self) -> &MheProblem {
        each_mhe!(self, e => e.problem())
    }
    /// The MHE configuration (M, η, P, Q, R, K, warm start).
    pub fn config(&self) -> &MheConfig {
        each_mhe!(self, e => e.config())
    }
    /// φ(K) certificate of Φ for window length m (None if m > M).
    pub fn certificate(&self, m: usize) -> Option<&Certificate> {
        each_mhe!(self, e => e.map(m).map(IterationMap::certificate))
    }
    /// Restarts the estimator at t = 0 with prior x̄₀ (keeps every allocation).
    pub fn reset(&mut self, prior: &[f64]) -> mhe_core::Result<()> {
        each_mhe!(self, e => e.reset(prior))
    }
    /// The initial prior x̄₀.
    pub fn initial_prior(&self) -> &[f64] {
        each_mhe!(self, e => e.initial_prior())
    }
}

impl Estimator for CaseStudyEstimator {
    fn estimate(&mut self) -> mhe_core::Result<&[f64]> {
        each_mhe!(self, e => e.estimate())
    }
    fn push(&mut self, u: &[f64], y: &[f64]) -> mhe_core::Result<()> {
        each_mhe!(self, e => e.push(u, y))
    }
    fn nx(&self) -> usize {
        each_mhe!(self, e => Estimator::nx(e))
    }
}

fn case_study_record_hook(e: &CaseStudyEstimator) -> Option<&MheRecord> {
    Some(e.last_record())
}

/// The case study's controller.
#[derive(Debug)]
// Built once per run and stepped in place (never moved in the loop), so variant sizes
// do not matter for speed; boxing them would add an indirection per step instead.
#[allow(clippy::large_enum_variant)]
pub enum CaseStudyController {
    /// Exact MPC (active set, Clarabel fallback; boxed, it is large).
    Exact(Box<ExactMpc>),
    /// Sub-optimal MPC with projected gradient.
    SuboptimalPg(SuboptimalMpc<ProjectedGradient>),
    /// Sub-optimal MPC with FISTA.
    SuboptimalFista(SuboptimalMpc<Fista>),
    /// Sub-optimal MPC with ADMM.
    SuboptimalAdmm(SuboptimalMpc<Admm>),
    /// Saturated LQR.
    SaturatedLqr(SaturatedLqr),
}

macro_rules! each_ctrl {
    ($self:expr, $c:ident => $body:expr) => {
        match $self {
            CaseStudyController::Exact($c) => $body,
            CaseStudyController::SuboptimalPg($c) => $body,
            CaseStudyController::SuboptimalFista($c) => $body,
            CaseStudyController::SuboptimalAdmm($c) => $body,
            CaseStudyController::SaturatedLqr($c) => $body,
        }
    };
}

impl CaseStudyController {
    /// Forgets the MPC's warm start (the sub-optimal MPC's iterate, the exact MPC's working
    /// set; no-op for the saturated LQR), so a reused controller behaves like a new one.
    pub fn reset(&mut self) {
        match self {
            CaseStudyController::Exact(c) => c.reset(),
            CaseStudyController::SuboptimalPg(c) => c.reset(),
            CaseStudyController::SuboptimalFista(c) => c.reset(),
            CaseStudyController::SuboptimalAdmm(c) => c.reset(),
            CaseStudyController::SaturatedLqr(_) => {}
        }
    }
}

impl Controller for CaseStudyController {
    fn control(&mut self, x_hat: &[f64], u: &mut [f64]) -> mpc_core::Result<()> {
        each_ctrl!(self, c => c.control(x_hat, u))
    }
    fn nu(&self) -> usize {
        each_ctrl!(self, c => c.nu())
    }
    fn nx(&self) -> usize {
        each_ctrl!(self, c => c.nx())
    }
}

/// The case-study loop: enum-dispatched MHE and controller, boxed disturbance (one
/// virtual call per step, no allocation).
pub type CaseStudyLoop = ClosedLoop<CaseStudyEstimator, CaseStudyController, Box<dyn Disturbance>>;

/// The scenario's true disturbance w_t: uniform on `noise.scale`·𝒲 (the case study),
/// zero-mean Gaussian with covariance `scale²·covariance`, or zero, seeded with `seed`.
/// A zero scale gives w ≡ 0.
///
/// Errors: uniform noise on an unbounded 𝒲 (`InvalidSet` naming `"W"`).
pub fn scenario_disturbance(scenario: &Scenario, seed: u64) -> Result<Box<dyn Disturbance>> {
    let nw = scenario.plant.nw();
    let noise = &scenario.noise;
    if noise.scale == 0.0 {
        return Ok(Box::new(Zero(nw)));
    }
    Ok(match noise.kind {
        NoiseKind::Zero => Box::new(Zero(nw)),
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
            Box::new(Gaussian::new(vec![0.0; nw], cov, seed)?)
        }
    })
}

fn mhe_estimator(
    solver: Solver,
    plant: &LtiSystem,
    sets: &MheSets,
    cfg: &MheConfig,
    prior: &[f64],
) -> Result<CaseStudyEstimator> {
    Ok(match solver {
        Solver::Pg => CaseStudyEstimator::Pg(MheEstimator::new(plant, sets, cfg, prior, |qp| {
            ProjectedGradient::new(qp, StepRule::Optimal)
        })?),
        Solver::Fista => {
            CaseStudyEstimator::Fista(MheEstimator::new(plant, sets, cfg, prior, |qp| {
                Ok(Fista::new(qp))
            })?)
        }
        Solver::Admm | Solver::AdmmPr => {
            let params = solver.admm_params_or_default();
            let e = MheEstimator::new(plant, sets, cfg, prior, |qp| Admm::new(qp, params))?;
            if solver == Solver::Admm {
                CaseStudyEstimator::Admm(e)
            } else {
                CaseStudyEstimator::AdmmPr(e)
            }
        }
    })
}

fn controller(scenario: &Scenario, choice: ControllerChoice) -> Result<CaseStudyController> {
    let spec = scenario
        .mpc
        .as_ref()
        .ok_or(ClosedLoopError::MissingSection { section: "mpc" })?;
    Ok(match choice {
        ControllerChoice::SaturatedLqr => CaseStudyController::SaturatedLqr(SaturatedLqr::new(
            &scenario.plant,
            spec.q.as_ref(),
            spec.r.as_ref(),
            scenario.sets.input.clone(),
        )?),
        ControllerChoice::ExactMpc => CaseStudyController::Exact(Box::new(ExactMpc::new(
            &CondensedMpc::from_scenario(scenario)?,
        )?)),
        ControllerChoice::SuboptimalMpc { iterations, solver } => {
            if iterations == 0 {
                return Err(ClosedLoopError::OutOfRange {
                    name: "controller iterations",
                    value: 0.0,
                    range: "integers ≥ 1",
                });
            }
            let mpc = CondensedMpc::from_scenario(scenario)?;
            let warm = mpc_core::WarmStart::default();
            let qp = mpc.qp().clone();
            match solver {
                Solver::Pg => CaseStudyController::SuboptimalPg(SuboptimalMpc::new(
                    &mpc,
                    ProjectedGradient::new(qp, StepRule::Optimal).map_err(MpcError::Qp)?,
                    iterations,
                    warm,
                )?),
                Solver::Fista => CaseStudyController::SuboptimalFista(SuboptimalMpc::new(
                    &mpc,
                    Fista::new(qp),
                    iterations,
                    warm,
                )?),
                Solver::Admm | Solver::AdmmPr => {
                    CaseStudyController::SuboptimalAdmm(SuboptimalMpc::new(
                        &mpc,
                        Admm::new(qp, solver.admm_params_or_default()).map_err(MpcError::Qp)?,
                        iterations,
                        warm,
                    )?)
                }
            }
        }
    })
}

/// A ready closed loop for a scenario with `[mhe]` and `[mpc]` sections (the case study:
/// `scenarios/case-study.toml`): the scenario's plant, sets, x₀, prior, MHE weights (P from
/// LMI (2) when not given) and warm-start rule, with the solver, K, exact-solve flag,
/// controller, seed and T of `options`. MHE records are captured.
///
/// Errors: a missing section, K = 0 or K_c = 0, an infeasible LMI, a bad disturbance
/// set, and every construction error of the components.
///
/// ```no_run
/// use closed_loop::sim::{build_case_study, CaseStudyOptions, ControllerChoice, Solver};
/// let scenario = lti_model::scenario::Scenario::from_file("scenarios/case-study.toml").unwrap();
/// let mut opts = CaseStudyOptions::from_scenario(&scenario).unwrap();
/// opts.solver = Solver::Pg;
/// opts.iterations = 652;
/// opts.controller = ControllerChoice::ExactMpc;
/// let mut cl = build_case_study(&scenario, &opts).unwrap();
/// let trace = cl.run().unwrap();
/// println!("sup ‖e‖ = {}", trace.sup_norm_e());
/// ```
pub fn build_case_study(scenario: &Scenario, options: &CaseStudyOptions) -> Result<CaseStudyLoop> {
    let spec = scenario
        .mhe
        .as_ref()
        .ok_or(ClosedLoopError::MissingSection { section: "mhe" })?;
    if options.iterations == 0 {
        return Err(ClosedLoopError::OutOfRange {
            name: "iterations",
            value: 0.0,
            range: "integers ≥ 1",
        });
    }
    if options.steps == 0 {
        return Err(ClosedLoopError::ZeroSteps);
    }
    let plant = scenario.plant.clone();
    let mut cfg = MheConfig::from_spec(spec, &plant, options.exact_mhe_solve)?;
    cfg.iterations = options.iterations;
    let sets = MheSets::from_scenario(&scenario.sets);
    let sim = &scenario.simulation;
    let estimator = mhe_estimator(options.solver, &plant, &sets, &cfg, &sim.prior)?;
    let ctrl = controller(scenario, options.controller)?;
    let disturbance = scenario_disturbance(scenario, options.seed)?;
    let m = cfg.horizon;
    ClosedLoop::new(plant, estimator, ctrl, disturbance, &sim.x0, options.steps)?
        .with_mhe_records(case_study_record_hook, m)
}

impl ClosedLoop<CaseStudyEstimator, CaseStudyController, Box<dyn Disturbance>> {
    /// Restarts the case study at t = 0 with a new disturbance seed (for Monte-Carlo runs):
    /// the MHE restarts from its initial prior, the sub-optimal MPC cold-starts, and every
    /// buffer is kept (allocation-free).
    pub fn reseed(&mut self, seed: u64) -> Result<()> {
        // x_next is n_x scratch between steps: it holds the prior while the MHE resets.
        let mut prior = std::mem::take(&mut self.x_next);
        prior.copy_from_slice(self.estimator.initial_prior());
        let res = self.restart(|est, ctrl, dist| {
            est.reset(&prior)?;
            ctrl.reset();
            dist.reseed(seed);
            Ok(())
        });
        self.x_next = prior;
        res
    }
}
