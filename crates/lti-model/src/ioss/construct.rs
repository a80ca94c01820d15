//! Construction of the extremal P of LMI (2): covariance-form start from P = +∞, value
//! iteration of U, and the fictitious-disturbance variant for an E that does not reach
//! every state (module doc of [`crate::ioss`], "Construction").

use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef};

use crate::error::Result;
use crate::matrix::symmetrize;
use crate::system::LtiSystem;

use super::IossOptions;
use super::check::stacked;
use super::doubling::{Doubling, balance, invert_covariance, maximal_covariance};

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

/// The maximal solution P* of LMI (2): for η = 0 one application of U (exact, U does not
/// depend on P); for η > 0 the doubling algorithm on the balanced, normalised data
/// ([`super::doubling`]), tightened by a relative ε so that P passes the relative check with
/// margin (module doc, "Construction at any scale"), then one value-iteration step U as a
/// polish. Every candidate is measured against the user's data; the first that passes is
/// returned.
pub(super) fn extremal_solution(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    opts: &IossOptions,
) -> Result<Extremal> {
    if eta == 0.0 {
        return zero_eta_solution(sys, q, r, opts);
    }
    let scaled = balance(sys, q, r)?;
    let margin = (opts.lmi_relative_tolerance * (2.0 + 1.0 / eta)).min(1e-6);
    let mut outcome = Extremal::Unreached;
    for eps in [margin, 0.0] {
        let tight = 1.0 - eps;
        let (q_t, r_t) = (&scaled.q * tight, &scaled.r * tight);
        let x = match maximal_covariance(
            &scaled.sys,
            eta * tight,
            q_t.as_ref(),
            r_t.as_ref(),
            opts.max_iterations,
        ) {
            Doubling::Converged { x, steps } => (x, steps),
            Doubling::NotConverged { steps } => {
                outcome = Extremal::NotConverged { iterations: steps };
                continue;
            }
            Doubling::Failed => continue,
        };
        let (x, steps) = x;
        let Some(p_scaled) = invert_covariance(&x)? else {
            // X singular: P = +∞ on ker X (E does not reach every state).
            outcome = Extremal::Unreached;
            continue;
        };
        // Polish: one step of U on the tightened, scaled data (U(P*) = P*; it removes the
        // rounding of the inversion).
        let polished = apply_u(
            &scaled.sys,
            eta * tight,
            q_t.as_ref(),
            r_t.as_ref(),
            p_scaled.as_ref(),
        )
        .unwrap_or(p_scaled);
        let p = scaled.unscale(polished.as_ref());
        let check = super::assess(sys, eta, q, r, p.as_ref(), opts)?;
        if check.passed() {
            return Ok(Extremal::Found {
                p,
                iterations: steps + 1,
            });
        }
        outcome = if check.p_ratio().is_some_and(|r| r > opts.min_condition) {
            Extremal::Found {
                p,
                iterations: steps + 1,
            }
        } else {
            let (min_eigenvalue, max_eigenvalue) = check.singular_pair();
            Extremal::Singular {
                min_eigenvalue,
                max_eigenvalue,
            }
        };
    }
    Ok(outcome)
}

/// η = 0: U(P) does not depend on P, so P = U(I) is the maximal solution.
fn zero_eta_solution(
    sys: &LtiSystem,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    opts: &IossOptions,
) -> Result<Extremal> {
    let nx = sys.nx();
    let Some(p) = apply_u(sys, 0.0, q, r, Mat::<f64>::identity(nx, nx).as_ref()) else {
        return Ok(Extremal::KktSingular { iteration: 0 });
    };
    let check = super::assess(sys, 0.0, q, r, p.as_ref(), opts)?;
    if !check.p_ratio().is_some_and(|r| r > opts.min_condition) {
        let (min_eigenvalue, max_eigenvalue) = check.singular_pair();
        return Ok(Extremal::Singular {
            min_eigenvalue,
            max_eigenvalue,
        });
    }
    Ok(Extremal::Found { p, iterations: 1 })
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
