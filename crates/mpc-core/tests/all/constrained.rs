//! The MPC with state constraints x_k ∈ 𝒳 (k = 1..N): the exact MPC against an uncondensed
//! Clarabel solve, infeasible steps (typed error from `solve`, documented fallback and
//! status from `control`), the K-iteration MPC, and the void L_π.

use faer::Mat;
use lti_model::{BoxSet, LtiSystem};
use mpc_core::{
    CondensedMpc, ControlStatus, Controller, ExactMpc, MpcConfig, MpcError, MpcFallback,
    STATE_CONSTRAINED_VOID_REASON, SuboptimalMpc, WarmStart, lipschitz_report_for,
};
use qp_iter::QpError;
use qp_iter::method::Method;
use qp_iter::reference::clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use rand::Rng;

use crate::common::{csc, gaussian, random_problem, rng};

/// Uncondensed: v = (x₀…x_N, u₀…u_{N−1}), x₀ = x̂, x_{k+1} = Ax_k + Bu_k, u_k ∈ 𝒰,
/// x_k ∈ 𝒳 (k = 1..N). `None` if Clarabel says infeasible.
fn uncondensed(mpc: &CondensedMpc, xs: &BoxSet, x_hat: &[f64]) -> Option<Vec<f64>> {
    uncondensed_with_outputs(mpc, xs, None, x_hat)
}

/// [`uncondensed`] with output rows C x_k ∈ 𝒴_c (k = 1..N) as well.
fn uncondensed_with_outputs(
    mpc: &CondensedMpc,
    xs: &BoxSet,
    ys: Option<&BoxSet>,
    x_hat: &[f64],
) -> Option<Vec<f64>> {
    let sys = mpc.system();
    let (nx, nu, n) = (sys.nx(), sys.nu(), mpc.horizon());
    let nvx = (n + 1) * nx;
    let nv = nvx + n * nu;
    let mut p = Mat::<f64>::zeros(nv, nv);
    for k in 0..=n {
        let w = if k < n {
            mpc.q_c()
        } else {
            mpc.terminal_weight()
        };
        for i in 0..nx {
            for j in 0..nx {
                p[(k * nx + i, k * nx + j)] = 2.0 * w[(i, j)];
            }
        }
    }
    for k in 0..n {
        for i in 0..nu {
            for j in 0..nu {
                p[(nvx + k * nu + i, nvx + k * nu + j)] = 2.0 * mpc.r_c()[(i, j)];
            }
        }
    }
    let mut rows: Vec<(Vec<(usize, f64)>, f64)> = Vec::new();
    for i in 0..nx {
        rows.push((vec![(i, 1.0)], x_hat[i]));
    }
    for k in 0..n {
        for i in 0..nx {
            let mut r = vec![((k + 1) * nx + i, 1.0)];
            for j in 0..nx {
                r.push((k * nx + j, -sys.a()[(i, j)]));
            }
            for j in 0..nu {
                r.push((nvx + k * nu + j, -sys.b()[(i, j)]));
            }
            rows.push((r, 0.0));
        }
    }
    let neq = rows.len();
    let mut bound = |v: usize, lo: f64, hi: f64| {
        if hi.is_finite() {
            rows.push((vec![(v, 1.0)], hi));
        }
        if lo.is_finite() {
            rows.push((vec![(v, -1.0)], -lo));
        }
    };
    let us = mpc.input_set();
    for k in 0..n {
        for i in 0..nu {
            bound(nvx + k * nu + i, us.lower()[i], us.upper()[i]);
        }
        for i in 0..nx {
            bound((k + 1) * nx + i, xs.lower()[i], xs.upper()[i]);
        }
    }
    if let Some(ys) = ys {
        let c = sys.c();
        for k in 1..=n {
            for i in 0..sys.ny() {
                let row = |sign: f64| -> Vec<(usize, f64)> {
                    (0..nx).map(|j| (k * nx + j, sign * c[(i, j)])).collect()
                };
                if ys.upper()[i].is_finite() {
                    rows.push((row(1.0), ys.upper()[i]));
                }
                if ys.lower()[i].is_finite() {
                    rows.push((row(-1.0), -ys.lower()[i]));
                }
            }
        }
    }
    let am = Mat::from_fn(rows.len(), nv, |r, v| {
        rows[r]
            .0
            .iter()
            .filter(|(k, _)| *k == v)
            .map(|(_, x)| x)
            .sum()
    });
    let b: Vec<f64> = rows.iter().map(|r| r.1).collect();
    let mut cones = vec![SupportedConeT::ZeroConeT(neq)];
    if rows.len() > neq {
        cones.push(SupportedConeT::NonnegativeConeT(rows.len() - neq));
    }
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-12)
        .tol_gap_rel(1e-12)
        .tol_feas(1e-12)
        .max_iter(400)
        .build()
        .unwrap();
    let mut s = DefaultSolver::new(
        &csc(&p, true),
        &vec![0.0; nv],
        &csc(&am, false),
        &b,
        &cones,
        settings,
    )
    .unwrap();
    s.solve();
    match s.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Some(s.solution.x[nvx..].to_vec()),
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => None,
        other => panic!("uncondensed Clarabel: {other:?}"),
    }
}

