//! The regional certificate (issue 27): the lifted model against the real loop, soundness on
//! random plants, the region's boundary, and the void reasons.

use closed_loop::scenario::{ControllerChoice, LoopOptions, Scenario, ScenarioLoop};
use faer::{Mat, Par};
use iss_certificate::linear::{LiftedLayout, LiftedLoop};
use iss_certificate::regional::{
    RegionalDetail, RegionalOptions, RegionalVoid, RowKind, k_reg, regional_certificate,
    regional_detail,
};
use qp_iter::Method;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::build;

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn apply(a: &Mat<f64>, x: &[f64]) -> Vec<f64> {
    (0..a.nrows())
        .map(|i| (0..a.ncols()).map(|j| a[(i, j)] * x[j]).sum())
        .collect()
}

/// X_t from the running loop (t ≥ M), as in the linear tests.
fn lifted_state(cl: &ScenarioLoop, l: LiftedLayout) -> Vec<f64> {
    let (t, tr) = (cl.t(), cl.trace());
    let mut x = vec![0.0; l.dim()];
    x[..l.nx].copy_from_slice(cl.state());
    for j in 0..l.horizon {
        let s = t - l.horizon + j;
        x[l.u_window(j)..l.u_window(j) + l.nu].copy_from_slice(tr.u(s).unwrap());
        x[l.y_window(j)..l.y_window(j) + l.ny].copy_from_slice(tr.y(s).unwrap());
        x[l.estimates(j)..l.estimates(j) + l.nx].copy_from_slice(tr.x_hat(s).unwrap());
    }
    x[l.warm_start()..l.warm_start() + l.nz].copy_from_slice(cl.estimator().warm_start_point());
    if l.n_controller > 0 {
        let closed_loop::scenario::ScenarioController::Suboptimal(c) = cl.controller() else {
            panic!("a controller block without the K_c-iteration MPC");
        };
        x[l.controller()..l.controller() + l.n_controller].copy_from_slice(c.input_sequence());
    }
    x
}

/// X_{t+1} = 𝔸X_t + 𝔹_w w_t of the regional model.
fn lifted_step(d: &RegionalDetail, x: &[f64], w: &[f64]) -> Vec<f64> {
    apply(&d.a, x)
        .iter()
        .zip(apply(&d.bw, w))
        .map(|(p, q)| p + q)
        .collect()
}

/// X_M = 𝕄υ from a run's own x₀, x̄₀ and w₀..w_{M−1} (the loop stepped M times).
fn start_up_state(cl: &ScenarioLoop, s: &Scenario, d: &RegionalDetail) -> Vec<f64> {
    let big_m = s.mhe.as_ref().unwrap().horizon();
    let mut v = s.simulation.x0.clone();
    v.extend_from_slice(&s.simulation.prior);
    for t in 0..big_m {
        v.extend_from_slice(cl.trace().w(t).unwrap());
    }
    apply(&d.start_map, &v)
}

fn options(s: &Scenario, method: Method, k: usize) -> LoopOptions {
    let mut o = LoopOptions::from_scenario(s).unwrap();
    o.method = method;
    o = o.with_iterations(k).expect("K is in range");
    o.controller = ControllerChoice::ExactMpc;
    o
}

pub(crate) const STAND_IN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../scenarios/case-study-certified.toml"
);

/// 𝔸(K) of the regional model is the matrix of `linear::LiftedLoop` (same layout), for
/// each method and both warm starts.
#[test]
fn lifted_matrix_matches_the_linear_module() {
    for (method, shifted) in [
        (Method::PG, false),
        (Method::FISTA, false),
        (Method::ADMM, true),
    ] {
        let mut s = Scenario::from_file(STAND_IN).unwrap();
        if shifted {
            s.mhe = s
                .mhe
                .map(|m| m.with_warm_start(mhe_core::WarmStart::Shifted));
        }
        let res = s.clone().resolve().unwrap();
        let o = options(&s, method, 7);
        let cl = build(&s, &o).unwrap();
        let lin = LiftedLoop::from_loop(&cl, &res, method, Par::Seq).unwrap();
        let a = lin.matrix(7, Par::Seq).unwrap();
        let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
        let (_, d) = regional_detail(&res, method, 7, &ro).unwrap();
        assert_eq!((d.a.nrows(), d.a.ncols()), (a.nrows(), a.ncols()));
        let gap = (&d.a - &a).norm_max();
        assert!(gap <= 1e-12 * a.norm_max().max(1.0), "{method}: {gap:e}");
    }
}

