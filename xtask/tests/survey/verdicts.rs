//! One verdict on generated tiny plants: `coverage::verdict` (what `reproduce`'s
//! `certified`, the sweep's `certified` column, `export`'s `MHE_CERTIFIED` and `certify`
//! state) checked against what it must mean, configuration by configuration.

use closed_loop::scenario::{ControllerChoice, ResolvedScenario, Scenario};
use iss_certificate::certificate::certify_closed_loop;
use iss_certificate::coverage::{
    CertificateKind, Certified, Configuration, PairVerdict, Scalar, global_of, solver_certified,
    verdict, verdict_options,
};
use qp_iter::Method;
use toml::Value;

use crate::generate::{Base, base, chain, scenario_table, to_text};
use crate::{Tally, draw, runner};

const METHODS: [Method; 3] = [Method::PG, Method::FISTA, Method::ADMM_PR];

fn resolve(b: &Base, warm_start: &str) -> Result<ResolvedScenario, String> {
    let mut t = scenario_table(b);
    if let Some(m) = t.get_mut("mhe").and_then(Value::as_table_mut) {
        m.insert("warm_start".into(), Value::String(warm_start.into()));
    }
    Scenario::from_toml_str(&to_text(&t))
        .map_err(|e| chain(&e))?
        .resolve()
        .map_err(|e| chain(&e))
}

pub fn survey(seed: u64, plants: usize) -> Tally {
    let mut tally = Tally::default();
    let mut rn = runner(seed, 2);
    let strategy = base();
    for _ in 0..plants {
        let b = draw(&mut rn, &strategy);
        let (paper, shifted) = match (resolve(&b, "paper"), resolve(&b, "shifted")) {
            (Ok(p), Ok(s)) => (p, s),
            (Err(e), _) | (_, Err(e)) => {
                // A valid generated plant is refused only by a premise of its own (e.g. η
                // too large for M): counted, not a verdict case.
                tally.cases += 1;
                tally.refused += 1;
                let _ = e;
                continue;
            }
        };
        if paper.ioss().is_some_and(|r| r.is_err()) {
            tally.cases += 1;
            tally.refused += 1;
            continue;
        }
        let opts = verdict_options(paper.scenario(), METHODS.to_vec(), None);
        let cert = match certify_closed_loop(&paper, &opts) {
            Ok(c) => c,
            Err(e) => {
                tally.cases += 1;
                tally.finding(format!(
                    "the certificate fails on a valid plant: {}\n--- plant {b:?}",
                    chain(&e)
                ));
                continue;
            }
        };
        for method in METHODS {
            let Some(sc) = cert.solver(method) else {
                tally.finding(format!("no entry for {method:?}\n--- plant {b:?}"));
                continue;
            };
            // The verdict's floor: the smaller of Theorem 1's K_min and the global loop
            // certificate's K_glob (every K ≥ K_glob is certified by it).
            // The iteration chain's K_chain lowers it further (that K only: not monotone).
            let g = global_of(&cert, method, ControllerChoice::ExactMpc);
            let k_glob = g.and_then(|g| g.exact.k_glob());
            let k_chain = g.and_then(|g| g.chain.as_ref()).and_then(|c| c.k_chain());
            let k_min = [sc.k_min, k_glob, k_chain].into_iter().flatten().min();
            let mut ks = vec![1usize, 2, 3, 50, 1000];
            if let Some(k) = k_min {
                ks.extend([k.saturating_sub(1).max(1), k, k + 1, 2 * k]);
            }
            let at = |resolved: &ResolvedScenario, k: usize, controller, scalar| {
                verdict(
                    resolved,
                    &cert,
                    &Configuration {
                        method,
                        k_e: k,
                        controller,
                        scalar,
                    },
                )
            };
            let mut checks: Vec<Result<(), String>> = Vec::new();
            for &k in &ks {
                let f64v = at(&paper, k, ControllerChoice::ExactMpc, Scalar::F64);
                let next = at(&paper, k + 1, ControllerChoice::ExactMpc, Scalar::F64);
                let f32v = at(&paper, k, ControllerChoice::ExactMpc, Scalar::F32);
                let shift = at(&shifted, k, ControllerChoice::ExactMpc, Scalar::F64);
                let lqr = at(&paper, k, ControllerChoice::SaturatedLqr, Scalar::F64);
                checks.push(one(k, k_min, &f64v, &next));
                checks.push(wording(&f64v));
                checks.push(wording(&f32v));
                if f32v.certified == Certified::Yes && f64v.certified != Certified::Yes {
                    checks.push(Err(format!(
                        "f32 certified at K = {k} where f64 is {:?}",
                        f64v.certified
                    )));
                }
                for (what, v) in [
                    ("a shifted warm start", &shift),
                    ("the saturated LQR", &lqr),
                ] {
                    if v.certified == Certified::Yes {
                        checks.push(Err(format!(
                            "certified at K = {k} for {what} (no certificate covers it)"
                        )));
                    }
                }
            }
            // The per-solver `certified` of certificate.json is the verdict at K_min.
            let flag = solver_certified(paper.scenario(), &cert, sc, ControllerChoice::ExactMpc);
            let at_k_min = k_min.map(|k| at(&paper, k, ControllerChoice::ExactMpc, Scalar::F64));
            let yes = at_k_min
                .as_ref()
                .is_some_and(|v| v.certified == Certified::Yes);
            if flag != yes {
                checks.push(Err(format!(
                    "certificate.json's per-solver certified = {flag}, the verdict at K_min \
                     {k_min:?} is {:?}",
                    at_k_min.as_ref().map(|v| v.certified)
                )));
            }
            let shifted_flag =
                solver_certified(shifted.scenario(), &cert, sc, ControllerChoice::ExactMpc);
            if shifted_flag {
                checks.push(Err(
                    "certificate.json's per-solver certified = true for a shifted warm start"
                        .into(),
                ));
            }
            for c in checks {
                tally.cases += 1;
                match c {
                    Ok(()) => tally.accepted += 1,
                    Err(why) => {
                        tally.finding(format!("dishonest: {method:?}: {why}\n--- plant {b:?}"))
                    }
                }
            }
        }
    }
    tally
}

