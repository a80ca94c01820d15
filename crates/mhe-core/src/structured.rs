//! H_c z of an MHE window through the dynamics, without the dense H_c (issue 12): a forward
//! pass for x̂_j and the residuals ŷ_j, an adjoint pass for the gradient,
//! O(m·(n_x² + n_x n_w + n_x n_y + n_w² + n_y²)) per product instead of O(n_z²),
//! n_z = n_x + m n_w.
//!
//! With p = Tz the paper's variables (x̂₀, then per stage ŵ_j and ŷ_j = C x̂_j + F ŵ²_j, where
//! x̂_{j+1} = A x̂_j + E ŵ¹_j) and H_t = blkdiag(2η^m P, 2η^{m−1−j}Q, η^{m−1−j}R), H_c = 2TᵀH_tT
//! (`problem.rs`). So H_c z = 2Tᵀg with g = H_t p, and Tᵀg by the adjoint recursion
//! λ_m = 0, λ_j = Aᵀλ_{j+1} + Cᵀg_{y,j}: the ŵ¹_j-part of Tᵀg is g_{w¹,j} + Eᵀλ_{j+1}, the
//! ŵ²_j-part g_{w²,j} + Fᵀg_{y,j}, the x̂₀-part g_{x₀} + λ₀.
//!
//! The product runs in two passes over the stages, the factor 2 folded into the weights
//! (4η^m P, 4Q, 2R, so λ below is 2λ): forward, x̂_{j+1} = A x̂_j + E ŵ¹_j and everything of
//! stage j that does not need λ (ŷ_j, g_{y,j}, Cᵀg_{y,j}, 4η^{m−1−j}Qŵ_j + Fᵀg_{y,j});
//! backward, λ_j = Aᵀλ_{j+1} + Cᵀg_{y,j} and the ŵ¹_j-part's Eᵀλ_{j+1}. Only the two
//! recursions are serial; the rest of a stage overlaps them. With the Jacobi scaling z = Dy
//! (`qp_iter::scaled`) D is folded into the same passes ([`HessianOperator::apply_scaled`]).
//!
//! The blocks are stored per column, contiguously, in fixed-size arrays (compile-time n_x,
//! n_y, n_w1, n_w2: exact for the shapes in [`SPECIALISED_SHAPES`], zero-padded to
//! (4, 4, 4, 4), (8, 8, 8, 8), (12, 8, 12, 8) or (16, 16, 16, 16) otherwise), compiled for
//! AVX2 + FMA when the CPU has them (as `qp_iter::kernel` decides); larger plants run the
//! same passes with run-time sizes. The tests compare each with the dense H_c.

use faer::MatRef;
use qp_iter::kernel::{Kernel, KernelPath};
use qp_iter::operator::HessianOperator;

use crate::problem::WindowLayout;

/// Plant shapes (n_x, n_y, n_w1, n_w2) with a fixed-size product: the stand-in (4, 1, 4, 1),
/// two outputs (4, 2, 4, 2), the double integrator (2, 1, 2, 1).
pub const SPECIALISED_SHAPES: [(usize, usize, usize, usize); 3] =
    [(4, 1, 4, 1), (4, 2, 4, 2), (2, 1, 2, 1)];

/// [`HessianOperator::dense_crossover`] of the exact fixed-size products: the smallest n_z
/// from which PG and FISTA through them beat the dense kernel (measured on the stand-in,
/// (4, 2, 4, 2) and (2, 1, 2, 1): `docs/benchmarks.md`, "Structured iteration").
pub const EXACT_CROSSOVER: usize = 64;
/// The same for the zero-padded fixed-size products (measured on (3, 1, 3, 1), (6, 3, 6, 3),
/// (12, 6, 6, 6), (12, 6, 12, 6)).
pub const PADDED_CROSSOVER: usize = 160;
/// The same for the run-time-size product (measured on (17, 2, 17, 2)).
pub const RUN_TIME_CROSSOVER: usize = 400;

/// `s·` the r × c block of `m` at (r0, c0), per column and zero-padded to R × C:
/// `out[k][i] = s·m[r0 + i, c0 + k]` for i < r, k < c.
fn cols<const R: usize, const C: usize>(
    m: MatRef<'_, f64>,
    (r0, c0): (usize, usize),
    (r, c): (usize, usize),
    s: f64,
) -> [[f64; R]; C] {
    std::array::from_fn(|k| {
        std::array::from_fn(|i| {
            if i < r && k < c {
                s * m[(r0 + i, c0 + k)]
            } else {
                0.0
            }
        })
    })
}

