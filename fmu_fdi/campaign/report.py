"""The campaign report: one self-contained HTML file (plots embedded as PNG) and the tables as CSV.

Files written to the output folder: ``report.html``; ``false_alarms.csv`` (one row per
diagnoser), ``detection.csv``, ``delays.csv``, ``sweep.csv`` (rows per diagnoser and target /
scale), ``confusion_<diagnoser>.csv``, ``runs.csv`` (one row per run: scenario, status, per diagnoser
false alarms, delay and verdict); with operating points, ``operating_points.csv`` (per diagnoser
and point: false-alarm rate, detection and isolation with their intervals).

The report opens with the campaign's settings (simulation, sample, analysis, every FMU with its
GUID) and, when fewer runs finished than the campaign file plans (Ctrl-C), a banner saying so:
the figures then describe only the finished runs.
"""
from __future__ import annotations

import base64
import csv
import html
import io
import math
from pathlib import Path

from .aggregate import CampaignFigures


def write_report(figures: CampaignFigures, out_dir) -> dict:
    """Write the HTML report and CSV tables of ``figures``; returns ``{name: path}``."""
    import matplotlib

    matplotlib.use("Agg")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    fa_rows, det_rows, delay_rows, sweep_rows, point_rows = [], [], [], [], []
    for name, d in figures.diagnosers.items():
        for r in d.by_point:
            row = {"diagnoser": name, **{k: v for k, v in r.items() if not k.endswith("interval") and k != "values"},
                   **r["values"]}
            for key in ("interval", "detection_interval", "isolation_interval"):
                lo, hi = r[key] or (None, None)
                row[f"{key.replace('interval', '').rstrip('_') or 'rate'}_lower"] = lo
                row[f"{key.replace('interval', '').rstrip('_') or 'rate'}_upper"] = hi
            point_rows.append(row)
        fa = d.false_alarms
        row = {"diagnoser": name, "samples": fa["samples"], "alarm_samples": fa["alarm_samples"],
               "rate": fa["rate"], "onsets": fa["onsets"]}
        if fa["interval"]:
            row.update(rate_lower=fa["interval"][0], rate_upper=fa["interval"][1], mtbfa_s=fa["mtbfa"],
                       mtbfa_lower_s=fa["mtbfa_interval"][0], mtbfa_upper_s=fa["mtbfa_interval"][1])
        fa_rows.append(row)
        det_rows += [{"diagnoser": name, **r} for r in d.detection]
        delay_rows += [{"diagnoser": name, **{k: v for k, v in r.items() if k != "values"}} for r in d.delays]
        sweep_rows += [{"diagnoser": name, **{k: v for k, v in r.items() if k != "interval"},
                        "rate_lower": r["interval"][0] if r["interval"] else None,
                        "rate_upper": r["interval"][1] if r["interval"] else None} for r in d.sweep]
        conf_path = out / f"confusion_{name}.csv"
        with open(conf_path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["injected \\ isolated as"] + d.confusion["columns"])
            for label, counts in zip(d.confusion["rows"], d.confusion["counts"]):
                w.writerow([label] + counts)
        files[f"confusion_{name}"] = conf_path
    for key, rows in (("false_alarms", fa_rows), ("detection", det_rows), ("delays", delay_rows),
                      ("sweep", sweep_rows), ("runs", figures.run_rows)):
        files[key] = _csv(out / f"{key}.csv", rows)
    if point_rows:
        files["operating_points"] = _csv(out / "operating_points.csv", point_rows)
    files["report"] = out / "report.html"
    files["report"].write_text(_html(figures), encoding="utf-8")
    return files


def _csv(path: Path, rows: list) -> Path:
    cols = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, cols)
        w.writeheader()
        w.writerows(rows)
    return path


def _png(fig) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return f'<img alt="plot" src="data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}">'


def _fmt(x, digits=4) -> str:
    if x is None:
        return "–"
    if isinstance(x, float):
        if math.isinf(x):
            return "∞"
        return f"{x:.{digits}g}"
    return html.escape(str(x))


