//! Alg. 1 as a simulation: wiring, nominal convergence, K → ∞, determinism, bad input.

use crate::build;
use closed_loop::scenario::Scenario;
use closed_loop::scenario::{ControllerChoice, LoopOptions};
use closed_loop::sim::{ClosedLoop, ClosedLoopError};
use faer::{Mat, mat};
use lti_model::disturbance::{Disturbance, UniformBox, Zero};
use lti_model::spec::NoiseKind;
use lti_model::{BoxSet, LtiSystem};
use mhe_core::{Estimator, MheEstimator, MheProblem, MheSets};
use mpc_core::{CondensedMpc, Controller, ExactMpc, SaturatedLqr};
use qp_iter::Method;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};

const CASE_STUDY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../scenarios/case-study.toml"
);

fn case_study() -> Scenario {
    Scenario::from_file(CASE_STUDY).unwrap()
}

fn options(s: &Scenario, k: usize, exact: bool) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(s).unwrap();
    o.method = Method::PG;
    o.iterations = k;
    o.exact_mhe_solve = exact;
    o.controller = ControllerChoice::ExactMpc;
    o
}

use lti_model::vecmath::dist2 as dist;

use lti_model::vecmath::norm2 as norm;

/// y = M x for a faer matrix.
fn mul(m: faer::MatRef<'_, f64>, x: &[f64]) -> Vec<f64> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)] * x[j]).sum())
        .collect()
}

/// An exact MHE written independently of `MheEstimator`'s bookkeeping: the whole history
/// in plain vectors, ℙ_t solved by Clarabel (through `ReferenceSolver`) on the window QP of
/// `MheProblem`, x̂_{t|t} = X_z z* + X_θ θ, prior x̄₀ for t ≤ M and this estimator's own
/// x̂_{t−M} after (trap 1). The "exact estimator" of the paper's analysis (ε_t = 0).
#[derive(Debug)]
struct ExactMhe {
    problem: MheProblem,
    solvers: Vec<ReferenceSolver>,
    prior: Vec<f64>,
    u: Vec<Vec<f64>>,
    y: Vec<Vec<f64>>,
    estimates: Vec<Vec<f64>>,
    /// Per t: some ŵ* entry lies on a bound of 𝒲 (within 1e-9).
    active: Vec<bool>,
}

impl ExactMhe {
    fn new(s: &Scenario) -> Self {
        let cfg = s.mhe.as_ref().unwrap().config(&s.plant, false).unwrap();
        let problem = MheProblem::new(
            &s.plant,
            cfg.horizon,
            &cfg.weights(),
            &MheSets::from_scenario(&s.sets),
        )
        .unwrap();
        let settings = ReferenceSettings::default();
        let solvers = problem
            .windows()
            .iter()
            .map(|w| ReferenceSolver::new(w.qp(), settings).unwrap())
            .collect();
        Self {
            problem,
            solvers,
            prior: s.simulation.prior.clone(),
            u: Vec::new(),
            y: Vec::new(),
            estimates: Vec::new(),
            active: Vec::new(),
        }
    }

    /// θ_t = (prior, u_{t−m..t−1}, y_{t−m..t−1}).
    fn theta(&self, t: usize) -> (usize, Vec<f64>) {
        let big_m = self.problem.horizon();
        let m = t.min(big_m);
        let mut theta = if t <= big_m {
            self.prior.clone()
        } else {
            self.estimates[t - big_m].clone()
        };
        for j in t - m..t {
            theta.extend_from_slice(&self.u[j]);
        }
        for j in t - m..t {
            theta.extend_from_slice(&self.y[j]);
        }
        (m, theta)
    }
}

impl Estimator for ExactMhe {
    type Error = mhe_core::MheError;
    fn estimate(&mut self) -> mhe_core::Result<&[f64]> {
        let t = self.u.len();
        if self.estimates.len() == t {
            let (m, theta) = self.theta(t);
            let z = self.solvers[m].solve(&theta).unwrap().z;
            let w_set = &self.problem.sets().disturbance;
            let nx = self.problem.dims().nx;
            let nw = w_set.lower().len();
            let active = z[nx..].iter().enumerate().any(|(i, &v)| {
                let k = i % nw;
                v <= w_set.lower()[k] + 1e-9 || v >= w_set.upper()[k] - 1e-9
            });
            self.active.push(active);
            let (xz, xt) = self.problem.windows()[m].x_end_maps();
            let a = mul(xz, &z);
            let b = mul(xt, &theta);
            self.estimates
                .push(a.iter().zip(&b).map(|(p, q)| p + q).collect());
        }
        Ok(&self.estimates[t])
    }
    fn push(&mut self, u: &[f64], y: &[f64]) -> mhe_core::Result<()> {
        self.estimate()?;
        self.u.push(u.to_vec());
        self.y.push(y.to_vec());
        Ok(())
    }
    fn nx(&self) -> usize {
        self.problem.dims().nx
    }
}

