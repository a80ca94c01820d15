//! Regional ISS of Alg. 1 from its lifted linear loop (issue 27; derivation and proof in
//! `docs/theory.md`, "Regional ISS of the lifted loop").
//!
//! Where no constraint is active, Alg. 1 with a fixed K is exactly linear: for t ≥ M,
//! X_{t+1} = 𝔸(K)X_t + 𝔹_w w_t on the lifted state of [`crate::linear`]; for t < M the
//! growing windows compose to X_M = 𝕄υ with υ = (x₀, x̄₀, w₀, …, w_{M−1}). Every constraint
//! that could make the loop non-linear — every point an MHE projection acts on, in every
//! inner iteration of every window; every row of the MPC's unconstrained input sequence
//! (exact MPC) or of the LQR input (saturated LQR); every general 𝒳/𝒴 row of the MHE — is a
//! linear functional of X_t (or of υ for t < M). For a metric ‖X‖_P with ‖𝔸‖_P = λ < 1,
//! superposition X_t = 𝔸^{t−M}X_M + Σ_k 𝔸^k𝔹_w w_{t−1−k} (valid while no row is active) gives
//! |c_iX_t| ≤ (the free response's reach over the user's set: exact for t − M < S, see
//! `reach.rs`, and ‖P^{−½}c_iᵀ‖·‖𝔸^S X_M‖_P beyond) + w̄Σ_k‖c_i𝔸^k𝔹_w‖_* (the second sum to
//! T terms plus a certified tail; ‖·‖_* the dual norm of one step's disturbance set, the
//! scenario's noise box by default). If the start-up rows hold over the user's set and every
//! full-window row's reach is within min(u_i, −l_i), then by induction the loop is
//! the linear one for all t: ISS with rate λ for the free response and the asymptotic gains
//! Σ_k‖x_read𝔸^k𝔹_w‖, Σ_k‖e_read𝔸^k𝔹_w‖ (Theorem R of `docs/theory.md`).
//!
//! **What it does not claim.** It is regional: outside the certified set (a larger x₀, prior
//! error or disturbance) only the global certificate (Theorem 1) speaks, and a constraint
//! that activates voids nothing but this certificate. It covers the exact MPC, the saturated
//! LQR and the K_c-iteration MPC on the input box 𝒰^N (its previous sequence U_{t−1} joins X,
//! the point each of its inner iterates projects is a row; not with the MPC's state rows);
//! PG, FISTA and ADMM on a box, PG and FISTA on
//! general rows. The disturbance bound is a Euclidean bound per step (a Gaussian noise has
//! none: give `certificate.w_bar`).

mod candidate;
// The start-up certificate's parts (issue 35 item 2): each method's step with its clip, the
// zonotope abstraction and the real start-up over it. Built and tested; not yet wired into
// `certify_at` (the hand-off to Theorem R at t = T is the next step), hence unused outside
// their tests.
#[cfg_attr(not(test), allow(dead_code))]
mod clip_form;
mod cost;
#[cfg_attr(not(test), allow(dead_code))]
mod handoff;
mod lifted;
mod metric;
mod model;
mod reach;
mod search;
mod start_rows;
#[cfg_attr(not(test), allow(dead_code))]
mod startup;
#[cfg_attr(not(test), allow(dead_code))]
mod zonotope;

use faer::{Mat, Par};
#[cfg(feature = "serde")]
use serde::Serialize;

pub use cost::{RegionalEstimate, estimate};
pub use model::{ModelError, RowKind, RowLabel};
pub use search::*;
pub use start_rows::KFreeLimits;

use crate::linear::spectral_radius;
use candidate::{Candidate, evaluate, impulse};
use closed_loop::scenario::{ControllerChoice, ResolvedScenario};
use cost::{Budget, bytes_text};
use lifted::RegionalModel;
use start_rows::{
    StartupCheck, check_nominal, k_free_check, start_witness, startup_check, startup_terms,
};

