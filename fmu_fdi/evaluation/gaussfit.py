"""A threshold from a fault-free log too short for the evaluation's tail: a Gaussian fit.

Why a log can be too short. A per-sample false-alarm rate α read off the evaluation J needs
independent draws of J: J is thinned to every L-th sample (L its decorrelation length,
:func:`~fmu_fdi.evaluation.datadriven.decorrelation_length`), leaving ``n = T/L`` effective
samples of a log of T. The distribution-free bound (the largest of n samples is an upper
γ-confidence bound of the ``1 − α`` quantile) exists when ``1 − (1 − α)^n ≥ γ``, i.e.

    n ≥ ln(1 − γ) / ln(1 − α)        (α = 1e-3, γ = 0.95: n ≥ 2995, a log of 2995·L);

the peaks-over-threshold fit needs ``2·MIN_EXCESSES = 60`` effective samples (a log of 60·L).
A moving-window evaluator makes L long (a window of N samples alone gives L ≈ N; a slow
residual more), so a log of a few thousand samples can hold fewer than 60.

The Gaussian fit. J's correlation comes from its window; the residual r itself decorrelates
much sooner, and its second moments — not a tail — are what is estimated. Under the
hypothesis the design rests on (a linear plant driven by Gaussian noise: r is a stationary
Gaussian sequence), J of the quadratic evaluators is a function of the Gaussian quadratic
form ``Q = Σ_i c_i ||M r(k−i)||²`` (:mod:`.analytic`), whose distribution is fixed by the
autocovariance Γ(0..N−1) of r: here estimated from the log,

    Γ̂(k) = (1/T) Σ_t r(t) r(t−k)ᵀ

(about zero, not the sample mean: a bias in the log raises Q as it raises J; the 1/T form
keeps the stacked window covariance positive semidefinite). The threshold is the exact
``1 − α`` quantile of Q (Imhof 1961) mapped through J, like :func:`analytic_threshold`.
Confidence: Γ̂'s level is a mean of ``||r||²`` over ``n_r = T / L_r`` effective samples
(L_r: the decorrelation length of ``||r||²``); for Gaussian r, ``n_r Γ̂ / Γ`` is close to
χ²(n_r) in scale, so Γ̂ · ``n_r / χ²_{1−γ}(n_r)`` is an upper γ-confidence bound of the level
(the classical interval of a variance), and the threshold is computed from it. The shape of
the spectrum is taken as estimated. The result is only as good as the Gaussian hypothesis:
it is marked ``method = "gaussian"`` with that assumption in the design's info.
"""
from __future__ import annotations

import numpy as np
from scipy import stats

from ..runtime.evaluation import Evaluator
from .analytic import _eigenvalues, _quantile
from .datadriven import ShortLogError, ThresholdEstimate, data_driven_threshold, decorrelation_length
from .quadform import imhof_quantile

#: fewest effective residual samples a Gaussian fit is made from: the level bound's factor
#: n_r / χ²_{0.05}(n_r) is then at most 2.54 (a threshold ≤ 59 % above the point estimate for
#: rms/norm); 30 samples: 1.62 (27 %), 100: 1.29 (14 %)
MIN_RESIDUAL_SAMPLES = 10
KINDS = ("norm", "rms", "ewrms", "peak", "chi2")


class _LogCovariance:
    """The autocovariance of a residual record, in the shape :mod:`.analytic` reads (``lags``)."""

    def __init__(self, r: np.ndarray, scale: float):
        self.r, self.scale = r, scale
        self.Gamma0 = scale * (r.T @ r) / r.shape[0]

    @property
    def dim(self) -> int:
        return self.r.shape[1]

    def lags(self, max_lag: int) -> np.ndarray:
        T = self.r.shape[0]
        out = np.zeros((max_lag + 1, self.dim, self.dim))
        for k in range(min(max_lag, T - 1) + 1):  # Γ(k) = E r(t) r(t−k)ᵀ, biased (1/T): PSD block Toeplitz
            out[k] = self.scale * (self.r[k:].T @ self.r[:T - k]) / T
        return out

    def weighted(self, W) -> "_LogCovariance":
        return _LogCovariance(self.r @ np.asarray(W, float).T, self.scale)


