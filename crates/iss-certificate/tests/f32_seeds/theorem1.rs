//! Theorem 1 with the f32 rounding folded in (docs/theory.md "Certified f32: rounding as an
//! input", steps 1–5; `certificate::precision`) against 200 closed-loop seeds with
//! `mhe_embedded` in f32 at the f32 K_min, on the Rao–Rawlings–Lee pair (the shipped
//! scenarios it certifies). Per step: step 3's bound on ε_t (the iteration's rounding model
//! of `qp_iter::rounding` folded in), the propagation's rounding of x̂ (step 4), the
//! per-step bound on ‖x̂_f32 − x̂_f64‖ (`DeviationBound`, plain and Jacobi-scaled); per run: Props. 1 and 3's
//! trajectory inequalities with the perturbed gains, the offset c_d/(1 − φ_u) and the
//! rounding's k_r·sup‖r‖. References: the exact optimum z*_t of each window (active set, in
//! f64) at the exact data θ_t (the f32 run's own prior), and the same estimator in f64.
//!
//! The plant of the pair has B = 0 (the MPC is inert, u = 0), so the plant's trajectory does
//! not depend on the estimate: the scenario's std loop gives x, w and y for both estimators.

use super::data::{norm, owned_for, singles, to32, windows32, windows64};
use super::scenario;
use closed_loop::record::Trace;
use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario};
use iss_certificate::analysis::{GainsAtK, IssAnalysis};
use iss_certificate::certificate::precision::{
    DeviationBound, Scalar, WindowRounding, certify_scalar, window_roundings,
};
use iss_certificate::certificate::{
    CertificateOptions, ClosedLoopCertificate, certify_closed_loop,
};
use iss_certificate::coverage::verdict_options;
use qp_iter::Method;
use qp_iter::active_set::{ActiveSetSettings, ActiveSetSolver};
use qp_iter::rounding::F32_UNIT_ROUNDOFF;

/// The certificate's numbers a run is checked against.
struct Claim {
    resolved: ResolvedScenario,
    /// Projected gradient, plain or Jacobi-scaled (both run `mhe_embedded::Method::Pg`; the
    /// scaling is in the window data).
    method: Method,
    cert: ClosedLoopCertificate,
    /// K_min in f32 (the run's K).
    k: usize,
    /// Per window m: PG's one-step f32 models (their propagation rounding is every
    /// method's).
    windows: Vec<WindowRounding>,
    /// φ_u(K): projected gradient's qᴷ, q = max_m (r_m + a_m); the Jacobi variant's
    /// max_m κ(D_m)φ_u,m (`ScalarCertificate::phi_u`).
    phi_u: f64,
    /// g_d, c_d: the rounding's gain from ‖θ_t‖ into ε_t and its constant.
    g_d: f64,
    c_d: f64,
    /// The gains of Props. 1 and 3 with φ → φ_u and φL_Φ → φ_uL_Φ + g_d.
    gains: GainsAtK,
    /// k_r: the gain of sup‖r_t‖ (x̂'s propagation rounding) into e_t.
    k_r: f64,
    analysis: IssAnalysis,
}

