//! Experiment: the padded projected-gradient step written once over `pulp::Simd`.

use pulp::{Simd, WithSimd};

use super::PaddedSymmetric;

/// One PG step z ← Π(z − α(Hz + q)), in place when the product is one panel.
pub(super) struct PgStep<'a> {
    pub h: &'a PaddedSymmetric,
    pub z: &'a mut [f64],
    pub q: &'a [f64],
    pub lo: &'a [f64],
    pub hi: &'a [f64],
    pub alpha: f64,
    pub scratch: &'a mut [f64],
}

/// Sums of V vectors of rows r0 .. r0 + 4V over all n columns.
#[inline(always)]
fn product<S: Simd, const V: usize>(
    simd: S,
    h: &PaddedSymmetric,
    x: &[f64],
    r0: usize,
) -> [S::f64s; V] {
    let (n, ld, hs) = (h.n(), h.ld(), h.as_slice());
    let zero = simd.splat_f64s(0.0);
    let mut acc = [zero; V];
    let x = &x[..n];
    let rows = 4 * V;
    if V <= 5 {
        let mut odd = [zero; V];
        let mut j = 0;
        while j + 2 <= n {
            let x0 = simd.splat_f64s(x[j]);
            let x1 = simd.splat_f64s(x[j + 1]);
            let c0 = S::as_simd_f64s(&hs[j * ld + r0..j * ld + r0 + rows]).0;
            let c1 = S::as_simd_f64s(&hs[(j + 1) * ld + r0..(j + 1) * ld + r0 + rows]).0;
            for v in 0..V {
                acc[v] = simd.mul_add_f64s(c0[v], x0, acc[v]);
                odd[v] = simd.mul_add_f64s(c1[v], x1, odd[v]);
            }
            j += 2;
        }
        if j < n {
            let xj = simd.splat_f64s(x[j]);
            let c = S::as_simd_f64s(&hs[j * ld + r0..j * ld + r0 + rows]).0;
            for v in 0..V {
                acc[v] = simd.mul_add_f64s(c[v], xj, acc[v]);
            }
        }
        for v in 0..V {
            acc[v] = simd.add_f64s(acc[v], odd[v]);
        }
    } else {
        for (j, &xj) in x.iter().enumerate() {
            let xj = simd.splat_f64s(xj);
            let c = S::as_simd_f64s(&hs[j * ld + r0..j * ld + r0 + rows]).0;
            for v in 0..V {
                acc[v] = simd.mul_add_f64s(c[v], xj, acc[v]);
            }
        }
    }
    acc
}

/// PG epilogue on rows r0 .. r0 + 4V: out = Π(z − αq − α s); `z` is read before `out` is
/// written (row block by row block), `z = None` reads z from `out` itself (in place).
#[inline(always)]
fn epilogue<S: Simd, const V: usize>(
    simd: S,
    acc: [S::f64s; V],
    r0: usize,
    z: Option<&[f64]>,
    q: &[f64],
    lo: &[f64],
    hi: &[f64],
    alpha: f64,
    out: &mut [f64],
) {
    let rows = 4 * V;
    let a = simd.splat_f64s(alpha);
    let q = S::as_simd_f64s(&q[r0..r0 + rows]).0;
    let lo = S::as_simd_f64s(&lo[r0..r0 + rows]).0;
    let hi = S::as_simd_f64s(&hi[r0..r0 + rows]).0;
    let out = S::as_mut_simd_f64s(&mut out[r0..r0 + rows]).0;
    let zs = z.map(|z| S::as_simd_f64s(&z[r0..r0 + rows]).0);
    for v in 0..V {
        let zv = match zs {
            Some(z) => z[v],
            None => out[v],
        };
        let base = simd.negate_mul_add_f64s(a, q[v], zv);
        let w = simd.negate_mul_add_f64s(a, acc[v], base);
        out[v] = simd.min_f64s(hi[v], simd.max_f64s(lo[v], w));
    }
}

#[inline(always)]
fn panel<S: Simd, const V: usize>(simd: S, s: &mut PgStep<'_>, r0: usize, in_place: bool) {
    if in_place {
        let acc = product::<S, V>(simd, s.h, s.z, r0);
        epilogue::<S, V>(simd, acc, r0, None, s.q, s.lo, s.hi, s.alpha, s.z);
    } else {
        let acc = product::<S, V>(simd, s.h, s.z, r0);
        epilogue::<S, V>(
            simd,
            acc,
            r0,
            Some(s.z),
            s.q,
            s.lo,
            s.hi,
            s.alpha,
            s.scratch,
        );
    }
}

impl WithSimd for PgStep<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        let mut s = self;
        assert!(core::mem::size_of::<S::f64s>() == 32, "4-lane f64 vectors");
        let ld = s.h.ld();
        let (mut r0, mut left) = (0, ld / 4);
        let in_place = left <= 15;
        while left > 15 {
            panel::<S, 8>(simd, &mut s, r0, false);
            r0 += 32;
            left -= 8;
        }
        match left {
            0 => {}
            1 => panel::<S, 1>(simd, &mut s, r0, in_place),
            2 => panel::<S, 2>(simd, &mut s, r0, in_place),
            3 => panel::<S, 3>(simd, &mut s, r0, in_place),
            4 => panel::<S, 4>(simd, &mut s, r0, in_place),
            5 => panel::<S, 5>(simd, &mut s, r0, in_place),
            6 => panel::<S, 6>(simd, &mut s, r0, in_place),
            7 => panel::<S, 7>(simd, &mut s, r0, in_place),
            8 => panel::<S, 8>(simd, &mut s, r0, in_place),
            9 => panel::<S, 9>(simd, &mut s, r0, in_place),
            10 => panel::<S, 10>(simd, &mut s, r0, in_place),
            11 => panel::<S, 11>(simd, &mut s, r0, in_place),
            12 => panel::<S, 12>(simd, &mut s, r0, in_place),
            13 => panel::<S, 13>(simd, &mut s, r0, in_place),
            14 => panel::<S, 14>(simd, &mut s, r0, in_place),
            _ => panel::<S, 15>(simd, &mut s, r0, in_place),
        }
        if !in_place {
            s.z[..ld].copy_from_slice(&s.scratch[..ld]);
        }
    }
}
