//! The report's verdicts, one place each: per method the flattened Theorem 1 verdict
//! ([`SolverSummary`]) and the scenario's own verdict ([`Report::certified`]), which
//! `certificate.json`, the terminal summaries and the tests all read.

use iss_certificate::analysis::Premise;
use iss_certificate::budget::NotComputed;
use iss_certificate::certificate::SolverCertificate;
use iss_certificate::coverage::CertificateKind;
use iss_certificate::outcome::VoidReason;
use qp_iter::Method;

use crate::Report;

/// One method's verdict of Theorem 1, flattened: K_min or why there is none, the premises,
/// φ(K), and whether a certificate covers the scenario's configuration with this method.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct SolverSummary {
    /// The method Φ.
    pub solver: Method,
    /// Whether this is the scenario's `mhe.method` (the one simulated).
    pub simulated: bool,
    /// Theorem 1 (K_min) or the global loop certificate (K_glob) certifies ISS for some K, and
    /// a certificate covers the scenario's configuration (false for a shifted warm start or
    /// the saturated LQR: [`iss_certificate::coverage::solver_certified`]).
    pub certified: bool,
    /// Smallest certified K; None when void or not computed.
    pub k_min: Option<usize>,
    /// The global loop certificate's K_glob in f64 (Theorem L3; None: `global` says why).
    pub k_glob: Option<usize>,
    /// Its K_glob in f32 (Theorem L3u).
    pub k_glob_f32: Option<usize>,
    /// The smallest K the one verdict certifies in f32 — Theorem 1 with the f32 rounding
    /// folded in or Theorem L3u ([`F32Entry::k`]); None: [`SolverSummary::f32_reason`].
    pub k_f32: Option<usize>,
    /// Why no K is certified in f32 (None when one is).
    pub f32_reason: Option<iss_certificate::coverage::PairReason>,
    /// K_chain: the smallest K the iteration chain certified (Theorem L3b, L3c for FISTA;
    /// f64, pg, fista and their Jacobi variants; that K only: the chain is not monotone in K).
    pub k_chain: Option<usize>,
    /// The global certificate's outcome in f64 and f32 (None: not computed with the
    /// certificate, or not for this controller).
    pub global: Option<iss_certificate::lure::global_outcome::MethodGlobal>,
    /// Why there is no K_min (empty when there is one, and when it was not computed).
    pub void_reasons: Vec<VoidReason>,
    /// Not certified and not void: the analysis budget stopped the phase that decides it.
    pub not_computed: Option<NotComputed>,
    /// Every premise with pass/fail, value, margin and fix.
    pub premises: Vec<Premise>,
    /// φ(K) = prefactor · rateᴷ: the rate.
    pub phi_rate: f64,
    /// Prefactor of φ(K).
    pub phi_prefactor: f64,
    /// 1 − (sg1 + sg2 + sg3) = det(I − Γ) at K_min, > 0 iff ρ(Γ) < 1 (None when void).
    pub margin_at_k_min: Option<f64>,
    /// K_min with the sampled L_Φ instead of the certified bound (not a certificate).
    pub k_min_with_sampled_l_phi: Option<usize>,
}

impl SolverSummary {
    /// The summary of `sc` in `report`'s scenario (its method simulated, its controller).
    fn new(report: &Report, sc: &SolverCertificate) -> Self {
        let f32 = report.f32.iter().find(|e| e.solver == sc.solver);
        let global =
            iss_certificate::coverage::global_of(&report.certificate, sc.solver, report.controller)
                .filter(|_| {
                    iss_certificate::coverage::covering(
                        &report.scenario,
                        sc.solver,
                        report.controller,
                    )
                    .covers()
                    .is_some()
                });
        Self {
            solver: sc.solver,
            simulated: sc.solver == report.solver,
            certified: iss_certificate::coverage::solver_certified(
                &report.scenario,
                &report.certificate,
                sc,
                report.controller,
            ),
            k_min: sc.k_min,
            k_glob: global.and_then(|g| g.exact.k_glob()),
            k_glob_f32: global.and_then(|g| g.f32.k_glob()),
            k_f32: f32.and_then(F32Entry::k),
            f32_reason: f32
                .filter(|e| e.k().is_none())
                .and_then(|e| e.verdict.reason.clone()),
            k_chain: global
                .and_then(|g| g.chain.as_ref())
                .and_then(|c| c.k_chain()),
            global: global.cloned(),
            void_reasons: sc.void_reasons.clone(),
            not_computed: sc.not_computed.clone(),
            premises: sc.analysis.premises.clone(),
            phi_rate: sc.phi_rate,
            phi_prefactor: sc.phi_prefactor,
            margin_at_k_min: sc.at_k_min.as_ref().map(|g| g.margin),
            k_min_with_sampled_l_phi: sc.k_min_with_sampled_l_phi,
        }
    }
}

