"""Type stubs of suboptimal_mhe (see __init__.py for the docstrings)."""

import os
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

MAX_DIMENSION: int
METHODS: Tuple[str, ...]
#: General rows: (G, h) is {v : G v <= h}; (G, lower, upper) is {v : lower <= G v <= upper}.
Rows = Union[Tuple[ArrayLike, ArrayLike], Tuple[ArrayLike, ArrayLike, ArrayLike]]

class MheError(ValueError): ...
class InputError(MheError): ...
class ShapeError(InputError): ...
class NonFiniteError(InputError): ...
class NotPositiveDefiniteError(InputError): ...
class OutOfRangeError(InputError): ...
class ScenarioError(MheError): ...
class Reason:
    """A void, IOSS or skip reason: ``kind``, its fields (attributes), ``str()`` the CLI sentence."""
    kind: str
    fields: Dict[str, Any]
    def __init__(self, data: Dict[str, Any]) -> None: ...
    def __getattr__(self, name: str) -> Any: ...

class CertificateError(MheError): ...
class NumericalError(MheError): ...
class UnsupportedError(MheError): ...

class Plant:
    """x⁺ = Ax + Bu + Ew¹, y = Cx + Fw² (E, F default I)."""
    def __init__(
        self, A: ArrayLike, B: ArrayLike, C: ArrayLike, E: Optional[ArrayLike] = ..., F: Optional[ArrayLike] = ...
    ) -> None: ...
    @property
    def nx(self) -> int: ...
    @property
    def nu(self) -> int: ...
    @property
    def ny(self) -> int: ...
    @property
    def nw(self) -> int: ...
    @property
    def A(self) -> NDArray[np.float64]: ...
    @property
    def B(self) -> NDArray[np.float64]: ...
    @property
    def C(self) -> NDArray[np.float64]: ...
    @property
    def E(self) -> NDArray[np.float64]: ...
    @property
    def F(self) -> NDArray[np.float64]: ...

class Estimator:
    """Alg. 1 with exactly k iterations of method per step (horizon M in steps, eta in [0, 1))."""
    model: Plant
    def __init__(
        self,
        model: Plant,
        horizon: int,
        eta: float,
        k: int,
        method: str = ...,
        q: Optional[ArrayLike] = ...,
        r: Optional[ArrayLike] = ...,
        p: Optional[ArrayLike] = ...,
        prior: Optional[ArrayLike] = ...,
        dtype: Any = ...,
        state_box: Optional[Tuple[ArrayLike, ArrayLike]] = ...,
        output_box: Optional[Tuple[ArrayLike, ArrayLike]] = ...,
        disturbance_box: Optional[Tuple[ArrayLike, ArrayLike]] = ...,
        state_rows: Optional[Rows] = ...,
        output_rows: Optional[Rows] = ...,
        disturbance_rows: Optional[Rows] = ...,
    ) -> None: ...
    dtype: np.dtype[Any]
    def push(self, u: ArrayLike, y: ArrayLike) -> None: ...
    def estimate(self, out: Optional[NDArray[Any]] = ...) -> NDArray[Any]: ...
    def reset(self, prior: Optional[ArrayLike] = ...) -> None: ...
    @property
    def t(self) -> int: ...
    @property
    def P(self) -> NDArray[np.float64]: ...

class Scenario:
    @classmethod
    def from_file(cls, path: Union[str, "os.PathLike[str]"]) -> Scenario: ...
    @classmethod
    def from_toml(cls, text: str) -> Scenario: ...
    @property
    def name(self) -> str: ...
    @property
    def plant(self) -> Plant: ...
    def to_toml(self) -> str: ...

class Model:
    """A closed loop from NumPy values (iss_certificate::LoopModel)."""
    plant: Plant
    def __init__(
        self,
        plant: Plant,
        *,
        mhe: Dict[str, Any],
        mpc_horizon: Optional[int] = ...,
        mpc: Optional[Dict[str, Any]] = ...,
        state_box: Optional[Tuple[ArrayLike, ArrayLike]] = ...,
        input_box: Optional[Tuple[ArrayLike, ArrayLike]] = ...,
        output_box: Optional[Tuple[ArrayLike, ArrayLike]] = ...,
        disturbance_box: Optional[Tuple[ArrayLike, ArrayLike]] = ...,
        state_rows: Optional[Rows] = ...,
        input_rows: Optional[Rows] = ...,
        output_rows: Optional[Rows] = ...,
        disturbance_rows: Optional[Rows] = ...,
        x0: Optional[ArrayLike] = ...,
        prior: Optional[ArrayLike] = ...,
        w_bar: Optional[float] = ...,
        name: Optional[str] = ...,
    ) -> None: ...
    @property
    def k(self) -> int: ...
    @property
    def w_bar(self) -> Optional[float]: ...
    @property
    def scenario(self) -> Scenario: ...

class Certificate:
    """certificate.json's `certificate` (ClosedLoopCertificate)."""
    def verdict(self, method: str, k: int, scalar: str = ...) -> Dict[str, Any]: ...
    def reasons(self, method: str) -> List[Reason]: ...
    @property
    def ioss_failure(self) -> Optional[Reason]: ...
    @property
    def skipped(self) -> List[Reason]: ...
    def to_json(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]: ...
    @property
    def methods(self) -> List[str]: ...
    def k_min(self, method: str) -> Optional[int]: ...
    def k_glob(self, method: str) -> Optional[int]: ...
    def k_chain(self, method: str) -> Optional[int]: ...
    def void_reasons(self, method: str) -> List[str]: ...
    @property
    def k_mins(self) -> Dict[str, Optional[int]]: ...
    @property
    def ioss_passed(self) -> bool: ...

def certify(
    scenario: Union[Model, Scenario, str, "os.PathLike[str]"],
    *,
    methods: Optional[List[str]] = ...,
    seed: int = ...,
    phase_seconds: Optional[float] = ...,
    lipschitz_pairs: int = ...,
    gamma13_sequences: int = ...,
    enumeration_max_vars: int = ...,
    k_max: int = ...,
    gamma13: Optional[float] = ...,
) -> Certificate: ...
def simulate(
    scenario: Union[Model, Scenario, str, "os.PathLike[str]"],
    steps: Optional[int] = ...,
    seed: Optional[int] = ...,
    *,
    method: Optional[str] = ...,
    k: Optional[int] = ...,
) -> Dict[str, Any]:
    """x, x_hat, u, y, w, e_norm, x_kf, e_kf_norm (NumPy arrays) and kalman_error (str | None)."""

def set_kernel(name: str) -> None: ...

def sweep(
    config: Union[str, os.PathLike[str]],
    out_dir: Union[str, os.PathLike[str], None] = ...,
    *,
    threads: int = ...,
) -> Dict[str, Any]: ...

def export(
    model: Union[Model, Scenario, str, os.PathLike[str]],
    out_dir: Union[str, os.PathLike[str]],
    *,
    lang: str = ...,
    method: Optional[str] = ...,
    k: Union[int, str] = ...,
    kc: Union[int, str, None] = ...,
    mpc_method: Optional[str] = ...,
    dtype: str = ...,
    prefix: str = ...,
    allow_uncertified: bool = ...,
) -> Dict[str, Any]: ...
