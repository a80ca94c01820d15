//! The plant of eq. (1): x⁺ = Ax + Bu + E w¹, y = Cx + F w² (paper: E = I, F = I).

use faer::{Mat, MatRef};

use crate::error::{ModelError, Result};
use crate::matrix::{check_finite, check_finite_slice, check_len, check_shape};

/// A discrete-time LTI system, eq. (1) of the paper, validated at construction.
///
/// The augmented disturbance is w = (w¹, w²): w¹ ∈ ℝ^{n_w1} enters the state through
/// `E` and w² ∈ ℝ^{n_w2} enters the output through `F`. The paper's setting is E = I_{n_x},
/// F = I_{n_y} (the default of [`LtiSystem::new`]), so w ∈ ℝ^{n_x + n_y}.
///
/// ```
/// use faer::mat;
/// use lti_model::LtiSystem;
/// let sys = LtiSystem::new(
///     mat![[1.0, 0.1], [0.0, 1.0]],
///     mat![[0.0], [0.1]],
///     mat![[1.0, 0.0]],
/// ).unwrap();
/// assert_eq!((sys.nx(), sys.nu(), sys.ny(), sys.nw()), (2, 1, 1, 3));
/// let mut x_next = [0.0; 2];
/// let mut y = [0.0; 1];
/// sys.step(&[1.0, 2.0], &[1.0], &[0.0; 3], &mut x_next, &mut y);
/// assert!((x_next[0] - 1.2).abs() < 1e-12 && (y[0] - 1.0).abs() < 1e-12);
/// ```
#[derive(Debug, Clone)]
pub struct LtiSystem {
    a: Mat<f64>,
    b: Mat<f64>,
    c: Mat<f64>,
    e: Mat<f64>,
    f: Mat<f64>,
}

impl LtiSystem {
    /// System with the paper's disturbance structure: w¹ enters every state, w² every output.
    pub fn new(a: Mat<f64>, b: Mat<f64>, c: Mat<f64>) -> Result<Self> {
        let nx = a.nrows();
        let ny = c.nrows();
        Self::with_disturbance(a, b, c, Mat::identity(nx, nx), Mat::identity(ny, ny))
    }

    /// System with explicit disturbance input matrices `E` (n_x × n_w1) and `F` (n_y × n_w2).
    pub fn with_disturbance(
        a: Mat<f64>,
        b: Mat<f64>,
        c: Mat<f64>,
        e: Mat<f64>,
        f: Mat<f64>,
    ) -> Result<Self> {
        let nx = a.nrows();
        if nx == 0 {
            return Err(ModelError::Shape {
                name: "A".into(),
                expected_rows: 1,
                expected_cols: 1,
                actual_rows: 0,
                actual_cols: a.ncols(),
            });
        }
        check_shape("A", a.as_ref(), nx, nx)?;
        check_shape("B", b.as_ref(), nx, b.ncols())?;
        check_shape("C", c.as_ref(), c.nrows(), nx)?;
        if c.nrows() == 0 {
            return Err(ModelError::Shape {
                name: "C".into(),
                expected_rows: 1,
                expected_cols: nx,
                actual_rows: 0,
                actual_cols: c.ncols(),
            });
        }
        check_shape("E", e.as_ref(), nx, e.ncols())?;
        check_shape("F", f.as_ref(), c.nrows(), f.ncols())?;
        for (name, m) in [("A", &a), ("B", &b), ("C", &c), ("E", &e), ("F", &f)] {
            check_finite(name, m.as_ref())?;
        }
        Ok(Self { a, b, c, e, f })
    }

