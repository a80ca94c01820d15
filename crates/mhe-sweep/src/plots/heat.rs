//! Heat maps of a 2-D sweep over (K_e, K_c), drawn from its `points.csv`: per MHE solver and
//! disturbance scale the bounded fraction and the median last-quarter ‖e‖, per solver ρ_lin
//! (it does not depend on the scale), each with three region boundaries as staircases: the
//! empirical one (every run bounded at every grid pair above), the linear one (ρ_lin < 1 at
//! every grid pair above; [`pair_thresholds`](crate::pair_thresholds)) and the joint
//! certificate's ([`certified_boundary`](crate::certified_boundary); "certificate: not
//! computed" in the legend while it is empty). `mhe_plots::heatmap` draws them; this module
//! reads the table and chooses the maps.

use mhe_plots::PlotError;
use mhe_plots::heatmap::{Axis, ColorScale, HeatMap};

use crate::{ControllerChoice, PairThresholds, Sweep, SweepConfig, Table};

/// The value grid of one column of `points.csv` for one solver and scale.
fn values(
    table: &Table,
    solver: &str,
    scale: &str,
    column: &str,
    k_e: &Axis,
    k_c: &Axis,
) -> Vec<Vec<Option<f64>>> {
    let mut v = vec![vec![None; k_c.values().len()]; k_e.values().len()];
    for row in 0..table.rows.len() {
        if table.text(row, "solver") != Some(solver) || table.text(row, "scale") != Some(scale) {
            continue;
        }
        let int = |name| table.text(row, name).and_then(|s| s.parse::<usize>().ok());
        let (Some(ke), Some(kc)) = (int("k"), int("k_c")) else {
            continue;
        };
        if let (Some(i), Some(j)) = (
            k_e.values().iter().position(|&x| x == ke),
            k_c.values().iter().position(|&x| x == kc),
        ) {
            v[i][j] = table.number(row, column);
        }
    }
    v
}

/// The file stem of a solver (its name, safe in a file name).
fn stem(solver: &str) -> String {
    solver
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The heat maps of one (solver, scale): what they share.
struct PairMaps<'a> {
    p: &'a PairThresholds,
    table: &'a Table,
    cfg: &'a SweepConfig,
    /// The MPC's method.
    mpc: &'a str,
    k_e: Axis,
    k_c: Axis,
    /// `-scale{s}` when the sweep has more than one scale.
    suffix: String,
    /// The sweep line, the region rule, the bounded rule.
    rules: Vec<String>,
}

impl<'a> PairMaps<'a> {
    fn new(
        sweep: &'a Sweep,
        p: &'a PairThresholds,
        table: &'a Table,
        mpc: &'a str,
        several_scales: bool,
    ) -> Self {
        let cfg = sweep.config();
        let suffix = if several_scales {
            format!("-scale{}", p.scale)
        } else {
            String::new()
        };
        let sub = format!(
            "{} · MHE {} · MPC {mpc} · T = {} · {} seeds · w scale {}",
            cfg.name,
            p.solver,
            sweep.steps(),
            cfg.seeds,
            p.scale
        );
        let rules = vec![
            sub,
            "regions: a pair counts when its criterion holds at every grid pair with K_e and K_c at least as large".to_string(),
            format!(
                "bounded: completed, finite, sup‖x‖ ≤ {f}·(1 + ‖x₀‖) and sup‖e‖ ≤ {f}·(1 + ‖e₀‖)",
                f = cfg.bounded_factor
            ),
        ];
        Self {
            p,
            table,
            cfg,
            mpc,
            k_e: Axis::new(&p.k_e_grid),
            k_c: Axis::new(&p.k_c_grid),
            suffix,
            rules,
        }
    }

    /// A map of `column` with the pair's boundaries.
    fn make(
        &self,
        title: String,
        label: &str,
        column: &str,
        scale: ColorScale,
        notes: Vec<String>,
    ) -> HeatMap {
        let p = self.p;
        HeatMap {
            title,
            value_label: label.to_string(),
            values: values(
                self.table, &p.solver, &p.scale, column, &self.k_e, &self.k_c,
            ),
            k_e: self.k_e.clone(),
            k_c: self.k_c.clone(),
            scale,
            empirical: p.empirical_boundary.clone(),
            linear: p.linear_boundary.clone(),
            certified: p.certified_boundary.clone(),
            regional: p.regional.clone(),
            notes,
        }
    }

