//! Fixtures: the case study (design.md §4), seeded random systems, and an independent
//! Clarabel solve of the *uncondensed* MPC (explicit states, equality constraints).

use faer::Mat;
use lti_model::{BoxSet, LtiSystem};
use mpc_core::{CondensedMpc, MpcConfig};
use qp_iter::reference::clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// The stand-in case-study plant of design.md §4.
pub fn case_study_system() -> LtiSystem {
    lti_model::presets::case_study_plant()
}

/// Case-study MPC config: N = 10, Q_c = I₄, R_c = 0.1·I₂, DARE terminal, u ∈ [−1, 1]².
pub fn case_study_config() -> MpcConfig {
    MpcConfig::new(
        10,
        Mat::identity(4, 4),
        Mat::<f64>::identity(2, 2) * 0.1,
        BoxSet::symmetric(&[1.0, 1.0]).unwrap(),
    )
}

pub fn case_study_mpc() -> CondensedMpc {
    CondensedMpc::new(&case_study_system(), case_study_config()).unwrap()
}

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

pub fn gaussian(rng: &mut ChaCha8Rng, n: usize, scale: f64) -> Vec<f64> {
    (0..n)
        .map(|_| scale * rng.sample::<f64, _>(StandardNormal))
        .collect()
}

fn gaussian_mat(rng: &mut ChaCha8Rng, r: usize, c: usize) -> Mat<f64> {
    Mat::from_fn(r, c, |_, _| rng.sample::<f64, _>(StandardNormal))
}

/// A random MPC problem: n_x ∈ 1..=4, n_u ∈ 1..=2, N ∈ 1..=6, A with spectral radius up to
/// ~1.3 (open-loop unstable allowed), Q_c = MᵀM + 0.1I, R_c = NᵀN + 0.05I, a random box
/// around 0 (one side possibly infinite).
pub fn random_problem(seed: u64) -> (LtiSystem, MpcConfig) {
    let mut r = rng(seed);
    let nx = r.random_range(1..=4);
    let nu = r.random_range(1..=2);
    let n = r.random_range(1..=6);
    let a = gaussian_mat(&mut r, nx, nx) * (0.4 + 0.5 * r.random::<f64>());
    let b = gaussian_mat(&mut r, nx, nu);
    let c = gaussian_mat(&mut r, 1, nx);
    let m = gaussian_mat(&mut r, nx, nx);
    let q = m.transpose() * &m + Mat::<f64>::identity(nx, nx) * 0.1;
    let k = gaussian_mat(&mut r, nu, nu);
    let rc = k.transpose() * &k + Mat::<f64>::identity(nu, nu) * 0.05;
    let lower: Vec<f64> = (0..nu)
        .map(|_| {
            if r.random::<f64>() < 0.15 {
                f64::NEG_INFINITY
            } else {
                -(0.2 + 2.0 * r.random::<f64>())
            }
        })
        .collect();
    let upper: Vec<f64> = (0..nu).map(|_| 0.2 + 2.0 * r.random::<f64>()).collect();
    let sys = LtiSystem::new(a, b, c).unwrap();
    (
        sys,
        MpcConfig::new(n, q, rc, BoxSet::new(lower, upper).unwrap()),
    )
}

/// CSC of a dense matrix (Clarabel's form; `upper_only` for P).
pub fn csc(
    m: &Mat<f64>,
    upper_only: bool,
) -> qp_iter::reference::clarabel::algebra::CscMatrix<f64> {
    qp_iter::reference::dense_to_csc(m.as_ref(), upper_only)
}

/// The uncondensed MPC as a QP in v = (x₀, …, x_N, u₀, …, u_{N−1}): cost ½vᵀPv, rows
/// Av (=, ≤) b — the equalities first, then one row per finite input bound.
struct UncondensedQp {
    pm: Mat<f64>,
    am: Mat<f64>,
    b: Vec<f64>,
    /// (variable, upper?, value) of each bound row, in row order after the equalities.
    bounds: Vec<(usize, bool, f64)>,
    /// Equality rows: x₀ = x̂ and the dynamics.
    neq: usize,
    /// Offset of u₀ in v.
    nvx: usize,
    /// Length of v.
    nv: usize,
}

