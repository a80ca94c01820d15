//! Glue: the "fits T_s" verdict of [`mhe_budget::fits`] (computed there, only) in export's
//! README and certificate.json and in reproduce's outputs.

use anyhow::{Result, bail};
use closed_loop::scenario::Scenario;
use mhe_budget::{Budget, Scalar, StepDims, Target, Verdict};
use serde::Serialize;
use serde_json::json;

/// The (target, clock) pairs of `--target` / `--clock-mhz`: both targets at their default
/// clocks when no target is given. Checked before anything slow runs.
pub(crate) fn targets(target: Option<&str>, clock_mhz: Option<f64>) -> Result<Vec<(Target, f64)>> {
    let out = match (target, clock_mhz) {
        (Some(t), c) => {
            let t = Target::parse(t)?;
            vec![(t, c.unwrap_or(t.default_clock_mhz()))]
        }
        (None, Some(_)) => bail!(
            "--clock-mhz: give the target it applies to with --target cortex-m4f or --target \
             cortex-m7"
        ),
        (None, None) => Target::ALL.map(|t| (t, t.default_clock_mhz())).to_vec(),
    };
    for (_, c) in &out {
        mhe_budget::check_clock(*c)?;
    }
    Ok(out)
}

/// The full window of the scenario's MHE.
pub(crate) fn dims(scenario: &Scenario, horizon: usize) -> StepDims {
    let p = &scenario.plant;
    StepDims::of(p.nx(), p.nu(), p.ny(), p.nw(), horizon)
}

/// The verdict per target for (method, K) on the scenario's window and T_s, from the
/// model's rows of the export's scalar (f32: its own calibration, the instructions of the f32
/// export at this K; what the certificate says of f32 is [`f32_note`]).
pub(crate) fn budgets(
    targets: &[(Target, f64)],
    method: &str,
    dims: StepDims,
    k: usize,
    sample_time: Option<f64>,
    f32: bool,
) -> Result<Vec<Budget>> {
    let scalar = if f32 { Scalar::F32 } else { Scalar::F64 };
    targets
        .iter()
        .map(|&(t, c)| {
            Ok(mhe_budget::fits(
                t,
                c,
                method,
                scalar,
                dims,
                k,
                sample_time,
            )?)
        })
        .collect()
}

