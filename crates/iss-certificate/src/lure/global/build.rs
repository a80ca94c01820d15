//! Building the global loop's LMI matrices from a scenario (docs/theory.md §4).

use closed_loop::scenario::{LoopOptions, ResolvedScenario, ScenarioController, ScenarioLoop};
use faer::linalg::solvers::Solve;
use faer::{Mat, Par};
use lti_model::LtiSystem;
use mhe_core::WarmStart as MheWarmStart;
use qp_iter::{Certificate, IterationMap, MethodMap};

use super::{GlobalError, GlobalLoop, Optimum, add, mul};
use crate::linear::{LiftedLayout, LiftedLoop, LinearError};
use crate::lure::InnerRate;

/// The global loop of `options.method` on `resolved` (K does not matter: the LMI sees K only
/// through φ(K)).
///
/// Errors: as [`crate::linear::linear_stability`]; a method whose φ does not fit eq. (11);
/// the shifted warm start; a QP with general rows or without 0 in its box; the sub-optimal
/// MPC ([`GlobalError`]).
pub fn global_loop(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
) -> Result<GlobalLoop, GlobalError> {
    global_loop_with(resolved, options, true)
}

/// As [`global_loop`]; with `boxes = false` every bound of both QPs is dropped (the optimum is
/// the unconstrained one, σ₁ = σ₃ = 0 exactly): the linear loop of K_lin with only the
/// iteration error uncertain — a diagnostic and the object of the ρ_lin ≥ 1 refusal test.
pub fn global_loop_with(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    boxes: bool,
) -> Result<GlobalLoop, GlobalError> {
    build(resolved, options, boxes, boxes, false)
}

/// As [`global_loop`], keeping the MHE's box (`mhe_box`) and the controller's input box
/// (`mpc_box`) separately: a diagnostic of which optimum's description binds.
pub fn global_loop_boxes(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    mhe_box: bool,
    mpc_box: bool,
) -> Result<GlobalLoop, GlobalError> {
    build(resolved, options, mhe_box, mpc_box, false)
}

/// The sizes a search's estimate needs (`global_outcome::search_seconds`), with the norm
/// its φ holds in: what [`global_loop`] would build, read without forming a matrix.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct LoopSize {
    /// dim ζ of the LMI.
    pub n_zeta: usize,
    /// dim X.
    pub n_x: usize,
    /// Whether the controller's optimum is a channel (a finite input bound: the τ₃ grid).
    pub mpc_channel: bool,
    /// 1/D_i of the norm φ holds in (one φ* search per distinct one).
    pub d_inv: Vec<f64>,
}

/// The size of [`global_loop`]'s LMI for `options`, from the one-step loop's window and the
/// two QPs' boxes only (no lifted matrix, no inner-level rate): the estimate before the build
/// (the thermal rod M = 30 builds n_ζ ≈ 2 900 per method only to find the search beyond the
/// budget). Refuses what [`global_loop`] refuses before its lifted dynamics, in the same order,
/// and a box without 0 in its interior (`linear`'s probes); anything else [`global_loop`]
/// refuses is found when it runs.
pub fn loop_size(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
) -> Result<LoopSize, GlobalError> {
    let (quiet, opts) = one_step(resolved, options);
    let cl = quiet.build_loop(&opts).map_err(LinearError::from)?;
    let est = cl.estimator();
    if est.config().warm_start != MheWarmStart::Paper {
        return Err(GlobalError::WarmStart);
    }
    let m = est.config().horizon;
    let map = est.map(m).ok_or(LinearError::Internal(
        "the MHE has no map for window length M",
    ))?;
    let (fits, d_inv) = match map {
        MethodMap::Scaled(s) => (
            s.inner().certificate().fits_eq11,
            s.scaling().iter().map(|d| 1.0 / d).collect::<Vec<_>>(),
        ),
        other => (other.certificate().fits_eq11, vec![1.0; map.problem().n()]),
    };
    if !fits {
        return Err(GlobalError::Phi {
            method: options.method.name().to_string(),
        });
    }
    let mhe = Optimum::of(map.problem(), "mhe")?;
    let (mpc, _) = controller_optimum(&cl, &quiet)?;
    let zset = map.problem().zset();
    let (lo, up) = (zset.lower(), zset.upper());
    if let Some(index) = (0..lo.len()).find(|&i| !(lo[i] < 0.0 && up[i] > 0.0)) {
        return Err(LinearError::OriginNotInterior {
            problem: "MHE",
            index,
            lower: lo[index],
            upper: up[index],
        }
        .into());
    }
    let plant = cl.plant();
    let nz = map.problem().n();
    let lay = LiftedLayout {
        nx: plant.nx(),
        nu: plant.nu(),
        ny: plant.ny(),
        horizon: m,
        nz,
        n_controller: 0,
    };
    let nw = plant.nw1() + plant.nw2();
    let n_x = lay.dim();
    Ok(LoopSize {
        n_zeta: n_x + mhe.bounded.len() + nz + mpc.bounded.len() + nw,
        n_x,
        mpc_channel: !mpc.bounded.is_empty(),
        d_inv,
    })
}