/// A random MPC with a random 𝒳 (some components bounded, around 0).
fn constrained(seed: u64) -> (LtiSystem, MpcConfig, BoxSet) {
    let (sys, mut cfg) = random_problem(seed);
    let mut r = rng(seed ^ 0x5757);
    let nx = sys.nx();
    let lo = (0..nx)
        .map(|_| {
            if r.random::<f64>() < 0.7 {
                -(0.3 + 2.0 * r.random::<f64>())
            } else {
                f64::NEG_INFINITY
            }
        })
        .collect();
    let hi = (0..nx)
        .map(|_| {
            if r.random::<f64>() < 0.7 {
                0.3 + 2.0 * r.random::<f64>()
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let xs = BoxSet::new(lo, hi).unwrap();
    cfg.state_set = Some(xs.clone());
    (sys, cfg, xs)
}

#[test]
fn state_constrained_exact_mpc_matches_uncondensed_clarabel_and_agrees_on_infeasibility() {
    let (mut feasible, mut infeasible, mut worst) = (0, 0, 0.0f64);
    for seed in 0..150u64 {
        let (sys, cfg, xs) = constrained(seed);
        let mpc = CondensedMpc::new(&sys, cfg).unwrap();
        let mut exact = ExactMpc::new(&mpc).unwrap();
        let mut r = rng(seed);
        for _ in 0..4 {
            let x_hat = gaussian(&mut r, sys.nx(), 1.0);
            let reference = uncondensed(&mpc, &xs, &x_hat);
            match (exact.solve(&x_hat), reference) {
                (Ok(u), Some(uc)) => {
                    let d: f64 = u
                        .iter()
                        .zip(&uc)
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum::<f64>()
                        .sqrt();
                    let s = 1.0 + uc.iter().map(|v| v * v).sum::<f64>().sqrt();
                    assert!(d / s <= 1e-7, "seed {seed}: {:.3e}", d / s);
                    worst = worst.max(d / s);
                    feasible += 1;
                }
                (Err(MpcError::Qp(QpError::Infeasible { .. })), None) => infeasible += 1,
                (a, b) => panic!("seed {seed}: exact {a:?} vs Clarabel {b:?}"),
            }
        }
    }
    println!("{feasible} feasible (worst rel. {worst:.3e}), {infeasible} infeasible");
    assert!(feasible > 100 && infeasible > 10, "{feasible} {infeasible}");
}

/// An MPC whose 𝒳 cannot be met from far away: x₁ ∈ [−1, 1] with |u| ≤ 1 on a double integrator.
fn tight() -> CondensedMpc {
    let sys = LtiSystem::new(
        faer::mat![[1.0, 0.1], [0.0, 1.0]],
        faer::mat![[0.005], [0.1]],
        faer::mat![[1.0, 0.0]],
    )
    .unwrap();
    let mut cfg = MpcConfig::new(
        5,
        Mat::identity(2, 2),
        faer::mat![[0.1]],
        BoxSet::symmetric(&[1.0]).unwrap(),
    );
    cfg.state_set = Some(BoxSet::symmetric(&[1.0, 10.0]).unwrap());
    CondensedMpc::new(&sys, cfg).unwrap()
}

#[test]
fn an_infeasible_step_is_a_typed_error_of_solve_and_a_documented_fallback_of_control() {
    let mpc = tight();
    let mut exact = ExactMpc::new(&mpc).unwrap();
    let far = [5.0, 0.0];
    assert!(matches!(
        exact.solve(&far),
        Err(MpcError::Qp(QpError::Infeasible {
            constraint: Some(_),
            ..
        }))
    ));
    let mut u = [0.0];
    exact.control(&far, &mut u).unwrap();
    assert!(matches!(
        exact.status(),
        ControlStatus::Infeasible {
            fallback: MpcFallback::InputOnlyMpc,
            ..
        }
    ));
    // The fallback is u*₀ of the same MPC without the state rows.
    let box_only = CondensedMpc::new(
        mpc.system(),
        MpcConfig::new(
            5,
            Mat::identity(2, 2),
            faer::mat![[0.1]],
            BoxSet::symmetric(&[1.0]).unwrap(),
        ),
    )
    .unwrap();
    let mut reference = ExactMpc::new(&box_only).unwrap();
    let mut u_ref = [0.0];
    reference.control(&far, &mut u_ref).unwrap();
    assert!((u[0] - u_ref[0]).abs() < 1e-12, "{u:?} {u_ref:?}");
    // A feasible x̂ afterwards: the status says so again.
    exact.control(&[0.2, 0.0], &mut u).unwrap();
    assert_eq!(exact.status(), ControlStatus::Applied { violation: 0.0 });

    // The K-iteration MPC with PG / FISTA: exact projection, feasible plans, and the
    // shifted plan on an infeasible step.
    for method in [Method::PG, Method::FISTA] {
        let map = method.build(mpc.qp().clone()).unwrap();
        let mut sub = SuboptimalMpc::new(&mpc, map, 30, WarmStart::default()).unwrap();
        sub.control(&[0.5, 0.0], &mut u).unwrap();
        match sub.status() {
            ControlStatus::Applied { violation } => assert!(violation <= 1e-9, "{violation}"),
            other => panic!("{other:?}"),
        }
        sub.control(&far, &mut u).unwrap();
        assert!(matches!(
            sub.status(),
            ControlStatus::Infeasible {
                fallback: MpcFallback::ShiftedPlan,
                ..
            }
        ));
        assert!(u[0].abs() <= 1.0);
    }
    // ADMM on the rows: its violation is reported, not hidden.
    let map = Method::ADMM.build(mpc.qp().clone()).unwrap();
    let mut sub = SuboptimalMpc::new(&mpc, map, 3, WarmStart::default()).unwrap();
    sub.control(&[0.9, 1.0], &mut u).unwrap();
    assert!(matches!(sub.status(), ControlStatus::Applied { violation } if violation.is_finite()));
}

#[test]
fn l_pi_is_void_with_state_constraints() {
    let mpc = tight();
    assert_eq!(
        mpc.certificate_void_reason(),
        Some(STATE_CONSTRAINED_VOID_REASON)
    );
    let rep = lipschitz_report_for(&mpc, 50, 0, 1.0).unwrap();
    assert!(rep.l_pi().is_infinite() && rep.void_reason.is_some());
    assert!(rep.to_string().contains("void"));
}

/// A random MPC with a random output box 𝒴_c (some components bounded, around 0) and no
/// state rows.
fn output_constrained(seed: u64) -> (LtiSystem, MpcConfig, BoxSet) {
    let (sys, mut cfg) = random_problem(seed);
    let mut r = rng(seed ^ 0x0707);
    let ny = sys.ny();
    let mut side = |sign: f64| -> Vec<f64> {
        (0..ny)
            .map(|_| {
                if r.random::<f64>() < 0.8 {
                    sign * (0.3 + 2.0 * r.random::<f64>())
                } else {
                    sign * f64::INFINITY
                }
            })
            .collect()
    };
    let (mut lo, hi) = (side(-1.0), side(1.0));
    if lo.iter().chain(&hi).all(|v| v.is_infinite()) {
        lo[0] = -0.5;
    }
    let ys = BoxSet::new(lo, hi).unwrap();
    cfg.state_set = None;
    cfg.output_set = Some(ys.clone());
    (sys, cfg, ys)
}

#[test]
fn output_constrained_exact_mpc_matches_uncondensed_clarabel() {
    let (mut feasible, mut infeasible, mut active, mut worst) = (0, 0, 0, 0.0f64);
    for seed in 0..120u64 {
        let (sys, cfg, ys) = output_constrained(seed);
        let whole = BoxSet::whole(sys.nx());
        let mpc = CondensedMpc::new(&sys, cfg).unwrap();
        assert!(mpc.has_output_constraints() && !mpc.has_state_constraints());
        assert_eq!(
            mpc.certificate_void_reason(),
            Some(mpc_core::OUTPUT_CONSTRAINED_VOID_REASON)
        );
        let mut exact = ExactMpc::new(&mpc).unwrap();
        let mut r = rng(seed);
        for _ in 0..4 {
            let x_hat = gaussian(&mut r, sys.nx(), 1.0);
            let reference = uncondensed_with_outputs(&mpc, &whole, Some(&ys), &x_hat);
            match (exact.solve(&x_hat).map(<[f64]>::to_vec), reference) {
                (Ok(u), Some(uc)) => {
                    let d: f64 = u
                        .iter()
                        .zip(&uc)
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum::<f64>()
                        .sqrt();
                    let s = 1.0 + uc.iter().map(|v| v * v).sum::<f64>().sqrt();
                    assert!(d / s <= 1e-7, "seed {seed}: {:.3e}", d / s);
                    worst = worst.max(d / s);
                    feasible += 1;
                    // Is an output row active at the optimum?
                    let g = mpc.qp().general().unwrap();
                    let gz =
                        g.g() * lti_model::matrix::col(&u) + g.e() * lti_model::matrix::col(&x_hat);
                    if (0..g.m()).any(|p| {
                        (gz[(p, 0)] - g.upper()[p]).abs() < 1e-7
                            || (gz[(p, 0)] - g.lower()[p]).abs() < 1e-7
                    }) {
                        active += 1;
                    }
                }
                (Err(MpcError::Qp(QpError::Infeasible { .. })), None) => infeasible += 1,
                (a, b) => panic!("seed {seed}: exact {a:?} vs Clarabel {b:?}"),
            }
        }
    }
    println!(
        "{feasible} feasible ({active} with an active output row, worst rel. {worst:.3e}), {infeasible} infeasible"
    );
    assert!(
        feasible > 100 && active > 20,
        "{feasible} {active} {infeasible}"
    );
}

#[test]
fn an_active_output_bound_moves_the_plan_and_is_met() {
    // Double integrator, y = position, |y| ≤ 0.5: from x̂ = (0.4, 1.0) the input-only MPC
    // overshoots 0.5; with the output row the plan keeps C x_k ≤ 0.5 and Clarabel agrees.
    let sys = LtiSystem::new(
        faer::mat![[1.0, 0.1], [0.0, 1.0]],
        faer::mat![[0.005], [0.1]],
        faer::mat![[1.0, 0.0]],
    )
    .unwrap();
    let mut cfg = MpcConfig::new(
        10,
        Mat::identity(2, 2),
        faer::mat![[0.1]],
        BoxSet::symmetric(&[5.0]).unwrap(),
    );
    let free = CondensedMpc::new(&sys, cfg.clone()).unwrap();
    let ys = BoxSet::symmetric(&[0.5]).unwrap();
    cfg.output_set = Some(ys.clone());
    let mpc = CondensedMpc::new(&sys, cfg).unwrap();
    assert_eq!(mpc.qp().general().unwrap().m(), 10);
    assert_eq!(mpc.output_row(3), Some((4, 0)));
    let x_hat = [0.4, 1.0];
    let peak = |m: &CondensedMpc, u: &[f64]| -> f64 {
        let x = m.phi() * lti_model::matrix::col(&x_hat) + m.gamma() * lti_model::matrix::col(u);
        (0..m.horizon())
            .map(|k| x[(2 * k, 0)])
            .fold(f64::MIN, f64::max)
    };
    let u_free = ExactMpc::new(&free)
        .unwrap()
        .solve(&x_hat)
        .unwrap()
        .to_vec();
    assert!(
        peak(&free, &u_free) > 0.5 + 1e-3,
        "{}",
        peak(&free, &u_free)
    );
    let u = ExactMpc::new(&mpc).unwrap().solve(&x_hat).unwrap().to_vec();
    let p = peak(&mpc, &u);
    assert!((p - 0.5).abs() < 1e-9, "the bound is active: peak {p}");
    let uc = uncondensed_with_outputs(&mpc, &BoxSet::whole(2), Some(&ys), &x_hat).unwrap();
    let d = u
        .iter()
        .zip(&uc)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(d < 1e-6, "exact vs Clarabel: {d:e}");
    // The K-iteration MPC (FISTA projects exactly onto 𝒰^N ∩ rows) keeps the bound too.
    let mut sub = SuboptimalMpc::new(
        &mpc,
        qp_iter::fista::Fista::new(mpc.qp().clone()),
        500,
        WarmStart::default(),
    )
    .unwrap();
    let mut u0 = [0.0];
    sub.control(&x_hat, &mut u0).unwrap();
    assert!(matches!(sub.status(), ControlStatus::Applied { .. }));
    assert!((u0[0] - u[0]).abs() < 1e-3, "{} vs {}", u0[0], u[0]);
}
