//! Fast projected gradient (FISTA with constant momentum, "V-FISTA") for strongly convex QPs.
//!
//! Map: the first step after a warm/cold start is one plain projected-gradient step
//! x₀ = T(z⁰); every later step is V-FISTA,
//!
//! x_{k+1} = T(y_k),  y_{k+1} = x_{k+1} + β(x_{k+1} − x_k),  y₀ = x₀,
//!
//! with T(y) = Π_Z(y − ∇f(y)/L), f(z) = ½zᵀHz + qᵀz and β = (√κ − 1)/(√κ + 1).
//! The returned iterate is x (a projection, hence feasible); y may leave Z.
//!
//! ## Requirements
//! H ≻ 0 with μ = λ_min(H), L = λ_max(H), κ = L/μ; Z closed convex with an exact projection.
//!
//! ## Certificate (derivation)
//! Let F = f + I_Z, F* = F(z*). Three facts:
//!
//! (a) *Prox-grad inequality* (Beck 2017, Thm 10.16) for L-smooth f with step 1/L: for all
//!     x ∈ Z and every y ∈ ℝⁿ,
//!     F(x) − F(T(y)) ≥ (L/2)‖x − T(y)‖² − (L/2)‖x − y‖² + ℓ(x, y), where
//!     ℓ(x, y) = f(x) − f(y) − ⟨∇f(y), x − y⟩ ≥ (μ/2)‖x − y‖² by strong convexity.
//!     With x = z*, y = z⁰ and x₀ = T(z⁰):
//!     F(x₀) − F* + (L/2)‖x₀ − z*‖² ≤ ((L − μ)/2)‖z⁰ − z*‖².
//!     This holds for *any* z⁰, feasible or not; it is why the first step is a PG step
//!     (F(z⁰) − F* itself is not bounded by ‖z⁰ − z*‖² alone when ∇f(z*) ≠ 0).
//! (b) *V-FISTA rate* (Beck 2017, Thm 10.42; Nesterov 2018, constant-step scheme §2.2):
//!     F(x_k) − F* ≤ (1 − 1/√κ)ᵏ [F(x₀) − F* + (μ/2)‖x₀ − z*‖²]
//!                 ≤ (1 − 1/√κ)ᵏ ((L − μ)/2)‖z⁰ − z*‖²   (by (a), as μ ≤ L).
//! (c) *Quadratic growth*: for x ∈ Z, F(x) − F* ≥ ⟨∇f(z*), x − z*⟩ + (μ/2)‖x − z*‖²
//!     ≥ (μ/2)‖x − z*‖², since ⟨∇f(z*), x − z*⟩ ≥ 0 is optimality of z* over Z.
//!
//! After K ≥ 1 steps of this map the iterate is z^K = x_{K−1}, so
//! ‖z^K − z*‖ ≤ √(κ − 1) · (1 − 1/√κ)^{(K−1)/2} ‖z⁰ − z*‖,
//! i.e. φ(K) = c·rᴷ with r = √(1 − 1/√κ) and c = √(κ − 1)/r = √(κ + √κ).
//! For K = 0, φ(0) = c ≥ 1 is trivially valid. For κ = 1 the rate is 0: H = μI and the
//! PG step is exact. The bound is on the Euclidean iterate distance and every iterate is
//! feasible, so it fits eq. (11) as is, with a prefactor > 1: for K below roughly
//! √κ·ln κ it is weaker than projected gradient's (1 − 1/κ)ᴷ, beyond that much stronger.
//! With general rows l ≤ Gz ≤ u, T projects exactly onto Z ∩ {l ≤ Gz ≤ u}
//! ([`crate::general_projection`]); (a)–(c) use only that Z is closed convex with an exact
//! projection, so the certificate holds unchanged.
//!
//! ## Reference
//! A. Beck, *First-Order Methods in Optimization*, SIAM 2017, §10.7.7 (V-FISTA),
//! Thm 10.16 and Thm 10.42; Y. Nesterov, *Lectures on Convex Optimization*, 2018, §2.2.

use crate::IterationMap;
use crate::certificate::{BoundedQuantity, CertNorm, Certificate};
use crate::general_projection::ProjectionState;
use crate::kernel::{Vectors, clamp_nan_propagating};
use crate::pg::GradientSetup;
use crate::problem::ParametricQp;

/// Indices of z and q in [`FistaState`]'s vectors.
const Z: usize = 0;
const Q: usize = 3;

/// Fast projected gradient with constant momentum β = (√κ − 1)/(√κ + 1) and step 1/L.
#[derive(Debug, Clone)]
pub struct Fista {
    g: GradientSetup,
    inv_l: f64,
    beta: f64,
    cert: Certificate,
}

