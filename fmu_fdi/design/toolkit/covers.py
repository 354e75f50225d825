"""Type 2 minimum dynamic covers: the least-order ``X = X1 + Y X2`` (left) and ``X = X1 + X2 Y`` (right).

Given proper ``X1`` and ``X2`` with one realisation ``(A, B, [C1; C2], [D1; D2])`` (left), find a proper
``Y`` such that

    X(λ) = X1(λ) + Y(λ) X2(λ)                                                                  (1)

has least McMillan degree (A. Varga, "Reliable algorithms for computing minimal dynamic covers",
Proc. IEEE CDC 2003; Varga 2017, *Solving Fault Diagnosis Problems*, sec. 7.9 and 10.4.2; the peer
functions are DescriptorSystems.jl ``glmcover2``/``grmcover2``). With an output injection K and an
output feedforward G,

    X = (A + K C2,  B + K D2,  C1 + G C2,  D1 + G D2),      Y = (A + K C2,  K,  C1 + G C2,  G),

and the order drops to the codimension of the largest subspace that K makes unobservable from
``C1 + G C2``. The computation is on the dual (right) problem ``Xᵀ = X1ᵀ + X2ᵀ Yᵀ``, a pair
``(a, [b2 b1])`` with ``a = Aᵀ``, ``b1 = C1ᵀ``, ``b2 = C2ᵀ``: a cover is a subspace ``V`` with

    a V ⊆ V + Im b2,       Im b1 ⊆ V + Im b2                     (Type 2; Type 1 asks Im b1 ⊆ V),

on which ``a + b2 F`` acts and ``b1 + b2 G`` lies; its least dimension is the least order of (1)
when the realisation is maximally controllable (Varga 2003). Algorithm: an orthogonal staircase of
``(a, [b2 b1])`` that compresses at every step the ``b2``-chain block before the ``b1``-chain block
(SVD rank decisions, threshold ``max(atol, rtol·||[A B; C D]||)``); the ``b1``-blocks, made
invariant by a non-orthogonal elimination of the ``b2``-block rows (column operations with the
full-row-rank sub-diagonal ``b2``-blocks, backwards) and by ``F``, ``G`` acting on the first
``b2``-block, span V. ``cond`` reports the largest norm of those non-orthogonal steps (the accuracy
lost is about ``cond·eps``).

Used by :mod:`..problems.approximate_matching` (``mindeg``: a row of the optimal filter plus a
combination of the left null-space basis of the whole ``[Gu Gd Gf Gw; I 0 0 0]``, the same fault
and noise response by construction) and :mod:`.least_solve` (a stable exact-matching row lowered).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ...compression import RowCompression
from ...linalg import EPS
from ...lti import LTI, vstack


@dataclass
class Cover:
    """``X = X1 + Y X2`` of least order: ``X`` and ``Y`` share ``(A, K)``-part of their realisations."""

    X: LTI
    Y: LTI
    #: order of the compound realisation the cover started from, and the rank threshold used
    order_before: int
    tol: float
    #: largest norm of the non-orthogonal eliminations, of F and of G
    cond: float


def _rank(s: np.ndarray, tol: float) -> int:
    return int(np.sum(s > tol))


def right_cover2(a: np.ndarray, b1: np.ndarray, b2: np.ndarray, c: np.ndarray, d1: np.ndarray,
                 d2: np.ndarray, tol: float):
    """Right Type 2 cover of ``X1 = (a, b1, c, d1)`` by ``X2 = (a, b2, c, d2)``: ``X = X1 + X2 Y`` of least
    order. Returns ``(ar, br, cr, dr, f, g, cond)``: ``X = (ar, br, cr, dr)``, ``Y = (ar, br, f, g)``."""
    n, m1, m2 = a.shape[0], b1.shape[1], b2.shape[1]
    a, c = a.astype(float, copy=True), c.astype(float, copy=True)
    bb = np.hstack([b2, b1]).astype(float)
    # staircase: per step a b2-chain block (from the previous b2-block's columns, or b2) and then a
    # b1-chain block (from the previous b1-block's columns, or b1), each compressed by an SVD
    steps: list[tuple[tuple[int, int], tuple[int, int]]] = []
    r0 = 0
    src = (("b", np.arange(m2)), ("b", np.arange(m2, m2 + m1)))
    while r0 < n:
        step = []
        for which, cols in src:
            part = (bb if which == "b" else a)[r0:, cols]
            rho = 0
            if part.size:
                cmp = RowCompression(part)
                rho = _rank(cmp.s, tol)
                if rho:  # rows/columns ≥ r0 only: the source columns keep their zeros
                    cmp.rotate(r0, a, rows=(bb,), cols=(c,))
                    part = (bb if which == "b" else a)[r0 + rho:, cols]
                    part[...] = 0.0  # what the rank decision declared zero
            step.append((r0, rho))
            r0 += rho
        if step[0][1] + step[1][1] == 0:
            break
        steps.append((step[0], step[1]))
        src = (("a", np.arange(step[0][0], step[0][0] + step[0][1])),
               ("a", np.arange(step[1][0], step[1][0] + step[1][1])))
    x2 = [np.arange(s, s + k) for (s, k), _ in steps]
    x1 = np.concatenate([np.arange(s, s + k) for _, (s, k) in steps]) if steps else np.zeros(0, int)
    cond = 1.0
    # backwards, for the b2-blocks j ≥ 2 (0-based j ≥ 1): the rows of b2-block j in the columns of the b1-blocks
    # are zeroed by column operations with b2-block j-1 (full row rank a[x2_j, x2_{j-1}]); the inverse row
    # operation changes the rows of b2-block j-1 only (handled next) — in b2-block j-1's column no b1-row
    # it touches is nonzero, so the sub-diagonal b2-blocks keep their rank
    for j in range(len(x2) - 1, 0, -1):
        r, q = x2[j], x2[j - 1]
        if r.size == 0 or q.size == 0:
            continue
        X = -np.linalg.lstsq(a[np.ix_(r, q)], a[np.ix_(r, x1)], rcond=None)[0]
        cond = max(cond, float(np.linalg.norm(X, 2)))
        a[:, x1] += a[:, q] @ X       # a T, T = I + E (E: X at rows q, columns x1)
        c[:, x1] += c[:, q] @ X
        a[q, :] -= X @ a[x1, :]       # T⁻¹ a, T⁻¹ = I − E
        bb[q, :] -= X @ bb[x1, :]
        a[np.ix_(r, x1)] = 0.0
    k1 = x1.size
    f = np.zeros((m2, k1))
    g = np.zeros((m2, m1))
    if steps and x2[0].size:
        r = x2[0]
        f = -np.linalg.lstsq(bb[np.ix_(r, np.arange(m2))], a[np.ix_(r, x1)], rcond=None)[0]
        g = -np.linalg.lstsq(bb[np.ix_(r, np.arange(m2))], bb[r, m2:], rcond=None)[0]
        cond = max(cond, float(np.linalg.norm(f, 2)) if f.size else 0.0, float(np.linalg.norm(g, 2)) if g.size else 0.0)
    ar = a[np.ix_(x1, x1)] + bb[x1, :m2] @ f
    br = bb[x1, m2:] + bb[x1, :m2] @ g
    cr = c[:, x1] + d2 @ f
    dr = d1 + d2 @ g
    return ar, br, cr, dr, f, g, cond


def left_cover2(X1: LTI, X2: LTI, *, rtol: float | None = None, atol: float = 0.0) -> Cover:
    """Type 2 minimum dynamic cover ``X = X1 + Y X2`` of least McMillan degree (equation (1)).

    ``X1`` (p1 × m) and ``X2`` (p2 × m, possibly p2 = 0) are proper, of one sampling time. Their compound
    ``[X1; X2]`` is balanced (SLICOT TB01ID) and every rank decision — its minimal realisation (TB01PD on the
    balanced coordinates), the deflation and the staircase — uses the threshold ``tol = max(atol,
    rtol·||[A B; C D]||_2)`` of that balanced realisation (default ``rtol = (n + 1)·1e3·eps``, as the pencil
    basis; a larger ``rtol`` treats data known to that relative accuracy, e.g. modes an optimal filter
    cancels only to 1e-9, as exact).

    Two steps. (i) The cover's least order is reached only on a realisation that no output injection
    through ``X2`` makes less controllable ("maximally controllable", Varga 2003): the states that one
    injection ``K0`` makes uncontrollable — on the dual, the output-nulling subspace ``V*`` of
    ``(Aᵀ, C2ᵀ, Bᵀ, D2ᵀ)`` (:func:`.pencil._output_nulling`, orthogonal deflation), e.g. the states of a
    dynamic combination ``Y0 X2`` inside ``X1`` — are removed first: ``X1' = (A + K0 C2, B + K0 D2, C1, D1)
    = X1 + Y0' X2`` on ``V*⊥``, with ``X2' = M X2`` (``M = (A + K0 C2, K0, C2, I)``, biproper with a proper
    inverse: the same row space). (ii) :func:`right_cover2` on the dual of ``[X1'; X2']``.
    Returns the :class:`Cover` with ``Y = Y0' + Y'' M`` and ``X`` minimal.
    """
    from .pencil import _output_nulling

    if X1.m != X2.m or X1.dt != X2.dt:
        raise ValueError(f"left_cover2: X1 ({X1.p}×{X1.m}, dt={X1.dt}) and X2 ({X2.p}×{X2.m}, dt={X2.dt}) must "
                         f"have the same inputs and sampling time")
    p1, p2, dt = X1.p, X2.p, X1.dt
    S = vstack([X1, X2]) if p2 else X1
    if S.n:  # balanced first, then every rank decision (the minimal realisation's too) relative to it
        S, _ = S.balanced()
    norm = float(np.linalg.norm(np.block([[S.A, S.B], [S.C, S.D]]), 2)) if S.n else float(np.linalg.norm(S.D, 2))
    tol = max(atol, ((S.n + 1) * 1e3 * EPS if rtol is None else rtol) * norm)
    if S.n:
        S = S.minreal(tol, equil="N")
    n = S.n
    A, B, C1, C2, D1, D2 = S.A, S.B, S.C[:p1], S.C[p1:], S.D[:p1], S.D[p1:]
    Y0 = LTI.zero(p1, p2, dt)
    M = LTI.static(np.eye(p2), dt)
    cond = 1.0
    if n and p2:
        P, _, _, F, _, fnorm = _output_nulling(A.T, C2.T, B.T, D2.T, tol)
        if P.shape[1]:
            K0 = P @ F.T  # dual feedback u = F ξ on x = P ξ: K0 = (F Pᵀ)ᵀ
            cond = max(cond, float(np.linalg.norm(K0, 2)))
            Ak, Bk = A + K0 @ C2, B + K0 @ D2
            Y0, M = LTI(Ak, K0, C1, np.zeros((p1, p2)), dt), LTI(Ak, K0, C2, np.eye(p2), dt)
            W = sla.null_space(P.T)  # V*⊥: (A + K0 C2)-invariant and holding Im(B + K0 D2)
            A, B, C1, C2 = W.T @ Ak @ W, W.T @ Bk, C1 @ W, C2 @ W
    ar, br, cr, dr, f, g, c2 = right_cover2(A.T, C1.T, C2.T, B.T, D1.T, D2.T, tol)
    X = LTI(ar.T, cr.T, br.T, dr.T, dt)
    Y = LTI(ar.T, f.T, br.T, g.T, dt)
    if Y0.n:
        Y = (Y0 + Y @ M).minreal(tol)
    if X.n:
        Xm = X.minreal(tol)
        if Xm.n < X.n:  # (a cancellation the staircase did not see)
            X = Xm
    return Cover(X, Y, n, tol, max(cond, c2))
