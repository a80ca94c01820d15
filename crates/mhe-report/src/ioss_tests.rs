//! The δ-IOSS certificate of a scenario on a double integrator: the typed errors, the one
//! verdict and the hints (each checked against a hand computation).

#![allow(clippy::unwrap_used)]

use super::*;

/// A double integrator with y = x₁, with or without `[mhe]` (η = 0.8).
fn scenario(mhe: bool) -> Scenario {
    let mut text = String::from(
        r#"name = "double-integrator"
        plant = { a = [[1.0, 0.1], [0.0, 1.0]], b = [[0.005], [0.1]], c = [[1.0, 0.0]] }
        sets = { input = { lower = -1, upper = 1 }, disturbance = { lower = -0.01, upper = 0.01 } }
        simulation = { x0 = [1.0, 0.0], steps = 20 }
"#,
    );
    if mhe {
        text.push_str("mhe = { horizon = 5, eta = 0.8, iterations = 20 }\n");
    }
    Scenario::from_toml_str(&text).unwrap()
}

#[test]
fn eta_is_required_and_checked_before_any_solve() {
    let none = ioss_certificate(&scenario(false), &IossRequest::default());
    assert_eq!(none.unwrap_err(), IossError::NoEta);
    let request = IossRequest {
        eta: Some(1.0),
        p: None,
    };
    let out_of_range = ioss_certificate(&scenario(true), &request).unwrap_err();
    assert_eq!(
        out_of_range,
        IossError::EtaOutOfRange {
            eta: 1.0,
            origin: EtaSource::Given
        }
    );
}

#[test]
fn a_supplied_p_of_the_wrong_shape_or_asymmetric_is_refused() {
    let p = |p: Mat<f64>| IossRequest {
        eta: None,
        p: Some(SuppliedP {
            p,
            source: "test".into(),
        }),
    };
    let e = ioss_certificate(&scenario(true), &p(Mat::identity(3, 3))).unwrap_err();
    assert!(matches!(e, IossError::PShape { rows: 3, nx: 2, .. }), "{e}");
    let mut asym = Mat::<f64>::identity(2, 2);
    asym[(0, 1)] = 0.5;
    let e = ioss_certificate(&scenario(true), &p(asym)).unwrap_err();
    assert!(matches!(e, IossError::PNotSymmetric { .. }), "{e}");
}

#[test]
fn the_computed_p_passes_and_a_tiny_supplied_p_fails_with_its_source() {
    let s = scenario(true);
    let ok = ioss_certificate(&s, &IossRequest::default()).unwrap();
    assert!(ok.passed && ok.failure.is_none() && ok.hint.is_none());
    assert_eq!(
        (ok.eta, ok.eta_source, ok.weights_source),
        (0.8, EtaSource::Scenario, WeightsSource::Scenario)
    );
    assert_eq!(ok.p_source, None);
    // No [mpc]: no L_π, and no closed loop to cover.
    assert!(ok.controller_lipschitz.is_none() && ok.controller_lipschitz_skipped.is_none());
    // P = 1e-12·I: the −CᵀRC and −Q terms dominate, LMI (2) is violated, P is kept in the
    // report with its eigenvalues, and the hint is to let P be computed.
    let tiny = IossRequest {
        eta: None,
        p: Some(SuppliedP {
            p: Mat::from_fn(2, 2, |i, j| if i == j { 1e-12 } else { 0.0 }),
            source: "my file".into(),
        }),
    };
    let bad = ioss_certificate(&s, &tiny).unwrap();
    assert!(!bad.passed);
    assert!(
        bad.failure
            .as_ref()
            .unwrap()
            .to_string()
            .contains("my file")
    );
    assert_eq!(bad.hint, Some(IossHint::OmitSuppliedP));
    assert_eq!(bad.p_source.as_deref(), Some("my file"));
    assert!(bad.certificate.is_some());
}

#[test]
fn an_infeasible_eta_fails_once_and_hints_the_smallest_feasible_one() {
    // η = 0 is infeasible: for x = (0, 1) ∈ ker C and w = 0, LMI (2) needs ‖Ax‖²_P ≤ 0, but
    // Ax = (0.1, 1) ≠ 0.
    let request = IossRequest {
        eta: Some(0.0),
        p: None,
    };
    let out = ioss_certificate(&scenario(true), &request).unwrap();
    assert!(!out.passed && out.certificate.is_none());
    assert!(matches!(out.failure, Some(IossFailure::Infeasible { .. })));
    match out.hint {
        // Feasible at η = 0.8 (the test above), so the smallest feasible η is in (0, 0.8].
        Some(IossHint::RaiseEta { eta_min }) => assert!(eta_min > 0.0 && eta_min <= 0.8),
        other => panic!("{other:?}"),
    }
}
