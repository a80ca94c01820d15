//! Computing the certificate of a resolved scenario: every constant, per method.

use lti_model::matrix::{spectral_norm, sym_extreme_eigenvalues};
use mhe_core::{LipschitzSampling, MheProblem};

use super::*;
use crate::analysis::{IssInputs, eta_sup_for_horizon, min_horizon_for_eta};
use crate::outcome::IossFailure;
use closed_loop::scenario::ResolvedScenario;
use closed_loop::sim::ClosedLoopError;

fn map_certificates(
    solver: Method,
    problem: &MheProblem,
) -> Result<Vec<Certificate>, ClosedLoopError> {
    problem
        .windows()
        .iter()
        .map(|w| {
            solver
                .certificate_for(w.qp().clone())
                .map_err(|e| ClosedLoopError::Mhe(mhe_core::MheError::Qp(e)))
        })
        .collect()
}

/// The verdict the analysis budget cut short (issue 37 item 6): no K_min, the certified
/// γ₁,₃'s free-set enumeration skipped for `certificate.phase_seconds`, and nothing else
/// that voids the certificate whatever γ₁,₃ is (a structural reason, or a premise other than
/// "gamma13 finite"). The enumeration gives a γ₁,₃ no larger than the family bound, so with
/// it the certificate may exist: "not computed", with the enumeration's estimate, not "void".
fn budget_cut(
    k_min: Option<usize>,
    analysis: &IssAnalysis,
    gamma13: &Gamma13Report,
    structurally_void: bool,
) -> Option<crate::budget::NotComputed> {
    if k_min.is_some() || structurally_void {
        return None;
    }
    // A refuted user value (or any other void reason of γ₁,₃ than the budget) stands.
    let cut = match &gamma13.void {
        None | Some(crate::gamma13::Gamma13Void::NotComputedWithinBudget { .. }) => {
            gamma13.certified.as_ref()?.over_budget.clone()?
        }
        Some(_) => return None,
    };
    analysis
        .violated()
        .iter()
        .all(|p| p.name == "gamma13 finite")
        .then_some(cut)
}

/// Computes the closed-loop certificate of a scenario (needs `[mhe]` and `[mpc]`).
///
/// Errors only for bad input (missing sections, invalid data); an infeasible LMI or a
/// violated premise is *reported* in the result (void certificates), not an error.
pub fn certify_closed_loop(
    resolved: &ResolvedScenario,
    opts: &CertificateOptions,
) -> Result<ClosedLoopCertificate, ClosedLoopError> {
    certify_closed_loop_timed(resolved, opts).map(|(c, _)| c)
}

/// Wall time of each part of [`certify_closed_loop`] (seconds), for the commands' own
/// timing output (the certificate itself is deterministic; these are not).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[non_exhaustive]
pub struct CertificateTimes {
    /// The MHE's condensed windows, H̄ and the certified L_Φ.
    pub mhe_constants_s: f64,
    /// The sampled L_Φ (exact solves of every window at seeded pairs).
    pub l_phi_sampling_s: f64,
    /// L_π (certified and sampled).
    pub l_pi_s: f64,
    /// γ₁,₃ (certified and sampled).
    pub gamma13_s: f64,
    /// Theorem 1 per solver (φ(K), the small-gain conditions, K_min).
    pub theorem1_s: f64,
    /// The global loop certificate (Theorem L3, its f32 form and the iteration chain;
    /// 0 when not computed: `global_seconds` None).
    pub global_s: f64,
    /// The whole certificate.
    pub total_s: f64,
}

/// [`certify_closed_loop`] with the wall time of each part.
pub fn certify_closed_loop_timed(
    resolved: &ResolvedScenario,
    opts: &CertificateOptions,
) -> Result<(ClosedLoopCertificate, CertificateTimes), ClosedLoopError> {
    certify_closed_loop_with(resolved, opts, ComputedParts::default())
}