fn exact_loop(s: &Scenario) -> ClosedLoop<ExactMhe, ExactMpc, Box<dyn Disturbance>> {
    let mpc = CondensedMpc::new(&s.plant, s.mpc.as_ref().unwrap().config(&s.sets)).unwrap();
    ClosedLoop::new(
        s.plant.clone(),
        ExactMhe::new(s),
        ExactMpc::new(&mpc).unwrap(),
        closed_loop::scenario::scenario_disturbance(s, s.noise.seed).unwrap(),
        &s.simulation.x0,
        s.simulation.steps,
    )
    .unwrap()
}

/// G_m with x̂_{t|t} − x_t = G_m (x^prior − x_{t−m}) when w ≡ 0 and no bound of 𝒲 is active.
///
/// Derivation: with w ≡ 0 and prior = x_{t−m}, the true trajectory (ŵ = 0 ∈ 𝒲) has cost 0,
/// and H_c ≻ 0 makes it the unique minimiser, so x̂ = x_t. Without active bounds
/// z*(θ) = −H_c⁻¹F_c θ, and x̂ = X_z z* + X_θ θ is linear in θ; changing only the prior by δ
/// changes x̂ by (X_θ − X_z H_c⁻¹F_c)[:, :n_x] δ = G_m δ.
fn prior_error_map(problem: &MheProblem, m: usize) -> Mat<f64> {
    let w = &problem.windows()[m];
    let nx = problem.dims().nx;
    let (xz, xt) = w.x_end_maps();
    let f = w.f_c();
    let fx = Mat::from_fn(f.nrows(), nx, |i, j| f[(i, j)]);
    let lu = w.h_c().to_owned().partial_piv_lu();
    let sol = faer::linalg::solvers::Solve::solve(&lu, &fx);
    Mat::from_fn(nx, nx, |i, j| xt[(i, j)]) - xz * sol
}

/// w ≡ 0, exact MHE, exact MPC on the case study (M = 5, η = 0.8).
///
/// What theory gives: the MHE estimate does *not* become exact once the window is full (the
/// prior term 2η^M‖x̂ − x^prior‖²_P pulls towards the MHE's own, wrong, old estimate), it
/// contracts: e_t = G_M e_{t−M} whenever no bound of 𝒲 is active at t (derivation at
/// [`prior_error_map`]). Prop. 3's sufficient condition 6η^M < 1 fails here (1.97), but
/// ‖G_5‖ < 1 is the exact criterion in that regime, so e_t → 0 geometrically. Then x̂_t → x_t,
/// and near the origin the MPC with DARE terminal cost is the LQR law (inputs unsaturated),
/// so x_{t+1} = (A − BK)x_t − BKe_t with ρ(A − BK) < 1 and x_t → 0 too.
#[test]
fn nominal_exact_mhe_and_mpc_converge() {
    let mut s = case_study();
    s.noise.kind = NoiseKind::Zero;
    let mut cl = exact_loop(&s);
    cl.run().unwrap();
    let tr = cl.trace();
    assert_eq!(tr.sup_norm_w(), 0.0);
    let big_m = cl.estimator().problem.horizon();
    let g = prior_error_map(&cl.estimator().problem, big_m);
    let g_norm = lti_model::matrix::spectral_norm(g.as_ref());
    assert!(g_norm < 1.0, "‖G_M‖ = {g_norm}");

    // The identity e_t = G_M e_{t−M} on every step without active bounds.
    let mut checked = 0;
    for t in big_m + 1..tr.len() {
        if cl.estimator().active[t] {
            continue;
        }
        let pred = mul(g.as_ref(), tr.e(t - big_m).unwrap());
        let err = dist(&pred, tr.e(t).unwrap());
        assert!(
            err <= 1e-7 * norm(tr.e(t - big_m).unwrap()) + 1e-12,
            "t = {t}: ‖e_t − G e_(t−M)‖ = {err:e}"
        );
        checked += 1;
    }
    assert!(checked >= 25, "only {checked} unconstrained steps");

    // Hence geometric decay: over the run at least ⌊(T − 1 − M)/M⌋ contractions by ‖G‖.
    let t_last = tr.len() - 1;
    let e0 = tr.e_norms()[0];
    assert!(
        tr.e_norms()[t_last] <= 1e-6 * e0,
        "‖e_T−1‖ = {:e}, ‖e_0‖ = {e0}",
        tr.e_norms()[t_last]
    );
    // x_t: strictly decreasing over the last quarter and ≤ 1e-4 ‖x_0‖ at T.
    let xn = tr.x_norms();
    for t in tr.len() * 3 / 4..tr.len() {
        assert!(xn[t + 1] < xn[t], "‖x‖ not decreasing at t = {t}");
    }
    assert!(xn[tr.len()] <= 1e-4 * xn[0], "‖x_T‖ = {:e}", xn[tr.len()]);

    // The same with the sub-optimal MHE at the paper's K = 652 (φ(652) = r^652 with
    // r ≈ 0.896 for PG on this problem, ≈ 1e-31: an exact MHE to rounding): same trajectory.
    let mut sub = build(&s, &options(&s, 652, false)).unwrap();
    let ts = sub.run().unwrap();
    for t in 0..tr.len() {
        assert!(dist(ts.e(t).unwrap(), tr.e(t).unwrap()) <= 1e-9, "t = {t}");
        assert!(
            dist(ts.x(t + 1).unwrap(), tr.x(t + 1).unwrap()) <= 1e-9,
            "t = {t}"
        );
    }
}

