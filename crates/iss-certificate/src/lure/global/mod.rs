//! The global loop certificate (docs/theory.md, "One certificate for the whole loop", §4):
//! the lifted linear dynamics kept **exact**, and only the two nonlinear pieces — the
//! window's optimum z*_t and the iteration error d_t = zᴷ_t − z*_t — described by quadratic
//! constraints, so the LMI lives on ζ = (X, z*, d, U*, w) and its only matrix unknown is the
//! storage P on X (n_X = 67 on the double integrator, 116 on the case study).
//!
//! - z*_t solves min ½zᵀHz + zᵀFθ_t over the box Z ∋ 0: its variational inequality at the
//!   feasible point 0 gives σ₁ = −z*ᵀ(Hz* + Fθ) ≥ 0, and on every coordinate without a bound
//!   the stationarity (Hz* + Fθ)_i = 0 holds exactly (those coordinates are eliminated).
//! - The exact MPC (or the saturated LQR, H = I, F = K) is the same: σ₃ ≥ 0 on its optimum.
//! - d_t obeys the method's certified contraction ‖D⁻¹d‖ ≤ φ(K)‖D⁻¹(z⁰ − z*)‖ (D = I, or the
//!   Jacobi scaling with the inner map's own bound): σ₂ ≥ 0, z⁰ = W X_t the paper's warm start.
//!
//! The LMI (S-procedure, τ₂ = 1 by homogeneity) is
//! ‖X⁺‖²_P − ρ²‖X‖²_P − γ²‖w‖² + τ₁σ₁ + σ₂ + τ₃σ₃ ≤ 0 for all ζ. It depends on K only through
//! φ(K), and a smaller φ only shrinks the set σ₂ ≥ 0, so the certified K form the interval
//! {K : φ(K) ≤ φ*}: K_glob is exact once φ* (the largest certifiable φ) is bisected.
//! For fixed (τ₁, τ₃, ρ, γ) a P comes from the Riccati equation of the worst case over the
//! inputs v = (z*_B, d, U*_B, w), solved by the structure-preserving doubling algorithm; the
//! P it returns is *untrusted* until the LMI matrix, formed afresh, passes the Jacobi
//! eigenvalue check of `lure::sdp` with a margin above its rounding.

use closed_loop::ClosedLoop;
use closed_loop::scenario::{ScenarioController, ScenarioEstimator};
use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef, Par};
use lti_model::disturbance::Disturbance;
use qp_iter::{Certificate, ParametricQp};

use super::sdp::{Sym, sym_eigenvalues};
use crate::linear::{LiftedLoop, LinearError};

/// Why a scenario has no global loop certificate here.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GlobalError {
    /// Building the loop or its linear pieces failed.
    #[error(transparent)]
    Linear(#[from] LinearError),
    /// The method's φ(K) does not bound ‖zᴷ − z*‖ in the Euclidean norm (eq. (11)).
    #[error(
        "mhe.method = {method}: its φ(K) does not bound ‖zᴷ − z*‖ (eq. (11)), which the global \
         certificate needs; choose a method whose certificate fits eq. (11)"
    )]
    Phi {
        /// The method.
        method: String,
    },
    /// The shifted warm start is not the paper's z⁰ = zᴷ_{t−1}.
    #[error(
        "mhe.warm_start = \"shifted\": the global certificate models the paper's warm start \
         z⁰_t = zᴷ_(t−1) only (the shifted one's d-bound is not the method's φ(K)); set \
         mhe.warm_start = \"paper\""
    )]
    WarmStart,
    /// A QP whose optimum is not described by the box variational inequality at 0.
    #[error(
        "{what}: {why}; the global certificate needs a box containing 0 and no general rows \
         (sets.state in the MHE/MPC adds rows: drop it, or use the regional certificate)"
    )]
    Qp {
        /// Which QP (`mhe` or `mpc`).
        what: &'static str,
        /// Why.
        why: &'static str,
    },
    /// X_t of a running loop cannot be read (see [`GlobalLoop::lifted_state`]).
    #[error(
        "the lifted state X_t needs the last M = {horizon} samples of the loop's trace, which \
         is at t = {t}: step the loop at least M times first (and give an output of length \
         dim X = {dim})"
    )]
    LiftedState {
        /// The loop's t.
        t: usize,
        /// M.
        horizon: usize,
        /// dim X.
        dim: usize,
    },
    /// The controller is not a static optimum (the sub-optimal MPC's K_c iterations).
    #[error(
        "mpc.iterations is set: the global certificate models the exact MPC or the saturated \
         LQR (a static optimum); omit mpc.iterations"
    )]
    Controller,
}