/// The user's uncertainty and the search settings.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
pub struct RegionalOptions {
    /// The controller (exact MPC or saturated LQR).
    #[cfg_attr(feature = "serde", serde(skip))]
    pub controller: ControllerChoice,
    /// Nominal x₀ (`simulation.x0`).
    pub x0_nominal: Vec<f64>,
    /// ‖x₀ − x₀_nominal‖ ≤ this (`certificate.x0_radius`).
    pub x0_radius: f64,
    /// ‖x̄₀ − x₀‖ ≤ this (`certificate.prior_error`).
    pub prior_error: f64,
    /// ‖w_t‖₂ ≤ this (`certificate.w_bar`).
    pub w_bar: f64,
    /// The per-step disturbance set's shape. `Some(r)`: the box |w_i| ≤ (w̄/‖r‖₂)·r_i — at the
    /// default w̄ = ‖r‖₂ the scenario's own noise box, inside the ball ‖w‖₂ ≤ w̄ and up to
    /// √n_w times smaller in a row's worst case; `None`: the ball (`certificate.w_bar`).
    pub w_box: Option<Vec<f64>>,
    /// Candidate metrics: λ = ρ_lin + (1 − ρ_lin)·f for each f here (Stein equation with
    /// Q = I at the rate λ).
    pub rate_fractions: Vec<f64>,
    /// Estimated single-core seconds one certificate (or one K_reg search) may take
    /// (`certificate.phase_seconds`; `regional/cost.rs` estimates each stage before it runs).
    pub phase_seconds: f64,
}

/// Why there is no regional certificate. Serialised as its sentence.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RegionalVoid {
    /// The loop could not be modelled (with the reason).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// ρ_lin(K) ≥ 1: the linear loop itself is not stable, no region exists.
    #[error(
        "ρ_lin(K = {k}) = {} ≥ 1: the loop is unstable even where no constraint is active",
        lti_model::numfmt::sig4(*rho)
    )]
    Unstable {
        /// K.
        k: usize,
        /// ρ_lin(K).
        rho: f64,
    },
    /// No candidate metric could be formed (ill-conditioned Stein solutions).
    #[error(
        "no Lyapunov metric of the lifted matrix could be formed at K = {k} (ρ_lin = {})",
        lti_model::numfmt::sig4(*rho)
    )]
    NoMetric {
        /// K.
        k: usize,
        /// ρ_lin(K).
        rho: f64,
    },
    /// The noise has no per-step bound and none was given.
    #[error(
        "the scenario's noise has no per-step bound (Gaussian, or a truncated normal with an \
         infinite `noise.truncate` bound): set `certificate.w_bar` to the disturbance level the \
         region must tolerate"
    )]
    UnboundedNoise,
    /// A bad option.
    #[error("{0}")]
    Options(String),
    /// A stage's estimated cost is beyond what is left of the budget (`regional/cost.rs`).
    #[error(
        "not computed at K = {k}: {stage} is estimated at ≈ {} s of one core ({} multiply-adds, \
         ≈ {} of memory), more than the {} s left of the analysis budget (scenario key \
         `certificate.phase_seconds`, {} s; raise it to compute)",
        crate::budget::secs(*seconds),
        crate::budget::sci(*work),
        bytes_text(*bytes),
        crate::budget::secs(*left),
        crate::budget::secs(*budget)
    )]
    OverBudget {
        /// K.
        k: usize,
        /// The stage (the lifted model and its rows, or the metrics and margins).
        stage: &'static str,
        /// Estimated multiply-adds.
        work: f64,
        /// Estimated seconds of one core.
        seconds: f64,
        /// Estimated peak bytes.
        bytes: f64,
        /// Seconds left of the budget when the stage was reached.
        left: f64,
        /// `certificate.phase_seconds`.
        budget: f64,
    },
    /// A stage's estimated memory is beyond the documented limit for dense matrices.
    #[error(
        "not computed at K = {k}: {stage} would hold ≈ {} (its constraint rows grow with \
         K·n_z·dim X), above the limit of {} for dense matrices (docs/limits.md); lower K or \
         `mhe.horizon`",
        bytes_text(*bytes),
        bytes_text(lti_model::spec::limits::MAX_DENSE_BYTES)
    )]
    OverMemory {
        /// K.
        k: usize,
        /// The stage.
        stage: &'static str,
        /// Estimated peak bytes.
        bytes: f64,
    },
}

