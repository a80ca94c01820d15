//! The plant-level sections of a scenario file: `[plant]`, `[sets]`, `[noise]`,
//! `[simulation]`, as raw serde mirrors (`Raw*`, every key optional, unknown keys refused)
//! and their validated, typed forms. The file itself is composed in `closed-loop`.

use faer::Mat;
use serde::{Deserialize, Serialize};

use super::format::*;
use crate::error::Result;
use crate::matrix;
use crate::sets::BoxSet;
use crate::system::LtiSystem;

/// Number of simulation steps when `[simulation].steps` is omitted (the case study's 40).
pub const DEFAULT_STEPS: usize = 40;

/// Largest T accepted (`simulation.steps`; a run's trace is preallocated).
pub const MAX_STEPS: usize = 100_000;

/// The constraint sets of eq. (1); an omitted set is the whole space.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioSets {
    /// 𝒳 ⊂ ℝ^{n_x} (`sets.state`).
    pub state: BoxSet,
    /// 𝒰 ⊂ ℝ^{n_u} (`sets.input`).
    pub input: BoxSet,
    /// 𝒴 ⊂ ℝ^{n_y} (`sets.output`).
    pub output: BoxSet,
    /// 𝒲 ⊂ ℝ^{n_w1 + n_w2} for the augmented w = (w¹, w²) (`sets.disturbance`).
    pub disturbance: BoxSet,
}

/// Distribution of the true disturbance w_t = (w¹_t, w²_t).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NoiseKind {
    /// Independent uniform entries on `scale`·𝒲 (needs finite bounds on 𝒲).
    Uniform,
    /// Zero-mean Gaussian with covariance `scale²`·`covariance` (not clipped to 𝒲).
    Gaussian,
    /// w_t = 0.
    Zero,
    /// Independent truncated normal entries: N(μ_i, `scale²`·`covariance`_ii) conditioned
    /// on the box `noise.truncate` (default 𝒲); `covariance` must be diagonal.
    #[serde(rename = "truncated-normal")]
    TruncatedNormal,
}

/// The `[noise]` section: which disturbance the simulation draws, and its seed.
#[derive(Debug, Clone)]
pub struct NoiseSpec {
    /// Distribution.
    pub kind: NoiseKind,
    /// Multiplies the bounds of 𝒲 (uniform) or the standard deviation (Gaussian); ≥ 0.
    pub scale: f64,
    /// Covariance of the Gaussian before scaling, n_w square and positive definite
    /// (`Some` exactly when `kind` is [`NoiseKind::Gaussian`]).
    pub covariance: Option<Mat<f64>>,
    /// Seed of the disturbance generator (ChaCha8).
    pub seed: u64,
    /// Mean offset μ added to every draw (`noise.mean`, n_w; `None`: 0). For the truncated
    /// normal, the location of the underlying normal.
    pub mean: Option<Vec<f64>>,
    /// The truncation box of [`NoiseKind::TruncatedNormal`] (`noise.truncate`; `Some`
    /// exactly for that kind, default 𝒲 = `sets.disturbance`).
    pub truncate: Option<BoxSet>,
}

impl NoiseSpec {
    /// The Gaussian covariance after scaling, `scale²·covariance` (`None` unless Gaussian).
    ///
    /// ```
    /// use lti_model::spec::{NoiseKind, NoiseSpec};
    /// let noise = NoiseSpec {
    ///     kind: NoiseKind::Gaussian,
    ///     scale: 2.0,
    ///     covariance: Some(faer::Mat::from_fn(2, 2, |i, j| if i == j { 0.25 } else { 0.0 })),
    ///     seed: 0,
    ///     mean: None,
    ///     truncate: None,
    /// };
    /// let cov = noise.scaled_covariance().unwrap();
    /// assert_eq!((cov[(0, 0)], cov[(1, 1)], cov[(0, 1)]), (1.0, 1.0, 0.0));
    /// ```
    pub fn scaled_covariance(&self) -> Option<Mat<f64>> {
        let s2 = self.scale * self.scale;
        self.covariance
            .as_ref()
            .map(|c| Mat::from_fn(c.nrows(), c.ncols(), |i, j| s2 * c[(i, j)]))
    }

