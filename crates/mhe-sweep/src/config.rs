//! The sweep configuration: [`SweepConfig`], read from TOML through serde (every table
//! `deny_unknown_fields`) and `serde_path_to_error`, then validated, and the grid of
//! [`Point`]s it spans.
//!
//! Like the scenario file, parsing runs in two stages: the text is deserialised into
//! private `Raw*` mirror structs whose keys are all optional, so a type error names the
//! full key path it happened at (`k.points`, `solvers[1]`, `controller.iterations`); then
//! [`SweepConfig`] is built from them, checking every value and limit and naming the key
//! of each failure.

use std::fmt::{self, Write as _};

use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde::de::{self, MapAccess, Visitor};

use super::error::{Result, SweepError, config_err};
use super::grid::{RawK, k_c_grid, k_grid, positive};
use super::region::IterationCost;
use super::{ControllerChoice, Method};
use closed_loop::metrics::{DEFAULT_BOUNDED_FACTOR, Metric};
use closed_loop::sim::ClosedLoopError;

/// Largest K accepted in a grid (a run costs T·K iterations).
pub const MAX_K: usize = qp_iter::MAX_ITERATIONS;
/// Largest horizon T accepted (a run's trace, MHE records included, is preallocated:
/// about 1 KiB per step for the case study, per worker thread).
pub const MAX_STEPS: usize = lti_model::spec::plant::MAX_STEPS;
/// Largest number of seeds per point.
pub const MAX_SEEDS: usize = 10_000_000;

/// A validated sweep configuration (a TOML file; see `docs/sweeps.md`).
///
/// ```
/// use mhe_sweep::SweepConfig;
/// let cfg = SweepConfig::from_toml_str(r#"
///     name = "demo"
///     scenario = "../scenarios/case-study.toml"
///     k = { from = 1, to = 1000, points = 4 }
///     solvers = ["pg", "fista"]
///     seeds = 8
/// "#, std::path::Path::new("sweeps")).unwrap();
/// assert_eq!(cfg.k_grid, vec![1, 10, 100, 1000]);
/// assert_eq!(cfg.points().len(), 8);
/// assert!(SweepConfig::from_toml_str("name = 'x'\nscenario = 's'\nk = []\nsolvers = ['pg']\nseeds = 1",
///     std::path::Path::new(".")).is_err()); // empty K grid
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct SweepConfig {
    /// Name of the sweep (`name`): labels the outputs, default output directory
    /// `target/sweeps/<name>`.
    pub name: String,
    /// The scenario file (`scenario`), resolved against the config file's directory.
    pub scenario: PathBuf,
    /// The iteration budgets K (`k`: a list, or `{ from, to, points }` log-spaced), sorted,
    /// without duplicates, each ≥ 1.
    pub k_grid: Vec<usize>,
    /// The MHE's iteration maps Φ (`solvers`, any of `"pg"`, `"fista"`, `"admm"`, `"admm-pr"`).
    pub solvers: Vec<Method>,
    /// Runs per point (`seeds` ≥ 1).
    pub seeds: usize,
    /// Disturbance scales (`scales`, each ≥ 0, finite): the scenario's `noise.scale` is set
    /// to each in turn. `None` keeps the scenario's.
    pub scales: Option<Vec<f64>>,
    /// Horizon T (`steps`); `None` keeps the scenario's `simulation.steps`.
    pub steps: Option<usize>,
    /// Base seed of the run seeds (`base_seed`; default: the scenario's `noise.seed`).
    pub base_seed: Option<u64>,
    /// Also solve every ℙ_t exactly to record ε_t (`exact_mhe_solve`, default false: it
    /// adds one active-set solve of the MHE QP per step).
    pub exact_mhe_solve: bool,
    /// The controller π (`controller`: `"exact-mpc"` (default), `"saturated-lqr"`, or
    /// `{ kind = "suboptimal-mpc", iterations = Kc, solver = "pg" }`). In a 2-D sweep
    /// (`k_c` given) it is the sub-optimal MPC with `iterations` = the smallest K_c of the
    /// grid; every point runs its own K_c ([`SweepConfig::controller_at`]).
    pub controller: ControllerChoice,
    /// The MPC's iteration budgets K_c (`k_c`, a list or `{ from, to, points }` like `k`),
    /// sorted, without duplicates: a 2-D sweep over (K_e, K_c) = (`k`, `k_c`). Only with the
    /// sub-optimal MPC, whose `iterations` it replaces. `None`: a 1-D sweep over K.
    pub k_c_grid: Option<Vec<usize>>,
    /// The weights of the cost K_e·t_e + K_c·t_c by which a 2-D sweep picks its cheapest
    /// stable pair (`cost = { t_e, t_c }`, default 1:1; only with `k_c`).
    pub cost: IterationCost,
    /// The metrics kept (`metrics`; default: all, `sup_eps` only with the exact solve).
    pub metrics: Vec<Metric>,
    /// Same disturbance draw for run r at every point (`common_random_numbers`, default
    /// true); false mixes the point (K, solver, scale) into the seed.
    pub common_random_numbers: bool,
    /// A run is bounded when it completes with finite values and sup‖x‖ ≤
    /// `bounded_factor`·(1 + ‖x₀‖) (`bounded_factor`, default 1000).
    pub bounded_factor: f64,
    /// Compute the theoretical columns from the closed-loop certificate (`certificate`,
    /// default true; false writes them as void, e.g. for quick tests: the certificate
    /// takes seconds).
    pub certificate: bool,
    /// Compute ρ_lin(K) and K_lin of the lifted loop on the sweep's K grid (`linear`,
    /// default true; `iss_certificate::linear`, one eigenvalue problem of dim 𝔸(K) per K and solver).
    pub linear: bool,
    /// Also run the Kalman filter of the MHE's weights in place of the MHE (`estimators =
    /// ["mhe", "kalman"]`; default `["mhe"]`): the same controller and, run by run, the same
    /// draws; written to `kalman.csv` (`mhe_sweep::baseline`).
    pub kalman: bool,
}

