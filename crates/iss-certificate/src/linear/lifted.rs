//! The lifted LTI system of Alg. 1 with a fixed K where no constraint is active
//! (derivation: the parent module and `docs/theory.md`, "The exact linear stability boundary").

use faer::{Mat, MatRef, Par};
use mhe_core::MheEstimator;
use mhe_core::WarmStart as MheWarmStart;
use mhe_core::problem::WindowLayout;
use mpc_core::{CondensedMpc, SuboptimalMpc, WarmStart as MpcWarmStart};
use qp_iter::Method;

use super::LinearError;
use super::iteration::{IterationLinearisation, KStepMap, Linearise, all_finite, linearise, mul};
use closed_loop::scenario::{ResolvedScenario, ScenarioController, ScenarioLoop};

/// Block offsets of the lifted state X_t (at the start of step t ≥ M, before x̂_t):
///
/// X_t = (x_t, u_{t−M..t−1}, y_{t−M..t−1}, x̂_{t−M..t−1}, z⁰_t, U_{t−1}),
///
/// each window oldest first; z⁰_t is the MHE's warm start (zᴷ_{t−1} under the paper's Σ_t = I);
/// U_{t−1} is the sub-optimal MPC's previous iterate (absent for a static controller).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LiftedLayout {
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
    /// n_y.
    pub ny: usize,
    /// M.
    pub horizon: usize,
    /// n_z = n_x + M n_w: the MHE's condensed decision vector.
    pub nz: usize,
    /// N n_u for the sub-optimal MPC, 0 for a static law.
    pub n_controller: usize,
}

impl LiftedLayout {
    /// Offset of x_t.
    pub fn x(&self) -> usize {
        0
    }
    /// Offset of u_{t−M+j} (j = 0 oldest).
    pub fn u_window(&self, j: usize) -> usize {
        self.nx + j * self.nu
    }
    /// Offset of y_{t−M+j}.
    pub fn y_window(&self, j: usize) -> usize {
        self.nx + self.horizon * self.nu + j * self.ny
    }
    /// Offset of x̂_{t−M+j} (j = 0 is the prior of the window at t, trap 1).
    pub fn estimates(&self, j: usize) -> usize {
        self.nx + self.horizon * (self.nu + self.ny) + j * self.nx
    }
    /// Offset of z⁰_t.
    pub fn warm_start(&self) -> usize {
        self.nx + self.horizon * (self.nu + self.ny + self.nx)
    }
    /// Offset of U_{t−1}.
    pub fn controller(&self) -> usize {
        self.warm_start() + self.nz
    }
    /// dim X = n_x + M(n_u + n_y + n_x) + n_z (+ N n_u).
    pub fn dim(&self) -> usize {
        self.controller() + self.n_controller
    }
}

/// The controller's linear piece.
#[derive(Debug, Clone)]
enum ControlPiece {
    /// u = L x̂ (exact MPC: L = −E₀H⁻¹F; saturated LQR: L = −K_lqr).
    Gain(Mat<f64>),
    /// U_t = G_c W U_{t−1} + J_c x̂_t, u = E₀U_t (K_c iterations of the MPC's Φ; W the
    /// warm-start rule's linear part).
    Iterative {
        /// G_c W (N n_u × N n_u).
        g_w: Mat<f64>,
        /// J_c (N n_u × n_x).
        j: Mat<f64>,
    },
}

/// The lifted matrix 𝔸(K) of Alg. 1 in the inactive region, for one case-study loop: every
/// K-independent piece is extracted once from the objects the simulation runs.
#[derive(Debug, Clone)]
pub struct LiftedLoop {
    solver: Method,
    layout: LiftedLayout,
    window: WindowLayout,
    a: Mat<f64>,
    b: Mat<f64>,
    c: Mat<f64>,
    e: Mat<f64>,
    mhe: IterationLinearisation,
    x_z: Mat<f64>,
    x_theta: Mat<f64>,
    mhe_warm: MheWarmStart,
    control: ControlPiece,
}

struct MhePieces {
    lin: IterationLinearisation,
    x_z: Mat<f64>,
    x_theta: Mat<f64>,
    window: WindowLayout,
    warm: MheWarmStart,
}

