//! The Lur'e loop of a shipped scenario (`iss_certificate::lure::scenario`): with every
//! clamp the identity it is K_lin's lifted loop, and its clamped iterations are the MHE's.
#![allow(clippy::unwrap_used)]

use closed_loop::scenario::{LoopOptions, ResolvedScenario, Scenario};
use iss_certificate::lure::scenario::{
    ScenarioLureError, frozen_slope_radius, refuted_at, scenario_lure,
};
use qp_iter::Method;

fn resolved(file: &str) -> ResolvedScenario {
    let path = format!("{}/../../scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
    Scenario::from_file(&path)
        .expect("scenario parses")
        .resolve()
        .expect("scenario resolves")
}

fn options(r: &ResolvedScenario, method: Method) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(r.scenario()).expect("loop options");
    o.method = method;
    o
}

/// With Δ = v the constructed loop's lifted matrix is 𝔸(K) of K_lin, entry by entry up to
/// the rounding of two product orders.
#[test]
fn unclamped_lure_loop_is_the_lifted_matrix() {
    let r = resolved("double-integrator.toml");
    for method in [Method::PG, Method::JACOBI_PRESETS[0]] {
        let sl = scenario_lure(&r, &options(&r, method)).expect("PG loop builds");
        let lp = &sl.lure;
        lp.validate().expect("shapes");
        assert_eq!(lp.n_x(), sl.lifted.dim());
        assert!(lp.n_c() > 0, "the MHE's 𝒲 box gives channels");
        for k in [1usize, 2, 5] {
            let want = sl.lifted.matrix(k, faer::Par::Seq).expect("𝔸(K)");
            let got = lp.lifted_linear(k);
            let n = want.nrows();
            let scale = (0..n)
                .flat_map(|i| (0..n).map(move |j| (i, j)))
                .map(|(i, j)| want[(i, j)].abs())
                .fold(1.0_f64, f64::max);
            let mut worst = 0.0_f64;
            for i in 0..n {
                for j in 0..n {
                    worst = worst.max((got.at(i, j) - want[(i, j)]).abs());
                }
            }
            assert!(
                worst <= 1e-11 * scale,
                "{}: K = {k}: |Δ| = {worst:e} (scale {scale:e})",
                method.name()
            );
        }
    }
}

/// The clamps change the loop: with the clamps kept, one sample from a state that drives
/// the MHE's iterate outside 𝒲 differs from the linear step (the channels are wired in).
#[test]
fn clamps_are_wired_into_the_iterations() {
    let r = resolved("double-integrator.toml");
    let sl = scenario_lure(&r, &options(&r, Method::PG)).expect("PG loop builds");
    let lp = &sl.lure;
    let u = lp.unclamped();
    // A large warm start: v is far outside any box, so Δ = 0 (s = 0) differs from Δ = v.
    let mut x = vec![0.0; lp.n_x()];
    let lay = sl.lifted.layout();
    for j in 0..lay.nz {
        x[lay.warm_start() + j] = 1e3;
    }
    let xi0 = lp.s0.apply(&x);
    let v = lp.c.apply(&xi0);
    let dx = lp.d_x.apply(&x);
    let v: Vec<f64> = v.iter().zip(&dx).map(|(a, b)| a + b).collect();
    assert!(
        v.iter().any(|t| t.abs() > 1.0),
        "the probe reaches the channels"
    );
    let lin = u.a_xi.apply(&xi0);
    let zero_clamp: Vec<f64> = lp
        .a_xi
        .apply(&xi0)
        .iter()
        .zip(lp.e_x.apply(&x))
        .map(|(a, b)| a + b)
        .collect();
    let lin: Vec<f64> = lin
        .iter()
        .zip(u.e_x.apply(&x))
        .map(|(a, b)| a + b)
        .collect();
    let diff: f64 = lin
        .iter()
        .zip(&zero_clamp)
        .map(|(a, b)| (a - b).abs())
        .sum();
    assert!(diff > 1.0, "Δ = 0 and Δ = v give the same step");
}

/// Methods whose clamps sit elsewhere are refused with the key to change.
#[test]
fn fista_and_admm_are_refused_by_name() {
    let r = resolved("double-integrator.toml");
    for method in [Method::FISTA, Method::ADMM_PR] {
        match scenario_lure(&r, &options(&r, method)) {
            Err(e @ ScenarioLureError::Method { .. }) => {
                assert!(e.to_string().contains("mhe.method"), "{e}");
            }
            other => panic!("{}: expected a method error, got {other:?}", method.name()),
        }
    }
}

