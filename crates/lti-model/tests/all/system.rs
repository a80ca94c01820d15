//! `LtiSystem` (eq. (1)): validation, one step against a hand computation, checked steps,
//! observability and detectability against systems whose hidden modes are known.

use faer::{Mat, mat};
use lti_model::{LtiSystem, ModelError};

fn shape_name(err: ModelError) -> String {
    match err {
        ModelError::Shape { name, .. } => name,
        other => panic!("expected Shape, got {other:?}"),
    }
}

fn nonfinite(err: ModelError) -> (String, usize, usize) {
    match err {
        ModelError::NonFinite { name, row, col, .. } => (name, row, col),
        other => panic!("expected NonFinite, got {other:?}"),
    }
}

#[test]
fn constructor_rejects_wrong_shapes_naming_the_matrix() {
    let a = mat![[1.0, 0.1], [0.0, 1.0]];
    let b = mat![[0.0], [0.1]];
    let c = mat![[1.0, 0.0]];
    assert_eq!(
        shape_name(LtiSystem::new(Mat::zeros(2, 3), b.clone(), c.clone()).unwrap_err()),
        "A"
    );
    assert_eq!(
        shape_name(
            LtiSystem::new(Mat::zeros(0, 0), Mat::zeros(0, 1), Mat::zeros(1, 0)).unwrap_err()
        ),
        "A"
    );
    assert_eq!(
        shape_name(LtiSystem::new(a.clone(), mat![[1.0]], c.clone()).unwrap_err()),
        "B"
    );
    assert_eq!(
        shape_name(LtiSystem::new(a.clone(), b.clone(), mat![[1.0, 0.0, 0.0]]).unwrap_err()),
        "C"
    );
    assert_eq!(
        shape_name(LtiSystem::new(a.clone(), b.clone(), Mat::zeros(0, 2)).unwrap_err()),
        "C"
    );
    let e_bad = Mat::<f64>::identity(3, 3);
    assert_eq!(
        shape_name(
            LtiSystem::with_disturbance(
                a.clone(),
                b.clone(),
                c.clone(),
                e_bad,
                Mat::identity(1, 1)
            )
            .unwrap_err()
        ),
        "E"
    );
    assert_eq!(
        shape_name(
            LtiSystem::with_disturbance(
                a.clone(),
                b.clone(),
                c.clone(),
                Mat::identity(2, 2),
                Mat::zeros(2, 1)
            )
            .unwrap_err()
        ),
        "F"
    );
    // Error messages carry the shapes.
    let msg = LtiSystem::new(a, mat![[1.0]], c).unwrap_err().to_string();
    assert!(
        msg.contains("`B`") && msg.contains("1x1") && msg.contains("2x1"),
        "{msg}"
    );
}

#[test]
fn constructor_rejects_non_finite_entries() {
    let a = mat![[1.0, 0.1], [0.0, 1.0]];
    let b = mat![[0.0], [0.1]];
    let c = mat![[1.0, 0.0]];
    assert_eq!(
        nonfinite(
            LtiSystem::new(mat![[1.0, 0.1], [f64::NAN, 1.0]], b.clone(), c.clone()).unwrap_err()
        ),
        ("A".to_string(), 1, 0)
    );
    assert_eq!(
        nonfinite(LtiSystem::new(a.clone(), mat![[0.0], [f64::INFINITY]], c.clone()).unwrap_err()),
        ("B".to_string(), 1, 0)
    );
    assert_eq!(
        nonfinite(
            LtiSystem::new(a.clone(), b.clone(), mat![[1.0, f64::NEG_INFINITY]]).unwrap_err()
        ),
        ("C".to_string(), 0, 1)
    );
    let e = mat![[1.0], [f64::NAN]];
    assert_eq!(
        nonfinite(LtiSystem::with_disturbance(a, b, c, e, Mat::identity(1, 1)).unwrap_err()).0,
        "E".to_string()
    );
}

