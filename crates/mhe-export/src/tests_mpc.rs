//! The K_c-iteration MPC on the target: the std closed loop (portable `MheEstimator` +
//! portable `SuboptimalMpc`) against `mhe-embedded`'s `Mhe` + `Mpc`, the exported C and the
//! exported Rust loop programs, bit for bit in x̂ and u; the K_c refusal.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;
use std::process::Command;

use closed_loop::ClosedLoop;
use closed_loop::scenario::{Scenario, scenario_disturbance};
use qp_iter::Method;

use super::extract::{OwnedMpc, OwnedProblem, portable_estimator, portable_mpc};
use super::tests::workspace_root;
use super::tests::{
    bits, certified_preset_pg, exported_artefact, methods, parse_replay, run_program, scratch_dir,
    write_files,
};
use super::*;

/// One closed loop of a scenario: the MHE's method and K_e, the MPC's method and K_c.
pub(super) struct LoopCase {
    pub resolved: ResolvedScenario,
    pub path: PathBuf,
    pub mhe: Method,
    pub k_e: usize,
    pub k_c: usize,
}

impl LoopCase {
    pub(super) fn new(file: &str, k_c: usize) -> Self {
        let path = workspace_root().join("scenarios").join(file);
        let sc = Scenario::from_file(&path).unwrap();
        let mhe = sc.mhe.as_ref().unwrap();
        let (m, k_e) = (mhe.method(), mhe.iterations().get());
        Self {
            resolved: sc.resolve().unwrap(),
            path,
            mhe: m,
            k_e,
            k_c,
        }
    }

    /// The std loop on the portable kernel: per step (x̂_t, u_t, y_t).
    pub(super) fn run_std(&self, mpc_method: Method) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        let sc = self.resolved.scenario();
        let est = portable_estimator(&self.resolved, self.mhe, self.k_e).unwrap();
        let ctrl = portable_mpc(&self.resolved, mpc_method, self.k_c).unwrap();
        let dist = scenario_disturbance(sc, sc.noise.seed).unwrap();
        let mut cl = ClosedLoop::new(
            sc.plant.clone(),
            est,
            ctrl,
            dist,
            &sc.simulation.x0,
            sc.simulation.steps,
        )
        .unwrap();
        let tr = cl.run().unwrap();
        (0..tr.len())
            .map(|t| {
                (
                    tr.x_hat(t).unwrap().to_vec(),
                    tr.u(t).unwrap().to_vec(),
                    tr.y(t).unwrap().to_vec(),
                )
            })
            .collect()
    }

    /// The exported data of the MHE and of the MPC with `mpc_method`.
    pub(super) fn data(&self, mpc_method: Method) -> (OwnedProblem, OwnedMpc) {
        let est = portable_estimator(&self.resolved, self.mhe, self.k_e).unwrap();
        let p = OwnedProblem::from_estimator(&est, &self.resolved.scenario().plant).unwrap();
        let ctrl = portable_mpc(&self.resolved, mpc_method, self.k_c).unwrap();
        let m = OwnedMpc::from_controller(&ctrl, self.resolved.mpc().unwrap()).unwrap();
        (p, m)
    }
}

/// `mhe-embedded`'s loop fed with the y_t of `std`: per step the (x̂_t, u_t) it computes.
fn run_embedded<
    const NX: usize,
    const NU: usize,
    const NY: usize,
    const M: usize,
    const NZ: usize,
    const NTH: usize,
    const NSEQ: usize,
>(
    p: &OwnedProblem,
    mpc: &OwnedMpc,
    prior: &[f64],
    ys: &[Vec<f64>],
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let st = p.structured_views();
    let views = p.window_views(&st);
    let problem = p.view(&views);
    let mp = mpc.view();
    let mut mhe =
        mhe_embedded::Mhe::<f64, NX, NU, NY, M, NZ, NTH>::new(&problem, prior.try_into().unwrap())
            .unwrap();
    let mut ctrl = mhe_embedded::Mpc::<f64, NX, NU, NSEQ>::new(&mp).unwrap();
    let mut out = Vec::new();
    for y in ys {
        let x = *mhe.estimate();
        let u = *ctrl.control(&x).unwrap();
        out.push((x.to_vec(), u.to_vec()));
        mhe.push(&u, y.as_slice().try_into().unwrap()).unwrap();
    }
    out
}

fn bits_of(rows: &[(Vec<f64>, Vec<f64>)]) -> Vec<Vec<u64>> {
    rows.iter()
        .map(|(x, u)| x.iter().chain(u).map(|v| v.to_bits()).collect())
        .collect()
}

