//! The estimator: Alg. 1 steps 1–3 with every buffer sized at compile time.

use crate::data::{DataError, Problem, WarmStart};
use crate::qp::{self, SLOTS};
use crate::scalar::Scalar;

/// Why [`Mhe::push`] refused a pair: an entry is NaN or ±∞ (nothing changed). No finite
/// range is imposed: the certificate bounds the disturbances, not the measurements.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum PushError {
    /// `u[index]` is not finite.
    NonFiniteInput {
        /// The entry of u.
        index: usize,
    },
    /// `y[index]` is not finite.
    NonFiniteMeasurement {
        /// The entry of y.
        index: usize,
    },
}

impl core::fmt::Display for PushError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PushError::NonFiniteInput { index } => write!(f, "u[{index}] is not finite"),
            PushError::NonFiniteMeasurement { index } => write!(f, "y[{index}] is not finite"),
        }
    }
}

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
pub(crate) fn mul_add<T: Scalar>(m: &[T], rows: usize, cols: usize, x: &[T], y: &mut [T]) {
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

    /// The number of pairs pushed, saturated at M + 1 (only min(t, M) and whether t > M
    /// matter, and a free-running counter would overflow).
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
            self.work.each_mut().map(|w| w.as_mut_slice()),
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
    /// t ← t + 1. Runs [`Mhe::estimate`] first if it was not run at this t. A NaN or ±∞ in
    /// u or y is refused before anything changes.
    pub fn push(&mut self, u: &[T; NU], y: &[T; NY]) -> Result<(), PushError> {
        if let Some(index) = u.iter().position(|v| !v.is_finite()) {
            return Err(PushError::NonFiniteInput { index });
        }
        if let Some(index) = y.iter().position(|v| !v.is_finite()) {
            return Err(PushError::NonFiniteMeasurement { index });
        }
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
        if self.t <= M {
            self.t += 1;
        }
        self.estimated = false;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{Method, Window};

    // n_x = 1, n_u = 1, n_y = 1, n_w = 2, M = 2 (made-up data, PG).
    const INF: f64 = f64::INFINITY;
    static W0: Window<'static, f64> = Window {
        n: 1,
        n_theta: 1,
        h: &[2.0],
        m_rho: &[],
        m_inv: &[],
        q0: &[0.0],
        f: &[-2.0],
        lower: &[-INF],
        upper: &[INF],
        scaling: &[],
        step: 0.5,
        momentum: 0.0,
        inv_rho: 0.0,
        relaxation: 0.0,
        structured: None,
    };
    static W1: Window<'static, f64> = Window {
        n: 3,
        n_theta: 3,
        h: &[3.0, 0.0, 1.0, 0.0, 2.0, 0.0, 1.0, 0.0, 3.0],
        m_rho: &[],
        m_inv: &[],
        q0: &[0.0; 3],
        f: &[-1.6, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -2.0],
        lower: &[-INF, -0.1, -0.1],
        upper: &[INF, 0.1, 0.1],
        scaling: &[],
        step: 0.4,
        momentum: 0.0,
        inv_rho: 0.0,
        relaxation: 0.0,
        structured: None,
    };
    static W2: Window<'static, f64> = Window {
        n: 5,
        n_theta: 5,
        h: &[
            3.0, 0.0, 1.0, 0.0, 0.5, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0,
            0.0, 2.0, 0.0, 0.5, 0.0, 0.0, 0.0, 3.0,
        ],
        m_rho: &[],
        m_inv: &[],
        q0: &[0.0; 5],
        f: &[
            -1.6, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -2.0, 0.0, 0.0, 0.0,
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -2.0,
        ],
        lower: &[-INF, -0.1, -0.1, -0.1, -0.1],
        upper: &[INF, 0.1, 0.1, 0.1, 0.1],
        scaling: &[],
        step: 0.3,
        momentum: 0.0,
        inv_rho: 0.0,
        relaxation: 0.0,
        structured: None,
    };
    static WINDOWS: [Window<'static, f64>; 3] = [W0, W1, W2];
    static P: Problem<'static, f64> = Problem {
        nx: 1,
        nu: 1,
        ny: 1,
        nw1: 1,
        nw2: 1,
        horizon: 2,
        iterations: 5,
        method: Method::Pg,
        warm_start: WarmStart::Shifted,
        a: &[0.9],
        b: &[0.5],
        e: &[1.0],
        windows: &WINDOWS,
    };
    type Est = Mhe<'static, f64, 1, 1, 1, 2, 5, 5>;

    fn pair(k: usize) -> ([f64; 1], [f64; 1]) {
        ([0.1 * k as f64], [1.0 - 0.05 * k as f64])
    }

    /// A counter set to usize::MAX once the window is full (as after 2^64 − 1 steps, or
    /// 2^32 − 1 on a 32-bit target) runs on with the same bits as one that counted.
    #[test]
    fn the_step_counter_started_near_the_limit_saturates() {
        let mut a = Est::new(&P, [0.5]).expect("the data fit");
        for k in 0..4 {
            let (u, y) = pair(k);
            a.push(&u, &y).expect("finite");
        }
        assert_eq!(a.t(), 3, "saturated at M + 1");
        let mut b = a.clone();
        b.t = usize::MAX;
        for k in 4..10 {
            let (u, y) = pair(k);
            a.push(&u, &y).expect("finite");
            b.push(&u, &y).expect("finite");
            assert_eq!(
                a.estimate().map(f64::to_bits),
                b.estimate().map(f64::to_bits)
            );
        }
    }

    /// NaN or ±∞ in u or y: refused with the entry named, the estimator unchanged.
    #[test]
    fn a_non_finite_pair_is_refused_and_nothing_changes() {
        let mut a = Est::new(&P, [0.5]).expect("the data fit");
        for k in 0..3 {
            let (u, y) = pair(k);
            a.push(&u, &y).expect("finite");
        }
        let before = a.clone();
        assert_eq!(
            a.push(&[f64::NAN], &[1.0]),
            Err(PushError::NonFiniteInput { index: 0 })
        );
        assert_eq!(
            a.push(&[0.0], &[f64::NEG_INFINITY]),
            Err(PushError::NonFiniteMeasurement { index: 0 })
        );
        assert_eq!(a.t, before.t);
        assert_eq!(a.estimated, before.estimated);
        assert_eq!(a.z0.map(f64::to_bits), before.z0.map(f64::to_bits));
        assert_eq!(a.y_ring.data, before.y_ring.data);
        let mut b = before;
        a.push(&[0.2], &[0.7]).expect("finite");
        b.push(&[0.2], &[0.7]).expect("finite");
        assert_eq!(
            a.estimate().map(f64::to_bits),
            b.estimate().map(f64::to_bits)
        );
    }
}
