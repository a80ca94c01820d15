//! Diagonal preconditioning: any iteration map run on the scaled problem z = D y.
//!
//! With D = diag(d), d > 0, the QP min ½zᵀHz + qᵀz over the box [l, u] becomes
//! min ½yᵀ(DHD)y + (Dq)ᵀy over the box [D⁻¹l, D⁻¹u] — still a box, so every projection stays
//! exact, and its condition number κ(DHD) can be far below κ(H). The MHE's QP is the case
//! in point: the weights η^{i−1} of cost (9) make κ(H) grow like η^{−M} (issue 12), and
//! **Jacobi scaling** d_i = H_ii^{−½} (unit diagonal) removes that growth.
//!
//! **The certificate in the problem's norm (design trap 5).** The inner map certifies
//! ‖yᴷ − y*‖ ≤ c·rᴷ‖y⁰ − y*‖ in its own (scaled) coordinates. With z = Dy,
//! ‖zᴷ − z*‖ ≤ d_max‖yᴷ − y*‖ and ‖y⁰ − y*‖ ≤ ‖z⁰ − z*‖/d_min, so
//!
//!   ‖zᴷ − z*‖ ≤ κ(D)·c·rᴷ·‖z⁰ − z*‖,  κ(D) = d_max/d_min:
//!
//! the same rate r, the prefactor multiplied by κ(D) (an additive log κ(D)/log(1/r) in K,
//! not a worse rate). The scaled iterate is feasible exactly when the inner one is
//! (y ∈ [D⁻¹l, D⁻¹u] ⇔ Dy ∈ [l, u]), so eq. (11) fits when the inner certificate does.
//! Everything above `qp-iter` (ε_t, L_Φ, H̄, Props. 1–3) stays in the Euclidean norm of z.
//!
//! ```
//! use faer::{mat, Mat};
//! use qp_iter::BoxSet;
//! use qp_iter::{IterationMap, ParametricQp, run_fixed};
//! use qp_iter::method::{Method, Scaling};
//! // A badly scaled QP: κ(H) = 10⁴, κ(DHD) = 1 (H is diagonal).
//! let qp = ParametricQp::new(mat![[1.0e4, 0.0], [0.0, 1.0]], vec![-1.0e4, -1.0],
//!     Mat::zeros(2, 0), BoxSet::whole(2)).unwrap();
//! let plain = Method::PG.build(qp.clone()).unwrap();
//! let scaled = Method::PG.with_scaling(Scaling::Jacobi).build(qp).unwrap();
//! assert!(scaled.certificate().rate < 1e-12 && plain.certificate().rate > 0.999);
//! let mut s = scaled.new_state();
//! scaled.load(&mut s, &[]);
//! scaled.warm_start(&mut s, &[0.0, 0.0], None);
//! run_fixed(&scaled, &mut s, 1);
//! let z = scaled.iterate(&s);
//! assert!((z[0] - 1.0).abs() < 1e-12 && (z[1] - 1.0).abs() < 1e-12);
//! ```

use crate::BoxSet;
use faer::Mat;

use crate::certificate::Certificate;
use crate::error::Result;
use crate::operator::DiagonalScaled;
use crate::problem::ParametricQp;
use crate::{IterationMap, QpError};

/// Φ of an inner map run on the diagonally scaled problem, reporting iterates, duals and
/// its certificate in the coordinates of the original problem.
#[derive(Debug, Clone)]
pub struct Scaled<M> {
    /// The original problem (what [`IterationMap::problem`] reports).
    qp: ParametricQp,
    /// d: z = D y.
    d: Vec<f64>,
    inner: M,
    cert: Certificate,
    /// κ(D) = d_max/d_min.
    kappa_d: f64,
}

/// The state of a [`Scaled`] map: the inner state (in y) and the iterate and dual in z.
#[derive(Debug)]
pub struct ScaledState<S> {
    inner: S,
    /// y⁰ = D⁻¹z⁰ (and D·λ for a dual) while warm-starting.
    scratch: Vec<f64>,
    /// z = D y of the current iterate.
    z: Vec<f64>,
    /// D⁻¹λ_y: the box multipliers in z (when the inner map has a dual).
    dual: Vec<f64>,
    has_dual: bool,
}

impl<S> ScaledState<S> {
    /// The inner map's state (in the scaled coordinates y).
    pub fn inner_mut(&mut self) -> &mut S {
        &mut self.inner
    }
}

/// d_i = H_ii^{−½}: the scaled Hessian DHD has a unit diagonal.
pub fn jacobi_scaling(qp: &ParametricQp) -> Vec<f64> {
    let h = qp.h();
    (0..qp.n()).map(|i| 1.0 / h[(i, i)].sqrt()).collect()
}