// ---------------------------------------------------------------------------------------
// Raw mirror of the file (stage 1: types and key paths)
// ---------------------------------------------------------------------------------------

/// The keys of a sweep config, all optional (missing keys are reported in stage 2).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawConfig {
    name: Option<String>,
    scenario: Option<String>,
    k: Option<RawK>,
    k_c: Option<RawK>,
    cost: Option<RawCost>,
    #[serde(alias = "methods")]
    solvers: Option<Vec<Method>>,
    seeds: Option<i64>,
    scales: Option<Vec<f64>>,
    steps: Option<i64>,
    base_seed: Option<i64>,
    exact_mhe_solve: Option<bool>,
    controller: Option<RawController>,
    metrics: Option<Vec<String>>,
    common_random_numbers: Option<bool>,
    bounded_factor: Option<f64>,
    certificate: Option<bool>,
    linear: Option<bool>,
    estimators: Option<Vec<String>>,
}

/// `cost`: the weights t_e, t_c of K_e·t_e + K_c·t_c.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCost {
    t_e: Option<f64>,
    t_c: Option<f64>,
}

/// `controller`: a name, or a table for the sub-optimal MPC.
#[derive(Debug)]
enum RawController {
    Name(String),
    Table(RawControllerTable),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawControllerTable {
    kind: Option<String>,
    iterations: Option<i64>,
    #[serde(alias = "method")]
    solver: Option<Method>,
}

// A string or a table, told apart by the TOML value itself (as `k` in `grid.rs`).
impl<'de> Deserialize<'de> for RawController {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct CVisitor;
        impl<'de> Visitor<'de> for CVisitor {
            type Value = RawController;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(
                    "a string (\"exact-mpc\", \"saturated-lqr\") or a table \
                     `{ kind = \"suboptimal-mpc\", iterations, solver }`",
                )
            }
            fn visit_str<E: de::Error>(self, s: &str) -> std::result::Result<RawController, E> {
                Ok(RawController::Name(s.to_string()))
            }
            fn visit_map<A: MapAccess<'de>>(
                self,
                map: A,
            ) -> std::result::Result<RawController, A::Error> {
                RawControllerTable::deserialize(de::value::MapAccessDeserializer::new(map))
                    .map(RawController::Table)
            }
        }
        d.deserialize_any(CVisitor)
    }
}

