//! The closed-loop ISS certificate of Theorem 1 for a scenario: every constant, where it
//! comes from, the premises, and the smallest certified K per solver.
//!
//! [`certify_closed_loop`] assembles the inputs of [`crate::analysis::IssAnalysis`]:
//!
//! | constant | source |
//! | --- | --- |
//! | P, η, λ(P), λ̄(Q) | [`lti_model::ioss::certify`] (LMI (2)), or the scenario's P verified |
//! | H̄ | [`mhe_core::MheProblem::h_bar`] (ε in condensed coordinates) |
//! | L_Φ | [`mhe_core::MheProblem::lipschitz_certified`], sampled estimate beside it |
//! | L_π | tightest certified bound of [`mpc_core::lipschitz_report_for`], sampled beside it |
//! | γ₁,₃ | [`crate::gamma13::gamma13_report`]: certified, or user-supplied ("not verified", refuted by the sampled lower estimate if below it) |
//! | φ(K) | each solver's certificate, worst rate and prefactor over the window lengths m = 0..M |
//!
//! The controller analysed is the exact MPC (the paper's setting). A violated premise makes
//! a solver's certificate void: `k_min` is `None` and `void_reasons` says why; a K is never
//! computed from a void bound.
//!
//! [`check_trajectory`] evaluates the trajectory inequalities of Prop. 1 (ε_t) and Prop. 3
//! (e_t) on a simulated trace with the reported constants, both sides computed from the trace.
//!
//! ## The virtual disturbance σ_t (Lemma 1)
//! For t ≤ M the paper bounds the jump of z* while the window grows by L_Φσ_t with
//! σ_t = (1 − η⁻¹)‖H_t‖ + ‖A‖ + ‖B‖ + ‖C‖ + 2, whose first term is negative for η < 1 as
//! printed; we use |1 − η⁻¹|‖H_t‖ (the magnitude the proof needs) with H_t the paper's weight
//! of eq. (10). σ_t = 0 for t > M. This term is the least rigorous step of the paper
//! (it invokes Hager's Lipschitz theorem for a change of the constraint matrices); the
//! trajectory check reports it as part of the right-hand side, not as a verified bound.

use lti_model::ioss;
use lti_model::matrix::{spectral_norm, sym_extreme_eigenvalues};
use mhe_core::{LipschitzSampling, MheProblem};
use qp_iter::Certificate;
use serde::Serialize;

use crate::analysis::{GainsAtK, IssAnalysis, IssInputs, eta_sup_for_horizon, min_horizon_for_eta};
pub use crate::gamma13::{Gamma13Report, Gamma13Source};
use crate::record::Trace;
use crate::scenario::ResolvedScenario;
use crate::sim::ClosedLoopError;
use qp_iter::Method;

/// Settings of [`certify_closed_loop`].
#[derive(Debug, Clone, PartialEq)]
pub struct CertificateOptions {
    /// Solvers to certify.
    pub solvers: Vec<Method>,
    /// γ₁,₃ source.
    pub gamma13: Gamma13Source,
    /// Seed of every sampled estimate.
    pub seed: u64,
    /// Random pairs for the sampled L_Φ and L_π.
    pub lipschitz_pairs: usize,
    /// Injected error sequences per magnitude for the sampled γ₁,₃ (0 skips it).
    pub gamma13_sequences: usize,
    /// Cap on the number of saturable input variables for the γ₁,₃ free-set enumeration
    /// (above it the polynomial bound alone is used, and the skip is reported).
    pub enumeration_max_vars: usize,
    /// Largest K searched for K_min.
    pub k_max: usize,
}

impl Default for CertificateOptions {
    fn default() -> Self {
        Self {
            solvers: Method::PRESETS.to_vec(),
            gamma13: Gamma13Source::Certified,
            seed: 0,
            lipschitz_pairs: 200,
            gamma13_sequences: 30,
            enumeration_max_vars: 20,
            k_max: 1 << 24,
        }
    }
}

/// L_Φ figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LPhiReport {
    /// max_m certified bound (used in the certificate).
    pub certified: f64,
    /// max_m sampled estimate (a lower bound on the true constant).
    pub sampled: f64,
    /// Per window length m = 0..M: (certified, sampled).
    pub per_window: Vec<(f64, f64)>,
}