fn mhe_pieces<M: Linearise>(est: &MheEstimator<M>) -> Result<MhePieces, LinearError> {
    let m = est.config().horizon;
    let window = est
        .problem()
        .window(m)
        .ok_or(LinearError::Internal("the MHE has no window of length M"))?;
    let map = est.map(m).ok_or(LinearError::Internal(
        "the MHE has no map for window length M",
    ))?;
    let (x_z, x_theta) = window.x_end_maps();
    Ok(MhePieces {
        lin: linearise(map, "MHE")?,
        x_z: x_z.to_owned(),
        x_theta: x_theta.to_owned(),
        window: window.layout(),
        warm: est.config().warm_start,
    })
}

fn suboptimal_piece<M: Linearise>(
    ctrl: &SuboptimalMpc<M>,
    nu: usize,
    par: Par,
) -> Result<ControlPiece, LinearError> {
    let lin = linearise(ctrl.map(), "MPC")?;
    let KStepMap { g, j, .. } = lin.k_step(ctrl.iterations(), par)?;
    let n = lin.n;
    let w = mpc_warm_matrix(ctrl.warm_start_rule(), n, nu);
    Ok(ControlPiece::Iterative {
        g_w: mul(g.as_ref(), w.as_ref(), par),
        j,
    })
}

/// W: the linear part of the sub-optimal MPC's warm start U⁰_t = W U_{t−1} (constants such as
/// Π_𝒰(0) dropped: 0 is interior to 𝒰 wherever this is used).
pub(crate) fn mpc_warm_matrix(rule: MpcWarmStart, n: usize, nu: usize) -> Mat<f64> {
    let blocks = n / nu;
    Mat::from_fn(n, n, |r, c| {
        let (br, ir) = (r / nu, r % nu);
        let (bc, ic) = (c / nu, c % nu);
        let hit = |src: usize| bc == src && ic == ir;
        let v = match rule {
            MpcWarmStart::Previous => r == c,
            MpcWarmStart::Cold => false,
            MpcWarmStart::ShiftZero => br + 1 < blocks && hit(br + 1),
            MpcWarmStart::ShiftRepeatLast => hit((br + 1).min(blocks - 1)),
        };
        if v { 1.0 } else { 0.0 }
    })
}

/// −E₀H⁻¹F: the first n_u rows of the unconstrained minimiser U* = −H⁻¹Fx̂.
fn exact_gain(mpc: &CondensedMpc) -> Result<Mat<f64>, LinearError> {
    use faer::linalg::solvers::Solve;
    let qp = mpc.qp();
    let llt = qp
        .h()
        .to_owned()
        .llt(faer::Side::Lower)
        .map_err(|_| LinearError::Internal("the MPC Hessian is not positive definite"))?;
    let sol = llt.solve(qp.f());
    let nu = mpc.nu();
    Ok(Mat::from_fn(nu, qp.n_theta(), |i, j| -sol[(i, j)]))
}

impl LiftedLoop {
    /// Extracts the K-independent pieces from a loop built by
    /// [`ResolvedScenario::build_loop`] (the same MHE maps, window, warm-start rule and
    /// controller the simulation runs) with the MHE method `method`. `resolved` is the
    /// scenario the loop was built from: the exact MPC's gain is formed from its MPC, the
    /// one the builder uses.
    ///
    /// Errors: 0 not interior to the MHE's or MPC's box, a probe reaching a bound, the
    /// scenario lacking `[mpc]`.
    pub fn from_loop(
        cl: &ScenarioLoop,
        resolved: &ResolvedScenario,
        method: Method,
        par: Par,
    ) -> Result<Self, LinearError> {
        let solver = method;
        let pieces = mhe_pieces(cl.estimator())?;
        let plant = cl.plant();
        let nu = plant.nu();
        let control = match cl.controller() {
            ScenarioController::Exact(_) => {
                ControlPiece::Gain(exact_gain(resolved.mpc().map_err(LinearError::from)?)?)
            }
            ScenarioController::SaturatedLqr(c) => {
                let k = c.gain();
                ControlPiece::Gain(Mat::from_fn(k.nrows(), k.ncols(), |i, j| -k[(i, j)]))
            }
            ScenarioController::Suboptimal(c) => suboptimal_piece(c, nu, par)?,
        };
        let n_controller = match &control {
            ControlPiece::Gain(_) => 0,
            ControlPiece::Iterative { j, .. } => j.nrows(),
        };
        let layout = LiftedLayout {
            nx: plant.nx(),
            nu,
            ny: plant.ny(),
            horizon: pieces.window.m,
            nz: pieces.window.nz(),
            n_controller,
        };
        Ok(Self {
            solver,
            layout,
            window: pieces.window,
            a: plant.a().to_owned(),
            b: plant.b().to_owned(),
            c: plant.c().to_owned(),
            e: plant.e().to_owned(),
            mhe: pieces.lin,
            x_z: pieces.x_z,
            x_theta: pieces.x_theta,
            mhe_warm: pieces.warm,
            control,
        })
    }

