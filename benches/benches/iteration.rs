//! Per-iteration cost of the iteration maps Φ, their time to a fixed accuracy, Clarabel's
//! full solve, and the fixed-size reference kernel — all in one run, so ratios between
//! them are meaningful on a shared machine.
//!
//! Groups (criterion ids `group/function[/parameter]`):
//! - `n30`: one step of PG, FISTA, ADMM at n = 30; the reference kernels `ref_*`
//!   (compile-time 30 × 30, AVX2 + FMA by run-time detection); our product
//!   `Kernel::matvec_padded` and its portable path; faer `matmul` (Par::Seq,
//!   preallocated); the padded FISTA and ADMM kernels (`Kernel::*_padded`) the steps run.
//!   Before these, [`interleaved_n30`] times the steps (also ADMM with α = 2) and the
//!   padded kernels round by round.
//! - `grid`: one step of each method and one `matvec_padded` for n = 10 … 400.
//! - `accuracy`: load θ + cold start + K steps, K the smallest count with
//!   ‖z − z*‖ ≤ 1e-6‖z⁰ − z*‖ (z* from the polished Clarabel reference), and Clarabel's
//!   full interior-point solve for the same θ, for n = 10 … 400 and 30.
//!
//! The iteration counts K and the kernel paths are written to
//! `target/criterion/iteration-meta.json` for `bench-table` (docs/benchmarks.md).
//!
//! Run: `cargo bench -p benches --bench iteration`.

use std::collections::BTreeMap;
use std::hint::black_box;
use std::time::Duration;

use benches::{FixedLayout, FixedMatVec, Instance, dist, random_instance};
use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, BenchmarkId, Criterion, criterion_group, criterion_main};
use faer::linalg::matmul::matmul;
use faer::{Accum, Col, Mat, Par};
use qp_iter::admm::{Admm, AdmmParams};
use qp_iter::fista::Fista;
use qp_iter::kernel::{AlignedVec, Kernel, PaddedSymmetric};
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};
use qp_iter::{IterationMap, RunStatus, run_fixed, run_until};

const SEED: u64 = 2024;
const GRID: [usize; 6] = [10, 20, 50, 100, 200, 400];
/// Relative accuracy of the time-to-accuracy benchmark: ‖z − z*‖ ≤ ε‖z⁰ − z*‖.
const EPS: f64 = 1e-6;

fn instance(n: usize) -> Instance {
    random_instance(n, SEED + n as u64)
}

fn methods(inst: &Instance) -> (ProjectedGradient, Fista, Admm) {
    let pg = ProjectedGradient::new(inst.qp.clone(), StepRule::Optimal)
        .unwrap_or_else(|e| panic!("pg: {e}"));
    let fista = Fista::new(inst.qp.clone());
    let admm =
        Admm::new(inst.qp.clone(), AdmmParams::default()).unwrap_or_else(|e| panic!("admm: {e}"));
    (pg, fista, admm)
}

/// One step of `map`, with θ loaded and a cold start once; later steps continue from
/// wherever the iteration is (a step's cost does not depend on the iterate).
fn bench_step<M: IterationMap>(
    g: &mut BenchmarkGroup<'_, WallTime>,
    id: BenchmarkId,
    map: &M,
    theta: &[f64],
) {
    let mut s = map.new_state();
    map.load(&mut s, theta);
    map.cold_start(&mut s);
    g.bench_function(id, |b| b.iter(|| map.step(black_box(&mut s))));
}

fn x_vec(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| ((i * 7919) % 13) as f64 / 13.0 - 0.5)
        .collect()
}

/// Unix time when the first benchmark group of this run started (stale results from
/// earlier runs are older and `bench_table` leaves them out).
fn run_started() -> u64 {
    static START: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *START.get_or_init(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs())
    })
}

