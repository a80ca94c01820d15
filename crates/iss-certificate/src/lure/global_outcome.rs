//! The global loop certificate as one typed outcome per (scenario, method), budgeted
//! (docs/theory.md §4; issue 35): what `cargo xtask certify` prints and writes.
//!
//! [`GlobalLoop`]'s LMI depends on the method only through the weights D⁻¹ of the
//! norm in which φ(K) holds (plain or Jacobi), so φ* is searched once per norm and
//! K_glob = min{K : φ_method(K) ≤ φ*} per method. Where no φ ≥ 0 is certified the outcome
//! says what binds, from two cheap extra checks: the same loop with every box dropped at
//! φ = 0 (only the optimum's one-multiplier VI differs), and the spectral radius of that
//! exact-MHE linear loop (Theorem L3 (ii): ρ_lin ≥ 1 excludes every certificate).

use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario};
use faer::Par;
use qp_iter::Method;
use qp_iter::rounding::F32_UNIT_ROUNDOFF;

use super::global::{
    GlobalCertificate, GlobalLoop, GlobalOptions, LoopSize, PrecisionCertificate, PrecisionVoid,
    RefineGrid, certify_precision, global_loop, global_loop_with, loop_rounding, loop_size,
};
use crate::budget::DENSE_RATE;

/// The settings of [`global_outcomes`].
#[derive(Debug, Clone, Copy)]
pub struct GlobalSettings {
    /// The search's scalars (τ grid, φ tolerance, ρ, K scanned up to).
    pub search: GlobalOptions,
    /// Estimated single-core seconds the φ* searches may take (`certificate.phase_seconds`);
    /// beyond it nothing is searched ([`GlobalOutcome::NotComputed`]).
    pub phase_seconds: f64,
}

impl Default for GlobalSettings {
    /// 5 × 5 multipliers (the measured table of docs/theory.md §4) and the default phase
    /// budget.
    fn default() -> Self {
        Self {
            search: GlobalOptions {
                tau_points: 5,
                ..GlobalOptions::default()
            },
            phase_seconds: crate::budget::DEFAULT_PHASE_SECONDS,
        }
    }
}

/// The certified K of the global loop certificate for one method, with the checked numbers.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct GlobalK {
    /// K_glob: the smallest K with φ(K) ≤ φ* (every larger K is certified too).
    pub k_glob: usize,
    /// φ*: the largest certified φ found (bisection, relative tolerance `phi_tol`).
    pub phi_star: f64,
    /// φ(K_glob) of the method (min of eq. (11)'s φ and the inner-level rate).
    pub phi_at_k: f64,
    /// −λ_max(LMI)/Σ scale in the independent check (> the rounding allowance) of the
    /// reported certificate (the refined one where [`GlobalK::gains`] says so).
    pub margin: f64,
    /// ρ of the reported certificate: ‖X_{t+1}‖²_P ≤ ρ²‖X_t‖²_P + γ²‖w_t‖² for every K ≥
    /// K_glob.
    pub rho: f64,
    /// γ of the reported certificate.
    pub gamma: f64,
    /// lim sup ‖x_t‖ ≤ gain_x·w̄ for every K ≥ K_glob (w̄ = sup ‖w_t‖₂).
    pub gain_x: f64,
    /// lim sup ‖x_t − x̂_t‖ ≤ gain_e·w̄ for every K ≥ K_glob.
    pub gain_e: f64,
    /// Which certificate the ρ, γ, gains and margin above are.
    pub gains: Gains,
}

/// Which certificate [`GlobalK`]'s ρ, γ, gains and margin belong to (docs/theory.md §4, "The
/// reported gains"). Both are checked certificates of every K ≥ K_glob.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Gains {
    /// Refined at φ(K_glob) ([`GlobalLoop::refine_at`]): the storage chosen for the gain.
    Refined {
        /// gain_x of the certificate at φ* (ρ = ρ_max, the Riccati's minimal storage).
        gain_x_at_phi_star: f64,
    },
    /// The refinement's estimate exceeds the budget: the certificate at φ* (ρ = ρ_max; its
    /// gains are loose).
    NotComputed {
        /// The estimate (single-core seconds) of the norm's φ* search with the refinement.
        estimate_seconds: f64,
        /// The budget.
        budget_seconds: f64,
    },
}

