//! The lifted loop with the disturbance, (𝔸, 𝔹_w), its constraint rows over X and the
//! start-up map X_M = 𝕄υ with the start-up rows over υ (module docs of `model.rs`).

use faer::Mat;

use super::model::{Pieces, RowKind, Rows, control, mhe_step, shifted_warm_start};
use crate::linear::{LiftedLayout, LinearError};

/// The loop at one K in the two column spaces.
#[derive(Debug, Clone)]
pub(crate) struct RegionalModel {
    pub layout: LiftedLayout,
    /// 𝔸(K): X_{t+1} = 𝔸X_t + 𝔹_w w_t for t ≥ M while no row is active.
    pub a: Mat<f64>,
    /// 𝔹_w (dim X × n_w): w¹ through E into x, w² through F into the newest y.
    pub bw: Mat<f64>,
    /// Rows over X_t (t ≥ M).
    pub rows: Rows,
    /// x_t = x_read·X_t.
    pub x_read: Mat<f64>,
    /// e_t = x̂_t − x_t = e_read·X_t.
    pub e_read: Mat<f64>,
    /// X_M = 𝕄υ, υ = (x₀, x̄₀, w₀, …, w_{M−1}).
    pub start_map: Mat<f64>,
    /// Rows over υ for t < M.
    pub startup_rows: Rows,
    /// n_x, n_w.
    pub nx: usize,
    pub nw: usize,
}

fn set_block(dst: &mut Mat<f64>, r0: usize, src: &Mat<f64>) {
    for j in 0..src.ncols() {
        for i in 0..src.nrows() {
            dst[(r0 + i, j)] = src[(i, j)];
        }
    }
}

fn rows_of(m: &Mat<f64>, r0: usize, n: usize) -> Mat<f64> {
    m.as_ref().subrows(r0, n).to_owned()
}

/// The loop for t ≥ M on X: 𝔸, 𝔹_w, the readouts, and (with `rows`) every row over X.
struct FullWindow {
    layout: LiftedLayout,
    a: Mat<f64>,
    bw: Mat<f64>,
    x_read: Mat<f64>,
    e_read: Mat<f64>,
}

fn full_window(
    p: &Pieces,
    k: usize,
    mut rows: Option<&mut Rows>,
) -> Result<FullWindow, LinearError> {
    let big_m = p.windows.len() - 1;
    let full = &p.windows[big_m];
    let w = full.layout;
    let d = w.dims;
    let (nx, nu, ny, nw, nw1) = (d.nx, d.nu, d.ny, d.nw(), d.nw1);
    let layout = LiftedLayout {
        nx,
        nu,
        ny,
        horizon: big_m,
        nz: w.nz(),
        n_controller: p.law.n_controller(),
    };
    let n = layout.dim();
    let eye = Mat::<f64>::identity(n, n);
    let z0 = rows_of(&eye, layout.warm_start(), w.nz());
    let mut theta = Mat::<f64>::zeros(w.n_theta(), n);
    for i in 0..nx {
        theta[(i, layout.estimates(0) + i)] = 1.0;
    }
    for j in 0..big_m {
        for i in 0..nu {
            theta[(w.u_offset(j) + i, layout.u_window(j) + i)] = 1.0;
        }
        for i in 0..ny {
            theta[(w.y_offset(j) + i, layout.y_window(j) + i)] = 1.0;
        }
    }
    let (zk, xh) = mhe_step(
        full,
        k,
        z0.as_ref(),
        theta.as_ref(),
        None,
        rows.as_deref_mut(),
    )?;
    let nc = layout.n_controller;
    let prev = (nc > 0).then(|| rows_of(&eye, layout.controller(), nc));
    let (u, seq) = control(
        &p.law,
        nu,
        xh.as_ref(),
        prev.as_ref().map(|m| m.as_ref()),
        None,
        rows,
    )?;
    let x_read = rows_of(&eye, layout.x(), nx);
    let mut a = Mat::<f64>::zeros(n, n);
    set_block(&mut a, layout.x(), &(&p.a * &x_read + &p.b * &u));
    for j in 0..big_m - 1 {
        for i in 0..nu {
            a[(layout.u_window(j) + i, layout.u_window(j + 1) + i)] = 1.0;
        }
        for i in 0..ny {
            a[(layout.y_window(j) + i, layout.y_window(j + 1) + i)] = 1.0;
        }
        for i in 0..nx {
            a[(layout.estimates(j) + i, layout.estimates(j + 1) + i)] = 1.0;
        }
    }
    set_block(&mut a, layout.u_window(big_m - 1), &u);
    set_block(&mut a, layout.y_window(big_m - 1), &(&p.c * &x_read));
    set_block(&mut a, layout.estimates(big_m - 1), &xh);
    let z_next = if p.shifted {
        let (wz, wth) = shifted_warm_start(p, w);
        &wz * &zk + &wth * &theta
    } else {
        zk.clone()
    };
    set_block(&mut a, layout.warm_start(), &z_next);
    if let Some(seq) = &seq {
        set_block(&mut a, layout.controller(), seq);
    }
    let mut bw = Mat::<f64>::zeros(n, nw);
    for i in 0..nx {
        for j in 0..nw1 {
            bw[(layout.x() + i, j)] = p.e[(i, j)];
        }
    }
    for i in 0..ny {
        for j in 0..nw - nw1 {
            bw[(layout.y_window(big_m - 1) + i, nw1 + j)] = p.f[(i, j)];
        }
    }
    let e_read = &xh - &x_read;
    Ok(FullWindow {
        layout,
        a,
        bw,
        x_read,
        e_read,
    })
}

