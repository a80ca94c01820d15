//! `Estimator(..., dtype="float32")`: the std estimator's ℙ_t data (as `cargo xtask export`
//! extracts them: H, F, q₀, the box, α, β, ρ(H + ρI)⁻¹, (H + ρI)⁻¹, the Jacobi d, A, B, E)
//! rounded once to f32, run by `mhe_embedded::MheRt`: the operations of the board's
//! `mhe_embedded::Mhe<f32, …>` in the same order, so a notebook gets the board's bits.

use mhe_core::{MheEstimator, WarmStart};
use mhe_embedded::{Method as EmbMethod, MheRt, Problem, Window};
use qp_iter::kernel::PaddedSymmetric;
use qp_iter::{IterationMap, MethodMap, ParametricQp};

/// Why the f32 path cannot run an estimator (the message names the fix).
pub(crate) type Refusal = String;

/// One window's data in f32 (each f64 rounded once, as the exporter writes them).
struct Win32 {
    n: usize,
    n_theta: usize,
    arrays: [Box<[f32]>; 8],
    step: f32,
    momentum: f32,
    inv_rho: f32,
    relaxation: f32,
}

fn f32s(v: impl IntoIterator<Item = f64>) -> Box<[f32]> {
    v.into_iter().map(|x| x as f32).collect()
}

/// Column-major n × n of a padded matrix (entry (i, j) at j·n + i).
fn unpad(m: &PaddedSymmetric) -> Box<[f32]> {
    let (n, ld) = (m.n(), m.ld());
    let s = m.as_slice();
    f32s((0..n * n).map(|k| s[(k / n) * ld + k % n]))
}

fn base(qp: &ParametricQp) -> Win32 {
    let (n, nt) = (qp.n(), qp.n_theta());
    let (h, f) = (qp.h(), qp.f());
    Win32 {
        n,
        n_theta: nt,
        arrays: [
            f32s((0..n * n).map(|k| h[(k % n, k / n)])),
            Box::new([]),
            Box::new([]),
            f32s(qp.q0().iter().copied()),
            f32s((0..n * nt).map(|k| f[(k / nt, k % nt)])),
            f32s(qp.zset().lower().iter().copied()),
            f32s(qp.zset().upper().iter().copied()),
            Box::new([]),
        ],
        step: 0.0,
        momentum: 0.0,
        inv_rho: 0.0,
        relaxation: 0.0,
    }
}

/// The f32 data of window m (`xtask/src/export/extract.rs`'s `window_of`, rounded once).
fn window_of(map: &MethodMap, m: usize) -> Result<(EmbMethod, Win32), Refusal> {
    let qp = map.problem();
    if qp.general().is_some() {
        return Err(format!(
            "window m = {m} has general constraint rows; the f32 kernel covers box \
             constraints only: use boxes for the sets, or dtype=\"float64\""
        ));
    }
    let structured = || {
        format!(
            "window m = {m} (n = {}) runs through the structured Hessian product, which the \
             f32 kernel does not implement: use a shorter horizon or dtype=\"float64\"",
            qp.n()
        )
    };
    Ok(match map {
        MethodMap::Pg(pg) => {
            if pg.is_structured() {
                return Err(structured());
            }
            let mut w = base(qp);
            w.step = pg.alpha() as f32;
            (EmbMethod::Pg, w)
        }
        MethodMap::Fista(f) => {
            if f.is_structured() {
                return Err(structured());
            }
            let mut w = base(qp);
            w.step = f.step_size() as f32;
            w.momentum = f.momentum() as f32;
            (EmbMethod::Fista, w)
        }
        MethodMap::Admm(a) => {
            let mut w = base(qp);
            let (m_rho, m_inv) = a.stored_inverses();
            w.arrays[1] = unpad(m_rho);
            w.arrays[2] = unpad(m_inv);
            w.inv_rho = (1.0 / a.rho()) as f32;
            w.relaxation = a.relaxation() as f32;
            (EmbMethod::Admm, w)
        }
        MethodMap::Scaled(s) => {
            let (method, mut w) = window_of(s.inner(), m)?;
            w.arrays[7] = f32s(s.scaling().iter().copied());
            (method, w)
        }
        other => {
            return Err(format!(
                "method `{}` has no f32 kernel (mhe-embedded implements pg, fista and admm, \
                 plain or -jacobi): use one of those or dtype=\"float64\"",
                other.name()
            ));
        }
    })
}