/// The two long enumerations of the certificate, computed elsewhere in independent pieces
/// (the sweep's pool runs them as tasks beside its runs: [`mpc_core::CondensedMpc::lipschitz_enumerated_in`]
/// and the stages of [`crate::gamma13::Gamma13Plan`]). `None`: computed by
/// [`certify_closed_loop_with`] itself.
#[derive(Debug, Default)]
#[non_exhaustive]
pub struct ComputedParts {
    /// L_enum of the scenario's MPC: what `mpc.lipschitz_enumerated(`[`mpc_core::ENUMERATION_MAX_VARS`]`)`
    /// returns (used only without state constraints).
    pub l_pi_enumerated: Option<Result<Option<f64>, mpc_core::MpcError>>,
    /// The certified γ₁,₃: what [`crate::gamma13::gamma13_certified_budgeted`] returns with
    /// `opts.enumeration_max_vars`, [`crate::gamma13::GAMMA13_PATTERN_FAMILIES`] and
    /// `opts.phase_seconds` (used only for [`Gamma13Source::Certified`] without state
    /// constraints).
    pub gamma13_certified: Option<Result<crate::gamma13::Gamma13Certificate, mpc_core::MpcError>>,
}

/// [`certify_closed_loop_timed`] with the parts of `parts` computed elsewhere: the same
/// certificate, bit for bit, when they are what their fields say.
pub fn certify_closed_loop_with(
    resolved: &ResolvedScenario,
    opts: &CertificateOptions,
    parts: ComputedParts,
) -> Result<(ClosedLoopCertificate, CertificateTimes), ClosedLoopError> {
    let ComputedParts {
        l_pi_enumerated,
        gamma13_certified,
    } = parts;
    let start = std::time::Instant::now();
    let mut times = CertificateTimes::default();
    let mut split = laps(start);
    let scenario = resolved.scenario();
    let spec = scenario
        .mhe
        .as_ref()
        .ok_or(ClosedLoopError::MissingSection { section: "mhe" })?;
    let mpc = resolved.mpc()?.clone();
    // A phase every certificate needs, estimated beyond its documented limit: refused now.
    crate::budget::check_required_phases(scenario, Some(&mpc), opts)?;
    let sys = &scenario.plant;
    let (m, eta) = (spec.horizon(), spec.eta());
    let c_norm = spectral_norm(sys.c());
    let (_, q_max) = sym_extreme_eigenvalues("Q", spec.q().as_ref())?;

    let (ioss_cert, ioss_failure) = assumption2(resolved)?;
    // MHE constants (need P). ℙ_t with the resolved P: the scenario's one problem, shared
    // with the simulation.
    let problem = ioss_cert
        .as_ref()
        .map(|_| resolved.mhe_problem().cloned())
        .transpose()?;
    times.mhe_constants_s = split();
    let lemma1_origin_offsets: Vec<f64> = problem.as_ref().map_or_else(Vec::new, |pr| {
        pr.windows().iter().map(lemma1::origin_offset).collect()
    });
    let (h_bar, l_phi, h_paper_norms) = mhe_constants(problem.as_deref(), opts)?;
    times.l_phi_sampling_s = split();
    // Controller constants; a numerical failure names the scenario keys that shape the QP.
    let explain = |e: mpc_core::MpcError| match &scenario.mpc {
        Some(spec) => spec.explain(sys, e),
        None => e,
    };
    let radius = resolved.sampling_radius();
    let l_pi = l_pi_report(&mpc, opts, radius, l_pi_enumerated).map_err(explain)?;
    let l_pi_used = l_pi.l_pi();
    times.l_pi_s = split();
    let gamma13 = gamma13_report(&mpc, opts, gamma13_certified).map_err(explain)?;
    times.gamma13_s = split();

    let (p_min, p_max) = ioss_cert
        .as_ref()
        .map(|c| (c.p_min_eigenvalue, c.p_max_eigenvalue))
        .unzip();
    let shared = shared_inputs(
        (m, eta, q_max),
        ioss_cert.as_ref(),
        h_bar,
        &l_phi,
        l_pi_used,
        gamma13.used,
        sys,
    );
    let theorem1 = Theorem1Parts {
        shared: &shared,
        problem: problem.as_deref(),
        mpc: &mpc,
        gamma13: &gamma13,
        l_phi_sampled: l_phi.sampled,
    };
    let solvers = opts
        .solvers
        .iter()
        .map(|&solver| theorem1.solver_certificate(solver, opts))
        .collect::<Result<Vec<_>, _>>()?;
    times.theorem1_s = split();
    let global = opts.global_seconds.and_then(|phase_seconds| {
        let settings = crate::lure::global_outcome::GlobalSettings {
            phase_seconds,
            ..Default::default()
        };
        crate::lure::global_outcome::global_section(resolved, &opts.solvers, &settings)
    });
    times.global_s = split();
    times.total_s = start.elapsed().as_secs_f64();
    let certificate = ClosedLoopCertificate {
        scenario: scenario.name.clone(),
        horizon: m,
        eta,
        rho: 6f64.powf(1.0 / m as f64) * eta,
        ioss: ioss_cert.as_ref().map(ioss::IossCertificate::report),
        ioss_failure,
        p_min,
        p_max,
        q_max,
        h_bar,
        c_norm,
        l_phi,
        l_pi,
        l_pi_used,
        gamma13,
        solvers,
        nearest: NearestParameters {
            min_horizon_at_eta: min_horizon_for_eta(eta),
            eta_sup_at_horizon: eta_sup_for_horizon(m),
        },
        h_paper_norms,
        sigma_model_part: spectral_norm(sys.a()) + spectral_norm(sys.b()) + c_norm + 2.0,
        lemma1_origin_offsets,
        global,
    };
    Ok((certificate, times))
}

