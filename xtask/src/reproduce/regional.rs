//! The summary's lines of K_reg (issue 27, computed by [`mhe_report::regional`]): per
//! method K_reg against K_lin and K_min with the ratios, and why there is no K_reg where there
//! is none.

use super::*;
use closed_loop::scenario::ControllerChoice;
use mhe_report::regional::RegionalEntry;

/// The controller of a regional certificate in words.
fn controller_text(c: ControllerChoice) -> String {
    match c {
        ControllerChoice::ExactMpc => "exact MPC".into(),
        ControllerChoice::SaturatedLqr => "saturated LQR".into(),
        ControllerChoice::SuboptimalMpc { iterations, method } => {
            format!("MPC with K_c = {iterations} iterations of {method}")
        }
    }
}

/// The summary's lines: per method K_reg against K_lin and K_min with the ratios (ρ_lin at
/// K_reg, the necessary condition), and why there is no K_reg where there is none.
pub(super) fn summary(entries: &[RegionalEntry]) -> String {
    use lti_model::numfmt::sig4;
    let mut s = String::new();
    if entries.is_empty() {
        return s;
    }
    let _ = writeln!(
        s,
        "\nRegional certificate ({}; inside the region no constraint is active, so the loop \
         is the linear one): K_reg = smallest K whose region contains the scenario's uncertainty,\n\
         searched up to K_min, against K_lin and Theorem 1's K_min. ρ_lin(K_reg) < 1 is \
         necessary (printed below); K_lin, from which ρ_lin < 1 on the whole grid (with the \
         exact MPC), can exceed K_reg where ρ_lin is not monotone in K",
        entries
            .iter()
            .find_map(|e| e
                .uncertainty
                .as_ref()
                .map(|o| controller_text(o.controller)))
            .unwrap_or_else(|| "the scenario's controller".into())
    );
    if let Some(o) = entries.iter().find_map(|e| e.uncertainty.as_ref()) {
        let _ = writeln!(
            s,
            "  uncertainty: ‖x₀ − x₀_nominal‖ ≤ {}, prior error ≤ {}, w̄ = {}",
            sig4(o.x0_radius),
            sig4(o.prior_error),
            sig4(o.w_bar)
        );
    }
    let k = |v: Option<usize>| v.map_or_else(|| "none".to_string(), |k| k.to_string());
    let ratio = |a: Option<usize>, b: Option<usize>| match (a, b) {
        (Some(a), Some(b)) if b > 0 => sig4(a as f64 / b as f64),
        _ => "-".into(),
    };
    for e in entries {
        // "not computed", never "none", when ρ_lin was not computed (issue 37 item 13).
        let k_lin = match (&e.k_lin_not_computed, e.k_lin) {
            (Some(_), _) => "not computed".to_string(),
            (None, v) => k(v),
        };
        let reg = match e.k_reg {
            Some(r) => r.to_string(),
            None if e.refuted_every_k.is_some() => "none at any K".into(),
            None if e.tried.is_empty() => "none".into(),
            None => format!("none ≤ {}", e.search_max),
        };
        // "no K_min", not "K_min = none": a void summary prints no `K_min =`.
        let k_min = e
            .k_min
            .map_or_else(|| "no K_min".to_string(), |k| format!("K_min = {k}"));
        let _ = writeln!(
            s,
            "  {:<14} K_lin = {}, K_reg = {reg}, {k_min}; K_reg/K_lin = {}, K_min/K_lin = {}",
            e.solver,
            k_lin,
            ratio(e.k_reg, e.k_lin),
            ratio(e.k_min, e.k_lin),
        );
        if let Some(why) = &e.k_lin_not_computed {
            let why = why.strip_prefix("not computed: ").unwrap_or(why);
            let _ = writeln!(s, "      K_lin not computed: {why}");
        }
        // Why not K_reg ≤ 2·K_lin (the target), when the search evaluated 2·K_lin.
        if let (Some(l), Some(p)) = (e.k_lin, &e.at_two_k_lin) {
            if e.k_reg.is_none_or(|r| r > 2 * l) && !p.contains {
                let _ = writeln!(s, "      not at 2·K_lin = {}: {}", p.k, p.note);
            }
        }
        match (&e.certificate, &e.void) {
            (Some(c), None) => {
                let _ = writeln!(
                    s,
                    "      at K_reg: ρ_lin = {}, rate λ = {}, certified gains sup‖x‖ ≤ {}·w̄, \
                     sup‖e‖ ≤ {}·w̄, uncertainty certified up to {}× the scenario's",
                    super::numfmt::rate(c.rho_lin),
                    super::numfmt::rate(c.rate),
                    sig4(c.gain_x),
                    sig4(c.gain_e),
                    sig4(c.margin)
                );
            }
            (_, Some(v)) => {
                let _ = writeln!(s, "      no K_reg: {v}");
            }
            (None, None) => {}
        }
    }
    s
}

#[cfg(test)]
#[path = "regional_tests.rs"]
mod tests;
