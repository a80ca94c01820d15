//! `reproduce` for a scenario whose controller is the K-iteration MPC (`mpc.iterations`): the
//! joint MPC + MHE certificate (iss_certificate::joint), the run at the cheapest certified pair and
//! every inequality of the joint proof checked on it.

use std::fmt::Write as _;

use anyhow::{Context, Result};
use closed_loop::Trace;
use closed_loop::scenario::ResolvedScenario;
use iss_certificate::certificate::ClosedLoopCertificate;
use iss_certificate::joint::{
    JointCertificate, JointOptions, JointTrajectoryCheck, certify_joint, check_joint_trajectory,
    delta_series,
};
use qp_iter::Method;

use super::numfmt::num;

/// The joint certificate and its trajectory check, as written to certificate.json (`joint`).
#[derive(Debug, Clone)]
pub struct JointReport {
    /// K_c of the scenario (`mpc.iterations`).
    pub scenario_k_c: usize,
    /// The certificate: region, Pareto front, cheapest pair, gains there.
    pub certificate: JointCertificate,
    /// Every inequality on the run at the cheapest pair (None when it did not run).
    pub trajectory: Option<JointTrajectoryCheck>,
    /// max_t ‖u_t(replay) − u_t(trace)‖ of the δ replay (0: δ_t is the loop's own).
    pub replay_mismatch: Option<f64>,
    /// Why the check did not run (None when it ran).
    pub reason: Option<String>,
}

/// The joint certificate of the scenario's MHE method `mhe` and its MPC (`mpc.method`), or
/// None when the scenario's controller is the exact MPC.
pub fn joint_certificate(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    mhe: Method,
) -> Result<Option<JointCertificate>> {
    let scenario = resolved.scenario();
    let Some(spec) = scenario.mpc.as_ref().filter(|m| m.iterations().is_some()) else {
        return Ok(None);
    };
    let mpc = resolved.mpc()?;
    let (nx, ny) = (scenario.plant.nx(), scenario.plant.ny());
    let n_e = nx + cert.horizon * (nx + ny);
    let j = certify_joint(cert, mpc, n_e, mhe, spec.method(), &JointOptions::default())
        .context("cannot compute the joint MPC + MHE certificate")?;
    Ok(Some(j))
}

/// Runs the joint checks on `trace` (simulated at the cheapest pair with the exact MHE solve on).
pub fn check(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    j: &JointCertificate,
    trace: Option<&Trace>,
    scenario_k_c: usize,
) -> Result<JointReport> {
    let mut report = JointReport {
        scenario_k_c,
        certificate: j.clone(),
        trajectory: None,
        replay_mismatch: None,
        reason: None,
    };
    let (Some(p), Some(trace)) = (j.region.cheapest, trace) else {
        report.reason = Some(if j.region.cheapest.is_none() {
            "no certified pair (see the void reasons)".into()
        } else {
            "the run at the cheapest certified pair was not simulated".into()
        });
        return Ok(report);
    };
    let mpc = resolved.mpc()?;
    let d = delta_series(
        mpc,
        j.mpc_method,
        p.k_c,
        mpc_core::WarmStart::default(),
        trace,
    )?;
    report.replay_mismatch = Some(d.replay_mismatch);
    report.trajectory = check_joint_trajectory(
        cert,
        &j.analysis,
        p.k_e,
        p.k_c,
        trace,
        &d.delta,
        &d.input_error,
        j.plant_beta,
        j.gamma1w,
    );
    if report.trajectory.is_none() {
        report.reason = Some(if j.plant_beta.is_none() {
            "β₁ of the plant is unknown (γ₁,₃ void): the joint inequalities cannot be checked"
                .into()
        } else {
            "ε_t was not recorded (exact MHE solve off)".into()
        });
    }
    Ok(report)
}

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
