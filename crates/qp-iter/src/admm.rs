//! ADMM with a fixed penalty for min ½zᵀHz + qᵀz s.t. z ∈ Z, splitting z = v, v ∈ Z.
//!
//! With the unscaled multiplier y of z − v = 0, penalty ρ and relaxation α, one step is
//!
//! z⁺ = (H + ρI)⁻¹(ρv − y − q),  w = αz⁺ + (1 − α)v + y/ρ,  v⁺ = Π_Z(w),  y⁺ = ρ(w − v⁺).
//!
//! (H + ρI)⁻¹ is formed once at setup (Cholesky, then the dense inverse, stored in the
//! kernels' padded layout), so a step is one matrix–vector product with ρ(H + ρI)⁻¹ plus
//! O(n) work; (H + ρI)⁻¹q is recomputed at [`IterationMap::load`].
//!
//! **Returned iterate**: [`IterationMap::iterate`] is the projected split variable v
//! (always in Z). The unprojected z satisfies Z only in the limit; its distance to Z is
//! [`Admm::constraint_violation`] and ‖z − v‖ is [`Admm::primal_residual`].
//!
//! ## Requirements
//! H ≻ 0 with μ = λ_min(H), L = λ_max(H); Z closed convex with an exact projection;
//! ρ > 0; α ∈ (0, 2].
//!
//! ## Certificate (derivation)
//! The step is relaxed Douglas–Rachford splitting on s = v + y/ρ (the DR variable):
//! v = Π_Z(s), z⁺ = prox_{f/ρ}(2v − s), s⁺ = s + α(z⁺ − v), i.e.
//! s⁺ = (1 − α/2)s + (α/2)R_f R_Z s with reflections R = 2·prox − I, f(z) = ½zᵀHz + qᵀz.
//! (Check: w = αz⁺ + (1 − α)v + s − v = s + α(z⁺ − v) = s⁺, and v⁺ = Π_Z(s⁺).)
//! R_Z is non-expansive; R_f is affine with linear part 2ρ(H + ρI)⁻¹ − I, whose
//! eigenvalues are (ρ − λ)/(ρ + λ), λ ∈ [μ, L], so it is δ-Lipschitz with
//! δ = max(|ρ − μ|/(ρ + μ), |ρ − L|/(ρ + L)). Hence the step is a contraction on s with
//!
//! r = |1 − α/2| + (α/2)·δ,   ‖s^K − s*‖₂ ≤ rᴷ‖s⁰ − s*‖₂,  s* = z* + y*/ρ, y* = −(Hz* + q).
//!
//! This is Giselsson–Boyd's bound for their relaxation parameter α_GB = α/2 (their
//! α_GB = 1/2 is plain DR = ADMM with α = 1, rate (1 + δ)/2; their optimum α_GB = 1 is
//! α = 2 here, rate δ). With ρ = √(μL), δ = (√κ − 1)/(√κ + 1). This is
//! [`Admm::splitting_certificate`] (quantity: splitting variable; any start, any dual).
//!
//! Since v = Π_Z(s) and z* = Π_Z(s*), ‖v^K − z*‖ ≤ ‖s^K − s*‖. When the dual is *not*
//! supplied, the warm start sets y⁰ = −(Hz⁰ + q) (the multiplier z⁰ would have if it were
//! optimal), so s⁰ − s* = (I − H/ρ)(z⁰ − z*) and
//!
//! ‖v^K − z*‖₂ ≤ c·rᴷ‖z⁰ − z*‖₂,  c = ‖I − H/ρ‖₂ = max(|1 − μ/ρ|, |1 − L/ρ|),
//!
//! which is eq. (11) for the feasible iterate v (including K = 0, where v⁰ = Π_Z(s⁰)).
//! That is [`IterationMap::certificate`]; it covers warm starts without a dual and the cold
//! start (which, for this reason, uses the same dual rule rather than y = 0).
//!
//! ## Reference
//! P. Giselsson, S. Boyd, "Linear convergence and metric selection for Douglas–Rachford
//! splitting and ADMM", IEEE TAC 62(2), 2017 (linear rate of relaxed DR for f strongly
//! convex and smooth, here in the identity metric; the derivation above is self-contained);
//! S. Boyd et al., "Distributed optimization and statistical learning via ADMM" (2011)
//! §3.4.3 for over-relaxation.

use std::cell::{Cell, UnsafeCell};

