//! The global loop certificate in a given precision (issue 36; docs/theory.md §4,
//! "The global loop certificate in f32"): the estimator's rounding put into the one LMI.
//!
//! In unit round-off u the window's computed iteration is the exact map plus
//! ‖δ‖ ≤ a‖z‖ + b‖θ‖ + c per step ([`qp_iter::rounding`], window M), and x̂'s computed
//! propagation adds ‖r‖ ≤ ρ_z‖zᴷ‖ + ρ_u‖u window‖ (`certificate::precision`). With r the
//! exact map's one-step rate, q = r + a < 1 and S = 1/(1 − q), K computed steps give
//!
//! ‖d‖ ≤ φ_u(K)‖z⁰ − z*‖ + β_z‖z*‖ + β_θ‖θ‖ + c_d,
//! φ_u(K) = min(qᴷ, φ(K) + sup_{K' ≥ K}(q^{K'} − r^{K'})),
//!
//! β_z = aS, β_θ = bS, c_d = cS. z*, θ, z⁰ are linear in ζ, so the homogeneous part is a
//! quadratic constraint (split (1 + α)/(1 + 1/α)), the propagation's is another (multiplier
//! μ), and the constants c_d, ρ_z c_d are two more bounded exogenous inputs (d_c, r_c) of
//! the γ-channel: the certificate is ISS with an offset. The LMI depends on K only through
//! φ_u(K), non-increasing in K (it bounds every K' ≥ K), so the certified K are
//! {K : φ_u(K) ≤ φ*_u} = {K ≥ K_glob(u)}, φ*_u ≤ the exact φ*.

use closed_loop::scenario::{LoopOptions, ResolvedScenario};
use faer::Mat;
use qp_iter::rounding::{
    AdmmRounding, FistaRounding, IterationRounding, admm_rounding, fista_rounding,
    iteration_rounding,
};
use qp_iter::{IterationMap, Method, MethodKind, MethodMap, ParametricQp, Scaling};

use super::{GlobalCertificate, GlobalError, GlobalLoop, GlobalOptions, mul};
use crate::certificate::precision::{PropagationRounding, propagation_rounding};
use crate::linear::LinearError;

/// The rounding of the global loop's window (length M) in unit round-off u.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct LoopRounding {
    /// The unit round-off u.
    pub unit_roundoff: f64,
    /// K computed iterations on window M (projected gradient or V-FISTA).
    pub steps: StepRounding,
    /// x̂'s propagation through window M: ρ_z (`from_z`), ρ_u (`from_u`).
    pub propagation: PropagationRounding,
}

/// The K-step model of the window's computed iteration:
/// ‖zᴷ − z*‖ ≤ φ_u(K)‖z⁰ − z*‖ + β_z‖z*‖ + β_θ‖θ‖ + c_d.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum StepRounding {
    /// Projected gradient: the exact map contracts in the Euclidean norm with rate r, so the
    /// computed one does with q = r + a (docs/theory.md, step 2).
    Pg(IterationRounding),
    /// V-FISTA: the inner rate's storage P̃ carries the step errors (docs/theory.md, "FISTA
    /// in f32").
    Fista(FistaSteps),
    /// ADMM (relaxed Douglas–Rachford): the exact step is r-Lipschitz on s for any two
    /// points; the rounded start, steps and output clamp (docs/theory.md, "ADMM in f32").
    Admm(AdmmRounding),
    /// A Jacobi-scaled method (projected gradient, V-FISTA or ADMM): the method on the scaled problem
    /// in y = D⁻¹z, with the rounded division y⁰ = z⁰/d and product z = d·y; every bound in
    /// the weighted norm ‖D⁻¹·‖ the global certificate uses for the Jacobi variants
    /// (docs/theory.md, "Jacobi-scaled projected gradient in f32").
    Jacobi(JacobiSteps),
}

/// A Jacobi-scaled method's model: the scaled problem's model and the scaling's extremes.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct JacobiSteps {
    /// K steps on the scaled problem (in y): projected gradient, V-FISTA or ADMM.
    pub scaled: Box<StepRounding>,
    /// Φ̄ ≥ φ_u^y(K) for every K (projected gradient: 1; ADMM: 2c₀ + a₀, since the exact
    /// φ(K) ≤ φ(0) = c₀; V-FISTA: φ^y(0) plus the supremum of its rounding part).
    pub phi_sup: f64,
    /// min_i d_i (‖D⁻¹v‖ ≤ ‖v‖/d_min).
    pub d_min: f64,
    /// max_i d_i (‖v‖ ≤ d_max‖D⁻¹v‖).
    pub d_max: f64,
    /// The unit round-off u.
    pub unit_roundoff: f64,
}

