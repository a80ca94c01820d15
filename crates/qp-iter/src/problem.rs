//! Parametric QP data: min ½zᵀHz + (q₀ + Fθ)ᵀz s.t. z ∈ Z and, optionally,
//! l₀ − Eθ ≤ Gz ≤ u₀ − Eθ ([`GeneralConstraints`]).

use crate::matrix::{
    check_finite, check_finite_slice, check_len, check_positive_definite, check_shape,
};
use crate::{BoxSet, ConvexSet};
use faer::{Mat, MatRef};

use crate::error::{QpError, Result};
use crate::operator::HessianOperator;

/// A strongly convex parametric QP over a box: min ½zᵀHz + (q₀ + Fθ)ᵀz s.t. z ∈ Z.
///
/// Validated at construction: H symmetric positive definite and finite, q₀ of length n,
/// F of shape n × n_θ, Z of dimension n. Caches μ = λ_min(H), L = λ_max(H) and a
/// row-major copy of H for the hot loop.
///
/// ```
/// use faer::{mat, Mat};
/// use qp_iter::BoxSet;
/// use qp_iter::ParametricQp;
/// let qp = ParametricQp::new(
///     mat![[2.0, 0.0], [0.0, 1.0]], vec![0.0, 0.0], Mat::identity(2, 2),
///     BoxSet::symmetric(&[1.0, 1.0]).unwrap(),
/// ).unwrap();
/// assert_eq!((qp.n(), qp.n_theta()), (2, 2));
/// assert!((qp.mu() - 1.0).abs() < 1e-12 && (qp.l() - 2.0).abs() < 1e-12);
/// ```
#[derive(Debug, Clone)]
pub struct ParametricQp {
    h: Mat<f64>,
    h_rows: Vec<f64>,
    q0: Vec<f64>,
    f: Mat<f64>,
    f_rows: Vec<f64>,
    zset: BoxSet,
    mu: f64,
    l: f64,
    /// A structured product z ↦ Hz equal to the dense one ([`crate::operator`]).
    op: Option<std::sync::Arc<dyn HessianOperator>>,
    /// Optional rows l₀ − Eθ ≤ Gz ≤ u₀ − Eθ besides the box.
    general: Option<std::sync::Arc<GeneralConstraints>>,
}

/// General constraints l₀ − Eθ ≤ Gz ≤ u₀ − Eθ whose bounds move with the parameter θ (the
/// MHE's state and output rows depend on the inputs in θ, the MPC's state rows on x̂).
///
/// Validated at construction: G (m × n) and E (m × n_θ) finite, bounds of length m with
/// ±∞ allowed per side, no NaN, l₀ ≤ u₀, l₀ ≠ +∞ and u₀ ≠ −∞. The column counts are checked
/// against the problem by [`ParametricQp::with_general`].
///
/// ```
/// use faer::{mat, Mat};
/// use qp_iter::problem::GeneralConstraints;
/// // z₀ + z₁ ≤ 1 − θ₀, no lower bound.
/// let gc = GeneralConstraints::new(mat![[1.0, 1.0]], mat![[1.0]],
///     vec![f64::NEG_INFINITY], vec![1.0]).unwrap();
/// let (mut lo, mut hi) = ([0.0], [0.0]);
/// gc.bounds(&[0.25], &mut lo, &mut hi);
/// assert_eq!((lo[0], hi[0]), (f64::NEG_INFINITY, 0.75));
/// ```
#[derive(Debug, Clone)]
pub struct GeneralConstraints {
    g: Mat<f64>,
    e: Mat<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    /// G row-major (m × n).
    g_rows: Vec<f64>,
    /// E row-major (m × n_θ).
    e_rows: Vec<f64>,
}

impl GeneralConstraints {
    /// Validates and builds the rows (see the type's documentation).
    pub fn new(g: Mat<f64>, e: Mat<f64>, lower: Vec<f64>, upper: Vec<f64>) -> Result<Self> {
        let m = g.nrows();
        check_finite("G", g.as_ref())?;
        check_shape("E", e.as_ref(), m, e.ncols())?;
        check_finite("E", e.as_ref())?;
        check_len("G lower bounds", &lower, m)?;
        check_len("G upper bounds", &upper, m)?;
        for i in 0..m {
            let (l, u) = (lower[i], upper[i]);
            if l.is_nan() || u.is_nan() || l > u || l == f64::INFINITY || u == f64::NEG_INFINITY {
                return Err(crate::DataError::InvalidSet {
                    name: "G rows".into(),
                    reason: format!(
                        "row {i} has bounds [{l}, {u}]; each row needs lower ≤ upper, no NaN, \
                         lower < +∞ and upper > −∞"
                    ),
                }
                .into());
            }
        }
        let g_rows = crate::matrix::row_major(g.as_ref());
        let e_rows = crate::matrix::row_major(e.as_ref());
        Ok(Self {
            g,
            e,
            lower,
            upper,
            g_rows,
            e_rows,
        })
    }