/// The global loop certificate of one (scenario, method) pair: a certified K_glob, or why
/// none, with numbers.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GlobalOutcome {
    /// Every K ≥ K_glob is certified (Theorem L3).
    #[error(
        "K_glob = {} (φ* = {:.4e}, LMI margin {:.2e}; lim sup ‖x‖ ≤ {:.3e}·w̄, ‖x − x̂‖ ≤ \
         {:.3e}·w̄ at ρ = {:.4}{})",
        .0.k_glob,
        .0.phi_star,
        .0.margin,
        .0.gain_x,
        .0.gain_e,
        .0.rho,
        .0.gains
    )]
    Certified(GlobalK),
    /// φ* exists but the method's φ(K) stays above it up to `k_max`: the φ-ball on the
    /// iteration error binds.
    #[error(
        "no K ≤ {k_max}: the φ-ball binds (φ({k_max}) = {phi_at_k_max:.3e} > φ* = {phi_star:.3e})"
    )]
    PhiBallBinds {
        /// φ*.
        phi_star: f64,
        /// The largest K scanned.
        k_max: usize,
        /// φ(k_max) of the method.
        phi_at_k_max: f64,
    },
    /// Not even φ = 0 (the exact MHE) is certified with the scenario's boxes, while the same
    /// loop without boxes is: the optimum's one-multiplier VI (σ₁, σ₃ ≥ 0) binds.
    #[error(
        "none: even φ = 0 (exact MHE) is not certified with the boxes, but is without them \
         (margin {margin_without_boxes:.2e}): the optimum's one-multiplier VI binds"
    )]
    OptimumBinds {
        /// The check's margin of the box-free loop at φ = 0.
        margin_without_boxes: f64,
    },
    /// A has an eigenvalue with |λ| > 1 beyond rounding that only bounded inputs reach (every
    /// input of the controller's 𝒰 is bounded, or the unbounded ones leave that mode
    /// uncontrolled): the states a bounded input can steer back to 0 form a bounded set, so
    /// no loop is globally asymptotically stable and no global certificate exists at any K
    /// (the reason Theorem 1's Assumption 4 fails globally, `gamma13::Gamma13Void`). Decided
    /// before any LMI is built.
    #[error(
        "none: A has an eigenvalue with |λ| = {spectral_radius:.4} > 1 that only bounded \
         inputs reach{}: no global certificate can exist at any K (the states a bounded input \
         steers back to 0 form a bounded set); the regional certificate (K_reg) is the one \
         that can apply",
        if *.unbounded_inputs == 0 {
            " (every input in 𝒰 is bounded)".to_string()
        } else {
            format!(" (the {} unbounded input(s) do not reach it)", .unbounded_inputs)
        }
    )]
    UnstableWithBoundedInput {
        /// |λ| of that eigenvalue (A's spectral radius when every input is bounded).
        spectral_radius: f64,
        /// Inputs of 𝒰 with an infinite bound (0: every input bounded).
        unbounded_inputs: usize,
    },
    /// The exact-MHE linear loop (φ = 0, boxes dropped) has spectral radius ≥ 1: no
    /// quadratic certificate exists at any K (Theorem L3 (ii)).
    #[error("none: ρ_lin = {rho_lin:.6} ≥ 1 for the exact-MHE linear loop (Theorem L3 (ii))")]
    LinearUnstable {
        /// ρ of the exact-MHE linear loop.
        rho_lin: f64,
    },
    /// Not even the box-free loop at φ = 0 is certified although its ρ_lin < 1: the
    /// Riccati search or its check failed (e.g. Jacobi weights spanning decades).
    #[error(
        "none: even the box-free exact-MHE loop (ρ_lin = {rho_lin:.6} < 1) found no checked \
         storage with these multipliers (the search, not the loop, fails)"
    )]
    SearchFailed {
        /// ρ of the exact-MHE linear loop.
        rho_lin: f64,
    },
    /// The estimate of the φ* search exceeds the budget.
    #[error(
        "not computed within the budget: the φ* searches (n_ζ = {n_zeta}) are estimated at \
         {estimate_seconds:.1} s > {budget_seconds} s; raise certificate.phase_seconds \
         (certify: --global-seconds)"
    )]
    NotComputed {
        /// dim ζ of the LMI.
        n_zeta: usize,
        /// The estimate (single-core seconds) of every φ* search needed.
        estimate_seconds: f64,
        /// The budget.
        budget_seconds: f64,
    },
    /// The global certificate does not model this configuration (the reason names the key).
    #[error("not applicable: {reason}")]
    Unsupported {
        /// [`super::global::GlobalError`]'s sentence.
        reason: String,
    },
}

