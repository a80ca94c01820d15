//! TOML scenario files: plant, sets, noise, simulation, and the (reserved) MHE and MPC
//! settings, parsed with serde and validated into typed structs.
//!
//! Parsing runs in two stages. First the text is deserialised into private `Raw*`
//! mirror structs (every table `deny_unknown_fields`, every key optional) through
//! `serde_path_to_error`, so a type error names the dotted key it happened at. Then
//! [`Scenario`] is built from the raw structs, checking every shape against the plant and
//! every weight for symmetry and positive definiteness. Every failure is a
//! [`ModelError::Scenario`] whose `key` is the dotted TOML key (`"mhe.q"`), `"<toml>"`
//! for a syntax error or `"<file>"` for an I/O error, and whose `problem` says what is
//! wrong and how to fix it. The full format is documented in `docs/scenario-format.md`.
//!
//! ```
//! use lti_model::scenario::Scenario;
//! let s = Scenario::from_toml_str(r#"
//!     name = "double-integrator"
//!     [plant]
//!     a = [[1.0, 0.1], [0.0, 1.0]]
//!     b = [[0.005], [0.1]]
//!     c = [[1.0, 0.0]]
//!     [sets]
//!     input = { lower = [-1], upper = [1] }
//! "#).unwrap();
//! assert_eq!((s.plant.nx(), s.plant.nu(), s.plant.ny()), (2, 1, 1));
//! assert!(s.sets.state.is_whole());
//! assert_eq!(s.sets.input.upper(), &[1.0]);
//!
//! let err = Scenario::from_toml_str("name = \"x\"\n[plant]\na = [[1.0]]\nc = [[1.0]]\nd = 1")
//!     .unwrap_err();
//! match err {
//!     lti_model::ModelError::Scenario { key, .. } => assert_eq!(key, "plant.d"),
//!     other => panic!("{other}"),
//! }
//! ```

use std::fmt;
use std::path::Path;

use faer::Mat;
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::ser::{SerializeMap, SerializeSeq, Serializer};
use serde::{Deserialize, Serialize};

use crate::error::{ModelError, Result};
use crate::matrix;
use crate::sets::BoxSet;
use crate::system::LtiSystem;

/// Number of simulation steps when `[simulation].steps` is omitted (the case study's 40).
pub const DEFAULT_STEPS: usize = 40;

/// Largest n_x, n_u, n_y, n_w1, n_w2 a scenario may have. Dense n × n weights are built
/// from a few bytes of text (`q = 1.0`, `{ diagonal = [...] }`), so without a cap a short
/// file could request terabytes; dense MHE/MPC at this size is already impractical.
pub const MAX_DIMENSION: usize = 4096;