/// The binding row of a region, with its figures.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct Limit {
    /// Which constraint.
    pub row: RowLabel,
    /// Its bound min(u, −l) (full-window rows) or the bound it reaches (start-up rows).
    pub bound: f64,
    /// The certified bound on the largest value the row takes over the user's set (full
    /// window: its reach in Theorem R; start-up: |center| + deviation).
    pub reach: f64,
    /// A value of the row that an admissible realization of the user's set reaches in the
    /// linear loop (≤ `reach`; equal for start-up rows): the true worst case lies in
    /// [attained, reach]. Above `bound`, a constraint certainly activates (theory.md,
    /// Theorem R, "the witness").
    pub attained: f64,
    /// The step t at which `attained` is reached.
    pub attained_at: usize,
}

/// The regional certificate at one K.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct RegionalCertificate {
    /// Φ of the MHE.
    pub method: String,
    /// K.
    pub k: usize,
    /// dim X.
    pub dim: usize,
    /// ρ_lin(K).
    pub rho_lin: f64,
    /// The metric chosen (the evaluated candidate with the largest margin).
    pub metric: String,
    /// λ = ‖𝔸‖_P: the certified decay rate per step.
    pub rate: f64,
    /// b = ‖P^{½}𝔹_w‖₂.
    pub disturbance_gain: f64,
    /// The largest ‖X_M‖_P for which no full-window row activates at the user's w̄:
    /// min_c (bound_c − w̄h̃_c)/‖P^{−½}cᵀ‖ (theory.md, Theorem R).
    pub radius: f64,
    /// The full-window row that limits the user's set (largest reach / bound).
    pub radius_limit: Option<Limit>,
    /// sup over the user's set of ‖X_M‖_P.
    pub initial_radius: f64,
    /// bw̄/(1 − λ): a bound on ‖X_t^{w}‖_P, the disturbance's part of the lifted state in
    /// the metric (reported; the row conditions use the tighter per-row sums).
    pub invariant_radius: f64,
    /// Every start-up row holds over the user's set.
    pub startup_holds: bool,
    /// The start-up row with the smallest slack.
    pub startup_limit: Option<Limit>,
    /// S: the steps after M over which every full-window row's free response was taken
    /// exactly (Theorem R; the metric bounds the rest; 0 when the budget left none).
    pub exact_steps: usize,
    /// A row of step t = 0 that an admissible realization drives past its bound. Step 0 does
    /// not depend on K: the MHE's window-0 problem (the prior alone) is solved by its warm
    /// start, the prior, so every iterate of every Φ is the prior and x̂₀ = x̄₀ at every K; so
    /// this refutes the set at every K, not only at this one (theory.md, Theorem R, "the
    /// witness").
    pub refuted_at_start: Option<Limit>,
    /// T: the impulse terms summed exactly (the metric's tail bounds the rest; fewer than the
    /// 10⁻⁹ decay length only when the budget left no more).
    pub impulse_terms: usize,
    /// How many of the candidate metrics (`options.rate_fractions`) were evaluated: all that
    /// the budget admits, or one when a witness refutes the set at this K.
    pub metrics_evaluated: usize,
    /// The row (full window or start-up) that an admissible realization of the user's set
    /// drives farthest past its bound in the linear loop, when one is driven past it: then a
    /// constraint certainly activates and no region on which none is active contains the set
    /// at this K (theory.md, Theorem R, "the witness").
    pub witness: Option<Limit>,
    /// Number of constraint rows (full window, start-up).
    pub rows: (usize, usize),
    /// The user's set lies in the certified region.
    pub contains: bool,
    /// The largest factor s such that (s·x0_radius, s·prior_error, s·w̄) is still certified
    /// (the nominal x₀ kept); ≥ 1 iff `contains` (∞ if the set is a point and certified).
    pub margin: f64,
    /// The largest x0_radius certified with the user's prior_error and w̄ (0 if none).
    pub max_x0_radius: f64,
    /// The largest prior_error certified with the user's x0_radius and w̄.
    pub max_prior_error: f64,
    /// The largest w̄ certified with the user's x0_radius and prior_error.
    pub max_w_bar: f64,
    /// ‖x_read P^{−½}‖: ‖x_t‖ ≤ this·‖X_t‖_P.
    pub x_read_norm: f64,
    /// ‖e_read P^{−½}‖: ‖e_t‖ ≤ this·‖X_t‖_P.
    pub e_read_norm: f64,
    /// Certified asymptotic gain from w̄ to sup‖x_t‖: ‖x_read P^{−½}‖·b/(1 − λ).
    pub gain_x: f64,
    /// Certified asymptotic gain from w̄ to sup‖e_t‖.
    pub gain_e: f64,
    /// The user's set.
    pub options: RegionalOptions,
}

