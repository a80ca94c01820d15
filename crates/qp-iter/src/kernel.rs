//! Dense kernels for the hot loop: y = H x for a small square H stored row-major, and the
//! fused steps of the methods (projected gradient z⁺ = Π_\[l,u\](z − α(Hz + q)), FISTA,
//! ADMM), each one pass over the matrix.
//!
//! One iteration of every method is one such product plus O(n) work, so this module is
//! the single place where per-iteration cost is decided.
//!
//! ## Padded layout (what the methods run)
//! [`PaddedSymmetric`] stores the matrix by columns with leading dimension
//! [`padded_len`]`(n)` (n rounded up to 4) in a 64-byte aligned buffer, and the methods
//! keep every vector padded the same way with zeros ([`AlignedVec`]): each column is whole
//! aligned 4-wide loads, so the AVX2 kernels ([`Kernel::pg_step_padded`],
//! [`Kernel::fista_step_padded`] and [`Kernel::admm_dr_step_padded`]) need no masks or tails and no load
//! crosses a cache line. Rows go in const-generic panels of 1 … 15 vectors chosen at
//! run time; up to n = 60 the whole product is one panel and the steps update in place.
//! The row-major kernels below ([`Kernel::matvec`], [`Kernel::matvec_symmetric`],
//! [`Kernel::projected_gradient_step`], …) take any slice and serve everything else.
//!
//! ## Dispatch
//! The committed build targets baseline x86-64 (SSE2 only; no `-C target-cpu=native`).
//! On x86-64 CPUs with AVX2 and FMA the kernels run a hand-vectorised path compiled with
//! `#[target_feature(enable = "avx2,fma")]`; everywhere else a portable path with four
//! independent accumulators per row. The choice is made once: [`Kernel::detect`] caches it
//! in a `OnceLock`, and a [`Kernel`] value stored in a method's setup data carries it, so a
//! call costs one predictable branch, not a CPU query.
//!
//! ## AVX2 path of the row-major `matvec`
//! Eight rows at a time, one 4-wide accumulator per row (eight independent FMA chains:
//! enough to cover the FMA latency on two pipes), the column remainder through a masked
//! load, the row remainder by repeating the last row and storing only the valid sums.
//! The eight accumulators are reduced to two vectors of row sums with `hadd`, one blend and
//! one lane permute per four rows. The result differs from a sequential dot product only
//! by rounding (fused multiply–add, different summation order).

use std::sync::OnceLock;

/// Which implementation a [`Kernel`] runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KernelPath {
    /// Plain Rust, four accumulators per row; what the baseline target vectorises itself.
    Portable,
    /// x86-64 AVX2 + FMA intrinsics (selected only when the CPU reports both).
    Avx2Fma,
}

impl KernelPath {
    /// Short name for reports (`"portable"`, `"avx2+fma"`).
    pub fn name(self) -> &'static str {
        match self {
            KernelPath::Portable => "portable",
            KernelPath::Avx2Fma => "avx2+fma",
        }
    }

    /// Whether the running CPU can execute this path.
    pub fn is_available(self) -> bool {
        match self {
            KernelPath::Portable => true,
            KernelPath::Avx2Fma => avx2_fma_detected(),
        }
    }
}

#[cfg(target_arch = "x86_64")]
fn avx2_fma_detected() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

#[cfg(not(target_arch = "x86_64"))]
fn avx2_fma_detected() -> bool {
    false
}

/// A dense-kernel implementation chosen once (a validated [`KernelPath`]).
///
/// Invariant: `path` is [`KernelPath::Avx2Fma`] only if the running CPU supports AVX2 and
/// FMA (the constructors check it; the field is private).
///
/// ```
/// use qp_iter::kernel::{Kernel, KernelPath};
/// let k = Kernel::detect();
/// let h = [2.0, 1.0, 1.0, 3.0]; // [[2, 1], [1, 3]] row-major
/// let mut y = [0.0; 2];
/// k.matvec(&h, 2, &[1.0, -1.0], &mut y);
/// assert_eq!(y, [1.0, -2.0]);
/// assert!(Kernel::with_path(KernelPath::Portable).is_some());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Kernel {
    path: KernelPath,
}

static DETECTED: OnceLock<Kernel> = OnceLock::new();

impl Kernel {
    /// The fastest path the running CPU supports (detected on first use, then cached).
    #[inline]
    pub fn detect() -> Self {
        *DETECTED.get_or_init(|| {
            if avx2_fma_detected() {
                Kernel {
                    path: KernelPath::Avx2Fma,
                }
            } else {
                Kernel {
                    path: KernelPath::Portable,
                }
            }
        })
    }

    /// The portable path (for comparisons and tests).
    pub fn portable() -> Self {
        Kernel {
            path: KernelPath::Portable,
        }
    }

    /// The given path, or `None` if the running CPU cannot execute it.
    pub fn with_path(path: KernelPath) -> Option<Self> {
        path.is_available().then_some(Kernel { path })
    }

    /// The path this kernel runs.
    pub fn path(self) -> KernelPath {
        self.path
    }

