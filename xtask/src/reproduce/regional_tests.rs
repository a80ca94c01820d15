#![allow(clippy::unwrap_used)]
//! K_reg as `reproduce` reports it: the library's search, ordered between K_lin and K_min,
//! and a reason whenever there is none.

use super::*;
use closed_loop::scenario::LoopOptions;
use closed_loop::scenario::ResolvedScenario;
use iss_certificate::certificate::certify_closed_loop;
use iss_certificate::linear::linear_stability;
use iss_certificate::regional::RegionalOptions;
use iss_certificate::regional::k_reg;
use mhe_report::regional::regional_entry;
use qp_iter::Method;

const STAND_IN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenarios/case-study-certified.toml"
);

fn stand_in() -> ResolvedScenario {
    Scenario::from_file(STAND_IN).unwrap().resolve().unwrap()
}

/// Theorem 1's K_min per method, without the sampled estimates.
fn k_mins(res: &ResolvedScenario, methods: &[Method]) -> Vec<Option<usize>> {
    let opts = CertificateOptions {
        solvers: methods.to_vec(),
        gamma13_sequences: 0,
        lipschitz_pairs: 0,
        ..CertificateOptions::default()
    };
    let cert = certify_closed_loop(res, &opts).unwrap();
    methods
        .iter()
        .map(|&m| cert.solver(m).and_then(|s| s.k_min))
        .collect()
}

/// A small uncertainty around the origin (x₀ = 10⁻⁴·1, prior error 10⁻⁴, w̄ = 10⁻⁶): the
/// region contains it as soon as the linear loop is stable with room to spare. The entry's
/// K_reg is the library's `k_reg` up to the entry's search cap (K_min), its certificate is
/// at K_reg and contains the set, and K_lin ≤ K_reg ≤ K_min with K_lin exact (every K).
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_k_reg_is_the_library_search_between_k_lin_and_k_min() {
    let res = stand_in();
    let mut o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
    o.x0_nominal = vec![1e-4; 4];
    o.x0_radius = 0.0;
    o.prior_error = 1e-4;
    o.w_bar = 1e-6;
    let methods = [Method::ADMM, Method::FISTA];
    let k_min = k_mins(&res, &methods);
    for (&m, &k_min) in methods.iter().zip(&k_min) {
        let k_min = k_min.unwrap();
        let e = regional_entry(&res, m, &Ok(o.clone()), Some(k_min), None);
        assert_eq!(e.search_max, k_min, "{}", e.search_max_reason);
        let direct = k_reg(&res, m, &o, k_min).unwrap();
        assert_eq!(e.k_reg, direct.k_reg, "{m}");
        let k_reg = e.k_reg.unwrap_or_else(|| panic!("{m}: {:?}", e.void));
        assert!(e.void.is_none());
        let c = e.certificate.as_ref().unwrap();
        assert_eq!((e.k, c.k), (Some(k_reg), k_reg));
        assert!(c.contains && c.margin >= 1.0 && c.rho_lin < 1.0);
        assert_eq!(e.tried.len(), direct.tried.len());
        assert!(e.tried.iter().any(|t| t.k == k_reg && t.contains));
        // K_lin exactly: ρ_lin on every K up to K_reg.
        let mut lo = LoopOptions::from_scenario(res.scenario()).unwrap();
        lo.method = m;
        lo.controller = ControllerChoice::ExactMpc;
        let grid: Vec<usize> = (1..=k_reg).collect();
        let lin = linear_stability(&res, &lo, &grid, faer::Par::Seq).unwrap();
        let k_lin = lin.k_lin.unwrap();
        assert!(
            k_lin <= k_reg && k_reg <= k_min,
            "{m}: {k_lin} {k_reg} {k_min}"
        );
        // The summary line carries the three and the ratios.
        let mut e = e;
        e.k_lin = Some(k_lin);
        let text = summary(std::slice::from_ref(&e));
        assert!(
            text.contains(&format!(
                "K_lin = {k_lin}, K_reg = {k_reg}, K_min = {k_min}; K_reg/K_lin = {}, K_min/K_lin = {}",
                lti_model::numfmt::sig4(k_reg as f64 / k_lin as f64),
                lti_model::numfmt::sig4(k_min as f64 / k_lin as f64)
            )),
            "{text}"
        );
    }
}

/// The stand-in's own uncertainty (x₀ = (12, −10, 10, −10), prior error 10.39, w̄ = 0.2236) is
/// in no region, at any K: at t = 1 the MHE's first inner iterate, which does not depend on K,
/// takes a 𝒲 component past its box (×73) under an admissible realization (and at t = 0 the
/// exact MPC's input leaves its box), so the search ends before any K is evaluated and the
/// entry names the row, by how much, and that it holds at every K; a void uncertainty (Gaussian noise without `certificate.w_bar`) keeps its reason.
#[test]
fn no_k_reg_carries_its_reason() {
    let res = stand_in();
    let o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc);
    let e = regional_entry(&res, Method::ADMM_PR, &o, Some(42), Some(7));
    assert_eq!(e.k_reg, None);
    assert_eq!((e.search_max, e.k, e.tried.len()), (42, None, 0));
    assert!(e.certificate.is_none());
    let why = e.void.as_deref().unwrap();
    assert!(
        why.contains("no K whose region contains the scenario's uncertainty exists")
            && why.contains("start-up step t = 1")
            && why.contains("against its bound")
            && why.contains("so this holds at every K (checked once, before the search)")
            // The exact MPC's input at t = 0 from the nominal x₀ leaves |u| ≤ 1: no smaller set.
            && why.contains("The nominal point alone")
            && e.k_free.as_ref().is_some_and(|k| k.scale == 0.0),
        "{why}"
    );
    let text = summary(std::slice::from_ref(&e));
    assert!(text.contains("K_reg = none at any K"), "{text}");
    assert!(text.contains("holds at every K"), "{text}");
    assert!(
        text.contains("uncertainty: ‖x₀ − x₀_nominal‖ ≤ 0, prior error ≤ 10.39, w̄ = 0.2236"),
        "{text}"
    );

    let void = Err(iss_certificate::regional::RegionalVoid::UnboundedNoise);
    let e = regional_entry(&res, Method::ADMM, &void, Some(89), None);
    assert_eq!((e.k_reg, e.k, e.tried.len()), (None, None, 0));
    assert!(e.void.unwrap().contains("certificate.w_bar"));
}

