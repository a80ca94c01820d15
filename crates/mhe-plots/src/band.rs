//! Band charts: a metric over K (log axis) per solver, as a 5–95 % band with its median line
//! and markers, or one value per K as a line (a fraction, ρ_lin); per solver the certified
//! K_min (dashed), K_reg (long thin dashes: the regional certificate) and K_lin (dotted) as
//! vertical lines; void certificates, missing thresholds and undrawable points noted under
//! the chart (never dropped silently: [`BandChart::prepare`]).

use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::prelude::*;

use crate::{PlotError, shorten, three_digits};

/// Colours of the curves as RGB (matplotlib's tab10 order); [`Curve::color`] indexes it.
pub const CURVE_PALETTE: [(u8, u8, u8); 8] = [
    (31, 119, 180),
    (214, 39, 40),
    (44, 160, 44),
    (148, 103, 189),
    (255, 127, 14),
    (140, 86, 75),
    (227, 119, 194),
    (23, 190, 207),
];

/// One solver's curve.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// The solver's name (legend entry).
    pub solver: String,
    /// Index into [`CURVE_PALETTE`] (taken modulo its length).
    pub color: usize,
    /// (K, q05, q50, q95), or (K, v, v, v) for a single value (no band is drawn when every
    /// point has q05 = q95).
    pub points: Vec<(f64, f64, f64, f64)>,
    /// The certified K_min (drawn dashed unless the certificate is void).
    pub k_min: Option<f64>,
    /// K_lin of the linear analysis on the grid (drawn dotted).
    pub k_lin: Option<f64>,
    /// K_reg of the regional certificate (drawn in long thin dashes).
    pub k_reg: Option<f64>,
    /// Why there is no K_reg (empty when there is one or the column is absent).
    pub regional_note: String,
    /// Why the certificate is void (`None`: not void).
    pub void_reason: Option<String>,
}

/// A band chart (data only) and its rendering.
#[derive(Debug, Clone, PartialEq)]
pub struct BandChart {
    /// Title above the chart.
    pub title: String,
    /// y-axis label.
    pub y_label: String,
    /// Logarithmic y axis (the x axis, K, is always logarithmic).
    pub log_y: bool,
    /// One curve per solver.
    pub curves: Vec<Curve>,
    /// Lines of text under the chart.
    pub notes: Vec<String>,
    /// A horizontal reference line (e.g. ρ_lin = 1) and its legend label.
    pub hline: Option<(f64, String)>,
}

fn color(c: &Curve) -> RGBColor {
    let (r, g, b) = CURVE_PALETTE[c.color % CURVE_PALETTE.len()];
    RGBColor(r, g, b)
}

impl BandChart {
    /// Drops the points a log axis cannot show and notes how many, notes void certificates
    /// and thresholds missing or outside the K range. Call before [`BandChart::svg`].
    pub fn prepare(&mut self) {
        self.drop_undrawable();
        let (k_lo, k_hi) = self.k_range();
        let any_k_lin = self.curves.iter().any(|c| c.k_lin.is_some());
        let notes: Vec<String> = self
            .curves
            .iter()
            .flat_map(|c| threshold_notes(c, (k_lo, k_hi), any_k_lin))
            .collect();
        self.notes.extend(notes);
    }

    fn drop_undrawable(&mut self) {
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
    }

    /// The smallest and largest K of the drawn points ((1, 10) when there is none).
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

    /// The y range of the bands ((1, 10) when there is none).
    fn y_extent(&self) -> (f64, f64) {
        let ys = self
            .curves
            .iter()
            .flat_map(|c| c.points.iter().flat_map(|p| [p.1, p.3]));
        let (y_min, y_max) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
        if y_min.is_finite() {
            (y_min, y_max)
        } else {
            (1.0, 10.0)
        }
    }

    /// Renders the chart as SVG text (`name` for messages).
    ///
    /// ```
    /// use mhe_plots::band::{BandChart, Curve};
    /// let mut chart = BandChart {
    ///     title: "sup ‖e‖".into(),
    ///     y_label: "sup ‖e‖".into(),
    ///     log_y: true,
    ///     curves: vec![Curve {
    ///         solver: "pg".into(),
    ///         color: 0,
    ///         points: vec![(1.0, 2.0, 3.0, 4.0), (10.0, 0.5, 1.0, 2.0)],
    ///         k_min: Some(5.0),
    ///         k_lin: None,
    ///         k_reg: None,
    ///         regional_note: String::new(),
    ///         void_reason: None,
    ///     }],
    ///     notes: vec![],
    ///     hline: None,
    /// };
    /// chart.prepare();
    /// let svg = chart.svg("error.svg")?;
    /// assert!(svg.contains("certified K_min(pg) = 5"));
    /// # Ok::<(), mhe_plots::PlotError>(())
    /// ```
    pub fn svg(&self, name: &str) -> Result<String, PlotError> {
        let context = format!("plot `{name}`");
        let err = |e: &dyn std::fmt::Display| PlotError::drawing(&context, e);
        let note_h = 18 * self.notes.len() as u32;
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (900, 540 + note_h)).into_drawing_area();
            root.fill(&WHITE).map_err(|e| err(&e))?;
            let (upper, lower) = root.split_vertically(540);
            self.draw_upper(&upper, &context)?;
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