impl<M: IterationMap> Scaled<M> {
    /// Scales `qp` by `d` (every entry positive and finite) and builds the inner map on
    /// the scaled problem with `build`.
    pub fn new(
        qp: ParametricQp,
        d: Vec<f64>,
        build: impl FnOnce(ParametricQp) -> Result<M>,
    ) -> Result<Self> {
        let n = qp.n();
        if d.len() != n {
            return Err(QpError::Parameter {
                name: "scaling".into(),
                value: d.len() as f64,
                reason: format!("the diagonal scaling has {} entries, z has {n}", d.len()),
            });
        }
        if let Some(&bad) = d.iter().find(|x| !(x.is_finite() && **x > 0.0)) {
            return Err(QpError::Parameter {
                name: "scaling".into(),
                value: bad,
                reason: "every entry of a diagonal scaling must be positive and finite".into(),
            });
        }
        let h = qp.h();
        let hs = Mat::from_fn(n, n, |i, j| d[i] * h[(i, j)] * d[j]);
        let q0: Vec<f64> = qp.q0().iter().zip(&d).map(|(q, di)| di * q).collect();
        let f = qp.f();
        let fs = Mat::from_fn(n, f.ncols(), |i, j| d[i] * f[(i, j)]);
        let (lo, hi) = (qp.zset().lower(), qp.zset().upper());
        let zset = BoxSet::new(
            lo.iter().zip(&d).map(|(l, di)| l / di).collect(),
            hi.iter().zip(&d).map(|(u, di)| u / di).collect(),
        )?;
        let mut scaled = ParametricQp::new(hs, q0, fs, zset)?;
        // General rows carried through: G z = (G D) y, bounds and E unchanged.
        if let Some(gc) = qp.general() {
            let g = gc.g();
            let gd = Mat::from_fn(gc.m(), n, |i, j| g[(i, j)] * d[j]);
            scaled = scaled.with_general(crate::problem::GeneralConstraints::new(
                gd,
                gc.e().to_owned(),
                gc.lower().to_vec(),
                gc.upper().to_vec(),
            )?)?;
        }
        if let Some(op) = qp.operator() {
            scaled = scaled.with_operator(std::sync::Arc::new(DiagonalScaled {
                inner: op.clone(),
                d: d.clone(),
            }))?;
        }
        let inner = build(scaled)?;
        let (d_min, d_max) = d
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(a, b), &x| (a.min(x), b.max(x)));
        let kappa_d = d_max / d_min;
        let c = inner.certificate();
        let cert = Certificate {
            rate: c.rate,
            prefactor: c.prefactor * kappa_d,
            quantity: c.quantity,
            norm: c.norm.clone(),
            fits_eq11: c.fits_eq11,
            premise: format!(
                "{}; on the diagonally scaled problem z = Dy, converted to ‖z‖ with κ(D) = {kappa_d:.6e}",
                c.premise
            ),
            source: format!(
                "{}; ‖zᴷ − z*‖ ≤ d_max‖yᴷ − y*‖, ‖y⁰ − y*‖ ≤ ‖z⁰ − z*‖/d_min (qp_iter::scaled)",
                c.source
            ),
        };
        Ok(Self {
            qp,
            d,
            inner,
            cert,
            kappa_d,
        })
    }

    /// The scaling d (z = D y).
    pub fn scaling(&self) -> &[f64] {
        &self.d
    }

    /// κ(D) = d_max/d_min, the factor between the inner and the reported prefactor.
    pub fn kappa_d(&self) -> f64 {
        self.kappa_d
    }

    /// The map on the scaled problem.
    pub fn inner(&self) -> &M {
        &self.inner
    }

    /// The map on the scaled problem, mutable (to change its kernel).
    pub fn inner_mut(&mut self) -> &mut M {
        &mut self.inner
    }

    /// Sets the reported iterate z = D·(inner iterate) and the dual in z from the inner
    /// state (the map does it after every call; a caller that drives the inner state
    /// directly, like a linearisation probe, calls it after).
    pub fn refresh(&self, s: &mut ScaledState<M::State>) {
        for ((z, y), d) in
            s.z.iter_mut()
                .zip(self.inner.iterate(&s.inner))
                .zip(&self.d)
        {
            *z = d * y;
        }
        s.has_dual = match self.inner.dual(&s.inner) {
            Some(l) => {
                let n = self.d.len();
                for ((o, l), d) in s.dual.iter_mut().zip(l).zip(&self.d) {
                    *o = l / d;
                }
                // G rows: G z = (G D) y, the same rows, the same multipliers.
                for (o, l) in s.dual[n..].iter_mut().zip(l.get(n..).unwrap_or(&[])) {
                    *o = *l;
                }
                true
            }
            None => false,
        };
    }
}

