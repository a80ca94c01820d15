//! The sub-optimal MHE of Alg. 1 (steps 1–3): K warm-started iterations of Φ per time step.

use std::sync::Arc;

use faer::Mat;
use lti_model::LtiSystem;
use qp_iter::active_set::ExactSolver;
use qp_iter::{IterationMap, ParametricQp, run_fixed};

pub use crate::settings::WarmStart;

use crate::error::{MheError, Result};
use crate::problem::{Dims, MheProblem, MheSets, MheWeights, WindowLayout, pow_i32};
use crate::record::MheRecord;

/// The estimator trait of the closed loop (its own crate, `loop-traits`, so that a user's
/// estimator needs no QP solver); re-exported here.
pub use loop_traits::Estimator;

/// Settings of [`MheEstimator`]: built by [`MheConfig::new`] with the paper's warm start
/// and no exact solve, changed by the `with_*` methods (new settings will not break your
/// code), or read from a scenario file by `MheSettings`.
///
/// ```
/// use faer::{Mat, mat};
/// use mhe_core::{MheConfig, WarmStart};
/// use qp_iter::Iterations;
/// let k = Iterations::new(20)?; // K = 0 is refused here, with `IterationsError::Zero`
/// let cfg = MheConfig::new(5, 0.8, Mat::identity(2, 2), Mat::identity(3, 3), mat![[1.0]], k)
///     .with_warm_start(WarmStart::Paper)
///     .with_exact_solve(true);
/// assert_eq!((cfg.horizon, cfg.iterations.get(), cfg.exact_solve), (5, 20, true));
/// # Ok::<(), qp_iter::IterationsError>(())
/// ```
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct MheConfig {
    /// Horizon M ≥ 1.
    pub horizon: usize,
    /// η ∈ [0, 1) of cost (9).
    pub eta: f64,
    /// Prior weight P ≻ 0 (n_x × n_x).
    pub p: Mat<f64>,
    /// Disturbance weight Q ≻ 0 (n_w × n_w, n_w = n_w1 + n_w2).
    pub q: Mat<f64>,
    /// Output weight R ≻ 0 (n_y × n_y).
    pub r: Mat<f64>,
    /// Iterations K ≥ 1 of Φ per time step.
    pub iterations: qp_iter::Iterations,
    /// Warm-start rule Σ_t (the paper's is the certified default).
    pub warm_start: WarmStart,
    /// Also solve ℙ_t exactly each step and record ε_t (analysis runs): the warm-started
    /// active-set solver of `qp_iter::active_set` (allocation-free), Clarabel as fallback.
    pub exact_solve: bool,
}

impl MheConfig {
    /// Horizon M, η of cost (9), the weights P, Q, R and K iterations per step, with the
    /// paper's warm start Σ_t and no exact solve. Checked when an estimator is built.
    pub fn new(
        horizon: usize,
        eta: f64,
        p: Mat<f64>,
        q: Mat<f64>,
        r: Mat<f64>,
        iterations: qp_iter::Iterations,
    ) -> Self {
        Self {
            horizon,
            eta,
            p,
            q,
            r,
            iterations,
            warm_start: WarmStart::Paper,
            exact_solve: false,
        }
    }

    /// The warm-start rule Σ_t.
    #[must_use]
    pub fn with_warm_start(mut self, warm_start: WarmStart) -> Self {
        self.warm_start = warm_start;
        self
    }

    /// Also solve ℙ_t exactly each step and record ε_t.
    #[must_use]
    pub fn with_exact_solve(mut self, exact_solve: bool) -> Self {
        self.exact_solve = exact_solve;
        self
    }

    /// The weights (η, P, Q, R).
    pub fn weights(&self) -> MheWeights {
        MheWeights {
            eta: self.eta,
            p: self.p.clone(),
            q: self.q.clone(),
            r: self.r.clone(),
        }
    }
}

/// Fixed-capacity ring buffer of equal-width vectors (allocation-free after `new`).
#[derive(Debug, Clone)]
struct Ring {
    data: Vec<f64>,
    width: usize,
    cap: usize,
    len: usize,
    next: usize,
}

