//! `From<&library type>` for the records of Theorem 1, its premises, L_Φ, the closed-loop checks and the coverage verdicts.

use super::super::*;

impl From<&closed_loop::bounded::Divergence> for Divergence {
    fn from(l: &closed_loop::bounded::Divergence) -> Self {
        Self {
            t: l.t,
            signal: Signal::from(&l.signal),
            value: num(l.value),
            limit: num(l.limit),
            stopped: l.stopped,
        }
    }
}

impl From<&closed_loop::bounded::Signal> for Signal {
    fn from(l: &closed_loop::bounded::Signal) -> Self {
        match l {
            closed_loop::bounded::Signal::E => Self::E,
            closed_loop::bounded::Signal::X => Self::X,
            closed_loop::bounded::Signal::Epsilon => Self::Epsilon,
            closed_loop::bounded::Signal::U => Self::U,
        }
    }
}

impl From<&iss_certificate::analysis::GainsAtK> for GainsAtK {
    fn from(l: &iss_certificate::analysis::GainsAtK) -> Self {
        Self {
            k: l.k,
            phi: num(l.phi),
            c1: num(l.c1),
            c2: num(l.c2),
            c3: num(l.c3),
            c3w: num(l.c3w),
            c_e: num(l.c_e),
            c_w: num(l.c_w),
            c_eps: num(l.c_eps),
            gamma21: num(l.gamma21),
            gamma23: num(l.gamma23),
            gamma2w: num(l.gamma2w),
            gamma2sigma: num(l.gamma2sigma),
            gamma31: num(l.gamma31),
            gamma32: num(l.gamma32),
            gamma3w: num(l.gamma3w),
            gamma3sigma: num(l.gamma3sigma),
            sg1: num(l.sg1),
            sg2: num(l.sg2),
            sg3: num(l.sg3),
            paper_conditions: l.paper_conditions,
            margin: num(l.margin),
            certified: l.certified,
        }
    }
}

impl From<&iss_certificate::analysis::IssAnalysis> for IssAnalysis {
    fn from(l: &iss_certificate::analysis::IssAnalysis) -> Self {
        Self {
            inputs: IssInputs::from(&l.inputs),
            rho: num(l.rho),
            lambda_pp: num(l.lambda_pp),
            lambda_qp: num(l.lambda_qp),
            lambda_hp: num(l.lambda_hp),
            l_phi_used: num(l.l_phi_used),
            premises: l.premises.iter().map(Premise::from).collect(),
        }
    }
}

impl From<&iss_certificate::analysis::IssInputs> for IssInputs {
    fn from(l: &iss_certificate::analysis::IssInputs) -> Self {
        Self {
            horizon: l.horizon,
            eta: num(l.eta),
            p_min: num(l.p_min),
            p_max: num(l.p_max),
            q_max: num(l.q_max),
            h_bar: num(l.h_bar),
            l_phi: num(l.l_phi),
            l_pi: num(l.l_pi),
            c_norm: num(l.c_norm),
            f_norm: num(l.f_norm),
            gamma13: num(l.gamma13),
            phi_rate: num(l.phi_rate),
            phi_prefactor: num(l.phi_prefactor),
            phi_fits_eq11: l.phi_fits_eq11,
            lmi_certified: l.lmi_certified,
        }
    }
}

impl From<&iss_certificate::analysis::Premise> for Premise {
    fn from(l: &iss_certificate::analysis::Premise) -> Self {
        Self {
            name: l.name.to_string(),
            needed_by: l.needed_by.to_string(),
            holds: l.holds,
            value: num(l.value),
            margin: l.margin.and_then(num),
            fix: l.fix.as_ref().map_or_else(String::new, ToString::to_string),
            not_evaluated: l.not_evaluated.as_ref().map(ToString::to_string),
        }
    }
}

