//! The summary's comparison with the paper's published values, and a void certificate's
//! reason in a few words.

use super::*;

pub(super) fn fmt_opt(v: Option<usize>) -> String {
    v.map_or_else(|| "none".to_string(), |k| k.to_string())
}

pub(super) fn comparison(cert: &ClosedLoopCertificate, solver: Method) -> Vec<ComparisonRow> {
    let sc = cert.solver(solver);
    let phi = sc.map_or_else(
        || "not computed".to_string(),
        |s| {
            format!(
                "{}·{}^K ({})",
                numfmt::num(s.phi_prefactor),
                numfmt::rate(s.phi_rate),
                s.solver.name()
            )
        },
    );
    let g = &cert.gamma13;
    let gamma_sampled = g.sampled.as_ref().map_or(String::new(), |s| {
        format!("; sampled ≥ {}", numfmt::num(s.gamma13_lower))
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
                numfmt::num(cert.rho),
                cert.horizon,
                numfmt::num(cert.eta)
            ),
            paper: format!(
                "{} (not printed; from M = 5, η = 0.8)",
                numfmt::num(6f64.powf(0.2) * 0.8)
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
                numfmt::num(cert.l_phi.certified.unwrap_or(f64::NAN)),
                numfmt::num(cert.l_phi.sampled.unwrap_or(f64::NAN))
            ),
            paper: "5.32 (sample-based)".into(),
        },
        ComparisonRow {
            quantity: "γ₁,₃".into(),
            ours: format!(
                "{} {}{gamma_sampled}{}",
                numfmt::num(g.used),
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
                numfmt::num(cert.l_pi_used),
                numfmt::num(cert.l_pi.sampled.estimate)
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

pub(super) fn short_reason(s: &SolverCertificate) -> String {
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
