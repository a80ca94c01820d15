"""General rows ``(G, h)`` — {v : G v ≤ h} — for the sets 𝒳, 𝒰, 𝒴, 𝒲 (issue 39, Build 1).

The library's sets are boxes (``mhe_core::MheSets``, the MPC's input box, a scenario's
``[sets]``); a bounded 𝒳 or 𝒴 becomes general rows of the QPs. Rows with one nonzero entry
are exactly such bounds and are accepted (the same estimator and certificate as the box);
a row coupling components raises ``UnsupportedError`` saying why."""

import numpy as np
import pytest

import suboptimal_mhe as sm

PLANT = sm.Plant([[1.0, 0.1], [0.0, 1.0]], [[0.005], [0.1]], [[1.0, 0.0]])
#: −0.5 ≤ x₁ ≤ 0.5 and −0.25 ≤ x₂ ≤ 0.75 as four rows, scaled (2x ≤ 1 is x ≤ 0.5).
G_X = np.array([[2.0, 0.0], [-1.0, 0.0], [0.0, 4.0], [0.0, -1.0]])
H_X = np.array([1.0, 0.5, 3.0, 0.25])
BOX_X = ([-0.5, -0.25], [0.5, 0.75])


def run(est, steps=12):
    xs = []
    for t in range(steps):
        est.push([0.1 * np.sin(t)], [2.0 + 0.1 * t])
        xs.append(est.estimate())
    return np.array(xs)


@pytest.mark.parametrize("method", ["pg", "admm"])
def test_bound_rows_give_the_box_estimator_bit_for_bit(method):
    boxed = sm.Estimator(PLANT, horizon=5, eta=0.8, k=50, method=method, state_box=BOX_X,
                         output_box=([-1.0], [1.5]), disturbance_box=([-0.2] * 3, [0.2] * 3))
    rows = sm.Estimator(PLANT, horizon=5, eta=0.8, k=50, method=method, state_rows=(G_X, H_X),
                        output_rows=([[1.0], [-2.0]], [1.5, 2.0]),
                        disturbance_rows=(np.vstack([np.eye(3), -np.eye(3)]), [0.2] * 6))
    a, b = run(boxed), run(rows)
    np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64))
    free = run(sm.Estimator(PLANT, horizon=5, eta=0.8, k=50, method=method))
    assert np.abs(free - a).max() > 0.1  # the sets are active: not a trivial agreement


def test_two_sided_rows_as_scipy_linear_constraint():
    # (G, lower, upper): lower ≤ G v ≤ upper, the form of scipy.optimize.LinearConstraint that
    # python-control's constraints use; here diag(2, 1) v ∈ [−1, 1] × [−0.25, 0.75] = BOX_X.
    two = sm.Estimator(PLANT, horizon=5, eta=0.8, k=50, state_rows=(np.diag([2.0, 1.0]), [-1.0, -0.25], [1.0, 0.75]))
    boxed = sm.Estimator(PLANT, horizon=5, eta=0.8, k=50, state_box=BOX_X)
    np.testing.assert_array_equal(run(two).view(np.uint64), run(boxed).view(np.uint64))
    # One-sided rows of a triple: ±inf is no bound.
    half = sm.Estimator(PLANT, horizon=5, eta=0.8, k=50,
                        state_rows=(np.eye(2), [-0.5, -np.inf], [np.inf, 0.75]))
    ref = sm.Estimator(PLANT, horizon=5, eta=0.8, k=50, state_box=([-0.5, -np.inf], [np.inf, 0.75]))
    np.testing.assert_array_equal(run(half), run(ref))
    # A coupled row with no bound (±inf) constrains nothing: accepted.
    free = sm.Estimator(PLANT, horizon=5, eta=0.8, k=50,
                        state_rows=([[1.0, 0.0], [1.0, 1.0]], [-0.5, -np.inf], [np.inf, np.inf]))
    np.testing.assert_array_equal(run(free), run(sm.Estimator(PLANT, horizon=5, eta=0.8, k=50,
                                                                state_box=([-0.5, -np.inf], [np.inf, np.inf]))))
    with pytest.raises(sm.UnsupportedError, match="row 1 of G couples"):
        sm.Estimator(PLANT, horizon=5, eta=0.8, k=10, state_rows=([[1.0, 0.0], [1.0, -1.0]], [-1, -1], [1, 1]))
    with pytest.raises(sm.InputError, match="row 0 of G is zero"):
        sm.Estimator(PLANT, horizon=5, eta=0.8, k=10, state_rows=([[0.0, 0.0]], [0.5], [1.0]))


def test_rows_intersect_with_a_box():
    # x₁ ≤ 0.5 from the rows, x₁ ≥ −0.5 and x₂'s bounds from the box.
    both = sm.Estimator(PLANT, horizon=5, eta=0.8, k=50, state_box=([-0.5, -0.25], [9.0, 0.75]),
                        state_rows=([[1.0, 0.0]], [0.5]))
    boxed = sm.Estimator(PLANT, horizon=5, eta=0.8, k=50, state_box=BOX_X)
    np.testing.assert_array_equal(run(both), run(boxed))