/// 𝔸(K) alone, from the K-step maps (no rows): what ρ_lin(K) needs, at log₂K products of the
/// lifted step instead of K, so an unstable K is refused before its rows are built.
pub(crate) fn matrix(p: &Pieces, k: usize) -> Result<Mat<f64>, LinearError> {
    Ok(full_window(p, k, None)?.a)
}

/// Builds the model at K from the pieces.
pub(crate) fn build(p: &Pieces, k: usize) -> Result<RegionalModel, LinearError> {
    let big_m = p.windows.len() - 1;
    let d = p.windows[big_m].layout.dims;
    let (nx, nw) = (d.nx, d.nw());
    let mut rows = Rows::new();
    let FullWindow {
        layout,
        a,
        bw,
        x_read,
        e_read,
    } = full_window(p, k, Some(&mut rows))?;

    let StartUp {
        x,
        us,
        ys,
        xhs,
        z0,
        seq_prev,
        rows: startup_rows,
    } = startup(p, k, big_m)?;
    let nv = 2 * nx + big_m * nw;
    let mut start_map = Mat::<f64>::zeros(layout.dim(), nv);
    set_block(&mut start_map, layout.x(), &x);
    for j in 0..big_m {
        set_block(&mut start_map, layout.u_window(j), &us[j]);
        set_block(&mut start_map, layout.y_window(j), &ys[j]);
        set_block(&mut start_map, layout.estimates(j), &xhs[j]);
    }
    set_block(&mut start_map, layout.warm_start(), &z0);
    if let Some(seq) = &seq_prev {
        set_block(&mut start_map, layout.controller(), seq);
    }
    Ok(RegionalModel {
        layout,
        a,
        bw,
        rows,
        x_read,
        e_read,
        start_map,
        startup_rows,
        nx,
        nw,
    })
}

/// The growing-window steps t < `steps` on υ = (x₀, x̄₀, w₀..w_{M−1}): the state, the
/// windows' data, the estimates, the warm start and the rows of every step.
struct StartUp {
    x: Mat<f64>,
    us: Vec<Mat<f64>>,
    ys: Vec<Mat<f64>>,
    xhs: Vec<Mat<f64>>,
    z0: Mat<f64>,
    seq_prev: Option<Mat<f64>>,
    rows: Rows,
}

