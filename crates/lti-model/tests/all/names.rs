//! `lti_model::spec::names`: a file key in an error becomes the Rust field that set it.

use lti_model::ModelError;
use lti_model::spec::key_error;
use lti_model::spec::names::{rust_field, rust_text};

const T: [(&str, &str); 3] = [
    ("mhe.p", "MheBuilder::p"),
    ("sets.input", "LoopModelBuilder::input_box"),
    ("[mhe]", "the MHE"),
];

#[test]
fn keys_are_replaced_whole_and_by_the_longest_match() {
    assert_eq!(rust_field("mhe.p", &[&T]), "MheBuilder::p");
    assert_eq!(
        rust_field("sets.input.lower", &[&T]),
        "LoopModelBuilder::input_box.lower"
    );
    assert_eq!(rust_field("mhe.prior", &[&T]), "mhe.prior");
    let later = [("mhe.p", "the prior weight")];
    assert_eq!(rust_field("mhe.p", &[&T, &later]), "MheBuilder::p");
    assert_eq!(rust_field("mhe.p", &[&later, &T]), "the prior weight");
    assert_eq!(
        rust_text("`mhe.p` and `mhe.prior` in [mhe]", &[&T]),
        "`MheBuilder::p` and `mhe.prior` in the MHE"
    );
    assert_eq!(
        rust_text("is required but missing; add it, e.g. `horizon = 5`", &[&T]),
        "is required but missing; add it, e.g. `.horizon(5)`"
    );
}

#[test]
fn a_scenario_error_becomes_invalid_and_others_keep_their_kind() {
    let e = key_error(
        "mhe.p",
        "is not positive definite (a positive number s gives s·I)",
    );
    assert_eq!(
        e.for_rust(&[&T]),
        ModelError::Invalid {
            field: "MheBuilder::p".into(),
            problem: "is not positive definite".into()
        }
    );
    let e = ModelError::NotSymmetric {
        name: "mhe.p".into(),
        asymmetry: 1.0,
    };
    assert_eq!(
        e.for_rust(&[&T]),
        ModelError::NotSymmetric {
            name: "MheBuilder::p".into(),
            asymmetry: 1.0
        }
    );
    let e = ModelError::Numerical {
        routine: "DARE".into(),
        reason: "mhe.p".into(),
    };
    assert_eq!(e.clone().for_rust(&[&T]), e);
}
