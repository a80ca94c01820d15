#!/usr/bin/env python3
"""Times DAQP (cold), OSQP (warm-started; condensed and uncondensed) and ProxQP
(warm-started) on the case-study MHE QPs exported by `cargo run --release -p benches --bin export_qps` and writes
target/peers/results.json, which `cargo bench -p benches --bench mhe` merges into its table.

Each QP is  min 0.5 z'Hz + q'z  s.t.  lower <= z <= upper  (H, bounds shared by the
instances of a preset; q, the MHE warm start z0 and Clarabel's z* per instance).

Timing: the solvers' own timers (C/C++ time, no Python overhead), summed over all
instances of a preset per round, for ROUNDS rounds taken in turn (solver by solver within a
round, as the Rust bench does); reported: the fastest and the median round's mean time per
instance. Python wall time per call is reported beside it.

- DAQP: `daqp.solve` per instance, nothing reused (setup + solve = its cold exact solve);
  simple bounds, infinite bounds passed as +-1e30 (DAQP's infinity).
- OSQP: set up once; per instance `update(q)`, `warm_start(x=z0)` (the dual is kept
  from the previous instance, as in a running MHE), `solve()`; time = update + solve +
  polish. eps_abs = eps_rel = the tolerance below, polishing off (at most instances no
  bound is active, so there is nothing to polish), max_iter 100000.
- OSQP uncondensed ("osqp_sparse"): the same QP with the window's states as variables and
  the dynamics as equality constraints (the file's "sparse" section: P, A_eq, per instance
  q, b, the lifted warm start v0); A = [A_eq; rows of I for the bounded variables]. Set up
  once; per instance `update(q, l, u)` (b enters l = u of the equality rows),
  `warm_start(x=v0)` (dual kept), `solve()`; same settings as OSQP. Its error is measured
  on the condensed part of v (x0, w) against z*.
- ProxQP (dense, box constraints): set up once; per instance `update(g=q)` (H unchanged:
  no preconditioner update) and a solve warm-started at z0 (InitialGuess.WARM_START);
  time = its run_time (update + solve). eps_abs = the tolerance below.

Tolerances: per preset and solver, the loosest of 1e-6, 1e-7, ..., 1e-13 whose solutions
are all "solved" and within the benchmark's accuracy (the file's eps, 1e-6) of z*
relative to ||z0 - z*|| on every instance — found in untimed calibration passes before
the timing (on the M = 5 and 9 presets 1e-7 leaves 2e-6 (OSQP) and 4e-6 (ProxQP)).
A solver that meets it at no tolerance is timed at the tightest, and its error shows it.

Every solution is checked against z*: the largest ||z - z*|| / ||z0 - z*|| per solver is
reported (the benchmark's accuracy target is 1e-6); a solver that fails to report
"solved" on any instance makes the script exit non-zero.

Usage: peers.py [DIR]   (DIR holds paper.json, certified.json, m50.json,
cart-pendulum.json; default target/peers; a preset whose file is missing is skipped)
"""

import json
import os
import platform
import statistics
import sys
import time

import numpy as np
import scipy.sparse as sp

import daqp
import osqp
import proxsuite

ROUNDS = 50
DAQP_INF = 1e30
TOLERANCES = [10.0**-k for k in range(6, 14)]


def load(path):
    with open(path) as f:
        d = json.load(f)
    return d, *dense(d)


def dense(d):
    n = d["n"]
    H = np.array(d["H"], dtype=float).reshape(n, n)
    lo = np.array([-np.inf if v is None else v for v in d["lower"]], dtype=float)
    up = np.array([np.inf if v is None else v for v in d["upper"]], dtype=float)
    inst = [
        (np.array(i["q"], dtype=float), np.array(i["z0"], dtype=float), np.array(i["z_star"], dtype=float))
        for i in d["instances"]
    ]
    return H, lo, up, inst


def bounds(values, inf):
    return np.array([inf if v is None else v for v in values], dtype=float)


class Daqp:
    name = "daqp"

    def __init__(self, H, lo, up, eps=None):
        self.H = np.ascontiguousarray(H)
        self.A = np.zeros((0, H.shape[0]))
        self.bu = np.where(np.isfinite(up), up, DAQP_INF)
        self.bl = np.where(np.isfinite(lo), lo, -DAQP_INF)
        self.sense = np.zeros(H.shape[0], dtype=np.int32)

    def solve(self, q, z0):
        x, _, flag, info = daqp.solve(self.H, q, self.A, self.bu, self.bl, self.sense)
        return x, flag == 1, info["setup_time"] + info["solve_time"], info["iterations"]


