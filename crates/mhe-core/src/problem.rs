//! The MHE problem ℙ_t of eqs. (8)–(10) in condensed coordinates: one parametric QP per
//! window length m = 0..M, plus the paper's H_t, z_t, z̃_t and the constants the ISS
//! analysis needs (W_m, H̄, L_Φ).
//!
//! See the crate documentation for the coordinate conventions and the derivation of the
//! certified L_Φ.

use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef, Side};
use lti_model::matrix::{check_positive_definite, sym_extreme_eigenvalues};
use lti_model::{BoxSet, ConvexSet, LtiSystem, ModelError};
use qp_iter::ParametricQp;

use crate::error::{MheError, Result};

/// Weights of the MHE cost (9): decay η, prior weight P, disturbance weight Q, output weight R.
///
/// (η, P, Q, R) should satisfy LMI (2) for the analysis to apply (use
/// [`lti_model::ioss::certify`] to compute P); the estimator itself only needs P, Q, R ≻ 0.
#[derive(Debug, Clone)]
pub struct MheWeights {
    /// η ∈ [0, 1) of LMI (2) and cost (9).
    pub eta: f64,
    /// P ≻ 0, n_x × n_x: the prior weight (W_δ of eq. 3).
    pub p: Mat<f64>,
    /// Q ≻ 0, n_w × n_w with n_w = n_w1 + n_w2: the weight of ŵ = (ŵ¹, ŵ²).
    pub q: Mat<f64>,
    /// R ≻ 0, n_y × n_y: the weight of the output residual ŷ − y.
    pub r: Mat<f64>,
}

/// The constraint sets of ℙ_t: 𝒳 (state), 𝒴 (output), 𝒲 (augmented disturbance).
///
/// ŵ ∈ 𝒲 and x̂_{t−M_t|t} ∈ 𝒳 are boxes of the QP. x̂_{i|t} ∈ 𝒳 for the later stages
/// i = 1..M_t and ŷ_i = Cx̂_i + Fŵ²_i ∈ 𝒴 for i = 0..M_t−1 are general rows
/// l₀ − Eθ ≤ Gz ≤ u₀ − Eθ of the QP (G and E from the prediction matrices: x̂_i depends on the
/// inputs in θ), one per finite component ([`qp_iter::GeneralConstraints`]).
#[derive(Debug, Clone, PartialEq)]
pub struct MheSets {
    /// 𝒳 ⊂ ℝ^{n_x}.
    pub state: BoxSet,
    /// 𝒴 ⊂ ℝ^{n_y}.
    pub output: BoxSet,
    /// 𝒲 ⊂ ℝ^{n_w}.
    pub disturbance: BoxSet,
}

impl MheSets {
    /// 𝒳, 𝒴, 𝒲 all the whole space (the unconstrained MHE).
    pub fn unconstrained(sys: &LtiSystem) -> Self {
        Self {
            state: BoxSet::whole(sys.nx()),
            output: BoxSet::whole(sys.ny()),
            disturbance: BoxSet::whole(sys.nw()),
        }
    }

    /// 𝒳 and 𝒴 the whole space, 𝒲 the given box.
    pub fn with_disturbance(sys: &LtiSystem, disturbance: BoxSet) -> Self {
        Self {
            disturbance,
            ..Self::unconstrained(sys)
        }
    }

    /// The MHE's sets from a scenario's `[sets]` section (𝒰 is the controller's business).
    pub fn from_scenario(sets: &lti_model::spec::ScenarioSets) -> Self {
        Self {
            state: sets.state.clone(),
            output: sets.output.clone(),
            disturbance: sets.disturbance.clone(),
        }
    }
}

/// Dimensions of the plant, shared by every window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
    /// n_y.
    pub ny: usize,
    /// n_w1 (dimension of ŵ¹).
    pub nw1: usize,
    /// n_w2 (dimension of ŵ²).
    pub nw2: usize,
}

impl Dims {
    /// Dimensions of `sys`.
    pub fn of(sys: &LtiSystem) -> Self {
        Self {
            nx: sys.nx(),
            nu: sys.nu(),
            ny: sys.ny(),
            nw1: sys.nw1(),
            nw2: sys.nw2(),
        }
    }
    /// n_w = n_w1 + n_w2: one stage of ŵ.
    pub fn nw(&self) -> usize {
        self.nw1 + self.nw2
    }
}

