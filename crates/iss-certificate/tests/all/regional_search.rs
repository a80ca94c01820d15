//! The regional certificate's budget and its K_reg search: what each stage costs and what a
//! smaller budget gives up (only tightness), and the witnesses that end a search.

use closed_loop::scenario::{ControllerChoice, Scenario};
use iss_certificate::regional::{
    RegionalOptions, RegionalVoid, k_reg, regional_certificate, regional_detail,
};
use qp_iter::Method;

use super::regional::STAND_IN;

/// The cart-pendulum (𝒰 = ℝ, default budget) and its own uncertainty with the exact MPC.
fn cart_pendulum() -> (closed_loop::scenario::ResolvedScenario, RegionalOptions) {
    let res = Scenario::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/cart-pendulum.toml"
    ))
    .unwrap()
    .resolve()
    .unwrap();
    let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
    (res, ro)
}

/// The budget (`certificate.phase_seconds`) and the memory limit: a stage whose estimate does
/// not fit is refused before it runs, naming the key; a K_reg search stops at the first
/// evaluation that does not fit and says so, keeping what it certified.
#[test]
fn the_budget_refuses_a_stage_before_it_runs_and_stops_the_search() {
    use iss_certificate::regional::estimate;
    let res = Scenario::from_file(STAND_IN).unwrap().resolve().unwrap();
    let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
    assert_eq!(
        ro.phase_seconds,
        closed_loop::scenario::DEFAULT_PHASE_SECONDS
    );
    let est = estimate(&res, Method::ADMM, 20, &ro, 0.9).unwrap();
    assert!(est.seconds > 0.0 && est.bytes > 0.0 && est.work > 0.0);
    // A budget below the first stage's estimate: refused at once, nothing computed.
    let tiny = RegionalOptions {
        phase_seconds: est.seconds * 1e-6,
        ..ro.clone()
    };
    let started = std::time::Instant::now();
    let e = regional_certificate(&res, Method::ADMM, 20, &tiny).unwrap_err();
    assert!(matches!(e, RegionalVoid::OverBudget { k: 20, .. }), "{e:?}");
    let text = e.to_string();
    assert!(text.contains("certificate.phase_seconds"), "{text}");
    assert!(text.contains("K = 20"), "{text}");
    // A K so large that its rows exceed the memory limit: refused by the estimate, at once.
    let e = regional_certificate(&res, Method::ADMM, 10_000_000, &ro).unwrap_err();
    assert!(matches!(e, RegionalVoid::OverMemory { .. }), "{e:?}");
    assert!(e.to_string().contains("GiB"), "{e}");
    assert!(started.elapsed().as_secs_f64() < 60.0);
    // The search: with a budget that fits K = 1, 2, 4 at their full estimates (an evaluation
    // with less budget left takes fewer exact free-response steps, so it costs at most its
    // estimate), it evaluates them, stops at the first K that does not fit, and says why.
    // FISTA-Jacobi on the cart-pendulum (𝒰 = ℝ and K_lin = 1: no row free of K refutes the
    // set, and K = 1, 2, 4 are stable, so every stage runs).
    let (res, ro) = cart_pendulum();
    let fj = Method::JACOBI_PRESETS[1];
    let cost = |k: usize| estimate(&res, fj, k, &ro, 0.9).unwrap().seconds;
    let budget = cost(1) + cost(2) + cost(4) + 0.5 * cost(8);
    let cut = RegionalOptions {
        phase_seconds: budget,
        ..ro.clone()
    };
    let kr = k_reg(&res, fj, &cut, 1 << 20).unwrap();
    assert_eq!(kr.k_reg, None, "{kr:?}");
    let stopped = kr.stopped.as_ref().map(ToString::to_string).unwrap();
    let stop_k: usize = stopped
        .split("K = ")
        .nth(1)
        .and_then(|t| t.split(':').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{stopped}"));
    assert!(
        stop_k >= 8 && stopped.contains("phase_seconds"),
        "{stopped}"
    );
    assert!(
        kr.tried.iter().any(|t| t.0 == 4) && kr.tried.iter().all(|t| t.0 < stop_k),
        "{:?}",
        kr.tried
    );
    assert!(
        kr.spent_seconds > 0.0 && kr.spent_seconds <= budget,
        "{} of {budget}",
        kr.spent_seconds
    );
    // Without the cut the search goes on past K = 8.
    let full = k_reg(&res, fj, &ro, 16).unwrap();
    assert!(
        full.stopped.is_none() && full.tried.iter().any(|t| t.0 == 16),
        "{full:?}"
    );
}

/// The budget fits stage 2 to what is left (`regional/cost.rs`, `AnalysisPlan`): fewer impulse
/// terms, metrics or exact steps only loosen the certificate. On the cart-pendulum's
/// FISTA-Jacobi, from the least budget that computes a certificate up to a generous one: at a K
/// it certifies, every row's reach stays at or above the generous budget's, the margin never
/// exceeds the generous one, and a certificate that contains the set under a small budget
/// contains it under the large one; at a refuted K no budget contains
/// the set, and a probe that reaches the witness's step finds the same witness (row, step,
/// value), computing one metric besides.
#[test]
fn a_smaller_budget_only_loosens_the_certificate_and_finds_the_same_witness() {
    use iss_certificate::regional::estimate;
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/cart-pendulum-regional.toml"
    );
    let res = Scenario::from_file(path).unwrap().resolve().unwrap();
    let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
    let method: Method = "fista-jacobi".parse().unwrap();
    let with = |seconds: f64| RegionalOptions {
        phase_seconds: seconds,
        ..ro.clone()
    };
    for k in [8, 13] {
        let (big, big_d) = regional_detail(&res, method, k, &with(1e4)).unwrap();
        let full = estimate(&res, method, k, &with(1e4), big.rho_lin)
            .unwrap()
            .seconds;
        let (mut computed, mut witnessed) = (0, 0);
        for fraction in [0.02, 0.05, 0.15, 0.4] {
            let Ok((c, d)) = regional_detail(&res, method, k, &with(full * fraction)) else {
                continue;
            };
            computed += 1;
            if big.witness.is_none() {
                assert!(
                    c.impulse_terms <= big.impulse_terms
                        && c.metrics_evaluated <= big.metrics_evaluated,
                    "K = {k}, {fraction}: {} {} against {} {}",
                    c.impulse_terms,
                    c.metrics_evaluated,
                    big.impulse_terms,
                    big.metrics_evaluated
                );
                assert!(
                    c.margin <= big.margin * (1.0 + 1e-9) + 1e-12,
                    "K = {k}, {fraction}: margin {} above the generous {}",
                    c.margin,
                    big.margin
                );
                assert!(!c.contains || big.contains, "K = {k}, {fraction}");
                for (i, (r, r_big)) in d.reach.iter().zip(&big_d.reach).enumerate() {
                    assert!(
                        *r >= r_big * (1.0 - 1e-9) || *r >= big_d.upper[i].min(-big_d.lower[i]),
                        "K = {k}, {fraction}, row {i}: reach {r} below the generous {r_big}"
                    );
                }
            } else {
                // Refuted: no sound certificate may contain the set, whatever its budget.
                assert!(!c.contains, "K = {k}, {fraction}: contains a refuted set");
            }
            // The generous run's exact steps stop at the witness; a budget whose probe reaches
            // that step finds it too.
            if let Some(w) = big
                .witness
                .as_ref()
                .filter(|_| c.exact_steps >= big.exact_steps)
            {
                let wc = c.witness.as_ref().expect("the probe finds the witness");
                assert_eq!(
                    (wc.row, wc.attained_at),
                    (w.row, w.attained_at),
                    "K = {k}, {fraction}"
                );
                assert!((wc.attained - w.attained).abs() <= 1e-12 * w.attained.abs());
                assert_eq!(c.metrics_evaluated, 1, "a refuted K computes one metric");
                witnessed += 1;
            }
        }
        assert!(computed >= 2, "K = {k}: only {computed} budgets computed");
        assert_eq!(
            big.witness.is_some(),
            witnessed > 0,
            "K = {k}: the refuted K is refuted under some smaller budget too"
        );
    }
}

