//! (d) MHE vs Kalman filter, with the expectation derived, not tuned.
//!
//! Derivation (details in `mhe_core::kalman`). With 𝒲 = ℝ^{n_w} (and 𝒳 = ℝ^{n_x},
//! 𝒴 = ℝ^{n_y}), ℙ_t for t ≤ M is the η-discounted full-information problem
//! min 2η^t‖x̂₀ − x̄₀‖²_P + Σ_{j<t} η^{t−1−j}(2‖ŵ_j‖²_Q + ‖C x̂_j + F ŵ²_j − y_j‖²_R).
//! Scaling by η^{−t} (same minimiser) gives ‖x̂₀ − x̄₀‖²_{2P} + Σ_j (‖ŵ_j‖²_{2η^{−(j+1)}Q} +
//! ‖ŷ_j − y_j‖²_{η^{−(j+1)}R}): −2 log of the posterior of (x₀, w) given y in the Gaussian
//! model x₀ ~ N(x̄₀, (2P)⁻¹), w_j ~ N(0, η^{j+1}(2Q)⁻¹), y_j = C x_j + F w²_j + v_j,
//! v_j ~ N(0, η^{j+1}R⁻¹). The posterior mode is the mean and x̂_t is linear in (x₀, w), so
//! x̂*_{t|t} = E[x_t | y_{<t}], which the predictor-form Kalman filter for that model
//! computes: λ = η, Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹ (w¹ and w² correlated unless Q is
//! block-diagonal: cross-covariance E Σ_w,12 Fᵀ), Σ_v = R⁻¹ — the factor 2 on Q and the
//! 2η^{M_t} on the prior are why Σ_w and Π₀ carry ½. Hence equality for t ≤ M (to rounding).
//!
//! For t > M the MHE's prior is its own estimate x̂_{t−M|t−M} with weight 2η^M P, the
//! filter's is its propagated mean with information Π_{t−M}⁻¹; the same derivation applied
//! to the window [t − M, t) shows the MHE equals the matching filter *restarted* at t − M
//! from (x̂_{t−M|t−M}, (2P)⁻¹). The difference to the un-restarted filter is then a bounded
//! quantity: with noise-free data both are unbiased, the MHE error obeys e_t = G e_{t−M}
//! (G = ∂x̂_{t|t}/∂prior of the length-M window) and the filter's e_{t+1} = (A − K_t C)e_t;
//! both identities are checked and bound the difference.

use faer::Mat;
use faer::linalg::solvers::Solve;
use mhe_core::{Estimator, KalmanFilter, MheEstimator, MheSets};
use qp_iter::IterationMap;
use qp_iter::fista::Fista;

use crate::common::{Fixture, case_study, dist, random_fixture, simulate};

fn unconstrained(mut f: Fixture, horizon: usize) -> Fixture {
    f.sets = MheSets::unconstrained(&f.sys);
    f.config.horizon = horizon;
    f.config.exact_solve = true;
    f
}

/// The MHE with K large enough that every window's certificate gives φ(K) ≤ 1e-13, so its
/// own estimates (which become the priors for t > M) are the exact MHE's to rounding.
fn mhe(f: &Fixture) -> MheEstimator<Fista> {
    let probe = MheEstimator::new(&f.sys, &f.sets, &f.config, &f.prior, |qp| {
        Ok(Fista::new(qp))
    })
    .unwrap();
    let k = probe
        .maps()
        .iter()
        .map(|m| m.certificate().min_iterations(1e-13).unwrap())
        .max()
        .unwrap();
    let mut cfg = f.config.clone();
    cfg.iterations = crate::common::k(k);
    MheEstimator::new(&f.sys, &f.sets, &cfg, &f.prior, |qp| Ok(Fista::new(qp))).unwrap()
}

fn matching(f: &Fixture, prior: &[f64]) -> KalmanFilter {
    let c = &f.config;
    KalmanFilter::matching_mhe(&f.sys, prior, c.eta, &c.p, &c.q, &c.r).unwrap()
}

fn rel(a: &[f64], b: &[f64]) -> f64 {
    dist(a, b) / b.iter().fold(1.0_f64, |m, x| m.max(x.abs()))
}

/// Equality for t ≤ M, restart identity for t > M. Returns the largest difference to the
/// un-restarted filter for t > M (printed: bounded, not zero).
fn compare(f: &Fixture, steps: usize, seed: u64) -> f64 {
    let big_m = f.config.horizon;
    let (us, ys, _) = simulate(f, steps, seed);
    let mut est = mhe(f);
    let mut kf = matching(f, &f.prior);
    let mut worst_after = 0.0_f64;
    for t in 0..steps {
        est.estimate().unwrap();
        let rec = est.last_record();
        let x_mhe = rec.x_hat_exact().unwrap();
        assert!(
            rel(rec.x_hat(), x_mhe) < 1e-9,
            "K-iterate vs exact at t = {t}"
        );
        let x_kf = kf.estimate().unwrap();
        if t <= big_m {
            let d = rel(x_mhe, x_kf);
            assert!(
                d < 1e-8,
                "t = {t} ≤ M: MHE {x_mhe:?} vs fading-memory KF {x_kf:?} ({d:e})"
            );
        } else {
            worst_after = worst_after.max(dist(x_mhe, x_kf));
            let mut restarted = matching(f, rec.prior());
            for j in 0..big_m {
                restarted
                    .push(rec.u(j).unwrap(), rec.y(j).unwrap())
                    .unwrap();
            }
            let d = rel(x_mhe, restarted.estimate().unwrap());
            assert!(
                d < 1e-8,
                "t = {t} > M: MHE vs filter restarted at t − M from the MHE prior ({d:e})"
            );
        }
        est.push(&us[t], &ys[t]).unwrap();
        kf.push(&us[t], &ys[t]).unwrap();
    }
    worst_after
}

