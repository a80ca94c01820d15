"""The Python results equal the CLI's: certificate.json key by key, trace.csv bit for bit."""

import csv
import json
import subprocess

import numpy as np
import pytest

import suboptimal_mhe as sm

SCENARIO = "scenarios/double-integrator.toml"


@pytest.fixture(scope="module")
def reproduced(root, xtask, tmp_path_factory):
    """`xtask reproduce --scenario double-integrator` (≈ 4 s), on the portable kernel."""
    out = tmp_path_factory.mktemp("reproduce")
    subprocess.run(
        [str(xtask), "reproduce", "--scenario", str(root / SCENARIO), "--out", str(out)],
        check=True,
        cwd=root,
        capture_output=True,
    )
    return out / "double-integrator"


def test_certificate_equals_certificate_json(root, reproduced):
    cli = json.loads((reproduced / "certificate.json").read_text())["certificate"]
    cert = sm.certify(root / SCENARIO)
    ours = cert.to_dict()
    assert sorted(ours) == sorted(cli)
    for key in cli:
        assert ours[key] == cli[key], key
    assert json.loads(cert.to_json()) == cli
    # The shortcuts read the same document.
    for s in cli["solvers"]:
        assert cert.k_min(s["solver"]) == s["k_min"]
        assert cert.void_reasons(s["solver"]) == s["void_reasons"]
    assert cert.k_min("admm-pr") is not None
    # The verdict at the scenario's (method, K) is reproduce's `at_scenario`.
    doc = json.loads((reproduced / "certificate.json").read_text())
    assert cert.verdict(doc["solver"], doc["scenario_iterations"]) == doc["at_scenario"]
    k_min = doc["at_scenario"]["k_min"]
    assert cert.verdict(doc["solver"], k_min)["certified"] == "yes"


def read_trace(path):
    runs = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            runs.setdefault(int(row["k"]), []).append(row)
    return runs


def column(rows, prefix, n):
    return np.array([[float(r[f"{prefix}{i + 1}"]) for i in range(n)] for r in rows])


def test_simulate_equals_trace_csv_bit_for_bit(root, reproduced):
    runs = read_trace(reproduced / "trace.csv")
    doc = json.loads((reproduced / "certificate.json").read_text())
    for run in doc["runs"]:
        rows = runs[run["k"]]
        sim = sm.simulate(root / SCENARIO, steps=run["steps"], seed=run["seed"], method=run["solver"], k=run["k"])
        T = len(rows)
        assert T == run["steps"]
        for name, prefix, n in [("x", "x", 2), ("x_hat", "xhat", 2), ("u", "u", 1), ("y", "y", 1), ("w", "w", 3)]:
            np.testing.assert_array_equal(sim[name][:T], column(rows, prefix, n), err_msg=f"{name}, k = {run['k']}")
        np.testing.assert_array_equal(sim["e_norm"], [float(r["e_norm"]) for r in rows])
        # The Kalman baseline beside it (trace.csv's xkf, ekf_norm).
        assert sim["kalman_error"] is None
        np.testing.assert_array_equal(sim["x_kf"], column(rows, "xkf", 2))
        np.testing.assert_array_equal(sim["e_kf_norm"], [float(r["ekf_norm"]) for r in rows])
        assert sim["x"].shape == (T + 1, 2)


def test_simulate_shapes_and_defaults(root):
    sim = sm.simulate(sm.Scenario.from_file(root / SCENARIO), steps=7)
    assert sim["x"].shape == (8, 2) and sim["x_hat"].shape == (7, 2)
    assert sim["u"].shape == (7, 1) and sim["y"].shape == (7, 1) and sim["w"].shape == (7, 3)
    np.testing.assert_allclose(sim["e_norm"], np.linalg.norm(sim["x_hat"] - sim["x"][:7], axis=1), rtol=1e-12)


def test_scenario_round_trip_and_plant(root):
    sc = sm.Scenario.from_file(root / SCENARIO)
    assert sc.name == "double-integrator"
    again = sm.Scenario.from_toml(sc.to_toml())
    assert again.to_toml() == sc.to_toml()
    assert sc.plant.nx == 2 and sc.plant.nw == 3


@pytest.mark.parametrize(
    "call, exc, words",
    [
        (lambda r: sm.certify(r / "no-such-file.toml"), sm.ScenarioError, ["no-such-file"]),
        (lambda r: sm.Scenario.from_toml("name = 1"), sm.ScenarioError, ["name"]),
        (lambda r: sm.certify(r / SCENARIO, k_max=0), sm.OutOfRangeError, ["k_max"]),
        (lambda r: sm.certify(r / SCENARIO, lipschitz_pairs=-1), sm.OutOfRangeError, ["lipschitz_pairs"]),
        (lambda r: sm.certify(r / SCENARIO, gamma13=float("nan")), sm.OutOfRangeError, ["gamma13"]),
        (lambda r: sm.certify(42), sm.InputError, ["scenario"]),
        (lambda r: sm.simulate(r / SCENARIO, steps=0), sm.OutOfRangeError, ["steps"]),
        (lambda r: sm.simulate(r / SCENARIO, steps=10**9), sm.OutOfRangeError, ["steps"]),
        (lambda r: sm.simulate(r / SCENARIO, seed=-1), sm.OutOfRangeError, ["seed"]),
        (lambda r: sm.simulate(r / SCENARIO, method="newton"), sm.InputError, ["method"]),
    ],
)
def test_bad_certify_and_simulate_arguments(root, call, exc, words):
    with pytest.raises(exc) as info:
        call(root)
    for w in words:
        assert w in str(info.value), str(info.value)


def test_scenario_errors_name_the_scenario_key(root):
    text = (root / SCENARIO).read_text().replace("eta = 0.8", "eta = 1.5")
    with pytest.raises(sm.ScenarioError, match=r"mhe\.eta"):
        sm.Scenario.from_toml(text)


def test_certify_needs_mpc(root):
    text = (root / SCENARIO).read_text()
    no_mpc = text[: text.index("[mpc]")]
    with pytest.raises(sm.ScenarioError, match=r"\[mpc\]"):
        sm.certify(sm.Scenario.from_toml(no_mpc))


def test_certify_releases_the_gil(root):
    # While certify runs in a thread, this thread keeps running Python. With the GIL held
    # for the whole call, this loop would stall for about the call's duration (one gap as
    # long as the call); released, its longest gap is a scheduler slice.
    import threading
    import time

    # A 1-second phase budget: the call still lasts seconds (the scan and Theorem 1 at every
    # method), against 40 s with the scenario's default budget (docs/testing.md, "Session 24").
    text = (root / SCENARIO).read_text() + "\n[certificate]\nphase_seconds = 1.0\n"
    sc = sm.Scenario.from_toml(text)
    worker = threading.Thread(target=lambda: sm.certify(sc))
    t0 = last = time.perf_counter()
    longest = 0.0
    worker.start()
    while worker.is_alive():
        now = time.perf_counter()
        longest = max(longest, now - last)
        last = now
    duration = time.perf_counter() - t0
    worker.join()
    assert longest < 0.5 * duration, (longest, duration)
