//! `From<&library type>` for the records of [`super::outcomes`].

use super::*;

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

impl From<&iss_certificate::gamma13::Gamma13Certificate> for Gamma13Certificate {
    fn from(l: &iss_certificate::gamma13::Gamma13Certificate) -> Self {
        Self {
            gamma13: num(l.gamma13),
            method: l.method.as_ref().map(Gamma13Method::from),
            metric: l.metric.as_ref().map(ToString::to_string),
            pattern_blocks: l.pattern_blocks,
            pattern_families: l.pattern_families,
            gamma13_polynomial: num(l.gamma13_polynomial),
            gamma13_enumerated: l.gamma13_enumerated.and_then(num),
            gamma13_linear: l.gamma13_linear.and_then(num),
            gamma14: num(l.gamma14),
            gamma1w: num(l.gamma1w),
            beta_prefactor: l.beta_prefactor.and_then(num),
            beta_rate: l.beta_rate.and_then(num),
            candidates: l.candidates.iter().map(MetricResult::from).collect(),
            variables: l.variables,
            saturable: l.saturable,
            free_sets: l.free_sets,
            enumerated: l.enumerated,
            void: l.void.as_ref().map(Gamma13Void::from),
            skipped: l.skipped.iter().map(SkippedComputation::from).collect(),
            over_budget: l.over_budget.as_ref().map(NotComputed::from),
        }
    }
}

impl From<&iss_certificate::gamma13::Gamma13Method> for Gamma13Method {
    fn from(l: &iss_certificate::gamma13::Gamma13Method) -> Self {
        match l {
            iss_certificate::gamma13::Gamma13Method::Polynomial => Self::Polynomial,
            iss_certificate::gamma13::Gamma13Method::Enumerated => Self::Enumerated,
            iss_certificate::gamma13::Gamma13Method::Linear => Self::Linear,
            other => Self::Other(format!("{other:?}")),
        }
    }
}

impl From<&iss_certificate::gamma13::Gamma13Void> for Gamma13Void {
    fn from(l: &iss_certificate::gamma13::Gamma13Void) -> Self {
        match l {
            iss_certificate::gamma13::Gamma13Void::OriginOutsideInputSet => {
                Self::OriginOutsideInputSet
            }
            iss_certificate::gamma13::Gamma13Void::SaturatedDynamicsNotStable {
                spectral_radius,
                input_bounded,
                marginal,
            } => Self::SaturatedDynamicsNotStable {
                spectral_radius: num(*spectral_radius),
                input_bounded: *input_bounded,
                marginal: *marginal,
            },
            iss_certificate::gamma13::Gamma13Void::NoContractingMetric {
                best_contraction,
                metric,
                enumerated,
                pattern_blocks,
            } => Self::NoContractingMetric {
                best_contraction: num(*best_contraction),
                metric: metric.to_string(),
                enumerated: *enumerated,
                pattern_blocks: *pattern_blocks,
            },
            iss_certificate::gamma13::Gamma13Void::StateConstrainedMpc => Self::StateConstrainedMpc,
            iss_certificate::gamma13::Gamma13Void::OutputConstrainedMpc => {
                Self::OutputConstrainedMpc
            }
            iss_certificate::gamma13::Gamma13Void::NotComputedWithinBudget {
                best_contraction,
                not_computed,
            } => Self::NotComputedWithinBudget {
                best_contraction: num(*best_contraction),
                not_computed: NotComputed::from(not_computed),
            },
            iss_certificate::gamma13::Gamma13Void::UserValueRefuted {
                user,
                sampled_lower,
            } => Self::UserValueRefuted {
                user: num(*user),
                sampled_lower: num(*sampled_lower),
            },
            other => Self::Other(other.to_string()),
        }
    }
}