/// A step-0 witness refutes every K: t = 0 does not depend on K (the window-0 MHE is solved by
/// its warm start, the prior, whatever Φ and K). On the stand-in the exact MPC's input
/// sequence at t = 0 leaves |u| ≤ 1 by a factor above 8 for an admissible prior: the same row
/// and value at K = 1, 3, 40 and for PG, FISTA and ADMM (to 1e-12), and the K_reg search
/// checks step 0 first and ends with `refuted_every_k` (the same row) before any K is
/// evaluated, for every method, ADMM α = 2 (K_lin = 7) included.
#[test]
fn a_step_zero_witness_is_the_same_at_every_k_and_ends_the_search() {
    let res = Scenario::from_file(STAND_IN).unwrap().resolve().unwrap();
    let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
    let mut seen: Option<iss_certificate::regional::Limit> = None;
    for method in [Method::PG, Method::FISTA, Method::ADMM] {
        for k in [1, 3, 40] {
            let c = regional_certificate(&res, method, k, &ro).unwrap();
            let w = c
                .refuted_at_start
                .clone()
                .unwrap_or_else(|| panic!("{method} K = {k}: no step-0 witness"));
            assert!(w.attained > w.bound && w.row.step == Some(0) && !c.contains);
            match &seen {
                None => seen = Some(w),
                Some(s) => {
                    assert_eq!(s.row, w.row, "{method} K = {k}");
                    assert!(
                        (s.attained - w.attained).abs() <= 1e-12 * s.attained,
                        "{method} K = {k}: {} against {}",
                        w.attained,
                        s.attained
                    );
                }
            }
        }
    }
    let s = seen.unwrap();
    assert!(s.attained / s.bound > 8.0, "{s:?}");
    // The search checks the rows free of K first (step 0, and the MHE's first inner iterates at
    // step 1: `lifted::k_free_rows`, test `k_free_rows_are_the_same_at_every_k`): it ends before
    // any K, on the row with the largest ratio among them, at least the step-0 witness's.
    for method in Method::ALL {
        let kr = k_reg(&res, method, &ro, 1 << 10).unwrap();
        assert_eq!(kr.k_reg, None, "{method}");
        assert!(
            kr.tried.is_empty() && kr.certificate.is_none(),
            "{method}: {:?}",
            kr.tried
        );
        let l = kr.refuted_every_k.as_ref().unwrap();
        assert!(
            l.attained / l.bound >= (s.attained / s.bound) * (1.0 - 1e-12),
            "{method}: {l:?} against {s:?}"
        );
        match l.row.step {
            Some(0) => {}
            Some(1) => assert_ne!(l.row.kind, iss_certificate::regional::RowKind::Input),
            _ => panic!("{method}: {l:?}"),
        }
        assert_eq!(l.attained_at, l.row.step.unwrap());
    }
}