    /// y = H x for a general H, n × n row-major in `h`; writes `y[..n]` only.
    /// Allocation-free.
    ///
    /// # Panics
    /// If `h.len() != n²`, `x.len() < n` or `y.len() < n` (a caller bug: dimensions are
    /// validated when a problem is built).
    #[inline]
    pub fn matvec(self, h: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
        check_dims(h, n, x.len(), y.len());
        if n == 0 {
            return;
        }
        match self.path {
            KernelPath::Portable => portable::matvec(h, n, x, y),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Kernel` is `Avx2Fma` only if the CPU supports AVX2 and FMA (type
            // invariant); lengths were checked above and n ≥ 1.
            KernelPath::Avx2Fma => unsafe { avx2::matvec(h, n, x, y) },
            #[cfg(not(target_arch = "x86_64"))]
            KernelPath::Avx2Fma => portable::matvec(h, n, x, y),
        }
    }

    /// y = H x for a *symmetric* H (n × n in `h`; row i is column i). Faster than
    /// [`Kernel::matvec`]: it sums scaled columns, so it needs no horizontal sums and keeps
    /// y in registers. Every Hessian of this crate is symmetric (exactly, by
    /// [`crate::ParametricQp`]). For a non-symmetric `h` the result is Hᵀx.
    ///
    /// ```
    /// use qp_iter::kernel::Kernel;
    /// let h = [2.0, 1.0, 1.0, 3.0];
    /// let mut y = [0.0; 2];
    /// Kernel::detect().matvec_symmetric(&h, 2, &[1.0, -1.0], &mut y);
    /// assert_eq!(y, [1.0, -2.0]);
    /// ```
    ///
    /// # Panics
    /// As [`Kernel::matvec`].
    #[inline]
    pub fn matvec_symmetric(self, h: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
        check_dims(h, n, x.len(), y.len());
        if n == 0 {
            return;
        }
        match self.path {
            KernelPath::Portable => portable::matvec_columns(h, n, n, x, y),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: AVX2 + FMA by the type invariant; n ≥ 1; h has n² entries, x and y
            // at least n (checked above); x and y do not overlap (& and &mut).
            KernelPath::Avx2Fma => unsafe {
                avx2_sym::run::<{ avx2_sym::STORE }>(avx2_sym::Ctx::product(h, n, x, y))
            },
            #[cfg(not(target_arch = "x86_64"))]
            KernelPath::Avx2Fma => portable::matvec_columns(h, n, n, x, y),
        }
    }

    /// The projected-gradient step z⁺ = Π_\[l,u\](z − α(Hz + q)) for a symmetric H,
    /// written to `out` in one pass over H (the step of [`crate::pg`], fused: no separate
    /// Hz buffer, axpy and projection loops). As in [`Kernel::matvec_symmetric`], a
    /// non-symmetric `h` acts as Hᵀ.
    ///
    /// Clamping is `min(u, max(l, v))` in that operand order, so a NaN in `v` stays NaN
    /// (the drivers then report it) instead of being clamped to a bound. Allocation-free.
    ///
    /// ```
    /// use qp_iter::kernel::Kernel;
    /// let h = [2.0, 0.0, 0.0, 1.0];
    /// let (z, q) = ([0.0, 0.0], [-2.0, -4.0]);
    /// let mut out = [0.0; 2];
    /// Kernel::detect().projected_gradient_step(&h, 2, &z, &q, 0.5, &[-3.0, -1.0], &[3.0, 1.0], &mut out);
    /// assert_eq!(out, [1.0, 1.0]); // (1, 2) before clamping z₂ to 1
    /// ```
    ///
    /// # Panics
    /// If `h.len() != n²` or any of `z`, `q`, `lower`, `upper`, `out` is shorter than n.
    #[inline]
    pub fn projected_gradient_step(
        self,
        h: &[f64],
        n: usize,
        z: &[f64],
        q: &[f64],
        alpha: f64,
        lower: &[f64],
        upper: &[f64],
        out: &mut [f64],
    ) {
        check_dims(h, n, z.len(), out.len());
        check_lens(
            "projected_gradient_step",
            n,
            [q.len(), lower.len(), upper.len()],
        );
        if n == 0 {
            return;
        }
        match self.path {
            KernelPath::Portable => portable::pg_step(h, n, n, z, q, alpha, lower, upper, out),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: AVX2 + FMA by the type invariant; n ≥ 1; all lengths checked above;
            // `out` is a distinct &mut, so it overlaps none of the inputs.
            KernelPath::Avx2Fma => unsafe {
                let mut c = avx2_sym::Ctx::product(h, n, z, out);
                (c.q, c.lo, c.hi, c.a) = (q.as_ptr(), lower.as_ptr(), upper.as_ptr(), alpha);
                avx2_sym::run::<{ avx2_sym::PG }>(c)
            },
            #[cfg(not(target_arch = "x86_64"))]
            KernelPath::Avx2Fma => portable::pg_step(h, n, n, z, q, alpha, lower, upper, out),
        }
    }

    /// One fused step of constant-momentum FISTA ([`crate::fista`]) for a symmetric H:
    ///
    /// x⁺ = Π_\[l,u\](y − α(Hy + q)),  y⁺ = x⁺ + β(x⁺ − x),
    ///
    /// with x = `z` on entry. Writes x⁺ into `z` and y⁺ into `y_next` (swap `y` and
    /// `y_next` afterwards); one pass over H, no other loops. β = 0 gives the plain
    /// projected-gradient step (FISTA's restart step). NaN-propagating clamp as in
    /// [`Kernel::projected_gradient_step`]. Allocation-free.
    ///
    /// ```
    /// use qp_iter::kernel::Kernel;
    /// let h = [2.0, 0.0, 0.0, 1.0];
    /// let (y, q) = ([0.0, 0.0], [-2.0, -4.0]);
    /// let mut z = [0.5, 0.0]; // x_k
    /// let mut y_next = [0.0; 2];
    /// Kernel::detect().fista_step(&h, 2, &y, &q, 0.5, &[-3.0, -1.0], &[3.0, 1.0], 0.5, &mut z, &mut y_next);
    /// assert_eq!(z, [1.0, 1.0]);
    /// assert_eq!(y_next, [1.25, 1.5]); // x⁺ + ½(x⁺ − x)
    /// ```
    ///
    /// # Panics
    /// If `h.len() != n²` or any vector is shorter than n.
    #[inline]
    pub fn fista_step(
        self,
        h: &[f64],
        n: usize,
        y: &[f64],
        q: &[f64],
        alpha: f64,
        lower: &[f64],
        upper: &[f64],
        beta: f64,
        z: &mut [f64],
        y_next: &mut [f64],
    ) {
        check_dims(h, n, y.len(), z.len());
        check_lens(
            "fista_step",
            n,
            [q.len(), lower.len(), upper.len(), y_next.len()],
        );
        if n == 0 {
            return;
        }
        match self.path {
            KernelPath::Portable => {
                portable::fista_step(h, n, n, y, q, alpha, lower, upper, beta, z, y_next)
            }
            #[cfg(target_arch = "x86_64")]
            // SAFETY: AVX2 + FMA by the type invariant; n ≥ 1; all lengths checked above;
            // `z` and `y_next` are distinct &mut, overlapping no input.
            KernelPath::Avx2Fma => unsafe {
                let mut c = avx2_sym::Ctx::product(h, n, y, z);
                (c.q, c.lo, c.hi, c.a, c.b) =
                    (q.as_ptr(), lower.as_ptr(), upper.as_ptr(), alpha, beta);
                c.next = y_next.as_mut_ptr();
                avx2_sym::run::<{ avx2_sym::FISTA }>(c)
            },
            #[cfg(not(target_arch = "x86_64"))]
            KernelPath::Avx2Fma => {
                portable::fista_step(h, n, n, y, q, alpha, lower, upper, beta, z, y_next)
            }
        }
    }

    /// One fused step of relaxed ADMM ([`crate::admm`]) on min ½zᵀHz + qᵀz, z = v ∈ [l, u],
    /// with the dense map M = ρ(H + ρI)⁻¹ (symmetric) and m_q = (H + ρI)⁻¹q:
    ///
    /// z = M t − m_q,  w = a z + (1 − a)v + y/ρ,  v⁺ = Π_\[l,u\](w),  y⁺ = ρ(w − v⁺),
    /// t⁺ = v⁺ − y⁺/ρ = 2v⁺ − w,
    ///
    /// where t = v − y/ρ is carried between steps (`t` in, `t_next` out: swap them
    /// afterwards). Writes z, v⁺ (over `v`), y⁺ (over `dual`) and t⁺; one pass over M, no
    /// other loops. `relaxation` is a ∈ (0, 2], `rho` is ρ > 0 (not checked here).
    /// NaN-propagating clamp as in [`Kernel::projected_gradient_step`]. Allocation-free.
    ///
    /// ```
    /// use qp_iter::kernel::Kernel;
    /// // M = I (ρ(H+ρI)⁻¹ for H → 0), m_q = 0, a = 1, ρ = 1: z = t, w = z + y.
    /// let m = [1.0, 0.0, 0.0, 1.0];
    /// let (mut z, mut v, mut y, mut t_next) = ([0.0; 2], [0.0, 0.0], [0.5, 0.0], [0.0; 2]);
    /// let t = [2.0, 0.25];
    /// Kernel::detect().admm_step(&m, 2, &t, &[0.0, 0.0], 1.0, 1.0, &[-1.0, -1.0], &[1.0, 1.0],
    ///     &mut z, &mut v, &mut y, &mut t_next);
    /// assert_eq!(z, [2.0, 0.25]);
    /// assert_eq!(v, [1.0, 0.25]); // w = (2.5, 0.25) clamped
    /// assert_eq!(y, [1.5, 0.0]);  // ρ(w − v⁺)
    /// assert_eq!(t_next, [-0.5, 0.25]);
    /// ```
    ///
    /// # Panics
    /// If `m.len() != n²` or any vector is shorter than n.
    #[inline]
    pub fn admm_step(
        self,
        m: &[f64],
        n: usize,
        t: &[f64],
        mq: &[f64],
        relaxation: f64,
        rho: f64,
        lower: &[f64],
        upper: &[f64],
        z: &mut [f64],
        v: &mut [f64],
        dual: &mut [f64],
        t_next: &mut [f64],
    ) {
        check_dims(m, n, t.len(), z.len());
        check_lens(
            "admm_step",
            n,
            [
                mq.len(),
                lower.len(),
                upper.len(),
                v.len(),
                dual.len(),
                t_next.len(),
            ],
        );
        if n == 0 {
            return;
        }
        match self.path {
            KernelPath::Portable => portable::admm_step(
                m, n, n, t, mq, relaxation, rho, lower, upper, z, v, dual, t_next,
            ),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: AVX2 + FMA by the type invariant; n ≥ 1; all lengths checked above;
            // the four outputs are distinct &mut, overlapping no input.
            KernelPath::Avx2Fma => unsafe {
                let mut c = avx2_sym::Ctx::product(m, n, t, z);
                (c.q, c.lo, c.hi, c.a, c.b) =
                    (mq.as_ptr(), lower.as_ptr(), upper.as_ptr(), relaxation, rho);
                (c.next, c.v, c.dual) = (t_next.as_mut_ptr(), v.as_mut_ptr(), dual.as_mut_ptr());
                if relaxation == 1.0 {
                    avx2_sym::run::<{ avx2_sym::ADMM1 }>(c)
                } else {
                    avx2_sym::run::<{ avx2_sym::ADMM }>(c)
                }
            },
            #[cfg(not(target_arch = "x86_64"))]
            KernelPath::Avx2Fma => portable::admm_step(
                m, n, n, t, mq, relaxation, rho, lower, upper, z, v, dual, t_next,
            ),
        }
    }
}

/// Rows of every padded vector and matrix column: n rounded up to a multiple of 4, so each
/// column of a [`PaddedSymmetric`] and each padded vector is a whole number of 4-wide
/// SIMD vectors (no masked or partial loads, no tail code).
///
/// ```
/// assert_eq!(qp_iter::kernel::padded_len(30), 32);
/// assert_eq!(qp_iter::kernel::padded_len(32), 32);
/// ```
#[inline]
pub fn padded_len(n: usize) -> usize {
    n.div_ceil(4) * 4
}

/// One cache line of f64: the allocation unit of [`AlignedVec`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
struct Line([f64; 8]);

/// A zero-initialised `f64` buffer whose first entry starts a cache line (64-byte
/// aligned): a padded vector or matrix column in it is read with whole 32-byte loads that
/// never straddle two cache lines. Dereferences to `[f64]` of its length.
///
/// ```
/// use qp_iter::kernel::AlignedVec;
/// let v = AlignedVec::padded(&[1.0, 2.0, 3.0]);
/// assert_eq!(&v[..], &[1.0, 2.0, 3.0, 0.0]); // padded to 4 entries with zeros
/// assert_eq!(v.as_ptr() as usize % 64, 0);
/// ```
#[derive(Clone, PartialEq)]
pub struct AlignedVec {
    lines: Vec<Line>,
    len: usize,
}

impl AlignedVec {
    /// `len` zeros.
    pub fn zeros(len: usize) -> Self {
        Self {
            lines: vec![Line([0.0; 8]); len.div_ceil(8)],
            len,
        }
    }

    /// `x` followed by zeros up to [`padded_len`]`(x.len())` entries.
    pub fn padded(x: &[f64]) -> Self {
        let mut v = Self::zeros(padded_len(x.len()));
        v[..x.len()].copy_from_slice(x);
        v
    }
}

impl std::ops::Deref for AlignedVec {
    type Target = [f64];
    #[inline]
    fn deref(&self) -> &[f64] {
        // SAFETY: `Line` is `repr(C)` around `[f64; 8]` (size 64, no padding), so `lines`
        // is 8·lines.len() ≥ len initialised, contiguous f64; an empty Vec's pointer is
        // non-null and aligned, valid for a zero-length slice.
        unsafe { std::slice::from_raw_parts(self.lines.as_ptr().cast::<f64>(), self.len) }
    }
}

impl std::ops::DerefMut for AlignedVec {
    #[inline]
    fn deref_mut(&mut self) -> &mut [f64] {
        // SAFETY: as in `deref`; `&mut self` makes the borrow unique.
        unsafe { std::slice::from_raw_parts_mut(self.lines.as_mut_ptr().cast::<f64>(), self.len) }
    }
}

impl std::fmt::Debug for AlignedVec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

/// `K` vectors of `ld` entries each, back to back in one [`AlignedVec`]: a method's state.
/// One allocation, so the vectors cannot alias one another modulo 4 KiB; with the in-place
/// padded steps a step writes nothing but vector data (measured at n = 30: swapping two
/// `AlignedVec` handles per step cost ≈ 3 ns, flipping an index ≈ 2 ns).
#[derive(Debug, Clone)]
pub(crate) struct Vectors<const K: usize> {
    buf: AlignedVec,
    ld: usize,
}

impl<const K: usize> Vectors<K> {
    /// `K` zero vectors of `ld` entries.
    pub(crate) fn zeros(ld: usize) -> Self {
        Self {
            buf: AlignedVec::zeros(K * ld),
            ld,
        }
    }

    /// Vector `i` (< K).
    #[inline]
    pub(crate) fn get(&self, i: usize) -> &[f64] {
        &self.buf[i * self.ld..(i + 1) * self.ld]
    }

    /// Vector `i` (< K), mutable.
    #[inline]
    pub(crate) fn get_mut(&mut self, i: usize) -> &mut [f64] {
        &mut self.buf[i * self.ld..(i + 1) * self.ld]
    }

    /// All `K` vectors, mutable (disjoint).
    #[inline]
    pub(crate) fn all_mut(&mut self) -> [&mut [f64]; K] {
        let (ld, base) = (self.ld, self.buf.as_mut_ptr());
        // SAFETY: the buffer holds exactly K·ld entries (set at construction, never
        // resized), so vector i, entries i·ld .. (i+1)·ld, lies inside it; the K ranges
        // are disjoint and all derive from the one `&mut self` borrow. (Pointer
        // arithmetic instead of `chunks_exact_mut`: no per-step checks in the hot path.)
        std::array::from_fn(|i| unsafe { std::slice::from_raw_parts_mut(base.add(i * ld), ld) })
    }
}

/// A symmetric n × n matrix laid out for the padded kernels ([`Kernel::pg_step_padded`]
/// and its siblings): column j at offset j·ld with ld = [`padded_len`]`(n)`, rows n .. ld
/// zero, the first column 64-byte aligned. Every column is ld/4 whole SIMD vectors, so the
/// kernels run without masks or tails and their loads never split a cache line.
///
/// ```
/// use qp_iter::kernel::PaddedSymmetric;
/// let h = PaddedSymmetric::from_row_major(&[2.0, 1.0, 1.0, 3.0], 2).unwrap();
/// assert_eq!((h.n(), h.ld()), (2, 4));
/// assert_eq!(h.as_slice(), &[2.0, 1.0, 0.0, 0.0, 1.0, 3.0, 0.0, 0.0]);
/// assert!(PaddedSymmetric::from_row_major(&[1.0; 3], 2).is_none());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct PaddedSymmetric {
    data: AlignedVec,
    n: usize,
    ld: usize,
}

impl PaddedSymmetric {
    /// From H row-major (length n²); `None` on a length mismatch. Column j is stored from
    /// row j of `h`, so for a non-symmetric `h` the kernels apply Hᵀ (as
    /// [`Kernel::matvec_symmetric`] does).
    pub fn from_row_major(h: &[f64], n: usize) -> Option<Self> {
        if n.checked_mul(n) != Some(h.len()) {
            return None;
        }
        Some(Self::from_fn(n, |i, j| h[j * n + i]))
    }

    /// The dimension n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The leading dimension ld = [`padded_len`]`(n)`: the length every vector passed to
    /// the padded kernels must have at least.
    pub fn ld(&self) -> usize {
        self.ld
    }

    /// Entry (i, j) = `f(i, j)` for i, j < n; as [`PaddedSymmetric::from_row_major`], the
    /// kernels read column j, so a non-symmetric `f` acts as its transpose.
    pub fn from_fn(n: usize, f: impl Fn(usize, usize) -> f64) -> Self {
        let ld = padded_len(n);
        let mut data = AlignedVec::zeros(n * ld);
        // `max(1)`: no chunks for n = 0 (chunk size 0 is not allowed).
        for (j, col) in data.chunks_exact_mut(ld.max(1)).enumerate() {
            for (i, c) in col[..n].iter_mut().enumerate() {
                *c = f(i, j);
            }
        }
        Self { data, n, ld }
    }

    /// The n columns of ld entries each, column after column.
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }
}