def _table(header, rows) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{_fmt(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _html(fig: CampaignFigures) -> str:
    pct = f"{fig.confidence:.0%}"
    planned = fig.planned if fig.planned is not None else fig.runs
    parts = [f"<h1>Campaign {html.escape(fig.name)}</h1>"]
    if fig.runs < planned or fig.interrupted:
        parts.append(f"<p class='banner'>Partial campaign: {fig.runs} of {planned} planned runs finished "
                     f"(stopped before the end; run again with --resume to finish it). Every figure below "
                     f"describes the finished runs only.</p>")
    parts.append(f"<p>{fig.runs} of {planned} planned runs, {len(fig.failed)} failed; intervals are exact "
                 f"(Clopper–Pearson) at {pct} confidence; step h = {fig.step:g} s; target false-alarm rate "
                 f"{fig.target_rate:g} per sample.</p>")
    parts += [f"<p class='note'>{html.escape(w)}</p>" for w in fig.warnings]
    parts.append(_settings_html(fig.settings))
    if fig.points:
        parts.append(_envelope_html(fig))
    if fig.failed:
        parts.append("<h2>Failed runs</h2>" + _table(["run", "error"], [[f["run"], f["error"]] for f in fig.failed]))
    for name, d in fig.diagnosers.items():
        parts.append(f"<h2>Diagnoser {html.escape(name)}</h2>")
        parts += [f"<p class='note'>{html.escape(n)}</p>" for n in d.notes]
        fa = d.false_alarms
        if fa["samples"]:
            parts.append("<h3>False alarms</h3>" + _table(
                ["fault-free samples", "alarmed samples", "rate per sample", f"{pct} interval", "alarm onsets",
                 "MTBFA (s)", f"{pct} interval (s)"],
                [[fa["samples"], fa["alarm_samples"], fa["rate"],
                  f"[{_fmt(fa['interval'][0])}, {_fmt(fa['interval'][1])}]", fa["onsets"], fa["mtbfa"],
                  f"[{_fmt(fa['mtbfa_interval'][0])}, {_fmt(fa['mtbfa_interval'][1])}]"]]))
        if d.detection:
            parts.append("<h3>Detection probability against fault size</h3>"
                         "<p>Fault magnitude in the units of the faulted variable (its offset, factor or rate as "
                         "the fault kind says).</p>" + _detection_plot(d) + _table(
                ["target", "kind", "magnitude", "runs", "detected", "probability", f"{pct} interval"],
                [[r["target"], r["kind"], r["magnitude"], r["runs"], r["detected"], r["probability"],
                  f"[{_fmt(r['lower'])}, {_fmt(r['upper'])}]"] for r in d.detection]))
            parts.append("<h3>Detection delay</h3>" + _delay_plot(d) + _table(
                ["target", "magnitude", "detected", "min", "10 %", "median", "90 %", "max"],
                [[r["target"], r["magnitude"], r["detected"], r.get("min"), r.get("p10"), r.get("median"),
                  r.get("p90"), r.get("max")] for r in d.delays]))
            c = d.confusion
            parts.append("<h3>Isolation (runs by injected fault and verdict)</h3>"
                         "<p>The verdict is the isolation the diagnoser held longest while it alarmed in the faulty "
                         "part; <b>none</b>: the fault raised no alarm there; <b>unknown</b>: alarms without an "
                         "isolation (isolated_fault = −1).</p>" + _confusion_plot(d) + _table(
                ["injected \\ isolated as"] + c["columns"], [[r] + counts for r, counts in zip(c["rows"], c["counts"])]))
        if d.sweep:
            ch = d.choice
            text = (f"threshold_scale {ch['scale']:.4g} meets the target: rate {ch['rate']:.3g} per sample, upper "
                    f"{pct} bound {ch['upper']:.3g} ≤ {fig.target_rate:g}; detection probability "
                    f"{_fmt(ch['detection'])}" if ch["scale"] is not None else html.escape(ch["reason"]))
            parts.append(f"<h3>Threshold sweep</h3><p>{text} (scales relative to the campaign's thresholds). "
                         f"The shaded band reaches the one-sided upper {pct} bound of the table; a rate of 0 is "
                         f"drawn at 0 (the axis is linear below one alarm in the fault-free samples).</p>"
                         + _sweep_plot(d, fig) + _table(
                             ["scale", "alarmed samples", "rate", f"upper {pct} bound", "onsets", "detection"],
                             [[r["scale"], r["fa_samples"], r["rate"], r["upper"], r["fa_onsets"], r["detection"]]
                              for r in d.sweep]))
    if fig.run_rows:
        header = list(dict.fromkeys(k for r in fig.run_rows for k in r if k != "key"))
        shown = fig.run_rows[:_RUNS_SHOWN]
        more = (f"<p>The first {_RUNS_SHOWN} of {len(fig.run_rows)} runs; all are in runs.csv.</p>"
                if len(fig.run_rows) > _RUNS_SHOWN else "<p>Also in runs.csv.</p>")
        parts.append("<h2>Runs</h2>" + more + _table(header, [[r.get(h) for h in header] for r in shown]))
    style = ("body{font-family:sans-serif;max-width:1400px;margin:auto;padding:0 12px}img{max-width:100%}"
             "table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #bbb;padding:2px 6px;"
             "text-align:right}.note{color:#a40}.banner{background:#fde2c8;border:2px solid #c60;padding:8px;"
             "font-weight:bold}")
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(fig.name)}</title>"
            f"<style>{style}</style></head><body>{''.join(parts)}</body></html>")


