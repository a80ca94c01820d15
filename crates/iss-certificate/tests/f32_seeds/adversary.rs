//! An optimised adversary against the f32 global certificate (Theorem L3u): hill climbing
//! with random restarts over x₀, the prior's error and a w sequence, each candidate one
//! closed-loop run of [`F32Run::run`] (`mhe_embedded` in f32 in the loop: the seeded runs'
//! loop, the same code), maximising the larger of the worst one-step ratio
//! (‖X_{t+1}‖²_P − γ²(‖w_t‖² + o²))/(ρ²‖X_t‖²_P) and the multi-step ratio of [`Outcome`].
//! The w sequence is per step a scale a_t ∈ [0, 3] times a pattern in {−1, 0, 1}^{n_w} (−1:
//! 𝒲's lower bound, 1: its upper, 0: zero): vertices of 𝒲, zero, and scaled vertices;
//! noise-free stretches (a_t = 0) are drawn and mutated on purpose, since there the rounding
//! offset γ²o² alone must cover the supply. Half the moves change w at or just before the
//! step of the current worst ratio.
//!
//! Called from `global::f32_runs_respect_the_global_certificate` on the certificate it has
//! just computed (one solve per scenario/method for the seeds and the adversary), and on its
//! refuted variants (γ = 0, K = 1). The budget is [`Budget::from_env`]: the CI's
//! [`DEFAULT_RESTARTS`] restarts × [`DEFAULT_MOVES`] moves (+ 1 start each) from seed
//! [`DEFAULT_SEED`], or `F32_ADVERSARY_RESTARTS`, `F32_ADVERSARY_MOVES`,
//! `F32_ADVERSARY_SEED` for hand runs, e.g.
//! `F32_ADVERSARY_RESTARTS=30 F32_ADVERSARY_MOVES=100 cargo test --release -p
//! iss-certificate --test loop_level -- --ignored f32_seeds --nocapture` (3 030 runs per
//! pair: ≈ 35 s for the double integrator's PG at K = 664, seconds for the others).

use super::global::{F32Run, Inputs, Outcome};
use iss_certificate::lure::global::GlobalCertificate;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Restarts of the CI budget.
pub(super) const DEFAULT_RESTARTS: usize = 12;
/// Hill-climbing moves per restart of the CI budget.
pub(super) const DEFAULT_MOVES: usize = 60;
/// The search's seed of the CI budget.
pub(super) const DEFAULT_SEED: u64 = 36;
/// The largest scale of 𝒲's vertices (the seeded runs' 3 × 𝒲).
const MAX_SCALE: f64 = 3.0;

/// The adversary's budget.
#[derive(Debug, Clone, Copy)]
pub(super) struct Budget {
    /// Random restarts.
    pub(super) restarts: usize,
    /// Hill-climbing moves per restart.
    pub(super) moves: usize,
    /// Steps per run (from t = 0).
    pub(super) steps: usize,
    /// The search's seed.
    pub(super) seed: u64,
}

impl Budget {
    /// The CI budget, or `F32_ADVERSARY_RESTARTS` / `F32_ADVERSARY_MOVES` /
    /// `F32_ADVERSARY_SEED` where set.
    pub(super) fn from_env(steps: usize) -> Self {
        let var = |name: &str, default: usize| {
            std::env::var(name).map_or(default, |v| {
                v.parse()
                    .unwrap_or_else(|_| panic!("{name} = {v:?} is not a count"))
            })
        };
        Budget {
            restarts: var("F32_ADVERSARY_RESTARTS", DEFAULT_RESTARTS),
            moves: var("F32_ADVERSARY_MOVES", DEFAULT_MOVES),
            steps,
            seed: var("F32_ADVERSARY_SEED", DEFAULT_SEED as usize) as u64,
        }
    }
}

/// One point of the search.
#[derive(Debug, Clone)]
struct Point {
    x0: Vec<f64>,
    /// prior − x₀.
    err: Vec<f64>,
    /// a_t per step.
    scale: Vec<f64>,
    /// The pattern, n_w per step.
    s: Vec<i8>,
}

/// The worst point found.
#[derive(Debug, Clone)]
pub(super) struct Found {
    /// Its outcome.
    pub(super) outcome: Outcome,
    /// The run's inputs.
    pub(super) inputs: Inputs,
    /// Runs spent (until the first violation, where one was found).
    pub(super) runs: usize,
    /// The largest multi-step ratio of any run (`outcome` is the best point's, whose score
    /// is in practice its one-step ratio).
    pub(super) multi: f64,
}

