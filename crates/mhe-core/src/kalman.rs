//! Kalman filter in prediction form (the MHE's timing), optionally with fading memory.
//!
//! ## Model
//! x_{t+1} = A x_t + B u_t + ξ_t, y_t = C x_t + ζ_t with zero-mean Gaussian noise,
//! cov(ξ_t) = λ^{t+1} Q̄, cov(ζ_t) = λ^{t+1} R̄, cov(ξ_t, ζ_t) = λ^{t+1} S̄, x₀ ~ N(x̄₀, Π₀),
//! where λ ∈ (0, 1] is the forgetting factor (λ = 1: the standard filter). With w = (w¹, w²)
//! of covariance Σ_w and an extra output noise v of covariance Σ_v (y = Cx + Fw² + v):
//! Q̄ = E Σ_w,11 Eᵀ, R̄ = F Σ_w,22 Fᵀ + Σ_v, S̄ = E Σ_w,12 Fᵀ.
//!
//! ## Recursion
//! The filter keeps x̂_t = E[x_t | y_0..y_{t−1}] (the MHE's x̂_{t|t}: measurements up to
//! t − 1) and the scaled covariance Π_t = λ^{−t} cov(x_t | y_0..y_{t−1}). Writing the
//! predictor-form Kalman recursion for P_t = λ^t Π_t and dividing by λ^{t+1}:
//!
//! S̃ = CΠCᵀ + λR̄,  K = (AΠCᵀ + λS̄) S̃⁻¹,
//! x̂⁺ = A x̂ + B u + K (y − C x̂),  Π⁺ = λ⁻¹ (AΠAᵀ − K S̃ Kᵀ) + Q̄.
//!
//! Dividing the covariance by λ each step multiplies the information by λ: old data is
//! discounted geometrically, which is what the η-weights of the MHE cost (9) do.
//!
//! ## Matching the MHE
//! [`KalmanFilter::matching_mhe`] sets λ = η, Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹, Σ_v = R⁻¹. Then
//! x̂_t equals the minimiser's x̂_{t|t} of the *full-information* problem
//! min 2η^t‖x̂₀ − x̄₀‖²_P + Σ_{j<t} η^{t−1−j}(2‖ŵ_j‖²_Q + ‖C x̂_j + F ŵ²_j − y_j‖²_R)
//! (no constraints): multiplying the cost by η^{−t} does not move the minimiser and turns it
//! into ‖x̂₀ − x̄₀‖²_{2P} + Σ_j ‖ŵ_j‖²_{2η^{−(j+1)}Q} + ‖ŷ_j − y_j‖²_{η^{−(j+1)}R}, which is
//! −2 log of the posterior density of (x₀, w) given y for the Gaussian model above
//! (covariances the inverse weights). A Gaussian posterior's mode is its mean, x̂_t is a
//! linear function of (x₀, w), so the minimiser's x̂_t is E[x_t | y_0..y_{t−1}] — the
//! filter's. For t ≤ M that problem *is* the MHE's ℙ_t (𝒲 = ℝ^{n_w}).

use faer::Mat;
use lti_model::LtiSystem;
use lti_model::matrix::{
    check_finite, check_positive_definite, check_shape, sym_extreme_eigenvalues,
};

use crate::error::{MheError, Result};
use crate::estimator::{Estimator, check_vec};
use crate::problem::Dims;

/// Kalman filter (prediction form) with forgetting factor λ ∈ (0, 1]; see the module docs.
///
/// ```
/// use faer::{mat, Mat};
/// use lti_model::LtiSystem;
/// use mhe_core::{Estimator, KalmanFilter};
/// let sys = LtiSystem::new(mat![[1.0]], mat![[0.0]], mat![[1.0]]).unwrap();
/// // Random constant observed in unit noise: x̂ after n samples is the running average
/// // weighted with the prior (Π₀ = 1): x̂ = (x̄₀ + Σy)/(n + 1).
/// let w_cov = mat![[0.0, 0.0], [0.0, 1.0]];
/// let mut kf = KalmanFilter::new(&sys, &[0.0], mat![[1.0]], w_cov, mat![[0.0]]).unwrap();
/// kf.push(&[0.0], &[2.0]).unwrap();
/// kf.push(&[0.0], &[4.0]).unwrap();
/// assert!((kf.estimate().unwrap()[0] - 2.0).abs() < 1e-12);
/// ```
#[derive(Debug, Clone)]
pub struct KalmanFilter {
    d: Dims,
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    qbar: Vec<f64>,
    rbar: Vec<f64>,
    sbar: Vec<f64>,
    lambda: f64,
    x0: Vec<f64>,
    pi0: Vec<f64>,
    x: Vec<f64>,
    pi: Vec<f64>,
    t: usize,
    // scratch
    s: Vec<f64>,
    g: Vec<f64>,
    k: Vec<f64>,
    kw: Vec<f64>,
    ap: Vec<f64>,
    pi_next: Vec<f64>,
    x_next: Vec<f64>,
    innov: Vec<f64>,
    col: Vec<f64>,
}

