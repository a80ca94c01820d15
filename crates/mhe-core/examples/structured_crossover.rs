//! Per-iteration time of projected gradient and FISTA on the stand-in's MHE QP, dense kernel
//! against the structured H_c z (`mhe_core::structured`), for M = 2 … 50: the measured
//! crossover behind `qp_iter::operator::STRUCTURED_MIN_N`. The variants take turns batch by
//! batch (41 rounds, the first untimed), each figure is its fastest batch, so the ratios
//! are from the same conditions (a shared machine).
//! With `--detail` (M = 5 … 50): the product H_c z alone — the dense kernel, the
//! fixed-size blocks with AVX2 + FMA (as built) and without (portable), the run-time-size
//! passes (`MheHessian::generic`) — the Jacobi-scaled PG and FISTA dense against
//! structured, and PG on the run-time-size product. With `--shapes`: PG dense
//! against structured on random plants of other shapes (n_x, n_y, n_w1, n_w2): exact
//! fixed-size, zero-padded and run-time-size products.
//! Run: `cargo run --release -p mhe-core --example structured_crossover [-- --detail]`.

use std::hint::black_box;
use std::sync::Arc;
use std::time::Instant;

use faer::Mat;
use lti_model::BoxSet;
use mhe_core::structured::MheHessian;
use mhe_core::{MheProblem, MheSets, MheWeights, MheWindow};
use qp_iter::fista::Fista;
use qp_iter::kernel::{AlignedVec, Kernel, PaddedSymmetric};
use qp_iter::operator::HessianOperator;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::scaled::{Scaled, jacobi_scaling};
use qp_iter::{IterationMap, ParametricQp};

/// One timed variant: a name and a batch of `per_batch` operations.
type Variant<'a> = (&'a str, usize, Box<dyn FnMut() + 'a>);

/// Fastest batch per variant, in µs per operation, over `rounds` interleaved rounds.
fn interleave(variants: &mut [Variant<'_>], rounds: usize) -> Vec<f64> {
    let mut best = vec![f64::INFINITY; variants.len()];
    for round in 0..=rounds {
        for ((_, per, run), b) in variants.iter_mut().zip(&mut best) {
            let t = Instant::now();
            run();
            let us = t.elapsed().as_secs_f64() * 1e6 / *per as f64;
            if round > 0 {
                *b = b.min(us);
            }
        }
    }
    best
}

/// A batch of `k` steps of `map` from a fixed warm start.
fn steps<'a, M: IterationMap>(map: &'a M, theta: &[f64], k: usize) -> Box<dyn FnMut() + 'a> {
    let mut s = map.new_state();
    map.load(&mut s, theta);
    let z0 = vec![0.01; map.problem().n()];
    Box::new(move || {
        map.warm_start(&mut s, &z0, None);
        map.run_steps(&mut s, k);
        black_box(map.iterate(&s));
    })
}

/// A batch of `k` dense products H_c z (the kernel the dense steps run).
fn dense_products(qp: &ParametricQp, k: usize) -> Box<dyn FnMut() + '_> {
    let n = qp.n();
    let h = PaddedSymmetric::from_fn(n, |i, j| qp.h()[(i, j)]);
    let z = AlignedVec::padded(&(0..n).map(|i| (i as f64).sin()).collect::<Vec<_>>());
    let mut y = AlignedVec::zeros(h.ld());
    let kernel = Kernel::detect();
    Box::new(move || {
        for _ in 0..k {
            kernel.matvec_padded(&h, black_box(&z), &mut y);
        }
        black_box(&y);
    })
}

/// A batch of `k` products H_c z.
fn products<'a>(op: &'a dyn HessianOperator, k: usize) -> Box<dyn FnMut() + 'a> {
    let n = op.n();
    let z: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
    let (mut out, mut work) = (vec![0.0; n], vec![0.0; op.work_len()]);
    Box::new(move || {
        for _ in 0..k {
            op.apply(black_box(&z), &mut out, &mut work);
        }
        black_box(&out);
    })
}