/// max_t of ‖x^K_t − x*_t‖, ‖x̂^K_t − x̂*_t‖, ‖u^K_t − u*_t‖ between a trace and the exact one.
fn gap(a: &closed_loop::Trace, b: &closed_loop::Trace) -> f64 {
    let mut g: f64 = 0.0;
    for t in 0..a.len() {
        g = g
            .max(dist(a.x(t + 1).unwrap(), b.x(t + 1).unwrap()))
            .max(dist(a.x_hat(t).unwrap(), b.x_hat(t).unwrap()))
            .max(dist(a.u(t).unwrap(), b.u(t).unwrap()));
    }
    g
}

/// K → ∞: the sub-optimal closed loop approaches the one with the exact MHE (same seed, so
/// the same w sequence; same exact MPC).
///
/// Tolerance at K = 2000: φ(2000) = r^2000 with r ≈ 0.896 (PG, step 2/(L + μ)) is below
/// 1e-90, so every zᴷ_t is the minimiser to rounding. The exact loop's z*_t comes from
/// Clarabel with an active-set polish accepted at a KKT residual ~1e-12, so per step the two
/// estimates differ by ~1e-12·‖z‖; the loop maps that through MPC and plant (gains of order
/// L_π‖B‖ and ‖G‖ < 1 per window), so 1e-9·(1 + sup‖x‖) leaves a margin of ≥ 100.
#[test]
fn suboptimal_trajectory_approaches_exact_as_k_grows() {
    let s = case_study();
    let mut ex = exact_loop(&s);
    let exact = ex.run().unwrap().clone();
    let tol = 1e-9 * (1.0 + exact.sup_norm_x());
    let ks = [20, 50, 100, 200, 2000];
    let gaps: Vec<f64> = ks
        .iter()
        .map(|&k| {
            let mut cl = build(&s, &options(&s, k, false)).unwrap();
            assert_eq!(cl.trace().steps(), s.simulation.steps);
            gap(cl.run().unwrap(), &exact)
        })
        .collect();
    for (i, w) in gaps.windows(2).enumerate() {
        assert!(
            w[1] < 0.5 * w[0] || w[1] <= tol,
            "gap did not shrink from K = {} ({:e}) to K = {} ({:e})",
            ks[i],
            w[0],
            ks[i + 1],
            w[1]
        );
    }
    assert!(
        gaps[0] > 1e3 * tol,
        "K = 20 should differ visibly: {:e}",
        gaps[0]
    );
    assert!(gaps[4] <= tol, "K = 2000: gap {:e} > {tol:e}", gaps[4]);
}

/// Same seed → identical trace; another seed → other w; `reseed` = a fresh build, bit for
/// bit, also with the exact MPC and the MHE's exact solve (warm-started active sets).
#[test]
fn same_seed_gives_identical_trace() {
    let s = case_study();
    for (controller, exact_mhe) in [
        (
            ControllerChoice::SuboptimalMpc {
                iterations: 10,
                method: Method::FISTA,
            },
            false,
        ),
        (ControllerChoice::ExactMpc, false),
        (ControllerChoice::ExactMpc, true),
    ] {
        let mut o = options(&s, 5, exact_mhe);
        o.controller = controller;
        let run = |o: &LoopOptions| {
            let mut cl = build(&s, o).unwrap();
            cl.run().unwrap().clone()
        };
        let a = run(&o);
        let b = run(&o);
        assert_eq!(a, b);
        assert_eq!(a.to_json().unwrap(), b.to_json().unwrap());
        let mut o2 = o;
        o2.seed += 1;
        let c = run(&o2);
        assert_ne!(a.w(0), c.w(0));

        let mut cl = build(&s, &o2).unwrap();
        cl.run().unwrap();
        cl.reseed(o.seed).unwrap();
        assert_eq!(cl.t(), 0);
        assert!(cl.trace().is_empty());
        assert_eq!(cl.run().unwrap(), &a, "{controller:?}");
    }
}

/// An estimator that returns x̂_t = (0.1 t, …) and logs the protocol.
#[derive(Debug, Default)]
struct Spy {
    nx: usize,
    x: Vec<f64>,
    pushes: Vec<(Vec<f64>, Vec<f64>)>,
    /// Number of pushes seen by each `estimate` call.
    seen: Vec<usize>,
}