impl std::fmt::Display for Gains {
    /// The suffix of [`GlobalOutcome::Certified`]'s sentence.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Refined { .. } => write!(f, ", refined at φ(K_glob)"),
            Self::NotComputed {
                estimate_seconds,
                budget_seconds,
            } => write!(
                f,
                "; gains of the certificate at φ*: their refinement was not computed within the \
                 budget ({estimate_seconds:.1} s > {budget_seconds} s; raise \
                 certificate.phase_seconds)"
            ),
        }
    }
}

impl GlobalOutcome {
    /// The certified K_glob, if any.
    pub fn k_glob(&self) -> Option<usize> {
        match self {
            Self::Certified(k) => Some(k.k_glob),
            _ => None,
        }
    }

    /// Whether the budget stopped the search (not proved void).
    pub fn is_not_computed(&self) -> bool {
        matches!(self, Self::NotComputed { .. })
    }
}

/// The global loop certificate of one method in f32 (Theorem L3u, docs/theory.md "The global
/// loop certificate in a given precision"), with the checked numbers.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct PrecisionK {
    /// The unit round-off u of f32.
    pub unit_roundoff: f64,
    /// K_glob(u): every K ≥ it is certified in f32.
    pub k_glob: usize,
    /// φ*_u.
    pub phi_star: f64,
    /// The ISS offset o of the rounding's constant terms (lim sup bounds hold with √(w̄² + o²)).
    pub offset: f64,
    /// ρ of the checked certificate.
    pub rho: f64,
    /// γ of the checked certificate.
    pub gamma: f64,
    /// The LMI's margin in the independent check.
    pub margin: f64,
}

/// The global certificate of one method in f32: a K_glob(u), or why none.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PrecisionOutcome {
    /// Every K ≥ K_glob(u) is certified in f32.
    #[error(
        "f32: K_glob = {} (φ*_u = {:.4e}, ISS offset {:.3e}, LMI margin {:.2e})",
        .0.k_glob,
        .0.phi_star,
        .0.offset,
        .0.margin
    )]
    Certified(PrecisionK),
    /// The rounding model refuses, or the LMI with the rounding terms certifies no K.
    #[error("f32: {0}")]
    Void(PrecisionVoid),
    /// The exact-arithmetic loop has no K_glob: its outcome (f32 can only shrink it).
    #[error("f32: the exact loop has none ({0})")]
    NoExact(Box<GlobalOutcome>),
    /// The f32 search's estimate (with its norm's φ* search) exceeds the budget.
    #[error(
        "f32: not computed within the budget: the f32 search is estimated at \
         {estimate_seconds:.1} s > {budget_seconds} s; raise certificate.phase_seconds"
    )]
    NotComputed {
        /// The estimate (seconds) of the norm's searches with the f32 ones.
        estimate_seconds: f64,
        /// The budget.
        budget_seconds: f64,
    },
    /// The search failed to build (the reason names the key).
    #[error("f32: not applicable: {reason}")]
    Unsupported {
        /// Why.
        reason: String,
    },
    /// Not searched ([`global_outcomes`] computes f64 only).
    #[error("f32: not searched")]
    NotAsked,
}

impl PrecisionOutcome {
    /// The certified K_glob(u), if any.
    pub fn k_glob(&self) -> Option<usize> {
        match self {
            Self::Certified(k) => Some(k.k_glob),
            _ => None,
        }
    }

    /// Whether a budget stopped the search (here or in the exact loop's φ*).
    pub fn is_not_computed(&self) -> bool {
        match self {
            Self::NotComputed { .. } => true,
            Self::NoExact(e) => e.is_not_computed(),
            _ => false,
        }
    }
}

