//! The global loop certificate in f32 (Theorem L3u, docs/theory.md "The global loop
//! certificate in a given precision") against 200 closed-loop runs with `mhe_embedded` in
//! f32 in the loop and against the optimised adversary of adversary.rs on the same loop
//! ([`F32Run::run`] from explicit inputs: both use it), at the f32 K_glob: the case study
//! (PG K = 13, PG-Jacobi 5, ADMM-PR-Jacobi 3) and the double integrator (PG 664,
//! ADMM-PR-Jacobi 52).

use super::adversary;
use super::data::{apply, owned_for, singles, to32, widen, windows32, windows64};
use super::scenario;
use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario};
use iss_certificate::certificate::certify_closed_loop;
use iss_certificate::certificate::precision::DeviationBound;
use iss_certificate::coverage::verdict_options;
use iss_certificate::linear::LiftedLayout;
use iss_certificate::lure::global::{GlobalCertificate, certify_precision, global_loop};
use iss_certificate::lure::global_outcome::GlobalSettings;
use mpc_core::Controller;
use qp_iter::Method;
use qp_iter::rounding::F32_UNIT_ROUNDOFF;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Seeds 0..NOISY_SEEDS draw w; the rest of the 200 run with w = 0.
const NOISY_SEEDS: u64 = 100;

/// One f32 run of a scenario's loop: the plant in f64, `mhe_embedded` in f32 (PG, K, the
/// paper's warm start: the exported code's arithmetic; `MheRt` equals the const-size
/// estimator bit for bit), the scenario's exact controller in f64 at the computed x̂, w
/// from [`Inputs`] (the seeded runs: uniform on 𝒲 × a random scale; the adversary's: its
/// choice).
pub(super) struct F32Run<'a> {
    pub(super) problem: mhe_embedded::Problem<'a, f32>,
    resolved: ResolvedScenario,
    pub(super) layout: LiftedLayout,
    /// The same estimator in f64 fed the run's (u, y), and the per-step bound on
    /// ‖x̂_f32 − x̂_f64‖ (`DeviationBound`, fresh per run); None: not tracked.
    pub(super) deviation: Option<(mhe_embedded::Problem<'a, f64>, DeviationBound)>,
}

/// What a run starts from and is driven by.
#[derive(Debug, Clone)]
pub(super) struct Inputs {
    /// The plant's x₀.
    pub(super) x0: Vec<f64>,
    /// The estimator's prior (rounded to f32 as it is loaded).
    pub(super) prior: Vec<f64>,
    /// w_t = (w¹_t, w²_t), n_w per step from t = 0 (zero past the end).
    pub(super) w: Vec<f64>,
}

/// What one run measured against a certificate.
#[derive(Debug, Clone, Copy)]
pub(super) struct Outcome {
    /// max over t ≥ M of (‖X_{t+1}‖²_P − γ²(‖w_t‖² + o²))/(ρ²‖X_t‖²_P): ≤ 1 where the
    /// certified one-step inequality holds.
    pub(super) worst: f64,
    /// max over t > M of ‖X_t‖²_P / (ρ^{2(t−M)}‖X_M‖²_P + γ²/(1 − ρ²)(sup‖w‖² + o²)).
    pub(super) multi: f64,
    /// The step (counted from t = M) where `worst` was reached.
    pub(super) at: usize,
    /// ‖X_t‖²_P stayed within ρ^{2(t−M)}‖X_M‖²_P + γ²/(1 − ρ²)(sup‖w‖² + o²).
    pub(super) within: bool,
    /// max_t ‖x̂_f32 − x̂_f64‖ / `DeviationBound` (0 where the bound is not tracked).
    pub(super) deviation: f64,
}

impl Outcome {
    pub(super) fn holds(&self) -> bool {
        self.within && self.worst <= 1.0 && self.deviation <= 1.0
    }

    /// The adversary's objective: the larger of the one-step and multi-step ratios (∞ where
    /// the run diverged).
    pub(super) fn score(&self) -> f64 {
        self.worst.max(self.multi)
    }
}

