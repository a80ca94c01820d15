//! The `[mpc]` settings: owned, parsed and validated here; [`MpcSettings::config`] turns
//! them, with the scenario's sets, into the [`MpcConfig`] of the condensed MPC.
//!
//! ```
//! use mpc_core::settings::{MpcSettings, RawMpc};
//! use lti_model::LtiSystem;
//! let raw: RawMpc = lti_model::spec::format::parse("horizon = 10\nr = 0.1").unwrap();
//! let sys = LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]]).unwrap();
//! let s = MpcSettings::from_raw(&raw, &sys).unwrap();
//! assert_eq!((s.horizon(), s.r()[(0, 0)]), (10, 0.1));
//! ```

use faer::Mat;
use lti_model::LtiSystem;
use lti_model::spec::format::{
    at_least_one, key_error, required, rows_of, sized_matrix, weight, wrap,
};
use lti_model::spec::names::PLANT_NAMES;
use lti_model::spec::{MatrixSpec, ScenarioSets};
use qp_iter::Iterations;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use crate::condensed::{CondensedMpc, MpcConfig, Terminal};
use crate::error::MpcError;

/// Terminal cost of the MPC (`mpc.terminal`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum TerminalCost {
    /// Solution of the discrete algebraic Riccati equation for (A, B, Q_c, R_c).
    Dare,
}

/// The validated `[mpc]` section. The fields are private: every value held passed
/// [`MpcSettings::from_raw`], and a change goes through [`MpcSettings::to_raw`] and
/// [`MpcSettings::from_raw`] again, or a setter whose argument is valid by its type
/// ([`MpcSettings::with_iterations`]).
#[derive(Debug, Clone)]
pub struct MpcSettings {
    horizon: usize,
    q: Mat<f64>,
    r: Mat<f64>,
    terminal: TerminalCost,
    iterations: Option<Iterations>,
    method: qp_iter::Method,
    output: Option<lti_model::BoxSet>,
}

impl MpcSettings {
    /// Prediction horizon N ≥ 1 (`mpc.horizon`).
    pub fn horizon(&self) -> usize {
        self.horizon
    }
    /// Stage state weight Q_c, n_x square, positive semidefinite with (A, Q_c^½) detectable
    /// (default I; see [`crate::detectable`]).
    pub fn q(&self) -> &Mat<f64> {
        &self.q
    }
    /// Stage input weight R_c, n_u square, positive definite (default I).
    pub fn r(&self) -> &Mat<f64> {
        &self.r
    }
    /// Terminal cost (default DARE).
    pub fn terminal(&self) -> TerminalCost {
        self.terminal
    }
    /// K_c iterations of [`MpcSettings::method`] per step: the sub-optimal MPC
    /// ([`crate::SuboptimalMpc`], `mpc.iterations`); `None` is the exact MPC.
    pub fn iterations(&self) -> Option<Iterations> {
        self.iterations
    }
    /// The sub-optimal MPC's iteration map (`mpc.method`, default FISTA; only with
    /// `mpc.iterations`).
    pub fn method(&self) -> qp_iter::Method {
        self.method
    }
    /// Output constraints C x_k ∈ 𝒴_c on the predicted outputs k = 1..N (`mpc.output`, a
    /// box of n_y bounds containing 0; `None`: none). Not the MHE's `sets.output`.
    pub fn output(&self) -> Option<&lti_model::BoxSet> {
        self.output.as_ref()
    }
    /// The same settings with K_c iterations of [`MpcSettings::method`] per step (`Some`:
    /// the sub-optimal MPC) or the exact MPC (`None`); valid by its type, nothing else
    /// depends on it.
    #[must_use]
    pub fn with_iterations(mut self, iterations: Option<Iterations>) -> Self {
        self.iterations = iterations;
        self
    }
}

/// The sub-optimal MPC's Φ when `mpc.method` (or a sweep's `controller.solver`) is not
/// given: FISTA.
pub const DEFAULT_METHOD: qp_iter::Method = qp_iter::Method::FISTA;