    /// The box uniform noise is drawn from, μ + `scale`·𝒲 (`None` unless uniform).
    pub fn uniform_box(&self, disturbance: &BoxSet) -> Option<(Vec<f64>, Vec<f64>)> {
        (self.kind == NoiseKind::Uniform).then(|| {
            let scale = |v: &[f64]| {
                v.iter()
                    .enumerate()
                    .map(|(i, b)| self.scale * b + self.mean_at(i))
                    .collect::<Vec<f64>>()
            };
            (scale(disturbance.lower()), scale(disturbance.upper()))
        })
    }

    /// The mean offset of component i (0 without `noise.mean`).
    pub fn mean_at(&self, i: usize) -> f64 {
        self.mean.as_ref().map_or(0.0, |m| m[i])
    }

    /// Whether the simulated law can draw outside 𝒲 (`disturbance`): a Gaussian (unbounded),
    /// a scaled or shifted box, a truncation box not inside 𝒲. Then the runs report the
    /// draws outside 𝒲 (the ISS statement does not cover those steps).
    pub fn can_leave(&self, disturbance: &BoxSet) -> bool {
        let inside = |lo: &[f64], hi: &[f64]| {
            lo.iter().zip(disturbance.lower()).all(|(a, b)| a >= b)
                && hi.iter().zip(disturbance.upper()).all(|(a, b)| a <= b)
        };
        match self.kind {
            NoiseKind::Zero => false,
            _ if self.scale == 0.0 => {
                let mean: Vec<f64> = (0..disturbance.lower().len())
                    .map(|i| self.mean_at(i))
                    .collect();
                !inside(&mean, &mean)
            }
            NoiseKind::Gaussian => true,
            NoiseKind::Uniform => self
                .uniform_box(disturbance)
                .is_none_or(|(lo, hi)| !inside(&lo, &hi)),
            NoiseKind::TruncatedNormal => self
                .truncate
                .as_ref()
                .is_none_or(|t| !inside(t.lower(), t.upper())),
        }
    }
}

/// The `[simulation]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulationSpec {
    /// True initial state x₀ ∈ 𝒳 (default 0).
    pub x0: Vec<f64>,
    /// Initial prior x̄₀ = x^prior_0 of the MHE (default 0; need not lie in 𝒳, the
    /// estimator projects it).
    pub prior: Vec<f64>,
    /// Number of closed-loop time steps (default [`DEFAULT_STEPS`]).
    pub steps: usize,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RawPlant {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub a: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub b: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub c: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub e: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub f: Option<MatrixSpec>,
    /// `plant.sample_time`: the sample period T_s in seconds (optional; the budget of one
    /// estimator step on a target, see [`validate_sample_time`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sample_time: Option<f64>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RawSets {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub state: Option<Table<RawBox>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input: Option<Table<RawBox>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub output: Option<Table<RawBox>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub disturbance: Option<Table<RawBox>>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RawBox {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lower: Option<Bounds>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub upper: Option<Bounds>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RawNoise {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kind: Option<NoiseKind>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub covariance: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mean: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truncate: Option<Table<RawBox>>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RawSimulation {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub x0: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub steps: Option<usize>,
}

pub fn box_set(key: &str, raw: Option<&RawBox>, n: usize, what: &str) -> Result<BoxSet> {
    let Some(raw) = raw else {
        return Ok(BoxSet::whole(n));
    };
    let lower = bound_vec(
        &format!("{key}.lower"),
        raw.lower.as_ref(),
        n,
        f64::NEG_INFINITY,
        what,
    )?;
    let upper = bound_vec(
        &format!("{key}.upper"),
        raw.upper.as_ref(),
        n,
        f64::INFINITY,
        what,
    )?;
    let set = BoxSet::named(key, lower, upper).map_err(|e| wrap(key, e.into()))?;
    // Assumption 1: 𝒵 = 𝒳 × 𝒰 × 𝒴 × 𝒲 contains the origin.
    for (i, (l, u)) in set.lower().iter().zip(set.upper()).enumerate() {
        if *l > 0.0 || *u < 0.0 {
            return Err(key_error(
                key,
                format!(
                    "component {i} is [{l}, {u}], which excludes 0; Assumption 1 of the paper needs \
                     every set to contain the origin, so widen the bounds or shift the coordinates"
                ),
            ));
        }
    }
    Ok(set)
}

