//! `certify --loop`: per method, the three answers to "from which K is the closed loop
//! fine?" side by side — the linear boundary K_lin (necessary), Theorem 1's K_min and the
//! global loop certificate's K_glob (both sufficient; docs/theory.md §4), each budgeted by
//! its own phase budget.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::{Result, anyhow, bail};
use closed_loop::scenario::{LoopOptions, MAX_PHASE_SECONDS, ResolvedScenario, Scenario};
use iss_certificate::certificate::{CertificateOptions, certify_closed_loop};
use iss_certificate::coverage::verdict_options;
use iss_certificate::linear::{linear_stability_all_budgeted, log_spaced};
use iss_certificate::lure::chain_outcome::ChainOutcome;
use iss_certificate::lure::global_outcome::GlobalOutcome;
use qp_iter::Method;

use crate::reproduce::numfmt::num;

/// The eight methods, in the order of the coverage tables.
pub const METHODS: [Method; 8] = Method::ALL;

/// One method's row.
#[derive(Debug, Clone)]
pub struct LoopMethod {
    /// The method.
    pub method: Method,
    /// K_lin on the grid (`None`: `k_lin_note` says why).
    pub k_lin: Option<usize>,
    /// Why K_lin is absent (unstable at every grid K, over the budget, …).
    pub k_lin_note: Option<String>,
    /// Theorem 1's K_min (`None`: `k_min_note` says why).
    pub theorem1_k_min: Option<usize>,
    /// Why K_min is absent.
    pub k_min_note: Option<String>,
    /// The global loop certificate's outcome.
    pub global: GlobalOutcome,
    /// The iteration chain (Theorem L3b, L3c for FISTA; None: not pg, fista or their Jacobi variants).
    pub chain: Option<ChainOutcome>,
}

/// The loop section of the certify document.
#[derive(Debug, Clone)]
pub struct LoopSection {
    /// The budget of the global φ* search (seconds of one core).
    pub global_seconds: f64,
    /// Wall-clock seconds of the whole section.
    pub elapsed_seconds: f64,
    /// One row per method of [`METHODS`].
    pub methods: Vec<LoopMethod>,
}

/// The global budget: `--global-seconds`, else `certificate.phase_seconds`; checked.
pub fn global_budget(scenario: &Scenario, flag: Option<f64>) -> Result<f64> {
    let s = flag.unwrap_or_else(|| scenario.certificate.phase_seconds());
    if !(s > 0.0 && s <= MAX_PHASE_SECONDS) {
        bail!(
            "--global-seconds = {s}: the budget of the global loop certificate must be in \
             (0, {MAX_PHASE_SECONDS:e}] seconds"
        );
    }
    Ok(s)
}

/// K_lin, Theorem 1's K_min and K_glob of every method on `scenario`.
pub fn loop_section(scenario: &Scenario, global_seconds: f64) -> Result<LoopSection> {
    let t0 = Instant::now();
    let resolved = scenario
        .clone()
        .resolve()
        .map_err(|e| anyhow!("--loop needs a scenario that resolves (its [mhe]): {e}"))?;
    let base = LoopOptions::from_scenario(scenario)
        .map_err(|e| anyhow!("--loop needs [mhe] and a controller: {e}"))?;
    let options: Vec<LoopOptions> = METHODS
        .iter()
        .map(|&m| {
            let mut o = base;
            o.method = m;
            o
        })
        .collect();
    let (k_mins, globals, k_min_err) = theorem1_and_global(scenario, &resolved, global_seconds);
    let k_top = k_mins
        .iter()
        .flatten()
        .copied()
        .max()
        .unwrap_or(0)
        .max(2000);
    let linear = linear_stability_all_budgeted(
        &resolved,
        &options,
        &log_spaced(1, k_top, 25),
        scenario.certificate.phase_seconds(),
        &|_, _| {},
    );
    let methods = METHODS
        .iter()
        .zip(k_mins)
        .zip(linear)
        .zip(globals)
        .map(|(((&method, k_min), lin), (global, chain))| {
            let (k_lin, k_lin_note) = match lin {
                Ok(r) => match r.k_lin {
                    Some(k) => (Some(k), None),
                    None => (None, Some(format!("ρ_lin ≥ 1 up to K = {k_top}"))),
                },
                Err(e) => (None, Some(e.to_string())),
            };
            let k_min_note = match (&k_min, &k_min_err) {
                (Some(_), _) => None,
                (None, Some(e)) => Some(e.clone()),
                (None, None) => Some("void or not certified (see `reproduce`)".to_string()),
            };
            LoopMethod {
                method,
                k_lin,
                k_lin_note,
                theorem1_k_min: k_min,
                k_min_note,
                global,
                chain,
            }
        })
        .collect();
    Ok(LoopSection {
        global_seconds,
        elapsed_seconds: t0.elapsed().as_secs_f64(),
        methods,
    })
}

/// One method's global loop certificate and iteration chain.
type MethodOutcomes = (GlobalOutcome, Option<ChainOutcome>);

