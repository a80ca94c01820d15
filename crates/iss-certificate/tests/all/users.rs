//! Issue 25, item 5: the MPC and the noise users bring — a PSD `mpc.q`, output rows of the
//! MPC (`mpc.output`), and the simulated noise model separate from 𝒲.

use closed_loop::scenario::{ControllerChoice, LoopOptions, Scenario};
use iss_certificate::certificate::{CertificateOptions, Gamma13Source};
use qp_iter::Method;

const CASE_STUDY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../scenarios/case-study.toml"
);

fn case_study_with(section: &str, extra: &str) -> String {
    let text = std::fs::read_to_string(CASE_STUDY).unwrap();
    text.replace(
        &format!("[{section}]\n"),
        &format!("[{section}]\n{extra}\n"),
    )
}

#[test]
fn mpc_output_rows_reach_the_mpc_and_void_l_pi_and_gamma13_by_name() {
    let s = Scenario::from_toml_str(&case_study_with(
        "mpc",
        "output = { lower = -4.0, upper = 4.0 }",
    ))
    .unwrap();
    // Round trip through the canonical TOML keeps the key.
    let again = Scenario::from_toml_str(&s.to_toml_string().unwrap()).unwrap();
    assert!(again.mpc.as_ref().unwrap().output().is_some());
    let resolved = s.clone().resolve().unwrap();
    let mpc = resolved.mpc().unwrap();
    assert!(mpc.has_output_constraints() && !mpc.has_state_constraints());
    assert_eq!(mpc.qp().general().unwrap().m(), mpc.horizon());
    let opts = CertificateOptions {
        gamma13: Gamma13Source::Certified,
        gamma13_sequences: 0,
        lipschitz_pairs: 0,
        solvers: vec![Method::PG],
        ..CertificateOptions::default()
    };
    let c = crate::certify(&s, &opts).unwrap();
    assert_eq!(
        c.gamma13.void,
        Some(iss_certificate::gamma13::Gamma13Void::OutputConstrainedMpc)
    );
    let all =
        iss_certificate::outcome::VoidReason::join(&c.solvers[0].void_reasons).replace("; ", "\n");
    assert!(
        all.contains("L_π, γ₁,₃") && all.contains("mpc.output"),
        "{all}"
    );
    assert!(c.solvers[0].k_min.is_none());
    // The closed loop runs with the output rows (exact MPC).
    let mut o = LoopOptions::from_scenario(&s).unwrap();
    o.method = Method::PG;
    o = o.with_iterations(200).expect("K is in range");
    o.controller = ControllerChoice::ExactMpc;
    o.steps = 30;
    let mut cl = crate::build(&s, &o).unwrap();
    let trace = cl.run().unwrap();
    assert_eq!(trace.len(), 30);
}