fn check_dimension(key: &str, what: &str, n: usize) -> Result<()> {
    if n > MAX_DIMENSION {
        return Err(scenario_err(
            key,
            format!(
                "gives {what} = {n}, above the supported maximum {MAX_DIMENSION}; dense MHE/MPC at \
                 this size is impractical, reduce the model"
            ),
        ));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Typed, validated scenario
// ---------------------------------------------------------------------------------------

/// A validated scenario: everything needed to set up a run of Alg. 1.
///
/// Built by [`Scenario::from_toml_str`] / [`Scenario::from_file`]; all dimensions are
/// consistent with [`Scenario::plant`].
#[derive(Debug, Clone)]
pub struct Scenario {
    /// Scenario name (`name`), used to label outputs.
    pub name: String,
    /// Free-text description (`description`).
    pub description: Option<String>,
    /// The plant of eq. (1) (`[plant]`).
    pub plant: LtiSystem,
    /// The constraint sets 𝒳, 𝒰, 𝒴, 𝒲 (`[sets]`).
    pub sets: ScenarioSets,
    /// How the true disturbance w_t is drawn (`[noise]`).
    pub noise: NoiseSpec,
    /// Initial state, prior and length of a run (`[simulation]`).
    pub simulation: SimulationSpec,
    /// MHE settings (`[mhe]`), if the scenario has them.
    pub mhe: Option<MheSpec>,
    /// MPC settings (`[mpc]`), if the scenario has them.
    pub mpc: Option<MpcSpec>,
    /// The verbatim text this scenario was parsed from (`None` if it was built in code), so
    /// that a run can record exactly what it used, comments included.
    pub source: Option<String>,
}

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
}

impl NoiseSpec {
    /// The Gaussian covariance after scaling, `scale²·covariance` (`None` unless Gaussian).
    ///
    /// ```
    /// let s = lti_model::scenario::Scenario::from_toml_str(
    ///     "name = \"g\"\n[plant]\na = [[0.5]]\nb = [[1.0]]\nc = [[1.0]]\n\
    ///      [noise]\nkind = \"gaussian\"\nscale = 2.0\ncovariance = 0.25\n",
    /// ).unwrap();
    /// let cov = s.noise.scaled_covariance().unwrap();
    /// assert_eq!((cov[(0, 0)], cov[(1, 1)], cov[(0, 1)]), (1.0, 1.0, 0.0));
    /// ```
    pub fn scaled_covariance(&self) -> Option<Mat<f64>> {
        let s2 = self.scale * self.scale;
        self.covariance
            .as_ref()
            .map(|c| Mat::from_fn(c.nrows(), c.ncols(), |i, j| s2 * c[(i, j)]))
    }

    /// The box uniform noise is drawn from, `scale`·𝒲 (`None` unless uniform).
    pub fn uniform_box(&self, disturbance: &BoxSet) -> Option<(Vec<f64>, Vec<f64>)> {
        (self.kind == NoiseKind::Uniform).then(|| {
            let scale = |v: &[f64]| v.iter().map(|b| self.scale * b).collect::<Vec<f64>>();
            (scale(disturbance.lower()), scale(disturbance.upper()))
        })
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

/// The iteration map Φ the MHE runs K times per time step (Assumption 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum MheSolver {
    /// Projected gradient (`"pg"`), the certified default.
    #[serde(rename = "pg")]
    ProjectedGradient,
    /// Accelerated projected gradient (`"fista"`).
    #[serde(rename = "fista")]
    Fista,
    /// ADMM (`"admm"`, relaxation α = 1).
    #[serde(rename = "admm")]
    Admm,
    /// ADMM over-relaxed to α = 2 (`"admm-pr"`, Peaceman–Rachford).
    #[serde(rename = "admm-pr")]
    AdmmPr,
}

/// How z⁰_{t+1} is obtained from zᴷ_t (step 2 of Alg. 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WarmStart {
    /// The paper's Σ_t: reuse zᴷ_t, zero-filling a new stage while the window grows.
    Paper,
    /// Time-shifted warm start (an extension; not covered by the paper's analysis).
    Shifted,
}

/// The `[mhe]` section (consumed by `mhe-core`).
#[derive(Debug, Clone)]
pub struct MheSpec {
    /// Horizon M ≥ 1.
    pub horizon: usize,
    /// Decay rate η ∈ [0, 1) of LMI (2) and cost (9).
    pub eta: f64,
    /// Disturbance weight Q, n_w = n_w1 + n_w2 square, positive definite (default I).
    pub q: Mat<f64>,
    /// Output weight R, n_y square, positive definite (default I).
    pub r: Mat<f64>,
    /// Prior weight P of W_δ (eq. 3), n_x square, positive definite; `None` means
    /// "compute it from LMI (2)".
    pub p: Option<Mat<f64>>,
    /// Iterations K ≥ 1 of Φ per time step.
    pub iterations: usize,
    /// The iteration map Φ (default projected gradient).
    pub solver: MheSolver,
    /// Warm-start rule (default the paper's).
    pub warm_start: WarmStart,
}

/// Terminal cost of the MPC.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TerminalCost {
    /// Solution of the discrete algebraic Riccati equation for (A, B, Q_c, R_c).
    Dare,
}

/// The `[mpc]` section (consumed by `mpc-core`).
#[derive(Debug, Clone)]
pub struct MpcSpec {
    /// Prediction horizon N ≥ 1.
    pub horizon: usize,
    /// Stage state weight Q_c, n_x square, positive definite (default I).
    pub q: Mat<f64>,
    /// Stage input weight R_c, n_u square, positive definite (default I).
    pub r: Mat<f64>,
    /// Terminal cost (default DARE).
    pub terminal: TerminalCost,
}

impl Scenario {
    /// Parses and validates a scenario from TOML text.
    pub fn from_toml_str(text: &str) -> Result<Self> {
        let de = toml::Deserializer::parse(text).map_err(|e| syntax_error(text, &e))?;
        let raw: RawScenario =
            serde_path_to_error::deserialize(de).map_err(|e| data_error(text, &e))?;
        let mut scenario = validate(raw)?;
        scenario.source = Some(text.to_string());
        Ok(scenario)
    }

    /// Reads, parses and validates a scenario file. I/O errors have key `"<file>"`.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| {
            scenario_err(
                "<file>",
                format!(
                    "cannot read `{}`: {e}; check the path (relative paths are resolved from the \
                     current directory)",
                    path.display()
                ),
            )
        })?;
        Self::from_toml_str(&text)
    }

    /// Canonical TOML of the validated scenario: every default made explicit, matrices as
    /// rows, comments dropped. Parsing it gives back an equal scenario.
    pub fn to_toml_string(&self) -> Result<String> {
        let raw = RawScenario::from_typed(self);
        toml::to_string(&raw)
            .map_err(|e| scenario_err("<toml>", format!("cannot serialise the scenario: {e}")))
    }
}

