"""Void / IOSS / skip reasons as typed data (iss_certificate::outcome)."""

import pytest

import suboptimal_mhe as sm

KINDS = {"l_phi_undefined", "controller_undefined", "premise_fails", "premise_not_evaluated",
         "gamma13", "no_k", "no_pair", "boundary_cut"}


@pytest.fixture(scope="module")
def void_cert():
    # M = 5, η = 0.8: 6·η^M ≈ 1.97 ≥ 1, so Prop. 3's premise ρ < 1 fails: Theorem 1 is void.
    plant = sm.Plant(A=[[.95, .1], [0, .9]], B=[[.005], [.1]], C=[[1, 0]])
    model = sm.Model(plant, mhe=dict(horizon=5, eta=0.8, k=200, method="pg"), mpc_horizon=10,
                     input_box=([-1.0], [1.0]), disturbance_box=([-.01] * 3, [.01] * 3))
    return sm.certify(model, methods=["pg", "fista"])


def test_void_reasons_are_typed_and_print_the_cli_sentence(void_cert):
    for m in void_cert.methods:
        typed = void_cert.reasons(m)
        assert [str(r) for r in typed] == void_cert.void_reasons(m)
        assert all(r.kind in KINDS for r in typed)
    typed = void_cert.reasons("pg")
    assert void_cert.k_min("pg") is None and typed
    fails = [r for r in typed if r.kind == "premise_fails"]
    assert fails, [repr(r) for r in typed]
    r = fails[0]
    assert r.premise == "rho < 1" and r.value >= 1.0  # ρ ≥ 1: the failed premise, as a number
    assert "6η^M = 1.966" in r.fix and r.premise in str(r) and r.fix in str(r)
    with pytest.raises(AttributeError, match="no field"):
        r.k_max


def test_ioss_and_skips_are_typed(void_cert):
    assert void_cert.ioss_failure is None  # LMI (2) holds
    assert void_cert.ioss_passed
    for s in void_cert.skipped:
        assert s.kind in {"over_variable_cap", "over_budget", "no_sequences"}
        assert s.computation and str(s)


def test_reasons_of_an_uncertified_method_name_the_argument(void_cert):
    with pytest.raises(sm.InputError, match="method"):
        void_cert.reasons("newton")
