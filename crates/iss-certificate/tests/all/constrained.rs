//! Issue 15: the case study with bounded 𝒳 and 𝒴 — the MHE with its general rows, the MPC
//! with predicted-state rows (infeasible steps recorded with the fallback applied), and the
//! certificate void with the exact reasons.

use closed_loop::scenario::{ControllerChoice, LoopOptions, Scenario};
use iss_certificate::certificate::{CertificateOptions, Gamma13Source};
use mpc_core::{ControlStatus, MpcFallback};
use qp_iter::Method;

const CASE_STUDY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../scenarios/case-study.toml"
);

/// The case study with 𝒳 = [−15, 15] × [−12, 12] × [−12, 12] × [−12, x̄₄] (x₀ = (12, −10, 10,
/// −10) inside), 𝒴 = [−20, 20]; x̄₄ = 12, or 2 with `tight`: x₄⁺ = 0.5(x₁ + x₃ + x₄) has no
/// input, and from the prior (7, −7, 3, −5) it is predicted at 2.5 > 2, so the MPC is
/// infeasible at t = 0 (and the plant itself leaves 𝒳).
fn constrained(tight: bool) -> Scenario {
    let text = std::fs::read_to_string(CASE_STUDY).unwrap();
    let x4 = if tight { 2.0 } else { 12.0 };
    let sets = format!(
        "[sets]\nstate = {{ lower = [-15.0, -12.0, -12.0, -12.0], upper = [15.0, 12.0, 12.0, {x4:.1}] }}\n\
         output = {{ lower = [-20.0], upper = [20.0] }}\n"
    );
    Scenario::from_toml_str(&text.replace("[sets]\n", &sets)).unwrap()
}

fn options(s: &Scenario, method: Method, controller: ControllerChoice) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(s).unwrap();
    o.method = method;
    o = o.with_iterations(200).expect("K is in range");
    o.exact_mhe_solve = true;
    o.controller = controller;
    o
}

#[test]
fn constrained_case_study_runs_and_records_what_the_mpc_applied() {
    for tight in [false, true] {
        let s = constrained(tight);
        for controller in [
            ControllerChoice::ExactMpc,
            ControllerChoice::suboptimal(50, Method::FISTA).unwrap(),
        ] {
            let mut cl = crate::build(&s, &options(&s, Method::PG, controller)).unwrap();
            let trace = cl.run().unwrap().clone();
            assert_eq!(trace.len(), 40);
            let infeasible: Vec<usize> = trace.infeasible_steps().collect();
            if tight {
                assert!(infeasible.contains(&0), "{controller:?}: {infeasible:?}");
                let want = match controller {
                    ControllerChoice::ExactMpc => MpcFallback::InputOnlyMpc,
                    _ => MpcFallback::ShiftedPlan,
                };
                for t in &infeasible {
                    assert!(matches!(
                        trace.control_status(*t),
                        Some(ControlStatus::Infeasible { fallback, .. }) if fallback == want
                    ));
                }
            } else {
                assert!(infeasible.is_empty(), "{controller:?}: {infeasible:?}");
            }
            // The MHE with PG: feasible iterates with the rows of 𝒳 and 𝒴.
            let mhe = trace.mhe().unwrap();
            for t in 0..trace.len() {
                let v = mhe.step(t).unwrap().violation();
                assert!(v <= 1e-8, "t {t}: violation {v}");
            }
        }
    }
}

#[test]
fn the_certificate_is_void_with_the_exact_reasons() {
    let s = constrained(false);
    let opts = CertificateOptions {
        gamma13: Gamma13Source::User(4.5676),
        gamma13_sequences: 0,
        lipschitz_pairs: 20,
        solvers: vec![Method::PG, Method::ADMM],
        ..CertificateOptions::default()
    };
    let c = crate::certify(&s, &opts).unwrap();
    for sc in &c.solvers {
        assert_eq!(sc.k_min, None);
        let all = iss_certificate::outcome::VoidReason::join(&sc.void_reasons).replace("; ", "\n");
        assert!(
            all.contains("L_Φ (Lemma 1)") && all.contains("FIXED set"),
            "{all}"
        );
        assert!(
            all.contains("L_π, γ₁,₃") && all.contains("state constraints"),
            "{all}"
        );
    }
    // γ₁,₃ computed (not user-supplied): void with its typed reason.
    let computed = CertificateOptions {
        gamma13: Gamma13Source::Certified,
        gamma13_sequences: 2,
        lipschitz_pairs: 0,
        solvers: vec![Method::PG],
        ..CertificateOptions::default()
    };
    let c2 = crate::certify(&s, &computed).unwrap();
    assert_eq!(
        c2.gamma13.void,
        Some(iss_certificate::gamma13::Gamma13Void::StateConstrainedMpc)
    );
    assert!(c2.gamma13.used.is_infinite() && c2.solvers[0].k_min.is_none());
    // ADMM splits on the rows: its φ does not fit eq. (11), and its certificate says why.
    let admm = &c.solvers[1];
    assert!(!admm.fits_eq11);
    assert!(
        admm.per_window
            .iter()
            .any(|p| p.premise.contains("surjective"))
    );
}

/// The linearisation of ADMM split on [I; G]z (ξ = (x, w, y)) reproduces K real steps where
/// no bound or row is active, like the other maps' (PG and FISTA with the exact projection
/// too: the projection is the identity there).
#[test]
fn linearisations_with_general_rows_match_brute_force() {
    use faer::Par;
    use iss_certificate::linear::linearise;
    use qp_iter::IterationMap;
    let s = constrained(false);
    for method in [Method::PG, Method::FISTA, Method::ADMM] {
        let o = options(&s, method, ControllerChoice::ExactMpc);
        let cl = crate::build(&s, &o).unwrap();
        let e = cl.estimator();
        let map = e.map(e.config().horizon).unwrap();
        assert!(map.problem().general().is_some());
        let lin = linearise(map, "MHE").unwrap();
        let (n, nt) = (map.problem().n(), map.problem().n_theta());
        let h = 1e-6;
        let mut st = map.new_state();
        for k in [1, 3, 12] {
            let km = lin.k_step(k, Par::Seq).unwrap();
            let (mut worst, mut scale) = (0.0f64, 0.0f64);
            for c in 0..n + nt {
                let (mut z0, mut theta) = (vec![0.0; n], vec![0.0; nt]);
                if c < n {
                    z0[c] = h;
                } else {
                    theta[c - n] = h;
                }
                map.load(&mut st, &theta);
                map.warm_start(&mut st, &z0, None);
                qp_iter::run_fixed(map, &mut st, k);
                let z = map.iterate(&st);
                for r in 0..n {
                    let col = if c < n {
                        km.g[(r, c)]
                    } else {
                        km.j[(r, c - n)]
                    };
                    worst = worst.max((z[r] / h - col).abs());
                    scale = scale.max(col.abs());
                }
            }
            assert!(
                worst <= 1e-7 * scale.max(1.0),
                "{method} K = {k}: {worst:e}"
            );
        }
    }
}
