//! Bad input: typed errors at setup; NaN during iteration is a run status, not a panic.

use faer::{Mat, mat};
use qp_iter::admm::{Admm, AdmmParams, Penalty};
use qp_iter::fista::Fista;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};
use qp_iter::{BoxSet, DataError as ModelError};
use qp_iter::{IterationMap, ParametricQp, QpError, RunStatus, run_fixed, run_until};

fn h2() -> Mat<f64> {
    mat![[2.0, 0.5], [0.5, 1.0]]
}
fn box2() -> BoxSet {
    BoxSet::symmetric(&[1.0, 1.0]).unwrap()
}
fn qp2() -> ParametricQp {
    ParametricQp::new(h2(), vec![1.0, -1.0], Mat::identity(2, 2), box2()).unwrap()
}

fn model_err(e: QpError) -> ModelError {
    match e {
        QpError::Data(m) => m,
        other => panic!("expected a model error, got {other:?}"),
    }
}

#[test]
fn invalid_hessians_are_rejected() {
    let e = ParametricQp::new(
        mat![[2.0, 1.0], [0.0, 1.0]],
        vec![0.0; 2],
        Mat::zeros(2, 0),
        box2(),
    )
    .unwrap_err();
    assert!(matches!(model_err(e), ModelError::NotSymmetric { name, .. } if name == "H"));
    let e = ParametricQp::new(
        mat![[1.0, 2.0], [2.0, 1.0]],
        vec![0.0; 2],
        Mat::zeros(2, 0),
        box2(),
    )
    .unwrap_err();
    assert!(matches!(model_err(e), ModelError::NotPositiveDefinite { name, .. } if name == "H"));
    let e = ParametricQp::new(
        mat![[1.0, 0.0], [0.0, 0.0]],
        vec![0.0; 2],
        Mat::zeros(2, 0),
        box2(),
    )
    .unwrap_err();
    assert!(matches!(
        model_err(e),
        ModelError::NotPositiveDefinite { .. }
    ));
    let e = ParametricQp::new(
        mat![[f64::NAN, 0.0], [0.0, 1.0]],
        vec![0.0; 2],
        Mat::zeros(2, 0),
        box2(),
    )
    .unwrap_err();
    assert!(matches!(model_err(e), ModelError::NonFinite { name, .. } if name == "H"));
    let e =
        ParametricQp::new(Mat::zeros(2, 3), vec![0.0; 2], Mat::zeros(2, 0), box2()).unwrap_err();
    assert!(matches!(model_err(e), ModelError::Shape { name, .. } if name == "H"));
}

#[test]
fn shape_and_nan_errors_name_the_field() {
    let e = ParametricQp::new(h2(), vec![0.0; 3], Mat::zeros(2, 0), box2()).unwrap_err();
    assert!(matches!(model_err(e), ModelError::Shape { name, .. } if name == "q0"));
    let e = ParametricQp::new(h2(), vec![0.0, f64::NAN], Mat::zeros(2, 0), box2()).unwrap_err();
    assert!(matches!(model_err(e), ModelError::NonFinite { name, .. } if name == "q0"));
    let e = ParametricQp::new(h2(), vec![0.0; 2], Mat::zeros(3, 1), box2()).unwrap_err();
    assert!(matches!(model_err(e), ModelError::Shape { name, .. } if name == "F"));
    let e =
        ParametricQp::new(h2(), vec![0.0; 2], mat![[1.0], [f64::INFINITY]], box2()).unwrap_err();
    assert!(matches!(model_err(e), ModelError::NonFinite { name, .. } if name == "F"));
    let e = ParametricQp::new(h2(), vec![0.0; 2], Mat::zeros(2, 0), BoxSet::whole(3)).unwrap_err();
    assert!(matches!(model_err(e), ModelError::Shape { name, .. } if name == "Z"));
    // θ: length and finiteness, checked outside the hot loop.
    let qp = qp2();
    assert!(matches!(
        model_err(qp.check_theta(&[0.0]).unwrap_err()),
        ModelError::Shape { .. }
    ));
    assert!(matches!(
        model_err(qp.check_theta(&[0.0, f64::NAN]).unwrap_err()),
        ModelError::NonFinite { .. }
    ));
}

#[test]
fn empty_or_inverted_boxes_are_rejected() {
    let to_qp = |e: ModelError| -> QpError { e.into() };
    for (lo, up) in [
        (vec![1.0], vec![0.0]),
        (vec![f64::INFINITY], vec![f64::INFINITY]),
        (vec![f64::NEG_INFINITY], vec![f64::NEG_INFINITY]),
        (vec![f64::NAN], vec![1.0]),
        (vec![0.0, 0.0], vec![1.0]),
    ] {
        let e = to_qp(BoxSet::new(lo, up).unwrap_err());
        assert!(matches!(model_err(e), ModelError::InvalidSet { .. }));
    }
}

