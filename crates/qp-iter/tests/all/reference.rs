//! The Clarabel reference against independent answers: closed forms, brute-force
//! active-set enumeration, KKT conditions; and update-in-place against a fresh build.

use faer::Mat;
use qp_iter::BoxSet;
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};
use qp_iter::{ParametricQp, QpError};
use rand::Rng;

use crate::common::{
    Gen, dist, gradient, linear_term, norm, normal, random_instance, random_spd, rng,
};

/// Brute force: try every assignment free / at lower / at upper, keep the one satisfying KKT.
fn brute_force(qp: &ParametricQp, q: &[f64]) -> Vec<f64> {
    let n = qp.n();
    let (lo, up) = (qp.zset().lower(), qp.zset().upper());
    let h = qp.h();
    let mut best: Option<(f64, Vec<f64>)> = None;
    for code in 0..3usize.pow(n as u32) {
        let state: Vec<usize> = (0..n).map(|i| code / 3usize.pow(i as u32) % 3).collect();
        if (0..n)
            .any(|i| (state[i] == 1 && !lo[i].is_finite()) || (state[i] == 2 && !up[i].is_finite()))
        {
            continue;
        }
        let fixed: Vec<Option<f64>> = (0..n)
            .map(|i| match state[i] {
                1 => Some(lo[i]),
                2 => Some(up[i]),
                _ => None,
            })
            .collect();
        let free: Vec<usize> = (0..n).filter(|&i| fixed[i].is_none()).collect();
        let mut z: Vec<f64> = fixed.iter().map(|f| f.unwrap_or(0.0)).collect();
        if !free.is_empty() {
            let a = Mat::from_fn(free.len(), free.len(), |r, c| h[(free[r], free[c])]);
            let b = Mat::from_fn(free.len(), 1, |r, _| {
                let i = free[r];
                -(q[i]
                    + (0..n)
                        .filter_map(|j| fixed[j].map(|v| h[(i, j)] * v))
                        .sum::<f64>())
            });
            let x = faer::linalg::solvers::Solve::solve(&a.partial_piv_lu(), b);
            for (r, &i) in free.iter().enumerate() {
                z[i] = x[(r, 0)];
            }
        }
        let g = gradient(qp, q, &z);
        let tol = 1e-9 * (1.0 + norm(&z) + norm(q));
        let kkt = (0..n).all(|i| match state[i] {
            0 => z[i] >= lo[i] - tol && z[i] <= up[i] + tol,
            1 => g[i] >= -tol,
            _ => g[i] <= tol,
        });
        if kkt {
            let f = qp.objective(q, &z);
            if best.as_ref().is_none_or(|(bf, _)| f < *bf) {
                best = Some((f, z));
            }
        }
    }
    best.unwrap().1
}

#[test]
fn matches_brute_force_active_set_enumeration() {
    let mut polished = 0;
    for seed in 60_000..60_080 {
        let inst = random_instance(
            seed,
            Gen {
                n_min: 1,
                n_max: 6,
                ..Gen::default()
            },
        );
        let mut r = ReferenceSolver::new(&inst.qp, ReferenceSettings::default()).unwrap();
        let sol = r.solve(&inst.theta).unwrap();
        let q = linear_term(&inst.qp, &inst.theta);
        let bf = brute_force(&inst.qp, &q);
        assert!(
            dist(&sol.z, &bf) <= 1e-9 * (1.0 + norm(&bf)),
            "seed {seed}: {:?} vs {:?}",
            sol.z,
            bf
        );
        polished += usize::from(sol.polished);
    }
    assert!(polished >= 76, "polish accepted on {polished}/80");
}

