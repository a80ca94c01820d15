//! The sample period as a budget of an artefact: the verdict of [`mhe_budget::fits_loop`]
//! (computed there, only) for the exported loop — the MHE at K and, with the MPC, its K_c
//! iterations — in the artefact's README and certificate.json, and per method in
//! `reproduce`'s outputs (docs/embedded.md, "The sample period as a budget").

use std::path::Path;

use closed_loop::scenario::Scenario;
use mhe_budget::{Budget, BudgetError, Scalar, Step, StepDims, Target, Verdict};
use serde::Serialize;
use serde_json::json;

use crate::ExportError;

/// Both targets at their default clocks (an STM32F405 at 168 MHz, an STM32H7 at 480 MHz):
/// the targets of an export whose options give none.
pub fn default_targets() -> Vec<(Target, f64)> {
    Target::ALL.map(|t| (t, t.default_clock_mhz())).to_vec()
}

/// Each clock finite and > 0 (before any work).
///
/// # Errors
/// [`ExportError::InvalidOption`] (`budget_targets`, naming `--clock-mhz`).
pub fn check_targets(targets: &[(Target, f64)]) -> Result<(), ExportError> {
    for (_, c) in targets {
        mhe_budget::check_clock(*c).map_err(|e| option_error(&e))?;
    }
    Ok(())
}

fn option_error(e: &BudgetError) -> ExportError {
    ExportError::InvalidOption {
        option: "budget_targets",
        message: e.to_string(),
    }
}

/// The full window of the scenario's MHE at horizon M.
pub fn dims(scenario: &Scenario, horizon: usize) -> StepDims {
    let p = &scenario.plant;
    StepDims::of(p.nx(), p.nu(), p.ny(), p.nw(), horizon)
}

/// The budget per target of a loop step: the MHE (`mhe`) and, when given, the MPC (`mpc`),
/// from the model's rows of `scalar` (f32: its own calibration, the instructions of the f32
/// export; what the certificate says of f32 is [`f32_note`]).
///
/// # Errors
/// [`ExportError::InvalidOption`] for a bad clock, T_s, K = 0 or K_c = 0 (the message names
/// the key).
pub fn budgets(
    targets: &[(Target, f64)],
    scalar: Scalar,
    mhe: Step<'_>,
    mpc: Option<Step<'_>>,
    sample_time: Option<f64>,
) -> Result<Vec<Budget>, ExportError> {
    targets
        .iter()
        .map(|&(t, c)| {
            mhe_budget::fits_loop(t, c, scalar, mhe, mpc, sample_time).map_err(|e| option_error(&e))
        })
        .collect()
}

/// What an f32 export's budget says about its K (`certified`: the export's verdict, which
/// for f32 is Theorem 1 with the f32 rounding folded in or the global loop certificate in
/// f32: docs/embedded.md, "What the certificate covers"). The budget itself is a
/// measurement of the f32 code.
pub fn f32_note(certified: bool) -> &'static str {
    if certified {
        "f32: the instructions of the f32 export at this K, which the certificate covers in f32"
    } else {
        "f32: the instructions of the f32 export at this K; this K is NOT certified in f32 \
         (certificate.json `uncertified_reason`)"
    }
}

/// One target's verdict as written to certificate.json (export's `budget`, reproduce's
/// `budget.methods[].targets`).
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct TargetRecord {
    /// `cortex-m4f` or `cortex-m7`.
    pub target: String,
    /// The export's scalar (`f64`, `f32`): the model rows the figures come from.
    pub scalar: &'static str,
    /// f32: whether the certificate covers this K in f32 ([`f32_note`]); null for f64.
    pub scalar_note: Option<&'static str>,
    /// The clock.
    pub clock_mhz: f64,
    /// K.
    pub iterations: usize,
    /// With the MPC: its method (omitted without).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mpc_method: Option<String>,
    /// With the MPC: K_c (omitted without).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mpc_iterations: Option<usize>,
    /// With the MPC: the MPC's share of `instructions_per_step_bound` (omitted without).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mpc_instructions_bound: Option<f64>,
    /// The model's prediction of the max instructions per step (null: not calibrated).
    pub instructions_per_step: Option<f64>,
    /// The prediction raised by the model's worst relative error: what the verdict uses.
    pub instructions_per_step_bound: Option<f64>,
    /// µs per step at one instruction per cycle, from the bound.
    pub micros_per_step: Option<f64>,
    /// n_z (or the MPC's n) outside the calibrated sizes.
    pub extrapolated: bool,
    /// `fits`, `does_not_fit` or `not_computed`.
    pub fits_sample_time: &'static str,
    /// (T_s − t) / T_s when it fits.
    pub margin: Option<f64>,
    /// The largest K that fits T_s (with the MPC at its K_c; null: not even K = 1, or not
    /// computed).
    pub k_max_fitting: Option<usize>,
    /// Why not computed.
    pub reason: Option<String>,
    /// The verdict in one line.
    pub summary: String,
}

