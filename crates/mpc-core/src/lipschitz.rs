//! L_π of Assumption 3, ‖π(x) − π(x')‖ ≤ L_π‖x − x'‖: a certified upper bound for the
//! box-constrained condensed MPC and a sampled estimate for any memoryless controller.
//!
//! ## Certified bound (derivation; design.md trap 9)
//!
//! Premise: H ≻ 0 and Z = 𝒰^N closed and convex (a box), no state constraints; this is
//! what [`CondensedMpc`] builds. Completing the square,
//! ½UᵀHU + (Fx)ᵀU = ½‖U − v(x)‖²_H + const(x) with v(x) = −H⁻¹Fx, so
//!
//! U*(x) = Π^H_{𝒰^N}(v(x)),
//!
//! the projection in the inner product ⟨a, b⟩_H = aᵀHb. A projection onto a closed convex
//! set in a Hilbert space is non-expansive in that space's norm, so for all x, x' ∈ ℝ^{n_x}
//!
//! ‖U*(x) − U*(x')‖_H ≤ ‖v(x) − v(x')‖_H = ‖H^{−1/2}F(x − x')‖₂ ≤ c‖x − x'‖,
//! c = ‖H^{−1/2}F‖₂ = √λ_max(FᵀH⁻¹F).
//!
//! (a) *Sequence bound*: ‖·‖₂ ≤ λ_min(H)^{−1/2}‖·‖_H and u₀ is a sub-vector of U, so
//!     ‖π(x) − π(x')‖ ≤ ‖U*(x) − U*(x')‖₂ ≤ c/√λ_min(H) · ‖x − x'‖.
//! (b) *First-block bound* (tighter, proven the same way): with E₀ = [I_{n_u} 0 … 0],
//!     Δu₀ = E₀ΔU = (E₀H^{−1/2})(H^{1/2}ΔU), so
//!     ‖π(x) − π(x')‖ ≤ ‖E₀H^{−1/2}‖₂ ‖ΔU‖_H ≤ √λ_max([H⁻¹]₀₀) · c · ‖x − x'‖,
//!     where [H⁻¹]₀₀ = E₀H⁻¹E₀ᵀ is the leading n_u × n_u block of H⁻¹. Since
//!     λ_max([H⁻¹]₀₀) ≤ λ_max(H⁻¹) = 1/λ_min(H), (b) ≤ (a). (b) is the certified L_π.
//!
//! Both hold on all of ℝ^{n_x}, hence on 𝒳. A lower reference: if 0 ∈ int 𝒰, then
//! v(x) ∈ 𝒰^N for x near 0, π(x) = −E₀H⁻¹Fx there, and L_π ≥ ‖E₀H⁻¹F‖₂ (with the DARE
//! terminal cost E₀H⁻¹F is the LQR gain K).
//!
//! ## Enumerated bound (tighter, small problems)
//!
//! For a free set f ⊆ {1, …, N·n_u} (the variables strictly inside their bounds) let
//! J_f = −S_f(H_ff)⁻¹F_f (S_f the columns of I indexed by f; J_f is zero off f). Then
//!
//! L_π ≤ L_enum := max_f ‖E₀J_f‖₂ ≤ (b).
//!
//! *Proof.* Fix x, x', Δ = x' − x, U(t) = U*(x + tΔ). U is Lipschitz in t (by (a)), hence
//! absolutely continuous and differentiable for almost every t ∈ (0, 1), with
//! U(1) − U(0) = ∫ U'(t)dt. At such a t let A be the set of variables at a bound and f its
//! complement. For i ∈ A, s ↦ U_i(s) attains its bound (a minimum or maximum over the box)
//! at s = t, so U_i'(t) = 0. For i ∈ f, U_i(s) stays strictly inside its bounds for s near t
//! (continuity), so stationarity (HU(s) + F(x + sΔ))_i = 0 holds near t; differentiating,
//! H_ff U_f'(t) + H_fA U_A'(t) + F_fΔ = 0 with U_A'(t) = 0, i.e. U'(t) = J_fΔ. Hence
//! ‖u₀(x') − u₀(x)‖ ≤ ∫‖E₀J_{f(t)}Δ‖dt ≤ L_enum‖Δ‖. And J_fΔ is the H-orthogonal projection
//! of −H⁻¹FΔ onto {U : U_A = 0}, non-expansive in ‖·‖_H, so each ‖E₀J_f‖₂ ≤ (b). ∎
//!
//! A variable with two infinite bounds is never at a bound, so f always contains it: the
//! maximum runs over the 2^s free sets of the s saturable variables (not only those some x
//! realises), so it is an upper bound, computed by [`CondensedMpc::lipschitz_enumerated`]
//! when 2^s is affordable (the case study's 2²⁰ sets take ≈ 2 s in the opt-level-1 test
//! build). With 𝒰 = ℝ^{n_u} (s = 0) there is one free set and L_enum = ‖E₀H⁻¹F‖₂ exactly.
//!
//! ## Polynomial bound (any size)
//!
//! Every local gain is K(M) = K_lin + G·M·R at an orthogonal projector M of ℝ^s
//! ([`crate::free_sets`]), so L_enum ≤ L_poly := sup_{0 ⪯ M ⪯ I} ‖K(M)‖₂, computed exactly (up
//! to a scalar search) by the S-procedure of [`crate::robust_norm`] in O((N·n_u)³) time.
//! Every 0 ⪯ M ⪯ I gives K(M) = −E₀H^{−½}ΠH^{−½}F with 0 ⪯ Π ⪯ I, so L_poly ≤ (b). L_poly is
//! tightened by the partial enumeration of [`crate::free_sets`]: the maximum of the same bound
//! over the 2^{|𝒫_k|} families that fix the saturation pattern of the first k input blocks
//! (k as large as [`LIPSCHITZ_PATTERN_FAMILIES`] allows); the smaller of the two is reported.
//! The certified L_π is min(L_enum, L_poly, (b)) = L_enum when enumerated, else L_poly.
//!
//! ## Sampled estimate
//!
//! [`lipschitz_sampled`] returns the largest ratio ‖π(x) − π(x')‖/‖x − x'‖ over seeded
//! pairs drawn in the ball of radius r (projected onto an optional state box). The pairs
//! cycle through four kinds: independent pairs; close pairs x' = x + δd (δ = 10⁻³r, d a
//! random unit vector); pairs straddling a switch of the active set, located by bisection
//! on a random segment (π is piecewise affine, so a segment whose midpoint value is not
//! the average of its end values contains a switch); and close pairs along the top right
//! singular vector of a central finite-difference Jacobian of π at a random point. Every
//! ratio is an actual evaluation of π, so the estimate is a lower bound on the true L_π.

