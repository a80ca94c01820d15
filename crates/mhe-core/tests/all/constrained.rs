//! The MHE with bounded 𝒳 and 𝒴 on every stage: the condensed QP's general rows against an
//! uncondensed Clarabel formulation (x, w, ŷ as variables, the dynamics and the output map
//! as equalities), the certificate consequences, and the K-iteration estimator.

use faer::Mat;
use lti_model::BoxSet;
use mhe_core::problem::{LIPSCHITZ_VOID_REASON, MheProblem};
use mhe_core::{MheEstimator, MheSets};
use qp_iter::IterationMap;
use qp_iter::active_set::ExactSolver;
use qp_iter::method::Method;
use qp_iter::reference::clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{Fixture, csc, dist, random_fixture};

/// m steps of data with w inside 𝒲; 𝒳 and 𝒴 boxes just around the true trajectory (so ℙ
/// is feasible and, the prior being wrong, bounds are active), some components unbounded.
struct Data {
    us: Vec<Vec<f64>>,
    ys: Vec<Vec<f64>>,
    sets: MheSets,
}

fn data(f: &Fixture, m: usize, seed: u64) -> Data {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (nx, nu, ny, nw) = (f.sys.nx(), f.sys.nu(), f.sys.ny(), f.sys.nw());
    let (wlo, whi) = (f.sets.disturbance.lower(), f.sets.disturbance.upper());
    let mut x = f.x0.clone();
    let (mut us, mut ys, mut xs) = (Vec::new(), Vec::new(), vec![x.clone()]);
    for _ in 0..m {
        let u: Vec<f64> = (0..nu).map(|_| 2.0 * rng.random::<f64>() - 1.0).collect();
        let w: Vec<f64> = (0..nw)
            .map(|i| wlo[i] + (whi[i] - wlo[i]) * (0.05 + 0.9 * rng.random::<f64>()))
            .collect();
        let mut xn = vec![0.0; nx];
        let mut y = vec![0.0; ny];
        f.sys.step(&x, &u, &w, &mut xn, &mut y);
        us.push(u);
        ys.push(y);
        x = xn;
        xs.push(x.clone());
    }
    let around = |vals: &[Vec<f64>], n: usize, rng: &mut ChaCha8Rng| {
        let (mut lo, mut hi) = (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]);
        for i in 0..n {
            let mn = vals.iter().map(|v| v[i]).fold(f64::INFINITY, f64::min);
            let mx = vals.iter().map(|v| v[i]).fold(f64::NEG_INFINITY, f64::max);
            if rng.random::<f64>() < 0.8 {
                lo[i] = mn - 0.05 * rng.random::<f64>();
            }
            if rng.random::<f64>() < 0.8 {
                hi[i] = mx + 0.05 * rng.random::<f64>();
            }
        }
        BoxSet::new(lo, hi).unwrap()
    };
    let state = around(&xs, nx, &mut rng);
    let output = if ys.is_empty() {
        BoxSet::whole(ny)
    } else {
        around(&ys, ny, &mut rng)
    };
    Data {
        us,
        ys,
        sets: MheSets {
            state,
            output,
            disturbance: f.sets.disturbance.clone(),
        },
    }
}

fn theta(f: &Fixture, d: &Data) -> Vec<f64> {
    let mut t = f.prior.clone();
    for u in &d.us {
        t.extend_from_slice(u);
    }
    for y in &d.ys {
        t.extend_from_slice(y);
    }
    t
}

