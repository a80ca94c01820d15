//! iss-certificate integration tests (one binary).
#![allow(clippy::unwrap_used)]

mod analysis;
mod asymptotic;
mod budget;
mod certificate;
mod constrained;
mod coverage;
mod findings;
mod gamma13;
mod joint;
mod krylov;
mod linear;
mod mends;
mod plants;
mod plants_ii;
mod regional;
mod users;

use closed_loop::scenario::{LoopOptions, Scenario, ScenarioLoop};
use closed_loop::sim::ClosedLoopError;
use iss_certificate::certificate::{
    CertificateOptions, ClosedLoopCertificate, certify_closed_loop,
};

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