impl From<&iss_certificate::asymptotic::AsymptoticGains> for AsymptoticGains {
    fn from(l: &iss_certificate::asymptotic::AsymptoticGains) -> Self {
        Self {
            k: l.k,
            phi: num(l.phi),
            gain_x: num(l.gain_x),
            gain_epsilon: num(l.gain_epsilon),
            gain_e: num(l.gain_e),
            limsup: ComparisonSystem::from(&l.limsup),
            theorem1: ComparisonSystem::from(&l.theorem1),
            e_from_w: num(l.e_from_w),
            e_from_epsilon: num(l.e_from_epsilon),
            gamma13: num(l.gamma13),
            gamma1w: num(l.gamma1w),
        }
    }
}

impl From<&iss_certificate::asymptotic::ComparisonSystem> for ComparisonSystem {
    fn from(l: &iss_certificate::asymptotic::ComparisonSystem) -> Self {
        Self {
            matrix: l
                .matrix
                .iter()
                .map(|x| x.iter().map(|x| num(*x)).collect())
                .collect(),
            input: l.input.iter().map(|x| num(*x)).collect(),
            spectral_radius: num(l.spectral_radius),
            gains: l.gains.iter().map(|x| num(*x)).collect(),
        }
    }
}

impl From<&iss_certificate::asymptotic::MeasuredGains> for MeasuredGains {
    fn from(l: &iss_certificate::asymptotic::MeasuredGains) -> Self {
        Self {
            steps: l.steps,
            tail_from: l.tail_from,
            w_sup: num(l.w_sup),
            e_tail_sup: num(l.e_tail_sup),
            x_tail_sup: num(l.x_tail_sup),
            epsilon_tail_sup: l.epsilon_tail_sup.and_then(num),
            e_sup: num(l.e_sup),
            x_sup: num(l.x_sup),
            gain_e: l.gain_e.and_then(num),
            gain_x: l.gain_x.and_then(num),
            gain_epsilon: l.gain_epsilon.and_then(num),
            gain_e_whole_run: l.gain_e_whole_run.and_then(num),
            gain_x_whole_run: l.gain_x_whole_run.and_then(num),
        }
    }
}

impl From<&iss_certificate::budget::NotComputed> for NotComputed {
    fn from(l: &iss_certificate::budget::NotComputed) -> Self {
        Self {
            phase: l.phase.to_string(),
            needed_seconds: num(l.needed_seconds),
            budget_seconds: num(l.budget_seconds),
        }
    }
}

impl From<&iss_certificate::certificate::ClosedLoopCertificate> for ClosedLoopCertificate {
    fn from(l: &iss_certificate::certificate::ClosedLoopCertificate) -> Self {
        Self {
            scenario: l.scenario.to_string(),
            horizon: l.horizon,
            eta: num(l.eta),
            rho: num(l.rho),
            ioss: l.ioss.as_ref().map(IossReport::from),
            ioss_failure: l.ioss_failure.as_ref().map(ToString::to_string),
            p_min: l.p_min.and_then(num),
            p_max: l.p_max.and_then(num),
            q_max: num(l.q_max),
            h_bar: l.h_bar.and_then(num),
            c_norm: num(l.c_norm),
            l_phi: LPhiReport::from(&l.l_phi),
            l_pi: LipschitzReport::from(&l.l_pi),
            l_pi_used: num(l.l_pi_used),
            gamma13: Gamma13Report::from(&l.gamma13),
            solvers: l.solvers.iter().map(SolverCertificate::from).collect(),
            nearest: NearestParameters::from(&l.nearest),
            h_paper_norms: l.h_paper_norms.iter().map(|x| num(*x)).collect(),
            sigma_model_part: num(l.sigma_model_part),
            lemma1_origin_offsets: l.lemma1_origin_offsets.iter().map(|x| num(*x)).collect(),
        }
    }
}

impl From<&iss_certificate::certificate::LPhiReport> for LPhiReport {
    fn from(l: &iss_certificate::certificate::LPhiReport) -> Self {
        Self {
            certified: l.certified.and_then(num),
            sampled: l.sampled.and_then(num),
            per_window: l.per_window.iter().map(|x| (num(x.0), num(x.1))).collect(),
            pairs_reduced: l.pairs_reduced.as_ref().map(ToString::to_string),
        }
    }
}