use faer::{Mat, Side};
use lti_model::{BoxSet, ConvexSet, Projection};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
#[cfg(feature = "serde")]
use serde::Serialize;

use crate::Controller;
use crate::condensed::CondensedMpc;
use crate::error::{MpcError, Result};
use crate::exact::ExactMpc;

/// Family budget of the partial enumeration in L_poly (module docs): the saturation patterns
/// of the leading input blocks are enumerated while 2^{|𝒫_k|} ≤ this.
pub const LIPSCHITZ_PATTERN_FAMILIES: u64 = 64;

/// The certified L_π of the box-constrained condensed MPC and its ingredients.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct LipschitzCertificate {
    /// (b) ‖E₀H^{−1/2}‖₂·‖H^{−1/2}F‖₂: a certified L_π from two norms (≥ `polynomial`).
    pub first_block: f64,
    /// (a) ‖H^{−1/2}F‖₂/√λ_min(H): also bounds ‖U*(x) − U*(x')‖₂ / ‖x − x'‖.
    pub sequence: f64,
    /// c = ‖H^{−1/2}F‖₂.
    pub h_inv_sqrt_f: f64,
    /// ‖E₀H^{−1/2}‖₂ = √λ_max([H⁻¹]₀₀).
    pub e0_h_inv_sqrt: f64,
    /// λ_min(H).
    pub h_min_eigenvalue: f64,
    /// ‖E₀H⁻¹F‖₂, the gain of the unconstrained law; a lower bound on L_π when
    /// `origin_interior` holds.
    pub unconstrained_gain: f64,
    /// 0 lies in the interior of 𝒰 (every lower bound < 0 < every upper bound).
    pub origin_interior: bool,
    /// L_poly ≥ sup_{0 ⪯ M ⪯ I} ‖K_lin + G·M·R‖₂ over the family, or over the partial
    /// enumeration's families (module docs, "Polynomial bound"); equals `unconstrained_gain`
    /// when nothing can saturate.
    pub polynomial: f64,
    /// s, the number of saturable QP variables (finite bound on at least one side).
    pub saturable: usize,
}

