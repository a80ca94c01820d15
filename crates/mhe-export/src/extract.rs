//! The std estimator's numbers, copied out for `mhe-embedded` and the generated code: ℙ_t
//! of every window as the built maps hold it (H, F, q₀, the box, α, β, ρ(H + ρI)⁻¹ and
//! (H + ρI)⁻¹, the Jacobi d), and the model's A, B, E.

use anyhow::{Result, bail};
use closed_loop::scenario::ResolvedScenario;
use lti_model::LtiSystem;
use mhe_core::{MheEstimator, WarmStart};
use mpc_core::{CondensedMpc, SuboptimalMpc};
use qp_iter::kernel::{Kernel, PaddedSymmetric};
use qp_iter::{IterationMap, Method, MethodMap, ParametricQp};

/// One window's data (the fields of [`mhe_embedded::Window`], owned).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct OwnedWindow {
    pub n: usize,
    pub n_theta: usize,
    pub h: Vec<f64>,
    pub m_rho: Vec<f64>,
    pub m_inv: Vec<f64>,
    pub q0: Vec<f64>,
    pub f: Vec<f64>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub scaling: Vec<f64>,
    pub step: f64,
    pub momentum: f64,
    pub inv_rho: f64,
    pub relaxation: f64,
    /// PG and FISTA from the std crossover: the structured product's factors (`h` empty).
    pub structured: Option<OwnedStructured>,
}

/// The factors of one window's structured H_c (the fields of
/// [`mhe_embedded::Structured`], owned): the numbers `mhe_core::structured::MheHessian`
/// builds its blocks from, with the same weight scalings (4η^m P, 4Q, 2R) computed the same
/// way, so the f64 values are its bits.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct OwnedStructured {
    pub nx: usize,
    pub ny: usize,
    pub nw1: usize,
    pub nw2: usize,
    pub order: mhe_embedded::SumOrder,
    pub a: Vec<f64>,
    pub e: Vec<f64>,
    pub c: Vec<f64>,
    pub f: Vec<f64>,
    pub q: Vec<f64>,
    pub r: Vec<f64>,
    pub p: Vec<f64>,
    pub decay: Vec<f64>,
}

/// `s·m` by columns (entry (i, j) at j·rows + i).
fn col_major(m: faer::MatRef<'_, f64>, s: f64) -> Vec<f64> {
    let r = m.nrows();
    (0..r * m.ncols()).map(|k| s * m[(k % r, k / r)]).collect()
}

/// η^k as `mhe_core` computes it (`powi` of the exponent as i32).
fn eta_pow(eta: f64, k: usize) -> f64 {
    eta.powi(i32::try_from(k).unwrap_or(i32::MAX))
}

/// The largest n_x, n_y, n_w1, n_w2 of the std fixed-size products (beyond: run-time sizes).
const FIXED_MAX: usize = 16;

impl OwnedStructured {
    /// The factors of window m (length m) of the MHE with this plant and these weights.
    pub(crate) fn new(sys: &LtiSystem, w: &mhe_core::MheWeights, m: usize) -> Self {
        let (nx, ny, nw1, nw2) = (sys.nx(), sys.ny(), sys.nw1(), sys.nw2());
        let order = if [nx, ny, nw1, nw2].iter().all(|&d| d <= FIXED_MAX) {
            mhe_embedded::SumOrder::Fixed
        } else {
            mhe_embedded::SumOrder::RunTime
        };
        Self {
            nx,
            ny,
            nw1,
            nw2,
            order,
            a: col_major(sys.a(), 1.0),
            e: col_major(sys.e(), 1.0),
            c: col_major(sys.c(), 1.0),
            f: col_major(sys.f(), 1.0),
            q: col_major(w.q.as_ref(), 4.0),
            r: col_major(w.r.as_ref(), 2.0),
            p: col_major(w.p.as_ref(), 4.0 * eta_pow(w.eta, m)),
            decay: (0..m).map(|j| eta_pow(w.eta, m - 1 - j)).collect(),
        }
    }