/// Largest accepted `plant.sample_time` in seconds (one day): a larger period is a typo
/// for a plant a discrete-time MHE runs on.
pub const MAX_SAMPLE_TIME: f64 = 86_400.0;

/// `plant.sample_time`: the sample period T_s in seconds, `None` when the scenario gives
/// none. Finite and in (0, [`MAX_SAMPLE_TIME`]], else a typed error naming the key.
pub fn validate_sample_time(raw: Option<&RawPlant>) -> Result<Option<f64>> {
    let Some(ts) = raw.and_then(|p| p.sample_time) else {
        return Ok(None);
    };
    if !ts.is_finite() || ts <= 0.0 || ts > MAX_SAMPLE_TIME {
        return Err(key_error(
            "plant.sample_time",
            format!(
                "is {ts}; give the sample period T_s in seconds, a finite number in \
                 (0, {MAX_SAMPLE_TIME}], e.g. `sample_time = 0.02` for 50 Hz, or omit the key"
            ),
        ));
    }
    Ok(Some(ts))
}

pub fn validate_plant(raw: Option<&RawPlant>) -> Result<LtiSystem> {
    let Some(p) = raw else {
        return Err(key_error(
            "plant",
            "the [plant] section is required but missing; add it with a, b, c, e.g. \
             [plant] a = [[0.5]] b = [[1.0]] c = [[1.0]]",
        ));
    };
    let missing = |k: &str, what: &str| {
        key_error(
            format!("plant.{k}"),
            format!("is required but missing; give {what} as an array of rows"),
        )
    };
    let a = free_matrix(
        "plant.a",
        p.a.as_ref()
            .ok_or_else(|| missing("a", "the n_x × n_x matrix A"))?,
    )?;
    let nx = a.nrows();
    check_dimension("plant.a", "n_x", nx)?;
    if nx == 0 || a.ncols() != nx {
        return Err(key_error(
            "plant.a",
            format!(
                "has shape {}×{}, but A must be square and non-empty (n_x × n_x)",
                a.nrows(),
                a.ncols()
            ),
        ));
    }
    let b = free_matrix(
        "plant.b",
        p.b.as_ref()
            .ok_or_else(|| missing("b", "the n_x × n_u matrix B"))?,
    )?;
    if b.nrows() != nx {
        return Err(key_error(
            "plant.b",
            format!(
                "has {} rows, expected n_x = {nx} (the size of A); give one row per state",
                b.nrows()
            ),
        ));
    }
    let c = free_matrix(
        "plant.c",
        p.c.as_ref()
            .ok_or_else(|| missing("c", "the n_y × n_x matrix C"))?,
    )?;
    if c.nrows() == 0 || c.ncols() != nx {
        return Err(key_error(
            "plant.c",
            format!(
                "has shape {}×{}, expected n_y × {nx} with n_y ≥ 1 (n_x = {nx} columns, one per state)",
                c.nrows(),
                c.ncols()
            ),
        ));
    }
    let ny = c.nrows();
    check_dimension("plant.c", "n_y", ny)?;
    check_dimension("plant.b", "n_u", b.ncols())?;
    let disturbance_matrix = |key: &str,
                              spec: Option<&MatrixSpec>,
                              n: usize,
                              what: &str|
     -> Result<Mat<f64>> {
        match spec {
            None => Ok(Mat::identity(n, n)),
            Some(MatrixSpec::Scalar(s)) => scalar_identity(key, *s, n),
            Some(spec @ MatrixSpec::Diagonal(_)) => {
                sized_matrix(key, spec, n, n, &format!("one row per {what}"))
            }
            Some(MatrixSpec::Rows(r)) => {
                let m = rows_to_mat(key, r)?;
                if m.nrows() != n {
                    return Err(key_error(
                        key,
                        format!(
                            "has {} rows, expected {n} (one per {what}); give one row per {what}",
                            m.nrows()
                        ),
                    ));
                }
                Ok(m)
            }
        }
    };
    let e = disturbance_matrix("plant.e", p.e.as_ref(), nx, "state")?;
    let f = disturbance_matrix("plant.f", p.f.as_ref(), ny, "output")?;
    check_dimension("plant.e", "n_w1", e.ncols())?;
    check_dimension("plant.f", "n_w2", f.ncols())?;
    LtiSystem::with_disturbance(a, b, c, e, f).map_err(|e| wrap("plant", e.in_context("plant")))
}

