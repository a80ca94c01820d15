//! H_c z of an MHE window through the dynamics, without the dense H_c: the product the std
//! estimator runs PG and FISTA through from n_z ≥ its crossover (`mhe_core::structured`),
//! repeated here operation for operation on the portable path (no FMA), so an exported
//! estimator on a long window stays bit for bit with the std one and stores the plant
//! blocks (O(n_x² + n_w² + n_x n_y)) instead of H (n_z²).
//!
//! With the weights folded in (4η^m P, 4Q, 2R): a forward pass x̂_{j+1} = A x̂_j + E ŵ¹_j with
//! ŷ_j = C x̂_j + F ŵ²_j, g_{y,j} = η^{m−1−j}·2R ŷ_j and the ŵ_j-part 4Q η^{m−1−j} ŵ_j + Fᵀg_{y,j}
//! (ŵ² rows); a backward pass λ_m = 0, the ŵ¹_j-part += Eᵀλ_{j+1},
//! λ_j = Aᵀλ_{j+1} + Cᵀg_{y,j}; the x̂₀-part 4η^m P x̂₀ + λ₀. On the Jacobi-scaled problem
//! (z = D y) D is folded into the same passes, as `mhe_core`'s `apply_scaled`.
//!
//! Each product is summed in the order of the std product it repeats ([`SumOrder`]). The std
//! fixed-size product zero-pads plants that are not one of its exact shapes; the padding
//! adds ±0 terms, which can only turn a sum that is exactly −0 into +0.

use crate::data::{DataError, check};
use crate::scalar::Scalar;

/// The summation order of the std product this one repeats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SumOrder {
    /// The fixed-size product (n_x, n_y, n_w1, n_w2 ≤ 16): each row of a block product in two
    /// partial sums (even and odd columns, the odd one added last), an accumulated
    /// term first in the even sum.
    Fixed,
    /// The run-time-size product (a size > 16): each row summed from 0 in column order.
    RunTime,
}

/// The factors of one window's structured H_c (see the module docs). Every block is stored
/// by columns (entry (i, k) at k·rows + i); the transposes are read from the same storage.
#[derive(Debug, Clone, Copy)]
pub struct Structured<'a, T> {
    /// n_x.
    pub nx: usize,
    /// n_y.
    pub ny: usize,
    /// n_w1.
    pub nw1: usize,
    /// n_w2.
    pub nw2: usize,
    /// The std product's summation order.
    pub order: SumOrder,
    /// A (n_x × n_x).
    pub a: &'a [T],
    /// E (n_x × n_w1).
    pub e: &'a [T],
    /// C (n_y × n_x).
    pub c: &'a [T],
    /// F (n_y × n_w2).
    pub f: &'a [T],
    /// 4Q (n_w × n_w).
    pub q: &'a [T],
    /// 2R (n_y × n_y).
    pub r: &'a [T],
    /// 4η^m P (n_x × n_x).
    pub p: &'a [T],
    /// η^{m−1−j} for the stages j = 0..m (m = the window length).
    pub decay: &'a [T],
}

/// A block of a stored matrix: entry (i, k) at `i·rs + k·cs` (a column-major block has
/// rs = 1, cs = rows; its transpose rs = rows of the block, cs = 1).
#[derive(Clone, Copy)]
struct Block<'m, T> {
    m: &'m [T],
    rs: usize,
    cs: usize,
}

impl<'m, T: Scalar> Block<'m, T> {
    /// Column-major r × c from `m` at offset `off` with leading dimension `ld`.
    fn cols(m: &'m [T], off: usize, ld: usize) -> Self {
        Self {
            m: &m[off..],
            rs: 1,
            cs: ld,
        }
    }

    /// The transpose of a column-major block with leading dimension `ld`.
    fn t(m: &'m [T], ld: usize) -> Self {
        Self { m, rs: ld, cs: 1 }
    }

    #[inline(always)]
    fn at(&self, i: usize, k: usize) -> T {
        self.m[i * self.rs + k * self.cs]
    }
}

/// out[..r] = (out when `acc`) + B x with x = `x` (c = x.len()) in the fixed-size product's
/// order: per row, the even columns in s0 (from the accumulated term, else from column 0),
/// the odd ones in s1 (from column 1), then s0 + s1.
#[inline]
fn gemv_fixed<T: Scalar>(b: Block<'_, T>, x: &[T], out: &mut [T], acc: bool) {
    let c = x.len();
    for (i, o) in out.iter_mut().enumerate() {
        let mut s0 = if acc { *o } else { T::ZERO };
        let mut s1 = T::ZERO;
        for (k, &xk) in x.iter().enumerate() {
            let p = b.at(i, k);
            if k % 2 == 0 {
                s0 = if k == 0 && !acc { p * xk } else { p * xk + s0 };
            } else if k == 1 {
                s1 = p * xk;
            } else {
                s1 = p * xk + s1;
            }
        }
        *o = if c > 1 { s0 + s1 } else { s0 };
    }
}

