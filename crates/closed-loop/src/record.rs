//! The trace of one closed-loop run of Alg. 1: preallocated per-step records.
//!
//! A [`Trace`] is sized for T steps when the loop is built and filled in place, so a step
//! allocates nothing. Per step t it holds x_t, u_t, y_t, w_t = (w¹_t, w²_t), x̂_t,
//! e_t = x̂_t − x_t, ‖e_t‖ and ‖x_t‖ (Euclidean norms), and, when the loop captures them,
//! the estimator's MHE record (prior, window data, K-th iterate, exact optimum and ε_t when
//! the exact solve is on) in [`MheTrace`]. The final state x_T is kept as well.
//!
//! With the `serde` feature, serialisation (`Trace::to_json`) writes one object per step; the
//! MHE part uses the field names of [`mhe_core::MheRecord`]'s. The files of `cargo xtask
//! reproduce` do not use it: `trace.json` has its own versioned records
//! (`certificate_json::v1::TraceRecord`), filled from the accessors below.

use mhe_core::MheRecord;
use mhe_core::problem::Dims;
use qp_iter::RunStatus;

pub(crate) use lti_model::vecmath::norm2;

/// Fixed-stride storage of `capacity` rows of `width` values (allocation-free writes).
#[derive(Debug, Clone, PartialEq)]
struct Rows {
    data: Vec<f64>,
    width: usize,
}

impl Rows {
    fn new(width: usize, capacity: usize) -> Self {
        Self {
            data: vec![0.0; width * capacity],
            width,
        }
    }
    fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.width..(i + 1) * self.width]
    }
    fn row_mut(&mut self, i: usize) -> &mut [f64] {
        &mut self.data[i * self.width..(i + 1) * self.width]
    }
}

/// Per-step records of a closed-loop run (Alg. 1), preallocated for T steps.
///
/// Steps are indexed t = 0..len (len ≤ T); states x_0..x_len (one more than steps).
///
/// ```
/// use closed_loop::sim::ClosedLoop;
/// use faer::mat;
/// use lti_model::{BoxSet, LtiSystem, disturbance::Zero};
/// use mhe_core::Estimator;
/// use mpc_core::SaturatedLqr;
/// /// Dead reckoning x̂_{t+1} = 0.5 x̂_t + u_t: exact when w = 0 and x̂_0 = x_0.
/// #[derive(Debug)]
/// struct DeadReckoning([f64; 1]);
/// impl Estimator for DeadReckoning {
///     type Error = std::convert::Infallible;
///     fn estimate(&mut self) -> Result<&[f64], Self::Error> { Ok(&self.0) }
///     fn push(&mut self, u: &[f64], _y: &[f64]) -> Result<(), Self::Error> {
///         self.0[0] = 0.5 * self.0[0] + u[0];
///         Ok(())
///     }
///     fn nx(&self) -> usize { 1 }
/// }
/// let sys = LtiSystem::new(mat![[0.5]], mat![[1.0]], mat![[1.0]]).unwrap();
/// let lqr = SaturatedLqr::from_gain(mat![[0.25]], BoxSet::symmetric(&[1.0]).unwrap()).unwrap();
/// let est = DeadReckoning([2.0]);
/// let mut cl = ClosedLoop::new(sys, est, lqr, Zero(2), &[2.0], 3).unwrap();
/// let trace = cl.run().unwrap();
/// // x_{t+1} = (0.5 − 0.25) x_t: 2, 0.5, 0.125, 0.03125.
/// assert_eq!(trace.len(), 3);
/// assert_eq!(trace.x(3), Some(&[0.03125][..]));
/// assert_eq!(trace.sup_norm_x(), 2.0);
/// assert_eq!(trace.tail_mean_x(), Some(0.125)); // last quarter: ⌈3/4⌉ = 1 step (t = 2)
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    nx: usize,
    nu: usize,
    ny: usize,
    nw1: usize,
    nw: usize,
    steps: usize,
    len: usize,
    x: Rows,
    u: Rows,
    y: Rows,
    w: Rows,
    x_hat: Rows,
    e: Rows,
    e_norm: Vec<f64>,
    x_norm: Vec<f64>,
    w_norm: Vec<f64>,
    /// What the controller applied at each step ([`Trace::control_status`]).
    control: Vec<mpc_core::ControlStatus>,
    mhe: Option<MheTrace>,
}