/// A random plant: stable (ρ(A) < 1), marginal (ρ = 1) or unstable with 𝒰 = ℝ; the noise on
/// a subset of the states (E a column selection); small x₀ and prior so the region can
/// contain them.
fn random_plant(seed: u64, kind: usize) -> Scenario {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    let nx = 2 + (seed % 2) as usize;
    let mut a = Mat::from_fn(nx, nx, |_, _| r.random_range(-1.0..1.0));
    let rho = lti_model::system::spectral_radius(a.as_ref())
        .unwrap()
        .max(1e-3);
    let target = [0.7, 1.0, 1.3][kind];
    a *= faer::Scale(target / rho);
    let (row, mat) = (crate::toml_row, crate::toml_matrix);
    let b = Mat::from_fn(nx, 1, |i, _| {
        if i == nx - 1 {
            1.0
        } else {
            r.random_range(-0.5..0.5)
        }
    });
    let c = Mat::from_fn(1, nx, |_, j| {
        if j == 0 {
            1.0
        } else {
            r.random_range(-0.5..0.5)
        }
    });
    // Noise on the first state only: E = e₁ (n_x × 1), F = 1.
    let e = Mat::from_fn(nx, 1, |i, _| if i == 0 { 1.0 } else { 0.0 });
    let input = if kind == 2 {
        String::new()
    } else {
        "input = { lower = [-1.0], upper = [1.0] }".into()
    };
    let x0: Vec<f64> = (0..nx).map(|_| r.random_range(-0.01..0.01)).collect();
    let text = format!(
        r#"name = "random-{seed}"
[plant]
a = {a}
b = {b}
c = {c}
e = {e}
f = [[1.0]]
[sets]
{input}
disturbance = {{ lower = [-0.5, -0.5], upper = [0.5, 0.5] }}
[noise]
kind = "uniform"
scale = 0.002
seed = {seed}
[simulation]
x0 = {x0}
prior = {p0}
steps = 60
[mhe]
horizon = 3
eta = 0.5
iterations = 1
[mpc]
horizon = 5
q = 1.0
r = 1.0
"#,
        a = mat(&a),
        b = mat(&b),
        c = mat(&c),
        e = mat(&e),
        x0 = row(x0.clone()),
        p0 = row(vec![0.0; nx]),
    );
    Scenario::from_toml_str(&text).unwrap()
}