/// The padded kernels: the same steps as [`Kernel::projected_gradient_step`],
/// [`Kernel::fista_step`] and [`Kernel::admm_step`], on a [`PaddedSymmetric`] matrix and
/// vectors of (at least) ld = [`padded_len`]`(n)` entries. They compute all ld rows; the
/// padding rows of the matrix are zero, so with zero padding in q, the bounds and the
/// starting vectors the padding of every output stays zero (it is never an input to the
/// product: only the first n entries of the multiplied vector are read). Vectors from
/// [`AlignedVec`] make every load an aligned 32-byte load; other slices work, slower.
/// This is what the methods' `step` runs.
impl Kernel {
    /// y = Hx on the padded layout: reads `x[..n]`, writes `y[..ld]` (rows n .. ld: 0).
    ///
    /// ```
    /// use qp_iter::kernel::{Kernel, PaddedSymmetric};
    /// let h = PaddedSymmetric::from_row_major(&[2.0, 1.0, 1.0, 3.0], 2).unwrap();
    /// let mut y = [7.0; 4];
    /// Kernel::detect().matvec_padded(&h, &[1.0, -1.0], &mut y);
    /// assert_eq!(y, [1.0, -2.0, 0.0, 0.0]);
    /// ```
    ///
    /// # Panics
    /// If `x.len() < n` or `y.len() < ld`.
    #[inline]
    pub fn matvec_padded(self, h: &PaddedSymmetric, x: &[f64], y: &mut [f64]) {
        check_lens("matvec_padded (x)", h.n, [x.len()]);
        check_lens("matvec_padded (y)", h.ld, [y.len()]);
        if h.n == 0 {
            return;
        }
        match self.path {
            KernelPath::Portable => {
                portable::matvec_columns(h.as_slice(), h.n, h.ld, x, y);
            }
            #[cfg(target_arch = "x86_64")]
            // SAFETY: AVX2 + FMA by the type invariant; n ≥ 1; the matrix holds n columns
            // of ld entries (type invariant), x ≥ n and y ≥ ld entries (checked above).
            KernelPath::Avx2Fma => unsafe {
                avx2_pad::run::<{ avx2_pad::STORE }>(avx2_pad::Ctx::product(
                    h,
                    x.as_ptr(),
                    y.as_mut_ptr(),
                ))
            },
            #[cfg(not(target_arch = "x86_64"))]
            KernelPath::Avx2Fma => portable::matvec_columns(h.as_slice(), h.n, h.ld, x, y),
        }
    }

    /// The projected-gradient step z ← Π_\[l,u\](z − α(Hz + q)) of
    /// [`Kernel::projected_gradient_step`] on the padded layout, **in place**: when the
    /// whole product is one register panel (ld ≤ 60, see [`PADDED_IN_PLACE_MAX`]) every
    /// entry of z is read before the first is written, so z is overwritten directly;
    /// otherwise (and on the portable path) the step goes through `scratch` and is copied
    /// back. In place, a method's state needs no second buffer to swap (a per-step store
    /// of which buffer is current was measured to cost ≈ 2–3 ns at n = 30). Every vector
    /// ≥ ld entries.
    ///
    /// ```
    /// use qp_iter::kernel::{AlignedVec, Kernel, PaddedSymmetric};
    /// let h = PaddedSymmetric::from_row_major(&[2.0, 0.0, 0.0, 1.0], 2).unwrap();
    /// let (mut z, q) = (AlignedVec::padded(&[0.0, 0.0]), AlignedVec::padded(&[-2.0, -4.0]));
    /// let (lo, hi) = (AlignedVec::padded(&[-3.0, -1.0]), AlignedVec::padded(&[3.0, 1.0]));
    /// let mut scratch = AlignedVec::zeros(h.ld());
    /// Kernel::detect().pg_step_padded(&h, &mut z, &q, 0.5, &lo, &hi, &mut scratch);
    /// assert_eq!(&z[..], &[1.0, 1.0, 0.0, 0.0]); // (1, 2) before clamping z₂ to 1
    /// ```
    ///
    /// # Panics
    /// If any vector is shorter than ld.
    #[inline]
    pub fn pg_step_padded(
        self,
        h: &PaddedSymmetric,
        z: &mut [f64],
        q: &[f64],
        alpha: f64,
        lower: &[f64],
        upper: &[f64],
        scratch: &mut [f64],
    ) {
        check_lens(
            "pg_step_padded",
            h.ld,
            [z.len(), q.len(), lower.len(), upper.len(), scratch.len()],
        );
        if h.n == 0 {
            return;
        }
        let (hs, n, ld) = (h.as_slice(), h.n, h.ld);
        self.in_place(
            ld,
            z,
            scratch,
            (),
            // SAFETY: AVX2 + FMA by the type invariant; n ≥ 1; n columns of ld entries;
            // every vector ≥ ld (checked above); `x` and `dest` as `in_place` documents.
            |x, dest, ()| unsafe {
                let mut c = avx2_pad::Ctx::product(h, x, dest);
                (c.q, c.lo, c.hi, c.a) = (q.as_ptr(), lower.as_ptr(), upper.as_ptr(), alpha);
                avx2_pad::run::<{ avx2_pad::PG }>(c);
            },
            |z, out, ()| portable::pg_step(hs, n, ld, z, q, alpha, lower, upper, out),
        );
    }

    /// The FISTA step of [`Kernel::fista_step`] on the padded layout, in place as
    /// [`Kernel::pg_step_padded`]: x⁺ = Π_\[l,u\](y − α(Hy + q)) over `z` (x on entry),
    /// y⁺ = x⁺ + β(x⁺ − x) over `y`, computed as (1 + β)x⁺ − βx (so β = 0 gives y⁺ = x⁺
    /// exactly). Every vector ≥ ld entries.
    ///
    /// ```
    /// use qp_iter::kernel::{AlignedVec, Kernel, PaddedSymmetric};
    /// let h = PaddedSymmetric::from_row_major(&[2.0, 0.0, 0.0, 1.0], 2).unwrap();
    /// let (mut y, q) = (AlignedVec::padded(&[0.0, 0.0]), AlignedVec::padded(&[-2.0, -4.0]));
    /// let (lo, hi) = (AlignedVec::padded(&[-3.0, -1.0]), AlignedVec::padded(&[3.0, 1.0]));
    /// let (mut z, mut scratch) = (AlignedVec::padded(&[0.5, 0.0]), AlignedVec::zeros(4));
    /// Kernel::detect().fista_step_padded(&h, &mut y, &q, 0.5, &lo, &hi, 0.5, &mut z, &mut scratch);
    /// assert_eq!(&z[..2], &[1.0, 1.0]);
    /// assert_eq!(&y[..2], &[1.25, 1.5]); // x⁺ + ½(x⁺ − x)
    /// ```
    ///
    /// # Panics
    /// If any vector is shorter than ld.
    #[inline]
    pub fn fista_step_padded(
        self,
        h: &PaddedSymmetric,
        y: &mut [f64],
        q: &[f64],
        alpha: f64,
        lower: &[f64],
        upper: &[f64],
        beta: f64,
        z: &mut [f64],
        scratch: &mut [f64],
    ) {
        check_lens(
            "fista_step_padded",
            h.ld,
            [
                y.len(),
                q.len(),
                lower.len(),
                upper.len(),
                z.len(),
                scratch.len(),
            ],
        );
        if h.n == 0 {
            return;
        }
        let (hs, n, ld) = (h.as_slice(), h.n, h.ld);
        self.in_place(
            ld,
            y,
            scratch,
            z,
            // SAFETY: as in `pg_step_padded`, with y⁺ (`next`) in place of y; `z` is a
            // distinct `&mut` the product never reads (only the epilogue, row by row,
            // before writing the same row).
            |x, dest, z| unsafe {
                let mut c = avx2_pad::Ctx::product(h, x, z.as_mut_ptr());
                (c.q, c.lo, c.hi, c.a, c.b) =
                    (q.as_ptr(), lower.as_ptr(), upper.as_ptr(), alpha, beta);
                c.next = dest;
                avx2_pad::run::<{ avx2_pad::FISTA }>(c);
            },
            |y, next, z| portable::fista_step(hs, n, ld, y, q, alpha, lower, upper, beta, z, next),
        );
    }

    /// The relaxed ADMM step of [`Kernel::admm_step`] on the padded layout (M =
    /// ρ(H + ρI)⁻¹ in `m`, m_q = (H + ρI)⁻¹q), carried on the Douglas–Rachford variable
    /// s = v + y/ρ instead of (v, y): with v = Π_\[l,u\](s),
    /// z⁺ = Mt − m_q, s⁺ = a z⁺ + s − a v (= w = a z⁺ + (1 − a)v + y/ρ of [`Kernel::admm_step`]) over `s`,
    /// t⁺ = 2Π_\[l,u\](s⁺) − s⁺ over `t`, z⁺ over `z`; in place as
    /// [`Kernel::pg_step_padded`]. v = Π(s) and y = ρ(s − v) are not stored (a caller
    /// forms them when asked): three stores per four rows instead of four. Every vector
    /// ≥ ld entries.
    ///
    /// ```
    /// use qp_iter::kernel::{AlignedVec, Kernel, PaddedSymmetric};
    /// let m = PaddedSymmetric::from_row_major(&[1.0, 0.0, 0.0, 1.0], 2).unwrap();
    /// let (lo, hi) = (AlignedVec::padded(&[-1.0, -1.0]), AlignedVec::padded(&[1.0, 1.0]));
    /// // s = (1.5, 0.25): v = (1, 0.25), t = 2v − s = (0.5, 0.25).
    /// let (mut s, mut t) = (AlignedVec::padded(&[1.5, 0.25]), AlignedVec::padded(&[0.5, 0.25]));
    /// let (mq, mut z, mut scratch) = (AlignedVec::zeros(4), AlignedVec::zeros(4), AlignedVec::zeros(4));
    /// Kernel::detect().admm_dr_step_padded(&m, &mut t, &mq, 1.0, &lo, &hi, &mut z, &mut s, &mut scratch);
    /// assert_eq!(&z[..2], &[0.5, 0.25]); // z⁺ = t
    /// assert_eq!(&s[..2], &[1.0, 0.25]); // s⁺ = z⁺ + s − v
    /// assert_eq!(&t[..2], &[1.0, 0.25]); // 2Π(s⁺) − s⁺
    /// ```
    ///
    /// # Panics
    /// If any vector is shorter than ld.
    #[inline(always)]
    pub fn admm_dr_step_padded(
        self,
        m: &PaddedSymmetric,
        t: &mut [f64],
        mq: &[f64],
        relaxation: f64,
        lower: &[f64],
        upper: &[f64],
        z: &mut [f64],
        s: &mut [f64],
        scratch: &mut [f64],
    ) {
        check_lens(
            "admm_dr_step_padded",
            m.ld,
            [
                t.len(),
                mq.len(),
                lower.len(),
                upper.len(),
                z.len(),
                s.len(),
                scratch.len(),
            ],
        );
        if m.n == 0 {
            return;
        }
        let (ms, n, ld) = (m.as_slice(), m.n, m.ld);
        self.in_place(
            ld,
            t,
            scratch,
            (z, s),
            // SAFETY: as in `pg_step_padded`, with t⁺ in place of t; z and s are distinct
            // `&mut`s the product never reads (the epilogue reads s row by row before
            // writing the same rows).
            |x, dest, (z, s)| unsafe {
                let mut c = avx2_pad::Ctx::product(m, x, dest);
                (c.q, c.lo, c.hi, c.a) = (mq.as_ptr(), lower.as_ptr(), upper.as_ptr(), relaxation);
                (c.next, c.v) = (z.as_mut_ptr(), s.as_mut_ptr());
                if relaxation == 1.0 {
                    avx2_pad::run::<{ avx2_pad::DR1 }>(c)
                } else {
                    avx2_pad::run::<{ avx2_pad::DR }>(c)
                }
            },
            |t, t_next, (z, s)| {
                portable::admm_dr_step(ms, n, ld, t, mq, relaxation, lower, upper, z, s, t_next)
            },
        );
    }

