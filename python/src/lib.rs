//! `suboptimal_mhe._native`: the thin PyO3 layer of the Python package (issue 39).
//!
//! Everything here converts NumPy arrays to the workspace's typed Rust API (`LtiSystem`,
//! `MheSettings::builder()`, `Scenario`, `certify_closed_loop`, `ScenarioLoop`) and Rust
//! errors to the package's exceptions; the Python module `suboptimal_mhe` adds argument
//! checks that name the Python argument, docstrings and the result classes. No numerical
//! routine lives here: the numbers are the CLI's, computed by the same functions.

use closed_loop::scenario::{ControllerChoice, LoopOptions, ResolvedScenario, Scenario};
use faer::Mat;
use iss_certificate::certificate::ClosedLoopCertificate;
use iss_certificate::certificate::{CertificateOptions, Gamma13Source, certify_closed_loop};
use iss_certificate::coverage::{self, Configuration, Scalar, verdict_options};
use iss_certificate::{Certificate, CertifyOptions, LoopModel, ModelBuildError, certify};
use lti_model::spec::MatrixSpec;
use lti_model::{LtiSystem, ModelError};
use mhe_core::{MheError as RustMheError, MheEstimator, MheSets, MheSettings};
use mpc_core::settings::{MpcSettings, RawMpc};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use qp_iter::{Method, MethodMap};
use std::sync::{Mutex, MutexGuard};

mod embedded;
mod export;
mod reasons;
mod sweep;

create_exception!(
    suboptimal_mhe,
    MheError,
    PyValueError,
    "Base of every error the package raises (a ValueError: the input was refused)."
);
create_exception!(
    suboptimal_mhe,
    InputError,
    MheError,
    "An argument is invalid; the message names it and says how to fix it."
);
create_exception!(
    suboptimal_mhe,
    ShapeError,
    InputError,
    "An array has the wrong shape or a dimension is above the supported maximum."
);
create_exception!(
    suboptimal_mhe,
    NonFiniteError,
    InputError,
    "An array or scalar has a NaN or infinite entry."
);
create_exception!(
    suboptimal_mhe,
    NotPositiveDefiniteError,
    InputError,
    "A weight (Q, R, P) is not symmetric positive definite."
);
create_exception!(
    suboptimal_mhe,
    OutOfRangeError,
    InputError,
    "A scalar is outside its admissible range (e.g. eta not in [0, 1), k < 1)."
);
create_exception!(
    suboptimal_mhe,
    ScenarioError,
    MheError,
    "A scenario (file or TOML text) is invalid or lacks a section the call needs."
);
create_exception!(
    suboptimal_mhe,
    CertificateError,
    MheError,
    "The model cannot be set up for the certificate (e.g. LMI (2) infeasible for the MHE)."
);
create_exception!(
    suboptimal_mhe,
    NumericalError,
    MheError,
    "A numerical step failed (e.g. a window's QP is not strongly convex)."
);
create_exception!(
    suboptimal_mhe,
    UnsupportedError,
    MheError,
    "The request is valid but not supported by this version; the message says what is."
);

/// The `MheBuilder` methods that are arguments of `Estimator(...)`.
const MHE_KEYS: [&str; 7] = [
    "MheBuilder::horizon",
    "MheBuilder::eta",
    "MheBuilder::iterations",
    "MheBuilder::method",
    "MheBuilder::q",
    "MheBuilder::r",
    "MheBuilder::p",
];

/// The Python argument a `MheBuilder` method corresponds to (the builder's errors name
/// its methods, `MheBuilder::eta`).
fn argument_of(key: &str) -> &str {
    match key {
        "MheBuilder::iterations" => "k",
        other => other.strip_prefix("MheBuilder::").unwrap_or(other),
    }
}

/// A `ModelError` as the package exception of its kind.
fn model_err(e: &ModelError) -> PyErr {
    let msg = e.to_string();
    match e {
        ModelError::Shape { .. } => ShapeError::new_err(msg),
        ModelError::NonFinite { .. } => NonFiniteError::new_err(msg),
        ModelError::NotSymmetric { .. } | ModelError::NotPositiveDefinite { .. } => {
            NotPositiveDefiniteError::new_err(msg)
        }
        ModelError::OutOfRange { .. } => OutOfRangeError::new_err(msg),
        ModelError::InvalidSet { .. } => InputError::new_err(msg),
        ModelError::LmiInfeasible { .. } => CertificateError::new_err(msg),
        ModelError::Numerical { .. } => NumericalError::new_err(msg),
        ModelError::Scenario { .. } => ScenarioError::new_err(msg),
        ModelError::Invalid { .. } => InputError::new_err(msg),
        _ => MheError::new_err(msg),
    }
}

/// An error of `Estimator(...)`: the builder's errors name its methods (`MheBuilder::eta`),
/// renamed to the Python arguments.
fn estimator_err(e: &RustMheError) -> PyErr {
    match e {
        RustMheError::Model(ModelError::Invalid {
            field: key,
            problem,
        }) if key.starts_with("MheBuilder::") => {
            let mut problem = problem.clone();
            for k in MHE_KEYS {
                problem = problem.replace(&format!("`{k}`"), &format!("`{}`", argument_of(k)));
            }
            let problem = python_hint(problem);
            InputError::new_err(format!("argument `{}`: {problem}", argument_of(key)))
        }
        other => mhe_err(other),
    }
}

/// An `mhe_core::MheError` as the package exception of its kind.
fn mhe_err(e: &RustMheError) -> PyErr {
    let msg = e.to_string();
    match e {
        RustMheError::Model(m) => model_err(m),
        RustMheError::OutOfRange { .. } => OutOfRangeError::new_err(msg),
        RustMheError::Length { .. } => ShapeError::new_err(msg),
        RustMheError::NonFinite { .. } => NonFiniteError::new_err(msg),
        RustMheError::Unsupported { .. } => UnsupportedError::new_err(msg),
        RustMheError::NotStronglyConvex { .. } | RustMheError::Numerical { .. } => {
            NumericalError::new_err(msg)
        }
        _ => MheError::new_err(msg),
    }
}

