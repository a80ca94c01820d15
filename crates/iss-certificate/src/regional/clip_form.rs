//! Each method's inner step with its projection kept: ξ⁺ = Pξ + Q·π_Z(Rξ + Sθ + c) + Tθ
//! (docs/theory.md, "Regional ISS with an active start-up", step 1).
//!
//! The linear module probes S = P + QR and S_θ = QS + T, which is all it needs where no
//! bound acts; a probe cannot separate P, Q and R, so they are read here from the methods'
//! definitions (their parameters read from the built maps, [`qp_iter::MethodMap`]):
//!
//! | method | ξ | P | Q | R | S | c |
//! | --- | --- | --- | --- | --- | --- | --- |
//! | PG (step α) | z | 0 | I | I − αH | −αF | −αq₀ |
//! | FISTA (1/L, β) | (x, y) | [[0, 0], [−βI, 0]] | [I; (1 + β)I] | [0, I − H/L] | −F/L | −q₀/L |
//!
//! T = 0 for both. FISTA's first step after a warm start (its restart) is the same with
//! β = 0, from ξ = (z⁰, z⁰). On the Jacobi-scaled problem (z = Dy) the table holds for the
//! scaled (H, F, q₀, Z) in the coordinates y, ξ starts from D⁻¹z⁰ and the iterate is D·y.
//! ADMM (its projection acts on the relaxed split point and enters s and u with opposite
//! signs) and general rows (an exact projection onto Z ∩ {l ≤ Gz ≤ u}, not a clip) are not
//! covered: [`ClipForm::of`] says so with a typed reason.

use faer::{Mat, MatRef};
use qp_iter::{IterationMap, MethodMap};

use super::model::ModelError;

/// One inner step ξ⁺ = Pξ + Q·π_Z(Rξ + Sθ + c) + Tθ (T = 0 for the methods covered).
#[derive(Debug, Clone)]
pub(crate) struct ClipStep {
    pub p: Mat<f64>,
    pub q: Mat<f64>,
    pub r: Mat<f64>,
    pub s: Mat<f64>,
    pub c: Vec<f64>,
}

/// The inner iteration of one method on one QP with its clips.
#[derive(Debug, Clone)]
pub(crate) struct ClipForm {
    /// n: length of z.
    pub n: usize,
    /// ξ before the first step, from z⁰ (n_ξ × n).
    pub pre: Mat<f64>,
    /// FISTA's restart step (the first step after a warm start), counted in K.
    pub restart: Option<ClipStep>,
    /// Every further step.
    pub step: ClipStep,
    /// Z in the coordinates π acts on.
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    /// The iterate z = readout·ξ (n × n_ξ).
    pub readout: Mat<f64>,
}

fn not_covered(what: &str) -> ModelError {
    ModelError::NotCovered(format!(
        "{what}: the start-up certificate covers PG and FISTA (plain or Jacobi-scaled) on a \
         box; this method's projection is not written as a clip of its iteration state"
    ))
}

/// The PG-shaped step on (H, F, q₀) with step a: P = 0 on ξ of size n·blocks handled by caller.
fn gradient_point(inner: &qp_iter::ParametricQp, a: f64) -> (Mat<f64>, Mat<f64>, Vec<f64>) {
    let (n, h, f) = (inner.n(), inner.h(), inner.f());
    let r = Mat::from_fn(n, n, |i, j| f64::from(u8::from(i == j)) - a * h[(i, j)]);
    let s = Mat::from_fn(n, f.ncols(), |i, j| -a * f[(i, j)]);
    let c = inner.q0().iter().map(|q| -a * q).collect();
    (r, s, c)
}

/// FISTA's step with momentum `beta` on ξ = (x, y): x⁺ = π(T-point of y), y⁺ = (1 + β)x⁺ − βx.
fn fista_step(inner: &qp_iter::ParametricQp, inv_l: f64, beta: f64) -> ClipStep {
    let n = inner.n();
    let (t, s, c) = gradient_point(inner, inv_l);
    ClipStep {
        p: Mat::from_fn(
            2 * n,
            2 * n,
            |i, j| {
                if i >= n && j == i - n { -beta } else { 0.0 }
            },
        ),
        q: Mat::from_fn(2 * n, n, |i, j| {
            if i == j {
                1.0
            } else if i == j + n {
                1.0 + beta
            } else {
                0.0
            }
        }),
        r: Mat::from_fn(n, 2 * n, |i, j| if j >= n { t[(i, j - n)] } else { 0.0 }),
        s,
        c,
    }
}

