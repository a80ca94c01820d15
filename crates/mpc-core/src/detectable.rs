//! Detectability of (A, Q_c^½): when the stage weight Q_c is only positive *semi*definite.
//!
//! The DARE terminal cost needs its stabilising solution, which exists (and is the unique
//! PSD one) when (A, B) is stabilisable and (A, Q_c^½) is detectable: every mode of A that
//! Q_c does not see, directly or through the dynamics, decays (|λ| < 1). Q_c ≻ 0 is
//! detectable trivially. For a singular Q_c this module finds the modes that are not.
//!
//! ## Method
//!
//! ker 𝒪 of the observability matrix 𝒪 = [Q_c; Q_c A; …; Q_c A^{n−1}] is the largest
//! A-invariant subspace in ker Q_c (ker Q_c^½ A^k = ker Q_c A^k, so Q_c stands for its root).
//! With an orthonormal basis N of it, A N = N A_u, A_u = Nᵀ A N; the eigenvalues of A_u are the
//! unobservable modes and (A, Q_c^½) is detectable iff each has |λ| < 1
//! ([`lti_model::LtiSystem::unobservable_subspace`] with C = Q_c, numerical rank 1e-9·σ_max).
//!
//! ## Reference
//!
//! B. D. O. Anderson, J. B. Moore, *Optimal Filtering*, 1979, App. C (detectability and the
//! stabilising Riccati solution); the PBH form: λ is undetectable iff A v = λ v, Q_c v = 0 for
//! some v ≠ 0 with |λ| ≥ 1.

use faer::{Mat, MatRef};
use lti_model::LtiSystem;

use crate::error::{MpcError, Result};

/// Moduli at or above `1 − MARGIN` count as not decaying (marginal modes are undetectable:
/// the DARE has no stabilising solution with an unobserved mode on the unit circle).
pub const MARGIN: f64 = 1e-9;

/// A mode of A that Q_c does not see and that does not decay.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct UndetectableMode {
    /// Real part of the eigenvalue λ.
    pub re: f64,
    /// Imaginary part of λ.
    pub im: f64,
    /// |λ| ≥ 1 − [`MARGIN`].
    pub modulus: f64,
    /// The state components the mode lives in (indices of the eigenvector entries of at
    /// least 10% of its largest one), ascending.
    pub states: Vec<usize>,
}

impl std::fmt::Display for UndetectableMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let lambda = if self.im == 0.0 {
            lti_model::numfmt::sig4(self.re)
        } else {
            format!(
                "{} {} {}i",
                lti_model::numfmt::sig4(self.re),
                if self.im < 0.0 { '−' } else { '+' },
                lti_model::numfmt::sig4(self.im.abs())
            )
        };
        let states: Vec<String> = self.states.iter().map(|i| format!("x_{i}")).collect();
        write!(
            f,
            "λ = {lambda} (|λ| = {}) in the state component(s) {}",
            lti_model::numfmt::sig4(self.modulus),
            states.join(", ")
        )
    }
}

/// The modes of A with |λ| ≥ 1 − [`MARGIN`] that Q_c (n_x × n_x, symmetric ⪰ 0) does not
/// see: empty iff (A, Q_c^½) is detectable. Largest modulus first.
///
/// ```
/// use faer::mat;
/// // A double integrator weighted on the velocity only: the position is unseen and
/// // marginal (λ = 1), so the pair is not detectable ...
/// let a = mat![[1.0, 0.0], [0.0, 1.0]];
/// let modes = mpc_core::detectable::undetectable_modes(a.as_ref(), mat![[0.0, 0.0], [0.0, 1.0]].as_ref()).unwrap();
/// assert_eq!(modes[0].states, vec![0]);
/// // ... but with the dynamics coupling position into velocity it is.
/// let a = mat![[1.0, 0.0], [0.1, 1.0]];
/// assert!(mpc_core::detectable::undetectable_modes(a.as_ref(), mat![[0.0, 0.0], [0.0, 1.0]].as_ref()).unwrap().is_empty());
/// ```
pub fn undetectable_modes(
    a: MatRef<'_, f64>,
    q_c: MatRef<'_, f64>,
) -> Result<Vec<UndetectableMode>> {
    let n = a.nrows();
    let sys = LtiSystem::new(a.to_owned(), Mat::zeros(n, 0), q_c.to_owned())?;
    let basis = sys.unobservable_subspace()?;
    if basis.ncols() == 0 {
        return Ok(Vec::new());
    }
    let au = basis.transpose() * a * &basis;
    let eig = au.eigen().map_err(|e| {
        MpcError::Model(lti_model::ModelError::Numerical {
            routine: "eigenvectors of A on ker 𝒪(A, Q_c)".into(),
            reason: format!("{e:?}"),
        })
    })?;
    let (s, u) = (eig.S().column_vector(), eig.U());
    let mut out = Vec::new();
    for k in 0..s.nrows() {
        let lambda = s[k];
        let modulus = lambda.norm();
        if modulus < 1.0 - MARGIN {
            continue;
        }
        // A complex pair is one mode: report the member with im ≥ 0 only.
        if lambda.im < 0.0 {
            continue;
        }
        // The eigenvector in state coordinates: v = N z.
        let mags: Vec<f64> = (0..n)
            .map(|i| {
                let (mut re, mut im) = (0.0, 0.0);
                for j in 0..basis.ncols() {
                    re += basis[(i, j)] * u[(j, k)].re;
                    im += basis[(i, j)] * u[(j, k)].im;
                }
                re.hypot(im)
            })
            .collect();
        let top = mags.iter().copied().fold(0.0, f64::max);
        out.push(UndetectableMode {
            re: lambda.re,
            im: lambda.im,
            modulus,
            states: (0..n).filter(|&i| mags[i] >= 0.1 * top).collect(),
        });
    }
    out.sort_by(|x, y| y.modulus.total_cmp(&x.modulus));
    Ok(out)
}

/// [`MpcError::NotDetectable`] for the first mode of [`undetectable_modes`], if any.
pub fn check_detectable(a: MatRef<'_, f64>, q_c: MatRef<'_, f64>) -> Result<()> {
    match undetectable_modes(a, q_c)?.into_iter().next() {
        None => Ok(()),
        Some(mode) => Err(MpcError::NotDetectable { mode }),
    }
}
