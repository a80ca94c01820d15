//! (a) The exact MHE solution (condensed QP, z* from the reference solver) equals an
//! independent solve: Clarabel on the *uncondensed* problem (8) with explicit state,
//! disturbance and output variables and the model as equality constraints.

use faer::Mat;
use mhe_core::{MheEstimator, MheRecord};
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::reference::clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus,
    SupportedConeT, ZeroConeT,
};

use crate::common::{Fixture, case_study, csc, random_fixture, simulate};

/// Index layout of v = (x̂₀..x̂_m, ŵ₀..ŵ_{m−1}, ŷ₀..ŷ_{m−1}) for window length m.
#[derive(Clone, Copy)]
struct Layout {
    nx: usize,
    nw: usize,
    ny: usize,
    m: usize,
}

impl Layout {
    fn xi(self, j: usize) -> usize {
        j * self.nx
    }
    fn wi(self, j: usize) -> usize {
        (self.m + 1) * self.nx + j * self.nw
    }
    fn yi(self, j: usize) -> usize {
        (self.m + 1) * self.nx + self.m * self.nw + j * self.ny
    }
    fn n(self) -> usize {
        (self.m + 1) * self.nx + self.m * (self.nw + self.ny)
    }
}

/// The cost (9) as ½vᵀHv + qᵀv + const.
fn cost(f: &Fixture, rec: &MheRecord, l: Layout) -> (Mat<f64>, Vec<f64>, f64) {
    let (nx, nw, ny, m) = (l.nx, l.nw, l.ny, l.m);
    let cfg = &f.config;
    let (xi, wi, yi) = (|j| l.xi(j), |j| l.wi(j), |j| l.yi(j));
    let n = l.n();
    let mut h = Mat::<f64>::zeros(n, n);
    let mut q = vec![0.0; n];
    let mut konst = 0.0;
    let etam = cfg.eta.powi(m as i32);
    let p = rec.prior();
    for i in 0..nx {
        for k in 0..nx {
            h[(xi(0) + i, xi(0) + k)] += 4.0 * etam * cfg.p[(i, k)];
            q[xi(0) + i] -= 4.0 * etam * cfg.p[(i, k)] * p[k];
            konst += 2.0 * etam * p[i] * cfg.p[(i, k)] * p[k];
        }
    }
    for j in 0..m {
        let d = cfg.eta.powi((m - 1 - j) as i32);
        let y = rec.y(j).unwrap();
        for i in 0..nw {
            for k in 0..nw {
                h[(wi(j) + i, wi(j) + k)] += 4.0 * d * cfg.q[(i, k)];
            }
        }
        for i in 0..ny {
            for k in 0..ny {
                h[(yi(j) + i, yi(j) + k)] += 2.0 * d * cfg.r[(i, k)];
                q[yi(j) + i] -= 2.0 * d * cfg.r[(i, k)] * y[k];
                konst += d * y[i] * cfg.r[(i, k)] * y[k];
            }
        }
    }
    (h, q, konst)
}

/// The model as equality rows (the first `neq`) and the disturbance box as rows Av ≤ b.
fn constraint_rows(f: &Fixture, rec: &MheRecord, l: Layout) -> (Mat<f64>, Vec<f64>, usize, usize) {
    let sys = &f.sys;
    let (nx, ny, nw1, nw2) = (sys.nx(), sys.ny(), sys.nw1(), sys.nw2());
    let (nw, m, n) = (l.nw, l.m, l.n());
    let (xi, wi, yi) = (|j| l.xi(j), |j| l.wi(j), |j| l.yi(j));
    // Equalities: x̂_{j+1} − A x̂_j − E ŵ¹_j = B u_j;  ŷ_j − C x̂_j − F ŵ²_j = 0.
    let neq = m * (nx + ny);
    let lo = f.sets.disturbance.lower();
    let up = f.sets.disturbance.upper();
    let nbox: usize = m
        * (lo.iter().filter(|v| v.is_finite()).count()
            + up.iter().filter(|v| v.is_finite()).count());
    let mut a = Mat::<f64>::zeros(neq + nbox, n);
    let mut b = vec![0.0; neq + nbox];
    for j in 0..m {
        let r0 = j * (nx + ny);
        let u = rec.u(j).unwrap();
        for i in 0..nx {
            a[(r0 + i, xi(j + 1) + i)] = 1.0;
            for k in 0..nx {
                a[(r0 + i, xi(j) + k)] = -sys.a()[(i, k)];
            }
            for k in 0..nw1 {
                a[(r0 + i, wi(j) + k)] = -sys.e()[(i, k)];
            }
            b[r0 + i] = (0..sys.nu()).map(|k| sys.b()[(i, k)] * u[k]).sum();
        }
        for i in 0..ny {
            a[(r0 + nx + i, yi(j) + i)] = 1.0;
            for k in 0..nx {
                a[(r0 + nx + i, xi(j) + k)] = -sys.c()[(i, k)];
            }
            for k in 0..nw2 {
                a[(r0 + nx + i, wi(j) + nw1 + k)] = -sys.f()[(i, k)];
            }
        }
    }
    let mut r = neq;
    for j in 0..m {
        for i in 0..nw {
            if up[i].is_finite() {
                a[(r, wi(j) + i)] = 1.0;
                b[r] = up[i];
                r += 1;
            }
            if lo[i].is_finite() {
                a[(r, wi(j) + i)] = -1.0;
                b[r] = -lo[i];
                r += 1;
            }
        }
    }
    (a, b, neq, nbox)
}

