//! A small primal log-barrier interior-point solver for LMIs, and the independent check of
//! its answer.
//!
//! After the Kronecker reduction of [`super::inner`] the LMIs of this module have at most
//! six unknowns and blocks of at most 5 × 5, so a dense barrier method on plain `Vec<f64>`
//! is exact enough, fast, and pure Rust (Clarabel's PSD cone would pull in BLAS/LAPACK).
//! Its answer is never trusted as is: [`sym_eigenvalues`] (cyclic Jacobi or faer's
//! symmetric eigensolver, no Cholesky, no shared code with the solver) recomputes the
//! spectrum of every matrix a caller certifies.

/// A dense symmetric matrix stored row-major, n × n.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Sym {
    pub n: usize,
    pub a: Vec<f64>,
}

impl Sym {
    pub fn zeros(n: usize) -> Self {
        Self {
            n,
            a: vec![0.0; n * n],
        }
    }
    pub fn identity(n: usize) -> Self {
        let mut s = Self::zeros(n);
        for i in 0..n {
            s.a[i * n + i] = 1.0;
        }
        s
    }
    #[inline]
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.a[i * self.n + j]
    }
    #[inline]
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        self.a[i * self.n + j] += v;
    }
    /// self += s·other.
    pub fn axpy(&mut self, s: f64, other: &Sym) {
        for (x, y) in self.a.iter_mut().zip(&other.a) {
            *x += s * y;
        }
    }
    /// Σ|a_ij|: the scale rounding errors are measured against.
    pub fn abs_sum(&self) -> f64 {
        self.a.iter().map(|x| x.abs()).sum()
    }
}

/// G(y) = F₀ + Σᵢ yᵢFᵢ, required positive definite.
#[derive(Debug, Clone)]
pub(crate) struct AffineBlock {
    pub f0: Sym,
    pub fi: Vec<Sym>,
}

impl AffineBlock {
    fn eval(&self, y: &[f64]) -> Sym {
        let mut g = self.f0.clone();
        for (yi, fi) in y.iter().zip(&self.fi) {
            if *yi != 0.0 {
                g.axpy(*yi, fi);
            }
        }
        g
    }
}