impl Estimator for Spy {
    type Error = mhe_core::MheError;
    fn estimate(&mut self) -> mhe_core::Result<&[f64]> {
        self.seen.push(self.pushes.len());
        let t = self.pushes.len() as f64;
        self.x = vec![0.1 * t; self.nx];
        Ok(&self.x)
    }
    fn push(&mut self, u: &[f64], y: &[f64]) -> mhe_core::Result<()> {
        self.pushes.push((u.to_vec(), y.to_vec()));
        Ok(())
    }
    fn nx(&self) -> usize {
        self.nx
    }
}

fn lqr(s: &Scenario) -> SaturatedLqr {
    let spec = s.mpc.as_ref().unwrap();
    SaturatedLqr::new(
        &s.plant,
        spec.q().as_ref(),
        spec.r().as_ref(),
        s.sets.input.clone(),
    )
    .unwrap()
}

/// The order of Alg. 1 and eq. (1), recomputed from the trace with the matrices alone:
/// x̂_t from t pushes, u_t = π(x̂_t), y_t = C x_t + w²_t pushed after the estimate,
/// x_{t+1} = A x_t + B u_t + w¹_t, e_t = x̂_t − x_t, and the norms.
#[test]
fn trace_follows_alg1_and_eq1() {
    let s = case_study();
    let spy = Spy {
        nx: 4,
        ..Spy::default()
    };
    let w = UniformBox::from_box(&s.sets.disturbance, 3).unwrap();
    let mut cl = ClosedLoop::new(s.plant.clone(), spy, lqr(&s), w, &s.simulation.x0, 12).unwrap();
    cl.run().unwrap();
    let tr = cl.trace();
    let (a, b, c) = (s.plant.a(), s.plant.b(), s.plant.c());
    let mut pi = lqr(&s);
    let spy = cl.estimator();
    assert_eq!(spy.seen, (0..12).collect::<Vec<_>>());
    for t in 0..12 {
        let x = tr.x(t).unwrap();
        let u = tr.u(t).unwrap();
        let xh = tr.x_hat(t).unwrap();
        assert_eq!(xh, &[0.1 * t as f64; 4][..]);
        let mut u_ref = [0.0; 2];
        pi.control(xh, &mut u_ref).unwrap();
        assert_eq!(u, &u_ref[..]);
        let (w1, w2) = (tr.w1(t).unwrap(), tr.w2(t).unwrap());
        assert_eq!((w1.len(), w2.len()), (4, 1));
        assert!(tr.w(t).unwrap().iter().all(|v| v.abs() <= 0.1));
        let y_ref: f64 = (0..4).map(|j| c[(0, j)] * x[j]).sum::<f64>() + w2[0];
        assert!((tr.y(t).unwrap()[0] - y_ref).abs() <= 1e-14);
        let x_next = tr.x(t + 1).unwrap();
        for i in 0..4 {
            let r = (0..4).map(|j| a[(i, j)] * x[j]).sum::<f64>()
                + (0..2).map(|j| b[(i, j)] * u[j]).sum::<f64>()
                + w1[i];
            assert!((x_next[i] - r).abs() <= 1e-13, "t = {t}, i = {i}");
        }
        let e: Vec<f64> = xh.iter().zip(x).map(|(p, q)| p - q).collect();
        assert_eq!(tr.e(t).unwrap(), &e[..]);
        assert_eq!(tr.e_norms()[t], norm(&e));
        assert_eq!(tr.x_norms()[t], norm(x));
        assert_eq!(spy.pushes[t].0, u);
        assert_eq!(spy.pushes[t].1, tr.y(t).unwrap());
    }
    assert_eq!(cl.state(), tr.x(12).unwrap());
    assert!(tr.mhe().is_none() && tr.mhe_step(0).is_none());
    assert!(tr.epsilons().all(|e| e.is_none()));
}

