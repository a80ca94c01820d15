//! Scenario files: the shipped case study against design.md §4 and every accepted form (and
//! the helpers the other `scenario_*` modules share). One test per kind of bad input, each
//! checking the `key` the error names, is in `scenario_errors`; arbitrary edits in
//! `scenario_fuzz`.

use closed_loop::scenario::Scenario;
use faer::Mat;
use lti_model::spec::NoiseKind;
use lti_model::{ConvexSet, ModelError, ioss};
use mhe_core::WarmStart;
use mpc_core::settings::TerminalCost;
use qp_iter::Method;

pub(crate) const CASE_STUDY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../scenarios/case-study.toml"
);

/// A small valid scenario; tests splice their faulty line into it.
pub(crate) const BASE: &str = r#"
name = "base"
[plant]
a = [[0.9, 0.1], [0.0, 0.8]]
b = [[0.0], [1.0]]
c = [[1.0, 0.0]]
[sets]
input = { lower = [-1.0], upper = [1.0] }
disturbance = { lower = -0.1, upper = 0.1 }
[simulation]
x0 = [1.0, -1.0]
steps = 10
[mhe]
horizon = 3
eta = 0.8
iterations = 20
[mpc]
horizon = 5
"#;

/// `BASE` with `line` inserted right after the header `[section]` (or at the top for "").
pub(crate) fn with(section: &str, line: &str) -> String {
    if section.is_empty() {
        return format!("{line}\n{BASE}");
    }
    let header = format!("[{section}]\n");
    if BASE.contains(&header) {
        BASE.replacen(&header, &format!("{header}{line}\n"), 1)
    } else {
        format!("{BASE}\n{header}{line}\n")
    }
}

/// `BASE` with the line starting with `prefix` inside `[section]` replaced by `line`.
pub(crate) fn replacing(prefix: &str, line: &str) -> String {
    let out: Vec<String> = BASE
        .lines()
        .map(|l| {
            if l.starts_with(prefix) {
                line.to_string()
            } else {
                l.to_string()
            }
        })
        .collect();
    assert_ne!(
        out.join("\n"),
        BASE.trim_end(),
        "prefix {prefix:?} matched nothing"
    );
    out.join("\n")
}

/// Parses `text`, expects a scenario error, and returns (key, problem).
pub(crate) fn scenario_error(text: &str) -> (String, String) {
    match Scenario::from_toml_str(text) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(ModelError::Scenario { key, problem }) => {
            // Display names the key too.
            let shown = ModelError::Scenario {
                key: key.clone(),
                problem: problem.clone(),
            }
            .to_string();
            assert!(shown.contains(&key), "{shown}");
            (key, problem)
        }
        Err(other) => panic!("expected ModelError::Scenario, got {other:?}"),
    }
}

pub(crate) fn assert_key(text: &str, expected_key: &str, problem_contains: &str) {
    let (key, problem) = scenario_error(text);
    assert_eq!(key, expected_key, "problem: {problem}");
    assert!(
        problem
            .to_lowercase()
            .contains(&problem_contains.to_lowercase()),
        "problem for `{key}` should mention {problem_contains:?}: {problem}"
    );
}

pub(crate) fn assert_mat(m: &Mat<f64>, rows: &[&[f64]]) {
    assert_eq!((m.nrows(), m.ncols()), (rows.len(), rows[0].len()));
    for (i, r) in rows.iter().enumerate() {
        for (j, v) in r.iter().enumerate() {
            assert_eq!(m[(i, j)], *v, "entry ({i}, {j})");
        }
    }
}

pub(crate) fn identity(n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect()
}

pub(crate) fn assert_mat_vec(m: &Mat<f64>, rows: &[Vec<f64>]) {
    let refs: Vec<&[f64]> = rows.iter().map(Vec::as_slice).collect();
    assert_mat(m, &refs);
}

// ---------------------------------------------------------------------------------------
// The shipped case study
// ---------------------------------------------------------------------------------------

