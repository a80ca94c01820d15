//! Projected gradient: z⁺ = Π_Z(z − α(Hz + q)).
//!
//! ## Requirements
//! H ≻ 0 with μ = λ_min(H), L = λ_max(H); Z closed convex with an exact projection.
//!
//! ## Certificate
//! ‖zᴷ − z*‖₂ ≤ φ(K)‖z⁰ − z*‖₂ with φ(K) = q(α)ᴷ, q(α) = max(|1 − αμ|, |1 − αL|):
//! the gradient step z ↦ z − α∇f(z) is a q(α)-contraction for a quadratic, the projection
//! is non-expansive and z* is a fixed point of the map. For α = 1/L this is (1 − μ/L)ᴷ,
//! for α = 2/(L+μ) it is ((κ−1)/(κ+1))ᴷ.
//! Every iterate is feasible (it is a projection), so the bound fits eq. (11) as is.
//! With general rows l ≤ Gz ≤ u the projection onto Z ∩ {l ≤ Gz ≤ u} is exact
//! ([`crate::general_projection`]), and the certificate holds unchanged.
//!
//! ## Reference
//! Y. Nesterov, *Lectures on Convex Optimization* (2018), Thm. 2.1.15 and §2.2.4;
//! the contraction argument for quadratics is the one used in Richter, Jones, Morari,
//! "Computational complexity certification for real-time MPC with input constraints
//! based on the fast gradient method", IEEE TAC 57(6), 2012.

use crate::IterationMap;
use crate::certificate::{BoundedQuantity, CertNorm, Certificate};
use crate::error::{QpError, Result};
use crate::general_projection::{GeneralProjection, ProjectionState};
use crate::kernel::{AlignedVec, Kernel, PaddedSymmetric, Vectors, clamp_nan_propagating};
use crate::operator::HessianOperator;
use crate::problem::ParametricQp;
use std::sync::Arc;

/// Step-size rule of [`ProjectedGradient`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepRule {
    /// α = 1/L: rate 1 − μ/L.
    InverseL,
    /// α = 2/(L + μ): rate (κ − 1)/(κ + 1), the best constant step.
    Optimal,
    /// A user step α. The certificate uses max(|1 − αμ|, |1 − αL|), which is ≥ 1
    /// (no certificate) for α ≥ 2/L.
    Fixed(f64),
}

/// What projected gradient and FISTA share: the problem, H and the box in the padded
/// layout of the kernels ([`crate::kernel::PaddedSymmetric`], zero padding), the kernel,
/// the structured Hessian when it replaces the dense kernel, and the handling of the
/// padded state vectors (linear term, warm and cold start).
#[derive(Debug, Clone)]
pub(crate) struct GradientSetup {
    pub(crate) qp: ParametricQp,
    pub(crate) h: PaddedSymmetric,
    pub(crate) lower: AlignedVec,
    pub(crate) upper: AlignedVec,
    pub(crate) kernel: Kernel,
    /// The problem's structured Hessian, used instead of the dense kernel when n ≥ its
    /// [`HessianOperator::dense_crossover`] (or when forced), and never with general rows.
    pub(crate) op: Option<Arc<dyn HessianOperator>>,
    /// The exact projection onto Z ∩ {l ≤ Gz ≤ u} when the problem has general rows.
    pub(crate) general: Option<GeneralProjection>,
}

impl GradientSetup {
    pub(crate) fn new(qp: ParametricQp) -> Self {
        let n = qp.n();
        let h = qp.h();
        let h = PaddedSymmetric::from_fn(n, |i, j| h[(i, j)]);
        Self {
            general: GeneralProjection::new(&qp, h.ld()),
            h,
            lower: AlignedVec::padded(qp.zset().lower()),
            upper: AlignedVec::padded(qp.zset().upper()),
            kernel: crate::kernel::get_global_kernel(),
            op: qp
                .operator()
                .filter(|op| n >= op.dense_crossover() && qp.general().is_none())
                .cloned(),
            qp,
        }
    }

    /// Uses the problem's structured Hessian (if it has one) whatever n.
    pub(crate) fn force_structured(&mut self) {
        if self.general.is_none() {
            self.op = self.qp.operator().cloned();
        }
    }