impl F32Run<'_> {
    /// The lifted state X_t (t ≥ M) of the f32 run from its records (u_s, y_s, x̂_s).
    fn lifted(&self, x: &[f64], rec: &[[Vec<f64>; 3]], z0: &[f64]) -> Vec<f64> {
        let l = self.layout;
        let t = rec.len();
        let mut big = vec![0.0; l.dim()];
        big[..l.nx].copy_from_slice(x);
        for j in 0..l.horizon {
            let [u, y, xh] = &rec[t - l.horizon + j];
            big[l.u_window(j)..l.u_window(j) + l.nu].copy_from_slice(u);
            big[l.y_window(j)..l.y_window(j) + l.ny].copy_from_slice(y);
            big[l.estimates(j)..l.estimates(j) + l.nx].copy_from_slice(xh);
        }
        big[l.warm_start()..l.warm_start() + l.nz].copy_from_slice(&z0[..l.nz]);
        big
    }

    /// The inputs of seed `seed` for `steps` steps: x₀ and the prior up to 100 × a random
    /// magnitude, noise 0.5–3 × 𝒲 below [`NOISY_SEEDS`], none from there.
    fn seeded(&self, seed: u64, steps: usize) -> Inputs {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mag = 10f64.powf(rng.random_range(-2.0..2.0));
        let scale = rng.random_range(0.5..3.0);
        // Seeds ≥ 100 run noise-free: the supply is then γ²o² alone (the rounding's offset),
        // so the one-step inequality is tested where w does not cover it.
        let scale = if seed < NOISY_SEEDS { scale } else { 0.0 };
        let nx = self.layout.nx;
        let wset = &self.resolved.scenario().sets.disturbance;
        let x0 = (0..nx).map(|_| mag * rng.random_range(-1.0..1.0)).collect();
        let prior = (0..nx).map(|_| mag * rng.random_range(-1.0..1.0)).collect();
        let w = (0..steps)
            .flat_map(|_| 0..wset.lower().len())
            .map(|i| scale * rng.random_range(wset.lower()[i]..=wset.upper()[i]))
            .collect();
        Inputs { x0, prior, w }
    }

    /// The run from `inp` for `steps` steps: ‖X_t‖²_P per t ≥ M, ‖w_t‖² per t ≥ M, and the
    /// largest ‖x̂_f32 − x̂_f64‖ / its bound (0 without a tracked bound).
    fn storage(
        &self,
        c: &GlobalCertificate,
        inp: &Inputs,
        steps: usize,
    ) -> (Vec<f64>, Vec<f64>, f64) {
        let sys = self.resolved.mhe_problem().expect("mhe").system().clone();
        let (nx, nu, nw1) = (sys.nx(), sys.nu(), sys.nw1());
        let nw = nw1 + sys.nw2();
        let mut ctrl = self
            .resolved
            .controller(ControllerChoice::ExactMpc)
            .expect("controller");
        let m = self.layout.horizon;
        let mut x = inp.x0.clone();
        let prior = to32(&inp.prior);
        let mut work = vec![0f32; mhe_embedded::MheRt::workspace_len(&self.problem)];
        let mut mhe = mhe_embedded::MheRt::new(&self.problem, &prior, &mut work).expect("dims");
        let mut rec: Vec<[Vec<f64>; 3]> = Vec::new();
        let (mut storage, mut wn) = (Vec::new(), Vec::new());
        // The f64 twin and the deviation bound (projected gradient only).
        let mut work64 = self.deviation.as_ref().map_or_else(Vec::new, |(p, _)| {
            vec![0f64; mhe_embedded::MheRt::workspace_len(p)]
        });
        let mut twin = self.deviation.as_ref().map(|(p, bound)| {
            let m64 = mhe_embedded::MheRt::new(p, &inp.prior, &mut work64).expect("dims");
            (m64, bound.clone(), Vec::<Vec<f64>>::new())
        });
        let mut deviation = 0.0_f64;
        for t in 0..steps {
            if t >= m {
                let z0 = widen(mhe.start());
                storage.push(c.storage(&self.lifted(&x, &rec, &z0)));
            }
            let xh: Vec<f64> = mhe.estimate().iter().map(|v| f64::from(*v)).collect();
            if let Some((m64, bound, estimates)) = twin.as_mut() {
                // θ_t of the f64 run: its prior (its estimate M steps back once the window is
                // full) and the (u, y) window.
                let mw = t.min(m);
                let prior = if t <= m {
                    &inp.prior
                } else {
                    &estimates[t - m]
                };
                let window = &rec[t - mw..];
                let us: Vec<f64> = window.iter().flat_map(|r| r[0].clone()).collect();
                let ys: Vec<f64> = window.iter().flat_map(|r| r[1].clone()).collect();
                let sq = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>();
                let theta = (sq(prior) + sq(&us) + sq(&ys)).sqrt();
                let b = bound.step(theta, sq(&us).sqrt());
                let x64 = m64.estimate().to_vec();
                let d = x64
                    .iter()
                    .zip(&xh)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    .sqrt();
                deviation = deviation.max(d / b);
                estimates.push(x64);
            }
            let mut u = vec![0.0; nu];
            // A run whose f32 estimate overflowed (an uncertified K diverges) has no finite
            // storage from here: recorded as ∞, which every check refuses.
            if ctrl.control(&xh, &mut u).is_err() {
                assert!(
                    xh.iter().any(|v| !v.is_finite()),
                    "the exact MPC fails at a finite estimate {xh:?}"
                );
                storage.push(f64::INFINITY);
                break;
            }
            let w: Vec<f64> = (t * nw..(t + 1) * nw)
                .map(|i| inp.w.get(i).copied().unwrap_or(0.0))
                .collect();
            let (w1, w2) = w.split_at(nw1);
            let y: Vec<f64> = apply(sys.c(), &x)
                .iter()
                .zip(apply(sys.f(), w2))
                .map(|(a, b)| a + b)
                .collect();
            let (ax, bu, ew) = (apply(sys.a(), &x), apply(sys.b(), &u), apply(sys.e(), w1));
            x = (0..nx).map(|i| ax[i] + bu[i] + ew[i]).collect();
            if t >= m {
                wn.push(w.iter().map(|v| v * v).sum::<f64>());
            }
            if mhe.push(&to32(&u), &to32(&y)).is_err() {
                // (u, y) beyond f32's range: the run diverged (as above).
                storage.push(f64::INFINITY);
                break;
            }
            if let Some((m64, _, _)) = twin.as_mut() {
                m64.push(&u, &y).expect("finite (u, y)");
            }
            rec.push([u, y, xh]);
        }
        (storage, wn, deviation)
    }

    /// The run from `inp` against `c` with the rounding offset `offset` (module docs).
    pub(super) fn run(
        &self,
        c: &GlobalCertificate,
        offset: f64,
        inp: &Inputs,
        steps: usize,
    ) -> Outcome {
        let (storage, wn, deviation) = self.storage(c, inp, steps);
        if storage.iter().any(|v| !v.is_finite()) {
            // Diverged (f32 overflow): no inequality holds.
            return Outcome {
                worst: f64::INFINITY,
                multi: f64::INFINITY,
                at: 0,
                within: false,
                deviation,
            };
        }
        let (r2, g2, o2) = (c.rho * c.rho, c.gamma * c.gamma, offset * offset);
        let (mut worst, mut multi, mut at) = (0.0_f64, 0.0_f64, 0);
        let (mut within, mut wsup) = (true, 0.0_f64);
        for t in 0..storage.len() - 1 {
            let (v, vn) = (storage[t], storage[t + 1]);
            let supply = g2 * (wn[t] + o2);
            let slack = 1e-9 * (vn.abs() + r2 * v + supply);
            let ratio = (vn - supply - slack) / (r2 * v).max(f64::MIN_POSITIVE);
            if ratio > worst {
                (worst, at) = (ratio, t);
            }
            wsup = wsup.max(wn[t]);
            let bound = r2.powf((t + 1) as f64) * storage[0] + g2 / (1.0 - r2) * (wsup + o2);
            within &= vn <= bound * (1.0 + 1e-9);
            multi = multi.max(vn / bound.max(f64::MIN_POSITIVE));
        }
        Outcome {
            worst,
            multi,
            at,
            within,
            deviation,
        }
    }

    /// The run of `seed` (see [`Self::seeded`]).
    fn run_seed(&self, c: &GlobalCertificate, offset: f64, seed: u64, steps: usize) -> Outcome {
        self.run(c, offset, &self.seeded(seed, steps), steps)
    }
}

