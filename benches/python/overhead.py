"""Per-call overhead of the Python binding: push(u, y) + estimate() from Python against the
same calls made in Rust (Estimator._native.time_rust_calls), on the double integrator with
M = 10, K = 20 ADMM, for dtype="float64" (mhe_core::MheEstimator) and dtype="float32"
(mhe_embedded::MheRt, the board's kernel). Prints microseconds per call (median and minimum
over the repeats); docs/python.md quotes the result.

Run: python benches/python/overhead.py   (in the venv of scripts/python.sh)
"""

import time

import numpy as np

import suboptimal_mhe as sm


def main(n: int = 20000, repeats: int = 5) -> None:
    for dtype in ("float64", "float32"):
        run(dtype, n, repeats)


def run(dtype: str, n: int, repeats: int) -> None:
    plant = sm.Plant([[1, 0.1], [0, 1]], [[0.005], [0.1]], [[1, 0]])
    u, y, out = np.array([0.1]), np.array([1.0]), np.empty(2, dtype=dtype)
    rows = []
    for _ in range(repeats):
        est = sm.Estimator(plant, horizon=10, eta=0.8, k=20, method="admm", dtype=dtype)
        est.push(u, y)
        rust = est._native.time_rust_calls(u, y, n) / n
        est.reset()
        est.push(u, y)
        t0 = time.perf_counter()
        for _ in range(n):
            est.push(u, y)
            est.estimate()
        py_new = (time.perf_counter() - t0) / n
        est.reset()
        est.push(u, y)
        t0 = time.perf_counter()
        for _ in range(n):
            est.push(u, y)
            est.estimate(out)
        py_out = (time.perf_counter() - t0) / n
        rows.append((rust, py_new, py_out))
    # The median of the repeats, and the minimum (the least disturbed repeat: on a shared
    # machine the other jobs only ever add time).
    for stat, f in (("median", np.median), ("min", np.min)):
        rust, py_new, py_out = f(np.array(rows), axis=0)
        print(f"dtype={dtype} ({stat} of {repeats} x {n} calls)")
        print(f"Rust push+estimate:            {rust * 1e6:8.2f} us/call")
        print(f"Python push+estimate():        {py_new * 1e6:8.2f} us/call  (+{(py_new - rust) * 1e6:.2f} us, {py_new / rust:.2f}x)")
        print(f"Python push+estimate(out):     {py_out * 1e6:8.2f} us/call  (+{(py_out - rust) * 1e6:.2f} us, {py_out / rust:.2f}x)")


if __name__ == "__main__":
    main()
