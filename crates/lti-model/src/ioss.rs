//! δ-IOSS certificate: Assumption 2, LMI (2) of Yang–Manzie–Pu.
//!
//! LMI (2) with B̄ = [E, 0], D̄ = [0, F] (the paper: E = I, F = I) says, for all x and
//! w = (w¹, w²),
//!
//! ‖Ax + B̄w‖²_P ≤ η‖x‖²_P + ‖w‖²_Q + ‖Cx + D̄w‖²_R,                         (★)
//!
//! i.e. W_δ(x, x') = ‖x − x'‖²_P is a δ-IOSS Lyapunov function (eq. 4) with supply
//! s(x, w) = ‖w‖²_Q + ‖Cx + D̄w‖²_R.
//!
//! ## Construction (pure Rust, no SDP solver)
//! Define the monotone operator
//!
//! U(P)(x⁺) = min { η xᵀPx + s(x, w) : Ax + B̄w = x⁺ }.
//!
//! P satisfies (★) iff P ⪯ U(P) (take the minimiser on the right of (★)). U is monotone
//! (P ⪯ P' ⇒ U(P) ⪯ U(P')) and bounded: choosing x = 0, w¹ = E⁻¹x⁺ shows U(P) ⪯ B for every
//! P, with B = E⁻ᵀ(M₁₁ − M₁₂M₂₂⁻¹M₂₁)E⁻¹, M = Q + D̄ᵀRD̄. Hence every feasible P̂ obeys
//! P̂ ⪯ U(P̂) ⪯ B, and by induction P̂ ⪯ Uᵏ(B). The value iteration P_{k+1} = U(P_k) from
//! P₀ = B therefore decreases monotonically to a fixed point P* that dominates every
//! feasible P: the *maximal* solution of the associated Riccati equation, which satisfies
//! (★) (with equality in some direction) and gives the smallest Λ^Q_P and Λ^{H̄}_P in Prop. 3.
//! (Iterating upward from 0 instead finds the *minimal* fixed point, which is singular on
//! every unobservable mode — a trap.) This needs E invertible, as in the paper (E = I).
//!
//! Each application of U is one equality-constrained least-squares problem, solved through
//! its KKT system [[Ψ, Gᵀ], [G, 0]] with Ψ = diag(ηP, 0) + diag(0, Q) + [C D̄]ᵀR[C D̄] and
//! G = [A B̄]: the multiplier block equals −U(P).
//!
//! P* is singular exactly when some x⁺ ≠ 0 is reached at zero supply forever, i.e. when an
//! unobservable mode does not decay faster than √η: then LMI (2) has no P ≻ 0 and
//! [`certify`] returns [`ModelError::LmiInfeasible`] naming that mode.
//!
//! ## Verification
//! Whatever the construction, the returned P is checked explicitly: the LMI matrix of (2)
//! is formed and its largest eigenvalue must be ≤ `lmi_tolerance`; λ_min(P) must be > 0.
//! [`verify`] runs the same check on a user-supplied P.

use faer::linalg::solvers::{DenseSolveCore, Solve};
use faer::{Mat, MatRef};
use serde::Serialize;

use crate::error::{ModelError, Result};
use crate::matrix::{
    check_finite, check_positive_definite, check_shape, sym_eigenvalues, sym_extreme_eigenvalues,
    symmetrize, to_rows,
};
use crate::system::LtiSystem;

/// Default absolute tolerance on the largest eigenvalue of the LMI matrix, applied after
/// scaling by max(1, ‖P‖_max, ‖Q‖_max, ‖R‖_max).
pub const LMI_TOL: f64 = 1e-9;

/// Settings of [`certify_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IossOptions {
    /// Cap on value iterations of U.
    pub max_iterations: usize,
    /// Stop when max|P_{k+1} − P_k| ≤ `tolerance`·max(1, max|P_k|).
    pub tolerance: f64,
    /// Tolerance on λ_max of the LMI matrix (scaled, see [`LMI_TOL`]).
    pub lmi_tolerance: f64,
    /// P counts as positive definite when λ_min(P) > `min_condition`·λ_max(P).
    pub min_condition: f64,
}

