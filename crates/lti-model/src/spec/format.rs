//! The scenario file format shared by every layer's settings: matrices written as rows,
//! s·I or a diagonal ([`MatrixSpec`]), bounds with ±∞ ([`Bounds`]), sections that must be
//! tables ([`Table`]), and errors that name the dotted key ([`key_error`], [`data_error`],
//! [`syntax_error`]). The helpers below check a value against the size the plant fixes.
//! `lti-model` parses `[plant]`, `[sets]`, `[noise]`, `[simulation]` with them
//! ([`super::plant`]); `mhe-core` and `mpc-core` parse their own `[mhe]` / `[mpc]`
//! sections; `closed-loop` composes the file.

use std::fmt;

use faer::Mat;
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::ser::{SerializeMap, SerializeSeq, Serializer};
use serde::{Deserialize, Serialize};

use crate::error::{ModelError, Result};
use crate::matrix;

pub use super::limits::{MAX_DENSE_BYTES, MAX_FILE_BYTES, check_dense_bytes, read_limited};

/// Largest n_x, n_u, n_y, n_w1, n_w2 a scenario may have. Dense n × n weights are built
/// from a few bytes of text (`q = 1.0`, `{ diagonal = [...] }`), so without a cap a short
/// file could request terabytes; dense MHE/MPC at this size is already impractical.
pub const MAX_DIMENSION: usize = 4096;

/// Largest magnitude of a finite number in a scenario (matrix entries, vectors, finite
/// bounds, scales): 1e100. The computations multiply a few of them (AᵀPA, BᵀXB, ΓᵀQ̄Γ,
/// ‖x‖²); with every factor ≤ 1e100 a product of three summed over n ≤ 4096 terms stays
/// below f64's 1.8e308, so a value that would overflow is refused here, naming its entry,
/// instead of surfacing as ∞ or NaN inside the LMI, the Riccati equation or a norm.
pub const MAX_MAGNITUDE: f64 = 1e100;

/// The refusal of a finite `value` beyond [`MAX_MAGNITUDE`] at `what` (e.g. "entry (0, 1)").
pub fn magnitude_error(key: &str, what: &str, value: f64) -> ModelError {
    key_error(
        key,
        format!(
            "{what} is {value:.3e}, beyond ±{MAX_MAGNITUDE:e}, the largest magnitude accepted \
             (products of a few such numbers overflow f64); rescale the units of the model \
             (docs/limits.md)"
        ),
    )
}

/// Refuses a finite number beyond [`MAX_MAGNITUDE`] (a non-finite one is checked by the
/// caller, with its own message).
pub fn check_magnitude(key: &str, what: &str, value: f64) -> Result<()> {
    if value.is_finite() && value.abs() > MAX_MAGNITUDE {
        return Err(magnitude_error(key, what, value));
    }
    Ok(())
}

/// The smallest nonzero magnitude of a scale factor (`noise.scale`, a sweep's `scales`,
/// γ₁,₃): 1/[`MAX_MAGNITUDE`] = 1e-100. Its square must not underflow, and its inverse must
/// stay within the limit.
pub const MIN_SCALE: f64 = 1.0 / MAX_MAGNITUDE;

/// Refuses a scale factor outside {0} ∪ [[`MIN_SCALE`], [`MAX_MAGNITUDE`]] (or not finite),
/// naming `key`: the one rule for `noise.scale`, a sweep's `scales` and γ₁,₃ (which must
/// also be > 0: the caller checks).
pub fn check_scale(key: &str, value: f64) -> Result<()> {
    if !(value.is_finite() && value >= 0.0) {
        return Err(key_error(
            key,
            format!("is {value}; it must be a finite number ≥ 0"),
        ));
    }
    if value > MAX_MAGNITUDE {
        return Err(key_error(
            key,
            format!(
                "is {value:.3e}, above {MAX_MAGNITUDE:e}, the largest scale accepted (products of \
                 a few such numbers overflow f64); rescale the units of the model \
                 (docs/limits.md)"
            ),
        ));
    }
    if value > 0.0 && value < MIN_SCALE {
        return Err(key_error(
            key,
            format!(
                "is {value:.3e}, nonzero but below {MIN_SCALE:e}, the smallest scale accepted \
                 (its square underflows, its inverse overflows); use a larger value, or 0 where \
                 it turns a disturbance off (docs/limits.md)"
            ),
        ));
    }
    Ok(())
}

