//! The relative check of LMI (2) (issue 11, item 5): scaled-down P refused, a P from an
//! independent SDP solve accepted, scale invariance, and agreement of `verify` with an
//! eigenvalue check of the LMI matrix assembled here from its blocks.

use faer::{Mat, Side};
use lti_model::ioss::{self, LMI_RELATIVE_TOL, P_MIN_RATIO};
use lti_model::{LmiFailure, LtiSystem, ModelError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn case_study() -> (LtiSystem, Mat<f64>, Mat<f64>) {
    (
        lti_model::presets::case_study_plant(),
        Mat::identity(5, 5),
        Mat::identity(1, 1),
    )
}

fn rows(r: &[[f64; 4]; 4]) -> Mat<f64> {
    Mat::from_fn(4, 4, |i, j| r[i][j])
}

/// P from an independent SDP solve on the case study (scenarios/case-study.toml: η = 0.8,
/// Q = I₅, R = 1), outside this repository, with cvxpy 1.7 and its CLARABEL solver:
///
/// ```text
/// maximise trace(P)  s.t.  J(P) + m·S(P) ⪯ 0,  P ⪰ 0,   m = 1e-6
/// J = GᵀPG − diag(ηP, Q) − HᵀRH,  S = GᵀPG + diag(P, Q) + HᵀRH,  G = [A I 0], H = [C 0 1]
/// ```
///
/// (`P = cp.Variable((4, 4), symmetric=True)`, `cp.bmat` for the blocks, the LMI constraint
/// `(M + M.T)/2 << 0`, `prob.solve(solver="CLARABEL")`, then `(P + Pᵀ)/2` printed with
/// `repr`). The margin m puts P strictly inside the feasible set, so solver accuracy
/// (≈ 1e-8) cannot push it out. numpy measured, for this P, μ = λ_max(L⁻¹JL⁻ᵀ) with
/// S = LLᵀ: −9.994738939561587e-07.
const SDP_P_MARGIN: [[f64; 4]; 4] = [
    [
        0.5807500330039143,
        -0.07815598514933901,
        0.009290302781362674,
        -0.23596923409176712,
    ],
    [
        -0.07815598514933901,
        0.6877364719984909,
        0.045381108026235156,
        -0.05358428421378354,
    ],
    [
        0.009290302781362674,
        0.045381108026235156,
        0.9813910796830972,
        -0.01591900994588476,
    ],
    [
        -0.23596923409176712,
        -0.05358428421378354,
        -0.01591900994588476,
        0.5028532690432853,
    ],
];
/// μ of [`SDP_P_MARGIN`] measured by numpy (Cholesky of S, `eigvalsh`).
const SDP_P_MARGIN_MU: f64 = -9.994738939561587e-07;
/// trace(P) of the same SDP with m = 0: the maximal trace over LMI (2), which the maximal
/// solution P* attains (P* ⪰ every feasible P).
const SDP_MAX_TRACE: f64 = 2.7527380939086266;

/// J and S of LMI (2) assembled here block by block (not through `ioss`).
pub fn lmi_and_scale_by_blocks(
    sys: &LtiSystem,
    eta: f64,
    q: &Mat<f64>,
    r: &Mat<f64>,
    p: &Mat<f64>,
) -> (Mat<f64>, Mat<f64>) {
    let (a, c) = (sys.a().to_owned(), sys.c().to_owned());
    let (bb, db) = (sys.b_bar(), sys.d_bar());
    let apa = a.transpose() * p * &a;
    let crc = c.transpose() * r * &c;
    let apb = a.transpose() * p * &bb;
    let crd = c.transpose() * r * &db;
    let bpb = bb.transpose() * p * &bb;
    let drd = db.transpose() * r * &db;
    let j11 = &apa - p * eta - &crc;
    let j12 = &apb - &crd;
    let j22 = &bpb - q - &drd;
    let s11 = &apa + p + &crc;
    let s12 = &apb + &crd;
    let s22 = &bpb + q + &drd;
    let (nx, nw) = (sys.nx(), sys.nw());
    let assemble = |m11: &Mat<f64>, m12: &Mat<f64>, m22: &Mat<f64>| {
        Mat::from_fn(nx + nw, nx + nw, |i, j| match (i < nx, j < nx) {
            (true, true) => m11[(i, j)],
            (true, false) => m12[(i, j - nx)],
            (false, true) => m12[(j, i - nx)],
            (false, false) => m22[(i - nx, j - nx)],
        })
    };
    (assemble(&j11, &j12, &j22), assemble(&s11, &s12, &s22))
}

fn lambda_max(m: &Mat<f64>) -> f64 {
    let s = Mat::from_fn(m.nrows(), m.ncols(), |i, j| 0.5 * (m[(i, j)] + m[(j, i)]));
    let ev = s.self_adjoint_eigenvalues(Side::Lower).unwrap();
    ev.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

fn lambda_min(m: &Mat<f64>) -> f64 {
    let s = Mat::from_fn(m.nrows(), m.ncols(), |i, j| 0.5 * (m[(i, j)] + m[(j, i)]));
    let ev = s.self_adjoint_eigenvalues(Side::Lower).unwrap();
    ev.iter().copied().fold(f64::INFINITY, f64::min)
}

/// λ_max(J − tS), from the block assembly and an unscaled eigenvalue routine.
fn shifted_lambda_max(j: &Mat<f64>, s: &Mat<f64>, t: f64) -> f64 {
    lambda_max(&(j - s * t))
}

#[test]
fn scaled_down_identity_is_refused_on_case_study() {
    let (sys, q, r) = case_study();
    // Independent witness that every P = c·I violates (★): for x ∈ ker C and w = 0, (★)
    // reads c‖Ax‖² ≤ 0.8c‖x‖², i.e. needs Nᵀ(AᵀA − 0.8I)N ⪯ 0 for a basis N of ker C.
    let c = sys.c().to_owned();
    let svd = c.svd().unwrap();
    let v = svd.V();
    let n = Mat::from_fn(4, 3, |i, j| v[(i, 1 + j)]);
    assert!((&c * &n).norm_max() < 1e-14);
    let a = sys.a().to_owned();
    let witness =
        lambda_max(&(n.transpose() * (a.transpose() * &a - Mat::<f64>::identity(4, 4) * 0.8) * &n));
    assert!(witness > 1e-3, "witness {witness}");

    for scale in [1e-12, 1e-9, 1.0] {
        let p = Mat::<f64>::identity(4, 4) * scale;
        let err = ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), p.as_ref()).unwrap_err();
        let ModelError::LmiInfeasible {
            cause:
                LmiFailure::Violated {
                    relative_violation,
                    tolerance,
                    lmi_max_eigenvalue,
                },
        } = err
        else {
            panic!("scale {scale}: {err:?}")
        };
        assert_eq!(tolerance, LMI_RELATIVE_TOL);
        // The violation is a property of the direction, not of P's size: μ is per cent.
        assert!(
            relative_violation > 1e-2,
            "scale {scale}: μ = {relative_violation:e}"
        );
        let (j, _) = lmi_and_scale_by_blocks(&sys, 0.8, &q, &r, &p);
        let hi = lambda_max(&j);
        assert!(hi > 0.0 && (hi - lmi_max_eigenvalue).abs() <= 1e-12 * (1.0 + hi.abs()));
        if scale == 1e-12 {
            // The finding: +4.9e-14, i.e. ≈ 5 % of P's scale.
            assert!(hi > 1e-2 * scale && hi < scale, "λmax(J) = {hi:e}");
        }
    }
}

