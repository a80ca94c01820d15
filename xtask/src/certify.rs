//! `cargo xtask certify`: the δ-IOSS certificate (Assumption 2, LMI (2)) of a scenario,
//! as a short text summary and a self-contained JSON document (docs/certificate-json.md).
//!
//! The JSON carries A, C, B̄, D̄, η, Q, R and P, so any tool can rebuild the LMI matrix and
//! check its eigenvalues without this code.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use closed_loop::scenario::Scenario;
use faer::Mat;
use lti_model::ioss::{self, IossOptions, IossReport};
use lti_model::{LtiSystem, ModelError, matrix};
use serde::Serialize;

use crate::provenance::Provenance;
use crate::reproduce::numfmt::num;

/// Value of the `format` field.
pub const FORMAT: &str = certificate_json::v1::IOSS_FORMAT;
/// Value of the `format_version` field; bumped on any incompatible change.
pub const FORMAT_VERSION: u32 = certificate_json::v1::IOSS_FORMAT_VERSION;
/// Seeded random pairs for the sampled L_π estimate.
pub const LPI_SAMPLE_PAIRS: usize = 200;
/// The pass/fail rule of the LMI (2) check (recorded in the JSON; `lti_model::ioss` module doc).
pub const TOLERANCE_RULE: &str = "pass iff lambda_min(P) > p_min_ratio * lambda_max(P) and \
    lmi_relative_violation = max_v v'Jv / v'Sv <= lmi_relative_tolerance, with J the LMI (2) matrix \
    G'PG - diag(eta P, Q) - H'RH and S = G'PG + diag(P, Q) + H'RH, G = [A Bbar], H = [C Dbar]; \
    then P satisfies LMI (2) exactly for eta' = (eta + tol)/(1 - tol) and (Q, R)(1 + tol)/(1 - tol)";
/// Resolution of the η bisection run to suggest a feasible η after a failure.
const ETA_HINT_RESOLUTION: f64 = 1e-4;

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

/// The scenario the certificate is for.
#[derive(Debug, Clone)]
pub struct ScenarioInfo {
    /// `name` of the scenario.
    pub name: String,
    /// Path the scenario was read from, as given.
    pub path: String,
}

/// The plant's dimensions, written as flat fields `nx`, `nu`, `ny`, `nw1`, `nw2` into both
/// JSON documents (certificate and reproduce).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PlantDims {
    /// n_x.
    pub nx: usize,
    /// n_u.
    pub nu: usize,
    /// n_y.
    pub ny: usize,
    /// n_w1 (entries of w¹).
    pub nw1: usize,
    /// n_w2 (entries of w²).
    pub nw2: usize,
}

impl PlantDims {
    /// The dimensions of `sys`.
    pub fn of(sys: &lti_model::LtiSystem) -> Self {
        Self {
            nx: sys.nx(),
            nu: sys.nu(),
            ny: sys.ny(),
            nw1: sys.nw1(),
            nw2: sys.nw2(),
        }
    }
}

/// The plant data that enters LMI (2).
#[derive(Debug, Clone)]
pub struct SystemInfo {
    /// n_x, n_u, n_y, n_w1, n_w2.
    pub dims: PlantDims,
    /// A (n_x × n_x).
    pub a: Vec<Vec<f64>>,
    /// C (n_y × n_x).
    pub c: Vec<Vec<f64>>,
    /// B̄ = [E, 0] (n_x × n_w).
    pub b_bar: Vec<Vec<f64>>,
    /// D̄ = [0, F] (n_y × n_w).
    pub d_bar: Vec<Vec<f64>>,
}

/// The parameters of LMI (2) and where each came from.
#[derive(Debug, Clone)]
pub struct Inputs {
    /// η.
    pub eta: f64,
    /// `"scenario mhe.eta"` or `"--eta"`.
    pub eta_source: String,
    /// Q (n_w × n_w).
    pub q: Vec<Vec<f64>>,
    /// R (n_y × n_y).
    pub r: Vec<Vec<f64>>,
    /// `"scenario mhe.q, mhe.r"` or `"identity (no [mhe] section)"`.
    pub weights_source: String,
    /// `"computed"`, `"scenario mhe.p"` or `"--p-file <path>"`.
    pub p_source: String,
}

