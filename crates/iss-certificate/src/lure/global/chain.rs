//! The iteration chain (docs/theory.md §4b, §4c): the K inner iterations of the
//! projected-gradient family, of FISTA and of ADMM kept as exact steps inside the global LMI,
//! instead of only the φ-ball σ₂.
//!
//! PG (and PG-Jacobi, in its scaled coordinates) runs zᵏ⁺¹ = Π_Z(S zᵏ + S_θθ); FISTA (and
//! FISTA-Jacobi) runs zᵏ⁺¹ = Π_Z(S yᵏ + S_θθ) with yᵏ = zᵏ + β_k(zᵏ − zᵏ⁻¹), β₀ = β₁ = 0 (the
//! restart step and y₀ = x₀ of `qp_iter::fista`) and β_k = β after. Both have the window's
//! optimum as fixed point, z* = Π_Z(S z* + S_θθ). With eᵏ = zᵏ − z* and the pre-clamp
//! pᵏ = S(eᵏ + β_k(eᵏ − eᵏ⁻¹)) (PG: β = 0), every coordinate i with a bound obeys the
//! incremental sector of a scalar projection, e^{k+1}_i(pᵏ_i − e^{k+1}_i) ≥ 0, and every free
//! coordinate e^{k+1}_i = pᵏ_i exactly: the two methods differ only in this linear recursion
//! ([`IterationChain::momentum`]). ADMM (Douglas–Rachford on s = v + u) clamps its state
//! itself, δᵏ = Π_Z(sᵏ) − z* against εᵏ = sᵏ − s*, s* = z* + u* with the scaled dual
//! u* = −∇f(z*)/ρ linear in ζ, and updates εᵏ⁺¹ = Aεᵏ + Bδᵏ: K + 1 clamps, d = δᴷ.
//!
//! So ζ gains the bounded parts of every clamp's output but the last (e¹_B … e^{K−1}_B; d
//! keeps only its bounded part; the free parts are eliminated), the supply gains
//! Σ_k λ_k Σ_i μ_i D_i⁻² c_{k,i} with λ_k, μ_i ≥ 0, and σ₂ stays with its own multiplier τ₂ ≥ 0: every constraint holds on every
//! trajectory, so the certificate is sound exactly as Theorem L3 (i); Theorem L3's own
//! multipliers (λ = 0, τ₂ = 1) are tried first. The answer goes through the same independent
//! check ([`GlobalLoop`]'s `certify_supply`: the LMI matrix formed afresh, Jacobi eigenvalues
//! with a margin above its rounding, P ≻ 0 likewise).
//!
//! Size: dim ζ grows by n_B per iteration and the check is dense (O(dim³)), so chains above
//! [`ChainOptions::max_dim`] are refused ([`ChainError::TooLarge`]); the chain is meant for
//! K ≤ ~50.

use closed_loop::scenario::{LoopOptions, ResolvedScenario};
use faer::Mat;
use qp_iter::IterationMap;

use super::{GlobalCertificate, GlobalError, GlobalLoop, GlobalOptions, global_loop, mul};
use crate::linear::{LinearError, linearise};

mod recursion;
use recursion::{Step, recursion, step_of};

/// Why no iteration chain (or no chain of this size).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ChainError {
    /// The global loop itself has no form here.
    #[error(transparent)]
    Global(#[from] GlobalError),
    /// The method is not PG, FISTA or ADMM (or a Jacobi variant) with the probed linear form
    /// of its recursion (one linear map and a clamp per coordinate).
    #[error(
        "mhe.method = {method}: the iteration chain models pg, fista and admm (with their \
         parameters and Jacobi variants) only; choose one of them for mhe.method, or use \
         Theorem L3's φ-ball (lure::global::GlobalLoop::k_glob)"
    )]
    Method {
        /// The method.
        method: String,
    },
    /// K = 0: there is no iteration to chain.
    #[error("mhe.iterations = 0: the chain needs K ≥ 1")]
    ZeroIterations,
    /// The chain's LMI at this K is larger than the documented limit.
    #[error(
        "K = {k}: the chain's LMI would have dim ζ = {dim} > {max} (it grows by n_B = {n_b} \
         per iteration, so the chain reaches K ≤ {k_fit} here); for K above it use Theorem \
         L3's K_glob, or a smaller mhe.iterations"
    )]
    TooLarge {
        /// K asked for (the scenario's `mhe.iterations`, or a K of the chain's scan).
        k: usize,
        /// dim ζ at that K.
        dim: usize,
        /// The limit ([`ChainOptions::max_dim`]).
        max: usize,
        /// Bounded coordinates of z (ζ's growth per iteration).
        n_b: usize,
        /// The largest K whose chain fits the limit (0: not even K = 1).
        k_fit: usize,
    },
}

