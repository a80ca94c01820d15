//! K_lin: the lifted LTI system of Alg. 1 against the real closed loop (build_case_study +
//! step), the K-step map against brute force, PG's step against its closed form.

use crate::build;
use closed_loop::scenario::Scenario;
use closed_loop::scenario::{
    ControllerChoice, LoopOptions, ResolvedScenario, ScenarioController, ScenarioLoop,
};
use faer::{Mat, Par};
use iss_certificate::linear::log_spaced;
use iss_certificate::linear::{
    LiftedLayout, LiftedLoop, LinearError, LinearReport, linear_stability, linearise,
    spectral_radius,
};
use mhe_core::WarmStart;
use qp_iter::IterationMap;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{Method, MethodMap};
use rand::{Rng, SeedableRng};

/// An open-loop unstable plant (eigenvalues 1.5 and 0.8), input and disturbance
/// unconstrained, no noise: no constraint can become active, so the closed loop *is* the
/// lifted LTI system for t ≥ M. (A, B) is controllable and (A, C) observable.
const UNSTABLE: &str = include_str!("../data/unstable-2state.toml");

const CERTIFIED: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../scenarios/case-study-certified.toml"
);

const METHODS: [Method; 8] = Method::ALL;

fn unstable() -> Scenario {
    Scenario::from_toml_str(UNSTABLE).unwrap()
}

fn options(s: &Scenario, solver: Method, k: usize, controller: ControllerChoice) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(s).unwrap();
    o.method = solver;
    o = o.with_iterations(k).expect("K is in range");
    o.controller = controller;
    o
}

fn resolve(s: &Scenario) -> ResolvedScenario {
    s.clone().resolve().unwrap()
}

use lti_model::vecmath::norm2 as norm;

/// z⁰ of the MHE at the loop's current t.
fn warm_start_point(cl: &ScenarioLoop) -> Vec<f64> {
    cl.estimator().warm_start_point().to_vec()
}

/// U_{t−1} of the sub-optimal MPC (empty for a static law).
fn controller_state(cl: &ScenarioLoop) -> Vec<f64> {
    match cl.controller() {
        ScenarioController::Suboptimal(c) => c.input_sequence().to_vec(),
        ScenarioController::Exact(_) | ScenarioController::SaturatedLqr(_) => Vec::new(),
    }
}

/// X_t assembled from the running loop's trace and components (t ≥ M).
fn lifted_state(cl: &ScenarioLoop, l: LiftedLayout) -> Vec<f64> {
    let (t, tr) = (cl.t(), cl.trace());
    let mut x = vec![0.0; l.dim()];
    x[..l.nx].copy_from_slice(cl.state());
    for j in 0..l.horizon {
        let s = t - l.horizon + j;
        x[l.u_window(j)..l.u_window(j) + l.nu].copy_from_slice(tr.u(s).unwrap());
        x[l.y_window(j)..l.y_window(j) + l.ny].copy_from_slice(tr.y(s).unwrap());
        x[l.estimates(j)..l.estimates(j) + l.nx].copy_from_slice(tr.x_hat(s).unwrap());
    }
    x[l.warm_start()..l.warm_start() + l.nz].copy_from_slice(&warm_start_point(cl));
    x[l.controller()..].copy_from_slice(&controller_state(cl));
    x
}

fn apply(a: &Mat<f64>, x: &[f64]) -> Vec<f64> {
    (0..a.nrows())
        .map(|i| (0..a.ncols()).map(|j| a[(i, j)] * x[j]).sum())
        .collect()
}

/// The lifted recursion X_{t+1} = 𝔸(K)X_t reproduces the real closed loop step by step:
/// every block of X (plant, windows, prior ring, warm start, MPC iterate) for 30 steps.
fn check_trajectory(s: &Scenario, o: &LoopOptions) {
    let mut cl = build(s, o).unwrap();
    let lifted = LiftedLoop::from_loop(&cl, &resolve(s), o.method, Par::Seq).unwrap();
    let l = lifted.layout();
    let a = lifted.matrix(o.iterations.get(), Par::Seq).unwrap();
    assert_eq!(a.nrows(), l.dim());
    for _ in 0..l.horizon + 3 {
        cl.step().unwrap();
    }
    let mut x = lifted_state(&cl, l);
    for step in 0..30 {
        cl.step().unwrap();
        x = apply(&a, &x);
        let sim = lifted_state(&cl, l);
        let scale = norm(&sim).max(1e-300);
        let gap = norm(&x.iter().zip(&sim).map(|(p, q)| p - q).collect::<Vec<_>>());
        assert!(
            gap <= 1e-9 * scale,
            "{} K = {} {:?}: step {step}: ‖X_lin − X_sim‖ = {gap:e}, ‖X_sim‖ = {scale:e}",
            o.method,
            o.iterations,
            o.controller
        );
    }
}

