//! The exact MPC law π(x̂) = u*₀(x̂) (the paper's setting).
//!
//! By default the condensed box QP is solved by [`qp_iter::active_set`] (primal active set,
//! warm-started from the previous call's working set, allocation-free, every answer
//! KKT-verified); Clarabel ([`qp_iter::reference`]) is the fallback when the active-set
//! method stops without a verified optimum, and an explicit alternative backend.

use lti_model::{BoxSet, Projection};
use qp_iter::QpError;
use qp_iter::active_set::{ActiveSetInfo, ActiveSetSettings, ExactSolver};
#[cfg(feature = "clarabel")]
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};

use crate::condensed::CondensedMpc;
use crate::error::{MpcError, Result};
use crate::{ControlStatus, Controller, MpcFallback, check_io};

/// How [`ExactMpc`] computes U*(x̂).
///
/// `#[non_exhaustive]`: the `Clarabel` variant exists with the cargo feature `clarabel` (on by
/// default).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum ExactBackend {
    /// Primal active set (the default): a few hundred nanoseconds per warm-started call
    /// at the case study's size, no allocation; falls back to Clarabel with default
    /// settings if it stops without a verified optimum (counted by
    /// [`ExactMpc::fallbacks`]).
    ActiveSet(ActiveSetSettings),
    /// Clarabel's interior-point method and an active-set polish every call (≈ 100× slower,
    /// allocates): the independent reference.
    #[cfg(feature = "clarabel")]
    Clarabel(ReferenceSettings),
}

impl Default for ExactBackend {
    fn default() -> Self {
        Self::ActiveSet(ActiveSetSettings::default())
    }
}

#[derive(Debug)]
#[allow(clippy::large_enum_variant)] // one per controller, never moved in a hot loop
enum Backend {
    /// Active set with the Clarabel fallback.
    ActiveSet(ExactSolver),
    #[cfg(feature = "clarabel")]
    Clarabel(Box<ReferenceSolver>),
}

/// The QP's row as the composition traits report it (`loop-traits` knows no QP solver).
fn loop_row(row: qp_iter::ConstraintRow) -> loop_traits::ConstraintRow {
    match row {
        qp_iter::ConstraintRow::Box(i) => loop_traits::ConstraintRow::Box(i),
        qp_iter::ConstraintRow::General(i) => loop_traits::ConstraintRow::General(i),
    }
}

/// The exact condensed MPC: every call solves min ½UᵀHU + (Fx̂)ᵀU over 𝒰^N (and the
/// predicted-state rows, with state constraints) and returns u*₀, projected onto 𝒰 so that
/// it lies in 𝒰 exactly.
///
/// **Infeasible steps** (state constraints only): [`ExactMpc::solve`] returns the typed
/// error `MpcError::Qp(QpError::Infeasible { .. })`; [`Controller::control`] applies the
/// documented fallback — u*₀ of the input-constrained MPC, i.e. the same QP without the
/// state rows (always feasible) — and reports it in [`Controller::status`]
/// ([`ControlStatus::Infeasible`] with [`MpcFallback::InputOnlyMpc`]).
///
/// With the default [`ExactBackend::ActiveSet`], [`Controller::control`] allocates nothing
/// after construction (unless a Clarabel fallback is needed, which the tests never see on
/// the case study).
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{BoxSet, LtiSystem};
/// use mpc_core::{CondensedMpc, Controller, ExactMpc, MpcConfig};
/// let sys = LtiSystem::new(mat![[1.0, 0.1], [0.0, 1.0]], mat![[0.005], [0.1]], mat![[1.0, 0.0]]).unwrap();
/// let mpc = CondensedMpc::new(&sys, MpcConfig::new(5, Mat::identity(2, 2), mat![[0.1]],
///     BoxSet::symmetric(&[1.0]).unwrap())).unwrap();
/// let mut ctrl = ExactMpc::new(&mpc).unwrap();
/// let mut u = [0.0];
/// ctrl.control(&[50.0, 0.0], &mut u).unwrap();
/// assert_eq!(u, [-1.0]); // far away: saturated
/// assert_eq!(ctrl.fallbacks(), 0);
/// ```
#[derive(Debug)]
pub struct ExactMpc {
    backend: Backend,
    input_set: BoxSet,
    nx: usize,
    nu: usize,
    /// U*(x̂) of the last successful call.
    u_seq: Vec<f64>,
    solved: bool,
    last_info: Option<ActiveSetInfo>,
    /// With state constraints: the input-constrained MPC (rows dropped), the fallback of an
    /// infeasible step.
    input_only: Option<ExactSolver>,
    status: ControlStatus,
}

impl ExactMpc {
    /// The default backend: active set with Clarabel as the fallback.
    pub fn new(mpc: &CondensedMpc) -> Result<Self> {
        Self::with_backend(mpc, ExactBackend::default())
    }

    /// Clarabel with the given settings every call (the previous default; allocates).
    #[cfg(feature = "clarabel")]
    pub fn with_settings(mpc: &CondensedMpc, settings: ReferenceSettings) -> Result<Self> {
        Self::with_backend(mpc, ExactBackend::Clarabel(settings))
    }