class Osqp:
    name = "osqp"

    def __init__(self, H, lo, up, eps):
        n = H.shape[0]
        self.m = osqp.OSQP()
        self.m.setup(
            P=sp.csc_matrix(np.triu(H)),
            q=np.zeros(n),
            A=sp.csc_matrix(np.eye(n)),
            l=lo,
            u=up,
            verbose=False,
            eps_abs=eps,
            eps_rel=eps,
            warm_starting=True,
            polishing=False,
            max_iter=100000,
        )

    def solve(self, q, z0):
        self.m.update(q=q)
        self.m.warm_start(x=z0)
        r = self.m.solve()
        i = r.info
        ok = i.status == "solved"
        return r.x, ok, i.update_time + i.solve_time + i.polish_time, i.iter


class OsqpSparse:
    """OSQP on the uncondensed QP; `solve` takes the instance index (q, b, v0 per instance)."""

    name = "osqp_sparse"

    def __init__(self, sparse, eps):
        n = sparse["n"]
        P = sp.csc_matrix((sparse["P"]["v"], (sparse["P"]["i"], sparse["P"]["j"])), shape=(n, n))
        ae = sparse["A_eq"]
        A_eq = sp.csc_matrix((ae["v"], (ae["i"], ae["j"])), shape=(ae["m"], n))
        lo = bounds(sparse["lower"], -np.inf)
        up = bounds(sparse["upper"], np.inf)
        boxed = np.flatnonzero(np.isfinite(lo) | np.isfinite(up))
        I_box = sp.csc_matrix((np.ones(len(boxed)), (np.arange(len(boxed)), boxed)), shape=(len(boxed), n))
        self.m_eq = ae["m"]
        self.lo_box, self.up_box = lo[boxed], up[boxed]
        self.z_index = np.array(sparse["z_index"])
        self.inst = [
            (np.array(i["q"], dtype=float), np.array(i["b"], dtype=float), np.array(i["v0"], dtype=float))
            for i in sparse["instances"]
        ]
        b0 = self.inst[0][1]
        self.m = osqp.OSQP()
        self.m.setup(
            P=P,
            q=np.zeros(n),
            A=sp.vstack([A_eq, I_box], format="csc"),
            l=np.concatenate([b0, self.lo_box]),
            u=np.concatenate([b0, self.up_box]),
            verbose=False,
            eps_abs=eps,
            eps_rel=eps,
            warm_starting=True,
            polishing=False,
            max_iter=100000,
        )

    def solve(self, k):
        q, b, v0 = self.inst[k]
        self.m.update(q=q, l=np.concatenate([b, self.lo_box]), u=np.concatenate([b, self.up_box]))
        self.m.warm_start(x=v0)
        r = self.m.solve()
        i = r.info
        ok = i.status == "solved"
        return r.x[self.z_index], ok, i.update_time + i.solve_time + i.polish_time, i.iter


class ProxQp:
    name = "proxqp"

    def __init__(self, H, lo, up, eps):
        n = H.shape[0]
        self.qp = proxsuite.proxqp.dense.QP(n, 0, 0, True)
        self.qp.settings.eps_abs = eps
        self.qp.settings.verbose = False
        self.qp.settings.compute_timings = True
        self.qp.init(H, np.zeros(n), None, None, None, None, None, l_box=lo, u_box=up)
        self.qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START

    def solve(self, q, z0):
        self.qp.update(g=q, update_preconditioner=False)
        self.qp.solve(z0, None, None)
        r = self.qp.results
        ok = r.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
        return r.x, ok, r.info.run_time * 1e-6, r.info.iter


def solve_all(s, inst):
    """Every instance once: (worst ||z - z*|| / ||z0 - z*||, failures, iterations)."""
    worst, failures, iters = 0.0, 0, []
    for k, (q, z0, zs) in enumerate(inst):
        x, ok, _, it = s.solve(k) if isinstance(s, OsqpSparse) else s.solve(q, z0)
        worst = max(worst, float(np.linalg.norm(np.asarray(x) - zs) / np.linalg.norm(z0 - zs)))
        failures += 0 if ok else 1
        iters.append(int(it))
    return worst, failures, iters