impl Trace {
    /// An empty trace for `steps` steps of a plant with the given dimensions
    /// (n_w1 = dim w¹; n_w = dim w).
    pub(crate) fn new(
        nx: usize,
        nu: usize,
        ny: usize,
        nw1: usize,
        nw: usize,
        steps: usize,
    ) -> Self {
        Self {
            nx,
            nu,
            ny,
            nw1,
            nw,
            steps,
            len: 0,
            x: Rows::new(nx, steps + 1),
            u: Rows::new(nu, steps),
            y: Rows::new(ny, steps),
            w: Rows::new(nw, steps),
            x_hat: Rows::new(nx, steps),
            e: Rows::new(nx, steps),
            e_norm: vec![0.0; steps],
            x_norm: vec![0.0; steps + 1],
            w_norm: vec![0.0; steps],
            control: vec![mpc_core::ControlStatus::Applied { violation: 0.0 }; steps],
            mhe: None,
        }
    }

    /// Records what the controller applied at the step being taken (before `push_step`).
    pub(crate) fn set_control_status(&mut self, s: mpc_core::ControlStatus) {
        if let Some(slot) = self.control.get_mut(self.len) {
            *slot = s;
        }
    }

    /// What the controller applied at step t (`None` beyond the completed steps): the law as
    /// designed (with the plan's measured constraint violation), or, for an infeasible
    /// state-constrained MPC, the fallback it applied instead.
    pub fn control_status(&self, t: usize) -> Option<mpc_core::ControlStatus> {
        (t < self.len).then(|| self.control[t])
    }

