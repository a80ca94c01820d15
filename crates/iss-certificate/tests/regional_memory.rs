//! The regional certificate's cost estimate (`iss_certificate::regional::estimate`, what its
//! budget and memory limit are checked by) against the heap high-water mark of
//! `regional_certificate` on a grid of plants, horizons, methods and K (issue 23 item 3:
//! "estimate vs measured peak on a grid of sizes, within 2×").
//!
//! Its own test binary: the counting allocator is process-wide.
#![allow(clippy::unwrap_used)]

use closed_loop::scenario::{ControllerChoice, Scenario};
use iss_certificate::regional::{RegionalOptions, RegionalVoid, estimate, regional_certificate};
use qp_iter::Method;

#[global_allocator]
static GLOBAL: alloc_counter::CountingAllocator = alloc_counter::CountingAllocator;

fn scenario(file: &str, horizon: usize) -> Scenario {
    let path = format!("{}/../../scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap();
    let mut s = Scenario::from_toml_str(&text).unwrap();
    if let Some(m) = s.mhe.as_mut() {
        *m = m.to_builder().horizon(horizon).build(&s.plant).unwrap();
    }
    s
}

#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_memory_estimate_is_within_2x_of_the_peak() {
    // Every product on this thread (the allocator counts per thread).
    faer::set_global_parallelism(faer::Par::Seq);
    let mut checked = 0;
    // The first certificate of the process also allocates one-time global state.
    {
        let res = scenario("case-study-certified.toml", 9).resolve().unwrap();
        let o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
        let _ = regional_certificate(&res, Method::FISTA, 20, &o);
    }
    for (file, horizon, ks) in [
        ("case-study-certified.toml", 9, [100usize, 400]),
        ("case-study-certified.toml", 20, [50, 200]),
        ("quadruple-tank.toml", 9, [150, 600]),
        ("double-integrator.toml", 15, [100, 400]),
    ] {
        let res = scenario(file, horizon).resolve().unwrap();
        let o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
        for method in [Method::PG, Method::FISTA, Method::ADMM] {
            for k in ks {
                let (r, peak) =
                    alloc_counter::peak_bytes(|| regional_certificate(&res, method, k, &o));
                let (rho, unstable) = match &r {
                    Ok(c) => (c.rho_lin, false),
                    // ρ_lin ≥ 1 ends the certificate at its first stage (ρ_lin from the K-step
                    // maps, before any row is built): the estimate of the stages it would have
                    // run is then an upper bound, not a match.
                    Err(RegionalVoid::Unstable { .. }) => (0.0, true),
                    Err(e) => panic!("{file} M = {horizon} {method} K = {k}: {e}"),
                };
                let est = estimate(&res, method, k, &o, rho).unwrap();
                let ratio = est.bytes / peak as f64;
                eprintln!(
                    "{file} M = {horizon} {method} K = {k}: estimate {:.3e} B, peak {peak} B, \
                     ratio {ratio:.2}",
                    est.bytes
                );
                assert!(
                    if unstable {
                        ratio >= 0.5
                    } else {
                        (0.5..=2.0).contains(&ratio)
                    },
                    "{file} M = {horizon} {method} K = {k}: estimate {:.0} B, measured peak \
                     {peak} B (ratio {ratio:.2})",
                    est.bytes
                );
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 24);
}

/// Calibration of the time estimate (run by hand, release, quiet machine; prints the table of
/// docs/limits.md): estimated seconds of one core against the measured single-thread time.
#[test]
#[ignore = "calibration: prints estimate vs measured time"]
fn time_estimate_calibration() {
    faer::set_global_parallelism(faer::Par::Seq);
    for (file, horizon, method, k) in [
        ("case-study-certified.toml", 9, Method::FISTA, 800usize),
        ("case-study-certified.toml", 20, Method::PG, 400),
        ("quadruple-tank.toml", 9, Method::ADMM, 1200),
        ("thermal-rod-m10.toml", 10, Method::ADMM, 20),
        ("thermal-rod-m10.toml", 10, Method::FISTA, 80),
        ("mass-chain.toml", 10, Method::FISTA, 100),
    ] {
        let res = scenario(file, horizon).resolve().unwrap();
        let mut o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
        o.phase_seconds = 1e6;
        let t = std::time::Instant::now();
        let r = regional_certificate(&res, method, k, &o);
        let secs = t.elapsed().as_secs_f64();
        let rho = r.as_ref().map_or(0.0, |c| c.rho_lin);
        let est = estimate(&res, method, k, &o, rho).unwrap();
        println!(
            "{file} M = {horizon} {method} K = {k}: estimate {:.2} s, measured {secs:.2} s \
             (ratio {:.2}), {}",
            est.seconds,
            est.seconds / secs,
            r.map_or_else(|e| e.to_string(), |_| "certificate".into())
        );
    }
}
