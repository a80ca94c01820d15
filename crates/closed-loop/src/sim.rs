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
//! **From a scenario.** [`crate::scenario::ResolvedScenario::build_loop`] turns a resolved
//! scenario (e.g. `scenarios/case-study.toml`) into a ready
//! [`crate::scenario::ScenarioLoop`].

use lti_model::disturbance::Disturbance;
use lti_model::{LtiSystem, ModelError};
use mhe_core::problem::Dims;
use mhe_core::{Estimator, MheError, MheEstimator, MheRecord};
use mpc_core::{Controller, MpcError};
use qp_iter::IterationMap;

use crate::record::{CaptureError, Trace};

/// Errors of the closed-loop simulation: bad setup (at construction) or a failed step
/// (naming the step t and the cause). After a step error the loop is stopped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
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
        /// Cause: the estimator's own error ([`ComponentError::downcast_ref`] recovers it).
        source: ComponentError,
    },
    /// The controller failed at step t.
    #[error("step t = {t}: the controller failed: {source}")]
    Controller {
        /// Step.
        t: usize,
        /// Cause: the controller's own error ([`ComponentError::downcast_ref`] recovers it).
        source: ComponentError,
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
    /// A signal of the loop became NaN, infinite, or so large (≥ [`DIVERGED_MAGNITUDE`])
    /// that its norm overflows: the run diverged at t.
    #[error(
        "step t = {t}: `{name}` has the entry {value:e} at index {index} (non-finite or beyond 1e154, \
         where norms overflow); the closed loop diverged at t = {t} \
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

/// The error of a user-supplied (or built-in) estimator or controller, type-erased so the
/// loop can carry any component's error type; equal when the messages are equal.
///
/// ```
/// use closed_loop::sim::ComponentError;
/// let e = ComponentError::new(mpc_core::MpcError::NonFiniteIterate);
/// assert_eq!(e.downcast_ref::<mpc_core::MpcError>(), Some(&mpc_core::MpcError::NonFiniteIterate));
/// ```
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct ComponentError(std::sync::Arc<dyn std::error::Error + Send + Sync>);

impl ComponentError {
    /// Wraps a component's error.
    pub fn new<E: std::error::Error + Send + Sync + 'static>(e: E) -> Self {
        Self(std::sync::Arc::new(e))
    }
    /// The component's error as its concrete type, if it is one.
    pub fn downcast_ref<E: std::error::Error + 'static>(&self) -> Option<&E> {
        self.0.downcast_ref::<E>()
    }
}

impl std::fmt::Display for ComponentError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for ComponentError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.0.source()
    }
}

impl PartialEq for ComponentError {
    fn eq(&self, other: &Self) -> bool {
        self.to_string() == other.to_string()
    }
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

/// Entry magnitude beyond which a signal counts as diverged: its square overflows f64, so
/// its norm (and every metric built on it) would be +∞ although the entry is finite.
pub const DIVERGED_MAGNITUDE: f64 = 1e154;

fn check_finite(t: usize, name: &'static str, v: &[f64]) -> Result<()> {
    match v.iter().position(|a| !(a.abs() < DIVERGED_MAGNITUDE)) {
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
/// let k = qp_iter::Iterations::new(20).unwrap();
/// let cfg = MheConfig::new(3, 0.8, Mat::identity(2, 2), Mat::identity(3, 3), mat![[1.0]], k)
///     .with_exact_solve(true);
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
            .map_err(|e| ClosedLoopError::Estimator {
                t,
                source: ComponentError::new(e),
            })?;
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
            .map_err(|e| ClosedLoopError::Controller {
                t,
                source: ComponentError::new(e),
            })?;
        check_finite(t, "u", &self.u)?;
        self.trace.set_control_status(self.controller.status());
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
            .map_err(|e| ClosedLoopError::Estimator {
                t,
                source: ComponentError::new(e),
            })?;
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

    /// Restarts the run at t = 0 after `reset` has reset the components; `reset` also gets
    /// the estimator's initial prior x̄₀ (held in scratch, so nothing is allocated).
    pub fn restart_with_prior<F>(&mut self, reset: F) -> Result<()>
    where
        F: FnOnce(&mut MheEstimator<M>, &mut C, &mut D, &[f64]) -> Result<()>,
    {
        // x_next is n_x scratch between steps: it holds the prior while the MHE resets.
        let mut prior = std::mem::take(&mut self.x_next);
        prior.copy_from_slice(self.estimator.initial_prior());
        let res = self.restart(|est, ctrl, dist| reset(est, ctrl, dist, &prior));
        self.x_next = prior;
        res
    }
}
