//! The check of one P against LMI (2), relative to the scale of the LMI's own terms
//! (module doc of [`crate::ioss`], "Verification").

use faer::{Mat, MatRef, Side};

use crate::error::{LmiFailure, ModelError, Result};
use crate::matrix::{
    SYMMETRY_TOL, asymmetry, check_finite, check_shape, sym_eigenvalues, symmetrize,
};
use crate::system::LtiSystem;

use super::{IossOptions, check_inputs};

/// G = [A B̄] (n_x × (n_x + n_w)) and H = [C D̄] (n_y × (n_x + n_w)): LMI (2) is
/// J = GᵀPG − diag(ηP, Q) − HᵀRH.
pub(super) fn stacked(sys: &LtiSystem) -> (Mat<f64>, Mat<f64>) {
    let nx = sys.nx();
    let nz = nx + sys.nw();
    let (bbar, dbar) = (sys.b_bar(), sys.d_bar());
    let g = Mat::from_fn(nx, nz, |i, j| {
        if j < nx {
            sys.a()[(i, j)]
        } else {
            bbar[(i, j - nx)]
        }
    });
    let h = Mat::from_fn(sys.ny(), nz, |i, j| {
        if j < nx {
            sys.c()[(i, j)]
        } else {
            dbar[(i, j - nx)]
        }
    });
    (g, h)
}

/// The LMI matrix J of (2) and its scale matrix S, both exactly symmetric:
///
/// J = GᵀPG − diag(ηP, Q) − HᵀRH,  S = GᵀPG + diag(P, Q) + HᵀRH.
fn lmi_and_scale(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
) -> (Mat<f64>, Mat<f64>) {
    let (nx, nw) = (sys.nx(), sys.nw());
    let (g, h) = stacked(sys);
    let gpg = g.transpose() * p * &g;
    let hrh = h.transpose() * r * &h;
    let mut j = &gpg - &hrh;
    let mut s = &gpg + &hrh;
    for a in 0..nx {
        for b in 0..nx {
            j[(a, b)] -= eta * p[(a, b)];
            s[(a, b)] += p[(a, b)];
        }
    }
    for a in 0..nw {
        for b in 0..nw {
            j[(nx + a, nx + b)] -= q[(a, b)];
            s[(nx + a, nx + b)] += q[(a, b)];
        }
    }
    (symmetrize(j.as_ref()), symmetrize(s.as_ref()))
}