impl JacobiSteps {
    /// γ₂: the relative error of y⁰ = z⁰/d̃ and z = d̃·y with the stored d̃ = fl(d)
    /// (two rounding factors each).
    pub fn scaling_error(&self) -> f64 {
        qp_iter::rounding::gamma(2, self.unit_roundoff)
    }
}

/// V-FISTA's K-step rounding model (docs/theory.md, "FISTA in f32"): the inner-rate LMI
/// (Theorem L1) certifies ‖F(ξ) − F(ξ')‖_N ≤ ρ‖ξ − ξ'‖_N for *any* two states ξ = (x, x₋) on
/// the window's QP (its sector constraints are incremental), N = P̃ ⊗ I; a computed step is
/// F(ξ) + (δ, 0) with ‖δ‖ ≤ a_y((1 + β)‖x‖ + β‖x₋‖) + b‖θ‖ + c.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct FistaSteps {
    /// One step's model (T with step 1/L, the extrapolation).
    pub step: FistaRounding,
    /// ρ: the storage's incremental rate (Theorem L1).
    pub rate: f64,
    /// r₀ = max(|1 − μ/L|, |1 − L̄/L|) on the widened spectrum [μ, L̄]: the restart step's
    /// rate and the Lipschitz constant of T.
    pub restart_rate: f64,
    /// √P̃₁₁ = ‖(δ, 0)‖_N/‖δ‖.
    pub s_first: f64,
    /// √(𝟙ᵀP̃𝟙) = ‖(δ, δ)‖_N/‖δ‖ (the restart step perturbs x and x₋ alike).
    pub s_ones: f64,
    /// √(P̃⁻¹)₁₁ ≥ ‖x‖/‖ξ‖_N.
    pub c_x: f64,
    /// √(P̃⁻¹)₂₂ ≥ ‖x₋‖/‖ξ‖_N.
    pub c_m: f64,
}

impl FistaSteps {
    /// The model of `qp`'s V-FISTA in precision u: the step model and the inner rate's
    /// storage (None with the reason when either is missing).
    pub(crate) fn of(qp: &ParametricQp, method: Method, u: f64) -> Result<Self, String> {
        let step = fista_rounding(&method, qp, u).map_err(|e| e.to_string())?;
        let inner = crate::lure::inner_rate(qp, method).map_err(|e| match e {
            crate::lure::LureError::NoRate { .. } => format!(
                "fista: V-FISTA's inner-rate LMI (sector multipliers on the gradient and the \
                 clamp, Theorem L1) certifies no incremental rate on this window (κ = {}; it \
                 does up to κ ≈ 5), and the f32 bound carries the step errors through it: \
                 rounding not bounded (pg and pg-jacobi have a model at any κ)",
                lti_model::numfmt::sig4(qp.l() / qp.mu())
            ),
            other => other.to_string(),
        })?;
        let p = &inner.storage;
        if p.len() != 4 {
            return Err("internal: V-FISTA's storage is not 2 × 2".into());
        }
        let det = p[0] * p[3] - p[1] * p[2];
        if !(det > 0.0 && p[0] > 0.0 && p[3] > 0.0) {
            return Err("the inner rate's storage is not positive definite".into());
        }
        let (mu, l) = super::super::widened(qp).map_err(|e| e.to_string())?;
        let h = 1.0 / qp.l();
        let restart_rate = (1.0 - h * mu).abs().max((1.0 - h * l).abs());
        // Our own f64 evaluation of these constants: 1e-12 relative covers it.
        let up = 1.0 + 1e-12;
        Ok(Self {
            step,
            rate: inner.rate * up,
            restart_rate: restart_rate * up,
            s_first: p[0].sqrt() * up,
            s_ones: (p[0] + p[1] + p[2] + p[3]).max(0.0).sqrt() * up,
            c_x: (p[3] / det).sqrt() * up,
            c_m: (p[0] / det).sqrt() * up,
        })
    }

    /// a_y with T's Lipschitz constant max(1, r₀).
    pub(crate) fn a_y(&self) -> f64 {
        let a = self.step.step.a;
        (self.restart_rate.max(1.0) + a) * self.step.extrapolation + a
    }

    /// Ā = a_y((1 + β)c_x + βc_m): the step error's gain from ‖ξ − ξ*‖_N.
    pub(crate) fn a_bar(&self) -> f64 {
        let b = self.step.momentum;
        self.a_y() * ((1.0 + b) * self.c_x + b * self.c_m)
    }

    /// q = ρ + √P̃₁₁·Ā: the rate of the computed run's distance to the exact one.
    pub(crate) fn q(&self) -> f64 {
        self.rate + self.s_first * self.a_bar()
    }

