//! `riccati`: expm, ZOH, DARE, DLQR and discrete Lyapunov, each against an independent
//! answer (closed forms, Taylor series, quadrature, value iteration, power series,
//! closed-loop simulation).

use faer::{Mat, MatRef, mat};
use lti_model::ModelError;
use lti_model::riccati::{dare, dlqr_gain, dlyap, expm, residual_dare, residual_dlyap, zoh};
use lti_model::system::spectral_radius;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

fn randn(rng: &mut ChaCha8Rng, r: usize, c: usize) -> Mat<f64> {
    Mat::from_fn(r, c, |_, _| rng.sample::<f64, _>(StandardNormal))
}

/// A random matrix rescaled to spectral radius `rho`.
fn with_radius(rng: &mut ChaCha8Rng, n: usize, rho: f64) -> Mat<f64> {
    let a = randn(rng, n, n);
    let r0 = spectral_radius(a.as_ref()).unwrap();
    Mat::from_fn(n, n, |i, j| a[(i, j)] * rho / r0)
}

fn max_abs_diff(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> f64 {
    assert_eq!((a.nrows(), a.ncols()), (b.nrows(), b.ncols()));
    (a - b).norm_max()
}

fn assert_shape_err(err: ModelError, expected: &str) {
    match err {
        ModelError::Shape { name, .. } => assert_eq!(name, expected),
        other => panic!("expected Shape({expected}), got {other:?}"),
    }
}

fn assert_nonfinite_err(err: ModelError, expected: &str) {
    match err {
        ModelError::NonFinite { name, .. } => assert_eq!(name, expected),
        other => panic!("expected NonFinite({expected}), got {other:?}"),
    }
}

fn assert_numerical_err(err: ModelError, expected: &str) -> String {
    match err {
        ModelError::Numerical { routine, reason } => {
            assert_eq!(routine, expected, "reason: {reason}");
            reason
        }
        other => panic!("expected Numerical({expected}), got {other:?}"),
    }
}

// ---------------------------------------------------------------- expm

#[test]
fn expm_diagonal_matches_scalar_exponentials() {
    for d in [[-2.0, 0.5, 3.0], [-40.0, 0.0, 12.0], [1e-9, -1e-3, 7.5]] {
        let a = Mat::from_fn(3, 3, |i, j| if i == j { d[i] } else { 0.0 });
        let e = expm(a.as_ref()).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { d[i].exp() } else { 0.0 };
                // exp has relative condition number |x| at x, so allow 1e-14·max(1, |d_i|).
                let tol = 1e-14 * d[i].abs().max(1.0) * want.abs();
                assert!(
                    (e[(i, j)] - want).abs() <= tol,
                    "d={d:?} ({i},{j}): {} vs {want}",
                    e[(i, j)]
                );
            }
        }
    }
}

/// Number of squarings s = ⌈log₂(‖A‖₁/θ₁₃)⌉ (at least 1) that `expm` performs: each one
/// can add a rounding error relative to the result, so tests scale tolerances by it.
fn squarings(a: MatRef<'_, f64>) -> f64 {
    let norm1 = (0..a.ncols())
        .map(|j| (0..a.nrows()).map(|i| a[(i, j)].abs()).sum::<f64>())
        .fold(0.0, f64::max);
    (norm1 / 5.371_920_351_148_152).log2().ceil().max(1.0)
}

#[test]
fn expm_nilpotent_is_a_finite_series() {
    // N strictly upper triangular: N³ = 0, so e^N = I + N + N²/2 exactly.
    for (a, b, c) in [(1.0, 2.0, 3.0), (-50.0, 7.0, 0.25), (1e3, -1e3, 1e-3)] {
        let n = mat![[0.0, a, b], [0.0, 0.0, c], [0.0, 0.0, 0.0]];
        let want = mat![[1.0, a, b + a * c / 2.0], [0.0, 1.0, c], [0.0, 0.0, 1.0]];
        let e = expm(n.as_ref()).unwrap();
        let tol = 1e-14 * want.norm_max() * squarings(n.as_ref());
        assert!(
            max_abs_diff(e.as_ref(), want.as_ref()) <= tol,
            "(a,b,c)=({a},{b},{c}): {e:?}"
        );
    }
}