impl LipschitzCertificate {
    /// The certified L_π without enumeration: min(L_poly, (b)).
    pub fn l_pi(&self) -> f64 {
        self.polynomial.min(self.first_block)
    }
}

impl CondensedMpc {
    /// Certified upper bound on L_π (Assumption 3) from H and F; see the module docs.
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use lti_model::{BoxSet, LtiSystem};
    /// use mpc_core::{CondensedMpc, MpcConfig};
    /// let sys = LtiSystem::new(mat![[1.0, 0.1], [0.0, 1.0]], mat![[0.005], [0.1]], mat![[1.0, 0.0]]).unwrap();
    /// let mpc = CondensedMpc::new(&sys, MpcConfig::new(5, Mat::identity(2, 2), mat![[0.1]],
    ///     BoxSet::symmetric(&[1.0]).unwrap())).unwrap();
    /// let c = mpc.lipschitz_certified().unwrap();
    /// assert!(c.unconstrained_gain <= c.first_block * (1.0 + 1e-12) && c.first_block <= c.sequence * (1.0 + 1e-12));
    /// ```
    pub fn lipschitz_certified(&self) -> Result<LipschitzCertificate> {
        let qp = self.qp();
        let n = qp.n();
        let nu = self.nu();
        let llt = qp.h().to_owned().llt(Side::Lower).map_err(|e| {
            MpcError::Model(lti_model::ModelError::Numerical {
                routine: "Cholesky of H (L_π certificate)".into(),
                reason: format!("{e:?}"),
            })
        })?;
        let h_inv_f = faer::linalg::solvers::Solve::solve(&llt, qp.f());
        let h_inv = faer::linalg::solvers::Solve::solve(&llt, Mat::<f64>::identity(n, n));
        let ftf = qp.f().transpose() * &h_inv_f;
        let (_, c2) = lti_model::matrix::sym_extreme_eigenvalues("FᵀH⁻¹F", ftf.as_ref())?;
        let block = h_inv.as_ref().submatrix(0, 0, nu, nu).to_owned();
        let (_, b2) = lti_model::matrix::sym_extreme_eigenvalues("[H⁻¹]₀₀", block.as_ref())?;
        let c = c2.max(0.0).sqrt();
        let e0 = b2.max(0.0).sqrt();
        let mu = qp.mu();
        let gain =
            lti_model::matrix::spectral_norm(h_inv_f.as_ref().submatrix(0, 0, nu, self.nx()));
        let us = self.input_set();
        let origin_interior =
            us.lower().iter().all(|l| *l < 0.0) && us.upper().iter().all(|u| *u > 0.0);
        let gains = self.local_gains()?;
        let mut polynomial = gains.lipschitz_bound()?;
        let depth = self.pattern_depth(LIPSCHITZ_PATTERN_FAMILIES);
        if depth > 0 && gains.s() > 0 {
            // Both bounds are sound; stop once the running maximum cannot win.
            let mut worst = 0.0_f64;
            for g in self.pattern_gains_iter(depth)? {
                worst = worst.max(g?.lipschitz_bound()?);
                if worst >= polynomial {
                    break;
                }
            }
            polynomial = polynomial.min(worst);
        }
        Ok(LipschitzCertificate {
            polynomial,
            saturable: gains.s(),
            first_block: e0 * c,
            sequence: c / mu.sqrt(),
            h_inv_sqrt_f: c,
            e0_h_inv_sqrt: e0,
            h_min_eigenvalue: mu,
            unconstrained_gain: gain,
            origin_interior,
        })
    }

    /// Sampled L_π of the exact MPC ([`ExactMpc`]) over `n_pairs` seeded pairs in the ball
    /// of radius `radius` (see [`lipschitz_sampled`]).
    pub fn lipschitz_sampled(
        &self,
        n_pairs: usize,
        seed: u64,
        radius: f64,
    ) -> Result<SampledLipschitz> {
        let mut exact = ExactMpc::new(self)?;
        lipschitz_sampled(&mut exact, n_pairs, seed, radius, None)
    }
}