/// Index layout of the vectors of a window of length m.
///
/// - condensed decision vector z = (x̂₀, ŵ₀, …, ŵ_{m−1}), ŵ_j = (ŵ¹_j, ŵ²_j), length n_x + m n_w;
/// - parameter θ = (prior, u₀, …, u_{m−1}, y₀, …, y_{m−1}), length n_x + m(n_u + n_y);
/// - the paper's z_t of eq. (10) = (x̂₀, ŵ₀, ŷ₀, …, ŵ_{m−1}, ŷ_{m−1}), length n_x + m(n_w + n_y).
///
/// Index j counts stages from the oldest: window time j is absolute time t − m + j.
///
/// ```
/// use mhe_core::problem::{Dims, WindowLayout};
/// let d = Dims { nx: 4, nu: 2, ny: 1, nw1: 4, nw2: 1 };
/// let l = WindowLayout { dims: d, m: 5 };
/// assert_eq!((l.nz(), l.n_theta(), l.n_paper()), (29, 19, 34));
/// assert_eq!((l.w_offset(1), l.u_offset(1), l.y_offset(0)), (9, 6, 14));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WindowLayout {
    /// Plant dimensions.
    pub dims: Dims,
    /// Window length m = M_t.
    pub m: usize,
}

impl WindowLayout {
    /// Length of z: n_x + m n_w.
    pub fn nz(&self) -> usize {
        self.dims.nx + self.m * self.dims.nw()
    }
    /// Length of θ: n_x + m (n_u + n_y).
    pub fn n_theta(&self) -> usize {
        self.dims.nx + self.m * (self.dims.nu + self.dims.ny)
    }
    /// Length of the paper's z_t: n_x + m (n_w + n_y).
    pub fn n_paper(&self) -> usize {
        self.dims.nx + self.m * (self.dims.nw() + self.dims.ny)
    }
    /// Offset of ŵ_j in z (ŵ¹_j first, then ŵ²_j at `+ n_w1`).
    pub fn w_offset(&self, j: usize) -> usize {
        self.dims.nx + j * self.dims.nw()
    }
    /// Offset of u_j in θ.
    pub fn u_offset(&self, j: usize) -> usize {
        self.dims.nx + j * self.dims.nu
    }
    /// Offset of y_j in θ.
    pub fn y_offset(&self, j: usize) -> usize {
        self.dims.nx + self.m * self.dims.nu + j * self.dims.ny
    }
    /// Offset of ŵ_j in the paper's z_t.
    pub fn paper_w_offset(&self, j: usize) -> usize {
        self.dims.nx + j * (self.dims.nw() + self.dims.ny)
    }
    /// Offset of ŷ_j in the paper's z_t.
    pub fn paper_y_offset(&self, j: usize) -> usize {
        self.paper_w_offset(j) + self.dims.nw()
    }
}

/// ℙ_t for one window length m, as the parametric QP min ½zᵀH_c z + (q₀ + F_c θ)ᵀz, z ∈ Z.
///
/// Built from the paper's form V_MHE = ‖T z + S θ − Z̃ θ‖²_{H_t} (eq. 10): T and S map the
/// condensed z and θ to the paper's z_t (ŷ eliminated through ŷ_j = C x̂_j + F ŵ²_j), Z̃ maps θ
/// to z̃_t. Hence H_c = 2TᵀH_tT, F_c = 2TᵀH_t(S − Z̃), q₀ = 0, and
/// V_MHE(z) = ½zᵀH_c z + (F_cθ)ᵀz + ‖(S − Z̃)θ‖²_{H_t}.
#[derive(Debug, Clone)]
pub struct MheWindow {
    layout: WindowLayout,
    qp: ParametricQp,
    t_map: Mat<f64>,
    s_map: Mat<f64>,
    ztilde_map: Mat<f64>,
    h_paper: Mat<f64>,
    xend_z: Mat<f64>,
    xend_theta: Mat<f64>,
    weight_min: f64,
    weight_max: f64,
    lipschitz_certified: f64,
    lipschitz_unconstrained: f64,
    lipschitz_void: bool,
}

/// Why the certified L_Φ of Lemma 1 is void when 𝒳 or 𝒴 is bounded and the plant has inputs.
pub const LIPSCHITZ_VOID_REASON: &str = "the certified L_Φ of Lemma 1 (an H-weighted projection onto a \
     FIXED set) does not hold: with a bounded 𝒳 (`sets.state`) or 𝒴 (`sets.output`) the rows \
     x̂_i ∈ 𝒳, ŷ_i ∈ 𝒴 have bounds that move with the inputs in θ, so the feasible set moves with θ; \
     only the sampled estimate is reported";

