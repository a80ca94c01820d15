//! γ₁,₃ of Assumption 4: the gain from estimation error e to state x of the closed loop
//! x⁺ = Ax + Bπ(x + e) + w¹ under the box-constrained condensed MPC π.
//!
//! ## Sufficient method (certified): contraction over all free sets
//! π(x) = E₀Π^H_{𝒰^N}(−H⁻¹Fx) is continuous and piecewise affine; on the region where exactly
//! the inputs in 𝔽 are free it is affine with Jacobian K_𝔽 (see
//! [`mpc_core::CondensedMpc::for_each_free_set`]). Along any segment, then,
//! π(x) − π(x') = K̄(x − x') with K̄ a convex combination of the K_𝔽. For a metric S ≻ 0 let
//!
//! - λ_S = max_𝔽 ‖A + BK_𝔽‖_S (‖M‖_S = ‖S^{1/2}MS^{−1/2}‖₂), and
//! - g_S = max_𝔽 ‖S^{1/2}BK_𝔽‖₂.
//!
//! Operator norms are convex, so ‖A + BK̄‖_S ≤ λ_S and ‖S^{1/2}BK̄‖₂ ≤ g_S. With
//! f(x) = Ax + Bπ(x), f(0) = 0 (0 ∈ int 𝒰, so π(0) = 0):
//!
//! x⁺ = f(x) + B(π(x + e) − π(x)) + w¹ ⇒ ‖x⁺‖_S ≤ λ_S‖x‖_S + g_S‖e‖ + √λ̄(S)‖w¹‖.
//!
//! If λ_S < 1, iterating gives Assumption 4 with linear gains
//! β₁(s, g) = √(λ̄(S)/λ(S))·λ_S^g·s, **γ₁,₃ = g_S / (√λ(S)(1 − λ_S))**,
//! γ₁ʷ = √(λ̄(S)/λ(S))/(1 − λ_S). This is an incremental (contraction) argument in the spirit of
//! Lohmiller & Slotine, "On contraction analysis for non-linear systems", Automatica 34(6),
//! 1998, specialised to piecewise-affine laws through the convex hull of their local gains.
//! The enumeration visits 2^{N·n_u} free sets (all of them, realisable or not, which keeps the
//! bound sound); for N·n_u beyond `max_vars` the method is not applied and the user must supply
//! γ₁,₃.
//!
//! The enumeration runs in fixed mask chunks on the rayon pool (deterministic reduction).
//! A metric is dropped once its contraction factor reaches 1 (it can no longer certify).
//!
//! Candidate metrics: I, the DARE terminal weight P_f (the LQR value function), and the
//! Lyapunov solution of A (if A is Schur). The smallest certified γ₁,₃ wins.
//!
//! ## Sampled lower estimate
//! With x₀ = 0 and w = 0, Assumption 4 reads ‖x_t‖ ≤ γ₁,₃·sup‖e‖, so for any injected error
//! sequence, sup_t‖x_t‖ / sup_t‖e_t‖ is a lower bound on every valid linear γ₁,₃.
//! [`gamma13_sampled`] takes the maximum over seeded sequences (constant, random, and
//! sign-alternating along random directions, at several magnitudes), so the conservatism of the
//! certified figure is visible.

use faer::{Mat, MatRef, Side};
use lti_model::matrix::sym_lambda_max_in_place;
use mpc_core::{CondensedMpc, Controller, MpcError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

/// One candidate metric S and its contraction figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MetricResult {
    /// Which S (`"identity"`, `"dare-terminal"`, `"open-loop-lyapunov"`).
    pub metric: String,
    /// λ_S = max_𝔽 ‖A + BK_𝔽‖_S.
    pub contraction: f64,
    /// g_S = max_𝔽 ‖S^{1/2}BK_𝔽‖₂.
    pub input_gain: f64,
    /// √(λ̄(S)/λ(S)): prefactor of β₁.
    pub condition_sqrt: f64,
    /// γ₁,₃ = g_S/(√λ(S)(1 − λ_S)), or ∞ when λ_S ≥ 1.
    pub gamma13: f64,
    /// γ₁ʷ = √(λ̄(S)/λ(S))/(1 − λ_S), or ∞ when λ_S ≥ 1.
    pub gamma1w: f64,
}