    /// The dense steps on `kernel`, and the structured Hessian (if one runs) on the same
    /// path: a map set to the portable kernel runs no fused multiply–add anywhere.
    pub(crate) fn set_kernel(&mut self, kernel: Kernel) {
        self.kernel = kernel;
        if let Some(op) = self.op.as_ref().and_then(|op| op.on_kernel(kernel)) {
            self.op = Some(op);
        }
    }

    /// Workspace of the structured Hessian (empty for the dense kernel).
    pub(crate) fn op_work(&self) -> Vec<f64> {
        vec![0.0; self.op.as_ref().map_or(0, |op| op.work_len())]
    }

    /// `K` padded zero vectors; vector `q` holds the padded q₀ (the linear term of θ = 0).
    pub(crate) fn vectors<const K: usize>(&self, q: usize) -> Vectors<K> {
        let mut v = Vectors::zeros(self.h.ld());
        v.get_mut(q)[..self.qp.n()].copy_from_slice(self.qp.q0());
        v
    }

    /// q = q₀ + Fθ into the first n entries (the padding stays zero).
    #[inline]
    pub(crate) fn load(&self, q: &mut [f64], theta: &[f64]) {
        self.qp.linear_term(theta, &mut q[..self.qp.n()]);
    }

    /// z = z⁰ (warm start) or Π_Z(0) (cold start), padding reset to zero.
    #[inline]
    pub(crate) fn start(&self, z: &mut [f64], z0: Option<&[f64]>) {
        z.fill(0.0);
        let z = &mut z[..self.qp.n()];
        match z0 {
            Some(z0) => z.copy_from_slice(z0),
            None => self.qp.project(z),
        }
    }

    /// The projection state of a new map state (`None` without general rows).
    pub(crate) fn projection_state(&self) -> Option<Box<ProjectionState>> {
        self.general
            .as_ref()
            .map(|p| Box::new(p.new_state(&self.qp, self.h.ld())))
    }

    /// The premise's words for the projection this setup performs.
    pub(crate) fn projection_words(&self) -> &'static str {
        if self.general.is_some() {
            "exact projection onto Z ∩ {l ≤ Gz ≤ u} (Goldfarb–Idnani with H = I)"
        } else {
            "exact projection onto a box"
        }
    }

    /// The largest violation by the iterate `z` (box, and the rows with the loaded bounds).
    pub(crate) fn violation(&self, p: Option<&ProjectionState>, z: &[f64]) -> f64 {
        match (&self.general, p) {
            (Some(g), Some(p)) => g.violation(&self.qp, p, z),
            _ => crate::general_projection::box_violation(&self.qp, z),
        }
    }

    /// The first n entries of a padded vector: the iterate a caller sees.
    #[inline]
    pub(crate) fn head<'a>(&self, v: &'a [f64]) -> &'a [f64] {
        &v[..self.qp.n()]
    }
}

/// Projected gradient method with a constant step.
#[derive(Debug, Clone)]
pub struct ProjectedGradient {
    g: GradientSetup,
    alpha: f64,
    cert: Certificate,
}

/// State of [`ProjectedGradient`]: the iterate (updated in place), the kernel's scratch
/// buffer (used only for n > 60) and the loaded linear term, padded to the kernels' length
/// (see [`crate::kernel::padded_len`]) in one allocation.
#[derive(Debug, Clone)]
pub struct PgState {
    /// [z, scratch, q].
    v: Vectors<3>,
    /// Workspace of the structured Hessian (empty for the dense kernel).
    work: Vec<f64>,
    /// The exact projection's workspace (general rows only).
    proj: Option<Box<ProjectionState>>,
}

impl PgState {
    /// The projection's workspace and statistics, with general rows.
    pub fn projection(&self) -> Option<&ProjectionState> {
        self.proj.as_deref()
    }
}

/// Indices into [`PgState`]'s vectors.
const Z: usize = 0;
const Q: usize = 2;

