//! The exact MPC law against an independent uncondensed Clarabel solve, 𝒰 exactly
//! respected, the condensation consistent with simulation, and MPC = LQR unconstrained.

use faer::Mat;
use lti_model::{BoxSet, ConvexSet, Projection};
use mpc_core::{CondensedMpc, Controller, ExactBackend, ExactMpc, MpcConfig};
use qp_iter::reference::ReferenceSettings;

use crate::common::*;

/// Points from small to far outside the saturation region.
fn sample_points(nx: usize, seed: u64, count: usize) -> Vec<Vec<f64>> {
    let mut r = rng(seed);
    let scales = [0.01, 0.3, 1.0, 5.0, 30.0, 1e3];
    (0..count)
        .map(|i| gaussian(&mut r, nx, scales[i % scales.len()]))
        .collect()
}

/// |U − U_ref|∞ ≤ tol·(1 + |U_ref|∞); independently, our objective must not exceed the
/// reference's (clipped into 𝒰^N to make it feasible) and our KKT residual must be tiny.
/// Both backends (active set, the default, and Clarabel) are checked.
fn check_against_uncondensed(mpc: &CondensedMpc, points: &[Vec<f64>], tol: f64) {
    for backend in [
        ExactBackend::default(),
        ExactBackend::Clarabel(ReferenceSettings::default()),
    ] {
        let mut exact = ExactMpc::with_backend(mpc, backend).unwrap();
        check_backend(&mut exact, mpc, points, tol);
        assert_eq!(exact.fallbacks(), 0, "{backend:?}");
    }
}

/// ‖U − Π(U − (HU + q))‖∞, computed here from the QP data.
fn natural_residual(mpc: &CondensedMpc, q: &[f64], seq: &[f64]) -> f64 {
    let h = mpc.qp().h();
    let n = seq.len();
    let mut t: Vec<f64> = (0..n)
        .map(|i| seq[i] - ((0..n).map(|j| h[(i, j)] * seq[j]).sum::<f64>() + q[i]))
        .collect();
    mpc.qp().zset().project(&mut t);
    max_abs_diff(seq, &t)
}

fn check_backend(exact: &mut ExactMpc, mpc: &CondensedMpc, points: &[Vec<f64>], tol: f64) {
    let (nu, n) = (mpc.nu(), mpc.horizon());
    for x in points {
        let mut reference = uncondensed_solve(
            mpc.system(),
            mpc.q_c(),
            mpc.r_c(),
            mpc.terminal_weight(),
            mpc.input_set(),
            n,
            x,
        );
        let seq = exact.solve(x).unwrap().to_vec();
        assert_eq!(exact.input_sequence(), Some(&seq[..]));
        let xmax = x.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let scale = 1.0 + reference.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let err = max_abs_diff(&seq, &reference);
        assert!(
            err <= tol * scale,
            "x̂ = {x:?}: ‖U − U_ref‖∞ = {err:e}\n U = {seq:?}\n ref = {reference:?}"
        );
        let mut q = vec![0.0; mpc.qp().n()];
        mpc.qp().linear_term(x, &mut q);
        mpc.qp().zset().project(&mut reference);
        let (ours, theirs) = (
            mpc.qp().objective(&q, &seq),
            mpc.qp().objective(&q, &reference),
        );
        assert!(
            ours <= theirs + 1e-13 * theirs.abs().max(1.0),
            "x̂ = {x:?}: objective {ours} > reference {theirs}"
        );
        let kkt = natural_residual(mpc, &q, &seq);
        assert!(
            kkt <= 1e-9 * (1.0 + xmax),
            "x̂ = {x:?}: KKT residual {kkt:e}"
        );
        let mut u = vec![0.0; nu];
        exact.control(x, &mut u).unwrap();
        assert!(max_abs_diff(&u, &reference[..nu]) <= tol * scale);
        // 𝒰 respected exactly, no tolerance.
        assert!(mpc.input_set().contains(&u, 0.0), "u = {u:?} outside 𝒰");
    }
}