    /// The part of φ_u(K) beyond the exact φ(K):
    /// c_x·s_𝟙·[qʲa + s₁Ā r₀ Σ_{k<j} q^{j−1−k}ρᵏ], j = K − 1; with `sup`, its supremum over
    /// every K' ≥ K ([`StepRounding::phi_u`]).
    pub(crate) fn extra_phi(&self, k: usize, sup: bool) -> f64 {
        if k == 0 && !sup {
            return 0.0;
        }
        // K' ≥ max(K, 1): K = 0 runs no step, and its envelope is that of K = 1.
        let j = k.max(1) - 1;
        let (q, rho) = (self.q(), self.rate);
        let ji = i32::try_from(j).unwrap_or(i32::MAX);
        let qj = q.powi(ji);
        // Σ_{k<j} q^{j−1−k}ρᵏ ≤ min(j·q^{j−1}, qʲ/(q − ρ)) (each term ≤ q^{j−1}; q > ρ);
        // over j' ≥ j: j'q^{j'−1} peaks at j' = −1/ln q, qʲ/(q − ρ) decreases.
        let lin = if !sup {
            if j == 0 {
                0.0
            } else {
                j as f64 * q.powi(ji - 1)
            }
        } else if q > 0.0 && q < 1.0 {
            let jf = (j as f64).max(-1.0 / q.ln());
            jf * q.powf(jf - 1.0)
        } else {
            f64::INFINITY
        };
        let sum = if q > rho {
            lin.min(qj / (q - rho))
        } else {
            lin
        };
        self.c_x
            * self.s_ones
            * (qj * self.step.step.a + self.s_first * self.a_bar() * self.restart_rate * sum)
    }

    /// The factor of b and c: c_x(s_𝟙 + s₁/(1 − q)).
    fn input_factor(&self) -> f64 {
        self.c_x * (self.s_ones + self.s_first / (1.0 - self.q()))
    }
}

