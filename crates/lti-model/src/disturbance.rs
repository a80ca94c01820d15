//! Seeded disturbance models for w = (w¹, w²) of eq. (1).
//!
//! Every model owns a [`ChaCha8Rng`] seeded with `seed_from_u64`, so one seed gives one
//! sequence on every machine and for every thread count (ChaCha is portable and each
//! model has its own stream; sweeps derive the seed from (base seed, run index)).
//! [`Disturbance::sample`] writes into a caller buffer and allocates nothing, so it can
//! sit in the closed-loop hot path.

use faer::{Mat, MatRef, Side};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::error::{ModelError, Result};
use crate::matrix::{check_finite_slice, check_len, check_positive_definite, symmetrize};
use crate::sets::{BoxSet, ConvexSet};

/// A random disturbance source w ∈ ℝ^dim.
///
/// ```
/// use lti_model::disturbance::{Disturbance, UniformBox};
/// let mut w = UniformBox::new(vec![-0.1; 3], vec![0.1; 3], 7).unwrap();
/// let mut out = [0.0; 3];
/// w.sample(&mut out);
/// assert!(out.iter().all(|v| v.abs() <= 0.1));
/// ```
pub trait Disturbance: Send + std::fmt::Debug {
    /// Dimension of w.
    fn dim(&self) -> usize;

    /// Draws the next w into `out` without allocating.
    ///
    /// `out.len()` must equal [`Disturbance::dim`] (debug-asserted; in release builds only
    /// the first min(len, dim) entries are written).
    fn sample(&mut self, out: &mut [f64]);

    /// Restarts the stream: after `reseed(s)` the model draws what a fresh model built with
    /// seed `s` draws.
    fn reseed(&mut self, seed: u64);

    /// The next `steps` draws, one `Vec` each (allocating; for tests and plots).
    ///
    /// ```
    /// use lti_model::disturbance::{Disturbance, Zero};
    /// assert_eq!(Zero(2).sequence(3), vec![vec![0.0; 2]; 3]);
    /// ```
    fn sequence(&mut self, steps: usize) -> Vec<Vec<f64>> {
        (0..steps)
            .map(|_| {
                let mut w = vec![0.0; self.dim()];
                self.sample(&mut w);
                w
            })
            .collect()
    }
}

impl<D: Disturbance + ?Sized> Disturbance for Box<D> {
    fn dim(&self) -> usize {
        (**self).dim()
    }
    fn sample(&mut self, out: &mut [f64]) {
        (**self).sample(out);
    }
    fn reseed(&mut self, seed: u64) {
        (**self).reseed(seed);
    }
}

/// No disturbance: w = 0 ∈ ℝ^dim (nominal runs).
///
/// ```
/// use lti_model::disturbance::{Disturbance, Zero};
/// let mut out = [1.0; 2];
/// Zero(2).sample(&mut out);
/// assert_eq!(out, [0.0, 0.0]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Zero(pub usize);

impl Disturbance for Zero {
    fn dim(&self) -> usize {
        self.0
    }
    fn sample(&mut self, out: &mut [f64]) {
        debug_assert_eq!(out.len(), self.0);
        out.fill(0.0);
    }
    fn reseed(&mut self, _seed: u64) {}
}

/// Each entry independently uniform on [l_i, u_i]: the case study's 𝒲 = [−0.1, 0.1]^{n_w}
/// (design notes §4), so every draw lies in 𝒲 as the paper's analysis assumes.
///
/// ```
/// use lti_model::disturbance::{Disturbance, UniformBox};
/// let mut w = UniformBox::new(vec![0.0, -2.0], vec![1.0, -1.0], 42).unwrap();
/// let seq = w.sequence(100);
/// assert!(seq.iter().all(|v| (0.0..=1.0).contains(&v[0]) && (-2.0..=-1.0).contains(&v[1])));
/// ```
#[derive(Debug, Clone)]
pub struct UniformBox {
    set: BoxSet,
    width: Vec<f64>,
    rng: ChaCha8Rng,
}

impl UniformBox {
    /// Uniform on the box [lower, upper]. The bounds follow the [`BoxSet`] rules (equal
    /// lengths, no NaN, lower ≤ upper) and must also be finite with a finite width;
    /// violations are `InvalidSet` naming `"W"`.
    pub fn new(lower: Vec<f64>, upper: Vec<f64>, seed: u64) -> Result<Self> {
        Self::from_box(&BoxSet::named("W", lower, upper)?, seed)
    }

