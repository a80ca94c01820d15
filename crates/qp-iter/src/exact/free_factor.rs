//! The Cholesky factor of H_FF for the free set F of [`crate::active_set`], kept up to date
//! when one variable leaves or enters F instead of being recomputed (Golub & Van Loan,
//! *Matrix Computations*, 4th ed., §6.5.4; Gill, Golub, Murray, Saunders, "Methods for
//! modifying matrix factorizations", Math. Comp. 28 (1974)).
//!
//! The variables of F are kept in *factor order* (the order they entered, not ascending):
//! H_FF = L Lᵀ with rows and columns of H_FF in that order, L lower triangular with a
//! positive diagonal. Row a of L lives in a physical row `slot[a]` of an n × n buffer, so
//! neither operation moves rows:
//!
//! - **append** (a variable i enters F, becomes the last): the new row (lᵀ, d) solves
//!   L l = H_{F,i}, d = √(h_ii − ‖l‖²) — n_F² flops;
//! - **remove** (the variable at position p leaves F): dropping row p of L leaves rows
//!   p+1.. with one entry above the diagonal; Givens rotations of columns (k, k+1),
//!   k = p, p+1, …, computed and applied row by row, restore the triangle in place (the
//!   last column becomes zero and is dropped) — ≈ 3(n_F − p)² flops.
//!
//! Both are backward stable; the caller recomputes the factor from H after a bounded number
//! of updates and whenever an update reports numerical trouble (an error leaves the factor
//! invalid).

/// A factor-update failure: the pivot (d² of an append, ρ of a rotation, or the Cholesky
/// pivot of a fresh factorisation) and the variable it belongs to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FactorBreakdown {
    pub pivot: f64,
    pub var: usize,
}

const NONE: usize = usize::MAX;

/// An append whose pivot d² is below this fraction of h_ii lost (almost) every digit to
/// cancellation: the factor is recomputed from H instead (only H_FF with κ ≳ 10⁸ gets here).
const APPEND_RELATIVE_PIVOT: f64 = 1e-8;

/// L Lᵀ = H_FF in factor order; see the module documentation.
#[derive(Debug, Clone)]
pub(crate) struct FreeFactor {
    n: usize,
    /// Factor position → variable.
    order: Vec<usize>,
    /// Variable → factor position (`NONE` if not in F).
    pos: Vec<usize>,
    /// Factor position → physical row of `l`.
    slot: Vec<usize>,
    /// Unused physical rows.
    spare: Vec<usize>,
    /// n × n, row-major; physical row `slot[a]` holds L[a][0..=a].
    l: Vec<f64>,
    /// Givens cosines and sines of a removal, indexed by the first column they rotate.
    cs: Vec<f64>,
    sn: Vec<f64>,
    /// The row of an append.
    col: Vec<f64>,
    valid: bool,
    /// Appends and removals since the last fresh factorisation.
    updates: usize,
}

impl FreeFactor {
    /// Workspace for n variables (allocates once); invalid until [`FreeFactor::factorize`].
    pub(crate) fn new(n: usize) -> Self {
        Self {
            n,
            order: Vec::with_capacity(n),
            pos: vec![NONE; n],
            slot: Vec::with_capacity(n),
            spare: Vec::with_capacity(n),
            l: vec![0.0; n * n],
            cs: vec![0.0; n],
            sn: vec![0.0; n],
            col: vec![0.0; n],
            valid: false,
            updates: 0,
        }
    }

    /// Whether the factor holds L Lᵀ = H_FF for F = [`FreeFactor::order`].
    pub(crate) fn is_valid(&self) -> bool {
        self.valid
    }

    /// Marks the factor unusable (the next use must call [`FreeFactor::factorize`]).
    pub(crate) fn invalidate(&mut self) {
        self.valid = false;
    }

    /// |F|.
    pub(crate) fn len(&self) -> usize {
        self.order.len()
    }

    /// The variables of F in factor order.
    pub(crate) fn order(&self) -> &[usize] {
        &self.order
    }

    /// Whether variable `i` is in F.
    pub(crate) fn contains(&self, i: usize) -> bool {
        self.pos[i] != NONE
    }

    /// Appends and removals since the last fresh factorisation.
    pub(crate) fn updates(&self) -> usize {
        self.updates
    }

    fn row(&self, a: usize) -> &[f64] {
        let s = self.slot[a] * self.n;
        &self.l[s..s + a + 1]
    }

    fn clear(&mut self) {
        for &i in &self.order {
            self.pos[i] = NONE;
        }
        self.order.clear();
        self.slot.clear();
        self.spare.clear();
        self.spare.extend((0..self.n).rev());
        self.valid = false;
    }

