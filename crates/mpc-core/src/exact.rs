//! The exact MPC law π(x̂) = u*₀(x̂) (the paper's setting), solved by Clarabel each call.

use lti_model::{BoxSet, Projection};
use qp_iter::QpError;
use qp_iter::reference::{ReferenceSettings, ReferenceSolution, ReferenceSolver};

use crate::condensed::CondensedMpc;
use crate::error::{MpcError, Result};
use crate::{Controller, check_io};

/// The exact condensed MPC: every call solves min ½UᵀHU + (Fx̂)ᵀU over 𝒰^N with
/// [`qp_iter::reference::ReferenceSolver`] (Clarabel, then an active-set polish accepted
/// only if it passes a KKT check) and returns u*₀, projected onto 𝒰 so that it lies in 𝒰
/// exactly (the projection moves it by at most the solver's feasibility tolerance).
///
/// **Allocates** on every call (Clarabel's solution vectors, the polish): meant for the
/// paper's exact-MPC setting, tests and analysis, not for allocation-free hot loops — use
/// [`crate::SuboptimalMpc`] there.
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
/// ```
#[derive(Debug)]
pub struct ExactMpc {
    solver: ReferenceSolver,
    input_set: BoxSet,
    nx: usize,
    nu: usize,
    last: Option<ReferenceSolution>,
}

impl ExactMpc {
    /// Clarabel with [`ReferenceSettings::default`] (tolerance 1e-11, polish on).
    pub fn new(mpc: &CondensedMpc) -> Result<Self> {
        Self::with_settings(mpc, ReferenceSettings::default())
    }

    /// Clarabel with the given settings.
    pub fn with_settings(mpc: &CondensedMpc, settings: ReferenceSettings) -> Result<Self> {
        let solver = ReferenceSolver::new(mpc.qp(), settings)?;
        Ok(Self {
            solver,
            input_set: mpc.input_set().clone(),
            nx: mpc.nx(),
            nu: mpc.nu(),
            last: None,
        })
    }

    /// Solves for x̂ and returns the whole optimal sequence U*(x̂) with multipliers.
    ///
    /// Errors: [`MpcError::Dimension`] / [`MpcError::NonFinite`] for `x_hat`,
    /// [`MpcError::Solver`] if Clarabel does not report `Solved`.
    pub fn solve(&mut self, x_hat: &[f64]) -> Result<&ReferenceSolution> {
        crate::error::check_len("x_hat", x_hat, self.nx)?;
        crate::error::check_finite("x_hat", x_hat)?;
        let sol = self.solver.solve(x_hat).map_err(|e| match e {
            QpError::Reference { status } => MpcError::Solver { status },
            other => MpcError::Qp(other),
        })?;
        Ok(self.last.insert(sol))
    }

    /// The solution of the last successful call.
    pub fn last_solution(&self) -> Option<&ReferenceSolution> {
        self.last.as_ref()
    }
}

impl Controller for ExactMpc {
    fn control(&mut self, x_hat: &[f64], u: &mut [f64]) -> Result<()> {
        check_io(x_hat, u, self.nx, self.nu)?;
        let nu = self.nu;
        let sol = self.solve(x_hat)?;
        u.copy_from_slice(&sol.z[..nu]);
        self.input_set.project(u);
        Ok(())
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn nx(&self) -> usize {
        self.nx
    }
}