    /// The steps at which the state-constrained MPC was infeasible (a fallback was applied).
    pub fn infeasible_steps(&self) -> impl Iterator<Item = usize> + '_ {
        self.control[..self.len]
            .iter()
            .enumerate()
            .filter(|(_, s)| matches!(s, mpc_core::ControlStatus::Infeasible { .. }))
            .map(|(t, _)| t)
    }

    pub(crate) fn enable_mhe(&mut self, dims: Dims, max_window: usize) {
        self.mhe = Some(MheTrace::new(dims, max_window, self.steps));
    }

    pub(crate) fn mhe_mut(&mut self) -> Option<&mut MheTrace> {
        self.mhe.as_mut()
    }

    /// Forgets every step (keeps the buffers).
    pub(crate) fn clear(&mut self) {
        self.len = 0;
        if let Some(m) = self.mhe.as_mut() {
            m.len = 0;
        }
    }

    pub(crate) fn set_initial_state(&mut self, x0: &[f64]) {
        self.x.row_mut(0).copy_from_slice(x0);
        self.x_norm[0] = norm2(x0);
    }

    /// Writes step t = len: x̂_t, u_t, y_t, w_t, and x_{t+1}; x_t is already stored.
    pub(crate) fn push_step(
        &mut self,
        x_hat: &[f64],
        u: &[f64],
        y: &[f64],
        w: &[f64],
        x_next: &[f64],
    ) {
        let t = self.len;
        let e = self.e.row_mut(t);
        let x = &self.x.data[t * self.nx..(t + 1) * self.nx];
        for ((ei, xh), xi) in e.iter_mut().zip(x_hat).zip(x) {
            *ei = xh - xi;
        }
        self.e_norm[t] = norm2(e);
        self.x_hat.row_mut(t).copy_from_slice(x_hat);
        self.u.row_mut(t).copy_from_slice(u);
        self.y.row_mut(t).copy_from_slice(y);
        self.w.row_mut(t).copy_from_slice(w);
        self.w_norm[t] = norm2(w);
        self.x.row_mut(t + 1).copy_from_slice(x_next);
        self.x_norm[t + 1] = norm2(x_next);
        self.len += 1;
    }

    /// Number of completed steps (len ≤ T).
    pub fn len(&self) -> usize {
        self.len
    }
    /// True before the first step.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The horizon T the trace was built for.
    pub fn steps(&self) -> usize {
        self.steps
    }
    /// (n_x, n_u, n_y, n_w) of the plant.
    pub fn dims(&self) -> (usize, usize, usize, usize) {
        (self.nx, self.nu, self.ny, self.nw)
    }
    /// dim w¹ (the first [`Trace::nw1`] entries of w_t are w¹_t, the rest w²_t).
    pub fn nw1(&self) -> usize {
        self.nw1
    }

    /// The true state x_t, t = 0..=len (x_len is the state after the last step).
    pub fn x(&self, t: usize) -> Option<&[f64]> {
        (t <= self.len).then(|| self.x.row(t))
    }
    /// The input u_t = π(x̂_t), t < len.
    pub fn u(&self, t: usize) -> Option<&[f64]> {
        (t < self.len).then(|| self.u.row(t))
    }
    /// The measurement y_t = C x_t + F w²_t, t < len.
    pub fn y(&self, t: usize) -> Option<&[f64]> {
        (t < self.len).then(|| self.y.row(t))
    }
    /// The disturbance w_t = (w¹_t, w²_t), t < len.
    pub fn w(&self, t: usize) -> Option<&[f64]> {
        (t < self.len).then(|| self.w.row(t))
    }
    /// w¹_t (process disturbance), t < len.
    pub fn w1(&self, t: usize) -> Option<&[f64]> {
        self.w(t).map(|w| &w[..self.nw1])
    }
    /// w²_t (measurement noise), t < len.
    pub fn w2(&self, t: usize) -> Option<&[f64]> {
        self.w(t).map(|w| &w[self.nw1..])
    }
    /// The estimate x̂_t used by the controller at t, t < len.
    pub fn x_hat(&self, t: usize) -> Option<&[f64]> {
        (t < self.len).then(|| self.x_hat.row(t))
    }
    /// The estimation error e_t = x̂_t − x_t, t < len.
    pub fn e(&self, t: usize) -> Option<&[f64]> {
        (t < self.len).then(|| self.e.row(t))
    }
    /// ‖e_t‖₂ for t = 0..len.
    pub fn e_norms(&self) -> &[f64] {
        &self.e_norm[..self.len]
    }
    /// ‖x_t‖₂ for t = 0..=len (the final state included).
    pub fn x_norms(&self) -> &[f64] {
        &self.x_norm[..=self.len]
    }
    /// ‖w_t‖₂ for t = 0..len.
    pub fn w_norms(&self) -> &[f64] {
        &self.w_norm[..self.len]
    }
    /// The MHE records, if the loop captured them (see
    /// [`crate::sim::ClosedLoop::with_mhe_records`]).
    pub fn mhe(&self) -> Option<&MheTrace> {
        self.mhe.as_ref()
    }
    /// The MHE record of step t (None if not captured or t ≥ len).
    pub fn mhe_step(&self, t: usize) -> Option<MheStep<'_>> {
        if t >= self.len {
            return None;
        }
        self.mhe.as_ref().and_then(|m| m.step(t))
    }
    /// ε_t = ‖zᴷ_t − z*_t‖₂ per step (None where not recorded: no MHE record captured or the
    /// estimator's exact solve off).
    pub fn epsilons(&self) -> impl Iterator<Item = Option<f64>> + '_ {
        (0..self.len).map(|t| self.mhe_step(t).and_then(|s| s.epsilon()))
    }

    /// sup_t ‖e_t‖ over the recorded steps (0 before the first step): ‖e‖_{[0,T−1]} of
    /// Prop. 3 / Theorem 1.
    pub fn sup_norm_e(&self) -> f64 {
        sup(self.e_norms())
    }
    /// sup_t ‖x_t‖ over x_0..x_len (the final state included).
    pub fn sup_norm_x(&self) -> f64 {
        sup(self.x_norms())
    }
    /// sup_t ‖w_t‖ over the recorded steps: ‖w‖_{[0,T−1]} of Theorem 1.
    pub fn sup_norm_w(&self) -> f64 {
        sup(self.w_norms())
    }
    /// Mean of ‖e_t‖ over the last quarter of the recorded steps (the last ⌈len/4⌉ steps;
    /// None before the first step).
    pub fn tail_mean_e(&self) -> Option<f64> {
        tail_mean(self.e_norms())
    }
    /// Mean of ‖x_t‖ over the last quarter of the recorded steps t < len (the last ⌈len/4⌉
    /// steps, same t as [`Trace::tail_mean_e`]; None before the first step).
    pub fn tail_mean_x(&self) -> Option<f64> {
        tail_mean(&self.x_norm[..self.len])
    }
    /// Mean of ‖w_t‖ over the last quarter of the recorded steps.
    pub fn tail_mean_w(&self) -> Option<f64> {
        tail_mean(self.w_norms())
    }
    /// Mean of ε_t over the last quarter of the recorded steps (None unless every step
    /// there has ε_t).
    pub fn tail_mean_epsilon(&self) -> Option<f64> {
        let start = tail_start(self.len)?;
        let mut sum = 0.0;
        for t in start..self.len {
            sum += self.mhe_step(t)?.epsilon()?;
        }
        Some(sum / (self.len - start) as f64)
    }

    /// The trace as JSON (see the module docs for the layout).
    #[cfg(feature = "serde")]
    pub fn to_json(&self) -> serde_json::Result<String> {
        serde_json::to_string(self)
    }
    /// The trace as indented JSON.
    #[cfg(feature = "serde")]
    pub fn to_json_pretty(&self) -> serde_json::Result<String> {
        serde_json::to_string_pretty(self)
    }
}

