//! Rounding model of one iteration in precision u (issue 36): the iteration the portable
//! kernel runs in floating point is the exact map plus a bounded perturbation,
//!
//! fl(Φ)(z) = Φ(z) + δ,  ‖δ‖₂ ≤ a‖z‖₂ + b‖θ‖₂ + c,
//!
//! where Φ is the exact map on the exact data (H, F, q₀, the box, the step, held in f64)
//! and fl(Φ) is the map computed with every datum rounded once to precision u and every
//! operation correctly rounded, summed in the order of `mhe_embedded` (products of a row
//! summed from 0 in column order, q = q₀ + Fθ summed from q₀ in θ order, no fused
//! multiply–add). docs/theory.md, "Certified f32: rounding as an input (issue 36)", derives
//! a, b and c; the proof is Higham's (Accuracy and Stability of Numerical Algorithms,
//! 2nd ed., Lemma 3.1 and §3.1): a quantity computed as a sum of products, each term
//! carrying at most N rounding factors (1 + δᵢ), |δᵢ| ≤ u, equals Σ termⱼ(1 + θⱼ) with
//! |θⱼ| ≤ γ_N = Nu/(1 − Nu). The clamp is exact (a comparison); only the rounded bounds of
//! the box move it, by at most u·|bound| per component.
//!
//! Covered: projected gradient on the problem as given (any constant step,
//! [`iteration_rounding`]) and one V-FISTA step ([`fista_rounding`]: the same model of the
//! projected-gradient step T plus the extrapolation's; FISTA's K-step bound needs the
//! incremental contraction of its inner-rate storage, which `iss-certificate` composes).
//! Not covered (typed [`RoundingVoid`] with the reason): ADMM (its stored ρ(H + ρI)⁻¹ is
//! perturbed by rounding in proportion to κ(H + ρI); the bound is not derived here yet),
//! the Jacobi-scaled maps, problems with general constraint rows, and windows that run the
//! structured Hessian product (it sums in another order than the dense one modelled here).
//!
//! Subnormal numbers: an underflowing product adds an absolute error ≤ 2⁻¹⁵⁰ (f32) or
//! 2⁻¹⁰⁷⁵ (f64), an underflowing sum is exact (gradual underflow); `c` includes that
//! term. Overflow is a premise: every magnitude stays below the format's maximum (the
//! caller checks it with the bound itself).

use crate::method::{Method, MethodKind, Scaling};
use crate::pg::StepRule;
use crate::problem::ParametricQp;

/// Unit round-off of f32, u = 2⁻²⁴.
pub const F32_UNIT_ROUNDOFF: f64 = 5.960_464_477_539_063e-8;
/// Unit round-off of f64, u = 2⁻⁵³.
pub const F64_UNIT_ROUNDOFF: f64 = f64::EPSILON / 2.0;

/// γ_n = n·u/(1 − n·u) (∞ when n·u ≥ 1).
///
/// ```
/// use qp_iter::rounding::{F32_UNIT_ROUNDOFF, gamma};
/// assert!((gamma(10, F32_UNIT_ROUNDOFF) - 5.96e-7).abs() < 1e-9);
/// assert_eq!(gamma(1 << 24, F32_UNIT_ROUNDOFF), f64::INFINITY);
/// ```
pub fn gamma(n: usize, u: f64) -> f64 {
    let nu = n as f64 * u;
    if nu >= 1.0 {
        f64::INFINITY
    } else {
        nu / (1.0 - nu)
    }
}

/// The absolute error of one underflowing product in precision u: 2⁻¹⁰⁷⁵ for f64 (which
/// rounds to 0 in f64 itself, and so does its effect), else 2⁻¹⁵⁰, f32's (valid for any
/// format with at least f32's exponent range).
fn underflow_unit(u: f64) -> f64 {
    if u == F64_UNIT_ROUNDOFF {
        0.0
    } else {
        2f64.powi(-150)
    }
}

/// A bound on ‖|M|‖₂ (the spectral norm of the entrywise absolute value) of a matrix given
/// by `get(i, j)`: √(‖|M|‖₁‖|M|‖_∞), which is ≥ ‖|M|‖₂ (Hölder).
pub fn abs_norm_bound(rows: usize, cols: usize, get: impl Fn(usize, usize) -> f64) -> f64 {
    let mut col_max = 0.0f64;
    let mut row_sums = vec![0.0f64; rows];
    for j in 0..cols {
        let mut s = 0.0;
        for (i, r) in row_sums.iter_mut().enumerate() {
            let v = get(i, j).abs();
            s += v;
            *r += v;
        }
        col_max = col_max.max(s);
    }
    let row_max = row_sums.into_iter().fold(0.0, f64::max);
    // The f64 sums above round up by at most a relative γ_n(2⁻⁵³): covered by this factor.
    (col_max * row_max).sqrt() * (1.0 + 1e-12)
}