impl Found {
    /// ‖x₀‖, ‖prior − x₀‖, the steps with w ≠ 0, where the worst one-step ratio is (M the
    /// window) and whether w = 0 there.
    pub(super) fn describe(&self, nw: usize, m: usize) -> String {
        let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|a| a * a).sum::<f64>().sqrt();
        let i = &self.inputs;
        let nonzero = |w: &[f64]| w.iter().any(|v| *v != 0.0);
        let noisy = i.w.chunks(nw).filter(|w| nonzero(w)).count();
        let t = m + self.outcome.at;
        format!(
            "‖x₀‖ {:.2e}, ‖prior − x₀‖ {:.2e}, w ≠ 0 on {noisy} of {} steps, worst at t = M + {} \
             (w_t {})",
            norm(&mut i.x0.iter().copied()),
            norm(&mut i.x0.iter().zip(&i.prior).map(|(x, p)| p - x)),
            i.w.len() / nw,
            self.outcome.at,
            if i.w.chunks(nw).nth(t).is_some_and(nonzero) {
                "≠ 0"
            } else {
                "= 0"
            }
        )
    }
}

struct Search<'a> {
    lo: &'a [f64],
    hi: &'a [f64],
    m: usize,
    steps: usize,
}

impl Search<'_> {
    fn nw(&self) -> usize {
        self.lo.len()
    }

    fn inputs(&self, p: &Point) -> Inputs {
        let nw = self.nw();
        let w =
            p.s.iter()
                .enumerate()
                .map(|(i, &s)| {
                    p.scale[i / nw]
                        * match s {
                            1 => self.hi[i % nw],
                            -1 => self.lo[i % nw],
                            _ => 0.0,
                        }
                })
                .collect();
        let prior = p.x0.iter().zip(&p.err).map(|(x, e)| x + e).collect();
        Inputs {
            x0: p.x0.clone(),
            prior,
            w,
        }
    }

    fn vertex(&self, rng: &mut ChaCha8Rng) -> Vec<i8> {
        (0..self.nw())
            .map(|_| if rng.random_bool(0.5) { 1 } else { -1 })
            .collect()
    }

    /// A random start: x₀ at a magnitude 10⁻⁶–10⁴ (the seeded runs draw 10⁻²–10²; the small
    /// ones are where the rounding offset is felt), the prior's error at 10⁻³–10³ times that
    /// (or none), and a w sequence of one of four kinds: none, random vertices, random
    /// vertices then zero from a random step, or one vertex held at a random scale.
    fn draw(&self, rng: &mut ChaCha8Rng, nx: usize) -> Point {
        let nw = self.nw();
        let mag = 10f64.powf(rng.random_range(-6.0..4.0));
        let emag = if rng.random_bool(0.1) {
            0.0
        } else {
            mag * 10f64.powf(rng.random_range(-3.0..3.0))
        };
        let x0 = (0..nx).map(|_| mag * rng.random_range(-1.0..1.0)).collect();
        let err = (0..nx)
            .map(|_| emag * rng.random_range(-1.0..1.0))
            .collect();
        let (mut scale, mut s) = (vec![0.0; self.steps], vec![0i8; self.steps * nw]);
        match rng.random_range(0..4) {
            0 => {}
            1 | 2 => {
                let stop = if rng.random_bool(0.5) {
                    self.steps
                } else {
                    rng.random_range(0..self.steps)
                };
                for t in 0..stop {
                    scale[t] = 1.0;
                    let v = self.vertex(rng);
                    s[t * nw..(t + 1) * nw].copy_from_slice(&v);
                }
            }
            _ => {
                let (a, v) = (rng.random_range(0.0..MAX_SCALE), self.vertex(rng));
                for t in 0..self.steps {
                    scale[t] = a;
                    s[t * nw..(t + 1) * nw].copy_from_slice(&v);
                }
            }
        }
        Point { x0, err, scale, s }
    }

    /// A step to change: half the time one of the four before the worst one-step ratio's
    /// w_t (`at` counts from t = M), else any.
    fn step(&self, rng: &mut ChaCha8Rng, at: usize) -> usize {
        if rng.random_bool(0.5) {
            (self.m + at).saturating_sub(rng.random_range(0..4))
        } else {
            rng.random_range(0..self.steps)
        }
        .min(self.steps - 1)
    }

    fn mutate(&self, rng: &mut ChaCha8Rng, p: &Point, at: usize) -> Point {
        let mut q = p.clone();
        let nw = self.nw();
        let nx = q.x0.len();
        let t = self.step(rng, at);
        let factor = |rng: &mut ChaCha8Rng| [0.1, 0.5, 2.0, 10.0][rng.random_range(0..4)];
        match rng.random_range(0..11) {
            // One entry: 0 → 1, ±1 → ∓1.
            0 => {
                let i = t * nw + rng.random_range(0..nw);
                q.s[i] = if q.s[i] == 1 { -1 } else { 1 };
                if q.scale[t] == 0.0 {
                    q.scale[t] = 1.0;
                }
            }
            // A new vertex at step t.
            1 => {
                let v = self.vertex(rng);
                q.s[t * nw..(t + 1) * nw].copy_from_slice(&v);
                q.scale[t] = 1.0;
            }
            // A noise-free stretch ending at step t.
            2 => {
                let a = t.saturating_sub(rng.random_range(0..self.steps));
                q.scale[a..=t].fill(0.0);
            }
            // One vertex held over a stretch ending at step t.
            3 => {
                let a = t.saturating_sub(rng.random_range(0..self.steps / 2 + 1));
                let v = self.vertex(rng);
                let amp = if q.scale[t] > 0.0 { q.scale[t] } else { 1.0 };
                for k in a..=t {
                    q.scale[k] = amp;
                    q.s[k * nw..(k + 1) * nw].copy_from_slice(&v);
                }
            }
            // Step t's scale.
            4 => {
                q.scale[t] = match rng.random_range(0..4) {
                    0 => 0.0,
                    1 => MAX_SCALE,
                    _ => (q.scale[t].max(0.05) * factor(rng)).min(MAX_SCALE),
                };
            }
            // The initial condition's magnitude (x₀ and the error together).
            5 => {
                let f = factor(rng);
                q.x0.iter_mut().chain(&mut q.err).for_each(|v| *v *= f);
            }
            // The prior's error alone: scaled, reversed or zero.
            6 => {
                let f = [0.0, -1.0, 0.5, 2.0, 10.0][rng.random_range(0..5)];
                q.err.iter_mut().for_each(|v| *v *= f);
            }
            // One component of x₀ or of the error.
            7 => {
                let sc =
                    q.x0.iter()
                        .chain(&q.err)
                        .fold(1e-9_f64, |a, v| a.max(v.abs()));
                let i = rng.random_range(0..2 * nx);
                let v = if i < nx {
                    &mut q.x0[i]
                } else {
                    &mut q.err[i - nx]
                };
                *v += sc * rng.random_range(-1.0..1.0);
            }
            // Every component of x₀ and of the error by a small relative step.
            _ => {
                let sigma = 10f64.powf(rng.random_range(-3.0..-0.5));
                let sx = q.x0.iter().fold(1e-9_f64, |a, v| a.max(v.abs()));
                let se = q.err.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
                let se = if se > 0.0 { se } else { sx };
                for v in &mut q.x0 {
                    *v += sigma * sx * rng.random_range(-1.0..1.0);
                }
                for v in &mut q.err {
                    *v += sigma * se * rng.random_range(-1.0..1.0);
                }
            }
        }
        q
    }
}

