//! Drivers outside the trait: exactly K steps, or until a tolerance.

#[cfg(feature = "serde")]
use serde::Serialize;

use crate::IterationMap;

/// Outcome of a driver run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum RunStatus {
    /// Ran the requested K steps (fixed-K driver).
    Completed,
    /// Reached the tolerance (tolerance driver).
    Converged,
    /// Hit the iteration cap without reaching the tolerance.
    MaxIterations,
    /// A NaN or ∞ appeared in the iterate (e.g. NaN in θ); the run stopped there.
    NonFinite,
    /// The observer asked to stop.
    Stopped,
}

impl RunStatus {
    /// The snake_case name files write (`"completed"`, `"max_iterations"`, …): the same as
    /// its serde form, without needing the `serde` feature.
    pub fn name(self) -> &'static str {
        match self {
            RunStatus::Completed => "completed",
            RunStatus::Converged => "converged",
            RunStatus::MaxIterations => "max_iterations",
            RunStatus::NonFinite => "non_finite",
            RunStatus::Stopped => "stopped",
        }
    }
}

/// Result of a driver run.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct RunResult {
    /// Steps actually taken.
    pub iterations: usize,
    /// Why the run ended.
    pub status: RunStatus,
}

fn all_finite(z: &[f64]) -> bool {
    z.iter().all(|v| v.is_finite())
}

/// Applies Φ exactly `k` times (the paper's fixed iteration budget K).
///
/// Checks finiteness once at the end (O(n), allocation-free): a non-finite iterate is
/// reported as [`RunStatus::NonFinite`], never a panic.
pub fn run_fixed<M: IterationMap>(map: &M, state: &mut M::State, k: usize) -> RunResult {
    map.run_steps(state, k);
    let status = if all_finite(map.iterate(state)) {
        RunStatus::Completed
    } else {
        RunStatus::NonFinite
    };
    RunResult {
        iterations: k,
        status,
    }
}

/// Steps until `observer(k, z^k)` returns `true` (converged), at most `max_iter` steps.
///
/// The observer sees the iterate after every step; it returns `Some(true)` to declare
/// convergence, `Some(false)` to stop early, `None` to continue. Typical use: stop when
/// ‖z^k − z*‖ ≤ tol·‖z⁰ − z*‖ against a reference solution.
pub fn run_until<M, O>(map: &M, state: &mut M::State, max_iter: usize, mut observer: O) -> RunResult
where
    M: IterationMap,
    O: FnMut(usize, &[f64]) -> Option<bool>,
{
    for k in 1..=max_iter {
        map.step(state);
        let z = map.iterate(state);
        if !all_finite(z) {
            return RunResult {
                iterations: k,
                status: RunStatus::NonFinite,
            };
        }
        match observer(k, z) {
            Some(true) => {
                return RunResult {
                    iterations: k,
                    status: RunStatus::Converged,
                };
            }
            Some(false) => {
                return RunResult {
                    iterations: k,
                    status: RunStatus::Stopped,
                };
            }
            None => {}
        }
    }
    RunResult {
        iterations: max_iter,
        status: RunStatus::MaxIterations,
    }
}

#[cfg(test)]
mod tests {
    use super::RunStatus;

    /// serde's `rename_all = "snake_case"` of the variant's name.
    fn snake(debug: &str) -> String {
        let mut out = String::new();
        for (i, c) in debug.chars().enumerate() {
            if c.is_ascii_uppercase() && i > 0 {
                out.push('_');
            }
            out.push(c.to_ascii_lowercase());
        }
        out
    }

    /// `name()` is the serde form (trace.csv writes it; trace.json writes the serde form).
    #[test]
    fn names_are_the_serde_names() {
        use RunStatus::*;
        for s in [Completed, Converged, MaxIterations, NonFinite, Stopped] {
            assert_eq!(s.name(), snake(&format!("{s:?}")));
            #[cfg(feature = "serde")]
            assert_eq!(
                serde_json::to_value(s).ok(),
                Some(serde_json::Value::from(s.name()))
            );
        }
    }
}
