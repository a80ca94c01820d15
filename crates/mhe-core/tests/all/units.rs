//! Issue 37, item 7: AFTI-16 with its forward speed in ft/s (the MATLAB demo's units) and
//! Q = R = I. The window's H_c is ill-conditioned by the states' units; the refusal names
//! `plant.a` and the diagonal scaling to apply, not "weights too unequal" on `mhe.q`.

use faer::{Mat, mat};
use lti_model::{LtiSystem, ModelError};
use mhe_core::{MheError, MheSets, MheSettings};

/// AFTI-16 (MATLAB MPC Toolbox demo `afti16`), speed in ft/s, ZOH at 0.05 s, outputs α, θ.
fn afti16_ft_per_s() -> LtiSystem {
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
    let (a, b) = lti_model::riccati::zoh(a_c.as_ref(), b_c.as_ref(), 0.05).unwrap();
    LtiSystem::new(a, b, mat![[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]).unwrap()
}

#[test]
fn afti16_in_ft_per_s_blames_the_units_with_the_scaling() {
    let sys = afti16_ft_per_s();
    let raw: mhe_core::RawMhe =
        lti_model::spec::format::parse("horizon = 10\neta = 0.8\niterations = 5").unwrap();
    let s = MheSettings::from_raw(&raw, &sys).unwrap();
    let t = lti_model::ioss::state_scaling(&sys, s.q().as_ref(), s.r().as_ref()).unwrap();
    let spread =
        t.iter().copied().fold(0.0, f64::max) / t.iter().copied().fold(f64::INFINITY, f64::min);
    eprintln!("balancing scaling of AFTI-16 in ft/s: {t:?} (spread {spread:e})");
    let e = MheError::NotStronglyConvex {
        window: 10,
        min_eigenvalue: 1e-4,
        max_eigenvalue: 1e10,
    };
    let words = ["units", "T = diag(", "T⁻¹AT", "not the weights"];
    // A scenario's path (`explain`) names the key …
    match s.explain(&sys, e) {
        MheError::Model(ModelError::Scenario { key, problem }) => {
            assert_eq!(key, "plant.a", "{problem}");
            for word in words {
                assert!(problem.contains(word), "{word}: {problem}");
            }
        }
        other => panic!("{other:?}"),
    }
    // … and the Rust path (`MheSettings::estimator`), when it refuses the window, the matrix.
    if let Err(real) = s.estimator(&sys, &MheSets::unconstrained(&sys), &[0.0; 4]) {
        match real {
            MheError::Model(ModelError::Invalid { field, problem }) => {
                assert_eq!(field, "LtiSystem::a", "{problem}");
                assert!(!problem.contains("plant."), "{problem}");
                for word in words {
                    assert!(problem.contains(word), "{word}: {problem}");
                }
            }
            other => panic!("{other:?}"),
        }
    }
    // The same plant with its speed in 100 ft/s has a spread 100× smaller.
    let s_units = [0.01, 1.0, 1.0, 1.0];
    let scaled = LtiSystem::new(
        Mat::from_fn(4, 4, |i, j| s_units[i] * sys.a()[(i, j)] / s_units[j]),
        Mat::from_fn(4, 2, |i, j| s_units[i] * sys.b()[(i, j)]),
        Mat::from_fn(2, 4, |i, j| sys.c()[(i, j)] / s_units[j]),
    )
    .unwrap();
    let t2 = lti_model::ioss::state_scaling(&scaled, s.q().as_ref(), s.r().as_ref()).unwrap();
    let spread2 =
        t2.iter().copied().fold(0.0, f64::max) / t2.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(spread2 < spread, "{spread2:e} vs {spread:e}");
}