/// Why the rounding of a method is not covered.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct RoundingVoid {
    /// The sentence a report prints (what is not covered and why).
    pub reason: String,
}

impl std::fmt::Display for RoundingVoid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.reason)
    }
}

/// The rounding model of one iteration of a covered method on one QP (module docs):
/// ‖fl(Φ)(z) − Φ(z)‖ ≤ a‖z‖ + b‖θ‖ + c, and the exact map's Euclidean contraction rate r.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct IterationRounding {
    /// The unit round-off u the model is for.
    pub unit_roundoff: f64,
    /// The exact map's rate r: ‖Φ(z) − Φ(z')‖ ≤ r‖z − z'‖ (at fixed θ).
    pub rate: f64,
    /// Its sensitivity to θ: ‖Φ_θ(z) − Φ_θ'(z)‖ ≤ s_θ‖θ − θ'‖ (PG: α‖F‖₂ bounded by α‖|F|‖₂).
    pub theta_sensitivity: f64,
    /// Coefficient of ‖z‖.
    pub a: f64,
    /// Coefficient of ‖θ‖.
    pub b: f64,
    /// Constant (q₀, the rounded box, underflow).
    pub c: f64,
    /// N: the most rounding factors one term of a component carries (γ_N is used).
    pub roundings: usize,
}

impl IterationRounding {
    /// r + a: the rate of the computed iteration towards z* (docs/theory.md, step 2).
    pub fn perturbed_rate(&self) -> f64 {
        self.rate + self.a
    }

    /// Whether the computed iteration still contracts (r + a < 1): the premise every bound
    /// below needs.
    pub fn contracts(&self) -> bool {
        self.perturbed_rate() < 1.0
    }

    /// The additive term of K computed iterations from any z⁰:
    /// ‖zᴷ − z*‖ ≤ (r + a)ᴷ‖z⁰ − z*‖ + d_K with d_K = (a‖z*‖ + b‖θ‖ + c)·Σ_{k<K}(r + a)ᵏ;
    /// ∞ when r + a ≥ 1.
    pub fn additive(&self, k: usize, z_star_norm: f64, theta_norm: f64) -> f64 {
        let q = self.perturbed_rate();
        if !(q < 1.0) {
            return f64::INFINITY;
        }
        let sum = (1.0 - q.powi(i32::try_from(k).unwrap_or(i32::MAX))) / (1.0 - q);
        (self.a * z_star_norm + self.b * theta_norm + self.c) * sum
    }
}

/// The rounding model of `method` on `qp` in precision `u` (module docs), or why it is not
/// covered. Projected gradient only: its rate r is a Euclidean contraction of the whole
/// iteration, so one step's model is all its K-step bound needs; FISTA's step model is
/// [`fista_rounding`] and ADMM's K-step one [`admm_rounding`] (their K-step bounds, and the
/// certificates' use of them, are in `iss-certificate`).
pub fn iteration_rounding(
    method: &Method,
    qp: &ParametricQp,
    u: f64,
) -> Result<IterationRounding, RoundingVoid> {
    covered_problem(method, qp, u)?;
    let alpha = match method.kind {
        MethodKind::Pg(rule) => match rule {
            StepRule::InverseL => 1.0 / qp.l(),
            StepRule::Optimal => 2.0 / (qp.l() + qp.mu()),
            StepRule::Fixed(a) => a,
        },
        MethodKind::Fista(_) => {
            return void(
                "FISTA: its state (x, x₋) has no Euclidean contraction, so one step's \
                 perturbation does not bound K steps; its K-step model goes through the inner \
                 rate's storage (`fista_rounding`)"
                    .into(),
            );
        }
        MethodKind::Admm(_) => {
            return void(
                "ADMM: it contracts on s = v + y/ρ, not on the iterate v, so a one-step model \
                 of v does not bound K steps; its K-step model is `admm_rounding`"
                    .into(),
            );
        }
        // The test-only `Trial` method (cfg(test)): unreachable in the library build.
        #[allow(unreachable_patterns)]
        _ => {
            return void(format!(
                "`{}` has no rounding model (only pg and fista are covered)",
                method.name()
            ));
        }
    };
    Ok(gradient_step_rounding(qp, alpha, u))
}