// ---------------------------------------------------------------------------------------
// Raw (serde) mirror of the file
// ---------------------------------------------------------------------------------------

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    #[serde(skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    description: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    plant: Option<Table<RawPlant>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    sets: Option<Table<RawSets>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    noise: Option<Table<RawNoise>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    simulation: Option<Table<RawSimulation>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mhe: Option<Table<RawMhe>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mpc: Option<Table<RawMpc>>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawPlant {
    #[serde(skip_serializing_if = "Option::is_none")]
    a: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    b: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    c: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    e: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    f: Option<MatrixSpec>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawSets {
    #[serde(skip_serializing_if = "Option::is_none")]
    state: Option<Table<RawBox>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    input: Option<Table<RawBox>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    output: Option<Table<RawBox>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    disturbance: Option<Table<RawBox>>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawBox {
    #[serde(skip_serializing_if = "Option::is_none")]
    lower: Option<Bounds>,
    #[serde(skip_serializing_if = "Option::is_none")]
    upper: Option<Bounds>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawNoise {
    #[serde(skip_serializing_if = "Option::is_none")]
    kind: Option<NoiseKind>,
    #[serde(skip_serializing_if = "Option::is_none")]
    scale: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    covariance: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    seed: Option<u64>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawSimulation {
    #[serde(skip_serializing_if = "Option::is_none")]
    x0: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    prior: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    steps: Option<usize>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawMhe {
    #[serde(skip_serializing_if = "Option::is_none")]
    horizon: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    eta: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    q: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    r: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    p: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    iterations: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    solver: Option<MheSolver>,
    #[serde(skip_serializing_if = "Option::is_none")]
    warm_start: Option<WarmStart>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RawMpc {
    #[serde(skip_serializing_if = "Option::is_none")]
    horizon: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    q: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    r: Option<MatrixSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    terminal: Option<TerminalCost>,
}

/// A section or set that must be a TOML table. Serde's derived structs also accept an
/// array of positional values (`state = [0, 1]`), which would be silently misread; this
/// wrapper refuses anything but a table.
#[derive(Debug)]
struct Table<T>(T);

impl<T> std::ops::Deref for Table<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.0
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Table<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct TableVisitor<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for TableVisitor<T> {
            type Value = Table<T>;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a table: a [section] or an inline table { key = value, ... }")
            }
            fn visit_map<A: MapAccess<'de>>(
                self,
                map: A,
            ) -> std::result::Result<Table<T>, A::Error> {
                T::deserialize(de::value::MapAccessDeserializer::new(map)).map(Table)
            }
        }
        d.deserialize_map(TableVisitor(std::marker::PhantomData))
    }
}

impl<T: Serialize> Serialize for Table<T> {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

/// A matrix as written in a scenario: rows, a multiple of the identity, or a diagonal.
#[derive(Debug, Clone, PartialEq)]
enum MatrixSpec {
    /// `[[1, 0], [0, 1]]`: row-major nested arrays (rows may still be ragged here).
    Rows(Vec<Vec<f64>>),
    /// `s`: s·I of the size the key requires.
    Scalar(f64),
    /// `{ diagonal = [d1, d2, ...] }`.
    Diagonal(Vec<f64>),
}

const MATRIX_FORMS: &str = "a matrix: an array of rows such as [[1.0, 0.0], [0.0, 1.0]], a number s \
                            meaning s·I, or a table { diagonal = [d1, d2, ...] }";

struct MatrixVisitor;

impl<'de> Visitor<'de> for MatrixVisitor {
    type Value = MatrixSpec;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(MATRIX_FORMS)
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> std::result::Result<MatrixSpec, E> {
        Ok(MatrixSpec::Scalar(v as f64))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> std::result::Result<MatrixSpec, E> {
        Ok(MatrixSpec::Scalar(v as f64))
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> std::result::Result<MatrixSpec, E> {
        Ok(MatrixSpec::Scalar(v))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<MatrixSpec, A::Error> {
        let mut rows = Vec::new();
        while let Some(Row(row)) = seq.next_element::<Row>()? {
            rows.push(row);
        }
        Ok(MatrixSpec::Rows(rows))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> std::result::Result<MatrixSpec, A::Error> {
        let mut diagonal: Option<Vec<f64>> = None;
        while let Some(key) = map.next_key::<String>()? {
            if key != "diagonal" {
                return Err(de::Error::unknown_field(&key, &["diagonal"]));
            }
            if diagonal.is_some() {
                return Err(de::Error::duplicate_field("diagonal"));
            }
            diagonal = Some(map.next_value()?);
        }
        diagonal
            .map(MatrixSpec::Diagonal)
            .ok_or_else(|| de::Error::missing_field("diagonal"))
    }
}

impl<'de> Deserialize<'de> for MatrixSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        d.deserialize_any(MatrixVisitor)
    }
}

impl Serialize for MatrixSpec {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            MatrixSpec::Rows(rows) => rows.serialize(s),
            MatrixSpec::Scalar(v) => s.serialize_f64(*v),
            MatrixSpec::Diagonal(d) => {
                let mut m = s.serialize_map(Some(1))?;
                m.serialize_entry("diagonal", d)?;
                m.end()
            }
        }
    }
}

/// One row of a [`MatrixSpec::Rows`]; rejects a bare number with a hint about `[[...]]`.
struct Row(Vec<f64>);

impl<'de> Deserialize<'de> for Row {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct RowVisitor;
        impl<'de> Visitor<'de> for RowVisitor {
            type Value = Row;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(
                    "a row of numbers such as [1.0, 0.0] (a matrix is an array of rows: write a 1×n \
                     matrix as [[a, b, ...]] and an n×1 matrix as [[a], [b], ...])",
                )
            }
            fn visit_seq<A: SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> std::result::Result<Row, A::Error> {
                let mut row = Vec::new();
                while let Some(v) = seq.next_element::<Number>()? {
                    row.push(v.0);
                }
                Ok(Row(row))
            }
        }
        d.deserialize_seq(RowVisitor)
    }
}

