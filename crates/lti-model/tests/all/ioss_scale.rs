//! LMI (2) at any scale (issue 25, item 1): a table of plants × weight ratios × common
//! weight scalings 1e-12 … 1e12 × diagonal unit changes spanning 10⁶, against the maximal
//! P pinned from an independent SDP solve; and an infeasible η refused with the exact
//! boundary.

use faer::{Mat, MatRef, mat};
use lti_model::ioss::{self, LMI_RELATIVE_TOL};
use lti_model::{LmiFailure, LtiSystem, ModelError};

/// AFTI-16 (MATLAB MPC Toolbox demo `afti16`; Kapasouris, Athans, Stein 1990) with the
/// forward speed in units of 100 ft/s, ZOH at T_s = 0.05 s; outputs α and θ.
pub fn afti16() -> LtiSystem {
    let a_c = mat![
        [-0.0151, -60.5651, 0.0, -32.174],
        [-0.0001, -1.3411, 0.9929, 0.0],
        [0.00018, 43.2541, -0.86939, 0.0],
        [0.0, 0.0, 1.0, 0.0]
    ];
    let b_c = mat![
        [-2.516, -13.136],
        [-0.1689, -0.2514],
        [-17.251, -1.5766],
        [0.0, 0.0]
    ];
    // speed/100: x₁' = x₁/100, A' = SAS⁻¹, B' = SB with S = diag(0.01, 1, 1, 1).
    let s = [0.01, 1.0, 1.0, 1.0];
    let a_c = Mat::from_fn(4, 4, |i, j| s[i] * a_c[(i, j)] / s[j]);
    let b_c = Mat::from_fn(4, 2, |i, j| s[i] * b_c[(i, j)]);
    let (a, b) = lti_model::riccati::zoh(a_c.as_ref(), b_c.as_ref(), 0.05).unwrap();
    LtiSystem::new(a, b, mat![[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]).unwrap()
}

fn plant(name: &str) -> LtiSystem {
    match name {
        "case_study" => lti_model::presets::case_study_plant(),
        "afti16" => afti16(),
        "double_integrator" => {
            let (a, b) = lti_model::riccati::zoh(
                mat![[0.0, 1.0], [0.0, 0.0]].as_ref(),
                mat![[0.0], [1.0]].as_ref(),
                0.1,
            )
            .unwrap();
            LtiSystem::new(a, b, mat![[1.0, 0.0]]).unwrap()
        }
        _ => unreachable!(),
    }
}

/// The maximal P of LMI (2) at η = 0.8, Q = I, R = (r/q)·I, E = I, F = I, printed by
/// `scripts/lmi2_reference.py` (CVXPY 1.7 + Clarabel 0.11, `maximise trace(P)` subject to
/// LMI (2) and P ⪰ 0, gap and feasibility tolerances 1e-10, a second pass in the
/// coordinates balanced by the first; Clarabel reported `optimal` for 6 of the 9 and
/// `optimal_inaccurate` for r/q = 1e4 of each plant). AFTI-16's P is nearly singular
/// (λ_min/λ_max ≈ 1e-8), so the SDP's entries are accurate to ≈ 1e-6 in the Jacobi-scaled distance below (measured: 6e-7).
const PINNED: &[(&str, f64, &[&[f64]])] = &[
    (
        "case_study",
        1.000000e-04,
        &[
            &[
                5.785499213350e-01,
                -8.027891062827e-02,
                1.042561627162e-02,
                -2.148424689330e-01,
            ],
            &[
                -8.027891062827e-02,
                6.796663732085e-01,
                5.035893345954e-02,
                -2.640088644566e-02,
            ],
            &[
                1.042561627162e-02,
                5.035893345954e-02,
                9.773938324064e-01,
                -3.145465086617e-02,
            ],
            &[
                -2.148424689330e-01,
                -2.640088644566e-02,
                -3.145465086617e-02,
                2.914655198992e-01,
            ],
        ],
    ),
    (
        "case_study",
        1.000000e+00,
        &[
            &[
                5.807517828690e-01,
                -7.815614824749e-02,
                9.290309956597e-03,
                -2.359694955258e-01,
            ],
            &[
                -7.815614824749e-02,
                6.877384847051e-01,
                4.538110909810e-02,
                -5.358438534471e-02,
            ],
            &[
                9.290309956597e-03,
                4.538110909810e-02,
                9.813930780226e-01,
                -1.591905767896e-02,
            ],
            &[
                -2.359694955258e-01,
                -5.358438534471e-02,
                -1.591905767896e-02,
                5.028547477571e-01,
            ],
        ],
    ),
    (
        "case_study",
        1.000000e+04,
        &[
            &[
                5.814588531058e-01,
                -7.726480484392e-02,
                8.604989477601e-03,
                -2.429978734688e-01,
            ],
            &[
                -7.726480484392e-02,
                6.922062689997e-01,
                4.249879115461e-02,
                -6.620567017971e-02,
            ],
            &[
                8.604989477601e-03,
                4.249879115461e-02,
                9.835722871778e-01,
                -6.618962088505e-03,
            ],
            &[
                -2.429978734688e-01,
                -6.620567017971e-02,
                -6.618962088505e-03,
                5.772523789355e-01,
            ],
        ],
    ),
    (
        "afti16",
        1.000000e-04,
        &[
            &[
                1.120026358312e-06,
                6.772764569726e-04,
                -9.894375633596e-05,
                -2.459677477699e-07,
            ],
            &[
                6.772764569726e-04,
                4.106260967819e-01,
                -6.003605676472e-02,
                2.578154130482e-04,
            ],
            &[
                -9.894375633596e-05,
                -6.003605676472e-02,
                8.787259270672e-03,
                -9.338523763806e-05,
            ],
            &[
                -2.459677477699e-07,
                2.578154130482e-04,
                -9.338523763806e-05,
                4.980593305397e-04,
            ],
        ],
    ),
    (
        "afti16",
        1.000000e+00,
        &[
            &[
                1.322258334456e-06,
                5.861220732145e-04,
                -1.065057890970e-04,
                -6.889383298297e-06,
            ],
            &[
                5.861220732145e-04,
                6.099874663231e-01,
                -6.253889736701e-02,
                2.694728818277e-02,
            ],
            &[
                -1.065057890970e-04,
                -6.253889736701e-02,
                1.639840360535e-02,
                -3.666630213626e-02,
            ],
            &[
                -6.889383298297e-06,
                2.694728818277e-02,
                -3.666630213626e-02,
                4.614021858886e-01,
            ],
        ],
    ),
    (
        "afti16",
        1.000000e+04,
        &[
            &[
                1.375041151746e-06,
                5.600209861940e-04,
                -1.129566131754e-04,
                -3.904055753022e-06,
            ],
            &[
                5.600209861940e-04,
                6.933332253069e-01,
                -5.859897724346e-02,
                1.924573576072e-02,
            ],
            &[
                -1.129566131754e-04,
                -5.859897724346e-02,
                1.755539714466e-02,
                -4.091063075468e-02,
            ],
            &[
                -3.904055753022e-06,
                1.924573576072e-02,
                -4.091063075468e-02,
                5.925291755261e-01,
            ],
        ],
    ),
    (
        "double_integrator",
        1.000000e-04,
        &[
            &[4.983983488533e-04, -2.484573924901e-04],
            &[-2.484573924901e-04, 2.231433804153e-04],
        ],
    ),
    (
        "double_integrator",
        1.000000e+00,
        &[
            &[4.582721629626e-01, -7.596009651010e-02],
            &[-7.596009651010e-02, 3.826489201300e-02],
        ],
    ),
    (
        "double_integrator",
        1.000000e+04,
        &[
            &[5.880264939113e-01, -8.297144433737e-02],
            &[-8.297144433737e-02, 3.956321754706e-02],
        ],
    ),
];

/// max_ij |P − P_ref|_ij / √(P_ref,ii·P_ref,jj): the distance in the Jacobi-scaled
/// coordinates (unchanged by a change of units of the states or a common weight scaling).
fn metric_distance(p: MatRef<'_, f64>, p_ref: MatRef<'_, f64>) -> f64 {
    let n = p.nrows();
    let mut worst = 0.0_f64;
    for i in 0..n {
        for j in 0..n {
            let d = (p[(i, j)] - p_ref[(i, j)]).abs() / (p_ref[(i, i)] * p_ref[(j, j)]).sqrt();
            worst = worst.max(d);
        }
    }
    worst
}

/// The plant in units x = T x̃ (T diagonal): Ã = T⁻¹AT, C̃ = CT, Ẽ = T⁻¹ (w¹ in the old units).
fn in_units(sys: &LtiSystem, t: &[f64]) -> LtiSystem {
    let n = sys.nx();
    LtiSystem::with_disturbance(
        Mat::from_fn(n, n, |i, j| sys.a()[(i, j)] * t[j] / t[i]),
        Mat::from_fn(n, sys.nu(), |i, j| sys.b()[(i, j)] / t[i]),
        Mat::from_fn(sys.ny(), n, |i, j| sys.c()[(i, j)] * t[j]),
        Mat::from_fn(n, n, |i, j| if i == j { 1.0 / t[i] } else { 0.0 }),
        Mat::identity(sys.ny(), sys.ny()),
    )
    .unwrap()
}

#[test]
fn maximal_p_found_at_every_weight_and_unit_scaling() {
    let units: [&[f64]; 3] = [&[1.0; 4], &[1.0, 1e3, 1e-3, 1e3], &[1e-3, 1e3, 1.0, 1e-3]];
    let mut worst: f64 = 0.0;
    let mut cases = 0;
    for &(name, ratio, rows) in PINNED {
        let base = plant(name);
        let n = base.nx();
        let ny = base.ny();
        let p_ref = Mat::from_fn(n, n, |i, j| rows[i][j]);
        for scale in [1e-12, 1e-6, 1.0, 1e6, 1e12] {
            for t in units {
                let t = &t[..n];
                let sys = in_units(&base, t);
                let q = Mat::<f64>::identity(n + ny, n + ny) * scale;
                let r = Mat::<f64>::identity(ny, ny) * (scale * ratio);
                let cert = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()).unwrap_or_else(|e| {
                    panic!("{name} r/q = {ratio}, scale {scale}, units {t:?}: {e}")
                });
                assert!(
                    cert.lmi_relative_violation < 0.0,
                    "{name} r/q = {ratio}, scale {scale}, units {t:?}: μ = {} (no margin)",
                    cert.lmi_relative_violation
                );
                let expected = Mat::from_fn(n, n, |i, j| scale * t[i] * p_ref[(i, j)] * t[j]);
                let d = metric_distance(cert.p.as_ref(), expected.as_ref());
                worst = worst.max(d);
                cases += 1;
                assert!(
                    d < 1e-5,
                    "{name} r/q = {ratio}, scale {scale}, units {t:?}: P differs from the SDP \
                     maximal P by {d:e} in its metric"
                );
            }
        }
    }
    assert_eq!(cases, 9 * 5 * 3);
    eprintln!("largest distance from the SDP solution over {cases} cases: {worst:e}");
}