/// `s·` the transpose of the r × c block of `m` at (0, 0), per column (row i of the block)
/// and zero-padded to C × R: `out[i][k] = s·m[i, k]` for i < r, k < c.
fn cols_t<const R: usize, const C: usize>(
    m: MatRef<'_, f64>,
    (r, c): (usize, usize),
    s: f64,
) -> [[f64; C]; R] {
    std::array::from_fn(|i| {
        std::array::from_fn(|k| if i < r && k < c { s * m[(i, k)] } else { 0.0 })
    })
}

/// The first `n` entries of `src` (times `d` when `S`), zero-padded to N (unrolled over
/// N: a copy loop of run-time length becomes a `memcpy` call).
#[inline(always)]
fn load<const N: usize, const S: bool>(src: &[f64], d: &[f64], n: usize) -> [f64; N] {
    let (src, d) = (&src[..n], &d[..n]);
    std::array::from_fn(|i| match (src.get(i), d.get(i)) {
        (Some(x), Some(d)) => {
            if S {
                d * x
            } else {
                *x
            }
        }
        _ => 0.0,
    })
}

/// dst[..n] = src[..n] (n ≤ N, unrolled over N).
#[inline(always)]
fn store<const N: usize>(dst: &mut [f64], src: &[f64; N], n: usize) {
    for (i, s) in src.iter().enumerate() {
        if i < n {
            if let Some(d) = dst.get_mut(i) {
                *d = *s;
            }
        }
    }
}

/// a·b + c, fused when `F` (only inside the AVX2 + FMA instantiation).
#[inline(always)]
fn fma<const F: bool>(a: f64, b: f64, c: f64) -> f64 {
    if F { a.mul_add(b, c) } else { a * b + c }
}

/// acc + Σ_k cols[k]·x[k], summed in two partial sums (half the dependency chain).
#[inline(always)]
fn gemv<const R: usize, const C: usize, const F: bool>(
    cols: &[[f64; R]; C],
    x: &[f64; C],
    acc: [f64; R],
) -> [f64; R] {
    let mut s0 = acc;
    let mut s1 = [0.0; R];
    for k in 0..C {
        for i in 0..R {
            if k % 2 == 0 {
                s0[i] = fma::<F>(cols[k][i], x[k], s0[i]);
            } else if k == 1 {
                s1[i] = cols[k][i] * x[k];
            } else {
                s1[i] = fma::<F>(cols[k][i], x[k], s1[i]);
            }
        }
    }
    if C > 1 {
        for i in 0..R {
            s0[i] += s1[i];
        }
    }
    s0
}

/// Σ_k cols[k]·x[k] (C ≥ 1).
#[inline(always)]
fn gemv0<const R: usize, const C: usize, const F: bool>(
    cols: &[[f64; R]; C],
    x: &[f64; C],
) -> [f64; R] {
    let mut s0 = [0.0; R];
    let mut s1 = [0.0; R];
    for k in 0..C {
        for i in 0..R {
            let (s, first) = if k % 2 == 0 {
                (&mut s0[i], k == 0)
            } else {
                (&mut s1[i], k == 1)
            };
            *s = if first {
                cols[k][i] * x[k]
            } else {
                fma::<F>(cols[k][i], x[k], *s)
            };
        }
    }
    if C > 1 {
        for i in 0..R {
            s0[i] += s1[i];
        }
    }
    s0
}

#[inline(always)]
fn scale<const R: usize>(s: f64, v: [f64; R]) -> [f64; R] {
    v.map(|x| s * x)
}

/// The blocks of one stage for compile-time sizes NX ≥ n_x, NY ≥ n_y, NW1 ≥ n_w1,
/// NW2 ≥ n_w2 (zero-padded when `PAD`, exact otherwise), per column, weights folded in.
#[derive(Debug, Clone)]
struct Blocks<const NX: usize, const NY: usize, const NW1: usize, const NW2: usize, const PAD: bool>
{
    /// (n_x, n_w1, n_w2): the actual sizes.
    dims: (usize, usize, usize),
    a: [[f64; NX]; NX],
    at: [[f64; NX]; NX],
    e: [[f64; NX]; NW1],
    et: [[f64; NW1]; NX],
    c: [[f64; NY]; NX],
    ct: [[f64; NX]; NY],
    f: [[f64; NY]; NW2],
    ft: [[f64; NW2]; NY],
    /// 4Q in its (ŵ¹, ŵ²) blocks.
    q11: [[f64; NW1]; NW1],
    q12: [[f64; NW1]; NW2],
    q21: [[f64; NW2]; NW1],
    q22: [[f64; NW2]; NW2],
    /// 2R.
    r: [[f64; NY]; NY],
    /// 4η^m P.
    p: [[f64; NX]; NX],
}

