//! The chain LMI of Theorem L2 as sparse SDP blocks (one per link: (a), (b) for each
//! iteration, (c)), its unknowns' layout, and the independent check of a solution.

use super::*;

/// The variables of one chain at a fixed K (indices into the unknown vector y).
pub(super) struct Layout {
    pub(super) nx: usize,
    pub(super) nxi: usize,
    pub(super) nc: usize,
    pub(super) nw: usize,
    pub(super) k: usize,
    pub(super) p0: usize,
    pub(super) q0: usize,
    pub(super) nq: usize,
    pub(super) l0: usize,
    pub(super) g0: usize,
    pub(super) t: usize,
}

impl Layout {
    pub(super) fn new(lp: &LureLoop, k: usize) -> Self {
        let (nx, nxi, nc, nw) = (lp.n_x(), lp.n_xi(), lp.n_c(), lp.n_w());
        let ns = nx + nxi;
        let nq = ns * (ns + 1) / 2;
        let p0 = 0;
        let q0 = nx * (nx + 1) / 2;
        let l0 = q0 + (k + 1) * nq;
        let g0 = l0 + k * nc;
        let t = g0 + k + 2;
        Self {
            nx,
            nxi,
            nc,
            nw,
            k,
            p0,
            q0,
            nq,
            l0,
            g0,
            t,
        }
    }
    pub(super) fn unknowns(&self) -> usize {
        self.t + 1
    }
    pub(super) fn sym_from(&self, y: &[f64], start: usize, n: usize) -> Sym {
        let mut s = Sym::zeros(n);
        let mut idx = start;
        for i in 0..n {
            for j in i..n {
                s.a[i * n + j] = y[idx];
                s.a[j * n + i] = y[idx];
                idx += 1;
            }
        }
        s
    }
    pub(super) fn p(&self, y: &[f64]) -> Sym {
        self.sym_from(y, self.p0, self.nx)
    }
    pub(super) fn q(&self, y: &[f64], k: usize) -> Sym {
        self.sym_from(y, self.q0 + k * self.nq, self.nx + self.nxi)
    }
    pub(super) fn lambda<'a>(&self, y: &'a [f64], k: usize) -> &'a [f64] {
        &y[self.l0 + k * self.nc..self.l0 + (k + 1) * self.nc]
    }
    pub(super) fn g(&self, y: &[f64], k: usize) -> f64 {
        y[self.g0 + k]
    }
}

/// Nᵀ Q N and |N|ᵀ|Q||N| (the latter bounds the rounding of the former).
pub(super) fn congruence(n: &Matrix, q: &Sym) -> (Sym, Sym) {
    let d = n.cols;
    let mut out = Sym::zeros(d);
    let mut abs = Sym::zeros(d);
    for i in 0..d {
        for j in 0..d {
            let (mut v, mut s) = (0.0, 0.0);
            for r in 0..n.rows {
                let a = n.at(r, i);
                if a == 0.0 {
                    continue;
                }
                for c in 0..n.rows {
                    let t = a * q.at(r, c) * n.at(c, j);
                    v += t;
                    s += t.abs();
                }
            }
            out.a[i * d + j] = v;
            abs.a[i * d + j] = s;
        }
    }
    (out, abs)
}

/// Stacks row blocks [[I 0 …], …] given as (matrix, column offset) into an r × d matrix.
pub(super) fn stack(rows: usize, cols: usize, parts: &[(usize, usize, &Matrix)]) -> Matrix {
    let mut m = Matrix::zeros(rows, cols);
    for (r0, c0, p) in parts {
        for i in 0..p.rows {
            for j in 0..p.cols {
                m.data[(r0 + i) * cols + c0 + j] += p.at(i, j);
            }
        }
    }
    m
}

pub(super) fn eye(n: usize) -> Matrix {
    let mut m = Matrix::zeros(n, n);
    for i in 0..n {
        m.data[i * n + i] = 1.0;
    }
    m
}

/// The chain's link matrices M (each must be ⪯ 0) and their rounding scales, formed from
/// concrete values of the unknowns by explicit products.
pub(super) struct Links {
    /// (a), (b)_0 … (b)_{K−1}, (c).
    pub(super) mats: Vec<(Sym, f64)>,
}

