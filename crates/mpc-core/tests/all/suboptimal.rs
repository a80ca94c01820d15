//! SuboptimalMpc: convergence to the exact law for K large, the warm-start rules,
//! feasibility for every K, and map/problem consistency.

use lti_model::{BoxSet, ConvexSet, Projection};
use mpc_core::{CondensedMpc, Controller, ExactMpc, MpcConfig, MpcError, SuboptimalMpc, WarmStart};
use qp_iter::IterationMap;
use qp_iter::admm::{Admm, AdmmParams};
use qp_iter::fista::Fista;
use qp_iter::pg::{ProjectedGradient, StepRule};

use crate::common::*;

/// Runs a nominal closed loop x⁺ = Ax + Bu with the K-iteration law and checks every
/// input against the exact law (same x̂) to `tol`, and 𝒰 exactly.
fn closed_loop_matches_exact<M: IterationMap>(
    mpc: &CondensedMpc,
    ctrl: &mut SuboptimalMpc<M>,
    x0: &[f64],
    steps: usize,
    tol: f64,
) {
    let mut exact = ExactMpc::new(mpc).unwrap();
    let sys = mpc.system();
    let (nx, nu) = (sys.nx(), sys.nu());
    let mut x = x0.to_vec();
    let (mut u, mut ue) = (vec![0.0; nu], vec![0.0; nu]);
    let mut y = vec![0.0; sys.ny()];
    let w = vec![0.0; sys.nw()];
    for t in 0..steps {
        ctrl.control(&x, &mut u).unwrap();
        exact.control(&x, &mut ue).unwrap();
        assert!(mpc.input_set().contains(&u, 0.0));
        assert!(
            mpc.qp().zset().contains(ctrl.input_sequence(), 0.0),
            "{}: iterate leaves 𝒰^N",
            ctrl.map().name()
        );
        let err = max_abs_diff(&u, &ue);
        assert!(
            err <= tol,
            "{} t = {t}: |u − u*| = {err:e}",
            ctrl.map().name()
        );
        let mut xn = vec![0.0; nx];
        sys.step(&x, &u, &w, &mut xn, &mut y);
        x = xn;
    }
}

#[test]
fn large_k_converges_to_exact_case_study() {
    let mpc = case_study_mpc();
    let x0 = [12.0, -10.0, 10.0, -10.0];
    // K from each certificate so that φ(K) ≤ 1e-11.
    let pg = ProjectedGradient::new(mpc.qp().clone(), StepRule::Optimal).unwrap();
    let k = pg.certificate().min_iterations(1e-11).unwrap();
    let mut c = SuboptimalMpc::new(&mpc, pg, k, WarmStart::ShiftRepeatLast).unwrap();
    closed_loop_matches_exact(&mpc, &mut c, &x0, 15, 1e-7);

    let fista = Fista::new(mpc.qp().clone());
    let k = fista.certificate().min_iterations(1e-11).unwrap();
    let mut c = SuboptimalMpc::new(&mpc, fista, k, WarmStart::ShiftZero).unwrap();
    closed_loop_matches_exact(&mpc, &mut c, &x0, 15, 1e-7);

    let admm = Admm::new(mpc.qp().clone(), AdmmParams::default()).unwrap();
    let k = admm.certificate().min_iterations(1e-11).unwrap();
    let mut c = SuboptimalMpc::new(&mpc, admm, k, WarmStart::Previous).unwrap();
    closed_loop_matches_exact(&mpc, &mut c, &x0, 15, 1e-7);
}

#[test]
fn large_k_converges_to_exact_random_systems() {
    for seed in 0..8 {
        let (sys, cfg) = random_problem(700 + seed);
        let mpc = CondensedMpc::new(&sys, cfg).unwrap();
        let fista = Fista::new(mpc.qp().clone());
        let k = fista.certificate().min_iterations(1e-11).unwrap();
        let mut c = SuboptimalMpc::new(&mpc, fista, k, WarmStart::default()).unwrap();
        let mut r = rng(seed);
        let x0 = gaussian(&mut r, sys.nx(), 3.0);
        closed_loop_matches_exact(&mpc, &mut c, &x0, 6, 1e-7);
    }
}

