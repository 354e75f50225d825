"""Campaign figures from the per-run summaries, with exact binomial intervals.

Per diagnoser:

- **False alarms.** ``k`` alarmed samples among the ``N`` scored fault-free samples of all
  runs: rate ``k/N`` with the exact Clopper–Pearson interval (Clopper & Pearson 1934)::

      lower = B⁻¹(α/2; k, N − k + 1),   upper = B⁻¹(1 − α/2; k + 1, N − k),   α = 1 − confidence

  (``lower = 0`` for ``k = 0``, ``upper = 1`` for ``k = N``), ``B⁻¹`` the beta quantile. The mean
  time between false alarms is ``MTBFA = N h / m`` with ``m`` the alarm onsets (rising edges) and
  ``h`` the step; its interval is ``h / p`` over the Clopper–Pearson interval of the onset
  probability per sample ``p = m / N``. The binomial model takes the samples as independent
  trials; alarms of a windowed evaluation come in clusters, so the per-sample interval is
  optimistic when ``k`` is large next to ``m`` (the onsets, rare and far apart, are close to
  independent: their interval is the honest one, and the report shows both counts).
- **Detection probability against fault size**: per target and magnitude (magnitudes binned
  when a random sample has many distinct values) the share of runs whose fault raised an alarm
  in the faulty part, with its Clopper–Pearson interval.
- **Detection delays**: their distribution per target and magnitude (quantiles, all values).
- **Isolation confusion matrix**: runs by injected fault (its label) and the diagnoser's
  predominant verdict (:mod:`fmu_fdi.campaign.execute`).
- **Across the operating envelope** (campaigns with [sample.operating_points]): per operating
  point the false-alarm rate (as above, over that point's fault-free samples), the detection
  probability over its faulty runs and the share isolated as the injected fault, each with its
  Clopper–Pearson interval — per diagnoser, so a scheduled diagnoser and a single-point one
  in the same campaign are compared on the same runs.
- **Threshold sweep**: for each factor ``s`` on every threshold, the false-alarm rate (and its
  one-sided upper bound at the campaign's confidence) and the detection probability: the ROC.
  The chosen scale is the smallest ``s`` whose upper bound is at most the target rate
  (a one-sided Clopper–Pearson test of ``p ≤ target`` at that confidence).
"""
from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np


