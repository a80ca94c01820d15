//! The iteration maps on problems with general rows: PG and FISTA with the exact
//! projection keep their certificate and feasible iterates (and lose the bound when the
//! projection ignores the rows); ADMM split on [I; G]z converges to the Goldfarb–Idnani
//! solution with a void certificate and a measured violation.

use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use qp_iter::dual_active_set::{DualActiveSetStatus, ParametricDualActiveSet};
use qp_iter::method::{Method, Scaling};
use qp_iter::{IterationMap, MethodMap, ParametricQp};

use crate::common::{dist, norm, normal, rng};
use crate::general::{Kind, general_instance};

const K_MAX: usize = 60;

fn config(cases: u32, seed: u64) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..Config::default()
    }
}

/// z* by Goldfarb–Idnani (verified KKT) and a start z⁰.
fn solved(seed: u64) -> (ParametricQp, Vec<f64>, Vec<f64>, Vec<f64>) {
    let (qp, theta) = general_instance(seed, Kind::Feasible);
    let mut gi = ParametricDualActiveSet::new(&qp, Default::default()).unwrap();
    let info = gi.solve(&theta).unwrap();
    assert!(info.is_verified(1e-10), "seed {seed}: {info:?}");
    let mut r = rng(seed ^ 0x2b);
    let z0: Vec<f64> = (0..qp.n()).map(|_| 3.0 * normal(&mut r)).collect();
    (qp, theta, gi.z().to_vec(), z0)
}

/// errors ‖zᴷ − z*‖ and violations for K = 0..=K_MAX.
fn run(map: &MethodMap, theta: &[f64], z0: &[f64], zstar: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut s = map.new_state();
    map.load(&mut s, theta);
    map.warm_start(&mut s, z0, None);
    let (mut e, mut v) = (vec![dist(map.iterate(&s), zstar)], vec![0.0]);
    for _ in 0..K_MAX {
        map.step(&mut s);
        e.push(dist(map.iterate(&s), zstar));
        v.push(map.violation(&s));
    }
    (e, v)
}

/// The certificate's bound on every K, and feasibility of every iterate after a step.
fn check_certified(method: Method, seed: u64) -> std::result::Result<(), TestCaseError> {
    let (qp, theta, zstar, z0) = solved(seed);
    let map = method.build(qp.clone()).unwrap();
    let c = map.certificate().clone();
    prop_assert!(c.fits_eq11 && c.rate < 1.0, "{method}: {c:?}");
    if qp.general().is_some() {
        prop_assert!(c.premise.contains("Gz"), "{}", c.premise);
    }
    let (errs, viol) = run(&map, &theta, &z0, &zstar);
    let e0 = dist(&z0, &zstar);
    let slack = 1e-9 * (1.0 + norm(&zstar));
    let scale = 1.0 + norm(&zstar) + norm(&z0);
    for (k, (&ek, &vk)) in errs.iter().zip(&viol).enumerate() {
        prop_assert!(
            ek <= c.phi(k) * (e0 + slack) * (1.0 + 1e-9) + slack,
            "seed {seed} {method}: K = {k}: {ek:.3e} > φ(K)·e0 = {:.3e}",
            c.phi(k) * e0
        );
        prop_assert!(
            vk <= 1e-9 * scale,
            "seed {seed} {method}: K = {k}: violation {vk:.3e}"
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(1000, 0x15_0101))]
    /// PG (both step rules via the named method and 1/L), FISTA and their Jacobi-scaled
    /// versions: ‖zᴷ − z*‖ ≤ φ(K)‖z⁰ − z*‖ on random QPs with general rows, K = 0…60, and
    /// every iterate feasible.
    #[test]
    #[ignore = "long: run by .ci/run with --ignored"]
    fn long_pg_and_fista_certificates_hold_with_general_rows(seed in any::<u64>()) {
        for m in [Method::PG, Method::FISTA, Method::PG.with_scaling(Scaling::Jacobi),
                  Method::FISTA.with_scaling(Scaling::Jacobi)] {
            check_certified(m, seed)?;
        }
    }
}