pub fn check_dimension(key: &str, what: &str, n: usize) -> Result<()> {
    if n > MAX_DIMENSION {
        return Err(key_error(
            key,
            format!(
                "gives {what} = {n}, above the supported maximum {MAX_DIMENSION}; dense MHE/MPC at \
                 this size is impractical, reduce the model"
            ),
        ));
    }
    Ok(())
}

/// A section or set that must be a TOML table. Serde's derived structs also accept an
/// array of positional values (`state = [0, 1]`), which would be silently misread; this
/// wrapper refuses anything but a table.
#[derive(Debug)]
pub struct Table<T>(pub T);

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
pub enum MatrixSpec {
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
pub enum Bounds {
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

pub fn key_error(key: impl Into<String>, problem: impl Into<String>) -> ModelError {
    ModelError::Scenario {
        key: key.into(),
        problem: problem.into(),
    }
}

/// Re-labels an lti-model error (shape, finiteness, weight, set) as a scenario error at `key`.
pub fn wrap(key: &str, e: ModelError) -> ModelError {
    let hint = match &e {
        ModelError::NotPositiveDefinite { .. } => " (a positive number s gives s·I)",
        ModelError::InvalidSet { .. } => {
            "; bounds must be numbers or ±inf, with lower[i] ≤ upper[i], lower[i] < inf and upper[i] > -inf"
        }
        _ => "",
    };
    match e {
        ModelError::Scenario { .. } => e,
        other => key_error(key, format!("{other}{hint}")),
    }
}

/// (line, column), both 1-based, of a byte offset in `text`.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// " (line L, column C)" of a span's start in `text`, or "" without a span.
pub fn at_line(text: &str, span: Option<std::ops::Range<usize>>) -> String {
    span.map(|s| {
        let (l, c) = line_col(text, s.start);
        format!(" (line {l}, column {c})")
    })
    .unwrap_or_default()
}

pub fn syntax_error(text: &str, e: &toml::de::Error) -> ModelError {
    key_error(
        "<toml>",
        format!(
            "the file is not valid TOML{}: {}; fix the syntax (https://toml.io/en/v1.0.0)",
            at_line(text, e.span()),
            e.message().trim_end()
        ),
    )
}

/// First name between backticks in a serde message (`unknown field `x`, ...`).
pub fn backticked(msg: &str) -> Option<&str> {
    let start = msg.find('`')? + 1;
    let len = msg.get(start..)?.find('`')?;
    msg.get(start..start + len)
}

pub fn data_error(text: &str, e: &serde_path_to_error::Error<toml::de::Error>) -> ModelError {
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
    key_error(
        key,
        format!("{element}{msg}{}{hint}", at_line(text, e.inner().span())),
    )
}

// ---------------------------------------------------------------------------------------
// Validation
// ---------------------------------------------------------------------------------------

/// Rows → matrix, with messages for ragged rows and non-finite entries.
pub fn rows_to_mat(key: &str, rows: &[Vec<f64>]) -> Result<Mat<f64>> {
    let ncols = rows.first().map_or(0, Vec::len);
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != ncols) {
        return Err(key_error(
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
        } => key_error(
            key,
            format!("entry ({row}, {col}) is {value}; every matrix entry must be a finite number"),
        ),
        other => wrap(key, other),
    })?;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            check_magnitude(key, &format!("entry ({i}, {j})"), m[(i, j)])?;
        }
    }
    Ok(())
}

pub fn scalar_identity(key: &str, s: f64, n: usize) -> Result<Mat<f64>> {
    if !s.is_finite() {
        return Err(key_error(
            key,
            format!("the scalar {s} (meaning s·I) must be a finite number"),
        ));
    }
    check_magnitude(key, "the scalar s (meaning s·I)", s)?;
    Ok(Mat::from_fn(n, n, |i, j| if i == j { s } else { 0.0 }))
}

pub fn diagonal(key: &str, d: &[f64]) -> Result<Mat<f64>> {
    check_dimension(key, "the matrix size", d.len())?;
    if let Some((i, v)) = d.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(key_error(
            key,
            format!("diagonal entry {i} is {v}; every matrix entry must be a finite number"),
        ));
    }
    for (i, v) in d.iter().enumerate() {
        check_magnitude(key, &format!("diagonal entry {i}"), *v)?;
    }
    Ok(Mat::from_fn(d.len(), d.len(), |i, j| {
        if i == j { d[i] } else { 0.0 }
    }))
}

