//! The condensed input-constrained linear MPC π(x̂) as a parametric QP.
//!
//! Decision U = (u₀, …, u_{N−1}) ∈ 𝒰^N, nominal prediction (w = 0)
//! x_k = Aᵏx̂ + Σ_{j<k} A^{k−1−j}B u_j, i.e. X = (x₁, …, x_N) = Φx̂ + ΓU, and cost
//!
//! J(x̂, U) = Σ_{k<N} (‖x_k‖²_{Q_c} + ‖u_k‖²_{R_c}) + ‖x_N‖²_{P_f}
//!         = ½UᵀHU + (Fx̂)ᵀU + x̂ᵀ(Q_c + ΦᵀQ̄Φ)x̂,
//!
//! with Q̄ = diag(Q_c, …, Q_c, P_f), R̄ = diag(R_c, …, R_c), H = 2(ΓᵀQ̄Γ + R̄) ≻ 0 (R_c ≻ 0)
//! and F = 2ΓᵀQ̄Φ. The constant does not affect the minimiser, so π(x̂) = u*₀(x̂) where
//! U*(x̂) solves the [`ParametricQp`] min ½UᵀHU + (Fx̂)ᵀU s.t. U ∈ 𝒰^N, θ = x̂, q₀ = 0.
//!
//! **State constraints.** With a bounded 𝒳 the predicted states x_k = Φ_k x̂ + Γ_k U ∈ 𝒳,
//! k = 1..N, are general rows l − Φ_k x̂ ≤ Γ_k U ≤ u − Φ_k x̂ of the QP (one per finite
//! component; [`qp_iter::GeneralConstraints`] with G = Γ_k, E = Φ_k). The MPC can then be
//! infeasible at some x̂ ([`crate::ControlStatus::Infeasible`]), and the analysis of L_π and
//! γ₁,₃ (box-constrained inputs only) does not apply: [`CondensedMpc::certificate_void_reason`].

use faer::Mat;
use lti_model::matrix::{
    SYMMETRY_TOL, asymmetry, check_finite, check_positive_definite, check_shape,
    sym_extreme_eigenvalues,
};
use lti_model::riccati::dare;
use lti_model::{BoxSet, ConvexSet, LtiSystem, ModelError};
use qp_iter::ParametricQp;

use crate::error::{MpcError, Result};

/// Terminal cost P_f of the MPC.
#[derive(Debug, Clone, PartialEq)]
pub enum Terminal {
    /// The stabilising solution of the DARE for (A, B, Q_c, R_c): the infinite-horizon
    /// LQR cost-to-go, so that the unconstrained MPC equals the LQR law u = −Kx̂.
    Dare,
    /// A user-given symmetric P_f ⪰ 0 (n_x × n_x).
    Given(Mat<f64>),
}

/// Settings of the condensed MPC; validated by [`CondensedMpc::new`].
///
/// ```
/// use faer::Mat;
/// use lti_model::BoxSet;
/// let cfg = mpc_core::MpcConfig::new(10, Mat::identity(4, 4), Mat::<f64>::identity(2, 2) * 0.1,
///     BoxSet::symmetric(&[1.0, 1.0]).unwrap());
/// assert_eq!(cfg.terminal, mpc_core::Terminal::Dare);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct MpcConfig {
    /// Prediction horizon N ≥ 1.
    pub horizon: usize,
    /// Stage state weight Q_c ⪰ 0 (n_x × n_x, symmetric).
    pub q_c: Mat<f64>,
    /// Stage input weight R_c ≻ 0 (n_u × n_u, symmetric).
    pub r_c: Mat<f64>,
    /// Terminal weight P_f (DARE by default).
    pub terminal: Terminal,
    /// Input set 𝒰 (a box, possibly with infinite bounds).
    pub input_set: BoxSet,
    /// State set 𝒳 imposed on the predicted x₁…x_N (general rows of the QP; `None` or the
    /// whole space: no rows).
    pub state_set: Option<BoxSet>,
    /// Output set 𝒴_c imposed on the predicted outputs C x₁ … C x_N (noise-free: the MPC
    /// predicts with w = 0); general rows after the state rows (`None` or the whole space:
    /// no rows). In a scenario: `mpc.output`.
    pub output_set: Option<BoxSet>,
}