/// J and S of [`lmi_and_scale`] in the coordinates z̃ = (x, w¹, v, ξ) with v = Cx + Fw²
/// the output residual and ξ the part of w² that F does not see, or None when F does not
/// have full row rank (σ_min(F) ≤ [`SPLIT_MIN_SV`]·σ_max(F)), F is empty, or the SVD
/// fails.
///
/// With F = UΣVᵀ = U[Σ₁ 0][V₁ V₂]ᵀ and K = V₁Σ₁⁻¹Uᵀ (FK = I, FV₂ = 0), w² = K(v − Cx) + V₂ξ
/// is z = T z̃ with T invertible, so J̃ = TᵀJT and S̃ = TᵀST (a congruence: μ is the same).
/// In these coordinates H T = [0, 0, I, 0]: the output term is diag(0, 0, R, 0) exactly, on
/// coordinates of its own, instead of the rank-n_y term HᵀRH spread over every row of J. For
/// R much larger than Q (or Q much smaller than R) that term is what rounds away the terms
/// of size Q and P in J (issue 37, item 4: `mhe.r = 1e12` measured μ = 6.7e-6 for a valid
/// P); here every term is formed on its own scale and the Jacobi scaling of the pencil
/// separates them. K and V₂ come from an SVD: the rounding is a relative perturbation of F
/// of order u, far below τ.
fn lmi_and_scale_split(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
) -> Option<(Mat<f64>, Mat<f64>)> {
    let (nx, nw1, nw2, ny) = (sys.nx(), sys.nw1(), sys.nw2(), sys.ny());
    if ny == 0 || nw2 < ny {
        return None;
    }
    let f = sys.f();
    let svd = f.to_owned().svd().ok()?;
    let sv = svd.S().column_vector();
    let smax = (0..ny).map(|i| sv[i]).fold(0.0, f64::max);
    if !(0..ny).all(|i| sv[i] > SPLIT_MIN_SV * smax) {
        return None;
    }
    let (u, v) = (svd.U(), svd.V());
    // K = V₁Σ₁⁻¹Uᵀ (n_w2 × n_y), V₂ (n_w2 × (n_w2 − n_y)).
    let k = Mat::from_fn(nw2, ny, |i, j| {
        (0..ny).map(|l| v[(i, l)] / sv[l] * u[(j, l)]).sum::<f64>()
    });
    let kc = &k * sys.c();
    let nz = nx + nw1 + nw2;
    // z̃ = (x, w¹, v, ξ): column offsets.
    let (ow1, ov, oxi) = (nx, nx + nw1, nx + nw1 + ny);
    // G̃ = G T = [A, E, 0, 0].
    let g = Mat::from_fn(nx, nz, |i, j| {
        if j < nx {
            sys.a()[(i, j)]
        } else if j < ov {
            sys.e()[(i, j - ow1)]
        } else {
            0.0
        }
    });
    // L = the w-rows of T: w¹ = w¹, w² = −KCx + Kv + V₂ξ.
    let l = Mat::from_fn(nw1 + nw2, nz, |i, j| {
        if i < nw1 {
            f64::from(u8::from(j == ow1 + i))
        } else {
            let i2 = i - nw1;
            if j < nx {
                -kc[(i2, j)]
            } else if j < ov {
                0.0
            } else if j < oxi {
                k[(i2, j - ov)]
            } else {
                v[(i2, ny + j - oxi)]
            }
        }
    });
    let gpg = g.transpose() * p * &g;
    let lql = l.transpose() * q * &l;
    let mut j = &gpg - &lql;
    let mut s = &gpg + &lql;
    for a in 0..nx {
        for b in 0..nx {
            j[(a, b)] -= eta * p[(a, b)];
            s[(a, b)] += p[(a, b)];
        }
    }
    for a in 0..ny {
        for b in 0..ny {
            j[(ov + a, ov + b)] -= r[(a, b)];
            s[(ov + a, ov + b)] += r[(a, b)];
        }
    }
    Some((symmetrize(j.as_ref()), symmetrize(s.as_ref())))
}

/// The user's coordinates decide μ while their rounding estimate n·u·cond(Ŝ) is at most
/// this share of τ (a hundredth: the verdict cannot be moved by rounding).
const ROUNDING_SHARE: f64 = 1e-2;

/// F counts as having full row rank for [`lmi_and_scale_split`] when σ_min(F) >
/// SPLIT_MIN_SV·σ_max(F): K = F⁺ then has ‖K‖·‖F‖ < 1e8, so the SVD's rounding stays a
/// relative perturbation of F far below τ.
const SPLIT_MIN_SV: f64 = 1e-8;

/// The LMI matrix of (2) for a given P (⪯ 0 iff P certifies δ-IOSS with (η, Q, R)):
///
/// [[AᵀPA − ηP − CᵀRC, AᵀPB̄ − CᵀRD̄], [B̄ᵀPA − D̄ᵀRC, B̄ᵀPB̄ − Q − D̄ᵀRD̄]].
///
/// Shapes are the caller's contract (use [`super::verify`] or [`assess`] for untrusted
/// input); the result is exactly symmetric.
pub fn lmi_matrix(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
) -> Mat<f64> {
    lmi_and_scale(sys, eta, q, r, p).0
}

/// The scale matrix S(P) = GᵀPG + diag(P, Q) + HᵀRH ≻ 0 of the relative check: the sum
/// of the positive semidefinite terms LMI (2) is made of (with P in place of ηP, so that
/// S ≻ 0 also for η = 0). Shapes are the caller's contract.
pub fn lmi_scale_matrix(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
) -> Mat<f64> {
    lmi_and_scale(sys, eta, q, r, p).1
}