#[test]
fn mhe_equals_fading_memory_kalman_up_to_m_then_restarted_filter() {
    let f = unconstrained(case_study(8, 5, true), 8);
    let after = compare(&f, 20, 11);
    println!("case study, M = 8: sup_{{t>M}} ‖x̂_MHE − x̂_KF‖ = {after:.3e} (bounded, not zero)");
    assert!(
        after > 1e-8,
        "for t > M the arrival costs differ, so the estimates should too"
    );
    for seed in 0..6 {
        let horizon = 2 + seed as usize % 4;
        let f = unconstrained(random_fixture(600 + seed, horizon, 5, true), horizon);
        let after = compare(&f, 2 * horizon + 5, seed);
        println!("random {seed}, M = {horizon}: sup_{{t>M}} ‖x̂_MHE − x̂_KF‖ = {after:.3e}");
    }
}

fn row_major_to_mat(v: &[f64], r: usize, c: usize) -> Mat<f64> {
    Mat::from_fn(r, c, |i, j| v[i * c + j])
}

#[test]
fn difference_after_m_is_bounded_by_the_two_error_recursions() {
    // Noise-free data, wrong prior: both estimators are unbiased linear filters, so their
    // errors obey e_t = G e_{t−M} (MHE) and e_{t+1} = (A − K_t C) e_t (filter) exactly.
    let mut f = unconstrained(case_study(5, 5, true), 5);
    f.noise = 0.0;
    let big_m = 5;
    let steps = 80;
    let (us, ys, xs) = simulate(&f, steps, 3);
    let mut est = mhe(&f);
    let mut kf = matching(&f, &f.prior);

    // G = ∂x̂_{t|t}/∂prior for the length-M window: x̂ = X_z z* + X_θ θ, z* = −H_c⁻¹F_c θ.
    let win = est.problem().window(big_m).unwrap();
    let (xz, xth) = win.x_end_maps();
    let hinv_f = win
        .h_c()
        .to_owned()
        .llt(faer::Side::Lower)
        .unwrap()
        .solve(win.f_c());
    let total = xth - xz * &hinv_f;
    let g = total.as_ref().submatrix(0, 0, 4, 4).to_owned();
    let rho = lti_model::system::spectral_radius(g.as_ref()).unwrap();
    println!("ρ(G) = {rho:.4} (M-step contraction of the MHE error)");
    assert!(rho < 1.0);

    let (a, c) = (f.sys.a().to_owned(), f.sys.c().to_owned());
    let mut e_mhe: Vec<Vec<f64>> = Vec::new();
    let mut phi_kf = Mat::<f64>::identity(4, 4);
    let e0: Vec<f64> = (0..4).map(|i| f.prior[i] - f.x0[i]).collect();
    let mut worst = 0.0_f64;
    for t in 0..steps {
        est.estimate().unwrap();
        let x_mhe = est.last_record().x_hat().to_vec();
        let x_kf = kf.estimate().unwrap().to_vec();
        let e: Vec<f64> = (0..4).map(|i| x_mhe[i] - xs[t][i]).collect();
        let ek: Vec<f64> = (0..4).map(|i| x_kf[i] - xs[t][i]).collect();
        if t > big_m {
            let pred: Vec<f64> = (0..4)
                .map(|i| (0..4).map(|k| g[(i, k)] * e_mhe[t - big_m][k]).sum())
                .collect();
            assert!(
                dist(&e, &pred) <= 1e-9 * (1.0 + crate::common::dist(&pred, &[0.0; 4])),
                "t = {t}: e_t ≠ G e_(t−M)"
            );
        }
        let pred_kf: Vec<f64> = (0..4)
            .map(|i| (0..4).map(|k| phi_kf[(i, k)] * e0[k]).sum())
            .collect();
        assert!(
            dist(&ek, &pred_kf) <= 1e-9 * (1.0 + dist(&pred_kf, &[0.0; 4])),
            "t = {t}: filter error recursion"
        );
        // The two recursions bound the difference d_t = e_t − e^KF_t.
        let d = dist(&x_mhe, &x_kf);
        let bound = dist(&e, &[0.0; 4]) + dist(&pred_kf, &[0.0; 4]);
        assert!(d <= bound * (1.0 + 1e-9) + 1e-12);
        if t >= steps - big_m {
            worst = worst.max(d);
        }
        e_mhe.push(e);
        est.push(&us[t], &ys[t]).unwrap();
        kf.push(&us[t], &ys[t]).unwrap();
        let k = row_major_to_mat(kf.gain(), 4, 1);
        phi_kf = (&a - &k * &c) * &phi_kf;
    }
    let e0n = dist(&e0, &[0.0; 4]);
    println!("‖x̂_MHE − x̂_KF‖ over the last window: {worst:.3e} (initial error {e0n:.3e})");
    // Both error recursions contract: ρ(G) < 1 and ‖Φ_KF‖ → 0, so the difference decays.
    let phi_norm = lti_model::matrix::spectral_norm(phi_kf.as_ref());
    let g_pow_bound = rho.powi((steps / big_m) as i32 - 2);
    println!("‖Φ_KF(T)‖ = {phi_norm:.3e}, ρ(G)^(T/M − 2) = {g_pow_bound:.3e}");
    assert!(worst < 1e-3 * e0n);
}