/// The global certificate of one method, in f64 and in f32.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct MethodGlobal {
    /// The MHE's method.
    pub method: Method,
    /// Exact arithmetic (f64: its rounding is below the check's margin, docs/theory.md).
    pub exact: GlobalOutcome,
    /// f32.
    pub f32: PrecisionOutcome,
    /// The iteration chain (Theorems L3b, L3c; f64 only) for PG, FISTA and their Jacobi
    /// variants; None for other methods.
    pub chain: Option<super::chain_outcome::ChainOutcome>,
}

/// The global loop certificate of a scenario: one entry per method, for the scenario's
/// controller (what [`crate::certificate::ClosedLoopCertificate::global`] holds).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct GlobalSection {
    /// The controller the loop was built with (the verdict uses the section only for it).
    pub controller: ControllerChoice,
    /// The budget the searches ran under.
    pub budget_seconds: f64,
    /// One entry per method.
    pub methods: Vec<MethodGlobal>,
}

impl MethodGlobal {
    /// Whether some K is certified in f64: a K_glob (Theorem L3) or a K the iteration chain
    /// certified (Theorem L3b).
    pub fn certifies_some_k(&self) -> bool {
        self.exact.k_glob().is_some() || self.chain.as_ref().is_some_and(|c| c.k_chain().is_some())
    }

    /// K_chain: the smallest K the iteration chain checked and certified (f64), if any.
    pub fn k_chain(&self) -> Option<usize> {
        self.chain.as_ref().and_then(|c| c.k_chain())
    }
}

impl GlobalSection {
    /// The entry of `method`.
    pub fn method(&self, method: Method) -> Option<&MethodGlobal> {
        self.methods.iter().find(|m| m.method == method)
    }
}

/// Estimated single-core seconds of one φ* search on a loop of dim ζ = `n_zeta`, dim X =
/// `n_x`, with `tau_calls` multiplier pairs per failed φ: per LMI call a doubling Riccati
/// (`RICCATI_FACTOR`·n_X³) and the independent check (`CHECK_FACTOR`·n_ζ³: forming the
/// LMI matrix and its eigenvalues, faer's above 16), and 2·(`tau_calls` + 1) calls. Measured
/// in release, idle (`global_outcome::calibrate_search_seconds`, docs/certificate-coverage.md):
/// the searches that find φ* took 0.16–0.21 s at n_ζ = 126 (estimate 0.45), 0.36–0.93 s at
/// n_ζ = 147 with an input bound (0.78) and 1.5–2.3 s at n_ζ = 235 (3.3); a search that
/// fails at φ = 0 stops after a few calls. [`global_section`] budgets each norm's search on
/// its own (they run on one thread each).
pub fn search_seconds(n_zeta: usize, n_x: usize, tau_calls: usize) -> f64 {
    let calls = 2.0 * (tau_calls as f64 + 1.0);
    calls * (riccati_seconds(n_x) + check_seconds(n_zeta))
}

/// The n_X³ factor of one doubling Riccati solve (≈ 25 doublings; measured: 108 solves at
/// n_X = 116 in ≈ 4 s of the refinement).
const RICCATI_FACTOR: f64 = 500.0;

/// The n_ζ³ factor of one independent check (the LMI matrix formed afresh, equilibrated, and
/// its eigenvalues).
const CHECK_FACTOR: f64 = 300.0;

/// Estimated seconds of one doubling Riccati solve at dim X = `n_x`.
fn riccati_seconds(n_x: usize) -> f64 {
    RICCATI_FACTOR * (n_x as f64).powi(3) / DENSE_RATE
}

/// Estimated seconds of one independent check of the LMI at dim ζ = `n_zeta`.
fn check_seconds(n_zeta: usize) -> f64 {
    CHECK_FACTOR * (n_zeta as f64).powi(3) / DENSE_RATE
}

/// The global outcome of every loop in `options` (one per method) on `resolved`, in order:
/// [`global_section`]'s exact outcomes, without the f32 searches.
pub fn global_outcomes(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    settings: &GlobalSettings,
) -> Vec<GlobalOutcome> {
    searches(resolved, options, settings, false)
        .into_iter()
        .map(|(exact, _)| exact)
        .collect()
}