#[test]
fn lifted_matrix_reproduces_the_closed_loop_exactly() {
    let s = unstable();
    for solver in METHODS {
        for k in [1, 2, 7] {
            check_trajectory(&s, &options(&s, solver, k, ControllerChoice::ExactMpc));
        }
        check_trajectory(&s, &options(&s, solver, 4, ControllerChoice::SaturatedLqr));
        for mpc in [Method::PG, Method::FISTA, Method::ADMM] {
            let ctrl = ControllerChoice::suboptimal(3, mpc).unwrap();
            check_trajectory(&s, &options(&s, solver, 5, ctrl));
        }
    }
    // The time-shifted warm start (an option, not the paper's Σ_t).
    let mut shifted = unstable();
    shifted.mhe = shifted.mhe.map(|m| m.with_warm_start(WarmStart::Shifted));
    for solver in METHODS {
        check_trajectory(
            &shifted,
            &options(&shifted, solver, 3, ControllerChoice::ExactMpc),
        );
    }
}

/// Growth rate of the simulated loop: (S(T)/S(T₀))^{1/(T−T₀)} with S(t) the largest
/// ‖(x, x̂, u)‖ over the 12 steps up to t (damps the oscillation of complex modes).
fn simulated_rate(s: &Scenario, solver: Method, k: usize, rho: f64) -> f64 {
    // Keep ρ^T inside [1e-120, 1e120] (squares stay finite): T ≤ 120/|log₁₀ρ|, ≤ 360 steps.
    let budget = ((120.0 / rho.log10().abs().max(1e-3)) as usize).min(360);
    let t0 = (budget / 3).min(60);
    let span = budget - t0;
    let mut o = options(s, solver, k, ControllerChoice::ExactMpc);
    o.steps = t0 + span;
    let mut cl = build(s, &o).unwrap();
    let tr = cl.run().unwrap();
    let size = |t: usize| {
        (t.saturating_sub(11)..=t)
            .map(|t| {
                (norm(tr.x(t).unwrap()).powi(2)
                    + norm(tr.x_hat(t).unwrap()).powi(2)
                    + norm(tr.u(t).unwrap()).powi(2))
                .sqrt()
            })
            .fold(0.0, f64::max)
    };
    let end = o.steps - 1;
    (size(end) / size(t0)).powf(1.0 / (end - t0) as f64)
}

/// The brief's check: on both sides of a crossing of ρ_lin = 1 the simulation grows where
/// ρ_lin > 1 and decays where ρ_lin < 1, and its growth rate is ρ_lin to 1 % (measured: ≤ 0.2 %).
#[test]
fn rho_lin_predicts_growth_and_decay_of_the_simulation() {
    let s = unstable();
    for solver in METHODS {
        let o = options(&s, solver, 1, ControllerChoice::ExactMpc);
        let report =
            linear_stability(&resolve(&s), &o, &log_spaced(1, 2000, 40), Par::Seq).unwrap();
        let k_lin = report.k_lin.unwrap();
        assert!(
            k_lin > 1,
            "{solver}: the test plant needs a crossing, K_lin = {k_lin}"
        );
        // The grid points on each side of K_lin nearest to it with |ρ − 1| ≥ 0.02.
        let below = report
            .rho_lin
            .iter()
            .rev()
            .find(|p| p.0 < k_lin && p.1 >= 1.02)
            .copied()
            .unwrap();
        let above = report
            .rho_lin
            .iter()
            .find(|p| p.0 >= k_lin && p.1 <= 0.98)
            .copied()
            .unwrap();
        for (k, rho) in [below, above, report.rho_lin[0]] {
            let rate = simulated_rate(&s, solver, k, rho);
            assert_eq!(
                rate > 1.0,
                rho > 1.0,
                "{solver} K = {k}: ρ_lin = {rho}, simulated {rate}"
            );
            assert!(
                (rate - rho).abs() <= 0.01 * rho,
                "{solver} K = {k}: ρ_lin = {rho}, simulated growth rate {rate}"
            );
        }
    }
}

