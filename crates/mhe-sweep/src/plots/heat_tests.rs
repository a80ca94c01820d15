//! Unit tests of the heat maps' glue: the value grid read from `points.csv`, file names.

#![allow(clippy::unwrap_used)]
use super::*;

#[test]
fn values_are_read_per_solver_and_scale_at_their_grid_pair() {
    let t = Table::parse(
        "point,k,k_c,solver,scale,bounded_fraction\n\
         0,1,1,pg,1,0.5\n1,10,1,pg,1,1\n2,10,5,pg,1,inf\n3,10,5,pg,2,0\n4,1,5,admm,1,0.25\n5,3,5,pg,1,1\n",
    )
    .unwrap();
    let (k_e, k_c) = (Axis::new(&[1, 10]), Axis::new(&[1, 5]));
    let v = values(&t, "pg", "1", "bounded_fraction", &k_e, &k_c);
    // (1, 5) is admm's; K_e = 3 is not on the grid; scale 2 is another map.
    assert_eq!(
        v,
        vec![vec![Some(0.5), None], vec![Some(1.0), Some(f64::INFINITY)]]
    );
}

#[test]
fn file_stems_keep_only_safe_characters() {
    assert_eq!(stem("admm-jacobi"), "admm-jacobi");
    assert_eq!(stem("admm(rho=2)"), "admm_rho_2_");
}
