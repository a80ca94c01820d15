//! An optimised adversary against the K-step f32 rounding model (issue 36; docs/theory.md,
//! "FISTA in f32", "Jacobi-scaled projected gradient in f32", "ADMM in f32"), next to
//! `fista_rounding`'s random starts: hill climbing with random restarts over the start z⁰
//! (f32 numbers), the parameter θ and K ∈ {1, 2, 3, 5, 10, 30, 100} maximises, per method and
//! QP, the rounding part ‖f32 run − exact run‖ over its bound φ_u(K at φ = 0)e₀ + inputs, and
//! separately the whole error ‖D⁻¹(zᴷ − z*)‖ over φ_u(K)e₀ + β_z‖z*‖ + β_θ‖θ‖ + c_d. Every
//! evaluated point must satisfy both bounds; the climb must do at least as well as as many
//! random draws from its own start distribution; and the same climb against the
//! exact-arithmetic bound φ(K)e₀ alone must break it (the rounding terms are needed where the
//! premise, exact arithmetic, fails). The objective is a pure function of (QP, z⁰, θ, K);
//! every random choice comes from a seeded ChaCha8Rng.

use super::fista_rounding::{Setup, kappa_of, methods, norm, qp};
use faer::Side;
use iss_certificate::lure::global::StepRounding;
use qp_iter::rounding::F32_UNIT_ROUNDOFF;
use qp_iter::{Method, Scaling};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::cell::RefCell;

/// The number of kinds of move (`Target::one_move`).
const MOVES: usize = 14;

/// The iteration counts searched over.
const KS: [usize; 7] = [1, 2, 3, 5, 10, 30, 100];

/// What a search maximises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Goal {
    /// ‖f32 run − exact run‖ / (φ_u(K at φ = 0)e₀ + inputs).
    Rounding,
    /// ‖D⁻¹(zᴷ − z*)‖ / (φ_u(K)e₀ + inputs).
    Full,
    /// ‖D⁻¹(zᴷ − z*)‖ / (φ(K)e₀ + allowance): the exact-arithmetic bound alone (> 1 breaks it).
    Exact,
}

/// A point of the search: an f32 start, the parameter, and K = KS[k].
#[derive(Clone, Debug)]
struct Point {
    z0: Vec<f64>,
    theta: Vec<f64>,
    k: usize,
}

/// z rounded to f32 (the start the estimator stores).
fn f32r(v: f64) -> f64 {
    f64::from(v as f32)
}

/// The f32 number `steps` units in the last place above (or below) x.
fn ulps(x: f64, steps: i32) -> f64 {
    let mut v = x as f32;
    for _ in 0..steps.unsigned_abs() {
        let up = steps > 0;
        v = if v == 0.0 {
            if up {
                f32::from_bits(1)
            } else {
                -f32::from_bits(1)
            }
        } else if (v > 0.0) == up {
            f32::from_bits(v.to_bits() + 1)
        } else {
            f32::from_bits(v.to_bits() - 1)
        };
    }
    f64::from(v)
}

/// ±2ᵉ·m with a mantissa m whose products and sums round the most: 1 + 2⁻²³ (one unit
/// above 1), 2 − 2⁻²³, 1 + 2⁻¹² (its square is a tie), 1 + 2⁻¹¹ + 2⁻²³, or 1 + k·2⁻²³.
fn rounding_heavy(rng: &mut ChaCha8Rng, magnitude: f64) -> f64 {
    let e = magnitude.max(1e-30).log2().floor() as i32 + rng.random_range(-1..=1);
    let m = match rng.random_range(0..5) {
        0 => 1.0 + 2f64.powi(-23),
        1 => 2.0 - 2f64.powi(-23),
        2 => 1.0 + 2f64.powi(-12),
        3 => 1.0 + 2f64.powi(-11) + 2f64.powi(-23),
        _ => 1.0 + f64::from(rng.random_range(1..(1u32 << 23))) * 2f64.powi(-23),
    };
    let s = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    f32r(s * m * 2f64.powi(e))
}

/// A vector with every entry exact (`{:e}` round-trips f64).
fn cells(v: &[f64]) -> String {
    let cells: Vec<String> = v.iter().map(|x| format!("{x:e}")).collect();
    format!("[{}]", cells.join(", "))
}