pub fn validate_noise(
    raw: Option<&RawNoise>,
    sets: &ScenarioSets,
    disturbance_given: bool,
    nw: usize,
) -> Result<NoiseSpec> {
    let bounded = sets
        .disturbance
        .lower()
        .iter()
        .chain(sets.disturbance.upper())
        .all(|b| b.is_finite());
    let Some(raw) = raw else {
        return default_noise(disturbance_given, bounded);
    };
    let kind = raw.kind.unwrap_or(NoiseKind::Uniform);
    let scale = noise_scale(raw)?;
    if kind == NoiseKind::Uniform && !bounded {
        return Err(key_error(
            "noise.kind",
            "uniform noise is drawn from sets.disturbance, which has an infinite (or no) bound; give \
             sets.disturbance finite bounds or choose kind = \"gaussian\" or \"zero\"",
        ));
    }
    let covariance = noise_covariance(raw, kind, nw)?;
    let mean = noise_mean(raw, kind, nw)?;
    let truncate = noise_truncate(raw, kind, covariance.as_ref(), sets, nw)?;
    Ok(NoiseSpec {
        kind,
        scale,
        covariance,
        seed: raw.seed.unwrap_or(0),
        mean,
        truncate,
    })
}

/// The noise of a scenario without a `[noise]` section: zero without a disturbance, else
/// uniform on `sets.disturbance` (which must then be bounded).
fn default_noise(disturbance_given: bool, bounded: bool) -> Result<NoiseSpec> {
    if !disturbance_given {
        return Ok(NoiseSpec {
            kind: NoiseKind::Zero,
            scale: 1.0,
            covariance: None,
            seed: 0,
            mean: None,
            truncate: None,
        });
    }
    if !bounded {
        return Err(key_error(
            "sets.disturbance",
            "without a [noise] section the disturbance is uniform on sets.disturbance, which needs \
             finite bounds; make every bound finite or add [noise] with kind = \"gaussian\" or \"zero\"",
        ));
    }
    Ok(NoiseSpec {
        kind: NoiseKind::Uniform,
        scale: 1.0,
        covariance: None,
        seed: 0,
        mean: None,
        truncate: None,
    })
}

/// `noise.scale`: finite, ≥ 0, and not so small that its square underflows.
fn noise_scale(raw: &RawNoise) -> Result<f64> {
    let scale = raw.scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale >= 0.0) {
        return Err(key_error(
            "noise.scale",
            format!("is {scale}; it must be a finite number ≥ 0"),
        ));
    }
    check_magnitude("noise.scale", "the scale", scale)?;
    // scale² multiplies the covariance: a nonzero scale so small that it underflows would
    // silently give a singular (Gaussian) or zero (uniform) disturbance.
    if scale > 0.0 && scale < 1.0 / MAX_MAGNITUDE {
        return Err(key_error(
            "noise.scale",
            format!(
                "is {scale:e}, nonzero but below {:e}, the smallest scale accepted (its square \
                 underflows); use 0 for no disturbance, or a larger scale (docs/limits.md)",
                1.0 / MAX_MAGNITUDE
            ),
        ));
    }
    Ok(scale)
}