use lti_model::spec::format::{at_line, backticked};

fn syntax_error(text: &str, e: &toml::de::Error) -> SweepError {
    SweepError::Toml(format!(
        "{}{}; fix the syntax (https://toml.io/en/v1.0.0)",
        e.message().trim_end(),
        at_line(text, e.span())
    ))
}

/// A type error or unknown key, named by its full key path (`k[1]`, `controller.solver`).
fn data_error(text: &str, e: &serde_path_to_error::Error<toml::de::Error>) -> SweepError {
    use serde_path_to_error::Segment;
    let mut key = String::new();
    for seg in e.path() {
        match seg {
            Segment::Seq { index } => {
                let _ = write!(key, "[{index}]");
            }
            Segment::Map { key: k } | Segment::Enum { variant: k } => {
                if !key.is_empty() {
                    key.push('.');
                }
                key.push_str(k);
            }
            Segment::Unknown => {}
        }
    }
    let msg = e.inner().message().trim_end().to_string();
    let hint = if msg.starts_with("unknown field") {
        // The path may end at the table or at the key; the key itself is in the message.
        if let Some(name) = backticked(&msg) {
            if !(key == name || key.ends_with(&format!(".{name}"))) {
                if !key.is_empty() {
                    key.push('.');
                }
                key.push_str(name);
            }
        }
        "; remove the key or correct its spelling (docs/sweeps.md lists every key)"
    } else {
        ""
    };
    if key.is_empty() {
        key.push_str("<root>");
    }
    config_err(
        key,
        format!("{msg}{}{hint}", at_line(text, e.inner().span())),
    )
}

// ---------------------------------------------------------------------------------------
// Validation (stage 2: values, limits, defaults)
// ---------------------------------------------------------------------------------------

/// `cost = { t_e, t_c }` (only with `k_c`; default 1:1).
fn cost(raw: Option<RawCost>, two_d: bool) -> Result<IterationCost> {
    let Some(raw) = raw else {
        return Ok(IterationCost::default());
    };
    if !two_d {
        return Err(config_err(
            "cost",
            "weighs K_e against K_c and needs a 2-D sweep: add a K_c grid `k_c = [...]` or remove cost",
        ));
    }
    let weight = |v: Option<f64>, key: &str| -> Result<f64> {
        let v = v.unwrap_or(1.0);
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(config_err(
                key,
                format!("a cost per iteration must be finite and ≥ 0, got {v}"),
            ))
        }
    };
    let c = IterationCost {
        t_e: weight(raw.t_e, "cost.t_e")?,
        t_c: weight(raw.t_c, "cost.t_c")?,
    };
    if c.t_e == 0.0 && c.t_c == 0.0 {
        return Err(config_err(
            "cost",
            "t_e = t_c = 0 makes every pair free; give at least one positive weight (default 1:1)",
        ));
    }
    Ok(c)
}