/// What the check of one P measured ([`assess`]).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct LmiCheck {
    /// λ_min(P).
    pub p_min_eigenvalue: f64,
    /// λ_max(P).
    pub p_max_eigenvalue: f64,
    /// The floor ρ: the Jacobi-scaled P̂ = diag(P)^{−½}·P·diag(P)^{−½} must have
    /// λ_min(P̂) > ρ·λ_max(P̂).
    pub p_min_ratio: f64,
    /// λ_min(P̂) of the Jacobi-scaled P̂ (None if a diagonal entry of P is not positive:
    /// P̂ does not exist, see `p_nonpositive_diagonal`).
    pub p_scaled_min_eigenvalue: Option<f64>,
    /// λ_max(P̂) of the Jacobi-scaled P̂ (None as `p_scaled_min_eigenvalue`).
    pub p_scaled_max_eigenvalue: Option<f64>,
    /// The first diagonal entry (index, value) of P that is not positive, if any: such a P
    /// is not positive definite.
    pub p_nonpositive_diagonal: Option<(usize, f64)>,
    /// All eigenvalues of the LMI matrix J, ascending.
    pub lmi_eigenvalues: Vec<f64>,
    /// λ_max(J), unscaled (reported; the test is on `relative_violation`).
    pub lmi_max_eigenvalue: f64,
    /// μ(P) = max_v vᵀJv / vᵀSv ∈ [−1, 1], computed in the output-residual coordinates
    /// (`lmi_and_scale_split`, F of full row rank) or the user's, whichever has the
    /// better-conditioned Jacobi-scaled S (the smaller rounding error); None when P is not
    /// positive definite (λ_min(P) ≤ 0: μ is defined for P ≻ 0 only). The verdict is on
    /// this value.
    pub relative_violation: Option<f64>,
    /// The same μ(P) computed from J and S in the user's coordinates (x, w), reported for
    /// comparison: with R ≫ Q its rounding error is ≈ u·r/q (issue 37, item 4), so it may
    /// exceed τ for a valid P. None as `relative_violation`.
    pub relative_violation_original_units: Option<f64>,
    /// τ: P passes when μ(P) ≤ τ.
    pub relative_tolerance: f64,
}

impl LmiCheck {
    /// λ_min(P̂)/λ_max(P̂) of the Jacobi-scaled P̂ = diag(P)^{−½}·P·diag(P)^{−½} (None if
    /// P has a non-positive diagonal entry, or λ_max(P̂) ≤ 0). Unlike λ_min(P)/λ_max(P) it does not change
    /// when the states change units (x = Tx̃, T diagonal), and it is what decides whether
    /// P ≻ 0 is resolvable in f64: the Jacobi-scaled matrix's eigenvalues are computed to
    /// ≈ n·u·λ_max(P̂).
    pub fn p_ratio(&self) -> Option<f64> {
        let (lo, hi) = self
            .p_scaled_min_eigenvalue
            .zip(self.p_scaled_max_eigenvalue)?;
        (hi > 0.0).then(|| lo / hi)
    }

    /// (λ_min, λ_max) of P̂ when it exists, else of P: the pair a singularity report names.
    pub(crate) fn singular_pair(&self) -> (f64, f64) {
        self.p_scaled_min_eigenvalue
            .zip(self.p_scaled_max_eigenvalue)
            .unwrap_or((self.p_min_eigenvalue, self.p_max_eigenvalue))
    }