/// The global certificate of every method in `methods` on `resolved`, in f64 (Theorem L3)
/// and in f32 (Theorem L3u), for the scenario's own controller and warm start: what
/// [`crate::certificate::certify_closed_loop`] stores when `global_seconds` is set, and the
/// one source of K_glob for the verdict ([`crate::coverage::verdict`]) and `certify --loop`.
/// None when the scenario has no loop (no `[mhe]`).
pub fn global_section(
    resolved: &ResolvedScenario,
    methods: &[Method],
    settings: &GlobalSettings,
) -> Option<GlobalSection> {
    let base = LoopOptions::from_scenario(resolved.scenario()).ok()?;
    let options: Vec<LoopOptions> = methods
        .iter()
        .map(|&m| LoopOptions { method: m, ..base })
        .collect();
    let out = searches(resolved, &options, settings, true);
    // Each method's chain gets half a phase (pg with pg-jacobi take one phase, fista with
    // fista-jacobi another; they run side by side, so a thread's work stays within a phase).
    let chain_s = settings.phase_seconds / 2.0;
    let chains = super::chain_outcome::chains(resolved, &options, &out, chain_s);
    Some(GlobalSection {
        controller: base.controller,
        budget_seconds: settings.phase_seconds,
        methods: methods
            .iter()
            .zip(out)
            .zip(chains)
            .map(|((&method, (exact, f32)), chain)| MethodGlobal {
                method,
                exact,
                f32,
                chain,
            })
            .collect(),
    })
}

/// One loop's plan: its size (or why none), and its f32 outcome where it is known without a
/// search.
struct Planned {
    size: Result<LoopSize, GlobalOutcome>,
    /// The f32 outcome known without a search (void, unsupported, not asked), or None: search.
    f32: Option<PrecisionOutcome>,
}

/// Each loop's size (estimated before anything is built, [`loop_size`]), the loops grouped by
/// norm (one φ* search per distinct D⁻¹; each group's first loop is the one searched), and
/// each f32 outcome known without a search.
fn plan_loops(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    with_f32: bool,
) -> (Vec<Planned>, Vec<Vec<usize>>) {
    let unsupported = |e: super::global::GlobalError| GlobalOutcome::Unsupported {
        reason: e.to_string(),
    };
    let impossible = super::no_global::no_global_certificate(resolved);
    let mut plan: Vec<Planned> = options
        .iter()
        .map(|o| Planned {
            size: match &impossible {
                Some(why) => Err(why.clone()),
                None => loop_size(resolved, o).map_err(unsupported),
            },
            f32: None,
        })
        .collect();
    let mut norms: Vec<Vec<usize>> = Vec::new();
    for i in 0..plan.len() {
        let Ok(z) = &plan[i].size else { continue };
        let same = |g: &&mut Vec<usize>| plan[g[0]].size.as_ref().is_ok_and(|h| h.d_inv == z.d_inv);
        match norms.iter_mut().find(same) {
            Some(g) => g.push(i),
            None => norms.push(vec![i]),
        }
    }
    for (p, o) in plan.iter_mut().zip(options) {
        p.f32 = Some(match (&p.size, with_f32) {
            (Err(e), _) => PrecisionOutcome::NoExact(Box::new(e.clone())),
            (Ok(_), false) => PrecisionOutcome::NotAsked,
            (Ok(_), true) => match loop_rounding(resolved, o, F32_UNIT_ROUNDOFF) {
                Ok(Ok(_)) => continue,
                Ok(Err(why)) => PrecisionOutcome::Void(why),
                Err(e) => PrecisionOutcome::Unsupported {
                    reason: e.to_string(),
                },
            },
        });
    }
    (plan, norms)
}

