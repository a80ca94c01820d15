//! The linear pieces of Alg. 1 where no constraint is active, with the disturbance and with
//! every constraint row written as a linear functional (derivation: `docs/theory.md`,
//! "Regional ISS of the lifted loop").
//!
//! One time step of the MHE with window length m is linear in its inputs (z⁰_t, θ_t): the
//! iteration state starts at ξ₀ = Ξ(z⁰, θ) and moves by ξ_{j+1} = Sξ_j + S_θθ; the point the
//! projection acts on at inner step j is Rξ_j (PG: the iterate; FISTA: T(y); ADMM: the split
//! variable s), and the projection is the identity exactly when that point lies in Z. So the
//! rows "Rξ_j ∈ Z for j = 0..K − k₀" (and, with general rows, l₀ ≤ GRξ_j + Eθ ≤ u₀) are the
//! exact conditions for the step to be the linear map. The same code runs on two column
//! spaces: the start-up unknowns υ = (x₀, x̄₀, w₀..w_{M−1}) for t < M, and the lifted state
//! X_t for t ≥ M.

use faer::{Mat, MatRef};
use mhe_core::problem::WindowLayout;
#[cfg(feature = "serde")]
use serde::Serialize;

use crate::linear::{IterationLinearisation, LinearError, linearise};
use closed_loop::scenario::{ControllerChoice, ResolvedScenario};

/// What a constraint row constrains.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum RowKind {
    /// A component of the point the MHE's projection acts on (box Z = 𝒳 × 𝒲^m).
    MheBox,
    /// A general row of the MHE (𝒳 / 𝒴 on propagated states or outputs).
    MheGeneral,
    /// A row of the MPC's input sequence (exact MPC: −H⁻¹Fx̂ ∈ 𝒰^N, then its predicted-state
    /// rows; K_c-iteration MPC: the point inner iterate `iterate` projects) or of the
    /// saturated LQR.
    Input,
}

/// Which constraint a row is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize))]
#[non_exhaustive]
pub struct RowLabel {
    /// The kind.
    pub kind: RowKind,
    /// Start-up step t < M, or `None` for the full-window steps t ≥ M.
    pub step: Option<usize>,
    /// Inner iteration j (0 for the input rows).
    pub iterate: usize,
    /// Component of the constrained vector.
    pub index: usize,
}

/// Constraint rows over a column space: lower ≤ row·v ≤ upper, stored as dense blocks (the
/// rows of block 0, then of block 1, …) so that norms in a metric are one product per block.
#[derive(Debug, Clone)]
pub(crate) struct Rows {
    pub blocks: Vec<Mat<f64>>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub labels: Vec<RowLabel>,
}

impl Rows {
    pub fn new() -> Self {
        Self {
            blocks: Vec::new(),
            lower: Vec::new(),
            upper: Vec::new(),
            labels: Vec::new(),
        }
    }
    /// Appends the rows of `m` that have a finite bound.
    fn push_block(
        &mut self,
        m: MatRef<'_, f64>,
        lower: &[f64],
        upper: &[f64],
        label: impl Fn(usize) -> RowLabel,
    ) {
        let keep: Vec<usize> = (0..m.nrows())
            .filter(|&i| lower[i].is_finite() || upper[i].is_finite())
            .collect();
        if keep.is_empty() {
            return;
        }
        self.blocks
            .push(Mat::from_fn(keep.len(), m.ncols(), |r, c| m[(keep[r], c)]));
        for &i in &keep {
            self.lower.push(lower[i]);
            self.upper.push(upper[i]);
            self.labels.push(label(i));
        }
    }
    /// The rows whose label `keep` accepts, in order.
    pub fn retain(&self, keep: impl Fn(&RowLabel) -> bool) -> Self {
        let mut out = Self::new();
        let mut i = 0;
        for b in &self.blocks {
            let picked: Vec<usize> = (0..b.nrows())
                .filter(|&r| keep(&self.labels[i + r]))
                .collect();
            if !picked.is_empty() {
                out.blocks
                    .push(Mat::from_fn(picked.len(), b.ncols(), |r, c| {
                        b[(picked[r], c)]
                    }));
                for &r in &picked {
                    out.lower.push(self.lower[i + r]);
                    out.upper.push(self.upper[i + r]);
                    out.labels.push(self.labels[i + r]);
                }
            }
            i += b.nrows();
        }
        out
    }
    /// Every row as a vector (for checks; allocates).
    pub fn to_vecs(&self) -> Vec<Vec<f64>> {
        self.blocks
            .iter()
            .flat_map(|b| (0..b.nrows()).map(move |i| (0..b.ncols()).map(|j| b[(i, j)]).collect()))
            .collect()
    }
}