/// Interleaved timing at n = 30, outside criterion: every round times one batch of each
/// variant in turn, and a variant's figure is its fastest batch. Criterion measures one
/// benchmark after the other for seconds each, so on a shared VM a drift of the host's
/// speed between two benchmarks enters their ratio; here every variant sees the same
/// conditions within each round, so the *ratios* are the robust figures.
fn interleaved_n30(_c: &mut Criterion) {
    run_started();
    const N: usize = 30;
    const ROUNDS: usize = 300;
    const BATCH: usize = 2000;
    let inst = instance(N);
    let h = inst.qp.h_row_major().to_vec();
    let xs = x_vec(N);
    let x: [f64; N] = std::array::from_fn(|i| xs[i]);
    let Some(fixed) = FixedMatVec::<N>::new(&h, FixedLayout::ColumnAxpy) else {
        panic!("30×30 H")
    };
    let (pg, fista, admm) = methods(&inst);
    let k = Kernel::detect();
    let (lo, hi) = (
        inst.qp.zset().lower().to_vec(),
        inst.qp.zset().upper().to_vec(),
    );
    let mut q = vec![0.0; N];
    inst.qp.linear_term(&inst.theta, &mut q);
    let (rho, relax) = (admm.rho(), admm.relaxation());
    let m_rho = admm_map(&inst, rho);
    let (alpha, beta) = (fista.step_size(), fista.momentum());
    let (hp, mp) = (
        PaddedSymmetric::from_row_major(&h, N).unwrap_or_else(|| panic!("30×30 H")),
        PaddedSymmetric::from_row_major(&m_rho, N).unwrap_or_else(|| panic!("30×30 M")),
    );
    let ld = hp.ld();
    // m_q = (H + ρI)⁻¹q = ρ(H + ρI)⁻¹q / ρ.
    let mut mqa = AlignedVec::zeros(ld);
    k.matvec_padded(&mp, &q, &mut mqa);
    mqa.iter_mut().for_each(|v| *v /= rho);

    let mut variants: Vec<(&'static str, Batch)> = Vec::new();
    {
        let mut y = [0.0; N];
        variants.push((
            "ref_column_axpy",
            Box::new(move || {
                for _ in 0..BATCH {
                    fixed.apply(black_box(&x), &mut y);
                    black_box(&mut y);
                }
            }),
        ));
    }
    {
        let (hp, xs, mut y) = (hp.clone(), AlignedVec::padded(&xs), AlignedVec::zeros(ld));
        variants.push((
            "matvec_padded",
            Box::new(move || {
                for _ in 0..BATCH {
                    k.matvec_padded(&hp, black_box(&xs), &mut y);
                    black_box(&mut y);
                }
            }),
        ));
    }
    fn stepper<M: IterationMap + 'static>(map: M, theta: &[f64]) -> Batch {
        let mut s = map.new_state();
        map.load(&mut s, theta);
        map.cold_start(&mut s);
        Box::new(move || {
            for _ in 0..BATCH {
                map.step(black_box(&mut s));
            }
        })
    }
    // The same steps on copies of the maps and states placed elsewhere in memory: the
    // fused steps' time depends on where H and the state vectors sit relative to each
    // other (4K aliasing between the epilogue's stores and later loads), so the table
    // reports the spread over these placements next to the first one.
    let mut pads = Vec::new();
    for (p, names) in PLACEMENTS.iter().enumerate() {
        pads.push(vec![0u8; 1000 * (p + 1) + 328]);
        variants.push((names[0], stepper(pg.clone(), &inst.theta)));
        pads.push(vec![0u8; 520 * (p + 1)]);
        variants.push((names[1], stepper(fista.clone(), &inst.theta)));
        pads.push(vec![0u8; 1700 * (p + 1)]);
        variants.push((names[2], stepper(admm.clone(), &inst.theta)));
    }
    let admm_pr = Admm::new(
        inst.qp.clone(),
        AdmmParams {
            relaxation: 2.0,
            ..AdmmParams::default()
        },
    )
    .unwrap_or_else(|e| panic!("admm α = 2: {e}"));
    variants.push(("step/pg", stepper(pg, &inst.theta)));
    variants.push(("step/fista", stepper(fista, &inst.theta)));
    variants.push(("step/admm", stepper(admm, &inst.theta)));
    variants.push(("step/admm_pr", stepper(admm_pr, &inst.theta)));

    // The kernels the steps run (padded layout, 64-byte aligned, separately allocated
    // vectors, updated in place).
    let alpha_pg = 2.0 / (inst.qp.l() + inst.qp.mu());
    let (qa, loa, hia) = (
        AlignedVec::padded(&q),
        AlignedVec::padded(&lo),
        AlignedVec::padded(&hi),
    );
    {
        let (hp, q, lo, hi) = (hp.clone(), qa.clone(), loa.clone(), hia.clone());
        let (mut z, mut scratch) = (AlignedVec::zeros(ld), AlignedVec::zeros(ld));
        variants.push((
            "fused_kernel/pg",
            Box::new(move || {
                for _ in 0..BATCH {
                    k.pg_step_padded(&hp, &mut z, &q, alpha_pg, &lo, &hi, &mut scratch);
                }
            }),
        ));
    }
    {
        let (hp, q, lo, hi) = (hp.clone(), qa.clone(), loa.clone(), hia.clone());
        let [mut y, mut z, mut scratch] = [(); 3].map(|_| AlignedVec::zeros(ld));
        variants.push((
            "fused_kernel/fista",
            Box::new(move || {
                for _ in 0..BATCH {
                    k.fista_step_padded(
                        &hp,
                        &mut y,
                        &q,
                        alpha,
                        &lo,
                        &hi,
                        beta,
                        &mut z,
                        &mut scratch,
                    );
                }
            }),
        ));
    }
    {
        let (mp, mq, lo, hi) = (mp.clone(), mqa.clone(), loa.clone(), hia.clone());
        let [mut t, mut z, mut dr, mut scratch] = [(); 4].map(|_| AlignedVec::zeros(ld));
        variants.push((
            "fused_kernel/admm",
            Box::new(move || {
                for _ in 0..BATCH {
                    k.admm_dr_step_padded(
                        &mp,
                        &mut t,
                        &mq,
                        relax,
                        &lo,
                        &hi,
                        &mut z,
                        &mut dr,
                        &mut scratch,
                    );
                }
            }),
        ));
    }
    let mut times = vec![Vec::with_capacity(ROUNDS); variants.len()];
    std::hint::black_box(&pads);
    for _ in 0..ROUNDS {
        for ((_, f), t) in variants.iter_mut().zip(&mut times) {
            let start = std::time::Instant::now();
            f();
            t.push(start.elapsed().as_nanos() as f64 / BATCH as f64);
        }
    }
    let mut out = serde_json::Map::new();
    for ((name, _), t) in variants.iter().zip(&mut times) {
        t.sort_by(f64::total_cmp);
        let (min, median) = (t[0], t[t.len() / 2]);
        eprintln!("interleaved n30 {name}: min {min:.1} ns, median {median:.1} ns");
        out.insert(
            (*name).into(),
            serde_json::json!({ "min_ns": min, "median_ns": median }),
        );
    }
    let _ = INTERLEAVED.set(serde_json::Value::Object(out));
}

