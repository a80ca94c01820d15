//! The condensed QP against an independent evaluation of cost (9) by simulation; the
//! m = 0 closed form; W_m and H̄; certified L_Φ ≥ sampled L_Φ.

use faer::Mat;
use mhe_core::problem::{LipschitzSampling, MheProblem};
use mhe_core::{MheSets, MheWeights};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{Fixture, case_study, random_fixture};

fn weights(f: &Fixture) -> MheWeights {
    f.config.weights()
}

/// V_MHE of eq. (9) by simulating the window (no condensing).
fn cost_by_simulation(f: &Fixture, m: usize, z: &[f64], theta: &[f64]) -> f64 {
    let s = &f.sys;
    let (nx, nu, ny, nw) = (s.nx(), s.nu(), s.ny(), s.nw());
    let cfg = &f.config;
    let quad = |w: &Mat<f64>, v: &[f64]| -> f64 {
        (0..v.len())
            .map(|i| (0..v.len()).map(|k| v[i] * w[(i, k)] * v[k]).sum::<f64>())
            .sum()
    };
    let dx: Vec<f64> = (0..nx).map(|i| z[i] - theta[i]).collect();
    let mut v = 2.0 * cfg.eta.powi(m as i32) * quad(&cfg.p, &dx);
    let mut x = z[..nx].to_vec();
    for j in 0..m {
        // Stage j is time t − m + j = t − i with i = m − j: weight η^{i−1}.
        let i = m - j;
        let w = &z[nx + j * nw..nx + (j + 1) * nw];
        let u = &theta[nx + j * nu..nx + (j + 1) * nu];
        let y = &theta[nx + m * nu + j * ny..nx + m * nu + (j + 1) * ny];
        let mut xn = vec![0.0; nx];
        let mut yhat = vec![0.0; ny];
        s.step(&x, u, w, &mut xn, &mut yhat);
        let r: Vec<f64> = (0..ny).map(|k| yhat[k] - y[k]).collect();
        v += cfg.eta.powi(i as i32 - 1) * (2.0 * quad(&cfg.q, w) + quad(&cfg.r, &r));
        x = xn;
    }
    v
}

fn check_condensing(f: &Fixture, seed: u64) {
    let prob = MheProblem::new(&f.sys, f.config.horizon, &weights(f), &f.sets).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for w in prob.windows() {
        let (nz, nth) = (w.layout().nz(), w.layout().n_theta());
        let qp = w.qp();
        assert_eq!((qp.n(), qp.n_theta()), (nz, nth));
        assert!(qp.q0().iter().all(|v| *v == 0.0));
        for _ in 0..5 {
            let z: Vec<f64> = (0..nz).map(|_| 4.0 * rng.random::<f64>() - 2.0).collect();
            let th: Vec<f64> = (0..nth).map(|_| 4.0 * rng.random::<f64>() - 2.0).collect();
            let v = cost_by_simulation(f, w.m(), &z, &th);
            let v0 = cost_by_simulation(f, w.m(), &vec![0.0; nz], &th);
            let mut q = vec![0.0; nz];
            qp.linear_term(&th, &mut q);
            let quad = qp.objective(&q, &z);
            let scale = v.abs().max(1.0);
            assert!(
                (v - v0 - quad).abs() < 1e-10 * scale,
                "m = {}: V(z) − V(0) = {} vs ½zᵀH_c z + qᵀz = {quad}",
                w.m(),
                v - v0
            );
            assert!(
                (w.cost(&z, &th) - v).abs() < 1e-10 * scale,
                "m = {}: paper form ‖z_t − z̃_t‖²_H_t",
                w.m()
            );
        }
        // W_m = H_c/2 and its eigenvalues.
        let wm = w.weight();
        let (lo, hi) = lti_model::matrix::sym_extreme_eigenvalues("W", wm.as_ref()).unwrap();
        assert!(
            (lo - w.weight_min_eigenvalue()).abs() < 1e-10 * hi
                && (hi - w.weight_max_eigenvalue()).abs() < 1e-10 * hi
        );
        assert!((hi - 0.5 * qp.l()).abs() < 1e-10 * hi);
        // x̂_{t|t} maps agree with propagation.
        let (xz, xth) = w.x_end_maps();
        assert_eq!((xz.nrows(), xz.ncols(), xth.ncols()), (f.sys.nx(), nz, nth));
    }
    let hbar = prob
        .windows()
        .iter()
        .map(|w| w.weight_max_eigenvalue())
        .fold(0.0, f64::max);
    assert_eq!(prob.h_bar(), hbar);
}

