//! What to simulate for a certificate, and the verdict that puts the two sides together:
//! the domain decisions `cargo xtask reproduce` (and any other front end) makes.

#[cfg(feature = "serde")]
use serde::Serialize;

use crate::certificate::SolverCertificate;
use closed_loop::bounded::Divergence;

/// Why a run was made at its K. `#[non_exhaustive]`: the tool records it (JSON
/// `k_source`) and decides nothing on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum KSource {
    /// The computed K_min of Theorem 1.
    ComputedKMin,
    /// The scenario's `mhe.iterations`.
    Scenario,
    /// A small K for comparison.
    Small,
}

impl KSource {
    /// The run tables' label: `"K_min"`, `"scenario"` or `"small K"`.
    pub fn label(self) -> &'static str {
        match self {
            KSource::ComputedKMin => "K_min",
            KSource::Scenario => "scenario",
            KSource::Small => "small K",
        }
    }

    /// Why the run, in a sentence: `"the computed K_min"`, `"mhe.iterations"` or
    /// `"small K for comparison"`.
    pub fn reason(self) -> &'static str {
        match self {
            KSource::ComputedKMin => "the computed K_min",
            KSource::Scenario => "mhe.iterations",
            KSource::Small => "small K for comparison",
        }
    }
}

/// The runs to simulate for a method's certificate: at K_min (when certified) and at the
/// scenario's K if it differs; when void, at the scenario's K and at `small_k` (if smaller)
/// so the loop's behaviour without a certificate is visible.
///
/// ```
/// use iss_certificate::plan::{KSource, plan_runs};
/// assert_eq!(plan_runs(652, Some(239), 5), vec![(239, KSource::ComputedKMin), (652, KSource::Scenario)]);
/// assert_eq!(plan_runs(652, None, 5), vec![(652, KSource::Scenario), (5, KSource::Small)]);
/// ```
pub fn plan_runs(scenario_k: usize, k_min: Option<usize>, small_k: usize) -> Vec<(usize, KSource)> {
    let mut plan = Vec::new();
    match k_min {
        Some(k_min) => {
            plan.push((k_min.max(1), KSource::ComputedKMin));
            if scenario_k != k_min.max(1) {
                plan.push((scenario_k, KSource::Scenario));
            }
        }
        None => {
            plan.push((scenario_k, KSource::Scenario));
            if small_k >= 1 && small_k < scenario_k {
                plan.push((small_k, KSource::Small));
            }
        }
    }
    plan
}

/// One simulated run as the verdict needs it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct RunOutcome<'a> {
    /// K of the run.
    pub k: usize,
    /// Steps completed.
    pub completed: usize,
    /// Why the run stopped early (`None` if it completed).
    pub error: Option<&'a str>,
    /// Where the run first left the bounded rule ([`closed_loop::bounded::first_unbounded`]).
    pub divergence: Option<Divergence>,
}

impl<'a> RunOutcome<'a> {
    /// A run as the verdict needs it (the struct is `#[non_exhaustive]`: a caller that
    /// reports its own runs builds them here).
    pub fn new(
        k: usize,
        completed: usize,
        error: Option<&'a str>,
        divergence: Option<Divergence>,
    ) -> Self {
        Self {
            k,
            completed,
            error,
            divergence,
        }
    }
}

