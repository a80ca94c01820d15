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
    GlobalCertificate, GlobalLoop, GlobalOptions, PrecisionCertificate, PrecisionVoid,
    certify_precision, global_loop, global_loop_with, loop_rounding,
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
    /// −λ_max(LMI)/Σ scale in the independent check (> the rounding allowance).
    pub margin: f64,
    /// ρ of the certificate: ‖X_{t+1}‖²_P ≤ ρ²‖X_t‖²_P + γ²‖w_t‖².
    pub rho: f64,
    /// γ of the certificate.
    pub gamma: f64,
    /// lim sup ‖x_t‖ ≤ gain_x·w̄ (loose: P is the Riccati's minimal storage at ρ).
    pub gain_x: f64,
    /// lim sup ‖x_t − x̂_t‖ ≤ gain_e·w̄.
    pub gain_e: f64,
}

/// The global loop certificate of one (scenario, method) pair: a certified K_glob, or why
/// none, with numbers.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GlobalOutcome {
    /// Every K ≥ K_glob is certified (Theorem L3).
    #[error(
        "K_glob = {} (φ* = {:.4e}, LMI margin {:.2e})",
        .0.k_glob,
        .0.phi_star,
        .0.margin
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
    /// The iteration chain (Theorem L3b, f64 only) for the PG family; None for other methods.
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
}

impl GlobalSection {
    /// The entry of `method`.
    pub fn method(&self, method: Method) -> Option<&MethodGlobal> {
        self.methods.iter().find(|m| m.method == method)
    }
}