#[test]
fn step_matches_hand_computation() {
    // A = [[1, 2], [3, 4]], B = [[1], [0]], C = [[1, -1]], E = I, F = I.
    let sys = LtiSystem::new(
        mat![[1.0, 2.0], [3.0, 4.0]],
        mat![[1.0], [0.0]],
        mat![[1.0, -1.0]],
    )
    .unwrap();
    assert_eq!(
        (sys.nx(), sys.nu(), sys.ny(), sys.nw1(), sys.nw2(), sys.nw()),
        (2, 1, 1, 2, 1, 3)
    );
    let (x, u, w) = ([1.0, -1.0], [0.5], [0.1, -0.2, 0.3]);
    let (mut xn, mut y) = ([0.0; 2], [0.0; 1]);
    sys.step(&x, &u, &w, &mut xn, &mut y);
    // x⁺ = (1 − 2 + 0.5 + 0.1, 3 − 4 + 0 − 0.2) = (−0.4, −1.2); y = 1 + 1 + 0.3 = 2.3.
    assert!(
        (xn[0] + 0.4).abs() < 1e-15 && (xn[1] + 1.2).abs() < 1e-15,
        "{xn:?}"
    );
    assert!((y[0] - 2.3).abs() < 1e-15, "{y:?}");

    // Explicit E, F: w¹ ∈ ℝ¹ enters state 2, w² ∈ ℝ² enters y as 2w²₁ − w²₂.
    let sys = LtiSystem::with_disturbance(
        mat![[1.0, 2.0], [3.0, 4.0]],
        mat![[1.0], [0.0]],
        mat![[1.0, -1.0]],
        mat![[0.0], [1.0]],
        mat![[2.0, -1.0]],
    )
    .unwrap();
    assert_eq!((sys.nw1(), sys.nw2()), (1, 2));
    sys.step(&x, &u, &[0.1, 1.0, 0.5], &mut xn, &mut y);
    assert!(
        (xn[0] + 0.5).abs() < 1e-15 && (xn[1] + 0.9).abs() < 1e-15,
        "{xn:?}"
    );
    assert!((y[0] - 3.5).abs() < 1e-15, "{y:?}");
    // B̄ = [E, 0], D̄ = [0, F].
    assert_eq!(
        lti_model::matrix::to_rows(sys.b_bar().as_ref()),
        vec![vec![0.0, 0.0, 0.0], vec![1.0, 0.0, 0.0]]
    );
    assert_eq!(
        lti_model::matrix::to_rows(sys.d_bar().as_ref()),
        vec![vec![0.0, 2.0, -1.0]]
    );
}

#[test]
fn checked_step_validates_lengths_and_values() {
    let sys = LtiSystem::new(
        mat![[0.5, 0.0], [0.0, 0.5]],
        mat![[1.0], [1.0]],
        mat![[1.0, 0.0]],
    )
    .unwrap();
    let (mut xn, mut y) = ([0.0; 2], [0.0; 1]);
    let ok = sys.checked_step(&[1.0, 1.0], &[0.0], &[0.0; 3], &mut xn, &mut y);
    assert!(ok.is_ok());
    assert_eq!(xn, [0.5, 0.5]);
    let len_err = |name: &str, r: lti_model::Result<()>| match r.unwrap_err() {
        ModelError::Shape {
            name: n,
            expected_rows,
            actual_rows,
            ..
        } => {
            assert_eq!(n, name);
            assert_ne!(expected_rows, actual_rows);
        }
        other => panic!("{other:?}"),
    };
    len_err(
        "x",
        sys.checked_step(&[1.0], &[0.0], &[0.0; 3], &mut xn, &mut y),
    );
    len_err(
        "u",
        sys.checked_step(&[1.0, 1.0], &[], &[0.0; 3], &mut xn, &mut y),
    );
    len_err(
        "w",
        sys.checked_step(&[1.0, 1.0], &[0.0], &[0.0; 2], &mut xn, &mut y),
    );
    len_err(
        "x_next",
        sys.checked_step(&[1.0, 1.0], &[0.0], &[0.0; 3], &mut [0.0; 3], &mut y),
    );
    len_err(
        "y",
        sys.checked_step(&[1.0, 1.0], &[0.0], &[0.0; 3], &mut xn, &mut []),
    );
    let nf = |name: &str, r: lti_model::Result<()>| assert_eq!(nonfinite(r.unwrap_err()).0, name);
    nf(
        "x",
        sys.checked_step(&[f64::NAN, 1.0], &[0.0], &[0.0; 3], &mut xn, &mut y),
    );
    nf(
        "u",
        sys.checked_step(&[1.0, 1.0], &[f64::INFINITY], &[0.0; 3], &mut xn, &mut y),
    );
    nf(
        "w",
        sys.checked_step(&[1.0, 1.0], &[0.0], &[0.0, 0.0, f64::NAN], &mut xn, &mut y),
    );
}