fn void<T>(reason: String) -> Result<T, RoundingVoid> {
    Err(RoundingVoid { reason })
}

/// What every covered method needs of the problem and of u: u in (0, 1), no general rows,
/// no Jacobi scaling, and the dense product (the structured one sums in another order).
fn covered_problem(method: &Method, qp: &ParametricQp, u: f64) -> Result<(), RoundingVoid> {
    if !(u > 0.0 && u < 1.0) {
        return void(format!("unit round-off {u} is not in (0, 1)"));
    }
    if qp.general().is_some() {
        return void(
            "the problem has general constraint rows (bounded sets.state or sets.output): \
             their projection is not an exact clamp, so its rounding is not modelled"
                .into(),
        );
    }
    if method.scaling != Scaling::None {
        return void(format!(
            "`{}`: these one-step models are of the plain method; a Jacobi-scaled one runs the \
             plain method on the scaled problem in y = D⁻¹z (its model: this function on \
             that problem, with the rounded scalings y⁰ = z⁰/d and z = d·y composed around \
             it, as `iss_certificate::lure::global::StepRounding::for_qp` does)",
            method.name()
        ));
    }
    let gradient = matches!(method.kind, MethodKind::Pg(_) | MethodKind::Fista(_));
    if let Some(op) = qp
        .operator()
        .filter(|op| gradient && qp.n() >= op.dense_crossover())
    {
        return void(format!(
            "the window's n_z = {} ≥ {} runs the structured Hessian product (forward and \
             adjoint passes through the dynamics), whose rounding is not modelled (only the \
             dense product's)",
            qp.n(),
            op.dense_crossover()
        ));
    }
    Ok(())
}

/// (‖q₀‖, ‖(max(|l_i|, |u_i|))_finite‖): the norms the models' constants scale with (the
/// rounded box moves a clamp by at most u·|bound| per component).
fn data_norms(qp: &ParametricQp) -> (f64, f64) {
    let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
    let zset = qp.zset();
    let bounds = norm(&mut zset.lower().iter().zip(zset.upper()).map(|(l, h)| {
        let l = if l.is_finite() { l.abs() } else { 0.0 };
        let h = if h.is_finite() { h.abs() } else { 0.0 };
        l.max(h)
    }));
    (norm(&mut qp.q0().iter().copied()), bounds)
}

/// The model of x = Π(z − α(Hz + q₀ + Fθ)) in precision u (docs/theory.md, step 1).
fn gradient_step_rounding(qp: &ParametricQp, alpha: f64, u: f64) -> IterationRounding {
    let (n, nt) = (qp.n(), qp.n_theta());
    let rate = (1.0 - alpha * qp.mu())
        .abs()
        .max((1.0 - alpha * qp.l()).abs());
    let h = qp.h();
    let f = qp.f();
    let h_abs = abs_norm_bound(n, n, |i, j| h[(i, j)]);
    let f_abs = abs_norm_bound(n, nt, |i, j| f[(i, j)]);
    // Rounding factors per term of x = z − α(Hz + q₀ + Fθ) (docs/theory.md, step 1):
    // H_ij z_j: the stored H (1), the product (1), the row sum (≤ n), + q (1), the stored
    // α (1), the product by α (1), the subtraction (1): n + 5. F_ik θ_k: the stored F and
    // θ (2), the product (1), the sum from q₀ (n_θ), + Hz (1), α (2), − (1): n_θ + 7.
    // q₀: stored (1), the sum (n_θ), + Hz (1), α (2), − (1): n_θ + 5. z: − (1).
    let roundings = (n + 5).max(nt + 7);
    let nu = gamma(roundings, u);
    let (q0, bounds) = data_norms(qp);
    // An underflowing product per term: n + n_θ + 2 products per component.
    let underflow = underflow_unit(u) * (n + nt + 2) as f64 * (n as f64).sqrt();
    let a = nu * (1.0 + alpha * h_abs);
    let b = nu * alpha * f_abs;
    let c = nu * alpha * q0 + u * bounds + underflow;
    IterationRounding {
        unit_roundoff: u,
        rate,
        theta_sensitivity: alpha * f_abs,
        a,
        b,
        c,
        roundings,
    }
}