/// State of [`Fista`]: iterate x_k and extrapolated point y_k (both updated in place by
/// the fused step), the kernel's scratch buffer (used only for n > 60), loaded q; padded
/// to the kernels' length (see [`crate::kernel::padded_len`]) in one allocation.
#[derive(Debug, Clone)]
pub struct FistaState {
    /// [z, y, scratch, q].
    v: Vectors<4>,
    /// True right after a warm/cold start: the next step is the plain PG step x₀ = T(z⁰).
    restart: bool,
    /// Workspace of the structured Hessian (empty for the dense kernel).
    work: Vec<f64>,
    /// The exact projection's workspace (general rows only).
    proj: Option<Box<ProjectionState>>,
}

impl FistaState {
    /// The projection's workspace and statistics, with general rows.
    pub fn projection(&self) -> Option<&ProjectionState> {
        self.proj.as_deref()
    }
}

impl Fista {
    /// Sets the method up for `qp` (step 1/L, momentum from κ = L/μ).
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use qp_iter::BoxSet;
    /// use qp_iter::{ParametricQp, IterationMap, run_fixed};
    /// use qp_iter::fista::Fista;
    /// let qp = ParametricQp::new(mat![[4.0, 1.0], [1.0, 1.0]], vec![-2.0, -4.0],
    ///     Mat::zeros(2, 0), BoxSet::symmetric(&[2.0, 2.0]).unwrap()).unwrap();
    /// let fista = Fista::new(qp);
    /// let mut s = fista.new_state();
    /// run_fixed(&fista, &mut s, 300);
    /// let z = fista.iterate(&s);
    /// // KKT: z₁ = 2 at its upper bound, z₀ = (2 − 2)/4 = 0 from the first row.
    /// assert!((z[0] - 0.0).abs() < 1e-9 && (z[1] - 2.0).abs() < 1e-9);
    /// let c = fista.certificate();
    /// assert!(c.fits_eq11 && c.phi(300) < 1e-6);
    /// ```
    pub fn new(qp: ParametricQp) -> Self {
        let (mu, l) = (qp.mu(), qp.l());
        let kappa = (l / mu).max(1.0);
        let sk = kappa.sqrt();
        let beta = (sk - 1.0) / (sk + 1.0);
        let rate = (1.0 - 1.0 / sk).max(0.0).sqrt();
        let prefactor = (kappa + sk).sqrt();
        let g = GradientSetup::new(qp);
        let projection = g.projection_words();
        let cert = Certificate {
            rate,
            prefactor,
            quantity: BoundedQuantity::IterateDistance,
            norm: CertNorm::Euclidean,
            fits_eq11: rate < 1.0,
            premise: format!(
                "H ≻ 0 (μ = {mu:.6e}, L = {l:.6e}, κ = {kappa:.6e}), step 1/L, momentum β = (√κ−1)/(√κ+1) = {beta:.6e}, \
                 first step after every (re)start a plain projected-gradient step; {projection}"
            ),
            source: "Beck (2017) Thm 10.16 + Thm 10.42 (V-FISTA) + quadratic growth: \
                     ‖z^K − z*‖ ≤ √(κ−1)(1 − 1/√κ)^((K−1)/2)‖z⁰ − z*‖"
                .into(),
        };
        Self {
            g,
            inv_l: 1.0 / l,
            beta,
            cert,
        }
    }

    /// Like [`Fista::new`], but always through the problem's structured Hessian when it has
    /// one, whatever n (to measure the crossover).
    pub fn new_structured(qp: ParametricQp) -> Self {
        let mut f = Self::new(qp);
        f.g.force_structured();
        f
    }

    /// Whether the steps use the problem's structured Hessian (the problem has one and
    /// n ≥ its [`crate::operator::HessianOperator::dense_crossover`]) instead of the dense
    /// kernel.
    pub fn is_structured(&self) -> bool {
        self.g.op.is_some()
    }

    /// The momentum β = (√κ − 1)/(√κ + 1).
    pub fn momentum(&self) -> f64 {
        self.beta
    }

    /// The step 1/L.
    pub fn step_size(&self) -> f64 {
        self.inv_l
    }

    /// y = z⁰ and the restart flag: the next step is T(z⁰) with zero momentum.
    fn reset(&self, s: &mut FistaState) {
        let [z, y, ..] = s.v.all_mut();
        y.copy_from_slice(z);
        s.restart = true;
    }
}

impl IterationMap for Fista {
    type State = FistaState;

