//! Shared fixtures for the criterion benchmarks of the iteration maps Φ (`qp-iter`).
//!
//! - [`random_instance`]: a seeded random strongly convex box-constrained QP of size n
//!   with condition number [`KAPPA`] and an active box (the stand-in for the case-study
//!   MHE QP until `mhe-core` provides it).
//! - [`FixedMatVec`]: the *reference kernel* of the performance target — a hand-written
//!   N × N matrix–vector product with compile-time dimensions, compiled for AVX2 + FMA via
//!   `#[target_feature]` and selected by run-time detection, so the portable build has it.
//!   Per-iteration times are reported as ratios to it.
//! - [`case_study`]: the real case-study MHE QPs from `mhe-core` along a simulated
//!   closed-loop trajectory (paper preset M = 5, certified preset M = 9).
//! - [`interleave`]: round-robin timing of several variants (fastest and median batch).

pub mod case_study;
pub mod uncondensed;

use faer::Mat;
use lti_model::BoxSet;
use qp_iter::ParametricQp;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Condition number κ = L/μ of every benchmark Hessian.
pub const KAPPA: f64 = 100.0;

/// Number of parameters θ of the benchmark QPs (q = q₀ + Fθ).
pub const N_THETA: usize = 4;

/// A benchmark problem: the QP and one parameter value θ.
#[derive(Debug, Clone)]
pub struct Instance {
    /// The QP: min ½zᵀHz + (q₀ + Fθ)ᵀz s.t. z ∈ [−1, 1]ⁿ.
    pub qp: ParametricQp,
    /// The parameter loaded before solving.
    pub theta: Vec<f64>,
}

/// Random SPD matrix Q diag(λ) Qᵀ with Q orthogonal (QR of a uniform random matrix) and
/// eigenvalues λ log-spaced from 1 to κ, so μ = 1 and L = κ exactly.
pub fn random_spd(n: usize, kappa: f64, rng: &mut ChaCha8Rng) -> Mat<f64> {
    let a = Mat::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
    let q = a.qr().compute_Q();
    let lam: Vec<f64> = (0..n)
        .map(|i| {
            if n == 1 {
                1.0
            } else {
                kappa.powf(i as f64 / (n - 1) as f64)
            }
        })
        .collect();
    Mat::from_fn(n, n, |i, j| {
        (0..n).map(|k| q[(i, k)] * lam[k] * q[(j, k)]).sum()
    })
}

/// Seeded random instance of size n: H with κ = [`KAPPA`]; q₀ = −H z_u for a random
/// unconstrained minimiser z_u ∈ [−2, 2]ⁿ, so that roughly half of the box [−1, 1]ⁿ is
/// active at the solution; F and θ random with entries in [−0.5, 0.5].
///
/// ```
/// let inst = benches::random_instance(12, 1);
/// assert_eq!(inst.qp.n(), 12);
/// assert!((inst.qp.kappa() - benches::KAPPA).abs() < 1e-6 * benches::KAPPA);
/// ```
pub fn random_instance(n: usize, seed: u64) -> Instance {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let h = random_spd(n, KAPPA, &mut rng);
    let zu: Vec<f64> = (0..n).map(|_| rng.random_range(-2.0..2.0)).collect();
    let q0: Vec<f64> = (0..n)
        .map(|i| -(0..n).map(|j| h[(i, j)] * zu[j]).sum::<f64>())
        .collect();
    let f = Mat::from_fn(n, N_THETA, |_, _| rng.random_range(-0.5..0.5));
    let theta = (0..N_THETA).map(|_| rng.random_range(-0.5..0.5)).collect();
    let zset = match BoxSet::symmetric(&vec![1.0; n]) {
        Ok(b) => b,
        Err(e) => panic!("unit box is valid: {e}"),
    };
    match ParametricQp::new(h, q0, f, zset) {
        Ok(qp) => Instance { qp, theta },
        Err(e) => panic!("random_instance({n}, {seed}) is SPD by construction: {e}"),
    }
}

/// Euclidean distance ‖a − b‖₂.
pub use lti_model::vecmath::dist2 as dist;

/// One timed variant of [`interleave`]: `run` does `per_call` operations per call.
pub struct Variant<'a> {
    /// Name in reports.
    pub name: String,
    /// Operations one call of `run` performs (the reported time is per operation).
    pub per_call: f64,
    /// One batch.
    pub run: Box<dyn FnMut() + 'a>,
}

