//! Theorem L2 (the loop-level Lur'e certificate, issue 35) checked independently:
//! (i) with the clamps replaced by the identity the chain reaches K_lin of the lifted linear
//! loop; (ii) sampled trajectories with active clamps stay inside the certified ISS bound;
//! (iii) an optimised search over clamp patterns finds no violation where certified, and
//! does find one for the certificate of the unclamped loop on an unstable plant.
//!
//! The loops are a scalar plant x⁺ = a x + b u + w, u = −ℓx̂, with a one-step MHE-like
//! estimator: z = (s, ω) estimates (x_{t−1}, w_{t−1}), cost
//! ½q(s − x̂_{t−1})² + ½q_w ω² + ½r(a s + ω + b u_{t−1} − y_t)² + ½r(s − y_{t−1})², solved by
//! K projected-gradient steps (step 1/L) from (x̂_{t−1}, 0); the box clamps ω (and, where
//! asked, s). Lifted state X = (x_t, x_{t−1}, x̂_{t−1}).

use faer::{Mat, Par};
use iss_certificate::linear::spectral_radius_dense;
use iss_certificate::lure::loop_level::{
    LoopCertificate, LoopError, LoopOptions, LureLoop, Matrix, certify_loop, k_loop,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

mod f32_seeds;
mod sound;

#[derive(Debug, Clone, Copy)]
struct Plant {
    a: f64,
    b: f64,
    ell: f64,
    q: f64,
    qw: f64,
    r: f64,
    clamp_s: bool,
}

impl Plant {
    /// H, F (gradient Hξ − F X) and α = 1/λ_max(H).
    fn qp(&self) -> ([[f64; 2]; 2], [[f64; 3]; 2], f64) {
        let Plant {
            a,
            b,
            ell,
            q,
            qw,
            r,
            ..
        } = *self;
        // Residuals gᵀξ − fᵀX with weights.
        let res: [(f64, [f64; 2], [f64; 3]); 4] = [
            (q, [1.0, 0.0], [0.0, 0.0, 1.0]),
            (qw, [0.0, 1.0], [0.0, 0.0, 0.0]),
            (r, [a, 1.0], [1.0, 0.0, b * ell]),
            (r, [1.0, 0.0], [0.0, 1.0, 0.0]),
        ];
        let mut h = [[0.0; 2]; 2];
        let mut f = [[0.0; 3]; 2];
        for (w, g, fx) in res {
            for i in 0..2 {
                for j in 0..2 {
                    h[i][j] += w * g[i] * g[j];
                }
                for j in 0..3 {
                    f[i][j] += w * g[i] * fx[j];
                }
            }
        }
        let tr = h[0][0] + h[1][1];
        let det = h[0][0] * h[1][1] - h[0][1] * h[1][0];
        let l = 0.5 * tr + (0.25 * tr * tr - det).sqrt();
        (h, f, 1.0 / l)
    }

    /// One sample of the real loop: K projected-gradient steps with the box [−c, c] on the
    /// clamped components (c = ∞: unclamped), or with the given slopes per iteration.
    fn step(
        &self,
        x: &[f64; 3],
        w: f64,
        k: usize,
        clamp: &mut dyn FnMut(usize, usize, f64) -> f64,
    ) -> [f64; 3] {
        let (h, f, alpha) = self.qp();
        let mut xi = [x[2], 0.0];
        for kk in 0..k {
            let mut v = [0.0; 2];
            for i in 0..2 {
                let grad = h[i][0] * xi[0] + h[i][1] * xi[1]
                    - (f[i][0] * x[0] + f[i][1] * x[1] + f[i][2] * x[2]);
                v[i] = xi[i] - alpha * grad;
            }
            let s_new = if self.clamp_s {
                clamp(kk, 1, v[0])
            } else {
                v[0]
            };
            xi = [s_new, clamp(kk, 0, v[1])];
        }
        let xhat = self.a * xi[0] + xi[1] - self.b * self.ell * x[2];
        let u = -self.ell * xhat;
        [self.a * x[0] + self.b * u + w, x[0], xhat]
    }

    fn lure(&self) -> LureLoop {
        let (h, f, al) = self.qp();
        let (a, b, ell) = (self.a, self.b, self.ell);
        let i_ah = [
            [1.0 - al * h[0][0], -al * h[0][1]],
            [-al * h[1][0], 1.0 - al * h[1][1]],
        ];
        let af = |i: usize| vec![al * f[i][0], al * f[i][1], al * f[i][2]];
        let (a_xi, b_delta, e_x, c, d_x) = if self.clamp_s {
            (
                Matrix::zeros(2, 2),
                Matrix::new(2, 2, vec![1.0, 0.0, 0.0, 1.0]),
                Matrix::zeros(2, 3),
                Matrix::new(2, 2, vec![i_ah[0][0], i_ah[0][1], i_ah[1][0], i_ah[1][1]]),
                Matrix::new(2, 3, [af(0), af(1)].concat()),
            )
        } else {
            (
                Matrix::new(2, 2, vec![i_ah[0][0], i_ah[0][1], 0.0, 0.0]),
                Matrix::new(2, 1, vec![0.0, 1.0]),
                Matrix::new(2, 3, [af(0), vec![0.0; 3]].concat()),
                Matrix::new(1, 2, vec![i_ah[1][0], i_ah[1][1]]),
                Matrix::new(1, 3, af(1)),
            )
        };
        let nc = c.rows;
        LureLoop {
            s0: Matrix::new(2, 3, vec![0.0, 0.0, 1.0, 0.0, 0.0, 0.0]),
            s_w: Matrix::zeros(2, 1),
            a_xi,
            b_delta,
            e_x,
            e_w: Matrix::zeros(2, 1),
            c,
            d_x,
            d_w: Matrix::zeros(nc, 1),
            a_loop: Matrix::new(
                3,
                3,
                vec![a, 0.0, b * b * ell * ell, 1.0, 0.0, 0.0, 0.0, 0.0, -b * ell],
            ),
            g_loop: Matrix::new(3, 2, vec![-b * ell * a, -b * ell, 0.0, 0.0, a, 1.0]),
            b_loop: Matrix::new(3, 1, vec![1.0, 0.0, 0.0]),
        }
    }

    /// ρ_lin(K) from the lifted matrix built column by column by the real loop's step with
    /// no clamp (independent of `LureLoop`), through `linear`'s eigenvalue solver.
    fn rho_lin(&self, k: usize) -> f64 {
        let mut m = Mat::<f64>::zeros(3, 3);
        for j in 0..3 {
            let mut e = [0.0; 3];
            e[j] = 1.0;
            let col = self.step(&e, 0.0, k, &mut |_, _, v| v);
            for i in 0..3 {
                m[(i, j)] = col[i];
            }
        }
        spectral_radius_dense(m.as_ref(), Par::Seq).expect("3 × 3 eigenvalues")
    }

    /// K_lin on 0..=k_max: the smallest K from which ρ_lin < 1 up to k_max.
    fn k_lin(&self, k_max: usize) -> Option<usize> {
        let ok: Vec<bool> = (0..=k_max).map(|k| self.rho_lin(k) < 1.0).collect();
        let last_bad = ok.iter().rposition(|o| !o);
        match last_bad {
            None => Some(0),
            Some(i) if i < k_max => Some(i + 1),
            _ => None,
        }
    }
}

fn norm_p(c: &LoopCertificate, x: &[f64; 3]) -> f64 {
    c.storage(x)
}

const UNSTABLE: Plant = Plant {
    a: 1.5,
    b: 1.0,
    ell: 1.0,
    q: 0.05,
    qw: 50.0,
    r: 1.0,
    clamp_s: false,
};

fn plants() -> [Plant; 3] {
    [
        UNSTABLE,
        Plant {
            a: 1.2,
            qw: 100.0,
            q: 0.2,
            ell: 0.9,
            ..UNSTABLE
        },
        Plant {
            a: 0.95,
            qw: 5.0,
            q: 0.01,
            ell: 0.5,
            ..UNSTABLE
        },
    ]
}

#[test]
#[ignore = "release: barrier SDPs, run by .ci/run with --release --ignored"]
fn sdp_unclamped_chain_reaches_k_lin() {
    let opts = LoopOptions::default();
    for p in plants() {
        let k_lin = p.k_lin(15).expect("K_lin within 15");
        let lp = p.lure().unclamped();
        let cert = k_loop(&lp, 15, &opts)
            .expect("small LMI")
            .expect("a certificate where ρ_lin < 1");
        assert_eq!(
            cert.k, k_lin,
            "{p:?}: K_loop(unclamped) = {} vs K_lin = {k_lin}",
            cert.k
        );
        let rl = p.rho_lin(cert.k);
        // A quadratic certificate with rate ρ bounds the spectral radius; the bisection
        // brackets ρ_lin to its tolerance.
        assert!(cert.rho >= rl - 1e-9, "ρ = {} < ρ_lin = {rl}", cert.rho);
        assert!(
            cert.rho <= rl + 0.02,
            "ρ = {} far above ρ_lin = {rl}",
            cert.rho
        );
        eprintln!(
            "{p:?}: K_lin = K_loop = {k_lin}, ρ_lin = {rl:.4}, ρ = {:.4}",
            cert.rho
        );
    }
}

#[test]
#[ignore = "release: barrier SDPs, run by .ci/run with --release --ignored"]
fn sdp_clamped_k_loop_is_at_least_k_lin() {
    let opts = LoopOptions::default();
    for p in plants() {
        let k_lin = p.k_lin(15).expect("K_lin within 15");
        let c = k_loop(&p.lure(), 15, &opts).expect("small LMI");
        // The ω box is harmless globally (s is free): every plant here gets a certificate.
        let cert = c.as_ref().expect("a loop certificate within K = 15");
        assert!(cert.k >= k_lin, "{p:?}: K_loop {} < K_lin {k_lin}", cert.k);
        eprintln!(
            "{p:?}: K_lin = {k_lin}, K_loop (ω clamped) = {:?}, ρ = {:?}, γ = {:?}",
            c.as_ref().map(|c| c.k),
            c.as_ref().map(|c| c.rho),
            c.as_ref().map(|c| c.gamma)
        );
    }
}

/// A clamp on the estimate of an unstable plant keeps the control bounded, so no global
/// certificate can exist; the chain must certify nothing.
#[test]
#[ignore = "release: barrier SDPs, run by .ci/run with --release --ignored"]
fn sdp_certifies_nothing_where_the_clamped_loop_is_globally_unstable() {
    let p = Plant {
        clamp_s: true,
        ..UNSTABLE
    };
    let opts = LoopOptions::default();
    for k in 0..=8 {
        let r = certify_loop(&p.lure(), k, &opts);
        assert!(
            matches!(r, Err(LoopError::NotCertified { .. })),
            "K = {k}: {r:?}"
        );
    }
    // And the clamps really make it diverge from a large start at a K where ρ_lin < 1.
    let k = p.k_lin(15).expect("K_lin");
    let mut x = [50.0, 50.0, 0.0];
    for _ in 0..60 {
        x = p.step(&x, 0.0, k, &mut |_, _, v| v.clamp(-1.0, 1.0));
    }
    assert!(x[0].abs() > 1e6, "clamped loop did not diverge: {x:?}");
}

/// The largest one-step ratio (‖X⁺‖²_P − γ²w²)/(ρ²‖X‖²_P) over X, w and per-iteration
/// slopes s ∈ [0, 1]: random starts, then coordinate-wise local improvement.
fn worst_ratio(
    p: &Plant,
    c: &LoopCertificate,
    wbar: f64,
    rng: &mut ChaCha8Rng,
    starts: usize,
) -> f64 {
    let k = c.k;
    let nsl = 2 * k.max(1);
    let eval = |x: &[f64; 3], w: f64, sl: &[f64]| {
        let y = p.step(x, w, k, &mut |kk, i, v| sl[2 * kk + i] * v);
        (norm_p(c, &y) - c.gamma * c.gamma * w * w) / (c.rho * c.rho * norm_p(c, x))
    };
    let mut best = f64::NEG_INFINITY;
    for _ in 0..starts {
        let mut x = [
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ];
        let mut w = rng.random_range(-wbar..=wbar);
        let mut sl: Vec<f64> = (0..nsl)
            .map(|_| {
                if rng.random_bool(0.5) {
                    rng.random_range(0.0..=1.0)
                } else {
                    f64::from(u8::from(rng.random_bool(0.5)))
                }
            })
            .collect();
        let mut val = eval(&x, w, &sl);
        let mut h = 0.3;
        for _ in 0..40 {
            let mut improved = false;
            for j in 0..3 + 1 + nsl {
                for dir in [-1.0, 1.0] {
                    let (mut x2, mut w2, mut sl2) = (x, w, sl.clone());
                    match j {
                        0..=2 => x2[j] += dir * h,
                        3 => w2 = (w2 + dir * h * wbar).clamp(-wbar, wbar),
                        _ => sl2[j - 4] = (sl2[j - 4] + dir * h).clamp(0.0, 1.0),
                    }
                    let v2 = eval(&x2, w2, &sl2);
                    if v2 > val {
                        (x, w, sl, val, improved) = (x2, w2, sl2, v2, true);
                    }
                }
            }
            if !improved {
                h *= 0.5;
            }
        }
        best = best.max(val);
    }
    best
}

fn random_plant(rng: &mut ChaCha8Rng) -> Plant {
    let a = rng.random_range(0.3..1.6);
    Plant {
        a,
        b: rng.random_range(0.5..1.5),
        ell: 0.0,
        q: rng.random_range(0.01..1.0),
        qw: rng.random_range(0.2..50.0),
        r: 1.0,
        clamp_s: a < 0.9 && rng.random_bool(0.5),
    }
    .with_deadbeat_gain()
}

impl Plant {
    /// ℓ placing a − bℓ at a random stable point.
    fn with_deadbeat_gain(mut self) -> Self {
        self.ell = (self.a - 0.3) / self.b;
        self
    }
}

/// (ii) and (iii): on random plants where the chain certifies, thousands of sampled runs
/// with real clamps and with arbitrary sector slopes stay within the certified bound, and
/// the optimised one-step search finds no violation.
#[test]
#[ignore = "release: barrier SDPs, run by .ci/run with --release --ignored"]
fn sdp_sampled_and_adversarial_clamps_respect_the_certificate() {
    let mut rng = ChaCha8Rng::seed_from_u64(35);
    let opts = LoopOptions {
        rho_tol: 1e-2,
        ..LoopOptions::default()
    };
    let (mut certified, mut runs, mut worst) = (0usize, 0usize, 0.0_f64);
    for _inst in 0..30 {
        let p = random_plant(&mut rng);
        let k = rng.random_range(1..=6);
        let Ok(c) = certify_loop(&p.lure(), k, &opts) else {
            continue;
        };
        certified += 1;
        let wbar = 0.1;
        for run in 0..100 {
            let cbox: f64 = rng.random_range(0.01..2.0);
            let mut x = [
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
            ];
            let v0 = norm_p(&c, &x);
            let mut vt;
            let mut rho2t = 1.0;
            for _t in 0..80 {
                let w = rng.random_range(-wbar..=wbar);
                let before = norm_p(&c, &x);
                x = if run % 2 == 0 {
                    p.step(&x, w, k, &mut |_, _, v| v.clamp(-cbox, cbox))
                } else {
                    let s: f64 = rng.random_range(0.0..=1.0);
                    p.step(&x, w, k, &mut |_, _, v| s * v)
                };
                vt = norm_p(&c, &x);
                rho2t *= c.rho * c.rho;
                let one = c.rho * c.rho * before + c.gamma * c.gamma * w * w;
                assert!(
                    vt <= one * (1.0 + 1e-9) + 1e-300,
                    "{p:?} K = {k}: one step {vt} > {one}"
                );
                let iss = rho2t * v0 + c.gamma * c.gamma / (1.0 - c.rho * c.rho) * wbar * wbar;
                assert!(
                    vt <= iss * (1.0 + 1e-9),
                    "{p:?} K = {k}: ISS bound {vt} > {iss}"
                );
                runs += 1;
            }
        }
        // From X₀ = 0 the certified readout gains bound every sample, not only the lim sup.
        let ge = c
            .readout_gain(&Matrix::new(1, 3, vec![0.0, 1.0, -1.0]))
            .expect("P invertible");
        let gx = c
            .readout_gain(&Matrix::new(1, 3, vec![1.0, 0.0, 0.0]))
            .expect("P invertible");
        assert!(gx.is_finite() && ge.is_finite() && gx > 0.0);
        for _run in 0..20 {
            let cbox: f64 = rng.random_range(0.01..2.0);
            let mut x = [0.0; 3];
            for _t in 0..80 {
                let w = if rng.random_bool(0.5) { wbar } else { -wbar };
                x = p.step(&x, w, k, &mut |_, _, v| v.clamp(-cbox, cbox));
                assert!(
                    (x[1] - x[2]).abs() <= ge * wbar * (1.0 + 1e-9),
                    "‖e‖ above its gain"
                );
                assert!(x[0].abs() <= gx * wbar * (1.0 + 1e-9), "‖x‖ above its gain");
            }
        }
        let r = worst_ratio(&p, &c, 0.1, &mut rng, 20);
        worst = worst.max(r);
        assert!(
            r <= 1.0 + 1e-9,
            "{p:?} K = {k}: adversarial one-step ratio {r}"
        );
    }
    eprintln!("{certified}/30 certified; {runs} sampled steps; worst adversarial ratio {worst:.6}");
    assert!(
        certified >= 8,
        "too few certified instances ({certified}) to test anything"
    );
}

/// (iii) The premise matters: the certificate of the unclamped loop (multipliers dropped,
/// clamps assumed inactive) on an unstable plant with its estimate clamped is refuted by the
/// same search, and by a run from a large start.
#[test]
#[ignore = "release: barrier SDPs, run by .ci/run with --release --ignored"]
fn sdp_dropping_the_multipliers_gives_a_certificate_clamps_refute() {
    let p = Plant {
        clamp_s: true,
        ..UNSTABLE
    };
    let opts = LoopOptions::default();
    let k = p.k_lin(15).expect("K_lin");
    let unsound = certify_loop(&p.lure().unclamped(), k, &opts).expect("linear loop certified");
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let r = worst_ratio(&p, &unsound, 0.1, &mut rng, 20);
    assert!(
        r > 1.0 + 1e-3,
        "search found no violation of the unclamped certificate: {r}"
    );
    let mut x = [50.0, 50.0, 0.0];
    let v0 = norm_p(&unsound, &x);
    let mut refuted = false;
    let mut rho2t = 1.0;
    for _ in 0..60 {
        x = p.step(&x, 0.0, k, &mut |_, _, v| v.clamp(-1.0, 1.0));
        rho2t *= unsound.rho * unsound.rho;
        refuted |= norm_p(&unsound, &x) > rho2t * v0;
    }
    assert!(refuted, "clamped run stayed inside the unclamped bound");
    eprintln!(
        "unclamped certificate at K = {k}: ρ = {:.4}; adversarial one-step ratio {r:.3}",
        unsound.rho
    );
}

/// The global loop certificate (`lure::global`) against random plants, CI-sized (the
/// ≥ 1 000-plant run is tests/global_sound.rs): 20 random plants × 8 methods; every
/// certificate re-checked independently, every certified pair attacked (random runs, the
/// optimised adversary, a long run) at K_glob, and the adversary at K = 1 where ρ_lin(1) ≥ 1.
#[test]
#[ignore = "release: run by .ci/run with --release --ignored"]
fn sdp_global_sound_small() {
    let sweep = sound::sweep::Sweep::run(0..20, &sound::sweep::SweepConfig::small());
    sweep.print();
    sweep.assert_sound();
}

#[test]
fn bad_shapes_and_sizes_are_typed_errors() {
    let mut lp = UNSTABLE.lure();
    lp.e_x = Matrix::zeros(2, 2);
    assert!(matches!(
        certify_loop(&lp, 1, &LoopOptions::default()),
        Err(LoopError::Shape { name: "e_x", .. })
    ));
    let opts = LoopOptions {
        max_unknowns: 50,
        ..LoopOptions::default()
    };
    let e = certify_loop(&UNSTABLE.lure(), 5, &opts).expect_err("too large");
    assert!(
        matches!(e, LoopError::SizeLimit { unknowns, .. } if unknowns > 50),
        "{e}"
    );
    assert!(e.to_string().contains("unknowns"));
}
