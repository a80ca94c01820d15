//! `certificate_json::v1` records of the certify document.

// `From<&record>` for the document of `certificate_json::v1` (the schema is the crate's).
use certificate_json::v1;
use certificate_json::v1::num as json_num;

impl From<&crate::certify::CertificateDocument> for v1::IossCertificate {
    fn from(l: &crate::certify::CertificateDocument) -> Self {
        Self {
            format: l.format.to_string(),
            format_version: l.format_version,
            passed: l.passed,
            failure: l.failure.as_ref().map(ToString::to_string),
            hint: l.hint.as_ref().map(ToString::to_string),
            scenario: v1::IossScenario::from(&l.scenario),
            provenance: v1::Provenance::from(&l.provenance),
            system: v1::IossSystem::from(&l.system),
            inputs: v1::IossInputs::from(&l.inputs),
            certificate: l.certificate.as_ref().map(v1::IossReport::from),
            tolerance_rule: l.tolerance_rule.to_string(),
            controller_lipschitz: l
                .controller_lipschitz
                .as_ref()
                .map(v1::LipschitzReport::from),
            controller_lipschitz_skipped: l
                .controller_lipschitz_skipped
                .as_ref()
                .map(ToString::to_string),
            closed_loop: l.closed_loop.as_ref().map(v1::Coverage::from),
            loop_methods: l.loop_methods.as_ref().map(v1::LoopSection::from),
        }
    }
}

impl From<&crate::certify::loop_methods::LoopSection> for v1::LoopSection {
    fn from(l: &crate::certify::loop_methods::LoopSection) -> Self {
        Self {
            global_seconds: json_num(l.global_seconds),
            elapsed_seconds: json_num(l.elapsed_seconds),
            methods: l
                .methods
                .iter()
                .map(|m| v1::LoopMethod {
                    method: m.method.name().to_string(),
                    k_lin: m.k_lin,
                    k_lin_note: m.k_lin_note.clone(),
                    theorem1_k_min: m.theorem1_k_min,
                    k_min_note: m.k_min_note.clone(),
                    global: v1::GlobalLoopOutcome::from(&m.global),
                })
                .collect(),
        }
    }
}

impl From<&crate::certify::Inputs> for v1::IossInputs {
    fn from(l: &crate::certify::Inputs) -> Self {
        Self {
            eta: json_num(l.eta),
            eta_source: l.eta_source.to_string(),
            q: l.q
                .iter()
                .map(|x| x.iter().map(|x| json_num(*x)).collect())
                .collect(),
            r: l.r
                .iter()
                .map(|x| x.iter().map(|x| json_num(*x)).collect())
                .collect(),
            weights_source: l.weights_source.to_string(),
            p_source: l.p_source.to_string(),
        }
    }
}

impl From<&crate::certify::PlantDims> for v1::PlantDims {
    fn from(l: &crate::certify::PlantDims) -> Self {
        Self {
            nx: l.nx,
            nu: l.nu,
            ny: l.ny,
            nw1: l.nw1,
            nw2: l.nw2,
        }
    }
}

impl From<&crate::certify::ScenarioInfo> for v1::IossScenario {
    fn from(l: &crate::certify::ScenarioInfo) -> Self {
        Self {
            name: l.name.to_string(),
            path: l.path.to_string(),
        }
    }
}

impl From<&crate::certify::SystemInfo> for v1::IossSystem {
    fn from(l: &crate::certify::SystemInfo) -> Self {
        Self {
            dims: v1::PlantDims::from(&l.dims),
            a: l.a
                .iter()
                .map(|x| x.iter().map(|x| json_num(*x)).collect())
                .collect(),
            c: l.c
                .iter()
                .map(|x| x.iter().map(|x| json_num(*x)).collect())
                .collect(),
            b_bar: l
                .b_bar
                .iter()
                .map(|x| x.iter().map(|x| json_num(*x)).collect())
                .collect(),
            d_bar: l
                .d_bar
                .iter()
                .map(|x| x.iter().map(|x| json_num(*x)).collect())
                .collect(),
        }
    }
}