#[test]
fn expm_rotation_generator_gives_cos_sin() {
    for theta in [0.0, 0.1, 1.0, 3.0, 30.0, -7.0] {
        let a = mat![[0.0, theta], [-theta, 0.0]];
        let e = expm(a.as_ref()).unwrap();
        let want = mat![[theta.cos(), theta.sin()], [-theta.sin(), theta.cos()]];
        // Squaring s = ⌈log₂(|θ|/θ₁₃)⌉ times amplifies roundoff by ~2^s.
        let tol = 2e-15 * (1.0 + theta.abs());
        assert!(
            max_abs_diff(e.as_ref(), want.as_ref()) <= tol,
            "theta={theta}: {e:?}"
        );
    }
}

/// Σ_{k<60} Aᵏ/k!, accurate for ‖A‖ ≤ 2 (the tail is below 2⁶⁰/60! ≈ 1e-64).
fn taylor_expm(a: MatRef<'_, f64>) -> Mat<f64> {
    let n = a.nrows();
    let mut sum = Mat::<f64>::identity(n, n);
    let mut term = Mat::<f64>::identity(n, n);
    for k in 1..60 {
        term = &term * a;
        term = Mat::from_fn(n, n, |i, j| term[(i, j)] / k as f64);
        sum += &term;
    }
    sum
}

#[test]
fn expm_matches_long_taylor_series_on_small_random_matrices() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for trial in 0..40 {
        let n = 1 + trial % 6;
        let a = randn(&mut rng, n, n);
        let scale: f64 = rng.random_range(0.01..2.0) / a.norm_max().max(1e-12) / n as f64;
        let a = Mat::from_fn(n, n, |i, j| a[(i, j)] * scale);
        let e = expm(a.as_ref()).unwrap();
        let t = taylor_expm(a.as_ref());
        let err = max_abs_diff(e.as_ref(), t.as_ref()) / t.norm_max();
        assert!(err <= 1e-14, "trial {trial}: relative error {err:e}");
    }
}

#[test]
fn expm_group_properties_for_larger_norms() {
    // e^{A} e^{-A} = I and e^{2A} = (e^{A})² for random A with ‖A‖ up to ~20
    // (exercises the squaring phase; the Taylor series would be inaccurate here).
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for trial in 0..10 {
        let n = 2 + trial % 4;
        let a = randn(&mut rng, n, n);
        let a = Mat::from_fn(n, n, |i, j| a[(i, j)] * 3.0 / (n as f64).sqrt());
        let neg = Mat::from_fn(n, n, |i, j| -a[(i, j)]);
        let two = Mat::from_fn(n, n, |i, j| 2.0 * a[(i, j)]);
        let ea = expm(a.as_ref()).unwrap();
        let ena = expm(neg.as_ref()).unwrap();
        let e2a = expm(two.as_ref()).unwrap();
        let id = Mat::<f64>::identity(n, n);
        let cond = ea.norm_max() * ena.norm_max() * n as f64;
        assert!(
            max_abs_diff((&ea * &ena).as_ref(), id.as_ref()) <= 1e-13 * cond,
            "trial {trial}"
        );
        let sq = &ea * &ea;
        assert!(
            max_abs_diff(e2a.as_ref(), sq.as_ref()) <= 1e-13 * sq.norm_max() * n as f64,
            "trial {trial}"
        );
    }
}

#[test]
fn expm_rejects_bad_input() {
    assert_shape_err(expm(Mat::<f64>::zeros(2, 3).as_ref()).unwrap_err(), "A");
    assert_nonfinite_err(
        expm(mat![[1.0, f64::NAN], [0.0, 1.0]].as_ref()).unwrap_err(),
        "A",
    );
    assert_nonfinite_err(expm(mat![[f64::INFINITY]].as_ref()).unwrap_err(), "A");
    // e^{1000} overflows f64: an error, not inf entries.
    assert_numerical_err(expm(mat![[1000.0]].as_ref()).unwrap_err(), "expm");
    // ‖A‖₁ itself overflows, or e^A does after the maximal 1022 squarings: errors, no hang.
    let huge = mat![[f64::MAX, f64::MAX], [0.0, 0.0]];
    assert_numerical_err(expm(huge.as_ref()).unwrap_err(), "expm");
    assert_numerical_err(expm(mat![[f64::MAX]].as_ref()).unwrap_err(), "expm");
    // ... while e^{-1000} and e^{-1e300} underflow harmlessly to 0.
    assert_eq!(expm(mat![[-1e300]].as_ref()).unwrap()[(0, 0)], 0.0);
    assert_eq!(expm(mat![[-1000.0]].as_ref()).unwrap()[(0, 0)], 0.0);
}