impl Report {
    /// Theorem 1's verdict of every method, in the certificate's order.
    ///
    /// ```no_run
    /// # use closed_loop::scenario::Scenario;
    /// let scenario = Scenario::from_file("scenarios/case-study-certified.toml")?;
    /// let report = mhe_report::report(scenario, &mhe_report::Options::default(), &mhe_report::Quiet)?;
    /// for s in report.solver_summaries() {
    ///     println!("{}: K_min = {:?}, covered: {}", s.solver, s.k_min, s.certified);
    /// }
    /// println!("the scenario's configuration can be certified: {}", report.certified());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn solver_summaries(&self) -> Vec<SolverSummary> {
        (self.certificate.solvers.iter())
            .map(|s| SolverSummary::new(self, s))
            .collect()
    }

    /// Some pair (K, K_c) of the scenario's configuration is certified: a certificate covers
    /// it and, for Theorem 1, its method has a K_min; any other certificate needs the joint
    /// region's cheapest pair as well.
    pub fn certified(&self) -> bool {
        self.applicable.may_certify()
            && (self.applicable.kind() == Some(CertificateKind::Theorem1)
                || (self.joint_certificate.as_ref()).is_some_and(|j| j.region.cheapest.is_some()))
    }

    /// The smallest K of `method` that the one verdict ([`iss_certificate::coverage::verdict`],
    /// f64, the scenario's warm start and controller) certifies: Theorem 1's K_min, the
    /// global loop certificate's K_glob or a K the iteration chain certified, whichever is
    /// smallest (its `k_min`); None when no K is certified or nothing covers the
    /// configuration. The K of the sample-period budget: the cheapest certified step.
    pub fn smallest_certified_k(&self, method: Method) -> Option<usize> {
        use iss_certificate::coverage::{Certified, Configuration, Scalar, verdict};
        let v = verdict(
            &self.resolved,
            &self.certificate,
            &Configuration {
                method,
                k_e: self.iterations,
                controller: self.controller,
                scalar: Scalar::F64,
            },
        );
        v.k_min.filter(|_| v.certified != Certified::Void)
    }

    /// `mhe.iterations` equals the K_min of the scenario's method (None when void).
    pub fn iterations_match_k_min(&self) -> Option<bool> {
        (self.certificate.solver(self.solver))
            .and_then(|s| s.k_min)
            .map(|k| k == self.iterations)
    }
}

/// One method's verdict in f32 at the scenario's K and controller
/// ([`iss_certificate::coverage::verdict`] with [`iss_certificate::coverage::Scalar::F32`]):
/// its floor is the smallest K certified in f32, by Theorem 1 with the f32 rounding folded
/// in or by the global loop certificate in f32 (Theorem L3u).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct F32Entry {
    /// The method.
    pub solver: Method,
    /// The verdict.
    pub verdict: iss_certificate::coverage::PairVerdict,
}

impl F32Entry {
    /// The verdicts of every method of `cert` on `resolved` with `controller`, at `k`.
    pub(crate) fn all(
        resolved: &closed_loop::scenario::ResolvedScenario,
        cert: &iss_certificate::certificate::ClosedLoopCertificate,
        controller: closed_loop::scenario::ControllerChoice,
        k: usize,
    ) -> Vec<Self> {
        use iss_certificate::coverage::{Configuration, Scalar, verdict};
        (cert.solvers.iter())
            .map(|s| Self {
                solver: s.solver,
                verdict: verdict(
                    resolved,
                    cert,
                    &Configuration {
                        method: s.solver,
                        k_e: k,
                        controller,
                        scalar: Scalar::F32,
                    },
                ),
            })
            .collect()
    }

    /// The smallest K certified in f32 (None: the verdict's reason says why).
    ///
    /// ```no_run
    /// # use closed_loop::scenario::Scenario;
    /// let scenario = Scenario::from_file("scenarios/rao-rawlings-lee.toml")?;
    /// let report = mhe_report::report(scenario, &mhe_report::Options::default(), &mhe_report::Quiet)?;
    /// for e in &report.f32 {
    ///     println!("{}: f32 from K = {:?}", e.solver, e.k());
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn k(&self) -> Option<usize> {
        let c = self.verdict.certified;
        if c.is_certified() || c.is_below_floor() {
            self.verdict.k_min
        } else {
            None
        }
    }
}
