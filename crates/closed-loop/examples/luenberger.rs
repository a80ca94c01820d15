//! A user's own estimator in the closed loop: a Luenberger observer (steady-state Kalman gain
//! from the dual DARE) written here, with its own error type, run against the sub-optimal
//! MHE at several K on the same disturbance draws, through the library's Monte-Carlo driver
//! ([`closed_loop::monte_carlo::monte_carlo`]: the sweep's seeds, metrics and bounded rule). The
//! factory that builds each run returns this file's own error type ([`SetupError`]): the
//! driver hands it back unchanged.
//!
//! ```text
//! cargo run --release -p closed-loop --example luenberger [-- SCENARIO.toml RUNS]
//! ```
//! (default `scenarios/case-study-certified.toml`, 20 runs).

use closed_loop::metrics::{DEFAULT_BOUNDED_FACTOR, Metric, RunMetrics};
use closed_loop::monte_carlo::{MonteCarlo, monte_carlo};
use closed_loop::scenario::{ControllerChoice, LoopOptions, Scenario, scenario_disturbance};
use closed_loop::sim::{ClosedLoop, ClosedLoopError};
use faer::Mat;
use lti_model::{LtiSystem, ModelError};
use mhe_core::Estimator;

/// The observer's own error: no gain for this plant, a measurement or input of the wrong
/// length, or a NaN.
#[derive(Debug, thiserror::Error)]
enum ObserverError {
    #[error("observer gain: the dual DARE has no stabilising solution: {0}")]
    Gain(#[source] ModelError),
    #[error("`{name}` has length {actual}, expected {expected}")]
    Length {
        name: &'static str,
        expected: usize,
        actual: usize,
    },
    #[error("`{name}` is not finite")]
    NonFinite { name: &'static str },
}

/// x̂_{t+1} = A x̂_t + B u_t + L(y_t − C x̂_t) (predictor form: x̂_t uses y up to t − 1, the
/// timing of Alg. 1) with L = K_dᵀ = A X Cᵀ(R + C X Cᵀ)⁻¹, K_d the LQR gain of the dual
/// pair (Aᵀ, Cᵀ): the steady-state Kalman predictor for Q = I, R = I, and A − LC is Schur.
#[derive(Debug)]
struct Luenberger {
    plant: LtiSystem,
    l: Mat<f64>,
    x_hat: Vec<f64>,
    next: Vec<f64>,
}

impl Luenberger {
    fn new(plant: &LtiSystem, prior: &[f64]) -> Result<Self, ObserverError> {
        let (nx, ny) = (plant.nx(), plant.ny());
        let at = plant.a().transpose().to_owned();
        let ct = plant.c().transpose().to_owned();
        let (kd, _) = lti_model::riccati::dlqr_gain(
            at.as_ref(),
            ct.as_ref(),
            Mat::<f64>::identity(nx, nx).as_ref(),
            Mat::<f64>::identity(ny, ny).as_ref(),
        )
        .map_err(ObserverError::Gain)?;
        let l = kd.transpose().to_owned();
        Ok(Self {
            plant: plant.clone(),
            l,
            x_hat: prior.to_vec(),
            next: vec![0.0; nx],
        })
    }
}

impl Estimator for Luenberger {
    type Error = ObserverError;
    fn estimate(&mut self) -> Result<&[f64], ObserverError> {
        Ok(&self.x_hat)
    }
    fn push(&mut self, u: &[f64], y: &[f64]) -> Result<(), ObserverError> {
        for (name, v, n) in [("u", u, self.plant.nu()), ("y", y, self.plant.ny())] {
            if v.len() != n {
                return Err(ObserverError::Length {
                    name,
                    expected: n,
                    actual: v.len(),
                });
            }
            if v.iter().any(|a| !a.is_finite()) {
                return Err(ObserverError::NonFinite { name });
            }
        }
        let (a, b, c) = (self.plant.a(), self.plant.b(), self.plant.c());
        let nx = self.x_hat.len();
        for i in 0..nx {
            let mut v = 0.0;
            for j in 0..nx {
                v += a[(i, j)] * self.x_hat[j];
            }
            for j in 0..u.len() {
                v += b[(i, j)] * u[j];
            }
            for k in 0..y.len() {
                let innovation = y[k] - (0..nx).map(|j| c[(k, j)] * self.x_hat[j]).sum::<f64>();
                v += self.l[(i, k)] * innovation;
            }
            self.next[i] = v;
        }
        std::mem::swap(&mut self.x_hat, &mut self.next);
        Ok(())
    }
    fn nx(&self) -> usize {
        self.plant.nx()
    }
}

/// Why one Monte-Carlo run could not be built: the observer, or the loop around it (the
/// factory's own error type; `monte_carlo` returns it unchanged).
#[derive(Debug, thiserror::Error)]
enum SetupError {
    #[error(transparent)]
    Observer(#[from] ObserverError),
    #[error(transparent)]
    Loop(#[from] ClosedLoopError),
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .map_or("scenarios/case-study-certified.toml", String::as_str);
    let runs: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(20);
    let resolved = Scenario::from_file(path)?.resolve()?;
    let sc = resolved.scenario();
    let base = LoopOptions::from_scenario(sc)?;
    // The library's Monte-Carlo driver: same seeds, metrics and bounded rule as `sweep`.
    let settings = MonteCarlo::new(
        runs,
        sc.noise.seed,
        (sc.sets.input.lower(), sc.sets.input.upper()),
    )
    .with_bounded_factor(DEFAULT_BOUNDED_FACTOR);
    println!("# {path}: {runs} runs per row (exact MPC, the same disturbance draws in every row)");
    println!(
        "{:<22} {:>9} {:>14} {:>14}",
        "estimator", "bounded", "tail ‖e‖ mean", "tail ‖e‖ max"
    );
    let report = |name: &str, metrics: &[RunMetrics]| {
        let tails: Vec<f64> = metrics
            .iter()
            .map(|m| m.get(Metric::TailMeanE).unwrap_or(f64::NAN))
            .collect();
        let bounded = metrics.iter().filter(|m| m.bounded).count();
        let mean = tails.iter().sum::<f64>() / tails.len() as f64;
        let max = tails.iter().copied().fold(0.0, f64::max);
        println!(
            "{name:<22} {:>9} {mean:>14.5} {max:>14.5}",
            format!("{bounded}/{}", metrics.len())
        );
    };
    // The user's observer, in the same loop type and driver as the built-in estimators.
    let observer = monte_carlo(&settings, |seed| -> Result<_, SetupError> {
        Ok(ClosedLoop::new(
            sc.plant.clone(),
            Luenberger::new(&sc.plant, &sc.simulation.prior)?,
            resolved.controller(ControllerChoice::ExactMpc)?,
            scenario_disturbance(sc, seed)?,
            &sc.simulation.x0,
            base.steps,
        )?)
    })?;
    report("luenberger", &observer);
    // The sub-optimal MHE at several K, same seeds.
    for k in [1, 5, 20, 100, base.iterations.get()] {
        let mhe = monte_carlo(&settings, |seed| {
            let mut o = base.with_iterations(k)?;
            o.seed = seed;
            resolved.build_loop(&o)
        })?;
        report(&format!("mhe {} K={k}", base.method), &mhe);
    }
    Ok(())
}