impl StepRounding {
    /// The model of K computed iterations of `method` on `qp` in unit round-off `u`
    /// (every method, plain or Jacobi-scaled), or why it is not covered
    /// ([`PrecisionVoid::NotCovered`]). The premise q < 1 is the caller's to check
    /// ([`StepRounding::perturbed_rate`]).
    pub fn for_qp(method: Method, qp: &ParametricQp, u: f64) -> Result<Self, PrecisionVoid> {
        let not_covered = |why: String| PrecisionVoid::NotCovered { why };
        if method.scaling == Scaling::Jacobi {
            let map = method
                .build(qp.clone())
                .map_err(|e| not_covered(e.to_string()))?;
            let MethodMap::Scaled(s) = &map else {
                return Err(not_covered(
                    "internal: a Jacobi method without a scaling".into(),
                ));
            };
            let scaled = Self::for_qp(method.with_scaling(Scaling::None), s.inner().problem(), u)
                .map_err(|e| match e {
                PrecisionVoid::NotCovered { why } => not_covered(format!(
                    "on the Jacobi-scaled window (y = D⁻¹z, κ(D) = {}): {why}",
                    lti_model::numfmt::sig4(s.kappa_d())
                )),
                other => other,
            })?;
            let phi_sup = match &scaled {
                Self::Admm(a) => 2.0 * a.start + a.a0,
                // φ^y(K) = c·ρᴷ ≤ φ^y(0) = c (∞ without a rate ≤ 1), plus the rounding
                // part's supremum over every K (`extra_phi` at K = 0 with `sup`).
                Self::Fista(f) => {
                    let c = s.inner().certificate();
                    let exact = if c.rate <= 1.0 {
                        c.prefactor
                    } else {
                        f64::INFINITY
                    };
                    exact + f.extra_phi(0, true)
                }
                _ => 1.0,
            };
            let d = s.scaling();
            let d_min = d.iter().copied().fold(f64::INFINITY, f64::min);
            let d_max = d.iter().copied().fold(0.0, f64::max);
            if !(d_min > 0.0 && d_max.is_finite()) {
                return Err(not_covered(
                    "the Jacobi scaling is not positive and finite".into(),
                ));
            }
            return Ok(Self::Jacobi(JacobiSteps {
                scaled: Box::new(scaled),
                phi_sup,
                d_min,
                d_max,
                unit_roundoff: u,
            }));
        }
        match method.kind {
            MethodKind::Fista(_) => FistaSteps::of(qp, method, u)
                .map(Self::Fista)
                .map_err(not_covered),
            MethodKind::Admm(_) => admm_rounding(&method, qp, u)
                .map(Self::Admm)
                .map_err(|e| not_covered(e.to_string())),
            _ => iteration_rounding(&method, qp, u)
                .map(Self::Pg)
                .map_err(|e| not_covered(e.to_string())),
        }
    }
    /// q: the computed iteration's rate (projected gradient: r + a; V-FISTA: ρ + s₁Ā).
    pub fn perturbed_rate(&self) -> f64 {
        match self {
            Self::Pg(r) => r.perturbed_rate(),
            Self::Fista(f) => f.q(),
            Self::Admm(a) => a.perturbed_rate(),
            Self::Jacobi(j) => j.scaled.perturbed_rate(),
        }
    }
    /// The exact iteration's rate the premise q < 1 starts from (r, or ρ), and the
    /// rounding's addition to it (a, or s₁Ā).
    pub fn rate_and_rounding(&self) -> (f64, f64) {
        match self {
            Self::Pg(r) => (r.rate, r.a),
            Self::Fista(f) => (f.rate, f.s_first * f.a_bar()),
            Self::Admm(a) => (a.rate, a.a),
            Self::Jacobi(j) => j.scaled.rate_and_rounding(),
        }
    }
    /// S = 1/(1 − q) (∞ when q ≥ 1).
    fn sum(&self) -> f64 {
        let q = self.perturbed_rate();
        if q < 1.0 {
            1.0 / (1.0 - q)
        } else {
            f64::INFINITY
        }
    }
    /// β_z: the gain from ‖z*‖ into ‖d‖ (every K). Projected gradient: a/(1 − q); V-FISTA:
    /// c_x(s_𝟙a + s₁A/(1 − q)), A = a_y(1 + 2β).
    pub fn beta_z(&self) -> f64 {
        match self {
            Self::Pg(r) => r.a * self.sum(),
            Self::Fista(f) => {
                let big_a = f.a_y() * (1.0 + 2.0 * f.step.momentum);
                f.c_x * (f.s_ones * f.step.step.a + f.s_first * big_a * self.sum())
            }
            // c₀·(a₀ + a·c₀/(1 − q)): the start's error and the steps' through ‖s*‖.
            Self::Admm(a) => a.a0 + a.a * a.start * self.sum(),
            // ((1 + g)(gΦ̄ + β_z^y) + g)/d_min: the scaled model's β_z on ‖y*‖ plus the
            // two rounded scalings (φ_u^y ≤ Φ̄), and ‖y*‖ ≤ ‖z*‖/d_min.
            Self::Jacobi(j) => {
                let g = j.scaling_error();
                ((1.0 + g) * (g * j.phi_sup + j.scaled.beta_z()) + g) / j.d_min
            }
        }
    }
    /// β_θ: the gain from ‖θ‖ into ‖d‖ (b/(1 − q); V-FISTA: b·c_x(s_𝟙 + s₁/(1 − q))).
    pub fn beta_theta(&self) -> f64 {
        match self {
            Self::Pg(r) => r.b * self.sum(),
            Self::Fista(f) => f.step.step.b * f.input_factor(),
            Self::Admm(a) => a.b0 + (a.a * a.s_theta + a.b) * self.sum(),
            Self::Jacobi(j) => (1.0 + j.scaling_error()) * j.scaled.beta_theta(),
        }
    }
    /// c_d: the constant in ‖d‖ (c/(1 − q); V-FISTA: c·c_x(s_𝟙 + s₁/(1 − q))).
    pub fn offset_d(&self) -> f64 {
        match self {
            Self::Pg(r) => r.c * self.sum(),
            Self::Fista(f) => f.step.step.c * f.input_factor(),
            Self::Admm(a) => a.c0 + (a.a * a.s_c + a.c) * self.sum() + a.output,
            Self::Jacobi(j) => (1.0 + j.scaling_error()) * j.scaled.offset_d(),
        }
    }
    /// φ_u(K) at exactly K from the exact map's certified K-step bound `phi_k` = φ(K)
    /// (docs/theory.md): K computed iterations from z⁰ satisfy
    /// ‖zᴷ − z*‖ ≤ φ_u(K)‖z⁰ − z*‖ + β_z‖z*‖ + β_θ‖θ‖ + c_d. Projected gradient:
    /// min(qᴷ, φ(K) + qᴷ − rᴷ); ADMM: φ(K) + qᴷa₀ + c₀(qᴷ − rᴷ); V-FISTA: φ(K) + c_x s_𝟙[qʲa +
    /// s₁Ā r₀ Σ_{k<j} q^{j−1−k}ρᵏ], j = K − 1. Not monotone in K (qᴷ − rᴷ rises before it
    /// falls): a set of certified K uses [`StepRounding::phi_u`].
    pub fn phi_u_at(&self, phi_k: f64, k: usize) -> f64 {
        self.phi_u_with(phi_k, k, false)
    }