impl Ring {
    fn new(width: usize, cap: usize) -> Self {
        Self {
            data: vec![0.0; width * cap],
            width,
            cap,
            len: 0,
            next: 0,
        }
    }
    fn push(&mut self, v: &[f64]) {
        if self.cap == 0 {
            return;
        }
        let w = self.width;
        self.data[self.next * w..(self.next + 1) * w].copy_from_slice(v);
        self.next = (self.next + 1) % self.cap;
        self.len = (self.len + 1).min(self.cap);
    }
    /// The k-th newest entry (k = 1 is the newest); caller guarantees 1 ≤ k ≤ len.
    fn back(&self, k: usize) -> &[f64] {
        debug_assert!(k >= 1 && k <= self.len);
        let idx = (self.next + self.cap - k) % self.cap;
        &self.data[idx * self.width..(idx + 1) * self.width]
    }
    fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
    }
}

/// Row-major copies of the model and weights for allocation-free loops on tiny matrices.
#[derive(Debug, Clone)]
pub(crate) struct HotModel {
    pub(crate) d: Dims,
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    e: Vec<f64>,
    f: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
    r: Vec<f64>,
    eta: f64,
}

use lti_model::matrix::row_major;

/// y += M x for row-major M (rows × cols).
#[inline]
fn mul_add(m: &[f64], rows: usize, cols: usize, x: &[f64], y: &mut [f64]) {
    for i in 0..rows {
        let row = &m[i * cols..(i + 1) * cols];
        let mut acc = 0.0;
        for (a, b) in row.iter().zip(x) {
            acc += a * b;
        }
        y[i] += acc;
    }
}

/// vᵀ W v for row-major square W.
#[inline]
fn quad(w: &[f64], v: &[f64]) -> f64 {
    let n = v.len();
    let mut s = 0.0;
    for i in 0..n {
        let mut acc = 0.0;
        for j in 0..n {
            acc += w[i * n + j] * v[j];
        }
        s += v[i] * acc;
    }
    s
}

impl HotModel {
    pub(crate) fn new(sys: &LtiSystem, w: &MheWeights) -> Self {
        Self {
            d: Dims::of(sys),
            a: row_major(sys.a()),
            b: row_major(sys.b()),
            c: row_major(sys.c()),
            e: row_major(sys.e()),
            f: row_major(sys.f()),
            p: row_major(w.p.as_ref()),
            q: row_major(w.q.as_ref()),
            r: row_major(w.r.as_ref()),
            eta: w.eta,
        }
    }

    /// x⁺ = A x + B u + E w¹ into `out`.
    #[inline]
    pub(crate) fn step(&self, x: &[f64], u: &[f64], w1: &[f64], out: &mut [f64]) {
        let d = self.d;
        out.fill(0.0);
        mul_add(&self.a, d.nx, d.nx, x, out);
        mul_add(&self.b, d.nx, d.nu, u, out);
        mul_add(&self.e, d.nx, d.nw1, w1, out);
    }

    /// x̂_{t|t}: propagate x̂₀ of `z` through the window (inputs from θ).
    /// `x` is the output, `tmp` scratch, both of length n_x.
    pub(crate) fn propagate(
        &self,
        lay: WindowLayout,
        z: &[f64],
        theta: &[f64],
        x: &mut [f64],
        tmp: &mut [f64],
    ) {
        let d = self.d;
        x.copy_from_slice(&z[..d.nx]);
        for j in 0..lay.m {
            let uo = lay.u_offset(j);
            let wo = lay.w_offset(j);
            self.step(x, &theta[uo..uo + d.nu], &z[wo..wo + d.nw1], tmp);
            x.copy_from_slice(tmp);
        }
    }

