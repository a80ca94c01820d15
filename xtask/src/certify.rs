//! `cargo xtask certify`: the δ-IOSS certificate (Assumption 2, LMI (2)) of a scenario,
//! as a short text summary and a self-contained JSON document (docs/certificate-json.md).
//!
//! The certificate is the library's ([`mhe_report::ioss::ioss_certificate`]); the tool reads
//! the files (the scenario, `--p-file`), words the errors and hints with its flags, and writes
//! `certificate_json::v1::IossCertificate`. The JSON carries A, C, B̄, D̄, η, Q, R and P, so
//! any tool can rebuild the LMI matrix and check its eigenvalues without this code.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use certificate_json::v1;
use closed_loop::scenario::Scenario;
use faer::Mat;
use lti_model::matrix;
use mhe_report::ioss::{
    ETA_HINT_RESOLUTION, EtaSource, IossError, IossHint, IossOutcome, IossRequest, SuppliedP,
    WeightsSource,
};

use crate::provenance::Provenance;
use crate::reproduce::numfmt::num;

/// Value of the `format` field.
pub const FORMAT: &str = v1::IOSS_FORMAT;
/// Value of the `format_version` field; bumped on any incompatible change.
pub const FORMAT_VERSION: u32 = v1::IOSS_FORMAT_VERSION;
/// The pass/fail rule of the LMI (2) check (recorded in the JSON; `lti_model::ioss` module doc).
pub const TOLERANCE_RULE: &str = "pass iff lambda_min(P) > p_min_ratio * lambda_max(P) and \
    lmi_relative_violation = max_v v'Jv / v'Sv <= lmi_relative_tolerance, with J the LMI (2) matrix \
    G'PG - diag(eta P, Q) - H'RH and S = G'PG + diag(P, Q) + H'RH, G = [A Bbar], H = [C Dbar]; \
    then P satisfies LMI (2) exactly for eta' = (eta + tol)/(1 - tol) and (Q, R)(1 + tol)/(1 - tol)";

/// What to certify.
#[derive(Debug, Clone)]
pub struct CertifyRequest {
    /// Scenario file.
    pub scenario: PathBuf,
    /// Overrides `mhe.eta`.
    pub eta: Option<f64>,
    /// A user-supplied P to verify instead of computing one (overrides `mhe.p`).
    pub p_file: Option<PathBuf>,
    /// `--loop`: also K_lin, Theorem 1's K_min and the global loop certificate per method.
    pub loop_methods: bool,
    /// `--global-seconds`: the budget of the global φ* searches (default
    /// `certificate.phase_seconds`).
    pub global_seconds: Option<f64>,
}

/// Result of [`certify`]: the library's outcome, its JSON document and its text summary.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// JSON document.
    pub document: v1::IossCertificate,
    /// The library's typed outcome the document was written from (read by the tests; the
    /// command prints the summary and writes the document).
    #[cfg_attr(not(test), allow(dead_code))]
    pub check: IossOutcome,
    /// Human-readable summary, several lines, ending in PASS or FAIL.
    pub summary: String,
}

/// Reads a P matrix from JSON: a bare array of rows, an object with a `p` field, or a
/// certificate written by this tool (`certificate.p`).
pub fn read_p_file(path: &Path) -> Result<Mat<f64>> {
    let text = lti_model::spec::format::read_limited(path)
        .map_err(|e| anyhow!("{e}"))
        .with_context(|| format!("cannot read --p-file `{}`", path.display()))?;
    // A byte-order mark is accepted, as in a TOML scenario.
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let value: serde_json::Value = serde_json::from_str(text)
        .with_context(|| format!("--p-file `{}` is not valid JSON", path.display()))?;
    parse_p(&value).with_context(|| format!("--p-file `{}`", path.display()))
}