/// The JSON document `certify` writes (docs/certificate-json.md).
#[derive(Debug, Clone)]
pub struct CertificateDocument {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`FORMAT_VERSION`].
    pub format_version: u32,
    /// True iff P ≻ 0 and λ_max(LMI matrix) ≤ tolerance.
    pub passed: bool,
    /// Why the check failed (`null` when passed).
    pub failure: Option<String>,
    /// A suggestion after a failure (e.g. the smallest feasible η), else `null`.
    pub hint: Option<String>,
    /// Scenario name and path.
    pub scenario: ScenarioInfo,
    /// Git revision, tool version, compiler, time.
    pub provenance: Provenance,
    /// A, C, B̄, D̄ and the dimensions.
    pub system: SystemInfo,
    /// η, Q, R and their sources.
    pub inputs: Inputs,
    /// P and the LMI check; `null` if no P exists (LMI infeasible).
    pub certificate: Option<IossReport>,
    /// Always [`TOLERANCE_RULE`].
    pub tolerance_rule: String,
    /// L_π of the scenario's MPC (Assumption 3): certified bounds and a sampled estimate;
    /// `null` when the scenario has no [mpc] section or the MPC it describes is not
    /// supported (then `controller_lipschitz_skipped` says why). Not part of the LMI
    /// pass/fail.
    pub controller_lipschitz: Option<mpc_core::LipschitzReport>,
    /// Why L_π was not computed although the scenario has an [mpc] section (e.g. state
    /// constraints in the MPC); `null` otherwise. A part of the scenario the LMI does not
    /// need never blocks its check.
    pub controller_lipschitz_skipped: Option<String>,
    /// Which closed-loop certificate covers the scenario's configuration (its method, warm
    /// start and controller: `iss_certificate::coverage::covering`, the decision `reproduce`,
    /// `sweep` and `export` make), or why none does; `null` without [mhe]. `certify` checks
    /// LMI (2) only: the verdict at K is `reproduce`'s.
    pub closed_loop: Option<iss_certificate::coverage::Coverage>,
    /// `--loop`: per method K_lin, Theorem 1's K_min and K_glob; `None` without it.
    pub loop_methods: Option<loop_methods::LoopSection>,
}

/// Result of [`certify`]: the document and its text summary.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// JSON document.
    pub document: CertificateDocument,
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

/// The LMI check of a P that [`ioss::verify`] rejected, so a failure can still be reported
/// with its eigenvalues and relative violation. P must be n_x × n_x, finite and symmetric.
fn failed_report(
    sys: &LtiSystem,
    eta: f64,
    q: &Mat<f64>,
    r: &Mat<f64>,
    p: &Mat<f64>,
) -> Result<IossReport> {
    let p = matrix::symmetrize(p.as_ref());
    let check = ioss::assess(
        sys,
        eta,
        q.as_ref(),
        r.as_ref(),
        p.as_ref(),
        &IossOptions::default(),
    )?;
    Ok(IossReport::from_check(
        p.as_ref(),
        eta,
        q.as_ref(),
        r.as_ref(),
        &check,
        ioss::METHOD_USER,
        0,
    ))
}