impl MpcConfig {
    /// Config with the DARE terminal cost and no state constraints.
    pub fn new(horizon: usize, q_c: Mat<f64>, r_c: Mat<f64>, input_set: BoxSet) -> Self {
        Self {
            horizon,
            q_c,
            r_c,
            terminal: Terminal::Dare,
            input_set,
            state_set: None,
            output_set: None,
        }
    }
}

/// The condensed MPC: validated weights, prediction matrices and the parametric QP.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{BoxSet, LtiSystem};
/// use mpc_core::{CondensedMpc, MpcConfig};
/// let sys = LtiSystem::new(mat![[1.0, 0.1], [0.0, 1.0]], mat![[0.005], [0.1]], mat![[1.0, 0.0]]).unwrap();
/// let mpc = CondensedMpc::new(&sys, MpcConfig::new(5, Mat::identity(2, 2), mat![[0.1]],
///     BoxSet::symmetric(&[1.0]).unwrap())).unwrap();
/// assert_eq!((mpc.qp().n(), mpc.qp().n_theta()), (5, 2));
/// ```
#[derive(Debug, Clone)]
pub struct CondensedMpc {
    system: LtiSystem,
    horizon: usize,
    q_c: Mat<f64>,
    r_c: Mat<f64>,
    p_f: Mat<f64>,
    input_set: BoxSet,
    phi: Mat<f64>,
    gamma: Mat<f64>,
    q_bar: Mat<f64>,
    qp: ParametricQp,
    /// (k, i) of each general row: x_{k,i} ∈ 𝒳_i, k = 1..N.
    state_rows: Vec<(usize, usize)>,
    /// (k, i) of each output row (after the state rows): (C x_k)_i ∈ 𝒴_c,i, k = 1..N.
    output_rows: Vec<(usize, usize)>,
}

/// Why L_π and γ₁,₃ are void for an MPC with state constraints.
pub const STATE_CONSTRAINED_VOID_REASON: &str = "the MPC has state constraints x_k ∈ 𝒳 \
     (`sets.state`): the certified L_π and γ₁,₃ assume box-constrained inputs only (π is an \
     H-weighted projection onto the fixed set 𝒰^N), but the predicted-state rows move with x̂ and \
     the MPC can be infeasible; no certified L_π or γ₁,₃ is reported";

/// Whether a symmetric PSD weight is singular: λ_min ≤ 1e-12·max(1, λ_max) (then the
/// detectability of (A, Q_c^½) decides whether the DARE has a stabilising solution).
pub(crate) fn is_singular(m: &Mat<f64>) -> bool {
    sym_extreme_eigenvalues("Q_c", m.as_ref())
        .map_or(true, |(lo, hi)| lo <= 1e-12 * hi.abs().max(1.0))
}

/// Why L_π and γ₁,₃ are void for an MPC with output constraints (and no state constraints).
pub const OUTPUT_CONSTRAINED_VOID_REASON: &str = "the MPC has output constraints C x_k ∈ 𝒴_c \
     (`mpc.output`): the certified L_π and γ₁,₃ assume box-constrained inputs only (π is an \
     H-weighted projection onto the fixed set 𝒰^N), but the predicted-output rows move with x̂ \
     and the MPC can be infeasible; no certified L_π or γ₁,₃ is reported";

/// Validates a weight that must be symmetric positive semidefinite (Q_c, P_f).
pub(crate) fn check_psd(name: &'static str, m: &Mat<f64>, n: usize) -> Result<()> {
    check_shape(name, m.as_ref(), n, n)?;
    check_finite(name, m.as_ref())?;
    let scale = m.norm_max().max(1.0);
    let asym = asymmetry(m.as_ref());
    if asym > SYMMETRY_TOL * scale {
        return Err(ModelError::NotSymmetric {
            name: name.to_string(),
            asymmetry: asym,
        }
        .into());
    }
    let (lo, hi) = sym_extreme_eigenvalues(name, m.as_ref())?;
    // Round-off of the eigensolver: accept −1e-12·max(1, λ_max).
    if !(lo >= -1e-12 * hi.abs().max(1.0)) {
        return Err(MpcError::NotPositiveSemidefinite {
            name,
            min_eigenvalue: lo,
        });
    }
    Ok(())
}