    /// Fresh Cholesky factorisation of H_FF (`h` row-major n × n) for F = `free` in that
    /// order. On failure the factor is invalid.
    pub(crate) fn factorize(
        &mut self,
        h: &[f64],
        free: impl Iterator<Item = usize>,
    ) -> Result<(), FactorBreakdown> {
        let n = self.n;
        self.clear();
        for (a, i) in free.enumerate() {
            self.order.push(i);
            self.pos[i] = a;
        }
        let nf = self.order.len();
        // Physical row a for position a: the spare stack keeps the rest.
        self.spare.truncate(n - nf);
        self.slot.extend(0..nf);
        let l = &mut self.l;
        for a in 0..nf {
            let ia = self.order[a];
            for b in 0..=a {
                l[a * n + b] = h[ia * n + self.order[b]];
            }
        }
        for j in 0..nf {
            let row_j = &l[j * n..j * n + j];
            let d = l[j * n + j] - dot(row_j, row_j);
            if !(d > 0.0 && d.is_finite()) {
                return Err(FactorBreakdown {
                    pivot: d,
                    var: self.order[j],
                });
            }
            let d = d.sqrt();
            l[j * n + j] = d;
            for i in j + 1..nf {
                let (top, bottom) = l.split_at_mut(i * n);
                let row_j = &top[j * n..j * n + j];
                let row_i = &mut bottom[..j + 1];
                row_i[j] = (row_i[j] - dot(&row_i[..j], row_j)) / d;
            }
        }
        self.valid = true;
        self.updates = 0;
        Ok(())
    }

    /// Variable `var` (not in F) enters F as the last position. Needs a valid factor; on
    /// failure the factor is invalid.
    pub(crate) fn append(&mut self, h: &[f64], var: usize) -> Result<(), FactorBreakdown> {
        debug_assert!(self.valid && !self.contains(var));
        let n = self.n;
        let nf = self.order.len();
        let h_row = &h[var * n..(var + 1) * n];
        // L l = H_{F,var}.
        for a in 0..nf {
            let r = self.row(a);
            let v = (h_row[self.order[a]] - dot(&r[..a], &self.col[..a])) / r[a];
            self.col[a] = v;
        }
        let d2 = h_row[var] - dot(&self.col[..nf], &self.col[..nf]);
        if !(d2 > APPEND_RELATIVE_PIVOT * h_row[var] && d2.is_finite()) {
            self.valid = false;
            return Err(FactorBreakdown { pivot: d2, var });
        }
        let Some(s) = self.spare.pop() else {
            // Unreachable while |F| < n; a broken invariant is a breakdown, not a panic.
            self.valid = false;
            return Err(FactorBreakdown { pivot: d2, var });
        };
        let row = &mut self.l[s * n..s * n + nf + 1];
        row[..nf].copy_from_slice(&self.col[..nf]);
        row[nf] = d2.sqrt();
        self.slot.push(s);
        self.order.push(var);
        self.pos[var] = nf;
        self.updates += 1;
        Ok(())
    }

    /// Variable `var` (in F) leaves F; returns the position it had (later positions move
    /// down by one). Needs a valid factor; on failure the factor is invalid.
    pub(crate) fn remove(&mut self, var: usize) -> Result<usize, FactorBreakdown> {
        debug_assert!(self.valid && self.contains(var));
        let n = self.n;
        let p = self.pos[var];
        let nf = self.order.len();
        // Old row r (> p) becomes row r − 1: apply the rotations k = p..r−2 already found,
        // then find rotation r − 1 that zeroes its entry in column r.
        for r in p + 1..nf {
            let s = self.slot[r] * n;
            let row = &mut self.l[s..s + r + 1];
            for k in p..r - 1 {
                let (c, sn) = (self.cs[k], self.sn[k]);
                let (a, b) = (row[k], row[k + 1]);
                row[k] = c * a + sn * b;
                row[k + 1] = c * b - sn * a;
            }
            let k = r - 1;
            let (a, b) = (row[k], row[k + 1]);
            let rho = (a * a + b * b).sqrt();
            if !(rho > 0.0 && rho.is_finite()) {
                self.valid = false;
                return Err(FactorBreakdown {
                    pivot: rho,
                    var: self.order[r],
                });
            }
            self.cs[k] = a / rho;
            self.sn[k] = b / rho;
            row[k] = rho;
            row[k + 1] = 0.0;
        }
        let freed = self.slot.remove(p);
        self.spare.push(freed);
        self.order.remove(p);
        self.pos[var] = NONE;
        for a in p..self.order.len() {
            self.pos[self.order[a]] = a;
        }
        self.updates += 1;
        Ok(p)
    }

