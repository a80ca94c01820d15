//! Line charts as SVG (plotters, SVG backend, no font files): one [`Chart`], or small
//! multiples on a [`Grid`] under one title and one legend.
//!
//! A [`Chart`] is plain data (series of (x, y) points, horizontal reference lines, axis
//! labels, linear or log y), so the code that extracts the data is separate from the drawing
//! and both can be tested on their own. On a log axis, points with y ≤ 0 or non-finite y
//! cannot be drawn: the line is broken there and [`render_svg`] reports how many points it
//! left out ([`Rendered::dropped`]); callers put that in the caption.

use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::PlotError;

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

/// Chart size in pixels.
pub const SIZE: (u32, u32) = (640, 400);

/// Colours of the series as RGB: colour-blind-safe (Okabe–Ito), black first.
pub const PALETTE: [(u8, u8, u8); 6] = [
    (0, 0, 0),
    (0, 114, 178),
    (230, 159, 0),
    (0, 158, 115),
    (204, 121, 167),
    (86, 180, 233),
];

/// Colour of reference lines (the constraint bounds are red in the paper's Fig. 2(c)).
const BOUND_COLOR: RGBColor = RGBColor(200, 30, 30);

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

/// An SVG document and how many points could not be drawn.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
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

/// The smallest and largest drawable x and y of `chart` (y including the reference lines);
/// infinite when there is none.
fn extent(chart: &Chart) -> ((f64, f64), (f64, f64)) {
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
    (xs, ys)
}

/// (x range, y range) of a chart.
type XyRanges = ((f64, f64), (f64, f64));

/// Axis ranges covering every drawable point and reference line, padded; on a log axis
/// rounded out to whole decades.
fn ranges(chart: &Chart) -> Result<XyRanges, PlotError> {
    let (mut xs, mut ys) = extent(chart);
    if !(xs.0.is_finite() && ys.0.is_finite()) {
        return Err(PlotError::NoDrawablePoint {
            kind: "chart",
            title: chart.title.clone(),
        });
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

fn palette(i: usize) -> RGBColor {
    let (r, g, b) = PALETTE[i % PALETTE.len()];
    RGBColor(r, g, b)
}

fn style(s: &Series) -> ShapeStyle {
    palette(s.color).stroke_width(2)
}

/// The error of a drawing call in the chart titled `title`.
fn plot_err<E: std::fmt::Display>(title: &str) -> impl FnOnce(E) -> PlotError + '_ {
    move |e| PlotError::drawing(&format!("cannot draw chart `{title}`"), e)
}

/// A chart's plotting context: linear x, linear or log y.
type Ctx<'a, DB, Y> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, Y>>;

/// Grid lines, tick labels and axis labels.
fn draw_mesh<'a, DB: DrawingBackend + 'a, Y>(
    ctx: &mut Ctx<'a, DB, Y>,
    chart: &Chart,
) -> Result<(), PlotError>
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let mut mesh = ctx.configure_mesh();
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
    mesh.draw().map_err(plot_err(&chart.title))
}

/// One series: its drawable runs (solid or dashed), the legend entry on the first run, the
/// markers.
fn draw_series<'a, DB: DrawingBackend + 'a, Y>(
    ctx: &mut Ctx<'a, DB, Y>,
    chart: &Chart,
    s: &Series,
) -> Result<(), PlotError>
where
    Y: Ranged<ValueType = f64>,
{
    let err = || plot_err(&chart.title);
    let st = style(s);
    let mut first = true;
    for seg in segments(&s.points, chart.log_y) {
        let anno = match s.pattern {
            Pattern::Solid => ctx
                .draw_series(LineSeries::new(seg.iter().copied(), st))
                .map_err(err())?,
            Pattern::Dashed => ctx
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
            ctx.draw_series(seg.iter().map(|&p| Circle::new(p, 3, st.filled())))
                .map_err(err())?;
        }
    }
    Ok(())
}

/// The reference lines across `x_range`, dashed red; one legend entry per label.
fn draw_hlines<'a, DB: DrawingBackend + 'a, Y>(
    ctx: &mut Ctx<'a, DB, Y>,
    chart: &Chart,
    x_range: (f64, f64),
) -> Result<(), PlotError>
where
    Y: Ranged<ValueType = f64>,
{
    let mut labelled: Vec<&str> = Vec::new();
    for h in chart
        .hlines
        .iter()
        .filter(|h| drawable(chart.log_y, (0.0, h.y)))
    {
        let st = BOUND_COLOR.stroke_width(2);
        let anno = ctx
            .draw_series(DashedLineSeries::new(
                [(x_range.0, h.y), (x_range.1, h.y)],
                10,
                5,
                st,
            ))
            .map_err(plot_err(&chart.title))?;
        if !labelled.contains(&h.label.as_str()) {
            labelled.push(h.label.as_str());
            anno.label(h.label.as_str()).legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (9, 0)], st)
                    + PathElement::new(vec![(14, 0), (22, 0)], st)
            });
        }
    }
    Ok(())
}

