//! The certificate's side of a sweep point: Theorem 1 per solver (from the closed-loop
//! certificate of the scenario), evaluated at each K as the theoretical columns of
//! `points.csv` (φ(K), the slopes of (sg1)–(sg3), the margin, certified, K_min), and the
//! exact linear stability boundary beside it (ρ_lin(K) and K_lin of `iss_certificate::linear` on the
//! sweep's own K grid).

use closed_loop::scenario::{LoopOptions, ResolvedScenario, Scenario};
use iss_certificate::linear::{LinearReport, linear_stability};

use super::format::csv_text;
use super::region::Staircase;
use super::{ControllerChoice, Method};
use iss_certificate::analysis::IssAnalysis;
use iss_certificate::certificate::{
    CertificateOptions, ClosedLoopCertificate, certify_closed_loop,
};
use iss_certificate::coverage::{Applicable, Scalar, covering, theorem1_at, with_global};

/// The certificate's side of a point: Theorem 1 for one solver.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub enum SolverTheory {
    /// An analysis (void when a premise fails: then `void_reasons` says which).
    Analysis {
        /// Theorem 1's constants for this solver.
        analysis: Box<IssAnalysis>,
        /// Smallest certified K (None when void or beyond the search range).
        k_min: Option<usize>,
        /// Why the certificate is void, whatever K (empty when the premises hold).
        void_reasons: Vec<iss_certificate::outcome::VoidReason>,
        /// The analysis budget cut the verdict (None: computed).
        not_computed: Option<iss_certificate::budget::NotComputed>,
        /// The global loop certificate the verdict combines with Theorem 1's
        /// ([`iss_certificate::coverage::with_global`]).
        global: Option<Box<iss_certificate::lure::global_outcome::MethodGlobal>>,
    },
    /// The joint certificate of the MHE solver with the K_c-iteration MPC
    /// ([`iss_certificate::coverage::Applicable::Joint`]): the verdict at (K_e, K_c).
    Joint(Box<Applicable>),
    /// No analysis available (the reason is written in the `void_reason` column).
    Unavailable(String),
}

impl SolverTheory {
    /// The theoretical columns at (K_e, K_c): [`SolverTheory::at`] for Theorem 1 (the exact
    /// MPC: `k_c` is ignored), the joint certificate's verdict at the pair otherwise
    /// ([`Applicable::at`]; φ is φ_e(K_e), the margin 1 − ρ(Γ), K_min the smallest certified
    /// K_e at this K_c; no slopes).
    pub fn at_pair(&self, k: usize, k_c: Option<usize>) -> TheoryAtK {
        let SolverTheory::Joint(app) = self else {
            return self.at(k);
        };
        let v = app.at(k, k_c);
        let phi = match app.as_ref() {
            Applicable::Joint { analysis, .. } => Some(analysis.theorem1.at(k).phi),
            _ => None,
        };
        TheoryAtK {
            phi,
            slopes: None,
            margin: v.margin,
            certified: v.certified.as_str(),
            k_min: v.k_min,
            void_reason: csv_text(&v.reason_text()),
            ..TheoryAtK::default()
        }
    }

    /// The theoretical columns at K: slopes of (sg1)–(sg3), the margin 1 − (sg1 + sg2 + sg3),
    /// `certified` = `"yes"`, `"no"`, `"void"` (a premise of Theorem 1 fails, whatever K) or
    /// `"not_computed"` (a budget, or the iteration chain not checked at K), K_min and the reason.
    /// The linear columns (ρ_lin, K_lin) are left empty here; [`LinearSide::fill`] adds them.
    pub fn at(&self, k: usize) -> TheoryAtK {
        match self {
            SolverTheory::Analysis {
                analysis,
                k_min,
                void_reasons,
                not_computed,
                global,
            } => {
                let g = analysis.at(k);
                // The verdict is the one rule of `iss_certificate::coverage`.
                let v = with_global(
                    theorem1_at(analysis, *k_min, void_reasons, not_computed.as_ref(), k),
                    global.as_deref(),
                    k,
                    Scalar::F64,
                );
                // Props. 1 and 3 divide by 1 − φ(K): for φ(K) ≥ 1 the gains, slopes and
                // margin are undefined (written empty), not large.
                let defined = g.phi < 1.0 && g.phi.is_finite();
                TheoryAtK {
                    phi: Some(g.phi),
                    slopes: defined.then_some([g.sg1, g.sg2, g.sg3]),
                    margin: defined.then_some(g.margin),
                    certified: v.certified.as_str(),
                    k_min: v.k_min.or(*k_min),
                    void_reason: csv_text(&v.reason_text()),
                    ..TheoryAtK::default()
                }
            }
            SolverTheory::Joint(_) => {
                self.at_pair(k, None) // no K_c: void, "the joint certificate needs K_c"
            }
            SolverTheory::Unavailable(reason) => TheoryAtK {
                phi: None,
                slopes: None,
                margin: None,
                certified: "void",
                k_min: None,
                void_reason: csv_text(reason),
                ..TheoryAtK::default()
            },
        }
    }
}