/// The captured MHE record is the estimate's own, with the window and prior of Alg. 1
/// (trap 1: prior x̄₀ for t ≤ M, x̂_{t−M} after; trap 2: the window holds u, y of
/// t − M_t … t − 1), and ε_t is recorded when the exact solve is on.
#[test]
fn mhe_records_are_captured_with_alg1_window_and_prior() {
    let s = case_study();
    let mut cl = build(&s, &options(&s, 5, true)).unwrap();
    let tr = cl.run().unwrap();
    let big_m = 5;
    let mhe = tr.mhe().unwrap();
    assert_eq!((mhe.len(), mhe.max_window()), (tr.len(), big_m));
    for t in 0..tr.len() {
        let r = tr.mhe_step(t).unwrap();
        let m = t.min(big_m);
        assert_eq!((r.t(), r.window(), r.iterations()), (t, m, 5));
        assert_eq!(r.x_hat(), tr.x_hat(t).unwrap());
        let prior = if t <= big_m {
            &s.simulation.prior[..]
        } else {
            tr.x_hat(t - big_m).unwrap()
        };
        assert_eq!(r.prior(), prior, "t = {t}");
        for j in 0..m {
            assert_eq!(r.u(j).unwrap(), tr.u(t - m + j).unwrap());
            assert_eq!(r.y(j).unwrap(), tr.y(t - m + j).unwrap());
            assert!(r.w2_k(j).unwrap()[0].abs() <= 0.1);
        }
        assert!(r.u(m).is_none());
        let eps = r.epsilon().unwrap();
        assert!(eps <= r.initial_error().unwrap() + 1e-12);
        let xs = r.x_hat_exact().unwrap();
        assert_eq!(r.w_exact_flat().unwrap().len(), m * 5);
        assert!(xs.iter().all(|v| v.is_finite()));
    }
    // ε_t > 0 somewhere for K = 5 (it is the point of the record).
    assert!(tr.epsilons().flatten().any(|e| e > 1e-6));

    let v: serde_json::Value = serde_json::from_str(&tr.to_json().unwrap()).unwrap();
    let recs = v["records"].as_array().unwrap();
    assert_eq!(recs.len(), tr.len());
    assert_eq!(v["dims"]["nw1"], 4);
    let r6 = &recs[6];
    assert_eq!(r6["mhe"]["window"], 5);
    assert_eq!(r6["mhe"]["w_k"].as_array().unwrap().len(), 5);
    assert_eq!(
        r6["mhe"]["epsilon"].as_f64(),
        tr.mhe_step(6).unwrap().epsilon()
    );
    assert_eq!(r6["x_hat"][0].as_f64(), Some(tr.x_hat(6).unwrap()[0]));
    assert_eq!(v["summary"]["sup_norm_e"].as_f64(), Some(tr.sup_norm_e()));
}

/// The helpers against brute force over the accessors.
#[test]
fn trace_statistics_match_brute_force() {
    let s = case_study();
    let mut cl = build(&s, &options(&s, 20, false)).unwrap();
    let tr = cl.run().unwrap();
    let n = tr.len();
    let max = |f: &dyn Fn(usize) -> f64, r: std::ops::Range<usize>| r.map(f).fold(0.0, f64::max);
    assert_eq!(tr.sup_norm_e(), max(&|t| norm(tr.e(t).unwrap()), 0..n));
    assert_eq!(tr.sup_norm_x(), max(&|t| norm(tr.x(t).unwrap()), 0..n + 1));
    assert_eq!(tr.sup_norm_w(), max(&|t| norm(tr.w(t).unwrap()), 0..n));
    assert!(tr.sup_norm_w() <= 0.1 * 5f64.sqrt());
    // Last quarter of 40 steps: t = 30..39.
    let mean = |f: &dyn Fn(usize) -> f64| (30..40).map(f).sum::<f64>() / 10.0;
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs().max(1e-300);
    assert!(close(
        tr.tail_mean_e().unwrap(),
        mean(&|t| norm(tr.e(t).unwrap()))
    ));
    assert!(close(
        tr.tail_mean_x().unwrap(),
        mean(&|t| norm(tr.x(t).unwrap()))
    ));
    assert!(close(
        tr.tail_mean_w().unwrap(),
        mean(&|t| norm(tr.w(t).unwrap()))
    ));
    assert_eq!(tr.tail_mean_epsilon(), None); // exact solve off
    assert_eq!(tr.x(n + 1), None);
    assert_eq!(tr.u(n), None);
}

fn mhe_for(sys: &LtiSystem, s: &Scenario) -> MheEstimator<ProjectedGradient> {
    let mut cfg = s.mhe.as_ref().unwrap().config(&s.plant, false).unwrap();
    cfg.iterations = 3;
    if (sys.nx(), sys.ny()) != (s.plant.nx(), s.plant.ny()) {
        cfg.p = Mat::identity(sys.nx(), sys.nx());
        cfg.q = Mat::identity(sys.nw(), sys.nw());
        cfg.r = Mat::identity(sys.ny(), sys.ny());
    }
    MheEstimator::new(
        sys,
        &MheSets::unconstrained(sys),
        &cfg,
        &vec![0.0; sys.nx()],
        |qp| ProjectedGradient::new(qp, StepRule::Optimal),
    )
    .unwrap()
}

fn dim_err(e: ClosedLoopError) -> (&'static str, usize, usize) {
    match e {
        ClosedLoopError::Dimension {
            what,
            expected,
            actual,
        } => (what, expected, actual),
        other => panic!("expected a dimension error, got {other}"),
    }
}