#[test]
fn p_from_an_independent_sdp_passes_and_matches_the_maximal_p() {
    let (sys, q, r) = case_study();
    let p_sdp = rows(&SDP_P_MARGIN);
    let cert = ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), p_sdp.as_ref()).unwrap();
    assert_eq!(cert.method, ioss::METHOD_USER);
    // μ measured here agrees with numpy's Cholesky-based value.
    assert!(
        (cert.lmi_relative_violation - SDP_P_MARGIN_MU).abs() <= 1e-11,
        "μ = {:e}",
        cert.lmi_relative_violation
    );
    // The computed P* is the maximal solution: it dominates the SDP's P, by little.
    let star = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()).unwrap();
    assert!(star.lmi_relative_violation <= star.lmi_relative_tolerance);
    let gap = &star.p - &p_sdp;
    let scale = star.p_max_eigenvalue;
    assert!(
        lambda_min(&gap) >= -1e-12 * scale,
        "P* − P_sdp has λ_min {:e}",
        lambda_min(&gap)
    );
    assert!(
        lambda_max(&gap) <= 1e-5 * scale,
        "P* − P_sdp has λ_max {:e}",
        lambda_max(&gap)
    );
    let trace: f64 = (0..4).map(|i| star.p[(i, i)]).sum();
    assert!(
        (trace - SDP_MAX_TRACE).abs() <= 1e-7 * SDP_MAX_TRACE,
        "trace P* = {trace}, SDP max trace {SDP_MAX_TRACE}"
    );
}