use faer::{Mat, Side};

use crate::IterationMap;
use crate::certificate::{BoundedQuantity, CertNorm, Certificate};
use crate::error::{QpError, Result};
use crate::kernel::{Kernel, PaddedSymmetric, Vectors, clamp_nan_propagating};
use crate::problem::ParametricQp;

/// Penalty rule of [`Admm`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Penalty {
    /// ρ = √(μL): minimises δ(ρ) (Giselsson–Boyd), δ = (√κ − 1)/(√κ + 1).
    Optimal,
    /// A user penalty ρ > 0.
    Fixed(f64),
}

/// Parameters of [`Admm`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdmmParams {
    /// Penalty ρ.
    pub penalty: Penalty,
    /// Relaxation α ∈ (0, 2]: 1 is plain ADMM, 2 gives Giselsson–Boyd's optimal rate δ.
    pub relaxation: f64,
}

impl AdmmParams {
    /// ρ (√(μL) for [`Penalty::Optimal`]) and α for `qp`, validated: ρ positive and finite,
    /// α ∈ (0, 2]. Shared by [`Admm`] and the split on general rows.
    pub(crate) fn resolve(&self, qp: &ParametricQp) -> Result<(f64, f64)> {
        let rho = match self.penalty {
            Penalty::Optimal => (qp.mu() * qp.l()).sqrt(),
            Penalty::Fixed(r) => r,
        };
        let resolved = AdmmParams {
            penalty: Penalty::Fixed(rho),
            relaxation: self.relaxation,
        };
        <Admm as crate::method::Family>::validate(&resolved)?;
        Ok((rho, self.relaxation))
    }
}

impl Default for AdmmParams {
    fn default() -> Self {
        Self {
            penalty: Penalty::Optimal,
            relaxation: 1.0,
        }
    }
}

/// ADMM with a fixed penalty and a factorisation of H + ρI computed once.
#[derive(Debug, Clone)]
pub struct Admm {
    qp: ParametricQp,
    rho: f64,
    alpha: f64,
    /// ρ(H + ρI)⁻¹ in the kernels' padded layout.
    m_rho: PaddedSymmetric,
    /// (H + ρI)⁻¹ in the padded layout (for (H + ρI)⁻¹q at load time).
    m_inv: PaddedSymmetric,
    /// H in the padded layout (for the gradient dual −(Hz⁰ + q) of a start).
    h: PaddedSymmetric,
    cert: Certificate,
    split_cert: Certificate,
    kernel: Kernel,
}

/// State of [`Admm`]: z, the Douglas–Rachford variable s = v + y/ρ, loaded q and
/// (H + ρI)⁻¹q, the next product's input t = 2Π_Z(s) − s = v − y/ρ (updated in place by
/// the fused step), the kernel's scratch buffer (used only for n > 60) and the box
/// (copied, so that everything the step touches but the matrix is one block); padded to
/// the kernels' length (see [`crate::kernel::padded_len`], padding zero), in one
/// allocation. The step stores z, s and t only; v = Π_Z(s) and y = ρ(s − v) are formed
/// from s on the first read after a change (`iterate`, `dual`), in a second block.
pub struct AdmmState {
    /// [z, s, q, m_q, l, u, t, scratch].
    v: Vectors<8>,
    /// [v, y] of the current s once `fresh` is set.
    vy: UnsafeCell<Vectors<2>>,
    /// Whether `vy` holds Π_Z(s) and ρ(s − Π_Z(s)) of the current s. Cleared by every
    /// method taking `&mut AdmmState` that changes s.
    fresh: Cell<bool>,
}

impl Clone for AdmmState {
    fn clone(&self) -> Self {
        Self {
            v: self.v.clone(),
            // SAFETY: `vy` is only written through `Admm::vy` while `fresh` is false, on
            // this thread (AdmmState is not Sync), never while this shared borrow exists.
            vy: UnsafeCell::new(unsafe { &*self.vy.get() }.clone()),
            fresh: self.fresh.clone(),
        }
    }
}

impl std::fmt::Debug for AdmmState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AdmmState")
            .field("v", &self.v)
            .field("fresh", &self.fresh)
            .finish_non_exhaustive()
    }
}

/// Indices into [`AdmmState`]'s vectors.
const Z: usize = 0;
const S: usize = 1;
const LO: usize = 4;
const HI: usize = 5;