/// Names of the extra placements of the PG, FISTA and ADMM steps in [`interleaved_n30`].
const PLACEMENTS: [[&str; 3]; 3] = [
    ["step/pg@1", "step/fista@1", "step/admm@1"],
    ["step/pg@2", "step/fista@2", "step/admm@2"],
    ["step/pg@3", "step/fista@3", "step/admm@3"],
];

/// One timed batch of a variant in [`interleaved_n30`].
type Batch = Box<dyn FnMut()>;

/// Results of [`interleaved_n30`], written into the meta file at the end of the run.
static INTERLEAVED: std::sync::OnceLock<serde_json::Value> = std::sync::OnceLock::new();

fn per_iteration_n30(c: &mut Criterion) {
    run_started();
    const N: usize = 30;
    let inst = instance(N);
    let h = inst.qp.h_row_major();
    let mut g = c.benchmark_group("n30");
    // Many short samples: on a shared machine most of them fall inside one time slice.
    g.sample_size(200)
        .measurement_time(Duration::from_millis(2000));

    // Reference kernels: compile-time N, AVX2+FMA through run-time detection.
    let xs = x_vec(N);
    let x: [f64; N] = std::array::from_fn(|i| xs[i]);
    for (name, layout) in [
        ("ref_column_axpy", FixedLayout::ColumnAxpy),
        ("ref_row_dot", FixedLayout::RowDot),
    ] {
        let Some(k) = FixedMatVec::<N>::new(h, layout) else {
            panic!("30×30 H")
        };
        let mut y = [0.0; N];
        g.bench_function(name, |b| {
            b.iter(|| {
                k.apply(black_box(&x), &mut y);
                black_box(&mut y);
            })
        });
    }

    // The same product chained, x ← (H/L)x: each call needs the previous result, as in an
    // iteration, so call latency instead of throughput (H/L keeps ‖x‖ bounded away from 0
    // and ∞: power iteration with λ_max = 1).
    let h_scaled: Vec<f64> = h.iter().map(|v| v / inst.qp.l()).collect();
    {
        let Some(k) = FixedMatVec::<N>::new(&h_scaled, FixedLayout::ColumnAxpy) else {
            panic!("30×30 H")
        };
        let (mut xa, mut xb) = (x, [0.0; N]);
        g.bench_function("ref_column_axpy_chained", |b| {
            b.iter(|| {
                k.apply(&xa, &mut xb);
                std::mem::swap(&mut xa, &mut xb);
            })
        });
        let hs = PaddedSymmetric::from_row_major(&h_scaled, N).unwrap_or_else(|| panic!("30×30 H"));
        let (mut xa, mut xb) = (AlignedVec::padded(&xs), AlignedVec::zeros(hs.ld()));
        let k = Kernel::detect();
        g.bench_function("matvec_padded_chained", |b| {
            b.iter(|| {
                k.matvec_padded(&hs, &xa, &mut xb);
                std::mem::swap(&mut xa, &mut xb);
            })
        });
    }

    // Our product (run-time dispatch) and its portable path, same call pattern.
    let hp = PaddedSymmetric::from_row_major(h, N).unwrap_or_else(|| panic!("30×30 H"));
    let ld = hp.ld();
    let (xp, mut ys) = (AlignedVec::padded(&xs), AlignedVec::zeros(ld));
    for (name, k) in [
        ("matvec_padded", Kernel::detect()),
        ("matvec_padded_portable", Kernel::portable()),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                k.matvec_padded(&hp, black_box(&xp), &mut ys);
                black_box(&mut ys);
            })
        });
    }

    // faer matmul into a preallocated column, sequential.
    let hm = Mat::from_fn(N, N, |i, j| h[i * N + j]);
    let xc = Col::from_fn(N, |i| xs[i]);
    let mut yc = Col::<f64>::zeros(N);
    g.bench_function("faer_matmul_seq", |b| {
        b.iter(|| {
            matmul(
                yc.as_mat_mut(),
                Accum::Replace,
                hm.as_ref(),
                black_box(&xc).as_mat(),
                1.0,
                Par::Seq,
            );
            black_box(&mut yc);
        })
    });

    // The methods' steps.
    let (pg, fista, admm) = methods(&inst);
    bench_step(&mut g, BenchmarkId::new("step", "pg"), &pg, &inst.theta);
    bench_step(
        &mut g,
        BenchmarkId::new("step", "fista"),
        &fista,
        &inst.theta,
    );
    bench_step(&mut g, BenchmarkId::new("step", "admm"), &admm, &inst.theta);

    // The padded kernels the steps run, on the same data and separately allocated
    // aligned buffers: one step of FISTA and ADMM as one pass over the matrix.
    let k = Kernel::detect();
    let mut q = vec![0.0; N];
    inst.qp.linear_term(&inst.theta, &mut q);
    let (alpha, beta) = (fista.step_size(), fista.momentum());
    let (qa, lo, hi) = (
        AlignedVec::padded(&q),
        AlignedVec::padded(inst.qp.zset().lower()),
        AlignedVec::padded(inst.qp.zset().upper()),
    );
    let [mut y, mut z, mut scratch] = [(); 3].map(|_| AlignedVec::zeros(ld));
    g.bench_function(BenchmarkId::new("fused_kernel", "fista"), |b| {
        b.iter(|| {
            k.fista_step_padded(
                &hp,
                &mut y,
                &qa,
                alpha,
                &lo,
                &hi,
                beta,
                &mut z,
                &mut scratch,
            );
        })
    });
    let (rho, relax) = (admm.rho(), admm.relaxation());
    let m_rho = admm_map(&inst, rho);
    let mp = PaddedSymmetric::from_row_major(&m_rho, N).unwrap_or_else(|| panic!("30×30 M"));
    // m_q = (H + ρI)⁻¹q = ρ(H + ρI)⁻¹q / ρ.
    let mut mqa = AlignedVec::zeros(ld);
    k.matvec_padded(&mp, &qa, &mut mqa);
    mqa.iter_mut().for_each(|v| *v /= rho);
    let [mut t, mut z, mut dr] = [(); 3].map(|_| AlignedVec::zeros(ld));
    g.bench_function(BenchmarkId::new("fused_kernel", "admm"), |b| {
        b.iter(|| {
            k.admm_dr_step_padded(
                &mp,
                &mut t,
                &mqa,
                relax,
                &lo,
                &hi,
                &mut z,
                &mut dr,
                &mut scratch,
            );
        })
    });
    g.finish();
}

