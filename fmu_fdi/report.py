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


def plot_diagnosis(result, path, *, prefix: str = "", title: str = "", fault_names=(), t_on=None) -> Path:
    """PNG of residuals, evaluations against thresholds, alarms and the isolation result.

    ``result`` is a structured array with ``time`` and the diagnostic outputs (optionally
    behind ``prefix``, e.g. ``"fdi."`` for a co-simulation result).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(result["time"])
    names = result.dtype.names
    groups = sorted(int(n.rsplit("_", 1)[1]) for n in names if n.startswith(f"{prefix}evaluation_"))
    residuals = sorted(int(n.rsplit("_", 1)[1]) for n in names if n.startswith(f"{prefix}residual_"))
    fig, axes = plt.subplots(len(groups) + 2, 1, figsize=(9, 2.0 * (len(groups) + 2)), sharex=True)
    ax = axes[0]
    for k in residuals:
        ax.plot(t, _field(result, f"residual_{k}", prefix), lw=0.8, label=f"residual_{k}")
    ax.set_ylabel("residuals")
    ax.legend(loc="upper left", fontsize=7, ncol=min(len(residuals), 6))
    for ax, g in zip(axes[1:], groups):
        ev = _field(result, f"evaluation_{g}", prefix)
        th = _field(result, f"threshold_{g}", prefix)
        al = _field(result, f"alarm_{g}", prefix).astype(bool)
        ax.plot(t, ev, lw=0.9, label=f"evaluation_{g}")
        ax.plot(t, th, "k--", lw=0.9, label=f"threshold_{g}")
        ax.fill_between(t, 0, 1, where=al, transform=ax.get_xaxis_transform(), color="tab:red", alpha=0.15,
                        label="alarm")
        ax.set_ylabel(f"group {g}")
        ax.legend(loc="upper left", fontsize=7)
    ax = axes[-1]
    iso = _field(result, "isolated_fault", prefix)
    ax.step(t, iso, where="post", color="tab:purple", label="isolated_fault")
    ax.step(t, _field(result, "fault_detected", prefix).astype(float) * 0.5, where="post", color="tab:red",
            lw=0.8, label="fault_detected (0.5)")
    if fault_names:
        ax.set_yticks([-1, 0] + list(range(1, len(fault_names) + 1)))
        ax.set_yticklabels(["unknown", "none"] + list(fault_names), fontsize=7)
    ax.legend(loc="upper left", fontsize=7)
    ax.set_xlabel("time (s)")
    if t_on is not None:
        for a in axes:
            a.axvline(t_on, color="gray", lw=0.8, ls=":")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


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
