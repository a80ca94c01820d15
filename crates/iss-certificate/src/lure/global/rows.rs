//! Per-row (diagonal) multipliers on the optima's variational inequalities (docs/theory.md §4,
//! "Per-row multipliers"), and the frozen-clamp obstruction of that multiplier class.
//!
//! On a box containing 0 every row of an optimum satisfies z_i·g_i ≤ 0 (g = Hz + Fθ: an
//! interior row has g_i = 0, a row at its upper bound u_i ≥ 0 has g_i ≤ 0, at l_i ≤ 0 has
//! g_i ≥ 0). σ₁ = −Σ_i z_i g_i is their sum with equal weights; a multiplier λ_i ≥ 0 per row
//! is the diagonal sector multiplier of the clamp. For fixed ρ the LMI is jointly affine in
//! (P, λ, φ²), so the largest certifiable φ² is a concave function of λ: a coordinate ascent
//! over groups of rows, with the Riccati of [`GlobalLoop`] as the feasibility oracle, raises φ
//! from the scalar search's φ* (λ = τ·𝟙 is that certificate). The answer is accepted only
//! through the same independent check as every other global certificate.

use std::cell::Cell;
use std::ops::Range;

use faer::linalg::solvers::Solve;
use faer::{Mat, Par};

use super::{GlobalCertificate, GlobalError, GlobalLoop, GlobalOptions, mul};
use crate::linear::{LinearError, spectral_radius_dense};

/// Options of the per-row multiplier search ([`GlobalLoop::phi_star_rows`]).
#[derive(Debug, Clone, Copy)]
pub struct RowSearch {
    /// The rows of each optimum are searched in contiguous groups, at most this many groups
    /// in all (one λ per group; the rows of one group share it).
    pub max_groups: usize,
    /// The relative step in φ (or ρ) the ascent starts with; halved after a sweep without
    /// gain.
    pub step: f64,
    /// The ascent stops when the step falls below this (relative precision of φ*).
    pub tol: f64,
    /// Budget: Riccati solves at most (the search then reports what it has).
    pub max_solves: usize,
}

impl Default for RowSearch {
    fn default() -> Self {
        Self {
            max_groups: 24,
            step: 0.25,
            tol: 0.02,
            max_solves: 4_000,
        }
    }
}

/// The fixed parts of the supply: φ²·AᵀA − BᵀB is formed from these (σ₂).
struct Pieces {
    aa: Mat<f64>,
    bb: Mat<f64>,
}

impl GlobalLoop {
    /// (rows of the MHE optimum with a bound, rows of the controller's optimum with a bound).
    pub fn bounded_rows(&self) -> (usize, usize) {
        (self.grad_mhe.nrows(), self.grad_mpc.nrows())
    }

    fn pieces(&self) -> Pieces {
        Pieces {
            aa: mul(self.sig2_a.transpose(), self.sig2_a.as_ref()),
            bb: mul(self.sig2_b.transpose(), self.sig2_b.as_ref()),
        }
    }

    /// Π = φ²AᵀA − BᵀB − Σ_i λ_i·sym(e_{z_i} g_iᵀ) (MHE rows, then MPC rows).
    fn supply_rows(&self, pc: &Pieces, phi: f64, lambda: &[f64]) -> Mat<f64> {
        let nc = self.n_zeta();
        let mut pi = Mat::from_fn(nc, nc, |i, j| phi * phi * pc.aa[(i, j)] - pc.bb[(i, j)]);
        let nm = self.grad_mhe.nrows();
        for (r, &l) in lambda.iter().enumerate() {
            let (col, g) = if r < nm {
                (self.o_z + r, self.grad_mhe.row(r))
            } else {
                (self.o_u + r - nm, self.grad_mpc.row(r - nm))
            };
            for j in 0..nc {
                let v = 0.5 * l * g[j];
                pi[(col, j)] -= v;
                pi[(j, col)] -= v;
            }
        }
        pi
    }

