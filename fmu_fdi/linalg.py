"""Orthogonal rank and subspace helpers with tolerances relative to the data's norm.

Every rank decision in fmu-fdi goes through :func:`rank_tol`, so one rule holds
everywhere: a singular value counts when it exceeds ``rtol * sigma_max`` (plus an
optional absolute floor). The default ``rtol = max(shape) * eps * 1e3`` follows
LAPACK practice (``max(m, n) * eps * ||M||``) with three digits of headroom for data
that went through a few orthogonal transformations before the test.
"""
from __future__ import annotations

import functools

import numpy as np
import scipy.linalg as sla

EPS = np.finfo(float).eps


def single_blas_thread(fn):
    """Run ``fn`` with one BLAS/LAPACK thread.

    Design code works on matrices of at most a few hundred rows, where threaded BLAS gains
    nothing and, on a loaded machine, its spin-waiting threads cost up to 50x (measured on
    the n = 200 benchmark: 0.35 s single-threaded, 19 s with default threads next to one
    other busy process on 2 cores).
    """

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper


def default_rtol(shape) -> float:
    """Relative rank tolerance for a matrix of the given shape."""
    return max(1, *shape) * EPS * 1e3


def rank_tol(s: np.ndarray, shape, rtol: float | None = None, atol: float = 0.0) -> float:
    """Threshold below which singular values ``s`` (descending) count as zero."""
    if rtol is None:
        rtol = default_rtol(shape)
    smax = s[0] if s.size else 0.0
    return max(rtol * smax, atol)


def rank(M: np.ndarray, rtol: float | None = None, atol: float = 0.0) -> int:
    """Numerical rank by SVD with a tolerance relative to ``||M||_2``."""
    M = np.atleast_2d(np.asarray(M))
    if M.size == 0:
        return 0
    s = sla.svd(M, compute_uv=False)
    return int(np.sum(s > rank_tol(s, M.shape, rtol, atol)))


def left_null(M: np.ndarray, rtol: float | None = None, atol: float = 0.0) -> np.ndarray:
    """Orthonormal rows ``N`` spanning the left null space: ``N @ M ~ 0``.

    Returned as a (k, rows) array; ``k = rows - rank(M)``.
    """
    M = np.atleast_2d(np.asarray(M, dtype=float))
    rows = M.shape[0]
    if M.shape[1] == 0 or not np.any(M):
        return np.eye(rows)
    U, s, _ = sla.svd(M, full_matrices=True)
    r = int(np.sum(s > rank_tol(s, M.shape, rtol, atol)))
    return U[:, r:].T.copy()


def right_null(M: np.ndarray, rtol: float | None = None, atol: float = 0.0) -> np.ndarray:
    """Orthonormal columns spanning the right null space: ``M @ N ~ 0``."""
    return left_null(np.asarray(M).T, rtol, atol).T


def orth_rows(M: np.ndarray, rtol: float | None = None, atol: float = 0.0) -> np.ndarray:
    """Orthonormal rows spanning the row space of ``M``."""
    M = np.atleast_2d(np.asarray(M, dtype=float))
    if M.size == 0:
        return np.zeros((0, M.shape[1]))
    _, s, Vh = sla.svd(M, full_matrices=False)
    r = int(np.sum(s > rank_tol(s, M.shape, rtol, atol)))
    return Vh[:r]


def complement_rows(N: np.ndarray, S: np.ndarray, rtol: float | None = None) -> np.ndarray:
    """Orthonormal rows of ``span(N)`` orthogonal to ``span(S)``.

    ``N`` must have orthonormal rows and ``span(S) ⊂ span(N)`` (numerically). The
    result has ``dim span(N) - rank(S)`` rows.
    """
    if S.shape[0] == 0:
        return N.copy()
    Sorth = orth_rows(S, rtol)
    Z = N - (N @ Sorth.T) @ Sorth
    k = N.shape[0] - Sorth.shape[0]
    if k <= 0:
        return np.zeros((0, N.shape[1]))
    _, _, Vh = sla.svd(Z, full_matrices=False)
    return Vh[:k]


def is_finite(*arrays) -> bool:
    return all(np.all(np.isfinite(np.asarray(a, dtype=float))) for a in arrays)


def sqrtm_psd(M: np.ndarray) -> np.ndarray:
    """Symmetric square root of a positive semidefinite matrix (via eigh)."""
    w, V = sla.eigh((M + M.T) / 2)
    w = np.clip(w, 0.0, None)
    return (V * np.sqrt(w)) @ V.T


def inv_sqrtm_pd(M: np.ndarray) -> np.ndarray:
    """Symmetric inverse square root of a positive definite matrix (via eigh)."""
    w, V = sla.eigh((M + M.T) / 2)
    if w[0] <= EPS * max(1.0, w[-1]) * M.shape[0]:
        raise np.linalg.LinAlgError("matrix is not positive definite")
    return (V / np.sqrt(w)) @ V.T


