//! Solving the global loop's LMI: the supply, the Riccati candidate P, its independent
//! check, and the searches over (τ₁, τ₃, ρ, γ) and φ.

use faer::Mat;
use faer::linalg::solvers::Solve;

use super::{GlobalCertificate, GlobalLoop, GlobalOptions, add, mul, readout_gain, sym_of};
use crate::lure::sdp::{Sym, sym_eigenvalues};

/// The pieces of one LMI evaluation.
struct Terms {
    /// Π (the supply: multipliers and −γ²‖w‖²), N × N.
    pi: Mat<f64>,
}
impl GlobalLoop {
    fn supply(&self, phi: f64, tau1: f64, tau3: f64) -> Terms {
        let nc = self.n_zeta();
        let mut pi = Mat::<f64>::zeros(nc, nc);
        let aa = mul(self.sig2_a.transpose(), self.sig2_a.as_ref());
        let bb = mul(self.sig2_b.transpose(), self.sig2_b.as_ref());
        for i in 0..nc {
            for j in 0..nc {
                pi[(i, j)] = tau1 * self.sigma_mhe[(i, j)] + phi * phi * aa[(i, j)] - bb[(i, j)];
            }
        }
        if let Some(s3) = &self.sigma_mpc {
            for i in 0..nc {
                for j in 0..nc {
                    pi[(i, j)] += tau3 * s3[(i, j)];
                }
            }
        }
        if let Some(r) = &self.extra_supply {
            add(&mut pi, r);
        }
        Terms { pi }
    }

