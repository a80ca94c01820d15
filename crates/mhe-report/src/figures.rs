//! The paper's figures from a [`Report`]'s runs (feature `figures`): Fig. 2(a)–(c)
//! analogues, the norms, every state with its estimate, inputs and outputs with their bounds;
//! the same SVG bytes as `cargo xtask reproduce` writes. [`figures`] gives the charts as data
//! (to restyle or draw elsewhere), [`render`] their SVG text with notes on what was left out.
//!
//! ```no_run
//! use closed_loop::scenario::Scenario;
//!
//! let scenario = Scenario::from_file("scenarios/case-study-certified.toml")?;
//! let report = mhe_report::report(scenario, &mhe_report::Options::default(), &mhe_report::Quiet)?;
//! let drawn = mhe_report::figures::render(&report.scenario, &report.runs, 6);
//! for (name, svg) in &drawn.files {
//!     std::fs::write(name, svg)?;
//! }
//! for note in &drawn.notes {
//!     println!("{note}");
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! `cargo run -p mhe-report --features figures --example first_report` runs it on a double
//! integrator.

use closed_loop::scenario::Scenario;
use lti_model::BoxSet;
use mhe_plots::PlotError;
use mhe_plots::chart::{self, Chart, Grid, HLine, Legend, MAX_PANELS, Pattern, Rendered, Series};

#[cfg(doc)]
use crate::Report;
use crate::Run;

/// One SVG file: a single chart or small multiples.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Figure {
    /// One chart.
    Single(Chart),
    /// One panel per component.
    Grid(Grid),
}

impl Figure {
    /// Its SVG text, with the count of points not drawn (≤ 0 on a log axis, non-finite).
    pub fn render(&self) -> Result<Rendered, PlotError> {
        match self {
            Figure::Single(c) => chart::render_svg(c),
            Figure::Grid(g) => chart::render_grid_svg(g),
        }
    }
}

/// The figures of a report as data: (file name, figure), and notes on what they leave out.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Figures {
    /// (file name, e.g. `fig2a_x1.svg`; figure), in the order the tool writes them.
    pub files: Vec<(String, Figure)>,
    /// Figures not built (no run recorded the MHE window of Fig. 2(c)) or components left
    /// out of a grid, and why.
    pub notes: Vec<String>,
}

/// The figures of a report as SVG text.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Drawn {
    /// (file name, SVG text), in the order the tool writes them.
    pub files: Vec<(String, String)>,
    /// Figures not written or with points left out, and why (the JSON files hold every
    /// number, so a figure without drawable data is a note, not an error).
    pub notes: Vec<String>,
}

/// `i` (1-based) as subscript digits: 12 → `₁₂`.
fn subscript(i: usize) -> String {
    i.to_string()
        .chars()
        .map(|c| char::from_u32(0x2080 + c.to_digit(10).unwrap_or(0)).unwrap_or(c))
        .collect()
}

/// The figures of one scenario's runs ([`Report::runs`]); `fig2c_t` is the time step of
/// Fig. 2(c)'s ŵ² window (the paper shows t = 6). Colour i+1 is run i; the true state is black.
pub fn figures(scenario: &Scenario, runs: &[Run], fig2c_t: usize) -> Figures {
    let (mut files, mut notes) = fig2(scenario, runs, fig2c_t);
    let (grids, grid_notes) = component_grids(scenario, runs);
    files.extend(grids);
    notes.extend(grid_notes);
    Figures { files, notes }
}

/// [`figures`] rendered: the SVG text of each figure that has drawable data, and the notes
/// (those of [`figures`], then per figure the ones not written or with points left out).
pub fn render(scenario: &Scenario, runs: &[Run], fig2c_t: usize) -> Drawn {
    let Figures { files, mut notes } = figures(scenario, runs, fig2c_t);
    let mut out = Vec::new();
    for (name, fig) in files {
        let rendered = match fig.render() {
            Ok(r) => r,
            Err(e) => {
                notes.push(format!("{name} not written: {e}"));
                continue;
            }
        };
        if rendered.dropped > 0 {
            notes.push(format!(
                "{name}: {} point(s) ≤ 0 or non-finite not drawn",
                rendered.dropped
            ));
        }
        out.push((name, rendered.svg));
    }
    Drawn { files: out, notes }
}

/// A figure file of one chart.
type Named = (String, Figure);