/// A closed-loop / scenario error: the model errors keep their kind, the rest are about the
/// scenario (missing section, dimensions).
fn loop_err(e: &closed_loop::ClosedLoopError) -> PyErr {
    use closed_loop::ClosedLoopError as E;
    match e {
        E::Model(m) => model_err(m),
        E::Mhe(m) => mhe_err(m),
        other => ScenarioError::new_err(other.to_string()),
    }
}

/// A dense matrix from a 2-D NumPy array (C or Fortran order, any strides).
fn mat_of(a: &PyReadonlyArray2<'_, f64>) -> Mat<f64> {
    let v = a.as_array();
    Mat::from_fn(v.nrows(), v.ncols(), |i, j| v[[i, j]])
}

fn slice_of<'a>(a: &'a PyReadonlyArray1<'_, f64>, name: &str) -> PyResult<&'a [f64]> {
    a.as_slice()
        .map_err(|_| ShapeError::new_err(format!("`{name}` must be a contiguous 1-D array")))
}

fn matrix_py<'py>(
    py: Python<'py>,
    m: faer::MatRef<'_, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect();
    PyArray2::from_vec2(py, &rows).map_err(|e| MheError::new_err(e.to_string()))
}

/// The plant x⁺ = Ax + Bu + Ew¹, y = Cx + Fw² (eq. (1)), validated by `LtiSystem`.
#[pyclass(module = "suboptimal_mhe._native", name = "_Plant", frozen)]
struct Plant {
    sys: LtiSystem,
}

#[pymethods]
impl Plant {
    #[new]
    fn new(
        a: PyReadonlyArray2<'_, f64>,
        b: PyReadonlyArray2<'_, f64>,
        c: PyReadonlyArray2<'_, f64>,
        e: PyReadonlyArray2<'_, f64>,
        f: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<Self> {
        let sys =
            LtiSystem::with_disturbance(mat_of(&a), mat_of(&b), mat_of(&c), mat_of(&e), mat_of(&f))
                .map_err(|e| model_err(&e))?;
        Ok(Self { sys })
    }

    /// (n_x, n_u, n_y, n_w1, n_w2).
    #[getter]
    fn dims(&self) -> (usize, usize, usize, usize, usize) {
        let s = &self.sys;
        (s.nx(), s.nu(), s.ny(), s.nw1(), s.nw2())
    }

    fn matrix<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let s = &self.sys;
        let m = match name {
            "A" => s.a(),
            "B" => s.b(),
            "C" => s.c(),
            "E" => s.e(),
            "F" => s.f(),
            _ => {
                return Err(InputError::new_err(format!(
                    "no matrix `{name}`: use A, B, C, E or F"
                )));
            }
        };
        matrix_py(py, m)
    }
}

/// Alg. 1 with K iterations of the certified method per step (`mhe_core::MheEstimator`).
#[pyclass(module = "suboptimal_mhe._native", name = "_Estimator")]
struct Estimator {
    /// Behind a mutex: the iteration state has `Cell`s (Send, not Sync), and a Python
    /// object may be reached from several threads; uncontended, a lock costs nanoseconds.
    mhe: Mutex<MheEstimator<MethodMap>>,
    /// `dtype="float32"`: the embedded f32 kernel on the same data (then `push`/`estimate`
    /// go there; `mhe` only answers `p`).
    f32: Option<Mutex<F32State>>,
    settings: MheSettings,
    /// n_x: the length `estimate_into` checks `out` against.
    nx: usize,
}

/// The f32 estimator and its input scratch (u, y rounded once to f32; no allocation per call).
#[derive(Debug)]
struct F32State {
    est: embedded::F32Estimator,
    u: Vec<f32>,
    y: Vec<f32>,
}

impl F32State {
    fn push(&mut self, u: &[f64], y: &[f64]) -> PyResult<()> {
        let (nu, ny) = (self.u.len(), self.y.len());
        for (name, got, want) in [("u", u.len(), nu), ("y", y.len(), ny)] {
            if got != want {
                return Err(ShapeError::new_err(format!(
                    "argument `{name}` has length {got}, expected {want}"
                )));
            }
        }
        for (d, s) in self.u.iter_mut().zip(u) {
            *d = *s as f32;
        }
        for (d, s) in self.y.iter_mut().zip(y) {
            *d = *s as f32;
        }
        self.est.push(&self.u, &self.y).map_err(|e| {
            NonFiniteError::new_err(format!(
                "{e} in float32 (NaN, ±inf, or beyond ±3.4e38): the estimator is unchanged"
            ))
        })
    }
}

fn poisoned<T>(_: T) -> PyErr {
    MheError::new_err("the estimator failed inside an earlier call; create a new Estimator")
}

impl Estimator {
    /// The estimator, refused after a panic inside an earlier call (its state may be
    /// half-updated: a new estimator is the fix).
    fn mhe(&self) -> PyResult<MutexGuard<'_, MheEstimator<MethodMap>>> {
        self.mhe.lock().map_err(poisoned)
    }
}

/// The estimator's sets 𝒳, 𝒴, 𝒲 from the box arguments (None: the whole space), each
/// checked against its dimension before anything is built.
fn sets_of(
    sys: &LtiSystem,
    state_box: Option<&PyBox<'_>>,
    output_box: Option<&PyBox<'_>>,
    disturbance_box: Option<&PyBox<'_>>,
) -> PyResult<MheSets> {
    let one = |b: Option<&PyBox<'_>>, name: &str, n: usize| -> PyResult<qp_iter::BoxSet> {
        let Some(b) = b else {
            return Ok(qp_iter::BoxSet::whole(n));
        };
        let (l, u) = box_of(b, name)?;
        if l.len() != n || u.len() != n {
            return Err(ShapeError::new_err(format!(
                "argument `{name}` has bounds of lengths ({}, {}), expected {n} each",
                l.len(),
                u.len()
            )));
        }
        qp_iter::BoxSet::named(name, l.to_vec(), u.to_vec())
            .map_err(|e| InputError::new_err(format!("argument `{name}`: {e}")))
    };
    Ok(MheSets {
        state: one(state_box, "state_box", sys.nx())?,
        output: one(output_box, "output_box", sys.ny())?,
        disturbance: one(disturbance_box, "disturbance_box", sys.nw())?,
    })
}

