//! The exact linear stability boundary ρ_lin(K) per method (`iss_certificate::linear`).

use closed_loop::ClosedLoopError;
use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario};
use iss_certificate::certificate::ClosedLoopCertificate;
use qp_iter::Method;

use crate::Observer;

/// ρ_lin of one method, or why it has none.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct LinearEntry {
    /// The method.
    pub solver: String,
    /// The report (null when the analysis does not apply).
    pub report: Option<iss_certificate::linear::LinearReport>,
    /// Why there is no report (e.g. 0 on a bound of a box: no inactive neighbourhood).
    pub error: Option<String>,
}

/// Largest MHE window size n_z = n_x + M·n_w for which ρ_lin is computed for every method of
/// the certificate; above it only for the scenario's own method (the one simulated). One
/// eigenvalue problem of the lifted loop costs O(dim³) with dim ≈ 2·n_z + …, 25 per method:
/// at M = 50 on the stand-in (n_z = 254, dim = 608) eight methods took most of `reproduce`'s
/// time.
pub const LINEAR_ALL_METHODS_MAX_NZ: usize = iss_certificate::linear::ALL_METHODS_MAX_NZ;

/// K grid of the linear analysis: 25 log-spaced K from 1 to max(2000, every K_min), for
/// every method of the certificate (only for `own`, the scenario's method, when the window
/// has more than [`LINEAR_ALL_METHODS_MAX_NZ`] variables: the others then say so); every
/// (method, K) pair is a task on the global rayon pool
/// ([`iss_certificate::linear::linear_stability_all_budgeted`]; the result does not depend on the
/// thread count).
///
/// Beyond the budget `phase_seconds` (estimated seconds of one core for all methods) nothing
/// is computed (each `error` names the estimate, the budget and `certificate.phase_seconds`);
/// the progress goes to [`Observer::linear_progress`].
pub fn linear_entries(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    own: Method,
    phase_seconds: f64,
    observer: &dyn Observer,
) -> Vec<LinearEntry> {
    let plant = &resolved.scenario().plant;
    let n_z = plant.nx() + cert.horizon * plant.nw();
    let all = n_z <= LINEAR_ALL_METHODS_MAX_NZ;
    let top = cert
        .solvers
        .iter()
        .filter_map(|s| s.k_min)
        .fold(2000, usize::max);
    let grid = iss_certificate::linear::log_spaced(1, top, 25);
    let methods: Vec<Method> = cert.solvers.iter().map(|s| s.solver).collect();
    let options: Vec<Result<LoopOptions, ClosedLoopError>> = methods
        .iter()
        .filter(|&&m| all || m == own)
        .map(|&m| {
            LoopOptions::from_scenario(resolved.scenario()).map(|mut o| {
                o.method = m;
                o.controller = ControllerChoice::ExactMpc;
                o
            })
        })
        .collect();
    let ok: Vec<LoopOptions> = options
        .iter()
        .filter_map(|o| o.as_ref().ok().copied())
        .collect();
    let start = std::time::Instant::now();
    let progress = |done: usize, total: usize| {
        observer.linear_progress(done, total, start.elapsed().as_secs_f64());
    };
    let mut reports = iss_certificate::linear::linear_stability_all_budgeted(
        resolved,
        &ok,
        &grid,
        phase_seconds,
        &progress,
    )
    .into_iter();
    let mut options = options.into_iter();
    methods
        .iter()
        .map(|&m| {
            if !(all || m == own) {
                return LinearEntry {
                    solver: m.name().into_owned(),
                    report: None,
                    error: Some(format!(
                        "not computed: the MHE window has n_z = {n_z} > {LINEAR_ALL_METHODS_MAX_NZ} \
                         variables, so ρ_lin is computed for the scenario's method ({}) only; \
                         set mhe.method to another method to get its ρ_lin",
                        own.name(),
                    )),
                };
            }
            let o = options
                .next()
                .unwrap_or(Err(ClosedLoopError::MissingSection { section: "mhe" }));
            let result = match o {
                Ok(_) => reports
                    .next()
                    .unwrap_or(Err(iss_certificate::linear::LinearError::ZeroIterations)),
                Err(e) => Err(iss_certificate::linear::LinearError::from(e)),
            };
            let (report, error) = match result {
                Ok(r) => (Some(r), None),
                Err(e) => (None, Some(e.to_string())),
            };
            LinearEntry {
                solver: m.name().into_owned(),
                report,
                error,
            }
        })
        .collect()
}