impl CondensedMpc {
    /// L_enum = max over all free sets f of ‖E₀J_f‖₂ (module docs, "Enumerated bound"): a
    /// certified upper bound on L_π, never above [`LipschitzCertificate::first_block`].
    ///
    /// Costs 2^s small Cholesky solves (s saturable variables, [`CondensedMpc::saturable`]);
    /// returns `Ok(None)` when s > `max_vars` (at most 30). Allocation happens once, before
    /// the loop.
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use lti_model::{BoxSet, LtiSystem};
    /// use mpc_core::{CondensedMpc, MpcConfig};
    /// let sys = LtiSystem::new(mat![[1.0, 0.1], [0.0, 1.0]], mat![[0.005], [0.1]], mat![[1.0, 0.0]]).unwrap();
    /// let mpc = CondensedMpc::new(&sys, MpcConfig::new(5, Mat::identity(2, 2), mat![[0.1]],
    ///     BoxSet::symmetric(&[1.0]).unwrap())).unwrap();
    /// let l_enum = mpc.lipschitz_enumerated(20).unwrap().unwrap();
    /// let c = mpc.lipschitz_certified().unwrap();
    /// assert!(c.unconstrained_gain <= l_enum * (1.0 + 1e-12) && l_enum <= c.first_block * (1.0 + 1e-12));
    /// assert!(l_enum <= c.polynomial * (1.0 + 1e-9));
    /// assert!(mpc.lipschitz_enumerated(4).unwrap().is_none()); // s = N·n_u = 5 > 4
    /// ```
    pub fn lipschitz_enumerated(&self, max_vars: usize) -> Result<Option<f64>> {
        self.lipschitz_enumerated_in(max_vars, 0..self.free_set_count())
    }

    /// [`CondensedMpc::lipschitz_enumerated`] over the free sets of the masks in `masks`
    /// only ([`CondensedMpc::for_each_free_set_in`]): the maximum of the pieces over ranges
    /// that cover 0..2^s is L_enum, bit for bit (a maximum does not depend on the order), so
    /// a caller can run the enumeration as independent tasks. `Ok(None)` when s > `max_vars`.
    pub fn lipschitz_enumerated_in(
        &self,
        max_vars: usize,
        masks: std::ops::Range<u64>,
    ) -> Result<Option<f64>> {
        let nu = self.nu();
        let mut g = vec![0.0; nu * nu];
        let mut best = 0.0_f64;
        let visited = self.for_each_free_set_in(max_vars, masks, |_, k, nx| {
            // ‖K_f‖₂² = λ_max(K_f K_fᵀ) (n_u × n_u).
            for p in 0..nu {
                for q in 0..nu {
                    g[p * nu + q] = (0..nx).map(|j| k[p * nx + j] * k[q * nx + j]).sum();
                }
            }
            // Stops as soon as it cannot raise `best` (the same maximum, bit for bit).
            if let Some(top) = lti_model::matrix::sym_lambda_max_above(&mut g, nu, best * best) {
                best = best.max(top.max(0.0).sqrt());
            }
        })?;
        Ok(visited.then_some(best))
    }
}

/// Result of [`lipschitz_sampled`].
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct SampledLipschitz {
    /// max ‖π(x) − π(x')‖/‖x − x'‖ over the pairs (a lower bound on L_π).
    pub estimate: f64,
    /// The pair attaining the maximum.
    pub worst_x: Vec<f64>,
    /// Its partner.
    pub worst_x_prime: Vec<f64>,
    /// Number of pairs (ratios) evaluated.
    pub pairs: usize,
    /// Number of evaluations of π.
    pub evaluations: usize,
    /// Segments on which a switch of π was located by bisection.
    pub switches_located: usize,
    /// Seed of the ChaCha8 generator.
    pub seed: u64,
    /// Sampling radius r.
    pub radius: f64,
    /// Close-pair distance δ = 10⁻³r.
    pub delta: f64,
}

struct Sampler<'a, C: Controller<Error = MpcError> + ?Sized> {
    ctrl: &'a mut C,
    domain: Option<&'a BoxSet>,
    rng: ChaCha8Rng,
    nx: usize,
    radius: f64,
    evaluations: usize,
}