/// Largest K accepted (`mpc.iterations`): [`qp_iter::MAX_ITERATIONS`], the one budget limit.
pub const MAX_ITERATIONS: usize = qp_iter::MAX_ITERATIONS;

/// Serde mirror of the `[mpc]` table: every key optional, unknown keys refused.
#[derive(Debug, Default)]
#[cfg_attr(feature = "serde", derive(Deserialize, Serialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct RawMpc {
    /// `horizon`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub horizon: Option<usize>,
    /// `q`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub q: Option<MatrixSpec>,
    /// `r`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub r: Option<MatrixSpec>,
    /// `terminal`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub terminal: Option<TerminalCost>,
    /// `iterations` (K_c of the sub-optimal MPC).
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub iterations: Option<usize>,
    /// `method` of the sub-optimal MPC.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub method: Option<qp_iter::Method>,
    /// `output`: the MPC's output box 𝒴_c.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub output: Option<lti_model::spec::Table<lti_model::spec::plant::RawBox>>,
}

/// Estimated peak heap bytes of [`CondensedMpc::new`] at horizon `n` for `nx` states and `nu`
/// inputs, from the sizes it allocates: with p = N n_x predicted states and v = N n_u inputs,
/// the dense block-diagonal Q̄ (p²), Γ and Γᵀ Q̄ (p·v each), R̄, the products and the Hessian
/// with the QP's copies (≈ 6 v²), the powers of A, Φ and F (small). Counted, not measured:
/// at the quadrotor's N = 1000 (p = 12 000, v = 4 000) it gives 2.5 GiB, the measured peak
/// was 2.4 GB.
pub fn condensed_bytes(n: usize, nx: usize, nu: usize) -> f64 {
    let (n, nx, nu) = (n as f64, nx as f64, nu as f64);
    let (p, v) = (n * nx, n * nu);
    8.0 * (p * p + 2.0 * p * v + 6.0 * v * v + (n + 1.0) * nx * nx + p * nx + v * nx)
}

