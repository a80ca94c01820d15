//! P for a disturbance input E of any rank (issue 11, item 6): noise on some states only,
//! the velocities of a mass chain, noise that reaches not every mode, and infeasible cases
//! with their precise reason.

use faer::{Mat, mat};
use lti_model::ioss::{self, LMI_RELATIVE_TOL};
use lti_model::{LmiFailure, LtiSystem, ModelError, riccati};

use super::ioss::sampled_violation;
use super::ioss_relative::lmi_and_scale_by_blocks;

fn lambda_extremes(m: &Mat<f64>) -> (f64, f64) {
    lti_model::matrix::sym_extreme_eigenvalues("m", m.as_ref()).unwrap()
}

/// 6 masses (m = 1) in a row between two walls, springs k = 1 between neighbours and to
/// the walls, dampers 0.05 parallel to every spring (Wang & Boyd's oscillating masses with
/// light damping); x = (p, v) ∈ ℝ¹², ZOH at Ts = 0.5; three input forces on masses 1, 3,
/// 5; w¹ ∈ ℝ⁶ enters the velocities only (E = [0; I₆]); y = the positions in `sensors`.
fn mass_chain(sensors: &[usize]) -> LtiSystem {
    let n = 6;
    let k = Mat::from_fn(n, n, |i, j| match i.abs_diff(j) {
        0 => 2.0,
        1 => -1.0,
        _ => 0.0,
    });
    let ac = Mat::from_fn(2 * n, 2 * n, |i, j| match (i < n, j < n) {
        (true, true) => 0.0,
        (true, false) => f64::from(u8::from(j - n == i)),
        (false, true) => -k[(i - n, j)],
        (false, false) => -0.05 * k[(i - n, j - n)],
    });
    let bc = Mat::from_fn(2 * n, 3, |i, j| f64::from(u8::from(i == n + 2 * j)));
    let (a, b) = riccati::zoh(ac.as_ref(), bc.as_ref(), 0.5).unwrap();
    let e = Mat::from_fn(2 * n, n, |i, j| f64::from(u8::from(i == n + j)));
    let c = Mat::from_fn(sensors.len(), 2 * n, |i, j| {
        f64::from(u8::from(j == sensors[i]))
    });
    let ny = sensors.len();
    LtiSystem::with_disturbance(a, b, c, e, Mat::identity(ny, ny)).unwrap()
}

/// trace(P) of max trace(P) s.t. LMI (2) ⪯ 0, P ⪰ 0 for `mass_chain(&[0, 2, 5])`, η = 0.8,
/// Q = I₉, R = I₃, solved outside this repository with cvxpy 1.7 + CLARABEL (A from
/// scipy.linalg.expm of the same A_c·0.5; its first row starts 0.7674911748437521,
/// 0.11115162976662737). The maximal solution P* attains it.
const CHAIN_SDP_MAX_TRACE: f64 = 3.5696853687424515;

#[test]
fn mass_chain_with_noise_on_the_velocities_gets_the_maximal_p() {
    let sys = mass_chain(&[0, 2, 5]);
    // The ZOH matches scipy's expm (independent of this crate's expm).
    assert!((sys.a()[(0, 0)] - 0.7674911748437521).abs() <= 1e-13);
    assert!((sys.a()[(0, 1)] - 0.11115162976662737).abs() <= 1e-13);
    assert!((sys.a()[(0, 6)] - 0.4486012311489629).abs() <= 1e-13);
    assert_eq!((sys.nx(), sys.nw1(), sys.nw2()), (12, 6, 3));
    let (q, r) = (Mat::<f64>::identity(9, 9), Mat::<f64>::identity(3, 3));
    let cert = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()).unwrap();
    assert_eq!(cert.method, ioss::METHOD_MAXIMAL);
    assert!(cert.lmi_relative_violation <= LMI_RELATIVE_TOL);
    assert!(cert.p_min_eigenvalue > 1e-3 * cert.p_max_eigenvalue);
    // Independent checks: (★) on random points; λ_max of the LMI assembled here.
    let v = sampled_violation(&sys, 0.8, &q, &r, &cert.p, 20_000, 3);
    assert!(v <= 1e-10, "sampled violation {v:e}");
    let (j, _) = lmi_and_scale_by_blocks(&sys, 0.8, &q, &r, &cert.p);
    let (_, j_max) = lambda_extremes(&j);
    assert!(j_max <= 1e-12, "λmax(J) = {j_max:e}");
    // Maximal: the SDP's maximal trace, and 1.01·P* is refused.
    let trace: f64 = (0..12).map(|i| cert.p[(i, i)]).sum();
    assert!(
        (trace - CHAIN_SDP_MAX_TRACE).abs() <= 1e-6 * CHAIN_SDP_MAX_TRACE,
        "trace P* = {trace}, SDP {CHAIN_SDP_MAX_TRACE}"
    );
    let bigger = &cert.p * 1.01;
    assert!(matches!(
        ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), bigger.as_ref()),
        Err(ModelError::LmiInfeasible {
            cause: LmiFailure::Violated { .. }
        })
    ));
}