/// The rounding model of one V-FISTA step ([`crate::fista`]) in precision u: the computed
/// step from (x, x₋) is x⁺ = fl(T)(ŷ) with ŷ = fl(x + β(x − x₋)) (or fl((1 + β)x − βx₋) on
/// the structured branch), T the projected-gradient step with step 1/L. Componentwise
/// |ŷ − y| ≤ γ₄((1 + β)|x| + β|x₋|) (the stored β, the difference or the stored 1 + β, the
/// product, the sum: at most four factors per term), and `step` bounds fl(T)(ŷ) − T(ŷ); T
/// is non-expansive, so ‖x⁺ − T(y)‖ ≤ a_y((1 + β)‖x‖ + β‖x₋‖) + b‖θ‖ + c
/// ([`FistaRounding::a_y`]). The restart step after a warm start is `step` itself (β = 0,
/// and ŷ = x exactly). docs/theory.md, "FISTA in f32".
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct FistaRounding {
    /// The model of T (step 1/L): its `rate` is the restart step's contraction 1 − μ/L.
    pub step: IterationRounding,
    /// β, the momentum the map runs with.
    pub momentum: f64,
    /// γ₄: the extrapolation's componentwise relative error.
    pub extrapolation: f64,
}

impl FistaRounding {
    /// a_y = (1 + a)γ₄ + a: ‖fl(T)(ŷ) − T(y)‖ ≤ a_y((1 + β)‖x‖ + β‖x₋‖) + b‖θ‖ + c, from
    /// ‖fl(T)(ŷ) − T(ŷ)‖ ≤ a‖ŷ‖ + b‖θ‖ + c, ‖T(ŷ) − T(y)‖ ≤ ‖ŷ − y‖ and ‖ŷ‖ ≤ ‖y‖ + ‖ŷ − y‖.
    pub fn a_y(&self) -> f64 {
        (1.0 + self.step.a) * self.extrapolation + self.step.a
    }
}

/// The rounding model of one step of `method` = FISTA (plain) on `qp` in precision `u`, or
/// why it is not covered ([`FistaRounding`]).
///
/// ```
/// use faer::mat;
/// use qp_iter::rounding::{F32_UNIT_ROUNDOFF, fista_rounding};
/// use qp_iter::{BoxSet, Method, ParametricQp};
/// let qp = ParametricQp::new(mat![[4.0, 1.0], [1.0, 2.0]], vec![0.5, -1.0],
///     faer::Mat::zeros(2, 0), BoxSet::symmetric(&[1.0, 1.0]).unwrap()).unwrap();
/// let r = fista_rounding(&Method::FISTA, &qp, F32_UNIT_ROUNDOFF).unwrap();
/// assert!(r.momentum > 0.0 && r.a_y() < 1e-5);
/// assert!(fista_rounding(&Method::PG, &qp, F32_UNIT_ROUNDOFF).is_err());
/// ```
pub fn fista_rounding(
    method: &Method,
    qp: &ParametricQp,
    u: f64,
) -> Result<FistaRounding, RoundingVoid> {
    covered_problem(method, qp, u)?;
    if !matches!(method.kind, MethodKind::Fista(_)) {
        return void(format!("`{}` is not FISTA", method.name()));
    }
    let fista = crate::fista::Fista::new(qp.clone());
    Ok(FistaRounding {
        step: gradient_step_rounding(qp, fista.step_size(), u),
        momentum: fista.momentum(),
        extrapolation: gamma(4, u),
    })
}

