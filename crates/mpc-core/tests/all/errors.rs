//! Bad input: typed errors naming the field, no panics, outputs unchanged on error.

use faer::{Mat, mat};
use lti_model::{BoxSet, ModelError};
use mpc_core::{
    CondensedMpc, Controller, ExactMpc, MpcConfig, MpcError, SaturatedLqr, SuboptimalMpc, Terminal,
    WarmStart,
};
use qp_iter::fista::Fista;

use crate::common::*;

fn build(cfg: MpcConfig) -> MpcError {
    CondensedMpc::new(&case_study_system(), cfg).unwrap_err()
}

fn model_name(e: &MpcError) -> Option<&str> {
    match e {
        MpcError::Model(
            ModelError::Shape { name, .. }
            | ModelError::NonFinite { name, .. }
            | ModelError::NotSymmetric { name, .. }
            | ModelError::NotPositiveDefinite { name, .. }
            | ModelError::InvalidSet { name, .. },
        ) => Some(name),
        _ => None,
    }
}

/// The horizon and the weights Q_c, R_c: typed errors naming the field.
#[test]
fn setup_errors_name_the_weights() {
    let base = case_study_config;
    assert_eq!(
        build(MpcConfig {
            horizon: 0,
            ..base()
        }),
        MpcError::Horizon { value: 0 }
    );

    let e = build(MpcConfig {
        q_c: mat![
            [1.0, 0.5, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0]
        ],
        ..base()
    });
    assert!(
        matches!(e, MpcError::Model(ModelError::NotSymmetric { ref name, .. }) if name == "Q_c"),
        "{e}"
    );
    let mut q = Mat::<f64>::identity(4, 4);
    q[(2, 2)] = -0.1;
    let e = build(MpcConfig { q_c: q, ..base() });
    assert!(
        matches!(e, MpcError::NotPositiveSemidefinite { name: "Q_c", min_eigenvalue } if (min_eigenvalue + 0.1).abs() < 1e-12),
        "{e}"
    );
    assert_eq!(
        model_name(&build(MpcConfig {
            q_c: Mat::identity(3, 3),
            ..base()
        })),
        Some("Q_c")
    );
    let mut q = Mat::<f64>::identity(4, 4);
    q[(0, 0)] = f64::NAN;
    assert_eq!(
        model_name(&build(MpcConfig { q_c: q, ..base() })),
        Some("Q_c")
    );

    // R_c ⪰ 0 but singular: must be ≻ 0.
    let e = build(MpcConfig {
        r_c: mat![[1.0, 0.0], [0.0, 0.0]],
        ..base()
    });
    assert!(
        matches!(e, MpcError::Model(ModelError::NotPositiveDefinite { ref name, .. }) if name == "R_c"),
        "{e}"
    );
    assert_eq!(
        model_name(&build(MpcConfig {
            r_c: Mat::identity(3, 3),
            ..base()
        })),
        Some("R_c")
    );
}

/// The input and state sets and the terminal cost P_f: typed errors naming the field.
#[test]
fn setup_errors_name_the_sets_and_terminal_cost() {
    let base = case_study_config;
    assert_eq!(
        model_name(&build(MpcConfig {
            input_set: BoxSet::symmetric(&[1.0]).unwrap(),
            ..base()
        })),
        Some("input_set")
    );
    assert_eq!(
        model_name(&build(MpcConfig {
            state_set: Some(BoxSet::whole(3)),
            ..base()
        })),
        Some("state_set")
    );

    let mut p = Mat::<f64>::identity(4, 4);
    p[(1, 1)] = -1.0;
    let e = build(MpcConfig {
        terminal: Terminal::Given(p),
        ..base()
    });
    assert!(
        matches!(e, MpcError::NotPositiveSemidefinite { name: "P_f", .. }),
        "{e}"
    );
    assert_eq!(
        model_name(&build(MpcConfig {
            terminal: Terminal::Given(Mat::identity(2, 2)),
            ..base()
        })),
        Some("P_f")
    );

    // Finite state bounds are general rows of the QP (tests/all/constrained.rs); a state
    // set of the wrong dimension names its key.
    assert_eq!(
        model_name(&build(MpcConfig {
            state_set: Some(BoxSet::symmetric(&[5.0; 3]).unwrap()),
            ..base()
        })),
        Some("state_set")
    );
}