/// P from cvxpy + CLARABEL for the case study with E = diag(1, 1, 0, 1) (η = 0.8, Q = I,
/// R = 1), outside this repository: maximise trace(P) s.t. J(P) + 1e-6·S(P) ⪯ 0, P ⪰ 0
/// (the script of `ioss_relative::SDP_P_MARGIN` with the zero column of E dropped: a w¹
/// entry that enters nothing only adds a decoupled −1 to the LMI).
const SDP_P_E1101: [[f64; 4]; 4] = [
    [
        0.6137714157319736,
        -0.10996408081611578,
        -0.36830462702260763,
        -0.24918221515978883,
    ],
    [
        -0.10996408081611578,
        0.9636979048253874,
        4.865680139341722,
        -0.07492725751519048,
    ],
    [
        -0.36830462702260763,
        4.865680139341722,
        89.66589424855452,
        -0.5839963871751906,
    ],
    [
        -0.24918221515978883,
        -0.07492725751519048,
        -0.5839963871751906,
        0.5200025464102911,
    ],
];
/// The same SDP with margin 0: the maximal trace.
const SDP_MAX_TRACE_E1101: f64 = 91.76372831207873;

#[test]
fn case_study_with_noise_on_three_states_gets_the_maximal_p() {
    let base = lti_model::presets::case_study_plant();
    let e = mat![
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 1.0]
    ];
    let sys = LtiSystem::with_disturbance(
        base.a().to_owned(),
        base.b().to_owned(),
        base.c().to_owned(),
        e,
        Mat::identity(1, 1),
    )
    .unwrap();
    let (q, r) = (Mat::<f64>::identity(5, 5), Mat::<f64>::identity(1, 1));
    let cert = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()).unwrap();
    assert_eq!(cert.method, ioss::METHOD_MAXIMAL);
    let p_sdp = Mat::from_fn(4, 4, |i, j| SDP_P_E1101[i][j]);
    let sdp = ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), p_sdp.as_ref()).unwrap();
    assert!(sdp.lmi_relative_violation < 0.0);
    let (gap_lo, gap_hi) = lambda_extremes(&(&cert.p - &p_sdp));
    let scale = cert.p_max_eigenvalue;
    assert!(
        gap_lo >= -1e-12 * scale && gap_hi <= 1e-5 * scale,
        "P* − P_sdp ∈ [{gap_lo:e}, {gap_hi:e}]"
    );
    let trace: f64 = (0..4).map(|i| cert.p[(i, i)]).sum();
    assert!(
        (trace - SDP_MAX_TRACE_E1101).abs() <= 1e-7 * SDP_MAX_TRACE_E1101,
        "trace P* = {trace}"
    );
    let v = sampled_violation(&sys, 0.8, &q, &r, &cert.p, 20_000, 4);
    assert!(v <= 1e-10, "sampled violation {v:e}");
}

/// Noise that reaches not every mode: no maximal P (P may grow without bound along the
/// unreached mode 0.5, since 0.5² < η), or none reachable from above (the unreached mode
/// 1.2, seen by C). The fictitious-disturbance construction gives a verified P.
#[test]
fn noise_that_reaches_not_every_mode_gets_a_verified_p() {
    for (a22, e) in [
        (0.5, mat![[1.0], [0.0]]),
        (1.2, mat![[1.0], [0.0]]),
        (0.5, Mat::<f64>::zeros(2, 0)),
    ] {
        let nw1 = e.ncols();
        let sys = LtiSystem::with_disturbance(
            mat![[0.9, 0.0], [0.0, a22]],
            mat![[1.0], [1.0]],
            mat![[1.0, 1.0]],
            e,
            Mat::identity(1, 1),
        )
        .unwrap();
        let (q, r) = (
            Mat::<f64>::identity(nw1 + 1, nw1 + 1),
            Mat::<f64>::identity(1, 1),
        );
        let cert = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref())
            .unwrap_or_else(|err| panic!("a22 = {a22}, nw1 = {nw1}: {err}"));
        assert_eq!(cert.method, ioss::METHOD_FICTITIOUS);
        assert!(cert.lmi_relative_violation <= LMI_RELATIVE_TOL);
        let v = sampled_violation(&sys, 0.8, &q, &r, &cert.p, 20_000, 5);
        assert!(v <= 1e-10, "a22 = {a22}: sampled violation {v:e}");
        let (j, _) = lmi_and_scale_by_blocks(&sys, 0.8, &q, &r, &cert.p);
        assert!(lambda_extremes(&j).1 <= 1e-12);
    }
}

