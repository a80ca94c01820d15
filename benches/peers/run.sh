#!/usr/bin/env bash
# Peer solvers on the case-study MHE QPs, side by side with ours (issue 6, item 8).
# Not part of the test suite. Needs python3 (with venv) and network access to PyPI.
#
# 1. exports the QPs (H, q, box, warm start z0, Clarabel's z*, and the uncondensed form)
#    of the presets paper (M = 5), certified (M = 9), m50 (M = 50) and cart-pendulum
#    (cart-pendulum-regional.toml, M = 9) to target/peers/*.json,
# 2. creates benches/peers/.venv (gitignored) and installs DAQP, OSQP, ProxQP into it,
# 3. times DAQP (cold), OSQP (warm; condensed and uncondensed) and ProxQP (warm)
#    -> target/peers/results.json,
# 4. runs `cargo bench -p benches --bench mhe`, whose table then has the peers' rows
#    (ratios against DAQP's exact solve).
#
# Usage: benches/peers/run.sh            (from anywhere; ≈ 3 min with a built workspace)
#
# target/peers is under the repository root whatever CARGO_TARGET_DIR says: the mhe bench
# reads the peers' results there.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
venv="benches/peers/.venv"
out="target/peers"

if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check \
    daqp==0.11.0 osqp==1.1.3 proxsuite==0.8.0 numpy scipy

cargo run --release --quiet -p benches --bin export_qps -- "$out"
"$venv/bin/python" benches/peers/peers.py "$out"
cargo bench -p benches --bench mhe
