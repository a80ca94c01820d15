//! The exact linear stability boundary per method, for certificate.json and the summary.

use super::*;

/// ρ_lin of one method, or why it has none.
#[derive(Debug, Clone, Serialize)]
pub struct LinearEntry {
    /// The method.
    pub solver: String,
    /// The report (null when the analysis does not apply).
    pub report: Option<closed_loop::linear::LinearReport>,
    /// Why there is no report (e.g. 0 on a bound of a box: no inactive neighbourhood).
    pub error: Option<String>,
}

/// K grid of the linear analysis: 25 log-spaced K from 1 to max(2000, every K_min), for
/// every method of the certificate; every (method, K) pair is a task on the global rayon pool
/// ([`closed_loop::linear::linear_stability_all`]; the result does not depend on the thread
/// count).
///
/// Beyond the budget `phase_seconds` (estimated seconds of one core for all methods) nothing
/// is computed (each `error` names the estimate, the budget and `certificate.phase_seconds`);
/// with `live`, progress lines go to
/// stderr every 10 s once the analysis has run for 2 s.
pub(super) fn linear_entries(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    phase_seconds: f64,
    live: bool,
) -> Vec<LinearEntry> {
    let top = cert
        .solvers
        .iter()
        .filter_map(|s| s.k_min)
        .fold(2000, usize::max);
    let grid = closed_loop::sweep::log_spaced(1, top, 25);
    let methods: Vec<Method> = cert.solvers.iter().map(|s| s.solver).collect();
    let options: Vec<Result<LoopOptions, ClosedLoopError>> = methods
        .iter()
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
    let last = std::sync::Mutex::new(0.0_f64);
    let progress = |done: usize, total: usize| {
        if !live {
            return;
        }
        let t = start.elapsed().as_secs_f64();
        let Ok(mut last) = last.lock() else { return };
        if t >= 2.0 && t - *last >= 10.0 {
            *last = t;
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "  ρ_lin: {done}/{total} (method, K) eigenvalue problems done, {t:.0} s"
            );
        }
    };
    let mut reports = closed_loop::linear::linear_stability_all_budgeted(
        resolved,
        &ok,
        &grid,
        phase_seconds,
        &progress,
    )
    .into_iter();
    methods
        .iter()
        .zip(options)
        .map(|(&m, o)| {
            let result = match o {
                Ok(_) => reports
                    .next()
                    .unwrap_or(Err(closed_loop::linear::LinearError::ZeroIterations)),
                Err(e) => Err(closed_loop::linear::LinearError::from(e)),
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