impl<C: Controller<Error = MpcError> + ?Sized> Sampler<'_, C> {
    fn eval(&mut self, x: &[f64]) -> Result<Vec<f64>> {
        let mut u = vec![0.0; self.ctrl.nu()];
        self.ctrl.control(x, &mut u)?;
        self.evaluations += 1;
        Ok(u)
    }

    fn unit(&mut self) -> Vec<f64> {
        loop {
            let g: Vec<f64> = (0..self.nx)
                .map(|_| self.rng.sample(StandardNormal))
                .collect();
            let norm = norm(&g);
            if norm > 1e-12 {
                return g.iter().map(|v| v / norm).collect();
            }
        }
    }

    fn clamp(&self, x: &mut [f64]) {
        if let Some(d) = self.domain {
            d.project(x);
        }
    }

    /// Uniform in the ball of radius r, projected onto the domain.
    fn point(&mut self) -> Vec<f64> {
        let d = self.unit();
        let s: f64 = self.rng.random::<f64>();
        let rho = self.radius * s.powf(1.0 / self.nx as f64);
        let mut x: Vec<f64> = d.iter().map(|v| rho * v).collect();
        self.clamp(&mut x);
        x
    }

    /// A pair δ apart across a switch of π: bisection of a random segment on which π bends
    /// (`true`), or the segment's ends where π is affine on it (`false`).
    fn switch_pair(&mut self, delta: f64) -> Result<(EvaluatedPair, bool)> {
        let (mut a, mut b) = (self.point(), self.point());
        let (mut ua, mut ub) = (self.eval(&a)?, self.eval(&b)?);
        let scale =
            |u: &[f64], v: &[f64]| 1.0 + u.iter().chain(v).map(|t| t.abs()).fold(0.0, f64::max);
        let tol = 1e-8 * scale(&ua, &ub);
        let mut m = lerp(&a, &b, 0.5);
        let mut um = self.eval(&m)?;
        if !bends(&ua, &ub, &um, tol) {
            return Ok(((a, ua, b, ub), false));
        }
        // Invariant: π bends on [a, b] and m is its midpoint.
        while dist(&a, &b) > delta {
            let (m1, m2) = (lerp(&a, &m, 0.5), lerp(&m, &b, 0.5));
            let u1 = self.eval(&m1)?;
            if bends(&ua, &um, &u1, tol) {
                (b, ub, m, um) = (m, um, m1, u1);
                continue;
            }
            let u2 = self.eval(&m2)?;
            if bends(&um, &ub, &u2, tol) {
                (a, ua, m, um) = (m, um, m2, u2);
                continue;
            }
            break; // affine on both halves: the switch is at m
        }
        let dir: Vec<f64> = {
            let l = dist(&a, &b);
            a.iter().zip(&b).map(|(p, q)| (q - p) / l).collect()
        };
        let mut x: Vec<f64> = m
            .iter()
            .zip(&dir)
            .map(|(p, q)| p - 0.5 * delta * q)
            .collect();
        let mut y: Vec<f64> = m
            .iter()
            .zip(&dir)
            .map(|(p, q)| p + 0.5 * delta * q)
            .collect();
        self.clamp(&mut x);
        self.clamp(&mut y);
        let (ux, uy) = (self.eval(&x)?, self.eval(&y)?);
        Ok(((x, ux, y, uy), true))
    }

    /// A pair δ apart along the steepest direction of π at a random point (the top right
    /// singular vector of a central-difference Jacobian; a random direction if that fails).
    fn steepest_pair(&mut self, delta: f64) -> Result<EvaluatedPair> {
        let nx = self.nx;
        let x = self.point();
        let nu = self.ctrl.nu();
        let mut jac = Mat::<f64>::zeros(nu, nx);
        for j in 0..nx {
            let mut p = x.clone();
            let mut q = x.clone();
            p[j] += 0.5 * delta;
            q[j] -= 0.5 * delta;
            let (up, uq) = (self.eval(&p)?, self.eval(&q)?);
            for r in 0..nu {
                jac[(r, j)] = (up[r] - uq[r]) / delta;
            }
        }
        let jtj = jac.transpose() * &jac;
        let dir: Vec<f64> = match jtj.self_adjoint_eigen(Side::Lower) {
            Ok(e) => (0..nx).map(|r| e.U()[(r, nx - 1)]).collect(),
            Err(_) => self.unit(),
        };
        let mut y: Vec<f64> = x.iter().zip(&dir).map(|(p, q)| p + delta * q).collect();
        self.clamp(&mut y);
        let (ux, uy) = (self.eval(&x)?, self.eval(&y)?);
        Ok((x, ux, y, uy))
    }
}