/// Assumption 2 as resolved once with the scenario: the IOSS certificate, or why there is none.
fn assumption2(
    resolved: &ResolvedScenario,
) -> Result<(Option<ioss::IossCertificate>, Option<IossFailure>), ClosedLoopError> {
    match resolved.ioss() {
        Some(Ok(c)) => Ok((Some(c.clone()), None)),
        Some(Err(e)) => Ok((None, Some(IossFailure { error: e.clone() }))),
        None => Err(ClosedLoopError::MissingSection { section: "mhe" }),
    }
}

/// The inputs every solver shares; φ's rate, prefactor and fit are the solver's own.
fn shared_inputs(
    (m, eta, q_max): (usize, f64, f64),
    ioss_cert: Option<&ioss::IossCertificate>,
    h_bar: Option<f64>,
    l_phi: &LPhiReport,
    l_pi_used: f64,
    gamma13_used: f64,
    sys: &lti_model::LtiSystem,
) -> IssInputs {
    IssInputs {
        horizon: m,
        eta,
        // The analysis's inputs keep NaN for "no P" (the premise "LMI (2) feasible" and
        // the ones built from P then fail or are not evaluated).
        p_min: ioss_cert.map_or(f64::NAN, |c| c.p_min_eigenvalue),
        p_max: ioss_cert.map_or(f64::NAN, |c| c.p_max_eigenvalue),
        q_max,
        h_bar: h_bar.unwrap_or(f64::NAN),
        // No value makes the premise "L_Phi finite" fail (not evaluated: no P).
        l_phi: l_phi.certified.unwrap_or(f64::NAN),
        l_pi: l_pi_used,
        c_norm: spectral_norm(sys.c()),
        f_norm: spectral_norm(sys.f()),
        gamma13: gamma13_used,
        phi_rate: f64::NAN,
        phi_prefactor: f64::NAN,
        phi_fits_eq11: false,
        lmi_certified: ioss_cert.is_some(),
    }
}

/// A stopwatch: each call returns the seconds since the previous one (since `start` at the
/// first), the phase timings of [`CertificateTimes`].
fn laps(start: std::time::Instant) -> impl FnMut() -> f64 {
    let mut lap = start;
    move || {
        let now = std::time::Instant::now();
        let dt = (now - lap).as_secs_f64();
        lap = now;
        dt
    }
}

