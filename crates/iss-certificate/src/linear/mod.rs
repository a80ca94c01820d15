//! K_lin: the exact linear stability boundary of Alg. 1 (design.md §7.4, issue 13).
//!
//! Where no constraint is active — the box Z of the MHE QP (𝒳 × 𝒲^M) and the MPC's 𝒰^N are
//! never touched, so every projection is the identity — and w ≡ 0, Alg. 1 with a fixed
//! iteration budget K is a linear time-invariant system for t ≥ M (the window has its full
//! length M). Its state is
//!
//! X_t = (x_t, u_{t−M..t−1}, y_{t−M..t−1}, x̂_{t−M..t−1}, z⁰_t, U_{t−1}),
//!
//! dim X = n_x + M(n_u + n_y + n_x) + n_z (+ N n_u for a K_c-iteration MPC), n_z = n_x + M n_w:
//!
//! - the plant state x_t;
//! - the u and y windows the MHE holds (θ_t = (x̂_{t−M}, u_{t−M..t−1}, y_{t−M..t−1}));
//! - the ring of the last M estimates: the prior of the window that starts at t − M is the
//!   estimate the scheme produced M steps earlier, x̂_{t−M} (design trap 1);
//! - the warm start z⁰_t = zᴷ_{t−1} (Σ_t = I for t ≥ M, trap 3; or the time-shifted option);
//! - the sub-optimal MPC's previous iterate U_{t−1}, which its warm start shifts.
//!
//! One step: zᴷ_t = G_K z⁰_t + J_K θ_t (`iteration.rs`), x̂_t = X_z zᴷ_t + X_θ θ_t (the last
//! state of the window propagated through the model, trap 2), u_t = L x̂_t (the unconstrained
//! MPC gain L = −E₀H⁻¹F, or −K_lqr) or U_t = G^c_{K_c} W U_{t−1} + J^c_{K_c} x̂_t, y_t = C x_t,
//! x_{t+1} = A x_t + B u_t, then every window shifts by one stage. Hence X_{t+1} = 𝔸(K) X_t
//! and ρ_lin(K) = max|λ(𝔸(K))|.
//!
//! **What it claims and what it does not.** ρ_lin(K) > 1 means a perturbation grows for as
//! long as the constraints stay inactive: a closed loop that is stable for every small
//! disturbance needs ρ_lin(K) ≤ 1, so ρ_lin < 1 is *necessary* (with a margin for noise),
//! exact, and cheap. It is not sufficient: it says nothing once a bound of 𝒲 or 𝒰
//! becomes active (saturation changes the system), nothing about the transient t < M, and
//! nothing about the size of the noise. K_lin ≤ K_emp ≤ K_cert brackets the truth.
//!
//! Entry points: [`linear_stability`] (the report on a K grid for one scenario and solver),
//! [`LiftedLoop`] (the matrix 𝔸(K) itself), [`linearise`] (one iteration map).

mod iteration;
mod kgrid;
mod krylov;
mod lifted;
mod work;

use faer::Par;
#[cfg(feature = "serde")]
use serde::Serialize;

pub use iteration::{IterationLinearisation, KStepMap, Linearise, linearise};
pub use kgrid::log_spaced;
pub use krylov::{KRYLOV_MIN_DIM, spectral_radius_krylov, spectral_radius_krylov_steps};
pub(crate) use lifted::mpc_warm_matrix;
pub use lifted::{LiftedLayout, LiftedLoop, spectral_radius, spectral_radius_dense};
pub use work::{LiftedDims, eigen_work};

use closed_loop::scenario::{LoopOptions, ResolvedScenario};
use closed_loop::sim::ClosedLoopError;
use qp_iter::Method;

/// Largest MHE window size n_z = n_x + M·n_w for which `reproduce` computes ρ_lin for every
/// method of the certificate; above it only for the scenario's own method (the one
/// simulated). The budget's estimate ([`crate::budget::estimate_phases`]) follows the same
/// rule.
pub const ALL_METHODS_MAX_NZ: usize = 128;

/// The fix for a zero-width interval of Z (lower = upper), the usual way to write "no noise
/// here" in `sets.disturbance`: that is what `plant.e` / `plant.f` with fewer columns say.
fn zero_width_hint(problem: &str, lower: f64, upper: f64) -> &'static str {
    if problem == "MHE" && lower == upper {
        ". A zero-width interval fixes that variable: for noise that enters some states (or \
         outputs) only, give `plant.e` (`plant.f`) only the columns that carry noise and drop \
         the fixed components from `sets.disturbance` (docs/scenario-format.md, [plant])"
    } else {
        ""
    }
}

