//! δ-IOSS certificate: Assumption 2, LMI (2) of Yang–Manzie–Pu.
//!
//! LMI (2) with B̄ = [E, 0], D̄ = [0, F] (the paper: E = I, F = I) says, for all x and
//! w = (w¹, w²),
//!
//! ‖Ax + B̄w‖²_P ≤ η‖x‖²_P + ‖w‖²_Q + ‖Cx + D̄w‖²_R,                         (★)
//!
//! i.e. W_δ(x, x') = ‖x − x'‖²_P is a δ-IOSS Lyapunov function (eq. 4) with supply
//! s(x, w) = ‖w‖²_Q + ‖Cx + D̄w‖²_R. With G = [A B̄] and H = [C D̄] the LMI matrix is
//! J(P) = GᵀPG − diag(ηP, Q) − HᵀRH ⪯ 0.
//!
//! ## When LMI (2) is feasible (any E)
//! A P ≻ 0 with J(P) ≺ 0 exists iff every unobservable mode of (A, C) has |λ| < √η,
//! whatever E, F, Q, R. Necessity: for an unobservable eigenvector x and w = 0, (★) reads
//! |λ|²‖x‖²_P ≤ η‖x‖²_P. Sufficiency: (A/√η, C) detectable gives P₁ ≻ 0 and σ with
//! AᵀP₁A − ηP₁ − σCᵀC ≺ 0, so M₁ = GᵀP₁G − diag(ηP₁, 0) is negative on
//! ker N = {(x, 0) : Cx = 0}, N = diag(0, Q) + HᵀRH ⪰ 0; by Finsler's lemma
//! J(cP₁) = cM₁ − N ≺ 0 for c > 0 small enough. Infeasibility is therefore always reported
//! as [`LmiFailure::UnobservableMode`] with the offending |λ|.
//!
//! ## Construction (pure Rust, no SDP solver)
//! Define the monotone operator U(P)(x⁺) = min { η xᵀPx + s(x, w) : Ax + B̄w = x⁺ }.
//! P satisfies (★) iff P ⪯ U(P) (take the minimiser on the right of (★)), and
//! P ⪯ P' ⇒ U(P) ⪯ U(P'). For P ≻ 0, U(P) = (GΨ⁻¹Gᵀ)⁻¹ with Ψ = diag(ηP, Q) + HᵀRH, so
//! in covariance form X = P⁻¹ (η > 0), by Woodbury,
//!
//! X⁺ = GΣGᵀ − GΣHᵀ(R⁻¹ + HΣHᵀ)⁻¹HΣGᵀ,  Σ = diag(X/η, Q⁻¹),
//!
//! a Kalman covariance recursion that needs no inverse of X: X = 0 stands for P = +∞ (x
//! forced to 0). From X₀ = 0 it gives X₁ = B̄M⁻¹B̄ᵀ (M = Q + D̄ᵀRD̄) and X_k = Uᵏ(+∞)⁻¹;
//! the measurement term keeps the range (R⁻¹ ≻ 0), so range X_k is the set of states w¹
//! reaches through A in k steps, and X_k ≻ 0 for some k ≤ n_x iff (A, E) is controllable
//! (E invertible, the paper's case: k = 1, P₀ = X₁⁻¹). Then P₀ = X_k⁻¹ = Uᵏ(+∞) ⪰ Uᵏ(P̂)
//! ⪰ P̂ for every feasible P̂, and U(P₀) ⪯ P₀, so the value iteration P_{j+1} = U(P_j)
//! decreases monotonically to a fixed point P* that dominates every feasible P: the
//! *maximal* solution of the associated Riccati equation, which satisfies (★) with equality
//! in some direction and gives the smallest Λ^Q_P and Λ^{H̄}_P in Prop. 3. (Iterating
//! upward from 0 instead finds the *minimal* fixed point, singular on every unobservable
//! mode — a trap.) For η = 0, U(P) does not depend on P and one step from any P₀ is exact.
//!
//! Each application of U is one equality-constrained least-squares problem, solved through
//! its KKT system [[Ψ, Gᵀ], [G, 0]]: the multiplier block equals −U(P).
//!
//! ## Construction at any scale (what the code does)
//! The value iteration converges linearly with the closed-loop rate of the covariance
//! recursion and its stopping test depends on the units (issue 25: AFTI-16 with its speed in
//! 100 ft/s, `mhe.r = 1e4`). The code therefore computes the same P* = X*⁻¹ differently
//! (the `doubling` module):
//!
//! 1. **Balance and normalise** by congruences that leave μ(P) unchanged: w = D_w w̃ with
//!    D_w = diag(Q)^{−½} and y scaled by diag(R)^{½} (Q̃, R̃ with unit diagonal; a common
//!    scaling of the weights disappears), and x = T x̃ with T diagonal chosen by
//!    Parlett–Reinsch sweeps on [A, E; C] (powers of two, so exact). P = T⁻¹P̃T⁻¹.
//! 2. **Doubling.** With Ã = A/√η, C̃ = C/√η, W = B̄Q⁻¹B̄ᵀ, V = R⁻¹ + D̄Q⁻¹D̄ᵀ and the cross
//!    term S = B̄Q⁻¹D̄ᵀ removed (Â = Ã − SV⁻¹C̃, Ŵ = W − SV⁻¹Sᵀ), the covariance recursion is
//!    the filter Riccati recursion of (Â, C̃, Ŵ, V); the structure-preserving doubling
//!    algorithm produces its iterates from X = 0 at steps 1, 2, 4, 8, …, so it converges
//!    quadratically (8–10 steps on the shipped plants), to the same fixed point.
//! 3. **Margin.** The doubling runs on (η, Q, R)·(1 − ε) with ε = τ(2 + 1/η) (at most 1e-6):
//!    the maximal P of the tightened data satisfies J(P) ⪯ −ε(diag(ηP, Q) + HᵀRH) ⪯
//!    −ε/(2 + 1/η)·S(P) for the user's data, so μ(P) ≤ −τ up to rounding instead of μ ≈ 0
//!    (P* has equality in some direction). P is within ≈ ε of P* (relative). If the tightened
//!    problem has no P (η within ε of the boundary) the untightened one is used.
//! 4. **Polish** with one step of U on the scaled data, undo the scaling, and measure P
//!    against the user's data ([`assess`]). The reported `iterations` are the doubling steps
//!    plus the polish.
//!
//! For η = 0, U does not depend on P and P = U(I) is computed directly. Tested against
//! pinned SDP solutions for three plants × three weight ratios × weight scalings 1e-12 … 1e12
//! × unit changes spanning 10⁶ (`tests/all/ioss_scale.rs`, `scripts/lmi2_reference.py`).
//! 5. **Reduced R.** If the P of steps 1–4 fails the check although LMI (2) is feasible (the
//!    doubling loses accuracy for R/Q ≳ 1e8), the maximal P of (Q, c·R), c = 10⁻², 10⁻⁴, …,
//!    10⁻²⁴, is taken instead: c·R ⪯ R, and LMI (2) is monotone in R, so it certifies the
//!    user's data ([`METHOD_REDUCED_R`]; not the maximal P of R). Issue 37, item 4: the stand-in
//!    with `mhe.r = 1e9 … 1e12` or `mhe.q ≤ 1e-10` was refused.
//!
//! **E that does not reach every state** (rank E < n_x and (A, E) not controllable, e.g.
//! noise on some decoupled states only): X_k stays singular; along an unreached mode that
//! decays faster than √η, P can grow without bound (J(P + t·vvᵀ) = J(P) − t(η − |λ|²)·
//! diag(vvᵀ, 0) for a left eigenvector v with vᵀE = 0), so no maximal P need exist. The
//! construction then adds a fictitious disturbance w³ entering every state (E₃ = I,
//! weight q₃I). LMI (2) of the augmented system contains LMI (2) of the original as a
//! principal submatrix, so the augmented P certifies the original; the augmented (A, [E, I])
//! is controllable, and feasibility does not depend on E, so the augmented problem is
//! feasible exactly when the original is. q₃ = 1/(δ·λ_max(X₁)) with
//! δ = [`IossOptions::fictitious_disturbance`]: w³ moves the state by a δ-fraction of what
//! the real disturbance does at equal cost. The result is verified against the original
//! LMI and named `"riccati-value-iteration+fictitious-disturbance"`. (A rank-deficient E
//! with (A, E) controllable, such as noise on the velocities of a mass chain, needs no
//! fictitious disturbance: the maximal P exists and is computed as above.)
//!
//! ## Verification: the tolerance rule
//! Whatever the construction, P is checked explicitly ([`assess`], [`verify`]). With the
//! scale matrix S(P) = GᵀPG + diag(P, Q) + HᵀRH ≻ 0 — the sum of the positive semidefinite
//! terms that make up J (P in place of ηP so that S ≻ 0 also for η = 0) — the relative
//! violation
//!
//! μ(P) = max_v vᵀJ(P)v / vᵀS(P)v ∈ [−1, 1]
//!
//! is dimensionless and invariant under (P, Q, R) → c(P, Q, R) and under linear changes of
//! the coordinates of x and w (J and S transform by the same congruence). It is therefore
//! computed where it is best resolved: in the user's coordinates and, when F has full row
//! rank, in the output-residual coordinates (x, w¹, v = Cx + Fw², ξ ∈ ker F), where the
//! output term is diag(0, 0, R, 0) on coordinates of its own rather than the rank-n_y term
//! HᵀRH spread over every row of J (with R ≫ Q that term rounds away the terms of size Q:
//! μ ≈ 6.7e-6 measured for a valid P at r/q = 1e12). μ's rounding is ≈ n·u·cond(Ŝ), Ŝ the
//! Jacobi-scaled S: the user's coordinates decide while that is below τ/100, beyond it the
//! better-conditioned of the two; the user-coordinate value is reported as
//! [`LmiCheck::relative_violation_original_units`]. P passes iff
//!
//! 1. λ_min(P̂) > ρ·λ_max(P̂) for the Jacobi-scaled P̂ = diag(P)^{−½}·P·diag(P)^{−½},
//!    ρ = [`P_MIN_RATIO`] = 1e-10, and
//! 2. μ(P) ≤ τ, τ = [`LMI_RELATIVE_TOL`] = 1e-9.
//!
//! What 2 means: μ ≤ τ ⇔ J ⪯ τS ⇔ (1 − τ)GᵀPG ⪯ diag((η + τ)P, (1 + τ)Q) + (1 + τ)HᵀRH,
//! i.e. P satisfies LMI (2) *exactly* for η' = (η + τ)/(1 − τ) and (Q, R)·(1 + τ)/(1 − τ):
//! a relative change of 2·10⁻⁹ in the data, far below any modelling precision, and far
//! above the rounding of forming and factorising J and S in f64 (≈ n·u ≈ 1e-14 relative to
//! the terms; the computation of μ uses the Jacobi scaling diag(S)^{−½}, a congruence, so
//! rounding is relative to each row's own scale). A valid P is not refused because of
//! rounding; a P that violates (★) by more than a billionth of the terms in the violating
//! direction is refused. The maximal P* computed above has μ ≈ ±1e-15 (equality in some
//! direction).
//!
//! Why relative to S, direction by direction, and not to a global norm: for P = 1e-12·I on
//! the case study the violation sits in ker C with w = 0, where neither Q nor R contributes
//! (λ_max(J) = +4.9e-14, μ ≈ 0.04); a tolerance scaled by max(1, ‖P‖, ‖Q‖, ‖R‖) (the rule
//! before) is ≈ 1e-9 there and accepted that P.
//!
//! What 1 means (P̂ rather than P so that the rule does not depend on the units of the
//! states: x = Tx̃ with T diagonal maps P to TPT and leaves P̂ unchanged; a plant whose
//! states differ in scale by 10⁶ has λ_min(P)/λ_max(P) ≈ 10⁻¹² for a perfectly resolvable
//! P): the symmetric eigensolver resolves eigenvalues of P̂ to ≈ n·u·λ_max(P̂)
//! ≈ 1e-15·λ_max(P), so ρ = 1e-10 leaves a 10⁵ margin before "λ_min(P) > 0" becomes a
//! rounding artefact; Λ^P_P = λ_max/λ_min ≥ 10¹⁰ would also make the constants of Prop. 3
//! void in practice. The refusal carries the measured ratio
//! ([`LmiFailure::PNumericallySingular`]).

