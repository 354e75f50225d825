"""Plots and tables of diagnosis results (matplotlib, headless)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _field(result, name: str, prefix: str):
    names = result.dtype.names
    for cand in (f"{prefix}{name}", name):
        if cand in names:
            return np.asarray(result[cand])
    raise KeyError(f"no column {prefix}{name} or {name} in the result")


def fault_onsets(result) -> list[tuple[str, float]]:
    """``(fault name, first time active)`` from the ``fault.<name>.active`` columns."""
    t = np.asarray(result["time"])
    out = []
    for n in result.dtype.names:
        if n.startswith("fault.") and n.endswith(".active"):
            active = np.asarray(result[n]).astype(bool)
            if active.any():
                out.append((n[len("fault."):-len(".active")], float(t[active][0])))
    return out


_THRESHOLD_LABEL = {
    "fixed": "threshold (fixed)",
    "adaptive": "adaptive threshold\nJ0 + a·E(u - u0): rises\nwith the input excursion",
    "majorant": "adaptive threshold\nJ0 + E(bound on the inputs'\neffect): rises with the inputs",
}


def _with_unit(label: str, unit) -> str:
    return f"{label} [{unit}]" if unit else label


def plot_diagnosis(result, path, *, prefix: str = "", title=None, fault_names=(), t_on=None,
                   design: dict | None = None) -> Path:
    """Write :func:`diagnosis_figure` (same arguments) to ``path`` (PNG, SVG or PDF by its suffix); returns it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = diagnosis_figure(result, prefix=prefix, title=title, fault_names=fault_names, t_on=t_on, design=design)
    path = Path(path)
    try:
        fig.savefig(path, dpi=110)
    finally:
        plt.close(fig)
    return path