    /// The per-row form −z_i g_i of row `r` (MHE rows first) as a symmetric matrix on ζ.
    pub fn row_form(&self, r: usize) -> Mat<f64> {
        let nc = self.n_zeta();
        let mut lam = vec![0.0; self.grad_mhe.nrows() + self.grad_mpc.nrows()];
        lam[r] = 1.0;
        let zero = Pieces {
            aa: Mat::zeros(nc, nc),
            bb: Mat::zeros(nc, nc),
        };
        self.supply_rows(&zero, 0.0, &lam)
    }

    /// The scalar starts of the per-row search: for each optimum, `tau_points` log-spaced
    /// values over 10⁻⁶…10⁶ times the ratio of σ₂'s scale to that optimum's form (the raw
    /// 10⁻⁴…10⁴ of the scalar search misses loops whose units make the ratio large); a single
    /// 0 for an optimum without bounded rows.
    fn row_grid(&self, pc: &Pieces, opts: &GlobalOptions) -> [Vec<f64>; 2] {
        let max = |m: &Mat<f64>| {
            m.col_iter()
                .flat_map(|c| c.iter().copied())
                .fold(0.0_f64, |a, v| a.max(v.abs()))
        };
        let b = max(&pc.bb).max(f64::MIN_POSITIVE);
        let k = opts.tau_points.max(2);
        let grid = |form: Option<&Mat<f64>>| match form {
            Some(f) if max(f) > 0.0 => {
                let s = b / max(f);
                (0..k)
                    .map(|i| s * 10f64.powf(-6.0 + 12.0 * i as f64 / (k - 1) as f64))
                    .collect()
            }
            _ => vec![0.0],
        };
        let (nm, nu) = self.bounded_rows();
        [
            grid((nm > 0).then_some(&self.sigma_mhe)),
            grid(if nu > 0 {
                self.sigma_mpc.as_ref()
            } else {
                None
            }),
        ]
    }

    /// The search's oracle: the Riccati candidate P exists, is positive definite, and the LMI
    /// without w is negative definite by Cholesky (`gamma2_for`). Convergence of the doubling
    /// alone is not enough: it does not see the sup over v turn unbounded. The certificate is
    /// still decided by the independent check.
    pub(super) fn feasible(&self, rho: f64, pi: &Mat<f64>) -> bool {
        self.riccati(rho, pi, 1e-6).is_some_and(|p| {
            p.llt(faer::Side::Lower).is_ok() && self.gamma2_for(&p, rho, pi).is_some()
        })
    }

    /// Contiguous groups of rows, per optimum, at most `max_groups` in all, after the groups
    /// "every row" and "each optimum's rows" (the scalar multipliers' directions).
    fn row_groups(&self, max_groups: usize) -> Vec<Range<usize>> {
        let (nm, nu) = self.bounded_rows();
        let total = (nm + nu).max(1);
        let mut out: Vec<Range<usize>> = Vec::new();
        out.push(0..nm + nu);
        if nm > 0 && nu > 0 {
            out.extend([0..nm, nm..nm + nu]);
        }
        for (start, n) in [(0, nm), (nm, nu)] {
            if n == 0 {
                continue;
            }
            let g = (max_groups.max(2) * n).div_ceil(total).clamp(1, n);
            let size = n.div_ceil(g);
            let mut a = 0;
            while a < n {
                let b = (a + size).min(n);
                out.push(start + a..start + b);
                a = b;
            }
        }
        out
    }