/// The search's best: the ratio and where it was reached (QP seed, K, ‖z⁰‖, ‖θ‖).
#[derive(Clone, Debug)]
struct Best {
    ratio: f64,
    seed: u64,
    point: Option<Point>,
}

impl Best {
    const NONE: Best = Best {
        ratio: 0.0,
        seed: 0,
        point: None,
    };
    fn keep(&mut self, ratio: f64, seed: u64, p: &Point) {
        if ratio > self.ratio {
            *self = Best {
                ratio,
                seed,
                point: Some(p.clone()),
            };
        }
    }
    fn at(&self) -> String {
        let (k, z0, theta) = self
            .point
            .as_ref()
            .map_or((0, 0.0, 0.0), |p| (KS[p.k], norm(&p.z0), norm(&p.theta)));
        format!(
            "{:.4e} (QP {}, K {k}, ‖z⁰‖ {z0:.1e}, ‖θ‖ {theta:.1e})",
            self.ratio, self.seed
        )
    }
    /// The best point evaluated again gives the same ratio, bit for bit (the objective is a
    /// pure function of the point).
    fn recheck(&self, targets: &[Target], goal: Goal) {
        let (Some(p), Some(t)) = (&self.point, targets.iter().find(|t| t.seed == self.seed)) else {
            return;
        };
        let again = t.measure(p, goal);
        assert_eq!(
            again.to_bits(),
            self.ratio.to_bits(),
            "{goal:?} {}",
            self.at()
        );
    }
}

/// One method on one QP, with what the moves need.
struct Target {
    seed: u64,
    kappa: f64,
    setup: Setup,
    /// Unit directions in z of the run problem's smallest and largest eigenvalues (mapped
    /// by D for Jacobi): the slowest and fastest modes.
    slow: Vec<f64>,
    fast: Vec<f64>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    evals: usize,
    /// Per move, this climb's tries and strict improvements (the moves' weights), and the
    /// moves of the last neighbour.
    tried: [usize; MOVES],
    won: [usize; MOVES],
    last: Vec<usize>,
    /// The last few (θ, z*(θ)).
    cache: RefCell<Vec<(Vec<f64>, Vec<f64>)>>,
}

impl Target {
    fn new(method: Method, seed: u64) -> Self {
        let (n, nt) = (3 + (seed as usize % 14), 2 + (seed as usize % 5));
        let kappa = kappa_of(method, seed);
        Self::of(method, seed, kappa, &qp(seed, n, nt, kappa))
    }

    /// `method` on the given QP (`seed` labels it; κ is reported).
    fn of(method: Method, seed: u64, kappa: f64, p: &qp_iter::ParametricQp) -> Self {
        let n = p.n();
        let setup = Setup::new(method, p);
        assert!(
            setup.model.perturbed_rate() < 1.0,
            "{} QP {seed}: {:?}",
            method.name(),
            setup.model
        );
        let h = setup.run_qp.h().to_owned();
        let evd = h.self_adjoint_eigen(Side::Lower).expect("eigen");
        let (u, s) = (evd.U(), evd.S().column_vector());
        let (mut imin, mut imax) = (0, 0);
        for i in 0..n {
            if s[i] < s[imin] {
                imin = i;
            }
            if s[i] > s[imax] {
                imax = i;
            }
        }
        let dir = |c: usize| -> Vec<f64> {
            let v: Vec<f64> = (0..n).map(|i| u[(i, c)] * setup.d[i]).collect();
            let l = norm(&v);
            v.into_iter().map(|x| x / l).collect()
        };
        let (slow, fast) = (dir(imin), dir(imax));
        let lo = setup.qp.zset().lower().to_vec();
        let hi = setup.qp.zset().upper().to_vec();
        Self {
            seed,
            kappa,
            setup,
            slow,
            fast,
            lo,
            hi,
            evals: 0,
            tried: [0; MOVES],
            won: [0; MOVES],
            last: Vec::new(),
            cache: RefCell::new(Vec::new()),
        }
    }

    /// z*(θ) from a cold start ([`Setup::optimum_cold`]), the last few remembered by θ's
    /// bits (most moves leave θ as it was).
    fn zstar(&self, theta: &[f64]) -> Vec<f64> {
        let mut cache = self.cache.borrow_mut();
        if let Some((_, z)) = cache
            .iter()
            .find(|(t, _)| t.iter().zip(theta).all(|(a, b)| a.to_bits() == b.to_bits()))
        {
            return z.clone();
        }
        let z = self.setup.optimum_cold(theta);
        if cache.len() == 4 {
            cache.remove(0);
        }
        cache.push((theta.to_vec(), z.clone()));
        z
    }