    /// V_MHE of eq. (9) at condensed z (allocation-free; scratch `x`, `tmp` of length n_x,
    /// `res` of length max(n_x, n_y)).
    pub(crate) fn cost(
        &self,
        lay: WindowLayout,
        z: &[f64],
        theta: &[f64],
        x: &mut [f64],
        tmp: &mut [f64],
        res: &mut [f64],
    ) -> f64 {
        let d = self.d;
        let m = lay.m;
        let nx = d.nx;
        x.copy_from_slice(&z[..nx]);
        for i in 0..nx {
            res[i] = z[i] - theta[i];
        }
        let mut v = 2.0 * self.eta.powi(pow_i32(m)) * quad(&self.p, &res[..nx]);
        for j in 0..m {
            let decay = self.eta.powi(pow_i32(m - 1 - j));
            let wo = lay.w_offset(j);
            let w = &z[wo..wo + d.nw()];
            let yo = lay.y_offset(j);
            // ŷ_j − y_j = C x̂_j + F ŵ²_j − y_j.
            let r = &mut res[..d.ny];
            for i in 0..d.ny {
                r[i] = -theta[yo + i];
            }
            mul_add(&self.c, d.ny, nx, x, r);
            mul_add(&self.f, d.ny, d.nw2, &w[d.nw1..], r);
            v += decay * (2.0 * quad(&self.q, w) + quad(&self.r, r));
            let uo = lay.u_offset(j);
            self.step(x, &theta[uo..uo + d.nu], &w[..d.nw1], tmp);
            x.copy_from_slice(tmp);
        }
        v
    }
}

pub(crate) fn check_vec(name: &'static str, v: &[f64], n: usize) -> Result<()> {
    if v.len() != n {
        return Err(MheError::Length {
            name,
            expected: n,
            actual: v.len(),
        });
    }
    if let Some(index) = v.iter().position(|x| !x.is_finite()) {
        return Err(MheError::NonFinite {
            name,
            index,
            value: v[index],
        });
    }
    Ok(())
}

/// The sub-optimal MHE of Alg. 1, generic over the iteration map Φ.
///
/// One Φ (and its state) per window length m = 0..M, all built at construction; a time
/// step loads θ, warm-starts, runs exactly K iterations and propagates x̂ᴷ_{t−M_t|t}
/// through the window. See the crate documentation for the conventions.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::LtiSystem;
/// use qp_iter::pg::{ProjectedGradient, StepRule};
/// use mhe_core::{Estimator, MheConfig, MheEstimator, MheSets, WarmStart};
/// let sys = LtiSystem::new(mat![[0.9, 0.1], [0.0, 0.8]], mat![[0.0], [1.0]], mat![[1.0, 0.0]]).unwrap();
/// let k = qp_iter::Iterations::new(20).unwrap();
/// let cfg = MheConfig::new(3, 0.8, Mat::identity(2, 2), Mat::identity(3, 3), mat![[1.0]], k)
///     .with_exact_solve(true);
/// let mut mhe = MheEstimator::new(&sys, &MheSets::unconstrained(&sys), &cfg, &[1.0, -1.0],
///     |qp| ProjectedGradient::new(qp, StepRule::Optimal)).unwrap();
/// assert_eq!(mhe.estimate().unwrap(), &[1.0, -1.0]); // t = 0: the prior
/// mhe.push(&[0.5], &[0.7]).unwrap();
/// let x1 = mhe.estimate().unwrap().to_vec();
/// let rec = mhe.last_record();
/// assert_eq!((rec.t, rec.window), (1, 1));
/// assert!(rec.epsilon.unwrap() <= rec.initial_error.unwrap());
/// # let _ = x1;
/// ```
#[derive(Debug)]
pub struct MheEstimator<M: IterationMap> {
    /// ℙ_t for every window length, built once and shared (a sweep's runs, the
    /// certificate and the simulation read the same one).
    problem: Arc<MheProblem>,
    config: MheConfig,
    maps: Vec<M>,
    states: Vec<M::State>,
    model: HotModel,
    initial_prior: Vec<f64>,
    t: usize,
    estimated: bool,
    u_ring: Ring,
    y_ring: Ring,
    estimates: Ring,
    theta: Vec<f64>,
    z0: Vec<f64>,
    zk: Vec<f64>,
    zstar: Vec<f64>,
    x_work: Vec<f64>,
    x_tmp: Vec<f64>,
    res: Vec<f64>,
    x_hat_exact: Vec<f64>,
    record: MheRecord,
    references: Vec<ExactSolver>,
    /// Where the exact solve of the next step starts (valid if `exact_start`): z*_t with a
    /// zero newest stage while the window grows, shifted by one stage after.
    zstar_start: Vec<f64>,
    exact_start: bool,
}