def model(**sets):
    return sm.Model(PLANT, mhe=dict(horizon=5, eta=0.8, k=100, method="pg"), mpc_horizon=5, **sets)


def test_model_rows_give_the_box_certificate():
    # The quick start's model (docs/python.md; K_min = 189 for admm-pr) with 𝒰 and 𝒲 as rows.
    plant = sm.Plant(A=[[.95, .1], [0, .9]], B=[[.005], [.1]], C=[[1, 0]])
    mhe = dict(horizon=10, eta=0.8, k=200, method="admm-pr")
    a = sm.certify(sm.Model(plant, mhe=mhe, mpc_horizon=10, input_box=([-1.0], [1.0]),
                            disturbance_box=([-.01] * 3, [.01] * 3)), methods=["admm-pr"])
    b = sm.certify(sm.Model(plant, mhe=mhe, mpc_horizon=10, input_rows=([[2.0], [-1.0]], [2.0, 1.0]),
                            disturbance_rows=(np.vstack([np.eye(3), -np.eye(3)]), [.01] * 6)),
                   methods=["admm-pr"])
    assert a.to_dict() == b.to_dict()
    assert a.k_min("admm-pr") is not None


@pytest.mark.parametrize(
    "kwargs, exc, words",
    [
        # A coupled row: not representable by the library's sets.
        (dict(state_rows=([[1.0, 1.0]], [1.0])), sm.UnsupportedError, ["state_rows", "row 0", "couples", "boxes"]),
        (dict(disturbance_rows=([[0.0, 1.0, -1.0]], [0.1])), sm.UnsupportedError, ["disturbance_rows", "[1, 2]"]),
        (dict(state_rows=([[1.0, 0.0, 0.0]], [1.0])), sm.ShapeError, ["state_rows[0]", "x2"]),
        (dict(state_rows=([[1.0, 0.0]], [1.0, 2.0])), sm.ShapeError, ["state_rows[1]", "length 1"]),
        (dict(output_rows=([[np.nan]], [1.0])), sm.NonFiniteError, ["output_rows[0]"]),
        (dict(output_rows=([[1.0]], [np.nan])), sm.NonFiniteError, ["output_rows[1]"]),
        (dict(output_rows=([[1.0]],)), sm.InputError, ["output_rows", "(G, h)"]),
        (dict(state_rows=([[0.0, 0.0]], [-1.0])), sm.InputError, ["state_rows", "empty"]),
        (dict(state_rows=([[1.0, 0.0], [-1.0, 0.0]], [-1.0, -1.0])), sm.InputError, ["state_rows", "empty"]),
        (dict(state_box=([0.0, 0.0], [1.0, 1.0]), state_rows=([[1.0, 0.0]], [-0.5])), sm.InputError,
         ["state_box` with `state_rows", "empty"]),
    ],
)
def test_bad_rows_raise_the_named_exception(kwargs, exc, words):
    with pytest.raises(exc) as e:
        sm.Estimator(PLANT, horizon=5, eta=0.8, k=10, **kwargs)
    for w in words:
        assert w in str(e.value), str(e.value)


def test_model_rows_must_contain_the_origin_and_couplings_are_refused():
    with pytest.raises(sm.InputError, match=r"`input_rows`: the set must contain 0 \(Assumption 1\)"):
        model(input_rows=([[-1.0]], [-0.5]))  # u ≥ 0.5
    with pytest.raises(sm.UnsupportedError, match="input_rows.*couples"):
        sm.Model(sm.Plant(np.eye(2) * 0.9, np.eye(2), [[1.0, 0.0]]),
                 mhe=dict(horizon=5, eta=0.8, k=100), mpc_horizon=5, input_rows=([[1.0, 1.0]], [1.0]))


def test_combinations_the_library_does_not_cover_say_why(tmp_path):
    # The board's f32 kernel has no general rows: a state or output bound refuses float32.
    with pytest.raises(sm.UnsupportedError, match="general constraint rows"):
        sm.Estimator(PLANT, horizon=5, eta=0.8, k=10, dtype="float32", output_rows=([[1.0]], [1.5]))
    # 𝒲 rows are a box of the QP: float32 runs.
    sm.Estimator(PLANT, horizon=5, eta=0.8, k=10, dtype="float32",
                 disturbance_rows=(np.vstack([np.eye(3), -np.eye(3)]), [0.2] * 6))
    # ADMM on general rows: its certificate is void (data, not an exception), with the reason.
    m = model(state_rows=(G_X, H_X), input_box=([-1.0], [1.0]), disturbance_box=([-0.01] * 3, [0.01] * 3))
    cert = sm.certify(m, methods=["admm"])
    assert cert.k_min("admm") is None and cert.void_reasons("admm")
