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
# Usage: scripts/python.sh   (after CI's release test build: the wheel ≈ 167 s of wall on 2 cores,
#        the workspace's crates compiled again, the registry ones shared; warm: 14–40 s;
#        docs/python.md, "Cost")
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

# The wheel's cargo build (python/ is a workspace of its own) reuses what CI's release build
# (`cargo test --workspace --release`, whose xtask XTASK is) left in CARGO_TARGET_DIR only for
# registry crates of the same version and features, and their dependents: one differing low
# crate (syn, serde, rand) rebuilt faer, gemm and clarabel (docs/python.md, "Cost"). The
# workspace's own crates are always built again: cargo hashes a path package by its path
# relative to the workspace root, which differs from python/. Name the registry crates that
# differ; a note, not a failure. Features per crate with `cargo tree` (no build) against the
# workspace with its dev-dependencies (what the test build unifies): the target-only graph (no
# proc-macros) and the whole one (proc-macros and build scripts too).
tree_features() {
    cargo tree -q "$@" --prefix none -f '{p}|{f}' 2>/dev/null | sed 's/ (\*)$//' | grep -v ' (/' | sort -u
}
not_shared() {
    local edges
    for edges in normal,no-proc-macro normal,build; do
        awk -F'|' 'NR == FNR { seen[$0] = 1; split($1, n, " "); pkg[n[1]] = 1; next }
            { split($1, n, " ") } (n[1] in pkg) && !($0 in seen) { print "    " $1 " [" $2 "]" }' \
            <(tree_features --workspace -e "$edges,dev") \
            <(tree_features --manifest-path python/Cargo.toml -e "$edges")
    done | sort -u
}
differ=$(not_shared)
if [ -n "$differ" ]; then
    say "note: the wheel builds these crates (and all that depend on them) again: python/ resolves them with other versions or features than \`cargo test --workspace --release\` (docs/python.md, \"Cost\"):"
    printf '%s\n' "$differ"
fi

VENV=${VENV:-$ROOT/target/python-venv}
if [ ! -x "$VENV/bin/python" ]; then
    say "creating the venv $VENV"
    python3 -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip
# pytest-xdist: two workers, each test file on one (`--dist loadfile`: a module's fixtures,
# such as the reproduced double integrator, are computed once).
"$VENV/bin/python" -m pip install -q pytest pytest-xdist numpy hypothesis

say "pip install ./python (maturin build backend: the release abi3 wheel)"
# The README's one command; CARGO_TARGET_DIR (exported above) keeps the build incremental.
"$VENV/bin/python" -m pip install -q --force-reinstall --no-deps "$ROOT/python"

say "pytest python/tests"
# From outside python/, so the installed wheel is tested, not the source tree.
# Two workers (the machine's cores): the slowest files (test_cli's reproduced double integrator,
# test_model's certificates from arrays and from the file, ≈ 90 s each alone) run side by side.
(cd "$CARGO_TARGET_DIR" && SUBOPTIMAL_MHE_XTASK="$XTASK" "$VENV/bin/python" -m pytest -q -p no:cacheprovider \
    -n "${PYTEST_WORKERS:-2}" --dist loadfile "$ROOT/python/tests")
say "done"