    /// A padded step that overwrites `io`, the vector the matrix is applied to. AVX2:
    /// `avx2(x, dest, aux)` with x = `io` and dest = `io` itself when the product is one
    /// register panel (ld ≤ [`PADDED_IN_PLACE_MAX`]: all of x is read before the first
    /// store, each epilogue row reads x before writing it), else `scratch`, copied back.
    /// Portable: `portable(io, scratch, aux)` writes the new `io` into `scratch`, copied
    /// back. `aux` carries the step's other outputs.
    #[inline]
    fn in_place<A>(
        self,
        ld: usize,
        io: &mut [f64],
        scratch: &mut [f64],
        aux: A,
        avx2: impl FnOnce(*mut f64, *mut f64, A),
        portable: impl FnOnce(&[f64], &mut [f64], A),
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.path == KernelPath::Avx2Fma {
            let in_place = ld <= PADDED_IN_PLACE_MAX;
            let x = io.as_mut_ptr();
            avx2(x, if in_place { x } else { scratch.as_mut_ptr() }, aux);
            if !in_place {
                io[..ld].copy_from_slice(&scratch[..ld]);
            }
            return;
        }
        let _ = avx2; // only the portable path on this target
        portable(io, scratch, aux);
        io[..ld].copy_from_slice(&scratch[..ld]);
    }
}

/// Largest leading dimension for which the padded steps update their input in place
/// (one register panel of ≤ 15 vectors, see `avx2_pad::run`): n ≤ 60.
pub const PADDED_IN_PLACE_MAX: usize = 60;

#[inline]
fn check_lens<const K: usize>(what: &str, n: usize, lens: [usize; K]) {
    // Only the shortest length leaves the registers (on the cold panic path): a slice
    // argument made every step store the whole array (8 stores per ADMM step).
    let shortest = lens.into_iter().fold(usize::MAX, usize::min);
    if shortest < n {
        lens_too_short(what, n, shortest);
    }
}

#[cold]
#[inline(never)]
fn lens_too_short(what: &str, n: usize, shortest: usize) -> ! {
    panic!("{what}: every vector needs length ≥ n = {n} (the shortest has {shortest})")
}

#[inline]
fn check_dims(h: &[f64], n: usize, x_len: usize, y_len: usize) {
    assert!(
        n.checked_mul(n) == Some(h.len()) && x_len >= n && y_len >= n,
        "dense kernel: need h.len() = n² and x, y of length ≥ n (n = {n}, h.len() = {}, x.len() = {x_len}, y.len() = {y_len})",
        h.len()
    );
}

/// y = H x, H n × n row-major in `h` (length n²); writes `y[..n]`. Allocation-free.
///
/// Runs the fastest path for this CPU ([`Kernel::detect`], cached after the first call).
/// For a symmetric H, [`matvec_symmetric`] is faster.
///
/// # Panics
/// If `h.len() != n²`, `x.len() < n` or `y.len() < n`.
#[inline]
pub fn matvec(h: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
    Kernel::detect().matvec(h, n, x, y);
}

/// y = H x for a symmetric H ([`Kernel::matvec_symmetric`] on the detected path).
///
/// # Panics
/// If `h.len() != n²`, `x.len() < n` or `y.len() < n`.
#[inline]
pub fn matvec_symmetric(h: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
    Kernel::detect().matvec_symmetric(h, n, x, y);
}

/// Clamp with NaN propagation: `min(u, max(l, v))` with the same operand order as the
/// `vmaxpd`/`vminpd` of the AVX2 path, so both paths agree bit for bit on the clamp.
#[inline(always)]
pub(crate) fn clamp_nan_propagating(v: f64, l: f64, u: f64) -> f64 {
    let w = if l > v { l } else { v };
    if u < w { u } else { w }
}

mod portable {
    use super::clamp_nan_propagating;

    /// Dot product with four independent partial sums (lets the baseline target use
    /// two SSE2 registers and hides the add latency).
    #[inline(always)]
    fn dot(a: &[f64], b: &[f64]) -> f64 {
        let mut acc = [0.0f64; 4];
        let (ac, ar) = (a.chunks_exact(4), a.chunks_exact(4).remainder());
        let (bc, br) = (b.chunks_exact(4), b.chunks_exact(4).remainder());
        for (ca, cb) in ac.zip(bc) {
            for k in 0..4 {
                acc[k] += ca[k] * cb[k];
            }
        }
        let mut tail = 0.0;
        for (x, y) in ar.iter().zip(br) {
            tail += x * y;
        }
        (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
    }

    pub(super) fn matvec(h: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
        let x = &x[..n];
        for (row, yi) in h.chunks_exact(n).zip(&mut y[..n]) {
            *yi = dot(row, x);
        }
    }

    /// y[..ld] = Σⱼ xⱼ h[j ld .. (j+1) ld], j < n (= Hx for a symmetric H stored by
    /// columns with leading dimension ld ≥ n: ld = n unpadded, [`super::padded_len`]
    /// padded): element-wise, so the baseline target vectorises it without reassociating
    /// sums.
    pub(super) fn matvec_columns(h: &[f64], n: usize, ld: usize, x: &[f64], y: &mut [f64]) {
        let y = &mut y[..ld];
        y.fill(0.0);
        for (col, &xj) in h.chunks_exact(ld).zip(&x[..n]) {
            for (yi, &c) in y.iter_mut().zip(col) {
                *yi += c * xj;
            }
        }
    }

    /// Projected-gradient step on rows 0 .. ld (ld as in [`matvec_columns`]).
    pub(super) fn pg_step(
        h: &[f64],
        n: usize,
        ld: usize,
        z: &[f64],
        q: &[f64],
        alpha: f64,
        lower: &[f64],
        upper: &[f64],
        out: &mut [f64],
    ) {
        // `out` holds Hz first, then z⁺ row by row.
        matvec_columns(h, n, ld, z, out);
        for i in 0..ld {
            let v = z[i] - alpha * (out[i] + q[i]);
            out[i] = clamp_nan_propagating(v, lower[i], upper[i]);
        }
    }

    /// FISTA step on rows 0 .. ld.
    pub(super) fn fista_step(
        h: &[f64],
        n: usize,
        ld: usize,
        y: &[f64],
        q: &[f64],
        alpha: f64,
        lower: &[f64],
        upper: &[f64],
        beta: f64,
        z: &mut [f64],
        y_next: &mut [f64],
    ) {
        // `y_next` holds Hy first, then y⁺ row by row.
        matvec_columns(h, n, ld, y, y_next);
        for i in 0..ld {
            let x = clamp_nan_propagating(y[i] - alpha * (y_next[i] + q[i]), lower[i], upper[i]);
            y_next[i] = x + beta * (x - z[i]);
            z[i] = x;
        }
    }

    /// The ADMM step on the DR variable s (see `Kernel::admm_dr_step_padded`), rows 0 .. ld.
    pub(super) fn admm_dr_step(
        m: &[f64],
        n: usize,
        ld: usize,
        t: &[f64],
        mq: &[f64],
        a: f64,
        lower: &[f64],
        upper: &[f64],
        z: &mut [f64],
        s: &mut [f64],
        t_next: &mut [f64],
    ) {
        // `z` holds Mt first, then Mt − m_q.
        matvec_columns(m, n, ld, t, z);
        for i in 0..ld {
            z[i] -= mq[i];
            let v = clamp_nan_propagating(s[i], lower[i], upper[i]);
            let w = a * z[i] + (s[i] - a * v);
            t_next[i] = 2.0 * clamp_nan_propagating(w, lower[i], upper[i]) - w;
            s[i] = w;
        }
    }

    /// Relaxed ADMM step on rows 0 .. ld.
    pub(super) fn admm_step(
        m: &[f64],
        n: usize,
        ld: usize,
        t: &[f64],
        mq: &[f64],
        a: f64,
        rho: f64,
        lower: &[f64],
        upper: &[f64],
        z: &mut [f64],
        v: &mut [f64],
        dual: &mut [f64],
        t_next: &mut [f64],
    ) {
        let ir = 1.0 / rho;
        // `z` holds Mt first, then Mt − m_q.
        matvec_columns(m, n, ld, t, z);
        for i in 0..ld {
            z[i] -= mq[i];
            let w = a * z[i] + (1.0 - a) * v[i] + ir * dual[i];
            let vp = clamp_nan_propagating(w, lower[i], upper[i]);
            dual[i] = rho * (w - vp);
            t_next[i] = 2.0 * vp - w;
            v[i] = vp;
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    /// Lane mask with the first `r` of four lanes set (r ∈ 0..=4).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn first_lanes(r: usize) -> __m256i {
        _mm256_cmpgt_epi64(_mm256_set1_epi64x(r as i64), _mm256_setr_epi64x(0, 1, 2, 3))
    }

    /// [Σa₀, Σa₁, Σa₂, Σa₃]: horizontal sums of four accumulators.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn reduce4(a0: __m256d, a1: __m256d, a2: __m256d, a3: __m256d) -> __m256d {
        // t0 = [a0₀+a0₁, a1₀+a1₁, a0₂+a0₃, a1₂+a1₃], t1 likewise for a2, a3.
        let t0 = _mm256_hadd_pd(a0, a1);
        let t1 = _mm256_hadd_pd(a2, a3);
        // [t0₂, t0₃, t1₀, t1₁] + [t0₀, t0₁, t1₂, t1₃]
        let swapped = _mm256_permute2f128_pd::<0x21>(t0, t1);
        let blended = _mm256_blend_pd::<0b1100>(t0, t1);
        _mm256_add_pd(swapped, blended)
    }

    /// Row sums H[r, :]·x for the eight rows r = i, …, i+7, each index clamped to n − 1
    /// (the caller stores only the valid ones).
    ///
    /// # Safety
    /// AVX2 and FMA available; n ≥ 1; `h` valid for n² reads; `x` valid for n reads;
    /// i < n.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn rows8<const R: usize>(
        h: *const f64,
        n: usize,
        x: *const f64,
        i: usize,
    ) -> (__m256d, __m256d) {
        let last = n - 1;
        // SAFETY (all `add`s in this block): every row index is ≤ n − 1, so each row
        // pointer starts inside the n² allocation and the row's n entries lie in it.
        let p: [*const f64; 8] = unsafe {
            [
                h.add(i.min(last) * n),
                h.add((i + 1).min(last) * n),
                h.add((i + 2).min(last) * n),
                h.add((i + 3).min(last) * n),
                h.add((i + 4).min(last) * n),
                h.add((i + 5).min(last) * n),
                h.add((i + 6).min(last) * n),
                h.add((i + 7).min(last) * n),
            ]
        };
        let mut a = [_mm256_setzero_pd(); 8];
        let full = n & !3;
        let mut j = 0;
        while j < full {
            // SAFETY: j + 4 ≤ full ≤ n, so the four entries from j are inside x and
            // inside each row.
            unsafe {
                let xv = _mm256_loadu_pd(x.add(j));
                for r in 0..8 {
                    a[r] = _mm256_fmadd_pd(_mm256_loadu_pd(p[r].add(j)), xv, a[r]);
                }
            }
            j += 4;
        }
        if R > 0 {
            // SAFETY: only the R = n − full < 4 entries from `full` are read, inside x and
            // inside each row: 64/128-bit moves (zero-extended) for R = 1, 2, a masked
            // load (masked-off lanes are not accessed) for R = 3.
            unsafe {
                let tail = |p: *const f64| match R {
                    1 => _mm256_zextpd128_pd256(_mm_load_sd(p)),
                    2 => _mm256_zextpd128_pd256(_mm_loadu_pd(p)),
                    _ => _mm256_maskload_pd(p, first_lanes(3)),
                };
                let xv = tail(x.add(full));
                for r in 0..8 {
                    a[r] = _mm256_fmadd_pd(tail(p[r].add(full)), xv, a[r]);
                }
            }
        }
        (
            reduce4(a[0], a[1], a[2], a[3]),
            reduce4(a[4], a[5], a[6], a[7]),
        )
    }

