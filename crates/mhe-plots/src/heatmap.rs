//! Heat maps of a value over the (K_e, K_c) grid of a 2-D sweep, with three region
//! boundaries as staircases: the empirical one (solid black), the linear one (dashed
//! magenta), the certified one (dash-dot orange), and the regional certificate's pairs as
//! green dots; a colour bar on the right, the legend and notes under the chart.
//!
//! Cells are drawn on log axes when a grid is closer to geometric than to arithmetic spacing
//! ([`Axis::new`]), with one cell per grid value and edges halfway between neighbours (in
//! log K for a log axis). A boundary at a grid K_c runs along the lower edge of that K_c's
//! cells: the region is the cells above and to the right of it.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::{PlotError, shorten, three_digits};

/// A region boundary: per K_e, the smallest K_c of the region (`None`: no K_c at that K_e).
pub type Staircase = Vec<(usize, Option<usize>)>;

/// One axis of the grid: its values and whether cells are spaced in log K.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    values: Vec<usize>,
    log: bool,
    /// Cell edges in axis coordinates (values.len() + 1 of them).
    edges: Vec<f64>,
}

impl Axis {
    /// An axis over the sorted, distinct `values`, on a log scale when the grid's log
    /// steps are more uniform than its linear steps (the relative spread of the steps,
    /// max/min, is compared; a tie or a grid of fewer than 3 values spanning less than a
    /// factor 10 is linear).
    pub fn new(values: &[usize]) -> Self {
        let mut values = values.to_vec();
        values.sort_unstable();
        values.dedup();
        let log = Self::is_geometric(&values);
        let mut axis = Self {
            values,
            log,
            edges: Vec::new(),
        };
        let t: Vec<f64> = axis.values.iter().map(|&v| axis.t(v as f64)).collect();
        axis.edges = match t.len() {
            0 => vec![0.0, 1.0],
            1 => vec![t[0] - 0.5, t[0] + 0.5],
            n => {
                let mut e = vec![t[0] - (t[1] - t[0]) / 2.0];
                e.extend(t.windows(2).map(|w| (w[0] + w[1]) / 2.0));
                e.push(t[n - 1] + (t[n - 1] - t[n - 2]) / 2.0);
                e
            }
        };
        axis
    }

    /// Whether sorted, distinct `values` are closer to geometric than arithmetic spacing.
    fn is_geometric(values: &[usize]) -> bool {
        let spread = |v: &[f64]| {
            let steps: Vec<f64> = v.windows(2).map(|w| w[1] - w[0]).collect();
            let lo = steps.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = steps.iter().copied().fold(0.0, f64::max);
            if lo > 0.0 { hi / lo } else { f64::INFINITY }
        };
        let lin: Vec<f64> = values.iter().map(|&v| v as f64).collect();
        let logs: Vec<f64> = lin.iter().map(|v| v.max(1.0).ln()).collect();
        match values.len() {
            0 | 1 => false,
            2 => lin[1] >= 10.0 * lin[0],
            _ => spread(&logs) < spread(&lin),
        }
    }

    /// The grid values, sorted and distinct.
    pub fn values(&self) -> &[usize] {
        &self.values
    }

    /// Whether cells are spaced in log K.
    pub fn is_log(&self) -> bool {
        self.log
    }

    /// The axis coordinate of a value.
    fn t(&self, v: f64) -> f64 {
        if self.log { v.max(1e-300).ln() } else { v }
    }

    fn lo(&self) -> f64 {
        self.edges[0]
    }

    fn hi(&self) -> f64 {
        self.edges[self.edges.len() - 1]
    }

    /// Where a region starting at `v` begins on this axis: the lower edge of v's cell for
    /// a grid value, v itself otherwise; clamped to the axis (the flag says it was).
    fn edge_below(&self, v: usize) -> (f64, bool) {
        match self.values.iter().position(|&g| g == v) {
            Some(i) => (self.edges[i], false),
            None => {
                let t = self.t(v as f64);
                let c = t.clamp(self.lo(), self.hi());
                (c, c != t)
            }
        }
    }