    /// The MHE's iteration map.
    pub fn solver(&self) -> Method {
        self.solver
    }
    /// The block layout of X_t.
    pub fn layout(&self) -> LiftedLayout {
        self.layout
    }
    /// dim X.
    pub fn dim(&self) -> usize {
        self.layout.dim()
    }
    /// The dimensions that set the cost of ρ_lin.
    pub fn dims(&self) -> super::LiftedDims {
        let l = self.layout;
        super::LiftedDims {
            nx: l.nx,
            nu: l.nu,
            ny: l.ny,
            horizon: l.horizon,
            nz: l.nz,
            n_controller: l.n_controller,
            n_theta: self.mhe.n_theta,
        }
    }
    /// Estimated multiply-adds of ρ_lin on `grid` ([`super::LiftedDims::grid_work`]).
    pub fn grid_work(&self, grid: &[usize]) -> f64 {
        self.dims().grid_work(self.mhe.lift_dim(), grid)
    }
    /// The linearised MHE map Φ at window length M.
    pub fn mhe_linearisation(&self) -> &IterationLinearisation {
        &self.mhe
    }

    /// S_θ: X_t ↦ θ_t = (x̂_{t−M}, u_{t−M..t−1}, y_{t−M..t−1}) (n_θ × dim X).
    fn theta_selection(&self) -> Mat<f64> {
        let (l, w) = (self.layout, self.window);
        let d = w.dims;
        let mut s = Mat::<f64>::zeros(w.n_theta(), l.dim());
        for i in 0..d.nx {
            s[(i, l.estimates(0) + i)] = 1.0;
        }
        for j in 0..w.m {
            for i in 0..d.nu {
                s[(w.u_offset(j) + i, l.u_window(j) + i)] = 1.0;
            }
            for i in 0..d.ny {
                s[(w.y_offset(j) + i, l.y_window(j) + i)] = 1.0;
            }
        }
        s
    }

    /// The lifted matrix 𝔸(K): X_{t+1} = 𝔸(K) X_t for t ≥ M while no constraint is active
    /// and w ≡ 0 (the constant terms of the affine maps are zero for the MHE and MPC QPs,
    /// q₀ = 0).
    ///
    /// Errors: K = 0, a non-finite K-step map.
    pub fn matrix(&self, k: usize, par: Par) -> Result<Mat<f64>, LinearError> {
        let km = self.mhe.k_step(k, par)?;
        self.matrix_with(&km, par)
    }

    /// 𝔸(K) from the MHE's K-step map `km` (K = `km.k`).
    fn matrix_with(&self, km: &KStepMap, par: Par) -> Result<Mat<f64>, LinearError> {
        let k = km.k;
        let l = self.layout;
        let s_theta = self.theta_selection();
        // zᴷ_t = G z⁰_t + J θ_t.
        let mut zk = mul(km.j.as_ref(), s_theta.as_ref(), par);
        add_block(&mut zk, 0, l.warm_start(), km.g.as_ref());
        let a = self.assemble(zk.as_ref(), s_theta.as_ref(), par);
        if !all_finite(a.as_ref()) {
            return Err(LinearError::NonFinite {
                what: "the lifted matrix",
                k,
            });
        }
        Ok(a)
    }

    /// The loop map split at the MHE's last iterate: X_{t+1} = 𝒜 X_t + 𝒢_z zᴷ_t (t ≥ M, w ≡ 0,
    /// the controller's and the warm start's linear pieces; zᴷ_t is whatever the K inner
    /// iterations return), as (𝒜, 𝒢_z) with 𝒢_z of size dim X × n_z. With zᴷ_t = G z⁰_t +
    /// J θ_t this is [`LiftedLoop::matrix`]; `lure::loop_level` feeds zᴷ_t from iterations
    /// whose clamps it keeps. Same products as `matrix` (no cancellation: the two column
    /// groups of one assembly on the space (X_t, zᴷ_t)).
    pub fn split_at_iterate(&self, par: Par) -> (Mat<f64>, Mat<f64>) {
        let (n, nz) = (self.layout.dim(), self.layout.nz);
        let s_theta = self.theta_selection();
        let zk = Mat::from_fn(nz, n + nz, |i, j| if j == n + i { 1.0 } else { 0.0 });
        let st = Mat::from_fn(s_theta.nrows(), n + nz, |i, j| {
            if j < n { s_theta[(i, j)] } else { 0.0 }
        });
        let a = self.assemble(zk.as_ref(), st.as_ref(), par);
        (
            a.as_ref().subcols(0, n).to_owned(),
            a.as_ref().subcols(n, nz).to_owned(),
        )
    }