def clopper_pearson(k: int, n: int, confidence: float = 0.95, side: str = "two-sided") -> tuple:
    """Exact binomial interval of a proportion ``k / n`` (Clopper & Pearson 1934).

    Parameters
    ----------
    k, n : int
        Successes and trials, ``0 ≤ k ≤ n``, ``n ≥ 1``.
    confidence : float
        Coverage in (0, 1).
    side : {"two-sided", "upper", "lower"}
        ``"upper"``: ``(0, u)`` with ``u = B⁻¹(c; k + 1, n − k)``, the one-sided upper bound;
        ``"lower"``: ``(l, 1)``.

    Returns
    -------
    (lower, upper)

    Examples
    --------
    >>> lo, hi = clopper_pearson(0, 3000, 0.95, side="upper")
    >>> round(hi * 3000, 3)   # the "rule of three": about 3 / n
    2.995
    """
    from scipy.stats import beta

    if isinstance(k, bool) or isinstance(n, bool) or int(k) != k or int(n) != n or not 0 <= k <= n or n < 1:
        raise ValueError(f"clopper_pearson needs integers 0 <= k <= n, n >= 1; got k={k}, n={n}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    k, n = int(k), int(n)
    tail = {"two-sided": (1 - confidence) / 2, "upper": 1 - confidence, "lower": 1 - confidence}.get(side)
    if tail is None:
        raise ValueError(f"side must be 'two-sided', 'upper' or 'lower', got {side!r}")
    lo = 0.0 if k == 0 or side == "upper" else float(beta.ppf(tail, k, n - k + 1))
    hi = 1.0 if k == n or side == "lower" else float(beta.ppf(1 - tail, k + 1, n - k))
    return lo, hi


@dataclass
class DiagnoserFigures:
    """Everything :func:`aggregate` finds for one diagnoser; ``tables`` are lists of row dicts."""

    name: str
    false_alarms: dict
    detection: list
    delays: list
    confusion: dict
    sweep: list
    choice: dict
    notes: list = field(default_factory=list)
    by_point: list = field(default_factory=list)  # one row per operating point (module docstring)


@dataclass
class CampaignFigures:
    name: str
    runs: int
    failed: list
    step: float
    confidence: float
    target_rate: float
    diagnosers: dict
    planned: int | None = None  # runs the campaign file lists (None: as many as ran)
    interrupted: bool = False  # stopped before every run finished (Ctrl-C)
    warnings: list = field(default_factory=list)  # what reading the results left out
    settings: dict = field(default_factory=dict)  # the campaign's set-up, for the report
    run_rows: list = field(default_factory=list)  # one compact row per run record, for the report
    points: list = field(default_factory=list)  # the operating points' labels, in the campaign's order


def aggregate(results) -> CampaignFigures:
    """Figures of a finished (or partial) campaign (see the module docstring).

    Parameters
    ----------
    results : CampaignResults
        From :func:`~fmu_fdi.campaign.runner.run_campaign`.
    """
    spec = results.spec
    conf = spec.analysis["confidence"]
    target = spec.analysis["false_alarm_rate"]
    scales = spec.scales.tolist()
    ok = [r for r in results.records if r["status"] == "ok"]
    failed = [{"run": r["run"]["index"], "error": r.get("error", "")} for r in results.records if r["status"] != "ok"]
    names = sorted({d for r in ok for d in r["diagnosers"]})
    points = spec.sample.get("operating_points") or []
    out = {}
    for name in names:
        runs = [(r["run"], r["diagnosers"][name]) for r in ok if name in r["diagnosers"]]
        out[name] = _diagnoser(name, runs, spec.step, conf, target, scales)
        if points:
            out[name].by_point = by_operating_point(runs, points, conf)
    extra = getattr(results, "extra", {}) or {}
    return CampaignFigures(spec.name, len(results.records), failed, spec.step, conf, target, out,
                           planned=extra.get("planned"), interrupted=bool(getattr(results, "interrupted", False)),
                           warnings=list(extra.get("warnings", [])), settings=_settings(spec),
                           run_rows=[_run_row(r) for r in results.records],
                           points=[point_label(p) for p in points])


def point_label(point: dict) -> str:
    """``Q1=21.37, Q2=53.8``: the point's input signals (its parameters too when it has no signal)."""
    shown = {n: v for n, v in point.items() if "." not in n} or point
    return ", ".join(f"{n}={v:.4g}" for n, v in shown.items())


def by_operating_point(runs, points: list, conf: float) -> list:
    """Per operating point of the campaign (in its order): fault-free samples ``N``, alarmed
    samples ``k``, alarm onsets, rate ``k/N`` and its Clopper–Pearson interval; faulty runs
    ``n``, detected ``d``, ``d/n`` and its interval; isolated as the injected fault ``i``, ``i/n``
    and its interval (module docstring). A run belongs to the point its operating point equals."""
    rows = []
    for j, point in enumerate(points, 1):
        mine = [(run, s) for run, s in runs if run.get("operating_point") == point]
        N = sum(s["samples"] for _, s in mine)
        k = sum(s["alarm_samples"] for _, s in mine)
        faulty = [(run, s) for run, s in mine if run["fault"] is not None]
        n = len(faulty)
        d = sum(bool(s["detected"]) for _, s in faulty)
        i = sum(s.get("isolated_as") == run["fault"]["label"] for run, s in faulty if run["fault"]["label"])
        rows.append({"point": j, "label": point_label(point), "values": dict(point), "fault_free_runs": len(mine) - n,
                     "samples": N, "alarm_samples": k, "onsets": sum(s["false_alarms"] for _, s in mine),
                     "rate": k / N if N else None, "interval": clopper_pearson(k, N, conf) if N else None,
                     "faulty_runs": n, "detected": d, "detection": d / n if n else None,
                     "detection_interval": clopper_pearson(d, n, conf) if n else None, "isolated": i,
                     "isolation": i / n if n else None, "isolation_interval": clopper_pearson(i, n, conf) if n else None})
    return rows


def _run_row(record) -> dict:
    """A run as the report lists it: scenario, status and per diagnoser detected / delay."""
    run, f = record["run"], record["run"].get("fault")
    row = {"run": run["index"], "key": run["key"],
           "fault": "fault-free" if not f else f"{f.get('kind')} {f.get('target')} {f.get('magnitude')} "
                                                f"from {f.get('onset')} s"
                                                + ("" if f.get("duration") is None else f" for {f['duration']} s"),
           "parameters": " ".join(f"{k}={v}" for k, v in run.get("parameters", {}).items()),
           "status": record["status"] if record["status"] == "ok" else f"failed: {record.get('error', '')}"}
    for name, d in (record.get("diagnosers") or {}).items():
        row[f"{name}: false alarms"] = d.get("false_alarms")
        if f:
            row[f"{name}: delay (s)"] = d.get("delay")
            row[f"{name}: isolated as"] = d.get("isolated_as")
    return row


def _settings(spec) -> dict:
    """What the report records of the set-up: simulation, sample, analysis, FMUs with GUIDs."""
    from ..cosim.instance import FMUInstance

    fmus = {}
    for name, path in spec.fmus.items():
        try:
            md = FMUInstance(name, path).model_description
            fmus[name] = {"file": str(path), "guid": md.guid, "fmi": md.fmiVersion, "model": md.modelName}
        except Exception as exc:  # the FMU was read when the campaign was checked; it may have gone since
            fmus[name] = {"file": str(path), "guid": f"unreadable now: {exc}", "fmi": "", "model": ""}
    s = spec.sample
    return {"simulation": {"start": spec.start, "stop": spec.stop, "step": spec.step, "order": spec.order},
            "sample": {k: v for k, v in s.items() if k != "fault"}, "fault": s["fault"],
            "parameters": dict(spec.parameters), "analysis": spec.analysis, "fmus": fmus,
            "diagnosers": spec.diagnosers}


def _diagnoser(name, runs, h, conf, target, scales) -> DiagnoserFigures:
    N = sum(s["samples"] for _, s in runs)
    k = sum(s["alarm_samples"] for _, s in runs)
    m = sum(s["false_alarms"] for _, s in runs)
    notes = []
    fa = {"samples": N, "alarm_samples": k, "onsets": m, "rate": k / N if N else None,
          "interval": clopper_pearson(k, N, conf) if N else None,
          "onset_rate": m / N if N else None, "onset_interval": clopper_pearson(m, N, conf) if N else None}
    if N:
        lo, hi = fa["onset_interval"]
        fa["mtbfa"] = N * h / m if m else math.inf
        fa["mtbfa_interval"] = (h / hi, h / lo if lo > 0 else math.inf)
    faulty = [(run, s) for run, s in runs if run["fault"] is not None]
    groups = _size_groups(faulty)
    detection, delays = [], []
    for (target_name, kind, label), bins in groups.items():
        for size, members in bins:
            n = len(members)
            d = sum(bool(s["detected"]) for _, s in members)
            lo, hi = clopper_pearson(d, n, conf)
            detection.append({"target": target_name, "kind": kind, "label": label, "magnitude": size, "runs": n,
                              "detected": d, "probability": d / n, "lower": lo, "upper": hi})
            values = sorted(s["delay"] for _, s in members if s["delay"] is not None)
            row = {"target": target_name, "kind": kind, "magnitude": size, "detected": len(values)}
            if values:
                q = np.quantile(values, [0.1, 0.5, 0.9])
                row.update(min=values[0], p10=float(q[0]), median=float(q[1]), p90=float(q[2]), max=values[-1])
            row["values"] = values
            delays.append(row)
    labels = sorted({run["fault"]["label"] or run["fault"]["target"] for run, _ in faulty})
    verdicts = defaultdict(lambda: defaultdict(int))
    for run, s in faulty:
        verdicts[run["fault"]["label"] or run["fault"]["target"]][s.get("isolated_as", "none")] += 1
    columns = sorted({v for row in verdicts.values() for v in row}, key=lambda v: (v in ("none", "unknown"), v))
    confusion = {"rows": labels, "columns": columns,
                 "counts": [[verdicts[r][c] for c in columns] for r in labels]}
    sweep, choice = [], {"scale": None, "reason": "no run has a threshold sweep"}
    with_sweep = [(run, s) for run, s in runs if "sweep" in s]
    if with_sweep:
        if not all(s.get("sweep_exact", False) for _, s in with_sweep):
            bad = sum(not s.get("sweep_exact", False) for _, s in with_sweep)
            notes.append(f"the sweep's factor 1 does not reproduce the FMU's fault_detected in {bad} run(s): "
                         f"its decision rule is not the one read from the design; the sweep is not reliable")
        n_faulty = sum(run["fault"] is not None for run, _ in with_sweep)
        for j, sc in enumerate(scales):
            kk = sum(s["sweep"]["fa_samples"][j] for _, s in with_sweep)
            mm = sum(s["sweep"]["fa_onsets"][j] for _, s in with_sweep)
            dd = sum(s["sweep"]["delay"][j] is not None for run, s in with_sweep if run["fault"] is not None)
            row = {"scale": sc, "samples": N, "fa_samples": kk, "fa_onsets": mm, "rate": kk / N if N else None,
                   "upper": clopper_pearson(kk, N, conf, "upper")[1] if N else None,
                   "interval": clopper_pearson(kk, N, conf) if N else None,
                   "faulty_runs": n_faulty, "detected": dd, "detection": dd / n_faulty if n_faulty else None}
            sweep.append(row)
        meeting = [row for row in sweep if row["upper"] is not None and row["upper"] <= target]
        if meeting:
            best = min(meeting, key=lambda row: row["scale"])
            choice = {"scale": best["scale"], "rate": best["rate"], "upper": best["upper"],
                      "interval": best["interval"], "detection": best["detection"], "reason": ""}
        elif N:
            need = math.log(1 - conf) / math.log(1 - target)
            choice = {"scale": None, "reason": (
                f"no scale in the sweep has an upper {conf:.0%} bound <= {target:g}: with {N} fault-free samples "
                f"even zero alarms bound the rate by {clopper_pearson(0, N, conf, 'upper')[1]:.3g}; "
                f"at least {math.ceil(need)} samples are needed" if N < need else
                f"no scale in the sweep has an upper {conf:.0%} bound <= {target:g}: extend analysis.scales.max")}
    return DiagnoserFigures(name, fa, detection, delays, confusion, sweep, choice, notes)


def _size_groups(faulty, max_bins: int = 8) -> dict:
    """Faulty runs by (target, kind, label), then by magnitude: the exact values when there are
    at most ``max_bins`` of them, else quantile bins labelled by their median magnitude."""
    by = defaultdict(list)
    for run, s in faulty:
        f = run["fault"]
        by[(f["target"], f["kind"], f["label"])].append((run, s))
    out = {}
    for key, members in by.items():
        sizes = sorted({r["fault"]["magnitude"] for r, _ in members})
        if len(sizes) <= max_bins:
            out[key] = [(v, [(r, s) for r, s in members if r["fault"]["magnitude"] == v]) for v in sizes]
            continue
        members = sorted(members, key=lambda rs: rs[0]["fault"]["magnitude"])
        chunks = np.array_split(np.arange(len(members)), max_bins)
        out[key] = [(float(np.median([members[i][0]["fault"]["magnitude"] for i in c])), [members[i] for i in c])
                    for c in chunks if len(c)]
    return out
