//! `sets`: projection properties of boxes and products (feasibility, idempotence, the
//! obtuse-angle optimality condition), polytope membership against the box it came from,
//! and validation of bad bounds.

use lti_model::{BoxSet, ConvexSet, ModelError, Polytope, Projection, Set};
use proptest::prelude::*;

/// One coordinate's bounds: finite pair in [−10, 10], each side independently infinite
/// with probability 1/4.
fn bound() -> impl Strategy<Value = (f64, f64)> {
    (-10.0..10.0f64, 0.0..10.0f64, 0..4u8, 0..4u8).prop_map(|(l, w, inf_l, inf_u)| {
        let lo = if inf_l == 0 { f64::NEG_INFINITY } else { l };
        // Sometimes a degenerate interval l = u.
        let width = if w < 0.5 { 0.0 } else { w };
        let hi = if inf_u == 0 { f64::INFINITY } else { l + width };
        (lo, hi)
    })
}

fn box_set(max_dim: usize) -> impl Strategy<Value = BoxSet> {
    prop::collection::vec(bound(), 1..=max_dim).prop_map(|b| {
        let (lower, upper): (Vec<f64>, Vec<f64>) = b.into_iter().unzip();
        BoxSet::new(lower, upper).unwrap()
    })
}

/// A nested product of whole spaces, boxes and products (depth ≤ 2).
fn product_set() -> impl Strategy<Value = Set> {
    let leaf = prop_oneof![
        (1..4usize).prop_map(Set::Whole),
        box_set(4).prop_map(Set::Box)
    ];
    leaf.prop_recursive(2, 12, 4, |inner| {
        prop::collection::vec(inner, 1..4).prop_map(Set::Product)
    })
    .prop_map(|s| match s {
        Set::Product(_) => s,
        other => Set::Product(vec![other]),
    })
}

/// A feasible point of the box: uniform inside finite intervals, within ±30 of the finite
/// side on half-infinite ones, anywhere in [−30, 30] on free coordinates.
fn feasible_point(b: &BoxSet, t: &[f64]) -> Vec<f64> {
    b.lower()
        .iter()
        .zip(b.upper())
        .zip(t)
        .map(|((&l, &u), &t)| match (l.is_finite(), u.is_finite()) {
            (true, true) => (l + t * (u - l)).clamp(l, u),
            (true, false) => l + 30.0 * t,
            (false, true) => u - 30.0 * t,
            (false, false) => 60.0 * t - 30.0,
        })
        .collect()
}

fn dot_residual(x: &[f64], px: &[f64], y: &[f64]) -> f64 {
    x.iter()
        .zip(px)
        .zip(y)
        .map(|((x, p), y)| (x - p) * (y - p))
        .sum()
}

/// The three projection properties for any projectable set with equivalent box `b`.
fn check_projection<S: Projection>(
    s: &S,
    b: &BoxSet,
    x: &[f64],
    ts: &[Vec<f64>],
) -> std::result::Result<(), TestCaseError> {
    let mut px = x.to_vec();
    s.project(&mut px);
    prop_assert!(
        s.contains(&px, 0.0),
        "P(x) = {:?} infeasible for {:?}",
        px,
        s
    );
    prop_assert_eq!(s.violation(&px), 0.0);
    let mut ppx = px.clone();
    s.project(&mut ppx);
    prop_assert_eq!(&ppx, &px, "projection not idempotent");
    for t in ts {
        let y = feasible_point(b, t);
        prop_assert!(s.contains(&y, 0.0), "sampled y {:?} not feasible", y);
        let d = dot_residual(x, &px, &y);
        prop_assert!(
            d <= 1e-9,
            "⟨x − P(x), y − P(x)⟩ = {} > 0 for x {:?}, y {:?}",
            d,
            x,
            y
        );
    }
    // Independent answer for a box: the projection is the coordinatewise clamp, and the
    // violation of x is max(l − x, x − u, 0).
    let clamp: Vec<f64> = x
        .iter()
        .zip(b.lower().iter().zip(b.upper()))
        .map(|(&x, (&l, &u))| x.max(l).min(u))
        .collect();
    prop_assert_eq!(&px, &clamp);
    let viol = x
        .iter()
        .zip(b.lower().iter().zip(b.upper()))
        .map(|(&x, (&l, &u))| (l - x).max(x - u).max(0.0))
        .fold(0.0, f64::max);
    prop_assert_eq!(s.violation(x), viol);
    Ok(())
}