/// (x, π(x), y, π(y)).
type EvaluatedPair = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

use lti_model::vecmath::{dist2 as dist, norm2 as norm};

fn lerp(a: &[f64], b: &[f64], t: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect()
}

/// ‖u_m − (u_a + u_b)/2‖_∞ > tol: π is not affine on the segment.
fn bends(ua: &[f64], ub: &[f64], um: &[f64], tol: f64) -> bool {
    ua.iter()
        .zip(ub)
        .zip(um)
        .any(|((a, b), m)| (m - 0.5 * (a + b)).abs() > tol)
}

/// Sampled L_π of a memoryless controller (for [`ExactMpc`] and [`crate::SaturatedLqr`];
/// a [`crate::SuboptimalMpc`] depends on its warm start, so its ratios mean nothing).
///
/// `n_pairs` ≥ 1 ratios are evaluated in the ball of radius `radius` > 0 around 0; if
/// `domain` (the state set 𝒳, n_x-dimensional) is given, every point is projected onto it.
///
/// ```
/// use faer::mat;
/// use lti_model::BoxSet;
/// use mpc_core::{SaturatedLqr, lipschitz_sampled};
/// let mut lqr = SaturatedLqr::from_gain(mat![[3.0, 4.0]], BoxSet::symmetric(&[1.0]).unwrap()).unwrap();
/// let s = lipschitz_sampled(&mut lqr, 200, 7, 1.0, None).unwrap();
/// assert!(s.estimate <= 5.0 + 1e-9 && s.estimate > 4.9); // ‖K‖₂ = 5
/// ```
pub fn lipschitz_sampled<C: Controller<Error = MpcError> + ?Sized>(
    ctrl: &mut C,
    n_pairs: usize,
    seed: u64,
    radius: f64,
    domain: Option<&BoxSet>,
) -> Result<SampledLipschitz> {
    if n_pairs == 0 {
        return Err(MpcError::Parameter {
            name: "n_pairs",
            value: 0.0,
            reason: "at least one pair is needed",
        });
    }
    if !(radius > 0.0 && radius.is_finite()) {
        return Err(MpcError::Parameter {
            name: "radius",
            value: radius,
            reason: "must be positive and finite",
        });
    }
    let nx = ctrl.nx();
    if let Some(d) = domain {
        if d.dim() != nx {
            return Err(MpcError::Dimension {
                name: "domain",
                expected: nx,
                actual: d.dim(),
            });
        }
    }
    let delta = 1e-3 * radius;
    let mut s = Sampler {
        ctrl,
        domain,
        rng: ChaCha8Rng::seed_from_u64(seed),
        nx,
        radius,
        evaluations: 0,
    };
    let mut best = SampledLipschitz {
        estimate: 0.0,
        worst_x: vec![0.0; nx],
        worst_x_prime: vec![0.0; nx],
        pairs: 0,
        evaluations: 0,
        switches_located: 0,
        seed,
        radius,
        delta,
    };
    let record = |best: &mut SampledLipschitz, x: &[f64], ux: &[f64], y: &[f64], uy: &[f64]| {
        let d = dist(x, y);
        if d > 1e-12 * radius {
            best.pairs += 1;
            let r = dist(ux, uy) / d;
            if r > best.estimate {
                best.estimate = r;
                best.worst_x = x.to_vec();
                best.worst_x_prime = y.to_vec();
            }
        }
    };
    for i in 0..n_pairs {
        match i % 4 {
            0 => {
                let (x, y) = (s.point(), s.point());
                let (ux, uy) = (s.eval(&x)?, s.eval(&y)?);
                record(&mut best, &x, &ux, &y, &uy);
            }
            1 => {
                let x = s.point();
                let d = s.unit();
                let mut y: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a + delta * b).collect();
                s.clamp(&mut y);
                let (ux, uy) = (s.eval(&x)?, s.eval(&y)?);
                record(&mut best, &x, &ux, &y, &uy);
            }
            2 => {
                let (pair, located) = s.switch_pair(delta)?;
                best.switches_located += usize::from(located);
                let (x, ux, y, uy) = pair;
                record(&mut best, &x, &ux, &y, &uy);
            }
            _ => {
                let (x, ux, y, uy) = s.steepest_pair(delta)?;
                record(&mut best, &x, &ux, &y, &uy);
            }
        }
    }
    best.evaluations = s.evaluations;
    Ok(best)
}

