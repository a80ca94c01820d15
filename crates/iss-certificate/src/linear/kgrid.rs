//! The K-step maps of one iteration map for every K of an ascending grid, sharing the work:
//! [`IterationLinearisation::k_step`] forms 𝕊^{K−k₀} of the augmented (n_ξ + n_θ) step matrix
//! by repeated squaring for each K separately; here the binary powers of the n_ξ × n_ξ block
//! are formed once and the grid is walked upwards.
//!
//! With [S | S_θ] the one-step map and Ξ the start map, after P = K − k₀ steps
//!
//! ξ_P = S^P Ξ (z⁰, θ) + Y_P θ,   Y_P = Σ_{i<P} S^i S_θ,
//!
//! so W_P = S^P Ξ + [0 | Y_P] gives zᴷ = R W_P (z⁰, θ). The affine steps compose as
//! (S^a, Y_a)∘(S^b, Y_b) = (S^{a+b}, Y_a + S^a Y_b), so with (S^{2^j}, Y_{2^j}) cached
//! (Y_{2^{j+1}} = Y_{2^j} + S^{2^j} Y_{2^j}) an advance by Δ costs one n_ξ² (n + n_θ) product
//! per set bit of Δ, and the squarings cost n_ξ³ each, once.

use faer::{Accum, Mat, Par, linalg::matmul::matmul};

use super::LinearError;
use super::iteration::{IterationLinearisation, KStepMap, all_finite, mul};

/// Calls `each` with the K-step map of `lin` for every K of `grid` in order (ascending, each
/// K ≥ max(1, k₀)); the maps equal [`IterationLinearisation::k_step`] up to rounding. One
/// map is alive at a time.
///
/// Errors: an empty grid, a K of 0 or below k₀, a grid not ascending
/// ([`LinearError::ZeroIterations`]); a non-finite map; the first error of `each`.
pub(crate) fn k_steps(
    lin: &IterationLinearisation,
    grid: &[usize],
    par: Par,
    mut each: impl FnMut(KStepMap) -> Result<(), LinearError>,
) -> Result<(), LinearError> {
    let k0 = lin.start_steps;
    if grid.is_empty()
        || grid.iter().any(|&k| k == 0 || k < k0)
        || grid.windows(2).any(|w| w[0] > w[1])
    {
        return Err(LinearError::ZeroIterations);
    }
    let (n, nt, nxi) = (lin.n, lin.n_theta, lin.lift_dim());
    let s = lin.step.as_ref().subcols(0, nxi);
    let s_theta = lin.step.as_ref().subcols(nxi, nt);
    // Binary powers (S^{2^j}, Y_{2^j}) up to the largest step needed.
    let top = grid[grid.len() - 1] - k0;
    let bits = (usize::BITS - top.leading_zeros()) as usize;
    let mut powers: Vec<(Mat<f64>, Mat<f64>)> = Vec::with_capacity(bits);
    if bits > 0 {
        powers.push((s.to_owned(), s_theta.to_owned()));
    }
    for j in 1..bits {
        let (sp, yp) = &powers[j - 1];
        let s2 = mul(sp.as_ref(), sp.as_ref(), par);
        let mut y2 = yp.clone();
        matmul(y2.as_mut(), Accum::Add, sp.as_ref(), yp.as_ref(), 1.0, par);
        powers.push((s2, y2));
    }
    let mut w = lin.start.clone(); // W_0 = Ξ
    let mut p = 0usize;
    for &k in grid {
        let delta = k - k0 - p;
        for (j, (sp, yp)) in powers.iter().enumerate() {
            if delta & (1 << j) != 0 {
                let mut next = mul(sp.as_ref(), w.as_ref(), par);
                let mut theta_cols = next.as_mut().subcols_mut(n, nt);
                theta_cols += yp.as_ref();
                w = next;
            }
        }
        p = k - k0;
        let z_k = mul(lin.readout.as_ref(), w.as_ref(), par);
        if !all_finite(z_k.as_ref()) {
            return Err(LinearError::NonFinite {
                what: "the K-step map",
                k,
            });
        }
        each(KStepMap {
            k,
            g: z_k.as_ref().subcols(0, n).to_owned(),
            j: z_k.as_ref().subcols(n, nt).to_owned(),
        })?;
    }
    Ok(())
}

/// `n` log-spaced integers from `from` to `to` (rounded, duplicates removed).
///
/// ```
/// use iss_certificate::linear::log_spaced;
/// assert_eq!(log_spaced(1, 1000, 4), vec![1, 10, 100, 1000]);
/// assert_eq!(log_spaced(1, 4, 10), vec![1, 2, 3, 4]); // rounding merges neighbours
/// assert_eq!(log_spaced(5, 5, 3), vec![5]);
/// ```
pub fn log_spaced(from: usize, to: usize, n: usize) -> Vec<usize> {
    if n <= 1 || from == to {
        return vec![from];
    }
    let (a, b) = ((from as f64).ln(), (to as f64).ln());
    let mut out: Vec<usize> = (0..n)
        .map(|i| {
            let v = (a + (b - a) * i as f64 / (n - 1) as f64).exp().round();
            // Clamp against rounding past the ends.
            (v as usize).clamp(from.min(to), from.max(to))
        })
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}