/// Brute force: K real steps (`run_fixed`) from every unit probe give G_K and J_K.
#[test]
fn k_step_map_matches_brute_force_run_fixed() {
    for s in [unstable(), Scenario::from_file(CERTIFIED).unwrap()] {
        for solver in METHODS {
            let o = options(&s, solver, 1, ControllerChoice::ExactMpc);
            let cl = build(&s, &o).unwrap();
            let e = cl.estimator();
            brute_force(e.map(e.config().horizon).unwrap());
        }
    }
}

fn brute_force<M: iss_certificate::linear::Linearise>(map: &M) {
    let lin = linearise(map, "MHE").unwrap();
    let qp = map.problem();
    let (n, nt) = (qp.n(), qp.n_theta());
    // Probes inside the box: 1e-4 of the smallest bound.
    let h = qp
        .zset()
        .lower()
        .iter()
        .chain(qp.zset().upper())
        .fold(1.0_f64, |m, b| m.min(b.abs()))
        * 1e-4;
    let mut st = map.new_state();
    for k in [1, 2, 5, 37] {
        let km = lin.k_step(k, Par::Seq).unwrap();
        let mut worst = 0.0_f64;
        let mut scale = 0.0_f64;
        for c in 0..n + nt {
            let mut z0 = vec![0.0; n];
            let mut theta = vec![0.0; nt];
            if c < n {
                z0[c] = h;
            } else {
                theta[c - n] = h;
            }
            map.load(&mut st, &theta);
            map.warm_start(&mut st, &z0, None);
            qp_iter::run_fixed(map, &mut st, k);
            let z = map.iterate(&st);
            for r in 0..n {
                let lin_col = if c < n {
                    km.g[(r, c)]
                } else {
                    km.j[(r, c - n)]
                };
                worst = worst.max((z[r] / h - lin_col).abs());
                scale = scale.max(lin_col.abs());
            }
        }
        assert!(
            worst <= 1e-9 * scale.max(1.0),
            "{} K = {k}: brute force differs by {worst:e} (scale {scale:e})",
            map.name()
        );
    }
}

/// PG's probed step is the closed form z⁺ = z − α(Hz + Fθ).
#[test]
fn pg_linearisation_is_the_closed_form() {
    let s = Scenario::from_file(CERTIFIED).unwrap();
    let o = options(&s, Method::PG, 1, ControllerChoice::ExactMpc);
    let cl = build(&s, &o).unwrap();
    let e = cl.estimator();
    let MethodMap::Pg(pg) = e.map(e.config().horizon).unwrap() else {
        panic!("PG estimator expected")
    };
    let pg: &ProjectedGradient = pg;
    let lin = linearise(pg, "MHE").unwrap();
    let (h, f, alpha) = (pg.problem().h(), pg.problem().f(), pg.alpha());
    let (n, nt) = (h.nrows(), f.ncols());
    let mut worst = 0.0_f64;
    for i in 0..n {
        for j in 0..n {
            let want = if i == j { 1.0 } else { 0.0 } - alpha * h[(i, j)];
            worst = worst.max((lin.step[(i, j)] - want).abs());
        }
        for j in 0..nt {
            worst = worst.max((lin.step[(i, n + j)] + alpha * f[(i, j)]).abs());
        }
    }
    assert!(
        worst <= 1e-12,
        "PG step differs from I − αH, −αF by {worst:e}"
    );
    // Same step rule as built: α = 2/(L + μ).
    let again = ProjectedGradient::new(pg.problem().clone(), StepRule::Optimal).unwrap();
    assert_eq!(again.alpha(), alpha);
}

/// K → ∞: zᴷ → z* = −H⁻¹Fθ whatever z⁰ (G_K → 0, J_K → −H⁻¹F), checked against a
/// Cholesky solve.
#[test]
fn k_step_map_converges_to_the_exact_unconstrained_solution() {
    use faer::linalg::solvers::Solve;
    let s = unstable();
    for solver in METHODS {
        let o = options(&s, solver, 1, ControllerChoice::ExactMpc);
        let cl = build(&s, &o).unwrap();
        let lifted = LiftedLoop::from_loop(&cl, &resolve(&s), o.method, Par::Seq).unwrap();
        let lin = lifted.mhe_linearisation();
        let qp = cl.estimator().map(5).unwrap().problem().clone();
        let exact = qp
            .h()
            .to_owned()
            .llt(faer::Side::Lower)
            .unwrap()
            .solve(qp.f());
        let km = lin.k_step(1 << 20, Par::Seq).unwrap();
        let g_max = km.g.norm_max();
        let j_err = (&km.j + &exact).norm_max() / exact.norm_max();
        assert!(
            g_max < 1e-8 && j_err < 1e-8,
            "{solver}: ‖G‖ = {g_max:e}, J error {j_err:e}"
        );
    }
}