use lti_model::matrix::row_major;

fn check_psd(name: &str, m: &Mat<f64>, n: usize) -> Result<()> {
    check_shape(name, m.as_ref(), n, n)?;
    check_finite(name, m.as_ref())?;
    let asym = lti_model::matrix::asymmetry(m.as_ref());
    let scale = m.norm_max().max(1.0);
    if asym > lti_model::matrix::SYMMETRY_TOL * scale {
        return Err(lti_model::ModelError::NotSymmetric {
            name: name.into(),
            asymmetry: asym,
        }
        .into());
    }
    if n > 0 {
        let (lo, _) = sym_extreme_eigenvalues(name, m.as_ref())?;
        if lo < -1e-12 * scale {
            return Err(lti_model::ModelError::NotPositiveDefinite {
                name: name.into(),
                min_eigenvalue: lo,
            }
            .into());
        }
    }
    Ok(())
}

/// In-place Cholesky of a row-major n × n SPD matrix (lower factor); false if not SPD.
fn cholesky(a: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if !(d > 0.0) {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut v = a[i * n + j];
            for k in 0..j {
                v -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = v / d;
        }
    }
    true
}

/// Solves L Lᵀ x = b in place for the lower factor L (row-major).
fn chol_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut v = b[i];
        for k in 0..i {
            v -= l[i * n + k] * b[k];
        }
        b[i] = v / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut v = b[i];
        for k in i + 1..n {
            v -= l[k * n + i] * b[k];
        }
        b[i] = v / l[i * n + i];
    }
}

impl KalmanFilter {
    /// Standard Kalman filter (λ = 1): prior x̄₀ with covariance Π₀ ≻ 0, disturbance
    /// covariance Σ_w ⪰ 0 of w = (w¹, w²) (n_w × n_w) and extra output-noise covariance
    /// Σ_v ⪰ 0 (n_y × n_y). R̄ = F Σ_w,22 Fᵀ + Σ_v must be positive definite.
    pub fn new(
        sys: &LtiSystem,
        prior: &[f64],
        prior_cov: Mat<f64>,
        w_cov: Mat<f64>,
        v_cov: Mat<f64>,
    ) -> Result<Self> {
        Self::with_forgetting(sys, prior, prior_cov, w_cov, v_cov, 1.0)
    }