/// `noise.covariance`: required by (and only by) the Gaussian kinds.
fn noise_covariance(raw: &RawNoise, kind: NoiseKind, nw: usize) -> Result<Option<Mat<f64>>> {
    Ok(match (kind, raw.covariance.as_ref()) {
        (NoiseKind::Gaussian | NoiseKind::TruncatedNormal, Some(c)) => Some(weight(
            "noise.covariance",
            Some(c),
            nw,
            "n_w = n_w1 + n_w2 square",
        )?),
        (NoiseKind::TruncatedNormal, None) => {
            return Err(key_error(
                "noise.covariance",
                format!(
                    "kind = \"truncated-normal\" needs the covariance of the underlying normal \
                     ({nw}×{nw}, diagonal, positive); add e.g. `covariance = 0.01` for 0.01·I"
                ),
            ));
        }
        (NoiseKind::Gaussian, None) => {
            return Err(key_error(
                "noise.covariance",
                format!(
                    "kind = \"gaussian\" needs a covariance ({nw}×{nw}, symmetric positive definite); \
                     add e.g. `covariance = 0.01` for 0.01·I"
                ),
            ));
        }
        (_, Some(_)) => {
            return Err(key_error(
                "noise.covariance",
                "is only used with kind = \"gaussian\" or \"truncated-normal\"; remove it or set \
                 kind = \"gaussian\"",
            ));
        }
        (_, None) => None,
    })
}

/// `noise.mean`: an offset of drawn noise, so not with `kind = "zero"`.
fn noise_mean(raw: &RawNoise, kind: NoiseKind, nw: usize) -> Result<Option<Vec<f64>>> {
    Ok(match (&raw.mean, kind) {
        (None, _) => None,
        (Some(_), NoiseKind::Zero) => {
            return Err(key_error(
                "noise.mean",
                "is an offset of the drawn noise, but kind = \"zero\" draws nothing; remove it or \
                 choose kind = \"uniform\", \"gaussian\" or \"truncated-normal\"",
            ));
        }
        (Some(m), _) => Some(vector(
            "noise.mean",
            Some(m),
            nw,
            "disturbance component (w¹ then w²)",
        )?),
    })
}

/// `noise.truncate`: the truncated normal's box (default `sets.disturbance`), with a diagonal
/// covariance and lower < upper in every component; only with `kind = "truncated-normal"`.
fn noise_truncate(
    raw: &RawNoise,
    kind: NoiseKind,
    covariance: Option<&Mat<f64>>,
    sets: &ScenarioSets,
    nw: usize,
) -> Result<Option<BoxSet>> {
    Ok(match (kind, raw.truncate.as_deref()) {
        (NoiseKind::TruncatedNormal, t) => {
            if let Some(c) = covariance {
                for i in 0..nw {
                    for j in 0..nw {
                        if i != j && c[(i, j)] != 0.0 {
                            return Err(key_error(
                                "noise.covariance",
                                format!(
                                    "entry ({i}, {j}) is {}; kind = \"truncated-normal\" draws \
                                     independent components, so the covariance must be diagonal \
                                     (use kind = \"gaussian\" for correlated noise)",
                                    c[(i, j)]
                                ),
                            ));
                        }
                    }
                }
            }
            let set = match t {
                None => sets.disturbance.clone(),
                Some(t) => {
                    let lower = bound_vec(
                        "noise.truncate.lower",
                        t.lower.as_ref(),
                        nw,
                        f64::NEG_INFINITY,
                        "disturbance component",
                    )?;
                    let upper = bound_vec(
                        "noise.truncate.upper",
                        t.upper.as_ref(),
                        nw,
                        f64::INFINITY,
                        "disturbance component",
                    )?;
                    BoxSet::named("noise.truncate", lower, upper)
                        .map_err(|e| wrap("noise.truncate", e.into()))?
                }
            };
            for i in 0..nw {
                if !(set.lower()[i] < set.upper()[i]) {
                    return Err(key_error(
                        "noise.truncate",
                        format!(
                            "component {i} is [{}, {}]: a truncated normal needs lower < upper",
                            set.lower()[i],
                            set.upper()[i]
                        ),
                    ));
                }
            }
            Some(set)
        }
        (_, Some(_)) => {
            return Err(key_error(
                "noise.truncate",
                "is only used with kind = \"truncated-normal\"; remove it or set that kind",
            ));
        }
        (_, None) => None,
    })
}

/// The raw form of a box (for writing a scenario back to TOML).
pub fn raw_box(b: &BoxSet) -> RawBox {
    RawBox {
        lower: Some(Bounds::Each(b.lower().to_vec())),
        upper: Some(Bounds::Each(b.upper().to_vec())),
    }
}

