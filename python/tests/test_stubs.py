"""The type stubs shipped in the wheel (``__init__.pyi``) parse and match the module: every
public name is declared, and the signatures of the public callables list the same parameters
(issue 39, Conventions: type stubs)."""

import ast
import inspect
import pathlib

import pytest

import suboptimal_mhe as sm

STUB = pathlib.Path(sm.__file__).with_name("__init__.pyi")


@pytest.fixture(scope="module")
def stub():
    assert STUB.is_file(), f"{STUB} is not in the installed package"
    return ast.parse(STUB.read_text(), filename=str(STUB))  # a SyntaxError fails here


def declared(tree):
    """Top-level names of the stub: classes, functions, assignments; class → its functions."""
    names, methods = {}, {}
    for node in tree.body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
            names[node.name] = node
            if isinstance(node, ast.ClassDef):
                methods[node.name] = {n.name: n for n in node.body if isinstance(n, ast.FunctionDef)}
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names[node.target.id] = node
        elif isinstance(node, ast.Assign):
            for t in node.targets:
                if isinstance(t, ast.Name):
                    names[t.id] = node
    return names, methods


def params(fn):
    a = fn.args
    return [p.arg for p in a.posonlyargs + a.args + a.kwonlyargs]


def test_every_public_name_is_in_the_stub(stub):
    names, _ = declared(stub)
    missing = [n for n in sm.__all__ if n not in names]
    assert not missing, missing


@pytest.mark.parametrize("name", ["certify", "simulate", "sweep", "export", "set_kernel"])
def test_function_signatures_match(stub, name):
    names, _ = declared(stub)
    assert params(names[name]) == list(inspect.signature(getattr(sm, name)).parameters), name


@pytest.mark.parametrize("cls", ["Plant", "Estimator", "Model"])
def test_constructor_signatures_match(stub, cls):
    _, methods = declared(stub)
    runtime = ["self", *inspect.signature(getattr(sm, cls)).parameters]
    assert params(methods[cls]["__init__"]) == runtime, cls
