"""PO-MOESP subspace identification (Verhaegen 1994; Verhaegen & Verdult 2007, ch. 9).

From N samples of inputs u (m) and outputs y (p) of

    x(k+1) = A x(k) + B u(k),    y(k) = C x(k) + D u(k) + v(k),

build block Hankel matrices with s block rows of the past (U_p, Y_p) and of the future
(U_f, Y_f) and the LQ factorisation

    [U_f; Z_p; Y_f] = [L11 0 0; L21 L22 0; L31 L32 L33] Q,   Z_p = [U_p; Y_p].

``Y_f = O_s X_f + H_s U_f + V_f``: the past data Z_p is an instrument uncorrelated with
white output noise, so the column space of L32 is the extended observability matrix O_s.

- Order: the singular values σ_i of L32; n is the largest gap log(σ_i/σ_{i+1}) among the
  values above ``rtol·σ_1`` (the numerical floor; noise raises the tail evenly).
- A, C: shift invariance of O_s = U_1 Σ_1^(1/2): C = O_s[:p], A = O_s[:-p]^+ O_s[p:].
- B, D: with O_s^⊥ = U_2^T (left null space), O_s^⊥ Y_f = O_s^⊥ H_s U_f, i.e.
  O_s^⊥ L31 L11^{-1} = O_s^⊥ H_s, linear in (D, B) (Verhaegen & Dewilde 1992): solved by
  least squares. No simulation is involved, so open-loop unstable plants identified from
  closed-loop data (noise-free) come out right too.

The continuous-time model is the exact inverse of the zero-order hold (matrix logarithm
of [[A, B], [0, I]]); it exists when no eigenvalue of A is on the closed negative real axis.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ..design.problems.datadriven import past_future_lq, realize_from_lq
from ..errors import DesignError
from .errors import IdentificationError


@dataclass
class SubspaceModel:
    """A discrete-time model identified from data, with what the order decision saw.

    Attributes
    ----------
    A, B, C, D : ndarray
        Discrete-time matrices (sample time ``dt``).
    dt : float
    singular_values : ndarray
        σ_i of the projected data (the order was read from them).
    order : int
    block_rows : int
        s, the number of block rows of the past and of the future.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float
    singular_values: np.ndarray
    order: int
    block_rows: int
    info: dict = field(default_factory=dict)

    def to_continuous(self):
        """``(Ac, Bc, C, D)``: the continuous model whose ZOH sampling is this one (a static gain,
        :func:`static_model`: no state, ``D`` the gain)."""
        n, m = self.B.shape
        if self.info.get("static") is not None:
            D = np.asarray(self.info["static"], float)
            return np.zeros((0, 0)), np.zeros((0, m)), np.zeros((D.shape[0], 0)), D.copy()
        M = np.zeros((n + m, n + m))
        M[:n, :n], M[:n, n:], M[n:, n:] = self.A, self.B, np.eye(m)
        ev = np.linalg.eigvals(self.A)
        bad = ev[(np.abs(ev.imag) <= 1e-9 * np.maximum(1.0, np.abs(ev))) & (ev.real <= 0)]
        if bad.size:
            raise IdentificationError(
                f"the identified discrete model has eigenvalue(s) {np.round(bad.real, 6).tolist()} on the "
                f"negative real axis: no continuous model samples to it; choose a smaller sample time "
                f"--ts or a lower order")
        L = sla.logm(M) / self.dt
        L = L.real if np.iscomplexobj(L) else L
        return L[:n, :n], L[:n, n:], self.C.copy(), self.D.copy()

    def simulate(self, u, x0=None) -> np.ndarray:
        """Outputs for inputs u (N×m) from x0 (default 0)."""
        u = np.asarray(u, float).reshape(len(u), -1)
        x = np.zeros(self.A.shape[0]) if x0 is None else np.asarray(x0, float)
        drive = u @ self.B.T                    # the input's push per step, once for the whole record
        X = np.empty((len(u), self.A.shape[0]))
        step = self.A.dot
        for k in range(len(u)):
            X[k] = x
            x = step(x) + drive[k]
        return X @ self.C.T + u @ self.D.T