impl AdmmState {
    /// The first n entries of vector `i`.
    fn head(&self, i: usize, n: usize) -> &[f64] {
        &self.v.get(i)[..n]
    }
}

impl Admm {
    /// Sets ADMM up for `qp`: validates ρ and α, factorises H + ρI and stores its inverse.
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use qp_iter::BoxSet;
    /// use qp_iter::{ParametricQp, IterationMap, run_fixed};
    /// use qp_iter::admm::{Admm, AdmmParams};
    /// let qp = ParametricQp::new(mat![[4.0, 1.0], [1.0, 1.0]], vec![-2.0, -4.0],
    ///     Mat::zeros(2, 0), BoxSet::symmetric(&[2.0, 2.0]).unwrap()).unwrap();
    /// let admm = Admm::new(qp, AdmmParams::default()).unwrap();
    /// let mut s = admm.new_state();
    /// run_fixed(&admm, &mut s, 300);
    /// let v = admm.iterate(&s); // feasible split variable
    /// assert!((v[0] - 0.0).abs() < 1e-9 && (v[1] - 2.0).abs() < 1e-9);
    /// let y = admm.dual(&s).unwrap(); // y* = −(Hz* + q): upper bound of z₁ active
    /// assert!((y[1] - 2.0).abs() < 1e-9 && admm.constraint_violation(&s) < 1e-9);
    /// assert!(admm.certificate().phi(300) < 1e-6);
    /// ```
    pub fn new(qp: ParametricQp, params: AdmmParams) -> Result<Self> {
        let (mu, l) = (qp.mu(), qp.l());
        let (rho, alpha) = params.resolve(&qp)?;
        let n = qp.n();
        let h = qp.h();
        let shifted = Mat::from_fn(n, n, |i, j| h[(i, j)] + if i == j { rho } else { 0.0 });
        let llt = shifted
            .llt(Side::Lower)
            .map_err(|e| crate::DataError::Numerical {
                routine: "Cholesky factorisation of H + ρI (ADMM setup)".into(),
                reason: format!("{e:?}; H must be positive definite and ρ positive"),
            })?;
        let inv = faer::linalg::solvers::Solve::solve(&llt, Mat::<f64>::identity(n, n));
        // Symmetrise so the stored map is exactly symmetric, as the analysis assumes.
        let sym = |i: usize, j: usize| 0.5 * (inv[(i, j)] + inv[(j, i)]);
        let m_inv = PaddedSymmetric::from_fn(n, sym);
        if m_inv.as_slice().iter().any(|x| !x.is_finite()) {
            return Err(crate::DataError::Numerical {
                routine: "inverse of H + ρI (ADMM setup)".into(),
                reason: "non-finite entries; H + ρI is numerically singular — scale H or change ρ"
                    .into(),
            }
            .into());
        }
        let m_rho = PaddedSymmetric::from_fn(n, |i, j| rho * sym(i, j));
        let h = PaddedSymmetric::from_fn(n, |i, j| h[(i, j)]);

        let delta = ((rho - mu).abs() / (rho + mu)).max((rho - l).abs() / (rho + l));
        let rate = (1.0 - 0.5 * alpha).abs() + 0.5 * alpha * delta;
        let c = (1.0 - mu / rho).abs().max((1.0 - l / rho).abs());
        let common = format!(
            "H ≻ 0 (μ = {mu:.6e}, L = {l:.6e}), fixed penalty ρ = {rho:.6e}, relaxation α = {alpha}, \
             δ = max(|ρ−μ|/(ρ+μ), |ρ−L|/(ρ+L)) = {delta:.6e}, rate |1−α/2| + αδ/2; exact projection onto a box"
        );
        let cert = Certificate {
            rate,
            prefactor: c,
            quantity: BoundedQuantity::IterateDistance,
            norm: CertNorm::Euclidean,
            fits_eq11: rate < 1.0,
            premise: format!(
                "{common}; bound on the returned (feasible) split variable v; warm start without a dual \
                 (y⁰ = −(Hz⁰ + q), also used by the cold start); prefactor ‖I − H/ρ‖₂"
            ),
            source: "Giselsson & Boyd, IEEE TAC 62(2) 2017 (DR contraction, α_GB = α/2) + non-expansive \
                     projection + gradient-dual warm start: ‖v^K − z*‖ ≤ ‖I − H/ρ‖·rᴷ‖z⁰ − z*‖"
                .into(),
        };
        let split_cert = Certificate {
            rate,
            prefactor: 1.0,
            quantity: BoundedQuantity::SplittingVariable,
            norm: CertNorm::Other("Euclidean norm of the DR variable s = v + y/ρ (s* = z* + y*/ρ)".into()),
            fits_eq11: false,
            premise: format!("{common}; any start, any dual"),
            source: "Giselsson & Boyd, IEEE TAC 62(2) 2017, relaxed DR contraction in the Euclidean metric".into(),
        };
        Ok(Self {
            rho,
            alpha,
            m_rho,
            m_inv,
            h,
            qp,
            cert,
            split_cert,
            kernel: crate::kernel::get_global_kernel(),
        })
    }