/// Soundness against the real loop: at K_reg of random stable, marginal and unstable
/// (𝒰 = ℝ) plants with noise on one state, the simulated loop (its own uniform noise within
/// w̄) stays the linear loop for every step — no constraint activates, X_t equals the lifted
/// prediction — and ‖X_t‖_P, ‖x_t‖, ‖e_t‖ meet the certified decay bounds.
#[test]
fn random_plants_stay_linear_and_meet_the_certified_decay() {
    let mut checked = 0;
    for seed in 0..12u64 {
        let kind = (seed % 3) as usize;
        let s = random_plant(1000 + seed, kind);
        let res = s.clone().resolve().unwrap();
        let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
        for method in [Method::PG, Method::FISTA, Method::ADMM] {
            let kr = match k_reg(&res, method, &ro, 256) {
                Ok(kr) => kr,
                Err(e) => panic!("seed {seed} {method}: {e}"),
            };
            let Some(k) = kr.k_reg else { continue };
            let (c, d) = regional_detail(&res, method, k, &ro).unwrap();
            assert!(c.contains && c.rate < 1.0);
            let o = options(&s, method, k);
            let mut cl = build(&s, &o).unwrap();
            let big_m = s.mhe.as_ref().unwrap().horizon();
            for _ in 0..big_m {
                cl.step().unwrap();
            }
            let l = LiftedLayout {
                nx: s.plant.nx(),
                nu: 1,
                ny: 1,
                horizon: big_m,
                nz: s.plant.nx() + big_m * s.plant.nw(),
                n_controller: 0,
            };
            let mut x = start_up_state(&cl, &s, &d);
            let pnorm = |x: &[f64]| norm(&apply(&d.p_half, x));
            let x_m = pnorm(&x);
            assert!(x_m <= c.initial_radius * (1.0 + 1e-9));
            let w_bar = ro.w_bar;
            for step in 0..40 {
                let sim = lifted_state(&cl, l);
                let gap = norm(&x.iter().zip(&sim).map(|(p, q)| p - q).collect::<Vec<_>>());
                assert!(
                    gap <= 1e-8 * norm(&sim).max(1e-12),
                    "seed {seed} {method} K = {k} step {step}: left the linear loop ({gap:e})"
                );
                let lam_t = c.rate.powi(step);
                let bound =
                    lam_t * x_m + c.disturbance_gain * w_bar * (1.0 - lam_t) / (1.0 - c.rate);
                assert!(pnorm(&sim) <= bound * (1.0 + 1e-9) + 1e-15);
                assert!(norm(cl.state()) <= c.x_read_norm * bound * (1.0 + 1e-9) + 1e-15);
                let t = cl.t();
                let e_now = norm(&apply(&d.e_read, &sim));
                assert!(e_now <= c.e_read_norm * bound * (1.0 + 1e-9) + 1e-15);
                cl.step().unwrap();
                let w = cl.trace().w(t).unwrap().to_vec();
                x = lifted_step(&d, &x, &w);
            }
            checked += 1;
        }
    }
    assert!(
        checked >= 12,
        "only {checked} certified (plant, method) pairs"
    );
}