/// Runs the certificate for a scenario. Input problems (unreadable or invalid scenario,
/// bad η, malformed P) are errors; an LMI that fails is an [`Outcome`] with
/// `passed = false`.
pub fn certify(req: &CertifyRequest) -> Result<Outcome> {
    let scenario = Scenario::from_file(&req.scenario)
        .map_err(|e| anyhow!("{e}"))
        .with_context(|| format!("invalid scenario `{}`", req.scenario.display()))?;
    let sys = &scenario.plant;
    let inputs = lmi_inputs(req, &scenario)?;
    // Checked before anything large is computed.
    let global_seconds = loop_methods::global_budget(&scenario, req.global_seconds)?;
    let mut lmi = lmi_verdict(sys, &inputs)?;
    let hint = hint(sys, &inputs, &mut lmi);
    let (controller_lipschitz, controller_lipschitz_skipped) = controller_lipschitz(&scenario)?;
    let LmiInputs {
        eta,
        eta_source,
        q,
        r,
        weights_source,
        user_p,
    } = inputs;
    let LmiVerdict {
        passed,
        failure,
        certificate,
        ..
    } = lmi;
    let closed_loop = closed_loop::scenario::LoopOptions::from_scenario(&scenario)
        .ok()
        .map(|o| iss_certificate::coverage::covering(&scenario, o.method, o.controller));
    let loop_methods = if req.loop_methods {
        Some(loop_methods::loop_section(&scenario, global_seconds)?)
    } else {
        None
    };
    let document = CertificateDocument {
        format: FORMAT.to_string(),
        format_version: FORMAT_VERSION,
        passed,
        failure,
        hint,
        scenario: ScenarioInfo {
            name: scenario.name.clone(),
            // Relative to the workspace when inside it, so files do not record machine paths.
            path: req
                .scenario
                .strip_prefix(crate::provenance::workspace_root())
                .unwrap_or(&req.scenario)
                .display()
                .to_string(),
        },
        provenance: Provenance::collect(),
        system: SystemInfo {
            dims: PlantDims::of(sys),
            a: matrix::to_rows(sys.a()),
            c: matrix::to_rows(sys.c()),
            b_bar: matrix::to_rows(sys.b_bar().as_ref()),
            d_bar: matrix::to_rows(sys.d_bar().as_ref()),
        },
        inputs: Inputs {
            eta,
            eta_source,
            q: matrix::to_rows(q.as_ref()),
            r: matrix::to_rows(r.as_ref()),
            weights_source: weights_source.to_string(),
            p_source: user_p.map_or_else(|| "computed".to_string(), |(_, s)| s),
        },
        certificate,
        tolerance_rule: TOLERANCE_RULE.to_string(),
        controller_lipschitz,
        controller_lipschitz_skipped,
        closed_loop,
        loop_methods,
    };
    let summary = summarize(&document);
    Ok(Outcome { document, summary })
}

/// η, Q, R and the user's P (with where each came from) of LMI (2), checked.
struct LmiInputs {
    eta: f64,
    eta_source: String,
    q: Mat<f64>,
    r: Mat<f64>,
    weights_source: &'static str,
    /// P from `--p-file` or `mhe.p`, and which.
    user_p: Option<(Mat<f64>, String)>,
}

/// η from `--eta` or `mhe.eta`, Q and R from `[mhe]` (identity without it), P from
/// `--p-file` or `mhe.p`; bad input (no η, η ∉ [0, 1), P of the wrong size or not
/// symmetric) is an error naming its source.
fn lmi_inputs(req: &CertifyRequest, scenario: &Scenario) -> Result<LmiInputs> {
    let sys = &scenario.plant;
    let mhe = scenario.mhe.as_ref();
    let (eta, eta_source) = match (req.eta, mhe) {
        (Some(eta), _) => (eta, "--eta".to_string()),
        (None, Some(m)) => (m.eta(), "scenario mhe.eta".to_string()),
        (None, None) => bail!(
            "scenario `{}` has no [mhe] section, so η is unknown: add [mhe] with eta (and q, r), \
             or pass --eta (Q and R are then identity)",
            req.scenario.display()
        ),
    };
    if !(eta.is_finite() && (0.0..1.0).contains(&eta)) {
        bail!("η = {eta} ({eta_source}) is out of range: LMI (2) needs η ∈ [0, 1)");
    }
    let (q, r, weights_source) = match mhe {
        Some(m) => (m.q().clone(), m.r().clone(), "scenario mhe.q, mhe.r"),
        None => (
            Mat::identity(sys.nw(), sys.nw()),
            Mat::identity(sys.ny(), sys.ny()),
            "identity (no [mhe] section)",
        ),
    };
    let user_p = match (&req.p_file, mhe.and_then(|m| m.p())) {
        (Some(path), _) => Some((read_p_file(path)?, format!("--p-file {}", path.display()))),
        (None, Some(p)) => Some((p.clone(), "scenario mhe.p".to_string())),
        (None, None) => None,
    };
    if let Some((p, source)) = &user_p {
        if p.nrows() != sys.nx() || p.ncols() != sys.nx() {
            bail!(
                "P from {source} is {}×{}, but the plant has n_x = {} (P must be {}×{})",
                p.nrows(),
                p.ncols(),
                sys.nx(),
                sys.nx(),
                sys.nx()
            );
        }
        let asym = matrix::asymmetry(p.as_ref());
        if asym > matrix::SYMMETRY_TOL * p.norm_max().max(1.0) {
            bail!(
                "P from {source} is not symmetric (max |P - Pᵀ| = {asym:e}); supply a symmetric P"
            );
        }
    }
    Ok(LmiInputs {
        eta,
        eta_source,
        q,
        r,
        weights_source,
        user_p,
    })
}