#[pymethods]
impl Estimator {
    #[new]
    #[pyo3(signature = (plant, horizon, eta, k, method, prior, q=None, r=None, p=None,
        state_box=None, output_box=None, disturbance_box=None, dtype="float64"))]
    fn new(
        py: Python<'_>,
        plant: &Plant,
        horizon: usize,
        eta: f64,
        k: usize,
        method: &str,
        prior: PyReadonlyArray1<'_, f64>,
        q: Option<PyReadonlyArray2<'_, f64>>,
        r: Option<PyReadonlyArray2<'_, f64>>,
        p: Option<PyReadonlyArray2<'_, f64>>,
        state_box: Option<PyBox<'_>>,
        output_box: Option<PyBox<'_>>,
        disturbance_box: Option<PyBox<'_>>,
        dtype: &str,
    ) -> PyResult<Self> {
        let method: Method = method.parse().map_err(|e: qp_iter::QpError| {
            InputError::new_err(format!("argument `method`: {e}"))
        })?;
        let single = match dtype {
            "float64" => false,
            "float32" => true,
            other => {
                return Err(InputError::new_err(format!(
                    "argument `dtype` = {other:?}: use \"float64\" or \"float32\""
                )));
            }
        };
        let mut b = MheSettings::builder()
            .horizon(horizon)
            .eta(eta)
            .iterations(k)
            .method(method);
        if let Some(q) = &q {
            b = b.q(&mat_of(q));
        }
        if let Some(r) = &r {
            b = b.r(&mat_of(r));
        }
        if let Some(p) = &p {
            b = b.p(&mat_of(p));
        }
        let prior = slice_of(&prior, "prior")?.to_vec();
        let sys = plant.sys.clone();
        let sets = sets_of(
            &sys,
            state_box.as_ref(),
            output_box.as_ref(),
            disturbance_box.as_ref(),
        )?;
        // P from LMI (2) and the condensed windows: the long part, without the GIL.
        let (settings, mhe, f32) = py.detach(move || -> Result<_, PyErr> {
            let settings = b.build(&sys).map_err(|e| estimator_err(&e))?;
            let mhe = settings
                .estimator(&sys, &sets, &prior)
                .map_err(|e| estimator_err(&e))?;
            let f32 = if single {
                let est = embedded::F32Estimator::new(&mhe, &sys, &prior).map_err(|e| {
                    UnsupportedError::new_err(format!("argument `dtype` = \"float32\": {e}"))
                })?;
                Some(Mutex::new(F32State {
                    est,
                    u: vec![0.0; sys.nu()],
                    y: vec![0.0; sys.ny()],
                }))
            } else {
                None
            };
            Ok((settings, mhe, f32))
        })?;
        let nx = plant.sys.nx();
        Ok(Self {
            mhe: Mutex::new(mhe),
            f32,
            settings,
            nx,
        })
    }

    /// Appends (u_t, y_t) to the window.
    fn push(&self, u: PyReadonlyArray1<'_, f64>, y: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        let (u, y) = (slice_of(&u, "u")?, slice_of(&y, "y")?);
        if let Some(f) = &self.f32 {
            return f.lock().map_err(poisoned)?.push(u, y);
        }
        self.mhe()?.push(u, y).map_err(|e| mhe_err(&e))
    }

    /// x̂_{t|t}: K iterations on the current window (a new array each call; float32 for
    /// `dtype="float32"`).
    fn estimate<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        if let Some(f) = &self.f32 {
            let mut f = f.lock().map_err(poisoned)?;
            return Ok(PyArray1::from_slice(py, f.est.estimate()).into_any());
        }
        let mut mhe = self.mhe()?;
        let x = mhe.estimate().map_err(|e| mhe_err(&e))?;
        Ok(PyArray1::from_slice(py, x).into_any())
    }

    /// x̂_{t|t} written into `out` (length n_x, float64; float32 for `dtype="float32"`): no
    /// allocation per call.
    fn estimate_into(&self, out: &Bound<'_, PyAny>) -> PyResult<()> {
        if let Some(f) = &self.f32 {
            let out = out.cast::<PyArray1<f32>>().map_err(|_| {
                ShapeError::new_err(
                    "argument `out` must be a 1-D float32 array (dtype=\"float32\")",
                )
            })?;
            let mut f = f.lock().map_err(poisoned)?;
            return copy_out(out, f.est.estimate(), self.nx);
        }
        let out = out
            .cast::<PyArray1<f64>>()
            .map_err(|_| ShapeError::new_err("argument `out` must be a 1-D float64 array"))?;
        let mut mhe = self.mhe()?;
        let x = mhe.estimate().map_err(|e| mhe_err(&e))?;
        copy_out(out, x, self.nx)
    }

    /// Wall seconds of `n` calls of `push(u, y)` + `estimate()` made in Rust alone: the
    /// baseline of the per-call overhead benchmark (benches/python/overhead.py).
    fn time_rust_calls(
        &self,
        u: PyReadonlyArray1<'_, f64>,
        y: PyReadonlyArray1<'_, f64>,
        n: usize,
    ) -> PyResult<f64> {
        let (u, y) = (slice_of(&u, "u")?, slice_of(&y, "y")?);
        if let Some(f) = &self.f32 {
            let mut f = f.lock().map_err(poisoned)?;
            let t0 = std::time::Instant::now();
            for _ in 0..n {
                f.push(u, y)?;
                std::hint::black_box(f.est.estimate());
            }
            return Ok(t0.elapsed().as_secs_f64());
        }
        let mut mhe = self.mhe()?;
        let t0 = std::time::Instant::now();
        for _ in 0..n {
            mhe.push(u, y).map_err(|e| mhe_err(&e))?;
            std::hint::black_box(mhe.estimate().map_err(|e| mhe_err(&e))?);
        }
        Ok(t0.elapsed().as_secs_f64())
    }

    /// Restarts at t = 0 with the prior x̄₀ = `prior`.
    fn reset(&self, prior: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        let prior = slice_of(&prior, "prior")?;
        if let Some(f) = &self.f32 {
            let p32: Vec<f32> = prior.iter().map(|x| *x as f32).collect();
            return f
                .lock()
                .map_err(poisoned)?
                .est
                .reset(&p32)
                .map_err(|e| ShapeError::new_err(format!("argument `prior`: {e}")));
        }
        self.mhe()?.reset(prior).map_err(|e| mhe_err(&e))
    }

    /// Time step t (number of pushes since the last reset; the f32 kernel saturates it at
    /// M + 1, as the board's).
    #[getter]
    fn t(&self) -> PyResult<usize> {
        if let Some(f) = &self.f32 {
            return Ok(f.lock().map_err(poisoned)?.est.t());
        }
        Ok(self.mhe()?.t())
    }

    /// The prior weight P in use (from LMI (2) unless given).
    #[getter]
    fn p<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix_py(py, self.mhe()?.config().weights().p.as_ref())
    }

    /// (horizon M, eta, K, method name).
    #[getter]
    fn settings(&self) -> (usize, f64, usize, String) {
        let s = &self.settings;
        (
            s.horizon(),
            s.eta(),
            s.iterations().get(),
            s.method().name().into_owned(),
        )
    }

    /// Test hook: the board's const-size `mhe_embedded::Mhe<f32, 4, 2, 1, 9, 49, 31>` (the
    /// case study's sizes) on this estimator's f32 data from `prior`, fed the rows of `u`
    /// and `y`: x̂ before each push and after the last (steps + 1 rows, float32).
    fn _replay_const_case_study<'py>(
        &self,
        py: Python<'py>,
        prior: PyReadonlyArray1<'_, f64>,
        u: PyReadonlyArray2<'_, f64>,
        y: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let Some(f) = &self.f32 else {
            return Err(UnsupportedError::new_err("dtype=\"float32\" only"));
        };
        let rows = |a: &PyReadonlyArray2<'_, f64>| -> Vec<Vec<f32>> {
            a.as_array()
                .rows()
                .into_iter()
                .map(|r| r.iter().map(|x| *x as f32).collect())
                .collect()
        };
        let pairs: Vec<_> = rows(&u).into_iter().zip(rows(&y)).collect();
        let p32: Vec<f32> = slice_of(&prior, "prior")?
            .iter()
            .map(|x| *x as f32)
            .collect();
        let f = f.lock().map_err(poisoned)?;
        let xs = embedded::replay_const_case_study(f.est.problem(), &p32, &pairs)
            .ok_or_else(|| ShapeError::new_err("not the case study's sizes or a bad pair"))?;
        let flat: Vec<f32> = xs.iter().flatten().copied().collect();
        let arr = PyArray1::from_vec(py, flat);
        arr.reshape([xs.len(), 4])
    }
}

