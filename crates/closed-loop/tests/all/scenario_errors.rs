//! Bad scenario files: one test per kind of bad input, each checking the `key` the error
//! names, and the resource limits checked before anything large is allocated.

use crate::scenario::{BASE, assert_key, replacing, with};
use closed_loop::scenario::Scenario;
use lti_model::ModelError;

#[test]
fn malformed_toml() {
    assert_key("name = \"x\"\n[plant\na = 1", "<toml>", "line 2");
    assert_key("name = \"x\"\nname = \"y\"", "<toml>", "line 2");
    assert_key("", "name", "missing");
}

#[test]
fn unknown_keys() {
    assert_key(&with("", "colour = \"red\""), "colour", "unknown field");
    assert_key(&with("plant", "d = [[0.0]]"), "plant.d", "remove the key");
    assert_key(&with("mhe", "horizn = 4"), "mhe.horizn", "unknown field");
    assert_key(
        &with("mpc", "terminal_set = true"),
        "mpc.terminal_set",
        "unknown field",
    );
    assert_key(
        &with("simulation", "t0 = 0"),
        "simulation.t0",
        "unknown field",
    );
    assert_key(&with("noise", "sed = 1"), "noise.sed", "unknown field");
    assert_key(
        &with("sets", "inptu = { lower = [0], upper = [0] }"),
        "sets.inptu",
        "unknown field",
    );
    assert_key(
        &with("sets", "state = { lower = [0, 0], uper = [1, 1] }"),
        "sets.state.uper",
        "unknown field",
    );
    assert_key(
        &with("mhe", "q = { diag = [1, 1, 1] }"),
        "mhe.q.diag",
        "unknown field",
    );
    assert_key(&with("extra", "x = 1"), "extra", "unknown field");
}

#[test]
fn missing_sections_and_keys() {
    assert_key("name = \"x\"\n[mhe]\nhorizon = 1", "plant", "[plant]");
    assert_key(&BASE.replace("name = \"base\"", ""), "name", "required");
    assert_key(&replacing("c = ", ""), "plant.c", "required");
    assert_key(&replacing("a = ", ""), "plant.a", "required");
    assert_key(&replacing("b = ", ""), "plant.b", "required");
    assert_key(&replacing("horizon = 3", ""), "mhe.horizon", "required");
    assert_key(&replacing("eta = ", ""), "mhe.eta", "required");
    assert_key(
        &replacing("iterations = ", ""),
        "mhe.iterations",
        "required",
    );
    assert_key(&replacing("horizon = 5", ""), "mpc.horizon", "required");
    assert_key(&with("mhe", "q = {}"), "mhe.q.diagonal", "missing");
}

#[test]
fn wrong_matrix_shapes() {
    assert_key(
        &replacing("a = ", "a = [[0.9, 0.1, 0.0], [0.0, 0.8, 0.0]]"),
        "plant.a",
        "square",
    );
    assert_key(
        &replacing("a = ", "a = [[0.9, 0.1], [0.0]]"),
        "plant.a",
        "row 1 has 1 entries",
    );
    assert_key(&replacing("a = ", "a = []"), "plant.a", "non-empty");
    assert_key(
        &replacing("a = ", "a = 0.5"),
        "plant.a",
        "size of this matrix is not known",
    );
    assert_key(
        &replacing("b = ", "b = [[0.0], [1.0], [2.0]]"),
        "plant.b",
        "expected n_x = 2",
    );
    assert_key(
        &replacing("c = ", "c = [[1.0, 0.0, 0.0]]"),
        "plant.c",
        "expected n_y × 2",
    );
    assert_key(
        &replacing("c = ", "c = [1.0, 0.0]"),
        "plant.c",
        "element [0]",
    );
    assert_key(&with("plant", "e = [[1.0, 0.0]]"), "plant.e", "expected 2");
    assert_key(
        &with("plant", "f = { diagonal = [1, 1] }"),
        "plant.f",
        "1×1",
    );
    assert_key(
        &with("mhe", "q = [[1.0, 0.0], [0.0, 1.0]]"),
        "mhe.q",
        "expected 3×3",
    );
    assert_key(&with("mhe", "q = { diagonal = [1, 1] }"), "mhe.q", "3×3");
    assert_key(
        &with("mhe", "r = [[1.0, 0.0], [0.0, 1.0]]"),
        "mhe.r",
        "expected 1×1",
    );
    assert_key(&with("mhe", "p = [[1.0]]"), "mhe.p", "expected 2×2");
    assert_key(&with("mpc", "q = [[1.0]]"), "mpc.q", "expected 2×2");
    assert_key(&with("mpc", "r = { diagonal = [1, 1] }"), "mpc.r", "1×1");
    assert_key(
        &with("noise", "kind = \"gaussian\"\ncovariance = [[1.0]]"),
        "noise.covariance",
        "expected 3×3",
    );
    assert_key(&with("mhe", "q = \"identity\""), "mhe.q", "array of rows");
}

