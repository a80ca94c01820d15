//! A scenario's MHE data as `mhe_embedded` reads them (PG on the problem as given, the
//! exporter's layout) in f64 and rounded once to f32, and the estimator's warm start read
//! back. Shared by tests/all (`precision`, `global_precision`) and tests/loop_level
//! (`f32_seeds`).
#![allow(dead_code)] // each test binary uses a part

use closed_loop::scenario::ResolvedScenario;

/// One window's data for `mhe_embedded` (PG, plain or Jacobi-scaled), as the exporter
/// copies it: H by columns, F by rows, α = 2/(L + μ) of the std map — of the scaled problem
/// with its scaling d for the Jacobi variant (`mhe_export::extract`'s `window_of`).
pub(crate) struct Owned {
    pub(crate) n: usize,
    pub(crate) nt: usize,
    h: Vec<f64>,
    q0: Vec<f64>,
    f: Vec<f64>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    step: f64,
    /// V-FISTA's β (0 for the other methods).
    momentum: f64,
    scaling: Vec<f64>,
    /// ADMM: ρ(H + ρI)⁻¹ and (H + ρI)⁻¹ by columns, 1/ρ, α (empty / 0 otherwise).
    m_rho: Vec<f64>,
    m_inv: Vec<f64>,
    inv_rho: f64,
    relaxation: f64,
}

/// PG on the problem as given.
pub(crate) fn owned(resolved: &ResolvedScenario) -> Vec<Owned> {
    owned_for(resolved, qp_iter::Method::PG)
}

/// `method` (PG, V-FISTA or ADMM, plain or Jacobi-scaled): the problem its map runs on, its
/// scaling, the gradient methods' step (and V-FISTA's momentum) and ADMM's stored data
/// (`mhe_export::extract`'s `window_of`).
pub(crate) fn owned_for(resolved: &ResolvedScenario, method: qp_iter::Method) -> Vec<Owned> {
    use qp_iter::{IterationMap, MethodMap};
    let problem = resolved.mhe_problem().expect("MHE builds");
    problem
        .windows()
        .iter()
        .map(|w| {
            let map = method.build(w.qp().clone()).expect("the method builds");
            let (inner, scaling) = match &map {
                MethodMap::Scaled(s) => (s.inner(), s.scaling().to_vec()),
                other => (other, Vec::new()),
            };
            let qp = inner.problem().clone();
            let cols = |m: &qp_iter::kernel::PaddedSymmetric| -> Vec<f64> {
                let n = m.n();
                (0..n * n)
                    .map(|k| m.as_slice()[(k / n) * m.ld() + k % n])
                    .collect()
            };
            let (m_rho, m_inv, inv_rho, relaxation) = match inner {
                MethodMap::Admm(a) => {
                    let (mr, mi) = a.stored_inverses();
                    (cols(mr), cols(mi), 1.0 / a.rho(), a.relaxation())
                }
                MethodMap::Pg(_) | MethodMap::Fista(_) => (Vec::new(), Vec::new(), 0.0, 0.0),
                _ => panic!("PG, V-FISTA or ADMM only"),
            };
            let (step, momentum) = match inner {
                MethodMap::Fista(f) => (f.step_size(), f.momentum()),
                _ => (2.0 / (qp.l() + qp.mu()), 0.0),
            };
            let (n, nt) = (qp.n(), qp.n_theta());
            let (h, f) = (qp.h(), qp.f());
            Owned {
                n,
                nt,
                h: (0..n * n).map(|k| h[(k % n, k / n)]).collect(),
                q0: qp.q0().to_vec(),
                f: (0..n * nt).map(|k| f[(k / nt, k % nt)]).collect(),
                lo: qp.zset().lower().to_vec(),
                hi: qp.zset().upper().to_vec(),
                step,
                momentum,
                scaling,
                m_rho,
                m_inv,
                inv_rho,
                relaxation,
            }
        })
        .collect()
}

pub(crate) fn to32(v: &[f64]) -> Vec<f32> {
    v.iter().map(|x| *x as f32).collect()
}

/// The f64 windows as `mhe_embedded` reads them (PG, no scaling).
pub(crate) fn windows64(ws: &[Owned]) -> Vec<mhe_embedded::Window<'_, f64>> {
    ws.iter()
        .map(|w| mhe_embedded::Window {
            n: w.n,
            n_theta: w.nt,
            h: &w.h,
            m_rho: &w.m_rho,
            m_inv: &w.m_inv,
            q0: &w.q0,
            f: &w.f,
            lower: &w.lo,
            upper: &w.hi,
            scaling: &w.scaling,
            step: w.step,
            momentum: w.momentum,
            inv_rho: w.inv_rho,
            relaxation: w.relaxation,
            structured: None,
        })
        .collect()
}

/// The f32 copies of each window's (H, q₀, F, lower, upper, scaling, ADMM's M_ρ and M).
pub(crate) fn singles(ws: &[Owned]) -> Vec<[Vec<f32>; 8]> {
    ws.iter()
        .map(|w| {
            [
                to32(&w.h),
                to32(&w.q0),
                to32(&w.f),
                to32(&w.lo),
                to32(&w.hi),
                to32(&w.scaling),
                to32(&w.m_rho),
                to32(&w.m_inv),
            ]
        })
        .collect()
}

/// The f32 windows over `singles(ws)`, the step rounded to f32.
pub(crate) fn windows32<'a>(
    ws: &[Owned],
    s32: &'a [[Vec<f32>; 8]],
) -> Vec<mhe_embedded::Window<'a, f32>> {
    ws.iter()
        .zip(s32)
        .map(|(w, s)| mhe_embedded::Window {
            n: w.n,
            n_theta: w.nt,
            h: &s[0],
            m_rho: &s[6],
            m_inv: &s[7],
            q0: &s[1],
            f: &s[2],
            lower: &s[3],
            upper: &s[4],
            scaling: &s[5],
            step: w.step as f32,
            momentum: w.momentum as f32,
            inv_rho: w.inv_rho as f32,
            relaxation: w.relaxation as f32,
            structured: None,
        })
        .collect()
}

/// An f32 slice widened to f64 (exactly).
pub(crate) fn widen(v: &[f32]) -> Vec<f64> {
    v.iter().map(|x| f64::from(*x)).collect()
}

/// y = M x (row-major through faer).
pub(crate) fn apply(m: faer::MatRef<'_, f64>, x: &[f64]) -> Vec<f64> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)] * x[j]).sum())
        .collect()
}

/// ‖v‖₂.
pub(crate) fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}
