//! The export's size limit (before the certificate) and the survey behind docs/embedded.md's
//! budget table: the survey's certified K is `export --k certified`'s.
#![allow(clippy::unwrap_used)]

use std::time::Instant;

use closed_loop::scenario::Scenario;
use qp_iter::Method;

use super::extract::{OwnedProblem, portable_estimator};
use super::survey::{MAX_DATA_BYTES, data_bytes};
use super::tests::workspace_root;
use super::*;

fn scenario(file: &str) -> Scenario {
    Scenario::from_file(workspace_root().join("scenarios").join(file)).unwrap()
}

/// The size bound against the numbers an export actually stores: equal where every window
/// is dense (the certified preset's n_z ≤ 49 < the crossover), for PG (H, F) and ADMM-PR
/// (H, F and the two inverses).
#[test]
fn the_size_bound_counts_the_exported_numbers() {
    let sc = scenario("case-study-certified.toml");
    let resolved = sc.clone().resolve().unwrap();
    for method in [Method::PG, Method::ADMM_PR] {
        let est = portable_estimator(&resolved, method, 1).unwrap();
        let p = OwnedProblem::from_estimator(&est, &sc.plant).unwrap();
        let stored: usize = (p.windows.iter())
            .map(|w| {
                assert!(w.structured.is_none());
                w.h.len() + w.f.len() + w.m_rho.len() + w.m_inv.len()
            })
            .sum();
        assert_eq!(data_bytes(&sc, method, ScalarKind::F64), 8 * stored);
        assert_eq!(data_bytes(&sc, method, ScalarKind::F32), 4 * stored);
    }
}

/// thermal-rod-m30 (windows up to n_z = 710) is refused by the scenario check, before the
/// certificate (which alone took minutes), naming `mhe.horizon`; thermal-rod-m10 passes.
#[test]
fn a_too_large_export_is_refused_before_the_certificate() {
    let big = scenario("thermal-rod-m30.toml");
    let start = Instant::now();
    for method in Method::ALL {
        for scalar in [ScalarKind::F64, ScalarKind::F32] {
            let o = ExportOptions {
                method: Some(method),
                scalar,
                ..Default::default()
            };
            let e = o.check_scenario(&big).unwrap_err();
            assert!(matches!(e, ExportError::Scenario { .. }), "{e:?}");
            let msg = e.to_string();
            assert!(
                msg.starts_with("`mhe.horizon` = 30:") && msg.contains("n_z = 710"),
                "{msg}"
            );
            assert!(data_bytes(&big, method, scalar) > MAX_DATA_BYTES);
        }
    }
    // The survey says so per method, without computing a certificate.
    let resolved = big.resolve().unwrap();
    let s = survey(&resolved, &ExportOptions::default(), &[]).unwrap();
    assert_eq!(s.len(), Method::ALL.len());
    assert!(
        s.iter()
            .all(|m| m.f64.verdict == "refused" && m.f32.verdict == "refused" && m.f64.k.is_none())
    );
    assert!(start.elapsed().as_secs() < 10, "{:?}", start.elapsed());
    let mid = scenario("thermal-rod-m10.toml");
    for method in Method::ALL {
        let o = ExportOptions {
            method: Some(method),
            ..Default::default()
        };
        assert!(o.check_scenario(&mid).is_ok(), "{}", method.name());
    }
}

/// The survey's certified K per scalar is what `export --k certified` exports (one verdict),
/// its budget is the export's, and an f32 K it does not certify has a short reason.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_the_survey_agrees_with_the_export() {
    let sc = scenario("double-integrator.toml");
    let resolved = sc.resolve().unwrap();
    let o = ExportOptions::default();
    let s = survey(&resolved, &o, &[Method::ADMM_PR, Method::FISTA]).unwrap();
    assert_eq!(s.len(), 2);
    let m = &s[0];
    assert_eq!(m.method, "admm-pr");
    let mut eo = ExportOptions {
        method: Some(Method::ADMM_PR),
        ..Default::default()
    };
    let art = export(&resolved, &eo).unwrap();
    assert_eq!(m.f64.k, Some(art.k()));
    assert_eq!(m.f64.verdict, "yes");
    let summaries = |a: &crate::Artefact| -> Vec<String> {
        a.budgets()
            .iter()
            .map(mhe_budget::Budget::summary)
            .collect()
    };
    let from_survey: Vec<_> = m.f64.budget.iter().map(|b| b.summary.clone()).collect();
    assert_eq!(from_survey, summaries(&art));
    // f32: ADMM's rounding model (session 26) certifies K = 68 by the global certificate in
    // f32 (67 exact), and `export --scalar f32 --k certified` exports that K.
    eo.scalar = ScalarKind::F32;
    let art32 = export(&resolved, &eo).unwrap();
    assert_eq!(m.f32.k, Some(art32.k()));
    assert_eq!(m.f32.verdict, "yes");
    assert!(m.f32.k.is_some_and(|k| k >= art.k()), "{:?}", m.f32.k);
    let from_survey: Vec<_> = m.f32.budget.iter().map(|b| b.summary.clone()).collect();
    assert_eq!(from_survey, summaries(&art32));
    // FISTA has no f32 bound at this window's κ (its incremental rate does not exist): not
    // certified, with a short cell and the whole reason.
    let f = &s[1];
    assert_eq!(f.method, "fista");
    assert_eq!(f.f32.k, None);
    let short = f.f32.short_reason.as_deref().unwrap();
    assert!(
        short.starts_with("f32: ") && short.chars().count() <= 60,
        "{short}"
    );
    let whole = f.f32.reason.as_deref().unwrap();
    assert!(whole.len() > short.len());
    let e = export(
        &resolved,
        &ExportOptions {
            method: Some(Method::FISTA),
            scalar: ScalarKind::F32,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        matches!(e, ExportError::NotCertified { option: "k", .. }),
        "{e:?}"
    );
}