def ordered_schur(A: np.ndarray, select) -> tuple[np.ndarray, np.ndarray, int]:
    """Real Schur form ``A = Z T Zᵀ`` with the eigenvalues ``select(re, im)`` accepts leading: ``(T, Z, k)``.

    As ``scipy.linalg.schur(A, output='real', sort=select)``, but membership is decided ONCE, on
    the eigenvalues of the unordered form's diagonal blocks (both members of a complex pair by
    the one with ``im > 0``), and the blocks are then reordered by LAPACK ``dtrsen`` (Bai &
    Demmel 1993), which takes that decision as given. The ``gees`` sort re-evaluates ``select``
    on the reordered form, whose eigenvalues move by rounding (``‖A‖·eps`` relative, far more for
    a defective cluster): one on the boundary of the region can change side, and ``gees`` then
    fails with "Leading eigenvalues do not satisfy sort condition". Here ``k`` is the number of
    selected eigenvalues, counted on the decision made.
    """
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    if n == 0:
        return A.copy(), np.eye(0), 0
    T, Z = sla.schur(A, output="real")
    mask = np.zeros(n, dtype=np.int32)
    i = 0
    while i < n:
        if i + 1 < n and T[i + 1, i] != 0.0:
            ev = np.linalg.eigvals(T[i:i + 2, i:i + 2])
            z = ev[np.argmax(ev.imag)]
            mask[i:i + 2] = bool(select(float(z.real), float(abs(z.imag))))
            i += 2
        else:
            mask[i] = bool(select(float(T[i, i]), 0.0))
            i += 1
    k = int(mask.sum())
    if k in (0, n) or np.all(mask[:k]):
        return T, Z, k
    Ts, Zs, _, _, m, _, _, info = sla.lapack.dtrsen(mask, T, Z, job="N")
    if info != 0:  # dtrsen's only failure (info = 1): two blocks too close to be swapped stably
        from .errors import DesignError

        raise DesignError(f"the real Schur form cannot be reordered (LAPACK dtrsen info = {info}): eigenvalues on "
                          f"both sides of the region's boundary are too close to separate (order {n}, {k} selected)")
    return Ts, Zs, int(m)


def shifted_hessenberg_solve(H: np.ndarray, lam: complex, R: np.ndarray) -> tuple[np.ndarray, float]:
    """``X = (lam I - H)^{-1} R`` for an upper Hessenberg ``H`` in O(n²) per column of R,
    and the reciprocal condition estimate of the triangular factor.

    Gaussian elimination with partial pivoting restricted to the one subdiagonal (each step
    chooses the larger of rows k, k+1; multipliers are at most 1 in modulus), then one
    back substitution (LAPACK ``ztrtrs``) — the frequency-response method of Laub
    (IEEE TAC 26, 1981, "Efficient multivariable frequency response computations"): with
    ``A = Z H Zᵀ`` reduced once, every further point costs O(n²) instead of a dense O(n³)
    solve. ``rcond`` is LAPACK ``ztrcon`` of the triangular factor in the 1-norm (the
    pivoted bidiagonal L has entries at most 1, so it estimates the conditioning of
    ``lam I - H``); a zero pivot raises :class:`numpy.linalg.LinAlgError`.
    """
    n = H.shape[0]
    M = np.array(H, dtype=complex, order="F")  # Fortran order: LAPACK reads it without a copy
    M *= -1.0
    M[np.diag_indices(n)] += lam
    X = np.array(R, dtype=complex, order="F")
    for k in range(n - 1):
        a, b = M[k, k], M[k + 1, k]
        if b == 0:
            continue
        if abs(b) > abs(a):
            row = M[k, k:].copy()
            M[k, k:] = M[k + 1, k:]
            M[k + 1, k:] = row
            row = X[k].copy()
            X[k] = X[k + 1]
            X[k + 1] = row
            a, b = b, a
        lk = b / a
        M[k + 1, k + 1:] -= lk * M[k, k + 1:]
        M[k + 1, k] = 0.0
        X[k + 1] -= lk * X[k]
    diag = np.abs(np.diagonal(M))
    if n and not np.all(diag > 0):
        raise np.linalg.LinAlgError(f"lam I - A is singular at lam = {lam}: zero pivot {int(np.argmin(diag)) + 1} "
                                    f"of {n}")
    ztrcon, = sla.get_lapack_funcs(("trcon",), (M,))
    rcond, info = ztrcon(M, norm="1", uplo="U", diag="N")
    X = sla.solve_triangular(M, X, lower=False, check_finite=False)
    return X, float(rcond)
