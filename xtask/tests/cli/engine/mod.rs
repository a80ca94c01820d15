//! The sweep engine's integration tests (one binary): sweeps, 2-D sweeps, and the one truth
//! of the bounded rule, the coverage and the thresholds across reproduce and sweeps.
#![allow(clippy::unwrap_used)]

mod regional;
mod sweep;
mod sweep2d;
mod sweep_io;
mod truth;

use closed_loop::scenario::{LoopOptions, Scenario, ScenarioLoop};
use closed_loop::sim::ClosedLoopError;

/// Runs `sweep` into `out` on `threads` threads (one shard of it, if given), silently.
pub fn run_sweep(
    sweep: &xtask::sweep_engine::Sweep,
    out: &std::path::Path,
    threads: usize,
    shard: Option<xtask::sweep_engine::Shard>,
) -> xtask::sweep_engine::SweepReport {
    sweep
        .run(
            &xtask::sweep_engine::RunOptions {
                out_dir: out.to_path_buf(),
                threads,
                shard,
            },
            &xtask::sweep_engine::NoProgress,
        )
        .unwrap()
}

/// Resolves `s` and builds its loop (tests that vary the scenario between builds).
pub fn build(s: &Scenario, o: &LoopOptions) -> Result<ScenarioLoop, ClosedLoopError> {
    s.clone().resolve()?.build_loop(o)
}

/// Resolves `s` and certifies it.
pub fn certify(
    s: &Scenario,
    o: &iss_certificate::certificate::CertificateOptions,
) -> Result<iss_certificate::certificate::ClosedLoopCertificate, ClosedLoopError> {
    iss_certificate::certificate::certify_closed_loop(&s.clone().resolve()?, o)
}
