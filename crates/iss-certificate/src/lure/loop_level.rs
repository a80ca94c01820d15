//! The loop level: Theorem L2 of docs/theory.md ("One certificate for the whole loop",
//! §3) — global ISS of a sample-to-sample loop whose inner iterations pass through
//! slope-[0, 1] clamps, from a chain of quadratic storages V₀ … V_K, one LMI per link.
//!
//! The loop ([`LureLoop`]) is given by its matrices: with X the sample-level state, w the
//! disturbance, ξ the iteration state and Δ the clamp outputs,
//!
//! ```text
//! ξ⁰ = S₀X + S_w w,
//! ξᵏ⁺¹ = A_ξ ξᵏ + B_Δ Δᵏ + E_X X + E_w w,   Δᵏ_i = s·vᵏ_i with s ∈ [0, 1],
//! vᵏ = C ξᵏ + D_X X + D_w w,
//! X⁺ = 𝒜X + 𝒢ξᴷ + ℬw.
//! ```
//!
//! A box projection with 0 in the box is such a channel: Π(v)_i = s_i v_i, s_i ∈ [0, 1]
//! (docs/theory.md §1), whatever the bounds. For a fixed K and ρ the chain (a)–(c) is an LMI
//! in (P, Q₀ … Q_K, Λ₀ … Λ_{K−1}, g₀ … g_{K+1}); it is solved by the barrier method of
//! `lure::sdp` on blocks sparse in the unknowns, and a solution is accepted only after the
//! independent check (Jacobi eigenvalues of every link's matrix, formed afresh, clear a
//! rounding allowance). ρ is bisected. The unknowns grow as K·(n_X + n_ξ)²/2: the dense
//! Newton system limits the size ([`LoopOptions::max_unknowns`]), and the lifted loops of
//! the shipped scenarios (n_X ≥ 39) are above it today.

use super::sdp::{
    SparseBlock, Sym, cholesky, logdet_inverse, maximise_last_sparse, sym_eigenvalues,
};
#[cfg(feature = "serde")]
use serde::Serialize;

/// A dense row-major matrix (rows × cols).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
pub struct Matrix {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Row-major entries.
    pub data: Vec<f64>,
}

impl Matrix {
    /// A matrix from its row-major entries.
    pub fn new(rows: usize, cols: usize, data: Vec<f64>) -> Self {
        Self { rows, cols, data }
    }
    /// The zero matrix.
    pub fn zeros(rows: usize, cols: usize) -> Self {
        Self::new(rows, cols, vec![0.0; rows * cols])
    }
    /// Entry (i, j).
    #[inline]
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.cols + j]
    }
    /// y = self · x.
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        (0..self.rows)
            .map(|i| (0..self.cols).map(|j| self.at(i, j) * x[j]).sum())
            .collect()
    }
    fn mul(&self, o: &Matrix) -> Matrix {
        let mut c = Matrix::zeros(self.rows, o.cols);
        for i in 0..self.rows {
            for k in 0..self.cols {
                let a = self.at(i, k);
                if a != 0.0 {
                    for j in 0..o.cols {
                        c.data[i * o.cols + j] += a * o.at(k, j);
                    }
                }
            }
        }
        c
    }
    fn add(&self, o: &Matrix) -> Matrix {
        let data = self.data.iter().zip(&o.data).map(|(a, b)| a + b).collect();
        Matrix::new(self.rows, self.cols, data)
    }
}

/// The loop: a linear sample map in feedback with slope-[0, 1] channels inside its K inner
/// iterations (module docs for the equations; every name is the matrix of the same name).
#[derive(Debug, Clone, PartialEq)]
pub struct LureLoop {
    /// S₀: n_ξ × n_X, the start of the iteration from the loop state (warm start).
    pub s0: Matrix,
    /// S_w: n_ξ × n_w.
    pub s_w: Matrix,
    /// A_ξ: n_ξ × n_ξ.
    pub a_xi: Matrix,
    /// B_Δ: n_ξ × n_c.
    pub b_delta: Matrix,
    /// E_X: n_ξ × n_X (the data θ = ΘX entering each iteration).
    pub e_x: Matrix,
    /// E_w: n_ξ × n_w.
    pub e_w: Matrix,
    /// C: n_c × n_ξ (the clamps' arguments).
    pub c: Matrix,
    /// D_X: n_c × n_X.
    pub d_x: Matrix,
    /// D_w: n_c × n_w.
    pub d_w: Matrix,
    /// 𝒜: n_X × n_X.
    pub a_loop: Matrix,
    /// 𝒢: n_X × n_ξ (the last iterate's way into the loop).
    pub g_loop: Matrix,
    /// ℬ: n_X × n_w.
    pub b_loop: Matrix,
}

