//! Behaviour of every method: convergence to Clarabel's optimum, fixed point at z*,
//! restart semantics, feasibility after every step, certificate formulas.

use faer::Mat;
use qp_iter::admm::{Admm, AdmmParams, Penalty};
use qp_iter::fista::Fista;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{BoxSet, ConvexSet};
use qp_iter::{Certificate, IterationMap, ParametricQp, RunStatus, run_fixed, run_until};

use crate::common::{Gen, dist, gradient, norm, random_instance, reference};

/// Object-safe helpers over [`IterationMap`], so every method runs through the same checks.
trait DynMap {
    fn label(&self) -> String;
    fn cert(&self) -> &Certificate;
    fn converge(&self, theta: &[f64], z0: &[f64], zstar: &[f64], tol: f64) -> (RunStatus, usize);
    fn one_step_from(
        &self,
        theta: &[f64],
        z: &[f64],
        dual: Option<&[f64]>,
    ) -> (Vec<f64>, Option<Vec<f64>>);
    fn trajectory(
        &self,
        dirty: bool,
        theta_old: &[f64],
        theta: &[f64],
        z0: Option<&[f64]>,
        k: usize,
    ) -> Vec<Vec<f64>>;
    fn feasible_every_step(&self, theta: &[f64], z0: &[f64], k: usize) -> bool;
}

impl<M: IterationMap> DynMap for M {
    fn label(&self) -> String {
        format!("{} (rate {:.4})", self.name(), self.certificate().rate)
    }
    fn cert(&self) -> &Certificate {
        self.certificate()
    }
    fn converge(&self, theta: &[f64], z0: &[f64], zstar: &[f64], tol: f64) -> (RunStatus, usize) {
        let mut s = self.new_state();
        self.load(&mut s, theta);
        self.warm_start(&mut s, z0, None);
        // The certified budget for accuracy tol/10 (capped): the certificate must deliver it.
        let e0 = dist(z0, zstar).max(1e-300);
        let kmax = self
            .certificate()
            .min_iterations(0.1 * tol / e0)
            .unwrap_or(200_000)
            .clamp(1, 200_000);
        let res = run_until(self, &mut s, kmax, |_, z| {
            (dist(z, zstar) <= tol).then_some(true)
        });
        (res.status, res.iterations)
    }
    fn one_step_from(
        &self,
        theta: &[f64],
        z: &[f64],
        dual: Option<&[f64]>,
    ) -> (Vec<f64>, Option<Vec<f64>>) {
        let mut s = self.new_state();
        self.load(&mut s, theta);
        self.warm_start(&mut s, z, dual);
        self.step(&mut s);
        (
            self.iterate(&s).to_vec(),
            self.dual(&s).map(<[f64]>::to_vec),
        )
    }
    fn trajectory(
        &self,
        dirty: bool,
        theta_old: &[f64],
        theta: &[f64],
        z0: Option<&[f64]>,
        k: usize,
    ) -> Vec<Vec<f64>> {
        let mut s = self.new_state();
        if dirty {
            // Another θ and a few steps first.
            self.load(&mut s, theta_old);
            run_fixed(self, &mut s, 7);
        }
        self.load(&mut s, theta);
        match z0 {
            Some(z0) => self.warm_start(&mut s, z0, None),
            None => self.cold_start(&mut s),
        }
        let mut out = vec![self.iterate(&s).to_vec()];
        for _ in 0..k {
            self.step(&mut s);
            out.push(self.iterate(&s).to_vec());
        }
        out
    }
    fn feasible_every_step(&self, theta: &[f64], z0: &[f64], k: usize) -> bool {
        let mut s = self.new_state();
        self.load(&mut s, theta);
        self.warm_start(&mut s, z0, None);
        (0..k).all(|_| {
            self.step(&mut s);
            self.problem().zset().contains(self.iterate(&s), 0.0)
        })
    }
}

/// Every method variant for `qp`.
fn methods(qp: &ParametricQp) -> Vec<Box<dyn DynMap>> {
    vec![
        Box::new(ProjectedGradient::new(qp.clone(), StepRule::InverseL).unwrap()),
        Box::new(ProjectedGradient::new(qp.clone(), StepRule::Optimal).unwrap()),
        Box::new(Fista::new(qp.clone())),
        Box::new(Admm::new(qp.clone(), AdmmParams::default()).unwrap()),
        Box::new(
            Admm::new(
                qp.clone(),
                AdmmParams {
                    penalty: Penalty::Optimal,
                    relaxation: 2.0,
                },
            )
            .unwrap(),
        ),
        Box::new(
            Admm::new(
                qp.clone(),
                AdmmParams {
                    penalty: Penalty::Fixed(3.0 * qp.l()),
                    relaxation: 1.6,
                },
            )
            .unwrap(),
        ),
    ]
}

