//! The linear part of one iteration map Φ where no bound of Z is active, and the K-step map
//! z⁰ ↦ zᴷ of one MHE (or MPC) time step built from it.
//!
//! Every method of `qp-iter` is, away from the bounds of its box Z, an *affine* recursion on
//! a method-specific iteration state ξ driven by θ (through q = q₀ + Fθ):
//!
//! | method | ξ | n_ξ | start (load θ, warm start z⁰, no dual) | one step | iterate |
//! | --- | --- | --- | --- | --- | --- |
//! | PG | z | n | ξ = z⁰ | z⁺ = z − α(Hz + q) | z |
//! | FISTA | (x, y) | 2n | one PG step with 1/L: x₀ = y₀ = T(z⁰) | x⁺ = T(y), y⁺ = x⁺ + β(x⁺ − x) | x |
//! | ADMM | s = v + y/ρ | n | s⁰ = z⁰ − (Hz⁰ + q)/ρ | s⁺ = s + α(z⁺ − s), z⁺ = (H + ρI)⁻¹(ρs − q) | v = s |
//!
//! (T(y) = y − (Hy + q)/L; with Z inactive Π_Z is the identity, so v = Π_Z(s) = s and
//! t = 2Π_Z(s) − s = s.) The momentum, the dual and the split variable are *not* carried
//! from one time step to the next: the MHE (and the sub-optimal MPC) warm-start every time
//! step from a primal point without a dual, which resets them
//! ([`qp_iter::IterationMap::warm_start`]). So the time-step map is zᴷ = G_K z⁰ + J_K θ,
//! and ξ lives only inside one time step.
//!
//! **How the columns are obtained.** [`linearise`] applies the *real* map — `load`,
//! `warm_start`, `step`, `iterate` of the object the simulation runs — to unit
//! perturbations h·e_i of (ξ, θ) around the origin, and divides the response by h. The
//! response is exact (not a finite difference of a non-linear function): the map is affine
//! wherever the projection is inactive, and every probe checks that the iterate lies
//! strictly inside Z (otherwise [`LinearError::ProbeActive`]). One coefficient cannot be
//! reached through the trait (FISTA's state (x, y) cannot be set with x ≠ y): FISTA's
//! momentum β is read from [`Fista::momentum`], while its T is probed from the real restart
//! step. The tests compare the resulting K-step map with brute force (K real
//! steps of `run_fixed` per unit probe) and PG with the closed form z⁺ = z − α(Hz + Fθ).
//!
//! **K-step map.** With the augmented one-step matrix 𝕊 = [[S, S_θ], [0, I]] acting on
//! (ξ, θ), the K-step map is R·[𝕊^{K−k₀}]·Ξ with the start map Ξ (which already contains
//! k₀ steps: 1 for FISTA, 0 otherwise), computed by repeated squaring in O(n³ log K).

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
pub use qp_iter::Linearise;
use qp_iter::ParametricQp;

use super::LinearError;

/// Probe scale relative to the smallest finite bound magnitude of Z (a power of two, so the
/// division by h is exact).
const PROBE_SCALE: f64 = 1.0 / 1_048_576.0;

/// The affine pieces of one iteration map in the region where no bound of Z is active
/// (constant terms, which do not affect stability, dropped).
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct IterationLinearisation {
    /// n: length of z.
    pub n: usize,
    /// n_θ: length of θ.
    pub n_theta: usize,
    /// k₀: steps contained in [`IterationLinearisation::start`].
    pub start_steps: usize,
    /// Ξ = [Ξ_z | Ξ_θ] (n_ξ × (n + n_θ)): ξ after the warm start from z⁰ with θ loaded and k₀ steps.
    pub start: Mat<f64>,
    /// [S | S_θ] (n_ξ × (n_ξ + n_θ)): ξ⁺ = Sξ + S_θθ.
    pub step: Mat<f64>,
    /// R (n × n_ξ): the iterate z = Rξ.
    pub readout: Mat<f64>,
}