    /// φ_u(K) as the certificates use it: the supremum of [`StepRounding::phi_u_at`] over every
    /// K' ≥ K, given `phi_k` = φ(K) of a non-increasing φ (every φ of `qp_iter` is). So the
    /// bound with φ_u(K) holds for every K' ≥ K and φ_u is non-increasing — "certified from
    /// K_min on" and the bisection for K_min rest on that. The rising parts enter as
    /// sup_{K' ≥ K}(q^{K'} − r^{K'}) (and V-FISTA's sum likewise); equal to `phi_u_at` from
    /// K ≈ 1/ln(1/r) on.
    pub fn phi_u(&self, phi_k: f64, k: usize) -> f64 {
        self.phi_u_with(phi_k, k, true)
    }

    fn phi_u_with(&self, phi_k: f64, k: usize, sup: bool) -> f64 {
        let rise = |q: f64, r: f64| {
            if sup {
                rise_sup(q, r, k)
            } else {
                rise_at(q, r, k as f64)
            }
        };
        match self {
            Self::Pg(r) => {
                let q = r.perturbed_rate();
                let qk = q.powi(i32::try_from(k).unwrap_or(i32::MAX));
                qk.min(phi_k + rise(q, r.rate))
            }
            Self::Fista(f) => phi_k + f.extra_phi(k, sup),
            Self::Admm(a) => {
                let q = a.perturbed_rate();
                let qk = q.powi(i32::try_from(k).unwrap_or(i32::MAX));
                phi_k + qk * a.a0 + a.start * rise(q, a.rate)
            }
            Self::Jacobi(j) => {
                let g = j.scaling_error();
                (1.0 + g).powi(2) * j.scaled.phi_u_with(phi_k, k, sup)
            }
        }
    }
    /// The factor from the model's norm to the Euclidean norm of z (d_max for the Jacobi
    /// variants, whose bounds are on ‖D⁻¹·‖; else 1): the constant c_d enters the loop as
    /// an input in z of norm ≤ this × c_d.
    pub fn to_euclidean(&self) -> f64 {
        match self {
            Self::Jacobi(j) => j.d_max,
            _ => 1.0,
        }
    }
}

/// q^j − r^j (0 when q ≤ r), as qʲ(1 − (r/q)ʲ) with `exp_m1`: no cancellation when r ≈ q,
/// where the rounding's part lives (q − r ~ 10⁻⁵).
fn rise_at(q: f64, r: f64, j: f64) -> f64 {
    if !(q > r) {
        return 0.0;
    }
    if !(r > 0.0) {
        return q.powf(j);
    }
    (q.powf(j) * -(j * (r / q).ln()).exp_m1()).max(0.0)
}

/// sup over real K' ≥ K of q^{K'} − r^{K'} (0 ≤ r < q < 1; 0 when q ≤ r, ∞ when q ≥ 1): the
/// difference rises until K* = ln(ln r / ln q)/ln(q/r) and falls after it.
fn rise_sup(q: f64, r: f64, k: usize) -> f64 {
    if !(q > r) {
        return 0.0;
    }
    if !(q < 1.0) {
        return f64::INFINITY;
    }
    let kf = k as f64;
    let peak = if r > 0.0 {
        // ln(ln r / ln q) = ln(1 + ln(r/q)/ln q): without cancellation when r ≈ q.
        let lrq = (r / q).ln();
        ((lrq / q.ln()).ln_1p() / -lrq).max(kf)
    } else {
        kf
    };
    rise_at(q, r, peak)
}

impl LoopRounding {
    /// q: the computed iteration's rate ([`StepRounding::perturbed_rate`]).
    pub fn perturbed_rate(&self) -> f64 {
        self.steps.perturbed_rate()
    }
    /// β_z ([`StepRounding::beta_z`]).
    pub fn beta_z(&self) -> f64 {
        self.steps.beta_z()
    }
    /// β_θ ([`StepRounding::beta_theta`]).
    pub fn beta_theta(&self) -> f64 {
        self.steps.beta_theta()
    }
    /// c_d ([`StepRounding::offset_d`]).
    pub fn offset_d(&self) -> f64 {
        self.steps.offset_d()
    }
    /// The ultimate-bound offset √(c_d² + (ρ_z c_d)²) with c_d in z's Euclidean norm
    /// ([`StepRounding::to_euclidean`]): the exogenous inputs (d_c, r_c) the certificate's γ
    /// multiplies, besides w.
    pub fn offset(&self) -> f64 {
        let c = self.offset_d() * self.steps.to_euclidean();
        c * (1.0 + self.propagation.from_z.powi(2)).sqrt()
    }
    /// φ_u(K) ([`StepRounding::phi_u`]).
    pub fn phi_u(&self, phi_k: f64, k: usize) -> f64 {
        self.steps.phi_u(phi_k, k)
    }
}