/// ρ(H + ρI)⁻¹ row-major (symmetrised), ADMM's step matrix.
fn admm_map(inst: &Instance, rho: f64) -> Vec<f64> {
    let n = inst.qp.n();
    let h = inst.qp.h();
    let shifted = Mat::from_fn(n, n, |i, j| h[(i, j)] + if i == j { rho } else { 0.0 });
    let Ok(llt) = shifted.llt(faer::Side::Lower) else {
        panic!("H + ρI is SPD")
    };
    let inv = faer::linalg::solvers::Solve::solve(&llt, Mat::<f64>::identity(n, n));
    (0..n * n)
        .map(|k| 0.5 * rho * (inv[(k / n, k % n)] + inv[(k % n, k / n)]))
        .collect()
}

fn per_iteration_grid(c: &mut Criterion) {
    run_started();
    let mut g = c.benchmark_group("grid");
    g.sample_size(100);
    for n in GRID {
        let inst = instance(n);
        let hp = PaddedSymmetric::from_row_major(inst.qp.h_row_major(), n)
            .unwrap_or_else(|| panic!("{n}×{n} H"));
        let (xs, mut ys) = (AlignedVec::padded(&x_vec(n)), AlignedVec::zeros(hp.ld()));
        let k = Kernel::detect();
        g.bench_function(BenchmarkId::new("matvec_padded", n), |b| {
            b.iter(|| {
                k.matvec_padded(&hp, black_box(&xs), &mut ys);
                black_box(&mut ys);
            })
        });
        let (pg, fista, admm) = methods(&inst);
        bench_step(&mut g, BenchmarkId::new("pg", n), &pg, &inst.theta);
        bench_step(&mut g, BenchmarkId::new("fista", n), &fista, &inst.theta);
        bench_step(&mut g, BenchmarkId::new("admm", n), &admm, &inst.theta);
    }
    g.finish();
}

