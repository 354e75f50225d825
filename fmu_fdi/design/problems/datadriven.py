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

from ...errors import DesignError
from ...generator import ResidualBank, ResidualGenerator
from ...lti import LTI
from ...model import FDIModel


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


def order_from_singular_values(sv: np.ndarray, max_order: int, rtol: float = 1e-9, atol: float = 0.0) -> int:
    """The largest gap log(σ_i/σ_{i+1}) among the values above ``max(rtol·σ_1, atol)`` (at least 1)."""
    cands = int(min(max_order, sv.size - 1, np.sum(sv > max(rtol * sv[0], atol))))
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


def realize_from_lq(L11, L31, L32, s: int, m: int, p: int, n: int | None, *, max_order: int = 10,
                    rtol: float = 1e-9, feedthrough: bool = True):
    """``(A, B, C, D, σ)`` of order n (default from σ) from the LQ blocks (MOESP; Verhaegen 1994).

    A, C from the shift invariance of Γ_s = U_1 Σ_1^(1/2); B, D by least squares from
    ``Γ⊥ L31 L11^{-1} = Γ⊥ H_s``, linear in (D, B) (Verhaegen & Dewilde 1992) — no
    simulation, so an unstable plant recorded in closed loop comes out right too.
    """
    U, sv, _ = sla.svd(L32, full_matrices=True)
    if sv[0] <= 0:
        raise DesignError("the outputs do not depend on the past data: no state is seen")
    if n is None:
        n = order_from_singular_values(sv, min(max_order, s * p - 1), rtol)
    Os = U[:, :n] * np.sqrt(sv[:n])
    C = Os[:p]
    A = np.linalg.lstsq(Os[:-p], Os[p:], rcond=None)[0]
    Uperp = U[:, n:].T
    M = sla.solve_triangular(L11.T, (Uperp @ L31).T, lower=False).T  # Γ⊥ L31 L11^{-1}
    # block i of M: Γ⊥_i D + (Σ_{k>i} Γ⊥_k C A^(k−i−1)) B
    Lk = [Uperp[:, k * p:(k + 1) * p] for k in range(s)]
    lhs, rhs = [], []
    for i in range(s):
        acc = np.zeros((Uperp.shape[0], n))
        for k in range(i + 1, s):
            acc += Lk[k] @ Os[(k - i - 1) * p:(k - i) * p]
        lhs.append(np.hstack([Lk[i], acc]) if feedthrough else acc)
        rhs.append(M[:, i * m:(i + 1) * m])
    DB = np.linalg.lstsq(np.vstack(lhs), np.vstack(rhs), rcond=None)[0]
    D, B = (DB[:p], DB[p:]) if feedthrough else (np.zeros((p, m)), DB)
    return A, B, C, D, sv


def _kernel_observer(A, B, C, D, idx, ny, nu, dt, name) -> LTI:
    """Residual ``r = y_idx − ŷ`` of the predictor ``x̂+ = A x̂ + B u + K (y_idx − C x̂ − D u)`` on [y; u].

    A stable identified plant gets K = 0, a parallel model: a sensor bias keeps its full
    size in r at steady state. An unstable one gets the K placing the predictor's poles at
    the median magnitude of the plant's eigenvalues capped at 0.9 (spread by 1 % so one
    output can place them): a stable kernel representation (Ding 2014, sec. 5.3).
    """
    from scipy.signal import place_poles

    n, p = A.shape[0], C.shape[0]
    lam = np.abs(np.linalg.eigvals(A))
    if np.all(lam < 1.0):
        K = np.zeros((n, p))
    else:
        rho = min(float(np.median(lam)), 0.9)
        try:
            K = place_poles(A.T, C.T, rho * (1.0 - 0.01 * np.arange(n))).gain_matrix.T
        except (ValueError, np.linalg.LinAlgError) as exc:
            raise DesignError(f"relation {name}: the identified plant is unstable and its predictor cannot be "
                              f"stabilised from outputs {idx} ({exc})") from None
    Ey = np.zeros((p, ny))
    Ey[np.arange(p), idx] = 1.0
    Bq = np.hstack([K @ Ey, B - K @ D])
    Dq = np.hstack([Ey, -D])
    return LTI(A - K @ C, Bq, -C, Dq, dt)


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