/// The theoretical columns of a point.
#[derive(Debug, Clone, PartialEq, Default)]
#[non_exhaustive]
pub struct TheoryAtK {
    /// φ(K) of Assumption 5 (the solver's certified contraction after K iterations).
    pub phi: Option<f64>,
    /// Slopes of (sg1), (sg2), (sg3) at K (None where φ(K) ≥ 1: undefined).
    pub slopes: Option<[f64; 3]>,
    /// Certified ISS margin 1 − (sg1 + sg2 + sg3) (> 0 iff ρ(Γ) < 1).
    pub margin: Option<f64>,
    /// `"yes"`, `"no"`, `"void"` or `"not_computed"`.
    pub certified: &'static str,
    /// Smallest certified K of this solver.
    pub k_min: Option<usize>,
    /// Why the certificate is void (empty otherwise).
    pub void_reason: String,
    /// ρ_lin(K): spectral radius of the lifted loop 𝔸(K) (None when the linear analysis
    /// is not available: then `linear_note` says why).
    pub rho_lin: Option<f64>,
    /// K_lin on the sweep's K grid for this solver (None: ρ_lin ≥ 1 at the largest K, or
    /// no analysis).
    pub k_lin: Option<usize>,
    /// Why ρ_lin is missing (empty otherwise).
    pub linear_note: String,
    /// K_reg of this solver at this point's disturbance scale: the smallest K whose
    /// regional certificate contains the scenario's uncertainty (`iss_certificate::regional`;
    /// None: `regional_note` says why).
    pub k_reg: Option<usize>,
    /// Why K_reg is missing (empty otherwise).
    pub regional_note: String,
}

/// ρ_lin of one MHE solver with one controller: the report on the K grid, or why not.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct LinearEntry {
    /// Φ of the MHE.
    pub solver: Method,
    /// K_c of the sub-optimal MPC in a 2-D sweep (None: the sweep's one controller).
    pub k_c: Option<usize>,
    /// ρ_lin on the K grid and K_lin, or why the analysis is not available.
    pub report: Result<LinearReport, String>,
}

/// The linear side of a sweep: per solver (and per K_c in a 2-D sweep) ρ_lin on the K grid,
/// or why not.
#[derive(Debug, Clone)]
pub struct LinearSide(pub Vec<LinearEntry>);

impl LinearSide {
    /// Adds ρ_lin(K), K_lin (or the reason they are missing) of `solver` (at `k_c` in a 2-D
    /// sweep: ρ_lin(K_e, K_c), and K_lin on the K_e grid at that K_c) to `theory`.
    pub fn fill(&self, solver: Method, k_c: Option<usize>, k: usize, theory: &mut TheoryAtK) {
        match self
            .0
            .iter()
            .find(|e| e.solver == solver && e.k_c == k_c)
            .map(|e| &e.report)
        {
            Some(Ok(report)) => {
                theory.rho_lin = report
                    .rho_lin
                    .iter()
                    .find(|(kk, _)| *kk == k)
                    .map(|&(_, rho)| rho);
                theory.k_lin = report.k_lin;
                if theory.rho_lin.is_none() {
                    theory.linear_note = format!("K = {k} is not on the analysed grid");
                }
            }
            Some(Err(reason)) => theory.linear_note = csv_text(reason),
            None => theory.linear_note = "no linear analysis for this solver".into(),
        }
    }
}

/// ρ_lin(K) of the lifted loop (`iss_certificate::linear`) for each solver and each controller of
/// `controllers` (`(None, c)`: the sweep's one controller; `(Some(K_c), c)`: the sub-optimal
/// MPC at K_c in a 2-D sweep) on `grid(solver)` (the K of its points). An analysis that
/// cannot be done (a bound of Z through the origin, a failed eigenvalue solve) is kept as
/// its reason, per entry.
pub fn solver_linear(
    resolved: &ResolvedScenario,
    solvers: &[Method],
    controllers: &[(Option<usize>, ControllerChoice)],
    grid: impl Fn(Method) -> Vec<usize>,
) -> LinearSide {
    let mut out = Vec::new();
    for &s in solvers {
        let k_grid = grid(s);
        for &(k_c, controller) in controllers {
            // K, seed and T do not enter 𝔸(K)'s construction (`linear_stability`).
            let opts = LoopOptions {
                method: s,
                iterations: qp_iter::Iterations::ONE,
                exact_mhe_solve: false,
                controller,
                seed: 0,
                steps: 1,
            };
            let report = linear_stability(resolved, &opts, &k_grid, faer::Par::Seq)
                .map_err(|e| format!("no linear analysis: {e}"));
            out.push(LinearEntry {
                solver: s,
                k_c,
                report,
            });
        }
    }
    LinearSide(out)
}

