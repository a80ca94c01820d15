//! The exact active-set solver against two independent answers: Clarabel (with its own
//! rigorous error bound) on thousands of random QPs, and brute-force enumeration of every
//! active pattern on small ones; warm starts, degenerate cases and bad input.

use faer::Mat;
use faer::prelude::Solve;
use qp_iter::BoxSet;
use qp_iter::active_set::{ActiveSetSettings, ActiveSetSolver, ExactSolver};
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};
use qp_iter::{ParametricQp, QpError};
use rand::Rng;

use crate::common::{Gen, dist, gradient, linear_term, norm, random_instance, reference, rng};

/// Natural residual computed here, not by the crate.
fn natural_residual(qp: &ParametricQp, q: &[f64], z: &[f64]) -> f64 {
    let g = gradient(qp, q, z);
    let mut p: Vec<f64> = z.iter().zip(&g).map(|(z, g)| z - g).collect();
    qp.project(&mut p);
    z.iter()
        .zip(&p)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_matches_clarabel_on_2000_random_qps() {
    let (mut worst_rel, mut max_iters, mut total_iters) = (0.0f64, 0, 0);
    let (count, mut clarabel_failed) = (2000, 0);
    for seed in 0..count {
        let inst = random_instance(70_000 + seed, Gen::default());
        let mut s = ActiveSetSolver::new(&inst.qp, ActiveSetSettings::default()).unwrap();
        let info = s
            .solve(&inst.theta)
            .unwrap_or_else(|e| panic!("seed {}: {e}", inst.seed));
        let z = s.z();
        let q = linear_term(&inst.qp, &inst.theta);
        let scale = 1.0 + norm(z) + norm(&q);
        // The rigorous error bound ‖z − z*‖ ≤ (1 + L)/μ · (natural residual) holds whatever
        // Clarabel does; on the rare instance where Clarabel itself fails (interior-point
        // "insufficient progress" at κ ≈ 1e4) it is the only check.
        let res = natural_residual(&inst.qp, &q, z);
        assert!(res <= 1e-9 * scale, "seed {}: residual {res:e}", inst.seed);
        if ReferenceSolver::new(&inst.qp, ReferenceSettings::default())
            .unwrap()
            .solve(&inst.theta)
            .is_err()
        {
            clarabel_failed += 1;
            continue;
        }
        let r = reference(&inst);
        // Feasible exactly, KKT to tolerance (checked independently), and within the
        // reference's certified error of Clarabel's optimum.
        let (lo, up) = (inst.qp.zset().lower(), inst.qp.zset().upper());
        assert!(
            z.iter()
                .enumerate()
                .all(|(i, v)| *v >= lo[i] && *v <= up[i])
        );
        let d = dist(z, &r.sol.z);
        assert!(
            d <= r.err + 1e-9 * scale,
            "seed {}: ‖z − z_ref‖ = {d:e}, reference error bound {:e}",
            inst.seed,
            r.err
        );
        worst_rel = worst_rel.max(d / scale);
        // Multipliers: nonnegative, complementary, and Hz + q = λ_l − λ_u.
        let g = gradient(&inst.qp, &r.q, z);
        for i in 0..z.len() {
            let (ll, lu) = (s.lower_multipliers()[i], s.upper_multipliers()[i]);
            assert!(ll >= 0.0 && lu >= 0.0);
            assert!(ll == 0.0 || z[i] == lo[i]);
            assert!(lu == 0.0 || z[i] == up[i]);
            assert!(
                (g[i] - (ll - lu)).abs() <= 1e-9 * scale,
                "seed {}",
                inst.seed
            );
        }
        max_iters = max_iters.max(info.iterations);
        total_iters += info.iterations;
    }
    println!(
        "active set vs Clarabel: {count} QPs ({clarabel_failed} where Clarabel failed), worst \
         ‖z − z_ref‖/scale {worst_rel:.2e}, subspace solves mean {:.1}, max {max_iters}",
        total_iters as f64 / count as f64
    );
    assert!(
        clarabel_failed * 100 < count,
        "Clarabel failed on {clarabel_failed}"
    );
}

/// Every KKT point of a strictly convex QP is its unique minimiser: enumerate all 3ⁿ
/// patterns (free / at lower / at upper), solve each, and keep the one satisfying KKT.
fn brute_force(qp: &ParametricQp, q: &[f64]) -> Vec<f64> {
    let n = qp.n();
    let h = qp.h();
    let (lo, up) = (qp.zset().lower(), qp.zset().upper());
    let mut best: Option<(Vec<f64>, f64)> = None;
    for code in 0..3usize.pow(n as u32) {
        let mut pat = vec![0u8; n];
        let mut c = code;
        for p in pat.iter_mut() {
            *p = (c % 3) as u8;
            c /= 3;
        }
        if (0..n)
            .any(|i| (pat[i] == 1 && !lo[i].is_finite()) || (pat[i] == 2 && !up[i].is_finite()))
        {
            continue;
        }
        let mut z = vec![0.0; n];
        for i in 0..n {
            z[i] = match pat[i] {
                1 => lo[i],
                2 => up[i],
                _ => 0.0,
            };
        }
        let free: Vec<usize> = (0..n).filter(|&i| pat[i] == 0).collect();
        if !free.is_empty() {
            let nf = free.len();
            let hff = Mat::from_fn(nf, nf, |a, b| h[(free[a], free[b])]);
            let rhs = Mat::from_fn(nf, 1, |a, _| {
                let i = free[a];
                -(q[i]
                    + (0..n)
                        .filter(|&j| pat[j] != 0)
                        .map(|j| h[(i, j)] * z[j])
                        .sum::<f64>())
            });
            let sol = hff.partial_piv_lu().solve(&rhs);
            for (a, &i) in free.iter().enumerate() {
                z[i] = sol[(a, 0)];
            }
        }
        let g = gradient(qp, q, &z);
        let scale = 1.0 + norm(q) + norm(&g);
        let tol = 1e-9 * scale;
        let ok = (0..n).all(|i| match pat[i] {
            0 => z[i] >= lo[i] - tol && z[i] <= up[i] + tol,
            1 => g[i] >= -tol,
            _ => g[i] <= tol,
        });
        if ok {
            let f = qp.objective(q, &z);
            if best.as_ref().is_none_or(|(_, fb)| f < *fb) {
                best = Some((z, f));
            }
        }
    }
    best.map(|(z, _)| z).unwrap()
}

#[test]
fn matches_brute_force_enumeration_on_small_qps() {
    let opts = Gen {
        n_min: 1,
        n_max: 6,
        log10_kappa_max: 3.0,
        p_finite: 0.9,
    };
    for seed in 0..400 {
        let inst = random_instance(90_000 + seed, opts);
        let q = linear_term(&inst.qp, &inst.theta);
        let want = brute_force(&inst.qp, &q);
        let mut s = ActiveSetSolver::new(&inst.qp, ActiveSetSettings::default()).unwrap();
        s.solve(&inst.theta).unwrap();
        let scale = 1.0 + norm(&want) + norm(&q);
        assert!(
            dist(s.z(), &want) <= 1e-9 * scale * (1.0 + inst.qp.kappa()),
            "seed {}: {:?} vs {want:?}",
            inst.seed,
            s.z()
        );
    }
}

#[test]
fn warm_started_sequence_equals_fresh_solves_and_is_cheaper() {
    let mut r = rng(5);
    let (mut warm_iters, mut cold_iters, mut reused) = (0usize, 0usize, 0usize);
    for seed in 0..40 {
        let inst = random_instance(
            110_000 + seed,
            Gen {
                n_min: 10,
                n_max: 25,
                ..Gen::default()
            },
        );
        let n_theta = inst.qp.n_theta();
        let mut warm = ActiveSetSolver::new(&inst.qp, ActiveSetSettings::default()).unwrap();
        let mut theta = inst.theta.clone();
        for _ in 0..30 {
            // A slowly drifting parameter, as in a closed loop.
            for t in theta.iter_mut() {
                *t += 0.05 * (r.random::<f64>() - 0.5);
            }
            let wi = warm.solve(&theta).unwrap();
            let mut fresh = ActiveSetSolver::new(&inst.qp, ActiveSetSettings::default()).unwrap();
            let ci = fresh.solve(&theta).unwrap();
            let q = linear_term(&inst.qp, &theta);
            let scale = 1.0 + norm(fresh.z()) + norm(&q);
            assert!(
                dist(warm.z(), fresh.z()) <= 1e-9 * scale * inst.qp.kappa(),
                "seed {seed}, n_θ = {n_theta}"
            );
            warm_iters += wi.iterations;
            cold_iters += ci.iterations;
            reused += usize::from(wi.factorizations == 0);
        }
    }
    println!(
        "subspace solves: warm {warm_iters}, cold {cold_iters}; cached factor reused {reused}/1200"
    );
    assert!(warm_iters < cold_iters);
    assert!(reused > 0);
}

#[test]
fn degenerate_and_special_boxes() {
    // Fixed variables (l = u), infinite bounds, and a minimiser exactly on a bound with a
    // zero multiplier (weakly active: degenerate).
    let h = faer::mat![[2.0, 0.5, 0.0], [0.5, 1.0, 0.1], [0.0, 0.1, 3.0]];
    let zset = BoxSet::new(
        vec![0.7, f64::NEG_INFINITY, 0.0],
        vec![0.7, f64::INFINITY, 1.0],
    )
    .unwrap();
    // Unconstrained minimiser over (z₁, z₂) with z₀ = 0.7: choose q so z₂* = 0 exactly
    // (on its lower bound, multiplier 0) and z₁* = −1.
    let zs = [0.7, -1.0, 0.0];
    let hz: Vec<f64> = (0..3)
        .map(|i| (0..3).map(|j| h[(i, j)] * zs[j]).sum::<f64>())
        .collect();
    let q0 = vec![-hz[0] + 5.0, -hz[1], -hz[2]];
    let qp = ParametricQp::new(h, q0.clone(), Mat::zeros(3, 0), zset).unwrap();
    let mut s = ActiveSetSolver::new(&qp, ActiveSetSettings::default()).unwrap();
    s.solve(&[]).unwrap();
    assert!(dist(s.z(), &zs) < 1e-14, "{:?}", s.z());
    assert!(s.z()[0] == 0.7);
    // The fixed variable's multiplier carries the +5 pushed into its gradient.
    assert!((s.lower_multipliers()[0] - 5.0).abs() < 1e-12);
    assert!(s.upper_multipliers()[0] == 0.0);
    assert!(natural_residual(&qp, &q0, s.z()) < 1e-14);

    // Unconstrained: one subspace solve, the Newton point.
    let qp = ParametricQp::new(
        faer::mat![[4.0, 1.0], [1.0, 3.0]],
        vec![1.0, 2.0],
        Mat::zeros(2, 0),
        BoxSet::whole(2),
    )
    .unwrap();
    let mut s = ActiveSetSolver::new(&qp, ActiveSetSettings::default()).unwrap();
    let info = s.solve(&[]).unwrap();
    assert_eq!((info.iterations, info.active), (1, 0));
    // H⁻¹ = [[3, −1], [−1, 4]]/11 ⇒ z* = −H⁻¹q = (−1, −7)/11.
    assert!(dist(s.z(), &[-1.0 / 11.0, -7.0 / 11.0]) < 1e-15);
}

#[test]
fn bad_input_is_a_typed_error() {
    let inst = random_instance(3, Gen::default());
    for tol in [0.0, -1.0, 1.0, f64::NAN] {
        assert!(matches!(
            ActiveSetSolver::new(&inst.qp, ActiveSetSettings { tol, ..ActiveSetSettings::default() }),
            Err(QpError::Parameter { ref name, .. }) if name == "tol"
        ));
    }
    assert!(matches!(
        ActiveSetSolver::new(
            &inst.qp,
            ActiveSetSettings {
                max_iter: Some(0),
                ..ActiveSetSettings::default()
            }
        ),
        Err(QpError::Parameter { ref name, .. }) if name == "max_iter"
    ));
    let mut s = ActiveSetSolver::new(&inst.qp, ActiveSetSettings::default()).unwrap();
    let mut bad = inst.theta.clone();
    bad.push(0.0);
    assert!(matches!(s.solve(&bad), Err(QpError::Data(_))));
    let mut nan_q = vec![0.0; inst.qp.n()];
    nan_q[0] = f64::NAN;
    assert!(matches!(s.solve_q(&nan_q), Err(QpError::Data(_))));
    assert!(matches!(s.solve_q(&[0.0]), Err(QpError::Data(_))) || inst.qp.n() == 1);
}

#[test]
fn iteration_limit_is_a_typed_error_and_the_solver_recovers() {
    // A cold start far from the box needs several working-set changes.
    let n = 8;
    let h = Mat::from_fn(n, n, |i, j| if i == j { 2.0 } else { 0.3 });
    let qp = ParametricQp::new(
        h,
        vec![-50.0; n],
        Mat::identity(n, n),
        BoxSet::symmetric(&vec![1.0; n]).unwrap(),
    )
    .unwrap();
    let mut s = ActiveSetSolver::new(
        &qp,
        ActiveSetSettings {
            max_iter: Some(2),
            ..ActiveSetSettings::default()
        },
    )
    .unwrap();
    let theta = vec![0.0; n];
    assert!(matches!(
        s.solve(&theta),
        Err(QpError::NotConverged { iterations: 2, .. })
    ));
    // The failed call leaves a consistent state: an easy problem next (q = 0, z* = 0 inside
    // the box) is solved by the same solver.
    let info = s.solve(&vec![50.0; n]).unwrap();
    assert!(norm(s.z()) < 1e-14 && info.iterations <= 2);
    let mut full = ActiveSetSolver::new(&qp, ActiveSetSettings::default()).unwrap();
    full.solve(&theta).unwrap();
    assert!(full.z().iter().all(|v| *v == 1.0));
}

#[test]
fn exact_solver_falls_back_to_clarabel_and_counts_it() {
    let inst = random_instance(
        4,
        Gen {
            n_min: 12,
            n_max: 12,
            ..Gen::default()
        },
    );
    let q = linear_term(&inst.qp, &inst.theta);
    // One subspace solve is not enough from a cold start here: the active set gives up
    // and Clarabel answers.
    let mut starved = ExactSolver::with_settings(
        &inst.qp,
        ActiveSetSettings {
            max_iter: Some(1),
            ..ActiveSetSettings::default()
        },
    )
    .unwrap();
    let mut full = ExactSolver::new(&inst.qp).unwrap();
    let a = starved.solve(&inst.theta).unwrap().to_vec();
    let b = full.solve(&inst.theta).unwrap().to_vec();
    assert_eq!((starved.fallbacks(), full.fallbacks()), (1, 0));
    assert!(starved.last_info().is_none() && full.last_info().is_some());
    let scale = 1.0 + norm(&b) + norm(&q);
    assert!(dist(&a, &b) <= 1e-8 * scale, "{a:?} vs {b:?}");
    assert!(natural_residual(&inst.qp, &q, &b) <= 1e-10 * scale);
    assert!(
        matches!(
            full.solve(&[f64::NAN; 4][..inst.qp.n_theta()]),
            Err(QpError::Data(_))
        ) || inst.qp.n_theta() == 0
    );
}

/// The factor updates (a bound entering or leaving W updates the Cholesky factor of H_FF
/// instead of recomputing it) against recomputing it at every change (`max_updates =
/// Some(0)`, the method before the updates): on thousands of random QPs, each solved for a
/// sequence of strongly varying θ and from random warm-start points, so that the working
/// set changes many times, the two give the same minimiser to 1e-10 relative.
#[test]
fn updated_factor_gives_the_same_solutions_as_fresh_factorisations() {
    let mut r = rng(17);
    let (mut solves, mut updates, mut fresh_factorizations) = (0usize, 0usize, 0usize);
    let mut worst = 0.0f64;
    for seed in 0..2500u64 {
        let inst = random_instance(
            130_000 + seed,
            Gen {
                n_min: 2,
                n_max: 40,
                ..Gen::default()
            },
        );
        let n = inst.qp.n();
        let mut upd = ActiveSetSolver::new(&inst.qp, ActiveSetSettings::default()).unwrap();
        let mut fresh = ActiveSetSolver::new(
            &inst.qp,
            ActiveSetSettings {
                max_updates: Some(0),
                ..ActiveSetSettings::default()
            },
        )
        .unwrap();
        let mut theta = inst.theta.clone();
        for step in 0..6 {
            for t in theta.iter_mut() {
                *t += 1.5 * (r.random::<f64>() - 0.5);
            }
            if step == 3 {
                // A random start point: the cached factor is updated to its free set.
                let z0: Vec<f64> = (0..n).map(|_| 3.0 * (r.random::<f64>() - 0.5)).collect();
                upd.warm_start(&z0).unwrap();
                fresh.warm_start(&z0).unwrap();
            }
            let a = upd
                .solve(&theta)
                .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            let b = fresh.solve(&theta).unwrap();
            assert_eq!(b.updates, 0);
            let q = linear_term(&inst.qp, &theta);
            let scale = 1.0 + norm(fresh.z()) + norm(&q);
            let d = dist(upd.z(), fresh.z()) / scale;
            assert!(
                d <= 1e-10,
                "seed {seed}, step {step}: relative difference {d:e}"
            );
            // Both are answers in their own right.
            assert!(natural_residual(&inst.qp, &q, upd.z()) <= 1e-9 * scale);
            worst = worst.max(d);
            solves += 1;
            updates += a.updates;
            fresh_factorizations += a.factorizations;
        }
    }
    println!(
        "factor updates vs fresh factorisations: {solves} solves, {updates} updates, {fresh_factorizations} fresh factorisations, worst relative difference {worst:.2e}"
    );
    assert!(
        updates > 10 * solves / 2,
        "too few working-set changes: {updates}"
    );
}

/// A long warm-started sequence on one QP (hundreds of updates between fresh
/// factorisations) stays at the fresh answer, with and without a forced refresh budget.
#[test]
fn long_update_sequences_stay_accurate() {
    let mut r = rng(23);
    for seed in 0..20u64 {
        let inst = random_instance(
            150_000 + seed,
            Gen {
                n_min: 60,
                n_max: 80,
                log10_kappa_max: 3.0,
                p_finite: 0.9,
            },
        );
        let settings = |max_updates| ActiveSetSettings {
            max_updates,
            ..ActiveSetSettings::default()
        };
        let mut long = ActiveSetSolver::new(&inst.qp, settings(Some(usize::MAX))).unwrap();
        let mut capped = ActiveSetSolver::new(&inst.qp, settings(None)).unwrap();
        // q drifts (θ may be empty): the minimiser wanders through the box.
        let mut q = linear_term(&inst.qp, &inst.theta);
        let amp = 0.3 * (1.0 + norm(&q));
        let (mut total, mut factorizations) = (0, 0);
        for _ in 0..150 {
            for v in q.iter_mut() {
                *v += amp * (r.random::<f64>() - 0.5);
            }
            let info = long.solve_q(&q).unwrap();
            total += info.updates;
            factorizations += info.factorizations;
            capped.solve_q(&q).unwrap();
            let mut fresh = ActiveSetSolver::new(&inst.qp, settings(Some(0))).unwrap();
            fresh.solve_q(&q).unwrap();
            let scale = 1.0 + norm(fresh.z()) + norm(&q);
            assert!(dist(long.z(), fresh.z()) <= 1e-10 * scale, "seed {seed}");
            assert!(dist(capped.z(), fresh.z()) <= 1e-10 * scale, "seed {seed}");
        }
        let (lo, up) = (inst.qp.zset().lower(), inst.qp.zset().upper());
        let unconstrained = lo.iter().chain(up).all(|b| b.is_infinite());
        // One fresh factorisation, then hundreds of updates on it.
        assert!(
            factorizations == 1 && (total > 300 || unconstrained),
            "seed {seed}: {total} updates, {factorizations} factorisations"
        );
    }
}

/// After `reset` the solver reproduces a fresh solver bit for bit, whatever factor updates
/// happened before (what a restarted Monte-Carlo run relies on).
#[test]
fn reset_reproduces_a_fresh_solver_bit_for_bit() {
    let mut r = rng(31);
    for seed in 0..200u64 {
        let inst = random_instance(170_000 + seed, Gen::default());
        let thetas: Vec<Vec<f64>> = (0..5)
            .map(|_| {
                inst.theta
                    .iter()
                    .map(|t| t + 2.0 * (r.random::<f64>() - 0.5))
                    .collect()
            })
            .collect();
        let mut used = ActiveSetSolver::new(&inst.qp, ActiveSetSettings::default()).unwrap();
        for theta in thetas.iter().rev() {
            used.solve(theta).unwrap();
        }
        used.reset();
        let mut fresh = ActiveSetSolver::new(&inst.qp, ActiveSetSettings::default()).unwrap();
        for theta in &thetas {
            let a = used.solve(theta).unwrap();
            let b = fresh.solve(theta).unwrap();
            assert_eq!(a, b, "seed {seed}");
            assert_eq!(used.z(), fresh.z(), "seed {seed}");
        }
    }
}
