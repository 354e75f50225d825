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

Model sets over the operating envelope (:class:`ModelSet`, :func:`model_set_from_fmu`):
one linear model per operating point of a nonlinear plant FMU (linearised or identified by
:func:`fmu_fdi.identify.model_from_fmu` at each point), with the *scheduling signals* named
— measured inputs or outputs whose operating values place each member in the envelope. A
model set is the input of a scheduled diagnoser (:mod:`fmu_fdi.schedule`). File format
``fmu-fdi-model-set/1`` (JSON, docs/design-file.md, "Scheduled designs")::

    {"format": "fmu-fdi-model-set/1", "name": "...", "schedule": ["Q1", "Q2"],
     "provenance": {...},                       # the grid asked for, FMU, method
     "members": [{"point": {"Q1": .., "Q2": ..}, # the operating values that were asked for
                  "model": {fmu-fdi-model/1}},  # with its operating point and provenance
                 ...]}

A member's place in the envelope is the operating value of each scheduling signal in its
model (``u0`` or ``y0``), which for an input is the value asked for and for an output the
steady state the plant settled to.
"""
from __future__ import annotations

from pathlib import Path
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


# ---------------------------------------------------------------- model sets over the envelope
MODEL_SET_FORMAT = "fmu-fdi-model-set/1"


def parse_grid(item: str) -> tuple[str, np.ndarray]:
    """``"Q1=10:30:5"`` → ``("Q1", [10, 15, 20, 25, 30])``: K ≥ 1 equally spaced values from LO to HI."""
    key, sep, rng = item.partition("=")
    parts = rng.split(":")
    try:
        if not sep or not key.strip() or len(parts) != 3:
            raise ValueError
        lo, hi, k = float(parts[0]), float(parts[1]), int(parts[2])
        if k < 1 or not (np.isfinite(lo) and np.isfinite(hi)) or (k == 1 and lo != hi) or (k > 1 and lo == hi):
            raise ValueError
    except ValueError:
        raise ModelError(f"--at-grid takes NAME=LO:HI:K with finite LO != HI and an integer K >= 2 (or LO = HI "
                         f"with K = 1), got {item!r}") from None
    return key.strip(), np.linspace(lo, hi, k)


def grid_points(grids: Sequence[tuple[str, np.ndarray]], mode: str = "product") -> list[dict]:
    """Operating points of a grid: the tensor ``product`` of the axes (last axis fastest), or a
    ``path`` that walks all axes together (all of the same length K: point k takes value k of each)."""
    names = [g[0] for g in grids]
    if len(set(names)) != len(names):
        raise ModelError(f"a grid names a variable twice: {names}")
    if not grids:
        raise ModelError("a grid needs at least one NAME=LO:HI:K")
    if mode == "product":
        mesh = np.meshgrid(*[g[1] for g in grids], indexing="ij")
        return [dict(zip(names, map(float, row))) for row in np.column_stack([m.ravel() for m in mesh])]
    if mode == "path":
        sizes = {len(g[1]) for g in grids}
        if len(sizes) != 1:
            raise ModelError(f"a path grid needs the same K on every axis, got {[len(g[1]) for g in grids]}")
        return [dict(zip(names, map(float, vals))) for vals in zip(*[g[1] for g in grids])]
    raise ModelError(f"grid mode must be 'product' or 'path', got {mode!r}")


class ModelSet:
    """Linear models of one plant at several operating points (module docstring).

    Parameters
    ----------
    members : list of FDIModel
        Same u, y, d and fault names (the same residual structure is designed for each);
        orders may differ.
    schedule : list of str
        Scheduling signals: names among the members' u or y.
    points : list of dict, optional
        The operating values asked for per member (provenance; default: the schedule values).
    """

    def __init__(self, members: Sequence[FDIModel], schedule: Sequence[str], *, points=None, name: str = "plant",
                 provenance: dict | None = None):
        members = list(members)
        if not members:
            raise ModelError("a model set needs at least one member")
        first = members[0]
        for k, m in enumerate(members[1:], 2):
            for what in ("u_names", "y_names", "d_names", "fault_names"):
                if list(getattr(m, what)) != list(getattr(first, what)):
                    raise ModelError(f"model set member {k} ('{m.name}') has {what[:-6]} {list(getattr(m, what))}, "
                                     f"member 1 ('{first.name}') has {list(getattr(first, what))}: every member "
                                     f"needs the same signals and faults")
            if abs(m.dt - first.dt) > 1e-12 * max(first.dt, 1.0):
                raise ModelError(f"model set member {k} has dt = {m.dt}, member 1 has {first.dt}")
        schedule = [str(s) for s in schedule]
        if not schedule or len(set(schedule)) != len(schedule):
            raise ModelError(f"name one or more distinct scheduling signals, got {schedule}")
        bad = [s for s in schedule if s not in first.u_names and s not in first.y_names]
        if bad:
            raise ModelError(f"scheduling signals {bad} are not measured: a scheduling signal must be a model input "
                             f"u {first.u_names} or output y {first.y_names}")
        self.members, self.schedule, self.name = members, schedule, name
        self.provenance = dict(provenance or {})
        P = self.points
        for i in range(len(members)):
            for j in range(i):
                if np.array_equal(P[i], P[j]):
                    raise ModelError(f"model set members {j + 1} and {i + 1} sit at the same scheduling point "
                                     f"{dict(zip(schedule, P[i].tolist()))}: the schedule could not tell them apart")
        req = [dict(p) for p in points] if points is not None else [dict(zip(schedule, r.tolist())) for r in P]
        if len(req) != len(members):
            raise ModelError(f"{len(req)} requested points for {len(members)} members")
        self.requested = req

    def __len__(self) -> int:
        return len(self.members)

    @property
    def points(self) -> np.ndarray:
        """K × S: member k's operating value of each scheduling signal (its u0 or y0 entry)."""
        def value(m, s):
            return float(m.u0[m.u_names.index(s)]) if s in m.u_names else float(m.y0[m.y_names.index(s)])
        return np.array([[value(m, s) for s in self.schedule] for m in self.members], float).reshape(len(self), -1)

    def to_dict(self) -> dict:
        from .designfile import _clean

        return _clean({"format": MODEL_SET_FORMAT, "name": self.name, "schedule": list(self.schedule),
                       "provenance": dict(self.provenance),
                       "members": [{"point": p, "model": m.to_dict()} for p, m in zip(self.requested, self.members)]})

    @classmethod
    def from_dict(cls, d, source: str = "model set") -> "ModelSet":
        from ._schema import array, check_format, check_keys, names, table, text

        check_format(d, MODEL_SET_FORMAT, source, ModelError)
        check_keys(d, ("format", "schedule", "members"), ("format", "name", "schedule", "members", "provenance"),
                   source, ModelError)
        schedule = names(d["schedule"], f"{source}: schedule", ModelError)
        members, points = [], []
        for k, item in enumerate(array(d["members"], f"{source}: members", ModelError), 1):
            where = f"{source}: members[{k}]"
            check_keys(table(item, where, ModelError), ("model",), ("point", "model"), where, ModelError)
            members.append(FDIModel.from_dict(item["model"], source=f"{where}.model"))
            pt = table(item.get("point", {}), f"{where}.point", ModelError)
            points.append(pt)
        name = text(d.get("name", "plant"), f"{source}: name", ModelError)
        prov = table(d.get("provenance", {}), f"{source}: provenance", ModelError)
        return cls(members, schedule, points=points, name=name, provenance=prov)

    def to_file(self, path) -> Path:
        """Write the set as JSON (``.json``); floats round-trip exactly; written atomically."""
        import json

        from .outpath import check_output_path, write_atomically

        path = check_output_path(path, (".json",), "model-set file", error=ModelError)
        body = json.dumps(self.to_dict(), indent=1, allow_nan=False)
        return write_atomically(path, lambda part: part.write_text(body, encoding="utf-8"))

    @classmethod
    def from_file(cls, path) -> "ModelSet":
        from ._schema import parse, read_text

        body = read_text(path, "model-set file", ModelError)
        return cls.from_dict(parse(body, "json", str(path), ModelError), source=str(path))