/// `controller`; with a K_c grid (`k_c_first` = its smallest K_c) only the sub-optimal MPC,
/// without `iterations`, is accepted.
fn controller(raw: Option<RawController>, k_c_first: Option<usize>) -> Result<ControllerChoice> {
    if let Some(first) = k_c_first {
        return controller_2d(raw, first);
    }
    let t = match raw {
        None => return Ok(ControllerChoice::ExactMpc),
        Some(RawController::Name(s)) => {
            return match s.as_str() {
                "exact-mpc" => Ok(ControllerChoice::ExactMpc),
                "saturated-lqr" => Ok(ControllerChoice::SaturatedLqr),
                "suboptimal-mpc" => Err(config_err(
                    "controller",
                    "the sub-optimal MPC needs its budget: `controller = { kind = \"suboptimal-mpc\", iterations = 20, solver = \"pg\" }`",
                )),
                other => Err(config_err(
                    "controller",
                    format!(
                        "unknown controller `{other}`; use \"exact-mpc\", \"saturated-lqr\" or a table {{ kind = \"suboptimal-mpc\", iterations, solver }}"
                    ),
                )),
            };
        }
        Some(RawController::Table(t)) => t,
    };
    match t.kind.as_deref() {
        Some("suboptimal-mpc") => {}
        Some(other) => {
            return Err(config_err(
                "controller.kind",
                format!("a controller table must be kind = \"suboptimal-mpc\", got `{other}`"),
            ));
        }
        None => {
            return Err(config_err(
                "controller.kind",
                "missing (\"suboptimal-mpc\")",
            ));
        }
    }
    let iterations = t.iterations.ok_or_else(|| {
        config_err(
            "controller.iterations",
            "missing (K_c ≥ 1), or give a K_c grid `k_c = [1, 5, 20]` for a 2-D sweep over (K, K_c)",
        )
    })?;
    let iterations = positive(iterations, "controller.iterations", MAX_K)?;
    ControllerChoice::suboptimal(iterations, mpc_solver(t.solver)?)
        .map_err(|e| config_err("controller.iterations", e.to_string()))
}

/// `controller.solver` (the scenario's default, [`mpc_core::settings::DEFAULT_METHOD`]),
/// read by the same serde path as `mpc.method`.
fn mpc_solver(raw: Option<Method>) -> Result<Method> {
    Ok(raw.unwrap_or(mpc_core::settings::DEFAULT_METHOD))
}

/// The controller of a 2-D sweep: the sub-optimal MPC (as a table without `iterations`,
/// or the name `"suboptimal-mpc"` for its default solver PG); its K_c is each point's.
fn controller_2d(raw: Option<RawController>, k_c_first: usize) -> Result<ControllerChoice> {
    let needs = "a K_c grid needs the sub-optimal MPC: set `controller = { kind = \"suboptimal-mpc\", solver = \"pg\" }` (without iterations), or remove k_c";
    let solver = match raw {
        None => {
            return Err(config_err(
                "k_c",
                format!("{needs} (the controller defaults to the exact MPC)"),
            ));
        }
        Some(RawController::Name(s)) if s == "suboptimal-mpc" => None,
        Some(RawController::Name(s)) => {
            return Err(config_err("k_c", format!("{needs} (controller = \"{s}\")")));
        }
        Some(RawController::Table(t)) => {
            match t.kind.as_deref() {
                Some("suboptimal-mpc") => {}
                Some(other) => {
                    return Err(config_err(
                        "controller.kind",
                        format!(
                            "a controller table must be kind = \"suboptimal-mpc\", got `{other}`"
                        ),
                    ));
                }
                None => {
                    return Err(config_err(
                        "controller.kind",
                        "missing (\"suboptimal-mpc\")",
                    ));
                }
            }
            if let Some(n) = t.iterations {
                return Err(config_err(
                    "controller.iterations",
                    format!(
                        "= {n} conflicts with k_c: in a 2-D sweep every point runs its own K_c from the k_c grid; remove controller.iterations"
                    ),
                ));
            }
            t.solver
        }
    };
    ControllerChoice::suboptimal(k_c_first, mpc_solver(solver)?)
        .map_err(|e| config_err("k_c", e.to_string()))
}

/// `solvers` (or `methods`): read by the same serde path as `mhe.method` (names or tables
/// with parameters); non-empty, no method twice.
fn solvers(raw: Option<Vec<Method>>) -> Result<Vec<Method>> {
    let names = Method::PRESETS.map(|m| format!("\"{m}\"")).join(", ");
    let methods = raw.ok_or_else(|| config_err("solvers", format!("missing (any of {names})")))?;
    if methods.is_empty() {
        return Err(config_err(
            "solvers",
            format!("empty; list at least one of {names}"),
        ));
    }
    let mut out = Vec::new();
    for (i, m) in methods.into_iter().enumerate() {
        if out.contains(&m) {
            return Err(config_err(
                format!("solvers[{i}]"),
                format!("`{m}` is listed twice"),
            ));
        }
        out.push(m);
    }
    Ok(out)
}