def _weights(r: np.ndarray, G: np.ndarray, s: int, p_group: int | None) -> np.ndarray:
    """Combination of the parity relations: with Σ the covariance of the fault-free residuals
    on the record,

    - a sensor relation (one output): the single vector ``w ∝ Σ^{-1} b`` maximising the
      steady-state bias-to-noise ratio ``(w b)² / (w Σ w)``, ``b = Γ⊥ 1_s`` the relations'
      response to a unit bias on the sensor, scaled so that ``w Σ w = 1``;
    - all relations (detection): the whitening ``Σ^{-1/2}`` (unit covariance on the record).

    Σ is factored by its eigen-decomposition; directions below ``1e-12·λ_max`` are dropped
    (relations that are exactly silent on the record carry no noise and no information).
    """
    S = np.cov(r, rowvar=False).reshape(r.shape[1], r.shape[1])
    lam, V = np.linalg.eigh((S + S.T) / 2)
    keep = lam > 1e-12 * max(lam.max(), np.finfo(float).tiny)
    lam, V = lam[keep], V[:, keep]
    if p_group == 1:
        b = G @ np.ones(s)
        c = (V.T @ b) / lam  # Σ^+ b in the eigenbasis
        w = V @ c
        norm = np.sqrt(c @ (lam * c))
        if norm <= 0:
            raise DesignError("no parity relation of the record responds to a sensor bias: increase the block rows")
        return (w / norm)[None, :]
    return (V / np.sqrt(lam)).T


def data_driven(model: FDIModel, t, u, y, *, kind: str = "sensor", form: str = "kernel", order: int | None = None,
                extra: int = 2, max_order: int = 10, rtol: float = 1e-9, atol: float = 0.0) -> ResidualGenerator:
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
    form : {'kernel', 'parity'}
        'kernel': the stable kernel representation realised from the same LQ — (A, B, C, D)
        of each relation's plant identified from the record and the residual of its
        predictor (``_kernel_observer``): infinite memory, so a sensor bias stays visible in
        steady state even when the plant is slow next to the sample time. 'parity': the
        finite-memory parity relations (window s), best for plants fast next to s samples.
    order : int, optional
        Plant order seen by each relation (default the model's order n when it has states,
        else read from the singular values).
    extra : int
        Block rows beyond the smallest window with a relation.
    max_order, rtol, atol
        Order selection (module docstring): singular values at or below ``max(rtol·σ_1, atol)`` are
        not candidates (``atol`` absolute, default 0).

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
    if form not in ("kernel", "parity"):
        raise DesignError(f"form must be 'kernel' or 'parity', got {form!r}")
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
    members, info, joint = [], {"relations": {}}, None
    for name, idx in groups:
        yi = dy[:, idx]
        s0 = max_order + 1
        n = order if order is not None else (model.n or None)
        if n is None:
            sv = sla.svd(past_future_lq(du, yi, s0)[2], compute_uv=False)
            n = order_from_singular_values(sv, max_order, rtol, atol)
        if form == "kernel":
            s = max(n + 1, s0)
            if joint is None:  # one plant from all outputs (the best-conditioned estimate of the modes);
                # each predictor then reads only its own outputs y_idx
                joint = realize_from_lq(*past_future_lq(du, dy, s), s, model.nu, model.ny, n, feedthrough=False)
            A, B, C, D, _ = joint
            Q = _kernel_observer(A, B, C[idx], D[idx], idx, model.ny, model.nu, dt, name)
            rows = len(idx)
        else:
            s = int(np.ceil((n + 1) / len(idx))) + int(extra)
            G, M = _parity_rows(du, yi, s, n)
            if G.shape[0] == 0:
                raise DesignError(f"relation {name}: no parity relation with {s} block rows and order {n}")
            Q = _fir(G, -M, idx, model.ny, model.nu, s, dt)
            rows = G.shape[0]
        r = ResidualGenerator(Q, dmodel, "data").simulate(dy, du)[s:]  # fault-free residuals of the record
        if form == "kernel":  # unit standard deviation on the record
            W = np.diag(1.0 / np.maximum(r.std(axis=0), np.finfo(float).tiny))
        else:
            W = _weights(r, G, s, len(idx) if kind == "sensor" else None)
        Q = LTI(Q.A, Q.B, W @ Q.C, W @ Q.D, dt)
        members.append(ResidualGenerator(Q, dmodel, "data"))
        info["relations"][name] = {"form": form, "order": int(n), "block_rows": int(s), "relations": int(rows),
                                   "outputs": [model.y_names[i] for i in idx]}
    if kind == "detection":  # one residual vector, evaluated as one group
        Q = members[0].Q
        return ResidualGenerator(Q, dmodel, "data", groups=[list(range(Q.p))], info=info)
    bank = ResidualBank(members, "data", info={**info, "structure": np.eye(len(members), dtype=int).tolist(),
                                               "faults": [g[0] for g in groups]})
    return bank
