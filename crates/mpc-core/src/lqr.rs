//! Saturated LQR: u = Π_𝒰(−Kx̂), the simple second implementation of [`Controller`].

use faer::Mat;
use lti_model::matrix::{check_finite, check_positive_definite, spectral_norm};
use lti_model::riccati::dlqr_gain;
use lti_model::{BoxSet, ConvexSet, LtiSystem, ModelError, Projection};

use crate::error::{MpcError, Result};
use crate::{Controller, check_io};

/// u = clip(−Kx̂) onto the box 𝒰, with K the discrete LQR gain for (A, B, Q_c, R_c).
///
/// Allocation-free per call. Its Lipschitz constant (Assumption 3) is certified as
/// L_π = ‖K‖₂: x ↦ −Kx is ‖K‖₂-Lipschitz and the Euclidean projection onto a convex set
/// is non-expansive.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::{BoxSet, LtiSystem};
/// use mpc_core::{Controller, SaturatedLqr};
/// let sys = LtiSystem::new(mat![[1.0, 0.1], [0.0, 1.0]], mat![[0.005], [0.1]], mat![[1.0, 0.0]]).unwrap();
/// let mut lqr = SaturatedLqr::new(&sys, Mat::identity(2, 2).as_ref(), mat![[0.1]].as_ref(),
///     BoxSet::symmetric(&[1.0]).unwrap()).unwrap();
/// let mut u = [0.0];
/// lqr.control(&[100.0, 0.0], &mut u).unwrap();
/// assert_eq!(u, [-1.0]); // saturated
/// ```
#[derive(Debug, Clone)]
pub struct SaturatedLqr {
    k: Mat<f64>,
    /// −K row-major (n_u × n_x), for the allocation-free product.
    neg_k_rows: Vec<f64>,
    input_set: BoxSet,
    nx: usize,
    nu: usize,
}

impl SaturatedLqr {
    /// LQR gain from the DARE for (A, B, Q_c, R_c), saturated onto `input_set`.
    ///
    /// Errors: `Model(...)` naming `"Q_c"`, `"R_c"`, `"input_set"`, or `Numerical` (DARE)
    /// if (A, B) is not stabilisable or (A, Q_c) not detectable.
    pub fn new(
        system: &LtiSystem,
        q_c: faer::MatRef<'_, f64>,
        r_c: faer::MatRef<'_, f64>,
        input_set: BoxSet,
    ) -> Result<Self> {
        let (nx, nu) = (system.nx(), system.nu());
        crate::condensed::check_psd("Q_c", &q_c.to_owned(), nx)?;
        check_positive_definite("R_c", r_c, nu)?;
        if crate::condensed::is_singular(&q_c.to_owned()) {
            crate::detectable::check_detectable(system.a(), q_c)?;
        }
        let (k, _) =
            dlqr_gain(system.a(), system.b(), q_c, r_c).map_err(|e| e.in_context("lqr"))?;
        Self::from_gain(k, input_set)
    }

    /// A user gain K (n_u × n_x, finite), saturated onto `input_set` (n_u-dimensional).
    pub fn from_gain(k: Mat<f64>, input_set: BoxSet) -> Result<Self> {
        let (nu, nx) = (k.nrows(), k.ncols());
        check_finite("K", k.as_ref())?;
        if nu == 0 || nx == 0 {
            return Err(ModelError::Shape {
                name: "K".into(),
                expected_rows: nu.max(1),
                expected_cols: nx.max(1),
                actual_rows: nu,
                actual_cols: nx,
            }
            .into());
        }
        if input_set.dim() != nu {
            return Err(MpcError::Model(ModelError::Shape {
                name: "input_set".into(),
                expected_rows: nu,
                expected_cols: 1,
                actual_rows: input_set.dim(),
                actual_cols: 1,
            }));
        }
        let neg_k_rows = (0..nu * nx).map(|i| -k[(i / nx, i % nx)]).collect();
        Ok(Self {
            k,
            neg_k_rows,
            input_set,
            nx,
            nu,
        })
    }

    /// The gain K (u = −Kx̂ before saturation).
    pub fn gain(&self) -> &Mat<f64> {
        &self.k
    }
    /// The input set 𝒰.
    pub fn input_set(&self) -> &BoxSet {
        &self.input_set
    }
    /// Certified L_π = ‖K‖₂ (Assumption 3; clipping onto 𝒰 is non-expansive).
    pub fn lipschitz_certified(&self) -> f64 {
        spectral_norm(self.k.as_ref())
    }
}

impl Controller for SaturatedLqr {
    type Error = MpcError;
    fn control(&mut self, x_hat: &[f64], u: &mut [f64]) -> Result<()> {
        check_io(x_hat, u, self.nx, self.nu)?;
        for (i, ui) in u.iter_mut().enumerate() {
            let row = &self.neg_k_rows[i * self.nx..(i + 1) * self.nx];
            *ui = row.iter().zip(x_hat).map(|(a, b)| a * b).sum();
        }
        self.input_set.project(u);
        Ok(())
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn nx(&self) -> usize {
        self.nx
    }
}
