"""Scheduled diagnosers: one design per member of a model set, switched by a measured signal.

A linear diagnoser is valid near the operating point it was designed at (Varga 2017, ch. 1;
Chen & Patton 1999, ch. 1: "several models" as the remedy for a plant that moves). Given a
:class:`~fmu_fdi.modelset.ModelSet` — the plant linearised or identified at K operating
points, with measured scheduling signals — :meth:`ScheduledDiagnoser.design` designs each
member with the same method and options (same residual structure: residual i means the same
everywhere), each with its own operating point and thresholds, and schedules them by the
nearest-member rule with hysteresis of :mod:`fmu_fdi.runtime.schedule` (docs/semantics.md §12).
Every member filters every sample, so a switch is bumpless.

The design file (format ``fmu-fdi-scheduled-design/1``, docs/design-file.md) embeds the K
member designs (each an ordinary ``fmu-fdi-design/1``) and the schedule.
"""
from __future__ import annotations

import copy
import time
from pathlib import Path

import numpy as np

from .designfile import DesignFileError, _clean, checked_design, parse_design_file, validate_design
from .diagnoser import Diagnoser, _version
from .errors import DesignError
from .runtime.design_check import DesignCheckError
from .runtime.schedule import (SCHEDULED_FORMAT, ScheduledRuntime, check_scheduled_design, default_scale,
                               is_scheduled)

DEFAULT_HYSTERESIS = 0.2


def validate_scheduled_design(d, source: str = "scheduled design") -> dict:
    """Check a scheduled design dict; returns it or raises DesignFileError (one line). The run-time
    rules are :func:`~fmu_fdi.runtime.schedule.check_scheduled_design` (the FMU applies the same);
    each member also passes :func:`~fmu_fdi.designfile.validate_design` (its embedded model)."""
    try:
        check_scheduled_design(d, source)
    except DesignCheckError as exc:
        raise DesignFileError(str(exc)) from None
    for k, m in enumerate(d["members"], 1):
        validate_design(m, f"{source}: members[{k}]")
    return d