#[test]
fn the_bound_fails_when_the_projection_ignores_the_rows() {
    // The premise "exact projection onto the feasible set" broken: PG projecting onto the
    // box only (the rows dropped) converges to the box-only minimiser, and the bound
    // against the constrained z* fails on many instances.
    let mut failed = 0;
    let mut instances = 0;
    for seed in 0..300u64 {
        let (qp, theta, zstar, z0) = solved(seed);
        if qp.general().is_none() {
            continue;
        }
        instances += 1;
        let map = Method::PG.build(qp.without_general()).unwrap();
        let c = map.certificate().clone();
        let (errs, _) = run(&map, &theta, &z0, &zstar);
        let e0 = dist(&z0, &zstar);
        if errs
            .iter()
            .enumerate()
            .any(|(k, &e)| e > c.phi(k) * e0 * (1.0 + 1e-6) + 1e-6)
        {
            failed += 1;
        }
    }
    println!("box-only projection: bound violated on {failed} of {instances} instances");
    assert!(failed * 4 > instances, "{failed} of {instances}");
}

proptest! {
    #![proptest_config(config(300, 0x15_0102))]
    /// ADMM split on [I; G]z: void certificate with the surjectivity reason, and it
    /// converges to the exact solution (x within 1e-6 relative after 20 000 steps, the
    /// measured violation with it) — on instances whose multipliers are moderate: with
    /// nearly parallel equality rows (‖λ‖_∞ ~ 10³) the dual must travel far and ADMM takes
    /// ~10⁶ steps (z* with its multipliers is checked to be a fixed point instead).
    #[test]
    #[ignore = "long: run by .ci/run with --ignored"]
    fn long_admm_split_converges_but_is_not_certified(seed in any::<u64>()) {
        let (qp, theta, zstar, z0) = solved(seed);
        let mut gi = ParametricDualActiveSet::new(&qp, Default::default()).unwrap();
        gi.solve(&theta).unwrap();
        let lam_max = gi.multipliers().iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let y: Vec<f64> = gi.multipliers().iter().map(|v| -v).collect();
        let has_rows = qp.general().is_some();
        // α = 2 (admm-pr) is left out: OSQP's iteration converges for α ∈ (0, 2) only.
        for method in [Method::ADMM, Method::admm(None, 1.6).unwrap()] {
            let map = method.build(qp.clone()).unwrap();
            let c = map.certificate();
            if !has_rows {
                prop_assert!(c.fits_eq11);
                continue;
            }
            prop_assert!(matches!(map, MethodMap::AdmmSplit(_)));
            prop_assert!(!c.fits_eq11 && c.rate >= 1.0 && c.min_iterations(0.5).is_none());
            prop_assert!(c.premise.contains("surjective"), "{}", c.premise);
            let mut s = map.new_state();
            map.load(&mut s, &theta);
            // (z*, −λ*) is a fixed point (Hz + q + [I; G]ᵀy = 0 in ADMM's sign).
            map.warm_start(&mut s, &zstar, Some(&y));
            map.run_steps(&mut s, 100);
            prop_assert!(dist(map.iterate(&s), &zstar) <= 1e-9 * (1.0 + norm(&zstar)));
            if lam_max > 100.0 {
                continue;
            }
            map.warm_start(&mut s, &z0, None);
            map.run_steps(&mut s, 20_000);
            let rel = dist(map.iterate(&s), &zstar) / (1.0 + norm(&zstar));
            prop_assert!(rel < 1e-6, "seed {seed} {method}: rel {rel:.3e}");
            prop_assert!(map.violation(&s) < 1e-6 * (1.0 + norm(&zstar)));
        }
    }
}

#[test]
fn admm_split_iterates_are_infeasible_before_convergence_and_it_is_measured() {
    // Design trap 7: the violation is reported, not hidden.
    let mut seen = 0;
    for seed in 0..100u64 {
        let (qp, theta, _, z0) = solved(seed);
        if qp.general().is_none() {
            continue;
        }
        let map = Method::ADMM.build(qp).unwrap();
        let mut s = map.new_state();
        map.load(&mut s, &theta);
        map.warm_start(&mut s, &z0, None);
        map.run_steps(&mut s, 3);
        if map.violation(&s) > 1e-3 {
            seen += 1;
        }
    }
    assert!(seen > 10, "{seen}");
}

#[test]
fn infeasible_bounds_give_a_non_finite_iterate_and_name_the_row() {
    let (qp, theta) = general_instance(7, Kind::InfeasiblePair);
    for m in [Method::PG, Method::FISTA] {
        let map = m.build(qp.clone()).unwrap();
        let mut s = map.new_state();
        map.load(&mut s, &theta);
        let r = map.run_fixed(&mut s, 3);
        assert_eq!(r.status, qp_iter::RunStatus::NonFinite, "{m}");
    }
    let mut gi = ParametricDualActiveSet::new(&qp, Default::default()).unwrap();
    assert!(matches!(
        gi.solve(&theta).unwrap().status,
        DualActiveSetStatus::Infeasible { .. }
    ));
}