    /// # Safety
    /// AVX2 and FMA available; n ≥ 1; h.len() = n²; x.len() ≥ n; y.len() ≥ n.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn matvec(h: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
        // SAFETY: forwarded contract; R = n mod 4.
        unsafe {
            match n % 4 {
                0 => matvec_r::<0>(h, n, x, y),
                1 => matvec_r::<1>(h, n, x, y),
                2 => matvec_r::<2>(h, n, x, y),
                _ => matvec_r::<3>(h, n, x, y),
            }
        }
    }

    /// # Safety
    /// As [`matvec`], and R = n mod 4.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn matvec_r<const R: usize>(h: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
        let (hp, xp, yp) = (h.as_ptr(), x.as_ptr(), y.as_mut_ptr());
        let mut i = 0;
        while i + 8 <= n {
            // SAFETY: caller's contract; i < n; rows i..i+8 and y[i..i+8] are in bounds.
            unsafe {
                let (s0, s1) = rows8::<R>(hp, n, xp, i);
                _mm256_storeu_pd(yp.add(i), s0);
                _mm256_storeu_pd(yp.add(i + 4), s1);
            }
            i += 8;
        }
        if i < n {
            // SAFETY: caller's contract; i < n.
            let (s0, s1) = unsafe { rows8::<R>(hp, n, xp, i) };
            let mut tmp = [0.0f64; 8];
            // SAFETY: `tmp` holds eight f64.
            unsafe {
                _mm256_storeu_pd(tmp.as_mut_ptr(), s0);
                _mm256_storeu_pd(tmp.as_mut_ptr().add(4), s1);
            }
            y[i..n].copy_from_slice(&tmp[..n - i]);
        }
    }
}

/// Column-oriented kernels for symmetric H: the rows of a symmetric row-major H are its
/// columns, so y = Σⱼ xⱼ H[:, j] reads contiguous memory, keeps up to 32 entries of y in
/// eight registers and needs no horizontal sums. A row-local epilogue (store, PG, FISTA or
/// ADMM update) runs on each finished vector of four rows, so a method's whole step is one
/// pass over H.
#[cfg(target_arch = "x86_64")]
mod avx2_sym {
    use std::arch::x86_64::*;

    /// Epilogue: store Hx.
    pub(super) const STORE: u8 = 0;
    /// Epilogue: projected-gradient step.
    pub(super) const PG: u8 = 1;
    /// Epilogue: FISTA step with momentum.
    pub(super) const FISTA: u8 = 2;
    /// Epilogue: relaxed ADMM step.
    pub(super) const ADMM: u8 = 3;
    /// Epilogue: ADMM step without relaxation (a = 1: w = z + y/ρ, the old v is not read).
    pub(super) const ADMM1: u8 = 4;

    /// Pointers and scalars of one call (null / 0 where an epilogue does not use them).
    #[derive(Clone, Copy)]
    pub(super) struct Ctx {
        pub h: *const f64,
        pub n: usize,
        /// The point H is applied to: x, z (PG), y (FISTA), t (ADMM).
        pub x: *const f64,
        /// Hx, z⁺ (PG), z in/out (FISTA), z out (ADMM).
        pub out: *mut f64,
        /// q (PG, FISTA) or m_q (ADMM).
        pub q: *const f64,
        pub lo: *const f64,
        pub hi: *const f64,
        /// α (PG, FISTA) or the relaxation a (ADMM).
        pub a: f64,
        /// β (FISTA) or ρ (ADMM).
        pub b: f64,
        /// y_next (FISTA) or t_next (ADMM).
        pub next: *mut f64,
        /// v in/out (ADMM).
        pub v: *mut f64,
        /// y in/out (ADMM).
        pub dual: *mut f64,
    }

    impl Ctx {
        /// y = Hx with every other field empty.
        pub(super) fn product(h: &[f64], n: usize, x: &[f64], out: &mut [f64]) -> Self {
            Ctx {
                h: h.as_ptr(),
                n,
                x: x.as_ptr(),
                out: out.as_mut_ptr(),
                q: std::ptr::null(),
                lo: std::ptr::null(),
                hi: std::ptr::null(),
                a: 0.0,
                b: 0.0,
                next: std::ptr::null_mut(),
                v: std::ptr::null_mut(),
                dual: std::ptr::null_mut(),
            }
        }
    }

    /// Lanes at `p + r`: all four when `T` = 0, else the first `T` (the others zero).
    /// Plain 128/64-bit moves, no masked loads.
    ///
    /// # Safety
    /// AVX available; the selected lanes are valid reads.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn ld<const T: usize>(p: *const f64, r: usize) -> __m256d {
        // SAFETY: forwarded contract.
        unsafe {
            let p = p.add(r);
            match T {
                0 => _mm256_loadu_pd(p),
                1 => _mm256_zextpd128_pd256(_mm_load_sd(p)),
                2 => _mm256_zextpd128_pd256(_mm_loadu_pd(p)),
                _ => _mm256_set_m128d(_mm_load_sd(p.add(2)), _mm_loadu_pd(p)),
            }
        }
    }

    /// Stores lanes at `p + r`: all four when `T` = 0, else the first `T`. Plain
    /// 128/64-bit moves (masked stores are slow on some AMD cores).
    ///
    /// # Safety
    /// AVX available; the selected lanes are valid writes.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn st<const T: usize>(p: *mut f64, r: usize, v: __m256d) {
        // SAFETY: forwarded contract.
        unsafe {
            let p = p.add(r);
            let lo = _mm256_castpd256_pd128(v);
            match T {
                0 => _mm256_storeu_pd(p, v),
                1 => _mm_store_sd(p, lo),
                2 => _mm_storeu_pd(p, lo),
                _ => {
                    _mm_storeu_pd(p, lo);
                    _mm_store_sd(p.add(2), _mm256_extractf128_pd::<1>(v));
                }
            }
        }
    }

    /// `min(hi, max(lo, v))`: a NaN in v stays NaN (vmaxpd/vminpd return the second
    /// operand when either is NaN).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn clamp(v: __m256d, lo: __m256d, hi: __m256d) -> __m256d {
        _mm256_min_pd(hi, _mm256_max_pd(lo, v))
    }

    /// The epilogue `E` on rows r .. r+4 (the first `T` of them when `T` > 0) with
    /// s = (Hx)[rows].
    ///
    /// # Safety
    /// AVX2 + FMA available; the selected rows are < n; the pointers `E` uses are valid
    /// for n elements (see [`run`]).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn epilogue<const E: u8, const T: usize>(c: &Ctx, r: usize, s: __m256d) {
        // SAFETY: forwarded contract: rows in bounds, pointers valid for E.
        unsafe {
            // Everything that does not depend on s is formed first, so the chain from the
            // last FMA of the product to the stored iterate is as short as possible.
            match E {
                PG => {
                    // z − α(s + q) = (z − αq) − αs
                    let alpha = _mm256_set1_pd(c.a);
                    let base = _mm256_fnmadd_pd(alpha, ld::<T>(c.q, r), ld::<T>(c.x, r));
                    let z = _mm256_fnmadd_pd(alpha, s, base);
                    st::<T>(c.out, r, clamp(z, ld::<T>(c.lo, r), ld::<T>(c.hi, r)));
                }
                FISTA => {
                    let alpha = _mm256_set1_pd(c.a);
                    let base = _mm256_fnmadd_pd(alpha, ld::<T>(c.q, r), ld::<T>(c.x, r));
                    let x = clamp(
                        _mm256_fnmadd_pd(alpha, s, base),
                        ld::<T>(c.lo, r),
                        ld::<T>(c.hi, r),
                    );
                    let d = _mm256_sub_pd(x, ld::<T>(c.out, r));
                    st::<T>(c.next, r, _mm256_fmadd_pd(_mm256_set1_pd(c.b), d, x));
                    st::<T>(c.out, r, x);
                }
                ADMM1 => {
                    let z = _mm256_sub_pd(s, ld::<T>(c.q, r));
                    st::<T>(c.out, r, z);
                    let w = _mm256_fmadd_pd(ld::<T>(c.dual, r), _mm256_set1_pd(1.0 / c.b), z);
                    let vp = clamp(w, ld::<T>(c.lo, r), ld::<T>(c.hi, r));
                    st::<T>(
                        c.dual,
                        r,
                        _mm256_mul_pd(_mm256_set1_pd(c.b), _mm256_sub_pd(w, vp)),
                    );
                    st::<T>(c.next, r, _mm256_sub_pd(_mm256_add_pd(vp, vp), w));
                    st::<T>(c.v, r, vp);
                }
                ADMM => {
                    let z = _mm256_sub_pd(s, ld::<T>(c.q, r));
                    st::<T>(c.out, r, z);
                    let (a, rho) = (_mm256_set1_pd(c.a), _mm256_set1_pd(c.b));
                    let y_rho = _mm256_mul_pd(ld::<T>(c.dual, r), _mm256_set1_pd(1.0 / c.b));
                    let rest = _mm256_fmadd_pd(_mm256_set1_pd(1.0 - c.a), ld::<T>(c.v, r), y_rho);
                    // w = a z + (1 − a)v + y/ρ
                    let w = _mm256_fmadd_pd(a, z, rest);
                    let vp = clamp(w, ld::<T>(c.lo, r), ld::<T>(c.hi, r));
                    st::<T>(c.dual, r, _mm256_mul_pd(rho, _mm256_sub_pd(w, vp)));
                    st::<T>(c.next, r, _mm256_sub_pd(_mm256_add_pd(vp, vp), w));
                    st::<T>(c.v, r, vp);
                }
                _ => st::<T>(c.out, r, s),
            }
        }
    }

    /// Rows r0 .. r0 + 4V + R: V full vectors and an R-row tail (R < 4), all columns,
    /// then the epilogue.
    ///
    /// # Safety
    /// AVX2 and FMA available; r0 + 4V + R ≤ n; the pointers as in [`run`].
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn panel<const V: usize, const R: usize, const E: u8>(c: &Ctx, r0: usize) {
        let mut acc = [_mm256_setzero_pd(); V];
        let mut t2 = _mm_setzero_pd();
        let mut t1 = _mm_setzero_pd();
        for j in 0..c.n {
            // SAFETY: column j of the panel is h[j n + r0 .. j n + r0 + 4V + R], inside
            // the n² entries because r0 + 4V + R ≤ n; x[j] with j < n.
            unsafe {
                let col = c.h.add(j * c.n + r0);
                let xj = _mm256_broadcast_sd(&*c.x.add(j));
                for v in 0..V {
                    acc[v] = _mm256_fmadd_pd(_mm256_loadu_pd(col.add(4 * v)), xj, acc[v]);
                }
                let xj2 = _mm256_castpd256_pd128(xj);
                if R >= 2 {
                    t2 = _mm_fmadd_pd(_mm_loadu_pd(col.add(4 * V)), xj2, t2);
                }
                if R % 2 == 1 {
                    // Upper lane stays 0 (copied from the loaded operand).
                    t1 = _mm_fmadd_sd(_mm_load_sd(col.add(4 * V + (R & 2))), xj2, t1);
                }
            }
        }
        for v in 0..V {
            // SAFETY: rows r0 + 4v .. + 4 lie below n.
            unsafe { epilogue::<E, 0>(c, r0 + 4 * v, acc[v]) };
        }
        if R > 0 {
            // Tail sums as one vector [t2₀, t2₁, t1₀, 0] (R = 3), [t2₀, t2₁, 0, 0] (R = 2)
            // or [t1₀, 0, 0, 0] (R = 1); only the first R lanes are stored.
            let s = match R {
                1 => _mm256_zextpd128_pd256(t1),
                2 => _mm256_zextpd128_pd256(t2),
                _ => _mm256_set_m128d(t1, t2),
            };
            // SAFETY: rows r0 + 4V .. r0 + 4V + R lie below n.
            unsafe { epilogue::<E, R>(c, r0 + 4 * V, s) };
        }
    }

    /// The last panel: V full vectors plus an r-row tail (r < 4).
    ///
    /// # Safety
    /// As [`panel`] with R = r.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn last<const V: usize, const E: u8>(c: &Ctx, r0: usize, r: usize) {
        // SAFETY: forwarded contract.
        unsafe {
            match r {
                0 => panel::<V, 0, E>(c, r0),
                1 => panel::<V, 1, E>(c, r0),
                2 => panel::<V, 2, E>(c, r0),
                _ => panel::<V, 3, E>(c, r0),
            }
        }
    }

    /// All rows: panels of 32, then one panel for the remaining < 32.
    ///
    /// # Safety
    /// AVX2 and FMA available; n ≥ 1; `h` valid for n² reads and `x` for n reads; the
    /// pointers epilogue `E` uses valid for n elements (reads: `q`, `lo`, `hi`; writes:
    /// `out`, and `next`, `v`, `dual` where used; `out` also read by FISTA, `v` and `dual`
    /// by ADMM); no written range overlaps `x`, `h` or another written range.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn run<const E: u8>(c: Ctx) {
        let mut r0 = 0;
        // SAFETY (whole body): every panel ends at row ≤ n; the caller's contract covers
        // the pointers.
        unsafe {
            while c.n - r0 >= 32 {
                panel::<8, 0, E>(&c, r0);
                r0 += 32;
            }
            let left = c.n - r0;
            if left == 0 {
                return;
            }
            let r = left % 4;
            match left / 4 {
                0 => last::<0, E>(&c, r0, r),
                1 => last::<1, E>(&c, r0, r),
                2 => last::<2, E>(&c, r0, r),
                3 => last::<3, E>(&c, r0, r),
                4 => last::<4, E>(&c, r0, r),
                5 => last::<5, E>(&c, r0, r),
                6 => last::<6, E>(&c, r0, r),
                _ => last::<7, E>(&c, r0, r),
            }
        }
    }
}