    /// State dimension n_x.
    pub fn nx(&self) -> usize {
        self.a.nrows()
    }
    /// Input dimension n_u.
    pub fn nu(&self) -> usize {
        self.b.ncols()
    }
    /// Output dimension n_y.
    pub fn ny(&self) -> usize {
        self.c.nrows()
    }
    /// Dimension of w¹ (process disturbance).
    pub fn nw1(&self) -> usize {
        self.e.ncols()
    }
    /// Dimension of w² (measurement noise).
    pub fn nw2(&self) -> usize {
        self.f.ncols()
    }
    /// Dimension of the augmented disturbance w = (w¹, w²).
    pub fn nw(&self) -> usize {
        self.nw1() + self.nw2()
    }
    /// A in eq. (1).
    pub fn a(&self) -> MatRef<'_, f64> {
        self.a.as_ref()
    }
    /// B in eq. (1).
    pub fn b(&self) -> MatRef<'_, f64> {
        self.b.as_ref()
    }
    /// C in eq. (1).
    pub fn c(&self) -> MatRef<'_, f64> {
        self.c.as_ref()
    }
    /// E: how w¹ enters the state (I in the paper).
    pub fn e(&self) -> MatRef<'_, f64> {
        self.e.as_ref()
    }
    /// F: how w² enters the output (I in the paper).
    pub fn f(&self) -> MatRef<'_, f64> {
        self.f.as_ref()
    }

    /// B̄ = [E, 0] of LMI (2): maps w to the state update.
    pub fn b_bar(&self) -> Mat<f64> {
        let (nx, nw1) = (self.nx(), self.nw1());
        Mat::from_fn(
            nx,
            self.nw(),
            |i, j| if j < nw1 { self.e[(i, j)] } else { 0.0 },
        )
    }

    /// D̄ = [0, F] of LMI (2): maps w to the output.
    pub fn d_bar(&self) -> Mat<f64> {
        let nw1 = self.nw1();
        Mat::from_fn(self.ny(), self.nw(), |i, j| {
            if j < nw1 { 0.0 } else { self.f[(i, j - nw1)] }
        })
    }

    /// One step of eq. (1), in place and allocation-free:
    /// `x_next = A x + B u + E w¹`, `y = C x + F w²`, with `w = (w¹, w²)`.
    ///
    /// Lengths are the caller's contract (checked with `debug_assert`); use
    /// [`LtiSystem::checked_step`] for untrusted input.
    pub fn step(&self, x: &[f64], u: &[f64], w: &[f64], x_next: &mut [f64], y: &mut [f64]) {
        debug_assert_eq!(x.len(), self.nx());
        debug_assert_eq!(u.len(), self.nu());
        debug_assert_eq!(w.len(), self.nw());
        let (w1, w2) = w.split_at(self.nw1());
        for i in 0..self.nx() {
            let mut acc = 0.0;
            for j in 0..self.nx() {
                acc += self.a[(i, j)] * x[j];
            }
            for j in 0..self.nu() {
                acc += self.b[(i, j)] * u[j];
            }
            for j in 0..w1.len() {
                acc += self.e[(i, j)] * w1[j];
            }
            x_next[i] = acc;
        }
        self.output(x, w2, y);
    }

    /// y = C x + F w², in place.
    pub fn output(&self, x: &[f64], w2: &[f64], y: &mut [f64]) {
        for i in 0..self.ny() {
            let mut acc = 0.0;
            for j in 0..self.nx() {
                acc += self.c[(i, j)] * x[j];
            }
            for j in 0..w2.len() {
                acc += self.f[(i, j)] * w2[j];
            }
            y[i] = acc;
        }
    }

    /// [`LtiSystem::step`] with length and finiteness checks on every argument.
    pub fn checked_step(
        &self,
        x: &[f64],
        u: &[f64],
        w: &[f64],
        x_next: &mut [f64],
        y: &mut [f64],
    ) -> Result<()> {
        check_len("x", x, self.nx())?;
        check_len("u", u, self.nu())?;
        check_len("w", w, self.nw())?;
        check_len("x_next", x_next, self.nx())?;
        check_len("y", y, self.ny())?;
        check_finite_slice("x", x)?;
        check_finite_slice("u", u)?;
        check_finite_slice("w", w)?;
        self.step(x, u, w, x_next, y);
        Ok(())
    }

    /// Observability matrix [C; CA; …; CA^{n−1}].
    pub fn observability_matrix(&self) -> Mat<f64> {
        let (nx, ny) = (self.nx(), self.ny());
        let mut o = Mat::zeros(nx * ny, nx);
        let mut cak = self.c.clone();
        for k in 0..nx {
            o.as_mut().submatrix_mut(k * ny, 0, ny, nx).copy_from(&cak);
            cak = &cak * &self.a;
        }
        o
    }

    /// Orthonormal basis (columns) of the unobservable subspace ker 𝒪.
    ///
    /// A singular value σ of 𝒪 counts as zero when σ ≤ 1e-9·max(1, σ_max).
    pub fn unobservable_subspace(&self) -> Result<Mat<f64>> {
        let o = self.observability_matrix();
        let svd = o.svd().map_err(|e| ModelError::Numerical {
            routine: "SVD of the observability matrix".into(),
            reason: format!("{e:?}"),
        })?;
        let s = svd.S().column_vector();
        let smax = if s.nrows() > 0 { s[0] } else { 0.0 };
        let tol = 1e-9 * smax.max(1.0);
        let nx = self.nx();
        let rank = (0..s.nrows()).filter(|&i| s[i] > tol).count();
        let v = svd.V();
        Ok(Mat::from_fn(nx, nx - rank, |i, j| v[(i, rank + j)]))
    }

    /// True if (A, C) is observable (numerical rank of 𝒪 is n_x).
    pub fn is_observable(&self) -> Result<bool> {
        Ok(self.unobservable_subspace()?.ncols() == 0)
    }

    /// Spectral radius of A restricted to its unobservable subspace (0 if observable).
    ///
    /// (A, C) is detectable iff this is < 1, and δ-IOSS with decay η (LMI (2)) can only
    /// hold if it is < √η: unobserved modes must decay at least that fast.
    pub fn unobservable_spectral_radius(&self) -> Result<f64> {
        let n = self.unobservable_subspace()?;
        if n.ncols() == 0 {
            return Ok(0.0);
        }
        // ker 𝒪 is A-invariant, so A N = N A_u with A_u = Nᵀ A N (N orthonormal).
        let au = n.transpose() * &self.a * &n;
        spectral_radius(au.as_ref())
    }

    /// True if (A, C) is detectable: every unobservable mode has |λ| < 1.
    pub fn is_detectable(&self) -> Result<bool> {
        Ok(self.unobservable_spectral_radius()? < 1.0)
    }
}