fn sup(v: &[f64]) -> f64 {
    // NaN-propagating max: a diverged run must not look bounded.
    v.iter()
        .fold(0.0, |m: f64, &a| if a > m || a.is_nan() { a } else { m })
}

/// First step of the last quarter: len − ⌈len/4⌉.
fn tail_start(len: usize) -> Option<usize> {
    (len > 0).then(|| len - len.div_ceil(4))
}

fn tail_mean(v: &[f64]) -> Option<f64> {
    let start = tail_start(v.len())?;
    let tail = &v[start..];
    Some(tail.iter().sum::<f64>() / tail.len() as f64)
}

/// The scalar part of one captured [`MheRecord`].
#[derive(Debug, Clone, Copy, PartialEq)]
struct MheScalars {
    t: usize,
    window: usize,
    iterations: usize,
    status: RunStatus,
    cost_k: f64,
    cost_exact: Option<f64>,
    epsilon: Option<f64>,
    initial_error: Option<f64>,
    violation: f64,
    has_exact: bool,
}

/// The MHE records of a run: for every step a copy of the estimator's [`MheRecord`], in
/// fixed-stride preallocated storage (windows up to `max_window` stages), so capturing
/// allocates nothing.
///
/// The record is captured right after the estimate, so when a step fails later (or on a
/// non-finite estimate) this holds one more record than the [`Trace`] has steps: the
/// failing step's, for diagnosis ([`MheTrace::step`] returns it; [`Trace::mhe_step`]
/// and the JSON output stop at the trace's steps).
#[derive(Debug, Clone, PartialEq)]
pub struct MheTrace {
    dims: Dims,
    max_window: usize,
    len: usize,
    scalars: Vec<MheScalars>,
    prior: Rows,
    u: Rows,
    y: Rows,
    x_start_k: Rows,
    w_k: Rows,
    x_hat: Rows,
    x_start_exact: Rows,
    w_exact: Rows,
    x_hat_exact: Rows,
}

/// Why a record could not be captured (turned into a step error by the loop).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum CaptureError {
    Dims(Dims),
    Window(usize),
}

impl MheTrace {
    fn new(dims: Dims, max_window: usize, steps: usize) -> Self {
        let nw = dims.nw();
        let blank = MheScalars {
            t: 0,
            window: 0,
            iterations: 0,
            status: RunStatus::Completed,
            cost_k: 0.0,
            cost_exact: None,
            epsilon: None,
            initial_error: None,
            violation: 0.0,
            has_exact: false,
        };
        Self {
            dims,
            max_window,
            len: 0,
            scalars: vec![blank; steps],
            prior: Rows::new(dims.nx, steps),
            u: Rows::new(max_window * dims.nu, steps),
            y: Rows::new(max_window * dims.ny, steps),
            x_start_k: Rows::new(dims.nx, steps),
            w_k: Rows::new(max_window * nw, steps),
            x_hat: Rows::new(dims.nx, steps),
            x_start_exact: Rows::new(dims.nx, steps),
            w_exact: Rows::new(max_window * nw, steps),
            x_hat_exact: Rows::new(dims.nx, steps),
        }
    }