/// A matrix or vector entry: any TOML number (integers are converted to f64).
struct Number(f64);

impl<'de> Deserialize<'de> for Number {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct NumberVisitor;
        impl Visitor<'_> for NumberVisitor {
            type Value = Number;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> std::result::Result<Number, E> {
                Ok(Number(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> std::result::Result<Number, E> {
                Ok(Number(v as f64))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> std::result::Result<Number, E> {
                Ok(Number(v))
            }
        }
        d.deserialize_any(NumberVisitor)
    }
}

/// Box bounds: one value per component, or one value for all of them. Each value is a
/// number, TOML's `inf` / `-inf`, or the strings `"inf"`, `"+inf"`, `"-inf"`.
#[derive(Debug, Clone, PartialEq)]
enum Bounds {
    All(f64),
    Each(Vec<f64>),
}

const BOUND_FORMS: &str = "a number, inf / -inf, or the string \"inf\" / \"-inf\"";

fn parse_bound_str<E: de::Error>(v: &str) -> std::result::Result<f64, E> {
    match v.trim() {
        "inf" | "+inf" | "infinity" | "+infinity" => Ok(f64::INFINITY),
        "-inf" | "-infinity" => Ok(f64::NEG_INFINITY),
        _ => Err(de::Error::invalid_value(
            de::Unexpected::Str(v),
            &BOUND_FORMS,
        )),
    }
}

struct Bound(f64);

impl<'de> Deserialize<'de> for Bound {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct BoundVisitor;
        impl Visitor<'_> for BoundVisitor {
            type Value = Bound;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(BOUND_FORMS)
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> std::result::Result<Bound, E> {
                Ok(Bound(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> std::result::Result<Bound, E> {
                Ok(Bound(v as f64))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> std::result::Result<Bound, E> {
                Ok(Bound(v))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> std::result::Result<Bound, E> {
                parse_bound_str(v).map(Bound)
            }
        }
        d.deserialize_any(BoundVisitor)
    }
}

impl<'de> Deserialize<'de> for Bounds {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct BoundsVisitor;
        impl<'de> Visitor<'de> for BoundsVisitor {
            type Value = Bounds;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(
                    f,
                    "an array of bounds, or one bound for every component ({BOUND_FORMS})"
                )
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> std::result::Result<Bounds, E> {
                Ok(Bounds::All(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> std::result::Result<Bounds, E> {
                Ok(Bounds::All(v as f64))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> std::result::Result<Bounds, E> {
                Ok(Bounds::All(v))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> std::result::Result<Bounds, E> {
                parse_bound_str(v).map(Bounds::All)
            }
            fn visit_seq<A: SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> std::result::Result<Bounds, A::Error> {
                let mut out = Vec::new();
                while let Some(Bound(b)) = seq.next_element()? {
                    out.push(b);
                }
                Ok(Bounds::Each(out))
            }
        }
        d.deserialize_any(BoundsVisitor)
    }
}

impl Serialize for Bounds {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        // TOML writes ±∞ as the float literals `inf` / `-inf`, which the parser accepts.
        match self {
            Bounds::All(v) => s.serialize_f64(*v),
            Bounds::Each(v) => {
                let mut seq = s.serialize_seq(Some(v.len()))?;
                for b in v {
                    seq.serialize_element(b)?;
                }
                seq.end()
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------

fn scenario_err(key: impl Into<String>, problem: impl Into<String>) -> ModelError {
    ModelError::Scenario {
        key: key.into(),
        problem: problem.into(),
    }
}

/// Re-labels an lti-model error (shape, finiteness, weight, set) as a scenario error at `key`.
fn wrap(key: &str, e: ModelError) -> ModelError {
    let hint = match &e {
        ModelError::NotPositiveDefinite { .. } => " (a positive number s gives s·I)",
        ModelError::InvalidSet { .. } => {
            "; bounds must be numbers or ±inf, with lower[i] ≤ upper[i], lower[i] < inf and upper[i] > -inf"
        }
        _ => "",
    };
    match e {
        ModelError::Scenario { .. } => e,
        other => scenario_err(key, format!("{other}{hint}")),
    }
}

/// (line, column), both 1-based, of a byte offset in `text`.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

fn at_line(text: &str, span: Option<std::ops::Range<usize>>) -> String {
    span.map(|s| {
        let (l, c) = line_col(text, s.start);
        format!(" (line {l}, column {c})")
    })
    .unwrap_or_default()
}

fn syntax_error(text: &str, e: &toml::de::Error) -> ModelError {
    scenario_err(
        "<toml>",
        format!(
            "the file is not valid TOML{}: {}; fix the syntax (https://toml.io/en/v1.0.0)",
            at_line(text, e.span()),
            e.message().trim_end()
        ),
    )
}

/// First name between backticks in a serde message (`unknown field `x`, ...`).
fn backticked(msg: &str) -> Option<&str> {
    let start = msg.find('`')? + 1;
    let len = msg.get(start..)?.find('`')?;
    msg.get(start..start + len)
}

fn data_error(text: &str, e: &serde_path_to_error::Error<toml::de::Error>) -> ModelError {
    use serde_path_to_error::Segment;
    let mut key = String::new();
    let mut index = String::new();
    for seg in e.path() {
        match seg {
            Segment::Seq { index: i } => index.push_str(&format!("[{i}]")),
            Segment::Map { key: k } | Segment::Enum { variant: k } => {
                if !key.is_empty() {
                    key.push('.');
                }
                key.push_str(k);
                index.clear();
            }
            Segment::Unknown => {}
        }
    }
    let msg = e.inner().message().trim_end().to_string();
    let mut extend = |name: &str| {
        if !(key == name || key.ends_with(&format!(".{name}"))) {
            if !key.is_empty() {
                key.push('.');
            }
            key.push_str(name);
        }
    };
    let hint = if msg.starts_with("unknown field") {
        if let Some(name) = backticked(&msg) {
            extend(name);
        }
        "; remove the key or correct its spelling (docs/scenario-format.md lists every key)"
    } else if msg.starts_with("missing field") {
        if let Some(name) = backticked(&msg) {
            extend(name);
        }
        "; add the key"
    } else if msg.starts_with("unknown variant") {
        "; use one of the listed values"
    } else if msg.starts_with("duplicate") {
        "; give each key once"
    } else {
        ""
    };
    let key = if key.is_empty() {
        "<root>".to_string()
    } else {
        key
    };
    let element = if index.is_empty() {
        String::new()
    } else {
        format!("element {index}: ")
    };
    scenario_err(
        key,
        format!("{element}{msg}{}{hint}", at_line(text, e.inner().span())),
    )
}

// ---------------------------------------------------------------------------------------
// Validation
// ---------------------------------------------------------------------------------------

/// Rows → matrix, with messages for ragged rows and non-finite entries.
fn rows_to_mat(key: &str, rows: &[Vec<f64>]) -> Result<Mat<f64>> {
    let ncols = rows.first().map_or(0, Vec::len);
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != ncols) {
        return Err(scenario_err(
            key,
            format!(
                "row {i} has {} entries but row 0 has {ncols}; every row of a matrix must have the \
                 same length",
                r.len()
            ),
        ));
    }
    let m = Mat::from_fn(rows.len(), ncols, |i, j| rows[i][j]);
    check_entries(key, &m)?;
    Ok(m)
}

fn check_entries(key: &str, m: &Mat<f64>) -> Result<()> {
    matrix::check_finite(key, m.as_ref()).map_err(|e| match e {
        ModelError::NonFinite {
            row, col, value, ..
        } => scenario_err(
            key,
            format!("entry ({row}, {col}) is {value}; every matrix entry must be a finite number"),
        ),
        other => wrap(key, other),
    })
}

fn scalar_identity(key: &str, s: f64, n: usize) -> Result<Mat<f64>> {
    if !s.is_finite() {
        return Err(scenario_err(
            key,
            format!("the scalar {s} (meaning s·I) must be a finite number"),
        ));
    }
    Ok(Mat::from_fn(n, n, |i, j| if i == j { s } else { 0.0 }))
}

fn diagonal(key: &str, d: &[f64]) -> Result<Mat<f64>> {
    check_dimension(key, "the matrix size", d.len())?;
    if let Some((i, v)) = d.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(scenario_err(
            key,
            format!("diagonal entry {i} is {v}; every matrix entry must be a finite number"),
        ));
    }
    Ok(Mat::from_fn(d.len(), d.len(), |i, j| {
        if i == j { d[i] } else { 0.0 }
    }))
}

/// A matrix whose shape comes from the file (plant A, B, C): a bare scalar is refused.
fn free_matrix(key: &str, spec: &MatrixSpec) -> Result<Mat<f64>> {
    match spec {
        MatrixSpec::Rows(rows) => rows_to_mat(key, rows),
        MatrixSpec::Diagonal(d) => diagonal(key, d),
        MatrixSpec::Scalar(_) => Err(scenario_err(
            key,
            "a bare number means s·I, but the size of this matrix is not known yet; write it as an \
             array of rows, e.g. [[1.0, 0.0], [0.0, 1.0]], or as { diagonal = [...] }",
        )),
    }
}

/// A matrix whose shape the plant fixes: `rows × cols`, where `dims` explains why.
fn sized_matrix(
    key: &str,
    spec: &MatrixSpec,
    rows: usize,
    cols: usize,
    dims: &str,
) -> Result<Mat<f64>> {
    let m = match spec {
        MatrixSpec::Rows(r) => rows_to_mat(key, r)?,
        MatrixSpec::Scalar(s) if rows == cols => scalar_identity(key, *s, rows)?,
        MatrixSpec::Scalar(_) => {
            return Err(scenario_err(
                key,
                format!(
                    "a bare number means s·I, which is square, but this matrix must be {rows}×{cols} \
                     ({dims}); write it as an array of rows"
                ),
            ));
        }
        MatrixSpec::Diagonal(d) => {
            if rows != cols || d.len() != rows {
                return Err(scenario_err(
                    key,
                    format!(
                        "the diagonal has {} entries, so the matrix is {}×{}, but it must be \
                         {rows}×{cols} ({dims})",
                        d.len(),
                        d.len(),
                        d.len()
                    ),
                ));
            }
            diagonal(key, d)?
        }
    };
    if m.nrows() != rows || m.ncols() != cols {
        return Err(scenario_err(
            key,
            format!(
                "has shape {}×{}, expected {rows}×{cols} ({dims}); give {rows} rows of {cols} entries",
                m.nrows(),
                m.ncols()
            ),
        ));
    }
    Ok(m)
}

/// A weight: `n × n`, finite, symmetric, positive definite; `None` gives the identity.
fn weight(key: &str, spec: Option<&MatrixSpec>, n: usize, dims: &str) -> Result<Mat<f64>> {
    let m = match spec {
        Some(s) => sized_matrix(key, s, n, n, dims)?,
        None => Mat::identity(n, n),
    };
    matrix::check_positive_definite(key, m.as_ref(), n).map_err(|e| wrap(key, e))?;
    Ok(m)
}

fn vector(key: &str, v: Option<&Vec<f64>>, n: usize, what: &str) -> Result<Vec<f64>> {
    let Some(v) = v else { return Ok(vec![0.0; n]) };
    if v.len() != n {
        return Err(scenario_err(
            key,
            format!(
                "has {} entries, expected {n} (one per {what}); give exactly {n} numbers",
                v.len()
            ),
        ));
    }
    if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
        return Err(scenario_err(
            key,
            format!("entry {i} is {x}; every entry must be a finite number"),
        ));
    }
    Ok(v.clone())
}

fn bound_vec(
    key: &str,
    b: Option<&Bounds>,
    n: usize,
    default: f64,
    what: &str,
) -> Result<Vec<f64>> {
    match b {
        None => Ok(vec![default; n]),
        Some(Bounds::All(v)) => Ok(vec![*v; n]),
        Some(Bounds::Each(v)) if v.len() == n => Ok(v.clone()),
        Some(Bounds::Each(v)) => Err(scenario_err(
            key,
            format!(
                "has {} entries, expected {n} (one per {what}); give {n} bounds or a single bound for all",
                v.len()
            ),
        )),
    }
}

fn box_set(key: &str, raw: Option<&RawBox>, n: usize, what: &str) -> Result<BoxSet> {
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
    let set = BoxSet::named(key, lower, upper).map_err(|e| wrap(key, e))?;
    // Assumption 1: 𝒵 = 𝒳 × 𝒰 × 𝒴 × 𝒲 contains the origin.
    for (i, (l, u)) in set.lower().iter().zip(set.upper()).enumerate() {
        if *l > 0.0 || *u < 0.0 {
            return Err(scenario_err(
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

fn required<T: Copy>(key: &str, v: Option<T>, example: &str) -> Result<T> {
    v.ok_or_else(|| {
        scenario_err(
            key,
            format!("is required but missing; add it, e.g. `{example}`"),
        )
    })
}

fn at_least_one(key: &str, v: usize, what: &str) -> Result<usize> {
    if v == 0 {
        return Err(scenario_err(
            key,
            format!("is 0, but {what} must be at least 1"),
        ));
    }
    Ok(v)
}

fn validate_plant(raw: Option<&RawPlant>) -> Result<LtiSystem> {
    let Some(p) = raw else {
        return Err(scenario_err(
            "plant",
            "the [plant] section is required but missing; add it with a, b, c, e.g. \
             [plant] a = [[0.5]] b = [[1.0]] c = [[1.0]]",
        ));
    };
    let missing = |k: &str, what: &str| {
        scenario_err(
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
        return Err(scenario_err(
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
        return Err(scenario_err(
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
        return Err(scenario_err(
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
                    return Err(scenario_err(
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

fn validate_noise(
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
        if !disturbance_given {
            return Ok(NoiseSpec {
                kind: NoiseKind::Zero,
                scale: 1.0,
                covariance: None,
                seed: 0,
            });
        }
        if !bounded {
            return Err(scenario_err(
                "sets.disturbance",
                "without a [noise] section the disturbance is uniform on sets.disturbance, which needs \
                 finite bounds; make every bound finite or add [noise] with kind = \"gaussian\" or \"zero\"",
            ));
        }
        return Ok(NoiseSpec {
            kind: NoiseKind::Uniform,
            scale: 1.0,
            covariance: None,
            seed: 0,
        });
    };
    let kind = raw.kind.unwrap_or(NoiseKind::Uniform);
    let scale = raw.scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale >= 0.0) {
        return Err(scenario_err(
            "noise.scale",
            format!("is {scale}; it must be a finite number ≥ 0"),
        ));
    }
    if kind == NoiseKind::Uniform && !bounded {
        return Err(scenario_err(
            "noise.kind",
            "uniform noise is drawn from sets.disturbance, which has an infinite (or no) bound; give \
             sets.disturbance finite bounds or choose kind = \"gaussian\" or \"zero\"",
        ));
    }
    let covariance = match (kind, raw.covariance.as_ref()) {
        (NoiseKind::Gaussian, Some(c)) => Some(weight(
            "noise.covariance",
            Some(c),
            nw,
            "n_w = n_w1 + n_w2 square",
        )?),
        (NoiseKind::Gaussian, None) => {
            return Err(scenario_err(
                "noise.covariance",
                format!(
                    "kind = \"gaussian\" needs a covariance ({nw}×{nw}, symmetric positive definite); \
                     add e.g. `covariance = 0.01` for 0.01·I"
                ),
            ));
        }
        (_, Some(_)) => {
            return Err(scenario_err(
                "noise.covariance",
                "is only used with kind = \"gaussian\"; remove it or set kind = \"gaussian\"",
            ));
        }
        (_, None) => None,
    };
    Ok(NoiseSpec {
        kind,
        scale,
        covariance,
        seed: raw.seed.unwrap_or(0),
    })
}

fn validate_mhe(raw: &RawMhe, sys: &LtiSystem) -> Result<MheSpec> {
    let horizon = required("mhe.horizon", raw.horizon, "horizon = 5")?;
    let horizon = at_least_one("mhe.horizon", horizon, "the estimation horizon M")?;
    let eta = required("mhe.eta", raw.eta, "eta = 0.8")?;
    if !(eta.is_finite() && (0.0..1.0).contains(&eta)) {
        return Err(scenario_err(
            "mhe.eta",
            format!("is {eta}, but η must lie in [0, 1) (Assumption 2); pick e.g. 0.8"),
        ));
    }
    let iterations = required("mhe.iterations", raw.iterations, "iterations = 50")?;
    let iterations = at_least_one("mhe.iterations", iterations, "the iteration count K")?;
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
    Ok(MheSpec {
        horizon,
        eta,
        q,
        r,
        p,
        iterations,
        solver: raw.solver.unwrap_or(MheSolver::ProjectedGradient),
        warm_start: raw.warm_start.unwrap_or(WarmStart::Paper),
    })
}

fn validate_mpc(raw: &RawMpc, sys: &LtiSystem) -> Result<MpcSpec> {
    let horizon = required("mpc.horizon", raw.horizon, "horizon = 10")?;
    let horizon = at_least_one("mpc.horizon", horizon, "the prediction horizon N")?;
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
    Ok(MpcSpec {
        horizon,
        q,
        r,
        terminal: raw.terminal.unwrap_or(TerminalCost::Dare),
    })
}

fn validate(raw: RawScenario) -> Result<Scenario> {
    let name = raw.name.clone().ok_or_else(|| {
        scenario_err(
            "name",
            "is required but missing; add a top-level `name = \"my-scenario\"`",
        )
    })?;
    if name.trim().is_empty() {
        return Err(scenario_err(
            "name",
            "is empty; give the scenario a name, e.g. `name = \"case-study\"`",
        ));
    }
    let plant = validate_plant(raw.plant.as_deref())?;
    let (nx, nu, ny, nw) = (plant.nx(), plant.nu(), plant.ny(), plant.nw());
    let raw_sets = raw.sets.as_deref();
    let pick = |f: fn(&RawSets) -> Option<&RawBox>| raw_sets.and_then(f);
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
    let disturbance_given = pick(|s| s.disturbance.as_deref()).is_some();
    let noise = validate_noise(raw.noise.as_deref(), &sets, disturbance_given, nw)?;

    let sim = raw.simulation.as_deref();
    let x0 = vector(
        "simulation.x0",
        sim.and_then(|s| s.x0.as_ref()),
        nx,
        "state",
    )?;
    let prior = vector(
        "simulation.prior",
        sim.and_then(|s| s.prior.as_ref()),
        nx,
        "state",
    )?;
    let steps = at_least_one(
        "simulation.steps",
        sim.and_then(|s| s.steps).unwrap_or(DEFAULT_STEPS),
        "the number of time steps",
    )?;
    let violation = crate::sets::ConvexSet::violation(&sets.state, &x0);
    if violation > 0.0 {
        return Err(scenario_err(
            "simulation.x0",
            format!(
                "lies outside sets.state (by {violation}); the true initial state must satisfy x₀ ∈ 𝒳"
            ),
        ));
    }

    let mhe = raw
        .mhe
        .as_ref()
        .map(|m| validate_mhe(m, &plant))
        .transpose()?;
    let mpc = raw
        .mpc
        .as_ref()
        .map(|m| validate_mpc(m, &plant))
        .transpose()?;

    Ok(Scenario {
        name,
        description: raw.description,
        plant,
        sets,
        noise,
        simulation: SimulationSpec { x0, prior, steps },
        mhe,
        mpc,
        source: None,
    })
}

// ---------------------------------------------------------------------------------------
// Typed → raw (for `to_toml_string`)
// ---------------------------------------------------------------------------------------

fn rows_of(m: &Mat<f64>) -> MatrixSpec {
    MatrixSpec::Rows(matrix::to_rows(m.as_ref()))
}

fn raw_box(b: &BoxSet) -> RawBox {
    RawBox {
        lower: Some(Bounds::Each(b.lower().to_vec())),
        upper: Some(Bounds::Each(b.upper().to_vec())),
    }
}

impl RawScenario {
    fn from_typed(s: &Scenario) -> Self {
        let p = &s.plant;
        let to_mat = |m: faer::MatRef<'_, f64>| MatrixSpec::Rows(matrix::to_rows(m));
        RawScenario {
            name: Some(s.name.clone()),
            description: s.description.clone(),
            plant: Some(Table(RawPlant {
                a: Some(to_mat(p.a())),
                b: Some(to_mat(p.b())),
                c: Some(to_mat(p.c())),
                e: Some(to_mat(p.e())),
                f: Some(to_mat(p.f())),
            })),
            sets: Some(Table(RawSets {
                state: Some(Table(raw_box(&s.sets.state))),
                input: Some(Table(raw_box(&s.sets.input))),
                output: Some(Table(raw_box(&s.sets.output))),
                disturbance: Some(Table(raw_box(&s.sets.disturbance))),
            })),
            noise: Some(Table(RawNoise {
                kind: Some(s.noise.kind),
                scale: Some(s.noise.scale),
                covariance: s.noise.covariance.as_ref().map(rows_of),
                seed: Some(s.noise.seed),
            })),
            simulation: Some(Table(RawSimulation {
                x0: Some(s.simulation.x0.clone()),
                prior: Some(s.simulation.prior.clone()),
                steps: Some(s.simulation.steps),
            })),
            mhe: s.mhe.as_ref().map(|m| {
                Table(RawMhe {
                    horizon: Some(m.horizon),
                    eta: Some(m.eta),
                    q: Some(rows_of(&m.q)),
                    r: Some(rows_of(&m.r)),
                    p: m.p.as_ref().map(rows_of),
                    iterations: Some(m.iterations),
                    solver: Some(m.solver),
                    warm_start: Some(m.warm_start),
                })
            }),
            mpc: s.mpc.as_ref().map(|m| {
                Table(RawMpc {
                    horizon: Some(m.horizon),
                    q: Some(rows_of(&m.q)),
                    r: Some(rows_of(&m.r)),
                    terminal: Some(m.terminal),
                })
            }),
        }
    }
}
