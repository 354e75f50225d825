"""The judge's bound on a *refined* reading of a decoupled block holds, judged by a 50-digit truth (judge24).

``postconditions._decoupled_values`` refines the points that may reach a block's peak (``_refined_values``: the
row's solves by iterative refinement in longdouble, two steps, residuals against the stored data) and charges each
refined point ``3N·u_x·||err||_F`` (``_decoupled_reading``, u_x = ``REFINED_UNIT`` = 2^-64 on x86). That bound
assumes the refinement converged; judge23 left it unchecked at order 125 (audit seed 338), where the clongdouble
truth of tests/test_judge_plain_bound.py moves by 6× the refined bound between 2 and 5 of its own refinement steps.

The truth here is independent of floating point: ``R(λ) = Q_b(λ)·Ge(λ)`` from the stored double data (exact in
decimal), every solve by Gaussian elimination with partial pivoting in Python's ``decimal`` at 50 significant digits
(stdlib; its error, ~1e-50 times the systems' conditioning, is some thirty decades below the bound's ~3N·5.4e-20
times the same conditioning). On seed 4 it agrees with mpmath at 40 digits to the double bit.

Measured (x86, the judge's own readings, error / bound per point, Frobenius norm over the block):

- H∞ matching seed 4 (order 22, plant 23; both decoupled readings of the shipped filter, 144 points, every point
  refined for the measurement): worst 0.0040 (u/d) and 0.0037 (the other block) at 1, 2, 3 or 5 steps alike — the
  refinement has converged after one step; at the blocks' peaks ≤ 7.1e-4.
- Audit seed 338 (order 125, plant 30; ``normalised_leak`` of tests/test_audit_seeds20.py's product realisation
  Y·Φ·Q0, its two decoupled readings, every point refined by the judge; the same GEPP in mpmath at 40 digits — 16
  min for 244 points, too slow for CI — at all 244 points of the first reading and 66 of the second: every 4th and
  each block's 6 largest): worst 7.3e-4 (u/d) and 1.3e-3 (the other block) of the bound in the first, 4.4e-4 and 1.05e-3
  in the second; at the blocks' peaks (k = 117, true u/d value 3.15e-11, reading off by 2.6e-14, bound 9.2e-11)
  ≤ 3.3e-4. With 1, 3 or 5 steps instead of 2 the worst ratio stays 4.3e-4 … 1.6e-3: converged after one step.
  Against the bound without judge23's residual term (main 7bc7918's): ≤ 2.8e-3 — main's refined readings were
  within their bound too. judge23's "3.84× the refined bound" was the clongdouble truth's own error: it is off the
  40-digit value by 3.84× (u/d) and 1.58× (the other block) main's bound, and the judge's reading by 3.84× from it.
  The double-double reading (``_dd_refined_values``, 3 steps) is off by ≤ 3e-16 of its bound at 2^-64.
- So two longdouble steps converge on both; the bound is ≥ 780× (338) and ≥ 250× (seed 4) the error, and
  the residual term judge23 adds at refined points (the plain reading's ``|W r̂|`` scaled by u_x/u) raises the
  refined bound by up to 22× there (seed 338, the first reading, point 12) without being needed.
"""
from decimal import Decimal, localcontext

import numpy as np
import pytest

import fmu_fdi.design.toolkit.postconditions as pc
from fmu_fdi.design.toolkit.postconditions import REFINED_UNIT
import test_judge_plain_bound as plain

readings = plain.readings  # the fixture: seed 4's two decoupled readings of its shipped filter (~4 s)

pytestmark = pytest.mark.skipif(pc.DD_READING, reason="the x86 (longdouble) refinement is the one measured here")


def _dec(X):
    return [[Decimal(float(v)) for v in row] for row in np.atleast_2d(np.asarray(X, float))]


def _dec_solve(lr, li, A, Br, Bi):
    """``(λI − A)^{-1}(Br + j·Bi)``, ``λ = lr + j·li``, A real, all Decimal: GEPP on the real and imaginary
    parts."""
    n, c = len(A), len(Br[0])
    Mr = [[(lr if i == j else 0) - A[i][j] for j in range(n)] + list(Br[i]) for i in range(n)]
    Mi = [[(li if i == j else Decimal(0)) for j in range(n)] + list(Bi[i]) for i in range(n)]
    for j in range(n):
        p = max(range(j, n), key=lambda i: abs(Mr[i][j]) + abs(Mi[i][j]))
        Mr[j], Mr[p], Mi[j], Mi[p] = Mr[p], Mr[j], Mi[p], Mi[j]
        pr, pi, rr, ri = Mr[j][j], Mi[j][j], Mr[j], Mi[j]
        den = pr * pr + pi * pi
        for i in range(j + 1, n):
            ar, ai = Mr[i][j], Mi[i][j]
            if not ar and not ai:
                continue
            fr, fi = (ar * pr + ai * pi) / den, (ai * pr - ar * pi) / den
            xr, xi = Mr[i], Mi[i]
            for k in range(j + 1, n + c):
                xr[k] -= fr * rr[k] - fi * ri[k]
                xi[k] -= fr * ri[k] + fi * rr[k]
    Xr, Xi = [[None] * c for _ in range(n)], [[None] * c for _ in range(n)]
    for j in range(n - 1, -1, -1):
        pr, pi = Mr[j][j], Mi[j][j]
        den = pr * pr + pi * pi
        for k in range(c):
            sr, si = Mr[j][n + k], Mi[j][n + k]
            for q in range(j + 1, n):
                sr -= Mr[j][q] * Xr[q][k] - Mi[j][q] * Xi[q][k]
                si -= Mr[j][q] * Xi[q][k] + Mi[j][q] * Xr[q][k]
            Xr[j][k], Xi[j][k] = (sr * pr + si * pi) / den, (si * pr - sr * pi) / den
    return Xr, Xi