impl Claim {
    /// Theorem 1 for PG on `file` with the options `coverage::verdict` uses (no global
    /// section: Theorem 1 alone), in f32.
    fn new(file: &str, method: Method) -> Self {
        let resolved = scenario(file);
        let mut opts = verdict_options(resolved.scenario(), vec![method], None);
        opts.global_seconds = None;
        let cert = certify_closed_loop(&resolved, &opts).expect("certificate computes");
        let k_max = CertificateOptions::default().k_max;
        let sc = certify_scalar(&resolved, &cert, method, Scalar::F32, k_max).expect("runs");
        let k = sc
            .k_min
            .unwrap_or_else(|| panic!("{file}: f32 void: {:?}", sc.reason));
        let k64 = sc.k_min_f64.expect("certified in f64");
        assert!(k >= k64, "K_min(f32) = {k} < K_min(f64) = {k64}");
        let windows = window_roundings(&resolved, &cert, Method::PG, F32_UNIT_ROUNDOFF)
            .expect("builds")
            .expect("PG is covered");
        let analysis = cert.solver(method).expect("certified").analysis.clone();
        let phi_u = sc.phi_u.expect("φ_u at K_min");
        if method == Method::PG {
            let qk = sc.perturbed_rate.powi(i32::try_from(k).expect("K fits"));
            assert!((phi_u - qk).abs() <= 1e-12 * qk, "PG: φ_u = qᴷ");
        }
        let gains = analysis.at_perturbed(k, phi_u, sc.rounding_gain);
        // docs/theory.md step 4: κ_r = 1 + √Λ^P_P/(1 − √ρ^M), S_e = √(2Λ^H̄_P)(φ_uL_Φ + g_d)
        // ·2(M L_π + 1), k_r = (1 + S_e)κ_r.
        let (a, m) = (&analysis, analysis.inputs.horizon);
        let kappa_r = 1.0 + a.lambda_pp.sqrt() / (1.0 - a.rho.powi(m as i32).sqrt());
        let s_e = (2.0 * a.lambda_hp).sqrt()
            * (phi_u * a.l_phi_used + sc.rounding_gain)
            * 2.0
            * (m as f64 * a.inputs.l_pi + 1.0);
        eprintln!(
            "{file} {}: K_min f64 {k64}, f32 {k}; q {:.6}, φ_u(K) {phi_u:.3e}, g_d {:.3e}, c_d \
             {:.3e}, self-loop {:?}, margin {:?}",
            method.name(),
            sc.perturbed_rate,
            sc.rounding_gain,
            sc.rounding_offset,
            sc.self_loop,
            sc.margin
        );
        Self {
            resolved,
            method,
            cert,
            k,
            windows,
            phi_u,
            g_d: sc.rounding_gain,
            c_d: sc.rounding_offset,
            gains,
            k_r: (1.0 + s_e) * kappa_r,
            analysis,
        }
    }
}

/// One step t of the f32 run against its references.
#[derive(Debug, Clone, Copy, Default)]
struct StepRecord {
    /// ε_t = ‖zᴷ_t − z*_t‖ (f32 iterate, exact optimum at the exact data θ_t).
    eps: f64,
    /// ‖e_t‖ = ‖x_t − x̂_t‖ of the f32 run.
    e: f64,
    /// ‖θ_t‖ (the f32 run's prior, the exact u and y).
    theta: f64,
    /// ‖r_t‖: the computed x̂ against the exact propagation of the computed zᴷ.
    r: f64,
    /// Step 3's bound on ε_t and its part without the rounding (φ_u‖z⁰ − z*‖).
    eps_bound: f64,
    eps_exact_part: f64,
    /// Step 4's bound on ‖r_t‖.
    r_bound: f64,
    /// ‖x̂_f32 − x̂_f64‖ and `DeviationBound`'s bound.
    dev: f64,
    dev_bound: f64,
    /// ‖x_t‖ and ‖w_t‖.
    x: f64,
    w: f64,
    /// w_t ∈ 𝒲 (the certificate's claim covers the run up to the first w_t ∉ 𝒲).
    w_in_set: bool,
}

/// x̂(z) = the exact propagation through window m of z = (x₀, w_0, …, w_{m−1}) with the u
/// window `us` (n_u per step), in f64.
fn propagate(r: &ResolvedScenario, z: &[f64], us: &[f64], m: usize) -> Vec<f64> {
    let sys = r.mhe_problem().expect("mhe").system();
    let (nx, nu, nw1, nw) = (sys.nx(), sys.nu(), sys.nw1(), sys.nw());
    let mut x = z[..nx].to_vec();
    for j in 0..m {
        let w1 = &z[nx + j * nw..nx + j * nw + nw1];
        let u = &us[j * nu..(j + 1) * nu];
        x = (0..nx)
            .map(|i| {
                let a: f64 = (0..nx).map(|k| sys.a()[(i, k)] * x[k]).sum();
                let b: f64 = (0..nu).map(|k| sys.b()[(i, k)] * u[k]).sum();
                let e: f64 = (0..nw1).map(|k| sys.e()[(i, k)] * w1[k]).sum();
                a + b + e
            })
            .collect();
    }
    x
}