/// PG dense against structured on a random plant of each shape, identity weights.
fn shapes() -> Result<(), Box<dyn std::error::Error>> {
    println!("shape (n_x, n_y, n_w1, n_w2)     M    n_z   PG dense   PG struct   ratio  (µs/step)");
    for shape in [
        (2, 1, 2, 1),
        (4, 2, 4, 2),
        (3, 1, 3, 1),
        (6, 3, 6, 3),
        (12, 6, 6, 6),
        (12, 6, 12, 6),
        (17, 2, 17, 2),
    ] {
        let (nx, ny, nw1, nw2) = shape;
        let m_of = |k: usize, s: usize| {
            Mat::from_fn(k, s, |i, j| ((i * 7 + j * 3) % 5) as f64 * 0.1 - 0.2)
        };
        let a = Mat::from_fn(nx, nx, |i, j| {
            if i == j {
                0.9
            } else {
                0.3 / nx as f64 * ((i + 2 * j) % 3) as f64
            }
        });
        let sys = lti_model::LtiSystem::with_disturbance(
            a,
            m_of(nx, 1),
            Mat::from_fn(ny, nx, |i, j| if i == j % ny { 1.0 } else { 0.1 }),
            Mat::from_fn(nx, nw1, |i, j| if i == j { 1.0 } else { 0.0 }),
            Mat::identity(ny, nw2),
        )?;
        let sets = MheSets::with_disturbance(&sys, BoxSet::symmetric(&vec![0.1; nw1 + nw2])?);
        let weights = MheWeights {
            eta: 0.8,
            p: Mat::identity(nx, nx),
            q: Mat::identity(nw1 + nw2, nw1 + nw2),
            r: Mat::identity(ny, ny),
        };
        for m in [5, 9, 10, 20, 40] {
            let prob = MheProblem::new(&sys, m, &weights, &sets)?;
            let qp = prob.window(m).ok_or("window")?.qp().clone();
            let dense_qp = ParametricQp::new(
                qp.h().to_owned(),
                qp.q0().to_vec(),
                qp.f().to_owned(),
                qp.zset().clone(),
            )?;
            let theta = vec![0.5; qp.n_theta()];
            let (d, s) = (
                ProjectedGradient::new(dense_qp, StepRule::Optimal)?,
                ProjectedGradient::new_structured(qp.clone(), StepRule::Optimal)?,
            );
            let k = (20_000 / qp.n()).max(10);
            let mut v: Vec<Variant<'_>> = vec![
                ("pg dense", k, steps(&d, &theta, k)),
                ("pg structured", k, steps(&s, &theta, k)),
            ];
            let t = interleave(&mut v, 40);
            println!(
                "{:<30} {m:>5} {:>6} {:>10.3} {:>11.3} {:>7.2}",
                format!("{shape:?}"),
                qp.n(),
                t[0],
                t[1],
                t[1] / t[0]
            );
        }
    }
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    if std::env::args().any(|a| a == "--shapes") {
        return shapes();
    }
    let detail = std::env::args().any(|a| a == "--detail");
    let sys = lti_model::presets::case_study_plant();
    let q = Mat::<f64>::identity(5, 5);
    let r = Mat::<f64>::identity(1, 1);
    let cert = lti_model::ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref())?;
    let sets = MheSets::with_disturbance(&sys, BoxSet::symmetric(&[0.1; 5])?);
    let weights = MheWeights {
        eta: 0.8,
        p: cert.p,
        q,
        r,
    };
    if detail {
        println!(
            "    M    n_z | H_c z: dense  fixed  portable  generic | PG-J: dense  struct | FISTA-J: dense  struct | PG generic  (µs)"
        );
    } else {
        println!(
            "    M    n_z   PG dense   PG struct   ratio   FISTA dense   FISTA struct   ratio  (µs/step)"
        );
    }
    let grid: &[usize] = if detail {
        &[5, 10, 20, 30, 50]
    } else {
        &[2, 5, 8, 10, 11, 12, 13, 14, 15, 20, 25, 30, 40, 50]
    };
    for &m in grid {
        let prob = MheProblem::new(&sys, m, &weights, &sets)?;
        let w = prob.window(m).ok_or("window")?;
        let qp = w.qp().clone();
        let dense_qp = ParametricQp::new(
            qp.h().to_owned(),
            qp.q0().to_vec(),
            qp.f().to_owned(),
            qp.zset().clone(),
        )?;
        let theta = vec![0.5; qp.n_theta()];
        let k = (20_000 / qp.n()).max(10);
        if detail {
            detail_row(m, &sys, w, &weights, &qp, dense_qp, &theta, k)?;
        } else {
            summary_row(m, &qp, dense_qp, &theta, k)?;
        }
    }
    Ok(())
}