    /// The chart on a log K axis and a log or linear y axis.
    fn draw_upper<DB: DrawingBackend>(
        &self,
        upper: &DrawingArea<DB, Shift>,
        context: &str,
    ) -> Result<(), PlotError> {
        let err = |e: &dyn std::fmt::Display| PlotError::drawing(context, e);
        let (k_lo, k_hi) = self.k_range();
        let x = (k_lo / 1.25)..(k_hi * 1.25);
        let (y_min, y_max) = self.y_extent();
        let mut builder = ChartBuilder::on(upper);
        builder
            .caption(&self.title, ("sans-serif", 17))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(74);
        if self.log_y {
            let (lo, hi) = (y_min / 1.5, y_max * 1.5);
            let mut chart = builder
                .build_cartesian_2d(x.log_scale(), (lo..hi).log_scale())
                .map_err(|e| err(&e))?;
            self.draw_body(&mut chart, (lo, hi), context)
        } else {
            let (lo, hi) = (y_min.min(0.0), y_max.max(1.0) * 1.05);
            let mut chart = builder
                .build_cartesian_2d(x.log_scale(), lo..hi)
                .map_err(|e| err(&e))?;
            self.draw_body(&mut chart, (lo, hi), context)
        }
    }

    /// Mesh, curves, reference line and legend on a context of either y coordinate type.
    fn draw_body<'a, DB: DrawingBackend + 'a, Y>(
        &self,
        chart: &mut Ctx<'a, DB, Y>,
        y: (f64, f64),
        context: &str,
    ) -> Result<(), PlotError>
    where
        Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        let err = |e: &dyn std::fmt::Display| PlotError::drawing(context, e);
        chart
            .configure_mesh()
            .x_desc("K (iterations of Φ per MHE step, log scale)")
            .y_desc(self.y_label.as_str())
            .x_label_formatter(&|x: &f64| three_digits(*x))
            .y_label_formatter(&|y: &f64| three_digits(*y))
            .draw()
            .map_err(|e| err(&e))?;
        let k = self.k_range();
        for c in &self.curves {
            draw_curve(chart, c, context)?;
            draw_thresholds(chart, c, k, y, context)?;
        }
        if let Some((level, label)) = &self.hline {
            chart
                .draw_series(LineSeries::new(
                    vec![(k.0 / 1.25, *level), (k.1 * 1.25, *level)],
                    BLACK.stroke_width(1),
                ))
                .map_err(|e| err(&e))?
                .label(label.as_str())
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
            .map_err(|e| err(&e))
    }
}

/// The notes of one curve: void certificate, thresholds missing or outside `[k_lo, k_hi]`.
fn threshold_notes(c: &Curve, (k_lo, k_hi): (f64, f64), any_k_lin: bool) -> Vec<String> {
    let mut notes = Vec::new();
    match (&c.void_reason, c.k_min) {
        (Some(r), _) => notes.push(format!(
            "{}: certificate void, no K_min line ({})",
            c.solver,
            shorten(r, 90)
        )),
        (None, Some(k)) if k < k_lo || k > k_hi => notes.push(format!(
            "{}: certified K_min = {k} lies outside the K grid",
            c.solver
        )),
        (None, None) => notes.push(format!(
            "{}: no certified K within the search range",
            c.solver
        )),
        _ => {}
    }
    match c.k_lin {
        Some(k) if k < k_lo || k > k_hi => {
            notes.push(format!("{}: K_lin = {k} lies outside the K grid", c.solver));
        }
        None if any_k_lin => notes.push(format!(
            "{}: no K_lin on the grid (ρ_lin ≥ 1 at its largest K, or no analysis)",
            c.solver
        )),
        _ => {}
    }
    match c.k_reg {
        Some(k) if k < k_lo || k > k_hi => {
            notes.push(format!("{}: K_reg = {k} lies outside the K grid", c.solver));
        }
        None if !c.regional_note.is_empty() => notes.push(format!(
            "{}: no K_reg ({})",
            c.solver,
            shorten(&c.regional_note, 110)
        )),
        _ => {}
    }
    notes
}