/// Draws the mesh, series, lines and legend onto a chart context of either y coordinate
/// type.
fn draw_body<'a, DB: DrawingBackend + 'a, Y>(
    ctx: &mut Ctx<'a, DB, Y>,
    chart: &Chart,
    x_range: (f64, f64),
) -> Result<(), PlotError>
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    draw_mesh(ctx, chart)?;
    for s in &chart.series {
        draw_series(ctx, chart, s)?;
    }
    draw_hlines(ctx, chart, x_range)?;
    if let Some(position) = chart.legend.position() {
        ctx.configure_series_labels()
            .position(position)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(plot_err(&chart.title))?;
    }
    Ok(())
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
    area: &DrawingArea<DB, Shift>,
    chart: &Chart,
    caption: u32,
) -> Result<(), PlotError> {
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
        draw_body(&mut ctx, chart, xr)
    } else {
        let mut ctx = builder
            .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
            .map_err(err())?;
        draw_body(&mut ctx, chart, xr)
    }
}

/// Renders a chart as an SVG document.
///
/// Errors: no drawable point at all, or a drawing failure.
///
/// ```
/// use mhe_plots::chart::{render_svg, Chart, Legend, Pattern, Series};
/// let chart = Chart {
///     title: "decay".into(),
///     x_label: "t".into(),
///     y_label: "‖e_t‖".into(),
///     log_y: true,
///     integer_x: true,
///     series: vec![Series {
///         label: "‖e_t‖".into(),
///         points: (0..20).map(|t| (t as f64, 0.5f64.powi(t))).collect(),
///         color: 1,
///         pattern: Pattern::Solid,
///         markers: false,
///     }],
///     hlines: vec![],
///     legend: Legend::UpperRight,
/// };
/// let r = render_svg(&chart)?;
/// assert!(r.svg.starts_with("<svg") && r.dropped == 0);
/// # Ok::<(), mhe_plots::PlotError>(())
/// ```
pub fn render_svg(chart: &Chart) -> Result<Rendered, PlotError> {
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

/// One entry of a grid's legend: label, line style, dashed.
type Entry = (String, ShapeStyle, bool);

/// The legend of a grid: the series and the distinct reference lines of `chart`.
fn legend_entries(chart: &Chart) -> Vec<Entry> {
    let mut out: Vec<Entry> = chart
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
fn place_legend(entries: &[Entry], width: u32) -> Vec<(u32, u32, u32)> {
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

/// The grid's legend in its band under the title.
fn draw_grid_legend<DB: DrawingBackend>(
    legend: &DrawingArea<DB, Shift>,
    grid: &Grid,
    entries: &[Entry],
    placed: &[(u32, u32, u32)],
) -> Result<(), PlotError> {
    let err = || plot_err(&grid.title);
    for ((label, st, dashed), (x, _, row)) in entries.iter().zip(placed) {
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
    Ok(())
}

/// One panel of a grid: the chart without its own legend, or a message when it has no
/// drawable point.
fn draw_panel<DB: DrawingBackend>(
    cell: &DrawingArea<DB, Shift>,
    grid: &Grid,
    chart: &Chart,
) -> Result<(), PlotError> {
    if ranges(chart).is_ok() {
        // The grid's legend replaces the panels' own.
        let panel = Chart {
            legend: Legend::Hidden,
            ..chart.clone()
        };
        return draw_chart(cell, &panel, 14);
    }
    let err = || plot_err(&grid.title);
    cell.titled(chart.title.as_str(), ("sans-serif", 14))
        .map_err(err())?
        .draw_text(
            "no drawable point",
            &("sans-serif", 13).into_font().color(&BLACK),
            (20, 40),
        )
        .map_err(err())
}

/// Checks a grid can be drawn: 1 to [`MAX_PANELS`] panels, a drawable point somewhere.
fn check_grid(grid: &Grid) -> Result<(), PlotError> {
    let n = grid.panels.len();
    if n == 0 || n > MAX_PANELS {
        return Err(PlotError::PanelCount {
            title: grid.title.clone(),
            panels: n,
        });
    }
    if grid.panels.iter().all(|c| ranges(c).is_err()) {
        return Err(PlotError::NoDrawablePoint {
            kind: "grid",
            title: grid.title.clone(),
        });
    }
    Ok(())
}

/// Renders small multiples as one SVG document: the panels on a [`grid_shape`] grid, a panel
/// without a drawable point says so in its place. At most [`MAX_PANELS`] panels are drawn
/// (callers cap and note it; more is an error here, never a silent cut).
///
/// Errors: no panel, more than [`MAX_PANELS`], no drawable point in any panel, or a drawing
/// failure.
pub fn render_grid_svg(grid: &Grid) -> Result<Rendered, PlotError> {
    check_grid(grid)?;
    let n = grid.panels.len();
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
        draw_grid_legend(&legend, grid, &entries, &placed)?;
        let (body, bottom) = rest.split_vertically(ph * rows as u32);
        if let Some(note) = &grid.note {
            bottom
                .draw_text(note, &("sans-serif", 13).into_font().color(&BLACK), (12, 6))
                .map_err(err())?;
        }
        let cells = body.split_evenly((rows, cols));
        for (cell, chart) in cells.iter().zip(&grid.panels) {
            draw_panel(cell, grid, chart)?;
        }
        root.present().map_err(err())?;
    }
    Ok(Rendered {
        svg,
        dropped: grid.panels.iter().map(dropped).sum(),
    })
}

#[cfg(test)]
#[path = "chart_tests.rs"]
mod tests;