/// Theorem 1's K_min and the global outcome per method, from the one certificate every
/// command computes (`verdict_options`, the global budget `global_seconds`: the verdict's
/// K_glob is this one), or why none.
fn theorem1_and_global(
    scenario: &Scenario,
    resolved: &ResolvedScenario,
    global_seconds: f64,
) -> (Vec<Option<usize>>, Vec<MethodOutcomes>, Option<String>) {
    let opts = CertificateOptions {
        global_seconds: Some(global_seconds),
        ..verdict_options(scenario, METHODS.to_vec(), None)
    };
    let cert = certify_closed_loop(resolved, &opts);
    let global = |m: Method| match cert.as_ref().map(|c| c.global.as_ref()) {
        Ok(Some(g)) => g.method(m).map_or_else(
            || {
                let reason = format!("no entry for {}", m.name());
                (GlobalOutcome::Unsupported { reason }, None)
            },
            |x| (x.exact.clone(), x.chain.clone()),
        ),
        Ok(None) => {
            let reason = "--loop needs [mhe] and a controller".into();
            (GlobalOutcome::Unsupported { reason }, None)
        }
        Err(e) => {
            let reason = format!("no certificate: {e}");
            (GlobalOutcome::Unsupported { reason }, None)
        }
    };
    let globals = METHODS.iter().map(|&m| global(m)).collect();
    match &cert {
        Ok(c) => (
            METHODS
                .iter()
                .map(|&m| c.solver(m).and_then(|s| s.k_min))
                .collect(),
            globals,
            None,
        ),
        Err(e) => (vec![None; METHODS.len()], globals, Some(e.to_string())),
    }
}

/// The section's lines of the summary: one per method, and every distinct reason (why no
/// K_glob, K_lin or K_min) once below, numbered.
pub fn summary_lines(s: &mut String, l: &LoopSection) {
    let _ = writeln!(
        s,
        "closed loop per method (K_lin necessary; Theorem 1 K_min and K_glob certified; \
         {} s, global budget {} s):",
        num(l.elapsed_seconds),
        num(l.global_seconds)
    );
    let mut notes: Vec<String> = Vec::new();
    let mut note = |text: String| {
        let i = notes.iter().position(|n| *n == text).unwrap_or_else(|| {
            notes.push(text);
            notes.len() - 1
        });
        format!("({})", i + 1)
    };
    for m in &l.methods {
        let mut k = |k: Option<usize>, why: &Option<String>| match (k, why) {
            (Some(k), _) => k.to_string(),
            (None, Some(w)) => format!("— {}", note(w.clone())),
            (None, None) => "—".to_string(),
        };
        let (k_lin, k_min) = (
            k(m.k_lin, &m.k_lin_note),
            k(m.theorem1_k_min, &m.k_min_note),
        );
        let global = match &m.global {
            GlobalOutcome::Certified(_) => m.global.to_string(),
            other => format!("{} {}", short(other), note(other.to_string())),
        };
        let chain = m
            .chain
            .as_ref()
            .map_or_else(String::new, |c| format!("; chain: {c}"));
        let _ = writeln!(
            s,
            "  {:<15} K_lin {:>8}  Theorem 1 {:>8}  global: {global}{chain}",
            m.method.name(),
            k_lin,
            k_min
        );
    }
    for (i, n) in notes.iter().enumerate() {
        let _ = writeln!(s, "  ({}) {n}", i + 1);
    }
}

/// A few words for an outcome without K_glob (the sentence is the note).
fn short(o: &GlobalOutcome) -> &'static str {
    match o {
        GlobalOutcome::PhiBallBinds { .. } => "none: the φ-ball binds",
        GlobalOutcome::OptimumBinds { .. } => "none: the optimum's VI binds",
        GlobalOutcome::LinearUnstable { .. } => "none: ρ_lin ≥ 1",
        GlobalOutcome::UnstableWithBoundedInput { .. } => "none: |λ| > 1 only bounded inputs reach",
        GlobalOutcome::SearchFailed { .. } => "none: the search failed",
        GlobalOutcome::NotComputed { .. } => "not computed within the budget",
        _ => "not applicable",
    }
}

impl From<&LoopSection> for certificate_json::v1::LoopSection {
    fn from(l: &LoopSection) -> Self {
        use certificate_json::v1;
        Self {
            global_seconds: v1::num(l.global_seconds),
            elapsed_seconds: v1::num(l.elapsed_seconds),
            methods: (l.methods.iter())
                .map(|m| v1::LoopMethod {
                    method: m.method.name().to_string(),
                    k_lin: m.k_lin,
                    k_lin_note: m.k_lin_note.clone(),
                    theorem1_k_min: m.theorem1_k_min,
                    k_min_note: m.k_min_note.clone(),
                    global: v1::GlobalLoopOutcome::from(&m.global),
                    k_chain: m.chain.as_ref().and_then(ChainOutcome::k_chain),
                    chain: m.chain.as_ref().map(ToString::to_string),
                })
                .collect(),
        }
    }
}