/// Errors of the linear stability analysis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LinearError {
    /// The loop could not be built (scenario, MHE, MPC).
    #[error(transparent)]
    Build(#[from] ClosedLoopError),
    /// A bound of Z passes through or excludes 0, so the inactive region has no point near
    /// the origin to linearise at.
    #[error(
        "0 is not an interior point of the {problem} QP's box (component {index}: [{lower}, {upper}]); \
         the linear analysis needs a neighbourhood of the origin where no bound is active{}",
        zero_width_hint(problem, *lower, *upper)
    )]
    OriginNotInterior {
        /// `"MHE"` or `"MPC"`.
        problem: &'static str,
        /// Component of z.
        index: usize,
        /// Its lower bound.
        lower: f64,
        /// Its upper bound.
        upper: f64,
    },
    /// A probe of the iteration map reached a bound (the map is not affine there).
    #[error(
        "probing the {problem} iteration map reached a bound at component {index}; the map is not \
         affine there (a box of width ~1e-6 relative, or a badly scaled problem)"
    )]
    ProbeActive {
        /// `"MHE"` or `"MPC"`.
        problem: &'static str,
        /// Component of z.
        index: usize,
    },
    /// K = 0 (or an empty grid).
    #[error("the iteration budget K must be ≥ 1 and the K grid non-empty")]
    ZeroIterations,
    /// A NaN or ∞ in a linearised map.
    #[error("{what} has a non-finite entry (K = {k})")]
    NonFinite {
        /// Which map.
        what: &'static str,
        /// K (0 for the one-step probe).
        k: usize,
    },
    /// The eigenvalue solver failed.
    #[error("the eigenvalues of the {dim} × {dim} lifted matrix did not converge")]
    Eigenvalues {
        /// dim X.
        dim: usize,
    },
    /// The estimated time of ρ_lin on the K grid exceeds the analysis budget.
    #[error(
        "not computed: ρ_lin of {loops} method(s) on {ks} K of the {dim} × {dim} lifted matrix is \
         estimated at ≈ {} s of one core > the analysis budget of {} s (scenario key \
         `certificate.phase_seconds`; raise it to compute ρ_lin)",
        crate::budget::secs(*seconds),
        crate::budget::secs(*limit)
    )]
    OverBudget {
        /// dim X.
        dim: usize,
        /// Number of K on the grid.
        ks: usize,
        /// Number of loops (methods) analysed together.
        loops: usize,
        /// The estimate (seconds of one core).
        seconds: f64,
        /// The budget.
        limit: f64,
    },
    /// A structural invariant of the built objects does not hold (a bug, not bad input).
    #[error("internal: {0}")]
    Internal(&'static str),
}

/// ρ_lin on a K grid for one solver, with K_lin and every unstable K.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct LinearReport {
    /// Φ of the MHE.
    pub solver: Method,
    /// dim X of the lifted system.
    pub dim: usize,
    /// (K, ρ_lin(K)) for every K of the grid, ascending.
    pub rho_lin: Vec<(usize, f64)>,
    /// K_lin: the smallest grid K from which ρ_lin < 1 on the whole grid above (None if
    /// ρ_lin ≥ 1 at the largest K).
    pub k_lin: Option<usize>,
    /// Every grid K with ρ_lin(K) ≥ 1 (ρ_lin need not be monotone in K).
    pub unstable_ks: Vec<usize>,
}

impl LinearReport {
    /// Builds the report from (K, ρ) pairs (sorted by K, duplicates dropped).
    pub fn from_pairs(solver: Method, dim: usize, mut rho_lin: Vec<(usize, f64)>) -> Self {
        rho_lin.sort_by_key(|p| p.0);
        rho_lin.dedup_by_key(|p| p.0);
        let unstable_ks: Vec<usize> = rho_lin
            .iter()
            .filter(|p| !(p.1 < 1.0))
            .map(|p| p.0)
            .collect();
        let k_lin = match rho_lin.iter().rposition(|p| !(p.1 < 1.0)) {
            None => rho_lin.first().map(|p| p.0),
            Some(i) => rho_lin.get(i + 1).map(|p| p.0),
        };
        Self {
            solver,
            dim,
            rho_lin,
            k_lin,
            unstable_ks,
        }
    }
}

impl LiftedLoop {
    /// ρ_lin(K) for every K of `k_grid` and the report.
    pub fn report(&self, k_grid: &[usize], par: Par) -> Result<LinearReport, LinearError> {
        if k_grid.is_empty() || k_grid.contains(&0) {
            return Err(LinearError::ZeroIterations);
        }
        let mut grid = k_grid.to_vec();
        grid.sort_unstable();
        grid.dedup();
        let pairs = self.spectral_radii(&grid, par, &mut |_| {})?;
        Ok(LinearReport::from_pairs(self.solver(), self.dim(), pairs))
    }
}