impl<M: IterationMap> MheEstimator<M> {
    /// Validates everything, builds ℙ_t for m = 0..M and one Φ per window length with
    /// `factory`, and sets t = 0 with prior x̄₀ = `prior`.
    ///
    /// Errors name the field: `horizon` (M = 0), `eta` (∉ [0, 1)),
    /// `P`/`Q`/`R` (shape, not positive definite), `prior` (length, NaN), the sets
    /// (dimension), and the factory's error.
    pub fn new<F>(
        sys: &LtiSystem,
        sets: &MheSets,
        config: &MheConfig,
        prior: &[f64],
        factory: F,
    ) -> Result<Self>
    where
        F: Fn(ParametricQp) -> qp_iter::Result<M>,
    {
        lti_model::work_count::record(lti_model::work_count::Work::EstimatorBuilt);
        let dims = Dims::of(sys);
        crate::problem::validate_problem(dims, config.horizon, &config.weights(), sets)?;
        check_vec("prior", prior, dims.nx)?;
        let problem = MheProblem::new(sys, config.horizon, &config.weights(), sets)?;
        Self::from_problem(
            Arc::new(problem),
            config.iterations,
            config.warm_start,
            config.exact_solve,
            prior,
            factory,
        )
    }

    /// The estimator on a problem built once and shared ([`MheProblem`] carries the plant,
    /// M, η, P, Q, R and the sets): only what a run chooses is given here — K, the warm
    /// start, the exact solve of each ℙ_t — so many runs (a sweep, the certificate's
    /// checks) share one set of windows.
    ///
    /// ```
    /// use std::sync::Arc;
    /// use faer::{mat, Mat};
    /// use lti_model::LtiSystem;
    /// use mhe_core::{Estimator, MheEstimator, MheProblem, MheSets, MheWeights, WarmStart};
    /// let sys = LtiSystem::new(mat![[0.9, 0.1], [0.0, 0.8]], mat![[0.0], [1.0]], mat![[1.0, 0.0]]).unwrap();
    /// let w = MheWeights { eta: 0.8, p: Mat::identity(2, 2), q: Mat::identity(3, 3), r: mat![[1.0]] };
    /// let problem = Arc::new(MheProblem::new(&sys, 3, &w, &MheSets::unconstrained(&sys)).unwrap());
    /// let k = |n| qp_iter::Iterations::new(n).unwrap();
    /// let mut a = MheEstimator::from_problem(problem.clone(), k(20), WarmStart::Paper, false,
    ///     &[1.0, -1.0], |qp| qp_iter::Method::FISTA.build(qp)).unwrap();
    /// let mut b = MheEstimator::from_problem(problem, k(5), WarmStart::Paper, false,
    ///     &[1.0, -1.0], |qp| qp_iter::Method::PG.build(qp)).unwrap();
    /// assert_eq!(a.estimate().unwrap(), b.estimate().unwrap()); // t = 0: the prior
    /// ```
    pub fn from_problem<F>(
        problem: Arc<MheProblem>,
        iterations: qp_iter::Iterations,
        warm_start: WarmStart,
        exact_solve: bool,
        prior: &[f64],
        factory: F,
    ) -> Result<Self>
    where
        F: Fn(ParametricQp) -> qp_iter::Result<M>,
    {
        lti_model::work_count::record(lti_model::work_count::Work::EstimatorBuilt);
        let dims = problem.dims();
        check_vec("prior", prior, dims.nx)?;
        let weights = problem.weights();
        let config = MheConfig::new(
            problem.horizon(),
            weights.eta,
            weights.p.clone(),
            weights.q.clone(),
            weights.r.clone(),
            iterations,
        )
        .with_warm_start(warm_start)
        .with_exact_solve(exact_solve);
        let maps = problem
            .windows()
            .iter()
            .map(|w| factory(w.qp().clone()))
            .collect::<qp_iter::Result<Vec<M>>>()?;
        for (m, (map, w)) in maps.iter().zip(problem.windows()).enumerate() {
            if map.problem().n() != w.layout().nz()
                || map.problem().n_theta() != w.layout().n_theta()
            {
                return Err(MheError::Unsupported {
                    what: format!(
                        "the factory returned a map for a different problem at window length {m}"
                    ),
                    hint: "build Φ from the ParametricQp the factory is given".into(),
                });
            }
        }
        let states = maps.iter().map(IterationMap::new_state).collect();
        let references = if exact_solve {
            problem
                .windows()
                .iter()
                .map(|w| ExactSolver::new(w.qp()))
                .collect::<qp_iter::Result<Vec<_>>>()?
        } else {
            Vec::new()
        };
        let big_m = config.horizon;
        let full = WindowLayout { dims, m: big_m };
        let mut z0 = vec![0.0; full.nz()];
        z0[..dims.nx].copy_from_slice(prior);
        Ok(Self {
            model: HotModel::new(problem.system(), weights),
            problem,
            config,
            maps,
            states,
            initial_prior: prior.to_vec(),
            t: 0,
            estimated: false,
            u_ring: Ring::new(dims.nu, big_m),
            y_ring: Ring::new(dims.ny, big_m),
            estimates: Ring::new(dims.nx, big_m),
            theta: vec![0.0; full.n_theta()],
            z0,
            zk: vec![0.0; full.nz()],
            zstar: vec![0.0; full.nz()],
            x_work: vec![0.0; dims.nx],
            x_tmp: vec![0.0; dims.nx],
            res: vec![0.0; dims.nx.max(dims.ny)],
            x_hat_exact: vec![0.0; dims.nx],
            record: MheRecord::with_capacity(dims, big_m),
            references,
            zstar_start: vec![0.0; full.nz()],
            exact_start: false,
        })
    }