impl MpcSettings {
    /// Validates the `[mpc]` table against the plant; errors name the key (`mpc.r`).
    pub fn from_raw(raw: &RawMpc, sys: &LtiSystem) -> lti_model::Result<Self> {
        if sys.nu() == 0 {
            return Err(key_error(
                "plant.b",
                format!(
                    "has 0 columns (n_u = 0), but the MPC of [mpc] computes inputs; give B as \
                     {} rows of n_u ≥ 1 entries, or remove [mpc]",
                    sys.nx()
                ),
            ));
        }
        let horizon = required("mpc.horizon", raw.horizon, "horizon = 10")?;
        let horizon = at_least_one("mpc.horizon", horizon, "the prediction horizon N")?;
        // Refused here, before anything is built (issue 37 item 13: a quadrotor at N = 1000
        // ran 137 s to 2.4 GB first): the peak of `CondensedMpc::new`, dominated by the dense
        // block-diagonal Q̄ of (N n_x)² entries.
        let bytes = condensed_bytes(horizon, sys.nx(), sys.nu());
        if bytes > lti_model::spec::format::MAX_DENSE_BYTES {
            // The estimate grows with N: bisect for the largest N within the limit.
            let fits = |n: usize| {
                condensed_bytes(n, sys.nx(), sys.nu()) <= lti_model::spec::format::MAX_DENSE_BYTES
            };
            let (mut lo, mut hi) = (0usize, horizon); // fits(lo) (N = 0: nothing), !fits(hi)
            while hi - lo > 1 {
                let mid = lo + (hi - lo) / 2;
                if fits(mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let largest = (lo >= 1).then_some(lo);
            return Err(key_error(
                "mpc.horizon",
                format!(
                    "is {horizon}: the condensed MPC (N·n_u = {} inputs, N·n_x = {} predicted \
                     states) needs an estimated {:.1} GiB of dense matrices to build, above the \
                     limit of {:.0} GiB (docs/limits.md); {}",
                    horizon.saturating_mul(sys.nu()),
                    horizon.saturating_mul(sys.nx()),
                    bytes / (1u64 << 30) as f64,
                    lti_model::spec::format::MAX_DENSE_BYTES / (1u64 << 30) as f64,
                    match largest {
                        Some(n) => format!("the largest N within it is {n}: set mpc.horizon ≤ {n}"),
                        None => "no N fits: reduce the plant's size".to_string(),
                    }
                ),
            ));
        }
        let q = state_weight(raw.q.as_ref(), sys)?;
        let r = weight(
            "mpc.r",
            raw.r.as_ref(),
            sys.nu(),
            &format!("n_u = {} square", sys.nu()),
        )?;
        let iterations = match raw.iterations {
            None => {
                if raw.method.is_some() {
                    return Err(key_error(
                        "mpc.method",
                        "is the sub-optimal MPC's method, but mpc.iterations is not set: add                          `iterations = 50` (K_c per step) or remove mpc.method for the exact MPC",
                    ));
                }
                None
            }
            Some(k) => Some(Iterations::new(k).map_err(|e| match e {
                qp_iter::IterationsError::AboveLimit { value, limit } => key_error(
                    "mpc.iterations",
                    format!(
                        "is {value}, above the limit {limit} (each time step runs K_c \
                         iterations); remove it for the exact MPC"
                    ),
                ),
                _ => key_error(
                    "mpc.iterations",
                    "is 0, but the MPC's iteration count K_c must be at least 1",
                ),
            })?),
        };
        let output = match raw.output.as_deref() {
            None => None,
            Some(b) => Some(lti_model::spec::plant::box_set(
                "mpc.output",
                Some(b),
                sys.ny(),
                "output",
            )?)
            .filter(|set| !set.is_whole()),
        };
        Ok(Self {
            output,
            horizon,
            q,
            r,
            terminal: raw.terminal.unwrap_or(TerminalCost::Dare),
            iterations,
            method: raw.method.unwrap_or(DEFAULT_METHOD),
        })
    }

    /// The raw form (for writing a scenario back to TOML).
    pub fn to_raw(&self) -> RawMpc {
        RawMpc {
            horizon: Some(self.horizon),
            q: Some(rows_of(&self.q)),
            r: Some(rows_of(&self.r)),
            terminal: Some(self.terminal),
            iterations: self.iterations.map(Iterations::get),
            method: self.iterations.map(|_| self.method),
            output: self
                .output
                .as_ref()
                .map(|b| lti_model::spec::Table(lti_model::spec::plant::raw_box(b))),
        }
    }

    /// The condensed MPC's configuration with the input set `sets.input`, the state set
    /// `sets.state` (predicted-state rows when bounded, see [`MpcConfig::state_set`]) and the
    /// output box `mpc.output` (predicted-output rows, [`MpcConfig::output_set`]).
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
            output_set: self.output.clone(),
        }
    }
}

impl MpcSettings {
    /// The condensed MPC of these settings on `sys` ([`CondensedMpc::new`] with
    /// [`MpcSettings::config`]), a failure named by its scenario key
    /// ([`MpcSettings::explain`]).
    pub fn build(&self, sys: &LtiSystem, sets: &ScenarioSets) -> crate::Result<CondensedMpc> {
        CondensedMpc::new(sys, self.config(sets)).map_err(|e| self.explain(sys, e))
    }

