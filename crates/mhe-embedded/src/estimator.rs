//! The estimator: Alg. 1 steps 1–3 with every buffer sized at compile time.

use crate::data::{DataError, Problem, WarmStart};
use crate::qp::{self, SLOTS};
use crate::scalar::Scalar;

/// Fixed-capacity ring buffer of M vectors of length W.
#[derive(Debug, Clone, Copy)]
struct Ring<T, const W: usize, const M: usize> {
    data: [[T; W]; M],
    len: usize,
    next: usize,
}

impl<T: Scalar, const W: usize, const M: usize> Ring<T, W, M> {
    fn new() -> Self {
        Self {
            data: [[T::ZERO; W]; M],
            len: 0,
            next: 0,
        }
    }
    fn push(&mut self, v: &[T; W]) {
        if M == 0 {
            return;
        }
        self.data[self.next] = *v;
        self.next = (self.next + 1) % M;
        self.len = (self.len + 1).min(M);
    }
    /// The k-th newest entry (k = 1 is the newest), 1 ≤ k ≤ len.
    fn back(&self, k: usize) -> &[T; W] {
        &self.data[(self.next + M - k) % M]
    }
    fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
    }
}

/// The sub-optimal MHE of Alg. 1 on borrowed problem data, allocation-free.
///
/// Const parameters (checked against the data by [`Mhe::new`]): `NX` = n_x, `NU` = n_u,
/// `NY` = n_y, `M` = the horizon, `NZ` = n_x + M n_w (the full window's z), `NTH` = n_x +
/// M (n_u + n_y) (its θ).
///
/// Protocol per time step t (as `mhe_core::Estimator`): [`Mhe::estimate`] gives x̂_{t|t}
/// from the data up to t − 1, then [`Mhe::push`] appends (u_t, y_t) and advances t.
#[derive(Debug, Clone)]
pub struct Mhe<
    'a,
    T: Scalar,
    const NX: usize,
    const NU: usize,
    const NY: usize,
    const M: usize,
    const NZ: usize,
    const NTH: usize,
> {
    p: &'a Problem<'a, T>,
    prior: [T; NX],
    t: usize,
    estimated: bool,
    u_ring: Ring<T, NU, M>,
    y_ring: Ring<T, NY, M>,
    estimates: Ring<T, NX, M>,
    theta: [T; NTH],
    z0: [T; NZ],
    zk: [T; NZ],
    work: [[T; NZ]; SLOTS],
    x_hat: [T; NX],
    x_tmp: [T; NX],
}

/// y[..rows] += M x for row-major M, each row summed from 0 first (the std `mul_add`).
#[inline]
fn mul_add<T: Scalar>(m: &[T], rows: usize, cols: usize, x: &[T], y: &mut [T]) {
    for i in 0..rows {
        let mut acc = T::ZERO;
        for (a, b) in m[i * cols..(i + 1) * cols].iter().zip(x) {
            acc = acc + *a * *b;
        }
        y[i] = y[i] + acc;
    }
}

impl<
    'a,
    T: Scalar,
    const NX: usize,
    const NU: usize,
    const NY: usize,
    const M: usize,
    const NZ: usize,
    const NTH: usize,