/// The region's boundary. Without disturbance the certified set of X_M is the ellipsoid
/// ‖X‖_P ≤ r = min_c bound_c/‖P^{−½}cᵀ‖: from the point extreme along each row's normal the
/// linear loop keeps every row within its bound at every step and decays at the certified
/// rate, and the binding row's point 1 % farther out activates it. With the disturbance, the
/// certified radius shrinks by w̄h̃_c/‖P^{−½}cᵀ‖; from the same extreme points with the
/// worst-case disturbance sequence for that row, no row activates either.
#[test]
fn boundary_points_along_each_normal_are_inactive_and_one_percent_more_activates() {
    for seed in [2000u64, 2001, 2002] {
        let s = random_plant(seed, (seed % 3) as usize);
        let res = s.clone().resolve().unwrap();
        let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
        for w_bar in [0.0, ro.w_bar] {
            let o = RegionalOptions {
                w_bar,
                ..ro.clone()
            };
            let (c, d) = regional_detail(&res, Method::FISTA, 20, &o).unwrap();
            let r = c.radius;
            assert!(r.is_finite() && r > 0.0, "seed {seed}: radius {r}");
            let p_inv = &d.p_neg_half * &d.p_neg_half;
            let inside = |x: &[f64], tag: &str| {
                for (j, other) in d.rows.iter().enumerate() {
                    let v: f64 = other.iter().zip(x).map(|(a, b)| a * b).sum();
                    let tol = 1e-9 * d.upper[j].abs().min(d.lower[j].abs()).max(1e-12);
                    assert!(
                        v <= d.upper[j] + tol && v >= d.lower[j] - tol,
                        "seed {seed} w̄ = {w_bar}: row {j} active ({v} ∉ [{}, {}]) {tag}",
                        d.lower[j],
                        d.upper[j]
                    );
                }
            };
            let pnorm = |x: &[f64]| norm(&apply(&d.p_half, x));
            let mut hit_limit = false;
            for (i, row) in d.rows.iter().enumerate().step_by(3) {
                let cv = Mat::from_fn(row.len(), 1, |j, _| row[j]);
                let pc = &p_inv * &cv;
                let nrm = norm(&apply(&d.p_neg_half, row));
                let xs: Vec<f64> = (0..row.len()).map(|j| r * pc[(j, 0)] / nrm).collect();
                // Worst-case disturbance for row i at step T: w_{T−1−k} ∥ (c𝔸ᵏ𝔹_w)ᵀ.
                let t_end = 30;
                let mut v = Vec::new();
                let mut cak = row.clone(); // c𝔸ᵏ
                for _ in 0..t_end {
                    let g = apply(&d.bw.transpose().to_owned(), &cak);
                    let gn = norm(&g);
                    v.push(if gn > 0.0 {
                        g.iter().map(|x| w_bar * x / gn).collect::<Vec<_>>()
                    } else {
                        vec![0.0; g.len()]
                    });
                    cak = apply(&d.a.transpose().to_owned(), &cak);
                }
                let mut x = xs.clone();
                let x0p = pnorm(&xs);
                let mut xf = xs.clone(); // the free response
                for t in 0..t_end {
                    inside(&x, &format!("at step {t} from row {i}'s point"));
                    let lt = c.rate.powi(t as i32);
                    assert!(pnorm(&xf) <= lt * x0p * (1.0 + 1e-9) + 1e-15);
                    let w = &v[t_end - 1 - t];
                    x = lifted_step(&d, &x, w);
                    xf = apply(&d.a, &xf);
                }
                hit_limit |= i == 0;
            }
            assert!(hit_limit);
            if w_bar == 0.0 {
                // The binding row: argmin bound/‖P^{−½}cᵀ‖, which sets r at w̄ = 0.
                let i = (0..d.rows.len())
                    .min_by(|&a, &b| {
                        let f = |j: usize| {
                            d.upper[j].min(-d.lower[j]) / norm(&apply(&d.p_neg_half, &d.rows[j]))
                        };
                        f(a).total_cmp(&f(b))
                    })
                    .unwrap();
                let row = &d.rows[i];
                let cv = Mat::from_fn(row.len(), 1, |j, _| row[j]);
                let pc = &p_inv * &cv;
                let nrm = norm(&apply(&d.p_neg_half, row));
                let v: f64 = (0..row.len())
                    .map(|j| row[j] * 1.01 * r * pc[(j, 0)] / nrm)
                    .sum();
                assert!(
                    v > d.upper[i] || v < d.lower[i],
                    "1 % farther must activate"
                );
            }
        }
    }
}

/// Each broken premise voids with its exact reason.
#[test]
fn broken_premises_void_with_their_reason() {
    // ρ_lin ≥ 1: the unstable test plant at K = 1 (PG).
    let s = Scenario::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/unstable-2state.toml"
    ))
    .unwrap();
    let res = s.clone().resolve().unwrap();
    let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
    match regional_certificate(&res, Method::PG, 1, &ro) {
        Err(RegionalVoid::Unstable { k: 1, rho }) => assert!(rho >= 1.0),
        other => panic!("{other:?}"),
    }
    // A K_c-iteration MPC is covered on its input box; with the MPC's state rows it is not,
    // and says so (the mass chain with its state box in `sets.state`).
    let sub = ControllerChoice::suboptimal(5, Method::PG).unwrap();
    let boxed = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/mass-chain-state-box.toml"
    );
    let rb = Scenario::from_file(boxed).unwrap().resolve().unwrap();
    let ob = RegionalOptions::from_scenario(&rb, sub).unwrap();
    let e = regional_certificate(&rb, Method::PG, 4, &ob).unwrap_err();
    assert!(
        e.to_string().contains("K_c-iteration MPC with state rows"),
        "{e}"
    );
    // Gaussian noise without certificate.w_bar.
    let text = std::fs::read_to_string(STAND_IN).unwrap().replace(
        "kind = \"uniform\"",
        "kind = \"gaussian\"\ncovariance = [[1,0,0,0,0],[0,1,0,0,0],[0,0,1,0,0],[0,0,0,1,0],[0,0,0,0,1]]",
    );
    let g = Scenario::from_toml_str(&text).unwrap().resolve().unwrap();
    assert_eq!(
        RegionalOptions::from_scenario(&g, ControllerChoice::ExactMpc).unwrap_err(),
        RegionalVoid::UnboundedNoise
    );
    // 0 on the boundary of 𝒰.
    let text = std::fs::read_to_string(STAND_IN)
        .unwrap()
        .replace("lower = [-1.0, -1.0]", "lower = [0.0, -1.0]");
    let b = Scenario::from_toml_str(&text).unwrap().resolve().unwrap();
    let ro = RegionalOptions::from_scenario(&b, ControllerChoice::ExactMpc).unwrap();
    let e = regional_certificate(&b, Method::PG, 10, &ro).unwrap_err();
    assert!(
        e.to_string()
            .contains("0 is not an interior point of the MPC"),
        "{e}"
    );
}