    /// The tick positions (a grid value per cell, thinned to at most 12 labels).
    fn ticks(&self) -> Vec<f64> {
        let step = self.values.len().div_ceil(12).max(1);
        self.values
            .iter()
            .step_by(step)
            .map(|&v| self.t(v as f64))
            .collect()
    }

    /// The label of a tick: the grid value nearest to `t`.
    fn label(&self, t: f64) -> String {
        self.values
            .iter()
            .min_by(|a, b| {
                (self.t(**a as f64) - t)
                    .abs()
                    .total_cmp(&(self.t(**b as f64) - t).abs())
            })
            .map_or_else(String::new, |v| v.to_string())
    }

    fn describe(&self, name: &str) -> String {
        format!("{name} ({} scale)", if self.log { "log" } else { "linear" })
    }

    /// The plot coordinate over the axis's cells.
    fn coord(&self) -> CellCoord {
        CellCoord {
            lo: self.lo(),
            hi: self.hi(),
            ticks: self.ticks(),
        }
    }
}

/// A linear plot coordinate over [lo, hi] whose ticks are the grid's cells (plotters'
/// `f64` ranges choose round numbers instead).
#[derive(Debug, Clone)]
struct CellCoord {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
}

impl Ranged for CellCoord {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let s = if self.hi > self.lo {
            (value - self.lo) / (self.hi - self.lo)
        } else {
            0.5
        };
        limit.0 + (s * f64::from(limit.1 - limit.0)).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, _hint: Hint) -> Vec<f64> {
        self.ticks.clone()
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

/// How values map to colours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ColorScale {
    /// Viridis from `lo` to `hi` on a linear scale (e.g. a fraction: 0 to 1).
    Linear {
        /// The value at the bottom of the bar.
        lo: f64,
        /// The value at the top of the bar.
        hi: f64,
    },
    /// Viridis from `lo` to `hi` on a log scale (e.g. an error).
    Log {
        /// The value at the bottom of the bar (> 0).
        lo: f64,
        /// The value at the top of the bar.
        hi: f64,
    },
    /// Blue below 1, white at 1, red above, in log v clipped at `e^±span` (e.g. ρ_lin).
    AroundOne {
        /// Half the width of the bar in log v.
        span: f64,
    },
}

/// Viridis at s ∈ [0, 1] (piecewise linear through 9 samples of matplotlib's map).
fn viridis(s: f64) -> RGBColor {
    const V: [(u8, u8, u8); 9] = [
        (68, 1, 84),
        (71, 44, 122),
        (59, 81, 139),
        (44, 113, 142),
        (33, 144, 141),
        (39, 173, 129),
        (92, 200, 99),
        (170, 220, 50),
        (253, 231, 37),
    ];
    let x = s.clamp(0.0, 1.0) * 8.0;
    let i = (x.floor() as usize).min(7);
    let f = x - i as f64;
    let mix = |a: u8, b: u8| (f64::from(a) + f * (f64::from(b) - f64::from(a))).round() as u8;
    RGBColor(
        mix(V[i].0, V[i + 1].0),
        mix(V[i].1, V[i + 1].1),
        mix(V[i].2, V[i + 1].2),
    )
}

impl ColorScale {
    /// The colour of a finite value.
    fn color(&self, v: f64) -> RGBColor {
        match *self {
            ColorScale::Linear { lo, hi } => {
                viridis(if hi > lo { (v - lo) / (hi - lo) } else { 0.5 })
            }
            ColorScale::Log { lo, hi } => {
                let (a, b) = (lo.ln(), hi.ln());
                viridis(if b > a && v > 0.0 {
                    (v.ln() - a) / (b - a)
                } else {
                    0.5
                })
            }
            ColorScale::AroundOne { span } => {
                let s = (v.max(1e-300).ln() / span).clamp(-1.0, 1.0);
                let toward = |c: u8, s: f64| (255.0 + s * (f64::from(c) - 255.0)).round() as u8;
                if s < 0.0 {
                    RGBColor(toward(33, -s), toward(102, -s), toward(172, -s))
                } else {
                    RGBColor(toward(178, s), toward(24, s), toward(43, s))
                }
            }
        }
    }

