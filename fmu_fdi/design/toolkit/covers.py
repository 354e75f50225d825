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
    """``X = X1 + Y X2`` of least order (X minimal; Y proper, of the cover's order plus that of the removed
    injection part)."""

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


def _compound(X1: LTI, X2: LTI, rtol, atol: float, vrtol: float | None = None):
    """Step (i) of :func:`left_cover2`: the balanced minimal compound ``[X1; X2]`` with the states one output
    injection through X2 makes uncontrollable removed: ``(A, B, C1, C2, D1, D2, Y0, M, tol, cond, n)`` —
    ``(A, B, C1, D1)`` realises ``X1' = X1 + Y0 X2`` and ``(A, B, C2, D2)`` realises ``M X2``; ``n`` is the
    compound's minimal order before the removal. The removal's rank decisions use ``max(atol, vrtol·norm)``
    when ``vrtol`` is given (:func:`left_cover2`), the compound's ``tol`` otherwise."""
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
        vtol = tol if vrtol is None else max(atol, float(vrtol) * norm)
        P = None
        if vrtol is not None:
            K0, P = _near_uncontrollable(A, B, C2, D2, vtol, tol)
        if P is None:
            P, _, _, F, _, fnorm = _output_nulling(A.T, C2.T, B.T, D2.T, vtol)
            K0 = P @ F.T  # dual feedback u = F ξ on x = P ξ: K0 = (F Pᵀ)ᵀ
        if P.shape[1]:
            cond = max(cond, float(np.linalg.norm(K0, 2)))
            Ak, Bk = A + K0 @ C2, B + K0 @ D2
            Y0, M = LTI(Ak, K0, C1, np.zeros((p1, p2)), dt), LTI(Ak, K0, C2, np.eye(p2), dt)
            W = sla.null_space(P.T)  # V*⊥: (A + K0 C2)-invariant and holding Im(B + K0 D2)
            A, B, C1, C2 = W.T @ Ak @ W, W.T @ Bk, C1 @ W, C2 @ W
    return A, B, C1, C2, D1, D2, Y0, M, tol, cond, n


def _near_uncontrollable(A, B, C2, D2, vtol: float, tol: float):
    """Step (i) of :func:`_compound` with a loosened threshold, by eigenvalues: ``(K0, P)`` or ``(None, None)``
    when ``D2`` has not full row rank (above ``tol``).

    With ``D2`` of full row rank the injection ``K0 = −B D2⁺`` leaves ``(Â, B̂) = (A + K0 C2, B (I − D2⁺ D2))``,
    and the states any injection makes uncontrollable are the uncontrollable ones of that pair (the output
    ``C2 x + D2 u`` fixes the rest of the injection). Each eigenvalue λ of Â is judged by its PBH test,
    ``σ_min([Â − λI, B̂]) ≤ vtol``, and ``P`` spans the left invariant subspace of the accepted ones (ordered real
    Schur form of Âᵀ, :func:`...linalg.ordered_schur`; orthonormal). One decision per mode instead of the
    deflation's chain of rank decisions, whose rounding grows pass after pass: on random AMMP seed 26 the PBH
    values of the balanced compound (order 49) run from 7e-12 to 1e-2 of its norm, the deflation finds no state
    at any threshold up to 1e-3, this test 12 at 3e-7, and the cover drops from 25 to 18 with the row's
    response to 5e-11."""
    from ...linalg import ordered_schur

    n = A.shape[0]
    U, sv, Vh = np.linalg.svd(D2)
    if not (sv.size == D2.shape[0] and sv[-1] > tol):
        return None, None
    Dp = Vh[:sv.size].T @ (U.T / sv[:, None])  # D2⁺ (full row rank: D2 D2⁺ = I)
    K0 = -B @ Dp
    Ah, Bh = A + K0 @ C2, B + K0 @ D2
    ev = np.linalg.eigvals(Ah)
    pbh = np.array([np.linalg.svd(np.hstack([Ah - z * np.eye(n), Bh]), compute_uv=False)[-1] for z in ev])
    chosen = ev[pbh <= vtol]
    if not chosen.size:
        return K0, np.zeros((n, 0))

    def select(re, im):
        z = complex(re, im)
        return bool(np.min(np.abs(chosen - z)) <= 1e-9 * max(1.0, abs(z)))

    _, Z, k = ordered_schur(Ah.T, select)
    return K0, Z[:, :k]