def is_model_set_file(path) -> bool:
    """Whether ``path`` is a JSON file whose ``format`` is a model set (cheap: reads the text once)."""
    import json

    p = Path(path)
    if p.suffix.lower() != ".json" or not p.is_file():
        return False
    try:
        return json.loads(p.read_text(encoding="utf-8")).get("format") == MODEL_SET_FORMAT
    except (OSError, ValueError, AttributeError):
        return False


def model_set_from_fmu(path, inputs=None, outputs=None, disturbances=(), *, at: Sequence[dict],
                       schedule: Sequence[str] | None = None, name: str | None = None, progress=None,
                       **options) -> ModelSet:
    """Linearise or identify a plant FMU at each operating point of ``at`` (a list of dicts).

    Each point is passed as ``at`` to :func:`fmu_fdi.identify.model_from_fmu` with the other
    options (``method``, ``sensor_faults``, excitation, ...). Values common to every point
    (e.g. ``{"noise_enable": False}``) go in ``options["fixed"]``. ``schedule`` defaults to
    the variables the points vary that are model inputs or outputs. ``progress(k, K, point,
    model)`` is called after each member. Each member's provenance adds ``member`` (1-based),
    ``set_size`` and ``requested_point``.
    """
    from .identify import model_from_fmu

    points = [dict(p) for p in at]
    if not points:
        raise ModelError("at=[...] holds no operating point")
    fixed = dict(options.pop("fixed", None) or {})
    keys = list(dict.fromkeys(k for p in points for k in p))  # every name any point sets, in order
    missing = [(i + 1, [k for k in keys if k not in p]) for i, p in enumerate(points) if set(p) != set(keys)]
    if missing:
        raise ModelError(f"every operating point must set the same variables {keys}; point {missing[0][0]} lacks "
                         f"{missing[0][1]}")
    varied = [k for k in keys if any(p[k] != points[0][k] for p in points)] or keys
    members = []
    for k, pt in enumerate(points, 1):
        model = model_from_fmu(path, inputs, outputs, disturbances, at={**fixed, **pt}, **options)
        model.name = f"{model.name}_{k}"
        model.provenance.update({"member": k, "set_size": len(points),
                                 "requested_point": [f"{n}={v!r}" for n, v in pt.items()]})
        members.append(model)
        if progress is not None:
            progress(k, len(points), pt, model)
    if schedule is None:
        m0 = members[0]
        schedule = [v for v in varied if v in m0.u_names or v in m0.y_names]
        if not schedule:
            raise ModelError(f"the grid varies {varied}, none of which is a model input {m0.u_names} or output "
                             f"{m0.y_names}: name the measured scheduling signal(s) (schedule=[...] / --schedule-on)")
    prov = {"fmu": Path(path).name, "points": len(points), "varied": varied,
            "fixed": [f"{n}={v!r}" for n, v in fixed.items()], "method": members[0].provenance.get("method", "")}
    return ModelSet(members, schedule, points=points, name=name or members[0].name.rsplit("_", 1)[0],
                    provenance=prov)