    /// The LMI matrix X⁺ᵀPX⁺ − ρ²E_XᵀPE_X + Π, formed afresh, with the entrywise scale of
    /// its rounding: (|X⁺|ᵀ|P||X⁺| + |Π| + ρ²|P|)_ij.
    fn lmi(&self, p: &Mat<f64>, rho: f64, pi: &Mat<f64>) -> (Sym, Sym) {
        let (n, nc) = (self.n_x, self.n_zeta());
        let px = mul(p.as_ref(), self.x_plus.as_ref());
        let q = mul(self.x_plus.transpose(), px.as_ref());
        let abs = |m: &Mat<f64>| Mat::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)].abs());
        let (xa, pa) = (abs(&self.x_plus), abs(p));
        let qa = mul(xa.transpose(), mul(pa.as_ref(), xa.as_ref()).as_ref());
        let mut m = Sym::zeros(nc);
        let mut sc = Sym::zeros(nc);
        for i in 0..nc {
            for j in 0..nc {
                let mut v = 0.5 * (q[(i, j)] + q[(j, i)]) + 0.5 * (pi[(i, j)] + pi[(j, i)]);
                let mut e = qa[(i, j)].max(qa[(j, i)]) + pi[(i, j)].abs().max(pi[(j, i)].abs());
                if i < n && j < n {
                    let t = rho * rho * 0.5 * (p[(i, j)] + p[(j, i)]);
                    v -= t;
                    e += t.abs();
                }
                m.a[i * nc + j] = v;
                sc.a[i * nc + j] = e;
            }
        }
        (m, sc)
    }

    /// The independent check: P ≻ 0 and the LMI ⪯ 0, by Jacobi eigenvalues of the matrices
    /// equilibrated by a positive diagonal congruence D (d_i = scale_ii^(−½): definiteness is
    /// invariant, and the entrywise rounding scales with it), each clearing 10³·dim·ε·Σ scale.
    /// Returns (LMI margin, P margin), −λ_max and λ_min relative to Σ scale.
    /// Err(Some(f)): negative but within the allowance, f = allowance/|λ| (how much more
    /// strictness the solve needs); Err(None): not negative definite.
    fn check(&self, p: &Mat<f64>, rho: f64, pi: &Mat<f64>) -> Result<(f64, f64), Option<f64>> {
        let tol =
            |n: usize, scale: f64| 1e3 * n as f64 * f64::EPSILON * scale.max(f64::MIN_POSITIVE);
        let equilibrate = |m: &Sym, sc: &Sym| {
            let n = m.n;
            let d: Vec<f64> = (0..n)
                .map(|i| {
                    let s = sc.at(i, i);
                    if s > 0.0 && s.is_finite() {
                        1.0 / s.sqrt()
                    } else {
                        1.0
                    }
                })
                .collect();
            let mut mm = Sym::zeros(n);
            let mut total = 0.0;
            for i in 0..n {
                for j in 0..n {
                    mm.a[i * n + j] = d[i] * d[j] * m.at(i, j);
                    total += d[i] * d[j] * sc.at(i, j);
                }
            }
            (mm, total)
        };
        let ps = sym_of(p);
        let pabs = Sym {
            n: ps.n,
            a: ps.a.iter().map(|v| v.abs()).collect(),
        };
        let (pe, pscale) = equilibrate(&ps, &pabs);
        let pev = sym_eigenvalues(&pe);
        let pt = tol(pe.n, pscale);
        if !(pev[0] > pt) {
            return Err((pev[0] > 0.0).then(|| 2.0 * pt / pev[0]));
        }
        let (m, sc) = self.lmi(p, rho, pi);
        let (me, scale) = equilibrate(&m, &sc);
        let top = sym_eigenvalues(&me).last().copied().ok_or(None)?;
        let t = tol(me.n, scale);
        if !(-top > t) {
            return Err((top < 0.0).then(|| 2.0 * t / -top));
        }
        Ok((-top / scale, pev[0] / pscale))
    }

    /// A candidate P for fixed scalars: the minimal solution of the worst-case Riccati
    /// equation with a strict supply (δ on X, ε on v), by doubling; None if it diverges.
    pub(super) fn riccati(&self, rho: f64, pi: &Mat<f64>, strict: f64) -> Option<Mat<f64>> {
        // w is not an input of this problem (γ = ∞): its γ comes from the P found
        // (`gamma2_for`).
        let (n, nv) = (self.n_x, self.n_v - self.n_w);
        let big = pi.as_ref();
        let scale = (0..n + nv)
            .map(|i| big[(i, i)].abs())
            .fold(0.0_f64, f64::max)
            .max(1e-300);
        let delta = strict * scale;
        // ε per input coordinate, relative to its own diagonal (the Jacobi weights D⁻² span
        // decades: one ε for all would swamp the small ones).
        let eps: Vec<f64> = (0..nv)
            .map(|i| strict * big[(n + i, n + i)].abs().max(1e-6 * scale))
            .collect();
        let r2 = rho * rho;
        // Cost c = −(Π + δE_X + εE_v)/ρ² of the min-form; dynamics (A, B)/ρ.
        let qc = Mat::from_fn(n, n, |i, j| {
            -(big[(i, j)] + if i == j { delta } else { 0.0 }) / r2
        });
        let sc = Mat::from_fn(n, nv, |i, j| -big[(i, n + j)] / r2);
        let rc = Mat::from_fn(nv, nv, |i, j| {
            -(big[(n + i, n + j)] + if i == j { eps[i] } else { 0.0 }) / r2
        });
        let llt = rc.llt(faer::Side::Lower).ok()?;
        let at = Mat::from_fn(n, n, |i, j| self.x_plus[(i, j)] / rho);
        let bt = Mat::from_fn(n, nv, |i, j| self.x_plus[(i, n + j)] / rho);
        let rinv_sct = llt.solve(sc.transpose().to_owned()); // Rc⁻¹Scᵀ
        let rinv_bt = llt.solve(bt.transpose().to_owned()); // Rc⁻¹B̃ᵀ
        let mut a = at.clone();
        let t = mul(bt.as_ref(), rinv_sct.as_ref());
        for i in 0..n {
            for j in 0..n {
                a[(i, j)] -= t[(i, j)];
            }
        }
        let mut g = mul(bt.as_ref(), rinv_bt.as_ref());
        let scs = mul(sc.as_ref(), rinv_sct.as_ref());
        let mut h = Mat::from_fn(n, n, |i, j| qc[(i, j)] - scs[(i, j)]);
        let h0 = norm_max(&h).max(1e-300);
        let eye = Mat::<f64>::identity(n, n);
        for _ in 0..64 {
            let mut w = mul(g.as_ref(), h.as_ref());
            add(&mut w, &eye);
            let lu = w.partial_piv_lu();
            let wa = lu.solve(&a);
            let wg = lu.solve(&g);
            let dh = mul(a.transpose(), mul(h.as_ref(), wa.as_ref()).as_ref());
            let dg = mul(a.as_ref(), mul(wg.as_ref(), a.transpose()).as_ref());
            let a_next = mul(a.as_ref(), wa.as_ref());
            let change = norm_max(&dh);
            add(&mut h, &dh);
            add(&mut g, &dg);
            symmetrise(&mut h);
            symmetrise(&mut g);
            a = a_next;
            let hn = norm_max(&h);
            if !hn.is_finite() || hn > 1e12 * h0 {
                return None;
            }
            if change <= 1e-14 * hn {
                let p = Mat::from_fn(n, n, |i, j| -h[(i, j)]);
                return Some(p);
            }
        }
        None
    }

    /// Tries the scalars (τ₁, τ₃) at (φ, ρ, γ²); a P that passes the independent check.
    /// γ² for a P of the LMI without w: twice the smallest γ² that the Schur complement
    /// allows, λ_max(D + Cᵀ(−M₀)⁻¹C) with M₀ the LMI on the other coordinates, C its
    /// coupling to w and D = ℬᵀPℬ. None if M₀ is not negative definite.
    pub(super) fn gamma2_for(&self, p: &Mat<f64>, rho: f64, pi: &Mat<f64>) -> Option<f64> {
        let (m, _) = self.lmi(p, rho, pi);
        let nc = m.n;
        let n0 = nc - self.n_w;
        let neg = Mat::from_fn(n0, n0, |i, j| -m.at(i, j));
        let c = Mat::from_fn(n0, self.n_w, |i, j| m.at(i, n0 + j));
        let llt = neg.llt(faer::Side::Lower).ok()?;
        let x = llt.solve(&c);
        let mut s = mul(c.transpose(), x.as_ref());
        for i in 0..self.n_w {
            for j in 0..self.n_w {
                s[(i, j)] += m.at(n0 + i, n0 + j);
            }
        }
        let top = sym_eigenvalues(&sym_of(&s)).last().copied()?;
        let floor = 1e-9 * norm_max(p).max(f64::MIN_POSITIVE);
        let g2 = 2.0 * top.max(0.0) + floor;
        g2.is_finite().then_some(g2)
    }

    fn certify_scalars(
        &self,
        phi: f64,
        rho: f64,
        tau1: f64,
        tau3: f64,
    ) -> Option<GlobalCertificate> {
        let Terms { pi: pi0 } = self.supply(phi, tau1, tau3);
        self.certify_supply(phi, rho, &pi0, [tau1, tau3], Vec::new())
    }

    /// The Riccati candidate for the supply `pi0` (without w), its γ², and the independent
    /// check; the certificate records `tau` and `lambda` (the multipliers that formed `pi0`).
    pub(super) fn certify_supply(
        &self,
        phi: f64,
        rho: f64,
        pi0: &Mat<f64>,
        tau: [f64; 2],
        lambda: Vec<f64>,
    ) -> Option<GlobalCertificate> {
        self.certify_supply_from(phi, rho, pi0, tau, lambda, 1e-6)
    }

    /// [`GlobalLoop::certify_supply`] from strictness `strict` (δ = ε relative to Π).
    fn certify_supply_from(
        &self,
        phi: f64,
        rho: f64,
        pi0: &Mat<f64>,
        tau: [f64; 2],
        lambda: Vec<f64>,
        strict: f64,
    ) -> Option<GlobalCertificate> {
        // Raised (twice at most) when the check finds the LMI negative but within its
        // rounding allowance.
        let mut strict = strict;
        let mut found = None;
        for _ in 0..3 {
            let p = self.riccati(rho, pi0, strict)?;
            let gamma2 = self.gamma2_for(&p, rho, pi0)?;
            let mut pi = pi0.clone();
            let nc = self.n_zeta();
            for k in 0..self.n_w {
                pi[(nc - self.n_w + k, nc - self.n_w + k)] -= gamma2;
            }
            match self.check(&p, rho, &pi) {
                Ok(m) => {
                    found = Some((p, gamma2, m));
                    break;
                }
                Err(Some(need)) => strict *= need.clamp(2.0, 1e4),
                Err(None) => return None,
            }
        }
        let (p, gamma2, (margin, p_margin)) = found?;
        let gamma = gamma2.sqrt();
        let (gain_x, gain_e) = self.gains(&p, rho, gamma)?;
        Some(GlobalCertificate {
            phi,
            rho,
            gamma,
            tau,
            lambda,
            p,
            margin,
            p_margin,
            gain_x,
            gain_e,
        })
    }

    /// The multipliers tried: τ relative to the scale of σ₂'s form.
    pub(super) fn tau_grid(&self, opts: &GlobalOptions) -> Vec<f64> {
        let k = opts.tau_points.max(2);
        (0..k)
            .map(|i| 10f64.powf(-4.0 + 8.0 * i as f64 / (k - 1) as f64))
            .collect()
    }

    /// A certificate at φ with ρ = `rho_max` (feasibility), trying the multiplier grid
    /// (τ₁ × τ₃; a single point for a channel without bounded coordinates).
    pub fn certify_phi(&self, phi: f64, opts: &GlobalOptions) -> Option<GlobalCertificate> {
        self.certify_phi_from(phi, opts, None)
    }

    /// As [`GlobalLoop::certify_phi`], trying `first` (multipliers that certified a nearby φ)
    /// before the grid.
    pub(super) fn certify_phi_from(
        &self,
        phi: f64,
        opts: &GlobalOptions,
        first: Option<[f64; 2]>,
    ) -> Option<GlobalCertificate> {
        if let Some([t1, t3]) = first {
            if let Some(c) = self.certify_scalars(phi, opts.rho_max, t1, t3) {
                return Some(c);
            }
        }
        let grid = self.tau_grid(opts);
        let tau1s: Vec<f64> = if self.mhe_bounded > 0 {
            grid.clone()
        } else {
            vec![0.0]
        };
        let tau3s: Vec<f64> = if self.sigma_mpc.is_some() {
            grid
        } else {
            vec![0.0]
        };
        for &t1 in &tau1s {
            for &t3 in &tau3s {
                if first == Some([t1, t3]) {
                    continue;
                }
                if let Some(c) = self.certify_scalars(phi, opts.rho_max, t1, t3) {
                    return Some(c);
                }
            }
        }
        None
    }

    /// φ*: the largest φ (to `phi_tol`, relative) with a checked certificate, with it; None
    /// if even φ = 0 (d ≡ 0: the exact-MHE loop with the box) has none.
    pub fn phi_star(&self, opts: &GlobalOptions) -> Option<GlobalCertificate> {
        let mut best = self.certify_phi(0.0, opts)?;
        let mut tau = Some(best.tau);
        // Grow an upper bracket, then bisect.
        let mut lo = 0.0;
        let mut hi = 1e-3;
        while let Some(c) = self.certify_phi_from(hi, opts, tau) {
            tau = Some(c.tau);
            best = c;
            lo = hi;
            hi *= 4.0;
            if hi > 1e3 {
                return Some(best);
            }
        }
        while hi - lo > opts.phi_tol * hi {
            let mid = if lo == 0.0 {
                hi / 4.0
            } else {
                (lo * hi).sqrt()
            };
            match self.certify_phi_from(mid, opts, tau) {
                Some(c) => {
                    tau = Some(c.tau);
                    best = c;
                    lo = mid;
                }
                None => hi = mid,
            }
            if lo == 0.0 && hi < 1e-12 {
                break;
            }
        }
        Some(best)
    }

    /// K_glob: the first K ≤ `k_max` with φ(K) ≤ φ* (the certified K are exactly those, an
    /// interval since φ decreases in K), with the certificate at φ*.
    pub fn k_glob(&self, opts: &GlobalOptions) -> Option<(usize, GlobalCertificate)> {
        let cert = self.phi_star(opts)?;
        let k = crate::lure::first_k(|k| self.phi(k) <= cert.phi, opts.k_max)?;
        Some((k, cert))
    }

    /// The reported certificate at `phi` ≤ `base.phi` (Theorem L3's gains, docs/theory.md
    /// §4 "The reported gains"): the storage chosen for the gain, not for feasibility. At φ*
    /// itself ρ sits at `rho_max` (φ* is the edge of feasibility there), so the caller refines
    /// at the φ(K_glob) it reports. With `base`'s multipliers, Riccati candidates over
    /// [`RefineGrid`] — ρ, the strictness δ and a weight on the readouts x_t, x̂_{t−1} (a
    /// stricter supply: its storage is larger where the gains read it) — are *screened* by
    /// their gain_e for the supply itself (each one doubling, O(n_X³)); the best are then
    /// checked independently against the supply itself ([`GlobalLoop::certify_phi`]'s check,
    /// the costly O(n_ζ³) step) until one passes. `base` is returned when nothing beats it
    /// (it certifies every φ ≤ base.phi: the supply only shrinks), for per-row multipliers
    /// (`lambda`), and for `phi` > base.phi (no refinement there: the result's `phi` says
    /// what it certifies).
    pub fn refine_at(&self, phi: f64, base: &GlobalCertificate) -> GlobalCertificate {
        self.refine_at_with(phi, base, &RefineGrid::default())
    }

    /// [`GlobalLoop::refine_at`] over `grid`.
    pub fn refine_at_with(
        &self,
        phi: f64,
        base: &GlobalCertificate,
        grid: &RefineGrid,
    ) -> GlobalCertificate {
        if !base.lambda.is_empty() || !(phi <= base.phi) {
            return base.clone();
        }
        let [t1, t3] = base.tau;
        let Terms { pi: pi0 } = self.supply(phi, t1, t3);
        let mut found: Vec<(f64, f64, f64, f64)> = Vec::new(); // (gain_e, ρ, δ, readout)
        let gap = (1.0 - base.rho).max(1e-12);
        let n = grid.rho_points.max(2);
        for i in 0..n {
            let rho = 1.0 - gap * gap.powf(-(i as f64) / (n - 1) as f64);
            for &readout in &grid.readout {
                let pi_w = self.readout_weighted(&pi0, readout);
                for &strict in &grid.strict {
                    if let Some(ge) = self.screen(&pi0, &pi_w, rho, strict) {
                        found.push((ge, rho, strict, readout));
                    }
                }
            }
        }
        found.sort_by(|a, b| a.0.total_cmp(&b.0));
        for &(ge, rho, strict, readout) in found.iter().take(grid.checks) {
            if ge >= base.gain_e {
                break;
            }
            let pi_w = self.readout_weighted(&pi0, readout);
            let Some(p) = self.riccati(rho, &pi_w, strict) else {
                continue;
            };
            if let Some(c) = self.certify_storage(phi, rho, p, &pi0, [t1, t3]) {
                if c.gain_e < base.gain_e {
                    return c;
                }
            }
        }
        base.clone()
    }

    /// [`GlobalLoop::refine_at`] at `base.phi`.
    pub fn refine(&self, base: &GlobalCertificate) -> GlobalCertificate {
        self.refine_at(base.phi, base)
    }

    /// Π + w·s·(‖x_t‖² + ‖x̂_{t−1}‖²) on X (s: Π's largest diagonal entry): a stricter supply
    /// whose storage is larger in the readouts' directions. Π itself for w = 0.
    fn readout_weighted(&self, pi0: &Mat<f64>, w: f64) -> Mat<f64> {
        let mut pi = pi0.clone();
        if w > 0.0 {
            let s = (0..pi.nrows())
                .map(|i| pi[(i, i)].abs())
                .fold(0.0_f64, f64::max);
            let lay = self.lifted.layout();
            let est = lay.estimates(lay.horizon - 1);
            for i in (0..lay.nx).chain(est..est + lay.nx) {
                pi[(i, i)] += w * s;
            }
        }
        pi
    }

    /// The independent check of a given storage `p` for the supply `pi0` (γ² from `p`), as a
    /// certificate; None if it fails.
    fn certify_storage(
        &self,
        phi: f64,
        rho: f64,
        p: Mat<f64>,
        pi0: &Mat<f64>,
        tau: [f64; 2],
    ) -> Option<GlobalCertificate> {
        let gamma2 = self.gamma2_for(&p, rho, pi0)?;
        let mut pi = pi0.clone();
        let nc = self.n_zeta();
        for k in 0..self.n_w {
            pi[(nc - self.n_w + k, nc - self.n_w + k)] -= gamma2;
        }
        let (margin, p_margin) = self.check(&p, rho, &pi).ok()?;
        let gamma = gamma2.sqrt();
        let (gain_x, gain_e) = self.gains(&p, rho, gamma)?;
        Some(GlobalCertificate {
            phi,
            rho,
            gamma,
            tau,
            lambda: Vec::new(),
            p,
            margin,
            p_margin,
            gain_x,
            gain_e,
        })
    }

    /// The unchecked gain_e for the supply `pi0` of the Riccati candidate of `pi_w`
    /// (screening only: no certificate).
    fn screen(&self, pi0: &Mat<f64>, pi_w: &Mat<f64>, rho: f64, strict: f64) -> Option<f64> {
        let p = self.riccati(rho, pi_w, strict)?;
        let gamma = self.gamma2_for(&p, rho, pi0)?.sqrt();
        self.gains(&p, rho, gamma).map(|(_, ge)| ge)
    }

    /// (gain_x, gain_e) of a storage: lim sup ‖x‖ and ‖x − x̂‖ over w̄.
    fn gains(&self, p: &Mat<f64>, rho: f64, gamma: f64) -> Option<(f64, f64)> {
        let nx = self.lifted.layout().nx;
        let rx = Mat::from_fn(nx, self.n_x, |i, j| if i == j { 1.0 } else { 0.0 });
        let est = self
            .lifted
            .layout()
            .estimates(self.lifted.layout().horizon - 1);
        let rest = Mat::from_fn(nx, self.n_x, |i, j| if j == est + i { 1.0 } else { 0.0 });
        let gain_x = readout_gain(p, rho, gamma, rx.as_ref())?;
        let gain_e = gain_x + readout_gain(p, rho, gamma, rest.as_ref())?;
        Some((gain_x, gain_e))
    }
}

