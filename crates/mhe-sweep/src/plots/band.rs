//! The plots of a 1-D sweep, drawn from its `points.csv`: one band chart per metric
//! (5–95 % band, median line), the bounded fraction, and ρ_lin(K), each with the solvers'
//! thresholds (`mhe_plots::band` draws them; this module reads the table and chooses the
//! charts).

use mhe_plots::PlotError;
use mhe_plots::band::{BandChart, CURVE_PALETTE, Curve};

use crate::{Sweep, Table};

/// A colour per method (an index into [`CURVE_PALETTE`]), from the one method list: the
/// named methods (and their `-jacobi` forms) by their place in `Method::PRESETS`, any other
/// method by its family's place in the list, after them.
fn color_of(solver: &str) -> usize {
    let base = solver.strip_suffix("-jacobi").unwrap_or(solver);
    let index = match base.parse::<qp_iter::Method>() {
        Ok(m) => match qp_iter::Method::PRESETS.iter().position(|p| *p == m) {
            Some(i) => i,
            None => {
                let families = qp_iter::Method::families();
                qp_iter::Method::PRESETS.len()
                    + families.iter().position(|f| *f == m.family()).unwrap_or(0)
            }
        },
        Err(_) => CURVE_PALETTE.len() - 1,
    };
    index % CURVE_PALETTE.len()
}

