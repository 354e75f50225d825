"""Time per frequency point of ``fmu_fdi.freqresp.transfer_values`` (one Hessenberg form, a banded LU per
point; issue 17) against one dense LU solve per point (numpy.linalg.solve of λI - A), on random stable
realisations of orders 64, 128, 256 (p = 3, m = 5) at 200 points — both measured in this run, best of
three, the Hessenberg reduction included (caches cleared before each repeat).

    python benchmarks/freqresp_speed.py
"""
from __future__ import annotations

import time

import numpy as np

from fmu_fdi import freqresp

K, REPEATS = 200, 3


def best(fn) -> float:
    times = []
    for _ in range(REPEATS):
        freqresp.clear_caches()
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    rng = np.random.default_rng(0)
    lams = 1j * np.logspace(-2, 2, K)
    print(f"{'n':>5} {'dense µs/pt':>12} {'Hessenberg µs/pt':>17} {'dense/Hessenberg':>17} {'max rel diff':>13}")
    for n in (64, 128, 256):
        A = -2 * np.eye(n) + rng.standard_normal((n, n)) / np.sqrt(n)
        B, C, D = rng.standard_normal((n, 5)), rng.standard_normal((3, n)), np.zeros((3, 5))
        eye = np.eye(n)
        dense = lambda: np.array([C @ np.linalg.solve(lam * eye - A, B) + D for lam in lams])  # noqa: E731
        hess = lambda: freqresp.transfer_values(A, B, C, D, lams)  # noqa: E731
        td, th = best(dense), best(hess)
        ref, got = dense(), hess()
        diff = np.max(np.abs(got - ref)) / np.max(np.abs(ref))
        print(f"{n:>5} {td / K * 1e6:>12.0f} {th / K * 1e6:>17.0f} {td / th:>17.1f} {diff:>13.1e}")


if __name__ == "__main__":
    main()