impl<const NX: usize, const NY: usize, const NW1: usize, const NW2: usize, const PAD: bool>
    Blocks<NX, NY, NW1, NW2, PAD>
{
    /// Whether a plant of these sizes fits (exactly, unless `PAD`).
    fn fits(m: &Mats<'_>) -> bool {
        let (nx, ny, nw1, nw2) = (m.a.nrows(), m.c.nrows(), m.e.ncols(), m.f.ncols());
        if PAD {
            nx <= NX && ny <= NY && nw1 <= NW1 && nw2 <= NW2
        } else {
            (nx, ny, nw1, nw2) == (NX, NY, NW1, NW2)
        }
    }

    fn new(m: &Mats<'_>) -> Self {
        let (nx, ny, nw1, nw2) = (m.a.nrows(), m.c.nrows(), m.e.ncols(), m.f.ncols());
        Self {
            dims: (nx, nw1, nw2),
            a: cols(m.a, (0, 0), (nx, nx), 1.0),
            at: cols_t(m.a, (nx, nx), 1.0),
            e: cols(m.e, (0, 0), (nx, nw1), 1.0),
            et: cols_t(m.e, (nx, nw1), 1.0),
            c: cols(m.c, (0, 0), (ny, nx), 1.0),
            ct: cols_t(m.c, (ny, nx), 1.0),
            f: cols(m.f, (0, 0), (ny, nw2), 1.0),
            ft: cols_t(m.f, (ny, nw2), 1.0),
            q11: cols(m.q, (0, 0), (nw1, nw1), 4.0),
            q12: cols(m.q, (0, nw1), (nw1, nw2), 4.0),
            q21: cols(m.q, (nw1, 0), (nw2, nw1), 4.0),
            q22: cols(m.q, (nw1, nw1), (nw2, nw2), 4.0),
            r: cols(m.r, (0, 0), (ny, ny), 2.0),
            p: cols(m.p, (0, 0), (nx, nx), 4.0 * m.eta_m),
        }
    }

    /// out = H_c z (`S`: out = D H_c D z with D = diag(d)); `cg` (m·NX) holds Cᵀg_{y,j}.
    /// Lengths checked by the caller.
    #[inline(always)]
    fn apply<const F: bool, const S: bool>(
        &self,
        decay: &[f64],
        d: &[f64],
        z: &[f64],
        out: &mut [f64],
        cg: &mut [f64],
    ) {
        // Compile-time sizes unless padded.
        let (nx, nw1, nw2) = if PAD { self.dims } else { (NX, NW1, NW2) };
        let (m, nw) = (decay.len(), nw1 + nw2);
        let n = nx + m * nw;
        let (z0, zw) = z[..n].split_at(nx);
        let (o0, ow) = out[..n].split_at_mut(nx);
        let (d0, dw) = d[..n].split_at(nx);
        let cg = &mut cg[..m * NX];
        let x0: [f64; NX] = load::<NX, S>(z0, d0, nx);
        // Forward: x̂_{j+1} = A x̂_j + E ŵ¹_j, and stage j's terms without λ.
        let mut x = x0;
        let stages = zw
            .chunks_exact(nw)
            .zip(dw.chunks_exact(nw))
            .zip(ow.chunks_exact_mut(nw))
            .zip(cg.chunks_exact_mut(NX))
            .zip(decay);
        for ((((w, dj), o), cgj), &eta_j) in stages {
            let w1: [f64; NW1] = load::<NW1, S>(w, dj, nw1);
            let w2: [f64; NW2] = load::<NW2, S>(&w[nw1..], &dj[nw1..], nw2);
            // ŷ_j = C x̂_j + F ŵ²_j, g_y = 2η^{m−1−j}R ŷ_j.
            let y = gemv::<NY, NX, F>(&self.c, &x, gemv0::<NY, NW2, F>(&self.f, &w2));
            let gy = scale(eta_j, gemv0::<NY, NY, F>(&self.r, &y));
            cgj.copy_from_slice(&gemv0::<NX, NY, F>(&self.ct, &gy));
            let (v1, v2) = (scale(eta_j, w1), scale(eta_j, w2));
            let o1 = gemv::<NW1, NW1, F>(&self.q11, &v1, gemv0::<NW1, NW2, F>(&self.q12, &v2));
            let o2 = gemv::<NW2, NW1, F>(
                &self.q21,
                &v1,
                gemv::<NW2, NW2, F>(&self.q22, &v2, gemv0::<NW2, NY, F>(&self.ft, &gy)),
            );
            let (o_1, o_2) = o.split_at_mut(nw1);
            store(o_1, &o1, nw1);
            store(o_2, &o2, nw2);
            x = gemv::<NX, NX, F>(&self.a, &x, gemv0::<NX, NW1, F>(&self.e, &w1));
        }
        // Backward: λ_m = 0, the ŵ¹_j-part gets Eᵀλ_{j+1}, λ_j = Aᵀλ_{j+1} + Cᵀg_{y,j}.
        let mut lam = [0.0; NX];
        let stages = ow
            .chunks_exact_mut(nw)
            .zip(dw.chunks_exact(nw))
            .zip(cg.chunks_exact(NX))
            .rev();
        for ((o, dj), cgj) in stages {
            let o1 = gemv::<NW1, NX, F>(&self.et, &lam, load::<NW1, false>(o, o, nw1));
            store(o, &o1, nw1);
            if S {
                for (v, di) in o.iter_mut().zip(dj) {
                    *v *= di;
                }
            }
            lam = gemv::<NX, NX, F>(&self.at, &lam, std::array::from_fn(|i| cgj[i]));
        }
        let g0 = gemv::<NX, NX, F>(&self.p, &x0, lam);
        for ((o, g), d) in o0.iter_mut().zip(&g0).zip(d0) {
            *o = if S { d * g } else { *g };
        }
    }
}

