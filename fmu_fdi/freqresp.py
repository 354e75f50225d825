"""Frequency responses of large realisations: one Hessenberg form of A, reused across points and stages.

A transfer matrix ``G(λ) = C (λI - A)^{-1} B + D`` at K points costs K dense O(n³) solves when
each point is solved on its own. With the Hessenberg form ``A = Z H Zᵀ`` (H upper Hessenberg, Z
orthogonal; Golub & Van Loan, *Matrix Computations*, 4th ed., sec. 7.4.3) every point is one
Hessenberg solve

    G(λ) = (C Z) (λI - H)^{-1} (Zᵀ B) + D,

O(n²) for the LU factorisation with partial pivoting of ``λI - H`` and O(n² min(p, m)) for the
solves — Laub's method (IEEE TAC 26, 1981; :func:`shifted_hessenberg_solve`). The solve runs on the
smaller side: ``(λI - H)ᵀ Yᵀ = (C Z)ᵀ`` when there are fewer outputs than inputs.

Not the Schur form (issue 17): its QR iterations leave a normwise backward error of some eps·‖A‖
spread over every entry, which at a point beside an eigenvalue pair with ill-conditioned eigenvectors
is read back amplified by ``‖C R(λ)‖‖R(λ) B‖``; the Hessenberg reduction is finite (exact for a
realisation already in Hessenberg form, as the designs' staircase forms are), and Gaussian elimination
with partial pivoting then has the componentwise backward error of a dense LU solve. Random seed 163's
order-72 filter (already Hessenberg, entries over 16 decades) read Q(z) 1.8e-8 off by the Schur
form, 8.9e-11 by this path and 1.8e-10 by a dense LU solve (against an 80-bit solve). Both forms are
normwise backward stable; the gain is in the constant, on realisations already (nearly) Hessenberg.

The design and its judge evaluate the same plant on several grids, stage after stage (the
post-conditions' internal form ``R = Q·Ge`` before and after the normalisation, the report);
the factorisation is therefore kept for the next call on the same matrix, found by the content
of A (a BLAKE2 digest of its bytes, shape and type), as are the eigenvalues
(:func:`eigenvalues`) and the values on a grid met again: a plant of order 1000 is factorised
once, not once per stage.
"""
from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict

import numpy as np
import scipy.linalg as sla

#: Hessenberg forms kept (least recently used first out): the plant, the basis, the filter, a spare
FORM_CACHE_SIZE = 4
#: eigenvalue sets kept
EIG_CACHE_SIZE = 32
#: value sets kept (a plant on the judge's grid is read before and after the normalisation, and by the report)
VALUE_CACHE_SIZE = 8

_form_cache: "OrderedDict[bytes, tuple[np.ndarray, np.ndarray]]" = OrderedDict()
_eig_cache: "OrderedDict[bytes, np.ndarray]" = OrderedDict()
_value_cache: "OrderedDict[bytes, np.ndarray]" = OrderedDict()
#: one lock for the three caches: designs may run in threads (a Dask campaign's threaded workers)
_lock = threading.Lock()


def clear_caches() -> None:
    """Forget every kept factorisation, spectrum and value set (a benchmark timing each stage on its own)."""
    with _lock:
        for cache in (_form_cache, _eig_cache, _value_cache):
            cache.clear()


def content_key(*arrays: np.ndarray) -> bytes:
    """A digest of the arrays' shapes, types and bytes (equal content, equal key)."""
    h = hashlib.blake2b(digest_size=20)
    for A in arrays:
        A = np.ascontiguousarray(A)
        h.update(repr((A.shape, A.dtype.str)).encode())
        h.update(A.data)
    return h.digest()


def remember(cache: OrderedDict, key: bytes, value, size: int):
    """Keep ``value`` under ``key`` in the least-recently-used ``cache`` of at most ``size`` entries; returns it."""
    with _lock:
        cache[key] = value
        cache.move_to_end(key)
        while len(cache) > size:
            cache.popitem(last=False)
    return value


def recall(cache: OrderedDict, key: bytes):
    """The kept value for ``key`` (now the most recently used), or None."""
    with _lock:
        hit = cache.get(key)
        if hit is not None:
            cache.move_to_end(key)
    return hit