    /// The `mhe_embedded` view (borrowing `self`).
    #[cfg(test)]
    pub(crate) fn view(&self) -> mhe_embedded::Structured<'_, f64> {
        mhe_embedded::Structured {
            nx: self.nx,
            ny: self.ny,
            nw1: self.nw1,
            nw2: self.nw2,
            order: self.order,
            a: &self.a,
            e: &self.e,
            c: &self.c,
            f: &self.f,
            q: &self.q,
            r: &self.r,
            p: &self.p,
            decay: &self.decay,
        }
    }

    /// Whether the two workspaces fit in the estimator's work vectors of n = n_x + m n_w
    /// (as `mhe_embedded` checks).
    fn fits(&self) -> bool {
        let nw = self.nw1 + self.nw2;
        let n = self.nx + self.decay.len() * nw;
        self.decay.len() * self.ny <= n && 4 * self.nx + self.ny + 2 * nw <= n
    }
}

impl OwnedWindow {
    /// The `mhe_embedded` view (borrowing `self`; the structured factors from `st`, the
    /// view of `self.structured`).
    #[cfg(test)]
    pub(crate) fn view<'a>(
        &'a self,
        st: Option<&'a mhe_embedded::Structured<'a, f64>>,
    ) -> mhe_embedded::Window<'a, f64> {
        let w = self;
        mhe_embedded::Window {
            n: w.n,
            n_theta: w.n_theta,
            h: &w.h,
            m_rho: &w.m_rho,
            m_inv: &w.m_inv,
            q0: &w.q0,
            f: &w.f,
            lower: &w.lower,
            upper: &w.upper,
            scaling: &w.scaling,
            step: w.step,
            momentum: w.momentum,
            inv_rho: w.inv_rho,
            relaxation: w.relaxation,
            structured: st,
        }
    }
}

/// The whole problem (the fields of [`mhe_embedded::Problem`], owned).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct OwnedProblem {
    pub nx: usize,
    pub nu: usize,
    pub ny: usize,
    pub nw1: usize,
    pub nw2: usize,
    pub horizon: usize,
    pub iterations: usize,
    pub method: mhe_embedded::Method,
    pub warm_start: mhe_embedded::WarmStart,
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub e: Vec<f64>,
    pub windows: Vec<OwnedWindow>,
    /// The stored steps of the artefact's self-test (empty: no self-test).
    pub self_test: Vec<SelfTestStep>,
}

/// One stored step of the artefact's self-test: (u_t, y_t) pushed, then x̂_{t+1|t+1} of the
/// std estimator on the portable kernel.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SelfTestStep {
    pub u: Vec<f64>,
    pub y: Vec<f64>,
    pub x: Vec<f64>,
}

/// The scenario's MHE with `method` and K on the portable kernel (the arithmetic every
/// exported build repeats).
pub(crate) fn portable_estimator(
    resolved: &ResolvedScenario,
    method: Method,
    iterations: usize,
) -> Result<MheEstimator<MethodMap>> {
    let mut cfg = resolved.mhe_config()?.clone();
    cfg.iterations = qp_iter::Iterations::new(iterations)
        .map_err(|e| anyhow::anyhow!("the MHE's iterations K {e}"))?;
    cfg.exact_solve = false;
    let sc = resolved.scenario();
    // `with_kernel` reaches the maps' dense steps only: the structured product of a long
    // window (`mhe_core::structured::MheHessian`) takes FMA or not from the global kernel
    // when the problem is built. So the problem is built with the global kernel portable
    // (restored after; one build at a time in this process).
    static BUILD: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one = BUILD
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let previous = qp_iter::kernel::get_global_kernel();
    qp_iter::kernel::set_global_kernel(Kernel::portable());
    let est = MheEstimator::new(
        &sc.plant,
        resolved.mhe_sets(),
        &cfg,
        &sc.simulation.prior,
        |qp| Ok(method.build(qp)?.with_kernel(Kernel::portable())),
    );
    qp_iter::kernel::set_global_kernel(previous);
    Ok(est?)
}

