//! Issue 27's two mends of the certificate, each with the case that fails on the old form.

use closed_loop::scenario::Scenario;
use faer::{Mat, mat};
use iss_certificate::gamma13::gamma13_certified;
use lti_model::matrix::spectral_norm;
use lti_model::{BoxSet, LtiSystem};
use mhe_core::MheProblem;
use mpc_core::{CondensedMpc, Controller, ExactMpc, MpcConfig};
use qp_iter::active_set::ExactSolver;

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Mend (a): Lemma 1 for the growing window. On the stand-in, window 0 → 1 with the data
/// scaled, the paper's bound L_Φσ₁ (σ₁ a constant of the model) is exceeded once the data
/// are large, while L_Φ(‖θ₀‖ + ‖θ₁‖) (z*(0) = 0, 0 ∈ Z) holds at every scale.
#[test]
fn lemma1_growing_window_bound_scales_with_the_data() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/case-study-certified.toml"
    );
    let sc = Scenario::from_file(path).unwrap();
    let res = sc.clone().resolve().unwrap();
    let mut cfg = res.mhe_config().unwrap().clone();
    let ioss = res.ioss().unwrap().as_ref().unwrap();
    cfg.p = ioss.p.clone();
    let sys = &sc.plant;
    let spec = sc.mhe.as_ref().unwrap();
    let pr = MheProblem::new(sys, spec.horizon(), &cfg.weights(), res.mhe_sets()).unwrap();
    let l_phi = pr.lipschitz_certified().max(1.0);
    let (w0, w1) = (pr.window(0).unwrap(), pr.window(1).unwrap());
    assert_eq!(iss_certificate::certificate::lemma1::origin_offset(w0), 0.0);
    assert_eq!(iss_certificate::certificate::lemma1::origin_offset(w1), 0.0);
    // The paper's σ₁ = |1 − η⁻¹|‖H₁‖ + ‖A‖ + ‖B‖ + ‖C‖ + 2 (with |·|, see theory.md).
    let sigma1 = (1.0 - 1.0 / spec.eta()).abs() * spectral_norm(w1.h_paper())
        + spectral_norm(sys.a())
        + spectral_norm(sys.b())
        + spectral_norm(sys.c())
        + 2.0;
    let x0 = [12.0, -10.0, 10.0, -10.0];
    let prior = [7.0, -7.0, 3.0, -5.0];
    let mut y0 = vec![0.0; sys.ny()];
    sys.output(&x0, &vec![0.0; sys.nw2()], &mut y0);
    let u0 = [0.3, -0.2];
    let lay = w1.layout();
    let mut worst_old = 0.0_f64;
    for scale in [1.0, 10.0, 100.0, 1000.0] {
        let th0: Vec<f64> = prior.iter().map(|v| v * scale).collect();
        let mut th1 = vec![0.0; lay.n_theta()];
        th1[..4].copy_from_slice(&th0);
        for (j, v) in u0.iter().enumerate() {
            th1[lay.u_offset(0) + j] = v * scale;
        }
        for (j, v) in y0.iter().enumerate() {
            th1[lay.y_offset(0) + j] = v * scale;
        }
        let z0 = ExactSolver::new(w0.qp())
            .unwrap()
            .solve(&th0)
            .unwrap()
            .to_vec();
        let z1 = ExactSolver::new(w1.qp())
            .unwrap()
            .solve(&th1)
            .unwrap()
            .to_vec();
        let mut padded = z0.clone();
        padded.resize(z1.len(), 0.0); // Σ₀ = blkdiag(I, 0)
        let lhs = norm(
            &padded
                .iter()
                .zip(&z1)
                .map(|(a, b)| a - b)
                .collect::<Vec<_>>(),
        );
        let new = l_phi * (norm(&th0) + norm(&th1));
        assert!(lhs <= new * (1.0 + 1e-12), "scale {scale}: {lhs} > {new}");
        worst_old = worst_old.max(lhs / (l_phi * sigma1));
    }
    // The old form fails: at scale 1000 the left side is far above L_Φσ₁.
    assert!(worst_old > 10.0, "old-form ratio {worst_old}");
}

/// Mend (b), plant side: w¹ enters as Ew¹, so γ₁ʷ = ‖S^{½}E‖/(√λ(S)(1 − λ_S)). With E = 50·I
/// a constant unit disturbance drives ‖x‖ far above the old γ₁ʷ = √(λ̄(S)/λ(S))/(1 − λ_S)
/// (which assumed E = I) and stays below the new one.
#[test]
fn gamma1w_carries_the_noise_matrix_e() {
    let e_scale = 50.0;
    let sys = LtiSystem::with_disturbance(
        mat![[0.9, 0.2], [0.0, 0.7]],
        mat![[0.0], [1.0]],
        mat![[1.0, 0.0]],
        Mat::<f64>::identity(2, 2) * e_scale,
        mat![[1.0]],
    )
    .unwrap();
    let mpc = CondensedMpc::new(
        &sys,
        MpcConfig::new(5, Mat::identity(2, 2), mat![[1.0]], BoxSet::whole(1)),
    )
    .unwrap();
    let c = gamma13_certified(&mpc, 14).unwrap();
    assert!(c.gamma1w.is_finite());
    let old = c.beta_prefactor.expect("certified") / (1.0 - c.beta_rate.expect("certified"));
    let mut exact = ExactMpc::new(&mpc).unwrap();
    let mut worst = 0.0_f64;
    for dir in [[1.0, 0.0], [0.0, 1.0], [0.6, 0.8], [0.6, -0.8], [-0.8, 0.6]] {
        let (mut x, mut u, mut y) = (vec![0.0; 2], vec![0.0], vec![0.0]);
        let w = [dir[0], dir[1], 0.0];
        for _ in 0..400 {
            exact.control(&x, &mut u).unwrap();
            let mut next = vec![0.0; 2];
            sys.step(&x, &u, &w, &mut next, &mut y);
            x = next;
            worst = worst.max(norm(&x));
        }
    }
    assert!(worst <= c.gamma1w, "{worst} > γ₁ʷ = {}", c.gamma1w);
    assert!(
        worst > old,
        "the old form {old} should be exceeded ({worst})"
    );
}
