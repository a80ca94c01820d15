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
    /// No legend (the other panels of a [`Grid`]: the first one carries it).
    Hidden,
}

impl Legend {
    fn position(self) -> Option<SeriesLabelPosition> {
        match self {
            Legend::UpperRight => Some(SeriesLabelPosition::UpperRight),
            Legend::MiddleRight => Some(SeriesLabelPosition::MiddleRight),
            Legend::LowerLeft => Some(SeriesLabelPosition::LowerLeft),
            Legend::Hidden => None,
        }
    }
}

/// Small multiples: one [`Chart`] per panel on a grid (e.g. one panel per state), under one
/// title and one legend (the first panel's series and lines; give the series labels that
/// hold for every panel), with an optional note below (e.g. that panels were left out).
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Title above the panels.
    pub title: String,
    /// The panels, row by row.
    pub panels: Vec<Chart>,
    /// A line of text under the panels.
    pub note: Option<String>,
}

/// Most panels a [`Grid`] draws (4 × 4); callers cap their panels at this and say so.
pub const MAX_PANELS: usize = 16;

/// Panel size in a grid of more than one panel.
pub const PANEL_SIZE: (u32, u32) = (400, 260);

/// (rows, columns) of a grid of `n` panels: at most 4 columns, as square as possible.
pub fn grid_shape(n: usize) -> (usize, usize) {
    let n = n.max(1);
    let mut cols = 1;
    while cols * cols < n && cols < 4 {
        cols += 1;
    }
    (n.div_ceil(cols), cols)
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
        if let Some(position) = chart.legend.position() {
            $ctx.configure_series_labels()
                .position(position)
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(160, 160, 160))
                .label_font(("sans-serif", 13))
                .draw()
                .map_err(err())?;
        }
    }};
}

/// Points of `chart` that cannot be drawn.
fn dropped(chart: &Chart) -> usize {
    chart
        .series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|&&p| !drawable(chart.log_y, p))
        .count()
}

/// Draws `chart` into `area` (a whole document or one panel); `caption` is the title's font
/// size.
fn draw_chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    chart: &Chart,
    caption: u32,
) -> Result<()> {
    let (xr, yr) = ranges(chart)?;
    let err = || plot_err(&chart.title);
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(chart.title.as_str(), ("sans-serif", caption))
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
    Ok(())
}

/// Renders a chart as an SVG document.
///
/// Errors: no drawable point at all, or a drawing failure. (xtask is a binary crate, so
/// the examples are the unit tests below.)
pub fn render_svg(chart: &Chart) -> Result<Rendered> {
    ranges(chart)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err(&chart.title))?;
        draw_chart(&root, chart, 17)?;
        root.present().map_err(plot_err(&chart.title))?;
    }
    Ok(Rendered {
        svg,
        dropped: dropped(chart),
    })
}

/// The legend of a grid: (label, line style, dashed) of the series and the distinct
/// reference lines of `chart`.
fn legend_entries(chart: &Chart) -> Vec<(String, ShapeStyle, bool)> {
    let mut out: Vec<(String, ShapeStyle, bool)> = chart
        .series
        .iter()
        .map(|s| (s.label.clone(), style(s), s.pattern == Pattern::Dashed))
        .collect();
    for h in &chart.hlines {
        if !out.iter().any(|(l, _, _)| *l == h.label) {
            out.push((h.label.clone(), BOUND_COLOR.stroke_width(2), true));
        }
    }
    out
}

/// (x, width, row) of each legend entry, left to right, wrapping at `width` (text width
/// estimated at 7.5 px per character of 13 px sans-serif).
fn place_legend(entries: &[(String, ShapeStyle, bool)], width: u32) -> Vec<(u32, u32, u32)> {
    let mut out = Vec::with_capacity(entries.len());
    let (mut x, mut row) = (16u32, 0u32);
    for (label, _, _) in entries {
        let w = 28 + (label.chars().count() as f64 * 7.5).ceil() as u32 + 24;
        if x > 16 && x + w > width {
            x = 16;
            row += 1;
        }
        out.push((x, w, row));
        x += w;
    }
    out
}