    /// The penalty ρ.
    pub fn rho(&self) -> f64 {
        self.rho
    }

    /// The relaxation α.
    pub fn relaxation(&self) -> f64 {
        self.alpha
    }

    /// The matrices a step and a load apply, as stored (for code generation that must
    /// reproduce the steps bit for bit): ρ(H + ρI)⁻¹ and (H + ρI)⁻¹.
    pub fn stored_inverses(&self) -> (&PaddedSymmetric, &PaddedSymmetric) {
        (&self.m_rho, &self.m_inv)
    }

    /// ‖s^K − s*‖ ≤ rᴷ‖s⁰ − s*‖ on the DR variable s = v + y/ρ: holds for any start and dual.
    pub fn splitting_certificate(&self) -> &Certificate {
        &self.split_cert
    }

    /// Writes the DR variable s = v + y/ρ (the quantity of [`Admm::splitting_certificate`]).
    pub fn splitting_variable(&self, state: &AdmmState, out: &mut [f64]) {
        let n = self.qp.n();
        for (o, s) in out.iter_mut().zip(state.head(S, n)) {
            *o = *s;
        }
    }

    /// v = Π_Z(s) and y = ρ(s − v) of the current s, formed on the first call after s
    /// changed.
    fn vy<'s>(&self, state: &'s AdmmState) -> (&'s [f64], &'s [f64]) {
        let n = self.qp.n();
        if !state.fresh.get() {
            // SAFETY: `fresh` is false only between a `&mut AdmmState` method and the
            // first call here; every shared borrow of `vy` is handed out below after
            // `fresh` is set, so none exists now, and AdmmState is not Sync, so no other
            // thread calls this on the same state.
            let vy = unsafe { &mut *state.vy.get() };
            let [v, y] = vy.all_mut();
            let (lo, hi, s) = (state.v.get(LO), state.v.get(HI), state.v.get(S));
            for i in 0..n {
                v[i] = clamp_nan_propagating(s[i], lo[i], hi[i]);
                y[i] = self.rho * (s[i] - v[i]);
            }
            state.fresh.set(true);
        }
        // SAFETY: `fresh` is set: nothing writes `vy` until a `&mut AdmmState` method
        // clears it, which ends this borrow first.
        let vy = unsafe { &*state.vy.get() };
        (&vy.get(0)[..n], &vy.get(1)[..n])
    }

    /// The unprojected primal iterate z (in Z only in the limit).
    pub fn primal_z<'s>(&self, state: &'s AdmmState) -> &'s [f64] {
        state.head(Z, self.qp.n())
    }

    /// Euclidean distance of z to Z: how far the unprojected iterate is from feasible.
    pub fn constraint_violation(&self, state: &AdmmState) -> f64 {
        let (lo, up) = (self.qp.zset().lower(), self.qp.zset().upper());
        let mut acc = 0.0;
        for ((z, l), u) in self.primal_z(state).iter().zip(lo).zip(up) {
            let d = z - z.max(*l).min(*u);
            acc += d * d;
        }
        acc.sqrt()
    }

    /// Primal residual ‖z − v‖₂ (≥ [`Admm::constraint_violation`], since v ∈ Z).
    pub fn primal_residual(&self, state: &AdmmState) -> f64 {
        self.primal_z(state)
            .iter()
            .zip(self.iterate(state))
            .map(|(z, v)| (z - v) * (z - v))
            .sum::<f64>()
            .sqrt()
    }

    /// z = z⁰ (warm) or Π_Z(0) (cold), y⁰ given or the gradient dual; then s = z⁰ + y⁰/ρ
    /// and the step's input t = 2Π_Z(s) − s (the formula the fused step uses for t⁺),
    /// padding zero. v = Π_Z(s) and y = ρ(s − v) follow on demand.
    fn start(&self, st: &mut AdmmState, z0: Option<&[f64]>, y0: Option<&[f64]>) {
        let (n, ir) = (self.qp.n(), 1.0 / self.rho);
        let AdmmState { v, vy, fresh } = st;
        let [z, s, q, _, lo, hi, t, _] = v.all_mut();
        // y⁰ goes through y of the lazy block, which is rewritten on the next read.
        let [_, y] = vy.get_mut().all_mut();
        z.fill(0.0);
        y.fill(0.0);
        match z0 {
            Some(z0) => z[..n].copy_from_slice(z0),
            None => self.qp.project(&mut z[..n]),
        }
        match y0 {
            Some(y0) => y[..n].copy_from_slice(y0),
            None => {
                // y = −(Hz + q): the gradient dual (padding: Hz = 0, q = 0).
                self.kernel.matvec_padded(&self.h, z, y);
                for (y, q) in y.iter_mut().zip(&q[..n]) {
                    *y = -(*y + q);
                }
            }
        }
        for i in 0..n {
            s[i] = z[i] + ir * y[i];
            t[i] = 2.0 * clamp_nan_propagating(s[i], lo[i], hi[i]) - s[i];
        }
        fresh.set(false);
    }

    /// Loads q = q₀ + Fθ (or q₀ when `theta` is `None`) and m_q = (H + ρI)⁻¹q.
    fn load_q(&self, st: &mut AdmmState, theta: Option<&[f64]>) {
        let n = self.qp.n();
        let [_, _, q, mq, ..] = st.v.all_mut();
        let q = &mut q[..n];
        match theta {
            Some(theta) => self.qp.linear_term(theta, q),
            None => q.copy_from_slice(self.qp.q0()),
        }
        self.kernel.matvec_padded(&self.m_inv, q, mq);
    }
}

