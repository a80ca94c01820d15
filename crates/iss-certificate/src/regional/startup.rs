//! The start-up of the real loop over the scenario's uncertainty, with the clips acting
//! (docs/theory.md, "Regional ISS with an active start-up", step 2).
//!
//! The steps are those of `lifted::startup` and `lifted::full_window` — the growing window
//! t < M from the padded warm start and the prior x̄₀, then full windows whose prior is the
//! estimate of M steps before — but every vector is a zonotope over υ = (x₀, x̄₀ − x₀,
//! w₀, w₁, …) and each inner iterate's projection is the clip of [`super::zonotope`]. So
//! every reachable value of x_t, x̂_t and u_t lies in the set reported for step t, whether or
//! not a constraint acts. The controller: the saturated LQR is a clip; the exact MPC is
//! covered where its unconstrained minimiser provably lies in 𝒰 (and its state rows hold)
//! over the whole set, else a typed reason names the row; the K_c-iteration MPC is not
//! covered yet.

use faer::Mat;

use super::clip_form::ClipForm;
use super::handoff::{HandOff, hand_off};
use super::model::{ModelError, Pieces, RowKind, shifted_warm_start};
use super::zonotope::{self, ClipStatus, Space};
use crate::linear::LiftedLayout;
use closed_loop::scenario::{ControllerChoice, ResolvedScenario};

/// The scenario's uncertainty: x₀ ∈ x0_nominal + r_x𝔹, ‖x̄₀ − x₀‖ ≤ r_e, and per step w in
/// the box |w_i| ≤ w_half_i (`Some`) or the ball ‖w‖ ≤ w̄.
#[derive(Debug, Clone)]
pub(crate) struct Uncertainty {
    pub x0_nominal: Vec<f64>,
    pub x0_radius: f64,
    pub prior_error: f64,
    pub w: WSet,
}

/// The per-step disturbance set.
#[derive(Debug, Clone)]
pub(crate) enum WSet {
    Box(Vec<f64>),
    Ball(f64),
}

/// One clip that acted (not inactive) during the start-up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ActiveClip {
    pub kind: RowKind,
    pub step: usize,
    pub iterate: usize,
    pub index: usize,
    pub status: ClipStatus,
}

/// Interval hulls of one step's values.
#[derive(Debug, Clone)]
pub(crate) struct StepHull {
    pub x: Vec<(f64, f64)>,
    pub x_hat: Vec<(f64, f64)>,
    pub u: Vec<(f64, f64)>,
}

/// T steps of the real loop over the set.
#[derive(Debug, Clone)]
pub(crate) struct Propagation {
    pub hulls: Vec<StepHull>,
    pub active: Vec<ActiveClip>,
}

impl Uncertainty {
    /// The set of the regional certificate's options (the scenario's own by default).
    pub(crate) fn of(o: &super::RegionalOptions) -> Self {
        let w = match &o.w_box {
            Some(r) => {
                let norm = r.iter().map(|x| x * x).sum::<f64>().sqrt();
                let scale = if norm > 0.0 { o.w_bar / norm } else { 0.0 };
                WSet::Box(r.iter().map(|x| x * scale).collect())
            }
            None => WSet::Ball(o.w_bar),
        };
        Self {
            x0_nominal: o.x0_nominal.clone(),
            x0_radius: o.x0_radius,
            prior_error: o.prior_error,
            w,
        }
    }
}

/// The clip form of every window length's MHE map (0..=M).
pub(crate) fn window_forms(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
) -> Result<Vec<ClipForm>, ModelError> {
    let est = resolved
        .estimator(method, qp_iter::Iterations::ONE, false)
        .map_err(|e| ModelError::Linear(crate::linear::LinearError::Build(e)))?;
    (0..=est.config().horizon)
        .map(|m| {
            est.map(m).map_or(
                Err(ModelError::NotCovered(
                    "the MHE has no map of this length".into(),
                )),
                ClipForm::of,
            )
        })
        .collect()
}

fn hull(space: &Space, m: &Mat<f64>) -> Vec<(f64, f64)> {
    let m = space.widen(m.as_ref());
    (0..m.nrows())
        .map(|i| space.interval(m.as_ref(), i))
        .collect()
}