    /// Says which scenario keys cause a numerical failure of the MPC built from these
    /// settings: the DARE of the terminal cost (no stabilizing solution: `plant.a`,
    /// `plant.b`, `mpc.q`) and a condensed Hessian H = 2(ΓᵀQ̄Γ + R̄) that is not positive
    /// definite or not finite in f64 although `mpc.r` is — an unstable A amplified over the
    /// horizon (`plant.a`, `mpc.horizon`), or else the scale of the prediction term against
    /// `mpc.r`. Other errors (already naming a key, or not numerical) pass unchanged.
    pub fn explain(&self, sys: &LtiSystem, e: MpcError) -> MpcError {
        use lti_model::ModelError;
        let rho = || lti_model::system::spectral_radius(sys.a()).unwrap_or(f64::NAN);
        match e {
            MpcError::Model(ModelError::Numerical { routine, reason })
                if routine.starts_with("DARE") =>
            {
                // A badly scaled entry (1e50 in a Schur-stable A, `mpc.q = 1e100`) breaks the
                // Riccati iteration in f64: named as such, not as "not stabilizable".
                if let Some(e) = badly_scaled(&[
                    ("plant.a", sys.a()),
                    ("plant.b", sys.b()),
                    ("mpc.q", self.q.as_ref()),
                    ("mpc.r", self.r.as_ref()),
                ]) {
                    return e;
                }
                key_error(
                    "plant.b",
                    format!(
                        "cannot stabilise `plant.a` (spectral radius ρ(A) = {:.4e}): the terminal \
                         cost `mpc.terminal` = \"dare\" needs (A, B) stabilizable and every \
                         unstable mode of A seen by `mpc.q`, and the Riccati equation has no \
                         stabilizing solution ({reason}); give B a column that reaches every \
                         unstable mode, use `mpc.q` ≻ 0, or rescale the plant",
                        rho()
                    ),
                )
                .into()
            }
            MpcError::Qp(qp_iter::QpError::Data(
                qp_iter::DataError::NotPositiveDefinite { ref name, .. }
                | qp_iter::DataError::NonFinite { ref name, .. }
                | qp_iter::DataError::Numerical {
                    routine: ref name, ..
                },
            )) if name.contains('H') || name.contains('F') => {
                let n = self.horizon;
                let r_min = lti_model::matrix::sym_extreme_eigenvalues("R_c", self.r.as_ref())
                    .map_or(f64::NAN, |(lo, _)| lo);
                if let Some((rho, growth, shorter)) = lti_model::system::unstable_over(rho(), n) {
                    return key_error(
                        "plant.a",
                        format!(
                            "is unstable (spectral radius ρ(A) = {rho:.4e}): over the MPC horizon \
                             `mpc.horizon` = {n} the predictions grow like ρ^N = {growth:.3e}, so \
                             the condensed Hessian H = 2(ΓᵀQ̄Γ + R̄) loses `mpc.r` (λ_min = \
                             {r_min:.3e}) to rounding and is not positive definite in f64; use \
                             `mpc.horizon` ≤ {shorter} (ρ^N ≤ 1e3), or pre-stabilise or rescale \
                             the plant"
                        ),
                    )
                    .into();
                }
                key_error(
                    "mpc.r",
                    format!(
                        "(λ_min = {r_min:.3e}) is lost to rounding next to the prediction term \
                         ΓᵀQ̄Γ built from `plant.a`, `plant.b`, `mpc.q` and the DARE terminal \
                         weight over `mpc.horizon` = {n} steps: the condensed Hessian is not \
                         positive definite (or not finite) in f64; increase `mpc.r` or rescale \
                         `plant.b` and `mpc.q` towards the size of `mpc.r`"
                    ),
                )
                .into()
            }
            MpcError::NotDetectable { mode } => key_error(
                "mpc.q",
                format!(
                    "is singular and the mode {mode} of `plant.a` is not seen by it and does not \
                     decay, so (A, Q_c^½) is not detectable and the DARE terminal cost has no \
                     stabilising solution; give a positive weight to one of those state \
                     components in `mpc.q` (or make `mpc.q` positive definite)"
                ),
            )
            .into(),
            MpcError::Model(e @ ModelError::Scenario { .. }) => e.into(),
            MpcError::Qp(qp_iter::QpError::Data(e)) => self.explain(sys, MpcError::Model(e.into())),
            MpcError::Model(e) => key_error(
                "mpc",
                format!(
                    "the MPC cannot be built from `plant.a`, `plant.b`, `mpc.q`, `mpc.r` over \
                     `mpc.horizon` = {}: {e}; rescale the model towards entries of similar size",
                    self.horizon
                ),
            )
            .into(),
            other => other,
        }
    }
}