/// The noise-free scenario and the loop options of one step with one iteration: the loop the
/// lifted dynamics are read from.
fn one_step(resolved: &ResolvedScenario, options: &LoopOptions) -> (ResolvedScenario, LoopOptions) {
    let mut quiet = resolved.clone();
    quiet.set_noise_scale(0.0);
    let mut opts = *options;
    opts.steps = 1;
    opts.iterations = qp_iter::Iterations::ONE;
    opts.exact_mhe_solve = false;
    (quiet, opts)
}

/// [`global_loop_boxes`]; with `rounding` two exogenous blocks follow w in ζ (issue 36,
/// `super::precision`): d_c (n_z) added to zᴷ and r_c (n_x) added to x̂ (and so to the
/// controller's input), both counted as exogenous inputs of the γ-channel.
pub(super) fn build(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
    mhe_box: bool,
    mpc_box: bool,
    rounding: bool,
) -> Result<GlobalLoop, GlobalError> {
    let (quiet, opts) = one_step(resolved, options);
    let cl = quiet.build_loop(&opts).map_err(LinearError::from)?;
    let est = cl.estimator();
    if est.config().warm_start != MheWarmStart::Paper {
        return Err(GlobalError::WarmStart);
    }
    let m = est.config().horizon;
    let map = est.map(m).ok_or(LinearError::Internal(
        "the MHE has no map for window length M",
    ))?;
    let name = options.method.name().to_string();
    let (cert, inner, d_inv) = method_certificate(map, &name);
    if !cert.fits_eq11 {
        return Err(GlobalError::Phi { method: name });
    }
    let mut mhe = Optimum::of(map.problem(), "mhe")?;
    let plant = cl.plant();
    let (mut mpc, law) = controller_optimum(&cl, &quiet)?;
    for (o, keep) in [(&mut mhe, mhe_box), (&mut mpc, mpc_box)] {
        if !keep {
            o.drop_bounds();
        }
    }
    let lifted = LiftedLoop::from_loop(&cl, &quiet, options.method, Par::Seq)?;
    let lay = lifted.layout();
    let (n, nz) = (lay.dim(), lay.nz);
    let (nx, nu) = (plant.nx(), plant.nu());
    let (a_loop, g_z) = lifted.split_at_iterate(Par::Seq);
    let s_theta = lifted.parameter_selection();
    let nw = plant.nw1() + plant.nw2();
    let nzb = mhe.bounded.len();
    let nub = mpc.bounded.len();
    let (o_z, o_d) = (n, n + nzb);
    let o_u = o_d + nz;
    // With `rounding`: r_h (n_x, adversarial) before w, d_c and r_c (exogenous) after it.
    let (n_r, n_extra) = if rounding { (nx, nz + nx) } else { (0, 0) };
    let o_w = o_u + nub + n_r;
    let nc = o_w + nw + n_extra;
    // θ_t as a map of ζ.
    let theta = Mat::from_fn(s_theta.nrows(), nc, |i, j| {
        if j < n { s_theta[(i, j)] } else { 0.0 }
    });
    let zstar = mhe.map(&theta, o_z)?;
    let sigma_mhe = mhe.vi_form(&zstar, &theta);
    let grad_mhe = mhe.bounded_gradient(&zstar, &theta);
    let mut zk = zstar.clone();
    for i in 0..nz {
        zk[(i, o_d + i)] += 1.0;
        if rounding {
            zk[(i, o_w + nw + i)] += 1.0; // d_c
        }
    }
    // x̂_t: the newest estimate row block of X⁺ (X_θ S_θ X + X_z zᴷ).
    let est = lay.estimates(lay.horizon - 1);
    let mut xhat = Mat::from_fn(
        nx,
        nc,
        |i, j| if j < n { a_loop[(est + i, j)] } else { 0.0 },
    );
    add(&mut xhat, &mul(g_z.as_ref().subrows(est, nx), zk.as_ref()));
    // x̂ computed = x̂(zᴷ) + r_h + r_c (its propagation's rounding).
    let r_cols = |i: usize| [o_w - nx + i, o_w + nw + nz + i];
    for i in (0..nx).filter(|_| rounding) {
        for c in r_cols(i) {
            xhat[(i, c)] += 1.0;
        }
    }
    // U* of the controller and u = E₀U* (the saturated LQR: U* = u).
    let ustar = mpc.map(&xhat, o_u)?;
    let sigma_mpc = (nub > 0).then(|| mpc.vi_form(&ustar, &xhat));
    let grad_mpc = mpc.bounded_gradient(&ustar, &xhat);
    let u = ustar.as_ref().subrows(0, nu).to_owned();
    let b_u = input_matrix(plant, &lay);
    // 𝒜, 𝒢_z include u = L x̂: take it out and put the channel's u in.
    let bl = mul(b_u.as_ref(), law.as_ref());
    let (a0, g0) = without_feedback(&a_loop, &g_z, &bl, est, nx);
    let mut x_plus = Mat::from_fn(n, nc, |i, j| if j < n { a0[(i, j)] } else { 0.0 });
    add(&mut x_plus, &mul(g0.as_ref(), zk.as_ref()));
    add(&mut x_plus, &mul(b_u.as_ref(), u.as_ref()));
    add_disturbance(&mut x_plus, plant, &lay, o_w);
    for i in (0..nx).filter(|_| rounding) {
        for c in r_cols(i) {
            x_plus[(est + i, c)] += 1.0;
        }
    }
    let (sig2_a, sig2_b) = sigma2_pieces(&d_inv[..nz], &zstar, lay.warm_start(), o_d);
    Ok(GlobalLoop {
        lifted,
        cert,
        inner,
        d_inv,
        n_x: n,
        n_v: nc - n,
        n_w: nw + n_extra,
        x_plus,
        sigma_mhe,
        sigma_mpc,
        sig2_a,
        sig2_b,
        xhat,
        mhe_bounded: nzb,
        o_z,
        o_u,
        grad_mhe,
        grad_mpc,
        zstar,
        d_col: o_d,
        extra_supply: None,
    })
}