    fn name(&self) -> &'static str {
        "fista"
    }
    fn problem(&self) -> &ParametricQp {
        &self.g.qp
    }
    fn new_state(&self) -> FistaState {
        let mut s = FistaState {
            v: self.g.vectors(Q),
            restart: true,
            work: self.g.op_work(),
            proj: self.g.projection_state(),
        };
        self.cold_start(&mut s);
        s
    }
    fn load(&self, state: &mut FistaState, theta: &[f64]) {
        self.g.load(state.v.get_mut(Q), theta);
        if let (Some(p), Some(ps)) = (&self.g.general, &mut state.proj) {
            p.load(&self.g.qp, ps, theta);
        }
    }
    fn warm_start(&self, state: &mut FistaState, z0: &[f64], _dual: Option<&[f64]>) {
        self.g.start(state.v.get_mut(Z), Some(z0));
        self.reset(state);
    }
    fn cold_start(&self, state: &mut FistaState) {
        self.g.start(state.v.get_mut(Z), None);
        self.reset(state);
    }
    #[inline]
    fn step(&self, s: &mut FistaState) {
        // One pass over the padded H: x_{k+1} = T(y_k) over x_k in `z`, y_{k+1} = x_{k+1}
        // + b(x_{k+1} − x_k) over y_k. On the restart step y = z⁰ and b = 0, so the step
        // is exactly the PG step x₀ = T(z⁰) and y₀ = x₀ (the momentum is reset).
        let b = if s.restart { 0.0 } else { self.beta };
        s.restart = false;
        let g = &self.g;
        let [z, y, scratch, q] = s.v.all_mut();
        if let (Some(p), Some(ps)) = (&g.general, &mut s.proj) {
            // General rows: w = y − (Hy + q)/L unclamped, x⁺ = Π(w) exactly, then momentum.
            let n = g.qp.n();
            // (An empty AlignedVec holds no allocation.)
            let mut w = std::mem::replace(&mut ps.w, crate::kernel::AlignedVec::zeros(0));
            w.copy_from_slice(y);
            g.kernel
                .pg_step_padded(&g.h, &mut w, q, self.inv_l, &p.free_lo, &p.free_hi, scratch);
            p.project(&g.qp, ps, &mut w[..n]);
            for i in 0..n {
                let x = w[i];
                y[i] = x + b * (x - z[i]);
                z[i] = x;
            }
            ps.w = w;
            return;
        }
        match &g.op {
            // Hy through the problem's structure (O(M) for the MHE), then the kernel's
            // update: NaN-preserving clamp, y⁺ = (1 + β)x⁺ − βx.
            Some(op) => {
                let n = g.qp.n();
                op.apply(&y[..n], &mut scratch[..n], &mut s.work);
                let a = self.inv_l;
                for (((((y, z), hy), q), l), u) in y[..n]
                    .iter_mut()
                    .zip(&mut z[..n])
                    .zip(&scratch[..n])
                    .zip(&q[..n])
                    .zip(&g.lower[..n])
                    .zip(&g.upper[..n])
                {
                    let x = clamp_nan_propagating(*y - a * (hy + q), *l, *u);
                    *y = (1.0 + b) * x - b * *z;
                    *z = x;
                }
            }
            None => g
                .kernel
                .fista_step_padded(&g.h, y, q, self.inv_l, &g.lower, &g.upper, b, z, scratch),
        }
    }
    fn iterate<'s>(&self, state: &'s FistaState) -> &'s [f64] {
        self.g.head(state.v.get(Z))
    }
    fn violation(&self, state: &FistaState) -> f64 {
        self.g.violation(state.proj.as_deref(), self.iterate(state))
    }
    fn certificate(&self) -> &Certificate {
        &self.cert
    }
    fn set_kernel(&mut self, kernel: crate::kernel::Kernel) {
        self.g.set_kernel(kernel);
    }
}

/// ξ = (x, y). One coefficient cannot be reached through [`IterationMap`] (a state with
/// x ≠ y cannot be set), so the momentum β is read from [`Fista::momentum`] while T is
/// probed from the real restart step.
impl crate::linearise::Linearise for Fista {
    fn lift_dim(&self) -> usize {
        2 * self.problem().n()
    }
    fn start_steps(&self) -> usize {
        1
    }
    /// ξ₀ = (x₀, y₀) = (T(z⁰), T(z⁰)): the restart step of the real map.
    fn start_probe(&self, st: &mut FistaState, z0: &[f64], theta: &[f64], xi: &mut [f64]) {
        let n = self.problem().n();
        self.load(st, theta);
        self.warm_start(st, z0, None);
        self.step(st);
        let x = self.iterate(st);
        xi[..n].copy_from_slice(x);
        xi[n..].copy_from_slice(x);
    }
    /// x⁺ = T(y) from the real restart step (a plain step from y with zero momentum, the
    /// same fused kernel), y⁺ = x⁺ + β(x⁺ − x) with the map's β.
    fn step_probe(&self, st: &mut FistaState, xi: &[f64], theta: &[f64], out: &mut [f64]) {
        let n = self.problem().n();
        let beta = self.momentum();
        self.load(st, theta);
        self.warm_start(st, &xi[n..], None);
        self.step(st);
        let tx = self.iterate(st);
        for i in 0..n {
            out[i] = tx[i];
            out[n + i] = tx[i] + beta * (tx[i] - xi[i]);
        }
    }
    fn readout(&self) -> faer::Mat<f64> {
        let n = self.problem().n();
        crate::linearise::leading_identity(n, 2 * n)
    }
}

