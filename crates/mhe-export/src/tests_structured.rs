//! The structured Hessian product on the target (issue 36, Build 3): `mhe-embedded`'s product
//! equals `mhe_core::structured::MheHessian` on the portable path bit for bit (exact,
//! padded and run-time sizes, plain and Jacobi-scaled); windows from the std crossover are
//! exported with the factors instead of H, and the exported Rust and C replay the std
//! estimator bit for bit on plants past the crossover.
#![allow(clippy::unwrap_used)]

use std::process::Command;

use closed_loop::scenario::{LoopOptions, Scenario};
use faer::Mat;
use mhe_core::problem::{Dims, WindowLayout};
use mhe_core::structured::MheHessian;
use qp_iter::Method;
use qp_iter::kernel::Kernel;
use qp_iter::operator::HessianOperator;

use super::extract::{OwnedProblem, portable_estimator};
use super::tests::{
    Case, artefact, bits, parse_replay, record_self_test, replay_input, run_program, run_std,
    scratch_dir, workspace_root, write_files,
};
use super::*;

/// A deterministic generator of values in [−1, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
    }

    fn mat(&mut self, r: usize, c: usize) -> Mat<f64> {
        Mat::from_fn(r, c, |_, _| self.next())
    }

    /// A symmetric positive definite n × n matrix.
    fn spd(&mut self, n: usize) -> Mat<f64> {
        let g = self.mat(n, n);
        Mat::from_fn(n, n, |i, j| {
            (0..n).map(|k| g[(i, k)] * g[(j, k)]).sum::<f64>() + if i == j { 1.0 } else { 0.0 }
        })
    }
}

/// `s·m` by columns.
fn cols(m: &Mat<f64>, s: f64) -> Vec<f64> {
    let r = m.nrows();
    (0..r * m.ncols()).map(|k| s * m[(k % r, k / r)]).collect()
}

/// On random plants of each kind of std product, `mhe_embedded::Structured::apply` gives the
/// bits of `MheHessian` on the portable kernel (FMA off), unscaled and scaled, and both are
/// within rounding of the dense product through `mhe_embedded` (checked once, generic).
#[test]
fn the_embedded_product_is_the_std_product_bit_for_bit() {
    let mut rng = Lcg(36);
    // (n_x, n_y, n_w1, n_w2, m, order): exact, exact, padded, padded, run-time sizes.
    let shapes = [
        (4, 1, 4, 1, 12, mhe_embedded::SumOrder::Fixed),
        (4, 2, 4, 2, 10, mhe_embedded::SumOrder::Fixed),
        (3, 1, 3, 1, 9, mhe_embedded::SumOrder::Fixed),
        (6, 3, 6, 2, 7, mhe_embedded::SumOrder::Fixed),
        (17, 2, 17, 2, 5, mhe_embedded::SumOrder::RunTime),
    ];
    for (nx, ny, nw1, nw2, m, order) in shapes {
        let (a, c, e, f) = (
            rng.mat(nx, nx),
            rng.mat(ny, nx),
            rng.mat(nx, nw1),
            rng.mat(ny, nw2),
        );
        let (p, q, r) = (rng.spd(nx), rng.spd(nw1 + nw2), rng.spd(ny));
        let eta: f64 = 0.8;
        let layout = WindowLayout {
            dims: Dims {
                nx,
                nu: 1,
                ny,
                nw1,
                nw2,
            },
            m,
        };
        let std = MheHessian::new(
            layout,
            a.as_ref(),
            c.as_ref(),
            e.as_ref(),
            f.as_ref(),
            eta,
            p.as_ref(),
            q.as_ref(),
            r.as_ref(),
        )
        .with_kernel(Kernel::portable());
        let std = if order == mhe_embedded::SumOrder::RunTime {
            std.generic()
        } else {
            std
        };
        assert_eq!(std.is_specialised(), order == mhe_embedded::SumOrder::Fixed);
        let pow = |k: usize| eta.powi(i32::try_from(k).unwrap());
        let (fa, fe, fc, ff, fq, fr, fp) = (
            cols(&a, 1.0),
            cols(&e, 1.0),
            cols(&c, 1.0),
            cols(&f, 1.0),
            cols(&q, 4.0),
            cols(&r, 2.0),
            cols(&p, 4.0 * pow(m)),
        );
        let decay: Vec<f64> = (0..m).map(|j| pow(m - 1 - j)).collect();
        let st = mhe_embedded::Structured {
            nx,
            ny,
            nw1,
            nw2,
            order,
            a: &fa,
            e: &fe,
            c: &fc,
            f: &ff,
            q: &fq,
            r: &fr,
            p: &fp,
            decay: &decay,
        };
        let n = std.n();
        let (la, lb) = st.work_lens();
        let mut work = vec![0.0; std.work_len()];
        let (mut wa, mut wb) = (vec![0.0; la], vec![0.0; lb]);
        let d: Vec<f64> = (0..n).map(|_| 1.5 + rng.next()).collect();
        for trial in 0..3 {
            let z: Vec<f64> = (0..n).map(|_| 3.0 * rng.next()).collect();
            let (mut want, mut got) = (vec![0.0; n], vec![0.0; n]);
            std.apply(&z, &mut want, &mut work);
            st.apply(&[], &z, &mut got, &mut wa, &mut wb);
            let tag = format!("({nx}, {ny}, {nw1}, {nw2}), m = {m}, trial {trial}");
            assert_eq!(bits(&[got]), bits(&[want.clone()]), "{tag}: unscaled");
            std.apply_scaled(&d, &z, &mut want, &mut work);
            let mut got = vec![0.0; n];
            st.apply(&d, &z, &mut got, &mut wa, &mut wb);
            assert_eq!(bits(&[got]), bits(&[want]), "{tag}: scaled");
        }
    }
}

