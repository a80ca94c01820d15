//! How much work a simulation is, the limit on it, and progress while it runs.
//!
//! One simulation runs T steps of Alg. 1; each step runs K iterations of Φ on the MHE QP in
//! the condensed variables z = (x̂_{t−M}, ŵ_{t−M}, …, ŵ_{t−1}), n_z = n_x + M·(n_w1 + n_w2),
//! and one iteration costs O(n_z²) (a dense n_z × n_z product). The estimate T·K·n_z²
//! (multiply-adds) is what the report logs before each simulation and what
//! [`MAX_SIMULATION_WORK`] bounds (docs/limits.md).

use closed_loop::scenario::Scenario;
use iss_certificate::plan::KSource;
use lti_model::numfmt::sig4;
use qp_iter::Method;

/// Largest estimated work T·K·n_z² (multiply-adds) of one simulation. At the ~3·10⁹
/// multiply-adds per second one core sustains on these iterations, this is about an hour:
/// legal, and shown with progress.
pub const MAX_SIMULATION_WORK: f64 = 1e13;

/// Largest number of iterations T·K of one simulation, whatever n_z: on a tiny QP the cost of
/// an iteration is its fixed overhead, not n_z² (10¹⁰ iterations are minutes to an hour).
/// `mhe.iterations` and `simulation.steps` at their maxima (10⁷ × 10⁵ = 10¹²) exceed it.
pub const MAX_SIMULATION_ITERATIONS: f64 = 1e10;

/// The work of one simulation: T steps × K iterations on the n_z-dimensional MHE QP.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Work {
    /// K.
    pub k: usize,
    /// T.
    pub steps: usize,
    /// n_z at a full window.
    pub n_z: usize,
}

impl Work {
    /// The work of a simulation of `scenario` at `k` iterations (None without `[mhe]`).
    pub fn of(scenario: &Scenario, k: usize) -> Option<Self> {
        let m = scenario.mhe.as_ref()?.horizon();
        let p = &scenario.plant;
        Some(Self {
            k,
            steps: scenario.simulation.steps,
            n_z: p.nx() + m * p.nw(),
        })
    }

    /// T·K.
    pub fn iterations(&self) -> f64 {
        self.k as f64 * self.steps as f64
    }

    /// T·K·n_z², the estimate that is limited.
    pub fn multiply_adds(&self) -> f64 {
        self.iterations() * (self.n_z as f64).powi(2)
    }

    /// Within [`MAX_SIMULATION_WORK`] and [`MAX_SIMULATION_ITERATIONS`].
    pub fn within_limit(&self) -> bool {
        self.multiply_adds() <= MAX_SIMULATION_WORK
            && self.iterations() <= MAX_SIMULATION_ITERATIONS
    }

    /// What is simulated and how much work it is (printed before the simulation).
    pub fn line(&self, solver: Method, source: KSource) -> String {
        let why = source.reason();
        format!(
            "simulating {} at K = {} ({why}): {} steps × {} iterations, n_z = {}, ≈ {} \
             iterations of O(n_z²) (≈ {} multiply-adds)",
            solver.name().to_uppercase(),
            self.k,
            self.steps,
            self.k,
            self.n_z,
            sig4(self.iterations()),
            sig4(self.multiply_adds()),
        )
    }

    /// How far beyond the limits (for the messages): `"≈ 1e12 iterations, above the limit
    /// 1e10"` or the same in multiply-adds.
    pub fn excess(&self) -> String {
        if self.iterations() > MAX_SIMULATION_ITERATIONS {
            format!(
                "T·K = {} iterations, above the limit {} of one simulation",
                sig4(self.iterations()),
                sig4(MAX_SIMULATION_ITERATIONS)
            )
        } else {
            format!(
                "T·K·n_z² ≈ {} multiply-adds (n_z = {}), above the limit {} of one simulation",
                sig4(self.multiply_adds()),
                self.n_z,
                sig4(MAX_SIMULATION_WORK)
            )
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    fn cart_pendulum() -> Scenario {
        Scenario::from_file(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../scenarios/cart-pendulum.toml"),
        )
        .unwrap()
    }

    /// The work line of the example: PG at K_min on the cart-pendulum.
    #[test]
    fn work_line_names_steps_iterations_and_n_z() {
        let w = Work::of(&cart_pendulum(), 139_380).unwrap();
        assert_eq!((w.steps, w.n_z), (150, 58)); // n_z = 4 + 9·(4 + 2)
        assert_eq!(w.iterations(), 20_907_000.0);
        assert!(w.within_limit());
        assert_eq!(
            w.line(Method::PG, KSource::ComputedKMin),
            "simulating PG at K = 139380 (the computed K_min): 150 steps × 139380 iterations, \
             n_z = 58, ≈ 2.091e7 iterations of O(n_z²) (≈ 7.033e10 multiply-adds)"
        );
    }

    /// Both keys at their maxima: 10¹² iterations, beyond the limit for any plant.
    #[test]
    fn the_largest_keys_exceed_the_work_limit() {
        let mut s = cart_pendulum();
        s.simulation.steps = lti_model::spec::plant::MAX_STEPS;
        let w = Work::of(&s, mhe_core::settings::MAX_ITERATIONS).unwrap();
        assert_eq!(w.iterations(), 1e12);
        assert!(!w.within_limit());
        assert_eq!(
            w.excess(),
            "T·K = 1e12 iterations, above the limit 1e10 of one simulation"
        );
        // The smallest plant (n_z = 3: n_x = n_y = 1, M = 1) too.
        let tiny = Work { n_z: 3, ..w };
        assert!(!tiny.within_limit());
        // A large QP is limited by its multiply-adds.
        let big = Work {
            k: 100_000,
            steps: 10_000,
            n_z: 200,
        };
        assert!(!big.within_limit());
        assert!(big.excess().contains("n_z = 200"), "{}", big.excess());
    }
}
