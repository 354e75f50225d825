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
Confidence: the whole estimate Γ̂(0..N−1) — its level *and* its shape — varies from log to
log, and the quantile with it. Its sampling law is that of the sample autocovariances of a
Gaussian sequence (Bartlett's formula, Brockwell & Davis 1991, Thm 7.2.1: it depends on the
autocovariance at all lags, not only the window's), reproduced by a *spectral parametric
bootstrap*: B Gaussian records of the log's length are drawn from the lag-window spectral
estimate

    Ŝ(ω) = Σ_{|k|≤M} w(k/M) Γ̂(k) e^{−iωk}    (Parzen window w: Ŝ ⪰ 0; Brockwell & Davis §10.4)

(circulant embedding: the FFT of white noise shaped by Ŝ(ω)^{1/2}; Davison & Hinkley 1997,
§8.3; Dahlhaus & Janas 1996), each record's Γ̂* is estimated as the log's was, and the
threshold functional q(·) (Satterthwaite's moment-matched quantile, cheap and with the exact
quantile's sensitivity to the moments) is evaluated on it. With Γ̃ the bootstrap world's true
autocovariance (w(k/M) Γ̂(k)), the pivot ``D = ln q(Γ̂*) − ln q(Γ̃)`` has nearly the law of
``ln q(Γ̂) − ln q(Γ)``, so the *basic* bootstrap bound (Davison & Hinkley §5.2)

    J_th = q̂ · exp(−D_{(1−γ)}),       q̂ the exact (Imhof) quantile under Γ̂,

would cover the true quantile with probability γ if D were an exact pivot. It is not: the
log's own autocovariance estimate sets both q̂ and the bootstrap world, so a log that
underestimates the correlation has a low q̂ *and* a narrow D (the basic bootstrap's coverage
error is of order n^{−1/2}, Hall 1992, *The Bootstrap and Edgeworth Expansion*, §3.5). Measured
(benchmarks/threshold_coverage.py; AR(1) pole 0.9, rms:20, 1e-3, 3000-6000 samples): the
one-sided D_{(1−γ)} covered 123 of 140 logs (88 %) though the bootstrap law of D matched the
true one (sd 0.059 vs 0.057, 5 % quantile −0.100 vs −0.094 over 1000 records); a batch-means
bootstrap-t did no better. The bound is therefore read at the two-sided interval's upper end,
``D_{((1−γ)/2)}`` (:func:`calibrated_level`), which the benchmark measures at or above γ. M spans five decorrelation lengths of r (at
least four windows, at most T/4), so the bootstrap world keeps the correlations that make
Γ̂ vary. A log of fewer than ``MIN_RESIDUAL_SAMPLES`` effective residual samples (n_r = T/L_r,
L_r the decorrelation length of ``||r||²``) is refused. The result is only as good as the
Gaussian hypothesis: it is marked ``method = "gaussian"`` with that assumption in the design's
info.

References: P. J. Brockwell, R. A. Davis, *Time Series: Theory and Methods*, 2nd ed., Springer
1991, §7.2, §10.4. A. C. Davison, D. V. Hinkley, *Bootstrap Methods and their Application*,
CUP 1997, §5.2, §8.3. R. Dahlhaus, D. Janas, "A frequency domain bootstrap for ratio
statistics in time series analysis", Ann. Statist. 24 (1996) 1934-1963. J. P. Imhof,
Biometrika 48 (1961) 419-426.
"""
from __future__ import annotations

import numpy as np

from ..runtime.evaluation import Evaluator
from . import datadriven
from .analytic import _eigenvalues, _moments, _quantile, _weights_of
from .datadriven import ShortLogError, ThresholdEstimate, data_driven_threshold, decorrelation_length
from .quadform import imhof_quantile, scaled_chi2_quantile

#: fewest effective residual samples a Gaussian fit is made from: a variance from n_r
#: independent samples is then uncertain by a factor n_r / χ²_{0.05}(n_r) = 2.54 at 95 % (a
#: threshold ≤ 59 % above the point estimate for rms/norm); 30 samples: 1.62, 100: 1.29
MIN_RESIDUAL_SAMPLES = 10
N_BOOT = 200  # bootstrap records: the 5 % quantile of the pivot from the 10th smallest of 200
ACF_SPAN = 5  # lag window M: this many decorrelation lengths of r (module docstring)
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


class _Lags:
    """An autocovariance given by its lags Γ(0..K) (zero beyond), in the shape :mod:`.analytic` reads."""

    def __init__(self, G: np.ndarray):
        self.G, self.Gamma0 = G, G[0]

    @property
    def dim(self) -> int:
        return self.G.shape[1]

    def lags(self, max_lag: int) -> np.ndarray:
        out = np.zeros((max_lag + 1, self.dim, self.dim))
        k = min(max_lag, self.G.shape[0] - 1) + 1
        out[:k] = self.G[:k]
        return out

    def discounted_energy(self, lam: float) -> float:
        """``Σ_{k≥1} λ^k ||Γ(k)||_F²`` over the lags held."""
        k = np.arange(1, self.G.shape[0])
        return float(np.sum(lam ** k * np.sum(self.G[1:] ** 2, axis=(1, 2))))


def sample_autocovariance(r: np.ndarray, max_lag: int) -> np.ndarray:
    """``Γ̂(k) = (1/T) Σ_t r(t+k) r(t)ᵀ``, k = 0..max_lag, about zero (FFT; r of shape (T, p) or
    (B, T, p)); the biased form, a positive semidefinite sequence (Brockwell & Davis §7.2)."""
    T = r.shape[-2]
    nfft = 1 << int(np.ceil(np.log2(T + max_lag + 1)))
    F = np.fft.rfft(r, nfft, axis=-2)
    C = np.fft.irfft(F[..., :, None] * np.conj(F[..., None, :]), nfft, axis=-3)
    return C[..., :max_lag + 1, :, :] / T


def _parzen(x: np.ndarray) -> np.ndarray:
    """Parzen lag window on |x| ≤ 1 (its transform is ≥ 0, so the windowed spectrum stays ⪰ 0)."""
    x = np.abs(x)
    return np.where(x <= 0.5, 1 - 6 * x ** 2 + 6 * x ** 3, 2 * (1 - x) ** 3)


def _shaping_filter(G: np.ndarray, nfft: int) -> np.ndarray:
    """``Ŝ(ω_j)^{1/2}`` at the nfft Fourier frequencies of the lags G(0..M) (already windowed)."""
    M, p = G.shape[0] - 1, G.shape[1]
    c = np.zeros((nfft, p, p))
    c[:M + 1] = G
    c[nfft - M:] = G[1:][::-1].transpose(0, 2, 1)  # Γ(−k) = Γ(k)ᵀ
    S = np.fft.fft(c, axis=0)
    S = 0.5 * (S + np.conj(S.transpose(0, 2, 1)))
    s, V = np.linalg.eigh(S)
    return (V * np.sqrt(np.clip(s, 0.0, None))[:, None, :]) @ np.conj(V.transpose(0, 2, 1))


def _log_quantiles(G: np.ndarray, ev: Evaluator, rate: float) -> np.ndarray:
    """ln of the threshold functional (Satterthwaite's quantile mapped through J) for each lag set in
    G (shape (B, K+1, p, p)); ``chi2``: G of the weighted residual W r."""
    if ev.kind == "peak":
        ev, rate, root = Evaluator({"kind": "norm"}, ev.dim), rate / ev.n, True
    else:
        root = ev.kind != "chi2"
    q = np.array([scaled_chi2_quantile(*_moments(_Lags(g), ev), rate) for g in G])
    return 0.5 * np.log(q) if root else np.log(q)


def _bootstrap_pivot(r: np.ndarray, ev: Evaluator, rate: float, n_boot: int, seed: int) -> tuple[np.ndarray, int]:
    """Draws of ``ln q(Γ̂*) − ln q(Γ̃)`` (module docstring) and the lag window M used."""
    T, p = r.shape
    c = _weights_of(ev, truncate=True) if ev.kind != "peak" else np.ones(1)
    K = c.size - 1  # lags the functional reads
    G_all = sample_autocovariance(r, T // 4)
    rho = np.einsum("kii->k", G_all) / np.trace(G_all[0])
    below = np.flatnonzero(np.abs(rho[1:]) < datadriven.ACF_LEVEL)
    L = int(below[0] + 1) if below.size else T // 4
    M = int(min(T // 4, max(4 * (K + 1), ACF_SPAN * L)))
    G_tilde = _parzen(np.arange(M + 1) / M)[:, None, None] * G_all[:M + 1]
    nfft = 1 << int(np.ceil(np.log2(T + M)))
    root = _shaping_filter(G_tilde, nfft)
    rng = np.random.default_rng(seed)
    lq_true = _log_quantiles(G_tilde[None, :K + 1], ev, rate)[0]
    out = np.empty(n_boot)
    chunk = max(1, int(2 ** 22 // (nfft * p * p)))  # records per batch: a few tens of MB
    for b0 in range(0, n_boot, chunk):
        b1 = min(n_boot, b0 + chunk)
        E = np.fft.fft(rng.standard_normal((b1 - b0, nfft, p)), axis=1)
        x = np.fft.ifft(np.einsum("fij,bfj->bfi", root, E), axis=1).real[:, :T]
        out[b0:b1] = _log_quantiles(sample_autocovariance(x, K), ev, rate) - lq_true
    return out, M



def calibrated_level(confidence: float) -> float:
    """The pivot quantile the bound is read at: ``(1 − γ)/2``, the upper end of the two-sided
    γ interval (module docstring: the one-sided basic bootstrap, ``1 − γ``, measured 88 %)."""
    return 0.5 * (1.0 - confidence)


def gaussian_threshold(residuals, evaluation: dict, rate: float, confidence: float = 0.95, *,
                       skip: int = 0, n_boot: int = N_BOOT, seed: int = 0) -> ThresholdEstimate:
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
    n_boot, seed : int
        Bootstrap records for the confidence bound and their seed (results are reproducible).

    Returns
    -------
    ThresholdEstimate
        ``method="gaussian"``; ``n_effective`` = n_r, ``decorrelation_length`` = L_r;
        ``details``: ``bound_factor`` (value / point, ``exp(−D_{((1−γ)/2)})``), ``lag_window`` M,
        ``n_boot``, ``seed``, ``assumption``.

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
    if int(n_boot) < 20:
        raise ValueError(f"n_boot must be at least 20, got {n_boot}")
    point = _threshold(_LogCovariance(r, 1.0), ev, rate)
    rw = r @ ev.W.T if ev.kind == "chi2" else r
    pivot, M = _bootstrap_pivot(rw, ev, rate, int(n_boot), int(seed))
    factor = float(np.exp(-np.quantile(pivot, calibrated_level(confidence))))
    return ThresholdEstimate(value=point * max(factor, 1.0), method="gaussian", rate=rate, confidence=confidence,
                             point=point, n_samples=int(r.shape[0]), n_effective=int(n), decorrelation_length=int(L),
                             details={"bound_factor": max(factor, 1.0), "lag_window": M, "n_boot": int(n_boot),
                                      "seed": int(seed), "assumption": "Gaussian stationary residual: the exact "
                                      "quantile of the evaluation's quadratic form under the residual autocovariance "
                                      "estimated from the log, raised to a one-sided confidence bound by a spectral "
                                      "parametric bootstrap of that estimate (level and shape)"})


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
    power = datadriven.tail_power_for(evaluation.get("kind") if isinstance(evaluation, dict) else None)
    try:
        return data_driven_threshold(evaluations, rate, confidence, skip=skip, tail_power=power)
    except ShortLogError as short:
        try:
            est = gaussian_threshold(residuals, evaluation, rate, confidence, skip=skip)
        except ShortLogError as also:
            raise ShortLogError(f"{short}; a Gaussian fit of the residuals cannot be made either: {also}",
                                max(short.needed or 0, also.needed or 0) or None) from None
        except ValueError as other:
            raise ShortLogError(f"{short} (and {other})", short.needed) from None
        return ThresholdEstimate(**{**est.__dict__, "details": {**est.details, "short_log": str(short)}})
