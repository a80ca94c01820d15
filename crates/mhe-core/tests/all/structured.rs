//! The structured H_c z (`mhe_core::structured`, forward + adjoint pass) against the dense
//! H_c of every window, and projected gradient through it against the dense kernel.

use mhe_core::MheProblem;
use qp_iter::operator::HessianOperator;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{IterationMap, ParametricQp};
use rand::{Rng, SeedableRng};

use crate::common::{Fixture, case_study, random_fixture};

fn problem(f: &Fixture) -> MheProblem {
    MheProblem::new(
        &f.sys,
        f.config.horizon,
        &mhe_core::MheWeights {
            eta: f.config.eta,
            p: f.config.p.clone(),
            q: f.config.q.clone(),
            r: f.config.r.clone(),
        },
        &f.sets,
    )
    .unwrap()
}

/// ‖H_c z − op(z)‖∞ ≤ 1e-12·‖H_c‖·‖z‖∞ on random z, every window, random plants.
#[test]
fn structured_product_equals_the_dense_hessian() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut fixtures: Vec<Fixture> = (0..40)
        .map(|s| random_fixture(900 + s, 1 + (s as usize % 12), 1, false))
        .collect();
    fixtures.push(case_study(30, 1, false));
    let mut checked = 0;
    for f in &fixtures {
        for w in problem(f).windows() {
            let qp = w.qp();
            let op = qp
                .operator()
                .expect("every MHE window carries its structured H_c");
            let n = qp.n();
            let mut work = vec![f64::NAN; op.work_len()];
            let mut out = vec![f64::NAN; n];
            for _ in 0..5 {
                let z: Vec<f64> = (0..n).map(|_| 2.0 * rng.random::<f64>() - 1.0).collect();
                op.apply(&z, &mut out, &mut work);
                let h = qp.h();
                let scale = h.norm_max() * n as f64;
                for i in 0..n {
                    let dense: f64 = (0..n).map(|j| h[(i, j)] * z[j]).sum();
                    assert!(
                        (dense - out[i]).abs() <= 1e-12 * scale,
                        "window {}: row {i}: dense {dense} vs structured {}",
                        w.layout().m,
                        out[i]
                    );
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 1000, "{checked}");
}

/// PG through the operator gives the dense kernel's iterates up to rounding (n ≥ the
/// crossover, so the structured path is taken).
#[test]
fn structured_projected_gradient_matches_the_dense_kernel() {
    let f = case_study(40, 1, false);
    let prob = problem(&f);
    let w = prob.window(40).unwrap();
    let qp = w.qp().clone();
    assert!(qp.n() >= qp_iter::operator::STRUCTURED_MIN_N);
    let dense_qp = ParametricQp::new(
        qp.h().to_owned(),
        qp.q0().to_vec(),
        qp.f().to_owned(),
        qp.zset().clone(),
    )
    .unwrap();
    let structured = ProjectedGradient::new(qp.clone(), StepRule::Optimal).unwrap();
    let dense = ProjectedGradient::new(dense_qp, StepRule::Optimal).unwrap();
    assert!(structured.is_structured() && !dense.is_structured());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let theta: Vec<f64> = (0..qp.n_theta())
        .map(|_| 3.0 * (2.0 * rng.random::<f64>() - 1.0))
        .collect();
    let z0: Vec<f64> = (0..qp.n())
        .map(|_| 0.1 * (2.0 * rng.random::<f64>() - 1.0))
        .collect();
    let (mut a, mut b) = (structured.new_state(), dense.new_state());
    for (m, s) in [(&structured, &mut a), (&dense, &mut b)] {
        m.load(s, &theta);
        m.warm_start(s, &z0, None);
    }
    for k in 0..200 {
        structured.step(&mut a);
        dense.step(&mut b);
        let (za, zb) = (structured.iterate(&a), dense.iterate(&b));
        let scale = zb.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        for i in 0..za.len() {
            assert!(
                (za[i] - zb[i]).abs() <= 1e-9 * scale,
                "step {k}, z[{i}]: {} vs {}",
                za[i],
                zb[i]
            );
        }
    }
}