/// Result of [`gamma13_certified`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Gamma13Certificate {
    /// Best (smallest) certified γ₁,₃ over the candidate metrics; ∞ when none contracts.
    pub gamma13: f64,
    /// The metric that achieved it (None when none contracts).
    pub metric: Option<String>,
    /// Every candidate's figures.
    pub candidates: Vec<MetricResult>,
    /// Number of free sets enumerated (2^{N·n_u}).
    pub free_sets: u64,
    /// Whether the enumeration ran (false when N·n_u > `max_vars`).
    pub enumerated: bool,
}

struct Metric {
    name: &'static str,
    half: Mat<f64>,
    neg_half: Mat<f64>,
    lmin: f64,
    lmax: f64,
}

fn metric(name: &'static str, s: MatRef<'_, f64>) -> Option<Metric> {
    let evd = lti_model::matrix::symmetrize(s)
        .self_adjoint_eigen(Side::Lower)
        .ok()?;
    let (u, d) = (evd.U(), evd.S().column_vector());
    let n = s.nrows();
    let lmin = (0..n).map(|i| d[i]).fold(f64::INFINITY, f64::min);
    let lmax = (0..n).map(|i| d[i]).fold(0.0, f64::max);
    if !(lmin > 0.0) || !lmax.is_finite() {
        return None;
    }
    let build = |p: f64| {
        Mat::from_fn(n, n, |i, j| {
            (0..n).map(|k| u[(i, k)] * d[k].powf(p) * u[(j, k)]).sum()
        })
    };
    Some(Metric {
        name,
        half: build(0.5),
        neg_half: build(-0.5),
        lmin,
        lmax,
    })
}

/// Per mask chunk: (enumerated, masks visited, max λ per metric, max g per metric).
type ChunkMax = (bool, u64, Vec<f64>, Vec<f64>);