impl ClipStep {
    /// ξ⁺ with π the box clip on [lower, upper] (`clip`) or the identity; writes `out`.
    pub(crate) fn apply(
        &self,
        xi: &[f64],
        theta: &[f64],
        (lower, upper): (&[f64], &[f64]),
        clip: bool,
        out: &mut [f64],
    ) {
        let v: Vec<f64> = (0..self.r.nrows())
            .map(|i| {
                let a = (0..xi.len()).map(|j| self.r[(i, j)] * xi[j]).sum::<f64>()
                    + (0..theta.len())
                        .map(|j| self.s[(i, j)] * theta[j])
                        .sum::<f64>()
                    + self.c[i];
                if clip { a.clamp(lower[i], upper[i]) } else { a }
            })
            .collect();
        for (i, o) in out.iter_mut().enumerate() {
            *o = (0..xi.len()).map(|j| self.p[(i, j)] * xi[j]).sum::<f64>()
                + (0..v.len()).map(|j| self.q[(i, j)] * v[j]).sum::<f64>();
        }
    }

    /// The linear part where π is the identity: [P + QR | QS].
    pub(crate) fn linear(&self) -> Mat<f64> {
        let a = &self.p + &self.q * &self.r;
        let b = &self.q * &self.s;
        Mat::from_fn(a.nrows(), a.ncols() + b.ncols(), |i, j| {
            if j < a.ncols() {
                a[(i, j)]
            } else {
                b[(i, j - a.ncols())]
            }
        })
    }
}

impl ClipForm {
    /// The clip form of `map` read off its definition, or why it is not covered.
    pub(crate) fn of(map: &MethodMap) -> Result<Self, ModelError> {
        let (d, inner) = match map {
            MethodMap::Scaled(s) => (Some(s.scaling().to_vec()), s.inner()),
            m => (None, m),
        };
        let qp = inner.problem();
        if qp.general().is_some() {
            return Err(not_covered(
                "general rows (sets.state / sets.output on the window): the projection onto \
                 Z ∩ {l ≤ Gz ≤ u} is not a clip",
            ));
        }
        let n = qp.n();
        let dinv = |j: usize| d.as_ref().map_or(1.0, |d| 1.0 / d[j]);
        let dz = |i: usize| d.as_ref().map_or(1.0, |d| d[i]);
        let (pre, restart, step, nxi) = match inner {
            MethodMap::Pg(pg) => {
                let (r, s, c) = gradient_point(qp, pg.alpha());
                let step = ClipStep {
                    p: Mat::zeros(n, n),
                    q: Mat::identity(n, n),
                    r,
                    s,
                    c,
                };
                let pre = Mat::from_fn(n, n, |i, j| if i == j { dinv(j) } else { 0.0 });
                (pre, None, step, n)
            }
            MethodMap::Fista(f) => {
                let pre = Mat::from_fn(2 * n, n, |i, j| if i % n == j { dinv(j) } else { 0.0 });
                let restart = fista_step(qp, f.step_size(), 0.0);
                let step = fista_step(qp, f.step_size(), f.momentum());
                (pre, Some(restart), step, 2 * n)
            }
            MethodMap::Scaled(_) => return Err(not_covered("a scaling of a scaled map")),
            _ => return Err(not_covered(&format!("the method `{}`", inner.name()))),
        };
        Ok(Self {
            n,
            pre,
            restart,
            step,
            lower: qp.zset().lower().to_vec(),
            upper: qp.zset().upper().to_vec(),
            readout: Mat::from_fn(n, nxi, |i, j| if i == j { dz(i) } else { 0.0 }),
        })
    }

    /// n_ξ.
    pub(crate) fn lift_dim(&self) -> usize {
        self.pre.nrows()
    }

    /// k₀: steps taken by the restart.
    pub(crate) fn start_steps(&self) -> usize {
        usize::from(self.restart.is_some())
    }

