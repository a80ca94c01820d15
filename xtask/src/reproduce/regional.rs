//! The regional certificate (issue 27, `iss_certificate::regional`) of each method at its K_min,
//! for certificate.json: the region, the limiting constraint and the certified gains.

use super::*;

/// One method's regional certificate at its K_min, or why there is none.
#[derive(Debug, Clone, Serialize)]
pub struct RegionalEntry {
    /// The method.
    pub solver: String,
    /// The K it was evaluated at (the method's K_min; null when Theorem 1 is void).
    pub k: Option<usize>,
    /// The certificate (null when void).
    pub certificate: Option<iss_certificate::regional::RegionalCertificate>,
    /// Why there is none.
    pub void: Option<String>,
}

/// Largest K·n_z at which `reproduce` evaluates the regional certificate: its rows (every
/// pre-projection point of all K inner iterates of every window) grow with K·n_z, and the
/// cart-pendulum's PG at K_min = 140 227 needed more than 24 GB. Beyond it the entry says so.
pub const REGIONAL_MAX_K_NZ: usize = 200_000;

/// [`iss_certificate::regional::regional_certificate`] of every method at its K_min, with the
/// exact MPC and the scenario's own uncertainty (`certificate.x0_radius`, `prior_error`,
/// `w_bar` or their defaults); not computed when K_min·n_z > [`REGIONAL_MAX_K_NZ`].
pub(super) fn regional_entries(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
) -> Vec<RegionalEntry> {
    use iss_certificate::regional::{RegionalOptions, regional_certificate};
    let options = RegionalOptions::from_scenario(resolved, ControllerChoice::ExactMpc);
    let plant = &resolved.scenario().plant;
    let n_z = plant.nx() + cert.horizon * plant.nw();
    cert.solvers
        .iter()
        .map(|s| {
            let solver = s.solver.name().into_owned();
            let (certificate, void) = match (&options, s.k_min) {
                (Err(e), _) => (None, Some(e.to_string())),
                (Ok(_), None) => (
                    None,
                    Some("not evaluated: Theorem 1 gives no K_min for this method".into()),
                ),
                (Ok(_), Some(k)) if k.saturating_mul(n_z) > REGIONAL_MAX_K_NZ => (
                    None,
                    Some(format!(
                        "not computed: the region's rows grow with K·n_z, and K_min·n_z = \
                         {k}·{n_z} is above {REGIONAL_MAX_K_NZ}, the limit of `reproduce` \
                         (iss_certificate::regional::regional_certificate computes it)"
                    )),
                ),
                (Ok(o), Some(k)) => match regional_certificate(resolved, s.solver, k.max(1), o) {
                    Ok(c) => (Some(c), None),
                    Err(e) => (None, Some(e.to_string())),
                },
            };
            RegionalEntry {
                solver,
                k: s.k_min,
                certificate,
                void,
            }
        })
        .collect()
}