    /// Fading-memory filter with forgetting factor λ ∈ (0, 1] (see the module docs).
    pub fn with_forgetting(
        sys: &LtiSystem,
        prior: &[f64],
        prior_cov: Mat<f64>,
        w_cov: Mat<f64>,
        v_cov: Mat<f64>,
        lambda: f64,
    ) -> Result<Self> {
        let d = Dims::of(sys);
        if !(lambda > 0.0 && lambda <= 1.0) {
            return Err(MheError::OutOfRange {
                name: "lambda",
                value: lambda,
                range: "(0, 1]",
            });
        }
        check_vec("prior", prior, d.nx)?;
        check_positive_definite("prior_cov", prior_cov.as_ref(), d.nx)?;
        check_psd("w_cov", &w_cov, d.nw())?;
        check_psd("v_cov", &v_cov, d.ny)?;
        let (e, f) = (sys.e(), sys.f());
        let s11 = w_cov.as_ref().submatrix(0, 0, d.nw1, d.nw1);
        let s12 = w_cov.as_ref().submatrix(0, d.nw1, d.nw1, d.nw2);
        let s22 = w_cov.as_ref().submatrix(d.nw1, d.nw1, d.nw2, d.nw2);
        let qbar = e * s11 * e.transpose();
        let rbar = f * s22 * f.transpose() + &v_cov;
        let sbar = e * s12 * f.transpose();
        check_positive_definite("R̄ = F Σ_w,22 Fᵀ + Σ_v", rbar.as_ref(), d.ny)?;
        let (nx, ny) = (d.nx, d.ny);
        let pi0 = row_major(lti_model::matrix::symmetrize(prior_cov.as_ref()).as_ref());
        Ok(Self {
            d,
            a: row_major(sys.a()),
            b: row_major(sys.b()),
            c: row_major(sys.c()),
            qbar: row_major(lti_model::matrix::symmetrize(qbar.as_ref()).as_ref()),
            rbar: row_major(lti_model::matrix::symmetrize(rbar.as_ref()).as_ref()),
            sbar: row_major(sbar.as_ref()),
            lambda,
            x0: prior.to_vec(),
            x: prior.to_vec(),
            pi: pi0.clone(),
            pi0,
            t: 0,
            s: vec![0.0; ny * ny],
            g: vec![0.0; nx * ny],
            k: vec![0.0; nx * ny],
            kw: vec![0.0; nx * ny],
            ap: vec![0.0; nx * nx],
            pi_next: vec![0.0; nx * nx],
            x_next: vec![0.0; nx],
            innov: vec![0.0; ny],
            col: vec![0.0; ny],
        })
    }

    /// The filter whose estimate equals the unconstrained full-information version of the
    /// MHE cost (9) with weights (η, P, Q, R): λ = η, Π₀ = (2P)⁻¹, Σ_w = (2Q)⁻¹, Σ_v = R⁻¹
    /// (derivation in the module docs). Needs η ∈ (0, 1).
    pub fn matching_mhe(
        sys: &LtiSystem,
        prior: &[f64],
        eta: f64,
        p: &Mat<f64>,
        q: &Mat<f64>,
        r: &Mat<f64>,
    ) -> Result<Self> {
        let d = Dims::of(sys);
        if !(eta > 0.0 && eta < 1.0) {
            return Err(MheError::OutOfRange {
                name: "eta",
                value: eta,
                range: "(0, 1) for the fading-memory filter",
            });
        }
        check_positive_definite("P", p.as_ref(), d.nx)?;
        check_positive_definite("Q", q.as_ref(), d.nw())?;
        check_positive_definite("R", r.as_ref(), d.ny)?;
        let inv = |m: &Mat<f64>, scale: f64| -> Mat<f64> {
            let n = m.nrows();
            let lu = m.partial_piv_lu();
            let id = Mat::<f64>::identity(n, n);
            let x = faer::linalg::solvers::Solve::solve(&lu, &id);
            Mat::from_fn(n, n, |i, j| 0.5 * (x[(i, j)] + x[(j, i)]) / scale)
        };
        Self::with_forgetting(sys, prior, inv(p, 2.0), inv(q, 2.0), inv(r, 1.0), eta)
    }

    /// Restarts at t = 0 with prior x̄₀ and the initial covariance Π₀.
    pub fn reset(&mut self, prior: &[f64]) -> Result<()> {
        check_vec("prior", prior, self.d.nx)?;
        self.x0.copy_from_slice(prior);
        self.x.copy_from_slice(prior);
        self.pi.copy_from_slice(&self.pi0);
        self.k.fill(0.0);
        self.t = 0;
        Ok(())
    }

    /// Current time t.
    pub fn t(&self) -> usize {
        self.t
    }
    /// Forgetting factor λ.
    pub fn lambda(&self) -> f64 {
        self.lambda
    }
    /// The scaled covariance Π_t = λ^{−t} cov(x_t | y_0..y_{t−1}), row-major n_x × n_x.
    pub fn covariance(&self) -> &[f64] {
        &self.pi
    }
    /// The gain K of the last update, row-major n_x × n_y (zero before the first push):
    /// x̂_{t+1} = A x̂_t + B u_t + K (y_t − C x̂_t).
    pub fn gain(&self) -> &[f64] {
        &self.k
    }
    /// The current estimate x̂_t (same as [`Estimator::estimate`], without `&mut`).
    pub fn state(&self) -> &[f64] {
        &self.x
    }
}