impl From<&iss_certificate::certificate::NearestParameters> for NearestParameters {
    fn from(l: &iss_certificate::certificate::NearestParameters) -> Self {
        Self {
            min_horizon_at_eta: l.min_horizon_at_eta,
            eta_sup_at_horizon: num(l.eta_sup_at_horizon),
        }
    }
}

impl From<&iss_certificate::certificate::SolverCertificate> for SolverCertificate {
    fn from(l: &iss_certificate::certificate::SolverCertificate) -> Self {
        Self {
            solver: Method::from(&l.solver),
            phi_rate: num(l.phi_rate),
            phi_prefactor: num(l.phi_prefactor),
            fits_eq11: l.fits_eq11,
            per_window: l
                .per_window
                .iter()
                .map(IterationCertificate::from)
                .collect(),
            analysis: IssAnalysis::from(&l.analysis),
            k_min: l.k_min,
            at_k_min: l.at_k_min.as_ref().map(GainsAtK::from),
            void_reasons: l.void_reasons.iter().map(ToString::to_string).collect(),
            not_computed: l.not_computed.as_ref().map(NotComputed::from),
            k_min_with_sampled_l_phi: l.k_min_with_sampled_l_phi,
        }
    }
}

impl From<&iss_certificate::certificate::InequalityCheck> for InequalityCheck {
    fn from(l: &iss_certificate::certificate::InequalityCheck) -> Self {
        Self {
            holds: l.holds,
            worst_ratio: num(l.worst_ratio),
            worst_t: l.worst_t,
            first_violation: l.first_violation,
            within_rounding_floor: l.within_rounding_floor,
            max_rounding_floor: num(l.max_rounding_floor),
        }
    }
}

impl From<&iss_certificate::certificate::TrajectoryCheck> for TrajectoryCheck {
    fn from(l: &iss_certificate::certificate::TrajectoryCheck) -> Self {
        Self {
            prop1: InequalityCheck::from(&l.prop1),
            prop3: InequalityCheck::from(&l.prop3),
            divergence: l.divergence.as_ref().map(Divergence::from),
        }
    }
}

impl From<&iss_certificate::coverage::CertificateKind> for CertificateKind {
    fn from(l: &iss_certificate::coverage::CertificateKind) -> Self {
        match l {
            iss_certificate::coverage::CertificateKind::Theorem1 => Self::Theorem1,
            iss_certificate::coverage::CertificateKind::Joint => Self::Joint,
            iss_certificate::coverage::CertificateKind::Global => Self::Global,
            iss_certificate::coverage::CertificateKind::Chain => Self::Chain,
            other => Self::Other(format!("{other:?}")),
        }
    }
}

impl From<&iss_certificate::coverage::Certified> for Certified {
    fn from(l: &iss_certificate::coverage::Certified) -> Self {
        match l {
            iss_certificate::coverage::Certified::Yes => Self::Yes,
            iss_certificate::coverage::Certified::No => Self::No,
            iss_certificate::coverage::Certified::Void => Self::Void,
            iss_certificate::coverage::Certified::NotComputed => Self::NotComputed,
            other => Self::Other(format!("{other:?}")),
        }
    }
}

impl From<&iss_certificate::coverage::Coverage> for Coverage {
    fn from(l: &iss_certificate::coverage::Coverage) -> Self {
        match l {
            iss_certificate::coverage::Coverage::Covered(a0) => {
                Self::Covered(CertificateKind::from(a0))
            }
            iss_certificate::coverage::Coverage::Uncovered(a0) => Self::Uncovered(a0.to_string()),
            other => Self::Other(format!("{other:?}")),
        }
    }
}

impl From<&iss_certificate::coverage::PairVerdict> for PairVerdict {
    fn from(l: &iss_certificate::coverage::PairVerdict) -> Self {
        Self {
            certificate: l.certificate.as_ref().map(CertificateKind::from),
            certified: Certified::from(&l.certified),
            k_min: l.k_min,
            margin: l.margin.and_then(num),
            reason: l.reason_text(),
        }
    }
}
