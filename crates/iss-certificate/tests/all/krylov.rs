//! ρ_lin by Arnoldi's method (`linear/krylov.rs`) against the dense eigenvalues: on the
//! lifted matrices of the shipped scenarios and on random matrices with the lifted loop's
//! structure (delay lines feeding a dense core). Whenever Arnoldi accepts an answer it agrees
//! with the dense spectral radius to 1e-9 relative.

use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario, Scenario};
use faer::{Mat, Par};
use iss_certificate::linear::{
    KRYLOV_MIN_DIM, LiftedLoop, spectral_radius, spectral_radius_dense, spectral_radius_krylov,
    spectral_radius_krylov_steps,
};
use rand::{Rng, SeedableRng};

/// Relative agreement required between an accepted Arnoldi ρ and the dense one.
const AGREEMENT: f64 = 1e-9;

fn scenarios_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios")
}

/// The lifted loop of a shipped scenario with its own method and the exact MPC (as
/// `reproduce` builds it), or None when the scenario has no linear analysis.
fn lifted(name: &str) -> Option<(LiftedLoop, ResolvedScenario)> {
    let s = Scenario::from_file(scenarios_dir().join(format!("{name}.toml"))).ok()?;
    let mut r = s.resolve().ok()?;
    r.set_noise_scale(0.0);
    let mut o = LoopOptions::from_scenario(r.scenario()).ok()?;
    o.controller = ControllerChoice::ExactMpc;
    o.steps = 1;
    o = o.with_iterations(1).expect("K is in range");
    o.exact_mhe_solve = false;
    let cl = r.build_loop(&o).ok()?;
    let l = LiftedLoop::from_loop(&cl, &r, o.method, Par::Seq).ok()?;
    Some((l, r))
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= AGREEMENT * a.abs().max(b.abs()).max(1e-3)
}

/// On every shipped scenario with a lifted loop of dim ≥ 100 (thermal-rod-m30: the ignored
/// test below), at K = 1, 10, 100, 1000: every accepted Arnoldi ρ equals the dense one, and
/// Arnoldi accepts on most of them. Long (8 scenarios × 4 K, a dense eigenvalue problem of
/// dimension up to ~650 each): `.ci/run` runs it with `--ignored long_`.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_krylov_agrees_with_dense_on_shipped_scenarios() {
    let mut accepted = 0;
    let mut tried = 0;
    for name in [
        "thermal-rod-m10",
        "quadrotor",
        "quadrotor-free",
        "afti16",
        "mass-chain",
        "cart-pendulum",
        "quadruple-tank",
        "rao-rawlings-lee",
    ] {
        let t0 = std::time::Instant::now();
        let Some((l, _)) = lifted(name) else {
            eprintln!("{name}: no lifted loop");
            continue;
        };
        eprintln!(
            "{name}: dim {}, built in {:.2} s",
            l.dim(),
            t0.elapsed().as_secs_f64()
        );
        if l.dim() < 100 {
            continue;
        }
        for k in [1usize, 10, 100, 1000] {
            let a = l.matrix(k, Par::Seq).unwrap();
            let t0 = std::time::Instant::now();
            let dense = spectral_radius_dense(a.as_ref(), Par::Seq).unwrap();
            let td = t0.elapsed().as_secs_f64();
            tried += 1;
            let t0 = std::time::Instant::now();
            let kr = spectral_radius_krylov_steps(a.as_ref(), Par::Seq);
            eprintln!(
                "  K = {k}: dense {dense} in {td:.3} s, Arnoldi {kr:?} in {:.3} s",
                t0.elapsed().as_secs_f64()
            );
            if let Some(rho) = kr.map(|p| p.0) {
                accepted += 1;
                assert!(
                    close(rho, dense),
                    "{name} K = {k} (dim {}): Arnoldi {rho}, dense {dense}",
                    l.dim()
                );
            }
        }
    }
    assert!(
        tried >= 8,
        "only {tried} (scenario, K) pairs had a lifted loop"
    );
    assert!(
        2 * accepted >= tried,
        "Arnoldi accepted only {accepted} of {tried}"
    );
}

/// A random matrix shaped like the lifted loop: a dense core of `core` rows reading the
/// whole state — a stable "plant" (block upper triangular: decaying real eigenvalues and
/// rotations on the diagonal, random coupling above) —, and a delay line of `len` blocks of
/// `width` that shifts, is fed by the core and feeds the core with weight `coupling`.
fn lifted_like(
    rng: &mut rand_chacha::ChaCha8Rng,
    core: usize,
    width: usize,
    len: usize,
    coupling: f64,
) -> Mat<f64> {
    let n = core + width * len;
    let mut a = Mat::<f64>::zeros(n, n);
    let mut i = 0;
    while i < core {
        let r = 0.97 * 0.99_f64.powi(i as i32);
        if i + 1 < core && rng.random::<f64>() < 0.3 {
            let phi = rng.random::<f64>() * 3.0;
            let (c, s) = (r * phi.cos(), r * phi.sin());
            a[(i, i)] = c;
            a[(i + 1, i + 1)] = c;
            a[(i, i + 1)] = s;
            a[(i + 1, i)] = -s;
            i += 2;
        } else {
            a[(i, i)] = if rng.random::<f64>() < 0.5 { r } else { -r };
            i += 1;
        }
    }
    for i in 0..core {
        for j in i + 2..core {
            a[(i, j)] = (rng.random::<f64>() - 0.5) * 2.0 / (core as f64).sqrt();
        }
        // The core reads the oldest block of the delay line.
        for j in 0..width {
            a[(i, n - width + j)] = (rng.random::<f64>() - 0.5) * coupling;
        }
    }
    // The newest block of the line takes the first `width` core entries; the rest shift.
    for j in 0..width {
        a[(core + j, j)] = 1.0;
    }
    for b in 1..len {
        for j in 0..width {
            a[(core + b * width + j, core + (b - 1) * width + j)] = 1.0;
        }
    }
    a
}