fn scales(raw: Option<Vec<f64>>) -> Result<Option<Vec<f64>>> {
    let Some(list) = raw else {
        return Ok(None);
    };
    if list.is_empty() {
        return Err(config_err(
            "scales",
            "empty; omit it to keep the scenario's noise.scale",
        ));
    }
    let mut out = Vec::new();
    for (i, &s) in list.iter().enumerate() {
        let key = format!("scales[{i}]");
        // The same limits as the scenario's `noise.scale` (docs/limits.md).
        if let Err(e) = lti_model::spec::format::check_scale("noise.scale", s) {
            let problem = match e {
                lti_model::ModelError::Scenario { problem, .. } => problem,
                other => other.to_string(),
            };
            return Err(config_err(
                key,
                format!("a disturbance scale (it replaces the scenario's `noise.scale`) {problem}"),
            ));
        }
        if out.contains(&s) {
            return Err(config_err(key, format!("{s} is listed twice")));
        }
        out.push(s);
    }
    Ok(Some(out))
}

fn metrics(raw: Option<Vec<String>>, exact_mhe_solve: bool) -> Result<Vec<Metric>> {
    let Some(names) = raw else {
        return Ok(Metric::ALL
            .into_iter()
            .filter(|m| exact_mhe_solve || *m != Metric::SupEps)
            .collect());
    };
    let mut out = Vec::new();
    for (i, n) in names.iter().enumerate() {
        let m = n
            .parse::<Metric>()
            .map_err(|e| config_err(format!("metrics[{i}]"), e))?;
        if m == Metric::SupEps && !exact_mhe_solve {
            return Err(config_err(
                format!("metrics[{i}]"),
                "sup_eps needs ε_t, which only the exact MHE solve gives: set exact_mhe_solve = true or drop it",
            ));
        }
        if !out.contains(&m) {
            out.push(m);
        }
    }
    out.sort_unstable();
    Ok(out)
}

fn name(raw: Option<String>) -> Result<String> {
    let name = raw.ok_or_else(|| config_err("name", "missing (names the output directory)"))?;
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.')
        || name.starts_with('.')
    {
        return Err(config_err(
            "name",
            format!(
                "`{name}` must be non-empty ASCII letters, digits, `-`, `_`, `.`, and must not start \
                 with `.` (it names a directory)"
            ),
        ));
    }
    Ok(name)
}

impl SweepConfig {
    /// Parses and validates a config; relative `scenario` paths are resolved against
    /// `base_dir` (the config file's directory). Unknown keys are errors; every error names
    /// its full key path.
    pub fn from_toml_str(text: &str, base_dir: &Path) -> Result<Self> {
        let de = toml::Deserializer::parse(text).map_err(|e| syntax_error(text, &e))?;
        let raw: RawConfig =
            serde_path_to_error::deserialize(de).map_err(|e| data_error(text, &e))?;
        let name = name(raw.name)?;
        let scenario = raw
            .scenario
            .ok_or_else(|| config_err("scenario", "missing (path of the scenario TOML)"))?;
        let scenario = base_dir.join(scenario);
        let k_grid = k_grid(raw.k)?;
        let solvers = solvers(raw.solvers)?;
        let seeds = raw
            .seeds
            .ok_or_else(|| config_err("seeds", "missing (number of runs per point, ≥ 1)"))?;
        let seeds = positive(seeds, "seeds", MAX_SEEDS)?;
        let scales = scales(raw.scales)?;
        let steps = raw
            .steps
            .map(|s| positive(s, "steps", MAX_STEPS))
            .transpose()?;
        let base_seed = match raw.base_seed {
            None => None,
            Some(s) => Some(
                u64::try_from(s)
                    .map_err(|_| config_err("base_seed", format!("must be ≥ 0, got {s}")))?,
            ),
        };
        let exact_mhe_solve = raw.exact_mhe_solve.unwrap_or(false);
        let k_c_grid = k_c_grid(raw.k_c)?;
        let controller = controller(
            raw.controller,
            k_c_grid.as_ref().and_then(|g| g.first().copied()),
        )?;
        let cost = cost(raw.cost, k_c_grid.is_some())?;
        let metrics = metrics(raw.metrics, exact_mhe_solve)?;
        let common_random_numbers = raw.common_random_numbers.unwrap_or(true);
        let bounded_factor = raw.bounded_factor.unwrap_or(DEFAULT_BOUNDED_FACTOR);
        if !(bounded_factor.is_finite() && bounded_factor > 0.0) {
            return Err(config_err(
                "bounded_factor",
                format!("must be finite and > 0, got {bounded_factor}"),
            ));
        }
        let certificate = raw.certificate.unwrap_or(true);
        let linear = raw.linear.unwrap_or(true);
        let kalman = super::baseline::parse_estimators(raw.estimators.as_deref())?;
        Ok(Self {
            kalman,
            name,
            scenario,
            k_grid,
            solvers,
            seeds,
            scales,
            steps,
            base_seed,
            exact_mhe_solve,
            controller,
            k_c_grid,
            cost,
            metrics,
            common_random_numbers,
            bounded_factor,
            certificate,
            linear,
        })
    }

