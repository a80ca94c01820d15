#!/usr/bin/env python3
"""Reference solutions of LMI (2) for the scale table of lti-model/tests/all/ioss_scale.rs.

Run once, outside the tests (CI does not need Python):

    python3 -m venv /tmp/sdp && /tmp/sdp/bin/pip install cvxpy clarabel numpy scipy
    /tmp/sdp/bin/python scripts/lmi2_reference.py

For each plant and weight ratio r/q (Q = q I, R = r I, E = I, F = I) it solves the SDP

    maximise trace(P)  s.t.  G'PG - diag(eta P, Q) - H'RH <= 0,  P >= 0,

G = [A  [I 0]], H = [C  [0 I]], with Clarabel through CVXPY. The maximiser is the maximal
solution P* of LMI (2) (it dominates every feasible P, so it maximises the trace). The
printed P (with q = 1) is pinned in the test; the other rows of the table (common weight
scalings 1e-12 ... 1e12 and diagonal unit changes x = T x~) follow from it exactly:
P(c Q, c R) = c P and P~ = T P T.
"""
import numpy as np
import scipy.linalg as sla
import cvxpy as cp


def zoh(ac, bc, ts):
    n, m = bc.shape
    blk = np.zeros((n + m, n + m))
    blk[:n, :n] = ac * ts
    blk[:n, n:] = bc * ts
    e = sla.expm(blk)
    return e[:n, :n], e[:n, n:]


def afti16():
    # MATLAB MPC Toolbox demo afti16 (Kapasouris, Athans, Stein 1990), speed in 100 ft/s.
    ac = np.array([[-0.0151, -60.5651, 0, -32.174],
                   [-0.0001, -1.3411, 0.9929, 0],
                   [0.00018, 43.2541, -0.86939, 0],
                   [0, 0, 1, 0]])
    bc = np.array([[-2.516, -13.136], [-0.1689, -0.2514], [-17.251, -1.5766], [0, 0]])
    s = np.diag([0.01, 1, 1, 1])
    ac = s @ ac @ np.linalg.inv(s)
    bc = s @ bc
    a, _ = zoh(ac, bc, 0.05)
    return a, np.array([[0, 1.0, 0, 0], [0, 0, 0, 1.0]])


def case_study():
    a = np.array([[0.7, -0.1, 0, 0], [0.2, -0.5, 0.1, 0], [0, 0.1, 0.1, 0], [0.5, 0, 0.5, 0.5]])
    return a, np.array([[0.1, 0.3, 0.8, 0.5]])


def double_integrator():
    a, _ = zoh(np.array([[0, 1.0], [0, 0]]), np.array([[0], [1.0]]), 0.1)
    return a, np.array([[1.0, 0]])


def solve(a, c, eta, q, r):
    """Two passes: the second in the coordinates x = T x~, T = diag(P1)^(-1/2) of the first
    pass's answer (a congruence: P = T^-1 P~ T^-1), which balances the SDP when the states
    differ in scale (AFTI-16: P[0,0] ~ 1e-6 against P[1,1] ~ 0.6)."""
    status, p1 = solve_once(a, c, np.eye(a.shape[0]), eta, q, r)
    t = np.diag(1.0 / np.sqrt(np.diag(p1)))
    status, pt = solve_once(np.linalg.inv(t) @ a @ t, c @ t, np.linalg.inv(t), eta, q, r)
    ti = np.linalg.inv(t)
    return status, ti @ pt @ ti


def solve_once(a, c, e, eta, q, r):
    n, ny = a.shape[0], c.shape[0]
    g = np.hstack([a, e, np.zeros((n, ny))])
    h = np.hstack([c, np.zeros((ny, n)), np.eye(ny)])
    p = cp.Variable((n, n), symmetric=True)
    qm = q * np.eye(n + ny)
    z = np.zeros((n, n + ny))
    lhs = g.T @ p @ g - cp.bmat([[eta * p, z], [z.T, np.zeros((n + ny, n + ny))]])[: 2 * n + ny, : 2 * n + ny]
    blk = np.zeros((2 * n + ny, 2 * n + ny))
    blk[n:, n:] = qm
    j = lhs - blk - r * (h.T @ h)
    prob = cp.Problem(cp.Maximize(cp.trace(p)), [(j + j.T) / 2 << 0, p >> 0])
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10, max_iter=500)
    return prob.status, p.value


if __name__ == "__main__":
    for name, (a, c), eta in [("case_study", case_study(), 0.8), ("afti16", afti16(), 0.8),
                              ("double_integrator", double_integrator(), 0.8)]:
        for ratio in [1e-4, 1.0, 1e4]:
            status, p = solve(a, c, eta, 1.0, ratio)
            rows = ", ".join("[" + ", ".join(f"{v:.12e}" for v in row) + "]" for row in p)
            print(f"// {name} eta={eta} r/q={ratio:g} status={status}")
            print(f"({name!r}, {ratio:e}, &[{rows}]),")
