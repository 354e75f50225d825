"""The campaign report: one self-contained HTML file (plots embedded as PNG) and the tables as CSV.

Files written to the output folder: ``report.html``; ``false_alarms.csv`` (one row per
diagnoser), ``detection.csv``, ``delays.csv``, ``sweep.csv`` (rows per diagnoser and target /
scale), ``confusion_<diagnoser>.csv``.
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
    fa_rows, det_rows, delay_rows, sweep_rows = [], [], [], []
    for name, d in figures.diagnosers.items():
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
                      ("sweep", sweep_rows)):
        files[key] = _csv(out / f"{key}.csv", rows)
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
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
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
    parts = [f"<h1>Campaign {html.escape(fig.name)}</h1>",
             f"<p>{fig.runs} runs, {len(fig.failed)} failed; intervals are exact (Clopper–Pearson) at {pct} "
             f"confidence; step h = {fig.step:g} s; target false-alarm rate {fig.target_rate:g} per sample.</p>"]
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
            parts.append("<h3>Detection probability against fault size</h3>" + _detection_plot(d) + _table(
                ["target", "kind", "magnitude", "runs", "detected", "probability", f"{pct} interval"],
                [[r["target"], r["kind"], r["magnitude"], r["runs"], r["detected"], r["probability"],
                  f"[{_fmt(r['lower'])}, {_fmt(r['upper'])}]"] for r in d.detection]))
            parts.append("<h3>Detection delay</h3>" + _delay_plot(d) + _table(
                ["target", "magnitude", "detected", "min", "10 %", "median", "90 %", "max"],
                [[r["target"], r["magnitude"], r["detected"], r.get("min"), r.get("p10"), r.get("median"),
                  r.get("p90"), r.get("max")] for r in d.delays]))
            c = d.confusion
            parts.append("<h3>Isolation (runs by injected fault and verdict)</h3>" + _confusion_plot(d) + _table(
                ["injected \\ isolated as"] + c["columns"], [[r] + counts for r, counts in zip(c["rows"], c["counts"])]))
        if d.sweep:
            ch = d.choice
            text = (f"threshold_scale {ch['scale']:.4g} meets the target: rate {ch['rate']:.3g} per sample, upper "
                    f"{pct} bound {ch['upper']:.3g} ≤ {fig.target_rate:g}; detection probability "
                    f"{_fmt(ch['detection'])}" if ch["scale"] is not None else html.escape(ch["reason"]))
            parts.append(f"<h3>Threshold sweep</h3><p>{text} (scales relative to the campaign's thresholds).</p>"
                         + _sweep_plot(d, fig) + _table(
                             ["scale", "alarmed samples", "rate", f"upper {pct} bound", "onsets", "detection"],
                             [[r["scale"], r["fa_samples"], r["rate"], r["upper"], r["fa_onsets"], r["detection"]]
                              for r in d.sweep]))
    style = ("body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;margin:8px 0}"
             "td,th{border:1px solid #bbb;padding:2px 6px;text-align:right}.note{color:#a40}")
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(fig.name)}</title>"
            f"<style>{style}</style></head><body>{''.join(parts)}</body></html>")


def _detection_plot(d) -> str:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 3.5))
    for target in dict.fromkeys(r["target"] for r in d.detection):
        rows = [r for r in d.detection if r["target"] == target]
        x = [r["magnitude"] for r in rows]
        p = [r["probability"] for r in rows]
        err = [[pi - r["lower"] for pi, r in zip(p, rows)], [r["upper"] - pi for pi, r in zip(p, rows)]]
        ax.errorbar(x, p, yerr=err, marker="o", capsize=3, label=target)
    ax.set_xlabel("fault magnitude")
    ax.set_ylabel("detection probability")
    ax.set_ylim(-0.05, 1.05)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return _png(fig)


def _delay_plot(d) -> str:
    import matplotlib.pyplot as plt

    rows = [r for r in d.delays if r["values"]]
    if not rows:
        return ""
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.boxplot([r["values"] for r in rows], whis=(0, 100))
    ax.set_xticks(range(1, len(rows) + 1), [f"{r['target'].split('.')[-1]}\n{r['magnitude']:.3g}" for r in rows],
                  fontsize=6)
    ax.set_ylabel("detection delay (s)")
    ax.grid(alpha=0.3)
    return _png(fig)


def _confusion_plot(d) -> str:
    import matplotlib.pyplot as plt
    import numpy as np

    c = d.confusion
    if not c["rows"]:
        return ""
    M = np.array(c["counts"], float)
    fig, ax = plt.subplots(figsize=(1 + 0.6 * len(c["columns"]), 1 + 0.4 * len(c["rows"])))
    ax.imshow(M / np.maximum(M.sum(axis=1, keepdims=True), 1), cmap="Blues", vmin=0, vmax=1)
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            ax.text(j, i, f"{int(M[i, j])}", ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(c["columns"])), c["columns"], rotation=60, fontsize=7)
    ax.set_yticks(range(len(c["rows"])), c["rows"], fontsize=7)
    ax.set_xlabel("isolated as")
    ax.set_ylabel("injected")
    return _png(fig)


def _sweep_plot(d, figures) -> str:
    import matplotlib.pyplot as plt

    rows = [r for r in d.sweep if r["rate"] is not None]
    if not rows:
        return ""
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.5))
    s = [r["scale"] for r in rows]
    floor = 0.5 / rows[0]["samples"]  # zero counts drawn at half a sample (log axis)
    a1.semilogy(s, [max(r["rate"], floor) for r in rows], "o-", label="rate per sample")
    a1.fill_between(s, [max(r["interval"][0], floor) for r in rows], [r["interval"][1] for r in rows], alpha=0.3,
                    label=f"{figures.confidence:.0%} interval")
    a1.axhline(figures.target_rate, color="r", ls="--", label="target")
    if d.choice["scale"] is not None:
        a1.axvline(d.choice["scale"], color="g", ls=":", label="chosen scale")
    a1.set_xlabel("threshold scale")
    a1.set_ylabel("false-alarm rate")
    a1.legend(fontsize=7)
    if any(r["detection"] is not None for r in rows):
        a2.semilogx([max(r["rate"], floor) for r in rows], [r["detection"] or 0.0 for r in rows], "o-")
        a2.set_xlabel("false-alarm rate per sample")
        a2.set_ylabel("detection probability")
        a2.set_title("ROC over threshold_scale", fontsize=9)
    for ax in (a1, a2):
        ax.grid(alpha=0.3)
    return _png(fig)
