//! Q_c ⪰ 0 with (A, Q_c^½) detectable (issue 25, item 5): the DARE terminal cost against
//! independent answers, and the typed refusal of an undetectable pair.

use faer::linalg::solvers::DenseSolveCore;
use faer::{Mat, mat};
use lti_model::riccati::{dare, residual_dare};
use lti_model::system::spectral_radius;
use lti_model::{BoxSet, LtiSystem};
use mpc_core::detectable::undetectable_modes;
use mpc_core::settings::{MpcSettings, RawMpc};
use mpc_core::{CondensedMpc, MpcConfig, MpcError, SaturatedLqr};

/// The scalar DARE's stabilising root: x² + (r − a²r − q)x − qr = 0, the larger root.
fn scalar_dare(a: f64, q: f64, r: f64) -> f64 {
    let p = r - a * a * r - q;
    (-p + (p * p + 4.0 * q * r).sqrt()) / 2.0
}

/// The Riccati value iteration X_{k+1} = AᵀX_kA − AᵀX_kB(R + BᵀX_kB)⁻¹BᵀX_kA + Q from
/// X₀ = 0 (converges to the stabilising solution under stabilisability and detectability;
/// independent of the doubling algorithm behind `dare`).
fn value_iteration(a: &Mat<f64>, b: &Mat<f64>, q: &Mat<f64>, r: &Mat<f64>) -> Mat<f64> {
    let n = a.nrows();
    let mut x = Mat::<f64>::zeros(n, n);
    for _ in 0..20_000 {
        let s = r + b.transpose() * &x * b;
        let sinv = s.partial_piv_lu().inverse();
        let next =
            a.transpose() * &x * a - a.transpose() * &x * b * &sinv * b.transpose() * &x * a + q;
        let diff = (&next - &x).norm_max();
        x = next;
        if diff < 1e-14 * x.norm_max().max(1.0) {
            break;
        }
    }
    x
}

#[test]
fn psd_q_c_dare_matches_the_scalar_closed_form_per_decoupled_mode() {
    // A = diag(2, 0.5), B = I, Q_c = diag(1, 0), R = I: X = diag(2 + √5, 0) (the stable
    // unseen mode costs nothing).
    let a = mat![[2.0, 0.0], [0.0, 0.5]];
    let b = Mat::<f64>::identity(2, 2);
    let q = mat![[1.0, 0.0], [0.0, 0.0]];
    let r = Mat::<f64>::identity(2, 2);
    assert!(
        undetectable_modes(a.as_ref(), q.as_ref())
            .unwrap()
            .is_empty()
    );
    let x = dare(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref()).unwrap();
    assert!((x[(0, 0)] - scalar_dare(2.0, 1.0, 1.0)).abs() < 1e-12);
    assert!((x[(0, 0)] - (2.0 + 5f64.sqrt())).abs() < 1e-12);
    assert!(x[(1, 1)].abs() < 1e-12 && x[(0, 1)].abs() < 1e-12);
    let sys = LtiSystem::new(a, b, Mat::identity(2, 2)).unwrap();
    let mpc = CondensedMpc::new(
        &sys,
        MpcConfig::new(5, q, r, BoxSet::symmetric(&[1.0, 1.0]).unwrap()),
    )
    .unwrap();
    assert!((mpc.terminal_weight()[(0, 0)] - (2.0 + 5f64.sqrt())).abs() < 1e-12);
}

#[test]
fn psd_q_c_seen_through_the_dynamics_matches_value_iteration() {
    // The unstable x₀ (λ = 1.2) is not weighted but drives the weighted x₁: detectable.
    let a = mat![[1.2, 0.0], [0.3, 0.5]];
    let b = mat![[1.0], [0.0]];
    let q = mat![[0.0, 0.0], [0.0, 1.0]];
    let r = mat![[0.1]];
    assert!(
        undetectable_modes(a.as_ref(), q.as_ref())
            .unwrap()
            .is_empty()
    );
    let x = dare(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref()).unwrap();
    let reference = value_iteration(&a, &b, &q, &r);
    assert!(
        (&x - &reference).norm_max() < 1e-9 * reference.norm_max(),
        "doubling {x:?} vs value iteration {reference:?}"
    );
    assert!(
        residual_dare(a.as_ref(), b.as_ref(), q.as_ref(), r.as_ref(), x.as_ref()).unwrap() < 1e-10
    );
    let k = (&r + b.transpose() * &x * &b).partial_piv_lu().inverse() * b.transpose() * &x * &a;
    assert!(spectral_radius((&a - &b * &k).as_ref()).unwrap() < 1.0);
    // The saturated LQR accepts the same PSD weight.
    let sys = LtiSystem::new(a, b, Mat::identity(2, 2)).unwrap();
    SaturatedLqr::new(
        &sys,
        q.as_ref(),
        r.as_ref(),
        BoxSet::symmetric(&[1.0]).unwrap(),
    )
    .unwrap();
}