impl Estimator for KalmanFilter {
    type Error = MheError;
    fn estimate(&mut self) -> Result<&[f64]> {
        Ok(&self.x)
    }

    fn push(&mut self, u: &[f64], y: &[f64]) -> Result<()> {
        let Dims { nx, nu, ny, .. } = self.d;
        check_vec("u", u, nu)?;
        check_vec("y", y, ny)?;
        let lam = self.lambda;
        // AΠ (nx × nx).
        for i in 0..nx {
            for j in 0..nx {
                let mut v = 0.0;
                for k in 0..nx {
                    v += self.a[i * nx + k] * self.pi[k * nx + j];
                }
                self.ap[i * nx + j] = v;
            }
        }
        // G = AΠCᵀ + λS̄ (nx × ny).
        for i in 0..nx {
            for j in 0..ny {
                let mut v = lam * self.sbar[i * ny + j];
                for k in 0..nx {
                    v += self.ap[i * nx + k] * self.c[j * nx + k];
                }
                self.g[i * ny + j] = v;
            }
        }
        // S̃ = CΠCᵀ + λR̄ (ny × ny).
        for i in 0..ny {
            for j in 0..ny {
                let mut v = lam * self.rbar[i * ny + j];
                for k in 0..nx {
                    let mut cp = 0.0;
                    for l in 0..nx {
                        cp += self.c[i * nx + l] * self.pi[l * nx + k];
                    }
                    v += cp * self.c[j * nx + k];
                }
                self.s[i * ny + j] = v;
            }
        }
        if !cholesky(&mut self.s, ny) {
            return Err(MheError::Numerical {
                t: self.t,
                reason: "Kalman filter: innovation covariance lost positive definiteness".into(),
            });
        }
        // K = G S̃⁻¹, row by row: S̃ K_iᵀ = G_iᵀ.
        for i in 0..nx {
            self.col.copy_from_slice(&self.g[i * ny..(i + 1) * ny]);
            chol_solve(&self.s, ny, &mut self.col);
            self.kw[i * ny..(i + 1) * ny].copy_from_slice(&self.col);
        }
        // Innovation and x̂⁺ = A x̂ + B u + K(y − C x̂).
        for i in 0..ny {
            let mut v = y[i];
            for k in 0..nx {
                v -= self.c[i * nx + k] * self.x[k];
            }
            self.innov[i] = v;
        }
        for i in 0..nx {
            let mut v = 0.0;
            for k in 0..nx {
                v += self.a[i * nx + k] * self.x[k];
            }
            for k in 0..nu {
                v += self.b[i * nu + k] * u[k];
            }
            for k in 0..ny {
                v += self.kw[i * ny + k] * self.innov[k];
            }
            self.x_next[i] = v;
        }
        // Π⁺ = λ⁻¹(AΠAᵀ − K Gᵀ) + Q̄  (K S̃ Kᵀ = K Gᵀ), symmetrised.
        for i in 0..nx {
            for j in 0..nx {
                let mut v = 0.0;
                for k in 0..nx {
                    v += self.ap[i * nx + k] * self.a[j * nx + k];
                }
                for k in 0..ny {
                    v -= self.kw[i * ny + k] * self.g[j * ny + k];
                }
                self.pi_next[i * nx + j] = v / lam + self.qbar[i * nx + j];
            }
        }
        if self
            .x_next
            .iter()
            .chain(&self.pi_next)
            .any(|v| !v.is_finite())
        {
            return Err(MheError::Numerical {
                t: self.t,
                reason: "Kalman filter: non-finite update".into(),
            });
        }
        for i in 0..nx {
            for j in 0..nx {
                self.pi[i * nx + j] = 0.5 * (self.pi_next[i * nx + j] + self.pi_next[j * nx + i]);
            }
        }
        self.x.copy_from_slice(&self.x_next);
        self.k.copy_from_slice(&self.kw);
        self.t += 1;
        Ok(())
    }

    fn nx(&self) -> usize {
        self.d.nx
    }
}