/// Certificate of one solver Φ.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolverCertificate {
    /// The solver.
    pub solver: Method,
    /// φ(K) = prefactor · rateᴷ, worst over window lengths.
    pub phi_rate: f64,
    /// Prefactor of φ(K).
    pub phi_prefactor: f64,
    /// Whether every window's certificate fits eq. (11).
    pub fits_eq11: bool,
    /// The per-window certificates (m = 0..M).
    pub per_window: Vec<Certificate>,
    /// Theorem 1 with these constants (premises included).
    pub analysis: IssAnalysis,
    /// Smallest certified K (None when void or beyond `k_max`).
    pub k_min: Option<usize>,
    /// Constants and slopes at K_min.
    pub at_k_min: Option<GainsAtK>,
    /// Why there is no K_min (empty when there is one).
    pub void_reasons: Vec<String>,
    /// K_min with the *sampled* L_Φ in place of the certified bound — not a certificate,
    /// reported to show how much of K_min is due to L_Φ's conservatism.
    pub k_min_with_sampled_l_phi: Option<usize>,
}

/// Parameters near the scenario's that satisfy ρ < 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NearestParameters {
    /// Smallest M with 6η^M < 1 at the scenario's η.
    pub min_horizon_at_eta: Option<usize>,
    /// η must be below 6^{−1/M} at the scenario's M.
    pub eta_sup_at_horizon: f64,
}

/// Everything [`certify_closed_loop`] computes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClosedLoopCertificate {
    /// Scenario name.
    pub scenario: String,
    /// MHE horizon M.
    pub horizon: usize,
    /// η.
    pub eta: f64,
    /// ρ = 6^{1/M}η.
    pub rho: f64,
    /// The δ-IOSS certificate (None when LMI (2) is infeasible).
    pub ioss: Option<ioss::IossReport>,
    /// Why LMI (2) failed (None when it holds).
    pub ioss_failure: Option<String>,
    /// λ_min(P), λ_max(P), λ_max(Q).
    pub p_min: f64,
    /// λ_max(P).
    pub p_max: f64,
    /// λ_max(Q).
    pub q_max: f64,
    /// H̄ (NaN when the MHE could not be built).
    pub h_bar: f64,
    /// ‖C‖₂.
    pub c_norm: f64,
    /// L_Φ.
    pub l_phi: LPhiReport,
    /// L_π report (certified, enumerated, sampled).
    pub l_pi: mpc_core::LipschitzReport,
    /// L_π used (tightest certified bound).
    pub l_pi_used: f64,
    /// γ₁,₃.
    pub gamma13: Gamma13Report,
    /// One certificate per solver.
    pub solvers: Vec<SolverCertificate>,
    /// Nearest parameters satisfying ρ < 1.
    pub nearest: NearestParameters,
    /// ‖H_t‖₂ of the paper's weight (eq. 10) per window length m = 0..M, for σ_t.
    pub h_paper_norms: Vec<f64>,
    /// ‖A‖₂ + ‖B‖₂ + ‖C‖₂ + 2: the model part of σ_t.
    pub sigma_model_part: f64,
}

impl ClosedLoopCertificate {
    /// The certificate of one solver.
    pub fn solver(&self, solver: Method) -> Option<&SolverCertificate> {
        self.solvers.iter().find(|s| s.solver == solver)
    }

    /// σ_t of Lemma 1 (module doc): |1 − η⁻¹|‖H_t‖ + ‖A‖ + ‖B‖ + ‖C‖ + 2 for t ≤ M, else 0.
    pub fn sigma(&self, t: usize) -> f64 {
        if t > self.horizon {
            return 0.0;
        }
        let h = self
            .h_paper_norms
            .get(t.min(self.horizon))
            .copied()
            .unwrap_or(f64::NAN);
        (1.0 - 1.0 / self.eta).abs() * h + self.sigma_model_part
    }
}

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