    /// x ← H_FF⁻¹ x for x in factor order (length |F|).
    pub(crate) fn solve_in_place(&self, x: &mut [f64]) {
        let nf = self.order.len();
        debug_assert_eq!(x.len(), nf);
        // L y = x.
        for a in 0..nf {
            let r = self.row(a);
            x[a] = (x[a] - dot(&r[..a], &x[..a])) / r[a];
        }
        // Lᵀ x = y, column-oriented: row a of L is column a of Lᵀ.
        for a in (0..nf).rev() {
            let r = self.row(a);
            let xa = x[a] / r[a];
            x[a] = xa;
            for (xb, lb) in x[..a].iter_mut().zip(&r[..a]) {
                *xb -= lb * xa;
            }
        }
    }

    /// L as a dense row-major |F| × |F| matrix in factor order (tests).
    #[cfg(test)]
    pub(crate) fn dense(&self) -> Vec<f64> {
        let nf = self.order.len();
        let mut m = vec![0.0; nf * nf];
        for a in 0..nf {
            m[a * nf..a * nf + a + 1].copy_from_slice(self.row(a));
        }
        m
    }
}

/// Dot product with four partial sums (a fixed summation order).
#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let chunks = a.len() / 4;
    for c in 0..chunks {
        for k in 0..4 {
            acc[k] += a[4 * c + k] * b[4 * c + k];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for k in 4 * chunks..a.len() {
        s += a[k] * b[k];
    }
    s
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A random SPD matrix (row-major) from a fixed LCG: B Bᵀ + n·I scaled rows.
    fn spd(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let b: Vec<f64> = (0..n * n).map(|_| next()).collect();
        let mut h = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                h[i * n + j] = (0..n).map(|k| b[i * n + k] * b[j * n + k]).sum::<f64>()
                    + if i == j { 0.05 } else { 0.0 };
            }
        }
        h
    }

    /// max |L − L_fresh| / max |L_fresh| against a fresh factorisation in the same order.
    fn deviation(f: &FreeFactor, h: &[f64], n: usize) -> f64 {
        let mut fresh = FreeFactor::new(n);
        fresh.factorize(h, f.order().iter().copied()).unwrap();
        let (a, b) = (f.dense(), fresh.dense());
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        a.iter()
            .zip(&b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
            / scale
    }

    #[test]
    fn updates_match_a_fresh_factorisation() {
        let mut worst = 0.0f64;
        for seed in 0..40u64 {
            let n = 5 + (seed as usize * 7) % 40;
            let h = spd(n, seed);
            let mut f = FreeFactor::new(n);
            f.factorize(&h, (0..n).filter(|i| i % 3 != 0)).unwrap();
            let mut s = seed;
            for _ in 0..4 * n {
                s = s.wrapping_mul(2862933555777941757).wrapping_add(3037000493);
                let i = (s >> 33) as usize % n;
                if f.contains(i) {
                    if f.len() > 1 {
                        f.remove(i).unwrap();
                    }
                } else {
                    f.append(&h, i).unwrap();
                }
                assert!(f.order().iter().enumerate().all(|(a, &v)| f.pos[v] == a));
            }
            let d = deviation(&f, &h, n);
            worst = worst.max(d);
            assert!(d < 1e-10, "seed {seed}, n = {n}: deviation {d:e}");
            // And the solve: H_FF x = b.
            let nf = f.len();
            let b: Vec<f64> = (0..nf).map(|a| (a as f64).cos()).collect();
            let mut x = b.clone();
            f.solve_in_place(&mut x);
            for a in 0..nf {
                let ia = f.order()[a];
                let r: f64 = (0..nf).map(|c| h[ia * n + f.order()[c]] * x[c]).sum();
                assert!((r - b[a]).abs() < 1e-9, "seed {seed}");
            }
        }
        assert!(worst < 1e-10);
    }

    #[test]
    fn removing_everything_and_appending_back_is_fine() {
        let n = 12;
        let h = spd(n, 99);
        let mut f = FreeFactor::new(n);
        f.factorize(&h, 0..n).unwrap();
        for i in [5, 0, 11, 3, 4, 1, 2, 6, 7, 8, 9, 10] {
            f.remove(i).unwrap();
        }
        assert_eq!(f.len(), 0);
        for i in (0..n).rev() {
            f.append(&h, i).unwrap();
        }
        assert!(deviation(&f, &h, n) < 1e-12);
    }

    #[test]
    fn an_indefinite_matrix_is_a_breakdown() {
        let h = vec![1.0, 2.0, 2.0, 1.0];
        let mut f = FreeFactor::new(2);
        assert!(f.factorize(&h, 0..2).is_err());
        assert!(!f.is_valid());
        f.factorize(&h, 0..1).unwrap();
        let e = f.append(&h, 1).unwrap_err();
        assert_eq!(e.var, 1);
        assert!(e.pivot < 0.0 && !f.is_valid());
    }
}
