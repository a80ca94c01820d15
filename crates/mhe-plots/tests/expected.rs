//! Each renderer on a small fixed input, compared byte for byte with a committed SVG
//! (`tests/expected/`), so any change of the output is seen. After an intended change:
//! `UPDATE_EXPECTED=1 cargo test -p mhe-plots --test expected`, then review the diff.

use std::path::PathBuf;

use mhe_plots::band::{BandChart, Curve};
use mhe_plots::chart::{Chart, Grid, HLine, Legend, Pattern, Series, render_grid_svg, render_svg};
use mhe_plots::heatmap::{Axis, ColorScale, HeatMap};

fn check(name: &str, svg: &str) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/expected")
        .join(name);
    if std::env::var_os("UPDATE_EXPECTED").is_some() {
        std::fs::write(&path, svg).expect("tests/expected is writable");
        return;
    }
    let expected = std::fs::read_to_string(&path).expect("the expected SVG is committed");
    assert!(
        svg == expected,
        "{name} differs from tests/expected/{name} (UPDATE_EXPECTED=1 rewrites it)"
    );
}

fn series(label: &str, color: usize, pattern: Pattern, points: Vec<(f64, f64)>) -> Series {
    Series {
        label: label.into(),
        points,
        color,
        pattern,
        markers: pattern == Pattern::Dashed,
    }
}

fn chart(title: &str, log_y: bool) -> Chart {
    Chart {
        title: title.into(),
        x_label: "t".into(),
        y_label: "y".into(),
        log_y,
        integer_x: true,
        series: vec![
            series(
                "x₁",
                0,
                Pattern::Solid,
                vec![(0.0, 1.0), (1.0, 0.5), (2.0, 0.25)],
            ),
            series(
                "x̂₁",
                1,
                Pattern::Dashed,
                vec![(0.0, 0.8), (1.0, 0.0), (2.0, 0.3)],
            ),
        ],
        hlines: vec![HLine {
            label: "bound".into(),
            y: 0.9,
        }],
        legend: Legend::UpperRight,
    }
}

#[test]
fn line_chart_is_unchanged() {
    let r = render_svg(&chart("chart", true)).expect("drawable");
    assert_eq!(r.dropped, 1, "0 on the log axis");
    check("chart.svg", &r.svg);
}

#[test]
fn grid_is_unchanged() {
    let grid = Grid {
        title: "grid".into(),
        panels: vec![chart("a", false), chart("b", true)],
        note: Some("note".into()),
    };
    check("grid.svg", &render_grid_svg(&grid).expect("drawable").svg);
}

#[test]
fn band_chart_is_unchanged() {
    let mut band = BandChart {
        title: "band".into(),
        y_label: "sup ‖e‖".into(),
        log_y: true,
        curves: vec![Curve {
            solver: "pg".into(),
            color: 0,
            points: vec![(1.0, 1.0, 2.0, 3.0), (10.0, 0.5, 1.0, 2.0)],
            k_min: Some(5.0),
            k_lin: Some(3.0),
            k_reg: None,
            regional_note: "no region".into(),
            void_reason: None,
        }],
        notes: vec!["note".into()],
        hline: Some((1.0, "level".into())),
    };
    band.prepare();
    check("band.svg", &band.svg("band.svg").expect("drawable"));
}

#[test]
fn heat_map_is_unchanged() {
    let map = HeatMap {
        title: "heat map".into(),
        value_label: "ρ_lin".into(),
        k_e: Axis::new(&[1, 10]),
        k_c: Axis::new(&[1, 2]),
        values: vec![vec![Some(1.2), None], vec![Some(0.9), Some(f64::INFINITY)]],
        scale: ColorScale::AroundOne { span: 0.5 },
        empirical: vec![(1, None), (10, Some(2))],
        linear: Some(vec![(1, Some(2)), (10, Some(1))]),
        certified: vec![(10, Some(2))],
        regional: vec![(2, Some(10))],
        notes: vec!["note".into()],
    };
    check("heatmap.svg", &map.svg("heatmap.svg").expect("drawable"));
}