def eigenvalues(A: np.ndarray) -> np.ndarray:
    """``numpy.linalg.eigvals(A)``, computed once per content of A (a fresh copy each call), block by
    block for a block-diagonal A (:func:`diagonal_blocks`); kept for ``Aᵀ`` too (a dual realisation
    and the basis it transposes into have one spectrum)."""
    key = content_key(A)
    hit = recall(_eig_cache, key)
    if hit is None:
        A = np.asarray(A)
        blocks = diagonal_blocks(A) if A.ndim == 2 and A.shape[0] == A.shape[1] else [None]
        hit = np.linalg.eigvals(A) if len(blocks) == 1 else \
            np.concatenate([np.linalg.eigvals(A[np.ix_(g, g)]) for g in blocks])
        remember(_eig_cache, key, hit, EIG_CACHE_SIZE)
        if A.ndim == 2 and A.shape[0] >= BLOCK_MIN:
            remember(_eig_cache, content_key(A.T), hit, EIG_CACHE_SIZE)
    return hit.copy()


#: relative distance (to the pole's own scale, :func:`beside_poles`) under which an evaluation point counts as on
#: a pole: at it a stable product ``Q(λ)·G(λ)`` that cancels the pole reads rounding/δ (approximate audit seed 13:
#: R_fc 1.2e5 at z = 1 against its peak 1.0); at 1e-6 the rounding is amplified by eps/δ ≈ 1e-10 only
BESIDE_POLE = 1e-6


def beside_poles(points, poles, dt: float = 0.0, rel: float = BESIDE_POLE) -> tuple[np.ndarray, np.ndarray]:
    """``(on, radius)``: the mask of the evaluation ``points`` that lie on one of ``poles`` — within ``rel`` of the
    pole's scale — and, per point, the radius ``rel·scale`` of its nearest pole (nearest relative to that scale).
    The one definition of "a grid point on a plant pole" of the designs (:mod:`..design.problems.nullspace` skips
    such points, :mod:`..design.problems.approximate_matching` moves them ``2·radius`` aside).

    A pole's scale is its own magnitude ``|p|`` — not the largest pole's: an H∞ filter's pole at 4e9 made every
    plant pole ~1 "zero" and moved the whole low band 4e3 up (approximate-matching options seed 26 read its error
    6.9e-5 for 0.298). A pole at 0 (an integrator computed ~eps‖A‖ off, a double one ~√eps off) is one whose
    magnitude is below ``√eps`` of the median pole magnitude; its scale is the smallest pole magnitude above that
    floor (1 if none, and 1 in discrete time, where the points lie on ``|λ| = 1``)."""
    points = np.atleast_1d(np.asarray(points, complex))
    poles = np.ravel(np.asarray(poles, complex))
    if not poles.size or not points.size:
        return np.zeros(points.size, bool), np.zeros(points.size)
    mags = np.abs(poles)
    floor = np.sqrt(np.finfo(float).eps) * float(np.median(mags))
    real = mags[mags > floor]
    lo = 1.0 if dt or not real.size else float(np.min(real))
    tol = rel * np.where(mags > floor, mags, lo)
    ratio = np.abs(points[:, None] - poles[None, :]) / tol[None, :]
    near = np.argmin(ratio, axis=1)
    return ratio[np.arange(points.size), near] <= 1.0, tol[near]


