//! The estimator with sizes known at run time: [`MheRt`] runs the operations of
//! [`crate::Mhe`] in the same order on buffers the caller owns (one slice of
//! [`MheRt::workspace_len`] scalars), so a host (the Python package's `dtype="float32"`, a
//! test bench) reproduces the board's bits without compiling the sizes in.

use crate::data::{DataError, Problem, WarmStart, check};
use crate::estimator::{PushError, mul_add};
use crate::qp::{self, SLOTS};
use crate::scalar::Scalar;

/// Ring buffer of `cap` vectors of width `width` over a caller-owned slice (the const-size
/// estimator's `Ring` with run-time sizes).
#[derive(Debug)]
struct RingRt<'b, T> {
    data: &'b mut [T],
    width: usize,
    cap: usize,
    len: usize,
    next: usize,
}

impl<T: Scalar> RingRt<'_, T> {
    fn push(&mut self, v: &[T]) {
        if self.cap == 0 {
            return;
        }
        let w = self.width;
        self.data[self.next * w..(self.next + 1) * w].copy_from_slice(&v[..w]);
        self.next = (self.next + 1) % self.cap;
        self.len = (self.len + 1).min(self.cap);
    }
    /// The k-th newest entry (k = 1 is the newest), 1 ≤ k ≤ len.
    fn back(&self, k: usize) -> &[T] {
        let i = (self.next + self.cap - k) % self.cap;
        &self.data[i * self.width..(i + 1) * self.width]
    }
    fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
    }
}

/// Splits `n` scalars off the front of `rest`.
fn take<'b, T>(rest: &mut &'b mut [T], n: usize) -> &'b mut [T] {
    let (head, tail) = core::mem::take(rest).split_at_mut(n);
    *rest = tail;
    head
}

/// [`crate::Mhe`] with n_x, n_u, n_y, M read from the [`Problem`] and every buffer in one
/// caller-owned slice: the same operations in the same order (the shared `qp::run`, the
/// same ring, θ, warm start and propagation), so its estimates equal the const-size
/// estimator's bit for bit at f32 and f64. No allocation anywhere.
#[derive(Debug)]
pub struct MheRt<'a, 'b, T: Scalar> {
    p: &'a Problem<'a, T>,
    nx: usize,
    nu: usize,
    ny: usize,
    horizon: usize,
    prior: &'b mut [T],
    t: usize,
    estimated: bool,
    u_ring: RingRt<'b, T>,
    y_ring: RingRt<'b, T>,
    estimates: RingRt<'b, T>,
    theta: &'b mut [T],
    z0: &'b mut [T],
    zk: &'b mut [T],
    work: [&'b mut [T]; SLOTS],
    x_hat: &'b mut [T],
    x_tmp: &'b mut [T],
}

impl<'a, 'b, T: Scalar> MheRt<'a, 'b, T> {
    /// The scalars [`MheRt::new`] needs in its workspace for `problem`:
    /// 3 n_x + M (n_u + n_y + n_x) + n_θ + (2 + 6) n_z (saturating, so absurd sizes fail
    /// the length check instead of overflowing).
    pub fn workspace_len(problem: &Problem<'_, T>) -> usize {
        let (nx, m) = (problem.nx, problem.horizon);
        let nz = m.saturating_mul(problem.nw()).saturating_add(nx);
        let nth = m
            .saturating_mul(problem.nu.saturating_add(problem.ny))
            .saturating_add(nx);
        let rings = m.saturating_mul(problem.nu.saturating_add(problem.ny).saturating_add(nx));
        nx.saturating_mul(3)
            .saturating_add(rings)
            .saturating_add(nth)
            .saturating_add(nz.saturating_mul(2 + SLOTS))
    }

