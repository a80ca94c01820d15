//! The `[mhe]` settings: owned, parsed and validated here, resolved once into an
//! [`MheConfig`] (with P of LMI (2) computed when the file does not give it).
//!
//! ```
//! use mhe_core::settings::{MheSettings, RawMhe};
//! use lti_model::LtiSystem;
//! let raw: RawMhe = lti_model::spec::format::parse("horizon = 5\neta = 0.8\niterations = 40\nmethod = \"fista\"").unwrap();
//! let sys = LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]]).unwrap();
//! let s = MheSettings::from_raw(&raw, &sys).unwrap();
//! assert_eq!(s.method(), qp_iter::Method::FISTA);
//! let cfg = s.config(&sys, false).unwrap(); // P from LMI (2)
//! assert_eq!(usize::from(cfg.iterations), 40);
//! ```

use faer::Mat;
use lti_model::LtiSystem;
use lti_model::spec::MatrixSpec;
use lti_model::spec::format::{
    at_least_one, check_dense_bytes, key_error, required, rows_of, weight,
};
use qp_iter::{Iterations, Method};
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use crate::error::{MheError, Result};
use crate::estimator::MheConfig;
use crate::problem::STRONG_CONVEXITY_TOL;

/// Largest K accepted (`mhe.iterations`): [`qp_iter::MAX_ITERATIONS`], the one budget limit.
pub const MAX_ITERATIONS: usize = qp_iter::MAX_ITERATIONS;

/// How z⁰_{t+1} is obtained from zᴷ_t (step 2 of Alg. 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum WarmStart {
    /// The paper's Σ_t: reuse zᴷ_t, zero-filling a new stage while the window grows.
    Paper,
    /// Time-shifted warm start (an extension; not covered by the paper's analysis).
    Shifted,
}

/// The validated `[mhe]` section. The fields are private: every value held passed
/// [`MheSettings::from_raw`] (or [`crate::MheBuilder::build`]), and a change goes through
/// [`MheSettings::to_builder`] (re-validated) or a setter whose argument is valid by its
/// type ([`MheSettings::with_iterations`], [`MheSettings::with_warm_start`]).
#[derive(Debug, Clone)]
pub struct MheSettings {
    horizon: usize,
    eta: f64,
    q: Mat<f64>,
    r: Mat<f64>,
    p: Option<Mat<f64>>,
    iterations: Iterations,
    method: Method,
    warm_start: WarmStart,
}

impl MheSettings {
    /// Horizon M ≥ 1 (`mhe.horizon`).
    pub fn horizon(&self) -> usize {
        self.horizon
    }
    /// Decay rate η ∈ [0, 1) of LMI (2) and cost (9) (`mhe.eta`).
    pub fn eta(&self) -> f64 {
        self.eta
    }
    /// Disturbance weight Q, n_w = n_w1 + n_w2 square, positive definite (default I).
    pub fn q(&self) -> &Mat<f64> {
        &self.q
    }
    /// Output weight R, n_y square, positive definite (default I).
    pub fn r(&self) -> &Mat<f64> {
        &self.r
    }
    /// Prior weight P of W_δ (eq. 3), n_x square, positive definite; `None` means
    /// "compute it from LMI (2)" ([`MheSettings::config`]).
    pub fn p(&self) -> Option<&Mat<f64>> {
        self.p.as_ref()
    }
    /// Iterations K of Φ per time step (`mhe.iterations`).
    pub fn iterations(&self) -> Iterations {
        self.iterations
    }
    /// The iteration map Φ (`mhe.method`, default projected gradient).
    pub fn method(&self) -> Method {
        self.method
    }
    /// Warm-start rule (default the paper's).
    pub fn warm_start(&self) -> WarmStart {
        self.warm_start
    }
    /// The same settings with K iterations per time step (valid by its type: nothing else
    /// depends on K, so nothing is re-validated).
    #[must_use]
    pub fn with_iterations(mut self, iterations: Iterations) -> Self {
        self.iterations = iterations;
        self
    }
    /// The same settings with another warm-start rule (nothing else depends on it).
    #[must_use]
    pub fn with_warm_start(mut self, warm_start: WarmStart) -> Self {
        self.warm_start = warm_start;
        self
    }
    /// A builder holding these settings, to change a value that is validated against the
    /// plant (M, η, a weight, Φ) and build again.
    pub fn to_builder(&self) -> crate::MheBuilder {
        crate::MheBuilder::from_raw(self.to_raw())
    }
}