/// `"fista"` (no parameters: step 1/L, momentum from κ).
impl crate::method::Family for Fista {
    type Params = ();
    const NAME: &'static str = "fista";
    const PRESETS: &'static [(&'static str, ())] = &[("fista", ())];
    const KEYS: &'static [&'static str] = &[];
    fn with_keys(base: (), _key: &dyn Fn(&str) -> Option<f64>) {
        base
    }
    fn keys_of(_p: &()) -> Vec<(&'static str, f64)> {
        Vec::new()
    }
    fn validate(_p: &()) -> crate::Result<()> {
        Ok(())
    }
    fn build(_p: &(), qp: ParametricQp) -> crate::Result<crate::MethodMap> {
        Ok(crate::MethodMap::Fista(Fista::new(qp)))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::BoxSet;
    use crate::kernel::AlignedVec;
    use faer::Mat;

    /// n = 7 SPD H (diagonally dominant), two parameters, a box active at the solution.
    fn qp() -> ParametricQp {
        let n = 7;
        let h = Mat::from_fn(n, n, |i, j| {
            if i == j {
                4.0 + i as f64
            } else {
                1.0 / (1.0 + i.abs_diff(j) as f64)
            }
        });
        let f = Mat::from_fn(n, 2, |i, k| ((i + 3 * k) % 4) as f64 - 1.5);
        let q0 = (0..n).map(|i| (i as f64 * 0.7).sin() * 6.0).collect();
        ParametricQp::new(h, q0, f, BoxSet::symmetric(&[0.4; 7]).unwrap()).unwrap()
    }

    /// T(y) = Π_Z(y − (Hy + q)/L) with the crate's padded PG kernel (the certificate's PG
    /// step; same summation as the FISTA kernel, so comparisons are bit for bit).
    fn pg_step(f: &Fista, y: &[f64], q: &[f64]) -> Vec<f64> {
        let (g, n) = (&f.g, f.problem().n());
        let (mut y, q) = (AlignedVec::padded(y), AlignedVec::padded(q));
        let mut scratch = AlignedVec::zeros(g.h.ld());
        g.kernel.pg_step_padded(
            &g.h,
            &mut y,
            &q,
            f.step_size(),
            &g.lower,
            &g.upper,
            &mut scratch,
        );
        y[..n].to_vec()
    }

    #[test]
    fn the_step_after_every_start_is_exactly_the_pg_step() {
        let f = Fista::new(qp());
        let mut s = f.new_state();
        let theta = [0.3, -1.1];
        f.load(&mut s, &theta);
        let q = s.v.get(Q)[..7].to_vec();
        let z0: Vec<f64> = (0..7).map(|i| 0.9 - 0.3 * i as f64).collect(); // outside Z
        for start in 0..3 {
            match start {
                0 => f.warm_start(&mut s, &z0, None),
                1 => f.cold_start(&mut s),
                // A warm start in the middle of a run, with momentum built up.
                _ => {
                    run_steps(&f, &mut s, 9);
                    f.warm_start(&mut s, &z0, None);
                }
            }
            let start_point = f.iterate(&s).to_vec();
            // x₀ = T(z⁰) and, with y₀ = x₀ (momentum reset), x₁ = T(x₀): bit for bit.
            let x0 = pg_step(&f, &start_point, &q);
            f.step(&mut s);
            assert_eq!(f.iterate(&s), x0.as_slice(), "start {start}: x₀");
            let x1 = pg_step(&f, &x0, &q);
            f.step(&mut s);
            assert_eq!(f.iterate(&s), x1.as_slice(), "start {start}: x₁");
            // From then on momentum: x₂ = T(x₁ + β(x₁ − x₀)) (to rounding).
            let y1: Vec<f64> = x1
                .iter()
                .zip(&x0)
                .map(|(a, b)| a + f.momentum() * (a - b))
                .collect();
            let x2 = pg_step(&f, &y1, &q);
            f.step(&mut s);
            for (a, b) in f.iterate(&s).iter().zip(&x2) {
                assert!((a - b).abs() <= 1e-14, "start {start}: x₂ {a} vs {b}");
            }
            // The momentum step differs from a PG step here (the test can fail).
            assert!(
                f.iterate(&s) != pg_step(&f, &x1, &q).as_slice(),
                "start {start}"
            );
        }
    }

    fn run_steps(f: &Fista, s: &mut FistaState, k: usize) {
        for _ in 0..k {
            f.step(s);
        }
    }
}
