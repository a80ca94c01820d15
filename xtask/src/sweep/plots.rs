//! The SVG plots of an assembled sweep, drawn from its `points.csv`: one band chart per
//! metric (5–95 % band, median line), the bounded fraction, and ρ_lin(K); certified K_min
//! (dashed), K_reg (long thin dashes: the regional certificate) and K_lin (dotted) drawn per
//! solver, void certificates, missing K_reg and undrawable points noted under the chart
//! (never dropped silently).

use anyhow::{Result, anyhow};
use plotters::prelude::*;
use xtask::sweep_engine::{Sweep, Table};

use crate::output::OutputSet;

/// One solver's curve at one scale.
#[derive(Debug, Clone, PartialEq)]
struct Curve {
    solver: String,
    /// (K, q05, q50, q95) or (K, value) for the bounded fraction (lo = mid = hi).
    points: Vec<(f64, f64, f64, f64)>,
    k_min: Option<f64>,
    /// K_lin of the linear analysis on the grid (drawn dotted).
    k_lin: Option<f64>,
    /// K_reg of the regional certificate (drawn in long thin dashes).
    k_reg: Option<f64>,
    /// Why there is no K_reg (empty when there is one or the column is absent).
    regional_note: String,
    void_reason: Option<String>,
}

const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// A colour per method, from the one method list: the named methods (and their `-jacobi`
/// forms) by their place in `Method::PRESETS`, any other method by its family's place in
/// the list, after them.
fn color_of(solver: &str) -> RGBColor {
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
        Err(_) => COLORS.len() - 1,
    };
    COLORS[index % COLORS.len()]
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

/// A chart description (data only) and its rendering.
struct BandChart<'a> {
    title: String,
    y_label: &'a str,
    log_y: bool,
    curves: Vec<Curve>,
    notes: Vec<String>,
    /// A horizontal reference line (ρ_lin = 1) and its legend label.
    hline: Option<(f64, &'a str)>,
}

/// A tick label with at most 3 significant digits and no float noise (0.6, 1000, 2.5e-5).
fn tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    let digits = (2 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

pub(super) fn shorten(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        s.chars().take(n).collect::<String>() + "…"
    }
}