/// T = 0, mismatched dimensions, bad options: typed errors at construction.
#[test]
fn bad_input_gives_typed_errors() {
    let s = case_study();
    let p = || s.plant.clone();
    let x0 = &s.simulation.x0[..];
    let new = |est, ctrl: SaturatedLqr, d: Box<dyn Disturbance>, x0: &[f64], steps| {
        ClosedLoop::new(p(), est, ctrl, d, x0, steps).map(|_| ())
    };
    let zero = || -> Box<dyn Disturbance> { Box::new(Zero(5)) };
    assert_eq!(
        new(mhe_for(&p(), &s), lqr(&s), zero(), x0, 0),
        Err(ClosedLoopError::ZeroSteps)
    );
    assert_eq!(
        dim_err(new(mhe_for(&p(), &s), lqr(&s), zero(), &x0[..3], 5).unwrap_err()),
        ("x0 length", 4, 3)
    );
    assert!(matches!(
        new(
            mhe_for(&p(), &s),
            lqr(&s),
            zero(),
            &[0.0, f64::NAN, 0.0, 0.0],
            5
        ),
        Err(ClosedLoopError::NonFiniteInitialState { index: 1, .. })
    ));
    let small = LtiSystem::new(
        mat![[0.5, 0.0], [0.0, 0.5]],
        mat![[1.0], [0.0]],
        mat![[1.0, 0.0]],
    )
    .unwrap();
    assert_eq!(
        dim_err(new(mhe_for(&small, &s), lqr(&s), zero(), x0, 5).unwrap_err()),
        ("estimator n_x", 4, 2)
    );
    let lqr1 =
        SaturatedLqr::from_gain(Mat::zeros(1, 4), BoxSet::symmetric(&[1.0]).unwrap()).unwrap();
    assert_eq!(
        dim_err(new(mhe_for(&p(), &s), lqr1, zero(), x0, 5).unwrap_err()),
        ("controller n_u", 2, 1)
    );
    let lqr_x3 =
        SaturatedLqr::from_gain(Mat::zeros(2, 3), BoxSet::symmetric(&[1.0; 2]).unwrap()).unwrap();
    assert_eq!(
        dim_err(new(mhe_for(&p(), &s), lqr_x3, zero(), x0, 5).unwrap_err()),
        ("controller n_x", 4, 3)
    );
    let (what, e, a) =
        dim_err(new(mhe_for(&p(), &s), lqr(&s), Box::new(Zero(4)), x0, 5).unwrap_err());
    assert_eq!((what.starts_with("disturbance dim"), e, a), (true, 5, 4));
    // An MHE for a plant with the same n_x but one input: caught through its record.
    let one_input = LtiSystem::new(
        s.plant.a().to_owned(),
        Mat::from_fn(4, 1, |i, _| s.plant.b()[(i, 0)]),
        s.plant.c().to_owned(),
    )
    .unwrap();
    let err =
        ClosedLoop::new_mhe(p(), mhe_for(&one_input, &s), lqr(&s), Zero(5), x0, 5).unwrap_err();
    assert_eq!(dim_err(err), ("MHE record n_u", 2, 1));

    // Builder options.
    // K = 0 is refused once, by the estimator that defines K (`MheEstimator`).
    let mut o = options(&s, 0, false);
    assert!(matches!(
        build(&s, &o),
        Err(ClosedLoopError::Mhe(mhe_core::MheError::OutOfRange {
            name: "iterations",
            ..
        }))
    ));
    o.iterations = 5;
    o.steps = 0;
    assert!(matches!(build(&s, &o), Err(ClosedLoopError::ZeroSteps)));
    o.steps = 40;
    o.controller = ControllerChoice::SuboptimalMpc {
        iterations: 0,
        method: Method::PG,
    };
    assert!(matches!(
        build(&s, &o),
        Err(ClosedLoopError::OutOfRange {
            name: "controller iterations",
            ..
        })
    ));
    o.controller = ControllerChoice::SaturatedLqr;
    let mut no_mpc = s.clone();
    no_mpc.mpc = None;
    assert_eq!(
        build(&no_mpc, &o).map(|_| ()),
        Err(ClosedLoopError::MissingSection { section: "mpc" })
    );
    let mut no_mhe = s.clone();
    no_mhe.mhe = None;
    assert_eq!(
        LoopOptions::from_scenario(&no_mhe),
        Err(ClosedLoopError::MissingSection { section: "mhe" })
    );
    assert_eq!(
        build(&no_mhe, &o).map(|_| ()),
        Err(ClosedLoopError::MissingSection { section: "mhe" })
    );
    let mut unbounded = s.clone();
    unbounded.sets.disturbance = BoxSet::whole(5);
    let err = build(&unbounded, &o).map(|_| ()).unwrap_err();
    assert!(err.to_string().contains("`W`"), "{err}");
    assert!(matches!(
        "newton".parse::<Method>(),
        Err(qp_iter::QpError::UnknownMethod { ref name, ref known })
            if name == "newton" && known.contains("\"admm-pr\"")
    ));
    for name in ["pg", "fista", "admm", "admm-pr"] {
        assert_eq!(name.parse::<Method>().unwrap().name(), name);
    }

    // MHE records: only before the first step, and only windows that fit.
    let mut cl = ClosedLoop::new(p(), mhe_for(&p(), &s), lqr(&s), Zero(5), x0, 8).unwrap();
    cl.step().unwrap();
    assert_eq!(
        cl.with_mhe_records(closed_loop::sim::mhe_record_hook, 5)
            .map(|_| ()),
        Err(ClosedLoopError::AlreadyStarted { t: 1 })
    );
    let mut cl = ClosedLoop::new(p(), mhe_for(&p(), &s), lqr(&s), Zero(5), x0, 8)
        .unwrap()
        .with_mhe_records(closed_loop::sim::mhe_record_hook, 2)
        .unwrap();
    assert_eq!(
        cl.run().map(|_| ()),
        Err(ClosedLoopError::RecordCapacity {
            t: 3,
            window: 3,
            capacity: 2
        })
    );
    assert_eq!(cl.trace().len(), 3);
}

