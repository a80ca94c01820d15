//! The global loop certificate in f32 and f64 (issue 36; docs/theory.md §4, "The global
//! loop certificate in a given precision"): the estimator's rounding folded into the one LMI.
//! Its 200-seed runs with `mhe_embedded` in f32 in the loop are tests/f32_seeds/global.rs
//! (the loop_level binary, run by .ci/run in release).

use closed_loop::scenario::Scenario;
use iss_certificate::lure::global::{
    GlobalOptions, PrecisionVoid, certify_precision, global_loop, loop_rounding,
};
use qp_iter::Method;
use qp_iter::rounding::{F32_UNIT_ROUNDOFF, F64_UNIT_ROUNDOFF};

fn scenario(file: &str) -> Scenario {
    let path = format!("{}/../../scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
    Scenario::from_file(&path).expect("scenario parses")
}

use crate::loop_options as options;

use crate::ALL_METHODS as METHODS;

/// The table of docs/theory.md: per method, K_glob exact / f64 / f32 (or the reason).
#[test]
#[ignore = "measurement (release): a few minutes"]
fn measure_k_glob_per_precision() {
    let file =
        std::env::var("GLOBAL_SCENARIOS").unwrap_or_else(|_| "double-integrator.toml".into());
    let opts = GlobalOptions {
        tau_points: 5,
        ..GlobalOptions::default()
    };
    // GLOBAL_METHODS=pg,pg-jacobi: only those (default: all eight).
    let only = std::env::var("GLOBAL_METHODS").ok();
    for file in file.split(',') {
        let r = scenario(file).resolve().expect("resolves");
        for m in METHODS {
            if only
                .as_ref()
                .is_some_and(|o| !o.split(',').any(|n| n == m.name()))
            {
                continue;
            }
            let o = options(&r, m);
            let t0 = std::time::Instant::now();
            let gl = match global_loop(&r, &o) {
                Ok(g) => g,
                Err(e) => {
                    eprintln!("| {file} | {} | refused: {e} |", m.name());
                    continue;
                }
            };
            // Uncovered methods need no φ*: the reason comes first.
            if let Err(why) = loop_rounding(&r, &o, F32_UNIT_ROUNDOFF).expect("builds") {
                eprintln!("| {file} | {} | f32: {why} |", m.name());
                continue;
            }
            let exact = gl.phi_star(&opts);
            for (name, u) in [("f64", F64_UNIT_ROUNDOFF), ("f32", F32_UNIT_ROUNDOFF)] {
                let p = certify_precision(&r, &o, &gl, exact.as_ref(), u, &opts).expect("builds");
                let rd = p.rounding.as_ref();
                eprintln!(
                    "| {file} | {} | {name} | exact K {:?} | K {:?} | φ* {:?} | φ*_u {:?} | split {:?} | q {:?} r {:?} | β_z {:?} β_θ {:?} | ρ_z {:?} ρ_u {:?} | offset {:.3e} | ρ {:?} γ {:?} margin {:?} | {} | {:.1} s",
                    m.name(),
                    p.k_glob_exact,
                    p.k_glob,
                    exact.as_ref().map(|c| c.phi),
                    p.phi_star,
                    p.split,
                    rd.map(|r| r.perturbed_rate()),
                    rd.map(|r| r.steps.rate_and_rounding().0),
                    rd.map(|r| r.beta_z()),
                    rd.map(|r| r.beta_theta()),
                    rd.map(|r| r.propagation.from_z),
                    rd.map(|r| r.propagation.from_u),
                    p.offset(),
                    p.certificate.as_ref().map(|c| c.rho),
                    p.certificate.as_ref().map(|c| c.gamma),
                    p.certificate.as_ref().map(|c| c.margin),
                    p.reason
                        .as_ref()
                        .map(ToString::to_string)
                        .unwrap_or_default(),
                    t0.elapsed().as_secs_f64()
                );
            }
        }
    }
}

/// The double integrator with the MHE's measurement weight `r` (mhe.r).
fn double_integrator_with_r(r: &str) -> Scenario {
    let path = format!(
        "{}/../../scenarios/double-integrator.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(path).expect("reads");
    let text = text.replace("r = 1.0\niterations", &format!("r = {r}\niterations"));
    Scenario::from_toml_str(&text).expect("parses")
}

/// (ii) An ill-conditioned window: f32's rounding breaks PG's contraction (r + a ≥ 1), and
/// the certificate refuses f32 with that reason, naming the window; f64 still contracts.
#[test]
fn an_ill_conditioned_window_refuses_f32_with_the_reason() {
    let s = double_integrator_with_r("1e7");
    let r = s.resolve().expect("resolves");
    let o = options(&r, Method::PG);
    let f64r = loop_rounding(&r, &o, F64_UNIT_ROUNDOFF)
        .expect("builds")
        .expect("f64 contracts");
    let why = loop_rounding(&r, &o, F32_UNIT_ROUNDOFF)
        .expect("builds")
        .expect_err("f32 breaks the contraction");
    println!("f64: {f64r:?}\nf32: {why}");
    assert!(
        matches!(why, PrecisionVoid::ContractionBroken { window: 9, .. }),
        "{why:?}"
    );
    assert!(why.to_string().contains("window m = 9") && why.to_string().contains("u·κ(H)"));
    // The full certificate says the same, before any LMI is solved (no exact φ* needed).
    let gl = global_loop(&r, &o).expect("builds");
    let p = certify_precision(
        &r,
        &o,
        &gl,
        None,
        F32_UNIT_ROUNDOFF,
        &GlobalOptions::default(),
    )
    .expect("builds");
    assert!(p.k_glob.is_none());
    assert!(matches!(
        p.reason,
        Some(PrecisionVoid::ContractionBroken { .. })
    ));
    // ADMM has a rounding model (session 26), and on this window f32 breaks its contraction
    // too (its exact rate is within 10⁻⁵ of 1); the reason shows how close.
    let o = options(&r, Method::PRESETS[3]);
    let why = loop_rounding(&r, &o, F32_UNIT_ROUNDOFF)
        .expect("builds")
        .expect_err("f32 breaks ADMM's contraction");
    assert!(
        matches!(why, PrecisionVoid::ContractionBroken { window: 9, .. }),
        "{why:?}"
    );
    assert!(why.to_string().contains("1 − "), "{why}");
    // FISTA is not covered on this window: no incremental rate at its κ.
    let o = options(&r, Method::FISTA);
    let why = loop_rounding(&r, &o, F32_UNIT_ROUNDOFF)
        .expect("builds")
        .expect_err("not covered");
    assert!(why.to_string().contains("incremental rate"), "{why}");
}