/// Why no loop certificate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LoopError {
    /// A matrix has the wrong shape or a non-finite entry.
    #[error(
        "loop matrix `{name}` is {rows} × {cols} (expected {want_rows} × {want_cols}) or not finite"
    )]
    Shape {
        /// The field of [`LureLoop`].
        name: &'static str,
        /// Its rows.
        rows: usize,
        /// Its columns.
        cols: usize,
        /// Expected rows.
        want_rows: usize,
        /// Expected columns.
        want_cols: usize,
    },
    /// The chain's LMI has more unknowns than the dense barrier method handles.
    #[error(
        "the loop LMI at K = {k} has {unknowns} unknowns (n_X = {n_x}, n_ξ = {n_xi}), above the \
         limit {limit} of the dense solver; reduce K or the window (mhe.horizon)"
    )]
    SizeLimit {
        /// K.
        k: usize,
        /// Unknowns of the LMI.
        unknowns: usize,
        /// dim X.
        n_x: usize,
        /// dim ξ.
        n_xi: usize,
        /// The limit.
        limit: usize,
    },
    /// No ρ < 1 passed the solver and the independent check.
    #[error(
        "no loop certificate at K = {k}: the chain LMI is infeasible for ρ = {rho_max} (or its \
         solution failed the independent check)"
    )]
    NotCertified {
        /// K.
        k: usize,
        /// The largest ρ tried.
        rho_max: f64,
    },
}

/// Options of the loop certificate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopOptions {
    /// Bisection stops when the bracket of ρ is narrower.
    pub rho_tol: f64,
    /// The largest ρ tried (< 1).
    pub rho_max: f64,
    /// Size limit of the LMI (unknowns).
    pub max_unknowns: usize,
}

impl Default for LoopOptions {
    fn default() -> Self {
        Self {
            rho_tol: 1e-3,
            rho_max: 0.9999,
            max_unknowns: 1200,
        }
    }
}

/// A checked loop certificate: ‖X_{t+1}‖²_P ≤ ρ²‖X_t‖²_P + γ²‖w_t‖² along every run with K
/// inner iterations, whatever the clamps do, hence
/// ‖X_t‖²_P ≤ ρ^{2t}‖X_0‖²_P + γ²/(1 − ρ²)·w̄².
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct LoopCertificate {
    /// K.
    pub k: usize,
    /// ρ < 1.
    pub rho: f64,
    /// γ ≥ 0.
    pub gamma: f64,
    /// P ≻ 0 (row-major n_X × n_X).
    pub p: Vec<f64>,
    /// The smallest relative margin −λ_max/scale over the chain's links in the check.
    pub margin: f64,
    /// lim sup ‖X‖ ≤ `gain_x`·w̄: γ/√(λ_min(P)(1 − ρ²)).
    pub gain_x: f64,
}

impl LoopCertificate {
    /// ‖X‖²_P.
    pub fn storage(&self, x: &[f64]) -> f64 {
        let n = x.len();
        (0..n)
            .map(|i| (0..n).map(|j| x[i] * self.p[i * n + j] * x[j]).sum::<f64>())
            .sum()
    }

    /// The certified asymptotic gain of a readout R X (e.g. the estimation error or x):
    /// lim sup ‖RX‖ ≤ γ·√(λ_max(R P⁻¹ Rᵀ)/(1 − ρ²))·w̄. None if P is not numerically
    /// invertible.
    pub fn readout_gain(&self, r: &Matrix) -> Option<f64> {
        let n = r.cols;
        let l = cholesky(&Sym {
            n,
            a: self.p.clone(),
        })?;
        let (_, inv) = logdet_inverse(&l, n);
        let mut m = Sym::zeros(r.rows);
        for i in 0..r.rows {
            for j in 0..r.rows {
                let mut v = 0.0;
                for a in 0..n {
                    for b in 0..n {
                        v += r.at(i, a) * inv.at(a, b) * r.at(j, b);
                    }
                }
                m.add(i, j, v);
            }
        }
        let top = sym_eigenvalues(&m).last().copied().unwrap_or(0.0).max(0.0);
        Some(self.gamma * (top / (1.0 - self.rho * self.rho)).sqrt() * (1.0 + 1e-9))
    }
}

