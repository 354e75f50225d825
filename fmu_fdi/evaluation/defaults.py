"""Default threshold when nothing else is known: sized by the smallest fault to detect.

For a step fault of size F on fault j, residual group i settles at ``|Rf_ij(1)| F``
(discrete DC gain, block 2-norm); the evaluation functions settle at that value
(``norm``, ``rms``, ``ewrms``, ``peak``) or at ``(α + β / (1 - γ))`` times it (``narendra``).
The default threshold of group i is half the smallest settled evaluation over the faults
the group sees, so every step fault of size ≥ F is detected at steady state with a
factor-2 margin against modelling error. It assumes no noise or uncertainty: with
either, design the threshold (threshold_selector, analytic or data-driven thresholds).

A model with a noise model (noise inputs w, unit white: e.g. the innovation form an
identified model carries) knows more than fault sizes, and its default threshold comes from
that noise (:func:`default_thresholds`): per group the analytic threshold whose per-sample
false-alarm probability under the noise model is ``DEFAULT_RATE``,

    J_th,i = Q_i⁻¹(1 − DEFAULT_RATE)

(:func:`~fmu_fdi.evaluation.analytic_threshold`, Imhof's exact quantile of the evaluation's
quadratic form). The fault-size rule is unit-dependent (a "unit" fault is 1 cm on a tank level
but 1 rad on an aircraft's sideslip) and blind to noise: below the noise's threshold it alarms
without a fault, far above it it misses faults the noise would let through. The design prints
the smallest fault each group then detects at steady state (:mod:`.guidance`).
"""
from __future__ import annotations

import numpy as np

from ..errors import DesignError

#: per-sample false-alarm probability of the default threshold under a model's noise model
#: (one false alarm per 10⁵ samples before persistence: the order of the wind-turbine
#: benchmark's mean time between false alarms, 10⁵·Ts)
DEFAULT_RATE = 1e-5


def _settled_gain(evaluation: dict) -> float:
    kind = evaluation.get("kind")
    if kind in ("norm", "rms", "ewrms", "peak"):
        return 1.0
    if kind == "narendra":
        g = float(evaluation.get("gamma", 0.9))
        return float(evaluation.get("alpha", 0.0)) + float(evaluation.get("beta", 1.0)) / (1.0 - g)
    raise DesignError(f"no fault-size default for the '{kind}' evaluation (a statistical test): give a threshold")


def fault_size_thresholds(gen, evaluation: dict | list, size: float = 1.0) -> list[float]:
    """One fixed threshold per residual group (see module docstring); ``gen`` discrete."""
    if not gen.dt:
        raise DesignError("fault_size_thresholds needs the discrete generator")
    if not (size > 0 and np.isfinite(size)):
        raise DesignError(f"fault size must be positive, got {size!r}")
    model = gen.model
    if not model.faults:
        raise DesignError("the model has no faults to size a threshold by: give a threshold")
    evals = evaluation if isinstance(evaluation, list) else [evaluation] * len(gen.groups)
    out = []
    for i, settled in enumerate(settled_fault_gains(gen)):
        seen = [v for v in settled if v > 1e-9 * max(settled + [1e-300])]
        if not seen:
            raise DesignError(f"residual group {i + 1} has zero steady-state response to every fault: "
                              f"give a threshold")
        out.append(0.5 * size * min(seen) * _settled_gain(evals[i]))
    return out


def settled_fault_gains(gen) -> list[list[float]]:
    """Per residual group, per fault of the model: ``||Rf_ij(1)||``, the settled residual of that
    group per unit step fault (discrete DC gain, block 2-norm); ``gen`` discrete."""
    model = gen.model
    dc = gen.Rf.dcgain() if gen.Rf.m else np.zeros((gen.Q.p, 0))
    return [[float(np.linalg.norm(dc[np.ix_(grp, np.arange(model.nf)[f.columns])], 2)) for f in model.faults]
            for grp in gen.groups]


def default_thresholds(gen, evaluation: dict | list, size: float = 1.0) -> tuple[list[float], list[str]]:
    """The threshold per residual group when none is given, and for each a phrase saying what set
    it (module docstring): the analytic threshold at ``DEFAULT_RATE`` under the model's noise
    inputs (w unit white) when the model has them and the group's evaluation is quadratic
    (``norm``, ``rms``, ``ewrms``, ``chi2``), else ``fault_size_thresholds(gen, evaluation, size)``;
    ``gen`` discrete."""
    from .analytic import analytic_threshold

    evals = evaluation if isinstance(evaluation, list) else [evaluation] * len(gen.groups)
    out, why, sized = [], [], None
    for i in range(len(gen.groups)):
        noise = None
        if gen.model.nw:
            try:
                noise = analytic_threshold(gen, evals[i], DEFAULT_RATE, noise_cov=np.eye(gen.model.nw), group=i)
            except ValueError:  # an evaluation without a closed-form distribution (peak, narendra)
                noise = None
        if noise is not None:
            out.append(float(noise))
            why.append(f"the model's noise (analytic:{DEFAULT_RATE:g}: false alarms {DEFAULT_RATE:g} per sample)")
            continue
        sized = fault_size_thresholds(gen, evals, size) if sized is None else sized
        out.append(float(sized[i]))
        why.append(f"fault-size:{size:g} (" + ("the model has no noise model" if not gen.model.nw else
                                               f"no noise quantile for a '{evals[i].get('kind')}' evaluation") + ")")
    return out, why