/// Frobenius norm: an upper bound on the spectral norm. The exact norm can only raise a
/// running maximum when the Frobenius norm exceeds it, so most masks skip the eigenproblem
/// and the enumerated maxima are unchanged.
fn frobenius(m: &[f64]) -> f64 {
    m.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// ‖M‖₂ of a small square row-major matrix via λ_max(MᵀM), with scratch `g` (n²).
fn norm2(m: &[f64], n: usize, g: &mut [f64]) -> f64 {
    for i in 0..n {
        for j in 0..n {
            g[i * n + j] = (0..n).map(|k| m[k * n + i] * m[k * n + j]).sum();
        }
    }
    sym_lambda_max_in_place(g, n).max(0.0).sqrt()
}

/// Certified γ₁,₃ by contraction over all free sets (module doc). `max_vars` caps N·n_u
/// (at most 30; 2^{N·n_u} small solves).
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{BoxSet, LtiSystem};
/// use mpc_core::{CondensedMpc, MpcConfig};
/// let sys = LtiSystem::new(mat![[0.9, 0.1], [0.0, 0.8]], mat![[0.0], [0.1]], mat![[1.0, 0.0]]).unwrap();
/// let mpc = CondensedMpc::new(&sys, MpcConfig::new(4, Mat::identity(2, 2), mat![[0.1]],
///     BoxSet::symmetric(&[1.0]).unwrap())).unwrap();
/// let c = closed_loop::gamma13::gamma13_certified(&mpc, 20).unwrap();
/// assert!(c.enumerated && c.gamma13.is_finite());
/// ```
pub fn gamma13_certified(
    mpc: &CondensedMpc,
    max_vars: usize,
) -> Result<Gamma13Certificate, MpcError> {
    let sys = mpc.system();
    let (nx, nu) = (mpc.nx(), mpc.nu());
    let mut metrics: Vec<Metric> = Vec::new();
    metrics.extend(metric("identity", Mat::<f64>::identity(nx, nx).as_ref()));
    metrics.extend(metric("dare-terminal", mpc.terminal_weight().as_ref()));
    if let Ok(s) = lti_model::riccati::dlyap(sys.a(), Mat::<f64>::identity(nx, nx).as_ref()) {
        metrics.extend(metric("open-loop-lyapunov", s.as_ref()));
    }
    let a: Vec<f64> = (0..nx * nx).map(|k| sys.a()[(k / nx, k % nx)]).collect();
    let b: Vec<f64> = (0..nx * nu).map(|k| sys.b()[(k / nu, k % nu)]).collect();
    let halves: Vec<(Vec<f64>, Vec<f64>)> = metrics
        .iter()
        .map(|m| {
            let h = (0..nx * nx).map(|k| m.half[(k / nx, k % nx)]).collect();
            let nh = (0..nx * nx).map(|k| m.neg_half[(k / nx, k % nx)]).collect();
            (h, nh)
        })
        .collect();
    // Split the 2^{N·n_u} masks into fixed chunks (independent of the thread count) and
    // reduce chunk maxima in chunk order: the result is the same on any number of threads.
    let total = mpc.free_set_count();
    let chunks: u64 = 64;
    let step = total.div_ceil(chunks).max(1);
    let ranges: Vec<std::ops::Range<u64>> = (0..chunks)
        .map(|c| (c * step).min(total)..((c + 1) * step).min(total))
        .filter(|r| !r.is_empty())
        .collect();
    let n_metrics = metrics.len();
    let per_chunk: Vec<Result<ChunkMax, MpcError>> = ranges
        .into_par_iter()
        .map(|range| {
            let mut lam = vec![0.0_f64; n_metrics];
            let mut gin = vec![0.0_f64; n_metrics];
            let (mut bk, mut j, mut t1, mut t2, mut g) = (
                vec![0.0; nx * nx],
                vec![0.0; nx * nx],
                vec![0.0; nx * nx],
                vec![0.0; nx * nx],
                vec![0.0; nx * nx],
            );
            let mut count = 0u64;
            let mul = |x: &[f64], y: &[f64], out: &mut [f64]| {
                for i in 0..nx {
                    for c in 0..nx {
                        out[i * nx + c] = (0..nx).map(|k| x[i * nx + k] * y[k * nx + c]).sum();
                    }
                }
            };
            let ran = mpc.for_each_free_set_in(max_vars, range, |_, kf, _| {
                count += 1;
                for i in 0..nx {
                    for c in 0..nx {
                        let v: f64 = (0..nu).map(|p| b[i * nu + p] * kf[p * nx + c]).sum();
                        bk[i * nx + c] = v;
                        j[i * nx + c] = a[i * nx + c] + v;
                    }
                }
                for (mi, (h, nh)) in halves.iter().enumerate() {
                    // A metric whose contraction factor already reached 1 can never certify:
                    // stop spending time on it (its reported λ_S is then a lower bound ≥ 1).
                    if lam[mi] >= 1.0 {
                        continue;
                    }
                    mul(h, &j, &mut t1);
                    mul(&t1, nh, &mut t2);
                    if frobenius(&t2) > lam[mi] {
                        lam[mi] = lam[mi].max(norm2(&t2, nx, &mut g));
                    }
                    mul(h, &bk, &mut t1);
                    if frobenius(&t1) > gin[mi] {
                        gin[mi] = gin[mi].max(norm2(&t1, nx, &mut g));
                    }
                }
            })?;
            Ok((ran, count, lam, gin))
        })
        .collect();
    let mut lam = vec![0.0_f64; n_metrics];
    let mut gin = vec![0.0_f64; n_metrics];
    let mut count = 0u64;
    let mut enumerated = true;
    for r in per_chunk {
        let (ran, c, l, g) = r?;
        enumerated &= ran;
        count += c;
        for i in 0..n_metrics {
            lam[i] = lam[i].max(l[i]);
            gin[i] = gin[i].max(g[i]);
        }
    }
    let candidates: Vec<MetricResult> = metrics
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let contracts = enumerated && lam[i] < 1.0;
            let cond = (m.lmax / m.lmin).sqrt();
            MetricResult {
                metric: m.name.to_string(),
                contraction: if enumerated { lam[i] } else { f64::NAN },
                input_gain: if enumerated { gin[i] } else { f64::NAN },
                condition_sqrt: cond,
                gamma13: if contracts {
                    gin[i] / (m.lmin.sqrt() * (1.0 - lam[i]))
                } else {
                    f64::INFINITY
                },
                gamma1w: if contracts {
                    cond / (1.0 - lam[i])
                } else {
                    f64::INFINITY
                },
            }
        })
        .collect();
    let best = candidates
        .iter()
        .filter(|c| c.gamma13.is_finite())
        .min_by(|x, y| x.gamma13.total_cmp(&y.gamma13));
    Ok(Gamma13Certificate {
        gamma13: best.map_or(f64::INFINITY, |c| c.gamma13),
        metric: best.map(|c| c.metric.clone()),
        candidates,
        free_sets: count,
        enumerated,
    })
}