mod check;
mod construct;
mod doubling;

use faer::{Mat, MatRef};
#[cfg(feature = "serde")]
use serde::Serialize;

pub use check::{LmiCheck, assess, lmi_matrix, lmi_scale_matrix};

use crate::error::{LmiFailure, ModelError, Result};
use crate::matrix::{
    check_positive_definite, spectral_norm, sym_extreme_eigenvalues, symmetrize, to_rows,
};
use crate::system::LtiSystem;
use construct::{Extremal, extremal_solution, first_covariance, with_fictitious_disturbance};

/// τ: P passes LMI (2) when μ(P) = max vᵀJv/vᵀSv ≤ τ (module doc, "Verification").
pub const LMI_RELATIVE_TOL: f64 = 1e-9;

/// ρ: P counts as positive definite when λ_min(P) > ρ·λ_max(P) (module doc).
pub const P_MIN_RATIO: f64 = 1e-10;

/// `method` of a P computed as the maximal solution.
pub const METHOD_MAXIMAL: &str = "riccati-doubling";
/// `method` of a P computed with a fictitious disturbance (E does not reach every state).
pub const METHOD_FICTITIOUS: &str = "riccati-doubling+fictitious-disturbance";
/// `method` of a P computed as the maximal solution for a smaller output weight c·R
/// (c = 10⁻², 10⁻⁴, …): the maximal P of the user's R/Q ratio was not resolvable in f64.
pub const METHOD_REDUCED_R: &str = "riccati-doubling+reduced-output-weight";
/// `method` of a user-supplied P.
pub const METHOD_USER: &str = "user";