/// Renders small multiples as one SVG document: the panels on a [`grid_shape`] grid, a panel
/// without a drawable point says so in its place. At most [`MAX_PANELS`] panels are drawn
/// (callers cap and note it; more is an error here, never a silent cut).
///
/// Errors: no panel, more than [`MAX_PANELS`], no drawable point in any panel, or a drawing
/// failure.
pub fn render_grid_svg(grid: &Grid) -> Result<Rendered> {
    let n = grid.panels.len();
    if n == 0 || n > MAX_PANELS {
        bail!(
            "grid `{}` has {n} panels (1 to {MAX_PANELS} can be drawn)",
            grid.title
        );
    }
    if grid.panels.iter().all(|c| ranges(c).is_err()) {
        bail!(
            "grid `{}` has no drawable point (every value is missing, non-finite, or ≤ 0 on a log axis)",
            grid.title
        );
    }
    let (rows, cols) = grid_shape(n);
    let (pw, ph) = if n == 1 { SIZE } else { PANEL_SIZE };
    let width = pw * cols as u32;
    let entries = legend_entries(&grid.panels[0]);
    let placed = place_legend(&entries, width);
    let legend_h = placed.last().map_or(0, |(_, _, row)| 22 * (row + 1));
    let (title_h, note_h) = (34, if grid.note.is_some() { 26 } else { 0 });
    let size = (width, title_h + legend_h + ph * rows as u32 + note_h);
    let mut svg = String::new();
    {
        let err = || plot_err(&grid.title);
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(err())?;
        let (top, rest) = root.split_vertically(title_h);
        top.titled(grid.title.as_str(), ("sans-serif", 17))
            .map_err(err())?;
        let (legend, rest) = rest.split_vertically(legend_h);
        for ((label, st, dashed), (x, _, row)) in entries.iter().zip(&placed) {
            let (x, y) = (*x as i32, 11 + 22 * *row as i32);
            let gap = if *dashed { 5 } else { 0 };
            legend
                .draw(&PathElement::new(vec![(x, y), (x + 9, y)], *st))
                .map_err(err())?;
            legend
                .draw(&PathElement::new(vec![(x + 9 + gap, y), (x + 22, y)], *st))
                .map_err(err())?;
            legend
                .draw_text(
                    label,
                    &("sans-serif", 13).into_font().color(&BLACK),
                    (x + 28, y - 7),
                )
                .map_err(err())?;
        }
        let (body, bottom) = rest.split_vertically(ph * rows as u32);
        if let Some(note) = &grid.note {
            bottom
                .draw_text(note, &("sans-serif", 13).into_font().color(&BLACK), (12, 6))
                .map_err(err())?;
        }
        let cells = body.split_evenly((rows, cols));
        for (cell, chart) in cells.iter().zip(&grid.panels) {
            if ranges(chart).is_ok() {
                // The grid's legend replaces the panels' own.
                let panel = Chart {
                    legend: Legend::Hidden,
                    ..chart.clone()
                };
                draw_chart(cell, &panel, 14)?;
            } else {
                cell.titled(chart.title.as_str(), ("sans-serif", 14))
                    .map_err(err())?
                    .draw_text(
                        "no drawable point",
                        &("sans-serif", 13).into_font().color(&BLACK),
                        (20, 40),
                    )
                    .map_err(err())?;
            }
        }
        root.present().map_err(err())?;
    }
    Ok(Rendered {
        svg,
        dropped: grid.panels.iter().map(dropped).sum(),
    })
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
    fn grids_are_at_most_four_wide_and_square_when_possible() {
        assert_eq!(grid_shape(1), (1, 1));
        assert_eq!(grid_shape(2), (1, 2));
        assert_eq!(grid_shape(4), (2, 2));
        assert_eq!(grid_shape(5), (2, 3));
        assert_eq!(grid_shape(9), (3, 3));
        assert_eq!(grid_shape(12), (3, 4));
        assert_eq!(grid_shape(16), (4, 4));
    }

    #[test]
    fn grid_draws_every_panel_and_its_note() {
        let panel = |i: usize| Chart {
            title: format!("panel {i}"),
            legend: if i == 0 {
                Legend::UpperRight
            } else {
                Legend::Hidden
            },
            ..chart(
                false,
                vec![line(
                    &format!("s{i}"),
                    (0..5).map(|t| (t as f64, (i * t) as f64)).collect(),
                )],
            )
        };
        let mut panels: Vec<Chart> = (0..12).map(panel).collect();
        // A panel without data is drawn as a message, not an error.
        panels[11].series[0].points = vec![(0.0, f64::NAN)];
        let grid = Grid {
            title: "states".into(),
            panels,
            note: Some("12 of 40 drawn".into()),
        };
        let r = render_grid_svg(&grid).unwrap();
        assert_eq!(r.dropped, 1);
        for i in 0..12 {
            assert!(r.svg.contains(&format!("\npanel {i}\n")), "panel {i}");
        }
        assert!(r.svg.contains("12 of 40 drawn") && r.svg.contains("no drawable point"));
        // One legend for the grid: the first panel's series.
        assert_eq!(r.svg.matches("\ns0\n").count(), 1);
        assert!(!r.svg.contains("\ns1\n"));
        // 4 columns × 3 rows of 400 × 260, title, one legend row and the note.
        assert!(
            r.svg.contains(r#"width="1600" height="862""#),
            "{}",
            &r.svg[..120]
        );
        let too_many = Grid {
            panels: (0..=MAX_PANELS).map(panel).collect(),
            ..grid
        };
        assert!(render_grid_svg(&too_many).is_err());
    }

    #[test]
    fn single_point_gets_a_nonempty_range() {
        let ((x0, x1), (y0, y1)) =
            ranges(&chart(false, vec![line("a", vec![(3.0, 2.0)])])).unwrap();
        assert!(x0 < 3.0 && 3.0 < x1 && y0 < 2.0 && 2.0 < y1);
    }
}