/// The search of [`IterationChain::certify_chain`].
#[derive(Debug, Clone, Copy)]
pub struct ChainOptions {
    /// Theorem L3's scalars (τ grid, ρ_max).
    pub global: GlobalOptions,
    /// Values of the chain's overall weight s (log-spaced, 10⁻³…10³ times σ₂'s scale
    /// against the chain's; plus τ₂ = 0).
    pub scale_points: usize,
    /// Ratios r of λ_k = s·rᵏ tried.
    pub ratios: [f64; 5],
    /// The largest dim ζ accepted (the check is a dense Jacobi eigenvalue problem: O(dim³)).
    pub max_dim: usize,
    /// Budget of the scan: Riccati solves at most over all K (the scan then says so).
    pub max_solves: usize,
    /// After the grid: a coordinate ascent of 1/ρ over (τ₁, τ₂, τ₃) and groups of the λ_k
    /// (`lure::global` rows' ascent) from the grid point of smallest ρ, with at most this
    /// many solves per K (0: the grid only).
    pub ascent_solves: usize,
}

impl Default for ChainOptions {
    fn default() -> Self {
        Self {
            global: GlobalOptions {
                tau_points: 5,
                ..GlobalOptions::default()
            },
            scale_points: 5,
            ratios: [1.0, 0.7, 1.4, 0.4, 2.5],
            max_dim: 1_500,
            max_solves: 20_000,
            ascent_solves: 400,
        }
    }
}

/// The PG-family or FISTA loop with its probed step, ready to be chained at any K.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct IterationChain {
    /// Theorem L3's loop (σ₁, σ₂, σ₃, the exact lifted dynamics).
    pub global: GlobalLoop,
    /// The method's linear recursion between clamps, in z coordinates.
    step: Step,
    bounded: Vec<usize>,
    free: Vec<usize>,
}

/// A checked chain certificate at K: ‖X_{t+1}‖²_P ≤ ρ²‖X_t‖²_P + γ²‖w_t‖² for t ≥ M when the
/// MHE runs exactly K iterations of its method (Theorem L3's statement, with the chain's constraints).
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct ChainCertificate {
    /// K.
    pub k: usize,
    /// τ₂ ≥ 0, σ₂'s multiplier (0: the chain alone).
    pub tau2: f64,
    /// λ_j ≥ 0, the multiplier of clamp j's sector constraints (one per clamp: K for PG and
    /// FISTA, K + 1 for ADMM).
    pub lambda: Vec<f64>,
    /// μ_i > 0 per bounded coordinate (the multiplier of c_{k,i} is λ_k·μ_i); empty: all 1.
    pub mu: Vec<f64>,
    /// P, ρ, γ, τ₁, τ₃, the margins and gains (its `phi` is φ(K), its `lambda` empty).
    pub cert: GlobalCertificate,
}

/// The chain at one K: the transformed loop on ζ' and the factors of the K forms,
/// c_k = ½(A_kᵀB_k + B_kᵀA_k), stacked: rows k·n_B … of `a`, `b`.
struct ChainAt {
    gl: GlobalLoop,
    /// K, the iterations.
    k_iter: usize,
    /// The clamps (one λ each): K, or K + 1 for ADMM.
    k: usize,
    a: Mat<f64>,
    b: Mat<f64>,
}

