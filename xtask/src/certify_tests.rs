//! Unit tests of `cargo xtask certify` (P files, reports, the summary).

#![allow(clippy::unwrap_used)]

use super::*;
use crate::provenance::workspace_root;

fn case_study() -> PathBuf {
    workspace_root().join("scenarios/case-study.toml")
}

fn request(eta: Option<f64>, p_file: Option<PathBuf>) -> CertifyRequest {
    CertifyRequest {
        scenario: case_study(),
        eta,
        p_file,
        loop_methods: false,
        global_seconds: None,
    }
}

/// The case study certified with the computed P, once per test binary (two tests read it;
/// each certification is seconds in the test profile).
fn case_study_outcome() -> &'static Outcome {
    static OUTCOME: std::sync::OnceLock<Outcome> = std::sync::OnceLock::new();
    OUTCOME.get_or_init(|| certify(&request(None, None)).expect("the case study certifies"))
}

fn temp_path(name: &str) -> PathBuf {
    crate::test_dir::test_dir("certify", "scenarios").join(name)
}

/// Certifies a scenario given as text (written to a temporary file `name`).
fn certify_text(name: &str, text: &str) -> Outcome {
    let path = temp_path(name);
    std::fs::write(&path, text).unwrap();
    certify(&CertifyRequest {
        scenario: path,
        eta: None,
        p_file: None,
        loop_methods: false,
        global_seconds: None,
    })
    .unwrap()
}

fn mat(rows: &serde_json::Value) -> Mat<f64> {
    parse_p(rows).unwrap()
}

