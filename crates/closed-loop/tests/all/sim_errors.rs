//! Bad input and failing runs: typed errors at construction and at the failing step.

use crate::build;
use crate::sim::{case_study, lqr, mhe_for, norm, options};
use closed_loop::scenario::{ControllerChoice, LoopOptions};
use closed_loop::sim::{ClosedLoop, ClosedLoopError};
use faer::{Mat, mat};
use lti_model::disturbance::{Disturbance, Zero};
use lti_model::{BoxSet, LtiSystem};
use mhe_core::Estimator;
use mpc_core::{Controller, SaturatedLqr};
use qp_iter::Method;

fn dim_err(e: ClosedLoopError) -> (&'static str, usize, usize) {
    match e {
        ClosedLoopError::Dimension {
            what,
            expected,
            actual,
        } => (what, expected, actual),
        other => panic!("expected a dimension error, got {other}"),
    }
}

/// T = 0, mismatched dimensions: typed errors at construction.
#[test]
fn bad_construction_gives_typed_errors() {
    let s = case_study();
    let p = || s.plant.clone();
    let x0 = &s.simulation.x0[..];
    let new = |est, ctrl: SaturatedLqr, d: Box<dyn Disturbance>, x0: &[f64], steps| {
        ClosedLoop::new(p(), est, ctrl, d, x0, steps).map(|_| ())
    };
    let zero = || -> Box<dyn Disturbance> { Box::new(Zero(5)) };
    assert_eq!(
        new(mhe_for(&p(), &s), lqr(&s), zero(), x0, 0),
        Err(ClosedLoopError::ZeroSteps)
    );
    assert_eq!(
        dim_err(new(mhe_for(&p(), &s), lqr(&s), zero(), &x0[..3], 5).unwrap_err()),
        ("x0 length", 4, 3)
    );
    assert!(matches!(
        new(
            mhe_for(&p(), &s),
            lqr(&s),
            zero(),
            &[0.0, f64::NAN, 0.0, 0.0],
            5
        ),
        Err(ClosedLoopError::NonFiniteInitialState { index: 1, .. })
    ));
    let small = LtiSystem::new(
        mat![[0.5, 0.0], [0.0, 0.5]],
        mat![[1.0], [0.0]],
        mat![[1.0, 0.0]],
    )
    .unwrap();
    assert_eq!(
        dim_err(new(mhe_for(&small, &s), lqr(&s), zero(), x0, 5).unwrap_err()),
        ("estimator n_x", 4, 2)
    );
    let lqr1 =
        SaturatedLqr::from_gain(Mat::zeros(1, 4), BoxSet::symmetric(&[1.0]).unwrap()).unwrap();
    assert_eq!(
        dim_err(new(mhe_for(&p(), &s), lqr1, zero(), x0, 5).unwrap_err()),
        ("controller n_u", 2, 1)
    );
    let lqr_x3 =
        SaturatedLqr::from_gain(Mat::zeros(2, 3), BoxSet::symmetric(&[1.0; 2]).unwrap()).unwrap();
    assert_eq!(
        dim_err(new(mhe_for(&p(), &s), lqr_x3, zero(), x0, 5).unwrap_err()),
        ("controller n_x", 4, 3)
    );
    let (what, e, a) =
        dim_err(new(mhe_for(&p(), &s), lqr(&s), Box::new(Zero(4)), x0, 5).unwrap_err());
    assert_eq!((what.starts_with("disturbance dim"), e, a), (true, 5, 4));
    // An MHE for a plant with the same n_x but one input: caught through its record.
    let one_input = LtiSystem::new(
        s.plant.a().to_owned(),
        Mat::from_fn(4, 1, |i, _| s.plant.b()[(i, 0)]),
        s.plant.c().to_owned(),
    )
    .unwrap();
    let err =
        ClosedLoop::new_mhe(p(), mhe_for(&one_input, &s), lqr(&s), Zero(5), x0, 5).unwrap_err();
    assert_eq!(dim_err(err), ("MHE record n_u", 2, 1));
}