/// Computes the closed-loop certificate of a scenario (needs `[mhe]` and `[mpc]`).
///
/// Errors only for bad input (missing sections, invalid data); an infeasible LMI or a
/// violated premise is *reported* in the result (void certificates), not an error.
pub fn certify_closed_loop(
    resolved: &ResolvedScenario,
    opts: &CertificateOptions,
) -> Result<ClosedLoopCertificate, ClosedLoopError> {
    let scenario = resolved.scenario();
    let spec = scenario
        .mhe
        .as_ref()
        .ok_or(ClosedLoopError::MissingSection { section: "mhe" })?;
    let mpc = resolved.mpc()?.clone();
    let sys = &scenario.plant;
    let (m, eta) = (spec.horizon, spec.eta);
    let c_norm = spectral_norm(sys.c());
    let (_, q_max) = sym_extreme_eigenvalues("Q", spec.q.as_ref())?;

    // Assumption 2 (resolved once with the scenario).
    let (ioss_cert, ioss_failure) = match resolved.ioss() {
        Some(Ok(c)) => (Some(c.clone()), None),
        Some(Err(e)) => (None, Some(e.to_string())),
        None => return Err(ClosedLoopError::MissingSection { section: "mhe" }),
    };

    // MHE constants (need P).
    let problem = match &ioss_cert {
        Some(c) => {
            let mut cfg = resolved.mhe_config()?.clone();
            cfg.p = c.p.clone();
            Some(MheProblem::new(
                sys,
                m,
                &cfg.weights(),
                resolved.mhe_sets(),
            )?)
        }
        None => None,
    };
    let (h_bar, l_phi, h_paper_norms) = match &problem {
        Some(pr) => {
            let sampling = LipschitzSampling {
                pairs: opts.lipschitz_pairs,
                seed: opts.seed,
                ..LipschitzSampling::default()
            };
            let est = pr.sample_lipschitz(&sampling)?;
            let per_window: Vec<(f64, f64)> =
                est.iter().map(|e| (e.certified, e.sampled)).collect();
            let norms = pr
                .windows()
                .iter()
                .map(|w| spectral_norm(w.h_paper()))
                .collect();
            (
                pr.h_bar(),
                LPhiReport {
                    certified: pr.lipschitz_certified(),
                    sampled: per_window.iter().map(|p| p.1).fold(0.0, f64::max),
                    per_window,
                },
                norms,
            )
        }
        None => (
            f64::NAN,
            LPhiReport {
                certified: f64::NAN,
                sampled: f64::NAN,
                per_window: Vec::new(),
            },
            Vec::new(),
        ),
    };

    // Controller constants.
    let radius = resolved.sampling_radius();
    let l_pi = mpc_core::lipschitz_report_for(&mpc, opts.lipschitz_pairs, opts.seed, radius)?;
    let l_pi_used = l_pi.l_pi();
    let gamma13 = crate::gamma13::gamma13_report(
        &mpc,
        opts.gamma13,
        opts.gamma13_sequences,
        opts.seed,
        opts.enumeration_max_vars,
    )?;

    let (p_min, p_max) = ioss_cert.as_ref().map_or((f64::NAN, f64::NAN), |c| {
        (c.p_min_eigenvalue, c.p_max_eigenvalue)
    });
    let mut solvers = Vec::new();
    for &solver in &opts.solvers {
        let per_window = match &problem {
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
            horizon: m,
            eta,
            p_min,
            p_max,
            q_max,
            h_bar,
            l_phi: l_phi.certified,
            l_pi: l_pi_used,
            c_norm,
            gamma13: gamma13.used,
            phi_rate,
            phi_prefactor,
            phi_fits_eq11: fits_eq11,
            lmi_certified: ioss_cert.is_some(),
        };
        let analysis = IssAnalysis::new(inputs.clone());
        let k_min = analysis.k_min(opts.k_max);
        let mut void_reasons: Vec<String> = analysis
            .violated()
            .iter()
            .map(|p| match &gamma13.void {
                // The exact reason (typed in `gamma13.void`) instead of the generic fix.
                Some(v) if p.name == "gamma13 finite" => format!("{} fails: {v}", p.name),
                _ => format!(
                    "{} fails ({} = {:.6}): {}",
                    p.name, p.needed_by, p.value, p.fix
                ),
            })
            .collect();
        if k_min.is_none() && void_reasons.is_empty() {
            void_reasons.push(format!("no K ≤ {} satisfies (sg1)–(sg3)", opts.k_max));
        }
        let sampled_analysis = IssAnalysis::new(IssInputs {
            l_phi: l_phi.sampled,
            ..inputs
        });
        solvers.push(SolverCertificate {
            solver,
            phi_rate,
            phi_prefactor,
            fits_eq11,
            per_window,
            at_k_min: k_min.map(|k| analysis.at(k)),
            analysis,
            k_min,
            void_reasons,
            k_min_with_sampled_l_phi: sampled_analysis.k_min(opts.k_max),
        });
    }
    Ok(ClosedLoopCertificate {
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
    })
}