/// Smallest K with ‖z^K − z*‖ ≤ EPS‖z⁰ − z*‖ from θ loaded and a cold start.
fn iterations_to_accuracy<M: IterationMap>(map: &M, theta: &[f64], z_star: &[f64]) -> usize {
    let mut s = map.new_state();
    map.load(&mut s, theta);
    map.cold_start(&mut s);
    let e0 = dist(map.iterate(&s), z_star);
    let r = run_until(map, &mut s, 1_000_000, |_, z| {
        (dist(z, z_star) <= EPS * e0).then_some(true)
    });
    assert_eq!(
        r.status,
        RunStatus::Converged,
        "{} did not reach {EPS:e}",
        map.name()
    );
    r.iterations
}

/// Load θ, cold start, K steps: the whole first-order solve.
fn bench_solve<M: IterationMap>(
    g: &mut BenchmarkGroup<'_, WallTime>,
    n: usize,
    map: &M,
    theta: &[f64],
    k: usize,
) {
    let mut s = map.new_state();
    g.bench_function(BenchmarkId::new(map.name(), n), |b| {
        b.iter(|| {
            map.load(&mut s, black_box(theta));
            map.cold_start(&mut s);
            run_fixed(map, &mut s, k)
        })
    });
}

fn to_accuracy(c: &mut Criterion) {
    run_started();
    let mut g = c.benchmark_group("accuracy");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(200))
        .measurement_time(Duration::from_millis(1500));
    let mut counts: BTreeMap<usize, BTreeMap<&'static str, usize>> = BTreeMap::new();
    for n in [10, 20, 30, 50, 100, 200, 400] {
        let inst = instance(n);
        let mut exact = ReferenceSolver::new(&inst.qp, ReferenceSettings::default())
            .unwrap_or_else(|e| panic!("{e}"));
        let z_star = exact
            .solve(&inst.theta)
            .unwrap_or_else(|e| panic!("reference n = {n}: {e}"))
            .z;
        let (pg, fista, admm) = methods(&inst);
        let k_pg = iterations_to_accuracy(&pg, &inst.theta, &z_star);
        let k_fista = iterations_to_accuracy(&fista, &inst.theta, &z_star);
        let k_admm = iterations_to_accuracy(&admm, &inst.theta, &z_star);
        bench_solve(&mut g, n, &pg, &inst.theta, k_pg);
        bench_solve(&mut g, n, &fista, &inst.theta, k_fista);
        bench_solve(&mut g, n, &admm, &inst.theta, k_admm);

        // Clarabel's interior-point solve at its usual accuracy (no polish), set up once;
        // a solve overwrites q (update_q) and runs the whole IPM.
        let settings = ReferenceSettings {
            tol: 1e-8,
            polish: false,
            ..ReferenceSettings::default()
        };
        let mut ipm = ReferenceSolver::new(&inst.qp, settings).unwrap_or_else(|e| panic!("{e}"));
        let sol = ipm
            .solve(&inst.theta)
            .unwrap_or_else(|e| panic!("clarabel n = {n}: {e}"));
        let e0 = dist(&vec![0.0; n], &z_star);
        let clarabel_rel = dist(&sol.z, &z_star) / e0;
        g.bench_function(BenchmarkId::new("clarabel", n), |b| {
            b.iter(|| ipm.solve(black_box(&inst.theta)))
        });

        let entry = counts.entry(n).or_default();
        entry.insert("pg", k_pg);
        entry.insert("fista", k_fista);
        entry.insert("admm", k_admm);
        entry.insert("clarabel_ipm_iterations", sol.iterations as usize);
        eprintln!(
            "accuracy n = {n}: K_pg = {k_pg}, K_fista = {k_fista}, K_admm = {k_admm}, clarabel {} IPM iterations, \
             ‖z_clarabel − z*‖/‖z⁰ − z*‖ = {clarabel_rel:.1e}",
            sol.iterations
        );
    }
    g.finish();
    write_meta(&counts);
}

/// Records iteration counts and kernel paths next to criterion's results.
fn write_meta(iterations: &BTreeMap<usize, BTreeMap<&'static str, usize>>) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/criterion");
    let reference_simd =
        FixedMatVec::<30>::new(&[0.0; 900], FixedLayout::ColumnAxpy).is_some_and(|k| k.is_simd());
    let meta = serde_json::json!({
        "kernel_path": Kernel::detect().path().name(),
        "reference_simd": reference_simd,
        "eps": EPS,
        "run_started_unix": run_started(),
        "iterations": iterations,
        "interleaved_n30": INTERLEAVED.get(),
    });
    let text = serde_json::to_string_pretty(&meta).unwrap_or_default();
    if let Err(e) = std::fs::create_dir_all(&dir)
        .and_then(|_| std::fs::write(dir.join("iteration-meta.json"), text))
    {
        eprintln!("could not write iteration-meta.json: {e}");
    }
}

fn config() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_millis(1000))
        .sample_size(30)
        .without_plots()
}

criterion_group! {
    name = iteration;
    config = config();
    targets = interleaved_n30, per_iteration_n30, per_iteration_grid, to_accuracy
}
criterion_main!(iteration);