impl MpcSettings {
    /// A builder with no key set (see [`MpcBuilder`]).
    ///
    /// ```
    /// use lti_model::LtiSystem;
    /// use mpc_core::MpcSettings;
    /// let sys = LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]]).unwrap();
    /// let s = MpcSettings::builder().horizon(10).r(&faer::mat![[0.1]]).iterations(30).build(&sys)?;
    /// assert_eq!((s.horizon(), s.iterations().map(|k| k.get())), (10, Some(30)));
    /// # Ok::<(), mpc_core::MpcError>(())
    /// ```
    pub fn builder() -> MpcBuilder {
        MpcBuilder::default()
    }

    /// A builder holding these settings, to change a value and validate again.
    pub fn to_builder(&self) -> MpcBuilder {
        MpcBuilder { raw: self.to_raw() }
    }
}

/// Builder of [`MpcSettings`]: every key of the `[mpc]` table as a method; what is not set
/// takes the file format's default (Q_c = I, R_c = I, the DARE terminal cost, the exact
/// MPC), and N is required, as in a file.
#[derive(Debug, Default)]
pub struct MpcBuilder {
    raw: RawMpc,
}

impl MpcBuilder {
    /// N ≥ 1 (`mpc.horizon`, required).
    pub fn horizon(mut self, horizon: usize) -> Self {
        self.raw.horizon = Some(horizon);
        self
    }
    /// Q_c ⪰ 0, n_x square, (A, Q_c^½) detectable (`mpc.q`, default I).
    pub fn q(mut self, q: &Mat<f64>) -> Self {
        self.raw.q = Some(rows_of(q));
        self
    }
    /// R_c ≻ 0, n_u square (`mpc.r`, default I).
    pub fn r(mut self, r: &Mat<f64>) -> Self {
        self.raw.r = Some(rows_of(r));
        self
    }
    /// The terminal cost (`mpc.terminal`, default DARE).
    pub fn terminal(mut self, terminal: TerminalCost) -> Self {
        self.raw.terminal = Some(terminal);
        self
    }
    /// K_c ≥ 1 iterations per step: the sub-optimal MPC (`mpc.iterations`; unset: exact).
    pub fn iterations(mut self, k: usize) -> Self {
        self.raw.iterations = Some(k);
        self
    }
    /// The sub-optimal MPC's Φ (`mpc.method`, default FISTA; only with iterations).
    pub fn method(mut self, method: qp_iter::Method) -> Self {
        self.raw.method = Some(method);
        self
    }
    /// The output box 𝒴_c of the predicted outputs (`mpc.output`, default none).
    pub fn output(mut self, output: &lti_model::BoxSet) -> Self {
        self.raw.output = Some(lti_model::spec::Table(lti_model::spec::plant::raw_box(
            output,
        )));
        self
    }
    /// The `[mpc]` table these calls describe (for the scenario layer).
    pub fn into_raw(self) -> RawMpc {
        self.raw
    }
    /// Validates against the plant exactly as a scenario's `[mpc]` table is validated; the
    /// error is a [`lti_model::ModelError::Invalid`] naming the method that set the value
    /// (`MpcBuilder::r`, [`MPC_NAMES`]).
    pub fn build(&self, sys: &LtiSystem) -> crate::Result<MpcSettings> {
        MpcSettings::from_raw(&self.raw, sys)
            .map_err(|e| MpcError::Model(e.for_rust(&[&MPC_NAMES, &PLANT_NAMES])))
    }
}

/// The `[mpc]` keys and the [`MpcBuilder`] methods that set them.
pub const MPC_NAMES: [(&str, &str); 7] = [
    ("mpc.horizon", "MpcBuilder::horizon"),
    ("mpc.q", "MpcBuilder::q"),
    ("mpc.r", "MpcBuilder::r"),
    ("mpc.terminal", "MpcBuilder::terminal"),
    ("mpc.iterations", "MpcBuilder::iterations"),
    ("mpc.method", "MpcBuilder::method"),
    ("mpc.output", "MpcBuilder::output"),
];

