//! The one bounded rule of every run: the sweep's `bounded` column, `monte_carlo`,
//! `reproduce`'s `diverged` / `diverged_at` / `signal`, and the trajectory checks all call
//! [`first_unbounded`].
//!
//! A run is **bounded** when every signal stays finite and within `factor` (default
//! [`DEFAULT_BOUNDED_FACTOR`] = 1000) times its own scale: the initial one and the run's
//! own disturbance so far, w̄_t = max_{s ≤ t} ‖w_s‖ (process and measurement noise as
//! drawn, 0 when not recorded):
//!
//! | signal | limit at every recorded t |
//! | --- | --- |
//! | e (‖x_t − x̂_t‖) | factor·(1 + ‖e₀‖ + w̄_t), e₀ = x₀ − x̂₀ |
//! | x (‖x_t‖, x_T included) | factor·(1 + ‖x₀‖ + w̄_t) |
//! | ε (ε_t = ‖zᴷ_t − z*_t‖, when recorded) | factor·(1 + ‖e₀‖ + ε₀ + w̄_t) |
//! | u (‖u_t‖) | finite (the input box, not this rule, bounds u) |
//!
//! The w̄_t term makes the rule independent of the units of the disturbance (issue 37 item
//! 3): a stable plant driven by noise of size 10³ has states of size 10³·(its gain), which
//! is bounded, not diverged; an absolute limit called it diverged at t = 2. A loop that
//! does diverge grows geometrically and still crosses the limit within a few steps.
//!
//! The first step t (and signal, in the order e, x, ε, u at equal t) at which a limit fails
//! is reported as a [`Divergence`]. A run that stopped early (a non-finite signal caught by
//! the loop) diverged at the step where it stopped if no limit failed before.

#[cfg(feature = "serde")]
use serde::Serialize;

use crate::record::{Trace, norm2};

/// Default bound factor of the rule (the sweep's `bounded_factor`).
pub const DEFAULT_BOUNDED_FACTOR: f64 = 1e3;

/// The signal whose limit failed first.
///
/// Exhaustive on purpose: certificate-json's `v1::Signal` names each variant, so a new
/// signal is a schema decision the compiler asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum Signal {
    /// The estimation error e_t = x_t − x̂_t.
    E,
    /// The plant state x_t.
    X,
    /// The MHE's sub-optimality ε_t.
    Epsilon,
    /// The applied input u_t.
    U,
}

impl Signal {
    /// The norm as printed: `‖e‖`, `‖x‖`, `ε`, `‖u‖`.
    pub fn symbol(self) -> &'static str {
        match self {
            Signal::E => "‖e‖",
            Signal::X => "‖x‖",
            Signal::Epsilon => "ε",
            Signal::U => "‖u‖",
        }
    }
}

/// Where and how a run first left the bounded rule.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Divergence {
    /// The first step at which a limit failed.
    pub t: usize,
    /// The signal.
    pub signal: Signal,
    /// Its value at t (NaN or ±∞ when non-finite; for a stopped run, the last recorded value).
    pub value: f64,
    /// The limit it exceeded (∞ for "must be finite").
    pub limit: f64,
    /// The run stopped early at t (the loop caught a non-finite signal).
    pub stopped: bool,
}

impl Divergence {
    /// A divergence record (the loop builds its own; this is for callers that report one).
    pub fn new(t: usize, signal: Signal, value: f64, limit: f64, stopped: bool) -> Self {
        Self {
            t,
            signal,
            value,
            limit,
            stopped,
        }
    }
}

impl std::fmt::Display for Divergence {
    /// `"diverged at t = 7: ‖e‖ = 1.2e4 > 1.0e4"`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.stopped {
            write!(
                f,
                "diverged at t = {}: the loop stopped on a non-finite or overflowing signal",
                self.t
            )
        } else if self.limit.is_finite() {
            write!(
                f,
                "diverged at t = {}: {} = {:.1e} > {:.1e}",
                self.t,
                self.signal.symbol(),
                self.value,
                self.limit
            )
        } else {
            write!(
                f,
                "diverged at t = {}: {} = {} (not finite)",
                self.t,
                self.signal.symbol(),
                self.value
            )
        }
    }
}

/// The limits of the rule for one run without the disturbance term (see the module docs):
/// at step t each limit is raised by `factor`·w̄_t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundedLimits {
    /// Limit on ‖e_t‖ at w̄_t = 0.
    pub e: f64,
    /// Limit on ‖x_t‖ at w̄_t = 0.
    pub x: f64,
    /// Limit on ε_t at w̄_t = 0.
    pub epsilon: f64,
    /// The factor (multiplies w̄_t).
    pub factor: f64,
}

