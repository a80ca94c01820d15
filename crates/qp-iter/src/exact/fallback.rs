//! The exact solve with a fallback ([`ExactSolver`]): the primal active set, Goldfarb–Idnani
//! for general rows, Clarabel when either stops without a verified optimum (cargo feature
//! `clarabel`; without it that stop is the error). Re-exported as
//! `qp_iter::active_set::ExactSolver`.

use super::active_set::{ActiveSetInfo, ActiveSetSettings, ActiveSetSolver};
use crate::dual_active_set::{DualActiveSetSettings, DualActiveSetStatus, ParametricDualActiveSet};
use crate::error::{QpError, Result};
use crate::problem::ParametricQp;
#[cfg(feature = "clarabel")]
use crate::reference::{ReferenceSettings, ReferenceSolver};

/// An exact solve that cannot stop without an answer: [`ActiveSetSolver`] first, Clarabel
/// ([`ReferenceSolver`], default settings, built on first use) when the active-set method
/// stops without a verified optimum. What `mpc-core`'s exact MPC and `mhe-core`'s ε_t use.
/// A problem with general rows is solved by Goldfarb–Idnani
/// ([`crate::dual_active_set`], started cold each call; warm starts are ignored) with the
/// same Clarabel fallback, and an infeasible θ is [`QpError::Infeasible`].
///
/// Allocation-free while the active set succeeds (every case-study test run); a fallback
/// allocates (Clarabel) and is counted by [`ExactSolver::fallbacks`]. Built without the
/// cargo feature `clarabel` there is no fallback: a stop without a verified optimum is
/// returned ([`QpError::NotConverged`]) and counted the same way.
///
/// ```
/// use faer::{mat, Mat};
/// use qp_iter::BoxSet;
/// use qp_iter::ParametricQp;
/// use qp_iter::active_set::ExactSolver;
/// let qp = ParametricQp::new(mat![[4.0, 1.0], [1.0, 1.0]], vec![-2.0, -4.0],
///     Mat::identity(2, 2), BoxSet::symmetric(&[2.0, 2.0]).unwrap()).unwrap();
/// let mut s = ExactSolver::new(&qp).unwrap();
/// let z = s.solve(&[-1.0, 1.0]).unwrap();
/// assert!((z[0] - 0.25).abs() < 1e-15 && z[1] == 2.0);
/// assert_eq!(s.fallbacks(), 0);
/// ```
#[derive(Debug)]
pub struct ExactSolver {
    active: ActiveSetSolver,
    /// With general rows: Goldfarb–Idnani instead of `active` (which then solves nothing).
    general: Option<Box<ParametricDualActiveSet>>,
    #[cfg(feature = "clarabel")]
    fallback: Option<Box<ReferenceSolver>>,
    fallbacks: usize,
    /// The last solution (the active set's, or Clarabel's after a fallback).
    z: Vec<f64>,
    last_info: Option<ActiveSetInfo>,
}

impl ExactSolver {
    /// Active set with [`ActiveSetSettings::default`].
    pub fn new(qp: &ParametricQp) -> Result<Self> {
        Self::with_settings(qp, ActiveSetSettings::default())
    }

    /// Active set with the given settings.
    pub fn with_settings(qp: &ParametricQp, settings: ActiveSetSettings) -> Result<Self> {
        let general = match qp.general() {
            Some(_) => Some(Box::new(ParametricDualActiveSet::new(
                qp,
                DualActiveSetSettings::default(),
            )?)),
            None => None,
        };
        Ok(Self {
            active: ActiveSetSolver::new(&qp.without_general(), settings)?,
            general,
            #[cfg(feature = "clarabel")]
            fallback: None,
            fallbacks: 0,
            z: vec![0.0; qp.n()],
            last_info: None,
        })
    }

