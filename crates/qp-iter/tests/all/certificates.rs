//! Certificate soundness on random strongly convex QPs (3 × 700 instances, one set per
//! method family): after K = 0…60 steps the certified quantity is within φ(K)·(initial
//! value), with z* from Clarabel (polished) and its own error bound as slack.

use qp_iter::admm::{Admm, AdmmParams, Penalty};
use qp_iter::fista::Fista;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{BoundedQuantity, CertNorm, IterationMap};
use rand::Rng;

use crate::common::{
    Gen, Instance, Reference, Tally, check_sequence, dist, gradient, random_instance, reference,
    rng,
};

pub const K_MAX: usize = 60;
const INSTANCES: u64 = 700;

/// ‖iterate_k − z*‖ for k = 0…K_MAX after load(θ) and warm_start(z⁰, dual).
pub fn iterate_errors<M: IterationMap>(
    map: &M,
    inst: &Instance,
    zstar: &[f64],
    dual: Option<&[f64]>,
) -> Vec<f64> {
    let mut s = map.new_state();
    map.load(&mut s, &inst.theta);
    map.warm_start(&mut s, &inst.z0, dual);
    let mut errs = vec![dist(map.iterate(&s), zstar)];
    for _ in 0..K_MAX {
        map.step(&mut s);
        errs.push(dist(map.iterate(&s), zstar));
    }
    errs
}

/// Checks `map.certificate()` (an eq. (11) bound on the returned iterate) on one instance.
fn check_eq11<M: IterationMap>(map: &M, inst: &Instance, r: &Reference, tally: &mut Tally) {
    let c = map.certificate();
    assert_eq!(
        (c.quantity, &c.norm),
        (BoundedQuantity::IterateDistance, &CertNorm::Euclidean)
    );
    assert!(
        c.fits_eq11 && c.rate < 1.0,
        "{}: rate {}",
        map.name(),
        c.rate
    );
    let errs = iterate_errors(map, inst, &r.sol.z, None);
    let e0 = dist(&inst.z0, &r.sol.z);
    let bad = check_sequence(e0, &errs, |k| c.phi(k), r.err, tally);
    assert_eq!(
        bad,
        0,
        "seed {}: {} certificate violated (κ = {:.3e}, n = {}): e0 = {e0:.3e}, errors {:?}, φ = {:?}",
        inst.seed,
        map.name(),
        inst.qp.kappa(),
        inst.qp.n(),
        &errs[..8.min(errs.len())],
        (0..8).map(|k| c.phi(k)).collect::<Vec<_>>()
    );
}

#[test]
fn projected_gradient_bound_holds_on_random_qps() {
    let (mut inv_l, mut opt) = (Tally::default(), Tally::default());
    for seed in 0..INSTANCES {
        let inst = random_instance(seed, Gen::default());
        let r = reference(&inst);
        let pg = ProjectedGradient::new(inst.qp.clone(), StepRule::InverseL).unwrap();
        check_eq11(&pg, &inst, &r, &mut inv_l);
        let pg = ProjectedGradient::new(inst.qp.clone(), StepRule::Optimal).unwrap();
        check_eq11(&pg, &inst, &r, &mut opt);
    }
    println!("pg 1/L: {inv_l:?}\npg 2/(L+μ): {opt:?}");
    // The bound is attained up to the start's component on the extreme eigenvectors:
    // a checker that never gets close to it would be suspicious.
    assert!(
        inv_l.worst_ratio > 0.5 && opt.worst_ratio > 0.5,
        "{inv_l:?} {opt:?}"
    );
    assert!(inv_l.checks >= INSTANCES as usize * (K_MAX + 1));
}

#[test]
fn fista_bound_holds_on_random_qps() {
    let mut t = Tally::default();
    for seed in 10_000..10_000 + INSTANCES {
        let inst = random_instance(seed, Gen::default());
        let r = reference(&inst);
        check_eq11(&Fista::new(inst.qp.clone()), &inst, &r, &mut t);
    }
    println!("fista: {t:?}");
    assert!(t.checks >= INSTANCES as usize * (K_MAX + 1));
}

#[test]
fn admm_bounds_hold_on_random_qps() {
    let (mut eq11, mut split) = (Tally::default(), Tally::default());
    for seed in 20_000..20_000 + INSTANCES {
        let inst = random_instance(seed, Gen::default());
        let r = reference(&inst);
        let (mu, l) = (inst.qp.mu(), inst.qp.l());
        let mut g = rng(seed ^ 0xadd);
        let rho = mu / 10.0 * (100.0 * l / mu).powf(g.random::<f64>());
        let alpha = 0.2 + 1.8 * g.random::<f64>();
        let maps = [
            Admm::new(inst.qp.clone(), AdmmParams::default()).unwrap(),
            Admm::new(
                inst.qp.clone(),
                AdmmParams {
                    penalty: Penalty::Optimal,
                    relaxation: 2.0,
                },
            )
            .unwrap(),
            Admm::new(
                inst.qp.clone(),
                AdmmParams {
                    penalty: Penalty::Fixed(rho),
                    relaxation: alpha,
                },
            )
            .unwrap(),
        ];
        // y* = −(Hz* + q) and s* = z* + y*/ρ.
        let ystar: Vec<f64> = gradient(&inst.qp, &r.q, &r.sol.z)
            .iter()
            .map(|g| -g)
            .collect();
        let y0: Vec<f64> = (0..inst.qp.n())
            .map(|i| ystar[i] + 2.0 * crate::common::normal(&mut g))
            .collect();
        for admm in &maps {
            check_eq11(admm, &inst, &r, &mut eq11);
            // DR variable: any dual.
            let c = admm.splitting_certificate();
            assert_eq!(c.quantity, BoundedQuantity::SplittingVariable);
            assert!(!c.fits_eq11);
            let sstar: Vec<f64> = r
                .sol
                .z
                .iter()
                .zip(&ystar)
                .map(|(z, y)| z + y / admm.rho())
                .collect();
            let mut s = admm.new_state();
            admm.load(&mut s, &inst.theta);
            admm.warm_start(&mut s, &inst.z0, Some(&y0));
            let mut sv = vec![0.0; inst.qp.n()];
            let mut errs = Vec::with_capacity(K_MAX + 1);
            for k in 0..=K_MAX {
                if k > 0 {
                    admm.step(&mut s);
                }
                admm.splitting_variable(&s, &mut sv);
                errs.push(dist(&sv, &sstar));
            }
            let slack = r.err * (1.0 + l / admm.rho());
            let bad = check_sequence(errs[0], &errs, |k| c.phi(k), slack, &mut split);
            assert_eq!(
                bad,
                0,
                "seed {}: ADMM DR-variable bound violated (ρ = {}, α = {})",
                seed,
                admm.rho(),
                admm.relaxation()
            );
        }
    }
    println!("admm eq.(11) on v: {eq11:?}\nadmm DR variable: {split:?}");
    assert!(split.worst_ratio > 0.1, "{split:?}");
}