class ScheduledDiagnoser(Diagnoser):
    """K member diagnosers and the schedule that picks the one shown (module docstring).

    Parameters
    ----------
    members : list of Diagnoser
        One per operating point, same signals, faults and residual structure.
    schedule : list of str
        Scheduling signals (inputs or outputs of the design).
    points : array K × S
        Member k's operating value of each scheduling signal.
    scale : list of float, optional
        Unit of distance per scheduling signal (default: the grid step,
        :func:`~fmu_fdi.runtime.schedule.default_scale`).
    hysteresis : float
        η in those units: the active member a gives way to the nearest b only if d_b + η < d_a.
    warm_start : bool
        Start every member's filter at its steady state for the first sample (``schedule.warm``,
        default on; LTI members only): without it a member designed far from where the plant
        starts carries a start-up transient of that size for as long as its slowest pole lasts.
    """

    def __init__(self, members, schedule, points, *, scale=None, hysteresis: float = DEFAULT_HYSTERESIS,
                 warm_start: bool = True, name: str | None = None, report: dict | None = None,
                 model_set: dict | None = None):
        members = list(members)
        if not members:
            raise DesignError("a scheduled diagnoser needs at least one member")
        pts = np.asarray(points, float).reshape(len(members), -1).tolist()
        first = members[0].design
        d = {"format": SCHEDULED_FORMAT, "name": name or f"{first['name']}_scheduled",
             "created_by": f"fmu-fdi {_version()}", "signals": copy.deepcopy(first["signals"]),
             "faults": copy.deepcopy(first["faults"]),
             "schedule": {"rule": "nearest", "signals": list(schedule), "points": pts,
                          "scale": list(map(float, scale)) if scale is not None else default_scale(pts),
                          "hysteresis": float(hysteresis)},
             "members": [copy.deepcopy(m.design) for m in members]}
        if warm_start:
            d["schedule"]["warm"] = [warm_gain(m.design, k) for k, m in enumerate(members, 1)]
        if first.get("units"):
            d["units"] = dict(first["units"])
        if report:
            d["report"] = report
        if model_set:
            d["model_set"] = model_set
        self._adopt(validate_scheduled_design(_clean(d), "scheduled diagnoser"), members)

    def _adopt(self, design: dict, members) -> None:
        self.design = design
        self.members = members
        self.generator = self.continuous = None  # per member: members[k].generator
        self.runtime = ScheduledRuntime(design, checked=True)
        self.Ts = self.runtime.Ts

    # ------------------------------------------------------------- design
    @classmethod
    def design(cls, model_set, method, *, Ts: float | None = None, evaluation=None, thresholds=None,
               decision: dict | None = None, hysteresis: float = DEFAULT_HYSTERESIS, scale=None,
               warm_start: bool = True,
               name: str | None = None, valid_range: dict | None = None, **method_options) -> "ScheduledDiagnoser":
        """One design per member: ``gen = method(member, **method_options)``, then
        ``Diagnoser(gen, Ts=Ts, evaluation=..., thresholds=..., decision=...)``.

        ``thresholds`` may be a callable ``thresholds(gen, evaluation)`` (e.g. a threshold
        designer such as :func:`fmu_fdi.evaluation.fault_size_thresholds` wrapped), so every
        member gets thresholds of its own; the seconds each member's design took are kept in
        ``design["report"]["design_seconds"]``.
        """
        if thresholds is None:
            raise DesignError("thresholds are required (a number, spec, or a callable thresholds(gen, evaluation))")
        members, seconds = [], []
        for k, model in enumerate(model_set.members, 1):
            t0 = time.perf_counter()
            try:
                gen = method(model, **method_options)
                if getattr(gen, "dt", 0.0) == 0.0 and Ts is not None:
                    gen = gen.to_discrete(Ts)
                thr = thresholds(gen, evaluation) if callable(thresholds) else thresholds
                members.append(Diagnoser(gen, evaluation=evaluation, thresholds=thr, decision=decision,
                                         name=f"{model.name}", valid_range=valid_range))
            except (DesignError, ValueError) as exc:
                raise DesignError(f"member {k} ('{model.name}'): {exc}") from None
            seconds.append(time.perf_counter() - t0)
        return cls(members, model_set.schedule, model_set.points, scale=scale, hysteresis=hysteresis,
                   warm_start=warm_start, name=name,
                   report={"design_seconds": seconds}, model_set={"name": model_set.name,
                                                                  "provenance": dict(model_set.provenance)})

    # run: output_names, fault_names, fault_name, reset, step and run are Diagnoser's, on the
    # scheduled runtime (outputs add active_member; step's isolation fields are the active member's)

    # -------------------------------------------------------------- files
    def save(self, path) -> Path:
        """Write the scheduled design file (JSON, docs/design-file.md)."""
        from .outpath import check_output_path, json_text, write_atomically

        d = validate_scheduled_design(_clean(self.design), str(path))
        path = check_output_path(path, (".json",), "design file", error=DesignFileError)
        body = json_text(d)  # rows on one line, by the C encoder
        return write_atomically(path, lambda part: part.write_text(body, encoding="utf-8"))

    @classmethod
    def from_design(cls, design: dict) -> "ScheduledDiagnoser":
        self = cls.__new__(cls)
        d = validate_scheduled_design(copy.deepcopy(design), "scheduled design")
        self._adopt(d, [Diagnoser.from_design(m) for m in d["members"]])
        return self

    @classmethod
    def load(cls, path) -> "ScheduledDiagnoser":
        return cls.from_design(parse_design_file(path))


def warm_gain(design: dict, k: int) -> list:
    """``M = (I − A)⁻¹ B`` of a member's discrete LTI filter (its steady-state gain, the state
    for a held input v being ``M v``); refused for a filter with a pole at z = 1."""
    g = design["generator"]["discrete"]
    if g.get("kind") != "lti":
        raise DesignError(f"member {k}: a warm start needs an LTI generator, not {g.get('kind')!r} "
                          f"(warm_start=False)")
    A = np.asarray(g["A"], float).reshape(len(g["A"]), -1)
    n = A.shape[0]
    B = np.asarray(g["B"], float).reshape(n, -1)
    if n == 0:
        return []
    s = np.linalg.svd(np.eye(n) - A, compute_uv=False)
    if s[-1] <= n * np.finfo(float).eps * max(s[0], 1.0):
        raise DesignError(f"member {k}: its filter has a pole at z = 1 (smallest singular value of I - A "
                          f"{s[-1]:.3g}), so it has no steady state to start from (warm_start=False)")
    return np.linalg.solve(np.eye(n) - A, B).tolist()


