//! `From<&library type>` for the records of γ₁,₃ and the joint MHE + MPC certificate.

use super::super::*;

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
            self_loop: num(l.self_loop),
            delta_offset: num(l.delta_offset),
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
