//! `From<&library type>` for the records of the linear and regional analyses, LMI (2), the MPC's L_π, the iteration certificates and the sweep's notes.

use super::super::*;

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
            lmi_relative_violation: l.lmi_relative_violation.and_then(num),
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