/// Kernels on the padded layout ([`PaddedSymmetric`]): every column is ld/4 whole vectors,
/// 32-byte aligned when the storage is an [`AlignedVec`], so there are no masks, tails or
/// cache-line-splitting loads. Rows go in panels of 8 to 15 vectors (see [`run`]), one
/// accumulator per vector: eight or more independent FMA chains cover the FMA latency on
/// two pipes (the chain of a panel is no longer than its issue time), as in the
/// reference kernel. The
/// epilogue runs on each finished vector, its parts that do not depend on the product
/// formed first, so a method's whole step is one pass over the matrix.
#[cfg(target_arch = "x86_64")]
mod avx2_pad {
    use std::arch::x86_64::*;

    use super::PaddedSymmetric;

    /// Epilogue: store Hx.
    pub(super) const STORE: u8 = 0;
    /// Epilogue: projected-gradient step.
    pub(super) const PG: u8 = 1;
    /// Epilogue: FISTA step with momentum.
    pub(super) const FISTA: u8 = 2;
    /// Epilogue: ADMM on the DR variable s (`Kernel::admm_dr_step_padded`), a = 1.
    pub(super) const DR1: u8 = 3;
    /// Epilogue: ADMM on the DR variable s, any relaxation a.
    pub(super) const DR: u8 = 4;

    /// Pointers and scalars of one call (null / 0 where an epilogue does not use them).
    #[derive(Clone, Copy)]
    pub(super) struct Ctx {
        /// n columns of `ld` entries.
        pub h: *const f64,
        pub n: usize,
        pub ld: usize,
        /// The point H is applied to: x, z (PG), y (FISTA), t (ADMM).
        pub x: *const f64,
        /// Hx, z⁺ (PG), z in/out (FISTA), t⁺ (ADMM).
        pub out: *mut f64,
        /// q (PG, FISTA) or m_q (ADMM).
        pub q: *const f64,
        pub lo: *const f64,
        pub hi: *const f64,
        /// α (PG, FISTA) or the relaxation a (ADMM).
        pub a: f64,
        /// β (FISTA).
        pub b: f64,
        /// y_next (FISTA) or z (ADMM).
        pub next: *mut f64,
        /// The DR variable s in/out (ADMM).
        pub v: *mut f64,
    }

    impl Ctx {
        /// y = Hx with every other field empty.
        pub(super) fn product(h: &PaddedSymmetric, x: *const f64, out: *mut f64) -> Self {
            Ctx {
                h: h.as_slice().as_ptr(),
                n: h.n(),
                ld: h.ld(),
                x,
                out,
                q: std::ptr::null(),
                lo: std::ptr::null(),
                hi: std::ptr::null(),
                a: 0.0,
                b: 0.0,
                next: std::ptr::null_mut(),
                v: std::ptr::null_mut(),
            }
        }
    }