impl std::fmt::Debug for Variant<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Variant")
            .field("name", &self.name)
            .field("per_call", &self.per_call)
            .finish_non_exhaustive()
    }
}

/// Fastest and median time per operation of a variant over the rounds of [`interleave`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Fastest batch, ns per operation.
    pub min_ns: f64,
    /// Median batch, ns per operation.
    pub median_ns: f64,
}

/// Times every variant once per round, in turn, for `rounds` rounds (after one untimed
/// warm-up round). On a shared machine the host's speed drifts over seconds; within a round
/// every variant sees about the same conditions, so ratios of the per-variant fastest
/// batches are robust where back-to-back measurements are not.
///
/// ```
/// let mut x = 0u64;
/// let mut v = vec![benches::Variant {
///     name: "add".into(),
///     per_call: 100.0,
///     run: Box::new(|| for i in 0..100 { x = std::hint::black_box(x + i) }),
/// }];
/// let t = benches::interleave(&mut v, 5);
/// assert!(t[0].min_ns <= t[0].median_ns);
/// ```
pub fn interleave(variants: &mut [Variant<'_>], rounds: usize) -> Vec<Timing> {
    for v in variants.iter_mut() {
        (v.run)();
    }
    let mut times = vec![Vec::with_capacity(rounds); variants.len()];
    for _ in 0..rounds.max(1) {
        for (v, t) in variants.iter_mut().zip(&mut times) {
            let start = std::time::Instant::now();
            (v.run)();
            t.push(start.elapsed().as_nanos() as f64 / v.per_call);
        }
    }
    times
        .into_iter()
        .map(|mut t| {
            t.sort_by(f64::total_cmp);
            Timing {
                min_ns: t[0],
                median_ns: t[t.len() / 2],
            }
        })
        .collect()
}

/// Storage order of a [`FixedMatVec`] and the loop it runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FixedLayout {
    /// Column-major, y = Σⱼ xⱼ H[:, j]: N independent vector FMAs per column, the whole of
    /// y kept in registers, no horizontal sums.
    ColumnAxpy,
    /// Row-major, yᵢ = H[i, :]·x with four partial sums per row.
    RowDot,
}

/// The reference kernel: y = H x for an N × N matrix with compile-time dimensions,
/// written in plain Rust (arrays and loops) and compiled twice — for the baseline target
/// and with `#[target_feature(enable = "avx2,fma")]` — with the AVX2 copy chosen at
/// construction when the CPU has it.
///
/// ```
/// use benches::{FixedLayout, FixedMatVec};
/// let h: Vec<f64> = (0..9).map(|k| k as f64).collect(); // [[0,1,2],[3,4,5],[6,7,8]]
/// for layout in [FixedLayout::ColumnAxpy, FixedLayout::RowDot] {
///     let k = FixedMatVec::<3>::new(&h, layout).unwrap();
///     let mut y = [0.0; 3];
///     k.apply(&[1.0, 0.0, -1.0], &mut y);
///     assert_eq!(y, [-2.0, -2.0, -2.0]);
/// }
/// ```
#[derive(Debug, Clone)]
pub struct FixedMatVec<const N: usize> {
    /// Columns (ColumnAxpy) or rows (RowDot) of H.
    m: Box<Aligned<N>>,
    layout: FixedLayout,
    simd: bool,
}

#[derive(Debug, Clone)]
#[repr(C, align(64))]
struct Aligned<const N: usize>([[f64; N]; N]);

impl<const N: usize> FixedMatVec<N> {
    /// From H row-major (length N²); `None` on a length mismatch.
    pub fn new(h_row_major: &[f64], layout: FixedLayout) -> Option<Self> {
        if h_row_major.len() != N * N {
            return None;
        }
        let mut m = Box::new(Aligned([[0.0; N]; N]));
        for i in 0..N {
            for j in 0..N {
                let v = h_row_major[i * N + j];
                match layout {
                    FixedLayout::ColumnAxpy => m.0[j][i] = v,
                    FixedLayout::RowDot => m.0[i][j] = v,
                }
            }
        }
        Some(Self {
            m,
            layout,
            simd: simd_available(),
        })
    }

    /// Whether the AVX2 + FMA copy runs.
    pub fn is_simd(&self) -> bool {
        self.simd
    }

