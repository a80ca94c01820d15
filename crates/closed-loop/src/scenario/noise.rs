//! The simulated noise against 𝒲: which draws of a run left the set the MHE and the
//! certificate assume.
//!
//! The scenario's `[noise]` is the *simulated* law (uniform, Gaussian, truncated normal, a
//! mean offset); `sets.disturbance` is 𝒲, the set the MHE constrains ŵ to and Theorem 1's
//! ISS statement assumes (w_t ∈ 𝒲 for every t). A step whose draw w_t ∉ 𝒲 is outside the
//! certificate's premises: its ISS bound is not claimed for that step (nor, since the bound
//! is over the whole past, for the steps after it). Runs report how many such steps there were.

use lti_model::{BoxSet, ConvexSet};

use crate::record::Trace;

/// The steps t of `trace` whose draw w_t lies outside 𝒲 (`disturbance`, violation > 0),
/// ascending.
///
/// ```
/// use closed_loop::scenario::{Scenario, LoopOptions, draws_outside};
/// let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenarios/case-study.toml")).unwrap();
/// // Twice the box the MHE assumes: some draws leave 𝒲.
/// let s = Scenario::from_toml_str(&text.replace("scale = 1.0", "scale = 2.0")).unwrap();
/// let mut o = LoopOptions::from_scenario(&s).unwrap();
/// o.steps = 20;
/// let mut cl = s.clone().resolve().unwrap().build_loop(&o).unwrap();
/// let trace = cl.run().unwrap();
/// assert!(!draws_outside(trace, &s.sets.disturbance).is_empty());
/// ```
pub fn draws_outside(trace: &Trace, disturbance: &BoxSet) -> Vec<usize> {
    (0..trace.len())
        .filter(|&t| {
            trace
                .w(t)
                .is_some_and(|w| !(disturbance.violation(w) <= 0.0))
        })
        .collect()
}
