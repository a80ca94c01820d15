//! The summary that fits a screen (issue 38 item 5): per job one table — method, K_min
//! (Theorem 1), K_glob (the global loop certificate, Theorem L3), K_chain, K_f32 (the
//! smallest K certified in f32), K_lin, K_reg, the certified gains g_e and g_x at K_min, and what the
//! simulation of the scenario's method showed — and one verdict line; a reason shared by
//! several cells is printed once, as a numbered footnote. Everything else (premises, the
//! paper's constants, the long explanations, the work log) is in `-v` and `summary.md`.
//!
//! Every number is read from the document written as certificate.json, nothing is
//! recomputed here (a test parses the table back against the file).

use super::numfmt::num;
use super::*;
use iss_certificate::outcome::VoidReason;

/// Footnotes: equal texts get one number.
#[derive(Default)]
struct Notes(Vec<String>);

impl Notes {
    /// `[n]` of `text`, numbering it on first use.
    fn mark(&mut self, text: String) -> String {
        let i = match self.0.iter().position(|t| *t == text) {
            Some(i) => i,
            None => {
                self.0.push(text);
                self.0.len() - 1
            }
        };
        format!("[{}]", i + 1)
    }
}

/// The header of the table (also parsed by the tests).
pub(super) const TABLE_HEADER: [&str; 10] = [
    "method",
    "K_min",
    "K_glob",
    "K_chain",
    "K_f32",
    "K_lin",
    "K_reg",
    "g_e",
    "g_x",
    "simulated",
];

/// The screen summary of one job; `out` is its output directory.
pub(super) fn screen(d: &CertificateDocument, out: &Path) -> String {
    let c = &d.certificate;
    let mut notes = Notes::default();
    let mut s = String::new();
    let sim = match d.runs.first() {
        Some(r) => format!(
            "{} simulated with the {}, seed {}, T = {}",
            d.solver,
            if d.joint.is_some() {
                "K-iteration MPC"
            } else {
                "exact MPC"
            },
            r.seed,
            r.steps
        ),
        None => format!("{} not simulated", d.solver),
    };
    let _ = writeln!(
        s,
        "== {}: {} · M = {}, η = {}, ρ = {} · {sim} ==",
        d.label,
        d.scenario.path,
        c.horizon,
        num(c.eta),
        num(c.rho)
    );
    let h = TABLE_HEADER;
    let _ = writeln!(
        s,
        "  {:<14} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}  {}",
        h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8], h[9]
    );
    for sv in &d.solvers {
        let k_min = k_min_cell(sv, &mut notes);
        let k_glob = k_glob_cell(sv, &mut notes);
        let k_chain = k_chain_cell(sv, &mut notes);
        let k_f32 = k_f32_cell(sv, &mut notes);
        let k_lin = k_lin_cell(d, &sv.solver.name(), &mut notes);
        let k_reg = k_reg_cell(d, &sv.solver.name(), &mut notes);
        let gains = d
            .asymptotic_gains
            .methods
            .iter()
            .find(|m| m.solver == sv.solver.name())
            .and_then(|m| m.theorem1.as_ref());
        let (g_e, g_x) = gains.map_or_else(
            || ("-".to_string(), "-".to_string()),
            |g| (num(g.gain_e), num(g.gain_x)),
        );
        let simulated = if sv.solver.name() == d.solver {
            simulated_cell(d, &mut notes)
        } else {
            String::new()
        };
        let row = format!(
            "  {:<14} {k_min:>8} {k_glob:>8} {k_chain:>8} {k_f32:>8} {k_lin:>8} {k_reg:>8} {g_e:>8} {g_x:>8}  {simulated}",
            sv.solver.name()
        );
        let _ = writeln!(s, "{}", row.trim_end());
    }
    for (i, n) in notes.0.iter().enumerate() {
        let _ = writeln!(s, "  [{}] {n}", i + 1);
    }
    let _ = writeln!(s, "verdict: {}", super::summary::verdict(d));
    if let Some(b) = &d.budget {
        let _ = writeln!(s, "{}", b.screen_line(&d.solver));
    }
    let figures = d.files.iter().filter(|f| f.ends_with(".svg")).count();
    let mut listed: Vec<String> = d
        .files
        .iter()
        .filter(|f| !f.ends_with(".svg"))
        .cloned()
        .collect();
    if figures > 0 {
        listed.push(format!("{figures} SVG figures"));
    }
    listed.push(SUMMARY_FILE.into());
    let _ = write!(
        s,
        "files: {}/ ({}); -v prints the premises, the paper's constants and the checks",
        out.display(),
        listed.join(", ")
    );
    s
}