#[test]
fn spectral_radius_of_a_known_spectrum() {
    // T·D·T⁻¹ with D holding 0.3, −1.2 and the complex pair 0.9·e^{±0.7i}: ρ = 1.2, then
    // with the pair scaled to 1.4: ρ = 1.4.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
    let t = Mat::from_fn(4, 4, |i, j| {
        rng.random::<f64>() - 0.5 + if i == j { 2.0 } else { 0.0 }
    });
    let t_inv = {
        use faer::linalg::solvers::Solve;
        t.partial_piv_lu().solve(Mat::<f64>::identity(4, 4))
    };
    for (r, want) in [(0.9, 1.2), (1.4, 1.4)] {
        let (c, sn) = (r * 0.7_f64.cos(), r * 0.7_f64.sin());
        let mut d = Mat::<f64>::zeros(4, 4);
        d[(0, 0)] = 0.3;
        d[(1, 1)] = -1.2;
        d[(2, 2)] = c;
        d[(3, 3)] = c;
        d[(2, 3)] = -sn;
        d[(3, 2)] = sn;
        let m = &t * &d * &t_inv;
        let rho = spectral_radius(m.as_ref(), Par::Seq).unwrap();
        assert!((rho - want).abs() <= 1e-10 * want, "ρ = {rho}, want {want}");
    }
}

#[test]
fn report_finds_k_lin_on_a_non_monotone_sequence() {
    let r = LinearReport::from_pairs(
        Method::PG,
        3,
        vec![(30, 0.9), (1, 1.3), (3, 0.8), (10, 1.0), (100, 0.7)],
    );
    assert_eq!(
        r.rho_lin.iter().map(|p| p.0).collect::<Vec<_>>(),
        [1, 3, 10, 30, 100]
    );
    assert_eq!(r.unstable_ks, [1, 10]);
    assert_eq!(r.k_lin, Some(30));
    let all_stable = LinearReport::from_pairs(Method::PG, 3, vec![(1, 0.5), (2, 0.4)]);
    assert_eq!(
        (all_stable.k_lin, all_stable.unstable_ks.len()),
        (Some(1), 0)
    );
    let top_unstable = LinearReport::from_pairs(Method::PG, 3, vec![(1, 0.5), (2, 1.4)]);
    assert_eq!(top_unstable.k_lin, None);
    let nan = LinearReport::from_pairs(Method::PG, 3, vec![(1, 0.5), (2, f64::NAN)]);
    assert_eq!((nan.k_lin, nan.unstable_ks), (None, vec![2]));
}

