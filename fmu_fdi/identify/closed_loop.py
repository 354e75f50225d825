"""A plant in its own loop: the joint input-output method with the references as instruments.

A plant FMU with its controller inside (DR300, VTOL) reports the controller's output u as an
FMU output; the experiment excites the references r. The sensor noise fed back through the
controller makes u correlated with the noise, so an open-loop method from u to y is biased
(PO-MOESP's future inputs are no longer independent of the future noise). The references are
not: the map from r to z = [u; y] is an *open-loop* problem (Verhaegen 1993; Ljung 1999,
sec. 13.5, the joint input-output approach), identified consistently by PO-MOESP,

    x[k+1] = A x + B r,    u = Cu x + Du r,    y = Cy x + Dy r,

and the plant from u to y follows by inverting the first equation pair for r. A co-simulation
record reads the controller output at t_k before r_k acts (it was computed at the end of the
step before), so a channel j of u answers r one sample late: its *delay* d_j is 1 when its
first Markov parameter ``Cu_j B`` dominates its feedthrough (``‖Du_j‖ ≤ 0.1 ‖Cu_j B‖``), else 0.
With the decoupling matrix E (row j: ``Du_j`` for d_j = 0, ``Cu_j B`` for d_j = 1) and
Γ (row j: ``Cu_j``, resp. ``Cu_j A``),

    r[k] = E⁻¹ (ũ[k] − Γ x[k]),   ũ_j[k] = u_j[k + d_j],
    x[k+1] = F x + H₀ u[k] + H₁ u[k+1],   F = A − B E⁻¹ Γ,   H₀, H₁ = B E⁻¹ on the d = 0, 1 columns,

and with ξ = x − H₁ u (causal form) the plant is

    ξ[k+1] = F ξ + (F H₁ + H₀) u,    y = C' ξ,    C' = Cy − Dy E⁻¹ Γ.

Its feedthrough ``C' H₁ + Dy E⁻¹ S₀`` is that of a record whose y_k is read before u_k acts,
zero up to the noise, and dropped (as ``feedthrough=False`` does for an open-loop record). Each
delayed channel leaves one mode at z = 0 that u cannot reach (F's null space): the controllable
staircase (SLICOT TB01PD) removes it, and the controller's states, which y does not see, with it
(exactly so on noise-free data). A model input that is itself an excited FMU input (the
DR300's load torque) is its own reference: ``Cu_j = 0``, ``Du_j = e_j``.

References
----------
M. Verhaegen, Application of a subspace model identification technique to identify LTI
systems operating in closed-loop, *Automatica* 29(4), 1027–1040, 1993.
L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall 1999.
"""
from __future__ import annotations

import numpy as np

from .errors import IdentificationError
from .subspace import SubspaceModel, least_order_near_best, moesp

#: a channel's feedthrough below this fraction of its first Markov parameter is noise: delay 1
DELAY_RATIO = 0.1


def joint_models(r, u, y, dt: float, own: list, order: int | None = None, *, max_order: int = 10):
    """Candidate joint models from r to [u_own; y] (PO-MOESP, feedthrough estimated): the order
    from the singular values first, then every order (``order`` given: that one alone).

    ``own[j]`` is the column of r that model input j *is* (an excited FMU input), or None (an FMU
    output: identified)."""
    r, u, y = (np.asarray(a, float).reshape(len(a), -1) for a in (r, u, y))
    if r.shape[1] != u.shape[1]:
        raise IdentificationError(
            f"a plant in its own loop is identified from its references, one per model input: {r.shape[1]} "
            f"excited input(s) for {u.shape[1]} model input(s); excite as many FMU inputs as the model has inputs")
    z = np.hstack([u[:, [j for j, k in enumerate(own) if k is None]], y])
    if order is not None:
        return [moesp(r, z, dt, order, max_order=max_order, feedthrough=True)]
    return moesp(r, z, dt, None, max_order=max_order, feedthrough=True, candidates=True)