/// θ = (prior, u_{t−m..t−1}, y_{t−m..t−1}) of step t from the trace and a prior.
fn theta(trace: &Trace, t: usize, m: usize, prior: &[f64]) -> Vec<f64> {
    let mut th = prior.to_vec();
    th.extend((t - m..t).flat_map(|s| trace.u(s).expect("u").to_vec()));
    th.extend((t - m..t).flat_map(|s| trace.y(s).expect("y").to_vec()));
    th
}

impl Claim {
    /// The scenario's std loop of `seed` (the plant's x, w, y; u = 0).
    fn trace(&self, seed: u64, steps: usize) -> Trace {
        let mut o = LoopOptions::from_scenario(self.resolved.scenario()).expect("options");
        o.method = Method::PG;
        o = o.with_iterations(1).expect("K is in range");
        o.controller = ControllerChoice::ExactMpc;
        o.seed = seed;
        o.steps = steps;
        let mut lp = self.resolved.build_loop(&o).expect("loop builds");
        let trace = lp.run().expect("loop runs").clone();
        let u_zero = (0..trace.len()).all(|t| trace.u(t).expect("u").iter().all(|v| *v == 0.0));
        assert!(u_zero, "B = 0: the MPC is inert");
        trace
    }

    /// One seed: per step t < `steps`, the f32 run against its references.
    fn run(&self, seed: u64, steps: usize) -> Vec<StepRecord> {
        let trace = self.trace(seed, steps);
        let r = &self.resolved;
        let problem = r.mhe_problem().expect("mhe");
        let sys = problem.system();
        let (nx, mm) = (sys.nx(), self.cert.horizon);
        let ws = owned_for(r, self.method);
        let (v64, s32) = (windows64(&ws), singles(&ws));
        let v32 = windows32(&ws, &s32);
        let rm = |m: faer::MatRef<'_, f64>| lti_model::matrix::row_major(m);
        let (a, b, e) = (rm(sys.a()), rm(sys.b()), rm(sys.e()));
        let (a32, b32, e32) = (to32(&a), to32(&b), to32(&e));
        let p64 = mhe_embedded::Problem {
            nx,
            nu: sys.nu(),
            ny: sys.ny(),
            nw1: sys.nw1(),
            nw2: sys.nw2(),
            horizon: mm,
            iterations: self.k,
            method: mhe_embedded::Method::Pg,
            warm_start: mhe_embedded::WarmStart::Paper,
            a: &a,
            b: &b,
            e: &e,
            windows: &v64,
        };
        let p32 = mhe_embedded::Problem {
            nx,
            nu: p64.nu,
            ny: p64.ny,
            nw1: p64.nw1,
            nw2: p64.nw2,
            horizon: mm,
            iterations: self.k,
            method: p64.method,
            warm_start: p64.warm_start,
            a: &a32,
            b: &b32,
            e: &e32,
            windows: &v32,
        };
        let prior = r.scenario().simulation.prior.clone();
        let mut w64 = vec![0f64; mhe_embedded::MheRt::workspace_len(&p64)];
        let mut w32 = vec![0f32; mhe_embedded::MheRt::workspace_len(&p32)];
        let mut m64 = mhe_embedded::MheRt::new(&p64, &prior, &mut w64).expect("dims");
        let mut m32 = mhe_embedded::MheRt::new(&p32, &to32(&prior), &mut w32).expect("dims");
        let mut exact: Vec<ActiveSetSolver> = (problem.windows().iter())
            .map(|w| ActiveSetSolver::new(w.qp(), ActiveSetSettings::default()).expect("QP"))
            .collect();
        // The per-step deviation bound of projected gradient, plain or Jacobi-scaled (in the
        // scaled coordinates, session 28).
        let mut dev = DeviationBound::new(r, &self.cert, self.method, self.k)
            .expect("builds")
            .expect("PG and PG-Jacobi are covered");
        let set = &r.scenario().sets.disturbance;
        let (mut x32s, mut x64s) = (Vec::<Vec<f64>>::new(), Vec::<Vec<f64>>::new());
        let mut out = Vec::with_capacity(steps);
        for t in 0..steps {
            let m = t.min(mm);
            let n = problem.windows()[m].qp().n();
            let pick = |xs: &[Vec<f64>]| {
                if t <= mm {
                    prior.clone()
                } else {
                    xs[t - mm].clone()
                }
            };
            let (th32, th64) = (
                theta(&trace, t, m, &pick(&x32s)),
                theta(&trace, t, m, &pick(&x64s)),
            );
            let z0 = super::data::widen(m32.start());
            let xh32: Vec<f64> = m32.estimate().iter().map(|v| f64::from(*v)).collect();
            let zk = super::data::widen(m32.iterate());
            let xh64 = m64.estimate().to_vec();
            exact[m].solve(&th32).expect("the exact MHE solves");
            let zs = exact[m].z();
            let diff = |p: &[f64], q: &[f64]| {
                norm(&p.iter().zip(q).map(|(a, b)| a - b).collect::<Vec<_>>())
            };
            let wr = &self.windows[m];
            let us: Vec<f64> = th32[nx..nx + m * sys.nu()].to_vec();
            let eps_exact_part = self.phi_u * diff(&z0[..n], zs);
            let theta_n = norm(&th32);
            let p = &wr.propagation;
            let w = trace.w(t).expect("w");
            let w_in_set = (w.iter().zip(set.lower().iter().zip(set.upper())))
                .all(|(v, (l, h))| *l <= *v && *v <= *h);
            out.push(StepRecord {
                eps: diff(&zk[..n], zs),
                e: diff(trace.x(t).expect("x"), &xh32),
                theta: theta_n,
                r: diff(&xh32, &propagate(r, &zk[..n], &us, m)),
                eps_bound: eps_exact_part + self.g_d * theta_n + self.c_d,
                eps_exact_part,
                r_bound: p.from_z * norm(&zk[..n]) + p.from_u * norm(&us),
                dev: diff(&xh32, &xh64),
                dev_bound: dev.step(norm(&th64), norm(&th64[nx..nx + m * sys.nu()])),
                x: trace.x_norms()[t],
                w: norm(w),
                w_in_set,
            });
            let (u, y) = (trace.u(t).expect("u"), trace.y(t).expect("y"));
            m64.push(u, y).expect("finite");
            m32.push(&to32(u), &to32(y)).expect("finite");
            x32s.push(xh32);
            x64s.push(xh64);
        }
        out
    }
}