// ---------------------------------------------------------------- ZOH

#[test]
fn zoh_double_integrator_closed_form() {
    let ac = mat![[0.0, 1.0], [0.0, 0.0]];
    let bc = mat![[0.0], [1.0]];
    for t in [1e-3, 0.01, 0.1, 1.0, 2.5, 40.0] {
        let (a, b) = zoh(ac.as_ref(), bc.as_ref(), t).unwrap();
        let a_want = mat![[1.0, t], [0.0, 1.0]];
        let b_want = mat![[t * t / 2.0], [t]];
        assert!(
            max_abs_diff(a.as_ref(), a_want.as_ref()) <= 1e-15 * (1.0 + t),
            "T={t}: {a:?}"
        );
        assert!(
            max_abs_diff(b.as_ref(), b_want.as_ref()) <= 1e-15 * (1.0 + t * t),
            "T={t}: {b:?}"
        );
    }
}

#[test]
fn zoh_matches_simpson_quadrature_and_the_invertible_closed_form() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    for trial in 0..8 {
        let n = 1 + trial % 4;
        let m = 1 + trial % 3;
        let ac = randn(&mut rng, n, n);
        let bc = randn(&mut rng, n, m);
        let t: f64 = rng.random_range(0.05..0.8);
        let (a, b) = zoh(ac.as_ref(), bc.as_ref(), t).unwrap();

        let act = Mat::from_fn(n, n, |i, j| ac[(i, j)] * t);
        assert!(
            max_abs_diff(a.as_ref(), expm(act.as_ref()).unwrap().as_ref()) <= 1e-14 * a.norm_max()
        );

        // Composite Simpson on ∫₀ᵀ e^{A_c s} ds B_c with 400 panels: error O(h⁴) ≈ 1e-13.
        let panels = 400;
        let h = t / panels as f64;
        let mut integral = Mat::<f64>::zeros(n, n);
        for k in 0..=panels {
            let w = if k == 0 || k == panels {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            };
            let s = k as f64 * h;
            let e = expm(Mat::from_fn(n, n, |i, j| ac[(i, j)] * s).as_ref()).unwrap();
            integral += Mat::from_fn(n, n, |i, j| e[(i, j)] * w * h / 3.0);
        }
        let b_quad = &integral * &bc;
        let err = max_abs_diff(b.as_ref(), b_quad.as_ref());
        assert!(
            err <= 1e-11 * b.norm_max().max(1.0),
            "trial {trial}: |B - quad| = {err:e}"
        );

        // A_c invertible (generic): B = A_c⁻¹ (e^{A_c T} − I) B_c.
        use faer::linalg::solvers::Solve;
        let rhs = (&a - Mat::<f64>::identity(n, n)) * &bc;
        let b_closed = ac.partial_piv_lu().solve(&rhs);
        let err = max_abs_diff(b.as_ref(), b_closed.as_ref());
        assert!(
            err <= 1e-10 * b.norm_max().max(1.0),
            "trial {trial}: |B - closed form| = {err:e}"
        );
    }
}

#[test]
fn zoh_rejects_bad_input() {
    let ac = mat![[0.0, 1.0], [0.0, 0.0]];
    let bc = mat![[0.0], [1.0]];
    for ts in [0.0, -0.1, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        match zoh(ac.as_ref(), bc.as_ref(), ts).unwrap_err() {
            ModelError::OutOfRange { name, .. } => assert_eq!(name, "ts"),
            other => panic!("ts={ts}: {other:?}"),
        }
    }
    // A_c·ts overflows.
    match zoh(mat![[1e300]].as_ref(), mat![[1.0]].as_ref(), 1e10).unwrap_err() {
        ModelError::OutOfRange { name, .. } => assert_eq!(name, "ts"),
        other => panic!("{other:?}"),
    }
    assert_shape_err(
        zoh(Mat::<f64>::zeros(2, 3).as_ref(), bc.as_ref(), 0.1).unwrap_err(),
        "A_c",
    );
    assert_shape_err(
        zoh(Mat::<f64>::zeros(0, 0).as_ref(), bc.as_ref(), 0.1).unwrap_err(),
        "A_c",
    );
    assert_shape_err(
        zoh(ac.as_ref(), mat![[1.0], [2.0], [3.0]].as_ref(), 0.1).unwrap_err(),
        "B_c",
    );
    assert_nonfinite_err(
        zoh(mat![[f64::NAN]].as_ref(), mat![[1.0]].as_ref(), 0.1).unwrap_err(),
        "A_c",
    );
    assert_nonfinite_err(
        zoh(ac.as_ref(), mat![[0.0], [f64::NAN]].as_ref(), 0.1).unwrap_err(),
        "B_c",
    );
}