/// Result of [`check_trajectory`] for one proposition.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InequalityCheck {
    /// The inequality held at every t.
    pub holds: bool,
    /// max over t ≥ 1 of lhs/rhs (≤ 1 when it holds; t = 0 is trivially tight for Prop. 1).
    pub worst_ratio: f64,
    /// Time of the worst ratio.
    pub worst_t: usize,
    /// First t where it failed, if any.
    pub first_violation: Option<usize>,
}

/// Prop. 1 and Prop. 3 evaluated on a trace.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrajectoryCheck {
    /// ‖ε_t‖ ≤ φᵗε₀ + γ₂,₁‖x‖ + γ₂,₃‖e‖ + γ₂ʷ‖w‖ + γ₂^σ‖σ‖ (sups over [0, t−1]).
    pub prop1: InequalityCheck,
    /// ‖e_t‖ ≤ C_e√ρᵗ‖e₀‖ + √(2Λ^H̄_P)C₁‖x‖ + C_ε‖ε‖ + C_w‖w‖ + √(2Λ^H̄_P)φL_Φ‖σ‖.
    pub prop3: InequalityCheck,
}

/// Evaluates the trajectory inequalities of Props. 1 and 3 at budget `k` with the constants
/// of `analysis` (from the certificate) on a trace recorded with the exact MHE solve on.
///
/// Returns `None` when the trace has no ε_t (exact solve off).
pub fn check_trajectory(
    cert: &ClosedLoopCertificate,
    analysis: &IssAnalysis,
    k: usize,
    trace: &Trace,
) -> Option<TrajectoryCheck> {
    let eps: Vec<f64> = trace.epsilons().collect::<Option<Vec<f64>>>()?;
    let g = analysis.at(k);
    let n = trace.len().min(eps.len());
    let (xs, es, ws) = (trace.x_norms(), trace.e_norms(), trace.w_norms());
    let sqrt_rho = analysis.rho.sqrt();
    let a = (2.0 * analysis.lambda_hp).sqrt();
    let mut p1 = InequalityCheck {
        holds: true,
        worst_ratio: 0.0,
        worst_t: 0,
        first_violation: None,
    };
    let mut p3 = p1.clone();
    let (mut sx, mut se, mut sw, mut seps, mut ssig) =
        (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    let tol = |r: f64| r.abs() * 1e-12 + 1e-14;
    let record = |c: &mut InequalityCheck, t: usize, lhs: f64, rhs: f64| {
        let ratio = if rhs > 0.0 {
            lhs / rhs
        } else if lhs > 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
        // t = 0 is an identity (rhs = ε₀ resp. ≥ ‖e₀‖): checked, but not a "worst ratio".
        if t > 0 && ratio > c.worst_ratio {
            c.worst_ratio = ratio;
            c.worst_t = t;
        }
        if lhs > rhs + tol(rhs) && c.first_violation.is_none() {
            c.holds = false;
            c.first_violation = Some(t);
        }
    };
    for t in 0..n {
        if t > 0 {
            sx = sx.max(xs[t - 1]);
            se = se.max(es[t - 1]);
            sw = sw.max(ws[t - 1]);
            seps = seps.max(eps[t - 1]);
            ssig = ssig.max(cert.sigma(t - 1));
        }
        let ti = i32::try_from(t).unwrap_or(i32::MAX);
        let rhs1 = g.phi.powi(ti) * eps[0]
            + g.gamma21 * sx
            + g.gamma23 * se
            + g.gamma2w * sw
            + g.gamma2sigma * ssig;
        record(&mut p1, t, eps[t], rhs1);
        let rhs3 = g.c_e * sqrt_rho.powi(ti) * es[0]
            + a * g.c1 * sx
            + g.c_eps * seps
            + g.c_w * sw
            + g.gamma3sigma * ssig;
        record(&mut p3, t, es[t], rhs3);
    }
    Some(TrajectoryCheck {
        prop1: p1,
        prop3: p3,
    })
}

/// The analysis with L_Φ replaced by the sampled estimate (for the "sampled L_Φ" check).
pub fn analysis_with_sampled_l_phi(
    cert: &ClosedLoopCertificate,
    solver: &SolverCertificate,
) -> IssAnalysis {
    IssAnalysis::new(IssInputs {
        l_phi: cert.l_phi.sampled,
        ..solver.analysis.inputs.clone()
    })
}
