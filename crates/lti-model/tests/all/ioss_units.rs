//! LMI (2) verdicts that do not depend on the units of q, r or the states (issue 37,
//! item 4): q, r anywhere in 1e-12 … 1e12 and diagonal state scalings up to 10³, against a
//! closed-form maximal P and against the invariance of μ under congruences.

use faer::{Mat, mat};
use lti_model::LtiSystem;
use lti_model::ioss::{self, IossOptions, LMI_RELATIVE_TOL};
use proptest::prelude::*;

/// The plant in units x = T x̃ (T diagonal): Ã = T⁻¹AT, C̃ = CT, Ẽ = T⁻¹E (w¹ in the old
/// units), F unchanged; a P of the old units is T P T in the new.
fn in_units(sys: &LtiSystem, t: &[f64]) -> LtiSystem {
    let n = sys.nx();
    LtiSystem::with_disturbance(
        Mat::from_fn(n, n, |i, j| sys.a()[(i, j)] * t[j] / t[i]),
        Mat::from_fn(n, sys.nu(), |i, j| sys.b()[(i, j)] / t[i]),
        Mat::from_fn(sys.ny(), n, |i, j| sys.c()[(i, j)] * t[j]),
        Mat::from_fn(n, sys.nw1(), |i, j| sys.e()[(i, j)] / t[i]),
        sys.f().to_owned(),
    )
    .expect("a diagonal change of units keeps the shapes")
}

/// The maximal p of LMI (2) for x⁺ = a x + w¹, y = c x + w², Q = diag(q₁, q₂), R = r, by
/// hand: eliminating w² (Schur complement on −q₂ − r) leaves
/// [[(a² − η)p − ρ, ap], [ap, p − q₁]] ⪯ 0 with ρ = c²·r·q₂/(q₂ + r), i.e.
/// ηp² + bp − ρq₁ ≤ 0, b = (a² − η)q₁ + ρ (and p < q₁, implied), so
/// p* = 2ρq₁/(b + √(b² + 4ηρq₁)) (the positive root, without cancellation).
fn scalar_maximal_p(a: f64, c: f64, eta: f64, q1: f64, q2: f64, r: f64) -> f64 {
    let rho = c * c * (r * q2 / (q2 + r));
    let b = (a * a - eta) * q1 + rho;
    2.0 * rho * q1 / (b + (b * b + 4.0 * eta * rho * q1).sqrt())
}

/// The closed form at every weight and unit scaling: p*·(1 − 1e-6) passes, p*·(1 + 1e-3)
/// fails, and certify finds a P ≤ p* that passes (the maximal one up to 1e-6 unless it had
/// to reduce R, and within 1e-4: the construction's margin). On the old check (μ from J in the user's coordinates) p*·(1 − 1e-6) was
/// refused for r/q ≳ 1e9.
#[test]
fn scalar_closed_form_at_every_scale() {
    let (a, c, eta) = (1.1, 0.7, 0.8);
    let decades = [-12, -8, -4, 0, 4, 8, 12];
    let mut cases = 0;
    for &dq in &decades {
        for &dr in &decades {
            for t in [1e-3, 1.0, 1e3] {
                let (q1, r) = (10f64.powi(dq), 10f64.powi(dr));
                let q2 = q1;
                let p_star = scalar_maximal_p(a, c, eta, q1, q2, r);
                let sys = LtiSystem::new(mat![[a]], mat![[1.0]], mat![[c]]).expect("1 × 1");
                let sys = in_units(&sys, &[t]);
                let q = mat![[q1, 0.0], [0.0, q2]];
                let rm = mat![[r]];
                let at = |f: f64| mat![[t * t * p_star * f]];
                let case = format!("q = {q1:e}, r = {r:e}, t = {t:e}, p* = {p_star:e}");
                let below =
                    ioss::verify(&sys, eta, q.as_ref(), rm.as_ref(), at(1.0 - 1e-6).as_ref());
                assert!(below.is_ok(), "{case}: p*(1 − 1e-6) refused: {below:?}");
                let above =
                    ioss::verify(&sys, eta, q.as_ref(), rm.as_ref(), at(1.0 + 1e-3).as_ref());
                assert!(above.is_err(), "{case}: p*(1 + 1e-3) accepted");
                let cert = ioss::certify(&sys, eta, q.as_ref(), rm.as_ref())
                    .unwrap_or_else(|e| panic!("{case}: {e}"));
                let p = cert.p[(0, 0)] / (t * t);
                assert!(
                    p <= p_star * (1.0 + 1e-6),
                    "{case}: p = {p:e} above the maximum"
                );
                // The construction tightens the data by ε ≤ 1e-6 for a margin; at r/q = 1e12
                // the maximal p is that sensitive to it (measured: 2.2e-5 relative).
                // Beyond r/q = 1e12 the doubling's P passes but need not be maximal
                // (measured: 6× below p* at r/q = 1e16).
                if cert.method == ioss::METHOD_MAXIMAL && (dr - dq).abs() <= 12 {
                    assert!(p >= p_star * (1.0 - 1e-4), "{case}: p = {p:e} not maximal");
                }
                cases += 1;
            }
        }
    }
    assert_eq!(cases, 7 * 7 * 3);
}