    /// Number of rows m.
    pub fn m(&self) -> usize {
        self.g.nrows()
    }
    /// G (m × n).
    pub fn g(&self) -> MatRef<'_, f64> {
        self.g.as_ref()
    }
    /// G row-major (length m·n), for kernels.
    pub fn g_row_major(&self) -> &[f64] {
        &self.g_rows
    }
    /// E (m × n_θ).
    pub fn e(&self) -> MatRef<'_, f64> {
        self.e.as_ref()
    }
    /// l₀.
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }
    /// u₀.
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }

    /// The bounds for θ: `lo` = l₀ − Eθ, `hi` = u₀ − Eθ (±∞ stay ±∞). Allocation-free;
    /// lengths are debug-asserted.
    #[inline]
    pub fn bounds(&self, theta: &[f64], lo: &mut [f64], hi: &mut [f64]) {
        let (m, nt) = (self.m(), self.e.ncols());
        debug_assert_eq!(theta.len(), nt);
        debug_assert!(lo.len() == m && hi.len() == m);
        for i in 0..m {
            let row = &self.e_rows[i * nt..(i + 1) * nt];
            let et: f64 = row.iter().zip(theta).map(|(a, b)| a * b).sum();
            lo[i] = self.lower[i] - et;
            hi[i] = self.upper[i] - et;
        }
    }

    /// (Gz)_i for one row.
    #[inline]
    pub fn row_dot(&self, i: usize, z: &[f64]) -> f64 {
        let n = self.g.ncols();
        self.g_rows[i * n..(i + 1) * n]
            .iter()
            .zip(z)
            .map(|(a, b)| a * b)
            .sum()
    }

    /// max_i max(lo_i − (Gz)_i, (Gz)_i − hi_i, 0): the largest violation of the rows by z
    /// for the bounds `lo`, `hi` (from [`GeneralConstraints::bounds`]). Allocation-free.
    pub fn violation(&self, z: &[f64], lo: &[f64], hi: &[f64]) -> f64 {
        let mut v = 0.0f64;
        for i in 0..self.m() {
            let gz = self.row_dot(i, z);
            v = v.max(lo[i] - gz).max(gz - hi[i]);
        }
        v
    }
}

impl ParametricQp {
    /// Validates and builds the problem.
    pub fn new(h: Mat<f64>, q0: Vec<f64>, f: Mat<f64>, zset: BoxSet) -> Result<Self> {
        let n = h.nrows();
        let (mu, l) = check_positive_definite("H", h.as_ref(), n)?;
        check_len("q0", &q0, n)?;
        check_finite_slice("q0", &q0)?;
        check_shape("F", f.as_ref(), n, f.ncols())?;
        check_finite("F", f.as_ref())?;
        if zset.dim() != n {
            return Err(crate::DataError::Shape {
                name: "Z".into(),
                expected_rows: n,
                expected_cols: 1,
                actual_rows: zset.dim(),
                actual_cols: 1,
            }
            .into());
        }
        // Symmetrise exactly so that the hot loop sees a symmetric H.
        let h = crate::matrix::symmetrize(h.as_ref());
        let h_rows = (0..n * n).map(|k| h[(k / n, k % n)]).collect();
        let nt = f.ncols();
        let f_rows = (0..n * nt).map(|k| f[(k / nt, k % nt)]).collect();
        Ok(Self {
            h,
            h_rows,
            q0,
            f,
            f_rows,
            zset,
            mu,
            l,
            op: None,
            general: None,
        })
    }

    /// Adds general constraints l₀ − Eθ ≤ Gz ≤ u₀ − Eθ (G with n columns, E with n_θ).
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use qp_iter::BoxSet;
    /// use qp_iter::ParametricQp;
    /// use qp_iter::problem::GeneralConstraints;
    /// let qp = ParametricQp::new(Mat::identity(2, 2), vec![0.0; 2], Mat::zeros(2, 1),
    ///     BoxSet::whole(2)).unwrap();
    /// let gc = GeneralConstraints::new(mat![[1.0, 1.0]], mat![[1.0]], vec![-1.0], vec![1.0])
    ///     .unwrap();
    /// let qp = qp.with_general(gc).unwrap();
    /// assert_eq!(qp.general().unwrap().m(), 1);
    /// ```
    pub fn with_general(mut self, gc: GeneralConstraints) -> Result<Self> {
        check_shape("G", gc.g(), gc.m(), self.n())?;
        check_shape("E", gc.e(), gc.m(), self.n_theta())?;
        self.general = (gc.m() > 0).then(|| std::sync::Arc::new(gc));
        Ok(self)
    }

    /// The general constraints, if the problem has any (m > 0).
    pub fn general(&self) -> Option<&GeneralConstraints> {
        self.general.as_deref()
    }

    /// The same problem without its general constraints (the box-only relaxation).
    pub fn without_general(&self) -> Self {
        let mut p = self.clone();
        p.general = None;
        p
    }