// ---------------------------------------------------------------- DARE

/// The positive root of b²x² + (r(1 − a²) − qb²)x − qr = 0 (the scalar DARE, multiplied
/// by r + b²x), by the cancellation-free form of the quadratic formula.
fn scalar_dare(a: f64, b: f64, q: f64, r: f64) -> f64 {
    let (qa, qb, qc) = (b * b, r * (1.0 - a * a) - q * b * b, -q * r);
    let disc = (qb * qb - 4.0 * qa * qc).sqrt();
    if qb <= 0.0 {
        (-qb + disc) / (2.0 * qa)
    } else {
        2.0 * qc / (-qb - disc)
    }
}

#[test]
fn dare_scalar_matches_quadratic_formula() {
    for (a, b, q, r) in [
        (2.0, 1.0, 1.0, 1.0),
        (0.5, 1.0, 1.0, 1.0),
        (-3.0, 0.2, 5.0, 0.1),
        (1.0, 1.0, 1.0, 1.0),
        (0.99, 3.0, 0.01, 2.0),
    ] {
        let x = dare(
            mat![[a]].as_ref(),
            mat![[b]].as_ref(),
            mat![[q]].as_ref(),
            mat![[r]].as_ref(),
        )
        .unwrap();
        let want = scalar_dare(a, b, q, r);
        assert!(
            (x[(0, 0)] - want).abs() <= 1e-13 * want,
            "(a,b,q,r)=({a},{b},{q},{r}): {} vs {want}",
            x[(0, 0)]
        );
        // Stabilizing: |a − b k| < 1 with k = b x a / (r + b² x).
        let k = b * want * a / (r + b * b * want);
        assert!((a - b * k).abs() < 1.0);
    }
}

/// X_{k+1} = AᵀX_kA − AᵀX_kB(R + BᵀX_kB)⁻¹BᵀX_kA + Q from X₀ = Q: converges (linearly) to
/// the stabilizing solution under stabilizability and detectability.
fn value_iteration(
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
) -> Mat<f64> {
    use faer::linalg::solvers::Solve;
    let mut x = q.to_owned();
    for _ in 0..200_000 {
        let s = r + b.transpose() * &x * b;
        let btxa = b.transpose() * &x * a;
        let corr = s.partial_piv_lu().solve(&btxa);
        let next = a.transpose() * &x * a - btxa.transpose() * &corr + q;
        let next = Mat::from_fn(x.nrows(), x.ncols(), |i, j| {
            0.5 * (next[(i, j)] + next[(j, i)])
        });
        let change = max_abs_diff(next.as_ref(), x.as_ref());
        x = next;
        if change <= 1e-15 * x.norm_max() {
            break;
        }
    }
    x
}

fn random_dare_problem(
    rng: &mut ChaCha8Rng,
    trial: usize,
) -> (Mat<f64>, Mat<f64>, Mat<f64>, Mat<f64>) {
    let n = 1 + trial % 6;
    let m = 1 + trial % 3;
    let rho: f64 = rng.random_range(0.3..1.6);
    let a = with_radius(rng, n, rho);
    let b = randn(rng, n, m);
    // Alternate Q ≻ 0 and a rank-deficient Q = CᵀC (detectable for generic C).
    let q = if trial % 2 == 0 {
        let mq = randn(rng, n, n);
        mq.transpose() * &mq + Mat::<f64>::identity(n, n) * 0.1
    } else {
        let c = randn(rng, 1, n);
        c.transpose() * &c
    };
    let mr = randn(rng, m, m);
    let r = mr.transpose() * &mr + Mat::<f64>::identity(m, m) * 0.5;
    (a, b, q, r)
}

