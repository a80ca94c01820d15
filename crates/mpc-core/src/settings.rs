//! The `[mpc]` settings: owned, parsed and validated here; [`MpcSettings::config`] turns
//! them, with the scenario's sets, into the [`MpcConfig`] of the condensed MPC.
//!
//! ```
//! use mpc_core::settings::{MpcSettings, RawMpc};
//! use lti_model::LtiSystem;
//! let raw: RawMpc = lti_model::spec::format::parse("horizon = 10\nr = 0.1").unwrap();
//! let sys = LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]]).unwrap();
//! let s = MpcSettings::from_raw(&raw, &sys).unwrap();
//! assert_eq!((s.horizon, s.r[(0, 0)]), (10, 0.1));
//! ```

use faer::Mat;
use lti_model::LtiSystem;
use lti_model::spec::format::{at_least_one, check_dense_bytes, required, rows_of, weight};
use lti_model::spec::{MatrixSpec, ScenarioSets};
use serde::{Deserialize, Serialize};

use crate::condensed::{MpcConfig, Terminal};

/// Terminal cost of the MPC (`mpc.terminal`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TerminalCost {
    /// Solution of the discrete algebraic Riccati equation for (A, B, Q_c, R_c).
    Dare,
}

/// The validated `[mpc]` section.
#[derive(Debug, Clone)]
pub struct MpcSettings {
    /// Prediction horizon N ≥ 1 (`mpc.horizon`).
    pub horizon: usize,
    /// Stage state weight Q_c, n_x square, positive definite (default I).
    pub q: Mat<f64>,
    /// Stage input weight R_c, n_u square, positive definite (default I).
    pub r: Mat<f64>,
    /// Terminal cost (default DARE).
    pub terminal: TerminalCost,
}

/// Serde mirror of the `[mpc]` table: every key optional, unknown keys refused.
#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RawMpc {
    /// `horizon`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub horizon: Option<usize>,
    /// `q`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub q: Option<MatrixSpec>,
    /// `r`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub r: Option<MatrixSpec>,
    /// `terminal`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub terminal: Option<TerminalCost>,
}

impl MpcSettings {
    /// Validates the `[mpc]` table against the plant; errors name the key (`mpc.r`).
    pub fn from_raw(raw: &RawMpc, sys: &LtiSystem) -> lti_model::Result<Self> {
        let horizon = required("mpc.horizon", raw.horizon, "horizon = 10")?;
        let horizon = at_least_one("mpc.horizon", horizon, "the prediction horizon N")?;
        // Condensed: H (N n_u)², the predictions (N n_x) × (N n_u), F (N n_u) × n_x.
        let (n, nu, nx) = (horizon as f64, sys.nu() as f64, sys.nx() as f64);
        let vars = n * nu;
        check_dense_bytes(
            "mpc.horizon",
            &format!("a condensed MPC with N·n_u = {vars} inputs"),
            8.0 * (vars * vars + n * nx * vars + vars * nx),
        )?;
        let q = weight(
            "mpc.q",
            raw.q.as_ref(),
            sys.nx(),
            &format!("n_x = {} square", sys.nx()),
        )?;
        let r = weight(
            "mpc.r",
            raw.r.as_ref(),
            sys.nu(),
            &format!("n_u = {} square", sys.nu()),
        )?;
        Ok(Self {
            horizon,
            q,
            r,
            terminal: raw.terminal.unwrap_or(TerminalCost::Dare),
        })
    }

    /// The raw form (for writing a scenario back to TOML).
    pub fn to_raw(&self) -> RawMpc {
        RawMpc {
            horizon: Some(self.horizon),
            q: Some(rows_of(&self.q)),
            r: Some(rows_of(&self.r)),
            terminal: Some(self.terminal),
        }
    }

    /// The condensed MPC's configuration with the input set `sets.input` and the state set
    /// `sets.state` (the latter must be the whole space, see [`MpcConfig::state_set`]).
    pub fn config(&self, sets: &ScenarioSets) -> MpcConfig {
        let terminal = match self.terminal {
            TerminalCost::Dare => Terminal::Dare,
        };
        MpcConfig {
            horizon: self.horizon,
            q_c: self.q.clone(),
            r_c: self.r.clone(),
            terminal,
            input_set: sets.input.clone(),
            state_set: Some(sets.state.clone()),
        }
    }
}
