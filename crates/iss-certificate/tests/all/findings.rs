//! Issue 14 item 4: numerical failures are reported by the user's key and the fix, never by
//! an internal symbol (H, radius, …) alone. One test per finding of the issue.

use closed_loop::scenario::{LoopOptions, Scenario};
use closed_loop::sim::ClosedLoopError;
use lti_model::ModelError;
use mhe_core::{MheError, MheSettings};

const CASE_STUDY: &str = include_str!("../../../../scenarios/case-study.toml");

/// The case study with `from` replaced by `to` (which must occur).
fn case_study_with(from: &str, to: &str) -> String {
    assert!(CASE_STUDY.contains(from), "{from:?} not in the case study");
    CASE_STUDY.replacen(from, to, 1)
}

/// The (key, problem) of a scenario error, wherever it is wrapped.
fn key_problem(e: &ModelError) -> (String, String) {
    match e {
        ModelError::Scenario { key, problem } => (key.clone(), problem.clone()),
        other => panic!("expected a scenario error naming a key, got {other:?}"),
    }
}

fn key_problem_cl(e: &ClosedLoopError) -> (String, String) {
    match e {
        ClosedLoopError::Model(m) => key_problem(m),
        ClosedLoopError::Mhe(MheError::Model(m)) => key_problem(m),
        ClosedLoopError::Mpc(mpc_core::MpcError::Model(m)) => key_problem(m),
        other => panic!("expected a scenario error naming a key, got {other:?}"),
    }
}

fn assert_mentions(problem: &str, parts: &[&str]) {
    for p in parts {
        assert!(problem.contains(p), "{p:?} missing from: {problem}");
    }
}

/// Finding 1: B with 0 columns was reported as "`mpc.r` not positive definite".
#[test]
fn b_without_columns_names_plant_b_not_mpc_r() {
    let text = case_study_with(
        "b = [\n  [0.0, 0.1],\n  [0.1, 1.0],\n  [0.1, 0.0],\n  [0.0, 0.0],\n]",
        "b = [[], [], [], []]",
    )
    .replace("input = { lower = [-1.0, -1.0], upper = [1.0, 1.0] }", "");
    let (key, problem) = key_problem(&Scenario::from_toml_str(&text).unwrap_err());
    assert_eq!(key, "plant.b", "{problem}");
    assert_mentions(&problem, &["n_u = 0", "remove [mpc]"]);
}

/// Finding 2: x0 = [1e300, …] was reported as "parameter `radius` = inf is invalid".
#[test]
fn huge_initial_state_names_simulation_x0() {
    let text = case_study_with("x0 = [12.0, -10.0, 10.0, -10.0]", "x0 = [1e300, 0, 0, 0]");
    let (key, problem) = key_problem(&Scenario::from_toml_str(&text).unwrap_err());
    assert_eq!(key, "simulation.x0", "{problem}");
    assert_mentions(&problem, &["entry 0", "1.000e300", "1e100", "rescale"]);
}

/// Finding 3: a singular E gave "λ_min(P) = NaN … try a larger η". P is now computed for E
/// of any rank; when LMI (2) is infeasible the message names the scenario key to change.
#[test]
fn singular_e_resolves_and_an_infeasible_lmi_names_its_key() {
    let text = case_study_with("# e, f omitted", "e = { diagonal = [1, 1, 0, 1] }\n#");
    let resolved = Scenario::from_toml_str(&text).unwrap().resolve().unwrap();
    assert!(
        matches!(resolved.ioss(), Some(Ok(_))),
        "{:?}",
        resolved.ioss()
    );
    let opts = LoopOptions::from_scenario(resolved.scenario()).unwrap();
    resolved.build_loop(&opts).unwrap();

    // Not detectable (the unobservable mode has |λ| = 1.2): change C.
    let base = "name = \"x\"\n[plant]\nb = [[0.0], [1.0]]\nc = [[1.0, 0.0]]\n\
                e = { diagonal = [1, 0] }\n[mhe]\nhorizon = 2\neta = 0.8\niterations = 3\n\
                [mpc]\nhorizon = 2\n";
    let undetectable = base.replace("[plant]\n", "[plant]\na = [[0.5, 0.0], [0.0, 1.2]]\n");
    let resolved = Scenario::from_toml_str(&undetectable)
        .unwrap()
        .resolve()
        .unwrap();
    let msg = match resolved.ioss() {
        Some(Err(e)) => e.to_string(),
        other => panic!("expected an infeasible LMI, got {other:?}"),
    };
    assert_mentions(&msg, &["`plant.c`", "add a sensor"]);
    // Detectable, but the mode (|λ| = 0.95) is slower than √η = 0.894: raise η.
    let slow = base.replace("[plant]\n", "[plant]\na = [[0.5, 0.0], [0.0, 0.95]]\n");
    let resolved = Scenario::from_toml_str(&slow).unwrap().resolve().unwrap();
    let opts = LoopOptions::from_scenario(resolved.scenario()).unwrap();
    let err = resolved.build_loop(&opts).unwrap_err().to_string();
    assert_mentions(&err, &["`mhe.eta`", "η > 0.9025"]);
}

