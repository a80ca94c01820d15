"""Shared fixtures: the repository root and the CLI (`xtask`) the results are compared with."""

import os
import pathlib

# Both this process and the CLI it is compared with run the portable kernel, so results
# agree bit for bit (the package applies $QP_ITER_KERNEL at import: suboptimal_mhe.set_kernel).
os.environ.setdefault("QP_ITER_KERNEL", "portable")

import pytest  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def root() -> pathlib.Path:
    return ROOT


@pytest.fixture(scope="session")
def xtask() -> pathlib.Path:
    """The CLI binary: $SUBOPTIMAL_MHE_XTASK (scripts/python.sh sets it) or target/release/xtask."""
    path = pathlib.Path(os.environ.get("SUBOPTIMAL_MHE_XTASK", ROOT / "target" / "release" / "xtask"))
    if not path.is_file():
        pytest.skip(f"the CLI {path} is not built (cargo build -p xtask --release)")
    return path
