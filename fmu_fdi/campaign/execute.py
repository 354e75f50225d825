"""One campaign run on a worker: FMUs instantiated once and reset between runs, and the run's
summary (what :mod:`fmu_fdi.campaign.aggregate` needs, without the traces).

Per diagnoser (every FMU with ``fault_detected`` and ``isolated_fault`` outputs) a run's
summary holds, over the *scored* samples (rows 1 … N, the diagnoses; none before the
campaign's ``zone_start``), split into the faulty part ``F = [t_on, t_off)`` and the
fault-free part ``H`` (the rest):

- ``samples``, ``alarm_samples``: fault-free samples, and those with ``fault_detected``;
- ``false_alarms``: alarm onsets in H (rising edges; :func:`fmu_fdi.metrics.metrics`);
- ``detected``, ``delay`` (``t_dt``), ``t_isolate`` (``t_it``): from :func:`~fmu_fdi.metrics.metrics`;
- ``isolated_as``: the isolation the diagnoser held longest over the alarmed samples of F (its
  predominant verdict; ``"none"`` when F raised no alarm, ``"unknown"`` for −1);
- ``max_ratio``: the largest ``evaluation_i / threshold_i`` over H and over F;
- ``sweep``: for every factor ``s`` of the campaign's threshold_scale grid, the alarm samples and
  onsets in H and the detection delay in F had every threshold been ``s`` times larger. The
  alarms are recomputed from the recorded evaluations with the design's decision rule
  (raw test ``J_i ≥ s J_th,i``, persistence k of n, latch; Frank's section 7, as
  :mod:`fmu_fdi.runtime.decision`); ``sweep_exact`` tells whether the factor 1 reproduces the
  FMU's own ``fault_detected`` at every sample (if not, the sweep is not to be trusted).
"""
from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

from ..cosim import CoSimulation, SimulationFailed
from ..cosim.instance import FMUInstance
from ..metrics import metrics

_EPS = 1e-9


class PooledInstance(FMUInstance):
    """An :class:`FMUInstance` that outlives a run: the first :meth:`start` extracts and
    instantiates, later ones call ``reset`` (FMI 2 ``fmi2Reset``, FMI 3 ``fmi3Reset``: the
    instance returns to its state right after instantiation) and initialise again. The
    master's :meth:`close` keeps the instance unless it failed; :meth:`dispose` frees it."""

    def start(self, start_time, stop_time, values):
        if self._slave is None:
            return super().start(start_time, stop_time, values)
        self._status = 0
        self.log.clear()
        try:
            self._slave.reset()
            if self.fmi_version == 2:
                self._slave.setupExperiment(startTime=start_time, stopTime=stop_time)
                self._write(values, start_time)
                self._slave.enterInitializationMode()
            else:
                self._write(values, start_time)
                self._slave.enterInitializationMode(startTime=start_time, stopTime=stop_time)
            self._slave.exitInitializationMode()
        except Exception as exc:
            self._status = max(self._status, getattr(exc, "status", 3))
            raise self._failure(f"failed to reset and initialise at t={start_time:g}: {exc}", start_time) from exc

    def close(self):
        if self._status >= 2:  # Discard or worse: start the next run from a fresh instance
            self.dispose()

    def dispose(self):
        """Terminate and free the instance and delete its extraction."""
        super().close()