/// Every method, from each instance's z⁰, converges to the reference optimum within the
/// budget of its certificate.
fn every_method_reaches_the_reference_optimum(seeds: std::ops::Range<u64>, opts: Gen) {
    for seed in seeds {
        let inst = random_instance(seed, opts);
        let r = reference(&inst);
        let tol = 1e-8 * (1.0 + norm(&r.sol.z));
        for m in methods(&inst.qp) {
            let (status, k) = m.converge(&inst.theta, &inst.z0, &r.sol.z, tol);
            assert_eq!(
                status,
                RunStatus::Converged,
                "seed {seed}, n = {}: {} stopped after {k} steps",
                inst.qp.n(),
                m.label()
            );
        }
    }
}

#[test]
fn every_method_reaches_the_reference_optimum_within_its_certified_budget() {
    let opts = Gen {
        log10_kappa_max: 3.0,
        ..Gen::default()
    };
    every_method_reaches_the_reference_optimum(50_000..50_060, opts);
}

/// Beyond n = 60 the padded kernels step through a scratch buffer instead of in place
/// (more than one register panel): the same end-to-end check there.
#[test]
fn every_method_reaches_the_reference_optimum_beyond_one_register_panel() {
    let opts = Gen {
        n_min: 61,
        n_max: 90,
        log10_kappa_max: 2.0,
        ..Gen::default()
    };
    every_method_reaches_the_reference_optimum(51_000..51_004, opts);
}

#[test]
fn admm_dual_and_residuals_converge_to_the_reference() {
    for seed in 51_000..51_040 {
        let inst = random_instance(
            seed,
            Gen {
                log10_kappa_max: 2.0,
                ..Gen::default()
            },
        );
        let r = reference(&inst);
        let admm = Admm::new(inst.qp.clone(), AdmmParams::default()).unwrap();
        let mut s = admm.new_state();
        admm.load(&mut s, &inst.theta);
        admm.warm_start(&mut s, &inst.z0, None);
        let k = admm.splitting_certificate().min_iterations(1e-13).unwrap();
        assert_eq!(run_fixed(&admm, &mut s, k).status, RunStatus::Completed);
        let y = admm.dual(&s).unwrap();
        let ystar = r.sol.dual();
        let scale = 1.0 + norm(&ystar) + norm(&r.sol.z) * inst.qp.l();
        assert!(
            dist(y, &ystar) <= 1e-8 * scale,
            "seed {seed}: dual error {:e}",
            dist(y, &ystar)
        );
        assert!(dist(admm.iterate(&s), &r.sol.z) <= 1e-9 * (1.0 + norm(&r.sol.z)));
        assert!(admm.constraint_violation(&s) <= admm.primal_residual(&s) + 1e-15);
        assert!(
            admm.primal_residual(&s) <= 1e-9 * (1.0 + norm(&r.sol.z)),
            "seed {seed}"
        );
        // constraint_violation is the Euclidean distance of z to Z.
        let z = admm.primal_z(&s);
        let mut p = z.to_vec();
        inst.qp.project(&mut p);
        assert!((admm.constraint_violation(&s) - dist(&p, z)).abs() <= 1e-15);
        assert!((admm.primal_residual(&s) - dist(z, admm.iterate(&s))).abs() <= 1e-15);
    }
}

#[test]
fn one_step_from_the_optimum_stays_there() {
    for seed in 52_000..52_100 {
        let inst = random_instance(seed, Gen::default());
        let r = reference(&inst);
        let zstar = &r.sol.z;
        let tol = 1e-9 * (1.0 + norm(zstar)) + r.err;
        let ystar: Vec<f64> = gradient(&inst.qp, &r.q, zstar).iter().map(|g| -g).collect();
        for m in methods(&inst.qp) {
            let (z1, y1) = m.one_step_from(&inst.theta, zstar, Some(&ystar));
            assert!(
                dist(&z1, zstar) <= tol,
                "seed {seed}: {} moved by {:e}",
                m.label(),
                dist(&z1, zstar)
            );
            if let Some(y1) = y1 {
                let ytol = 1e-9 * (1.0 + norm(&ystar)) + inst.qp.l() * r.err;
                assert!(
                    dist(&y1, &ystar) <= ytol,
                    "seed {seed}: {} dual moved by {:e}",
                    m.label(),
                    dist(&y1, &ystar)
                );
                // Without a dual, ADMM derives y* = −(Hz* + q) itself.
                let (z1, y1) = m.one_step_from(&inst.theta, zstar, None);
                assert!(
                    dist(&z1, zstar) <= tol && dist(&y1.unwrap(), &ystar) <= ytol,
                    "seed {seed}"
                );
            }
        }
    }
}

#[test]
fn load_then_restart_equals_a_fresh_state() {
    for seed in 53_000..53_040 {
        let inst = random_instance(seed, Gen::default());
        let theta_old: Vec<f64> = inst.theta.iter().map(|t| 3.0 - t).collect();
        for m in methods(&inst.qp) {
            for z0 in [None, Some(inst.z0.as_slice())] {
                let fresh = m.trajectory(false, &theta_old, &inst.theta, z0, 25);
                let reused = m.trajectory(true, &theta_old, &inst.theta, z0, 25);
                assert_eq!(
                    fresh,
                    reused,
                    "seed {seed}: {} (warm start: {})",
                    m.label(),
                    z0.is_some()
                );
            }
        }
    }
}

