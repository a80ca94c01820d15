//! Construction of the extremal P of LMI (2): covariance-form start from P = +∞, value
//! iteration of U, and the fictitious-disturbance variant for an E that does not reach
//! every state (module doc of [`crate::ioss`], "Construction").

use faer::linalg::solvers::{DenseSolveCore, Solve};
use faer::{Mat, MatRef};

use crate::error::Result;
use crate::matrix::{sym_extreme_eigenvalues, symmetrize};
use crate::system::LtiSystem;

use super::IossOptions;
use super::check::stacked;

/// λ_min(X)/λ_max(X) at which the covariance phase stops early: X is then inverted into a
/// well-conditioned start P₀ = X⁻¹ of the value iteration.
const COVARIANCE_STOP_RATIO: f64 = 1e-6;

/// Outcome of [`extremal_solution`].
#[derive(Debug, Clone)]
pub(super) enum Extremal {
    /// Converged to a P ≻ 0 (relative to `min_condition`): the maximal solution.
    Found { p: Mat<f64>, iterations: usize },
    /// The covariance phase did not reach every state: X_k stayed singular for k ≤ n_x + 1
    /// (E does not excite every mode of A), so no finite start P₀ ⪰ P* exists.
    Unreached,
    /// The iterates converge to (or reach) a numerically singular P.
    Singular {
        min_eigenvalue: f64,
        max_eigenvalue: f64,
    },
    /// No convergence within `max_iterations` (P still ≻ 0).
    NotConverged { iterations: usize },
    /// The KKT system of U was singular at this iteration.
    KktSingular { iteration: usize },
}

/// X₁ = B̄M⁻¹B̄ᵀ with M = Q + D̄ᵀRD̄: the covariance-form image of P = +∞
/// (U(+∞) = X₁⁻¹ when E has full row rank). Returns None if M is numerically singular.
pub(super) fn first_covariance(
    sys: &LtiSystem,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
) -> Option<Mat<f64>> {
    let bbar = sys.b_bar();
    let dbar = sys.d_bar();
    let m = q.to_owned() + dbar.transpose() * r * &dbar;
    let sol = m.partial_piv_lu().solve(bbar.transpose());
    let x = symmetrize((&bbar * sol).as_ref());
    x.norm_max().is_finite().then_some(x)
}

/// One covariance-form step X ↦ U(X⁻¹)⁻¹ = GΨ⁻¹Gᵀ for η > 0, with
/// Ψ⁻¹ = Σ − ΣHᵀ(R⁻¹ + HΣHᵀ)⁻¹HΣ, Σ = diag(X/η, Q⁻¹) (Woodbury): no inverse of X, so
/// X may be singular (P = +∞ on ker X).
fn covariance_step(
    g: &Mat<f64>,
    h: &Mat<f64>,
    eta: f64,
    q_inv: &Mat<f64>,
    r_inv: &Mat<f64>,
    x: &Mat<f64>,
) -> Option<Mat<f64>> {
    let nx = x.nrows();
    let nz = g.ncols();
    let sigma = Mat::from_fn(nz, nz, |a, b| match (a < nx, b < nx) {
        (true, true) => x[(a, b)] / eta,
        (false, false) => q_inv[(a - nx, b - nx)],
        _ => 0.0,
    });
    let sht = &sigma * h.transpose();
    let t = h * &sht + r_inv;
    let psi_inv = &sigma - &sht * t.partial_piv_lu().solve(sht.transpose());
    let next = symmetrize((g * psi_inv * g.transpose()).as_ref());
    next.norm_max().is_finite().then_some(next)
}

/// Start of the value iteration: P₀ = X_k⁻¹ = Uᵏ(+∞) ⪰ every feasible P, from the
/// covariance phase X₀ = 0, X_{k+1} = U(X_k⁻¹)⁻¹ (k ≤ n_x + 1, stopping once X_k is
/// well conditioned). None if X_k stays singular relative to `min_condition`.
fn start_from_above(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    min_condition: f64,
) -> Result<Option<Mat<f64>>> {
    let nx = sys.nx();
    if eta == 0.0 {
        // U(P) does not depend on P when η = 0 (the x term has weight 0): any start works.
        return Ok(Some(Mat::identity(nx, nx)));
    }
    let (g, h) = stacked(sys);
    let q_inv = q.to_owned().partial_piv_lu().inverse();
    let r_inv = r.to_owned().partial_piv_lu().inverse();
    let mut x = Mat::<f64>::zeros(nx, nx);
    let (mut lo, mut hi) = (0.0, 0.0);
    for _ in 0..=nx {
        let Some(next) = covariance_step(&g, &h, eta, &q_inv, &r_inv, &x) else {
            return Ok(None);
        };
        x = next;
        (lo, hi) = sym_extreme_eigenvalues("X", x.as_ref())?;
        if hi > 0.0 && lo > COVARIANCE_STOP_RATIO * hi {
            break;
        }
    }
    if !(hi > 0.0 && lo > min_condition * hi) {
        return Ok(None);
    }
    let p0 = x.partial_piv_lu().inverse();
    Ok(p0.norm_max().is_finite().then(|| symmetrize(p0.as_ref())))
}

