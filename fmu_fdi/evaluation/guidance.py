"""What a design's thresholds mean under the model's noise: false-alarm rate and smallest fault.

For residual group i with threshold ``J_th`` and a quadratic evaluator (``norm``, ``rms``,
``ewrms``: ``J = sqrt(Q)``; ``chi2``: ``J = Q``), the per-sample false-alarm probability in
fault-free stationary operation with the model's noise inputs w unit white is

    α_i = P(J ≥ J_th) = P(Q ≥ J_th²)    (Q = Σ λ_j χ²_1, Imhof 1961),

computed from the exact residual autocovariance (:mod:`.covariance`) as in
:func:`~fmu_fdi.evaluation.analytic_threshold`, whose quantile this inverts; for a stacked
window longer than ``EXACT_SIZE`` values, the Satterthwaite match ``g χ²_h`` of its mean and
variance (its tail is lighter than Q's: α is then underestimated, by up to ×5 at 1e-4 for
strongly correlated residuals, see analytic_threshold).

The smallest step fault of each kind the group detects at steady state is
``J_th / (||Rf_ij(1)|| · s)``, with s the evaluator's settled gain (1 for ``norm``, ``rms``,
``ewrms``, ``peak``; :mod:`.defaults`): the settled evaluation of a fault of that size equals
the threshold. Noise adds to it, so a fault of this size is detected about half the time.

A threshold whose α exceeds ``WARN_RATE`` lies within the noise: the diagnoser will alarm
without a fault (the warning states the rate and the mean time between false alarms).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

WARN_RATE = 1e-3
#: largest stacked window (samples × residuals) whose eigenvalues are computed for the exact tail;
#: beyond it the Satterthwaite match (a guidance printed at every design must stay cheap)
EXACT_SIZE = 400


@dataclass
class GroupGuidance:
    """One residual group: its threshold, α (None without a noise model or for a non-quadratic
    evaluator), the smallest detectable step fault per fault name (None: not seen) and the
    group's index (0-based)."""

    threshold: float
    alpha: float | None
    smallest: dict
    group: int = 0


def false_alarm_probability(gen, evaluation: dict, threshold: float, group: int) -> float | None:
    """``P(J ≥ threshold)`` per sample under the model's w unit white noise (module docstring)."""
    from ..runtime.evaluation import Evaluator
    from .analytic import _eigenvalues, _moments, _weights_of
    from .covariance import group_rows, residual_covariance
    from .quadform import imhof_sf

    if not gen.model.nw:
        return None
    rows = group_rows(gen, group)
    ev = Evaluator(evaluation, len(rows))
    if ev.kind not in ("norm", "rms", "ewrms", "chi2"):
        return None
    cov = residual_covariance(gen, noise_cov=np.eye(gen.model.nw), group=group)
    if ev.kind == "chi2":
        cov = cov.weighted(ev.W)
    x = float(threshold) if ev.kind == "chi2" else float(threshold) ** 2
    c = _weights_of(ev, truncate=True)
    if c is not None and c.size * len(rows) <= EXACT_SIZE:
        return float(imhof_sf(x, _eigenvalues(cov, ev)))
    mean, var = _moments(cov, ev)
    g, h = var / (2 * mean), 2 * mean * mean / var
    return float(stats.chi2.sf(x / g, h))


def threshold_guidance(gen, evaluation, thresholds) -> list[GroupGuidance]:
    """Per residual group of a discrete ``gen`` with a fixed threshold (a number or a
    ThresholdEstimate; adaptive thresholds are left out): :class:`GroupGuidance` (module docstring)."""
    from .defaults import _settled_gain, settled_fault_gains

    evals = evaluation if isinstance(evaluation, list) else [evaluation] * len(gen.groups)
    ths = list(thresholds) if isinstance(thresholds, (list, tuple, np.ndarray)) else [thresholds] * len(gen.groups)
    out = []
    for i, gains in enumerate(settled_fault_gains(gen)):
        th = _fixed_value(ths[i])
        if th is None:  # an adaptive threshold: no single value to judge
            continue
        try:
            s = _settled_gain(evals[i])
        except Exception:  # a statistical test: no settled value
            s = None
        smallest = {f.name: (th / (g * s) if s and g > 1e-12 * max(gains + [1e-300]) else None)
                    for f, g in zip(gen.model.faults, gains)}
        out.append(GroupGuidance(th, false_alarm_probability(gen, evals[i], th, i), smallest, i))
    return out


def _fixed_value(t) -> float | None:
    """The value of a fixed threshold (a number or a ThresholdEstimate's ``value``), else None."""
    t = getattr(t, "value", t)
    try:
        return float(t)
    except (TypeError, ValueError):
        return None


def describe(gen, guidance, emit=print, warn=None) -> None:
    """Lines per group: threshold, α and mean samples between false alarms, smallest faults; a warning
    (to ``warn``) for each group whose α exceeds WARN_RATE."""
    for g in guidance:
        i = g.group
        far = ("no noise model: false-alarm rate unknown" if g.alpha is None else
               f"false alarms {g.alpha:.2g} per sample (one per {1 / max(g.alpha, 1e-300):.3g} samples = "
               f"{gen.dt / max(g.alpha, 1e-300):.3g} s) under the model's noise")
        small = ", ".join(f"{k} {v:.3g}" for k, v in g.smallest.items() if v is not None) or "none"
        emit(f"group {i + 1}: threshold {g.threshold:.4g}, {far}; smallest step fault detected: {small}")
        if g.alpha is not None and g.alpha > WARN_RATE and warn is not None:
            warn(f"warning: group {i + 1}'s threshold {g.threshold:.4g} lies within the noise: {g.alpha:.2g} false "
                 f"alarms per sample; raise it (e.g. --threshold analytic:1e-5 sizes it from the noise model)")
