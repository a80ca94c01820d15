//! (e) Bad input: typed errors naming the field, and the estimator unchanged after an error.

use faer::{Mat, mat};
use lti_model::{BoxSet, ModelError};
use mhe_core::{Estimator, KalmanFilter, MheConfig, MheError, MheEstimator, MheSets};
use qp_iter::pg::{ProjectedGradient, StepRule};

use crate::common::{Fixture, case_study, simulate};

fn build(
    f: &Fixture,
    cfg: &MheConfig,
    sets: &MheSets,
    prior: &[f64],
) -> mhe_core::Result<MheEstimator<ProjectedGradient>> {
    MheEstimator::new(&f.sys, sets, cfg, prior, |qp| {
        ProjectedGradient::new(qp, StepRule::InverseL)
    })
}

fn model_name(e: MheError) -> String {
    match e {
        MheError::Model(ModelError::Shape { name, .. })
        | MheError::Model(ModelError::NotPositiveDefinite { name, .. })
        | MheError::Model(ModelError::NotSymmetric { name, .. })
        | MheError::Model(ModelError::NonFinite { name, .. }) => name,
        other => panic!("expected a model error, got {other:?}"),
    }
}

#[test]
fn configuration_errors_name_the_field() {
    let f = case_study(5, 10, false);
    let ok = |cfg: &MheConfig| build(&f, cfg, &f.sets, &f.prior);
    assert!(ok(&f.config).is_ok());

    let mut c = f.config.clone();
    c.horizon = 0;
    assert!(matches!(
        ok(&c).unwrap_err(),
        MheError::OutOfRange {
            name: "horizon",
            ..
        }
    ));
    for eta in [1.0, 1.5, -0.1, f64::NAN] {
        let mut c = f.config.clone();
        c.eta = eta;
        assert!(
            matches!(
                ok(&c).unwrap_err(),
                MheError::OutOfRange { name: "eta", .. }
            ),
            "η = {eta}"
        );
    }
    // K = 0 cannot reach the estimator: the config holds a `qp_iter::Iterations`.
    assert_eq!(
        qp_iter::Iterations::new(0),
        Err(qp_iter::IterationsError::Zero)
    );

    // Q, R, P: wrong shape (the paper's "Q = I⁴" read literally is a trap: n_w = 5), indefinite.
    let mut c = f.config.clone();
    c.q = Mat::identity(4, 4);
    assert_eq!(model_name(ok(&c).unwrap_err()), "Q");
    let mut c = f.config.clone();
    c.q[(2, 2)] = -1.0;
    assert_eq!(model_name(ok(&c).unwrap_err()), "Q");
    let mut c = f.config.clone();
    c.r = mat![[0.0]];
    assert_eq!(model_name(ok(&c).unwrap_err()), "R");
    let mut c = f.config.clone();
    c.p = Mat::identity(3, 3);
    assert_eq!(model_name(ok(&c).unwrap_err()), "P");
    let mut c = f.config.clone();
    c.p[(0, 1)] += 1.0;
    assert_eq!(model_name(ok(&c).unwrap_err()), "P");

    // Prior.
    assert!(matches!(
        build(&f, &f.config, &f.sets, &[1.0, 2.0]).unwrap_err(),
        MheError::Length {
            name: "prior",
            expected: 4,
            actual: 2
        }
    ));
    assert!(matches!(
        build(&f, &f.config, &f.sets, &[1.0, f64::NAN, 0.0, 0.0]).unwrap_err(),
        MheError::NonFinite {
            name: "prior",
            index: 1,
            ..
        }
    ));

    // Sets: wrong dimension; bounded 𝒳 or 𝒴 are general rows of the QP (supported).
    let mut s = f.sets.clone();
    s.disturbance = BoxSet::symmetric(&[0.1; 4]).unwrap();
    assert_eq!(
        model_name(build(&f, &f.config, &s, &f.prior).unwrap_err()),
        "sets.disturbance"
    );
    let mut s = f.sets.clone();
    s.state = BoxSet::symmetric(&[100.0; 4]).unwrap();
    s.output = BoxSet::symmetric(&[100.0]).unwrap();
    assert!(build(&f, &f.config, &s, &f.prior).is_ok());
    let mut s = f.sets.clone();
    s.output = BoxSet::symmetric(&[100.0, 1.0]).unwrap_or_else(|_| unreachable!());
    assert_eq!(
        model_name(build(&f, &f.config, &s, &f.prior).unwrap_err()),
        "sets.output"
    );

    // η = 0 drops all but the newest stage: x̂ ∈ ℝ⁴ from one scalar output is not
    // determined, H_c is singular, and the error says so instead of running a void QP.
    let mut c = f.config.clone();
    c.eta = 0.0;
    assert!(matches!(
        ok(&c).unwrap_err(),
        MheError::NotStronglyConvex { window: 1, .. }
    ));

    // A factory error is passed through.
    let e = MheEstimator::new(&f.sys, &f.sets, &f.config, &f.prior, |qp| {
        ProjectedGradient::new(qp, StepRule::Fixed(-1.0))
    })
    .unwrap_err();
    assert!(matches!(e, MheError::Qp(_)), "{e:?}");
}