#[test]
fn matches_closed_forms() {
    let mut g = rng(61);
    for _ in 0..20 {
        let n = g.random_range(1..=20usize);
        // Unconstrained: z* = −H⁻¹q, no multipliers.
        let h = random_spd(&mut g, n, 100.0, 0.5);
        let q: Vec<f64> = (0..n).map(|_| normal(&mut g)).collect();
        let qp =
            ParametricQp::new(h.clone(), q.clone(), Mat::zeros(n, 0), BoxSet::whole(n)).unwrap();
        let sol = ReferenceSolver::new(&qp, ReferenceSettings::default())
            .unwrap()
            .solve(&[])
            .unwrap();
        let rhs = Mat::from_fn(n, 1, |i, _| -q[i]);
        let x = faer::linalg::solvers::Solve::solve(&h.partial_piv_lu(), rhs);
        let exact: Vec<f64> = (0..n).map(|i| x[(i, 0)]).collect();
        assert!(dist(&sol.z, &exact) <= 1e-10 * (1.0 + norm(&exact)));
        assert!(
            sol.lower_multipliers
                .iter()
                .chain(&sol.upper_multipliers)
                .all(|m| *m == 0.0)
        );
        // Diagonal H over a box: z*_i = clamp(−q_i/h_i, l_i, u_i).
        let d: Vec<f64> = (0..n).map(|_| 0.1 + 10.0 * g.random::<f64>()).collect();
        let lo: Vec<f64> = (0..n).map(|_| -g.random::<f64>()).collect();
        let up: Vec<f64> = (0..n).map(|_| g.random::<f64>()).collect();
        let hd = Mat::from_fn(n, n, |i, j| if i == j { d[i] } else { 0.0 });
        let qp = ParametricQp::new(
            hd,
            q.clone(),
            Mat::zeros(n, 0),
            BoxSet::new(lo.clone(), up.clone()).unwrap(),
        )
        .unwrap();
        let sol = ReferenceSolver::new(&qp, ReferenceSettings::default())
            .unwrap()
            .solve(&[])
            .unwrap();
        for i in 0..n {
            let zi = (-q[i] / d[i]).clamp(lo[i], up[i]);
            assert!((sol.z[i] - zi).abs() <= 1e-12, "{i}: {} vs {zi}", sol.z[i]);
            // Multiplier of the active bound: d_i z_i + q_i + λ_u − λ_l = 0.
            let gi = d[i] * zi + q[i];
            assert!((sol.upper_multipliers[i] - sol.lower_multipliers[i] + gi).abs() <= 1e-9);
        }
    }
}

#[test]
fn multipliers_satisfy_kkt() {
    for seed in 62_000..62_100 {
        let inst = random_instance(seed, Gen::default());
        let mut r = ReferenceSolver::new(&inst.qp, ReferenceSettings::default()).unwrap();
        let sol = r.solve(&inst.theta).unwrap();
        let q = linear_term(&inst.qp, &inst.theta);
        let g = gradient(&inst.qp, &q, &sol.z);
        let scale = 1.0 + norm(&g) + norm(&q);
        let (lo, up) = (inst.qp.zset().lower(), inst.qp.zset().upper());
        for i in 0..inst.qp.n() {
            let (ll, lu) = (sol.lower_multipliers[i], sol.upper_multipliers[i]);
            assert!(
                (g[i] + lu - ll).abs() <= 1e-9 * scale,
                "seed {seed}: stationarity at {i}"
            );
            assert!(ll >= 0.0 && lu >= 0.0);
            assert!(
                sol.z[i] >= lo[i] && sol.z[i] <= up[i],
                "seed {seed}: infeasible"
            );
            if lo[i].is_finite() {
                assert!(
                    ll * (sol.z[i] - lo[i]) <= 1e-9 * scale,
                    "seed {seed}: complementarity"
                );
            } else {
                assert_eq!(ll, 0.0);
            }
            if up[i].is_finite() {
                assert!(
                    lu * (up[i] - sol.z[i]) <= 1e-9 * scale,
                    "seed {seed}: complementarity"
                );
            } else {
                assert_eq!(lu, 0.0);
            }
        }
        assert!(
            sol.kkt_residual <= 1e-10 * scale,
            "seed {seed}: {}",
            sol.kkt_residual
        );
        let y = sol.dual();
        assert!(y.iter().zip(&g).all(|(y, g)| (y + g).abs() <= 1e-9 * scale));
    }
}