    /// Four entries from `p + r` (an aligned load whenever `p` is 32-byte aligned).
    ///
    /// # Safety
    /// AVX available; `p + r .. p + r + 4` valid for reads.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn ld(p: *const f64, r: usize) -> __m256d {
        // SAFETY: forwarded contract.
        unsafe { _mm256_loadu_pd(p.add(r)) }
    }

    /// Stores four entries at `p + r`.
    ///
    /// # Safety
    /// AVX available; `p + r .. p + r + 4` valid for writes.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn st(p: *mut f64, r: usize, v: __m256d) {
        // SAFETY: forwarded contract.
        unsafe { _mm256_storeu_pd(p.add(r), v) }
    }

    /// `min(hi, max(lo, v))`: a NaN in v stays NaN (vmaxpd/vminpd return the second
    /// operand when either is NaN).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn clamp(v: __m256d, lo: __m256d, hi: __m256d) -> __m256d {
        _mm256_min_pd(hi, _mm256_max_pd(lo, v))
    }

    /// The epilogue `E` on rows r .. r + 4 with s = (Hx)[rows].
    ///
    /// # Safety
    /// AVX2 + FMA available; r + 4 ≤ ld; the pointers `E` uses valid for ld elements.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn epilogue<const E: u8>(c: &Ctx, r: usize, s: __m256d) {
        // SAFETY: forwarded contract: rows in bounds, pointers valid for E.
        unsafe {
            match E {
                PG => {
                    // z − α(s + q) = (z − αq) − αs
                    let alpha = _mm256_set1_pd(c.a);
                    let base = _mm256_fnmadd_pd(alpha, ld(c.q, r), ld(c.x, r));
                    let z = _mm256_fnmadd_pd(alpha, s, base);
                    st(c.out, r, clamp(z, ld(c.lo, r), ld(c.hi, r)));
                }
                FISTA => {
                    // x⁺ as PG; y⁺ = (1 + β)x⁺ − βx with βx formed before s is ready.
                    let alpha = _mm256_set1_pd(c.a);
                    let base = _mm256_fnmadd_pd(alpha, ld(c.q, r), ld(c.x, r));
                    let bx = _mm256_mul_pd(_mm256_set1_pd(c.b), ld(c.out, r));
                    let x = clamp(_mm256_fnmadd_pd(alpha, s, base), ld(c.lo, r), ld(c.hi, r));
                    st(c.next, r, _mm256_fmsub_pd(_mm256_set1_pd(1.0 + c.b), x, bx));
                    st(c.out, r, x);
                }
                DR1 | DR => {
                    // s = Mt − m_q = z⁺ (sums started at −m_q); the DR variable d (in
                    // `c.v`) gives v = Π(d) and s⁺ = a z⁺ + (d − a v), the bracket formed
                    // before the product is done; t⁺ = 2Π(s⁺) − s⁺ first (the next step's
                    // input).
                    let (lo, hi) = (ld(c.lo, r), ld(c.hi, r));
                    let d = ld(c.v, r);
                    let v = clamp(d, lo, hi);
                    let w = if E == DR1 {
                        _mm256_add_pd(s, _mm256_sub_pd(d, v))
                    } else {
                        let a = _mm256_set1_pd(c.a);
                        _mm256_fmadd_pd(a, s, _mm256_fnmadd_pd(a, v, d))
                    };
                    let vp = clamp(w, lo, hi);
                    st(c.out, r, _mm256_fmsub_pd(_mm256_set1_pd(2.0), vp, w));
                    st(c.v, r, w);
                    st(c.next, r, s);
                }
                _ => st(c.out, r, s),
            }
        }
    }

    /// Rows r0 .. r0 + 4V, all n columns, then the epilogue on each vector. Each row is
    /// summed column after column by FMAs (for V ≤ 5: even and odd columns separately,
    /// then added).
    ///
    /// # Safety
    /// AVX2 and FMA available; r0 + 4V ≤ ld; the pointers as in [`run`].
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn panel<const V: usize, const E: u8>(c: &Ctx, r0: usize) {
        let mut acc = [_mm256_setzero_pd(); V];
        // SAFETY (whole body): column j of the panel is h[j ld + r0 .. j ld + r0 + 4V],
        // inside the n·ld entries because j < n and r0 + 4V ≤ ld; x[j] with j < n; the
        // epilogue's rows r0 + 4v + 4 ≤ ld (also those of m_q read here).
        unsafe {
            if matches!(E, DR1 | DR) {
                // ADMM: the sums start at −m_q, so they end at z⁺ = Mt − m_q. The m_q
                // loads do not depend on the previous step, and the epilogue saves the
                // subtraction and one load per vector (−2 ns per step at n = 30).
                for (v, a) in acc.iter_mut().enumerate() {
                    *a = _mm256_sub_pd(*a, ld(c.q, r0 + 4 * v));
                }
            }
            let mut col = c.h.add(r0);
            if V <= 5 {
                // Few vectors: V chains of n FMAs would wait on latency (4 cycles each,
                // issue V/2), so even and odd columns go to two sets of accumulators.
                let mut odd = [_mm256_setzero_pd(); V];
                let mut j = 0;
                while j + 2 <= c.n {
                    let x0 = _mm256_broadcast_sd(&*c.x.add(j));
                    let x1 = _mm256_broadcast_sd(&*c.x.add(j + 1));
                    for (v, a) in acc.iter_mut().enumerate() {
                        *a = _mm256_fmadd_pd(ld(col, 4 * v), x0, *a);
                    }
                    for (v, a) in odd.iter_mut().enumerate() {
                        *a = _mm256_fmadd_pd(ld(col, c.ld + 4 * v), x1, *a);
                    }
                    col = col.add(2 * c.ld);
                    j += 2;
                }
                if j < c.n {
                    let xj = _mm256_broadcast_sd(&*c.x.add(j));
                    for (v, a) in acc.iter_mut().enumerate() {
                        *a = _mm256_fmadd_pd(ld(col, 4 * v), xj, *a);
                    }
                }
                for (a, o) in acc.iter_mut().zip(odd) {
                    *a = _mm256_add_pd(*a, o);
                }
            } else {
                for j in 0..c.n {
                    let xj = _mm256_broadcast_sd(&*c.x.add(j));
                    for (v, a) in acc.iter_mut().enumerate() {
                        *a = _mm256_fmadd_pd(ld(col, 4 * v), xj, *a);
                    }
                    col = col.add(c.ld);
                }
            }
            // Written out per vector (not a loop LLVM may keep rolled for a large
            // epilogue, which would move the accumulators through the stack): constant
            // indices, the branches beyond V removed at compile time.
            macro_rules! each_vector {
                ($($v:literal)*) => {$(
                    if let Some(&a) = acc.get($v) {
                        epilogue::<E>(c, r0 + 4 * $v, a);
                    }
                )*};
            }
            each_vector!(0 1 2 3 4 5 6 7 8 9 10 11 12 13 14);
        }
    }

    /// [`panel`] compiled on its own: each panel size gets its own register allocation
    /// (inlined into one dispatcher, the large epilogues made LLVM spill accumulators).
    ///
    /// # Safety
    /// As [`panel`].
    #[inline(never)]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn own<const V: usize, const E: u8>(c: &Ctx, r0: usize) {
        // SAFETY: forwarded contract.
        unsafe { panel::<V, E>(c, r0) }
    }

    /// All ld rows: panels of eight vectors (32 rows) while more than 15 vectors are
    /// left, then one panel for the remaining 1 ..= 15 vectors. Every panel but a lone
    /// small one has ≥ 8 independent chains, so its chain latency never exceeds its issue
    /// time; up to 15 accumulators plus the broadcast fit the 16 ymm registers (n = 49:
    /// one 13-vector panel instead of 8 + 5, whose second panel would wait on latency).
    ///
    /// # Safety
    /// AVX2 and FMA available; n ≥ 1; ld a multiple of 4 with ld ≥ n; `h` valid for n·ld
    /// reads and `x` for n reads; the pointers epilogue `E` uses valid for ld elements
    /// (reads: `q`, `lo`, `hi`; writes: `out`, and `next`, `v`, `dual` where used; `out`
    /// also read by FISTA, `v` and `dual` by ADMM); no written range overlaps `h` or
    /// another written range, nor `x` — except that `out` (PG, ADMM) or `next` (FISTA)
    /// may be `x` itself when ld ≤ [`super::PADDED_IN_PLACE_MAX`] (one panel: all of x
    /// is read before the first store, and each epilogue row reads x before writing it).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn run<const E: u8>(c: Ctx) {
        let (mut r0, mut left) = (0, c.ld / 4);
        // SAFETY (whole body): every panel ends at row r0 + 4·V ≤ ld; the caller's
        // contract covers the pointers.
        unsafe {
            while left > 15 {
                own::<8, E>(&c, r0);
                r0 += 32;
                left -= 8;
            }
            match left {
                0 => {}
                1 => own::<1, E>(&c, r0),
                2 => own::<2, E>(&c, r0),
                3 => own::<3, E>(&c, r0),
                4 => own::<4, E>(&c, r0),
                5 => own::<5, E>(&c, r0),
                6 => own::<6, E>(&c, r0),
                7 => own::<7, E>(&c, r0),
                8 => own::<8, E>(&c, r0),
                9 => own::<9, E>(&c, r0),
                10 => own::<10, E>(&c, r0),
                11 => own::<11, E>(&c, r0),
                12 => own::<12, E>(&c, r0),
                13 => own::<13, E>(&c, r0),
                14 => own::<14, E>(&c, r0),
                _ => own::<15, E>(&c, r0),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn naive(h: &[f64], n: usize, x: &[f64]) -> Vec<f64> {
        (0..n)
            .map(|i| (0..n).map(|j| h[i * n + j] * x[j]).sum())
            .collect()
    }

    fn paths() -> Vec<Kernel> {
        let mut v = vec![Kernel::portable()];
        if let Some(k) = Kernel::with_path(KernelPath::Avx2Fma) {
            v.push(k);
        }
        v
    }

    fn random_vec(rng: &mut ChaCha8Rng, len: usize) -> Vec<f64> {
        (0..len).map(|_| rng.random_range(-1.0..1.0)).collect()
    }

    fn random_symmetric(rng: &mut ChaCha8Rng, n: usize) -> Vec<f64> {
        let mut h = random_vec(rng, n * n);
        for i in 0..n {
            for j in 0..i {
                h[i * n + j] = h[j * n + i];
            }
        }
        h
    }

    fn transpose(h: &[f64], n: usize) -> Vec<f64> {
        (0..n * n).map(|k| h[(k % n) * n + k / n]).collect()
    }

    #[test]
    fn matvec_symmetric_matches_naive_on_every_path_and_size() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for k in paths() {
            for n in (1..=70).chain([95, 128, 131]) {
                let x = random_vec(&mut rng, n);
                // Symmetric H: Hx. General H: the documented Hᵀx (checks the layout logic
                // on data where rows and columns differ).
                for sym in [true, false] {
                    let h = if sym {
                        random_symmetric(&mut rng, n)
                    } else {
                        random_vec(&mut rng, n * n)
                    };
                    let want = naive(&transpose(&h, n), n, &x);
                    let mut y = vec![7.0; n + 3];
                    k.matvec_symmetric(&h, n, &x, &mut y);
                    for i in 0..n {
                        assert!(
                            (y[i] - want[i]).abs() <= tol(n),
                            "{:?} n = {n} sym = {sym} row {i}: {} vs {}",
                            k.path(),
                            y[i],
                            want[i]
                        );
                    }
                    assert!(
                        y[n..].iter().all(|&v| v == 7.0),
                        "{:?} wrote past n = {n}",
                        k.path()
                    );
                }
            }
        }
    }

    /// Rounding tolerance for a length-n dot product of entries bounded by 1 in magnitude.
    fn tol(n: usize) -> f64 {
        4.0 * n as f64 * f64::EPSILON
    }

    #[test]
    fn matvec_matches_naive_on_every_path_and_size() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for k in paths() {
            for n in (1..=70).chain([95, 128, 131]) {
                let h = random_vec(&mut rng, n * n);
                let x = random_vec(&mut rng, n);
                let want = naive(&h, n, &x);
                // y longer than n: the extra entries must be left alone.
                let mut y = vec![7.0; n + 3];
                k.matvec(&h, n, &x, &mut y);
                for i in 0..n {
                    assert!(
                        (y[i] - want[i]).abs() <= tol(n),
                        "{:?} n = {n} row {i}: {} vs {}",
                        k.path(),
                        y[i],
                        want[i]
                    );
                }
                assert!(
                    y[n..].iter().all(|&v| v == 7.0),
                    "{:?} wrote past n = {n}",
                    k.path()
                );
            }
        }
    }

    #[test]
    fn pg_step_matches_three_pass_step_on_every_path_and_size() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for k in paths() {
            for n in (1..=70).chain([95, 128, 131]) {
                let h = random_symmetric(&mut rng, n);
                let z = random_vec(&mut rng, n);
                let q = random_vec(&mut rng, n);
                // Bounds that clip about half of the entries; some infinite.
                let lower: Vec<f64> = (0..n)
                    .map(|i| {
                        if i % 5 == 0 {
                            f64::NEG_INFINITY
                        } else {
                            rng.random_range(-0.6..0.0)
                        }
                    })
                    .collect();
                let upper: Vec<f64> = (0..n)
                    .map(|i| {
                        if i % 7 == 0 {
                            f64::INFINITY
                        } else {
                            rng.random_range(0.0..0.6)
                        }
                    })
                    .collect();
                let alpha = rng.random_range(0.1..1.0);
                let hz = naive(&h, n, &z);
                let mut out = vec![7.0; n + 2];
                k.projected_gradient_step(&h, n, &z, &q, alpha, &lower, &upper, &mut out);
                for i in 0..n {
                    let want = (z[i] - alpha * (hz[i] + q[i])).max(lower[i]).min(upper[i]);
                    assert!(
                        (out[i] - want).abs() <= tol(n),
                        "{:?} n = {n} row {i}: {} vs {want}",
                        k.path(),
                        out[i]
                    );
                }
                assert!(
                    out[n..].iter().all(|&v| v == 7.0),
                    "{:?} wrote past n = {n}",
                    k.path()
                );
            }
        }
    }

    /// Bounds that clip about half of the entries of a vector in [−1, 1]; some infinite.
    fn random_box(rng: &mut ChaCha8Rng, n: usize) -> (Vec<f64>, Vec<f64>) {
        let lower = (0..n)
            .map(|i| {
                if i % 5 == 0 {
                    f64::NEG_INFINITY
                } else {
                    rng.random_range(-0.6..0.0)
                }
            })
            .collect();
        let upper = (0..n)
            .map(|i| {
                if i % 7 == 0 {
                    f64::INFINITY
                } else {
                    rng.random_range(0.0..0.6)
                }
            })
            .collect();
        (lower, upper)
    }

    #[test]
    fn fista_step_matches_unfused_formula_on_every_path_and_size() {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        for k in paths() {
            for n in (1..=70).chain([95, 128, 131]) {
                let h = random_symmetric(&mut rng, n);
                let (y, q, x) = (
                    random_vec(&mut rng, n),
                    random_vec(&mut rng, n),
                    random_vec(&mut rng, n),
                );
                let (lower, upper) = random_box(&mut rng, n);
                let (alpha, beta) = (rng.random_range(0.1..1.0), rng.random_range(0.0..1.0));
                let hy = naive(&h, n, &y);
                let mut z = x.clone();
                z.push(7.0);
                let mut y_next = vec![7.0; n + 1];
                k.fista_step(
                    &h,
                    n,
                    &y,
                    &q,
                    alpha,
                    &lower,
                    &upper,
                    beta,
                    &mut z,
                    &mut y_next,
                );
                for i in 0..n {
                    let xp = (y[i] - alpha * (hy[i] + q[i])).max(lower[i]).min(upper[i]);
                    let yp = xp + beta * (xp - x[i]);
                    assert!(
                        (z[i] - xp).abs() <= tol(n),
                        "{:?} n = {n} row {i}: x⁺ {} vs {xp}",
                        k.path(),
                        z[i]
                    );
                    assert!(
                        (y_next[i] - yp).abs() <= 4.0 * tol(n),
                        "{:?} n = {n} row {i}: y⁺",
                        k.path()
                    );
                }
                assert!(
                    z[n] == 7.0 && y_next[n] == 7.0,
                    "{:?} wrote past n = {n}",
                    k.path()
                );
            }
        }
    }

    #[test]
    fn admm_step_matches_unfused_formula_on_every_path_and_size() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for k in paths() {
            for n in (1..=70).chain([95, 128, 131]) {
                let m = random_symmetric(&mut rng, n);
                let (t, mq) = (random_vec(&mut rng, n), random_vec(&mut rng, n));
                let (v0, y0) = (random_vec(&mut rng, n), random_vec(&mut rng, n));
                let (lower, upper) = random_box(&mut rng, n);
                // Plain ADMM (a = 1, its own code path) on even n, relaxed otherwise.
                let a = if n % 2 == 0 {
                    1.0
                } else {
                    rng.random_range(0.5..2.0)
                };
                let rho = rng.random_range(0.5..4.0);
                let mt = naive(&m, n, &t);
                let (mut z, mut v, mut y, mut t_next) =
                    (vec![7.0; n + 1], v0.clone(), y0.clone(), vec![7.0; n + 1]);
                v.push(7.0);
                y.push(7.0);
                k.admm_step(
                    &m,
                    n,
                    &t,
                    &mq,
                    a,
                    rho,
                    &lower,
                    &upper,
                    &mut z,
                    &mut v,
                    &mut y,
                    &mut t_next,
                );
                for i in 0..n {
                    let zi = mt[i] - mq[i];
                    let w = a * zi + (1.0 - a) * v0[i] + y0[i] / rho;
                    let vp = w.max(lower[i]).min(upper[i]);
                    let yp = rho * (w - vp);
                    let tp = vp - yp / rho;
                    let e = 16.0 * tol(n);
                    assert!((z[i] - zi).abs() <= e, "{:?} n = {n} row {i}: z", k.path());
                    assert!((v[i] - vp).abs() <= e, "{:?} n = {n} row {i}: v", k.path());
                    assert!(
                        (y[i] - yp).abs() <= rho * e,
                        "{:?} n = {n} row {i}: y",
                        k.path()
                    );
                    assert!(
                        (t_next[i] - tp).abs() <= e,
                        "{:?} n = {n} row {i}: t",
                        k.path()
                    );
                }
                assert!(
                    z[n] == 7.0 && v[n] == 7.0 && y[n] == 7.0 && t_next[n] == 7.0,
                    "{:?} wrote past n = {n}",
                    k.path()
                );
            }
        }
    }

    #[test]
    fn fused_steps_propagate_nan_instead_of_clamping_it() {
        for k in paths() {
            for n in [1, 5, 9, 33] {
                let h = vec![1.0; n * n];
                let (lo, hi, zero) = (vec![-1.0; n], vec![1.0; n], vec![0.0; n]);
                let mut x = vec![0.0; n];
                x[n - 1] = f64::NAN;
                let mut out = vec![0.0; n];
                k.projected_gradient_step(&h, n, &x, &zero, 0.5, &lo, &hi, &mut out);
                assert!(
                    out.iter().all(|v| v.is_nan()),
                    "pg {:?} n = {n}: {out:?}",
                    k.path()
                );
                let (mut z, mut y_next) = (vec![0.0; n], vec![0.0; n]);
                k.fista_step(&h, n, &x, &zero, 0.5, &lo, &hi, 0.5, &mut z, &mut y_next);
                assert!(
                    z.iter().chain(&y_next).all(|v| v.is_nan()),
                    "fista {:?} n = {n}",
                    k.path()
                );
                let (mut z, mut v, mut y, mut t) =
                    (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                k.admm_step(
                    &h, n, &x, &zero, 1.0, 1.0, &lo, &hi, &mut z, &mut v, &mut y, &mut t,
                );
                assert!(
                    v.iter().chain(&y).chain(&t).all(|v| v.is_nan()),
                    "admm {:?} n = {n}",
                    k.path()
                );
            }
        }
    }

    /// Padded copies of `x` (length ld, zero padding) in 64-byte aligned buffers.
    fn pad(x: &[f64]) -> AlignedVec {
        AlignedVec::padded(x)
    }

    fn assert_close(what: &str, k: Kernel, n: usize, got: &[f64], want: &[f64], e: f64) {
        for i in 0..n {
            assert!(
                (got[i] - want[i]).abs() <= e,
                "{:?} n = {n} {what} row {i}: {} vs {}",
                k.path(),
                got[i],
                want[i]
            );
        }
    }

    fn padding_is_zero(v: &[f64], n: usize) -> bool {
        v[n..].iter().all(|&x| x == 0.0)
    }

    #[test]
    fn padded_layout_is_aligned_and_zero_padded() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        for n in [1, 2, 3, 4, 5, 29, 30, 31, 32, 33, 49] {
            let h = random_vec(&mut rng, n * n);
            let p = PaddedSymmetric::from_row_major(&h, n).unwrap();
            assert_eq!(p.ld(), padded_len(n));
            assert!(p.ld() % 4 == 0 && p.ld() >= n && p.ld() < n + 4);
            assert_eq!(p.as_slice().as_ptr() as usize % 64, 0);
            for j in 0..n {
                let col = &p.as_slice()[j * p.ld()..(j + 1) * p.ld()];
                assert_eq!(&col[..n], &h[j * n..(j + 1) * n], "n = {n} column {j}");
                assert!(padding_is_zero(col, n));
            }
            assert!(PaddedSymmetric::from_row_major(&h, n + 1).is_none());
            assert_eq!(PaddedSymmetric::from_fn(n, |i, j| h[j * n + i]), p);
            let v = AlignedVec::zeros(n);
            assert_eq!((v.len(), v.as_ptr() as usize % 64), (n, 0));
        }
        assert!(AlignedVec::zeros(0).is_empty());
    }

    #[test]
    fn state_vectors_are_disjoint_consecutive_and_aligned() {
        for ld in [0, 4, 32] {
            let mut v = Vectors::<3>::zeros(ld);
            for (i, x) in v.all_mut().into_iter().enumerate() {
                assert_eq!(x.len(), ld);
                x.fill(i as f64);
            }
            for i in 0..3 {
                assert!(
                    v.get(i).iter().all(|&x| x == i as f64),
                    "ld = {ld}, vector {i}"
                );
                v.get_mut(i).fill(-1.0);
            }
            assert!(v.buf.iter().all(|&x| x == -1.0) && v.buf.len() == 3 * ld);
            assert_eq!(v.buf.as_ptr() as usize % 64, 0);
        }
    }

    /// Every padded kernel against the naive product and the unfused formulas, on every
    /// path, at sizes with every remainder mod 4 (and n = 1), across panel boundaries, in
    /// place (ld ≤ 60) and through the scratch buffer (ld > 60).
    #[test]
    fn padded_kernels_match_naive_on_every_path_and_size() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for k in paths() {
            for n in (1..=70).chain([95, 128, 131]) {
                let ld = padded_len(n);
                // A general H: the kernels apply Hᵀ (the stored columns are H's rows).
                let h = random_vec(&mut rng, n * n);
                let hp = PaddedSymmetric::from_row_major(&h, n).unwrap();
                let ht = transpose(&h, n);
                let (x, q, z0) = (
                    random_vec(&mut rng, n),
                    random_vec(&mut rng, n),
                    random_vec(&mut rng, n),
                );
                let (lower, upper) = random_box(&mut rng, n);
                let (lo, hi) = (pad(&lower), pad(&upper));
                let hx = naive(&ht, n, &x);
                let e = tol(n);
                let mut scratch = AlignedVec::zeros(ld);

                let mut y = AlignedVec::zeros(ld);
                y.fill(7.0);
                k.matvec_padded(&hp, &x, &mut y);
                assert_close("Hx", k, n, &y, &hx, e);
                assert!(padding_is_zero(&y, n), "{:?} n = {n}", k.path());

                let alpha = rng.random_range(0.1..1.0);
                let mut z = pad(&x);
                k.pg_step_padded(&hp, &mut z, &pad(&q), alpha, &lo, &hi, &mut scratch);
                let want: Vec<f64> = (0..n)
                    .map(|i| (x[i] - alpha * (hx[i] + q[i])).max(lower[i]).min(upper[i]))
                    .collect();
                assert_close("pg", k, n, &z, &want, e);
                assert!(padding_is_zero(&z, n), "{:?} n = {n} pg", k.path());

                let beta = rng.random_range(0.0..1.0);
                let (mut z, mut y) = (pad(&z0), pad(&x));
                k.fista_step_padded(
                    &hp,
                    &mut y,
                    &pad(&q),
                    alpha,
                    &lo,
                    &hi,
                    beta,
                    &mut z,
                    &mut scratch,
                );
                let want_y: Vec<f64> = (0..n).map(|i| want[i] + beta * (want[i] - z0[i])).collect();
                assert_close("fista x⁺", k, n, &z, &want, e);
                assert_close("fista y⁺", k, n, &y, &want_y, 4.0 * e);
                assert!(padding_is_zero(&z, n) && padding_is_zero(&y, n));

                // ADMM: plain, Peaceman–Rachford and a general relaxation.
                for a in [1.0, 2.0, rng.random_range(0.5..1.9)] {
                    // ADMM on the DR variable s (v = Π(s) not stored): z⁺ = Mt − m_q.
                    let wz: Vec<f64> = (0..n).map(|i| hx[i] - q[i]).collect();
                    let e = 16.0 * e;
                    let s0 = random_vec(&mut rng, n);
                    let (mut t, mut z, mut s) = (pad(&x), AlignedVec::zeros(ld), pad(&s0));
                    z.fill(7.0);
                    k.admm_dr_step_padded(
                        &hp,
                        &mut t,
                        &pad(&q),
                        a,
                        &lo,
                        &hi,
                        &mut z,
                        &mut s,
                        &mut scratch,
                    );
                    let (mut ws, mut wt) = (vec![], vec![]);
                    for i in 0..n {
                        let v = s0[i].max(lower[i]).min(upper[i]);
                        let w = a * wz[i] + s0[i] - a * v;
                        let vp = w.max(lower[i]).min(upper[i]);
                        ws.push(w);
                        wt.push(2.0 * vp - w);
                    }
                    assert_close("admm dr z", k, n, &z, &wz, e);
                    assert_close("admm dr s", k, n, &s, &ws, e);
                    assert_close("admm dr t", k, n, &t, &wt, 2.0 * e);
                    assert!(
                        [&z, &s, &t].iter().all(|b| padding_is_zero(b, n)),
                        "{:?} n = {n} a = {a}: dr padding",
                        k.path()
                    );
                }
            }
        }
    }

    /// From six vectors (n > 20) up, the padded and unpadded kernels sum each row in the
    /// same order (column by column, one FMA per entry), so on the same path their steps
    /// agree bit for bit (below, the padded AVX2 kernel splits even and odd columns), in
    /// place and through the scratch buffer alike.
    #[test]
    fn padded_and_unpadded_steps_agree_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(10);
        for k in paths() {
            for n in [21, 29, 30, 37, 49, 60, 61, 70] {
                let h = random_symmetric(&mut rng, n);
                let hp = PaddedSymmetric::from_row_major(&h, n).unwrap();
                let (z, q) = (random_vec(&mut rng, n), random_vec(&mut rng, n));
                let (lo, hi) = random_box(&mut rng, n);
                let mut out = vec![0.0; n];
                k.projected_gradient_step(&h, n, &z, &q, 0.3, &lo, &hi, &mut out);
                let (mut zp, mut scratch) = (pad(&z), AlignedVec::zeros(hp.ld()));
                k.pg_step_padded(
                    &hp,
                    &mut zp,
                    &pad(&q),
                    0.3,
                    &pad(&lo),
                    &pad(&hi),
                    &mut scratch,
                );
                assert_eq!(&zp[..n], &out[..], "{:?} n = {n}", k.path());
            }
        }
    }

    #[test]
    fn padded_steps_propagate_nan_instead_of_clamping_it() {
        for k in paths() {
            for n in [1, 5, 9, 33, 61] {
                let h = PaddedSymmetric::from_row_major(&vec![1.0; n * n], n).unwrap();
                let ld = h.ld();
                let (lo, hi) = (pad(&vec![-1.0; n]), pad(&vec![1.0; n]));
                let zero = AlignedVec::zeros(ld);
                let mut x = AlignedVec::zeros(ld);
                x[n - 1] = f64::NAN;
                let mut scratch = AlignedVec::zeros(ld);
                let mut z = x.clone();
                k.pg_step_padded(&h, &mut z, &zero, 0.5, &lo, &hi, &mut scratch);
                assert!(
                    z[..n].iter().all(|v| v.is_nan()),
                    "pg {:?} n = {n}",
                    k.path()
                );
                let (mut z, mut y) = (AlignedVec::zeros(ld), x.clone());
                k.fista_step_padded(&h, &mut y, &zero, 0.5, &lo, &hi, 0.5, &mut z, &mut scratch);
                assert!(
                    z[..n].iter().chain(&y[..n]).all(|v| v.is_nan()),
                    "fista {:?} n = {n}",
                    k.path()
                );
                for a in [1.0, 2.0, 1.5] {
                    let (mut t, mut z, mut s) = (x.clone(), AlignedVec::zeros(ld), x.clone());
                    k.admm_dr_step_padded(
                        &h,
                        &mut t,
                        &zero,
                        a,
                        &lo,
                        &hi,
                        &mut z,
                        &mut s,
                        &mut scratch,
                    );
                    assert!(
                        z[..n]
                            .iter()
                            .chain(&s[..n])
                            .chain(&t[..n])
                            .all(|v| v.is_nan()),
                        "admm dr a = {a} {:?} n = {n}",
                        k.path()
                    );
                }
            }
        }
    }

    #[test]
    #[should_panic(expected = "pg_step_padded")]
    fn padded_kernel_rejects_unpadded_vectors() {
        let h = PaddedSymmetric::from_row_major(&[1.0; 9], 3).unwrap();
        let v = [0.0; 3];
        let (mut z, mut scratch) = ([0.0; 4], [0.0; 4]);
        Kernel::detect().pg_step_padded(&h, &mut z, &v, 1.0, &v, &v, &mut scratch);
    }

    #[test]
    fn detect_picks_avx2_when_the_cpu_has_it() {
        let want = if KernelPath::Avx2Fma.is_available() {
            KernelPath::Avx2Fma
        } else {
            KernelPath::Portable
        };
        assert_eq!(Kernel::detect().path(), want);
        assert_eq!(Kernel::detect(), Kernel::detect());
    }

    #[test]
    fn zero_size_is_a_no_op() {
        for k in paths() {
            let mut y: [f64; 0] = [];
            k.matvec(&[], 0, &[], &mut y);
            k.matvec_symmetric(&[], 0, &[], &mut y);
            k.projected_gradient_step(&[], 0, &[], &[], 1.0, &[], &[], &mut y);
            k.fista_step(&[], 0, &[], &[], 1.0, &[], &[], 0.5, &mut [], &mut y);
            k.admm_step(
                &[],
                0,
                &[],
                &[],
                1.0,
                1.0,
                &[],
                &[],
                &mut [],
                &mut [],
                &mut [],
                &mut y,
            );
            let h = PaddedSymmetric::from_row_major(&[], 0).unwrap();
            let (mut a, mut b, mut c) = ([0.0; 0], [0.0; 0], [0.0; 0]);
            k.matvec_padded(&h, &[], &mut y);
            k.pg_step_padded(&h, &mut a, &[], 1.0, &[], &[], &mut y);
            k.fista_step_padded(&h, &mut a, &[], 1.0, &[], &[], 0.5, &mut b, &mut y);
            k.admm_dr_step_padded(&h, &mut a, &[], 2.0, &[], &[], &mut b, &mut c, &mut y);
        }
    }

    #[test]
    #[should_panic(expected = "dense kernel")]
    fn wrong_length_panics_with_a_message() {
        let mut y = [0.0; 2];
        matvec(&[1.0, 2.0, 3.0], 2, &[1.0, 1.0], &mut y);
    }
}