impl MheWindow {
    /// The index layout of z, θ and z_t.
    pub fn layout(&self) -> WindowLayout {
        self.layout
    }
    /// Window length m.
    pub fn m(&self) -> usize {
        self.layout.m
    }
    /// The parametric QP (H_c, q₀ = 0, F_c, Z) handed to the iteration map Φ.
    pub fn qp(&self) -> &ParametricQp {
        &self.qp
    }
    /// H_c = 2TᵀH_tT, the Hessian of V_MHE in condensed coordinates.
    pub fn h_c(&self) -> MatRef<'_, f64> {
        self.qp.h()
    }
    /// F_c = 2TᵀH_t(S − Z̃): the linear term is F_c θ.
    pub fn f_c(&self) -> MatRef<'_, f64> {
        self.qp.f()
    }
    /// The weight matrix W_m = H_c/2 = TᵀH_tT: V_MHE(z) − V_MHE(z*) ≥ ‖z − z*‖²_{W_m} on Z
    /// and V_MHE(z) ≤ 2‖z − z*‖²_{W_m} + 2V_MHE(z*) (the step used in Prop. 2).
    pub fn weight(&self) -> Mat<f64> {
        let h = self.qp.h();
        Mat::from_fn(h.nrows(), h.ncols(), |i, j| 0.5 * h[(i, j)])
    }
    /// λ_min(W_m).
    pub fn weight_min_eigenvalue(&self) -> f64 {
        self.weight_min
    }
    /// λ_max(W_m): this window's contribution to H̄ of Prop. 2 (ε in condensed coordinates).
    pub fn weight_max_eigenvalue(&self) -> f64 {
        self.weight_max
    }
    /// The paper's H_t = blkdiag(2η^m P, 2η^{m−1}Q, η^{m−1}R, …, 2Q, R) of eq. (10).
    pub fn h_paper(&self) -> MatRef<'_, f64> {
        self.h_paper.as_ref()
    }
    /// T: condensed z ↦ the z-dependent part of the paper's z_t.
    pub fn t_map(&self) -> MatRef<'_, f64> {
        self.t_map.as_ref()
    }
    /// S: θ ↦ the θ-dependent part of the paper's z_t (inputs entering ŷ through the states).
    pub fn s_map(&self) -> MatRef<'_, f64> {
        self.s_map.as_ref()
    }
    /// Z̃: θ ↦ z̃_t = (prior, 0, y₀, …, 0, y_{m−1}) of eq. (10).
    pub fn ztilde_map(&self) -> MatRef<'_, f64> {
        self.ztilde_map.as_ref()
    }
    /// x̂_{t|t} = X_z z + X_θ θ: the last state of the window propagated through the model.
    /// Returns (X_z, X_θ).
    pub fn x_end_maps(&self) -> (MatRef<'_, f64>, MatRef<'_, f64>) {
        (self.xend_z.as_ref(), self.xend_theta.as_ref())
    }
    /// Certified L_Φ(m) = ‖H_c^{-1/2}F_c‖₂/√λ_min(H_c): Lipschitz constant of θ ↦ z*(θ) in
    /// Euclidean norms (Lemma 1; derivation in the crate documentation). +∞ (void) when the
    /// window has rows whose bounds move with θ ([`MheWindow::lipschitz_void_reason`]).
    pub fn lipschitz_certified(&self) -> f64 {
        self.lipschitz_certified
    }
    /// Why [`MheWindow::lipschitz_certified`] is void (+∞), if it is.
    pub fn lipschitz_void_reason(&self) -> Option<&'static str> {
        self.lipschitz_void.then_some(LIPSCHITZ_VOID_REASON)
    }
    /// ‖H_c⁻¹F_c‖₂: the exact Lipschitz constant of θ ↦ z*(θ) when no bound of Z is active
    /// (a lower bound on the sup over θ of the local constant whenever Z = ℝⁿ).
    pub fn lipschitz_unconstrained(&self) -> f64 {
        self.lipschitz_unconstrained
    }

    /// The paper's z_t = T z + S θ for condensed z and parameter θ (allocates; analysis only).
    pub fn paper_z(&self, z: &[f64], theta: &[f64]) -> Vec<f64> {
        let n = self.layout.n_paper();
        (0..n)
            .map(|i| {
                let a: f64 = (0..z.len()).map(|j| self.t_map[(i, j)] * z[j]).sum();
                let b: f64 = (0..theta.len())
                    .map(|j| self.s_map[(i, j)] * theta[j])
                    .sum();
                a + b
            })
            .collect()
    }

    /// z̃_t = Z̃ θ (allocates; analysis only).
    pub fn ztilde(&self, theta: &[f64]) -> Vec<f64> {
        let n = self.layout.n_paper();
        (0..n)
            .map(|i| {
                (0..theta.len())
                    .map(|j| self.ztilde_map[(i, j)] * theta[j])
                    .sum()
            })
            .collect()
    }

    /// V_MHE = ‖z_t − z̃_t‖²_{H_t} (eq. 10) at condensed z (allocates; analysis only).
    pub fn cost(&self, z: &[f64], theta: &[f64]) -> f64 {
        let zp = self.paper_z(z, theta);
        let zt = self.ztilde(theta);
        let d: Vec<f64> = zp.iter().zip(&zt).map(|(a, b)| a - b).collect();
        let n = d.len();
        let mut v = 0.0;
        for i in 0..n {
            for j in 0..n {
                v += d[i] * self.h_paper[(i, j)] * d[j];
            }
        }
        v
    }
}