#[test]
fn dare_random_stabilizable_systems_residual_schur_and_value_iteration() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    for trial in 0..30 {
        let (a, b, q, r) = random_dare_problem(&mut rng, trial);
        let x = dare(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref()).unwrap();
        let scale = x.norm_max().max(1.0);
        let res =
            residual_dare(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref(), x.as_ref()).unwrap();
        assert!(
            res <= 1e-10 * scale,
            "trial {trial}: residual {res:e}, |X| = {scale:e}"
        );
        // Symmetric PSD.
        assert_eq!(lti_model::matrix::asymmetry(x.as_ref()), 0.0);
        let (lo, _) = lti_model::matrix::sym_extreme_eigenvalues("X", x.as_ref()).unwrap();
        assert!(lo >= -1e-10 * scale, "trial {trial}: λ_min(X) = {lo}");
        // Stabilizing.
        let (k, x2) = dlqr_gain(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref()).unwrap();
        assert_eq!(max_abs_diff(x.as_ref(), x2.as_ref()), 0.0);
        let rho_cl = spectral_radius((&a - &b * &k).as_ref()).unwrap();
        assert!(rho_cl < 1.0, "trial {trial}: closed-loop radius {rho_cl}");
        // Independent answer: Riccati value iteration.
        let xv = value_iteration(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref());
        let err = max_abs_diff(x.as_ref(), xv.as_ref());
        assert!(
            err <= 1e-8 * scale,
            "trial {trial}: |X_SDA − X_VI| = {err:e}, |X| = {scale:e}"
        );
    }
}

#[test]
fn dlqr_gain_formula_and_closed_loop_cost() {
    use faer::linalg::solvers::Solve;
    let mut rng = ChaCha8Rng::seed_from_u64(32);
    for trial in 0..10 {
        let (a, b, q, r) = random_dare_problem(&mut rng, trial);
        let n = a.nrows();
        let (k, x) = dlqr_gain(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref()).unwrap();
        // K = (R + BᵀXB)⁻¹ BᵀXA, via an LU solve instead of the Cholesky used inside.
        let s = &r + b.transpose() * &x * &b;
        let k_want = s.partial_piv_lu().solve(b.transpose() * &x * &a);
        assert!(max_abs_diff(k.as_ref(), k_want.as_ref()) <= 1e-10 * k_want.norm_max().max(1.0));
        // x₀ᵀXx₀ = Σ_t x_tᵀ(Q + KᵀRK)x_t along x_{t+1} = (A − BK)x_t.
        let acl = &a - &b * &k;
        let stage = &q + k.transpose() * &r * &k;
        let mut xt = randn(&mut rng, n, 1);
        let x0 = xt.clone();
        let mut cost = 0.0;
        for _ in 0..100_000 {
            let c = (xt.transpose() * &stage * &xt)[(0, 0)];
            cost += c;
            xt = &acl * &xt;
            if c <= 1e-300 || xt.norm_max() <= 1e-160 {
                break;
            }
        }
        let want = (x0.transpose() * &x * &x0)[(0, 0)];
        assert!(
            (cost - want).abs() <= 1e-9 * want.max(1.0),
            "trial {trial}: simulated {cost} vs x0ᵀXx0 {want}"
        );
    }
}

#[test]
fn dare_without_inputs_is_the_lyapunov_equation() {
    // m = 0: X = AᵀXA + Q.
    let a = mat![[0.5, 0.2], [0.0, -0.3]];
    let q = mat![[1.0, 0.0], [0.0, 2.0]];
    let x = dare(
        a.as_ref(),
        Mat::<f64>::zeros(2, 0).as_ref(),
        q.as_ref(),
        Mat::<f64>::zeros(0, 0).as_ref(),
    )
    .unwrap();
    let xl = dlyap(a.as_ref(), q.as_ref()).unwrap();
    assert!(max_abs_diff(x.as_ref(), xl.as_ref()) <= 1e-13);
}

#[test]
fn dare_unstabilizable_or_undetectable_is_an_error() {
    // Uncontrollable unstable mode 2 (B does not reach it), Q ≻ 0.
    let err = dare(
        mat![[2.0, 0.0], [0.0, 0.5]].as_ref(),
        mat![[0.0], [1.0]].as_ref(),
        Mat::<f64>::identity(2, 2).as_ref(),
        mat![[1.0]].as_ref(),
    )
    .unwrap_err();
    let reason = assert_numerical_err(err, "DARE");
    assert!(reason.contains("not stabilizable"), "{reason}");
    // Scalar with b = 0.
    let err = dare(
        mat![[1.5]].as_ref(),
        mat![[0.0]].as_ref(),
        mat![[1.0]].as_ref(),
        mat![[1.0]].as_ref(),
    )
    .unwrap_err();
    assert_numerical_err(err, "DARE");
    // Unstable mode that Q does not see (Q = 0): the only PSD solution X = 0 is not stabilizing.
    let err = dare(
        mat![[2.0]].as_ref(),
        mat![[1.0]].as_ref(),
        mat![[0.0]].as_ref(),
        mat![[1.0]].as_ref(),
    )
    .unwrap_err();
    let reason = assert_numerical_err(err, "DARE");
    assert!(reason.contains("detectable"), "{reason}");
    // Uncontrollable mode on the unit circle.
    let err = dare(
        mat![[1.0, 0.0], [0.0, 0.5]].as_ref(),
        mat![[0.0], [1.0]].as_ref(),
        Mat::<f64>::identity(2, 2).as_ref(),
        mat![[1.0]].as_ref(),
    )
    .unwrap_err();
    assert_numerical_err(err, "DARE");
}