    /// φ*, searched over per-row multipliers: from `base` (a certificate of the scalar search,
    /// whose τ starts the search) or, without one, from the best scalar pair at φ = 0 driven
    /// to ρ ≤ `rho_max` first. None if no checked certificate is found; never below `base`.
    pub fn phi_star_rows(
        &self,
        opts: &GlobalOptions,
        search: &RowSearch,
        base: Option<&GlobalCertificate>,
    ) -> Option<GlobalCertificate> {
        let (nm, nu) = self.bounded_rows();
        if nm + nu == 0 {
            return base.cloned();
        }
        let pc = self.pieces();
        let solves = Cell::new(0usize);
        let feasible = |phi: f64, rho: f64, lam: &[f64]| {
            solves.set(solves.get() + 1);
            self.feasible(rho, &self.supply_rows(&pc, phi, lam))
        };
        let groups = self.row_groups(search.max_groups);
        let spread = |t: [f64; 2]| -> Vec<f64> {
            (0..nm + nu)
                .map(|r| if r < nm { t[0] } else { t[1] })
                .collect()
        };
        let (mut lam, phi0) = match base {
            Some(b) => (spread(b.tau), b.phi),
            None => {
                // The best scalar pair by the smallest ρ at φ = 0, then ρ driven down.
                let [g1, g3] = self.row_grid(&pc, opts);
                let mut best: Option<(f64, Vec<f64>)> = None;
                for &t1 in &g1 {
                    for &t3 in &g3 {
                        let lam = spread([t1, t3]);
                        if let Some(r) = smallest_rho(|r| feasible(0.0, r, &lam)) {
                            if best.as_ref().is_none_or(|(b, _)| r < *b) {
                                best = Some((r, lam));
                            }
                        }
                    }
                }
                let (rho, lam) = best?;
                let target = opts.rho_max;
                let (rho, lam) = ascend(
                    lam,
                    1.0 / rho,
                    &groups,
                    search,
                    &solves,
                    |lvl| lvl >= 1.0 / target,
                    |lvl, l| feasible(0.0, 1.0 / lvl, l),
                );
                if 1.0 / rho > target {
                    return None;
                }
                (lam, 0.0)
            }
        };
        // φ = 0 ⇒ first a positive φ with these λ (a bracket from 10⁻³ down).
        let mut phi = phi0;
        if phi == 0.0 {
            let mut t = 1e-3;
            while t > 1e-9 && !feasible(t, opts.rho_max, &lam) {
                t /= 8.0;
            }
            if t > 1e-9 {
                phi = t;
            }
        }
        if phi > 0.0 {
            let (p, l) = ascend(
                lam,
                phi,
                &groups,
                search,
                &solves,
                |_| false,
                |lvl, l| feasible(lvl, opts.rho_max, l),
            );
            phi = p;
            lam = l;
        }
        // The check decides; back off by the tolerance a few times if it refuses.
        for _ in 0..6 {
            let pi = self.supply_rows(&pc, phi, &lam);
            let tau = [0.0, 0.0];
            if let Some(c) = self.certify_supply(phi, opts.rho_max, &pi, tau, lam.clone()) {
                return Some(match base {
                    Some(b) if b.phi >= c.phi => b.clone(),
                    _ => c,
                });
            }
            phi /= 1.0 + search.tol;
        }
        base.cloned()
    }

    /// The per-row certificate at a given φ: [`GlobalLoop::rho_min_rows`], then the check at
    /// `rho_max`. None if ρ_max is not reached or the check refuses.
    pub fn certify_phi_rows(
        &self,
        phi: f64,
        opts: &GlobalOptions,
        search: &RowSearch,
    ) -> Option<GlobalCertificate> {
        let (rho, lam) = self.rho_min_rows(phi, opts, search)?;
        if rho > opts.rho_max {
            return None;
        }
        let pi = self.supply_rows(&self.pieces(), phi, &lam);
        self.certify_supply(phi, opts.rho_max, &pi, [0.0, 0.0], lam)
    }