/// The candidates [`GlobalLoop::refine_at`] screens.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineGrid {
    /// ρ points, 1 − ρ log-spaced from 1 − base.ρ to 1.
    pub rho_points: usize,
    /// Strictness δ = ε relative to Π: a larger δ makes P larger in every direction (smaller
    /// readouts) at the price of a larger γ.
    pub strict: Vec<f64>,
    /// Weights on ‖x_t‖² + ‖x̂_{t−1}‖² added to the supply (relative to Π's scale).
    pub readout: Vec<f64>,
    /// Screened candidates checked at most (each check costs one φ* search call).
    pub checks: usize,
}

impl Default for RefineGrid {
    /// As measured in docs/theory.md §4, "The reported gains".
    fn default() -> Self {
        Self {
            rho_points: 9,
            strict: vec![1e-6, 1e-4, 1e-2],
            readout: vec![0.0, 1e-3, 1e-2, 1e-1],
            checks: 5,
        }
    }
}

fn norm_max(m: &Mat<f64>) -> f64 {
    let mut s = 0.0_f64;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            s = s.max(m[(i, j)].abs());
        }
    }
    s
}

fn symmetrise(m: &mut Mat<f64>) {
    let n = m.nrows();
    for i in 0..n {
        for j in 0..i {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}