#[test]
fn non_finite_entries() {
    assert_key(
        &replacing("a = ", "a = [[nan, 0.1], [0.0, 0.8]]"),
        "plant.a",
        "entry (0, 0) is NaN",
    );
    assert_key(
        &replacing("b = ", "b = [[0.0], [inf]]"),
        "plant.b",
        "entry (1, 0) is inf",
    );
    assert_key(&replacing("c = ", "c = [[1.0, -inf]]"), "plant.c", "finite");
    assert_key(&with("mhe", "q = inf"), "mhe.q", "finite");
    assert_key(
        &with("mhe", "q = { diagonal = [1, nan, 1] }"),
        "mhe.q",
        "diagonal entry 1",
    );
    assert_key(
        &with("mpc", "q = [[1.0, 0.0], [0.0, nan]]"),
        "mpc.q",
        "finite",
    );
    assert_key(
        &replacing("x0 = ", "x0 = [1.0, nan]"),
        "simulation.x0",
        "finite",
    );
    assert_key(
        &with("simulation", "prior = [inf, 0]"),
        "simulation.prior",
        "finite",
    );
    assert_key(
        &with("mhe", "eta = nan").replace("eta = 0.8\n", ""),
        "mhe.eta",
        "[0, 1)",
    );
    assert_key(&with("noise", "scale = inf"), "noise.scale", "finite");
    assert_key(
        &with("sets", "state = { lower = [nan, 0], upper = [1, 1] }"),
        "sets.state",
        "nan",
    );
}

#[test]
fn weights_must_be_symmetric_positive_definite() {
    let nonsym = "q = [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]";
    assert_key(&with("mhe", nonsym), "mhe.q", "not symmetric");
    assert_key(&with("mhe", "r = -1.0"), "mhe.r", "not positive definite");
    assert_key(&with("mhe", "r = 0"), "mhe.r", "positive definite");
    assert_key(
        &with("mhe", "q = { diagonal = [1, -1, 1] }"),
        "mhe.q",
        "positive definite",
    );
    assert_key(
        &with("mhe", "p = [[1.0, 2.0], [2.0, 1.0]]"),
        "mhe.p",
        "positive definite",
    );
    assert_key(
        &with("mpc", "q = [[1.0, 2.0], [2.0, 1.0]]"),
        "mpc.q",
        "positive semidefinite",
    );
    assert_key(&with("mpc", "r = -0.1"), "mpc.r", "positive definite");
    assert_key(
        &with(
            "noise",
            "kind = \"gaussian\"\ncovariance = [[1, 0, 0], [0, 1, 0], [0, 1, 1]]",
        ),
        "noise.covariance",
        "symmetric",
    );
}