/// Why the global certificate certifies no K in a precision.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum PrecisionVoid {
    /// The exact-arithmetic loop has no certificate (no φ*), so neither has a rounded one.
    Exact,
    /// The method's rounding model is not derived (its sentence, from `qp_iter::rounding`).
    NotCovered {
        /// Why.
        why: String,
    },
    /// Rounding breaks the window's contraction: q ≥ 1 (r + a, or V-FISTA's ρ + s₁Ā).
    ContractionBroken {
        /// The window length M.
        window: usize,
        /// The exact rate (r, or ρ).
        rate: f64,
        /// The rounding's addition to it (a, or s₁Ā).
        rounding: f64,
    },
    /// The LMI with the rounding terms is infeasible even at φ_u = 0 (every K).
    Infeasible {
        /// β_z, β_θ: the rounding's gains into ‖d‖.
        beta: [f64; 2],
    },
    /// φ*_u > 0 but φ_u(K) stays above it up to `k_max`.
    KBeyond {
        /// The search limit.
        k_max: usize,
    },
}

impl std::fmt::Display for PrecisionVoid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use lti_model::numfmt::sig4;
        match self {
            Self::Exact => f.write_str(
                "the exact-arithmetic loop has no global certificate (no φ*); rounding can only \
                 shrink the certified set",
            ),
            Self::NotCovered { why } => write!(f, "not covered: {why}"),
            Self::ContractionBroken {
                window,
                rate,
                rounding,
            } => write!(
                f,
                "void: rounding breaks the contraction in window m = {window} (the exact rate {} \
                 plus the rounding's {} is ≥ 1: u·κ(H) too large); improve the conditioning or \
                 run in f64",
                // A rate within 10⁻⁴ of 1 prints as its distance to 1 (sig4 would say "1").
                if *rate > 0.9999 && *rate < 1.0 {
                    format!("1 − {}", sig4(1.0 - rate))
                } else {
                    sig4(*rate)
                },
                sig4(*rounding)
            ),
            Self::Infeasible { beta } => write!(
                f,
                "void: the LMI with the rounding terms (β_z = {}, β_θ = {}) is infeasible at \
                 every K (even φ_u = 0)",
                sig4(beta[0]),
                sig4(beta[1])
            ),
            Self::KBeyond { k_max } => write!(f, "no K ≤ {k_max} reaches φ*_u"),
        }
    }
}

/// The global certificate in one precision.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct PrecisionCertificate {
    /// The unit round-off u.
    pub unit_roundoff: f64,
    /// The first certified K in this precision (every K ≥ it is certified).
    pub k_glob: Option<usize>,
    /// The exact-arithmetic K_glob (the same φ*, the same K search), for comparison.
    pub k_glob_exact: Option<usize>,
    /// φ*_u: every K with φ_u(K) ≤ it is certified.
    pub phi_star: Option<f64>,
    /// The window's rounding model (None when not covered).
    pub rounding: Option<LoopRounding>,
    /// (α, μ): the split of the homogeneous bound and the propagation's multiplier used.
    pub split: Option<[f64; 2]>,
    /// The checked certificate at φ*_u: ‖X⁺‖²_P ≤ ρ²‖X‖²_P + γ²(‖w‖² + ‖d_c‖² + ‖r_c‖²),
    /// ‖d_c‖² + ‖r_c‖² ≤ `offset`² (its `phi` is √(1 + α)·φ*_u).
    pub certificate: Option<GlobalCertificate>,
    /// Why there is no K (None when there is one).
    pub reason: Option<PrecisionVoid>,
}

impl PrecisionCertificate {
    /// The ultimate-bound offset (0 without a rounding model).
    pub fn offset(&self) -> f64 {
        self.rounding.as_ref().map_or(0.0, LoopRounding::offset)
    }
}

/// The rounding model of `options.method` on the scenario's window M in unit round-off `u`,
/// or why it is not covered.
pub fn loop_rounding(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    u: f64,
) -> Result<Result<LoopRounding, PrecisionVoid>, GlobalError> {
    let problem = resolved.mhe_problem().map_err(LinearError::from)?;
    let m = problem.windows().len() - 1;
    let qp = problem.windows()[m].qp();
    let steps = match StepRounding::for_qp(options.method, qp, u) {
        Ok(s) => s,
        Err(PrecisionVoid::NotCovered { why }) => {
            let why = format!("window m = {m}: {why}");
            return Ok(Err(PrecisionVoid::NotCovered { why }));
        }
        Err(other) => return Ok(Err(other)),
    };
    if !(steps.perturbed_rate() < 1.0) {
        let (rate, rounding) = steps.rate_and_rounding();
        return Ok(Err(PrecisionVoid::ContractionBroken {
            window: m,
            rate,
            rounding,
        }));
    }
    Ok(Ok(LoopRounding {
        unit_roundoff: u,
        steps,
        propagation: propagation_rounding(problem.system(), m, u),
    }))
}