    /// Uniform on a validated box, which must be bounded (`InvalidSet` naming `"W"`
    /// otherwise).
    ///
    /// ```
    /// use lti_model::{BoxSet, disturbance::UniformBox};
    /// let w = BoxSet::symmetric(&[0.1, 0.1]).unwrap();
    /// assert!(UniformBox::from_box(&w, 0).is_ok());
    /// assert!(UniformBox::from_box(&BoxSet::whole(2), 0).is_err());
    /// ```
    pub fn from_box(set: &BoxSet, seed: u64) -> Result<Self> {
        let mut width = Vec::with_capacity(set.lower().len());
        for (i, (&l, &u)) in set.lower().iter().zip(set.upper()).enumerate() {
            let w = u - l;
            if !(l.is_finite() && u.is_finite() && w.is_finite()) {
                return Err(ModelError::InvalidSet {
                    name: "W".into(),
                    reason: format!(
                        "bound {i} is [{l}, {u}]: a uniform disturbance needs finite bounds with a finite width"
                    ),
                });
            }
            width.push(w);
        }
        Ok(Self {
            set: set.clone(),
            width,
            rng: ChaCha8Rng::seed_from_u64(seed),
        })
    }

    /// Lower bounds l.
    pub fn lower(&self) -> &[f64] {
        self.set.lower()
    }
    /// Upper bounds u.
    pub fn upper(&self) -> &[f64] {
        self.set.upper()
    }
    /// The box 𝒲 the draws lie in.
    pub fn set(&self) -> &BoxSet {
        &self.set
    }
}

impl Disturbance for UniformBox {
    fn dim(&self) -> usize {
        self.width.len()
    }
    #[inline]
    fn sample(&mut self, out: &mut [f64]) {
        debug_assert_eq!(out.len(), self.width.len());
        let bounds = self.set.lower().iter().zip(self.set.upper());
        for ((o, (&l, &u)), &w) in out.iter_mut().zip(bounds).zip(&self.width) {
            let t: f64 = self.rng.random();
            // l + w·t with t ∈ [0, 1) can round past u; clamp keeps every draw in 𝒲.
            *o = (l + w * t).clamp(l, u);
        }
    }
    fn reseed(&mut self, seed: u64) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
    }
}

/// Gaussian w = μ + L·ξ with ξ ~ N(0, I) and L the lower Cholesky factor of the covariance
/// Σ = LLᵀ ≻ 0. Unbounded: draws can leave any box 𝒲, so use it for robustness studies,
/// not where the analysis assumes w ∈ 𝒲.
///
/// ```
/// use faer::mat;
/// use lti_model::disturbance::{Disturbance, Gaussian};
/// let mut w = Gaussian::new(vec![1.0, 0.0], mat![[0.04, 0.0], [0.0, 0.01]], 3).unwrap();
/// let mut out = [0.0; 2];
/// w.sample(&mut out);
/// assert!(out.iter().all(|v| v.is_finite()));
/// ```
#[derive(Debug, Clone)]
pub struct Gaussian {
    mean: Vec<f64>,
    covariance: Mat<f64>,
    chol: Mat<f64>,
    xi: Vec<f64>,
    rng: ChaCha8Rng,
}

impl Gaussian {
    /// Gaussian with the given mean (finite, `"mean"`) and covariance (n × n, finite,
    /// symmetric, positive definite, `"covariance"`).
    pub fn new(mean: Vec<f64>, covariance: Mat<f64>, seed: u64) -> Result<Self> {
        let n = mean.len();
        check_finite_slice("mean", &mean)?;
        check_positive_definite("covariance", covariance.as_ref(), n)?;
        let covariance = symmetrize(covariance.as_ref());
        let llt = covariance
            .llt(Side::Lower)
            .map_err(|_| ModelError::NotPositiveDefinite {
                name: "covariance".into(),
                min_eigenvalue: 0.0,
            })?;
        let chol = llt.L().to_owned();
        Ok(Self {
            mean,
            covariance,
            chol,
            xi: vec![0.0; n],
            rng: ChaCha8Rng::seed_from_u64(seed),
        })
    }