/// LMI (2)'s one verdict: passed, the failure, the report, and the η bisection when it ran.
struct LmiVerdict {
    passed: bool,
    failure: Option<String>,
    certificate: Option<IossReport>,
    bisection: Option<lti_model::Result<ioss::EtaBisection>>,
}

/// LMI (2) at η: the user's P verified, or P computed; a construction that fails at η but
/// finds a P at a smaller η is verified at η (feasibility is monotone in η).
fn lmi_verdict(sys: &LtiSystem, inputs: &LmiInputs) -> Result<LmiVerdict> {
    let LmiInputs {
        eta, q, r, user_p, ..
    } = inputs;
    let eta = *eta;
    let result = match &user_p {
        Some((p, _)) => ioss::verify(sys, eta, q.as_ref(), r.as_ref(), p.as_ref()),
        None => ioss::certify(sys, eta, q.as_ref(), r.as_ref()),
    };
    // One verdict (issue 37 item 4): feasibility is monotone in η (−η'P ⪯ −ηP for η' > η), so
    // when the construction at η fails but the bisection finds a P at some η_min ≤ η, that
    // P — verified at η itself — is the certificate, and "infeasible" is never printed beside
    // "the smallest feasible η is below yours".
    let mut bisection = None;
    let result = match result {
        Err(ModelError::LmiInfeasible { cause }) if user_p.is_none() => {
            let b = ioss::min_feasible_eta(sys, q.as_ref(), r.as_ref(), ETA_HINT_RESOLUTION);
            let at_eta = match &b {
                Ok(b) if b.certificate.eta <= eta => {
                    ioss::verify(sys, eta, q.as_ref(), r.as_ref(), b.certificate.p.as_ref())
                        .ok()
                        .map(|mut c| {
                            c.method =
                                format!("{} at η = {}", b.certificate.method, b.certificate.eta);
                            c
                        })
                }
                _ => None,
            };
            bisection = Some(b);
            at_eta.ok_or(ModelError::LmiInfeasible { cause })
        }
        other => other,
    };
    let (passed, failure, certificate) = match result {
        Ok(cert) => (true, None, Some(cert.report())),
        Err(ModelError::LmiInfeasible { cause }) => match &user_p {
            Some((p, source)) => (
                false,
                Some(format!("{cause} (P from {source})")),
                Some(failed_report(sys, eta, q, r, p)?),
            ),
            None => (false, Some(format!("LMI (2) infeasible: {cause}")), None),
        },
        // The construction itself failed (no convergence, singular KKT system): a FAIL with
        // the way to supply P, not an input error.
        Err(e @ ModelError::Numerical { .. }) if user_p.is_none() => {
            (false, Some(format!("no P computed: {e}")), None)
        }
        Err(ModelError::NotPositiveDefinite {
            name,
            min_eigenvalue,
        }) if user_p.is_some() && name == "P" => {
            let report = user_p
                .as_ref()
                .map(|(p, _)| failed_report(sys, eta, q, r, p))
                .transpose()?;
            (
                false,
                Some(format!(
                    "the P from {} is not positive definite (λ_min(P) = {min_eigenvalue:e})",
                    user_p.as_ref().map_or("", |(_, s)| s.as_str())
                )),
                report,
            )
        }
        Err(other) => return Err(anyhow!("{other}")).context("cannot check LMI (2)"),
    };
    Ok(LmiVerdict {
        passed,
        failure,
        certificate,
        bisection,
    })
}