#[test]
fn mpc_output_is_checked_against_the_plant() {
    let e = Scenario::from_toml_str(&case_study_with(
        "mpc",
        "output = { lower = [-4.0, -1.0], upper = [4.0, 1.0] }",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("mpc.output"), "{e}");
    let e = Scenario::from_toml_str(&case_study_with(
        "mpc",
        "output = { lower = 1.0, upper = 4.0 }",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("mpc.output") && e.contains("excludes 0"), "{e}");
}

#[test]
fn a_psd_mpc_q_is_accepted_exactly_when_detectable() {
    for diag in [
        "[1.0, 0.0, 0.0, 0.0]",
        "[0.0, 0.0, 0.0, 1.0]",
        "[0.0, 0.0, 0.0, 0.0]",
    ] {
        let text = case_study_with("mpc", "").replace(
            "q = 1.0            # Q_c = I₄",
            &format!("q = {{ diagonal = {diag} }}"),
        );
        let base = Scenario::from_toml_str(&std::fs::read_to_string(CASE_STUDY).unwrap()).unwrap();
        let d: Vec<f64> = diag
            .trim_matches(|c| c == '[' || c == ']')
            .split(',')
            .map(|v| v.trim().parse().unwrap())
            .collect();
        let q = faer::Mat::from_fn(4, 4, |i, j| if i == j { d[i] } else { 0.0 });
        let modes = mpc_core::detectable::undetectable_modes(base.plant.a(), q.as_ref()).unwrap();
        match Scenario::from_toml_str(&text) {
            Ok(s) => {
                assert!(modes.is_empty(), "{diag}: accepted with {modes:?}");
                let r = s.resolve().unwrap();
                assert_eq!(r.mpc().unwrap().q_c()[(1, 1)], 0.0);
            }
            Err(e) => {
                assert!(
                    !modes.is_empty(),
                    "{diag}: refused although detectable: {e}"
                );
                let e = e.to_string();
                assert!(e.contains("mpc.q") && e.contains("|λ|"), "{e}");
            }
        }
    }
}

/// The case study with its `[noise]` section replaced by `noise`.
fn with_noise(noise: &str) -> Result<Scenario, lti_model::ModelError> {
    let text = std::fs::read_to_string(CASE_STUDY).unwrap();
    let start = text.find("[noise]").unwrap();
    let end = text.find("[simulation]").unwrap();
    let text = format!("{}[noise]\n{noise}\n\n{}", &text[..start], &text[end..]);
    Scenario::from_toml_str(&text)
}

fn run(s: &Scenario, steps: usize) -> closed_loop::record::Trace {
    let mut o = LoopOptions::from_scenario(s).unwrap();
    o.steps = steps;
    o.controller = ControllerChoice::ExactMpc;
    let mut cl = crate::build(s, &o).unwrap();
    cl.run().unwrap().clone()
}

#[test]
fn truncated_normal_noise_is_seeded_bounded_and_counted_against_w() {
    // Rao–Rawlings–Lee-style nonnegative noise: N(0, 0.05²) truncated to [0, 0.2] per
    // component, while the MHE assumes 𝒲 = [−0.1, 0.1]⁵.
    let s = with_noise(
        "kind = \"truncated-normal\"\ncovariance = 0.0025\ntruncate = { lower = 0.0, upper = 0.2 }\nseed = 11",
    )
    .unwrap();
    assert!(s.noise.can_leave(&s.sets.disturbance));
    let (a, b) = (run(&s, 60), run(&s, 60));
    let w = &s.sets.disturbance;
    let mut above = 0;
    for t in 0..a.len() {
        assert_eq!(a.w(t), b.w(t), "seeded: t = {t}");
        for &v in a.w(t).unwrap() {
            assert!((0.0..=0.2).contains(&v), "t = {t}: {v}");
            above += usize::from(v > 0.1);
        }
    }
    let outside = closed_loop::scenario::draws_outside(&a, w);
    assert!(above > 0 && !outside.is_empty(), "{above} {outside:?}");
    // Every step with a component above 0.1 is counted, and only those.
    for t in 0..a.len() {
        let leaves = a.w(t).unwrap().iter().any(|v| *v > 0.1);
        assert_eq!(leaves, outside.contains(&t), "t = {t}");
    }
    // Truncated to 𝒲 itself (the default): nothing leaves.
    let inside = with_noise("kind = \"truncated-normal\"\ncovariance = 0.0025\nseed = 11").unwrap();
    assert!(!inside.noise.can_leave(&inside.sets.disturbance));
    assert!(closed_loop::scenario::draws_outside(&run(&inside, 60), w).is_empty());
    // The canonical TOML keeps the kind, the truncation and the mean.
    let again = Scenario::from_toml_str(&s.to_toml_string().unwrap()).unwrap();
    assert_eq!(again.noise.truncate, s.noise.truncate);
}

#[test]
fn a_mean_offset_shifts_the_draws_and_leaves_w() {
    let s = with_noise("kind = \"uniform\"\nmean = [0.05, 0.0, 0.0, 0.0, 0.0]\nseed = 3").unwrap();
    let t = run(&s, 80);
    let m: f64 = (0..t.len()).map(|k| t.w(k).unwrap()[0]).sum::<f64>() / t.len() as f64;
    // Uniform on [−0.05, 0.15]: mean 0.05, σ = 0.2/√12 ≈ 0.058, 5 standard errors ≈ 0.032.
    assert!((m - 0.05).abs() < 0.033, "{m}");
    assert!((0..t.len()).all(|k| (-0.05..=0.15).contains(&t.w(k).unwrap()[0])));
    let outside = closed_loop::scenario::draws_outside(&t, &s.sets.disturbance);
    assert!(
        !outside.is_empty() && outside.len() < t.len(),
        "{outside:?}"
    );
    // Gaussian with a mean; and the nominal scale 0 keeps the offset (w ≡ μ).
    let g = with_noise("kind = \"gaussian\"\ncovariance = 1e-4\nmean = 0.02\nseed = 3");
    assert!(g.is_err(), "a scalar mean is refused (n_w numbers)");
    let zero =
        with_noise("kind = \"uniform\"\nscale = 0.0\nmean = [0.2, 0.0, 0.0, 0.0, 0.0]").unwrap();
    let t = run(&zero, 5);
    assert!((0..5).all(|k| t.w(k).unwrap() == [0.2, 0.0, 0.0, 0.0, 0.0]));
    assert_eq!(
        closed_loop::scenario::draws_outside(&t, &zero.sets.disturbance).len(),
        5
    );
}

#[test]
fn noise_keys_are_validated_by_name() {
    let err = |noise: &str| with_noise(noise).unwrap_err().to_string();
    let e = err("kind = \"uniform\"\nmean = [0.1, 0.0]");
    assert!(e.contains("noise.mean") && e.contains("5"), "{e}");
    let e = err("kind = \"zero\"\nmean = [0.1, 0.0, 0.0, 0.0, 0.0]");
    assert!(e.contains("noise.mean"), "{e}");
    let e = err("kind = \"uniform\"\ntruncate = { lower = 0.0 }");
    assert!(e.contains("noise.truncate"), "{e}");
    let e = err("kind = \"truncated-normal\"");
    assert!(e.contains("noise.covariance"), "{e}");
    let e = err(
        "kind = \"truncated-normal\"\ncovariance = [[1, 0.5, 0, 0, 0], [0.5, 1, 0, 0, 0], [0, 0, 1, 0, 0], [0, 0, 0, 1, 0], [0, 0, 0, 0, 1]]",
    );
    assert!(
        e.contains("noise.covariance") && e.contains("diagonal"),
        "{e}"
    );
    let e = err(
        "kind = \"truncated-normal\"\ncovariance = 1.0\ntruncate = { lower = 0.0, upper = 0.0 }",
    );
    assert!(e.contains("noise.truncate"), "{e}");
}

/// The standard predictor-form Kalman filter written out with dense matrices (no shared
/// code with `mhe_core::KalmanFilter`), for Q̄ = E Σ_w,11 Eᵀ, R̄ = F Σ_w,22 Fᵀ + Σ_v,
/// S̄ = E Σ_w,12 Fᵀ.
fn dense_kalman(
    sys: &lti_model::LtiSystem,
    prior: &[f64],
    pi0: faer::Mat<f64>,
    sw: &faer::Mat<f64>,
    sv: &faer::Mat<f64>,
    trace: &closed_loop::record::Trace,
) -> Vec<Vec<f64>> {
    use faer::linalg::solvers::DenseSolveCore;
    let (nx, nw1, nw2) = (sys.nx(), sys.nw1(), sys.nw2());
    let (a, b, c, e, f) = (sys.a(), sys.b(), sys.c(), sys.e(), sys.f());
    let s11 = sw.as_ref().submatrix(0, 0, nw1, nw1);
    let s12 = sw.as_ref().submatrix(0, nw1, nw1, nw2);
    let s22 = sw.as_ref().submatrix(nw1, nw1, nw2, nw2);
    let qbar = e * s11 * e.transpose();
    let rbar = f * s22 * f.transpose() + sv;
    let sbar = e * s12 * f.transpose();
    let mut x = faer::Mat::from_fn(nx, 1, |i, _| prior[i]);
    let mut pi = pi0;
    let mut out = Vec::new();
    for t in 0..trace.len() {
        out.push((0..nx).map(|i| x[(i, 0)]).collect());
        let u = faer::Mat::from_fn(sys.nu(), 1, |i, _| trace.u(t).unwrap()[i]);
        let y = faer::Mat::from_fn(sys.ny(), 1, |i, _| trace.y(t).unwrap()[i]);
        let s = c * &pi * c.transpose() + &rbar;
        let k = (a * &pi * c.transpose() + &sbar) * s.partial_piv_lu().inverse();
        x = a * &x + b * &u + &k * (&y - c * &x);
        pi = a * &pi * a.transpose() + &qbar - &k * &s * k.transpose();
    }
    out
}

#[test]
fn the_kalman_baseline_uses_the_mhe_weights_and_matches_a_dense_filter() {
    let s = Scenario::from_toml_str(&std::fs::read_to_string(CASE_STUDY).unwrap()).unwrap();
    let trace = run(&s, 40);
    let resolved = s.clone().resolve().unwrap();
    let cfg = resolved.mhe_config().unwrap();
    let sys = &s.plant;
    let mut kf =
        closed_loop::baseline::kalman_for_mhe(sys, &s.simulation.prior, &cfg.p, &cfg.q, &cfg.r)
            .unwrap();
    let b = closed_loop::baseline::run_on_trace(&mut kf, &trace);
    assert!(b.error.is_none() && !b.diverged(), "{b:?}");
    assert_eq!(b.x_hat.len(), 40);
    // Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹, Σ_v = R⁻¹ computed here by a Cholesky-free route: solve with
    // the explicit inverse of 2P etc.
    use faer::linalg::solvers::DenseSolveCore;
    let half_inv = |m: &faer::Mat<f64>, s: f64| (m * s).partial_piv_lu().inverse();
    let reference = dense_kalman(
        sys,
        &s.simulation.prior,
        half_inv(&cfg.p, 2.0),
        &half_inv(&cfg.q, 2.0),
        &half_inv(&cfg.r, 1.0),
        &trace,
    );
    for t in 0..40 {
        let d: f64 = b.x_hat[t]
            .iter()
            .zip(&reference[t])
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(
            d < 1e-9 * (1.0 + reference[t].iter().map(|v| v.abs()).fold(0.0, f64::max)),
            "t = {t}: {d:e}"
        );
    }
    // The error norms are of x_t − x̂^b_t.
    let e0: f64 = trace
        .x(0)
        .unwrap()
        .iter()
        .zip(&b.x_hat[0])
        .map(|(p, q)| (p - q).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!((b.e_norms[0] - e0).abs() < 1e-12);
}

/// An estimator whose estimate grows without bound: reported diverged, with the step.
#[derive(Debug)]
struct Exploding(Vec<f64>);

impl mhe_core::Estimator for Exploding {
    type Error = mhe_core::MheError;
    fn estimate(&mut self) -> Result<&[f64], Self::Error> {
        Ok(&self.0)
    }
    fn push(&mut self, _u: &[f64], _y: &[f64]) -> Result<(), Self::Error> {
        for v in &mut self.0 {
            *v = 10.0 * *v + 1.0;
        }
        Ok(())
    }
    fn nx(&self) -> usize {
        self.0.len()
    }
}

#[test]
fn a_diverging_baseline_is_reported_diverged() {
    let s = Scenario::from_toml_str(&std::fs::read_to_string(CASE_STUDY).unwrap()).unwrap();
    let trace = run(&s, 40);
    let b = closed_loop::baseline::run_on_trace(&mut Exploding(vec![0.0; 4]), &trace);
    let d = b.divergence.expect("diverged");
    assert!(b.diverged() && d.t > 0 && d.t < 40, "{d:?}");
    assert!(d.to_string().contains("diverged at t ="), "{d}");
}

/// A singular Q_c leaves every constant of the certificate defined: L_π and γ₁,₃ use
/// H = 2(ΓᵀQ̄Γ + R̄) ≻ 0 (R_c ≻ 0) and metrics that are positive definite by construction;
/// a singular DARE solution is left out of the γ₁,₃ metric search, never inverted.
#[test]
fn a_singular_q_c_keeps_the_certificate_finite_or_void_by_name() {
    let text = case_study_with("mpc", "").replace(
        "q = 1.0            # Q_c = I₄",
        "q = { diagonal = [0.0, 0.0, 1.0, 0.0] }",
    );
    let s = Scenario::from_toml_str(&text).unwrap();
    let opts = CertificateOptions {
        gamma13: Gamma13Source::Certified,
        gamma13_sequences: 0,
        lipschitz_pairs: 0,
        solvers: vec![Method::PG],
        ..CertificateOptions::default()
    };
    let c = crate::certify(&s, &opts).unwrap();
    assert!(
        c.l_pi.certified.l_pi().is_finite(),
        "{:?}",
        c.l_pi.certified
    );
    match &c.gamma13.void {
        None => assert!(c.gamma13.used.is_finite() && c.gamma13.used > 0.0),
        Some(v) => assert!(!v.to_string().is_empty()),
    }
    let sc = &c.solvers[0];
    assert!(sc.k_min.is_some() || !sc.void_reasons.is_empty());
    println!(
        "singular Q_c: L_π = {}, γ₁,₃ = {}, K_min = {:?}",
        c.l_pi.certified.l_pi(),
        c.gamma13.used,
        sc.k_min
    );
}