    /// The largest violation of the constraints by z for parameter θ: the box
    /// max(l − z, z − u) and, with general rows, max(l₀ − Eθ − Gz, Gz − u₀ + Eθ); 0 if z is
    /// feasible. Allocates nothing; `gbuf` must hold 2m entries (m = rows of G, 0 without).
    pub fn violation(&self, z: &[f64], theta: &[f64], gbuf: &mut [f64]) -> f64 {
        let mut v = 0.0f64;
        for ((zi, l), u) in z.iter().zip(self.zset.lower()).zip(self.zset.upper()) {
            v = v.max(l - zi).max(zi - u);
        }
        if let Some(gc) = self.general() {
            let (lo, hi) = gbuf[..2 * gc.m()].split_at_mut(gc.m());
            gc.bounds(theta, lo, hi);
            v = v.max(gc.violation(z, lo, hi));
        }
        v
    }

    /// Attaches a structured Hessian operator (it must compute the same Hz; projected
    /// gradient and FISTA use it from its
    /// [`dense_crossover`](crate::operator::HessianOperator::dense_crossover) variables).
    pub fn with_operator(mut self, op: std::sync::Arc<dyn HessianOperator>) -> Result<Self> {
        if op.n() != self.n() {
            return Err(QpError::Parameter {
                name: "operator".into(),
                value: op.n() as f64,
                reason: format!(
                    "the Hessian operator acts on {} variables, H on {}",
                    op.n(),
                    self.n()
                ),
            });
        }
        self.op = Some(op);
        Ok(self)
    }

    /// The structured Hessian operator, if the problem has one.
    pub fn operator(&self) -> Option<&std::sync::Arc<dyn HessianOperator>> {
        self.op.as_ref()
    }

    /// Number of decision variables n.
    pub fn n(&self) -> usize {
        self.h.nrows()
    }
    /// Number of parameters n_θ.
    pub fn n_theta(&self) -> usize {
        self.f.ncols()
    }
    /// H.
    pub fn h(&self) -> MatRef<'_, f64> {
        self.h.as_ref()
    }
    /// H row-major (length n²), for kernels.
    pub fn h_row_major(&self) -> &[f64] {
        &self.h_rows
    }
    /// q₀.
    pub fn q0(&self) -> &[f64] {
        &self.q0
    }
    /// F.
    pub fn f(&self) -> MatRef<'_, f64> {
        self.f.as_ref()
    }
    /// The feasible box Z.
    pub fn zset(&self) -> &BoxSet {
        &self.zset
    }
    /// μ = λ_min(H): strong-convexity modulus.
    pub fn mu(&self) -> f64 {
        self.mu
    }
    /// L = λ_max(H): gradient Lipschitz constant.
    pub fn l(&self) -> f64 {
        self.l
    }
    /// Condition number κ = L/μ.
    pub fn kappa(&self) -> f64 {
        self.l / self.mu
    }

    /// Writes q = q₀ + Fθ into `q` (allocation-free). Lengths are debug-asserted.
    #[inline]
    pub fn linear_term(&self, theta: &[f64], q: &mut [f64]) {
        let (n, nt) = (self.n(), self.n_theta());
        debug_assert_eq!(theta.len(), nt);
        debug_assert_eq!(q.len(), n);
        for i in 0..n {
            let row = &self.f_rows[i * nt..(i + 1) * nt];
            let mut acc = self.q0[i];
            for (a, b) in row.iter().zip(theta) {
                acc += a * b;
            }
            q[i] = acc;
        }
    }

    /// Π_Z(x) in place, keeping NaN as NaN (`min(u, max(l, x))`, the operand order of
    /// [`crate::kernel`]'s clamp), so a NaN produced during iteration reaches the drivers'
    /// finiteness check instead of being clamped onto a bound. Allocation-free.
    ///
    /// ```
    /// use faer::Mat;
    /// use qp_iter::BoxSet;
    /// use qp_iter::ParametricQp;
    /// let qp = ParametricQp::new(Mat::identity(2, 2), vec![0.0; 2], Mat::zeros(2, 0),
    ///     BoxSet::symmetric(&[1.0, 1.0]).unwrap()).unwrap();
    /// let mut x = [3.0, f64::NAN];
    /// qp.project(&mut x);
    /// assert!(x[0] == 1.0 && x[1].is_nan());
    /// ```
    #[inline]
    pub fn project(&self, x: &mut [f64]) {
        for ((xi, &l), &u) in x.iter_mut().zip(self.zset.lower()).zip(self.zset.upper()) {
            let w = if l > *xi { l } else { *xi };
            *xi = if u < w { u } else { w };
        }
    }

    /// Objective ½zᵀHz + qᵀz for a given linear term q.
    pub fn objective(&self, q: &[f64], z: &[f64]) -> f64 {
        let n = self.n();
        let mut val = 0.0;
        for i in 0..n {
            let mut hz = 0.0;
            for j in 0..n {
                hz += self.h_rows[i * n + j] * z[j];
            }
            val += z[i] * (0.5 * hz + q[i]);
        }
        val
    }

    /// Validated θ: length n_θ and finite (for callers outside the hot loop).
    pub fn check_theta(&self, theta: &[f64]) -> Result<()> {
        check_len("theta", theta, self.n_theta())?;
        check_finite_slice("theta", theta)?;
        Ok(())
    }
}
