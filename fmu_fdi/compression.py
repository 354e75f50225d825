"""Orthogonal row compressions of a tall block, applied without forming an n × n orthogonal matrix.

A staircase step (controllability staircase, output-nulling deflation, Type 1 dynamic covers;
Varga 2017, sec. 10.1) rotates the trailing coordinates so that the first ``ρ`` rows carry a
block ``P`` of m rows and c ≪ m columns, ``Uᵀ P = [Σ Vᵀ; 0]``, with the rank ρ decided on the
singular values. The full SVD forms U (m × m) and rotating the system with it costs O(n m²) a
step, O(n⁴) for a staircase of n/c steps. Here

    P = Q [R; 0]  (Householder QR, LAPACK dgeqrf),   R = U_r Σ Vᵀ  (SVD of the c × c triangle),
    U = Q diag(U_r, I),

the same compression (the singular values of R are those of P; the first ρ columns of U are P's
left singular vectors, the rest an orthonormal completion) applied in O(n m c) a
step (the reflectors in compact WY form, matrix products), O(n³) for the staircase — the cost of a
Hessenberg reduction.

Rows of P past its last nonzero row are left out of the rotation (``U = U_w ⊕ I``): a staircase on
a pair already in block Hessenberg form (the chain-ordered pair of a Type 1 cover) then rotates
only the rows its next block reaches, O(n c²) a step. Any orthonormal completion is as good as
another: the staircase's blocks are the Krylov subspaces of the pair, which do not depend on it.

Blocks of at most :data:`DENSE_ROWS` rows take the full SVD as before (the same rotation to the last
bit for the small models of the test suite).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

#: a block of at most this many rows is compressed by a full SVD and its explicit U
DENSE_ROWS = 64


class RowCompression:
    """``Uᵀ P = [Σ Vᵀ; 0]`` for a block ``P`` (m × c): singular values ``s`` and the rotation U,
    applied to the rows/columns of other matrices by :meth:`rotate`."""

    def __init__(self, part: np.ndarray):
        m, c = part.shape
        self.U = self.qr = self.tau = self.Ur = self._V = self._T = None
        if m <= DENSE_ROWS:
            self.U, self.s, _ = sla.svd(part, full_matrices=True)
            self.width = m
            return
        nz = np.flatnonzero(np.any(part != 0, axis=1))
        self.width = w = int(nz[-1]) + 1 if nz.size else 0
        if w == 0:
            self.s = np.zeros(min(m, c))
        elif w <= DENSE_ROWS or w <= c:
            self.U, self.s, _ = sla.svd(part[:w], full_matrices=True)
        else:
            geqrf, = sla.get_lapack_funcs(("geqrf",), (part,))
            qr, tau, _, info = geqrf(np.array(part[:w], order="F"))
            if info != 0:  # pragma: no cover - geqrf fails only on invalid arguments
                raise np.linalg.LinAlgError(f"Householder QR failed (LAPACK dgeqrf info = {info})")
            self.qr, self.tau = qr, tau
            self.Ur, self.s, _ = sla.svd(np.triu(qr[:c, :c]))

    def _wy(self):
        """``Q = I - V T Vᵀ`` (compact WY form of the reflectors; Schreiber & Van Loan 1989, LAPACK dlarft):
        V unit lower trapezoidal from dgeqrf, T upper triangular by the forward recurrence."""
        if self._V is None:
            qr, tau = self.qr, self.tau
            c = tau.size
            V = np.tril(qr[:, :c], -1)
            V[np.arange(c), np.arange(c)] = 1.0
            T = np.zeros((c, c))
            for i in range(c):
                T[:i, i] = -tau[i] * (T[:i, :i] @ (V[:, :i].T @ V[:, i]))
                T[i, i] = tau[i]
            self._V, self._T = V, T
        return self._V, self._T

    def _left_T(self, X: np.ndarray) -> None:
        """``X ← Uᵀ X`` in place (X a view of ``width`` rows: no copy of the rows it spans)."""
        if self.U is not None:
            X[...] = self.U.T @ X
            return
        V, T = self._wy()
        X -= V @ (T.T @ (V.T @ X))
        c = self.Ur.shape[0]
        X[:c] = self.Ur.T @ X[:c]

    def _right(self, X: np.ndarray) -> None:
        """``X ← X U`` in place (X a view of ``width`` columns)."""
        if self.U is not None:
            X[...] = X @ self.U
            return
        V, T = self._wy()
        X -= ((X @ V) @ T) @ V.T
        c = self.Ur.shape[0]
        X[:, :c] = X[:, :c] @ self.Ur

    def rotate(self, start: int, a: np.ndarray, rows=(), cols=()) -> None:
        """In place, with Z the identity whose block at ``start`` is U (the block P sat at rows
        ``start:start + m`` of the system): ``a ← Zᵀ a Z``, each of ``rows`` ``← Zᵀ X``, each of
        ``cols`` ``← X Z``. Only the ``width`` rows/columns U acts on change (updated through views:
        a staircase on a large pair is bound by memory traffic, not by arithmetic)."""
        if self.width == 0:
            return
        sl = slice(start, start + self.width)
        self._left_T(a[sl, :])
        self._right(a[:, sl])
        for X in rows:
            self._left_T(X[sl, :])
        for X in cols:
            self._right(X[:, sl])


def staircase_zeros(a: np.ndarray, b: np.ndarray, taus: list[int]) -> None:
    """In place: zero the entries of ``(a, b)`` below the block Hessenberg pattern of a staircase
    with block sizes ``taus`` (``b`` below block 1, block column j of ``a`` below block j + 2) —
    the rounding (and the singular values at or below the rank tolerance) the staircase's rank
    decisions declared zero, set to zero as a Hessenberg reduction does, so that a later staircase
    on the pair sees the structure (:class:`RowCompression` rotates only the rows it reaches)."""
    starts = np.cumsum([0] + list(taus))
    if len(taus):
        b[starts[1]:, :] = 0.0
    for j in range(len(taus)):
        a[starts[min(j + 2, len(taus))]:, starts[j]:starts[j + 1]] = 0.0


def nonzero_spans(M: np.ndarray, *cuts: int) -> list[slice]:
    """The rows of M split at ``cuts`` into contiguous ranges, each trimmed to its first and last row with a
    nonzero entry (empty ranges dropped): an update ``X[rows] += M[rows] Y`` over these slices changes
    what it would over all rows (the zero rows add exact zeros) and costs their size only — the
    elimination of a Type 1 cover works on a block Hessenberg pair whose blocks reach a few rows."""
    nz = np.any(M != 0, axis=1)
    edges = sorted({0, M.shape[0], *[min(max(c, 0), M.shape[0]) for c in cuts]})
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        idx = np.flatnonzero(nz[lo:hi])
        if idx.size:
            out.append(slice(lo + int(idx[0]), lo + int(idx[-1]) + 1))
    return out
