//! No panic on arbitrary edits of a valid scenario file.

use crate::scenario::CASE_STUDY;
use closed_loop::scenario::Scenario;
use lti_model::ModelError;
use proptest::prelude::*;

const TOKENS: &[&str] = &[
    "",
    "0",
    "-1",
    "1e400",
    "nan",
    "inf",
    "-inf",
    "\"inf\"",
    "[[1]]",
    "[]",
    "[[]]",
    "{}",
    "{ diagonal = [] }",
    "\"x\"",
    "[",
    "]",
    "=",
    "\n[plant]\n",
    "9223372036854775807",
    "-9223372036854775808",
    "true",
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Replacing any span of the case study by a token, or cutting it short, gives Ok or a
    /// scenario error, never a panic; a valid result stays internally consistent.
    #[test]
    fn edits_never_panic(start in 0usize..4000, len in 0usize..12, tok in 0usize..TOKENS.len(), cut in any::<bool>()) {
        let text = std::fs::read_to_string(CASE_STUDY).unwrap();
        let clamp = |i: usize| {
            let mut i = i.min(text.len());
            while !text.is_char_boundary(i) { i -= 1; }
            i
        };
        let (a, b) = (clamp(start), clamp(start + len));
        let edited = if cut { text[..a].to_string() } else { format!("{}{}{}", &text[..a], TOKENS[tok], &text[b..]) };
        match Scenario::from_toml_str(&edited) {
            Ok(s) => {
                prop_assert_eq!(s.simulation.x0.len(), s.plant.nx());
                prop_assert_eq!(s.sets.disturbance.lower().len(), s.plant.nw());
                if let Some(m) = &s.mhe { prop_assert_eq!(m.q().nrows(), s.plant.nw()); }
            }
            Err(ModelError::Scenario { key, problem }) => {
                prop_assert!(!key.is_empty() && !problem.is_empty());
            }
            Err(other) => prop_assert!(false, "non-scenario error {:?}", other),
        }
    }
}