/// Rebuilds LMI (2) from the JSON alone (A, C, B̄, D̄, η, Q, R, P), as an outside tool
/// would, and returns its largest eigenvalue.
fn lmi_max_from_json(doc: &serde_json::Value) -> f64 {
    let sys = &doc["system"];
    let cert = &doc["certificate"];
    let (a, c, bb, db) = (
        mat(&sys["a"]),
        mat(&sys["c"]),
        mat(&sys["b_bar"]),
        mat(&sys["d_bar"]),
    );
    let (p, q, r) = (mat(&cert["p"]), mat(&cert["q"]), mat(&cert["r"]));
    let eta = cert["eta"].as_f64().unwrap();
    // Stack [A B̄] and [C D̄]: LMI = [A B̄]ᵀP[A B̄] − diag(ηP, Q) − [C D̄]ᵀR[C D̄].
    let (nx, nw) = (a.nrows(), bb.ncols());
    let ab = Mat::from_fn(nx, nx + nw, |i, j| {
        if j < nx { a[(i, j)] } else { bb[(i, j - nx)] }
    });
    let cd = Mat::from_fn(c.nrows(), nx + nw, |i, j| {
        if j < nx { c[(i, j)] } else { db[(i, j - nx)] }
    });
    let mut m = ab.transpose() * &p * &ab - cd.transpose() * &r * &cd;
    for i in 0..nx {
        for j in 0..nx {
            m[(i, j)] -= eta * p[(i, j)];
        }
    }
    for i in 0..nw {
        for j in 0..nw {
            m[(nx + i, nx + j)] -= q[(i, j)];
        }
    }
    let ev = m.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    ev.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn case_study_passes_and_json_verifies_independently() {
    let out = case_study_outcome();
    assert!(out.document.passed, "{}", out.summary);
    assert!(out.summary.ends_with("PASS"));
    let path = temp_path("cert.json");
    write_json(&out.document, &path).unwrap();
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(doc["format"], FORMAT);
    assert_eq!(doc["scenario"]["name"], "case-study");
    assert_eq!(doc["scenario"]["path"], "scenarios/case-study.toml");
    assert_eq!(doc["inputs"]["eta"], 0.8);
    assert_eq!(doc["certificate"]["eta"], 0.8);
    assert_eq!(doc["system"]["nw1"], 4);
    assert!(doc["provenance"]["git_revision"].is_string());
    let tol = doc["certificate"]["lmi_relative_tolerance"]
        .as_f64()
        .unwrap();
    let mu = doc["certificate"]["lmi_relative_violation"]
        .as_f64()
        .unwrap();
    assert!(mu <= tol, "μ = {mu:e} > τ = {tol:e}");
    let hi = lmi_max_from_json(&doc);
    // The maximal P makes LMI (2) tight: λmax(J) is zero up to rounding of its terms (O(1)).
    assert!(hi <= 1e-12, "LMI rebuilt from JSON has λmax = {hi:e}");
    // Issue 4: L_π certified ≥ L_π sampled, both in the JSON and the summary.
    let lpi = &doc["controller_lipschitz"];
    let enumerated = lpi["enumerated"].as_f64().unwrap();
    let sampled = lpi["sampled"]["estimate"].as_f64().unwrap();
    let bound_b = lpi["certified"]["first_block"].as_f64().unwrap();
    assert!(
        sampled > 0.0
            && sampled <= enumerated * (1.0 + 1e-9)
            && enumerated <= bound_b * (1.0 + 1e-12)
    );
    assert!(out.summary.contains("certified L_π") && out.summary.contains("sampled"));
    let reported = doc["certificate"]["lmi_max_eigenvalue"].as_f64().unwrap();
    assert!((hi - reported).abs() <= 1e-9, "{hi:e} vs {reported:e}");
    let p = mat(&doc["certificate"]["p"]);
    let (lo, _) = matrix::sym_extreme_eigenvalues("P", p.as_ref()).unwrap();
    assert!(lo > 0.0);

    // Feeding the certificate back as --p-file verifies the same P.
    let again = certify(&request(None, Some(path.clone()))).unwrap();
    assert!(again.document.passed, "{}", again.summary);
    assert!(again.document.inputs.p_source.starts_with("--p-file"));
    assert_eq!(again.check.certificate.as_ref().unwrap().method, "user");
}

#[test]
fn too_large_p_fails_with_eigenvalues() {
    let out = case_study_outcome();
    let p = &out.check.certificate.as_ref().unwrap().p;
    // The computed P is the maximal solution (ioss docs), so 2P violates LMI (2).
    let doubled: Vec<Vec<f64>> = p
        .iter()
        .map(|r| r.iter().map(|v| 2.0 * v).collect())
        .collect();
    let path = temp_path("p2.json");
    std::fs::write(
        &path,
        serde_json::to_string(&serde_json::json!({ "p": doubled })).unwrap(),
    )
    .unwrap();
    let out = certify(&request(None, Some(path))).unwrap();
    assert!(!out.document.passed);
    assert!(out.summary.ends_with("FAIL"), "{}", out.summary);
    let cert = out.check.certificate.as_ref().unwrap();
    assert!(
        cert.lmi_relative_violation
            .is_some_and(|mu| mu > cert.lmi_relative_tolerance)
    );
    assert!(cert.lmi_max_eigenvalue > 0.0);
    let failure = out.document.failure.as_ref().unwrap();
    assert!(failure.contains("violates LMI (2)"), "{failure}");
    assert!(failure.contains("--p-file"), "{failure}");
}

/// Issue 11 finding: P = 1e-12·I and 1e-9·I passed the absolute tolerance 1e-9 although
/// LMI (2) fails in ker C by a few per cent of P's own scale.
#[test]
fn scaled_down_identity_p_fails() {
    for scale in [1e-12, 1e-9] {
        let rows: Vec<Vec<f64>> = (0..4)
            .map(|i| (0..4).map(|j| if i == j { scale } else { 0.0 }).collect())
            .collect();
        let path = temp_path(&format!("p_scaled_{scale:e}.json"));
        std::fs::write(&path, serde_json::to_string(&rows).unwrap()).unwrap();
        let out = certify(&request(None, Some(path))).unwrap();
        assert!(!out.document.passed, "{}", out.summary);
        assert!(out.summary.ends_with("FAIL"));
        let cert = out.check.certificate.as_ref().unwrap();
        assert!(cert.lmi_max_eigenvalue > 0.0);
        // A violation of per-cent size relative to the LMI's terms, not rounding.
        assert!(
            cert.lmi_relative_violation.is_some_and(|mu| mu > 1e-3),
            "μ = {:?}",
            cert.lmi_relative_violation
        );
    }
}

#[test]
fn infeasible_eta_fails_with_hint() {
    // η = 0 is infeasible for the case study: for x ∈ ker C (3-dimensional) and w = 0,
    // LMI (2) would need ‖Ax‖²_P ≤ 0, i.e. A x = 0 on ker C, which A does not satisfy.
    let out = certify(&request(Some(0.0), None)).unwrap();
    assert!(!out.document.passed, "{}", out.summary);
    assert!(out.check.certificate.is_none());
    assert!(
        out.document
            .failure
            .as_ref()
            .unwrap()
            .contains("infeasible")
    );
    let hint = out.document.hint.as_ref().unwrap();
    assert!(hint.contains("smallest feasible η"), "{hint}");
    // One verdict: "infeasible" is never printed beside a smallest feasible η at or below
    // the requested one (feasibility is monotone in η).
    let eta_min: f64 = hint
        .split("≈ ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no η in the hint: {hint}"));
    assert!(eta_min > 0.0, "{hint}");
    assert_eq!(out.document.inputs.eta_source, "--eta");
}

