//! Zero heap allocations per closed-loop step after construction (PG MHE with the exact
//! solve off and its record captured, exact MPC, saturated LQR or sub-optimal MPC, uniform
//! disturbance), counted by a global allocator. A separate test binary: the allocator is
//! process-wide.
#![allow(clippy::unwrap_used)]

use closed_loop::scenario::Scenario;
use closed_loop::scenario::{ControllerChoice, LoopOptions, scenario_disturbance};
use closed_loop::sim::ClosedLoop;
use lti_model::disturbance::Disturbance;
use mhe_core::{Estimator, MheEstimator, MheSets};
use mpc_core::{CondensedMpc, Controller, SaturatedLqr, SuboptimalMpc, WarmStart};
use qp_iter::Method;
use qp_iter::pg::{ProjectedGradient, StepRule};

#[global_allocator]
static GLOBAL: alloc_counter::CountingAllocator = alloc_counter::CountingAllocator;

const CASE_STUDY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../scenarios/case-study.toml"
);

/// Allocations made by stepping `cl` to the end.
fn allocations_of_run<E: Estimator, C: Controller, D: Disturbance>(
    cl: &mut ClosedLoop<E, C, D>,
) -> usize {
    let before = alloc_counter::count();
    while !cl.is_finished() {
        cl.step().unwrap();
    }
    alloc_counter::count() - before
}

fn pg_mhe(s: &Scenario) -> MheEstimator<ProjectedGradient> {
    let cfg = s.mhe.as_ref().unwrap().config(&s.plant, false).unwrap();
    MheEstimator::new(
        &s.plant,
        &MheSets::from_scenario(&s.sets),
        &cfg,
        &s.simulation.prior,
        |qp| ProjectedGradient::new(qp, StepRule::Optimal),
    )
    .unwrap()
}

#[test]
fn closed_loop_steps_do_not_allocate() {
    // One test function: the counter is global, parallel tests would pollute it.
    let s = Scenario::from_file(CASE_STUDY).unwrap();
    let spec = s.mpc.as_ref().unwrap();
    let steps = s.simulation.steps;

    // Generic loop: PG MHE (record captured) + saturated LQR.
    let lqr = SaturatedLqr::new(
        &s.plant,
        spec.q().as_ref(),
        spec.r().as_ref(),
        s.sets.input.clone(),
    )
    .unwrap();
    let w = scenario_disturbance(&s, 1).unwrap();
    let mut cl =
        ClosedLoop::new_mhe(s.plant.clone(), pg_mhe(&s), lqr, w, &s.simulation.x0, steps).unwrap();
    assert_eq!(allocations_of_run(&mut cl), 0, "PG MHE + saturated LQR");
    assert_eq!(cl.trace().len(), steps);
    assert_eq!(cl.trace().mhe().unwrap().len(), steps);
    assert!(cl.trace().sup_norm_x().is_finite());

    // Generic loop: PG MHE + sub-optimal MPC (PG, K_c = 30).
    let mpc = CondensedMpc::new(&s.plant, s.mpc.as_ref().unwrap().config(&s.sets)).unwrap();
    let map = ProjectedGradient::new(mpc.qp().clone(), StepRule::Optimal).unwrap();
    let sub = SuboptimalMpc::new(&mpc, map, 30, WarmStart::default()).unwrap();
    let w = scenario_disturbance(&s, 2).unwrap();
    let mut cl =
        ClosedLoop::new_mhe(s.plant.clone(), pg_mhe(&s), sub, w, &s.simulation.x0, steps).unwrap();
    assert_eq!(allocations_of_run(&mut cl), 0, "PG MHE + sub-optimal MPC");

    // The case-study builder (enum dispatch, boxed disturbance), and a Monte-Carlo reseed.
    for controller in [
        ControllerChoice::ExactMpc,
        ControllerChoice::SaturatedLqr,
        ControllerChoice::suboptimal(20, Method::FISTA).unwrap(),
    ] {
        let mut o = LoopOptions::from_scenario(&s).unwrap();
        o = o.with_iterations(25).expect("K is in range");
        o.controller = controller;
        let mut cl = s.clone().resolve().unwrap().build_loop(&o).unwrap();
        assert_eq!(allocations_of_run(&mut cl), 0, "case study {controller:?}");
        let first = cl.trace().clone();
        let before = alloc_counter::count();
        cl.reseed(o.seed).unwrap();
        assert_eq!(alloc_counter::count() - before, 0, "reseed");
        assert_eq!(allocations_of_run(&mut cl), 0, "after reseed");
        assert_eq!(cl.trace(), &first);
    }

    // The counter works.
    let before = alloc_counter::count();
    let v = std::hint::black_box(vec![1.0_f64; 3]);
    assert!(alloc_counter::count() > before && v.len() == 3);
}