/// The rounding's supply pieces on the augmented ζ (module docs): Σ_β = β_z²ZᵀZ + β_θ²ΘᵀΘ
/// and Σ_r = 2ρ_z²(Z + E_d)ᵀ(Z + E_d) + 2ρ_u²E_UᵀE_U − E_rᵀE_r.
fn supply_pieces(gl: &GlobalLoop, rd: &LoopRounding) -> (Mat<f64>, Mat<f64>) {
    let lay = gl.lifted.layout();
    let (n, nc, nz) = (gl.n_x, gl.n_zeta(), lay.nz);
    let s_theta = gl.lifted.parameter_selection();
    let theta = Mat::from_fn(s_theta.nrows(), nc, |i, j| {
        if j < n { s_theta[(i, j)] } else { 0.0 }
    });
    let z = &gl.zstar;
    let zd = Mat::from_fn(nz, nc, |i, j| {
        z[(i, j)] + if j == gl.d_col + i { 1.0 } else { 0.0 }
    });
    let nuw = lay.horizon * lay.nu;
    let uwin = Mat::from_fn(
        nuw,
        nc,
        |i, j| {
            if j == lay.u_window(0) + i { 1.0 } else { 0.0 }
        },
    );
    // r_h sits just before w: o_w = nc − n_w, o_r = o_w − n_x.
    let o_r = nc - gl.n_w - lay.nx;
    let gram = |m: &Mat<f64>| mul(m.transpose(), m.as_ref());
    let (zz, tt, dd, uu) = (gram(z), gram(&theta), gram(&zd), gram(&uwin));
    let (bz, bt) = (rd.beta_z(), rd.beta_theta());
    let (pz, pu) = (rd.propagation.from_z, rd.propagation.from_u);
    let beta = Mat::from_fn(nc, nc, |i, j| bz * bz * zz[(i, j)] + bt * bt * tt[(i, j)]);
    let prop = Mat::from_fn(nc, nc, |i, j| {
        let r = if i == j && (o_r..o_r + lay.nx).contains(&i) {
            1.0
        } else {
            0.0
        };
        2.0 * pz * pz * dd[(i, j)] + 2.0 * pu * pu * uu[(i, j)] - r
    });
    (beta, prop)
}

/// The pieces of the rounding channel's supply, and the scaling of r_h's block.
struct SupplyPieces<'a> {
    base: &'a GlobalLoop,
    beta: &'a Mat<f64>,
    prop: &'a Mat<f64>,
    /// First column of r_h in ζ.
    o_r: usize,
    /// n_x of the lifted state (r_h's length).
    nxp: usize,
}

impl SupplyPieces<'_> {
    /// `gl` := the base loop with the supply of split (α, μ); returns √(1 + α), the scale of
    /// φ in the LMI. r_h = r̃/√μ: the same LMI with r̃'s block at unit scale (the Riccati's
    /// strictness and the check's allowance are relative to the largest diagonal, which μ
    /// would dominate).
    fn apply(&self, gl: &mut GlobalLoop, [alpha, mu]: [f64; 2]) -> f64 {
        let (o_r, nxp) = (self.o_r, self.nxp);
        let k1 = 2.0 * (1.0 + 1.0 / alpha);
        let sc = |i: usize| {
            if (o_r..o_r + nxp).contains(&i) {
                mu.sqrt().recip()
            } else {
                1.0
            }
        };
        *gl = self.base.clone();
        gl.extra_supply = Some(Mat::from_fn(
            self.beta.nrows(),
            self.beta.ncols(),
            |i, j| (k1 * self.beta[(i, j)] + mu * self.prop[(i, j)]) * sc(i) * sc(j),
        ));
        for j in o_r..o_r + nxp {
            for i in 0..gl.x_plus.nrows() {
                gl.x_plus[(i, j)] *= sc(j);
            }
            for i in 0..gl.xhat.nrows() {
                gl.xhat[(i, j)] *= sc(j);
            }
        }
        if let Some(s3) = gl.sigma_mpc.as_mut() {
            let n = s3.nrows();
            for i in 0..n {
                for j in 0..n {
                    s3[(i, j)] *= sc(i) * sc(j);
                }
            }
        }
        (1.0 + alpha).sqrt()
    }
}

/// The largest φ_u in [0, φ*] (to `opts.phi_tol`) the loop `gl` certifies, given that it
/// certifies φ_u = 0 with `c`; `c` becomes the certificate at the returned φ_u.
fn bisect_phi(
    gl: &GlobalLoop,
    scale: f64,
    phi_star: f64,
    opts: &GlobalOptions,
    c: &mut GlobalCertificate,
) -> f64 {
    let (mut lo, mut hi) = (0.0, phi_star);
    while hi - lo > opts.phi_tol * hi && hi > 1e-12 {
        let mid = if lo == 0.0 {
            hi / 4.0
        } else {
            (lo * hi).sqrt()
        };
        match gl.certify_phi_from(scale * mid, opts, Some(c.tau)) {
            Some(cm) => {
                *c = cm;
                lo = mid;
            }
            None => hi = mid,
        }
    }
    lo
}