#[test]
fn scalar_ranges() {
    assert_key(&BASE.replace("eta = 0.8", "eta = 1.0"), "mhe.eta", "[0, 1)");
    assert_key(
        &BASE.replace("eta = 0.8", "eta = -0.1"),
        "mhe.eta",
        "[0, 1)",
    );
    assert_key(&BASE.replace("eta = 0.8", "eta = 1"), "mhe.eta", "[0, 1)");
    assert!(Scenario::from_toml_str(&BASE.replace("eta = 0.8", "eta = 0")).is_ok());
    assert_key(
        &BASE.replace("horizon = 3", "horizon = 0"),
        "mhe.horizon",
        "at least 1",
    );
    assert_key(
        &BASE.replace("horizon = 3", "horizon = -2"),
        "mhe.horizon",
        "invalid value",
    );
    assert_key(
        &BASE.replace("iterations = 20", "iterations = 0"),
        "mhe.iterations",
        "at least 1",
    );
    assert_key(
        &BASE.replace("horizon = 5", "horizon = 0"),
        "mpc.horizon",
        "at least 1",
    );
    assert_key(
        &BASE.replace("steps = 10", "steps = 0"),
        "simulation.steps",
        "at least 1",
    );
    assert_key(
        &BASE.replace("eta = 0.8", "eta = \"0.8\""),
        "mhe.eta",
        "invalid type",
    );
    assert_key(&with("noise", "scale = -1"), "noise.scale", "≥ 0");
    assert_key(&with("noise", "seed = -1"), "noise.seed", "invalid value");
}

#[test]
fn bad_boxes() {
    let inverted = "input = { lower = [1.0], upper = [-1.0] }";
    assert_key(
        &BASE.replace("input = { lower = [-1.0], upper = [1.0] }", inverted),
        "sets.input",
        "lower[0] = 1 > upper[0] = -1",
    );
    assert_key(
        &with("sets", "state = { lower = [-1, -1, -1], upper = 1 }"),
        "sets.state.lower",
        "expected 2",
    );
    assert_key(
        &with("sets", "state = { lower = [1, -1], upper = 2 }"),
        "sets.state",
        "origin",
    );
    assert_key(
        &with("sets", "state = { lower = [\"-infinite\", 0], upper = 1 }"),
        "sets.state.lower",
        "\"-inf\"",
    );
    assert_key(
        &with("sets", "output = { upper = -inf }"),
        "sets.output",
        "empty",
    );
    assert_key(
        &with("sets", "state = [0, 1]"),
        "sets.state",
        "invalid type",
    );
}

#[test]
fn bad_simulation_vectors() {
    assert_key(
        &BASE.replace("x0 = [1.0, -1.0]", "x0 = [1.0, -1.0, 0.0]"),
        "simulation.x0",
        "expected 2",
    );
    assert_key(
        &with("simulation", "prior = [1.0]"),
        "simulation.prior",
        "expected 2",
    );
    assert_key(
        &with("sets", "state = { lower = -0.5, upper = 0.5 }"),
        "simulation.x0",
        "outside sets.state",
    );
}

#[test]
fn bad_enumerations() {
    assert_key(
        &with("mhe", "solver = \"newton\""),
        "mhe.solver",
        "\"pg\", \"fista\", \"admm\"",
    );
    assert_key(
        &with("mhe", "method = \"PG\""),
        "mhe.method",
        "unknown method",
    );
    assert_key(
        &with("mhe", "warm_start = \"cold\""),
        "mhe.warm_start",
        "expected `paper` or `shifted`",
    );
    assert_key(
        &with("mpc", "terminal = \"none\""),
        "mpc.terminal",
        "`dare`",
    );
    assert_key(
        &with("noise", "kind = \"laplace\""),
        "noise.kind",
        "`uniform`, `gaussian`, `zero`",
    );
}

