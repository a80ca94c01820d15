"""Model (NumPy values → iss_certificate::LoopModel) and certify(model): the certificate of
the double integrator built from arrays equals the one of scenarios/double-integrator.toml,
key by key; bad arguments raise the package's exception naming the Python argument."""

import numpy as np
import pytest

import suboptimal_mhe as sm

SCENARIO = "scenarios/double-integrator.toml"
T = 0.1


def plant():
    # The file's values (ZOH of ÿ = u at 0.1 s, printed by plants::print_coverage_scenarios).
    a = [[0.9999999999999999, 0.09999999999999998], [0.0, 0.9999999999999999]]
    b = [[0.004999999999999998], [0.09999999999999998]]
    return sm.Plant(A=a, B=b, C=[[1.0, 0.0]])


def model(**over):
    kwargs = dict(
        mhe=dict(horizon=9, eta=0.8, k=10, method="admm-pr", q=1.0, r=1.0),
        mpc_horizon=10,
        disturbance_box=([-0.01] * 3, [0.01] * 3),
        x0=[1.0, 0.0],
        prior=[0.0, 0.0],
        name="double-integrator",
    )
    kwargs.update(over)
    return sm.Model(plant(), **kwargs)


@pytest.fixture(scope="module")
def from_numpy():
    # The file's noise.seed = 11: the seed of every sampled estimate.
    return sm.certify(model(), seed=11)


def test_model_certificate_equals_the_scenario_files(root, from_numpy):
    # certify(Model) uses the verdict's options (no sampled Lipschitz pairs, no sampled γ₁,₃
    # sequences): the scenario path with the same options must give the same document.
    ours = from_numpy.to_dict()
    file = sm.certify(root / SCENARIO, lipschitz_pairs=0, gamma13_sequences=0).to_dict()
    assert sorted(ours) == sorted(file)
    for key in file:
        assert ours[key] == file[key], key
    assert from_numpy.k_min("admm-pr") is not None
    assert set(from_numpy.methods) == {m + s for m in sm.METHODS for s in ("", "-jacobi")}


def test_verdict_is_certificate_verdict(from_numpy):
    k_min = from_numpy.k_min("admm-pr")
    k_glob = from_numpy.k_glob("admm-pr")
    # The double integrator: the global loop certificate's floor is below Theorem 1's.
    assert k_glob is not None and k_glob < k_min, (k_glob, k_min)
    yes = from_numpy.verdict("admm-pr", k_min)
    assert yes["certified"] == "yes" and yes["k_min"] == k_glob and yes["certificate"] == "theorem1"
    assert yes["reason"] == ""
    by_global = from_numpy.verdict("admm-pr", k_glob)
    assert by_global["certified"] == "yes" and by_global["certificate"] == "global"
    if k_glob > 1:
        assert from_numpy.verdict("admm-pr", k_glob - 1)["certified"] == "no"
    # A method the certificate did not cover is void, with the reason.
    only_pg = sm.certify(model(), methods=["pg"], seed=11)
    other = only_pg.verdict("fista", 10_000)
    assert other["certified"] == "void" and other["reason"]
    assert only_pg.methods == ["pg"]
    assert only_pg.k_min("pg") == from_numpy.k_min("pg")


def test_model_properties_and_scenario():
    m = model(w_bar=0.02)
    assert m.k == 10 and m.w_bar == 0.02
    assert model().w_bar == pytest.approx(0.01 * np.sqrt(3), rel=1e-15)
    assert model(disturbance_box=None).w_bar is None
    sc = sm.Scenario.from_toml(m.scenario.to_toml())
    assert sc.name == "double-integrator"
    np.testing.assert_array_equal(sc.plant.A, plant().A)
    # simulate accepts the model (its scenario).
    sim = sm.simulate(m, steps=5, seed=11)
    assert sim["x"].shape == (6, 2)


def test_mpc_weights():
    # Theorem 1's K_min under one budget (phase_seconds = 0.5 skips the global loop
    # certificate, 2–3 s a call, which this test does not read).
    m = model(mpc_horizon=None, mpc=dict(horizon=10, q=1.0, r=1.0))
    assert sm.certify(m, methods=["admm-pr"], seed=11, phase_seconds=0.5).k_min("admm-pr") == sm.certify(
        model(), methods=["admm-pr"], seed=11, phase_seconds=0.5
    ).k_min("admm-pr")
    heavy = model(mpc_horizon=None, mpc=dict(horizon=10, q=np.diag([10.0, 1.0]), r=0.1))
    assert sm.certify(heavy, methods=["pg"], phase_seconds=0.5).to_dict()["scenario"] == "double-integrator"


