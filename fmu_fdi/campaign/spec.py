"""The campaign file (TOML, ``format = "fmu-fdi-campaign/1"``) and the runs it stands for.

A campaign is one co-simulation set-up (FMUs, connections, inputs, step, stop, order, fixed
parameters) and a sample of scenarios over it: fault kind, target, magnitude, onset and
duration, plant parameters, plus fault-free runs; every run gets its own noise seeds. Paths
are relative to the campaign file. A complete file::

    format = "fmu-fdi-campaign/1"
    name = "dts200-sensor-bank"

    [simulation]
    step = 1.0
    stop = 600.0
    order = "jacobi"                 # or "gauss-seidel" (default); start = 0.0 by default

    [fmus]                           # instance -> FMU, in stepping order (plants first)
    plant = "dts200.fmu"
    bank = "dos.fmu"

    [connections]                    # optional; default: "auto" (same-named outputs -> inputs)
    auto = true                      # or: pairs = [["plant.h1", "bank.h1"], ...]

    [inputs]                         # optional external signals
    file = "pumps.csv"               # a CSV with a 'time' column (or: time = [...], and
    interpolation = "zoh"            #  [inputs.values] Q1 = [...], ...)

    [parameters]                     # set in every run
    "plant.noise_enable" = true

    [diagnosers.bank]                # optional: every FMU with fault_detected is a diagnoser;
    faults = ["sensor_h1", "..."]    #  its fault list (isolated_fault j -> name) defaults to the
                                     #  design the FMU carries

    [labels]                         # optional: target -> model fault the diagnoser should name;
    "plant.f_sensor_h1" = "sensor_h1"  # default: an input 'f_<name>' realises fault <name>

    [sample]
    method = "grid"                  # every combination; or "random" (runs draws)
    runs = 100                       # random only: faulty runs
    seed = 1                         # random only: the sampler's seed
    replicates = 2                   # grid only: every combination this often (new noise)
    fault_free = 20                  # fault-free runs (per parameter combination in a grid)
    seeds = ["plant.seed"]           # noise-seed parameters: a distinct value in every run
    seed_base = 1000

    [sample.fault]                   # a list: grid values / random choice; {min, max[, scale =
    kind = ["abrupt"]                #  "log"]}: random only, uniform (log-uniform)
    target = ["plant.f_sensor_h1", "plant.f_sensor_h2"]
    magnitude = [0.5, 1.0]
    onset = [300.0]
    duration = [inf]                 # inf: permanent (the default)

    [sample.parameters]              # plant parameters, sampled like the fault
    "plant.az1" = [0.44, 0.46]

    [sample.operating_points]        # optional: the operating envelope, a dimension of its own
    mode = "path"                    # point k takes value k of every list ("product": every
    Q1 = [21.37, 25.65, 29.92]       #  combination); a bare name is an input signal held at the
    Q2 = [53.80, 43.04, 32.28]       #  value over the run, "instance.variable" a parameter set at
    "plant.h1_start" = [41.0, 42.1, 43.8]  # its start (e.g. the plant's state at that point)

    [analysis]
    confidence = 0.95                # of every interval
    false_alarm_rate = 1e-3          # target per sample of the threshold choice
    scales = {min = 0.5, max = 2.0, count = 16}   # threshold_scale sweep (geometric)
    zone_start = 0.0                 # samples before it are not scored (start-up transients)

    [output]
    traces = false                   # keep every run's full record (CSV)

Operating points: a grid makes its runs (fault-free and faulty) at every point; a random sample
draws a point per run. An input signal of a point replaces the [inputs] signal of that name
(or adds one); the report shows false alarms and detection per point, diagnoser by diagnoser
(:mod:`fmu_fdi.campaign.aggregate`).

Seeds: the k-th run (0-based, in the order of :meth:`CampaignSpec.runs`) sets the j-th seed
parameter to ``seed_base + k · len(seeds) + j``: no two runs share a noise sequence, and a
run's seeds do not depend on how the campaign is executed.

Values are taken as written or refused, before anything runs: numbers are numbers (``true`` is
not 1), every parameter and seed must fit its FMU variable's type (an Integer seed above
2^31 − 1 is an error, not a wrapped seed), a name is set in one place only ([parameters] or
[sample]), targets read ``instance.variable``. A campaign makes at most :data:`MAX_RUNS` runs
and :data:`MAX_SCALES` sweep factors; a run at most ``MAX_STEPS`` steps
(:mod:`fmu_fdi.cosim.master`).
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..cosim import CoSimulationError, Fault, InputSignals
from ..cosim.master import ORDERS

FORMAT = "fmu-fdi-campaign/1"
FAULT_DIMENSIONS = ("kind", "target", "magnitude", "onset", "duration")
_TOP = {"format", "name", "simulation", "fmus", "connections", "inputs", "parameters", "diagnosers", "labels",
        "sample", "analysis", "output"}
_SAMPLE = {"method", "runs", "seed", "replicates", "fault_free", "seeds", "seed_base", "fault", "parameters",
           "operating_points"}
_ANALYSIS_DEFAULTS = {"confidence": 0.95, "false_alarm_rate": 1e-3,
                      "scales": {"min": 0.5, "max": 2.0, "count": 16}, "zone_start": None}


#: most runs one campaign file may make (each run's record stays in memory for the report)
MAX_RUNS = 1_000_000
#: most threshold_scale factors of the sweep (each costs one decision pass per run and diagnoser)
MAX_SCALES = 10_000


class CampaignError(CoSimulationError):
    """A campaign file that cannot be run: the message names the key and what is wrong."""


@dataclass(frozen=True)
class Run:
    """One co-simulation of a campaign.

    ``fault`` is None (fault-free) or a dict with the keys of :data:`FAULT_DIMENSIONS`
    (``duration`` None: permanent) and ``label``, the model fault it realises; ``parameters`` holds the sampled plant parameters and the
    noise seeds (and the operating point's parameters). ``operating_point`` (None without
    [sample.operating_points]) maps each name of the point to its value: bare names are input
    signals held at that value (:meth:`input_signals`). ``key`` identifies the scenario (a hash
    of its content), so a resumed campaign recognises the runs it has finished.
    """

    index: int
    fault: dict | None
    parameters: dict
    operating_point: dict | None = None

    @property
    def key(self) -> str:
        content = {"fault": self.fault, "parameters": self.parameters}
        if self.operating_point is not None:
            content["operating_point"] = self.operating_point
        text = json.dumps(content, sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def input_signals(self, base: InputSignals | None, start: float = 0.0) -> InputSignals | None:
        """The campaign's input signals ``base`` with the operating point's signals (its bare
        names) held at their values over the whole run, added when ``base`` lacks them."""
        held = {n: v for n, v in (self.operating_point or {}).items() if "." not in n}
        if not held:
            return base
        if base is None:
            return InputSignals([start], {n: [v] for n, v in held.items()})
        values = dict(base.values, **{n: np.full(base.time.shape, float(v)) for n, v in held.items()})
        return InputSignals(base.time, values, base.interpolation)

    def faults(self) -> list:
        """The :class:`~fmu_fdi.cosim.Fault` list of the run (empty when fault-free)."""
        if self.fault is None:
            return []
        f = self.fault
        end = None if f["duration"] is None else f["onset"] + f["duration"]
        return [Fault(f["kind"], f["target"], onset=f["onset"], magnitude=f["magnitude"], end=end,
                      name="injected", ramp=f.get("ramp"), period=f.get("period"))]

    def to_dict(self) -> dict:
        out = {"index": self.index, "key": self.key, "fault": self.fault, "parameters": self.parameters}
        if self.operating_point is not None:
            out["operating_point"] = self.operating_point
        return out


@dataclass
class CampaignSpec:
    """A validated campaign file (see the module docstring for the format).

    Build one with :meth:`load` (a TOML file) or :meth:`from_dict`; :meth:`runs` lists the runs.
    """

    name: str
    folder: Path
    fmus: dict
    step: float
    stop: float
    start: float = 0.0
    order: str = "gauss-seidel"
    connections: object = "auto"
    inputs: InputSignals | None = None
    parameters: dict = field(default_factory=dict)
    diagnosers: dict = field(default_factory=dict)
    labels: dict = field(default_factory=dict)
    sample: dict = field(default_factory=dict)
    analysis: dict = field(default_factory=dict)
    traces: bool = False
    source: dict = field(default_factory=dict)

    # ------------------------------------------------------------------ reading
    @classmethod
    def load(cls, path) -> "CampaignSpec":
        """Read and validate a campaign TOML file."""
        try:
            import tomllib
        except ModuleNotFoundError:  # Python 3.10
            import tomli as tomllib
        from .._schema import read_text

        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"campaign file: no such file {str(path)!r}")
        text = read_text(path, "campaign file", CampaignError)  # binary, UTF-16, an FMU: one-line errors
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise CampaignError(f"campaign file {path}: not valid TOML: {exc}") from None
        except RecursionError:
            raise CampaignError(f"campaign file {path}: nested too deeply to be a campaign file") from None
        try:
            return cls.from_dict(data, path.resolve().parent)
        except RecursionError:
            raise CampaignError(f"campaign file {path}: nested too deeply to be a campaign file") from None

    @classmethod
    def from_dict(cls, data: dict, folder=".") -> "CampaignSpec":
        """Validate a campaign given as a dict (the TOML file's content); paths relative to ``folder``."""
        data = copy.deepcopy(data)
        folder = Path(folder)
        fmt = data.get("format")
        if fmt != FORMAT:
            raise CampaignError(f"campaign: format must be {FORMAT!r}, got {fmt!r}")
        unknown = set(data) - _TOP
        if unknown:
            raise CampaignError(f"campaign: unknown key(s) {sorted(unknown)}; known: {sorted(_TOP)}")
        sim = _table(data, "simulation")
        for key in ("step", "stop"):
            if key not in sim:
                raise CampaignError(f"campaign: [simulation] needs {key!r}")
        order = sim.get("order", "gauss-seidel")
        if order not in ORDERS:
            raise CampaignError(f"campaign: [simulation] order {order!r} is not one of {ORDERS}")
        fmus = _table(data, "fmus")
        if not fmus:
            raise CampaignError("campaign: [fmus] names no FMU")
        paths = {}
        for name, rel in fmus.items():
            p = (folder / str(rel)).resolve()
            if not p.is_file():
                raise CampaignError(f"campaign: [fmus] {name} = {rel!r}: no such file {str(p)!r}")
            paths[name] = p
        spec = cls(name=str(data.get("name", "campaign")), folder=folder, fmus=paths,
                   step=_float(sim["step"], "simulation.step"), stop=_float(sim["stop"], "simulation.stop"),
                   start=_float(sim.get("start", 0.0), "simulation.start"), order=order,
                   connections=_connections(data.get("connections")),
                   inputs=_inputs(data.get("inputs"), folder), parameters=dict(_table(data, "parameters")),
                   diagnosers={k: dict(v) for k, v in _table(data, "diagnosers").items()},
                   labels=dict(_table(data, "labels")), sample=_sample(_table(data, "sample")),
                   analysis=_analysis(_table(data, "analysis")),
                   traces=bool(_table(data, "output").get("traces", False)), source=data)
        unused = sorted(set(spec.labels) - set(spec.sample["fault"]["target"]))
        if unused:
            raise CampaignError(f"campaign: [labels] {', '.join(unused)} is not a fault target of [sample.fault] "
                                f"({', '.join(spec.sample['fault']['target']) or 'none'})")
        drawn = set(spec.sample["seeds"]) | set(spec.sample["parameters"])
        twice = sorted(drawn & set(spec.parameters))
        if twice:
            raise CampaignError(f"campaign: {', '.join(twice)} is set in [parameters] and drawn per run by [sample] "
                                f"(seeds or sample.parameters); the run would ignore the [parameters] value: "
                                f"give it in one place")
        points = spec.sample["operating_points"]
        twice = sorted(set(points[0] if points else ()) & (drawn | set(spec.parameters)))
        if twice:
            raise CampaignError(f"campaign: {', '.join(twice)} is set by [sample.operating_points] and by "
                                f"[parameters] or [sample] (seeds or sample.parameters): give it in one place")
        for name, table in spec.diagnosers.items():
            if name not in paths:
                raise CampaignError(f"campaign: [diagnosers.{name}] is not an FMU of [fmus] ({', '.join(paths)})")
            extra = set(table) - {"faults", "persistence", "latch"}
            if extra:
                raise CampaignError(f"campaign: unknown key(s) {sorted(extra)} in [diagnosers.{name}]; known: "
                                    f"faults, persistence, latch")
        spec.check()
        return spec

    def check(self):
        """Check every name before anything runs: one co-simulation set-up (no FMU instantiated)
        per distinct fault kind, target and permanence, with every parameter and seed name."""
        from ..cosim import CoSimulation
        from ..cosim.instance import FMUInstance

        runs = self.runs()
        instances = {name: FMUInstance(name, path) for name, path in self.fmus.items()}
        seen = {"last": runs[-1]}  # the largest seeds: each seed must fit its variable's type
        for r in runs:
            f = r.fault
            key = None if f is None else (f["kind"], f["target"], f["duration"] is None)
            seen.setdefault(key, r)
        for r in seen.values():
            try:
                CoSimulation(instances, self.connections, r.input_signals(self.inputs, self.start), step=self.step,
                             stop=self.stop,
                             start=self.start, order=self.order, faults=r.faults(),
                             parameters={**self.parameters, **r.parameters})
            except CoSimulationError as exc:
                raise CampaignError(f"campaign: run {r.index}: {exc}") from None

    # ------------------------------------------------------------------ runs
    def runs(self) -> list:
        """Every run of the campaign, fault-free runs first, in a fixed order."""
        s = self.sample
        params = s["parameters"]
        fault_dims = {k: s["fault"][k] for k in FAULT_DIMENSIONS}
        count = self.run_count()
        if count > MAX_RUNS:
            raise CampaignError(f"campaign: [sample] makes {count:.4g} runs, more than the {MAX_RUNS} a campaign may "
                                f"have; sample fewer (method = \"random\" with runs = N, or shorter lists)")
        scenarios = []  # (fault or None, parameters, operating point or None)
        points = s["operating_points"] or [None]
        if s["method"] == "grid":
            names = list(params)
            combos = [dict(zip(names, values)) for values in itertools.product(*(params[n] for n in names))]
            for point in points:  # every run of the grid at each operating point in turn
                for combo in combos:
                    scenarios += [(None, combo, point)] * s["fault_free"]
                if s["fault"]["target"]:
                    for combo in combos:
                        for values in itertools.product(*(fault_dims[k] for k in FAULT_DIMENSIONS)):
                            fault = dict(zip(FAULT_DIMENSIONS, values))
                            scenarios += [(fault, combo, point)] * s["replicates"]
        else:
            rng = np.random.default_rng(s["seed"])
            for k in range(s["fault_free"] + s["runs"]):
                combo = {n: _draw(rng, v) for n, v in params.items()}
                fault = ({d: _draw(rng, fault_dims[d]) for d in FAULT_DIMENSIONS}
                         if k >= s["fault_free"] else None)
                point = points[int(rng.integers(len(points)))] if s["operating_points"] else None
                scenarios.append((fault, combo, point))
        runs = []
        seeds = s["seeds"]
        for k, (fault, combo, point) in enumerate(scenarios):
            p = dict(combo, **{n: v for n, v in (point or {}).items() if "." in n})
            for j, name in enumerate(seeds):
                p[name] = s["seed_base"] + k * len(seeds) + j
            if fault is not None:
                fault = {**fault, **{x: s["fault"][x] for x in ("ramp", "period") if x in s["fault"]},
                         "label": self.label(fault["target"])}
                if math.isinf(fault["duration"]):
                    fault["duration"] = None  # permanent (JSON has no inf)
                zone = self.analysis["zone_start"]
                if zone is not None and fault["onset"] < zone:
                    raise CampaignError(f"campaign: run {k}: fault onset {fault['onset']:g} is before "
                                        f"analysis.zone_start {zone:g} (the scored part must start fault-free)")
            run = Run(k, fault, p, None if point is None else dict(point))
            try:
                run.faults()
            except CoSimulationError as exc:
                raise CampaignError(f"campaign: run {k}: {exc}") from None
            runs.append(run)
        return runs

    def run_count(self) -> int:
        """How many runs :meth:`runs` makes, counted without making them."""
        s = self.sample
        if s["method"] != "grid":
            return s["fault_free"] + s["runs"]
        combos = math.prod(len(v) for v in s["parameters"].values()) * max(len(s["operating_points"]), 1)
        faults = math.prod(len(s["fault"][k]) for k in FAULT_DIMENSIONS) if s["fault"]["target"] else 0
        return combos * (s["fault_free"] + faults * s["replicates"])

    @property
    def scales(self) -> np.ndarray:
        """The threshold_scale factors of the sweep (geometric grid, always containing 1)."""
        sc = self.analysis["scales"]
        grid = np.geomspace(sc["min"], sc["max"], sc["count"])
        return np.unique(np.append(grid, 1.0))

    def label(self, target: str) -> str | None:
        """The model fault a fault on ``target`` realises: [labels], else ``f_<name>`` -> ``<name>``."""
        if target in self.labels:
            return str(self.labels[target])
        var = target.split(".", 1)[1]
        return var[2:] if var.startswith("f_") else None

    def to_dict(self) -> dict:
        """The campaign's content as read (for the results header)."""
        return self.source


# ---------------------------------------------------------------------- helpers
def _table(data, key) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise CampaignError(f"campaign: [{key}] must be a table, got {type(value).__name__}")
    return value


def _float(x, what) -> float:
    if isinstance(x, bool) or isinstance(x, str):
        raise CampaignError(f"campaign: {what} must be a number, got {x!r}")
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise CampaignError(f"campaign: {what} must be a number, got {x!r}") from None
    if math.isnan(v):
        raise CampaignError(f"campaign: {what} is NaN")
    return v


def _connections(value):
    if value is None:
        return "auto"
    if not isinstance(value, dict):
        raise CampaignError("campaign: [connections] must be a table with auto = true or pairs = [[src, dst], ...]")
    if "pairs" in value:
        pairs = value["pairs"]
        if not all(isinstance(p, list) and len(p) == 2 for p in pairs):
            raise CampaignError("campaign: [connections] pairs must be [[\"fmu.out\", \"fmu.in\"], ...]")
        return [tuple(p) for p in pairs]
    return "auto" if value.get("auto", True) else None


def _inputs(value, folder):
    if value is None:
        return None
    interp = value.get("interpolation", "zoh")
    if "file" in value:
        return InputSignals.from_csv(folder / value["file"], interp)
    if "time" in value and "values" in value:
        return InputSignals(value["time"], value["values"], interp)
    raise CampaignError("campaign: [inputs] needs file = \"x.csv\", or time = [...] with [inputs.values]")


def _dimension(value, what, numeric=True):
    """A sampled dimension: a non-empty list, or (numeric) {min, max[, scale]}."""
    if isinstance(value, dict):
        if not numeric:
            raise CampaignError(f"campaign: {what} must be a list")
        if set(value) - {"min", "max", "scale"} or "min" not in value or "max" not in value:
            raise CampaignError(f"campaign: {what} range must be {{min = a, max = b[, scale = \"log\"]}}, got {value}")
        lo, hi = _float(value["min"], what + ".min"), _float(value["max"], what + ".max")
        scale = value.get("scale", "linear")
        if scale not in ("linear", "log") or not lo <= hi or (scale == "log" and not lo > 0):
            raise CampaignError(f"campaign: {what} range {value} needs min <= max (> 0 for scale = \"log\")")
        return {"min": lo, "max": hi, "scale": scale}
    if not isinstance(value, list):
        value = [value]
    if not value:
        raise CampaignError(f"campaign: {what} is an empty list")
    return [_float(v, what) if numeric and v is not None else v for v in value]


def _draw(rng, dim):
    if isinstance(dim, dict):
        if dim["scale"] == "log":
            return float(math.exp(rng.uniform(math.log(dim["min"]), math.log(dim["max"]))))
        return float(rng.uniform(dim["min"], dim["max"]))
    return dim[int(rng.integers(len(dim)))]


def _sample(s: dict) -> dict:
    unknown = set(s) - _SAMPLE
    if unknown:
        raise CampaignError(f"campaign: unknown key(s) {sorted(unknown)} in [sample]; known: {sorted(_SAMPLE)}")
    method = s.get("method", "grid")
    if method not in ("grid", "random"):
        raise CampaignError(f"campaign: [sample] method must be 'grid' or 'random', got {method!r}")
    out = {"method": method}
    for key, default, low in (("runs", 0, 0), ("seed", 0, 0), ("replicates", 1, 1), ("fault_free", 0, 0),
                              ("seed_base", 1, 0)):
        v = s.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            raise CampaignError(f"campaign: [sample] {key} must be an integer >= {low}, got {v!r}")
        out[key] = v
    if method == "grid" and isinstance(s.get("fault", {}).get("magnitude"), dict):
        raise CampaignError("campaign: a grid samples lists only; use method = \"random\" for ranges")
    seeds = s.get("seeds", [])
    out["seeds"] = [seeds] if isinstance(seeds, str) else list(seeds)
    f = dict(s.get("fault", {}))
    extra = set(f) - set(FAULT_DIMENSIONS) - {"ramp", "period"}
    if extra:
        raise CampaignError(f"campaign: unknown key(s) {sorted(extra)} in [sample.fault]")
    fault = {"kind": _dimension(f.get("kind", ["abrupt"]), "sample.fault.kind", numeric=False),
             "target": _dimension(f["target"], "sample.fault.target", numeric=False) if f.get("target") else [],
             "magnitude": _dimension(f.get("magnitude", [1.0]), "sample.fault.magnitude"),
             "onset": _dimension(f.get("onset", [0.0]), "sample.fault.onset"),
             "duration": _dimension(f.get("duration", [math.inf]), "sample.fault.duration")}
    for x in ("ramp", "period"):
        if x in f:
            fault[x] = _float(f[x], f"sample.fault.{x}")
    for target in fault["target"]:
        if not isinstance(target, str) or "." not in target.strip(".") or target.startswith("."):
            raise CampaignError(f"campaign: sample.fault.target {target!r} must read 'instance.variable', "
                                f"e.g. 'plant.f_sensor_h1'")
    out["fault"] = fault
    if method == "random" and out["runs"] and not fault["target"]:
        raise CampaignError("campaign: [sample] runs > 0 needs [sample.fault] target")
    if method == "grid":
        for key, dim in fault.items():
            if isinstance(dim, dict):
                raise CampaignError(f"campaign: sample.fault.{key} is a range; a grid takes lists only")
    out["parameters"] = {}
    for name, dim in s.get("parameters", {}).items():
        d = _dimension(dim, f"sample.parameters.{name!r}", numeric=not isinstance(dim, list)
                       or all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in dim))
        if method == "grid" and isinstance(d, dict):
            raise CampaignError(f"campaign: sample.parameters.{name!r} is a range; a grid takes lists only")
        out["parameters"][name] = d
    if not out["fault_free"] and not fault["target"]:
        raise CampaignError("campaign: [sample] has no runs: give fault_free > 0 or [sample.fault] target")
    out["operating_points"] = _operating_points(s.get("operating_points"))
    return out