/// The adversary against `c` with the rounding offset `offset` on `run` (its K is
/// `run.problem.iterations`), w built on 𝒲 = [lo, hi], seeded by `budget.seed`, maximising
/// `score` ([`Outcome::score`] for the certificate's inequalities, or the deviation ratio):
/// the worst point found, the first violating one where one exists within the budget (the
/// search stops there).
pub(super) fn attack(
    run: &F32Run<'_>,
    c: &GlobalCertificate,
    offset: f64,
    (lo, hi): (&[f64], &[f64]),
    budget: Budget,
    score: impl Fn(&Outcome) -> f64,
) -> Found {
    let mut rng = ChaCha8Rng::seed_from_u64(budget.seed);
    let search = Search {
        lo,
        hi,
        m: run.layout.horizon,
        steps: budget.steps,
    };
    let nx = run.layout.nx;
    let (mut runs, mut multi) = (0, 0.0_f64);
    let mut eval = |p: &Point| {
        let o = run.run(c, offset, &search.inputs(p), budget.steps);
        runs += 1;
        multi = multi.max(o.multi);
        o
    };
    let mut best: Option<(Outcome, Point)> = None;
    for _ in 0..budget.restarts {
        let mut p = search.draw(&mut rng, nx);
        let mut f = eval(&p);
        for _ in 0..budget.moves {
            if !f.holds() {
                break;
            }
            let q = search.mutate(&mut rng, &p, f.at);
            let g = eval(&q);
            if score(&g) >= score(&f) || !g.holds() {
                (p, f) = (q, g);
            }
        }
        if best
            .as_ref()
            .is_none_or(|(b, _)| score(&f) > score(b) || !f.holds())
        {
            best = Some((f, p));
        }
        if !f.holds() {
            break;
        }
    }
    let (outcome, p) = best.expect("at least one restart");
    Found {
        outcome,
        inputs: search.inputs(&p),
        runs,
        multi,
    }
}