    /// Copies `rec` into slot `t` (= the number of records so far); allocation-free.
    pub(crate) fn capture(&mut self, t: usize, rec: &MheRecord) -> Result<(), CaptureError> {
        if rec.dims() != self.dims {
            return Err(CaptureError::Dims(rec.dims()));
        }
        if rec.window > self.max_window || t >= self.scalars.len() {
            return Err(CaptureError::Window(rec.window));
        }
        let m = rec.window;
        let d = self.dims;
        let exact = rec.x_hat_exact().is_some();
        self.scalars[t] = MheScalars {
            t: rec.t,
            window: m,
            iterations: rec.iterations,
            status: rec.status,
            cost_k: rec.cost_k,
            cost_exact: rec.cost_exact,
            epsilon: rec.epsilon,
            initial_error: rec.initial_error,
            violation: rec.violation,
            has_exact: exact,
        };
        copy_prefix(self.prior.row_mut(t), rec.prior());
        copy_prefix(self.u.row_mut(t), &rec.u_flat()[..m * d.nu]);
        copy_prefix(self.y.row_mut(t), &rec.y_flat()[..m * d.ny]);
        copy_prefix(self.x_start_k.row_mut(t), rec.x_start_k());
        copy_prefix(self.w_k.row_mut(t), &rec.w_k_flat()[..m * d.nw()]);
        copy_prefix(self.x_hat.row_mut(t), rec.x_hat());
        if let (Some(xs), Some(ws), Some(xh)) =
            (rec.x_start_exact(), rec.w_exact_flat(), rec.x_hat_exact())
        {
            copy_prefix(self.x_start_exact.row_mut(t), xs);
            copy_prefix(self.w_exact.row_mut(t), &ws[..m * d.nw()]);
            copy_prefix(self.x_hat_exact.row_mut(t), xh);
        }
        self.len = t + 1;
        Ok(())
    }

    /// Number of captured records.
    pub fn len(&self) -> usize {
        self.len
    }
    /// True before the first capture.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The plant dimensions the records were made for.
    pub fn dims(&self) -> Dims {
        self.dims
    }
    /// The longest window the storage holds (the estimator's M).
    pub fn max_window(&self) -> usize {
        self.max_window
    }
    /// The record of step t (None if t ≥ len).
    pub fn step(&self, t: usize) -> Option<MheStep<'_>> {
        (t < self.len).then_some(MheStep { trace: self, t })
    }
}

/// Copies `src` into the first `src.len()` entries of `dst` (callers guarantee the fit).
fn copy_prefix(dst: &mut [f64], src: &[f64]) {
    let n = src.len().min(dst.len());
    dst[..n].copy_from_slice(&src[..n]);
}

/// One captured MHE record (a view into [`MheTrace`]); accessors mirror
/// [`mhe_core::MheRecord`]. Stage j of a window is time t − M_t + j.
#[derive(Debug, Clone, Copy)]
pub struct MheStep<'a> {
    trace: &'a MheTrace,
    t: usize,
}