_RUNS_SHOWN = 500


def _envelope_html(fig: CampaignFigures) -> str:
    """False alarms, detection and isolation per operating point, the diagnosers side by side."""
    pct = f"{fig.confidence:.0%}"
    names = [n for n, d in fig.diagnosers.items() if d.by_point]
    if not names:
        return ""

    def cell(p, lo_hi):
        return "–" if p is None else f"{_fmt(p)} [{_fmt(lo_hi[0])}, {_fmt(lo_hi[1])}]"

    header = ["operating point"]
    for n in names:
        header += [f"{n}: false-alarm rate [{pct}]", f"{n}: detection [{pct}]", f"{n}: isolation [{pct}]"]
    rows = []
    for j, label in enumerate(fig.points):
        row = [f"{j + 1}: {label}"]
        for n in names:
            r = fig.diagnosers[n].by_point[j]
            row += [cell(r["rate"], r["interval"] or (None, None)) + f" ({r['alarm_samples']} of {r['samples']})",
                    cell(r["detection"], r["detection_interval"] or (None, None)) + f" ({r['detected']} of "
                                                                                    f"{r['faulty_runs']})",
                    cell(r["isolation"], r["isolation_interval"] or (None, None))]
        rows.append(row)
    return ("<h2>Across the operating envelope</h2><p>Per operating point: the false-alarm rate per fault-free "
            f"sample, the share of faulty runs detected and the share isolated as the injected fault, with exact "
            f"{pct} intervals, for every diagnoser on the same runs.</p>" + _envelope_plot(fig, names)
            + _table(header, rows))


def _envelope_plot(fig: CampaignFigures, names) -> str:
    import matplotlib.pyplot as plt

    f, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.5))
    x = list(range(1, len(fig.points) + 1))
    for i, n in enumerate(names):
        rows = fig.diagnosers[n].by_point
        shift = (i - (len(names) - 1) / 2) * 0.06
        fa = [(j + shift, r["rate"], r["interval"]) for j, r in zip(x, rows) if r["rate"] is not None]
        if fa:
            a1.errorbar([p[0] for p in fa], [p[1] for p in fa], capsize=3, marker="o", label=n,
                        yerr=[[p[1] - p[2][0] for p in fa], [p[2][1] - p[1] for p in fa]])
        det = [(j + shift, r["detection"], r["detection_interval"]) for j, r in zip(x, rows)
               if r["detection"] is not None]
        if det:
            a2.errorbar([p[0] for p in det], [p[1] for p in det], capsize=3, marker="s", label=n,
                        yerr=[[p[1] - p[2][0] for p in det], [p[2][1] - p[1] for p in det]])
    samples = [r["samples"] for n in names for r in fig.diagnosers[n].by_point if r["samples"]]
    a1.set_yscale("symlog", linthresh=1.0 / max(max(samples, default=1), 1))
    a1.set_ylim(bottom=0.0)
    a1.set_ylabel("false-alarm rate per sample (linear below one alarm)", fontsize=10)
    a2.set_ylabel("detection probability", fontsize=10)
    a2.set_ylim(-0.05, 1.05)
    for ax in (a1, a2):
        ax.set_xticks(x, [str(j) for j in x])
        ax.set_xlabel("operating point (numbered as in the table)", fontsize=10)
        ax.tick_params(labelsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=9)
    return _png(f)


