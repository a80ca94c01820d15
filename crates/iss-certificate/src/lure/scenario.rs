//! The Lur'e loop of a shipped scenario: the lifted closed loop of `linear::lifted` (t ≥ M)
//! with the MHE's K inner iterations kept as iterations whose box projections are
//! slope-[0, 1] channels (docs/theory.md, "One certificate for the whole loop", §3).
//!
//! For the projected-gradient family (`pg`, `pg-jacobi`) one inner step is
//! zᵏ⁺¹ = Π_Z(S zᵏ + S_θ θ) with [S | S_θ] the probed step of `linear::iteration` (the map
//! before its projection: where Z is inactive, Π_Z is the identity). Each coordinate with a
//! finite bound is a channel Δ_i = Π(v)_i = s_i·v_i, s_i ∈ [0, 1] (0 is interior to Z, which
//! `linearise` checks); a coordinate without bounds passes linearly. The loop state X and
//! the split X⁺ = 𝒜X + 𝒢_z zᴷ + ℬw are those of [`LiftedLoop::split_at_iterate`], so with
//! every clamp the identity the loop's lifted matrix is K_lin's 𝔸(K) (tested).
//!
//! Not covered (typed errors): FISTA and ADMM (their restart step and resolvent put a clamp
//! inside the start map or between two linear maps: a different channel layout), and a
//! controller with constraints that can activate (saturated LQR, the sub-optimal MPC, an
//! exact MPC with a finite input bound): their clamps are not channels of this loop.

use closed_loop::scenario::{LoopOptions, ResolvedScenario, ScenarioController, ScenarioLoop};
use faer::{Mat, MatRef, Par};
use qp_iter::{IterationMap, MethodMap};

use super::loop_level::{LureLoop, Matrix};
use crate::linear::{LiftedLayout, LiftedLoop, LinearError, linearise};

/// Why a scenario's loop has no Lur'e form here.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScenarioLureError {
    /// Building the loop or its linear pieces failed.
    #[error(transparent)]
    Linear(#[from] LinearError),
    /// The MHE method's clamps do not sit where this module models them.
    #[error(
        "mhe.method = {method}: the loop certificate models the projected-gradient family \
         (pg, pg-jacobi) only; choose mhe.method = \"pg\" or \"pg-jacobi\""
    )]
    Method {
        /// The method's name.
        method: String,
    },
    /// The controller has constraints that can activate.
    #[error(
        "the controller has constraints that can activate ({why}): the loop certificate \
         models an unconstrained (linear) controller; omit sets.input or use the exact MPC"
    )]
    Controller {
        /// What.
        why: &'static str,
    },
    /// A slope pattern of the wrong length or outside [0, 1].
    #[error("slope pattern: {len} slopes for {channels} channels, each must lie in [0, 1]")]
    Slopes {
        /// The pattern's length.
        len: usize,
        /// n_c.
        channels: usize,
    },
}

/// The Lur'e loop of one (scenario, MHE method) pair with its provenance.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct ScenarioLure {
    /// The loop (n_X = dim of the lifted state, n_ξ = n_z, one channel per bounded
    /// coordinate of the MHE's z, n_w = n_w¹ + n_w²).
    pub lure: LureLoop,
    /// The lifted loop it was built from (K_lin's).
    pub lifted: LiftedLoop,
}

fn to_matrix(m: MatRef<'_, f64>) -> Matrix {
    let (r, c) = (m.nrows(), m.ncols());
    let mut data = Vec::with_capacity(r * c);
    for i in 0..r {
        for j in 0..c {
            data.push(m[(i, j)]);
        }
    }
    Matrix::new(r, c, data)
}

fn mul(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(a.nrows(), b.ncols());
    faer::linalg::matmul::matmul(out.as_mut(), faer::Accum::Replace, a, b, 1.0, Par::Seq);
    out
}