pub(super) fn links(lp: &LureLoop, lay: &Layout, rho: f64, y: &[f64]) -> Links {
    let (nx, nxi, nc, nw, k) = (lay.nx, lay.nxi, lay.nc, lay.nw, lay.k);
    let mut mats = Vec::with_capacity(k + 2);
    let p = lay.p(y);
    // (a): ζ = (X, w); V₀(X, S₀X + S_w w) − ρ²‖X‖²_P − g₀‖w‖².
    {
        let d = nx + nw;
        let n0 = stack(
            nx + nxi,
            d,
            &[(0, 0, &eye(nx)), (nx, 0, &lp.s0), (nx, nx, &lp.s_w)],
        );
        let (mut m, mut s) = congruence(&n0, &lay.q(y, 0));
        for i in 0..nx {
            for j in 0..nx {
                let t = rho * rho * p.at(i, j);
                m.a[i * d + j] -= t;
                s.a[i * d + j] += t.abs();
            }
        }
        let g = lay.g(y, 0);
        for i in nx..d {
            m.a[i * d + i] -= g;
            s.a[i * d + i] += g.abs();
        }
        mats.push((m, s.abs_sum()));
    }
    // (b)_k: ζ = (X, ξ, Δ, w).
    let d = nx + nxi + nc + nw;
    let (cx, cxi, cd, cw) = (0, nx, nx + nxi, nx + nxi + nc);
    let n1 = stack(
        nx + nxi,
        d,
        &[
            (0, 0, &eye(nx)),
            (nx, cx, &lp.e_x),
            (nx, cxi, &lp.a_xi),
            (nx, cd, &lp.b_delta),
            (nx, cw, &lp.e_w),
        ],
    );
    let n0 = stack(nx + nxi, d, &[(0, 0, &eye(nx)), (nx, cxi, &eye(nxi))]);
    // v = D_X X + C ξ + D_w w as rows over ζ.
    let v = stack(
        nc,
        d,
        &[(0, cx, &lp.d_x), (0, cxi, &lp.c), (0, cw, &lp.d_w)],
    );
    for kk in 0..k {
        let (m1, s1) = congruence(&n1, &lay.q(y, kk + 1));
        let (m0, s0) = congruence(&n0, &lay.q(y, kk));
        let mut m = m1;
        m.axpy(-1.0, &m0);
        let mut s = s1;
        s.axpy(1.0, &s0);
        // + Σ λ_i·2Δ_i(v_i − Δ_i).
        for (i, lam) in lay.lambda(y, kk).iter().enumerate() {
            let di = cd + i;
            for j in 0..d {
                let t = lam * v.at(i, j);
                m.a[di * d + j] += t;
                m.a[j * d + di] += t;
                s.a[di * d + j] += t.abs();
                s.a[j * d + di] += t.abs();
            }
            m.a[di * d + di] -= 2.0 * lam;
            s.a[di * d + di] += 2.0 * lam.abs();
        }
        let g = lay.g(y, kk + 1);
        for i in cw..d {
            m.a[i * d + i] -= g;
            s.a[i * d + i] += g.abs();
        }
        mats.push((m, s.abs_sum()));
    }
    // (c): ζ = (X, ξ, w); ‖𝒜X + 𝒢ξ + ℬw‖²_P − V_K(X, ξ) − g_{K+1}‖w‖².
    {
        let d = nx + nxi + nw;
        let nplus = stack(
            nx,
            d,
            &[
                (0, 0, &lp.a_loop),
                (0, nx, &lp.g_loop),
                (0, nx + nxi, &lp.b_loop),
            ],
        );
        let nk = stack(nx + nxi, d, &[(0, 0, &eye(nx + nxi))]);
        let (m1, s1) = congruence(&nplus, &p);
        let (m0, s0) = congruence(&nk, &lay.q(y, k));
        let mut m = m1;
        m.axpy(-1.0, &m0);
        let mut s = s1;
        s.axpy(1.0, &s0);
        let g = lay.g(y, k + 1);
        for i in nx + nxi..d {
            m.a[i * d + i] -= g;
            s.a[i * d + i] += g.abs();
        }
        mats.push((m, s.abs_sum()));
    }
    Links { mats }
}

/// Upper bound on the entries of each Q_k relative to tr P ≤ 1: keeps the barrier's
/// feasible set bounded (a certificate needing larger storages is not found).
pub(super) const Q_BOUND: f64 = 1e4;

/// The unknowns of each link (for the sparse blocks): P, Q_k, Q_{k+1}, Λ_k, g.
pub(super) fn link_unknowns(lay: &Layout, link: usize) -> Vec<usize> {
    let k = lay.k;
    let qr = |kk: usize| lay.q0 + kk * lay.nq..lay.q0 + (kk + 1) * lay.nq;
    let mut v: Vec<usize> = Vec::new();
    if link == 0 {
        v.extend(lay.p0..lay.q0);
        v.extend(qr(0));
        v.push(lay.g0);
    } else if link <= k {
        let kk = link - 1;
        v.extend(qr(kk));
        v.extend(qr(kk + 1));
        v.extend(lay.l0 + kk * lay.nc..lay.l0 + (kk + 1) * lay.nc);
        v.push(lay.g0 + kk + 1);
    } else {
        v.extend(lay.p0..lay.q0);
        v.extend(qr(k));
        v.push(lay.g0 + k + 1);
    }
    v
}

pub(super) fn neg(s: &Sym) -> Sym {
    Sym {
        n: s.n,
        a: s.a.iter().map(|x| -x).collect(),
    }
}

