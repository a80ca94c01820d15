//! The iteration chain (`iss_certificate::lure::global::IterationChain`, docs/theory.md §4b):
//! the K PG iterations as exact sector constraints inside Theorem L3's LMI.

use std::time::Instant;

use closed_loop::scenario::{LoopOptions, ResolvedScenario, Scenario};
use faer::Par;
use iss_certificate::lure::global::{
    ChainError, ChainOptions, GlobalOptions, IterationChain, iteration_chain,
};
use qp_iter::Method;

fn scenario(file: &str) -> Scenario {
    let path = format!("{}/../../scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
    Scenario::from_file(&path).expect("scenario parses")
}

fn resolved(file: &str) -> ResolvedScenario {
    scenario(file).resolve().expect("scenario resolves")
}

fn options(r: &ResolvedScenario, method: Method) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(r.scenario()).expect("loop options");
    o.method = method;
    o
}

fn chain(file: &str, method: Method) -> IterationChain {
    let r = resolved(file);
    iteration_chain(&r, &options(&r, method)).expect("the chain builds")
}

/// (ii) of §4b: where ρ_lin(K) ≥ 1 the chain certifies nothing (the linear loop — every
/// clamp the identity, z* the unconstrained optimum — satisfies every constraint with
/// equality). Double integrator, PG, K = 10: ρ_lin = 1.015.
#[test]
fn chain_refuses_where_rho_lin_is_at_least_one() {
    let ch = chain("double-integrator.toml", Method::PG);
    let k = 10;
    let rho = ch.global.lifted.spectral_radius(k, Par::Seq).expect("ρ_lin");
    assert!(rho >= 1.0, "the premise: ρ_lin({k}) = {rho}");
    let opts = ChainOptions {
        scale_points: 3,
        global: GlobalOptions {
            tau_points: 3,
            ..GlobalOptions::default()
        },
        ..ChainOptions::default()
    };
    let (c, used) = ch.certify_chain(k, &opts).expect("within the size limit");
    assert!(c.is_none(), "certified K = {k} where ρ_lin = {rho}");
    assert!(used > 10, "the search tried {used} points only");
}

/// Methods outside the PG family, K = 0 and a chain above the size limit are refused with
/// the key to change.
#[test]
fn chain_refuses_what_it_does_not_model() {
    let r = resolved("double-integrator.toml");
    let e = iteration_chain(&r, &options(&r, Method::PRESETS[1])).expect_err("fista");
    assert!(matches!(e, ChainError::Method { .. }), "{e}");
    assert!(e.to_string().contains("mhe.method"));
    let ch = iteration_chain(&r, &options(&r, Method::PG)).expect("pg");
    let opts = ChainOptions::default();
    let e = ch.certify_chain(0, &opts).expect_err("K = 0");
    assert!(matches!(e, ChainError::ZeroIterations), "{e}");
    let big = (opts.max_dim / ch.n_b().max(1)) + 2;
    let e = ch.certify_chain(big, &opts).expect_err("too large");
    assert!(matches!(e, ChainError::TooLarge { .. }), "{e}");
    assert!(e.to_string().contains("mhe.iterations"));
}

/// Exploration / measurement: the chain's K on a scenario per method, beside K_lin and
/// Theorem L3's K_glob.
#[test]
#[ignore = "measurement (release): minutes"]
fn measure_k_chain() {
    let files = std::env::var("CHAIN_SCENARIOS").unwrap_or_else(|_| {
        "double-integrator.toml,case-study.toml,case-study-certified.toml".into()
    });
    let kmax: usize = std::env::var("CHAIN_KMAX")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(60);
    for file in files.split(',') {
        for method in [Method::PG, Method::JACOBI_PRESETS[0]] {
            let t0 = Instant::now();
            let r = resolved(file);
            let ch = match iteration_chain(&r, &options(&r, method)) {
                Ok(c) => c,
                Err(e) => {
                    eprintln!("{file} {}: {e}", method.name());
                    continue;
                }
            };
            // K_lin: the first K from which ρ_lin < 1 up to 300 (ρ_lin is not monotone).
            let stable: Vec<bool> = (1..=300)
                .map(|k| {
                    ch.global
                        .lifted
                        .spectral_radius(k, Par::Seq)
                        .is_ok_and(|r| r < 1.0)
                })
                .collect();
            let k_lin = (0..300).find(|&i| stable[i..].iter().all(|s| *s)).map(|i| i + 1);
            let first_stable = stable.iter().position(|s| *s).map(|i| i + 1);
            let opts = ChainOptions::default();
            eprintln!(
                "{file} {}: n_X = {}, n_B = {}, dim ζ(1) = {}, K_lin = {k_lin:?} (first ρ_lin < 1 at {first_stable:?})",
                method.name(),
                ch.global.n_x(),
                ch.n_b(),
                ch.dim(1)
            );
            let scan = ch.k_chain(kmax, &opts);
            let t1 = t0.elapsed().as_secs_f64();
            let glob = ch.global.k_glob(&opts.global).map(|(k, _)| k);
            match &scan.certified {
                Some(c) => eprintln!(
                    "  K_chain = {} (τ₂ = {:.2e}, λ₀ = {:.2e}, ρ = {}, margin {:.2e}), {} solves, {t1:.1} s; K_glob = {glob:?} ({:.1} s)",
                    c.k,
                    c.tau2,
                    c.lambda.first().copied().unwrap_or(0.0),
                    c.cert.rho,
                    c.cert.margin,
                    scan.solves,
                    t0.elapsed().as_secs_f64()
                ),
                None => eprintln!(
                    "  K_chain none up to {} (stopped: {}), {} solves, {t1:.1} s; K_glob = {glob:?}",
                    scan.last_k, scan.stopped, scan.solves
                ),
            }
        }
    }
}