    /// y = H x.
    #[inline]
    pub fn apply(&self, x: &[f64; N], y: &mut [f64; N]) {
        let m = &self.m.0;
        #[cfg(target_arch = "x86_64")]
        if self.simd {
            // SAFETY: `simd` is set only when the CPU reports AVX2 and FMA.
            unsafe {
                match self.layout {
                    FixedLayout::ColumnAxpy => column_axpy_avx2(m, x, y),
                    FixedLayout::RowDot => row_dot_avx2(m, x, y),
                }
            }
            return;
        }
        match self.layout {
            FixedLayout::ColumnAxpy => column_axpy::<N, false>(m, x, y),
            FixedLayout::RowDot => row_dot::<N, false>(m, x, y),
        }
    }
}

fn simd_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// a·b + c, fused when compiled for FMA (`mul_add` would be a libm call without it).
#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

#[inline(always)]
fn column_axpy<const N: usize, const FMA: bool>(
    cols: &[[f64; N]; N],
    x: &[f64; N],
    y: &mut [f64; N],
) {
    let mut acc = [0.0; N];
    for j in 0..N {
        let xj = x[j];
        for i in 0..N {
            acc[i] = madd::<FMA>(cols[j][i], xj, acc[i]);
        }
    }
    *y = acc;
}

#[inline(always)]
fn row_dot<const N: usize, const FMA: bool>(rows: &[[f64; N]; N], x: &[f64; N], y: &mut [f64; N]) {
    for i in 0..N {
        let r = &rows[i];
        let mut s = [0.0; 4];
        let mut j = 0;
        while j + 4 <= N {
            for k in 0..4 {
                s[k] = madd::<FMA>(r[j + k], x[j + k], s[k]);
            }
            j += 4;
        }
        let mut t = 0.0;
        while j < N {
            t = madd::<FMA>(r[j], x[j], t);
            j += 1;
        }
        y[i] = (s[0] + s[1]) + (s[2] + s[3]) + t;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn column_axpy_avx2<const N: usize>(cols: &[[f64; N]; N], x: &[f64; N], y: &mut [f64; N]) {
    column_axpy::<N, true>(cols, x, y)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn row_dot_avx2<const N: usize>(rows: &[[f64; N]; N], x: &[f64; N], y: &mut [f64; N]) {
    row_dot::<N, true>(rows, x, y)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn fixed_kernels_match_naive_product_on_both_paths() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let h: Vec<f64> = (0..900).map(|_| rng.random_range(-1.0..1.0)).collect();
        let x: [f64; 30] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let want: Vec<f64> = (0..30)
            .map(|i| (0..30).map(|j| h[i * 30 + j] * x[j]).sum())
            .collect();
        for layout in [FixedLayout::ColumnAxpy, FixedLayout::RowDot] {
            let mut k = FixedMatVec::<30>::new(&h, layout).unwrap();
            for simd in [k.simd, false] {
                k.simd = simd;
                let mut y = [0.0; 30];
                k.apply(&x, &mut y);
                for i in 0..30 {
                    assert!(
                        (y[i] - want[i]).abs() < 1e-13,
                        "{layout:?} simd={simd} row {i}"
                    );
                }
            }
        }
        assert!(FixedMatVec::<30>::new(&h[..899], FixedLayout::RowDot).is_none());
    }

    #[test]
    fn random_instance_has_the_requested_spectrum_and_an_active_box() {
        let inst = random_instance(30, 5);
        assert!((inst.qp.mu() - 1.0).abs() < 1e-9 && (inst.qp.l() - KAPPA).abs() < 1e-9 * KAPPA);
        // Same seed, same data.
        assert_eq!(
            random_instance(30, 5).qp.h_row_major(),
            inst.qp.h_row_major()
        );
        // The box is active at the solution (projected gradient run to convergence).
        use qp_iter::IterationMap;
        let pg =
            qp_iter::pg::ProjectedGradient::new(inst.qp.clone(), qp_iter::pg::StepRule::Optimal)
                .unwrap();
        let mut s = pg.new_state();
        pg.load(&mut s, &inst.theta);
        qp_iter::run_fixed(&pg, &mut s, 3000);
        let at_bound = pg
            .iterate(&s)
            .iter()
            .filter(|v| (v.abs() - 1.0).abs() < 1e-12)
            .count();
        assert!(
            (5..=25).contains(&at_bound),
            "{at_bound} of 30 components at a bound"
        );
    }
}
