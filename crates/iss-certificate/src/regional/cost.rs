//! The cost of one regional certificate, estimated from the dimensions before each stage
//! starts (issue 23 item 3, issue 25 item 4), with the same counts the code allocates by.
//!
//! Two stages, each checked against what is left of the budget before it runs:
//!
//! 1. **The lifted model** ([`model_cost`]): every inner iterate of every window as a linear
//!    map — per iterate a product of the step matrix (n_ξ × n_ξ) with the n_ξ × cols iterate
//!    and the readout (n_z × n_ξ); cols = dim X for the full window, dim υ = 2n_x + M n_w for
//!    the M start-up windows — then the spectral radius of 𝔸(K) ([`crate::linear::eigen_work`]).
//!    Its memory is the rows: one stored row of cols entries per finitely bounded component of
//!    every projected point of every iterate.
//! 2. **The metrics and the margins** ([`analysis_plan`], once ρ_lin(K) is known): the impulse
//!    response to T terms and its product with every full-window row (rows × dim X × T n_w),
//!    the free response's exact reach over S steps (`reach.rs`: S (dim X² + rows × dim X)
//!    dim υ), and per candidate rate a Stein equation by doubling (3 dim³ per doubling step, as
//!    many steps as (ρ/λ)^(2^j) needs to reach 1e-14), the square roots (≈ 12 dim³) and the
//!    rows in the metric (rows × dim X²). T, S and the candidates are fitted to the budget:
//!    only 8 terms and the cheapest candidate are required ([`AnalysisPlan`]).
//!
//! All are multiply-adds of blocked dense kernels, at [`crate::budget::DENSE_RATE`] per second
//! of one core; the calibration against measured times is in `docs/limits.md`.

#[cfg(feature = "serde")]
use serde::Serialize;

use super::model::{self, Pieces};
use super::{RegionalOptions, RegionalVoid};
use crate::linear::eigen_work;
use closed_loop::scenario::ResolvedScenario;

/// Bytes of one f64, times the overhead measured over the counted matrices (column padding,
/// the row labels and bounds, transient copies): the heap peak of `regional_certificate` was
/// 1.2–1.4× the counted f64s on the grid of `tests/regional_memory.rs`.
const F64: f64 = 8.0 * 1.35;

/// Estimated work and memory of one stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StageCost {
    /// Multiply-adds.
    pub work: f64,
    /// Peak bytes held by the stage's large matrices.
    pub bytes: f64,
}

/// The sizes of the model at K that the stages' costs depend on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Sizes {
    /// dim X.
    pub dim: f64,
    /// dim υ = 2n_x + M n_w.
    pub nv: f64,
    /// n_w.
    pub nw: f64,
    /// Full-window rows.
    pub rows: f64,
    /// Start-up rows.
    pub startup_rows: f64,
}

fn finite_bounds(lower: &[f64], upper: &[f64]) -> f64 {
    lower
        .iter()
        .zip(upper)
        .filter(|(l, u)| l.is_finite() || u.is_finite())
        .count() as f64
}

/// (work, rows) of one MHE step of window `w` with K iterations on `cols` columns
/// (`model::mhe_step`).
fn step_cost(w: &super::model::WindowStep, k: usize, cols: f64) -> (f64, f64) {
    let lin = &w.lin;
    let (n, nt, xi) = (lin.n as f64, lin.n_theta as f64, lin.lift_dim() as f64);
    let iterates = (k.saturating_sub(lin.start_steps) + 1) as f64;
    let (g_rows, g_work) = w.general.as_ref().map_or((0.0, 0.0), |(g, _, l, u)| {
        (finite_bounds(l, u), g.nrows() as f64 * (n + nt) * cols)
    });
    let per_iterate = (xi * xi + n * xi) * cols + g_work;
    let work = xi * (n + nt) * cols + xi * nt * cols + iterates * per_iterate + n * cols * n;
    let rows = iterates * (finite_bounds(&w.lower, &w.upper) + g_rows);
    (work, rows)
}

