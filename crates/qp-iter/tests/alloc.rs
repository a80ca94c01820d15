//! Zero heap allocations per step, load and restart, proved with the workspace's counting
//! global allocator (`alloc_counter`). A separate test binary, because the allocator is
//! process-global; counting is per thread so the test harness's own threads do not
//! interfere.
#![allow(clippy::unwrap_used)]

use faer::Mat;
use qp_iter::BoxSet;
use qp_iter::admm::{Admm, AdmmParams, Penalty};
use qp_iter::fista::Fista;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{IterationMap, ParametricQp, run_fixed, run_until};

#[global_allocator]
static GLOBAL: alloc_counter::CountingAllocator = alloc_counter::CountingAllocator;

use alloc_counter::allocations;

/// n = 30 (the case-study size), three parameters, a box with some infinite bounds.
fn problem() -> ParametricQp {
    let n = 30;
    let h = Mat::from_fn(n, n, |i, j| {
        1.0 / (1.0 + i.abs_diff(j) as f64) + if i == j { 0.1 * i as f64 } else { 0.0 }
    });
    let f = Mat::from_fn(n, 3, |i, k| ((i + 2 * k) % 5) as f64 - 2.0);
    let lo = (0..n)
        .map(|i| if i % 4 == 0 { f64::NEG_INFINITY } else { -0.5 })
        .collect();
    let up = (0..n)
        .map(|i| if i % 5 == 0 { f64::INFINITY } else { 0.7 })
        .collect();
    let q0 = (0..n).map(|i| (i as f64).sin()).collect();
    ParametricQp::new(h, q0, f, BoxSet::new(lo, up).unwrap()).unwrap()
}

/// load + warm start (and cold start) + K steps through both drivers.
fn exercise<M: IterationMap>(m: &M, s: &mut M::State, z0: &[f64], dual: Option<&[f64]>) {
    for theta in [[0.3, -1.0, 2.0], [1.0, 0.0, -0.5]] {
        m.load(s, &theta);
        m.warm_start(s, z0, dual);
        for _ in 0..20 {
            m.step(s);
        }
        run_fixed(m, s, 20);
        let mut k = 0;
        run_until(m, s, 20, |_, z| {
            k += 1;
            (z[0] > 1e9).then_some(true)
        });
        m.cold_start(s);
        run_fixed(m, s, 5);
        std::hint::black_box(m.iterate(s));
        std::hint::black_box(m.dual(s));
    }
}

fn assert_no_allocations<M: IterationMap>(m: &M, dual: Option<&[f64]>) {
    let mut s = m.new_state(); // setup may allocate
    let z0 = vec![0.25; m.problem().n()];
    exercise(m, &mut s, &z0, dual); // warm-up: lazy one-time initialisation, if any
    let count = allocations(|| exercise(m, &mut s, &z0, dual));
    assert_eq!(
        count,
        0,
        "{}: {count} allocations in load / warm start / steps",
        m.name()
    );
}

#[test]
fn the_allocator_counts() {
    // The test would be void if the counter missed allocations.
    let n = allocations(|| {
        std::hint::black_box(vec![1u8; 16]);
    });
    assert_eq!(n, 1);
}

#[test]
fn no_method_allocates_after_setup() {
    let qp = problem();
    assert_no_allocations(
        &ProjectedGradient::new(qp.clone(), StepRule::InverseL).unwrap(),
        None,
    );
    assert_no_allocations(
        &ProjectedGradient::new(qp.clone(), StepRule::Optimal).unwrap(),
        None,
    );
    assert_no_allocations(&Fista::new(qp.clone()), None);
    let admm = Admm::new(qp.clone(), AdmmParams::default()).unwrap();
    assert_no_allocations(&admm, None);
    let y0 = vec![0.1; qp.n()];
    assert_no_allocations(&admm, Some(&y0));
    let admm2 = Admm::new(
        qp.clone(),
        AdmmParams {
            penalty: Penalty::Fixed(2.0),
            relaxation: 1.7,
        },
    )
    .unwrap();
    assert_no_allocations(&admm2, Some(&y0));
    // Peaceman–Rachford (relaxation 2) runs its own kernel epilogue.
    let admm_pr = Admm::new(
        qp.clone(),
        AdmmParams {
            penalty: Penalty::Optimal,
            relaxation: 2.0,
        },
    )
    .unwrap();
    assert_no_allocations(&admm_pr, None);
    // ADMM's diagnostics too.
    let mut s = admm.new_state();
    let mut out = vec![0.0; qp.n()];
    let count = allocations(|| {
        std::hint::black_box(admm.constraint_violation(&s));
        std::hint::black_box(admm.primal_residual(&s));
        admm.splitting_variable(&s, &mut out);
        admm.step(&mut s);
    });
    assert_eq!(count, 0);
}

