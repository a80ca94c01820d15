//! The `[mhe]` settings built in Rust: [`MheBuilder`] fills the same raw table a scenario
//! file does and validates it with the same code ([`MheSettings::from_raw`]), so the file
//! format, the library API and the sweep share one validated type, [`MheSettings`]. Its
//! errors name the builder method ([`MHE_NAMES`]: `MheBuilder::eta`, not the file key
//! `mhe.eta`).
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
use lti_model::spec::names::PLANT_NAMES;
use qp_iter::{Method, MethodMap};

use crate::error::{MheError, Result};
use crate::estimator::{MheEstimator, WarmStart};
use crate::problem::MheSets;
use crate::settings::{MheSettings, RawMhe};

/// The `[mhe]` keys and the [`MheBuilder`] methods that set them (an estimator's prior is
/// the `prior` argument of [`MheSettings::estimator`]).
pub const MHE_NAMES: [(&str, &str); 10] = [
    ("mhe.horizon", "MheBuilder::horizon"),
    ("mhe.eta", "MheBuilder::eta"),
    ("mhe.iterations", "MheBuilder::iterations"),
    ("mhe.q", "MheBuilder::q"),
    ("mhe.r", "MheBuilder::r"),
    ("mhe.p", "MheBuilder::p"),
    ("mhe.method", "MheBuilder::method"),
    ("mhe.warm_start", "MheBuilder::warm_start"),
    ("simulation.prior", "the prior of MheSettings::estimator"),
    ("simulation.x0", "the initial state"),
];

/// `e` as the Rust entry points report it: the `[mhe]` and plant keys named by the builder
/// methods and [`LtiSystem`] matrices ([`lti_model::ModelError::for_rust`]).
pub(crate) fn rust_named(e: MheError) -> MheError {
    match e {
        MheError::Model(m) => MheError::Model(m.for_rust(&[&MHE_NAMES, &PLANT_NAMES])),
        other => other,
    }
}

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
        let cfg = self.config(sys, false).map_err(rust_named)?;
        let method = self.method();
        MheEstimator::new(sys, sets, &cfg, prior, |qp| method.build(qp))
            .map_err(|e| rust_named(self.explain(sys, e)))
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
    /// Validates against the plant exactly as a scenario's `[mhe]` table is validated; the
    /// error is a [`lti_model::ModelError::Invalid`] naming the method that set the value
    /// (`MheBuilder::eta`, [`MHE_NAMES`]).
    pub fn build(&self, sys: &LtiSystem) -> Result<MheSettings> {
        MheSettings::from_raw(&self.raw, sys).map_err(|e| rust_named(MheError::Model(e)))
    }
}

#[cfg(test)]
mod tests {
    use lti_model::ModelError;
    use lti_model::spec::names::{PLANT_NAMES, rust_text};

    use super::*;
    use crate::settings::RawMhe;

    fn sys() -> LtiSystem {
        LtiSystem::new(
            faer::mat![[0.9, 0.1], [0.0, 0.8]],
            faer::mat![[0.0], [0.1]],
            faer::mat![[1.0, 0.0]],
        )
        .expect("a valid plant")
    }