class Worker:
    """Runs campaign runs with FMU instances kept alive between them.

    Parameters
    ----------
    payload : dict
        From :func:`fmu_fdi.campaign.runner.payload`: the campaign's set-up, the FMUs' bytes
        (so a worker on another machine needs no shared file system) and the scales.
    """

    def __init__(self, payload: dict):
        self.payload = payload
        self.folder = Path(tempfile.mkdtemp(prefix="fmu_fdi_campaign_"))
        self.instances = {}
        for name, blob in payload["fmus"].items():
            path = self.folder / f"{name}.fmu"
            path.write_bytes(blob)
            self.instances[name] = PooledInstance(name, path)
        self.diagnosers = {name: _diagnoser_info(name, inst, payload["diagnosers"].get(name, {}))
                           for name, inst in self.instances.items()
                           if {"fault_detected", "isolated_fault"} <= set(inst.names("output"))}
        self.scales = np.asarray(payload["scales"], float)

    def run(self, run: dict) -> dict:
        """Co-simulate ``run`` (a :meth:`Run.to_dict`) and return its record: the run, its
        status (``ok`` or ``failed`` with the message), the summary per diagnoser, and the
        wall time; with ``traces`` the full record is written to ``traces/run_<index>.csv``."""
        from .spec import Run

        p = self.payload
        tic = time.perf_counter()
        r = Run(run["index"], run["fault"], run["parameters"], run.get("operating_point"))
        record = {"run": r.to_dict(), "status": "ok", "pid": os.getpid(),
                  "reused": all(inst._slave is not None for inst in self.instances.values())}
        try:
            sim = CoSimulation(self.instances, p["connections"], r.input_signals(p["inputs"], p["start"]),
                               step=p["step"], stop=p["stop"],
                               start=p["start"], order=p["order"], faults=r.faults(),
                               parameters={**p["parameters"], **r.parameters})
            result = sim.run()
        except SimulationFailed as exc:
            record.update(status="failed", error=str(exc))
            result = exc.result
        except Exception as exc:  # a bad scenario must not end the campaign: it is reported
            record.update(status="failed", error=f"{type(exc).__name__}: {exc}")
            result = None
        if record["status"] == "ok":
            record["diagnosers"] = {name: summarise(result, r, info, p, self.scales)
                                    for name, info in self.diagnosers.items()}
        if p.get("traces_dir") and result is not None:
            result.to_csv(Path(p["traces_dir"]) / f"run_{r.index:06d}.csv")
        record["seconds"] = time.perf_counter() - tic
        return record

    def close(self):
        for inst in self.instances.values():
            inst.dispose()
        shutil.rmtree(self.folder, ignore_errors=True)


def _diagnoser_info(name: str, inst: FMUInstance, given: dict) -> dict:
    """Fault names and decision rule of a diagnoser: the campaign's [diagnosers.NAME] table,
    else the design the FMU carries (``resources/*/design.json``), else none / the default."""
    design = {}
    try:
        with zipfile.ZipFile(inst.path) as z:
            found = [n for n in z.namelist() if n.startswith("resources/") and n.endswith("/design.json")]
            if len(found) == 1:
                design = json.loads(z.read(found[0]))
    except (OSError, zipfile.BadZipFile, ValueError):
        design = {}
    decision = dict(design.get("decision", {}))
    decision.update({k: given[k] for k in ("persistence", "latch") if k in given})
    faults = given.get("faults", [f["name"] for f in design.get("faults", [])])
    outputs = inst.names("output")
    groups = sorted(int(v.split("_")[1]) for v in outputs if v.startswith("evaluation_") and v[11:].isdigit())
    missing = [k for k in groups if f"threshold_{k}" not in outputs]
    if missing:
        groups = []
    pers = decision.get("persistence", [1, 1])
    return {"instance": name, "faults": list(faults), "groups": groups, "persistence": (int(pers[0]), int(pers[1])),
            "latch": bool(decision.get("latch", False))}


def decide(J: np.ndarray, th: np.ndarray, persistence=(1, 1), latch=False) -> np.ndarray:
    """``fault_detected`` from evaluations ``J`` and thresholds ``th`` (samples × groups), row 0
    excluded (no diagnosis yet): raw ``J ≥ th``, alarm when k of the last n raw tests fired,
    latched if asked (:mod:`fmu_fdi.runtime.decision`)."""
    raw = J >= th
    raw[0] = False
    k, n = persistence
    if n > 1:
        c = np.vstack([np.zeros((n, raw.shape[1]), np.int64), np.cumsum(raw, axis=0, dtype=np.int64)])
        raw = c[n:] - c[:-n] >= k  # raw tests fired among the last n samples (fewer at the start)
    if latch:
        raw = np.maximum.accumulate(raw, axis=0)
    return raw.any(axis=1)