/// The stand-in's own uncertainty (x₀ = (12, −10, 10, −10), prior error 10.9, w̄ = 0.22) is
/// far outside any region: the MHE's 𝒲 = [−0.1, 0.1] and 𝒰 = [−1, 1] rows bind, and the
/// certificate says which and by how much.
#[test]
fn the_stand_in_names_its_limiting_constraint() {
    let res = Scenario::from_file(STAND_IN).unwrap().resolve().unwrap();
    let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
    let c = regional_certificate(&res, Method::ADMM, 20, &ro).unwrap();
    assert!(!c.contains);
    assert!(c.margin < 1.0);
    let lim = c.radius_limit.unwrap();
    assert!(matches!(lim.row.kind, RowKind::MheBox | RowKind::Input));
    let sl = c.startup_limit.unwrap();
    assert!(sl.reach > sl.bound, "{sl:?}");
}

/// The free response's exact reach (reach.rs): on random stable, marginal and unstable plants,
/// sampled extreme points of the user's set — x₀ and the prior error on their spheres, every
/// w_t at a vertex of the scenario's noise box — never take a full-window row of the lifted
/// linear loop beyond its certified reach at any step; and with the set shrunk to the nominal
/// x₀ (no disturbance) the reach is attained by the nominal trajectory itself (it is exact
/// where the exact steps cover the peak, not the metric's Cauchy–Schwarz bound).
#[test]
fn the_rows_reach_bounds_sampled_extreme_points_and_is_attained_by_the_nominal() {
    let mut checked = [0usize; 3];
    for seed in 3000u64..3024 {
        let kind = (seed % 3) as usize;
        let s = random_plant(seed, kind);
        let res = s.clone().resolve().unwrap();
        let mut o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
        o.x0_radius = 0.005;
        o.prior_error = 0.01;
        let r = o.w_box.clone().expect("the uniform noise gives its box");
        // K = 20 of FISTA is not stable on every plant: those have no reach to check.
        let Ok((_, d)) = regional_detail(&res, Method::FISTA, 20, &o) else {
            continue;
        };
        checked[kind] += 1;
        let nx = s.plant.nx();
        let nw = r.len();
        let big_m = s.mhe.as_ref().unwrap().horizon();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut sphere = |n: usize, radius: f64| {
            let v: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
            let nv = norm(&v).max(1e-300);
            v.iter().map(|x| radius * x / nv).collect::<Vec<_>>()
        };
        let mut vertices = ChaCha8Rng::seed_from_u64(seed + 1);
        let mut vertex = || -> Vec<f64> {
            r.iter()
                .map(|ri| if vertices.random_bool(0.5) { *ri } else { -ri })
                .collect()
        };
        let mut worst: f64 = 0.0;
        for _ in 0..200 {
            let dx = sphere(nx, o.x0_radius);
            let de = sphere(nx, o.prior_error);
            let mut v: Vec<f64> = (0..nx).map(|i| o.x0_nominal[i] + dx[i]).collect();
            v.extend((0..nx).map(|i| o.x0_nominal[i] + dx[i] + de[i]));
            for _ in 0..big_m {
                v.extend(vertex());
            }
            let mut x = apply(&d.start_map, &v);
            for _ in 0..150 {
                for (i, row) in d.rows.iter().enumerate() {
                    let val: f64 = row.iter().zip(&x).map(|(a, b)| a * b).sum();
                    assert!(
                        val.abs() <= d.reach[i] * (1.0 + 1e-9) + 1e-14,
                        "seed {seed}: row {i} at {val} beyond its reach {}",
                        d.reach[i]
                    );
                    if d.reach[i] > 0.0 {
                        worst = worst.max(val.abs() / d.reach[i]);
                    }
                }
                let w = vertex();
                assert_eq!(w.len(), nw);
                x = lifted_step(&d, &x, &w);
            }
        }
        // Random extreme points are not the worst case of any row: no lower bound on `worst`
        // here (tightness is checked on the nominal trajectory below).
        assert!(worst > 0.0, "seed {seed}: no row moved");

        // The nominal set: the reach is the nominal trajectory's own peak on some row.
        let point = RegionalOptions {
            x0_radius: 0.0,
            prior_error: 0.0,
            w_bar: 0.0,
            w_box: None,
            ..o.clone()
        };
        let (_, d) = regional_detail(&res, Method::FISTA, 20, &point).unwrap();
        let mut v: Vec<f64> = o.x0_nominal.iter().chain(&o.x0_nominal).copied().collect();
        v.extend(vec![0.0; big_m * nw]);
        let mut x = apply(&d.start_map, &v);
        let mut peak = vec![0.0f64; d.rows.len()];
        for _ in 0..2000 {
            for (i, row) in d.rows.iter().enumerate() {
                let val: f64 = row.iter().zip(&x).map(|(a, b)| a * b).sum();
                peak[i] = peak[i].max(val.abs());
            }
            x = apply(&d.a, &x);
        }
        let attained = (0..peak.len())
            .filter(|&i| d.reach[i] > 0.0)
            .map(|i| peak[i] / d.reach[i])
            .fold(0.0f64, f64::max);
        // Attained on the stable plants; on marginal and unstable ones ρ_lin(20) is close to
        // 1, S (≤ 2000 steps) ends before the response has decayed and the metric's bound
        // beyond S can dominate (docs/theory.md, Theorem R: what S costs).
        if kind == 0 {
            assert!(
                attained > 1.0 - 1e-9,
                "seed {seed}: no row's reach is attained ({attained})"
            );
        }
        assert!(
            peak.iter()
                .zip(&d.reach)
                .all(|(p, q)| *p <= q * (1.0 + 1e-9) + 1e-15)
        );
    }
    assert!(
        checked.iter().all(|&c| c >= 2),
        "stable/marginal/unstable checked: {checked:?}"
    );
}