/// Copies `x` into the 1-D array `out` after checking its length against n_x.
fn copy_out<T: numpy::Element + Copy>(
    out: &Bound<'_, PyArray1<T>>,
    x: &[T],
    nx: usize,
) -> PyResult<()> {
    let mut w = out
        .try_readwrite()
        .map_err(|e| InputError::new_err(format!("argument `out`: {e}")))?;
    let dst = w
        .as_slice_mut()
        .map_err(|_| ShapeError::new_err("argument `out` must be a contiguous 1-D array"))?;
    if dst.len() != nx {
        return Err(ShapeError::new_err(format!(
            "argument `out` has length {}, expected n_x = {nx}",
            dst.len()
        )));
    }
    dst.copy_from_slice(x);
    Ok(())
}

/// A validated scenario (`closed_loop::scenario::Scenario`).
#[pyclass(module = "suboptimal_mhe._native", name = "_Scenario", frozen)]
struct PyScenario {
    scenario: Scenario,
}

#[pymethods]
impl PyScenario {
    #[staticmethod]
    fn from_file(path: std::path::PathBuf) -> PyResult<Self> {
        Scenario::from_file(&path)
            .map(|scenario| Self { scenario })
            .map_err(|e| model_err(&e))
    }

    #[staticmethod]
    fn from_toml(text: &str) -> PyResult<Self> {
        Scenario::from_toml_str(text)
            .map(|scenario| Self { scenario })
            .map_err(|e| model_err(&e))
    }

    #[getter]
    fn name(&self) -> String {
        self.scenario.name.clone()
    }

    fn to_toml(&self) -> PyResult<String> {
        self.scenario.to_toml_string().map_err(|e| model_err(&e))
    }

    fn plant(&self) -> Plant {
        Plant {
            sys: self.scenario.plant.clone(),
        }
    }
}

/// The closed-loop certificate of `scenario` as the JSON `cargo xtask reproduce` writes
/// under `certificate` in certificate.json: the same options (`verdict_options` with
/// reproduce's sampling defaults, the four named methods plain and Jacobi-scaled plus the
/// scenario's own), so the numbers are the CLI's.
#[pyfunction]
#[pyo3(signature = (scenario, lipschitz_pairs=200, gamma13_sequences=30, enumeration_max_vars=20, k_max=1 << 24, gamma13=None))]
fn certify_json(
    py: Python<'_>,
    scenario: &PyScenario,
    lipschitz_pairs: usize,
    gamma13_sequences: usize,
    enumeration_max_vars: usize,
    k_max: usize,
    gamma13: Option<f64>,
) -> PyResult<PyCertificate> {
    let sc = scenario.scenario.clone();
    let mhe = sc.mhe.as_ref().ok_or_else(|| {
        ScenarioError::new_err(
            "the scenario has no [mhe] section: add one (horizon, eta, iterations)",
        )
    })?;
    if sc.mpc.is_none() {
        return Err(ScenarioError::new_err(
            "the scenario has no [mpc] section: the closed-loop certificate needs the controller",
        ));
    }
    let mut solvers = CertificateOptions::default().solvers;
    if !solvers.contains(&mhe.method()) {
        solvers.push(mhe.method());
    }
    let verdict = verdict_options(&sc, solvers, gamma13);
    let opts = CertificateOptions {
        lipschitz_pairs,
        gamma13_sequences: if verdict.gamma13 == Gamma13Source::Certified {
            gamma13_sequences
        } else {
            verdict.gamma13_sequences
        },
        enumeration_max_vars,
        k_max,
        ..verdict
    };
    let controller = match sc
        .mpc
        .as_ref()
        .and_then(|m| m.iterations().map(|k| (k, m.method())))
    {
        Some((iterations, method)) => ControllerChoice::SuboptimalMpc { iterations, method },
        None => ControllerChoice::ExactMpc,
    };
    // PyErr is built lazily, so it may be made without the GIL.
    py.detach(move || {
        let resolved = sc.resolve().map_err(|e| loop_err(&e))?;
        let cert = certify_closed_loop(&resolved, &opts).map_err(|e| loop_err(&e))?;
        Ok(PyCertificate {
            held: Held::Scenario {
                resolved: Box::new(resolved),
                cert: Box::new(cert),
                controller,
            },
        })
    })
}

