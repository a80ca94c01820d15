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

fn transpose(h: &[f64], n: usize) -> Vec<f64> {
    (0..n * n).map(|k| h[(k % n) * n + k / n]).collect()
}

/// Rounding tolerance for a length-n dot product of entries bounded by 1 in magnitude.
fn tol(n: usize) -> f64 {
    4.0 * n as f64 * f64::EPSILON
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
                k.admm_dr_step_padded(&h, &mut t, &zero, a, &lo, &hi, &mut z, &mut s, &mut scratch);
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
        let h = PaddedSymmetric::from_row_major(&[], 0).unwrap();
        let (mut a, mut b, mut c) = ([0.0; 0], [0.0; 0], [0.0; 0]);
        k.matvec_padded(&h, &[], &mut y);
        k.pg_step_padded(&h, &mut a, &[], 1.0, &[], &[], &mut y);
        k.fista_step_padded(&h, &mut a, &[], 1.0, &[], &[], 0.5, &mut b, &mut y);
        k.admm_dr_step_padded(&h, &mut a, &[], 2.0, &[], &[], &mut b, &mut c, &mut y);
    }
}

/// The plain padded product sums each row column after column, one FMA per entry on the
/// AVX2 path and a multiply then an add on the portable path, at every size: it rounds
/// exactly like the sequential loops below (the rounding ADMM's m_q and gradient dual had
/// before the product moved to the padded layout).
#[test]
fn padded_product_rounds_like_a_column_order_sum() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for k in paths() {
        for n in (1..=70).chain([95, 128, 131]) {
            let h = random_vec(&mut rng, n * n);
            // Column j of the stored matrix is row j of `h`.
            let hp = PaddedSymmetric::from_row_major(&h, n).unwrap();
            let x = random_vec(&mut rng, n);
            let mut y = AlignedVec::zeros(hp.ld());
            k.matvec_padded(&hp, &x, &mut y);
            for i in 0..n {
                let mut want = 0.0f64;
                for j in 0..n {
                    let c = h[j * n + i];
                    want = match k.path() {
                        KernelPath::Avx2Fma => c.mul_add(x[j], want),
                        KernelPath::Portable => want + c * x[j],
                    };
                }
                assert_eq!(
                    y[i].to_bits(),
                    want.to_bits(),
                    "{:?} n = {n} row {i}: {} vs {want}",
                    k.path(),
                    y[i]
                );
            }
        }
    }
}