    /// Reads and validates a config file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = lti_model::spec::format::read_limited(path).map_err(|e| {
            config_err(
                "<file>",
                match e {
                    lti_model::ModelError::Scenario { problem, .. } => problem,
                    other => other.to_string(),
                },
            )
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::from_toml_str(&text, base)
    }

    /// The points of the sweep, in output order (scale, then solver, then K_c in a 2-D
    /// sweep, then K), with the given scales (the config's, or `[default_scale]`).
    pub(super) fn points_with(&self, default_scale: f64) -> Vec<Point> {
        let scales = self.scales.clone().unwrap_or_else(|| vec![default_scale]);
        let k_cs: Vec<Option<usize>> = match &self.k_c_grid {
            None => vec![None],
            Some(g) => g.iter().copied().map(Some).collect(),
        };
        let mut out = Vec::new();
        for (scale_index, &scale) in scales.iter().enumerate() {
            for &solver in &self.solvers {
                for &k_c in &k_cs {
                    for &k in &self.k_grid {
                        out.push(Point {
                            index: out.len(),
                            k,
                            k_c,
                            solver,
                            scale,
                            scale_index,
                        });
                    }
                }
            }
        }
        out
    }

    /// Whether this is a 2-D sweep over (K_e, K_c) (`k_c` given).
    pub fn is_2d(&self) -> bool {
        self.k_c_grid.is_some()
    }

    /// The controller of point `p`: the config's, with the point's K_c in a 2-D sweep.
    ///
    /// Errors: the point's K_c is 0 or above [`MAX_K`] (only a point built by hand: the
    /// grid's are validated), naming `controller iterations`.
    pub fn controller_at(
        &self,
        p: &Point,
    ) -> std::result::Result<ControllerChoice, ClosedLoopError> {
        self.controller_for(p.k_c)
    }

    /// The controller at `k_c`: the sub-optimal MPC with K_c = `k_c` in a 2-D sweep, the
    /// config's controller for `None`.
    ///
    /// Errors: as [`ControllerChoice::suboptimal`], a K_c that is not an iteration budget.
    pub fn controller_for(
        &self,
        k_c: Option<usize>,
    ) -> std::result::Result<ControllerChoice, ClosedLoopError> {
        match (self.controller, k_c) {
            (ControllerChoice::SuboptimalMpc { method, .. }, Some(k_c)) => {
                ControllerChoice::suboptimal(k_c, method)
            }
            (c, _) => Ok(c),
        }
    }

    /// The controllers of the linear and regional sides: one per K_c of the grid in a 2-D
    /// sweep (a K_c that is not an iteration budget, only in a hand-edited config, has none:
    /// its points fail to build, naming it), the config's controller otherwise.
    pub fn grid_controllers(&self) -> Vec<(Option<usize>, ControllerChoice)> {
        match &self.k_c_grid {
            None => vec![(None, self.controller)],
            Some(grid) => grid
                .iter()
                .filter_map(|&k_c| Some((Some(k_c), self.controller_for(Some(k_c)).ok()?)))
                .collect(),
        }
    }

    /// The points of the sweep (scale 1 standing for the scenario's when `scales` is
    /// omitted; [`Sweep::points`](super::Sweep::points) has the resolved scale).
    pub fn points(&self) -> Vec<Point> {
        self.points_with(1.0)
    }

    /// A canonical text of every setting that changes results (not the name, not the
    /// scenario path: the scenario's text enters the fingerprint instead; not `cost`, which
    /// only weighs the results). A 1-D sweep's text is the one fingerprints were first
    /// written with (old output directories resume); a 2-D sweep appends its K_c grid.
    pub(super) fn canonical(&self, steps: usize, base_seed: u64, scales: &[f64]) -> String {
        let mut s = String::new();
        let _ = write!(
            s,
            "k={:?};solvers=[{}];seeds={};scales={:?};steps={};base_seed={};exact={};controller={};metrics={:?};crn={};bounded_factor={:e};certificate={};linear={}",
            self.k_grid,
            self.solvers
                .iter()
                .map(fingerprint_name)
                .collect::<Vec<_>>()
                .join(", "),
            self.seeds,
            scales.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            steps,
            base_seed,
            self.exact_mhe_solve,
            match (self.controller, self.is_2d()) {
                (ControllerChoice::ExactMpc, _) => "ExactMpc".to_string(),
                (ControllerChoice::SaturatedLqr, _) => "SaturatedLqr".to_string(),
                (ControllerChoice::SuboptimalMpc { method, .. }, true) => format!(
                    "SuboptimalMpc {{ iterations: k_c, solver: {} }}",
                    fingerprint_name(&method)
                ),
                (ControllerChoice::SuboptimalMpc { iterations, method }, false) => format!(
                    "SuboptimalMpc {{ iterations: {iterations}, solver: {} }}",
                    fingerprint_name(&method)
                ),
            },
            self.metrics,
            self.common_random_numbers,
            self.bounded_factor,
            self.certificate,
            self.linear,
        );
        if let Some(g) = &self.k_c_grid {
            let _ = write!(s, ";k_c={g:?}");
        }
        // Only when set, so that existing sweeps keep their fingerprints.
        if self.kalman {
            s.push_str(";estimators=[mhe, kalman]");
        }
        s
    }
}