    /// The value at fraction s ∈ [0, 1] of the colour bar.
    fn value_at(&self, s: f64) -> f64 {
        match *self {
            ColorScale::Linear { lo, hi } => lo + s * (hi - lo),
            ColorScale::Log { lo, hi } => (lo.ln() + s * (hi.ln() - lo.ln())).exp(),
            ColorScale::AroundOne { span } => ((2.0 * s - 1.0) * span).exp(),
        }
    }
}

/// Colour of a cell without a finite value: diverged (+∞) dark grey, missing light grey.
const INFINITE_CELL: RGBColor = RGBColor(60, 60, 60);
const MISSING_CELL: RGBColor = RGBColor(215, 215, 215);
/// The boundaries: empirical solid black, linear dashed magenta, certified dash-dot orange.
const EMPIRICAL: RGBColor = RGBColor(0, 0, 0);
const LINEAR: RGBColor = RGBColor(220, 0, 200);
const CERTIFIED: RGBColor = RGBColor(255, 140, 0);
/// The regional certificate's pairs (K_reg, K_c): green dots.
const REGIONAL: RGBColor = RGBColor(0, 170, 60);

/// One heat map (data only); [`HeatMap::svg`] renders it.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatMap {
    /// Title above the chart.
    pub title: String,
    /// What the colour shows (the colour bar's label).
    pub value_label: String,
    /// The x axis.
    pub k_e: Axis,
    /// The y axis.
    pub k_c: Axis,
    /// `values[i][j]` at (K_e index i, K_c index j); `None`: missing (light grey); +∞:
    /// diverged (dark grey).
    pub values: Vec<Vec<Option<f64>>>,
    /// How values map to colours.
    pub scale: ColorScale,
    /// The empirical region's boundary.
    pub empirical: Staircase,
    /// The linear region's boundary; `None`: the linear analysis is not available.
    pub linear: Option<Staircase>,
    /// The certified region's boundary; empty: not computed.
    pub certified: Staircase,
    /// (K_c, K_reg) per grid K_c: a dot at (K_reg, K_c) where there is one.
    pub regional: Vec<(usize, Option<usize>)>,
    /// Lines of text under the chart (more are added for what the map cannot show).
    pub notes: Vec<String>,
}

/// A staircase as polylines in axis coordinates: entry k spans from its K_e's left edge to
/// the next entry's (the last to the right edge of the plot) at the lower edge of its K_c;
/// a K_e without a K_c leaves a gap (the region's side drawn up to the top edge).
fn staircase_paths(st: &[(usize, Option<usize>)], x: &Axis, y: &Axis) -> Paths {
    let mut st = st.to_vec();
    st.sort_by_key(|s| s.0);
    let top = y.hi();
    let mut clamped = false;
    let mut paths: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    for (n, &(ke, kc)) in st.iter().enumerate() {
        let (x_lo, cx) = x.edge_below(ke);
        let x_hi = st.get(n + 1).map_or(x.hi(), |next| x.edge_below(next.0).0);
        clamped |= cx;
        match kc {
            Some(kc) => {
                let (yv, cy) = y.edge_below(kc);
                clamped |= cy;
                if cur.is_empty() && n > 0 {
                    cur.push((x_lo, top));
                }
                cur.push((x_lo, yv));
                cur.push((x_hi, yv));
            }
            None => {
                if let Some(&(px, _)) = cur.last() {
                    cur.push((px, top));
                    paths.push(std::mem::take(&mut cur));
                }
            }
        }
    }
    if !cur.is_empty() {
        paths.push(cur);
    }
    (paths, clamped)
}

