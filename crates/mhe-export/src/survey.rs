//! Which methods an export can certify, and what each costs on the targets, without writing
//! an artefact: per method the smallest K the one verdict certifies in f64 and in f32 (what
//! `--k certified` exports) and the sample-period budget there. `scripts/cortex-m.sh table`
//! picks docs/embedded.md's rows from it (`cargo xtask export --survey`). Also the export's
//! size limit, checked before any certificate (a window of thousands of unknowns would take
//! minutes to certify and hundreds of MB of C source to write).

use closed_loop::scenario::{ControllerChoice, ResolvedScenario, Scenario};
use iss_certificate::certificate::certify_closed_loop;
use iss_certificate::coverage::{Configuration, PairReason, verdict, verdict_options};
use qp_iter::Method;
use serde::Serialize;

use crate::budget::TargetRecord;
use crate::{ExportError, ExportOptions, ScalarKind, coverage_scalar, scalar_name};

/// The largest problem data an export writes: 16 MiB of numbers in the export's scalar
/// (8× the flash of the largest target, an STM32H7's 2 MiB; the C source is ≈ 2.5× the
/// bytes). Checked on the scenario's dimensions before the certificate.
pub const MAX_DATA_BYTES: usize = 1 << 24;

/// The bytes of the numbers an export of `method` in `scalar` stores at most: per window
/// m = 0…M (n = n_x + m·n_w unknowns, n_θ = n_x + m(n_u + n_y)) F (n·n_θ) and the dense H
/// (n²), and for ADMM its two stored inverses (2n² more). PG and FISTA past the std
/// crossover store the structured product's factors instead of H: less than this bound.
pub fn data_bytes(scenario: &Scenario, method: Method, scalar: ScalarKind) -> usize {
    let Some(mhe) = scenario.mhe.as_ref() else {
        return 0;
    };
    let p = &scenario.plant;
    let squares = if method.name().starts_with("admm") {
        3
    } else {
        1
    };
    let numbers = (0..=mhe.horizon()).fold(0usize, |acc, m| {
        let d = mhe_budget::StepDims::of(p.nx(), p.nu(), p.ny(), p.nw(), m);
        acc.saturating_add(d.n.saturating_mul(d.n_theta + squares * d.n))
    });
    let bytes = match scalar {
        ScalarKind::F64 => 8,
        ScalarKind::F32 => 4,
    };
    numbers.saturating_mul(bytes)
}

/// [`data_bytes`] ≤ [`MAX_DATA_BYTES`], before any work.
///
/// # Errors
/// [`ExportError::Scenario`] naming `mhe.horizon`, the size and the fix.
pub(crate) fn check_size(
    scenario: &Scenario,
    method: Method,
    scalar: ScalarKind,
) -> Result<(), ExportError> {
    let bytes = data_bytes(scenario, method, scalar);
    if bytes <= MAX_DATA_BYTES {
        return Ok(());
    }
    let p = &scenario.plant;
    let horizon = scenario.mhe.as_ref().map_or(0, |m| m.horizon());
    let n = p.nx() + horizon * p.nw();
    Err(ExportError::Scenario {
        message: format!(
            "`mhe.horizon` = {horizon}: the export of {} in {} would store up to ≈ {:.0} MiB of \
             problem data (the dense bound; windows up to n_z = {n} unknowns), above the \
             export's limit of {} MiB \
             (no microcontroller holds it, and the certificate of such a window takes minutes): \
             lower mhe.horizon or the plant's size{}",
            method.name(),
            scalar_name(scalar),
            bytes as f64 / f64::from(1u32 << 20),
            MAX_DATA_BYTES >> 20,
            if method.name().starts_with("admm") {
                ", or export pg or fista (no stored inverses)"
            } else {
                ""
            }
        ),
    })
}

/// One method's survey: its certified K and budget per scalar.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct MethodSurvey {
    /// The method's name (`--method`).
    pub method: String,
    /// In f64.
    pub f64: ScalarSurvey,
    /// In f32.
    pub f32: ScalarSurvey,
}

/// A method's certified K in one scalar, and the budget there.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct ScalarSurvey {
    /// `f64` or `f32`.
    pub scalar: &'static str,
    /// The smallest K the one verdict certifies (what `--k certified` exports; null: none).
    pub k: Option<usize>,
    /// The verdict (at `k`, or at K = 1 without one): `yes`, `no`, `void`,
    /// `not_computed`, or `refused` (the export's size limit, before any certificate).
    pub verdict: &'static str,
    /// The certificate that certifies `k` (`theorem1`, `global`; null without `k`).
    pub certificate: Option<&'static str>,
    /// Why no K is certified: the short name of the reason (null when certified).
    pub short_reason: Option<String>,
    /// The whole reason, as `export`'s certificate.json says it (null when certified).
    pub reason: Option<String>,
    /// The sample-period budget per target at `k` (empty without `k`).
    pub budget: Vec<TargetRecord>,
}