/// (G, E, l₀, u₀): l₀ ≤ Gz + Eθ ≤ u₀.
pub(crate) type GeneralRows = (Mat<f64>, Mat<f64>, Vec<f64>, Vec<f64>);

/// One window length's step pieces.
#[derive(Debug, Clone)]
pub(crate) struct WindowStep {
    pub lin: IterationLinearisation,
    pub layout: WindowLayout,
    pub x_z: Mat<f64>,
    pub x_theta: Mat<f64>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    /// (G, E, l₀, u₀) of the general rows.
    pub general: Option<GeneralRows>,
}

/// The control law's linear piece. Static (exact MPC, saturated LQR): v = gain·x̂ with
/// lower ≤ v ≤ upper, u = its first n_u rows. The K_c-iteration MPC (`iterative`): U_t is K_c
/// steps of its Φ on θ = x̂_t from the warm start W·U_{t−1} (U = 0 at t = 0, the cold start),
/// and the point every inner iterate projects must lie in 𝒰^N = [lower, upper].
#[derive(Debug, Clone)]
pub(crate) struct Law {
    /// The static gain (0 × n_x for the K_c-iteration MPC).
    pub gain: Mat<f64>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub iterative: Option<MpcIteration>,
}

/// The K_c-iteration MPC's linear pieces.
#[derive(Debug, Clone)]
pub(crate) struct MpcIteration {
    /// Its Φ, linearised where no projection acts.
    pub lin: IterationLinearisation,
    /// K_c.
    pub k: usize,
    /// W of the warm start U⁰_t = W U_{t−1}.
    pub warm: Mat<f64>,
}

impl Law {
    /// N n_u for the K_c-iteration MPC (its previous sequence is part of the lifted state),
    /// 0 for a static law.
    pub fn n_controller(&self) -> usize {
        self.iterative.as_ref().map_or(0, |m| m.lin.n)
    }
}

/// Why the model cannot be built (a void reason of the regional certificate).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The linear analysis failed (origin not interior, probe active, …).
    #[error(transparent)]
    Linear(#[from] LinearError),
    /// A structure the regional certificate does not cover.
    #[error("{0}")]
    NotCovered(String),
}

pub(crate) fn mul(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    a * b
}

/// Every window length's pieces and the law, from the objects the simulation runs.
pub(crate) struct Pieces {
    pub windows: Vec<WindowStep>,
    pub law: Law,
    pub a: Mat<f64>,
    pub b: Mat<f64>,
    pub c: Mat<f64>,
    pub e: Mat<f64>,
    pub f: Mat<f64>,
    pub shifted: bool,
    /// M (the windows above may stop short of it: [`pieces_upto`]).
    pub horizon: usize,
}

pub(crate) fn pieces(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
    controller: ControllerChoice,
) -> Result<Pieces, ModelError> {
    pieces_upto(resolved, method, controller, usize::MAX)
}