/// The scalars of the search.
#[derive(Debug, Clone, Copy)]
pub struct GlobalOptions {
    /// Relative tolerance of the bisection on φ*.
    pub phi_tol: f64,
    /// Number of log-spaced values of each multiplier τ₁, τ₃ tried (≥ 2).
    pub tau_points: usize,
    /// The largest ρ tried (feasibility is tested there).
    pub rho_max: f64,
    /// K scanned up to (K_glob beyond it is reported as none).
    pub k_max: usize,
}

impl Default for GlobalOptions {
    fn default() -> Self {
        Self {
            phi_tol: 0.02,
            tau_points: 9,
            rho_max: 0.9999,
            k_max: 1_000_000,
        }
    }
}

/// A checked certificate: ‖X_{t+1}‖²_P ≤ ρ²‖X_t‖²_P + γ²‖w_t‖² for t ≥ M, whatever the box
/// constraints do.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct GlobalCertificate {
    /// The φ it certifies (every K with φ(K) ≤ phi is certified).
    pub phi: f64,
    /// ρ < 1.
    pub rho: f64,
    /// γ.
    pub gamma: f64,
    /// τ₁ (MHE optimum), τ₃ (MPC optimum; 0 without one); τ₂ = 1. [0, 0] when `lambda`
    /// holds the multipliers instead.
    pub tau: [f64; 2],
    /// Per-row multipliers λ_i ≥ 0 (MHE rows with a bound, then MPC rows) when the diagonal
    /// search certified it (docs/theory.md §4, "Per-row multipliers"); empty: the scalars τ.
    pub lambda: Vec<f64>,
    /// The storage P (n_X × n_X).
    pub p: Mat<f64>,
    /// −λ_max(LMI)/scale in the independent check.
    pub margin: f64,
    /// λ_min(P)/scale(P) in the independent check.
    pub p_margin: f64,
    /// lim sup ‖x_t‖ ≤ gain_x·w̄.
    pub gain_x: f64,
    /// lim sup ‖x_t − x̂_t‖ ≤ gain_e·w̄ (x_t read from X_t, x̂_t from X_{t+1}).
    pub gain_e: f64,
}

impl GlobalCertificate {
    /// γ·√(λ_max(R P⁻¹ Rᵀ)/(1 − ρ²)): lim sup ‖R X_t‖ ≤ this·w̄ (None if P is not invertible).
    pub fn readout_gain(&self, r: MatRef<'_, f64>) -> Option<f64> {
        readout_gain(&self.p, self.rho, self.gamma, r)
    }
    /// ‖X‖²_P.
    pub fn storage(&self, x: &[f64]) -> f64 {
        let n = x.len();
        let mut s = 0.0;
        for i in 0..n {
            for j in 0..n {
                s += x[i] * self.p[(i, j)] * x[j];
            }
        }
        s
    }
}

fn readout_gain(p: &Mat<f64>, rho: f64, gamma: f64, r: MatRef<'_, f64>) -> Option<f64> {
    let llt = p.llt(faer::Side::Lower).ok()?;
    let rt = r.transpose().to_owned();
    let x = llt.solve(&rt); // P⁻¹Rᵀ
    let m = mul(r, x.as_ref());
    let s = sym_of(&m);
    let top = sym_eigenvalues(&s).last().copied()?;
    Some(gamma * (top.max(0.0) / (1.0 - rho * rho)).sqrt())
}

/// A QP optimum as a channel: H, F (θ ↦ Fθ), the coordinates with a bound.
#[derive(Debug, Clone)]
struct Optimum {
    h: Mat<f64>,
    f: Mat<f64>,
    bounded: Vec<usize>,
    free: Vec<usize>,
}