> Mhe<'a, T, NX, NU, NY, M, NZ, NTH>
{
    /// An estimator at t = 0 with prior x̄₀ = `prior`; errors if a const parameter or a
    /// data length does not match the problem.
    pub fn new(problem: &'a Problem<'a, T>, prior: [T; NX]) -> Result<Self, DataError> {
        problem.validate(NX, NU, NY, M, NZ, NTH)?;
        let mut s = Self {
            p: problem,
            prior,
            t: 0,
            estimated: false,
            u_ring: Ring::new(),
            y_ring: Ring::new(),
            estimates: Ring::new(),
            theta: [T::ZERO; NTH],
            z0: [T::ZERO; NZ],
            zk: [T::ZERO; NZ],
            work: [[T::ZERO; NZ]; SLOTS],
            x_hat: [T::ZERO; NX],
            x_tmp: [T::ZERO; NX],
        };
        s.reset(prior);
        Ok(s)
    }

    /// Restarts at t = 0 with the prior x̄₀ = `prior`.
    pub fn reset(&mut self, prior: [T; NX]) {
        self.prior = prior;
        self.t = 0;
        self.estimated = false;
        self.u_ring.clear();
        self.y_ring.clear();
        self.estimates.clear();
        self.z0 = [T::ZERO; NZ];
        self.z0[..NX].copy_from_slice(&prior);
    }

    /// The number of pairs pushed.
    pub fn t(&self) -> usize {
        self.t
    }

    /// The problem data.
    pub fn problem(&self) -> &'a Problem<'a, T> {
        self.p
    }

    /// x⁺ = A x + B u + E w¹ into `out` (summed as the std `HotModel::step`).
    fn step_model(p: &Problem<'_, T>, x: &[T], u: &[T], w1: &[T], out: &mut [T; NX]) {
        *out = [T::ZERO; NX];
        mul_add(p.a, NX, NX, x, out);
        mul_add(p.b, NX, NU, u, out);
        mul_add(p.e, NX, p.nw1, w1, out);
    }

    /// Step 1 of Alg. 1: K iterations on ℙ_t from z⁰_t, then x̂ᴷ_{t|t}. Idempotent at a
    /// given t.
    pub fn estimate(&mut self) -> &[T; NX] {
        let p = self.p;
        let t = self.t;
        let m = t.min(M);
        let nw = p.nw();
        let w = &p.windows[m];
        let (nz, nth) = (w.n, w.n_theta);
        // θ_t = (prior, u_{t−m..t−1}, y_{t−m..t−1}).
        if t <= M {
            self.theta[..NX].copy_from_slice(&self.prior);
        } else {
            self.theta[..NX].copy_from_slice(self.estimates.back(M));
        }
        let (u_off, y_off) = (NX, NX + m * NU);
        for j in 0..m {
            self.theta[u_off + j * NU..u_off + (j + 1) * NU]
                .copy_from_slice(self.u_ring.back(m - j));
            self.theta[y_off + j * NY..y_off + (j + 1) * NY]
                .copy_from_slice(self.y_ring.back(m - j));
        }
        qp::run(
            p.method,
            w,
            &self.theta[..nth],
            Some(&self.z0[..nz]),
            p.iterations,
            &mut self.work,
            &mut self.zk[..nz],
        );
        // x̂_{t|t}: x̂₀ propagated through the window with the inputs of θ and ŵ¹ of z.
        self.x_hat.copy_from_slice(&self.zk[..NX]);
        for j in 0..m {
            let uo = u_off + j * NU;
            let wo = NX + j * nw;
            Self::step_model(
                p,
                &self.x_hat,
                &self.theta[uo..uo + NU],
                &self.zk[wo..wo + p.nw1],
                &mut self.x_tmp,
            );
            self.x_hat = self.x_tmp;
        }
        self.estimated = true;
        &self.x_hat
    }

    /// Steps 2–3 of Alg. 1: the warm start Σ_t, the prior ring buffer and (u_t, y_t);
    /// t ← t + 1. Runs [`Mhe::estimate`] first if it was not run at this t.
    pub fn push(&mut self, u: &[T; NU], y: &[T; NY]) {
        if !self.estimated {
            self.estimate();
        }
        let p = self.p;
        let t = self.t;
        let m = t.min(M);
        let nw = p.nw();
        let nz = NX + m * nw;
        if t < M {
            self.z0[..nz].copy_from_slice(&self.zk[..nz]);
            for v in &mut self.z0[nz..nz + nw] {
                *v = T::ZERO;
            }
        } else {
            match p.warm_start {
                WarmStart::Paper => self.z0[..nz].copy_from_slice(&self.zk[..nz]),
                WarmStart::Shifted => {
                    let uo = NX;
                    let wo = NX;
                    Self::step_model(
                        p,
                        &self.zk[..NX],
                        &self.theta[uo..uo + NU],
                        &self.zk[wo..wo + p.nw1],
                        &mut self.x_tmp,
                    );
                    self.z0[..NX].copy_from_slice(&self.x_tmp);
                    self.z0[NX..nz - nw].copy_from_slice(&self.zk[NX + nw..nz]);
                    for v in &mut self.z0[nz - nw..nz] {
                        *v = T::ZERO;
                    }
                }
            }
        }
        self.estimates.push(&self.x_hat);
        self.u_ring.push(u);
        self.y_ring.push(y);
        self.t += 1;
        self.estimated = false;
    }
}