/// The shapes of `config` against `system` (N ≥ 1, n_u ≥ 1, Q_c ⪰ 0, R_c ≻ 0, the sets'
/// dimensions), before anything is built.
fn check_config(system: &LtiSystem, config: &MpcConfig) -> Result<()> {
    let (nx, nu) = (system.nx(), system.nu());
    let n = config.horizon;
    if n == 0 {
        return Err(MpcError::Horizon { value: 0 });
    }
    if nu == 0 {
        return Err(ModelError::Shape {
            name: "B".into(),
            expected_rows: nx,
            expected_cols: 1,
            actual_rows: nx,
            actual_cols: 0,
        }
        .into());
    }
    check_psd("Q_c", &config.q_c, nx)?;
    check_positive_definite("R_c", config.r_c.as_ref(), nu)?;
    if config.input_set.dim() != nu {
        return Err(ModelError::Shape {
            name: "input_set".into(),
            expected_rows: nu,
            expected_cols: 1,
            actual_rows: config.input_set.dim(),
            actual_cols: 1,
        }
        .into());
    }
    if let Some(ys) = &config.output_set {
        if ys.dim() != system.ny() {
            return Err(ModelError::Shape {
                name: "output_set".into(),
                expected_rows: system.ny(),
                expected_cols: 1,
                actual_rows: ys.dim(),
                actual_cols: 1,
            }
            .into());
        }
    }
    if let Some(xs) = &config.state_set {
        if xs.dim() != nx {
            return Err(ModelError::Shape {
                name: "state_set".into(),
                expected_rows: nx,
                expected_cols: 1,
                actual_rows: xs.dim(),
                actual_cols: 1,
            }
            .into());
        }
    }
    Ok(())
}

/// P_f: the stabilising DARE solution, or the given matrix (checked ⪰ 0, symmetrised).
fn terminal_weight(
    system: &LtiSystem,
    terminal: &Terminal,
    q_c: &Mat<f64>,
    r_c: &Mat<f64>,
) -> Result<Mat<f64>> {
    let nx = system.nx();
    Ok(match terminal {
        Terminal::Dare => {
            // Q_c ⪰ 0: the stabilising DARE solution needs (A, Q_c^½) detectable; a
            // singular Q_c is checked first so the error names the unseen mode.
            if is_singular(q_c) {
                crate::detectable::check_detectable(system.a(), q_c.as_ref())?;
            }
            dare(system.a(), system.b(), q_c.as_ref(), r_c.as_ref())?
        }
        Terminal::Given(p) => {
            check_psd("P_f", p, nx)?;
            lti_model::matrix::symmetrize(p.as_ref())
        }
    })
}

/// The condensed prediction x_{1..N} = Φ x̂ + Γ U: Φ = [A; A²; …; A^N] and the block
/// lower-triangular Γ with blocks A^{k−1−j} B.
fn prediction(system: &LtiSystem, n: usize) -> (Mat<f64>, Mat<f64>) {
    let (nx, nu) = (system.nx(), system.nu());
    let a = system.a();
    let b = system.b();
    // Powers A⁰ … A^N.
    let mut pows: Vec<Mat<f64>> = Vec::with_capacity(n + 1);
    pows.push(Mat::identity(nx, nx));
    for k in 1..=n {
        let next = &pows[k - 1] * a;
        pows.push(next);
    }
    let mut phi = Mat::<f64>::zeros(n * nx, nx);
    let mut gamma = Mat::<f64>::zeros(n * nx, n * nu);
    for k in 1..=n {
        phi.as_mut()
            .submatrix_mut((k - 1) * nx, 0, nx, nx)
            .copy_from(&pows[k]);
        for j in 0..k {
            let blk = &pows[k - 1 - j] * b;
            gamma
                .as_mut()
                .submatrix_mut((k - 1) * nx, j * nu, nx, nu)
                .copy_from(&blk);
        }
    }
    (phi, gamma)
}

