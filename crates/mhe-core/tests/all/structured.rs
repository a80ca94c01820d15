//! The structured H_c z (`mhe_core::structured`, forward + adjoint pass) against the dense
//! H_c of every window, in each of its implementations (fixed-size with and without FMA,
//! zero-padded, run-time sizes) and Jacobi-scaled; projected gradient and FISTA through it
//! (plain and Jacobi-scaled) against the dense kernel.

use lti_model::{BoxSet, LtiSystem};
use mhe_core::structured::MheHessian;
use mhe_core::{MheProblem, MheSets, MheWindow};
use qp_iter::fista::Fista;
use qp_iter::kernel::Kernel;
use qp_iter::method::{Method, MethodMap, Scaling};
use qp_iter::operator::HessianOperator;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::{IterationMap, ParametricQp};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{Fixture, case_study, random_fixture, random_mat, random_spd};

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

/// A random plant of the given (n_x, n_y, n_w1, n_w2), random SPD weights (full Q).
fn sized_fixture(seed: u64, (nx, ny, nw1, nw2): (usize, usize, usize, usize), m: usize) -> Fixture {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let sys = LtiSystem::with_disturbance(
        random_mat(&mut rng, nx, nx, 0.9 / (nx as f64).sqrt()),
        random_mat(&mut rng, nx, 1, 1.0),
        random_mat(&mut rng, ny, nx, 1.0),
        random_mat(&mut rng, nx, nw1, 1.0),
        random_mat(&mut rng, ny, nw2, 1.0),
    )
    .unwrap();
    let sets = MheSets::with_disturbance(&sys, BoxSet::symmetric(&vec![0.2; nw1 + nw2]).unwrap());
    let mut f = random_fixture(seed, m, 1, false);
    f.config.p = random_spd(&mut rng, nx, 0.2);
    f.config.q = random_spd(&mut rng, nw1 + nw2, 0.2);
    f.config.r = random_spd(&mut rng, ny, 0.2);
    f.sys = sys;
    f.sets = sets;
    f
}

/// The window's operator in each implementation: as built (fixed-size on AVX2 + FMA when
/// detected, or padded, or run-time sizes), fixed-size without FMA, run-time sizes.
fn variants(f: &Fixture, w: &MheWindow) -> Vec<(&'static str, MheHessian)> {
    let op = MheHessian::new(
        w.layout(),
        f.sys.a(),
        f.sys.c(),
        f.sys.e(),
        f.sys.f(),
        f.config.eta,
        f.config.p.as_ref(),
        f.config.q.as_ref(),
        f.config.r.as_ref(),
    );
    vec![
        ("as built", op.clone()),
        ("portable", op.clone().with_kernel(Kernel::portable())),
        ("generic", op.generic()),
    ]
}

/// ‖H_c z − op(z)‖∞ ≤ 1e-12·‖H_c‖max·n·‖z‖∞ and the same for D H_c D y against the dense
/// product, on random z, every window, random plants of every size class.
#[test]
fn structured_product_equals_the_dense_hessian() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut fixtures: Vec<Fixture> = (0..40)
        .map(|s| random_fixture(900 + s, 1 + (s as usize % 12), 1, false))
        .collect();
    fixtures.push(case_study(30, 1, false));
    // Exact fixed sizes, each padded class, and run-time sizes (n_x > 16).
    for (k, shape) in [
        (4, 1, 4, 1),
        (4, 2, 4, 2),
        (2, 1, 2, 1),
        (3, 1, 2, 1),
        (6, 3, 5, 2),
        (12, 6, 6, 6),
        (16, 9, 16, 3),
        (17, 2, 3, 1),
    ]
    .into_iter()
    .enumerate()
    {
        fixtures.push(sized_fixture(70 + k as u64, shape, 6));
    }
    let (mut checked, mut specialised) = (0, 0);
    for f in &fixtures {
        for w in problem(f).windows() {
            let qp = w.qp();
            assert!(
                qp.operator().is_some(),
                "every MHE window carries its structured H_c"
            );
            let n = qp.n();
            let h = qp.h();
            let scale = h.norm_max() * n as f64;
            for (name, op) in variants(f, w) {
                specialised += usize::from(op.is_specialised());
                let mut work = vec![f64::NAN; op.work_len().max(op.scaled_work_len())];
                let mut out = vec![f64::NAN; n];
                for _ in 0..3 {
                    let z: Vec<f64> = (0..n).map(|_| 2.0 * rng.random::<f64>() - 1.0).collect();
                    let d: Vec<f64> = (0..n).map(|_| 0.1 + rng.random::<f64>()).collect();
                    op.apply(&z, &mut out, &mut work);
                    for i in 0..n {
                        let dense: f64 = (0..n).map(|j| h[(i, j)] * z[j]).sum();
                        assert!(
                            (dense - out[i]).abs() <= 1e-12 * scale,
                            "{name}, window {}: row {i}: dense {dense} vs structured {}",
                            w.layout().m,
                            out[i]
                        );
                    }
                    op.apply_scaled(&d, &z, &mut out, &mut work);
                    for i in 0..n {
                        let dense: f64 = (0..n).map(|j| d[i] * h[(i, j)] * d[j] * z[j]).sum();
                        assert!(
                            (dense - out[i]).abs() <= 1e-12 * scale,
                            "{name} scaled, window {}: row {i}: dense {dense} vs structured {}",
                            w.layout().m,
                            out[i]
                        );
                    }
                    checked += 1;
                }
            }
        }
    }
    assert!(
        checked > 3000 && specialised > 600,
        "{checked} {specialised}"
    );
}

