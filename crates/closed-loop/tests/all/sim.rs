//! Alg. 1 as a simulation: nominal convergence, K → ∞, determinism (and the helpers the
//! other `sim_*` modules share). The trace's protocol is in `sim_trace`, bad input and
//! failing runs in `sim_errors`.

use crate::build;
use closed_loop::scenario::Scenario;
use closed_loop::scenario::{ControllerChoice, LoopOptions};
use closed_loop::sim::ClosedLoop;
use faer::Mat;
use lti_model::LtiSystem;
use lti_model::disturbance::Disturbance;
use lti_model::spec::NoiseKind;
use mhe_core::{Estimator, MheEstimator, MheProblem, MheSets};
use mpc_core::{CondensedMpc, ExactMpc, SaturatedLqr};
use qp_iter::Method;
use qp_iter::pg::{ProjectedGradient, StepRule};
use qp_iter::reference::{ReferenceSettings, ReferenceSolver};

const CASE_STUDY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../scenarios/case-study.toml"
);

pub(crate) fn case_study() -> Scenario {
    Scenario::from_file(CASE_STUDY).unwrap()
}

pub(crate) fn options(s: &Scenario, k: usize, exact: bool) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(s).unwrap();
    o.method = Method::PG;
    o = o.with_iterations(k).expect("K is in range");
    o.exact_mhe_solve = exact;
    o.controller = ControllerChoice::ExactMpc;
    o
}

use lti_model::vecmath::dist2 as dist;

pub(crate) use lti_model::vecmath::norm2 as norm;

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
            ControllerChoice::suboptimal(10, Method::FISTA).unwrap(),
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

/// The case study's saturated LQR (a controller that needs no solve).
pub(crate) fn lqr(s: &Scenario) -> SaturatedLqr {
    let spec = s.mpc.as_ref().unwrap();
    SaturatedLqr::new(
        &s.plant,
        spec.q().as_ref(),
        spec.r().as_ref(),
        s.sets.input.clone(),
    )
    .unwrap()
}

/// A PG MHE (K = 3) for `sys` with the scenario's weights (identities if the sizes differ).
pub(crate) fn mhe_for(sys: &LtiSystem, s: &Scenario) -> MheEstimator<ProjectedGradient> {
    let mut cfg = s.mhe.as_ref().unwrap().config(&s.plant, false).unwrap();
    cfg.iterations = qp_iter::Iterations::new(3).unwrap();
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
