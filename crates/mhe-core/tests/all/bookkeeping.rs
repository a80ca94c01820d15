//! (c) Window bookkeeping at t = 0, 1, M−1, M, M+1 (and beyond) against a direct
//! construction from the full history: θ_t, the prior from the ring buffer, the warm start
//! Σ_t, x̂_{t|t} by propagation; idempotence of `estimate`, implicit estimate in `push`,
//! `reset`, and the shifted warm start.

use mhe_core::{MheEstimator, WarmStart};
use qp_iter::IterationMap;
use qp_iter::fista::Fista;

use crate::common::{Fixture, case_study, random_fixture, simulate};

/// x̂ propagated through the model from the record's x̂₀ and ŵ (independent of the crate).
fn propagate(f: &Fixture, x0: &[f64], ws: &[f64], us: &[Vec<f64>]) -> Vec<f64> {
    let (nx, ny, nw) = (f.sys.nx(), f.sys.ny(), f.sys.nw());
    let mut x = x0.to_vec();
    for (j, u) in us.iter().enumerate() {
        let mut xn = vec![0.0; nx];
        let mut y = vec![0.0; ny];
        f.sys
            .step(&x, u, &ws[j * nw..(j + 1) * nw], &mut xn, &mut y);
        x = xn;
    }
    x
}

/// Σ_t applied to zᴷ_{t−1}: z⁰_0 = x̄₀, while the window grows the previous variables with one
/// zero stage appended, then Σ = I (`Paper`) or the shift by one stage (`Shifted`).
fn check_warm_start(
    f: &Fixture,
    t: usize,
    z0: &[f64],
    prev_z: &[f64],
    prev_theta: &[f64],
    us: &[Vec<f64>],
) {
    let big_m = f.config.horizon;
    let (nx, nw) = (f.sys.nx(), f.sys.nw());
    if t == 0 {
        assert_eq!(z0, &f.prior[..], "z⁰_0 = x̄₀");
    } else if t <= big_m {
        assert_eq!(
            &z0[..prev_z.len()],
            prev_z,
            "t = {t}: previous variables kept"
        );
        assert!(
            z0[prev_z.len()..].iter().all(|v| *v == 0.0),
            "t = {t}: one zero stage appended"
        );
        assert_eq!(z0.len() - prev_z.len(), nw);
    } else {
        match f.config.warm_start {
            WarmStart::Paper => assert_eq!(z0, prev_z, "t = {t}: Σ = I"),
            WarmStart::Shifted => {
                // Previous window started at t − 1 − M with input u_{t−1−M} = prev θ's u₀.
                let u_old = &us[t - 1 - big_m];
                assert_eq!(&prev_theta[nx..nx + f.sys.nu()], &u_old[..]);
                let x_shift = propagate(
                    f,
                    &prev_z[..nx],
                    &prev_z[nx..nx + nw],
                    std::slice::from_ref(u_old),
                );
                for i in 0..nx {
                    assert!((z0[i] - x_shift[i]).abs() < 1e-12);
                }
                assert_eq!(&z0[nx..nx + (big_m - 1) * nw], &prev_z[nx + nw..]);
                assert!(z0[nx + (big_m - 1) * nw..].iter().all(|v| *v == 0.0));
            }
        }
    }
}

/// Skipping the explicit estimates (push runs them) and `reset` reproduce the trajectory
/// `estimates` of the run on (`us`, `ys`).
fn check_push_and_reset(f: &Fixture, us: &[Vec<f64>], ys: &[Vec<f64>], estimates: &[Vec<f64>]) {
    let steps = estimates.len();
    let mut lazy = MheEstimator::new(&f.sys, &f.sets, &f.config, &f.prior, |qp| {
        Ok(Fista::new(qp))
    })
    .unwrap();
    for t in 0..steps {
        lazy.push(&us[t], &ys[t]).unwrap();
        assert_eq!(
            lazy.last_record().x_hat(),
            &estimates[t][..],
            "implicit estimate at t = {t}"
        );
    }
    // reset reproduces the run.
    lazy.reset(&f.prior).unwrap();
    assert_eq!(lazy.t(), 0);
    for t in 0..steps {
        assert_eq!(
            lazy.estimate().unwrap(),
            &estimates[t][..],
            "after reset, t = {t}"
        );
        lazy.push(&us[t], &ys[t]).unwrap();
    }
}