impl RegionalOptions {
    /// The scenario's own uncertainty: x0_radius (default 0), prior_error (default
    /// ‖prior − x₀‖), w̄ (default the largest ‖w‖₂ of the uniform noise, 0 for none).
    pub fn from_scenario(
        resolved: &ResolvedScenario,
        controller: ControllerChoice,
    ) -> Result<Self, RegionalVoid> {
        let sc = resolved.scenario();
        let sim = &sc.simulation;
        let cs = &sc.certificate;
        let default_prior = sim
            .prior
            .iter()
            .zip(&sim.x0)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        let (w_bar, w_box) = match cs.w_bar {
            Some(w) => (w, None),
            // The box the simulated law draws from (with the mean offset), symmetrised:
            // r_i = max(|lo_i|, |hi_i|), w̄ = ‖r‖₂.
            None => {
                let n = &sc.noise;
                let nw = sc.sets.disturbance.lower().len();
                let half = |lo: &[f64], hi: &[f64]| -> Vec<f64> {
                    lo.iter()
                        .zip(hi)
                        .map(|(l, u)| l.abs().max(u.abs()))
                        .collect()
                };
                let mean: Vec<f64> = (0..nw).map(|i| n.mean_at(i)).collect();
                let r = match n.kind {
                    lti_model::spec::NoiseKind::Zero => half(&mean, &mean),
                    _ if n.scale == 0.0 => half(&mean, &mean),
                    lti_model::spec::NoiseKind::Gaussian => {
                        return Err(RegionalVoid::UnboundedNoise);
                    }
                    lti_model::spec::NoiseKind::Uniform => {
                        match n.uniform_box(&sc.sets.disturbance) {
                            Some((lo, hi)) => half(&lo, &hi),
                            None => return Err(RegionalVoid::UnboundedNoise),
                        }
                    }
                    lti_model::spec::NoiseKind::TruncatedNormal => match &n.truncate {
                        Some(t) if t.lower().iter().chain(t.upper()).all(|b| b.is_finite()) => {
                            half(t.lower(), t.upper())
                        }
                        _ => return Err(RegionalVoid::UnboundedNoise),
                    },
                };
                let norm = r.iter().map(|v| v * v).sum::<f64>().sqrt();
                (norm, (norm > 0.0).then_some(r))
            }
        };
        Ok(Self {
            controller,
            x0_nominal: sim.x0.clone(),
            x0_radius: cs.x0_radius.unwrap_or(0.0),
            prior_error: cs.prior_error.unwrap_or(default_prior),
            w_bar,
            w_box,
            rate_fractions: vec![0.02, 0.1, 0.25, 0.5, 0.75],
            phase_seconds: cs.phase_seconds(),
        })
    }
}

impl RegionalOptions {
    /// sup g·w over one step's disturbance set at w̄ = 1, g = (g(from), …, g(from + n_w − 1)):
    /// Σ|g_i|r_i/‖r‖₂ for the box, ‖g‖₂ for the ball (the dual norm; ≤ ‖g‖₂ either way).
    pub(crate) fn w_support(&self, g: impl Fn(usize) -> f64, from: usize, len: usize) -> f64 {
        match &self.w_box {
            Some(r) if r.len() == len => {
                let n = r.iter().map(|v| v * v).sum::<f64>().sqrt();
                (0..len).map(|j| g(from + j).abs() * r[j]).sum::<f64>() / n
            }
            _ => (from..from + len).map(|j| g(j).powi(2)).sum::<f64>().sqrt(),
        }
    }
}