/// [`pieces`] with the windows of length 0..=min(`last`, M) only: what the first steps need
/// (step 0 needs windows 0 and 1), at a fraction of the cost on a long horizon.
pub(crate) fn pieces_upto(
    resolved: &ResolvedScenario,
    method: qp_iter::Method,
    controller: ControllerChoice,
    last: usize,
) -> Result<Pieces, ModelError> {
    let est = resolved
        .estimator(method, qp_iter::Iterations::ONE, false)
        .map_err(|e| ModelError::Linear(LinearError::Build(e)))?;
    let big_m = est.config().horizon;
    let windows = window_steps(&est, big_m.min(last))?;
    let law = law_of(resolved, controller)?;
    for (l, u) in law.lower.iter().zip(&law.upper) {
        if !(*l < 0.0 && *u > 0.0) && (l.is_finite() || u.is_finite()) {
            return Err(LinearError::OriginNotInterior {
                problem: "MPC",
                index: 0,
                lower: *l,
                upper: *u,
            }
            .into());
        }
    }
    let sys = &resolved.scenario().plant;
    Ok(Pieces {
        windows,
        law,
        a: sys.a().to_owned(),
        b: sys.b().to_owned(),
        c: sys.c().to_owned(),
        e: sys.e().to_owned(),
        f: sys.f().to_owned(),
        shifted: matches!(est.config().warm_start, mhe_core::WarmStart::Shifted),
        horizon: big_m,
    })
}

/// Each window length's linearised step, its end-state maps, its box and general rows.
fn window_steps(
    est: &closed_loop::scenario::ScenarioEstimator,
    last: usize,
) -> Result<Vec<WindowStep>, ModelError> {
    let mut windows = Vec::with_capacity(last + 1);
    for m in 0..=last {
        let w = est.problem().window(m).ok_or(LinearError::Internal(
            "the MHE has no window of this length",
        ))?;
        let map = est
            .map(m)
            .ok_or(LinearError::Internal("the MHE has no map of this length"))?;
        let lin = linearise(map, "MHE")?;
        let qp = w.qp();
        let general = qp.general().map(|g| {
            (
                g.g().to_owned(),
                g.e().to_owned(),
                g.lower().to_vec(),
                g.upper().to_vec(),
            )
        });
        if general.is_some() && lin.lift_dim() != lin.n && lin.lift_dim() != 2 * lin.n {
            return Err(ModelError::NotCovered(
                "the MHE has general rows (sets.state / sets.output on the window) and runs the \
                 ADMM split, whose projected variable is not the iterate: the regional \
                 certificate covers PG and FISTA on general rows, and every method on a box"
                    .into(),
            ));
        }
        let (x_z, x_theta) = w.x_end_maps();
        windows.push(WindowStep {
            lin,
            layout: w.layout(),
            x_z: x_z.to_owned(),
            x_theta: x_theta.to_owned(),
            lower: qp.zset().lower().to_vec(),
            upper: qp.zset().upper().to_vec(),
            general,
        });
    }
    Ok(windows)
}

/// The exact MPC's linear law −H⁻¹F x̂ with 𝒰^N and, after it, its predicted-state rows.
fn exact_mpc_law(mpc: &mpc_core::CondensedMpc) -> Result<Law, ModelError> {
    use faer::linalg::solvers::Solve;
    let qp = mpc.qp();
    let llt = qp
        .h()
        .to_owned()
        .llt(faer::Side::Lower)
        .map_err(|_| LinearError::Internal("the MPC Hessian is not positive definite"))?;
    let sol = llt.solve(qp.f());
    let gain = Mat::from_fn(sol.nrows(), sol.ncols(), |i, j| -sol[(i, j)]);
    let mut lower = qp.zset().lower().to_vec();
    let mut upper = qp.zset().upper().to_vec();
    // State rows of the MPC (x_k ∈ 𝒳): l₀ ≤ GU* + Ex̂ ≤ u₀, appended after U*.
    let gain = match qp.general() {
        None => gain,
        Some(g) => {
            let rows = g.g() * &gain + g.e();
            lower.extend_from_slice(g.lower());
            upper.extend_from_slice(g.upper());
            let n = gain.nrows();
            Mat::from_fn(n + rows.nrows(), gain.ncols(), |i, j| {
                if i < n {
                    gain[(i, j)]
                } else {
                    rows[(i - n, j)]
                }
            })
        }
    };
    Ok(Law {
        gain,
        lower,
        upper,
        iterative: None,
    })
}

