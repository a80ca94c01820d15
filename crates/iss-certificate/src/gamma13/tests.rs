//! Unit tests of the γ₁,₃ certificate (private helpers).

#![allow(clippy::unwrap_used)]

use faer::Mat;
use lti_model::{BoxSet, LtiSystem};
use mpc_core::MpcConfig;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;

/// A random 2-state MPC with a bounded input, |λ(A)| up to ~1.2 (s = 4).
fn random_mpc(seed: u64) -> Option<CondensedMpc> {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    let mut gauss = |a: usize, b: usize| Mat::from_fn(a, b, |_, _| r.random_range(-1.0..1.0));
    let (a, b, c) = (gauss(2, 2) * 1.2, gauss(2, 1), gauss(1, 2));
    let sys = LtiSystem::new(a, b, c).ok()?;
    let cfg = MpcConfig::new(
        4,
        Mat::identity(2, 2),
        Mat::<f64>::identity(1, 1) * 0.1,
        BoxSet::symmetric(&[1.0]).ok()?,
    );
    CondensedMpc::new(&sys, cfg).ok()
}

/// A metric that does not contract has no gain figures: null in JSON with the reason,
/// never the partial maximum the enumeration stopped at (issue 15: `input_gain` 0.0).
#[test]
fn gains_of_a_metric_that_does_not_contract_are_null_with_a_reason() {
    let mut seen = 0;
    for seed in 0..40 {
        let Some(mpc) = random_mpc(seed) else {
            continue;
        };
        let c = gamma13_certified(&mpc, 14).unwrap();
        for m in &c.candidates {
            let enumerated_stops = m.contraction_enumerated.is_some_and(|l| l >= 1.0);
            if enumerated_stops {
                seen += 1;
                assert_eq!(m.input_gain_enumerated, None, "seed {seed} {}", m.metric);
                assert!(m.gamma13_enumerated.unwrap().is_infinite());
            }
            let contracts = m.contraction < 1.0 && !enumerated_stops;
            assert_eq!(m.not_computed.is_none(), contracts, "seed {seed} {m:?}");
            if m.contraction >= 1.0 {
                let reason = m.not_computed.expect("λ_S ≥ 1").to_string();
                assert!(reason.contains("≥ 1") && reason.contains("input_gain"));
                // No finite gain (null in the JSON: certificate_json::v1::num).
                assert!(!m.input_gain.is_finite(), "{}", m.input_gain);
            }
        }
    }
    assert!(seen > 0, "no enumerated metric that does not contract");
}
