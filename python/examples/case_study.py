"""Certify, simulate and plot the case study from Python (docs/python.md).

Run from the repository root, in the venv of scripts/python.sh:
    python python/examples/case_study.py [scenarios/case-study-certified.toml]
Plots ‖x̂_t − x_t‖ with matplotlib when it is installed (saved to case_study.png),
otherwise prints it.
"""

import sys

import numpy as np

import suboptimal_mhe as sm

path = sys.argv[1] if len(sys.argv) > 1 else "scenarios/case-study-certified.toml"
scenario = sm.Scenario.from_file(path)
cert = sm.certify(scenario)  # Theorem 1 per method, as `cargo xtask reproduce`
print(f"{scenario.name}: LMI (2) {'holds' if cert.ioss_passed else 'fails'}")
for method, k_min in cert.k_mins.items():
    why = "" if k_min is not None else "  void: " + "; ".join(cert.void_reasons(method))[:100]
    print(f"  {method:<16} K_min = {k_min}{why}")

own = cert.to_dict()["solvers"][0]["solver"]
k = cert.k_min(own)
if k is None:
    sys.exit(f"no K_min for {own}: nothing certified to simulate")
sim = sm.simulate(scenario, method=own, k=k)  # the closed loop at the certified K
print(f"simulated {len(sim['e_norm'])} steps of {own} at K = {k}: sup ‖e‖ = {np.max(sim['e_norm']):.3e}")

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib not installed: ‖e_t‖ =", np.array2string(sim["e_norm"][:10], precision=3), "…")
else:
    fig, ax = plt.subplots(figsize=(6, 3))
    ax.semilogy(sim["e_norm"], label=f"{own}, K = {k}")
    ax.set_xlabel("t (steps)")
    ax.set_ylabel("‖x̂_t − x_t‖₂")
    ax.legend()
    fig.tight_layout()
    fig.savefig("case_study.png", dpi=120)
    print("saved case_study.png")
