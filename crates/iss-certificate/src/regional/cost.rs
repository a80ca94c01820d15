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
//! 2. **The metrics and the margins** ([`analysis_cost`], once ρ_lin(K) is known): the impulse
//!    response to T terms (T from ρ_lin, as `impulse` picks it) and its product with every
//!    full-window row (rows × dim X × T n_w), the free response's exact reach over S ≤ T steps
//!    (`reach.rs`: S (dim X² + rows × dim X) dim υ, S = T when it fits in the budget, see
//!    [`free_steps`]), then per candidate rate a Stein equation by
//!    doubling (3 dim³ per doubling step, as many steps as (ρ/λ)^(2^j) needs to reach 1e-14),
//!    the square roots (≈ 12 dim³) and the rows in the metric (rows × dim X²).
//!
//! All are multiply-adds of blocked dense kernels, at [`crate::budget::DENSE_RATE`] per second
//! of one core; the calibration against measured times is in `docs/limits.md`.

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

/// The sizes of the model at K, from the pieces alone.
pub(crate) fn sizes(p: &Pieces, k: usize) -> Sizes {
    let big_m = p.windows.len() - 1;
    let full = &p.windows[big_m];
    let d = full.layout.dims;
    let (nx, nu, ny, nw) = (d.nx, d.nu, d.ny, d.nw());
    let dim = nx + big_m * (nu + ny + nx) + full.layout.nz();
    let nv = 2 * nx + big_m * nw;
    let law_rows = finite_bounds(&p.law.lower, &p.law.upper);
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

/// Stage 1: the lifted model at K and ρ_lin(K).
pub(crate) fn model_cost(p: &Pieces, k: usize) -> StageCost {
    let s = sizes(p, k);
    let big_m = p.windows.len() - 1;
    let full = step_cost(&p.windows[big_m], k, s.dim).0;
    let startup: f64 = p.windows[..big_m]
        .iter()
        .map(|w| step_cost(w, k, s.nv).0)
        .sum();
    let law = p.law.gain.nrows() as f64 * p.law.gain.ncols() as f64 * (s.dim + big_m as f64 * s.nv);
    let work = full + startup + law + eigen_work(s.dim as usize) + 2.0 * s.dim.powi(3);
    let bytes =
        F64 * (s.rows * s.dim + s.startup_rows * s.nv + 4.0 * s.dim * s.dim + 2.0 * s.dim * s.nv);
    StageCost { work, bytes }
}

/// A floor on one evaluation's cost from the scenario's dimensions alone (before the
/// windows' iteration maps are built, which is itself costly at large n_z): the candidate
/// metrics' square roots and products, 16 dim³ each, at least. Beyond the budget no K can be
/// evaluated, so the search is refused before anything is built.
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

/// Stage 2: the impulse response, the candidate metrics and every row's margin.
pub(crate) fn analysis_cost(s: &Sizes, rho: f64, fractions: &[f64], steps: usize) -> StageCost {
    let t = impulse_terms(rho) as f64;
    let impulse = t * s.dim * s.dim * s.nw + s.rows * s.dim * s.nw * t;
    let candidates: f64 = fractions
        .iter()
        .map(|f| {
            let lambda = rho + (1.0 - rho) * f;
            (3.0 * doubling_steps(rho, lambda) + 16.0) * s.dim.powi(3)
                + s.rows * s.dim * s.dim
                + s.dim * s.dim * s.nv
        })
        .sum();
    let free = steps as f64 * free_step_work(s);
    let bytes =
        F64 * (s.rows * s.dim + s.dim * s.nw * t + 8.0 * s.dim * s.dim + 2.0 * s.dim * s.nv);
    StageCost {
        work: impulse + free + candidates,
        bytes,
    }
}

/// One step of the free response's exact reach (`reach.rs`): 𝔸·[𝔸^s𝕄, 𝔸^s𝔹_w], every row
/// times both, and the rows' norms.
fn free_step_work(s: &Sizes) -> f64 {
    (s.dim * s.dim + s.rows * s.dim) * (s.nv + s.nw) + s.rows * (s.nv + s.nw)
}

/// S, the steps the free response is taken exactly: T (the impulse's terms), or as many as
/// fit in half the `left_seconds` of the budget after the rest of stage 2 (the other half
/// stays for the next K of a search), down to 0. The metric bounds the steps beyond S, so a
/// smaller S is sound, only less tight — S = 0 is the metric bound alone, which costs nothing
/// more, so the exact steps never make a certificate refuse that the budget would otherwise
/// admit. S depends on estimates only, never on the clock.
pub(crate) fn free_steps(s: &Sizes, rho: f64, fractions: &[f64], left_seconds: f64) -> usize {
    let t = impulse_terms(rho);
    let rest = t as f64 * (s.dim * s.dim * s.nw + s.rows * s.dim * s.nw)
        + fractions
            .iter()
            .map(|f| {
                let lambda = rho + (1.0 - rho) * f;
                (3.0 * doubling_steps(rho, lambda) + 16.0) * s.dim.powi(3) + s.rows * s.dim * s.dim
            })
            .sum::<f64>();
    let per_step = free_step_work(s).max(1.0);
    let affordable = ((0.5 * left_seconds * crate::budget::DENSE_RATE - rest) / per_step).floor();
    (t as f64).min(affordable).max(0.0) as usize
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
        let horizon = sc.mhe.as_ref().map_or(0, |m| m.horizon);
        let floor = floor_from_dims(
            sys.nx(),
            sys.nu(),
            sys.ny(),
            sys.nw(),
            horizon,
            options.rate_fractions.len(),
        );
        self.fits(
            k,
            "one evaluation (at least its candidate metrics, 16 dim³ each, from the dimensions)",
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
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
/// to 1 gives the longest, 400 terms).
pub fn estimate(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
    k: usize,
    options: &RegionalOptions,
    rho: f64,
) -> Result<RegionalEstimate, RegionalVoid> {
    let pieces = model::pieces(resolved, method, options.controller)?;
    let a = model_cost(&pieces, k);
    let sz = sizes(&pieces, k);
    let steps = free_steps(&sz, rho, &options.rate_fractions, options.phase_seconds);
    let b = analysis_cost(&sz, rho, &options.rate_fractions, steps);
    let work = a.work + b.work;
    Ok(RegionalEstimate {
        work,
        seconds: work / crate::budget::DENSE_RATE,
        bytes: a.bytes.max(b.bytes),
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