impl From<&Budget> for TargetRecord {
    fn from(b: &Budget) -> Self {
        let (fits_sample_time, k_max_fitting, margin, reason) = match &b.verdict {
            Verdict::Fits { margin, k_max } => ("fits", Some(*k_max), Some(*margin), None),
            Verdict::DoesNotFit { k_max } => ("does_not_fit", *k_max, None, None),
            Verdict::NotComputed { reason } => ("not_computed", None, None, Some(reason.clone())),
            // `Verdict` is `#[non_exhaustive]`: a verdict this file does not know yet.
            other => ("not_computed", None, None, Some(format!("{other:?}"))),
        };
        TargetRecord {
            target: b.target.name().into(),
            scalar: b.scalar.name(),
            scalar_note: None,
            clock_mhz: b.clock_mhz,
            iterations: b.k,
            mpc_method: b.mpc.as_ref().map(|m| m.method.clone()),
            mpc_iterations: b.mpc.as_ref().map(|m| m.k_c),
            mpc_instructions_bound: b
                .mpc
                .as_ref()
                .and_then(|m| m.instructions_upper)
                .map(f64::ceil),
            instructions_per_step: b.instructions.map(f64::ceil),
            instructions_per_step_bound: b.instructions_upper.map(f64::ceil),
            micros_per_step: b.micros,
            extrapolated: b.extrapolated,
            fits_sample_time,
            margin,
            k_max_fitting,
            reason,
            summary: b.summary(),
        }
    }
}

/// What every record counts (in certificate.json next to the records): the MHE step alone.
const UNIT: &str = "emulated instructions (qemu-system-arm -icount) of the MHE step (push + \
                    estimate, full window), one per cycle: not cycles; model \
                    crates/mhe-budget/data/cortex-m-model.csv";

/// The unit of a loop step's records (an export with the MPC).
const LOOP_UNIT: &str = "emulated instructions (qemu-system-arm -icount) of the loop step (push \
                         + estimate, full window, + the MPC's K_c-iteration control), one per \
                         cycle: not cycles; models crates/mhe-budget/data/cortex-m-model.csv \
                         (MHE) + cortex-m-mpc-model.csv (MPC)";

/// certificate.json's `budget` of an export.
/// `note`: an f32 export's [`f32_note`] (None for f64).
pub fn json(budgets: &[Budget], note: Option<&'static str>) -> serde_json::Value {
    let records: Vec<TargetRecord> = budgets
        .iter()
        .map(|b| TargetRecord {
            scalar_note: note.filter(|_| b.scalar == Scalar::F32),
            ..TargetRecord::from(b)
        })
        .collect();
    let unit = if budgets.iter().any(|b| b.mpc.is_some()) {
        LOOP_UNIT
    } else {
        UNIT
    };
    json!({
        "unit": unit,
        "targets": records,
    })
}

/// The README section.
pub fn readme(budgets: &[Budget], note: Option<&'static str>) -> String {
    let with_mpc = budgets.iter().find_map(|b| b.mpc.as_ref());
    let (what, mpc) = match with_mpc {
        None => (
            "Max instructions per MHE step (push + estimate, the full window)",
            " The MPC's K_c iterations are not in this figure.".to_string(),
        ),
        Some(m) => (
            "Max instructions per loop step (push + estimate on the full window, then the \
             MPC's control)",
            format!(
                " The MPC's K_c = {} iterations ({}) are in this figure, predicted by its own \
                 calibrated rows (the control part of the loop program, measured the same way) \
                 and raised by their own worst relative error.",
                m.k_c, m.method
            ),
        ),
    };
    let mut s = format!(
        "\n## The sample period as a budget\n\n\
         {what} predicted by the \
         calibrated model of `mhe_budget` (QEMU `-icount` measurements of every method, \
         docs/embedded.md), raised by the model's worst relative error; time at one \
         instruction per cycle (**instructions, not cycles**: flash wait states and \
         multi-cycle instructions add to it on a real board).{mpc}\n\n",
    );
    for b in budgets {
        s += &format!(
            "- {} at {} MHz, K = {}, {}: {}\n",
            b.target,
            b.clock_mhz,
            b.k,
            b.scalar.name(),
            b.summary()
        );
    }
    if let Some(note) = note.filter(|_| budgets.iter().any(|b| b.scalar == Scalar::F32)) {
        s += &format!("\n{note}.\n");
    }
    s
}