/// The plant and weight matrices an [`MheHessian`] is built from.
struct Mats<'a> {
    a: MatRef<'a, f64>,
    c: MatRef<'a, f64>,
    e: MatRef<'a, f64>,
    f: MatRef<'a, f64>,
    p: MatRef<'a, f64>,
    q: MatRef<'a, f64>,
    r: MatRef<'a, f64>,
    /// η^m.
    eta_m: f64,
}

/// The blocks for run-time sizes, per column (column k of an r × c block at `k·r`),
/// weights folded in as in [`Blocks`].
#[derive(Debug, Clone)]
struct DynBlocks {
    nx: usize,
    ny: usize,
    nw1: usize,
    nw2: usize,
    a: Vec<f64>,
    at: Vec<f64>,
    e: Vec<f64>,
    et: Vec<f64>,
    c: Vec<f64>,
    ct: Vec<f64>,
    f: Vec<f64>,
    ft: Vec<f64>,
    /// 4Q (n_w × n_w).
    q: Vec<f64>,
    /// 2R.
    r: Vec<f64>,
    /// 4η^m P.
    p: Vec<f64>,
}

/// `s·m` per column (`t`: of mᵀ).
fn dyn_cols(m: MatRef<'_, f64>, s: f64, t: bool) -> Vec<f64> {
    let (r, c) = if t {
        (m.ncols(), m.nrows())
    } else {
        (m.nrows(), m.ncols())
    };
    (0..r * c)
        .map(|k| {
            let (i, j) = (k % r, k / r);
            s * if t { m[(j, i)] } else { m[(i, j)] }
        })
        .collect()
}

/// out += Σ_k cols[k]·x[k] for r-long columns.
#[inline]
fn gemv_dyn(cols: &[f64], r: usize, x: &[f64], out: &mut [f64]) {
    if r == 0 {
        return;
    }
    for (col, &xk) in cols.chunks_exact(r).zip(x) {
        for (o, c) in out.iter_mut().zip(col) {
            *o += c * xk;
        }
    }
}