/// Stacks `parts` (each a form over the space) at the given row offsets of an n-row form.
fn assemble(space: &Space, n: usize, parts: &[(usize, &Mat<f64>)]) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(n, 1 + space.count());
    for (r0, m) in parts {
        let m = space.widen(m.as_ref());
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                out[(r0 + i, j)] = m[(i, j)];
            }
        }
    }
    out
}

/// The loop's state between steps, every entry a form over the space.
struct LoopState {
    x: Mat<f64>,
    prior: Mat<f64>,
    z0: Mat<f64>,
    us: Vec<Mat<f64>>,
    ys: Vec<Mat<f64>>,
    xhs: Vec<Mat<f64>>,
}

impl LoopState {
    /// Step 0: x₀ = x̄₀ + a ball of radius `x0_radius`, the prior x₀ plus a ball of radius
    /// `prior_error`, the warm start the prior.
    fn initial(space: &mut Space, nx: usize, unc: &Uncertainty) -> Self {
        let gx = space.add_ball(nx, unc.x0_radius);
        let ge = space.add_ball(nx, unc.prior_error);
        let cols = 1 + space.count();
        let x = Mat::from_fn(nx, cols, |i, j| {
            if j == 0 {
                unc.x0_nominal[i]
            } else if j == 1 + gx + i {
                1.0
            } else {
                0.0
            }
        });
        let prior = Mat::from_fn(nx, cols, |i, j| {
            x[(i, j)] + f64::from(u8::from(j == 1 + ge + i))
        });
        LoopState {
            x,
            z0: prior.clone(),
            prior,
            us: Vec::new(),
            ys: Vec::new(),
            xhs: Vec::new(),
        }
    }

    /// Boxes generators past `cap` over every form still read later (the last M data).
    fn reduce(&mut self, space: &mut Space, big_m: usize, cap: usize) {
        let keep = self.us.len().saturating_sub(big_m);
        let mut forms = vec![self.x.clone(), self.prior.clone(), self.z0.clone()];
        for v in [&self.us, &self.ys, &self.xhs] {
            forms.extend(v[keep..].iter().cloned());
        }
        space.reduce(&mut forms, cap);
        let mut it = forms.into_iter();
        let mut next = |old: &Mat<f64>| it.next().unwrap_or_else(|| old.clone());
        self.x = next(&self.x);
        self.prior = next(&self.prior);
        self.z0 = next(&self.z0);
        for v in [&mut self.us, &mut self.ys, &mut self.xhs] {
            for m in v[keep..].iter_mut() {
                *m = next(m);
            }
        }
    }
}

/// The law on the zonotope of x̂: u (first n_u rows) and what it clipped; a typed reason
/// where the law is not covered.
fn law(
    p: &Pieces,
    controller: ControllerChoice,
    space: &mut Space,
    xh: &Mat<f64>,
    t: usize,
    active: &mut Vec<ActiveClip>,
) -> Result<Mat<f64>, ModelError> {
    let nu = p.b.ncols();
    if p.law.iterative.is_some() {
        return Err(ModelError::NotCovered(
            "the K_c-iteration MPC in the start-up: its inner iterates are not propagated as \
             clips yet (the start-up certificate covers the exact MPC and the saturated LQR)"
                .into(),
        ));
    }
    let v = &p.law.gain * &space.widen(xh.as_ref());
    let v = match controller {
        ControllerChoice::SaturatedLqr => {
            let (v, status) = space.clip(v.as_ref(), &p.law.lower, &p.law.upper);
            for (index, s) in status.into_iter().enumerate() {
                if s != ClipStatus::Inactive {
                    active.push(ActiveClip {
                        kind: RowKind::Input,
                        step: t,
                        iterate: 0,
                        index,
                        status: s,
                    });
                }
            }
            v
        }
        _ => {
            for i in 0..v.nrows() {
                let (lo, hi) = space.interval(v.as_ref(), i);
                let (l, u) = (p.law.lower[i], p.law.upper[i]);
                if lo < l || hi > u {
                    return Err(ModelError::NotCovered(format!(
                        "the exact MPC at t = {t}: row {i} of its unconstrained minimiser \
                         (and predicted-state rows) reaches [{lo:.4e}, {hi:.4e}] over the set, \
                         beyond its bounds [{l:.4e}, {u:.4e}], so the minimiser is not the \
                         linear law there"
                    )));
                }
            }
            v
        }
    };
    Ok(v.as_ref().subrows(0, nu).to_owned())
}