/// Column-major n × n copy of a padded matrix (entry (i, j) at j·n + i).
fn unpad(m: &PaddedSymmetric) -> Vec<f64> {
    let (n, ld) = (m.n(), m.ld());
    let s = m.as_slice();
    (0..n * n).map(|k| s[(k / n) * ld + k % n]).collect()
}

fn dense_h(qp: &ParametricQp) -> Vec<f64> {
    let n = qp.n();
    let h = qp.h();
    (0..n * n).map(|k| h[(k % n, k / n)]).collect()
}

fn row_major_f(qp: &ParametricQp) -> Vec<f64> {
    let (n, nt) = (qp.n(), qp.n_theta());
    let f = qp.f();
    (0..n * nt).map(|k| f[(k / nt, k % nt)]).collect()
}

/// The plant and weights an MHE window's structured product is built from (`None`: the
/// MPC's QP, which has none).
type StructuredSource<'a> = Option<(&'a LtiSystem, &'a mhe_core::MheWeights)>;

fn window_of(
    map: &MethodMap,
    m: usize,
    src: StructuredSource<'_>,
) -> Result<(mhe_embedded::Method, OwnedWindow)> {
    let qp = map.problem();
    if qp.general().is_some() {
        bail!(
            "window m = {m} has general constraint rows (bounded sets.state or sets.output); \
             the embedded estimator covers box constraints only: drop those sets to export"
        );
    }
    let base = |qp: &ParametricQp| OwnedWindow {
        n: qp.n(),
        n_theta: qp.n_theta(),
        h: dense_h(qp),
        m_rho: Vec::new(),
        m_inv: Vec::new(),
        q0: qp.q0().to_vec(),
        f: row_major_f(qp),
        lower: qp.zset().lower().to_vec(),
        upper: qp.zset().upper().to_vec(),
        scaling: Vec::new(),
        step: 0.0,
        momentum: 0.0,
        inv_rho: 0.0,
        relaxation: 0.0,
        structured: None,
    };
    // The std map runs Hz through the structured product: export its factors, not H.
    let structured = |mut w: OwnedWindow| -> Result<OwnedWindow> {
        let Some((sys, weights)) = src else {
            bail!(
                "window m = {m} (n = {}) runs through a structured Hessian product that is \
                 not the MHE window's; the embedded code does not implement it",
                qp.n()
            );
        };
        let st = OwnedStructured::new(sys, weights, m);
        if !st.fits() {
            bail!(
                "window m = {m} (n = {}): the structured Hessian product's workspace does not \
                 fit the embedded estimator's work vectors (needs m n_y ≤ n and \
                 4n_x + n_y + 2n_w ≤ n); export a shorter horizon",
                qp.n()
            );
        }
        w.h = Vec::new();
        w.structured = Some(st);
        Ok(w)
    };
    Ok(match map {
        MethodMap::Pg(pg) => {
            let mut w = base(qp);
            if pg.is_structured() {
                w = structured(w)?;
            }
            w.step = pg.alpha();
            (mhe_embedded::Method::Pg, w)
        }
        MethodMap::Fista(f) => {
            let mut w = base(qp);
            if f.is_structured() {
                w = structured(w)?;
            }
            w.step = f.step_size();
            w.momentum = f.momentum();
            (mhe_embedded::Method::Fista, w)
        }
        MethodMap::Admm(a) => {
            let mut w = base(qp);
            let (m_rho, m_inv) = a.stored_inverses();
            w.m_rho = unpad(m_rho);
            w.m_inv = unpad(m_inv);
            w.inv_rho = 1.0 / a.rho();
            w.relaxation = a.relaxation();
            (mhe_embedded::Method::Admm, w)
        }
        MethodMap::AdmmSplit(_) => bail!(
            "window m = {m}: ADMM split on general rows is not exportable (box constraints only)"
        ),
        MethodMap::Scaled(s) => {
            let (method, mut w) = window_of(s.inner(), m, src)?;
            w.scaling = s.scaling().to_vec();
            (method, w)
        }
        other => bail!(
            "window m = {m}: method `{}` has no embedded implementation (mhe-embedded \
             implements pg, fista and admm, plain or Jacobi-scaled)",
            other.name()
        ),
    })
}