impl BandChart<'_> {
    /// Drops what a log axis cannot show, notes the K_min lines and void certificates.
    fn prepare(&mut self) {
        let mut dropped = 0;
        for c in &mut self.curves {
            let before = c.points.len();
            let log_y = self.log_y;
            c.points.retain(|&(_, lo, mid, hi)| {
                [lo, mid, hi]
                    .iter()
                    .all(|v| v.is_finite() && (!log_y || *v > 0.0))
            });
            dropped += before - c.points.len();
        }
        if dropped > 0 {
            self.notes.push(format!(
                "{dropped} points not drawn (non-finite{})",
                if self.log_y {
                    " or ≤ 0 on the log axis"
                } else {
                    ""
                }
            ));
        }
        let (k_lo, k_hi) = self.k_range();
        for c in &self.curves {
            match (&c.void_reason, c.k_min) {
                (Some(r), _) => self.notes.push(format!(
                    "{}: certificate void, no K_min line ({})",
                    c.solver,
                    shorten(r, 90)
                )),
                (None, Some(k)) if k < k_lo || k > k_hi => self.notes.push(format!(
                    "{}: certified K_min = {k} lies outside the K grid",
                    c.solver
                )),
                (None, None) => self.notes.push(format!(
                    "{}: no certified K within the search range",
                    c.solver
                )),
                _ => {}
            }
            match c.k_lin {
                Some(k) if k < k_lo || k > k_hi => self
                    .notes
                    .push(format!("{}: K_lin = {k} lies outside the K grid", c.solver)),
                None if self.curves.iter().any(|c| c.k_lin.is_some()) => self.notes.push(format!(
                    "{}: no K_lin on the grid (ρ_lin ≥ 1 at its largest K, or no analysis)",
                    c.solver
                )),
                _ => {}
            }
            match c.k_reg {
                Some(k) if k < k_lo || k > k_hi => self
                    .notes
                    .push(format!("{}: K_reg = {k} lies outside the K grid", c.solver)),
                None if !c.regional_note.is_empty() => self.notes.push(format!(
                    "{}: no K_reg ({})",
                    c.solver,
                    shorten(&c.regional_note, 110)
                )),
                _ => {}
            }
        }
    }

    fn k_range(&self) -> (f64, f64) {
        let ks = self
            .curves
            .iter()
            .flat_map(|c| c.points.iter().map(|p| p.0));
        let (lo, hi) = ks.fold((f64::INFINITY, 0.0f64), |(a, b), k| (a.min(k), b.max(k)));
        if lo.is_finite() {
            (lo, hi)
        } else {
            (1.0, 10.0)
        }
    }

    /// Renders the chart as SVG text (`name` for messages).
    fn svg(&self, name: &str) -> Result<String> {
        let err = |e: &dyn std::fmt::Display| anyhow!("plot `{name}`: {e}");
        let note_h = 18 * self.notes.len() as u32;
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (900, 540 + note_h)).into_drawing_area();
            root.fill(&WHITE).map_err(|e| err(&e))?;
            let (upper, lower) = root.split_vertically(540);
            let (k_lo, k_hi) = self.k_range();
            let x = (k_lo / 1.25)..(k_hi * 1.25);
            let ys = self
                .curves
                .iter()
                .flat_map(|c| c.points.iter().flat_map(|p| [p.1, p.3]));
            let (y_min, y_max) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
                (a.min(y), b.max(y))
            });
            let (y_min, y_max) = if y_min.is_finite() {
                (y_min, y_max)
            } else {
                (1.0, 10.0)
            };
            let mut builder = ChartBuilder::on(&upper);
            builder
                .caption(&self.title, ("sans-serif", 17))
                .margin(14)
                .x_label_area_size(44)
                .y_label_area_size(74);
            macro_rules! draw {
                ($chart:expr, $y_lo:expr, $y_hi:expr) => {{
                    let mut chart = $chart;
                    chart
                        .configure_mesh()
                        .x_desc("K (iterations of Φ per MHE step, log scale)")
                        .y_desc(self.y_label)
                        .x_label_formatter(&|x: &f64| tick(*x))
                        .y_label_formatter(&|y: &f64| tick(*y))
                        .draw()
                        .map_err(|e| err(&e))?;
                    for c in &self.curves {
                        let col = color_of(&c.solver);
                        if c.points.iter().any(|p| p.1 != p.3) {
                            let mut poly: Vec<(f64, f64)> =
                                c.points.iter().map(|p| (p.0, p.1)).collect();
                            poly.extend(c.points.iter().rev().map(|p| (p.0, p.3)));
                            chart
                                .draw_series(std::iter::once(Polygon::new(
                                    poly,
                                    col.mix(0.18).filled(),
                                )))
                                .map_err(|e| err(&e))?;
                        }
                        chart
                            .draw_series(LineSeries::new(
                                c.points.iter().map(|p| (p.0, p.2)),
                                col.stroke_width(2),
                            ))
                            .map_err(|e| err(&e))?
                            .label(c.solver.as_str())
                            .legend(move |(x, y)| {
                                PathElement::new(vec![(x, y), (x + 22, y)], col.stroke_width(2))
                            });
                        chart
                            .draw_series(
                                c.points
                                    .iter()
                                    .map(|p| Circle::new((p.0, p.2), 3, col.filled())),
                            )
                            .map_err(|e| err(&e))?;
                        // Certified K_min dashed (none when void), K_lin dotted.
                        let k_min = c.k_min.filter(|_| c.void_reason.is_none());
                        for (k, dash, gap, width, what) in [
                            (k_min, 8, 5, 2, "certified K_min"),
                            (c.k_reg, 14, 3, 1, "regional K_reg"),
                            (c.k_lin, 2, 4, 1, "K_lin"),
                        ] {
                            let Some(k) = k.filter(|k| *k >= k_lo && *k <= k_hi) else {
                                continue;
                            };
                            chart
                                .draw_series(DashedLineSeries::new(
                                    vec![(k, $y_lo), (k, $y_hi)],
                                    dash,
                                    gap,
                                    col.stroke_width(width),
                                ))
                                .map_err(|e| err(&e))?
                                .label(format!("{what}({}) = {k}", c.solver))
                                .legend(move |(x, y)| {
                                    PathElement::new(
                                        vec![
                                            (x, y),
                                            (x + dash as i32, y),
                                            (x + (dash + gap) as i32, y),
                                            (x + (2 * dash + gap) as i32, y),
                                        ],
                                        col.stroke_width(1),
                                    )
                                });
                        }
                    }
                    if let Some((level, label)) = self.hline {
                        chart
                            .draw_series(LineSeries::new(
                                vec![(k_lo / 1.25, level), (k_hi * 1.25, level)],
                                BLACK.stroke_width(1),
                            ))
                            .map_err(|e| err(&e))?
                            .label(label)
                            .legend(move |(x, y)| {
                                PathElement::new(vec![(x, y), (x + 22, y)], BLACK.stroke_width(1))
                            });
                    }
                    chart
                        .configure_series_labels()
                        .position(if self.log_y {
                            SeriesLabelPosition::UpperRight
                        } else {
                            SeriesLabelPosition::LowerRight
                        })
                        .background_style(WHITE.mix(0.85))
                        .border_style(BLACK)
                        .draw()
                        .map_err(|e| err(&e))?;
                }};
            }
            if self.log_y {
                let (lo, hi) = (y_min / 1.5, y_max * 1.5);
                let chart = builder
                    .build_cartesian_2d(x.clone().log_scale(), (lo..hi).log_scale())
                    .map_err(|e| err(&e))?;
                draw!(chart, lo, hi);
            } else {
                let (lo, hi) = (y_min.min(0.0), y_max.max(1.0) * 1.05);
                let chart = builder
                    .build_cartesian_2d(x.clone().log_scale(), lo..hi)
                    .map_err(|e| err(&e))?;
                draw!(chart, lo, hi);
            }
            for (i, n) in self.notes.iter().enumerate() {
                lower
                    .draw_text(
                        n,
                        &("sans-serif", 13).into_text_style(&lower),
                        (14, 18 * i as i32),
                    )
                    .map_err(|e| err(&e))?;
            }
            root.present().map_err(|e| err(&e))?;
        }
        Ok(svg)
    }

    #[cfg(test)]
    fn render(&self, path: &std::path::Path) -> Result<()> {
        crate::output::write_atomic(path, self.svg(&path.display().to_string())?.as_bytes())
    }
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