#[test]
fn dare_rejects_bad_input() {
    let a = mat![[1.0, 0.1], [0.0, 1.0]];
    let b = mat![[0.0], [0.1]];
    let q = Mat::<f64>::identity(2, 2);
    let r = mat![[1.0]];
    let call = |a: &Mat<f64>, b: &Mat<f64>, q: &Mat<f64>, r: &Mat<f64>| {
        dare(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref()).unwrap_err()
    };
    match call(&a, &b, &q, &mat![[0.0]]) {
        ModelError::NotPositiveDefinite { name, .. } => assert_eq!(name, "R"),
        other => panic!("{other:?}"),
    }
    match call(&a, &b, &q, &mat![[-1.0]]) {
        ModelError::NotPositiveDefinite { name, .. } => assert_eq!(name, "R"),
        other => panic!("{other:?}"),
    }
    match call(&a, &b, &mat![[1.0, 0.5], [0.0, 1.0]], &r) {
        ModelError::NotSymmetric { name, .. } => assert_eq!(name, "Q"),
        other => panic!("{other:?}"),
    }
    match call(&a, &b, &mat![[1.0, 0.0], [0.0, -0.1]], &r) {
        ModelError::NotPositiveDefinite {
            name,
            min_eigenvalue,
        } => {
            assert_eq!(name, "Q");
            assert!((min_eigenvalue + 0.1).abs() < 1e-12);
        }
        other => panic!("{other:?}"),
    }
    // Q = 0 (PSD, not PD) is accepted for a stable A.
    assert!(
        dare(
            mat![[0.5]].as_ref(),
            mat![[1.0]].as_ref(),
            mat![[0.0]].as_ref(),
            mat![[1.0]].as_ref()
        )
        .is_ok()
    );
    assert_shape_err(call(&Mat::zeros(2, 3), &b, &q, &r), "A");
    assert_shape_err(call(&a, &mat![[1.0]], &q, &r), "B");
    assert_shape_err(call(&a, &b, &Mat::<f64>::identity(3, 3), &r), "Q");
    assert_shape_err(call(&a, &b, &q, &Mat::<f64>::identity(2, 2)), "R");
    assert_nonfinite_err(call(&mat![[f64::NAN, 0.0], [0.0, 1.0]], &b, &q, &r), "A");
    assert_nonfinite_err(call(&a, &mat![[f64::INFINITY], [0.0]], &q, &r), "B");
    assert_nonfinite_err(call(&a, &b, &mat![[1.0, 0.0], [0.0, f64::NAN]], &r), "Q");
    assert_nonfinite_err(call(&a, &b, &q, &mat![[f64::NAN]]), "R");
}