/// The scenario with M = `horizon` (past the crossover) and K = `k`.
fn long_case(file: &str, horizon: usize, k: usize) -> Case {
    let path = workspace_root().join("scenarios").join(file);
    let mut sc = Scenario::from_file(&path).unwrap();
    let mhe = sc.mhe.as_mut().unwrap();
    *mhe = mhe
        .to_builder()
        .horizon(horizon)
        .iterations(k)
        .build(&sc.plant)
        .unwrap();
    let resolved = sc.clone().resolve().unwrap();
    let opts = LoopOptions::from_scenario(&sc).unwrap();
    let mut cl = resolved.build_loop(&opts).unwrap();
    let tr = cl.run().unwrap();
    let traj = (0..tr.len())
        .map(|t| (tr.u(t).unwrap().to_vec(), tr.y(t).unwrap().to_vec()))
        .collect();
    Case {
        path,
        k,
        resolved,
        traj,
    }
}

/// PG and FISTA, plain and Jacobi-scaled: the methods the structured product serves.
fn gradient_methods() -> Vec<Method> {
    let mut v = vec![Method::PG, Method::FISTA];
    v.extend(
        v.clone()
            .into_iter()
            .map(|m| m.with_scaling(qp_iter::Scaling::Jacobi)),
    );
    v
}

/// `mhe-embedded` (const-size, f64) over the case's trajectory.
fn run_embedded<
    const NX: usize,
    const NU: usize,
    const NY: usize,
    const M: usize,
    const NZ: usize,
    const NTH: usize,
>(
    p: &OwnedProblem,
    prior: &[f64],
    traj: &[(Vec<f64>, Vec<f64>)],
) -> Vec<Vec<f64>> {
    let st = p.structured_views();
    let views = p.window_views(&st);
    let problem = p.view(&views);
    let mut mhe =
        mhe_embedded::Mhe::<f64, NX, NU, NY, M, NZ, NTH>::new(&problem, prior.try_into().unwrap())
            .unwrap();
    let mut out = vec![mhe.estimate().to_vec()];
    for (u, y) in traj {
        mhe.push(
            u.as_slice().try_into().unwrap(),
            y.as_slice().try_into().unwrap(),
        )
        .unwrap();
        out.push(mhe.estimate().to_vec());
    }
    out
}