/// Serde mirror of the `[mhe]` table: every key optional, unknown keys refused.
#[derive(Debug, Default)]
#[cfg_attr(feature = "serde", derive(Deserialize, Serialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct RawMhe {
    /// `horizon`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub horizon: Option<usize>,
    /// `eta`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub eta: Option<f64>,
    /// `q`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub q: Option<MatrixSpec>,
    /// `r`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub r: Option<MatrixSpec>,
    /// `p`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub p: Option<MatrixSpec>,
    /// `iterations`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub iterations: Option<usize>,
    /// `method` (`solver` is accepted as its older name).
    #[cfg_attr(
        feature = "serde",
        serde(alias = "solver", skip_serializing_if = "Option::is_none")
    )]
    pub method: Option<Method>,
    /// `warm_start`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub warm_start: Option<WarmStart>,
}

impl MheSettings {
    /// Validates the `[mhe]` table against the plant; errors name the key (`mhe.eta`). The
    /// sets are not known here: the memory check of `mhe.horizon` counts every state and
    /// output as bounded (an upper bound; [`MheSettings::from_raw_with_sets`] counts the
    /// scenario's own).
    pub fn from_raw(raw: &RawMhe, sys: &LtiSystem) -> lti_model::Result<Self> {
        Self::from_raw_with_sets(raw, sys, None)
    }