def calibrated(make, inst, eps):
    """The solver at the loosest tolerance that meets the accuracy eps (untimed passes)."""
    for tol in TOLERANCES:
        s = make(tol)
        worst, failures, _ = solve_all(s, inst)
        if failures == 0 and worst <= eps:
            break
    s = make(tol)  # fresh: the timed rounds start from the same state as a first use
    s.tolerance = tol
    return s


def run_preset(path):
    d, H, lo, up, inst = load(path)
    eps = d["eps"]
    solvers = [
        Daqp(H, lo, up),
        calibrated(lambda tol: Osqp(H, lo, up, tol), inst, eps),
        calibrated(lambda tol: OsqpSparse(d["sparse"], tol), inst, eps),
        calibrated(lambda tol: ProxQp(H, lo, up, tol), inst, eps),
    ]
    solvers[0].tolerance = None
    per_round = {s.name: [] for s in solvers}
    wall = {s.name: [] for s in solvers}
    iters = {s.name: [] for s in solvers}
    worst = {s.name: 0.0 for s in solvers}
    failures = {s.name: 0 for s in solvers}
    for r in range(ROUNDS + 1):  # round 0 is a warm-up, not recorded
        for s in solvers:
            total = 0.0
            start = time.perf_counter()
            for k, (q, z0, zs) in enumerate(inst):
                x, ok, t, it = s.solve(k) if isinstance(s, OsqpSparse) else s.solve(q, z0)
                total += t
                if r == 0:
                    iters[s.name].append(int(it))
                    e0 = np.linalg.norm(z0 - zs)
                    worst[s.name] = max(worst[s.name], float(np.linalg.norm(np.asarray(x) - zs) / e0))
                    failures[s.name] += 0 if ok else 1
            elapsed = time.perf_counter() - start
            if r > 0:
                per_round[s.name].append(total / len(inst) * 1e9)
                wall[s.name].append(elapsed / len(inst) * 1e9)
    out = {}
    for s in solvers:
        k = sorted(iters[s.name])
        out[s.name] = {
            "solve_ns": {"min": min(per_round[s.name]), "median": statistics.median(per_round[s.name])},
            "python_wall_ns": {"min": min(wall[s.name]), "median": statistics.median(wall[s.name])},
            "iterations": {"min": k[0], "median": k[len(k) // 2], "max": k[-1]},
            "worst_rel_error": worst[s.name],
            "failures": failures[s.name],
            "tolerance": s.tolerance,
        }
    return d, out


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    default = os.path.join(here, "..", "..", "target", "peers")
    folder = sys.argv[1] if len(sys.argv) > 1 else default
    result = {
        "rounds": ROUNDS,
        "started_unix": time.time(),
        "python": platform.python_version(),
        "machine": platform.processor() or platform.machine(),
        "versions": {
            "daqp": getattr(daqp, "__version__", None) or pkg_version("daqp"),
            "osqp": osqp.__version__,
            "proxsuite": getattr(proxsuite, "__version__", None) or pkg_version("proxsuite"),
        },
        "presets": {},
    }
    failed = False
    for preset in ["paper", "certified", "m50", "cart-pendulum"]:
        path = os.path.join(folder, preset + ".json")
        if not os.path.exists(path):
            print("no", path, "- skipped")
            continue
        d, out = run_preset(path)
        out["fingerprint"] = d["fingerprint"]
        out["instances"] = len(d["instances"])
        result["presets"][preset] = out
        for name in ["daqp", "osqp", "osqp_sparse", "proxqp"]:
            o = out[name]
            print(
                f"{preset} (n = {d['n']}): {name:7s} {o['solve_ns']['min'] / 1e3:8.2f} us "
                f"(median {o['solve_ns']['median'] / 1e3:8.2f} us, python wall {o['python_wall_ns']['min'] / 1e3:8.2f} us), "
                f"iterations {o['iterations']['median']}/{o['iterations']['max']}, "
                f"worst ||z - z*||/||z0 - z*|| = {o['worst_rel_error']:.1e}, failures {o['failures']}, "
                f"tolerance {o['tolerance']}"
            )
            failed |= o["failures"] > 0
    with open(os.path.join(folder, "results.json"), "w") as f:
        json.dump(result, f, indent=1)
    print("wrote", os.path.join(folder, "results.json"))
    return 1 if failed else 0


def pkg_version(name):
    from importlib.metadata import version

    return version(name)


if __name__ == "__main__":
    sys.exit(main())
