//! Zonotopes over the start-up unknowns and the clip abstraction (docs/theory.md,
//! "Regional ISS with an active start-up", step 2).
//!
//! A set is c + Gε with ε in a product of Euclidean balls (the user's x₀ and prior-error
//! balls, radius r each) and unit intervals (the noise box's components and every generator
//! a clip adds). Every vector of the loop is an affine form over the same ε, stored as a
//! matrix [c | G]; a new generator appends a column, and forms built before it are widened
//! with zeros ([`Space::widen`]). The reach of a row g over the set is exact:
//! |gc| + Σ_balls r‖g_ball‖₂ + Σ_intervals |g_j|.
//!
//! **The clip.** On a component with interval [lo, hi] (its reach), π(v) = min(max(v, l), u)
//! is the identity when [lo, hi] ⊂ [l, u], the bound when the interval lies beyond it, and
//! otherwise it is replaced by the parallelogram λv + [m₋, m₊] with λ the chord slope
//! (π(hi) − π(lo))/(hi − lo) and m± the extremes of π(v) − λv over [lo, hi], attained at
//! lo, hi or a bound inside (π − λ·id is piecewise linear): the "DeepZ" relaxation, one new
//! generator (m₊ − m₋)/2. It contains the graph of π on [lo, hi], so the image zonotope
//! contains π of every point of the set (test
//! `every_real_iterate_lies_in_the_zonotope`). Intervals are widened by 10⁻¹² of their
//! magnitude so that rounding in the forms cannot move a point out.
//!
//! **Order reduction.** Past a cap, the interval generators with the smallest norm are
//! replaced by their interval hull, one generator per row of the joint state ("boxing");
//! the balls are kept. Boxing contains what it replaces, so the bounds stay sound.

use faer::{Mat, MatRef};

use super::clip_form::ClipForm;

/// Relative widening of every interval (rounding in the forms).
const PAD: f64 = 1e-12;

/// The generators' geometry: balls over consecutive generators, the rest unit intervals.
#[derive(Debug, Clone, Default)]
pub(crate) struct Space {
    /// (first generator, count, radius).
    balls: Vec<(usize, usize, f64)>,
    /// Number of generators (a form has 1 + count columns).
    count: usize,
}

/// What a clip did to one component.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ClipStatus {
    /// [lo, hi] inside the box: π is the identity.
    Inactive,
    /// [lo, hi] beyond a bound: π is that bound.
    Saturated,
    /// [lo, hi] crosses a bound: the parallelogram.
    Straddling,
}

impl Space {
    /// Generators so far.
    pub(crate) fn count(&self) -> usize {
        self.count
    }

    /// The balls: (first generator, count, radius).
    pub(crate) fn balls(&self) -> &[(usize, usize, f64)] {
        &self.balls
    }

    /// `len` generators forming a Euclidean ball of radius `radius`; returns the first.
    pub(crate) fn add_ball(&mut self, len: usize, radius: f64) -> usize {
        let first = self.count;
        self.balls.push((first, len, radius));
        self.count += len;
        first
    }

    /// `len` unit-interval generators; returns the first.
    pub(crate) fn add_intervals(&mut self, len: usize) -> usize {
        let first = self.count;
        self.count += len;
        first
    }

    fn in_ball(&self, j: usize) -> bool {
        self.balls.iter().any(|&(f, l, _)| j >= f && j < f + l)
    }

    /// `m` with zero columns for the generators added since it was built.
    pub(crate) fn widen(&self, m: MatRef<'_, f64>) -> Mat<f64> {
        let cols = 1 + self.count;
        Mat::from_fn(
            m.nrows(),
            cols,
            |i, j| {
                if j < m.ncols() { m[(i, j)] } else { 0.0 }
            },
        )
    }

    /// sup over the set of |row i of `m`| minus |its centre|: the generators' reach.
    pub(crate) fn spread(&self, m: MatRef<'_, f64>, i: usize) -> f64 {
        let g = |j: usize| {
            if 1 + j < m.ncols() {
                m[(i, 1 + j)]
            } else {
                0.0
            }
        };
        let balls: f64 = self
            .balls
            .iter()
            .map(|&(f, l, r)| r * (f..f + l).map(|j| g(j) * g(j)).sum::<f64>().sqrt())
            .sum();
        let intervals: f64 = (0..self.count)
            .filter(|&j| !self.in_ball(j))
            .map(|j| g(j).abs())
            .sum();
        balls + intervals
    }

    /// [lo, hi] of component i over the set, widened by [`PAD`].
    pub(crate) fn interval(&self, m: MatRef<'_, f64>, i: usize) -> (f64, f64) {
        let (c, s) = (m[(i, 0)], self.spread(m, i));
        let pad = PAD * (c.abs() + s);
        (c - s - pad, c + s + pad)
    }

