//! Saturated LQR: −Kx inside the box, clipping outside, K against an independent Riccati
//! iteration, L_π = ‖K‖₂.

use faer::{Mat, mat};
use lti_model::BoxSet;
use mpc_core::{Controller, SaturatedLqr, lipschitz_sampled};

use crate::common::*;

fn neg_kx(k: &Mat<f64>, x: &[f64]) -> Vec<f64> {
    (0..k.nrows())
        .map(|i| -(0..k.ncols()).map(|j| k[(i, j)] * x[j]).sum::<f64>())
        .collect()
}

#[test]
fn equals_minus_kx_inside_and_clip_outside() {
    let sys = case_study_system();
    let q = Mat::<f64>::identity(4, 4);
    let r = Mat::<f64>::identity(2, 2) * 0.1;
    let ubox = BoxSet::symmetric(&[1.0, 1.0]).unwrap();
    let mut lqr = SaturatedLqr::new(&sys, q.as_ref(), r.as_ref(), ubox).unwrap();
    let (k_ref, _) = riccati_by_iteration(&sys, &q, &r);
    assert!(
        (lqr.gain() - &k_ref).norm_max() <= 1e-9,
        "K differs from the Riccati iteration"
    );
    let mut rg = rng(9);
    let (mut inside, mut outside) = (0, 0);
    for i in 0..200 {
        let x = gaussian(&mut rg, 4, if i % 2 == 0 { 0.2 } else { 20.0 });
        let mut u = [0.0; 2];
        lqr.control(&x, &mut u).unwrap();
        let v = neg_kx(lqr.gain(), &x);
        if v.iter().all(|t| t.abs() <= 1.0) {
            inside += 1;
            assert!(max_abs_diff(&u, &v) <= 1e-14 * (1.0 + v[0].abs() + v[1].abs()));
        } else {
            outside += 1;
            let clipped: Vec<f64> = v.iter().map(|t| t.clamp(-1.0, 1.0)).collect();
            assert!(max_abs_diff(&u, &clipped) <= 1e-14 * (1.0 + v[0].abs() + v[1].abs()));
        }
        assert!(u.iter().all(|t| (-1.0..=1.0).contains(t)));
    }
    assert!(
        inside > 20 && outside > 20,
        "inside {inside}, outside {outside}"
    );
}

#[test]
fn lipschitz_is_norm_of_k_and_sampling_stays_below() {
    // ‖K‖₂ for K = [[1, 2], [0, 2]]: KᵀK = [[1, 2], [2, 8]], λ_max = (9 + √(49 + 16))/2.
    let mut lqr = SaturatedLqr::from_gain(
        mat![[1.0, 2.0], [0.0, 2.0]],
        BoxSet::symmetric(&[1.0, 0.5]).unwrap(),
    )
    .unwrap();
    let exact = ((9.0 + 65f64.sqrt()) / 2.0).sqrt();
    assert!((lqr.lipschitz_certified() - exact).abs() < 1e-12);
    let s = lipschitz_sampled(&mut lqr, 400, 1, 3.0, None).unwrap();
    assert!(
        s.estimate <= exact * (1.0 + 1e-12),
        "{} > {exact}",
        s.estimate
    );
    // The unsaturated region around 0 has radius ≥ 0.5/‖K‖ ≈ 0.17 > δ, and directed pairs
    // there attain ‖K‖₂ (up to finite differences, exact for a linear map).
    let s = lipschitz_sampled(&mut lqr, 400, 1, 0.1, None).unwrap();
    assert!(
        (s.estimate - exact).abs() <= 1e-9 * exact,
        "{} vs {exact}",
        s.estimate
    );
}