impl From<&iss_certificate::gamma13::MetricResult> for MetricResult {
    fn from(l: &iss_certificate::gamma13::MetricResult) -> Self {
        Self {
            metric: l.metric.to_string(),
            contraction: num(l.contraction),
            input_gain: num(l.input_gain),
            contraction_enumerated: l.contraction_enumerated.and_then(num),
            input_gain_enumerated: l.input_gain_enumerated.and_then(num),
            condition_sqrt: num(l.condition_sqrt),
            gamma13_polynomial: num(l.gamma13_polynomial),
            gamma13_enumerated: l.gamma13_enumerated.and_then(num),
            gamma13: num(l.gamma13),
            gamma1w: num(l.gamma1w),
            input_matrix_gain: num(l.input_matrix_gain),
            gamma14: num(l.gamma14),
            not_computed: l.not_computed.as_ref().map(ToString::to_string),
        }
    }
}

impl From<&iss_certificate::gamma13::SkippedComputation> for SkippedComputation {
    fn from(l: &iss_certificate::gamma13::SkippedComputation) -> Self {
        Self {
            computation: l.computation.to_string(),
            reason: l.reason.to_string(),
        }
    }
}

impl From<&iss_certificate::gamma13::Gamma13Report> for Gamma13Report {
    fn from(l: &iss_certificate::gamma13::Gamma13Report) -> Self {
        Self {
            used: num(l.used),
            source: l.source.to_string(),
            user: l.user.and_then(num),
            certified: l.certified.as_ref().map(Gamma13Certificate::from),
            sampled: l.sampled.as_ref().map(Gamma13Sampled::from),
            void: l.void.as_ref().map(Gamma13Void::from),
            skipped: l.skipped.iter().map(SkippedComputation::from).collect(),
        }
    }
}

impl From<&iss_certificate::gamma13::Gamma13Sampled> for Gamma13Sampled {
    fn from(l: &iss_certificate::gamma13::Gamma13Sampled) -> Self {
        Self {
            gamma13_lower: num(l.gamma13_lower),
            sequences: l.sequences,
            steps: l.steps,
            seed: l.seed,
        }
    }
}

impl From<&iss_certificate::joint::JointCertificate> for JointCertificate {
    fn from(l: &iss_certificate::joint::JointCertificate) -> Self {
        Self {
            mhe_method: Method::from(&l.mhe_method),
            mpc_method: Method::from(&l.mpc_method),
            warm_start: l.warm_start.to_string(),
            cost_model: l.cost_model.to_string(),
            analysis: JointAnalysis::from(&l.analysis),
            region: JointRegion::from(&l.region),
            at_cheapest: l.at_cheapest.as_ref().map(JointGains::from),
            plant_beta: l.plant_beta.map_or((None, None), |(prefactor, rate)| {
                (num(prefactor), num(rate))
            }),
            gamma1w: num(l.gamma1w),
        }
    }
}

impl From<&iss_certificate::joint::JointAnalysis> for JointAnalysis {
    fn from(l: &iss_certificate::joint::JointAnalysis) -> Self {
        Self {
            inputs: JointInputs::from(&l.inputs),
            theorem1: IssAnalysis::from(&l.theorem1),
            premises: l.premises.iter().map(Premise::from).collect(),
        }
    }
}

impl From<&iss_certificate::joint::JointGains> for JointGains {
    fn from(l: &iss_certificate::joint::JointGains) -> Self {
        Self {
            k_e: l.k_e,
            k_c: l.k_c,
            mhe: GainsAtK::from(&l.mhe),
            phi_c: num(l.phi_c),
            delta_rate: num(l.delta_rate),
            gamma13: num(l.gamma13),
            gamma14: num(l.gamma14),
            gamma24: num(l.gamma24),
            gamma34: num(l.gamma34),
            gamma41: num(l.gamma41),
            gamma43: num(l.gamma43),
            matrix: l.matrix.iter().map(|x| num(*x)).collect(),
            cycles: l.cycles.iter().map(Cycle::from).collect(),
            cycles_hold: l.cycles_hold,
            spectral_radius: num(l.spectral_radius),
            margin: num(l.margin),
            certified: l.certified,
        }
    }
}