/// A tick or cell label with at most 3 significant digits (0.6, 1000, 2.5e-5), +∞ as `∞`.
fn number(v: f64) -> String {
    if v == f64::INFINITY {
        "∞".into()
    } else {
        three_digits(v)
    }
}

/// How a boundary is stroked.
#[derive(Debug, Clone, Copy)]
enum Line {
    Solid,
    /// Dash and gap lengths in pixels.
    Dashed(u32, u32),
}

/// One legend entry under the chart.
struct LegendEntry {
    label: String,
    color: RGBAColor,
    width: u32,
    line: Line,
}

/// A staircase's polylines in axis coordinates and whether it was clamped to the grid.
type Paths = (Vec<Vec<(f64, f64)>>, bool);

/// A boundary to draw: its polylines (`None`: not available), stroke, colour, width, its
/// legend label, and the label when there is nothing to draw.
type Boundary = (Option<Paths>, Line, RGBColor, u32, String, String);

/// What is drawn over the cells, with the notes it adds.
struct Overlays {
    boundaries: [Boundary; 3],
    /// The regional certificate's pairs in axis coordinates.
    dots: Vec<(f64, f64)>,
    notes: Vec<String>,
}

/// The heat map's plotting context.
type Ctx<'a, DB> = ChartContext<'a, DB, Cartesian2d<CellCoord, CellCoord>>;

/// The chart's size in pixels without the notes, and the colour bar's width.
const SIZE: (u32, u32) = (980, 640);
const BAR_WIDTH: u32 = 120;