/// Stages the SVG plots of an assembled sweep from its `points.csv` (`table`) in `set`;
/// returns the file names.
pub fn plot_all(sweep: &Sweep, set: &mut OutputSet, table: &Table) -> Result<Vec<String>> {
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
    let mut render = |mut chart: BandChart<'_>, name: String| -> Result<()> {
        chart.prepare();
        set.add(&name, chart.svg(&name)?.as_bytes())?;
        written.push(name);
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
                y_label,
                log_y: true,
                curves: curves(table, scale, Column::Quantiles(col)),
                notes: vec![sub.clone()],
                hline: None,
            };
            render(chart, format!("{stem}{suffix}.svg"))?;
        }
        let chart = BandChart {
            title: "fraction of bounded runs".to_string(),
            y_label: "bounded fraction",
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
                y_label: "ρ_lin(K)",
                log_y: false,
                curves: curves(table, scale, Column::Value("rho_lin")),
                notes: vec![
                    format!("{} · the lifted loop of docs/theory.md (K_lin)", cfg.name),
                    "ρ_lin ≥ 1: small perturbations grow while no constraint is active (necessary condition)"
                        .to_string(),
                ],
                hline: Some((1.0, "ρ_lin = 1")),
            };
            render(chart, "rho-lin.svg".to_string())?;
        }
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn tick_labels() {
        assert_eq!(tick(0.6000000000000001), "0.6");
        assert_eq!(tick(1000.0), "1000");
        assert_eq!(tick(10.0), "10");
        assert_eq!(tick(0.125), "0.125");
        assert_eq!(tick(0.1234), "0.123");
        assert_eq!(tick(2.5e-5), "2.5e-5");
        assert_eq!(tick(0.0), "0");
    }

    #[test]
    fn curves_group_by_solver_and_note_void() {
        let t = Table::parse(
            "point,k,solver,scale,bounded_fraction,sup_e_q05,sup_e_q50,sup_e_q95,k_min_cert,certified,void_reason\n\
             0,1,pg,1,1,1,2,3,5,no,\n1,10,pg,1,1,0.5,1,2,5,yes,\n2,1,admm,1,0.5,inf,inf,inf,,void,rho < 1 fails\n",
        )
        .unwrap();
        let c = curves(&t, "1", Column::Quantiles("sup_e"));
        assert_eq!(c.len(), 2);
        assert_eq!(
            c[0].points,
            vec![(1.0, 1.0, 2.0, 3.0), (10.0, 0.5, 1.0, 2.0)]
        );
        assert_eq!(c[0].k_min, Some(5.0));
        assert_eq!(c[1].void_reason.as_deref(), Some("rho < 1 fails"));
        let mut chart = BandChart {
            title: "t".into(),
            y_label: "y",
            log_y: true,
            curves: c,
            notes: Vec::new(),
            hline: None,
        };
        chart.prepare();
        assert!(chart.curves[1].points.is_empty(), "∞ cannot be drawn");
        assert!(chart.notes.iter().any(|n| n.contains("1 points not drawn")));
        assert!(
            chart
                .notes
                .iter()
                .any(|n| n.contains("admm: certificate void"))
        );
        let dir = std::env::temp_dir().join(format!("xtask-sweep-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        chart.render(&dir.join("t.svg")).unwrap();
        let svg = std::fs::read_to_string(dir.join("t.svg")).unwrap();
        assert!(svg.contains("<svg") && svg.contains("certified K_min(pg) = 5"));
        let b = curves(&t, "1", Column::Value("bounded_fraction"));
        assert_eq!(b[1].points, vec![(1.0, 0.5, 0.5, 0.5)]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