/// The time-step map zᴷ = G z⁰ + J θ of K iterations from a warm start (no constant term).
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct KStepMap {
    /// K.
    pub k: usize,
    /// G = ∂zᴷ/∂z⁰ (n × n).
    pub g: Mat<f64>,
    /// J = ∂zᴷ/∂θ (n × n_θ).
    pub j: Mat<f64>,
}

/// Checks that 0 is an interior point of Z and returns the probe scale h.
fn probe_scale(qp: &ParametricQp, problem: &'static str) -> Result<f64, LinearError> {
    let (lo, up) = (qp.zset().lower(), qp.zset().upper());
    let mut smallest = 1.0_f64;
    for (index, (&l, &u)) in lo.iter().zip(up).enumerate() {
        if !(l < 0.0 && u > 0.0) {
            return Err(LinearError::OriginNotInterior {
                problem,
                index,
                lower: l,
                upper: u,
            });
        }
        smallest = smallest.min(-l).min(u);
    }
    Ok(smallest * PROBE_SCALE)
}

/// Errors if `z` touches or leaves Z (the probe left the region where the map is affine).
fn check_interior(qp: &ParametricQp, z: &[f64], problem: &'static str) -> Result<(), LinearError> {
    let (lo, up) = (qp.zset().lower(), qp.zset().upper());
    match (0..z.len()).find(|&i| !(z[i] > lo[i] && z[i] < up[i])) {
        None => Ok(()),
        Some(index) => Err(LinearError::ProbeActive { problem, index }),
    }
}

/// The linear part of `map` where Z is inactive, from probes of the real map (see the
/// module docs). `problem` names the QP in errors (`"MHE"`, `"MPC"`).
///
/// Errors: 0 not interior to Z ([`LinearError::OriginNotInterior`]); a probe reaching a
/// bound ([`LinearError::ProbeActive`]); a non-finite response ([`LinearError::NonFinite`]).
pub fn linearise<M: Linearise>(
    map: &M,
    problem: &'static str,
) -> Result<IterationLinearisation, LinearError> {
    let qp = map.problem();
    let (n, nt, nxi) = (qp.n(), qp.n_theta(), map.lift_dim());
    let h = probe_scale(qp, problem)?;
    let mut st = map.new_state();
    let mut z0 = vec![0.0; n];
    let mut theta = vec![0.0; nt];
    let mut xi = vec![0.0; nxi];
    let mut base = vec![0.0; nxi];

    // Start map Ξ: columns for z⁰ then θ.
    let mut start = Mat::<f64>::zeros(nxi, n + nt);
    map.start_probe(&mut st, &z0, &theta, &mut base);
    check_interior(qp, map.iterate(&st), problem)?;
    for c in 0..n + nt {
        if c < n {
            z0[c] = h;
        } else {
            theta[c - n] = h;
        }
        map.start_probe(&mut st, &z0, &theta, &mut xi);
        check_interior(qp, map.iterate(&st), problem)?;
        for r in 0..nxi {
            start[(r, c)] = (xi[r] - base[r]) / h;
        }
        if c < n {
            z0[c] = 0.0;
        } else {
            theta[c - n] = 0.0;
        }
    }

    // One step [S | S_θ]: columns for ξ then θ.
    let mut step = Mat::<f64>::zeros(nxi, nxi + nt);
    let mut xi_in = vec![0.0; nxi];
    map.step_probe(&mut st, &xi_in, &theta, &mut base);
    check_interior(qp, map.iterate(&st), problem)?;
    for c in 0..nxi + nt {
        if c < nxi {
            xi_in[c] = h;
        } else {
            theta[c - nxi] = h;
        }
        map.step_probe(&mut st, &xi_in, &theta, &mut xi);
        check_interior(qp, map.iterate(&st), problem)?;
        for r in 0..nxi {
            step[(r, c)] = (xi[r] - base[r]) / h;
        }
        if c < nxi {
            xi_in[c] = 0.0;
        } else {
            theta[c - nxi] = 0.0;
        }
    }
    let lin = IterationLinearisation {
        n,
        n_theta: nt,
        start_steps: map.start_steps(),
        start,
        step,
        readout: map.readout(),
    };
    if !all_finite(lin.start.as_ref()) || !all_finite(lin.step.as_ref()) {
        return Err(LinearError::NonFinite {
            what: "the probed iteration map",
            k: 0,
        });
    }
    Ok(lin)
}