/// Measuring p₁ + p₆ only hides every antisymmetric mode of the (symmetric) chain; with
/// light damping they decay slower than √0.8. The reason names the slowest one, computed
/// here independently on the antisymmetric subspace.
#[test]
fn hidden_chain_modes_are_a_precise_reason() {
    let base = mass_chain(&[0]);
    let c = Mat::from_fn(1, 12, |_, j| f64::from(u8::from(j == 0 || j == 5)));
    let sys = LtiSystem::with_disturbance(
        base.a().to_owned(),
        base.b().to_owned(),
        c,
        base.e().to_owned(),
        Mat::identity(1, 1),
    )
    .unwrap();
    // Antisymmetric subspace: p_i = −p_{7−i}, v_i = −v_{7−i} (orthonormal basis of 6 vectors).
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let basis = Mat::from_fn(12, 6, |i, j| {
        let (block, k, idx) = (j / 3, j % 3, i % 6);
        if i / 6 != block {
            0.0
        } else if idx == k {
            s
        } else if idx == 5 - k {
            -s
        } else {
            0.0
        }
    });
    let a_anti = basis.transpose() * sys.a() * &basis;
    assert!(
        (sys.a() * &basis - &basis * &a_anti).norm_max() < 1e-12,
        "not invariant"
    );
    let expected = lti_model::system::spectral_radius(a_anti.as_ref()).unwrap();
    assert!(expected > 0.8_f64.sqrt() && expected < 1.0);
    let (q, r) = (Mat::<f64>::identity(7, 7), Mat::<f64>::identity(1, 1));
    match ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()) {
        Err(ModelError::LmiInfeasible {
            cause: LmiFailure::UnobservableMode { modulus, eta },
        }) => {
            assert_eq!(eta, 0.8);
            assert!(
                (modulus - expected).abs() <= 1e-9,
                "{modulus} vs {expected}"
            );
        }
        other => panic!("expected UnobservableMode, got {other:?}"),
    }
    // Above |λ|² the same plant is feasible, with the same rank-deficient E.
    let eta = (expected * expected + 1.0) / 2.0;
    let cert = ioss::certify(&sys, eta, q.as_ref(), r.as_ref()).unwrap();
    assert!(cert.lmi_relative_violation <= LMI_RELATIVE_TOL);
}

#[test]
fn zero_eta_reason_on_the_case_study() {
    let sys = lti_model::presets::case_study_plant();
    let (q, r) = (Mat::<f64>::identity(5, 5), Mat::<f64>::identity(1, 1));
    match ioss::certify(&sys, 0.0, q.as_ref(), r.as_ref()) {
        Err(ModelError::LmiInfeasible {
            cause: LmiFailure::ZeroEtaNeedsDeadbeat { gain },
        }) => assert!(gain > 0.1, "gain {gain}"),
        other => panic!("expected ZeroEtaNeedsDeadbeat, got {other:?}"),
    }
}

/// When the construction cannot produce P, the message says where to supply one.
#[test]
fn failed_construction_points_to_mhe_p_and_p_file() {
    let sys = mass_chain(&[0, 2, 5]);
    let (q, r) = (Mat::<f64>::identity(9, 9), Mat::<f64>::identity(3, 3));
    let opts = ioss::IossOptions {
        max_iterations: 3,
        ..ioss::IossOptions::default()
    };
    let err = ioss::certify_with(&sys, 0.8, q.as_ref(), r.as_ref(), &opts).unwrap_err();
    assert!(matches!(err, ModelError::Numerical { .. }), "{err:?}");
    let text = err.to_string();
    assert!(
        text.contains("`mhe.p`") && text.contains("--p-file"),
        "{text}"
    );
    // A refused P names both ways of supplying a better one.
    let bad = Mat::<f64>::identity(12, 12);
    let text = ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), bad.as_ref())
        .unwrap_err()
        .to_string();
    assert!(
        text.contains("`mhe.p`") && text.contains("--p-file"),
        "{text}"
    );
}