/// The Lur'e loop of `options.method` on `resolved` (its controller; K, seed, T and the
/// exact-solve flag do not matter: K is the certificate's). The noise is irrelevant to the
/// matrices and set to zero for the build, as for K_lin.
///
/// Errors: as [`crate::linear::linear_stability`]; a method outside the PG family or a
/// controller with constraints ([`ScenarioLureError`]).
pub fn scenario_lure(
    resolved: &ResolvedScenario,
    options: &LoopOptions,
) -> Result<ScenarioLure, ScenarioLureError> {
    let mut quiet = resolved.clone();
    quiet.set_noise_scale(0.0);
    let mut opts = *options;
    opts.steps = 1;
    opts.iterations = qp_iter::Iterations::ONE;
    opts.exact_mhe_solve = false;
    let cl = quiet.build_loop(&opts).map_err(LinearError::from)?;
    let est = cl.estimator();
    let m = est.config().horizon;
    let map = est.map(m).ok_or(LinearError::Internal(
        "the MHE has no map for window length M",
    ))?;
    let is_pg = match map {
        MethodMap::Pg(_) => true,
        MethodMap::Scaled(s) => matches!(s.inner(), MethodMap::Pg(_)),
        _ => false,
    };
    if !is_pg {
        return Err(ScenarioLureError::Method {
            method: options.method.name().to_string(),
        });
    }
    check_controller(&cl, &quiet)?;
    let lifted = LiftedLoop::from_loop(&cl, &quiet, options.method, Par::Seq)?;
    let lin = linearise(map, "MHE")?;
    let lay = lifted.layout();
    let (n, nz) = (lay.dim(), lay.nz);
    let nxi = lin.lift_dim();
    if lin.start_steps != 0 || nxi != nz || lin.n != nz {
        return Err(LinearError::Internal("a PG map whose state is not z").into());
    }
    // Channels: the coordinates of z with a finite bound (in the map's own coordinates;
    // Jacobi scaling keeps finiteness).
    let set = map.problem().zset();
    let clamped: Vec<usize> = (0..nz)
        .filter(|&i| set.lower()[i].is_finite() || set.upper()[i].is_finite())
        .collect();
    let nc = clamped.len();
    let s_theta = lifted.parameter_selection();
    let nt = s_theta.nrows();
    // ξ⁰ = Ξ_z z⁰ + Ξ_θ θ, z⁰ read from X.
    let start = lin.start.as_ref();
    let mut s0 = mul(start.subcols(nz, nt), s_theta.as_ref());
    for i in 0..nxi {
        for j in 0..nz {
            s0[(i, lay.warm_start() + j)] += start[(i, j)];
        }
    }
    // v = S ξ + S_θ θ.
    let step = lin.step.as_ref();
    let s = step.subcols(0, nxi);
    let v_x = mul(step.subcols(nxi, nt), s_theta.as_ref());
    let is_clamped = {
        let mut f = vec![false; nxi];
        for &i in &clamped {
            f[i] = true;
        }
        f
    };
    let a_xi = Mat::from_fn(nxi, nxi, |i, j| if is_clamped[i] { 0.0 } else { s[(i, j)] });
    let e_x = Mat::from_fn(nxi, n, |i, j| if is_clamped[i] { 0.0 } else { v_x[(i, j)] });
    let b_delta = Mat::from_fn(nxi, nc, |i, c| if clamped[c] == i { 1.0 } else { 0.0 });
    let c = Mat::from_fn(nc, nxi, |r, j| s[(clamped[r], j)]);
    let d_x = Mat::from_fn(nc, n, |r, j| v_x[(clamped[r], j)]);
    // X⁺ = 𝒜X + 𝒢_z R ξᴷ + ℬw.
    let (a_loop, g_z) = lifted.split_at_iterate(Par::Seq);
    let g_loop = mul(g_z.as_ref(), lin.readout.as_ref());
    let b_loop = disturbance_input(&cl, &lay);
    let nw = b_loop.ncols();
    let lure = LureLoop {
        s0: to_matrix(s0.as_ref()),
        s_w: Matrix::zeros(nxi, nw),
        a_xi: to_matrix(a_xi.as_ref()),
        b_delta: to_matrix(b_delta.as_ref()),
        e_x: to_matrix(e_x.as_ref()),
        e_w: Matrix::zeros(nxi, nw),
        c: to_matrix(c.as_ref()),
        d_x: to_matrix(d_x.as_ref()),
        d_w: Matrix::zeros(nc, nw),
        a_loop: to_matrix(a_loop.as_ref()),
        g_loop: to_matrix(g_loop.as_ref()),
        b_loop: to_matrix(b_loop.as_ref()),
    };
    Ok(ScenarioLure { lure, lifted })
}