/// The joint certificate's region of (K_e, K_c) ([`iss_certificate::joint`]) for the MHE solver
/// `solver` and the sweep's sub-optimal MPC `controller` (its `method`; its `iterations` is
/// irrelevant), as a staircase: for each K_e of `k_e_grid`, ascending, the smallest certified
/// K_c (searched up to 2²⁴, so it may lie beyond the sweep's K_c grid), or None when no K_c
/// is certified at that K_e. The heat maps draw it and the 2-D thresholds take its cheapest
/// pair ([`super::pair_thresholds`]).
///
/// Empty means *not computed*: another controller, or a certificate that cannot be computed
/// (the heat maps then say "certificate: not computed"). A void certificate gives None at
/// every K_e.
pub fn certified_boundary(
    resolved: &ResolvedScenario,
    solver: Method,
    controller: ControllerChoice,
    k_e_grid: &[usize],
) -> Staircase {
    if !matches!(controller, ControllerChoice::SuboptimalMpc { .. }) {
        return Vec::new();
    }
    match solver_theory(resolved, &[solver], controller).pop() {
        Some((_, theory)) => joint_staircase(&theory, k_e_grid),
        None => Vec::new(),
    }
}

/// The staircase of a solver's joint certificate on `k_e_grid` (empty: not the joint
/// certificate, or uncovered; None at every K_e: void). The same analysis as the points'
/// `certified` column ([`SolverTheory::at_pair`]), so the two cannot disagree.
pub fn joint_staircase(theory: &SolverTheory, k_e_grid: &[usize]) -> Staircase {
    match theory {
        SolverTheory::Joint(app) => match app.as_ref() {
            Applicable::Joint {
                analysis,
                k_max,
                void_reasons,
            } => {
                if void_reasons.is_empty() {
                    analysis.boundary(k_e_grid, *k_max)
                } else {
                    k_e_grid.iter().map(|&k| (k, None)).collect()
                }
            }
            _ => Vec::new(),
        },
        _ => Vec::new(),
    }
}

/// The certificate covering each solver of the sweep with `controller`
/// ([`iss_certificate::coverage`]): Theorem 1 for the exact MPC, the joint certificate for the
/// K_c-iteration MPC, void with the reason otherwise (a shifted warm start, the saturated
/// LQR). Computed from the closed-loop certificate of the scenario
/// ([`certify_closed_loop`]; its sampled L_Φ, L_π and γ₁,₃ estimates are skipped, the
/// certified values are what enter the gains). A certificate that cannot be computed makes
/// the columns void with the error as the reason (the empirical side is still useful).
pub fn solver_theory(
    resolved: &ResolvedScenario,
    solvers: &[Method],
    controller: ControllerChoice,
) -> Vec<(Method, SolverTheory)> {
    let unavailable = |reason: String| {
        solvers
            .iter()
            .map(|&s| (s, SolverTheory::Unavailable(reason.clone())))
            .collect()
    };
    if let Some(&first) = solvers.first() {
        if let Some(reason) = covering(resolved.scenario(), first, controller).uncovered_reason() {
            return unavailable(reason.to_string());
        }
    }
    match certify_closed_loop(resolved, &certificate_options(resolved.scenario(), solvers)) {
        Err(e) => unavailable(format!("no certificate: {e}")),
        Ok(cert) => solvers
            .iter()
            .map(|&s| (s, theory_of(resolved, &cert, s, controller)))
            .collect(),
    }
}

/// The certificate options of a sweep: every command's
/// ([`iss_certificate::coverage::verdict_options`]: the scenario's user γ₁,₃ with the sample
/// that can refute it, its budget), so the `certified` column is `reproduce`'s verdict; the
/// other sampled estimates are skipped.
pub(super) fn certificate_options(scenario: &Scenario, solvers: &[Method]) -> CertificateOptions {
    iss_certificate::coverage::verdict_options(scenario, solvers.to_vec(), None)
}

/// The certificate covering `solver` with `controller`, from the scenario's certificate
/// ([`Applicable::new`]: Theorem 1, the joint certificate, or uncovered).
pub(super) fn theory_of(
    resolved: &ResolvedScenario,
    cert: &ClosedLoopCertificate,
    solver: Method,
    controller: ControllerChoice,
) -> SolverTheory {
    match Applicable::new(resolved, cert, solver, controller) {
        Applicable::Theorem1 {
            analysis,
            k_min,
            void_reasons,
            not_computed,
            global,
        } => SolverTheory::Analysis {
            analysis,
            k_min,
            void_reasons,
            not_computed,
            global,
        },
        Applicable::Uncovered(r) => SolverTheory::Unavailable(r.to_string()),
        // The joint certificate, or one this crate does not know: its verdicts come from
        // `Applicable::at`, the library's rule, never from a default here.
        other => SolverTheory::Joint(Box::new(other)),
    }
}