/// The regional certificate of `method` at K (module docs).
///
/// Errors are void reasons: the loop cannot be modelled, ρ_lin(K) ≥ 1, no metric.
pub fn regional_certificate(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
    k: usize,
    options: &RegionalOptions,
) -> Result<RegionalCertificate, RegionalVoid> {
    let mut budget = Budget::new(options.phase_seconds);
    budget.check_floor(resolved, k, options)?;
    let pieces = model::pieces(resolved, method, options.controller)?;
    certify_at(&pieces, method, k, options, &mut budget).map(|r| r.0)
}

/// The matrices behind a regional certificate (for checks and plots): the lifted loop
/// X_{t+1} = 𝔸X_t + 𝔹_w w_t (t ≥ M), X_M = 𝕄υ with υ = (x₀, x̄₀, w₀, …, w_{M−1}), the
/// readouts x_t = x_read·X_t and e_t = e_read·X_t, the full-window rows
/// lower ≤ row·X ≤ upper, and the chosen metric's P^{±½}.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct RegionalDetail {
    /// 𝔸(K).
    pub a: Mat<f64>,
    /// 𝔹_w.
    pub bw: Mat<f64>,
    /// 𝕄.
    pub start_map: Mat<f64>,
    /// x_read.
    pub x_read: Mat<f64>,
    /// e_read.
    pub e_read: Mat<f64>,
    /// The full-window rows.
    pub rows: Vec<Vec<f64>>,
    /// Their lower bounds.
    pub lower: Vec<f64>,
    /// Their upper bounds.
    pub upper: Vec<f64>,
    /// Their labels.
    pub labels: Vec<RowLabel>,
    /// P^{½}.
    pub p_half: Mat<f64>,
    /// P^{−½}.
    pub p_neg_half: Mat<f64>,
    /// Per full-window row, a bound on |row·X_t| for every t ≥ M over the user's set while no
    /// row is active: the free response's reach (exact over S steps, the metric's beyond)
    /// plus the disturbance's w̄·h̃ (Theorem R).
    pub reach: Vec<f64>,
}

/// [`regional_certificate`] with its [`RegionalDetail`].
pub fn regional_detail(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
    k: usize,
    options: &RegionalOptions,
) -> Result<(RegionalCertificate, RegionalDetail), RegionalVoid> {
    let mut budget = Budget::new(options.phase_seconds);
    budget.check_floor(resolved, k, options)?;
    let pieces = model::pieces(resolved, method, options.controller)?;
    let (c, model, m, reach) = certify_at(&pieces, method, k, options, &mut budget)?;
    Ok((c, detail_of(model, m, reach)))
}

fn certify_at(
    pieces: &model::Pieces,
    method: qp_iter::Method,
    k: usize,
    o: &RegionalOptions,
    budget: &mut Budget,
) -> Result<(RegionalCertificate, RegionalModel, metric::Metric, Vec<f64>), RegionalVoid> {
    check_nominal(pieces, o)?;
    if k == 0 || pieces.windows.iter().any(|w| k < w.lin.start_steps) {
        return Err(ModelError::from(crate::linear::LinearError::ZeroIterations).into());
    }
    let (model, rho) = stable_model(pieces, k, budget)?;
    let sizes = cost::sizes(pieces, k);
    let plan = cost::analysis_plan(&sizes, rho, &o.rate_fractions, budget.left);
    budget.spend(
        k,
        "the impulse response, the free response, the candidate metrics and the rows' margins",
        plan.base,
    )?;
    let (free, imp, imp_terms) = free_and_impulse(&model, o, &plan, budget);

    // Start-up rows over the user's set (exact: linear in υ).
    let terms = startup_terms(
        &model.startup_rows,
        (model.nx, model.nw, model.layout.horizon),
        o,
    );
    let at_start = start_witness(&model.startup_rows, &terms, o, |l| l.step == Some(0));
    let startup = startup_check(&model.startup_rows, &terms, o);
    // A witness (an admissible realization past a bound) refutes the set at this K whatever
    // the metric: one candidate then gives the certificate's figures, the others are skipped.
    let refuted = !startup.holds || free_refutes(&model, &free);
    let (c, metrics) =
        best_candidate(&model, (&imp, &free), (k, rho), (&plan, refuted), o, budget)?;
    let cert = assemble(
        method,
        (k, rho),
        &model,
        &c,
        startup,
        at_start,
        (free.steps, imp_terms, metrics),
        o,
    );
    Ok((cert, model, c.metric, c.reach))
}

