//! The per-step bound on ‖x̂_f32 − x̂_f64‖ of two estimators fed the same (u, y)
//! ([`DeviationBound`]; docs/theory.md, "The per-step deviation bound").

use qp_iter::Method;
use qp_iter::rounding::{
    AdmmRounding, F32_UNIT_ROUNDOFF, F64_UNIT_ROUNDOFF, IterationRounding, admm_rounding, gamma,
    iteration_rounding,
};

use super::{PropagationRounding, per_window};
use crate::certificate::ClosedLoopCertificate;
use crate::lure::global::{FistaSteps, StepRounding};
use closed_loop::scenario::ResolvedScenario;
use closed_loop::sim::ClosedLoopError;

/// The per-step bound on ‖x̂_f32,t − x̂_f64,t‖ of two estimators (same method, K, data) fed
/// the same (u_t, y_t), the f32 one with its data rounded once: docs/theory.md,
/// "Certified f32", step 5, for projected gradient, (session 28) ADMM and (session 30)
/// V-FISTA where its incremental storage exists, each plain or Jacobi-scaled (tracked in
/// the scaled coordinates y = D⁻¹z). Call
/// [`DeviationBound::step`] once per t with ‖θ_t‖ and the u window's norm of the f64 run; it
/// returns the bound at t.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct DeviationBound {
    windows: Vec<DeviationWindow>,
    k: usize,
    horizon: usize,
    t: usize,
    /// ‖D⁻¹(zᴷ_32 − zᴷ_64)‖ bound at t − 1 (D of window min(t − 1, M)).
    z_dev: f64,
    /// ‖D⁻¹(zᴷ_64 − z*)‖ and ‖D⁻¹z*‖ bounds at t − 1.
    eps64: f64,
    z_star: f64,
    /// Deviation bounds of x̂ so far.
    history: Vec<f64>,
}

/// One window of [`DeviationBound`]: both scalars' models of the method on the QP the
/// build runs (the scaled one for a Jacobi variant), its scaling, x̂'s propagation rounding
/// in both scalars, L_Φ and o_m.
#[derive(Debug, Clone)]
struct DeviationWindow {
    kernel: DeviationKernel,
    /// The Jacobi scaling d (empty: none, D = I), as the f64 build holds it.
    scaling: Vec<f64>,
    p32: PropagationRounding,
    p64: PropagationRounding,
    l_phi: f64,
    origin_offset: f64,
}

/// The method's one-step models in f32 and f64.
#[derive(Debug, Clone)]
enum DeviationKernel {
    /// Projected gradient: zᵏ⁺¹ = Π(zᵏ − α(Hzᵏ + q)).
    Pg(IterationRounding, IterationRounding),
    /// ADMM (relaxed Douglas–Rachford on s) with its relaxation α.
    Admm(AdmmRounding, AdmmRounding, f64),
    /// V-FISTA: both scalars' K-step models (one storage: the same window) and the exact
    /// certificate's φ(K) = c·ρᴷ as (c, ρ).
    Fista(Box<FistaSteps>, Box<FistaSteps>, (f64, f64)),
}

/// Relative slack on ‖D⁻¹z*‖ ≤ ‖z*‖/d_min for the scaled problem the build holds (its data
/// computed in f64 from the original window's; its optimum differs from D⁻¹z* by f64's
/// rounding times κ, far below this where the f32 contraction holds: u₃₂κ(H) < 1).
const SCALED_OPTIMUM_SLACK: f64 = 1e-6;

/// min_i d_i and max_i d_i of a scaling (1, 1 without one).
fn scaling_extremes(d: &[f64]) -> (f64, f64) {
    if d.is_empty() {
        return (1.0, 1.0);
    }
    (
        d.iter().copied().fold(f64::INFINITY, f64::min),
        d.iter().copied().fold(0.0, f64::max),
    )
}