/// The estimator's data in scalar `T`: `sys`'s sizes, M, K, the kernel's method and the
/// paper's warm start, over the given (A, B, E) and windows.
fn problem<'a, T>(
    sys: &lti_model::LtiSystem,
    horizon: usize,
    k: usize,
    method: mhe_embedded::Method,
    (a, b, e): (&'a [T], &'a [T], &'a [T]),
    windows: &'a [mhe_embedded::Window<'a, T>],
) -> mhe_embedded::Problem<'a, T> {
    mhe_embedded::Problem {
        nx: sys.nx(),
        nu: sys.nu(),
        ny: sys.ny(),
        nw1: sys.nw1(),
        nw2: sys.nw2(),
        horizon,
        iterations: k,
        method,
        warm_start: mhe_embedded::WarmStart::Paper,
        a,
        b,
        e,
        windows,
    }
}

/// `method` on `file`: the f32 certificate (Theorem L3u: the exact φ*, then φ*_u by the
/// search `coverage::verdict` runs, `GlobalSettings::default()`), then 200 f32 closed-loop
/// runs × `steps` steps at its K_glob(f32) (`mhe_embedded` in f32, random x₀ and prior up to
/// 100, noise 0.5–3 × 𝒲 on 100 of them, none on the other 100) satisfy the certified
/// one-step inequality with the rounding offset and the ISS bound; then the optimised
/// adversary of adversary.rs on the same loop and certificate (one solve for both) finds no
/// violation (its worst ratios are printed next to the seeds'). Its CI budget is 12 restarts
/// × 60 moves; `F32_ADVERSARY_RESTARTS`, `F32_ADVERSARY_MOVES` and `F32_ADVERSARY_SEED` set
/// another for hand runs (`F32_ADVERSARY_RESTARTS=30 F32_ADVERSARY_MOVES=100 cargo test
/// --release -p iss-certificate --test loop_level -- --ignored f32_seeds --nocapture`). The
/// checks can fail: with γ = 0 some seeded run and the adversary violate them, and where the
/// loop is unstable at K = 1 (`refute_k1`) so does K = 1, for both. Returns K_glob(f32).
pub(super) fn f32_runs_respect_the_global_certificate(
    file: &str,
    method: Method,
    steps: usize,
    refute_k1: bool,
) -> usize {
    let r = scenario(file);
    let mut o = LoopOptions::from_scenario(r.scenario()).expect("loop options");
    o.method = method;
    let gl = global_loop(&r, &o).expect("builds");
    let opts = GlobalSettings::default().search;
    let exact = gl.phi_star(&opts);
    let p32 =
        certify_precision(&r, &o, &gl, exact.as_ref(), F32_UNIT_ROUNDOFF, &opts).expect("builds");
    let k32 = p32.k_glob.expect("an f32 K_glob");
    let c = p32.certificate.as_ref().expect("certificate");
    eprintln!(
        "{file} {} K_glob exact {:?}, f32 {k32} (φ* {:?}, φ*_u {:?}); offset {:.3e}; f32: ρ {}, \
         γ {:.4e}, margin {:.3e}, split {:?}",
        method.name(),
        p32.k_glob_exact,
        exact.as_ref().map(|c| c.phi),
        p32.phi_star,
        p32.offset(),
        c.rho,
        c.gamma,
        c.margin,
        p32.split,
    );
    assert!(p32.k_glob_exact.is_some_and(|k| k <= k32));
    let ws = owned_for(&r, method);
    let s32 = singles(&ws);
    let v32 = windows32(&ws, &s32);
    let v64 = windows64(&ws);
    let sys = r.mhe_problem().expect("mhe").system().clone();
    let rm64 = |m: faer::MatRef<'_, f64>| lti_model::matrix::row_major(m);
    let (a64, b64, e64) = (rm64(sys.a()), rm64(sys.b()), rm64(sys.e()));
    let (a32, b32, e32) = (to32(&a64), to32(&b64), to32(&e64));
    let layout = gl.lifted.layout();
    // The per-step deviation bound beside the global certificate (projected gradient,
    // V-FISTA and ADMM, plain or Jacobi-scaled: every method here), from Theorem 1's L_Φ and o_m (any
    // (u, y): x₀, prior and noise beyond 𝒲 included).
    let kernel = match method.kind {
        qp_iter::MethodKind::Admm(_) => mhe_embedded::Method::Admm,
        qp_iter::MethodKind::Fista(_) => mhe_embedded::Method::Fista,
        _ => mhe_embedded::Method::Pg,
    };
    let deviation = {
        let mut opts = verdict_options(r.scenario(), vec![method], None);
        opts.global_seconds = None;
        let cert = certify_closed_loop(&r, &opts).expect("certificate computes");
        let bound = DeviationBound::new(&r, &cert, method, k32).expect("builds");
        // Step 5's per-step model covers every method here (PG, V-FISTA, ADMM; plain or
        // Jacobi-scaled).
        assert!(
            bound.is_ok(),
            "{}: no deviation bound: {:?}",
            method.name(),
            bound.as_ref().err()
        );
        bound.ok().map(|bound| {
            let p64 = problem(&sys, layout.horizon, k32, kernel, (&a64, &b64, &e64), &v64);
            (p64, bound)
        })
    };
    let mut run = F32Run {
        problem: problem(&sys, layout.horizon, k32, kernel, (&a32, &b32, &e32), &v32),
        resolved: r.clone(),
        layout,
        deviation,
    };
    // [with noise, noise-free]
    let (mut worst, mut multi, mut dev) = ([0.0_f64; 2], 0.0_f64, 0.0_f64);
    for seed in 0..200 {
        let out = run.run_seed(c, p32.offset(), seed, steps);
        assert!(out.within, "seed {seed}: ‖X‖²_P left the ISS bound");
        assert!(
            out.worst <= 1.0,
            "seed {seed}: one-step ratio {}",
            out.worst
        );
        assert!(
            out.deviation <= 1.0,
            "seed {seed}: ‖x̂_f32 − x̂_f64‖ above its bound × {}",
            out.deviation
        );
        let w = &mut worst[usize::from(seed >= NOISY_SEEDS)];
        *w = w.max(out.worst);
        multi = multi.max(out.multi);
        dev = dev.max(out.deviation);
    }
    eprintln!(
        "{file}: 200 f32 runs × {steps} steps at K = {k32}: worst one-step ratio {:.4} with \
         noise, {:.4} noise-free; multi-step {multi:.4}; ‖x̂_f32 − x̂_f64‖/bound {dev:.3e}",
        worst[0], worst[1],
    );
    let has_deviation = run.deviation.is_some();
    assert!(
        dev > 0.0 || !has_deviation,
        "the f32 and f64 estimators ran identically"
    );
    // The optimised adversary (adversary.rs) on the same loop and certificate.
    let wset = &r.scenario().sets.disturbance;
    let (lo, hi) = (wset.lower().to_vec(), wset.upper().to_vec());
    let budget = adversary::Budget::from_env(steps);
    let attack = |run: &F32Run<'_>, c: &GlobalCertificate| {
        adversary::attack(run, c, p32.offset(), (&lo, &hi), budget, Outcome::score)
    };
    let clock = std::time::Instant::now();
    let found = attack(&run, c);
    eprintln!(
        "{file} {} K = {k32}: adversary ({} restarts × {} moves, {} runs × {steps} steps, \
         {:.1} s): worst one-step ratio {:.4}, multi-step {:.4} (seeded runs: {:.4}, {multi:.4}); \
         its deviation/bound {:.3e}; worst point: {}",
        method.name(),
        budget.restarts,
        budget.moves,
        found.runs,
        clock.elapsed().as_secs_f64(),
        found.outcome.worst,
        found.multi,
        worst[0].max(worst[1]),
        found.outcome.deviation,
        found.describe(lo.len(), layout.horizon),
    );
    assert!(
        found.outcome.holds(),
        "{file} {} K = {k32}: the adversary (seed {}) violates the certificate: \
         {:?} at {:?}",
        method.name(),
        budget.seed,
        found.outcome,
        found.inputs
    );
    // The same search aimed at the deviation bound: ‖x̂_f32 − x̂_f64‖ / its bound.
    if has_deviation {
        let clock = std::time::Instant::now();
        let found = adversary::attack(&run, c, p32.offset(), (&lo, &hi), budget, |o| o.deviation);
        eprintln!(
            "{file} {} K = {k32}: deviation adversary ({} runs, {:.1} s): worst deviation/bound \
             {:.3e} (seeded runs: {dev:.3e}); worst point: {}",
            method.name(),
            found.runs,
            clock.elapsed().as_secs_f64(),
            found.outcome.deviation,
            found.describe(lo.len(), layout.horizon),
        );
        assert!(
            found.outcome.deviation <= 1.0,
            "{file} {} K = {k32}: the adversary (seed {}) exceeds the deviation bound × {} at {:?}",
            method.name(),
            budget.seed,
            found.outcome.deviation,
            found.inputs
        );
    }
    // The check has teeth: without the noise's supply (γ = 0) a run violates it …
    let mut no_gamma = c.clone();
    no_gamma.gamma = 0.0;
    let refuted = (0..20).any(|seed| !run.run_seed(&no_gamma, p32.offset(), seed, steps).holds());
    assert!(refuted, "the check never failed with γ = 0");
    // … the adversary finds such a run within its budget …
    let found = attack(&run, &no_gamma);
    eprintln!(
        "{file}: with γ = 0 the adversary violates after {} runs (ratio {:.4})",
        found.runs,
        found.outcome.score()
    );
    assert!(
        !found.outcome.holds(),
        "the adversary never failed with γ = 0"
    );
    // … and, where the loop is unstable at K = 1 (the double integrator), so does K = 1.
    if refute_k1 {
        run.problem.iterations = 1;
        // The deviation bound was built for K_glob(f32).
        run.deviation = None;
        let refuted = (0..20).any(|seed| !run.run_seed(c, p32.offset(), seed, steps).holds());
        assert!(refuted, "the check never failed at K = 1");
        let found = attack(&run, c);
        eprintln!(
            "{file}: at K = 1 the adversary violates after {} runs (ratio {:.4})",
            found.runs,
            found.outcome.score()
        );
        assert!(
            !found.outcome.holds(),
            "the adversary never failed at K = 1"
        );
    }
    k32
}