/// ℙ_t for every window length m = 0..M, validated once.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::LtiSystem;
/// use mhe_core::problem::{MheProblem, MheSets, MheWeights};
/// let sys = LtiSystem::new(mat![[0.9]], mat![[1.0]], mat![[1.0]]).unwrap();
/// let w = MheWeights { eta: 0.8, p: mat![[1.0]], q: Mat::identity(2, 2), r: mat![[1.0]] };
/// let prob = MheProblem::new(&sys, 3, &w, &MheSets::unconstrained(&sys)).unwrap();
/// assert_eq!(prob.windows().len(), 4);
/// // m = 0: V = 2‖x̂ − prior‖²_P, so H_c = 4P and F_c = −4P.
/// assert!((prob.window(0).unwrap().h_c()[(0, 0)] - 4.0).abs() < 1e-12);
/// assert!(prob.lipschitz_certified() >= 1.0);
/// ```
#[derive(Debug, Clone)]
pub struct MheProblem {
    sys: LtiSystem,
    dims: Dims,
    horizon: usize,
    weights: MheWeights,
    sets: MheSets,
    windows: Vec<MheWindow>,
}

/// Relative threshold below which λ_min(H_c)/λ_max(H_c) counts as singular.
pub const STRONG_CONVEXITY_TOL: f64 = 1e-12;

impl MheProblem {
    /// Validates the data and builds the windows m = 0..M.
    ///
    /// Errors: `horizon` = 0, η ∉ [0, 1), P/Q/R of the wrong shape or not positive
    /// definite, sets of the wrong dimension, a window whose H_c is singular.
    pub fn new(
        sys: &LtiSystem,
        horizon: usize,
        weights: &MheWeights,
        sets: &MheSets,
    ) -> Result<Self> {
        lti_model::work_count::record(lti_model::work_count::Work::MheProblemBuilt);
        let dims = Dims::of(sys);
        validate_problem(dims, horizon, weights, sets)?;
        let windows = (0..=horizon)
            .map(|m| build_window(sys, dims, m, weights, sets))
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            sys: sys.clone(),
            dims,
            horizon,
            weights: weights.clone(),
            sets: sets.clone(),
            windows,
        })
    }

    /// The plant.
    pub fn system(&self) -> &LtiSystem {
        &self.sys
    }
    /// Plant dimensions.
    pub fn dims(&self) -> Dims {
        self.dims
    }
    /// Horizon M.
    pub fn horizon(&self) -> usize {
        self.horizon
    }
    /// The weights (η, P, Q, R).
    pub fn weights(&self) -> &MheWeights {
        &self.weights
    }
    /// The sets 𝒳, 𝒴, 𝒲.
    pub fn sets(&self) -> &MheSets {
        &self.sets
    }
    /// Window of length m (None if m > M).
    pub fn window(&self, m: usize) -> Option<&MheWindow> {
        self.windows.get(m)
    }
    /// All windows, indexed by m = 0..M.
    pub fn windows(&self) -> &[MheWindow] {
        &self.windows
    }
    /// H̄ = sup_m λ_max(W_m) (Prop. 2 with ε measured in condensed coordinates).
    pub fn h_bar(&self) -> f64 {
        self.windows
            .iter()
            .map(MheWindow::weight_max_eigenvalue)
            .fold(0.0, f64::max)
    }
    /// Why the certified L_Φ is void (+∞) for some window length, if it is.
    pub fn lipschitz_void_reason(&self) -> Option<&'static str> {
        self.windows
            .iter()
            .find_map(MheWindow::lipschitz_void_reason)
    }
    /// max_m L_Φ(m): the certified L_Φ of Lemma 1 over all window lengths (+∞ when void:
    /// [`MheProblem::lipschitz_void_reason`]).
    pub fn lipschitz_certified(&self) -> f64 {
        self.windows
            .iter()
            .map(MheWindow::lipschitz_certified)
            .fold(0.0, f64::max)
    }
}