/// `solver`'s one-step model in precision `u` on the QP its map runs on (the scaled one for
/// a Jacobi variant), with that scaling (empty without one).
fn deviation_model(
    solver: Method,
    qp: &qp_iter::ParametricQp,
    u: f64,
) -> Result<(DeviationHalf, Vec<f64>), String> {
    let plain = solver.with_scaling(qp_iter::Scaling::None);
    let half = |qp: &qp_iter::ParametricQp| -> Result<DeviationHalf, String> {
        match plain.kind {
            qp_iter::MethodKind::Pg(_) => iteration_rounding(&plain, qp, u)
                .map(DeviationHalf::Pg)
                .map_err(|e| e.to_string()),
            qp_iter::MethodKind::Admm(p) => admm_rounding(&plain, qp, u)
                .map(|a| DeviationHalf::Admm(a, p.relaxation))
                .map_err(|e| e.to_string()),
            qp_iter::MethodKind::Fista(_) => {
                let steps = FistaSteps::of(qp, plain, u)?;
                let c = plain
                    .certificate_for(qp.clone())
                    .map_err(|e| e.to_string())?;
                Ok(DeviationHalf::Fista(Box::new(steps), (c.prefactor, c.rate)))
            }
            _ => Err(format!(
                "the per-step deviation bound is derived for projected gradient, V-FISTA and \
                 ADMM (plain and Jacobi-scaled), not {}",
                solver.name()
            )),
        }
    };
    if solver.scaling == qp_iter::Scaling::None {
        return Ok((half(qp)?, Vec::new()));
    }
    let map = solver.build(qp.clone()).map_err(|e| e.to_string())?;
    let qp_iter::MethodMap::Scaled(s) = &map else {
        return Err("internal: a Jacobi method without a scaling".into());
    };
    let h = half(qp_iter::IterationMap::problem(s.inner()))?;
    let d = s.scaling().to_vec();
    let (d_min, d_max) = scaling_extremes(&d);
    if !(d_min > 0.0 && d_max.is_finite()) {
        return Err("the Jacobi scaling is not positive and finite".into());
    }
    Ok((h, d))
}

/// One scalar's model of one window (the half of a [`DeviationKernel`]).
enum DeviationHalf {
    Pg(IterationRounding),
    Admm(AdmmRounding, f64),
    Fista(Box<FistaSteps>, (f64, f64)),
}

impl DeviationBound {
    /// The tracker for `solver` (projected gradient, V-FISTA or ADMM, plain or
    /// Jacobi-scaled) at K = `k`, or why the rounding is not covered.
    pub fn new(
        resolved: &ResolvedScenario,
        cert: &ClosedLoopCertificate,
        solver: Method,
        k: usize,
    ) -> Result<Result<Self, String>, ClosedLoopError> {
        if resolved.mhe_config()?.warm_start != mhe_core::WarmStart::Paper {
            return Ok(Err("only the paper's warm start is covered".into()));
        }
        let w32 = match per_window(resolved, cert, F32_UNIT_ROUNDOFF, |qp| {
            deviation_model(solver, qp, F32_UNIT_ROUNDOFF)
        })? {
            Ok(w) => w,
            Err(e) => return Ok(Err(e)),
        };
        let w64 = match per_window(resolved, cert, F64_UNIT_ROUNDOFF, |qp| {
            deviation_model(solver, qp, F64_UNIT_ROUNDOFF)
        })? {
            Ok(w) => w,
            Err(e) => return Ok(Err(e)),
        };
        let mut windows = Vec::with_capacity(w32.len());
        for (a, b) in w32.into_iter().zip(w64) {
            let ((h32, scaling), (h64, _)) = (a.model, b.model);
            let kernel = match (h32, h64) {
                (DeviationHalf::Pg(i32r), DeviationHalf::Pg(i64r)) => {
                    if !i32r.contracts() {
                        return Ok(Err(format!("window m = {}: r + a ≥ 1 in f32", a.m)));
                    }
                    DeviationKernel::Pg(i32r, i64r)
                }
                (DeviationHalf::Admm(a32, alpha), DeviationHalf::Admm(a64, _)) => {
                    if !(a32.perturbed_rate() < 1.0 && a64.perturbed_rate() < 1.0) {
                        return Ok(Err(format!("window m = {}: r + a ≥ 1 in f32", a.m)));
                    }
                    DeviationKernel::Admm(a32, a64, alpha)
                }
                (DeviationHalf::Fista(f32m, exact), DeviationHalf::Fista(f64m, _)) => {
                    if !(f32m.q() < 1.0 && f64m.q() < 1.0) {
                        return Ok(Err(format!("window m = {}: ρ + s₁Ā ≥ 1 in f32", a.m)));
                    }
                    DeviationKernel::Fista(f32m, f64m, exact)
                }
                _ => return Ok(Err("internal: the two scalars' models differ".into())),
            };
            windows.push(DeviationWindow {
                kernel,
                scaling,
                p32: a.propagation,
                p64: b.propagation,
                l_phi: b.l_phi,
                origin_offset: b.origin_offset,
            });
        }
        Ok(Ok(Self {
            horizon: windows.len() - 1,
            windows,
            k,
            t: 0,
            z_dev: 0.0,
            eps64: 0.0,
            z_star: 0.0,
            history: Vec::new(),
        }))
    }

