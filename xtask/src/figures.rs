//! Line charts as SVG (plotters, SVG backend, no font files): the Fig. 2 analogues and the
//! norm plots of `cargo xtask reproduce`.
//!
//! A [`Chart`] is plain data (series of (x, y) points, horizontal reference lines, axis
//! labels, linear or log y), so the code that extracts the data from a trace is separate
//! from the drawing and both can be tested on their own. On a log axis, points with y ≤ 0
//! or non-finite y cannot be drawn: the line is broken there and [`render_svg`] reports how
//! many points it left out ([`Rendered::dropped`]); callers put that in the caption.

use anyhow::{Result, anyhow, bail};
use plotters::prelude::*;

/// Line pattern of a series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    /// Solid line.
    Solid,
    /// Dashed line.
    Dashed,
}

/// One series: a polyline, optionally with a marker at every point.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend entry.
    pub label: String,
    /// Points in drawing order.
    pub points: Vec<(f64, f64)>,
    /// Index into [`PALETTE`] (taken modulo its length).
    pub color: usize,
    /// Line pattern.
    pub pattern: Pattern,
    /// Draw a small circle at every point (useful for short sequences such as ŵ²).
    pub markers: bool,
}

/// A horizontal reference line (e.g. a bound of 𝒲), drawn in red across the chart.
#[derive(Debug, Clone, PartialEq)]
pub struct HLine {
    /// Legend entry (the first line with a given label gets the legend entry).
    pub label: String,
    /// Height.
    pub y: f64,
}

/// A chart to render.
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    /// Title above the plot.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// Integer tick labels on the x axis (time steps).
    pub integer_x: bool,
    /// The series.
    pub series: Vec<Series>,
    /// Horizontal reference lines.
    pub hlines: Vec<HLine>,
    /// Where the legend goes (pick a corner the data leave empty).
    pub legend: Legend,
}

/// Legend placement inside the plot area.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Legend {
    /// Upper right corner.
    UpperRight,
    /// Middle of the right edge.
    MiddleRight,
    /// Lower left corner.
    LowerLeft,
}

impl Legend {
    fn position(self) -> SeriesLabelPosition {
        match self {
            Legend::UpperRight => SeriesLabelPosition::UpperRight,
            Legend::MiddleRight => SeriesLabelPosition::MiddleRight,
            Legend::LowerLeft => SeriesLabelPosition::LowerLeft,
        }
    }
}