    /// Independent entries with the given mean and standard deviations σ_i > 0
    /// (`"std"`: `Shape` on a length mismatch, `NotPositiveDefinite` if some σ_i ≤ 0).
    ///
    /// ```
    /// use lti_model::disturbance::Gaussian;
    /// let g = Gaussian::diagonal(vec![0.0; 2], &[0.1, 0.2], 1).unwrap();
    /// assert!((g.covariance()[(1, 1)] - 0.04).abs() < 1e-15);
    /// ```
    pub fn diagonal(mean: Vec<f64>, std: &[f64], seed: u64) -> Result<Self> {
        check_len("std", std, mean.len())?;
        check_finite_slice("std", std)?;
        if let Some(&s) = std.iter().find(|s| !(**s > 0.0)) {
            return Err(ModelError::NotPositiveDefinite {
                name: "std".into(),
                min_eigenvalue: s,
            });
        }
        let cov = Mat::from_fn(std.len(), std.len(), |i, j| {
            if i == j { std[i] * std[i] } else { 0.0 }
        });
        Self::new(mean, cov, seed)
    }

    /// Mean μ.
    pub fn mean(&self) -> &[f64] {
        &self.mean
    }
    /// Covariance Σ (symmetrised).
    pub fn covariance(&self) -> MatRef<'_, f64> {
        self.covariance.as_ref()
    }
    /// Lower Cholesky factor L with Σ = LLᵀ.
    pub fn cholesky_factor(&self) -> MatRef<'_, f64> {
        self.chol.as_ref()
    }
}

impl Disturbance for Gaussian {
    fn dim(&self) -> usize {
        self.mean.len()
    }
    fn sample(&mut self, out: &mut [f64]) {
        debug_assert_eq!(out.len(), self.mean.len());
        for x in &mut self.xi {
            *x = self.rng.sample(StandardNormal);
        }
        for (i, o) in out.iter_mut().enumerate().take(self.mean.len()) {
            let mut acc = self.mean[i];
            for j in 0..=i {
                acc += self.chol[(i, j)] * self.xi[j];
            }
            *o = acc;
        }
    }
    fn reseed(&mut self, seed: u64) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
    }
}

/// Independent truncated normal entries: w_i ~ N(μ_i, σ_i²) conditioned on
/// l_i ≤ w_i ≤ u_i (the classic bounded-noise experiment, e.g. Rao, Rawlings and Lee's
/// nonnegative noise: l = 0, u = ∞). μ is the location of the underlying normal, not the
/// mean of the truncated law.
///
/// ## Method
///
/// Exact per-component rejection sampling (C. P. Robert, "Simulation of truncated normal
/// variables", Statistics and Computing 5, 1995), on the standardised interval [α, β]:
/// a normal proposal when the interval holds 0 and is wide (acceptance ≥ 0.49); a uniform
/// proposal on [α, β] with acceptance exp((m² − z²)/2) (m the point of [α, β] nearest 0)
/// when it is short; Robert's exponential proposal with rate (α + √(α² + 4))/2 for a wide
/// interval in the tail. Every branch accepts with probability ≥ 0.04, so a draw costs a few
/// random numbers on average; it allocates nothing. σ_i = 0 gives w_i = μ_i (which must lie
/// in [l_i, u_i]).
///
/// ```
/// use lti_model::disturbance::{Disturbance, TruncatedNormal};
/// let mut w = TruncatedNormal::new(vec![0.0, 1.0], vec![1.0, 0.5],
///     vec![0.0, f64::NEG_INFINITY], vec![f64::INFINITY, 1.2], 5).unwrap();
/// for v in w.sequence(200) {
///     assert!(v[0] >= 0.0 && v[1] <= 1.2);
/// }
/// ```
#[derive(Debug, Clone)]
pub struct TruncatedNormal {
    mean: Vec<f64>,
    std: Vec<f64>,
    /// Standardised bounds α_i = (l_i − μ_i)/σ_i, β_i = (u_i − μ_i)/σ_i.
    alpha: Vec<f64>,
    beta: Vec<f64>,
    set: BoxSet,
    rng: ChaCha8Rng,
}

