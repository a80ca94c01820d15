//! closed-loop integration tests (one binary).
#![allow(clippy::unwrap_used)]

mod monte_carlo;
mod scenario;
mod scenario_errors;
mod scenario_fuzz;
mod sim;
mod sim_errors;
mod sim_trace;

use closed_loop::scenario::{LoopOptions, Scenario, ScenarioLoop};
use closed_loop::sim::ClosedLoopError;

/// Resolves `s` and builds its loop (tests that vary the scenario between builds).
pub fn build(s: &Scenario, o: &LoopOptions) -> Result<ScenarioLoop, ClosedLoopError> {
    s.clone().resolve()?.build_loop(o)
}