impl Default for IossOptions {
    fn default() -> Self {
        Self {
            max_iterations: 200_000,
            tolerance: 1e-14,
            lmi_tolerance: LMI_TOL,
            min_condition: 1e-10,
        }
    }
}

/// A verified solution P of LMI (2) for (A, C, η, Q, R).
#[derive(Debug, Clone)]
pub struct IossCertificate {
    /// P ≻ 0 of LMI (2); W_δ(x, x') = ‖x − x'‖²_P (eq. 3).
    pub p: Mat<f64>,
    /// Decay rate η ∈ [0, 1).
    pub eta: f64,
    /// Disturbance weight Q, (n_w1 + n_w2) square.
    pub q: Mat<f64>,
    /// Output weight R, n_y square.
    pub r: Mat<f64>,
    /// λ_min(P).
    pub p_min_eigenvalue: f64,
    /// λ_max(P).
    pub p_max_eigenvalue: f64,
    /// Largest eigenvalue of the LMI matrix (≤ tolerance when the certificate is valid).
    pub lmi_max_eigenvalue: f64,
    /// All eigenvalues of the LMI matrix, ascending.
    pub lmi_eigenvalues: Vec<f64>,
    /// Absolute tolerance the LMI check used (after scaling).
    pub lmi_tolerance: f64,
    /// How P was obtained (`"riccati-value-iteration"`, `"user"`).
    pub method: String,
    /// Iterations of the construction (0 for a user-supplied P).
    pub iterations: usize,
}

/// JSON form of [`IossCertificate`] (matrices as row-major nested arrays).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IossReport {
    /// P.
    pub p: Vec<Vec<f64>>,
    /// η.
    pub eta: f64,
    /// Q.
    pub q: Vec<Vec<f64>>,
    /// R.
    pub r: Vec<Vec<f64>>,
    /// λ_min(P).
    pub p_min_eigenvalue: f64,
    /// λ_max(P).
    pub p_max_eigenvalue: f64,
    /// Largest eigenvalue of the LMI matrix.
    pub lmi_max_eigenvalue: f64,
    /// Tolerance used for the LMI check.
    pub lmi_tolerance: f64,
    /// All eigenvalues of the LMI matrix, ascending.
    pub lmi_eigenvalues: Vec<f64>,
    /// Construction method.
    pub method: String,
    /// Iterations of the construction.
    pub iterations: usize,
}

impl IossCertificate {
    /// JSON-ready report.
    pub fn report(&self) -> IossReport {
        IossReport {
            p: to_rows(self.p.as_ref()),
            eta: self.eta,
            q: to_rows(self.q.as_ref()),
            r: to_rows(self.r.as_ref()),
            p_min_eigenvalue: self.p_min_eigenvalue,
            p_max_eigenvalue: self.p_max_eigenvalue,
            lmi_max_eigenvalue: self.lmi_max_eigenvalue,
            lmi_tolerance: self.lmi_tolerance,
            lmi_eigenvalues: self.lmi_eigenvalues.clone(),
            method: self.method.clone(),
            iterations: self.iterations,
        }
    }

    /// Λ^U_V = λ̄(U)/λ(V) with U = V = P (Prop. 3).
    pub fn lambda_pp(&self) -> f64 {
        self.p_max_eigenvalue / self.p_min_eigenvalue
    }
}

fn check_inputs(sys: &LtiSystem, eta: f64, q: MatRef<'_, f64>, r: MatRef<'_, f64>) -> Result<()> {
    if !(0.0..1.0).contains(&eta) {
        return Err(ModelError::OutOfRange {
            name: "eta".into(),
            value: eta,
            range: "[0, 1)".into(),
        });
    }
    check_positive_definite("Q", q, sys.nw())?;
    check_positive_definite("R", r, sys.ny())?;
    Ok(())
}