/// Bad builder options, missing sections, an unbounded 𝒲 and an unknown method: typed
/// errors before the loop is built.
#[test]
fn bad_options_give_typed_errors() {
    let s = case_study();
    // `LoopOptions::iterations` is a `qp_iter::Iterations`, so a built option cannot hold
    // K = 0: `with_iterations` refuses 0 and K above the limit, naming the field.
    let mut o = options(&s, 5, false);
    for k in [0, qp_iter::MAX_ITERATIONS + 1] {
        assert!(matches!(
            o.with_iterations(k),
            Err(ClosedLoopError::OutOfRange {
                name: "iterations",
                ..
            })
        ));
    }
    o.steps = 0;
    assert!(matches!(build(&s, &o), Err(ClosedLoopError::ZeroSteps)));
    o.steps = 40;
    // K_c likewise: a `ControllerChoice::SuboptimalMpc` holds a `qp_iter::Iterations`, and
    // `ControllerChoice::suboptimal` refuses 0 and K_c above the limit, naming the field.
    for k_c in [0, qp_iter::MAX_ITERATIONS + 1] {
        assert!(matches!(
            ControllerChoice::suboptimal(k_c, Method::PG),
            Err(ClosedLoopError::OutOfRange {
                name: "controller iterations",
                ..
            })
        ));
    }
    o.controller = ControllerChoice::SaturatedLqr;
    let mut no_mpc = s.clone();
    no_mpc.mpc = None;
    assert_eq!(
        build(&no_mpc, &o).map(|_| ()),
        Err(ClosedLoopError::MissingSection { section: "mpc" })
    );
    let mut no_mhe = s.clone();
    no_mhe.mhe = None;
    assert_eq!(
        LoopOptions::from_scenario(&no_mhe),
        Err(ClosedLoopError::MissingSection { section: "mhe" })
    );
    assert_eq!(
        build(&no_mhe, &o).map(|_| ()),
        Err(ClosedLoopError::MissingSection { section: "mhe" })
    );
    let mut unbounded = s.clone();
    unbounded.sets.disturbance = BoxSet::whole(5);
    let err = build(&unbounded, &o).map(|_| ()).unwrap_err();
    assert!(err.to_string().contains("`W`"), "{err}");
    assert!(matches!(
        "newton".parse::<Method>(),
        Err(qp_iter::QpError::UnknownMethod { ref name, ref known })
            if name == "newton" && known.contains("\"admm-pr\"")
    ));
    for name in ["pg", "fista", "admm", "admm-pr"] {
        assert_eq!(name.parse::<Method>().unwrap().name(), name);
    }
}

/// MHE records: only before the first step, and only windows that fit.
#[test]
fn bad_mhe_record_use_gives_typed_errors() {
    let s = case_study();
    let p = || s.plant.clone();
    let x0 = &s.simulation.x0[..];
    let mut cl = ClosedLoop::new(p(), mhe_for(&p(), &s), lqr(&s), Zero(5), x0, 8).unwrap();
    cl.step().unwrap();
    assert_eq!(
        cl.with_mhe_records(closed_loop::sim::mhe_record_hook, 5)
            .map(|_| ()),
        Err(ClosedLoopError::AlreadyStarted { t: 1 })
    );
    let mut cl = ClosedLoop::new(p(), mhe_for(&p(), &s), lqr(&s), Zero(5), x0, 8)
        .unwrap()
        .with_mhe_records(closed_loop::sim::mhe_record_hook, 2)
        .unwrap();
    assert_eq!(
        cl.run().map(|_| ()),
        Err(ClosedLoopError::RecordCapacity {
            t: 3,
            window: 3,
            capacity: 2
        })
    );
    assert_eq!(cl.trace().len(), 3);
}

/// An estimator that misbehaves at a given step.
#[derive(Debug)]
struct Faulty {
    t: usize,
    at: usize,
    len: usize,
    x: Vec<f64>,
}

impl Estimator for Faulty {
    type Error = mhe_core::MheError;
    fn estimate(&mut self) -> mhe_core::Result<&[f64]> {
        self.x = vec![0.0; if self.t == self.at { self.len } else { 4 }];
        if self.t == self.at && self.len == 4 {
            self.x[2] = f64::NAN;
        }
        Ok(&self.x)
    }
    fn push(&mut self, _u: &[f64], _y: &[f64]) -> mhe_core::Result<()> {
        self.t += 1;
        Ok(())
    }
    fn nx(&self) -> usize {
        4
    }
}