/// The case study at M = 14 (n_z = 74 ≥ 64: windows m = 12, 13, 14 run the structured
/// product in the std estimator), once refused by `export`: exported with the factors, no H
/// for those windows, and `mhe-embedded` equals the std estimator bit for bit.
#[test]
fn a_window_past_the_crossover_is_exported_and_bit_for_bit() {
    let c = long_case("case-study-certified.toml", 14, 40);
    let prior = c.resolved.scenario().simulation.prior.clone();
    for method in gradient_methods() {
        let mut std_est = portable_estimator(&c.resolved, method, c.k).unwrap();
        let p = OwnedProblem::from_estimator(&std_est, &c.resolved.scenario().plant).unwrap();
        let structured: Vec<usize> = (0..p.windows.len())
            .filter(|&m| p.windows[m].structured.is_some())
            .collect();
        assert_eq!(structured, [12, 13, 14], "{}", method.name());
        assert!(p.windows[14].h.is_empty());
        let expected = run_std(&mut std_est, &c.traj);
        let got = run_embedded::<4, 2, 1, 14, 74, 46>(&p, &prior, &c.traj);
        assert_eq!(
            bits(&got),
            bits(&expected),
            "{}: mhe-embedded differs from the std estimator on the portable kernel",
            method.name()
        );
    }
}

/// Structured data that do not fit are refused with the field named, before any step (a
/// decay of the wrong length), and the data of a PG export are refused under ADMM.
#[test]
fn bad_structured_data_are_refused_by_name() {
    let c = long_case("case-study-certified.toml", 14, 5);
    let est = portable_estimator(&c.resolved, Method::PG, c.k).unwrap();
    let p = OwnedProblem::from_estimator(&est, &c.resolved.scenario().plant).unwrap();
    let prior: [f64; 4] = c.resolved.scenario().simulation.prior[..]
        .try_into()
        .unwrap();
    let st = p.structured_views();
    let views = p.window_views(&st);
    let mut problem = p.view(&views);
    assert!(mhe_embedded::Mhe::<f64, 4, 2, 1, 14, 74, 46>::new(&problem, prior).is_ok());
    // ADMM on these data: refused (its (H + ρI)⁻¹ are missing; a structured window is
    // refused under ADMM too, `window structured (PG and FISTA only; ADMM needs h)`).
    problem.method = mhe_embedded::Method::Admm;
    assert!(mhe_embedded::Mhe::<f64, 4, 2, 1, 14, 74, 46>::new(&problem, prior).is_err());
    let mut bad = st.clone();
    let short = [1.0; 3];
    if let Some(s) = bad[14].as_mut() {
        s.decay = &short;
    }
    let views = p.window_views(&bad);
    let problem = p.view(&views);
    let err = mhe_embedded::Mhe::<f64, 4, 2, 1, 14, 74, 46>::new(&problem, prior).unwrap_err();
    assert_eq!(
        (err.what, err.expected, err.actual),
        ("structured decay length (m)", 14, 3)
    );
}

/// The exported C (gcc, the artefact's flags) and, for the methods in `rust`, the exported
/// Rust package on the long cases: their replay equals the std estimator bit for bit; the
/// f32 C build equals `mhe-embedded`'s `MheRt` at f32 bit for bit.
fn check_exports(cases: &[(&str, usize, &str)], methods: &[Method], rust: &[Method]) {
    let target = workspace_root().join("target").join("export-tests-target");
    for &(file, horizon, tag) in cases {
        let c = long_case(file, horizon, 30);
        let input = replay_input(&c.traj);
        let rust_dir = scratch_dir(&format!("rust-structured-{tag}"));
        for &method in methods {
            let mut est = portable_estimator(&c.resolved, method, c.k).unwrap();
            let expected = run_std(&mut est, &c.traj);
            let (mut p, art) = artefact(&c, method, ScalarKind::F64);
            assert!(p.windows[horizon].structured.is_some());
            record_self_test(&c, method, &mut p);
            // C, f64 (its self-test runs first in the replay).
            let dir = scratch_dir(&format!("c-structured-{tag}-{}", method.name()));
            write_files(&dir, Lang::C, &p, None, &art);
            build_c(&dir);
            let got = parse_replay(&run_program(&mut Command::new(dir.join("replay")), &input));
            assert_eq!(
                bits(&got),
                bits(&expected),
                "{} on {file}: the exported C differs",
                method.name()
            );
            if rust.contains(&method) {
                write_files(&rust_dir, Lang::Rust, &p, None, &art);
                let status = Command::new(env!("CARGO"))
                    .current_dir(&rust_dir)
                    .env("CARGO_TARGET_DIR", &target)
                    .args(["build", "--quiet", "--offline", "--bin", "replay"])
                    .args(["--features", "allow-uncertified"])
                    .status()
                    .unwrap();
                assert!(
                    status.success(),
                    "cargo build failed in {}",
                    rust_dir.display()
                );
                let got = parse_replay(&run_program(
                    &mut Command::new(target.join("debug").join("replay")),
                    &input,
                ));
                assert_eq!(
                    bits(&got),
                    bits(&expected),
                    "{} on {file}: the exported Rust differs",
                    method.name()
                );
            }
            // C, f32 against MheRt at f32 on the same rounded data.
            let mut art32 = art.clone();
            art32.scalar = ScalarKind::F32;
            let dir = scratch_dir(&format!("c32-structured-{tag}-{}", method.name()));
            write_files(&dir, Lang::C, &p, None, &art32);
            build_c(&dir);
            let got = parse_replay(&run_program(&mut Command::new(dir.join("replay")), &input));
            let want = run_rt_f32(&p, &art.prior, &c.traj);
            assert_eq!(
                f32_bits(&got),
                f32_bits(&want),
                "{} on {file}: the exported f32 C differs from MheRt<f32>",
                method.name()
            );
        }
    }
}