    /// The first condition that fails, or `None` if P certifies LMI (2): every diagonal
    /// entry of P positive (else [`LmiFailure::PNonPositiveDiagonal`]), λ_min(P̂) >
    /// ρ·λ_max(P̂) (else [`LmiFailure::PNumericallySingular`]), then μ(P) ≤ τ (else
    /// [`LmiFailure::Violated`]).
    pub fn failure(&self) -> Option<LmiFailure> {
        if let Some((index, value)) = self.p_nonpositive_diagonal {
            return Some(LmiFailure::PNonPositiveDiagonal { index, value });
        }
        let singular = || {
            let (min_eigenvalue, max_eigenvalue) = self.singular_pair();
            LmiFailure::PNumericallySingular {
                min_eigenvalue,
                max_eigenvalue,
                min_ratio: self.p_min_ratio,
            }
        };
        if !self.p_ratio().is_some_and(|r| r > self.p_min_ratio) {
            return Some(singular());
        }
        match self.relative_violation {
            Some(mu) if mu <= self.relative_tolerance => None,
            Some(mu) => Some(LmiFailure::Violated {
                relative_violation: mu,
                tolerance: self.relative_tolerance,
                lmi_max_eigenvalue: self.lmi_max_eigenvalue,
            }),
            // λ_min(P) ≤ 0 although λ_min(P̂) > ρ·λ_max(P̂) > 0: the two eigen-solves
            // disagree in rounding, and P is not resolvably positive definite.
            None => Some(singular()),
        }
    }

    /// True iff [`LmiCheck::failure`] is `None`.
    pub fn passed(&self) -> bool {
        self.failure().is_none()
    }
}

/// Measures P against LMI (2) with the tolerances of `opts`, without deciding: the result
/// holds the eigenvalues of P and of J, μ(P) and the thresholds; [`LmiCheck::failure`]
/// says whether and why P fails. Use it to report a P that fails; [`super::verify_with`]
/// is the deciding form.
///
/// Errors only for bad input: η out of range, Q or R not symmetric positive definite, P
/// of the wrong shape, non-finite or not symmetric (relative to its own largest entry).
pub fn assess(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
    opts: &IossOptions,
) -> Result<LmiCheck> {
    check_inputs(sys, eta, q, r)?;
    check_shape("P", p, sys.nx(), sys.nx())?;
    check_finite("P", p)?;
    check_no_subnormal(p)?;
    let asym = asymmetry(p);
    if asym > SYMMETRY_TOL * p.norm_max() {
        return Err(ModelError::NotSymmetric {
            name: "P".into(),
            asymmetry: asym,
        });
    }
    let p = symmetrize(p);
    let p_eig = sym_eigenvalues("P", p.as_ref())?;
    let (p_min, p_max) = (p_eig[0], p_eig[p_eig.len() - 1]);
    let n = p.nrows();
    let p_nonpositive_diagonal = (0..n).map(|i| (i, p[(i, i)])).find(|&(_, v)| !(v > 0.0));
    let (p_scaled_min, p_scaled_max) = if p_nonpositive_diagonal.is_none() {
        let d: Vec<f64> = (0..n).map(|i| 1.0 / p[(i, i)].sqrt()).collect();
        let scaled = Mat::from_fn(n, n, |a, b| d[a] * p[(a, b)] * d[b]);
        let e = sym_eigenvalues("diag(P)^(-1/2) P diag(P)^(-1/2)", scaled.as_ref())?;
        (Some(e[0]), Some(e[n - 1]))
    } else {
        (None, None)
    };
    let (j, s) = lmi_and_scale(sys, eta, q, r, p.as_ref());
    let lmi_eigenvalues = sym_eigenvalues("LMI matrix", j.as_ref())?;
    let lmi_max_eigenvalue = lmi_eigenvalues.last().copied().unwrap_or(0.0);
    let (relative_violation, relative_violation_original_units) = if p_min > 0.0 {
        // μ is the same in both coordinate systems; its rounding error is ≈ n·u·cond(Ŝ)
        // (Ŝ the Jacobi-scaled S). The user's coordinates decide while that error is below
        // ROUNDING_SHARE·τ (so well-scaled problems give bit-identical results); beyond, the
        // better-conditioned of the two: the residual coordinates when R dominates Q, the
        // user's when Q dominates R (where eliminating w² cancels terms of size Q).
        let original = relative_violation(j.as_ref(), s.as_ref())?;
        let split = match lmi_and_scale_split(sys, eta, q, r, p.as_ref()) {
            Some((js, ss)) => relative_violation(js.as_ref(), ss.as_ref())?,
            None => original,
        };
        let dim = s.nrows() as f64;
        let resolved =
            dim * f64::EPSILON * original.1 <= ROUNDING_SHARE * opts.lmi_relative_tolerance;
        let chosen = if resolved || split.1 >= original.1 {
            original
        } else {
            split
        };
        (Some(chosen.0), Some(original.0))
    } else {
        (None, None)
    };
    Ok(LmiCheck {
        p_min_eigenvalue: p_min,
        p_max_eigenvalue: p_max,
        p_min_ratio: opts.min_condition,
        p_scaled_min_eigenvalue: p_scaled_min,
        p_scaled_max_eigenvalue: p_scaled_max,
        p_nonpositive_diagonal,
        lmi_eigenvalues,
        lmi_max_eigenvalue,
        relative_violation,
        relative_violation_original_units,
        relative_tolerance: opts.lmi_relative_tolerance,
    })
}