    /// The fraction of bounded runs.
    fn bounded(&self) -> (HeatMap, String) {
        let map = self.make(
            format!("fraction of bounded runs — MHE {}", self.p.solver),
            "bounded fraction",
            "bounded_fraction",
            ColorScale::Linear { lo: 0.0, hi: 1.0 },
            self.rules.clone(),
        );
        let name = format!(
            "heatmap-bounded-{}{}.svg",
            stem(&self.p.solver),
            self.suffix
        );
        (map, name)
    }

    /// The median last-quarter ‖e‖, on a log colour scale over its finite positive values.
    fn error(&self) -> (HeatMap, String) {
        let mut m = self.make(
            format!("median last-quarter ‖e_t‖ — MHE {}", self.p.solver),
            "median ‖e‖",
            "tail_mean_e_q50",
            ColorScale::Log { lo: 1.0, hi: 10.0 },
            self.rules.clone(),
        );
        let finite: Vec<f64> = m
            .values
            .iter()
            .flatten()
            .flatten()
            .copied()
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = finite.iter().copied().fold(0.0, f64::max);
        if lo.is_finite() {
            m.scale = ColorScale::Log {
                lo,
                hi: hi.max(lo * 1.0001),
            };
        }
        let name = format!("heatmap-error-{}{}.svg", stem(&self.p.solver), self.suffix);
        (m, name)
    }

    /// ρ_lin of the lifted loop, around 1 (its span the largest |ln ρ_lin|, clamped).
    fn rho_lin(&self) -> (HeatMap, String) {
        let (cfg, p) = (self.cfg, self.p);
        let mut m = self.make(
            format!("ρ_lin(K_e, K_c) of the lifted loop — MHE {}", p.solver),
            "ρ_lin",
            "rho_lin",
            ColorScale::AroundOne { span: 0.1 },
            vec![
                format!(
                    "{} · MHE {} · MPC {} · the lifted loop of docs/theory.md (no constraint active)",
                    cfg.name, p.solver, self.mpc
                ),
                "ρ_lin ≥ 1 (red): small perturbations grow while no constraint is active; colours saturate at e^±span of the bar".to_string(),
                self.rules[2].clone(),
            ],
        );
        let span = m
            .values
            .iter()
            .flatten()
            .flatten()
            .filter(|v| v.is_finite() && **v > 0.0)
            .map(|v| v.ln().abs())
            .fold(0.0f64, f64::max);
        m.scale = ColorScale::AroundOne {
            span: span.clamp(0.01, std::f64::consts::LN_2),
        };
        (m, format!("heatmap-rho-lin-{}.svg", stem(&p.solver)))
    }
}

/// The disturbance scales of `pairs` in order of appearance.
fn scales_of(pairs: &[PairThresholds]) -> Vec<&str> {
    pairs.iter().fold(Vec::new(), |mut v, p| {
        if !v.contains(&p.scale.as_str()) {
            v.push(p.scale.as_str());
        }
        v
    })
}

/// The heat maps of an assembled 2-D sweep from its `points.csv` (`table`) and its 2-D
/// thresholds (`pairs`, which carry the boundaries): (file name, SVG text) per map.
pub fn heat_maps(
    sweep: &Sweep,
    table: &Table,
    pairs: &[PairThresholds],
) -> Result<Vec<(String, String)>, PlotError> {
    let scales = scales_of(pairs);
    let mpc = match sweep.config().controller {
        ControllerChoice::SuboptimalMpc { method, .. } => method.to_string(),
        _ => "?".into(),
    };
    let mut written = Vec::new();
    for p in pairs {
        let pair = PairMaps::new(sweep, p, table, &mpc, scales.len() > 1);
        let mut maps = vec![pair.bounded()];
        if table.column("tail_mean_e_q50").is_some() {
            maps.push(pair.error());
        }
        if scales.first() == Some(&p.scale.as_str()) && table.column("rho_lin").is_some() {
            maps.push(pair.rho_lin());
        }
        for (m, name) in maps {
            let svg = m.svg(&name)?;
            written.push((name, svg));
        }
    }
    Ok(written)
}

#[cfg(test)]
#[path = "heat_tests.rs"]
mod tests;