impl BoundedLimits {
    /// The limits of a trace with initial state `x0` and bound factor `factor`.
    pub fn of(trace: &Trace, x0: &[f64], factor: f64) -> Self {
        let e0 = trace
            .x_hat(0)
            .map_or(0.0, |xh| lti_model::vecmath::dist2(x0, xh));
        let eps0 = trace
            .epsilons()
            .next()
            .flatten()
            .filter(|v| v.is_finite())
            .unwrap_or(0.0);
        Self {
            e: factor * (1.0 + e0),
            x: factor * (1.0 + norm2(x0)),
            epsilon: factor * (1.0 + e0 + eps0),
            factor,
        }
    }
}

fn exceeds(v: f64, limit: f64) -> bool {
    !(v <= limit)
}

/// The first step and signal at which `trace` (initial state `x0`) leaves the bounded rule
/// with factor `factor`, or `None` when it is bounded. `stopped`: the run stopped early
/// because a signal became non-finite (a loop error); it then diverged at the step where
/// it stopped unless a limit failed before.
///
/// ```
/// use closed_loop::bounded::{DEFAULT_BOUNDED_FACTOR, Signal, first_unbounded_in};
/// // No disturbance recorded: ‖e‖ crosses 1000·(1 + 1) at t = 2.
/// let e = [1.0, 10.0, 3.0e3, 1.0e9];
/// let x = [1.0, 1.0, 1.0, 1.0, 1.0];
/// let d = first_unbounded_in(&e, &x, &[], &[], &[], 1.0, 1.0, DEFAULT_BOUNDED_FACTOR, false)
///     .unwrap();
/// assert_eq!((d.t, d.signal), (2, Signal::E));
/// assert_eq!(d.to_string(), "diverged at t = 2: ‖e‖ = 3.0e3 > 2.0e3");
/// // With ‖w_t‖ = 10 the limit is 1000·(1 + 1 + 10): 3e3 is within it, 1e9 is not.
/// let w = [10.0; 4];
/// let d = first_unbounded_in(&e, &x, &[], &[], &w, 1.0, 1.0, DEFAULT_BOUNDED_FACTOR, false)
///     .unwrap();
/// assert_eq!(d.t, 3);
/// ```
pub fn first_unbounded(
    trace: &Trace,
    x0: &[f64],
    factor: f64,
    stopped: bool,
) -> Option<Divergence> {
    let limits = BoundedLimits::of(trace, x0, factor);
    let eps: Vec<f64> = trace.epsilons().map_while(|e| e).collect();
    let u_norms: Vec<f64> = (0..trace.len())
        .map(|t| trace.u(t).map_or(0.0, norm2))
        .collect();
    scan(
        trace.e_norms(),
        trace.x_norms(),
        &eps,
        &u_norms,
        trace.w_norms(),
        limits,
        stopped,
    )
}

/// [`first_unbounded`] on the norms themselves (‖e_t‖, ‖x_t‖, ε_t, ‖u_t‖, ‖w_t‖ per step;
/// ε, u and w may be empty), with ‖e₀‖ = `e0` and ‖x₀‖ = `x0_norm`.
#[allow(clippy::too_many_arguments)]
pub fn first_unbounded_in(
    e: &[f64],
    x: &[f64],
    eps: &[f64],
    u: &[f64],
    w: &[f64],
    e0: f64,
    x0_norm: f64,
    factor: f64,
    stopped: bool,
) -> Option<Divergence> {
    let eps0 = eps
        .first()
        .copied()
        .filter(|v| v.is_finite())
        .unwrap_or(0.0);
    let limits = BoundedLimits {
        e: factor * (1.0 + e0),
        x: factor * (1.0 + x0_norm),
        epsilon: factor * (1.0 + e0 + eps0),
        factor,
    };
    scan(e, x, eps, u, w, limits, stopped)
}