fn uncondensed_qp(
    sys: &LtiSystem,
    q: &Mat<f64>,
    r: &Mat<f64>,
    p: &Mat<f64>,
    ubox: &BoxSet,
    n: usize,
    x_hat: &[f64],
) -> UncondensedQp {
    let (nx, nu) = (sys.nx(), sys.nu());
    let nvx = (n + 1) * nx;
    let nv = nvx + n * nu;
    let mut pm = Mat::<f64>::zeros(nv, nv);
    for k in 0..=n {
        let w = if k < n { q } else { p };
        for i in 0..nx {
            for j in 0..nx {
                pm[(k * nx + i, k * nx + j)] = 2.0 * w[(i, j)];
            }
        }
    }
    for k in 0..n {
        for i in 0..nu {
            for j in 0..nu {
                pm[(nvx + k * nu + i, nvx + k * nu + j)] = 2.0 * r[(i, j)];
            }
        }
    }
    // Equalities: x₀ = x̂; x_{k+1} − Ax_k − Bu_k = 0.
    let neq = (n + 1) * nx;
    let bounds: Vec<(usize, bool, f64)> = (0..n)
        .flat_map(|k| (0..nu).map(move |i| (k, i)))
        .flat_map(|(k, i)| {
            let v = nvx + k * nu + i;
            let mut rows = Vec::new();
            if ubox.upper()[i].is_finite() {
                rows.push((v, true, ubox.upper()[i]));
            }
            if ubox.lower()[i].is_finite() {
                rows.push((v, false, ubox.lower()[i]));
            }
            rows
        })
        .collect();
    let m = neq + bounds.len();
    let mut am = Mat::<f64>::zeros(m, nv);
    let mut b = vec![0.0; m];
    for i in 0..nx {
        am[(i, i)] = 1.0;
        b[i] = x_hat[i];
    }
    for k in 0..n {
        for i in 0..nx {
            let row = (k + 1) * nx + i;
            am[(row, (k + 1) * nx + i)] = 1.0;
            for j in 0..nx {
                am[(row, k * nx + j)] -= sys.a()[(i, j)];
            }
            for j in 0..nu {
                am[(row, nvx + k * nu + j)] -= sys.b()[(i, j)];
            }
        }
    }
    for (t, &(v, upper, val)) in bounds.iter().enumerate() {
        am[(neq + t, v)] = if upper { 1.0 } else { -1.0 };
        b[neq + t] = if upper { val } else { -val };
    }
    UncondensedQp {
        pm,
        am,
        b,
        bounds,
        neq,
        nvx,
        nv,
    }
}

/// Solves the uncondensed MPC with Clarabel directly: variables (x₀, …, x_N, u₀, …,
/// u_{N−1}), cost Σ_{k<N}(x_kᵀQ_cx_k + u_kᵀR_cu_k) + x_NᵀP_fx_N, equalities x₀ = x̂ and
/// x_{k+1} = Ax_k + Bu_k, bounds on u. Returns U* = (u₀, …, u_{N−1}).
pub fn uncondensed_solve(
    sys: &LtiSystem,
    q: &Mat<f64>,
    r: &Mat<f64>,
    p: &Mat<f64>,
    ubox: &BoxSet,
    n: usize,
    x_hat: &[f64],
) -> Vec<f64> {
    let qp = uncondensed_qp(sys, q, r, p, ubox, n, x_hat);
    let mut cones = vec![SupportedConeT::ZeroConeT(qp.neq)];
    if !qp.bounds.is_empty() {
        cones.push(SupportedConeT::NonnegativeConeT(qp.bounds.len()));
    }
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-12)
        .tol_gap_rel(1e-12)
        .tol_feas(1e-12)
        .max_iter(300)
        .build()
        .unwrap();
    let qv = vec![0.0; qp.nv];
    let mut solver = DefaultSolver::new(
        &csc(&qp.pm, true),
        &qv,
        &csc(&qp.am, false),
        &qp.b,
        &cones,
        settings,
    )
    .unwrap();
    solver.solve();
    assert!(
        matches!(
            solver.solution.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ),
        "uncondensed Clarabel: {:?}",
        solver.solution.status
    );
    let raw = &solver.solution.x;
    refine_on_active_set(
        &qp,
        raw,
        &solver.solution.s,
        &solver.solution.z,
        ubox,
        x_hat,
    )
    .unwrap_or_else(|| raw[qp.nvx..].to_vec())
}

