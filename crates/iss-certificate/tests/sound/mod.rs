//! The soundness harness of the global loop certificate (issue 35): the real closed loop
//! (the scenario's MHE with K iterations of the method, its controller, a disturbance
//! sequence we choose) checked against ‖X_{t+1}‖²_P ≤ ρ²‖X_t‖²_P + γ²‖w_t‖², its multi-step
//! form, the lim-sup gains, and an independent re-check of the LMI. Shared by
//! tests/global_sound.rs and the CI-sized run in tests/loop_level.rs.
#![allow(dead_code)] // each test binary uses a part

pub mod plants;
pub mod sweep;

use closed_loop::ClosedLoop;
use closed_loop::scenario::{LoopOptions, ResolvedScenario, ScenarioController, ScenarioEstimator};
use faer::{Mat, Side};
use iss_certificate::lure::global::{GlobalCertificate, GlobalLoop};
use lti_model::disturbance::Disturbance;
use qp_iter::Method;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// The eight methods (plain and Jacobi-scaled presets).
pub const METHODS: [Method; 8] = Method::ALL;

/// The scenario's loop options with `method`.
pub fn options(r: &ResolvedScenario, method: Method) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(r.scenario()).expect("loop options");
    o.method = method;
    o
}

/// A disturbance that replays a fixed sequence (n_w per step; zeros past its end).
#[derive(Debug, Clone)]
pub struct Replay {
    w: Vec<f64>,
    nw: usize,
    t: usize,
}

impl Disturbance for Replay {
    fn dim(&self) -> usize {
        self.nw
    }
    fn sample(&mut self, out: &mut [f64]) {
        let a = self.t * self.nw;
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.w.get(a + i).copied().unwrap_or(0.0);
        }
        self.t += 1;
    }
    fn reseed(&mut self, _seed: u64) {
        self.t = 0;
    }
}

/// A certificate with the loop it belongs to.
#[derive(Clone, Copy)]
pub struct Checked<'a> {
    /// The loop (its lifted layout reads X_t from a run).
    pub gl: &'a GlobalLoop,
    /// The certificate.
    pub c: &'a GlobalCertificate,
}

/// What one run showed (every ratio ≤ 1 where the certificate holds).
#[derive(Debug, Clone, Copy, Default)]
pub struct RunStats {
    /// max_t (‖X_{t+1}‖²_P − γ²‖w_t‖² − slack)/(ρ²‖X_t‖²_P).
    pub one_step: f64,
    /// max_t ‖X_t‖²_P / (ρ^{2(t−M)}‖X_M‖²_P + γ²Σ_s ρ^{2(t−1−s)}‖w_s‖²) (with slack).
    pub multi: f64,
    /// max_t ‖x_t‖ and ‖x_t − x̂_t‖ over their certified bounds (transient + gain·sup‖w‖).
    pub gain: f64,
    /// The loop stopped (an error or a non-finite state).
    pub diverged: bool,
}

impl RunStats {
    /// The worst of the three ratios (∞ if diverged).
    pub fn worst(&self) -> f64 {
        if self.diverged {
            f64::INFINITY
        } else {
            self.one_step.max(self.multi).max(self.gain)
        }
    }
}

/// The scenario's loop with a disturbance of our choice.
pub type Loop<D> = ClosedLoop<ScenarioEstimator, ScenarioController, D>;

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// The closed loop of `o` (method, K, controller) from x₀ and the prior, driven by `d`.
pub fn build<D: Disturbance>(
    r: &ResolvedScenario,
    o: &LoopOptions,
    x0: &[f64],
    prior: &[f64],
    d: D,
    steps: usize,
) -> Loop<D> {
    let mut est = r
        .estimator(o.method, o.iterations, false)
        .expect("estimator");
    est.reset(prior).expect("prior");
    let ctrl = r.controller(o.controller).expect("controller");
    ClosedLoop::new(r.scenario().plant.clone(), est, ctrl, d, x0, steps).expect("loop")
}

/// One run checked against the certificate: `steps` steps from (x₀, prior) under the
/// sequence `w` (n_w per step).
pub fn run(
    r: &ResolvedScenario,
    o: &LoopOptions,
    ck: Checked<'_>,
    x0: &[f64],
    prior: &[f64],
    w: &[f64],
    steps: usize,
) -> RunStats {
    let nw = r.scenario().plant.nw();
    let d = Replay {
        w: w.to_vec(),
        nw,
        t: 0,
    };
    check(&mut build(r, o, x0, prior, d, steps), ck, steps)
}

