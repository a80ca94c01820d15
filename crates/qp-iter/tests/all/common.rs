//! Fixtures: seeded random strongly convex parametric QPs, the Clarabel reference with a
//! rigorous bound on its own error, and the φ(K) bound checker shared by all tests.

use faer::Mat;
use qp_iter::BoxSet;
use qp_iter::ParametricQp;
use qp_iter::reference::{ReferenceSettings, ReferenceSolution, ReferenceSolver};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

pub fn normal(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}

/// Orthogonal factor of the QR decomposition of a Gaussian matrix.
pub fn random_orthogonal(rng: &mut ChaCha8Rng, n: usize) -> Mat<f64> {
    let g = Mat::from_fn(n, n, |_, _| normal(rng));
    g.qr().compute_Q()
}

/// H = Q diag(λ) Qᵀ with λ_min = μ, λ_max = μκ and the rest log-uniform in between.
pub fn random_spd(rng: &mut ChaCha8Rng, n: usize, kappa: f64, mu: f64) -> Mat<f64> {
    let q = random_orthogonal(rng, n);
    let lam: Vec<f64> = (0..n)
        .map(|i| match i {
            0 => mu,
            1 => mu * kappa,
            _ => mu * kappa.powf(rng.random::<f64>()),
        })
        .collect();
    let h = Mat::from_fn(n, n, |i, j| {
        (0..n).map(|k| q[(i, k)] * lam[k] * q[(j, k)]).sum::<f64>()
    });
    Mat::from_fn(n, n, |i, j| 0.5 * (h[(i, j)] + h[(j, i)]))
}

/// A random instance: problem, parameter θ and warm start z⁰.
#[derive(Debug, Clone)]
pub struct Instance {
    pub qp: ParametricQp,
    pub theta: Vec<f64>,
    pub z0: Vec<f64>,
    pub seed: u64,
}

/// Options of [`random_instance`].
#[derive(Debug, Clone, Copy)]
pub struct Gen {
    pub n_min: usize,
    pub n_max: usize,
    pub log10_kappa_max: f64,
    /// Probability that a bound is finite.
    pub p_finite: f64,
}

impl Default for Gen {
    fn default() -> Self {
        Self {
            n_min: 2,
            n_max: 30,
            log10_kappa_max: 4.0,
            p_finite: 0.75,
        }
    }
}

/// Random strongly convex parametric QP: n ∈ [n_min, n_max], κ log-uniform in
/// [1, 10^log10_kappa_max], μ log-uniform in [0.1, 10], a random box (each bound finite
/// with probability p_finite; 10 % of instances unconstrained), q₀ = −H z_c and F = −H G
/// so the unconstrained minimiser z_c + Gθ is O(1), θ Gaussian, z⁰ Gaussian (half the
/// time projected onto Z, half the time possibly infeasible).
pub fn random_instance(seed: u64, opts: Gen) -> Instance {
    let mut r = rng(seed);
    let n = r.random_range(opts.n_min..=opts.n_max);
    let n_theta = r.random_range(0..=4usize);
    let kappa = 10f64.powf(opts.log10_kappa_max * r.random::<f64>());
    let mu = 10f64.powf(2.0 * r.random::<f64>() - 1.0);
    let h = random_spd(&mut r, n, kappa, mu);
    let zc: Vec<f64> = (0..n).map(|_| 2.0 * normal(&mut r)).collect();
    let q0: Vec<f64> = (0..n)
        .map(|i| -(0..n).map(|j| h[(i, j)] * zc[j]).sum::<f64>())
        .collect();
    let g = Mat::from_fn(n, n_theta, |_, _| normal(&mut r));
    let f = Mat::from_fn(n, n_theta, |i, k| {
        -(0..n).map(|j| h[(i, j)] * g[(j, k)]).sum::<f64>()
    });
    let unconstrained = r.random::<f64>() < 0.1;
    let (mut lo, mut up) = (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]);
    if !unconstrained {
        for i in 0..n {
            let c = normal(&mut r);
            let w = 0.05 + 2.0 * r.random::<f64>();
            if r.random::<f64>() < opts.p_finite {
                lo[i] = c - w;
            }
            if r.random::<f64>() < opts.p_finite {
                up[i] = c + w;
            }
        }
    }
    let zset = BoxSet::new(lo, up).unwrap();
    let qp = ParametricQp::new(h, q0, f, zset).unwrap();
    let theta: Vec<f64> = (0..n_theta).map(|_| normal(&mut r)).collect();
    let mut z0: Vec<f64> = (0..n).map(|_| 3.0 * normal(&mut r)).collect();
    if r.random::<bool>() {
        qp.project(&mut z0);
    }
    Instance {
        qp,
        theta,
        z0,
        seed,
    }
}