    /// S_θ: X_t ↦ θ_t, the MHE's parameter (n_θ × dim X).
    pub fn parameter_selection(&self) -> Mat<f64> {
        self.theta_selection()
    }

    /// The rows of X_{t+1} given zᴷ_t = `zk` and θ_t = `s_theta`, both as linear maps of
    /// one column space (dim X columns in [`LiftedLoop::matrix`]; dim X + n_z in
    /// [`LiftedLoop::split_at_iterate`]); the plant, controller and shift blocks occupy the
    /// first dim X columns.
    fn assemble(&self, zk: MatRef<'_, f64>, s_theta: MatRef<'_, f64>, par: Par) -> Mat<f64> {
        let (l, w) = (self.layout, self.window);
        let (nx, nu, ny, big_m, nz) = (l.nx, l.nu, l.ny, l.horizon, l.nz);
        let n = l.dim();
        let cols = zk.ncols();
        // x̂_t = X_z zᴷ_t + X_θ θ_t.
        let mut xh = mul(self.x_z.as_ref(), zk, par);
        add(&mut xh, mul(self.x_theta.as_ref(), s_theta, par).as_ref());
        // u_t, and U_t for the sub-optimal MPC.
        let (u_row, u_seq) = match &self.control {
            ControlPiece::Gain(gain) => (mul(gain.as_ref(), xh.as_ref(), par), None),
            ControlPiece::Iterative { g_w, j } => {
                let mut seq = mul(j.as_ref(), xh.as_ref(), par);
                add_block(&mut seq, 0, l.controller(), g_w.as_ref());
                (seq.as_ref().subrows(0, nu).to_owned(), Some(seq))
            }
        };

        let mut a = Mat::<f64>::zeros(n, cols);
        // x_{t+1} = A x_t + B u_t.
        add_block(&mut a, 0, 0, self.a.as_ref());
        add_rows(
            &mut a,
            0,
            mul(self.b.as_ref(), u_row.as_ref(), par).as_ref(),
        );
        // Windows shift by one stage; the newest entry is u_t, y_t = C x_t, x̂_t.
        for j in 0..big_m - 1 {
            shift(&mut a, l.u_window(j), l.u_window(j + 1), nu);
            shift(&mut a, l.y_window(j), l.y_window(j + 1), ny);
            shift(&mut a, l.estimates(j), l.estimates(j + 1), nx);
        }
        add_rows(&mut a, l.u_window(big_m - 1), u_row.as_ref());
        add_block(&mut a, l.y_window(big_m - 1), 0, self.c.as_ref());
        add_rows(&mut a, l.estimates(big_m - 1), xh.as_ref());
        // z⁰_{t+1} = Σ(zᴷ_t, θ_t).
        match self.mhe_warm {
            MheWarmStart::Paper => add_rows(&mut a, l.warm_start(), zk),
            MheWarmStart::Shifted => {
                let (wz, wth) = self.shifted_warm_start();
                add_rows(&mut a, l.warm_start(), mul(wz.as_ref(), zk, par).as_ref());
                add_rows(
                    &mut a,
                    l.warm_start(),
                    mul(wth.as_ref(), s_theta, par).as_ref(),
                );
            }
        }
        if let Some(seq) = u_seq {
            add_rows(&mut a, l.controller(), seq.as_ref());
        }
        debug_assert_eq!(nz, w.nz());
        a
    }

    /// The time-shifted warm start z⁰ = W_z zᴷ + W_θ θ: x̂₀ ← A x̂₀ + B u₀ + E ŵ¹₀, stages
    /// shifted by one, newest stage zero (`MheEstimator::push`).
    fn shifted_warm_start(&self) -> (Mat<f64>, Mat<f64>) {
        let w = self.window;
        let d = w.dims;
        let (nz, nw) = (w.nz(), d.nw());
        let mut wz = Mat::<f64>::zeros(nz, nz);
        let mut wth = Mat::<f64>::zeros(nz, w.n_theta());
        add_block(&mut wz, 0, 0, self.a.as_ref());
        add_block(&mut wz, 0, w.w_offset(0), self.e.as_ref());
        add_block(&mut wth, 0, w.u_offset(0), self.b.as_ref());
        for i in d.nx..nz - nw {
            wz[(i, i + nw)] = 1.0;
        }
        (wz, wth)
    }