#[test]
fn case_study_matches_uncondensed_clarabel() {
    let mpc = case_study_mpc();
    let mut pts = sample_points(4, 11, 24);
    pts.push(vec![12.0, -10.0, 10.0, -10.0]); // x₀ of the case study
    pts.push(vec![0.0; 4]);
    check_against_uncondensed(&mpc, &pts, 1e-7);
}

#[test]
fn random_systems_match_uncondensed_clarabel() {
    for seed in 0..25 {
        let (sys, cfg) = random_problem(1000 + seed);
        let mpc = CondensedMpc::new(&sys, cfg).unwrap();
        let pts = sample_points(sys.nx(), 2000 + seed, 8);
        check_against_uncondensed(&mpc, &pts, 1e-7);
    }
}

#[test]
fn warm_started_closed_loop_equals_clarabel_and_reuses_the_working_set() {
    // A nominal closed loop from the case study's x₀: the warm-started active set agrees
    // with Clarabel at every step, needs no fallback, and mostly finishes in one
    // subspace solve once the working set settles.
    let mpc = case_study_mpc();
    let sys = mpc.system().clone();
    let mut fast = ExactMpc::new(&mpc).unwrap();
    let mut slow = ExactMpc::with_settings(&mpc, ReferenceSettings::default()).unwrap();
    let mut x = vec![12.0, -10.0, 10.0, -10.0];
    let (mut one_solve, mut saturated, steps) = (0, 0, 60);
    for _ in 0..steps {
        let a = fast.solve(&x).unwrap().to_vec();
        let b = slow.solve(&x).unwrap().to_vec();
        let scale = 1.0 + b.iter().map(|v| v.abs()).fold(0.0, f64::max);
        assert!(max_abs_diff(&a, &b) <= 1e-7 * scale, "x = {x:?}");
        let info = fast.last_info().unwrap();
        one_solve += usize::from(info.iterations == 1);
        saturated += usize::from(a[..2].iter().any(|v| v.abs() == 1.0));
        let mut xn = vec![0.0; 4];
        let (am, bm) = (sys.a(), sys.b());
        for i in 0..4 {
            xn[i] = (0..4).map(|j| am[(i, j)] * x[j]).sum::<f64>()
                + (0..2).map(|j| bm[(i, j)] * a[j]).sum::<f64>();
        }
        x = xn;
    }
    assert_eq!(fast.fallbacks(), 0);
    assert!(slow.last_info().is_none());
    assert!(
        saturated >= 1,
        "the loop never saturates: the test does not exercise 𝒰"
    );
    assert!(
        one_solve >= steps / 2,
        "only {one_solve}/{steps} calls in one subspace solve"
    );
}

#[test]
fn saturation_far_away_and_exact_box() {
    // Far outside, the inputs saturate; the law must return points of 𝒰 exactly.
    let mpc = case_study_mpc();
    let mut exact = ExactMpc::new(&mpc).unwrap();
    let mut saturated = 0;
    for x in sample_points(4, 5, 60) {
        let mut u = [0.0; 2];
        exact.control(&x, &mut u).unwrap();
        assert!(u.iter().all(|v| (-1.0..=1.0).contains(v)), "u = {u:?}");
        if u.iter().any(|v| v.abs() == 1.0) {
            saturated += 1;
        }
    }
    assert!(
        saturated >= 10,
        "only {saturated} saturated samples: the test does not exercise the box"
    );
}