def load_diagnoser(path):
    """A design file of either format: a :class:`Diagnoser` or a :class:`ScheduledDiagnoser`."""
    d = parse_design_file(path)
    if is_scheduled(d):
        return ScheduledDiagnoser.from_design(d)
    return Diagnoser._from_checked(d, checked_design(d, str(path), base=Path(path).parent))


def design_cli(args, design_one) -> int:
    """``fmu-fdi design SET.json ...``: each member designed by the design command itself
    (``design_one``, with the same options), then scheduled; one line per member."""
    import contextlib
    import io
    import tempfile

    from .modelset import ModelSet

    mset = ModelSet.from_file(args.model)
    if args.calibrate or args.method == "data":
        raise DesignError("a model set is designed from its models: --calibrate and --method data take one log, "
                          "not one per operating point")
    members, seconds = [], []
    base = args.name or f"{mset.name}_{args.method}"
    with tempfile.TemporaryDirectory(prefix="fmu_fdi_schedule_") as tmp:
        for k, model in enumerate(mset.members, 1):
            one = copy.copy(args)
            one.model, one.output, one.name = str(Path(tmp, f"m{k}.json")), str(Path(tmp, f"d{k}.json")), f"{base}_{k}"
            model.to_file(one.model)
            t0 = time.perf_counter()
            try:
                with contextlib.redirect_stdout(io.StringIO()):
                    design_one(one)
            except ValueError as exc:
                raise type(exc)(f"member {k} of {args.model}: {exc}") from None
            seconds.append(time.perf_counter() - t0)
            members.append(Diagnoser.load(one.output))
            print(f"member {k}/{len(mset)}: {members[-1].design['generator']['method']} designed in "
                  f"{seconds[-1]:.2f} s", flush=True)
    sd = ScheduledDiagnoser(members, mset.schedule, mset.points, hysteresis=args.hysteresis,
                            warm_start=args.warm_start, name=f"{base}_scheduled", report={"design_seconds": seconds},
                            model_set={"name": mset.name, "provenance": dict(mset.provenance)})
    path = sd.save(args.output)
    print(f"wrote {path}: {len(members)} members scheduled on {mset.schedule} (nearest, hysteresis "
          f"{args.hysteresis:g}), {members[0].runtime.n_residuals} residual(s) each")
    return 0


def design_of(obj):
    """The validated scheduled design of a ScheduledDiagnoser, scheduled design dict or file; None
    for anything else (``build_fmu``'s hook)."""
    if isinstance(obj, ScheduledDiagnoser):
        return validate_scheduled_design(_clean(obj.design), "scheduled diagnoser")  # _clean: a fresh JSON-ready copy
    if isinstance(obj, dict):
        return validate_scheduled_design(obj) if is_scheduled(obj) else None
    if isinstance(obj, Diagnoser):
        return None
    try:
        d = parse_design_file(obj)
    except DesignFileError:
        return None  # the plain loader reports it
    return validate_scheduled_design(d, str(obj)) if is_scheduled(d) else None


def scheduled_outputs(design: dict, names: list, descriptions: dict) -> tuple[list, dict]:
    """The FMU's output names and variable descriptions of a scheduled design (member 1's plus
    ``active_member``)."""
    from .runtime.schedule import output_names

    sch = design["schedule"]
    where = ", ".join(f"{k + 1} at " + ", ".join(f"{s}={p:g}" for s, p in zip(sch["signals"], pt))
                      for k, pt in enumerate(sch["points"]))
    descriptions = dict(descriptions, active_member=f"member whose outputs are shown (0 before the first valid "
                                                    f"sample; nearest on {', '.join(sch['signals'])}, hysteresis "
                                                    f"{sch['hysteresis']:g}): {where}")
    # docs/semantics.md §12: the flags of an overflow are any member's
    descriptions["numeric_reset"] = ("the last sample overflowed the evaluation of a member (a value became "
                                     "NaN/Inf): fault evidence for that member's groups it reached, its sample "
                                     "discarded, its generator and evaluation restarted (docs/semantics.md §8, §12)")
    descriptions["input_invalid"] = ("the last input sample had NaN/Inf or was outside its valid range (diagnosis and "
                                     "schedule held), or overflowed a member's evaluation (numeric_reset)")
    return output_names(names), descriptions