impl<'a> MheStep<'a> {
    fn s(&self) -> &'a MheScalars {
        &self.trace.scalars[self.t]
    }
    fn seq(&self, rows: &'a Rows, width: usize) -> &'a [f64] {
        &rows.row(self.t)[..self.window() * width]
    }
    /// The estimator's time step t (equals the loop's t when the estimator started at 0).
    pub fn t(&self) -> usize {
        self.s().t
    }
    /// Window length M_t = min(M, t).
    pub fn window(&self) -> usize {
        self.s().window
    }
    /// Iterations K of Φ run.
    pub fn iterations(&self) -> usize {
        self.s().iterations
    }
    /// Status of the K iterations.
    pub fn status(&self) -> RunStatus {
        self.s().status
    }
    /// V_MHE (eq. 9) at the K-th iterate.
    pub fn cost_k(&self) -> f64 {
        self.s().cost_k
    }
    /// V_MHE at the exact optimum (exact solve on).
    pub fn cost_exact(&self) -> Option<f64> {
        self.s().cost_exact
    }
    /// ε_t = ‖zᴷ_t − z*_t‖₂ in condensed coordinates (exact solve on).
    pub fn epsilon(&self) -> Option<f64> {
        self.s().epsilon
    }
    /// ‖z⁰_t − z*_t‖₂ (exact solve on).
    pub fn initial_error(&self) -> Option<f64> {
        self.s().initial_error
    }
    /// Largest violation of Z by zᴷ_t.
    pub fn violation(&self) -> f64 {
        self.s().violation
    }
    /// The prior x^prior_{t−M_t} used.
    pub fn prior(&self) -> &'a [f64] {
        self.trace.prior.row(self.t)
    }
    /// The window inputs u_{t−M_t..t−1}, flat, oldest first.
    pub fn u_flat(&self) -> &'a [f64] {
        self.seq(&self.trace.u, self.trace.dims.nu)
    }
    /// The window measurements y_{t−M_t..t−1}, flat, oldest first.
    pub fn y_flat(&self) -> &'a [f64] {
        self.seq(&self.trace.y, self.trace.dims.ny)
    }
    /// u_{t−M_t+j}.
    pub fn u(&self, j: usize) -> Option<&'a [f64]> {
        stage(self.u_flat(), self.trace.dims.nu, j)
    }
    /// y_{t−M_t+j}.
    pub fn y(&self, j: usize) -> Option<&'a [f64]> {
        stage(self.y_flat(), self.trace.dims.ny, j)
    }
    /// x̂ᴷ_{t−M_t|t}.
    pub fn x_start_k(&self) -> &'a [f64] {
        self.trace.x_start_k.row(self.t)
    }
    /// The ŵ sequence of the K-th iterate, flat, oldest first.
    pub fn w_k_flat(&self) -> &'a [f64] {
        self.seq(&self.trace.w_k, self.trace.dims.nw())
    }
    /// ŵᴷ_{t−M_t+j|t} = (ŵ¹, ŵ²).
    pub fn w_k(&self, j: usize) -> Option<&'a [f64]> {
        stage(self.w_k_flat(), self.trace.dims.nw(), j)
    }
    /// ŵ²ᴷ_{t−M_t+j|t}: the estimated measurement noise (Fig. 2(c)).
    pub fn w2_k(&self, j: usize) -> Option<&'a [f64]> {
        self.w_k(j).map(|w| &w[self.trace.dims.nw1..])
    }
    /// x̂ᴷ_{t|t}: the estimate the estimator returned.
    pub fn x_hat(&self) -> &'a [f64] {
        self.trace.x_hat.row(self.t)
    }
    /// x̂*_{t−M_t|t} (exact solve on).
    pub fn x_start_exact(&self) -> Option<&'a [f64]> {
        self.s()
            .has_exact
            .then(|| self.trace.x_start_exact.row(self.t))
    }
    /// The exact ŵ* sequence, flat (exact solve on).
    pub fn w_exact_flat(&self) -> Option<&'a [f64]> {
        self.s()
            .has_exact
            .then(|| self.seq(&self.trace.w_exact, self.trace.dims.nw()))
    }
    /// ŵ*_{t−M_t+j|t} (exact solve on).
    pub fn w_exact(&self, j: usize) -> Option<&'a [f64]> {
        self.w_exact_flat()
            .and_then(|w| stage(w, self.trace.dims.nw(), j))
    }
    /// x̂*_{t|t}: the exact MHE's estimate (exact solve on).
    pub fn x_hat_exact(&self) -> Option<&'a [f64]> {
        self.s()
            .has_exact
            .then(|| self.trace.x_hat_exact.row(self.t))
    }
}

fn stage(v: &[f64], width: usize, j: usize) -> Option<&[f64]> {
    v.get(j * width..(j + 1) * width)
}

/// The library's own JSON layout of a trace (feature `serde`; `trace.json` does not use it).
#[cfg(feature = "serde")]
mod serialise {
    use super::{MheStep, Trace};
    use serde::ser::{SerializeSeq, SerializeStruct};
    use serde::{Serialize, Serializer};