/// φ in the norm of the map that runs: for Jacobi variants the inner map's bound on
/// y = D⁻¹z (no κ(D) factor). Returns (certificate, inner rate, 1/D_i).
fn method_certificate(map: &MethodMap, name: &str) -> (Certificate, Option<InnerRate>, Vec<f64>) {
    match map {
        MethodMap::Scaled(s) => (
            s.inner().certificate().clone(),
            crate::lure::rate_of_map(s.inner(), name).ok(),
            s.scaling().iter().map(|d| 1.0 / d).collect::<Vec<_>>(),
        ),
        other => (
            other.certificate().clone(),
            crate::lure::rate_of_map(other, name).ok(),
            vec![1.0; map.problem().n()],
        ),
    }
}

/// The controller's optimum (σ₃'s channel) and its unconstrained law L (u = L x̂).
fn controller_optimum(
    cl: &ScenarioLoop,
    quiet: &ResolvedScenario,
) -> Result<(Optimum, Mat<f64>), GlobalError> {
    let plant = cl.plant();
    let (nx, nu) = (plant.nx(), plant.nu());
    match cl.controller() {
        ScenarioController::Exact(_) => {
            let qp = quiet.mpc().map_err(LinearError::from)?.qp();
            let o = Optimum::of(qp, "mpc")?;
            // L = −E₀H⁻¹F.
            let llt = qp
                .h()
                .to_owned()
                .llt(faer::Side::Lower)
                .map_err(|_| GlobalError::Qp {
                    what: "mpc",
                    why: "the Hessian is not positive definite",
                })?;
            let sol = llt.solve(qp.f());
            let l = Mat::from_fn(nu, qp.n_theta(), |i, j| -sol[(i, j)]);
            Ok((o, l))
        }
        ScenarioController::SaturatedLqr(c) => {
            let k = c.gain();
            let set = c.input_set();
            let o = Optimum::of_box(
                Mat::<f64>::identity(nu, nu).as_ref(),
                k.as_ref(),
                set.lower(),
                set.upper(),
                "mpc",
            )?;
            let l = Mat::from_fn(nu, nx, |i, j| -k[(i, j)]);
            Ok((o, l))
        }
        ScenarioController::Suboptimal(_) => Err(GlobalError::Controller),
    }
}