/// One run of `steps` steps (data from `seed`), each step checked against the direct
/// construction from the full history.
fn run_bookkeeping(f: &Fixture, steps: usize, seed: u64) {
    let big_m = f.config.horizon;
    let (nx, nw) = (f.sys.nx(), f.sys.nw());
    let (us, ys, _) = simulate(f, steps, seed);
    let mut mhe = MheEstimator::new(&f.sys, &f.sets, &f.config, &f.prior, |qp| {
        Ok(Fista::new(qp))
    })
    .unwrap();
    let mut estimates: Vec<Vec<f64>> = Vec::new();
    let mut prev_z: Vec<f64> = Vec::new();
    let mut prev_theta: Vec<f64> = Vec::new();
    for t in 0..steps {
        let m = t.min(big_m);
        assert_eq!((mhe.t(), mhe.window_len()), (t, m));
        assert!(mhe.iterate().is_none());
        // Σ_t applied to zᴷ_{t−1}.
        let z0 = mhe.warm_start_point().to_vec();
        assert_eq!(z0.len(), nx + m * nw);
        check_warm_start(f, t, &z0, &prev_z, &prev_theta, &us);
        let x_hat = mhe.estimate().unwrap().to_vec();
        let again = mhe.estimate().unwrap().to_vec();
        assert_eq!(x_hat, again, "estimate is idempotent at fixed t");
        let rec = mhe.last_record().clone();
        assert_eq!(
            (rec.t, rec.window, rec.iterations),
            (t, m, f.config.iterations.get())
        );

        // The window built directly from the full history.
        let prior: &[f64] = if t <= big_m {
            &f.prior
        } else {
            &estimates[t - big_m]
        };
        assert_eq!(rec.prior(), prior, "t = {t}: prior");
        let u_win: Vec<f64> = us[t - m..t].iter().flatten().copied().collect();
        let y_win: Vec<f64> = ys[t - m..t].iter().flatten().copied().collect();
        assert_eq!(rec.u_flat(), &u_win[..], "t = {t}: u window");
        assert_eq!(rec.y_flat(), &y_win[..], "t = {t}: y window");
        for j in 0..m {
            assert_eq!(rec.y(j).unwrap(), &ys[t - m + j][..]);
        }
        assert!(rec.y(m).is_none());
        let theta: Vec<f64> = prior.iter().chain(&u_win).chain(&y_win).copied().collect();
        assert_eq!(mhe.theta(), &theta[..], "t = {t}: θ");

        // x̂_{t|t} is the window's last state.
        let x_prop = propagate(f, rec.x_start_k(), rec.w_k_flat(), &us[t - m..t]);
        for i in 0..nx {
            assert!(
                (x_prop[i] - x_hat[i]).abs() <= 1e-10 * (1.0 + x_hat[i].abs()),
                "t = {t}"
            );
        }
        assert_eq!(rec.x_hat(), &x_hat[..]);
        let z: Vec<f64> = rec
            .x_start_k()
            .iter()
            .chain(rec.w_k_flat())
            .copied()
            .collect();
        assert_eq!(mhe.iterate().unwrap(), &z[..]);
        // Cost recorded = V_MHE through the paper's H_t form.
        let win = mhe.problem().window(m).unwrap();
        let v = win.cost(&z, &theta);
        assert!(
            (rec.cost_k - v).abs() <= 1e-9 * v.abs().max(1.0),
            "t = {t}: {} vs {v}",
            rec.cost_k
        );
        assert_eq!(rec.violation, 0.0, "FISTA iterates are projections");

        estimates.push(x_hat);
        prev_z = z;
        prev_theta = theta;
        mhe.push(&us[t], &ys[t]).unwrap();
    }

    check_push_and_reset(f, &us, &ys, &estimates);
}

#[test]
fn case_study_window_bookkeeping() {
    // M = 3: t = 0..8 covers 0, 1, M−1, M, M+1 and two more shifts.
    let f = case_study(3, 4, false);
    run_bookkeeping(&f, 9, 7);
}

#[test]
fn case_study_shifted_warm_start_bookkeeping() {
    let mut f = case_study(3, 4, false);
    f.config.warm_start = WarmStart::Shifted;
    run_bookkeeping(&f, 9, 8);
}

