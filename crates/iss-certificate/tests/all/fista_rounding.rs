//! The K-step rounding model of projected gradient, V-FISTA, ADMM and their Jacobi-scaled
//! variants (issue 36; docs/theory.md, "FISTA in f32", "Jacobi-scaled projected gradient in
//! f32", "ADMM in f32" and "FISTA-Jacobi in f32"): K iterations run in f32 in `mhe_embedded`'s dense order from a random
//! warm start stay within ‖zᴷ − z*‖ ≤ φ_u(K)‖z⁰ − z*‖ + β_z‖z*‖ + β_θ‖θ‖ + c_d, with z* the
//! exact optimum (the active-set solver in f64) — on random box QPs, κ up to 10⁴, K from 1
//! to 300, starts and parameters over seven decades, and starts chosen to be bad.

use faer::Mat;
use iss_certificate::lure::global::StepRounding;
use qp_iter::active_set::{ActiveSetSettings, ActiveSetSolver};
use qp_iter::rounding::F32_UNIT_ROUNDOFF;
use qp_iter::{BoxSet, Certificate, IterationMap, Method, MethodMap, ParametricQp, Scaling};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The test QPs' κ for `method` on seed `seed`: V-FISTA's incremental storage (Theorem L1,
/// sector multipliers) exists up to κ ≈ 5 (test below), so 1.5 … 4.4 there; projected
/// gradient's and ADMM's contraction at every κ, so 10 … 10⁴.
/// FISTA-Jacobi runs V-FISTA on the Jacobi-scaled problem, whose κ these QPs' geometric
/// diagonal does not reach (D H D has a unit diagonal): it gets the wide range.
pub(super) fn kappa_of(method: Method, seed: u64) -> f64 {
    if method == Method::FISTA {
        1.5 + 0.1 * (seed % 30) as f64
    } else {
        10f64.powi(1 + (seed % 4) as i32)
    }
}

/// A random box QP: H = diag(1 … κ, geometric) + GGᵀ/(10n); every third variable free.
pub(super) fn qp(seed: u64, n: usize, nt: usize, kappa: f64) -> ParametricQp {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let g = Mat::<f64>::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
    let mut h = &g * g.transpose() * faer::Scale(0.1 / n as f64);
    for i in 0..n {
        h[(i, i)] += kappa.powf(i as f64 / (n - 1) as f64);
    }
    let f = Mat::<f64>::from_fn(n, nt, |_, _| rng.random_range(-2.0..2.0));
    let lower = (0..n)
        .map(|i| if i % 3 == 0 { f64::NEG_INFINITY } else { -0.3 })
        .collect();
    let upper = (0..n)
        .map(|i| if i % 3 == 0 { f64::INFINITY } else { 0.7 })
        .collect();
    ParametricQp::new(h, vec![0.1; n], f, BoxSet::new(lower, upper).expect("box"))
        .expect("valid QP")
}

/// The scalars the runs are written in.
trait Real:
    Copy
    + PartialOrd
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::AddAssign
{
    fn of(v: f64) -> Self;
    fn to(self) -> f64;
}
impl Real for f32 {
    fn of(v: f64) -> Self {
        v as f32
    }
    fn to(self) -> f64 {
        f64::from(self)
    }
}
impl Real for f64 {
    fn of(v: f64) -> Self {
        v
    }
    fn to(self) -> f64 {
        self
    }
}

/// q = q₀ + Fθ summed from q₀ in θ order, and the box, in the scalar `T` (as the estimator
/// loads a window).
fn loaded<T: Real>(qp: &ParametricQp, theta: &[f64]) -> (Vec<T>, Vec<T>, Vec<T>) {
    let f = qp.f();
    let q = (0..qp.n())
        .map(|i| {
            let mut acc = T::of(qp.q0()[i]);
            for (j, th) in theta.iter().enumerate() {
                acc += T::of(f[(i, j)]) * T::of(*th);
            }
            acc
        })
        .collect();
    let cast = |v: &[f64]| v.iter().map(|v| T::of(*v)).collect();
    (q, cast(qp.zset().lower()), cast(qp.zset().upper()))
}

/// K iterations in the scalar `T` as `mhe_embedded::qp::run` (dense branch): q = q₀ + Fθ
/// summed from q₀ in θ order, Hy summed from 0 in column order, no fused multiply–add;
/// FISTA's first step is the plain step (β = 0), then x = Π(y − s(Hy + q)),
/// y = x + β(x − x₋). In f64 it is the exact run (its rounding ≈ 1e-16 relative).
fn run<T: Real>(
    qp: &ParametricQp,
    fista: bool,
    step: f64,
    beta: f64,
    theta: &[f64],
    z0: &[f64],
    k: usize,
) -> Vec<f64> {
    let n = qp.n();
    let h = qp.h();
    let (s, b_run) = (T::of(step), T::of(beta));
    let (q, lo, hi) = loaded::<T>(qp, theta);
    let mut z: Vec<T> = z0.iter().map(|v| T::of(*v)).collect();
    let mut y = z.clone();
    let mut hy = vec![T::of(0.0); n];
    for it in 0..k {
        let b = if fista && it > 0 { b_run } else { T::of(0.0) };
        hy.iter_mut().for_each(|v| *v = T::of(0.0));
        for j in 0..n {
            for (i, v) in hy.iter_mut().enumerate() {
                *v += T::of(h[(i, j)]) * y[j];
            }
        }
        for i in 0..n {
            let x = y[i] - s * (hy[i] + q[i]);
            let x = if lo[i] > x { lo[i] } else { x };
            let x = if hi[i] < x { hi[i] } else { x };
            y[i] = if fista { x + b * (x - z[i]) } else { x };
            z[i] = x;
        }
    }
    z.into_iter().map(Real::to).collect()
}

/// One ADMM solve in the scalar `T` as `mhe_embedded::qp::run` (ADMM arm): mq = M q,
/// y⁰ = −(Hz⁰ + q), s = z⁰ + y⁰/ρ, t = 2Π(s) − s; K times z = M_ρ t − mq, w = αz + (s − αΠ(s)),
/// t = 2Π(w) − w, s = w; the iterate Π(s). `m_rho`, `m_inv` by columns (the stored ones).
#[allow(clippy::too_many_arguments)]
fn run_admm<T: Real>(
    qp: &ParametricQp,
    m_rho: &[f64],
    m_inv: &[f64],
    rho: f64,
    alpha: f64,
    theta: &[f64],
    z0: &[f64],
    k: usize,
) -> Vec<f64> {
    let n = qp.n();
    let h = qp.h();
    let mv = |m: &dyn Fn(usize, usize) -> T, x: &[T]| -> Vec<T> {
        let mut y = vec![T::of(0.0); n];
        for (j, xj) in x.iter().enumerate() {
            for (i, yi) in y.iter_mut().enumerate() {
                *yi += m(i, j) * *xj;
            }
        }
        y
    };
    let (q, lo, hi) = loaded::<T>(qp, theta);
    let clamp = |x: T, i: usize| {
        let x = if lo[i] > x { lo[i] } else { x };
        if hi[i] < x { hi[i] } else { x }
    };
    let mr = |i: usize, j: usize| T::of(m_rho[j * n + i]);
    let mi = |i: usize, j: usize| T::of(m_inv[j * n + i]);
    let hm = |i: usize, j: usize| T::of(h[(i, j)]);
    let z: Vec<T> = z0.iter().map(|v| T::of(*v)).collect();
    let mq = mv(&mi, &q);
    let hz = mv(&hm, &z);
    let (inv_rho, a, two) = (T::of(1.0 / rho), T::of(alpha), T::of(2.0));
    let mut s: Vec<T> = (0..n)
        .map(|i| {
            let y = T::of(0.0) - (hz[i] + q[i]);
            z[i] + inv_rho * y
        })
        .collect();
    let mut t: Vec<T> = (0..n).map(|i| two * clamp(s[i], i) - s[i]).collect();
    for _ in 0..k {
        let zz = mv(&mr, &t);
        for i in 0..n {
            let zi = zz[i] - mq[i];
            let vv = clamp(s[i], i);
            let ww = a * zi + (s[i] - a * vv);
            t[i] = two * clamp(ww, i) - ww;
            s[i] = ww;
        }
    }
    (0..n).map(|i| clamp(s[i], i).to()).collect()
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt()
}

pub(super) fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// ADMM's stored inverses M_ρ, M (by columns), ρ and α.
type AdmmData = (Vec<f64>, Vec<f64>, f64, f64);

/// One method on one QP as the embedded estimator runs it: the K-step rounding model, the
/// exact map's certificate, the map that runs (the scaled problem's for Jacobi) and
/// z = D y's d (all 1 without scaling: every bound is on ‖D⁻¹·‖), and the exact optimum's
/// solver.
pub(super) struct Setup {
    pub(super) method: Method,
    /// The QP as given (its box is z's).
    pub(super) qp: ParametricQp,
    pub(super) model: StepRounding,
    cert: Certificate,
    pub(super) d: Vec<f64>,
    jacobi: bool,
    /// The problem the iteration runs on (the scaled one for Jacobi).
    pub(super) run_qp: ParametricQp,
    /// (step, momentum) of the gradient methods.
    step: f64,
    beta: f64,
    admm: Option<AdmmData>,
    exact: ActiveSetSolver,
    /// The solver as set up, never called.
    cold: ActiveSetSolver,
}

/// One f32 run of K iterations against the K-step model.
pub(super) struct Eval {
    /// ‖D⁻¹(zᴷ − z*)‖ of the f32 run.
    pub(super) err: f64,
    /// φ_u(K)e₀ + β_z‖z*‖ + β_θ‖θ‖ + c_d.
    pub(super) bound: f64,
    /// φ(K)e₀: the exact-arithmetic bound alone.
    pub(super) exact_bound: f64,
    /// ‖f32 run − exact run‖ and its bound φ_u(K at φ = 0)e₀ + inputs (not for Jacobi: its
    /// rounded y⁰ starts the computed run elsewhere).
    pub(super) dev: Option<(f64, f64)>,
    /// The exact optimum's and the f64 run's own error (≈ 1e-15 relative).
    pub(super) allowance: f64,
}

impl Setup {
    /// `method` on `p` (panics where the model does not cover it).
    pub(super) fn new(method: Method, p: &ParametricQp) -> Self {
        let n = p.n();
        let model = match StepRounding::for_qp(method, p, F32_UNIT_ROUNDOFF) {
            Ok(m) => m,
            Err(e) => panic!("{}: {e}", method.name()),
        };
        let map = method.build(p.clone()).expect("builds");
        let (run_qp, d, inner) = match &map {
            MethodMap::Scaled(s) => (s.inner().problem().clone(), s.scaling().to_vec(), s.inner()),
            other => (p.clone(), vec![1.0; n], other),
        };
        let jacobi = d.iter().any(|v| *v != 1.0);
        let cert = inner.certificate().clone();
        let (step, beta) = match inner {
            MethodMap::Pg(m) => (m.alpha(), 0.0),
            MethodMap::Fista(m) => (m.step_size(), m.momentum()),
            _ => (0.0, 0.0),
        };
        let admm = match inner {
            MethodMap::Admm(a) => {
                let (mr, mi) = a.stored_inverses();
                let cols = |m: &qp_iter::kernel::PaddedSymmetric| -> Vec<f64> {
                    (0..n * n)
                        .map(|k| m.as_slice()[(k / n) * m.ld() + k % n])
                        .collect()
                };
                Some((cols(mr), cols(mi), a.rho(), a.relaxation()))
            }
            _ => None,
        };
        let exact = ActiveSetSolver::new(p, ActiveSetSettings::default()).expect("solver");
        Self {
            method,
            qp: p.clone(),
            model,
            cert,
            d,
            jacobi,
            run_qp,
            step,
            beta,
            admm,
            cold: exact.clone(),
            exact,
        }
    }

    /// z*(θ), the exact optimum (the active-set solver in f64, warm-started from the last
    /// call's working set).
    pub(super) fn optimum(&mut self, theta: &[f64]) -> Vec<f64> {
        self.exact.solve(theta).expect("exact optimum");
        self.exact.z().to_vec()
    }

    /// z*(θ) from a cold start: a pure function of θ (the warm start's path can move the
    /// last bits).
    pub(super) fn optimum_cold(&self, theta: &[f64]) -> Vec<f64> {
        let mut s = self.cold.clone();
        s.solve(theta).expect("exact optimum");
        s.z().to_vec()
    }

    /// ‖D⁻¹(a − b)‖.
    pub(super) fn wdist(&self, a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .zip(&self.d)
            .map(|((a, b), d)| ((a - b) / d).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    /// K iterations from the f32 start `z0` at `theta`, in f32 and exactly, against the
    /// model (`zs` = z*(θ)).
    pub(super) fn eval(&self, theta: &[f64], z0: &[f64], zs: &[f64], k: usize) -> Eval {
        let d = &self.d;
        let fista = matches!(self.method.kind, qp_iter::MethodKind::Fista(_));
        // y⁰ = z⁰/d̃ and z = d̃·y in the scalar with the stored d̃ (the embedded estimator's
        // warm start and output on a scaled problem).
        let y0_32: Vec<f64> = z0
            .iter()
            .zip(d)
            .map(|(z, d)| f64::from(*z as f32 / *d as f32))
            .collect();
        let (rq, step, beta) = (&self.run_qp, self.step, self.beta);
        let run_any = |f32_run: bool, y0: &[f64]| match &self.admm {
            Some((mr, mi, rho, alpha)) if f32_run => {
                run_admm::<f32>(rq, mr, mi, *rho, *alpha, theta, y0, k)
            }
            Some((mr, mi, rho, alpha)) => run_admm::<f64>(rq, mr, mi, *rho, *alpha, theta, y0, k),
            None if f32_run => run::<f32>(rq, fista, step, beta, theta, y0, k),
            None => run::<f64>(rq, fista, step, beta, theta, y0, k),
        };
        let y32 = run_any(true, &y0_32);
        let zk: Vec<f64> = y32
            .iter()
            .zip(d)
            .map(|(y, d)| f64::from(*d as f32 * *y as f32))
            .collect();
        let e0 = self.wdist(z0, zs);
        let err = self.wdist(&zk, zs);
        let model = &self.model;
        let inputs =
            model.beta_z() * norm(zs) + model.beta_theta() * norm(theta) + model.offset_d();
        let phi = self.cert.phi(k);
        // The rounding's own part, against the exact run from the same z⁰: what the model
        // adds to φ(K) (φ_u at φ(K) = 0: projected gradient's qᴷ − rᴷ, V-FISTA's
        // c_x s_𝟙[…]), the derivations' Δ_K.
        let dev = (!self.jacobi).then(|| {
            let y0: Vec<f64> = z0.iter().zip(d).map(|(z, d)| z / d).collect();
            let exact_run: Vec<f64> = run_any(false, &y0)
                .iter()
                .zip(d)
                .map(|(y, d)| y * d)
                .collect();
            (dist(&zk, &exact_run), model.phi_u_at(0.0, k) * e0 + inputs)
        });
        Eval {
            err,
            bound: model.phi_u_at(phi, k) * e0 + inputs,
            exact_bound: phi * e0,
            dev,
            allowance: 1e-12 * (1.0 + norm(zs) + e0),
        }
    }
}

/// The methods with a K-step rounding model (`StepRounding::for_qp`), plain and Jacobi.
pub(super) fn methods() -> [Method; 7] {
    [
        Method::PG,
        Method::FISTA,
        Method::PG.with_scaling(Scaling::Jacobi),
        Method::FISTA.with_scaling(Scaling::Jacobi),
        Method::ADMM,
        Method::ADMM_PR,
        Method::ADMM_PR.with_scaling(Scaling::Jacobi),
    ]
}

/// The bound holds on 30 QPs × 5 K × 12 starts per method; reports the largest
/// measured/bound, which must not be absurdly small (the model is a worst case, not a
/// constant chosen to pass).
#[test]
fn k_computed_iterations_stay_within_the_k_step_model() {
    for method in methods() {
        let mut worst = 0.0f64;
        let mut worst_dev = 0.0f64;
        let mut checked = 0usize;
        let mut needed = 0usize;
        for seed in 0..30u64 {
            let (n, nt) = (3 + (seed as usize % 14), 2 + (seed as usize % 5));
            let p = qp(seed, n, nt, kappa_of(method, seed));
            let mut setup = Setup::new(method, &p);
            let model = &setup.model;
            assert!(model.perturbed_rate() < 1.0, "seed {seed}: {model:?}");
            let mut rng = ChaCha8Rng::seed_from_u64(5000 + seed);
            for k in [1usize, 2, 5, 30, 300] {
                for trial in 0..12 {
                    let scale = 10f64.powi(rng.random_range(-3..4));
                    let theta: Vec<f64> = (0..nt)
                        .map(|_| scale * rng.random_range(-1.0..1.0))
                        .collect();
                    let zs = setup.optimum(&theta);
                    // Half the starts random, half far out along the slowest direction.
                    let far = if trial % 2 == 0 { 1.0 } else { 1e3 };
                    let z0: Vec<f64> = (0..n)
                        .map(|i| {
                            f64::from((zs[i] + far * scale * rng.random_range(-1.0..1.0)) as f32)
                        })
                        .collect();
                    let ev = setup.eval(&theta, &z0, &zs, k);
                    let (err, bound, allowance) = (ev.err, ev.bound, ev.allowance);
                    // Runs the exact-arithmetic bound alone would not cover.
                    needed += usize::from(err > ev.exact_bound + allowance);
                    assert!(
                        err <= bound + allowance,
                        "{} seed {seed} K {k}: ‖D⁻¹(zᴷ − z*)‖ = {err:e} > bound {bound:e}",
                        method.name()
                    );
                    worst = worst.max(err / bound);
                    checked += 1;
                    if let Some((dev, dev_bound)) = ev.dev {
                        assert!(
                            dev <= dev_bound + allowance,
                            "{} seed {seed} K {k}: f32 − exact run {dev:e} > {dev_bound:e}",
                            method.name()
                        );
                        worst_dev = worst_dev.max(dev / dev_bound);
                    }
                }
            }
        }
        println!(
            "{}: {checked} runs, largest measured/bound {worst:.3e}; rounding part {worst_dev:.3e}; \
             {needed} runs beyond φ(K)·e₀ alone",
            method.name()
        );
        // The rounding terms are not decoration: f32 runs leave the exact bound.
        assert!(
            needed > 0,
            "{}: no run needed the rounding terms",
            method.name()
        );
        assert!(
            worst > 1e-6,
            "{}: measured/bound = {worst:e}",
            method.name()
        );
        if method.scaling == Scaling::None {
            assert!(
                worst_dev > 1e-4,
                "{}: rounding part = {worst_dev:e}",
                method.name()
            );
        }
    }
}

/// Where V-FISTA's inner-rate LMI certifies no incremental rate (κ = 100 here), its
/// rounding is not covered, and the reason says that and gives κ — not a generic refusal.
#[test]
fn fista_without_an_incremental_rate_is_not_covered_with_the_reason() {
    let p = qp(3, 8, 3, 100.0);
    let why = StepRounding::for_qp(Method::FISTA, &p, F32_UNIT_ROUNDOFF).expect_err("no rate");
    let text = why.to_string();
    assert!(
        text.contains("incremental rate") && text.contains("κ = 9"),
        "{text}"
    );
    // The same QP is covered for projected gradient.
    assert!(StepRounding::for_qp(Method::PG, &p, F32_UNIT_ROUNDOFF).is_ok());
}

/// What the certificates take of the K-step model (`StepRounding::phi_u`) bounds the exact
/// K-step factor (`phi_u_at`) at every later K' ≥ K and is non-increasing — "certified from
/// K_min on" rests on it — while `phi_u_at` itself rises before it falls for some method
/// (qᴷ − rᴷ with q > r), so the envelope is needed.
#[test]
fn the_certificates_phi_u_bounds_every_later_k_and_does_not_increase() {
    let mut rises = 0usize;
    for method in methods() {
        for seed in 0..6u64 {
            let p = qp(seed, 4 + seed as usize, 3, kappa_of(method, seed));
            let setup = Setup::new(method, &p);
            let (m, phi) = (&setup.model, |k: usize| setup.cert.phi(k));
            // φ = 0 isolates the rounding's part, where the rise is.
            for phi_of in [&phi as &dyn Fn(usize) -> f64, &|_| 0.0] {
                let at: Vec<f64> = (0..400).map(|k| m.phi_u_at(phi_of(k), k)).collect();
                let env: Vec<f64> = (0..400).map(|k| m.phi_u(phi_of(k), k)).collect();
                rises += at.windows(2).filter(|w| w[1] > w[0]).count();
                for k in 0..400 {
                    let later = at[k..].iter().copied().fold(0.0, f64::max);
                    assert!(
                        env[k] >= later * (1.0 - 1e-12),
                        "{} seed {seed} K {k}: φ_u {:e} < later φ_u_at {later:e}",
                        method.name(),
                        env[k]
                    );
                    assert!(
                        k == 0 || env[k] <= env[k - 1] * (1.0 + 1e-12),
                        "{} seed {seed}: φ_u rises at K = {k}",
                        method.name()
                    );
                }
            }
        }
    }
    assert!(
        rises > 0,
        "phi_u_at never rises: the envelope is not exercised"
    );
}