impl HeatMap {
    /// Renders the heat map as SVG text (`name` for messages).
    ///
    /// ```
    /// use mhe_plots::heatmap::{Axis, ColorScale, HeatMap};
    /// let map = HeatMap {
    ///     title: "bounded".into(),
    ///     value_label: "bounded fraction".into(),
    ///     k_e: Axis::new(&[1, 10, 100]),
    ///     k_c: Axis::new(&[1, 5]),
    ///     values: vec![vec![Some(0.0), Some(0.5)], vec![Some(1.0), Some(1.0)], vec![Some(1.0), None]],
    ///     scale: ColorScale::Linear { lo: 0.0, hi: 1.0 },
    ///     empirical: vec![(1, None), (10, Some(1))],
    ///     linear: None,
    ///     certified: vec![],
    ///     regional: vec![],
    ///     notes: vec![],
    /// };
    /// let svg = map.svg("bounded.svg")?;
    /// assert!(svg.contains("certificate: not computed"));
    /// # Ok::<(), mhe_plots::PlotError>(())
    /// ```
    pub fn svg(&self, name: &str) -> Result<String, PlotError> {
        let context = format!("heat map `{name}`");
        let err = |e: &dyn std::fmt::Display| PlotError::drawing(&context, e);
        let Overlays {
            boundaries,
            dots,
            mut notes,
        } = self.overlays();
        // The legend row, the notes (one may be added below).
        let note_h = 30 + 17 * (notes.len() as u32 + 1);
        let (w, h) = SIZE;
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (w, h + note_h)).into_drawing_area();
            root.fill(&WHITE).map_err(|e| err(&e))?;
            let (upper, lower) = root.split_vertically(h);
            let (main, bar) = upper.split_horizontally(w - BAR_WIDTH);
            let mut chart = self.chart(&main, &context)?;
            self.draw_cells(&mut chart, &context)?;
            let legend = draw_boundaries(&mut chart, boundaries, &context)?;
            draw_dots(&mut chart, &dots, &context)?;
            let bottom = self.k_c.values.first().copied();
            if !self.empirical.is_empty() && self.empirical.iter().all(|s| s.1 == bottom) {
                notes.insert(
                    0,
                    "empirical region: the whole grid (its boundary is the axes)".into(),
                );
            }
            self.draw_bar(&bar).map_err(|e| err(&e))?;
            draw_legend(&lower, &legend, &notes).map_err(|e| err(&e))?;
            root.present().map_err(|e| err(&e))?;
        }
        Ok(svg)
    }

    /// The boundaries' paths and the regional dots, and the notes on what the map cannot
    /// show (boundaries clamped to the grid, missing and diverged cells).
    fn overlays(&self) -> Overlays {
        let mut notes = self.notes.clone();
        let (emp_paths, emp_clamped) = staircase_paths(&self.empirical, &self.k_e, &self.k_c);
        let lin = self
            .linear
            .as_ref()
            .map(|st| staircase_paths(st, &self.k_e, &self.k_c));
        let (cert_paths, cert_clamped) = staircase_paths(&self.certified, &self.k_e, &self.k_c);
        if emp_clamped || lin.as_ref().is_some_and(|l| l.1) {
            notes.push("a boundary passes outside the grid and is drawn at its edge".into());
        }
        if cert_clamped {
            notes.push(
                "the certified region extends beyond the grid: drawn at the grid's edge".into(),
            );
        }
        let cells = self.values.iter().flatten();
        let missing = cells.clone().filter(|v| v.is_none()).count();
        let infinite = cells.filter(|v| v.is_some_and(|v| !v.is_finite())).count();
        if missing > 0 {
            notes.push(format!("{missing} cells without a value (light grey)"));
        }
        let dots = self.regional_dots();
        if !dots.is_empty() {
            notes.push(
                "green dots: (K_reg, K_c), the regional certificate at that pair (for the scenario's own set)"
                    .into(),
            );
        }
        if infinite > 0 {
            notes.push(format!("{infinite} cells not finite (dark grey: diverged)"));
        }
        let boundaries = self.boundaries(emp_paths, emp_clamped, lin, cert_paths, cert_clamped);
        Overlays {
            boundaries,
            dots,
            notes,
        }
    }

    /// The three boundaries with their styles and legend labels.
    fn boundaries(
        &self,
        emp_paths: Vec<Vec<(f64, f64)>>,
        emp_clamped: bool,
        lin: Option<Paths>,
        cert_paths: Vec<Vec<(f64, f64)>>,
        cert_clamped: bool,
    ) -> [Boundary; 3] {
        [
            (
                Some((emp_paths, emp_clamped)),
                Line::Solid,
                EMPIRICAL,
                4,
                "empirical: every run bounded from here up".to_string(),
                if self.empirical.iter().all(|s| s.1.is_none()) {
                    "empirical: no all-bounded region on the grid".to_string()
                } else {
                    String::new()
                },
            ),
            (
                lin,
                Line::Dashed(10, 6),
                LINEAR,
                3,
                "linear: ρ_lin < 1 from here up".to_string(),
                if self.linear.is_none() {
                    "linear: not computed".to_string()
                } else {
                    "linear: ρ_lin ≥ 1 at the largest pair".to_string()
                },
            ),
            (
                Some((cert_paths, cert_clamped)),
                Line::Dashed(4, 4),
                CERTIFIED,
                3,
                "certified: joint certificate from here up".to_string(),
                if self.certified.is_empty() {
                    "certificate: not computed".to_string()
                } else {
                    "certified: no pair on the grid".to_string()
                },
            ),
        ]
    }

    /// (K_reg, K_c) of the regional certificate in axis coordinates, at the middle of the
    /// K_c's cells (K_reg clamped to the grid).
    fn regional_dots(&self) -> Vec<(f64, f64)> {
        self.regional
            .iter()
            .filter_map(|&(k_c, k_reg)| {
                let j = self.k_c.values.iter().position(|&v| v == k_c)?;
                let x = self
                    .k_e
                    .t(k_reg? as f64)
                    .clamp(self.k_e.lo(), self.k_e.hi());
                Some((x, (self.k_c.edges[j] + self.k_c.edges[j + 1]) / 2.0))
            })
            .collect()
    }

    /// The chart over the cells with its title, axes and tick labels.
    fn chart<'a, DB: DrawingBackend>(
        &self,
        main: &'a DrawingArea<DB, Shift>,
        context: &str,
    ) -> Result<Ctx<'a, DB>, PlotError> {
        let err = |e: &dyn std::fmt::Display| PlotError::drawing(context, e);
        let mut chart = ChartBuilder::on(main)
            .caption(&self.title, ("sans-serif", 17))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d(self.k_e.coord(), self.k_c.coord())
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(self.k_e.describe("K_e: iterations of the MHE's Φ per step"))
            .y_desc(self.k_c.describe("K_c: iterations of the MPC's Φ per step"))
            .x_label_formatter(&|t: &f64| self.k_e.label(*t))
            .y_label_formatter(&|t: &f64| self.k_c.label(*t))
            .draw()
            .map_err(|e| err(&e))?;
        Ok(chart)
    }

    /// The cells, with their value written in when there is room (at most 14 × 14).
    fn draw_cells<'a, DB: DrawingBackend + 'a>(
        &self,
        chart: &mut Ctx<'a, DB>,
        context: &str,
    ) -> Result<(), PlotError> {
        let (nx, ny) = (self.k_e.values.len(), self.k_c.values.len());
        let write_values = nx <= 14 && ny <= 14;
        for i in 0..nx {
            for j in 0..ny {
                let v = self.values.get(i).and_then(|r| r.get(j)).copied().flatten();
                let color = match v {
                    None => MISSING_CELL,
                    Some(v) if !v.is_finite() => INFINITE_CELL,
                    Some(v) => self.scale.color(v),
                };
                let (a, b) = (
                    (self.k_e.edges[i], self.k_c.edges[j]),
                    (self.k_e.edges[i + 1], self.k_c.edges[j + 1]),
                );
                chart
                    .draw_series(std::iter::once(Rectangle::new([a, b], color.filled())))
                    .map_err(|e| PlotError::drawing(context, e))?;
                if let (true, Some(v)) = (write_values, v) {
                    draw_cell_value(chart, v, color, (a, b), context)?;
                }
            }
        }
        Ok(())
    }

    /// The colour bar: 60 bands from the bottom (low) to the top (high), 5 labels.
    fn draw_bar<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        let (top, bottom, x0, x1) = (70i32, 560i32, 10i32, 34i32);
        let n = 60;
        let band = f64::from(bottom - top) / f64::from(n);
        for k in 0..n {
            let s = (f64::from(k) + 0.5) / f64::from(n);
            let y1 = bottom - (f64::from(k) * band) as i32;
            let y0 = bottom - (f64::from(k + 1) * band).ceil() as i32;
            area.draw(&Rectangle::new(
                [(x0, y0), (x1, y1)],
                self.scale.color(self.scale.value_at(s)).filled(),
            ))?;
        }
        area.draw(&Rectangle::new(
            [(x0, top), (x1, bottom)],
            BLACK.stroke_width(1),
        ))?;
        let style = ("sans-serif", 12).into_text_style(area);
        for k in 0..5 {
            let s = f64::from(k) / 4.0;
            let y = bottom - (s * f64::from(bottom - top)) as i32;
            area.draw_text(&number(self.scale.value_at(s)), &style, (x1 + 5, y - 6))?;
        }
        area.draw_text(&shorten(&self.value_label, 16), &style, (4, top - 22))?;
        Ok(())
    }
}

