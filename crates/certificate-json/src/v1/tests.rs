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