@pytest.mark.parametrize(
    "over, exc, names",
    [
        (dict(mhe=dict(horizon=9, eta=1.2, k=10)), sm.OutOfRangeError, 'mhe["eta"]'),
        (dict(mhe=dict(horizon=9, eta=float("nan"), k=10)), sm.NonFiniteError, 'mhe["eta"]'),
        (dict(mhe=dict(horizon=0, eta=0.8, k=10)), sm.OutOfRangeError, 'mhe["horizon"]'),
        (dict(mhe=dict(horizon=9, eta=0.8)), sm.InputError, "mhe"),
        (dict(mhe=dict(horizon=9, eta=0.8, k=10, iterations=3)), sm.InputError, "iterations"),
        (dict(mhe=dict(horizon=9, eta=0.8, k=10, method="newton")), sm.InputError, 'mhe["method"]'),
        (dict(mhe=dict(horizon=9, eta=0.8, k=10, q=-1.0)), sm.NotPositiveDefiniteError, 'mhe["q"]'),
        (dict(mhe=dict(horizon=9, eta=0.8, k=10, r=np.eye(2))), sm.ShapeError, 'mhe["r"]'),
        (dict(mhe=dict(horizon=9, eta=0.8, k=10, p=[[1.0, 2.0], [2.0, 1.0]])), sm.NotPositiveDefiniteError, 'mhe["p"]'),
        (dict(mpc_horizon=None), sm.InputError, "mpc_horizon"),
        (dict(mpc=dict(horizon=10)), sm.InputError, "mpc_horizon"),
        (dict(mpc_horizon=None, mpc=dict(horizon=10, r=[[1.0, 0.0]])), sm.ShapeError, 'mpc["r"]'),
        (dict(disturbance_box=([-0.01] * 2, [0.01] * 2)), sm.ShapeError, "disturbance_box"),
        (dict(disturbance_box=([0.01] * 3, [0.02] * 3)), sm.InputError, "disturbance_box"),
        (dict(input_box=([float("nan")], [1.0])), sm.NonFiniteError, "input_box"),
        (dict(input_box=([-1.0, -1.0], [1.0, 1.0])), sm.ShapeError, "input_box"),
        (dict(input_box=(-1.0,)), sm.InputError, "input_box"),
        (dict(state_box=([-0.5, -1.0], [0.5, 1.0])), sm.InputError, "x0"),
        (dict(x0=[1.0, float("inf")]), sm.NonFiniteError, "x0"),
        (dict(prior=[0.0]), sm.ShapeError, "prior"),
        (dict(w_bar=-1.0), sm.InputError, "w_bar"),
        # Huge sizes: refused by the scenario's limits before anything is allocated.
        (dict(mhe=dict(horizon=100_000, eta=0.8, k=10)), sm.InputError, 'mhe["horizon"]'),
        (dict(disturbance_box=([-1e300] * 3, [0.01] * 3)), sm.InputError, "disturbance_box[0]"),
    ],
)
def test_bad_model_arguments_raise_named_errors(over, exc, names):
    with pytest.raises(exc) as info:
        model(**over)
    assert names in str(info.value), str(info.value)
    # Python names only: no Rust item leaks into the message.
    assert "::" not in str(info.value), str(info.value)


@pytest.mark.parametrize(
    "kwargs, exc, name",
    [
        (dict(methods=["pg", "newton"]), sm.InputError, "methods"),
        (dict(methods=[]), sm.InputError, "methods"),
        (dict(methods="pg"), sm.InputError, "methods"),
        (dict(gamma13=-1.0), sm.InputError, "gamma13"),
        (dict(phase_seconds=0.0), sm.InputError, "phase_seconds"),
        (dict(seed=-1), sm.OutOfRangeError, "seed"),
    ],
)
def test_bad_certify_arguments_raise_named_errors(kwargs, exc, name):
    m = model()
    with pytest.raises(exc) as info:
        sm.certify(m, **kwargs)
    assert f"`{name}`" in str(info.value) and "::" not in str(info.value), str(info.value)


def test_model_needs_a_plant():
    with pytest.raises(sm.InputError, match="`plant`"):
        sm.Model("double-integrator", mhe=dict(horizon=9, eta=0.8, k=10), mpc_horizon=10)


def test_docs_quick_start_runs(root, capsys):
    # docs/python.md's quick start, as written: a certified estimator on one's own plant.
    doc = (root / "docs" / "python.md").read_text()
    code = doc.split("## Quick start")[1].split("```python\n")[1].split("```")[0]
    assert len(code.strip().splitlines()) <= 15
    ns = {}
    exec(compile(code, "docs/python.md", "exec"), ns)
    assert ns["cert"].verdict("admm-pr", 200)["certified"] == "yes"
    assert ns["cert"].k_min("admm-pr") == 189
    assert ns["sim"]["x"].shape == (101, 2)
