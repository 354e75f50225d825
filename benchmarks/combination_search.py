"""Time the combination search's objective (``design/toolkit/_select.py``) against the plain
per-fault formula, measured in the same run, and check they agree.

The objective runs inside Nelder–Mead thousands of times per design (Boeing 747's strong row
[1,1,1,1,1]: ~11 000 evaluations). The baseline below is the formula as the docstring states it —
``γ_j(h) = max_λ ||h P_j(λ)|| / (||h Y(λ)|| ||Gf_j(λ)||)`` and the peak/strong-gain condition —
one ``einsum``/``norm`` per fault; the shipped one forms every fault's response with one product.
Printed: time per evaluation of each, their ratio, the largest relative difference of the values
(rounding only), then the Boeing 747 strong listing (FDGainTol 1e-2, freqs [0, 1]).

Run: ``python benchmarks/combination_search.py``
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from fmu_fdi.design.toolkit._select import visibility_gated


def baseline(P, Y, G, fcols, gate, strong):
    gn = [np.linalg.norm(G[:, :Y.shape[2], c], 2, axis=(1, 2)) for c in fcols]

    def value(h):
        resp = [np.linalg.norm(np.einsum("r,krc->kc", h, Pj), axis=1) for Pj in P]
        ny = np.linalg.norm(np.einsum("r,krc->kc", h, Y), axis=1)
        gam = []
        for r, g in zip(resp, gn):
            b = ny * g
            keep = b >= 1e-6 * b.max()
            gam.append(np.max(np.where(keep, r / np.where(keep, b, 1.0), 0.0)) if b.max() > 0 else 0.0)
        g = min(gam)
        if g < gate:
            return g - 1.0
        peaks = np.array([r.max() for r in resp])
        lows = min(np.linalg.norm(np.einsum("r,krc->kc", h, S), axis=1).min() for S in strong)
        return min(min(peaks.min(), lows) / peaks.max(), g)

    return value


def main(evals: int = 3000) -> None:
    rng = np.random.default_rng(0)
    K, rows, p, nf = 170, 5, 3, 5  # Boeing 747's sizes: 5 basis rows, 3 outputs, 5 faults, ~170 grid points
    cplx = lambda *s: rng.standard_normal(s) + 1j * rng.standard_normal(s)
    P = [cplx(K, rows, 1) for _ in range(nf)]
    strong = [cplx(2, rows, 1) for _ in range(nf)]
    Y, G = cplx(K, rows, p), cplx(K, p + 2, nf)
    fcols = [np.array([j]) for j in range(nf)]
    H = [h / np.linalg.norm(h) for h in rng.standard_normal((evals, rows))]
    fast, slow = visibility_gated(P, Y, G, fcols, 1e-3, strong), baseline(P, Y, G, fcols, 1e-3, strong)
    t0 = time.perf_counter(); a = [fast(h) for h in H]; t1 = time.perf_counter()
    b = [slow(h) for h in H]; t2 = time.perf_counter()
    diff = max(abs(x - y) / max(abs(y), 1e-300) for x, y in zip(a, b))
    print(f"objective: shipped {1e6 * (t1 - t0) / evals:.1f} us, per-fault baseline {1e6 * (t2 - t1) / evals:.1f} us, "
          f"ratio {(t2 - t1) / (t1 - t0):.2f}x; largest relative difference {diff:.1e}")

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_synthesis_published import boeing747
    from fmu_fdi.design.problems.achievable import achievable_structure
    m = boeing747()
    t = time.perf_counter()
    rows_ = achievable_structure(m, freqs=[0, 1], FDGainTol=1e-2)
    print(f"Boeing 747 strong listing (FDGainTol 1e-2): {len(rows_)} rows in {time.perf_counter() - t:.2f} s "
          f"(one objective evaluation costs {1e6 * (t1 - t0) / evals:.0f} us of it ~11 000 times per listed row)")


if __name__ == "__main__":
    main()