impl Optimum {
    /// Every bound dropped: the unconstrained optimum (σ = 0 exactly).
    fn drop_bounds(&mut self) {
        self.free = (0..self.h.nrows()).collect();
        self.bounded.clear();
    }

    fn of(qp: &ParametricQp, what: &'static str) -> Result<Self, GlobalError> {
        if qp.general().is_some() {
            return Err(GlobalError::Qp {
                what,
                why: "the QP has general constraint rows",
            });
        }
        if qp.q0().iter().any(|q| *q != 0.0) {
            return Err(GlobalError::Qp {
                what,
                why: "the QP has a constant linear term q₀ ≠ 0, so z*(0) ≠ 0",
            });
        }
        Self::of_box(qp.h(), qp.f(), qp.zset().lower(), qp.zset().upper(), what)
    }

    fn of_box(
        h: MatRef<'_, f64>,
        f: MatRef<'_, f64>,
        lo: &[f64],
        hi: &[f64],
        what: &'static str,
    ) -> Result<Self, GlobalError> {
        if lo.iter().zip(hi).any(|(l, u)| !(*l <= 0.0 && 0.0 <= *u)) {
            return Err(GlobalError::Qp {
                what,
                why: "0 is not in the box",
            });
        }
        let n = h.nrows();
        let (bounded, free) = (0..n).partition(|&i| lo[i].is_finite() || hi[i].is_finite());
        Ok(Self {
            h: h.to_owned(),
            f: f.to_owned(),
            bounded,
            free,
        })
    }

    /// The optimum as a linear map of ζ: bounded coordinates from `col0` on, free ones
    /// −H_FF⁻¹(H_FB z_B + (Fθ)_F) with θ = `theta` (a map of ζ).
    fn map(&self, theta: &Mat<f64>, col0: usize) -> Result<Mat<f64>, GlobalError> {
        let n = self.h.nrows();
        let nc = theta.ncols();
        let mut z = Mat::<f64>::zeros(n, nc);
        for (j, &b) in self.bounded.iter().enumerate() {
            z[(b, col0 + j)] = 1.0;
        }
        if !self.free.is_empty() {
            let nf = self.free.len();
            let hff = Mat::from_fn(nf, nf, |a, b| self.h[(self.free[a], self.free[b])]);
            let ft = mul(self.f.as_ref(), theta.as_ref());
            // rhs = H_FB z_B + (Fθ)_F as a map of ζ.
            let mut rhs = Mat::from_fn(nf, nc, |a, c| ft[(self.free[a], c)]);
            for (j, &b) in self.bounded.iter().enumerate() {
                for a in 0..nf {
                    rhs[(a, col0 + j)] += self.h[(self.free[a], b)];
                }
            }
            let llt = hff.llt(faer::Side::Lower).map_err(|_| GlobalError::Qp {
                what: "qp",
                why: "the Hessian is not positive definite",
            })?;
            let sol = llt.solve(&rhs);
            for a in 0..nf {
                for c in 0..nc {
                    z[(self.free[a], c)] = -sol[(a, c)];
                }
            }
        }
        Ok(z)
    }

    /// The rows with a bound of the gradient g = Hz* + Fθ, as maps of ζ (σ's per-row factors).
    fn bounded_gradient(&self, z: &Mat<f64>, theta: &Mat<f64>) -> Mat<f64> {
        let mut g = mul(self.h.as_ref(), z.as_ref());
        add(&mut g, &mul(self.f.as_ref(), theta.as_ref()));
        Mat::from_fn(self.bounded.len(), g.ncols(), |a, c| {
            g[(self.bounded[a], c)]
        })
    }

    /// σ = −z*ᵀ(Hz* + Fθ) as a symmetric form on ζ.
    fn vi_form(&self, z: &Mat<f64>, theta: &Mat<f64>) -> Mat<f64> {
        let mut g = mul(self.h.as_ref(), z.as_ref());
        add(&mut g, &mul(self.f.as_ref(), theta.as_ref()));
        let zg = mul(z.transpose(), g.as_ref());
        let nc = z.ncols();
        Mat::from_fn(nc, nc, |i, j| -0.5 * (zg[(i, j)] + zg[(j, i)]))
    }
}