impl ProjectedGradient {
    /// Sets the method up for `qp` with the given step rule.
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use qp_iter::BoxSet;
    /// use qp_iter::{ParametricQp, IterationMap, run_fixed};
    /// use qp_iter::pg::{ProjectedGradient, StepRule};
    /// let qp = ParametricQp::new(mat![[2.0, 0.0], [0.0, 1.0]], vec![-2.0, -4.0],
    ///     Mat::zeros(2, 0), BoxSet::symmetric(&[2.0, 2.0]).unwrap()).unwrap();
    /// let pg = ProjectedGradient::new(qp, StepRule::Optimal).unwrap();
    /// let mut s = pg.new_state();
    /// run_fixed(&pg, &mut s, 200);
    /// let z = pg.iterate(&s);
    /// assert!((z[0] - 1.0).abs() < 1e-9 && (z[1] - 2.0).abs() < 1e-9); // z₁ clipped at 2
    /// assert!((pg.certificate().rate - 1.0 / 3.0).abs() < 1e-12);
    /// ```
    pub fn new(qp: ParametricQp, rule: StepRule) -> Result<Self> {
        let (mu, l) = (qp.mu(), qp.l());
        let alpha = match rule {
            StepRule::InverseL => 1.0 / l,
            StepRule::Optimal => 2.0 / (l + mu),
            StepRule::Fixed(a) => {
                <Self as crate::method::Family>::validate(&rule)?;
                a
            }
        };
        let rate = (1.0 - alpha * mu).abs().max((1.0 - alpha * l).abs());
        let g = GradientSetup::new(qp);
        let projection = g.projection_words();
        let cert = Certificate {
            rate,
            prefactor: 1.0,
            quantity: BoundedQuantity::IterateDistance,
            norm: CertNorm::Euclidean,
            fits_eq11: rate < 1.0,
            premise: format!(
                "H ≻ 0 (μ = {mu:.6e}, L = {l:.6e}), constant step α = {alpha:.6e} < 2/L; {projection}"
            ),
            source: "Nesterov (2018) Thm 2.1.15; contraction of z ↦ Π(z − α∇f(z)) for quadratics"
                .into(),
        };
        Ok(Self { g, alpha, cert })
    }

    /// The step α.
    pub fn alpha(&self) -> f64 {
        self.alpha
    }

    /// Like [`ProjectedGradient::new`], but always through the problem's structured Hessian
    /// when it has one, whatever n (to measure the crossover).
    pub fn new_structured(qp: ParametricQp, rule: StepRule) -> Result<Self> {
        let mut pg = Self::new(qp, rule)?;
        pg.g.force_structured();
        Ok(pg)
    }

    /// Whether the steps use the problem's structured Hessian (the problem has one and
    /// n ≥ its [`HessianOperator::dense_crossover`]) instead of the dense kernel.
    pub fn is_structured(&self) -> bool {
        self.g.op.is_some()
    }
}

impl IterationMap for ProjectedGradient {
    type State = PgState;

    fn name(&self) -> &'static str {
        "pg"
    }
    fn problem(&self) -> &ParametricQp {
        &self.g.qp
    }
    fn new_state(&self) -> PgState {
        let mut s = PgState {
            v: self.g.vectors(Q),
            work: self.g.op_work(),
            proj: self.g.projection_state(),
        };
        self.cold_start(&mut s);
        s
    }
    fn load(&self, state: &mut PgState, theta: &[f64]) {
        self.g.load(state.v.get_mut(Q), theta);
        if let (Some(p), Some(ps)) = (&self.g.general, &mut state.proj) {
            p.load(&self.g.qp, ps, theta);
        }
    }
    fn warm_start(&self, state: &mut PgState, z0: &[f64], _dual: Option<&[f64]>) {
        self.g.start(state.v.get_mut(Z), Some(z0));
    }
    fn cold_start(&self, state: &mut PgState) {
        self.g.start(state.v.get_mut(Z), None);
    }
    #[inline]
    fn step(&self, s: &mut PgState) {
        // Fused z⁺ = Π_Z(z − α(Hz + q)) in one pass over the padded H (NaN-preserving
        // clamp), in place: no copy, no allocation, nothing else in the state changes.
        let g = &self.g;
        let [z, scratch, q] = s.v.all_mut();
        if let (Some(p), Some(ps)) = (&g.general, &mut s.proj) {
            // General rows: the unclamped step, then the exact projection.
            g.kernel
                .pg_step_padded(&g.h, z, q, self.alpha, &p.free_lo, &p.free_hi, scratch);
            p.project(&g.qp, ps, &mut z[..g.qp.n()]);
            return;
        }
        match &g.op {
            // Hz through the problem's structure (O(M) for the MHE), then the same
            // update and NaN-preserving clamp as the kernel.
            Some(op) => {
                let n = g.qp.n();
                op.apply(&z[..n], &mut scratch[..n], &mut s.work);
                let a = self.alpha;
                for ((((z, hz), q), l), u) in z[..n]
                    .iter_mut()
                    .zip(&scratch[..n])
                    .zip(&q[..n])
                    .zip(&g.lower[..n])
                    .zip(&g.upper[..n])
                {
                    *z = clamp_nan_propagating(*z - a * (hz + q), *l, *u);
                }
            }
            None => g
                .kernel
                .pg_step_padded(&g.h, z, q, self.alpha, &g.lower, &g.upper, scratch),
        }
    }
    fn iterate<'s>(&self, state: &'s PgState) -> &'s [f64] {
        self.g.head(state.v.get(Z))
    }
    fn violation(&self, state: &PgState) -> f64 {
        self.g.violation(state.proj.as_deref(), self.iterate(state))
    }
    fn certificate(&self) -> &Certificate {
        &self.cert
    }
    fn set_kernel(&mut self, kernel: Kernel) {
        self.g.set_kernel(kernel);
    }
}