/// Step errors name the step and the cause, and stop the loop; the trace keeps the steps
/// before.
#[test]
fn step_errors_name_the_step_and_stop_the_loop() {
    let s = case_study();
    let x0 = &s.simulation.x0[..];
    let faulty = |at, len| Faulty {
        t: 0,
        at,
        len,
        x: Vec::new(),
    };
    let mut cl = ClosedLoop::new(s.plant.clone(), faulty(3, 4), lqr(&s), Zero(5), x0, 10).unwrap();
    let err = cl.run().unwrap_err();
    assert!(matches!(
        err,
        ClosedLoopError::NonFinite {
            t: 3,
            name: "x_hat",
            index: 2,
            ..
        }
    ));
    assert!(err.to_string().contains("t = 3"), "{err}");
    assert_eq!(cl.trace().len(), 3);
    assert_eq!(cl.step(), Err(ClosedLoopError::Stopped { t: 3 }));
    assert_eq!(cl.run().map(|_| ()), Err(ClosedLoopError::Stopped { t: 3 }));

    let mut cl = ClosedLoop::new(s.plant.clone(), faulty(1, 3), lqr(&s), Zero(5), x0, 10).unwrap();
    assert_eq!(
        cl.run().map(|_| ()),
        Err(ClosedLoopError::EstimateLength {
            t: 1,
            expected: 4,
            actual: 3
        })
    );

    // The estimator's own error (wrong n_y at push, a user estimator) names the step.
    let other_c = LtiSystem::new(
        s.plant.a().to_owned(),
        s.plant.b().to_owned(),
        mat![[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]],
    )
    .unwrap();
    let est = mhe_for(&other_c, &s); // n_x = 4, n_u = 2, but n_y = 2
    let mut cl = ClosedLoop::new(s.plant.clone(), est, lqr(&s), Zero(5), x0, 4).unwrap();
    let err = cl.run().unwrap_err();
    assert!(
        matches!(err, ClosedLoopError::Estimator { t: 0, .. }),
        "{err}"
    );

    // A diverging plant is reported, not recorded as finite.
    let unstable = LtiSystem::new(
        Mat::from_fn(4, 4, |i, j| if i == j { 1e308 } else { 0.0 }),
        Mat::zeros(4, 2),
        s.plant.c().to_owned(),
    )
    .unwrap();
    let mut cl = ClosedLoop::new(unstable, faulty(99, 4), lqr(&s), Zero(5), &[10.0; 4], 5).unwrap();
    assert!(matches!(
        cl.run(),
        Err(ClosedLoopError::NonFinite {
            t: 0,
            name: "y" | "x_next",
            ..
        })
    ));

    // Running past T.
    let mut cl = ClosedLoop::new(s.plant.clone(), faulty(99, 4), lqr(&s), Zero(5), x0, 2).unwrap();
    assert_eq!(cl.run().unwrap().len(), 2);
    assert!(cl.is_finished());
    assert_eq!(cl.step(), Err(ClosedLoopError::Finished { steps: 2 }));
    assert_eq!(cl.run().unwrap().len(), 2);
}

/// A controller that fails at a given call.
#[derive(Debug)]
struct FailingController {
    calls: usize,
    at: usize,
}

impl Controller for FailingController {
    type Error = mpc_core::MpcError;
    fn control(&mut self, _x_hat: &[f64], u: &mut [f64]) -> mpc_core::Result<()> {
        self.calls += 1;
        if self.calls > self.at {
            return Err(mpc_core::MpcError::NonFiniteIterate);
        }
        u.fill(0.0);
        Ok(())
    }
    fn nu(&self) -> usize {
        2
    }
    fn nx(&self) -> usize {
        4
    }
}