#[test]
fn condensed_qp_reproduces_cost_9() {
    check_condensing(&case_study(5, 1, false), 1);
    for seed in 0..6 {
        check_condensing(
            &random_fixture(400 + seed, 1 + seed as usize % 4, 1, false),
            seed,
        );
    }
}

#[test]
fn window_zero_closed_form() {
    // m = 0: V = 2‖x̂ − prior‖²_P ⇒ H_c = 4P, F_c = −4P, z* = prior, exact L = 1 and the
    // certified bound is ‖(4P)^{1/2}‖/√(4λ_min P) = √κ(P).
    let f = case_study(5, 1, false);
    let prob = MheProblem::new(&f.sys, 5, &weights(&f), &f.sets).unwrap();
    let w0 = prob.window(0).unwrap();
    let p = &f.config.p;
    for i in 0..4 {
        for j in 0..4 {
            assert!((w0.h_c()[(i, j)] - 4.0 * p[(i, j)]).abs() < 1e-12 * p.norm_max());
            assert!((w0.f_c()[(i, j)] + 4.0 * p[(i, j)]).abs() < 1e-12 * p.norm_max());
        }
    }
    let (lo, hi) = lti_model::matrix::sym_extreme_eigenvalues("P", p.as_ref()).unwrap();
    assert!((w0.lipschitz_certified() - (hi / lo).sqrt()).abs() < 1e-9 * (hi / lo).sqrt());
    assert!((w0.lipschitz_unconstrained() - 1.0).abs() < 1e-9);
}

fn check_lipschitz(f: &Fixture, label: &str) {
    let prob = MheProblem::new(&f.sys, f.config.horizon, &weights(f), &f.sets).unwrap();
    let whole = f.sets.disturbance.is_whole();
    for radius in [1.0, 0.05] {
        let s = LipschitzSampling {
            pairs: 60,
            seed: 5,
            theta_radius: 10.0,
            perturbation: radius,
        };
        for est in prob.sample_lipschitz(&s).unwrap() {
            println!(
                "{label} m = {}: sampled {:.4} ≤ certified {:.4} (unconstrained ‖H⁻¹F‖ {:.4}, perturbation {radius})",
                est.window, est.sampled, est.certified, est.unconstrained
            );
            assert!(est.sampled > 0.0);
            assert!(
                est.sampled <= est.certified * (1.0 + 1e-9),
                "{label} m = {}: sampled above certified",
                est.window
            );
            if whole {
                assert!(est.sampled <= est.unconstrained * (1.0 + 1e-9));
            }
        }
    }
}

#[test]
fn certified_lipschitz_dominates_sampled() {
    check_lipschitz(&case_study(5, 1, false), "case study");
    let mut f = case_study(5, 1, false);
    f.sets = MheSets::unconstrained(&f.sys);
    check_lipschitz(&f, "case study, 𝒲 = ℝ⁵");
    for seed in 0..3 {
        check_lipschitz(
            &random_fixture(500 + seed, 3, 1, false),
            &format!("random {seed}"),
        );
    }
}

/// The sampled L_Φ is computed with the warm-started active set; the same seeded pairs
/// solved from scratch by Clarabel (the independent reference) give the same estimate.
#[test]
#[cfg(feature = "clarabel")]
fn sampled_lipschitz_matches_clarabel_on_the_same_pairs() {
    use rand::{Rng, SeedableRng};
    let f = case_study(5, 1, false);
    let prob = MheProblem::new(&f.sys, 5, &weights(&f), &f.sets).unwrap();
    let s = LipschitzSampling {
        pairs: 40,
        seed: 9,
        theta_radius: 10.0,
        perturbation: 1.0,
    };
    for (w, est) in prob
        .windows()
        .iter()
        .zip(prob.sample_lipschitz(&s).unwrap())
    {
        let mut clarabel =
            qp_iter::reference::ReferenceSolver::new(w.qp(), Default::default()).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed);
        let nth = w.qp().n_theta();
        let (mut ta, mut tb) = (vec![0.0; nth], vec![0.0; nth]);
        let mut best = 0.0_f64;
        for _ in 0..s.pairs {
            for i in 0..nth {
                ta[i] = s.theta_radius * (2.0 * rng.random::<f64>() - 1.0);
                tb[i] = ta[i] + s.perturbation * (2.0 * rng.random::<f64>() - 1.0);
            }
            let za = clarabel.solve(&ta).unwrap().z;
            let zb = clarabel.solve(&tb).unwrap().z;
            best =
                best.max(lti_model::vecmath::dist2(&za, &zb) / lti_model::vecmath::dist2(&ta, &tb));
        }
        assert!(
            (est.sampled - best).abs() <= 1e-7 * best.max(1e-12),
            "window {}: active set {} vs Clarabel {best}",
            est.window,
            est.sampled
        );
    }
}