/// out[..r] += B x in column order (the run-time-size product).
#[inline]
fn gemv_seq<T: Scalar>(b: Block<'_, T>, x: &[T], out: &mut [T]) {
    for (k, &xk) in x.iter().enumerate() {
        for (i, o) in out.iter_mut().enumerate() {
            *o = *o + b.at(i, k) * xk;
        }
    }
}

/// `dst = d ⊙ src` (`d` empty: a copy).
#[inline]
fn load<T: Scalar>(dst: &mut [T], src: &[T], d: &[T]) {
    if d.is_empty() {
        dst.copy_from_slice(src);
    } else {
        for ((o, s), di) in dst.iter_mut().zip(src).zip(d) {
            *o = *di * *s;
        }
    }
}

impl<T: Scalar> Structured<'_, T> {
    /// n_w.
    fn nw(&self) -> usize {
        self.nw1 + self.nw2
    }

    /// Scalars of the two workspaces [`Structured::apply`] needs (g_{y,j} per stage; the
    /// temporaries).
    pub fn work_lens(&self) -> (usize, usize) {
        let m = self.decay.len();
        (m * self.ny, 4 * self.nx + self.ny + 2 * self.nw())
    }

    /// Checks the block lengths against the sizes and that the two workspaces fit in
    /// vectors of length n = n_x + m n_w (the estimator lends two of its work vectors).
    pub(crate) fn validate(
        &self,
        nx: usize,
        ny: usize,
        nw1: usize,
        nw2: usize,
        m: usize,
    ) -> Result<(), DataError> {
        check("structured nx", nx, self.nx)?;
        check("structured ny", ny, self.ny)?;
        check("structured nw1", nw1, self.nw1)?;
        check("structured nw2", nw2, self.nw2)?;
        check("structured decay length (m)", m, self.decay.len())?;
        let nw = self.nw();
        check("structured a length", nx * nx, self.a.len())?;
        check("structured e length", nx * nw1, self.e.len())?;
        check("structured c length", ny * nx, self.c.len())?;
        check("structured f length", ny * nw2, self.f.len())?;
        check("structured q length", nw * nw, self.q.len())?;
        check("structured r length", ny * ny, self.r.len())?;
        check("structured p length", nx * nx, self.p.len())?;
        let n = nx + m * nw;
        let (wa, wb) = self.work_lens();
        for (what, len) in [
            ("structured workspace g_y (m n_y ≤ n)", wa),
            ("structured workspace (4n_x + n_y + 2n_w ≤ n)", wb),
        ] {
            if len > n {
                return Err(DataError {
                    what,
                    expected: n,
                    actual: len,
                });
            }
        }
        Ok(())
    }

    /// out[..n] = H_c z (`d` non-empty: D H_c D z with D = diag(d), the Jacobi-scaled
    /// problem's Hessian), n = n_x + m n_w; `wa`, `wb` hold at least [`Structured::work_lens`]
    /// scalars. The operations of `mhe_core::structured` on the portable path, in its order.
    pub fn apply(&self, d: &[T], z: &[T], out: &mut [T], wa: &mut [T], wb: &mut [T]) {
        let (nx, ny, nw) = (self.nx, self.ny, self.nw());
        let m = self.decay.len();
        let n = nx + m * nw;
        let gy_all = &mut wa[..m * ny];
        let (x, rest) = wb.split_at_mut(nx);
        let (xn, rest) = rest.split_at_mut(nx);
        let (lam, rest) = rest.split_at_mut(nx);
        let (lamn, rest) = rest.split_at_mut(nx);
        let (y, rest) = rest.split_at_mut(ny);
        let (wd, rest) = rest.split_at_mut(nw);
        let v = &mut rest[..nw];
        let (z0, zw) = z[..n].split_at(nx);
        let (o0, ow) = out[..n].split_at_mut(nx);
        let (d0, dw) = if d.is_empty() {
            (d, d)
        } else {
            d[..n].split_at(nx)
        };
        load(x, z0, d0);
        // Forward: stage j's terms without λ, then x̂_{j+1} = A x̂_j + E ŵ¹_j.
        for j in 0..m {
            let dj = if d.is_empty() {
                d
            } else {
                &dw[j * nw..(j + 1) * nw]
            };
            load(wd, &zw[j * nw..(j + 1) * nw], dj);
            let gy = &mut gy_all[j * ny..(j + 1) * ny];
            let o = &mut ow[j * nw..(j + 1) * nw];
            self.forward_stage(self.decay[j], x, wd, v, y, gy, o, xn);
            x.copy_from_slice(xn);
        }
        self.backward(dw, gy_all, ow, lam, lamn);
        load(x, z0, d0);
        o0.copy_from_slice(lam);
        if self.order == SumOrder::Fixed {
            gemv_fixed(Block::cols(self.p, 0, nx), x, o0, true);
        } else {
            gemv_seq(Block::cols(self.p, 0, nx), x, o0);
        }
        if !d.is_empty() {
            for (o, di) in o0.iter_mut().zip(d0) {
                *o = *di * *o;
            }
        }
    }

    /// Forward stage j of [`Structured::apply`], without λ: ŷ_j = C x̂_j + F ŵ²_j,
    /// g_{y,j} = η_j (2R ŷ_j) into `gy`, the ŵ_j-part 4Q η_j ŵ_j + Fᵀg_{y,j} into `o` and
    /// x̂_{j+1} = A x̂_j + E ŵ¹_j into `xn`, from x̂_j in `x` and the (scaled) ŵ_j in `wd`;
    /// `v` (n_w) and `y` (n_y) are scratch.
    fn forward_stage(
        &self,
        eta_j: T,
        x: &[T],
        wd: &[T],
        v: &mut [T],
        y: &mut [T],
        gy: &mut [T],
        o: &mut [T],
        xn: &mut [T],
    ) {
        let (nx, ny, nw1, nw) = (self.nx, self.ny, self.nw1, self.nw());
        let a = Block::cols(self.a, 0, nx);
        let e = Block::cols(self.e, 0, nx);
        let c = Block::cols(self.c, 0, ny);
        let f = Block::cols(self.f, 0, ny);
        let ft = Block::t(self.f, ny);
        let r = Block::cols(self.r, 0, ny);
        let (w1, w2) = wd.split_at(nw1);
        for (vi, wi) in v.iter_mut().zip(wd.iter()) {
            *vi = eta_j * *wi;
        }
        let (v1, v2) = v.split_at(nw1);
        if self.order == SumOrder::Fixed {
            // ŷ = C x̂ + F ŵ², g_y = η_j (2R ŷ).
            gemv_fixed(f, w2, y, false);
            gemv_fixed(c, x, y, true);
            gemv_fixed(r, y, gy, false);
            for g in gy.iter_mut() {
                *g = eta_j * *g;
            }
            let (o1, o2) = o.split_at_mut(nw1);
            gemv_fixed(Block::cols(self.q, nw1 * nw, nw), v2, o1, false);
            gemv_fixed(Block::cols(self.q, 0, nw), v1, o1, true);
            gemv_fixed(ft, gy, o2, false);
            gemv_fixed(Block::cols(self.q, nw1 * nw + nw1, nw), v2, o2, true);
            gemv_fixed(Block::cols(self.q, nw1, nw), v1, o2, true);
            gemv_fixed(e, w1, xn, false);
            gemv_fixed(a, x, xn, true);
        } else {
            y.fill(T::ZERO);
            gemv_seq(f, w2, y);
            gemv_seq(c, x, y);
            gy.fill(T::ZERO);
            gemv_seq(r, y, gy);
            for g in gy.iter_mut() {
                *g = *g * eta_j;
            }
            o.fill(T::ZERO);
            gemv_seq(Block::cols(self.q, 0, nw), v, o);
            gemv_seq(ft, gy, &mut o[nw1..]);
            xn.fill(T::ZERO);
            gemv_seq(e, w1, xn);
            gemv_seq(a, x, xn);
        }
    }

    /// Backward pass of [`Structured::apply`]: λ_m = 0, the ŵ¹_j-part of `ow` += Eᵀλ_{j+1}
    /// (then the stage scaled by D when `dw`, its diagonal, is non-empty),
    /// λ_j = Aᵀλ_{j+1} + Cᵀg_{y,j}; leaves λ₀ in `lam` (`lamn` is scratch).
    fn backward(&self, dw: &[T], gy_all: &[T], ow: &mut [T], lam: &mut [T], lamn: &mut [T]) {
        let (nx, ny, nw1, nw) = (self.nx, self.ny, self.nw1, self.nw());
        let fixed = self.order == SumOrder::Fixed;
        let at = Block::t(self.a, nx);
        let et = Block::t(self.e, nx);
        let ct = Block::t(self.c, ny);
        lam.fill(T::ZERO);
        for j in (0..self.decay.len()).rev() {
            let o = &mut ow[j * nw..(j + 1) * nw];
            let gy = &gy_all[j * ny..(j + 1) * ny];
            if fixed {
                gemv_fixed(et, lam, &mut o[..nw1], true);
            } else {
                gemv_seq(et, lam, &mut o[..nw1]);
            }
            if !dw.is_empty() {
                for (vi, di) in o.iter_mut().zip(&dw[j * nw..(j + 1) * nw]) {
                    *vi = *vi * *di;
                }
            }
            // Cᵀg_{y,j}, as the std product forms it in its forward pass.
            if fixed {
                gemv_fixed(ct, gy, lamn, false);
                gemv_fixed(at, lam, lamn, true);
            } else {
                lamn.fill(T::ZERO);
                gemv_seq(ct, gy, lamn);
                gemv_seq(at, lam, lamn);
            }
            lam.copy_from_slice(lamn);
        }
    }
}