/// Adds the budget to an artefact written into `dir`: `budget` as the last key of
/// certificate.json (the other keys keep their order and bytes) and a README section.
pub(crate) fn annotate(
    dir: &Path,
    budgets: &[Budget],
    note: Option<&'static str>,
) -> anyhow::Result<()> {
    let cert = dir.join("certificate.json");
    let text = std::fs::read_to_string(&cert)?;
    let Some(body) = text.trim_end().strip_suffix('}') else {
        anyhow::bail!("{}: not a JSON object", cert.display());
    };
    let value = serde_json::to_string_pretty(&json(budgets, note))?.replace('\n', "\n  ");
    std::fs::write(
        &cert,
        format!("{},\n  \"budget\": {value}\n}}\n", body.trim_end()),
    )?;
    let readme = dir.join("README.md");
    let mut text = std::fs::read_to_string(&readme)?;
    text += &self::readme(budgets, note);
    std::fs::write(&readme, text)?;
    Ok(())
}

/// reproduce's `budget`: per method at its smallest certified K (the one verdict's: Theorem
/// 1's K_min, the global K_glob or the chain's K), both targets at their default clocks, for
/// a scenario with a sample period.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct ReproduceBudget {
    /// T_s in seconds (`plant.sample_time`).
    pub sample_time: f64,
    /// What the numbers count.
    pub unit: &'static str,
    /// Per method.
    pub methods: Vec<MethodBudget>,
}

/// One method's budget at its smallest certified K.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct MethodBudget {
    /// The method.
    pub method: String,
    /// Its smallest certified K (null: none, so no verdict).
    pub k: Option<usize>,
    /// Per target (empty without K_min).
    pub targets: Vec<TargetRecord>,
}

impl MethodBudget {
    /// `pg K = 243: cortex-m4f@168 …; cortex-m7@480 …`.
    pub fn line(&self) -> String {
        let Some(k) = self.k else {
            return format!("{:<14} no certified K: fits T_s not computed", self.method);
        };
        let per: Vec<String> = (self.targets.iter())
            .map(|t| format!("{}@{} MHz {}", short(&t.target), t.clock_mhz, t.summary))
            .collect();
        format!("{:<14} K = {k}: {}", self.method, per.join("; "))
    }
}

impl ReproduceBudget {
    /// The screen's one line: the simulated method's verdict.
    pub fn screen_line(&self, solver: &str) -> String {
        let own = self.methods.iter().find(|m| m.method == solver);
        format!(
            "T_s = {} s budget (MHE step at the smallest certified K, instructions at 1/cycle): {} (-v: every method)",
            self.sample_time,
            own.map_or_else(|| format!("{solver}: not computed"), MethodBudget::line)
        )
    }

    /// The summary's block (`-v` and summary.txt): one line per method.
    pub fn block(&self) -> String {
        let mut s = format!(
            "\nSample period T_s = {} s as a budget (per method at its smallest certified K: \
             K_min, K_glob or K_chain, the one verdict's; predicted max \
             instructions per MHE step, raised by the model's error; µs at one instruction per \
             cycle: instructions, not cycles; docs/embedded.md)\n",
            self.sample_time
        );
        for m in &self.methods {
            s += &format!("  {}\n", m.line());
        }
        s
    }
}

fn short(target: &str) -> &str {
    match target {
        "cortex-m4f" => "M4F",
        "cortex-m7" => "M7",
        t => t,
    }
}