/// One closed-loop run of the scenario (`ScenarioLoop::run`): x (T+1 × n_x), x̂, u, y, w
/// (T rows each) and ‖e_t‖.
#[pyfunction]
#[pyo3(signature = (scenario, steps=None, seed=None, method=None, k=None))]
fn simulate<'py>(
    py: Python<'py>,
    scenario: &PyScenario,
    steps: Option<usize>,
    seed: Option<u64>,
    method: Option<&str>,
    k: Option<usize>,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let sc = scenario.scenario.clone();
    let mut opts = LoopOptions::from_scenario(&sc).map_err(|e| loop_err(&e))?;
    if let Some(steps) = steps {
        if steps == 0 || steps > lti_model::spec::plant::MAX_STEPS {
            return Err(OutOfRangeError::new_err(format!(
                "argument `steps` = {steps} must lie in [1, {}]",
                lti_model::spec::plant::MAX_STEPS
            )));
        }
        opts.steps = steps;
    }
    if let Some(seed) = seed {
        opts.seed = seed;
    }
    if let Some(m) = method {
        opts.method = m.parse().map_err(|e: qp_iter::QpError| {
            InputError::new_err(format!("argument `method`: {e}"))
        })?;
    }
    if let Some(k) = k {
        opts = opts.with_iterations(k).map_err(|e| loop_err(&e))?;
    }
    let out = py.detach(move || -> Result<_, closed_loop::ClosedLoopError> {
        let resolved = sc.resolve()?;
        let mut cl = resolved.build_loop(&opts)?;
        let trace = cl.run()?;
        let n = trace.len();
        let collect = |f: &dyn Fn(usize) -> Option<Vec<f64>>, rows: usize| -> Vec<Vec<f64>> {
            (0..rows).filter_map(f).collect()
        };
        let x = collect(&|t| trace.x(t).map(<[f64]>::to_vec), n + 1);
        let x_hat = collect(&|t| trace.x_hat(t).map(<[f64]>::to_vec), n);
        let u = collect(&|t| trace.u(t).map(<[f64]>::to_vec), n);
        let y = collect(&|t| trace.y(t).map(<[f64]>::to_vec), n);
        let w = collect(&|t| trace.w(t).map(<[f64]>::to_vec), n);
        let e_norm = trace.e_norms()[..n].to_vec();
        // The Kalman baseline of reproduce's trace.csv (xkf, ekf_norm): the standard filter
        // of the MHE's weights run over the same u and y.
        let cfg = resolved.mhe_config()?;
        let sc = resolved.scenario();
        let kalman = closed_loop::baseline::kalman_for_mhe(
            &sc.plant,
            &sc.simulation.prior,
            &cfg.p,
            &cfg.q,
            &cfg.r,
        )
        .map(|mut kf| closed_loop::baseline::run_on_trace(&mut kf, trace));
        Ok((x, x_hat, u, y, w, e_norm, kalman))
    });
    let (x, x_hat, u, y, w, e_norm, kalman) = out.map_err(|e| loop_err(&e))?;
    let d = pyo3::types::PyDict::new(py);
    let arr2 = |rows: &[Vec<f64>], ncols: usize| -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat: Vec<f64> = rows.iter().flatten().copied().collect();
        PyArray1::from_vec(py, flat)
            .reshape([rows.len(), ncols])
            .map_err(|e| MheError::new_err(e.to_string()))
    };
    let sys = &scenario.scenario.plant;
    d.set_item("x", arr2(&x, sys.nx())?)?;
    d.set_item("x_hat", arr2(&x_hat, sys.nx())?)?;
    d.set_item("u", arr2(&u, sys.nu())?)?;
    d.set_item("y", arr2(&y, sys.ny())?)?;
    d.set_item("w", arr2(&w, sys.nw())?)?;
    d.set_item("e_norm", PyArray1::from_vec(py, e_norm))?;
    match kalman {
        Ok(run) => {
            d.set_item("x_kf", arr2(&run.x_hat, sys.nx())?)?;
            d.set_item("e_kf_norm", PyArray1::from_vec(py, run.e_norms))?;
            d.set_item("kalman_error", run.error)?;
        }
        Err(e) => {
            d.set_item("x_kf", arr2(&[], sys.nx())?)?;
            d.set_item("e_kf_norm", PyArray1::from_vec(py, Vec::<f64>::new()))?;
            d.set_item("kalman_error", Some(e.to_string()))?;
        }
    }
    Ok(d)
}