impl IterationMap for Admm {
    type State = AdmmState;

    fn name(&self) -> &'static str {
        "admm"
    }
    fn problem(&self) -> &ParametricQp {
        &self.qp
    }
    fn new_state(&self) -> AdmmState {
        let ld = self.m_rho.ld();
        let mut s = AdmmState {
            v: Vectors::zeros(ld),
            vy: UnsafeCell::new(Vectors::zeros(ld)),
            fresh: Cell::new(false),
        };
        let n = self.qp.n();
        s.v.get_mut(LO)[..n].copy_from_slice(self.qp.zset().lower());
        s.v.get_mut(HI)[..n].copy_from_slice(self.qp.zset().upper());
        self.load_q(&mut s, None);
        self.cold_start(&mut s);
        s
    }
    fn load(&self, state: &mut AdmmState, theta: &[f64]) {
        self.load_q(state, Some(theta));
    }
    /// Warm start from z⁰ and, optionally, the unscaled multiplier y⁰ of z = v.
    /// Without y⁰ the dual is set to −(Hz⁰ + q) for the *loaded* q (load θ first), which
    /// is what [`IterationMap::certificate`] assumes.
    fn warm_start(&self, state: &mut AdmmState, z0: &[f64], dual: Option<&[f64]>) {
        self.start(state, Some(z0), dual);
    }
    /// Warm start from Π_Z(0) without a dual (gradient dual, see the module docs).
    fn cold_start(&self, state: &mut AdmmState) {
        self.start(state, None, None);
    }
    #[inline]
    fn step(&self, s: &mut AdmmState) {
        // One pass over ρ(H + ρI)⁻¹ (exactly symmetric, see `new`): z⁺ = ρ(H + ρI)⁻¹t −
        // (H + ρI)⁻¹q with t = v − y/ρ = 2Π_Z(s) − s, then s⁺ = αz⁺ + s − αΠ_Z(s) (= w of
        // the module docs) and t⁺ row by row, all in place; v and y follow on demand.
        s.fresh.set(false);
        let [z, dr, _, mq, lo, hi, t, scratch] = s.v.all_mut();
        self.kernel
            .admm_dr_step_padded(&self.m_rho, t, mq, self.alpha, lo, hi, z, dr, scratch);
    }
    fn iterate<'s>(&self, state: &'s AdmmState) -> &'s [f64] {
        self.vy(state).0
    }
    fn dual<'s>(&self, state: &'s AdmmState) -> Option<&'s [f64]> {
        Some(self.vy(state).1)
    }
    fn certificate(&self) -> &Certificate {
        &self.cert
    }
    fn set_kernel(&mut self, kernel: Kernel) {
        self.kernel = kernel;
    }
    fn matvecs_per_step(&self) -> usize {
        1
    }
}