    /// Restarts at t = 0 with a new initial prior x̄₀, keeping every allocation (for
    /// Monte-Carlo runs). On error nothing changes.
    pub fn reset(&mut self, prior: &[f64]) -> Result<()> {
        check_vec("prior", prior, self.model.d.nx)?;
        self.initial_prior.copy_from_slice(prior);
        self.t = 0;
        self.estimated = false;
        self.u_ring.clear();
        self.y_ring.clear();
        self.estimates.clear();
        self.z0.fill(0.0);
        self.z0[..prior.len()].copy_from_slice(prior);
        for r in &mut self.references {
            r.reset();
        }
        self.exact_start = false;
        Ok(())
    }

    /// The problem ℙ_t for every window length (H_c, F_c, W_m, L_Φ, …).
    pub fn problem(&self) -> &MheProblem {
        &self.problem
    }
    /// The shared problem (to build another estimator on the same windows).
    pub fn shared_problem(&self) -> &Arc<MheProblem> {
        &self.problem
    }
    /// The configuration.
    pub fn config(&self) -> &MheConfig {
        &self.config
    }
    /// Φ for window length m (None if m > M); its certificate is φ(K) for that window.
    pub fn map(&self, m: usize) -> Option<&M> {
        self.maps.get(m)
    }
    /// All maps, indexed by window length.
    pub fn maps(&self) -> &[M] {
        &self.maps
    }
    /// Current time t (number of (u, y) pairs pushed).
    pub fn t(&self) -> usize {
        self.t
    }
    /// Current window length M_t = min(M, t).
    pub fn window_len(&self) -> usize {
        self.t.min(self.config.horizon)
    }
    /// The initial prior x̄₀.
    pub fn initial_prior(&self) -> &[f64] {
        &self.initial_prior
    }
    /// The record of the last successful [`MheEstimator::estimate`].
    pub fn last_record(&self) -> &MheRecord {
        &self.record
    }
    /// The warm start z⁰_t that the next estimate at the current t starts from.
    pub fn warm_start_point(&self) -> &[f64] {
        let lay = WindowLayout {
            dims: self.model.d,
            m: self.window_len(),
        };
        &self.z0[..lay.nz()]
    }
    /// The K-th iterate zᴷ_t of the last estimate at the current t (None if not estimated yet).
    pub fn iterate(&self) -> Option<&[f64]> {
        let lay = WindowLayout {
            dims: self.model.d,
            m: self.window_len(),
        };
        self.estimated.then(|| &self.zk[..lay.nz()])
    }
    /// The parameter θ_t of the current window (valid after `estimate`).
    pub fn theta(&self) -> &[f64] {
        let lay = WindowLayout {
            dims: self.model.d,
            m: self.window_len(),
        };
        &self.theta[..lay.n_theta()]
    }