/// Draws z ~ N(0, 1) conditioned on α ≤ z ≤ β (α < β, not both infinite on one side).
fn truncated_standard(rng: &mut ChaCha8Rng, alpha: f64, beta: f64) -> f64 {
    if beta <= 0.0 && alpha < beta {
        // Mirror the left tail onto the right.
        return -truncated_standard(rng, -beta, -alpha);
    }
    // Now β > 0. Short interval: uniform proposal.
    let width = beta - alpha;
    let m = alpha.max(0.0);
    let short = if alpha <= 0.0 {
        width < 2.5
    } else {
        width <= 1.0 / alpha.max(0.5)
    };
    loop {
        let z = if short {
            let z = alpha + width * rng.random::<f64>();
            let ratio = ((m * m - z * z) / 2.0).exp();
            if rng.random::<f64>() > ratio {
                continue;
            }
            z
        } else if alpha <= 0.0 {
            // Holds 0 and is wide: normal proposal.
            let z: f64 = rng.sample(StandardNormal);
            if z < alpha || z > beta {
                continue;
            }
            z
        } else {
            // Right tail: Robert's exponential proposal.
            let lambda = (alpha + (alpha * alpha + 4.0).sqrt()) / 2.0;
            let u: f64 = rng.random();
            let z = alpha - (1.0 - u).ln() / lambda;
            let ratio = (-(z - lambda) * (z - lambda) / 2.0).exp();
            if z > beta || rng.random::<f64>() > ratio {
                continue;
            }
            z
        };
        return z;
    }
}

impl TruncatedNormal {
    /// Independent N(μ_i, σ_i²) truncated to [l_i, u_i]. μ finite (`"mean"`), σ_i ≥ 0
    /// finite (`"std"`), the bounds a valid box (`"truncation"`: no NaN, l ≤ u, infinite
    /// bounds allowed) with l_i < u_i when σ_i > 0 and μ_i ∈ [l_i, u_i] when σ_i = 0.
    pub fn new(
        mean: Vec<f64>,
        std: Vec<f64>,
        lower: Vec<f64>,
        upper: Vec<f64>,
        seed: u64,
    ) -> Result<Self> {
        let n = mean.len();
        check_finite_slice("mean", &mean)?;
        check_len("std", &std, n)?;
        check_finite_slice("std", &std)?;
        let set = BoxSet::named("truncation", lower, upper)?;
        if set.dim() != n {
            return Err(ModelError::Shape {
                name: "truncation".into(),
                expected_rows: n,
                expected_cols: 1,
                actual_rows: set.dim(),
                actual_cols: 1,
            });
        }
        let (mut alpha, mut beta) = (vec![0.0; n], vec![0.0; n]);
        for i in 0..n {
            let (l, u, mu, s) = (set.lower()[i], set.upper()[i], mean[i], std[i]);
            if !(s >= 0.0) {
                return Err(ModelError::InvalidSet {
                    name: "std".into(),
                    reason: format!("σ_{i} = {s} is negative; a standard deviation is ≥ 0"),
                });
            }
            if s == 0.0 {
                if !(l <= mu && mu <= u) {
                    return Err(ModelError::InvalidSet {
                        name: "truncation".into(),
                        reason: format!(
                            "component {i} has σ = 0 and location {mu} outside [{l}, {u}]: the law is empty"
                        ),
                    });
                }
                continue;
            }
            if !(l < u) {
                return Err(ModelError::InvalidSet {
                    name: "truncation".into(),
                    reason: format!(
                        "component {i} is [{l}, {u}], a single point: a truncated normal needs l < u"
                    ),
                });
            }
            alpha[i] = (l - mu) / s;
            beta[i] = (u - mu) / s;
        }
        Ok(Self {
            mean,
            std,
            alpha,
            beta,
            set,
            rng: ChaCha8Rng::seed_from_u64(seed),
        })
    }

    /// Locations μ of the underlying normals.
    pub fn mean(&self) -> &[f64] {
        &self.mean
    }
    /// Standard deviations σ of the underlying normals.
    pub fn std(&self) -> &[f64] {
        &self.std
    }
    /// The truncation box every draw lies in.
    pub fn set(&self) -> &BoxSet {
        &self.set
    }
}

impl Disturbance for TruncatedNormal {
    fn dim(&self) -> usize {
        self.mean.len()
    }
    fn sample(&mut self, out: &mut [f64]) {
        debug_assert_eq!(out.len(), self.mean.len());
        for (i, o) in out.iter_mut().enumerate().take(self.mean.len()) {
            let (mu, s) = (self.mean[i], self.std[i]);
            *o = if s == 0.0 {
                mu
            } else {
                let z = truncated_standard(&mut self.rng, self.alpha[i], self.beta[i]);
                (mu + s * z).clamp(self.set.lower()[i], self.set.upper()[i])
            };
        }
    }
    fn reseed(&mut self, seed: u64) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
    }
}