/// The standard filter (λ = 1) against the batch weighted least-squares problem
/// min ‖x₀ − x̄₀‖²_{Π₀⁻¹} + Σ_j ‖w_j‖²_{Σ_w⁻¹} + ‖y_j − C x_j − F w²_j‖²_{Σ_v⁻¹}, solved by
/// normal equations: its minimiser's x_t is E[x_t | y_{<t}].
#[test]
fn standard_kalman_equals_batch_least_squares() {
    let f = random_fixture(700, 3, 1, false);
    let s = &f.sys;
    let (nx, nu, ny, nw, nw1) = (s.nx(), s.nu(), s.ny(), s.nw(), s.nw1());
    let pi0 = crate::common::random_spd(
        &mut rand_chacha::rand_core::SeedableRng::seed_from_u64(1),
        nx,
        0.3,
    );
    let sw = crate::common::random_spd(
        &mut rand_chacha::rand_core::SeedableRng::seed_from_u64(2),
        nw,
        0.3,
    );
    let sv = crate::common::random_spd(
        &mut rand_chacha::rand_core::SeedableRng::seed_from_u64(3),
        ny,
        0.3,
    );
    let mut kf = KalmanFilter::new(s, &f.prior, pi0.clone(), sw.clone(), sv.clone()).unwrap();
    let steps = 7;
    let (us, ys, _) = simulate(&f, steps, 9);
    let inv = |m: &Mat<f64>| {
        m.partial_piv_lu()
            .solve(Mat::<f64>::identity(m.nrows(), m.nrows()))
    };
    let (pi0i, swi, svi) = (inv(&pi0), inv(&sw), inv(&sv));
    for t in 0..=steps {
        if t > 0 {
            kf.push(&us[t - 1], &ys[t - 1]).unwrap();
        }
        // z = (x₀, w₀..w_{t−1}); x_j = X_j z + c_j.
        let n = nx + t * nw;
        let mut h = Mat::<f64>::zeros(n, n);
        let mut g = Mat::<f64>::zeros(n, 1);
        for i in 0..nx {
            for k in 0..nx {
                h[(i, k)] += pi0i[(i, k)];
                g[(i, 0)] += pi0i[(i, k)] * f.prior[k];
            }
        }
        let mut xj = Mat::<f64>::zeros(nx, n);
        let mut cj = Mat::<f64>::zeros(nx, 1);
        for i in 0..nx {
            xj[(i, i)] = 1.0;
        }
        for j in 0..t {
            let off = nx + j * nw;
            for i in 0..nw {
                for k in 0..nw {
                    h[(off + i, off + k)] += swi[(i, k)];
                }
            }
            // r = y − C x_j − F w²_j = y − C c_j − (C X_j + F sel) z.
            let mut rz = s.c() * &xj;
            for i in 0..ny {
                for k in 0..s.nw2() {
                    rz[(i, off + nw1 + k)] += s.f()[(i, k)];
                }
            }
            let rc = s.c() * &cj;
            let r0 = Mat::from_fn(ny, 1, |i, _| ys[j][i] - rc[(i, 0)]);
            h += rz.transpose() * &svi * &rz;
            g += rz.transpose() * &svi * &r0;
            let mut xn = s.a() * &xj;
            for i in 0..nx {
                for k in 0..nw1 {
                    xn[(i, off + k)] += s.e()[(i, k)];
                }
            }
            let bu: Mat<f64> = s.b() * Mat::from_fn(nu, 1, |i, _| us[j][i]);
            cj = s.a() * &cj + bu;
            xj = xn;
        }
        let z = h.partial_piv_lu().solve(&g);
        let xt = &xj * &z + &cj;
        let xt: Vec<f64> = (0..nx).map(|i| xt[(i, 0)]).collect();
        let d = rel(kf.estimate().unwrap(), &xt);
        assert!(d < 1e-9, "t = {t}: KF vs batch least squares ({d:e})");
    }
}