/// What a curve shows: a metric's quantile columns (`{m}_q05`, `_q50`, `_q95`) as a band,
/// or one column as a line (the bounded fraction, ρ_lin).
#[derive(Debug, Clone, Copy)]
enum Column<'a> {
    Quantiles(&'a str),
    Value(&'a str),
}

/// Curves of one column for one scale, grouped by solver in order of appearance.
fn curves(table: &Table, scale: &str, column: Column<'_>) -> Vec<Curve> {
    let mut out: Vec<Curve> = Vec::new();
    for row in 0..table.rows.len() {
        if table.text(row, "scale") != Some(scale) {
            continue;
        }
        let Some(solver) = table.text(row, "solver") else {
            continue;
        };
        let Some(k) = table.number(row, "k") else {
            continue;
        };
        let vals = match column {
            Column::Quantiles(m) => (
                table.number(row, &format!("{m}_q05")),
                table.number(row, &format!("{m}_q50")),
                table.number(row, &format!("{m}_q95")),
            ),
            Column::Value(name) => {
                let f = table.number(row, name);
                (f, f, f)
            }
        };
        let idx = match out.iter().position(|c| c.solver == solver) {
            Some(i) => i,
            None => {
                let void = (table.text(row, "certified") == Some("void"))
                    .then(|| table.text(row, "void_reason").unwrap_or("").to_string());
                out.push(Curve {
                    solver: solver.to_string(),
                    color: color_of(solver),
                    points: Vec::new(),
                    k_min: table.number(row, "k_min_cert"),
                    k_lin: table.number(row, "k_lin"),
                    k_reg: table.number(row, "k_reg"),
                    regional_note: table.text(row, "regional_note").unwrap_or("").to_string(),
                    void_reason: void,
                });
                out.len() - 1
            }
        };
        if let (Some(lo), Some(mid), Some(hi)) = vals {
            out[idx].points.push((k, lo, mid, hi));
        }
    }
    out
}

/// The plotted metrics: (column, file stem, title, y label).
const PLOTS: [(&str, &str, &str, &str); 9] = [
    (
        "tail_mean_e",
        "error",
        "estimation error ‖e_t‖, mean over the last quarter",
        "‖e‖ (last-quarter mean)",
    ),
    (
        "tail_mean_x",
        "state",
        "state ‖x_t‖, mean over the last quarter",
        "‖x‖ (last-quarter mean)",
    ),
    ("sup_e", "error-sup", "sup_t ‖e_t‖", "sup ‖e‖"),
    ("sup_x", "state-sup", "sup_t ‖x_t‖", "sup ‖x‖"),
    (
        "gain_e",
        "gain-e",
        "empirical gain sup‖e‖ / sup‖w‖",
        "sup‖e‖ / sup‖w‖",
    ),
    (
        "gain_x",
        "gain-x",
        "empirical gain sup‖x‖ / sup‖w‖",
        "sup‖x‖ / sup‖w‖",
    ),
    (
        "tail_gain_e",
        "tail-gain-e",
        "empirical gain after the transient: last-quarter mean ‖e‖ / sup‖w‖",
        "last-quarter ‖e‖ / sup‖w‖",
    ),
    (
        "tail_gain_x",
        "tail-gain-x",
        "empirical gain after the transient: last-quarter mean ‖x‖ / sup‖w‖",
        "last-quarter ‖x‖ / sup‖w‖",
    ),
    (
        "sup_eps",
        "epsilon",
        "sup_t ε_t = ‖zᴷ − z*‖ (exact solve)",
        "sup ε",
    ),
];

/// The band charts of an assembled 1-D sweep from its `points.csv` (`table`): (file name,
/// SVG text) per chart, one set per disturbance scale (`-scale{s}` in the names when there
/// are several), ρ_lin once.
pub fn band_charts(sweep: &Sweep, table: &Table) -> Result<Vec<(String, String)>, PlotError> {
    let mut scales: Vec<String> = Vec::new();
    for r in 0..table.rows.len() {
        if let Some(s) = table.text(r, "scale") {
            if !scales.iter().any(|x| x == s) {
                scales.push(s.to_string());
            }
        }
    }
    let cfg = sweep.config();
    let mut written = Vec::new();
    let mut render = |mut chart: BandChart, name: String| -> Result<(), PlotError> {
        chart.prepare();
        let svg = chart.svg(&name)?;
        written.push((name, svg));
        Ok(())
    };
    for scale in &scales {
        let suffix = if scales.len() > 1 {
            format!("-scale{scale}")
        } else {
            String::new()
        };
        let sub = format!(
            "{} · T = {} · {} seeds · w scale {scale} · band 5–95 %, line median",
            cfg.name,
            sweep.steps(),
            cfg.seeds
        );
        let plain = sub.replace(" · band 5–95 %, line median", "");
        for (col, stem, title, y_label) in PLOTS {
            if table.column(&format!("{col}_q50")).is_none() {
                continue;
            }
            let chart = BandChart {
                title: title.to_string(),
                y_label: y_label.to_string(),
                log_y: true,
                curves: curves(table, scale, Column::Quantiles(col)),
                notes: vec![sub.clone()],
                hline: None,
            };
            render(chart, format!("{stem}{suffix}.svg"))?;
        }
        let chart = BandChart {
            title: "fraction of bounded runs".to_string(),
            y_label: "bounded fraction".to_string(),
            log_y: false,
            curves: curves(table, scale, Column::Value("bounded_fraction")),
            notes: vec![
                plain.clone(),
                format!(
                    "bounded: completed, finite, sup‖x‖ ≤ {f}·(1 + ‖x₀‖) and sup‖e‖ ≤ {f}·(1 + ‖e₀‖)",
                    f = cfg.bounded_factor
                ),
            ],
            hline: None,
        };
        render(chart, format!("bounded{suffix}.svg"))?;
        if table.column("rho_lin").is_some() && scale == &scales[0] {
            // ρ_lin does not depend on the disturbance scale: one chart.
            let chart = BandChart {
                title: "ρ_lin(K): spectral radius of Alg. 1 linearised where no constraint is active"
                    .to_string(),
                y_label: "ρ_lin(K)".to_string(),
                log_y: false,
                curves: curves(table, scale, Column::Value("rho_lin")),
                notes: vec![
                    format!("{} · the lifted loop of docs/theory.md (K_lin)", cfg.name),
                    "ρ_lin ≥ 1: small perturbations grow while no constraint is active (necessary condition)"
                        .to_string(),
                ],
                hline: Some((1.0, "ρ_lin = 1".to_string())),
            };
            render(chart, "rho-lin.svg".to_string())?;
        }
    }
    Ok(written)
}

#[cfg(test)]
#[path = "band_tests.rs"]
mod tests;