/// An unstabilisable plant (no DARE solution) and a bad LQR gain or weight: typed errors.
#[test]
fn dare_and_lqr_errors_name_the_field() {
    // (A, B) = (2, 0) is not stabilisable: the DARE has no stabilising solution.
    let sys = lti_model::LtiSystem::new(mat![[2.0]], mat![[0.0]], mat![[1.0]]).unwrap();
    let e = CondensedMpc::new(
        &sys,
        MpcConfig::new(3, mat![[1.0]], mat![[1.0]], BoxSet::whole(1)),
    )
    .unwrap_err();
    assert!(
        matches!(e, MpcError::Model(ModelError::Numerical { .. })),
        "{e}"
    );

    let e = SaturatedLqr::from_gain(mat![[1.0, 2.0]], BoxSet::whole(2)).unwrap_err();
    assert_eq!(model_name(&e), Some("input_set"));
    let e = SaturatedLqr::from_gain(mat![[1.0, f64::INFINITY]], BoxSet::whole(1)).unwrap_err();
    assert_eq!(model_name(&e), Some("K"));
    let sys = case_study_system();
    let e = SaturatedLqr::new(
        &sys,
        Mat::<f64>::identity(4, 4).as_ref(),
        mat![[0.1, 0.0], [0.0, -0.1]].as_ref(),
        BoxSet::whole(2),
    )
    .unwrap_err();
    assert_eq!(model_name(&e), Some("R_c"));
}

/// Every controller: wrong x̂ length, wrong u length, NaN / ∞ in x̂ → typed error, u unchanged.
fn check_call_errors(c: &mut dyn Controller<Error = MpcError>) {
    let (nx, nu) = (c.nx(), c.nu());
    let mut u = vec![7.0; nu];
    let e = c.control(&vec![0.0; nx + 1], &mut u).unwrap_err();
    assert_eq!(
        e,
        MpcError::Dimension {
            name: "x_hat",
            expected: nx,
            actual: nx + 1
        }
    );
    let e = c
        .control(&vec![0.0; nx], &mut vec![0.0; nu + 1])
        .unwrap_err();
    assert_eq!(
        e,
        MpcError::Dimension {
            name: "u",
            expected: nu,
            actual: nu + 1
        }
    );
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut x = vec![0.5; nx];
        x[nx - 1] = bad;
        let e = c.control(&x, &mut u).unwrap_err();
        assert!(
            matches!(e, MpcError::NonFinite { name: "x_hat", index, .. } if index == nx - 1),
            "{e}"
        );
    }
    assert!(u.iter().all(|v| *v == 7.0), "u changed on error");
    // Still usable afterwards.
    c.control(&vec![0.1; nx], &mut u).unwrap();
    assert!(u.iter().all(|v| v.is_finite() && *v != 7.0));
}

#[test]
fn control_call_errors() {
    let mpc = case_study_mpc();
    check_call_errors(&mut ExactMpc::new(&mpc).unwrap());
    check_call_errors(
        &mut SuboptimalMpc::new(&mpc, Fista::new(mpc.qp().clone()), 20, WarmStart::default())
            .unwrap(),
    );
    let sys = case_study_system();
    check_call_errors(
        &mut SaturatedLqr::new(
            &sys,
            Mat::<f64>::identity(4, 4).as_ref(),
            (Mat::<f64>::identity(2, 2) * 0.1).as_ref(),
            BoxSet::whole(2),
        )
        .unwrap(),
    );
    let mut exact = ExactMpc::new(&mpc).unwrap();
    assert!(matches!(
        exact.solve(&[1.0, f64::NAN, 0.0, 0.0]),
        Err(MpcError::NonFinite {
            name: "x_hat",
            index: 1,
            ..
        })
    ));
    assert!(matches!(
        mpc.cost(&[1.0], &[0.0; 20]),
        Err(MpcError::Dimension { name: "x_hat", .. })
    ));
    assert!(matches!(
        mpc.cost(&[1.0; 4], &[0.0; 19]),
        Err(MpcError::Dimension { name: "u_seq", .. })
    ));
}

#[test]
fn settings_name_the_key() {
    let sys = lti_model::LtiSystem::new(mat![[0.5]], mat![[1.0]], mat![[1.0]]).unwrap();
    let raw: mpc_core::RawMpc = lti_model::spec::format::parse("r = 0.1").unwrap();
    match mpc_core::MpcSettings::from_raw(&raw, &sys) {
        Err(lti_model::ModelError::Scenario { key, .. }) => assert_eq!(key, "mpc.horizon"),
        other => panic!("{other:?}"),
    }
    let raw: mpc_core::RawMpc = lti_model::spec::format::parse("horizon = 3\nr = -1.0").unwrap();
    match mpc_core::MpcSettings::from_raw(&raw, &sys) {
        Err(lti_model::ModelError::Scenario { key, .. }) => assert_eq!(key, "mpc.r"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn errors_display_the_field_and_fix() {
    let e = build(MpcConfig {
        horizon: 0,
        ..case_study_config()
    });
    assert!(e.to_string().contains("N ≥ 1"));
    let e = MpcError::Dimension {
        name: "x_hat",
        expected: 4,
        actual: 3,
    };
    assert_eq!(e.to_string(), "`x_hat` has length 3, expected 4");
}