/// Lower Cholesky factor of a symmetric matrix, None unless positive definite.
pub(crate) fn cholesky(s: &Sym) -> Option<Vec<f64>> {
    let n = s.n;
    let mut l = vec![0.0; n * n];
    for j in 0..n {
        let mut d = s.at(j, j);
        for k in 0..j {
            d -= l[j * n + k] * l[j * n + k];
        }
        if !(d > 0.0) || !d.is_finite() {
            return None;
        }
        let d = d.sqrt();
        l[j * n + j] = d;
        for i in j + 1..n {
            let mut v = s.at(i, j);
            for k in 0..j {
                v -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = v / d;
        }
    }
    Some(l)
}

/// log det and the inverse from a Cholesky factor.
pub(crate) fn logdet_inverse(l: &[f64], n: usize) -> (f64, Sym) {
    let logdet = 2.0 * (0..n).map(|i| l[i * n + i].ln()).sum::<f64>();
    let mut inv = Sym::zeros(n);
    let mut col = vec![0.0; n];
    for c in 0..n {
        // Solve L Lᵀ x = e_c.
        for i in 0..n {
            let mut v = if i == c { 1.0 } else { 0.0 };
            for k in 0..i {
                v -= l[i * n + k] * col[k];
            }
            col[i] = v / l[i * n + i];
        }
        for i in (0..n).rev() {
            let mut v = col[i];
            for k in i + 1..n {
                v -= l[k * n + i] * col[k];
            }
            col[i] = v / l[i * n + i];
        }
        for i in 0..n {
            inv.a[i * n + c] = col[i];
        }
    }
    (logdet, inv)
}

fn matmul(a: &Sym, b: &Sym) -> Vec<f64> {
    let n = a.n;
    let mut c = vec![0.0; n * n];
    for i in 0..n {
        for k in 0..n {
            let aik = a.a[i * n + k];
            if aik != 0.0 {
                for j in 0..n {
                    c[i * n + j] += aik * b.a[k * n + j];
                }
            }
        }
    }
    c
}

/// The barrier value −τ·y_last − Σ log det G_b(y), None outside the interior.
fn barrier(blocks: &[AffineBlock], y: &[f64], tau: f64) -> Option<f64> {
    let mut v = -tau * y[y.len() - 1];
    for b in blocks {
        let g = b.eval(y);
        let l = cholesky(&g)?;
        v -= 2.0 * (0..g.n).map(|i| l[i * g.n + i].ln()).sum::<f64>();
    }
    Some(v)
}

/// Maximises the last unknown subject to every block positive definite, from a strictly
/// feasible `y`. Returns the final point (strictly feasible; within `gap` of the optimum
/// when it converged, or the first centred point `good` accepts) or None when `y` is not
/// strictly feasible.
pub(crate) fn maximise_last(
    blocks: &[AffineBlock],
    mut y: Vec<f64>,
    gap: f64,
    good: impl Fn(&[f64]) -> bool,
) -> Option<Vec<f64>> {
    let d = y.len();
    let nu: f64 = blocks.iter().map(|b| b.f0.n as f64).sum();
    barrier(blocks, &y, 0.0)?;
    let mut tau = 1.0;
    for _outer in 0..60 {
        for _newton in 0..100 {
            let mut grad = vec![0.0; d];
            let mut hess = vec![0.0; d * d];
            grad[d - 1] -= tau;
            for b in blocks {
                let g = b.eval(&y);
                let l = cholesky(&g)?;
                let (_, inv) = logdet_inverse(&l, g.n);
                let w: Vec<Vec<f64>> = b.fi.iter().map(|f| matmul(&inv, f)).collect();
                let n = g.n;
                for i in 0..d {
                    grad[i] -= (0..n).map(|r| w[i][r * n + r]).sum::<f64>();
                    for k in 0..=i {
                        // tr(W_i W_k)
                        let mut s = 0.0;
                        for r in 0..n {
                            for c in 0..n {
                                s += w[i][r * n + c] * w[k][c * n + r];
                            }
                        }
                        hess[i * d + k] += s;
                        if k != i {
                            hess[k * d + i] += s;
                        }
                    }
                }
            }
            // Newton step: H Δ = −g (a tiny ridge if H is singular in floating point).
            let mut hs = Sym { n: d, a: hess };
            let l = match cholesky(&hs) {
                Some(l) => l,
                None => {
                    let ridge = 1e-12 * (1.0 + hs.abs_sum());
                    for i in 0..d {
                        hs.add(i, i, ridge);
                    }
                    cholesky(&hs)?
                }
            };
            let (_, hinv) = logdet_inverse(&l, d);
            let step: Vec<f64> = (0..d)
                .map(|i| -(0..d).map(|k| hinv.at(i, k) * grad[k]).sum::<f64>())
                .collect();
            let decrement: f64 = -step.iter().zip(&grad).map(|(s, g)| s * g).sum::<f64>();
            if !(decrement > 1e-14) {
                break;
            }
            let f0 = barrier(blocks, &y, tau)?;
            let mut s = 1.0;
            let mut moved = false;
            for _ in 0..60 {
                let trial: Vec<f64> = y.iter().zip(&step).map(|(a, b)| a + s * b).collect();
                if let Some(f) = barrier(blocks, &trial, tau) {
                    if f <= f0 - 0.25 * s * decrement {
                        y = trial;
                        moved = true;
                        break;
                    }
                }
                s *= 0.5;
            }
            if !moved || decrement < 1e-10 {
                break;
            }
        }
        if nu / tau < gap || good(&y) {
            break;
        }
        tau *= 8.0;
    }
    Some(y)
}

/// G(y) = F₀ + Σ_{(i, Fᵢ) ∈ terms} yᵢFᵢ, required positive definite: a block that involves
/// few of the unknowns. The loop level's links share only neighbouring storages, so its
/// blocks are sparse in the unknowns and the Hessian is assembled from the terms present.
#[derive(Debug, Clone)]
pub(crate) struct SparseBlock {
    pub f0: Sym,
    pub terms: Vec<(usize, Sym)>,
}

impl SparseBlock {
    fn eval(&self, y: &[f64]) -> Sym {
        let mut g = self.f0.clone();
        for (i, f) in &self.terms {
            if y[*i] != 0.0 {
                g.axpy(y[*i], f);
            }
        }
        g
    }
}

fn barrier_sparse(blocks: &[SparseBlock], y: &[f64], tau: f64) -> Option<f64> {
    let mut v = -tau * y[y.len() - 1];
    for b in blocks {
        let g = b.eval(y);
        let l = cholesky(&g)?;
        v -= 2.0 * (0..g.n).map(|i| l[i * g.n + i].ln()).sum::<f64>();
    }
    Some(v)
}

/// [`maximise_last`] on blocks given by their nonzero terms: the same path-following
/// barrier method, with the gradient and Hessian accumulated over each block's own unknowns.
pub(crate) fn maximise_last_sparse(
    blocks: &[SparseBlock],
    mut y: Vec<f64>,
    gap: f64,
    good: impl Fn(&[f64]) -> bool,
) -> Option<Vec<f64>> {
    let d = y.len();
    let nu: f64 = blocks.iter().map(|b| b.f0.n as f64).sum();
    barrier_sparse(blocks, &y, 0.0)?;
    let mut tau = 1.0;
    for _outer in 0..60 {
        for _newton in 0..100 {
            let mut grad = vec![0.0; d];
            let mut hess = vec![0.0; d * d];
            grad[d - 1] -= tau;
            for b in blocks {
                let g = b.eval(&y);
                let l = cholesky(&g)?;
                let (_, inv) = logdet_inverse(&l, g.n);
                let w: Vec<Vec<f64>> = b.terms.iter().map(|(_, f)| matmul(&inv, f)).collect();
                let n = g.n;
                for (a, (i, _)) in b.terms.iter().enumerate() {
                    grad[*i] -= (0..n).map(|r| w[a][r * n + r]).sum::<f64>();
                    for (c, (k, _)) in b.terms.iter().enumerate().take(a + 1) {
                        let mut s = 0.0;
                        for r in 0..n {
                            for q in 0..n {
                                s += w[a][r * n + q] * w[c][q * n + r];
                            }
                        }
                        hess[i * d + k] += s;
                        if a != c {
                            hess[k * d + i] += s;
                        }
                    }
                }
            }
            let mut hs = Sym { n: d, a: hess };
            let l = match cholesky(&hs) {
                Some(l) => l,
                None => {
                    let ridge = 1e-12 * (1.0 + hs.abs_sum());
                    for i in 0..d {
                        hs.add(i, i, ridge);
                    }
                    cholesky(&hs)?
                }
            };
            let step = chol_solve(&l, d, &grad);
            let decrement: f64 = step.iter().zip(&grad).map(|(s, g)| s * g).sum::<f64>();
            let step: Vec<f64> = step.iter().map(|s| -s).collect();
            if !(decrement > 1e-14) {
                break;
            }
            let f0 = barrier_sparse(blocks, &y, tau)?;
            let mut s = 1.0;
            let mut moved = false;
            for _ in 0..60 {
                let trial: Vec<f64> = y.iter().zip(&step).map(|(a, b)| a + s * b).collect();
                if let Some(f) = barrier_sparse(blocks, &trial, tau) {
                    if f <= f0 - 0.25 * s * decrement {
                        y = trial;
                        moved = true;
                        break;
                    }
                }
                s *= 0.5;
            }
            if !moved || decrement < 1e-10 {
                break;
            }
        }
        if nu / tau < gap || good(&y) {
            break;
        }
        tau *= 8.0;
    }
    Some(y)
}

/// x with L Lᵀ x = b.
fn chol_solve(l: &[f64], n: usize, b: &[f64]) -> Vec<f64> {
    let mut x = b.to_vec();
    for i in 0..n {
        let mut v = x[i];
        for k in 0..i {
            v -= l[i * n + k] * x[k];
        }
        x[i] = v / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut v = x[i];
        for k in i + 1..n {
            v -= l[k * n + i] * x[k];
        }
        x[i] = v / l[i * n + i];
    }
    x
}

/// Above this dimension [`sym_eigenvalues`] uses faer's Householder tridiagonalisation and
/// QR instead of cyclic Jacobi: on the global and chain loops' matrices (n in the hundreds)
/// Jacobi's ≈ 10 sweeps of 4n³ scalar operations were 47 % of the case study's `reproduce`
/// (perf, session 21). The small LMI blocks of [`super::inner`] keep Jacobi.
const JACOBI_MAX_DIM: usize = 16;

/// Eigenvalues of a symmetric matrix (ascending), accurate to a few ε‖S‖ (backward stable;
/// every caller's allowance is ≥ 10³·n·ε times an entrywise scale ≥ ‖S‖₂), and independent
/// of the barrier solver's Cholesky factorisations: cyclic Jacobi up to [`JACOBI_MAX_DIM`],
/// faer's symmetric eigensolver above it (Jacobi if that one does not converge).
pub(crate) fn sym_eigenvalues(s: &Sym) -> Vec<f64> {
    let n = s.n;
    if n > JACOBI_MAX_DIM {
        if let Some(ev) = householder_eigenvalues(s) {
            return ev;
        }
    }
    jacobi_eigenvalues(s)
}

/// faer's symmetric eigenvalues, sequential (the global searches run one thread per norm, and
/// the bits must not depend on a thread count); None if it does not converge.
fn householder_eigenvalues(s: &Sym) -> Option<Vec<f64>> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::evd::{self, ComputeEigenvectors};
    let n = s.n;
    let m = faer::Mat::from_fn(n, n, |i, j| 0.5 * (s.a[i * n + j] + s.a[j * n + i]));
    let mut d = faer::diag::Diag::<f64>::zeros(n);
    let par = faer::Par::Seq;
    let params = Default::default();
    let mut buf = MemBuffer::new(evd::self_adjoint_evd_scratch::<f64>(
        n,
        ComputeEigenvectors::No,
        par,
        params,
    ));
    evd::self_adjoint_evd(
        m.as_ref(),
        d.as_mut(),
        None,
        par,
        MemStack::new(&mut buf),
        params,
    )
    .ok()?;
    let mut ev: Vec<f64> = (0..n).map(|i| d[i]).collect();
    if !ev.iter().all(|v| v.is_finite()) {
        return None;
    }
    ev.sort_by(f64::total_cmp);
    Some(ev)
}