/// The LMI matrix of (2) for a given P (⪯ 0 iff P certifies δ-IOSS with (η, Q, R)):
///
/// [[AᵀPA − ηP − CᵀRC, AᵀPB̄ − CᵀRD̄], [B̄ᵀPA − D̄ᵀRC, B̄ᵀPB̄ − Q − D̄ᵀRD̄]].
///
/// Shapes are the caller's contract (use [`verify`] for untrusted input); the result is
/// exactly symmetric.
pub fn lmi_matrix(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
) -> Mat<f64> {
    let (nx, nw) = (sys.nx(), sys.nw());
    // G = [A B̄], H = [C D̄], J = GᵀPG − diag(ηP, Q) − HᵀRH.
    let g = Mat::from_fn(nx, nx + nw, |i, j| {
        if j < nx {
            sys.a()[(i, j)]
        } else {
            sys.b_bar()[(i, j - nx)]
        }
    });
    let dbar = sys.d_bar();
    let h = Mat::from_fn(sys.ny(), nx + nw, |i, j| {
        if j < nx {
            sys.c()[(i, j)]
        } else {
            dbar[(i, j - nx)]
        }
    });
    let mut j = g.transpose() * p * &g - h.transpose() * r * &h;
    for a in 0..nx {
        for b in 0..nx {
            j[(a, b)] -= eta * p[(a, b)];
        }
    }
    for a in 0..nw {
        for b in 0..nw {
            j[(nx + a, nx + b)] -= q[(a, b)];
        }
    }
    symmetrize(j.as_ref())
}

/// B with U(P) ⪯ B for all P (x = 0, w¹ = E⁻¹x⁺, w² optimal); see the module doc.
fn upper_bound(sys: &LtiSystem, q: MatRef<'_, f64>, r: MatRef<'_, f64>) -> Result<Mat<f64>> {
    let (nx, nw1, nw2) = (sys.nx(), sys.nw1(), sys.nw2());
    let not_invertible = || {
        ModelError::Numerical {
        routine: "δ-IOSS certificate".into(),
        reason: "the construction needs the disturbance input E square and invertible (the paper's E = I); \
                 supply your own P and use `ioss::verify`"
            .into(),
    }
    };
    if nw1 != nx {
        return Err(not_invertible());
    }
    let e_inv = {
        let e = sys.e().to_owned();
        let inv = e.partial_piv_lu().inverse();
        if !inv.norm_max().is_finite()
            || (&e * &inv - Mat::<f64>::identity(nx, nx)).norm_max() > 1e-8
        {
            return Err(not_invertible());
        }
        inv
    };
    let dbar = sys.d_bar();
    let m = q.to_owned() + dbar.transpose() * r * &dbar;
    let m11 = m.as_ref().submatrix(0, 0, nw1, nw1);
    let m12 = m.as_ref().submatrix(0, nw1, nw1, nw2);
    let m22 = m.as_ref().submatrix(nw1, nw1, nw2, nw2);
    let schur = if nw2 > 0 {
        m11 - m12 * m22.partial_piv_lu().solve(m12.transpose())
    } else {
        m11.to_owned()
    };
    Ok(symmetrize((e_inv.transpose() * schur * &e_inv).as_ref()))
}

/// One application of U (see the module doc). Returns None if the KKT system is singular.
fn apply_u(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
) -> Option<Mat<f64>> {
    let (nx, nw) = (sys.nx(), sys.nw());
    let nz = nx + nw;
    let bbar = sys.b_bar();
    let dbar = sys.d_bar();
    let hmat = Mat::from_fn(sys.ny(), nz, |i, j| {
        if j < nx {
            sys.c()[(i, j)]
        } else {
            dbar[(i, j - nx)]
        }
    });
    let psi = hmat.transpose() * r * &hmat;
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
            let gij = if j < nx {
                sys.a()[(i, j)]
            } else {
                bbar[(i, j - nx)]
            };
            kkt[(nz + i, j)] = gij;
            kkt[(j, nz + i)] = gij;
        }
    }
    let rhs = Mat::from_fn(nz + nx, nx, |i, j| if i == nz + j { 1.0 } else { 0.0 });
    let sol = kkt.partial_piv_lu().solve(&rhs);
    let u = Mat::from_fn(nx, nx, |i, j| -sol[(nz + i, j)]);
    if u.norm_max().is_finite() {
        Some(symmetrize(u.as_ref()))
    } else {
        None
    }
}