def left_cover2(X1: LTI, X2: LTI, *, rtol: float | None = None, atol: float = 0.0,
                vrtol: float | None = None) -> Cover:
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

    Guaranteed: the least order over the X whose Y is realised on the compound's states (Y'' has the cover's
    order). When the least-order X needs a Y with dynamics of its own that the compound does not hold — X1
    built on a null-space basis with other poles than X2's (an H∞-optimal row and the pencil basis: AMMP
    seeds 5 and 26, where step (i) at working precision removes nothing: see ``vrtol`` below), or X1 and the
    least X sharing an unstable pole Y must cancel — the order returned is an upper bound; the caller compares
    with another method (``mindeg`` also re-solves (2) from the reference). The
    compound's minimal realisation is TB01PD's on TB01ID-scaled data: states of X1 with Hankel singular values
    ≤ 1e-13 of the largest (an H∞-optimal row, seed 9: 18 of 33) can survive it at every ``rtol``, and then
    nothing is lowered — pass X1 balanced and truncated (``mindeg`` tries both).

    ``vrtol`` (default: ``rtol``'s threshold) is the relative tolerance of step (i) alone, which then judges each
    mode by its PBH test (:func:`_near_uncontrollable`; the deflation at that threshold when ``D2`` is rank
    deficient). Step (i) finds the states only as accurately as X1 is known, and the staircase of step (ii)
    needs them all removed: an H∞-optimal row known to ~1e-12 (random AMMP seed 5, the balanced compound of
    order 41 of a row and the basis) has 20 modes whose PBH values are ≤ 2e-9 of the norm (then a gap to
    1e-4), but the deflation at working precision removes none — its first constraint has singular values 2e-7
    and 3e-11 of the norm where the exact ones are 0 — and the staircase of step (ii), whose rank decisions
    then have clean gaps, stops at an unstable 13, where with the 20 states removed it gives the least order
    7 of the exact re-solve. Seed 26 (order 49): no gap — PBH values from 7e-12 to 1e-2 — and the cover
    drops with the threshold, 25 → 18 at 3e-7 (response to 5e-11) → 15 at 3e-6; the re-solve has 13.
    """
    A, B, C1, C2, D1, D2, Y0, M, tol, cond, n = _compound(X1, X2, rtol, atol, vrtol)
    dt = X1.dt
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


def stable_left_cover(X1: LTI, X2: LTI, good, choose, *, rtol: float | None = None, atol: float = 0.0,
                      max_order: int | None = None, vrtol: float | None = None) -> Cover | None:
    """A stable ``X = X1 + Y X2`` (one row X1) of the least order this method decides, or None.

    On the dual of the compound of :func:`_compound` (``a = Aᵀ``, ``b1 = C1ᵀ`` one column, ``b2 = C2ᵀ``), a
    Type 2 cover of dimension k whose map ``a + b2 F`` restricted to it has the characteristic polynomial
    ``α`` (monic, degree k) exists iff

        α(a) b1 ∈ K_k = Im [b2, a b2, …, a^k b2]                                                    (2)

    (the cover is spanned by ``v_0 = b1 + b2 g_0``, ``v_{j+1} = a v_j + b2 g_{j+1}``, and a relation
    ``Σ α_j v_j = 0`` is (2) with the ``g`` read off K_k's coefficients by back substitution). (2) is linear in
    α's coefficients: at each k the admissible α form an affine set ``α_p + Z t``. For k = 0, 1, … (up to
    ``max_order``, default the compound's order) the first k is taken at which (i) the set is every monic
    polynomial (Z of dimension k): α has the roots ``choose(k)``; (ii) the set is one point whose roots lie in
    ``good``; or (iii) the point of the set nearest (least squares, coefficients) to the polynomial of
    ``choose(k)`` has its roots in ``good``. Guaranteed: in cases (i)/(ii) at every k below, no stable X of that
    order exists, so the order returned is the least among stable solutions; when a smaller k had a
    proper affine subset (0 < dim Z < k) whose nearest point was unstable, a stable polynomial in that set may
    have been missed (deciding it is a non-convex problem): the order is then an upper bound of the least.
    Numerics: Krylov matrices of ``a/ρ`` (ρ = max(1, ||a||)), orthonormalised columns, ranks by SVD at the
    compound's tolerance; meant for the low orders of exact-matching rows (a stable solution of order ≤ ~10).
    X is minimal; Y is ``Y0' + Y'' M`` as in :func:`left_cover2`. ``vrtol`` as :func:`left_cover2`'s (step (i) mode
    by mode at that relative threshold).
    """
    if X1.p != 1:
        raise ValueError(f"stable_left_cover: X1 must be one row, got {X1.p}")
    A, B, C1, C2, D1, D2, Y0, M, tol, cond, n0 = _compound(X1, X2, rtol, atol, vrtol)
    dt, n = X1.dt, A.shape[0]
    a, b1, b2, c, d1, d2 = A.T, C1.T, C2.T, B.T, D1.T, D2.T
    rho = max(1.0, float(np.linalg.norm(a, 2))) if n else 1.0
    As = a / rho
    rel = (n + 1) * 1e3 * EPS if rtol is None else float(rtol)  # relative rank threshold of (2)
    top = n if max_order is None else min(n, int(max_order))
    kry1 = [b1[:, 0]]
    kry2 = [b2]
    for k in range(top + 1):
        if k:
            kry1.append(As @ kry1[-1])
            kry2.append(As @ kry2[-1])
        Kk = np.hstack(kry2) if b2.shape[1] else np.zeros((n, 0))
        if Kk.size:
            U, sv, _ = np.linalg.svd(Kk, full_matrices=False)
            U = U[:, sv > tol]  # (columns (a/ρ)^i C2ᵀ: of the compound's scale or below)
        else:
            U = np.zeros((n, 0))
        proj = lambda v: v - U @ (U.T @ v)  # noqa: E731  (component outside K_k)
        P = np.column_stack([proj(v) for v in kry1]) if n else np.zeros((0, k + 1))
        scale = max(float(np.linalg.norm(np.column_stack(kry1))) if n else 0.0, 1e-300)
        Pk, rhs = P[:, :k], -P[:, k]
        if k:
            sol, *_ = np.linalg.lstsq(Pk, rhs, rcond=None)
            if np.linalg.norm(Pk @ sol - rhs) > rel * scale * max(1.0, np.linalg.norm(sol)):
                continue
            _, sv, Vt = np.linalg.svd(Pk, full_matrices=True)
            rank = int(np.sum(sv > rel * scale))
            Z = Vt[rank:].T
        else:
            if np.linalg.norm(rhs) > rel * scale:
                continue
            sol, Z = np.zeros(0), np.zeros((0, 0))
        # α in the scaled variable μ = λ/ρ: coefficients α_0 … α_{k-1} (α_k = 1)
        want = np.real(np.poly(np.asarray(choose(k), complex) / rho))[::-1][:k] if k else np.zeros(0)
        if Z.shape[1] == k:
            alpha = want
        elif Z.shape[1] == 0:
            alpha = sol
        else:
            alpha = sol + Z @ np.linalg.lstsq(Z, want - sol, rcond=None)[0]
        roots = np.roots(np.r_[1.0, alpha[::-1]]) * rho if k else np.zeros(0)
        if not all(good(z.real, z.imag) for z in roots):
            continue
        return _krylov_cover(As, rho, b1, b2, c, d1, d2, alpha, U, Y0, M, tol, cond, n0, dt)
    return None


def _krylov_cover(As, rho, b1, b2, c, d1, d2, alpha, U, Y0, M, tol, cond, n0, dt) -> Cover | None:
    """The cover of :func:`stable_left_cover` for the admissible monic ``α`` (scaled variable): g from (2) by
    back substitution, ``v_j``, and the reduced dual system in companion form, unscaled and transposed."""
    k = alpha.size
    n, m2 = As.shape[0], b2.shape[1]
    al = np.r_[alpha, 1.0]
    # α(As) b1 and its coefficients h_i on [b2, As b2, …, As^k b2]: α(As) b1 + Σ_i As^i b2 h_i = 0
    v, target = b1[:, 0].copy(), np.zeros(n)
    for j in range(k + 1):
        target += al[j] * v
        v = As @ v
    cols = []
    w = b2
    for _ in range(k + 1):
        cols.append(w)
        w = As @ w
    Kk = np.hstack(cols) if m2 else np.zeros((n, 0))
    h = -np.linalg.lstsq(Kk, target, rcond=None)[0] if Kk.size else np.zeros((k + 1) * m2)
    H = h.reshape(k + 1, m2) if m2 else np.zeros((k + 1, 0))
    # h_i = Σ_{l=0}^{k-i} α_{i+l} g_l  ⇒  g_{k-i} = h_i − Σ_{l<k-i} α_{i+l} g_l  (i = k, k−1, …, 0)
    g = np.zeros((k + 1, m2))
    for i in range(k, -1, -1):
        l_new = k - i
        g[l_new] = H[i] - sum(al[i + l] * g[l] for l in range(l_new))
    V = np.zeros((n, k + 1))
    V[:, 0] = b1[:, 0] + b2 @ g[0]
    for j in range(k):
        V[:, j + 1] = As @ V[:, j] + b2 @ g[j + 1]
    if np.linalg.norm(V @ al) > 1e6 * EPS * max(1.0, np.linalg.norm(V)) * max(1.0, np.linalg.norm(al)):
        return None  # the relation (2) does not hold to working accuracy: no cover from this α
    # scaled variable μ = λ/ρ: companion of α on [v_0 … v_{k-1}], then λ = ρ μ (A_r = ρ · companion, the
    # feedback F v_j = g_{j+1} acts on the scaled pair (As, b2) and becomes ρ·F on (a, b2))
    ar = np.zeros((k, k))
    if k:
        ar[1:, :-1] = np.eye(k - 1)
        ar[:, -1] = -alpha
    ar = rho * ar
    br = np.zeros((k, 1))
    if k:
        br[0, 0] = 1.0
    f = rho * g[1:].T if k else np.zeros((m2, 0))
    cr = c @ V[:, :k] + d2 @ f
    dr = d1 + d2 @ g[:1].T
    X = LTI(ar.T, cr.T, br.T, dr.T, dt)
    Y = LTI(ar.T, f.T, br.T, g[:1], dt)
    if Y0.n:
        Y = (Y0 + Y @ M).minreal(tol)
    X = X.minreal(tol) if X.n else X
    return Cover(X, Y, n0, tol, cond)