/// A subnormal entry of P (0 < |p_ij| < 2.2e-308) is refused, naming it (issue 37, item
/// 14a: the eigen-solvers did not converge on it and the user read "NoConvergence"). It is
/// not flushed to 0 silently: the check must be of the P the user gave, and such an entry is
/// almost always a solver's or a writer's artefact that is best written as 0.
fn check_no_subnormal(p: MatRef<'_, f64>) -> Result<()> {
    for i in 0..p.nrows() {
        for j in 0..p.ncols() {
            let value = p[(i, j)];
            if value.is_subnormal() {
                return Err(ModelError::Scenario {
                    key: "mhe.p".into(),
                    problem: format!(
                        "P entry ({i}, {j}) = {value:e} is subnormal (0 < |x| < {:e}), and the \
                         eigen-solvers of the LMI (2) check do not converge on subnormal \
                         numbers; write 0 there (in `mhe.p` or the --p-file), or rescale P, Q \
                         and R together",
                        f64::MIN_POSITIVE
                    ),
                });
            }
        }
    }
    Ok(())
}

/// μ = λ_max of the pencil (J, S) for S ≻ 0 (NaN if S is singular to working precision): with the Jacobi scaling D = diag(S)^{−½}
/// and DSD = VΛVᵀ, μ = λ_max(Λ^{−½}VᵀDJDVΛ^{−½}). The scaling changes nothing
/// mathematically (a congruence) and makes the rounding relative to each row's own scale.
///
/// Returns (μ, cond(DSD)); μ's rounding error is ≈ n·u·cond(DSD).
fn relative_violation(j: MatRef<'_, f64>, s: MatRef<'_, f64>) -> Result<(f64, f64)> {
    let n = s.nrows();
    let d: Vec<f64> = (0..n).map(|i| 1.0 / s[(i, i)].sqrt()).collect();
    let s_hat = Mat::from_fn(n, n, |a, b| d[a] * s[(a, b)] * d[b]);
    let j_hat = Mat::from_fn(n, n, |a, b| d[a] * j[(a, b)] * d[b]);
    let numerical = |what: &str| ModelError::Numerical {
        routine: "relative LMI (2) check".into(),
        reason: what.to_string(),
    };
    let evd = s_hat
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| numerical(&format!("eigen-decomposition of the scale matrix: {e:?}")))?;
    let lam = evd.S().column_vector();
    let v = evd.U();
    let lam_min = (0..n).map(|i| lam[i]).fold(f64::INFINITY, f64::min);
    let lam_max = (0..n).map(|i| lam[i]).fold(0.0, f64::max);
    if !(lam_min > 0.0) {
        // Only for a P that is singular to working precision (refused by the ρ test anyway).
        return Ok((f64::NAN, f64::INFINITY));
    }
    let w = Mat::from_fn(n, n, |a, b| v[(a, b)] / lam[b].sqrt());
    let k = w.transpose() * &j_hat * &w;
    let eig = sym_eigenvalues("scaled LMI matrix", k.as_ref())?;
    Ok((
        eig.last().copied().unwrap_or(f64::NEG_INFINITY),
        lam_max / lam_min,
    ))
}