    /// [`MheSettings::from_raw`] with the scenario's sets: the memory check of `mhe.horizon`
    /// counts the general rows the MHE actually has (a finite state or output bound each), so
    /// a plant without state bounds is not refused for rows it never builds (issue 37 item
    /// 13: a 24-node rod at M = 30).
    pub fn from_raw_with_sets(
        raw: &RawMhe,
        sys: &LtiSystem,
        sets: Option<&lti_model::spec::ScenarioSets>,
    ) -> lti_model::Result<Self> {
        lti_model::work_count::record(lti_model::work_count::Work::MheSettingsValidated);
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
        let iterations =
            Iterations::new(iterations).map_err(|e| key_error("mhe.iterations", e.to_string()))?;
        // Before the size: a horizon the conditioning rules out is refused for that reason.
        check_window_conditioning(horizon, eta, sys)?;
        // The setup's heap from the sizes the code allocates by (crate::memory): every
        // window's QP, one Φ per window, the exact solvers of ε_t. Without the sets every
        // state and output is counted as bounded (an upper bound).
        let bounded = |b: &lti_model::BoxSet| {
            b.lower()
                .iter()
                .zip(b.upper())
                .filter(|(l, u)| l.is_finite() || u.is_finite())
                .count()
        };
        let (state_rows, output_rows) = sets.map_or((sys.nx(), sys.ny()), |s| {
            (bounded(&s.state), bounded(&s.output))
        });
        let bytes = crate::memory::setup_bytes(&crate::memory::SetupShape {
            nx: sys.nx(),
            nu: sys.nu(),
            ny: sys.ny(),
            nw: sys.nw(),
            state_rows,
            output_rows,
            horizon,
            method: raw.method.unwrap_or_default(),
            exact_solve: true,
        });
        check_dense_bytes(
            "mhe.horizon",
            &format!(
                "an MHE setup (one condensed QP, one Φ and one exact solver per window length up \
                 to M = {horizon})"
            ),
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
            iterations: Some(self.iterations.get()),
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
        Ok(MheConfig::new(
            self.horizon,
            self.eta,
            p,
            self.q.clone(),
            self.r.clone(),
            self.iterations,
        )
        .with_warm_start(self.warm_start)
        .with_exact_solve(exact_solve))
    }
}

/// η^(M−1) below which a window's condition number is kept by the horizon advice: 1e-8,
/// leaving four of the twelve digits of [`STRONG_CONVEXITY_TOL`] to the weights.
const DECAY_FLOOR: f64 = 1e-8;

/// The longest M with η^(M−1) ≥ [`DECAY_FLOOR`] (≥ 1), for advice.
fn longest_horizon(eta: f64) -> usize {
    if !(eta > 0.0) {
        return 1;
    }
    let m = 1.0 + (DECAY_FLOOR.ln() / eta.ln()).floor();
    if m.is_finite() && m >= 1.0 {
        m.min(1e9) as usize
    } else {
        1
    }
}

/// The smallest η with η^(M−1) ≥ [`DECAY_FLOOR`], for advice.
fn smallest_eta(horizon: usize) -> f64 {
    if horizon <= 1 {
        return 0.0;
    }
    DECAY_FLOOR.powf(1.0 / (horizon - 1) as f64)
}

/// Refuses an (M, η) whose longest window cannot be strongly convex in f64, before any
/// window is built. Stage j of the window of length M is weighted η^(M−1−j), and ŵ²_j
/// (j's output noise) enters only stage j, so with n_w2 ≥ 1 the Rayleigh quotients of
/// H_c along ŵ²_0 and ŵ²_{M−1} give λ_min/λ_max ≤ η^(M−1): at or below
/// [`STRONG_CONVEXITY_TOL`] the window is refused whatever the weights.
fn check_window_conditioning(horizon: usize, eta: f64, sys: &LtiSystem) -> lti_model::Result<()> {
    // η = 0 is legal for LMI (2) alone (`xtask certify`); building the MHE names it
    // ([`MheSettings::explain`]).
    if horizon < 2 || sys.nw2() == 0 || eta == 0.0 {
        return Ok(());
    }
    let decay = eta.powi(i32::try_from(horizon - 1).unwrap_or(i32::MAX));
    if decay > STRONG_CONVEXITY_TOL {
        return Ok(());
    }
    let condition = if decay > 0.0 {
        format!("at least 1/η^(M−1) = {:.3e}", 1.0 / decay)
    } else {
        "beyond any f64 (η^(M−1) underflows to 0)".to_string()
    };
    Err(key_error(
        "mhe.horizon",
        format!(
            "is {horizon} with `mhe.eta` = {eta}: the window's stage weights decay to \
             η^(M−1) = {decay:.3e}, so the condition number of the condensed Hessian H_c is \
             {condition}, beyond 1/{STRONG_CONVEXITY_TOL:e} where f64 cannot resolve it (the \
             MHE problem is not strongly convex numerically); {} (docs/limits.md)",
            horizon_advice(horizon, eta)
        ),
    ))
}

/// States whose balancing scales (`lti_model::ioss::state_scaling`) spread by more than
/// this are blamed for an ill-conditioned window before the weights: H_c's condition grows
/// like the square of the spread.
const UNITS_SPREAD: f64 = 1e2;

/// When the states' units differ in scale (spread of the balancing scaling T ≥
/// [`UNITS_SPREAD`]), the scaling to apply, with numbers (issue 37, item 7: AFTI-16 with its
/// speed in ft/s was refused as "weights too unequal" with Q = R = I).
fn units_advice(sys: &LtiSystem, q: &Mat<f64>, r: &Mat<f64>) -> Option<String> {
    let t = lti_model::ioss::state_scaling(sys, q.as_ref(), r.as_ref()).ok()?;
    let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = t.iter().copied().fold(0.0, f64::max);
    if !(lo > 0.0 && hi / lo >= UNITS_SPREAD) {
        return None;
    }
    let list: Vec<String> = t.iter().map(|v| format!("{:.3e}", v / lo)).collect();
    Some(format!(
        "balancing (A, E, C) gives the diagonal scaling x = T·x̃ with T = diag({}) (largest / \
         smallest = {:.1e}); measure state i in units t_i times larger: replace `plant.a` by \
         T⁻¹AT, `plant.b` by T⁻¹B, `plant.c` by CT, `plant.e` by T⁻¹E, and divide the state \
         bounds, `simulation.x0` and `simulation.prior` entrywise by t (docs/theory.md, \
         \"Assumption 2\")",
        list.join(", "),
        hi / lo
    ))
}

/// "use `mhe.horizon` ≤ M' at this η, or `mhe.eta` ≥ η' for this M" (the second part
/// only when some η < 1 keeps η^(M−1) ≥ [`DECAY_FLOOR`]).
fn horizon_advice(horizon: usize, eta: f64) -> String {
    let shorter = format!("use `mhe.horizon` ≤ {} at this η", longest_horizon(eta));
    let eta_min = smallest_eta(horizon);
    if eta_min < 0.9999 {
        format!("{shorter}, or `mhe.eta` ≥ {eta_min:.4} for this M")
    } else {
        format!("{shorter} (no η < 1 makes M = {horizon} well conditioned)")
    }
}

impl MheSettings {
    /// Says which scenario keys cause a failure to build the MHE from these settings: a
    /// window that is not strongly convex (`MheError::NotStronglyConvex`) or whose H_c is
    /// not finite is re-labelled as the key at fault — η = 0 (`mhe.eta`), an unstable A
    /// amplified over the window (`plant.a`, `mhe.horizon`), the decay η^(m−1)
    /// (`mhe.horizon`, `mhe.eta`), or else the weights (`mhe.q`, `mhe.r`, `mhe.p`, with
    /// `plant.c`, `plant.f`) — with the condition number and the fix. Other errors pass.
    pub fn explain(&self, sys: &LtiSystem, e: MheError) -> MheError {
        let (window, lo, hi) = match e {
            MheError::NotStronglyConvex {
                window,
                min_eigenvalue,
                max_eigenvalue,
            } => (window, min_eigenvalue, max_eigenvalue),
            MheError::Model(lti_model::ModelError::Numerical { ref routine, .. })
                if routine.contains("H_c") =>
            {
                (self.horizon, f64::NAN, f64::NAN)
            }
            other => return other,
        };
        let cond = if lo > 0.0 && hi.is_finite() {
            format!("λ_max/λ_min = {:.3e}", hi / lo)
        } else {
            format!("λ_min = {lo:.3e}, λ_max = {hi:.3e}")
        };
        let limit = format!("beyond 1/{STRONG_CONVEXITY_TOL:e}");
        let m = window;
        let eta = self.eta;
        if eta == 0.0 && m >= 1 {
            return key_error(
                "mhe.eta",
                format!(
                    "is 0: the prior gets weight η^m = 0, so the MHE problem of window length \
                     {m} is not strongly convex (H_c: {cond}); use η > 0 (e.g. 0.8)"
                ),
            )
            .into();
        }
        let rho = lti_model::system::spectral_radius(sys.a()).unwrap_or(f64::NAN);
        let decay = eta.powi(i32::try_from(m.saturating_sub(1)).unwrap_or(i32::MAX));
        if let Some((rho, growth, shorter)) = lti_model::system::unstable_over(rho, m) {
            return key_error(
                "plant.a",
                format!(
                    "is unstable (spectral radius ρ(A) = {rho:.4e}): over a window of m = {m} \
                     steps (`mhe.horizon` = {}) the predicted states grow like ρ^m = \
                     {growth:.3e}, so the condensed MHE Hessian H_c is numerically singular \
                     ({cond}, {limit}); use `mhe.horizon` ≤ {shorter} (ρ^M ≤ 1e3), or rescale \
                     or pre-stabilise the plant",
                    self.horizon
                ),
            )
            .into();
        }
        if decay < DECAY_FLOOR {
            return key_error(
                "mhe.horizon",
                format!(
                    "is {} with `mhe.eta` = {eta}: the stage weights of the window of length \
                     {m} decay to η^(m−1) = {decay:.3e}, so its condensed Hessian H_c is \
                     numerically singular ({cond}, {limit}); {}",
                    self.horizon,
                    horizon_advice(self.horizon, eta)
                ),
            )
            .into();
        }
        if let Some(advice) = units_advice(sys, &self.q, &self.r) {
            return key_error(
                "plant.a",
                format!(
                    "has states whose units differ in scale, which makes the MHE problem of \
                     window length {m} numerically not strongly convex ({cond}, {limit}) — \
                     not the weights: {advice}"
                ),
            )
            .into();
        }
        key_error(
            "mhe.q",
            format!(
                "with `mhe.r`, `mhe.p` (or the P of LMI (2)) and `plant.c`, `plant.f`, makes the \
                 MHE problem of window length {m} not strongly convex ({cond}, {limit}): the \
                 weights are too unequal in size, or x̂ is not determined by the window; \
                 rescale the weights towards the same magnitude"
            ),
        )
        .into()
    }
}

#[cfg(test)]
mod typed_tests {
    use super::*;