/// Solid for the first run, dashed for the others.
fn run_pattern(i: usize) -> Pattern {
    if i == 0 {
        Pattern::Solid
    } else {
        Pattern::Dashed
    }
}

/// `(t, v)` for each step of a per-step sequence.
fn indexed(values: &[f64]) -> Vec<(f64, f64)> {
    values
        .iter()
        .enumerate()
        .map(|(t, v)| (t as f64, *v))
        .collect()
}

/// Fig. 2(a)–(c) analogues and the norm plot.
fn fig2(scenario: &Scenario, runs: &[Run], fig2c_t: usize) -> (Vec<Named>, Vec<String>) {
    let mut out = vec![fig2a(runs), fig2b(runs)];
    let mut notes = Vec::new();
    let name = format!("fig2c_w2_t{fig2c_t}.svg");
    match fig2c(scenario, runs, fig2c_t) {
        Some(chart) => out.push((name, Figure::Single(chart))),
        None => notes.push(format!(
            "{name} not written: no run recorded the MHE window at t = {fig2c_t}"
        )),
    }
    out.push(norms(runs));
    (out, notes)
}

/// Fig. 2(a): x₁ and x̂₁.
fn fig2a(runs: &[Run]) -> Named {
    let multi = runs.len() > 1;
    let mut series = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        let tr = &r.trace;
        let suffix = if multi {
            format!(", K = {}", r.summary.k)
        } else {
            String::new()
        };
        series.push(Series {
            label: format!("x₁{suffix}"),
            points: (0..tr.len())
                .filter_map(|t| tr.x(t).map(|x| (t as f64, x[0])))
                .collect(),
            color: 0,
            pattern: run_pattern(i),
            markers: false,
        });
        series.push(Series {
            label: format!("x̂₁, K = {}", r.summary.k),
            points: (0..tr.len())
                .filter_map(|t| tr.x_hat(t).map(|x| (t as f64, x[0])))
                .collect(),
            color: i + 1,
            pattern: run_pattern(i),
            markers: false,
        });
    }
    (
        "fig2a_x1.svg".to_string(),
        Figure::Single(Chart {
            title: "Fig. 2(a): true state x₁ and sub-optimal estimate x̂₁".into(),
            x_label: "time step t".into(),
            y_label: "x₁".into(),
            log_y: false,
            integer_x: true,
            series,
            hlines: vec![],
            legend: Legend::UpperRight,
        }),
    )
}

/// Fig. 2(b): ε_t (log).
fn fig2b(runs: &[Run]) -> Named {
    let series = runs
        .iter()
        .enumerate()
        .map(|(i, r)| Series {
            label: format!("ε_t, K = {}", r.summary.k),
            points: r
                .trace
                .epsilons()
                .enumerate()
                .filter_map(|(t, e)| e.map(|e| (t as f64, e)))
                .collect(),
            color: i + 1,
            pattern: Pattern::Solid,
            markers: true,
        })
        .collect();
    (
        "fig2b_epsilon.svg".to_string(),
        Figure::Single(Chart {
            title: "Fig. 2(b): sub-optimality ε_t = ‖zᴷ_t − z*_t‖".into(),
            x_label: "time step t".into(),
            y_label: "ε_t".into(),
            log_y: true,
            integer_x: true,
            series,
            hlines: vec![],
            legend: Legend::MiddleRight,
        }),
    )
}

/// The ŵ² series of Fig. 2(c): per run and component, the K-th iterate and the exact
/// optimum over the window ending at t.
fn fig2c_series(scenario: &Scenario, runs: &[Run], t: usize) -> Vec<Series> {
    let nw1 = scenario.plant.nw1();
    let nw2 = scenario.plant.nw2();
    let mut series = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        let Some(rec) = r.trace.mhe_step(t) else {
            continue;
        };
        let start = t.saturating_sub(rec.window());
        for c in 0..nw2 {
            let comp = if nw2 > 1 {
                format!("[{}]", c + 1)
            } else {
                String::new()
            };
            let k_pts: Vec<(f64, f64)> = (0..rec.window())
                .filter_map(|j| rec.w2_k(j).map(|w| ((start + j) as f64, w[c])))
                .collect();
            series.push(Series {
                label: format!("ŵ²{comp}, K = {} iterate", r.summary.k),
                points: k_pts,
                color: i + 1,
                pattern: Pattern::Solid,
                markers: true,
            });
            let exact: Vec<(f64, f64)> = (0..rec.window())
                .filter_map(|j| rec.w_exact(j).map(|w| ((start + j) as f64, w[nw1 + c])))
                .collect();
            if !exact.is_empty() {
                series.push(Series {
                    label: format!("ŵ²{comp}, exact optimum (K = {} run)", r.summary.k),
                    points: exact,
                    color: i + 1,
                    pattern: Pattern::Dashed,
                    markers: true,
                });
            }
        }
    }
    series
}

