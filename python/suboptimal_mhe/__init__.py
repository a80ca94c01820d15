"""suboptimal_mhe: the certified fixed-iteration moving horizon estimator from Python.

NumPy in and out; the numbers are computed by the Rust workspace (the same functions as
``cargo xtask``), so a certificate here equals the CLI's ``certificate.json`` key by key.

Quick start (a double integrator measured in position, sampled at 0.1 s)::

    import numpy as np, suboptimal_mhe as sm
    plant = sm.Plant(A=[[1, .1], [0, 1]], B=[[.005], [.1]], C=[[1, 0]])
    est = sm.Estimator(plant, horizon=10, eta=0.8, k=20, method="admm")
    x_hat = est.estimate()            # x̂_{0|0} = the prior
    est.push(u=[0.0], y=[1.02])       # u_0, y_0
    x_hat = est.estimate()            # x̂_{1|1} after K = 20 ADMM iterations

Every error is a subclass of :class:`MheError` (itself a ``ValueError``) whose message names
the argument and the fix; arguments are checked before anything large is allocated.
"""

from __future__ import annotations

import json
import math
import os
from typing import Any, Dict, List, Optional

import numpy as np

from . import _native
from ._native import (
    CertificateError,
    InputError,
    MheError,
    NonFiniteError,
    NotPositiveDefiniteError,
    NumericalError,
    OutOfRangeError,
    ScenarioError,
    ShapeError,
    UnsupportedError,
)

__all__ = [
    "Plant",
    "Estimator",
    "Scenario",
    "Model",
    "Certificate",
    "Reason",
    "certify",
    "simulate",
    "set_kernel",
    "sweep",
    "export",
    "MheError",
    "InputError",
    "ShapeError",
    "NonFiniteError",
    "NotPositiveDefiniteError",
    "OutOfRangeError",
    "ScenarioError",
    "CertificateError",
    "NumericalError",
    "UnsupportedError",
    "MAX_DIMENSION",
    "METHODS",
]


def set_kernel(name: str) -> None:
    """Choose the dense kernel of every estimator, certificate and simulation built afterwards.

    ``"portable"`` computes bit for bit what the embedded crate, the exported C and
    ``QP_ITER_KERNEL=portable cargo xtask ...`` compute; ``"avx2+fma"`` the x86-64 intrinsics;
    ``"auto"`` the fastest the CPU supports (the default). At import the package applies
    ``$QP_ITER_KERNEL`` if it is set (the Rust library itself never reads the environment).
    Raises ``OutOfRangeError`` for an unknown name, ``UnsupportedError`` for a kernel this CPU
    cannot run.
    """
    _native.set_kernel(name)


if os.environ.get("QP_ITER_KERNEL"):
    set_kernel(os.environ["QP_ITER_KERNEL"])

#: Largest plant dimension accepted (n_x, n_u, n_y, n_w), as for a scenario file.
MAX_DIMENSION: int = _native.MAX_DIMENSION
#: The named methods Φ (each also with the suffix ``-jacobi``: the Jacobi-scaled problem).
METHODS = ("pg", "fista", "admm", "admm-pr")
#: float64 (NumPy's builtin dtypes are singletons: `dtype is _F64` is the cheap check).
_F64 = np.dtype(np.float64)


# --------------------------------------------------------------------------------------
# Argument checks: cheap, before any Rust call (so before anything large is allocated).
# --------------------------------------------------------------------------------------


def _matrix(name: str, value: Any, rows: Optional[int] = None, cols: Optional[int] = None) -> np.ndarray:
    """`value` as a finite float64 2-D array (a scalar is 1x1), shape-checked."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InputError(f"argument `{name}` is not a numeric array ({e}); pass a 2-D array of floats") from None
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    if arr.ndim != 2:
        raise ShapeError(f"argument `{name}` has {arr.ndim} dimensions, expected a 2-D array (a matrix)")
    r, c = arr.shape
    if (rows is not None and r != rows) or (cols is not None and c != cols):
        want = f"{rows if rows is not None else 'any'}x{cols if cols is not None else 'any'}"
        raise ShapeError(f"argument `{name}` has shape {r}x{c}, expected {want}")
    if max(r, c) > MAX_DIMENSION:
        raise ShapeError(
            f"argument `{name}` has shape {r}x{c}, above the supported maximum dimension {MAX_DIMENSION}"
        )
    _finite(name, arr)
    return np.ascontiguousarray(arr)


def _vector(name: str, value: Any, length: int) -> np.ndarray:
    """`value` as a finite float64 1-D array of `length` entries (a scalar is length 1)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InputError(f"argument `{name}` is not a numeric vector ({e})") from None
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        arr = arr.reshape(-1) if arr.size == length else arr
    if arr.ndim != 1 or arr.shape[0] != length:
        raise ShapeError(f"argument `{name}` has shape {arr.shape}, expected a vector of length {length}")
    _finite(name, arr)
    return np.ascontiguousarray(arr)


def _finite(name: str, arr: np.ndarray) -> None:
    if np.isfinite(arr).all():
        return
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        idx = tuple(int(i) for i in bad[0])
        raise NonFiniteError(
            f"argument `{name}` has a non-finite entry {arr[idx]} at index {idx}; all entries must be finite"
        )


