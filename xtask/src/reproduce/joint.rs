//! The summary block of the joint MPC + MHE certificate (computed by
//! [`mhe_report::joint`]) for a scenario whose controller is the K-iteration MPC.

use std::fmt::Write as _;

use mhe_report::joint::JointReport;

use super::numfmt::num;

/// The summary block of the joint certificate.
pub fn summary(r: &JointReport) -> String {
    let j = &r.certificate;
    let reg = &j.region;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nJoint certificate: MHE {} with K_e iterations + MPC {} with K_c iterations (warm start {}, ω = {}); small gain ρ(Γ) < 1 over (x, ε, e, δ)",
        j.mhe_method,
        j.mpc_method,
        j.warm_start,
        num(j.analysis.inputs.mpc.warm_gain)
    );
    for v in &reg.void_reasons {
        let _ = writeln!(s, "  void: {v}");
    }
    let opt = |v: Option<usize>| v.map_or_else(|| "none".to_string(), |k| k.to_string());
    let _ = writeln!(
        s,
        "  K_e floor (exact MPC) {}, K_c floor (exact MHE) {}, {} Pareto pairs",
        opt(reg.k_e_floor),
        opt(reg.k_c_floor),
        reg.pareto.len()
    );
    if let Some(p) = reg.cheapest {
        let _ = writeln!(
            s,
            "  cheapest certified pair (K_e, K_c) = ({}, {}) by {}",
            p.k_e, p.k_c, j.cost_model
        );
    }
    if let Some(g) = &j.at_cheapest {
        let _ = writeln!(
            s,
            "  there: ρ(Γ) = {}, largest cycle gain {}, γ₁,₄ = {}, γ₂,₄ = {}, γ₃,₄ = {}, γ₄,₁ = γ₄,₃ = {}",
            num(g.spectral_radius),
            num(g.cycles.iter().map(|c| c.gain).fold(0.0, f64::max)),
            num(g.gamma14),
            num(g.gamma24),
            num(g.gamma34),
            num(g.gamma41)
        );
    }
    match (&r.trajectory, &r.reason) {
        (Some(t), _) => {
            let _ = writeln!(
                s,
                "  trajectory check at the cheapest pair: {} (max lhs/rhs: plant {}, Prop. 1 {}, Prop. 3 {}, δ step {}, δ {}, ‖u − π(x̂)‖/δ {}; replay mismatch {})",
                match (t.inequalities_hold(), t.divergence) {
                    (true, None) => "every inequality holds at every t".to_string(),
                    (true, Some(d)) =>
                        format!("every inequality holds at every t, but the run {d}"),
                    (false, _) => "VIOLATED".to_string(),
                },
                num(t.plant.worst_ratio),
                num(t.prop1.worst_ratio),
                num(t.prop3.worst_ratio),
                num(t.delta_step.worst_ratio),
                num(t.delta.worst_ratio),
                num(t.input_error.worst_ratio),
                num(r.replay_mismatch.unwrap_or(f64::NAN))
            );
        }
        (None, Some(reason)) => {
            let _ = writeln!(s, "  trajectory check not run: {reason}");
        }
        (None, None) => {}
    }
    s
}