/// The searches of [`global_section`] (`with_f32`: also the f32 certificates): one thread
/// per norm (φ*, the refined gains, then the f32 searches of that norm's methods), each norm's
/// search, each refinement and each f32 search budgeted by its own estimate against
/// `settings.phase_seconds` (the threads run side by side, so the budget bounds each thread's
/// work), estimated from the sizes before any loop is built. Deterministic: no result depends
/// on the threads' order, nor on the other methods asked.
fn searches(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    settings: &GlobalSettings,
    with_f32: bool,
) -> Vec<(GlobalOutcome, PrecisionOutcome)> {
    let (plan, norms) = plan_loops(resolved, options, with_f32);
    let plan = &plan;
    let results: Vec<Vec<NormEntry>> = std::thread::scope(|s| {
        let handles: Vec<_> = norms
            .iter()
            .map(|members| s.spawn(move || run_norm(resolved, options, plan, members, settings)))
            .collect();
        handles
            .into_iter()
            .zip(&norms)
            .map(|(h, members)| {
                h.join().unwrap_or_else(|_| {
                    let why = GlobalOutcome::Unsupported {
                        reason: "internal: the search thread panicked".into(),
                    };
                    let f32 = PrecisionOutcome::NoExact(Box::new(why.clone()));
                    members
                        .iter()
                        .map(|&j| (j, why.clone(), f32.clone()))
                        .collect()
                })
            })
            .collect()
    });
    let mut out: Vec<Option<(GlobalOutcome, PrecisionOutcome)>> = vec![None; plan.len()];
    for (j, exact, f32) in results.into_iter().flatten() {
        out[j] = Some((exact, f32));
    }
    out.into_iter()
        .zip(plan)
        .map(|(found, p)| {
            found.unwrap_or_else(|| {
                let exact = match &p.size {
                    Err(e) => e.clone(),
                    Ok(_) => GlobalOutcome::Unsupported {
                        reason: "internal: a loop without a norm".into(),
                    },
                };
                let f32 = p.f32.clone().unwrap_or(PrecisionOutcome::NotAsked);
                (exact, f32)
            })
        })
        .collect()
}

/// One method's outcomes: its index in the options, exact, f32.
type NormEntry = (usize, GlobalOutcome, PrecisionOutcome);

/// One norm's work: within the budget, build its methods' loops, search φ* on the first,
/// then each method's K_glob with its refined gains and its f32 certificate.
fn run_norm(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    plan: &[Planned],
    members: &[usize],
    settings: &GlobalSettings,
) -> Vec<NormEntry> {
    let budget = settings.phase_seconds;
    let Some(Ok(size)) = members.first().map(|&i| &plan[i].size) else {
        return Vec::new();
    };
    let exact_s = search_seconds(size.n_zeta, size.n_x, tau_calls(size, &settings.search));
    let f32_of = |j: usize, why: &GlobalOutcome| {
        plan[j]
            .f32
            .clone()
            .unwrap_or_else(|| PrecisionOutcome::NoExact(Box::new(why.clone())))
    };
    if exact_s > budget {
        let why = GlobalOutcome::NotComputed {
            n_zeta: size.n_zeta,
            estimate_seconds: exact_s,
            budget_seconds: budget,
        };
        return members
            .iter()
            .map(|&j| (j, why.clone(), f32_of(j, &why)))
            .collect();
    }
    let loops: Vec<(usize, Result<GlobalLoop, GlobalOutcome>)> = members
        .iter()
        .map(|&j| {
            let gl = global_loop(resolved, &options[j]).map_err(|e| GlobalOutcome::Unsupported {
                reason: e.to_string(),
            });
            (j, gl)
        })
        .collect();
    let Some((i, g)) = loops
        .iter()
        .find_map(|(j, g)| g.as_ref().ok().map(|g| (*j, g)))
    else {
        return loops
            .into_iter()
            .map(|(j, g)| {
                let why = g.err().unwrap_or_else(|| GlobalOutcome::Unsupported {
                    reason: "internal: no loop".into(),
                });
                let f32 = f32_of(j, &why);
                (j, why, f32)
            })
            .collect();
    };
    let star = phi_star_or_why(resolved, &options[i], g, &settings.search);
    let refine_s = exact_s + refine_seconds(size.n_zeta, size.n_x);
    loops
        .iter()
        .map(|(j, gj)| {
            let exact = match (gj, &star) {
                (Err(e), _) => e.clone(),
                (Ok(_), Err(why)) => why.clone(),
                (Ok(gj), Ok(star)) => k_glob_of(gj, star, refine_s <= budget, settings, refine_s),
            };
            let f32 = match (&plan[*j].f32, gj, &star) {
                (Some(known), _, _) => known.clone(),
                (None, Err(e), _) => PrecisionOutcome::NoExact(Box::new(e.clone())),
                (None, Ok(_), Err(why)) => PrecisionOutcome::NoExact(Box::new(why.clone())),
                (None, Ok(gj), Ok(star)) => {
                    f32_search(resolved, &options[*j], gj, star, settings, exact_s)
                }
            };
            (*j, exact, f32)
        })
        .collect()
}

