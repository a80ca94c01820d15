//! The flags of the sample-period budget (`--target`, `--clock-mhz`); the verdict is
//! computed by `mhe_budget` and written by `mhe_export::budget` (the artefact's README and
//! certificate.json, reproduce's outputs).

use anyhow::{Result, bail};
use mhe_budget::Target;

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
