//! Stability from exact structure (issue 25, item 2): the quadrotor of the OSQP MPC
//! example, the double integrator, a Jordan block of size 4 (also hidden by an orthogonal
//! similarity), a rotation, and strictly stable / unstable neighbours.

use faer::{Mat, mat};
use lti_model::spectral::{Stability, classify};

/// A of the quadrotor in the OSQP documentation's MPC example (osqp.org, "Model predictive
/// control (MPC)", the Crazyflie model linearised about hover, T_s = 0.1 s).
pub fn quadrotor_a() -> Mat<f64> {
    let rows: [[f64; 12]; 12] = [
        [1., 0., 0., 0., 0., 0., 0.1, 0., 0., 0., 0., 0.],
        [0., 1., 0., 0., 0., 0., 0., 0.1, 0., 0., 0., 0.],
        [0., 0., 1., 0., 0., 0., 0., 0., 0.1, 0., 0., 0.],
        [0.0488, 0., 0., 1., 0., 0., 0.0016, 0., 0., 0.0992, 0., 0.],
        [0., -0.0488, 0., 0., 1., 0., 0., -0.0016, 0., 0., 0.0992, 0.],
        [0., 0., 0., 0., 0., 1., 0., 0., 0., 0., 0., 0.0992],
        [0., 0., 0., 0., 0., 0., 1., 0., 0., 0., 0., 0.],
        [0., 0., 0., 0., 0., 0., 0., 1., 0., 0., 0., 0.],
        [0., 0., 0., 0., 0., 0., 0., 0., 1., 0., 0., 0.],
        [0.9734, 0., 0., 0., 0., 0., 0.0488, 0., 0., 0.9846, 0., 0.],
        [0., -0.9734, 0., 0., 0., 0., 0., -0.0488, 0., 0., 0.9846, 0.],
        [0., 0., 0., 0., 0., 0., 0., 0., 0., 0., 0., 0.9846],
    ];
    Mat::from_fn(12, 12, |i, j| rows[i][j])
}

fn jordan(n: usize, lambda: f64) -> Mat<f64> {
    Mat::from_fn(n, n, |i, j| {
        if i == j {
            lambda
        } else if j == i + 1 {
            1.0
        } else {
            0.0
        }
    })
}

/// An orthogonal matrix (Householder reflection I − 2vvᵀ/vᵀv) that fills every entry.
fn reflection(n: usize) -> Mat<f64> {
    let v: Vec<f64> = (0..n).map(|i| 1.0 + 0.37 * i as f64).collect();
    let vv: f64 = v.iter().map(|x| x * x).sum();
    Mat::from_fn(n, n, |i, j| {
        (if i == j { 1.0 } else { 0.0 }) - 2.0 * v[i] * v[j] / vv
    })
}

#[test]
fn quadrotor_is_marginal_with_chains_of_length_3() {
    let a = quadrotor_a();
    // floating-point eigenvalues of the defective A are not on the unit circle …
    let ev = a.eigenvalues().unwrap();
    let naive = ev.iter().map(|z| z.norm()).fold(0.0, f64::max);
    eprintln!("naive spectral radius of the quadrotor: {naive}");
    // … the structure is: eigenvalue 1 nine times (chains 3, 3, 2, 1), 0.9846 three times.
    let f = classify(a.as_ref()).unwrap();
    assert_eq!(f.stability, Stability::Marginal);
    assert_eq!(f.spectral_radius, 1.0);
    assert_eq!(f.unit_circle_multiplicity, 9);
    assert_eq!(f.longest_chain, 3);
    // hidden by an orthogonal similarity (one dense 12 × 12 block): still marginal.
    let q = reflection(12);
    let dense = &q * &a * q.transpose();
    let f = classify(dense.as_ref()).unwrap();
    assert_eq!(f.block_sizes.last(), Some(&12));
    assert_eq!(f.stability, Stability::Marginal, "{f:?}");
    assert_eq!(f.longest_chain, 3, "{f:?}");
}

#[test]
fn double_integrator_is_marginal() {
    let (a, _) = lti_model::riccati::zoh(
        mat![[0.0, 1.0], [0.0, 0.0]].as_ref(),
        mat![[0.0], [1.0]].as_ref(),
        0.1,
    )
    .unwrap();
    let f = classify(a.as_ref()).unwrap();
    assert_eq!(
        (f.stability, f.longest_chain),
        (Stability::Marginal, 2),
        "{f:?}"
    );
}

