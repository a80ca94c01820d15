//! The summary's lines of the certified asymptotic gains (computed by
//! [`mhe_report::gains`]): per run the certified bound next to the measured gains, and per
//! method the certified gains at K_min.

use mhe_report::gains::{GainsReport, RunGains};

use super::numfmt::num;
use super::*;

/// The summary's line under a run: the certified bound and the measured gains.
pub(super) fn run_line(g: &RunGains) -> String {
    let certified = match (&g.certified, g.w_bar) {
        (Some(c), Some(w)) => format!(
            "certified{} lim sup ‖e‖ ≤ g_e·w̄ = {}·{} = {}, lim sup ‖x‖ ≤ g_x·w̄ = {}·{} = {}",
            // Theorem 1's unless another certificate covers the run's K.
            match c.certificate {
                iss_certificate::coverage::CertificateKind::Theorem1 => String::new(),
                kind => format!(" ({})", kind.title()),
            },
            num(c.gain_e),
            num(w),
            num(c.bound_e),
            num(c.gain_x),
            num(w),
            num(c.bound_x)
        ),
        _ => match g.certified_void.as_deref() {
            // The premises' sentences are printed above, once.
            Some(v) if v.contains("Theorem 1 is void") => {
                let before = v.split("Theorem 1 is void").next().unwrap_or_default();
                format!(
                    "certified asymptotic bound: none ({before}Theorem 1 is void: see the \
                     premises above)"
                )
            }
            v => format!(
                "certified asymptotic bound: none ({})",
                v.unwrap_or("no run data")
            ),
        },
    };
    let measured = match &g.measured {
        Some(m) if m.w_sup > 0.0 => format!(
            "measured (t ≥ {}) sup‖e‖ = {} = {}·w̄, sup‖x‖ = {} = {}·w̄ (whole run {}·w̄, {}·w̄; w̄ = sup‖w_t‖ = {})",
            m.tail_from,
            num(m.e_tail_sup),
            num(m.gain_e.unwrap_or(f64::NAN)),
            num(m.x_tail_sup),
            num(m.gain_x.unwrap_or(f64::NAN)),
            num(m.gain_e_whole_run.unwrap_or(f64::NAN)),
            num(m.gain_x_whole_run.unwrap_or(f64::NAN)),
            num(m.w_sup)
        ),
        Some(m) => format!(
            "measured (t ≥ {}) sup‖e‖ = {}, sup‖x‖ = {} (w ≡ 0: no gain to measure)",
            m.tail_from,
            num(m.e_tail_sup),
            num(m.x_tail_sup)
        ),
        None => "measured: no steps".into(),
    };
    format!("{certified}; {measured}")
}

/// The summary's section: per method, the certified gains at K_min.
pub(super) fn methods_section(r: &GainsReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nCertified asymptotic gains, Theorem 1's at K_min and the regional certificate's at \
         its K (lim sup ‖e‖ ≤ g_e·w̄, lim sup ‖x‖ ≤ g_x·w̄, w̄ ≥ sup‖w_t‖; docs/theory.md)"
    );
    if r.methods
        .iter()
        .all(|m| m.theorem1.is_none() && m.regional.is_none())
    {
        let _ = writeln!(
            s,
            "  none: no method has a certified K (the reasons are above)"
        );
        return s;
    }
    for m in &r.methods {
        let t1 = match &m.theorem1 {
            Some(g) => format!(
                "Theorem 1: g_e = {}, g_x = {}, g_ε = {}",
                num(g.gain_e),
                num(g.gain_x),
                num(g.gain_epsilon)
            ),
            None => "Theorem 1: void".into(),
        };
        let reg = match &m.regional {
            Some(g) => format!(
                "; regional at K = {}: g_e = {}, g_x = {} ({})",
                g.k,
                num(g.gain_e),
                num(g.gain_x),
                if g.contains {
                    "its region contains the scenario's uncertainty"
                } else {
                    "its region does not contain the scenario's uncertainty: not claimed for these runs"
                }
            ),
            None => String::new(),
        };
        let _ = writeln!(s, "  {:<14} {t1}{reg}", m.solver);
    }
    s
}