/// ρ_lin(K) on `k_grid` for the loop [`ResolvedScenario::build_loop`] builds from
/// `resolved` and `options` (its method and controller; its K, seed, T and exact-solve flag
/// do not matter). The noise is irrelevant to 𝔸(K) and is set to zero for the build, so a
/// scenario whose noise cannot be drawn still has a linear analysis.
///
/// ```no_run
/// use iss_certificate::linear::linear_stability;
/// use closed_loop::scenario::{LoopOptions, Scenario};
/// use iss_certificate::linear::log_spaced;
/// let s = Scenario::from_file("scenarios/case-study-certified.toml").unwrap().resolve().unwrap();
/// let mut o = LoopOptions::from_scenario(s.scenario()).unwrap();
/// o.method = qp_iter::Method::FISTA;
/// let r = linear_stability(&s, &o, &log_spaced(1, 2000, 16), faer::Par::Seq).unwrap();
/// println!("K_lin = {:?}, unstable at {:?}", r.k_lin, r.unstable_ks);
/// ```
pub fn linear_stability(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    k_grid: &[usize],
    par: Par,
) -> Result<LinearReport, LinearError> {
    if k_grid.is_empty() || k_grid.contains(&0) {
        return Err(LinearError::ZeroIterations);
    }
    lifted_loop(resolved, options, k_grid[0], par)?.report(k_grid, par)
}

/// The lifted loop of `options` on the noise-free copy of `resolved` (module docs).
fn lifted_loop(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    k: usize,
    par: Par,
) -> Result<LiftedLoop, LinearError> {
    let mut quiet = resolved.clone();
    quiet.set_noise_scale(0.0);
    let mut opts = options.with_iterations(k)?;
    opts.steps = 1;
    opts.exact_mhe_solve = false;
    let cl = quiet.build_loop(&opts)?;
    LiftedLoop::from_loop(&cl, &quiet, opts.method, par)
}

/// [`linear_stability`] for several loops (e.g. one per method) on one grid, one loop per
/// task on the global rayon pool (its K-step maps shared along the grid). Each ρ_lin is
/// computed sequentially inside, so the results do not depend on the thread count.
pub fn linear_stability_all(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    k_grid: &[usize],
) -> Vec<Result<LinearReport, LinearError>> {
    linear_stability_all_budgeted(resolved, options, k_grid, f64::INFINITY, &|_, _| {})
}

/// [`linear_stability_all`] with a time budget: when the estimated time of all loops on the
/// grid ([`LiftedLoop::grid_work`] at [`crate::budget::DENSE_RATE`]) exceeds
/// `phase_seconds`, none is computed ([`LinearError::OverBudget`], naming the scenario key);
/// `progress(done, total)` is called after each (loop, K) (from the worker threads).
pub fn linear_stability_all_budgeted(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    k_grid: &[usize],
    phase_seconds: f64,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Vec<Result<LinearReport, LinearError>> {
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    if k_grid.is_empty() || k_grid.contains(&0) {
        return options
            .iter()
            .map(|_| Err(LinearError::ZeroIterations))
            .collect();
    }
    // A lower bound from the scenario's dimensions (every map's state has ≥ n_z entries):
    // beyond the budget nothing is built (building the loops alone costs seconds at n_z ~ 10³).
    let sc = resolved.scenario();
    if let Some(spec) = sc.mhe.as_ref() {
        let (p, m) = (&sc.plant, spec.horizon());
        let dims = LiftedDims {
            nx: p.nx(),
            nu: p.nu(),
            ny: p.ny(),
            horizon: m,
            nz: p.nx() + m * (p.nw1() + p.nw2()),
            n_controller: 0,
            n_theta: p.nx() + m * (p.nu() + p.ny()),
        };
        let seconds =
            options.len() as f64 * dims.grid_work(dims.nz, k_grid) / crate::budget::DENSE_RATE;
        if seconds > phase_seconds {
            let over = LinearError::OverBudget {
                dim: dims.dim(),
                ks: k_grid.len(),
                loops: options.len(),
                seconds,
                limit: phase_seconds,
            };
            return options.iter().map(|_| Err(over.clone())).collect();
        }
    }
    let mut lifted: Vec<Result<LiftedLoop, LinearError>> = options
        .par_iter()
        .map(|o| lifted_loop(resolved, o, k_grid[0], Par::Seq))
        .collect();
    let built: Vec<&LiftedLoop> = lifted.iter().filter_map(|l| l.as_ref().ok()).collect();
    let seconds =
        built.iter().map(|l| l.grid_work(k_grid)).sum::<f64>() / crate::budget::DENSE_RATE;
    if seconds > phase_seconds {
        let over = LinearError::OverBudget {
            dim: built.iter().map(|l| l.dim()).max().unwrap_or(0),
            ks: k_grid.len(),
            loops: built.len(),
            seconds,
            limit: phase_seconds,
        };
        for l in &mut lifted {
            if l.is_ok() {
                *l = Err(over.clone());
            }
        }
    }
    let mut grid = k_grid.to_vec();
    grid.sort_unstable();
    grid.dedup();
    let total = grid.len() * lifted.iter().filter(|l| l.is_ok()).count();
    let done = AtomicUsize::new(0);
    // One loop per task, its K walked upwards (the K-step maps shared along the grid); each
    // ρ_lin is computed sequentially inside, so the results do not depend on the thread count.
    lifted
        .into_par_iter()
        .map(|l| {
            let l = l?;
            let pairs = l.spectral_radii(&grid, Par::Seq, &mut |_| {
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            })?;
            Ok(LinearReport::from_pairs(l.solver(), l.dim(), pairs))
        })
        .collect()
}
