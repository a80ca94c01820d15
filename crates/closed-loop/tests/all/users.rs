//! Issue 25, item 5: the MPC and the noise users bring — a PSD `mpc.q`, output rows of the
//! MPC (`mpc.output`), and the simulated noise model separate from 𝒲.

use closed_loop::certificate::{CertificateOptions, Gamma13Source};
use closed_loop::scenario::{ControllerChoice, LoopOptions, Scenario};
use qp_iter::Method;

const CASE_STUDY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../scenarios/case-study.toml"
);

fn case_study_with(section: &str, extra: &str) -> String {
    let text = std::fs::read_to_string(CASE_STUDY).unwrap();
    text.replace(
        &format!("[{section}]\n"),
        &format!("[{section}]\n{extra}\n"),
    )
}

#[test]
fn mpc_output_rows_reach_the_mpc_and_void_l_pi_and_gamma13_by_name() {
    let s = Scenario::from_toml_str(&case_study_with(
        "mpc",
        "output = { lower = -4.0, upper = 4.0 }",
    ))
    .unwrap();
    // Round trip through the canonical TOML keeps the key.
    let again = Scenario::from_toml_str(&s.to_toml_string().unwrap()).unwrap();
    assert!(again.mpc.as_ref().unwrap().output.is_some());
    let resolved = s.clone().resolve().unwrap();
    let mpc = resolved.mpc().unwrap();
    assert!(mpc.has_output_constraints() && !mpc.has_state_constraints());
    assert_eq!(mpc.qp().general().unwrap().m(), mpc.horizon());
    let opts = CertificateOptions {
        gamma13: Gamma13Source::Certified,
        gamma13_sequences: 0,
        lipschitz_pairs: 0,
        solvers: vec![Method::PG],
        ..CertificateOptions::default()
    };
    let c = crate::certify(&s, &opts).unwrap();
    assert_eq!(
        c.gamma13.void,
        Some(closed_loop::gamma13::Gamma13Void::OutputConstrainedMpc)
    );
    let all = c.solvers[0].void_reasons.join("\n");
    assert!(
        all.contains("L_π, γ₁,₃") && all.contains("mpc.output"),
        "{all}"
    );
    assert!(c.solvers[0].k_min.is_none());
    // The closed loop runs with the output rows (exact MPC).
    let mut o = LoopOptions::from_scenario(&s).unwrap();
    o.method = Method::PG;
    o.iterations = 200;
    o.controller = ControllerChoice::ExactMpc;
    o.steps = 30;
    let mut cl = crate::build(&s, &o).unwrap();
    let trace = cl.run().unwrap();
    assert_eq!(trace.len(), 30);
}