/// The case study at M = 14 (n_z = 74): FISTA (its own momentum form on the structured
/// branch) and Jacobi-scaled PG (D folded into the product) in C, f64 and f32, and scaled
/// PG in Rust (≈ 15 s; every method and the cart-pendulum: the ignored test below).
#[test]
fn exported_c_and_rust_past_the_crossover_are_bit_for_bit() {
    let pg_j = Method::PG.with_scaling(qp_iter::Scaling::Jacobi);
    check_exports(
        &[("case-study-certified.toml", 14, "cs14")],
        &[Method::FISTA, pg_j],
        &[pg_j],
    );
}

/// Every gradient method, C (f64, f32) and Rust, on the case study at M = 14 and the
/// cart-pendulum at M = 12 (n_z = 76, shape (4, 2, 4, 2)). ≈ 60 s; not in CI.
#[test]
#[ignore = "≈ 60 s: every gradient method, C and Rust, two plants (docs/testing.md)"]
fn exported_structured_every_method_both_plants() {
    let all = gradient_methods();
    check_exports(
        &[
            ("case-study-certified.toml", 14, "cs14"),
            ("cart-pendulum.toml", 12, "cp12"),
        ],
        &all,
        &all,
    );
}

fn build_c(dir: &std::path::Path) {
    let status = Command::new("cc")
        .current_dir(dir)
        .args(["-O2", "-std=c99", "-ffp-contract=off", "-fno-fast-math"])
        .args(["-DMHE_ALLOW_UNCERTIFIED", "-Wall", "-Wextra", "-Werror"])
        .args(["-Wpedantic", "-o", "replay"])
        .args(["mhe.c", "mhe_data.c", "replay.c", "-lm"])
        .status()
        .unwrap();
    assert!(status.success(), "cc failed in {}", dir.display());
}

fn f32_bits(v: &[Vec<f64>]) -> Vec<Vec<u32>> {
    v.iter()
        .map(|r| r.iter().map(|x| (*x as f32).to_bits()).collect())
        .collect()
}