/// Finding 4: A₁₁ = 1e308 was reported as "(A, B) is not stabilizable … check B".
#[test]
fn huge_entry_of_a_names_plant_a_and_its_position() {
    let text = case_study_with("[0.7, -0.1, 0.0, 0.0]", "[0.7, -0.1, 0.0, 1e308]");
    let (key, problem) = key_problem(&Scenario::from_toml_str(&text).unwrap_err());
    assert_eq!(key, "plant.a", "{problem}");
    assert_mentions(&problem, &["entry (0, 3)", "1.000e308", "rescale"]);
    // The same for a scalar weight and a bound.
    let text = case_study_with("r = 0.1 ", "r = 1e101 ");
    assert_eq!(
        key_problem(&Scenario::from_toml_str(&text).unwrap_err()).0,
        "mpc.r"
    );
    let text = case_study_with("lower = [-1.0, -1.0]", "lower = [-1e200, -1.0]");
    let (key, problem) = key_problem(&Scenario::from_toml_str(&text).unwrap_err());
    assert_eq!(key, "sets.input.lower");
    assert_mentions(&problem, &["bound 0", "inf"]);
}

/// Finding 5 (MPC): A₄₄ = 50 gave "`H` is not positive definite; use a symmetric matrix"
/// (H is internal): the unstable A over `mpc.horizon` is named, with a horizon that works.
#[test]
fn unstable_a_over_the_mpc_horizon_names_plant_a_and_mpc_horizon() {
    let text = case_study_with("[0.5,  0.0, 0.5, 0.5]", "[0.5,  0.0, 0.5, 50]");
    let err = Scenario::from_toml_str(&text)
        .unwrap()
        .resolve()
        .unwrap_err();
    let (key, problem) = key_problem_cl(&err);
    assert_eq!(key, "plant.a", "{problem}");
    assert_mentions(
        &problem,
        &[
            "ρ(A) = 5.0000e1",
            "`mpc.horizon` = 10",
            "`mpc.horizon` ≤ 1",
            "`mpc.r`",
        ],
    );
    assert!(!problem.contains("`H`"), "{problem}");
}

/// Finding 5 (MHE): with the MPC fine (N = 1), A₄₄ = 50 gave "not strongly convex
/// (λ_min = 0.53) … use η > 0" at η = 0.8: now the unstable A over `mhe.horizon`.
#[test]
fn unstable_a_over_the_mhe_window_names_plant_a_and_mhe_horizon() {
    let text = case_study_with("[0.5,  0.0, 0.5, 0.5]", "[0.5,  0.0, 0.5, 50]")
        .replace("horizon = 10       # N", "horizon = 1");
    let resolved = Scenario::from_toml_str(&text).unwrap().resolve().unwrap();
    let opts = LoopOptions::from_scenario(resolved.scenario()).unwrap();
    let err = resolved.build_loop(&opts).unwrap_err();
    let (key, problem) = key_problem_cl(&err);
    assert_eq!(key, "plant.a", "{problem}");
    assert_mentions(
        &problem,
        &["ρ(A) = 5.0000e1", "`mhe.horizon` = 5", "`mhe.horizon` ≤ 1"],
    );
    assert!(!problem.contains("use η > 0"), "{problem}");
}