/// Validates `[sets]` against the plant; also says whether `sets.disturbance` was given
/// (it decides the default noise).
pub fn validate_sets(raw: Option<&RawSets>, plant: &LtiSystem) -> Result<(ScenarioSets, bool)> {
    let (nx, nu, ny, nw) = (plant.nx(), plant.nu(), plant.ny(), plant.nw());
    let pick = |f: fn(&RawSets) -> Option<&RawBox>| raw.and_then(f);
    let sets = ScenarioSets {
        state: box_set("sets.state", pick(|s| s.state.as_deref()), nx, "state")?,
        input: box_set("sets.input", pick(|s| s.input.as_deref()), nu, "input")?,
        output: box_set("sets.output", pick(|s| s.output.as_deref()), ny, "output")?,
        disturbance: box_set(
            "sets.disturbance",
            pick(|s| s.disturbance.as_deref()),
            nw,
            "disturbance component (w¹ then w²)",
        )?,
    };
    Ok((sets, pick(|s| s.disturbance.as_deref()).is_some()))
}

/// Validates `[simulation]`: x₀ and the prior (length n_x, finite; x₀ ∈ 𝒳), T ≥ 1.
pub fn validate_simulation(
    raw: Option<&RawSimulation>,
    plant: &LtiSystem,
    sets: &ScenarioSets,
) -> Result<SimulationSpec> {
    let nx = plant.nx();
    let x0 = vector(
        "simulation.x0",
        raw.and_then(|s| s.x0.as_ref()),
        nx,
        "state",
    )?;
    let prior = vector(
        "simulation.prior",
        raw.and_then(|s| s.prior.as_ref()),
        nx,
        "state",
    )?;
    let steps = at_least_one(
        "simulation.steps",
        raw.and_then(|s| s.steps).unwrap_or(DEFAULT_STEPS),
        "the number of time steps",
    )?;
    if steps > MAX_STEPS {
        return Err(key_error(
            "simulation.steps",
            format!("is {steps}, above the limit {MAX_STEPS} (a run's trace is preallocated)"),
        ));
    }
    // The trace: x, x̂, u, y, w per step.
    let per_step = (2 * nx + plant.nu() + plant.ny() + plant.nw()) as f64;
    check_dense_bytes("simulation.steps", "a trace", 8.0 * per_step * steps as f64)?;
    let violation = crate::sets::ConvexSet::violation(&sets.state, &x0);
    if violation > 0.0 {
        return Err(key_error(
            "simulation.x0",
            format!(
                "lies outside sets.state (by {violation}); the true initial state must satisfy x₀ ∈ 𝒳"
            ),
        ));
    }
    Ok(SimulationSpec { x0, prior, steps })
}

/// The raw forms of validated plant-level sections (for writing a scenario back to TOML).
pub fn raw_sections(
    plant: &LtiSystem,
    sets: &ScenarioSets,
    noise: &NoiseSpec,
    simulation: &SimulationSpec,
) -> (RawPlant, RawSets, RawNoise, RawSimulation) {
    let to_mat = |m: faer::MatRef<'_, f64>| MatrixSpec::Rows(matrix::to_rows(m));
    (
        RawPlant {
            a: Some(to_mat(plant.a())),
            b: Some(to_mat(plant.b())),
            c: Some(to_mat(plant.c())),
            e: Some(to_mat(plant.e())),
            f: Some(to_mat(plant.f())),
            sample_time: None,
        },
        RawSets {
            state: Some(Table(raw_box(&sets.state))),
            input: Some(Table(raw_box(&sets.input))),
            output: Some(Table(raw_box(&sets.output))),
            disturbance: Some(Table(raw_box(&sets.disturbance))),
        },
        RawNoise {
            kind: Some(noise.kind),
            scale: Some(noise.scale),
            covariance: noise.covariance.as_ref().map(rows_of),
            seed: Some(noise.seed),
            mean: noise.mean.clone(),
            truncate: noise.truncate.as_ref().map(|b| Table(raw_box(b))),
        },
        RawSimulation {
            x0: Some(simulation.x0.clone()),
            prior: Some(simulation.prior.clone()),
            steps: Some(simulation.steps),
        },
    )
}
