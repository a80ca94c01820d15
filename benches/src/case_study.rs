//! The real case-study MHE QPs (from `mhe-core`), for the MHE benchmarks and the peer
//! export: window-M problems ℙ_t along a simulated closed-loop trajectory.
//!
//! A [`Preset`] names a scenario file (`scenarios/case-study.toml`, the paper's M = 5, or
//! `scenarios/case-study-certified.toml`, M = 9) and what it changes of it ([`M50`]: the
//! certified file with M = 50, T = 80; [`CART_PENDULUM`]: the cart-pendulum with the regional
//! budget, T = 40). [`CaseStudyQps::load`]
//!
//! 1. runs the scenario's closed loop ([`closed_loop::ResolvedScenario::build_loop`] with the file's
//!    solver, K, noise seed and T, exact MPC — or the preset's loop method at the K its
//!    certificate needs for [`EPS`]) and keeps its trace (u_t, y_t);
//! 2. replays (u_t, y_t) into an [`MheEstimator`] with the preset's replay map (V-FISTA,
//!    plain or Jacobi-scaled) at the K its certificate needs for relative accuracy [`EPS`]
//!    (P from LMI (2) via [`closed_loop::ResolvedScenario`]),
//!    and at every t with a full window (t ≥ M) records θ_t, the linear term q_t, the
//!    warm start z⁰_t the estimator starts from, and z*_t from the polished Clarabel
//!    reference ([`ReferenceSolver`]).
//!
//! For t ≥ M the window length is M, so every instance shares the QP data H, Z of
//! [`CaseStudyQps::qp`] and differs only in θ_t (hence q_t) and z⁰_t.

use std::path::PathBuf;

use closed_loop::scenario::{LoopOptions, ResolvedScenario, Scenario};
use closed_loop::{ClosedLoopError, Trace};
use lti_model::ModelError;
use mhe_core::{MheConfig, MheError, MheEstimator, MheProblem, MheSets};
use qp_iter::method::{Method, Scaling};
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};
use qp_iter::{IterationMap, ParametricQp, QpError};

/// Relative accuracy of the MHE benchmarks: ‖z − z*‖ ≤ EPS‖z⁰ − z*‖.
pub const EPS: f64 = 1e-6;

/// A case-study scenario file, its short name and what the preset changes of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Preset {
    /// Short name used in tables and file names (`"paper"`, `"certified"`, `"m50"`).
    pub name: &'static str,
    /// File name under `scenarios/`.
    pub file: &'static str,
    /// `mhe.horizon` replaced by this M (`None`: the file's).
    pub horizon: Option<usize>,
    /// `simulation.steps` replaced by this T (`None`: the file's).
    pub steps: Option<usize>,
    /// The closed loop's MHE runs this method at the K its certificate needs for [`EPS`]
    /// on the window-M QP (`None`: the file's method and K).
    pub loop_method: Option<Method>,
    /// The map whose estimator is replayed to record the warm starts z⁰_t, at the K its
    /// certificate needs for [`EPS`].
    pub replay: Method,
    /// The `mhe` bench searches K_reg (`iss_certificate::regional::k_reg`) on this preset:
    /// only where the file's `certificate.phase_seconds` lets the search reach it (it takes
    /// tens of seconds per method).
    pub k_reg: bool,
}

/// V-FISTA on the Jacobi-scaled problem (`"fista-jacobi"`).
const FISTA_JACOBI: Method = Method::FISTA.with_scaling(Scaling::Jacobi);

/// The paper's settings (M = 5) and the certified preset (M = 9, η = 0.8), as the files
/// have them (closed loop: PG at the file's K; replay: V-FISTA).
pub const PRESETS: [Preset; 2] = [
    Preset {
        name: "paper",
        file: "case-study.toml",
        horizon: None,
        steps: None,
        loop_method: None,
        replay: Method::FISTA,
        k_reg: false,
    },
    Preset {
        name: "certified",
        file: "case-study-certified.toml",
        horizon: None,
        steps: None,
        loop_method: None,
        replay: Method::FISTA,
        k_reg: false,
    },
];