/// The witness (Theorem R, "the witness"): for the binding full-window row, the realization
/// the certificate describes — x₀ and the prior error along the row's gradients, every w at the
/// vertex of the noise box that pushes the row the same way — lies in the user's set and takes
/// the lifted linear loop's row to exactly the reported `attained` value at `attained_at`;
/// `attained` never exceeds the certified `reach`.
#[test]
fn the_witness_realization_attains_the_reported_value() {
    let mut checked = 0;
    for seed in 4000u64..4012 {
        let s = random_plant(seed, (seed % 3) as usize);
        let res = s.clone().resolve().unwrap();
        let mut o = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
        o.x0_radius = 0.004;
        o.prior_error = 0.02;
        let r = o.w_box.clone().unwrap();
        let Ok((c, d)) = regional_detail(&res, Method::FISTA, 20, &o) else {
            continue;
        };
        let l = c.radius_limit.clone().unwrap();
        assert!(l.attained <= l.reach * (1.0 + 1e-12), "{l:?}");
        let i = d.labels.iter().position(|x| *x == l.row).unwrap();
        let nx = s.plant.nx();
        let big_m = s.mhe.as_ref().unwrap().horizon();
        let steps = l.attained_at - big_m;
        // g = c𝔸^s𝕄 and c𝔸^k𝔹_w.
        let at = |m: &Mat<f64>, k: usize| {
            let mut v = d.rows[i].clone();
            for _ in 0..k {
                v = apply(&d.a.transpose().to_owned(), &v);
            }
            apply(&m.transpose().to_owned(), &v)
        };
        let g = at(&d.start_map, steps);
        let gxp: Vec<f64> = (0..nx).map(|j| g[j] + g[nx + j]).collect();
        let center: f64 = gxp.iter().zip(&o.x0_nominal).map(|(a, b)| a * b).sum();
        let sigma = if center >= 0.0 { 1.0 } else { -1.0 };
        let unit = |v: &[f64], rad: f64| -> Vec<f64> {
            let n = norm(v);
            v.iter()
                .map(|x| if n > 0.0 { sigma * rad * x / n } else { 0.0 })
                .collect()
        };
        let dx = unit(&gxp, o.x0_radius);
        let de = unit(&g[nx..2 * nx], o.prior_error);
        let vertex = |gw: &[f64]| -> Vec<f64> {
            gw.iter()
                .zip(&r)
                .map(|(a, ri)| if sigma * a >= 0.0 { *ri } else { -ri })
                .collect()
        };
        let mut v: Vec<f64> = (0..nx).map(|j| o.x0_nominal[j] + dx[j]).collect();
        v.extend((0..nx).map(|j| o.x0_nominal[j] + dx[j] + de[j]));
        let nw = r.len();
        for t in 0..big_m {
            v.extend(vertex(&g[2 * nx + t * nw..2 * nx + (t + 1) * nw]));
        }
        let mut x = apply(&d.start_map, &v);
        for j in 0..steps {
            let w = vertex(&at(&d.bw, steps - 1 - j));
            x = lifted_step(&d, &x, &w);
        }
        let value: f64 = d.rows[i].iter().zip(&x).map(|(a, b)| a * b).sum();
        assert!(
            (value.abs() - l.attained).abs() <= 1e-9 * l.attained.max(1e-300),
            "seed {seed}: the realization reaches {value}, the certificate says {}",
            l.attained
        );
        checked += 1;
    }
    assert!(checked >= 6, "only {checked} plants checked");
}