/// (work, rows) of the control law on `cols` columns: the static gain, or the K_c steps of the
/// MPC's Φ with their rows (`model::control`).
fn law_cost(law: &super::model::Law, cols: f64) -> (f64, f64) {
    let bounded = finite_bounds(&law.lower, &law.upper);
    match &law.iterative {
        None => (
            law.gain.nrows() as f64 * law.gain.ncols() as f64 * cols,
            bounded,
        ),
        Some(m) => {
            let lin = &m.lin;
            let (n, nt, xi) = (lin.n as f64, lin.n_theta as f64, lin.lift_dim() as f64);
            let iterates = (m.k.saturating_sub(lin.start_steps) + 1) as f64;
            let work = n * n * cols
                + xi * (n + nt) * cols
                + xi * nt * cols
                + iterates * (xi * xi + n * xi) * cols;
            (work, iterates * bounded)
        }
    }
}

/// The sizes of the model at K, from the pieces alone.
pub(crate) fn sizes(p: &Pieces, k: usize) -> Sizes {
    let big_m = p.windows.len() - 1;
    let full = &p.windows[big_m];
    let d = full.layout.dims;
    let (nx, nu, ny, nw) = (d.nx, d.nu, d.ny, d.nw());
    let dim = nx + big_m * (nu + ny + nx) + full.layout.nz() + p.law.n_controller();
    let nv = 2 * nx + big_m * nw;
    let law_rows = law_cost(&p.law, 1.0).1;
    let (_, full_rows) = step_cost(full, k, dim as f64);
    let startup_rows: f64 = p.windows[..big_m]
        .iter()
        .map(|w| step_cost(w, k, nv as f64).1 + law_rows)
        .sum();
    Sizes {
        dim: dim as f64,
        nv: nv as f64,
        nw: nw as f64,
        rows: full_rows + law_rows,
        startup_rows,
    }
}

/// Stage 0: 𝔸(K) from the K-step maps and ρ_lin(K) (`lifted::matrix`): per map ⌈log₂K⌉
/// squarings and as many products of its augmented step (n_ξ + n_θ)³, the maps applied to the
/// dim X columns, the assembly, and the eigenvalues.
pub(crate) fn rho_cost(p: &Pieces, k: usize) -> StageCost {
    let s = sizes(p, k);
    let power = |lin: &crate::linear::IterationLinearisation, k: usize| {
        let m = (lin.lift_dim() + lin.n_theta) as f64;
        2.0 * (k.max(2) as f64).log2().ceil() * m.powi(3) + lin.n as f64 * m * s.dim
    };
    let big_m = p.windows.len() - 1;
    let mpc = p.law.iterative.as_ref().map_or(0.0, |m| power(&m.lin, m.k));
    StageCost {
        work: power(&p.windows[big_m].lin, k)
            + mpc
            + 4.0 * s.dim * s.dim * s.nv
            + eigen_work(s.dim as usize),
        bytes: F64 * 6.0 * s.dim * s.dim,
    }
}

/// Stage 1: the lifted model at K and ρ_lin(K).
pub(crate) fn model_cost(p: &Pieces, k: usize) -> StageCost {
    let s = sizes(p, k);
    let big_m = p.windows.len() - 1;
    let full = step_cost(&p.windows[big_m], k, s.dim).0;
    let startup: f64 = p.windows[..big_m]
        .iter()
        .map(|w| step_cost(w, k, s.nv).0)
        .sum();
    let law = law_cost(&p.law, s.dim).0 + big_m as f64 * law_cost(&p.law, s.nv).0;
    let work = full + startup + law + eigen_work(s.dim as usize) + 2.0 * s.dim.powi(3);
    let bytes =
        F64 * (s.rows * s.dim + s.startup_rows * s.nv + 4.0 * s.dim * s.dim + 2.0 * s.dim * s.nv);
    StageCost { work, bytes }
}

/// A floor on one evaluation's cost from the scenario's dimensions alone (before the
/// windows' iteration maps are built, which is itself costly at large n_z): the square roots
/// and products of `candidates` metrics, 16 dim³ each, at least (one is required). Beyond the
/// budget no K can be evaluated, so the search is refused before anything is built.
pub(crate) fn floor_from_dims(
    nx: usize,
    nu: usize,
    ny: usize,
    nw: usize,
    horizon: usize,
    candidates: usize,
) -> StageCost {
    let nz = nx + horizon * nw;
    let dim = (nx + horizon * (nu + ny + nx) + nz) as f64;
    StageCost {
        work: candidates as f64 * 16.0 * dim.powi(3),
        bytes: F64 * 4.0 * dim * dim,
    }
}