/// The verdict at K is "yes" exactly from the floor `k_min` (Theorem 1's K_min or the global
/// certificate's K_glob, the smaller) on, and stays "yes" at K + 1.
fn one(k: usize, k_min: Option<usize>, v: &PairVerdict, next: &PairVerdict) -> Result<(), String> {
    // The iteration chain speaks at the K it checked only: its "yes" need not persist at
    // K + 1, and where it was not checked (or found none above its K_chain) the verdict says
    // so instead of a plain "no".
    let chain = v.certificate == Some(CertificateKind::Chain)
        || v.reason_text().contains("the iteration chain");
    match v.certified {
        Certified::Yes if chain => {
            if k_min.is_none_or(|m| k < m) || v.k_min != k_min {
                return Err(format!("chain's yes at K = {k} with floor {k_min:?}"));
            }
        }
        _ if chain && k_min.is_some_and(|m| k > m) => {}
        Certified::Yes => {
            if k_min.is_none_or(|m| k < m) || v.k_min != k_min {
                return Err(format!(
                    "yes at K = {k} with K_min {k_min:?} (verdict's {:?})",
                    v.k_min
                ));
            }
            if next.certified != Certified::Yes {
                return Err(format!(
                    "yes at K = {k}, {:?} at K + 1: {}",
                    next.certified,
                    next.reason_text()
                ));
            }
        }
        Certified::No => {
            if k_min.is_none_or(|m| k >= m) {
                return Err(format!(
                    "no at K = {k} with K_min {k_min:?}: {}",
                    v.reason_text()
                ));
            }
        }
        // Void, not computed, or a verdict this survey does not know: never "yes".
        _ => {
            if k_min.is_some() && v.certificate.is_some() {
                return Err(format!(
                    "{:?} at K = {k} although K_min = {k_min:?}: {}",
                    v.certified,
                    v.reason_text()
                ));
            }
        }
    }
    Ok(())
}

/// A "not computed" names the key that computes it: the budget `certificate.phase_seconds`,
/// or `mhe.iterations` where the iteration chain was not checked at this K.
fn names_a_key(v: &PairVerdict) -> bool {
    let r = v.reason_text();
    r.contains("phase_seconds") || (r.contains("not checked at K") && r.contains("mhe.iterations"))
}

/// "void" never with a budget cause, "not computed" only with one (or the chain not checked at K); "void" and "not
/// computed" say why ("no" carries its K_min).
fn wording(v: &PairVerdict) -> Result<(), String> {
    let budget = v.reason_text().contains("phase_seconds") || v.reason_text().contains("budget");
    match v.certified {
        // "no" says why by its K_min (checked in `one`).
        Certified::Yes | Certified::No => Ok(()),
        _ if v.reason_text().trim().is_empty() => {
            Err(format!("{:?} without a reason", v.certified))
        }
        Certified::Void if budget => Err(format!("void with a budget cause: {}", v.reason_text())),
        // Not computed: a budget (naming `certificate.phase_seconds`), or the iteration chain
        // not checked at this K (naming `mhe.iterations`, the key that checks it).
        Certified::NotComputed if !names_a_key(v) => Err(format!(
            "not computed without naming `certificate.phase_seconds` or `mhe.iterations`: {}",
            v.reason_text()
        )),
        _ => Ok(()),
    }
}