#[test]
fn error_shrinks_with_k() {
    // ‖Uᴷ − U*‖ from the same cold start is non-increasing in K for PG (a contraction)
    // and obeys the certificate φ(K)‖U⁰ − U*‖.
    let mpc = case_study_mpc();
    let x = [3.0, -2.0, 1.0, 4.0];
    let mut exact = ExactMpc::new(&mpc).unwrap();
    let star = exact.solve(&x).unwrap().to_vec();
    let mut prev = f64::INFINITY;
    for k in [0, 1, 2, 5, 10, 50, 200] {
        let pg = ProjectedGradient::new(mpc.qp().clone(), StepRule::InverseL).unwrap();
        let phi = pg.certificate().phi(k);
        let mut c = SuboptimalMpc::new(&mpc, pg, k, WarmStart::Cold).unwrap();
        let mut u = [0.0; 2];
        c.control(&x, &mut u).unwrap();
        let mut z0 = vec![0.0; star.len()];
        mpc.qp().zset().project(&mut z0);
        let ek: f64 = c
            .input_sequence()
            .iter()
            .zip(&star)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        let e0_2: f64 = z0
            .iter()
            .zip(&star)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        assert!(ek <= phi * e0_2 + 1e-9, "K = {k}: {ek} > φ(K)·{e0_2}");
        assert!(ek <= prev + 1e-12);
        prev = ek;
    }
}

#[test]
fn warm_start_rules_with_k_zero() {
    // With K = 0 the returned sequence *is* the warm start, so each rule can be read off.
    let mpc = CondensedMpc::new(
        &case_study_system(),
        MpcConfig {
            input_set: BoxSet::new(vec![-1.0, 0.5], vec![1.0, 2.0]).unwrap(),
            ..case_study_config()
        },
    )
    .unwrap();
    let x = [5.0, -3.0, 2.0, 1.0];
    let nu = 2;
    for rule in [
        WarmStart::ShiftRepeatLast,
        WarmStart::ShiftZero,
        WarmStart::Previous,
        WarmStart::Cold,
    ] {
        let pg = ProjectedGradient::new(mpc.qp().clone(), StepRule::Optimal).unwrap();
        let mut c = SuboptimalMpc::new(&mpc, pg, 0, rule).unwrap();
        let mut u = [0.0; 2];
        // First call: cold start Π_{𝒰^N}(0) = (0, 0.5) per block.
        c.control(&x, &mut u).unwrap();
        assert_eq!(u, [0.0, 0.5]);
        c.set_iterations(30);
        c.control(&x, &mut u).unwrap();
        let prev = c.input_sequence().to_vec();
        let n = prev.len();
        c.set_iterations(0);
        c.control(&x, &mut u).unwrap();
        let got = c.input_sequence().to_vec();
        let expected: Vec<f64> = match rule {
            WarmStart::ShiftRepeatLast => {
                prev[nu..].iter().chain(&prev[n - nu..]).copied().collect()
            }
            WarmStart::ShiftZero => prev[nu..].iter().chain(&[0.0, 0.5]).copied().collect(),
            WarmStart::Previous => prev.clone(),
            WarmStart::Cold => (0..n).map(|i| if i % 2 == 0 { 0.0 } else { 0.5 }).collect(),
        };
        assert_eq!(got, expected, "{rule:?}");
        assert_eq!(u, [expected[0], expected[1]]);
        // reset() forgets the previous sequence.
        c.set_iterations(30);
        c.control(&x, &mut u).unwrap();
        c.reset();
        c.set_iterations(0);
        c.control(&x, &mut u).unwrap();
        assert_eq!(u, [0.0, 0.5], "{rule:?} after reset");
    }
}

#[test]
fn map_for_another_problem_is_refused() {
    let mpc = case_study_mpc();
    let other = CondensedMpc::new(
        &case_study_system(),
        MpcConfig {
            horizon: 9,
            ..case_study_config()
        },
    )
    .unwrap();
    let e = SuboptimalMpc::new(
        &mpc,
        Fista::new(other.qp().clone()),
        10,
        WarmStart::default(),
    )
    .unwrap_err();
    assert!(matches!(e, MpcError::MapMismatch { .. }), "{e}");
    let other = CondensedMpc::new(
        &case_study_system(),
        MpcConfig {
            r_c: faer::Mat::<f64>::identity(2, 2) * 0.2,
            ..case_study_config()
        },
    )
    .unwrap();
    let e = SuboptimalMpc::new(
        &mpc,
        Fista::new(other.qp().clone()),
        10,
        WarmStart::default(),
    )
    .unwrap_err();
    assert!(
        matches!(&e, MpcError::MapMismatch { what } if what.starts_with('H')),
        "{e}"
    );
    let other = CondensedMpc::new(
        &case_study_system(),
        MpcConfig {
            input_set: BoxSet::symmetric(&[1.0, 2.0]).unwrap(),
            ..case_study_config()
        },
    )
    .unwrap();
    let e = SuboptimalMpc::new(
        &mpc,
        Fista::new(other.qp().clone()),
        10,
        WarmStart::default(),
    )
    .unwrap_err();
    assert!(
        matches!(&e, MpcError::MapMismatch { what } if what.starts_with('Z')),
        "{e}"
    );
}
