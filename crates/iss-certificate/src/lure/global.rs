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

use closed_loop::scenario::{LoopOptions, ResolvedScenario, ScenarioController};
use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef, Par};
use mhe_core::WarmStart as MheWarmStart;
use qp_iter::{Certificate, IterationMap, MethodMap, ParametricQp};

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
    /// τ₁ (MHE optimum), τ₃ (MPC optimum; 0 without one); τ₂ = 1.
    pub tau: [f64; 2],
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
    /// z*_t and U*_t as maps of ζ (for tests and sampling).
    zstar: Mat<f64>,
    d_col: usize,
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

/// The global loop of `options.method` on `resolved` (K does not matter: the LMI sees K only
/// through φ(K)).
///
/// Errors: as [`crate::linear::linear_stability`]; a method whose φ does not fit eq. (11);
/// the shifted warm start; a QP with general rows or without 0 in its box; the sub-optimal
/// MPC ([`GlobalError`]).
pub fn global_loop(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
) -> Result<GlobalLoop, GlobalError> {
    global_loop_with(resolved, options, true)
}

/// As [`global_loop`]; with `boxes = false` every bound of both QPs is dropped (the optimum is
/// the unconstrained one, σ₁ = σ₃ = 0 exactly): the linear loop of K_lin with only the
/// iteration error uncertain — a diagnostic and the object of the ρ_lin ≥ 1 refusal test.
pub fn global_loop_with(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    boxes: bool,
) -> Result<GlobalLoop, GlobalError> {
    let mut quiet = resolved.clone();
    quiet.set_noise_scale(0.0);
    let mut opts = *options;
    opts.steps = 1;
    opts.iterations = 1;
    opts.exact_mhe_solve = false;
    let cl = quiet.build_loop(&opts).map_err(LinearError::from)?;
    let est = cl.estimator();
    if est.config().warm_start != MheWarmStart::Paper {
        return Err(GlobalError::WarmStart);
    }
    let m = est.config().horizon;
    let map = est.map(m).ok_or(LinearError::Internal(
        "the MHE has no map for window length M",
    ))?;
    let name = options.method.name().to_string();
    // φ in the norm of the map that runs: for Jacobi variants the inner map's bound on
    // y = D⁻¹z (no κ(D) factor).
    let (cert, inner, d_inv) = match map {
        MethodMap::Scaled(s) => (
            s.inner().certificate().clone(),
            super::rate_of_map(s.inner(), &name).ok(),
            s.scaling().iter().map(|d| 1.0 / d).collect::<Vec<_>>(),
        ),
        other => (
            other.certificate().clone(),
            super::rate_of_map(other, &name).ok(),
            vec![1.0; map.problem().n()],
        ),
    };
    if !cert.fits_eq11 {
        return Err(GlobalError::Phi { method: name });
    }
    let mut mhe = Optimum::of(map.problem(), "mhe")?;
    let plant = cl.plant();
    let (nx, nu) = (plant.nx(), plant.nu());
    let (mpc, law) = match cl.controller() {
        ScenarioController::Exact(_) => {
            let qp = quiet.mpc().map_err(LinearError::from)?.qp();
            let o = Optimum::of(qp, "mpc")?;
            // L = −E₀H⁻¹F.
            let llt = qp
                .h()
                .to_owned()
                .llt(faer::Side::Lower)
                .map_err(|_| GlobalError::Qp {
                    what: "mpc",
                    why: "the Hessian is not positive definite",
                })?;
            let sol = llt.solve(qp.f());
            let l = Mat::from_fn(nu, qp.n_theta(), |i, j| -sol[(i, j)]);
            (o, l)
        }
        ScenarioController::SaturatedLqr(c) => {
            let k = c.gain();
            let set = c.input_set();
            let o = Optimum::of_box(
                Mat::<f64>::identity(nu, nu).as_ref(),
                k.as_ref(),
                set.lower(),
                set.upper(),
                "mpc",
            )?;
            let l = Mat::from_fn(nu, nx, |i, j| -k[(i, j)]);
            (o, l)
        }
        ScenarioController::Suboptimal(_) => return Err(GlobalError::Controller),
    };
    let mut mpc = mpc;
    if !boxes {
        for o in [&mut mhe, &mut mpc] {
            o.free = (0..o.h.nrows()).collect();
            o.bounded.clear();
        }
    }
    let lifted = LiftedLoop::from_loop(&cl, &quiet, options.method, Par::Seq)?;
    let lay = lifted.layout();
    let (n, nz) = (lay.dim(), lay.nz);
    let (a_loop, g_z) = lifted.split_at_iterate(Par::Seq);
    let s_theta = lifted.parameter_selection();
    let (nw1, nw2) = (plant.nw1(), plant.nw2());
    let nw = nw1 + nw2;
    let nzb = mhe.bounded.len();
    let nub = mpc.bounded.len();
    let (o_z, o_d) = (n, n + nzb);
    let o_u = o_d + nz;
    let o_w = o_u + nub;
    let nc = o_w + nw;
    // θ_t as a map of ζ.
    let theta = Mat::from_fn(s_theta.nrows(), nc, |i, j| {
        if j < n { s_theta[(i, j)] } else { 0.0 }
    });
    let zstar = mhe.map(&theta, o_z)?;
    let sigma_mhe = mhe.vi_form(&zstar, &theta);
    let mut zk = zstar.clone();
    for i in 0..nz {
        zk[(i, o_d + i)] += 1.0;
    }
    // x̂_t: the newest estimate row block of X⁺ (X_θ S_θ X + X_z zᴷ).
    let est = lay.estimates(lay.horizon - 1);
    let mut xhat = Mat::from_fn(
        nx,
        nc,
        |i, j| if j < n { a_loop[(est + i, j)] } else { 0.0 },
    );
    add(&mut xhat, &mul(g_z.as_ref().subrows(est, nx), zk.as_ref()));
    // U* of the controller and u = E₀U* (the saturated LQR: U* = u).
    let ustar = mpc.map(&xhat, o_u)?;
    let sigma_mpc = if nub > 0 {
        Some(mpc.vi_form(&ustar, &xhat))
    } else {
        None
    };
    let u = ustar.as_ref().subrows(0, nu).to_owned();
    // B_u: u_t enters x_{t+1} (B) and the newest u-window entry.
    let b = plant.b();
    let mut b_u = Mat::<f64>::zeros(n, nu);
    for i in 0..nx {
        for j in 0..nu {
            b_u[(i, j)] = b[(i, j)];
        }
    }
    let u_new = lay.u_window(lay.horizon - 1);
    for j in 0..nu {
        b_u[(u_new + j, j)] = 1.0;
    }
    // 𝒜, 𝒢_z include u = L x̂: take it out and put the channel's u in.
    let bl = mul(b_u.as_ref(), law.as_ref());
    let a0 = {
        let mut a0 = a_loop.clone();
        let xh_x = a_loop.as_ref().subrows(est, nx);
        let sub = mul(bl.as_ref(), xh_x);
        for i in 0..n {
            for j in 0..n {
                a0[(i, j)] -= sub[(i, j)];
            }
        }
        a0
    };
    let g0 = {
        let mut g0 = g_z.clone();
        let sub = mul(bl.as_ref(), g_z.as_ref().subrows(est, nx));
        for i in 0..n {
            for j in 0..nz {
                g0[(i, j)] -= sub[(i, j)];
            }
        }
        g0
    };
    let mut x_plus = Mat::from_fn(n, nc, |i, j| if j < n { a0[(i, j)] } else { 0.0 });
    add(&mut x_plus, &mul(g0.as_ref(), zk.as_ref()));
    add(&mut x_plus, &mul(b_u.as_ref(), u.as_ref()));
    let (e, f) = (plant.e(), plant.f());
    for i in 0..nx {
        for j in 0..nw1 {
            x_plus[(i, o_w + j)] += e[(i, j)];
        }
    }
    let y_new = lay.y_window(lay.horizon - 1);
    for i in 0..lay.ny {
        for j in 0..nw2 {
            x_plus[(y_new + i, o_w + nw1 + j)] += f[(i, j)];
        }
    }
    // σ₂ pieces: a = D⁻¹(z⁰ − z*), z⁰ = the warm-start block of X; b = D⁻¹d.
    let ws = lay.warm_start();
    let sig2_a = Mat::from_fn(nz, nc, |i, j| {
        let w = if j == ws + i { 1.0 } else { 0.0 };
        d_inv[i] * (w - zstar[(i, j)])
    });
    let sig2_b = Mat::from_fn(nz, nc, |i, j| if j == o_d + i { d_inv[i] } else { 0.0 });
    Ok(GlobalLoop {
        lifted,
        cert,
        inner,
        d_inv,
        n_x: n,
        n_v: nc - n,
        n_w: nw,
        x_plus,
        sigma_mhe,
        sigma_mpc,
        sig2_a,
        sig2_b,
        xhat,
        mhe_bounded: nzb,
        zstar,
        d_col: o_d,
    })
}