impl LureLoop {
    /// dim X.
    pub fn n_x(&self) -> usize {
        self.a_loop.rows
    }
    /// dim ξ.
    pub fn n_xi(&self) -> usize {
        self.a_xi.rows
    }
    /// Number of clamp channels per iteration.
    pub fn n_c(&self) -> usize {
        self.c.rows
    }
    /// dim w.
    pub fn n_w(&self) -> usize {
        self.b_loop.cols
    }

    /// Checks every shape against n_X = rows of 𝒜, n_ξ = rows of A_ξ, n_c = rows of C and
    /// n_w = columns of ℬ.
    pub fn validate(&self) -> Result<(), LoopError> {
        let (nx, nxi, nc, nw) = (self.n_x(), self.n_xi(), self.n_c(), self.n_w());
        let list: [(&'static str, &Matrix, usize, usize); 12] = [
            ("s0", &self.s0, nxi, nx),
            ("s_w", &self.s_w, nxi, nw),
            ("a_xi", &self.a_xi, nxi, nxi),
            ("b_delta", &self.b_delta, nxi, nc),
            ("e_x", &self.e_x, nxi, nx),
            ("e_w", &self.e_w, nxi, nw),
            ("c", &self.c, nc, nxi),
            ("d_x", &self.d_x, nc, nx),
            ("d_w", &self.d_w, nc, nw),
            ("a_loop", &self.a_loop, nx, nx),
            ("g_loop", &self.g_loop, nx, nxi),
            ("b_loop", &self.b_loop, nx, nw),
        ];
        for (name, m, r, c) in list {
            let ok = m.rows == r
                && m.cols == c
                && m.data.len() == r * c
                && m.data.iter().all(|v| v.is_finite());
            if !ok {
                return Err(LoopError::Shape {
                    name,
                    rows: m.rows,
                    cols: m.cols,
                    want_rows: r,
                    want_cols: c,
                });
            }
        }
        Ok(())
    }

    /// The loop with every clamp replaced by the identity (Δ = v): the linear loop of
    /// `linear`, whose lifted matrix has spectral radius ρ_lin(K). Its certificate says
    /// nothing once a clamp is active — the tests show sampled clamps refuting it.
    pub fn unclamped(&self) -> LureLoop {
        let (nx, nxi, nw) = (self.n_x(), self.n_xi(), self.n_w());
        LureLoop {
            a_xi: self.a_xi.add(&self.b_delta.mul(&self.c)),
            e_x: self.e_x.add(&self.b_delta.mul(&self.d_x)),
            e_w: self.e_w.add(&self.b_delta.mul(&self.d_w)),
            b_delta: Matrix::zeros(nxi, 0),
            c: Matrix::zeros(0, nxi),
            d_x: Matrix::zeros(0, nx),
            d_w: Matrix::zeros(0, nw),
            ..self.clone()
        }
    }

    /// The lifted sample matrix with every clamp the identity and w = 0 (for tests and
    /// the linear limit): X⁺ = 𝔸(K)X.
    pub fn lifted_linear(&self, k: usize) -> Matrix {
        let u = self.unclamped();
        // ξᴷ = T X with T⁰ = S₀, Tᵏ⁺¹ = A_ξTᵏ + E_X.
        let mut t = u.s0.clone();
        for _ in 0..k {
            t = u.a_xi.mul(&t).add(&u.e_x);
        }
        u.a_loop.add(&u.g_loop.mul(&t))
    }
}

// The chain of links as blocks of the SDP, and the independent check: loop_level/chain.rs.
mod chain;
use chain::{Layout, blocks, check};

fn sizes(lp: &LureLoop, k: usize, opts: &LoopOptions) -> Result<Layout, LoopError> {
    lp.validate()?;
    let lay = Layout::new(lp, k);
    let unknowns = lay.unknowns();
    if unknowns > opts.max_unknowns {
        return Err(LoopError::SizeLimit {
            k,
            unknowns,
            n_x: lp.n_x(),
            n_xi: lp.n_xi(),
            limit: opts.max_unknowns,
        });
    }
    Ok(lay)
}

/// The number of unknowns of the chain LMI at K (for size estimates).
pub fn loop_unknowns(n_x: usize, n_xi: usize, n_c: usize, k: usize) -> usize {
    let ns = n_x + n_xi;
    n_x * (n_x + 1) / 2 + (k + 1) * ns * (ns + 1) / 2 + k * n_c + k + 3
}

/// The chain LMI at a fixed ρ: a checked certificate or None.
pub fn certify_loop_at(
    lp: &LureLoop,
    k: usize,
    rho: f64,
    opts: &LoopOptions,
) -> Result<Option<LoopCertificate>, LoopError> {
    let lay = sizes(lp, k, opts)?;
    Ok(solve_at(lp, &lay, rho))
}

fn solve_at(lp: &LureLoop, lay: &Layout, rho: f64) -> Option<LoopCertificate> {
    let d = lay.unknowns();
    let bl = blocks(lp, lay, rho);
    // Strictly feasible start: small P, g, λ; Q = 0; t far below every block's spectrum.
    let mut y = vec![0.0; d];
    let nx = lay.nx;
    let mut idx = lay.p0;
    for i in 0..nx {
        for j in i..nx {
            if i == j {
                y[idx] = 0.2 / nx as f64;
            }
            idx += 1;
        }
    }
    let extra = (lay.t - lay.l0).max(1) as f64;
    for v in &mut y[lay.l0..lay.t] {
        *v = 0.2 / extra;
    }
    let mut worst: f64 = 1.0;
    for b in &bl {
        worst = worst.max(b.eval_abs_sum(&y));
    }
    y[lay.t] = -(worst + 1.0);
    let good = |y: &[f64]| y[lay.t] > 0.0 && check(lp, lay, rho, y).is_some();
    let y = maximise_last_sparse(&bl, y, 1e-9, good)?;
    let margin = check(lp, lay, rho, &y)?;
    let p = lay.p(&y);
    let gsum: f64 = (0..lay.k + 2).map(|i| lay.g(&y, i)).sum();
    let gamma = gsum.max(0.0).sqrt();
    let lmin = sym_eigenvalues(&p)[0];
    let gain_x = gamma / (lmin * (1.0 - rho * rho)).sqrt() * (1.0 + 1e-9);
    Some(LoopCertificate {
        k: lay.k,
        rho,
        gamma,
        p: p.a,
        margin,
        gain_x,
    })
}

/// The loop certificate at K with the smallest ρ found by bisection (to `opts.rho_tol`).
pub fn certify_loop(
    lp: &LureLoop,
    k: usize,
    opts: &LoopOptions,
) -> Result<LoopCertificate, LoopError> {
    let lay = sizes(lp, k, opts)?;
    let mut best = solve_at(lp, &lay, opts.rho_max).ok_or(LoopError::NotCertified {
        k,
        rho_max: opts.rho_max,
    })?;
    let (mut lo, mut hi) = (0.0, opts.rho_max);
    while hi - lo > opts.rho_tol {
        let mid = 0.5 * (lo + hi);
        match solve_at(lp, &lay, mid) {
            Some(c) => {
                hi = mid;
                best = c;
            }
            None => lo = mid,
        }
    }
    Ok(best)
}

/// K_loop: the smallest K ≤ `k_max` with a loop certificate (a scan from K = 0; ρ at the
/// feasibility end only, then bisected at the K found). Err(SizeLimit) if the LMI outgrows
/// the solver before a certificate is found; Ok(None) if no K ≤ `k_max` is certified.
pub fn k_loop(
    lp: &LureLoop,
    k_max: usize,
    opts: &LoopOptions,
) -> Result<Option<LoopCertificate>, LoopError> {
    for k in 0..=k_max {
        let lay = sizes(lp, k, opts)?;
        if solve_at(lp, &lay, opts.rho_max).is_some() {
            return certify_loop(lp, k, opts).map(Some);
        }
    }
    Ok(None)
}