impl DynBlocks {
    fn new(m: &Mats<'_>) -> Self {
        Self {
            nx: m.a.nrows(),
            ny: m.c.nrows(),
            nw1: m.e.ncols(),
            nw2: m.f.ncols(),
            a: dyn_cols(m.a, 1.0, false),
            at: dyn_cols(m.a, 1.0, true),
            e: dyn_cols(m.e, 1.0, false),
            et: dyn_cols(m.e, 1.0, true),
            c: dyn_cols(m.c, 1.0, false),
            ct: dyn_cols(m.c, 1.0, true),
            f: dyn_cols(m.f, 1.0, false),
            ft: dyn_cols(m.f, 1.0, true),
            q: dyn_cols(m.q, 4.0, false),
            r: dyn_cols(m.r, 2.0, false),
            p: dyn_cols(m.p, 4.0 * m.eta_m, false),
        }
    }

    /// Workspace: Cᵀg_{y,j} per stage, x̂ twice, λ twice, ŷ, g_y, ŵ (scaled) and η-weighted ŵ.
    fn work_len(&self, m: usize) -> usize {
        let nw = self.nw1 + self.nw2;
        m * self.nx + 4 * self.nx + 2 * self.ny + 2 * nw
    }

    /// As [`Blocks::apply`], sizes at run time, temporaries in `work`.
    fn apply(
        &self,
        decay: &[f64],
        d: Option<&[f64]>,
        z: &[f64],
        out: &mut [f64],
        work: &mut [f64],
    ) {
        let (nx, ny, nw1) = (self.nx, self.ny, self.nw1);
        let (m, nw) = (decay.len(), self.nw1 + self.nw2);
        let n = nx + m * nw;
        let (cg, rest) = work.split_at_mut(m * nx);
        let (mut x, rest) = rest.split_at_mut(nx);
        let (mut xn, rest) = rest.split_at_mut(nx);
        let (mut lam, rest) = rest.split_at_mut(nx);
        let (mut lamn, rest) = rest.split_at_mut(nx);
        let (y, rest) = rest.split_at_mut(ny);
        let (gy, rest) = rest.split_at_mut(ny);
        let (wd, rest) = rest.split_at_mut(nw);
        let v = &mut rest[..nw];
        let (z0, zw) = z[..n].split_at(nx);
        let (o0, ow) = out[..n].split_at_mut(nx);
        let scaled = |dst: &mut [f64], src: &[f64], at: usize| match d {
            Some(d) => {
                for ((o, s), di) in dst.iter_mut().zip(src).zip(&d[at..]) {
                    *o = di * s;
                }
            }
            None => dst.copy_from_slice(src),
        };
        scaled(x, z0, 0);
        for (j, (((w, o), cgj), &eta_j)) in zw
            .chunks_exact(nw)
            .zip(ow.chunks_exact_mut(nw))
            .zip(cg.chunks_exact_mut(nx))
            .zip(decay)
            .enumerate()
        {
            scaled(wd, w, nx + j * nw);
            let (w1, w2) = wd.split_at(nw1);
            y.fill(0.0);
            gemv_dyn(&self.f, ny, w2, y);
            gemv_dyn(&self.c, ny, x, y);
            gy.fill(0.0);
            gemv_dyn(&self.r, ny, y, gy);
            for g in gy.iter_mut() {
                *g *= eta_j;
            }
            cgj.fill(0.0);
            gemv_dyn(&self.ct, nx, gy, cgj);
            for (vi, wi) in v.iter_mut().zip(wd.iter()) {
                *vi = eta_j * wi;
            }
            o.fill(0.0);
            gemv_dyn(&self.q, nw, v, o);
            gemv_dyn(&self.ft, self.nw2, gy, &mut o[nw1..]);
            xn.fill(0.0);
            gemv_dyn(&self.e, nx, w1, xn);
            gemv_dyn(&self.a, nx, x, xn);
            std::mem::swap(&mut x, &mut xn);
        }
        lam.fill(0.0);
        for (j, (o, cgj)) in ow
            .chunks_exact_mut(nw)
            .zip(cg.chunks_exact(nx))
            .enumerate()
            .rev()
        {
            gemv_dyn(&self.et, nw1, lam, &mut o[..nw1]);
            if let Some(d) = d {
                for (vi, di) in o.iter_mut().zip(&d[nx + j * nw..]) {
                    *vi *= di;
                }
            }
            lamn.copy_from_slice(cgj);
            gemv_dyn(&self.at, nx, lam, lamn);
            std::mem::swap(&mut lam, &mut lamn);
        }
        scaled(x, z0, 0);
        o0.copy_from_slice(lam);
        gemv_dyn(&self.p, nx, x, o0);
        if let Some(d) = d {
            for (o, di) in o0.iter_mut().zip(d) {
                *o *= di;
            }
        }
    }
}