#[test]
fn check_is_invariant_under_scaling_of_p_q_r() {
    let (sys, q, r) = case_study();
    let star = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()).unwrap();
    let bigger = &star.p * 1.01;
    let mu_bigger = ioss::assess(
        &sys,
        0.8,
        q.as_ref(),
        r.as_ref(),
        bigger.as_ref(),
        &ioss::IossOptions::default(),
    )
    .unwrap()
    .relative_violation
    .expect("P ≻ 0: μ is measured");
    assert!(mu_bigger > LMI_RELATIVE_TOL);
    for c in [1e-6, 1e6] {
        let (qc, rc) = (&q * c, &r * c);
        let ok = ioss::verify(&sys, 0.8, qc.as_ref(), rc.as_ref(), (&star.p * c).as_ref()).unwrap();
        assert!((ok.lmi_relative_violation - star.lmi_relative_violation).abs() <= 1e-13);
        assert!((ok.p_min_eigenvalue / star.p_min_eigenvalue / c - 1.0).abs() <= 1e-12);
        match ioss::verify(&sys, 0.8, qc.as_ref(), rc.as_ref(), (&bigger * c).as_ref()) {
            Err(ModelError::LmiInfeasible {
                cause:
                    LmiFailure::Violated {
                        relative_violation, ..
                    },
            }) => assert!((relative_violation - mu_bigger).abs() <= 1e-12 * mu_bigger),
            other => panic!("c = {c}: 1.01·P* must be refused, got {other:?}"),
        }
        // The construction is scale invariant too: P*(cQ, cR) = c·P*(Q, R).
        let pc = ioss::certify(&sys, 0.8, qc.as_ref(), rc.as_ref())
            .unwrap()
            .p;
        assert!((&pc - &star.p * c).norm_max() <= 1e-12 * c * star.p.norm_max());
    }
    // P alone scaled down is still valid (J(cP) = cJ(P) − (1 − c)N ⪯ 0) and accepted.
    let small = &star.p * 1e-6;
    assert!(ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), small.as_ref()).is_ok());
}

#[test]
fn numerically_singular_p_is_refused_with_its_ratio() {
    let (sys, q, r) = case_study();
    let star = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()).unwrap();
    // Half of P* is valid; squash one eigen-direction to a ratio below ρ.
    let evd = star.p.self_adjoint_eigen(Side::Lower).unwrap();
    let u = evd.U().to_owned();
    let s = evd.S().column_vector().to_owned();
    let lam = [s[0] * 1e-12, s[1], s[2], s[3]];
    let p = Mat::from_fn(4, 4, |i, j| {
        (0..4).map(|k| u[(i, k)] * lam[k] * u[(j, k)]).sum::<f64>() * 0.5
    });
    match ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), p.as_ref()) {
        Err(ModelError::LmiInfeasible {
            cause:
                LmiFailure::PNumericallySingular {
                    min_eigenvalue,
                    max_eigenvalue,
                    min_ratio,
                },
        }) => {
            assert_eq!(min_ratio, P_MIN_RATIO);
            let ratio = min_eigenvalue / max_eigenvalue;
            assert!(ratio > 0.0 && ratio < P_MIN_RATIO, "ratio {ratio:e}");
        }
        other => panic!("expected PNumericallySingular, got {other:?}"),
    }
}

/// A random symmetric PSD matrix with unit max-norm.
fn random_psd(rng: &mut ChaCha8Rng, n: usize) -> Mat<f64> {
    let g = Mat::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
    let m = g.transpose() * &g;
    let s = m.norm_max();
    &m * (1.0 / s)
}