#[test]
fn undetectable_q_c_is_refused_naming_the_mode() {
    // x₀ (λ = 1.2) neither weighted nor coupled into x₁: undetectable.
    let a = mat![[1.2, 0.0], [0.0, 0.5]];
    let q = mat![[0.0, 0.0], [0.0, 1.0]];
    let modes = undetectable_modes(a.as_ref(), q.as_ref()).unwrap();
    assert_eq!(modes.len(), 1);
    assert!((modes[0].modulus - 1.2).abs() < 1e-12);
    assert_eq!(modes[0].states, vec![0]);
    let sys = LtiSystem::new(a, mat![[1.0], [0.0]], Mat::identity(2, 2)).unwrap();
    let e = CondensedMpc::new(
        &sys,
        MpcConfig::new(
            5,
            q.clone(),
            mat![[1.0]],
            BoxSet::symmetric(&[1.0]).unwrap(),
        ),
    )
    .unwrap_err();
    assert!(matches!(e, MpcError::NotDetectable { .. }), "{e}");
    assert!(e.to_string().contains("x_0"), "{e}");
    // Through the scenario's `[mpc]`: the error names `mpc.q`, the mode and the fix.
    let raw: RawMpc =
        lti_model::spec::format::parse("horizon = 5\nq = { diagonal = [0.0, 1.0] }").unwrap();
    let e = MpcSettings::from_raw(&raw, &sys).unwrap_err().to_string();
    assert!(e.contains("mpc.q"), "{e}");
    assert!(e.contains("|λ| = 1.2"), "{e}");
    assert!(e.contains("x_0"), "{e}");
    assert!(e.contains("positive weight"), "{e}");
    // A marginal unseen mode (λ = 1, e.g. an integrator) is refused too.
    let a1 = mat![[1.0, 0.0], [0.0, 0.5]];
    assert_eq!(
        undetectable_modes(a1.as_ref(), q.as_ref()).unwrap().len(),
        1
    );
}

#[test]
fn complex_unseen_pair_is_one_mode() {
    // A rotation (|λ| = 1, complex pair) in (x₀, x₁), unweighted; x₂ weighted.
    let (c, s) = (0.6, 0.8);
    let a = mat![[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 0.9]];
    let q = mat![[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
    let modes = undetectable_modes(a.as_ref(), q.as_ref()).unwrap();
    assert_eq!(modes.len(), 1, "{modes:?}");
    assert!((modes[0].modulus - 1.0).abs() < 1e-12);
    assert!(modes[0].im > 0.0);
    assert_eq!(modes[0].states, vec![0, 1]);
}

#[test]
fn quadrotor_osqp_weights_with_zeros_are_accepted() {
    // The OSQP documentation's Q_c = diag(0, 0, 10, 10, 10, 10, 0, 0, 0, 5, 5, 5) on the
    // quadrotor of scenarios/quadrotor.toml: roll, pitch and the angle rates are seen
    // through the weighted positions and velocities, so the pair is detectable.
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/quadrotor.toml"
    ))
    .unwrap();
    // The [plant] table's lines (a, b, c), validated as the scenario loader does.
    let plant: String = text
        .lines()
        .skip_while(|l| l.trim() != "[plant]")
        .skip(1)
        .take_while(|l| !l.starts_with('['))
        .map(|l| format!("{l}\n"))
        .collect();
    let raw_plant: lti_model::spec::plant::RawPlant =
        lti_model::spec::format::parse(&plant).unwrap();
    let sys = lti_model::spec::plant::validate_plant(Some(&raw_plant)).unwrap();
    let raw: RawMpc = lti_model::spec::format::parse(
        "horizon = 10\nr = 0.1\nq = { diagonal = [0.0, 0.0, 10.0, 10.0, 10.0, 10.0, 0.0, 0.0, 0.0, 5.0, 5.0, 5.0] }",
    )
    .unwrap();
    let settings = MpcSettings::from_raw(&raw, &sys).unwrap();
    let sets = lti_model::spec::ScenarioSets {
        state: BoxSet::whole(12),
        input: BoxSet::symmetric(&[1.0; 4]).unwrap(),
        output: BoxSet::whole(6),
        disturbance: BoxSet::whole(sys.nw()),
    };
    let mpc = settings.build(&sys, &sets).unwrap();
    let (q, r) = (mpc.q_c().clone(), mpc.r_c().clone());
    let x = mpc.terminal_weight();
    let reference = value_iteration(&sys.a().to_owned(), &sys.b().to_owned(), &q, &r);
    assert!(
        (x - &reference).norm_max() < 1e-6 * reference.norm_max(),
        "doubling vs value iteration: {:e}",
        (x - &reference).norm_max()
    );
}