/// ξ = s, the splitting variable.
impl crate::linearise::Linearise for Admm {
    fn lift_dim(&self) -> usize {
        self.problem().n()
    }
    /// s⁰ = z⁰ + y⁰/ρ with the gradient dual y⁰ = −(Hz⁰ + q) of the real warm start.
    fn start_probe(&self, st: &mut AdmmState, z0: &[f64], theta: &[f64], xi: &mut [f64]) {
        self.load(st, theta);
        self.warm_start(st, z0, None);
        self.splitting_variable(st, xi);
    }
    /// s = ξ is set through the warm start with the dual 0 (s = z⁰ + 0/ρ), then one real
    /// step (allocates the zero dual: analysis only, never in the hot loop).
    fn step_probe(&self, st: &mut AdmmState, xi: &[f64], theta: &[f64], out: &mut [f64]) {
        let zero = vec![0.0; xi.len()];
        self.load(st, theta);
        self.warm_start(st, xi, Some(&zero));
        self.step(st);
        self.splitting_variable(st, out);
    }
    fn readout(&self) -> Mat<f64> {
        Mat::identity(self.problem().n(), self.problem().n())
    }
}

/// `"admm"` (ρ = √(μL), α = 1), `"admm-pr"` (α = 2), or `{ method = "admm", rho, alpha }`.
/// With general rows it builds the split on [I; G]z ([`crate::admm_general::AdmmSplit`]).
impl crate::method::Family for Admm {
    type Params = AdmmParams;
    const NAME: &'static str = "admm";
    const PRESETS: &'static [(&'static str, AdmmParams)] = &[
        (
            "admm",
            AdmmParams {
                penalty: Penalty::Optimal,
                relaxation: 1.0,
            },
        ),
        (
            "admm-pr",
            AdmmParams {
                penalty: Penalty::Optimal,
                relaxation: 2.0,
            },
        ),
    ];
    const KEYS: &'static [&'static str] = &["rho", "alpha"];
    fn with_keys(base: AdmmParams, key: &dyn Fn(&str) -> Option<f64>) -> AdmmParams {
        AdmmParams {
            penalty: key("rho").map_or(base.penalty, Penalty::Fixed),
            relaxation: key("alpha").unwrap_or(base.relaxation),
        }
    }
    fn keys_of(p: &AdmmParams) -> Vec<(&'static str, f64)> {
        let mut keys = Vec::with_capacity(2);
        if let Penalty::Fixed(r) = p.penalty {
            keys.push(("rho", r));
        }
        keys.push(("alpha", p.relaxation));
        keys
    }
    fn validate(p: &AdmmParams) -> Result<()> {
        let bad = |name: &str, value: f64, reason: &str| {
            Err(QpError::Parameter {
                name: name.into(),
                value,
                reason: reason.into(),
            })
        };
        if let Penalty::Fixed(r) = p.penalty {
            if !(r > 0.0 && r.is_finite()) {
                return bad("rho", r, "the ADMM penalty must be positive and finite");
            }
        }
        if !(p.relaxation > 0.0 && p.relaxation <= 2.0) {
            return bad(
                "alpha",
                p.relaxation,
                "the ADMM relaxation must lie in (0, 2] (1 = plain ADMM)",
            );
        }
        Ok(())
    }
    fn build(p: &AdmmParams, qp: ParametricQp) -> Result<crate::MethodMap> {
        Ok(if qp.general().is_some() {
            crate::MethodMap::AdmmSplit(crate::admm_general::AdmmSplit::new(qp, *p)?)
        } else {
            crate::MethodMap::Admm(Admm::new(qp, *p)?)
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::BoxSet;

    fn qp() -> ParametricQp {
        let n = 9;
        let h = Mat::from_fn(n, n, |i, j| {
            if i == j {
                3.0 + 0.5 * i as f64
            } else {
                0.6 / (1.0 + i.abs_diff(j) as f64)
            }
        });
        let f = Mat::from_fn(n, 2, |i, k| ((2 * i + k) % 5) as f64 - 2.0);
        let q0 = (0..n).map(|i| (i as f64).cos() * 4.0).collect();
        let lo = (0..n)
            .map(|i| if i % 3 == 0 { f64::NEG_INFINITY } else { -0.3 })
            .collect();
        ParametricQp::new(h, q0, f, BoxSet::new(lo, vec![0.5; n]).unwrap()).unwrap()
    }

    /// The unfused map of the module docs, on dense (H + ρI)⁻¹ from faer, step by step:
    /// z⁺ = (H + ρI)⁻¹(ρv − y − q), w = αz⁺ + (1 − α)v + y/ρ, v⁺ = Π_Z(w), y⁺ = ρ(w − v⁺).
    fn reference_run(
        qp: &ParametricQp,
        rho: f64,
        alpha: f64,
        q: &[f64],
        mut v: Vec<f64>,
        mut y: Vec<f64>,
        k: usize,
    ) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = qp.n();
        let h = qp.h();
        let shifted = Mat::from_fn(n, n, |i, j| h[(i, j)] + if i == j { rho } else { 0.0 });
        let inv = faer::linalg::solvers::Solve::solve(
            &shifted.partial_piv_lu(),
            Mat::<f64>::identity(n, n),
        );
        let mut z = vec![];
        for _ in 0..k {
            let rhs: Vec<f64> = (0..n).map(|i| rho * v[i] - y[i] - q[i]).collect();
            z = (0..n)
                .map(|i| (0..n).map(|j| inv[(i, j)] * rhs[j]).sum())
                .collect();
            let w: Vec<f64> = (0..n)
                .map(|i| alpha * z[i] + (1.0 - alpha) * v[i] + y[i] / rho)
                .collect();
            v = w.clone();
            qp.project(&mut v);
            y = (0..n).map(|i| rho * (w[i] - v[i])).collect();
        }
        (v, y, z)
    }

    #[test]
    fn fused_steps_follow_the_unfused_map_after_every_start() {
        let qp = qp();
        let theta = [0.7, -0.4];
        let mut q = vec![0.0; qp.n()];
        qp.linear_term(&theta, &mut q);
        let z0: Vec<f64> = (0..qp.n()).map(|i| 0.8 - 0.2 * i as f64).collect();
        let y0: Vec<f64> = (0..qp.n()).map(|i| 0.1 * i as f64 - 0.4).collect();
        for relaxation in [1.0, 1.6, 2.0] {
            let admm = Admm::new(
                qp.clone(),
                AdmmParams {
                    penalty: Penalty::Fixed(2.5),
                    relaxation,
                },
            )
            .unwrap();
            let mut s = admm.new_state();
            admm.load(&mut s, &theta);
            for dual in [Some(y0.as_slice()), None] {
                // A few steps first, so the start must reset the carried t.
                for _ in 0..4 {
                    admm.step(&mut s);
                }
                admm.warm_start(&mut s, &z0, dual);
                let (v_start, y_start) =
                    (admm.iterate(&s).to_vec(), admm.dual(&s).unwrap().to_vec());
                for k in [1, 2, 7] {
                    let mut t = s.clone();
                    for _ in 0..k {
                        admm.step(&mut t);
                    }
                    let (v, y, z) = reference_run(
                        &qp,
                        2.5,
                        relaxation,
                        &q,
                        v_start.clone(),
                        y_start.clone(),
                        k,
                    );
                    let (tv, ty) = (admm.iterate(&t), admm.dual(&t).unwrap());
                    for i in 0..qp.n() {
                        assert!(
                            (tv[i] - v[i]).abs() <= 1e-12 && (ty[i] - y[i]).abs() <= 1e-11,
                            "α = {relaxation}, dual {}, k = {k}, i = {i}: v {} vs {}, y {} vs {}",
                            dual.is_some(),
                            tv[i],
                            v[i],
                            ty[i],
                            y[i]
                        );
                    }
                    // z: the reference's last z⁺.
                    let tz = admm.primal_z(&t);
                    for i in 0..qp.n() {
                        assert!(
                            (tz[i] - z[i]).abs() <= 1e-12,
                            "α = {relaxation}, k = {k}, i = {i}: z {} vs {}",
                            tz[i],
                            z[i]
                        );
                    }
                }
                // Before any step z is the start point.
                assert_eq!(admm.primal_z(&s), z0, "α = {relaxation}");
            }
        }
    }
}
