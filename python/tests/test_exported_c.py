"""The exported C replay, compiled here, equals Python's estimator bit for bit: at f32 the
board's kernel (``Estimator(..., dtype="float32")``) against ``export(..., dtype="float32")``,
at f64 the portable kernel against ``export(...)`` and the closed loop's x̂ (= trace.csv,
tests/test_cli.py). Issue 39: "the exported C replay bit for bit at f32"."""

import os
import shutil
import subprocess

import numpy as np
import pytest

import suboptimal_mhe as sm

SCENARIO = "scenarios/double-integrator.toml"
#: The flags of the exported Makefile and docs/embedded.md: strict C99, no contraction into
#: fused multiply-adds, no fast-math (bit identity needs IEEE semantics).
CFLAGS = ["-O2", "-std=c99", "-ffp-contract=off", "-fno-fast-math",
          "-Wall", "-Wextra", "-Wpedantic", "-Werror"]
#: Iterations per step: fixed (not each method's K_min) so every method costs the same; the
#: f32 exports are uncertified anyway (allow_uncertified, -DMHE_ALLOW_UNCERTIFIED).
K = 25
STEPS = 40
METHODS = ["pg", "fista", "admm", "admm-pr", "pg-jacobi", "admm-pr-jacobi"]


def compiler():
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        pytest.skip("no C compiler (cc, gcc or clang) on PATH: the exported C replay cannot be built")
    return cc


@pytest.fixture(scope="module")
def cut(root, tmp_path_factory):
    """The scenario with ``[certificate] phase_seconds = 0.5``: the export's certificate then
    skips the global loop certificate at once (7.7 s → 0.6 s an export). The artefact's code
    and data are the same bytes; these exports are uncertified at K = 25 either way."""
    path = tmp_path_factory.mktemp("cut") / "double-integrator.toml"
    path.write_text((root / SCENARIO).read_text() + "\n[certificate]\nphase_seconds = 0.5\n")
    return path


@pytest.fixture(scope="module")
def run(root):
    """(u, y) of 40 steps of the scenario's closed loop, and its x̂ at each method (K = 25)."""
    plant = sm.Scenario.from_file(root / SCENARIO).plant
    sim = sm.simulate(root / SCENARIO, steps=STEPS)
    return plant, sim["u"], sim["y"]


def python_estimates(plant, method, dtype, us, ys):
    """x̂ before each push and after the last (STEPS + 1 rows): the replay's lines."""
    # The scenario's [mhe] (M = 9, η = 0.8, Q = I, R = I, P from LMI (2)), its 𝒲 box and prior.
    est = sm.Estimator(plant, horizon=9, eta=0.8, k=K, method=method, q=1.0, r=1.0,
                       prior=[0.0, 0.0], disturbance_box=([-0.01] * 3, [0.01] * 3), dtype=dtype)
    xs = []
    for u, y in zip(us, ys):
        xs.append(est.estimate())
        est.push(u, y)
    xs.append(est.estimate())
    return np.array(xs)


def c_replay(scenario, tmp_path, method, dtype, us, ys):
    """Exports the estimator of ``scenario`` (a file) at (method, K, dtype), builds ``replay``
    with ``cc`` and feeds it (u, y): its STEPS + 1 lines as float64 (exact: 17 significant
    digits)."""
    cc = compiler()
    out = tmp_path / f"{method}-{dtype}"
    summary = sm.export(scenario, out, method=method, k=K, dtype=dtype, allow_uncertified=True)
    assert summary["k"] == K and summary["method"] == method
    makefile = (out / "Makefile").read_text()
    for flag in ("-std=c99", "-ffp-contract=off", "-fno-fast-math"):
        assert flag in makefile, flag  # the flags used here are the artefact's own
    defs = [] if summary["certified"] else ["-DMHE_ALLOW_UNCERTIFIED"]
    build = subprocess.run([cc, *CFLAGS, *defs, "-o", "replay", "mhe.c", "mhe_data.c", "replay.c", "-lm"],
                           cwd=out, capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    # repr() is the shortest text that parses back (strtod) to the same float64; the replay
    # rounds it to its scalar once, as the Python f32 path does.
    lines = "".join(",".join(repr(float(v)) for v in (*u, *y)) + "\n" for u, y in zip(us, ys))
    rep = subprocess.run([str(out / "replay")], input=lines, capture_output=True, text=True, timeout=60)
    assert rep.returncode == 0, rep.stderr
    return np.array([[float(v) for v in line.split(",")] for line in rep.stdout.splitlines()])


@pytest.mark.parametrize("method", METHODS)
def test_f32_estimator_equals_the_exported_f32_c_bit_for_bit(cut, tmp_path, run, method):
    plant, us, ys = run
    got = python_estimates(plant, method, "float32", us, ys)
    assert got.dtype == np.float32 and got.shape == (STEPS + 1, 2)
    c = c_replay(cut, tmp_path, method, "float32", us, ys)
    assert c.shape == got.shape
    c32 = c.astype(np.float32)
    assert np.array_equal(c32.astype(np.float64), c), "the f32 replay printed a value that is not a float32"
    np.testing.assert_array_equal(got.view(np.uint32), c32.view(np.uint32))
    # Not a trivial agreement: f32 differs from f64 by its rounding, and x̂ moves.
    x64 = python_estimates(plant, method, "float64", us, ys)
    diff = np.abs(got.astype(np.float64) - x64)
    assert 0 < diff.max() < 1e-3, diff.max()
    assert np.abs(x64).max() > 0.1


@pytest.mark.parametrize("method", ["admm-pr", "fista-jacobi"])
def test_f64_estimator_equals_the_exported_c_and_the_closed_loop(root, cut, tmp_path, run, method):
    # conftest.py sets QP_ITER_KERNEL=portable: the kernel the exported C reproduces.
    plant, us, ys = run
    got = python_estimates(plant, method, "float64", us, ys)
    c = c_replay(cut, tmp_path, method, "float64", us, ys)
    np.testing.assert_array_equal(got.view(np.uint64), c.view(np.uint64))
    # The closed loop at this (method, K) — trace.csv's xhat (test_cli.py) — estimates the
    # same: x̂_t from its own u, y, so fed those the estimator repeats it.
    sim = sm.simulate(root / SCENARIO, steps=STEPS, method=method, k=K)
    again = python_estimates(plant, method, "float64", sim["u"], sim["y"])
    np.testing.assert_array_equal(again[:STEPS].view(np.uint64), sim["x_hat"].view(np.uint64))
