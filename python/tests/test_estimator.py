"""The Estimator against an independent answer and its input checks."""

import numpy as np
import pytest

import suboptimal_mhe as sm

A = [[1.0, 0.1], [0.0, 1.0]]
B = [[0.005], [0.1]]
C = [[1.0, 0.0]]


def plant():
    return sm.Plant(A, B, C)


def test_plant_dims_and_defaults():
    p = plant()
    assert (p.nx, p.nu, p.ny, p.nw) == (2, 1, 1, 3)
    np.testing.assert_array_equal(p.E, np.eye(2))
    np.testing.assert_array_equal(p.F, np.eye(1))
    np.testing.assert_array_equal(p.A, np.array(A))


def test_noise_free_estimate_converges_to_the_true_state():
    # Independent answer: with w ≡ 0 the true trajectory is simulated here in NumPy; the
    # certified MHE is robustly stable (Theorem 1), so its error decays from ‖x₀ − x̄₀‖ ≈ 1.1
    # (the prior term keeps it from vanishing exactly at a fixed K). A wrong u, y order or
    # an ignored input would leave an O(1) error.
    p = plant()
    est = sm.Estimator(p, horizon=10, eta=0.8, k=200, method="fista")
    a, b, c = np.array(A), np.array(B), np.array(C)
    x = np.array([1.0, -0.5])
    for t in range(40):
        x_hat = est.estimate()
        u = np.array([np.sin(0.3 * t)])
        est.push(u, c @ x)
        x = a @ x + b @ u
    assert est.t == 40
    assert np.linalg.norm(est.estimate() - x) < 1e-3


def test_first_estimate_is_the_prior_and_reset_restarts():
    est = sm.Estimator(plant(), horizon=5, eta=0.8, k=10, prior=[0.3, -0.2])
    np.testing.assert_array_equal(est.estimate(), [0.3, -0.2])
    est.push([0.0], [1.0])
    assert est.t == 1
    est.reset([1.0, 2.0])
    assert est.t == 0
    np.testing.assert_array_equal(est.estimate(), [1.0, 2.0])


def test_estimate_into_out_equals_estimate():
    e1 = sm.Estimator(plant(), horizon=5, eta=0.8, k=10, method="admm")
    e2 = sm.Estimator(plant(), horizon=5, eta=0.8, k=10, method="admm")
    out = np.empty(2)
    for t in range(12):
        y = [np.cos(t)]
        e1.push([0.1], y)
        e2.push([0.1], y)
        assert e1.estimate(out) is out
        np.testing.assert_array_equal(out, e2.estimate())


def test_p_is_the_certified_prior_weight_of_lmi2():
    # Independent check of LMI (2): G'PG - diag(ηP, Q) - H'RH ⪯ 0 (tolerance as the Rust check).
    est = sm.Estimator(plant(), horizon=5, eta=0.8, k=10)
    P = est.P
    a = np.array(A)
    c = np.array(C)
    b_bar = np.hstack([np.eye(2), np.zeros((2, 1))])
    d_bar = np.hstack([np.zeros((1, 2)), np.eye(1)])
    G = np.hstack([a, b_bar])
    H = np.hstack([c, d_bar])
    J = G.T @ P @ G - np.block([[0.8 * P, np.zeros((2, 3))], [np.zeros((3, 2)), np.eye(3)]]) - H.T @ H
    assert np.all(np.linalg.eigvalsh(P) > 0)
    assert np.max(np.linalg.eigvalsh(J)) <= 1e-8 * np.max(np.linalg.eigvalsh(G.T @ P @ G + np.eye(5)))


@pytest.mark.parametrize(
    "kwargs, exc, words",
    [
        (dict(eta=1.0), sm.OutOfRangeError, ["eta", "[0, 1)"]),
        (dict(eta=-0.1), sm.OutOfRangeError, ["eta"]),
        (dict(eta=float("nan")), sm.NonFiniteError, ["eta"]),
        (dict(k=0), sm.OutOfRangeError, ["`k`"]),
        (dict(horizon=0), sm.OutOfRangeError, ["horizon"]),
        (dict(q=np.diag([1.0, -1.0, 1.0])), sm.NotPositiveDefiniteError, ["`q`", "positive definite"]),
        (dict(q=np.ones((2, 2))), sm.ShapeError, ["`q`", "3x3"]),
        (dict(r=[[1.0, 2.0], [0.0, 1.0]]), sm.ShapeError, ["`r`"]),
        (dict(p=[[1.0, 0.5], [0.0, 1.0]]), sm.NotPositiveDefiniteError, ["`p`", "symmetric"]),
        (dict(prior=[0.0, np.inf]), sm.NonFiniteError, ["prior"]),
        (dict(prior=[0.0]), sm.ShapeError, ["prior"]),
        (dict(method="newton"), sm.InputError, ["method"]),
        (dict(q=np.array(["a"])), sm.InputError, ["`q`"]),
        (dict(dtype="float32", state_box=([-1.0, -1.0], [1.0, 1.0])), sm.UnsupportedError, ["dtype", "general constraint rows"]),
        (dict(dtype="float16"), sm.InputError, ["dtype", "float32"]),
        (dict(dtype="int8"), sm.InputError, ["dtype"]),
        (dict(horizon=10**9, eta=0.0), sm.InputError, ["argument `horizon`", "GiB"]),
        (dict(horizon=10**9), sm.InputError, ["argument `horizon`", "`eta`"]),
        (dict(horizon=200, eta=0.5), sm.InputError, ["argument `horizon`", "eta"]),
    ],
)
def test_bad_settings_raise_the_named_exception(kwargs, exc, words):
    args = dict(horizon=5, eta=0.8, k=10)
    args.update(kwargs)
    with pytest.raises(exc) as info:
        sm.Estimator(plant(), **args)
    assert isinstance(info.value, sm.MheError) and isinstance(info.value, ValueError)
    for w in words:
        assert w in str(info.value), str(info.value)