fn short(file: &str, horizon: usize) -> ResolvedScenario {
    let path = format!("{}/../../scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
    let mut s = Scenario::from_file(&path).expect("scenario parses");
    if let Some(m) = s.mhe.as_mut() {
        *m = (m.to_builder().horizon(horizon).build(&s.plant)).expect("M is valid");
    }
    s.resolve().expect("scenario resolves")
}

/// s = 𝟙 is the linear loop: ρ(𝔸_𝟙(K)) = ρ_lin(K); and at M = 2 the frozen loops refute
/// K = 1 and K = 2 (ρ(s = 0) = 1.006, 1.003, measured) while s = 0 is stable from K = 3.
#[test]
fn frozen_slopes_bound_k_loop_from_below() {
    let r = short("double-integrator.toml", 2);
    let sl = scenario_lure(&r, &options(&r, Method::PG)).expect("PG loop builds");
    let lp = &sl.lure;
    let nc = lp.n_c();
    for k in [1usize, 3] {
        let lin = sl.lifted.spectral_radius(k, faer::Par::Seq).expect("ρ_lin");
        let one = frozen_slope_radius(lp, &vec![1.0; nc], k).expect("ρ(𝟙)");
        assert!(
            (lin - one).abs() <= 1e-9,
            "K = {k}: ρ_lin {lin} vs ρ(𝟙) {one}"
        );
    }
    let zero = vec![vec![0.0; nc]];
    for k in [1usize, 2] {
        let hit = refuted_at(lp, k, &zero).expect("radii");
        assert!(
            matches!(hit, Some((0, rho)) if rho > 1.0),
            "K = {k}: {hit:?}"
        );
    }
    assert_eq!(refuted_at(lp, 3, &zero).expect("radii"), None);
    // Patterns are checked before anything is built.
    for bad in [vec![0.5; nc + 1], vec![1.5; nc]] {
        assert!(matches!(
            frozen_slope_radius(lp, &bad, 1),
            Err(ScenarioLureError::Slopes { .. })
        ));
    }
}

/// Deterministic pseudo-random vertex patterns (a 64-bit LCG; no dependency).
fn vertex_patterns(nc: usize, count: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut x = seed;
    let mut out = vec![vec![0.0; nc], vec![0.5; nc], vec![1.0; nc]];
    for _ in 0..count {
        out.push(
            (0..nc)
                .map(|_| {
                    x = x
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    if (x >> 33) & 1 == 1 { 1.0 } else { 0.0 }
                })
                .collect(),
        );
    }
    out
}

/// Measurement (docs/testing.md, docs/theory.md §3): on the shipped double integrator
/// (M = 9), per PG method and K, ρ_lin and the worst frozen-slope ρ over s = 0, ½, 𝟙 and 20
/// random vertices — the K at which every loop certificate is refuted — and the size of the
/// chain LMI there.
#[test]
#[ignore = "release-only measurement (docs/testing.md)"]
fn measure_frozen_slopes_double_integrator() {
    use iss_certificate::lure::loop_level::loop_unknowns;
    let r = resolved("double-integrator.toml");
    for method in [Method::PG, Method::JACOBI_PRESETS[0]] {
        let sl = scenario_lure(&r, &options(&r, method)).expect("PG loop builds");
        let lp = &sl.lure;
        let (nx, nxi, nc) = (lp.n_x(), lp.n_xi(), lp.n_c());
        println!("{}: n_X={nx} n_ξ={nxi} n_c={nc}", method.name());
        let pats = vertex_patterns(nc, 20, 7);
        for k in [1usize, 10, 20, 23, 30, 45, 46, 60, 90, 135, 230, 460] {
            let t = std::time::Instant::now();
            let lin = sl.lifted.spectral_radius(k, faer::Par::Seq).expect("ρ_lin");
            let mut worst = (0usize, 0.0_f64);
            for (i, s) in pats.iter().enumerate() {
                let rho = frozen_slope_radius(lp, s, k).expect("ρ_s");
                if rho > worst.1 {
                    worst = (i, rho);
                }
            }
            println!(
                "  K={k}: ρ_lin={lin:.5} worst frozen ρ={:.5} (pattern {}) unknowns={} ({:.2} s)",
                worst.1,
                worst.0,
                loop_unknowns(nx, nxi, nc, k),
                t.elapsed().as_secs_f64()
            );
        }
        // Every K of 1..=150: where ρ_lin < 1 but a frozen pattern refutes, and the first K
        // from which neither refutes up to 150.
        let (mut lin_from, mut frozen_from) = (None, None);
        let mut gaps = Vec::new();
        for k in 1..=150usize {
            let lin = sl.lifted.spectral_radius(k, faer::Par::Seq).expect("ρ_lin");
            let hit = refuted_at(lp, k, &pats).expect("radii");
            if lin < 1.0 && hit.is_some() {
                gaps.push(k);
            }
            if lin >= 1.0 {
                lin_from = None;
            } else if lin_from.is_none() {
                lin_from = Some(k);
            }
            if lin >= 1.0 || hit.is_some() {
                frozen_from = None;
            } else if frozen_from.is_none() {
                frozen_from = Some(k);
            }
        }
        println!(
            "  K ≤ 150: ρ_lin < 1 from K = {lin_from:?} on; no pattern refutes from K = \
             {frozen_from:?} on; ρ_lin < 1 but refuted at K ∈ {gaps:?}"
        );
    }
}