/// `MheRt<f32>` on the problem's data rounded to f32 once, over the trajectory.
fn run_rt_f32(p: &OwnedProblem, prior: &[f64], traj: &[(Vec<f64>, Vec<f64>)]) -> Vec<Vec<f64>> {
    let f32s = |v: &[f64]| v.iter().map(|x| *x as f32).collect::<Vec<f32>>();
    let sts: Vec<Option<[Vec<f32>; 8]>> = p
        .windows
        .iter()
        .map(|w| {
            w.structured.as_ref().map(|s| {
                [
                    f32s(&s.a),
                    f32s(&s.e),
                    f32s(&s.c),
                    f32s(&s.f),
                    f32s(&s.q),
                    f32s(&s.r),
                    f32s(&s.p),
                    f32s(&s.decay),
                ]
            })
        })
        .collect();
    let st_views: Vec<Option<mhe_embedded::Structured<'_, f32>>> = p
        .windows
        .iter()
        .zip(&sts)
        .map(|(w, s)| {
            let (o, s) = (w.structured.as_ref()?, s.as_ref()?);
            Some(mhe_embedded::Structured {
                nx: o.nx,
                ny: o.ny,
                nw1: o.nw1,
                nw2: o.nw2,
                order: o.order,
                a: &s[0],
                e: &s[1],
                c: &s[2],
                f: &s[3],
                q: &s[4],
                r: &s[5],
                p: &s[6],
                decay: &s[7],
            })
        })
        .collect();
    let store: Vec<[Vec<f32>; 8]> = p
        .windows
        .iter()
        .map(|w| {
            [
                f32s(&w.h),
                f32s(&w.m_rho),
                f32s(&w.m_inv),
                f32s(&w.q0),
                f32s(&w.f),
                f32s(&w.lower),
                f32s(&w.upper),
                f32s(&w.scaling),
            ]
        })
        .collect();
    let w32: Vec<mhe_embedded::Window<'_, f32>> = p
        .windows
        .iter()
        .zip(&store)
        .zip(&st_views)
        .map(|((w, s), st)| mhe_embedded::Window {
            n: w.n,
            n_theta: w.n_theta,
            h: &s[0],
            m_rho: &s[1],
            m_inv: &s[2],
            q0: &s[3],
            f: &s[4],
            lower: &s[5],
            upper: &s[6],
            scaling: &s[7],
            step: w.step as f32,
            momentum: w.momentum as f32,
            inv_rho: w.inv_rho as f32,
            relaxation: w.relaxation as f32,
            structured: st.as_ref(),
        })
        .collect();
    let (a, b, e) = (f32s(&p.a), f32s(&p.b), f32s(&p.e));
    let p32 = mhe_embedded::Problem {
        nx: p.nx,
        nu: p.nu,
        ny: p.ny,
        nw1: p.nw1,
        nw2: p.nw2,
        horizon: p.horizon,
        iterations: p.iterations,
        method: p.method,
        warm_start: p.warm_start,
        a: &a,
        b: &b,
        e: &e,
        windows: &w32,
    };
    let mut ws = vec![0.0f32; mhe_embedded::MheRt::workspace_len(&p32)];
    let mut rt = mhe_embedded::MheRt::new(&p32, &f32s(prior), &mut ws).unwrap();
    let mut out = vec![rt.estimate().iter().map(|x| f64::from(*x)).collect()];
    for (u, y) in traj {
        rt.push(&f32s(u), &f32s(y)).unwrap();
        out.push(rt.estimate().iter().map(|x| f64::from(*x)).collect());
    }
    out
}

/// Writes the C artefacts of the case study at M = 14, PG at K = 40, twice: as exported
/// (the long windows through the structured product) and with the dense H in every window
/// (what the export would store without it), into target/export-tests/structured-vs-dense/
/// {structured,dense}{,-f32}, for the flash and instruction measurement of docs/embedded.md
/// ("The structured Hessian product"). Ignored: it only writes files (≈ 5 s).
#[test]
#[ignore = "writes the artefacts of a measurement (docs/embedded.md)"]
fn structured_vs_dense_artefacts() {
    let c = long_case("case-study-certified.toml", 14, 40);
    let est = portable_estimator(&c.resolved, Method::PG, c.k).unwrap();
    let (mut p, art) = artefact(&c, Method::PG, ScalarKind::F64);
    record_self_test(&c, Method::PG, &mut p);
    let root = workspace_root().join("target/export-tests/structured-vs-dense");
    let mut art32 = art.clone();
    art32.scalar = ScalarKind::F32;
    let write = |name: &str, p: &OwnedProblem| {
        for (suffix, a) in [("", &art), ("-f32", &art32)] {
            let dir = root.join(format!("{name}{suffix}"));
            std::fs::create_dir_all(&dir).unwrap();
            write_files(&dir, Lang::C, p, None, a);
        }
    };
    write("structured", &p);
    for (w, map) in p.windows.iter_mut().zip(est.maps()) {
        if w.structured.take().is_some() {
            let h = qp_iter::IterationMap::problem(map).h();
            w.h = (0..w.n * w.n).map(|k| h[(k % w.n, k / w.n)]).collect();
        }
    }
    write("dense", &p);
    println!("{}", root.display());
}
