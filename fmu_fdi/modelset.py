"""Model sets: the interconnections of FDI models (re-exported from :mod:`fmu_fdi.model`, the
model's own algebra) and model sets over the operating envelope.

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

:func:`fmu_fdi.robustness.robustness` applies one residual filter to a list of models (e.g.
the plant at several operating points) and reports the worst decoupling and fault-sensitivity
figures (Varga 2017, sec. 5.4, the robustness of a design against model variations).

Model sets over the operating envelope (:class:`ModelSet`;
:func:`fmu_fdi.identify.model_set_from_fmu` makes one from a plant FMU):
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
from .model import FDIModel, feedback, parallel, series  # noqa: F401  (the model's algebra, model.py)


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
        from .outpath import _clean

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
