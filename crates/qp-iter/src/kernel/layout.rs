//! The padded layout the kernels run on.
//!
//! [`PaddedSymmetric`] stores the matrix by columns with leading dimension
//! [`padded_len`]`(n)` (n rounded up to 4) in a 64-byte aligned buffer, and the methods
//! keep every vector padded the same way with zeros ([`AlignedVec`], or several vectors in
//! one allocation, `Vectors`): each column is whole aligned 4-wide loads, so the AVX2
//! kernels need no masks or tails and no load crosses a cache line. The padding rows of
//! the matrix are zero, so with zero padding in every input the padding of every output
//! stays zero.

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

/// A symmetric n × n matrix laid out for the padded kernels
/// ([`Kernel::pg_step_padded`](super::Kernel::pg_step_padded) and its siblings): column j
/// at offset j·ld with ld = [`padded_len`]`(n)`, rows n .. ld zero, the first column
/// 64-byte aligned. Every column is ld/4 whole SIMD vectors, so the kernels run without
/// masks or tails and their loads never split a cache line.
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
    /// row j of `h`, so for a non-symmetric `h` the kernels apply Hᵀ.
    pub fn from_row_major(h: &[f64], n: usize) -> Option<Self> {
        if n.checked_mul(n) != Some(h.len()) {
            return None;
        }
        Some(Self::from_fn(n, |i, j| h[j * n + i]))
    }

    /// The dimension n.
    #[inline]
    pub fn n(&self) -> usize {
        self.n
    }

    /// The leading dimension ld = [`padded_len`]`(n)`: the length every vector passed to
    /// the padded kernels must have at least.
    #[inline]
    pub fn ld(&self) -> usize {
        self.ld
    }

    /// Entry (i, j) = `f(i, j)` for i, j < n, stored by columns: the kernels apply the
    /// matrix F with F_ij = `f(i, j)` (also for a non-symmetric `f`).
    ///
    /// ```
    /// use qp_iter::kernel::{Kernel, PaddedSymmetric};
    /// let f = PaddedSymmetric::from_fn(2, |i, j| if (i, j) == (0, 1) { 1.0 } else { 0.0 });
    /// let mut y = [0.0; 4];
    /// Kernel::detect().matvec_padded(&f, &[0.0, 5.0], &mut y);
    /// assert_eq!(y, [5.0, 0.0, 0.0, 0.0]); // F = [[0, 1], [0, 0]]
    /// ```
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
    #[inline]
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