/// The number of impulse-response terms `impulse` takes at ρ_lin = `rho`.
pub(crate) fn impulse_terms(rho: f64) -> usize {
    if rho < 1e-3 {
        8
    } else {
        ((1e-9f64).ln() / rho.ln()).ceil().clamp(8.0, 2000.0) as usize
    }
}

/// Doubling steps of the Stein series at rate λ for ρ(A) = ρ: (ρ/λ)^(2^j) ≤ 1e-14.
fn doubling_steps(rho: f64, lambda: f64) -> f64 {
    let q = (rho / lambda).clamp(1e-300, 1.0 - 1e-12);
    let needed = (1e-14f64).ln() / q.ln();
    // +3: transient growth of non-normal 𝔸 before the decay sets in.
    (needed.max(1.0).log2().ceil() + 3.0).min(64.0)
}

/// The fewest impulse terms a certificate takes: the metric's certified tail bounds the rest.
const MIN_TERMS: usize = 8;

/// The exact steps taken first, before the rest of the stage: a witness (theory.md, Theorem R)
/// shows up within a few dozen steps on the shipped loops (t = M + 1 … M + 93), and it refutes
/// the K at once, so nothing else is computed.
const PROBE_STEPS: usize = 64;

/// One impulse term: 𝔸·𝔸^k𝔹_w and every row times it.
fn impulse_term_work(s: &Sizes) -> f64 {
    s.dim * s.dim * s.nw + s.rows * s.dim * s.nw
}

/// One candidate metric at rate λ = ρ + (1 − ρ)f: the Stein equation by doubling, its square
/// roots, the rows in the metric and the start map in it.
fn candidate_work(s: &Sizes, rho: f64, f: f64) -> f64 {
    let lambda = rho + (1.0 - rho) * f;
    (3.0 * doubling_steps(rho, lambda) + 16.0) * s.dim.powi(3)
        + s.rows * s.dim * s.dim
        + s.dim * s.dim * s.nv
}

/// One step of the free response's exact reach (`reach.rs`): 𝔸·[𝔸^s𝕄, 𝔸^s𝔹_w], every row
/// times both, and the rows' norms.
fn free_step_work(s: &Sizes) -> f64 {
    (s.dim * s.dim + s.rows * s.dim) * (s.nv + s.nw) + s.rows * (s.nv + s.nw)
}

/// What stage 2 computes at one K, chosen from the estimates before it runs (never from the
/// clock): T impulse terms, S exact steps of the free response, and which candidate metrics.
///
/// The least a certificate needs — min(T_ρ, 8) terms and the cheapest candidate metric — must
/// fit in what is left of the budget (else the stage is refused). What it adds is taken, in
/// this order, from half of what is left (the other half stays for the next K of a search):
/// the first min(T_ρ, 64) exact steps (the probe: a witness there refutes the K, and then
/// only the least is computed besides), more impulse terms up to T_ρ (the length at which
/// ρ_lin^T ≤ 10⁻⁹; a short sum loosens every row by the metric's tail), the other candidate
/// metrics, then the exact steps up to T_ρ (computed again from the start). Each is sound at
/// any length — fewer terms, steps or metrics only loosen the bound — so the budget decides
/// how tight a certificate is, not whether there is one.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct AnalysisPlan {
    /// The least number of impulse terms, min(T_ρ, 8).
    pub least_terms: usize,
    /// T: impulse terms summed exactly when no witness refutes the K.
    pub terms: usize,
    /// The probe's exact steps.
    pub probe: usize,
    /// S: steps of the free response taken exactly (≥ `probe` when larger than it: then the
    /// steps are taken again from the start).
    pub steps: usize,
    /// The candidate metrics evaluated (indices into `rate_fractions`, ascending).
    pub candidates: Vec<usize>,
    /// The cheapest of them, evaluated first (alone when a witness refutes the K).
    pub cheapest: usize,
    /// Work of the least, the probe, the extra terms and the longer steps, with the stage's
    /// peak bytes (the other candidates are spent as they are evaluated).
    pub base: StageCost,
    /// Work of each candidate (by index).
    pub candidate_work: Vec<f64>,
    /// Work of one impulse term.
    pub term_work: f64,
    /// Work of one exact step.
    pub step_work: f64,
}