    fn sys() -> LtiSystem {
        LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]])
            .expect("a valid plant")
    }

    fn settings(text: &str) -> lti_model::Result<MheSettings> {
        let raw: RawMhe = lti_model::spec::format::parse(text)?;
        MheSettings::from_raw(&raw, &sys())
    }

    /// K is held as an `Iterations` (≥ 1 by type); a new K goes through `with_iterations`,
    /// and a value checked against the plant goes through `to_builder` and is re-validated.
    #[test]
    fn k_is_typed_and_changes_are_revalidated() {
        let s = settings("horizon = 5\neta = 0.8\niterations = 40").expect("valid");
        assert_eq!(s.iterations(), Iterations::new(40).expect("40 ≥ 1"));
        let s = s.with_iterations(Iterations::new(7).expect("7 ≥ 1"));
        assert_eq!((s.iterations().get(), s.to_raw().iterations), (7, Some(7)));
        let m = s
            .to_builder()
            .horizon(9)
            .build(&sys())
            .expect("M = 9 is valid");
        assert_eq!((m.horizon(), m.eta(), m.iterations().get()), (9, 0.8, 7));
        let e = s
            .to_builder()
            .eta(1.2)
            .build(&sys())
            .expect_err("η = 1.2 is refused");
        assert!(e.to_string().starts_with("MheBuilder::eta: is 1.2"), "{e}");
    }

    #[test]
    fn k_out_of_range_names_the_key_as_before() {
        for (k, text) in [
            (
                "0",
                "scenario: key `mhe.iterations`: is 0, but the iteration count K must be at \
                 least 1",
            ),
            (
                "10000001",
                "scenario: key `mhe.iterations`: is 10000001, above the limit 10000000 (each \
                 time step runs K iterations); a certified K beyond it is not practical to run",
            ),
        ] {
            let e = settings(&format!("horizon = 5\neta = 0.8\niterations = {k}"))
                .expect_err("refused");
            assert_eq!(e.to_string(), text);
        }
    }
}