/// One method's f32 outcome within the budget (the norm's search took `exact_s`).
fn f32_search(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    gj: &GlobalLoop,
    cert: &GlobalCertificate,
    settings: &GlobalSettings,
    exact_s: f64,
) -> PrecisionOutcome {
    let [first, full] = precision_seconds(gj.n_zeta(), gj.n_x());
    if exact_s + first > settings.phase_seconds {
        return PrecisionOutcome::NotComputed {
            estimate_seconds: exact_s + first,
            budget_seconds: settings.phase_seconds,
        };
    }
    let within = exact_s + full <= settings.phase_seconds;
    match precision_outcome(resolved, options, gj, cert, settings, within) {
        Some(out) => out,
        None => PrecisionOutcome::NotComputed {
            estimate_seconds: exact_s + full,
            budget_seconds: settings.phase_seconds,
        },
    }
}

/// The f32 certificate (Theorem L3u) of one method from its norm's exact certificate, in two
/// stages: first φ*_u = φ* only (the bisection's tolerance set to 1, so none runs) — where it
/// certifies, its K_glob(u) is the full search's, which tries φ* first; else the full search
/// with its bisection when `bisect_within` (its estimate fits the budget), else None: not
/// computed.
fn precision_outcome(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    g: &GlobalLoop,
    exact: &GlobalCertificate,
    settings: &GlobalSettings,
    bisect_within: bool,
) -> Option<PrecisionOutcome> {
    let u = F32_UNIT_ROUNDOFF;
    let first = GlobalOptions {
        phi_tol: 1.0,
        ..settings.search
    };
    match certify_precision(resolved, options, g, Some(exact), u, &first) {
        // Certified at φ*_u = φ* (or K beyond k_max there), or refused before the bisection
        // (no rounding model, broken contraction, infeasible at φ_u = 0 for every split): the
        // full search runs the same calls first, so this is final. A certificate at a smaller
        // φ*_u is not: with the bisection skipped it is φ*_u = 0, whose K is where φ_u(K)
        // underflows (240 637 on the double integrator, where the full search gives 664).
        Ok(p) if p.phi_star.is_none() || p.phi_star == Some(exact.phi) => {
            return Some(precision_of(&p));
        }
        Ok(_) => {}
        Err(e) => {
            return Some(PrecisionOutcome::Unsupported {
                reason: e.to_string(),
            });
        }
    }
    if !bisect_within {
        return None;
    }
    Some(
        match certify_precision(resolved, options, g, Some(exact), u, &settings.search) {
            Ok(p) => precision_of(&p),
            Err(e) => PrecisionOutcome::Unsupported {
                reason: e.to_string(),
            },
        },
    )
}

/// The outcome of a finished f32 search.
fn precision_of(p: &PrecisionCertificate) -> PrecisionOutcome {
    match (p.k_glob, p.phi_star, p.certificate.as_ref()) {
        (Some(k_glob), Some(phi_star), Some(c)) => PrecisionOutcome::Certified(PrecisionK {
            unit_roundoff: p.unit_roundoff,
            k_glob,
            phi_star,
            offset: p.offset(),
            rho: c.rho,
            gamma: c.gamma,
            margin: c.margin,
        }),
        _ => PrecisionOutcome::Void(p.reason.clone().unwrap_or(PrecisionVoid::Exact)),
    }
}

/// Estimated seconds of one method's f32 search ([`certify_precision`]): [first stage (the
/// splits at φ*, ≈ 8 LMI calls; one succeeds at once on the case study), full search (six
/// splits × a bisection to 2 %: ≈ 60 calls)] — the per-call cost of [`search_seconds`].
pub fn precision_seconds(n_zeta: usize, n_x: usize) -> [f64; 2] {
    [
        search_seconds(n_zeta, n_x, 3),
        search_seconds(n_zeta, n_x, 29),
    ]
}