    /// ρ_lin(K) = max |λ(𝔸(K))|.
    pub fn spectral_radius(&self, k: usize, par: Par) -> Result<f64, LinearError> {
        spectral_radius(self.matrix(k, par)?.as_ref(), par)
    }

    /// ρ_lin(K) for every K of an ascending `grid`, the K-step maps shared along the grid
    /// (`kgrid.rs`): the same values as [`LiftedLoop::spectral_radius`] per K up to rounding,
    /// at a fraction of the cost of the powers. `done(K)` is called after each K.
    ///
    /// Errors: as [`LiftedLoop::spectral_radius`]; a grid that is not ascending.
    pub fn spectral_radii(
        &self,
        grid: &[usize],
        par: Par,
        done: &mut dyn FnMut(usize),
    ) -> Result<Vec<(usize, f64)>, LinearError> {
        let mut out = Vec::with_capacity(grid.len());
        super::kgrid::k_steps(&self.mhe, grid, par, |km| {
            let k = km.k;
            let rho = spectral_radius(self.matrix_with(&km, par)?.as_ref(), par)?;
            out.push((k, rho));
            done(k);
            Ok(())
        })?;
        Ok(out)
    }
}

/// dst[r0.., c0..] += block.
fn add_block(dst: &mut Mat<f64>, r0: usize, c0: usize, block: MatRef<'_, f64>) {
    for j in 0..block.ncols() {
        for i in 0..block.nrows() {
            dst[(r0 + i, c0 + j)] += block[(i, j)];
        }
    }
}

/// dst[r0.., ..] += rows (full width).
fn add_rows(dst: &mut Mat<f64>, r0: usize, rows: MatRef<'_, f64>) {
    add_block(dst, r0, 0, rows);
}

fn add(dst: &mut Mat<f64>, m: MatRef<'_, f64>) {
    add_block(dst, 0, 0, m);
}

/// Rows `to..to+len` of X_{t+1} take rows `from..from+len` of X_t.
fn shift(dst: &mut Mat<f64>, to: usize, from: usize, len: usize) {
    for i in 0..len {
        dst[(to + i, from + i)] = 1.0;
    }
}

/// Spectral radius of a square, non-symmetric matrix: for dim ≥ [`super::KRYLOV_MIN_DIM`]
/// by Arnoldi's method ([`super::spectral_radius_krylov`]: the dominant Ritz values converged
/// to a residual of 1e-11·‖m‖_F), and otherwise — or when Arnoldi is not accepted — the dense
/// eigenvalues ([`spectral_radius_dense`]).
pub fn spectral_radius(m: MatRef<'_, f64>, par: Par) -> Result<f64, LinearError> {
    if m.nrows() >= super::KRYLOV_MIN_DIM
        && let Some(rho) = super::spectral_radius_krylov(m, par)
    {
        return Ok(rho);
    }
    spectral_radius_dense(m, par)
}

/// Spectral radius of a square, non-symmetric matrix: the real Schur eigenvalues of faer
/// with explicit parallelism (≈ 10·dim³ multiply-adds).
pub fn spectral_radius_dense(m: MatRef<'_, f64>, par: Par) -> Result<f64, LinearError> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::evd::{self, ComputeEigenvectors};
    let n = m.nrows();
    if n == 0 {
        return Ok(0.0);
    }
    let mut re = faer::diag::Diag::<f64>::zeros(n);
    let mut im = faer::diag::Diag::<f64>::zeros(n);
    let params = Default::default();
    let mut buf = MemBuffer::new(evd::evd_scratch::<f64>(
        n,
        ComputeEigenvectors::No,
        ComputeEigenvectors::No,
        par,
        params,
    ));
    evd::evd_real(
        m,
        re.as_mut(),
        im.as_mut(),
        None,
        None,
        par,
        MemStack::new(&mut buf),
        params,
    )
    .map_err(|_| LinearError::Eigenvalues { dim: n })?;
    let mut rho = 0.0_f64;
    for i in 0..n {
        let v = re[i].hypot(im[i]);
        if !v.is_finite() {
            return Err(LinearError::Eigenvalues { dim: n });
        }
        rho = rho.max(v);
    }
    Ok(rho)
}