    /// The smallest ρ the per-row search reaches at φ (the Riccati's answer, *not* checked: a
    /// diagnostic of how far a certificate is), with its λ: the best scalar pair by ρ, then
    /// the ascent over groups of rows, stopped once ρ ≤ `rho_max`. None if no pair has a
    /// Riccati solution at ρ ≤ 20.
    pub fn rho_min_rows(
        &self,
        phi: f64,
        opts: &GlobalOptions,
        search: &RowSearch,
    ) -> Option<(f64, Vec<f64>)> {
        let (nm, nu) = self.bounded_rows();
        let pc = self.pieces();
        let solves = Cell::new(0usize);
        let feasible = |rho: f64, lam: &[f64]| {
            solves.set(solves.get() + 1);
            self.feasible(rho, &self.supply_rows(&pc, phi, lam))
        };
        let [g1, g3] = self.row_grid(&pc, opts);
        let mut best: Option<(f64, Vec<f64>)> = None;
        for &t1 in &g1 {
            for &t3 in &g3 {
                let lam: Vec<f64> = (0..nm + nu).map(|r| if r < nm { t1 } else { t3 }).collect();
                if let Some(r) = smallest_rho(|r| feasible(r, &lam)) {
                    if best.as_ref().is_none_or(|(b, _)| r < *b) {
                        best = Some((r, lam));
                    }
                }
            }
        }
        let (rho, lam) = best?;
        let groups = self.row_groups(search.max_groups);
        let (lvl, lam) = ascend(
            lam,
            1.0 / rho,
            &groups,
            search,
            &solves,
            |lvl| lvl >= 1.0 / opts.rho_max,
            |lvl, l| feasible(1.0 / lvl, l),
        );
        Some((1.0 / lvl, lam))
    }

    /// ρ of the frozen-clamp loop: the rows marked in `clamped` (MHE rows, then MPC rows)
    /// held at 0, every other bounded row free (g_i = 0: the QP's optimum with those rows
    /// fixed), d = 0, w = 0 ([`GlobalLoop::frozen_slope_radius`] at angles π/2 and 0).
    ///
    /// Errors: as [`GlobalLoop::frozen_slope_radius`].
    pub fn frozen_clamp_radius(&self, clamped: &[bool]) -> Result<f64, GlobalError> {
        let (nm, nu) = self.bounded_rows();
        let angle: Vec<f64> = (0..nm + nu)
            .map(|r| {
                if clamped.get(r).copied().unwrap_or(false) {
                    std::f64::consts::FRAC_PI_2
                } else {
                    0.0
                }
            })
            .collect();
        self.frozen_slope_radius(&angle)
    }

    /// ρ of a frozen loop in which every bounded row r obeys
    /// cos θ_r·g_r + sin θ_r·h_r·z_r = 0 (θ_r ∈ [0, π/2]; h_r = |∂g_r/∂z_r| > 0 makes the
    /// angle unit-free): θ = 0 is a free row, θ = π/2 a row held at 0, and between, the
    /// optimum of the QP with the weight h_r·tan θ_r added on row r. Then z_r g_r ≤ 0 on every
    /// row, d = 0 and w = 0, so every constraint of (LMI-glob) with per-row (or scalar)
    /// multipliers holds on this loop at every φ ≥ 0 (σ₂ = φ²‖a‖² ≥ 0): ρ ≥ 1 refutes every
    /// certificate of the class, by the argument of Theorem L3 (ii).
    ///
    /// Errors: a singular row system (not expected: it is block-triangular, with the QPs'
    /// Hessians' Schur complements plus a non-negative diagonal), an eigenvalue failure.
    pub fn frozen_slope_radius(&self, angle: &[f64]) -> Result<f64, GlobalError> {
        let (nm, nu) = self.bounded_rows();
        let (n, nr) = (self.n_x, nm + nu);
        let col = |r: usize| {
            if r < nm {
                self.o_z + r
            } else {
                self.o_u + r - nm
            }
        };
        let grad = |r: usize| {
            if r < nm {
                self.grad_mhe.row(r)
            } else {
                self.grad_mpc.row(r - nm)
            }
        };
        // Row r: cos θ·(G_v v + G_X X)_r + sin θ·h_r·v_r = 0  ⇒  v = −M⁻¹ N X.
        let cs = |r: usize| {
            let t = angle.get(r).copied().unwrap_or(0.0);
            (t.cos(), t.sin() * grad(r)[col(r)].abs())
        };
        let m = Mat::from_fn(nr, nr, |a, b| {
            let (c, s) = cs(a);
            c * grad(a)[col(b)] + if a == b { s } else { 0.0 }
        });
        let nx = Mat::from_fn(nr, n, |a, j| cs(a).0 * grad(a)[j]);
        let v = if nr > 0 {
            let v = m.partial_piv_lu().solve(&nx);
            if v.col_iter()
                .flat_map(|c| c.iter().copied())
                .any(|x| !x.is_finite())
            {
                return Err(GlobalError::Linear(LinearError::Internal(
                    "the frozen-slope row system is singular",
                )));
            }
            v
        } else {
            Mat::zeros(0, n)
        };
        let mut a = Mat::from_fn(n, n, |i, j| self.x_plus[(i, j)]);
        for r in 0..nr {
            let c = col(r);
            for i in 0..n {
                let xi = self.x_plus[(i, c)];
                if xi != 0.0 {
                    for j in 0..n {
                        a[(i, j)] -= xi * v[(r, j)];
                    }
                }
            }
        }
        Ok(spectral_radius_dense(a.as_ref(), Par::Seq)?)
    }