/// The global loop of one (scenario, method) pair: every matrix of the LMI except the
/// scalars, on ζ = (X, z*_B, d, U*_B, w).
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct GlobalLoop {
    /// The lifted loop it was built from (K_lin's).
    pub lifted: LiftedLoop,
    /// The method's certificate φ(K) in the weighted norm `d_inv` uses.
    pub cert: Certificate,
    /// The inner-level rate of the same map, where one exists (min(φ, φ_iqc) is used).
    pub inner: Option<super::InnerRate>,
    /// 1/D_i: the weights of ‖·‖ in which φ holds (all 1 without Jacobi scaling).
    pub d_inv: Vec<f64>,
    n_x: usize,
    n_v: usize,
    n_w: usize,
    /// X⁺ as a map of ζ.
    x_plus: Mat<f64>,
    /// Σ₁ (MHE optimum), Σ₃ (MPC optimum, None without constraints).
    sigma_mhe: Mat<f64>,
    sigma_mpc: Option<Mat<f64>>,
    /// W E_X − Z* and E_d, weighted by D⁻¹: σ₂ = φ²‖a‖² − ‖b‖².
    sig2_a: Mat<f64>,
    sig2_b: Mat<f64>,
    /// x̂_t as a map of ζ.
    xhat: Mat<f64>,
    /// Coordinates of the MHE's z with a bound (σ₁'s channel; 0: σ₁ ≡ 0).
    mhe_bounded: usize,
    /// Per-row factors of σ₁ and σ₃: z*_B at columns `o_z..`, U*_B at `o_u..`, and the
    /// bounded rows of their gradients as maps of ζ (σ = −Σ_i z_i g_i over these rows).
    o_z: usize,
    o_u: usize,
    grad_mhe: Mat<f64>,
    grad_mpc: Mat<f64>,
    /// z*_t and U*_t as maps of ζ (for tests and sampling).
    zstar: Mat<f64>,
    d_col: usize,
    /// A form added to the supply (the rounding's homogeneous constraints, `precision`).
    extra_supply: Option<Mat<f64>>,
}

fn mul(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(a.nrows(), b.ncols());
    faer::linalg::matmul::matmul(out.as_mut(), faer::Accum::Replace, a, b, 1.0, Par::Seq);
    out
}

fn add(a: &mut Mat<f64>, b: &Mat<f64>) {
    for j in 0..a.ncols() {
        for i in 0..a.nrows() {
            a[(i, j)] += b[(i, j)];
        }
    }
}

fn sym_of(m: &Mat<f64>) -> Sym {
    let n = m.nrows();
    let mut s = Sym::zeros(n);
    for i in 0..n {
        for j in 0..n {
            s.a[i * n + j] = 0.5 * (m[(i, j)] + m[(j, i)]);
        }
    }
    s
}

mod build;
mod chain;
mod lmi;
mod precision;
mod rows;

pub use build::{LoopSize, global_loop, global_loop_boxes, global_loop_with, loop_size};
pub use chain::{
    ChainAttempt, ChainCertificate, ChainError, ChainOptions, ChainScan, IterationChain,
    iteration_chain,
};
pub use lmi::RefineGrid;
pub use precision::{
    FistaSteps, JacobiSteps, LoopRounding, PrecisionCertificate, PrecisionVoid, StepRounding,
    certify_precision, loop_rounding,
};
pub use rows::RowSearch;

