"""The Python RLS runtime with the native runtime's summation order (a test reference).

numpy evaluates the RLS products with OpenBLAS kernels (blocked, vectorised sums); the C
runtime sums dot products sequentially, in index order. Both are correct roundings of the
same formulas (docs/semantics.md §4.2), and the RLS recursion amplifies their last-bit
differences (to ~1e-12 after thousands of updates). ``sequential_rls()`` patches
:class:`fmu_fdi.runtime.rls.RLSStep` so that it does exactly the C runtime's floating-point
operations: the native outputs must then agree bit for bit, which separates "a different
rounding order" from "a different computation".
"""
import contextlib

import numpy as np

from fmu_fdi.runtime import rls as R


def _mv(M, x):
    out = np.empty(M.shape[0])
    for i in range(M.shape[0]):
        acc = 0.0
        for j in range(M.shape[1]):
            acc += float(M[i, j]) * float(x[j])
        out[i] = acc
    return out


def _dot(a, b):
    acc = 0.0
    for x, y in zip(a, b):
        acc += float(x) * float(y)
    return acc


def _mm(A, B):
    out = np.empty((A.shape[0], B.shape[1]))
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            acc = 0.0
            for q in range(A.shape[1]):
                acc += float(A[i, q]) * float(B[q, j])
            out[i, j] = acc
    return out


def _trace(P):
    acc = 0.0
    for q in range(P.shape[0]):
        acc += float(P[q, q])
    return acc


def _step_one(self, i, est, w):
    x = self._x[i]
    z = _mv(est.C, x) + _mv(est.D, w)
    self._x[i] = _mv(est.A, x) + _mv(est.B, w)
    if self.k < est.skip:
        return np.zeros(est.npar)
    self._update(i, z[0], z[1:])
    if self.k + 1 < est.warmup:
        return np.zeros(est.npar)
    return self._residual(i, est)


def _update(self, i, psi, phi):
    est = self.estimators[i]
    mu, P, theta = self.mu, self._P[i], self._theta[i]
    Pphi = _mv(P, phi)
    s = mu + _dot(phi, Pphi)
    K = Pphi / s
    err = psi - _dot(phi, theta)
    self._theta[i] = theta + K * err
    J = np.eye(P.shape[0]) - np.outer(K, phi)
    P = (_mm(_mm(J, P), J.T) + mu * np.outer(K, K)) / mu
    P = 0.5 * (P + P.T)
    tr = _trace(P)
    if tr > est.trace_max:
        P = P * (est.trace_max / tr)
    n = self._updates[i] = self._updates[i] + 1
    if (self.policy == "floor" and _trace(P) < est.trace_min) or (self.policy == "periodic" and n % self.period == 0):
        P = self.P0 * np.eye(P.shape[0])
        self._resets[i] += 1
    self._P[i] = P
    gamma = max(1.0 / n, 1.0 - self.mu_sigma)
    e2 = err * err * mu / s
    if self.clip and n > self.clip_after:
        sig = self._sigma(i, est)
        e2 = min(e2, (self.clip * self.clip) * (sig * sig))
    self._sigma2[i] += gamma * (e2 - self._sigma2[i])
    self._psi2[i] += gamma * (psi * psi - self._psi2[i])


@contextlib.contextmanager
def sequential_rls():
    saved = R.RLSStep._step_one, R.RLSStep._update
    R.RLSStep._step_one, R.RLSStep._update = _step_one, _update
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            yield
    finally:
        R.RLSStep._step_one, R.RLSStep._update = saved
