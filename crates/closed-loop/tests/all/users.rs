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