/// The rows of the predicted states (outputs) that `set` bounds: (k, i) for k = 1..N and
/// every component i with a finite bound; none for no set or the whole space.
fn finite_rows(set: Option<&BoxSet>, dim: usize, n: usize) -> Vec<(usize, usize)> {
    let Some(set) = set.filter(|s| !s.is_whole()) else {
        return Vec::new();
    };
    (1..=n)
        .flat_map(|k| (0..dim).map(move |i| (k, i)))
        .filter(|&(_, i)| set.lower()[i].is_finite() || set.upper()[i].is_finite())
        .collect()
}

/// The general rows of the QP: x_k = Φ_k x̂ + Γ_k U ∈ 𝒳 for k = 1..N, one row per finite
/// component; then C x_k = CΦ_k x̂ + CΓ_k U ∈ 𝒴_c. `None` when no row is bounded.
fn general_constraints(
    system: &LtiSystem,
    config: &MpcConfig,
    phi: &Mat<f64>,
    gamma: &Mat<f64>,
    state_rows: &[(usize, usize)],
    output_rows: &[(usize, usize)],
) -> Result<Option<qp_iter::GeneralConstraints>> {
    let (nx, nu, n) = (system.nx(), system.nu(), config.horizon);
    let (ms, mo) = (state_rows.len(), output_rows.len());
    if ms + mo == 0 {
        return Ok(None);
    }
    let c = system.c();
    // Row p of G (of E): Γ (Φ) row (k − 1)n_x + i for a state row; C times the
    // block k of Γ (Φ) for an output row.
    let entry = |m: &Mat<f64>, p: usize, j: usize| -> f64 {
        if p < ms {
            let (k, i) = state_rows[p];
            m[((k - 1) * nx + i, j)]
        } else {
            let (k, i) = output_rows[p - ms];
            (0..nx).map(|l| c[(i, l)] * m[((k - 1) * nx + l, j)]).sum()
        }
    };
    let g = Mat::from_fn(ms + mo, n * nu, |p, j| entry(gamma, p, j));
    let e = Mat::from_fn(ms + mo, nx, |p, j| entry(phi, p, j));
    let bound = |p: usize, upper: bool| -> f64 {
        let (set, i) = if p < ms {
            (config.state_set.as_ref(), state_rows[p].1)
        } else {
            (config.output_set.as_ref(), output_rows[p - ms].1)
        };
        let set = set.expect("rows exist only for a given set");
        if upper {
            set.upper()[i]
        } else {
            set.lower()[i]
        }
    };
    let lo = (0..ms + mo).map(|p| bound(p, false)).collect();
    let hi = (0..ms + mo).map(|p| bound(p, true)).collect();
    Ok(Some(qp_iter::GeneralConstraints::new(g, e, lo, hi)?))
}