/// The Python argument a Rust item of `LoopModelBuilder::build` / `certify` comes from
/// (`MheBuilder::eta` → `mhe["eta"]`), longest names first so none is cut by a prefix.
const PY_NAMES: [(&str, &str); 27] = [
    ("LoopModelBuilder::disturbance_box", "disturbance_box"),
    ("LoopModelBuilder::initial_state", "x0"),
    ("LoopModelBuilder::output_box", "output_box"),
    ("LoopModelBuilder::state_box", "state_box"),
    ("LoopModelBuilder::input_box", "input_box"),
    ("LoopModelBuilder::prior", "prior"),
    ("LoopModelBuilder::w_bar", "w_bar"),
    ("LoopModelBuilder::mhe", "mhe"),
    ("LoopModelBuilder::mpc", "mpc"),
    ("MheBuilder::iterations", "mhe[\"k\"]"),
    ("MheBuilder::warm_start", "mhe[\"warm_start\"]"),
    ("MheBuilder::horizon", "mhe[\"horizon\"]"),
    ("MheBuilder::method", "mhe[\"method\"]"),
    ("MheBuilder::eta", "mhe[\"eta\"]"),
    ("MheBuilder::q", "mhe[\"q\"]"),
    ("MheBuilder::r", "mhe[\"r\"]"),
    ("MheBuilder::p", "mhe[\"p\"]"),
    ("MpcBuilder::horizon", "mpc[\"horizon\"]"),
    ("MpcBuilder::q", "mpc[\"q\"]"),
    ("MpcBuilder::r", "mpc[\"r\"]"),
    ("CertifyOptions::phase_seconds", "phase_seconds"),
    ("CertifyOptions::gamma13", "gamma13"),
    ("CertifyOptions::methods", "methods"),
    ("LtiSystem::a", "plant.A"),
    ("LtiSystem::b", "plant.B"),
    ("LtiSystem::c", "plant.C"),
    ("LtiSystem", "plant"),
];

/// `text` with the Rust items named as the Python arguments, and the builder-call hints
/// (`.iterations(50)`) as keyword arguments.
fn python_text(text: &str) -> String {
    let mut out = text.to_string();
    for (rust, py) in PY_NAMES {
        out = out.replace(rust, py);
    }
    out = out
        .replace(".mpc_horizon(10)", "mpc_horizon=10")
        .replace(
            ".mhe(MheSettings::builder().horizon(10).eta(0.8).iterations(50))",
            "mhe=dict(horizon=10, eta=0.8, k=50)",
        )
        .replace(".mpc(settings)", "mpc=dict(horizon=10, q=1.0, r=1.0)")
        .replace("vec![Method::PG]", "[\"pg\"]")
        .replace("_box.lower", "_box[0]")
        .replace("_box.upper", "_box[1]");
    python_hint(out)
}

/// A builder-call hint `.name(value)` as the keyword argument `name=value` (K is `k`).
fn python_hint(text: String) -> String {
    let hint = text.split_once("e.g. `.").and_then(|(head, tail)| {
        let (call, rest) = tail.split_once('`')?;
        let (name, value) = call.strip_suffix(')')?.split_once('(')?;
        let name = if name == "iterations" { "k" } else { name };
        Some(format!("{head}e.g. `{name}={value}`{rest}"))
    });
    hint.unwrap_or(text)
}

/// A `ModelBuildError` as the package exception, naming the Python argument.
fn build_err(e: &ModelBuildError) -> PyErr {
    match e {
        ModelBuildError::Invalid { field, problem } => {
            let msg = format!(
                "argument `{}`: {}",
                python_text(field),
                python_text(problem)
            );
            // The kind of the problem, from the checks' own wording.
            if problem.contains("positive definite") || problem.contains("symmetric") {
                NotPositiveDefiniteError::new_err(msg)
            } else if problem.contains("finite") && !problem.contains("finite number") {
                NonFiniteError::new_err(msg)
            } else if problem.contains("shape")
                || problem.contains("entries")
                || problem.contains("dimension")
                || problem.contains("length")
            {
                ShapeError::new_err(msg)
            } else {
                InputError::new_err(msg)
            }
        }
        ModelBuildError::Missing { part, why } => InputError::new_err(format!(
            "argument `{}` is missing: {}",
            python_text(part),
            python_text(why)
        )),
        ModelBuildError::Certificate { problem } => CertificateError::new_err(format!(
            "the certificate could not be computed: {}",
            python_text(problem)
        )),
        other => MheError::new_err(python_text(&other.to_string())),
    }
}

/// A box set (lower, upper) of the Python arguments.
type PyBox<'py> = (PyReadonlyArray1<'py, f64>, PyReadonlyArray1<'py, f64>);

/// A closed loop built from NumPy values (`iss_certificate::LoopModel` through its builder).
#[pyclass(module = "suboptimal_mhe._native", name = "_Model", frozen)]
struct Model {
    model: LoopModel,
}

/// `(lower, upper)` of a box argument as slices.
fn box_of<'a>(b: &'a PyBox<'_>, name: &str) -> PyResult<(&'a [f64], &'a [f64])> {
    Ok((
        slice_of(&b.0, &format!("{name}[0]"))?,
        slice_of(&b.1, &format!("{name}[1]"))?,
    ))
}

