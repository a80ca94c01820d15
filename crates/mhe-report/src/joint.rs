//! `reproduce` for a scenario whose controller is the K-iteration MPC (`mpc.iterations`): the
//! joint MPC + MHE certificate (iss_certificate::joint), the run at the cheapest certified pair and
//! every inequality of the joint proof checked on it.

use closed_loop::Trace;
use closed_loop::scenario::ResolvedScenario;
use iss_certificate::certificate::ClosedLoopCertificate;
use iss_certificate::joint::{
    JointCertificate, JointOptions, JointTrajectoryCheck, certify_joint, check_joint_trajectory,
    delta_series,
};
use qp_iter::Method;

use crate::ReportError;

/// The joint certificate and its trajectory check, as written to certificate.json (`joint`).
#[derive(Debug, Clone)]
#[non_exhaustive]
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
) -> Result<Option<JointCertificate>, ReportError> {
    let scenario = resolved.scenario();
    let Some(spec) = scenario.mpc.as_ref().filter(|m| m.iterations().is_some()) else {
        return Ok(None);
    };
    let mpc = resolved.mpc()?;
    let (nx, ny) = (scenario.plant.nx(), scenario.plant.ny());
    let n_e = nx + cert.horizon * (nx + ny);
    let j = certify_joint(cert, mpc, n_e, mhe, spec.method(), &JointOptions::default())
        .map_err(ReportError::Joint)?;
    Ok(Some(j))
}

/// Runs the joint checks on `trace` (simulated at the cheapest pair with the exact MHE solve on).
pub fn check(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    j: &JointCertificate,
    trace: Option<&Trace>,
    scenario_k_c: usize,
) -> Result<JointReport, ReportError> {
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