/// Without a K_min the search stops at the documented cap, and at ⌊200 000/n_z⌋ when that is
/// smaller.
#[test]
fn the_search_cap_is_k_min_or_the_documented_cap() {
    use xtask::sweep_engine::{REGIONAL_MAX_K_NZ, REGIONAL_SEARCH_CAP, search_max};
    assert_eq!(search_max(Some(243), 49).0, 243);
    assert_eq!(search_max(None, 49).0, REGIONAL_SEARCH_CAP);
    let (k, why) = search_max(Some(140_227), 14);
    assert_eq!(k, REGIONAL_MAX_K_NZ / 14);
    assert!(why.contains("K_min = 140227"), "{why}");
}

/// K_reg above 2·K_lin, the target, says why: the entry carries the certificate at
/// 2·K_lin (`at_two_k_lin`, from `iss_certificate::regional::k_reg_probing`) and the summary
/// names the row an admissible realization drives past its bound there. The cart-pendulum's
/// FISTA-Jacobi: K_lin = 1, K_reg ≥ 13, and at K = 2 a 𝒲 component of the MHE's box leaves
/// it. With K_reg ≤ 2·K_lin (PG-Jacobi's 112 ≤ 170 on cart-pendulum-regional) no line is
/// printed, and without K_lin nothing is probed.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_k_reg_above_twice_k_lin_names_the_row_that_limits_the_region_there() {
    let res = Scenario::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/cart-pendulum.toml"
    ))
    .unwrap()
    .resolve()
    .unwrap();
    let o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc);
    let fj = Method::JACOBI_PRESETS[1];
    let e = regional_entry(&res, fj, &o, Some(64), Some(1));
    let k_reg = e.k_reg.unwrap_or_else(|| panic!("{:?}", e.void));
    assert!(k_reg > 2, "{k_reg}");
    let p = e.at_two_k_lin.as_ref().expect("K = 2 was evaluated");
    assert_eq!((p.k, p.contains), (2, false));
    assert!(
        p.note.contains("drives a row past its bound")
            && p.note.contains("MHE box")
            && p.note.contains("so a constraint activates"),
        "{}",
        p.note
    );
    let text = summary(std::slice::from_ref(&e));
    assert!(
        text.contains(&format!("not at 2·K_lin = 2: {}", p.note)),
        "{text}"
    );
    // K_reg ≤ 2·K_lin: the same entry with K_lin = K_reg prints no such line.
    let mut within = e.clone();
    within.k_lin = Some(k_reg);
    assert!(!summary(std::slice::from_ref(&within)).contains("not at 2·K_lin"));
    let unprobed = regional_entry(&res, fj, &o, Some(64), None);
    assert!(unprobed.at_two_k_lin.is_none());
    assert_eq!(unprobed.k_reg, e.k_reg);
}

/// Issue 37 item 13: above n_z = 128 ρ_lin is computed for the scenario's method only; the
/// others' K_lin is "not computed" with the reason, in the summary and in the JSON — never
/// "K_lin = none", which reads as "no K on the grid is stable".
#[test]
fn a_k_lin_not_computed_says_so_and_why() {
    let res = stand_in();
    let o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc);
    let why = "not computed: the MHE window has n_z = 300 > 128 variables, so ρ_lin is computed \
               for the scenario's method (admm-pr) only";
    let mut e = regional_entry(&res, Method::ADMM_PR, &o, Some(42), None);
    e.k_lin_not_computed = Some(why.to_string());
    let text = summary(std::slice::from_ref(&e));
    assert!(text.contains("K_lin = not computed,"), "{text}");
    assert!(!text.contains("K_lin = none"), "{text}");
    assert!(
        text.contains("K_lin not computed: the MHE window has n_z = 300 > 128"),
        "{text}"
    );
    let json = serde_json::to_value(certificate_json::v1::RegionalEntry::from(&e))
        .expect("an entry serialises");
    assert_eq!(json["k_lin_not_computed"], why);
    // Computed and none on the grid: the key is absent and the table says "none".
    let mut none = e;
    none.k_lin_not_computed = None;
    assert!(summary(std::slice::from_ref(&none)).contains("K_lin = none,"));
    let json = serde_json::to_value(certificate_json::v1::RegionalEntry::from(&none))
        .expect("an entry serialises");
    assert!(json.get("k_lin_not_computed").is_none());
}
