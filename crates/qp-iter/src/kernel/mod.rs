//! Dense kernels for the hot loop: y = Hx for a small symmetric H and the fused steps of
//! the methods (projected gradient z⁺ = Π_\[l,u\](z − α(Hz + q)), FISTA, ADMM on the
//! Douglas–Rachford variable), each one pass over the matrix.
//!
//! One iteration of every method is one such product plus O(n) work, so this module is
//! the single place where per-iteration cost is decided.
//!
//! ## Files
//! - `mod.rs` (here): dispatch ([`Kernel`], [`KernelPath`], detection) and the public
//!   entry points [`Kernel::matvec_padded`], [`Kernel::pg_step_padded`],
//!   [`Kernel::fista_step_padded`], [`Kernel::admm_dr_step_padded`]: lengths checked, then
//!   one of the two paths.
//! - `layout.rs`: the padded layout ([`padded_len`], [`AlignedVec`], [`PaddedSymmetric`]).
//! - `portable.rs`: the portable path, plain Rust.
//! - `avx2.rs`: the AVX2 + FMA path (x86-64 only), with the panel scheme it uses.
//!
//! ## Padded layout (what the methods run)
//! [`PaddedSymmetric`] stores the matrix by columns with leading dimension
//! [`padded_len`]`(n)` (n rounded up to 4) in a 64-byte aligned buffer, and the methods
//! keep every vector padded the same way with zeros ([`AlignedVec`]): each column is whole
//! aligned 4-wide loads, so the AVX2 kernels need no masks or tails and no load crosses a
//! cache line. Rows go in const-generic panels of 1 … 15 vectors chosen at run time; up to
//! n = 60 the whole product is one panel and the steps update in place.
//!
//! ## Dispatch
//! The committed build targets baseline x86-64 (SSE2 only; no `-C target-cpu=native`).
//! On x86-64 CPUs with AVX2 and FMA the kernels run a hand-vectorised path compiled with
//! `#[target_feature(enable = "avx2,fma")]`; everywhere else the portable path (the
//! product column by column, element-wise, which the baseline target vectorises, then the
//! step's row-local update). The choice is made once: [`Kernel::detect`] caches it in a
//! `OnceLock`, and a [`Kernel`] value stored in a method's setup data carries it, so a call
//! costs one predictable branch, not a CPU query. Maps are built with
//! [`get_global_kernel`] (the detected kernel unless a caller set another with
//! [`set_global_kernel`]) or are given one ([`crate::MethodMap::with_kernel`]); the library
//! never reads an environment variable.

mod layout;
mod portable;

#[cfg(target_arch = "x86_64")]
mod avx2;

#[cfg(test)]
mod tests;

pub(crate) use layout::Vectors;
pub use layout::{AlignedVec, PaddedSymmetric, padded_len};

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU8, Ordering};

/// Which implementation a [`Kernel`] runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KernelPath {
    /// Plain Rust; what the baseline target vectorises itself.
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
/// use qp_iter::kernel::{Kernel, KernelPath, PaddedSymmetric};
/// let k = Kernel::detect();
/// let h = PaddedSymmetric::from_row_major(&[2.0, 1.0, 1.0, 3.0], 2).unwrap();
/// let mut y = [0.0; 4]; // ld = 4 entries
/// k.matvec_padded(&h, &[1.0, -1.0], &mut y);
/// assert_eq!(y, [1.0, -2.0, 0.0, 0.0]);
/// assert!(Kernel::with_path(KernelPath::Portable).is_some());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Kernel {
    path: KernelPath,
}

static DETECTED: OnceLock<Kernel> = OnceLock::new();

/// The kernel maps are built with unless a caller chose one ([`set_global_kernel`]):
/// 0 = not set (detect), else `1 + KernelPath as u8`.
static GLOBAL: AtomicU8 = AtomicU8::new(0);