pub(crate) fn all_finite(m: MatRef<'_, f64>) -> bool {
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_finite()))
}

/// a · b with explicit parallelism.
pub(crate) fn mul(a: MatRef<'_, f64>, b: MatRef<'_, f64>, par: Par) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(a.nrows(), b.ncols());
    matmul(out.as_mut(), Accum::Replace, a, b, 1.0, par);
    out
}

/// mᵖ by repeated squaring (p ≥ 0).
pub(crate) fn matrix_power(m: MatRef<'_, f64>, mut p: usize, par: Par) -> Mat<f64> {
    let n = m.nrows();
    let mut result = Mat::<f64>::identity(n, n);
    let mut base = m.to_owned();
    let mut first = true;
    while p > 0 {
        if p & 1 == 1 {
            result = if first {
                base.clone()
            } else {
                mul(result.as_ref(), base.as_ref(), par)
            };
            first = false;
        }
        p >>= 1;
        if p > 0 {
            base = mul(base.as_ref(), base.as_ref(), par);
        }
    }
    result
}

impl IterationLinearisation {
    /// n_ξ.
    pub fn lift_dim(&self) -> usize {
        self.step.nrows()
    }

    /// The augmented one-step matrix 𝕊 = [[S, S_θ], [0, I]] on (ξ, θ).
    pub fn augmented_step(&self) -> Mat<f64> {
        let (nxi, nt) = (self.lift_dim(), self.n_theta);
        Mat::from_fn(nxi + nt, nxi + nt, |i, j| {
            if i < nxi {
                self.step[(i, j)]
            } else if i == j {
                1.0
            } else {
                0.0
            }
        })
    }

    /// The time-step map of K ≥ k₀ iterations (K ≥ 1): zᴷ = R 𝕊^{K−k₀} [Ξ; 0 I] (z⁰, θ),
    /// 𝕊^{K−k₀} by repeated squaring.
    ///
    /// Errors: K = 0 or K < k₀ ([`LinearError::ZeroIterations`]), a non-finite result.
    pub fn k_step(&self, k: usize, par: Par) -> Result<KStepMap, LinearError> {
        if k == 0 || k < self.start_steps {
            return Err(LinearError::ZeroIterations);
        }
        let (n, nt, nxi) = (self.n, self.n_theta, self.lift_dim());
        let power = matrix_power(self.augmented_step().as_ref(), k - self.start_steps, par);
        // [Ξ_z, Ξ_θ; 0, I] on (z⁰, θ).
        let start_aug = Mat::from_fn(nxi + nt, n + nt, |i, j| {
            if i < nxi {
                self.start[(i, j)]
            } else if j == n + (i - nxi) {
                1.0
            } else {
                0.0
            }
        });
        let xi_k = mul(power.as_ref(), start_aug.as_ref(), par);
        let z_k = mul(self.readout.as_ref(), xi_k.as_ref().subrows(0, nxi), par);
        if !all_finite(z_k.as_ref()) {
            return Err(LinearError::NonFinite {
                what: "the K-step map",
                k,
            });
        }
        Ok(KStepMap {
            k,
            g: z_k.as_ref().subcols(0, n).to_owned(),
            j: z_k.as_ref().subcols(n, nt).to_owned(),
        })
    }
}