    /// max_i d_prev,i/d_i over the previous window's variables: ‖D⁻¹(v, 0)‖ ≤ this ×
    /// ‖D_prev⁻¹v‖ (the paper's warm start embeds zᴷ_{t−1} as (zᴷ_{t−1}, 0) while the window
    /// grows, and copies it once it is full: 1 there).
    fn carry(&self, prev: usize, m: usize) -> f64 {
        let (dp, d) = (&self.windows[prev].scaling, &self.windows[m].scaling);
        if prev == m || d.is_empty() {
            return 1.0;
        }
        dp.iter().zip(d).map(|(a, b)| a / b).fold(0.0, f64::max)
    }

    /// The bound on ‖x̂_f32,t − x̂_f64,t‖ at the next t, from ‖θ_t‖ (the f64 run's window
    /// data: prior, u and y) and the norm of its u window.
    pub fn step(&mut self, theta_norm: f64, u_window_norm: f64) -> f64 {
        let u32 = F32_UNIT_ROUNDOFF;
        let m = self.t.min(self.horizon);
        let w = &self.windows[m];
        // The scaling's extremes and the relative errors γ₂ of y⁰ = z⁰/d̃ and z = d̃·y in each
        // scalar (0 without a scaling: the copies are exact).
        let scaled = !w.scaling.is_empty();
        let (d_min, d_max) = scaling_extremes(&w.scaling);
        let (g32, g64) = if scaled {
            (gamma(2, u32), gamma(2, F64_UNIT_ROUNDOFF))
        } else {
            (0.0, 0.0)
        };
        let carry = if self.t == 0 {
            1.0
        } else {
            self.carry(self.t.min(self.horizon + 1) - 1, m)
        };
        // ‖D⁻¹z*_t‖ (Euclidean ‖z*‖ ≤ o + L_Φ‖θ‖; the scaled problem's optimum within the
        // slack).
        let z_star = if scaled {
            (w.origin_offset + w.l_phi * theta_norm) / d_min * (1.0 + SCALED_OPTIMUM_SLACK)
        } else {
            w.origin_offset + w.l_phi * theta_norm
        };
        // The f64 run: ‖D⁻¹(z⁰ − z*)‖ ≤ carry·‖D⁻¹(zᴷ_{t−1} − z*_{t−1})‖ + carry·‖D⁻¹z*_{t−1}‖
        // + ‖D⁻¹z*_t‖ (any window change; at t = 0, z⁰ = (prior, 0) with ‖prior‖ ≤ ‖θ_0‖),
        // then y⁰'s rounded division.
        let e0 = if self.t == 0 {
            theta_norm / d_min + z_star
        } else {
            carry * (self.eps64 + self.z_star) + z_star
        };
        let e0 = e0 + g64 * (e0 + z_star);
        // The data: the prior differs by the deviation M steps back, u and y by rounding.
        let prior_dev = if self.t > self.horizon {
            self.history[self.t - self.horizon]
        } else {
            0.0
        };
        let d_theta = prior_dev + u32 * theta_norm;
        // y⁰'s deviation: the carried one and both rounded divisions
        // (‖D⁻¹z⁰_32‖ ≤ ‖D⁻¹z⁰_64‖ + carry·Z, ‖D⁻¹z⁰_64‖ ≤ ‖y*‖ + e0).
        let carried = carry * self.z_dev;
        let start = carried + g32 * (z_star + e0 + carried) + g64 * (z_star + e0);
        let run = Run {
            k: self.k,
            theta: theta_norm,
            d_theta,
            z_star,
            e0,
            start,
        };
        // (‖yᴷ_32 − yᴷ_64‖, ‖yᴷ_64 − y*‖) after K steps and the output.
        let (y_dev, eps64) = match &w.kernel {
            DeviationKernel::Pg(i32r, i64r) => run.pg(i32r, i64r),
            DeviationKernel::Admm(a32, a64, alpha) => run.admm(a32, a64, *alpha),
            DeviationKernel::Fista(f32m, f64m, exact) => run.fista(f32m, f64m, *exact),
        };
        // z = d̃·y in each scalar: ‖D⁻¹(z₃₂ − z₆₄)‖ ≤ Δ_K + γ₂‖y₃₂‖ + γ₂‖y₆₄‖.
        let y_norm64 = z_star + eps64;
        let z_dev = y_dev + g32 * (y_norm64 + y_dev) + g64 * y_norm64;
        // x̂ = Ψ_m zᴷ + Υ_m u, each computed with its propagation rounding; Euclidean
        // ‖z‖ ≤ d_max‖D⁻¹z‖.
        let z_norm64 = d_max * (1.0 + g64) * y_norm64;
        let z_dev_e = d_max * z_dev;
        let (p32, p64) = (&w.p32, &w.p64);
        let x_dev = p32.psi * z_dev_e
            + p32.upsilon * u32 * u_window_norm
            + p32.from_z * (z_norm64 + z_dev_e)
            + p32.from_u * u_window_norm * (1.0 + u32)
            + p64.from_z * z_norm64
            + p64.from_u * u_window_norm;
        // zᴷ_64 = fl(d·yᴷ_64): ‖D⁻¹(zᴷ_64 − z*)‖ ≤ ‖yᴷ − y*‖ + γ₂‖yᴷ‖ for the next step's start.
        self.eps64 = eps64 + g64 * y_norm64;
        self.z_star = z_star;
        self.z_dev = z_dev;
        self.history.push(x_dev);
        self.t += 1;
        x_dev
    }
}

