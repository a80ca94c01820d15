//! `From<&LtiSystem>` for the plant records of both documents.

use super::super::*;

/// Row-major rows of `m`, a non-finite entry as null.
fn rows(m: lti_model::faer::MatRef<'_, f64>) -> Vec<Vec<Option<f64>>> {
    (lti_model::matrix::to_rows(m).into_iter())
        .map(|r| r.into_iter().map(num).collect())
        .collect()
}

impl From<&lti_model::LtiSystem> for PlantDims {
    fn from(sys: &lti_model::LtiSystem) -> Self {
        Self {
            nx: sys.nx(),
            nu: sys.nu(),
            ny: sys.ny(),
            nw1: sys.nw1(),
            nw2: sys.nw2(),
        }
    }
}

impl From<&lti_model::LtiSystem> for IossSystem {
    fn from(sys: &lti_model::LtiSystem) -> Self {
        Self {
            dims: PlantDims::from(sys),
            a: rows(sys.a()),
            c: rows(sys.c()),
            b_bar: rows(sys.b_bar().as_ref()),
            d_bar: rows(sys.d_bar().as_ref()),
        }
    }
}
