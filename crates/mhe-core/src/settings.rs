//! The `[mhe]` settings: owned, parsed and validated here, resolved once into an
//! [`MheConfig`] (with P of LMI (2) computed when the file does not give it).
//!
//! ```
//! use mhe_core::settings::{MheSettings, RawMhe};
//! use lti_model::LtiSystem;
//! let raw: RawMhe = lti_model::spec::format::parse("horizon = 5\neta = 0.8\niterations = 40\nmethod = \"fista\"").unwrap();
//! let sys = LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]]).unwrap();
//! let s = MheSettings::from_raw(&raw, &sys).unwrap();
//! assert_eq!(s.method, qp_iter::Method::FISTA);
//! let cfg = s.config(&sys, false).unwrap(); // P from LMI (2)
//! assert_eq!(cfg.iterations, 40);
//! ```

use faer::Mat;
use lti_model::LtiSystem;
use lti_model::spec::MatrixSpec;
use lti_model::spec::format::{
    at_least_one, check_dense_bytes, key_error, required, rows_of, weight,
};
use qp_iter::Method;
use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::estimator::MheConfig;

/// Largest K accepted (`mhe.iterations`).
pub const MAX_ITERATIONS: usize = 10_000_000;

/// How z⁰_{t+1} is obtained from zᴷ_t (step 2 of Alg. 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WarmStart {
    /// The paper's Σ_t: reuse zᴷ_t, zero-filling a new stage while the window grows.
    Paper,
    /// Time-shifted warm start (an extension; not covered by the paper's analysis).
    Shifted,
}

/// The validated `[mhe]` section.
#[derive(Debug, Clone)]
pub struct MheSettings {
    /// Horizon M ≥ 1 (`mhe.horizon`).
    pub horizon: usize,
    /// Decay rate η ∈ [0, 1) of LMI (2) and cost (9) (`mhe.eta`).
    pub eta: f64,
    /// Disturbance weight Q, n_w = n_w1 + n_w2 square, positive definite (default I).
    pub q: Mat<f64>,
    /// Output weight R, n_y square, positive definite (default I).
    pub r: Mat<f64>,
    /// Prior weight P of W_δ (eq. 3), n_x square, positive definite; `None` means
    /// "compute it from LMI (2)" ([`MheSettings::config`]).
    pub p: Option<Mat<f64>>,
    /// Iterations K ≥ 1 of Φ per time step (`mhe.iterations`).
    pub iterations: usize,
    /// The iteration map Φ (`mhe.method`, default projected gradient).
    pub method: Method,
    /// Warm-start rule (default the paper's).
    pub warm_start: WarmStart,
}

/// Serde mirror of the `[mhe]` table: every key optional, unknown keys refused.
#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RawMhe {
    /// `horizon`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub horizon: Option<usize>,
    /// `eta`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub eta: Option<f64>,
    /// `q`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub q: Option<MatrixSpec>,
    /// `r`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub r: Option<MatrixSpec>,
    /// `p`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p: Option<MatrixSpec>,
    /// `iterations`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
    /// `method` (`solver` is accepted as its older name).
    #[serde(alias = "solver", skip_serializing_if = "Option::is_none")]
    pub method: Option<Method>,
    /// `warm_start`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warm_start: Option<WarmStart>,
}

impl MheSettings {
    /// Validates the `[mhe]` table against the plant; errors name the key (`mhe.eta`).
    pub fn from_raw(raw: &RawMhe, sys: &LtiSystem) -> lti_model::Result<Self> {
        let horizon = required("mhe.horizon", raw.horizon, "horizon = 5")?;
        let horizon = at_least_one("mhe.horizon", horizon, "the estimation horizon M")?;
        let eta = required("mhe.eta", raw.eta, "eta = 0.8")?;
        if !(eta.is_finite() && (0.0..1.0).contains(&eta)) {
            return Err(key_error(
                "mhe.eta",
                format!("is {eta}, but η must lie in [0, 1) (Assumption 2); pick e.g. 0.8"),
            ));
        }
        let iterations = required("mhe.iterations", raw.iterations, "iterations = 50")?;
        let iterations = at_least_one("mhe.iterations", iterations, "the iteration count K")?;
        if iterations > MAX_ITERATIONS {
            return Err(key_error(
                "mhe.iterations",
                format!(
                    "is {iterations}, above the limit {MAX_ITERATIONS} (each time step runs K \
                     iterations); a certified K beyond it is not practical to run"
                ),
            ));
        }
        // One condensed QP per window length m = 0..M: n_m = n_x + m·n_w variables,
        // θ_m = n_x + m(n_u + n_y) parameters; H is n_m², F is n_m × θ_m.
        let (nx, nw) = (sys.nx() as f64, sys.nw() as f64);
        let nuy = (sys.nu() + sys.ny()) as f64;
        let mut bytes = 0.0;
        for m in 0..=horizon.min(1 << 20) {
            let (n, theta) = (nx + m as f64 * nw, nx + m as f64 * nuy);
            bytes += 8.0 * (n * n + n * theta);
            if bytes > lti_model::spec::format::MAX_DENSE_BYTES {
                break;
            }
        }
        check_dense_bytes(
            "mhe.horizon",
            &format!("condensed MHE QPs for windows up to M = {horizon}"),
            bytes,
        )?;
        let nw = sys.nw();
        let q = weight(
            "mhe.q",
            raw.q.as_ref(),
            nw,
            &format!("n_w = n_w1 + n_w2 = {nw} square"),
        )?;
        let r = weight(
            "mhe.r",
            raw.r.as_ref(),
            sys.ny(),
            &format!("n_y = {} square", sys.ny()),
        )?;
        let p = match raw.p.as_ref() {
            Some(spec) => Some(weight(
                "mhe.p",
                Some(spec),
                sys.nx(),
                &format!("n_x = {} square", sys.nx()),
            )?),
            None => None,
        };
        Ok(Self {
            horizon,
            eta,
            q,
            r,
            p,
            iterations,
            method: raw.method.unwrap_or_default(),
            warm_start: raw.warm_start.unwrap_or(WarmStart::Paper),
        })
    }

    /// The raw form (for writing a scenario back to TOML).
    pub fn to_raw(&self) -> RawMhe {
        RawMhe {
            horizon: Some(self.horizon),
            eta: Some(self.eta),
            q: Some(rows_of(&self.q)),
            r: Some(rows_of(&self.r)),
            p: self.p.as_ref().map(rows_of),
            iterations: Some(self.iterations),
            method: Some(self.method),
            warm_start: Some(self.warm_start),
        }
    }

    /// The estimator configuration: P is the file's, or is computed from LMI (2) with
    /// [`lti_model::ioss::certify`] (the one place it is solved for a scenario: resolve a
    /// scenario once and share the result).
    pub fn config(&self, sys: &LtiSystem, exact_solve: bool) -> Result<MheConfig> {
        let p = match &self.p {
            Some(p) => p.clone(),
            None => lti_model::ioss::certify(sys, self.eta, self.q.as_ref(), self.r.as_ref())?.p,
        };
        Ok(MheConfig {
            horizon: self.horizon,
            eta: self.eta,
            p,
            q: self.q.clone(),
            r: self.r.clone(),
            iterations: self.iterations,
            warm_start: self.warm_start,
            exact_solve,
        })
    }
}