/// Active-set refinement on the *uncondensed* KKT system (interior-point answers are
/// accurate to ~1e-9 relative to the state magnitudes, and worse at weakly active bounds):
/// a bound is active when its multiplier `zl` exceeds its slack `sl`; then solve
/// [P Aᵀ; A 0](v, λ) = (0, b) with A = equalities + active bounds, and return U only if
/// it is feasible, the bound multipliers have the right sign and it is close to `raw`.
fn refine_on_active_set(
    qp: &UncondensedQp,
    raw: &[f64],
    sl: &[f64],
    zl: &[f64],
    ubox: &BoxSet,
    x_hat: &[f64],
) -> Option<Vec<f64>> {
    let (nv, neq, nvx) = (qp.nv, qp.neq, qp.nvx);
    let nu = ubox.lower().len();
    let active: Vec<(usize, bool, f64)> = qp
        .bounds
        .iter()
        .enumerate()
        .filter(|(t, _)| zl[neq + t] > sl[neq + t])
        .map(|(_, &r)| r)
        .collect();
    let na = active.len();
    let dim = nv + neq + na;
    let mut kkt = Mat::<f64>::zeros(dim, dim);
    let mut rhs = Mat::<f64>::zeros(dim, 1);
    for i in 0..nv {
        for j in 0..nv {
            kkt[(i, j)] = qp.pm[(i, j)];
        }
    }
    for r in 0..neq {
        for j in 0..nv {
            kkt[(nv + r, j)] = qp.am[(r, j)];
            kkt[(j, nv + r)] = qp.am[(r, j)];
        }
        rhs[(nv + r, 0)] = qp.b[r];
    }
    for (t, &(v, _, val)) in active.iter().enumerate() {
        kkt[(nv + neq + t, v)] = 1.0;
        kkt[(v, nv + neq + t)] = 1.0;
        rhs[(nv + neq + t, 0)] = val;
    }
    let sol = faer::linalg::solvers::Solve::solve(&kkt.partial_piv_lu(), rhs);
    let refined: Vec<f64> = (0..nv).map(|i| sol[(i, 0)]).collect();
    let scale = 1.0
        + x_hat
            .iter()
            .chain(&refined)
            .map(|v| v.abs())
            .fold(0.0, f64::max);
    let feasible = (nvx..nv).all(|v| {
        let i = (v - nvx) % nu;
        refined[v] >= ubox.lower()[i] - 1e-12 * scale
            && refined[v] <= ubox.upper()[i] + 1e-12 * scale
    });
    // Stationarity Pv + Aᵀλ + Σ ν e_i = 0: ν ≥ 0 at an upper bound, ν ≤ 0 at a lower one.
    let signs = active.iter().enumerate().all(|(t, &(_, upper, _))| {
        let nu_t = sol[(nv + neq + t, 0)];
        if upper {
            nu_t >= -1e-9 * scale
        } else {
            nu_t <= 1e-9 * scale
        }
    });
    let close = max_abs_diff(&refined[nvx..], &raw[nvx..]) <= 1e-4 * scale;
    (feasible && signs && close).then(|| refined[nvx..].to_vec())
}

/// Solves the K-step discrete Riccati recursion from P = Q to a fixed point (independent
/// of lti-model's doubling DARE) and returns (K, P).
pub fn riccati_by_iteration(sys: &LtiSystem, q: &Mat<f64>, r: &Mat<f64>) -> (Mat<f64>, Mat<f64>) {
    use faer::linalg::solvers::DenseSolveCore;
    let (a, b) = (sys.a(), sys.b());
    let mut p = q.clone();
    let mut k = Mat::<f64>::zeros(sys.nu(), sys.nx());
    for _ in 0..20_000 {
        let s = r + b.transpose() * &p * b;
        let s_inv = s.partial_piv_lu().inverse();
        k = &s_inv * b.transpose() * &p * a;
        let next = q + a.transpose() * &p * a - a.transpose() * &p * b * &k;
        let diff = (&next - &p).norm_max();
        p = next;
        if diff <= 1e-14 * p.norm_max().max(1.0) {
            break;
        }
    }
    (k, p)
}

pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}