    /// Every kind of `[mhe]` error on both entry points: the one check, the file naming the
    /// key (`mhe.q`) and the builder naming its method (`MheBuilder::q`), with the same
    /// problem text up to the names.
    #[test]
    fn each_error_names_the_key_in_a_file_and_the_method_in_rust() {
        let ok = || MheSettings::builder().horizon(3).eta(0.5).iterations(10);
        let i3 = Mat::<f64>::identity(3, 3);
        let not_pd = Mat::from_fn(3, 3, |i, j| if i == j { -1.0 } else { 0.0 });
        let nan = Mat::from_fn(3, 3, |i, j| if i == j { f64::NAN } else { 0.0 });
        let base = "horizon = 3\neta = 0.5\niterations = 10\n";
        let cases: Vec<(String, MheBuilder, &str)> = vec![
            (
                "eta = 0.5\niterations = 10".into(),
                MheSettings::builder().eta(0.5).iterations(10),
                "horizon",
            ),
            (
                "horizon = 3\niterations = 10".into(),
                MheSettings::builder().horizon(3).iterations(10),
                "eta",
            ),
            (
                "horizon = 3\neta = 0.5".into(),
                MheSettings::builder().horizon(3).eta(0.5),
                "iterations",
            ),
            (
                "horizon = 0\neta = 0.5\niterations = 10".into(),
                ok().horizon(0),
                "horizon",
            ),
            (
                "horizon = 3\neta = 1.2\niterations = 10".into(),
                ok().eta(1.2),
                "eta",
            ),
            (
                "horizon = 3\neta = nan\niterations = 10".into(),
                ok().eta(f64::NAN),
                "eta",
            ),
            (
                "horizon = 3\neta = 0.5\niterations = 0".into(),
                ok().iterations(0),
                "iterations",
            ),
            (
                "horizon = 3\neta = 0.5\niterations = 10000001".into(),
                ok().iterations(10_000_001),
                "iterations",
            ),
            (
                "horizon = 1048576\neta = 0.5\niterations = 10".into(),
                ok().horizon(1 << 20),
                "horizon",
            ),
            (
                "horizon = 60\neta = 0.5\niterations = 10".into(),
                ok().horizon(60),
                "horizon",
            ),
            (
                format!("{base}q = [[-1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]]"),
                ok().q(&not_pd),
                "q",
            ),
            (
                format!("{base}q = [[nan, 0, 0], [0, nan, 0], [0, 0, nan]]"),
                ok().q(&nan),
                "q",
            ),
            (
                format!("{base}r = [[1.0, 0], [0, 1.0]]"),
                ok().r(&Mat::identity(2, 2)),
                "r",
            ),
            (
                format!("{base}p = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]"),
                ok().p(&i3),
                "p",
            ),
        ];
        for (text, builder, name) in cases {
            let raw: RawMhe = lti_model::spec::format::parse(&text).expect("parses");
            let file = match MheSettings::from_raw(&raw, &sys()).expect_err("refused") {
                ModelError::Scenario { key, problem } => (key, problem),
                other => panic!("{text}: {other:?}"),
            };
            assert_eq!(file.0, format!("mhe.{name}"), "{text}");
            let rust = match builder.build(&sys()).expect_err("refused") {
                MheError::Model(ModelError::Invalid { field, problem }) => (field, problem),
                other => panic!("{text}: {other:?}"),
            };
            assert_eq!(rust.0, format!("MheBuilder::{name}"), "{text}");
            assert!(!rust.1.contains("mhe."), "{text}: {}", rust.1);
            assert_eq!(
                rust.1,
                rust_text(&file.1, &[&MHE_NAMES, &PLANT_NAMES]),
                "{text}"
            );
        }
    }

    /// An estimator that cannot be built (η = 0: the prior gets weight 0) is explained with
    /// the key on the file's path (`MheSettings::explain`) and the method on the Rust path.
    #[test]
    fn a_window_that_is_not_strongly_convex_names_the_method() {
        let s = MheSettings::builder()
            .horizon(3)
            .eta(0.0)
            .iterations(10)
            .p(&Mat::identity(2, 2))
            .build(&sys())
            .expect("η = 0 is valid for LMI (2) alone");
        let sets = MheSets::unconstrained(&sys());
        let e = s
            .estimator(&sys(), &sets, &[0.0, 0.0])
            .expect_err("not strongly convex");
        assert!(
            matches!(&e, MheError::Model(ModelError::Invalid { field, .. }) if field == "MheBuilder::eta"),
            "{e}"
        );
        let file = s.explain(
            &sys(),
            MheError::NotStronglyConvex {
                window: 1,
                min_eigenvalue: 0.0,
                max_eigenvalue: 1.0,
            },
        );
        assert!(
            matches!(&file, MheError::Model(ModelError::Scenario { key, .. }) if key == "mhe.eta"),
            "{file}"
        );
    }
}