/// Settings of [`certify_with`] and [`verify_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IossOptions {
    /// Cap on doubling steps of the construction (at most 64 are ever used: each step
    /// squares the closed-loop contraction).
    pub max_iterations: usize,
    /// Kept for compatibility (the doubling stops at 4ε relative change); must be in (0, 1).
    pub tolerance: f64,
    /// τ of the relative LMI check (see [`LMI_RELATIVE_TOL`]).
    pub lmi_relative_tolerance: f64,
    /// ρ: P counts as positive definite when λ_min(P) > ρ·λ_max(P) (see [`P_MIN_RATIO`]).
    pub min_condition: f64,
    /// δ of the fictitious disturbance used when E does not reach every state:
    /// q₃ = 1/(δ·λ_max(B̄M⁻¹B̄ᵀ)) (module doc).
    pub fictitious_disturbance: f64,
}

impl Default for IossOptions {
    fn default() -> Self {
        Self {
            max_iterations: 64,
            tolerance: 1e-14,
            lmi_relative_tolerance: LMI_RELATIVE_TOL,
            min_condition: P_MIN_RATIO,
            fictitious_disturbance: 1e-2,
        }
    }
}

/// A verified solution P of LMI (2) for (A, C, η, Q, R).
#[derive(Debug, Clone)]
#[non_exhaustive]
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
    /// Largest eigenvalue of the LMI matrix J (unscaled; the test is on μ).
    pub lmi_max_eigenvalue: f64,
    /// All eigenvalues of J, ascending.
    pub lmi_eigenvalues: Vec<f64>,
    /// μ(P) = max vᵀJv/vᵀSv (≤ `lmi_relative_tolerance` for a valid certificate).
    pub lmi_relative_violation: f64,
    /// τ the check used.
    pub lmi_relative_tolerance: f64,
    /// ρ the check used: λ_min(P) > ρ·λ_max(P).
    pub p_min_ratio: f64,
    /// How P was obtained ([`METHOD_MAXIMAL`], [`METHOD_FICTITIOUS`], [`METHOD_USER`]).
    pub method: String,
    /// Iterations of the construction (0 for a user-supplied P).
    pub iterations: usize,
}