#[test]
fn residual_helpers_check_shapes_and_detect_wrong_solutions() {
    let (a, b, q, r) = (mat![[2.0]], mat![[1.0]], mat![[1.0]], mat![[1.0]]);
    let x_true = mat![[2.0 + 5f64.sqrt()]];
    let res = residual_dare(
        a.as_ref(),
        b.as_ref(),
        q.as_ref(),
        r.as_ref(),
        x_true.as_ref(),
    )
    .unwrap();
    assert!(res <= 1e-14);
    // The non-stabilizing root 2 − √5 also satisfies the equation; a wrong X does not.
    let res = residual_dare(
        a.as_ref(),
        b.as_ref(),
        q.as_ref(),
        r.as_ref(),
        mat![[4.0]].as_ref(),
    )
    .unwrap();
    // x = 4: 4·4 − 16·4/5 + 1 − 4 = 0.2
    assert!((res - 0.2).abs() < 1e-14, "{res}");
    assert_shape_err(
        residual_dare(
            a.as_ref(),
            b.as_ref(),
            q.as_ref(),
            r.as_ref(),
            Mat::<f64>::zeros(2, 2).as_ref(),
        )
        .unwrap_err(),
        "X",
    );
    assert_shape_err(
        residual_dlyap(a.as_ref(), q.as_ref(), Mat::<f64>::zeros(1, 2).as_ref()).unwrap_err(),
        "X",
    );
    assert_nonfinite_err(
        residual_dlyap(a.as_ref(), q.as_ref(), mat![[f64::NAN]].as_ref()).unwrap_err(),
        "X",
    );
    // a = 0.5, q = 1, x = 1: 0.25 − 1 + 1 = 0.25.
    assert_eq!(
        residual_dlyap(
            mat![[0.5]].as_ref(),
            mat![[1.0]].as_ref(),
            mat![[1.0]].as_ref()
        )
        .unwrap(),
        0.25
    );
}

// ---------------------------------------------------------------- Lyapunov

#[test]
fn dlyap_scalar_closed_form() {
    for (a, q) in [
        (0.0, 1.0),
        (0.5, 3.0),
        (-0.9, 2.0),
        (0.999, 1.0),
        (0.3, 0.0),
        (0.7, -1.0),
    ] {
        let x = dlyap(mat![[a]].as_ref(), mat![[q]].as_ref()).unwrap();
        let want: f64 = q / (1.0 - a * a);
        assert!(
            (x[(0, 0)] - want).abs() <= 1e-13 * want.abs().max(1.0),
            "a={a}: {} vs {want}",
            x[(0, 0)]
        );
    }
}

/// Σ_k (Aᵀ)ᵏ Q Aᵏ summed term by term until the terms are negligible.
fn lyapunov_series(a: MatRef<'_, f64>, q: MatRef<'_, f64>) -> Mat<f64> {
    let mut sum = q.to_owned();
    let mut term = q.to_owned();
    for _ in 0..100_000 {
        term = a.transpose() * &term * a;
        sum += &term;
        if term.norm_max() <= 1e-18 * sum.norm_max() {
            break;
        }
    }
    sum
}

#[test]
fn dlyap_kronecker_and_smith_match_the_power_series() {
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    // n ≤ 40 uses the Kronecker system, n = 45 Smith doubling.
    for (trial, n) in [1usize, 2, 3, 5, 8, 45].into_iter().enumerate() {
        let rho: f64 = rng.random_range(0.2..0.97);
        let a = with_radius(&mut rng, n, rho);
        let mq = randn(&mut rng, n, n);
        let q = mq.transpose() * &mq;
        let x = dlyap(a.as_ref(), q.as_ref()).unwrap();
        let scale = x.norm_max().max(1.0);
        let res = residual_dlyap(a.as_ref(), q.as_ref(), x.as_ref()).unwrap();
        assert!(
            res <= 1e-11 * scale,
            "trial {trial} (n={n}): residual {res:e}"
        );
        let xs = lyapunov_series(a.as_ref(), q.as_ref());
        let err = max_abs_diff(x.as_ref(), xs.as_ref());
        assert!(
            err <= 1e-10 * scale,
            "trial {trial} (n={n}): |X − series| = {err:e}"
        );
        let (lo, _) = lti_model::matrix::sym_extreme_eigenvalues("X", x.as_ref()).unwrap();
        assert!(lo >= -1e-10 * scale);
    }
}

#[test]
fn dlyap_rejects_non_schur_and_bad_input() {
    for a in [
        mat![[1.0]],
        mat![[-1.2]],
        mat![[0.5, 0.0], [0.0, 1.1]],
        mat![[0.0, 1.0], [-1.0, 0.0]],
    ] {
        let n = a.nrows();
        let reason = assert_numerical_err(
            dlyap(a.as_ref(), Mat::<f64>::identity(n, n).as_ref()).unwrap_err(),
            "Lyapunov",
        );
        assert!(reason.contains("not Schur"), "{reason}");
    }
    let a = mat![[0.5, 0.0], [0.0, 0.5]];
    assert_shape_err(
        dlyap(a.as_ref(), Mat::<f64>::identity(3, 3).as_ref()).unwrap_err(),
        "Q",
    );
    assert_shape_err(
        dlyap(Mat::<f64>::zeros(2, 1).as_ref(), mat![[1.0]].as_ref()).unwrap_err(),
        "A",
    );
    assert_shape_err(
        dlyap(
            Mat::<f64>::zeros(0, 0).as_ref(),
            Mat::<f64>::zeros(0, 0).as_ref(),
        )
        .unwrap_err(),
        "A",
    );
    match dlyap(a.as_ref(), mat![[1.0, 2.0], [0.0, 1.0]].as_ref()).unwrap_err() {
        ModelError::NotSymmetric { name, .. } => assert_eq!(name, "Q"),
        other => panic!("{other:?}"),
    }
    assert_nonfinite_err(
        dlyap(mat![[f64::NAN]].as_ref(), mat![[1.0]].as_ref()).unwrap_err(),
        "A",
    );
    assert_nonfinite_err(
        dlyap(mat![[0.5]].as_ref(), mat![[f64::INFINITY]].as_ref()).unwrap_err(),
        "Q",
    );
}