/// Tick label of a log axis: plain for moderate magnitudes, else `1e-7` style.
pub fn log_tick(v: f64) -> String {
    let a = v.abs();
    if (1e-3..1e4).contains(&a) {
        let s = format!("{v:.3}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// Colours of the series: colour-blind-safe (Okabe–Ito), black first.
pub const PALETTE: [RGBColor; 6] = [
    RGBColor(0, 0, 0),
    RGBColor(0, 114, 178),
    RGBColor(230, 159, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
];
/// Colour of reference lines (the constraint bounds are red in the paper's Fig. 2(c)).
pub const BOUND_COLOR: RGBColor = RGBColor(200, 30, 30);

/// Chart size in pixels.
pub const SIZE: (u32, u32) = (640, 400);

/// An SVG document and how many points could not be drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendered {
    /// The SVG text.
    pub svg: String,
    /// Points left out (log y with y ≤ 0, or non-finite coordinates).
    pub dropped: usize,
}

fn drawable(log_y: bool, (x, y): (f64, f64)) -> bool {
    x.is_finite() && y.is_finite() && (!log_y || y > 0.0)
}

/// Splits a series into runs of drawable points (a gap breaks the line).
fn segments(points: &[(f64, f64)], log_y: bool) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut current = Vec::new();
    for &p in points {
        if drawable(log_y, p) {
            current.push(p);
        } else if !current.is_empty() {
            out.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// Axis ranges covering every drawable point and reference line, padded; on a log axis
/// rounded out to whole decades.
fn ranges(chart: &Chart) -> Result<((f64, f64), (f64, f64))> {
    let mut xs = (f64::INFINITY, f64::NEG_INFINITY);
    let mut ys = (f64::INFINITY, f64::NEG_INFINITY);
    let grow = |r: &mut (f64, f64), v: f64| {
        r.0 = r.0.min(v);
        r.1 = r.1.max(v);
    };
    for s in &chart.series {
        for &p in s.points.iter().filter(|&&p| drawable(chart.log_y, p)) {
            grow(&mut xs, p.0);
            grow(&mut ys, p.1);
        }
    }
    for h in chart
        .hlines
        .iter()
        .filter(|h| drawable(chart.log_y, (0.0, h.y)))
    {
        grow(&mut ys, h.y);
    }
    if !(xs.0.is_finite() && ys.0.is_finite()) {
        bail!(
            "chart `{}` has no drawable point (every value is missing, non-finite, or ≤ 0 on a log axis)",
            chart.title
        );
    }
    if xs.1 - xs.0 <= 0.0 {
        xs = (xs.0 - 0.5, xs.1 + 0.5);
    }
    if chart.log_y {
        let lo = 10f64.powf(ys.0.log10().floor());
        let mut hi = 10f64.powf(ys.1.log10().ceil());
        if hi <= lo {
            hi = lo * 10.0;
        }
        ys = (lo, hi);
    } else {
        let pad = if ys.1 > ys.0 {
            0.06 * (ys.1 - ys.0)
        } else {
            0.5 * ys.0.abs().max(1.0)
        };
        ys = (ys.0 - pad, ys.1 + pad);
    }
    Ok((xs, ys))
}

fn style(s: &Series) -> ShapeStyle {
    PALETTE[s.color % PALETTE.len()].stroke_width(2)
}

fn plot_err<E: std::fmt::Display>(title: &str) -> impl FnOnce(E) -> anyhow::Error + '_ {
    move |e| anyhow!("cannot draw chart `{title}`: {e}")
}

/// Draws the series and lines onto a chart context of either y coordinate type.
macro_rules! draw_body {
    ($ctx:expr, $chart:expr, $x_range:expr) => {{
        let chart: &Chart = $chart;
        let err = || plot_err(&chart.title);
        let mut mesh = $ctx.configure_mesh();
        mesh.x_desc(chart.x_label.as_str())
            .y_desc(chart.y_label.as_str())
            .max_light_lines(0)
            .bold_line_style(RGBColor(225, 225, 225))
            .label_style(("sans-serif", 13));
        let integer_fmt = |v: &f64| format!("{}", v.round());
        if chart.integer_x {
            mesh.x_label_formatter(&integer_fmt);
        }
        let log_fmt = |v: &f64| log_tick(*v);
        if chart.log_y {
            mesh.y_label_formatter(&log_fmt);
        }
        mesh.draw().map_err(err())?;
        for s in &chart.series {
            let st = style(s);
            let mut first = true;
            for seg in segments(&s.points, chart.log_y) {
                let anno = match s.pattern {
                    Pattern::Solid => $ctx
                        .draw_series(LineSeries::new(seg.iter().copied(), st))
                        .map_err(err())?,
                    Pattern::Dashed => $ctx
                        .draw_series(DashedLineSeries::new(seg.iter().copied(), 7, 4, st))
                        .map_err(err())?,
                };
                if first {
                    // Two strokes, touching (solid) or with a gap (dashed).
                    let gap = if s.pattern == Pattern::Dashed { 5 } else { 0 };
                    anno.label(s.label.as_str()).legend(move |(x, y)| {
                        EmptyElement::at((x, y))
                            + PathElement::new(vec![(0, 0), (9, 0)], st)
                            + PathElement::new(vec![(9 + gap, 0), (22, 0)], st)
                    });
                    first = false;
                }
                if s.markers {
                    $ctx.draw_series(seg.iter().map(|&p| Circle::new(p, 3, st.filled())))
                        .map_err(err())?;
                }
            }
        }
        let mut labelled: Vec<&str> = Vec::new();
        for h in chart
            .hlines
            .iter()
            .filter(|h| drawable(chart.log_y, (0.0, h.y)))
        {
            let st = BOUND_COLOR.stroke_width(2);
            let anno = $ctx
                .draw_series(DashedLineSeries::new(
                    [($x_range.0, h.y), ($x_range.1, h.y)],
                    10,
                    5,
                    st,
                ))
                .map_err(err())?;
            if !labelled.contains(&h.label.as_str()) {
                labelled.push(h.label.as_str());
                anno.label(h.label.as_str()).legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (9, 0)], st)
                        + PathElement::new(vec![(14, 0), (22, 0)], st)
                });
            }
        }
        $ctx.configure_series_labels()
            .position(chart.legend.position())
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(err())?;
    }};
}