impl From<&iss_certificate::joint::JointInputs> for JointInputs {
    fn from(l: &iss_certificate::joint::JointInputs) -> Self {
        Self {
            mhe: IssInputs::from(&l.mhe),
            gamma14: num(l.gamma14),
            mpc: MpcMapInputs::from(&l.mpc),
        }
    }
}

impl From<&iss_certificate::joint::MpcMapInputs> for MpcMapInputs {
    fn from(l: &iss_certificate::joint::MpcMapInputs) -> Self {
        Self {
            l_u: num(l.l_u),
            phi_rate: num(l.phi_rate),
            phi_prefactor: num(l.phi_prefactor),
            phi_fits_eq11: l.phi_fits_eq11,
            warm_gain: num(l.warm_gain),
            warm_start: l.warm_start.to_string(),
            origin_fixed: l.origin_fixed,
        }
    }
}

impl From<&iss_certificate::joint::JointRegion> for JointRegion {
    fn from(l: &iss_certificate::joint::JointRegion) -> Self {
        Self {
            k_max: l.k_max,
            k_e_floor: l.k_e_floor,
            k_c_floor: l.k_c_floor,
            pareto: l.pareto.iter().map(RegionPoint::from).collect(),
            cost_per_iteration: (num(l.cost_per_iteration.0), num(l.cost_per_iteration.1)),
            cheapest: l.cheapest.as_ref().map(RegionPoint::from),
            void_reasons: l.void_reasons.iter().map(ToString::to_string).collect(),
        }
    }
}

impl From<&iss_certificate::joint::RegionPoint> for RegionPoint {
    fn from(l: &iss_certificate::joint::RegionPoint) -> Self {
        Self {
            k_e: l.k_e,
            k_c: l.k_c,
        }
    }
}

impl From<&iss_certificate::joint::JointTrajectoryCheck> for JointTrajectoryCheck {
    fn from(l: &iss_certificate::joint::JointTrajectoryCheck) -> Self {
        Self {
            plant: InequalityCheck::from(&l.plant),
            prop1: InequalityCheck::from(&l.prop1),
            prop3: InequalityCheck::from(&l.prop3),
            delta_step: InequalityCheck::from(&l.delta_step),
            delta: InequalityCheck::from(&l.delta),
            input_error: InequalityCheck::from(&l.input_error),
            divergence: l.divergence.as_ref().map(Divergence::from),
        }
    }
}

impl From<&iss_certificate::linear::LinearReport> for LinearReport {
    fn from(l: &iss_certificate::linear::LinearReport) -> Self {
        Self {
            solver: Method::from(&l.solver),
            dim: l.dim,
            rho_lin: l.rho_lin.iter().map(|x| (x.0, num(x.1))).collect(),
            k_lin: l.k_lin,
            unstable_ks: l.unstable_ks.to_vec(),
        }
    }
}

impl From<&iss_certificate::plan::KSource> for KSource {
    fn from(l: &iss_certificate::plan::KSource) -> Self {
        match l {
            iss_certificate::plan::KSource::ComputedKMin => Self::ComputedKMin,
            iss_certificate::plan::KSource::Scenario => Self::Scenario,
            iss_certificate::plan::KSource::Small => Self::Small,
            other => Self::Other(format!("{other:?}")),
        }
    }
}

impl From<&iss_certificate::regional::KFreeLimits> for KFreeLimits {
    fn from(l: &iss_certificate::regional::KFreeLimits) -> Self {
        Self {
            scale: num(l.scale),
            max_x0_radius: num(l.max_x0_radius),
            max_prior_error: num(l.max_prior_error),
            max_w_bar: num(l.max_w_bar),
        }
    }
}

impl From<&iss_certificate::regional::Limit> for Limit {
    fn from(l: &iss_certificate::regional::Limit) -> Self {
        Self {
            row: RowLabel::from(&l.row),
            bound: num(l.bound),
            reach: num(l.reach),
            attained: num(l.attained),
            attained_at: l.attained_at,
        }
    }
}