    /// One evaluation: [`Target::measure`], counted.
    fn value(&mut self, p: &Point, goal: Goal) -> f64 {
        self.evals += 1;
        self.measure(p, goal)
    }

    /// The ratio `goal` asks for at `p`, after checking both bounds of the model there.
    fn measure(&self, p: &Point, goal: Goal) -> f64 {
        let k = KS[p.k];
        let zs = self.zstar(&p.theta);
        let ev = self.setup.eval(&p.theta, &p.z0, &zs, k);
        let name = self.setup.method.name();
        let (seed, kappa) = (self.seed, self.kappa);
        let at = || {
            format!(
                "{name} QP seed {seed} (κ = {kappa:e}) K {k}: z⁰ = {}, θ = {}, z* = {}",
                cells(&p.z0),
                cells(&p.theta),
                cells(&zs)
            )
        };
        assert!(
            ev.err <= ev.bound + ev.allowance,
            "{}: ‖D⁻¹(zᴷ − z*)‖ = {:e} > bound {:e}",
            at(),
            ev.err,
            ev.bound
        );
        if let Some((dev, dev_bound)) = ev.dev {
            assert!(
                dev <= dev_bound + ev.allowance,
                "{}: f32 − exact run {dev:e} > {dev_bound:e}",
                at()
            );
        }
        match goal {
            Goal::Rounding => ev.dev.map_or(0.0, |(d, b)| d / b),
            Goal::Full => ev.err / ev.bound,
            Goal::Exact => ev.err / (ev.exact_bound + ev.allowance),
        }
    }

    /// A start from `fista_rounding`'s distribution: θ over seven decades, z⁰ around z*(θ)
    /// at θ's scale (half the draws 10³ further out), K uniform.
    fn draw(&mut self, rng: &mut ChaCha8Rng) -> Point {
        let (n, nt) = (self.setup.qp.n(), self.setup.qp.n_theta());
        let scale = 10f64.powi(rng.random_range(-3..4));
        let theta: Vec<f64> = (0..nt)
            .map(|_| scale * rng.random_range(-1.0..1.0))
            .collect();
        let zs = self.zstar(&theta);
        let far = if rng.random_bool(0.5) { 1.0 } else { 1e3 };
        let z0 = (0..n)
            .map(|i| f32r(zs[i] + far * scale * rng.random_range(-1.0..1.0)))
            .collect();
        let k = rng.random_range(0..KS.len());
        Point { z0, theta, k }
    }

    /// A neighbour of `p`: one to three moves, then z⁰ rounded to f32 and both kept finite
    /// and far from f32's overflow.
    fn mutate(&mut self, rng: &mut ChaCha8Rng, p: &Point) -> Point {
        let mut q = p.clone();
        let moves = 1 + usize::from(rng.random_bool(0.35)) + usize::from(rng.random_bool(0.15));
        for _ in 0..moves {
            self.one_move(rng, &mut q);
        }
        for v in &mut q.z0 {
            *v = if v.is_finite() {
                f32r(v.clamp(-1e12, 1e12))
            } else {
                0.0
            };
        }
        for v in &mut q.theta {
            *v = if v.is_finite() {
                v.clamp(-1e10, 1e10)
            } else {
                0.0
            };
        }
        q
    }

    /// A move, with probability proportional to its success rate so far in this climb
    /// ((1 + improvements)/(2 + tries): every move keeps a chance).
    fn pick(&mut self, rng: &mut ChaCha8Rng) -> usize {
        let w: Vec<f64> = (0..MOVES)
            .map(|m| (1.0 + self.won[m] as f64) / (2.0 + self.tried[m] as f64))
            .collect();
        let mut x = rng.random_range(0.0..w.iter().sum::<f64>());
        let mut m = 0;
        while m + 1 < MOVES && x >= w[m] {
            x -= w[m];
            m += 1;
        }
        self.tried[m] += 1;
        m
    }