/// Random lifted-like matrices of dim 600–1000: every accepted Arnoldi ρ agrees with the
/// dense ρ, and Arnoldi accepts most of them; on an unstructured random matrix (eigenvalues
/// filling a disk, the hard case) an accepted ρ agrees too, and the dispatching function
/// agrees always (Arnoldi or its dense fallback).
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_krylov_agrees_with_dense_on_random_instances() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2025);
    let mut accepted = 0;
    let mut tried = 0;
    for case in 0..8 {
        let core = 200 + 40 * case;
        let width = 10 + case;
        let len = 40;
        let coupling = [1e-3, 1e-2, 0.1, 1.0][case % 4];
        let a = lifted_like(&mut rng, core, width, len, coupling);
        assert!(a.nrows() >= KRYLOV_MIN_DIM);
        let dense = spectral_radius_dense(a.as_ref(), Par::Seq).unwrap();
        tried += 1;
        if let Some(rho) = spectral_radius_krylov(a.as_ref(), Par::Seq) {
            accepted += 1;
            assert!(
                close(rho, dense),
                "case {case}: Arnoldi {rho}, dense {dense}"
            );
        }
        let auto = spectral_radius(a.as_ref(), Par::Seq).unwrap();
        assert!(
            close(auto, dense),
            "case {case}: auto {auto}, dense {dense}"
        );
    }
    assert!(
        2 * accepted >= tried,
        "Arnoldi accepted only {accepted} of {tried}"
    );
    let n = 650;
    let disk = Mat::from_fn(n, n, |_, _| (rng.random::<f64>() - 0.5) / (n as f64).sqrt());
    let dense = spectral_radius_dense(disk.as_ref(), Par::Seq).unwrap();
    if let Some(rho) = spectral_radius_krylov(disk.as_ref(), Par::Seq) {
        assert!(close(rho, dense), "disk: Arnoldi {rho}, dense {dense}");
    }
    let auto = spectral_radius(disk.as_ref(), Par::Seq).unwrap();
    assert!(close(auto, dense), "disk: auto {auto}, dense {dense}");
    // A known spectrum: the pair 0.99·e^{±0.3i} above 0.98 and the rest in [−0.9, 0.9].
    let n = 700;
    let mut t = Mat::<f64>::zeros(n, n);
    for i in 0..n {
        t[(i, i)] = rng.random::<f64>() * 1.8 - 0.9;
        for j in i + 1..(i + 4).min(n) {
            t[(i, j)] = rng.random::<f64>() - 0.5;
        }
    }
    let (c, s) = (0.99 * 0.3_f64.cos(), 0.99 * 0.3_f64.sin());
    t[(0, 0)] = c;
    t[(1, 1)] = c;
    t[(0, 1)] = s;
    t[(1, 0)] = -s;
    t[(1, 2)] = 0.0;
    t[(2, 2)] = 0.98;
    let rho = spectral_radius_krylov(t.as_ref(), Par::Seq).expect("accepted");
    assert!((rho - 0.99).abs() <= 1e-10, "ρ = {rho}");
}

/// A nilpotent matrix (one long shift) has ρ = 0; a zero matrix too; the identity 1.
#[test]
fn krylov_on_degenerate_matrices() {
    let n = 650;
    let shift = Mat::from_fn(n, n, |i, j| if i == j + 1 { 1.0 } else { 0.0 });
    let auto = spectral_radius(shift.as_ref(), Par::Seq).unwrap();
    assert!(auto.abs() <= 1e-6, "ρ(shift) = {auto}");
    assert_eq!(
        spectral_radius_krylov(Mat::<f64>::zeros(n, n).as_ref(), Par::Seq),
        Some(0.0)
    );
    let id = Mat::<f64>::identity(n, n);
    let rho = spectral_radius(id.as_ref(), Par::Seq).unwrap();
    assert!((rho - 1.0).abs() <= 1e-12, "ρ(I) = {rho}");
}

/// thermal-rod-m30 (dim 1480): ρ_lin along `reproduce`'s grid by Arnoldi and dense; the
/// largest relative difference and both times are printed. About a minute (the dense side).
///
/// `cargo test -p closed-loop --release --test all krylov_thermal_rod_m30 -- --ignored --nocapture`
#[test]
#[ignore]
fn krylov_thermal_rod_m30() {
    let (l, _) = lifted("thermal-rod-m30").unwrap();
    let mut worst = 0.0_f64;
    let (mut t_k, mut t_d) = (0.0, 0.0);
    for k in [1usize, 3, 10, 31, 100, 316, 1000, 3434] {
        let a = l.matrix(k, Par::Seq).unwrap();
        let t0 = std::time::Instant::now();
        let kr = spectral_radius_krylov_steps(a.as_ref(), Par::Seq);
        t_k += t0.elapsed().as_secs_f64();
        println!("K = {k}: Arnoldi (ρ, m) {kr:?}");
        let kr = kr.map(|p| p.0);
        let t0 = std::time::Instant::now();
        let dense = spectral_radius_dense(a.as_ref(), Par::Seq).unwrap();
        t_d += t0.elapsed().as_secs_f64();
        println!("K = {k}: Arnoldi {kr:?}, dense {dense}");
        let kr = kr.expect("Arnoldi accepted");
        assert!(close(kr, dense), "K = {k}: Arnoldi {kr}, dense {dense}");
        worst = worst.max((kr - dense).abs() / dense.max(1e-3));
    }
    println!("worst relative difference {worst:.1e}; Arnoldi {t_k:.2} s, dense {t_d:.2} s");
}
