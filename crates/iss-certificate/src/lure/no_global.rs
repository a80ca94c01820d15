//! Where no global certificate can exist (docs/theory.md §4, "Where no global certificate
//! can exist"): a mode of A with |λ| > 1 that only bounded inputs reach, decided before any
//! LMI of [`super::global_outcome`] is built.

use closed_loop::scenario::ResolvedScenario;

use super::global_outcome::GlobalOutcome;

/// [`GlobalOutcome::UnstableWithBoundedInput`] when it applies, else None (the searches
/// decide). Every input bounded: A unstable by `lti_model::spectral::classify` (which allows
/// for A's rounding). Some input with an infinite bound: a mode of A with |λ| > 1 + 10⁻⁶ that
/// those inputs do not reach (PBH: a mode of Aᵀ that B_freeᵀ does not see,
/// `mpc_core::detectable::undetectable_modes`).
pub(super) fn no_global_certificate(resolved: &ResolvedScenario) -> Option<GlobalOutcome> {
    let mpc = resolved.mpc().ok()?;
    let us = mpc.input_set();
    let a = resolved.scenario().plant.a();
    let free: Vec<usize> = (0..us.lower().len())
        .filter(|&j| !(us.lower()[j].is_finite() && us.upper()[j].is_finite()))
        .collect();
    if us.lower().is_empty() {
        return None;
    }
    let spectral_radius = if free.is_empty() {
        let facts = lti_model::spectral::classify(a).ok()?;
        (facts.stability == lti_model::spectral::Stability::Unstable)
            .then_some(facts.spectral_radius)?
    } else {
        let b = resolved.scenario().plant.b();
        let bf = faer::Mat::from_fn(b.nrows(), free.len(), |i, j| b[(i, free[j])]);
        let reach = &bf * bf.transpose();
        let modes = mpc_core::detectable::undetectable_modes(a.transpose(), reach.as_ref()).ok()?;
        modes
            .first()
            .map(|m| m.modulus)
            .filter(|&r| r > 1.0 + UNSTABLE_MARGIN)?
    };
    Some(GlobalOutcome::UnstableWithBoundedInput {
        spectral_radius,
        unbounded_inputs: free.len(),
    })
}

/// |λ| above 1 by more than this counts as unstable for a mode the unbounded inputs do not
/// reach (its eigenvalue is computed on a numerically determined subspace).
const UNSTABLE_MARGIN: f64 = 1e-6;