impl From<&iss_certificate::regional::RegionalCertificate> for RegionalCertificate {
    fn from(l: &iss_certificate::regional::RegionalCertificate) -> Self {
        Self {
            method: l.method.to_string(),
            k: l.k,
            dim: l.dim,
            rho_lin: num(l.rho_lin),
            metric: l.metric.to_string(),
            rate: num(l.rate),
            disturbance_gain: num(l.disturbance_gain),
            radius: num(l.radius),
            radius_limit: l.radius_limit.as_ref().map(Limit::from),
            initial_radius: num(l.initial_radius),
            invariant_radius: num(l.invariant_radius),
            startup_holds: l.startup_holds,
            startup_limit: l.startup_limit.as_ref().map(Limit::from),
            exact_steps: l.exact_steps,
            refuted_at_start: l.refuted_at_start.as_ref().map(Limit::from),
            impulse_terms: l.impulse_terms,
            metrics_evaluated: l.metrics_evaluated,
            witness: l.witness.as_ref().map(Limit::from),
            rows: (l.rows.0, l.rows.1),
            contains: l.contains,
            margin: num(l.margin),
            max_x0_radius: num(l.max_x0_radius),
            max_prior_error: num(l.max_prior_error),
            max_w_bar: num(l.max_w_bar),
            x_read_norm: num(l.x_read_norm),
            e_read_norm: num(l.e_read_norm),
            gain_x: num(l.gain_x),
            gain_e: num(l.gain_e),
            options: RegionalOptions::from(&l.options),
        }
    }
}

impl From<&iss_certificate::regional::RegionalOptions> for RegionalOptions {
    fn from(l: &iss_certificate::regional::RegionalOptions) -> Self {
        Self {
            x0_nominal: l.x0_nominal.iter().map(|x| num(*x)).collect(),
            x0_radius: num(l.x0_radius),
            prior_error: num(l.prior_error),
            w_bar: num(l.w_bar),
            w_box: l
                .w_box
                .as_ref()
                .map(|x| x.iter().map(|x| num(*x)).collect()),
            rate_fractions: l.rate_fractions.iter().map(|x| num(*x)).collect(),
            phase_seconds: num(l.phase_seconds),
        }
    }
}

impl From<&iss_certificate::regional::RowKind> for RowKind {
    fn from(l: &iss_certificate::regional::RowKind) -> Self {
        match l {
            iss_certificate::regional::RowKind::MheBox => Self::MheBox,
            iss_certificate::regional::RowKind::MheGeneral => Self::MheGeneral,
            iss_certificate::regional::RowKind::Input => Self::Input,
            other => Self::Other(format!("{other:?}")),
        }
    }
}

impl From<&iss_certificate::regional::RowLabel> for RowLabel {
    fn from(l: &iss_certificate::regional::RowLabel) -> Self {
        Self {
            kind: RowKind::from(&l.kind),
            step: l.step,
            iterate: l.iterate,
            index: l.index,
        }
    }
}

impl From<&iss_certificate::small_gain::Cycle> for Cycle {
    fn from(l: &iss_certificate::small_gain::Cycle) -> Self {
        Self {
            nodes: l.nodes.to_vec(),
            gain: num(l.gain),
        }
    }
}

impl From<&lti_model::ioss::IossReport> for IossReport {
    fn from(l: &lti_model::ioss::IossReport) -> Self {
        Self {
            p: l.p
                .iter()
                .map(|x| x.iter().map(|x| num(*x)).collect())
                .collect(),
            eta: num(l.eta),
            q: l.q
                .iter()
                .map(|x| x.iter().map(|x| num(*x)).collect())
                .collect(),
            r: l.r
                .iter()
                .map(|x| x.iter().map(|x| num(*x)).collect())
                .collect(),
            p_min_eigenvalue: num(l.p_min_eigenvalue),
            p_max_eigenvalue: num(l.p_max_eigenvalue),
            p_min_ratio: num(l.p_min_ratio),
            lmi_max_eigenvalue: num(l.lmi_max_eigenvalue),
            lmi_relative_violation: num(l.lmi_relative_violation),
            lmi_relative_tolerance: num(l.lmi_relative_tolerance),
            lmi_eigenvalues: l.lmi_eigenvalues.iter().map(|x| num(*x)).collect(),
            method: l.method.to_string(),
            iterations: l.iterations,
        }
    }
}

