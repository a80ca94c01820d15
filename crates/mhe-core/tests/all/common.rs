//! Fixtures: the case study (design.md §4), random detectable systems, simulated data.

use faer::{Mat, mat};
use lti_model::{BoxSet, LtiSystem};
use mhe_core::{MheConfig, MheSets};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// K as the typed budget (test values are ≥ 1).
pub fn k(n: usize) -> qp_iter::Iterations {
    qp_iter::Iterations::new(n).expect("a test K is at least 1")
}

/// A plant with MHE weights and sets.
pub struct Fixture {
    pub sys: LtiSystem,
    pub sets: MheSets,
    pub config: MheConfig,
    pub prior: Vec<f64>,
    pub x0: Vec<f64>,
    /// Bound of the simulated noise (may exceed 𝒲 so that bounds become active).
    pub noise: f64,
}

/// The stand-in case study: A, B of design.md §4, the paper's C, P from LMI (2) with
/// η = 0.8, Q = I₅, R = 1, 𝒲 = [−0.1, 0.1]⁵, x₀ and x̄₀ of the paper.
pub fn case_study(horizon: usize, iterations: usize, exact_solve: bool) -> Fixture {
    let sys = lti_model::presets::case_study_plant();
    let q = Mat::<f64>::identity(5, 5);
    let r = mat![[1.0]];
    let cert = lti_model::ioss::certify(&sys, 0.8, q.as_ref(), r.as_ref()).unwrap();
    let sets = MheSets::with_disturbance(&sys, BoxSet::symmetric(&[0.1; 5]).unwrap());
    Fixture {
        config: MheConfig::new(horizon, 0.8, cert.p, q, r, k(iterations))
            .with_exact_solve(exact_solve),
        sys,
        sets,
        prior: vec![7.0, -7.0, 3.0, -5.0],
        x0: vec![12.0, -10.0, 10.0, -10.0],
        noise: 0.1,
    }
}

pub fn random_mat(rng: &mut ChaCha8Rng, r: usize, c: usize, scale: f64) -> Mat<f64> {
    Mat::from_fn(r, c, |_, _| scale * (2.0 * rng.random::<f64>() - 1.0))
}

/// Random SPD matrix with eigenvalues roughly in [lo, lo + 1].
pub fn random_spd(rng: &mut ChaCha8Rng, n: usize, lo: f64) -> Mat<f64> {
    let g = random_mat(rng, n, n, 1.0);
    let m = &g * g.transpose();
    let s = m.norm_max().max(1e-12);
    Mat::from_fn(n, n, |i, j| m[(i, j)] / s + if i == j { lo } else { 0.0 })
}

/// A random detectable system with general E, F (n_w1 ≠ n_x possible), random SPD weights
/// (full Q, so ŵ¹ and ŵ² are coupled), a random box 𝒲 and noise that leaves 𝒲 at times.
pub fn random_fixture(seed: u64, horizon: usize, iterations: usize, exact_solve: bool) -> Fixture {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    loop {
        let nx = rng.random_range(1..=4);
        let nu = rng.random_range(0..=2);
        let ny = rng.random_range(1..=2);
        let nw1 = rng.random_range(1..=nx);
        let nw2 = rng.random_range(1..=ny);
        let a = random_mat(&mut rng, nx, nx, 0.8);
        let b = random_mat(&mut rng, nx, nu, 1.0);
        let c = random_mat(&mut rng, ny, nx, 1.0);
        let e = random_mat(&mut rng, nx, nw1, 1.0);
        let f = random_mat(&mut rng, ny, nw2, 1.0);
        let Ok(sys) = LtiSystem::with_disturbance(a, b, c, e, f) else {
            continue;
        };
        if !sys.is_detectable().unwrap() {
            continue;
        }
        let nw = nw1 + nw2;
        let radius: Vec<f64> = (0..nw).map(|_| 0.05 + 0.3 * rng.random::<f64>()).collect();
        let sets = MheSets::with_disturbance(&sys, BoxSet::symmetric(&radius).unwrap());
        let eta = 0.5 + 0.45 * rng.random::<f64>();
        let config = MheConfig::new(
            horizon,
            eta,
            random_spd(&mut rng, nx, 0.2),
            random_spd(&mut rng, nw, 0.2),
            random_spd(&mut rng, ny, 0.2),
            k(iterations),
        )
        .with_exact_solve(exact_solve);
        let prior = (0..nx)
            .map(|_| 3.0 * (2.0 * rng.random::<f64>() - 1.0))
            .collect();
        let x0 = (0..nx)
            .map(|_| 3.0 * (2.0 * rng.random::<f64>() - 1.0))
            .collect();
        return Fixture {
            sys,
            sets,
            config,
            prior,
            x0,
            noise: 0.4,
        };
    }
}

/// A time series of vectors.
pub type Series = Vec<Vec<f64>>;

/// Simulated open-loop data: u_t uniform in [−1, 1], w_t uniform in [−noise, noise].
/// Returns (us, ys, xs) with xs[t] the true state at t.
pub fn simulate(f: &Fixture, steps: usize, seed: u64) -> (Series, Series, Series) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (nx, nu, ny, nw) = (f.sys.nx(), f.sys.nu(), f.sys.ny(), f.sys.nw());
    let mut x = f.x0.clone();
    let (mut us, mut ys, mut xs) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..steps {
        let u: Vec<f64> = (0..nu).map(|_| 2.0 * rng.random::<f64>() - 1.0).collect();
        let w: Vec<f64> = (0..nw)
            .map(|_| f.noise * (2.0 * rng.random::<f64>() - 1.0))
            .collect();
        let mut xn = vec![0.0; nx];
        let mut y = vec![0.0; ny];
        f.sys.step(&x, &u, &w, &mut xn, &mut y);
        xs.push(x.clone());
        us.push(u);
        ys.push(y);
        x = xn;
    }
    (us, ys, xs)
}

pub use lti_model::vecmath::dist2 as dist;

/// CSC of a dense matrix (Clarabel's form; `upper_only` keeps the upper triangle, for P).
#[cfg(feature = "clarabel")]
pub fn csc(
    m: &faer::Mat<f64>,
    upper_only: bool,
) -> qp_iter::reference::clarabel::algebra::CscMatrix<f64> {
    qp_iter::reference::dense_to_csc(m.as_ref(), upper_only)
}