/// Solution of problem (8)–(9) with variables (x̂₀..x̂_m, ŵ₀..ŵ_{m−1}, ŷ₀..ŷ_{m−1}):
/// returns (x̂ sequence, ŵ sequence, optimal V_MHE).
fn uncondensed(f: &Fixture, rec: &MheRecord) -> (Vec<Vec<f64>>, Vec<Vec<f64>>, f64) {
    let sys = &f.sys;
    let l = Layout {
        nx: sys.nx(),
        nw: sys.nw1() + sys.nw2(),
        ny: sys.ny(),
        m: rec.window,
    };
    let (nx, nw, m, n) = (l.nx, l.nw, l.m, l.n());
    let (xi, wi) = (|j| l.xi(j), |j| l.wi(j));
    let (h, q, konst) = cost(f, rec, l);
    let (a, b, neq, nbox) = constraint_rows(f, rec, l);
    let mut cones: Vec<SupportedConeT<f64>> = Vec::new();
    if neq > 0 {
        cones.push(ZeroConeT(neq));
    }
    if nbox > 0 {
        cones.push(NonnegativeConeT(nbox));
    }
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-12)
        .tol_gap_rel(1e-12)
        .tol_feas(1e-12)
        .max_iter(500)
        .build()
        .unwrap();
    let mut solver =
        DefaultSolver::new(&csc(&h, true), &q, &csc(&a, false), &b, &cones, settings).unwrap();
    solver.solve();
    let st = solver.solution.status;
    assert!(
        matches!(st, SolverStatus::Solved | SolverStatus::AlmostSolved),
        "uncondensed Clarabel: {st:?}"
    );
    let v = polish(
        &h,
        &q,
        &a,
        &b,
        neq,
        &solver.solution.x,
        &solver.solution.s,
        &solver.solution.z,
    );
    let v = &v;
    let xs = (0..=m).map(|j| v[xi(j)..xi(j) + nx].to_vec()).collect();
    let ws = (0..m).map(|j| v[wi(j)..wi(j) + nw].to_vec()).collect();
    // V = ½vᵀHv + qᵀv + const.
    let mut val = konst;
    for i in 0..n {
        val += q[i] * v[i];
        for k in 0..n {
            val += 0.5 * v[i] * h[(i, k)] * v[k];
        }
    }
    (xs, ws, val)
}