/// std portable = mhe-embedded for every MPC method, in x̂ and u at every step.
fn check_embedded(
    c: &LoopCase,
    run: impl Fn(&OwnedProblem, &OwnedMpc, &[f64], &[Vec<f64>]) -> Vec<(Vec<f64>, Vec<f64>)>,
) {
    let prior = c.resolved.scenario().simulation.prior.clone();
    for method in methods() {
        let std = c.run_std(method);
        let (p, m) = c.data(method);
        let ys: Vec<Vec<f64>> = std.iter().map(|r| r.2.clone()).collect();
        let expected: Vec<(Vec<f64>, Vec<f64>)> =
            std.iter().map(|r| (r.0.clone(), r.1.clone())).collect();
        let got = run(&p, &m, &prior, &ys);
        assert_eq!(
            bits_of(&got),
            bits_of(&expected),
            "MPC {}: mhe-embedded's loop differs from the std loop on the portable kernel",
            method.name()
        );
    }
}

/// K_c = 125 is the joint certificate's floor at K_e = 243 for PG + PG on the certified
/// preset (`cargo xtask export … --kc certified` prints it); every MPC method runs it here.
#[test]
fn embedded_loop_equals_std_portable_bit_for_bit_on_the_certified_preset() {
    let c = LoopCase::new("case-study-certified.toml", 125);
    check_embedded(&c, run_embedded::<4, 2, 1, 9, 49, 31, 20>);
}

#[test]
fn embedded_loop_equals_std_portable_bit_for_bit_on_the_cart_pendulum() {
    let c = LoopCase::new("cart-pendulum.toml", 30);
    check_embedded(&c, run_embedded::<4, 1, 2, 9, 58, 31, 10>);
}

/// The loop program's input (one "y…" line per step) and its expected output (one
/// "x̂…,u…" line per step, then the line after the last y).
fn loop_io(std: &[(Vec<f64>, Vec<f64>, Vec<f64>)]) -> (String, Vec<Vec<u64>>) {
    let input = std
        .iter()
        .map(|r| {
            r.2.iter()
                .map(|v| format!("{v:?}"))
                .collect::<Vec<_>>()
                .join(",")
                + "\n"
        })
        .collect();
    let expected = std
        .iter()
        .map(|(x, u, _)| x.iter().chain(u).map(|v| v.to_bits()).collect())
        .collect();
    (input, expected)
}

/// The exported C loop program (gcc) and the exported Rust one reproduce the std loop's x̂
/// and u bit for bit, for every MPC method, on both scenarios.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_exported_c_and_rust_loops_equal_std_portable_bit_for_bit() {
    // Its own target directory: the replay test builds a package of the same name.
    let target = workspace_root()
        .join("target")
        .join("export-tests-loop-target");
    for (file, tag, k_c) in [
        ("case-study-certified.toml", "certified", 125),
        ("cart-pendulum.toml", "cart", 30),
    ] {
        let c = LoopCase::new(file, k_c);
        let rust_dir = scratch_dir(&format!("loop-rust-{tag}"));
        for method in methods() {
            let std = c.run_std(method);
            let (input, expected) = loop_io(&std);
            let (p, m) = c.data(method);
            let art = exported_artefact(&c.path, &c.resolved, c.mhe, c.k_e, Some(k_c));
            let dir = scratch_dir(&format!("loop-c-{tag}-{}", method.name()));
            write_files(&dir, Lang::C, &p, Some(&m), &art);
            let status = Command::new("make")
                .current_dir(&dir)
                .args([
                    "-s",
                    "loop",
                    "CFLAGS=-O2 -Werror",
                    "DEFS=-DMHE_ALLOW_UNCERTIFIED",
                ])
                .status()
                .unwrap();
            assert!(status.success(), "make loop failed in {}", dir.display());
            let got = parse_replay(&run_program(&mut Command::new(dir.join("loop")), &input));
            // One line per row, then the one after the last y.
            assert_eq!(got.len(), expected.len() + 1);
            assert_eq!(
                bits(&got[..expected.len()]),
                expected,
                "MPC {} on {file}: the exported C loop differs",
                method.name()
            );
            write_files(&rust_dir, Lang::Rust, &p, Some(&m), &art);
            let status = Command::new(env!("CARGO"))
                .current_dir(&rust_dir)
                .env("CARGO_TARGET_DIR", &target)
                .args(["build", "--quiet", "--offline", "--bin", "loop"])
                .args(["--features", "allow-uncertified"])
                .status()
                .unwrap();
            assert!(
                status.success(),
                "cargo build failed in {}",
                rust_dir.display()
            );
            let got = parse_replay(&run_program(
                &mut Command::new(target.join("debug").join("loop")),
                &input,
            ));
            assert_eq!(
                bits(&got[..expected.len()]),
                expected,
                "MPC {} on {file}: the exported Rust loop differs",
                method.name()
            );
        }
    }
}

