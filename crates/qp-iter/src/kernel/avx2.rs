//! Kernels on the padded layout ([`PaddedSymmetric`]): every column is ld/4 whole vectors,
//! 32-byte aligned when the storage is an [`AlignedVec`](super::AlignedVec), so there are no masks, tails or
//! cache-line-splitting loads. Rows go in panels of 8 to 15 vectors (see [`run`]), one
//! accumulator per vector: eight or more independent FMA chains cover the FMA latency on
//! two pipes (the chain of a panel is no longer than its issue time), as in the
//! reference kernel. The
//! epilogue runs on each finished vector, its parts that do not depend on the product
//! formed first, so a method's whole step is one pass over the matrix.

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

/// The epilogue `E` on rows r .. r + 4 with s = (Hx)\[rows\].
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
/// summed column after column by FMAs (for V ≤ 5 in the steps: even and odd columns
/// separately, then added; the plain product, `STORE`, always sums in column order, so it
/// rounds exactly like a sequential FMA loop over the columns).
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
        if V <= 5 && E != STORE {
            // Few vectors: V chains of n FMAs would wait on latency (4 cycles each,
            // issue V/2), so even and odd columns go to two sets of accumulators. (Not
            // for the plain product: ADMM's m_q and gradient dual keep the rounding of a
            // column-order sum at every n; it runs once per load, not per step.)
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