/// An owned allocation handed out as a `'static` borrow and freed in [`F32Estimator`]'s
/// `Drop` (a raw pointer: no `Box` is kept alive beside the borrows, so nothing aliases).
struct Owned<T: ?Sized>(*mut T);

impl<T: ?Sized> Owned<T> {
    fn new(b: Box<T>) -> Self {
        Self(Box::into_raw(b))
    }
    /// SAFETY (caller): the borrow must not outlive `self`, and no `&mut` to it may exist.
    unsafe fn shared(&self) -> &'static T {
        // SAFETY: the pointer comes from `Box::into_raw` and stays valid until `free`; the
        // caller keeps the borrow within `self`'s life.
        unsafe { &*self.0 }
    }
    /// SAFETY (caller): called once, after every borrow handed out is gone.
    unsafe fn free(&mut self) {
        // SAFETY: from `Box::into_raw`, freed once (the caller's contract).
        drop(unsafe { Box::from_raw(self.0) });
    }
}

/// The f32 estimator: `MheRt` over the f32 data and a workspace, all owned here.
pub(crate) struct F32Estimator {
    /// Borrows every allocation below; `None` only inside `Drop`.
    mhe: Option<MheRt<'static, 'static, f32>>,
    arrays: Vec<Owned<[f32]>>,
    windows: Owned<[Window<'static, f32>]>,
    problem: Owned<Problem<'static, f32>>,
    workspace: Owned<[f32]>,
    nx: usize,
}

// SAFETY: the raw pointers are allocations owned by this value alone (no other handle
// exists); `MheRt<f32>` and the data it borrows are `Send`.
unsafe impl Send for F32Estimator {}

impl std::fmt::Debug for F32Estimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("F32Estimator")
            .field("nx", &self.nx)
            .finish()
    }
}

impl Drop for F32Estimator {
    fn drop(&mut self) {
        // The estimator (the only holder of borrows) goes first.
        self.mhe = None;
        // SAFETY: every borrow of these allocations lived in `mhe` (dropped above) or in
        // the `Window`s / `Problem` freed here, in the order problem → windows → arrays.
        unsafe {
            self.problem.free();
            self.windows.free();
            for a in &mut self.arrays {
                a.free();
            }
            self.workspace.free();
        }
    }
}

