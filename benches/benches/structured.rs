//! The structured iteration of issue 12 on the stand-in's MHE QP (η = 0.8, P from LMI (2),
//! Q = I₅, R = 1: the certified preset's weights) for M = 5, 10, 20, 30, 50: one step of
//! PG and FISTA, plain and Jacobi-scaled, on the dense kernel and through the structured
//! H_c z (`mhe_core::structured::MheHessian`), and the products alone.
//!
//! Groups (criterion ids `structured/M<M>/<row>`):
//! - `product_dense`: `Kernel::matvec_padded` (what the dense steps run);
//!   `product_structured`: `MheHessian::apply` as built (fixed-size blocks, AVX2 + FMA when
//!   detected); `product_portable`: the same blocks without FMA; `product_generic`: the
//!   run-time-size passes (`MheHessian::generic`).
//! - `<method>_dense`, `<method>_structured` for `pg`, `fista`, `pg_jacobi`,
//!   `fista_jacobi`: per step of `run_steps` (a scaled map maps y back to z once per run),
//!   the dense problem (no operator) against the same problem with its operator, the
//!   structured path forced at every M (`Method::build` takes it from n ≥
//!   `STRUCTURED_MIN_N` = 200 on its own, i.e. M ≥ 40 here).
//!
//! Run: `cargo bench -p benches --bench structured` (≈ 2 min).

use std::hint::black_box;
use std::sync::Arc;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use faer::Mat;
use lti_model::BoxSet;
use mhe_core::structured::MheHessian;
use mhe_core::{MheProblem, MheSets, MheWeights};
use qp_iter::fista::Fista;
use qp_iter::kernel::{AlignedVec, Kernel, PaddedSymmetric};
use qp_iter::operator::HessianOperator;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::scaled::{Scaled, jacobi_scaling};
use qp_iter::{IterationMap, ParametricQp};

const HORIZONS: [usize; 5] = [5, 10, 20, 30, 50];

/// The stand-in's full window M: its QP (with operator), the same QP without, the
/// operator.
fn window(m: usize) -> (ParametricQp, ParametricQp, MheHessian) {
    let sys = lti_model::presets::case_study_plant();
    let (q, r) = (Mat::<f64>::identity(5, 5), Mat::<f64>::identity(1, 1));
    let cert = lti_model::ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref())
        .unwrap_or_else(|e| panic!("LMI (2): {e}"));
    let sets = MheSets::with_disturbance(
        &sys,
        BoxSet::symmetric(&[0.1; 5]).unwrap_or_else(|e| panic!("box: {e}")),
    );
    let weights = MheWeights {
        eta: 0.8,
        p: cert.p,
        q,
        r,
    };
    let prob =
        MheProblem::new(&sys, m, &weights, &sets).unwrap_or_else(|e| panic!("MHE M = {m}: {e}"));
    let w = prob.window(m).unwrap_or_else(|| panic!("no window {m}"));
    let qp = w.qp().clone();
    let dense = ParametricQp::new(
        qp.h().to_owned(),
        qp.q0().to_vec(),
        qp.f().to_owned(),
        qp.zset().clone(),
    )
    .unwrap_or_else(|e| panic!("dense QP: {e}"));
    let op = MheHessian::new(
        w.layout(),
        sys.a(),
        sys.c(),
        sys.e(),
        sys.f(),
        0.8,
        weights.p.as_ref(),
        weights.q.as_ref(),
        weights.r.as_ref(),
    );
    (qp, dense, op)
}

/// Per step of `run_steps` batches of `map` (θ loaded and warm-started once per batch).
fn per_step<M: IterationMap>(map: &M, theta: &[f64]) -> impl FnMut(u64) -> Duration {
    let mut s = map.new_state();
    map.load(&mut s, theta);
    let z0 = vec![0.01; map.problem().n()];
    move |iters| {
        map.warm_start(&mut s, &z0, None);
        let t = Instant::now();
        map.run_steps(&mut s, iters as usize);
        black_box(map.iterate(&s));
        t.elapsed()
    }
}

fn structured(c: &mut Criterion) {
    for m in HORIZONS {
        let (qp, dense, op) = window(m);
        let n = qp.n();
        let theta = vec![0.5; qp.n_theta()];
        let mut g = c.benchmark_group(format!("structured/M{m}"));

        // The products alone.
        let z: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let h = PaddedSymmetric::from_fn(n, |i, j| qp.h()[(i, j)]);
        let zp = AlignedVec::padded(&z);
        let mut y = AlignedVec::zeros(h.ld());
        let kernel = Kernel::detect();
        g.bench_function(BenchmarkId::new("product_dense", n), |b| {
            b.iter(|| kernel.matvec_padded(&h, black_box(&zp), &mut y))
        });
        for (name, op) in [
            ("product_structured", op.clone()),
            (
                "product_portable",
                op.clone().with_kernel(Kernel::portable()),
            ),
            ("product_generic", op.clone().generic()),
        ] {
            let (mut out, mut work) = (vec![0.0; n], vec![0.0; op.work_len()]);
            g.bench_function(BenchmarkId::new(name, n), |b| {
                b.iter(|| op.apply(black_box(&z), &mut out, &mut work))
            });
        }

        // One step, dense against structured (forced at every M).
        let forced = qp
            .clone()
            .with_operator(Arc::new(op.clone()))
            .unwrap_or_else(|e| panic!("operator: {e}"));
        let pg = |qp: ParametricQp, s: bool| {
            if s {
                ProjectedGradient::new_structured(qp, StepRule::Optimal)
            } else {
                ProjectedGradient::new(qp, StepRule::Optimal)
            }
            .unwrap_or_else(|e| panic!("pg: {e}"))
        };
        let fista = |qp: ParametricQp, s: bool| {
            if s {
                Fista::new_structured(qp)
            } else {
                Fista::new(qp)
            }
        };
        let d = jacobi_scaling(&qp);
        for (label, q, s) in [("dense", &dense, false), ("structured", &forced, true)] {
            let map = pg(q.clone(), s);
            g.bench_function(BenchmarkId::new(format!("pg_{label}"), n), |b| {
                b.iter_custom(per_step(&map, &theta))
            });
            let map = fista(q.clone(), s);
            g.bench_function(BenchmarkId::new(format!("fista_{label}"), n), |b| {
                b.iter_custom(per_step(&map, &theta))
            });
            let map = Scaled::new(q.clone(), d.clone(), |q| Ok(pg(q, s)))
                .unwrap_or_else(|e| panic!("scaled: {e}"));
            g.bench_function(BenchmarkId::new(format!("pg_jacobi_{label}"), n), |b| {
                b.iter_custom(per_step(&map, &theta))
            });
            let map = Scaled::new(q.clone(), d.clone(), |q| Ok(fista(q, s)))
                .unwrap_or_else(|e| panic!("scaled: {e}"));
            g.bench_function(BenchmarkId::new(format!("fista_jacobi_{label}"), n), |b| {
                b.iter_custom(per_step(&map, &theta))
            });
        }
        g.finish();
    }
}

fn config() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_millis(200))
        .measurement_time(Duration::from_millis(600))
        .sample_size(20)
        .without_plots()
}

criterion_group! {
    name = benches;
    config = config();
    targets = structured
}
criterion_main!(benches);
