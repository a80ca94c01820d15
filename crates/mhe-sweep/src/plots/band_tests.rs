//! Unit tests of the sweep plots' glue: curves read from `points.csv`, colours.

#![allow(clippy::unwrap_used)]
use super::*;

#[test]
fn curves_group_by_solver_and_read_the_certificate_columns() {
    let t = Table::parse(
        "point,k,solver,scale,bounded_fraction,sup_e_q05,sup_e_q50,sup_e_q95,k_min_cert,certified,void_reason\n\
         0,1,pg,1,1,1,2,3,5,no,\n1,10,pg,1,1,0.5,1,2,5,yes,\n2,1,admm,1,0.5,inf,inf,inf,,void,rho < 1 fails\n",
    )
    .unwrap();
    let c = curves(&t, "1", Column::Quantiles("sup_e"));
    assert_eq!(c.len(), 2);
    assert_eq!(
        c[0].points,
        vec![(1.0, 1.0, 2.0, 3.0), (10.0, 0.5, 1.0, 2.0)]
    );
    assert_eq!(c[0].k_min, Some(5.0));
    assert_eq!(c[1].void_reason.as_deref(), Some("rho < 1 fails"));
    assert_eq!(c[1].k_min, None);
    let b = curves(&t, "1", Column::Value("bounded_fraction"));
    assert_eq!(b[1].points, vec![(1.0, 0.5, 0.5, 0.5)]);
}

#[test]
fn colours_follow_the_method_list() {
    let pg = color_of("pg");
    assert_eq!(
        color_of("pg-jacobi"),
        pg,
        "a Jacobi form shares its method's colour"
    );
    assert_ne!(color_of("fista"), pg);
    assert_eq!(color_of("no such method"), CURVE_PALETTE.len() - 1);
}
