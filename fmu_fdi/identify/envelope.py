"""The door from a plant FMU to a model: one linear model at an operating point, or a model
set over the operating envelope (``fmu-fdi model``, ``--at-grid``).

:func:`model_from_fmu` linearises or identifies the FMU (:mod:`.fmu_model`) at one point (``at``
a dict) or at each of several (``at`` a list: a :class:`~fmu_fdi.modelset.ModelSet`,
:func:`model_set_from_fmu`). Identification stands above the model: :mod:`fmu_fdi.model` and
:mod:`fmu_fdi.modelset` hold the data and never import this package (docs/layers in README).
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from ..errors import ModelError
from ..model import minreal_option
from ..modelset import ModelSet, grid_points, parse_grid
from ..outpath import check_output_path
from . import fmu_model
from .fmu_model import summary


def model_from_fmu(path, inputs=None, outputs=None, disturbances=(), *, at=None, method: str = "auto", **options):
    """A linear model of a plant FMU: linearised (model exchange) or identified (co-simulation).

    One operating point (``at`` a dict or None) goes to
    :func:`fmu_fdi.identify.fmu_model.model_from_fmu`, which documents ``at``,
    ``method`` and the further options (``trim``, ``sensor_faults``, ``actuator_faults``,
    ``ts``, ``excite``, ``excitation``, ``parameters``, ``order``, ``noise`` —
    ``"innovation"`` or ``"measurement"`` adds unit white noise inputs ``w_<output>``
    learned from the data, docs/plant-fmu.md —, ...). The model carries the operating point
    and a ``provenance`` table (FMU, GUID, method, fit, noise model).
    ``minimal``/``minreal_tol`` reduce the linear model as in :meth:`FDIModel.from_matrices <fmu_fdi.model.FDIModel.from_matrices>`
    (checked before the FMU is touched). ``at`` a list of operating points gives a
    :class:`~fmu_fdi.modelset.ModelSet`, one member per point (``schedule=[...]`` names
    its scheduling signals; :func:`model_set_from_fmu`).
    """
    tol = minreal_option(options.pop("minimal", None), options.pop("minreal_tol", None))
    if isinstance(at, (list, tuple)):  # several operating points: a ModelSet
        mset = model_set_from_fmu(path, inputs, outputs, disturbances, at=at, method=method, **options)
        mset.members = [m if tol is None else m.minreal(tol) for m in mset.members]
        return mset
    model = fmu_model.model_from_fmu(path, inputs, outputs, disturbances, at=at, method=method, **options)
    return model if tol is None else model.minreal(tol)


def model_set_from_fmu(path, inputs=None, outputs=None, disturbances=(), *, at: Sequence[dict],
                       schedule: Sequence[str] | None = None, name: str | None = None, progress=None,
                       **options) -> ModelSet:
    """Linearise or identify a plant FMU at each operating point of ``at`` (a list of dicts).

    Each point is passed as ``at`` to :func:`model_from_fmu` with the other
    options (``method``, ``sensor_faults``, excitation, ...). Values common to every point
    (e.g. ``{"noise_enable": False}``) go in ``options["fixed"]``. ``schedule`` defaults to
    the variables the points vary that are model inputs or outputs. ``progress(k, K, point,
    model)`` is called after each member. Each member's provenance adds ``member`` (1-based),
    ``set_size`` and ``requested_point``. Members with and without a noise model (the default
    ``noise='auto'`` deciding differently per point) are refused.
    """
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
    noisy = [k for k, m in enumerate(members, 1) if m.w_names]
    if noisy and len(noisy) < len(members):
        quiet = [k for k in range(1, len(members) + 1) if k not in noisy]
        raise ModelError(f"members {noisy} were identified with a noise model and members {quiet} without one: their "
                         f"designs would differ in kind, not only in operating point; choose one for all "
                         f"(noise='innovation' or None / --noise innovation or none)")
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

    check_output_path(args.output, (".json",), "model-set file", error=ModelError)
    mset = model_set_from_fmu(args.plant, args.inputs, args.outputs, args.disturbances or (), at=points,
                              schedule=args.schedule_on, fixed=fixed, progress=progress, method=args.method,
                              trim=args.trim, sensor_faults=args.sensor_faults, actuator_faults=args.actuator_faults,
                              ts=args.ts, excite=args.excite, excitation=excitation, order=args.order,
                              min_fit=args.min_fit,
                              noise=None if args.noise == "none" else args.noise)
    if tol is not None:
        mset.members = [m.minreal(tol) for m in mset.members]
    from .plant_stability import check_plant_models

    check_plant_models(args.plant, mset.members, getattr(args, "allow_unstable", False))
    print(f"wrote {mset.to_file(args.output)}: {len(mset)} members scheduled on {mset.schedule}")
    return 0