fn row_major(m: faer::MatRef<'_, f64>) -> Vec<f64> {
    lti_model::matrix::row_major(m)
}

impl OwnedProblem {
    /// The data of `est` (built by [`portable_estimator`] or any `MheEstimator<MethodMap>`).
    pub(crate) fn from_estimator(est: &MheEstimator<MethodMap>, sys: &LtiSystem) -> Result<Self> {
        let mut method = None;
        let mut windows = Vec::new();
        let weights = est.problem().weights();
        for (m, map) in est.maps().iter().enumerate() {
            let (kind, w) = window_of(map, m, Some((sys, weights)))?;
            method = Some(kind);
            windows.push(w);
        }
        let Some(method) = method else {
            bail!("the estimator has no windows");
        };
        let cfg = est.config();
        Ok(Self {
            nx: sys.nx(),
            nu: sys.nu(),
            ny: sys.ny(),
            nw1: sys.nw1(),
            nw2: sys.nw2(),
            horizon: cfg.horizon,
            iterations: cfg.iterations.get(),
            method,
            warm_start: match cfg.warm_start {
                WarmStart::Paper => mhe_embedded::WarmStart::Paper,
                WarmStart::Shifted => mhe_embedded::WarmStart::Shifted,
            },
            a: row_major(sys.a()),
            b: row_major(sys.b()),
            e: row_major(sys.e()),
            windows,
            self_test: Vec::new(),
        })
    }

    /// Records the self-test: `steps` pairs of a noise-free run of `sys` from `prior` with a
    /// deterministic input (u_i = 0.1 sin(t + i)), and x̂ of `est` (fresh: at t = 0 with
    /// the prior `prior`) after each push. M + 2 steps cover the growing window, the full
    /// one and the prior taken from the ring of past estimates.
    pub(crate) fn record_self_test(
        &mut self,
        est: &mut MheEstimator<MethodMap>,
        sys: &LtiSystem,
        prior: &[f64],
        steps: usize,
    ) -> Result<()> {
        let (a, b, c) = (row_major(sys.a()), row_major(sys.b()), row_major(sys.c()));
        let (nx, nu, ny) = (sys.nx(), sys.nu(), sys.ny());
        let mut x = prior.to_vec();
        let mut out = Vec::with_capacity(steps);
        est.estimate()?;
        for t in 0..steps {
            let u: Vec<f64> = (0..nu).map(|i| 0.1 * ((t + i) as f64).sin()).collect();
            let y: Vec<f64> = (0..ny)
                .map(|i| (0..nx).map(|j| c[i * nx + j] * x[j]).sum())
                .collect();
            est.push(&u, &y)?;
            let xh = est.estimate()?.to_vec();
            x = (0..nx)
                .map(|i| {
                    (0..nx).map(|j| a[i * nx + j] * x[j]).sum::<f64>()
                        + (0..nu).map(|j| b[i * nu + j] * u[j]).sum::<f64>()
                })
                .collect();
            out.push(SelfTestStep { u, y, x: xh });
        }
        self.self_test = out;
        Ok(())
    }

    /// n_z of the full window.
    pub(crate) fn nz(&self) -> usize {
        self.nx + self.horizon * (self.nw1 + self.nw2)
    }

    /// n_θ of the full window.
    pub(crate) fn ntheta(&self) -> usize {
        self.nx + self.horizon * (self.nu + self.ny)
    }