#[test]
fn condensed_cost_equals_simulated_cost() {
    // ½UᵀHU + (Fx̂)ᵀU + const(x̂) = J(x̂, U) simulated step by step.
    let mut r = rng(3);
    for seed in 0..10 {
        let (sys, cfg) = random_problem(300 + seed);
        let mpc = CondensedMpc::new(&sys, cfg).unwrap();
        let n = mpc.qp().n();
        let x = gaussian(&mut r, sys.nx(), 2.0);
        let useq = gaussian(&mut r, n, 1.0);
        let mut q = vec![0.0; n];
        mpc.qp().linear_term(&x, &mut q);
        let condensed = mpc.qp().objective(&q, &useq) + mpc.cost_constant(&x).unwrap();
        let simulated = mpc.cost(&x, &useq).unwrap();
        assert!(
            (condensed - simulated).abs() <= 1e-10 * simulated.abs().max(1.0),
            "{condensed} vs {simulated}"
        );
    }
}

#[test]
fn unconstrained_mpc_with_dare_terminal_is_lqr() {
    // With 𝒰 = ℝ^{n_u} and P_f = DARE solution, the Bellman recursion gives P_k = P_f for all k,
    // so u*₀ = −Kx̂ with the LQR gain K (computed here by an independent Riccati iteration).
    for (i, (sys, cfg)) in [(case_study_system(), case_study_config())]
        .into_iter()
        .chain((0..10).map(|s| random_problem(500 + s)))
        .enumerate()
    {
        let nu = sys.nu();
        let cfg = MpcConfig {
            input_set: BoxSet::whole(nu),
            ..cfg
        };
        let mpc = CondensedMpc::new(&sys, cfg.clone()).unwrap();
        let (k, p) = riccati_by_iteration(&sys, &cfg.q_c, &cfg.r_c);
        let dp = (&p - mpc.terminal_weight()).norm_max();
        assert!(
            dp <= 1e-8 * p.norm_max(),
            "case {i}: DARE differs from the Riccati iteration by {dp:e}"
        );
        let mut exact = ExactMpc::new(&mpc).unwrap();
        let mut r = rng(77 + i as u64);
        for _ in 0..5 {
            let x = gaussian(&mut r, sys.nx(), 10.0);
            let mut u = vec![0.0; nu];
            exact.control(&x, &mut u).unwrap();
            let kx: Vec<f64> = (0..nu)
                .map(|a| -(0..sys.nx()).map(|b| k[(a, b)] * x[b]).sum::<f64>())
                .collect();
            let scale = 1.0 + kx.iter().map(|v| v.abs()).fold(0.0, f64::max);
            assert!(
                max_abs_diff(&u, &kx) <= 1e-7 * scale,
                "case {i}: u = {u:?}, −Kx = {kx:?}"
            );
        }
        // Closed form: E₀H⁻¹F = K.
        let c = mpc.lipschitz_certified().unwrap();
        let kn = lti_model::matrix::spectral_norm(k.as_ref());
        assert!((c.unconstrained_gain - kn).abs() <= 1e-8 * kn.max(1.0));
    }
}

#[test]
fn given_terminal_weight_is_used() {
    let sys = case_study_system();
    let pf = Mat::<f64>::identity(4, 4) * 3.0;
    let cfg = MpcConfig {
        terminal: mpc_core::Terminal::Given(pf.clone()),
        ..case_study_config()
    };
    let mpc = CondensedMpc::new(&sys, cfg).unwrap();
    assert_eq!(mpc.terminal_weight(), &pf);
    let x = [1.0, -2.0, 0.5, 3.0];
    let reference = uncondensed_solve(&sys, mpc.q_c(), mpc.r_c(), &pf, mpc.input_set(), 10, &x);
    let mut exact = ExactMpc::new(&mpc).unwrap();
    let seq = exact.solve(&x).unwrap().to_vec();
    assert!(max_abs_diff(&seq, &reference) <= 1e-7);
}

#[test]
fn whole_state_set_is_accepted() {
    let cfg = MpcConfig {
        state_set: Some(BoxSet::whole(4)),
        ..case_study_config()
    };
    assert!(CondensedMpc::new(&case_study_system(), cfg).is_ok());
}
