//! The Jacobi-scaled maps (`qp_iter::scaled`): their certificate — the inner rate with the
//! prefactor times κ(D) — holds on random badly scaled QPs; without the κ(D) factor (the
//! inner map's own claim read in the wrong coordinates) it is violated; D = I changes
//! nothing.

use faer::Mat;
use qp_iter::BoxSet;
use qp_iter::scaled::Scaled;
use qp_iter::{IterationMap, Method, MethodMap, ParametricQp};
use rand::Rng;

use crate::certificates::iterate_errors;
use crate::common::{Instance, Tally, check_sequence, dist, random_instance, reference, rng};

const INSTANCES: u64 = 300;

/// A random instance with its variables rescaled by S (log-uniform in [10^-1.5, 10^1.5]):
/// H' = SHS, q₀' = Sq₀, F' = SF, Z' = S⁻¹Z, z⁰' = S⁻¹z⁰ — the same problem in badly scaled
/// coordinates, the case Jacobi scaling is for. Returns it with z* and the reference's error
/// bound, both mapped from Clarabel's solve of the well-scaled original (z*' = S⁻¹z*).
fn badly_scaled(seed: u64) -> (Instance, Vec<f64>, f64) {
    let inst = random_instance(seed, crate::common::Gen::default());
    let qp = &inst.qp;
    let n = qp.n();
    let mut g = rng(seed ^ 0x5ca1e);
    let s: Vec<f64> = (0..n)
        .map(|_| 10f64.powf(3.0 * g.random::<f64>() - 1.5))
        .collect();
    let h = qp.h();
    let f = qp.f();
    let scaled = ParametricQp::new(
        Mat::from_fn(n, n, |i, j| s[i] * h[(i, j)] * s[j]),
        qp.q0().iter().zip(&s).map(|(q, si)| q * si).collect(),
        Mat::from_fn(n, f.ncols(), |i, j| s[i] * f[(i, j)]),
        BoxSet::new(
            qp.zset()
                .lower()
                .iter()
                .zip(&s)
                .map(|(l, si)| l / si)
                .collect(),
            qp.zset()
                .upper()
                .iter()
                .zip(&s)
                .map(|(u, si)| u / si)
                .collect(),
        )
        .unwrap(),
    )
    .unwrap();
    let r = reference(&inst);
    let zstar = r.sol.z.iter().zip(&s).map(|(z, si)| z / si).collect();
    let s_min = s.iter().copied().fold(f64::INFINITY, f64::min);
    let scaled_inst = Instance {
        qp: scaled,
        theta: inst.theta.clone(),
        z0: inst.z0.iter().zip(&s).map(|(z, si)| z / si).collect(),
        seed,
    };
    (scaled_inst, zstar, r.err / s_min)
}

#[test]
fn jacobi_certificates_hold_and_need_the_kappa_d_factor() {
    let mut held: [Tally; 4] = Default::default();
    let mut without_kappa_d: [Tally; 4] = Default::default();
    let mut better_rate = 0;
    for seed in 60_000..60_000 + INSTANCES {
        let (inst, zstar, err) = badly_scaled(seed);
        let e0 = dist(&inst.z0, &zstar);
        for (i, m) in Method::JACOBI_PRESETS.iter().enumerate() {
            let map = m.build(inst.qp.clone()).unwrap();
            let c = map.certificate().clone();
            assert!(c.fits_eq11 && c.rate < 1.0, "{m}: {c:?}");
            let errs = iterate_errors(&map, &inst, &zstar, None);
            let bad = check_sequence(e0, &errs, |k| c.phi(k), err, &mut held[i]);
            assert_eq!(bad, 0, "seed {seed}: {m} violated its certificate");
            // The premise broken: the inner map's bound (on y) read as a bound on z.
            let MethodMap::Scaled(s) = &map else {
                panic!("{m} is not scaled")
            };
            let inner = s.inner().certificate().clone();
            check_sequence(e0, &errs, |k| inner.phi(k), err, &mut without_kappa_d[i]);
            let plain = m.with_scaling(qp_iter::Scaling::None);
            if c.rate < plain.certificate_for(inst.qp.clone()).unwrap().rate {
                better_rate += 1;
            }
        }
    }
    for (i, m) in Method::JACOBI_PRESETS.iter().enumerate() {
        println!("{m}: {:?}; without κ(D): {:?}", held[i], without_kappa_d[i]);
        assert!(held[i].checks >= INSTANCES as usize * 61);
    }
    // Without κ(D) the claim fails somewhere: the factor is needed, and the checker can fail.
    let violated: usize = without_kappa_d.iter().map(|t| t.instances_violated).sum();
    assert!(
        violated > 0,
        "the κ(D)-free claim never failed: {without_kappa_d:?}"
    );
    // On badly scaled problems the scaled rate is better almost always.
    assert!(
        better_rate as f64 > 0.9 * 4.0 * INSTANCES as f64,
        "{better_rate} of {}",
        4 * INSTANCES
    );
}

#[test]
fn unit_scaling_changes_nothing() {
    for seed in 61_000..61_050 {
        let inst = random_instance(seed, crate::common::Gen::default());
        for m in Method::PRESETS {
            let plain = m.build(inst.qp.clone()).unwrap();
            let unit =
                Scaled::new(inst.qp.clone(), vec![1.0; inst.qp.n()], |qp| m.build(qp)).unwrap();
            assert_eq!(unit.kappa_d(), 1.0);
            assert_eq!(unit.certificate().rate, plain.certificate().rate);
            assert_eq!(unit.certificate().prefactor, plain.certificate().prefactor);
            let zs = inst.z0.clone();
            let a = iterate_errors(&plain, &inst, &zs, None);
            let b = iterate_errors(&unit, &inst, &zs, None);
            for (x, y) in a.iter().zip(&b) {
                assert!(
                    (x - y).abs() <= 1e-12 * (1.0 + x.abs()),
                    "{m} seed {seed}: {x} vs {y}"
                );
            }
        }
    }
}

#[test]
fn bad_scalings_are_typed_errors() {
    let inst = random_instance(7, crate::common::Gen::default());
    let n = inst.qp.n();
    for d in [
        vec![1.0; n + 1],
        {
            let mut d = vec![1.0; n];
            d[0] = 0.0;
            d
        },
        {
            let mut d = vec![1.0; n];
            d[n - 1] = f64::NAN;
            d
        },
    ] {
        let e = Scaled::new(inst.qp.clone(), d, |qp| Method::PG.build(qp)).unwrap_err();
        assert!(e.to_string().contains("scaling"), "{e}");
    }
}