#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_global_certificate_case_study() {
    f32_runs_respect_the_global_certificate("case-study.toml", Method::PG, 60, false);
}

/// The certified preset (M = 9, Theorem 1's setting) with PG: the budget table's f32 build of
/// `case-study-certified` (K = 34 by the global certificate in f32, equal to the exact K_glob).
#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_global_certificate_case_study_certified() {
    let k =
        f32_runs_respect_the_global_certificate("case-study-certified.toml", Method::PG, 60, false);
    assert_eq!(k, 34, "the f32 K_glob of docs/embedded.md's table");
}

/// The Jacobi-scaled PG (its scaled windows, the rounded scalings y⁰ = z⁰/d̃ and z = d̃·y of
/// `mhe_embedded`) at its f32 K_glob (5 on the case study; docs/theory.md "Jacobi-scaled
/// projected gradient in f32").
#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_global_certificate_case_study_pg_jacobi() {
    let k = f32_runs_respect_the_global_certificate(
        "case-study.toml",
        Method::PG.with_scaling(qp_iter::Scaling::Jacobi),
        60,
        false,
    );
    assert_eq!(k, 5, "the f32 K_glob of docs/theory.md");
}

/// FISTA-Jacobi (V-FISTA on its scaled windows with the rounded scalings) at its f32 K_glob
/// (11 on the case study, as in f64; docs/theory.md "FISTA-Jacobi in f32").
#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_global_certificate_case_study_fista_jacobi() {
    let k = f32_runs_respect_the_global_certificate(
        "case-study.toml",
        Method::FISTA.with_scaling(qp_iter::Scaling::Jacobi),
        60,
        false,
    );
    assert_eq!(k, 11, "the f32 K_glob of docs/theory.md");
}