#[test]
fn bad_method_parameters_are_rejected() {
    for a in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = ProjectedGradient::new(qp2(), StepRule::Fixed(a)).unwrap_err();
        assert!(
            // The file's key (`{ method = "pg", step = … }`).
            matches!(e, QpError::Parameter { ref name, .. } if name == "step"),
            "{e}"
        );
    }
    for rho in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = Admm::new(
            qp2(),
            AdmmParams {
                penalty: Penalty::Fixed(rho),
                relaxation: 1.0,
            },
        )
        .unwrap_err();
        assert!(
            matches!(e, QpError::Parameter { ref name, .. } if name == "rho"),
            "{e}"
        );
    }
    for alpha in [0.0, -0.5, 2.5, f64::NAN] {
        let e = Admm::new(
            qp2(),
            AdmmParams {
                penalty: Penalty::Optimal,
                relaxation: alpha,
            },
        )
        .unwrap_err();
        assert!(
            matches!(e, QpError::Parameter { ref name, .. } if name == "alpha"),
            "{e}"
        );
    }
    for tol in [0.0, -1.0, 1.5, f64::NAN] {
        let e = ReferenceSolver::new(
            &qp2(),
            ReferenceSettings {
                tol,
                ..ReferenceSettings::default()
            },
        )
        .unwrap_err();
        assert!(
            matches!(e, QpError::Parameter { ref name, .. } if name == "tol"),
            "{e}"
        );
    }
    let s = ReferenceSettings {
        polish_tol: 0.0,
        ..ReferenceSettings::default()
    };
    assert!(matches!(
        ReferenceSolver::new(&qp2(), s),
        Err(QpError::Parameter { .. })
    ));
}

#[test]
fn reference_rejects_bad_parameters() {
    let mut r = ReferenceSolver::new(&qp2(), ReferenceSettings::default()).unwrap();
    assert!(matches!(
        model_err(r.solve(&[0.0, f64::NAN]).unwrap_err()),
        ModelError::NonFinite { .. }
    ));
    assert!(matches!(
        model_err(r.solve(&[0.0]).unwrap_err()),
        ModelError::Shape { .. }
    ));
    assert!(matches!(
        model_err(r.solve_q(&[0.0; 3]).unwrap_err()),
        ModelError::Shape { .. }
    ));
    // Still usable afterwards.
    assert!(r.solve(&[0.0, 0.0]).unwrap().kkt_residual < 1e-12);
}

/// NaN in θ reaches the iterate and the drivers report it.
fn nan_is_a_status<M: IterationMap>(m: &M) {
    let mut s = m.new_state();
    m.load(&mut s, &[f64::NAN, 0.0]);
    m.cold_start(&mut s);
    let r = run_fixed(m, &mut s, 5);
    assert_eq!(r.status, RunStatus::NonFinite, "{}", m.name());
    let mut s = m.new_state();
    m.load(&mut s, &[0.0, f64::NAN]);
    m.warm_start(&mut s, &[0.0, 0.0], None);
    let r = run_until(m, &mut s, 100, |_, _| None);
    assert_eq!(
        (r.status, r.iterations),
        (RunStatus::NonFinite, 1),
        "{}",
        m.name()
    );
}

#[test]
fn nan_in_theta_is_reported_not_panicked() {
    // A box with finite bounds: the clamp must not hide the NaN.
    nan_is_a_status(&Fista::new(qp2()));
    nan_is_a_status(&Admm::new(qp2(), AdmmParams::default()).unwrap());
    // NaN in the ADMM warm-start dual as well.
    let admm = Admm::new(qp2(), AdmmParams::default()).unwrap();
    let mut s = admm.new_state();
    admm.warm_start(&mut s, &[0.0, 0.0], Some(&[f64::NAN, 0.0]));
    assert_eq!(run_fixed(&admm, &mut s, 3).status, RunStatus::NonFinite);
    // Projected gradient on an unbounded Z (its box clamp is lti-model's; see the crate report).
    let qp =
        ParametricQp::new(h2(), vec![1.0, -1.0], Mat::identity(2, 2), BoxSet::whole(2)).unwrap();
    nan_is_a_status(&ProjectedGradient::new(qp, StepRule::InverseL).unwrap());
}