/// See [`read_p_file`].
pub fn parse_p(value: &serde_json::Value) -> Result<Mat<f64>> {
    use serde_json::Value;
    let rows_value = match value {
        Value::Array(_) => value,
        Value::Object(o) => o
            .get("p")
            .or_else(|| o.get("certificate").and_then(|c| c.get("p")))
            .filter(|v| !v.is_null())
            .ok_or_else(|| {
                anyhow!(
                    "no P found: expected an array of rows, an object with a `p` field, or a \
                     certificate JSON with `certificate.p` (a failed run has `certificate: null`)"
                )
            })?,
        _ => bail!("expected an array of rows or an object with a `p` field"),
    };
    let rows: Vec<Vec<f64>> = serde_json::from_value(rows_value.clone())
        .context("P must be an array of rows of numbers, e.g. [[2.0, 0.1], [0.1, 1.0]]")?;
    check_p_rows(&rows)?;
    matrix::from_rows("P", &rows).map_err(|e| anyhow!("{e}"))
}

/// Every row of P as long as the first (a short row is named; the shape against n_x is
/// checked later) and every entry
/// within ±[`MAX_MAGNITUDE`](lti_model::spec::format::MAX_MAGNITUDE), the scenario's limit
/// (a larger one makes the eigenvalue solver fail without saying why).
fn check_p_rows(rows: &[Vec<f64>]) -> Result<()> {
    let n = rows.len();
    if n == 0 {
        bail!("P has no rows; give the n_x × n_x matrix as an array of rows");
    }
    let width = rows[0].len();
    for (i, row) in rows.iter().enumerate() {
        if row.len() != width {
            bail!(
                "row {i} of P has {} entries, but row 0 has {width}; every row of P needs \
                 the same number of entries (P is n_x × n_x); complete the row",
                row.len()
            );
        }
        for (j, &x) in row.iter().enumerate() {
            lti_model::spec::format::check_magnitude("P", &format!("entry ({i}, {j})"), x)
                .map_err(|e| match e {
                    lti_model::ModelError::Scenario { problem, .. } => {
                        anyhow!("P {problem}")
                    }
                    other => anyhow!(other),
                })?;
        }
    }
    Ok(())
}

/// Runs the certificate for a scenario. Input problems (unreadable or invalid scenario,
/// bad η, malformed P) are errors; an LMI that fails is an [`Outcome`] with
/// `passed = false`.
pub fn certify(req: &CertifyRequest) -> Result<Outcome> {
    let scenario = Scenario::from_file(&req.scenario)
        .map_err(|e| anyhow!("{e}"))
        .with_context(|| format!("invalid scenario `{}`", req.scenario.display()))?;
    let p = match &req.p_file {
        Some(path) => Some(SuppliedP {
            p: read_p_file(path)?,
            source: format!("--p-file {}", path.display()),
        }),
        None => None,
    };
    // Checked before anything large is computed.
    let global_seconds = loop_methods::global_budget(&scenario, req.global_seconds)?;
    let request = IossRequest { eta: req.eta, p };
    let check =
        mhe_report::ioss::ioss_certificate(&scenario, &request).map_err(|e| input_error(e, req))?;
    let loop_section = if req.loop_methods {
        Some(loop_methods::loop_section(&scenario, global_seconds)?)
    } else {
        None
    };
    let mut document = document(req, &scenario, &check);
    document.loop_methods = loop_section.as_ref().map(v1::LoopSection::from);
    let summary = summarize(&document, &check, loop_section.as_ref());
    Ok(Outcome {
        document,
        check,
        summary,
    })
}

/// The library's input error in the command's words (its flags, the scenario's path).
fn input_error(e: IossError, req: &CertifyRequest) -> anyhow::Error {
    match e {
        IossError::NoEta => anyhow!(
            "scenario `{}` has no [mhe] section, so η is unknown: add [mhe] with eta (and q, r), \
             or pass --eta (Q and R are then identity)",
            req.scenario.display()
        ),
        IossError::EtaOutOfRange { eta, origin } => anyhow!(
            "η = {eta} ({}) is out of range: LMI (2) needs η ∈ [0, 1)",
            eta_source(origin)
        ),
        IossError::Check(inner) => anyhow!("{inner}").context("cannot check LMI (2)"),
        IossError::Lipschitz(inner) => {
            anyhow!("{inner}").context("cannot compute L_π for the scenario's [mpc] section")
        }
        other => anyhow!("{other}"),
    }
}