/// The control law's linear piece for `controller` (exact MPC, saturated LQR, K_c-iteration
/// MPC on the input box).
fn law_of(resolved: &ResolvedScenario, controller: ControllerChoice) -> Result<Law, ModelError> {
    let build = |e| ModelError::Linear(LinearError::Build(e));
    let mpc = resolved.mpc().map_err(build)?;
    match controller {
        ControllerChoice::ExactMpc => exact_mpc_law(mpc),
        ControllerChoice::SaturatedLqr => {
            let ctrl = resolved
                .controller(ControllerChoice::SaturatedLqr)
                .map_err(build)?;
            let closed_loop::scenario::ScenarioController::SaturatedLqr(lqr) = ctrl else {
                return Err(LinearError::Internal("the saturated LQR was not built").into());
            };
            let k = lqr.gain();
            Ok(Law {
                gain: Mat::from_fn(k.nrows(), k.ncols(), |i, j| -k[(i, j)]),
                lower: lqr.input_set().lower().to_vec(),
                upper: lqr.input_set().upper().to_vec(),
                iterative: None,
            })
        }
        ControllerChoice::SuboptimalMpc { iterations, .. } => {
            if mpc.has_general_rows() {
                return Err(ModelError::NotCovered(
                    "a K_c-iteration MPC with state rows (sets.state in the MPC): it runs the \
                     ADMM split, whose projected variable is not the iterate; the regional \
                     certificate covers the K_c-iteration MPC on the input box 𝒰^N"
                        .into(),
                ));
            }
            let ctrl = resolved.controller(controller).map_err(build)?;
            let closed_loop::scenario::ScenarioController::Suboptimal(c) = ctrl else {
                return Err(LinearError::Internal("the K_c-iteration MPC was not built").into());
            };
            let lin = linearise(c.map(), "MPC")?;
            let warm = crate::linear::mpc_warm_matrix(c.warm_start_rule(), lin.n, mpc.nu());
            let qp = mpc.qp();
            Ok(Law {
                gain: Mat::zeros(0, qp.n_theta()),
                lower: qp.zset().lower().to_vec(),
                upper: qp.zset().upper().to_vec(),
                iterative: Some(MpcIteration {
                    lin,
                    k: iterations.get(),
                    warm,
                }),
            })
        }
    }
}

/// K iterations of a linearised Φ on the column space of `z0`, `theta`: pushes the rows of the
/// point every inner iterate projects (`kind`: on the box [lower, upper]; general rows as
/// `RowKind::MheGeneral`), returns zᴷ. Without `rows` (ρ_lin alone) zᴷ comes from the K-step
/// map by repeated squaring: log₂K products of the lifted step instead of K.
#[allow(clippy::too_many_arguments)]
fn iterate(
    lin: &IterationLinearisation,
    k: usize,
    z0: MatRef<'_, f64>,
    theta: MatRef<'_, f64>,
    (lower, upper): (&[f64], &[f64]),
    general: Option<&GeneralRows>,
    (kind, step): (RowKind, Option<usize>),
    rows: Option<&mut Rows>,
) -> Result<Mat<f64>, LinearError> {
    let (n, nt, nxi) = (lin.n, lin.n_theta, lin.lift_dim());
    if k == 0 || k < lin.start_steps {
        return Err(LinearError::ZeroIterations);
    }
    let Some(rows) = rows else {
        let km = lin.k_step(k, faer::Par::Seq)?;
        return Ok(mul(km.g.as_ref(), z0) + mul(km.j.as_ref(), theta));
    };
    let start = lin.start.as_ref();
    let mut xi = mul(start.subcols(0, n), z0) + mul(start.subcols(n, nt), theta);
    let s = lin.step.as_ref().subcols(0, nxi);
    let s_theta = mul(lin.step.as_ref().subcols(nxi, nt), theta);
    let mut it = Mat::<f64>::zeros(n, z0.ncols());
    for j in 0..=(k - lin.start_steps) {
        if j > 0 {
            xi = mul(s, xi.as_ref()) + &s_theta;
        }
        it = mul(lin.readout.as_ref(), xi.as_ref());
        let label = |kind, index| RowLabel {
            kind,
            step,
            iterate: j + lin.start_steps,
            index,
        };
        rows.push_block(it.as_ref(), lower, upper, |i| label(kind, i));
        if let Some((g, e, l0, u0)) = general {
            let gz = mul(g.as_ref(), it.as_ref()) + mul(e.as_ref(), theta);
            rows.push_block(gz.as_ref(), l0, u0, |i| label(RowKind::MheGeneral, i));
        }
    }
    Ok(it)
}

