//! Zero heap allocations per control call of `SuboptimalMpc` (PG, FISTA, ADMM),
//! `SaturatedLqr` and `ExactMpc` (active-set backend) after construction, error paths
//! included. A separate binary because it installs a counting global allocator.
#![allow(clippy::unwrap_used)]

use faer::Mat;
use lti_model::{BoxSet, LtiSystem};
use mpc_core::{CondensedMpc, Controller, MpcConfig, SaturatedLqr, SuboptimalMpc, WarmStart};
use qp_iter::admm::{Admm, AdmmParams};
use qp_iter::fista::Fista;
use qp_iter::pg::{ProjectedGradient, StepRule};

#[global_allocator]
static GLOBAL: alloc_counter::CountingAllocator = alloc_counter::CountingAllocator;

use alloc_counter::allocations;

/// A nominal closed loop of `steps` calls plus error calls; returns the allocation count.
fn count_loop(
    c: &mut dyn Controller<Error = mpc_core::MpcError>,
    sys: &LtiSystem,
    steps: usize,
) -> usize {
    let (nx, nu) = (sys.nx(), sys.nu());
    let mut x = [12.0, -10.0, 10.0, -10.0];
    let mut xn = [0.0; 4];
    let mut u = [0.0; 2];
    let mut y = [0.0; 1];
    let w = [0.0; 5];
    let bad_x = [f64::NAN, 0.0, 0.0, 0.0];
    assert_eq!((nx, nu), (4, 2));
    // Warm-up call outside the count (runtime kernel dispatch may initialise once).
    c.control(&x, &mut u).unwrap();
    allocations(|| {
        for _ in 0..steps {
            c.control(&x, &mut u).unwrap();
            sys.step(&x, &u, &w, &mut xn, &mut y);
            x = xn;
            assert!(c.control(&bad_x, &mut u).is_err());
            assert!(c.control(&x[..3], &mut u).is_err());
        }
    })
}

#[test]
fn control_calls_do_not_allocate() {
    let sys = lti_model::presets::case_study_plant();
    let ubox = BoxSet::symmetric(&[1.0, 1.0]).unwrap();
    let cfg = MpcConfig::new(
        10,
        Mat::identity(4, 4),
        Mat::<f64>::identity(2, 2) * 0.1,
        ubox.clone(),
    );
    let mpc = CondensedMpc::new(&sys, cfg).unwrap();

    for rule in [
        WarmStart::ShiftRepeatLast,
        WarmStart::ShiftZero,
        WarmStart::Previous,
        WarmStart::Cold,
    ] {
        let pg = ProjectedGradient::new(mpc.qp().clone(), StepRule::Optimal).unwrap();
        let mut c = SuboptimalMpc::new(&mpc, pg, 30, rule).unwrap();
        assert_eq!(count_loop(&mut c, &sys, 20), 0, "PG, {rule:?}");
    }
    let mut c =
        SuboptimalMpc::new(&mpc, Fista::new(mpc.qp().clone()), 30, WarmStart::default()).unwrap();
    assert_eq!(count_loop(&mut c, &sys, 20), 0, "FISTA");
    let admm = Admm::new(mpc.qp().clone(), AdmmParams::default()).unwrap();
    let mut c = SuboptimalMpc::new(&mpc, admm, 30, WarmStart::default()).unwrap();
    assert_eq!(count_loop(&mut c, &sys, 20), 0, "ADMM");

    let mut lqr = SaturatedLqr::new(
        &sys,
        Mat::<f64>::identity(4, 4).as_ref(),
        (Mat::<f64>::identity(2, 2) * 0.1).as_ref(),
        ubox,
    )
    .unwrap();
    assert_eq!(count_loop(&mut lqr, &sys, 20), 0, "saturated LQR");

    // The exact MPC with its default active-set backend: no allocation either.
    let mut exact = mpc_core::ExactMpc::new(&mpc).unwrap();
    assert_eq!(
        count_loop(&mut exact, &sys, 20),
        0,
        "exact MPC (active set)"
    );
    assert_eq!(exact.fallbacks(), 0);

    // The counter works: the Clarabel backend allocates, as documented.
    let mut exact =
        mpc_core::ExactMpc::with_settings(&mpc, qp_iter::reference::ReferenceSettings::default())
            .unwrap();
    let mut u = [0.0; 2];
    assert!(allocations(|| exact.control(&[1.0, 0.0, 0.0, 0.0], &mut u).unwrap()) > 0);
}