/// One application of U (module doc): the multiplier block of the KKT system
/// [[Ψ, Gᵀ], [G, 0]] with Ψ = diag(ηP, Q) + HᵀRH is −U(P). None if singular.
fn apply_u(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
) -> Option<Mat<f64>> {
    let (nx, nw) = (sys.nx(), sys.nw());
    let nz = nx + nw;
    let (g, h) = stacked(sys);
    let psi = h.transpose() * r * &h;
    let mut kkt = Mat::<f64>::zeros(nz + nx, nz + nx);
    kkt.as_mut().submatrix_mut(0, 0, nz, nz).copy_from(&psi);
    for a in 0..nx {
        for b in 0..nx {
            kkt[(a, b)] += eta * p[(a, b)];
        }
    }
    for a in 0..nw {
        for b in 0..nw {
            kkt[(nx + a, nx + b)] += q[(a, b)];
        }
    }
    for i in 0..nx {
        for j in 0..nz {
            kkt[(nz + i, j)] = g[(i, j)];
            kkt[(j, nz + i)] = g[(i, j)];
        }
    }
    let rhs = Mat::from_fn(nz + nx, nx, |i, j| if i == nz + j { 1.0 } else { 0.0 });
    let sol = kkt.partial_piv_lu().solve(&rhs);
    let u = Mat::from_fn(nx, nx, |i, j| -sol[(nz + i, j)]);
    u.norm_max().is_finite().then(|| symmetrize(u.as_ref()))
}

/// The maximal solution P* of LMI (2) by value iteration from P₀ = Uᵏ(+∞).
pub(super) fn extremal_solution(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    opts: &IossOptions,
) -> Result<Extremal> {
    let Some(mut p) = start_from_above(sys, eta, q, r, opts.min_condition)? else {
        return Ok(Extremal::Unreached);
    };
    let nx = sys.nx();
    let mut iterations = 0;
    let mut converged = false;
    for k in 0..opts.max_iterations {
        let Some(next) = apply_u(sys, eta, q, r, p.as_ref()) else {
            return Ok(Extremal::KktSingular { iteration: k });
        };
        let mut diff = 0.0_f64;
        for i in 0..nx {
            for j in 0..nx {
                diff = diff.max((next[(i, j)] - p[(i, j)]).abs());
            }
        }
        let scale = p.norm_max();
        p = next;
        iterations = k + 1;
        if diff <= opts.tolerance * scale {
            converged = true;
            break;
        }
    }
    let (lo, hi) = sym_extreme_eigenvalues("P", p.as_ref())?;
    if !(hi > 0.0 && lo > opts.min_condition * hi) {
        return Ok(Extremal::Singular {
            min_eigenvalue: lo,
            max_eigenvalue: hi,
        });
    }
    if !converged {
        return Ok(Extremal::NotConverged { iterations });
    }
    Ok(Extremal::Found { p, iterations })
}

/// The system and weights with a fictitious disturbance w³ entering every state:
/// E' = [E, I], w' = (w¹, w³, w²), Q' = [[Q₁₁, 0, Q₁₂], [0, q₃I, 0], [Q₂₁, 0, Q₂₂]].
/// LMI (2) of the result contains LMI (2) of `sys` as its principal submatrix (rows and
/// columns of w³ deleted), so a P that satisfies the former satisfies the latter.
pub(super) fn with_fictitious_disturbance(
    sys: &LtiSystem,
    q: MatRef<'_, f64>,
    q3: f64,
) -> Result<(LtiSystem, Mat<f64>)> {
    let (nx, nw1, nw2) = (sys.nx(), sys.nw1(), sys.nw2());
    let e = Mat::from_fn(nx, nw1 + nx, |i, j| {
        if j < nw1 {
            sys.e()[(i, j)]
        } else if j - nw1 == i {
            1.0
        } else {
            0.0
        }
    });
    let aug = LtiSystem::with_disturbance(
        sys.a().to_owned(),
        sys.b().to_owned(),
        sys.c().to_owned(),
        e,
        sys.f().to_owned(),
    )?;
    // Index of an augmented disturbance entry in the original w, or None for w³.
    let orig = |i: usize| -> Option<usize> {
        if i < nw1 {
            Some(i)
        } else if i < nw1 + nx {
            None
        } else {
            Some(i - nx)
        }
    };
    let n = nw1 + nx + nw2;
    let q_aug = Mat::from_fn(n, n, |a, b| match (orig(a), orig(b)) {
        (Some(i), Some(j)) => q[(i, j)],
        (None, None) if a == b => q3,
        _ => 0.0,
    });
    Ok((aug, q_aug))
}