/// B_u: u_t enters x_{t+1} (B) and the newest u-window entry.
fn input_matrix(plant: &LtiSystem, lay: &LiftedLayout) -> Mat<f64> {
    let (nx, nu) = (plant.nx(), plant.nu());
    let b = plant.b();
    let mut b_u = Mat::<f64>::zeros(lay.dim(), nu);
    for i in 0..nx {
        for j in 0..nu {
            b_u[(i, j)] = b[(i, j)];
        }
    }
    let u_new = lay.u_window(lay.horizon - 1);
    for j in 0..nu {
        b_u[(u_new + j, j)] = 1.0;
    }
    b_u
}

/// 𝒜 and 𝒢_z with the feedback u = L x̂ taken out (`bl` = B_u L, x̂ at row `est`).
fn without_feedback(
    a_loop: &Mat<f64>,
    g_z: &Mat<f64>,
    bl: &Mat<f64>,
    est: usize,
    nx: usize,
) -> (Mat<f64>, Mat<f64>) {
    let mut a0 = a_loop.clone();
    let sub = mul(bl.as_ref(), a_loop.as_ref().subrows(est, nx));
    for j in 0..a0.ncols() {
        for i in 0..a0.nrows() {
            a0[(i, j)] -= sub[(i, j)];
        }
    }
    let mut g0 = g_z.clone();
    let sub = mul(bl.as_ref(), g_z.as_ref().subrows(est, nx));
    for j in 0..g0.ncols() {
        for i in 0..g0.nrows() {
            g0[(i, j)] -= sub[(i, j)];
        }
    }
    (a0, g0)
}

/// The disturbance w = (w₁, w₂) at column `o_w`: E w₁ into x_{t+1}, F w₂ into the newest
/// y-window entry.
fn add_disturbance(x_plus: &mut Mat<f64>, plant: &LtiSystem, lay: &LiftedLayout, o_w: usize) {
    let (nx, nw1, nw2) = (plant.nx(), plant.nw1(), plant.nw2());
    let (e, f) = (plant.e(), plant.f());
    for i in 0..nx {
        for j in 0..nw1 {
            x_plus[(i, o_w + j)] += e[(i, j)];
        }
    }
    let y_new = lay.y_window(lay.horizon - 1);
    for i in 0..lay.ny {
        for j in 0..nw2 {
            x_plus[(y_new + i, o_w + nw1 + j)] += f[(i, j)];
        }
    }
}

/// σ₂ pieces: a = D⁻¹(z⁰ − z*), z⁰ = the warm-start block of X at column `ws`; b = D⁻¹d,
/// d at column `o_d`.
fn sigma2_pieces(d_inv: &[f64], zstar: &Mat<f64>, ws: usize, o_d: usize) -> (Mat<f64>, Mat<f64>) {
    let (nz, nc) = (d_inv.len(), zstar.ncols());
    let sig2_a = Mat::from_fn(nz, nc, |i, j| {
        let w = if j == ws + i { 1.0 } else { 0.0 };
        d_inv[i] * (w - zstar[(i, j)])
    });
    let sig2_b = Mat::from_fn(nz, nc, |i, j| if j == o_d + i { d_inv[i] } else { 0.0 });
    (sig2_a, sig2_b)
}