/// JSON form of [`IossCertificate`] (matrices as row-major nested arrays).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
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
    /// ρ: P must have λ_min(P) > ρ·λ_max(P).
    pub p_min_ratio: f64,
    /// Largest eigenvalue of the LMI matrix J (unscaled).
    pub lmi_max_eigenvalue: f64,
    /// μ(P) = max vᵀJv/vᵀSv; None when P is not positive definite.
    pub lmi_relative_violation: Option<f64>,
    /// τ: P passes when μ(P) ≤ τ.
    pub lmi_relative_tolerance: f64,
    /// All eigenvalues of J, ascending.
    pub lmi_eigenvalues: Vec<f64>,
    /// Construction method.
    pub method: String,
    /// Iterations of the construction.
    pub iterations: usize,
}

impl IossReport {
    /// The report of a P that was measured by [`assess`] (passed or not).
    pub fn from_check(
        p: MatRef<'_, f64>,
        eta: f64,
        q: MatRef<'_, f64>,
        r: MatRef<'_, f64>,
        check: &LmiCheck,
        method: &str,
        iterations: usize,
    ) -> Self {
        Self {
            p: to_rows(p),
            eta,
            q: to_rows(q),
            r: to_rows(r),
            p_min_eigenvalue: check.p_min_eigenvalue,
            p_max_eigenvalue: check.p_max_eigenvalue,
            p_min_ratio: check.p_min_ratio,
            lmi_max_eigenvalue: check.lmi_max_eigenvalue,
            lmi_relative_violation: check.relative_violation,
            lmi_relative_tolerance: check.relative_tolerance,
            lmi_eigenvalues: check.lmi_eigenvalues.clone(),
            method: method.to_string(),
            iterations,
        }
    }
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
            p_min_ratio: self.p_min_ratio,
            lmi_max_eigenvalue: self.lmi_max_eigenvalue,
            lmi_relative_violation: Some(self.lmi_relative_violation),
            lmi_relative_tolerance: self.lmi_relative_tolerance,
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

/// The diagonal state scaling x = T x̃ (T = diag(t), powers of two) that balances
/// [A, E; C] after normalising Q and R to unit diagonal — the scaling LMI (2) is solved in
/// (module doc, "Construction at any scale"). A large max t / min t says the states' units
/// differ in scale; a user whose problem is ill-conditioned because of units can measure
/// state i in units t_i times larger (issue 37, item 7).
///
/// Errors: Q or R not symmetric positive definite of the right size.
pub fn state_scaling(sys: &LtiSystem, q: MatRef<'_, f64>, r: MatRef<'_, f64>) -> Result<Vec<f64>> {
    check_positive_definite("Q", q, sys.nw())?;
    check_positive_definite("R", r, sys.ny())?;
    Ok(doubling::balance(sys, q, r)?.t)
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

fn check_options(opts: &IossOptions) -> Result<()> {
    let checks = [
        ("tolerance", opts.tolerance, "(0, 1)"),
        (
            "lmi_relative_tolerance",
            opts.lmi_relative_tolerance,
            "(0, 1)",
        ),
        ("min_condition", opts.min_condition, "(0, 1)"),
        (
            "fictitious_disturbance",
            opts.fictitious_disturbance,
            "(0, 1)",
        ),
    ];
    for (name, value, range) in checks {
        if !(value > 0.0 && value < 1.0) {
            return Err(ModelError::OutOfRange {
                name: name.into(),
                value,
                range: range.into(),
            });
        }
    }
    Ok(())
}

/// Computes P ≻ 0 satisfying LMI (2) with default [`IossOptions`], for E of any rank, or
/// [`ModelError::LmiInfeasible`] saying which condition fails and by how much.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{LtiSystem, ioss};
/// let sys = LtiSystem::new(mat![[0.9, 0.2], [0.0, 0.7]], mat![[0.0], [1.0]], mat![[1.0, 0.0]]).unwrap();
/// let cert = ioss::certify(&sys, 0.8, Mat::identity(3, 3).as_ref(), Mat::identity(1, 1).as_ref()).unwrap();
/// assert!(cert.p_min_eigenvalue > 0.0);
/// assert!(cert.lmi_relative_violation <= cert.lmi_relative_tolerance);
/// ```
pub fn certify(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
) -> Result<IossCertificate> {
    certify_with(sys, eta, q, r, &IossOptions::default())
}

thread_local! {
    static SOLVES: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// How many times LMI (2) was solved for P ([`certify`] / [`certify_with`]) on the calling
/// thread so far. A diagnostic: a scenario is resolved once, and tests check that a
/// command solves the LMI once per scenario, not once per consumer.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{LtiSystem, ioss};
/// let sys = LtiSystem::new(mat![[0.5]], mat![[1.0]], mat![[1.0]]).unwrap();
/// let before = ioss::lmi_solves_on_this_thread();
/// ioss::certify(&sys, 0.8, Mat::<f64>::identity(2, 2).as_ref(), mat![[1.0]].as_ref()).unwrap();
/// assert_eq!(ioss::lmi_solves_on_this_thread() - before, 1);
/// ```
pub fn lmi_solves_on_this_thread() -> usize {
    SOLVES.with(std::cell::Cell::get)
}

/// [`certify`] with explicit options.
///
/// Errors: bad input (as [`verify`]); [`ModelError::LmiInfeasible`] with
/// [`LmiFailure::UnobservableMode`] (no P exists), [`LmiFailure::SingularExtremalSolution`]
/// (η at the numerical boundary) or [`LmiFailure::Violated`] (the computed P fails the
/// check); [`ModelError::Numerical`] if the iteration does not converge or its KKT system
/// is singular (the message says how to supply P instead).
pub fn certify_with(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    opts: &IossOptions,
) -> Result<IossCertificate> {
    crate::work_count::record(crate::work_count::Work::LmiSolve);
    SOLVES.with(|c| c.set(c.get() + 1));
    check_inputs(sys, eta, q, r)?;
    check_options(opts)?;
    let first = extremal_solution(sys, eta, q, r, opts)?;
    if let Extremal::Found { p, iterations } = &first {
        let check = assess(sys, eta, q, r, p.as_ref(), opts)?;
        if check.passed() {
            return certificate_from(p.clone(), eta, q, r, check, METHOD_MAXIMAL, *iterations);
        }
    }
    if let Some(cause) = infeasibility_reason(sys, eta) {
        return Err(ModelError::LmiInfeasible { cause });
    }

    // E does not reach every state: retry with a fictitious disturbance (module doc).
    let x1 = first_covariance(sys, q, r);
    let x1_max = match &x1 {
        Some(x) => sym_extreme_eigenvalues("B̄M⁻¹B̄ᵀ", x.as_ref())?,
        None => (0.0, 0.0),
    };
    let e_reaches_all = x1_max.1 > 0.0 && x1_max.0 > opts.min_condition * x1_max.1;
    if !e_reaches_all {
        let scale = if x1_max.1 > 0.0 {
            x1_max.1
        } else {
            // E = 0: no real disturbance to compare with; use the weight of Q.
            1.0 / sym_extreme_eigenvalues("Q", q)?.1
        };
        let q3 = 1.0 / (opts.fictitious_disturbance * scale);
        let (aug, q_aug) = with_fictitious_disturbance(sys, q, q3)?;
        if let Extremal::Found { p, iterations } =
            extremal_solution(&aug, eta, q_aug.as_ref(), r, opts)?
        {
            let check = assess(sys, eta, q, r, p.as_ref(), opts)?;
            if check.passed() {
                return certificate_from(p, eta, q, r, check, METHOD_FICTITIOUS, iterations);
            }
        }
    }
    // Feasible, but the maximal P of these weights is not resolved (R/Q beyond ≈ 1e8):
    // a P of the same Q with a smaller R certifies the user's R too (module doc).
    if let Some((p, iterations)) = reduced_output_weight_solution(sys, eta, q, r, opts)? {
        return finish(sys, eta, q, r, p, opts, METHOD_REDUCED_R, iterations);
    }
    if let Extremal::Found { p, iterations } = first {
        return finish(sys, eta, q, r, p, opts, METHOD_MAXIMAL, iterations);
    }
    Err(match first {
        Extremal::Singular {
            min_eigenvalue,
            max_eigenvalue,
        } => ModelError::LmiInfeasible {
            cause: LmiFailure::SingularExtremalSolution {
                min_eigenvalue,
                max_eigenvalue,
                min_ratio: opts.min_condition,
                eta,
            },
        },
        Extremal::NotConverged { iterations } => numerical(format!(
            "the doubling iteration did not converge in {iterations} steps (η = {eta} is at the \
             feasibility boundary of LMI (2)); increase η (scenario key `mhe.eta`), or supply P"
        )),
        Extremal::KktSingular { iteration } => numerical(format!(
            "singular KKT system at iteration {iteration} (ker A ∩ ker C ≠ {{0}} with η = 0?); \
             use η > 0, or supply P"
        )),
        Extremal::Unreached | Extremal::Found { .. } => numerical(
            "the disturbance does not reach every state and the fictitious-disturbance \
             construction did not converge either; supply P"
                .to_string(),
        ),
    })
}

/// Steps of [`reduced_output_weight_solution`]: R·10⁻², R·10⁻⁴, …, R·10⁻²⁴.
const REDUCED_R_STEPS: i32 = 12;

/// A P for (η, Q, c·R) with c = 10⁻², 10⁻⁴, … that passes the check against the user's
/// (η, Q, R), or None. LMI (2) is monotone in R (c·R ⪯ R makes the term −HᵀRH only
/// smaller), so such a P certifies the user's data; it is the maximal P of the smaller R,
/// not of R. Used when the maximal P of (Q, R) is not resolvable (R/Q ≳ 1e8, issue 37,
/// item 4): the doubling is accurate at moderate ratios.
fn reduced_output_weight_solution(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    opts: &IossOptions,
) -> Result<Option<(Mat<f64>, usize)>> {
    let mut total = 0;
    for k in 1..=REDUCED_R_STEPS {
        let r_c = r * 10f64.powi(-2 * k);
        let Extremal::Found { p, iterations } = extremal_solution(sys, eta, q, r_c.as_ref(), opts)?
        else {
            continue;
        };
        total += iterations;
        if assess(sys, eta, q, r, p.as_ref(), opts)?.passed() {
            return Ok(Some((p, total)));
        }
    }
    Ok(None)
}

fn numerical(reason: String) -> ModelError {
    ModelError::Numerical {
        routine: "δ-IOSS Riccati iteration".into(),
        reason: format!(
            "{reason} (scenario key `mhe.p`, or `cargo xtask certify --p-file P.json`: the P \
             is then verified against LMI (2))"
        ),
    }
}

/// Why no P ≻ 0 exists, if one of the necessary conditions fails (module doc): for η > 0
/// an unobservable mode with |λ| ≥ √η; for η = 0, A x ≠ 0 for some x with C x = 0.
fn infeasibility_reason(sys: &LtiSystem, eta: f64) -> Option<LmiFailure> {
    if eta == 0.0 {
        let gain = a_on_ker_c(sys)?;
        let scale = spectral_norm(sys.a());
        return (gain > 1e-12 * scale).then_some(LmiFailure::ZeroEtaNeedsDeadbeat { gain });
    }
    let basis = sys.unobservable_subspace().ok()?;
    if basis.ncols() == 0 {
        return None;
    }
    let modulus = sys.unobservable_spectral_radius().ok()?;
    (modulus >= eta.sqrt()).then_some(LmiFailure::UnobservableMode { modulus, eta })
}

/// ‖A N‖₂ for an orthonormal basis N of ker C (0 if C is injective).
fn a_on_ker_c(sys: &LtiSystem) -> Option<f64> {
    let c = sys.c();
    let nx = sys.nx();
    let svd = c.to_owned().svd().ok()?;
    let sv = svd.S().column_vector();
    let smax = (0..sv.nrows()).map(|i| sv[i]).fold(0.0, f64::max);
    let rank = (0..sv.nrows()).filter(|&i| sv[i] > 1e-12 * smax).count();
    if rank == nx {
        return Some(0.0);
    }
    let v = svd.V();
    let kernel = Mat::from_fn(nx, nx - rank, |i, j| v[(i, rank + j)]);
    Some(spectral_norm((sys.a() * &kernel).as_ref()))
}

#[allow(clippy::too_many_arguments)]
fn finish(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: Mat<f64>,
    opts: &IossOptions,
    method: &str,
    iterations: usize,
) -> Result<IossCertificate> {
    let check = assess(sys, eta, q, r, p.as_ref(), opts)?;
    certificate_from(p, eta, q, r, check, method, iterations)
}

/// The certificate of a measured P, or the failure of its check.
fn certificate_from(
    p: Mat<f64>,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    check: LmiCheck,
    method: &str,
    iterations: usize,
) -> Result<IossCertificate> {
    // `failure` is None only with μ(P) ≤ τ measured; the last arm cannot occur.
    let mu = match (check.failure(), check.relative_violation) {
        (None, Some(mu)) => mu,
        (Some(cause), _) => return Err(ModelError::LmiInfeasible { cause }),
        (None, None) => return Err(numerical("LMI (2) passed without μ(P)".to_string())),
    };
    Ok(IossCertificate {
        p,
        eta,
        q: q.to_owned(),
        r: r.to_owned(),
        p_min_eigenvalue: check.p_min_eigenvalue,
        p_max_eigenvalue: check.p_max_eigenvalue,
        lmi_max_eigenvalue: check.lmi_max_eigenvalue,
        lmi_eigenvalues: check.lmi_eigenvalues,
        lmi_relative_violation: mu,
        lmi_relative_tolerance: check.relative_tolerance,
        p_min_ratio: check.p_min_ratio,
        method: method.to_string(),
        iterations,
    })
}

/// Verifies a user-supplied P against LMI (2) with the relative rule of the module doc
/// (default [`IossOptions`]).
///
/// Errors: bad shapes / non-finite / non-symmetric P, Q, R, η out of range;
/// [`ModelError::NotPositiveDefinite`] if λ_min(P) ≤ 0; [`ModelError::LmiInfeasible`] with
/// [`LmiFailure::PNumericallySingular`] (λ_min(P) ≤ ρ·λ_max(P), with the ratio) or
/// [`LmiFailure::Violated`] (μ(P) > τ, with μ).
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
    verify_with(sys, eta, q, r, p, &IossOptions::default())
}

/// [`verify`] with explicit options (τ, ρ).
pub fn verify_with(
    sys: &LtiSystem,
    eta: f64,
    q: MatRef<'_, f64>,
    r: MatRef<'_, f64>,
    p: MatRef<'_, f64>,
    opts: &IossOptions,
) -> Result<IossCertificate> {
    crate::work_count::record(crate::work_count::Work::LmiSolve);
    check_options(opts)?;
    let check = assess(sys, eta, q, r, p, opts)?;
    if !(check.p_min_eigenvalue > 0.0) {
        return Err(ModelError::NotPositiveDefinite {
            name: "P".into(),
            min_eigenvalue: check.p_min_eigenvalue,
        });
    }
    certificate_from(symmetrize(p), eta, q, r, check, METHOD_USER, 0)
}

/// Result of [`min_feasible_eta`].
#[derive(Debug, Clone)]
#[non_exhaustive]
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
    let opts = IossOptions::default();
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