/// The certified preset at M = 50 (η = 0.8: κ(H) ≈ 4.5·10⁵, the scale issue 12 is about),
/// T = 80 so that 31 instances have a full window. The closed loop runs ADMM α = 2 on the
/// Jacobi-scaled problem (`"admm-pr-jacobi"`) and the replay V-FISTA on it: the plain maps'
/// certificates need 10⁴–10⁶ iterations here.
pub const M50: Preset = Preset {
    name: "m50",
    file: "case-study-certified.toml",
    horizon: Some(50),
    steps: Some(80),
    loop_method: Some(Method::ADMM_PR.with_scaling(Scaling::Jacobi)),
    replay: FISTA_JACOBI,
    k_reg: false,
};

/// The cart-pendulum with the regional budget (`cart-pendulum-regional.toml`: M = 9,
/// n_x = 4, n_w = 6, 𝒰 = ℝ), the shipped scenario with a K_reg (FISTA-Jacobi 13 where
/// Theorem 1 needs 839), so the bench can time the MHE step at K_reg. T = 40 as in the
/// certified preset (32 instances). The file's loop, PG at K = 10, is uncertified (PG's
/// K_lin is 4423) and swings the pendulum to 0.87 rad by t = 40, so the loop and the replay
/// run FISTA-Jacobi at the K its certificate needs for [`EPS`].
pub const CART_PENDULUM: Preset = Preset {
    name: "cart-pendulum",
    file: "cart-pendulum-regional.toml",
    horizon: None,
    steps: Some(40),
    loop_method: Some(FISTA_JACOBI),
    replay: FISTA_JACOBI,
    k_reg: true,
};

/// The presets of the `mhe` bench and of `export_qps`: [`PRESETS`], [`M50`] and
/// [`CART_PENDULUM`].
pub const MHE_PRESETS: [Preset; 4] = [PRESETS[0], PRESETS[1], M50, CART_PENDULUM];