/// The first shipped K_reg (`scenarios/cart-pendulum-regional.toml`, docs/certificate-coverage.md):
/// at K = 13 of FISTA-Jacobi the regional certificate contains the scenario's own uncertainty,
/// and the real loop — the scenario's x₀ and prior, its uniform noise, 12 seeds — stays the
/// lifted linear loop for 150 steps (no projection of the MHE ever acts), as certified; at K = 8
/// the witness refutes any region.
#[test]
fn the_cart_pendulum_at_its_k_reg_stays_the_linear_loop() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/cart-pendulum-regional.toml"
    );
    let s = Scenario::from_file(path).unwrap();
    let res = s.clone().resolve().unwrap();
    let ro = RegionalOptions::from_scenario(&res, ControllerChoice::ExactMpc).unwrap();
    let method: Method = "fista-jacobi".parse().unwrap();
    let (c8, _) = regional_detail(&res, method, 8, &ro).unwrap();
    let w = c8.witness.expect("K = 8 is refuted by a witness");
    assert!(w.attained > w.bound && !c8.contains, "{w:?}");
    let k = 13;
    let (c, d) = regional_detail(&res, method, k, &ro).unwrap();
    assert!(
        c.contains && c.margin >= 1.0 && c.witness.is_none(),
        "{c:?}"
    );
    let big_m = s.mhe.as_ref().unwrap().horizon();
    let l = LiftedLayout {
        nx: s.plant.nx(),
        nu: s.plant.nu(),
        ny: s.plant.ny(),
        horizon: big_m,
        nz: s.plant.nx() + big_m * s.plant.nw(),
        n_controller: 0,
    };
    for seed in 0..12u64 {
        let mut o = options(&s, method, k);
        o.seed = seed;
        o.steps = big_m + 151;
        let mut cl = build(&s, &o).unwrap();
        for _ in 0..big_m {
            cl.step().unwrap();
        }
        let mut x = start_up_state(&cl, &s, &d);
        for step in 0..150 {
            let sim = lifted_state(&cl, l);
            let gap = norm(&x.iter().zip(&sim).map(|(p, q)| p - q).collect::<Vec<_>>());
            assert!(
                gap <= 1e-8 * norm(&sim).max(1e-12),
                "seed {seed} step {step}: the loop left the linear one ({gap:e})"
            );
            for (i, row) in d.rows.iter().enumerate() {
                let val: f64 = row.iter().zip(&sim).map(|(a, b)| a * b).sum();
                assert!(
                    val <= d.upper[i] && val >= d.lower[i],
                    "seed {seed}: row {i} active"
                );
            }
            let t = cl.t();
            cl.step().unwrap();
            let w = cl.trace().w(t).unwrap().to_vec();
            x = lifted_step(&d, &x, &w);
        }
    }
}