/// K_min, or why there is none (void: the reasons, proved; not computed: the budget).
fn k_min_cell(sv: &mhe_report::SolverSummary, notes: &mut Notes) -> String {
    if let Some(k) = sv.k_min {
        return k.to_string();
    }
    if let Some(nc) = &sv.not_computed {
        return format!("n/c{}", notes.mark(nc.to_string()));
    }
    let failed: Vec<&str> = sv
        .premises
        .iter()
        .filter(|p| !p.holds)
        .map(|p| p.name.as_str())
        .collect();
    let why = if !sv.void_reasons.is_empty() {
        VoidReason::join(&sv.void_reasons)
    } else if failed.is_empty() {
        "no K satisfies sg1 + sg2 + sg3 < 1".into()
    } else {
        format!("{} fails", failed.join(", "))
    };
    format!("void{}", notes.mark(format!("K_min void: {why}")))
}

/// K_glob of the global loop certificate (Theorem L3), or why there is none ("-": not
/// computed with this controller).
fn k_glob_cell(sv: &mhe_report::SolverSummary, notes: &mut Notes) -> String {
    use iss_certificate::lure::global_outcome::GlobalOutcome;
    match (&sv.global, sv.k_glob) {
        (_, Some(k)) => k.to_string(),
        (None, None) => "-".into(),
        (Some(g), None) => {
            let word = match &g.exact {
                GlobalOutcome::NotComputed { .. } => "n/c",
                GlobalOutcome::Unsupported { .. } => "n/a",
                GlobalOutcome::UnstableWithBoundedInput { .. } => {
                    return format!("none{}", notes.mark(impossible_note(&g.exact)));
                }
                _ => "none",
            };
            format!("{word}{}", notes.mark(format!("K_glob: {}", g.exact)))
        }
    }
}

/// The one footnote of K_glob and K_chain where no global certificate can exist.
fn impossible_note(why: &iss_certificate::lure::global_outcome::GlobalOutcome) -> String {
    format!("K_glob, K_chain: {why}")
}

/// K_chain of the iteration chain (Theorem L3b: that K only, pg, fista and their Jacobi variants), or why none
/// ("-": not modelled for this method or controller).
fn k_chain_cell(sv: &mhe_report::SolverSummary, notes: &mut Notes) -> String {
    use iss_certificate::lure::chain_outcome::{ChainCheck, ChainOutcome};
    if let Some(k) = sv.k_chain {
        return k.to_string();
    }
    let Some(chain) = sv.global.as_ref().and_then(|g| g.chain.as_ref()) else {
        return "-".into();
    };
    // No global certificate can exist: the chain shares K_glob's footnote.
    if let ChainOutcome::Impossible(why) = chain {
        return format!("none{}", notes.mark(impossible_note(why)));
    }
    let word = match chain {
        ChainOutcome::Unsupported { .. } => "n/a",
        ChainOutcome::Checked(c)
            if c.checks
                .iter()
                .any(|a| matches!(a, ChainCheck::NotComputed { .. })) =>
        {
            "n/c"
        }
        _ => "none",
    };
    format!("{word}{}", notes.mark(format!("K_chain: {chain}")))
}

/// The smallest K certified in f32 (Theorem 1 with the rounding folded in, or Theorem L3u),
/// or why there is none in a few words ([`iss_certificate::coverage::PairReason::short`]; the
/// sentence is `solvers[].f32_reason`).
fn k_f32_cell(sv: &mhe_report::SolverSummary, notes: &mut Notes) -> String {
    if let Some(k) = sv.k_f32 {
        return k.to_string();
    }
    let why = sv.f32_reason.as_ref().map_or_else(
        || "no reason recorded".to_string(),
        iss_certificate::coverage::PairReason::short,
    );
    let why = why.strip_prefix("f32: ").unwrap_or(&why);
    format!(
        "none{}",
        notes.mark(format!("K_f32 none: {why} (solvers[].f32_reason)"))
    )
}