/// A controller error names the step; the failing step's MHE record is kept for diagnosis
/// but is not part of the trace's steps.
#[test]
fn controller_error_keeps_the_failing_steps_mhe_record() {
    let s = case_study();
    let ctrl = FailingController { calls: 0, at: 2 };
    let mut cl = ClosedLoop::new_mhe(
        s.plant.clone(),
        mhe_for(&s.plant, &s),
        ctrl,
        Zero(5),
        &s.simulation.x0,
        6,
    )
    .unwrap();
    let err = cl.run().unwrap_err();
    assert_eq!(
        err,
        ClosedLoopError::Controller {
            t: 2,
            source: closed_loop::sim::ComponentError::new(mpc_core::MpcError::NonFiniteIterate)
        }
    );
    let tr = cl.trace();
    assert_eq!(tr.len(), 2);
    assert!(tr.mhe_step(2).is_none());
    let mhe = tr.mhe().unwrap();
    assert_eq!(mhe.len(), 3);
    assert_eq!(mhe.step(2).unwrap().window(), 2);
    let v: serde_json::Value = serde_json::from_str(&tr.to_json().unwrap()).unwrap();
    assert_eq!(v["records"].as_array().unwrap().len(), 2);
}

/// A run whose state grows geometrically (finite entries, but beyond 1e154 their squares
/// overflow and every norm is +∞) stops with an error naming the signal and the step, and
/// the trace before it keeps finite norms (issue: "sup_x = inf" with an empty error).
#[test]
fn a_run_whose_norms_would_overflow_stops_as_diverged_naming_t() {
    let s = case_study();
    let growing = LtiSystem::new(
        Mat::from_fn(4, 4, |i, j| if i == j { 1e10 } else { 0.0 }),
        Mat::zeros(4, 2),
        s.plant.c().to_owned(),
    )
    .unwrap();
    let est = Faulty {
        t: 0,
        at: 999,
        len: 4,
        x: Vec::new(),
    };
    let mut cl = ClosedLoop::new(growing, est, lqr(&s), Zero(5), &[1.0; 4], 40).unwrap();
    let err = cl.run().unwrap_err();
    // x_t = 1e10ᵗ: x_16 = 1e160 ≥ 1e154 is produced at step t = 15.
    match &err {
        &ClosedLoopError::NonFinite { t, name, value, .. } => {
            assert_eq!((t, name), (15, "x_next"), "{err}");
            assert!(value.is_finite() && value >= closed_loop::sim::DIVERGED_MAGNITUDE);
        }
        other => panic!("{other}"),
    }
    assert!(err.to_string().contains("diverged at t = 15"), "{err}");
    let tr = cl.trace();
    assert_eq!(tr.len(), 15);
    assert!(tr.sup_norm_x().is_finite());
}

/// The sweep's bounded rule covers the estimation error: an estimator that diverges while
/// the saturated input keeps x bounded is not "bounded".
#[test]
fn a_diverging_estimator_with_bounded_state_is_not_bounded() {
    /// x̂ doubles every step, whatever the data.
    #[derive(Debug)]
    struct Doubling(Vec<f64>);
    impl Estimator for Doubling {
        type Error = std::convert::Infallible;
        fn estimate(&mut self) -> Result<&[f64], Self::Error> {
            Ok(&self.0)
        }
        fn push(&mut self, _u: &[f64], _y: &[f64]) -> Result<(), Self::Error> {
            self.0.iter_mut().for_each(|v| *v *= 2.0);
            Ok(())
        }
        fn nx(&self) -> usize {
            self.0.len()
        }
    }
    let s = case_study();
    let x0 = &s.simulation.x0;
    let run = |est: Doubling| {
        let mut cl = ClosedLoop::new(s.plant.clone(), est, lqr(&s), Zero(5), x0, 40).unwrap();
        cl.run().unwrap().clone()
    };
    let input = (s.sets.input.lower(), s.sets.input.upper());
    // x̂ = 2ᵗ·1: ‖e‖ reaches ~1e12 while |u| ≤ 1 keeps the stable plant's x bounded.
    let diverging = run(Doubling(vec![1.0; 4]));
    assert!(diverging.sup_norm_x() < 1e3 * (1.0 + norm(x0)));
    let (_, bounded) = closed_loop::metrics::run_metrics(&diverging, x0, input, 1e3, None);
    assert!(!bounded, "sup ‖e‖ = {}", diverging.sup_norm_e());
    // The same loop with a sane estimate is bounded.
    let sane = run(Doubling(vec![0.0; 4]));
    let (_, bounded) = closed_loop::metrics::run_metrics(&sane, x0, input, 1e3, None);
    assert!(bounded);
}