/// Active-set refinement of the interior-point point on the *uncondensed* problem: the
/// box rows with multiplier > slack are taken as equalities and the KKT system
/// [[H, Aᵀ], [A, 0]] (v, λ) = (−q, b) is solved densely. The result is kept only if the
/// inactive rows are satisfied and the active multipliers are ≥ 0 (otherwise the raw
/// interior-point point is returned). Independent of the condensed formulation.
fn polish(
    h: &Mat<f64>,
    q: &[f64],
    a: &Mat<f64>,
    b: &[f64],
    neq: usize,
    x: &[f64],
    s: &[f64],
    z: &[f64],
) -> Vec<f64> {
    use faer::linalg::solvers::Solve;
    let n = h.nrows();
    let rows: Vec<usize> = (0..a.nrows()).filter(|&r| r < neq || z[r] > s[r]).collect();
    let k = rows.len();
    let kkt = Mat::from_fn(n + k, n + k, |i, j| match (i < n, j < n) {
        (true, true) => h[(i, j)],
        (true, false) => a[(rows[j - n], i)],
        (false, true) => a[(rows[i - n], j)],
        (false, false) => 0.0,
    });
    let rhs = Mat::from_fn(n + k, 1, |i, _| if i < n { -q[i] } else { b[rows[i - n]] });
    let sol = kkt.partial_piv_lu().solve(&rhs);
    let v: Vec<f64> = (0..n).map(|i| sol[(i, 0)]).collect();
    let scale = v.iter().fold(1.0_f64, |m, x| m.max(x.abs()));
    let ok_mult = (0..k).all(|i| rows[i] < neq || sol[(n + i, 0)] >= -1e-9);
    let ok_rows = (neq..a.nrows()).all(|r| {
        let av: f64 = (0..n).map(|j| a[(r, j)] * v[j]).sum();
        av <= b[r] + 1e-10 * scale
    });
    if ok_mult && ok_rows && v.iter().all(|x| x.is_finite()) {
        v
    } else {
        x.to_vec()
    }
}

/// Runs the estimator with the exact solve on and compares every step's z* with the
/// uncondensed solution. Returns (worst difference, number of steps with an active bound).
fn check(f: &Fixture, steps: usize, seed: u64) -> (f64, usize) {
    let (us, ys, _) = simulate(f, steps, seed);
    let mut mhe = MheEstimator::new(&f.sys, &f.sets, &f.config, &f.prior, |qp| {
        ProjectedGradient::new(qp, StepRule::Optimal)
    })
    .unwrap();
    let mut worst = 0.0_f64;
    let mut active = 0;
    let lo = f.sets.disturbance.lower();
    let up = f.sets.disturbance.upper();
    for t in 0..steps {
        mhe.estimate().unwrap();
        let rec = mhe.last_record();
        let (xs, ws, val) = uncondensed(f, rec);
        let scale = |v: &[f64]| v.iter().fold(1.0_f64, |s, x| s.max(x.abs()));
        let mut d = crate::common::dist(rec.x_start_exact().unwrap(), &xs[0]) / scale(&xs[0]);
        for (j, w) in ws.iter().enumerate() {
            d = d.max(crate::common::dist(rec.w_exact(j).unwrap(), w) / scale(w));
            if w.iter()
                .zip(lo.iter().zip(up))
                .any(|(v, (l, u))| (v - l).abs() < 1e-6 || (v - u).abs() < 1e-6)
            {
                active += 1;
            }
        }
        let xm = &xs[rec.window];
        d = d.max(crate::common::dist(rec.x_hat_exact().unwrap(), xm) / scale(xm));
        let dv = (rec.cost_exact.unwrap() - val).abs() / val.abs().max(1.0);
        assert!(
            d < 1e-7,
            "t = {t}: condensed vs uncondensed z* differ by {d:e}"
        );
        assert!(
            dv < 1e-7,
            "t = {t}: V_MHE(z*) {} vs uncondensed {val}",
            rec.cost_exact.unwrap()
        );
        worst = worst.max(d);
        mhe.push(&us[t], &ys[t]).unwrap();
    }
    (worst, active)
}

#[test]
fn case_study_exact_matches_uncondensed_clarabel() {
    let f = case_study(5, 10, true);
    // t = 0..13 covers t < M, t = M and t > M (prior from the ring buffer).
    let (worst, active) = check(&f, 14, 1);
    assert!(
        active > 0,
        "no bound of 𝒲 active: the test would not exercise the box"
    );
    println!(
        "case study: worst relative difference {worst:e}, {active} stages with an active bound"
    );
}

#[test]
fn random_systems_exact_match_uncondensed_clarabel() {
    let mut active_total = 0;
    for seed in 0..8 {
        let horizon = 1 + (seed as usize % 4);
        let f = random_fixture(100 + seed, horizon, 5, true);
        let (worst, active) = check(&f, 2 * horizon + 3, seed);
        active_total += active;
        println!(
            "seed {seed}: nx {} nu {} ny {} nw1 {} nw2 {} M {horizon}: worst {worst:e}, active {active}",
            f.sys.nx(),
            f.sys.nu(),
            f.sys.ny(),
            f.sys.nw1(),
            f.sys.nw2()
        );
    }
    assert!(active_total > 0);
}