/// The product's implementation, chosen at construction: exact fixed sizes, padded fixed
/// sizes, or run-time sizes.
#[derive(Debug, Clone)]
enum Product {
    S4141(Box<Blocks<4, 1, 4, 1, false>>),
    S4242(Box<Blocks<4, 2, 4, 2, false>>),
    S2121(Box<Blocks<2, 1, 2, 1, false>>),
    P4(Box<Blocks<4, 4, 4, 4, true>>),
    P8(Box<Blocks<8, 8, 8, 8, true>>),
    P12(Box<Blocks<12, 8, 12, 8, true>>),
    P16(Box<Blocks<16, 16, 16, 16, true>>),
    Dyn(Box<DynBlocks>),
}

impl Product {
    /// The exact fixed size, else the smallest padded one the plant fits, else run-time
    /// sizes.
    fn new(m: &Mats<'_>) -> Self {
        macro_rules! first_fit {
            ($($v:ident $t:ty),*) => {
                $(if <$t>::fits(m) {
                    return Self::$v(Box::new(<$t>::new(m)));
                })*
            };
        }
        first_fit!(
            S4141 Blocks<4, 1, 4, 1, false>,
            S4242 Blocks<4, 2, 4, 2, false>,
            S2121 Blocks<2, 1, 2, 1, false>,
            P4 Blocks<4, 4, 4, 4, true>,
            P8 Blocks<8, 8, 8, 8, true>,
            P12 Blocks<12, 8, 12, 8, true>,
            P16 Blocks<16, 16, 16, 16, true>
        );
        Self::Dyn(Box::new(DynBlocks::new(m)))
    }

    /// Rows of Cᵀg_y stored per stage (the padded n_x).
    fn cg_rows(&self) -> usize {
        match self {
            Self::S4141(_) | Self::S4242(_) | Self::P4(_) => 4,
            Self::S2121(_) => 2,
            Self::P8(_) => 8,
            Self::P12(_) => 12,
            Self::P16(_) => 16,
            Self::Dyn(b) => b.nx,
        }
    }
}

/// The structured H_c of one MHE window (see the module docs).
#[derive(Debug, Clone)]
pub struct MheHessian {
    layout: WindowLayout,
    product: Product,
    /// The run-time-size product (for [`MheHessian::generic`]).
    dyn_blocks: DynBlocks,
    /// η^{m−1−j} per stage j.
    decay: Vec<f64>,
    /// Fixed-size products compiled for AVX2 + FMA (a validated [`KernelPath`]).
    fma: bool,
}

impl MheHessian {
    /// The operator of the window with this layout, plant matrices and weights.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        layout: WindowLayout,
        a: MatRef<'_, f64>,
        c: MatRef<'_, f64>,
        e: MatRef<'_, f64>,
        f: MatRef<'_, f64>,
        eta: f64,
        p: MatRef<'_, f64>,
        q: MatRef<'_, f64>,
        r: MatRef<'_, f64>,
    ) -> Self {
        let m = layout.m;
        let mats = Mats {
            a,
            c,
            e,
            f,
            p,
            q,
            r,
            eta_m: eta.powi(crate::problem::pow_i32(m)),
        };
        let product = Product::new(&mats);
        let decay = (0..m)
            .map(|j| eta.powi(crate::problem::pow_i32(m - 1 - j)))
            .collect();
        Self {
            layout,
            product,
            dyn_blocks: DynBlocks::new(&mats),
            decay,
            fma: qp_iter::kernel::get_global_kernel().path() == KernelPath::Avx2Fma,
        }
    }

    /// The same operator on the run-time-size product (for tests and benchmarks).
    pub fn generic(mut self) -> Self {
        self.product = Product::Dyn(Box::new(self.dyn_blocks.clone()));
        self
    }

    /// The same operator with the fixed-size product compiled for `kernel`'s path (the
    /// portable one without FMA, or AVX2 + FMA).
    pub fn with_kernel(mut self, kernel: Kernel) -> Self {
        self.fma = kernel.path() == KernelPath::Avx2Fma;
        self
    }

    /// Whether the product runs on fixed-size blocks (exact for [`SPECIALISED_SHAPES`],
    /// zero-padded up to n_x, n_w1 ≤ 16 and n_y, n_w2 ≤ 16).
    pub fn is_specialised(&self) -> bool {
        !matches!(self.product, Product::Dyn(_))
    }

    fn run(&self, d: Option<&[f64]>, z: &[f64], out: &mut [f64], work: &mut [f64]) {
        let n = self.layout.nz();
        assert!(
            z.len() >= n
                && out.len() >= n
                && work.len() >= self.work_len()
                && d.is_none_or(|d| d.len() >= n),
            "MheHessian: vectors shorter than n = {n} or a workspace shorter than work_len"
        );
        let decay = &self.decay;
        macro_rules! fixed {
            ($b:expr) => {{
                let b = &**$b;
                match (self.fma, d) {
                    // SAFETY: `fma` is true only for a `Kernel` whose path is AVX2 + FMA,
                    // which `qp_iter::kernel` selects only when the running CPU has both.
                    (true, Some(d)) => unsafe { avx2::<_, true>(b, decay, d, z, out, work) },
                    // SAFETY: as above.
                    (true, None) => unsafe { avx2::<_, false>(b, decay, z, z, out, work) },
                    (false, Some(d)) => b.apply::<false, true>(decay, d, z, out, work),
                    (false, None) => b.apply::<false, false>(decay, z, z, out, work),
                }
            }};
        }
        match &self.product {
            Product::S4141(b) => fixed!(b),
            Product::S4242(b) => fixed!(b),
            Product::S2121(b) => fixed!(b),
            Product::P4(b) => fixed!(b),
            Product::P8(b) => fixed!(b),
            Product::P12(b) => fixed!(b),
            Product::P16(b) => fixed!(b),
            Product::Dyn(b) => b.apply(decay, d, z, out, work),
        }
    }
}