/// ρ_lin(K) first, from the K-step maps (log₂K products): an unstable K is refused before its
/// K·n_z rows are built. The margin 10⁻⁹ leaves the borderline cases to the iterated matrix,
/// whose ρ_lin the certificate reports. Returns the model with every row and that ρ_lin.
fn stable_model(
    pieces: &model::Pieces,
    k: usize,
    budget: &mut Budget,
) -> Result<(RegionalModel, f64), RegionalVoid> {
    budget.spend(
        k,
        "ρ_lin(K) from the K-step maps",
        cost::rho_cost(pieces, k),
    )?;
    let fast = lifted::matrix(pieces, k).map_err(ModelError::from)?;
    let rho_fast = spectral_radius(fast.as_ref(), Par::Seq).map_err(ModelError::from)?;
    if !(rho_fast < 1.0 + 1e-9) {
        return Err(RegionalVoid::Unstable { k, rho: rho_fast });
    }
    budget.spend(
        k,
        "the lifted model (every inner iterate's rows) and ρ_lin",
        cost::model_cost(pieces, k),
    )?;
    let model = lifted::build(pieces, k).map_err(ModelError::from)?;
    let rho = spectral_radius(model.a.as_ref(), Par::Seq).map_err(ModelError::from)?;
    if !(rho < 1.0) {
        return Err(RegionalVoid::Unstable { k, rho });
    }
    Ok((model, rho))
}

/// The free response's exact steps (the probe first: a witness there refutes the K, and then
/// only the least is computed) and the impulse terms; refunds what was planned and not spent.
fn free_and_impulse(
    model: &RegionalModel,
    o: &RegionalOptions,
    plan: &cost::AnalysisPlan,
    budget: &mut Budget,
) -> (reach::FreeReach, candidate::Impulse, usize) {
    let mut free = reach::free_reach(model, o, plan.probe);
    let mut refund = (plan.probe - free.steps) as f64 * plan.step_work;
    let probe_refutes = free.steps < plan.probe || free_refutes(model, &free);
    if plan.steps > plan.probe {
        if probe_refutes {
            refund += plan.steps as f64 * plan.step_work;
        } else {
            free = reach::free_reach(model, o, plan.steps);
            refund += (plan.steps - free.steps) as f64 * plan.step_work;
        }
    }
    let imp_terms = if probe_refutes {
        plan.least_terms
    } else {
        plan.terms
    };
    refund += (plan.terms - imp_terms) as f64 * plan.term_work;
    budget.refund(refund);
    (free, impulse(model, imp_terms, o), imp_terms)
}

/// The candidate metric that certifies the largest multiple of the user's set (then the
/// largest radius), the cheapest first; with a witness (`refuted`) only the cheapest. Returns it
/// and how many metrics were evaluated.
fn best_candidate(
    model: &RegionalModel,
    (imp, free): (&candidate::Impulse, &reach::FreeReach),
    (k, rho): (usize, f64),
    (plan, refuted): (&cost::AnalysisPlan, bool),
    o: &RegionalOptions,
    budget: &mut Budget,
) -> Result<(Candidate, usize), RegionalVoid> {
    let mut best: Option<(f64, Candidate)> = None;
    let mut metrics = 0;
    let order = std::iter::once(plan.cheapest).chain(
        plan.candidates
            .iter()
            .copied()
            .filter(|&i| i != plan.cheapest),
    );
    for i in order {
        if i != plan.cheapest {
            if refuted && best.is_some() {
                continue;
            }
            budget.spend(
                k,
                "a further candidate metric",
                cost::StageCost {
                    work: plan.candidate_work[i],
                    bytes: plan.base.bytes,
                },
            )?;
        }
        metrics += 1;
        let f = o.rate_fractions[i];
        let lam = rho + (1.0 - rho) * f;
        let Some(p) = metric::stein(model.a.as_ref(), lam) else {
            continue;
        };
        let Some(m) = metric::metric(p.as_ref()) else {
            continue;
        };
        let c = evaluate(
            model,
            imp,
            free,
            &m,
            format!("Stein, λ = ρ_lin + {f}·(1 − ρ_lin) = {lam:.6}"),
            o,
        );
        // Rank by the certified scale of the user's set, then by the radius.
        let key = c.full_scale(o).min(f64::MAX);
        let better = match &best {
            None => true,
            Some((bk, bc)) => key > *bk || (key == *bk && c.radius > bc.radius),
        };
        if better {
            best = Some((key, c));
        }
    }
    match best {
        Some((_, c)) => Ok((c, metrics)),
        None => Err(RegionalVoid::NoMetric { k, rho }),
    }
}