/// Called before each step t ≥ M with the lifted state X_t's form; `true` stops.
pub(crate) type Hook<'a> = (
    LiftedLayout,
    &'a mut dyn FnMut(usize, &Space, &Mat<f64>) -> Result<bool, ModelError>,
);

/// X_t in the lifted layout (t ≥ M): x, the last M inputs, outputs and estimates, z⁰.
fn lifted_form(space: &Space, l: LiftedLayout, st: &LoopState) -> Mat<f64> {
    let first = st.us.len() - l.horizon;
    let mut parts = vec![(l.x(), &st.x), (l.warm_start(), &st.z0)];
    for j in 0..l.horizon {
        parts.push((l.u_window(j), &st.us[first + j]));
        parts.push((l.y_window(j), &st.ys[first + j]));
        parts.push((l.estimates(j), &st.xhs[first + j]));
    }
    assemble(space, l.dim(), &parts)
}

/// `steps` steps of the real loop at K over the uncertainty, boxing generators past `cap`;
/// `hook` sees X_t before every step t ≥ M and may stop the propagation there.
#[allow(clippy::too_many_arguments)]
pub(crate) fn propagate(
    p: &Pieces,
    forms: &[ClipForm],
    controller: ControllerChoice,
    k: usize,
    steps: usize,
    unc: &Uncertainty,
    cap: usize,
    mut hook: Option<Hook<'_>>,
) -> Result<Propagation, ModelError> {
    let big_m = p.horizon;
    if forms.len() != p.windows.len() || p.windows.len() != big_m + 1 {
        return Err(ModelError::NotCovered(
            "the start-up needs every window length's pieces".into(),
        ));
    }
    let d = p.windows[0].layout.dims;
    let (nx, nw, nw1) = (d.nx, d.nw(), d.nw1);
    let mut space = Space::default();
    let mut st = LoopState::initial(&mut space, nx, unc);
    let (mut hulls, mut active) = (Vec::with_capacity(steps), Vec::new());
    for t in 0..steps {
        if let Some((layout, f)) = hook.as_mut()
            && t >= big_m
            && f(t, &space, &lifted_form(&space, *layout, &st))?
        {
            break;
        }
        let m = t.min(big_m);
        let ws = &p.windows[m];
        let lay = ws.layout;
        let first = t - m;
        let prior = if t < big_m { &st.prior } else { &st.xhs[first] };
        let mut parts = vec![(0, prior)];
        for j in 0..m {
            parts.push((lay.u_offset(j), &st.us[first + j]));
            parts.push((lay.y_offset(j), &st.ys[first + j]));
        }
        let theta = assemble(&space, lay.n_theta(), &parts);
        let z0 = space.widen(st.z0.as_ref());
        let (iterates, log) = zonotope::iterate(
            &forms[m],
            &mut space,
            z0.as_ref(),
            theta.as_ref(),
            k,
            usize::MAX,
        );
        record_mhe_clips(&log, t, &mut active);
        let zk = match iterates.last() {
            Some(z) => space.widen(z.as_ref()),
            None => return Err(crate::linear::LinearError::ZeroIterations.into()),
        };
        let theta = space.widen(theta.as_ref());
        let xh = &ws.x_z * &zk + &ws.x_theta * &theta;
        let u = law(p, controller, &mut space, &xh, t, &mut active)?;
        let w = disturbance(&mut space, &unc.w, nw);
        let (x, u, xh) = (
            space.widen(st.x.as_ref()),
            space.widen(u.as_ref()),
            space.widen(xh.as_ref()),
        );
        let w1 = w.as_ref().subrows(0, nw1);
        let w2 = w.as_ref().subrows(nw1, nw - nw1);
        let y = &p.c * &x + &p.f * w2;
        hulls.push(StepHull {
            x: hull(&space, &x),
            x_hat: hull(&space, &xh),
            u: hull(&space, &u),
        });
        st.x = &p.a * &x + &p.b * &u + &p.e * w1;
        st.z0 = if t < big_m {
            let nz = p.windows[t + 1].layout.nz();
            assemble(&space, nz, &[(0, &zk)])
        } else if p.shifted {
            let (wz, wth) = shifted_warm_start(p, lay);
            &wz * &zk + &wth * &theta
        } else {
            zk
        };
        st.us.push(u);
        st.ys.push(y);
        st.xhs.push(xh);
        st.reduce(&mut space, big_m, cap);
    }
    Ok(Propagation { hulls, active })
}