fn startup(p: &Pieces, k: usize, steps: usize) -> Result<StartUp, LinearError> {
    let big_m = p.horizon;
    let d = p.windows[0].layout.dims;
    let (nx, nu, nw, nw1) = (d.nx, d.nu, d.nw(), d.nw1);
    let nv = 2 * nx + big_m * nw;
    let ev = Mat::<f64>::identity(nv, nv);
    let mut x = rows_of(&ev, 0, nx);
    let prior = rows_of(&ev, nx, nx);
    let mut z0 = prior.clone();
    let (mut us, mut ys, mut xhs) = (Vec::new(), Vec::new(), Vec::new());
    let mut seq_prev: Option<Mat<f64>> = None;
    let mut rows = Rows::new();
    for t in 0..steps.min(big_m).min(p.windows.len() - 1) {
        let ws = &p.windows[t];
        let lay = ws.layout;
        let mut th = Mat::<f64>::zeros(lay.n_theta(), nv);
        set_block(&mut th, 0, &prior);
        for j in 0..t {
            set_block(&mut th, lay.u_offset(j), &us[j]);
            set_block(&mut th, lay.y_offset(j), &ys[j]);
        }
        let (zk, xh) = mhe_step(ws, k, z0.as_ref(), th.as_ref(), Some(t), Some(&mut rows))?;
        let (u, seq) = control(
            &p.law,
            nu,
            xh.as_ref(),
            seq_prev.as_ref().map(|m| m.as_ref()),
            Some(t),
            Some(&mut rows),
        )?;
        seq_prev = seq;
        let w1 = rows_of(&ev, 2 * nx + t * nw, nw1);
        let w2 = rows_of(&ev, 2 * nx + t * nw + nw1, nw - nw1);
        let y = &p.c * &x + &p.f * &w2;
        x = &p.a * &x + &p.b * &u + &p.e * &w1;
        let mut next = Mat::<f64>::zeros(p.windows[t + 1].layout.nz(), nv);
        set_block(&mut next, 0, &zk);
        z0 = next;
        us.push(u);
        ys.push(y);
        xhs.push(xh);
    }
    Ok(StartUp {
        x,
        us,
        ys,
        xhs,
        z0,
        seq_prev,
        rows,
    })
}

/// The rows that take the same value at every K ≥ `k` (the first K the method admits), on υ:
/// every row of step t = 0 (the window-0 problem is solved by its warm start, the prior, so
/// x̂₀ = x̄₀ at every K), and at t = 1 the MHE's rows of the inner iterates up to `k` (their
/// warm start, the padded prior, and their data x̄₀, u₀, y₀ come from step 0 alone). The MPC's
/// rows at t = 1 depend on x̂₁, hence on K, and are left out. A witness among these refutes
/// every K at the cost of two steps.
pub(crate) fn k_free_rows(p: &Pieces, k: usize) -> Result<Rows, LinearError> {
    Ok(startup(p, k, 2)?.rows.retain(|l| {
        l.step == Some(0)
            || (l.step == Some(1) && matches!(l.kind, RowKind::MheBox | RowKind::MheGeneral))
    }))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use closed_loop::scenario::{ControllerChoice, Scenario};
    use qp_iter::Method;

    /// The rows `k_free_rows` keeps take the same value at every K: the full model's start-up
    /// rows at three K carry each of them with the same label and coefficients, and step 1's
    /// MHE rows are among them (the double integrator's 𝒲 box at t = 1 is its witness).
    #[test]
    fn k_free_rows_are_the_same_at_every_k() {
        for (name, method) in [
            ("double-integrator", Method::PG),
            ("double-integrator", Method::ADMM_PR),
            ("case-study-certified", Method::FISTA),
            ("cart-pendulum", Method::ADMM),
        ] {
            let file = format!("{}/../../scenarios/{name}.toml", env!("CARGO_MANIFEST_DIR"));
            let res = Scenario::from_file(&file).unwrap().resolve().unwrap();
            let p = super::super::model::pieces(&res, method, ControllerChoice::ExactMpc).unwrap();
            let start = p
                .windows
                .iter()
                .map(|w| w.lin.start_steps)
                .max()
                .unwrap()
                .max(1);
            let free = k_free_rows(&p, start).unwrap();
            assert!(
                free.labels.iter().any(|l| l.step == Some(1)),
                "{name} {method}: no step-1 row"
            );
            let free_rows = free.to_vecs();
            for k in [start, start + 3, start + 30] {
                let m = build(&p, k).unwrap();
                let all = m.startup_rows.to_vecs();
                for (i, l) in free.labels.iter().enumerate() {
                    let j = m
                        .startup_rows
                        .labels
                        .iter()
                        .position(|x| x == l)
                        .unwrap_or_else(|| panic!("{name} {method} K = {k}: {l:?} missing"));
                    let scale = free_rows[i].iter().fold(1.0f64, |a, v| a.max(v.abs()));
                    for (a, b) in free_rows[i].iter().zip(&all[j]) {
                        assert!(
                            (a - b).abs() <= 1e-12 * scale,
                            "{name} {method} K = {k}: {l:?}: {a} against {b}"
                        );
                    }
                    assert_eq!(
                        (free.lower[i], free.upper[i]),
                        (m.startup_rows.lower[j], m.startup_rows.upper[j])
                    );
                }
            }
        }
    }
}