    fn one_move(&mut self, rng: &mut ChaCha8Rng, p: &mut Point) {
        let n = p.z0.len();
        let i = rng.random_range(0..n);
        let scale = p.theta.iter().fold(1e-3f64, |m, t| m.max(t.abs()));
        let sign = |rng: &mut ChaCha8Rng| if rng.random_bool(0.5) { 1 } else { -1 };
        let m = self.pick(rng);
        self.last.push(m);
        match m {
            // Scale a component of z⁰.
            0 => {
                let f = [2.0, 0.5, 10.0, 0.1, 1.0 + 2f64.powi(-10)][rng.random_range(0..5)];
                p.z0[i] *= f;
            }
            // Flip its sign.
            1 => p.z0[i] = -p.z0[i],
            // Onto a box bound, just past it, or past it by a fraction of the box.
            2 if self.lo[i].is_finite() && self.hi[i].is_finite() => {
                let (lo, hi) = (self.lo[i], self.hi[i]);
                let w = (hi - lo) * 2f64.powf(rng.random_range(-20.0..0.0));
                p.z0[i] = match rng.random_range(0..6) {
                    0 => lo,
                    1 => hi,
                    2 => ulps(hi, rng.random_range(1..4)),
                    3 => ulps(lo, -rng.random_range(1..4)),
                    4 => hi + w,
                    _ => lo - w,
                };
            }
            // A value whose products round the most, at the component's (or θ's) magnitude.
            2..=3 => {
                let m = if p.z0[i] != 0.0 { p.z0[i].abs() } else { scale };
                p.z0[i] = rounding_heavy(rng, m);
            }
            // Along the slowest (or fastest) mode by a multiple of the current distance, or
            // the offset replaced by that mode alone.
            4..=5 => {
                let zs = self.zstar(&p.theta);
                let e = (self.setup.wdist(&p.z0, &zs)).max(1e-6 * scale);
                let a = f64::from(sign(rng)) * e * 2f64.powf(rng.random_range(-3.0..3.0));
                let dir = if rng.random_bool(0.75) {
                    &self.slow
                } else {
                    &self.fast
                };
                let pure = rng.random_bool(0.5);
                for ((z, v), s) in p.z0.iter_mut().zip(dir).zip(&zs) {
                    *z = if pure { s + a * v } else { *z + a * v };
                }
            }
            // Scale (or mirror) the whole offset z⁰ − z*.
            6 => {
                let zs = self.zstar(&p.theta);
                let c = [2.0, 0.5, 10.0, 0.1, -1.0][rng.random_range(0..5)];
                for (z, s) in p.z0.iter_mut().zip(&zs) {
                    *z = s + c * (*z - s);
                }
            }
            // z⁰ at (a component of) z* rounded to f32, or a few units in the last place off.
            7 => {
                let zs = self.zstar(&p.theta);
                if rng.random_bool(0.5) {
                    p.z0 = zs.iter().map(|v| f32r(*v)).collect();
                } else {
                    p.z0[i] = ulps(zs[i], rng.random_range(-3..=3));
                }
            }
            // A few units in the last place.
            8 => p.z0[i] = ulps(p.z0[i], sign(rng) * rng.random_range(1..8)),
            // θ over decades, the start following z* (same offset, scaled) or staying put.
            9 => {
                let c = if rng.random_bool(0.5) {
                    10f64.powi(sign(rng))
                } else {
                    2f64.powf(rng.random_range(-1.0..1.0))
                };
                let old = self.zstar(&p.theta);
                p.theta.iter_mut().for_each(|t| *t *= c);
                if rng.random_bool(0.5) {
                    let new = self.zstar(&p.theta);
                    for ((z, o), s) in p.z0.iter_mut().zip(&old).zip(&new) {
                        *z = s + c * (*z - o);
                    }
                }
            }
            // One component of θ (scaled, flipped, rounding-heavy or redrawn), or all of
            // them nudged along a random direction; the start following z* or staying put.
            10..=11 => {
                let old = self.zstar(&p.theta);
                if m == 10 {
                    let j = rng.random_range(0..p.theta.len());
                    p.theta[j] = match rng.random_range(0..4) {
                        0 => p.theta[j] * [10.0, 0.1, 2.0, 0.5][rng.random_range(0..4)],
                        1 => -p.theta[j],
                        2 => rounding_heavy(rng, scale),
                        _ => scale * rng.random_range(-1.0..1.0),
                    };
                } else {
                    let eps = norm(&p.theta).max(1e-3) * 2f64.powf(rng.random_range(-12.0..0.0));
                    p.theta
                        .iter_mut()
                        .for_each(|t| *t += eps * rng.random_range(-1.0..1.0));
                }
                if rng.random_bool(0.5) {
                    let new = self.zstar(&p.theta);
                    for ((z, o), s) in p.z0.iter_mut().zip(&old).zip(&new) {
                        *z += s - o;
                    }
                }
            }
            // K: a neighbour in the list, or any.
            _ => {
                p.k = if rng.random_bool(0.5) {
                    let up = rng.random_bool(0.5);
                    if up {
                        (p.k + 1).min(KS.len() - 1)
                    } else {
                        p.k.saturating_sub(1)
                    }
                } else {
                    rng.random_range(0..KS.len())
                };
            }
        }
    }