/// Finding 6: `mhe.horizon = 1000000` gave "window length 116 is not strongly convex … use
/// η > 0": the horizon, η and the condition number are named, before anything is built.
#[test]
fn long_horizon_names_mhe_horizon_eta_and_the_condition_number() {
    for (m, alternative) in [
        ("1000000", "no η < 1 makes M = 1000000 well conditioned"),
        ("130", "`mhe.eta` ≥ 0.8669 for this M"),
    ] {
        let text = case_study_with("horizon = 5        # M", &format!("horizon = {m}"));
        let (key, problem) = key_problem(&Scenario::from_toml_str(&text).unwrap_err());
        assert_eq!(key, "mhe.horizon", "{problem}");
        assert_mentions(
            &problem,
            &[
                "`mhe.eta` = 0.8",
                "condition number",
                "`mhe.horizon` ≤ 83",
                alternative,
            ],
        );
    }
    // A window that fails although η^(M−1) passes the bound checked at parse time (the
    // weights take the rest): named the same way when the window is built.
    let text = "name = \"x\"\n[plant]\na = [[0.5]]\nb = [[1.0]]\nc = [[1.0]]\n\
                [mhe]\nhorizon = 40\neta = 0.5\niterations = 2\nq = { diagonal = [1e3, 1] }\n\
                [mpc]\nhorizon = 2\n";
    let resolved = Scenario::from_toml_str(text).unwrap().resolve().unwrap();
    let opts = LoopOptions::from_scenario(resolved.scenario()).unwrap();
    let err = resolved.build_loop(&opts).unwrap_err();
    let (key, problem) = key_problem_cl(&err);
    assert_eq!(key, "mhe.horizon", "{problem}");
    assert_mentions(
        &problem,
        &["`mhe.eta` = 0.5", "λ_max/λ_min", "`mhe.horizon` ≤ 27"],
    );
}

/// The mapping itself: η = 0 names `mhe.eta`; well-scaled data with a singular window
/// names the weights; an unrelated error passes unchanged.
#[test]
fn window_failures_are_explained_by_key() {
    let sys =
        lti_model::LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]]).unwrap();
    let raw: mhe_core::RawMhe =
        lti_model::spec::format::parse("horizon = 1\neta = 0.0\niterations = 1").unwrap();
    let s = MheSettings::from_raw(&raw, &sys).unwrap();
    let e = MheError::NotStronglyConvex {
        window: 1,
        min_eigenvalue: 0.0,
        max_eigenvalue: 1.0,
    };
    match s.explain(&sys, e) {
        MheError::Model(ModelError::Scenario { key, problem }) => {
            assert_eq!(key, "mhe.eta");
            assert_mentions(&problem, &["use η > 0"]);
        }
        other => panic!("{other:?}"),
    }
    let s = s.to_builder().eta(0.8).build(&sys).unwrap();
    let e = MheError::NotStronglyConvex {
        window: 1,
        min_eigenvalue: 1e-14,
        max_eigenvalue: 10.0,
    };
    match s.explain(&sys, e) {
        MheError::Model(ModelError::Scenario { key, problem }) => {
            assert_eq!(key, "mhe.q");
            assert_mentions(
                &problem,
                &["`mhe.r`", "`plant.c`", "λ_max/λ_min = 1.000e15"],
            );
        }
        other => panic!("{other:?}"),
    }
    let other = MheError::OutOfRange {
        name: "horizon",
        value: 0.0,
        range: "≥ 1",
    };
    assert_eq!(s.explain(&sys, other.clone()), other);
}

/// Found by the generated-input tests: a plant with a 670 entry in A (ρ(A)^N ≈ 3e8 over
/// N = 3) whose MPC builds but whose L_π analysis fails its Cholesky; the certificate's
/// error used to name only "H (L_π certificate)", and the exact MPC solve failure named no
/// key. Both now name the scenario keys.
#[test]
fn an_ill_conditioned_mpc_names_its_keys_in_the_certificate_and_the_solve() {
    let s = Scenario::from_toml_str(include_str!("ill_conditioned_mpc.toml")).unwrap();
    let e = crate::certify(
        &s,
        &iss_certificate::certificate::CertificateOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("`plant.a`") && e.contains("`mpc.horizon`"),
        "{e}"
    );
    let solve = mpc_core::MpcError::Solver {
        status: "InsufficientProgress".into(),
    }
    .to_string();
    assert!(
        solve.contains("`plant.a`") && solve.contains("`mpc.r`"),
        "{solve}"
    );
}