/// A cell's value at its centre, black on light cells and white on dark ones.
fn draw_cell_value<'a, DB: DrawingBackend + 'a>(
    chart: &mut Ctx<'a, DB>,
    v: f64,
    color: RGBColor,
    (a, b): ((f64, f64), (f64, f64)),
    context: &str,
) -> Result<(), PlotError> {
    let RGBColor(r, g, bl) = color;
    let light = 0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(bl) > 140.0;
    let style = ("sans-serif", 11)
        .into_font()
        .color(if light { &BLACK } else { &WHITE })
        .pos(Pos::new(HPos::Center, VPos::Center));
    let centre = ((a.0 + b.0) / 2.0, (a.1 + b.1) / 2.0);
    chart
        .draw_series(std::iter::once(Text::new(number(v), centre, style)))
        .map_err(|e| PlotError::drawing(context, e))?;
    Ok(())
}

/// The boundaries over the cells; returns their legend entries (it goes under the chart:
/// over the cells it would hide values).
fn draw_boundaries<'a, DB: DrawingBackend + 'a>(
    chart: &mut Ctx<'a, DB>,
    boundaries: [Boundary; 3],
    context: &str,
) -> Result<Vec<LegendEntry>, PlotError> {
    let mut legend = Vec::new();
    for (paths, line, color, width, label, missing) in boundaries {
        let paths = paths.map(|p| p.0).unwrap_or_default();
        for p in &paths {
            let style = color.stroke_width(width);
            match line {
                Line::Solid => chart
                    .draw_series(LineSeries::new(p.iter().copied(), style))
                    .map(|_| ()),
                Line::Dashed(dash, gap) => chart
                    .draw_series(DashedLineSeries::new(p.iter().copied(), dash, gap, style))
                    .map(|_| ()),
            }
            .map_err(|e| PlotError::drawing(context, e))?;
        }
        legend.push(if paths.is_empty() {
            LegendEntry {
                label: missing,
                color: color.mix(0.35),
                width: 2,
                line: Line::Solid,
            }
        } else {
            LegendEntry {
                label,
                color: color.to_rgba(),
                width,
                line,
            }
        });
    }
    Ok(legend)
}

