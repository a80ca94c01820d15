//! A structured Hessian: H·z without the dense H, for problems whose H has a cheap
//! product (the MHE's through its dynamics: a forward pass and an adjoint pass,
//! O(M·(n_x² + n_x n_w + n_x n_y)) instead of O(n²) with n = n_x + M n_w).
//!
//! A [`ParametricQp`](crate::ParametricQp) can carry one
//! ([`ParametricQp::with_operator`](crate::ParametricQp::with_operator)); projected gradient
//! and FISTA use it instead of the dense kernel when n ≥ its
//! [`HessianOperator::dense_crossover`] (measured per implementation, `docs/benchmarks.md`;
//! [`STRUCTURED_MIN_N`] for an operator that reports none). Everything else (μ, L, the certificates, the exact
//! solvers, ADMM's (H + ρI)⁻¹) still uses the dense H, which the operator must equal:
//! `apply` is a different way to compute the same product, checked against it in the tests
//! of every operator.

use std::fmt::Debug;

/// Default [`HessianOperator::dense_crossover`]: the smallest n at which projected gradient
/// and FISTA use an operator that reports no crossover of its own instead of the dense
/// kernel (the MHE's run-time-size product, the slowest measured, still ≤ 1.7× the dense
/// kernel at 200: `docs/benchmarks.md`, "Structured iteration").
pub const STRUCTURED_MIN_N: usize = 200;

/// z ↦ H z computed without the dense H.
pub trait HessianOperator: Send + Sync + Debug {
    /// n: the length of z.
    fn n(&self) -> usize;
    /// Length of the workspace `apply` needs.
    fn work_len(&self) -> usize;
    /// out = H z, using `work` (length [`HessianOperator::work_len`]) as scratch; must not
    /// allocate.
    fn apply(&self, z: &[f64], out: &mut [f64], work: &mut [f64]);
    /// Smallest n from which this product is faster than the dense kernel's (projected
    /// gradient and FISTA use it from there).
    fn dense_crossover(&self) -> usize {
        STRUCTURED_MIN_N
    }
    /// Length of the workspace [`HessianOperator::apply_scaled`] needs.
    fn scaled_work_len(&self) -> usize {
        self.work_len() + self.n()
    }
    /// out = D H D y for D = diag(d) (the Jacobi-scaled problem), using `work` (length
    /// [`HessianOperator::scaled_work_len`]); must not allocate. The default scales y into
    /// the workspace, applies H and scales the result; an operator may fold D into its
    /// own passes.
    /// The same operator with its arithmetic on `kernel`'s path (with or without fused
    /// multiply–adds), so that [`crate::IterationMap::set_kernel`] reaches the structured
    /// product too; `None` for an operator with a single path (the default).
    fn on_kernel(
        &self,
        _kernel: crate::kernel::Kernel,
    ) -> Option<std::sync::Arc<dyn HessianOperator>> {
        None
    }
    fn apply_scaled(&self, d: &[f64], y: &[f64], out: &mut [f64], work: &mut [f64]) {
        let (dy, rest) = work.split_at_mut(d.len());
        for ((o, y), d) in dy.iter_mut().zip(y).zip(d) {
            *o = d * y;
        }
        self.apply(dy, out, rest);
        for (o, d) in out.iter_mut().zip(d) {
            *o *= d;
        }
    }
}

/// D·H·D for a diagonal D, from an operator for H (what a scaled problem carries).
#[derive(Debug, Clone)]
pub struct DiagonalScaled<O> {
    /// The operator for H.
    pub inner: O,
    /// The diagonal of D.
    pub d: Vec<f64>,
}

impl<O: HessianOperator> HessianOperator for DiagonalScaled<O> {
    fn n(&self) -> usize {
        self.d.len()
    }
    fn work_len(&self) -> usize {
        self.inner.scaled_work_len()
    }
    fn apply(&self, y: &[f64], out: &mut [f64], work: &mut [f64]) {
        self.inner.apply_scaled(&self.d, y, out, work);
    }
    fn dense_crossover(&self) -> usize {
        self.inner.dense_crossover()
    }
    fn on_kernel(
        &self,
        kernel: crate::kernel::Kernel,
    ) -> Option<std::sync::Arc<dyn HessianOperator>> {
        let inner = self.inner.on_kernel(kernel)?;
        Some(std::sync::Arc::new(DiagonalScaled {
            inner,
            d: self.d.clone(),
        }))
    }
}

impl HessianOperator for std::sync::Arc<dyn HessianOperator> {
    fn n(&self) -> usize {
        (**self).n()
    }
    fn work_len(&self) -> usize {
        (**self).work_len()
    }
    fn apply(&self, z: &[f64], out: &mut [f64], work: &mut [f64]) {
        (**self).apply(z, out, work);
    }
    fn dense_crossover(&self) -> usize {
        (**self).dense_crossover()
    }
    fn scaled_work_len(&self) -> usize {
        (**self).scaled_work_len()
    }
    fn apply_scaled(&self, d: &[f64], y: &[f64], out: &mut [f64], work: &mut [f64]) {
        (**self).apply_scaled(d, y, out, work);
    }
    fn on_kernel(
        &self,
        kernel: crate::kernel::Kernel,
    ) -> Option<std::sync::Arc<dyn HessianOperator>> {
        (**self).on_kernel(kernel)
    }
}