/// The plan of stage 2 at ρ_lin = `rho` with `left_seconds` of the budget left.
pub(crate) fn analysis_plan(
    s: &Sizes,
    rho: f64,
    fractions: &[f64],
    left_seconds: f64,
) -> AnalysisPlan {
    let full = impulse_terms(rho);
    let candidate_work: Vec<f64> = fractions
        .iter()
        .map(|&f| candidate_work(s, rho, f))
        .collect();
    let cheapest = (0..candidate_work.len())
        .min_by(|&a, &b| candidate_work[a].total_cmp(&candidate_work[b]))
        .unwrap_or(0);
    let (term_work, step_work) = (impulse_term_work(s).max(1.0), free_step_work(s).max(1.0));
    let least_terms = full.min(MIN_TERMS);
    let cheapest_work = candidate_work.get(cheapest).copied().unwrap_or(0.0);
    let mut spare = 0.5 * left_seconds * crate::budget::DENSE_RATE
        - least_terms as f64 * term_work
        - cheapest_work;
    let mut take = |per: f64, most: usize| -> usize {
        if spare <= 0.0 {
            return 0;
        }
        let n = (spare / per).floor().min(most as f64).max(0.0) as usize;
        spare -= n as f64 * per;
        n
    };
    let probe = take(step_work, full.min(PROBE_STEPS));
    let terms = least_terms + take(term_work, full - least_terms);
    let mut candidates = Vec::with_capacity(candidate_work.len());
    for (i, &w) in candidate_work.iter().enumerate() {
        if i == cheapest || take(w, 1) == 1 {
            candidates.push(i);
        }
    }
    // Longer steps are taken again from the start: S steps cost S on top of the probe.
    let longer = if probe == full.min(PROBE_STEPS) {
        take(step_work, full)
    } else {
        0
    };
    let steps = if longer > probe { longer } else { probe };
    let step_total = probe + if longer > probe { longer } else { 0 };
    let bytes = F64
        * (s.rows * s.dim + s.dim * s.nw * terms as f64 + 8.0 * s.dim * s.dim + 2.0 * s.dim * s.nv);
    AnalysisPlan {
        least_terms,
        terms,
        probe,
        steps,
        base: StageCost {
            work: terms as f64 * term_work + step_total as f64 * step_work + cheapest_work,
            bytes,
        },
        candidates,
        cheapest,
        candidate_work,
        term_work,
        step_work,
    }
}

impl AnalysisPlan {
    /// The work of the whole plan (every candidate evaluated, every step taken).
    pub fn work(&self) -> f64 {
        self.base.work
            + self
                .candidates
                .iter()
                .filter(|&&i| i != self.cheapest)
                .map(|&i| self.candidate_work[i])
                .sum::<f64>()
    }
}

/// Bytes in MiB or GiB with at most 4 significant digits.
pub(crate) fn bytes_text(b: f64) -> String {
    const MIB: f64 = (1u64 << 20) as f64;
    if b >= 1024.0 * MIB {
        format!("{} GiB", lti_model::numfmt::sig4(b / (1024.0 * MIB)))
    } else {
        format!("{} MiB", lti_model::numfmt::sig4(b / MIB))
    }
}

/// What is left of the budget of one certificate or one K_reg search.
pub(crate) struct Budget {
    pub total: f64,
    pub left: f64,
}

impl Budget {
    pub fn new(total: f64) -> Self {
        Self { total, left: total }
    }