#[test]
fn polished_and_raw_clarabel_agree() {
    let (mut accepted, mut worst_gap, mut worst_raw_res, mut worst_pol_res) =
        (0, 0.0_f64, 0.0_f64, 0.0_f64);
    let seeds = 63_000..63_100u64;
    for seed in seeds.clone() {
        let inst = random_instance(seed, Gen::default());
        let raw_settings = ReferenceSettings {
            polish: false,
            ..ReferenceSettings::default()
        };
        let raw = ReferenceSolver::new(&inst.qp, raw_settings)
            .unwrap()
            .solve(&inst.theta)
            .unwrap();
        let pol = ReferenceSolver::new(&inst.qp, ReferenceSettings::default())
            .unwrap()
            .solve(&inst.theta)
            .unwrap();
        assert!(!raw.polished);
        let gap = dist(&raw.z, &pol.z) / (1.0 + norm(&pol.z));
        assert!(gap <= 1e-6 * inst.qp.kappa().sqrt(), "seed {seed}: {gap:e}");
        assert!(pol.kkt_residual <= raw.kkt_residual + 1e-12, "seed {seed}");
        accepted += usize::from(pol.polished);
        worst_gap = worst_gap.max(gap);
        worst_raw_res = worst_raw_res.max(raw.kkt_residual);
        worst_pol_res = worst_pol_res.max(pol.kkt_residual);
    }
    println!(
        "polish accepted {accepted}/{}; max relative |raw − polished| {worst_gap:.2e}; \
         max natural residual raw {worst_raw_res:.2e}, polished {worst_pol_res:.2e}",
        seeds.end - seeds.start
    );
    assert!(accepted >= 95, "{accepted}");
}

#[test]
fn update_in_place_matches_a_fresh_build() {
    let (mut t_update, mut t_fresh) = (std::time::Duration::ZERO, std::time::Duration::ZERO);
    for seed in 64_000..64_020 {
        let inst = random_instance(
            seed,
            Gen {
                n_min: 20,
                n_max: 30,
                ..Gen::default()
            },
        );
        for polish in [false, true] {
            let settings = ReferenceSettings {
                polish,
                ..ReferenceSettings::default()
            };
            let mut reused = ReferenceSolver::new(&inst.qp, settings).unwrap();
            let mut g = rng(seed);
            for _ in 0..5 {
                let theta: Vec<f64> = (0..inst.qp.n_theta()).map(|_| normal(&mut g)).collect();
                let t0 = std::time::Instant::now();
                let a = reused.solve(&theta).unwrap();
                t_update += t0.elapsed();
                let t0 = std::time::Instant::now();
                let b = ReferenceSolver::new(&inst.qp, settings)
                    .unwrap()
                    .solve(&theta)
                    .unwrap();
                t_fresh += t0.elapsed();
                let tol = if polish { 1e-12 } else { 1e-8 } * (1.0 + norm(&b.z));
                assert!(
                    dist(&a.z, &b.z) <= tol,
                    "seed {seed}: {:e}",
                    dist(&a.z, &b.z)
                );
            }
        }
    }
    println!(
        "reference re-solve via update_q: {t_update:?} total; rebuild + solve: {t_fresh:?} total (200 solves each)"
    );
}

#[test]
fn non_solved_status_is_a_typed_error() {
    let inst = random_instance(
        65,
        Gen {
            n_min: 20,
            ..Gen::default()
        },
    );
    let settings = ReferenceSettings {
        max_iter: 1,
        ..ReferenceSettings::default()
    };
    let err = ReferenceSolver::new(&inst.qp, settings)
        .unwrap()
        .solve(&inst.theta)
        .unwrap_err();
    assert!(
        matches!(&err, QpError::Reference { status } if status.contains("MaxIterations")),
        "{err}"
    );
}