#[test]
fn inconsistent_noise() {
    assert_key(
        &with("noise", "kind = \"gaussian\""),
        "noise.covariance",
        "needs a covariance",
    );
    assert_key(
        &with("noise", "kind = \"uniform\"\ncovariance = 1.0"),
        "noise.covariance",
        "only used",
    );
    let unbounded = BASE.replace(
        "disturbance = { lower = -0.1, upper = 0.1 }",
        "disturbance = { upper = 0.1 }",
    );
    assert_key(&unbounded, "sets.disturbance", "finite bounds");
    assert_key(
        &format!("{unbounded}\n[noise]\nkind = \"uniform\""),
        "noise.kind",
        "finite bounds",
    );
    assert!(Scenario::from_toml_str(&format!("{unbounded}\n[noise]\nkind = \"zero\"")).is_ok());
}

#[test]
fn oversized_dimensions_are_refused_before_allocating() {
    let n = lti_model::spec::MAX_DIMENSION + 1;
    let ones = vec!["0.5"; n].join(", ");
    assert_key(
        &replacing("a = ", &format!("a = {{ diagonal = [{ones}] }}")),
        "plant.a",
        "maximum",
    );
    // n_y rows of C would make the default R = I an n_y × n_y matrix.
    let rows = vec!["[1.0, 0.0]"; n].join(", ");
    assert_key(
        &replacing("c = ", &format!("c = [{rows}]")),
        "plant.c",
        "n_y",
    );
}

#[test]
fn missing_file_names_the_file() {
    let err = Scenario::from_file("/nonexistent/scenario.toml").unwrap_err();
    match err {
        ModelError::Scenario { key, problem } => {
            assert_eq!(key, "<file>");
            assert!(problem.contains("/nonexistent/scenario.toml"), "{problem}");
        }
        other => panic!("{other:?}"),
    }
}

/// Resource limits are checked before anything large is allocated, each naming the key, the
/// estimate and the limit (issue 14: a 640 GB allocation, a 32 GB trace, a silent 90 s run,
/// an endless read).
#[test]
fn sizes_beyond_the_limits_are_refused_before_allocation() {
    assert_key(
        &replacing("horizon = 5", "horizon = 100000"),
        "mpc.horizon",
        "GiB",
    );
    // At η = 0.99 the window's conditioning allows M = 2000 (η^1999 = 1.9e-9), its size not.
    assert_key(
        &replacing("horizon = 3", "horizon = 2000").replace("eta = 0.8", "eta = 0.99"),
        "mhe.horizon",
        "GiB",
    );
    // At η = 0.8 a horizon of 10⁶ is refused for its conditioning first (findings.rs).
    assert_key(
        &replacing("horizon = 3", "horizon = 1000000"),
        "mhe.horizon",
        "condition number",
    );
    assert_key(
        &replacing("steps = 10", "steps = 1000000000"),
        "simulation.steps",
        "limit",
    );
    assert_key(
        &replacing("iterations = 20", "iterations = 4000000000"),
        "mhe.iterations",
        "limit",
    );
    // Just inside the limits still parses.
    assert!(Scenario::from_toml_str(&replacing("horizon = 5", "horizon = 200")).is_ok());
    assert!(Scenario::from_toml_str(&replacing("steps = 10", "steps = 100000")).is_ok());
}

#[test]
fn an_endless_or_huge_file_is_refused_not_read() {
    match Scenario::from_file("/dev/zero") {
        Err(ModelError::Scenario { key, problem }) => {
            assert_eq!(key, "<file>");
            assert!(problem.contains("MiB"), "{problem}");
        }
        other => panic!("{other:?}"),
    }
    let dir = std::env::temp_dir().join(format!("scenario-bytes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bin = dir.join("bin.toml");
    std::fs::write(&bin, [0xff, 0xfe, 0x00, 0x41]).unwrap();
    match Scenario::from_file(&bin) {
        Err(ModelError::Scenario { key, problem }) => {
            assert_eq!(key, "<file>");
            assert!(problem.contains("not UTF-8"), "{problem}");
        }
        other => panic!("{other:?}"),
    }
}