    /// The best of `evals` draws.
    fn random(&mut self, goal: Goal, evals: usize, rng: &mut ChaCha8Rng, best: &mut Best) {
        for _ in 0..evals {
            let p = self.draw(rng);
            let v = self.value(&p, goal);
            best.keep(v, self.seed, &p);
        }
    }

    /// Hill climbing with random restarts, `evals` evaluations in all: a fifth of them are
    /// draws, the best `restarts` of which start a climb each (accepting equal-or-better
    /// neighbours) that shares the rest.
    fn climb(
        &mut self,
        goal: Goal,
        evals: usize,
        restarts: usize,
        rng: &mut ChaCha8Rng,
        best: &mut Best,
    ) {
        let screen = (evals / 5).max(restarts);
        let mut starts: Vec<(f64, Point)> = (0..screen)
            .map(|_| {
                let p = self.draw(rng);
                let v = self.value(&p, goal);
                best.keep(v, self.seed, &p);
                (v, p)
            })
            .collect();
        starts.sort_by(|a, b| b.0.total_cmp(&a.0));
        starts.truncate(restarts);
        let rest = evals - screen;
        for (r, (mut v, mut p)) in starts.into_iter().enumerate() {
            (self.tried, self.won) = ([0; MOVES], [0; MOVES]);
            // The climbs share the rest evenly, the first ones the remainder.
            let steps = rest / restarts + usize::from(r < rest % restarts);
            for _ in 0..steps {
                self.last.clear();
                let c = self.mutate(rng, &p);
                let w = self.value(&c, goal);
                if w > v {
                    for m in self.last.clone() {
                        self.won[m] += 1;
                    }
                }
                best.keep(w, self.seed, &c);
                if w >= v {
                    (p, v) = (c, w);
                }
            }
        }
    }
}

/// The searches on QPs `seeds` with `evals` evaluations per (QP, goal) for the adversary and
/// as many for the random draws; asserts the three properties of the module's doc.
fn search(seeds: &[u64], evals: usize, restarts: usize) {
    let (mut broken, mut weak) = (Vec::new(), Vec::new());
    for (mi, method) in methods().into_iter().enumerate() {
        let name = method.name();
        let mut lines = Vec::new();
        let mut total = 0usize;
        let mut exact = Best::NONE;
        let goals: &[Goal] = if method.scaling == Scaling::Jacobi {
            &[Goal::Full]
        } else {
            &[Goal::Rounding, Goal::Full]
        };
        let mut targets: Vec<Target> = seeds.iter().map(|s| Target::new(method, *s)).collect();
        for (gi, goal) in goals.iter().enumerate() {
            let (mut rand_best, mut adv_best) = (Best::NONE, Best::NONE);
            for t in &mut targets {
                let stream = 1000 * mi as u64 + 10 * gi as u64;
                let mut rng = ChaCha8Rng::seed_from_u64(t.seed);
                rng.set_stream(stream);
                t.random(*goal, evals, &mut rng, &mut rand_best);
                rng.set_stream(stream + 1);
                t.climb(*goal, evals, restarts, &mut rng, &mut adv_best);
            }
            rand_best.recheck(&targets, *goal);
            adv_best.recheck(&targets, *goal);
            let what = match goal {
                Goal::Rounding => "rounding part / its bound",
                _ => "whole error / its bound",
            };
            lines.push(format!(
                "  {what}: random {} | adversarial {}",
                rand_best.at(),
                adv_best.at()
            ));
            if adv_best.ratio < rand_best.ratio {
                weak.push(format!("{name} {what}"));
            }
        }
        // The teeth check: the same climb against φ(K)e₀ alone.
        for t in &mut targets {
            let mut rng = ChaCha8Rng::seed_from_u64(t.seed);
            rng.set_stream(1000 * mi as u64 + 99);
            t.climb(Goal::Exact, evals, restarts, &mut rng, &mut exact);
            total += t.evals;
        }
        exact.recheck(&targets, Goal::Exact);
        lines.push(format!(
            "  whole error / φ(K)e₀ (the exact-arithmetic bound alone): adversarial {}{}",
            exact.at(),
            if exact.ratio > 1.0 { ": broken" } else { "" }
        ));
        if exact.ratio > 1.0 {
            broken.push(format!("{name} {}", exact.at()));
        }
        // Per QP: for each goal `evals` random and `evals` adversarial, then `evals` against
        // φ(K)e₀ alone.
        println!(
            "{name}: {total} evaluations ({} QPs × {} searches × {evals}), every one within both bounds",
            seeds.len(),
            2 * goals.len() + 1
        );
        for l in lines {
            println!("{l}");
        }
    }
    // Not toothless: the climb does at least as well as as many random draws.
    assert!(
        weak.is_empty(),
        "the adversary did worse than random draws: {}",
        weak.join("; ")
    );
    // Where the premise (exact arithmetic) fails, the exact bound does: the rounding terms
    // are what the search could not break.
    assert!(
        !broken.is_empty(),
        "the adversary broke φ(K)e₀ alone for no method"
    );
    println!("φ(K)e₀ alone broken for {}", broken.join("; "));
}