/// The blocks of the feasibility problem at ρ: −M_link − tI ≻ 0, P − tI ≻ 0, λ − t > 0,
/// Q_BOUND·I − Q_k ≻ 0, 1 − tr P − Σg − Σλ > 0; maximise t.
pub(super) fn blocks(lp: &LureLoop, lay: &Layout, rho: f64) -> Vec<SparseBlock> {
    let d = lay.unknowns();
    let zero = vec![0.0; d];
    let base = links(lp, lay, rho, &zero);
    let mut out = Vec::new();
    let mut probe = zero.clone();
    for (li, (m0, _)) in base.mats.iter().enumerate() {
        let mut terms = Vec::new();
        for i in link_unknowns(lay, li) {
            probe[i] = 1.0;
            let mi = &links_one(lp, lay, rho, &probe, li).0;
            probe[i] = 0.0;
            let mut f = neg(mi);
            f.axpy(1.0, m0);
            if f.a.iter().any(|x| *x != 0.0) {
                terms.push((i, f));
            }
        }
        let mut ft = Sym::identity(m0.n);
        ft.a.iter_mut().for_each(|x| *x = -*x);
        terms.push((lay.t, ft));
        out.push(SparseBlock { f0: neg(m0), terms });
    }
    // P − tI.
    {
        let nx = lay.nx;
        let mut terms = Vec::new();
        let mut idx = lay.p0;
        for i in 0..nx {
            for j in i..nx {
                let mut e = Sym::zeros(nx);
                e.add(i, j, 1.0);
                if i != j {
                    e.add(j, i, 1.0);
                }
                terms.push((idx, e));
                idx += 1;
            }
        }
        terms.push((lay.t, neg(&Sym::identity(nx))));
        out.push(SparseBlock {
            f0: Sym::zeros(nx),
            terms,
        });
    }
    // λ − t.
    for i in lay.l0..lay.g0 {
        out.push(SparseBlock {
            f0: Sym::zeros(1),
            terms: vec![
                (i, Sym::identity(1)),
                (
                    lay.t,
                    Sym {
                        n: 1,
                        a: vec![-1.0],
                    },
                ),
            ],
        });
    }
    // Q_BOUND·I − Q_k.
    let ns = lay.nx + lay.nxi;
    for kk in 0..=lay.k {
        let mut f0 = Sym::identity(ns);
        f0.a.iter_mut().for_each(|x| *x *= Q_BOUND);
        let mut terms = Vec::new();
        let mut idx = lay.q0 + kk * lay.nq;
        for i in 0..ns {
            for j in i..ns {
                let mut e = Sym::zeros(ns);
                e.add(i, j, -1.0);
                if i != j {
                    e.add(j, i, -1.0);
                }
                terms.push((idx, e));
                idx += 1;
            }
        }
        out.push(SparseBlock { f0, terms });
    }
    // 1 − tr P − Σλ − Σg.
    {
        let mut terms = Vec::new();
        let mut idx = lay.p0;
        for i in 0..lay.nx {
            for j in i..lay.nx {
                if i == j {
                    terms.push((
                        idx,
                        Sym {
                            n: 1,
                            a: vec![-1.0],
                        },
                    ));
                }
                idx += 1;
            }
        }
        for i in lay.l0..lay.t {
            terms.push((
                i,
                Sym {
                    n: 1,
                    a: vec![-1.0],
                },
            ));
        }
        out.push(SparseBlock {
            f0: Sym::identity(1),
            terms,
        });
    }
    out
}

/// One link's matrix (for probing the basis).
pub(super) fn links_one(lp: &LureLoop, lay: &Layout, rho: f64, y: &[f64], li: usize) -> (Sym, f64) {
    links(lp, lay, rho, y).mats.swap_remove(li)
}

/// The independent check of a candidate: λ ≥ 0, P ≻ 0 and every link ⪯ 0, by Jacobi
/// eigenvalues of matrices formed afresh, each clearing 10³·dim·ε·scale. Returns the
/// smallest relative margin.
pub(super) fn check(lp: &LureLoop, lay: &Layout, rho: f64, y: &[f64]) -> Option<f64> {
    let tol = |n: usize, scale: f64| 1e3 * n as f64 * f64::EPSILON * scale.max(f64::MIN_POSITIVE);
    if (lay.l0..lay.g0).any(|i| !(y[i] >= 0.0)) {
        return None;
    }
    let p = lay.p(y);
    let ps = p.abs_sum();
    let ev = sym_eigenvalues(&p);
    if !(ev[0] > tol(p.n, ps)) {
        return None;
    }
    let mut margin = f64::INFINITY;
    for (m, scale) in links(lp, lay, rho, y).mats {
        let top = sym_eigenvalues(&m).last().copied().unwrap_or(0.0);
        if !(-top > tol(m.n, scale)) {
            return None;
        }
        margin = margin.min(-top / scale);
    }
    Some(margin)
}

impl SparseBlock {
    /// Σ|entries| of the block at y (a bound on its spectral radius).
    pub(super) fn eval_abs_sum(&self, y: &[f64]) -> f64 {
        let mut g = self.f0.clone();
        for (i, f) in &self.terms {
            g.axpy(y[*i], f);
        }
        g.abs_sum()
    }
}