/// Fig. 2(c): ŵ² at t, K-th iterate and exact optimum, with the bounds of 𝒲; `None` when no
/// run recorded the window at t.
fn fig2c(scenario: &Scenario, runs: &[Run], fig2c_t: usize) -> Option<Chart> {
    let series = fig2c_series(scenario, runs, fig2c_t);
    if series.is_empty() {
        return None;
    }
    let nw1 = scenario.plant.nw1();
    let d = &scenario.sets.disturbance;
    let mut hlines = Vec::new();
    for c in 0..scenario.plant.nw2() {
        for b in [d.lower()[nw1 + c], d.upper()[nw1 + c]] {
            if b.is_finite() {
                hlines.push(HLine {
                    label: "bounds of 𝒲 (w²)".into(),
                    y: b,
                });
            }
        }
    }
    Some(Chart {
        title: format!("Fig. 2(c): estimated measurement noise ŵ² at t = {fig2c_t}"),
        x_label: "window stage (time index)".into(),
        y_label: "ŵ²".into(),
        log_y: false,
        integer_x: true,
        series,
        hlines,
        legend: Legend::LowerLeft,
    })
}

/// ‖e_t‖ and ‖x_t‖ (log), with the Kalman baseline's error on the same data (markers).
fn norms(runs: &[Run]) -> Named {
    let mut series = Vec::new();
    for (i, r) in runs.iter().enumerate() {
        let tr = &r.trace;
        series.push(Series {
            label: format!("‖x_t‖, K = {}", r.summary.k),
            points: indexed(tr.x_norms()),
            color: i + 1,
            pattern: Pattern::Solid,
            markers: false,
        });
        series.push(Series {
            label: format!("‖e_t‖, K = {}", r.summary.k),
            points: indexed(tr.e_norms()),
            color: i + 1,
            pattern: Pattern::Dashed,
            markers: false,
        });
        if let Some(kf) = &r.kalman {
            series.push(Series {
                label: format!("‖e_t‖ Kalman filter, K = {} run", r.summary.k),
                points: indexed(&kf.e_norms),
                color: i + 1,
                pattern: Pattern::Dashed,
                markers: true,
            });
        }
    }
    (
        "norms.svg".to_string(),
        Figure::Single(Chart {
            title: "State norm ‖x_t‖, estimation error ‖e_t‖ (MHE; Kalman filter, markers)".into(),
            x_label: "time step t".into(),
            y_label: "norm".into(),
            log_y: true,
            integer_x: true,
            series,
            hlines: vec![],
            legend: Legend::UpperRight,
        }),
    )
}

/// What a component grid shows.
#[derive(Clone, Copy)]
enum Signal {
    /// x_i (black) and x̂_i per run.
    State,
    /// u_i per run, bounds of 𝒰.
    Input,
    /// y_i per run, bounds of 𝒴.
    Output,
}