/// ADMM-PR-Jacobi (its scaled windows, the stored ρ(H + ρI)⁻¹ and (H + ρI)⁻¹ in f32, the
/// rounded scalings) at its f32 K_glob (3 on the case study; docs/theory.md "ADMM in f32").
#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_global_certificate_case_study_admm_pr_jacobi() {
    let k = f32_runs_respect_the_global_certificate(
        "case-study.toml",
        Method::ADMM_PR.with_scaling(qp_iter::Scaling::Jacobi),
        60,
        false,
    );
    assert_eq!(k, 3, "the f32 K_glob of docs/theory.md");
}

#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_global_certificate_double_integrator() {
    f32_runs_respect_the_global_certificate("double-integrator.toml", Method::PG, 60, true);
}

/// The double integrator's f32 build of docs/embedded.md's budget table: ADMM-PR-Jacobi at its
/// f32 K_glob (52; 50 exact), and K = 1 refuted.
#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_global_certificate_double_integrator_admm_pr_jacobi() {
    let k = f32_runs_respect_the_global_certificate(
        "double-integrator.toml",
        Method::ADMM_PR.with_scaling(qp_iter::Scaling::Jacobi),
        60,
        true,
    );
    assert_eq!(k, 52, "the f32 K_glob of docs/embedded.md's budget table");
}