/// The largest lhs/rhs of Props. 1 and 3 (f32 form, module docs) over t ≥ 1 of one run, up
/// to the first w_t ∉ 𝒲: [Prop. 1, Prop. 3].
fn props(c: &Claim, recs: &[StepRecord]) -> [f64; 2] {
    let (g, a) = (&c.gains, &c.analysis);
    let m = a.inputs.horizon;
    let offsets = &c.cert.lemma1_origin_offsets;
    let sqrt_rho = a.rho.sqrt();
    let two_lhp = (2.0 * a.lambda_hp).sqrt();
    let (mut sx, mut se, mut sw, mut seps, mut ssig, mut sr) = (0f64, 0f64, 0f64, 0f64, 0f64, 0f64);
    let mut worst = [0f64; 2];
    for (t, s) in recs.iter().enumerate() {
        if t > 0 {
            let p = &recs[t - 1];
            if !p.w_in_set {
                break;
            }
            (sx, se, sw, seps) = (sx.max(p.x), se.max(p.e), sw.max(p.w), seps.max(p.eps));
        }
        // σ_t of the mended Lemma 1 while the window grows (t ≤ M), with o_m and L_Φ.
        if (1..=m).contains(&t) {
            let o = (offsets[t - 1] + offsets[t]) / a.l_phi_used;
            ssig = ssig.max(recs[t - 1].theta + s.theta + o);
        }
        sr = sr.max(s.r);
        let ti = i32::try_from(t).expect("t fits");
        let rhs1 = g.phi.powi(ti) * recs[0].eps
            + g.gamma21 * sx
            + g.gamma23 * se
            + g.gamma2w * sw
            + g.gamma2sigma * ssig
            + c.c_d / (1.0 - g.phi);
        let rhs3 = g.c_e * sqrt_rho.powi(ti) * recs[0].e
            + two_lhp * g.c1 * sx
            + g.c_eps * seps
            + g.c_w * sw
            + g.gamma3sigma * ssig
            + c.k_r * sr;
        if t > 0 {
            worst[0] = worst[0].max(s.eps / rhs1);
            worst[1] = worst[1].max(s.e / rhs3);
        }
    }
    worst
}