/// Result of [`gamma13_sampled`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Gamma13Sampled {
    /// max over sequences of sup‖x_t‖/sup‖e_t‖ (a lower bound on any valid linear γ₁,₃).
    pub gamma13_lower: f64,
    /// Number of injected sequences.
    pub sequences: usize,
    /// Steps per sequence.
    pub steps: usize,
    /// Seed.
    pub seed: u64,
}

/// Sampled lower estimate of γ₁,₃: simulates x⁺ = Ax + Bπ(x + e_t) from x₀ = 0 with w = 0 and
/// injected error sequences of magnitudes in `magnitudes` (module doc).
pub fn gamma13_sampled<C: Controller<Error = MpcError> + ?Sized>(
    controller: &mut C,
    sys: &lti_model::LtiSystem,
    magnitudes: &[f64],
    sequences_per_magnitude: usize,
    steps: usize,
    seed: u64,
) -> Result<Gamma13Sampled, MpcError> {
    let (nx, nu) = (sys.nx(), sys.nu());
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut x, mut xn, mut xe, mut u, mut y) = (
        vec![0.0; nx],
        vec![0.0; nx],
        vec![0.0; nx],
        vec![0.0; nu],
        vec![0.0; sys.ny()],
    );
    let w = vec![0.0; sys.nw()];
    let mut dir = vec![0.0; nx];
    let mut best = 0.0_f64;
    let mut count = 0;
    for &mag in magnitudes {
        for s in 0..sequences_per_magnitude {
            let kind = s % 3; // 0: constant, 1: i.i.d. random, 2: sign-alternating
            let unit = |d: &mut [f64], rng: &mut ChaCha8Rng| {
                for v in d.iter_mut() {
                    *v = rng.random_range(-1.0..1.0);
                }
                let nrm = d.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
                d.iter_mut().for_each(|v| *v *= mag / nrm);
            };
            unit(&mut dir, &mut rng);
            x.fill(0.0);
            let mut sup_x = 0.0_f64;
            for t in 0..steps {
                if kind == 1 {
                    unit(&mut dir, &mut rng);
                }
                let sign = if kind == 2 && t % 2 == 1 { -1.0 } else { 1.0 };
                for i in 0..nx {
                    xe[i] = x[i] + sign * dir[i];
                }
                controller.control(&xe, &mut u)?;
                sys.step(&x, &u, &w, &mut xn, &mut y);
                std::mem::swap(&mut x, &mut xn);
                sup_x = sup_x.max(x.iter().map(|v| v * v).sum::<f64>().sqrt());
            }
            best = best.max(sup_x / mag);
            count += 1;
        }
    }
    Ok(Gamma13Sampled {
        gamma13_lower: best,
        sequences: count,
        steps,
        seed,
    })
}