@pytest.mark.parametrize(
    "kwargs, exc, name",
    [
        (dict(A=[[1.0, 0.0]]), sm.ShapeError, "A"),
        (dict(B=[[1.0]]), sm.ShapeError, "B"),
        (dict(C=[[1.0, 0.0, 0.0]]), sm.ShapeError, "C"),
        (dict(A=[[np.nan, 0.0], [0.0, 1.0]]), sm.NonFiniteError, "A"),
        (dict(E=np.eye(3)), sm.ShapeError, "E"),
        (dict(F=np.eye(2)), sm.ShapeError, "F"),
        (dict(A=np.zeros((1, 5000))), sm.ShapeError, "A"),
        (dict(A="abc"), sm.InputError, "A"),
    ],
)
def test_bad_plants_raise_the_named_exception(kwargs, exc, name):
    args = dict(A=A, B=B, C=C)
    args.update(kwargs)
    with pytest.raises(exc, match=f"`{name}`"):
        sm.Plant(**args)


def test_bad_data_raises_and_leaves_the_estimator_unchanged():
    est = sm.Estimator(plant(), horizon=5, eta=0.8, k=10)
    est.push([0.0], [1.0])
    with pytest.raises(sm.NonFiniteError, match="y"):
        est.push([0.0], [np.nan])
    with pytest.raises(sm.NonFiniteError, match="u"):
        est.push(np.array([np.inf]), np.array([1.0]))
    with pytest.raises(sm.ShapeError, match="y"):
        est.push([0.0], [1.0, 2.0])
    with pytest.raises(sm.ShapeError, match="u"):
        est.push(np.zeros(3), np.zeros(1))
    assert est.t == 1
    with pytest.raises(sm.ShapeError, match="out"):
        est.estimate(np.empty(3))


def test_set_kernel_names_its_argument():
    sm.set_kernel("portable")
    with pytest.raises(sm.OutOfRangeError, match="name"):
        sm.set_kernel("fast")
    sm.set_kernel("portable")


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_push_takes_any_array_like_with_the_same_result(dtype):
    # float64 contiguous arrays go straight to Rust; lists, other dtypes and strided views
    # take the checked path: the same numbers, the same estimates.
    p2 = sm.Plant([[0.9, 0.1], [0.0, 0.8]], [[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0]])
    ests = [sm.Estimator(p2, horizon=4, eta=0.8, k=10, dtype=dtype) for _ in range(5)]
    for t in range(6):
        u = [0.125 * t, -0.25]  # exact in float32 too
        y = 0.5 + 0.125 * t
        ests[0].push(np.array(u), np.array([y]))
        ests[1].push(u, [y])
        ests[2].push(np.array(u, dtype=np.float32), y)  # float32 u, scalar y (n_y = 1)
        ests[3].push(np.array(u, dtype=np.float64)[::-1][::-1], np.array([y]))
        ests[4].push(np.array([u[0], 7.0, u[1]])[::2], np.array([[y]]))  # strided u, 2-D y
        xs = [e.estimate() for e in ests]
        for x in xs[1:]:
            np.testing.assert_array_equal(x, xs[0])
    est = ests[0]
    t, before = est.t, est.estimate()
    with pytest.raises(sm.ShapeError, match="`u`"):
        est.push(np.zeros(3), np.zeros(1))
    with pytest.raises(sm.ShapeError, match="`y`"):
        est.push(np.zeros(2), np.zeros((2, 2)))
    with pytest.raises(sm.NonFiniteError, match="`y`"):
        est.push(np.zeros(2, dtype=np.float32), np.array([np.nan], dtype=np.float32))
    with pytest.raises(sm.InputError, match="`u`"):
        est.push(["a", "b"], [1.0])
    assert est.t == t  # refused pushes change nothing
    np.testing.assert_array_equal(est.estimate(), before)