#[test]
fn case_study_matches_design_section_4() {
    let s = Scenario::from_file(CASE_STUDY).unwrap();
    assert_eq!(s.name, "case-study");
    let p = &s.plant;
    assert_eq!((p.nx(), p.nu(), p.ny(), p.nw1(), p.nw2()), (4, 2, 1, 4, 1));
    assert_mat(
        &p.a().to_owned(),
        &[
            &[0.7, -0.1, 0.0, 0.0],
            &[0.2, -0.5, 0.1, 0.0],
            &[0.0, 0.1, 0.1, 0.0],
            &[0.5, 0.0, 0.5, 0.5],
        ],
    );
    assert_mat(
        &p.b().to_owned(),
        &[&[0.0, 0.1], &[0.1, 1.0], &[0.1, 0.0], &[0.0, 0.0]],
    );
    assert_mat(&p.c().to_owned(), &[&[0.1, 0.3, 0.8, 0.5]]);
    assert_mat_vec(&p.e().to_owned(), &identity(4));
    assert_mat_vec(&p.f().to_owned(), &identity(1));

    assert!(s.sets.state.is_whole() && s.sets.state.lower().len() == 4);
    assert!(s.sets.output.is_whole() && s.sets.output.lower().len() == 1);
    assert_eq!(
        (s.sets.input.lower(), s.sets.input.upper()),
        (&[-1.0, -1.0][..], &[1.0, 1.0][..])
    );
    assert_eq!(s.sets.disturbance.lower(), &[-0.1; 5]);
    assert_eq!(s.sets.disturbance.upper(), &[0.1; 5]);

    assert_eq!(s.noise.kind, NoiseKind::Uniform);
    assert_eq!(s.noise.scale, 1.0);
    assert!(s.noise.covariance.is_none());
    assert_eq!(s.simulation.x0, vec![12.0, -10.0, 10.0, -10.0]);
    assert_eq!(s.simulation.prior, vec![7.0, -7.0, 3.0, -5.0]);
    assert_eq!(s.simulation.steps, 40);

    let mhe = s.mhe.as_ref().unwrap();
    assert_eq!(
        (mhe.horizon(), mhe.eta(), mhe.iterations().get()),
        (5, 0.8, 652)
    );
    assert_mat_vec(mhe.q(), &identity(5));
    assert_mat(mhe.r(), &[&[1.0]]);
    assert!(mhe.p().is_none());
    assert_eq!(
        (mhe.method(), mhe.warm_start()),
        (Method::PG, WarmStart::Paper)
    );

    let mpc = s.mpc.as_ref().unwrap();
    assert_eq!((mpc.horizon(), mpc.terminal()), (10, TerminalCost::Dare));
    assert_mat_vec(mpc.q(), &identity(4));
    assert_mat(mpc.r(), &[&[0.1, 0.0], &[0.0, 0.1]]);

    // The file says it is a stand-in, and the run can record the verbatim text.
    let src = s.source.as_deref().unwrap();
    assert!(src.contains("STAND-IN"));
    assert!(s.description.as_deref().unwrap().starts_with("Stand-in"));
}

/// LMI (2) assembled here from its blocks (not through `ioss::lmi_matrix`).
fn lmi_by_blocks(s: &Scenario, p: &Mat<f64>) -> Mat<f64> {
    let sys = &s.plant;
    let mhe = s.mhe.as_ref().unwrap();
    let (a, c) = (sys.a().to_owned(), sys.c().to_owned());
    let (bb, db) = (sys.b_bar(), sys.d_bar());
    let (q, r, eta) = (mhe.q(), mhe.r(), mhe.eta());
    let m11 = a.transpose() * p * &a - p * eta - c.transpose() * r * &c;
    let m12 = a.transpose() * p * &bb - c.transpose() * r * &db;
    let m22 = bb.transpose() * p * &bb - q - db.transpose() * r * &db;
    let (nx, nw) = (sys.nx(), sys.nw());
    Mat::from_fn(nx + nw, nx + nw, |i, j| match (i < nx, j < nx) {
        (true, true) => m11[(i, j)],
        (true, false) => m12[(i, j - nx)],
        (false, true) => m12[(j, i - nx)],
        (false, false) => m22[(i - nx, j - nx)],
    })
}

#[test]
fn case_study_certificate_satisfies_lmi_2() {
    let s = Scenario::from_file(CASE_STUDY).unwrap();
    let mhe = s.mhe.as_ref().unwrap();
    let cert = ioss::certify(&s.plant, mhe.eta(), mhe.q().as_ref(), mhe.r().as_ref()).unwrap();
    assert!(cert.p_min_eigenvalue > 0.0);
    assert!(
        cert.lmi_max_eigenvalue <= 1e-9,
        "{}",
        cert.lmi_max_eigenvalue
    );
    let m = lmi_by_blocks(&s, &cert.p);
    let (_, hi) = lti_model::matrix::sym_extreme_eigenvalues("LMI", m.as_ref()).unwrap();
    assert!(hi <= 1e-9, "independently assembled LMI has λmax = {hi:e}");
    assert!((hi - cert.lmi_max_eigenvalue).abs() <= 1e-9 * (1.0 + hi.abs()));
}

