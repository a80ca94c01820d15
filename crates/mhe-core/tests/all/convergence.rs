//! (b) ε_t in condensed coordinates obeys each map's certificate φ(K) (eq. 11) at every
//! step, and with K large the K-iteration estimate converges to the exact one.

use mhe_core::{MheConfig, MheEstimator, WarmStart};
use qp_iter::admm::{Admm, AdmmParams};
use qp_iter::fista::Fista;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{IterationMap, ParametricQp};

use crate::common::{Fixture, case_study, random_fixture, simulate};

/// Runs `steps` steps; checks ε_t ≤ φ_m(K)‖z⁰_t − z*_t‖ for the window's map at every t
/// and returns sup_t ‖x̂ᴷ_{t|t} − x̂*_{t|t}‖ (same θ) and sup_t ε_t.
fn run<M, F>(f: &Fixture, cfg: &MheConfig, steps: usize, factory: F) -> (f64, f64)
where
    M: IterationMap,
    F: Fn(ParametricQp) -> qp_iter::Result<M>,
{
    let (us, ys, _) = simulate(f, steps, 21);
    let mut mhe = MheEstimator::new(&f.sys, &f.sets, cfg, &f.prior, factory).unwrap();
    let (mut worst_x, mut worst_eps) = (0.0_f64, 0.0_f64);
    for t in 0..steps {
        mhe.estimate().unwrap();
        let rec = mhe.last_record();
        let cert = mhe.map(rec.window).unwrap().certificate();
        let (eps, eps0) = (rec.epsilon.unwrap(), rec.initial_error.unwrap());
        assert!(cert.fits_eq11);
        assert!(
            eps <= cert.phi(cfg.iterations.get()) * eps0 * (1.0 + 1e-9) + 1e-12,
            "{} t = {t}: ε = {eps:e} > φ(K)‖z⁰ − z*‖ = {:e}",
            mhe.map(0).unwrap().name(),
            cert.phi(cfg.iterations.get()) * eps0
        );
        assert!(rec.violation <= 1e-12, "Assumption 5: zᴷ feasible");
        worst_x = worst_x.max(crate::common::dist(rec.x_hat(), rec.x_hat_exact().unwrap()));
        worst_eps = worst_eps.max(eps);
        mhe.push(&us[t], &ys[t]).unwrap();
    }
    (worst_x, worst_eps)
}

fn with_k(f: &Fixture, k: usize, warm: WarmStart) -> MheConfig {
    let mut c = f.config.clone();
    c.iterations = crate::common::k(k);
    c.warm_start = warm;
    c.exact_solve = true;
    c
}

#[test]
fn certificates_hold_in_condensed_coordinates() {
    let f = case_study(5, 1, true);
    for k in [1, 5, 30] {
        for warm in [WarmStart::Paper, WarmStart::Shifted] {
            let cfg = with_k(&f, k, warm);
            run(&f, &cfg, 14, |qp| {
                ProjectedGradient::new(qp, StepRule::InverseL)
            });
            run(&f, &cfg, 14, |qp| {
                ProjectedGradient::new(qp, StepRule::Optimal)
            });
            run(&f, &cfg, 14, |qp| Ok(Fista::new(qp)));
            run(&f, &cfg, 14, |qp| Admm::new(qp, AdmmParams::default()));
        }
    }
    for seed in 0..3 {
        let f = random_fixture(800 + seed, 3, 1, true);
        let cfg = with_k(&f, 7, WarmStart::Paper);
        run(&f, &cfg, 9, |qp| {
            ProjectedGradient::new(qp, StepRule::Optimal)
        });
        run(&f, &cfg, 9, |qp| Ok(Fista::new(qp)));
    }
}

#[test]
fn k_large_converges_to_the_exact_estimate() {
    let f = case_study(5, 1, true);
    let probe = MheEstimator::new(&f.sys, &f.sets, &f.config, &f.prior, |qp| {
        ProjectedGradient::new(qp, StepRule::Optimal)
    })
    .unwrap();
    let rate = probe
        .maps()
        .iter()
        .map(|m| m.certificate().rate)
        .fold(0.0, f64::max);
    // K such that φ(K) ≤ 1e-12 on every window (derived from the certificate).
    let k_exact = probe
        .maps()
        .iter()
        .map(|m| m.certificate().min_iterations(1e-12).unwrap())
        .max()
        .unwrap();
    println!("PG (step 2/(L+μ)) worst rate {rate:.4}, K for φ ≤ 1e-12: {k_exact}");
    let mut last = f64::INFINITY;
    for k in [2, 8, 32, 128, k_exact] {
        let (dx, eps) = run(&f, &with_k(&f, k, WarmStart::Paper), 16, |qp| {
            ProjectedGradient::new(qp, StepRule::Optimal)
        });
        println!("K = {k}: sup_t ‖x̂ᴷ − x̂*‖ = {dx:.3e}, sup_t ε_t = {eps:.3e}");
        assert!(eps <= last * (1.0 + 1e-9), "sup ε did not decrease with K");
        last = eps;
        if k == k_exact {
            assert!(eps < 1e-9 && dx < 1e-9);
        }
    }
}