pub(crate) fn validate_problem(
    dims: Dims,
    horizon: usize,
    w: &MheWeights,
    sets: &MheSets,
) -> Result<()> {
    if horizon == 0 {
        return Err(MheError::OutOfRange {
            name: "horizon",
            value: 0.0,
            range: "integers ≥ 1",
        });
    }
    if !(0.0..1.0).contains(&w.eta) {
        return Err(MheError::OutOfRange {
            name: "eta",
            value: w.eta,
            range: "[0, 1)",
        });
    }
    check_positive_definite("P", w.p.as_ref(), dims.nx)?;
    check_positive_definite("Q", w.q.as_ref(), dims.nw())?;
    check_positive_definite("R", w.r.as_ref(), dims.ny)?;
    for (name, set, n) in [
        ("sets.state", &sets.state, dims.nx),
        ("sets.output", &sets.output, dims.ny),
        ("sets.disturbance", &sets.disturbance, dims.nw()),
    ] {
        if set.dim() != n {
            return Err(ModelError::Shape {
                name: name.into(),
                expected_rows: n,
                expected_cols: 1,
                actual_rows: set.dim(),
                actual_cols: 1,
            }
            .into());
        }
    }
    Ok(())
}

fn build_window(
    sys: &LtiSystem,
    d: Dims,
    m: usize,
    w: &MheWeights,
    sets: &MheSets,
) -> Result<MheWindow> {
    let layout = WindowLayout { dims: d, m };
    let (nz, nth) = (layout.nz(), layout.n_theta());
    let (a, c, e, f) = (sys.a(), sys.c(), sys.e(), sys.f());
    let maps = paper_maps(sys, layout, w, sets);
    let (h_c, f_c) = condense(&maps);
    let (lo, hi) = sym_extreme_eigenvalues("H_c", h_c.as_ref())?;
    if !(lo > STRONG_CONVEXITY_TOL * hi) || !hi.is_finite() {
        return Err(MheError::NotStronglyConvex {
            window: m,
            min_eigenvalue: lo,
            max_eigenvalue: hi,
        });
    }

    let zset = window_box(sets, m, nz)?;
    let (mut lipschitz_certified, lipschitz_unconstrained) = lipschitz(&h_c, &f_c, m, lo, hi)?;
    // Lemma 1's bound is an H_c-weighted projection onto a FIXED set; rows whose bounds move
    // with θ (E ≠ 0: the states depend on the inputs in θ) break it.
    let lipschitz_void = maps.rows.moves_with_theta();
    if lipschitz_void {
        lipschitz_certified = f64::INFINITY;
    }

    // The structured product H_c z (forward + adjoint pass) for long windows.
    let op = crate::structured::MheHessian::new(
        layout,
        a,
        c,
        e,
        f,
        w.eta,
        w.p.as_ref(),
        w.q.as_ref(),
        w.r.as_ref(),
    );
    let mut qp =
        ParametricQp::new(h_c, vec![0.0; nz], f_c, zset)?.with_operator(std::sync::Arc::new(op))?;
    let PaperMaps {
        t_map,
        s_map,
        ztilde_map,
        h_paper,
        xz,
        xth,
        rows,
    } = maps;
    if let Some(gc) = rows.build(nz, nth)? {
        qp = qp.with_general(gc)?;
    }
    Ok(MheWindow {
        layout,
        qp,
        t_map,
        s_map,
        ztilde_map,
        h_paper,
        xend_z: xz,
        xend_theta: xth,
        weight_min: 0.5 * lo,
        weight_max: 0.5 * hi,
        lipschitz_certified,
        lipschitz_unconstrained,
        lipschitz_void,
    })
}

