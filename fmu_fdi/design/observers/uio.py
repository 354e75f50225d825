"""Full-order unknown-input observer (UIO) residual generator (Chen & Patton 1999, ch. 3).

For ``x' = A x + Bu u + E d``, ``y = C x + Du u`` with ``E = Bd`` (unknown inputs d that
must not affect the residual) the observer

    z' = F z + T Bu u + K ỹ,     x̂ = z + H ỹ,     ỹ = y − Du u,
    r  = ỹ − C x̂ = (I − C H) ỹ − C z

with

    H = E (C E)⁺,   T = I − H C,   A1 = T A,   F = A1 − K1 C,   K = K1 + F H

has the error ``e = x − x̂ = T x − z`` with ``e' = F e`` whatever u and d are, because
``T E = 0`` and ``F T = T A − K C`` (Chen & Patton, Thm 3.1); so ``r = C e`` has zero
transfer from u and d and its dynamics are ``eig(F)``, assigned through ``K1`` by pole
placement on the pair ``(A1, C)``. (In discrete time the same equations hold with the
forward shift.) It exists if and only if (Thm 3.2)

1. ``rank(C E) = rank(E)`` — every disturbance direction shows in the outputs at once,
   otherwise no H solves ``H C E = E``;
2. ``(C, A1)`` is detectable — equivalently ``rank [λI − A, E; C, 0] = n + rank E`` for
   every λ outside the stability region: the invariant zeros of the disturbance channel
   ``(A, E, C)`` are the unobservable modes of ``(C, A1)`` and must be stable.

The measurement must not see d directly (``Dd = 0``): ``y = C x + Dd d`` would put ``Dd d``
into ``r`` (the classical UIO has no direct feedthrough of d; use
:func:`~fmu_fdi.design.problems.nullspace.nullspace_design` for such models).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import default_rtol, orth_rows, right_null
from ...lti import LTI
from ...model import FDIModel
from ._observer import observer_gain, observer_generator, residual_names


def unknown_input_observer(model: FDIModel, poles=None, *, atol: float = 0.0) -> ResidualGenerator:
    """Full-order UIO residual ``r = (I − C H)(y − Du u) − C z`` decoupled from u and d.

    Parameters
    ----------
    model : FDIModel
        ``E = Bd`` are the unknown inputs to decouple; ``Dd`` must be zero. Continuous or
        discrete (designed directly in discrete time).
    poles : array_like, optional
        Eigenvalues of ``F = T A − K1 C``: as many as ``(C, T A)`` has observable modes (n
        when observable), stable, closed under conjugation. Default: distinct poles twice as
        fast as the plant's modes.
    atol : float
        Absolute rank tolerance of the observability staircase (Varga's ``atol``): singular values at or
        below ``max(rtol·||[A; C]||, atol)`` count as zero (default 0: relative only);
        also the bound of the rank test ``rank(C E) = rank(E)``.

    Returns
    -------
    ResidualGenerator
        ``Q = (F, [K, T Bu − K Du], −C, [I − C H, −(I − C H) Du])`` (one residual group).
        ``info``: ``H``, ``T``, ``K1``, ``F``, ``K``, ``poles``, ``fixed_modes`` (the stable
        invariant zeros of (A, E, C) that stay in F), ``rank_E``, ``detected_faults``.

    Raises
    ------
    DesignError
        ``Dd ≠ 0``; ``rank(C E) < rank(E)`` (names the unknown-input directions C does not
        see); ``rank(E) ≥ p`` (no residual remains); ``(C, T A)`` not detectable (names the unstable modes, i.e. the unstable
        invariant zeros of the disturbance channel); poles invalid or of the wrong count.

    References
    ----------
    J. Chen and R. J. Patton, *Robust Model-Based Fault Diagnosis for Dynamic Systems*, Kluwer 1999,
    ch. 3 (Thms 3.1-3.2).
    J. Chen, R. J. Patton and H.-Y. Zhang, Design of unknown input observers and robust fault detection
    filters, Int. J. Control 63(1), 1996.
    """
    A, Bu, C, Du = model.A, model.Bu, model.C, model.Du
    n, p = model.n, model.ny
    if model.nd and np.any(model.Dd):
        cols = [nm for nm, col in zip(model.d_names, model.Dd.T) if np.any(col)]
        raise DesignError(
            f"Dd must be zero for the unknown-input observer, but the unknown inputs {cols} act directly on the "
            f"outputs: the residual r = y − C x̂ would contain Dd d, which the observer cannot cancel (the "
            f"full-order UIO assumes y = C x + Du u). Use nullspace_design, which handles feedthrough of d")
    E0 = _range_basis(model.Bd)  # orthonormal columns spanning range(E); H is the same for any basis
    rank_E = E0.shape[1]
    CE = C @ E0
    # C E0 has the size of C; a singular value below eps-level times ||C|| is a structural zero.
    ce_tol = max(default_rtol(CE.shape) * max(float(np.linalg.norm(C, 2)), np.finfo(float).tiny), atol)
    s = sla.svdvals(CE) if rank_E else np.zeros(0)
    rank_CE = int(np.sum(s > ce_tol))
    if rank_CE < rank_E:
        raise DesignError(_rank_message(model, rank_CE, rank_E, ce_tol))
    if rank_E >= p:
        raise DesignError(
            f"no residual remains: rank(E) = {rank_E} ≥ {p} outputs, so the unknown inputs span every output "
            f"direction; the UIO can estimate the state, but I − C H = 0 and every residual decoupled from d is "
            f"identically zero (p − rank Gd = 0)")
    H = E0 @ np.linalg.pinv(CE) if rank_E else np.zeros((n, p))
    T = np.eye(n) - H @ C
    A1 = T @ A
    gain = observer_gain(
        A1, C, poles, model.dt, what="(C, A1 = T A)",
        fixed_reason=("these are invariant zeros of the unknown-input channel (A, Bd, C) "
                      "(rank [λI − A, Bd; C, 0] < n + rank Bd there), so no UIO exists "
                      "(Chen & Patton 1999, Thm 3.2, condition 2)"), atol=atol)
    K1 = gain.L
    F = A1 - K1 @ C
    K = K1 + F @ H
    M = np.eye(p) - C @ H
    Q = LTI(F, np.hstack([K, T @ Bu - K @ Du]), -C, np.hstack([M, -M @ Du]), model.dt)
    info = {"H": H.tolist(), "T": T.tolist(), "K1": K1.tolist(), "F": F.tolist(), "K": K.tolist(),
            "poles": gain.poles.tolist(), "fixed_modes": gain.fixed.tolist(), "placement": gain.method,
            "rank_E": rank_E}
    return observer_generator(model, Q, "unknown_input_observer", info, residual_names(model))


def _range_basis(E: np.ndarray) -> np.ndarray:
    """Orthonormal columns spanning ``range(E)`` (relative rank tolerance, SVD)."""
    if E.size == 0 or not np.any(E):
        return np.zeros((E.shape[0], 0))
    return orth_rows(E.T).T


def _rank_message(model: FDIModel, rank_CE: int, rank_E: int, atol: float) -> str:
    """Name the unknown-input combinations that C does not see (``C Bd v = 0``, ``Bd v ≠ 0``)."""
    Bd, C = model.Bd, model.C
    N = right_null(C @ Bd, atol=atol)  # d-combinations invisible at the output ...
    U, s, Vh = sla.svd(Bd @ N, full_matrices=False) if N.size else (None, np.zeros(0), None)
    keep = s > default_rtol(Bd.shape) * max(float(np.linalg.norm(Bd, 2)), np.finfo(float).tiny)
    dirs = (N @ Vh[keep].T).T if keep.any() else np.zeros((0, model.nd))  # ... that do move the state
    named = "; ".join(
        " + ".join(f"{c:.3g}·{nm}" for c, nm in zip(v / np.max(np.abs(v)), model.d_names) if abs(c) > 1e-9)
        for v in dirs)
    return (f"no unknown-input observer exists: rank(C E) = {rank_CE} < rank(E) = {rank_E} with E = Bd "
            f"(Chen & Patton 1999, Thm 3.2, condition 1). The unknown-input direction(s) {named or '?'} "
            f"reach the outputs only through the dynamics (C Bd v = 0), so no H satisfies H C E = E; "
            f"measure a state these inputs drive directly, or use nullspace_design")