impl<M: IterationMap> IterationMap for Scaled<M> {
    type State = ScaledState<M::State>;

    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn problem(&self) -> &ParametricQp {
        &self.qp
    }
    fn new_state(&self) -> Self::State {
        let n = self.qp.n();
        ScaledState {
            inner: self.inner.new_state(),
            scratch: vec![0.0; n],
            z: vec![0.0; n],
            // Box multipliers, then (ADMM split on general rows) those of the G rows.
            dual: vec![0.0; n + self.qp.general().map_or(0, |g| g.m())],
            has_dual: false,
        }
    }
    fn load(&self, state: &mut Self::State, theta: &[f64]) {
        // The scaled F and q₀ give q_y = D(q₀ + Fθ) directly.
        self.inner.load(&mut state.inner, theta);
    }
    fn warm_start(&self, state: &mut Self::State, z0: &[f64], dual: Option<&[f64]>) {
        for ((y, z), d) in state.scratch.iter_mut().zip(z0).zip(&self.d) {
            *y = z / d;
        }
        match dual {
            Some(l) => {
                // λ_y = D λ_z; the inner map copies both before returning.
                let mut ly = std::mem::take(&mut state.dual);
                let n = self.d.len();
                for ((o, l), d) in ly.iter_mut().zip(l).zip(&self.d) {
                    *o = l * d;
                }
                for (o, l) in ly[n..].iter_mut().zip(l.get(n..).unwrap_or(&[])) {
                    *o = *l;
                }
                let k = l.len().min(ly.len());
                self.inner
                    .warm_start(&mut state.inner, &state.scratch, Some(&ly[..k]));
                state.dual = ly;
            }
            None => self
                .inner
                .warm_start(&mut state.inner, &state.scratch, None),
        }
        self.refresh(state);
    }
    fn cold_start(&self, state: &mut Self::State) {
        self.inner.cold_start(&mut state.inner);
        self.refresh(state);
    }
    fn step(&self, state: &mut Self::State) {
        self.inner.step(&mut state.inner);
        self.refresh(state);
    }
    fn run_steps(&self, state: &mut Self::State, k: usize) {
        self.inner.run_steps(&mut state.inner, k);
        self.refresh(state);
    }
    fn iterate<'s>(&self, state: &'s Self::State) -> &'s [f64] {
        &state.z
    }
    /// The inner map's violation: G rows are the same rows (G z = (G D) y); box rows are
    /// measured in y (in z they scale by d_i).
    fn violation(&self, state: &Self::State) -> f64 {
        self.inner.violation(&state.inner)
    }
    fn dual<'s>(&self, state: &'s Self::State) -> Option<&'s [f64]> {
        state.has_dual.then_some(state.dual.as_slice())
    }
    fn certificate(&self) -> &Certificate {
        &self.cert
    }
    fn set_kernel(&mut self, kernel: crate::kernel::Kernel) {
        self.inner.set_kernel(kernel);
    }
    fn matvecs_per_step(&self) -> usize {
        self.inner.matvecs_per_step()
    }
}

/// A map on the scaled problem z = Dy: ξ is the inner map's (in y); the start converts
/// z⁰ to y⁰ = D⁻¹z⁰, the readout is D·R_inner. The reported iterate is refreshed after each
/// probe so the interior check sees z.
impl<M: crate::linearise::Linearise> crate::linearise::Linearise for Scaled<M> {
    fn lift_dim(&self) -> usize {
        self.inner().lift_dim()
    }
    fn start_steps(&self) -> usize {
        self.inner().start_steps()
    }
    fn start_probe(&self, st: &mut Self::State, z0: &[f64], theta: &[f64], xi: &mut [f64]) {
        let y0: Vec<f64> = z0.iter().zip(self.scaling()).map(|(z, d)| z / d).collect();
        self.inner().start_probe(st.inner_mut(), &y0, theta, xi);
        self.refresh(st);
    }
    fn step_probe(&self, st: &mut Self::State, xi: &[f64], theta: &[f64], out: &mut [f64]) {
        self.inner().step_probe(st.inner_mut(), xi, theta, out);
        self.refresh(st);
    }
    fn readout(&self) -> faer::Mat<f64> {
        let r = self.inner().readout();
        let d = self.scaling();
        faer::Mat::from_fn(r.nrows(), r.ncols(), |i, j| d[i] * r[(i, j)])
    }
}