/// An unstable A over a prediction horizon n: ρ(A) > 1 with ρⁿ ≥ 10³, where condensed
/// Hessians lose their weights to rounding. Returns (ρ, ρⁿ, the longest horizon with
/// ρⁿ ≤ 10³, at least 1); None when A is stable enough over n (what the MHE's and the MPC's
/// error messages use to name `plant.a` and the horizon).
///
/// ```
/// let (rho, growth, shorter) = lti_model::system::unstable_over(10.0, 5).unwrap();
/// assert_eq!((rho, growth, shorter), (10.0, 1e5, 3));
/// assert!(lti_model::system::unstable_over(1.1, 5).is_none());
/// ```
pub fn unstable_over(rho: f64, n: usize) -> Option<(f64, f64, usize)> {
    let growth = rho.powi(i32::try_from(n).unwrap_or(i32::MAX));
    // `!(growth < 1e3)` so that an infinite or NaN growth counts as unstable.
    let unstable = rho > 1.0 && !(growth < 1e3);
    if !unstable {
        return None;
    }
    let shorter = if rho.is_finite() {
        ((3.0 / rho.log10()).floor() as usize).max(1)
    } else {
        1
    };
    Some((rho, growth, shorter))
}

/// Spectral radius max |λ_i(M)| of a square matrix.
pub fn spectral_radius(m: MatRef<'_, f64>) -> Result<f64> {
    if m.nrows() == 0 {
        return Ok(0.0);
    }
    let ev = m.eigenvalues().map_err(|e| ModelError::Numerical {
        routine: "eigenvalues".into(),
        reason: format!("{e:?}"),
    })?;
    Ok(ev.iter().map(|z| z.norm()).fold(0.0, f64::max))
}