/// One window's maps in the paper's variables (eq. (9)): the stacked residuals
/// T z + S θ − z̃ with z̃ = Z̃ θ, their weight H, the end state x̂_m = X_z z + X_θ θ, and the
/// general rows x̂_j ∈ 𝒳, ŷ_j ∈ 𝒴.
struct PaperMaps {
    t_map: Mat<f64>,
    s_map: Mat<f64>,
    ztilde_map: Mat<f64>,
    h_paper: Mat<f64>,
    xz: Mat<f64>,
    xth: Mat<f64>,
    rows: GeneralRows,
}

fn paper_maps(sys: &LtiSystem, layout: WindowLayout, w: &MheWeights, sets: &MheSets) -> PaperMaps {
    let (d, m) = (layout.dims, layout.m);
    let (nx, ny, nw, nw1) = (d.nx, d.ny, d.nw(), d.nw1);
    let (nz, nth, np) = (layout.nz(), layout.n_theta(), layout.n_paper());
    let (a, b, c, e, f) = (sys.a(), sys.b(), sys.c(), sys.e(), sys.f());
    let mut t_map = Mat::<f64>::zeros(np, nz);
    let mut s_map = Mat::<f64>::zeros(np, nth);
    let mut ztilde_map = Mat::<f64>::zeros(np, nth);
    let mut h_paper = Mat::<f64>::zeros(np, np);

    // x̂₀ block: z_t starts with x̂₀, z̃_t with the prior; weight 2η^m P.
    let eta_m = w.eta.powi(pow_i32(m));
    for i in 0..nx {
        t_map[(i, i)] = 1.0;
        ztilde_map[(i, i)] = 1.0;
        for j in 0..nx {
            h_paper[(i, j)] = 2.0 * eta_m * w.p[(i, j)];
        }
    }
    // x̂_j = X_z z + X_θ θ, propagated stage by stage.
    let mut xz = Mat::<f64>::zeros(nx, nz);
    let mut xth = Mat::<f64>::zeros(nx, nth);
    for i in 0..nx {
        xz[(i, i)] = 1.0;
    }
    // General rows (G, E, l₀, u₀): x̂_j ∈ 𝒳 for j = 1..m, ŷ_j ∈ 𝒴 for j = 0..m−1.
    let mut rows = GeneralRows::default();
    for j in 0..m {
        let pw = layout.paper_w_offset(j);
        let py = layout.paper_y_offset(j);
        let zw = layout.w_offset(j);
        // Stage j is time t − m + j, i.e. i = m − j in eq. (9): weight η^{m−1−j}.
        let decay = w.eta.powi(pow_i32(m - 1 - j));
        for i in 0..nw {
            t_map[(pw + i, zw + i)] = 1.0;
            for k in 0..nw {
                h_paper[(pw + i, pw + k)] = 2.0 * decay * w.q[(i, k)];
            }
        }
        // ŷ_j = C x̂_j + F ŵ²_j.
        let cxz = c * &xz;
        let cxth = c * &xth;
        for i in 0..ny {
            for k in 0..nz {
                t_map[(py + i, k)] = cxz[(i, k)];
            }
            for k in 0..d.nw2 {
                t_map[(py + i, zw + nw1 + k)] += f[(i, k)];
            }
            for k in 0..nth {
                s_map[(py + i, k)] = cxth[(i, k)];
            }
            ztilde_map[(py + i, layout.y_offset(j) + i)] = 1.0;
            for k in 0..ny {
                h_paper[(py + i, py + k)] = decay * w.r[(i, k)];
            }
        }
        // x̂_{j+1} = A x̂_j + B u_j + E ŵ¹_j.
        let mut xz_next = a * &xz;
        let mut xth_next = a * &xth;
        for i in 0..nx {
            for k in 0..nw1 {
                xz_next[(i, zw + k)] += e[(i, k)];
            }
            for k in 0..d.nu {
                xth_next[(i, layout.u_offset(j) + k)] += b[(i, k)];
            }
        }
        xz = xz_next;
        xth = xth_next;
        rows.push_finite(&xz, &xth, sets.state.lower(), sets.state.upper());
    }
    // ŷ_j = T_y z + S_y θ: the rows of T and S at the output offsets.
    for j in 0..m {
        let py = layout.paper_y_offset(j);
        let gy = t_map.subrows(py, ny).to_owned();
        let ey = s_map.subrows(py, ny).to_owned();
        rows.push_finite(&gy, &ey, sets.output.lower(), sets.output.upper());
    }
    PaperMaps {
        t_map,
        s_map,
        ztilde_map,
        h_paper,
        xz,
        xth,
        rows,
    }
}