/// The loaded linear term q = q₀ + Fθ.
pub fn linear_term(qp: &ParametricQp, theta: &[f64]) -> Vec<f64> {
    let mut q = vec![0.0; qp.n()];
    qp.linear_term(theta, &mut q);
    q
}

/// Hz + q, computed here (not by the crate).
pub fn gradient(qp: &ParametricQp, q: &[f64], z: &[f64]) -> Vec<f64> {
    let h = qp.h();
    (0..qp.n())
        .map(|i| (0..qp.n()).map(|j| h[(i, j)] * z[j]).sum::<f64>() + q[i])
        .collect()
}

/// ‖a − b‖₂.
pub fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// ‖v‖₂.
pub fn norm(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// Reference optimum and a rigorous bound on its distance to the true z*:
/// ‖ẑ − z*‖ ≤ (1 + L)/μ · ‖ẑ − Π_Z(ẑ − ∇f(ẑ))‖ (natural-residual error bound for a
/// μ-strongly convex, L-smooth f), plus a floor for the rounding in evaluating it.
#[derive(Debug, Clone)]
pub struct Reference {
    pub sol: ReferenceSolution,
    pub q: Vec<f64>,
    pub err: f64,
}

pub fn reference(inst: &Instance) -> Reference {
    let qp = &inst.qp;
    let mut solver = ReferenceSolver::new(qp, ReferenceSettings::default()).unwrap();
    let sol = solver
        .solve(&inst.theta)
        .unwrap_or_else(|e| panic!("seed {}: reference failed: {e}", inst.seed));
    let q = linear_term(qp, &inst.theta);
    let g = gradient(qp, &q, &sol.z);
    let mut p: Vec<f64> = sol.z.iter().zip(&g).map(|(z, g)| z - g).collect();
    qp.project(&mut p);
    let res = dist(&sol.z, &p);
    let scale = 1.0 + norm(&sol.z) + norm(&q);
    let err = (1.0 + qp.l()) / qp.mu() * (res + 1e-15 * scale * qp.l().max(1.0));
    Reference { sol, q, err }
}

/// Bookkeeping of a bound check over many instances and K.
#[derive(Debug, Default, Clone, Copy)]
pub struct Tally {
    pub checks: usize,
    pub violations: usize,
    pub instances_violated: usize,
    /// max over K ≥ 1 of err_K / (φ(K)·err_0), where φ(K)·err_0 > 1e-3 (so the
    /// reference's own error cannot dominate): how close the bound is to being attained.
    pub worst_ratio: f64,
}

/// Checks err_K ≤ φ(K)·(err_0 + slack)·(1 + 1e-9) + slack + 1e-9 for the errors
/// `errs[K]` of the iterate after K steps (K = 0, 1, …) against the initial error `e0`;
/// `slack` is the uncertainty of the reference. Returns the number of violated K.
pub fn check_sequence(
    e0: f64,
    errs: &[f64],
    phi: impl Fn(usize) -> f64,
    slack: f64,
    tally: &mut Tally,
) -> usize {
    let mut bad = 0;
    for (k, &ek) in errs.iter().enumerate() {
        let p = phi(k);
        let bound = p * (e0 + slack) * (1.0 + 1e-9) + slack + 1e-9;
        tally.checks += 1;
        if !(ek <= bound) {
            bad += 1;
        }
        let denom = p * e0;
        if k > 0 && denom > 1e-3 {
            tally.worst_ratio = tally.worst_ratio.max(ek / denom);
        }
    }
    tally.violations += bad;
    if bad > 0 {
        tally.instances_violated += 1;
    }
    bad
}
