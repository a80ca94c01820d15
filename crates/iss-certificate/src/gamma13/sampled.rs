//! Sampled lower estimate of γ₁,₃.
//!
//! With x₀ = 0 and w = 0, Assumption 4 reads ‖x_t‖ ≤ γ₁,₃·sup‖e‖, so for any injected error
//! sequence, sup_t‖x_t‖ / sup_t‖e_t‖ is a lower bound on every valid linear γ₁,₃.
//! [`gamma13_sampled`] takes the maximum over seeded sequences (constant, random, and
//! sign-alternating along random directions, at several magnitudes), so the conservatism of the
//! certified figure is visible.

use mpc_core::{Controller, MpcError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
#[cfg(feature = "serde")]
use serde::Serialize;

/// Result of [`gamma13_sampled`].
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
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
