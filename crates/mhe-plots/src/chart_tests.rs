//! Unit tests of the line charts.

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
    let ((x0, x1), (y0, y1)) = ranges(&chart(false, vec![line("a", vec![(3.0, 2.0)])])).unwrap();
    assert!(x0 < 3.0 && 3.0 < x1 && y0 < 2.0 && 2.0 < y1);
}