impl From<&mhe_sweep::ProbeNote> for ProbeNote {
    fn from(l: &mhe_sweep::ProbeNote) -> Self {
        Self {
            k: l.k,
            contains: l.contains,
            margin: l.margin.and_then(num),
            note: l.note.to_string(),
        }
    }
}

impl From<&mpc_core::lipschitz::LipschitzCertificate> for LipschitzCertificate {
    fn from(l: &mpc_core::lipschitz::LipschitzCertificate) -> Self {
        Self {
            first_block: num(l.first_block),
            sequence: num(l.sequence),
            h_inv_sqrt_f: num(l.h_inv_sqrt_f),
            e0_h_inv_sqrt: num(l.e0_h_inv_sqrt),
            h_min_eigenvalue: num(l.h_min_eigenvalue),
            unconstrained_gain: num(l.unconstrained_gain),
            origin_interior: l.origin_interior,
            polynomial: num(l.polynomial),
            saturable: l.saturable,
        }
    }
}

impl From<&mpc_core::lipschitz::LipschitzReport> for LipschitzReport {
    fn from(l: &mpc_core::lipschitz::LipschitzReport) -> Self {
        Self {
            certified: LipschitzCertificate::from(&l.certified),
            sampled: SampledLipschitz::from(&l.sampled),
            enumerated: l.enumerated.and_then(num),
            enumeration_skipped: l.enumeration_skipped.as_ref().map(ToString::to_string),
            saturated_lqr: num(l.saturated_lqr),
            void_reason: l.void_reason.as_ref().map(ToString::to_string),
        }
    }
}

impl From<&mpc_core::lipschitz::SampledLipschitz> for SampledLipschitz {
    fn from(l: &mpc_core::lipschitz::SampledLipschitz) -> Self {
        Self {
            estimate: num(l.estimate),
            worst_x: l.worst_x.iter().map(|x| num(*x)).collect(),
            worst_x_prime: l.worst_x_prime.iter().map(|x| num(*x)).collect(),
            pairs: l.pairs,
            evaluations: l.evaluations,
            switches_located: l.switches_located,
            seed: l.seed,
            radius: num(l.radius),
            delta: num(l.delta),
        }
    }
}

impl From<&qp_iter::certificate::BoundedQuantity> for BoundedQuantity {
    fn from(l: &qp_iter::certificate::BoundedQuantity) -> Self {
        match l {
            qp_iter::certificate::BoundedQuantity::IterateDistance => Self::IterateDistance,
            qp_iter::certificate::BoundedQuantity::SplittingVariable => Self::SplittingVariable,
            qp_iter::certificate::BoundedQuantity::ObjectiveGap => Self::ObjectiveGap,
        }
    }
}

impl From<&qp_iter::certificate::CertNorm> for CertNorm {
    fn from(l: &qp_iter::certificate::CertNorm) -> Self {
        match l {
            qp_iter::certificate::CertNorm::Euclidean => Self::Euclidean,
            qp_iter::certificate::CertNorm::Other(a0) => Self::Other(a0.to_string()),
        }
    }
}

impl From<&qp_iter::certificate::Certificate> for IterationCertificate {
    fn from(l: &qp_iter::certificate::Certificate) -> Self {
        Self {
            rate: num(l.rate),
            prefactor: num(l.prefactor),
            quantity: BoundedQuantity::from(&l.quantity),
            norm: CertNorm::from(&l.norm),
            fits_eq11: l.fits_eq11,
            premise: l.premise.to_string(),
            source: l.source.to_string(),
        }
    }
}