/// n from which PG and FISTA take the problem's operator.
fn crossover(qp: &ParametricQp) -> usize {
    qp.operator().unwrap().dense_crossover()
}

/// The QP without its operator: the dense kernel only.
fn dense(qp: &ParametricQp) -> ParametricQp {
    ParametricQp::new(
        qp.h().to_owned(),
        qp.q0().to_vec(),
        qp.f().to_owned(),
        qp.zset().clone(),
    )
    .unwrap()
}

/// Runs `a` and `b` from the same random θ and warm start for `k` steps; the largest
/// ‖z_a − z_b‖∞ / max(1, ‖z_b‖∞) over the steps.
fn max_relative_gap<A: IterationMap, B: IterationMap>(
    a: &A,
    b: &B,
    rng: &mut ChaCha8Rng,
    k: usize,
) -> f64 {
    let qp = b.problem();
    let theta: Vec<f64> = (0..qp.n_theta())
        .map(|_| 3.0 * (2.0 * rng.random::<f64>() - 1.0))
        .collect();
    let z0: Vec<f64> = (0..qp.n())
        .map(|_| 0.1 * (2.0 * rng.random::<f64>() - 1.0))
        .collect();
    let (mut sa, mut sb) = (a.new_state(), b.new_state());
    a.load(&mut sa, &theta);
    a.warm_start(&mut sa, &z0, None);
    b.load(&mut sb, &theta);
    b.warm_start(&mut sb, &z0, None);
    let mut gap = 0.0_f64;
    for _ in 0..k {
        a.step(&mut sa);
        b.step(&mut sb);
        let (za, zb) = (a.iterate(&sa), b.iterate(&sb));
        let scale = zb.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        let d = za
            .iter()
            .zip(zb)
            .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
        gap = gap.max(d / scale);
    }
    gap
}

/// PG and FISTA through the operator give the dense kernel's iterates up to rounding:
/// 1e-12 relative over 100 steps, on random windows (forced structured below the
/// crossover) and on the stand-in at M = 12 and 50 (structured by the crossover).
#[test]
fn structured_projected_gradient_and_fista_match_the_dense_kernel() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut windows: Vec<ParametricQp> = (0..12)
        .map(|s| {
            let f = random_fixture(400 + s, 10 + 3 * s as usize, 1, false);
            problem(&f).windows().last().unwrap().qp().clone()
        })
        .collect();
    for m in [12, 50] {
        let stand_in = problem(&case_study(m, 1, false))
            .window(m)
            .unwrap()
            .qp()
            .clone();
        assert!(stand_in.n() >= crossover(&stand_in));
        windows.push(stand_in);
    }
    let mut worst = 0.0_f64;
    for qp in &windows {
        let d = dense(qp);
        let forced = qp.n() < crossover(qp);
        let pg = if forced {
            ProjectedGradient::new_structured(qp.clone(), StepRule::Optimal).unwrap()
        } else {
            ProjectedGradient::new(qp.clone(), StepRule::Optimal).unwrap()
        };
        let fista = if forced {
            Fista::new_structured(qp.clone())
        } else {
            Fista::new(qp.clone())
        };
        let (pg_d, fista_d) = (
            ProjectedGradient::new(d.clone(), StepRule::Optimal).unwrap(),
            Fista::new(d),
        );
        assert!(pg.is_structured() && fista.is_structured());
        assert!(!pg_d.is_structured() && !fista_d.is_structured());
        for (name, gap) in [
            ("pg", max_relative_gap(&pg, &pg_d, &mut rng, 100)),
            ("fista", max_relative_gap(&fista, &fista_d, &mut rng, 100)),
        ] {
            assert!(gap <= 1e-12, "{name}, n = {}: gap {gap:e}", qp.n());
            worst = worst.max(gap);
        }
    }
    // The comparison can fail: the two products round differently.
    assert!(worst > 0.0);
}