def envelope_cli(args, excitation, fixed: dict) -> int:
    """``fmu-fdi model PLANT.fmu --at-grid ...``: write the model set, one line per member."""
    from .identify.fmu_model import summary
    from .model import minreal_option

    tol = minreal_option(args.minimal, args.minreal_tol)
    grids = [parse_grid(item) for item in args.at_grid]
    points = grid_points(grids, args.grid_mode)
    clash = sorted(set(fixed) & {g[0] for g in grids})
    if clash:
        raise ModelError(f"{clash} are given both in --at and --at-grid")
    single = [opt for opt, val in (("--record", args.record), ("--plot", args.plot)) if val]
    if single:
        raise ModelError(f"{' and '.join(single)} write one file for one operating point; with --at-grid run "
                         f"'fmu-fdi model' at that point (--at) for it")

    def progress(k, K, point, model):
        where = ", ".join(f"{n}={v:g}" for n, v in point.items())
        print(f"member {k}/{K} at {where}: {summary(model)}", flush=True)

    from .outpath import check_output_path

    check_output_path(args.output, (".json",), "model-set file", error=ModelError)
    mset = model_set_from_fmu(args.plant, args.inputs, args.outputs, args.disturbances or (), at=points,
                              schedule=args.schedule_on, fixed=fixed, progress=progress, method=args.method,
                              trim=args.trim, sensor_faults=args.sensor_faults, actuator_faults=args.actuator_faults,
                              ts=args.ts, excite=args.excite, excitation=excitation, order=args.order,
                              min_fit=args.min_fit, noise=args.noise)
    if tol is not None:
        mset.members = [m.minreal(tol) for m in mset.members]
    print(f"wrote {mset.to_file(args.output)}: {len(mset)} members scheduled on {mset.schedule}")
    return 0