/// Why the case-study fixtures could not be built.
#[derive(Debug, thiserror::Error)]
pub enum FixtureError {
    /// The scenario file could not be read or is invalid.
    #[error("scenario `{path}`: {source}")]
    Scenario {
        /// The file.
        path: String,
        /// The parser's error.
        source: ModelError,
    },
    /// The scenario has no `[mhe]` section.
    #[error("scenario `{path}` has no [mhe] section; the MHE benchmarks need one")]
    NoMhe {
        /// The file.
        path: String,
    },
    /// The closed-loop run failed.
    #[error("case-study closed loop: {0}")]
    ClosedLoop(#[from] ClosedLoopError),
    /// Building or stepping the MHE failed.
    #[error("MHE: {0}")]
    Mhe(#[from] MheError),
    /// The QP layer (certificate, reference solve) failed.
    #[error("QP: {0}")]
    Qp(#[from] QpError),
    /// A certificate gives no finite K (rate ≥ 1).
    #[error("the {method} certificate gives no K for accuracy {eps:e} (rate ≥ 1)")]
    NoCertifiedK {
        /// Method name.
        method: &'static str,
        /// The accuracy asked for.
        eps: f64,
    },
    /// The trace is shorter than the window, so no instance has a full window.
    #[error("the run has {steps} steps, fewer than the window M = {m}; raise simulation.steps")]
    ShortRun {
        /// T.
        steps: usize,
        /// M.
        m: usize,
    },
}

/// One MHE problem ℙ_t with a full window.
#[derive(Debug, Clone)]
pub struct MheInstance {
    /// Time t (≥ M).
    pub t: usize,
    /// θ_t = (prior, u_{t−M..t−1}, y_{t−M..t−1}).
    pub theta: Vec<f64>,
    /// q_t = q₀ + F_cθ_t.
    pub q: Vec<f64>,
    /// The estimator's warm start z⁰_t.
    pub z0: Vec<f64>,
    /// z*_t from the polished Clarabel reference.
    pub z_star: Vec<f64>,
}

/// The case-study MHE QPs of one preset along one simulated trajectory.
#[derive(Debug)]
pub struct CaseStudyQps {
    /// The preset.
    pub preset: Preset,
    /// The parsed scenario, resolved (P from LMI (2), the MPC).
    pub resolved: ResolvedScenario,
    /// MHE settings (P from LMI (2)); `iterations` is the scenario's K.
    pub config: MheConfig,
    /// The MHE constraint sets.
    pub sets: MheSets,
    /// ℙ_t for every window length.
    pub problem: MheProblem,
    /// The window-M QP, shared by every instance (n = n_x + M·n_w variables).
    pub qp: ParametricQp,
    /// The closed-loop trace whose (u_t, y_t) feed the estimators.
    pub trace: Trace,
    /// The instances t = M, …, T.
    pub instances: Vec<MheInstance>,
}

/// `scenarios/<file>` of this workspace.
pub fn scenario_path(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("scenarios")
        .join(file)
}

impl CaseStudyQps {
    /// Runs the preset's closed loop and records its window-M instances (module docs).
    pub fn load(preset: Preset) -> Result<Self, FixtureError> {
        let path = scenario_path(preset.file);
        let shown = path.display().to_string();
        let mut scenario = Scenario::from_file(&path).map_err(|source| FixtureError::Scenario {
            path: shown.clone(),
            source,
        })?;
        match scenario.mhe.as_mut() {
            None => return Err(FixtureError::NoMhe { path: shown }),
            Some(mhe) => {
                if let Some(m) = preset.horizon {
                    *mhe = mhe.to_builder().horizon(m).build(&scenario.plant)?;
                }
            }
        }
        if let Some(t) = preset.steps {
            scenario.simulation.steps = t;
        }
        let resolved = scenario.resolve()?;
        let config = resolved.mhe_config()?.clone();
        let sets = resolved.mhe_sets().clone();
        let plant = &resolved.scenario().plant;
        let problem = MheProblem::new(plant, config.horizon, &config.weights(), &sets)?;
        let m = config.horizon;
        let qp = match problem.window(m) {
            Some(w) => w.qp().clone(),
            None => return Err(FixtureError::ShortRun { steps: 0, m }),
        };
        let mut options = LoopOptions::from_scenario(resolved.scenario())?;
        if let Some(method) = preset.loop_method {
            options.method = method;
            options = options.with_iterations(certified_k(&method.build(qp.clone())?)?)?;
        }
        let trace = resolved.build_loop(&options)?.run()?.clone();
        let mut qps = Self {
            preset,
            resolved,
            config,
            sets,
            problem,
            qp: qp.clone(),
            trace,
            instances: Vec::new(),
        };
        if qps.trace.len() < m {
            return Err(FixtureError::ShortRun {
                steps: qps.trace.len(),
                m,
            });
        }
        let k = certified_k(&preset.replay.build(qp.clone())?)?;
        let mut est = qps.estimator(k, |qp| preset.replay.build(qp))?;
        let mut reference = ReferenceSolver::new(&qp, ReferenceSettings::default())?;
        for t in 0..=qps.trace.len() {
            est.estimate()?;
            if t >= m {
                let theta = est.theta().to_vec();
                let mut q = vec![0.0; qp.n()];
                qp.linear_term(&theta, &mut q);
                let z_star = reference.solve(&theta)?.z;
                qps.instances.push(MheInstance {
                    t,
                    theta,
                    q,
                    z0: est.warm_start_point().to_vec(),
                    z_star,
                });
            }
            if t < qps.trace.len() {
                qps.push(&mut est, t)?;
            }
        }
        Ok(qps)
    }

    /// Window length M.
    pub fn horizon(&self) -> usize {
        self.config.horizon
    }

    /// An MHE estimator for this preset with map `factory` and K = `iterations`, at t = 0.
    pub fn estimator<M, F>(
        &self,
        iterations: usize,
        factory: F,
    ) -> Result<MheEstimator<M>, FixtureError>
    where
        M: IterationMap,
        F: Fn(ParametricQp) -> qp_iter::Result<M>,
    {
        let mut cfg = self.config.clone();
        cfg.iterations =
            qp_iter::Iterations::new(iterations).map_err(|_| MheError::OutOfRange {
                name: "iterations",
                value: iterations as f64,
                range: "integers 1 ..= 10⁷ (qp_iter::MAX_ITERATIONS)",
            })?;
        Ok(MheEstimator::new(
            &self.resolved.scenario().plant,
            &self.sets,
            &cfg,
            &self.resolved.scenario().simulation.prior,
            factory,
        )?)
    }

    /// Feeds (u_t, y_t) of the trace into `est` (estimate first if needed, then push).
    pub fn push<M: IterationMap>(
        &self,
        est: &mut MheEstimator<M>,
        t: usize,
    ) -> Result<(), FixtureError> {
        match (self.trace.u(t), self.trace.y(t)) {
            (Some(u), Some(y)) => Ok(est.push(u, y)?),
            _ => Err(FixtureError::ShortRun {
                steps: self.trace.len(),
                m: t + 1,
            }),
        }
    }

    /// An estimator with K = `iterations` replayed to t = T (the last step, full window):
    /// `estimate()` then solves the last instance and is idempotent, so it can be timed.
    pub fn estimator_at_end<M, F>(
        &self,
        iterations: usize,
        factory: F,
    ) -> Result<MheEstimator<M>, FixtureError>
    where
        M: IterationMap,
        F: Fn(ParametricQp) -> qp_iter::Result<M>,
    {
        let mut est = self.estimator(iterations, factory)?;
        for t in 0..self.trace.len() {
            self.push(&mut est, t)?;
        }
        Ok(est)
    }
}

/// The K a map's certificate needs for φ(K) ≤ [`EPS`].
pub fn certified_k<M: IterationMap>(map: &M) -> Result<usize, FixtureError> {
    map.certificate()
        .min_iterations(EPS)
        .ok_or(FixtureError::NoCertifiedK {
            method: map.name(),
            eps: EPS,
        })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// ‖z − Π_Z(z − (Hz + q))‖_∞, computed here from H row-major (independent of Clarabel).
    fn natural_residual(qp: &ParametricQp, q: &[f64], z: &[f64]) -> f64 {
        let n = qp.n();
        let h = qp.h_row_major();
        let (lo, up) = (qp.zset().lower(), qp.zset().upper());
        (0..n)
            .map(|i| {
                let g = (0..n).map(|j| h[i * n + j] * z[j]).sum::<f64>() + q[i];
                (z[i] - (z[i] - g).max(lo[i]).min(up[i])).abs()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn paper_preset_instances_are_the_replayed_window_qps() {
        let qps = CaseStudyQps::load(PRESETS[0]).unwrap();
        let m = qps.horizon();
        let (nx, nu, ny, nw) = qps.trace.dims();
        assert_eq!((m, qps.qp.n()), (5, nx + m * nw));
        assert_eq!(qps.instances.len(), qps.trace.len() - m + 1);
        for inst in &qps.instances {
            // θ_t holds u_{t−M..t−1} and y_{t−M..t−1} of the closed-loop trace.
            for j in 0..m {
                let (uo, yo) = (nx + j * nu, nx + m * nu + j * ny);
                let step = inst.t - m + j;
                assert_eq!(&inst.theta[uo..uo + nu], qps.trace.u(step).unwrap());
                assert_eq!(&inst.theta[yo..yo + ny], qps.trace.y(step).unwrap());
            }
            let mut q = vec![0.0; qps.qp.n()];
            qps.qp.linear_term(&inst.theta, &mut q);
            assert_eq!(q, inst.q);
            // z* is optimal (KKT through the natural residual), z⁰ is not.
            let scale = 1.0 + inst.q.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(natural_residual(&qps.qp, &inst.q, &inst.z_star) <= 1e-9 * scale);
            assert!(natural_residual(&qps.qp, &inst.q, &inst.z0) > 1e-6);
        }
    }

    /// The M = 50 preset: the certified file's plant at M = 50, T = 80, every instance a
    /// full window with an optimal z* (the peers' and our accuracy yardstick).
    #[test]
    fn m50_preset_has_full_windows_with_optimal_references() {
        let qps = CaseStudyQps::load(M50).unwrap();
        let (nx, _, _, nw) = qps.trace.dims();
        assert_eq!((qps.horizon(), qps.qp.n()), (50, nx + 50 * nw));
        assert_eq!((qps.trace.len(), qps.instances.len()), (80, 31));
        for inst in &qps.instances {
            let scale = 1.0 + inst.q.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(natural_residual(&qps.qp, &inst.q, &inst.z_star) <= 1e-9 * scale);
        }
    }

    /// The cart-pendulum preset: n_w = 6 (four process, two measurement components), so
    /// n = 4 + 9·6 = 58; T = 40 gives 32 full windows, each with an optimal z*.
    #[test]
    fn cart_pendulum_preset_has_full_windows_with_optimal_references() {
        let qps = CaseStudyQps::load(CART_PENDULUM).unwrap();
        let (nx, _, _, nw) = qps.trace.dims();
        assert_eq!((nx, nw, qps.horizon(), qps.qp.n()), (4, 6, 9, 58));
        assert_eq!((qps.trace.len(), qps.instances.len()), (40, 32));
        for inst in &qps.instances {
            let scale = 1.0 + inst.q.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(natural_residual(&qps.qp, &inst.q, &inst.z_star) <= 1e-9 * scale);
        }
    }
}