    /// The structured factors of the windows as `mhe_embedded` views (borrowing `self`).
    #[cfg(test)]
    pub(crate) fn structured_views(&self) -> Vec<Option<mhe_embedded::Structured<'_, f64>>> {
        self.windows
            .iter()
            .map(|w| w.structured.as_ref().map(OwnedStructured::view))
            .collect()
    }

    /// The windows as `mhe_embedded` views (borrowing `self` and `st`, from
    /// [`OwnedProblem::structured_views`]).
    #[cfg(test)]
    pub(crate) fn window_views<'a>(
        &'a self,
        st: &'a [Option<mhe_embedded::Structured<'a, f64>>],
    ) -> Vec<mhe_embedded::Window<'a, f64>> {
        self.windows
            .iter()
            .zip(st)
            .map(|(w, s)| w.view(s.as_ref()))
            .collect()
    }

    /// The problem view over `windows` (from [`OwnedProblem::window_views`]).
    #[cfg(test)]
    pub(crate) fn view<'a>(
        &'a self,
        windows: &'a [mhe_embedded::Window<'a, f64>],
    ) -> mhe_embedded::Problem<'a, f64> {
        mhe_embedded::Problem {
            nx: self.nx,
            nu: self.nu,
            ny: self.ny,
            nw1: self.nw1,
            nw2: self.nw2,
            horizon: self.horizon,
            iterations: self.iterations,
            method: self.method,
            warm_start: self.warm_start,
            a: &self.a,
            b: &self.b,
            e: &self.e,
            windows,
        }
    }
}

/// The MPC's data (the fields of [`mhe_embedded::MpcProblem`], owned).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct OwnedMpc {
    pub nx: usize,
    pub nu: usize,
    pub horizon: usize,
    pub iterations: usize,
    pub method: mhe_embedded::Method,
    pub qp: OwnedWindow,
}

/// The scenario's K_c-iteration MPC with `method` on the portable kernel, warm-started by
/// shift-and-repeat (`mpc_core::WarmStart::default()`, as the scenario's controller).
pub(crate) fn portable_mpc(
    resolved: &ResolvedScenario,
    method: Method,
    iterations: usize,
) -> Result<SuboptimalMpc<MethodMap>> {
    let mpc = resolved.mpc()?;
    let map = method
        .build(mpc.qp().clone())?
        .with_kernel(Kernel::portable());
    Ok(SuboptimalMpc::new(
        mpc,
        map,
        iterations,
        mpc_core::WarmStart::ShiftRepeatLast,
    )?)
}

impl OwnedMpc {
    /// The data of `ctrl` (built by [`portable_mpc`]) for the MPC `mpc`.
    pub(crate) fn from_controller(
        ctrl: &SuboptimalMpc<MethodMap>,
        mpc: &CondensedMpc,
    ) -> Result<Self> {
        if mpc.has_state_constraints() {
            bail!(
                "the MPC has state constraints (bounded sets.state: general rows of its QP); \
                 the embedded MPC covers box input constraints only: drop sets.state to export \
                 the MPC"
            );
        }
        if ctrl.warm_start_rule() != mpc_core::WarmStart::ShiftRepeatLast {
            bail!("the embedded MPC implements the shift-and-repeat warm start only");
        }
        let (method, qp) = window_of(ctrl.map(), 0, None).map_err(|e| {
            anyhow::anyhow!(
                "the MPC's QP: {}",
                e.to_string().replace("window m = 0", "it")
            )
        })?;
        Ok(Self {
            nx: mpc.nx(),
            nu: mpc.nu(),
            horizon: mpc.horizon(),
            iterations: ctrl.iterations(),
            method,
            qp,
        })
    }

    /// N n_u.
    pub(crate) fn nseq(&self) -> usize {
        self.horizon * self.nu
    }

    /// The `mhe_embedded` view (borrowing `self`).
    #[cfg(test)]
    pub(crate) fn view(&self) -> mhe_embedded::MpcProblem<'_, f64> {
        mhe_embedded::MpcProblem {
            nx: self.nx,
            nu: self.nu,
            horizon: self.horizon,
            iterations: self.iterations,
            method: self.method,
            qp: self.qp.view(None),
        }
    }
}
