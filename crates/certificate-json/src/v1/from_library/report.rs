//! `From<&library type>` for the records of `mhe_report`'s report (the simulations, the
//! trajectory check, the gains, ρ_lin, K_reg, the joint check, the paper comparison).

use super::super::*;

impl From<&mhe_report::ComparisonRow> for ComparisonRow {
    fn from(l: &mhe_report::ComparisonRow) -> Self {
        Self {
            quantity: l.quantity.to_string(),
            ours: l.ours.to_string(),
            paper: l.paper.to_string(),
        }
    }
}

impl From<&mhe_report::KalmanSummary> for KalmanSummary {
    fn from(l: &mhe_report::KalmanSummary) -> Self {
        Self {
            weights: l.weights.to_string(),
            completed: l.completed,
            sup_norm_e: l.sup_norm_e.and_then(num),
            tail_mean_e: l.tail_mean_e.and_then(num),
            diverged: l.diverged,
            divergence: l.divergence.as_ref().map(Divergence::from),
            error: l.error.as_ref().map(ToString::to_string),
        }
    }
}

impl From<&mhe_report::RunSummary> for RunSummary {
    fn from(l: &mhe_report::RunSummary) -> Self {
        Self {
            label: l.label.to_string(),
            k: l.k,
            k_source: KSource::from(&l.k_source),
            solver: l.solver.to_string(),
            controller: l.controller.to_string(),
            exact_mhe_solve: l.exact_mhe_solve,
            seed: l.seed,
            steps: l.steps,
            completed: l.completed,
            error: l.error.as_ref().map(ToString::to_string),
            diverged: l.diverged,
            diverged_at: l.diverged_at,
            signal: l.signal.as_ref().map(Signal::from),
            divergence: l.divergence.as_ref().map(Divergence::from),
            mpc_infeasible_steps: l.mpc_infeasible_steps,
            sup_norm_e: num(l.sup_norm_e),
            sup_norm_x: num(l.sup_norm_x),
            final_norm_x: num(l.final_norm_x),
            tail_mean_e: l.tail_mean_e.and_then(num),
            tail_mean_x: l.tail_mean_x.and_then(num),
            tail_mean_epsilon: l.tail_mean_epsilon.and_then(num),
            w_outside: l.w_outside,
            w_outside_first: l.w_outside_first,
            kalman: l.kalman.as_ref().map(KalmanSummary::from),
        }
    }
}

impl From<&mhe_report::SkippedRun> for SkippedRun {
    fn from(l: &mhe_report::SkippedRun) -> Self {
        Self {
            k: l.k,
            k_source: KSource::from(&l.k_source),
            reason: l.reason.to_string(),
        }
    }
}

impl From<&mhe_report::TrajectoryReport> for TrajectoryReport {
    fn from(l: &mhe_report::TrajectoryReport) -> Self {
        Self {
            ran: l.ran,
            reason: l.reason.as_ref().map(ToString::to_string),
            solver: l.solver.to_string(),
            k: l.k,
            seed: l.seed,
            steps: l.steps,
            certified_l_phi: l.certified_l_phi.as_ref().map(TrajectoryCheck::from),
            sampled_l_phi: l.sampled_l_phi.as_ref().map(TrajectoryCheck::from),
            passed: l.passed,
        }
    }
}

impl From<&mhe_report::gains::CertifiedBound> for CertifiedBound {
    fn from(l: &mhe_report::gains::CertifiedBound) -> Self {
        Self {
            certificate: (&l.certificate).into(),
            gain_x: num(l.gain_x),
            gain_epsilon: l.gain_epsilon.and_then(num),
            gain_e: num(l.gain_e),
            bound_x: num(l.bound_x),
            bound_epsilon: l.bound_epsilon.and_then(num),
            bound_e: num(l.bound_e),
        }
    }
}

impl From<&mhe_report::gains::GainsReport> for GainsReport {
    fn from(l: &mhe_report::gains::GainsReport) -> Self {
        Self {
            meaning: l.meaning.to_string(),
            methods: l.methods.iter().map(MethodGains::from).collect(),
            runs: l.runs.iter().map(RunGains::from).collect(),
        }
    }
}

impl From<&mhe_report::gains::MethodGains> for MethodGains {
    fn from(l: &mhe_report::gains::MethodGains) -> Self {
        Self {
            solver: l.solver.to_string(),
            k_min: l.k_min,
            theorem1: l.theorem1.as_ref().map(AsymptoticGains::from),
            theorem1_void: l.theorem1_void.as_ref().map(ToString::to_string),
            regional: l.regional.as_ref().map(RegionalGains::from),
            regional_void: l.regional_void.as_ref().map(ToString::to_string),
        }
    }
}

impl From<&mhe_report::gains::RegionalGains> for RegionalGains {
    fn from(l: &mhe_report::gains::RegionalGains) -> Self {
        Self {
            k: l.k,
            gain_x: num(l.gain_x),
            gain_e: num(l.gain_e),
            contains: l.contains,
            w_bar: num(l.w_bar),
        }
    }
}

impl From<&mhe_report::gains::RunGains> for RunGains {
    fn from(l: &mhe_report::gains::RunGains) -> Self {
        Self {
            label: l.label.to_string(),
            k: l.k,
            controller: l.controller.to_string(),
            w_bar: l.w_bar.and_then(num),
            certified: l.certified.as_ref().map(CertifiedBound::from),
            certified_void: l.certified_void.as_ref().map(ToString::to_string),
            measured: l.measured.as_ref().map(MeasuredGains::from),
        }
    }
}