/// The uncondensed MHE (8)–(10): v = (x₀…x_m, ŵ₀…ŵ_{m−1}, ŷ₀…ŷ_{m−1}), minimise V_MHE with
/// x_{j+1} = Ax_j + Bu_j + Eŵ¹_j and ŷ_j = Cx_j + Fŵ²_j as equalities, x_j ∈ 𝒳 (j = 0..m),
/// ŵ_j ∈ 𝒲, ŷ_j ∈ 𝒴. Returns the condensed (x₀, ŵ₀, …).
fn uncondensed(f: &Fixture, d: &Data, m: usize) -> Vec<f64> {
    let sys = &f.sys;
    let (nx, nu, ny, nw1, nw) = (sys.nx(), sys.nu(), sys.ny(), sys.nw1(), sys.nw());
    let w = f.config.weights();
    let (xo, wo, yo) = (0, (m + 1) * nx, (m + 1) * nx + m * nw);
    let nv = yo + m * ny;
    // ½vᵀPv + cᵀv = V_MHE − const.
    let mut p = Mat::<f64>::zeros(nv, nv);
    let mut c = vec![0.0; nv];
    let eta_m = w.eta.powi(m as i32);
    for i in 0..nx {
        for k in 0..nx {
            p[(i, k)] = 4.0 * eta_m * w.p[(i, k)];
            c[i] -= 4.0 * eta_m * w.p[(i, k)] * f.prior[k];
        }
    }
    for j in 0..m {
        let dj = w.eta.powi((m - 1 - j) as i32);
        for i in 0..nw {
            for k in 0..nw {
                p[(wo + j * nw + i, wo + j * nw + k)] = 4.0 * dj * w.q[(i, k)];
            }
        }
        for i in 0..ny {
            for k in 0..ny {
                p[(yo + j * ny + i, yo + j * ny + k)] = 2.0 * dj * w.r[(i, k)];
                c[yo + j * ny + i] -= 2.0 * dj * w.r[(i, k)] * d.ys[j][k];
            }
        }
    }
    // Rows: equalities first, then one per finite bound.
    let mut rows: Vec<(Vec<(usize, f64)>, f64)> = Vec::new();
    let (a, b, cm, e, fm) = (sys.a(), sys.b(), sys.c(), sys.e(), sys.f());
    for j in 0..m {
        for i in 0..nx {
            let mut r = vec![(xo + (j + 1) * nx + i, 1.0)];
            for k in 0..nx {
                r.push((xo + j * nx + k, -a[(i, k)]));
            }
            for k in 0..nw1 {
                r.push((wo + j * nw + k, -e[(i, k)]));
            }
            let bu: f64 = (0..nu).map(|k| b[(i, k)] * d.us[j][k]).sum();
            rows.push((r, bu));
        }
        for i in 0..ny {
            let mut r = vec![(yo + j * ny + i, 1.0)];
            for k in 0..nx {
                r.push((xo + j * nx + k, -cm[(i, k)]));
            }
            for k in 0..nw - nw1 {
                r.push((wo + j * nw + nw1 + k, -fm[(i, k)]));
            }
            rows.push((r, 0.0));
        }
    }
    let n_eq = rows.len();
    let mut bound = |var: usize, lo: f64, hi: f64| {
        if hi.is_finite() {
            rows.push((vec![(var, 1.0)], hi));
        }
        if lo.is_finite() {
            rows.push((vec![(var, -1.0)], -lo));
        }
    };
    let s = &d.sets;
    for j in 0..=m {
        for i in 0..nx {
            bound(xo + j * nx + i, s.state.lower()[i], s.state.upper()[i]);
        }
    }
    for j in 0..m {
        for i in 0..nw {
            bound(
                wo + j * nw + i,
                s.disturbance.lower()[i],
                s.disturbance.upper()[i],
            );
        }
        for i in 0..ny {
            bound(yo + j * ny + i, s.output.lower()[i], s.output.upper()[i]);
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
    let bv: Vec<f64> = rows.iter().map(|r| r.1).collect();
    let mut cones = vec![SupportedConeT::ZeroConeT(n_eq)];
    if rows.len() > n_eq {
        cones.push(SupportedConeT::NonnegativeConeT(rows.len() - n_eq));
    }
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-12)
        .tol_gap_rel(1e-12)
        .tol_feas(1e-12)
        .max_iter(400)
        .build()
        .unwrap();
    let mut solver =
        DefaultSolver::new(&csc(&p, true), &c, &csc(&am, false), &bv, &cones, settings).unwrap();
    solver.solve();
    let sol = &solver.solution;
    assert!(
        matches!(
            sol.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ),
        "{:?}",
        sol.status
    );
    let mut z = sol.x[..nx].to_vec();
    z.extend_from_slice(&sol.x[wo..wo + m * nw]);
    z
}

#[test]
fn constrained_mhe_matches_an_uncondensed_clarabel_solve() {
    let (mut worst, mut rows, mut active) = (0.0f64, 0usize, 0usize);
    for seed in 0..120u64 {
        let m = 1 + (seed as usize % 5);
        let mut f = random_fixture(seed, m, 10, true);
        f.noise = 0.0;
        let d = data(&f, m, seed ^ 0x99);
        let prob = MheProblem::new(&f.sys, m, &f.config.weights(), &d.sets).unwrap();
        let win = prob.window(m).unwrap();
        let th = theta(&f, &d);
        let mut ex = ExactSolver::new(win.qp()).unwrap();
        let z = ex.solve(&th).unwrap().to_vec();
        let zc = uncondensed(&f, &d, m);
        let rel = dist(&z, &zc) / (1.0 + zc.iter().map(|v| v * v).sum::<f64>().sqrt());
        assert!(rel <= 1e-7, "seed {seed}: rel {rel:.3e}");
        worst = worst.max(rel);
        if let Some(gc) = win.qp().general() {
            rows += gc.m();
            let (mut lo, mut hi) = (vec![0.0; gc.m()], vec![0.0; gc.m()]);
            gc.bounds(&th, &mut lo, &mut hi);
            for r in 0..gc.m() {
                let g = gc.row_dot(r, &z);
                if (g - lo[r]).abs() < 1e-8 || (g - hi[r]).abs() < 1e-8 {
                    active += 1;
                }
            }
        }
    }
    println!("worst relative distance {worst:.3e}; {rows} general rows, {active} active");
    assert!(active > 20, "the test needs active rows: {active}");
}

#[test]
fn bounded_state_voids_the_certified_l_phi_with_the_reason() {
    let mut f = random_fixture(3, 3, 10, true);
    f.noise = 0.0;
    assert!(f.sys.nu() > 0 || f.sys.nu() == 0);
    let d = data(&f, 3, 5);
    let prob = MheProblem::new(&f.sys, 3, &f.config.weights(), &d.sets).unwrap();
    if f.sys.nu() > 0 {
        assert_eq!(prob.lipschitz_void_reason(), Some(LIPSCHITZ_VOID_REASON));
        assert!(prob.lipschitz_certified().is_infinite());
        // The sampled estimate is still there (finite).
        let est = prob
            .window(3)
            .unwrap()
            .sample_lipschitz(&mhe_core::problem::LipschitzSampling {
                pairs: 20,
                theta_radius: 0.1,
                perturbation: 0.01,
                ..Default::default()
            })
            .unwrap();
        assert!(est.sampled.is_finite() && est.certified.is_infinite());
    }
    // Whole 𝒳 and 𝒴: no rows, the certified bound as before.
    let free = MheProblem::new(&f.sys, 3, &f.config.weights(), &f.sets).unwrap();
    assert!(free.lipschitz_void_reason().is_none() && free.lipschitz_certified().is_finite());
    assert!(free.windows().iter().all(|w| w.qp().general().is_none()));
}

#[test]
fn k_iteration_estimator_with_bounded_sets_is_feasible_with_pg_and_reports_admm_violation() {
    for seed in 0..10u64 {
        let m = 3;
        let mut f = random_fixture(seed, m, 30, true);
        f.noise = 0.0;
        let steps = 8;
        let d = data(&f, steps, seed ^ 0x77);
        for method in [Method::PG, Method::FISTA, Method::ADMM] {
            let mut est =
                MheEstimator::new(&f.sys, &d.sets, &f.config, &f.prior, |qp| method.build(qp))
                    .unwrap();
            for t in 0..steps {
                est.estimate().unwrap();
                let rec = est.last_record();
                assert!(
                    rec.epsilon.unwrap().is_finite(),
                    "seed {seed} {method} t {t}"
                );
                if method != Method::ADMM {
                    assert!(
                        rec.violation <= 1e-8,
                        "seed {seed} {method} t {t}: {}",
                        rec.violation
                    );
                }
                est.push(&d.us[t], &d.ys[t]).unwrap();
            }
            if method == Method::ADMM {
                let cert = est.map(m).unwrap().certificate();
                let split = est.problem().window(m).unwrap().qp().general().is_some();
                assert_eq!(cert.fits_eq11, !split);
            }
        }
    }
}