def _operating_points(table) -> list:
    """[sample.operating_points] as a list of points ``{name: value}`` ([] when absent): ``mode``
    "path" (default; every list of one length K, point k takes value k of each) or "product"
    (every combination, last name fastest), as ``fmu-fdi model --at-grid`` (:func:`fmu_fdi.modelset.grid_points`)."""
    from ..errors import ModelError
    from ..modelset import grid_points

    if table is None:
        return []
    if not isinstance(table, dict):
        raise CampaignError(f"campaign: [sample.operating_points] must be a table, got {type(table).__name__}")
    table = dict(table)
    mode = table.pop("mode", "path")
    if not table:
        raise CampaignError("campaign: [sample.operating_points] names no signal or parameter")
    grids = []
    for name, values in table.items():
        if "." in name and (name.startswith(".") or name.endswith(".")):
            raise CampaignError(f"campaign: sample.operating_points {name!r} must be a signal name or "
                                f"'instance.parameter'")
        vals = _dimension(values, f"sample.operating_points.{name!r}", numeric=True)
        if isinstance(vals, dict) or any(not math.isfinite(v) for v in vals):
            raise CampaignError(f"campaign: sample.operating_points.{name!r} must be a list of finite numbers, "
                                f"got {values!r}")
        grids.append((name, np.asarray(vals, float)))
    try:
        points = grid_points(grids, {"path": "path", "product": "product"}.get(mode, repr(mode)))
    except ModelError as exc:
        raise CampaignError(f"campaign: [sample.operating_points]: {exc}") from None
    if len({tuple(p.values()) for p in points}) != len(points):
        raise CampaignError("campaign: [sample.operating_points] lists a point twice")
    return points