/// `states.svg`, `inputs.svg`, `outputs.svg`: one panel per component (at most
/// [`MAX_PANELS`], with a note in the figure and in the notes when more exist).
fn component_grids(scenario: &Scenario, runs: &[Run]) -> (Vec<(String, Figure)>, Vec<String>) {
    let p = &scenario.plant;
    let sets = &scenario.sets;
    let mut out = Vec::new();
    let mut notes = Vec::new();
    for (signal, file, n, symbol, what, bounds, set) in [
        (Signal::State, "states.svg", p.nx(), "x", "state", None, ""),
        (
            Signal::Input,
            "inputs.svg",
            p.nu(),
            "u",
            "input",
            Some(&sets.input),
            "𝒰",
        ),
        (
            Signal::Output,
            "outputs.svg",
            p.ny(),
            "y",
            "output",
            Some(&sets.output),
            "𝒴",
        ),
    ] {
        if n == 0 {
            continue;
        }
        let shown = n.min(MAX_PANELS);
        let note = (shown < n).then(|| {
            format!(
                "{shown} of {n} {what}s drawn ({symbol}{}…{symbol}{}); every {what} is in trace.csv and trace.json",
                subscript(1),
                subscript(shown)
            )
        });
        if let Some(note) = &note {
            notes.push(format!("{file}: {note}"));
        }
        let bounded = bounds.is_some_and(|b| {
            b.lower()[..shown]
                .iter()
                .chain(&b.upper()[..shown])
                .any(|v| v.is_finite())
        });
        // Bounds drawn where the set has them; with some bounded and others not, the panels
        // without say so.
        let panels = (0..shown)
            .map(|i| component_panel(signal, i, symbol, bounds.filter(|_| bounded), set, runs))
            .collect();
        let bound_note = if bounded {
            format!(", bounds of {set} in red")
        } else {
            format!(" ({set} has no bounds)")
        };
        let title = match signal {
            Signal::State => "True states x_i (black) and their estimates x̂_i".to_string(),
            Signal::Input => format!("Inputs u_t = π(x̂_t){bound_note}"),
            Signal::Output => format!("Measurements y_t{bound_note}"),
        };
        out.push((
            file.to_string(),
            Figure::Grid(Grid {
                title,
                panels,
                note,
            }),
        ));
    }
    (out, notes)
}

/// The series of run `r_i` in panel i of a component grid: the true state (black) and its
/// estimate, or the input or output. Labels hold for every panel (one legend per grid).
fn run_series(signal: Signal, i: usize, r_i: usize, r: &Run, multi: bool) -> Vec<Series> {
    let tr = &r.trace;
    let k = r.summary.k;
    let pattern = if r_i == 0 {
        Pattern::Solid
    } else {
        Pattern::Dashed
    };
    let points = |f: &dyn Fn(usize) -> Option<f64>| -> Vec<(f64, f64)> {
        (0..tr.len())
            .filter_map(|t| f(t).map(|v| (t as f64, v)))
            .collect()
    };
    match signal {
        // The true state of the first run in black; other runs' true states dashed black
        // (they differ when the estimates do).
        Signal::State => vec![
            Series {
                label: if multi {
                    format!("true state, K = {k} run")
                } else {
                    "true state".to_string()
                },
                points: points(&|t| tr.x(t).map(|x| x[i])),
                color: 0,
                pattern,
                markers: false,
            },
            Series {
                label: format!("estimate x̂, K = {k}"),
                points: points(&|t| tr.x_hat(t).map(|x| x[i])),
                color: r_i + 1,
                pattern,
                markers: false,
            },
        ],
        Signal::Input | Signal::Output => vec![Series {
            label: format!("K = {k}"),
            points: points(&|t| match signal {
                Signal::Input => tr.u(t).map(|u| u[i]),
                _ => tr.y(t).map(|y| y[i]),
            }),
            color: r_i + 1,
            pattern,
            markers: false,
        }],
    }
}

/// Panel i of a component grid (the grid draws one legend for all panels).
fn component_panel(
    signal: Signal,
    i: usize,
    symbol: &str,
    bounds: Option<&BoxSet>,
    set: &str,
    runs: &[Run],
) -> Chart {
    let sub = subscript(i + 1);
    let multi = runs.len() > 1;
    let series = runs
        .iter()
        .enumerate()
        .flat_map(|(r_i, r)| run_series(signal, i, r_i, r, multi))
        .collect();
    let mut hlines = Vec::new();
    if let Some(b) = bounds {
        for y in [b.lower()[i], b.upper()[i]] {
            if y.is_finite() {
                hlines.push(HLine {
                    label: format!("bounds of {set}"),
                    y,
                });
            }
        }
    }
    // Only passed `bounds` when some component is bounded: then say which are not.
    let unbounded = bounds.is_some() && hlines.is_empty();
    Chart {
        title: if unbounded {
            format!("{symbol}{sub} (no bound in {set})")
        } else {
            format!("{symbol}{sub}")
        },
        x_label: "time step t".into(),
        y_label: format!("{symbol}{sub}"),
        log_y: false,
        integer_x: true,
        series,
        hlines,
        legend: Legend::Hidden,
    }
}

#[cfg(test)]
#[path = "figures_tests.rs"]
mod tests;