    /// Step 1 of Alg. 1: K iterations of Φ on ℙ_t from z⁰_t; returns x̂ᴷ_{t|t}.
    ///
    /// Allocation-free (with `exact_solve` on too, unless the active set falls back to
    /// Clarabel). Idempotent at a given t (it always
    /// starts from the same z⁰_t). Errors only if the exact solve fails, in which case
    /// the record and the estimator are unchanged.
    pub fn estimate(&mut self) -> Result<&[f64]> {
        let t = self.t;
        let big_m = self.config.horizon;
        let m = t.min(big_m);
        let d = self.model.d;
        let window = &self.problem.windows()[m];
        let lay = window.layout();
        let (nz, nth) = (lay.nz(), lay.n_theta());

        // θ_t = (prior, u_{t−m..t−1}, y_{t−m..t−1}).
        {
            let theta = &mut self.theta[..nth];
            if t <= big_m {
                theta[..d.nx].copy_from_slice(&self.initial_prior);
            } else {
                theta[..d.nx].copy_from_slice(self.estimates.back(big_m));
            }
            for j in 0..m {
                let uo = lay.u_offset(j);
                theta[uo..uo + d.nu].copy_from_slice(self.u_ring.back(m - j));
                let yo = lay.y_offset(j);
                theta[yo..yo + d.ny].copy_from_slice(self.y_ring.back(m - j));
            }
        }
        let theta = &self.theta[..nth];

        let map = &self.maps[m];
        let state = &mut self.states[m];
        map.load(state, theta);
        map.warm_start(state, &self.z0[..nz], None);
        let run = run_fixed(map, state, self.config.iterations.get());
        let zk = &mut self.zk[..nz];
        zk.copy_from_slice(map.iterate(state));
        // Box and (with bounded 𝒳 / 𝒴) the general rows for this θ; 0 for PG / FISTA.
        let violation = map.violation(state);
        let cost_k = self.model.cost(
            lay,
            zk,
            theta,
            &mut self.x_work,
            &mut self.x_tmp,
            &mut self.res,
        );
        self.model
            .propagate(lay, zk, theta, &mut self.x_work, &mut self.x_tmp);

        let mut exact = None;
        if let Some(reference) = self.references.get_mut(m) {
            let to_error = |e: qp_iter::QpError| MheError::Reference {
                t,
                reason: e.to_string(),
            };
            if self.exact_start {
                reference
                    .warm_start(&self.zstar_start[..nz])
                    .map_err(to_error)?;
            }
            let z_star = reference.solve(theta).map_err(to_error)?;
            let zs = &mut self.zstar[..nz];
            zs.copy_from_slice(z_star);
            let eps = dist(zk, zs);
            let eps0 = dist(&self.z0[..nz], zs);
            let cost = self.model.cost(
                lay,
                zs,
                theta,
                &mut self.x_hat_exact,
                &mut self.x_tmp,
                &mut self.res,
            );
            self.model
                .propagate(lay, zs, theta, &mut self.x_hat_exact, &mut self.x_tmp);
            exact = Some((cost, eps, eps0));
        }

        self.record.begin(t, m, theta, run.iterations);
        self.record
            .set_iterate(zk, &self.x_work, run.status, cost_k, violation);
        if let Some((cost, eps, eps0)) = exact {
            self.record
                .set_exact(&self.zstar[..nz], &self.x_hat_exact, cost, eps, eps0);
        }
        self.estimated = true;
        Ok(self.record.x_hat())
    }