fn points(n: usize, count: usize) -> impl Strategy<Value = Vec<Vec<f64>>> {
    prop::collection::vec(prop::collection::vec(0.0..1.0f64, n), count)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn box_projection_is_feasible_idempotent_and_optimal(
        (b, x, ts) in box_set(6).prop_flat_map(|b| {
            let n = b.dim();
            (Just(b), prop::collection::vec(-40.0..40.0f64, n), points(n, 8))
        })
    ) {
        check_projection(&b, &b, &x, &ts)?;
    }

    #[test]
    fn product_projection_is_feasible_idempotent_and_optimal(
        (s, x, ts) in product_set().prop_flat_map(|s| {
            let n = s.dim();
            (Just(s), prop::collection::vec(-40.0..40.0f64, n), points(n, 8))
        })
    ) {
        let b = s.to_box();
        prop_assert_eq!(b.dim(), s.dim());
        check_projection(&s, &b, &x, &ts)?;
        // The product acts blockwise: projecting through Set::Box(to_box) gives the same.
        let (mut p1, mut p2) = (x.clone(), x.clone());
        s.project(&mut p1);
        Set::Box(b).project(&mut p2);
        prop_assert_eq!(p1, p2);
    }

    #[test]
    fn polytope_membership_matches_the_box(
        (b, xs, tol) in box_set(5).prop_flat_map(|b| {
            let n = b.dim();
            (Just(b), prop::collection::vec(prop::collection::vec(-15.0..15.0f64, n), 16), prop_oneof![Just(0.0), 0.0..0.5f64])
        })
    ) {
        let p = lti_model::Polytope::from_box(&b);
        prop_assert_eq!(p.dim(), b.dim());
        let finite = b.lower().iter().chain(b.upper()).filter(|v| v.is_finite()).count();
        prop_assert_eq!(p.g().nrows(), finite);
        let mut xs = xs;
        // Include points exactly on the boundary.
        let mut on_boundary: Vec<f64> = b.lower().iter().zip(b.upper()).map(|(&l, &u)| if l.is_finite() { l } else if u.is_finite() { u } else { 0.0 }).collect();
        xs.push(on_boundary.clone());
        on_boundary[0] += 1e-3;
        xs.push(on_boundary);
        for x in &xs {
            prop_assert_eq!(p.contains(x, tol), b.contains(x, tol), "x = {:?}", x);
            prop_assert_eq!(p.violation(x), b.violation(x), "x = {:?}", x);
        }
    }
}

fn assert_invalid_set(r: Result<BoxSet, qp_iter::DataError>, name: &str, reason_has: &str) {
    // The box's errors convert into the model's, field for field.
    match r.map_err(ModelError::from) {
        Err(ModelError::InvalidSet { name: n, reason }) => {
            assert_eq!(n, name);
            assert!(
                reason.contains(reason_has),
                "reason `{reason}` lacks `{reason_has}`"
            );
        }
        other => panic!("expected InvalidSet({name}), got {other:?}"),
    }
}