/// `KReg::k_free` is exact for the rows free of K: on the free quadrotor and the double
/// integrator (refuted at every K by the MHE's first iterate at t = 1: their prior error against
/// the noise box), the prior error it reports, times 0.99, leaves no row free of K past its
/// bound (the search goes on to evaluate K), and times 1.01 is refuted again; the same for the
/// joint scale of the set. On the stand-in the nominal point alone passes one (the exact MPC's
/// input at t = 0 from x₀ = (12, −10, 10, −10) leaves |u| ≤ 1): every limit is 0.
#[test]
fn the_k_free_limits_are_where_the_refutation_starts() {
    let res = Scenario::from_file(STAND_IN).unwrap().resolve().unwrap();
    let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
    let kr = k_reg(&res, Method::PG, &ro, 2).unwrap();
    assert!(kr.refuted_every_k.is_some());
    assert_eq!(
        (kr.k_free.scale, kr.k_free.max_prior_error),
        (0.0, 0.0),
        "{:?}",
        kr.k_free
    );
    for (name, method) in [
        ("quadrotor-free", Method::PG),
        ("quadrotor-free", Method::ADMM_PR),
        ("double-integrator", Method::FISTA),
    ] {
        let file = format!("{}/../../scenarios/{name}.toml", env!("CARGO_MANIFEST_DIR"));
        let res = Scenario::from_file(&file).unwrap().resolve().unwrap();
        let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
        let kr = k_reg(&res, method, &ro, 2).unwrap();
        assert!(kr.refuted_every_k.is_some(), "{name} {method}");
        let lim = kr.k_free.clone();
        assert!(
            lim.scale < 1.0 && lim.scale > 0.0,
            "{name} {method}: {lim:?}"
        );
        assert!(
            lim.max_prior_error < ro.prior_error,
            "{name} {method}: {lim:?}"
        );
        // Prior error alone (the other radii the user's), then the whole set scaled.
        let prior = |f: f64| RegionalOptions {
            prior_error: lim.max_prior_error * f,
            ..ro.clone()
        };
        let scaled = |f: f64| RegionalOptions {
            prior_error: ro.prior_error * lim.scale * f,
            x0_radius: ro.x0_radius * lim.scale * f,
            w_bar: ro.w_bar * lim.scale * f,
            ..ro.clone()
        };
        let mut cases: Vec<(&str, &dyn Fn(f64) -> RegionalOptions)> = vec![("scale", &scaled)];
        if lim.max_prior_error > 0.0 {
            cases.push(("prior error", &prior));
        } else {
            // A row free of K that the prior does not reach is past its bound at the user's
            // x₀ radius and w̄: an exact prior is refuted too.
            let exact = k_reg(&res, method, &prior(0.0), 2).unwrap();
            assert!(exact.refuted_every_k.is_some(), "{name} {method}");
        }
        for (what, o_of) in cases {
            let below = k_reg(&res, method, &o_of(0.99), 2).unwrap();
            assert!(
                below.refuted_every_k.is_none() && !below.tried.is_empty(),
                "{name} {method} {what} ×0.99: {:?}",
                below.refuted_every_k
            );
            let above = k_reg(&res, method, &o_of(1.01), 2).unwrap();
            assert!(
                above.refuted_every_k.is_some(),
                "{name} {method} {what} ×1.01"
            );
        }
    }
}

