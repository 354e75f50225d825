"""Approximate decoupling of noise: co-outer–co-inner factorisation and the gap.

When the noise inputs w cannot be decoupled exactly, the residual should see the faults
much more than the noise. The figure of merit is the fault-to-noise gap
``min_j ||Rf_j||∞ / ||Rw||∞`` (Varga 2017, sec. 5.3; acceptance A4/A5). Following
Varga's Procedure AFD we

1. split the exact (u, d)-decoupling residuals into ``Q2`` (also w-free) and ``Q1`` whose
   noise response ``Rw1`` has full normal row rank;
2. factor ``Rw1 = Ro Ri`` with ``Ri`` co-inner (``Ri Ri~ = I``) and ``Ro`` square, stable
   and minimum phase, and replace ``Q1 ← Ro^{-1} Q1`` so that ``||h1 Rw1||∞ = ||h1||``;
3. choose the combination ``h = [h1 h2]`` that maximises the gap.

The factorisation is the transpose of the inner–outer factorisation of Zhou, Doyle and
Glover (*Robust and Optimal Control*, Thm. 13.34; discrete analogue via the DARE). It
needs a full-row-rank feedthrough and no zeros on the stability boundary; otherwise
step 2 is skipped (the filter poles then set the frequency weighting, as in Varga's
Example 5.11 with its poles at −3).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ...linalg import inv_sqrtm_pd, rank, sqrtm_psd
from ...lti import LTI


def coouter_inverse(G: LTI) -> tuple[LTI, LTI] | None:
    """For stable ``G = Ro Ri``: return ``(Ro^{-1}, Ri)``, or None if the standard
    conditions fail (feedthrough not of full row rank, zeros on the stability boundary)."""
    if G.n == 0:
        return None
    Gt = G.transpose()  # tall: inner–outer of Gt = Gi Go gives G = Go^T Gi^T
    A, B, C, D = Gt.A, Gt.B, Gt.C, Gt.D
    if rank(D) < D.shape[1]:
        return None
    try:
        if G.is_discrete:
            X = sla.solve_discrete_are(A, B, C.T @ C, D.T @ D, s=C.T @ D)
            Rk = D.T @ D + B.T @ X @ B
            F = -np.linalg.solve(Rk, B.T @ X @ A + D.T @ C)
        else:
            X = sla.solve_continuous_are(A, B, C.T @ C, D.T @ D, s=C.T @ D)
            Rk = D.T @ D
            F = -np.linalg.solve(Rk, B.T @ X + D.T @ C)
        Rh, Rhi = sqrtm_psd(Rk), inv_sqrtm_pd(Rk)
    except (np.linalg.LinAlgError, ValueError):
        return None
    Acl = A + B @ F
    closed = LTI(Acl, B @ Rhi, C + D @ F, D @ Rhi, G.dt)
    if not closed.is_stable(margin=1e-9):
        return None
    Go_inv = LTI(Acl, B @ Rhi, F, Rhi, G.dt)
    _ = Rh  # Go = (A, B, -Rh F, Rh); only its inverse is needed
    return Go_inv.transpose(), closed.transpose()


def gap_objective(Rf: list[np.ndarray], Rw: np.ndarray):
    """Grid estimate of the gap of a combination ``h``.

    ``Rf[j]``: (points, rows, cols_j) responses to fault j; ``Rw``: (points, rows, mw).
    Rows whose noise response is exactly zero by construction must carry exact zeros in
    ``Rw`` (not rounding noise), or the ratio rewards vanishing combinations.
    """

    def objective(h: np.ndarray) -> float:
        fault = min(np.max(np.linalg.norm(np.einsum("r,krc->kc", h, F), axis=1)) for F in Rf)
        noise = np.max(np.linalg.norm(np.einsum("r,krc->kc", h, Rw), axis=1))
        if noise == 0.0:
            return 1e12 if fault > 0 else 0.0
        return float(fault / noise)

    return objective