/// The Jacobi-scaled PG and FISTA (`Scaled` over `DiagonalScaled`, D folded into the
/// structured passes) against the same maps on the dense problem, M = 12, 40 and 50.
#[test]
fn jacobi_scaled_maps_run_structured_and_match_the_dense_kernel() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    for m in [12, 40, 50] {
        let qp = problem(&case_study(m, 1, false))
            .window(m)
            .unwrap()
            .qp()
            .clone();
        assert!(qp.n() >= crossover(&qp));
        for method in [Method::PG, Method::FISTA] {
            let method = method.with_scaling(Scaling::Jacobi);
            let (s, d) = (
                method.build(qp.clone()).unwrap(),
                method.build(dense(&qp)).unwrap(),
            );
            let structured = |map: &MethodMap| match map {
                MethodMap::Scaled(s) => match s.inner() {
                    MethodMap::Pg(pg) => pg.is_structured(),
                    MethodMap::Fista(f) => f.is_structured(),
                    _ => false,
                },
                _ => false,
            };
            assert!(structured(&s) && !structured(&d), "{method}, M = {m}");
            let gap = max_relative_gap(&s, &d, &mut rng, 100);
            assert!(gap <= 1e-12 && gap > 0.0, "{method}, M = {m}: gap {gap:e}");
        }
    }
}

/// Each shape gets the implementation, and so the crossover, the docs say: exact for
/// `SPECIALISED_SHAPES`, padded up to 16, run-time sizes beyond.
#[test]
fn shapes_get_their_implementation_and_crossover() {
    use mhe_core::structured::{
        EXACT_CROSSOVER, PADDED_CROSSOVER, RUN_TIME_CROSSOVER, SPECIALISED_SHAPES,
    };
    let cases = SPECIALISED_SHAPES
        .iter()
        .map(|&s| (s, EXACT_CROSSOVER))
        .chain([
            ((3, 1, 3, 1), PADDED_CROSSOVER),
            ((4, 1, 3, 1), PADDED_CROSSOVER),
            ((12, 6, 12, 6), PADDED_CROSSOVER),
            ((16, 16, 16, 16), PADDED_CROSSOVER),
            ((17, 2, 3, 1), RUN_TIME_CROSSOVER),
            ((4, 1, 17, 1), RUN_TIME_CROSSOVER),
        ]);
    for (k, (shape, crossover)) in cases.enumerate() {
        let f = sized_fixture(200 + k as u64, shape, 3);
        let prob = problem(&f);
        let w = prob.window(3).unwrap();
        let op = &variants(&f, w)[0].1;
        assert_eq!(op.dense_crossover(), crossover, "{shape:?}");
        assert_eq!(
            op.is_specialised(),
            crossover != RUN_TIME_CROSSOVER,
            "{shape:?}"
        );
        assert_eq!(
            w.qp().operator().unwrap().dense_crossover(),
            crossover,
            "{shape:?}"
        );
    }
}

/// The run-time-size product on the stand-in equals the fixed-size one to rounding (both
/// against each other, a second independent path).
#[test]
fn fixed_and_run_time_sizes_agree() {
    let f = case_study(20, 1, false);
    let prob = problem(&f);
    let w = prob.window(20).unwrap();
    let ops = variants(&f, w);
    assert!(ops[0].1.is_specialised() && !ops[2].1.is_specialised());
    let n = w.qp().n();
    let z: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    let mut outs = Vec::new();
    for (_, op) in &ops {
        let (mut out, mut work) = (vec![0.0; n], vec![0.0; op.work_len()]);
        op.apply(&z, &mut out, &mut work);
        outs.push(out);
    }
    let scale = outs[2].iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    for o in &outs[..2] {
        for (a, b) in o.iter().zip(&outs[2]) {
            assert!((a - b).abs() <= 1e-13 * scale, "{a} vs {b}");
        }
    }
}

/// `with_kernel(portable)` on a map reaches its structured product too: PG and FISTA (plain
/// and Jacobi-scaled) past the crossover, built under whatever global kernel this machine
/// detects and then set to the portable one, step for step equal (bit for bit) to the same
/// maps on a problem whose operator was built portable. Before the fix the structured
/// product kept the fused multiply–adds of the build-time kernel (on an AVX2 + FMA machine
/// the gap was ≈ 1e-16, not 0); on a machine without FMA both sides are portable anyway.
#[test]
fn with_kernel_portable_reaches_the_structured_product() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let m = 40;
    let f = case_study(m, 1, false);
    let prob = problem(&f);
    let w = prob.window(m).unwrap();
    let qp = w.qp().clone();
    assert!(qp.n() >= crossover(&qp));
    let portable_op = MheHessian::new(
        w.layout(),
        f.sys.a(),
        f.sys.c(),
        f.sys.e(),
        f.sys.f(),
        f.config.eta,
        f.config.p.as_ref(),
        f.config.q.as_ref(),
        f.config.r.as_ref(),
    )
    .with_kernel(Kernel::portable());
    let portable_qp = qp
        .clone()
        .with_operator(std::sync::Arc::new(portable_op))
        .unwrap();
    for method in [
        Method::PG,
        Method::FISTA,
        Method::PG.with_scaling(Scaling::Jacobi),
        Method::FISTA.with_scaling(Scaling::Jacobi),
    ] {
        let set = method
            .build(qp.clone())
            .unwrap()
            .with_kernel(Kernel::portable());
        let built = method
            .build(portable_qp.clone())
            .unwrap()
            .with_kernel(Kernel::portable());
        let gap = max_relative_gap(&set, &built, &mut rng, 60);
        assert!(gap == 0.0, "{method}: gap {gap:e}");
    }
}