def _analysis(a: dict) -> dict:
    unknown = set(a) - set(_ANALYSIS_DEFAULTS)
    if unknown:
        raise CampaignError(f"campaign: unknown key(s) {sorted(unknown)} in [analysis]")
    out = {**_ANALYSIS_DEFAULTS, **a}
    c = _float(out["confidence"], "analysis.confidence")
    if not 0 < c < 1:
        raise CampaignError(f"campaign: analysis.confidence must lie in (0, 1), got {c}")
    rate = _float(out["false_alarm_rate"], "analysis.false_alarm_rate")
    if not 0 < rate < 1:
        raise CampaignError(f"campaign: analysis.false_alarm_rate must lie in (0, 1), got {rate}")
    sc = dict(_ANALYSIS_DEFAULTS["scales"], **out["scales"])
    lo, hi, n = _float(sc["min"], "analysis.scales.min"), _float(sc["max"], "analysis.scales.max"), sc["count"]
    if not 0 < lo <= hi or isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_SCALES \
            or not math.isfinite(hi):
        raise CampaignError(f"campaign: analysis.scales needs 0 < min <= max < inf and an integer count in "
                            f"[1, {MAX_SCALES}], got {sc}")
    zone = out["zone_start"]
    return {"confidence": c, "false_alarm_rate": rate, "scales": {"min": lo, "max": hi, "count": n},
            "zone_start": None if zone is None else _float(zone, "analysis.zone_start")}
