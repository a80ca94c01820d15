//! The `[mhe]` settings built in Rust: [`MheBuilder`] fills the same raw table a scenario
//! file does and validates it with the same code ([`MheSettings::from_raw`]), so the file
//! format, the library API and the sweep share one validated type, [`MheSettings`].
//!
//! ```
//! use faer::mat;
//! use lti_model::LtiSystem;
//! use mhe_core::{Method, MheSets, MheSettings};
//! let sys = LtiSystem::new(mat![[1.0, 0.1], [0.0, 0.9]], mat![[0.0], [0.1]], mat![[1.0, 0.0]]).unwrap();
//! let settings = MheSettings::builder().horizon(10).eta(0.8).iterations(40)
//!     .method(Method::FISTA).build(&sys).unwrap(); // Q = I, R = I; P from LMI (2)
//! let mut mhe = settings.estimator(&sys, &MheSets::unconstrained(&sys), &[0.0, 0.0]).unwrap();
//! for t in 0..20 {
//!     let x_hat = mhe.estimate().unwrap().to_vec();
//!     mhe.push(&[0.1], &[x_hat[0] + 0.01 * t as f64]).unwrap();
//! }
//! ```

use faer::Mat;
use lti_model::LtiSystem;
use lti_model::spec::format::rows_of;
use qp_iter::{Method, MethodMap};

use crate::error::Result;
use crate::estimator::{MheEstimator, WarmStart};
use crate::problem::MheSets;
use crate::settings::{MheSettings, RawMhe};

/// Builder of [`MheSettings`]: every key of the `[mhe]` table as a method; what is not set
/// takes the file format's default (Q = I, R = I, P from LMI (2), PG, the paper's warm
/// start), and M, η and K are required, as in a file.
#[derive(Debug, Default)]
pub struct MheBuilder {
    raw: RawMhe,
}

impl MheSettings {
    /// A builder with no key set (see [`MheBuilder`]).
    pub fn builder() -> MheBuilder {
        MheBuilder::default()
    }

    /// The estimator these settings describe on `sys` with the sets `sets` and the initial
    /// prior x̄₀ = `prior` (P from LMI (2) when not given: the certified prior weight).
    pub fn estimator(
        &self,
        sys: &LtiSystem,
        sets: &MheSets,
        prior: &[f64],
    ) -> Result<MheEstimator<MethodMap>> {
        let cfg = self.config(sys, false)?;
        let method = self.method();
        MheEstimator::new(sys, sets, &cfg, prior, |qp| method.build(qp))
            .map_err(|e| self.explain(sys, e))
    }
}

impl MheBuilder {
    /// A builder holding `raw` ([`MheSettings::to_builder`]).
    pub(crate) fn from_raw(raw: RawMhe) -> Self {
        Self { raw }
    }
    /// M ≥ 1 (`mhe.horizon`, required).
    pub fn horizon(mut self, horizon: usize) -> Self {
        self.raw.horizon = Some(horizon);
        self
    }
    /// η ∈ [0, 1) (`mhe.eta`, required).
    pub fn eta(mut self, eta: f64) -> Self {
        self.raw.eta = Some(eta);
        self
    }
    /// K ≥ 1 iterations per time step (`mhe.iterations`, required).
    pub fn iterations(mut self, k: usize) -> Self {
        self.raw.iterations = Some(k);
        self
    }
    /// Φ (`mhe.method`, default projected gradient).
    pub fn method(mut self, method: Method) -> Self {
        self.raw.method = Some(method);
        self
    }
    /// The warm start Σ_t (`mhe.warm_start`, default the paper's).
    pub fn warm_start(mut self, warm_start: WarmStart) -> Self {
        self.raw.warm_start = Some(warm_start);
        self
    }
    /// Q ≻ 0, n_w square (`mhe.q`, default I).
    pub fn q(mut self, q: &Mat<f64>) -> Self {
        self.raw.q = Some(rows_of(q));
        self
    }
    /// R ≻ 0, n_y square (`mhe.r`, default I).
    pub fn r(mut self, r: &Mat<f64>) -> Self {
        self.raw.r = Some(rows_of(r));
        self
    }
    /// P ≻ 0, n_x square (`mhe.p`, default: computed from LMI (2)).
    pub fn p(mut self, p: &Mat<f64>) -> Self {
        self.raw.p = Some(rows_of(p));
        self
    }
    /// Validates against the plant exactly as a scenario's `[mhe]` table is validated
    /// (errors name the key: `mhe.eta`, …).
    pub fn build(&self, sys: &LtiSystem) -> Result<MheSettings> {
        Ok(MheSettings::from_raw(&self.raw, sys)?)
    }
}
