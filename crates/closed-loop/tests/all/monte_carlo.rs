//! `closed_loop::monte_carlo::monte_carlo` with a factory that returns its own error type: the
//! error comes back as the factory gave it (no conversion to `ClosedLoopError`), and it is
//! the error of the lowest-numbered failing run whatever the thread count.

use closed_loop::monte_carlo::{MonteCarlo, monte_carlo, monte_carlo_seed};
use closed_loop::scenario::{LoopOptions, Scenario};
use closed_loop::sim::ClosedLoopError;

/// A user's own setup error: its own failure, or the library's.
#[derive(Debug, thiserror::Error)]
enum SetupError {
    #[error("no observer for seed {seed}")]
    NoObserver { seed: u64 },
    #[error(transparent)]
    Loop(#[from] ClosedLoopError),
}

const TEXT: &str = "name = \"mc\"\n[plant]\na = [[0.5]]\nb = [[1.0]]\nc = [[1.0]]\n\
    [sets]\ninput = { lower = -1, upper = 1 }\ndisturbance = { lower = -0.1, upper = 0.1 }\n\
    [simulation]\nx0 = [1.0]\nsteps = 10\n[mhe]\nhorizon = 3\neta = 0.8\niterations = 5\n\
    [mpc]\nhorizon = 5\n";

#[test]
fn factory_errors_keep_the_users_type_and_the_lowest_failing_run() {
    let resolved = Scenario::from_toml_str(TEXT).unwrap().resolve().unwrap();
    let sc = resolved.scenario();
    let settings = MonteCarlo::new(8, 3, (sc.sets.input.lower(), sc.sets.input.upper()))
        .with_bounded_factor(1e3);
    // Runs 2, 5 and 7 fail to build, with the user's own error.
    let failing = [2, 5, 7].map(|r| monte_carlo_seed(settings.base_seed, r));
    let make = |seed| -> Result<_, SetupError> {
        if failing.contains(&seed) {
            return Err(SetupError::NoObserver { seed });
        }
        let mut o = LoopOptions::from_scenario(sc)?;
        o.seed = seed;
        Ok(resolved.build_loop(&o)?)
    };
    for threads in [1, 2] {
        let err = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| monte_carlo(&settings, make))
            .unwrap_err();
        match err {
            SetupError::NoObserver { seed } => assert_eq!(seed, failing[0], "{threads} threads"),
            SetupError::Loop(e) => panic!("expected the user's error, got {e}"),
        }
    }
    // Without the failing seeds every run is built and run.
    let ok = monte_carlo(&settings, |seed| -> Result<_, SetupError> {
        let mut o = LoopOptions::from_scenario(sc)?;
        o.seed = seed;
        Ok(resolved.build_loop(&o)?)
    })
    .unwrap();
    assert!(ok.iter().all(|m| m.steps == 10 && m.error.is_empty()));
}