/// The MHE box rows the iterates of step `t` clipped (`log`: per iterate, per row).
fn record_mhe_clips(log: &[Vec<ClipStatus>], t: usize, active: &mut Vec<ActiveClip>) {
    for (j, status) in log.iter().enumerate() {
        for (index, s) in status.iter().enumerate() {
            if *s != ClipStatus::Inactive {
                active.push(ActiveClip {
                    kind: RowKind::MheBox,
                    step: t,
                    iterate: j,
                    index,
                    status: *s,
                });
            }
        }
    }
}

/// w_t: new generators (the box's half-widths, or a ball of radius w̄).
fn disturbance(space: &mut Space, set: &WSet, nw: usize) -> Mat<f64> {
    let gw = match set {
        WSet::Box(_) => space.add_intervals(nw),
        WSet::Ball(r) => space.add_ball(nw, *r),
    };
    let cols = 1 + space.count();
    Mat::from_fn(nw, cols, |i, j| match (set, j == 1 + gw + i) {
        (WSet::Box(h), true) => h[i],
        (WSet::Ball(_), true) => 1.0,
        _ => 0.0,
    })
}

/// The start-up certificate at one K: constraints may act for t < T; from T on no row is
/// active and the loop is the lifted linear one, ISS with rate λ (Theorem R from X_T).
#[derive(Debug, Clone)]
pub(crate) struct StartupCertificate {
    /// The first T (M ≤ T ≤ the bound searched) whose hand-off holds, or None.
    pub t: Option<usize>,
    /// The clips that acted before T (or before the last T tried).
    pub active: Vec<ActiveClip>,
    /// The hand-off at T, or the last one tried (its binding row and by how much it exceeds).
    pub hand_off: HandOff,
}

/// Searches T ∈ M + {0, 1, 2, 5, 10, 20, 40, 80, …} up to `t_max` for the first at which
/// the hand-off holds (each hand-off costs `exact` products of the rows with 𝔸).
pub(crate) fn certify(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
    controller: ControllerChoice,
    k: usize,
    unc: &Uncertainty,
    (t_max, exact, cap): (usize, usize, usize),
) -> Result<StartupCertificate, ModelError> {
    let p = super::model::pieces(resolved, method, controller)?;
    let forms = window_forms(resolved, method)?;
    let model = super::lifted::build(&p, k)?;
    let rho = crate::linear::spectral_radius(model.a.as_ref(), faer::Par::Seq)?;
    if !(rho < 1.0) {
        return Err(ModelError::NotCovered(format!(
            "ρ_lin = {rho:.6} ≥ 1: the full-window loop is not stable at K = {k}"
        )));
    }
    let mut last: Option<(usize, HandOff)> = None;
    let mut found = None;
    let big_m = p.horizon;
    let tried = |t: usize| {
        let s = t - big_m;
        s <= 2 || s == 5 || (s % 10 == 0 && (s / 10).is_power_of_two())
    };
    let mut f = |t: usize, space: &Space, x: &Mat<f64>| -> Result<bool, ModelError> {
        if !tried(t) {
            return Ok(false);
        }
        let h = hand_off(&model, space, x, &unc.w, exact, rho)?;
        let holds = h.holds;
        last = Some((t, h));
        if holds {
            found = Some(t);
        }
        Ok(holds)
    };
    let prop = propagate(
        &p,
        &forms,
        controller,
        k,
        t_max.max(big_m) + 1,
        unc,
        cap,
        Some((model.layout, &mut f)),
    )?;
    let Some((t_last, hand_off)) = last else {
        return Err(ModelError::NotCovered("no T ≥ M was tried".into()));
    };
    let active = prop
        .active
        .into_iter()
        .filter(|a| a.step < t_last)
        .collect();
    Ok(StartupCertificate {
        t: found,
        active,
        hand_off,
    })
}

#[cfg(test)]
#[path = "startup_tests.rs"]
mod tests;