def _weight(name: str, value: Any, n: int) -> np.ndarray:
    """A symmetric positive definite n x n weight; a scalar s means s·I."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InputError(f"argument `{name}` is not a numeric matrix ({e}); pass {n}x{n} floats or a scalar") from None
    if arr.ndim == 0:
        _finite(name, arr.reshape(1))
        arr = float(arr) * np.eye(n)
    arr = _matrix(name, arr, n, n)
    asym = float(np.max(np.abs(arr - arr.T))) if n else 0.0
    if asym > 1e-12 * max(1.0, float(np.max(np.abs(arr)))):
        raise NotPositiveDefiniteError(
            f"argument `{name}` is not symmetric (max |M - M^T| = {asym:.3e}); pass a symmetric matrix"
        )
    lam = float(np.linalg.eigvalsh(arr)[0])
    if not lam > 0.0:
        raise NotPositiveDefiniteError(
            f"argument `{name}` is not positive definite (smallest eigenvalue {lam:.3e}); "
            "use a symmetric matrix with positive eigenvalues"
        )
    return arr


def _positive_int(name: str, value: Any, hint: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"argument `{name}` must be an int, got {type(value).__name__}; {hint}")
    if value < 1:
        raise OutOfRangeError(f"argument `{name}` = {value} is out of range: must be >= 1; {hint}")
    return int(value)


def _eta(value: Any) -> float:
    try:
        eta = float(value)
    except (TypeError, ValueError):
        raise InputError(f"argument `eta` must be a number in [0, 1), got {value!r}") from None
    if not math.isfinite(eta):
        raise NonFiniteError(f"argument `eta` = {eta} is not finite; eta must lie in [0, 1), e.g. 0.8")
    if not 0.0 <= eta < 1.0:
        raise OutOfRangeError(
            f"argument `eta` = {eta} is out of range: must lie in [0, 1) (Assumption 2); pick e.g. 0.8"
        )
    return eta


# --------------------------------------------------------------------------------------
# Models
# --------------------------------------------------------------------------------------


class Plant:
    """The plant x_{t+1} = A x_t + B u_t + E w¹_t, y_t = C x_t + F w²_t (eq. (1) of the paper).

    ``E`` defaults to I (w¹ enters every state) and ``F`` to I (w² every output), the paper's
    structure. Matrices are array-likes of floats, in the plant's own units; a scalar is 1x1.
    An empty input (n_u = 0) is ``B=np.zeros((n_x, 0))``.
    """

    def __init__(self, A: Any, B: Any, C: Any, E: Any = None, F: Any = None) -> None:
        a = _matrix("A", A)
        nx = a.shape[0]
        a = _matrix("A", a, nx, nx)
        b = _matrix("B", B, nx, None)
        c = _matrix("C", C, None, nx)
        ny = c.shape[0]
        e = np.eye(nx) if E is None else _matrix("E", E, nx, None)
        f = np.eye(ny) if F is None else _matrix("F", F, ny, None)
        self._native = _native._Plant(a, b, c, e, f)

    @classmethod
    def _wrap(cls, native: Any) -> "Plant":
        obj = cls.__new__(cls)
        obj._native = native
        return obj

    @property
    def nx(self) -> int:
        """State dimension n_x."""
        return self._native.dims[0]

    @property
    def nu(self) -> int:
        """Input dimension n_u."""
        return self._native.dims[1]

    @property
    def ny(self) -> int:
        """Output dimension n_y."""
        return self._native.dims[2]

    @property
    def nw(self) -> int:
        """Disturbance dimension n_w = n_w1 + n_w2 (w = (w¹, w²))."""
        d = self._native.dims
        return d[3] + d[4]

    @property
    def A(self) -> np.ndarray:
        return self._native.matrix("A")

    @property
    def B(self) -> np.ndarray:
        return self._native.matrix("B")

    @property
    def C(self) -> np.ndarray:
        return self._native.matrix("C")

    @property
    def E(self) -> np.ndarray:
        return self._native.matrix("E")

    @property
    def F(self) -> np.ndarray:
        return self._native.matrix("F")

    def __repr__(self) -> str:
        return f"Plant(nx={self.nx}, nu={self.nu}, ny={self.ny}, nw={self.nw})"


class Estimator:
    """Alg. 1: the MHE with exactly ``k`` iterations of ``method`` per time step.

    ``horizon`` is M (steps), ``eta`` the decay rate η ∈ [0, 1) of LMI (2), ``q`` (n_w x n_w)
    and ``r`` (n_y x n_y) the stage weights (default I; a scalar s means s·I), ``p`` the prior
    weight (default: computed from LMI (2), the certified prior weight of Assumption 2),
    ``prior`` the initial prior x̄₀ (default 0). ``method`` is one of :data:`METHODS`,
    optionally with ``-jacobi``.

    Per step: ``est.estimate()`` returns x̂_{t|t} from the data up to t − 1, then
    ``est.push(u_t, y_t)``, the same order as ``mhe_core::MheEstimator`` (do-mpc's
    ``make_step`` is ``push`` followed by ``estimate``).

    ``state_box``, ``output_box`` and ``disturbance_box`` are the sets 𝒳 (n_x), 𝒴 (n_y)
    and 𝒲 (n_w = n_w1 + n_w2: the process then the measurement noise) as pairs
    ``(lower, upper)`` (±inf allowed; default: the whole space). 𝒲 and the x̂₀ part of 𝒳
    are boxes of the QP; 𝒳 at the later stages and 𝒴 become general rows of the QP
    (``mhe_core::MheSets``). ``state_rows``, ``output_rows`` and ``disturbance_rows`` give
    the same sets as general rows ``(G, h)``, {v : G v ≤ h}, intersected with the box: a row
    with one nonzero entry is a bound; a row coupling components raises
    :class:`UnsupportedError` (the library's sets are boxes; docs/python.md).

    ``dtype="float32"`` runs the microcontroller's single-precision kernel
    (``mhe_embedded``: the same data as ``cargo xtask export --scalar f32`` writes, rounded
    once, and the same operations in the same order), so the estimates are the board's bits;
    they are float32 arrays. It covers the methods the board runs — ``pg``, ``fista``,
    ``admm``, ``admm-pr``, plain or ``-jacobi`` — on box sets only (no ``state_box``/``output_box``, which
    make general rows) and unstructured windows; anything else raises
    :class:`UnsupportedError`. ``u`` and ``y`` are rounded to float32 once per push. Whether
    K is certified in f32 is ``Certificate.verdict(method, k, scalar="f32")`` (Theorem 1 with
    the f32 rounding folded in).
    """

    def __init__(
        self,
        model: Plant,
        horizon: int,
        eta: float,
        k: int,
        method: str = "pg",
        q: Any = None,
        r: Any = None,
        p: Any = None,
        prior: Any = None,
        dtype: Any = "float64",
        state_box: Any = None,
        output_box: Any = None,
        disturbance_box: Any = None,
        state_rows: Any = None,
        output_rows: Any = None,
        disturbance_rows: Any = None,
    ) -> None:
        if not isinstance(model, Plant):
            raise InputError(f"argument `model` must be a suboptimal_mhe.Plant, got {type(model).__name__}")
        if isinstance(dtype, str) and dtype in ("float64", "float32"):
            pass
        elif dtype is np.float64 or dtype is np.float32:
            dtype = np.dtype(dtype).name
        else:
            raise InputError(f"argument `dtype` = {dtype!r}: use \"float64\" or \"float32\"")
        horizon = _positive_int("horizon", horizon, "the horizon M is a number of steps, e.g. 10")
        k = _positive_int("k", k, "K is the number of iterations per step, e.g. 20")
        eta = _eta(eta)
        if not isinstance(method, str):
            raise InputError(f"argument `method` must be a str, one of {METHODS} (optionally with -jacobi)")
        self.model = model
        nx, ny, nw = model.nx, model.ny, model.nw
        qm = None if q is None else _weight("q", q, nw)
        rm = None if r is None else _weight("r", r, ny)
        pm = None if p is None else _weight("p", p, nx)
        x0 = np.zeros(nx) if prior is None else _vector("prior", prior, nx)
        sb = _set("state_box", state_box, "state_rows", state_rows, nx, origin=False)
        ob = _set("output_box", output_box, "output_rows", output_rows, ny, origin=False)
        db = _set("disturbance_box", disturbance_box, "disturbance_rows", disturbance_rows, nw, origin=False)
        self.dtype = np.dtype(dtype)
        self._native = _native._Estimator(
            model._native, horizon, eta, k, method, x0, q=qm, r=rm, p=pm,
            state_box=sb, output_box=ob, disturbance_box=db, dtype=self.dtype.name,
        )

    def push(self, u: Any, y: Any) -> None:
        """Appends the input u_t (length n_u) and the measurement y_t (length n_y)."""
        if type(u) is np.ndarray and type(y) is np.ndarray and u.dtype is _F64 and y.dtype is _F64:
            try:
                # Contiguous 1-D float64 arrays go straight to Rust, which checks their
                # length and finiteness before changing anything (docs/python.md, overhead).
                self._native.push(u, y)
                return
            except (TypeError, ShapeError):
                pass  # another dtype, strides or a wrong length: the checked path below
        # Lists, scalars, other arrays: converted and checked here, so an error names the
        # argument and its expected shape.
        self._native.push(_vector("u", u, self.model.nu), _vector("y", y, self.model.ny))

    def estimate(self, out: Optional[np.ndarray] = None) -> np.ndarray:
        """x̂_{t|t} (length n_x): K iterations on the current window.

        With ``out`` (an array of length n_x of the estimator's dtype) the estimate is
        written into it and ``out`` is returned: no allocation per call.
        """
        if out is None:
            return self._native.estimate()
        self._native.estimate_into(out)
        return out

    def reset(self, prior: Any = None) -> None:
        """Restarts at t = 0 with the prior x̄₀ = ``prior`` (default 0)."""
        nx = self.model.nx
        self._native.reset(np.zeros(nx) if prior is None else _vector("prior", prior, nx))

    @property
    def t(self) -> int:
        """Time step t: the number of pushes since construction or the last reset."""
        return self._native.t

    @property
    def P(self) -> np.ndarray:
        """The prior weight P in use (from LMI (2) unless given)."""
        return self._native.p

    def __repr__(self) -> str:
        m, eta, k, method = self._native.settings
        return f"Estimator(horizon={m}, eta={eta}, k={k}, method={method!r}, t={self.t})"


class Scenario:
    """A validated scenario (the TOML format of ``scenarios/*.toml``, docs/scenario-format.md)."""

    def __init__(self, native: Any) -> None:
        self._native = native

    @classmethod
    def from_file(cls, path: "os.PathLike[str] | str") -> "Scenario":
        """Reads and validates a scenario file (at most 16 MiB)."""
        return cls(_native._Scenario.from_file(os.fspath(path)))

    @classmethod
    def from_toml(cls, text: str) -> "Scenario":
        """Parses and validates a scenario from TOML text."""
        if not isinstance(text, str):
            raise InputError("argument `text` must be a str of TOML")
        return cls(_native._Scenario.from_toml(text))

    @property
    def name(self) -> str:
        return self._native.name

    @property
    def plant(self) -> Plant:
        return Plant._wrap(self._native.plant())

    def to_toml(self) -> str:
        """The canonical TOML: every default explicit (parses back to an equal scenario)."""
        return self._native.to_toml()

    def __repr__(self) -> str:
        return f"Scenario(name={self.name!r})"


def _scenario(s: Any) -> Scenario:
    if isinstance(s, Scenario):
        return s
    if isinstance(s, Model):
        return s.scenario
    if isinstance(s, (str, os.PathLike)):
        return Scenario.from_file(s)
    raise InputError(
        f"argument `scenario` must be a Scenario or a path to a scenario file, got {type(s).__name__}"
    )


_MHE_KEYS = ("horizon", "eta", "k", "method", "q", "r", "p")
_MPC_KEYS = ("horizon", "q", "r")


def _box(name: str, value: Any, n: int) -> Optional[tuple]:
    """A box argument ``(lower, upper)``: two float64 vectors of length n (±inf allowed)."""
    if value is None:
        return None
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise InputError(f"argument `{name}` must be a pair (lower, upper) of length-{n} vectors")
    out = []
    for i, v in enumerate(value):
        try:
            arr = np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise InputError(f"argument `{name}[{i}]` is not a numeric vector ({e})") from None
        arr = arr.reshape(1) if arr.ndim == 0 else arr
        if arr.ndim != 1 or arr.shape[0] != n:
            raise ShapeError(f"argument `{name}[{i}]` has shape {arr.shape}, expected a vector of length {n}")
        if np.any(np.isnan(arr)):
            raise NonFiniteError(f"argument `{name}[{i}]` has a NaN entry; bounds are numbers or ±inf")
        out.append(np.ascontiguousarray(arr))
    return (out[0], out[1])


#: Why a row coupling two components is refused (the sets of the library are boxes).
_COUPLED_WHY = (
    "the library's sets 𝒳, 𝒰, 𝒴, 𝒲 are boxes (mhe_core::MheSets, the MPC's input box, a "
    "scenario's [sets]): a bounded 𝒳 or 𝒴 becomes general rows of the QPs, one per bounded "
    "component, but a row coupling components has no place in the estimator's QP nor in the "
    "certificate (L_Φ of Lemma 1, L_π and γ₁,₃ are derived for boxes and those rows)"
)


def _rows(name: str, value: Any, n: int) -> tuple:
    """General rows ``(G, h)`` — {v : G v ≤ h}, G p x n — or ``(G, lower, upper)`` —
    {v : lower ≤ G v ≤ upper} — as the box they describe.

    A row with one nonzero entry g at component j bounds v_j ≤ h/g (g > 0) or v_j ≥ h/g
    (g < 0; h/g rounded once); a zero row is 0 ≤ h (redundant, or an empty set refused).
    A row with two or more nonzero entries raises :class:`UnsupportedError` saying why.
    """
    if not isinstance(value, (tuple, list)) or len(value) not in (2, 3):
        raise InputError(
            f"argument `{name}` must be a pair (G, h) meaning G v <= h, G a p x {n} matrix and h a "
            "length-p vector, or a triple (G, lower, upper) meaning lower <= G v <= upper"
        )
    g = _matrix(f"{name}[0]", value[0], cols=n)
    rows = g.shape[0]
    bounds = []
    for k in range(1, len(value)):
        try:
            b = np.asarray(value[k], dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise InputError(f"argument `{name}[{k}]` is not a numeric vector ({e})") from None
        b = b.reshape(1) if b.ndim == 0 else b
        if b.ndim != 1 or b.shape[0] != g.shape[0]:
            raise ShapeError(
                f"argument `{name}[{k}]` has shape {b.shape}, expected a vector of length {g.shape[0]} (one bound per row of G)"
            )
        if np.any(np.isnan(b)):
            raise NonFiniteError(f"argument `{name}[{k}]` has a NaN entry; bounds are numbers or ±inf (no bound)")
        bounds.append(b)
    if len(bounds) == 1:
        h = bounds[0]
    else:
        # lower <= G v <= upper (scipy's LinearConstraint, python-control's constraints) as
        # G v <= upper and -G v <= -lower.
        g, h = np.vstack([g, -g]), np.concatenate([bounds[1], -bounds[0]])
    lower, upper = np.full(n, -np.inf), np.full(n, np.inf)
    for i in range(g.shape[0]):
        if h[i] == np.inf:
            continue  # no bound: not a constraint, whatever the row couples
        nz = np.flatnonzero(g[i])
        if nz.size > 1:
            raise UnsupportedError(
                f"argument `{name}`: row {i % rows} of G couples components {nz.tolist()}; {_COUPLED_WHY}. "
                "Fix: give rows with one nonzero entry each (bounds), e.g. the bounding box of the "
                "polytope (a larger set: the certificate then holds for it)"
            )
        if nz.size == 0:
            if not h[i] >= 0.0:
                raise InputError(
                    f"argument `{name}`: row {i % rows} of G is zero and its bound excludes 0 (0 <= {h[i]} fails), "
                    "so the set is empty"
                )
            continue
        j = int(nz[0])
        bound = h[i] / g[i, j]
        if g[i, j] > 0.0:
            upper[j] = min(upper[j], bound)
        else:
            lower[j] = max(lower[j], bound)
    return lower, upper


def _set(box_name: str, box: Any, rows_name: str, rows: Any, n: int, origin: bool) -> Optional[tuple]:
    """The box of ``box`` ∩ ``rows`` (either may be None); ``origin``: the set must contain 0
    (Assumption 1, checked here so the message names the rows argument)."""
    b = _box(box_name, box, n)
    if rows is None:
        return b
    lower, upper = _rows(rows_name, rows, n)
    if b is not None:
        lower, upper = np.maximum(lower, b[0]), np.minimum(upper, b[1])
    what = rows_name if b is None else f"{box_name}` with `{rows_name}"
    empty = np.flatnonzero(~(lower <= upper) | (lower == np.inf) | (upper == -np.inf))
    if empty.size:
        j = int(empty[0])
        raise InputError(
            f"argument `{what}`: the set is empty (component {j}: {lower[j]} <= v <= {upper[j]}); loosen a bound"
        )
    outside = np.flatnonzero((lower > 0.0) | (upper < 0.0))
    if origin and outside.size:
        j = int(outside[0])
        raise InputError(
            f"argument `{what}`: the set must contain 0 (Assumption 1) but component {j} lies in "
            f"[{lower[j]}, {upper[j]}]; shift the coordinates or loosen the bound"
        )
    return np.ascontiguousarray(lower), np.ascontiguousarray(upper)


def _settings(name: str, value: Any, keys: tuple, required: tuple) -> Dict[str, Any]:
    if not isinstance(value, dict):
        raise InputError(f"argument `{name}` must be a dict with keys {keys}, e.g. dict(horizon=10, eta=0.8, k=50)")
    unknown = sorted(set(value) - set(keys))
    if unknown:
        raise InputError(f"argument `{name}` has unknown keys {unknown}; the keys are {keys}")
    missing = [k for k in required if value.get(k) is None]
    if missing:
        raise InputError(f"argument `{name}` lacks {missing}; e.g. dict(horizon=10, eta=0.8, k=50)")
    return value


class Model:
    """A closed loop from NumPy values: the plant, the sets, the MHE, the MPC and w̄.

    Built by ``iss_certificate::LoopModel::builder`` with the checks of a scenario file, so
    ``certify(model)`` equals the certificate of the same values written as a TOML scenario.

    ``mhe`` is a dict: ``horizon`` (M, steps), ``eta`` (η ∈ [0, 1)), ``k`` (K, iterations
    per step), ``method`` (default ``"pg"``, one of :data:`METHODS`, optionally
    ``-jacobi``), ``q`` (n_w x n_w), ``r`` (n_y x n_y), ``p`` (n_x x n_x; default from
    LMI (2)); a scalar weight s means s·I. The MPC is ``mpc_horizon=N`` (the exact MPC,
    Q_c = I, R_c = I, DARE terminal cost) or ``mpc=dict(horizon=N, q=..., r=...)``.
    Boxes are pairs ``(lower, upper)`` in the plant's units (±inf allowed, containing 0;
    omitted: the whole space): ``state_box`` 𝒳, ``input_box`` 𝒰, ``output_box`` 𝒴,
    ``disturbance_box`` 𝒲 for w = (w¹, w²); ``state_rows``, ``input_rows``,
    ``output_rows``, ``disturbance_rows`` the same sets as general rows ``(G, h)``
    ({v : G v ≤ h}: one nonzero entry per row, a bound; a coupling row raises
    :class:`UnsupportedError`), intersected with the box. ``x0`` is the true initial state and
    ``prior`` x̄₀ (default 0); ``w_bar`` a bound on ‖w_t‖₂ (default: the largest over 𝒲).
    Errors name the argument (``mhe["eta"]``, ``input_box``) and the fix.
    """

    def __init__(
        self,
        plant: Plant,
        *,
        mhe: Dict[str, Any],
        mpc_horizon: Optional[int] = None,
        mpc: Optional[Dict[str, Any]] = None,
        state_box: Any = None,
        input_box: Any = None,
        output_box: Any = None,
        disturbance_box: Any = None,
        state_rows: Any = None,
        input_rows: Any = None,
        output_rows: Any = None,
        disturbance_rows: Any = None,
        x0: Any = None,
        prior: Any = None,
        w_bar: Optional[float] = None,
        name: Optional[str] = None,
    ) -> None:
        if not isinstance(plant, Plant):
            raise InputError(f"argument `plant` must be a suboptimal_mhe.Plant, got {type(plant).__name__}")
        nx, nu, ny, nw = plant.nx, plant.nu, plant.ny, plant.nw
        m = _settings("mhe", mhe, _MHE_KEYS, ("horizon", "eta", "k"))
        horizon = _positive_int('mhe["horizon"]', m["horizon"], "the horizon M is a number of steps, e.g. 10")
        k = _positive_int('mhe["k"]', m["k"], "K is the number of iterations per step, e.g. 50")
        try:
            eta = _eta(m["eta"])
        except InputError as e:
            raise type(e)(str(e).replace("argument `eta`", 'argument `mhe["eta"]`')) from None
        method = m.get("method") or "pg"
        if not isinstance(method, str):
            raise InputError(f'argument `mhe["method"]` must be a str, one of {METHODS} (optionally with -jacobi)')
        q = None if m.get("q") is None else _weight('mhe["q"]', m["q"], nw)
        r = None if m.get("r") is None else _weight('mhe["r"]', m["r"], ny)
        p = None if m.get("p") is None else _weight('mhe["p"]', m["p"], nx)
        if (mpc_horizon is None) == (mpc is None):
            raise InputError(
                "give the MPC once: `mpc_horizon=10` (the exact MPC, Q_c = I, R_c = I) or "
                "`mpc=dict(horizon=10, q=1.0, r=1.0)`; Theorem 1 needs its L_π and γ₁,₃"
            )
        mpc_q = mpc_r = None
        if mpc is not None:
            c = _settings("mpc", mpc, _MPC_KEYS, ("horizon",))
            mpc_horizon = _positive_int('mpc["horizon"]', c["horizon"], "the MPC horizon N, e.g. 10")
            mpc_q = None if c.get("q") is None else _weight('mpc["q"]', c["q"], nx)
            mpc_r = None if c.get("r") is None else _weight('mpc["r"]', c["r"], nu)
        else:
            mpc_horizon = _positive_int("mpc_horizon", mpc_horizon, "the MPC horizon N, e.g. 10")
        if w_bar is not None:
            try:
                w_bar = float(w_bar)
            except (TypeError, ValueError):
                raise InputError(f"argument `w_bar` must be a number >= 0, got {w_bar!r}") from None
        if name is not None and not isinstance(name, str):
            raise InputError(f"argument `name` must be a str, got {type(name).__name__}")
        self.plant = plant
        self._native = _native._Model(
            plant._native,
            horizon,
            eta,
            k,
            method,
            q=q,
            r=r,
            p=p,
            mpc_horizon=mpc_horizon,
            mpc_q=mpc_q,
            mpc_r=mpc_r,
            state_box=_set("state_box", state_box, "state_rows", state_rows, nx, origin=True),
            input_box=_set("input_box", input_box, "input_rows", input_rows, nu, origin=True),
            output_box=_set("output_box", output_box, "output_rows", output_rows, ny, origin=True),
            disturbance_box=_set(
                "disturbance_box", disturbance_box, "disturbance_rows", disturbance_rows, nw, origin=True
            ),
            x0=None if x0 is None else _vector("x0", x0, nx),
            prior=None if prior is None else _vector("prior", prior, nx),
            w_bar=w_bar,
            name=name,
        )

    @property
    def k(self) -> int:
        """K, the MHE's iterations per step."""
        return self._native.k

    @property
    def w_bar(self) -> Optional[float]:
        """w̄ (given, else the largest ‖w‖₂ over 𝒲; ``None`` when 𝒲 is unbounded)."""
        return self._native.w_bar

    @property
    def scenario(self) -> "Scenario":
        """The model as a validated scenario (``to_toml()`` writes it for ``cargo xtask``)."""
        return Scenario(self._native.scenario())

    def __repr__(self) -> str:
        return f"Model({self.plant!r}, k={self.k})"


# --------------------------------------------------------------------------------------
# Certificate
# --------------------------------------------------------------------------------------


class Reason:
    """A void, IOSS or skip reason as data (``iss_certificate::outcome``'s enums).

    ``kind`` is the variant in snake_case — void: ``"l_phi_undefined"``,
    ``"controller_undefined"``, ``"premise_fails"`` (``premise``, ``needed_by``, ``value``,
    ``fix``), ``"premise_not_evaluated"`` (``premise``, ``because``), ``"gamma13"``
    (``premise``, ``void``: a dict with its own ``kind``), ``"no_k"`` (``k_max``),
    ``"no_pair"`` (``k_max``, ``spectral_radius``), ``"boundary_cut"`` (``max_corners``);
    ``"ioss_failure"`` (``error``); skip: ``"over_variable_cap"``, ``"over_budget"``,
    ``"no_sequences"``. The fields are attributes (and ``fields``, a dict); ``str(reason)``
    is the sentence the CLI prints and certificate.json carries.
    """

    __slots__ = ("kind", "fields", "_text")

    def __init__(self, data: Dict[str, Any]) -> None:
        data = dict(data)
        self.kind: str = data.pop("kind")
        self._text: str = data.pop("text")
        self.fields: Dict[str, Any] = data

    def __getattr__(self, name: str) -> Any:
        try:
            return self.fields[name]
        except KeyError:
            raise AttributeError(f"a {self.kind!r} reason has no field {name!r}; it has {sorted(self.fields)}") from None

    def __str__(self) -> str:
        return self._text

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Reason) and (self.kind, self.fields, self._text) == (other.kind, other.fields, other._text)

    def __repr__(self) -> str:
        return f"Reason(kind={self.kind!r}, {', '.join(f'{k}={v!r}' for k, v in self.fields.items())})"


class Certificate:
    """The closed-loop certificate (Theorem 1 per method): ``certificate`` in certificate.json.

    ``to_dict()`` / ``to_json()`` give the serde JSON of
    ``iss_certificate::certificate::ClosedLoopCertificate`` exactly as ``cargo xtask
    reproduce`` writes it (docs/reproduce-output.md); the attributes are shortcuts.
    """

    def __init__(self, text: str, native: Any) -> None:
        self._json = text
        self._dict: Dict[str, Any] = json.loads(text)
        self._native = native
        self._typed: Optional[Dict[str, Any]] = None

    def verdict(self, method: str, k: int, scalar: str = "f64") -> Dict[str, Any]:
        """Is ``k`` iterations of ``method`` per step certified? (``Certificate::verdict``.)

        ``scalar="f32"`` asks for the f32 arithmetic of ``Estimator(..., dtype="float32")``
        and the board: Theorem 1 with the f32 rounding folded in (the verdict of
        ``cargo xtask export --scalar f32``).

        A dict: ``certified`` (``"yes"``, ``"no"``: too few iterations, ``"void"``: a premise
        fails, ``reason`` says which, or ``"not_computed"``: the analysis budget stopped a
        phase), ``k_min`` (the smaller of Theorem 1's and the global certificate's floors), ``margin``
        (1 − ρ(Γ)), ``certificate`` (``"theorem1"``/``"joint"``/``"global"``: the one that covers).
        For a scenario it is reproduce's ``at_scenario`` at the scenario's method and K.
        """
        if not isinstance(method, str):
            raise InputError(f"argument `method` must be a str, one of {METHODS} (optionally with -jacobi)")
        k = _positive_int("k", k, "K is the number of iterations per step")
        if scalar not in ("f64", "f32"):
            raise InputError(f"argument `scalar` = {scalar!r}: use \"f64\" or \"f32\"")
        return json.loads(self._native.verdict(method, k, scalar))

    def to_json(self) -> str:
        """The JSON text, as the Rust code serialised it."""
        return self._json

    def to_dict(self) -> Dict[str, Any]:
        """A fresh ``dict`` of the JSON (safe to mutate)."""
        return json.loads(self._json)

    @property
    def methods(self) -> List[str]:
        """The certified methods, in the certificate's order."""
        return [s["solver"] if isinstance(s["solver"], str) else json.dumps(s["solver"]) for s in self._dict["solvers"]]

    def _solver(self, method: str) -> Dict[str, Any]:
        for s in self._dict["solvers"]:
            if s["solver"] == method:
                return s
        raise InputError(f"argument `method` = {method!r} is not in the certificate; use one of {self.methods}")

    def k_min(self, method: str) -> Optional[int]:
        """K_min of Theorem 1 for ``method``; ``None`` when the certificate is void for it."""
        return self._solver(method)["k_min"]

    def k_glob(self, method: str) -> Optional[int]:
        """K_glob of the global loop certificate (Theorem L3, docs/theory.md §4) for ``method``:
        every K ≥ K_glob is certified by it; ``None`` when it certifies no K, does not apply
        or was not computed within the budget (``certificate.phase_seconds``).

        The verdict is ``yes`` from the smaller of :meth:`k_min` and this on
        (``coverage::verdict``; its ``certificate`` names the one that covers).
        """
        self._solver(method)  # the method's entry exists (else InputError naming the methods)
        return self._native.k_glob(method)

    def k_chain(self, method: str) -> Optional[int]:
        """K_chain of the iteration chain (Theorem L3b, docs/theory.md §4b; pg and pg-jacobi,
        f64): the smallest K the chain checked and certified. It covers **only the K it
        checked**: the verdict at another K below :meth:`k_min` and :meth:`k_glob` says
        ``not_computed`` (not checked) or ``no``; ``None`` for other methods, when nothing was
        certified, or when the budget stopped it.
        """
        self._solver(method)  # the method's entry exists (else InputError naming the methods)
        return self._native.k_chain(method)

    def void_reasons(self, method: str) -> List[str]:
        """Why the certificate of ``method`` is void (empty when K_min exists), as sentences."""
        return list(self._solver(method)["void_reasons"])

    def _reasons(self) -> Dict[str, Any]:
        if self._typed is None:
            self._typed = json.loads(self._native.reasons_json())
        return self._typed

    def reasons(self, method: str) -> List["Reason"]:
        """Why the certificate of ``method`` is void, as typed :class:`Reason` s (``kind``
        and fields; ``str(reason)`` is the sentence of :meth:`void_reasons`)."""
        self._solver(method)  # names the argument when the method is not certified
        return [Reason(r) for r in self._reasons()["void"].get(method, [])]

    @property
    def ioss_failure(self) -> Optional["Reason"]:
        """Why LMI (2) failed (``kind == "ioss_failure"``, ``error``), or ``None``."""
        r = self._reasons()["ioss"]
        return None if r is None else Reason(r)

    @property
    def skipped(self) -> List["Reason"]:
        """The γ₁,₃ computations not run, each a :class:`Reason` with ``computation`` and
        ``kind`` ``"over_variable_cap"``, ``"over_budget"`` or ``"no_sequences"``."""
        return [Reason(r) for r in self._reasons()["skipped"]]

    @property
    def k_mins(self) -> Dict[str, Optional[int]]:
        """K_min per method (``None``: void)."""
        return {m: self.k_min(m) for m in self.methods}

    @property
    def ioss_passed(self) -> bool:
        """LMI (2) (Assumption 2) holds."""
        return self._dict["ioss"] is not None and self._dict["ioss_failure"] is None

    def __repr__(self) -> str:
        return f"Certificate(scenario={self._dict['scenario']!r}, k_min={self.k_mins})"


def certify(
    scenario: "Model | Scenario | str | os.PathLike[str]",
    *,
    methods: Optional[List[str]] = None,
    seed: int = 0,
    phase_seconds: Optional[float] = None,
    lipschitz_pairs: int = 200,
    gamma13_sequences: int = 30,
    enumeration_max_vars: int = 20,
    k_max: int = 1 << 24,
    gamma13: Optional[float] = None,
) -> Certificate:
    """The closed-loop certificate (Theorem 1 per method) of a :class:`Model` or a scenario.

    A :class:`Model` is certified by ``iss_certificate::certify`` with the options of every
    command's verdicts (``methods``: default the four named methods plain and Jacobi-scaled;
    ``gamma13``; ``phase_seconds``: the analysis budget per optional phase; ``seed`` of the
    sampled estimates); its :class:`Certificate` also answers ``verdict(method, k)``.
    A scenario (needs ``[mhe]`` and ``[mpc]``) is certified with ``cargo xtask reproduce``'s
    options (``lipschitz_pairs``, ``gamma13_sequences``, ``enumeration_max_vars``,
    ``k_max``; same defaults), so the result equals the ``certificate`` key of its
    certificate.json. The GIL is released while it runs.
    """
    if isinstance(scenario, Model):
        if methods is not None and (
            isinstance(methods, str) or not all(isinstance(m, str) for m in methods)
        ):
            raise InputError(f"argument `methods` must be a list of str, e.g. {list(METHODS)}")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**64:
            raise OutOfRangeError(f"argument `seed` = {seed!r} must be an int in [0, 2**64)")
        for name, v in (("gamma13", gamma13), ("phase_seconds", phase_seconds)):
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer))):
                raise InputError(f"argument `{name}` must be a number, got {type(v).__name__}")
        native = _native.certify_model(
            scenario._native,
            methods=None if methods is None else list(methods),
            gamma13=None if gamma13 is None else float(gamma13),
            phase_seconds=None if phase_seconds is None else float(phase_seconds),
            seed=int(seed),
        )
        return Certificate(native.json(), native)
    if methods is not None or seed != 0 or phase_seconds is not None:
        raise InputError(
            "arguments `methods`, `seed` and `phase_seconds` are for certify(Model(...)); a scenario "
            "sets them in its file (noise.seed, certificate.phase_seconds)"
        )
    sc = _scenario(scenario)
    for name, v in (
        ("lipschitz_pairs", lipschitz_pairs),
        ("gamma13_sequences", gamma13_sequences),
        ("enumeration_max_vars", enumeration_max_vars),
    ):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise OutOfRangeError(f"argument `{name}` = {v!r} must be an int >= 0")
    k_max = _positive_int("k_max", k_max, "the largest K searched for K_min, e.g. 2**24")
    if gamma13 is not None:
        g = float(gamma13)
        if not (math.isfinite(g) and g >= 0.0):
            raise OutOfRangeError(f"argument `gamma13` = {gamma13!r} must be a finite number >= 0")
        gamma13 = g
    native = _native.certify_json(
        sc._native,
        lipschitz_pairs=int(lipschitz_pairs),
        gamma13_sequences=int(gamma13_sequences),
        enumeration_max_vars=int(enumeration_max_vars),
        k_max=k_max,
        gamma13=gamma13,
    )
    return Certificate(native.json(), native)


def simulate(
    scenario: "Scenario | str | os.PathLike[str]",
    steps: Optional[int] = None,
    seed: Optional[int] = None,
    *,
    method: Optional[str] = None,
    k: Optional[int] = None,
) -> Dict[str, np.ndarray]:
    """One closed-loop run of the scenario (plant, MHE, MPC), as ``reproduce`` simulates it.

    Defaults: the scenario's ``simulation.steps``, ``noise.seed``, ``mhe.method`` and
    ``mhe.iterations``. Returns NumPy arrays: ``x`` (T+1 x n_x, the true state), ``x_hat``
    (T x n_x), ``u`` (T x n_u), ``y`` (T x n_y), ``w`` (T x n_w) and ``e_norm`` (T,
    ‖x̂_t − x_t‖₂); beside them the Kalman baseline of reproduce's trace.csv (the standard
    filter of the MHE's weights on the same u, y): ``x_kf``, ``e_kf_norm`` (shorter if the
    filter stopped) and ``kalman_error`` (``None``, or why it stopped / was not built).
    The GIL is released while it runs.
    """
    sc = _scenario(scenario)
    if steps is not None:
        steps = _positive_int("steps", steps, f"the number of steps T, at most {_native.MAX_STEPS}")
    if seed is not None:
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**64:
            raise OutOfRangeError(f"argument `seed` = {seed!r} must be an int in [0, 2**64)")
        seed = int(seed)
    if k is not None:
        k = _positive_int("k", k, "K is the number of iterations per step")
    if method is not None and not isinstance(method, str):
        raise InputError(f"argument `method` must be a str, one of {METHODS}")
    return _native.simulate(sc._native, steps, seed, method, k)


def _columns(path: str) -> Dict[str, np.ndarray]:
    """A CSV table as {column: array}: float64 where every entry parses, else str."""
    import csv

    with open(path, newline="", encoding="utf-8") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    header, body = rows[0], rows[1:]
    out: Dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        col = [r[j] if j < len(r) else "" for r in body]
        try:
            out[name] = np.array([float(v) for v in col], dtype=np.float64)
        except ValueError:
            out[name] = np.array(col, dtype=str)
    return out


def sweep(
    config: "os.PathLike[str] | str",
    out_dir: "os.PathLike[str] | str | None" = None,
    *,
    threads: int = 1,
) -> Dict[str, Any]:
    """Runs a sweep (``mhe_sweep::Sweep::run``, the engine of ``cargo xtask sweep``).

    ``config`` is a sweep file (``sweeps/*.toml``, docs/sweep.md) or its TOML text (relative
    paths then resolve from the current directory). The files go to ``out_dir`` (default: a
    new temporary directory), as the CLI writes them; an existing ``out_dir`` of the same
    sweep resumes. Returns ``{"points": {column: array}, "runs": {column: array},
    "out_dir": path}`` — the columns of points.csv and runs.csv as NumPy arrays (float64, or
    str for text columns), no pandas needed (``pandas.DataFrame(result["runs"])`` if you
    want one).

    Ctrl-C (``KeyboardInterrupt``) stops the sweep between two tasks (within one run or
    theory task per thread) and is re-raised; the point files finished so far stay in
    ``out_dir``, so calling again with the same ``out_dir`` resumes. The GIL is released
    while the sweep runs.
    """
    import tempfile

    threads = _positive_int("threads", threads, "the number of worker threads, e.g. 2")
    if isinstance(config, os.PathLike) or (isinstance(config, str) and "\n" not in config and "=" not in config):
        text, is_text = os.fspath(config), False
    elif isinstance(config, str):
        text, is_text = config, True
    else:
        raise InputError(f"argument `config` must be a path to a sweep file or its TOML text, got {type(config).__name__}")
    out = tempfile.mkdtemp(prefix="suboptimal-mhe-sweep-") if out_dir is None else os.fspath(out_dir)
    runs, points = _native.sweep_run(text, out, threads, is_text, os.getcwd() if is_text else None)
    return {"points": _columns(points), "runs": _columns(runs), "out_dir": out}


def export(
    model: "Model | Scenario | str | os.PathLike[str]",
    out_dir: "os.PathLike[str] | str",
    *,
    lang: str = "c",
    method: Optional[str] = None,
    k: "int | str" = "certified",
    kc: "int | str | None" = None,
    mpc_method: Optional[str] = None,
    dtype: str = "float64",
    prefix: str = "mhe",
    allow_uncertified: bool = False,
) -> Dict[str, Any]:
    """Exports the certified estimator for a microcontroller (``mhe_export``, what ``cargo
    xtask export`` runs): C99 sources (``lang="c"``) or a ``no_std`` Rust package
    (``lang="rust"``), the replay program, ``certificate.json`` and a README, into
    ``out_dir`` (created, or replaced as a whole when it holds an earlier export).

    ``k`` is an iteration count or ``"certified"`` (the smallest K the one verdict certifies:
    Theorem 1's K_min, Theorem L3's K_glob or the iteration chain's K); ``kc`` also exports
    the K_c-iteration MPC (a count or ``"certified"``: the joint certificate's floor).
    The export is refused (:class:`CertificateError`) unless the one verdict of every command
    certifies (method, K, dtype) — ``allow_uncertified=True`` exports anyway and the
    artefact says so. ``dtype="float32"`` exports f32 code. Returns ``{"out", "scenario",
    "method", "k", "k_min", "certified", "loop_certified", "uncertified_reason", "mpc"}``.
    The sample-period budget (``--target``) is the CLI's; the sources are the same bytes.
    The GIL is released while it runs.
    """
    def count(name: str, v: Any) -> str:
        if isinstance(v, str) and v == "certified":
            return v
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise InputError(f"argument `{name}` must be an int ≥ 1 or \"certified\", got {v!r}")
        return str(int(v))

    for name, v in (("lang", lang), ("dtype", dtype), ("prefix", prefix)):
        if not isinstance(v, str):
            raise InputError(f"argument `{name}` must be a str, got {type(v).__name__}")
    for name, v in (("method", method), ("mpc_method", mpc_method)):
        if v is not None and not isinstance(v, str):
            raise InputError(f"argument `{name}` must be a str (one of {list(METHODS)}), got {type(v).__name__}")
    args: Dict[str, Any] = dict(
        method=method,
        k=count("k", k),
        kc=None if kc is None else count("kc", kc),
        mpc_method=mpc_method,
        scalar=dtype,
        lang=lang,
        prefix=prefix,
        allow_uncertified=bool(allow_uncertified),
    )
    out = os.fspath(out_dir)
    if isinstance(model, Model):
        summary = _native.export_artefact(out, model=model._native, **args)
    elif isinstance(model, Scenario):
        summary = _native.export_artefact(out, scenario=model._native, **args)
    elif isinstance(model, (str, os.PathLike)):
        path = os.fspath(model)
        sc = Scenario.from_file(path)
        with open(path, "rb") as f:
            data = f.read()
        summary = _native.export_artefact(
            out, scenario=sc._native, source_path=path, source_bytes=data, **args
        )
    else:
        raise InputError(
            f"argument `model` must be a Model, a Scenario or a path to a scenario file, got {type(model).__name__}"
        )
    return json.loads(summary)