impl F32Estimator {
    /// The f32 estimator of `est` (its windows, M, K, method, warm start) for `sys`, at t = 0
    /// with `prior`.
    pub(crate) fn new(
        est: &MheEstimator<MethodMap>,
        sys: &lti_model::LtiSystem,
        prior: &[f64],
    ) -> Result<Self, Refusal> {
        let mut method = None;
        let mut wins = Vec::new();
        for (m, map) in est.maps().iter().enumerate() {
            let (kind, w) = window_of(map, m)?;
            method = Some(kind);
            wins.push(w);
        }
        let method = method.ok_or_else(|| "the estimator has no windows".to_string())?;
        let mut arrays = Vec::with_capacity(8 * wins.len() + 3);
        let mut own = |b: Box<[f32]>| -> &'static [f32] {
            let o = Owned::new(b);
            // SAFETY: `o` is kept in `arrays` until `Drop`, after `mhe` is gone.
            let r = unsafe { o.shared() };
            arrays.push(o);
            r
        };
        let mut views = Vec::with_capacity(wins.len());
        for w in wins {
            let [h, m_rho, m_inv, q0, f, lower, upper, scaling] = w.arrays.map(&mut own);
            views.push(Window {
                n: w.n,
                n_theta: w.n_theta,
                h,
                m_rho,
                m_inv,
                q0,
                f,
                lower,
                upper,
                scaling,
                step: w.step,
                momentum: w.momentum,
                inv_rho: w.inv_rho,
                relaxation: w.relaxation,
                structured: None,
            });
        }
        let rm = |m: faer::MatRef<'_, f64>| f32s(lti_model::matrix::row_major(m));
        let (a, b, e) = (own(rm(sys.a())), own(rm(sys.b())), own(rm(sys.e())));
        let windows = Owned::new(views.into_boxed_slice());
        let cfg = est.config();
        let problem = Owned::new(Box::new(Problem {
            nx: sys.nx(),
            nu: sys.nu(),
            ny: sys.ny(),
            nw1: sys.nw1(),
            nw2: sys.nw2(),
            horizon: cfg.horizon,
            iterations: cfg.iterations.get(),
            method,
            warm_start: match cfg.warm_start {
                WarmStart::Paper => mhe_embedded::WarmStart::Paper,
                WarmStart::Shifted => mhe_embedded::WarmStart::Shifted,
            },
            a,
            b,
            e,
            // SAFETY: freed in `Drop` after `problem` and `mhe`.
            windows: unsafe { windows.shared() },
        }));
        // SAFETY: freed in `Drop` after `mhe`, the only other borrower.
        let p: &'static Problem<'static, f32> = unsafe { problem.shared() };
        let len = MheRt::workspace_len(p);
        let workspace = Owned::new(vec![0.0f32; len].into_boxed_slice());
        // SAFETY: the one `&mut` to the workspace, held by `mhe` only; freed after it.
        let ws: &'static mut [f32] = unsafe { &mut *workspace.0 };
        let prior32: Vec<f32> = prior.iter().map(|x| *x as f32).collect();
        let mhe = MheRt::new(p, &prior32, ws).map_err(|e| format!("f32 data: {e}"))?;
        Ok(Self {
            mhe: Some(mhe),
            arrays,
            windows,
            problem,
            workspace,
            nx: sys.nx(),
        })
    }

    fn mhe(&mut self) -> &mut MheRt<'static, 'static, f32> {
        self.mhe.as_mut().expect("present until Drop")
    }

    /// x̂_{t|t} in f32.
    pub(crate) fn estimate(&mut self) -> &[f32] {
        self.mhe().estimate()
    }

    /// Appends (u_t, y_t) (already f32).
    pub(crate) fn push(&mut self, u: &[f32], y: &[f32]) -> Result<(), mhe_embedded::PushErrorRt> {
        self.mhe().push(u, y)
    }

    /// Restarts at t = 0.
    pub(crate) fn reset(&mut self, prior: &[f32]) -> Result<(), mhe_embedded::DataError> {
        self.mhe().reset(prior)
    }

    pub(crate) fn t(&self) -> usize {
        self.mhe.as_ref().map_or(0, MheRt::t)
    }

    /// The problem data (for the const-size replay of the tests).
    pub(crate) fn problem(&self) -> &Problem<'static, f32> {
        // SAFETY: freed only in `Drop`; the borrow is tied to `&self`.
        unsafe { self.problem.shared() }
    }
}

/// The board's const-size `mhe_embedded::Mhe<f32, 4, 2, 1, 9, 49, 31>` (the case study's
/// sizes: n_x = 4, n_u = 2, n_y = 1, M = 9, n_w = 5) on `problem` from `prior`, fed `pairs`:
/// x̂ before each push and after the last one. The reference the f32 pytest compares with
/// bit for bit (None: `problem` is not of those sizes).
pub(crate) fn replay_const_case_study(
    problem: &Problem<'_, f32>,
    prior: &[f32],
    pairs: &[(Vec<f32>, Vec<f32>)],
) -> Option<Vec<[f32; 4]>> {
    let prior: [f32; 4] = prior.try_into().ok()?;
    let mut mhe = mhe_embedded::Mhe::<f32, 4, 2, 1, 9, 49, 31>::new(problem, prior).ok()?;
    let mut out = Vec::with_capacity(pairs.len() + 1);
    for (u, y) in pairs {
        out.push(*mhe.estimate());
        let u: [f32; 2] = u.as_slice().try_into().ok()?;
        let y: [f32; 1] = y.as_slice().try_into().ok()?;
        mhe.push(&u, &y).ok()?;
    }
    out.push(*mhe.estimate());
    Some(out)
}