/// The condensed QP's H_c = 2TᵀHT and F_c = 2TᵀH(S − Z̃).
fn condense(maps: &PaperMaps) -> (Mat<f64>, Mat<f64>) {
    let PaperMaps {
        t_map,
        s_map,
        ztilde_map,
        h_paper,
        ..
    } = maps;
    let (nz, nth) = (t_map.ncols(), s_map.ncols());
    let ht = h_paper * t_map;
    let h_c = lti_model::matrix::symmetrize((t_map.transpose() * &ht).as_ref());
    let h_c = Mat::from_fn(nz, nz, |i, j| 2.0 * h_c[(i, j)]);
    let s_minus = s_map - ztilde_map;
    let f_c = t_map.transpose() * (h_paper * &s_minus);
    let f_c = Mat::from_fn(nz, nth, |i, j| 2.0 * f_c[(i, j)]);
    (h_c, f_c)
}

/// Z = 𝒳 × 𝒲^m.
fn window_box(sets: &MheSets, m: usize, nz: usize) -> Result<BoxSet> {
    let (mut lower, mut upper) = (Vec::with_capacity(nz), Vec::with_capacity(nz));
    lower.extend_from_slice(sets.state.lower());
    upper.extend_from_slice(sets.state.upper());
    for _ in 0..m {
        lower.extend_from_slice(sets.disturbance.lower());
        upper.extend_from_slice(sets.disturbance.upper());
    }
    let zset = BoxSet::named("Z", lower, upper).map_err(lti_model::ModelError::from)?;
    Ok(zset)
}

/// L_Φ of Lemma 1 and the unconstrained ‖H_c⁻¹F_c‖₂: ‖H^{-1/2}F‖₂² = λ_max(Fᵀ H⁻¹ F),
/// ‖H⁻¹F‖₂ directly (lo, hi: H_c's extreme eigenvalues).
fn lipschitz(h_c: &Mat<f64>, f_c: &Mat<f64>, m: usize, lo: f64, hi: f64) -> Result<(f64, f64)> {
    let llt = h_c
        .llt(Side::Lower)
        .map_err(|_| MheError::NotStronglyConvex {
            window: m,
            min_eigenvalue: lo,
            max_eigenvalue: hi,
        })?;
    let hinv_f = llt.solve(f_c);
    let ft_hinv_f = lti_model::matrix::symmetrize((f_c.transpose() * &hinv_f).as_ref());
    let (_, top) = sym_extreme_eigenvalues("F_cᵀH_c⁻¹F_c", ft_hinv_f.as_ref())?;
    Ok((
        top.max(0.0).sqrt() / lo.sqrt(),
        lti_model::matrix::spectral_norm(hinv_f.as_ref()),
    ))
}

/// The general rows of one window, gathered stage by stage.
#[derive(Default)]
struct GeneralRows {
    g: Vec<Vec<f64>>,
    e: Vec<Vec<f64>>,
    lo: Vec<f64>,
    hi: Vec<f64>,
}

impl GeneralRows {
    /// One row per component with a finite bound: lo_i ≤ (G_i z + E_i θ) ≤ hi_i, stored as
    /// lo_i − E_iθ ≤ G_i z ≤ hi_i − E_iθ.
    fn push_finite(&mut self, g: &Mat<f64>, e: &Mat<f64>, lo: &[f64], hi: &[f64]) {
        for i in 0..g.nrows() {
            if lo[i].is_finite() || hi[i].is_finite() {
                self.g.push((0..g.ncols()).map(|k| g[(i, k)]).collect());
                self.e.push((0..e.ncols()).map(|k| e[(i, k)]).collect());
                self.lo.push(lo[i]);
                self.hi.push(hi[i]);
            }
        }
    }

    fn moves_with_theta(&self) -> bool {
        self.e.iter().any(|r| r.iter().any(|v| *v != 0.0))
    }

    fn build(self, nz: usize, nth: usize) -> Result<Option<qp_iter::GeneralConstraints>> {
        if self.g.is_empty() {
            return Ok(None);
        }
        let m = self.g.len();
        let g = Mat::from_fn(m, nz, |i, k| self.g[i][k]);
        let e = Mat::from_fn(m, nth, |i, k| self.e[i][k]);
        Ok(Some(qp_iter::GeneralConstraints::new(
            g, e, self.lo, self.hi,
        )?))
    }
}