/// `mpc.q`: n_x square, finite, symmetric, positive *semi*definite (default I); a singular
/// Q_c must leave no non-decaying mode of A unseen ((A, Q_c^½) detectable, so that the DARE
/// terminal cost exists). Errors name `mpc.q`, the mode and the fix.
fn state_weight(spec: Option<&MatrixSpec>, sys: &LtiSystem) -> lti_model::Result<Mat<f64>> {
    let nx = sys.nx();
    let Some(spec) = spec else {
        return Ok(Mat::identity(nx, nx));
    };
    let m = sized_matrix("mpc.q", spec, nx, nx, &format!("n_x = {nx} square"))?;
    if let Err(e) = crate::condensed::check_psd("Q_c", &m, nx) {
        return Err(match e {
            MpcError::Model(e) => wrap("mpc.q", e),
            MpcError::NotPositiveSemidefinite { min_eigenvalue, .. } => key_error(
                "mpc.q",
                format!(
                    "is not positive semidefinite (smallest eigenvalue {min_eigenvalue:e}); the \
                     stage weight Q_c must be symmetric with nonnegative eigenvalues"
                ),
            ),
            other => key_error("mpc.q", other.to_string()),
        });
    }
    if crate::condensed::is_singular(&m) {
        match crate::detectable::undetectable_modes(sys.a(), m.as_ref()) {
            Ok(modes) if modes.is_empty() => {}
            Ok(modes) => {
                return Err(key_error(
                    "mpc.q",
                    format!(
                        "is singular, which is allowed when (A, Q_c^½) is detectable, but the mode \
                         {} of `plant.a` is not seen by `mpc.q` and does not decay (|λ| ≥ 1), so \
                         the DARE terminal cost has no stabilising solution and the MPC would not \
                         penalise that mode; give a positive weight to one of those state \
                         components in `mpc.q` (or make `mpc.q` positive definite)",
                        modes[0]
                    ),
                ));
            }
            Err(e) => return Err(key_error("mpc.q", e.to_string())),
        }
    }
    Ok(m)
}

/// Ratio of the largest to the smallest nonzero entry magnitude of the MPC's data beyond
/// which a failed Riccati equation is reported as bad scaling: 1e12 (the DARE's iterates
/// lose every significant digit of the small entries in f64 well before 1e16).
pub const BADLY_SCALED_RATIO: f64 = 1e12;

/// The error naming the largest entry of `mats` (scenario key, matrix) when it is more than
/// [`BADLY_SCALED_RATIO`] times the smallest nonzero one; None when the data are scaled
/// within that range.
fn badly_scaled(mats: &[(&str, faer::MatRef<'_, f64>)]) -> Option<MpcError> {
    let mut big: Option<(&str, usize, usize, f64)> = None;
    let mut small: Option<(&str, f64)> = None;
    for &(key, m) in mats {
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                let v = m[(i, j)].abs();
                if v == 0.0 || !v.is_finite() {
                    continue;
                }
                if big.is_none_or(|b| v > b.3) {
                    big = Some((key, i, j, v));
                }
                if small.is_none_or(|s| v < s.1) {
                    small = Some((key, v));
                }
            }
        }
    }
    let ((key, i, j, hi), (small_key, lo)) = (big?, small?);
    (hi > BADLY_SCALED_RATIO * lo).then(|| {
        key_error(
            key,
            format!(
                "is badly scaled: entry ({i}, {j}) is {hi:.3e}, {:.3e} times the smallest nonzero \
                 entry ({lo:.3e}, in `{small_key}`) of `plant.a`, `plant.b`, `mpc.q`, `mpc.r`; the \
                 Riccati equation of `mpc.terminal` = \"dare\" cannot be solved in f64 across \
                 that range (the limit is {BADLY_SCALED_RATIO:e}); rescale the units of the model",
                hi / lo
            ),
        )
        .into()
    })
}

