//! `export(...)`: the CLI's export (`mhe_export::export`, the one verdict, the same files)
//! from Python, on a `Model` or a scenario.

use std::path::PathBuf;

use mhe_export::{ExportError, ExportOptions, Iterations, Lang, ScalarKind, Source};
use pyo3::prelude::*;
use qp_iter::Method;
use serde_json::json;

use crate::{
    CertificateError, InputError, MheError, Model, PyScenario, ScenarioError, UnsupportedError,
};

/// The Python exception of an export error, naming the Python argument (`k`, `kc`, …).
fn export_err(e: &ExportError) -> PyErr {
    match e {
        ExportError::InvalidOption { option, message } => {
            InputError::new_err(format!("argument `{option}`: {message}"))
        }
        ExportError::Scenario { .. } => ScenarioError::new_err(e.to_string()),
        ExportError::Certificate { .. } | ExportError::NotCertified { .. } => {
            CertificateError::new_err(e.to_string())
        }
        ExportError::Unsupported { .. } => UnsupportedError::new_err(e.to_string()),
        _ => MheError::new_err(e.to_string()),
    }
}

fn method_arg(name: &str, m: Option<&str>) -> PyResult<Option<Method>> {
    m.map(|m| {
        m.parse()
            .map_err(|e: qp_iter::QpError| InputError::new_err(format!("argument `{name}`: {e}")))
    })
    .transpose()
}

/// Exports the certified estimator (and the K_c-iteration MPC when asked) of `model` or
/// `scenario` into `out` with `mhe_export`, exactly as `cargo xtask export` does; returns
/// a JSON summary (method, K, K_min, the verdicts). The GIL is released while it runs.
#[pyfunction]
#[pyo3(signature = (out, model=None, scenario=None, source_path=None, source_bytes=None, method=None, k="certified", kc=None, mpc_method=None, scalar="f64", lang="c", prefix="mhe", allow_uncertified=false))]
pub(crate) fn export_artefact(
    py: Python<'_>,
    out: PathBuf,
    model: Option<&Model>,
    scenario: Option<&PyScenario>,
    source_path: Option<String>,
    source_bytes: Option<Vec<u8>>,
    method: Option<&str>,
    k: &str,
    kc: Option<&str>,
    mpc_method: Option<&str>,
    scalar: &str,
    lang: &str,
    prefix: &str,
    allow_uncertified: bool,
) -> PyResult<String> {
    let mut o = ExportOptions::default();
    o.k = Iterations::parse("--k", k).map_err(|e| export_err(&e))?;
    o.k_c = kc
        .map(|a| Iterations::parse("--kc", a))
        .transpose()
        .map_err(|e| export_err(&e))?;
    o.method = method_arg("method", method)?;
    o.mpc_method = method_arg("mpc_method", mpc_method)?;
    o.scalar = match scalar {
        "f64" | "float64" => ScalarKind::F64,
        "f32" | "float32" => ScalarKind::F32,
        other => {
            return Err(InputError::new_err(format!(
                "argument `dtype` = {other:?}: use \"float64\" or \"float32\""
            )));
        }
    };
    o.lang = match lang {
        "c" => Lang::C,
        "rust" => Lang::Rust,
        other => {
            return Err(InputError::new_err(format!(
                "argument `lang` = {other:?}: use \"c\" or \"rust\""
            )));
        }
    };
    if prefix.trim().is_empty() {
        return Err(InputError::new_err(
            "argument `prefix` = \"\": give a C identifier, e.g. \"mhe\"",
        ));
    }
    o.prefix = prefix.to_string();
    o.allow_uncertified = allow_uncertified;
    if let (Some(path), Some(bytes)) = (source_path, source_bytes.as_deref()) {
        o.source = Source::from_bytes(path, bytes);
    }
    o.validate().map_err(|e| export_err(&e))?;
    mhe_export::check_output_dir(&out).map_err(|e| export_err(&e))?;
    let art = match (model, scenario) {
        (Some(m), None) => {
            let model = m.model.clone();
            o.check_scenario(model.scenario())
                .map_err(|e| export_err(&e))?;
            py.detach(move || mhe_export::export(model.resolved(), &o))
        }
        (None, Some(s)) => {
            let sc = s.scenario.clone();
            o.check_scenario(&sc).map_err(|e| export_err(&e))?;
            let resolved = sc
                .resolve()
                .map_err(|e| ScenarioError::new_err(format!("cannot set up the scenario: {e}")))?;
            py.detach(move || mhe_export::export(&resolved, &o))
        }
        _ => {
            return Err(InputError::new_err(
                "give exactly one of a Model or a scenario to export",
            ));
        }
    }
    .map_err(|e| export_err(&e))?;
    py.detach(|| art.write_to(&out))
        .map_err(|e| export_err(&e))?;
    Ok(json!({
        "out": out.display().to_string(),
        "scenario": art.scenario(),
        "method": art.method(),
        "k": art.k(),
        "k_min": art.k_min(),
        "certified": art.certified(),
        "loop_certified": art.loop_certified(),
        "uncertified_reason": art.uncertified_reason(),
        "mpc": art.mpc().map(|(m, k_c)| json!({"method": m, "k_c": k_c})),
    })
    .to_string())
}