/// K_c: `certified` is the joint floor at K_e; below it is refused unless allowed; a K_e
/// with no certified K_c is refused with the floor named.
#[test]
fn a_k_c_below_the_joint_floor_is_refused_unless_allowed() {
    let path = workspace_root().join("scenarios/case-study-certified.toml");
    let resolved = Scenario::from_file(&path).unwrap().resolve().unwrap();
    let cert = certified_preset_pg(&resolved);
    let joint = joint_certificate(&resolved, cert, Method::PG, Method::PG).unwrap();
    let k_e = cert.solver(Method::PG).unwrap().k_min.unwrap();
    let floor = joint.analysis.k_c_min(k_e, joint.region.k_max).unwrap();
    let decide = |kc: Iterations, k_e: usize, allow: bool| {
        decide_kc(&resolved, cert, &joint, kc, k_e, ScalarKind::F64, allow)
            .map(|(k, v)| (k, v.certified.is_certified()))
    };
    assert_eq!(
        decide(Iterations::Certified, k_e, false).unwrap(),
        (floor, true)
    );
    assert_eq!(
        decide(Iterations::Given(floor + 3), k_e, false).unwrap(),
        (floor + 3, true)
    );
    let err = decide(Iterations::Given(floor - 1), k_e, false)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("below the joint certificate's floor") && err.contains("--allow-uncertified"),
        "{err}"
    );
    assert_eq!(
        decide(Iterations::Given(floor - 1), k_e, true).unwrap(),
        (floor - 1, false)
    );
    assert!(Iterations::parse("--kc", "0").is_err());
    // Below the K_e floor no K_c is certified.
    let err = decide(Iterations::Certified, k_e - 1, false)
        .unwrap_err()
        .to_string();
    assert!(err.contains("no K_c"), "{err}");
    // An uncertified K_c says so in the header, the README and certificate.json.
    let c = LoopCase::new("case-study-certified.toml", floor - 1);
    let c = LoopCase { k_e, ..c };
    let (p, m) = c.data(Method::PG);
    let mut art = exported_artefact(&path, &resolved, Method::PG, k_e, Some(floor - 1));
    art.certified = true;
    art.reason = None;
    art.k_min = Some(k_e);
    art.mpc = Some(MpcArtefact {
        method: "pg".into(),
        k_c: floor - 1,
        k_c_min: Some(floor),
        certified: false,
        reason: Some(format!(
            "K_c = {} is below the certified floor {floor}",
            floor - 1
        )),
    });
    let dir = scratch_dir("uncertified-mpc");
    let sc = cert.solver(Method::PG).unwrap();
    write_artefact(
        &dir,
        Lang::C,
        &p,
        Some((&m, &joint)),
        &art,
        sc,
        &path,
        &serde_json::Value::Null,
    )
    .unwrap();
    let read = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
    assert!(read("mhe_data.h").contains("#define MPC_CERTIFIED 0"));
    assert!(read("mhe_data.h").contains("UNCERTIFIED, the joint certificate needs K_c"));
    assert!(read("README.md").contains("**UNCERTIFIED**"));
    let json: serde_json::Value = serde_json::from_str(&read("certificate.json")).unwrap();
    assert_eq!(json["certified"], true);
    assert_eq!(json["loop_certified"], false);
    assert_eq!(json["artefact_covered"], false);
    assert_eq!(json["mpc"]["certified"], false);
    assert_eq!(json["mpc"]["iterations"], floor - 1);
    assert_eq!(json["mpc"]["k_c_min"], floor);
    assert_eq!(json["mpc"]["at_pair"]["certified"], false);
    assert_eq!(json["mpc"]["joint"]["region"]["k_e_floor"], k_e);
}

/// An f32 export with the MPC builds (C, `float`) and its loop stays near the f64 loop on
/// the certified preset's y: the measured largest deviation in x̂ and in u is printed (the
/// certificate does not cover f32).
#[test]
fn f32_loop_builds_and_stays_near_f64() {
    let c = LoopCase::new("case-study-certified.toml", 125);
    let method = Method::PG;
    let std = c.run_std(method);
    let (input, expected) = loop_io(&std);
    let (p, m) = c.data(method);
    let mut art = exported_artefact(&c.path, &c.resolved, c.mhe, c.k_e, Some(c.k_c));
    art.scalar = ScalarKind::F32;
    let dir = scratch_dir("loop-c-f32");
    write_files(&dir, Lang::C, &p, Some(&m), &art);
    let status = Command::new("make")
        .current_dir(&dir)
        .args([
            "-s",
            "loop",
            "CFLAGS=-O2 -Werror",
            "DEFS=-DMHE_ALLOW_UNCERTIFIED",
        ])
        .status()
        .unwrap();
    assert!(status.success(), "make loop failed in {}", dir.display());
    let got = parse_replay(&run_program(&mut Command::new(dir.join("loop")), &input));
    let nx = c.resolved.scenario().plant.nx();
    let (mut dx, mut du, mut scale) = (0.0f64, 0.0f64, 0.0f64);
    for (g, e) in got.iter().zip(&expected) {
        for (i, (a, b)) in g.iter().zip(e).enumerate() {
            let b = f64::from_bits(*b);
            let d = (a - b).abs();
            if i < nx {
                dx = dx.max(d);
                scale = scale.max(b.abs());
            } else {
                du = du.max(d);
            }
        }
    }
    println!(
        "f32 loop: max |x̂_f32 − x̂_f64| = {dx:.3e} (max |x̂| = {scale:.3e}), max |u_f32 − u_f64| = {du:.3e}"
    );
    assert!(dx > 0.0 && dx < 1e-3 * scale && du < 1e-3, "{dx:e} {du:e}");
}
