//! What `report` refuses before the certificate (which can take minutes): a scenario without
//! `[mpc]`, and a scenario K whose simulation is beyond the work limit. Both typed, both
//! naming the scenario key.

use closed_loop::scenario::Scenario;
use mhe_report::{Options, Quiet, ReportError, report};

/// The double integrator of the README, `[mpc]` appended by the tests that need it.
const PLANT: &str = r#"name = "double-integrator"
plant = { a = [[1.0, 0.1], [0.0, 1.0]], b = [[0.005], [0.1]], c = [[1.0, 0.0]] }
sets = { input = { lower = -1, upper = 1 }, disturbance = { lower = -0.01, upper = 0.01 } }
"#;

fn scenario(tail: &str) -> Scenario {
    Scenario::from_toml_str(&format!("{PLANT}{tail}")).expect("the test scenario parses")
}

#[test]
fn a_scenario_without_mpc_is_refused_by_name() {
    let s = scenario(
        "simulation = { x0 = [1.0, 0.0], steps = 60 }\n\
         mhe = { horizon = 10, eta = 0.8, iterations = 20 }\n",
    );
    let e = report(s, &Options::default(), &Quiet).expect_err("no [mpc]");
    assert!(
        matches!(e, ReportError::Scenario(_)),
        "a missing section is ReportError::Scenario: {e}"
    );
    assert!(e.to_string().contains("mpc"), "{e}");
}

#[test]
fn the_work_limit_is_checked_before_the_certificate() {
    let s = scenario(
        "simulation = { x0 = [1.0, 0.0], steps = 2000 }\n\
         mhe = { horizon = 10, eta = 0.8, iterations = 10000000 }\n\
         mpc = { horizon = 10 }\n",
    );
    let t0 = std::time::Instant::now();
    let e = report(s, &Options::default(), &Quiet).expect_err("2·10¹⁰ iterations");
    assert!(
        t0.elapsed().as_secs_f64() < 5.0,
        "refused before the certificate"
    );
    let ReportError::WorkLimit { work } = &e else {
        panic!("expected ReportError::WorkLimit, got {e}");
    };
    assert_eq!((work.k, work.steps), (10_000_000, 2000));
    let msg = e.to_string();
    for key in ["mhe.iterations = 10000000", "simulation.steps = 2000"] {
        assert!(msg.contains(key), "{msg}");
    }
}