impl From<&mhe_report::joint::JointReport> for JointReport {
    fn from(l: &mhe_report::joint::JointReport) -> Self {
        Self {
            scenario_k_c: l.scenario_k_c,
            certificate: JointCertificate::from(&l.certificate),
            trajectory: l.trajectory.as_ref().map(JointTrajectoryCheck::from),
            replay_mismatch: l.replay_mismatch.and_then(num),
            reason: l.reason.as_ref().map(ToString::to_string),
        }
    }
}

impl From<&mhe_report::linear::LinearEntry> for LinearEntry {
    fn from(l: &mhe_report::linear::LinearEntry) -> Self {
        Self {
            solver: l.solver.to_string(),
            report: l.report.as_ref().map(LinearReport::from),
            error: l.error.as_ref().map(ToString::to_string),
        }
    }
}

impl From<&mhe_report::regional::RegionalEntry> for RegionalEntry {
    fn from(l: &mhe_report::regional::RegionalEntry) -> Self {
        Self {
            solver: l.solver.to_string(),
            k_lin: l.k_lin,
            k_lin_not_computed: l.k_lin_not_computed.as_ref().map(ToString::to_string),
            k_min: l.k_min,
            k_reg: l.k_reg,
            search_max: l.search_max,
            search_max_reason: l.search_max_reason.to_string(),
            k: l.k,
            certificate: l.certificate.as_ref().map(RegionalCertificate::from),
            tried: l.tried.iter().map(TriedK::from).collect(),
            void: l.void.as_ref().map(ToString::to_string),
            refuted_every_k: l.refuted_every_k.as_ref().map(Limit::from),
            k_free: l.k_free.as_ref().map(KFreeLimits::from),
            uncertainty: l.uncertainty.as_ref().map(RegionalOptions::from),
            at_two_k_lin: l.at_two_k_lin.as_ref().map(ProbeNote::from),
        }
    }
}

impl From<&mhe_report::regional::TriedK> for TriedK {
    fn from(l: &mhe_report::regional::TriedK) -> Self {
        Self {
            k: l.k,
            margin: num(l.margin),
            contains: l.contains,
        }
    }
}

impl From<&mhe_report::SolverSummary> for SolverSummary {
    fn from(l: &mhe_report::SolverSummary) -> Self {
        Self {
            solver: l.solver.name().to_string(),
            simulated: l.simulated,
            certified: l.certified,
            k_min: l.k_min,
            k_glob: l.k_glob,
            k_glob_f32: l.k_glob_f32,
            k_f32: l.k_f32,
            f32_reason: l
                .f32_reason
                .as_ref()
                .map_or_else(String::new, ToString::to_string),
            k_chain: l.k_chain,
            global: l.global.as_ref().map(GlobalRecord::from),
            void_reasons: l.void_reasons.iter().map(ToString::to_string).collect(),
            not_computed: l.not_computed.as_ref().map(NotComputed::from),
            premises: l.premises.iter().map(Premise::from).collect(),
            phi_rate: num(l.phi_rate),
            phi_prefactor: num(l.phi_prefactor),
            margin_at_k_min: l.margin_at_k_min.and_then(num),
            k_min_with_sampled_l_phi: l.k_min_with_sampled_l_phi,
        }
    }
}

impl From<&iss_certificate::lure::global_outcome::MethodGlobal> for GlobalRecord {
    fn from(l: &iss_certificate::lure::global_outcome::MethodGlobal) -> Self {
        use iss_certificate::lure::global_outcome::{GlobalOutcome, PrecisionOutcome};
        let k = match &l.exact {
            GlobalOutcome::Certified(k) => Some(k),
            _ => None,
        };
        Self {
            outcome: l.exact.to_string(),
            phi_star: k.and_then(|k| num(k.phi_star)),
            margin: k.and_then(|k| num(k.margin)),
            rho: k.and_then(|k| num(k.rho)),
            gamma: k.and_then(|k| num(k.gamma)),
            gain_x: k.and_then(|k| num(k.gain_x)),
            gain_e: k.and_then(|k| num(k.gain_e)),
            f32_outcome: l.f32.to_string(),
            f32_offset: match &l.f32 {
                PrecisionOutcome::Certified(p) => num(p.offset),
                _ => None,
            },
            chain: l.chain.as_ref().map(ChainRecord::from),
        }
    }
}

impl From<&iss_certificate::lure::chain_outcome::ChainOutcome> for ChainRecord {
    fn from(l: &iss_certificate::lure::chain_outcome::ChainOutcome) -> Self {
        use iss_certificate::lure::chain_outcome::ChainScanEnd;
        let Some(c) = l.chain() else {
            return Self {
                k_chain: None,
                checked: Vec::new(),
                certified: Vec::new(),
                outcomes: vec![l.to_string()],
                scan: "none".into(),
                margin: None,
                rho: None,
                gamma: None,
                budget_seconds: None,
            };
        };
        let best = c
            .k_chain()
            .and_then(|k| c.at(k))
            .and_then(|a| a.certified());
        let mut certified: Vec<usize> = c
            .checks
            .iter()
            .filter_map(|a| a.certified().map(|k| k.k))
            .collect();
        certified.sort_unstable();
        Self {
            k_chain: c.k_chain(),
            checked: c.checked(),
            certified,
            outcomes: c.checks.iter().map(ToString::to_string).collect(),
            scan: match c.scan {
                ChainScanEnd::Certified { .. } => "certified",
                ChainScanEnd::Cap { .. } => "cap",
                _ => "stopped",
            }
            .into(),
            margin: best.and_then(|b| num(b.margin)),
            rho: best.and_then(|b| num(b.rho)),
            gamma: best.and_then(|b| num(b.gamma)),
            budget_seconds: num(c.budget_seconds),
        }
    }
}