/// The case study of the issue: `mhe.r = 1e12` (q = 1), `mhe.q = 1e-10` (r = 1) and both
/// extremes at once are certified, and the P of q = r = 1 is accepted at r = 1e12 (the old
/// check measured μ = 6.7e-6 for it).
#[test]
fn case_study_extreme_weights_are_certified() {
    let sys = lti_model::presets::case_study_plant();
    let id5 = Mat::<f64>::identity(5, 5);
    let id1 = Mat::<f64>::identity(1, 1);
    let p1 = ioss::certify(&sys, 0.8, id5.as_ref(), id1.as_ref())
        .expect("q = r = 1")
        .p;
    for (q, r) in [
        (1.0, 1e9),
        (1.0, 1e12),
        (1e-10, 1.0),
        (1e-12, 1.0),
        (1e-12, 1e12),
    ] {
        let (qm, rm) = (&id5 * q, &id1 * r);
        let cert = ioss::certify(&sys, 0.8, qm.as_ref(), rm.as_ref())
            .unwrap_or_else(|e| panic!("q = {q}, r = {r}: {e}"));
        assert!(cert.lmi_relative_violation <= LMI_RELATIVE_TOL);
        let scaled = &p1 * q;
        let v = ioss::verify(&sys, 0.8, qm.as_ref(), rm.as_ref(), scaled.as_ref());
        assert!(
            v.is_ok(),
            "q = {q}, r = {r}: the P of q = r = 1 refused: {v:?}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// The verdict and μ are invariant: for q, r in 1e-12 … 1e12 (r ≥ q) and states up to
    /// 10³ apart, certify passes, and the P of q = r = 1 in the new units (T P₁ T·q) passes
    /// with the same μ as at q = r = 1 up to τ/10 (μ is invariant under the congruence;
    /// the old check's rounding was ≈ u·r/q: 6.7e-6 at r/q = 1e12).
    #[test]
    fn verdict_invariant_under_weight_and_state_scaling(
        lq in -12.0f64..12.0,
        lr_above in 0.0f64..24.0,
        units in proptest::collection::vec(-1.5f64..1.5, 4),
    ) {
        let lr = (lq + lr_above).min(12.0);
        let (q, r) = (10f64.powf(lq), 10f64.powf(lr));
        let base = lti_model::presets::case_study_plant();
        let t: Vec<f64> = units.iter().map(|u| 10f64.powf(*u)).collect();
        let sys = in_units(&base, &t);
        let id5 = Mat::<f64>::identity(5, 5);
        let id1 = Mat::<f64>::identity(1, 1);
        let p1 = ioss::certify(&base, 0.8, id5.as_ref(), id1.as_ref()).expect("q = r = 1");
        let mu1 = ioss::assess(&base, 0.8, id5.as_ref(), id1.as_ref(), p1.p.as_ref(),
            &IossOptions::default()).expect("assess").relative_violation.expect("P ≻ 0");
        let (qm, rm) = (&id5 * q, &id1 * r);
        let cert = ioss::certify(&sys, 0.8, qm.as_ref(), rm.as_ref());
        prop_assert!(cert.is_ok(), "q = {q:e}, r = {r:e}, t = {t:?}: {cert:?}");
        let p = Mat::from_fn(4, 4, |i, j| t[i] * p1.p[(i, j)] * t[j] * q);
        let check = ioss::assess(&sys, 0.8, qm.as_ref(), rm.as_ref(), p.as_ref(),
            &IossOptions::default()).expect("assess");
        // The top direction of the pencil has Hv = 0, so μ does not change with r ≥ q
        // either; measured −1.5380e-9 (residual coordinates) and −1.5077e-9 (the user's, at
        // q = r = 1): the two roundings differ by 3e-11, a thirtieth of τ.
        prop_assert!(
            check.relative_violation.is_some_and(|mu| (mu - mu1).abs() < 1e-10),
            "μ = {:?}, at q = r = 1: {mu1:e}",
            check.relative_violation
        );
        prop_assert!(check.passed(), "q = {q:e}, r = {r:e}, t = {t:?}: μ = {:?} (user units: {:?})",
            check.relative_violation, check.relative_violation_original_units);
    }
}

/// Issue 37, item 14a: a P with a subnormal entry is refused with the entry named and the
/// fix (the eigen-solvers used to fail with "NoConvergence"); the same P with 0 there passes.
#[test]
fn subnormal_p_entry_is_a_named_error() {
    let sys = lti_model::presets::case_study_plant();
    let (q, r) = (Mat::<f64>::identity(5, 5), Mat::<f64>::identity(1, 1));
    let p = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref())
        .expect("q = r = 1")
        .p;
    let mut bad = p.clone();
    bad[(0, 3)] = 5e-324;
    bad[(3, 0)] = 5e-324;
    let err = ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), bad.as_ref())
        .expect_err("a subnormal entry is refused");
    let text = err.to_string();
    assert!(
        matches!(err, lti_model::ModelError::Scenario { .. })
            && text.contains("P entry (0, 3)")
            && text.contains("write 0"),
        "{text}"
    );
    let mut fixed = p;
    fixed[(0, 3)] = 0.0;
    fixed[(3, 0)] = 0.0;
    let v = ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), fixed.as_ref());
    assert!(
        !matches!(
            v,
            Err(lti_model::ModelError::Numerical { .. })
                | Err(lti_model::ModelError::Scenario { .. })
        ),
        "{v:?}"
    );
}

/// Well-scaled data keep the user's coordinates, bit for bit: the case study at q = r = 1
/// (the presets of the golden files) has the μ of `xtask/tests/golden/*-certificate.json.gz`.
#[test]
fn well_scaled_check_is_unchanged() {
    let sys = lti_model::presets::case_study_plant();
    let (q, r) = (Mat::<f64>::identity(5, 5), Mat::<f64>::identity(1, 1));
    let cert = ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()).expect("q = r = 1");
    let check = ioss::assess(
        &sys,
        0.8,
        q.as_ref(),
        r.as_ref(),
        cert.p.as_ref(),
        &IossOptions::default(),
    )
    .expect("assess");
    assert_eq!(
        check.relative_violation.map(f64::to_bits),
        check.relative_violation_original_units.map(f64::to_bits)
    );
    assert_eq!(cert.lmi_relative_violation, -1.5076704189025632e-9);
}