/// The default budget: three QPs per method (κ = 10⁴, 10, 10² for projected gradient and
/// ADMM; 1.8, 2.3, 2.8 for V-FISTA).
#[test]
fn rounding_adversary_finds_no_violation_of_the_k_step_model() {
    search(&[3, 8, 13], 1200, 4);
}

/// A larger budget: twelve QPs per method (every κ of the test's classes), longer climbs.
#[test]
#[ignore = "long: run by .ci/run with --ignored"]
fn long_rounding_adversary_finds_no_violation_of_the_k_step_model() {
    search(&(0..12).collect::<Vec<_>>(), 4000, 8);
}

/// The K-step model on the MPC's QP of shipped scenarios (N·n_u variables, θ = x̂): what the
/// joint certificate in f32 folds in for the K_c-iteration MPC (session 28). Every method with
/// a model there, random draws and the hill climb on the whole error (the rounding part for
/// the plain methods): no violation.
#[test]
fn the_mpc_qps_of_shipped_scenarios_respect_the_k_step_model() {
    let mut checked = 0;
    for (label, file) in [
        (100, "case-study-certified.toml"),
        (101, "quadruple-tank.toml"),
        (102, "double-integrator.toml"),
    ] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../scenarios")
            .join(file);
        let sc = closed_loop::scenario::Scenario::from_file(&path).expect("parses");
        let r = sc.resolve().expect("resolves");
        let qp = r.mpc().expect("an MPC").qp().clone();
        let kappa = qp.l() / qp.mu();
        for (mi, method) in methods().into_iter().enumerate() {
            if StepRounding::for_qp(method, &qp, F32_UNIT_ROUNDOFF)
                .map_or(true, |m| !(m.perturbed_rate() < 1.0))
            {
                println!(
                    "{file} {}: no model on the MPC's QP (κ = {kappa:.3e})",
                    method.name()
                );
                continue;
            }
            let mut t = Target::of(method, label, kappa, &qp);
            let goals: &[Goal] = if method.scaling == Scaling::Jacobi {
                &[Goal::Full]
            } else {
                &[Goal::Rounding, Goal::Full]
            };
            for (gi, goal) in goals.iter().enumerate() {
                let (mut rand_best, mut adv_best) = (Best::NONE, Best::NONE);
                let mut rng = ChaCha8Rng::seed_from_u64(label);
                rng.set_stream(1000 * mi as u64 + 10 * gi as u64);
                t.random(*goal, 300, &mut rng, &mut rand_best);
                t.climb(*goal, 300, 3, &mut rng, &mut adv_best);
                println!(
                    "{file} {} (n = {}, κ = {kappa:.3e}) {goal:?}: random {} | adversarial {}",
                    method.name(),
                    qp.n(),
                    rand_best.at(),
                    adv_best.at()
                );
            }
            checked += 1;
        }
    }
    assert!(
        checked >= 9,
        "only {checked} (scenario, method) pairs had a model"
    );
}