/// An estimator that misbehaves at a given step.
#[derive(Debug)]
struct Faulty {
    t: usize,
    at: usize,
    len: usize,
    x: Vec<f64>,
}

impl Estimator for Faulty {
    type Error = mhe_core::MheError;
    fn estimate(&mut self) -> mhe_core::Result<&[f64]> {
        self.x = vec![0.0; if self.t == self.at { self.len } else { 4 }];
        if self.t == self.at && self.len == 4 {
            self.x[2] = f64::NAN;
        }
        Ok(&self.x)
    }
    fn push(&mut self, _u: &[f64], _y: &[f64]) -> mhe_core::Result<()> {
        self.t += 1;
        Ok(())
    }
    fn nx(&self) -> usize {
        4
    }
}

/// Step errors name the step and the cause, and stop the loop; the trace keeps the steps
/// before.
#[test]
fn step_errors_name_the_step_and_stop_the_loop() {
    let s = case_study();
    let x0 = &s.simulation.x0[..];
    let faulty = |at, len| Faulty {
        t: 0,
        at,
        len,
        x: Vec::new(),
    };
    let mut cl = ClosedLoop::new(s.plant.clone(), faulty(3, 4), lqr(&s), Zero(5), x0, 10).unwrap();
    let err = cl.run().unwrap_err();
    assert!(matches!(
        err,
        ClosedLoopError::NonFinite {
            t: 3,
            name: "x_hat",
            index: 2,
            ..
        }
    ));
    assert!(err.to_string().contains("t = 3"), "{err}");
    assert_eq!(cl.trace().len(), 3);
    assert_eq!(cl.step(), Err(ClosedLoopError::Stopped { t: 3 }));
    assert_eq!(cl.run().map(|_| ()), Err(ClosedLoopError::Stopped { t: 3 }));

    let mut cl = ClosedLoop::new(s.plant.clone(), faulty(1, 3), lqr(&s), Zero(5), x0, 10).unwrap();
    assert_eq!(
        cl.run().map(|_| ()),
        Err(ClosedLoopError::EstimateLength {
            t: 1,
            expected: 4,
            actual: 3
        })
    );

    // The estimator's own error (wrong n_y at push, a user estimator) names the step.
    let other_c = LtiSystem::new(
        s.plant.a().to_owned(),
        s.plant.b().to_owned(),
        mat![[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]],
    )
    .unwrap();
    let est = mhe_for(&other_c, &s); // n_x = 4, n_u = 2, but n_y = 2
    let mut cl = ClosedLoop::new(s.plant.clone(), est, lqr(&s), Zero(5), x0, 4).unwrap();
    let err = cl.run().unwrap_err();
    assert!(
        matches!(err, ClosedLoopError::Estimator { t: 0, .. }),
        "{err}"
    );

    // A diverging plant is reported, not recorded as finite.
    let unstable = LtiSystem::new(
        Mat::from_fn(4, 4, |i, j| if i == j { 1e308 } else { 0.0 }),
        Mat::zeros(4, 2),
        s.plant.c().to_owned(),
    )
    .unwrap();
    let mut cl = ClosedLoop::new(unstable, faulty(99, 4), lqr(&s), Zero(5), &[10.0; 4], 5).unwrap();
    assert!(matches!(
        cl.run(),
        Err(ClosedLoopError::NonFinite {
            t: 0,
            name: "y" | "x_next",
            ..
        })
    ));

    // Running past T.
    let mut cl = ClosedLoop::new(s.plant.clone(), faulty(99, 4), lqr(&s), Zero(5), x0, 2).unwrap();
    assert_eq!(cl.run().unwrap().len(), 2);
    assert!(cl.is_finished());
    assert_eq!(cl.step(), Err(ClosedLoopError::Finished { steps: 2 }));
    assert_eq!(cl.run().unwrap().len(), 2);
}

/// A controller that fails at a given call.
#[derive(Debug)]
struct FailingController {
    calls: usize,
    at: usize,
}