/// Both L_π figures for one MPC (what `cargo xtask certify` prints).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct LipschitzReport {
    /// The certified bound and its ingredients.
    pub certified: LipschitzCertificate,
    /// The sampled estimate with the exact MPC.
    pub sampled: SampledLipschitz,
    /// L_enum (the enumerated bound, ≤ `certified.polynomial`), if the number of saturable
    /// variables s ≤ [`ENUMERATION_MAX_VARS`].
    pub enumerated: Option<f64>,
    /// Why L_enum was not computed (None when it was): a named reason, never a silent cap.
    pub enumeration_skipped: Option<String>,
    /// ‖K‖₂ of the saturated LQR for the same (A, B, Q_c, R_c, 𝒰), for comparison.
    pub saturated_lqr: f64,
    /// Why no certified L_π exists (state constraints:
    /// [`crate::STATE_CONSTRAINED_VOID_REASON`]); then [`LipschitzReport::l_pi`] is +∞ and
    /// `certified` describes the input-constrained relaxation only. (Omitted from the
    /// serialised report when absent.)
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub void_reason: Option<&'static str>,
}

/// Largest number of saturable variables s for which [`lipschitz_report_for`] enumerates
/// free sets (2²⁰ ≈ 10⁶ solves); above it the polynomial bound L_poly is used.
pub const ENUMERATION_MAX_VARS: usize = 20;

impl LipschitzReport {
    /// The tightest certified L_π available: L_enum if computed, else min(L_poly, (b));
    /// +∞ when void ([`LipschitzReport::void_reason`]).
    pub fn l_pi(&self) -> f64 {
        if self.void_reason.is_some() {
            return f64::INFINITY;
        }
        self.enumerated
            .map_or(self.certified.l_pi(), |e| e.min(self.certified.l_pi()))
    }

    /// sampled ≤ L_enum ≤ L_poly ≤ (b) (up to a relative 1e-9 for the solvers' accuracy).
    pub fn consistent(&self) -> bool {
        let tol = 1.0 + 1e-9;
        let c = &self.certified;
        self.sampled.estimate <= self.l_pi() * tol
            && c.polynomial <= c.first_block * tol
            && self.enumerated.is_none_or(|e| e <= c.polynomial * tol)
    }
}

impl std::fmt::Display for LipschitzReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let c = &self.certified;
        let s = &self.sampled;
        writeln!(f, "L_π (Assumption 3), condensed box-constrained MPC:")?;
        if let Some(r) = self.void_reason {
            writeln!(f, "  void: {r}")?;
        }
        if self.void_reason.is_some() {
            // The bounds below are those of the box-constrained MPC; void above, they do not
            // certify this one.
            writeln!(
                f,
                "  certified L_π  none (void: the bounds below do not hold for this MPC)"
            )?;
        } else {
            writeln!(
                f,
                "  certified L_π  {:.6}  (the tightest bound below)",
                self.l_pi()
            )?;
        }
        match self.enumerated {
            Some(e) => writeln!(
                f,
                "  L_enum         {e:.6}  = max over all free sets f of ‖E₀J_f‖₂"
            )?,
            None => writeln!(
                f,
                "  L_enum         skipped: {}",
                self.enumeration_skipped
                    .as_deref()
                    .unwrap_or("not computed")
            )?,
        }
        writeln!(
            f,
            "  L_poly         {:.6}  = sup over 0 ⪯ M ⪯ I of ‖K_lin + G·M·R‖₂ (S-procedure; {} saturable variables)",
            c.polynomial, c.saturable
        )?;
        writeln!(
            f,
            "  bound (b)      {:.6}  = ‖E₀H^(-1/2)‖₂·‖H^(-1/2)F‖₂ = {:.6}·{:.6}",
            c.first_block, c.e0_h_inv_sqrt, c.h_inv_sqrt_f
        )?;
        writeln!(
            f,
            "  bound (a)      {:.6}  = ‖H^(-1/2)F‖₂/√λ_min(H), λ_min(H) = {:.6e}",
            c.sequence, c.h_min_eigenvalue
        )?;
        if s.pairs == 0 {
            writeln!(f, "  sampled        skipped (0 pairs requested)")?;
        } else {
            writeln!(
                f,
                "  sampled        {:.6}  over {} pairs ({} evaluations, {} switches located), seed {}, radius {:.6}",
                s.estimate, s.pairs, s.evaluations, s.switches_located, s.seed, s.radius
            )?;
        }
        if c.origin_interior {
            writeln!(
                f,
                "  unconstrained  {:.6}  = ‖E₀H⁻¹F‖₂ (a lower bound on L_π: 0 ∈ int 𝒰)",
                c.unconstrained_gain
            )?;
        }
        writeln!(
            f,
            "  saturated LQR  {:.6}  = ‖K‖₂ (its certified L_π)",
            self.saturated_lqr
        )?;
        if self.consistent() {
            write!(f, "  sampled ≤ certified: yes")
        } else {
            write!(f, "  sampled ≤ certified: NO (a bug: please report it)")
        }
    }
}