impl GlobalLoop {
    /// dim X.
    pub fn n_x(&self) -> usize {
        self.n_x
    }
    /// dim ζ = n_X + n_v.
    pub fn n_zeta(&self) -> usize {
        self.n_x + self.n_v
    }
    /// X⁺ as a map of ζ.
    pub fn x_plus_map(&self) -> MatRef<'_, f64> {
        self.x_plus.as_ref()
    }
    /// z*_t as a map of ζ.
    pub fn zstar_map(&self) -> MatRef<'_, f64> {
        self.zstar.as_ref()
    }
    /// x̂_t as a map of ζ.
    pub fn xhat_map(&self) -> MatRef<'_, f64> {
        self.xhat.as_ref()
    }
    /// The column of ζ where d starts (after X and z*_B).
    pub fn d_offset(&self) -> usize {
        self.d_col
    }
    /// Whether the controller's optimum is a channel (a finite input bound).
    pub fn has_mpc_channel(&self) -> bool {
        self.sigma_mpc.is_some()
    }

    /// The lifted state X_t = (x_t, u, y and x̂ of the last M samples, z⁰_t[, U_{t−1}]) of a
    /// running loop at its current t ≥ M, in this loop's layout: the point at which the
    /// certificate's storage ‖X_t‖²_P is read along a trajectory (tests, soundness runs).
    /// Allocates the result; [`GlobalLoop::lifted_state_into`] writes into a buffer.
    ///
    /// ```no_run
    /// # fn demo(r: &closed_loop::scenario::ResolvedScenario) -> Result<(), Box<dyn std::error::Error>> {
    /// use closed_loop::scenario::LoopOptions;
    /// use iss_certificate::lure::global::global_loop;
    /// let o = LoopOptions::from_scenario(r.scenario())?;
    /// let gl = global_loop(r, &o)?;
    /// let mut cl = r.build_loop(&o)?;
    /// for _ in 0..gl.lifted.layout().horizon {
    ///     cl.step()?;
    /// }
    /// let x_m = gl.lifted_state(&cl)?; // X_M: ‖X_M‖²_P starts the ISS bound
    /// assert_eq!(x_m.len(), gl.n_x());
    /// # Ok(()) }
    /// ```
    pub fn lifted_state<D: Disturbance>(
        &self,
        cl: &ClosedLoop<ScenarioEstimator, ScenarioController, D>,
    ) -> Result<Vec<f64>, GlobalError> {
        let mut x = vec![0.0; self.lifted.layout().dim()];
        self.lifted_state_into(cl, &mut x)?;
        Ok(x)
    }

    /// [`GlobalLoop::lifted_state`] into `out` (length dim X); allocates nothing.
    pub fn lifted_state_into<D: Disturbance>(
        &self,
        cl: &ClosedLoop<ScenarioEstimator, ScenarioController, D>,
        out: &mut [f64],
    ) -> Result<(), GlobalError> {
        let l = self.lifted.layout();
        let (t, tr) = (cl.t(), cl.trace());
        let err = GlobalError::LiftedState {
            t,
            horizon: l.horizon,
            dim: l.dim(),
        };
        if t < l.horizon || out.len() != l.dim() {
            return Err(err);
        }
        let copy = |out: &mut [f64], at: usize, v: Option<&[f64]>, n: usize| match v {
            Some(v) if v.len() == n => {
                out[at..at + n].copy_from_slice(v);
                true
            }
            _ => false,
        };
        let mut ok = copy(out, 0, Some(cl.state()), l.nx);
        for j in 0..l.horizon {
            let s = t - l.horizon + j;
            ok &= copy(out, l.u_window(j), tr.u(s), l.nu);
            ok &= copy(out, l.y_window(j), tr.y(s), l.ny);
            ok &= copy(out, l.estimates(j), tr.x_hat(s), l.nx);
        }
        let z0 = cl.estimator().warm_start_point();
        ok &= copy(out, l.warm_start(), Some(z0), l.nz);
        if l.n_controller > 0 {
            let u_prev = match cl.controller() {
                ScenarioController::Suboptimal(c) => Some(c.input_sequence()),
                _ => None,
            };
            ok &= copy(out, l.controller(), u_prev, l.n_controller);
        }
        if ok { Ok(()) } else { Err(err) }
    }

    /// φ(K) used: min(φ, φ_iqc) of the map in the weighted norm.
    pub fn phi(&self, k: usize) -> f64 {
        match &self.inner {
            Some(r) => r.phi_min(&self.cert, k),
            None => self.cert.phi(k),
        }
    }
}