/// One row of the default table: PG and FISTA, dense against structured.
fn summary_row(
    m: usize,
    qp: &ParametricQp,
    dense_qp: ParametricQp,
    theta: &[f64],
    k: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    // Force the structured path whatever the crossover says.
    let (pg_d, pg_s) = (
        ProjectedGradient::new(dense_qp.clone(), StepRule::Optimal)?,
        ProjectedGradient::new_structured(qp.clone(), StepRule::Optimal)?,
    );
    let (fi_d, fi_s) = (Fista::new(dense_qp), Fista::new_structured(qp.clone()));
    let mut v: Vec<Variant<'_>> = vec![
        ("pg dense", k, steps(&pg_d, theta, k)),
        ("pg structured", k, steps(&pg_s, theta, k)),
        ("fista dense", k, steps(&fi_d, theta, k)),
        ("fista structured", k, steps(&fi_s, theta, k)),
    ];
    let t = interleave(&mut v, 40);
    println!(
        "{m:>5} {:>6} {:>10.3} {:>11.3} {:>7.2} {:>13.3} {:>14.3} {:>7.2}",
        qp.n(),
        t[0],
        t[1],
        t[1] / t[0],
        t[2],
        t[3],
        t[3] / t[2]
    );
    Ok(())
}

/// One row of `--detail`: the H_c z kernels and the Jacobi-scaled maps.
#[allow(clippy::too_many_arguments)]
fn detail_row(
    m: usize,
    sys: &lti_model::LtiSystem,
    w: &MheWindow,
    weights: &MheWeights,
    qp: &ParametricQp,
    dense_qp: ParametricQp,
    theta: &[f64],
    k: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    let op = MheHessian::new(
        w.layout(),
        sys.a(),
        sys.c(),
        sys.e(),
        sys.f(),
        weights.eta,
        weights.p.as_ref(),
        weights.q.as_ref(),
        weights.r.as_ref(),
    );
    let (portable, generic) = (
        op.clone().with_kernel(Kernel::portable()),
        op.clone().generic(),
    );
    let generic_qp = qp.clone().with_operator(Arc::new(generic.clone()))?;
    let pg_g = ProjectedGradient::new_structured(generic_qp, StepRule::Optimal)?;
    // Jacobi-scaled PG and FISTA (what `pg-jacobi`, `fista-jacobi` build), dense
    // problem against the problem with its operator, structured path forced.
    let d = jacobi_scaling(qp);
    let pg = |q: ParametricQp, s: bool| {
        if s {
            ProjectedGradient::new_structured(q, StepRule::Optimal)
        } else {
            ProjectedGradient::new(q, StepRule::Optimal)
        }
    };
    let fi = |q: ParametricQp, s: bool| {
        Ok(if s {
            Fista::new_structured(q)
        } else {
            Fista::new(q)
        })
    };
    let (pgj_d, pgj_s) = (
        Scaled::new(dense_qp.clone(), d.clone(), |q| pg(q, false))?,
        Scaled::new(qp.clone(), d.clone(), |q| pg(q, true))?,
    );
    let (fij_d, fij_s) = (
        Scaled::new(dense_qp, d.clone(), |q| fi(q, false))?,
        Scaled::new(qp.clone(), d, |q| fi(q, true))?,
    );
    let mut v: Vec<Variant<'_>> = vec![
        ("H_c z dense", k, dense_products(qp, k)),
        ("H_c z fixed", k, products(&op, k)),
        ("H_c z portable", k, products(&portable, k)),
        ("H_c z generic", k, products(&generic, k)),
        ("pg-jacobi dense", k, steps(&pgj_d, theta, k)),
        ("pg-jacobi structured", k, steps(&pgj_s, theta, k)),
        ("fista-jacobi dense", k, steps(&fij_d, theta, k)),
        ("fista-jacobi structured", k, steps(&fij_s, theta, k)),
        ("pg generic", k, steps(&pg_g, theta, k)),
    ];
    let t = interleave(&mut v, 40);
    println!(
        "{m:>5} {:>6} | {:>11.3} {:>6.3} {:>9.3} {:>8.3} | {:>10.3} {:>7.3} | {:>13.3} {:>7.3} | {:>10.3}",
        qp.n(),
        t[0],
        t[1],
        t[2],
        t[3],
        t[4],
        t[5],
        t[6],
        t[7],
        t[8]
    );
    Ok(())
}