impl CondensedMpc {
    /// Validates `config` against `system` and builds H, F and the QP.
    ///
    /// Errors: [`MpcError::Horizon`] (N = 0); `Model(Shape | NonFinite | NotSymmetric |
    /// NotPositiveDefinite)` naming `"Q_c"`, `"R_c"`, `"P_f"` or `"input_set"`;
    /// [`MpcError::NotPositiveSemidefinite`] for Q_c or P_f; `Model(Numerical)` if the DARE
    /// has no stabilising solution ((A, B) not stabilisable or (A, Q_c) not detectable).
    pub fn new(system: &LtiSystem, config: MpcConfig) -> Result<Self> {
        lti_model::work_count::record(lti_model::work_count::Work::MpcBuilt);
        let (nx, nu) = (system.nx(), system.nu());
        let n = config.horizon;
        check_config(system, &config)?;
        let q_c = lti_model::matrix::symmetrize(config.q_c.as_ref());
        let r_c = lti_model::matrix::symmetrize(config.r_c.as_ref());
        let p_f = terminal_weight(system, &config.terminal, &q_c, &r_c)?;
        let (phi, gamma) = prediction(system, n);
        let mut q_blocks: Vec<faer::MatRef<'_, f64>> = vec![q_c.as_ref(); n - 1];
        q_blocks.push(p_f.as_ref());
        let q_bar = lti_model::matrix::block_diag(&q_blocks);
        let r_bar = lti_model::matrix::block_diag(&vec![r_c.as_ref(); n]);
        let gt_q = gamma.transpose() * &q_bar;
        let h = (&gt_q * &gamma + &r_bar) * 2.0;
        let f = (&gt_q * &phi) * 2.0;

        let lower: Vec<f64> = (0..n)
            .flat_map(|_| config.input_set.lower().iter().copied())
            .collect();
        let upper: Vec<f64> = (0..n)
            .flat_map(|_| config.input_set.upper().iter().copied())
            .collect();
        let zset =
            BoxSet::named("input_set^N", lower, upper).map_err(lti_model::ModelError::from)?;
        let mut qp = ParametricQp::new(h, vec![0.0; n * nu], f, zset)?;
        let state_rows = finite_rows(config.state_set.as_ref(), nx, n);
        let output_rows = finite_rows(config.output_set.as_ref(), system.ny(), n);
        if let Some(general) =
            general_constraints(system, &config, &phi, &gamma, &state_rows, &output_rows)?
        {
            qp = qp.with_general(general)?;
        }
        Ok(Self {
            system: system.clone(),
            horizon: n,
            q_c,
            r_c,
            p_f,
            input_set: config.input_set,
            phi,
            gamma,
            q_bar,
            qp,
            state_rows,
            output_rows,
        })
    }

    /// Whether the predicted states are constrained (x_k ∈ 𝒳, general rows of the QP).
    pub fn has_state_constraints(&self) -> bool {
        !self.state_rows.is_empty()
    }

    /// (k, i) of general row r: the row is x_{k,i} ∈ 𝒳_i (k = 1..N).
    pub fn state_row(&self, r: usize) -> Option<(usize, usize)> {
        self.state_rows.get(r).copied()
    }

    /// Whether the predicted outputs are constrained (C x_k ∈ 𝒴_c, general rows after the
    /// state rows).
    pub fn has_output_constraints(&self) -> bool {
        !self.output_rows.is_empty()
    }

    /// (k, i) of general row r when it is an output row: (C x_k)_i ∈ 𝒴_c,i (k = 1..N).
    pub fn output_row(&self, r: usize) -> Option<(usize, usize)> {
        r.checked_sub(self.state_rows.len())
            .and_then(|p| self.output_rows.get(p).copied())
    }

    /// Whether the QP has general rows (state or output constraints): the MPC can then be
    /// infeasible at some x̂.
    pub fn has_general_rows(&self) -> bool {
        self.has_state_constraints() || self.has_output_constraints()
    }