#[test]
fn canonical_toml_round_trips() {
    for text in [
        std::fs::read_to_string(CASE_STUDY).unwrap(),
        BASE.to_string(),
    ] {
        let s = Scenario::from_toml_str(&text).unwrap();
        let canon = s.to_toml_string().unwrap();
        let t = Scenario::from_toml_str(&canon).unwrap_or_else(|e| panic!("{e}\n{canon}"));
        assert_eq!(t.name, s.name);
        assert_eq!(t.description, s.description);
        assert_eq!(t.plant.a(), s.plant.a());
        assert_eq!(t.plant.b(), s.plant.b());
        assert_eq!(t.plant.c(), s.plant.c());
        assert_eq!(t.plant.e(), s.plant.e());
        assert_eq!(t.plant.f(), s.plant.f());
        assert_eq!(t.sets, s.sets);
        assert_eq!(
            (t.noise.kind, t.noise.scale, t.noise.seed),
            (s.noise.kind, s.noise.scale, s.noise.seed)
        );
        assert_eq!(t.simulation, s.simulation);
        let (a, b) = (t.mhe.unwrap(), s.mhe.unwrap());
        assert_eq!(
            (
                a.horizon(),
                a.eta(),
                a.iterations(),
                a.method(),
                a.warm_start()
            ),
            (
                b.horizon(),
                b.eta(),
                b.iterations(),
                b.method(),
                b.warm_start()
            )
        );
        assert_eq!((a.q(), a.r()), (b.q(), b.r()));
        let (a, b) = (t.mpc.unwrap(), s.mpc.unwrap());
        assert_eq!(
            (a.horizon(), a.q(), a.r(), a.terminal()),
            (b.horizon(), b.q(), b.r(), b.terminal())
        );
        // Canonical text is a fixed point.
        assert_eq!(
            Scenario::from_toml_str(&canon)
                .unwrap()
                .to_toml_string()
                .unwrap(),
            canon
        );
    }
}

// ---------------------------------------------------------------------------------------
// Accepted forms and defaults
// ---------------------------------------------------------------------------------------

#[test]
fn matrix_forms_agree() {
    let rows = with(
        "mhe",
        "q = [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]",
    );
    let scalar = with("mhe", "q = 2");
    let diag = with("mhe", "q = { diagonal = [2, 2.0, 2] }");
    let qs: Vec<Mat<f64>> = [rows, scalar, diag]
        .iter()
        .map(|t| Scenario::from_toml_str(t).unwrap().mhe.unwrap().q().clone())
        .collect();
    assert_eq!(qs[0], qs[1]);
    assert_eq!(qs[0], qs[2]);
    assert_eq!(qs[0][(1, 1)], 2.0);
}

#[test]
fn defaults_are_documented_values() {
    let s = Scenario::from_toml_str(BASE).unwrap();
    assert_eq!(s.plant.nw(), 3); // E = I₂, F = I₁
    let mhe = s.mhe.unwrap();
    assert_mat_vec(mhe.q(), &identity(3));
    assert_mat(mhe.r(), &[&[1.0]]);
    assert_eq!(
        (mhe.method(), mhe.warm_start()),
        (Method::PG, WarmStart::Paper)
    );
    let mpc = s.mpc.unwrap();
    assert_mat_vec(mpc.q(), &identity(2));
    assert_mat(mpc.r(), &[&[1.0]]);
    assert_eq!(mpc.terminal(), TerminalCost::Dare);
    // No [noise] but a disturbance box: uniform on it, seed 0.
    assert_eq!(
        (s.noise.kind, s.noise.scale, s.noise.seed),
        (NoiseKind::Uniform, 1.0, 0)
    );
    assert_eq!(s.simulation.prior, vec![0.0, 0.0]);

    // Minimal file: no sets, no noise, no simulation, no mhe/mpc.
    let s = Scenario::from_toml_str("name = \"m\"\n[plant]\na = [[0.5]]\nb = [[1.0]]\nc = [[1.0]]")
        .unwrap();
    assert!(s.sets.state.is_whole() && s.sets.input.is_whole() && s.sets.disturbance.is_whole());
    assert_eq!(s.noise.kind, NoiseKind::Zero);
    assert_eq!(s.simulation.x0, vec![0.0]);
    assert_eq!(s.simulation.steps, lti_model::spec::DEFAULT_STEPS);
    assert!(s.mhe.is_none() && s.mpc.is_none());
}