/// Runs `cl` to `steps` and checks every step against the certificate.
pub fn check<D: Disturbance>(cl: &mut Loop<D>, ck: Checked<'_>, steps: usize) -> RunStats {
    let (gl, c) = (ck.gl, ck.c);
    let lay = gl.lifted.layout();
    let (m, nx) = (lay.horizon, lay.nx);
    let mut st = RunStats::default();
    for _ in 0..m {
        if cl.step().is_err() {
            st.diverged = true;
            return st;
        }
    }
    let (r2, g2) = (c.rho * c.rho, c.gamma * c.gamma);
    // ‖R X‖² ≤ λ_max(R P⁻¹ Rᵀ)‖X‖²_P, λ from the certificate's own gains.
    let lam_x = (c.gain_x / c.gamma).powi(2) * (1.0 - r2);
    let lam_h = ((c.gain_e - c.gain_x) / c.gamma).powi(2) * (1.0 - r2);
    let mut x = gl.lifted_state(cl).expect("X_t at t ≥ M");
    let v0 = c.storage(&x);
    let (mut s, mut wsup) = (v0, 0.0_f64);
    let est = lay.estimates(m - 1);
    for t in m..steps - 1 {
        if cl.step().is_err() {
            st.diverged = true;
            return st;
        }
        let tr = cl.trace();
        let wt: Vec<f64> = tr
            .w1(t)
            .expect("w¹")
            .iter()
            .chain(tr.w2(t).expect("w²"))
            .copied()
            .collect();
        let w2: f64 = wt.iter().map(|v| v * v).sum();
        wsup = wsup.max(w2.sqrt());
        let xn = gl.lifted_state(cl).expect("X_t at t ≥ M");
        if xn.iter().any(|v| !v.is_finite()) {
            st.diverged = true;
            return st;
        }
        let (v, vn) = (c.storage(&x), c.storage(&xn));
        let slack = 1e-9 * (vn.abs() + r2 * v + g2 * w2);
        let ratio = |num: f64, den: f64| {
            if den > 1e-300 {
                num / den
            } else if num > 0.0 {
                f64::INFINITY
            } else {
                0.0
            }
        };
        st.one_step = st.one_step.max(ratio(vn - g2 * w2 - slack, r2 * v));
        s = r2 * s + g2 * w2;
        st.multi = st.multi.max(ratio(vn - 1e-9 * (vn.abs() + s), s));
        // ‖x_t‖ (X_t) and ‖x_t − x̂_t‖ (x̂_t in X_{t+1}) against transient + gain·sup‖w‖.
        let k = (t - m) as f64;
        let tx = (lam_x * r2.powf(k) * v0).sqrt();
        let th = (lam_h * r2.powf(k + 1.0) * v0).sqrt();
        let ex: Vec<f64> = (0..nx).map(|i| x[i] - xn[est + i]).collect();
        let bx = tx + c.gain_x * wsup;
        let be = tx + th + c.gain_e * wsup;
        let tol = 1e-9 * (bx + be);
        st.gain = st.gain.max(ratio(norm(&x[..nx]) - tol, bx));
        st.gain = st.gain.max(ratio(norm(&ex) - tol, be));
        x = xn;
    }
    st
}

/// The independent check of issue 35 item 4, re-done here from the loop's public maps: the
/// supply Π is re-assembled (per-row forms −z_i g_i for σ₁, σ₃; σ₂ from z*, the warm start
/// and d; −γ²‖w‖²), the LMI X⁺ᵀPX⁺ − ρ²E_XᵀPE_X + Π formed afresh and its largest
/// eigenvalue taken by faer's symmetric eigensolver (not the library's Jacobi), after a
/// diagonal equilibration; P ≻ 0 by the same. Returns the LMI's margin −λ_max/‖scale‖, or
/// why it fails (a margin within 10·n·ε of the rounding scale fails).
pub fn independent_margin(
    gl: &GlobalLoop,
    c: &GlobalCertificate,
    nw: usize,
) -> Result<f64, String> {
    let (n, nc) = (gl.n_x(), gl.n_zeta());
    let lay = gl.lifted.layout();
    let nz = lay.nz;
    let (nm, nu) = gl.bounded_rows();
    let mut pi = Mat::<f64>::zeros(nc, nc);
    for r in 0..nm + nu {
        let l = if c.lambda.is_empty() {
            if r < nm { c.tau[0] } else { c.tau[1] }
        } else {
            c.lambda[r]
        };
        if l != 0.0 {
            pi += gl.row_form(r) * faer::Scale(l);
        }
    }
    // σ₂ = φ²‖D⁻¹(z⁰ − z*)‖² − ‖D⁻¹d‖², z⁰ the warm start in X.
    let zs = gl.zstar_map();
    let ws = lay.warm_start();
    let a = Mat::from_fn(nz, nc, |i, j| {
        gl.d_inv[i] * (f64::from(u8::from(j == ws + i)) - zs[(i, j)])
    });
    let b = Mat::from_fn(nz, nc, |i, j| {
        gl.d_inv[i] * f64::from(u8::from(j == gl.d_offset() + i))
    });
    pi += a.transpose() * &a * faer::Scale(c.phi * c.phi);
    pi -= b.transpose() * &b;
    for k in nc - nw..nc {
        pi[(k, k)] -= c.gamma * c.gamma;
    }
    let xp = gl.x_plus_map();
    let p = &c.p;
    let mut lmi = xp.transpose() * p * xp + &pi;
    let abs = |m: &Mat<f64>| Mat::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)].abs());
    let (xa, pa) = (abs(&xp.to_owned()), abs(p));
    let mut scale = xa.transpose() * &pa * &xa + abs(&pi);
    for i in 0..n {
        for j in 0..n {
            lmi[(i, j)] -= c.rho * c.rho * p[(i, j)];
            scale[(i, j)] += c.rho * c.rho * pa[(i, j)];
        }
    }
    let top = equilibrated_extreme(&lmi, &scale, true)?;
    let pmin = equilibrated_extreme(p, &pa, false)?;
    if pmin <= 0.0 {
        return Err(format!(
            "P is not positive definite beyond rounding ({pmin:.3e})"
        ));
    }
    if top >= 0.0 {
        return Err(format!(
            "the LMI is not negative definite beyond rounding ({top:.3e})"
        ));
    }
    Ok(-top)
}