    /// Steps 2–3 of Alg. 1: warm start Σ_t, prior ring buffer and Υ for (u_t, y_t); t ← t + 1.
    ///
    /// Runs [`MheEstimator::estimate`] first if it was not run at this t (the prior ring
    /// buffer and the warm start need x̂ᴷ_{t|t} and zᴷ_t). Validates `u` and `y` before
    /// changing anything.
    pub fn push(&mut self, u: &[f64], y: &[f64]) -> Result<()> {
        let d = self.model.d;
        check_vec("u", u, d.nu)?;
        check_vec("y", y, d.ny)?;
        if !self.estimated {
            self.estimate()?;
        }
        let t = self.t;
        let big_m = self.config.horizon;
        let m = t.min(big_m);
        let lay = WindowLayout { dims: d, m };
        let nz = lay.nz();
        let nw = d.nw();
        if t < big_m {
            // Σ_t = blkdiag(I, 0): keep the variables, zero-fill the new (newest) stage.
            self.z0[..nz].copy_from_slice(&self.zk[..nz]);
            self.z0[nz..nz + nw].fill(0.0);
        } else {
            match self.config.warm_start {
                WarmStart::Paper => self.z0[..nz].copy_from_slice(&self.zk[..nz]),
                WarmStart::Shifted => {
                    // x̂₀ ← A x̂₀ + B u_{t−M} + E ŵ¹_{t−M}; drop the oldest stage; zero the newest.
                    let uo = lay.u_offset(0);
                    let wo = lay.w_offset(0);
                    self.model.step(
                        &self.zk[..d.nx],
                        &self.theta[uo..uo + d.nu],
                        &self.zk[wo..wo + d.nw1],
                        &mut self.x_tmp,
                    );
                    self.z0[..d.nx].copy_from_slice(&self.x_tmp);
                    self.z0[d.nx..nz - nw].copy_from_slice(&self.zk[d.nx + nw..nz]);
                    self.z0[nz - nw..nz].fill(0.0);
                }
            }
        }
        if !self.references.is_empty() {
            // The exact solve of ℙ_{t+1} starts from ℙ_t's minimiser moved to the next
            // window (its working set is mostly right; the answer does not depend on it).
            let zs = &self.zstar[..nz];
            let start = &mut self.zstar_start;
            if t < big_m {
                start[..nz].copy_from_slice(zs);
                start[nz..nz + nw].fill(0.0);
            } else {
                let uo = lay.u_offset(0);
                let wo = lay.w_offset(0);
                self.model.step(
                    &zs[..d.nx],
                    &self.theta[uo..uo + d.nu],
                    &zs[wo..wo + d.nw1],
                    &mut self.x_tmp,
                );
                start[..d.nx].copy_from_slice(&self.x_tmp);
                start[d.nx..nz - nw].copy_from_slice(&zs[d.nx + nw..nz]);
                start[nz - nw..nz].fill(0.0);
            }
            self.exact_start = true;
        }
        self.estimates.push(self.record.x_hat());
        self.u_ring.push(u);
        self.y_ring.push(y);
        self.t += 1;
        self.estimated = false;
        Ok(())
    }
}

use lti_model::vecmath::dist2 as dist;

impl<M: IterationMap> Estimator for MheEstimator<M> {
    type Error = MheError;
    fn estimate(&mut self) -> Result<&[f64]> {
        MheEstimator::estimate(self)
    }
    fn push(&mut self, u: &[f64], y: &[f64]) -> Result<()> {
        MheEstimator::push(self, u, y)
    }
    fn nx(&self) -> usize {
        self.model.d.nx
    }
}