impl ScalarSurvey {
    fn refused(scalar: ScalarKind, e: &ExportError) -> Self {
        Self {
            scalar: scalar_name(scalar),
            k: None,
            verdict: "refused",
            certificate: None,
            short_reason: Some("the export's size limit".into()),
            reason: Some(e.to_string()),
            budget: Vec::new(),
        }
    }
}

/// Per method of `methods` (all of [`Method::ALL`] when empty): the smallest K the one
/// verdict (`iss_certificate::coverage::verdict`, the exact MPC as `export` asks it)
/// certifies in f64 and in f32, and the budget of `options`' targets there. The
/// closed-loop certificate is computed once, for every method the size limit lets through.
///
/// # Errors
/// [`ExportError::InvalidOption`] / [`ExportError::Scenario`] (no `[mhe]`) before any work,
/// [`ExportError::Certificate`].
pub fn survey(
    resolved: &ResolvedScenario,
    options: &ExportOptions,
    methods: &[Method],
) -> Result<Vec<MethodSurvey>, ExportError> {
    options.validate()?;
    let scenario = resolved.scenario();
    let mhe = scenario.mhe.as_ref().ok_or_else(|| ExportError::Scenario {
        message: "the scenario has no [mhe] section: nothing to export".into(),
    })?;
    let methods = if methods.is_empty() {
        Method::ALL.to_vec()
    } else {
        methods.to_vec()
    };
    let scalars = [ScalarKind::F64, ScalarKind::F32];
    let admitted: Vec<Method> = (methods.iter().copied())
        .filter(|&m| scalars.iter().any(|&s| check_size(scenario, m, s).is_ok()))
        .collect();
    let cert = if admitted.is_empty() {
        None
    } else {
        let opts = verdict_options(scenario, admitted, None);
        Some(
            certify_closed_loop(resolved, &opts)
                .map_err(|e| ExportError::certificate(&anyhow::Error::new(e)))?,
        )
    };
    let dims = crate::budget::dims(scenario, mhe.horizon());
    let one = |method: Method, scalar: ScalarKind| -> Result<ScalarSurvey, ExportError> {
        if let Err(e) = check_size(scenario, method, scalar) {
            return Ok(ScalarSurvey::refused(scalar, &e));
        }
        let cert = cert.as_ref().ok_or_else(|| ExportError::Certificate {
            message: "no certificate computed".into(),
        })?;
        let config = |k_e| Configuration {
            method,
            k_e,
            controller: ControllerChoice::ExactMpc,
            scalar: coverage_scalar(scalar),
        };
        let probe = verdict(resolved, cert, &config(1));
        let k = if probe.certified.is_certified() {
            Some(1)
        } else {
            probe.k_min
        };
        let v = k.map_or(probe, |k| verdict(resolved, cert, &config(k)));
        let certified = v.certified.is_certified();
        let k = k.filter(|_| certified);
        let budget = match k {
            Some(k) => {
                let step = mhe_budget::Step {
                    method: &method.name(),
                    dims,
                    k,
                };
                let s = match scalar {
                    ScalarKind::F64 => mhe_budget::Scalar::F64,
                    ScalarKind::F32 => mhe_budget::Scalar::F32,
                };
                crate::budget::budgets(&options.targets(), s, step, None, scenario.sample_time)?
                    .iter()
                    .map(TargetRecord::from)
                    .collect()
            }
            None => Vec::new(),
        };
        Ok(ScalarSurvey {
            scalar: scalar_name(scalar),
            k,
            verdict: v.certified.as_str(),
            certificate: v.certificate.filter(|_| certified).map(|c| c.name()),
            short_reason: (!certified).then(|| {
                v.reason
                    .as_ref()
                    .map_or_else(|| "too few iterations".into(), short_reason)
            }),
            reason: (!certified).then(|| v.reason_text()),
            budget,
        })
    };
    methods
        .iter()
        .map(|&m| {
            Ok(MethodSurvey {
                method: m.name().into_owned(),
                f64: one(m, ScalarKind::F64)?,
                f32: one(m, ScalarKind::F32)?,
            })
        })
        .collect()
}

/// The named reason of a verdict, in a few words (the whole sentence stays in the export's
/// certificate.json): what a table cell can hold ([`PairReason::short`]).
pub fn short_reason(r: &PairReason) -> String {
    r.short()
}