/// A matrix whose shape comes from the file (plant A, B, C): a bare scalar is refused.
pub fn free_matrix(key: &str, spec: &MatrixSpec) -> Result<Mat<f64>> {
    match spec {
        MatrixSpec::Rows(rows) => rows_to_mat(key, rows),
        MatrixSpec::Diagonal(d) => diagonal(key, d),
        MatrixSpec::Scalar(_) => Err(key_error(
            key,
            "a bare number means s·I, but the size of this matrix is not known yet; write it as an \
             array of rows, e.g. [[1.0, 0.0], [0.0, 1.0]], or as { diagonal = [...] }",
        )),
    }
}

/// A matrix whose shape the plant fixes: `rows × cols`, where `dims` explains why.
pub fn sized_matrix(
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
            return Err(key_error(
                key,
                format!(
                    "a bare number means s·I, which is square, but this matrix must be {rows}×{cols} \
                     ({dims}); write it as an array of rows"
                ),
            ));
        }
        MatrixSpec::Diagonal(d) => {
            if rows != cols || d.len() != rows {
                return Err(key_error(
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
        return Err(key_error(
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
pub fn weight(key: &str, spec: Option<&MatrixSpec>, n: usize, dims: &str) -> Result<Mat<f64>> {
    let m = match spec {
        Some(s) => sized_matrix(key, s, n, n, dims)?,
        None => Mat::identity(n, n),
    };
    matrix::check_positive_definite(key, m.as_ref(), n).map_err(|e| wrap(key, e))?;
    Ok(m)
}

pub fn vector(key: &str, v: Option<&Vec<f64>>, n: usize, what: &str) -> Result<Vec<f64>> {
    let Some(v) = v else { return Ok(vec![0.0; n]) };
    if v.len() != n {
        return Err(key_error(
            key,
            format!(
                "has {} entries, expected {n} (one per {what}); give exactly {n} numbers",
                v.len()
            ),
        ));
    }
    if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
        return Err(key_error(
            key,
            format!("entry {i} is {x}; every entry must be a finite number"),
        ));
    }
    for (i, x) in v.iter().enumerate() {
        check_magnitude(key, &format!("entry {i}"), *x)?;
    }
    Ok(v.clone())
}

pub fn bound_vec(
    key: &str,
    b: Option<&Bounds>,
    n: usize,
    default: f64,
    what: &str,
) -> Result<Vec<f64>> {
    // A finite bound beyond MAX_MAGNITUDE is refused: ±inf says "no bound", and a huge
    // finite one makes upper − lower (the uniform noise's width) overflow.
    let bound = |i: Option<usize>, v: f64| -> Result<()> {
        if v.is_finite() && v.abs() > MAX_MAGNITUDE {
            let what = i.map_or("the bound".to_string(), |i| format!("bound {i}"));
            return Err(key_error(
                key,
                format!(
                    "{what} is {v:e}, beyond ±{MAX_MAGNITUDE:e}, the largest finite magnitude \
                     accepted; write inf / -inf for no bound, or rescale (docs/limits.md)"
                ),
            ));
        }
        Ok(())
    };
    match b {
        None => Ok(vec![default; n]),
        Some(Bounds::All(v)) => {
            bound(None, *v)?;
            Ok(vec![*v; n])
        }
        Some(Bounds::Each(v)) if v.len() == n => {
            for (i, x) in v.iter().enumerate() {
                bound(Some(i), *x)?;
            }
            Ok(v.clone())
        }
        Some(Bounds::Each(v)) => Err(key_error(
            key,
            format!(
                "has {} entries, expected {n} (one per {what}); give {n} bounds or a single bound for all",
                v.len()
            ),
        )),
    }
}

pub fn required<T: Copy>(key: &str, v: Option<T>, example: &str) -> Result<T> {
    v.ok_or_else(|| {
        key_error(
            key,
            format!("is required but missing; add it, e.g. `{example}`"),
        )
    })
}

pub fn at_least_one(key: &str, v: usize, what: &str) -> Result<usize> {
    if v == 0 {
        return Err(key_error(
            key,
            format!("is 0, but {what} must be at least 1"),
        ));
    }
    Ok(v)
}

pub fn rows_of(m: &Mat<f64>) -> MatrixSpec {
    MatrixSpec::Rows(matrix::to_rows(m.as_ref()))
}

/// Parses TOML `text` into the raw mirror `T`: a syntax error has key `"<toml>"` and the
/// line; a type error or an unknown key names the dotted key path (through
/// `serde_path_to_error`).
pub fn parse<T: serde::de::DeserializeOwned>(text: &str) -> Result<T> {
    let de = toml::Deserializer::parse(text).map_err(|e| syntax_error(text, &e))?;
    serde_path_to_error::deserialize(de).map_err(|e| data_error(text, &e))
}