    /// An estimator at t = 0 with prior x̄₀ = `prior` (length n_x) on `workspace` (length
    /// [`MheRt::workspace_len`]); errors if a length does not match the problem.
    pub fn new(
        problem: &'a Problem<'a, T>,
        prior: &[T],
        workspace: &'b mut [T],
    ) -> Result<Self, DataError> {
        let (nx, nu, ny, m) = (problem.nx, problem.nu, problem.ny, problem.horizon);
        check(
            "workspace length",
            Self::workspace_len(problem),
            workspace.len(),
        )?;
        let nz = nx + m * problem.nw();
        let nth = nx + m * (nu + ny);
        problem.validate(nx, nu, ny, m, nz, nth)?;
        check("prior length (n_x)", nx, prior.len())?;
        for v in workspace.iter_mut() {
            *v = T::ZERO;
        }
        let mut rest = workspace;
        let ring = |rest: &mut &'b mut [T], width: usize| RingRt {
            data: take(rest, m * width),
            width,
            cap: m,
            len: 0,
            next: 0,
        };
        let prior_buf = take(&mut rest, nx);
        let u_ring = ring(&mut rest, nu);
        let y_ring = ring(&mut rest, ny);
        let estimates = ring(&mut rest, nx);
        let theta = take(&mut rest, nth);
        let z0 = take(&mut rest, nz);
        let zk = take(&mut rest, nz);
        let work = [(); SLOTS].map(|()| take(&mut rest, nz));
        let x_hat = take(&mut rest, nx);
        let x_tmp = take(&mut rest, nx);
        let mut s = Self {
            p: problem,
            nx,
            nu,
            ny,
            horizon: m,
            prior: prior_buf,
            t: 0,
            estimated: false,
            u_ring,
            y_ring,
            estimates,
            theta,
            z0,
            zk,
            work,
            x_hat,
            x_tmp,
        };
        s.reset(prior)?;
        Ok(s)
    }

    /// Restarts at t = 0 with the prior x̄₀ = `prior` (length n_x).
    pub fn reset(&mut self, prior: &[T]) -> Result<(), DataError> {
        check("prior length (n_x)", self.nx, prior.len())?;
        self.prior.copy_from_slice(prior);
        self.t = 0;
        self.estimated = false;
        self.u_ring.clear();
        self.y_ring.clear();
        self.estimates.clear();
        for v in self.z0.iter_mut() {
            *v = T::ZERO;
        }
        self.z0[..self.nx].copy_from_slice(prior);
        Ok(())
    }

    /// The number of pairs pushed, saturated at M + 1 (as [`crate::Mhe::t`]).
    pub fn t(&self) -> usize {
        self.t
    }

    /// The problem data.
    pub fn problem(&self) -> &'a Problem<'a, T> {
        self.p
    }

    /// z⁰_t: the start of the iteration on ℙ_t (after a push, the warm start the next
    /// [`MheRt::estimate`] runs from; before it, the prior with zero noise). Its first n_z of
    /// the current window are in use; read-only, for checks of the iteration from outside.
    pub fn start(&self) -> &[T] {
        self.z0
    }

    /// zᴷ: the last [`MheRt::estimate`]'s K-th iterate (its first n_z of that window are in
    /// use; zero before the first estimate).
    pub fn iterate(&self) -> &[T] {
        self.zk
    }

    /// x⁺ = A x + B u + E w¹ into `out` (the const-size estimator's `step_model`).
    fn step_model(p: &Problem<'_, T>, x: &[T], u: &[T], w1: &[T], out: &mut [T]) {
        let (nx, nu) = (p.nx, p.nu);
        for v in out[..nx].iter_mut() {
            *v = T::ZERO;
        }
        mul_add(p.a, nx, nx, x, out);
        mul_add(p.b, nx, nu, u, out);
        mul_add(p.e, nx, p.nw1, w1, out);
    }