/// Estimated single-core seconds of one φ* search on a loop of dim ζ = `n_zeta`, dim X =
/// `n_x`, with `tau_calls` multiplier pairs per failed φ: a doubling Riccati (≈ 25 doublings
/// of ≈ 8·n_X³) and two Jacobi eigenvalue checks (scalar loops, ≈ 120·n_ζ³ at 1/20 of the
/// dense rate) per call, and 2·(`tau_calls` + 1) calls — calibrated on the double
/// integrator (n_ζ = 126: 4.6 s of CPU for both norms and the rest of `certify --loop`,
/// estimate 5.8 s) and the case study (n_ζ = 147, an input bound: 8.5 s of CPU for both
/// norms and the f32 search of PG, estimate 5.4 s per norm with the `tau_calls` of
/// [`global_section`]; docs/certificate-coverage.md). [`global_section`] budgets each norm's
/// search on its own (they run on one thread each).
pub fn search_seconds(n_zeta: usize, n_x: usize, tau_calls: usize) -> f64 {
    let (nz, nx) = (n_zeta as f64, n_x as f64);
    let per_call = 25.0 * 8.0 * nx.powi(3) + 20.0 * 120.0 * nz.powi(3);
    let calls = 2.0 * (tau_calls as f64 + 1.0);
    calls * per_call / DENSE_RATE
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
    // The two chains (pg, pg-jacobi) share one phase: half of it each.
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

/// One loop's pieces for the searches: the loop (or why none), its norm, its f32 rounding.
struct Planned {
    gl: Result<GlobalLoop, GlobalOutcome>,
    norm: Option<usize>,
    /// The f32 outcome known without a search (void, unsupported, not asked), or None: search.
    f32: Option<PrecisionOutcome>,
}

/// Each loop, its norm (`norms` holds the first loop of each distinct D⁻¹: one φ* search per
/// norm) and its f32 outcome where it is known without a search.
fn plan_loops(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    with_f32: bool,
) -> (Vec<Planned>, Vec<usize>) {
    let mut plan: Vec<Planned> = options
        .iter()
        .map(|o| Planned {
            gl: global_loop(resolved, o).map_err(|e| GlobalOutcome::Unsupported {
                reason: e.to_string(),
            }),
            norm: None,
            f32: None,
        })
        .collect();
    // One search per distinct norm: `norms` holds the first loop of each.
    let mut norms: Vec<usize> = Vec::new();
    for i in 0..plan.len() {
        let Ok(g) = &plan[i].gl else { continue };
        let same = |&j: &usize| plan[j].gl.as_ref().is_ok_and(|h| h.d_inv == g.d_inv);
        let n = norms.iter().position(same).unwrap_or_else(|| {
            norms.push(i);
            norms.len() - 1
        });
        plan[i].norm = Some(n);
    }
    for (p, o) in plan.iter_mut().zip(options) {
        p.f32 = Some(match (&p.gl, with_f32) {
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
/// per norm (φ*, then the f32 searches of that norm's methods), each norm's search and each
/// f32 search budgeted by its own estimate against `settings.phase_seconds` (the threads run
/// side by side, so the budget bounds each thread's work). Deterministic: no result depends
/// on the threads' order, nor on the other methods asked.
fn searches(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    settings: &GlobalSettings,
    with_f32: bool,
) -> Vec<(GlobalOutcome, PrecisionOutcome)> {
    let (plan, norms) = plan_loops(resolved, options, with_f32);
    let tau = |g: &GlobalLoop| tau_calls(g, &settings.search);
    let exact_s: Vec<f64> = norms
        .iter()
        .map(|&i| {
            plan[i]
                .gl
                .as_ref()
                .map_or(0.0, |g| search_seconds(g.n_zeta(), g.n_x(), tau(g)))
        })
        .collect();
    // One thread per norm: its φ* (within the budget) and, within the budget, its methods'
    // f32 certificates. Each norm and each method is budgeted on its own, so a method's
    // outcome does not depend on which other methods a command asks for.
    type NormResult = (
        Result<GlobalK, GlobalOutcome>,
        Vec<(usize, PrecisionOutcome)>,
    );
    let run_norm = |n: usize| -> NormResult {
        let i = norms[n];
        let g = match &plan[i].gl {
            Ok(g) => g,
            Err(e) => return (Err(e.clone()), Vec::new()),
        };
        let star = if exact_s[n] > settings.phase_seconds {
            Err(GlobalOutcome::NotComputed {
                n_zeta: g.n_zeta(),
                estimate_seconds: exact_s[n],
                budget_seconds: settings.phase_seconds,
            })
        } else {
            phi_star_or_why(resolved, &options[i], g, &settings.search)
        };
        let mut f32 = Vec::new();
        for (j, p) in plan.iter().enumerate() {
            let (Some(nj), None, Ok(gj)) = (p.norm, &p.f32, &p.gl) else {
                continue;
            };
            if nj != n {
                continue;
            }
            let [first, full] = precision_seconds(gj.n_zeta(), gj.n_x());
            let out = match &star {
                Err(why) => PrecisionOutcome::NoExact(Box::new(why.clone())),
                Ok(_) if exact_s[n] + first > settings.phase_seconds => {
                    PrecisionOutcome::NotComputed {
                        estimate_seconds: exact_s[n] + first,
                        budget_seconds: settings.phase_seconds,
                    }
                }
                Ok((_, cert)) => {
                    let within = exact_s[n] + full <= settings.phase_seconds;
                    match precision_outcome(resolved, &options[j], gj, cert, settings, within) {
                        Some(out) => out,
                        None => PrecisionOutcome::NotComputed {
                            estimate_seconds: exact_s[n] + full,
                            budget_seconds: settings.phase_seconds,
                        },
                    }
                }
            };
            f32.push((j, out));
        }
        (star.map(|(k, _)| k), f32)
    };
    let results: Vec<NormResult> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..norms.len())
            .map(|n| s.spawn(move || run_norm(n)))
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join().unwrap_or_else(|_| {
                    let why = GlobalOutcome::Unsupported {
                        reason: "internal: the search thread panicked".into(),
                    };
                    (Err(why), Vec::new())
                })
            })
            .collect()
    });
    let mut f32_found: Vec<Option<PrecisionOutcome>> = vec![None; plan.len()];
    for (_, f) in &results {
        for (j, o) in f {
            f32_found[*j] = Some(o.clone());
        }
    }
    plan.into_iter()
        .zip(f32_found)
        .map(|(p, found)| {
            let exact = match (&p.gl, p.norm) {
                (Err(e), _) => e.clone(),
                (Ok(g), Some(n)) => match &results[n].0 {
                    Ok(star) => k_glob_of(g, star, settings.search.k_max),
                    Err(why) => why.clone(),
                },
                (Ok(_), None) => GlobalOutcome::Unsupported {
                    reason: "internal: a loop without a norm".into(),
                },
            };
            let f32 = p.f32.or(found).unwrap_or(PrecisionOutcome::NotAsked);
            (exact, f32)
        })
        .collect()
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
        // Certified at φ*_u = φ*, or refused before the bisection (no rounding model, broken
        // contraction, infeasible at φ_u = 0 for every split: the full search runs the same
        // calls): final.
        Ok(p) if p.k_glob.is_some() || p.phi_star.is_none() => return Some(precision_of(&p)),
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
fn tau_calls(g: &GlobalLoop, opts: &GlobalOptions) -> usize {
    let k = opts.tau_points.max(2);
    k + usize::from(g.has_mpc_channel())
}

/// φ* of `g`'s norm with its certificate (K fields filled per method later; the checked
/// certificate itself for the precision search), or what binds.
fn phi_star_or_why(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    g: &GlobalLoop,
    opts: &GlobalOptions,
) -> Result<(GlobalK, GlobalCertificate), GlobalOutcome> {
    if let Some(c) = g.phi_star(opts) {
        let k = GlobalK {
            k_glob: 0,
            phi_star: c.phi,
            phi_at_k: f64::NAN,
            margin: c.margin,
            rho: c.rho,
            gamma: c.gamma,
            gain_x: c.gain_x,
            gain_e: c.gain_e,
        };
        return Ok((k, c));
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

/// K_glob of `g`'s method from its norm's φ*.
fn k_glob_of(g: &GlobalLoop, star: &GlobalK, k_max: usize) -> GlobalOutcome {
    match super::first_k(|k| g.phi(k) <= star.phi_star, k_max) {
        Some(k) => GlobalOutcome::Certified(GlobalK {
            k_glob: k,
            phi_at_k: g.phi(k),
            ..star.clone()
        }),
        None => GlobalOutcome::PhiBallBinds {
            phi_star: star.phi_star,
            k_max,
            phi_at_k_max: g.phi(k_max),
        },
    }
}