/// The exact active-set solver: solves with working-set changes (factor updates), warm
/// starts from a point, resets and fresh factorisations allocate nothing after setup.
#[test]
fn active_set_allocates_nothing_after_setup() {
    use qp_iter::active_set::{ActiveSetSettings, ActiveSetSolver, ExactSolver};
    let qp = problem();
    let n = qp.n();
    let thetas = [
        [0.3, -1.0, 2.0],
        [1.0, 0.0, -0.5],
        [-2.0, 3.0, 1.0],
        [0.0, 0.0, 0.0],
    ];
    let z0: Vec<f64> = (0..n)
        .map(|i| if i % 3 == 0 { 0.7 } else { -0.1 })
        .collect();
    for max_updates in [None, Some(0), Some(3)] {
        let settings = ActiveSetSettings {
            max_updates,
            ..ActiveSetSettings::default()
        };
        let mut s = ActiveSetSolver::new(&qp, settings).unwrap();
        let mut e = ExactSolver::with_settings(&qp, settings).unwrap();
        let mut updates = 0;
        let mut run = |s: &mut ActiveSetSolver, e: &mut ExactSolver| {
            for theta in &thetas {
                updates += s.solve(theta).unwrap().updates;
                std::hint::black_box(e.solve(theta).unwrap());
            }
            s.warm_start(&z0).unwrap();
            e.warm_start(&z0).unwrap();
            s.solve(&thetas[1]).unwrap();
            e.solve(&thetas[2]).unwrap();
            s.reset();
            e.reset();
            s.solve(&thetas[2]).unwrap();
            e.solve(&thetas[0]).unwrap();
        };
        run(&mut s, &mut e); // warm-up
        let count = allocations(|| run(&mut s, &mut e));
        assert_eq!(count, 0, "max_updates {max_updates:?}: {count} allocations");
        assert_eq!(e.fallbacks(), 0);
        assert!(max_updates == Some(0) || updates > 0, "{max_updates:?}");
    }
}

/// With general rows: PG and FISTA with the exact projection, ADMM split on [I; G]z, the
/// Jacobi-scaled PG and the exact solver (Goldfarb–Idnani) allocate nothing after setup.
#[test]
fn general_rows_allocate_nothing_after_setup() {
    use qp_iter::GeneralConstraints;
    use qp_iter::active_set::ExactSolver;
    use qp_iter::method::{Method, Scaling};
    let base = problem();
    let n = base.n();
    let m = 6;
    let g = Mat::from_fn(m, n, |r, j| if (j + r) % 3 == 0 { 1.0 } else { 0.0 });
    let e = Mat::from_fn(m, 3, |r, k| 0.1 * ((r + k) % 3) as f64);
    let qp = base
        .with_general(GeneralConstraints::new(g, e, vec![-0.8; m], vec![0.4; m]).unwrap())
        .unwrap();
    for method in [
        Method::PG,
        Method::FISTA,
        Method::ADMM,
        Method::PG.with_scaling(Scaling::Jacobi),
    ] {
        let map = method.build(qp.clone()).unwrap();
        assert_no_allocations(&map, None);
        let mut s = map.new_state();
        let count = allocations(|| {
            std::hint::black_box(map.violation(&s));
            map.step(&mut s);
        });
        assert_eq!(count, 0, "{method}");
    }
    let mut ex = ExactSolver::new(&qp).unwrap();
    ex.solve(&[0.3, -1.0, 2.0]).unwrap();
    let count = allocations(|| {
        for theta in [[0.3, -1.0, 2.0], [1.0, 0.0, -0.5]] {
            std::hint::black_box(ex.solve(&theta).unwrap());
        }
    });
    assert_eq!(count, 0);
}
