//! The exact MPC law against an independent uncondensed Clarabel solve, 𝒰 exactly
//! respected, the condensation consistent with simulation, and MPC = LQR unconstrained.

use faer::Mat;
use lti_model::{BoxSet, ConvexSet, Projection};
use mpc_core::{CondensedMpc, Controller, ExactMpc, MpcConfig};

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
fn check_against_uncondensed(mpc: &CondensedMpc, points: &[Vec<f64>], tol: f64) {
    let mut exact = ExactMpc::new(mpc).unwrap();
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
        let sol = exact.solve(x).unwrap().clone();
        let seq = sol.z.clone();
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
        assert!(
            sol.kkt_residual <= 1e-9 * (1.0 + xmax),
            "x̂ = {x:?}: KKT residual {:e}",
            sol.kkt_residual
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
    let seq = exact.solve(&x).unwrap().z.clone();
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