/// `sym_lambda_max` above `JACOBI_MAX_DIM` (dense eigenvalues) against the Jacobi rotations
/// on the same matrices: random PSD and indefinite matrices of sizes 25–60 agree to 1e-12
/// relative to ‖G‖.
#[test]
fn sym_lambda_max_dense_path_matches_jacobi() {
    use lti_model::matrix::{JACOBI_MAX_DIM, sym_lambda_max, sym_lambda_max_in_place};
    let mut state = 0x9E37_79B9_7F4A_7C15_u64;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1);
        ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    for k in [JACOBI_MAX_DIM + 1, 40, 60] {
        for psd in [true, false] {
            let b: Vec<f64> = (0..k * k).map(|_| next()).collect();
            let mut g = vec![0.0; k * k];
            for i in 0..k {
                for j in 0..k {
                    g[i * k + j] = if psd {
                        (0..k).map(|l| b[i * k + l] * b[j * k + l]).sum()
                    } else {
                        b[i * k + j] + b[j * k + i]
                    };
                }
            }
            let scale = g.iter().map(|v| v.abs()).fold(0.0, f64::max) * k as f64;
            let dense = sym_lambda_max(&mut g.clone(), k);
            let jacobi = sym_lambda_max_in_place(&mut g, k);
            assert!(
                (dense - jacobi).abs() <= 1e-12 * scale,
                "k = {k}, psd {psd}: {dense} vs {jacobi}"
            );
        }
    }
}

/// `sym_lambda_max_above` on 4 000 random symmetric matrices (PSD, indefinite and rank-one,
/// k = 1–8, scales 10⁻⁶–10⁶) and floors around, below and above λ_max: Some(λ) is bit for bit
/// `sym_lambda_max_in_place`'s value, None only where that value is ≤ the floor, and floors
/// just below λ_max never return None (the early stop has teeth only where it is sound).
#[test]
fn sym_lambda_max_above_is_the_running_maximum_bit_for_bit() {
    use lti_model::matrix::{sym_lambda_max_above, sym_lambda_max_in_place};
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let (mut stopped, mut computed) = (0, 0);
    for case in 0..4000 {
        let k = 1 + case % 8;
        let scale = 10f64.powi(rng.random_range(-6..=6));
        let b: Vec<f64> = (0..k * k).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut g = vec![0.0; k * k];
        for i in 0..k {
            for j in 0..k {
                g[i * k + j] = scale
                    * match case % 3 {
                        0 => (0..k).map(|l| b[i * k + l] * b[j * k + l]).sum(),
                        1 => b[i * k + j] + b[j * k + i],
                        _ => b[i] * b[j],
                    };
            }
        }
        let exact = sym_lambda_max_in_place(&mut g.clone(), k);
        let spread = exact.abs().max(scale);
        let floor = exact + spread * rng.random_range(-2.0..2.0);
        match sym_lambda_max_above(&mut g.clone(), k, floor) {
            Some(top) => {
                computed += 1;
                assert_eq!(top.to_bits(), exact.to_bits(), "case {case}");
            }
            None => {
                stopped += 1;
                assert!(exact <= floor, "case {case}: {exact} > floor {floor}");
            }
        }
        let just_below = exact - 1e-9 * spread;
        assert_eq!(
            sym_lambda_max_above(&mut g.clone(), k, just_below).map(f64::to_bits),
            Some(exact.to_bits()),
            "case {case}"
        );
    }
    assert!(
        stopped > 500 && computed > 500,
        "{stopped} stopped, {computed} computed"
    );
}
