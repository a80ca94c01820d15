#!/usr/bin/env python3
"""Fits the instruction model of crates/mhe-budget to the measured points.

Reads crates/mhe-budget/data/cortex-m-points.csv (`bash scripts/cortex-m.sh calibrate`) and
writes crates/mhe-budget/data/cortex-m-model.csv: per (target, method, scalar) the coefficients of

    instructions(K) = c0 + c_fixed * F + K * (c_quad * n^2 + c_lin * n)

with n = n_z and F = n * n_theta + M * n_x * (2 n_x + n_u) (+ 2 n^2 for ADMM): the
multiply-adds of the step outside the K iterations (q = q0 + F theta, the propagation of
x0 through the window, and ADMM's two products at the warm start), counted from the loops
of the portable kernel (crates/mhe-embedded/src/qp.rs, estimator.rs); n^2 are the
multiply-adds of an iteration's matrix-vector product and n its vector update.

Fitted on the points with K in FIT_KS (weighted least squares on the relative error);
the points at the other K are held out, and each row stores the worst relative error over
the held-out points (`held_out_rel_err`) and over all points (`max_rel_err`).

The MPC's share of a loop step (cortex-m-mpc-points.csv, the `mpc_control` part of the loop
program at K_c = k) gets the same model in cortex-m-mpc-model.csv, with n = N n_u,
n_theta = n_x and no propagation term (the MPC's q = F x_hat is its only product outside
the iterations, + 2 n^2 for ADMM's warm start).
Pure Python (no numpy).
"""
import csv
import math
import os
import subprocess
import sys

FIT_KS = {1, 256}
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
DATA = os.path.join(ROOT, "crates", "mhe-budget", "data")


def features(p):
    n, nth = int(p["n"]), int(p["n_theta"])
    # The MPC's points: no propagation of x0 through a window.
    m = 0 if "mhe_k" in p else int(p["horizon"])
    nx, nu = int(p["nx"]), int(p["nu"])
    k = int(p["k"])
    fixed = n * nth + m * nx * (2 * nx + nu)
    if p["method"].startswith("admm"):
        fixed += 2 * n * n
    return [1.0, float(fixed), float(k * n * n), float(k * n)]


def solve(a, b):
    """Gaussian elimination with partial pivoting."""
    n = len(b)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for c in range(n):
        piv = max(range(c, n), key=lambda r: abs(m[r][c]))
        m[c], m[piv] = m[piv], m[c]
        if m[c][c] == 0.0:
            sys.exit("singular normal equations: too few distinct sizes / K")
        for r in range(n):
            if r != c:
                f = m[r][c] / m[c][c]
                for j in range(c, n + 1):
                    m[r][j] -= f * m[c][j]
    return [m[i][n] / m[i][i] for i in range(n)]


def fit(points):
    # Columns scaled to unit max so the normal equations are well conditioned.
    rows = [features(p) for p in points]
    scale = [max(abs(r[j]) for r in rows) or 1.0 for j in range(4)]
    ata = [[0.0] * 4 for _ in range(4)]
    atb = [0.0] * 4
    for p, r in zip(points, rows):
        y = float(p["max"])
        w = 1.0 / y  # relative error
        x = [r[j] / scale[j] * w for j in range(4)]
        for i in range(4):
            atb[i] += x[i] * y * w
            for j in range(4):
                ata[i][j] += x[i] * x[j]
    c = solve(ata, atb)
    return [c[j] / scale[j] for j in range(4)]


def up4(x):
    """x rounded up to 4 decimals, so the stored bound still bounds every point."""
    return "%.4f" % (math.ceil(x * 1e4) / 1e4)


def predict(c, p):
    return sum(ci * fi for ci, fi in zip(c, features(p)))


def main():
    fit_file("cortex-m-points.csv", "cortex-m-model.csv", "MHE step")
    mpc = os.path.join(DATA, "cortex-m-mpc-points.csv")
    if os.path.exists(mpc):
        fit_file("cortex-m-mpc-points.csv", "cortex-m-mpc-model.csv", "MPC control")


def fit_file(points_name, model_name, what):
    src = os.path.join(DATA, points_name)
    lines = [l for l in open(src) if not l.startswith("#")]
    points = list(csv.DictReader(lines))
    header = [l for l in open(src) if l.startswith("#")]
    groups = {}
    for p in points:
        # Points of an older file have no scalar column: f64 exports.
        scalar = p.get("scalar") or "f64"
        groups.setdefault((p["target"], p["method"], scalar), []).append(p)
    out = []
    worst = 0.0
    for (target, method, scalar), ps in sorted(groups.items(), key=lambda g: (g[0][2] != "f64", g[0])):
        train = [p for p in ps if int(p["k"]) in FIT_KS]
        held = [p for p in ps if int(p["k"]) not in FIT_KS]
        c = fit(train)
        rel = lambda p: abs(predict(c, p) - float(p["max"])) / float(p["max"])
        held_err = max((rel(p) for p in held), default=float("nan"))
        all_err = max(rel(p) for p in ps)
        worst = max(worst, held_err)
        ns = [int(p["n"]) for p in ps]
        ks = [int(p["k"]) for p in ps]
        out.append([target, method] + ["%.6e" % v for v in c] +
                   [min(ns), max(ns), min(ks), max(ks), len(train), len(held),
                    up4(held_err), up4(all_err), scalar])
        print(f"{what}: {target:10} {method:15} {scalar} held-out max rel err {held_err:.4f}, all {all_err:.4f}")
    rev = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True).stdout.strip() or "unknown"
    with open(os.path.join(DATA, model_name), "w") as f:
        f.write(f"# {what}: instructions(K) = c0 + c_fixed*F + K*(c_quad*n^2 + c_lin*n), fitted by\n")
        f.write(f"# scripts/fit-instructions.py (commit {rev}) on the points with K in "
                f"{sorted(FIT_KS)} of {points_name}:\n")
        f.writelines(header)
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["target", "method", "c0", "c_fixed", "c_quad", "c_lin", "n_min", "n_max",
                    "k_min", "k_max", "fit_points", "held_out_points", "held_out_rel_err",
                    "max_rel_err", "scalar"])
        w.writerows(out)
    print(f"{what}: worst held-out relative error {worst:.4f}; wrote {DATA}/{model_name}")


if __name__ == "__main__":
    main()
