"""Model-set tools: interconnections of FDI models and robustness of one filter over many.

Interconnections (state-space, no inverses beyond the algebraic loop ``I + D_K D_u``):

- :func:`series` — a pre-system ``P`` (e.g. actuator dynamics) between the command and the
  plant input: ``u_plant = P u``. Disturbances, noise and faults keep entering the plant
  where they did (an actuator fault acts on the actuator's *output*).
- :func:`feedback` — the loop ``u = r − K y`` closed with a static gain or an LTI controller
  K; the new known inputs are the references r, the outputs stay y.
- :func:`parallel` — two models driven by the same known inputs, outputs stacked.

Faults are carried over as component faults with their columns in the new model (their
names, and their kind in the description), so every fault keeps acting where it acted.
An interconnection is often not minimal (e.g. the same actuator dynamics twice, or a
controller state the outputs do not see): ``minimal=True`` or ``minreal_tol=TOL`` reduce
the result to a minimal realisation (:func:`fmu_fdi.model.minimal_realisation`).

:func:`robustness` applies one residual filter to a list of models (e.g. the plant at
several operating points) and reports the worst decoupling and fault-sensitivity figures
(Varga 2017, sec. 5.4, the robustness of a design against model variations).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .errors import ModelError
from .faults import FaultSpec, component_fault
from .lti import LTI
from .model import FDIModel


def _as_lti(K, dt: float, shape: tuple[int, int], what: str) -> LTI:
    if isinstance(K, LTI):
        sys = K
    elif hasattr(K, "A") and hasattr(K, "B"):
        sys = LTI.from_control(K)
    else:
        sys = LTI.static(np.atleast_2d(np.asarray(K, float)), dt)
    if sys.n and abs(sys.dt - dt) > 1e-12 * max(1.0, dt):
        raise ModelError(f"{what} has sample time {sys.dt} but the model has {dt}")
    if (sys.p, sys.m) != shape:
        raise ModelError(f"{what} must be {shape[0]}x{shape[1]} (outputs x inputs), got {sys.p}x{sys.m}")
    return LTI(sys.A, sys.B, sys.C, sys.D, dt)


def _carried_faults(model: FDIModel, Bf: np.ndarray, Df: np.ndarray) -> list[FaultSpec]:
    out = []
    for f in model.faults:
        desc = f"{f.kind} fault carried over from model '{model.name}'" + (f": {f.description}" if f.description else "")
        out.append(component_fault(f.name, Bf[:, f.columns], Df[:, f.columns], description=desc))
    return out


def series(model: FDIModel, pre, *, name: str | None = None, minimal: bool | None = None,
           minreal_tol: float | None = None) -> FDIModel:
    """The model driven through ``pre``: ``u_plant = P(λ) u`` (P square, m×m).

    States ``[x_P; x]``: ``A = [A_P 0; Bu C_P  A]``, ``Bu' = [B_P; Bu D_P]``,
    ``C' = [Du C_P  C]``, ``Du' = Du D_P``; d, w and faults enter ``[0; B]``.
    """
    m = model.nu
    P = _as_lti(pre, model.dt, (m, m), "pre-system")
    nP, n = P.n, model.n
    A = np.block([[P.A, np.zeros((nP, n))], [model.Bu @ P.C, model.A]])
    Bu = np.vstack([P.B, model.Bu @ P.D])
    C = np.hstack([model.Du @ P.C, model.C])
    Du = model.Du @ P.D
    z = lambda B: np.vstack([np.zeros((nP, B.shape[1])), B])  # noqa: E731
    return FDIModel(A, Bu, C, Du, Bd=z(model.Bd), Dd=model.Dd, Bw=z(model.Bw), Dw=model.Dw,
                    faults=_carried_faults(model, z(model.Bf), model.Df), dt=model.dt, u_names=model.u_names,
                    y_names=model.y_names, d_names=model.d_names, w_names=model.w_names, units=model.units,
                    name=name or f"{model.name}_series", description=f"{model.name} with a {nP}-state pre-system "
                    f"in series", minimal=minimal, minreal_tol=minreal_tol)


def feedback(model: FDIModel, K, *, name: str | None = None, r_names: Sequence[str] | None = None,
             minimal: bool | None = None, minreal_tol: float | None = None) -> FDIModel:
    """The closed loop ``u = r − K(λ) y`` (K static m×p gain or LTI controller).

    With ``E = (I + D_K Du)^{-1}`` (the algebraic loop must be well posed) and the other
    inputs ``v = [d; w; f]``: ``u = E (r − C_K x_K − D_K C x − D_K D_v v)``, then the plant
    and controller state equations. New known inputs: r (default names ``r_<u>``).
    """
    m, p = model.nu, model.ny
    Kc = _as_lti(K, model.dt, (m, p), "controller")
    M = np.eye(m) + Kc.D @ model.Du
    if np.linalg.cond(M) > 1e12:
        raise ModelError(f"the feedback loop is not well posed: I + D_K Du is singular (condition "
                         f"{np.linalg.cond(M):.3g})")
    E = np.linalg.solve(M, np.eye(m))
    nk = Kc.n
    Bv = np.hstack([model.Bd, model.Bw, model.Bf])
    Dv = np.hstack([model.Dd, model.Dw, model.Df])
    # u = Ur r + Ux x + Uk xk + Uv v
    Ur, Ux, Uk, Uv = E, -E @ Kc.D @ model.C, -E @ Kc.C, -E @ Kc.D @ Dv
    # y = C x + Du u + Dv v
    Yr, Yx, Yk, Yv = model.Du @ Ur, model.C + model.Du @ Ux, model.Du @ Uk, Dv + model.Du @ Uv
    A = np.block([[model.A + model.Bu @ Ux, model.Bu @ Uk], [Kc.B @ Yx, Kc.A + Kc.B @ Yk]])
    Br = np.vstack([model.Bu @ Ur, Kc.B @ Yr])
    Bvc = np.vstack([Bv + model.Bu @ Uv, Kc.B @ Yv])
    C = np.hstack([Yx, Yk])
    nd, nw = model.nd, model.nw
    sl_d, sl_w, sl_f = slice(0, nd), slice(nd, nd + nw), slice(nd + nw, None)
    r_names = list(r_names or [f"r_{u}" for u in model.u_names])
    return FDIModel(A, Br, C, Yr, Bd=Bvc[:, sl_d], Dd=Yv[:, sl_d], Bw=Bvc[:, sl_w], Dw=Yv[:, sl_w],
                    faults=_carried_faults(model, Bvc[:, sl_f], Yv[:, sl_f]), dt=model.dt, u_names=r_names,
                    y_names=model.y_names, d_names=model.d_names, w_names=model.w_names,
                    units={k: v for k, v in model.units.items() if k in set(model.y_names) | set(model.d_names)
                           | set(model.w_names)},
                    name=name or f"{model.name}_loop", description=f"{model.name} in closed loop with a "
                    f"{nk}-state controller (u = r - K y)", minimal=minimal, minreal_tol=minreal_tol)


def parallel(first: FDIModel, second: FDIModel, *, name: str | None = None, minimal: bool | None = None,
             minreal_tol: float | None = None) -> FDIModel:
    """Two models driven by the same known inputs, outputs stacked ``[y1; y2]``;
    their d, w and faults are kept apart (names must differ)."""
    if first.nu != second.nu or abs(first.dt - second.dt) > 1e-12:
        raise ModelError("parallel models need the same known inputs and sample time")
    n1, n2 = first.n, second.n
    A = np.block([[first.A, np.zeros((n1, n2))], [np.zeros((n2, n1)), second.A]])
    Bu = np.vstack([first.Bu, second.Bu])
    C = np.block([[first.C, np.zeros((first.ny, n2))], [np.zeros((second.ny, n1)), second.C]])
    Du = np.vstack([first.Du, second.Du])

    def diag(B1, B2):
        return np.block([[B1, np.zeros((B1.shape[0], B2.shape[1]))], [np.zeros((B2.shape[0], B1.shape[1])), B2]])

    Bf, Df = diag(first.Bf, second.Bf), diag(first.Df, second.Df)
    faults = (_carried_faults(first, Bf[:, :first.nf], Df[:, :first.nf])
              + _carried_faults(second, Bf[:, first.nf:], Df[:, first.nf:]))
    return FDIModel(A, Bu, C, Du, Bd=diag(first.Bd, second.Bd), Dd=diag(first.Dd, second.Dd),
                    Bw=diag(first.Bw, second.Bw), Dw=diag(first.Dw, second.Dw), faults=faults, dt=first.dt,
                    u_names=first.u_names, y_names=list(first.y_names) + list(second.y_names),
                    d_names=list(first.d_names) + list(second.d_names),
                    w_names=list(first.w_names) + list(second.w_names),
                    name=name or f"{first.name}_{second.name}", minimal=minimal, minreal_tol=minreal_tol)


def robustness(gen, models: Sequence[FDIModel], *, structure=None, faults=None) -> dict:
    """Apply one filter to every model of a set; report per-model and worst figures.

    For each model (same signals as the design model): the relative decoupling of u and d
    and of the faults with ``S = 0``, and the smallest relative fault gain of the required
    faults (:func:`~fmu_fdi.design.postconditions.check_generator` with ``raise_error=False``),
    plus the H∞− index ``min_j ||Rf_j||∞``.
    """
    from .analysis import hinf_minus
    from .design.postconditions import check_generator
    from .generator import ResidualGenerator

    S = structure if structure is not None else gen.info.get("structure")
    names = faults if faults is not None else gen.info.get("faults")
    rows = []
    for mdl in models:
        if (mdl.ny, mdl.nu, mdl.fault_names) != (gen.model.ny, gen.model.nu, gen.model.fault_names):
            raise ModelError(f"model '{mdl.name}' has other signals than the design model '{gen.model.name}'")
        g = ResidualGenerator(gen.Q, mdl, gen.method, gen.residual_names, gen.groups)
        fig = check_generator(g, structure=S, faults=names, raise_error=False)
        rows.append({"model": mdl.name, "decoupling": fig.get("decoupling", 0.0),
                     "structure_leak": fig.get("structure_leak", 0.0),
                     "fault_visibility": fig.get("fault_visibility", float("inf")),
                     "hinf_minus": hinf_minus(g) if mdl.faults else 0.0})
    return {"models": rows,
            "worst_decoupling": max(r["decoupling"] for r in rows),
            "worst_structure_leak": max(r["structure_leak"] for r in rows),
            "worst_fault_visibility": min(r["fault_visibility"] for r in rows),
            "worst_hinf_minus": min(r["hinf_minus"] for r in rows)}