def hessenberg_form(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(H, Z)`` with ``A = Z H Zᵀ``, H real upper Hessenberg, Z orthogonal (Householder reflections,
    LAPACK dgehrd/dorghr; Golub & Van Loan sec. 7.4.3: a finite, backward-stable reduction); kept per content
    of A (read-only arrays: the cached form is shared)."""
    key = content_key(A)
    hit = recall(_form_cache, key)
    if hit is not None:
        return hit
    H, Z = sla.hessenberg(np.asarray(A, float), calc_q=True)
    H.setflags(write=False)
    Z.setflags(write=False)
    return remember(_form_cache, key, (H, Z), FORM_CACHE_SIZE)


def transfer_values(A, B, C, D, lams) -> np.ndarray:
    """``C (λI - A)^{-1} B + D`` at the complex points ``lams``: shape (K, p, m), NaN at a point
    where ``λI - A`` is exactly singular (an exactly zero pivot of its Hessenberg LU). Orders below
    :data:`SCHUR_MIN_ORDER`: one dense LU solve per point.

    Backward stable (a finite orthogonal reduction, then Gaussian elimination with partial pivoting), as a
    dense LU solve per point is; the values near a pole are as ill-conditioned as the point is close to it,
    either way.
    """
    A, B, C, D = (np.asarray(X, float) for X in (A, B, C, D))
    lams = np.atleast_1d(np.asarray(lams, complex))
    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    out = np.empty((lams.size, p, m), complex)
    out[:] = D
    if n == 0 or lams.size == 0 or p == 0 or m == 0:
        return out
    if not all(np.all(np.isfinite(X)) for X in (A, B, C, D)):  # as a dense solve would: NaN, no error
        out[:] = np.nan
        return out
    key = content_key(A, B, C, D, lams)
    hit = recall(_value_cache, key)
    if hit is not None:
        return hit.copy()
    if n < SCHUR_MIN_ORDER:  # small: one dense LU solve per point, as LTI.evalfr
        out[:] = dense_values(A, B, C, D, lams)
        remember(_value_cache, key, out.copy(), VALUE_CACHE_SIZE)
        return out
    rows, cols = np.flatnonzero(np.any(C != 0, axis=1)), np.flatnonzero(np.any(B != 0, axis=0))
    for g in diagonal_blocks(A):  # G = D + Σ_g C_g (λI - A_g)^{-1} B_g over the diagonal blocks of A
        sub = _strictly_proper(A[np.ix_(g, g)], B[np.ix_(g, cols)], C[np.ix_(rows, g)], lams)
        out[:, rows[:, None], cols[None, :]] += sub
    remember(_value_cache, key, out.copy(), VALUE_CACHE_SIZE)
    return out


#: (named for the Schur form this path used before issue 17's seed 163; tests set it)
#: below this order a dense LU solve per point costs no more than the Hessenberg form, and it keeps the values
#: of small models to the last bit as they were (a design that reads its grid at ω = 0 next to an
#: integrator at 1e-17 reads rounding there either way; which rounding decided test cases)
SCHUR_MIN_ORDER = 64
#: a matrix of at least this order is split into its diagonal blocks (groups of at least this order)
BLOCK_MIN = 64
#: points per stacked dense solve (:func:`dense_values`): K·n² complex entries, ≤ 16 MB at n = 63
DENSE_CHUNK = 256


def dense_values(A, B, C, D, lams) -> np.ndarray:
    """``C (λ_k I - A)^{-1} B + D`` at every point, one dense LU solve (LAPACK zgesv, partial pivoting) of
    ``λ_k I - A`` per point — the small orders' path of :func:`transfer_values`; NaN where it is exactly singular.

    The points are solved as stacks of :data:`DENSE_CHUNK` matrices (``numpy.linalg.solve`` loops zgesv over the
    stack in C): the same LAPACK call per point as one ``solve`` per point, bit for bit the same values, without a
    Python round per point (random audit seed 412's designs: 28 794 points of orders 8–55,
    benchmarks/transfer_values_speed.py). A stack holding an exactly singular matrix is solved point by point."""
    n = A.shape[0]
    out = np.empty((lams.size,) + D.shape, complex)
    Bc, diag = B.astype(complex), np.arange(n)
    for s in range(0, lams.size, DENSE_CHUNK):
        part = lams[s:s + DENSE_CHUNK]
        M = np.empty((part.size, n, n), complex)  # λI - A: -A, then λ added on the diagonal (the same sums)
        M[:] = -A
        M[:, diag, diag] += part[:, None]
        try:
            X = np.linalg.solve(M, np.broadcast_to(Bc, (part.size,) + Bc.shape))
        except np.linalg.LinAlgError:  # an exactly zero pivot somewhere in the stack: NaN at that point only
            X = np.empty((part.size,) + Bc.shape, complex)
            for k in range(part.size):
                try:
                    X[k] = np.linalg.solve(M[k], Bc)
                except np.linalg.LinAlgError:
                    X[k] = np.nan
        out[s:s + part.size] = C @ X + D
    return out


def diagonal_blocks(A: np.ndarray) -> list[np.ndarray]:
    """Index sets of a block-diagonal ``A`` (up to a permutation): the connected components of its
    nonzero pattern, merged in order into groups of at least :data:`BLOCK_MIN` states — the stacked
    rows of a bank are factorised block by block (Σ n_i³, not (Σ n_i)³). One set below BLOCK_MIN."""
    n = A.shape[0]
    if n < 2 * BLOCK_MIN:
        return [np.arange(n)]
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    count, label = connected_components(csr_matrix((A != 0) | (A.T != 0)), directed=False)
    if count == 1:
        return [np.arange(n)]
    groups, cur = [], []
    for comp in (np.flatnonzero(label == i) for i in range(count)):
        cur.append(comp)
        if sum(c.size for c in cur) >= BLOCK_MIN:
            groups.append(np.concatenate(cur))
            cur = []
    if cur:
        groups.append(np.concatenate(cur))
    return groups


def _strictly_proper(A, B, C, lams) -> np.ndarray:
    """``C (λI - A)^{-1} B`` at ``lams`` by the Hessenberg form (module docstring); NaN where singular."""
    n, p, m = A.shape[0], C.shape[0], B.shape[1]
    out = np.zeros((lams.size, p, m), complex)
    if n == 0 or p == 0 or m == 0:
        return out
    H, Z = hessenberg_form(A)
    Bh, Ch = Z.T @ B, C @ Z
    if p < m:  # the smaller side: (λI - H)ᵀ Yᵀ = (Z C)ᵀ, upper Hessenberg after reversing the order
        U, R = np.ascontiguousarray(H.T[::-1, ::-1]), Ch.T[::-1]
        X = shifted_hessenberg_solve(U, lams, R)  # (n, points, p)
        out[:] = np.einsum("nkp,nm->kpm", X[::-1], Bh)
    else:
        X = shifted_hessenberg_solve(H, lams, Bh)  # (n, points, m)
        out[:] = np.einsum("pn,nkm->kpm", Ch, X)
    return out


def shifted_hessenberg_solve(H: np.ndarray, lams: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``X[:, k, :] = (λ_k I - H)^{-1} R`` for a real upper Hessenberg H and complex points: shape (n, K, r);
    NaN for a point where ``λ_k I - H`` is exactly singular.

    Each point is one LU factorisation with partial pivoting of the banded matrix ``λ_k I - H`` (one
    subdiagonal, n - 1 superdiagonals; LAPACK zgbsv, called directly: scipy's solve_banded wrapper doubled
    the time per point), O(n²) work and O(n² r) for the solves: Gaussian
    elimination with partial pivoting, backward stable with a componentwise backward error
    ``|ΔM| ≤ γ_3n |L̂||Û|`` (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Thm 9.3) — the
    error class of a dense LU solve of ``λI - A`` itself when A is already Hessenberg (the staircase forms of
    the designs are), which the QR iterations of a Schur form are not.
    """
    n, K, r = H.shape[0], lams.size, R.shape[1]
    X = np.empty((n, K, r), complex)
    low = min(1, n - 1)  # subdiagonals (none for n = 1)
    up = n - 1
    diag = low + up  # the row of the diagonal in LAPACK's band storage with room for the fill-in (2 low + up + 1 rows)
    i, j = np.triu_indices(n, -low)  # the band: i ≤ j + 1, stored at band[diag + i - j, j]
    band = np.zeros((2 * low + up + 1, n), complex, order="F")
    band[diag + i - j, j] = -np.asarray(H, float)[i, j]
    gbsv, = sla.get_lapack_funcs(("gbsv",), (band,))
    Rc = np.asarray(R, complex, order="F")
    for k, lam in enumerate(np.asarray(lams, complex)):
        ab = band.copy(order="F")
        ab[diag] += lam
        _, _, x, info = gbsv(low, up, ab, Rc.copy(order="F"), overwrite_ab=1, overwrite_b=1)
        X[:, k, :] = x if info == 0 else np.nan  # info > 0: an exactly zero pivot, λ is an eigenvalue of H
    return X