/// One search at one K.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct ChainAttempt {
    /// The checked certificate, if found.
    pub cert: Option<ChainCertificate>,
    /// Riccati solves used.
    pub solves: usize,
    /// Without a certificate: the smallest ρ at which the ascent's oracle (Riccati, P ≻ 0, the
    /// LMI without w negative definite by Cholesky) held — unchecked, a distance to
    /// feasibility, not a certificate; None if no grid point was feasible at ρ = 2.
    pub rho_reached: Option<f64>,
}

/// What the scan found.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct ChainScan {
    /// The smallest K certified by the chain (with its certificate), None if none up to the
    /// last K tried.
    pub certified: Option<ChainCertificate>,
    /// The last K tried.
    pub last_k: usize,
    /// Whether the scan stopped on the budget or the size limit before `k_max` (so "none"
    /// means "not computed within the budget", not "void").
    pub stopped: bool,
    /// Riccati solves used.
    pub solves: usize,
}

/// The iteration chain of `options.method` on `resolved`.
///
/// Errors: as [`global_loop`]; a method outside PG, FISTA, ADMM and their Jacobi variants
/// ([`ChainError::Method`]).
pub fn iteration_chain(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
) -> Result<IterationChain, ChainError> {
    let global = global_loop(resolved, options)?;
    let mut quiet = resolved.clone();
    quiet.set_noise_scale(0.0);
    let mut opts = *options;
    opts.steps = 1;
    opts.iterations = qp_iter::Iterations::ONE;
    opts.exact_mhe_solve = false;
    let cl = quiet
        .build_loop(&opts)
        .map_err(|e| GlobalError::from(LinearError::from(e)))?;
    let est = cl.estimator();
    let map = est
        .map(est.config().horizon)
        .ok_or(GlobalError::from(LinearError::Internal(
            "the MHE has no map for window length M",
        )))?;
    let method = || ChainError::Method {
        method: options.method.name().to_string(),
    };
    let rec = recursion(map).ok_or_else(method)?;
    let lin = linearise(map, "MHE").map_err(GlobalError::from)?;
    let step = step_of(&lin, &rec).ok_or_else(method)?;
    let nz = map.problem().n();
    let set = map.problem().zset();
    let (bounded, free): (Vec<usize>, Vec<usize>) =
        (0..nz).partition(|&i| set.lower()[i].is_finite() || set.upper()[i].is_finite());
    if bounded.len() != global.mhe_bounded {
        return Err(GlobalError::from(LinearError::Internal(
            "the chain's bounded coordinates differ from the global loop's",
        ))
        .into());
    }
    Ok(IterationChain {
        global,
        step,
        bounded,
        free,
    })
}

impl IterationChain {
    /// n_B: bounded coordinates of z (ζ grows by n_B per iteration).
    pub fn n_b(&self) -> usize {
        self.bounded.len()
    }

    /// β_k, the momentum of the clamp of iteration k + 1 (pᵏ = S(eᵏ + β_k(eᵏ − eᵏ⁻¹))): 0 for
    /// PG; for FISTA 0 at k = 0, 1 (the restart step, y₀ = x₀) and β from k = 2 on.
    pub fn momentum(&self, k: usize) -> f64 {
        match &self.step {
            Step::Gradient { beta, .. } if k >= 2 => *beta,
            _ => 0.0,
        }
    }

    /// The clamps of K iterations: K (PG, FISTA), K + 1 (ADMM: v⁰ … vᴷ).
    pub fn clamps(&self, k: usize) -> usize {
        match self.step {
            Step::Gradient { .. } => k,
            Step::Splitting { .. } => k.saturating_add(1),
        }
    }

    fn n_z(&self) -> usize {
        match &self.step {
            Step::Gradient { s_z, .. } => s_z.nrows(),
            Step::Splitting { e, .. } => e.nrows(),
        }
    }