#[pymethods]
impl Model {
    #[new]
    #[pyo3(signature = (plant, horizon, eta, k, method, q=None, r=None, p=None,
        mpc_horizon=None, mpc_q=None, mpc_r=None, state_box=None, input_box=None,
        output_box=None, disturbance_box=None, x0=None, prior=None, w_bar=None, name=None))]
    fn new(
        py: Python<'_>,
        plant: &Plant,
        horizon: usize,
        eta: f64,
        k: usize,
        method: &str,
        q: Option<PyReadonlyArray2<'_, f64>>,
        r: Option<PyReadonlyArray2<'_, f64>>,
        p: Option<PyReadonlyArray2<'_, f64>>,
        mpc_horizon: Option<usize>,
        mpc_q: Option<PyReadonlyArray2<'_, f64>>,
        mpc_r: Option<PyReadonlyArray2<'_, f64>>,
        state_box: Option<PyBox<'_>>,
        input_box: Option<PyBox<'_>>,
        output_box: Option<PyBox<'_>>,
        disturbance_box: Option<PyBox<'_>>,
        x0: Option<PyReadonlyArray1<'_, f64>>,
        prior: Option<PyReadonlyArray1<'_, f64>>,
        w_bar: Option<f64>,
        name: Option<&str>,
    ) -> PyResult<Self> {
        let method: Method = method.parse().map_err(|e: qp_iter::QpError| {
            InputError::new_err(format!("argument `mhe[\"method\"]`: {e}"))
        })?;
        let mut mhe = MheSettings::builder()
            .horizon(horizon)
            .eta(eta)
            .iterations(k)
            .method(method);
        if let Some(q) = &q {
            mhe = mhe.q(&mat_of(q));
        }
        if let Some(r) = &r {
            mhe = mhe.r(&mat_of(r));
        }
        if let Some(p) = &p {
            mhe = mhe.p(&mat_of(p));
        }
        let mut b = LoopModel::builder(plant.sys.clone()).mhe(mhe);
        if let Some(name) = name {
            b = b.name(name);
        }
        if let Some(s) = &state_box {
            let (l, u) = box_of(s, "state_box")?;
            b = b.state_box(l, u);
        }
        if let Some(s) = &input_box {
            let (l, u) = box_of(s, "input_box")?;
            b = b.input_box(l, u);
        }
        if let Some(s) = &output_box {
            let (l, u) = box_of(s, "output_box")?;
            b = b.output_box(l, u);
        }
        if let Some(s) = &disturbance_box {
            let (l, u) = box_of(s, "disturbance_box")?;
            b = b.disturbance_box(l, u);
        }
        if let Some(x0) = &x0 {
            b = b.initial_state(slice_of(x0, "x0")?);
        }
        if let Some(prior) = &prior {
            b = b.prior(slice_of(prior, "prior")?);
        }
        if let Some(w) = w_bar {
            b = b.w_bar(w);
        }
        if let Some(n) = mpc_horizon {
            if mpc_q.is_none() && mpc_r.is_none() {
                b = b.mpc_horizon(n);
            } else {
                let rows = |m: &PyReadonlyArray2<'_, f64>| {
                    MatrixSpec::Rows(lti_model::matrix::to_rows(mat_of(m).as_ref()))
                };
                let raw = RawMpc {
                    horizon: Some(n),
                    q: mpc_q.as_ref().map(rows),
                    r: mpc_r.as_ref().map(rows),
                    ..Default::default()
                };
                let settings = MpcSettings::from_raw(&raw, &plant.sys).map_err(|e| match e {
                    ModelError::Scenario { key, problem } => {
                        let arg = key.strip_prefix("mpc.").unwrap_or(&key);
                        InputError::new_err(format!("argument `mpc[\"{arg}\"]`: {problem}"))
                    }
                    other => model_err(&other),
                })?;
                b = b.mpc(settings.to_builder());
            }
        }
        // LMI (2) for P and the MPC's Riccati equation: the long part, without the GIL.
        let model = py.detach(move || b.build()).map_err(|e| build_err(&e))?;
        Ok(Self { model })
    }

    /// K, the MHE's iterations per step.
    #[getter]
    fn k(&self) -> usize {
        self.model.iterations()
    }

    /// w̄: the given bound, else the largest ‖w‖₂ over 𝒲 (None when 𝒲 is unbounded).
    #[getter]
    fn w_bar(&self) -> Option<f64> {
        self.model.w_bar()
    }

    /// The model as a validated scenario (for `simulate` and `to_toml`).
    fn scenario(&self) -> PyScenario {
        PyScenario {
            scenario: self.model.scenario().clone(),
        }
    }
}

/// A certificate and what its verdicts need.
#[derive(Debug)]
enum Held {
    /// Of a `_Model`: `iss_certificate::Certificate`.
    Model(Box<Certificate>),
    /// Of a scenario, with reproduce's options: the verdict is `coverage::verdict` on it,
    /// as reproduce's `at_scenario`.
    Scenario {
        resolved: Box<ResolvedScenario>,
        cert: Box<ClosedLoopCertificate>,
        controller: ControllerChoice,
    },
}

/// The closed-loop certificate: its JSON and the verdict at any (method, K).
#[pyclass(module = "suboptimal_mhe._native", name = "_Certificate", frozen)]
struct PyCertificate {
    held: Held,
}

#[pymethods]
impl PyCertificate {
    /// The serde JSON of the closed-loop certificate (certificate.json's `certificate`).
    fn json(&self) -> PyResult<String> {
        let cert = match &self.held {
            Held::Model(c) => c.closed_loop(),
            Held::Scenario { cert, .. } => cert,
        };
        // Through the versioned schema the CLI writes (`certificate_json::v1`).
        let v1 = certificate_json::v1::ClosedLoopCertificate::from(cert);
        serde_json::to_string(&v1).map_err(|e| MheError::new_err(e.to_string()))
    }

    /// Every void, IOSS and skip reason as typed data (JSON: `reasons::all`).
    fn reasons_json(&self) -> PyResult<String> {
        let cert = match &self.held {
            Held::Model(c) => c.closed_loop(),
            Held::Scenario { cert, .. } => cert,
        };
        serde_json::to_string(&reasons::all(cert)).map_err(|e| MheError::new_err(e.to_string()))
    }

    /// K_glob of the global loop certificate for `method` (`coverage::global_of` with the
    /// controller the verdict uses): every K ≥ it is certified; None when there is none.
    fn k_glob(&self, method: &str) -> PyResult<Option<usize>> {
        let method: Method = method.parse().map_err(|e: qp_iter::QpError| {
            InputError::new_err(format!("argument `method`: {e}"))
        })?;
        Ok(match &self.held {
            Held::Model(c) => c.k_glob(method),
            Held::Scenario {
                cert, controller, ..
            } => coverage::global_of(cert, method, *controller).and_then(|g| g.exact.k_glob()),
        })
    }

    /// K_chain of `method` under the iteration chain (Theorem L3b; pg, fista and their Jacobi variants, f64): the
    /// smallest K the chain checked and certified; it covers only the K it checked.
    fn k_chain(&self, method: &str) -> PyResult<Option<usize>> {
        let method: Method = method.parse().map_err(|e: qp_iter::QpError| {
            InputError::new_err(format!("argument `method`: {e}"))
        })?;
        Ok(match &self.held {
            Held::Model(c) => c.k_chain(method),
            Held::Scenario {
                cert, controller, ..
            } => coverage::global_of(cert, method, *controller).and_then(|g| g.k_chain()),
        })
    }