/// λ_max (`top`) or λ_min of D m D, D = diag(scale)^(−½), relative to ‖D scale D‖_∞, minus
/// (for λ_max) or plus a 10·n·ε rounding allowance (so a sign beyond rounding survives).
fn equilibrated_extreme(m: &Mat<f64>, scale: &Mat<f64>, top: bool) -> Result<f64, String> {
    let n = m.nrows();
    let d: Vec<f64> = (0..n)
        .map(|i| {
            let s = scale[(i, i)];
            if s > 0.0 && s.is_finite() {
                1.0 / s.sqrt()
            } else {
                1.0
            }
        })
        .collect();
    let me = Mat::from_fn(n, n, |i, j| 0.5 * d[i] * d[j] * (m[(i, j)] + m[(j, i)]));
    let se = (0..n)
        .map(|i| (0..n).map(|j| d[i] * d[j] * scale[(i, j)]).sum::<f64>())
        .fold(0.0_f64, f64::max)
        .max(f64::MIN_POSITIVE);
    let ev = me
        .self_adjoint_eigenvalues(Side::Lower)
        .map_err(|e| format!("eigenvalues: {e:?}"))?;
    let allowance = 10.0 * n as f64 * f64::EPSILON;
    Ok(if top {
        ev.last().copied().unwrap_or(0.0) / se + allowance
    } else {
        ev.first().copied().unwrap_or(0.0) / se - allowance
    })
}

/// The disturbance box (n_w bounds) of the scenario.
pub fn w_box(r: &ResolvedScenario) -> (Vec<f64>, Vec<f64>) {
    let set = &r.scenario().sets.disturbance;
    (set.lower().to_vec(), set.upper().to_vec())
}

/// The adversary's budget.
#[derive(Debug, Clone, Copy)]
pub struct Budget {
    /// Random restarts.
    pub restarts: usize,
    /// Hill-climbing moves per restart.
    pub moves: usize,
    /// Steps per run after the window fills (T − M).
    pub horizon: usize,
}

/// One point of the search: x₀, prior, and a vertex pattern s ∈ {−1, 0, 1} per w entry
/// (−1: the lower bound, 1: the upper).
#[derive(Debug, Clone)]
struct Point {
    x0: Vec<f64>,
    prior: Vec<f64>,
    s: Vec<i8>,
}

fn draw(rng: &mut ChaCha8Rng, nx: usize, nws: usize, wbar: f64) -> Point {
    // Initial states and errors from 10⁻² to 10⁶ times the noise bound: large enough to
    // saturate any input box and any 𝒲 clamp of the MHE, small enough to leave w dominant.
    let mag = wbar * 10f64.powf(rng.random_range(-2.0..6.0));
    let err = wbar * 10f64.powf(rng.random_range(-2.0..6.0));
    let x0: Vec<f64> = (0..nx).map(|_| mag * rng.random_range(-1.0..1.0)).collect();
    let prior = x0
        .iter()
        .map(|x| x + err * rng.random_range(-1.0..1.0))
        .collect();
    let zero = rng.random_bool(0.15);
    let s = (0..nws)
        .map(|_| {
            if zero {
                0
            } else if rng.random_bool(0.5) {
                1
            } else {
                -1
            }
        })
        .collect();
    Point { x0, prior, s }
}