/// ≥ 1000 seeded cases: `verify` accepts exactly when the independently assembled LMI
/// satisfies λ_max(J − τS) ≤ 0 and λ_min(P) > ρλ_max(P). Cases with μ within 2e-10 of τ
/// (where two correct f64 computations may disagree) are counted
/// and must be rare.
#[test]
fn verify_agrees_with_an_independent_eigenvalue_check() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (mut accepted, mut refused, mut ambiguous, mut cases) = (0, 0, 0, 0);
    while cases < 1200 {
        let nx = rng.random_range(1..=5);
        let ny = rng.random_range(1..=2);
        let nw1 = rng.random_range(1..=nx);
        let a = Mat::from_fn(nx, nx, |_, _| rng.random_range(-0.9..0.9));
        let c = Mat::from_fn(ny, nx, |_, _| rng.random_range(-1.0..1.0));
        let e = Mat::from_fn(nx, nw1, |_, _| rng.random_range(-1.0..1.0));
        let sys =
            LtiSystem::with_disturbance(a, Mat::zeros(nx, 1), c, e, Mat::identity(ny, ny)).unwrap();
        let nw = nw1 + ny;
        let g = Mat::from_fn(nw, nw, |_, _| rng.random_range(-1.0..1.0));
        let q = g.transpose() * &g + Mat::<f64>::identity(nw, nw) * 0.1;
        let r = Mat::from_fn(ny, ny, |i, j| {
            if i == j {
                rng.random_range(0.1..3.0)
            } else {
                0.0
            }
        });
        let eta = rng.random_range(0.6..0.99);
        let Ok(star) = ioss::certify(&sys, eta, q.as_ref(), r.as_ref()) else {
            continue;
        };
        // Ten P per system: c·P*, P* enlarged by 1e-12…1e-4 (μ around τ), c·P* ± a PSD
        // perturbation, a random PD matrix, all at a random overall scale of (P, Q, R).
        for _ in 0..10 {
            let norm = star.p.norm_max();
            let p = match rng.random_range(0..4) {
                0 => &star.p * rng.random_range(0.2..1.1),
                // Just above the maximal P: violations from 1e-12 to 1e-4, around τ.
                1 => &star.p * (1.0 + 10f64.powf(rng.random_range(-12.0..-4.0))),
                2 => {
                    &star.p * rng.random_range(0.5..1.0)
                        + random_psd(&mut rng, nx) * (norm * rng.random_range(-0.3..0.3))
                }
                _ => {
                    random_psd(&mut rng, nx) * norm
                        + Mat::<f64>::identity(nx, nx) * (norm * rng.random_range(1e-3..0.5))
                }
            };
            let k = 10f64.powf(rng.random_range(-8.0..8.0));
            let (p, qk, rk) = (&p * k, &q * k, &r * k);
            cases += 1;
            let (j, s) = lmi_and_scale_by_blocks(&sys, eta, &qk, &rk, &p);
            let (p_lo, p_hi) = (lambda_min(&p), lambda_max(&p));
            let got = ioss::verify(&sys, eta, qk.as_ref(), rk.as_ref(), p.as_ref());
            if !(p_lo > 0.0) {
                assert!(matches!(got, Err(ModelError::NotPositiveDefinite { .. })));
                refused += 1;
                continue;
            }
            let ratio_ok = p_lo > P_MIN_RATIO * p_hi;
            let tau = LMI_RELATIVE_TOL;
            let clear_pass = shifted_lambda_max(&j, &s, tau - 2e-10) <= 0.0;
            let clear_fail = shifted_lambda_max(&j, &s, tau + 2e-10) > 0.0;
            if ratio_ok && !clear_pass && !clear_fail {
                ambiguous += 1;
                continue;
            }
            let expected = ratio_ok && clear_pass;
            assert_eq!(
                got.is_ok(),
                expected,
                "case {cases}: verify {got:?}, independent: ratio_ok {ratio_ok}, λmax(J − τS) = {:e}",
                shifted_lambda_max(&j, &s, tau)
            );
            if expected {
                accepted += 1;
            } else {
                refused += 1;
            }
        }
    }
    eprintln!("accepted {accepted}, refused {refused}, ambiguous {ambiguous}");
    assert!(
        accepted >= 200 && refused >= 200,
        "accepted {accepted}, refused {refused}"
    );
    assert!(
        ambiguous <= 10,
        "{ambiguous} cases within 2e-10 of the threshold"
    );
}

/// A P with a diagonal entry ≤ 0: `assess` reports no μ and no scaled eigenvalues (None,
/// not NaN) and its failure names that entry (its Jacobi scaling does not exist; before,
/// NaN eigenvalues reached a "numerically singular" message).
#[test]
fn a_p_with_a_non_positive_diagonal_entry_is_refused_naming_it() {
    let (sys, q, r) = case_study();
    let star = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()).unwrap();
    for value in [0.0, -1.0] {
        let mut p = star.p.clone();
        p[(2, 2)] = value;
        // `verify` refuses it as input (λ_min(P) < 0) before LMI (2).
        assert!(matches!(
            ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), p.as_ref()),
            Err(ModelError::NotPositiveDefinite { .. })
        ));
        let check = ioss::assess(
            &sys,
            0.8,
            q.as_ref(),
            r.as_ref(),
            p.as_ref(),
            &ioss::IossOptions::default(),
        )
        .unwrap();
        assert_eq!(check.p_nonpositive_diagonal, Some((2, value)));
        assert_eq!(check.p_scaled_min_eigenvalue, None);
        assert_eq!(check.p_ratio(), None);
        assert_eq!(check.relative_violation, None);
        match check.failure() {
            Some(cause @ LmiFailure::PNonPositiveDiagonal { index: 2, .. }) => {
                let text = cause.to_string();
                assert!(text.contains("(2, 2)") && text.contains("mhe.p"), "{text}");
            }
            other => panic!("expected PNonPositiveDiagonal at 2, got {other:?}"),
        }
    }
}