    /// z*(θ). Errors: θ of the wrong length or not finite ([`QpError::Data`]); Clarabel
    /// failing after an active-set failure ([`QpError::Reference`]); with general rows,
    /// constraints without a common point for this θ ([`QpError::Infeasible`], from the
    /// Goldfarb–Idnani solver, naming the row it could not meet).
    pub fn solve(&mut self, theta: &[f64]) -> Result<&[f64]> {
        self.last_info = None;
        if let Some(gi) = &mut self.general {
            let info = gi.solve(theta)?;
            match info.status {
                DualActiveSetStatus::Infeasible {
                    constraint,
                    violation,
                } => {
                    return Err(QpError::Infeasible {
                        solver: "dual active set",
                        detail: format!("{constraint} missed by {violation:.3e}"),
                        constraint: Some(constraint),
                    });
                }
                _ if info.is_verified(1e-9) => {
                    self.z.copy_from_slice(gi.z());
                    return Ok(&self.z);
                }
                #[cfg(feature = "clarabel")]
                _ => {
                    self.fallbacks += 1;
                    let reference = match &mut self.fallback {
                        Some(r) => r,
                        slot => slot.insert(Box::new(ReferenceSolver::new(
                            gi.problem(),
                            ReferenceSettings::default(),
                        )?)),
                    };
                    let sol = reference.solve(theta)?;
                    self.z.copy_from_slice(&sol.z);
                    return Ok(&self.z);
                }
                #[cfg(not(feature = "clarabel"))]
                _ => {
                    self.fallbacks += 1;
                    return Err(QpError::NotConverged {
                        solver: "dual active set",
                        iterations: info.iterations,
                        reason: format!(
                            "stopped without a verified optimum ({:?}) and the Clarabel fallback \
                             is not built; enable qp-iter's cargo feature `clarabel`",
                            info.status
                        ),
                    });
                }
            }
        }
        match self.active.solve(theta) {
            Ok(info) => {
                self.z.copy_from_slice(self.active.z());
                self.last_info = Some(info);
            }
            #[cfg(feature = "clarabel")]
            Err(QpError::NotConverged { .. }) => {
                self.fallbacks += 1;
                self.active.reset();
                let reference = match &mut self.fallback {
                    Some(r) => r,
                    slot => slot.insert(Box::new(ReferenceSolver::new(
                        self.active.problem(),
                        ReferenceSettings::default(),
                    )?)),
                };
                let sol = reference.solve(theta)?;
                self.z.copy_from_slice(&sol.z);
            }
            #[cfg(not(feature = "clarabel"))]
            Err(e @ QpError::NotConverged { .. }) => {
                self.fallbacks += 1;
                self.active.reset();
                return Err(e);
            }
            Err(e) => return Err(e),
        }
        Ok(&self.z)
    }

    /// Forgets the warm start and the cached factor: the next call gives a fresh solver's
    /// results, bit for bit.
    pub fn reset(&mut self) {
        self.active.reset();
        self.last_info = None;
    }

    /// The next call starts from Π_Z(`z0`) and the working set of the bounds it touches
    /// ([`ActiveSetSolver::warm_start`]) instead of the previous call's. Errors: `z0` of the
    /// wrong length or not finite ([`QpError::Data`]).
    pub fn warm_start(&mut self, z0: &[f64]) -> Result<()> {
        self.active.warm_start(z0)
    }

    /// The last solution.
    pub fn z(&self) -> &[f64] {
        &self.z
    }

    /// Calls the active set could not finish (solved by Clarabel instead).
    pub fn fallbacks(&self) -> usize {
        self.fallbacks
    }

    /// Iterations of the last call (`None` after a fallback).
    pub fn last_info(&self) -> Option<ActiveSetInfo> {
        self.last_info
    }

    /// The problem (with its general rows, if any).
    pub fn problem(&self) -> &ParametricQp {
        match &self.general {
            Some(gi) => gi.problem(),
            None => self.active.problem(),
        }
    }
}