def _settings_html(settings: dict) -> str:
    """The campaign's set-up as tables: simulation, sample and faults, analysis, FMUs (GUIDs)."""
    if not settings:
        return ""
    sim, sample, fault = settings["simulation"], settings["sample"], settings["fault"]
    rows = [["simulation", f"start {sim['start']:g} s, stop {sim['stop']:g} s, step {sim['step']:g} s, "
                           f"order {sim['order']}"],
            ["sampling", ", ".join(f"{k} = {v}" for k, v in sample.items())],
            ["fault kinds", _dim(fault["kind"])], ["fault targets", _dim(fault["target"]) or "none"],
            ["fault magnitudes", _dim(fault["magnitude"])], ["fault onsets (s)", _dim(fault["onset"])],
            ["fault durations (s)", _dim(fault["duration"]).replace("inf", "permanent")]]
    rows += [[f"fault {x}", fault[x]] for x in ("ramp", "period") if x in fault]
    rows.append(["parameters (every run)", ", ".join(f"{k} = {v}" for k, v in settings["parameters"].items())
                 or "none (the FMUs' start values)"])
    a = settings["analysis"]
    rows.append(["analysis", f"confidence {a['confidence']:g}, target false-alarm rate {a['false_alarm_rate']:g} "
                             f"per sample, scales {a['scales']['min']:g} … {a['scales']['max']:g} "
                             f"({a['scales']['count']} + 1), scored from "
                             + ("the start" if a["zone_start"] is None else f"{a['zone_start']:g} s")])
    for name, table in settings.get("diagnosers", {}).items():
        rows.append([f"diagnoser {name}", ", ".join(f"{k} = {v}" for k, v in table.items())])
    fmus = _table(["instance", "file", "model", "FMI", "GUID"],
                  [[n, f["file"], f["model"], f["fmi"], f["guid"]] for n, f in settings["fmus"].items()])
    body = "".join(f"<tr><th>{html.escape(str(k))}</th><td style='text-align:left'>{html.escape(str(v))}</td></tr>"
                   for k, v in rows)
    return f"<h2>Settings</h2><table class='settings'>{body}</table>{fmus}"


def _dim(value) -> str:
    if isinstance(value, dict):
        return f"{value['min']:g} … {value['max']:g} ({value['scale']})"
    return ", ".join("inf" if v is None else (f"{v:g}" if isinstance(v, float) else str(v)) for v in value)


def _magnitude_axis(values):
    """x positions of fault magnitudes: the values themselves, or their ranks when they do not
    fit a readable linear axis (|x| > 1e100 or not finite)."""
    xs = sorted(set(values))
    if all(math.isfinite(v) and abs(v) <= 1e100 for v in xs):
        return (lambda v: v), None
    pos = {v: i for i, v in enumerate(xs)}
    return (lambda v: pos[v]), ([pos[v] for v in xs], [f"{v:.3g}" for v in xs])


def _detection_plot(d) -> str:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(11, 4.5))
    at, ticks = _magnitude_axis([r["magnitude"] for r in d.detection])
    targets = list(dict.fromkeys(r["target"] for r in d.detection))
    span = [at(r["magnitude"]) for r in d.detection]
    width = (max(span) - min(span)) or 1.0
    markers = "osD^v<>p*h"
    for i, target in enumerate(targets):
        rows = [r for r in d.detection if r["target"] == target]
        shift = (i - (len(targets) - 1) / 2) * 0.012 * width  # side by side, so no curve hides another
        x = [at(r["magnitude"]) + shift for r in rows]
        p = [r["probability"] for r in rows]
        err = [[pi - r["lower"] for pi, r in zip(p, rows)], [r["upper"] - pi for pi, r in zip(p, rows)]]
        ax.errorbar(x, p, yerr=err, marker=markers[i % len(markers)], capsize=3, label=target)
    if ticks:
        ax.set_xticks(*ticks)
    ax.set_xlabel("fault magnitude (units of the faulted variable; curves offset slightly to stay apart)",
                  fontsize=10)
    ax.set_ylabel("detection probability", fontsize=10)
    ax.set_ylim(-0.05, 1.05)
    ax.tick_params(labelsize=9)
    ax.legend(fontsize=9)
    ax.grid(alpha=0.3)
    return _png(fig)