    /// zᴷ after K ≥ k₀ steps from the warm start z⁰ with θ loaded, each π the clip
    /// (`clip`) or the identity. For checks: allocates.
    pub(crate) fn run(&self, z0: &[f64], theta: &[f64], k: usize, clip: bool) -> Vec<f64> {
        let nxi = self.lift_dim();
        let mut xi: Vec<f64> = (0..nxi)
            .map(|i| (0..self.n).map(|j| self.pre[(i, j)] * z0[j]).sum())
            .collect();
        let mut next = vec![0.0; nxi];
        let bounds = (self.lower.as_slice(), self.upper.as_slice());
        for j in 0..k {
            let step = match (&self.restart, j) {
                (Some(r), 0) => r,
                _ => &self.step,
            };
            step.apply(&xi, theta, bounds, clip, &mut next);
            std::mem::swap(&mut xi, &mut next);
        }
        (0..self.n)
            .map(|i| (0..nxi).map(|j| self.readout[(i, j)] * xi[j]).sum())
            .collect()
    }

    /// The start map Ξ = [Ξ_z | Ξ_θ] where π is the identity (what `linearise` probes).
    pub(crate) fn linear_start(&self, n_theta: usize) -> Mat<f64> {
        match &self.restart {
            None => Mat::from_fn(self.lift_dim(), self.n + n_theta, |i, j| {
                if j < self.n { self.pre[(i, j)] } else { 0.0 }
            }),
            Some(r) => {
                let lin = r.linear();
                let nxi = self.lift_dim();
                let z = lin.as_ref().subcols(0, nxi) * self.pre.as_ref();
                let th = lin.as_ref().subcols(nxi, n_theta);
                concat_cols(z.as_ref(), th)
            }
        }
    }
}