/// Multiplier pairs tried per φ, as measured: the τ₁ grid, plus one for the τ₃ channel of an
/// input bound (the grid over τ₃ stops at its first success, so a τ₁ × τ₃ product is far
/// too pessimistic: the case study, with an input bound, measured ≈ 4 s of CPU per norm in
/// release against 20 s estimated as a product; docs/certificate-coverage.md).
fn tau_calls(size: &LoopSize, opts: &GlobalOptions) -> usize {
    let k = opts.tau_points.max(2);
    k + usize::from(size.mpc_channel)
}

/// Estimated seconds of one method's gain refinement ([`GlobalLoop::refine_at`] with the
/// default [`RefineGrid`]: 9 ρ × 3 strictness × 4 readout weights = 108 Riccati doublings
/// screened, then at most 5 candidates re-solved and checked), at [`search_seconds`]'s
/// per-call costs: 5.4 s at the certified case study's n_ζ = 235, n_X = 116 (measured
/// 4.4–5.4 s per norm), 1.0 s at the double integrator's (measured 1.0–1.1 s).
pub fn refine_seconds(n_zeta: usize, n_x: usize) -> f64 {
    let g = RefineGrid::default();
    let screened = (g.rho_points * g.strict.len() * g.readout.len()) as f64;
    let checks = g.checks as f64;
    (screened + checks) * riccati_seconds(n_x) + checks * check_seconds(n_zeta)
}

/// φ* of `g`'s norm with its checked certificate (the method's K_glob and gains are read from
/// it per method, [`k_glob_of`]), or what binds.
fn phi_star_or_why(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    g: &GlobalLoop,
    opts: &GlobalOptions,
) -> Result<GlobalCertificate, GlobalOutcome> {
    if let Some(c) = g.phi_star(opts) {
        return Ok(c);
    }
    let free =
        global_loop_with(resolved, options, false).map_err(|e| GlobalOutcome::Unsupported {
            reason: e.to_string(),
        })?;
    if let Some(c) = free.certify_phi(0.0, opts) {
        return Err(GlobalOutcome::OptimumBinds {
            margin_without_boxes: c.margin,
        });
    }
    let n = free.n_x();
    let a = free.x_plus_map().subcols(0, n).to_owned();
    match crate::linear::spectral_radius(a.as_ref(), Par::Seq) {
        Ok(rho_lin) if rho_lin >= 1.0 => Err(GlobalOutcome::LinearUnstable { rho_lin }),
        Ok(rho_lin) => Err(GlobalOutcome::SearchFailed { rho_lin }),
        Err(e) => Err(GlobalOutcome::Unsupported {
            reason: e.to_string(),
        }),
    }
}

/// K_glob of `g`'s method from its norm's certificate at φ* (`star`), with the gains of the
/// certificate refined at φ(K_glob) when `refine` (within the budget), else those at φ* with
/// [`Gains::NotComputed`] (`refine_s`: the estimate that did not fit).
fn k_glob_of(
    g: &GlobalLoop,
    star: &GlobalCertificate,
    refine: bool,
    settings: &GlobalSettings,
    refine_s: f64,
) -> GlobalOutcome {
    let k_max = settings.search.k_max;
    let Some(k) = super::first_k(|k| g.phi(k) <= star.phi, k_max) else {
        return GlobalOutcome::PhiBallBinds {
            phi_star: star.phi,
            k_max,
            phi_at_k_max: g.phi(k_max),
        };
    };
    let phi_at_k = g.phi(k);
    let (c, gains) = if refine {
        let gains = Gains::Refined {
            gain_x_at_phi_star: star.gain_x,
        };
        (g.refine_at(phi_at_k, star), gains)
    } else {
        let gains = Gains::NotComputed {
            estimate_seconds: refine_s,
            budget_seconds: settings.phase_seconds,
        };
        (star.clone(), gains)
    };
    GlobalOutcome::Certified(GlobalK {
        k_glob: k,
        phi_star: star.phi,
        phi_at_k,
        margin: c.margin,
        rho: c.rho,
        gamma: c.gamma,
        gain_x: c.gain_x,
        gain_e: c.gain_e,
        gains,
    })
}