#[test]
fn box_rejects_bad_bounds() {
    assert_invalid_set(
        BoxSet::new(vec![1.0, 0.0], vec![0.0, 1.0]),
        "box",
        "lower[0] = 1 > upper[0] = 0",
    );
    assert_invalid_set(
        BoxSet::new(vec![0.0, f64::NAN], vec![1.0, 1.0]),
        "box",
        "NaN",
    );
    assert_invalid_set(BoxSet::new(vec![0.0], vec![f64::NAN]), "box", "NaN");
    assert_invalid_set(
        BoxSet::new(vec![0.0, 0.0], vec![1.0]),
        "box",
        "lower has 2 entries but upper has 1",
    );
    assert_invalid_set(
        BoxSet::new(vec![f64::INFINITY], vec![f64::INFINITY]),
        "box",
        "empty",
    );
    assert_invalid_set(
        BoxSet::new(vec![f64::NEG_INFINITY], vec![f64::NEG_INFINITY]),
        "box",
        "empty",
    );
    assert_invalid_set(
        BoxSet::named("sets.input", vec![2.0], vec![1.0]),
        "sets.input",
        "empty",
    );
    assert_invalid_set(BoxSet::symmetric(&[-1.0]), "box", "empty");
    // Degenerate but valid.
    assert!(BoxSet::new(vec![1.0], vec![1.0]).is_ok());
    assert!(BoxSet::new(vec![], vec![]).is_ok());
}

#[test]
fn polytope_rejects_bad_data_and_checks_membership() {
    use faer::{Mat, mat};
    match Polytope::new(mat![[1.0, 0.0]], vec![1.0, 2.0]).unwrap_err() {
        ModelError::Shape { name, .. } => assert_eq!(name, "G"),
        other => panic!("{other:?}"),
    }
    match Polytope::new(mat![[f64::NAN, 0.0]], vec![1.0]).unwrap_err() {
        ModelError::NonFinite { name, .. } => assert_eq!(name, "G"),
        other => panic!("{other:?}"),
    }
    match Polytope::new(mat![[1.0, 0.0]], vec![f64::INFINITY]).unwrap_err() {
        ModelError::NonFinite { name, .. } => assert_eq!(name, "h"),
        other => panic!("{other:?}"),
    }
    // Triangle x ≥ 0, y ≥ 0, x + y ≤ 1, checked by hand.
    let p = Polytope::new(
        mat![[-1.0, 0.0], [0.0, -1.0], [1.0, 1.0]],
        vec![0.0, 0.0, 1.0],
    )
    .unwrap();
    assert!(p.contains(&[0.2, 0.3], 0.0));
    assert!(p.contains(&[1.0, 0.0], 0.0));
    assert!(!p.contains(&[0.6, 0.6], 0.1));
    assert!((p.violation(&[0.6, 0.6]) - 0.2).abs() < 1e-15);
    assert_eq!(p.violation(&[-2.0, 0.5]), 2.0);
    assert_eq!(p.violation(&[f64::NAN, 0.0]), f64::INFINITY);
    assert!(!p.contains(&[0.1], 1.0), "wrong length is never contained");
    let empty_rows = Polytope::new(Mat::zeros(0, 3), vec![]).unwrap();
    assert!(empty_rows.contains(&[1e9, -1e9, 0.0], 0.0));
}

#[test]
fn set_whole_and_nan_handling() {
    let s = Set::Product(vec![
        Set::Whole(2),
        Set::Box(BoxSet::symmetric(&[1.0]).unwrap()),
    ]);
    assert_eq!(s.dim(), 3);
    assert!(s.contains(&[1e300, -1e300, 1.0], 0.0));
    assert_eq!(s.violation(&[0.0, 0.0, 3.0]), 2.0);
    assert_eq!(s.violation(&[f64::NAN, 0.0, 0.0]), f64::INFINITY);
    assert_eq!(
        BoxSet::symmetric(&[1.0]).unwrap().violation(&[f64::NAN]),
        f64::INFINITY
    );
    assert!(
        s.to_box().lower()[..2]
            .iter()
            .all(|l| *l == f64::NEG_INFINITY)
    );
    assert!(BoxSet::whole(3).is_whole() && !BoxSet::symmetric(&[1.0]).unwrap().is_whole());
    assert_eq!(
        BoxSet::new(vec![-3.0, f64::NEG_INFINITY], vec![2.0, f64::INFINITY])
            .unwrap()
            .max_abs_finite_bound(),
        3.0
    );
}
