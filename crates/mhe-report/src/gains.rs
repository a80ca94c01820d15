//! What the certificate guarantees (issue 27): the certified asymptotic gains of Theorem 1
//! (`iss_certificate::asymptotic`, per method at its K_min) and of the regional certificate (at K_reg),
//! and per simulated run the certified bound next to the measured gains, for
//! certificate.json (`asymptotic_gains`) and the summary.

use iss_certificate::asymptotic::{AsymptoticGains, MeasuredGains, certified_gains};

use closed_loop::scenario::ControllerChoice;
use iss_certificate::certificate::{ClosedLoopCertificate, SolverCertificate};
use iss_certificate::coverage::CertificateKind;
use iss_certificate::lure::chain_outcome::ChainCheck;
use iss_certificate::lure::global_outcome::GlobalOutcome;
use iss_certificate::outcome::VoidReason;
use qp_iter::Method;

use crate::Run;

/// `asymptotic_gains` of certificate.json.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct GainsReport {
    /// What the numbers mean, in one sentence.
    pub meaning: String,
    /// Per method at its K_min: Theorem 1's certified gains and the regional ones.
    pub methods: Vec<MethodGains>,
    /// Per simulated run (same order as `runs`): the certified bound at the run's K next to
    /// the measured gains.
    pub runs: Vec<RunGains>,
}

/// One method's certified asymptotic gains at its K_min.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct MethodGains {
    /// The method.
    pub solver: String,
    /// Its K_min (null when Theorem 1 is void).
    pub k_min: Option<usize>,
    /// Theorem 1's gains at K_min (`iss_certificate::asymptotic::AsymptoticGains`): g_x,
    /// g_ε, g_e and the comparison systems; null when void.
    pub theorem1: Option<AsymptoticGains>,
    /// Why there are none (null when there are).
    pub theorem1_void: Option<String>,
    /// The regional certificate's gains at the K of the regional entry (K_reg, or the largest K
    /// its search tried; null when it has none).
    pub regional: Option<RegionalGains>,
    /// Why there are none.
    pub regional_void: Option<String>,
}

/// The regional certificate's gains (`iss_certificate::regional::RegionalCertificate`).
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RegionalGains {
    /// The K they are certified at.
    pub k: usize,
    /// lim sup‖x_t‖ ≤ gain_x·w̄ inside the region.
    pub gain_x: f64,
    /// lim sup‖e_t‖ ≤ gain_e·w̄ inside the region.
    pub gain_e: f64,
    /// The region contains the scenario's own uncertainty (x0_radius, prior_error, w̄): only
    /// then do these gains speak for the scenario's runs.
    pub contains: bool,
    /// The w̄ of the region.
    pub w_bar: f64,
}

/// One run's certified bound and measured gains.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RunGains {
    /// The run's label (`"K=243"`).
    pub label: String,
    /// Its K.
    pub k: usize,
    /// Its controller.
    pub controller: String,
    /// sup_t‖w_t‖ of the run, the w̄ of the bounds below (null for an empty run).
    pub w_bar: Option<f64>,
    /// Theorem 1's bounds at the run's K with w̄ = `w_bar` (null when void).
    pub certified: Option<CertifiedBound>,
    /// Why there is no certified bound for this run.
    pub certified_void: Option<String>,
    /// The measured gains (`iss_certificate::asymptotic::MeasuredGains`: tail sups over
    /// t ≥ T/2 and whole-run sups, each also per unit of `w_bar`); null for an empty run.
    pub measured: Option<MeasuredGains>,
}

/// g·w̄ for one run, from the certificate that certifies the run's K.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct CertifiedBound {
    /// The certificate the gains are of: Theorem 1 where it covers the run's K, else the
    /// global loop certificate (K ≥ K_glob) or the iteration chain (checked at that K).
    pub certificate: CertificateKind,
    /// g_x.
    pub gain_x: f64,
    /// g_ε (Theorem 1 only: the loop certificates do not bound the inner error ε_t).
    pub gain_epsilon: Option<f64>,
    /// g_e.
    pub gain_e: f64,
    /// lim sup‖x_t‖ ≤ g_x·w̄.
    pub bound_x: f64,
    /// lim sup ε_t ≤ g_ε·w̄ (Theorem 1 only).
    pub bound_epsilon: Option<f64>,
    /// lim sup‖e_t‖ ≤ g_e·w̄.
    pub bound_e: f64,
}

/// The report: every method of `cert` at its K_min with the regional entry of the same
/// method, and every run of the scenario's `solver`.
pub fn report(
    cert: &ClosedLoopCertificate,
    regional: &[crate::regional::RegionalEntry],
    runs: &[Run],
    solver: Method,
    not_covered: Option<&str>,
) -> GainsReport {
    let methods = (cert.solvers.iter())
        .map(|s| method_gains(cert, s, regional))
        .collect();
    let own = cert.solver(solver);
    let runs = (runs.iter())
        .map(|r| run_gains(cert, own, r, not_covered))
        .collect();
    GainsReport {
        meaning: "certified: lim sup_t ‖x_t‖ ≤ g_x·w̄, lim sup_t ε_t ≤ g_ε·w̄, lim sup_t ‖e_t‖ ≤ \
                  g_e·w̄ for every disturbance with sup_t ‖w_t‖₂ ≤ w̄ in 𝒲 (docs/theory.md, \
                  \"Certified asymptotic gains\"); measured: sup over t ≥ T/2 of ‖x_t‖, ε_t, \
                  ‖e_t‖ divided by the run's sup_t ‖w_t‖ (a lower estimate of the true gain once \
                  the transient has decayed)"
            .into(),
        methods,
        runs,
    }
}

