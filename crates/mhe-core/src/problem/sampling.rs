//! The sampled L_Φ of each window (a lower estimate beside the certified bound; trap 8).

use super::*;

/// Settings of the sampled L_Φ estimate ([`MheWindow::sample_lipschitz`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LipschitzSampling {
    /// Number of random pairs (θa, θb).
    pub pairs: usize,
    /// Seed of the ChaCha8 generator.
    pub seed: u64,
    /// θa is uniform in [−R, R]^{n_θ}.
    pub theta_radius: f64,
    /// θb = θa + δ with δ uniform in [−r, r]^{n_θ} (small r probes the local slope).
    pub perturbation: f64,
}

impl Default for LipschitzSampling {
    fn default() -> Self {
        Self {
            pairs: 200,
            seed: 0,
            theta_radius: 10.0,
            perturbation: 1.0,
        }
    }
}

/// Sampled and certified L_Φ of one window, side by side (trap 8).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct LipschitzEstimate {
    /// Window length m.
    pub window: usize,
    /// max ‖z*(θa) − z*(θb)‖/‖θa − θb‖ over the pairs (a lower bound on the true constant).
    pub sampled: f64,
    /// The certified bound ‖H_c^{-1/2}F_c‖₂/√λ_min(H_c).
    pub certified: f64,
    /// ‖H_c⁻¹F_c‖₂ (exact when no bound is active).
    pub unconstrained: f64,
    /// Pairs used.
    pub pairs: usize,
}

impl MheWindow {
    /// Sampled L_Φ: max ‖z*(θa) − z*(θb)‖₂/‖θa − θb‖₂ over seeded random pairs, z* exact
    /// (the primal active-set solver of `qp_iter::active_set`, every answer KKT-checked,
    /// warm-started from the previous solve — θb from θa's active set — with Clarabel as its
    /// fallback). Reported next to the certified bound.
    pub fn sample_lipschitz(&self, s: &LipschitzSampling) -> Result<LipschitzEstimate> {
        use rand::{Rng, SeedableRng};
        if !(s.theta_radius >= 0.0 && s.theta_radius.is_finite()) {
            return Err(MheError::OutOfRange {
                name: "theta_radius",
                value: s.theta_radius,
                range: "[0, ∞)",
            });
        }
        if !(s.perturbation > 0.0 && s.perturbation.is_finite()) {
            return Err(MheError::OutOfRange {
                name: "perturbation",
                value: s.perturbation,
                range: "(0, ∞)",
            });
        }
        let mut solver = qp_iter::active_set::ExactSolver::new(&self.qp)?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed);
        let nth = self.layout.n_theta();
        let mut best = 0.0_f64;
        let mut ta = vec![0.0; nth];
        let mut tb = vec![0.0; nth];
        let mut za = vec![0.0; self.qp.n()];
        for _ in 0..s.pairs {
            for i in 0..nth {
                ta[i] = s.theta_radius * (2.0 * rng.random::<f64>() - 1.0);
                tb[i] = ta[i] + s.perturbation * (2.0 * rng.random::<f64>() - 1.0);
            }
            // With bounded 𝒳 / 𝒴 a random θ can make ℙ_t infeasible: such pairs are skipped.
            match solver.solve(&ta) {
                Ok(z) => za.copy_from_slice(z),
                Err(qp_iter::QpError::Infeasible { .. }) => continue,
                Err(e) => return Err(e.into()),
            }
            let zb = match solver.solve(&tb) {
                Ok(z) => z,
                Err(qp_iter::QpError::Infeasible { .. }) => continue,
                Err(e) => return Err(e.into()),
            };
            let dz = za
                .iter()
                .zip(zb)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            let dt = ta
                .iter()
                .zip(&tb)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            if dt > 0.0 {
                best = best.max(dz / dt);
            }
        }
        Ok(LipschitzEstimate {
            window: self.layout.m,
            sampled: best,
            certified: self.lipschitz_certified,
            unconstrained: self.lipschitz_unconstrained,
            pairs: s.pairs,
        })
    }
}

impl MheProblem {
    /// [`MheWindow::sample_lipschitz`] for every window length m = 0..M.
    pub fn sample_lipschitz(&self, s: &LipschitzSampling) -> Result<Vec<LipschitzEstimate>> {
        self.windows.iter().map(|w| w.sample_lipschitz(s)).collect()
    }
}