/// The global certificate of `options.method` in unit round-off `u` (module docs), from the
/// exact loop `exact_loop` and its exact φ* certificate `exact` (None: the exact loop has
/// none). φ*_u is searched in [0, φ*]: first φ*_u = φ* itself (then K_glob(u) equals the
/// exact K_glob), else a bisection to `opts.phi_tol`, over a few splits (α, μ).
///
/// Errors: as [`super::global_loop`].
pub fn certify_precision(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    exact_loop: &GlobalLoop,
    exact: Option<&GlobalCertificate>,
    u: f64,
    opts: &GlobalOptions,
) -> Result<PrecisionCertificate, GlobalError> {
    let k_exact =
        exact.and_then(|c| crate::lure::first_k(|k| exact_loop.phi(k) <= c.phi, opts.k_max));
    let mut out = PrecisionCertificate {
        unit_roundoff: u,
        k_glob: None,
        k_glob_exact: k_exact,
        phi_star: None,
        rounding: None,
        split: None,
        certificate: None,
        reason: None,
    };
    let rd = match loop_rounding(resolved, options, u)? {
        Ok(r) => r,
        Err(why) => {
            out.reason = Some(why);
            return Ok(out);
        }
    };
    out.rounding = Some(rd.clone());
    let Some(exact) = exact else {
        out.reason = Some(PrecisionVoid::Exact);
        return Ok(out);
    };
    let base = super::build::build(resolved, options, true, true, true)?;
    let (beta, prop) = supply_pieces(&base, &rd);
    let mut gl = base.clone();
    let b = rd.beta_z() + rd.beta_theta();
    let star = exact.phi.max(f64::MIN_POSITIVE);
    // μ must exceed r_h's own storage gain ‖X⁺_rᵀPX⁺_r‖ (else r_h is a free input): scaled
    // by tr(X⁺_rᵀPX⁺_r) ≥ λ_max of the exact certificate's P.
    let o_r = gl.n_zeta() - gl.n_w - gl.lifted.layout().nx;
    let xr = gl.x_plus.as_ref().subcols(o_r, gl.lifted.layout().nx);
    let mr = mul(xr.transpose(), mul(exact.p.as_ref(), xr).as_ref());
    let lam_r = (0..mr.nrows()).map(|i| mr[(i, i)]).sum::<f64>().max(1e-300);
    let mut splits = Vec::new();
    for f in [1.0, 10.0, 100.0] {
        for mu in [4.0, 64.0] {
            splits.push([(f * b / star).clamp(1e-14, 1.0), mu * lam_r]);
        }
    }
    let nxp = gl.lifted.layout().nx;
    let pieces = SupplyPieces {
        base: &base,
        beta: &beta,
        prop: &prop,
        o_r,
        nxp,
    };
    let set = |gl: &mut GlobalLoop, split: [f64; 2]| pieces.apply(gl, split);
    // 1. φ*_u = φ*: K_glob(u) = the exact K_glob.
    let mut best: Option<(f64, [f64; 2], GlobalCertificate)> = None;
    for &s in &splits {
        let scale = set(&mut gl, s);
        if let Some(c) = gl.certify_phi_from(scale * exact.phi, opts, Some(exact.tau)) {
            best = Some((exact.phi, s, c));
            break;
        }
    }
    // 2. Else bisect φ_u in (0, φ*) per split, keeping the largest.
    if best.is_none() {
        for &s in &splits {
            let scale = set(&mut gl, s);
            let Some(mut c) = gl.certify_phi_from(0.0, opts, Some(exact.tau)) else {
                continue;
            };
            let lo = bisect_phi(&gl, scale, exact.phi, opts, &mut c);
            if best.as_ref().is_none_or(|(p, _, _)| lo > *p) {
                best = Some((lo, s, c));
            }
        }
    }
    let Some((phi_u, split, cert)) = best else {
        out.reason = Some(PrecisionVoid::Infeasible {
            beta: [rd.beta_z(), rd.beta_theta()],
        });
        return Ok(out);
    };
    out.phi_star = Some(phi_u);
    out.split = Some(split);
    out.certificate = Some(cert);
    out.k_glob = crate::lure::first_k(|k| rd.phi_u(exact_loop.phi(k), k) <= phi_u, opts.k_max);
    if out.k_glob.is_none() {
        out.reason = Some(PrecisionVoid::KBeyond { k_max: opts.k_max });
    }
    Ok(out)
}
