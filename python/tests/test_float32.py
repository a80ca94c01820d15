"""dtype="float32": the board's f32 kernel (mhe_embedded) from Python, bit for bit."""

import numpy as np
import pytest

import suboptimal_mhe as sm

W_BOX = ([-0.1] * 5, [0.1] * 5)


@pytest.fixture(scope="module")
def case_plant(root):
    return sm.Scenario.from_file(root / "scenarios" / "case-study-certified.toml").plant


def pairs(plant, steps, seed):
    """A noisy run of the plant (u, y rows), made here in NumPy."""
    rng = np.random.default_rng(seed)
    a, b, c = plant.A, plant.B, plant.C
    x = np.array([0.5, -0.2, 0.1, 0.3])
    us, ys = [], []
    for t in range(steps):
        u = np.array([0.3 * np.sin(0.2 * t), -0.2 * np.cos(0.1 * t)])
        y = c @ x + 0.05 * rng.standard_normal(plant.ny)
        us.append(u)
        ys.append(y)
        x = a @ x + b @ u + 0.02 * rng.standard_normal(plant.nx)
    return np.array(us), np.array(ys)


@pytest.mark.parametrize("method", ["pg", "fista", "admm", "admm-pr", "pg-jacobi"])
def test_f32_estimates_equal_the_const_size_board_kernel_bit_for_bit(case_plant, method):
    # The reference is mhe_embedded::Mhe<f32, 4, 2, 1, 9, 49, 31> (the board's build, sizes
    # compiled in) on the same f32 data; the Python path runs MheRt (sizes at run time).
    # 25 steps: the growing window, the full one, and priors from the ring.
    prior = np.array([0.1, 0.0, -0.1, 0.2])
    est = sm.Estimator(case_plant, horizon=9, eta=0.8, k=30, method=method, prior=prior,
                       dtype="float32", disturbance_box=W_BOX)
    us, ys = pairs(case_plant, 25, seed=1)
    got = []
    for u, y in zip(us, ys):
        got.append(est.estimate())
        est.push(u, y)
    got.append(est.estimate())
    got = np.array(got)
    assert got.dtype == np.float32
    ref = est._native._replay_const_case_study(prior, us, ys)
    assert ref.dtype == np.float32 and ref.shape == got.shape
    np.testing.assert_array_equal(got.view(np.uint32), ref.view(np.uint32))
    # Not a trivial agreement: the f32 estimates differ from the f64 ones by rounding only.
    e64 = sm.Estimator(case_plant, horizon=9, eta=0.8, k=30, method=method, prior=prior,
                       disturbance_box=W_BOX)
    x64 = []
    for u, y in zip(us, ys):
        x64.append(e64.estimate())
        e64.push(u, y)
    x64.append(e64.estimate())
    diff = np.abs(got.astype(np.float64) - np.array(x64))
    assert 0 < diff.max() < 1e-3, diff.max()


def test_f32_estimate_into_reset_and_t(case_plant):
    est = sm.Estimator(case_plant, horizon=9, eta=0.8, k=10, dtype=np.float32)
    assert est.dtype == np.float32
    out = np.empty(4, dtype=np.float32)
    assert est.estimate(out) is out
    np.testing.assert_array_equal(out, np.zeros(4, dtype=np.float32))
    us, ys = pairs(case_plant, 3, seed=2)
    for u, y in zip(us, ys):
        est.push(u, y)
    assert est.t == 3
    np.testing.assert_array_equal(est.estimate(out), est.estimate())
    with pytest.raises(sm.ShapeError, match="float32"):
        est.estimate(np.empty(4))
    est.reset([1.0, 2.0, 3.0, 4.0])
    assert est.t == 0
    np.testing.assert_array_equal(est.estimate(), np.float32([1, 2, 3, 4]))


def test_f32_refuses_what_the_board_does_not_run(case_plant):
    # A state box makes general rows of the QP, which the board's kernel has not.
    with pytest.raises(sm.UnsupportedError, match="general constraint rows"):
        sm.Estimator(case_plant, horizon=3, eta=0.8, k=10, dtype="float32",
                     state_box=([-1.0] * 4, [1.0] * 4))
    with pytest.raises(sm.InputError, match="dtype"):
        sm.Estimator(case_plant, horizon=3, eta=0.8, k=10, dtype="float16")


def test_f32_push_refuses_values_beyond_float32_and_keeps_its_state(case_plant):
    est = sm.Estimator(case_plant, horizon=9, eta=0.8, k=10, dtype="float32")
    est.push([0.0, 0.0], [1.0])
    before = est.estimate()
    with pytest.raises(sm.NonFiniteError, match="y\\[0\\]"):
        est.push([0.0, 0.0], [1e39])  # finite in f64, +inf in f32
    with pytest.raises(sm.ShapeError, match="`u`"):
        est.push([0.0], [1.0])
    assert est.t == 1
    np.testing.assert_array_equal(est.estimate(), before)


def test_boxes_of_the_estimator_are_checked_and_active():
    plant = sm.Plant([[1.0, 0.1], [0.0, 1.0]], [[0.005], [0.1]], [[1.0, 0.0]])
    with pytest.raises(sm.ShapeError, match="disturbance_box"):
        sm.Estimator(plant, horizon=5, eta=0.8, k=10, disturbance_box=([-1.0], [1.0]))
    with pytest.raises(sm.MheError, match="disturbance_box"):
        sm.Estimator(plant, horizon=5, eta=0.8, k=10, disturbance_box=([1.0] * 3, [-1.0] * 3))
    with pytest.raises(sm.NonFiniteError, match="state_box"):
        sm.Estimator(plant, horizon=5, eta=0.8, k=10, state_box=([np.nan] * 2, [1.0] * 2))
    # A tight 𝒳 box holds x̂ inside it where the unconstrained estimate leaves it.
    free = sm.Estimator(plant, horizon=5, eta=0.8, k=200, method="admm")
    boxed = sm.Estimator(plant, horizon=5, eta=0.8, k=200, method="admm",
                         state_box=([-0.5, -0.5], [0.5, 0.5]))
    for t in range(8):
        free.push([0.0], [2.0])
        boxed.push([0.0], [2.0])
    assert free.estimate()[0] > 1.0
    # (later stages of 𝒳 are general rows, met by ADMM up to its residual after K = 200)
    assert np.all(np.abs(boxed.estimate()) <= 0.5 + 1e-3)


def test_certificate_verdict_in_f32():
    # The quick start's model (docs/python.md): certified at K = 200 in f64; f32 folds the
    # rounding model into Theorem 1 (the verdict of `export --scalar f32`).
    plant = sm.Plant(A=[[.95, .1], [0, .9]], B=[[.005], [.1]], C=[[1, 0]])
    model = sm.Model(plant, mhe=dict(horizon=10, eta=0.8, k=200, method="admm-pr"), mpc_horizon=10,
                     input_box=([-1.0], [1.0]), disturbance_box=([-.01] * 3, [.01] * 3))
    cert = sm.certify(model, methods=["admm-pr"])
    v64 = cert.verdict("admm-pr", 200)
    v32 = cert.verdict("admm-pr", 200, scalar="f32")
    assert v64["certified"] == "yes"
    # Theorem 1's f32 arm has no ADMM model, and the global loop certificate (which has one
    # since session 26) certifies nothing on this plant (its VI binds): void, saying so.
    assert v32["certified"] == "void" and "f32" in v32["reason"]
    with pytest.raises(sm.InputError, match="scalar"):
        cert.verdict("admm-pr", 200, scalar="f16")