#[test]
fn bad_input_gives_typed_errors() {
    let s = unstable();
    let o = options(&s, Method::PG, 1, ControllerChoice::ExactMpc);
    assert_eq!(
        linear_stability(&resolve(&s), &o, &[], Par::Seq).unwrap_err(),
        LinearError::ZeroIterations
    );
    assert_eq!(
        linear_stability(&resolve(&s), &o, &[0, 3], Par::Seq).unwrap_err(),
        LinearError::ZeroIterations
    );
    // The linear analysis of the unstable plant with `sets.disturbance = {box}`: its error.
    let with_w_box = |w_box: &str| {
        let text = UNSTABLE.replace(
            "[noise]",
            &format!("[sets]\ndisturbance = {w_box}\n[noise]"),
        );
        let sc = Scenario::from_toml_str(&text).unwrap();
        linear_stability(&resolve(&sc), &o, &[1], Par::Seq).unwrap_err()
    };
    // 𝒲 with a bound at 0: no neighbourhood of the origin is free of active bounds.
    let err = with_w_box("{ lower = [-1.0, -1.0, 0.0], upper = 1.0 }");
    assert!(
        matches!(
            err,
            LinearError::OriginNotInterior {
                problem: "MHE",
                index: 4,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(!err.to_string().contains("plant.e"), "{err}");
    // A zero-width interval (a user's "no noise on this state"): the message names the fix,
    // `plant.e` with fewer columns.
    let err = with_w_box("{ lower = [-1.0, -1.0, 0.0], upper = [1.0, 1.0, 0.0] }");
    assert!(
        matches!(
            err,
            LinearError::OriginNotInterior {
                lower: 0.0,
                upper: 0.0,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("`plant.e`"), "{err}");
}

/// With constraints that do become active, ρ_lin still decides whether the loop can settle
/// at the origin (where nothing is active): on the certified preset without noise, ADMM with
/// α = 2 has ρ_lin ≥ 1 for small K and its estimation error does not converge (the 𝒲 box
/// keeps it bounded), while beyond K_lin it decays to round-off.
#[test]
fn certified_preset_converges_only_where_rho_lin_is_below_one() {
    let mut s = Scenario::from_file(CERTIFIED).unwrap();
    s.noise.kind = lti_model::spec::NoiseKind::Zero;
    let o = options(&s, Method::ADMM_PR, 1, ControllerChoice::ExactMpc);
    let report =
        linear_stability(&resolve(&s), &o, &[1, 2, 3, 4, 5, 6, 7, 8, 20], Par::Seq).unwrap();
    let k_lin = report.k_lin.unwrap();
    assert!(
        k_lin > 1,
        "ADMM α = 2 on the certified preset: K_lin = {k_lin}"
    );
    for &(k, rho) in &report.rho_lin {
        if (rho - 1.0).abs() < 0.05 {
            continue;
        }
        let mut o = options(&s, Method::ADMM_PR, k, ControllerChoice::ExactMpc);
        o.steps = 300;
        let mut cl = build(&s, &o).unwrap();
        let tr = cl.run().unwrap();
        let tail = tr.e_norms()[250..].iter().fold(0.0_f64, |m, &e| m.max(e));
        if rho > 1.0 {
            assert!(tail > 1e-3, "K = {k}, ρ_lin = {rho}: ‖e‖ fell to {tail:e}");
        } else {
            assert!(tail < 1e-12, "K = {k}, ρ_lin = {rho}: ‖e‖ still {tail:e}");
        }
    }
}

/// The K-step maps shared along the grid (`LiftedLoop::spectral_radii`) give the ρ_lin of
/// the per-K repeated squaring (`LiftedLoop::spectral_radius`) to 1e-10, for every method
/// (including FISTA's two-vector state and the Jacobi-scaled maps) on the unstable plant and
/// on the certified preset, with K on both sides of ρ_lin = 1.
#[test]
fn rho_lin_along_the_grid_equals_the_per_k_computation() {
    let certified = Scenario::from_file(CERTIFIED).unwrap();
    let grid = [1usize, 2, 3, 7, 16, 40, 100, 513, 2000];
    for s in [unstable(), certified] {
        for solver in METHODS {
            let o = options(&s, solver, 1, ControllerChoice::ExactMpc);
            let cl = build(&s, &o).unwrap();
            let lifted = LiftedLoop::from_loop(&cl, &resolve(&s), o.method, Par::Seq).unwrap();
            let mut seen = Vec::new();
            let along = lifted
                .spectral_radii(&grid, Par::Seq, &mut |k| seen.push(k))
                .unwrap();
            assert_eq!(seen, grid);
            for (k, rho) in along {
                let direct = lifted.spectral_radius(k, Par::Seq).unwrap();
                assert!(
                    (rho - direct).abs() <= 1e-10 * direct.max(1e-3),
                    "{} {solver} K = {k}: along the grid {rho}, per K {direct}",
                    s.name
                );
            }
        }
    }
}

/// Beyond the analysis budget ρ_lin is not computed, and the error names the estimate, the
/// budget and the scenario key; within it the budgeted call equals the unbudgeted one.
#[test]
fn rho_lin_beyond_the_budget_names_the_key() {
    use iss_certificate::linear::linear_stability_all_budgeted;
    let s = Scenario::from_file(CERTIFIED).unwrap();
    let r = resolve(&s);
    let opts: Vec<LoopOptions> = Method::PRESETS
        .iter()
        .map(|&m| options(&s, m, 1, ControllerChoice::ExactMpc))
        .collect();
    let grid = log_spaced(1, 2000, 25);
    let over = linear_stability_all_budgeted(&r, &opts, &grid, 1e-9, &|_, _| {});
    for e in &over {
        let e = e.as_ref().unwrap_err();
        assert!(matches!(e, LinearError::OverBudget { .. }), "{e}");
        let text = e.to_string();
        assert!(
            text.contains("certificate.phase_seconds") && text.contains("1.00e-9"),
            "{text}"
        );
    }
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let within = linear_stability_all_budgeted(&r, &opts, &grid, 1e6, &|_, _| {
        calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    });
    assert_eq!(calls.into_inner(), opts.len() * grid.len());
    let plain = iss_certificate::linear::linear_stability_all(&r, &opts, &grid);
    assert_eq!(within, plain);
}