/// What to do when LMI (2) fails: drop the user's P, supply one, or raise η to the smallest
/// feasible one (None when it passed).
fn hint(sys: &LtiSystem, inputs: &LmiInputs, lmi: &mut LmiVerdict) -> Option<String> {
    let (q, r, user_p) = (&inputs.q, &inputs.r, &inputs.user_p);
    if lmi.passed {
        None
    } else if user_p.is_some() {
        Some(
            "omit --p-file (and mhe.p) to let certify compute the maximal P for this η".to_string(),
        )
    } else if lmi.certificate.is_none()
        && lmi
            .failure
            .as_deref()
            .is_some_and(|f| f.starts_with("no P"))
    {
        Some(
            "compute P elsewhere (e.g. an SDP solver) and supply it as the scenario key `mhe.p` \
             or with `--p-file P.json`; certify then verifies it against LMI (2)"
                .to_string(),
        )
    } else {
        Some(
            match lmi.bisection.take().unwrap_or_else(|| {
                ioss::min_feasible_eta(sys, q.as_ref(), r.as_ref(), ETA_HINT_RESOLUTION)
            }) {
                Ok(b) => format!(
                    "the smallest feasible η for these Q, R is ≈ {} (bisection to {ETA_HINT_RESOLUTION:e}); \
                 pass --eta or set mhe.eta at or above it",
                    num(b.certificate.eta)
                ),
                Err(e) => format!("no η ∈ [0, 1) is feasible for these Q, R: {e}"),
            },
        )
    }
}

/// L_π of the scenario's MPC, if it has one; an MPC the project cannot build (state
/// constraints) is skipped with the reason: the LMI check does not need it.
#[allow(clippy::type_complexity)]
fn controller_lipschitz(
    scenario: &Scenario,
) -> Result<(Option<mpc_core::LipschitzReport>, Option<String>)> {
    let sys = &scenario.plant;
    // L_π of the scenario's MPC, if it has one. An MPC the project cannot build (state
    // constraints) is reported as skipped with the reason: the LMI check does not need it.
    Ok(match &scenario.mpc {
        Some(m) => {
            match m.build(sys, &scenario.sets).and_then(|mpc| {
                mpc_core::lipschitz_report_for(
                    &mpc,
                    LPI_SAMPLE_PAIRS,
                    scenario.noise.seed,
                    scenario.sampling_radius(),
                )
            }) {
                Ok(report) => (Some(report), None),
                Err(e @ mpc_core::MpcError::Unsupported { .. }) => (None, Some(e.to_string())),
                Err(e) => {
                    return Err(anyhow!("{e}"))
                        .context("cannot compute L_π for the scenario's [mpc] section");
                }
            }
        }
        None => (None, None),
    })
}

/// Writes the document as pretty JSON, creating parent directories.
pub fn write_json(doc: &CertificateDocument, path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create directory `{}`", dir.display()))?;
    }
    let text = serde_json::to_string_pretty(&certificate_json::v1::IossCertificate::from(doc))
        .context("cannot serialise the certificate")?;
    crate::output::write_atomic(path, (text + "\n").as_bytes())
}

#[cfg(test)]
#[path = "certify_tests.rs"]
mod tests;

// The terminal summary: certify/summary.rs; the JSON document's records: certify/json.rs.
mod json;
pub mod loop_methods;
mod summary;
use summary::summarize;
