"""Frequency responses of large realisations: one Schur form of A, reused across points and stages.

A transfer matrix ``G(λ) = C (λI - A)^{-1} B + D`` at K points costs K dense O(n³) solves when
each point is solved on its own. With the real Schur form ``A = Z T Zᵀ`` (T upper quasi-triangular,
Z orthogonal; Golub & Van Loan, *Matrix Computations*, 4th ed., sec. 7.5) every point is one
quasi-triangular solve

    G(λ) = (C Z) (λI - T)^{-1} (Zᵀ B) + D,

O(n² min(p, m)), and between two points only the diagonal of ``λI - T`` changes — Laub's method
(IEEE TAC 26, 1981) with the Schur form in place of the Hessenberg form, so that all the points are
solved together by one block back substitution whose work is real matrix products
(:func:`shifted_triangular_solve`). The solve runs on the smaller side: ``(λI - T)ᵀ Yᵀ = (C Z)ᵀ``
when there are fewer outputs than inputs.

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

#: factorisations kept (least recently used first out): the plant, the basis, the filter, a spare
SCHUR_CACHE_SIZE = 4
#: eigenvalue sets kept
EIG_CACHE_SIZE = 32
#: value sets kept (a plant on the judge's grid is read before and after the normalisation, and by the report)
VALUE_CACHE_SIZE = 8

_schur_cache: "OrderedDict[bytes, tuple[np.ndarray, np.ndarray]]" = OrderedDict()
_eig_cache: "OrderedDict[bytes, np.ndarray]" = OrderedDict()
_value_cache: "OrderedDict[bytes, np.ndarray]" = OrderedDict()
#: one lock for the three caches: designs may run in threads (a Dask campaign's threaded workers)
_lock = threading.Lock()


def clear_caches() -> None:
    """Forget every kept factorisation, spectrum and value set (a benchmark timing each stage on its own)."""
    with _lock:
        for cache in (_schur_cache, _eig_cache, _value_cache):
            cache.clear()


def content_key(*arrays: np.ndarray) -> bytes:
    """A digest of the arrays' shapes, types and bytes (equal content, equal key)."""
    h = hashlib.blake2b(digest_size=20)
    for A in arrays:
        A = np.ascontiguousarray(A)
        h.update(repr((A.shape, A.dtype.str)).encode())
        h.update(A.data)
    return h.digest()


def _remember(cache: OrderedDict, key: bytes, value, size: int):
    with _lock:
        cache[key] = value
        cache.move_to_end(key)
        while len(cache) > size:
            cache.popitem(last=False)
    return value


def _recall(cache: OrderedDict, key: bytes):
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
    hit = _recall(_eig_cache, key)
    if hit is None:
        A = np.asarray(A)
        blocks = diagonal_blocks(A) if A.ndim == 2 and A.shape[0] == A.shape[1] else [None]
        hit = np.linalg.eigvals(A) if len(blocks) == 1 else \
            np.concatenate([np.linalg.eigvals(A[np.ix_(g, g)]) for g in blocks])
        _remember(_eig_cache, key, hit, EIG_CACHE_SIZE)
        if A.ndim == 2 and A.shape[0] >= BLOCK_MIN:
            _remember(_eig_cache, content_key(A.T), hit, EIG_CACHE_SIZE)
    return hit.copy()