/// K_lin of `linear[]`, or why there is none.
fn k_lin_cell(d: &CertificateDocument, solver: &str, notes: &mut Notes) -> String {
    let Some(l) = d.linear.iter().find(|l| l.solver == solver) else {
        return "-".into();
    };
    match (&l.report, &l.error) {
        (Some(r), _) => r.k_lin.map_or_else(
            || {
                format!(
                    "none{}",
                    notes.mark("K_lin: ρ_lin(K) ≥ 1 at every K of the grid".into())
                )
            },
            |k| k.to_string(),
        ),
        (None, Some(e)) => {
            // The same reason for every method is one footnote.
            let e = e.strip_prefix("not computed: ").unwrap_or(e);
            format!("n/c{}", notes.mark(format!("K_lin not computed: {e}")))
        }
        (None, None) => "-".into(),
    }
}

/// K_reg of `regional[]`, or the first clause of why there is none (the full reason is in
/// `-v`, summary.md and `regional[].void`).
fn k_reg_cell(d: &CertificateDocument, solver: &str, notes: &mut Notes) -> String {
    let Some(r) = d.regional.iter().find(|r| r.solver == solver) else {
        return "-".into();
    };
    if let Some(k) = r.k_reg {
        return k.to_string();
    }
    let why = if r.refuted_every_k.is_some() {
        "K_reg none at any K: an admissible realization drives a constraint row free of K \
         (t ≤ 1) past its bound (regional[].refuted_every_k)"
            .to_string()
    } else {
        let v = r.void.as_deref().unwrap_or("no reason recorded");
        format!(
            "K_reg none (K ≤ {}): {} (regional[].void)",
            r.search_max,
            first_clause(v)
        )
    };
    format!("none{}", notes.mark(why))
}

/// The text up to the first ": " outside parentheses (the numbers of a void reason follow
/// it; a parenthesis such as "(largest K evaluated: 32)" stays whole), at most 120
/// characters.
pub(super) fn first_clause(v: &str) -> String {
    let mut depth = 0usize;
    let mut end = v.len();
    for (i, c) in v.char_indices() {
        match c {
            '(' => depth += 1,
            ')' => depth = depth.saturating_sub(1),
            ':' if depth == 0 && v[i + 1..].starts_with(' ') => {
                end = i;
                break;
            }
            _ => {}
        }
    }
    let head = &v[..end];
    if head.chars().count() <= 120 {
        head.to_string()
    } else {
        head.chars().take(119).collect::<String>() + "…"
    }
}

/// What each simulation of the scenario's method showed: bounded, diverged, stopped, or
/// not simulated; at the checked K, whether Props. 1 and 3 hold.
fn simulated_cell(d: &CertificateDocument, notes: &mut Notes) -> String {
    let tc = &d.trajectory_check;
    let mut cells: Vec<String> = Vec::new();
    for r in &d.runs {
        let mut cell = format!("K={} ", r.k);
        cell += &match (&r.divergence, &r.error) {
            (Some(dv), _) => format!("diverged at t = {}", dv.t),
            (None, Some(_)) => format!("stopped at t = {}", r.completed),
            (None, None) => "bounded".into(),
        };
        if tc.k == Some(r.k) && r.k_source == KSource::ComputedKMin {
            match tc.passed {
                Some(true) => cell += ", Props. 1, 3 hold",
                Some(false) => cell += ", Prop. 1 or 3 VIOLATED",
                None => {}
            }
        }
        if let Some(first) = r.w_outside_first {
            cell += &notes.mark(format!(
                "w_t ∉ 𝒲 at {} of {} steps from t = {first}: the certificate assumes w_t ∈ 𝒲",
                r.w_outside, r.completed
            ));
        }
        if r.mpc_infeasible_steps > 0 {
            cell += &notes.mark(format!(
                "the MPC was infeasible at {} of {} steps and applied its fallback",
                r.mpc_infeasible_steps, r.completed
            ));
        }
        cells.push(cell);
    }
    for r in &d.skipped_runs {
        cells.push(format!(
            "K={} not simulated{}",
            r.k,
            notes.mark(r.reason.clone())
        ));
    }
    if cells.is_empty() {
        return format!(
            "not simulated{}",
            notes.mark("the MHE needs a P and LMI (2) has none".into())
        );
    }
    cells.join("; ")
}