/// One step's quantities in the model's norm ([`DeviationBound::step`]).
struct Run {
    k: usize,
    /// ‖θ_t‖ and ‖θ̃_t − θ_t‖.
    theta: f64,
    d_theta: f64,
    /// ‖y*‖, the f64 run's ‖y⁰ − y*‖, and ‖y⁰_32 − y⁰_64‖.
    z_star: f64,
    e0: f64,
    start: f64,
}

impl Run {
    fn k(&self) -> i32 {
        i32::try_from(self.k).unwrap_or(i32::MAX)
    }

    /// Projected gradient: Δ_{k+1} ≤ (r + a₃₂)Δ_k + s_θΔθ + (a₃₂ + a₆₄)R + b₃₂(‖θ‖ + Δθ)
    /// + b₆₄‖θ‖ + c₃₂ + c₆₄, R ≥ every f64 iterate's norm.
    fn pg(&self, i32r: &IterationRounding, i64r: &IterationRounding) -> (f64, f64) {
        let (theta, d_theta) = (self.theta, self.d_theta);
        let q64 = i64r.perturbed_rate();
        let d64 = i64r.additive(self.k, self.z_star, theta);
        let eps64 = q64.powi(self.k()) * self.e0 + d64;
        // Every f64 iterate of this step: ‖y_k‖ ≤ ‖y*‖ + ‖y⁰ − y*‖ + d.
        let r_max = self.z_star + self.e0 + d64;
        let q = i32r.perturbed_rate();
        let forcing = i32r.theta_sensitivity * d_theta
            + (i32r.a + i64r.a) * r_max
            + i32r.b * (theta + d_theta)
            + i64r.b * theta
            + i32r.c
            + i64r.c;
        let qk = q.powi(self.k());
        (qk * self.start + (1.0 - qk) / (1.0 - q) * forcing, eps64)
    }