/// The rounding model of one ADMM solve ([`crate::admm`], relaxed Douglas–Rachford on
/// s = v + y/ρ) in precision u, in `mhe_embedded`'s order (docs/theory.md, "ADMM in f32"):
/// the computed start s̃⁰ = fl(z⁰ + fl(ρ̃⁻¹·ỹ⁰)), ỹ⁰ = −fl(H̃z⁰ + q̃), the computed step
/// s ↦ fl(α̃·fl(fl(M̃_ρ t̃) − m̃q) + fl(s − α̃·Π̃(s))), t̃ = fl(2Π̃(s) − s), with the stored
/// M_ρ = ρ(H + ρI)⁻¹ and m̃q = fl(M̃ q̃), M = (H + ρI)⁻¹, and the output Π̃(sᴷ). The exact
/// step S is r-Lipschitz for any two points (Giselsson–Boyd, the module docs of
/// [`crate::admm`]), so errors stay bounded.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct AdmmRounding {
    /// The unit round-off u.
    pub unit_roundoff: f64,
    /// r = |1 − α/2| + (α/2)δ: the exact step's Lipschitz constant on s.
    pub rate: f64,
    /// c₀ = ‖I − H/ρ‖ (bounded by max|1 − λ/ρ|): ‖s⁰ − s*‖ ≤ c₀‖z⁰ − z*‖ and
    /// ‖s*‖ ≤ c₀‖z*‖ + ‖q‖/ρ.
    pub start: f64,
    /// One step: ‖fl(S)(s) − S(s)‖ ≤ a‖s‖ + b‖θ‖ + c.
    pub a: f64,
    /// Coefficient of ‖θ‖ in one step's error.
    pub b: f64,
    /// Constant of one step's error.
    pub c: f64,
    /// The start: ‖s̃⁰ − s⁰‖ ≤ a₀‖z⁰‖ + b₀‖θ‖ + c₀′.
    pub a0: f64,
    /// Coefficient of ‖θ‖ in the start's error.
    pub b0: f64,
    /// Constant of the start's error.
    pub c0: f64,
    /// ‖|F|‖/ρ and ‖q₀‖/ρ: ‖q‖/ρ ≤ s_θ‖θ‖ + s_c.
    pub s_theta: f64,
    /// ‖q₀‖/ρ.
    pub s_c: f64,
    /// u‖bounds‖: the output clamp on the rounded box.
    pub output: f64,
}

impl AdmmRounding {
    /// q = r + a: the computed step's rate towards the exact run.
    pub fn perturbed_rate(&self) -> f64 {
        self.rate + self.a
    }
}