def open_loop(joint: SubspaceModel, own: list) -> SubspaceModel:
    """The plant from u to y recovered from a joint model (module docstring)."""
    from ..lti import LTI

    A, B, C, D = joint.A, joint.B, joint.C, joint.D
    n, q = B.shape
    m = len(own)
    free = [j for j, k in enumerate(own) if k is None]
    Cu, Du = np.zeros((m, n)), np.zeros((m, q))
    Cu[free], Du[free] = C[:len(free)], D[:len(free)]
    for j, k in enumerate(own):
        if k is not None:
            Du[j, k] = 1.0
    Cy, Dy = C[len(free):], D[len(free):]
    first = Cu @ B
    delay = np.array([k is None and np.linalg.norm(Du[j]) <= DELAY_RATIO * np.linalg.norm(first[j])
                      for j, k in enumerate(own)])
    E = np.where(delay[:, None], first, Du)
    G = np.where(delay[:, None], Cu @ A, Cu)
    s = np.linalg.svd(E, compute_uv=False)
    if not s[-1] > 1e-8 * s[0]:
        raise IdentificationError(
            f"the references do not reach the model inputs one to one (singular values of the decoupling matrix "
            f"{np.array2string(s, precision=3)}): excite the references of the controller that sets the model inputs")
    W = np.linalg.solve(E.T, np.eye(m)).T          # E⁻¹ (q × m)
    F = A - B @ W @ G
    BW = B @ W
    H1, H0 = BW * delay, BW * ~delay
    Cp = Cy - Dy @ W @ G
    # the inversion leaves a mode at 0 per delayed channel that u cannot reach, and the controller's states,
    # which y does not see: the minimal part (rank decisions at 1e-10 of ‖[F, B]‖: exact up to round-off;
    # from noisy data a controller state may stay as a near-cancelled pole/zero pair)
    Bo = F @ H1 + H0
    tol = 1e-10 * np.linalg.norm(np.hstack([F, Bo]), 2)
    red = LTI(F, Bo, Cp, np.zeros((Cp.shape[0], m)), joint.dt).minreal(tol=tol, job="M")
    return SubspaceModel(red.A, red.B, red.C, np.zeros((Cp.shape[0], m)), joint.dt, joint.singular_values,
                         red.n, joint.block_rows, info={**joint.info, "delays": delay.astype(int).tolist(),
                                                        "joint_order": joint.order})


def joint_outputs(joint: SubspaceModel, own: list) -> SubspaceModel:
    """The joint model's rows of y (the closed loop from r to y), for its validation."""
    k = sum(1 for j in own if j is None)
    return SubspaceModel(joint.A, joint.B, joint.C[k:], joint.D[k:], joint.dt, joint.singular_values, joint.order,
                         joint.block_rows, dict(joint.info))


def identify_closed_loop(r, u, y, r_val, u_val, y_val, dt: float, own: list, order: int | None = None, *,
                         max_order: int = 10):
    """``(plant, joint)``: the plant model and the joint model it came from.

    The joint order is the singular values' or, among the candidates within 3 of it whose plant
    has a continuous model, the smallest whose joint simulation error on the validation run
    (r_val → [u_val; y_val], initial state fitted; Σ_j ||e_j||²/||z_j − z̄_j||² / (m + p)) is
    within 2 % of the best plus 1e-4 (Ljung 1999, sec. 16.4, cross-validation). Noise-free data (the
    singular values past the gap at round-off, over 1e6 below it) keep the gap order: it is exact."""
    from .validation import simulated

    cands = joint_models(r, u, y, dt, own, order, max_order=max_order)
    free = [j for j, k in enumerate(own) if k is None]
    z_val = np.hstack([np.asarray(u_val, float)[:, free], np.asarray(y_val, float)])
    gap = cands[0]
    sv = gap.singular_values
    exact = gap.order < len(sv) and sv[gap.order - 1] > 1e6 * sv[gap.order]
    if exact:
        cands = [gap]
    scored = []
    for joint in cands:
        if joint is not gap and abs(joint.order - gap.order) > 3:
            continue
        try:
            plant = open_loop(joint, own)
            plant.to_continuous()
        except IdentificationError:
            continue
        z_hat = simulated(joint, np.asarray(r_val, float), z_val)
        den = np.maximum(np.sum((z_val - z_val.mean(0)) ** 2, axis=0), np.finfo(float).tiny)
        err = float(np.mean(np.sum((z_val - z_hat) ** 2, axis=0) / den))
        if np.isfinite(err):
            scored.append((err, joint.order, (plant, joint)))
    if not scored:  # the gap order's own refusal says why
        plant = open_loop(gap, own)
        plant.to_continuous()
        return plant, gap
    return least_order_near_best(scored)