    /// Why the certified L_π and γ₁,₃ do not apply (state or output constraints), if they
    /// do not: [`STATE_CONSTRAINED_VOID_REASON`], else [`OUTPUT_CONSTRAINED_VOID_REASON`].
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use lti_model::{BoxSet, LtiSystem};
    /// use mpc_core::{CondensedMpc, MpcConfig};
    /// let sys = LtiSystem::new(mat![[1.0, 0.1], [0.0, 1.0]], mat![[0.005], [0.1]], mat![[1.0, 0.0]]).unwrap();
    /// let mut cfg = MpcConfig::new(5, Mat::identity(2, 2), mat![[0.1]], BoxSet::symmetric(&[1.0]).unwrap());
    /// assert!(CondensedMpc::new(&sys, cfg.clone()).unwrap().certificate_void_reason().is_none());
    /// cfg.state_set = Some(BoxSet::symmetric(&[5.0, 1.0]).unwrap());
    /// let mpc = CondensedMpc::new(&sys, cfg).unwrap();
    /// assert_eq!(mpc.qp().general().unwrap().m(), 10); // 2 components × N = 5
    /// assert!(mpc.certificate_void_reason().unwrap().contains("state constraints"));
    /// ```
    pub fn certificate_void_reason(&self) -> Option<&'static str> {
        if self.has_state_constraints() {
            Some(STATE_CONSTRAINED_VOID_REASON)
        } else if self.has_output_constraints() {
            Some(OUTPUT_CONSTRAINED_VOID_REASON)
        } else {
            None
        }
    }

    /// The parametric QP (θ = x̂, Z = 𝒰^N); clone it to build an iteration map.
    pub fn qp(&self) -> &ParametricQp {
        &self.qp
    }
    /// The plant the predictions use.
    pub fn system(&self) -> &LtiSystem {
        &self.system
    }
    /// Horizon N.
    pub fn horizon(&self) -> usize {
        self.horizon
    }
    /// State dimension n_x (= n_θ).
    pub fn nx(&self) -> usize {
        self.system.nx()
    }
    /// Input dimension n_u.
    pub fn nu(&self) -> usize {
        self.system.nu()
    }
    /// Stage state weight Q_c (symmetrised).
    pub fn q_c(&self) -> &Mat<f64> {
        &self.q_c
    }
    /// Stage input weight R_c (symmetrised).
    pub fn r_c(&self) -> &Mat<f64> {
        &self.r_c
    }
    /// Terminal weight P_f (DARE solution or the user's, symmetrised).
    pub fn terminal_weight(&self) -> &Mat<f64> {
        &self.p_f
    }
    /// Input set 𝒰.
    pub fn input_set(&self) -> &BoxSet {
        &self.input_set
    }
    /// Φ = [A; A²; …; A^N]: X = Φx̂ + ΓU.
    pub fn phi(&self) -> &Mat<f64> {
        &self.phi
    }
    /// Γ, block (k−1, j) = A^{k−1−j}B for j < k: X = Φx̂ + ΓU.
    pub fn gamma(&self) -> &Mat<f64> {
        &self.gamma
    }

    /// The MPC cost J(x̂, U) computed by simulating the nominal model step by step
    /// (independent of H and F; used to check the condensation).
    pub fn cost(&self, x_hat: &[f64], u_seq: &[f64]) -> Result<f64> {
        let (nx, nu, n) = (self.nx(), self.nu(), self.horizon);
        crate::error::check_len("x_hat", x_hat, nx)?;
        crate::error::check_len("u_seq", u_seq, n * nu)?;
        let quad = |m: &Mat<f64>, v: &[f64]| -> f64 {
            let mut s = 0.0;
            for i in 0..v.len() {
                for j in 0..v.len() {
                    s += v[i] * m[(i, j)] * v[j];
                }
            }
            s
        };
        let a = self.system.a();
        let b = self.system.b();
        let mut x = x_hat.to_vec();
        let mut total = 0.0;
        for k in 0..n {
            let u = &u_seq[k * nu..(k + 1) * nu];
            total += quad(&self.q_c, &x) + quad(&self.r_c, u);
            let next: Vec<f64> = (0..nx)
                .map(|i| {
                    (0..nx).map(|j| a[(i, j)] * x[j]).sum::<f64>()
                        + (0..nu).map(|j| b[(i, j)] * u[j]).sum::<f64>()
                })
                .collect();
            x = next;
        }
        Ok(total + quad(&self.p_f, &x))
    }

    /// The U-independent part of the cost, x̂ᵀ(Q_c + ΦᵀQ̄Φ)x̂, so that
    /// J(x̂, U) = ½UᵀHU + (Fx̂)ᵀU + `cost_constant(x̂)`.
    pub fn cost_constant(&self, x_hat: &[f64]) -> Result<f64> {
        crate::error::check_len("x_hat", x_hat, self.nx())?;
        let x = lti_model::matrix::col(x_hat);
        let m = &self.q_c + self.phi.transpose() * &self.q_bar * &self.phi;
        let v = x.transpose() * &m * &x;
        Ok(v[(0, 0)])
    }
}