/// The stand-in with the weights of issue 25 (`mhe.r = 1e4`, a very small `mhe.q`): found.
#[test]
fn stand_in_with_extreme_weight_ratios() {
    let sys = lti_model::presets::case_study_plant();
    for (q, r) in [
        (1.0, 1e4),
        (1e-6, 1.0),
        (1.0, 1e6),
        (1e-12, 1e-12),
        (1e12, 1e12),
        (1e-12, 1e-8),
        (1e8, 1e12),
    ] {
        let qm = Mat::<f64>::identity(5, 5) * q;
        let rm = Mat::<f64>::identity(1, 1) * r;
        let cert = ioss::certify(&sys, 0.8, qm.as_ref(), rm.as_ref())
            .unwrap_or_else(|e| panic!("q = {q}, r = {r}: {e}"));
        assert!(
            cert.lmi_relative_violation <= LMI_RELATIVE_TOL,
            "q = {q}, r = {r}"
        );
    }
}

/// An unobservable mode λ = 0.9 makes every η ≤ 0.81 infeasible: refused with the exact
/// boundary |λ|², which the bisection confirms.
#[test]
fn infeasible_eta_refused_with_the_exact_boundary() {
    let sys = LtiSystem::new(
        mat![[0.5, 0.0], [0.3, 0.9]],
        mat![[1.0], [0.0]],
        mat![[1.0, 0.0]],
    )
    .unwrap();
    let (q, r) = (Mat::<f64>::identity(3, 3), Mat::<f64>::identity(1, 1));
    match ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()) {
        Err(ModelError::LmiInfeasible {
            cause: LmiFailure::UnobservableMode { modulus, .. },
        }) => assert!(
            (modulus * modulus - 0.81).abs() < 1e-12,
            "|λ|² = {}",
            modulus * modulus
        ),
        other => panic!("expected the unobservable mode, got {other:?}"),
    }
    let b = ioss::min_feasible_eta(&sys, q.as_ref(), r.as_ref(), 1e-6).unwrap();
    assert!(
        b.infeasible_below <= 0.81 && b.certificate.eta >= 0.81,
        "{b:?}"
    );
    assert!(
        b.certificate.eta - 0.81 < 1e-5,
        "smallest feasible η = {}",
        b.certificate.eta
    );
}