/// The rounding model of `method` = ADMM (plain, any ρ and α) on `qp` in precision `u`
/// ([`AdmmRounding`]), or why it is not covered.
///
/// ```
/// use faer::mat;
/// use qp_iter::rounding::{F32_UNIT_ROUNDOFF, admm_rounding};
/// use qp_iter::{BoxSet, Method, ParametricQp};
/// let qp = ParametricQp::new(mat![[4.0, 1.0], [1.0, 2.0]], vec![0.5, -1.0],
///     faer::Mat::zeros(2, 0), BoxSet::symmetric(&[1.0, 1.0]).unwrap()).unwrap();
/// let r = admm_rounding(&Method::ADMM, &qp, F32_UNIT_ROUNDOFF).unwrap();
/// assert!(r.perturbed_rate() < 1.0 && r.a < 1e-5);
/// ```
pub fn admm_rounding(
    method: &Method,
    qp: &ParametricQp,
    u: f64,
) -> Result<AdmmRounding, RoundingVoid> {
    covered_problem(method, qp, u)?;
    if !matches!(method.kind, MethodKind::Admm(_)) {
        return void(format!("`{}` is not ADMM", method.name()));
    }
    let map = method.build(qp.clone()).map_err(|e| RoundingVoid {
        reason: e.to_string(),
    })?;
    let crate::MethodMap::Admm(admm) = &map else {
        return void("internal: ADMM built another map".into());
    };
    let (rho, alpha) = (admm.rho(), admm.relaxation());
    let (n, nt) = (qp.n(), qp.n_theta());
    let h = qp.h();
    let f = qp.f();
    let (m_rho, m_inv) = admm.stored_inverses();
    let h_a = abs_norm_bound(n, n, |i, j| h[(i, j)]);
    let f_a = abs_norm_bound(n, nt, |i, j| f[(i, j)]);
    // Stored by columns with leading dimension ld (symmetric: either order).
    let entry =
        |m: &crate::kernel::PaddedSymmetric, i: usize, j: usize| m.as_slice()[j * m.ld() + i];
    let m_r = abs_norm_bound(n, n, |i, j| entry(m_rho, i, j));
    let m_i = abs_norm_bound(n, n, |i, j| entry(m_inv, i, j));
    let (q0n, bnd) = data_norms(qp);
    let g = |k: usize| gamma(k, u);
    let (g_m, g_q, g4) = (g(n + 2), g(nt + 3), g(4));
    // One step's error bound, linear with nonnegative coefficients in (‖s‖, ‖bounds‖, ‖q₀‖,
    // ‖θ‖): docs/theory.md, "ADMM in f32", (i)–(v).
    let step = |s_n: f64, b_n: f64, q0: f64, th: f64| {
        let t = 3.0 * s_n + 2.0 * b_n;
        let dt = 3.0 * u * s_n + (4.0 * u + 2.0 * u * u) * b_n;
        let tt = (1.0 + u).powi(2) * t;
        let e_a = m_r * dt + g_m * m_r * tt;
        let qq = q0 + f_a * th;
        let e_q = m_i * g_q * qq + g_m * m_i * (1.0 + g_q) * qq;
        let z = m_r * t + m_i * qq;
        let e_z = (1.0 + u) * (e_a + e_q) + u * z;
        let c_n = s_n + (1.0 + u) * b_n;
        alpha * e_z + alpha * u * b_n + g4 * (alpha * (z + e_z) + s_n + alpha * c_n)
    };
    // The start's error, linear in (‖z⁰‖, ‖q₀‖, ‖θ‖).
    let start_err = |z_n: f64, q0: f64, th: f64| {
        let qq = q0 + f_a * th;
        let e_hz = g_m * h_a * z_n;
        let e_q = g_q * qq;
        let hzq = h_a * z_n + qq;
        let e_y = (1.0 + u) * (e_hz + e_q) + u * hzq;
        e_y / rho + g(3) * ((hzq + e_y) / rho + z_n)
    };
    let up = 1.0 + 1e-12;
    let (mu, l) = (qp.mu(), qp.l());
    let start = (1.0 - mu / rho).abs().max((1.0 - l / rho).abs()) * up;
    let underflow = underflow_unit(u) * (2 * n + nt + 4) as f64 * (n as f64).sqrt();
    Ok(AdmmRounding {
        unit_roundoff: u,
        rate: admm.splitting_certificate().rate,
        start,
        a: step(1.0, 0.0, 0.0, 0.0) * up,
        b: step(0.0, 0.0, 0.0, 1.0) * up,
        c: step(0.0, bnd, q0n, 0.0) * up + underflow,
        a0: start_err(1.0, 0.0, 0.0) * up,
        b0: start_err(0.0, 0.0, 1.0) * up,
        c0: start_err(0.0, q0n, 0.0) * up + underflow,
        s_theta: f_a / rho * up,
        s_c: q0n / rho * up,
        output: u * bnd,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BoxSet;
    use faer::Mat;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random box QP with H = diag(1 … κ, geometric) + GGᵀ/(10n): condition ≈ κ.
    fn qp(seed: u64, n: usize, nt: usize, kappa: f64) -> ParametricQp {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let g = Mat::<f64>::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        let mut h = &g * g.transpose() * faer::Scale(0.1 / n as f64);
        for i in 0..n {
            h[(i, i)] += kappa.powf(i as f64 / (n - 1) as f64);
        }
        let f = Mat::<f64>::from_fn(n, nt, |_, _| rng.random_range(-2.0..2.0));
        let lower = (0..n)
            .map(|i| if i % 3 == 0 { f64::NEG_INFINITY } else { -0.3 })
            .collect();
        let upper = (0..n)
            .map(|i| if i % 3 == 0 { f64::INFINITY } else { 0.7 })
            .collect();
        ParametricQp::new(h, vec![0.1; n], f, BoxSet::new(lower, upper).expect("box"))
            .expect("valid QP")
    }

    /// One PG step in the scalar `T` in `mhe_embedded`'s order (independent of the model).
    fn pg_step_f32(qp: &ParametricQp, alpha: f64, theta: &[f64], z: &[f32]) -> Vec<f32> {
        let (n, nt) = (qp.n(), qp.n_theta());
        let (h, f) = (qp.h(), qp.f());
        let a = alpha as f32;
        let mut q = vec![0f32; n];
        for (i, qi) in q.iter_mut().enumerate() {
            let mut acc = qp.q0()[i] as f32;
            for k in 0..nt {
                acc += f[(i, k)] as f32 * theta[k] as f32;
            }
            *qi = acc;
        }
        let mut hz = vec![0f32; n];
        for j in 0..n {
            for (i, y) in hz.iter_mut().enumerate() {
                *y += h[(i, j)] as f32 * z[j];
            }
        }
        let zs = qp.zset();
        (0..n)
            .map(|i| {
                let x = z[i] - a * (hz[i] + q[i]);
                let l = zs.lower()[i] as f32;
                let u = zs.upper()[i] as f32;
                let w = if l > x { l } else { x };
                if u < w { u } else { w }
            })
            .collect()
    }

    /// The exact step Φ(z) in f64 (its own rounding, ~1e-16, is far below the f32 bound).
    fn pg_step_exact(qp: &ParametricQp, alpha: f64, theta: &[f64], z: &[f64]) -> Vec<f64> {
        let n = qp.n();
        let mut q = vec![0.0; n];
        qp.linear_term(theta, &mut q);
        let h = qp.h();
        let mut x: Vec<f64> = (0..n)
            .map(|i| {
                let hz: f64 = (0..n).map(|j| h[(i, j)] * z[j]).sum();
                z[i] - alpha * (hz + q[i])
            })
            .collect();
        qp.project(&mut x);
        x
    }

    #[test]
    fn one_pg_step_in_f32_stays_within_the_model() {
        let mut worst = 0.0f64;
        for seed in 0..40 {
            let (n, nt) = (3 + (seed as usize % 20), 2 + (seed as usize % 7));
            let p = qp(seed, n, nt, 10f64.powi(1 + (seed % 4) as i32));
            let r = iteration_rounding(&Method::PG, &p, F32_UNIT_ROUNDOFF).expect("pg is covered");
            let alpha = 2.0 / (p.l() + p.mu());
            let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
            for _ in 0..20 {
                let scale = 10f64.powi(rng.random_range(-3..4));
                let theta: Vec<f64> = (0..nt)
                    .map(|_| scale * rng.random_range(-1.0..1.0))
                    .collect();
                let z32: Vec<f32> = (0..n)
                    .map(|_| (scale * rng.random_range(-1.0..1.0)) as f32)
                    .collect();
                let z: Vec<f64> = z32.iter().map(|v| f64::from(*v)).collect();
                let got = pg_step_f32(&p, alpha, &theta, &z32);
                let want = pg_step_exact(&p, alpha, &theta, &z);
                let err = got
                    .iter()
                    .zip(&want)
                    .map(|(g, w)| (f64::from(*g) - w).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let zn = z.iter().map(|v| v * v).sum::<f64>().sqrt();
                let tn = theta.iter().map(|v| v * v).sum::<f64>().sqrt();
                let bound = r.a * zn + r.b * tn + r.c;
                assert!(err <= bound, "seed {seed}: error {err:e} > bound {bound:e}");
                worst = worst.max(err / bound);
            }
        }
        // The model is a worst case: the measured error sits well below it, but not absurdly.
        println!("largest measured/bound over 800 steps: {worst:.3e}");
        assert!(worst > 1e-4, "measured/bound = {worst:e}");
    }

    /// One V-FISTA step in f32 from (x, x₋) in `mhe_embedded`'s dense order: ŷ = x + β(x − x₋),
    /// then the projected-gradient step with step 1/L at ŷ.
    fn fista_step_f32(
        qp: &ParametricQp,
        beta: f64,
        theta: &[f64],
        x: &[f32],
        xm: &[f32],
    ) -> Vec<f32> {
        let b = beta as f32;
        let y: Vec<f32> = x.iter().zip(xm).map(|(x, m)| *x + b * (*x - *m)).collect();
        pg_step_f32(qp, 1.0 / qp.l(), theta, &y)
    }

    #[test]
    fn one_fista_step_in_f32_stays_within_the_model() {
        let mut worst = 0.0f64;
        for seed in 0..40 {
            let (n, nt) = (3 + (seed as usize % 20), 2 + (seed as usize % 7));
            let p = qp(seed, n, nt, 10f64.powi(1 + (seed % 4) as i32));
            let r = fista_rounding(&Method::FISTA, &p, F32_UNIT_ROUNDOFF).expect("covered");
            let beta = r.momentum;
            let mut rng = ChaCha8Rng::seed_from_u64(2000 + seed);
            for _ in 0..20 {
                let scale = 10f64.powi(rng.random_range(-3..4));
                let mut draw = |k: usize| -> Vec<f64> {
                    (0..k)
                        .map(|_| scale * rng.random_range(-1.0..1.0))
                        .collect()
                };
                let theta = draw(nt);
                let x32: Vec<f32> = draw(n).iter().map(|v| *v as f32).collect();
                let xm32: Vec<f32> = draw(n).iter().map(|v| *v as f32).collect();
                let x: Vec<f64> = x32.iter().map(|v| f64::from(*v)).collect();
                let xm: Vec<f64> = xm32.iter().map(|v| f64::from(*v)).collect();
                let got = fista_step_f32(&p, beta, &theta, &x32, &xm32);
                let y: Vec<f64> = x.iter().zip(&xm).map(|(x, m)| x + beta * (x - m)).collect();
                let want = pg_step_exact(&p, 1.0 / p.l(), &theta, &y);
                let nrm = |v: &[f64]| v.iter().map(|v| v * v).sum::<f64>().sqrt();
                let err = nrm(&got
                    .iter()
                    .zip(&want)
                    .map(|(g, w)| f64::from(*g) - w)
                    .collect::<Vec<_>>());
                let bound = r.a_y() * ((1.0 + beta) * nrm(&x) + beta * nrm(&xm))
                    + r.step.b * nrm(&theta)
                    + r.step.c;
                assert!(err <= bound, "seed {seed}: error {err:e} > bound {bound:e}");
                worst = worst.max(err / bound);
            }
        }
        println!("largest measured/bound over 800 FISTA steps: {worst:.3e}");
        assert!(worst > 1e-4, "measured/bound = {worst:e}");
    }

    #[test]
    fn a_window_on_the_structured_product_is_not_covered() {
        #[derive(Debug)]
        struct Dense(Mat<f64>);
        impl crate::operator::HessianOperator for Dense {
            fn n(&self) -> usize {
                self.0.nrows()
            }
            fn work_len(&self) -> usize {
                0
            }
            fn apply(&self, z: &[f64], out: &mut [f64], _: &mut [f64]) {
                for (i, o) in out.iter_mut().enumerate() {
                    *o = (0..z.len()).map(|j| self.0[(i, j)] * z[j]).sum();
                }
            }
            fn dense_crossover(&self) -> usize {
                4
            }
        }
        let small = qp(3, 3, 2, 10.0);
        let op = std::sync::Arc::new(Dense(small.h().to_owned()));
        let p = small.clone().with_operator(op.clone()).expect("same n");
        // n = 3 < 4: the dense product runs, covered.
        assert!(iteration_rounding(&Method::PG, &p, F32_UNIT_ROUNDOFF).is_ok());
        let big = qp(3, 6, 2, 10.0);
        let op = std::sync::Arc::new(Dense(big.h().to_owned()));
        let p = big.with_operator(op).expect("same n");
        for m in [Method::PG, Method::FISTA] {
            let why = if m == Method::PG {
                iteration_rounding(&m, &p, F32_UNIT_ROUNDOFF).expect_err("structured")
            } else {
                fista_rounding(&m, &p, F32_UNIT_ROUNDOFF).expect_err("structured")
            };
            assert!(why.reason.contains("structured Hessian product"), "{why}");
        }
    }

    #[test]
    fn an_ill_conditioned_qp_breaks_the_f32_contraction_and_not_the_f64_one() {
        // κ = 1e7: 1 − r = 2/(κ + 1) ≈ 2e-7 < a ≈ (n + 5)u(1 + α‖|H|‖) in f32.
        let p = qp(7, 12, 4, 1e7);
        let r32 = iteration_rounding(&Method::PG, &p, F32_UNIT_ROUNDOFF).expect("covered");
        assert!(r32.rate < 1.0 && !r32.contracts(), "{r32:?}");
        assert_eq!(r32.additive(10, 1.0, 1.0), f64::INFINITY);
        let r64 = iteration_rounding(&Method::PG, &p, F64_UNIT_ROUNDOFF).expect("covered");
        assert!(r64.contracts(), "{r64:?}");
        // A well-conditioned one contracts in f32 too.
        let good = iteration_rounding(&Method::PG, &qp(7, 12, 4, 100.0), F32_UNIT_ROUNDOFF)
            .expect("covered");
        assert!(good.contracts());
    }

    #[test]
    fn uncovered_methods_say_why() {
        let p = qp(1, 5, 2, 10.0);
        for m in [
            Method::FISTA,
            Method::ADMM,
            Method::PG.with_scaling(Scaling::Jacobi),
        ] {
            let e = iteration_rounding(&m, &p, F32_UNIT_ROUNDOFF).expect_err("not covered");
            assert!(!e.reason.is_empty());
        }
        // FISTA's model is its own (no Euclidean contraction of one step).
        assert!(
            iteration_rounding(&Method::FISTA, &p, F32_UNIT_ROUNDOFF)
                .expect_err("not covered")
                .reason
                .contains("fista_rounding")
        );
        assert!(fista_rounding(&Method::FISTA, &p, F32_UNIT_ROUNDOFF).is_ok());
        for m in [Method::ADMM, Method::FISTA.with_scaling(Scaling::Jacobi)] {
            assert!(fista_rounding(&m, &p, F32_UNIT_ROUNDOFF).is_err());
        }
    }
}