/// Renders a chart as an SVG document.
///
/// Errors: no drawable point at all, or a drawing failure. (xtask is a binary crate, so
/// the examples are the unit tests below.)
pub fn render_svg(chart: &Chart) -> Result<Rendered> {
    let (xr, yr) = ranges(chart)?;
    let dropped = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|&&p| !drawable(chart.log_y, p))
        .count();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        let err = || plot_err(&chart.title);
        root.fill(&WHITE).map_err(err())?;
        let mut builder = ChartBuilder::on(&root);
        builder
            .caption(chart.title.as_str(), ("sans-serif", 17))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(if chart.log_y { 62 } else { 56 });
        if chart.log_y {
            let mut ctx = builder
                .build_cartesian_2d(xr.0..xr.1, (yr.0..yr.1).log_scale())
                .map_err(err())?;
            draw_body!(ctx, chart, xr);
        } else {
            let mut ctx = builder
                .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
                .map_err(err())?;
            draw_body!(ctx, chart, xr);
        }
        root.present().map_err(err())?;
    }
    Ok(Rendered { svg, dropped })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    fn line(label: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: label.into(),
            points,
            color: 1,
            pattern: Pattern::Solid,
            markers: false,
        }
    }

    fn chart(log_y: bool, series: Vec<Series>) -> Chart {
        Chart {
            title: "test".into(),
            x_label: "t".into(),
            y_label: "y".into(),
            log_y,
            integer_x: true,
            series,
            hlines: vec![],
            legend: Legend::UpperRight,
        }
    }

    #[test]
    fn log_ticks_are_short() {
        assert_eq!(log_tick(1e-7), "1e-7");
        assert_eq!(log_tick(1e-15), "1e-15");
        assert_eq!(log_tick(0.001), "0.001");
        assert_eq!(log_tick(0.1), "0.1");
        assert_eq!(log_tick(10.0), "10");
        assert_eq!(log_tick(100000.0), "1e5");
    }

    #[test]
    fn renders_lines_legend_and_bounds() {
        let mut c = chart(
            false,
            vec![
                line(
                    "x₁",
                    (0..10).map(|t| (t as f64, (t as f64).sin())).collect(),
                ),
                Series {
                    pattern: Pattern::Dashed,
                    markers: true,
                    color: 2,
                    ..line("x̂₁", (0..10).map(|t| (t as f64, 0.5)).collect())
                },
            ],
        );
        c.hlines = vec![
            HLine {
                label: "bound of 𝒲".into(),
                y: 0.1,
            },
            HLine {
                label: "bound of 𝒲".into(),
                y: -0.1,
            },
        ];
        let r = render_svg(&c).unwrap();
        assert_eq!(r.dropped, 0);
        assert!(r.svg.starts_with("<svg"), "{}", &r.svg[..60]);
        assert!(r.svg.contains("x₁") && r.svg.contains("x̂₁"));
        // The bound is labelled once in the legend.
        assert_eq!(r.svg.matches("bound of 𝒲").count(), 1);
        // 10 markers.
        assert_eq!(r.svg.matches("<circle").count(), 10);
        assert!(r.svg.contains("#C81E1E"));
    }

    #[test]
    fn log_axis_breaks_lines_at_nonpositive_values() {
        let pts = vec![
            (0.0, 0.0),
            (1.0, 1e-3),
            (2.0, 1e-1),
            (3.0, -1.0),
            (4.0, 2.0),
        ];
        let segs = segments(&pts, true);
        assert_eq!(segs, vec![vec![(1.0, 1e-3), (2.0, 1e-1)], vec![(4.0, 2.0)]]);
        let r = render_svg(&chart(true, vec![line("ε", pts.clone())])).unwrap();
        assert_eq!(r.dropped, 2);
        // Linear axes keep every finite point.
        assert_eq!(segments(&pts, false).len(), 1);
        let ((x0, x1), (y0, y1)) = ranges(&chart(true, vec![line("ε", pts)])).unwrap();
        assert_eq!((x0, x1), (1.0, 4.0));
        assert_eq!((y0, y1), (1e-3, 10.0)); // whole decades around [1e-3, 2]
    }

    #[test]
    fn empty_chart_is_an_error() {
        let e = render_svg(&chart(true, vec![line("ε", vec![(0.0, 0.0)])])).unwrap_err();
        assert!(e.to_string().contains("no drawable point"), "{e}");
        let e = render_svg(&chart(false, vec![])).unwrap_err();
        assert!(e.to_string().contains("no drawable point"), "{e}");
    }

    #[test]
    fn single_point_gets_a_nonempty_range() {
        let ((x0, x1), (y0, y1)) =
            ranges(&chart(false, vec![line("a", vec![(3.0, 2.0)])])).unwrap();
        assert!(x0 < 3.0 && 3.0 < x1 && y0 < 2.0 && 2.0 < y1);
    }
}