/// `method` (PG, plain or Jacobi) on `file` at the f32 K_min: 200 seeds × `steps` steps (module docs). Every per-step
/// bound and both trajectory inequalities hold; the rounding terms are needed (some step's
/// ε_t exceeds the exact iteration's φ_u‖z⁰ − z*‖ alone) and the f32 run deviates from the
/// f64 one. Returns K_min(f32).
pub(super) fn f32_runs_respect_theorem_1(file: &str, method: Method, steps: usize) -> usize {
    let claim = Claim::new(file, method);
    // [ε_t / step 3, ‖r_t‖ / step 4, deviation / its bound, Prop. 1, Prop. 3]
    let mut worst = [0f64; 5];
    let (mut needs_rounding, mut largest_dev, mut left_set) = (0usize, 0f64, 0usize);
    for seed in 0..200 {
        let recs = claim.run(seed, steps);
        for (t, s) in recs.iter().enumerate() {
            let ratios = [
                s.eps / s.eps_bound,
                s.r / s.r_bound.max(f64::MIN_POSITIVE),
                s.dev / s.dev_bound,
            ];
            assert!(
                ratios.iter().all(|r| *r <= 1.0),
                "seed {seed}, t = {t}: {s:?}"
            );
            for (w, r) in worst.iter_mut().zip(ratios) {
                *w = w.max(r);
            }
            needs_rounding += usize::from(s.eps > s.eps_exact_part);
            largest_dev = largest_dev.max(s.dev);
        }
        left_set += usize::from(recs.iter().any(|s| !s.w_in_set));
        let [p1, p3] = props(&claim, &recs);
        assert!(
            p1 <= 1.0 && p3 <= 1.0,
            "seed {seed}: Prop. 1 ratio {p1}, Prop. 3 ratio {p3}"
        );
        worst[3] = worst[3].max(p1);
        worst[4] = worst[4].max(p3);
    }
    eprintln!(
        "{file} {}: 200 f32 runs × {steps} steps at K = {}: worst ratio ε_t/step 3 {:.3e}, \
         ‖r_t‖/step 4 {:.3e}, deviation/bound {:.3e}, Prop. 1 {:.3e}, Prop. 3 {:.3e}; \
         steps needing the rounding term {needs_rounding}; max ‖x̂_f32 − x̂_f64‖ \
         {largest_dev:.3e}; runs with some w_t ∉ 𝒲 {left_set}",
        method.name(),
        claim.k,
        worst[0],
        worst[1],
        worst[2],
        worst[3],
        worst[4]
    );
    assert!(needs_rounding > 0, "no step needed the rounding term");
    assert!(largest_dev > 0.0, "f32 and f64 ran identically");
    claim.k
}

#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_theorem_1_rao_rawlings_lee() {
    f32_runs_respect_theorem_1("rao-rawlings-lee.toml", Method::PG, 40);
}

#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_theorem_1_rao_rawlings_lee_half_normal() {
    f32_runs_respect_theorem_1("rao-rawlings-lee-half-normal.toml", Method::PG, 40);
}

/// The Jacobi-scaled projected gradient, certified in f32 by Theorem 1 since session 27 (its
/// K-step model, "Theorem 1 in f32 for every method"): K = 141 against 131 in f64.
#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn f32_seeds_theorem_1_rao_rawlings_lee_pg_jacobi() {
    let k = f32_runs_respect_theorem_1(
        "rao-rawlings-lee.toml",
        Method::PG.with_scaling(qp_iter::Scaling::Jacobi),
        40,
    );
    assert_eq!(k, 141);
}