def gaussian_threshold(residuals, evaluation: dict, rate: float, confidence: float = 0.95, *,
                       skip: int = 0) -> ThresholdEstimate:
    """Threshold with false-alarm rate ``rate`` for Gaussian residuals, from a short fault-free log.

    Parameters
    ----------
    residuals : array_like, (T,) or (T, p)
        The residual group's fault-free record (the generator run on the log).
    evaluation : dict
        Evaluator spec (``norm``, ``rms``, ``ewrms``, ``peak`` or ``chi2``).
    rate, confidence : float
        Per-sample false-alarm rate α and the confidence γ of the level bound (module docstring).
    skip : int
        Samples dropped at the start (the generator's transient).

    Returns
    -------
    ThresholdEstimate
        ``method="gaussian"``; ``n_effective`` = n_r, ``decorrelation_length`` = L_r;
        ``details``: ``level_factor`` (n_r / χ²_{1−γ}(n_r)), ``assumption``.

    Raises
    ------
    ValueError
        Another evaluator, a constant record, or fewer than ``MIN_RESIDUAL_SAMPLES``
        effective residual samples (the message says how long a log is needed).
    """
    rate, confidence = float(rate), float(confidence)
    if not (0.0 < rate < 1.0 and 0.0 < confidence < 1.0):
        raise ValueError(f"rate and confidence must be in (0, 1), got {rate}, {confidence}")
    r = np.asarray(residuals, float)
    r = r[:, None] if r.ndim == 1 else r
    r = r[int(skip):]
    if r.ndim != 2 or r.shape[0] < 2 or not np.all(np.isfinite(r)):
        raise ValueError("the residual record must be a finite (T, p) array with T ≥ 2 after skip")
    ev = Evaluator(evaluation, r.shape[1])  # validates the spec as the runtime does
    if ev.kind not in KINDS:
        raise ValueError(f"no Gaussian fit for the '{ev.kind}' evaluator (not a function of a quadratic form)")
    energy = np.sum(r * r, axis=1)
    L = decorrelation_length([energy])
    n = r.shape[0] // L
    if n < MIN_RESIDUAL_SAMPLES:
        raise ShortLogError(f"{n} effective residual samples (the residual's energy stays correlated over {L} samples "
                         f"of the {r.shape[0]}): a Gaussian fit needs {MIN_RESIDUAL_SAMPLES}, a fault-free log of "
                            f"at least about {MIN_RESIDUAL_SAMPLES * L} samples", MIN_RESIDUAL_SAMPLES * L)
    factor = float(n / stats.chi2.ppf(1.0 - confidence, n))
    point, value = (_threshold(_LogCovariance(r, s), ev, rate) for s in (1.0, factor))
    return ThresholdEstimate(value=value, method="gaussian", rate=rate, confidence=confidence, point=point,
                             n_samples=int(r.shape[0]), n_effective=int(n), decorrelation_length=int(L),
                             details={"level_factor": factor, "assumption": "Gaussian stationary residual: the exact "
                                      "quantile of the evaluation's quadratic form under the residual autocovariance "
                                      "estimated from the log, its level raised to a one-sided confidence bound"})


def _threshold(cov: _LogCovariance, ev: Evaluator, rate: float) -> float:
    if ev.kind == "peak":  # union bound over the window, as analytic_threshold
        return float(np.sqrt(imhof_quantile(rate / ev.n, _eigenvalues(cov, Evaluator({"kind": "norm"}, ev.dim)))))
    if ev.kind == "chi2":
        return float(_quantile(cov.weighted(ev.W), ev, rate, "exact"))
    return float(np.sqrt(_quantile(cov, ev, rate, "exact")))


def log_threshold(evaluations, residuals, evaluation: dict, rate: float, confidence: float = 0.95, *,
                  skip: int = 0) -> ThresholdEstimate:
    """``data:RATE``: the threshold from a fault-free log. The evaluation's own tail when the log
    holds enough effective samples of it (:func:`~fmu_fdi.evaluation.data_driven_threshold`:
    distribution-free, else a GPD tail fit); when it does not, the Gaussian fit of
    :func:`gaussian_threshold` on the residuals, its ``details["short_log"]`` saying why; when
    neither can be made, a :class:`ShortLogError` with both reasons and the longer log needed."""
    try:
        return data_driven_threshold(evaluations, rate, confidence, skip=skip)
    except ShortLogError as short:
        try:
            est = gaussian_threshold(residuals, evaluation, rate, confidence, skip=skip)
        except ShortLogError as also:
            raise ShortLogError(f"{short}; a Gaussian fit of the residuals cannot be made either: {also}",
                                max(short.needed or 0, also.needed or 0) or None) from None
        except ValueError as other:
            raise ShortLogError(f"{short} (and {other})", short.needed) from None
        return ThresholdEstimate(**{**est.__dict__, "details": {**est.details, "short_log": str(short)}})