/// The verdict on one method: every run that diverged first ("diverged at t = 7: ‖e‖ =
/// 1.2e4 > 1.0e4 (run at K = 1)", the bounded rule of [`closed_loop::bounded`]), then what
/// Theorem 1 certifies (or why nothing), what the trajectory check of Props. 1 and 3 found
/// (`None`: it did not run), and every other run that stopped.
pub fn verdict(
    cert: Option<&SolverCertificate>,
    trajectory_check: Option<bool>,
    runs: &[RunOutcome<'_>],
) -> String {
    format!(
        "{}{}",
        divergence_lead(runs),
        theorem1_verdict(cert, trajectory_check, runs)
    )
}

/// The leading sentences of a verdict for the runs that diverged (empty when none did).
///
/// ```
/// use closed_loop::bounded::{Divergence, Signal};
/// use iss_certificate::plan::{RunOutcome, divergence_lead};
/// let d = Divergence::new(7, Signal::E, 1.2e4, 1.0e4, false);
/// let runs = [RunOutcome::new(1, 60, None, Some(d))];
/// assert_eq!(divergence_lead(&runs), "diverged at t = 7: ‖e‖ = 1.2e4 > 1.0e4 (the run at K = 1). ");
/// ```
pub fn divergence_lead(runs: &[RunOutcome<'_>]) -> String {
    runs.iter()
        .filter_map(|r| {
            r.divergence
                .map(|d| format!("{d} (the run at K = {}). ", r.k))
        })
        .collect()
}

fn theorem1_verdict(
    cert: Option<&SolverCertificate>,
    trajectory_check: Option<bool>,
    runs: &[RunOutcome<'_>],
) -> String {
    let name = cert.map_or_else(
        || "the scenario's method".to_string(),
        |c| c.solver.to_string(),
    );
    let not_computed = cert.and_then(|s| s.not_computed.as_ref());
    let head = match cert.and_then(|s| s.k_min) {
        None if not_computed.is_some() => {
            let sims = if runs.is_empty() {
                "nothing was simulated".to_string()
            } else {
                let ks: Vec<String> = runs.iter().map(|r| r.k.to_string()).collect();
                format!(
                    "the loop was simulated anyway (K = {}) without a certificate",
                    ks.join(", ")
                )
            };
            format!(
                "Theorem 1's verdict for {name} is {}; {sims}.",
                not_computed.map_or_else(String::new, ToString::to_string)
            )
        }
        Some(k) => {
            let check = match trajectory_check {
                Some(true) => "Props. 1 and 3 hold at every step of the simulation at K_min",
                Some(false) => "the simulation at K_min VIOLATES Prop. 1 or 3 (see above)",
                None => "the trajectory check did not run",
            };
            format!("Theorem 1 certifies ISS of the closed loop for {name} with K ≥ {k}; {check}.")
        }
        None => {
            let failed: Vec<&str> = cert
                .map(|s| {
                    s.analysis
                        .premises
                        .iter()
                        .filter(|p| !p.holds)
                        .map(|p| p.name.as_str())
                        .collect()
                })
                .unwrap_or_default();
            let why = if failed.is_empty() {
                "no K satisfies sg1 + sg2 + sg3 < 1".to_string()
            } else {
                format!("premise {} fails", failed.join(", "))
            };
            let sims = if runs.is_empty() {
                "nothing was simulated".to_string()
            } else {
                let ks: Vec<String> = runs.iter().map(|r| r.k.to_string()).collect();
                format!(
                    "the loop was simulated anyway (K = {}) but no K is certified",
                    ks.join(", ")
                )
            };
            format!("Theorem 1 certifies nothing for {name} with these parameters ({why}); {sims}.")
        }
    };
    // A run that stopped is a result: say where and when.
    let stopped: String = runs
        .iter()
        .filter(|r| r.divergence.is_none())
        .filter_map(|r| {
            r.error.map(|e| {
                let what = if e.contains("diverged") {
                    "diverged"
                } else {
                    "stopped"
                };
                format!(
                    " The run at K = {} {what} at t = {}: {e}.",
                    r.k, r.completed
                )
            })
        })
        .collect();
    format!("{head}{stopped}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stopped_run_is_named_with_k_and_t() {
        let runs = [
            RunOutcome {
                k: 652,
                completed: 40,
                error: None,
                divergence: None,
            },
            RunOutcome {
                k: 1,
                completed: 125,
                error: Some("step t = 125: `x_next` … the closed loop diverged at t = 125"),
                divergence: None,
            },
        ];
        let v = verdict(None, None, &runs);
        assert!(v.contains("certifies nothing"), "{v}");
        assert!(v.contains("The run at K = 1 diverged at t = 125"), "{v}");
        assert!(!v.contains("K = 652 diverged"), "{v}");
    }
}
