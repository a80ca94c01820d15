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

/// Window lengths are small; saturate rather than wrap for absurd horizons.
pub(crate) fn pow_i32(k: usize) -> i32 {
    i32::try_from(k).unwrap_or(i32::MAX)
}

// Building one window (condensing, box, rows, L_Φ): problem/build.rs; the sampled L_Φ: problem/sampling.rs.
mod build;
mod sampling;
use build::build_window;
pub use sampling::{LipschitzEstimate, LipschitzSampling};