/// Similarity transform (A, C) → (TAT⁻¹, CT⁻¹) with a fixed well-conditioned T, so the
/// hidden mode is not aligned with a coordinate axis.
fn transformed(a: Mat<f64>, c: Mat<f64>) -> LtiSystem {
    use faer::linalg::solvers::DenseSolveCore;
    let t = mat![[1.0, 0.5], [-0.3, 2.0]];
    let tinv = t.partial_piv_lu().inverse();
    let a = &t * &a * &tinv;
    let c = &c * &tinv;
    LtiSystem::new(a, mat![[1.0], [0.0]], c).unwrap()
}

#[test]
fn observability_and_detectability_with_known_hidden_modes() {
    // Observable: C sees both modes of an upper-triangular A.
    let sys = transformed(mat![[1.2, 1.0], [0.0, 0.5]], mat![[1.0, 0.0]]);
    assert!(sys.is_observable().unwrap());
    assert!(sys.is_detectable().unwrap());
    assert_eq!(sys.unobservable_spectral_radius().unwrap(), 0.0);
    assert_eq!(sys.unobservable_subspace().unwrap().ncols(), 0);

    // Hidden stable mode 0.5 (C sees only the first coordinate of a diagonal A).
    let sys = transformed(mat![[1.2, 0.0], [0.0, 0.5]], mat![[1.0, 0.0]]);
    assert!(!sys.is_observable().unwrap());
    assert!(sys.is_detectable().unwrap());
    let rho = sys.unobservable_spectral_radius().unwrap();
    assert!((rho - 0.5).abs() < 1e-10, "hidden radius {rho}");
    // ker 𝒪 is one-dimensional and annihilated by C, CA.
    let n = sys.unobservable_subspace().unwrap();
    assert_eq!(n.ncols(), 1);
    assert!((sys.observability_matrix() * &n).norm_max() < 1e-12);

    // Hidden unstable mode −1.5: not detectable.
    let sys = transformed(mat![[0.5, 0.0], [0.0, -1.5]], mat![[1.0, 0.0]]);
    assert!(!sys.is_observable().unwrap());
    assert!(!sys.is_detectable().unwrap());
    let rho = sys.unobservable_spectral_radius().unwrap();
    assert!((rho - 1.5).abs() < 1e-10, "hidden radius {rho}");

    // Observability matrix of a hand example: C = [1, 0], A = [[1, 1], [0, 1]] → [[1, 0], [1, 1]].
    let sys = LtiSystem::new(
        mat![[1.0, 1.0], [0.0, 1.0]],
        mat![[0.0], [1.0]],
        mat![[1.0, 0.0]],
    )
    .unwrap();
    assert_eq!(
        lti_model::matrix::to_rows(sys.observability_matrix().as_ref()),
        vec![vec![1.0, 0.0], vec![1.0, 1.0]]
    );
    assert!(sys.is_observable().unwrap());
}

#[test]
fn spectral_radius_of_known_matrices() {
    use lti_model::system::spectral_radius;
    assert!((spectral_radius(mat![[0.0, 2.0], [-2.0, 0.0]].as_ref()).unwrap() - 2.0).abs() < 1e-14);
    assert!((spectral_radius(mat![[0.3, 5.0], [0.0, -0.7]].as_ref()).unwrap() - 0.7).abs() < 1e-14);
    assert_eq!(
        spectral_radius(Mat::<f64>::zeros(0, 0).as_ref()).unwrap(),
        0.0
    );
}