/// A method's name in the fingerprint text: fixed words (the ones fingerprints were first
/// written with), so output directories stay resumable across versions.
fn fingerprint_name(m: &Method) -> String {
    match *m {
        Method::PG => "Pg".into(),
        Method::FISTA => "Fista".into(),
        Method::ADMM => "Admm".into(),
        Method::ADMM_PR => "AdmmPr".into(),
        other => other.name().into_owned(),
    }
}

/// One sweep point: K (= K_e), K_c in a 2-D sweep, the MHE's solver Φ and the disturbance
/// scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// Index in the full grid (stable across shards; names the point file).
    pub index: usize,
    /// Iteration budget K (= K_e) of the MHE.
    pub k: usize,
    /// Iteration budget K_c of the sub-optimal MPC in a 2-D sweep (None: a 1-D sweep, the
    /// controller is the config's).
    pub k_c: Option<usize>,
    /// Φ of the MHE.
    pub solver: Method,
    /// Disturbance scale (`noise.scale`).
    pub scale: f64,
    /// Index of the scale in the config's list.
    pub scale_index: usize,
}

impl fmt::Display for Point {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.k_c {
            None => write!(
                f,
                "point {} (K = {}, solver = {}, scale = {})",
                self.index, self.k, self.solver, self.scale
            ),
            Some(k_c) => write!(
                f,
                "point {} (K = {}, K_c = {k_c}, solver = {}, scale = {})",
                self.index, self.k, self.solver, self.scale
            ),
        }
    }
}

#[cfg(test)]
#[path = "config_tests.rs"]
mod tests;