#[test]
fn input_errors_are_errors() {
    let bad_eta = certify(&request(Some(1.0), None)).unwrap_err();
    assert!(format!("{bad_eta:#}").contains("[0, 1)"), "{bad_eta:#}");
    let missing = CertifyRequest {
        scenario: "/nonexistent.toml".into(),
        eta: None,
        p_file: None,
        loop_methods: false,
        global_seconds: None,
    };
    let e = certify(&missing).unwrap_err();
    assert!(format!("{e:#}").contains("<file>"), "{e:#}");
    let path = temp_path("p_wrong_shape.json");
    std::fs::write(&path, "[[1.0, 0.0], [0.0, 1.0]]").unwrap();
    let e = certify(&request(None, Some(path))).unwrap_err();
    assert!(format!("{e:#}").contains("n_x = 4"), "{e:#}");
    let path = temp_path("p_nonsym.json");
    std::fs::write(&path, "[[1,2,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]").unwrap();
    let e = certify(&request(None, Some(path))).unwrap_err();
    assert!(format!("{e:#}").contains("not symmetric"), "{e:#}");
}

/// Issue 11 finding: with noise entering some states only (E = diag(1, 1, 0, 1)) the
/// built-in P was refused; now it is computed (the maximal P) and passes.
#[test]
fn singular_e_gets_a_computed_p() {
    let text = std::fs::read_to_string(case_study()).unwrap().replace(
        "[sets]",
        "e = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]\n\n[sets]",
    );
    let out = certify_text("e1101.toml", &text);
    assert!(out.document.passed, "{}", out.summary);
    let cert = out.check.certificate.as_ref().unwrap();
    assert_eq!(cert.method, lti_model::ioss::METHOD_MAXIMAL);
    assert!(
        cert.lmi_relative_violation
            .is_some_and(|mu| mu <= cert.lmi_relative_tolerance)
    );
    assert_eq!(out.document.system.b_bar[2], vec![Some(0.0); 5]);
}

#[test]
fn no_mhe_section_needs_eta() {
    let path = temp_path("no-mhe.toml");
    std::fs::write(
        &path,
        "name = \"s\"\n[plant]\na = [[0.5]]\nb = [[1.0]]\nc = [[1.0]]\n",
    )
    .unwrap();
    let req = CertifyRequest {
        scenario: path.clone(),
        eta: None,
        p_file: None,
        loop_methods: false,
        global_seconds: None,
    };
    let e = certify(&req).unwrap_err();
    assert!(format!("{e:#}").contains("--eta"), "{e:#}");
    let out = certify(&CertifyRequest {
        eta: Some(0.5),
        ..req
    })
    .unwrap();
    assert!(out.document.passed, "{}", out.summary);
    assert_eq!(
        out.document.inputs.weights_source,
        "identity (no [mhe] section)"
    );
}

#[test]
fn p_file_forms() {
    let rows = serde_json::json!([[2.0, 0.0], [0.0, 3.0]]);
    let a = parse_p(&rows).unwrap();
    let b = parse_p(&serde_json::json!({ "p": rows })).unwrap();
    let c = parse_p(&serde_json::json!({ "certificate": { "p": rows } })).unwrap();
    assert_eq!(a, b);
    assert_eq!(a, c);
    assert_eq!(a[(1, 1)], 3.0);
    assert!(parse_p(&serde_json::json!({ "certificate": null })).is_err());
    assert!(parse_p(&serde_json::json!([[1.0, 2.0], [3.0]])).is_err());
    assert!(parse_p(&serde_json::json!([["a"]])).is_err());
    assert!(parse_p(&serde_json::json!(1.0)).is_err());
}

/// Issue 15 item 4: a state set never blocks the LMI (2) check: certify passes, and L_π
/// is reported void with the exact reason (the state rows of the MPC move with x̂).
#[test]
fn a_state_set_does_not_block_the_lmi_check() {
    let text = std::fs::read_to_string(workspace_root().join("scenarios/case-study-certified.toml"))
        .unwrap()
        .replace(
            "[sets]\n",
            "[sets]\nstate = { lower = [-20.0, -20.0, -20.0, -20.0], upper = [20.0, 20.0, 20.0, 20.0] }\n",
        );
    assert!(text.contains("state = {"));
    let out = certify_text("state-set.toml", &text);
    assert!(out.document.passed);
    let l_pi = out.check.controller_lipschitz.as_ref().unwrap();
    let why = l_pi.void_reason.unwrap();
    assert!(why.contains("state constraints"), "{why}");
    assert!(l_pi.l_pi().is_infinite());
    assert!(
        out.summary.contains("L_π (Assumption 3)")
            && out.summary.contains("void: the MPC has state constraints"),
        "{}",
        out.summary
    );
    assert!(out.summary.ends_with("PASS"));
}

/// A bad `--global-seconds` is refused by name before anything is computed.
#[test]
fn bad_global_budget_names_the_flag() {
    let mut req = request(None, None);
    req.loop_methods = true;
    req.global_seconds = Some(-1.0);
    let e = certify(&req).unwrap_err();
    assert!(format!("{e:#}").contains("--global-seconds"), "{e:#}");
}