    /// The one verdict rule at (method, k) in `scalar` ("f64" or "f32") as JSON
    /// (`PairVerdict`): `coverage::verdict` (behind `Certificate::verdict` for a model), f32
    /// folding the rounding model into Theorem 1.
    #[pyo3(signature = (method, k, scalar="f64"))]
    fn verdict(&self, method: &str, k: usize, scalar: &str) -> PyResult<String> {
        let method: Method = method.parse().map_err(|e: qp_iter::QpError| {
            InputError::new_err(format!("argument `method`: {e}"))
        })?;
        let scalar = match scalar {
            "f64" | "float64" => Scalar::F64,
            "f32" | "float32" => Scalar::F32,
            other => {
                return Err(InputError::new_err(format!(
                    "argument `scalar` = {other:?}: use \"f64\" or \"f32\""
                )));
            }
        };
        let v = match &self.held {
            Held::Model(c) if scalar == Scalar::F64 => c.verdict(method, k),
            Held::Model(c) => {
                let resolved = c.model().resolved();
                // The model's controller, as `LoopModelBuilder::build` chose it.
                let controller = match resolved.scenario().mpc.as_ref() {
                    Some(m) => match m.iterations() {
                        Some(iterations) => ControllerChoice::SuboptimalMpc {
                            iterations,
                            method: m.method(),
                        },
                        None => ControllerChoice::ExactMpc,
                    },
                    None => ControllerChoice::ExactMpc,
                };
                let config = Configuration {
                    method,
                    k_e: k,
                    controller,
                    scalar,
                };
                coverage::verdict(resolved, c.closed_loop(), &config)
            }
            Held::Scenario {
                resolved,
                cert,
                controller,
            } => {
                let config = Configuration {
                    method,
                    k_e: k,
                    controller: *controller,
                    scalar,
                };
                coverage::verdict(resolved, cert, &config)
            }
        };
        let v1 = certificate_json::v1::PairVerdict::from(&v);
        serde_json::to_string(&v1).map_err(|e| MheError::new_err(e.to_string()))
    }
}

/// `iss_certificate::certify(model, options)`: Theorem 1 for `methods` with the options of
/// every command's verdicts (`CertifyOptions`).
#[pyfunction]
#[pyo3(signature = (model, methods=None, gamma13=None, phase_seconds=None, seed=0))]
fn certify_model(
    py: Python<'_>,
    model: &Model,
    methods: Option<Vec<String>>,
    gamma13: Option<f64>,
    phase_seconds: Option<f64>,
    seed: u64,
) -> PyResult<PyCertificate> {
    let mut opts = CertifyOptions::default().with_seed(seed);
    if let Some(names) = methods {
        let parsed = names
            .iter()
            .map(|m| m.parse::<Method>())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| InputError::new_err(format!("argument `methods`: {e}")))?;
        opts = opts.with_methods(parsed);
    }
    if let Some(g) = gamma13 {
        opts = opts.with_gamma13(g);
    }
    if let Some(s) = phase_seconds {
        opts = opts.with_phase_seconds(s);
    }
    let model = model.model.clone();
    let cert = py
        .detach(move || certify(&model, &opts))
        .map_err(|e| build_err(&e))?;
    Ok(PyCertificate {
        held: Held::Model(Box::new(cert)),
    })
}

/// Chooses the dense kernel every estimator, certificate and simulation of this process
/// builds from now on: `"portable"` (bit for bit what `mhe-embedded`, the exported C and
/// `QP_ITER_KERNEL=portable cargo xtask …` compute), `"avx2+fma"` or `"auto"` (the fastest
/// the CPU supports, the default). The library never reads the environment: the package
/// reads `QP_ITER_KERNEL` once at import and calls this.
#[pyfunction]
fn set_kernel(name: &str) -> PyResult<()> {
    use qp_iter::kernel::{Kernel, KernelPath, set_global_kernel};
    let path = match name.trim() {
        "" | "auto" => {
            set_global_kernel(Kernel::detect());
            return Ok(());
        }
        "portable" => KernelPath::Portable,
        "avx2+fma" | "avx2" => KernelPath::Avx2Fma,
        other => {
            return Err(OutOfRangeError::new_err(format!(
                "argument `name`: `{other}` is not a kernel; use \"portable\", \"avx2+fma\" or \"auto\""
            )));
        }
    };
    match Kernel::with_path(path) {
        Some(k) => {
            set_global_kernel(k);
            Ok(())
        }
        None => Err(UnsupportedError::new_err(format!(
            "argument `name`: this CPU cannot run the {} kernel; use \"portable\" or \"auto\"",
            path.name()
        ))),
    }
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("MheError", py.get_type::<MheError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("ShapeError", py.get_type::<ShapeError>())?;
    m.add("NonFiniteError", py.get_type::<NonFiniteError>())?;
    m.add(
        "NotPositiveDefiniteError",
        py.get_type::<NotPositiveDefiniteError>(),
    )?;
    m.add("OutOfRangeError", py.get_type::<OutOfRangeError>())?;
    m.add("ScenarioError", py.get_type::<ScenarioError>())?;
    m.add("CertificateError", py.get_type::<CertificateError>())?;
    m.add("NumericalError", py.get_type::<NumericalError>())?;
    m.add("UnsupportedError", py.get_type::<UnsupportedError>())?;
    m.add("MAX_DIMENSION", lti_model::spec::MAX_DIMENSION)?;
    m.add("MAX_STEPS", lti_model::spec::plant::MAX_STEPS)?;
    m.add_class::<Plant>()?;
    m.add_class::<Estimator>()?;
    m.add_class::<PyScenario>()?;
    m.add_class::<Model>()?;
    m.add_class::<PyCertificate>()?;
    m.add_function(wrap_pyfunction!(certify_model, m)?)?;
    m.add_function(wrap_pyfunction!(certify_json, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(set_kernel, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep_run, m)?)?;
    m.add_function(wrap_pyfunction!(export::export_artefact, m)?)?;
    Ok(())
}