/// A fixed-size product whose blocks can run under AVX2 + FMA.
trait FixedProduct {
    fn apply_fma<const S: bool>(
        &self,
        decay: &[f64],
        d: &[f64],
        z: &[f64],
        out: &mut [f64],
        cg: &mut [f64],
    );
}

impl<const NX: usize, const NY: usize, const NW1: usize, const NW2: usize, const PAD: bool>
    FixedProduct for Blocks<NX, NY, NW1, NW2, PAD>
{
    #[inline(always)]
    fn apply_fma<const S: bool>(
        &self,
        decay: &[f64],
        d: &[f64],
        z: &[f64],
        out: &mut [f64],
        cg: &mut [f64],
    ) {
        self.apply::<true, S>(decay, d, z, out, cg);
    }
}

/// [`Blocks::apply`] with fused multiply-adds, compiled for AVX2 + FMA.
///
/// # Safety
/// The running CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn avx2<B: FixedProduct, const S: bool>(
    b: &B,
    decay: &[f64],
    d: &[f64],
    z: &[f64],
    out: &mut [f64],
    cg: &mut [f64],
) {
    b.apply_fma::<S>(decay, d, z, out, cg);
}

/// Never called off x86-64 (`fma` is false there): the portable product.
///
/// # Safety
/// None needed; `unsafe` only to match the x86-64 signature.
#[cfg(not(target_arch = "x86_64"))]
unsafe fn avx2<B: FixedProduct, const S: bool>(
    b: &B,
    decay: &[f64],
    d: &[f64],
    z: &[f64],
    out: &mut [f64],
    cg: &mut [f64],
) {
    b.apply_fma::<S>(decay, d, z, out, cg);
}

impl HessianOperator for MheHessian {
    fn n(&self) -> usize {
        self.layout.nz()
    }
    fn work_len(&self) -> usize {
        let m = self.layout.m;
        self.dyn_blocks.work_len(m).max(m * self.product.cg_rows())
    }
    fn apply(&self, z: &[f64], out: &mut [f64], work: &mut [f64]) {
        self.run(None, z, out, work);
    }
    fn dense_crossover(&self) -> usize {
        match self.product {
            Product::S4141(_) | Product::S4242(_) | Product::S2121(_) => EXACT_CROSSOVER,
            Product::Dyn(_) => RUN_TIME_CROSSOVER,
            _ => PADDED_CROSSOVER,
        }
    }
    fn scaled_work_len(&self) -> usize {
        self.work_len()
    }
    fn apply_scaled(&self, d: &[f64], y: &[f64], out: &mut [f64], work: &mut [f64]) {
        self.run(Some(d), y, out, work);
    }
    fn on_kernel(&self, kernel: Kernel) -> Option<std::sync::Arc<dyn HessianOperator>> {
        Some(std::sync::Arc::new(self.clone().with_kernel(kernel)))
    }
}