/// Eigenvalues of a symmetric matrix by the cyclic Jacobi method (ascending): slow but
/// accurate to a few ε‖S‖.
fn jacobi_eigenvalues(s: &Sym) -> Vec<f64> {
    let n = s.n;
    let mut a = s.a.clone();
    // Symmetrise exactly (the callers build symmetric matrices; this removes any doubt).
    for i in 0..n {
        for j in 0..i {
            let m = 0.5 * (a[i * n + j] + a[j * n + i]);
            a[i * n + j] = m;
            a[j * n + i] = m;
        }
    }
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i * n + j] * a[i * n + j])
            .sum();
        let diag: f64 = (0..n).map(|i| a[i * n + i] * a[i * n + i]).sum();
        if off <= 1e-34 * diag || off == 0.0 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * c;
                for k in 0..n {
                    let akp = a[k * n + p];
                    let akq = a[k * n + q];
                    a[k * n + p] = c * akp - sn * akq;
                    a[k * n + q] = sn * akp + c * akq;
                }
                for k in 0..n {
                    let apk = a[p * n + k];
                    let aqk = a[q * n + k];
                    a[p * n + k] = c * apk - sn * aqk;
                    a[q * n + k] = sn * apk + c * aqk;
                }
            }
        }
    }
    let mut ev: Vec<f64> = (0..n).map(|i| a[i * n + i]).collect();
    ev.sort_by(f64::total_cmp);
    ev
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobi_eigenvalues_of_a_known_matrix() {
        // [[2,1],[1,2]]: 1 and 3.
        let s = Sym {
            n: 2,
            a: vec![2.0, 1.0, 1.0, 2.0],
        };
        let ev = sym_eigenvalues(&s);
        assert!((ev[0] - 1.0).abs() < 1e-14 && (ev[1] - 3.0).abs() < 1e-14);
    }

    #[test]
    fn both_eigensolvers_agree_above_the_jacobi_dimension() {
        // A symmetric 40 × 40 with a known spread: the two algorithms to 1e-12 of ‖S‖.
        let n = 40;
        let mut s = Sym::zeros(n);
        for i in 0..n {
            for j in 0..=i {
                let v = ((i * 7 + j * 13) % 17) as f64 - 8.0 + if i == j { i as f64 } else { 0.0 };
                s.a[i * n + j] = v;
                s.a[j * n + i] = v;
            }
        }
        let fast = sym_eigenvalues(&s);
        let slow = jacobi_eigenvalues(&s);
        let norm = slow.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        assert_eq!(fast.len(), n);
        for (a, b) in fast.iter().zip(&slow) {
            assert!((a - b).abs() <= 1e-12 * norm, "{a} vs {b}");
        }
        let trace: f64 = (0..n).map(|i| s.at(i, i)).sum();
        assert!((fast.iter().sum::<f64>() - trace).abs() <= 1e-10 * norm * n as f64);
    }

    #[test]
    fn barrier_maximises_a_scalar_lmi() {
        // max t s.t. [[1 − t, x], [x, 1 − t]] ≻ 0 and 1 − x² … as blocks: y = (x, t),
        // G₁ = [[1 − t, x], [x, 1 − t]] (needs |x| < 1 − t), G₂ = 0.5 − x (x < 0.5).
        // The optimum: x = 0, t = 1.
        let mut f0 = Sym::identity(2);
        f0.a[1] = 0.0;
        let fx = Sym {
            n: 2,
            a: vec![0.0, 1.0, 1.0, 0.0],
        };
        let mut ft = Sym::identity(2);
        ft.a.iter_mut().for_each(|v| *v = -*v);
        let b1 = AffineBlock {
            f0,
            fi: vec![fx, ft],
        };
        let b2 = AffineBlock {
            f0: Sym { n: 1, a: vec![0.5] },
            fi: vec![
                Sym {
                    n: 1,
                    a: vec![-1.0],
                },
                Sym::zeros(1),
            ],
        };
        let y =
            maximise_last(&[b1, b2], vec![0.1, -1.0], 1e-10, |_| false).expect("feasible start");
        assert!((y[1] - 1.0).abs() < 1e-8 && y[0].abs() < 1e-4, "{y:?}");
    }

    #[test]
    fn sparse_barrier_matches_the_dense_one() {
        // The LMI of `barrier_maximises_a_scalar_lmi` as sparse terms: same optimum.
        let mut f0 = Sym::identity(2);
        f0.a[1] = 0.0;
        let fx = Sym {
            n: 2,
            a: vec![0.0, 1.0, 1.0, 0.0],
        };
        let ft = Sym {
            n: 2,
            a: vec![-1.0, 0.0, 0.0, -1.0],
        };
        let b1 = SparseBlock {
            f0,
            terms: vec![(0, fx), (1, ft)],
        };
        let b2 = SparseBlock {
            f0: Sym { n: 1, a: vec![0.5] },
            terms: vec![(
                0,
                Sym {
                    n: 1,
                    a: vec![-1.0],
                },
            )],
        };
        let y = maximise_last_sparse(&[b1, b2], vec![0.1, -1.0], 1e-10, |_| false)
            .expect("feasible start");
        assert!((y[1] - 1.0).abs() < 1e-8 && y[0].abs() < 1e-4, "{y:?}");
    }
}