    /// The method's recursion from e⁰ (any columns) through its `clamps(K)` clamps, the clamp
    /// j given by `clamp`(j, its input); returns d = the last clamp's output. PG, FISTA: the
    /// input pᵏ = S_z(eᵏ + β_k(eᵏ − eᵏ⁻¹)), the output e^{k+1}. ADMM: the input εᵏ, the output
    /// δᵏ, ε^{k+1} = Aεᵏ + Bδᵏ from ε⁰ = Ee⁰. The one place the methods differ.
    fn unroll(
        &self,
        e0: Mat<f64>,
        k: usize,
        mut clamp: impl FnMut(usize, &Mat<f64>) -> Mat<f64>,
    ) -> Mat<f64> {
        match &self.step {
            Step::Gradient { s_z, .. } => {
                let mut prev = e0.clone();
                let mut e = e0;
                for step in 0..k {
                    let b = self.momentum(step);
                    let y = Mat::from_fn(e.nrows(), e.ncols(), |i, j| {
                        e[(i, j)] + b * (e[(i, j)] - prev[(i, j)])
                    });
                    let next = clamp(step, &mul(s_z.as_ref(), y.as_ref()));
                    prev = std::mem::replace(&mut e, next);
                }
                e
            }
            Step::Splitting { e, a, b } => {
                let mut eps = mul(e.as_ref(), e0.as_ref());
                let mut delta = clamp(0, &eps);
                for step in 1..=k {
                    eps = mul(a.as_ref(), eps.as_ref());
                    super::add(&mut eps, &mul(b.as_ref(), delta.as_ref()));
                    delta = clamp(step, &eps);
                }
                delta
            }
        }
    }

    /// The chain's recursion with every clamp the identity: eᴷ = G_K e⁰, the K-step map of the
    /// method's linear part (what Theorem L3b (ii) rests on; tests compare it with
    /// `linear::IterationLinearisation::k_step`).
    pub fn free_response(&self, k: usize) -> Mat<f64> {
        let n = self.n_z();
        self.unroll(Mat::identity(n, n), k, |_, p| p.clone())
    }