#[cfg(test)]
mod suboptimal_key_tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use lti_model::ModelError;

    fn settings(text: &str) -> lti_model::Result<MpcSettings> {
        let raw: RawMpc = lti_model::spec::format::parse(text)?;
        let sys = LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]]).unwrap();
        MpcSettings::from_raw(&raw, &sys)
    }

    #[test]
    fn iterations_select_the_suboptimal_mpc_and_round_trip() {
        let s = settings("horizon = 5\niterations = 40\nmethod = \"pg\"").unwrap();
        assert_eq!(
            (s.iterations().map(Iterations::get), s.method()),
            (Some(40), qp_iter::Method::PG)
        );
        let s = settings("horizon = 5\niterations = 40").unwrap();
        assert_eq!(s.method(), qp_iter::Method::FISTA);
        let raw = s.to_raw();
        assert_eq!(
            (raw.iterations, raw.method),
            (Some(40), Some(qp_iter::Method::FISTA))
        );
        assert_eq!(settings("horizon = 5").unwrap().iterations(), None);
    }

    /// K_c is an `Option<Iterations>`; the builder validates as a file does and
    /// `to_builder` round-trips.
    #[test]
    fn the_builder_validates_and_round_trips() {
        let sys = LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]]).unwrap();
        let s = MpcSettings::builder()
            .horizon(4)
            .iterations(12)
            .method(qp_iter::Method::PG)
            .build(&sys)
            .unwrap();
        assert_eq!(s.iterations(), Some(Iterations::new(12).unwrap()));
        let exact = s.clone().with_iterations(None);
        assert_eq!((exact.iterations(), exact.to_raw().method), (None, None));
        let again = s.to_builder().build(&sys).unwrap();
        assert_eq!((again.horizon(), again.method()), (4, qp_iter::Method::PG));
        let e = MpcSettings::builder()
            .horizon(4)
            .iterations(0)
            .build(&sys)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "MpcBuilder::iterations: is 0, but the MPC's iteration count K_c must be at least 1"
        );
    }

    /// Every kind of `[mpc]` error on both entry points: the same check, the file naming the
    /// key (`mpc.r`) and the builder naming its method (`MpcBuilder::r`), with the same
    /// problem text up to the names.
    #[test]
    fn each_error_names_the_key_in_a_file_and_the_method_in_rust() {
        let sys = LtiSystem::new(faer::mat![[0.5]], faer::mat![[1.0]], faer::mat![[1.0]]).unwrap();
        let b = MpcSettings::builder;
        let cases: [(&str, MpcBuilder, &str); 7] = [
            ("", b(), "horizon"),
            ("horizon = 0", b().horizon(0), "horizon"),
            ("horizon = 16777216", b().horizon(1 << 24), "horizon"),
            (
                "horizon = 3\nr = [[0.0]]",
                b().horizon(3).r(&faer::mat![[0.0]]),
                "r",
            ),
            (
                "horizon = 3\nq = [[1.0, 0.0]]",
                b().horizon(3).q(&faer::mat![[1.0, 0.0]]),
                "q",
            ),
            (
                "horizon = 3\niterations = 0",
                b().horizon(3).iterations(0),
                "iterations",
            ),
            (
                "horizon = 3\nmethod = \"pg\"",
                b().horizon(3).method(qp_iter::Method::PG),
                "method",
            ),
        ];
        for (text, builder, name) in cases {
            let file = match settings(text).unwrap_err() {
                ModelError::Scenario { key, problem } => (key, problem),
                other => panic!("{text}: {other:?}"),
            };
            assert_eq!(file.0, format!("mpc.{name}"), "{text}");
            let rust = match builder.build(&sys).unwrap_err() {
                MpcError::Model(ModelError::Invalid { field, problem }) => (field, problem),
                other => panic!("{text}: {other:?}"),
            };
            assert_eq!(rust.0, format!("MpcBuilder::{name}"), "{text}");
            assert!(!rust.1.contains("mpc."), "{text}: {}", rust.1);
            let renamed = lti_model::spec::names::rust_text(&file.1, &[&MPC_NAMES, &PLANT_NAMES]);
            assert_eq!(rust.1, renamed, "{text}");
        }
    }

    #[test]
    fn bad_iterations_and_orphan_method_name_the_key() {
        for (text, key) in [
            ("horizon = 5\niterations = 0", "mpc.iterations"),
            ("horizon = 5\niterations = 99999999999", "mpc.iterations"),
            ("horizon = 5\nmethod = \"pg\"", "mpc.method"),
            ("horizon = 5\niterations = 3\nmethod = \"newton\"", "method"),
        ] {
            let e = settings(text).unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        }
    }
}
