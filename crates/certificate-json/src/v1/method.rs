//! The method Φ as the certificates write it.

use serde::Serialize;

/// A method Φ, spelled as in the scenario file (`mhe.solver`): a preset's name (`"pg"`,
/// `"admm-jacobi"`, …) as a string, a tuned method as the table of its family and
/// parameters. The spelling is the configuration syntax `qp_iter::Method` reads and writes
/// (a configuration type, not an outcome: it keeps its serde form in qp-iter).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Method(pub serde_json::Value);

impl From<&qp_iter::Method> for Method {
    fn from(m: &qp_iter::Method) -> Self {
        // A method serialises to a string or a map of numbers: never an error; the name is
        // the fallback all the same.
        Self(serde_json::to_value(m).unwrap_or_else(|_| serde_json::Value::String(m.name().into())))
    }
}
