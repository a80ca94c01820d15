//! The terminal summary of `cargo xtask certify`.

use super::*;

/// The summary of `check`, with the names and sources of its document `d`.
pub(super) fn summarize(
    d: &v1::IossCertificate,
    check: &IossOutcome,
    loop_section: Option<&super::loop_methods::LoopSection>,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "δ-IOSS certificate (Assumption 2, LMI (2)) for scenario `{}` ({})",
        d.scenario.name, d.scenario.path
    );
    let sys = &d.system.dims;
    let _ = writeln!(
        s,
        "  plant        n_x = {}, n_u = {}, n_y = {}, n_w = {} + {}",
        sys.nx, sys.nu, sys.ny, sys.nw1, sys.nw2
    );
    let i = &d.inputs;
    let _ = writeln!(s, "  η            {} ({})", num(check.eta), i.eta_source);
    let _ = writeln!(
        s,
        "  Q, R         {}×{}, {}×{} ({})",
        i.q.len(),
        i.q.len(),
        i.r.len(),
        i.r.len(),
        i.weights_source
    );
    let _ = writeln!(s, "  P            {}", i.p_source);
    if let Some(c) = &check.certificate {
        if c.method != "user" {
            let _ = writeln!(
                s,
                "  method       {} ({} iterations)",
                c.method, c.iterations
            );
        }
        let _ = writeln!(s, "  λmin(P)      {}", num(c.p_min_eigenvalue));
        let _ = writeln!(s, "  λmax(P)      {}", num(c.p_max_eigenvalue));
        let _ = writeln!(
            s,
            "  λmin/λmax(P) {}   (the test: λmin/λmax of diag(P)^(-1/2)·P·diag(P)^(-1/2) > {})",
            num(c.p_min_eigenvalue / c.p_max_eigenvalue),
            num(c.p_min_ratio)
        );
        let _ = writeln!(
            s,
            "  λmax(LMI)    {}   (J of LMI (2), unscaled)",
            num(c.lmi_max_eigenvalue)
        );
        let _ = writeln!(
            s,
            "  μ = max vᵀJv/vᵀSv {}   (must be ≤ {}; S = GᵀPG + diag(P, Q) + HᵀRH, the \
             sum of the LMI's terms)",
            c.lmi_relative_violation
                .map_or_else(|| "— (P is not positive definite)".to_string(), num),
            num(c.lmi_relative_tolerance)
        );
    }
    if let Some(f) = &d.failure {
        let _ = writeln!(s, "  failure      {f}");
    }
    if let Some(h) = &d.hint {
        let _ = writeln!(s, "  hint         {h}");
    }
    if let Some(l) = &check.controller_lipschitz {
        let _ = writeln!(s, "{}", lipschitz_block(l));
    }
    if let Some(why) = &d.controller_lipschitz_skipped {
        let _ = writeln!(
            s,
            "L_π (Assumption 3): not computed — {why} (the LMI (2) check above does not need it)"
        );
    }
    if let Some(c) = &check.closed_loop {
        match c.covers() {
            Some(kind) => {
                let _ = writeln!(
                    s,
                    "closed loop: in the setting of the {} certificate (not a verdict: whether \
                     a K is certified is `cargo xtask reproduce`'s, or the table of `--loop`; \
                     PASS/FAIL below is LMI (2) alone)",
                    kind.title()
                );
            }
            None => {
                let _ = writeln!(
                    s,
                    "closed loop: NOT CERTIFIED — {} (PASS/FAIL below is LMI (2) alone, not a \
                     closed-loop certificate)",
                    c.uncovered_reason()
                        .map_or_else(|| "no certificate covers it".into(), ToString::to_string)
                );
            }
        }
    }
    if let Some(l) = loop_section {
        super::loop_methods::summary_lines(&mut s, l);
    }
    let _ = write!(s, "{}", if d.passed { "PASS" } else { "FAIL" });
    s
}

/// The L_π block of the summary: the text of [`mpc_core::LipschitzReport`]'s `Display`
/// with every number at most 4 significant digits (issue 23; certificate.json keeps them
/// all).
fn lipschitz_block(l: &mpc_core::LipschitzReport) -> String {
    let (c, sm) = (&l.certified, &l.sampled);
    let mut s = String::from("L_π (Assumption 3), condensed box-constrained MPC:\n");
    if let Some(r) = l.void_reason {
        let _ = writeln!(s, "  void: {r}");
        let _ = writeln!(
            s,
            "  certified L_π  none (void: the bounds below do not hold for this MPC)"
        );
    } else {
        let _ = writeln!(
            s,
            "  certified L_π  {}  (the tightest bound below)",
            num(l.l_pi())
        );
    }
    match l.enumerated {
        Some(e) => {
            let _ = writeln!(
                s,
                "  L_enum         {}  = max over all free sets f of ‖E₀J_f‖₂",
                num(e)
            );
        }
        None => {
            let _ = writeln!(
                s,
                "  L_enum         skipped: {}",
                l.enumeration_skipped.as_deref().unwrap_or("not computed")
            );
        }
    }
    let _ = writeln!(
        s,
        "  L_poly         {}  = sup over 0 ⪯ M ⪯ I of ‖K_lin + G·M·R‖₂ (S-procedure; {} \
         saturable variables)",
        num(c.polynomial),
        c.saturable
    );
    let _ = writeln!(
        s,
        "  bound (b)      {}  = ‖E₀H^(-1/2)‖₂·‖H^(-1/2)F‖₂ = {}·{}",
        num(c.first_block),
        num(c.e0_h_inv_sqrt),
        num(c.h_inv_sqrt_f)
    );
    let _ = writeln!(
        s,
        "  bound (a)      {}  = ‖H^(-1/2)F‖₂/√λ_min(H), λ_min(H) = {}",
        num(c.sequence),
        num(c.h_min_eigenvalue)
    );
    if sm.pairs == 0 {
        let _ = writeln!(s, "  sampled        skipped (0 pairs requested)");
    } else {
        let _ = writeln!(
            s,
            "  sampled        {}  over {} pairs ({} evaluations, {} switches located), seed {}, \
             radius {}",
            num(sm.estimate),
            sm.pairs,
            sm.evaluations,
            sm.switches_located,
            sm.seed,
            num(sm.radius)
        );
    }
    if c.origin_interior {
        let _ = writeln!(
            s,
            "  unconstrained  {}  = ‖E₀H⁻¹F‖₂ (a lower bound on L_π: 0 ∈ int 𝒰)",
            num(c.unconstrained_gain)
        );
    }
    let _ = writeln!(
        s,
        "  saturated LQR  {}  = ‖K‖₂ (its certified L_π)",
        num(l.saturated_lqr)
    );
    if l.consistent() {
        let _ = write!(s, "  sampled ≤ certified: yes");
    } else {
        let _ = write!(s, "  sampled ≤ certified: NO (a bug: please report it)");
    }
    s
}