/// The controller premise of [`scenario_lure`]: a linear controller (the exact MPC with no
/// finite input bound); every clamp of the loop is then one of the MHE's.
fn check_controller(cl: &ScenarioLoop, quiet: &ResolvedScenario) -> Result<(), ScenarioLureError> {
    match cl.controller() {
        ScenarioController::Exact(_) => {
            let qp = quiet.mpc().map_err(LinearError::from)?.qp();
            let set = qp.zset();
            let bounded = set
                .lower()
                .iter()
                .zip(set.upper())
                .any(|(l, u)| l.is_finite() || u.is_finite());
            if bounded {
                return Err(ScenarioLureError::Controller {
                    why: "the exact MPC has a finite input bound",
                });
            }
        }
        ScenarioController::SaturatedLqr(_) => {
            return Err(ScenarioLureError::Controller {
                why: "the saturated LQR",
            });
        }
        ScenarioController::Suboptimal(_) => {
            return Err(ScenarioLureError::Controller {
                why: "the sub-optimal MPC's K_c clamped iterations",
            });
        }
    }
    Ok(())
}

/// ℬ: w¹ enters x through E, w² the newest output of the window through F.
fn disturbance_input(cl: &ScenarioLoop, lay: &LiftedLayout) -> Mat<f64> {
    let n = lay.dim();
    let plant = cl.plant();
    let (nw1, nw2) = (plant.nw1(), plant.nw2());
    let mut b_loop = Mat::<f64>::zeros(n, nw1 + nw2);
    let (e, f) = (plant.e(), plant.f());
    for i in 0..lay.nx {
        for j in 0..nw1 {
            b_loop[(i, j)] = e[(i, j)];
        }
    }
    let y_new = lay.y_window(lay.horizon - 1);
    for i in 0..lay.ny {
        for j in 0..nw2 {
            b_loop[(y_new + i, nw1 + j)] = f[(i, j)];
        }
    }
    b_loop
}

/// ρ(𝔸_s(K)): the spectral radius of the loop with every channel frozen at slope s_c
/// (Δ_c = s_c·v_c in every iteration of every sample) and w = 0.
///
/// A frozen slope is an admissible clamp sequence of Theorem L2 (every |s_c| ≤ 1 in the
/// sector [0, 1]), so a certificate with rate ρ at K gives ρ(𝔸_s(K)) ≤ ρ < 1 for every s:
/// ρ(𝔸_s(K)) ≥ 1 refutes every loop certificate at K, whatever the multipliers. s = 𝟙 is the
/// linear loop (ρ_lin(K)); s = 0 is every bounded coordinate held at 0.
///
/// Errors: a pattern of the wrong length or outside [0, 1]; the eigenvalue solver failing.
pub fn frozen_slope_radius(
    lp: &LureLoop,
    slopes: &[f64],
    k: usize,
) -> Result<f64, ScenarioLureError> {
    let (nxi, nc) = (lp.n_xi(), lp.n_c());
    if slopes.len() != nc || !slopes.iter().all(|s| (0.0..=1.0).contains(s)) {
        return Err(ScenarioLureError::Slopes {
            len: slopes.len(),
            channels: nc,
        });
    }
    let mut frozen = lp.clone();
    for i in 0..nxi {
        for (c, s) in slopes.iter().enumerate() {
            frozen.b_delta.data[i * nc + c] *= s;
        }
    }
    let a = frozen.lifted_linear(k);
    let m = Mat::from_fn(a.rows, a.cols, |i, j| a.at(i, j));
    Ok(crate::linear::spectral_radius_dense(m.as_ref(), Par::Seq)?)
}

/// The first frozen-slope pattern of `patterns` that refutes every loop certificate at K
/// (ρ(𝔸_s(K)) ≥ 1 + 10⁻⁹, above the eigenvalue solver's rounding), with its ρ; None if all
/// are stable (a necessary condition only: it does not certify).
pub fn refuted_at(
    lp: &LureLoop,
    k: usize,
    patterns: &[Vec<f64>],
) -> Result<Option<(usize, f64)>, ScenarioLureError> {
    for (i, s) in patterns.iter().enumerate() {
        let rho = frozen_slope_radius(lp, s, k)?;
        if rho >= 1.0 + 1e-9 {
            return Ok(Some((i, rho)));
        }
    }
    Ok(None)
}
