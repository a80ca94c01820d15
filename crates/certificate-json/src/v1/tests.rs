//! The encodings of v1 are today's (the golden files of `cargo xtask reproduce` pin whole
//! documents; these pin the pieces a library change could silently alter).

use super::*;
use iss_certificate::coverage;

fn json<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string(v).expect("a v1 record serialises")
}

#[test]
fn non_finite_numbers_are_null() {
    assert_eq!(num(1.5), Some(1.5));
    assert_eq!(num(f64::NAN), None);
    assert_eq!(num(f64::INFINITY), None);
    assert_eq!(json(&num(f64::NEG_INFINITY)), "null");
}

#[test]
fn unit_enums_are_snake_case_strings() {
    assert_eq!(
        json(&CertificateKind::from(&coverage::CertificateKind::Theorem1)),
        "\"theorem1\""
    );
    assert_eq!(
        json(&CertificateKind::from(&coverage::CertificateKind::Joint)),
        "\"joint\""
    );
    assert_eq!(
        json(&Certified::from(&coverage::Certified::NotComputed)),
        "\"not_computed\""
    );
    assert_eq!(
        json(&KSource::from(
            &iss_certificate::plan::KSource::ComputedKMin
        )),
        "\"computed_k_min\""
    );
    assert_eq!(
        json(&Signal::from(&closed_loop::bounded::Signal::Epsilon)),
        "\"epsilon\""
    );
}

#[test]
fn coverage_is_externally_tagged() {
    let c = coverage::Coverage::Covered(coverage::CertificateKind::Joint);
    assert_eq!(json(&Coverage::from(&c)), "{\"covered\":\"joint\"}");
    let why = coverage::Uncovered::ShiftedWarmStart;
    let u = coverage::Coverage::Uncovered(why.clone());
    assert_eq!(
        json(&Coverage::from(&u)),
        serde_json::json!({ "uncovered": why.to_string() }).to_string()
    );
}

#[test]
fn typed_reasons_are_their_sentences() {
    let r = iss_certificate::outcome::VoidReason::NoK { k_max: 7 };
    let v: String = r.to_string();
    assert_eq!(v, "no K ≤ 7 satisfies sg1 + sg2 + sg3 < 1 (ρ(Γ) < 1)");
}

#[test]
fn methods_are_spelled_as_in_the_scenario() {
    assert_eq!(json(&Method::from(&qp_iter::Method::PG)), "\"pg\"");
    assert_eq!(
        json(&Method::from(&qp_iter::Method::ADMM_PR)),
        "\"admm-pr\""
    );
}

/// The global loop record (`certify --loop`) reads back as it was written, for each kind of
/// outcome, and has the same keys whatever the verdict (a number that does not apply is
/// `null`).
#[test]
fn global_loop_records_round_trip() {
    use iss_certificate::lure::global_outcome::GlobalOutcome as G;
    let outcomes = [
        G::LinearUnstable { rho_lin: 1.05 },
        G::PhiBallBinds {
            phi_star: 0.13,
            k_max: 1000,
            phi_at_k_max: 0.5,
        },
        G::NotComputed {
            n_zeta: 126,
            estimate_seconds: 35.0,
            budget_seconds: 10.0,
        },
        G::Unsupported {
            reason: "mpc.iterations is set".into(),
        },
        G::UnstableWithBoundedInput {
            spectral_radius: 1.3134,
            unbounded_inputs: 0,
        },
    ];
    let verdicts = [
        "linear_unstable",
        "phi_ball_binds",
        "not_computed",
        "not_applicable",
        "impossible",
    ];
    let section = LoopSection {
        global_seconds: Some(10.0),
        elapsed_seconds: Some(1.5),
        methods: outcomes
            .iter()
            .map(|o| LoopMethod {
                method: "pg".into(),
                k_lin: Some(47),
                k_lin_note: None,
                theorem1_k_min: None,
                k_min_note: Some("void".into()),
                global: GlobalLoopOutcome::from(o),
                k_chain: Some(1),
                chain: Some("K_chain = 1 (K tried: 1)".into()),
            })
            .collect(),
    };
    let text = json(&section);
    let back: LoopSection = serde_json::from_str(&text).expect("reads back");
    assert_eq!(back, section);
    let mut keys = None;
    for (m, v) in section.methods.iter().zip(verdicts) {
        assert_eq!(m.global.verdict, v);
        let value = serde_json::to_value(&m.global).expect("a value");
        let k: Vec<String> = value
            .as_object()
            .expect("an object")
            .keys()
            .cloned()
            .collect();
        assert_eq!(keys.get_or_insert_with(|| k.clone()), &k);
    }
    assert_eq!(section.methods[0].global.rho_lin, Some(1.05));
    assert!(
        section.methods[2]
            .global
            .reason
            .contains("certificate.phase_seconds")
    );
}
