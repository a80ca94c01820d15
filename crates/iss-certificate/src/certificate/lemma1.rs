//! Lemma 1 for the growing windows (t ≤ M) without the paper's σ_t (issue 27, mend (a)).
//!
//! While the window grows, the warm start pads the previous solution with a zero stage
//! (Σ_{t−1} = blkdiag(I, 0), ‖Σ_{t−1}‖ = 1), and the paper bounds ‖Σ_{t−1}z*_{t−1} − z*_t‖ by
//! L_Φσ_t with a constant σ_t built from ‖H_t‖, ‖A‖, ‖B‖, ‖C‖. That constant does not scale
//! with the data: on the stand-in, window 0 → 1 with the data ×10, the left side is 16.3 and
//! L_Φσ₁ = 14.4 (test `lemma1_growing_window_bound_scales_with_the_data`). The sound bound:
//! the QP has no constant linear term (q₀ = 0), so z*_m(θ) = Π^{H}_Z(−H⁻¹F_cθ) and
//!
//!   ‖Σ_{t−1}z*_{t−1} − z*_t‖ ≤ ‖z*_{t−1}‖ + ‖z*_t‖ ≤ L_Φ(‖θ_{t−1}‖ + ‖θ_t‖) + o_{t−1} + o_t,
//!
//! with o_m ≥ ‖z*_m(0)‖ the offset of window length m: 0 when 0 ∈ Z (the usual case), else
//! √κ(H)‖Π_Z(0)‖ (the H-projection of 0 onto the box is no longer in the H-norm than the
//! Euclidean clip of 0, which lies in the box). So Prop. 1's Case 1 reads
//! ‖ε_t‖ ≤ φ‖ε_{t−1}‖ + φL_Φσ_t with the data-dependent
//!
//!   σ_t := ‖θ_{t−1}‖ + ‖θ_t‖ + (o_{t−1} + o_t)/L_Φ  (t ≤ M; 0 for t > M),
//!
//! and every σ-gain of Props. 1 and 3 is unchanged. σ_t is a finite-support input (it is
//! nonzero on t ≤ M only), bounded by the first M steps' data.

use mhe_core::MheWindow;

use closed_loop::record::Trace;

/// o_m ≥ ‖z*_m(0)‖ for one window: 0 when 0 lies in the box Z and in every general row at
/// θ = 0; √κ(H)‖clip(0, Z)‖ for a box that excludes 0; +∞ when a general row excludes 0
/// (no bound is derived then).
pub fn origin_offset(window: &MheWindow) -> f64 {
    let qp = window.qp();
    if let Some(g) = qp.general() {
        let theta = vec![0.0; qp.n_theta()];
        let (mut lo, mut hi) = (vec![0.0; g.m()], vec![0.0; g.m()]);
        g.bounds(&theta, &mut lo, &mut hi);
        if lo.iter().zip(&hi).any(|(l, h)| *l > 0.0 || *h < 0.0) {
            return f64::INFINITY;
        }
    }
    let z = qp.zset();
    let clip2: f64 = z
        .lower()
        .iter()
        .zip(z.upper())
        .map(|(l, u)| 0f64.clamp(*l, *u).powi(2))
        .sum();
    if clip2 == 0.0 {
        0.0
    } else {
        qp.kappa().sqrt() * clip2.sqrt()
    }
}

/// ‖θ_t‖ = ‖(prior, u window, y window)‖₂ of step t of a trace recorded with the MHE's window
/// data (None when the trace has none).
pub fn theta_norm(trace: &Trace, t: usize) -> Option<f64> {
    let s = trace.mhe_step(t)?;
    let sq = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>();
    Some((sq(s.prior()) + sq(s.u_flat()) + sq(s.y_flat())).sqrt())
}

/// σ_t of the mended Lemma 1 at step t ≥ 1 (module doc): ‖θ_{t−1}‖ + ‖θ_t‖ + (o_{t−1} + o_t)/L_Φ
/// while the window grows (window(t) > window(t−1)), else 0. `offsets[m]` is o_m, `l_phi` the
/// L_Φ used (≥ 1). None when the trace has no window data at t or t − 1.
pub fn sigma(trace: &Trace, t: usize, offsets: &[f64], l_phi: f64) -> Option<f64> {
    if t == 0 {
        return Some(0.0);
    }
    let (a, b) = (trace.mhe_step(t - 1)?, trace.mhe_step(t)?);
    if b.window() <= a.window() {
        return Some(0.0);
    }
    let off = |m: usize| offsets.get(m).copied().unwrap_or(f64::INFINITY);
    Some(
        theta_norm(trace, t - 1)?
            + theta_norm(trace, t)?
            + (off(a.window()) + off(b.window())) / l_phi,
    )
}