#[test]
fn mpc_output_is_checked_against_the_plant() {
    let e = Scenario::from_toml_str(&case_study_with(
        "mpc",
        "output = { lower = [-4.0, -1.0], upper = [4.0, 1.0] }",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("mpc.output"), "{e}");
    let e = Scenario::from_toml_str(&case_study_with(
        "mpc",
        "output = { lower = 1.0, upper = 4.0 }",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("mpc.output") && e.contains("excludes 0"), "{e}");
}

#[test]
fn a_psd_mpc_q_is_accepted_exactly_when_detectable() {
    for diag in [
        "[1.0, 0.0, 0.0, 0.0]",
        "[0.0, 0.0, 0.0, 1.0]",
        "[0.0, 0.0, 0.0, 0.0]",
    ] {
        let text = case_study_with("mpc", "").replace(
            "q = 1.0            # Q_c = I₄",
            &format!("q = {{ diagonal = {diag} }}"),
        );
        let base = Scenario::from_toml_str(&std::fs::read_to_string(CASE_STUDY).unwrap()).unwrap();
        let d: Vec<f64> = diag
            .trim_matches(|c| c == '[' || c == ']')
            .split(',')
            .map(|v| v.trim().parse().unwrap())
            .collect();
        let q = faer::Mat::from_fn(4, 4, |i, j| if i == j { d[i] } else { 0.0 });
        let modes = mpc_core::detectable::undetectable_modes(base.plant.a(), q.as_ref()).unwrap();
        match Scenario::from_toml_str(&text) {
            Ok(s) => {
                assert!(modes.is_empty(), "{diag}: accepted with {modes:?}");
                let r = s.resolve().unwrap();
                assert_eq!(r.mpc().unwrap().q_c()[(1, 1)], 0.0);
            }
            Err(e) => {
                assert!(
                    !modes.is_empty(),
                    "{diag}: refused although detectable: {e}"
                );
                let e = e.to_string();
                assert!(e.contains("mpc.q") && e.contains("|λ|"), "{e}");
            }
        }
    }
}

/// The case study with its `[noise]` section replaced by `noise`.
fn with_noise(noise: &str) -> Result<Scenario, lti_model::ModelError> {
    let text = std::fs::read_to_string(CASE_STUDY).unwrap();
    let start = text.find("[noise]").unwrap();
    let end = text.find("[simulation]").unwrap();
    let text = format!("{}[noise]\n{noise}\n\n{}", &text[..start], &text[end..]);
    Scenario::from_toml_str(&text)
}

fn run(s: &Scenario, steps: usize) -> closed_loop::record::Trace {
    let mut o = LoopOptions::from_scenario(s).unwrap();
    o.steps = steps;
    o.controller = ControllerChoice::ExactMpc;
    let mut cl = crate::build(s, &o).unwrap();
    cl.run().unwrap().clone()
}

#[test]
fn truncated_normal_noise_is_seeded_bounded_and_counted_against_w() {
    // Rao–Rawlings–Lee-style nonnegative noise: N(0, 0.05²) truncated to [0, 0.2] per
    // component, while the MHE assumes 𝒲 = [−0.1, 0.1]⁵.
    let s = with_noise(
        "kind = \"truncated-normal\"\ncovariance = 0.0025\ntruncate = { lower = 0.0, upper = 0.2 }\nseed = 11",
    )
    .unwrap();
    assert!(s.noise.can_leave(&s.sets.disturbance));
    let (a, b) = (run(&s, 60), run(&s, 60));
    let w = &s.sets.disturbance;
    let mut above = 0;
    for t in 0..a.len() {
        assert_eq!(a.w(t), b.w(t), "seeded: t = {t}");
        for &v in a.w(t).unwrap() {
            assert!((0.0..=0.2).contains(&v), "t = {t}: {v}");
            above += usize::from(v > 0.1);
        }
    }
    let outside = closed_loop::scenario::draws_outside(&a, w);
    assert!(above > 0 && !outside.is_empty(), "{above} {outside:?}");
    // Every step with a component above 0.1 is counted, and only those.
    for t in 0..a.len() {
        let leaves = a.w(t).unwrap().iter().any(|v| *v > 0.1);
        assert_eq!(leaves, outside.contains(&t), "t = {t}");
    }
    // Truncated to 𝒲 itself (the default): nothing leaves.
    let inside = with_noise("kind = \"truncated-normal\"\ncovariance = 0.0025\nseed = 11").unwrap();
    assert!(!inside.noise.can_leave(&inside.sets.disturbance));
    assert!(closed_loop::scenario::draws_outside(&run(&inside, 60), w).is_empty());
    // The canonical TOML keeps the kind, the truncation and the mean.
    let again = Scenario::from_toml_str(&s.to_toml_string().unwrap()).unwrap();
    assert_eq!(again.noise.truncate, s.noise.truncate);
}

#[test]
fn a_mean_offset_shifts_the_draws_and_leaves_w() {
    let s = with_noise("kind = \"uniform\"\nmean = [0.05, 0.0, 0.0, 0.0, 0.0]\nseed = 3").unwrap();
    let t = run(&s, 80);
    let m: f64 = (0..t.len()).map(|k| t.w(k).unwrap()[0]).sum::<f64>() / t.len() as f64;
    // Uniform on [−0.05, 0.15]: mean 0.05, σ = 0.2/√12 ≈ 0.058, 5 standard errors ≈ 0.032.
    assert!((m - 0.05).abs() < 0.033, "{m}");
    assert!((0..t.len()).all(|k| (-0.05..=0.15).contains(&t.w(k).unwrap()[0])));
    let outside = closed_loop::scenario::draws_outside(&t, &s.sets.disturbance);
    assert!(
        !outside.is_empty() && outside.len() < t.len(),
        "{outside:?}"
    );
    // Gaussian with a mean; and the nominal scale 0 keeps the offset (w ≡ μ).
    let g = with_noise("kind = \"gaussian\"\ncovariance = 1e-4\nmean = 0.02\nseed = 3");
    assert!(g.is_err(), "a scalar mean is refused (n_w numbers)");
    let zero =
        with_noise("kind = \"uniform\"\nscale = 0.0\nmean = [0.2, 0.0, 0.0, 0.0, 0.0]").unwrap();
    let t = run(&zero, 5);
    assert!((0..5).all(|k| t.w(k).unwrap() == [0.2, 0.0, 0.0, 0.0, 0.0]));
    assert_eq!(
        closed_loop::scenario::draws_outside(&t, &zero.sets.disturbance).len(),
        5
    );
}

#[test]
fn noise_keys_are_validated_by_name() {
    let err = |noise: &str| with_noise(noise).unwrap_err().to_string();
    let e = err("kind = \"uniform\"\nmean = [0.1, 0.0]");
    assert!(e.contains("noise.mean") && e.contains("5"), "{e}");
    let e = err("kind = \"zero\"\nmean = [0.1, 0.0, 0.0, 0.0, 0.0]");
    assert!(e.contains("noise.mean"), "{e}");
    let e = err("kind = \"uniform\"\ntruncate = { lower = 0.0 }");
    assert!(e.contains("noise.truncate"), "{e}");
    let e = err("kind = \"truncated-normal\"");
    assert!(e.contains("noise.covariance"), "{e}");
    let e = err(
        "kind = \"truncated-normal\"\ncovariance = [[1, 0.5, 0, 0, 0], [0.5, 1, 0, 0, 0], [0, 0, 1, 0, 0], [0, 0, 0, 1, 0], [0, 0, 0, 0, 1]]",
    );
    assert!(
        e.contains("noise.covariance") && e.contains("diagonal"),
        "{e}"
    );
    let e = err(
        "kind = \"truncated-normal\"\ncovariance = 1.0\ntruncate = { lower = 0.0, upper = 0.0 }",
    );
    assert!(e.contains("noise.truncate"), "{e}");
}
