#!/usr/bin/env bash
# Builds the Python package (python/: PyO3 + maturin, one abi3 wheel for CPython >= 3.9),
# installs it into a fresh virtual environment and runs its pytest suite (docs/python.md):
#
#   1. python3 with venv and the headers: installed with apt-get when missing (root only;
#      otherwise the script stops with a message and status 0, like a skipped step);
#   2. a venv (VENV, default target/python-venv) with pytest, numpy, hypothesis;
#   3. `pip install ./python` (pyproject.toml: maturin as the build backend, fetched by pip;
#      it builds the release abi3 wheel in CARGO_TARGET_DIR and installs it);
#   4. pytest on python/tests, comparing with the release CLI (XTASK, built when missing).
#
# Usage: scripts/python.sh   (cold: 6.2 CPU-min, ≈ 3–4 min on 2 idle cores; warm: 14–40 s; docs/python.md)
# Env: VENV=dir  XTASK=path/to/xtask  CARGO_TARGET_DIR (default: the workspace's target/)
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT=$PWD
START=$(date +%s)
say() { printf '[python %3ss] %s\n' "$(($(date +%s) - START))" "$*"; }

have_python() {
    command -v python3 >/dev/null && python3 -c 'import venv, ensurepip, sysconfig, os, sys
sys.exit(0 if os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")) else 1)' 2>/dev/null
}
if ! have_python; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        say "installing python3, python3-venv and python3-dev with apt-get"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq
        apt-get install -y -qq python3 python3-venv python3-dev >/dev/null
    else
        say "skipped: python3 with venv and headers is missing and installing it needs root (apt-get)"
        exit 0
    fi
fi
say "$(python3 --version)"

export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$ROOT/target}
# Built (incrementally) whenever XTASK is not given: a binary left from an older checkout
# made the comparisons fail (or pass) against the wrong CLI.
if [ -z "${XTASK:-}" ]; then
    XTASK=$CARGO_TARGET_DIR/release/xtask
    say "building the release xtask (the CLI the tests compare with)"
    cargo build -q -p xtask --release
fi

VENV=${VENV:-$ROOT/target/python-venv}
if [ ! -x "$VENV/bin/python" ]; then
    say "creating the venv $VENV"
    python3 -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q pytest numpy hypothesis

say "pip install ./python (maturin build backend: the release abi3 wheel)"
# The README's one command; CARGO_TARGET_DIR (exported above) keeps the build incremental.
"$VENV/bin/python" -m pip install -q --force-reinstall --no-deps "$ROOT/python"

say "pytest python/tests"
# From outside python/, so the installed wheel is tested, not the source tree.
(cd "$CARGO_TARGET_DIR" && SUBOPTIMAL_MHE_XTASK="$XTASK" "$VENV/bin/python" -m pytest -q -p no:cacheprovider "$ROOT/python/tests")
say "done"