    /// ADMM (docs/theory.md, "ADMM in f32"): s⁰ = (I − H/ρ)z⁰ − q(θ)/ρ exactly, so the
    /// starts differ by ≤ c₀‖Δy⁰‖ + s_θΔθ + both start roundings; the exact step is
    /// r-Lipschitz on s and α·s_θ-Lipschitz in θ (‖αMF‖ ≤ α‖|F|‖/ρ, M = (H + ρI)⁻¹ ⪯ I/ρ),
    /// each computed step adds a‖s‖ + b‖θ‖ + c; the output clamps on the rounded boxes add
    /// u‖bounds‖ each.
    fn admm(&self, a32: &AdmmRounding, a64: &AdmmRounding, alpha: f64) -> (f64, f64) {
        let (theta, d_theta) = (self.theta, self.d_theta);
        let c0 = a64.start;
        // The f64 run against the exact one from the exact s⁰ (Δ₀ ≤ a₀‖y⁰‖ + b₀‖θ‖ + c₀′,
        // Δ_{k+1} ≤ qΔ_k + a(c₀rᵏe₀ + ‖s*‖) + b‖θ‖ + c), ‖s*‖ ≤ c₀‖y*‖ + ‖q‖/ρ.
        let s_star = c0 * self.z_star + a64.s_theta * theta + a64.s_c;
        let y0_64 = self.z_star + self.e0;
        let q64 = a64.perturbed_rate();
        let d64 = a64.a0 * y0_64
            + a64.b0 * theta
            + a64.c0
            + (a64.a * (c0 * self.e0 + s_star) + a64.b * theta + a64.c) / (1.0 - q64);
        // ‖vᴷ − y*‖ ≤ ‖sᴷ − s*‖ + u‖bounds‖ (Π is 1-Lipschitz, y* = Π(s*)).
        let eps64 = a64.rate.powi(self.k()) * c0 * self.e0 + d64 + a64.output;
        // Every f64 iterate: ‖s_k‖ ≤ ‖s*‖ + c₀e₀ + Δ.
        let r_s = s_star + c0 * self.e0 + d64;
        let start = c0 * self.start
            + a64.s_theta * d_theta
            + a32.a0 * (y0_64 + self.start)
            + a32.b0 * (theta + d_theta)
            + a32.c0
            + a64.a0 * y0_64
            + a64.b0 * theta
            + a64.c0;
        let q = a32.perturbed_rate();
        let forcing = alpha * a64.s_theta * d_theta
            + (a32.a + a64.a) * r_s
            + a32.b * (theta + d_theta)
            + a64.b * theta
            + a32.c
            + a64.c;
        let qk = q.powi(self.k());
        let s_dev = qk * start + (1.0 - qk) / (1.0 - q) * forcing;
        (s_dev + a32.output + a64.output, eps64)
    }

    /// V-FISTA (docs/theory.md, "The per-step deviation bound", V-FISTA): the restart step
    /// x¹ = T(y⁰) (β = 0; T is r₀-Lipschitz in y, s_θ-Lipschitz in θ) perturbs x and x₋
    /// alike, Δ₁ ≤ s_𝟙·d₁ in the storage norm N; each later step is the exact map
    /// (ρ-incremental in N for one θ, s₁s_θ between the two θ) plus both scalars' errors
    /// (δ, 0), ‖δ‖ ≤ a_y((1 + β)‖x‖ + β‖x₋‖) + b‖θ‖ + c, the f32 iterate's norm through
    /// ‖x₃₂‖ ≤ ‖x₆₄‖ + c_xΔ: Δ_{k+1} ≤ qΔ_k + s₁·forcing, q = ρ + s₁Ā; the output
    /// ‖x_K,32 − x_K,64‖ ≤ c_xΔ_K. R ≥ every f64 iterate's norm from the f64 model's
    /// supremum Φ̄ = c + sup Δ(K) ("FISTA-Jacobi in f32").
    fn fista(&self, f32m: &FistaSteps, f64m: &FistaSteps, (c, rate): (f64, f64)) -> (f64, f64) {
        let (theta, d_theta) = (self.theta, self.d_theta);
        let m64 = StepRounding::Fista(f64m.clone());
        let inputs64 = m64.beta_z() * self.z_star + m64.beta_theta() * theta + m64.offset_d();
        let phi_k = c * rate.powi(self.k());
        let eps64 = m64.phi_u_at(phi_k, self.k) * self.e0 + inputs64;
        let phi_sup = if rate <= 1.0 { c } else { f64::INFINITY } + f64m.extra_phi(0, true);
        let y0_64 = self.z_star + self.e0;
        let r_max = (self.z_star + phi_sup.max(1.0) * self.e0 + inputs64).max(y0_64);
        let (s32, s64) = (&f32m.step.step, &f64m.step.step);
        let ts = s32.theta_sensitivity;
        // The restart step from y⁰ in both scalars.
        let d1 = f32m.restart_rate * self.start
            + ts * d_theta
            + s32.a * (y0_64 + self.start)
            + s32.b * (theta + d_theta)
            + s32.c
            + s64.a * y0_64
            + s64.b * theta
            + s64.c;
        if self.k <= 1 {
            return (d1, eps64);
        }
        let beta = f32m.step.momentum;
        let forcing = ts * d_theta
            + (f32m.a_y() + f64m.a_y()) * (1.0 + 2.0 * beta) * r_max
            + s32.b * (theta + d_theta)
            + s64.b * theta
            + s32.c
            + s64.c;
        let q = f32m.q();
        let qk = q.powi(self.k() - 1);
        let delta = qk * f32m.s_ones * d1 + (1.0 - qk) / (1.0 - q) * f32m.s_first * forcing;
        (f32m.c_x * delta, eps64)
    }
}
