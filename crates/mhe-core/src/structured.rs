//! H_c z of an MHE window through the dynamics, without the dense H_c (issue 12): a forward
//! pass for x̂_j and the residuals ŷ_j, an adjoint pass for the gradient,
//! O(m·(n_x² + n_x n_w + n_x n_y + n_w² + n_y²)) per product instead of O(n_z²),
//! n_z = n_x + m n_w.
//!
//! With p = Tz the paper's variables (x̂₀, then per stage ŵ_j and ŷ_j = C x̂_j + F ŵ²_j, where
//! x̂_{j+1} = A x̂_j + E ŵ¹_j) and H_t = blkdiag(2η^m P, 2η^{m−1−j}Q, η^{m−1−j}R), H_c = 2TᵀH_tT
//! (`problem.rs`). So H_c z = 2Tᵀg with g = H_t p, and Tᵀg by the adjoint recursion
//! λ_m = 0, λ_j = Aᵀλ_{j+1} + Cᵀg_{y,j}: the ŵ¹_j-part of Tᵀg is g_{w¹,j} + Eᵀλ_{j+1}, the
//! ŵ²_j-part g_{w²,j} + Fᵀg_{y,j}, the x̂₀-part g_{x₀} + λ₀. The tests compare it with the
//! dense H_c.

use faer::MatRef;
use qp_iter::operator::HessianOperator;

use crate::problem::WindowLayout;

/// Row-major copy of a small dense matrix.
fn rows(m: MatRef<'_, f64>) -> Vec<f64> {
    (0..m.nrows() * m.ncols())
        .map(|k| m[(k / m.ncols(), k % m.ncols())])
        .collect()
}

/// out (+)= M x for a row-major r × c matrix M.
#[inline]
fn mul(m: &[f64], r: usize, c: usize, x: &[f64], out: &mut [f64], add: bool) {
    for i in 0..r {
        let row = &m[i * c..(i + 1) * c];
        let v: f64 = row.iter().zip(x).map(|(a, b)| a * b).sum();
        out[i] = if add { out[i] + v } else { v };
    }
}

/// out += Mᵀ x for a row-major r × c matrix M (x of length r, out of length c).
#[inline]
fn mul_t_add(m: &[f64], r: usize, c: usize, x: &[f64], out: &mut [f64]) {
    for i in 0..r {
        let xi = x[i];
        if xi != 0.0 {
            for (o, a) in out.iter_mut().zip(&m[i * c..(i + 1) * c]) {
                *o += a * xi;
            }
        }
    }
}

/// The structured H_c of one MHE window (see the module docs).
#[derive(Debug, Clone)]
pub struct MheHessian {
    layout: WindowLayout,
    a: Vec<f64>,
    c: Vec<f64>,
    e: Vec<f64>,
    f: Vec<f64>,
    /// 2η^m P.
    p2: Vec<f64>,
    /// 2Q.
    q2: Vec<f64>,
    /// R.
    r: Vec<f64>,
    /// η^{m−1−j} per stage j.
    decay: Vec<f64>,
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
        let eta_m = eta.powi(crate::problem::pow_i32(m));
        let p2 = rows(p).into_iter().map(|v| 2.0 * eta_m * v).collect();
        let q2 = rows(q).into_iter().map(|v| 2.0 * v).collect();
        let decay = (0..m)
            .map(|j| eta.powi(crate::problem::pow_i32(m - 1 - j)))
            .collect();
        Self {
            layout,
            a: rows(a),
            c: rows(c),
            e: rows(e),
            f: rows(f),
            p2,
            q2,
            r: rows(r),
            decay,
        }
    }
}

impl HessianOperator for MheHessian {
    fn n(&self) -> usize {
        self.layout.nz()
    }
    fn work_len(&self) -> usize {
        let d = self.layout.dims;
        // x̂_0..x̂_{m−1}, ŷ_0..ŷ_{m−1}, λ, a spare n_x, g_y.
        self.layout.m * (d.nx + d.ny) + 3 * d.nx + d.ny
    }
    fn apply(&self, z: &[f64], out: &mut [f64], work: &mut [f64]) {
        let d = self.layout.dims;
        let (nx, ny, nw, nw1, nw2, m) = (d.nx, d.ny, d.nw(), d.nw1, d.nw2, self.layout.m);
        let (xs, rest) = work.split_at_mut(m * nx + nx);
        let (ys, rest) = rest.split_at_mut(m * ny);
        let (lam, rest) = rest.split_at_mut(nx);
        let (spare, gy) = rest.split_at_mut(nx);
        let gy = &mut gy[..ny];
        // Forward: x̂_j and ŷ_j.
        xs[..nx].copy_from_slice(&z[..nx]);
        for j in 0..m {
            let w = &z[self.layout.w_offset(j)..][..nw];
            let (done, next) = xs.split_at_mut((j + 1) * nx);
            let xj = &done[j * nx..];
            let yj = &mut ys[j * ny..(j + 1) * ny];
            mul(&self.c, ny, nx, xj, yj, false);
            mul(&self.f, ny, nw2, &w[nw1..], yj, true);
            if j + 1 < m {
                let xn = &mut next[..nx];
                mul(&self.a, nx, nx, xj, xn, false);
                mul(&self.e, nx, nw1, &w[..nw1], xn, true);
            }
        }
        // Adjoint: λ_m = 0; per stage j from the last: the ŵ_j-part, then λ_j.
        lam.fill(0.0);
        for j in (0..m).rev() {
            let o = &mut out[self.layout.w_offset(j)..][..nw];
            let w = &z[self.layout.w_offset(j)..][..nw];
            let dj = self.decay[j];
            mul(&self.q2, nw, nw, w, o, false);
            mul(&self.r, ny, ny, &ys[j * ny..(j + 1) * ny], gy, false);
            for g in gy.iter_mut() {
                *g *= dj;
            }
            for v in o.iter_mut() {
                *v *= dj;
            }
            mul_t_add(&self.e, nx, nw1, lam, &mut o[..nw1]);
            mul_t_add(&self.f, ny, nw2, gy, &mut o[nw1..]);
            // λ_j = Aᵀλ_{j+1} + Cᵀ g_y,j.
            spare.fill(0.0);
            mul_t_add(&self.a, nx, nx, lam, spare);
            mul_t_add(&self.c, ny, nx, gy, spare);
            lam.copy_from_slice(spare);
        }
        mul(&self.p2, nx, nx, &z[..nx], &mut out[..nx], false);
        for (o, l) in out[..nx].iter_mut().zip(lam.iter()) {
            *o += l;
        }
        for v in out[..self.layout.nz()].iter_mut() {
            *v *= 2.0;
        }
    }
}
