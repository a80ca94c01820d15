//! The joint trajectory checks over many seeds at one certified pair.

#[cfg(feature = "serde")]
use serde::Serialize;

use super::certify::{JointCertificate, delta_series};
use super::region::RegionPoint;
use super::trajectory::check_joint_trajectory;
use crate::certificate::ClosedLoopCertificate;
use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario};
use closed_loop::sim::ClosedLoopError;

/// Worst lhs/rhs of every inequality over the seeds, and the seeds where one failed.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct SeedChecks {
    /// The pair simulated.
    pub pair: RegionPoint,
    /// Seeds run.
    pub seeds: u64,
    /// Seeds on which an inequality failed (or ε_t was missing).
    pub failed: Vec<u64>,
    /// Worst lhs/rhs over seeds and t: plant, Prop. 1, Prop. 3, δ step, δ, ‖u − π(x̂)‖/δ.
    pub worst: [f64; 6],
    /// Largest replay mismatch of δ_t (0: the replay reproduced every applied input).
    pub replay_mismatch: f64,
}

/// Simulates the scenario at `pair` (MHE `j.mhe_method` with K_e, MPC `j.mpc_method` with
/// K_c, the default warm start, the exact MHE solve on) for seeds 0..`seeds` and evaluates
/// [`check_joint_trajectory`] on each run.
///
/// Errors: the loop cannot be built or a run stops (a diverged run is an error here: at a
/// certified pair it would contradict the certificate).
pub fn check_on_seeds(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    j: &JointCertificate,
    pair: RegionPoint,
    seeds: u64,
) -> Result<SeedChecks, ClosedLoopError> {
    let mpc = resolved.mpc()?;
    let base = LoopOptions::from_scenario(resolved.scenario())?;
    let mut out = SeedChecks {
        pair,
        seeds,
        failed: Vec::new(),
        worst: [0.0; 6],
        replay_mismatch: 0.0,
    };
    for seed in 0..seeds {
        let opts = LoopOptions {
            method: j.mhe_method,
            exact_mhe_solve: true,
            controller: ControllerChoice::suboptimal(pair.k_c, j.mpc_method)?,
            seed,
            ..base.with_iterations(pair.k_e)?
        };
        let mut lp = resolved.build_loop(&opts)?;
        let trace = lp.run()?;
        let d = delta_series(
            mpc,
            j.mpc_method,
            pair.k_c,
            mpc_core::WarmStart::default(),
            trace,
        )?;
        out.replay_mismatch = out.replay_mismatch.max(d.replay_mismatch);
        let Some(ch) = check_joint_trajectory(
            cert,
            &j.analysis,
            pair.k_e,
            pair.k_c,
            trace,
            &d.delta,
            &d.input_error,
            j.plant_beta,
            j.gamma1w,
        ) else {
            out.failed.push(seed);
            continue;
        };
        if !ch.holds() {
            out.failed.push(seed);
        }
        for (w, c) in out.worst.iter_mut().zip([
            &ch.plant,
            &ch.prop1,
            &ch.prop3,
            &ch.delta_step,
            &ch.delta,
            &ch.input_error,
        ]) {
            *w = w.max(c.worst_ratio);
        }
    }
    Ok(out)
}
