"""`export()`: the CLI's export (the crate mhe-export) from Python — the same sources, the
same verdict, the same refusals, before any certificate for bad arguments."""

import json
import subprocess
import time

import pytest

import suboptimal_mhe as sm

SCENARIO = "scenarios/double-integrator.toml"
#: K_min of Theorem 1 for ADMM-PR on the double integrator (xtask/tests/cli/one_truth_cli.rs).
METHOD = "admm-pr"


@pytest.fixture(scope="module")
def exported(root, xtask, tmp_path_factory):
    """The double integrator exported at the certified K by Python and by the CLI."""
    base = tmp_path_factory.mktemp("export")
    py_out, cli_out = base / "py", base / "cli"
    summary = sm.export(root / SCENARIO, py_out, method=METHOD)
    subprocess.run(
        [str(xtask), "export", "--scenario", str(root / SCENARIO), "--out", str(cli_out),
         "--method", METHOD],
        check=True, capture_output=True, cwd=root,
    )
    return summary, py_out, cli_out


def test_export_writes_the_cli_sources_bit_for_bit(exported):
    summary, py_out, cli_out = exported
    assert summary["certified"] and summary["method"] == METHOD
    assert summary["k"] == summary["k_min"]
    sources = sorted(p.relative_to(cli_out) for p in cli_out.rglob("*") if p.is_file())
    # The CLI adds its sample-period budget and provenance to README.md / certificate.json;
    # every other file (the C sources, the data, the build files) is the same bytes.
    compared = [p for p in sources if p.name not in ("README.md", "certificate.json")]
    assert compared, sources
    for rel in compared:
        assert (py_out / rel).read_bytes() == (cli_out / rel).read_bytes(), rel
    py_cert = json.loads((py_out / "certificate.json").read_text())
    cli_cert = json.loads((cli_out / "certificate.json").read_text())
    for key in ("method", "iterations", "k_min", "certified", "loop_certified", "covers", "theorem1"):
        assert py_cert[key] == cli_cert[key], key


def test_export_refuses_an_uncertified_k_unless_asked(root, tmp_path):
    k_min = sm.export(root / SCENARIO, tmp_path / "a", method=METHOD)["k_min"]
    with pytest.raises(sm.CertificateError, match="K_min"):
        sm.export(root / SCENARIO, tmp_path / "b", method=METHOD, k=k_min - 1)
    assert not (tmp_path / "b").exists()
    s = sm.export(root / SCENARIO, tmp_path / "c", method=METHOD, k=k_min - 1, allow_uncertified=True)
    assert not s["certified"] and s["uncertified_reason"]


@pytest.mark.parametrize(
    "kwargs, exc, words",
    [
        (dict(k=0), sm.InputError, ["`k`"]),
        (dict(k=-3), sm.InputError, ["`k`"]),
        (dict(k=10**9), sm.InputError, ["`k`"]),
        (dict(k=2.5), sm.InputError, ["`k`"]),
        (dict(kc=0), sm.InputError, ["`k_c`"]),
        (dict(lang="fortran"), sm.InputError, ["`lang`"]),
        (dict(dtype="float16"), sm.InputError, ["`dtype`"]),
        (dict(method="nope"), sm.InputError, ["`method`"]),
        (dict(prefix="1bad"), sm.InputError, ["`prefix`"]),
        (dict(prefix=""), sm.InputError, ["`prefix`"]),
        (dict(mpc_method="pg"), sm.InputError, ["`mpc_method`"]),
    ],
)
def test_bad_export_arguments_are_refused_before_the_certificate(root, tmp_path, kwargs, exc, words):
    t0 = time.monotonic()
    with pytest.raises(exc) as e:
        sm.export(root / SCENARIO, tmp_path / "out", **kwargs)
    assert time.monotonic() - t0 < 2.0, "refused only after the certificate"
    for w in words:
        assert w in str(e.value), str(e.value)
    assert not (tmp_path / "out").exists()


def test_export_refuses_a_foreign_directory(root, tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    with pytest.raises(sm.MheError):
        sm.export(root / SCENARIO, tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"