/// Window lengths are small; saturate rather than wrap for absurd horizons.
pub(crate) fn pow_i32(k: usize) -> i32 {
    i32::try_from(k).unwrap_or(i32::MAX)
}

/// Settings of the sampled L_Φ estimate ([`MheWindow::sample_lipschitz`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LipschitzSampling {
    /// Number of random pairs (θa, θb).
    pub pairs: usize,
    /// Seed of the ChaCha8 generator.
    pub seed: u64,
    /// θa is uniform in [−R, R]^{n_θ}.
    pub theta_radius: f64,
    /// θb = θa + δ with δ uniform in [−r, r]^{n_θ} (small r probes the local slope).
    pub perturbation: f64,
}

impl Default for LipschitzSampling {
    fn default() -> Self {
        Self {
            pairs: 200,
            seed: 0,
            theta_radius: 10.0,
            perturbation: 1.0,
        }
    }
}

/// Sampled and certified L_Φ of one window, side by side (trap 8).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LipschitzEstimate {
    /// Window length m.
    pub window: usize,
    /// max ‖z*(θa) − z*(θb)‖/‖θa − θb‖ over the pairs (a lower bound on the true constant).
    pub sampled: f64,
    /// The certified bound ‖H_c^{-1/2}F_c‖₂/√λ_min(H_c).
    pub certified: f64,
    /// ‖H_c⁻¹F_c‖₂ (exact when no bound is active).
    pub unconstrained: f64,
    /// Pairs used.
    pub pairs: usize,
}

impl MheWindow {
    /// Sampled L_Φ: max ‖z*(θa) − z*(θb)‖₂/‖θa − θb‖₂ over seeded random pairs, z* exact
    /// (the primal active-set solver of `qp_iter::active_set`, every answer KKT-checked,
    /// warm-started from the previous solve — θb from θa's active set — with Clarabel as its
    /// fallback). Reported next to the certified bound.
    pub fn sample_lipschitz(&self, s: &LipschitzSampling) -> Result<LipschitzEstimate> {
        use rand::{Rng, SeedableRng};
        if !(s.theta_radius >= 0.0 && s.theta_radius.is_finite()) {
            return Err(MheError::OutOfRange {
                name: "theta_radius",
                value: s.theta_radius,
                range: "[0, ∞)",
            });
        }
        if !(s.perturbation > 0.0 && s.perturbation.is_finite()) {
            return Err(MheError::OutOfRange {
                name: "perturbation",
                value: s.perturbation,
                range: "(0, ∞)",
            });
        }
        let mut solver = qp_iter::active_set::ExactSolver::new(&self.qp)?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed);
        let nth = self.layout.n_theta();
        let mut best = 0.0_f64;
        let mut ta = vec![0.0; nth];
        let mut tb = vec![0.0; nth];
        let mut za = vec![0.0; self.qp.n()];
        for _ in 0..s.pairs {
            for i in 0..nth {
                ta[i] = s.theta_radius * (2.0 * rng.random::<f64>() - 1.0);
                tb[i] = ta[i] + s.perturbation * (2.0 * rng.random::<f64>() - 1.0);
            }
            // With bounded 𝒳 / 𝒴 a random θ can make ℙ_t infeasible: such pairs are skipped.
            match solver.solve(&ta) {
                Ok(z) => za.copy_from_slice(z),
                Err(qp_iter::QpError::Infeasible { .. }) => continue,
                Err(e) => return Err(e.into()),
            }
            let zb = match solver.solve(&tb) {
                Ok(z) => z,
                Err(qp_iter::QpError::Infeasible { .. }) => continue,
                Err(e) => return Err(e.into()),
            };
            let dz = za
                .iter()
                .zip(zb)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            let dt = ta
                .iter()
                .zip(&tb)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            if dt > 0.0 {
                best = best.max(dz / dt);
            }
        }
        Ok(LipschitzEstimate {
            window: self.layout.m,
            sampled: best,
            certified: self.lipschitz_certified,
            unconstrained: self.lipschitz_unconstrained,
            pairs: s.pairs,
        })
    }
}

impl MheProblem {
    /// [`MheWindow::sample_lipschitz`] for every window length m = 0..M.
    pub fn sample_lipschitz(&self, s: &LipschitzSampling) -> Result<Vec<LipschitzEstimate>> {
        self.windows.iter().map(|w| w.sample_lipschitz(s)).collect()
    }
}