/// Runs estimate/push over the data, injecting bad pushes at the given times; the
/// estimates must equal a clean run's.
fn run_with_bad_pushes<E: Estimator<Error = MheError>>(
    mut est: E,
    us: &[Vec<f64>],
    ys: &[Vec<f64>],
    inject: bool,
) -> Vec<Vec<f64>> {
    let mut out = Vec::new();
    for t in 0..us.len() {
        if inject && t % 2 == 0 {
            // Before estimate (push would otherwise run it).
            let mut bad_y = ys[t].clone();
            bad_y[0] = f64::NAN;
            assert!(matches!(
                est.push(&us[t], &bad_y).unwrap_err(),
                MheError::NonFinite {
                    name: "y",
                    index: 0,
                    ..
                }
            ));
        }
        out.push(est.estimate().unwrap().to_vec());
        if inject {
            let long_u: Vec<f64> = us[t].iter().copied().chain([0.0]).collect();
            assert!(matches!(
                est.push(&long_u, &ys[t]).unwrap_err(),
                MheError::Length { name: "u", .. }
            ));
            assert!(matches!(
                est.push(&us[t], &[]).unwrap_err(),
                MheError::Length {
                    name: "y",
                    expected: 1,
                    actual: 0
                }
            ));
            let mut bad_u = us[t].clone();
            bad_u[1] = f64::INFINITY;
            assert!(matches!(
                est.push(&bad_u, &ys[t]).unwrap_err(),
                MheError::NonFinite {
                    name: "u",
                    index: 1,
                    ..
                }
            ));
            assert_eq!(
                est.estimate().unwrap(),
                &out[t][..],
                "t = {t}: estimate changed by a failed push"
            );
        }
        est.push(&us[t], &ys[t]).unwrap();
    }
    out
}

#[test]
fn bad_measurements_and_inputs_leave_the_estimator_unchanged() {
    let f = case_study(3, 5, true);
    let (us, ys, _) = simulate(&f, 10, 3);
    let clean = run_with_bad_pushes(
        build(&f, &f.config, &f.sets, &f.prior).unwrap(),
        &us,
        &ys,
        false,
    );
    let dirty = run_with_bad_pushes(
        build(&f, &f.config, &f.sets, &f.prior).unwrap(),
        &us,
        &ys,
        true,
    );
    assert_eq!(clean, dirty);

    let kf = || {
        KalmanFilter::matching_mhe(&f.sys, &f.prior, 0.8, &f.config.p, &f.config.q, &f.config.r)
            .unwrap()
    };
    let clean = run_with_bad_pushes(kf(), &us, &ys, false);
    let dirty = run_with_bad_pushes(kf(), &us, &ys, true);
    assert_eq!(clean, dirty);

    let mut mhe = build(&f, &f.config, &f.sets, &f.prior).unwrap();
    assert!(matches!(
        mhe.reset(&[0.0; 3]).unwrap_err(),
        MheError::Length { name: "prior", .. }
    ));
    assert_eq!(mhe.initial_prior(), &f.prior[..]);
}

#[test]
fn kalman_configuration_errors() {
    let f = case_study(3, 5, false);
    let (p, q, r) = (&f.config.p, &f.config.q, &f.config.r);
    assert!(matches!(
        KalmanFilter::matching_mhe(&f.sys, &f.prior, 1.0, p, q, r).unwrap_err(),
        MheError::OutOfRange { name: "eta", .. }
    ));
    assert_eq!(
        model_name(
            KalmanFilter::matching_mhe(&f.sys, &f.prior, 0.8, p, &Mat::identity(4, 4), r)
                .unwrap_err()
        ),
        "Q"
    );
    assert!(matches!(
        KalmanFilter::matching_mhe(&f.sys, &[0.0], 0.8, p, q, r).unwrap_err(),
        MheError::Length { name: "prior", .. }
    ));
    // Singular measurement noise: R̄ = F Σ_w,22 Fᵀ + Σ_v = 0.
    let e = KalmanFilter::new(
        &f.sys,
        &f.prior,
        Mat::identity(4, 4),
        Mat::zeros(5, 5),
        mat![[0.0]],
    )
    .unwrap_err();
    assert!(
        matches!(e, MheError::Model(ModelError::NotPositiveDefinite { .. })),
        "{e:?}"
    );
    let e = KalmanFilter::new(
        &f.sys,
        &f.prior,
        Mat::identity(4, 4),
        Mat::identity(5, 5),
        mat![[-1.0]],
    )
    .unwrap_err();
    assert_eq!(model_name(e), "v_cov");
}