/// Where η came from, as the JSON and the summary name it.
fn eta_source(s: EtaSource) -> &'static str {
    match s {
        EtaSource::Scenario => "scenario mhe.eta",
        _ => "--eta",
    }
}

/// What to do after a failure, with the command's flags and the scenario's keys.
fn hint_text(h: &IossHint) -> String {
    match h {
        IossHint::OmitSuppliedP => {
            "omit --p-file (and mhe.p) to let certify compute the maximal P for this η".into()
        }
        IossHint::SupplyP => "compute P elsewhere (e.g. an SDP solver) and supply it as the \
             scenario key `mhe.p` or with `--p-file P.json`; certify then verifies it against \
             LMI (2)"
            .into(),
        IossHint::RaiseEta { eta_min } => format!(
            "the smallest feasible η for these Q, R is ≈ {} (bisection to \
             {ETA_HINT_RESOLUTION:e}); pass --eta or set mhe.eta at or above it",
            num(*eta_min)
        ),
        IossHint::NoFeasibleEta { error } => {
            format!("no η ∈ [0, 1) is feasible for these Q, R: {error}")
        }
        other => format!("{other:?}"),
    }
}

/// The JSON document of `check` (`certificate_json::v1::IossCertificate`).
fn document(req: &CertifyRequest, scenario: &Scenario, check: &IossOutcome) -> v1::IossCertificate {
    let rows = |m: faer::MatRef<'_, f64>| -> Vec<Vec<Option<f64>>> {
        (matrix::to_rows(m).into_iter())
            .map(|r| r.into_iter().map(v1::num).collect())
            .collect()
    };
    v1::IossCertificate {
        format: FORMAT.to_string(),
        format_version: FORMAT_VERSION,
        passed: check.passed,
        failure: check.failure.as_ref().map(ToString::to_string),
        hint: check.hint.as_ref().map(hint_text),
        scenario: v1::IossScenario {
            name: scenario.name.clone(),
            // Relative to the workspace when inside it, so files do not record machine paths.
            path: (req.scenario)
                .strip_prefix(crate::provenance::workspace_root())
                .unwrap_or(&req.scenario)
                .display()
                .to_string(),
        },
        provenance: v1::Provenance::from(&Provenance::collect()),
        system: v1::IossSystem::from(&scenario.plant),
        inputs: v1::IossInputs {
            eta: v1::num(check.eta),
            eta_source: eta_source(check.eta_source).to_string(),
            q: rows(check.q.as_ref()),
            r: rows(check.r.as_ref()),
            weights_source: match check.weights_source {
                WeightsSource::Scenario => "scenario mhe.q, mhe.r",
                _ => "identity (no [mhe] section)",
            }
            .to_string(),
            p_source: (check.p_source.clone()).unwrap_or_else(|| "computed".to_string()),
        },
        certificate: check.certificate.as_ref().map(v1::IossReport::from),
        tolerance_rule: TOLERANCE_RULE.to_string(),
        controller_lipschitz: (check.controller_lipschitz.as_ref()).map(v1::LipschitzReport::from),
        controller_lipschitz_skipped: (check.controller_lipschitz_skipped.as_ref())
            .map(ToString::to_string),
        closed_loop: check.closed_loop.as_ref().map(v1::Coverage::from),
        loop_methods: None,
    }
}

/// Writes the document as pretty JSON, creating parent directories.
pub fn write_json(doc: &v1::IossCertificate, path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create directory `{}`", dir.display()))?;
    }
    let text = serde_json::to_string_pretty(doc).context("cannot serialise the certificate")?;
    crate::output::write_atomic(path, (text + "\n").as_bytes())
}

#[cfg(test)]
#[path = "certify_tests.rs"]
mod tests;

// The terminal summary: certify/summary.rs; `--loop`'s section: certify/loop_methods.rs.
pub mod loop_methods;
mod summary;
use summary::summarize;