/// The regional certificate's pairs: green dots ringed in black.
fn draw_dots<'a, DB: DrawingBackend + 'a>(
    chart: &mut Ctx<'a, DB>,
    dots: &[(f64, f64)],
    context: &str,
) -> Result<(), PlotError> {
    let err = |e: &dyn std::fmt::Display| PlotError::drawing(context, e);
    chart
        .draw_series(dots.iter().map(|&c| Circle::new(c, 6, REGIONAL.filled())))
        .map_err(|e| err(&e))?;
    chart
        .draw_series(
            dots.iter()
                .map(|&c| Circle::new(c, 6, BLACK.stroke_width(1))),
        )
        .map_err(|e| err(&e))?;
    Ok(())
}

/// The legend row (one entry per boundary, 300 px apart) and the notes under it.
fn draw_legend<DB: DrawingBackend>(
    lower: &DrawingArea<DB, Shift>,
    legend: &[LegendEntry],
    notes: &[String],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let text = ("sans-serif", 13).into_text_style(lower);
    for (i, l) in legend.iter().enumerate() {
        let (x, y) = (80 + 300 * i as i32, 8);
        let style = ShapeStyle::from(l.color).stroke_width(l.width);
        match l.line {
            Line::Solid => lower.draw(&PathElement::new(vec![(x, y), (x + 30, y)], style))?,
            Line::Dashed(dash, gap) => {
                let (d, g) = (dash as i32, gap as i32);
                let mut x0 = x;
                while x0 < x + 30 {
                    lower.draw(&PathElement::new(
                        vec![(x0, y), ((x0 + d).min(x + 30), y)],
                        style,
                    ))?;
                    x0 += d + g;
                }
            }
        }
        lower.draw_text(&l.label, &text, (x + 36, y - 7))?;
    }
    for (i, n) in notes.iter().enumerate() {
        lower.draw_text(n, &text, (14, 26 + 17 * i as i32))?;
    }
    Ok(())
}

#[cfg(test)]
#[path = "heatmap_tests.rs"]
mod tests;