#[test]
fn cold_start_is_the_projection_of_zero() {
    let inst = random_instance(7, Gen::default());
    let mut p0 = vec![0.0; inst.qp.n()];
    inst.qp.project(&mut p0);
    // PG and FISTA start exactly at Π_Z(0).
    let pg = ProjectedGradient::new(inst.qp.clone(), StepRule::InverseL).unwrap();
    assert_eq!(pg.iterate(&pg.new_state()), p0.as_slice());
    let f = Fista::new(inst.qp.clone());
    assert_eq!(f.iterate(&f.new_state()), p0.as_slice());
    // ADMM: from Π_Z(0) with the gradient dual; its first iterate is Π_Z(Π_Z(0) − ∇f/ρ).
    let a = Admm::new(inst.qp.clone(), AdmmParams::default()).unwrap();
    let s = a.new_state();
    let g = gradient(&inst.qp, inst.qp.q0(), &p0);
    let mut expect: Vec<f64> = p0.iter().zip(&g).map(|(z, g)| z - g / a.rho()).collect();
    inst.qp.project(&mut expect);
    assert!(dist(a.iterate(&s), &expect) <= 1e-12 * (1.0 + norm(&expect)));
}

#[test]
fn returned_iterates_are_feasible_after_every_step() {
    for seed in 54_000..54_100 {
        let mut inst = random_instance(seed, Gen::default());
        // A start far outside the box.
        inst.z0.iter_mut().for_each(|z| *z *= 10.0);
        for m in methods(&inst.qp) {
            assert!(
                m.feasible_every_step(&inst.theta, &inst.z0, 100),
                "seed {seed}: {}",
                m.label()
            );
        }
    }
}

#[test]
fn certificate_formulas_match_closed_forms() {
    // Diagonal H with κ = 100: μ = 1, L = 100.
    let h = Mat::from_fn(
        3,
        3,
        |i, j| if i == j { [1.0, 10.0, 100.0][i] } else { 0.0 },
    );
    let qp = ParametricQp::new(
        h,
        vec![1.0; 3],
        Mat::zeros(3, 1),
        BoxSet::symmetric(&[1.0; 3]).unwrap(),
    )
    .unwrap();
    let sk: f64 = 10.0;
    let f = Fista::new(qp.clone());
    let c = f.certificate();
    assert!((c.rate - (1.0 - 1.0 / sk).sqrt()).abs() < 1e-12);
    assert!((c.prefactor - (100.0_f64 + sk).sqrt()).abs() < 1e-9);
    // φ(K) = √(κ−1)(1 − 1/√κ)^((K−1)/2).
    assert!((c.phi(11) - 99f64.sqrt() * 0.9f64.powi(5)).abs() < 1e-9);
    assert!((f.momentum() - 9.0 / 11.0).abs() < 1e-12 && (f.step_size() - 0.01).abs() < 1e-15);
    let a1 = Admm::new(qp.clone(), AdmmParams::default()).unwrap();
    assert!((a1.rho() - 10.0).abs() < 1e-9);
    assert!((a1.certificate().rate - 10.0 / 11.0).abs() < 1e-12); // (1 + δ)/2, δ = 9/11
    assert!((a1.certificate().prefactor - 9.0).abs() < 1e-9); // max(1 − μ/ρ, L/ρ − 1)
    let a2 = Admm::new(
        qp.clone(),
        AdmmParams {
            penalty: Penalty::Optimal,
            relaxation: 2.0,
        },
    )
    .unwrap();
    assert!((a2.certificate().rate - 9.0 / 11.0).abs() < 1e-12); // Giselsson–Boyd optimum
    assert_eq!(a2.splitting_certificate().prefactor, 1.0);
    for m in methods(&qp) {
        let c = m.cert();
        for eps in [1e-2, 1e-6, 1e-10] {
            let k = c.min_iterations(eps).unwrap();
            assert!(
                c.phi(k) <= eps && (k == 0 || c.phi(k - 1) > eps),
                "{}",
                m.label()
            );
        }
    }
}

#[test]
fn each_step_is_one_matrix_vector_product() {
    let inst = random_instance(3, Gen::default());
    assert_eq!(Fista::new(inst.qp.clone()).matvecs_per_step(), 1);
    assert_eq!(
        Admm::new(inst.qp.clone(), AdmmParams::default())
            .unwrap()
            .matvecs_per_step(),
        1
    );
}

#[test]
fn maps_are_send_sync_and_states_send() {
    fn send_sync<T: Send + Sync>() {}
    fn send<T: Send>() {}
    send_sync::<Fista>();
    send_sync::<Admm>();
    send::<qp_iter::fista::FistaState>();
    send::<qp_iter::admm::AdmmState>();
}