    /// [`ChainError::TooLarge`] at K with the limit `max`.
    pub(crate) fn too_large(&self, k: usize, max: usize) -> ChainError {
        // dim grows with K (by n_B per clamp): the largest K that fits, by bisection.
        let (mut lo, mut hi) = (0usize, k);
        while lo < hi {
            let mid = lo + (hi - lo).div_ceil(2);
            if mid > 0 && self.dim(mid) <= max {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        ChainError::TooLarge {
            k,
            dim: self.dim(k),
            max,
            n_b: self.n_b(),
            k_fit: lo,
        }
    }

    /// dim ζ of the chain at K: Theorem L3's with d's free part eliminated and
    /// (clamps − 1)·n_B added.
    pub fn dim(&self, k: usize) -> usize {
        let nz = self.n_z();
        (self.global.n_zeta() - nz).saturating_add(self.n_b().saturating_mul(self.clamps(k)))
    }

    /// The chain at K: ζ' = (X, z*_B, d_B, U*_B, the clamps' outputs but the last (bounded
    /// parts), w) and ζ = Tζ'.
    fn at(&self, k: usize, opts: &ChainOptions) -> Result<ChainAt, ChainError> {
        if k == 0 {
            return Err(ChainError::ZeroIterations);
        }
        let dim = self.dim(k);
        if dim > opts.max_dim {
            return Err(self.too_large(k, opts.max_dim));
        }
        let g = &self.global;
        let (nz, nb, nk) = (self.n_z(), self.n_b(), self.clamps(k));
        let nc = g.n_zeta();
        let (o_d, o_u) = (g.d_col, g.o_u);
        let n_after_u = nc - o_u; // U*_B, (r_h), w, …
        let nub = g.grad_mpc.nrows();
        // New columns.
        let o_db = o_d; // d_B right after z*_B
        let o_u2 = o_db + nb;
        let o_chain = o_u2 + nub;
        let o_rest = o_chain + (nk - 1) * nb; // what followed U*_B
        debug_assert_eq!(o_rest + n_after_u - nub, dim);
        // T₀: ζ' → ζ with the d rows still empty.
        let mut t = Mat::<f64>::zeros(nc, dim);
        for j in 0..o_d {
            t[(j, j)] = 1.0;
        }
        for j in 0..nub {
            t[(o_u + j, o_u2 + j)] = 1.0;
        }
        for j in nub..n_after_u {
            t[(o_u + j, o_rest + j - nub)] = 1.0;
        }
        let zstar = mul(g.zstar.as_ref(), t.as_ref());
        let ws = g.lifted.layout().warm_start();
        // e⁰ = W X − z*.
        let mut e = Mat::from_fn(nz, dim, |i, j| -zstar[(i, j)]);
        for i in 0..nz {
            e[(i, ws + i)] += 1.0;
        }
        let mut fa = Mat::<f64>::zeros(nk * nb, dim);
        let mut fb = Mat::<f64>::zeros(nk * nb, dim);
        let e = self.unroll(e, k, |step, pre| {
            // The clamp's output: a new chain column per bounded coordinate (d_B at the last
            // clamp), the free rows exactly its input.
            let col = if step + 1 == nk {
                o_db
            } else {
                o_chain + step * nb
            };
            let mut next = Mat::<f64>::zeros(nz, dim);
            for (a, &i) in self.bounded.iter().enumerate() {
                next[(i, col + a)] = 1.0;
            }
            for &i in &self.free {
                for j in 0..dim {
                    next[(i, j)] = pre[(i, j)];
                }
            }
            // c = Σ_{i∈B} D_i⁻² e⁺_i(p_i − e⁺_i), as ½(AᵀB + BᵀA): the sector in the map's
            // own coordinates y = D⁻¹z, where ‖S_y‖ ≤ 1 (in z, S_z = D S_y D⁻¹ spans the
            // decades of D and one weight per iteration could not balance its rows).
            for (r, &i) in self.bounded.iter().enumerate() {
                let w = g.d_inv[i];
                for j in 0..dim {
                    fa[(step * nb + r, j)] = w * next[(i, j)];
                    fb[(step * nb + r, j)] = w * (pre[(i, j)] - next[(i, j)]);
                }
            }
            next
        });
        // d = eᴷ fills T's d rows.
        for i in 0..nz {
            for j in 0..dim {
                t[(o_d + i, j)] = e[(i, j)];
            }
        }
        let right = |m: &Mat<f64>| mul(m.as_ref(), t.as_ref());
        let both = |m: &Mat<f64>| mul(t.transpose(), mul(m.as_ref(), t.as_ref()).as_ref());
        let gl = GlobalLoop {
            lifted: g.lifted.clone(),
            cert: g.cert.clone(),
            inner: g.inner.clone(),
            d_inv: g.d_inv.clone(),
            n_x: g.n_x,
            n_v: dim - g.n_x,
            n_w: g.n_w,
            x_plus: right(&g.x_plus),
            sigma_mhe: both(&g.sigma_mhe),
            sigma_mpc: g.sigma_mpc.as_ref().map(both),
            sig2_a: right(&g.sig2_a),
            sig2_b: right(&g.sig2_b),
            xhat: right(&g.xhat),
            mhe_bounded: g.mhe_bounded,
            o_z: g.o_z,
            o_u: o_u2,
            grad_mhe: right(&g.grad_mhe),
            grad_mpc: right(&g.grad_mpc),
            zstar,
            d_col: o_db,
            extra_supply: g.extra_supply.as_ref().map(both),
        };
        Ok(ChainAt {
            gl,
            k_iter: k,
            k: nk,
            a: fa,
            b: fb,
        })
    }

    /// A checked certificate of the chain LMI at K, or the smallest ρ the search reached.
    ///
    /// Errors: K = 0; a chain above [`ChainOptions::max_dim`] ([`ChainError::TooLarge`]).
    pub fn certify_chain(&self, k: usize, opts: &ChainOptions) -> Result<ChainAttempt, ChainError> {
        self.certify_chain_within(k, opts, usize::MAX)
    }

    /// [`IterationChain::certify_chain`] with at most `max_solves` Riccati solves (the
    /// caller's budget: an attempt with `solves >= max_solves` and no certificate was stopped
    /// by it, not refuted).
    ///
    /// Errors: as [`IterationChain::certify_chain`].
    pub fn certify_chain_within(
        &self,
        k: usize,
        opts: &ChainOptions,
        max_solves: usize,
    ) -> Result<ChainAttempt, ChainError> {
        let at = self.at(k, opts)?;
        Ok(at.search(self.global.phi(k), opts, max_solves))
    }

    /// The smallest K in 1..=`k_max` the chain certifies, scanning upwards (the certified set
    /// is not monotone a priori); stops early on the size limit or the solve budget.
    pub fn k_chain(&self, k_max: usize, opts: &ChainOptions) -> ChainScan {
        let mut solves = 0;
        let mut last_k = 0;
        for k in 1..=k_max {
            let Ok(at) = self.at(k, opts) else {
                return ChainScan {
                    certified: None,
                    last_k,
                    stopped: true,
                    solves,
                };
            };
            let left = opts.max_solves.saturating_sub(solves);
            let attempt = at.search(self.global.phi(k), opts, left);
            solves += attempt.solves;
            last_k = k;
            if let Some(c) = attempt.cert {
                return ChainScan {
                    certified: Some(c),
                    last_k,
                    stopped: false,
                    solves,
                };
            }
            if solves >= opts.max_solves {
                return ChainScan {
                    certified: None,
                    last_k,
                    stopped: k < k_max,
                    solves,
                };
            }
        }
        ChainScan {
            certified: None,
            last_k,
            stopped: false,
            solves,
        }
    }
}

fn attempt(
    cert: Option<ChainCertificate>,
    solves: usize,
    rho_reached: Option<f64>,
) -> ChainAttempt {
    ChainAttempt {
        cert,
        solves,
        rho_reached,
    }
}

impl ChainAt {
    /// Σ_k λ_k Σ_i μ_i c_{k,i} as a symmetric matrix on ζ' (μ = 𝟙 without `mu`).
    fn chain_form(&self, lambda: &[f64], mu: Option<&[f64]>) -> Mat<f64> {
        let nb = (self.a.nrows() / self.k.max(1)).max(1);
        let wa = Mat::from_fn(self.a.nrows(), self.a.ncols(), |r, j| {
            let m = mu.map_or(1.0, |mu| mu[r % nb]);
            lambda[r / nb] * m * self.a[(r, j)]
        });
        let ab = mul(wa.transpose(), self.b.as_ref());
        let n = ab.nrows();
        Mat::from_fn(n, n, |i, j| 0.5 * (ab[(i, j)] + ab[(j, i)]))
    }

    /// λ_k = rᵏ normalised so the largest is 1.
    fn profile(&self, r: f64) -> Vec<f64> {
        let top = (0..self.k)
            .map(|i| r.powi(i as i32))
            .fold(0.0_f64, f64::max);
        (0..self.k).map(|i| r.powi(i as i32) / top).collect()
    }

    /// Π = τ₁σ₁ + τ₂σ₂ + τ₃σ₃ + s·C (C = Σ_k λ_k c_k for the profile, `None`: no chain).
    fn supply(&self, phi: f64, tau: [f64; 3], chain: Option<(f64, &Mat<f64>)>) -> Mat<f64> {
        let g = &self.gl;
        let nc = g.n_zeta();
        let aa = mul(g.sig2_a.transpose(), g.sig2_a.as_ref());
        let bb = mul(g.sig2_b.transpose(), g.sig2_b.as_ref());
        let mut pi = Mat::from_fn(nc, nc, |i, j| {
            tau[0] * g.sigma_mhe[(i, j)] + tau[1] * (phi * phi * aa[(i, j)] - bb[(i, j)])
        });
        if let Some(s3) = &g.sigma_mpc {
            for j in 0..nc {
                for i in 0..nc {
                    pi[(i, j)] += tau[2] * s3[(i, j)];
                }
            }
        }
        if let Some(r) = &g.extra_supply {
            super::add(&mut pi, r);
        }
        if let Some((s, c)) = chain {
            for j in 0..nc {
                for i in 0..nc {
                    pi[(i, j)] += s * c[(i, j)];
                }
            }
        }
        pi
    }

    /// The multiplier search, in order: Theorem L3 (λ = 0, τ₂ = 1), then per profile rᵏ the
    /// chain with σ₂ (weights s on a log grid around σ₂'s scale against the chain's), then the
    /// chain alone (τ₂ = 0); τ₁ × τ₃ on Theorem L3's grid at each. The first point whose
    /// Riccati candidate passes the independent check is returned, with the solves used.
    fn search(&self, phi: f64, opts: &ChainOptions, budget: usize) -> ChainAttempt {
        let g = &self.gl;
        let max = |m: &Mat<f64>| {
            m.col_iter()
                .flat_map(|c| c.iter().copied())
                .fold(0.0_f64, |a, v| a.max(v.abs()))
        };
        let grid = g.tau_grid(&opts.global);
        let t1s = if g.mhe_bounded > 0 {
            grid.clone()
        } else {
            vec![0.0]
        };
        let t3s = if g.sigma_mpc.is_some() {
            grid
        } else {
            vec![0.0]
        };
        let rho = opts.global.rho_max;
        let used = std::cell::Cell::new(0usize);
        let try_point = |tau: [f64; 3], chain: Option<(f64, &Mat<f64>)>| {
            if used.get() >= budget {
                return None;
            }
            used.set(used.get() + 1);
            let pi = self.supply(phi, tau, chain);
            g.certify_supply(phi, rho, &pi, [tau[0], tau[2]], Vec::new())
        };
        let found = |c: GlobalCertificate, tau2: f64, lambda: Vec<f64>| ChainCertificate {
            k: self.k_iter,
            tau2,
            lambda,
            mu: Vec::new(),
            cert: c,
        };
        for &t1 in &t1s {
            for &t3 in &t3s {
                if let Some(c) = try_point([t1, 1.0, t3], None) {
                    return attempt(Some(found(c, 1.0, vec![0.0; self.k])), used.get(), None);
                }
            }
        }
        let bb = mul(g.sig2_b.transpose(), g.sig2_b.as_ref());
        let np = opts.scale_points.max(2);
        for &r in &opts.ratios {
            let prof = self.profile(r);
            let c = self.chain_form(&prof, None);
            let base = max(&bb) / max(&c).max(f64::MIN_POSITIVE);
            let scales =
                (0..np).map(|i| base * 10f64.powf(-3.0 + 6.0 * i as f64 / (np - 1) as f64));
            for s in scales {
                for &t1 in &t1s {
                    for &t3 in &t3s {
                        if let Some(cert) = try_point([t1, 1.0, t3], Some((s, &c))) {
                            let lambda = prof.iter().map(|l| s * l).collect();
                            return attempt(Some(found(cert, 1.0, lambda)), used.get(), None);
                        }
                    }
                }
            }
            for &t1 in &t1s {
                for &t3 in &t3s {
                    let tau = [t1 * base, 0.0, t3 * base];
                    if let Some(cert) = try_point(tau, Some((1.0, &c))) {
                        return attempt(Some(found(cert, 0.0, prof)), used.get(), None);
                    }
                }
            }
            if used.get() >= budget {
                break;
            }
        }
        let left = budget.saturating_sub(used.get()).min(opts.ascent_solves);
        let (cert, more, rho) = self.ascent(phi, opts, left, &t1s, &t3s);
        attempt(cert, used.get() + more, rho)
    }

    /// The supply of the multiplier vector m = (τ₁, τ₂, τ₃, λ₀ … λ_{K−1}, μ₀ … μ_{n_B−1}).
    fn supply_m(&self, phi: f64, m: &[f64]) -> Mat<f64> {
        let c = self.chain_form(&m[3..3 + self.k], Some(&m[3 + self.k..]));
        self.supply(phi, [m[0], m[1], m[2]], Some((1.0, &c)))
    }

    /// Stage 2 of [`ChainAt::search`]: from the grid point (τ₁ × τ₃ × s, profile 1, τ₂ ∈ {1, 0})
    /// feasible at the smallest of ρ = 2, 1.3, 1.1, 1.03, 1.01, a coordinate ascent of 1/ρ over
    /// τ₁, τ₂, τ₃, all λ, and 8 contiguous groups of λ_k, until ρ ≤ ρ_max; then the check.
    fn ascent(
        &self,
        phi: f64,
        opts: &ChainOptions,
        budget: usize,
        t1s: &[f64],
        t3s: &[f64],
    ) -> (Option<ChainCertificate>, usize, Option<f64>) {
        let g = &self.gl;
        let solves = std::cell::Cell::new(0usize);
        let feasible = |rho: f64, m: &[f64]| {
            solves.set(solves.get() + 1);
            g.feasible(rho, &self.supply_m(phi, m))
        };
        let k = self.k;
        let bb = mul(g.sig2_b.transpose(), g.sig2_b.as_ref());
        let max = |m: &Mat<f64>| {
            m.col_iter()
                .flat_map(|c| c.iter().copied())
                .fold(0.0_f64, |a, v| a.max(v.abs()))
        };
        let base = max(&bb) / max(&self.chain_form(&vec![1.0; k], None)).max(f64::MIN_POSITIVE);
        let nb = (self.a.nrows() / k.max(1)).max(1);
        let mut starts: Vec<Vec<f64>> = Vec::new();
        for &t1 in t1s {
            for &t3 in t3s {
                for e in [-2.0, 0.0, 2.0] {
                    let s = base * 10f64.powf(e);
                    let mut m = vec![t1, 1.0, t3];
                    m.extend(std::iter::repeat_n(s, k));
                    m.extend(std::iter::repeat_n(1.0, nb));
                    starts.push(m);
                }
                let mut m = vec![t1 * base, 0.0, t3 * base];
                m.extend(std::iter::repeat_n(base, k));
                m.extend(std::iter::repeat_n(1.0, nb));
                starts.push(m);
            }
        }
        let levels = [2.0, 1.3, 1.1, 1.03, 1.01];
        let mut best: Option<(f64, Vec<f64>)> = None;
        for m in starts {
            if solves.get() >= budget {
                break;
            }
            let mut reached = None;
            for &r in &levels {
                if best.as_ref().is_some_and(|(b, _)| r >= *b) {
                    continue;
                }
                if feasible(r, &m) {
                    reached = Some(r);
                } else {
                    break;
                }
            }
            if let Some(r) = reached {
                best = Some((r, m));
            }
        }
        let Some((rho0, m0)) = best else {
            return (None, solves.get(), None);
        };
        let mut groups: Vec<std::ops::Range<usize>> = vec![0..1, 1..2, 3..3 + k];
        if g.sigma_mpc.is_some() {
            groups.push(2..3);
        }
        // 8 contiguous groups of iterations, then 8 of coordinates (μ).
        for (start, n) in [(3, k), (3 + k, nb)] {
            let parts = n.min(8);
            for p in 0..parts {
                let (a, b) = (start + p * n / parts, start + (p + 1) * n / parts);
                if b > a && (parts > 1 || start > 3) {
                    groups.push(a..b);
                }
            }
        }
        let search = super::RowSearch {
            max_solves: budget,
            ..super::RowSearch::default()
        };
        let target = opts.global.rho_max;
        let (level, m) = super::rows::ascend(
            m0,
            1.0 / rho0,
            &groups,
            &search,
            &solves,
            |lvl| lvl >= 1.0 / target,
            |lvl, m| feasible(1.0 / lvl, m),
        );
        let rho = 1.0 / level;
        if rho > target {
            return (None, solves.get(), Some(rho));
        }
        let pi = self.supply_m(phi, &m);
        solves.set(solves.get() + 1);
        let cert = g
            .certify_supply(phi, target, &pi, [m[0], m[2]], Vec::new())
            .map(|c| ChainCertificate {
                k: self.k_iter,
                tau2: m[1],
                lambda: m[3..3 + k].to_vec(),
                mu: m[3 + k..].to_vec(),
                cert: c,
            });
        let reached = cert.is_none().then_some(rho);
        (cert, solves.get(), reached)
    }
}