    /// The given backend. Errors: invalid settings ([`MpcError::Qp`]).
    pub fn with_backend(mpc: &CondensedMpc, backend: ExactBackend) -> Result<Self> {
        let backend = match backend {
            ExactBackend::ActiveSet(settings) => {
                Backend::ActiveSet(ExactSolver::with_settings(mpc.qp(), settings)?)
            }
            #[cfg(feature = "clarabel")]
            ExactBackend::Clarabel(settings) => {
                Backend::Clarabel(Box::new(ReferenceSolver::new(mpc.qp(), settings)?))
            }
        };
        let input_only = if mpc.has_general_rows() {
            Some(ExactSolver::new(&mpc.qp().without_general())?)
        } else {
            None
        };
        Ok(Self {
            input_only,
            status: ControlStatus::Applied { violation: 0.0 },
            backend,
            input_set: mpc.input_set().clone(),
            nx: mpc.nx(),
            nu: mpc.nu(),
            u_seq: vec![0.0; mpc.qp().n()],
            solved: false,
            last_info: None,
        })
    }

    /// Solves for x̂ and returns the whole optimal sequence U*(x̂) = (u*₀, …, u*_{N−1}).
    ///
    /// Errors: [`MpcError::Dimension`] / [`MpcError::NonFinite`] for `x_hat`,
    /// [`MpcError::Solver`] if Clarabel (the backend or the fallback) does not solve it.
    pub fn solve(&mut self, x_hat: &[f64]) -> Result<&[f64]> {
        crate::error::check_len("x_hat", x_hat, self.nx)?;
        crate::error::check_finite("x_hat", x_hat)?;
        self.solved = false;
        self.last_info = None;
        match &mut self.backend {
            Backend::ActiveSet(solver) => {
                let z = solver.solve(x_hat).map_err(solver_error)?;
                self.u_seq.copy_from_slice(z);
                self.last_info = solver.last_info();
            }
            #[cfg(feature = "clarabel")]
            Backend::Clarabel(reference) => {
                let sol = reference.solve(x_hat).map_err(solver_error)?;
                self.u_seq.copy_from_slice(&sol.z);
            }
        }
        self.solved = true;
        Ok(&self.u_seq)
    }

    /// Forgets the active-set warm start (working set and cached factor), so that a
    /// controller reused across Monte-Carlo runs starts each run as a fresh one does. (The
    /// answer is the same optimum either way — the final subspace solve depends only on the
    /// optimal working set — the warm start changes how fast it is found.)
    pub fn reset(&mut self) {
        match &mut self.backend {
            Backend::ActiveSet(solver) => solver.reset(),
            #[cfg(feature = "clarabel")]
            Backend::Clarabel(_) => {}
        }
        self.solved = false;
        self.last_info = None;
    }

    /// U*(x̂) of the last successful call.
    pub fn input_sequence(&self) -> Option<&[f64]> {
        self.solved.then_some(&self.u_seq[..])
    }

    /// Calls the active-set backend could not finish and Clarabel solved instead.
    pub fn fallbacks(&self) -> usize {
        match &self.backend {
            Backend::ActiveSet(solver) => solver.fallbacks(),
            #[cfg(feature = "clarabel")]
            Backend::Clarabel(_) => 0,
        }
    }

    /// Iterations and factorisations of the last active-set solve (`None` with the
    /// Clarabel backend or after a fallback).
    pub fn last_info(&self) -> Option<ActiveSetInfo> {
        self.last_info
    }
}

fn solver_error(e: QpError) -> MpcError {
    match e {
        QpError::Reference { status } => MpcError::Solver { status },
        other => MpcError::Qp(other),
    }
}

impl Controller for ExactMpc {
    type Error = MpcError;
    fn control(&mut self, x_hat: &[f64], u: &mut [f64]) -> Result<()> {
        check_io(x_hat, u, self.nx, self.nu)?;
        let nu = self.nu;
        match self.solve(x_hat) {
            Ok(u_seq) => {
                u.copy_from_slice(&u_seq[..nu]);
                self.status = ControlStatus::Applied { violation: 0.0 };
            }
            Err(MpcError::Qp(QpError::Infeasible { constraint, .. })) => {
                let Some(fallback) = self.input_only.as_mut() else {
                    // Not reachable without state rows (a box is never empty).
                    return Err(MpcError::Qp(QpError::Infeasible {
                        solver: "exact MPC",
                        detail: "infeasible without state constraints".into(),
                        constraint,
                    }));
                };
                let z = fallback.solve(x_hat).map_err(solver_error)?;
                u.copy_from_slice(&z[..nu]);
                self.status = ControlStatus::Infeasible {
                    constraint: constraint.map(loop_row),
                    fallback: MpcFallback::InputOnlyMpc,
                };
            }
            Err(e) => return Err(e),
        }
        self.input_set.project(u);
        Ok(())
    }
    fn status(&self) -> ControlStatus {
        self.status
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn nx(&self) -> usize {
        self.nx
    }
}