/// ξ = z: the start is the warm start, one step is the real step.
impl crate::linearise::Linearise for ProjectedGradient {
    fn lift_dim(&self) -> usize {
        self.problem().n()
    }
    fn start_probe(&self, st: &mut PgState, z0: &[f64], theta: &[f64], xi: &mut [f64]) {
        self.load(st, theta);
        self.warm_start(st, z0, None);
        xi.copy_from_slice(self.iterate(st));
    }
    fn step_probe(&self, st: &mut PgState, xi: &[f64], theta: &[f64], out: &mut [f64]) {
        self.load(st, theta);
        self.warm_start(st, xi, None);
        self.step(st);
        out.copy_from_slice(self.iterate(st));
    }
    fn readout(&self) -> faer::Mat<f64> {
        faer::Mat::identity(self.problem().n(), self.problem().n())
    }
}

/// `"pg"` (step 2/(L + μ)) or `{ method = "pg", step = α }`.
impl crate::method::Family for ProjectedGradient {
    type Params = StepRule;
    const NAME: &'static str = "pg";
    const PRESETS: &'static [(&'static str, StepRule)] = &[("pg", StepRule::Optimal)];
    const KEYS: &'static [&'static str] = &["step"];
    fn with_keys(base: StepRule, key: &dyn Fn(&str) -> Option<f64>) -> StepRule {
        key("step").map_or(base, StepRule::Fixed)
    }
    fn keys_of(p: &StepRule) -> Vec<(&'static str, f64)> {
        match p {
            StepRule::Fixed(a) => vec![("step", *a)],
            StepRule::Optimal | StepRule::InverseL => Vec::new(),
        }
    }
    fn describe(p: &StepRule) -> std::borrow::Cow<'static, str> {
        match p {
            StepRule::Optimal => "pg".into(),
            StepRule::InverseL => "pg(step=1/L)".into(),
            StepRule::Fixed(a) => format!("pg(step={})", crate::method::short(*a)).into(),
        }
    }
    fn validate(p: &StepRule) -> Result<()> {
        match p {
            StepRule::Fixed(a) if !(*a > 0.0 && a.is_finite()) => Err(QpError::Parameter {
                name: "step".into(),
                value: *a,
                reason: "the step must be positive and finite".into(),
            }),
            _ => Ok(()),
        }
    }
    fn build(p: &StepRule, qp: ParametricQp) -> Result<crate::MethodMap> {
        Ok(crate::MethodMap::Pg(ProjectedGradient::new(qp, *p)?))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::BoxSet;
    use crate::{RunStatus, run_fixed};
    use faer::mat;

    /// A NaN in θ must surface as `NonFinite` even on a bounded box, where a max/min clamp
    /// would silently turn it into a bound.
    #[test]
    fn nan_theta_on_a_bounded_box_is_reported() {
        let qp = ParametricQp::new(
            mat![[2.0, 0.5], [0.5, 1.0]],
            vec![0.0, 0.0],
            faer::Mat::identity(2, 2),
            BoxSet::symmetric(&[1.0, 1.0]).unwrap(),
        )
        .unwrap();
        let pg = ProjectedGradient::new(qp, StepRule::InverseL).unwrap();
        let mut s = pg.new_state();
        pg.load(&mut s, &[f64::NAN, 0.0]);
        assert_eq!(run_fixed(&pg, &mut s, 5).status, RunStatus::NonFinite);
    }
}