/// L_π (Assumption 3) of the MPC, with its enumerated value when computed elsewhere.
fn l_pi_report(
    mpc: &mpc_core::CondensedMpc,
    opts: &CertificateOptions,
    radius: f64,
    enumerated: Option<Result<Option<f64>, mpc_core::MpcError>>,
) -> Result<mpc_core::LipschitzReport, mpc_core::MpcError> {
    mpc_core::lipschitz_report_with(mpc, opts.lipschitz_pairs, opts.seed, radius, |m| {
        match enumerated {
            Some(r) => r,
            None => m.lipschitz_enumerated(mpc_core::ENUMERATION_MAX_VARS),
        }
    })
}

/// γ₁,₃ (Assumption 4) of the MPC as `opts.gamma13` asks, with the certified estimate when
/// computed elsewhere.
fn gamma13_report(
    mpc: &mpc_core::CondensedMpc,
    opts: &CertificateOptions,
    certified: Option<Result<crate::gamma13::Gamma13Certificate, mpc_core::MpcError>>,
) -> Result<Gamma13Report, mpc_core::MpcError> {
    crate::gamma13::gamma13_report_with(mpc, opts.gamma13, opts.gamma13_sequences, opts.seed, |m| {
        match certified {
            Some(r) => r,
            None => crate::gamma13::gamma13_certified_budgeted(
                m,
                opts.enumeration_max_vars,
                crate::gamma13::GAMMA13_PATTERN_FAMILIES,
                opts.phase_seconds,
            ),
        }
    })
}

/// H̄, the L_Φ report and ‖H_t‖ of the paper's σ_t from the MHE's problem (None: LMI (2)
/// gave no P, so none of them exists).
fn mhe_constants(
    problem: Option<&MheProblem>,
    opts: &CertificateOptions,
) -> Result<(Option<f64>, LPhiReport, Vec<f64>), ClosedLoopError> {
    let Some(pr) = problem else {
        let none = LPhiReport {
            certified: None,
            sampled: None,
            per_window: Vec::new(),
            pairs_reduced: None,
        };
        return Ok((None, none, Vec::new()));
    };
    let (pairs, pairs_reduced) =
        crate::budget::l_phi_sampling_pairs(pr, opts.lipschitz_pairs, opts.phase_seconds);
    let sampling = LipschitzSampling {
        pairs,
        seed: opts.seed,
        ..LipschitzSampling::default()
    };
    let est = pr.sample_lipschitz(&sampling)?;
    let per_window: Vec<(f64, f64)> = est.iter().map(|e| (e.certified, e.sampled)).collect();
    let norms = pr
        .windows()
        .iter()
        .map(|w| spectral_norm(w.h_paper()))
        .collect();
    let l_phi = LPhiReport {
        certified: Some(pr.lipschitz_certified()),
        sampled: Some(per_window.iter().map(|p| p.1).fold(0.0, f64::max)),
        per_window,
        pairs_reduced,
    };
    Ok((Some(pr.h_bar()), l_phi, norms))
}

/// What Theorem 1's certificate of each solver is computed from: the constants every solver
/// shares, the MHE's problem (None without P), the MPC and γ₁,₃.
struct Theorem1Parts<'a> {
    shared: &'a IssInputs,
    problem: Option<&'a MheProblem>,
    mpc: &'a mpc_core::CondensedMpc,
    gamma13: &'a Gamma13Report,
    l_phi_sampled: Option<f64>,
}