/// `k_reg_probing` answers "why not at K = probe?" without changing the search: the same K's
/// with the same margins as `k_reg`, plus the probe evaluated on its own budget. On the
/// cart-pendulum's FISTA-Jacobi (K_reg 13 or 16 by the budget) a probe at K = 3, below K_reg
/// and not a K the search tries, is refuted by a witness: an admissible realization drives a
/// row past its bound there, the same witness the certificate at K = 3 alone finds. A probe
/// above K_reg is not evaluated (unless the search tried it), and a probe is never below the
/// first K.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_a_probe_says_why_k_reg_is_above_it_and_leaves_the_search_as_it_was() {
    use iss_certificate::regional::k_reg_probing;
    let (res, ro) = cart_pendulum();
    let fj = Method::JACOBI_PRESETS[1];
    // The four searches are independent and single-threaded (the slowest test of this
    // binary, its tail on 2 cores): the plain one and the probes at 3 and 2 run side by side,
    // then the probe above the K_reg the plain one found beside the certificate at K = 3.
    // Same calls, same assertions; `spent_seconds` sums estimates, not a clock, so running
    // them together changes none of them.
    let (plain, probed, two) = std::thread::scope(|s| {
        let plain = s.spawn(|| k_reg(&res, fj, &ro, 64).unwrap());
        let probed = s.spawn(|| k_reg_probing(&res, fj, &ro, 64, Some(3)).unwrap());
        let two = s.spawn(|| k_reg_probing(&res, fj, &ro, 64, Some(2)).unwrap());
        let join = |h: std::thread::ScopedJoinHandle<'_, _>| h.join().expect("search thread");
        (join(plain), join(probed), join(two))
    });
    let k_reg_found = plain
        .k_reg
        .expect("FISTA-Jacobi has a K_reg on the cart-pendulum");
    assert!(k_reg_found > 3, "{plain:?}");
    assert!(plain.tried.iter().all(|t| t.0 != 3), "{:?}", plain.tried);
    assert_eq!(probed.k_reg, plain.k_reg);
    assert_eq!(probed.certificate, plain.certificate);
    let without_probe: Vec<(usize, f64)> =
        probed.tried.iter().copied().filter(|t| t.0 != 3).collect();
    assert_eq!(
        format!("{without_probe:?}"),
        format!("{:?}", plain.tried),
        "the search's own K's and margins"
    );
    let p = probed
        .probe
        .as_ref()
        .expect("the probe at K = 3 was evaluated");
    assert_eq!(p.k, 3);
    let c = p.certificate.as_ref().unwrap();
    assert!(!c.contains && c.k == 3, "{c:?}");
    let w = c.witness.as_ref().expect("a witness refutes K = 3");
    assert!(w.attained > w.bound, "{w:?}");
    // The certificate at K = 3 alone, beside the search with a probe above the K_reg found.
    let (alone, above) = std::thread::scope(|s| {
        let above = s.spawn(|| k_reg_probing(&res, fj, &ro, 64, Some(k_reg_found + 5)).unwrap());
        let alone = regional_certificate(&res, fj, 3, &ro).unwrap();
        (alone, above.join().expect("search thread"))
    });
    assert_eq!(
        alone.witness.as_ref().map(|l| (l.row, l.attained_at)),
        Some((w.row, w.attained_at))
    );
    assert!(probed.spent_seconds > plain.spent_seconds);
    // Above K_reg: the search's answer stands, the probe is not evaluated.
    assert_eq!(above.k_reg, plain.k_reg);
    assert!(above.probe.is_none(), "{:?}", above.probe);
    // A probe the search tries anyway (a power of two below K_reg) is kept at no cost.
    assert_eq!(two.probe.as_ref().map(|p| p.k), Some(2));
    assert_eq!(two.spent_seconds, plain.spent_seconds);
}