fn mutate(rng: &mut ChaCha8Rng, p: &Point, nw: usize) -> Point {
    let mut q = p.clone();
    let nx = q.x0.len();
    match rng.random_range(0..5) {
        0 => {
            let i = rng.random_range(0..q.s.len());
            q.s[i] = if q.s[i] == 1 { -1 } else { 1 };
        }
        1 => {
            let t = rng.random_range(0..q.s.len() / nw);
            for v in &mut q.s[t * nw..(t + 1) * nw] {
                *v = if rng.random_bool(0.5) { 1 } else { -1 };
            }
        }
        2 => {
            let f = if rng.random_bool(0.5) { 2.0 } else { 0.5 };
            let err: Vec<f64> = q.prior.iter().zip(&q.x0).map(|(a, b)| a - b).collect();
            for (i, e) in err.iter().enumerate() {
                q.prior[i] = q.x0[i] + f * e;
            }
        }
        3 => {
            let f = if rng.random_bool(0.5) { 2.0 } else { 0.5 };
            for i in 0..nx {
                let e = q.prior[i] - q.x0[i];
                q.x0[i] *= f;
                q.prior[i] = q.x0[i] + e;
            }
        }
        _ => {
            let i = rng.random_range(0..nx);
            let scale =
                q.x0.iter()
                    .chain(&q.prior)
                    .fold(1e-6_f64, |a, v| a.max(v.abs()));
            q.prior[i] += scale * rng.random_range(-1.0..1.0);
        }
    }
    q
}

/// The optimised adversary: random restarts + hill climbing over (x₀, prior, a vertex
/// sequence of the w box) maximising the worst ratio of [`run`] (one-step, multi-step,
/// gains). Returns the worst stats found and the number of runs.
pub fn adversary(
    r: &ResolvedScenario,
    o: &LoopOptions,
    ck: Checked<'_>,
    budget: Budget,
    rng: &mut ChaCha8Rng,
) -> (RunStats, usize) {
    let (lo, hi) = w_box(r);
    let nw = lo.len();
    let nx = ck.gl.lifted.layout().nx;
    let m = ck.gl.lifted.layout().horizon;
    let steps = m + budget.horizon;
    let wbar = lo
        .iter()
        .chain(&hi)
        .fold(0.0_f64, |a, v| a.max(v.abs()))
        .max(1e-12);
    let eval = |p: &Point| {
        let w: Vec<f64> =
            p.s.iter()
                .enumerate()
                .map(|(i, &s)| match s {
                    1 => hi[i % nw],
                    -1 => lo[i % nw],
                    _ => 0.0,
                })
                .collect();
        run(r, o, ck, &p.x0, &p.prior, &w, steps)
    };
    let (mut worst, mut runs) = (RunStats::default(), 0);
    for _ in 0..budget.restarts {
        let mut p = draw(rng, nx, steps * nw, wbar);
        let mut f = eval(&p);
        runs += 1;
        for _ in 0..budget.moves {
            if f.worst() > 1.0 {
                break;
            }
            let q = mutate(rng, &p, nw);
            let g = eval(&q);
            runs += 1;
            if g.worst() >= f.worst() {
                p = q;
                f = g;
            }
        }
        if f.worst() > worst.worst() {
            worst = f;
        }
        if worst.worst() > 1.0 {
            break;
        }
    }
    (worst, runs)
}

/// Random admissible runs: x₀, prior and uniform w in the box; returns the worst stats.
pub fn random_runs(
    r: &ResolvedScenario,
    o: &LoopOptions,
    ck: Checked<'_>,
    runs: usize,
    steps_after: usize,
    rng: &mut ChaCha8Rng,
) -> RunStats {
    let (lo, hi) = w_box(r);
    let nw = lo.len();
    let nx = ck.gl.lifted.layout().nx;
    let steps = ck.gl.lifted.layout().horizon + steps_after;
    let wbar = lo
        .iter()
        .chain(&hi)
        .fold(0.0_f64, |a, v| a.max(v.abs()))
        .max(1e-12);
    let mut worst = RunStats::default();
    for _ in 0..runs {
        let p = draw(rng, nx, 0, wbar);
        let w: Vec<f64> = (0..steps * nw)
            .map(|i| rng.random_range(lo[i % nw]..=hi[i % nw]))
            .collect();
        let s = run(r, o, ck, &p.x0, &p.prior, &w, steps);
        if s.worst() > worst.worst() {
            worst = s;
        }
    }
    worst
}