/// What an f32 export's budget says about its K (`certified`: the export's verdict, which
/// for f32 is Theorem 1 with the f32 rounding folded in; void on every shipped scenario:
/// docs/theory.md, "Certified f32"). The budget itself is a measurement of the f32 code.
pub(crate) fn f32_note(certified: bool) -> &'static str {
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
    /// The model's prediction of the max instructions per step (null: not calibrated).
    pub instructions_per_step: Option<f64>,
    /// The prediction raised by the model's worst relative error: what the verdict uses.
    pub instructions_per_step_bound: Option<f64>,
    /// µs per step at one instruction per cycle, from the bound.
    pub micros_per_step: Option<f64>,
    /// n_z outside the calibrated sizes.
    pub extrapolated: bool,
    /// `fits`, `does_not_fit` or `not_computed`.
    pub fits_sample_time: &'static str,
    /// (T_s − t) / T_s when it fits.
    pub margin: Option<f64>,
    /// The largest K that fits T_s (null: not even K = 1, or not computed).
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
        };
        TargetRecord {
            target: b.target.name().into(),
            scalar: b.scalar.name(),
            scalar_note: None,
            clock_mhz: b.clock_mhz,
            iterations: b.k,
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

/// What every record counts (in certificate.json next to the records).
const UNIT: &str = "emulated instructions (qemu-system-arm -icount) of the MHE step (push + \
                    estimate, full window), one per cycle: not cycles; model \
                    crates/mhe-budget/data/cortex-m-model.csv";

/// certificate.json's `budget` of an export.
/// `note`: an f32 export's [`f32_note`] (None for f64).
pub(crate) fn json(budgets: &[Budget], note: Option<&'static str>) -> serde_json::Value {
    let records: Vec<TargetRecord> = budgets
        .iter()
        .map(|b| TargetRecord {
            scalar_note: note.filter(|_| b.scalar == Scalar::F32),
            ..TargetRecord::from(b)
        })
        .collect();
    json!({
        "unit": UNIT,
        "targets": records,
    })
}

/// reproduce's `budget`: per method at its certified K (K_min), both targets at their
/// default clocks, for a scenario with a sample period.
#[derive(Debug, Clone, Serialize)]
pub struct ReproduceBudget {
    /// T_s in seconds (`plant.sample_time`).
    pub sample_time: f64,
    /// What the numbers count.
    pub unit: &'static str,
    /// Per method.
    pub methods: Vec<MethodBudget>,
}

/// One method's budget at its K_min.
#[derive(Debug, Clone, Serialize)]
pub struct MethodBudget {
    /// The method.
    pub method: String,
    /// Its certified K (null: none, so no verdict).
    pub k_min: Option<usize>,
    /// Per target (empty without K_min).
    pub targets: Vec<TargetRecord>,
}

impl MethodBudget {
    /// `pg K_min = 243: cortex-m4f@168 …; cortex-m7@480 …`.
    pub fn line(&self) -> String {
        let Some(k) = self.k_min else {
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
            "T_s = {} s budget (MHE step at K_min, instructions at 1/cycle): {} (-v: every method)",
            self.sample_time,
            own.map_or_else(|| format!("{solver}: not computed"), MethodBudget::line)
        )
    }

    /// The summary's block (`-v` and summary.txt): one line per method.
    pub fn block(&self) -> String {
        let mut s = format!(
            "\nSample period T_s = {} s as a budget (per method at K_min; predicted max \
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

/// The budget of every method at its K_min (`None`: the scenario has no sample period or
/// no MHE).
pub(crate) fn reproduce(
    scenario: &Scenario,
    methods: &[(String, Option<usize>)],
) -> Option<ReproduceBudget> {
    let ts = scenario.sample_time?;
    let dims = dims(scenario, scenario.mhe.as_ref()?.horizon());
    let targets: Vec<(Target, f64)> = Target::ALL.map(|t| (t, t.default_clock_mhz())).to_vec();
    let methods = methods
        .iter()
        .map(|(m, k)| MethodBudget {
            method: m.clone(),
            k_min: *k,
            targets: k
                .and_then(|k| budgets(&targets, m, dims, k, Some(ts), false).ok())
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

/// The README section.
pub(crate) fn readme(budgets: &[Budget], note: Option<&'static str>) -> String {
    let mut s = String::from(
        "\n## The sample period as a budget\n\n\
         Max instructions per MHE step (push + estimate, the full window) predicted by the \
         calibrated model of `mhe_budget` (QEMU `-icount` measurements of every method, \
         docs/embedded.md), raised by the model's worst relative error; time at one \
         instruction per cycle (**instructions, not cycles**: flash wait states and \
         multi-cycle instructions add to it on a real board). The MPC's K_c iterations are \
         not in this figure.\n\n",
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

/// Adds the budget to an artefact written into `dir`: `budget` in certificate.json and a
/// README section.
pub(crate) fn annotate(
    dir: &std::path::Path,
    budgets: &[Budget],
    note: Option<&'static str>,
) -> Result<()> {
    // Inserted as the last key of the object, so the other keys keep their order.
    let cert = dir.join("certificate.json");
    let text = std::fs::read_to_string(&cert)?;
    let Some(body) = text.trim_end().strip_suffix('}') else {
        bail!("{}: not a JSON object", cert.display());
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

#[cfg(test)]
mod tests {
    use super::*;

    /// An f32 export's budget comes from the f32 rows (it said "not computed" before their
    /// calibration) and says whether the certificate covers its K in f32; f64 says nothing.
    #[test]
    fn f32_budgets_are_computed_and_say_what_the_certificate_covers() {
        let targets = targets(None, None).expect("defaults");
        let dims = StepDims {
            n: 58,
            n_theta: 31,
            horizon: 9,
            nx: 4,
            nu: 1,
        };
        let f32s = budgets(&targets, "pg", dims, 10, Some(0.02), true).expect("valid");
        let f64s = budgets(&targets, "pg", dims, 10, Some(0.02), false).expect("valid");
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
        assert!(
            json(&f32s, Some(f32_note(true)))["targets"][0]["scalar_note"]
                .as_str()
                .expect("a note")
                .contains("covers in f32")
        );
    }
}