/// Makes `kernel` the one every map and operator built afterwards runs (faer's
/// `set_global_parallelism` idiom); a map built earlier keeps its kernel. The library never
/// reads the environment: a tool decides (e.g. `cargo xtask` reads `QP_ITER_KERNEL`) and
/// calls this once at start-up. Per map: `MethodMap::with_kernel`.
///
/// ```
/// use qp_iter::kernel::{self, Kernel};
/// kernel::set_global_kernel(Kernel::portable());
/// assert_eq!(kernel::get_global_kernel(), Kernel::portable());
/// ```
pub fn set_global_kernel(kernel: Kernel) {
    let code = match kernel.path {
        KernelPath::Portable => 1,
        KernelPath::Avx2Fma => 2,
    };
    GLOBAL.store(code, Ordering::Relaxed);
}

/// The kernel new maps run: the one given to [`set_global_kernel`], else
/// [`Kernel::detect`]. Read at setup only (never per step).
pub fn get_global_kernel() -> Kernel {
    match GLOBAL.load(Ordering::Relaxed) {
        1 => Kernel::portable(),
        // Only a validated `Kernel` is ever stored, so the path is available.
        2 => Kernel {
            path: KernelPath::Avx2Fma,
        },
        _ => Kernel::detect(),
    }
}

impl Kernel {
    /// The fastest path the running CPU supports (detected on first use, then cached). A
    /// CPU query only: which kernel new maps run is [`get_global_kernel`].
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
}