fn concat_cols(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    Mat::from_fn(a.nrows(), a.ncols() + b.ncols(), |i, j| {
        if j < a.ncols() {
            a[(i, j)]
        } else {
            b[(i, j - a.ncols())]
        }
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::linear::linearise;
    use qp_iter::{BoxSet, Method, ParametricQp};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const COVERED: [Method; 4] = [
        Method::PG,
        Method::FISTA,
        Method::JACOBI_PRESETS[0],
        Method::JACOBI_PRESETS[1],
    ];

    /// A random SPD QP (badly scaled diagonal, so Jacobi matters) with a box around 0.
    fn random_qp(r: &mut ChaCha8Rng, n: usize, nt: usize, with_q0: bool) -> ParametricQp {
        let b = Mat::from_fn(n, n, |_, _| r.random_range(-1.0..1.0));
        let scale: Vec<f64> = (0..n)
            .map(|_| 10f64.powf(r.random_range(-1.0..1.0)))
            .collect();
        let h = Mat::from_fn(n, n, |i, j| {
            let g: f64 = (0..n).map(|k| b[(i, k)] * b[(j, k)]).sum();
            scale[i] * scale[j] * (g + if i == j { 0.5 } else { 0.0 })
        });
        let f = Mat::from_fn(n, nt, |_, _| r.random_range(-2.0..2.0));
        let q0 = (0..n)
            .map(|_| r.random_range(-0.5..0.5) * f64::from(u8::from(with_q0)))
            .collect();
        let half: Vec<f64> = (0..n).map(|_| r.random_range(0.2..1.0)).collect();
        ParametricQp::new(h, q0, f, BoxSet::symmetric(&half).unwrap()).unwrap()
    }

    fn close(a: f64, b: f64, scale: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * (1.0 + scale)
    }

    /// With π the identity the clip form is the probed linear map entry by entry (start,
    /// step, readout), on random QPs and on the shipped double integrator's MHE windows.
    #[test]
    fn without_clips_the_form_is_the_probed_linear_map() {
        let mut r = ChaCha8Rng::seed_from_u64(35);
        let mut maps = Vec::new();
        for _ in 0..6 {
            // q₀ = 0 as in the MHE: the probe's base point is then the origin, inside Z.
            let qp = random_qp(&mut r, 5, 3, false);
            for m in COVERED {
                maps.push(m.build(qp.clone()).unwrap());
            }
        }
        let file = format!(
            "{}/../../scenarios/double-integrator.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        let res = closed_loop::scenario::Scenario::from_file(&file)
            .unwrap()
            .resolve()
            .unwrap();
        for m in COVERED {
            let est = res.estimator(m, qp_iter::Iterations::ONE, false).unwrap();
            for w in [1, est.config().horizon] {
                maps.push(est.map(w).unwrap().clone());
            }
        }
        for map in &maps {
            let form = ClipForm::of(map).unwrap();
            let lin = linearise(map, "MHE").unwrap();
            let nt = lin.n_theta;
            assert_eq!(form.start_steps(), lin.start_steps);
            for (ours, probed, what) in [
                (form.step.linear(), lin.step.clone(), "step"),
                (form.linear_start(nt), lin.start.clone(), "start"),
                (form.readout.clone(), lin.readout.clone(), "readout"),
            ] {
                assert_eq!(
                    (ours.nrows(), ours.ncols()),
                    (probed.nrows(), probed.ncols())
                );
                let scale = probed.norm_max();
                for i in 0..ours.nrows() {
                    for j in 0..ours.ncols() {
                        assert!(
                            close(ours[(i, j)], probed[(i, j)], scale, 1e-10),
                            "{}: {what} ({i}, {j}) {} vs probed {}",
                            map.name(),
                            ours[(i, j)],
                            probed[(i, j)]
                        );
                    }
                }
            }
        }
    }

    /// With the real boxes, K steps of the clip form are K steps of the real method (qp-iter's
    /// `run_fixed` after `load` and `warm_start`), from random points far enough out that
    /// the clips act — and the same steps without the clips differ (the test can fail).
    #[test]
    fn with_clips_the_form_is_the_real_method() {
        let mut r = ChaCha8Rng::seed_from_u64(36);
        let mut clipped_runs = 0;
        for _ in 0..20 {
            let (n, nt) = (r.random_range(2..7), r.random_range(1..4));
            let qp = random_qp(&mut r, n, nt, true);
            for m in COVERED {
                let map = m.build(qp.clone()).unwrap();
                let form = ClipForm::of(&map).unwrap();
                let z0: Vec<f64> = (0..n).map(|_| r.random_range(-2.0..2.0)).collect();
                let theta: Vec<f64> = (0..nt).map(|_| r.random_range(-2.0..2.0)).collect();
                for k in [1, 2, 7] {
                    let mut st = map.new_state();
                    map.load(&mut st, &theta);
                    map.warm_start(&mut st, &z0, None);
                    qp_iter::run_fixed(&map, &mut st, k);
                    let real = map.iterate(&st).to_vec();
                    let ours = form.run(&z0, &theta, k, true);
                    let scale = real.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
                    for (a, b) in ours.iter().zip(&real) {
                        assert!(
                            close(*a, *b, scale, 1e-11),
                            "{}, K = {k}: {a} vs {b}",
                            map.name()
                        );
                    }
                    let free = form.run(&z0, &theta, k, false);
                    if free.iter().zip(&real).any(|(a, b)| (a - b).abs() > 1e-6) {
                        clipped_runs += 1;
                    }
                }
            }
        }
        assert!(
            clipped_runs > 200,
            "the clips acted on {clipped_runs} runs only"
        );
    }

    /// ADMM and general rows are a typed "not covered", never silently linear.
    #[test]
    fn admm_and_general_rows_are_not_covered() {
        let mut r = ChaCha8Rng::seed_from_u64(37);
        let qp = random_qp(&mut r, 3, 1, true);
        for m in [Method::ADMM, Method::ADMM_PR, Method::JACOBI_PRESETS[2]] {
            let e = ClipForm::of(&m.build(qp.clone()).unwrap()).unwrap_err();
            assert!(e.to_string().contains("not written as a clip"), "{e}");
        }
        let g = qp_iter::problem::GeneralConstraints::new(
            Mat::from_fn(1, 3, |_, j| j as f64),
            Mat::zeros(1, 1),
            vec![-1.0],
            vec![1.0],
        )
        .unwrap();
        let general = qp.with_general(g).unwrap();
        let e = ClipForm::of(&Method::PG.build(general).unwrap()).unwrap_err();
        assert!(e.to_string().contains("general rows"), "{e}");
    }
}
