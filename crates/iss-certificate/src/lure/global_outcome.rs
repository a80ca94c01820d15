//! The global loop certificate as one typed outcome per (scenario, method), budgeted
//! (docs/theory.md §4; issue 35): what `cargo xtask certify` prints and writes.
//!
//! [`GlobalLoop`]'s LMI depends on the method only through the weights D⁻¹ of the
//! norm in which φ(K) holds (plain or Jacobi), so φ* is searched once per norm and
//! K_glob = min{K : φ_method(K) ≤ φ*} per method. Where no φ ≥ 0 is certified the outcome
//! says what binds, from two cheap extra checks: the same loop with every box dropped at
//! φ = 0 (only the optimum's one-multiplier VI differs), and the spectral radius of that
//! exact-MHE linear loop (Theorem L3 (ii): ρ_lin ≥ 1 excludes every certificate).

use closed_loop::scenario::{LoopOptions, ResolvedScenario};
use faer::Par;

use super::global::{GlobalLoop, GlobalOptions, global_loop, global_loop_with};
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
}

/// Estimated single-core seconds of one φ* search on a loop of dim ζ = `n_zeta`, dim X =
/// `n_x`, with `tau_calls` multiplier pairs per failed φ: a doubling Riccati (≈ 25 doublings
/// of ≈ 8·n_X³) and two Jacobi eigenvalue checks (scalar loops, ≈ 120·n_ζ³ at 1/20 of the
/// dense rate) per call, and 2·(`tau_calls` + 1) calls — calibrated on the double
/// integrator (n_ζ = 126: 4.6 s of CPU for both norms and the rest of `certify --loop`,
/// estimate 5.8 s; docs/certificate-coverage.md).
pub fn search_seconds(n_zeta: usize, n_x: usize, tau_calls: usize) -> f64 {
    let (nz, nx) = (n_zeta as f64, n_x as f64);
    let per_call = 25.0 * 8.0 * nx.powi(3) + 20.0 * 120.0 * nz.powi(3);
    let calls = 2.0 * (tau_calls as f64 + 1.0);
    calls * per_call / DENSE_RATE
}

/// The global outcome of every loop in `options` (one per method) on `resolved`, in order.
/// φ* is searched once per norm (loops with equal weights D⁻¹ share it); the searches run
/// only if their total estimate is within `settings.phase_seconds`.
pub fn global_outcomes(
    resolved: &ResolvedScenario,
    options: &[LoopOptions],
    settings: &GlobalSettings,
) -> Vec<GlobalOutcome> {
    let loops: Vec<Result<GlobalLoop, GlobalOutcome>> = options
        .iter()
        .map(|o| {
            global_loop(resolved, o).map_err(|e| GlobalOutcome::Unsupported {
                reason: e.to_string(),
            })
        })
        .collect();
    // One search per distinct norm: `norms` holds the first loop of each, `norm_of[i]` the
    // norm of loop i.
    let mut norms: Vec<usize> = Vec::new();
    let mut norm_of: Vec<Option<usize>> = Vec::with_capacity(loops.len());
    for (i, l) in loops.iter().enumerate() {
        norm_of.push(l.as_ref().ok().map(|g| {
            let same = |&j: &usize| loops[j].as_ref().is_ok_and(|h| h.d_inv == g.d_inv);
            norms.iter().position(same).unwrap_or_else(|| {
                norms.push(i);
                norms.len() - 1
            })
        }));
    }
    let estimate: f64 = norms
        .iter()
        .filter_map(|&i| loops[i].as_ref().ok())
        .map(|g| search_seconds(g.n_zeta(), g.n_x(), tau_calls(g, &settings.search)))
        .sum();
    if estimate > settings.phase_seconds {
        let n_zeta = norms
            .iter()
            .filter_map(|&i| loops[i].as_ref().ok())
            .map(GlobalLoop::n_zeta)
            .max()
            .unwrap_or(0);
        let over = GlobalOutcome::NotComputed {
            n_zeta,
            estimate_seconds: estimate,
            budget_seconds: settings.phase_seconds,
        };
        return loops
            .into_iter()
            .map(|l| l.err().unwrap_or_else(|| over.clone()))
            .collect();
    }
    let stars: Vec<Result<GlobalK, GlobalOutcome>> = norms
        .iter()
        .map(|&i| match &loops[i] {
            Ok(g) => phi_star_or_why(resolved, &options[i], g, &settings.search),
            Err(e) => Err(e.clone()),
        })
        .collect();
    loops
        .iter()
        .zip(&norm_of)
        .map(|(l, n)| match (l, n) {
            (Err(e), _) => e.clone(),
            (Ok(g), Some(n)) => match &stars[*n] {
                Ok(star) => k_glob_of(g, star, settings.search.k_max),
                Err(why) => why.clone(),
            },
            (Ok(_), None) => GlobalOutcome::Unsupported {
                reason: "internal: a loop without a norm".into(),
            },
        })
        .collect()
}

/// Multiplier pairs tried per φ (τ₁ only with a bounded MHE coordinate, τ₃ only with an
/// input bound).
fn tau_calls(g: &GlobalLoop, opts: &GlobalOptions) -> usize {
    let k = opts.tau_points.max(2);
    let t3 = if g.has_mpc_channel() { k } else { 1 };
    k * t3
}

/// φ* of `g`'s norm with its certificate (K fields filled per method later), or what binds.
fn phi_star_or_why(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    g: &GlobalLoop,
    opts: &GlobalOptions,
) -> Result<GlobalK, GlobalOutcome> {
    if let Some(c) = g.phi_star(opts) {
        return Ok(GlobalK {
            k_glob: 0,
            phi_star: c.phi,
            phi_at_k: f64::NAN,
            margin: c.margin,
            rho: c.rho,
            gamma: c.gamma,
            gain_x: c.gain_x,
            gain_e: c.gain_e,
        });
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