    /// A flat sequence serialised as an array of stages.
    struct Stages<'a>(&'a [f64], usize);

    impl Serialize for Stages<'_> {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            let Stages(v, width) = *self;
            let count = v.len().checked_div(width).unwrap_or(0);
            let mut seq = s.serialize_seq(Some(count))?;
            for j in 0..count {
                seq.serialize_element(&v[j * width..(j + 1) * width])?;
            }
            seq.end()
        }
    }

    impl Serialize for MheStep<'_> {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            let d = self.trace.dims;
            let nw = d.nw();
            let mut st = s.serialize_struct("MheRecord", 18)?;
            st.serialize_field("t", &self.t())?;
            st.serialize_field("window", &self.window())?;
            st.serialize_field("prior", self.prior())?;
            st.serialize_field("u", &Stages(self.u_flat(), d.nu))?;
            st.serialize_field("y", &Stages(self.y_flat(), d.ny))?;
            st.serialize_field("x_start_k", self.x_start_k())?;
            st.serialize_field("w_k", &Stages(self.w_k_flat(), nw))?;
            st.serialize_field("x_hat", self.x_hat())?;
            st.serialize_field("x_start_exact", &self.x_start_exact())?;
            st.serialize_field("w_exact", &self.w_exact_flat().map(|w| Stages(w, nw)))?;
            st.serialize_field("x_hat_exact", &self.x_hat_exact())?;
            st.serialize_field("epsilon", &self.epsilon())?;
            st.serialize_field("initial_error", &self.initial_error())?;
            st.serialize_field("cost_k", &self.cost_k())?;
            st.serialize_field("cost_exact", &self.cost_exact())?;
            st.serialize_field("violation", &self.violation())?;
            st.serialize_field("iterations", &self.iterations())?;
            st.serialize_field("status", &self.status())?;
            st.end()
        }
    }

    /// One step of a [`Trace`] for serialisation.
    struct StepOut<'a> {
        trace: &'a Trace,
        t: usize,
    }

    impl Serialize for StepOut<'_> {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            let (tr, t) = (self.trace, self.t);
            let mut st = s.serialize_struct("Step", 11)?;
            st.serialize_field("t", &t)?;
            st.serialize_field("x", tr.x.row(t))?;
            st.serialize_field("u", tr.u.row(t))?;
            st.serialize_field("y", tr.y.row(t))?;
            st.serialize_field("w", tr.w.row(t))?;
            st.serialize_field("x_hat", tr.x_hat.row(t))?;
            st.serialize_field("e", tr.e.row(t))?;
            st.serialize_field("e_norm", &tr.e_norm[t])?;
            st.serialize_field("x_norm", &tr.x_norm[t])?;
            st.serialize_field("w_norm", &tr.w_norm[t])?;
            st.serialize_field("mhe", &tr.mhe_step(t))?;
            st.end()
        }
    }

    struct StepsOut<'a>(&'a Trace);

    impl Serialize for StepsOut<'_> {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            let mut seq = s.serialize_seq(Some(self.0.len))?;
            for t in 0..self.0.len {
                seq.serialize_element(&StepOut { trace: self.0, t })?;
            }
            seq.end()
        }
    }

    /// Summary statistics written next to the steps.
    #[derive(Serialize)]
    struct Summary {
        sup_norm_e: f64,
        sup_norm_x: f64,
        sup_norm_w: f64,
        tail_mean_e: Option<f64>,
        tail_mean_x: Option<f64>,
        tail_mean_w: Option<f64>,
        tail_mean_epsilon: Option<f64>,
    }

    #[derive(Serialize)]
    struct DimsOut {
        nx: usize,
        nu: usize,
        ny: usize,
        nw1: usize,
        nw2: usize,
    }

    impl Serialize for Trace {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            let mut st = s.serialize_struct("Trace", 6)?;
            st.serialize_field(
                "dims",
                &DimsOut {
                    nx: self.nx,
                    nu: self.nu,
                    ny: self.ny,
                    nw1: self.nw1,
                    nw2: self.nw - self.nw1,
                },
            )?;
            st.serialize_field("steps", &self.steps)?;
            st.serialize_field("len", &self.len)?;
            st.serialize_field(
                "summary",
                &Summary {
                    sup_norm_e: self.sup_norm_e(),
                    sup_norm_x: self.sup_norm_x(),
                    sup_norm_w: self.sup_norm_w(),
                    tail_mean_e: self.tail_mean_e(),
                    tail_mean_x: self.tail_mean_x(),
                    tail_mean_w: self.tail_mean_w(),
                    tail_mean_epsilon: self.tail_mean_epsilon(),
                },
            )?;
            st.serialize_field("x_final", self.x.row(self.len))?;
            st.serialize_field("records", &StepsOut(self))?;
            st.end()
        }
    }
}