/// One method's gains: Theorem 1's at its K_min, the regional certificate's at its K.
fn method_gains(
    cert: &ClosedLoopCertificate,
    s: &SolverCertificate,
    regional: &[crate::regional::RegionalEntry],
) -> MethodGains {
    let name = s.solver.name().into_owned();
    let (theorem1, theorem1_void) = match s.k_min {
        Some(k) => match certified_gains(cert, s, k) {
            Ok(g) => (Some(g), None),
            Err(e) => (None, Some(e.to_string())),
        },
        None => (
            None,
            Some(match &s.not_computed {
                Some(nc) => format!("Theorem 1 is {nc}"),
                None => format!("Theorem 1 is void: {}", VoidReason::join(&s.void_reasons)),
            }),
        ),
    };
    let entry = regional.iter().find(|r| r.solver == name);
    let (regional, regional_void) = match entry {
        Some(r) => match &r.certificate {
            Some(c) => (
                Some(RegionalGains {
                    k: c.k,
                    gain_x: c.gain_x,
                    gain_e: c.gain_e,
                    contains: c.contains,
                    w_bar: c.options.w_bar,
                }),
                None,
            ),
            None => (None, r.void.as_ref().map(ToString::to_string)),
        },
        None => (None, Some("not evaluated".into())),
    };
    MethodGains {
        solver: name,
        k_min: s.k_min,
        theorem1,
        theorem1_void,
        regional,
        regional_void,
    }
}

/// The gains of the loop certificate that covers `k` with the exact MPC: Theorem L3's where
/// K ≥ K_glob, else the iteration chain's where it was checked and certified at `k`. Err:
/// none covers `k`, with Theorem L3's K_glob if it has one (for the reason).
fn loop_gains(
    cert: &ClosedLoopCertificate,
    method: Method,
    k: usize,
) -> Result<(CertificateKind, f64, Option<f64>, f64), Option<usize>> {
    let g = iss_certificate::coverage::global_of(cert, method, ControllerChoice::ExactMpc)
        .ok_or(None)?;
    let k_glob = g.exact.k_glob();
    if let GlobalOutcome::Certified(gk) = &g.exact {
        if k >= gk.k_glob {
            return Ok((CertificateKind::Global, gk.gain_x, None, gk.gain_e));
        }
    }
    match g
        .chain
        .as_ref()
        .and_then(|c| c.chain())
        .and_then(|c| c.at(k))
    {
        Some(ChainCheck::Certified(c)) => Ok((CertificateKind::Chain, c.gain_x, None, c.gain_e)),
        _ => Err(k_glob),
    }
}

/// One run's certified bound at its K (with its own sup‖w_t‖ as w̄) and measured gains.
fn run_gains(
    cert: &ClosedLoopCertificate,
    own: Option<&SolverCertificate>,
    r: &Run,
    not_covered: Option<&str>,
) -> RunGains {
    let measured = MeasuredGains::from_trace(&r.trace);
    let w_bar = measured.as_ref().map(|m| m.w_sup);
    let void = if let Some(why) = not_covered {
        Some(format!("not certified: {why}"))
    } else if r.summary.controller != "exact MPC" {
        Some(
            "the controller is the K-iteration MPC: Theorem 1's gains assume the exact \
             MPC (the joint certificate's asymptotic gains are not derived)"
                .into(),
        )
    } else {
        r.summary.w_outside_first.map(|first| {
            format!(
                "w_t ∉ 𝒲 at {} step(s) from t = {first}: the bound assumes w_t ∈ 𝒲",
                r.summary.w_outside
            )
        })
    };
    let theorem1 = match (void, own) {
        (Some(v), _) => Err(v),
        (None, None) => Err("the scenario's solver was not certified".into()),
        (None, Some(s)) => certified_gains(cert, s, r.summary.k)
            .map(|g| {
                (
                    CertificateKind::Theorem1,
                    g.gain_x,
                    Some(g.gain_epsilon),
                    g.gain_e,
                )
            })
            .map_err(|e| e.to_string()),
    };
    // Where Theorem 1 does not cover the run's K, the certificate the one verdict names does
    // (Theorem L3 holds for every w, inside 𝒲 or not; the chain at the K it checked).
    let certified = match theorem1 {
        Ok(g) => Ok(g),
        Err(e) => match (not_covered, own) {
            (None, Some(s)) if r.summary.controller == "exact MPC" => {
                loop_gains(cert, s.solver, r.summary.k).map_err(|k_glob| match k_glob {
                    Some(kg) => format!(
                        "K = {} is below the global loop certificate's K_glob = {kg} and not \
                         a K the iteration chain certified; {e}",
                        r.summary.k
                    ),
                    None => e,
                })
            }
            _ => Err(e),
        },
    };
    let (certified, certified_void) = match certified {
        Ok((certificate, gain_x, gain_epsilon, gain_e)) => {
            let w = w_bar.unwrap_or(f64::NAN);
            (
                Some(CertifiedBound {
                    certificate,
                    gain_x,
                    gain_epsilon,
                    gain_e,
                    bound_x: gain_x * w,
                    bound_epsilon: gain_epsilon.map(|g| g * w),
                    bound_e: gain_e * w,
                }),
                None,
            )
        }
        Err(e) => (None, Some(e)),
    };
    RunGains {
        label: r.summary.label.clone(),
        k: r.summary.k,
        controller: r.summary.controller.clone(),
        w_bar,
        certified,
        certified_void,
        measured,
    }
}