    /// Step 1 of Alg. 1 (as [`crate::Mhe::estimate`]): K iterations on ℙ_t from z⁰_t,
    /// then x̂ᴷ_{t|t} (length n_x). Idempotent at a given t.
    pub fn estimate(&mut self) -> &[T] {
        let p = self.p;
        let (nx, nu, ny, mm) = (self.nx, self.nu, self.ny, self.horizon);
        let t = self.t;
        let m = t.min(mm);
        let nw = p.nw();
        let w = &p.windows[m];
        let (nz, nth) = (w.n, w.n_theta);
        if t <= mm {
            self.theta[..nx].copy_from_slice(self.prior);
        } else {
            self.theta[..nx].copy_from_slice(self.estimates.back(mm));
        }
        let (u_off, y_off) = (nx, nx + m * nu);
        for j in 0..m {
            self.theta[u_off + j * nu..u_off + (j + 1) * nu]
                .copy_from_slice(self.u_ring.back(m - j));
            self.theta[y_off + j * ny..y_off + (j + 1) * ny]
                .copy_from_slice(self.y_ring.back(m - j));
        }
        qp::run(
            p.method,
            w,
            &self.theta[..nth],
            Some(&self.z0[..nz]),
            p.iterations,
            self.work.each_mut().map(|w| &mut **w),
            &mut self.zk[..nz],
        );
        self.x_hat.copy_from_slice(&self.zk[..nx]);
        for j in 0..m {
            let uo = u_off + j * nu;
            let wo = nx + j * nw;
            Self::step_model(
                p,
                self.x_hat,
                &self.theta[uo..uo + nu],
                &self.zk[wo..wo + p.nw1],
                self.x_tmp,
            );
            self.x_hat.copy_from_slice(self.x_tmp);
        }
        self.estimated = true;
        self.x_hat
    }

    /// Steps 2–3 of Alg. 1 (as [`crate::Mhe::push`]); `u` of length n_u, `y` of length
    /// n_y (checked first, then finiteness; nothing changes on an error).
    pub fn push(&mut self, u: &[T], y: &[T]) -> Result<(), PushErrorRt> {
        check("u length (n_u)", self.nu, u.len()).map_err(PushErrorRt::Length)?;
        check("y length (n_y)", self.ny, y.len()).map_err(PushErrorRt::Length)?;
        if let Some(index) = u.iter().position(|v| !v.is_finite()) {
            return Err(PushErrorRt::Value(PushError::NonFiniteInput { index }));
        }
        if let Some(index) = y.iter().position(|v| !v.is_finite()) {
            return Err(PushErrorRt::Value(PushError::NonFiniteMeasurement {
                index,
            }));
        }
        if !self.estimated {
            self.estimate();
        }
        let p = self.p;
        let (nx, mm) = (self.nx, self.horizon);
        let t = self.t;
        let m = t.min(mm);
        let nw = p.nw();
        let nz = nx + m * nw;
        if t < mm {
            self.z0[..nz].copy_from_slice(&self.zk[..nz]);
            for v in &mut self.z0[nz..nz + nw] {
                *v = T::ZERO;
            }
        } else {
            match p.warm_start {
                WarmStart::Paper => self.z0[..nz].copy_from_slice(&self.zk[..nz]),
                WarmStart::Shifted => {
                    Self::step_model(
                        p,
                        &self.zk[..nx],
                        &self.theta[nx..nx + self.nu],
                        &self.zk[nx..nx + p.nw1],
                        self.x_tmp,
                    );
                    self.z0[..nx].copy_from_slice(self.x_tmp);
                    self.z0[nx..nz - nw].copy_from_slice(&self.zk[nx + nw..nz]);
                    for v in &mut self.z0[nz - nw..nz] {
                        *v = T::ZERO;
                    }
                }
            }
        }
        self.estimates.push(self.x_hat);
        self.u_ring.push(u);
        self.y_ring.push(y);
        if self.t <= mm {
            self.t += 1;
        }
        self.estimated = false;
        Ok(())
    }
}