def schur_form(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(T, Z)`` with ``A = Z T Zᵀ``, T real upper quasi-triangular (1×1 and 2×2 diagonal blocks, LAPACK
    dgees), Z orthogonal; kept per content of A (read-only arrays: the cached form is shared)."""
    key = content_key(A)
    hit = _recall(_schur_cache, key)
    if hit is not None:
        return hit
    T, Z = sla.schur(np.asarray(A, float), output="real")
    T.setflags(write=False)
    Z.setflags(write=False)
    return _remember(_schur_cache, key, (T, Z), SCHUR_CACHE_SIZE)


def transfer_values(A, B, C, D, lams) -> np.ndarray:
    """``C (λI - A)^{-1} B + D`` at the complex points ``lams``: shape (K, p, m), NaN at a point
    where ``λI - A`` is exactly singular (λ equals an eigenvalue of the Schur form). Orders below
    :data:`SCHUR_MIN_ORDER`: one dense LU solve per point.

    Backward stable (orthogonal reduction, then a triangular solve), as a dense LU solve per point is;
    the values near a pole are as ill-conditioned as the point is close to it, either way.
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
    hit = _recall(_value_cache, key)
    if hit is not None:
        return hit.copy()
    if n < SCHUR_MIN_ORDER:  # small: one dense LU solve per point, as LTI.evalfr
        eye, Bc = np.eye(n), B.astype(complex)
        for k, lam in enumerate(lams):
            try:
                out[k] = C @ np.linalg.solve(lam * eye - A, Bc) + D
            except np.linalg.LinAlgError:
                out[k] = np.nan
        _remember(_value_cache, key, out.copy(), VALUE_CACHE_SIZE)
        return out
    rows, cols = np.flatnonzero(np.any(C != 0, axis=1)), np.flatnonzero(np.any(B != 0, axis=0))
    for g in diagonal_blocks(A):  # G = D + Σ_g C_g (λI - A_g)^{-1} B_g over the diagonal blocks of A
        sub = _strictly_proper(A[np.ix_(g, g)], B[np.ix_(g, cols)], C[np.ix_(rows, g)], lams)
        out[:, rows[:, None], cols[None, :]] += sub
    _remember(_value_cache, key, out.copy(), VALUE_CACHE_SIZE)
    return out


#: below this order a dense LU solve per point costs no more than the Schur form, and it keeps the values
#: of small models to the last bit as they were (a design that reads its grid at ω = 0 next to an
#: integrator at 1e-17 reads rounding there either way; which rounding decided test cases)
SCHUR_MIN_ORDER = 64
#: a matrix of at least this order is split into its diagonal blocks (groups of at least this order)
BLOCK_MIN = 64


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
    """``C (λI - A)^{-1} B`` at ``lams`` by the Schur form (module docstring); NaN where singular."""
    n, p, m = A.shape[0], C.shape[0], B.shape[1]
    out = np.zeros((lams.size, p, m), complex)
    if n == 0 or p == 0 or m == 0:
        return out
    T, Z = schur_form(A)
    Bh, Ch = Z.T @ B, C @ Z
    if p < m:  # the smaller side: (λI - T)ᵀ Yᵀ = (C Z)ᵀ, upper quasi-triangular after reversing the order
        U, R = np.ascontiguousarray(T.T[::-1, ::-1]), Ch.T[::-1]
    else:
        U, R = T, Bh
    r = R.shape[1]
    step = max(1, 512 // r)  # points per pass: the right-hand sides of all of them form one block
    for k0 in range(0, lams.size, step):
        X = shifted_triangular_solve(U, lams[k0:k0 + step], R)  # (n, points, r)
        if p < m:
            out[k0:k0 + step] = np.einsum("nkp,nm->kpm", X[::-1], Bh)
        else:
            out[k0:k0 + step] = np.einsum("pn,nkm->kpm", Ch, X)
    return out


#: rows of a diagonal block in :func:`shifted_triangular_solve`
SOLVE_BLOCK = 64


def shifted_triangular_solve(U: np.ndarray, lams: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``X[:, k, :] = (λ_k I - U)^{-1} R`` for a real upper quasi-triangular U (a real Schur form) and
    complex points, all at once: shape (n, K, r); NaN for a point where ``λ_k I - U`` is singular.

    Block back substitution (Golub & Van Loan, sec. 3.1): within a diagonal block of about
    :data:`SOLVE_BLOCK` rows, row by row (a 2×2 diagonal block of U by Cramer's rule) for every point
    together; above it, one matrix product with the block's solution. U is real, so every update is
    a real matrix product on the real and imaginary parts side by side (half the work of complex
    arithmetic), and the O(n² K r) work runs as a matrix product instead of K triangular solves.
    """
    n, K, r = U.shape[0], lams.size, R.shape[1]
    X = np.empty((n, K * r), complex)
    X[:] = np.tile(np.asarray(R, float), (1, K))  # column k·r + i: point k, right-hand side i
    Xv = X.view(float)  # (n, 2 K r): real and imaginary parts interleaved; a real row operation acts on both
    lam = np.repeat(np.asarray(lams, complex), r)
    sub = np.zeros(n)
    sub[1:] = np.diagonal(U, -1)
    zero = np.zeros(K * r, bool)

    def pivot(d):
        zero[:] |= d == 0
        return np.where(d == 0, 1.0, d)

    hi = n
    while hi > 0:
        lo = max(0, hi - SOLVE_BLOCK)
        if lo > 0 and sub[lo] != 0:
            lo -= 1  # do not split a 2×2 block
        j = hi - 1
        while j >= lo:
            i = j - 1 if j > lo and sub[j] != 0 else j  # rows i..j: a 1×1 or 2×2 diagonal block
            if j + 1 < hi:  # (λI - U_jj) x_j = r_j + Σ_{l > j} u_jl x_l
                Xv[i:j + 1] += U[i:j + 1, j + 1:hi] @ Xv[j + 1:hi]
            if i == j:
                X[j] /= pivot(lam - U[j, j])
            else:
                a11, a22, a12, a21 = lam - U[i, i], lam - U[j, j], -U[i, j], -U[j, i]
                det = pivot(a11 * a22 - a12 * a21)
                r1, r2 = X[i].copy(), X[j].copy()
                X[i] = (a22 * r1 - a12 * r2) / det
                X[j] = (a11 * r2 - a21 * r1) / det
            j = i - 1
        if lo:
            Xv[:lo] += U[:lo, lo:hi] @ Xv[lo:hi]
        hi = lo
    X = X.reshape(n, K, r)
    X[:, np.any(zero.reshape(K, r), axis=1), :] = np.nan
    return X
