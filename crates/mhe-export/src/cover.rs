//! The certificate that covers an exported K when it is not Theorem 1: the global loop
//! certificate (Theorem L3/L3u) or the iteration chain (Theorem L3b), as the artefacts name it.

use closed_loop::scenario::ControllerChoice;
use iss_certificate::certificate::ClosedLoopCertificate;
use iss_certificate::coverage::{CertificateKind, PairVerdict};
use qp_iter::Method;
use serde_json::json;

use crate::api::ScalarKind;

/// The numbers of the certificate that covers the exported K when it is not Theorem 1: the
/// global loop certificate (every K ≥ K_glob; the verdict's `certificate` is
/// [`CertificateKind::Global`]) or the iteration chain (that K only, f64;
/// [`CertificateKind::Chain`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum GlobalCover {
    /// Theorem L3 (f64) or L3u (f32).
    L3 {
        /// K_glob in the artefact's scalar.
        k_glob: usize,
        /// φ* (φ*_u in f32).
        phi_star: f64,
        /// The ISS offset of the rounding (f32; None in f64, where the rounding is inside the
        /// check's margin).
        offset: Option<f64>,
    },
    /// Theorem L3b at the exported K (f64 only: the chain has no rounding input).
    Chain {
        /// The K checked and certified (the exported K).
        k: usize,
        /// The LMI's margin in the independent check.
        margin: f64,
        /// ρ of the certificate.
        rho: f64,
    },
}

impl GlobalCover {
    /// The cover of `method` in `scalar` from the certificate's global section, if the
    /// verdict `v` says the global certificate or the chain certifies.
    pub(crate) fn of(
        cert: &ClosedLoopCertificate,
        method: Method,
        scalar: ScalarKind,
        v: &PairVerdict,
        k: usize,
    ) -> Option<Self> {
        use iss_certificate::lure::global_outcome::{GlobalOutcome, PrecisionOutcome};
        if !v.certified.is_certified() {
            return None;
        }
        let g = iss_certificate::coverage::global_of(cert, method, ControllerChoice::ExactMpc)?;
        if v.certificate == Some(CertificateKind::Chain) {
            let c = g.chain.as_ref()?.chain()?.at(k)?.certified()?;
            return (scalar == ScalarKind::F64).then_some(Self::Chain {
                k,
                margin: c.margin,
                rho: c.rho,
            });
        }
        if v.certificate != Some(CertificateKind::Global) {
            return None;
        }
        match (scalar, &g.exact, &g.f32) {
            (ScalarKind::F64, GlobalOutcome::Certified(k), _) => Some(Self::L3 {
                k_glob: k.k_glob,
                phi_star: k.phi_star,
                offset: None,
            }),
            (ScalarKind::F32, _, PrecisionOutcome::Certified(k)) => Some(Self::L3 {
                k_glob: k.k_glob,
                phi_star: k.phi_star,
                offset: Some(k.offset),
            }),
            _ => None,
        }
    }

    /// The certificate's name in the artefact's words.
    pub(crate) fn name(&self) -> &'static str {
        match self {
            Self::L3 {
                offset: Some(_), ..
            } => "the global loop certificate in f32 (Theorem L3u)",
            Self::L3 { .. } => "the global loop certificate (Theorem L3)",
            Self::Chain { .. } => "the iteration chain (Theorem L3b; L3c for FISTA)",
        }
    }

    /// The ISS offset of f32's rounding (Theorem L3u only).
    pub(crate) fn offset(&self) -> Option<f64> {
        match self {
            Self::L3 { offset, .. } => *offset,
            Self::Chain { .. } => None,
        }
    }

    /// "K = … ≥ K_glob = … of …" or "K = … checked and certified by …" (banner, README).
    pub(crate) fn sentence(&self, k: usize) -> String {
        match self {
            Self::L3 { k_glob, .. } => format!("K = {k} ≥ K_glob = {k_glob} of {}", self.name()),
            Self::Chain { .. } => format!(
                "K = {k}, checked at this K and certified by {} (that K only: the chain is not \
                 monotone in K)",
                self.name()
            ),
        }
    }

    pub(crate) fn json(&self) -> serde_json::Value {
        match self {
            Self::L3 {
                k_glob,
                phi_star,
                offset,
            } => json!({
                "certificate": "global",
                "name": self.name(),
                "k_glob": k_glob,
                "phi_star": phi_star,
                "offset": offset,
            }),
            Self::Chain { k, margin, rho } => json!({
                "certificate": "chain",
                "name": self.name(),
                "k_chain": k,
                "margin": margin,
                "rho": rho,
            }),
        }
    }
}
