//! The lifted linear form of an iteration map: what a method tells the linear analysis
//! (ρ_lin(K), K_lin in `closed-loop`) about itself.
//!
//! Away from the bounds of its box Z every method of this crate is an *affine* recursion on
//! a method-specific iteration state ξ driven by θ (through q = q₀ + Fθ):
//!
//! | method | ξ | n_ξ | start (load θ, warm start z⁰, no dual) | one step | iterate |
//! | --- | --- | --- | --- | --- | --- |
//! | PG | z | n | ξ = z⁰ | z⁺ = z − α(Hz + q) | z |
//! | FISTA | (x, y) | 2n | one PG step with 1/L: x₀ = y₀ = T(z⁰) | x⁺ = T(y), y⁺ = x⁺ + β(x⁺ − x) | x |
//! | ADMM | s = v + y/ρ | n | s⁰ = z⁰ − (Hz⁰ + q)/ρ | s⁺ = s + α(z⁺ − s), z⁺ = (H + ρI)⁻¹(ρs − q) | v = s |
//!
//! Each method implements [`Linearise`] in its own file by driving its *real* `load`,
//! `warm_start` and `step` on a probe, so the linearisation follows the code that runs;
//! [`crate::MethodMap`] dispatches to the concrete method (`method.rs`).

use faer::Mat;

use crate::IterationMap;

/// The real map driven on one probe: what the linear analysis needs from a method.
///
/// ```
/// use faer::mat;
/// use qp_iter::BoxSet;
/// use qp_iter::{Linearise, Method, ParametricQp};
/// let qp = ParametricQp::new(mat![[2.0, 0.0], [0.0, 1.0]], vec![0.0; 2],
///     faer::Mat::zeros(2, 0), BoxSet::symmetric(&[1.0, 1.0]).unwrap()).unwrap();
/// let fista = Method::FISTA.build(qp).unwrap();
/// assert_eq!(fista.lift_dim(), 4); // ξ = (x, y)
/// assert_eq!(fista.start_steps(), 1); // the restart step
/// ```
pub trait Linearise: IterationMap {
    /// n_ξ: the dimension of the iteration state inside one time step.
    fn lift_dim(&self) -> usize;
    /// k₀: steps already taken by [`Linearise::start_probe`] (FISTA's restart step).
    fn start_steps(&self) -> usize {
        0
    }
    /// ξ after `load(θ)`, `warm_start(z⁰, None)` and k₀ steps, written to `xi`.
    fn start_probe(&self, st: &mut Self::State, z0: &[f64], theta: &[f64], xi: &mut [f64]);
    /// ξ⁺ after one step from ξ with θ loaded, written to `out`; leaves the map's iterate
    /// (the point checked against the bounds) in `st`.
    fn step_probe(&self, st: &mut Self::State, xi: &[f64], theta: &[f64], out: &mut [f64]);
    /// The iterate as a linear function of ξ: R (n × n_ξ).
    fn readout(&self) -> Mat<f64>;
}

/// R = [I_n 0] (n × n_ξ): the iterate is the first n entries of ξ.
pub(crate) fn leading_identity(n: usize, n_xi: usize) -> Mat<f64> {
    Mat::from_fn(n, n_xi, |i, j| if i == j { 1.0 } else { 0.0 })
}