/// One MHE step of window `ws` with K iterations on the column space of `z0`, `theta`:
/// pushes the rows of every projected point (when given), returns (zᴷ, x̂).
pub(crate) fn mhe_step(
    ws: &WindowStep,
    k: usize,
    z0: MatRef<'_, f64>,
    theta: MatRef<'_, f64>,
    step: Option<usize>,
    rows: Option<&mut Rows>,
) -> Result<(Mat<f64>, Mat<f64>), LinearError> {
    let it = iterate(
        &ws.lin,
        k,
        z0,
        theta,
        (&ws.lower, &ws.upper),
        ws.general.as_ref(),
        (RowKind::MheBox, step),
        rows,
    )?;
    let xh = mul(ws.x_z.as_ref(), it.as_ref()) + mul(ws.x_theta.as_ref(), theta);
    Ok((it, xh))
}

/// The law on x̂: pushes its rows (when given), returns u and, for the K_c-iteration MPC, U_t.
/// `prev` is U_{t−1} on the same column space (None: the cold start, U⁰ = 0).
pub(crate) fn control(
    law: &Law,
    nu: usize,
    xh: MatRef<'_, f64>,
    prev: Option<MatRef<'_, f64>>,
    step: Option<usize>,
    rows: Option<&mut Rows>,
) -> Result<(Mat<f64>, Option<Mat<f64>>), LinearError> {
    let Some(m) = &law.iterative else {
        let v = mul(law.gain.as_ref(), xh);
        if let Some(rows) = rows {
            rows.push_block(v.as_ref(), &law.lower, &law.upper, |i| RowLabel {
                kind: RowKind::Input,
                step,
                iterate: 0,
                index: i,
            });
        }
        return Ok((v.as_ref().subrows(0, nu).to_owned(), None));
    };
    let z0 = match prev {
        Some(p) => mul(m.warm.as_ref(), p),
        None => Mat::zeros(m.lin.n, xh.ncols()),
    };
    let seq = iterate(
        &m.lin,
        m.k,
        z0.as_ref(),
        xh,
        (&law.lower, &law.upper),
        None,
        (RowKind::Input, step),
        rows,
    )?;
    Ok((seq.as_ref().subrows(0, nu).to_owned(), Some(seq)))
}

/// The time-shifted warm start z⁰ = W_z zᴷ + W_θ θ (as `MheEstimator::push` for t ≥ M).
pub(crate) fn shifted_warm_start(p: &Pieces, w: WindowLayout) -> (Mat<f64>, Mat<f64>) {
    let d = w.dims;
    let (nz, nw) = (w.nz(), d.nw());
    let mut wz = Mat::<f64>::zeros(nz, nz);
    let mut wth = Mat::<f64>::zeros(nz, w.n_theta());
    for i in 0..d.nx {
        for j in 0..d.nx {
            wz[(i, j)] += p.a[(i, j)];
        }
        for j in 0..d.nw1 {
            wz[(i, w.w_offset(0) + j)] += p.e[(i, j)];
        }
        for j in 0..d.nu {
            wth[(i, w.u_offset(0) + j)] += p.b[(i, j)];
        }
    }
    for i in d.nx..nz - nw {
        wz[(i, i + nw)] = 1.0;
    }
    (wz, wth)
}
