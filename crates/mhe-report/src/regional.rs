//! K_reg of each method (issue 27, `iss_certificate::regional`) for certificate.json and the
//! summary: the smallest K whose regional certificate contains the scenario's own
//! uncertainty, searched up to the method's K_min (`mhe_sweep::search_max`), with
//! the region there — or, when there is none, the certificate at the largest K tried with the
//! constraint that limits the region and by how much.

use closed_loop::scenario::{ControllerChoice, ResolvedScenario};
use iss_certificate::certificate::ClosedLoopCertificate;
use iss_certificate::regional::{RegionalCertificate, RegionalOptions, RegionalVoid};
use mhe_sweep::{ProbeNote, k_reg_outcome, window_size};
use qp_iter::Method;

use crate::linear::LinearEntry;

/// One K the search evaluated.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct TriedK {
    /// K.
    pub k: usize,
    /// The largest certified scale of the scenario's uncertainty at K (capped just below 1
    /// when the region does not contain it; null: void at K, or ∞ when `contains`).
    pub margin: f64,
    /// The region at K contains the scenario's uncertainty.
    pub contains: bool,
}

/// One method's K_reg and regional certificate, or why there is none.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RegionalEntry {
    /// The method.
    pub solver: String,
    /// K_lin of `linear[]` (null: none on the grid, or not computed — then
    /// `k_lin_not_computed` says why), for the ratios.
    pub k_lin: Option<usize>,
    /// Why ρ_lin, hence K_lin, was not computed for this method (the `error` of its
    /// `linear[]` entry: above n_z = 128 only the scenario's method, the budget, …); omitted
    /// when it was computed, so a null `k_lin` without it means "none on the grid".
    pub k_lin_not_computed: Option<String>,
    /// Theorem 1's K_min (null: void or beyond its search range): it caps the search.
    pub k_min: Option<usize>,
    /// K_reg: the smallest K the search found whose region contains the scenario's own
    /// uncertainty (null: `void` says why).
    pub k_reg: Option<usize>,
    /// The largest K the search could try: min(K_min, or 2000 without one; ⌊200 000/n_z⌋).
    pub search_max: usize,
    /// Why `search_max` is that K.
    pub search_max_reason: String,
    /// The K `certificate` was evaluated at: K_reg, or the largest K tried when there is
    /// none (null: nothing evaluated).
    pub k: Option<usize>,
    /// The regional certificate at `k` (null when it could not be evaluated there).
    pub certificate: Option<RegionalCertificate>,
    /// Every K the search evaluated, ascending.
    pub tried: Vec<TriedK>,
    /// Why there is no K_reg (null when there is one): the void reason, or which constraint
    /// limits the region at the largest K tried and by how much.
    pub void: Option<String>,
    /// The step-0 row an admissible realization drives past its bound, when one does: no K
    /// has a region (step 0 does not depend on K; `void` says so).
    pub refuted_every_k: Option<iss_certificate::regional::Limit>,
    /// What the rows free of K (t = 0, the MHE's first inner iterates at t = 1) allow at any K:
    /// `{scale, max_x0_radius, max_prior_error, max_w_bar}`; no K's region contains a set
    /// beyond it (null: the search did not run).
    pub k_free: Option<iss_certificate::regional::KFreeLimits>,
    /// The scenario's uncertainty the search was for (null when it has none: `void` says why).
    pub uncertainty: Option<RegionalOptions>,
    /// The certificate at K = 2·K_lin, the target, when the search evaluated it (it
    /// asks for it as a bisection point: `iss_certificate::regional::k_reg_probing`): with
    /// K_reg above 2·K_lin, which row limits the region there and by how much.
    pub at_two_k_lin: Option<ProbeNote>,
}

/// K_reg ([`mhe_sweep::k_reg_outcome`]) of every method with the scenario's
/// controller (the exact MPC, or the K_c-iteration MPC of `mpc.iterations`) and the
/// scenario's own uncertainty (`certificate.x0_radius`, `prior_error`, `w_bar` or their
/// defaults), the search capped at the method's K_min. The phase has one budget,
/// `certificate.phase_seconds`, split evenly among the methods (so what each search may do
/// does not depend on the order or the thread count); the searches run in parallel.
pub fn regional_entries(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    linear: &[LinearEntry],
) -> Vec<RegionalEntry> {
    use rayon::prelude::*;
    let share = cert.solvers.len().max(1) as f64;
    let options =
        RegionalOptions::from_scenario(resolved, scenario_controller(resolved)).map(|o| {
            RegionalOptions {
                phase_seconds: o.phase_seconds / share,
                ..o
            }
        });
    cert.solvers
        .par_iter()
        .map(|s| {
            let entry = linear.iter().find(|l| l.solver == s.solver.name());
            let k_lin = entry.and_then(|l| l.report.as_ref()).and_then(|r| r.k_lin);
            let mut e = regional_entry(resolved, s.solver, &options, s.k_min, k_lin);
            e.k_lin_not_computed = match entry {
                Some(l) if l.report.is_none() => Some(
                    l.error
                        .clone()
                        .unwrap_or_else(|| "not computed".to_string()),
                ),
                Some(_) => None,
                None => Some("not computed: no ρ_lin entry for this method".to_string()),
            };
            e
        })
        .collect()
}

/// K_reg of one method (K_min caps the search; K_lin is copied for the ratios).
pub fn regional_entry(
    resolved: &ResolvedScenario,
    method: Method,
    options: &Result<RegionalOptions, RegionalVoid>,
    k_min: Option<usize>,
    k_lin: Option<usize>,
) -> RegionalEntry {
    let o = k_reg_outcome(
        resolved,
        method,
        options,
        k_min,
        window_size(resolved),
        k_lin.map(|k| 2 * k),
    );
    RegionalEntry {
        solver: method.name().into_owned(),
        k_lin,
        k_lin_not_computed: None,
        k_min,
        k_reg: o.k_reg,
        search_max: o.search_max,
        search_max_reason: o.search_max_reason,
        k: o.k,
        certificate: o.certificate,
        tried: o
            .tried
            .into_iter()
            .map(|(k, margin)| TriedK {
                k,
                margin,
                contains: margin >= 1.0,
            })
            .collect(),
        void: o.note,
        refuted_every_k: o.refuted_every_k,
        k_free: o.k_free,
        uncertainty: options.as_ref().ok().cloned(),
        at_two_k_lin: o.probe,
    }
}

/// The scenario's own controller: the exact MPC, or K_c iterations of `mpc.method` when
/// `mpc.iterations` is set.
pub fn scenario_controller(resolved: &ResolvedScenario) -> ControllerChoice {
    closed_loop::scenario::LoopOptions::from_scenario(resolved.scenario())
        .map_or(ControllerChoice::ExactMpc, |o| o.controller)
}