def summarise(result, run, info: dict, p: dict, scales) -> dict:
    """The run's figures for one diagnoser (see the module docstring)."""
    t = np.asarray(result["time"], float)
    prefix = _prefix(result, info)
    alarm = np.asarray(result[prefix + "fault_detected"], bool)
    iso = np.asarray(result[prefix + "isolated_fault"], int)
    zone = p["start"] if p["zone_start"] is None else max(p["start"], p["zone_start"])
    scored = t >= zone - _EPS * max(1.0, abs(zone))
    scored[0] = False
    f = run.fault
    if f is not None:
        t_on = f["onset"]
        t_off = math.inf if f["duration"] is None else t_on + f["duration"]
        F = scored & (t >= t_on - _EPS * max(1.0, abs(t_on)))
        if math.isfinite(t_off):
            F &= t < t_off - _EPS * max(1.0, abs(t_off))
    else:
        t_on = t_off = None
        F = np.zeros_like(scored)
    H = scored & ~F
    faults = info["faults"]
    true_index = None
    if f is not None and f.get("label") in faults:
        true_index = faults.index(f["label"]) + 1
    m = metrics(result, t_on=t_on, t_off=None if t_off is None or math.isinf(t_off) else t_off,
                fault=true_index, zone=(zone, float(t[-1] + (t[-1] - t[-2]))),
                alarm=prefix + "fault_detected", isolation=prefix + "isolated_fault")
    out = {"samples": int(H.sum()), "alarm_samples": int((alarm & H).sum()), "false_alarms": int(m.false_alarms),
           "faulty_samples": int(F.sum())}
    if f is not None:
        out.update(detected=m.missed_detection is False, delay=_num(m.t_dt), t_isolate=_num(m.t_it),
                   isolated_as=_verdict(iso[alarm & F], faults), label=f.get("label"))
    groups = info["groups"]
    if groups:
        J = np.column_stack([result[f"{prefix}evaluation_{k}"] for k in groups])
        th = np.column_stack([result[f"{prefix}threshold_{k}"] for k in groups])
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.max(np.where(th > 0, J / th, np.where(J > 0, np.inf, 0.0)), axis=1)
        out["max_ratio"] = {"fault_free": _num(ratio[H].max()) if H.any() else None,
                            "faulty": _num(ratio[F].max()) if F.any() else None}
        sweep = {"fa_samples": [], "fa_onsets": [], "delay": []}
        prev_scored = np.roll(scored, 1)  # row 0 is never scored, so the wrap-around is harmless
        for s in scales:
            a = decide(J, s * th, info["persistence"], info["latch"])
            if s == 1.0:
                out["sweep_exact"] = bool(np.array_equal(a[1:], alarm[1:]))
            onsets = a & ~(np.roll(a, 1) & prev_scored) & H
            sweep["fa_samples"].append(int((a & H).sum()))
            sweep["fa_onsets"].append(int(onsets.sum()))
            hit = np.flatnonzero(a & F)
            sweep["delay"].append(float(t[hit[0]] - t_on) if f is not None and hit.size else None)
        out["sweep"] = sweep
    return out


def _prefix(result, info) -> str:
    return info["instance"] + "."


def _verdict(iso: np.ndarray, faults: list) -> str:
    if iso.size == 0:
        return "none"
    values, counts = np.unique(iso, return_counts=True)
    v = int(values[np.argmax(counts)])  # ties: the smallest value, np.unique sorts
    if v == -1:
        return "unknown"
    if v == 0:
        return "none"
    return faults[v - 1] if 0 < v <= len(faults) else f"fault {v}"


def _num(x):
    x = float(x)
    return None if math.isnan(x) else (x if math.isfinite(x) else None)