/// Why [`MheRt::push`] refused a pair: a length that is not n_u / n_y, or a non-finite
/// entry (nothing changed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum PushErrorRt {
    /// u or y has the wrong length.
    Length(DataError),
    /// An entry is NaN or ±∞.
    Value(PushError),
}

impl core::fmt::Display for PushErrorRt {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PushErrorRt::Length(e) => e.fmt(f),
            PushErrorRt::Value(e) => e.fmt(f),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{Method, Window};
    use crate::estimator::Mhe;

    // n_x = 2, n_u = 1, n_y = 1, n_w1 = 2, n_w2 = 1, M = 2: n_z = 8, n_θ = 6.
    const NX: usize = 2;
    const M: usize = 2;
    const NZ: usize = 8;
    const NTH: usize = 6;
    const CAP: usize = NZ * NZ;

    /// Deterministic made-up numbers in [−1, 1) (an LCG), rounded to f32 once.
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) as f32
        }
    }

    /// One window's arrays (capacity for the largest window).
    struct Store {
        h: [f32; CAP],
        m_rho: [f32; CAP],
        m_inv: [f32; CAP],
        q0: [f32; NZ],
        f: [f32; NZ * NTH],
        lower: [f32; NZ],
        upper: [f32; NZ],
        scaling: [f32; NZ],
    }

    fn store(rng: &mut Lcg, n: usize) -> Store {
        let mut s = Store {
            h: [0.0; CAP],
            m_rho: [0.0; CAP],
            m_inv: [0.0; CAP],
            q0: [0.0; NZ],
            f: [0.0; NZ * NTH],
            lower: [0.0; NZ],
            upper: [0.0; NZ],
            scaling: [0.0; NZ],
        };
        for i in 0..n {
            for j in 0..n {
                let off = 0.2 * rng.next();
                s.h[j * n + i] = if i == j { 2.0 + rng.next() } else { off };
                s.m_rho[j * n + i] = if i == j { 0.5 } else { 0.1 * rng.next() };
                s.m_inv[j * n + i] = if i == j { 0.4 } else { 0.1 * rng.next() };
            }
        }
        for v in s.q0.iter_mut().chain(s.f.iter_mut()) {
            *v = rng.next();
        }
        for i in 0..NZ {
            // The x̂₀ block free, the disturbances in a box (some active).
            let free = i < NX;
            s.lower[i] = if free { f32::NEG_INFINITY } else { -0.2 };
            s.upper[i] = if free { f32::INFINITY } else { 0.15 };
            s.scaling[i] = 1.0 + 0.5 * rng.next();
        }
        s
    }

    fn window(s: &Store, m: usize, scaled: bool) -> Window<'_, f32> {
        let (n, nt) = (NX + 3 * m, NX + 2 * m);
        Window {
            n,
            n_theta: nt,
            h: &s.h[..n * n],
            m_rho: &s.m_rho[..n * n],
            m_inv: &s.m_inv[..n * n],
            q0: &s.q0[..n],
            f: &s.f[..n * nt],
            lower: &s.lower[..n],
            upper: &s.upper[..n],
            scaling: if scaled { &s.scaling[..n] } else { &[] },
            step: 0.3,
            momentum: 0.4,
            inv_rho: 0.8,
            relaxation: 1.6,
            structured: None,
        }
    }

    /// The runtime-size estimator against the const-size one at f32: every method, plain
    /// and Jacobi-scaled, both warm starts, 12 steps (the growing window, the full one and
    /// the prior from the ring), x̂ equal bit for bit at every step, after a reset too.
    #[test]
    fn the_runtime_size_estimator_is_the_const_size_one_bit_for_bit_at_f32() {
        let mut rng = Lcg(7);
        let stores = [store(&mut rng, NX), store(&mut rng, 5), store(&mut rng, NZ)];
        let (a, b, e) = ([0.9, 0.1, -0.2, 0.8], [0.5, 0.3], [1.0, 0.0, 0.2, 1.0]);
        for method in [Method::Pg, Method::Fista, Method::Admm] {
            for scaled in [false, true] {
                for warm_start in [WarmStart::Paper, WarmStart::Shifted] {
                    let windows = [
                        window(&stores[0], 0, scaled),
                        window(&stores[1], 1, scaled),
                        window(&stores[2], 2, scaled),
                    ];
                    let p = Problem {
                        nx: NX,
                        nu: 1,
                        ny: 1,
                        nw1: 2,
                        nw2: 1,
                        horizon: M,
                        iterations: 7,
                        method,
                        warm_start,
                        a: &a,
                        b: &b,
                        e: &e,
                        windows: &windows,
                    };
                    let prior = [0.3f32, -0.7];
                    let mut c = Mhe::<f32, NX, 1, 1, M, NZ, NTH>::new(&p, prior).expect("fits");
                    let mut ws = [0.0f32; 128];
                    let len = MheRt::workspace_len(&p);
                    let mut r = MheRt::new(&p, &prior, &mut ws[..len]).expect("fits");
                    let mut rng = Lcg(11);
                    for round in 0..2 {
                        for t in 0..12 {
                            let (u, y) = ([rng.next()], [rng.next()]);
                            let xc = c.estimate().map(f32::to_bits);
                            let xr = r.estimate();
                            assert_eq!(xr.len(), NX);
                            let xr = [xr[0].to_bits(), xr[1].to_bits()];
                            assert_eq!(
                                xc, xr,
                                "{method:?} scaled={scaled} {warm_start:?} round {round} t={t}"
                            );
                            c.push(&u, &y).expect("finite");
                            r.push(&u, &y).expect("finite");
                            assert_eq!(c.t(), r.t());
                        }
                        c.reset([-0.1, 0.2]);
                        r.reset(&[-0.1, 0.2]).expect("n_x entries");
                    }
                }
            }
        }
    }

    /// Wrong lengths (workspace, prior, u, y) and non-finite pairs are refused with the
    /// field named, and a refused push changes nothing.
    #[test]
    fn wrong_lengths_and_non_finite_pairs_are_refused() {
        let mut rng = Lcg(3);
        let stores = [store(&mut rng, NX), store(&mut rng, 5), store(&mut rng, NZ)];
        let windows = [
            window(&stores[0], 0, false),
            window(&stores[1], 1, false),
            window(&stores[2], 2, false),
        ];
        let p = Problem {
            nx: NX,
            nu: 1,
            ny: 1,
            nw1: 2,
            nw2: 1,
            horizon: M,
            iterations: 3,
            method: Method::Pg,
            warm_start: WarmStart::Paper,
            a: &[0.9, 0.1, -0.2, 0.8],
            b: &[0.5, 0.3],
            e: &[1.0, 0.0, 0.2, 1.0],
            windows: &windows,
        };
        let len = MheRt::workspace_len(&p);
        assert_eq!(len, 3 * 2 + 2 * (1 + 1 + 2) + NTH + 8 * NZ);
        let mut ws = [0.0f32; 128];
        let err = MheRt::new(&p, &[0.0, 0.0], &mut ws[..len - 1]).expect_err("short");
        assert_eq!(err.what, "workspace length");
        let err = MheRt::new(&p, &[0.0], &mut ws[..len]).expect_err("short prior");
        assert_eq!(err.what, "prior length (n_x)");
        let mut r = MheRt::new(&p, &[0.0, 0.0], &mut ws[..len]).expect("fits");
        let e = r.push(&[0.0, 1.0], &[0.0]).expect_err("u too long");
        assert!(matches!(e, PushErrorRt::Length(d) if d.what == "u length (n_u)"));
        let e = r.push(&[0.0], &[f32::NAN]).expect_err("NaN");
        assert_eq!(
            e,
            PushErrorRt::Value(PushError::NonFiniteMeasurement { index: 0 })
        );
        assert_eq!(r.t(), 0);
    }
}
