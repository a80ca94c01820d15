"""sweep(): the engine of `cargo xtask sweep`, NumPy columns out, Ctrl-C honoured."""

import _thread
import signal
import threading
import time

import numpy as np
import pytest

import suboptimal_mhe as sm


def small(root, seeds=3, steps=8, k="[1, 4, 25]"):
    scenario = (root / "scenarios" / "case-study-certified.toml").as_posix()
    return (f'name = "py"\nscenario = "{scenario}"\nk = {k}\nsolvers = ["pg"]\n'
            f"seeds = {seeds}\nsteps = {steps}\nbase_seed = 5\ncertificate = false\n")


def test_sweep_returns_the_csv_columns_as_arrays(root, tmp_path):
    res = sm.sweep(small(root), tmp_path / "out")
    runs, points = res["runs"], res["points"]
    assert all(isinstance(v, np.ndarray) for v in runs.values())
    n_runs = {len(v) for v in runs.values()}
    assert n_runs == {9}, n_runs  # 3 K × 3 seeds
    assert {len(v) for v in points.values()} == {3}
    # The arrays are the files' columns (the CLI's format).
    header = (tmp_path / "out" / "runs.csv").read_text().splitlines()[0].split(",")
    assert list(runs) == header


def test_bad_config_names_the_key(root, tmp_path):
    with pytest.raises(sm.InputError, match="seeds"):
        sm.sweep(small(root, seeds=0), tmp_path / "bad")


def test_ctrl_c_stops_a_sweep_quickly(root, tmp_path):
    # A sweep of minutes on one core (large enough that it cannot finish before the timer
    # on a fast, idle machine: 40 seeds once did), interrupted after 1 s: KeyboardInterrupt
    # within ~2 s.
    cfg = small(root, seeds=400, steps=400, k="[50, 100, 200, 400, 800, 1600]")
    # Python's own SIGINT handler, whatever the launcher left: a process started in the
    # background of a non-interactive shell (`cmd &`) inherits SIGINT ignored, Python then
    # installs no handler and `interrupt_main` does nothing (the sweep ran to its end: "DID
    # NOT RAISE", sessions 20 and 21).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(1.0, _thread.interrupt_main)
    t0 = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            sm.sweep(cfg, tmp_path / "int")
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    elapsed = time.monotonic() - t0
    assert elapsed < 5.0, elapsed
    assert (tmp_path / "int" / "points").is_dir()