/// The budget of every method's MHE step at its K in `methods` (the caller's smallest
/// certified K; `None`: no verdict) (`None`: the scenario has no sample period or no MHE).
pub fn reproduce(
    scenario: &Scenario,
    methods: &[(String, Option<usize>)],
) -> Option<ReproduceBudget> {
    let ts = scenario.sample_time?;
    let dims = dims(scenario, scenario.mhe.as_ref()?.horizon());
    let targets = default_targets();
    let methods = methods
        .iter()
        .map(|(m, k)| MethodBudget {
            method: m.clone(),
            k: *k,
            targets: k
                .and_then(|k| {
                    let step = Step { method: m, dims, k };
                    budgets(&targets, Scalar::F64, step, None, Some(ts)).ok()
                })
                .map(|bs| bs.iter().map(TargetRecord::from).collect())
                .unwrap_or_default(),
        })
        .collect();
    Some(ReproduceBudget {
        sample_time: ts,
        unit: UNIT,
        methods,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An f32 export's budget comes from the f32 rows (it said "not computed" before their
    /// calibration) and says whether the certificate covers its K in f32; f64 says nothing.
    #[test]
    fn f32_budgets_are_computed_and_say_what_the_certificate_covers() {
        let targets = default_targets();
        let dims = StepDims {
            n: 58,
            n_theta: 31,
            horizon: 9,
            nx: 4,
            nu: 1,
        };
        let step = Step {
            method: "pg",
            dims,
            k: 10,
        };
        let f32s = budgets(&targets, Scalar::F32, step, None, Some(0.02)).expect("valid");
        let f64s = budgets(&targets, Scalar::F64, step, None, Some(0.02)).expect("valid");
        for (a, b) in f32s.iter().zip(&f64s) {
            assert_eq!(a.scalar, Scalar::F32);
            assert!(!matches!(a.verdict, Verdict::NotComputed { .. }), "{a:?}");
            assert!(a.instructions.is_some() && a.instructions != b.instructions);
        }
        let j = json(&f32s, Some(f32_note(false)));
        let t = &j["targets"][0];
        assert_eq!(t["scalar"], "f32");
        assert!(
            t["scalar_note"]
                .as_str()
                .expect("a note")
                .contains("NOT certified in f32")
        );
        assert!(readme(&f32s, Some(f32_note(false))).contains("NOT certified in f32"));
        let j = json(&f64s, None);
        assert_eq!(j["targets"][1]["scalar"], "f64");
        assert!(j["targets"][1]["scalar_note"].is_null());
        // Without the MPC the records have no MPC keys (outputs as before the MPC counted).
        assert!(j["targets"][1].get("mpc_iterations").is_none());
        assert!(
            json(&f32s, Some(f32_note(true)))["targets"][0]["scalar_note"]
                .as_str()
                .expect("a note")
                .contains("covers in f32")
        );
    }

    /// With the MPC the records, the unit and the README say that K_c is counted.
    #[test]
    fn loop_budgets_say_the_mpc_is_counted() {
        let step = Step {
            method: "admm-pr",
            dims: StepDims::of(4, 1, 2, 6, 9),
            k: 10,
        };
        let mpc = Step {
            method: "fista",
            dims: StepDims::mpc(4, 1, 10),
            k: 99,
        };
        let bs =
            budgets(&default_targets(), Scalar::F64, step, Some(mpc), Some(0.02)).expect("valid");
        let j = json(&bs, None);
        assert!(j["unit"].as_str().expect("a unit").contains("loop step"));
        assert_eq!(j["targets"][0]["mpc_iterations"], 99);
        assert_eq!(j["targets"][0]["mpc_method"], "fista");
        assert!(
            j["targets"][0]["mpc_instructions_bound"]
                .as_f64()
                .expect("a bound")
                > 0.0
        );
        let r = readme(&bs, None);
        assert!(
            r.contains("K_c = 99 iterations (fista) are in this figure"),
            "{r}"
        );
        assert!(!r.contains("not in this figure"));
        let alone =
            budgets(&default_targets(), Scalar::F64, step, None, Some(0.02)).expect("valid");
        assert!(readme(&alone, None).contains("The MPC's K_c iterations are not in this figure"));
    }

    #[test]
    fn bad_clock_is_refused_naming_the_flag() {
        let e = check_targets(&[(Target::CortexM4F, 0.0)]).expect_err("clock 0");
        assert!(e.to_string().contains("--clock-mhz"), "{e}");
    }
}
