"""Data-driven parity relations from a fault-free I/O log (Ding 2014, ch. 5: subspace-aided
design of residual generators; the stable kernel representation identified from data).

With block Hankel matrices of s block rows of the past ``Z_p = [U_p; Y_p]`` and the future
``U_f``, ``Y_f`` of a fault-free record, the LQ factorisation

    [U_f; Z_p; Y_f] = [L11 0 0; L21 L22 0; L31 L32 L33] Q

separates ``Y_f = Γ_s X_f + H_u,s U_f (+ noise)``: the columns of L32 span the extended
observability matrix Γ_s (the past carries the state). With the SVD
``L32 = [U1 U2] diag(Σ1, Σ2) V^T`` (Σ2 at the noise floor), the rows of ``Γ_s^⊥ = U2^T``
annihilate the state, and ``Γ_s^⊥ H_u,s = Γ_s^⊥ L31 L11^{-1}``. The residual

    r(k) = Γ_s^⊥ y_s(k) − Γ_s^⊥ H_u,s u_s(k),   y_s(k) = [y(k−s+1); …; y(k)],

is zero for every fault-free trajectory of the linear plant and responds to faults
(Ding 2014, Theorem 5.1: the data-driven realisation of the kernel representation). It is
a finite-memory filter (all poles at 0), realised here as a shift register.

For isolation of sensor faults (a dedicated scheme, Clark 1978), relation i is identified
from u and the one output y_i the fault acts on: it cannot see the other sensors' faults.

The order n of the plant seen by each relation is read from the singular values of L32
(largest gap above ``rtol·σ_1``); ``s`` defaults to the smallest window giving at least one
relation (``s·p_i > n``) plus ``extra`` block rows, which average noise over a longer window.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..errors import DesignError
from ..generator import ResidualBank, ResidualGenerator
from ..lti import LTI
from ..model import FDIModel


def block_hankel(w: np.ndarray, start: int, rows: int, cols: int) -> np.ndarray:
    """Block Hankel matrix with block (i, j) = w[start + i + j] (column vector), rows·dim × cols."""
    d = w.shape[1]
    H = np.empty((rows * d, cols))
    for i in range(rows):
        H[i * d:(i + 1) * d] = w[start + i:start + i + cols].T
    return H


def past_future_lq(u: np.ndarray, y: np.ndarray, s: int, error=DesignError):
    """``(L11, L31, L32)`` of the LQ factorisation of ``[U_f; U_p; Y_p; Y_f]`` (module docstring).

    Raises ``error`` when the record is too short for s block rows or the inputs are not
    persistently exciting of order 2s.
    """
    N, m = u.shape
    p = y.shape[1]
    rows = 2 * s * (m + p)
    j = N - 2 * s + 1
    if j < 2 * rows:
        raise error(f"too little data: {N} samples give {max(j, 0)} Hankel columns for {rows} rows (s = {s} block "
                    f"rows, {m} inputs, {p} outputs); record at least {2 * rows + 2 * s - 1} samples or use "
                    f"fewer block rows (a lower order)")
    H = np.vstack([block_hankel(u, s, s, j), block_hankel(u, 0, s, j), block_hankel(y, 0, s, j),
                   block_hankel(y, s, s, j)])
    L = sla.qr(H.T, mode="r")[0][:rows].T
    sm, sz = s * m, s * (m + p)
    L11 = L[:sm, :sm]
    d = np.abs(np.diag(L11))
    if d.size and d.min() <= 1e-10 * d.max():
        raise error("the input is not persistently exciting of order 2s: the future inputs are (nearly) linearly "
                    f"dependent (min/max |diag L11| = {d.min() / d.max():.2g}); excite every input with a richer "
                    "signal (multisine or PRBS) or lower the order")
    return L11, L[sm + sz:, :sm], L[sm + sz:, sm:sm + sz]


def order_from_singular_values(sv: np.ndarray, max_order: int, rtol: float = 1e-9) -> int:
    """The largest gap log(σ_i/σ_{i+1}) among the values above ``rtol·σ_1`` (at least 1)."""
    cands = int(min(max_order, sv.size - 1, np.sum(sv > rtol * sv[0])))
    if cands < 1:
        return 1
    gaps = np.log(sv[:cands] / np.maximum(sv[1:cands + 1], rtol * sv[0]))
    return int(np.argmax(gaps)) + 1


def _parity_rows(u, y, s, n):
    """``(Γ⊥, Γ⊥ H_u,s)`` from the record (deviations) with s block rows and order n."""
    L11, L31, L32 = past_future_lq(u, y, s)
    U = sla.svd(L32, full_matrices=True)[0]
    G = U[:, n:].T
    M = sla.solve_triangular(L11.T, (G @ L31).T, lower=False).T
    return G, M


def _fir(Wy, Wu, y_idx, ny, nu, s, dt) -> LTI:
    """Shift-register realisation of r(k) = Σ_l Wy_l y(k−s+1+l) + Wu_l u(k−s+1+l) on [y; u]."""
    q = Wy.shape[0]
    v = ny + nu
    # coefficient of v(k − i), i = 0..s−1, over the full [y; u]
    coef = []
    for i in range(s):
        l = s - 1 - i
        c = np.zeros((q, v))
        c[:, y_idx] = Wy[:, l * len(y_idx):(l + 1) * len(y_idx)]
        c[:, ny:] = Wu[:, l * nu:(l + 1) * nu]
        coef.append(c)
    nx = (s - 1) * v
    A = np.zeros((nx, nx))
    B = np.zeros((nx, v))
    if nx:
        B[:v] = np.eye(v)
        A[v:, :-v] = np.eye(nx - v)
    C = np.hstack(coef[1:]) if nx else np.zeros((q, 0))
    return LTI(A, B, C, coef[0], dt)


def data_driven(model: FDIModel, t, u, y, *, kind: str = "sensor", order: int | None = None, extra: int = 2,
                max_order: int = 10, rtol: float = 1e-9) -> ResidualGenerator:
    """Parity relations identified from a fault-free record (module docstring).

    Parameters
    ----------
    model : FDIModel
        Supplies the signal names, the faults and the operating point (the record's
        deviations are taken from it); the filter itself comes from the data only. The
        generator's internal form is reported against this model, discretised at the
        record's sample time when it is continuous.
    t, u, y : array_like
        The fault-free record: times (uniform), known inputs (N×nu) and outputs (N×ny), in
        absolute values, columns in the model's order.
    kind : {'sensor', 'detection'}
        'sensor': a dedicated bank, one relation per sensor fault of the model, built from u
        and that sensor's output (isolation); 'detection': one group from all signals.
    order : int, optional
        Plant order seen by each relation (default the model's order n when it has states,
        else read from the singular values).
    extra : int
        Block rows beyond the smallest window with a relation.
    max_order, rtol
        Order selection (module docstring).

    Raises
    ------
    DesignError
        Uneven sampling, too little data, non-exciting inputs, no sensor faults for 'sensor'.
    """
    t = np.asarray(t, float)
    u = np.asarray(u, float).reshape(len(t), -1)
    y = np.asarray(y, float).reshape(len(t), -1)
    if u.shape[1] != model.nu or y.shape[1] != model.ny:
        raise DesignError(f"record has {u.shape[1]} inputs and {y.shape[1]} outputs; the model has {model.nu} and "
                          f"{model.ny}")
    if len(t) < 3:
        raise DesignError(f"the record has {len(t)} samples: far too little data")
    dt = float(np.median(np.diff(t)))
    if dt <= 0 or np.max(np.abs(np.diff(t) - dt)) > 1e-6 * dt:
        raise DesignError("the record's time steps are not uniform: resample it on a fixed step")
    if model.is_discrete and abs(model.dt - dt) > 1e-9 * dt:
        raise DesignError(f"the record's step {dt:g} s differs from the discrete model's {model.dt:g} s")
    if kind not in ("sensor", "detection"):
        raise DesignError(f"data-driven relations come as kind 'sensor' (a dedicated bank) or 'detection', got "
                          f"{kind!r}: actuator isolation from data is not available")
    du, dy = u - model.u0, y - model.y0
    dmodel = model if model.is_discrete else model.discretize(dt)
    if kind == "sensor":
        sensors = [f for f in model.faults if f.kind == "sensor"]
        if not sensors:
            raise DesignError("kind='sensor' builds one relation per sensor fault: the model has none")
        groups = [(f.name, [model.y_names.index(f.output)]) for f in sensors]
    else:
        groups = [("all", list(range(model.ny)))]
    members, info = [], {"relations": {}}
    for name, idx in groups:
        yi = dy[:, idx]
        s0 = max_order + 1
        n = order if order is not None else (model.n or None)
        if n is None:
            sv = sla.svd(past_future_lq(du, yi, s0)[2], compute_uv=False)
            n = order_from_singular_values(sv, max_order, rtol)
        s = int(np.ceil((n + 1) / len(idx))) + int(extra)
        G, M = _parity_rows(du, yi, s, n)
        if G.shape[0] == 0:
            raise DesignError(f"relation {name}: no parity relation with {s} block rows and order {n}")
        # normalise each relation by its fault-free RMS on the record, so residuals are comparable
        Q = _fir(G, -M, idx, model.ny, model.nu, s, dt)
        gen = ResidualGenerator(Q, dmodel, "data")
        r = gen.simulate(dy, du)[s:]
        rms = np.sqrt(np.mean(r * r, axis=0))
        scale = 1.0 / np.where(rms > 0, rms, 1.0)
        Q = LTI(Q.A, Q.B, scale[:, None] * Q.C, scale[:, None] * Q.D, dt)
        members.append(ResidualGenerator(Q, dmodel, "data"))
        info["relations"][name] = {"order": int(n), "block_rows": int(s), "relations": int(G.shape[0]),
                                   "outputs": [model.y_names[i] for i in idx]}
    if len(members) == 1 and kind == "detection":
        gen = members[0]
        gen.info.update(info)
        return gen
    bank = ResidualBank(members, "data", info={**info, "structure": np.eye(len(members), dtype=int).tolist(),
                                               "faults": [g[0] for g in groups]})
    return bank