/// The padded kernels: the product and the methods' steps on a [`PaddedSymmetric`] matrix
/// and vectors of (at least) ld = [`padded_len`]`(n)` entries. They compute all ld rows; the
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
        check_lens("matvec_padded (x)", h.n(), [x.len()]);
        check_lens("matvec_padded (y)", h.ld(), [y.len()]);
        if h.n() == 0 {
            return;
        }
        match self.path {
            KernelPath::Portable => {
                portable::matvec_columns(h.as_slice(), h.n(), h.ld(), x, y);
            }
            #[cfg(target_arch = "x86_64")]
            // SAFETY: AVX2 + FMA by the type invariant; n ≥ 1; the matrix holds n columns
            // of ld entries (type invariant), x ≥ n and y ≥ ld entries (checked above).
            KernelPath::Avx2Fma => unsafe {
                avx2::run::<{ avx2::STORE }>(avx2::Ctx::product(h, x.as_ptr(), y.as_mut_ptr()))
            },
            #[cfg(not(target_arch = "x86_64"))]
            KernelPath::Avx2Fma => portable::matvec_columns(h.as_slice(), h.n(), h.ld(), x, y),
        }
    }

    /// The projected-gradient step z ← Π_\[l,u\](z − α(Hz + q)) of [`crate::pg`] for a
    /// symmetric H, fused (no separate Hz buffer, axpy and projection loops) and **in
    /// place**: when the
    /// whole product is one register panel (ld ≤ 60, see [`PADDED_IN_PLACE_MAX`]) every
    /// entry of z is read before the first is written, so z is overwritten directly;
    /// otherwise (and on the portable path) the step goes through `scratch` and is copied
    /// back. In place, a method's state needs no second buffer to swap (a per-step store
    /// of which buffer is current was measured to cost ≈ 2–3 ns at n = 30). Every vector
    /// ≥ ld entries. Allocation-free.
    ///
    /// Clamping is `min(u, max(l, v))` in that operand order, so a NaN in `v` stays NaN
    /// (the drivers then report it) instead of being clamped to a bound; the same holds for
    /// the other steps.
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
            h.ld(),
            [z.len(), q.len(), lower.len(), upper.len(), scratch.len()],
        );
        if h.n() == 0 {
            return;
        }
        let (hs, n, ld) = (h.as_slice(), h.n(), h.ld());
        self.in_place(
            ld,
            z,
            scratch,
            (),
            // SAFETY: AVX2 + FMA by the type invariant; n ≥ 1; n columns of ld entries;
            // every vector ≥ ld (checked above); `x` and `dest` as `in_place` documents.
            |x, dest, ()| unsafe {
                let mut c = avx2::Ctx::product(h, x, dest);
                (c.q, c.lo, c.hi, c.a) = (q.as_ptr(), lower.as_ptr(), upper.as_ptr(), alpha);
                avx2::run::<{ avx2::PG }>(c);
            },
            |z, out, ()| portable::pg_step(hs, n, ld, z, q, alpha, lower, upper, out),
        );
    }

    /// One step of constant-momentum FISTA ([`crate::fista`]), fused and in place as
    /// [`Kernel::pg_step_padded`]: x⁺ = Π_\[l,u\](y − α(Hy + q)) over `z` (x on entry),
    /// y⁺ = x⁺ + β(x⁺ − x) over `y`, computed as (1 + β)x⁺ − βx (so β = 0, FISTA's restart
    /// step, gives y⁺ = x⁺ exactly). Every vector ≥ ld entries.
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
            h.ld(),
            [
                y.len(),
                q.len(),
                lower.len(),
                upper.len(),
                z.len(),
                scratch.len(),
            ],
        );
        if h.n() == 0 {
            return;
        }
        let (hs, n, ld) = (h.as_slice(), h.n(), h.ld());
        self.in_place(
            ld,
            y,
            scratch,
            z,
            // SAFETY: as in `pg_step_padded`, with y⁺ (`next`) in place of y; `z` is a
            // distinct `&mut` the product never reads (only the epilogue, row by row,
            // before writing the same row).
            |x, dest, z| unsafe {
                let mut c = avx2::Ctx::product(h, x, z.as_mut_ptr());
                (c.q, c.lo, c.hi, c.a, c.b) =
                    (q.as_ptr(), lower.as_ptr(), upper.as_ptr(), alpha, beta);
                c.next = dest;
                avx2::run::<{ avx2::FISTA }>(c);
            },
            |y, next, z| portable::fista_step(hs, n, ld, y, q, alpha, lower, upper, beta, z, next),
        );
    }

    /// One step of relaxed ADMM ([`crate::admm`]) on min ½zᵀHz + qᵀz, z = v ∈ \[l, u\]
    /// (M = ρ(H + ρI)⁻¹ in `m`, m_q = (H + ρI)⁻¹q, relaxation a ∈ (0, 2]), carried on the
    /// Douglas–Rachford variable s = v + y/ρ instead of (v, y): with v = Π_\[l,u\](s) and
    /// the input t = 2v − s = v − y/ρ,
    /// z⁺ = Mt − m_q, s⁺ = a z⁺ + s − a v (= w = a z⁺ + (1 − a)v + y/ρ, the relaxed point
    /// of the (v, y) form) over `s`, t⁺ = 2Π_\[l,u\](s⁺) − s⁺ over `t`, z⁺ over `z`; in place as
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
            m.ld(),
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
        if m.n() == 0 {
            return;
        }
        let (ms, n, ld) = (m.as_slice(), m.n(), m.ld());
        self.in_place(
            ld,
            t,
            scratch,
            (z, s),
            // SAFETY: as in `pg_step_padded`, with t⁺ in place of t; z and s are distinct
            // `&mut`s the product never reads (the epilogue reads s row by row before
            // writing the same rows).
            |x, dest, (z, s)| unsafe {
                let mut c = avx2::Ctx::product(m, x, dest);
                (c.q, c.lo, c.hi, c.a) = (mq.as_ptr(), lower.as_ptr(), upper.as_ptr(), relaxation);
                (c.next, c.v) = (z.as_mut_ptr(), s.as_mut_ptr());
                if relaxation == 1.0 {
                    avx2::run::<{ avx2::DR1 }>(c)
                } else {
                    avx2::run::<{ avx2::DR }>(c)
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
/// (one register panel of ≤ 15 vectors, see `avx2::run`): n ≤ 60.
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

/// Clamp with NaN propagation: `min(u, max(l, v))` with the same operand order as the
/// `vmaxpd`/`vminpd` of the AVX2 path, so both paths agree bit for bit on the clamp.
#[inline(always)]
pub(crate) fn clamp_nan_propagating(v: f64, l: f64, u: f64) -> f64 {
    let w = if l > v { l } else { v };
    if u < w { u } else { w }
}