/// Computes P ≻ 0 satisfying LMI (2) with default [`IossOptions`], or
/// [`ModelError::LmiInfeasible`] saying why none exists.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{LtiSystem, ioss};
/// let sys = LtiSystem::new(mat![[0.9, 0.2], [0.0, 0.7]], mat![[0.0], [1.0]], mat![[1.0, 0.0]]).unwrap();
/// let cert = ioss::certify(&sys, 0.8, Mat::identity(3, 3).as_ref(), Mat::identity(1, 1).as_ref()).unwrap();
/// assert!(cert.p_min_eigenvalue > 0.0);
/// assert!(cert.lmi_max_eigenvalue <= cert.lmi_tolerance);
/// ```
pub fn certify(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
) -> Result<IossCertificate> {
    certify_with(sys, eta, q, r, &IossOptions::default())
}

/// [`certify`] with explicit options.
pub fn certify_with(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    opts: &IossOptions,
) -> Result<IossCertificate> {
    check_inputs(sys, eta, q, r)?;
    let nx = sys.nx();
    let mut p = upper_bound(sys, q, r)?;
    let mut iterations = 0;
    let mut converged = false;
    for k in 0..opts.max_iterations {
        let Some(next) = apply_u(sys, eta, q, r, p.as_ref()) else {
            return Err(ModelError::Numerical {
                routine: "δ-IOSS Riccati iteration".into(),
                reason: format!(
                    "singular KKT system at iteration {k} (ker A ∩ ker C ≠ {{0}} with η = 0?)"
                ),
            });
        };
        let mut diff = 0.0_f64;
        for i in 0..nx {
            for j in 0..nx {
                diff = diff.max((next[(i, j)] - p[(i, j)]).abs());
            }
        }
        let scale = p.norm_max().max(1.0);
        p = next;
        iterations = k + 1;
        if diff <= opts.tolerance * scale {
            converged = true;
            break;
        }
    }
    let (pmin, pmax) = sym_extreme_eigenvalues("P", p.as_ref())?;
    if !(pmin > opts.min_condition * pmax) || !(pmax > 0.0) {
        return Err(infeasibility(sys, eta, pmin, pmax));
    }
    if !converged {
        return Err(ModelError::Numerical {
            routine: "δ-IOSS Riccati iteration".into(),
            reason: format!(
                "no convergence in {iterations} iterations (η = {eta} is probably at the feasibility boundary); \
                 increase η or `max_iterations`"
            ),
        });
    }
    let mut cert = check_lmi(sys, eta, q, r, p, opts.lmi_tolerance)?;
    cert.method = "riccati-value-iteration".into();
    cert.iterations = iterations;
    Ok(cert)
}

fn infeasibility(sys: &LtiSystem, eta: f64, pmin: f64, pmax: f64) -> ModelError {
    let rho_u = sys.unobservable_spectral_radius().unwrap_or(f64::NAN);
    let reason = if rho_u >= eta.sqrt() {
        format!(
            "(A, C) has an unobservable mode with |λ| = {rho_u:.6} ≥ √η = {:.6}; LMI (2) needs every unobservable \
             mode to decay faster than √η. {}",
            eta.sqrt(),
            if rho_u < 1.0 {
                format!(
                    "The pair is detectable: any η > {:.6} (= |λ|²) may be feasible.",
                    rho_u * rho_u
                )
            } else {
                "The pair is not detectable, so no η ∈ [0, 1) works: change C (add a sensor)."
                    .to_string()
            }
        )
    } else {
        format!(
            "the extremal solution of the associated Riccati equation is singular (λ_min(P) = {pmin:.3e}, \
             λ_max(P) = {pmax:.3e}): η = {eta} is too small for this system; try a larger η \
             (see `min_feasible_eta`)"
        )
    };
    ModelError::LmiInfeasible { reason }
}

fn check_lmi(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: Mat<f64>,
    tol: f64,
) -> Result<IossCertificate> {
    let (pmin, pmax) = sym_extreme_eigenvalues("P", p.as_ref())?;
    let j = lmi_matrix(sys, eta, q, r, p.as_ref());
    let eig = sym_eigenvalues("LMI matrix", j.as_ref())?;
    let jmax = eig.last().copied().unwrap_or(0.0);
    let scale = p.norm_max().max(q.norm_max()).max(r.norm_max()).max(1.0);
    let abs_tol = tol * scale;
    if !(pmin > 0.0) {
        return Err(ModelError::NotPositiveDefinite {
            name: "P".into(),
            min_eigenvalue: pmin,
        });
    }
    if !(jmax <= abs_tol) {
        return Err(ModelError::LmiInfeasible {
            reason: format!(
                "P violates LMI (2): largest eigenvalue of the LMI matrix is {jmax:.3e} > tolerance {abs_tol:.1e}"
            ),
        });
    }
    Ok(IossCertificate {
        p,
        eta,
        q: q.to_owned(),
        r: r.to_owned(),
        p_min_eigenvalue: pmin,
        p_max_eigenvalue: pmax,
        lmi_max_eigenvalue: jmax,
        lmi_eigenvalues: eig,
        lmi_tolerance: abs_tol,
        method: String::new(),
        iterations: 0,
    })
}