    /// The worst frozen loop found ([`GlobalLoop::frozen_slope_radius`]) among the clamp
    /// patterns none, all, each optimum's rows, each group of contiguous rows alone and all
    /// but it, `samples` random subsets and `samples` random angle vectors (seeded), then a
    /// local ascent over single angles. Returns (ρ, the angles θ_r).
    pub fn worst_frozen_clamp(
        &self,
        samples: usize,
        seed: u64,
    ) -> Result<(f64, Vec<f64>), GlobalError> {
        use rand::{Rng, SeedableRng};
        let (nm, nu) = self.bounded_rows();
        let nr = nm + nu;
        let mut pats: Vec<Vec<bool>> = vec![vec![false; nr], vec![true; nr]];
        pats.push((0..nr).map(|r| r < nm).collect());
        pats.push((0..nr).map(|r| r >= nm).collect());
        for g in self.row_groups(24) {
            pats.push((0..nr).map(|r| g.contains(&r)).collect());
            pats.push((0..nr).map(|r| !g.contains(&r)).collect());
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..samples {
            let p: f64 = rng.random_range(0.1..0.9);
            pats.push((0..nr).map(|_| rng.random_bool(p)).collect());
        }
        let half_pi = std::f64::consts::FRAC_PI_2;
        let mut angles: Vec<Vec<f64>> = pats
            .iter()
            .map(|p| p.iter().map(|&c| if c { half_pi } else { 0.0 }).collect())
            .collect();
        for _ in 0..samples {
            angles.push((0..nr).map(|_| rng.random_range(0.0..half_pi)).collect());
        }
        let mut worst = (f64::NEG_INFINITY, Vec::new());
        for a in angles {
            let r = self.frozen_slope_radius(&a)?;
            if r > worst.0 {
                worst = (r, a);
            }
        }
        // A local ascent from the worst: each angle moved by ±π/8, then ±π/32.
        for step in [half_pi / 4.0, half_pi / 16.0] {
            for r in 0..nr {
                for sgn in [1.0, -1.0] {
                    let mut a = worst.1.clone();
                    a[r] = (a[r] + sgn * step).clamp(0.0, half_pi);
                    let v = self.frozen_slope_radius(&a)?;
                    if v > worst.0 {
                        worst = (v, a);
                    }
                }
            }
        }
        Ok(worst)
    }
}

/// The smallest ρ ∈ [0.05, 20] (relative 10⁻³, bisection in log ρ) at which `ok` holds, ok
/// being monotone in ρ; None if it fails at 20.
fn smallest_rho(ok: impl Fn(f64) -> bool) -> Option<f64> {
    let (mut lo, mut hi) = (0.05_f64, 20.0_f64);
    if !ok(hi) {
        return None;
    }
    if ok(lo) {
        return Some(lo);
    }
    while hi / lo > 1.0 + 1e-3 {
        let mid = (lo * hi).sqrt();
        if ok(mid) { hi = mid } else { lo = mid }
    }
    Some(hi)
}

/// Coordinate ascent of a level (φ, or 1/ρ) over groups of multipliers: from (`lam`,
/// `level`) with `ok(level, lam)`, try level·(1 + δ) with λ unchanged, then with each group
/// scaled by (1 + δ)^{±4}; accept the first that holds; halve δ after a sweep without gain.
/// Stops when `done(level)`, δ < tol, or the budget is spent. Returns (level, λ).
pub(super) fn ascend(
    mut lam: Vec<f64>,
    mut level: f64,
    groups: &[Range<usize>],
    search: &RowSearch,
    solves: &Cell<usize>,
    done: impl Fn(f64) -> bool,
    ok: impl Fn(f64, &[f64]) -> bool,
) -> (f64, Vec<f64>) {
    let mut delta = search.step;
    while delta >= search.tol && solves.get() < search.max_solves && !done(level) {
        let trial = level * (1.0 + delta);
        if ok(trial, &lam) {
            level = trial;
            continue;
        }
        let f = (1.0 + delta).powi(4);
        let mut gained = false;
        'sweep: for g in groups {
            for scale in [f, 1.0 / f] {
                let mut l = lam.clone();
                for v in &mut l[g.clone()] {
                    *v *= scale;
                }
                if ok(trial, &l) {
                    lam = l;
                    level = trial;
                    gained = true;
                    break 'sweep;
                }
                if solves.get() >= search.max_solves {
                    break 'sweep;
                }
            }
        }
        if !gained {
            delta /= 2.0;
        }
    }
    (level, lam)
}