    /// The zonotope of π(v) on the box [lower, upper] (one new generator per straddling
    /// component) and what the clip did per component.
    pub(crate) fn clip(
        &mut self,
        v: MatRef<'_, f64>,
        lower: &[f64],
        upper: &[f64],
    ) -> (Mat<f64>, Vec<ClipStatus>) {
        let mut out = v.to_owned();
        let mut status = Vec::with_capacity(v.nrows());
        let mut added: Vec<(usize, f64)> = Vec::new();
        for i in 0..v.nrows() {
            let (lo, hi) = self.interval(v, i);
            let (l, u) = (lower[i], upper[i]);
            let f = |x: f64| x.clamp(l, u);
            if lo >= l && hi <= u {
                status.push(ClipStatus::Inactive);
                continue;
            }
            if hi <= l || lo >= u {
                for j in 0..out.ncols() {
                    out[(i, j)] = 0.0;
                }
                out[(i, 0)] = if hi <= l { l } else { u };
                status.push(ClipStatus::Saturated);
                continue;
            }
            let lambda = (f(hi) - f(lo)) / (hi - lo);
            let (mut m_lo, mut m_hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for x in [lo, hi, l, u] {
                if x >= lo && x <= hi {
                    let g = f(x) - lambda * x;
                    m_lo = m_lo.min(g);
                    m_hi = m_hi.max(g);
                }
            }
            for j in 0..out.ncols() {
                out[(i, j)] = lambda * v[(i, j)];
            }
            out[(i, 0)] += 0.5 * (m_lo + m_hi);
            added.push((i, 0.5 * (m_hi - m_lo)));
            status.push(ClipStatus::Straddling);
        }
        let first = self.add_intervals(added.len());
        let mut out = self.widen(out.as_ref());
        for (k, (i, g)) in added.into_iter().enumerate() {
            out[(i, 1 + first + k)] = g;
        }
        (out, status)
    }

    /// Boxes the smallest interval generators of the joint state `forms` (all widened to
    /// the current count) so that at most `cap` generators remain; returns the reduced
    /// forms in place. A no-op when already within the cap or when boxing would not shrink.
    pub(crate) fn reduce(&mut self, forms: &mut [Mat<f64>], cap: usize) {
        let rows: usize = forms.iter().map(|m| m.nrows()).sum();
        for m in forms.iter_mut() {
            *m = self.widen(m.as_ref());
        }
        if self.count <= cap {
            return;
        }
        let mut free: Vec<(usize, f64)> = (0..self.count)
            .filter(|&j| !self.in_ball(j))
            .map(|j| {
                let norm: f64 = forms
                    .iter()
                    .map(|m| (0..m.nrows()).map(|i| m[(i, 1 + j)].abs()).sum::<f64>())
                    .sum();
                (j, norm)
            })
            .collect();
        free.sort_by(|a, b| a.1.total_cmp(&b.1));
        let n_box = (self.count - cap + rows).min(free.len());
        if n_box <= rows {
            return;
        }
        let boxed: Vec<usize> = free[..n_box].iter().map(|&(j, _)| j).collect();
        let kept: Vec<usize> = (0..self.count).filter(|j| !boxed.contains(j)).collect();
        // New numbering: the kept generators in order, then one per row of the state.
        let mut balls = Vec::new();
        for &(f, l, r) in &self.balls {
            let new_first = kept.iter().position(|&j| j == f).unwrap_or(0);
            balls.push((new_first, l, r));
        }
        let count = kept.len() + rows;
        let mut row0 = 0;
        for m in forms.iter_mut() {
            let o = Mat::from_fn(m.nrows(), 1 + count, |i, c| {
                if c == 0 {
                    m[(i, 0)]
                } else if c - 1 < kept.len() {
                    m[(i, 1 + kept[c - 1])]
                } else if c - 1 - kept.len() == row0 + i {
                    boxed.iter().map(|&j| m[(i, 1 + j)].abs()).sum()
                } else {
                    0.0
                }
            });
            row0 += m.nrows();
            *m = o;
        }
        self.balls = balls;
        self.count = count;
    }
}

/// K steps of `form` over the zonotopes of z⁰ and θ (forms over `space`): the zonotope of
/// every iterate z¹..zᴷ and what each step's clip did. Generators past `cap` are boxed.
pub(crate) fn iterate(
    form: &ClipForm,
    space: &mut Space,
    z0: MatRef<'_, f64>,
    theta: MatRef<'_, f64>,
    k: usize,
    cap: usize,
) -> (Vec<Mat<f64>>, Vec<Vec<ClipStatus>>) {
    let mut xi = form.pre.as_ref() * z0;
    let mut theta = theta.to_owned();
    let mut iterates = Vec::with_capacity(k);
    let mut log = Vec::with_capacity(k);
    for j in 0..k {
        let step = match (&form.restart, j) {
            (Some(r), 0) => r,
            _ => &form.step,
        };
        let (x, t) = (space.widen(xi.as_ref()), space.widen(theta.as_ref()));
        let mut v = &step.r * &x + &step.s * &t;
        for (i, c) in step.c.iter().enumerate() {
            v[(i, 0)] += c;
        }
        let (pv, status) = space.clip(v.as_ref(), &form.lower, &form.upper);
        let x = space.widen(x.as_ref());
        let mut forms = [&step.p * &x + &step.q * &pv, t];
        space.reduce(&mut forms, cap);
        let [x, t] = forms;
        xi = x;
        theta = t;
        iterates.push(&form.readout * &xi);
        log.push(status);
    }
    (iterates, log)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use qp_iter::{BoxSet, IterationMap, Method, ParametricQp};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// One clip on an interval: every point of the graph lies in the parallelogram, and an
    /// interval inside the box or beyond it adds no generator.
    #[test]
    fn the_clip_contains_its_graph() {
        for (c, s, want) in [
            (0.0, 0.5, ClipStatus::Inactive),
            (3.0, 0.5, ClipStatus::Saturated),
            (-3.0, 0.5, ClipStatus::Saturated),
            (0.8, 0.5, ClipStatus::Straddling),
            (0.0, 3.0, ClipStatus::Straddling),
        ] {
            let mut space = Space::default();
            space.add_intervals(1);
            let v = Mat::from_fn(1, 2, |_, j| if j == 0 { c } else { s });
            let (out, status) = space.clip(v.as_ref(), &[-1.0], &[1.0]);
            assert_eq!(status, vec![want], "{c} ± {s}");
            let new = space.count() - 1;
            assert_eq!(new, usize::from(want == ClipStatus::Straddling));
            for a in 0..=100 {
                let e = -1.0 + 0.02 * f64::from(a);
                let y = (c + s * e).clamp(-1.0, 1.0);
                let at = out[(0, 0)] + out[(0, 1)] * e;
                let slack = if new == 1 { out[(0, 2)].abs() } else { 0.0 };
                assert!(
                    (y - at).abs() <= slack + 1e-12,
                    "{c} ± {s} at {e}: {y} vs {at} ± {slack}"
                );
            }
        }
    }

    fn random_qp(r: &mut ChaCha8Rng, n: usize, nt: usize) -> ParametricQp {
        let b = Mat::from_fn(n, n, |_, _| r.random_range(-1.0..1.0));
        let h = Mat::from_fn(n, n, |i, j| {
            (0..n).map(|k| b[(i, k)] * b[(j, k)]).sum::<f64>() + if i == j { 0.3 } else { 0.0 }
        });
        let f = Mat::from_fn(n, nt, |_, _| r.random_range(-1.0..1.0));
        let half: Vec<f64> = (0..n).map(|_| r.random_range(0.3..1.0)).collect();
        ParametricQp::new(h, vec![0.0; n], f, BoxSet::symmetric(&half).unwrap()).unwrap()
    }

    /// A point of the unit ball of dimension `d` (on its sphere with `boundary`).
    fn ball_point(r: &mut ChaCha8Rng, d: usize, boundary: bool) -> Vec<f64> {
        let g: Vec<f64> = (0..d).map(|_| r.random_range(-1.0..1.0)).collect();
        let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
        let scale = if boundary {
            1.0
        } else {
            r.random_range(0.0..1.0)
        };
        g.iter().map(|x| x * scale / norm).collect()
    }

    /// Soundness of the propagation: z⁰ in a ball, θ in a box, K = 12 clipped steps of PG,
    /// FISTA and their Jacobi variants; from 1 000 sampled points (half on the ball's sphere
    /// and at the box's vertices) every real iterate z¹..z¹² lies in its zonotope along every
    /// coordinate and 8 random directions — with the cap forcing order reduction — and the
    /// clips straddle on most runs (the test exercises the relaxation, not the identity).
    #[test]
    fn every_real_iterate_lies_in_the_zonotope() {
        let mut r = ChaCha8Rng::seed_from_u64(38);
        let (n, nt, k) = (4, 2, 12);
        let mut straddled = 0;
        for case in 0..8 {
            let qp = random_qp(&mut r, n, nt);
            let method = [
                Method::PG,
                Method::FISTA,
                Method::JACOBI_PRESETS[0],
                Method::JACOBI_PRESETS[1],
            ][case % 4];
            let map = method.build(qp).unwrap();
            let form = ClipForm::of(&map).unwrap();
            let mut space = Space::default();
            let radius = 0.8;
            let zb = space.add_ball(n, radius);
            let tb = space.add_intervals(nt);
            let zc: Vec<f64> = (0..n).map(|_| r.random_range(-0.5..0.5)).collect();
            let tc: Vec<f64> = (0..nt).map(|_| r.random_range(-1.0..1.0)).collect();
            let tw: Vec<f64> = (0..nt).map(|_| r.random_range(0.1..1.0)).collect();
            let cols = 1 + space.count();
            let z0 = Mat::from_fn(n, cols, |i, j| {
                if j == 0 {
                    zc[i]
                } else if j == 1 + zb + i {
                    1.0
                } else {
                    0.0
                }
            });
            let th = Mat::from_fn(nt, cols, |i, j| {
                if j == 0 {
                    tc[i]
                } else if j == 1 + tb + i {
                    tw[i]
                } else {
                    0.0
                }
            });
            let (iterates, log) = iterate(&form, &mut space, z0.as_ref(), th.as_ref(), k, 24);
            if log.iter().flatten().any(|s| *s == ClipStatus::Straddling) {
                straddled += 1;
            }
            let dirs: Vec<Vec<f64>> = (0..8).map(|_| ball_point(&mut r, n, true)).collect();
            for sample in 0..1000 {
                let edge = sample % 2 == 0;
                let e = ball_point(&mut r, n, edge);
                let z: Vec<f64> = (0..n).map(|i| zc[i] + radius * e[i]).collect();
                let t: Vec<f64> = (0..nt)
                    .map(|i| {
                        let u = if edge {
                            if r.random_bool(0.5) { 1.0 } else { -1.0 }
                        } else {
                            r.random_range(-1.0..1.0)
                        };
                        tc[i] + tw[i] * u
                    })
                    .collect();
                let mut st = map.new_state();
                map.load(&mut st, &t);
                map.warm_start(&mut st, &z, None);
                for (j, zono) in iterates.iter().enumerate() {
                    qp_iter::run_fixed(&map, &mut st, 1);
                    let real = map.iterate(&st);
                    let zono = space.widen(zono.as_ref());
                    for i in 0..n {
                        let (lo, hi) = space.interval(zono.as_ref(), i);
                        assert!(
                            real[i] >= lo - 1e-12 && real[i] <= hi + 1e-12,
                            "case {case} {}: z{}[{i}] = {} outside [{lo}, {hi}]",
                            map.name(),
                            j + 1,
                            real[i]
                        );
                    }
                    for d in &dirs {
                        let row = Mat::from_fn(1, zono.ncols(), |_, c| {
                            (0..n).map(|i| d[i] * zono[(i, c)]).sum::<f64>()
                        });
                        let (_, hi) = space.interval(row.as_ref(), 0);
                        let at: f64 = (0..n).map(|i| d[i] * real[i]).sum();
                        assert!(at <= hi + 1e-12, "case {case}: direction exceeds");
                    }
                }
            }
        }
        assert!(
            straddled >= 6,
            "the clips straddled on {straddled} of 8 cases"
        );
    }

    /// Where no clip acts, the zonotope is the linear image: no generator is added and the
    /// iterate's form is the probed linear K-step map applied to the inputs' forms.
    #[test]
    fn without_active_clips_the_zonotope_is_the_linear_image() {
        let mut r = ChaCha8Rng::seed_from_u64(39);
        let (n, nt, k) = (3, 2, 5);
        let qp = random_qp(&mut r, n, nt);
        let wide = ParametricQp::new(
            qp.h().to_owned(),
            vec![0.0; n],
            qp.f().to_owned(),
            BoxSet::symmetric(&[1e3; 3]).unwrap(),
        )
        .unwrap();
        for method in [Method::PG, Method::FISTA] {
            let map = method.build(wide.clone()).unwrap();
            let form = ClipForm::of(&map).unwrap();
            let mut space = Space::default();
            space.add_ball(n, 0.1);
            space.add_intervals(nt);
            let z0 = Mat::from_fn(n, 1 + n + nt, |i, j| f64::from(u8::from(j == 1 + i)) + 0.1);
            let th = Mat::from_fn(nt, 1 + n + nt, |i, j| f64::from(u8::from(j == 1 + n + i)));
            let (iterates, _) = iterate(&form, &mut space, z0.as_ref(), th.as_ref(), k, 100);
            assert_eq!(space.count(), n + nt, "{method}: a generator was added");
            let lin = crate::linear::linearise(&map, "MHE")
                .unwrap()
                .k_step(k, faer::Par::Seq)
                .unwrap();
            let want = &lin.g * &z0 + &lin.j * &th;
            let got = &iterates[k - 1];
            for i in 0..n {
                for j in 0..want.ncols() {
                    assert!(
                        (got[(i, j)] - want[(i, j)]).abs() < 1e-9,
                        "{method} ({i}, {j})"
                    );
                }
            }
        }
    }
}