/// The K_c-iteration MPC in the regional model (its previous sequence U_{t−1} in the lifted
/// state, every inner iterate's projected point a row): on the cart-pendulum with FISTA-Jacobi
/// at K_e = 13 and K_c PG steps of the MPC, 𝔸 is the linear module's matrix, and the real loop —
/// start-up through 𝕄 from the cold-started MPC, then 150 steps, 6 seeds — equals the lifted
/// linear loop while no row is active; where the certificate contains the scenario's set no row
/// ever is.
#[test]
fn the_k_c_iteration_mpc_is_modelled_exactly() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/cart-pendulum-regional.toml"
    );
    let s = Scenario::from_file(path).unwrap();
    let res = s.clone().resolve().unwrap();
    let method: Method = "fista-jacobi".parse().unwrap();
    let k = 13;
    let mut contained = 0;
    for k_c in [20, 50, 160] {
        let controller = ControllerChoice::suboptimal(k_c, Method::PG).unwrap();
        let ro = RegionalOptions::from_scenario(&res, controller).unwrap();
        let (c, d) = regional_detail(&res, method, k, &ro).unwrap();
        let mut o = options(&s, method, k);
        o.controller = controller;
        let cl = build(&s, &o).unwrap();
        let lin = LiftedLoop::from_loop(&cl, &res, method, Par::Seq).unwrap();
        let a = lin.matrix(k, Par::Seq).unwrap();
        let gap = (&d.a - &a).norm_max();
        assert!(gap <= 1e-12 * a.norm_max().max(1.0), "K_c = {k_c}: {gap:e}");
        let l = lin.layout();
        assert_eq!(l.n_controller, 10, "N n_u of the cart-pendulum's MPC");
        contained += usize::from(c.contains);
        for seed in 0..6u64 {
            let mut o = o;
            o.seed = seed;
            o.steps = l.horizon + 151;
            let mut cl = build(&s, &o).unwrap();
            for _ in 0..l.horizon {
                cl.step().unwrap();
            }
            let mut x = start_up_state(&cl, &s, &d);
            for step in 0..150 {
                let sim = lifted_state(&cl, l);
                let active = d.rows.iter().enumerate().any(|(i, row)| {
                    let val: f64 = row.iter().zip(&sim).map(|(a, b)| a * b).sum();
                    val > d.upper[i] || val < d.lower[i]
                });
                assert!(
                    !(c.contains && active),
                    "K_c = {k_c}, seed {seed}, step {step}: a row is active inside the region"
                );
                if active {
                    break;
                }
                let gap = norm(&x.iter().zip(&sim).map(|(p, q)| p - q).collect::<Vec<_>>());
                assert!(
                    gap <= 1e-8 * norm(&sim).max(1e-12),
                    "K_c = {k_c}, seed {seed}, step {step}: the loop left the linear one ({gap:e})"
                );
                let t = cl.t();
                cl.step().unwrap();
                let w = cl.trace().w(t).unwrap().to_vec();
                x = lifted_step(&d, &x, &w);
            }
        }
    }
    assert!(
        contained >= 1,
        "no K_c of the test has a region containing the set"
    );
}