#[cfg(test)]
mod tests {
    use closed_loop::scenario::{LoopOptions, Scenario};
    use qp_iter::Method;

    use super::super::global_loop;

    /// Σ_i of the per-row forms is σ₁ (MHE rows) and σ₃ (MPC rows): the scalar certificate is
    /// the per-row one with λ = τ·𝟙, so the per-row search starts from it exactly.
    #[test]
    fn row_forms_sum_to_the_scalar_forms() {
        let path = format!(
            "{}/../../scenarios/quadruple-tank.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        let r = Scenario::from_file(&path)
            .expect("parses")
            .resolve()
            .expect("resolves");
        let mut o = LoopOptions::from_scenario(r.scenario()).expect("options");
        o.method = Method::PG;
        let gl = global_loop(&r, &o).expect("builds");
        let (nm, nu) = gl.bounded_rows();
        assert!(nm > 0 && nu > 0, "both channels: {nm}, {nu}");
        let s3 = gl.sigma_mpc.as_ref().expect("an input bound");
        let nc = gl.n_zeta();
        for (range, sigma) in [(0..nm, &gl.sigma_mhe), (nm..nm + nu, s3)] {
            let mut sum = faer::Mat::<f64>::zeros(nc, nc);
            for r in range {
                super::super::add(&mut sum, &gl.row_form(r));
            }
            let scale = (0..nc)
                .flat_map(|i| (0..nc).map(move |j| (i, j)))
                .map(|(i, j)| sigma[(i, j)].abs())
                .fold(0.0_f64, f64::max);
            for i in 0..nc {
                for j in 0..nc {
                    let e = (sum[(i, j)] - sigma[(i, j)]).abs();
                    assert!(e <= 1e-9 * scale, "({i}, {j}): {e} vs scale {scale}");
                }
            }
        }
    }
}