impl Theorem1Parts<'_> {
    /// Theorem 1 for `solver`: φ of its windows, the analysis with this method's advice,
    /// K_min, and why void or not computed.
    fn solver_certificate(
        &self,
        solver: Method,
        opts: &CertificateOptions,
    ) -> Result<SolverCertificate, ClosedLoopError> {
        let per_window = match self.problem {
            Some(pr) => map_certificates(solver, pr)?,
            None => Vec::new(),
        };
        let phi_rate = per_window
            .iter()
            .map(|c| c.rate)
            .fold(if per_window.is_empty() { f64::NAN } else { 0.0 }, f64::max);
        let phi_prefactor = per_window
            .iter()
            .map(|c| c.prefactor)
            .fold(if per_window.is_empty() { f64::NAN } else { 0.0 }, f64::max);
        let fits_eq11 = !per_window.is_empty() && per_window.iter().all(|c| c.fits_eq11);
        let inputs = IssInputs {
            phi_rate,
            phi_prefactor,
            phi_fits_eq11: fits_eq11,
            ..self.shared.clone()
        };
        let mut analysis = IssAnalysis::new(inputs.clone());
        self.advise(&mut analysis, solver);
        let structural_void = self.structural_void();
        let structurally_void = !structural_void.is_empty();
        let k_min = if structurally_void {
            None
        } else {
            analysis.k_min(opts.k_max)
        };
        let mut void_reasons = structural_void;
        void_reasons.extend(self.violated(&analysis));
        if k_min.is_none() && void_reasons.is_empty() {
            void_reasons.push(VoidReason::NoK { k_max: opts.k_max });
        }
        let not_computed = budget_cut(k_min, &analysis, self.gamma13, structurally_void);
        if not_computed.is_some() {
            void_reasons.clear();
        }
        let k_min_with_sampled_l_phi =
            if opts.lipschitz_pairs == 0 || self.mpc.certificate_void_reason().is_some() {
                None
            } else {
                IssAnalysis::new(IssInputs {
                    l_phi: self.l_phi_sampled.unwrap_or(f64::NAN),
                    ..inputs
                })
                .k_min(opts.k_max)
            };
        Ok(SolverCertificate {
            solver,
            phi_rate,
            phi_prefactor,
            fits_eq11,
            per_window,
            at_k_min: k_min.map(|k| analysis.at(k)),
            analysis,
            k_min,
            void_reasons,
            not_computed,
            k_min_with_sampled_l_phi,
        })
    }

    /// The fixes the premises' generic advice does not know: γ₁,₃'s typed reason (e.g. no
    /// gain can exist), and for a rate ≥ 1 the fix this method has (ADMM has no step size;
    /// issue 37 item 13).
    fn advise(&self, analysis: &mut IssAnalysis, solver: Method) {
        if let Some(v) = &self.gamma13.void {
            for p in analysis.premises.iter_mut() {
                if p.name == "gamma13 finite" && !p.holds {
                    p.fix = Some(crate::analysis::PremiseFix::Gamma13(v.clone()));
                }
            }
        }
        let general_rows = self
            .problem
            .is_some_and(|pr| pr.windows().iter().any(|w| w.qp().general().is_some()));
        for p in analysis.premises.iter_mut() {
            if p.name == "phi rate < 1" && !p.holds && p.not_evaluated.is_none() {
                p.fix = Some(crate::analysis::PremiseFix::MethodDoesNotContract {
                    method: solver,
                    general_rows,
                });
            }
        }
    }

    /// Constants whose certified value does not exist for this scenario (issue 15: bounded
    /// 𝒳 / 𝒴 in the MHE, state constraints in the MPC): void with the reason.
    fn structural_void(&self) -> Vec<VoidReason> {
        self.problem
            .and_then(MheProblem::lipschitz_void_reason)
            .map(|reason| VoidReason::LPhiUndefined { reason })
            .into_iter()
            .chain(
                self.mpc
                    .certificate_void_reason()
                    .map(|reason| VoidReason::ControllerUndefined { reason }),
            )
            .collect()
    }

    /// The violated premises as void reasons, "gamma13 finite" with γ₁,₃'s typed reason
    /// instead of the generic fix.
    fn violated(&self, analysis: &IssAnalysis) -> Vec<VoidReason> {
        analysis
            .violated()
            .iter()
            .map(|p| match &self.gamma13.void {
                Some(v) if p.name == "gamma13 finite" => VoidReason::Gamma13 {
                    premise: p.name.clone(),
                    void: v.clone(),
                },
                _ => p.void_reason(),
            })
            .collect()
    }
}