/// Verifies a user-supplied P against LMI (2) (tolerance [`LMI_TOL`], scaled).
///
/// Errors: bad shapes / non-finite / non-symmetric / not positive definite P, Q, R, η out of
/// range, or [`ModelError::LmiInfeasible`] with the offending eigenvalue.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{LtiSystem, ioss};
/// let sys = LtiSystem::new(mat![[0.5]], mat![[1.0]], mat![[1.0]]).unwrap();
/// let (q, r) = (Mat::<f64>::identity(2, 2), Mat::<f64>::identity(1, 1));
/// // ‖0.5x + w¹‖²_p ≤ 0.8p x² + w¹² + w²² + (x + w²)² holds for p = 0.5 …
/// assert!(ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), mat![[0.5]].as_ref()).is_ok());
/// // … but not for p = 2 (the w¹ direction alone needs p ≤ 1).
/// assert!(ioss::verify(&sys, 0.8, q.as_ref(), r.as_ref(), mat![[2.0]].as_ref()).is_err());
/// ```
pub fn verify(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
) -> Result<IossCertificate> {
    check_inputs(sys, eta, q, r)?;
    check_shape("P", p, sys.nx(), sys.nx())?;
    check_finite("P", p)?;
    check_positive_definite("P", p, sys.nx())?;
    let mut cert = check_lmi(sys, eta, q, r, symmetrize(p), LMI_TOL)?;
    cert.method = "user".into();
    Ok(cert)
}

/// Result of [`min_feasible_eta`].
#[derive(Debug, Clone)]
pub struct EtaBisection {
    /// Smallest η found feasible (within `tolerance`), with its certificate.
    pub certificate: IossCertificate,
    /// Largest η found infeasible (or 0 if η = 0 is feasible).
    pub infeasible_below: f64,
    /// Bisection steps.
    pub steps: usize,
}

/// Bisection for the smallest η ∈ [0, 1) for which [`certify`] succeeds, to `tolerance`.
///
/// Feasibility is monotone in η (a P feasible for η is feasible for any η' > η, since
/// −η'P ⪯ −ηP), so bisection is exact up to the numerical definition of "P ≻ 0" in
/// [`IossOptions::min_condition`]. Errors if even η = 1 − tolerance is infeasible.
pub fn min_feasible_eta(
    sys: &LtiSystem,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    tolerance: f64,
) -> Result<EtaBisection> {
    if !(tolerance > 0.0 && tolerance < 0.5) {
        return Err(ModelError::OutOfRange {
            name: "tolerance".into(),
            value: tolerance,
            range: "(0, 0.5)".into(),
        });
    }
    check_inputs(sys, 0.5, q, r)?;
    let opts = IossOptions {
        max_iterations: 20_000,
        ..IossOptions::default()
    };
    if let Ok(c) = certify_with(sys, 0.0, q, r, &opts) {
        return Ok(EtaBisection {
            certificate: c,
            infeasible_below: 0.0,
            steps: 0,
        });
    }
    let mut hi_eta = 1.0 - tolerance;
    let mut best = certify_with(sys, hi_eta, q, r, &opts)?;
    let mut lo_eta = 0.0;
    let mut steps = 0;
    while hi_eta - lo_eta > tolerance {
        let mid = 0.5 * (lo_eta + hi_eta);
        steps += 1;
        match certify_with(sys, mid, q, r, &opts) {
            Ok(c) => {
                best = c;
                hi_eta = mid;
            }
            Err(_) => lo_eta = mid,
        }
    }
    Ok(EtaBisection {
        certificate: best,
        infeasible_below: lo_eta,
        steps,
    })
}