#[test]
fn jordan_block_of_size_4() {
    for lambda in [1.0, -1.0] {
        let j = jordan(4, lambda);
        let f = classify(j.as_ref()).unwrap();
        assert_eq!(
            (f.stability, f.longest_chain),
            (Stability::Marginal, 4),
            "{f:?}"
        );
        let q = reflection(4);
        let dense = &q * &j * q.transpose();
        let naive = dense
            .eigenvalues()
            .unwrap()
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max);
        let f = classify(dense.as_ref()).unwrap();
        assert_eq!(f.stability, Stability::Marginal, "naive ρ = {naive}, {f:?}");
        assert_eq!(f.spectral_radius, 1.0);
        assert_eq!(f.unit_circle_multiplicity, 4);
        assert_eq!(f.longest_chain, 4, "{f:?}");
    }
    // just inside and just outside the unit circle: decided, not rounded to marginal.
    for (lambda, want) in [
        (1.0 - 1e-6, Stability::Stable),
        (1.0 + 1e-6, Stability::Unstable),
    ] {
        let q = reflection(4);
        let dense = &q * &jordan(4, lambda) * q.transpose();
        assert_eq!(
            classify(dense.as_ref()).unwrap().stability,
            want,
            "λ = {lambda}"
        );
    }
}

#[test]
fn rotation_is_marginal_and_semisimple() {
    let th: f64 = 0.3;
    let a = mat![[th.cos(), -th.sin()], [th.sin(), th.cos()]];
    let f = classify(a.as_ref()).unwrap();
    assert_eq!(f.stability, Stability::Marginal);
    assert_eq!(f.unit_circle_multiplicity, 2);
    // a rotation block beside a damped state, hidden by a similarity
    let a3 = mat![
        [th.cos(), -th.sin(), 0.0],
        [th.sin(), th.cos(), 0.0],
        [0.2, 0.1, 0.5]
    ];
    let q = reflection(3);
    let f = classify((&q * &a3 * q.transpose()).as_ref()).unwrap();
    assert_eq!(f.stability, Stability::Marginal, "{f:?}");
    // scaled by 1.001: unstable; by 0.999: stable
    assert_eq!(
        classify((&a * 1.001).as_ref()).unwrap().stability,
        Stability::Unstable
    );
    assert_eq!(
        classify((&a * 0.999).as_ref()).unwrap().stability,
        Stability::Stable
    );
}

/// An undamped chain of `n` unit masses with unit springs to each other and to both walls,
/// ZOH at 0.5 s (the structure of `scenarios/mass-chain-undamped.toml`, with n masses):
/// every eigenvalue is on the unit circle (|λ| = 1, semisimple).
fn undamped_chain(n: usize) -> Mat<f64> {
    let a_c = Mat::from_fn(2 * n, 2 * n, |r, c| match (r < n, c < n) {
        (true, true) => 0.0,
        (true, false) => f64::from(u8::from(c - n == r)),
        (false, true) => {
            let (i, j) = (r - n, c);
            if i == j {
                -2.0
            } else if i.abs_diff(j) == 1 {
                1.0
            } else {
                0.0
            }
        }
        (false, false) => 0.0,
    });
    let b_c = Mat::<f64>::zeros(2 * n, 1);
    lti_model::riccati::zoh(a_c.as_ref(), b_c.as_ref(), 0.5)
        .expect("zoh of the chain")
        .0
}

/// Issue 37, item 5: a 10-mass undamped chain and the same A changed by 5e-13 (on the
/// diagonal: every eigenvalue moves out by ≈ 5e-13, beyond the rounding band of 3e-13 the
/// old rule used) get the same verdict, marginal; a real instability (negative damping,
/// |λ| − 1 ≈ 1e-4) is still unstable, and so is one of 1e-8 (far above δ_A·κ).
#[test]
fn marginal_chain_verdict_follows_the_spectrum_not_rounding() {
    let a = undamped_chain(10);
    let shipped = classify(a.as_ref()).expect("classify");
    assert_eq!(shipped.stability, Stability::Marginal, "{shipped:?}");
    let n = a.nrows();
    let nudged = Mat::from_fn(n, n, |i, j| a[(i, j)] + if i == j { 5e-13 } else { 0.0 });
    let ev = nudged.eigenvalues().expect("eigenvalues");
    let naive = ev.iter().map(|z| z.norm()).fold(0.0, f64::max);
    assert!(
        naive > 1.0 + 3e-13,
        "the nudge must move |λ| past the old band: {naive}"
    );
    let f = classify(nudged.as_ref()).expect("classify");
    assert_eq!(f.stability, Stability::Marginal, "{f:?}");
    assert_eq!(f.spectral_radius, 1.0);
    for grow in [1e-4, 1e-8] {
        let unstable = &a * (1.0 + grow);
        let f = classify(unstable.as_ref()).expect("classify");
        assert_eq!(f.stability, Stability::Unstable, "|λ| = 1 + {grow}: {f:?}");
        assert!((f.spectral_radius - 1.0 - grow).abs() < 1e-9, "{f:?}");
    }
}
