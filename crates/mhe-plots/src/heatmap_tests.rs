//! Unit tests of the 2-D heat maps.

#![allow(clippy::unwrap_used)]
use super::*;

#[test]
fn axes_pick_log_for_geometric_grids() {
    assert!(Axis::new(&[1, 2, 5, 10, 20, 50]).log);
    assert!(Axis::new(&[1, 3, 10, 32, 100]).log);
    assert!(!Axis::new(&[10, 20, 30, 40]).log);
    assert!(!Axis::new(&[5]).log);
    assert!(Axis::new(&[1, 100]).log && !Axis::new(&[4, 6]).log);
    let a = Axis::new(&[1, 4, 16]);
    // Edges halfway in log K: 1/2, 2, 8, 32.
    let e: Vec<f64> = a.edges.iter().map(|t| t.exp()).collect();
    for (x, y) in e.iter().zip([0.5, 2.0, 8.0, 32.0]) {
        assert!((x - y).abs() < 1e-9, "{e:?}");
    }
    let (t, clamped) = a.edge_below(4);
    assert!((t - 2f64.ln()).abs() < 1e-12 && !clamped);
    let (t, clamped) = a.edge_below(1000);
    assert!(
        (t - 32f64.ln()).abs() < 1e-12 && clamped,
        "beyond the grid: clamped"
    );
    assert_eq!(a.label(3f64.ln()), "4");
}

#[test]
fn staircases_become_paths_with_gaps_for_empty_columns() {
    let x = Axis::new(&[1, 2, 3]);
    let y = Axis::new(&[1, 2, 3]);
    // Linear axes: edges 0.5, 1.5, 2.5, 3.5.
    let (p, clamped) = staircase_paths(&[(1, None), (2, Some(3)), (3, Some(1))], &x, &y);
    assert!(!clamped);
    assert_eq!(
        p,
        vec![vec![
            (1.5, 3.5),
            (1.5, 2.5),
            (2.5, 2.5),
            (2.5, 0.5),
            (3.5, 0.5)
        ]]
    );
    let (p, _) = staircase_paths(&[(1, Some(2)), (2, None), (3, Some(2))], &x, &y);
    assert_eq!(p.len(), 2);
    assert_eq!(p[0], vec![(0.5, 1.5), (1.5, 1.5), (1.5, 3.5)]);
}

/// Tags open and close in order (a minimal well-formedness check of the SVG text).
fn well_formed(svg: &str) -> bool {
    let mut stack: Vec<String> = Vec::new();
    let mut rest = svg;
    while let Some(start) = rest.find('<') {
        let Some(end) = rest[start..].find('>') else {
            return false;
        };
        let tag = &rest[start + 1..start + end];
        rest = &rest[start + end + 1..];
        if tag.starts_with('?') || tag.starts_with('!') || tag.ends_with('/') {
            continue;
        }
        if let Some(name) = tag.strip_prefix('/') {
            if stack.pop().as_deref() != Some(name.trim()) {
                return false;
            }
        } else {
            stack.push(tag.split_whitespace().next().unwrap_or("").to_string());
        }
    }
    stack.is_empty()
}

#[test]
fn heat_map_is_a_valid_svg_with_the_three_boundaries_and_the_regional_dots() {
    let k_e = Axis::new(&[1, 10, 100]);
    let k_c = Axis::new(&[1, 5, 20]);
    let map = HeatMap {
        title: "bounded".into(),
        value_label: "bounded fraction".into(),
        values: vec![
            vec![Some(0.5), Some(1.0), Some(1.0)],
            vec![Some(0.0), None, Some(1.0)],
            vec![Some(f64::INFINITY), Some(1.0), Some(1.0)],
        ],
        k_e,
        k_c,
        scale: ColorScale::Linear { lo: 0.0, hi: 1.0 },
        empirical: vec![(1, Some(20)), (10, Some(20)), (100, Some(5))],
        linear: Some(vec![(1, Some(20)), (10, Some(5)), (100, Some(5))]),
        certified: vec![(10, None), (100, Some(20))],
        regional: vec![(1, None), (5, Some(13)), (20, Some(13))],
        notes: vec!["test".into()],
    };
    let svg = map.svg("h.svg").unwrap();
    assert!(
        svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"),
        "{svg}"
    );
    assert!(well_formed(&svg));
    for label in [
        "empirical: every run bounded from here up",
        "linear: ρ_lin &lt; 1 from here up",
        "certified: joint certificate from here up",
        "1 cells without a value",
        "1 cells not finite",
        "green dots: (K_reg, K_c)",
    ] {
        assert!(svg.contains(label), "no `{label}` in the SVG");
    }
    // Two regional dots (K_c = 5 and 20; none at K_c = 1), filled green.
    assert_eq!(svg.matches("fill=\"#00AA3C\"").count(), 2, "{svg}");
    // The boundaries' colours are drawn (stroke of the empirical and linear paths).
    assert!(svg.contains("stroke=\"#000000\"") && svg.contains("stroke=\"#DC00C8\""));
    // An empty certificate says so in the legend.
    let mut none = map.clone();
    none.certified.clear();
    none.linear = None;
    none.regional.clear();
    let svg = none.svg("h.svg").unwrap();
    assert!(well_formed(&svg));
    assert!(svg.contains("certificate: not computed") && svg.contains("linear: not computed"));
    assert!(!svg.contains("green dots"));
}