#[test]
fn infinite_bounds_and_broadcast() {
    let text = with(
        "sets",
        "state = { lower = [\"-inf\", -inf], upper = [\"inf\", 5] }\noutput = { upper = 3 }",
    );
    let s = Scenario::from_toml_str(&text).unwrap();
    assert_eq!(s.sets.state.lower(), &[f64::NEG_INFINITY; 2]);
    assert_eq!(s.sets.state.upper(), &[f64::INFINITY, 5.0]);
    assert_eq!(
        (s.sets.output.lower(), s.sets.output.upper()),
        (&[f64::NEG_INFINITY][..], &[3.0][..])
    );
    assert_eq!(s.sets.disturbance.upper(), &[0.1; 3]);
    assert!(s.sets.state.contains(&[-1e300, 4.0], 0.0));
}

#[test]
fn custom_disturbance_matrices_change_nw() {
    // E is 2×1 (one process disturbance), F = 0.5·I₁: n_w = 2, so Q must be 2×2.
    let text = with("plant", "e = [[0.0], [1.0]]\nf = 0.5").replace(
        "disturbance = { lower = -0.1, upper = 0.1 }",
        "disturbance = { lower = [-0.2, -0.1], upper = [0.2, 0.1] }",
    );
    let s = Scenario::from_toml_str(&text).unwrap();
    assert_eq!((s.plant.nw1(), s.plant.nw2()), (1, 1));
    assert_eq!(s.plant.f()[(0, 0)], 0.5);
    assert_eq!(s.mhe.unwrap().q().nrows(), 2);
    assert_key(
        &format!("{text}\n").replace(
            "eta = 0.8",
            "eta = 0.8\nq = 1.0\nr = [[1.0, 0.0], [0.0, 1.0]]",
        ),
        "mhe.r",
        "expected 1×1",
    );
}

#[test]
fn gaussian_noise() {
    let text = with(
        "noise",
        "kind = \"gaussian\"\nscale = 0.5\ncovariance = { diagonal = [1, 2, 3] }\nseed = 7",
    );
    let s = Scenario::from_toml_str(&text).unwrap();
    assert_eq!((s.noise.kind, s.noise.seed), (NoiseKind::Gaussian, 7));
    let cov = s.noise.scaled_covariance().unwrap();
    assert_mat(
        &cov,
        &[&[0.25, 0.0, 0.0], &[0.0, 0.5, 0.0], &[0.0, 0.0, 0.75]],
    );
    assert!(s.noise.uniform_box(&s.sets.disturbance).is_none());
    let u = Scenario::from_toml_str(&with("noise", "scale = 2.0")).unwrap();
    let (lo, hi) = u.noise.uniform_box(&u.sets.disturbance).unwrap();
    assert_eq!((lo, hi), (vec![-0.2; 3], vec![0.2; 3]));
}

#[test]
fn preset_plant_matches_the_shipped_scenarios() {
    let preset = lti_model::presets::case_study_plant();
    for file in ["case-study.toml", "case-study-certified.toml"] {
        let path = format!("{}/../../scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
        let s = Scenario::from_file(&path).unwrap();
        for (a, b) in [
            (preset.a(), s.plant.a()),
            (preset.b(), s.plant.b()),
            (preset.c(), s.plant.c()),
        ] {
            assert_eq!(a.to_owned(), b.to_owned(), "{file}");
        }
    }
}

#[test]
fn a_method_with_parameters_is_read_from_a_table() {
    let s = Scenario::from_toml_str(&with(
        "mhe",
        "method = { method = \"admm\", rho = 2.0, alpha = 1.5 }",
    ))
    .unwrap();
    assert_eq!(
        s.mhe.unwrap().method(),
        Method::admm(Some(2.0), 1.5).unwrap()
    );
    assert_key(
        &with("mhe", "method = { method = \"pg\", rho = 2.0 }"),
        "mhe.method",
        "`rho` is not a parameter of `pg`",
    );
}

#[test]
fn sample_time_is_optional_positive_and_finite() {
    let none = Scenario::from_toml_str(BASE).expect("base parses");
    assert_eq!(none.sample_time, None);
    let s = Scenario::from_toml_str(&with("plant", "sample_time = 0.02")).expect("valid T_s");
    assert_eq!(s.sample_time, Some(0.02));
    // Written back and parsed again: the same period.
    let again = Scenario::from_toml_str(&s.to_toml_string().expect("serialises")).expect("parses");
    assert_eq!(again.sample_time, Some(0.02));
    for bad in ["0.0", "-0.02", "nan", "inf", "1e9"] {
        assert_key(
            &with("plant", &format!("sample_time = {bad}")),
            "plant.sample_time",
            "sample period T_s in seconds",
        );
    }
    // The shipped cart-pendulum runs at 20 ms (its ZOH period).
    let cart = Scenario::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/cart-pendulum.toml"
    ))
    .expect("cart-pendulum parses");
    assert_eq!(cart.sample_time, Some(0.02));
}