def _dec_mul(A, X):
    return [[sum((A[i][q] * X[q][k] for q in range(len(X))), Decimal(0)) for k in range(len(X[0]))]
            for i in range(len(A))]


def _dec_add(X, Y):
    return [[a + b for a, b in zip(x, y)] for x, y in zip(X, Y)]


def product_error(Q, G, lam, val, digits: int = 50) -> np.ndarray:
    """``|val_k − Q(λ_k)·G(λ_k)|`` entrywise (points × rows × columns): Q, G as (A, B, C, D) double arrays (Q of
    positive order), the product and the difference in ``digits``-digit decimal arithmetic from the exact data."""
    out = np.empty(np.shape(val))
    with localcontext() as ctx:
        ctx.prec = digits
        (A, B, C, D), (Ae, Be, Ce, De) = [_dec(X) for X in Q], [_dec(X) for X in G]
        zero_e = [[Decimal(0)] * len(Be[0]) for _ in Be]
        for k, lk in enumerate(np.asarray(lam, complex)):
            lr, li = Decimal(lk.real), Decimal(lk.imag)
            Xr, Xi = _dec_solve(lr, li, Ae, Be, zero_e) if Ae and Ae[0] else (None, None)
            Gr = _dec_add(_dec_mul(Ce, Xr), De) if Xr else De
            Gi = _dec_mul(Ce, Xi) if Xi else [[Decimal(0)] * len(De[0]) for _ in De]
            Zr, Zi = _dec_solve(lr, li, A, _dec_mul(B, Gr), _dec_mul(B, Gi))
            Rr = _dec_add(_dec_mul(C, Zr), _dec_mul(D, Gr))
            Ri = _dec_add(_dec_mul(C, Zi), _dec_mul(D, Gi))
            for i, (rr, ri) in enumerate(zip(Rr, Ri)):
                for j, (a, b) in enumerate(zip(rr, ri)):
                    v = complex(val[k, i, j])
                    dr, di = a - Decimal(v.real), b - Decimal(v.imag)
                    out[k, i, j] = float((dr * dr + di * di).sqrt())
    return out


def _refined_ratios(reading, every: int = 4, top: int = 6) -> np.ndarray:
    """error / bound of the judge's refined reading at its refined points: each block's ``top`` largest readings (the
    peak, which the verdict reads) and every ``every``-th refined point besides."""
    Qi, Geb, lam, blocks = reading
    Qb = Qi.balanced()[0]
    N = max(Qb.n, Geb.n, 1)
    val, err, _, refined = pc._decoupled_values(Qi, Geb, lam, blocks, True)
    at = np.flatnonzero(refined)
    pick = set(at[::every].tolist())
    for b in blocks:
        r = np.linalg.norm(val[at][:, :, b], axis=(1, 2))
        pick |= set(at[np.argsort(r)[-top:]].tolist())
    ks = np.array(sorted(pick), int)
    d = product_error((Qb.A, Qb.B, Qb.C, Qb.D), (Geb.A, Geb.B, Geb.C, Geb.D), lam[ks], val[ks])
    out = []
    for b in blocks:
        e = 3 * N * REFINED_UNIT * np.linalg.norm(err[ks][:, :, b], axis=(1, 2))
        out.append(np.linalg.norm(d[:, :, b], axis=(1, 2)) / e)
    return np.concatenate(out)


def test_refined_reading_lies_within_its_bound(readings):
    """At the refined points of seed 4's two decoupled readings (each block's 6 largest and every 4th; 60 points,
    ~3 s of decimal arithmetic after the design's ~4 s), ``|refined reading − value|_F ≤ 3N·u_x·||err||_F``, the
    value from :func:`product_error` (its own error negligible, module docstring). Measured 0.0014. Not a test that
    cannot fail: with no refinement step (``_refined_solves(steps=0)``: the double solve charged at u_x) it fails
    with 1.9e3.
    """
    worst = max(float(np.max(_refined_ratios(r))) for r in readings)
    assert worst <= 1.0, f"refined reading off by {worst:.3g} times its bound"