/// The certificate from the best candidate and the start-up check: the witness with the largest
/// ratio, the margin, the largest single radii, the gains.
#[allow(clippy::too_many_arguments)]
fn assemble(
    method: qp_iter::Method,
    (k, rho): (usize, f64),
    model: &RegionalModel,
    c: &Candidate,
    startup: StartupCheck,
    at_start: Option<Limit>,
    (exact_steps, impulse_terms, metrics_evaluated): (usize, usize, usize),
    o: &RegionalOptions,
) -> RegionalCertificate {
    let StartupCheck {
        holds: startup_holds,
        scale: startup_scale,
        limit: startup_limit,
        max_x: sx,
        max_p: sp,
        max_w: sw,
    } = startup;
    let ratio = |l: &Limit| l.attained / l.bound;
    let witness = [c.witness.clone(), startup_limit.clone()]
        .into_iter()
        .flatten()
        .filter(|l| l.attained > l.bound)
        .max_by(|a, b| ratio(a).total_cmp(&ratio(b)));
    let full_scale = c.full_scale(o);
    let margin = full_scale.min(startup_scale);
    let contains = startup_holds && margin >= 1.0;
    // Largest single radius with the other two fixed (full-window and start-up conditions).
    let inv_rate = if c.rate < 1.0 {
        c.b / (1.0 - c.rate)
    } else {
        f64::INFINITY
    };
    let (full_x, full_p, full_w) = (c.max_x, c.max_p, c.max_w);
    let clamp = |v: f64| if v.is_nan() { 0.0 } else { v.max(0.0) };
    RegionalCertificate {
        method: method.to_string(),
        k,
        dim: model.layout.dim(),
        rho_lin: rho,
        metric: c.name.clone(),
        rate: c.rate,
        disturbance_gain: c.b,
        radius: c.radius,
        radius_limit: c.limit.clone(),
        initial_radius: c.nominal + o.x0_radius * c.a_x + o.prior_error * c.a_p + o.w_bar * c.a_w,
        invariant_radius: o.w_bar * inv_rate,
        startup_holds,
        startup_limit,
        witness,
        refuted_at_start: at_start,
        exact_steps,
        impulse_terms,
        metrics_evaluated,
        rows: (model.rows.labels.len(), model.startup_rows.labels.len()),
        contains,
        margin,
        max_x0_radius: clamp(full_x.min(sx)),
        max_prior_error: clamp(full_p.min(sp)),
        max_w_bar: clamp(full_w.min(sw)),
        x_read_norm: c.x_read_norm,
        e_read_norm: c.e_read_norm,
        gain_x: c.gain_x,
        gain_e: c.gain_e,
        options: o.clone(),
    }
}

/// Some full-window row's exact steps reach past its bound: a witness.
fn free_refutes(model: &RegionalModel, free: &reach::FreeReach) -> bool {
    free.attained
        .iter()
        .enumerate()
        .any(|(i, a)| a.value > model.rows.upper[i].min(-model.rows.lower[i]))
}

fn detail_of(model: RegionalModel, m: metric::Metric, reach: Vec<f64>) -> RegionalDetail {
    RegionalDetail {
        reach,
        rows: model.rows.to_vecs(),
        a: model.a,
        bw: model.bw,
        start_map: model.start_map,
        x_read: model.x_read,
        e_read: model.e_read,
        lower: model.rows.lower,
        upper: model.rows.upper,
        labels: model.rows.labels,
        p_half: m.half,
        p_neg_half: m.neg_half,
    }
}

#[cfg(feature = "serde")]
impl Serialize for RegionalVoid {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}
