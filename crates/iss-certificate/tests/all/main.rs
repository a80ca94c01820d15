//! iss-certificate integration tests (one binary).
#![allow(clippy::unwrap_used)]

mod analysis;
mod asymptotic;
mod budget;
mod certificate;
mod chain;
mod comparison;
mod constrained;
mod coverage;
#[path = "../f32_seeds/data.rs"]
mod f32_data;
mod findings;
mod fista_rounding;
mod gamma13;
mod global_outcome;
mod global_precision;
mod joint;
mod krylov;
mod linear;
mod lure;
mod mends;
mod model;
mod plants;
mod plants_ii;
mod precision;
mod regional;
mod regional_search;
mod rounding_adversary;
mod users;

use closed_loop::scenario::{LoopOptions, Scenario, ScenarioLoop};
use closed_loop::sim::ClosedLoopError;
use iss_certificate::certificate::{
    CertificateOptions, ClosedLoopCertificate, certify_closed_loop,
};

/// The eight preset methods: plain, then Jacobi-scaled.
pub const ALL_METHODS: [qp_iter::Method; 8] = [
    qp_iter::Method::PRESETS[0],
    qp_iter::Method::PRESETS[1],
    qp_iter::Method::PRESETS[2],
    qp_iter::Method::PRESETS[3],
    qp_iter::Method::JACOBI_PRESETS[0],
    qp_iter::Method::JACOBI_PRESETS[1],
    qp_iter::Method::JACOBI_PRESETS[2],
    qp_iter::Method::JACOBI_PRESETS[3],
];

/// The scenario's loop options with `method` in place of its own.
pub fn loop_options(
    r: &closed_loop::scenario::ResolvedScenario,
    method: qp_iter::Method,
) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(r.scenario()).expect("loop options");
    o.method = method;
    o
}

/// A vector as a TOML array, every entry exact (`{:e}` round-trips f64).
pub fn toml_row(v: Vec<f64>) -> String {
    let cells: Vec<String> = v.iter().map(|x| format!("{x:e}")).collect();
    format!("[{}]", cells.join(", "))
}

/// A matrix as a TOML array of rows (for scenario files written by the tests).
pub fn toml_matrix(m: &faer::Mat<f64>) -> String {
    let rows: Vec<String> = (0..m.nrows())
        .map(|i| toml_row((0..m.ncols()).map(|j| m[(i, j)]).collect()))
        .collect();
    format!("[{}]", rows.join(", "))
}

/// Resolves `s` and builds its loop (tests that vary the scenario between builds).
pub fn build(s: &Scenario, o: &LoopOptions) -> Result<ScenarioLoop, ClosedLoopError> {
    s.clone().resolve()?.build_loop(o)
}

/// Resolves `s` and certifies it.
pub fn certify(
    s: &Scenario,
    o: &CertificateOptions,
) -> Result<ClosedLoopCertificate, ClosedLoopError> {
    certify_closed_loop(&s.clone().resolve()?, o)
}