/// A band chart's plotting context: log K, linear or log y.
type Ctx<'a, DB, Y> = ChartContext<'a, DB, Cartesian2d<LogCoord<f64>, Y>>;

/// A curve: its band (when the quantiles differ), the median line with its legend entry, the
/// markers.
fn draw_curve<'a, DB: DrawingBackend + 'a, Y>(
    chart: &mut Ctx<'a, DB, Y>,
    c: &Curve,
    context: &str,
) -> Result<(), PlotError>
where
    Y: Ranged<ValueType = f64>,
{
    let err = |e: &dyn std::fmt::Display| PlotError::drawing(context, e);
    let col = color(c);
    if c.points.iter().any(|p| p.1 != p.3) {
        let mut poly: Vec<(f64, f64)> = c.points.iter().map(|p| (p.0, p.1)).collect();
        poly.extend(c.points.iter().rev().map(|p| (p.0, p.3)));
        chart
            .draw_series(std::iter::once(Polygon::new(poly, col.mix(0.18).filled())))
            .map_err(|e| err(&e))?;
    }
    chart
        .draw_series(LineSeries::new(
            c.points.iter().map(|p| (p.0, p.2)),
            col.stroke_width(2),
        ))
        .map_err(|e| err(&e))?
        .label(c.solver.as_str())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], col.stroke_width(2)));
    chart
        .draw_series(
            c.points
                .iter()
                .map(|p| Circle::new((p.0, p.2), 3, col.filled())),
        )
        .map_err(|e| err(&e))?;
    Ok(())
}

/// A curve's thresholds inside `[k_lo, k_hi]` as vertical lines over `y`: certified K_min
/// dashed (none when void), K_reg in long thin dashes, K_lin dotted.
fn draw_thresholds<'a, DB: DrawingBackend + 'a, Y>(
    chart: &mut Ctx<'a, DB, Y>,
    c: &Curve,
    (k_lo, k_hi): (f64, f64),
    (y_lo, y_hi): (f64, f64),
    context: &str,
) -> Result<(), PlotError>
where
    Y: Ranged<ValueType = f64>,
{
    let col = color(c);
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
                vec![(k, y_lo), (k, y_hi)],
                dash,
                gap,
                col.stroke_width(width),
            ))
            .map_err(|e| PlotError::drawing(context, e))?
            .label(format!("{what}({}) = {k}", c.solver))
            .legend(move |(x, y)| {
                PathElement::new(
                    vec![
                        (x, y),
                        (x + dash, y),
                        (x + dash + gap, y),
                        (x + 2 * dash + gap, y),
                    ],
                    col.stroke_width(1),
                )
            });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn curve(solver: &str, points: Vec<(f64, f64, f64, f64)>) -> Curve {
        Curve {
            solver: solver.into(),
            color: 0,
            points,
            k_min: Some(5.0),
            k_lin: None,
            k_reg: None,
            regional_note: String::new(),
            void_reason: None,
        }
    }

    #[test]
    fn prepare_drops_undrawable_points_and_notes_void_certificates() {
        let mut chart = BandChart {
            title: "t".into(),
            y_label: "y".into(),
            log_y: true,
            curves: vec![
                curve("pg", vec![(1.0, 1.0, 2.0, 3.0), (10.0, 0.5, 1.0, 2.0)]),
                Curve {
                    k_min: None,
                    void_reason: Some("rho < 1 fails".into()),
                    ..curve(
                        "admm",
                        vec![(1.0, f64::INFINITY, f64::INFINITY, f64::INFINITY)],
                    )
                },
            ],
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
        let svg = chart.svg("t.svg").unwrap();
        assert!(svg.contains("<svg") && svg.contains("certified K_min(pg) = 5"));
    }

    #[test]
    fn thresholds_outside_the_grid_are_noted_not_drawn() {
        let c = Curve {
            k_lin: Some(100.0),
            k_reg: None,
            regional_note: "no region".into(),
            ..curve("pg", vec![(1.0, 1.0, 1.0, 1.0), (10.0, 1.0, 1.0, 1.0)])
        };
        let notes = threshold_notes(&c, (1.0, 10.0), true);
        assert_eq!(
            notes,
            vec![
                "pg: K_lin = 100 lies outside the K grid".to_string(),
                "pg: no K_reg (no region)".to_string(),
            ]
        );
    }
}