#[test]
fn random_system_window_bookkeeping() {
    for seed in 0..4 {
        let horizon = 1 + seed as usize;
        let mut f = random_fixture(200 + seed, horizon, 3, false);
        run_bookkeeping(&f, 2 * horizon + 4, seed);
        f.config.warm_start = WarmStart::Shifted;
        run_bookkeeping(&f, 2 * horizon + 4, seed);
    }
}

#[test]
fn horizon_one_and_maps_per_window() {
    let f = random_fixture(300, 1, 2, false);
    let mhe = MheEstimator::new(&f.sys, &f.sets, &f.config, &f.prior, |qp| {
        Ok(Fista::new(qp))
    })
    .unwrap();
    assert_eq!(mhe.maps().len(), 2);
    for (m, map) in mhe.maps().iter().enumerate() {
        assert_eq!(map.problem().n(), f.sys.nx() + m * f.sys.nw());
    }
}

#[test]
fn record_serialises_nested_stages() {
    let f = case_study(2, 3, true);
    let (us, ys, _) = simulate(&f, 4, 2);
    let mut mhe = MheEstimator::new(&f.sys, &f.sets, &f.config, &f.prior, |qp| {
        Ok(Fista::new(qp))
    })
    .unwrap();
    for t in 0..3 {
        mhe.estimate().unwrap();
        mhe.push(&us[t], &ys[t]).unwrap();
    }
    mhe.estimate().unwrap();
    let rec = mhe.last_record();
    let v = serde_json::to_value(rec).unwrap();
    assert_eq!(v["t"], 3);
    assert_eq!(v["window"], 2);
    assert_eq!(v["u"].as_array().unwrap().len(), 2);
    assert_eq!(v["u"][1].as_array().unwrap().len(), 2);
    assert_eq!(v["y"][0][0].as_f64().unwrap(), ys[1][0]);
    assert_eq!(v["w_k"].as_array().unwrap().len(), 2);
    assert_eq!(v["w_k"][0].as_array().unwrap().len(), 5);
    assert_eq!(
        v["w_exact"][1][4].as_f64().unwrap(),
        rec.w_exact(1).unwrap()[4]
    );
    assert_eq!(v["status"], "completed");
    assert!(v["epsilon"].as_f64().unwrap() >= 0.0);
    // ŵ² at stage j (the Fig. 2(c) quantity).
    assert_eq!(rec.w2_k(1).unwrap(), &rec.w_k(1).unwrap()[4..]);

    // Without the exact solve the exact fields are null.
    let mut cfg = f.config.clone();
    cfg.exact_solve = false;
    let mut fast =
        MheEstimator::new(&f.sys, &f.sets, &cfg, &f.prior, |qp| Ok(Fista::new(qp))).unwrap();
    fast.estimate().unwrap();
    let v = serde_json::to_value(fast.last_record()).unwrap();
    assert!(v["w_exact"].is_null() && v["epsilon"].is_null() && v["x_hat_exact"].is_null());
    assert_eq!(v["u"].as_array().unwrap().len(), 0);
}

#[test]
fn settings_compute_p_from_the_lmi() {
    let raw: mhe_core::RawMhe =
        lti_model::spec::format::parse("horizon = 5\neta = 0.8\niterations = 7\n").unwrap();
    let f = case_study(5, 7, false);
    let plant = lti_model::presets::case_study_plant();
    let settings = mhe_core::MheSettings::from_raw(&raw, &plant).unwrap();
    let cfg = settings.config(&plant, false).unwrap();
    assert_eq!((cfg.horizon, cfg.iterations.get(), cfg.eta), (5, 7, 0.8));
    for i in 0..4 {
        for j in 0..4 {
            assert!((cfg.p[(i, j)] - f.config.p[(i, j)]).abs() < 1e-12 * f.config.p.norm_max());
        }
    }
    let prior = [0.0; 4];
    let mut mhe =
        MheEstimator::new(&plant, &f.sets, &cfg, &prior, |qp| Ok(Fista::new(qp))).unwrap();
    assert_eq!(mhe.estimate().unwrap(), &prior[..]);
    // Keys are named from the section: a missing K names `mhe.iterations`.
    let raw: mhe_core::RawMhe = lti_model::spec::format::parse("horizon = 5\neta = 0.8\n").unwrap();
    match mhe_core::MheSettings::from_raw(&raw, &plant) {
        Err(lti_model::ModelError::Scenario { key, .. }) => assert_eq!(key, "mhe.iterations"),
        other => panic!("{other:?}"),
    }
}
