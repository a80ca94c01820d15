//! The constants next to the paper's published values, and a void certificate's reason in a
//! few words.

use iss_certificate::certificate::{ClosedLoopCertificate, SolverCertificate};
use lti_model::numfmt::sig4;
use qp_iter::Method;

/// One row of the constants table (ours vs the paper's published values).
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct ComparisonRow {
    /// Quantity.
    pub quantity: String,
    /// Ours, for the stand-in plant.
    pub ours: String,
    /// The paper's, for its own plant (not printed in the paper).
    pub paper: String,
}

/// The constants of `solver`'s certificate (ρ, φ(K), L_Φ, γ₁,₃, L_π, K_min) next to the
/// values the paper publishes for its own plant.
pub fn paper_comparison(cert: &ClosedLoopCertificate, solver: Method) -> Vec<ComparisonRow> {
    let sc = cert.solver(solver);
    let phi = sc.map_or_else(
        || "not computed".to_string(),
        |s| {
            format!(
                "{}·{}^K ({})",
                sig4(s.phi_prefactor),
                rate(s.phi_rate),
                s.solver.name()
            )
        },
    );
    let g = &cert.gamma13;
    let gamma_sampled = g.sampled.as_ref().map_or(String::new(), |s| {
        format!("; sampled ≥ {}", sig4(s.gamma13_lower))
    });
    let k = match sc {
        Some(s) => match s.k_min {
            Some(k) => format!("K_min = {k} ({})", s.solver.name()),
            None => match &s.not_computed {
                Some(nc) => format!("none: {nc}"),
                None => format!("none: void ({})", short_reason(s)),
            },
        },
        None => "not computed".into(),
    };
    vec![
        ComparisonRow {
            quantity: "ρ = 6^(1/M)·η".into(),
            ours: format!(
                "{} (M = {}, η = {})",
                sig4(cert.rho),
                cert.horizon,
                sig4(cert.eta)
            ),
            paper: format!(
                "{} (not printed; from M = 5, η = 0.8)",
                sig4(6f64.powf(0.2) * 0.8)
            ),
        },
        ComparisonRow {
            quantity: "φ(K)".into(),
            ours: phi,
            paper: "0.98^K (partial gradient)".into(),
        },
        ComparisonRow {
            quantity: "L_Φ".into(),
            ours: format!(
                "{} certified; sampled {}",
                sig4(cert.l_phi.certified.unwrap_or(f64::NAN)),
                sig4(cert.l_phi.sampled.unwrap_or(f64::NAN))
            ),
            paper: "5.32 (sample-based)".into(),
        },
        ComparisonRow {
            quantity: "γ₁,₃".into(),
            ours: format!(
                "{} {}{gamma_sampled}{}",
                sig4(g.used),
                g.source,
                // The enumeration replaced by the polynomial bound for the analysis budget.
                if g.skipped.iter().any(|k| k.reason.is_budget()) {
                    " (S-procedure bound: the free-set enumeration is beyond the analysis \
                     budget, key `certificate.phase_seconds`)"
                } else {
                    ""
                }
            ),
            paper: "28.8 (method of their journal paper)".into(),
        },
        ComparisonRow {
            quantity: "L_π".into(),
            ours: format!(
                "{} certified; sampled {}",
                sig4(cert.l_pi_used),
                sig4(cert.l_pi.sampled.estimate)
            ),
            paper: "2.65 (sample-based)".into(),
        },
        ComparisonRow {
            quantity: "K".into(),
            ours: k,
            paper: "652 (from (sg1)–(sg3))".into(),
        },
    ]
}

/// Why `s` is void, in a few words: the failed premises, or the small gain.
pub fn short_reason(s: &SolverCertificate) -> String {
    let names: Vec<&str> = s
        .analysis
        .violated()
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    if names.is_empty() {
        "no K satisfies sg1 + sg2 + sg3 < 1".into()
    } else {
        format!("{} fails", names.join(", "))
    }
}

/// A rate in (0, 1) with 4 significant digits, or `(1 − d)` when 1 − rate < 0.01 (four
/// digits of the rate itself would hide how close to 1 it is).
fn rate(r: f64) -> String {
    if r.is_finite() && r < 1.0 && 1.0 - r < 0.01 {
        format!("(1 − {})", sig4(1.0 - r))
    } else {
        sig4(r)
    }
}