impl Controller for FailingController {
    type Error = mpc_core::MpcError;
    fn control(&mut self, _x_hat: &[f64], u: &mut [f64]) -> mpc_core::Result<()> {
        self.calls += 1;
        if self.calls > self.at {
            return Err(mpc_core::MpcError::NonFiniteIterate);
        }
        u.fill(0.0);
        Ok(())
    }
    fn nu(&self) -> usize {
        2
    }
    fn nx(&self) -> usize {
        4
    }
}

/// A controller error names the step; the failing step's MHE record is kept for diagnosis
/// but is not part of the trace's steps.
#[test]
fn controller_error_keeps_the_failing_steps_mhe_record() {
    let s = case_study();
    let ctrl = FailingController { calls: 0, at: 2 };
    let mut cl = ClosedLoop::new_mhe(
        s.plant.clone(),
        mhe_for(&s.plant, &s),
        ctrl,
        Zero(5),
        &s.simulation.x0,
        6,
    )
    .unwrap();
    let err = cl.run().unwrap_err();
    assert_eq!(
        err,
        ClosedLoopError::Controller {
            t: 2,
            source: closed_loop::sim::ComponentError::new(mpc_core::MpcError::NonFiniteIterate)
        }
    );
    let tr = cl.trace();
    assert_eq!(tr.len(), 2);
    assert!(tr.mhe_step(2).is_none());
    let mhe = tr.mhe().unwrap();
    assert_eq!(mhe.len(), 3);
    assert_eq!(mhe.step(2).unwrap().window(), 2);
    let v: serde_json::Value = serde_json::from_str(&tr.to_json().unwrap()).unwrap();
    assert_eq!(v["records"].as_array().unwrap().len(), 2);
}

/// A run whose state grows geometrically (finite entries, but beyond 1e154 their squares
/// overflow and every norm is +∞) stops with an error naming the signal and the step, and
/// the trace before it keeps finite norms (issue: "sup_x = inf" with an empty error).
#[test]
fn a_run_whose_norms_would_overflow_stops_as_diverged_naming_t() {
    let s = case_study();
    let growing = LtiSystem::new(
        Mat::from_fn(4, 4, |i, j| if i == j { 1e10 } else { 0.0 }),
        Mat::zeros(4, 2),
        s.plant.c().to_owned(),
    )
    .unwrap();
    let est = Faulty {
        t: 0,
        at: 999,
        len: 4,
        x: Vec::new(),
    };
    let mut cl = ClosedLoop::new(growing, est, lqr(&s), Zero(5), &[1.0; 4], 40).unwrap();
    let err = cl.run().unwrap_err();
    // x_t = 1e10ᵗ: x_16 = 1e160 ≥ 1e154 is produced at step t = 15.
    match &err {
        &ClosedLoopError::NonFinite { t, name, value, .. } => {
            assert_eq!((t, name), (15, "x_next"), "{err}");
            assert!(value.is_finite() && value >= closed_loop::sim::DIVERGED_MAGNITUDE);
        }
        other => panic!("{other}"),
    }
    assert!(err.to_string().contains("diverged at t = 15"), "{err}");
    let tr = cl.trace();
    assert_eq!(tr.len(), 15);
    assert!(tr.sup_norm_x().is_finite());
}

/// The sweep's bounded rule covers the estimation error: an estimator that diverges while
/// the saturated input keeps x bounded is not "bounded".
#[test]
fn a_diverging_estimator_with_bounded_state_is_not_bounded() {
    /// x̂ doubles every step, whatever the data.
    #[derive(Debug)]
    struct Doubling(Vec<f64>);
    impl Estimator for Doubling {
        type Error = std::convert::Infallible;
        fn estimate(&mut self) -> Result<&[f64], Self::Error> {
            Ok(&self.0)
        }
        fn push(&mut self, _u: &[f64], _y: &[f64]) -> Result<(), Self::Error> {
            self.0.iter_mut().for_each(|v| *v *= 2.0);
            Ok(())
        }
        fn nx(&self) -> usize {
            self.0.len()
        }
    }
    let s = case_study();
    let x0 = &s.simulation.x0;
    let run = |est: Doubling| {
        let mut cl = ClosedLoop::new(s.plant.clone(), est, lqr(&s), Zero(5), x0, 40).unwrap();
        cl.run().unwrap().clone()
    };
    let input = (s.sets.input.lower(), s.sets.input.upper());
    // x̂ = 2ᵗ·1: ‖e‖ reaches ~1e12 while |u| ≤ 1 keeps the stable plant's x bounded.
    let diverging = run(Doubling(vec![1.0; 4]));
    assert!(diverging.sup_norm_x() < 1e3 * (1.0 + norm(x0)));
    let (_, bounded) = closed_loop::metrics::run_metrics(&diverging, x0, input, 1e3, None);
    assert!(!bounded, "sup ‖e‖ = {}", diverging.sup_norm_e());
    // The same loop with a sane estimate is bounded.
    let sane = run(Doubling(vec![0.0; 4]));
    let (_, bounded) = closed_loop::metrics::run_metrics(&sane, x0, input, 1e3, None);
    assert!(bounded);
}