def diagnosis_figure(result, *, prefix: str = "", title=None, fault_names=(), t_on=None, design: dict | None = None):
    """Figure of residuals, evaluations against thresholds, alarms and the isolation result.

    Parameters
    ----------
    result : structured array
        ``time`` and the diagnostic outputs (optionally behind ``prefix``, e.g. ``"fdi."`` for
        a co-simulation result); ``fault.<name>.active`` columns mark the fault onsets.
    prefix : str
    title : str, optional
        Default: the diagnoser's name and method and the faults injected.
    fault_names : sequence of str, optional
        Names of the model's faults (1-based ``isolated_fault`` values); taken from
        ``design`` when given.
    t_on : float, optional
        A fault onset to mark when the result has no ``fault.*.active`` column.
    design : dict, optional
        The design: panels are named by the faults each group watches, axes get units,
        the isolation axis lists only the faults the design can isolate, thresholds say
        whether they are adaptive.

    Returns
    -------
    matplotlib.figure.Figure
        One panel of residuals, one per evaluation group, one of the isolation result;
        legends sit right of the axes, outside the data.
    """
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .designinfo import evaluation_unit, group_faults, isolable_faults, residual_unit

    t = np.asarray(result["time"])
    names = result.dtype.names
    groups = sorted(int(n.rsplit("_", 1)[1]) for n in names if n.startswith(f"{prefix}evaluation_"))
    residuals = sorted(int(n.rsplit("_", 1)[1]) for n in names if n.startswith(f"{prefix}residual_"))
    if design is not None:
        fault_names = [f["name"] for f in design["faults"]]
    watched = (group_faults(design) if design else None) or [[] for _ in groups]
    onsets = fault_onsets(result)
    if not onsets and t_on is not None:
        onsets = [("fault", float(t_on))]

    fig, axes = plt.subplots(len(groups) + 2, 1, figsize=(11, 2.1 * (len(groups) + 2)), sharex=True,
                             layout="constrained")

    def legend(ax):
        if not ax.get_legend_handles_labels()[0]:
            return  # nothing labelled on this panel (e.g. a log without residual columns)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0, fontsize=7, frameon=False)

    ax = axes[0]
    r_names = design["generator"]["residual_names"] if design else []
    for k in residuals:
        label = f"residual_{k}" + (f" ({r_names[k - 1]})" if k <= len(r_names) else "")
        ax.plot(t, _field(result, f"residual_{k}", prefix), lw=0.8, label=label)
    ax.set_ylabel(_with_unit("residuals", residual_unit(design) if design else None))
    ax.set_title("residuals", fontsize=8, loc="left")
    legend(ax)
    for ax, g in zip(axes[1:], groups):
        ev = _field(result, f"evaluation_{g}", prefix)
        th = np.asarray(_field(result, f"threshold_{g}", prefix), float)
        al = _field(result, f"alarm_{g}", prefix).astype(bool)
        # row 0 holds no diagnosis yet (its threshold reads 0): the threshold starts at row 1
        t_th, th = (t[1:], th[1:]) if th.size > 1 and th[0] == 0 and np.any(th[1:] != 0) else (t, th)
        spec = design["evaluation"][g - 1] if design and g <= len(design["evaluation"]) else None
        kind = spec["evaluator"]["kind"] if spec else "evaluation"
        ax.plot(t, ev, lw=0.9, label=f"{kind} of group {g}")
        if spec:
            th_label = _THRESHOLD_LABEL.get(spec["threshold"]["kind"], f"{spec['threshold']['kind']} threshold")
        else:
            th_label = "threshold (fixed)" if np.ptp(th) == 0 else "threshold (varies with the inputs: adaptive)"
        ax.plot(t_th, th, "k--", lw=0.9, label=th_label)
        ax.fill_between(t, 0, 1, where=al, transform=ax.get_xaxis_transform(), color="tab:red", alpha=0.15,
                        label=f"alarm_{g}")
        faults = watched[g - 1] if g <= len(watched) else []
        head = f"group {g}: watches {', '.join(faults)}" if faults else f"group {g}"
        ax.set_title(textwrap.shorten(head, 120, placeholder=" …"), fontsize=8, loc="left")
        ax.set_ylabel(_with_unit(kind, evaluation_unit(design, g - 1) if spec else None))
        legend(ax)
    ax = axes[-1]
    iso = _field(result, "isolated_fault", prefix)
    ax.step(t, iso, where="post", color="tab:purple", label="isolated_fault")
    ax.step(t, _field(result, "fault_detected", prefix).astype(float) * 0.5, where="post", color="tab:red",
            lw=0.8, label="fault_detected (drawn at 0.5)")
    if fault_names:
        shown = isolable_faults(design) if design else list(fault_names)
        ticks = {-1: "unknown / several", 0: "none"}
        ticks.update({fault_names.index(n) + 1: n for n in shown if n in fault_names})
        ticks.update({int(v): fault_names[int(v) - 1] for v in np.unique(iso)
                      if 0 < v <= len(fault_names)})  # never hide a value that occurs
        ax.set_yticks(sorted(ticks))
        ax.set_yticklabels([ticks[k] for k in sorted(ticks)], fontsize=7)
    ax.set_title("isolation (faults this design can isolate)" if design else "isolation", fontsize=8, loc="left")
    ax.set_xlabel("time [s]")
    for i, (name, when) in enumerate(onsets):
        for a in axes:
            a.axvline(when, color="gray", lw=0.9, ls=":", label=f"fault onset: {name}\nat t = {when:g} s"
                      if a is axes[-1] else None)
    legend(ax)
    if title is None:
        who = f"{design['name']} ({design['generator']['method']})" if design else "diagnosis"
        what = "; ".join(f"fault {n} from t = {w:g} s" for n, w in onsets) or "no fault injected"
        title = f"{who}: {what}"
    fig.suptitle(title, fontsize=10)
    return fig


def format_table(rows: list[dict], columns: list[tuple[str, str]]) -> str:
    """Fixed-width text table from dict rows; ``columns`` are (key, header) pairs."""
    cells = [[h for _, h in columns]] + [[_fmt(r.get(k)) for k, _ in columns] for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(columns))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "-" if not np.isfinite(v) else f"{v:g}"
    return str(v)