/// Both L_π figures for `mpc`: the certificate (bound (b), and L_enum when
/// N·n_u ≤ [`ENUMERATION_MAX_VARS`]), the sampled estimate with the exact MPC (`n_pairs`,
/// `seed`, `radius`; `n_pairs = 0` skips it: estimate 0 over 0 pairs), and ‖K‖₂ of the
/// saturated LQR for comparison.
pub fn lipschitz_report_for(
    mpc: &CondensedMpc,
    n_pairs: usize,
    seed: u64,
    radius: f64,
) -> Result<LipschitzReport> {
    lipschitz_report_with(mpc, n_pairs, seed, radius, |m| {
        m.lipschitz_enumerated(ENUMERATION_MAX_VARS)
    })
}

/// [`lipschitz_report_for`] with L_enum supplied by `enumerated` (called only when the
/// enumeration applies, i.e. without state constraints; it must return
/// `mpc.lipschitz_enumerated(ENUMERATION_MAX_VARS)`, e.g. assembled from
/// [`CondensedMpc::lipschitz_enumerated_in`] pieces computed elsewhere).
pub fn lipschitz_report_with(
    mpc: &CondensedMpc,
    n_pairs: usize,
    seed: u64,
    radius: f64,
    enumerated: impl FnOnce(&CondensedMpc) -> Result<Option<f64>>,
) -> Result<LipschitzReport> {
    let certified = mpc.lipschitz_certified()?;
    let void_reason = mpc.certificate_void_reason();
    // With state constraints the law is not the analysed one (and can be infeasible):
    // neither the sample nor the enumeration is run.
    let n_pairs = if void_reason.is_some() { 0 } else { n_pairs };
    // 0 pairs skips the sampled estimate (a caller that uses the certified bound only):
    // the maximum over no pairs is the trivial lower bound 0, reported as 0 pairs.
    let sampled = if n_pairs == 0 {
        SampledLipschitz {
            estimate: 0.0,
            worst_x: Vec::new(),
            worst_x_prime: Vec::new(),
            pairs: 0,
            evaluations: 0,
            switches_located: 0,
            seed,
            radius,
            delta: 1e-3 * radius,
        }
    } else {
        mpc.lipschitz_sampled(n_pairs, seed, radius)?
    };
    let enumerated = match void_reason {
        Some(_) => None,
        None => enumerated(mpc)?,
    };
    let enumeration_skipped = enumerated.is_none().then(|| {
        if let Some(r) = void_reason {
            return r.to_string();
        }
        format!(
            "{} saturable input variables > cap {ENUMERATION_MAX_VARS} (2^{} free sets); L_poly is used",
            certified.saturable, certified.saturable
        )
    });
    let lqr = crate::SaturatedLqr::new(
        mpc.system(),
        mpc.q_c().as_ref(),
        mpc.r_c().as_ref(),
        mpc.input_set().clone(),
    )?;
    Ok(LipschitzReport {
        certified,
        sampled,
        enumerated,
        enumeration_skipped,
        saturated_lqr: lqr.lipschitz_certified(),
        void_reason,
    })
}