fn scan(
    e: &[f64],
    x: &[f64],
    eps: &[f64],
    u: &[f64],
    w: &[f64],
    limits: BoundedLimits,
    stopped: bool,
) -> Option<Divergence> {
    let n = e.len().max(x.len()).max(eps.len()).max(u.len());
    // w̄_t = max_{s ≤ t} ‖w_s‖ (a non-finite draw does not raise it: f64::max drops NaN).
    let mut w_bar = 0.0_f64;
    for t in 0..n {
        if let Some(&wt) = w.get(t)
            && wt.is_finite()
        {
            w_bar = w_bar.max(wt);
        }
        let raise = limits.factor * w_bar;
        let checks = [
            (Signal::E, e.get(t), limits.e + raise),
            (Signal::X, x.get(t), limits.x + raise),
            (Signal::Epsilon, eps.get(t), limits.epsilon + raise),
            (Signal::U, u.get(t), f64::INFINITY),
        ];
        for (signal, v, limit) in checks {
            let Some(&v) = v else { continue };
            if exceeds(v, limit) || !v.is_finite() {
                return Some(Divergence {
                    t,
                    signal,
                    value: v,
                    limit,
                    stopped: false,
                });
            }
        }
    }
    stopped.then(|| {
        // The step the loop could not complete: e and x are recorded up to it.
        let t = e.len();
        Divergence {
            t,
            signal: Signal::X,
            value: x.last().copied().unwrap_or(f64::NAN),
            limit: limits.x + limits.factor * w_bar,
            stopped: true,
        }
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_first_failing_step_and_signal_are_reported() {
        // x fails at t = 3, e at t = 4: x is first.
        let e = [0.5, 1.0, 1.0, 1.0, 1e6];
        let x = [2.0, 2.0, 2.0, 5e3, 1.0, 1.0];
        let d = first_unbounded_in(&e, &x, &[], &[], &[], 0.5, 2.0, 1e3, false).unwrap();
        assert_eq!((d.t, d.signal), (3, Signal::X));
        assert_eq!(d.limit, 3e3);
        // At equal t, e is reported before x.
        let e = [0.5, 1.0, 1.0, 1e6];
        let d = first_unbounded_in(&e, &x, &[], &[], &[], 0.5, 2.0, 1e3, false).unwrap();
        assert_eq!((d.t, d.signal), (3, Signal::E));
    }

    #[test]
    fn epsilon_u_and_non_finite_values_count() {
        let e = [1.0; 4];
        let x = [1.0; 5];
        let eps = [0.1, 0.2, 1e9, 0.1];
        let d = first_unbounded_in(&e, &x, &eps, &[], &[], 1.0, 1.0, 1e3, false).unwrap();
        assert_eq!((d.t, d.signal), (2, Signal::Epsilon));
        let u = [0.0, f64::NAN, 0.0, 0.0];
        let d = first_unbounded_in(&e, &x, &[], &u, &[], 1.0, 1.0, 1e3, false).unwrap();
        assert_eq!((d.t, d.signal), (1, Signal::U));
        assert!(d.to_string().contains("not finite"), "{d}");
        // Bounded: exactly at the limit passes.
        let e = [1.0, 2e3];
        assert!(first_unbounded_in(&e, &x, &[], &[], &[], 1.0, 1.0, 1e3, false).is_none());
    }

    #[test]
    fn a_stopped_run_diverged_where_it_stopped() {
        let e = [1.0, 1.0, 1.0];
        let x = [1.0, 1.0, 1.0];
        let d = first_unbounded_in(&e, &x, &[], &[], &[], 1.0, 1.0, 1e3, true).unwrap();
        assert_eq!(d.t, 3);
        assert!(d.stopped);
        assert!(d.to_string().starts_with("diverged at t = 3"), "{d}");
    }

    /// Issue 37 item 3: a stable plant driven by noise of size 10³ (the Rao–Rawlings–Lee
    /// scenario with `noise.scale = 1000`) has ‖x‖, ‖e‖ of a few 10³·(its gain): bounded.
    /// The absolute rule (1000·(1 + ‖e₀‖) = 2.4e3) called it diverged at t = 2; scaled by
    /// the run's own w̄_t it is bounded, and a geometric blow-up is still caught.
    #[test]
    fn the_limit_scales_with_the_runs_own_disturbance() {
        let e0 = 2f64.sqrt();
        let w = [3.0e3; 6];
        // x, e of the size of 4·w̄ (bounded: the plant's gain times the noise).
        let e = [e0, 4.7e3, 8.0e3, 6.0e3, 7.0e3, 6.5e3];
        let x = [e0, 3.0e3, 1.2e4, 1.1e4, 1.0e4, 1.1e4];
        assert!(first_unbounded_in(&e, &x, &[], &[], &w, e0, e0, 1e3, false).is_none());
        // Without the disturbance term (the old rule) the same run "diverged" at t = 1.
        let d = first_unbounded_in(&e, &x, &[], &[], &[], e0, e0, 1e3, false).unwrap();
        assert_eq!((d.t, d.signal), (1, Signal::E));
        // A run that grows 10× per step still diverges, at the step it crosses
        // 1000·(1 + ‖e₀‖ + 3e3) ≈ 3.0e6.
        let e: Vec<f64> = (0..8).map(|t| 10f64.powi(t)).collect();
        let d = first_unbounded_in(&e, &[], &[], &[], &[3.0e3; 8], 1.0, 0.0, 1e3, false).unwrap();
        assert_eq!((d.t, d.signal), (7, Signal::E));
        assert!((d.limit - 1e3 * (1.0 + 1.0 + 3.0e3)).abs() < 1e-6, "{d:?}");
    }
}