def moesp(u, y, dt: float, order: int | None = None, *, block_rows: int | None = None, max_order: int = 10,
          rtol: float = 1e-9, feedthrough: bool = True, candidates: bool = False) -> SubspaceModel:
    """Identify a discrete state-space model by PO-MOESP (module docstring).

    Parameters
    ----------
    u, y : array_like, shape (N, m) and (N, p)
        Input and output samples (deviations from the operating point).
    dt : float
        Sample time.
    order : int, optional
        Model order; default chosen from the singular values.
    block_rows : int, optional
        s (default ``max(order or max_order, 1) + 1``); the order is at most s·p − 1.
    max_order : int
        Largest order considered when choosing it.
    rtol : float
        Singular values below ``rtol·σ_1`` are the numerical floor (not states).
    feedthrough : bool
        Estimate D; False fixes D = 0 (a record whose y_k is read before u_k acts, as from a
        co-simulation master, has no feedthrough).
    candidates : bool
        Return a list from one factorisation: the order from the singular values first, then
        every order 1 … min(max_order, s·p − 1) (for an order chosen by cross-validation).

    Raises
    ------
    IdentificationError
        Too little data for the block rows (with the numbers), input not persistently
        exciting, or no state seen.
    """
    u = np.asarray(u, float)
    y = np.asarray(y, float)
    u = u.reshape(len(u), -1)
    y = y.reshape(len(y), -1)
    N, m = u.shape
    p = y.shape[1]
    if len(y) != N:
        raise IdentificationError(f"u has {N} samples but y has {len(y)}")
    if order is not None and (int(order) != order or order < 1):
        raise IdentificationError(f"order must be a positive integer, got {order!r}")
    s = int(block_rows or max(order or max_order, 1) + 1)
    if order is not None and order > s * p - 1:
        raise IdentificationError(f"order {order} needs more block rows: at most s·p − 1 = {s * p - 1} with s = {s}")
    # each channel scaled to unit RMS so that the LQ and the order decision weigh them alike
    su = np.sqrt(np.mean(u * u, axis=0))
    sy = np.sqrt(np.mean(y * y, axis=0))
    for name, sc in (("input", su), ("output", sy)):
        if np.any(sc == 0):
            raise IdentificationError(f"{name} channel(s) {np.flatnonzero(sc == 0).tolist()} are identically zero "
                                      f"in the record: nothing to identify from them")
    u, y = u / su, y / sy
    try:
        L11, L31, L32 = past_future_lq(u, y, s, IdentificationError)
    except IdentificationError as exc:
        raise IdentificationError(str(exc).replace("too little data", f"too little data for order {order or max_order}")) from None
    orders = [order] if not candidates else [None] + list(range(1, min(max_order, s * p - 1) + 1))
    out = []
    for n_ in orders:
        try:
            A, B, C, D, sv = realize_from_lq(L11, L31, L32, s, m, p, n_, max_order=max_order, rtol=rtol,
                                             feedthrough=feedthrough)
        except DesignError as exc:
            if n_ is None or n_ == order:
                raise IdentificationError(str(exc)) from None
            continue
        n = A.shape[0]
        C, D, B = sy[:, None] * C, sy[:, None] * D / su, B / su
        out.append(SubspaceModel(A, B, C, D, float(dt), sv[: min(len(sv), max_order + 1)], n, s,
                                 info={"samples": N}))
    return out if candidates else out[0]


def static_model(u, y, dt: float) -> SubspaceModel:
    """Order 0: a static plant ``y(t) = D u(t)`` (a pure feedthrough), D by least squares.

    A co-simulation record reads y_k after the step that u_{k−1} drove (the inputs of a step are
    set at its start, the outputs read at its end), so the record sees ``y_{k+1} = D u_k``: the
    discrete model is that one-sample delay (``x⁺ = u``, ``y = D x``: what validation and the noise
    model simulate), its continuous model the gain D alone (``info['static']``)."""
    u = np.asarray(u, float).reshape(len(u), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    N, m = u.shape
    if N < 2 * m + 2:
        raise IdentificationError(f"too little data for a static gain: {N} samples for {m} inputs")
    s = np.linalg.svd(u[:-1], compute_uv=False)
    if not s[-1] > 1e-9 * s[0]:
        raise IdentificationError(f"the inputs are not independent in the record (singular values "
                                  f"{np.array2string(s, precision=3)}): excite each input")
    D = np.linalg.lstsq(u[:-1], y[1:], rcond=None)[0].T
    return SubspaceModel(np.zeros((m, m)), np.eye(m), D, np.zeros((y.shape[1], m)), float(dt), np.zeros(0), 0, 1,
                         info={"samples": N, "static": D})


#: an order within this factor (plus a floor) of the best validation error counts as as good as the best
PARSIMONY = (1.02, 1e-4)


def least_order_near_best(scored):
    """Parsimony in the order choice: among ``(error, order, candidate)`` triples, the candidate of
    least order whose validation error is within ``1.02·best + 1e-4`` of the best (a 2 % relative and
    1e-4 absolute allowance: a higher order that fits the validation data no better is over-fitting
    noise; Ljung 1999, sec. 16.4, the parsimony principle). ``scored`` must not be empty."""
    best = min(e for e, _, _ in scored)
    factor, floor = PARSIMONY
    return min((c for c in scored if c[0] <= factor * best + floor), key=lambda c: c[1])[2]