/// The pieces of one LMI evaluation.
struct Terms {
    /// Π (the supply: multipliers and −γ²‖w‖²), N × N.
    pi: Mat<f64>,
}

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

    /// φ(K) used: min(φ, φ_iqc) of the map in the weighted norm.
    pub fn phi(&self, k: usize) -> f64 {
        match &self.inner {
            Some(r) => r.phi_min(&self.cert, k),
            None => self.cert.phi(k),
        }
    }

    fn supply(&self, phi: f64, tau1: f64, tau3: f64) -> Terms {
        let nc = self.n_zeta();
        let mut pi = Mat::<f64>::zeros(nc, nc);
        let aa = mul(self.sig2_a.transpose(), self.sig2_a.as_ref());
        let bb = mul(self.sig2_b.transpose(), self.sig2_b.as_ref());
        for i in 0..nc {
            for j in 0..nc {
                pi[(i, j)] = tau1 * self.sigma_mhe[(i, j)] + phi * phi * aa[(i, j)] - bb[(i, j)];
            }
        }
        if let Some(s3) = &self.sigma_mpc {
            for i in 0..nc {
                for j in 0..nc {
                    pi[(i, j)] += tau3 * s3[(i, j)];
                }
            }
        }
        Terms { pi }
    }

    /// The LMI matrix X⁺ᵀPX⁺ − ρ²E_XᵀPE_X + Π, formed afresh, with the entrywise scale of
    /// its rounding: (|X⁺|ᵀ|P||X⁺| + |Π| + ρ²|P|)_ij.
    fn lmi(&self, p: &Mat<f64>, rho: f64, pi: &Mat<f64>) -> (Sym, Sym) {
        let (n, nc) = (self.n_x, self.n_zeta());
        let px = mul(p.as_ref(), self.x_plus.as_ref());
        let q = mul(self.x_plus.transpose(), px.as_ref());
        let abs = |m: &Mat<f64>| Mat::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)].abs());
        let (xa, pa) = (abs(&self.x_plus), abs(p));
        let qa = mul(xa.transpose(), mul(pa.as_ref(), xa.as_ref()).as_ref());
        let mut m = Sym::zeros(nc);
        let mut sc = Sym::zeros(nc);
        for i in 0..nc {
            for j in 0..nc {
                let mut v = 0.5 * (q[(i, j)] + q[(j, i)]) + 0.5 * (pi[(i, j)] + pi[(j, i)]);
                let mut e = qa[(i, j)].max(qa[(j, i)]) + pi[(i, j)].abs().max(pi[(j, i)].abs());
                if i < n && j < n {
                    let t = rho * rho * 0.5 * (p[(i, j)] + p[(j, i)]);
                    v -= t;
                    e += t.abs();
                }
                m.a[i * nc + j] = v;
                sc.a[i * nc + j] = e;
            }
        }
        (m, sc)
    }

    /// The independent check: P ≻ 0 and the LMI ⪯ 0, by Jacobi eigenvalues of the matrices
    /// equilibrated by a positive diagonal congruence D (d_i = scale_ii^(−½): definiteness is
    /// invariant, and the entrywise rounding scales with it), each clearing 10³·dim·ε·Σ scale.
    /// Returns (LMI margin, P margin), −λ_max and λ_min relative to Σ scale.
    /// Err(Some(f)): negative but within the allowance, f = allowance/|λ| (how much more
    /// strictness the solve needs); Err(None): not negative definite.
    fn check(&self, p: &Mat<f64>, rho: f64, pi: &Mat<f64>) -> Result<(f64, f64), Option<f64>> {
        let tol =
            |n: usize, scale: f64| 1e3 * n as f64 * f64::EPSILON * scale.max(f64::MIN_POSITIVE);
        let equilibrate = |m: &Sym, sc: &Sym| {
            let n = m.n;
            let d: Vec<f64> = (0..n)
                .map(|i| {
                    let s = sc.at(i, i);
                    if s > 0.0 && s.is_finite() {
                        1.0 / s.sqrt()
                    } else {
                        1.0
                    }
                })
                .collect();
            let mut mm = Sym::zeros(n);
            let mut total = 0.0;
            for i in 0..n {
                for j in 0..n {
                    mm.a[i * n + j] = d[i] * d[j] * m.at(i, j);
                    total += d[i] * d[j] * sc.at(i, j);
                }
            }
            (mm, total)
        };
        let ps = sym_of(p);
        let pabs = Sym {
            n: ps.n,
            a: ps.a.iter().map(|v| v.abs()).collect(),
        };
        let (pe, pscale) = equilibrate(&ps, &pabs);
        let pev = sym_eigenvalues(&pe);
        let pt = tol(pe.n, pscale);
        if !(pev[0] > pt) {
            return Err((pev[0] > 0.0).then(|| 2.0 * pt / pev[0]));
        }
        let (m, sc) = self.lmi(p, rho, pi);
        let (me, scale) = equilibrate(&m, &sc);
        let top = sym_eigenvalues(&me).last().copied().ok_or(None)?;
        let t = tol(me.n, scale);
        if !(-top > t) {
            return Err((top < 0.0).then(|| 2.0 * t / -top));
        }
        Ok((-top / scale, pev[0] / pscale))
    }

    /// A candidate P for fixed scalars: the minimal solution of the worst-case Riccati
    /// equation with a strict supply (δ on X, ε on v), by doubling; None if it diverges.
    fn riccati(&self, rho: f64, pi: &Mat<f64>, strict: f64) -> Option<Mat<f64>> {
        // w is not an input of this problem (γ = ∞): its γ comes from the P found
        // (`gamma2_for`).
        let (n, nv) = (self.n_x, self.n_v - self.n_w);
        let big = pi.as_ref();
        let scale = (0..n + nv)
            .map(|i| big[(i, i)].abs())
            .fold(0.0_f64, f64::max)
            .max(1e-300);
        let delta = strict * scale;
        // ε per input coordinate, relative to its own diagonal (the Jacobi weights D⁻² span
        // decades: one ε for all would swamp the small ones).
        let eps: Vec<f64> = (0..nv)
            .map(|i| strict * big[(n + i, n + i)].abs().max(1e-6 * scale))
            .collect();
        let r2 = rho * rho;
        // Cost c = −(Π + δE_X + εE_v)/ρ² of the min-form; dynamics (A, B)/ρ.
        let qc = Mat::from_fn(n, n, |i, j| {
            -(big[(i, j)] + if i == j { delta } else { 0.0 }) / r2
        });
        let sc = Mat::from_fn(n, nv, |i, j| -big[(i, n + j)] / r2);
        let rc = Mat::from_fn(nv, nv, |i, j| {
            -(big[(n + i, n + j)] + if i == j { eps[i] } else { 0.0 }) / r2
        });
        let llt = rc.llt(faer::Side::Lower).ok()?;
        let at = Mat::from_fn(n, n, |i, j| self.x_plus[(i, j)] / rho);
        let bt = Mat::from_fn(n, nv, |i, j| self.x_plus[(i, n + j)] / rho);
        let rinv_sct = llt.solve(sc.transpose().to_owned()); // Rc⁻¹Scᵀ
        let rinv_bt = llt.solve(bt.transpose().to_owned()); // Rc⁻¹B̃ᵀ
        let mut a = at.clone();
        let t = mul(bt.as_ref(), rinv_sct.as_ref());
        for i in 0..n {
            for j in 0..n {
                a[(i, j)] -= t[(i, j)];
            }
        }
        let mut g = mul(bt.as_ref(), rinv_bt.as_ref());
        let scs = mul(sc.as_ref(), rinv_sct.as_ref());
        let mut h = Mat::from_fn(n, n, |i, j| qc[(i, j)] - scs[(i, j)]);
        let h0 = norm_max(&h).max(1e-300);
        let eye = Mat::<f64>::identity(n, n);
        for _ in 0..64 {
            let mut w = mul(g.as_ref(), h.as_ref());
            add(&mut w, &eye);
            let lu = w.partial_piv_lu();
            let wa = lu.solve(&a);
            let wg = lu.solve(&g);
            let dh = mul(a.transpose(), mul(h.as_ref(), wa.as_ref()).as_ref());
            let dg = mul(a.as_ref(), mul(wg.as_ref(), a.transpose()).as_ref());
            let a_next = mul(a.as_ref(), wa.as_ref());
            let change = norm_max(&dh);
            add(&mut h, &dh);
            add(&mut g, &dg);
            symmetrise(&mut h);
            symmetrise(&mut g);
            a = a_next;
            let hn = norm_max(&h);
            if !hn.is_finite() || hn > 1e12 * h0 {
                return None;
            }
            if change <= 1e-14 * hn {
                let p = Mat::from_fn(n, n, |i, j| -h[(i, j)]);
                return Some(p);
            }
        }
        None
    }

    /// Tries the scalars (τ₁, τ₃) at (φ, ρ, γ²); a P that passes the independent check.
    /// γ² for a P of the LMI without w: twice the smallest γ² that the Schur complement
    /// allows, λ_max(D + Cᵀ(−M₀)⁻¹C) with M₀ the LMI on the other coordinates, C its
    /// coupling to w and D = ℬᵀPℬ. None if M₀ is not negative definite.
    fn gamma2_for(&self, p: &Mat<f64>, rho: f64, pi: &Mat<f64>) -> Option<f64> {
        let (m, _) = self.lmi(p, rho, pi);
        let nc = m.n;
        let n0 = nc - self.n_w;
        let neg = Mat::from_fn(n0, n0, |i, j| -m.at(i, j));
        let c = Mat::from_fn(n0, self.n_w, |i, j| m.at(i, n0 + j));
        let llt = neg.llt(faer::Side::Lower).ok()?;
        let x = llt.solve(&c);
        let mut s = mul(c.transpose(), x.as_ref());
        for i in 0..self.n_w {
            for j in 0..self.n_w {
                s[(i, j)] += m.at(n0 + i, n0 + j);
            }
        }
        let top = sym_eigenvalues(&sym_of(&s)).last().copied()?;
        let floor = 1e-9 * norm_max(p).max(f64::MIN_POSITIVE);
        let g2 = 2.0 * top.max(0.0) + floor;
        g2.is_finite().then_some(g2)
    }

    fn certify_scalars(
        &self,
        phi: f64,
        rho: f64,
        tau1: f64,
        tau3: f64,
    ) -> Option<GlobalCertificate> {
        let Terms { pi: pi0 } = self.supply(phi, tau1, tau3);
        // Strictness δ = ε relative to Π; raised (twice at most) when the check finds the LMI
        // negative but within its rounding allowance.
        let mut strict = 1e-6;
        let mut found = None;
        for _ in 0..3 {
            let p = self.riccati(rho, &pi0, strict)?;
            let gamma2 = self.gamma2_for(&p, rho, &pi0)?;
            let mut pi = pi0.clone();
            let nc = self.n_zeta();
            for k in 0..self.n_w {
                pi[(nc - self.n_w + k, nc - self.n_w + k)] -= gamma2;
            }
            match self.check(&p, rho, &pi) {
                Ok(m) => {
                    found = Some((p, gamma2, m));
                    break;
                }
                Err(Some(need)) => strict *= need.clamp(2.0, 1e4),
                Err(None) => return None,
            }
        }
        let (p, gamma2, (margin, p_margin)) = found?;
        let gamma = gamma2.sqrt();
        let nx = self.lifted.layout().nx;
        let rx = Mat::from_fn(nx, self.n_x, |i, j| if i == j { 1.0 } else { 0.0 });
        let est = self
            .lifted
            .layout()
            .estimates(self.lifted.layout().horizon - 1);
        let rest = Mat::from_fn(nx, self.n_x, |i, j| if j == est + i { 1.0 } else { 0.0 });
        let gain_x = readout_gain(&p, rho, gamma, rx.as_ref())?;
        let gain_e = gain_x + readout_gain(&p, rho, gamma, rest.as_ref())?;
        Some(GlobalCertificate {
            phi,
            rho,
            gamma,
            tau: [tau1, tau3],
            p,
            margin,
            p_margin,
            gain_x,
            gain_e,
        })
    }

    /// The multipliers tried: τ relative to the scale of σ₂'s form.
    fn tau_grid(&self, opts: &GlobalOptions) -> Vec<f64> {
        let k = opts.tau_points.max(2);
        (0..k)
            .map(|i| 10f64.powf(-4.0 + 8.0 * i as f64 / (k - 1) as f64))
            .collect()
    }

    /// A certificate at φ with ρ = `rho_max` (feasibility), trying the multiplier grid
    /// (τ₁ × τ₃; a single point for a channel without bounded coordinates).
    pub fn certify_phi(&self, phi: f64, opts: &GlobalOptions) -> Option<GlobalCertificate> {
        self.certify_phi_from(phi, opts, None)
    }

    /// As [`GlobalLoop::certify_phi`], trying `first` (multipliers that certified a nearby φ)
    /// before the grid.
    fn certify_phi_from(
        &self,
        phi: f64,
        opts: &GlobalOptions,
        first: Option<[f64; 2]>,
    ) -> Option<GlobalCertificate> {
        if let Some([t1, t3]) = first {
            if let Some(c) = self.certify_scalars(phi, opts.rho_max, t1, t3) {
                return Some(c);
            }
        }
        let grid = self.tau_grid(opts);
        let tau1s: Vec<f64> = if self.mhe_bounded > 0 {
            grid.clone()
        } else {
            vec![0.0]
        };
        let tau3s: Vec<f64> = if self.sigma_mpc.is_some() {
            grid
        } else {
            vec![0.0]
        };
        for &t1 in &tau1s {
            for &t3 in &tau3s {
                if first == Some([t1, t3]) {
                    continue;
                }
                if let Some(c) = self.certify_scalars(phi, opts.rho_max, t1, t3) {
                    return Some(c);
                }
            }
        }
        None
    }

    /// φ*: the largest φ (to `phi_tol`, relative) with a checked certificate, with it; None
    /// if even φ = 0 (d ≡ 0: the exact-MHE loop with the box) has none.
    pub fn phi_star(&self, opts: &GlobalOptions) -> Option<GlobalCertificate> {
        let mut best = self.certify_phi(0.0, opts)?;
        let mut tau = Some(best.tau);
        // Grow an upper bracket, then bisect.
        let mut lo = 0.0;
        let mut hi = 1e-3;
        while let Some(c) = self.certify_phi_from(hi, opts, tau) {
            tau = Some(c.tau);
            best = c;
            lo = hi;
            hi *= 4.0;
            if hi > 1e3 {
                return Some(best);
            }
        }
        while hi - lo > opts.phi_tol * hi {
            let mid = if lo == 0.0 {
                hi / 4.0
            } else {
                (lo * hi).sqrt()
            };
            match self.certify_phi_from(mid, opts, tau) {
                Some(c) => {
                    tau = Some(c.tau);
                    best = c;
                    lo = mid;
                }
                None => hi = mid,
            }
            if lo == 0.0 && hi < 1e-12 {
                break;
            }
        }
        Some(best)
    }

    /// K_glob: the first K ≤ `k_max` with φ(K) ≤ φ* (the certified K are exactly those, an
    /// interval since φ decreases in K), with the certificate at φ*.
    pub fn k_glob(&self, opts: &GlobalOptions) -> Option<(usize, GlobalCertificate)> {
        let cert = self.phi_star(opts)?;
        let k = super::first_k(|k| self.phi(k) <= cert.phi, opts.k_max)?;
        Some((k, cert))
    }

    /// A certificate at φ with the smallest ρ found (bisection to 10⁻³) from the multipliers
    /// that certify φ, then the one of smallest `gain_e` among ρ_min and four points between
    /// it and `base.rho` (the reported gains: ρ near 1 inflates 1/(1 − ρ²)).
    pub fn refine(&self, base: &GlobalCertificate) -> GlobalCertificate {
        let [t1, t3] = base.tau;
        let (mut lo, mut hi) = (0.0, base.rho);
        while hi - lo > 1e-3 {
            let mid = 0.5 * (lo + hi);
            if self.certify_scalars(base.phi, mid, t1, t3).is_some() {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let mut best = base.clone();
        for i in 0..5 {
            let rho = hi + (base.rho - hi) * i as f64 / 5.0;
            if let Some(c) = self.certify_scalars(base.phi, rho, t1, t3) {
                if c.gain_e < best.gain_e {
                    best = c;
                }
            }
        }
        best
    }
}

fn norm_max(m: &Mat<f64>) -> f64 {
    let mut s = 0.0_f64;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            s = s.max(m[(i, j)].abs());
        }
    }
    s
}

fn symmetrise(m: &mut Mat<f64>) {
    let n = m.nrows();
    for i in 0..n {
        for j in 0..i {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}