def _delay_plot(d) -> str:
    import matplotlib.pyplot as plt

    rows = [r for r in d.delays if r["values"]]
    if not rows:
        return ""
    fig, ax = plt.subplots(figsize=(11, 4.5))
    ax.boxplot([r["values"] for r in rows], whis=(0, 100))
    ax.set_xticks(range(1, len(rows) + 1), [f"{r['target'].split('.')[-1]}\n{r['magnitude']:.3g}" for r in rows],
                  fontsize=9 if len(rows) <= 16 else 7)
    ax.set_ylabel("detection delay (s)", fontsize=10)
    ax.tick_params(axis="y", labelsize=9)
    ax.grid(alpha=0.3)
    return _png(fig)


def _confusion_plot(d) -> str:
    import matplotlib.pyplot as plt
    import numpy as np

    c = d.confusion
    if not c["rows"]:
        return ""
    M = np.array(c["counts"], float)
    share = M / np.maximum(M.sum(axis=1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(2 + 1.0 * len(c["columns"]), 1.5 + 0.6 * len(c["rows"])))
    ax.imshow(share, cmap="Blues", vmin=0, vmax=1)
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            ax.text(j, i, f"{int(M[i, j])}", ha="center", va="center", fontsize=10,
                    color="white" if share[i, j] > 0.5 else "black")  # readable on dark and light cells
    ax.set_xticks(range(len(c["columns"])), c["columns"], rotation=45, ha="right", fontsize=9)
    ax.set_yticks(range(len(c["rows"])), c["rows"], fontsize=9)
    ax.set_xlabel("isolated as (none: no alarm; unknown: alarm, no isolation)", fontsize=9)
    ax.set_ylabel("injected", fontsize=10)
    return _png(fig)


def _sweep_plot(d, figures) -> str:
    """Rate against scale, and the ROC. The y (x) axis is symlog, linear below one alarmed sample
    in the N fault-free samples, so a rate of 0 sits at 0 and every band reaches the table's
    one-sided upper bound."""
    import matplotlib.pyplot as plt

    rows = [r for r in d.sweep if r["rate"] is not None]
    if not rows:
        return ""
    pct = f"{figures.confidence:.0%}"
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.5))
    s = [r["scale"] for r in rows]
    one = 1.0 / rows[0]["samples"]  # one alarmed sample
    a1.plot(s, [r["rate"] for r in rows], "o-", label="rate per sample (0 drawn at 0)")
    a1.fill_between(s, 0.0, [r["upper"] for r in rows], alpha=0.25, label=f"0 … one-sided upper {pct} bound")
    a1.axhline(figures.target_rate, color="r", ls="--", label="target")
    if d.choice["scale"] is not None:
        a1.axvline(d.choice["scale"], color="g", ls=":", label="chosen scale")
    a1.set_yscale("symlog", linthresh=one)
    a1.set_ylim(bottom=0.0)
    a1.set_xlabel("threshold scale", fontsize=10)
    a1.set_ylabel(f"false-alarm rate (linear below {one:.2g})", fontsize=10)
    a1.legend(fontsize=9)
    if any(r["detection"] is not None for r in rows):
        a2.plot([r["rate"] for r in rows], [r["detection"] or 0.0 for r in rows], "o-")
        a2.set_xscale("symlog", linthresh=one)
        a2.set_xlim(left=0.0)
        a2.set_xlabel(f"false-alarm rate per sample (linear below {one:.2g})", fontsize=10)
        a2.set_ylabel("detection probability", fontsize=10)
        a2.set_ylim(-0.05, 1.05)
        a2.set_title("ROC over threshold_scale", fontsize=10)
    for ax in (a1, a2):
        ax.tick_params(labelsize=9)
        ax.grid(alpha=0.3)
    return _png(fig)
