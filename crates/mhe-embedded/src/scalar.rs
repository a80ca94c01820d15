//! The scalar type: f64 (bit for bit with the std build) or f32.

use core::ops::{Add, Div, Mul, Neg, Sub};

/// A floating-point scalar: `f64` or `f32`. Only the four IEEE operations and comparisons
/// are used (no `sqrt`, no FMA), so the step is the same sequence of correctly rounded
/// operations on every target.
pub trait Scalar:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + core::fmt::Debug
    + 'static
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// 2.
    const TWO: Self;
    /// Whether the value is neither NaN nor ±∞.
    fn is_finite(self) -> bool;
}

impl Scalar for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const TWO: Self = 2.0;
    #[inline]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}

impl Scalar for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const TWO: Self = 2.0;
    #[inline]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
}

/// `min(u, max(l, v))` with NaN propagation, the operand order of `qp_iter::kernel`.
#[inline(always)]
pub(crate) fn clamp<T: Scalar>(v: T, l: T, u: T) -> T {
    let w = if l > v { l } else { v };
    if u < w { u } else { w }
}