    /// Refuses at once when even the floor of one evaluation (`floor_from_dims`) does
    /// not fit: nothing is built (spends nothing).
    pub fn check_floor(
        &self,
        resolved: &ResolvedScenario,
        k: usize,
        options: &RegionalOptions,
    ) -> Result<(), RegionalVoid> {
        let sc = resolved.scenario();
        let sys = &sc.plant;
        let horizon = sc.mhe.as_ref().map_or(0, |m| m.horizon());
        let floor = floor_from_dims(
            sys.nx(),
            sys.nu(),
            sys.ny(),
            sys.nw(),
            horizon,
            // One candidate metric is all an evaluation requires (`AnalysisPlan`).
            options.rate_fractions.len().min(1),
        );
        self.fits(
            k,
            "one evaluation (at least one candidate metric, 16 dim³, from the dimensions)",
            floor,
        )
        .map(|_| ())
    }

    /// Spends the stage's estimate, or refuses it.
    pub fn spend(
        &mut self,
        k: usize,
        stage: &'static str,
        c: StageCost,
    ) -> Result<(), RegionalVoid> {
        self.left -= self.fits(k, stage, c)?;
        Ok(())
    }

    /// Gives back the estimate of work that turned out unnecessary (exact steps after a
    /// witness, candidates a witness made pointless): what a search may still do depends on
    /// estimates only.
    pub fn refund(&mut self, work: f64) {
        self.left = (self.left + work / crate::budget::DENSE_RATE).min(self.total);
    }

    /// The stage's estimated seconds if it fits what is left, else why not (memory first: it
    /// is a hard limit).
    fn fits(&self, k: usize, stage: &'static str, c: StageCost) -> Result<f64, RegionalVoid> {
        if c.bytes > lti_model::spec::limits::MAX_DENSE_BYTES {
            return Err(RegionalVoid::OverMemory {
                k,
                stage,
                bytes: c.bytes,
            });
        }
        let seconds = c.work / crate::budget::DENSE_RATE;
        if seconds > self.left {
            return Err(RegionalVoid::OverBudget {
                k,
                stage,
                work: c.work,
                seconds,
                bytes: c.bytes,
                left: self.left,
                budget: self.total,
            });
        }
        Ok(seconds)
    }
}

/// The estimated cost of [`super::regional_certificate`] at K, as its budget checks it
/// (`regional/cost.rs`): multiply-adds, seconds of one core at
/// [`crate::budget::DENSE_RATE`], and the peak bytes of its large matrices.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct RegionalEstimate {
    /// Multiply-adds of both stages.
    pub work: f64,
    /// `work` in seconds of one core.
    pub seconds: f64,
    /// Peak bytes (the larger stage).
    pub bytes: f64,
}

/// [`RegionalEstimate`] of `method` at K. ρ_lin(K) sets the length of the impulse response
/// (the second stage): pass the certificate's `rho_lin` when known, else a bound (a ρ close
/// to 1 gives the longest, 2000 terms). The plan is the one a single certificate with the
/// whole `phase_seconds` would make.
pub fn estimate(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
    k: usize,
    options: &RegionalOptions,
    rho: f64,
) -> Result<RegionalEstimate, RegionalVoid> {
    let pieces = model::pieces(resolved, method, options.controller)?;
    let r = rho_cost(&pieces, k);
    let m = model_cost(&pieces, k);
    let a = StageCost {
        work: r.work + m.work,
        bytes: r.bytes.max(m.bytes),
    };
    let sz = sizes(&pieces, k);
    let plan = analysis_plan(
        &sz,
        rho,
        &options.rate_fractions,
        options.phase_seconds - a.work / crate::budget::DENSE_RATE,
    );
    let work = a.work + plan.work();
    Ok(RegionalEstimate {
        work,
        seconds: work / crate::budget::DENSE_RATE,
        bytes: a.bytes.max(plan.base.bytes),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn impulse_terms_follow_the_rate() {
        assert_eq!(impulse_terms(0.0), 8);
        assert_eq!(impulse_terms(0.5), 30);
        assert_eq!(impulse_terms(0.999_999), 2000);
    }

    #[test]
    fn doubling_steps_grow_as_the_rate_nears_rho() {
        let fast = doubling_steps(0.5, 0.9);
        let slow = doubling_steps(0.99, 0.9902);
        assert!(fast < slow && slow <= 64.0, "{fast} {slow}");
    }
}
