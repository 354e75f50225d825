"""Fixed thresholds from fault-free evaluation records, with a stated confidence.

Target: a threshold ``c`` whose per-sample false-alarm rate ``P(J(k) ≥ c)`` in
fault-free operation is at most ``rate``, and a statement that holds with probability
``confidence`` over the training records: ``c`` is an *upper confidence bound* of the
``(1 − rate)`` quantile of J.

Serial correlation. Evaluation signals are strongly autocorrelated (a window of N
samples makes J(k) and J(k+1) nearly equal), so neither the order-statistic bound nor a
bootstrap may treat the samples as independent. The records are *thinned*: with ``L``
the first lag at which the pooled sample autocorrelation of J drops below 0.05, every
L-th sample is kept. The thinned samples have the same marginal distribution, hence the
same per-sample rate, and are close to independent; at correlation ≤ 0.05 the joint
exceedance of a tail level α is ``α² (1 + O(ρ q²))``, so counts of exceedances stay
binomial to within a few percent (block maxima would estimate the rate of the block
maximum instead, which needs the extremal index to come back to a per-sample rate).

Two estimators:

- ``empirical``: the order statistic ``X_(r)`` of the n thinned samples with the
  smallest r such that ``P(Bin(n, 1 − rate) ≤ r − 1) ≥ confidence`` — then
  ``P(X_(r) ≥ q_{1−rate}) ≥ confidence`` for any continuous distribution (the classical
  distribution-free bound, e.g. Hahn & Meeker 1991, ch. 5). It exists when
  ``(1 − rate)^n ≤ 1 − confidence``, i.e. ``n ≳ −ln(1 − confidence)/rate``.
- ``gpd``: peaks over threshold (Pickands 1975; Coles 2001, ch. 4). The k largest
  thinned samples exceed ``u``; their excesses follow a generalised Pareto law
  ``GPD(ξ, σ)`` and the share of samples above u is ζ, so that

      P(J > c) ≈ ζ (1 + ξ (c − u)/σ)^{−1/ξ},   c(rate) = u + σ/ξ ((ζ/rate)^ξ − 1).

  All three parameters are estimated by maximum likelihood — the excesses' GPD
  likelihood times the binomial likelihood ``ζ^k (1 − ζ)^{n−k}`` of the exceedance count
  (Coles 2001, §4.3.3, §4.4.1) — and the confidence bound is the *profile likelihood*
  bound of the return level (Coles 2001, §2.6.6, §4.3.3): σ is written through c,
  ``σ = ξ (c − u) / ((ζ/rate)^ξ − 1)``, the log-likelihood is maximised over (ξ, ζ) at each
  c, and the bound is the c > ĉ at which the deviance ``2 (ℓ̂ − ℓ_p(c))`` reaches
  ``χ²_1(2γ − 1)`` (one-sided level γ). Unlike a percentile bootstrap around the fitted
  parameters, the profile bound follows the likelihood's asymmetry in ξ — the one that
  decides an extrapolation ζ/rate of tens to hundreds — and widens as the excesses grow
  few. ξ is kept ≥ 0 (:data:`XI_MIN`): an evaluation of Gaussian-driven residuals is unbounded, so
  its tail has no negative shape — a fitted ξ < 0 put the bound below the true quantile on white
  noise (and below −1/2 the likelihood is irregular, Smith 1985). The GPD is a *limit* law: fitted to a tail not yet in its
  asymptotic regime (u low in a light, Gaussian-like tail) it underestimates the far
  quantile whatever the confidence bound, so u is held at the ``1 − tail_fraction``
  quantile with at least ``MIN_EXCESSES`` excesses, which sets the fewest effective
  samples ``MIN_TAIL_SAMPLES`` (measured in benchmarks/threshold_coverage.py).

``method="auto"`` uses ``empirical`` when it exists and ``gpd`` below that rate.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

METHODS = ("auto", "empirical", "gpd")


class ShortLogError(ValueError):
    """The records hold too few effective samples for the estimate asked for (the message says
    how many there are, why, and how long a log is needed); ``needed`` is that length in samples."""

    def __init__(self, message: str, needed: int | None = None):
        super().__init__(message)
        self.needed = needed


def tail_power_for(kind: str | None) -> float:
    """The ``tail_power`` of :func:`data_driven_threshold` for an evaluation kind: 2 for the roots of a
    quadratic form and evaluations linear in |r| (Gaussian-like tails), 1 otherwise."""
    return 2.0 if kind in ("norm", "rms", "ewrms", "peak", "narendra") else 1.0


def empirical_need(rate: float, confidence: float) -> int:
    """Effective samples the distribution-free bound needs: the smallest n with
    ``1 − (1 − rate)^n ≥ confidence``, i.e. ``ceil(ln(1 − confidence) / ln(1 − rate))``
    (the largest of n independent samples exceeds the ``1 − rate`` quantile with probability
    ``1 − (1 − rate)^n``). rate 1e-3, confidence 0.95: 2995."""
    return int(np.ceil(np.log1p(-confidence) / np.log1p(-rate) - 1e-9))
ACF_LEVEL = 0.05  # autocorrelation below which thinned samples count as independent
MIN_EXCESSES = 30  # fewest excesses a GPD fit is made from
MAX_TAIL_FRACTION = 0.5  # largest share of the thinned samples above the GPD threshold u
MIN_TAIL_SAMPLES = int(np.ceil(MIN_EXCESSES / MAX_TAIL_FRACTION))  # fewest effective samples of a tail fit
XI_MIN = 0.0  # shape floor of the GPD fit: J unbounded (module docstring)


@dataclass(frozen=True)
class ThresholdEstimate:
    """A data-driven threshold and how it was obtained.

    Attributes
    ----------
    value : float
        The threshold: an upper confidence bound of the ``1 − rate`` quantile of J.
    method : str
        ``"empirical"`` or ``"gpd"``.
    rate : float
        Target per-sample false-alarm rate.
    confidence : float
        Confidence of ``P(J ≥ value) ≤ rate``: exact (binomial, ≥ the requested level)
        for ``empirical``, the nominal profile-likelihood level for ``gpd``.
    point : float
        Point estimate of the quantile (all samples for ``empirical``, the GPD fit for
        ``gpd``).
    n_samples : int
        Samples used (after ``skip``), all records together.
    n_effective : int
        Thinned, nearly independent samples the bound rests on.
    decorrelation_length : int
        Thinning step L.
    details : dict
        ``empirical``: ``order`` (r, 1-based ascending). ``gpd``: ``shape`` ξ, ``scale``
        σ, ``u``, ``excesses`` k, ``bound`` ("profile likelihood"), ``deviance`` χ²_1(2γ − 1).
    """

    value: float
    method: str
    rate: float
    confidence: float
    point: float
    n_samples: int
    n_effective: int
    decorrelation_length: int
    details: dict = field(default_factory=dict)


def _records(evaluations, skip: int) -> list[np.ndarray]:
    if isinstance(evaluations, np.ndarray):
        if evaluations.ndim != 1:
            raise ValueError(f"a single evaluation record must be 1-D, got shape {evaluations.shape}; pass several "
                             "records as a list of 1-D arrays")
        evaluations = [evaluations]
    out = []
    for i, rec in enumerate(evaluations):
        x = np.asarray(rec, dtype=float)
        if x.ndim != 1:
            raise ValueError(f"evaluation record {i} must be 1-D (one group's J), got shape {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError(f"evaluation record {i} contains NaN or Inf")
        if x.size > skip:
            out.append(x[skip:])
    if not out:
        raise ValueError(f"no samples left after skipping {skip} per record")
    return out


def decorrelation_length(records, level: float = ACF_LEVEL) -> int:
    """First lag L ≥ 1 at which the pooled autocorrelation of the records is below ``level``.

    The autocovariance at lag k pools the lagged products of every record about the
    common mean (records are not joined, so no spurious lag crosses a record boundary).
    """
    recs = [np.asarray(r, float) for r in records]
    mu = np.mean(np.concatenate(recs))
    longest = max(r.size for r in recs)
    sums = np.zeros(longest)
    counts = np.zeros(longest)
    for r in recs:
        x = r - mu
        n = x.size
        nfft = 1 << int(np.ceil(np.log2(2 * n)))
        f = np.fft.rfft(x, nfft)
        sums[:n] += np.fft.irfft(f * np.conj(f), nfft)[:n]
        counts[:n] += np.arange(n, 0, -1)
    if sums[0] <= 0:
        raise ValueError("the evaluation records are constant: no threshold can be estimated from them")
    max_lag = longest // 2  # beyond, the lagged products of one record thin out
    rho = sums[:max_lag + 1] / counts[:max_lag + 1] / (sums[0] / counts[0])
    below = np.flatnonzero(rho[1:] < level)
    if below.size == 0:
        raise ShortLogError(f"the autocorrelation of J stays above {level} up to lag {max_lag} (half the longest "
                            "record): the records are too short for their correlation time; give longer records or "
                            "thin= explicitly")
    return int(below[0] + 1)


def _order_index(n: int, rate: float, confidence: float) -> int | None:
    """Smallest 1-based r with ``P(Bin(n, 1 − rate) ≤ r − 1) ≥ confidence``; None if r > n."""
    r = int(stats.binom.ppf(confidence, n, 1.0 - rate)) + 1
    return r if r <= n else None


def _gpd_quantile(u: float, xi: float, sigma: float, zeta: float, rate: float) -> float:
    t = np.log(zeta / rate)
    if abs(xi) < 1e-9:
        return float(u + sigma * t)
    return float(u + sigma / xi * np.expm1(xi * t))


def _gpd_nll(y: np.ndarray, xi: float, sigma: float) -> float:
    """Negative log-likelihood of excesses y under GPD(ξ, σ) (Coles 2001, eq. 4.10); inf off the support."""
    if not sigma > 0 or xi < XI_MIN:
        return np.inf
    if abs(xi) < 1e-9:
        return float(y.size * np.log(sigma) + y.sum() / sigma)
    z = 1.0 + xi * y / sigma
    if np.any(z <= 0):
        return np.inf
    return float(y.size * np.log(sigma) + (1.0 + 1.0 / xi) * np.sum(np.log(z)))


def _count_nll(k: int, n: int, zeta: float) -> float:
    """Negative binomial log-likelihood of k exceedances in n samples."""
    if not 0.0 < zeta < 1.0:
        return np.inf
    return float(-(k * np.log(zeta) + (n - k) * np.log1p(-zeta)))


def _scale_for_level(c: float, u: float, xi: float, zeta: float, rate: float) -> float:
    """σ such that the ``1 − rate`` quantile of the POT model is c."""
    t = np.log(zeta / rate)
    if t <= 0:
        return -1.0
    return float((c - u) / t) if abs(xi) < 1e-9 else float(xi * (c - u) / np.expm1(xi * t))


def _gpd_mle(y: np.ndarray, k: int, n: int) -> tuple[float, float, float, float]:
    """(ξ, σ, ζ, nll) maximising the GPD × binomial likelihood (ζ̂ = k/n; ξ ≥ XI_MIN)."""
    xi0, _, s0 = stats.genpareto.fit(y, floc=0.0)
    best = None
    for start in ((max(xi0, XI_MIN + 1e-3), np.log(s0)), (XI_MIN + 1e-3, np.log(np.mean(y)))):
        res = optimize.minimize(lambda v: _gpd_nll(y, v[0], np.exp(v[1])), start, method="Nelder-Mead",
                                options={"xatol": 1e-8, "fatol": 1e-10, "maxiter": 4000})
        if best is None or res.fun < best.fun:
            best = res
    zeta = k / n
    return float(best.x[0]), float(np.exp(best.x[1])), zeta, float(best.fun) + _count_nll(k, n, zeta)


def _profile_nll(c: float, y: np.ndarray, u: float, k: int, n: int, rate: float, start) -> tuple[float, np.ndarray]:
    """``−ℓ_p(c) = min over (ξ, ζ) of −ℓ(ξ, σ(c, ξ, ζ), ζ)`` and the minimiser (ξ, logit ζ)."""
    def nll(v):
        xi, zeta = v[0], 1.0 / (1.0 + np.exp(-v[1]))
        return _gpd_nll(y, xi, _scale_for_level(c, u, xi, zeta, rate)) + _count_nll(k, n, zeta)

    best = None
    for x0 in (start, (max(start[0], XI_MIN) + 0.2, start[1]), (XI_MIN + 1e-3, start[1])):
        res = optimize.minimize(nll, x0, method="Nelder-Mead", options={"xatol": 1e-7, "fatol": 1e-9, "maxiter": 2000})
        if best is None or res.fun < best.fun:
            best = res
    return float(best.fun), best.x


def _profile_upper_bound(y, u, k, n, rate, confidence, xi, zeta, nll_hat, point) -> float:
    """The c > ĉ where the profile deviance reaches ``χ²_1(2γ − 1)`` (module docstring); ShortLogError
    when the likelihood does not bound the level within a factor 10⁴ of the fitted excess ĉ − u."""
    crit = float(stats.chi2.ppf(2.0 * confidence - 1.0, 1))
    start = np.array([xi, np.log(zeta / (1.0 - zeta))])

    def dev(c):
        nonlocal start
        f, start = _profile_nll(c, y, u, k, n, rate, start)
        return 2.0 * (f - nll_hat) - crit

    lo, d = point, point - u
    hi = u + 1.25 * d
    while dev(hi) < 0:
        lo, hi = hi, u + 1.25 * (hi - u)
        if hi - u > 1e4 * d:
            raise ShortLogError(f"the tail fit's likelihood does not bound the {1 - rate:g} quantile ({k} excesses, "
                                f"shape ξ = {xi:.2f}): a longer log is needed")
    return float(optimize.brentq(dev, lo, hi, xtol=1e-6 * d))


def _effective(n: int, n_all: int, L: int) -> str:
    """What 'effective samples' are, with the numbers of this log."""
    return (f"{n} effective samples: the evaluation stays correlated over {L} samples (autocorrelation ≥ "
            f"{ACF_LEVEL}), so only every {L}-th of the log's {n_all} samples counts as an independent draw")


def _gpd(x: np.ndarray, rate: float, confidence: float, tail_fraction: float, L: int = 1, n_all: int | None = None):
    n = x.size
    k = max(MIN_EXCESSES, int(np.ceil(tail_fraction * n)))
    if k > MAX_TAIL_FRACTION * n:
        need = MIN_TAIL_SAMPLES  # k = MIN_EXCESSES excesses, at most MAX_TAIL_FRACTION of the samples
        raise ShortLogError(f"{_effective(n, n_all or n, L)}: too few for a tail fit, which needs {need} ({k} excesses, "
                            f"at most {MAX_TAIL_FRACTION:.0%} of the samples): a fault-free log of at least about {need * L} samples (the "
                            f"distribution-free bound needs {empirical_need(rate, confidence)} effective samples, about "
                            f"{empirical_need(rate, confidence) * L}; several independent runs may add up to it; a short "
                            f"log underestimates the correlation length, so allow more), or a shorter evaluation window "
                            f"(less correlation)", need * L)
    xs = np.sort(x)
    u = float(xs[n - k - 1])
    y = xs[n - k:] - u
    y = y[y > 0]
    zeta = y.size / n
    if not rate < zeta:
        raise ValueError(f"rate {rate} is not in the tail fitted (excess fraction {zeta:.3g}): use method='empirical'")
    xi, sigma, zeta, nll_hat = _gpd_mle(y, y.size, n)
    point = _gpd_quantile(u, xi, sigma, zeta, rate)
    value = _profile_upper_bound(y, u, y.size, n, rate, confidence, xi, zeta, nll_hat, point)
    details = {"shape": xi, "scale": sigma, "u": u, "excesses": int(y.size),
               "bound": "profile likelihood", "deviance": float(stats.chi2.ppf(2.0 * confidence - 1.0, 1))}
    return max(value, point), point, details


def data_driven_threshold(evaluations, rate: float, confidence: float = 0.95, method: str = "auto", *,
                          thin: int | None = None, skip: int = 0, tail_fraction: float = 0.05,
                          tail_power: float = 1.0) -> ThresholdEstimate:
    """Threshold with false-alarm rate ≤ ``rate`` at confidence ``confidence``, from fault-free records.

    Parameters
    ----------
    evaluations : 1-D array or list of 1-D arrays
        Fault-free evaluation signals J of one residual group (e.g. the
        ``evaluation_<k>`` output of independent fault-free runs).
    rate : float
        Target per-sample false-alarm rate ``P(J(k) ≥ threshold)``, in (0, 1).
    confidence : float
        Probability, over the training records, that the threshold meets ``rate``.
    method : {"auto", "empirical", "gpd"}
        See the module docstring; ``auto`` takes ``empirical`` when its bound exists.
    thin : int, optional
        Thinning step (decorrelation length); estimated from the records when None.
    skip : int
        Samples dropped at the start of every record (evaluator and generator
        transients: the estimate is for the stationary regime).
    tail_fraction : float
        Share of the thinned samples above the GPD threshold u (at least 30 excesses).
    tail_power : float
        The GPD is fitted to the tail of ``J^tail_power`` (J ≥ 0 when not 1) and the bound mapped
        back (a monotone map: the coverage statement is unchanged). 2 for an evaluation that is
        the root of a Gaussian quadratic form (``norm``, ``rms``, ``ewrms``, ``peak``: J² has an
        exponential tail, ``P(Q > x) ~ C x^a e^{−x/b}``, in the GPD's ξ = 0 domain with a fast
        approach, where J's Gaussian-like tail looks bounded at any practical u and ξ ≥ 0 makes
        its bound needlessly high); 1 for ``chi2`` and the sequential tests.

    Returns
    -------
    ThresholdEstimate

    Notes
    -----
    The guarantee assumes stationary fault-free records whose thinned samples are
    independent and continuously distributed; records from independent runs (different
    noise seeds) help most, since they are independent by construction.

    References
    ----------
    G. J. Hahn, W. Q. Meeker, *Statistical Intervals*, Wiley 1991, ch. 5.
    S. Coles, *An Introduction to Statistical Modeling of Extreme Values*, Springer 2001.
    J. Pickands, "Statistical inference using extreme order statistics", Ann. Statist.
    3 (1975) 119-131.

    Examples
    --------
    >>> import numpy as np
    >>> J = np.abs(np.random.default_rng(1).standard_normal(20000))
    >>> est = data_driven_threshold(J, rate=0.01)
    >>> est.method, est.decorrelation_length, round(est.value, 2)  # |N(0,1)|: q = 2.58
    ('empirical', 1, 2.59)
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; use one of {METHODS}")
    rate, confidence = float(rate), float(confidence)
    if not 0.0 < rate < 1.0:
        raise ValueError(f"rate must be in (0, 1), got {rate}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    if not 0.0 < tail_fraction < 0.5:
        raise ValueError(f"tail_fraction must be in (0, 0.5), got {tail_fraction}")
    if int(skip) < 0:
        raise ValueError(f"skip must be >= 0, got {skip}")
    recs = _records(evaluations, int(skip))
    if thin is None:
        L = decorrelation_length(recs)
    else:
        L = int(thin)
        if L < 1:
            raise ValueError(f"thin must be a positive integer, got {thin}")
    x = np.concatenate([r[::L] for r in recs])
    n_all = sum(r.size for r in recs)
    n = x.size
    common = dict(rate=rate, n_samples=n_all, n_effective=n, decorrelation_length=L)

    r = _order_index(n, rate, confidence)
    if method == "empirical" and r is None:
        need = empirical_need(rate, confidence)
        raise ShortLogError(f"the empirical bound needs at least {need} effective samples for rate {rate} at confidence "
                         f"{confidence} (a log of at least about {need * L} samples), got {_effective(n, n_all, L)}; use "
                         f"method='gpd'", need * L)
    if method == "empirical" or (method == "auto" and r is not None):
        value = float(np.sort(x)[r - 1])
        achieved = float(stats.binom.cdf(r - 1, n, 1.0 - rate))
        point = float(np.quantile(np.concatenate(recs), 1.0 - rate))
        return ThresholdEstimate(value=value, method="empirical", confidence=achieved, point=point,
                                 details={"order": r}, **common)
    if not tail_power > 0:
        raise ValueError(f"tail_power must be positive, got {tail_power}")
    if tail_power != 1.0 and x.min() < 0:
        raise ValueError(f"tail_power {tail_power} needs J >= 0, got a sample {x.min():.3g}")
    value, point, details = _gpd(x ** tail_power, rate, confidence, tail_fraction, L, n_all)
    value, point = value ** (1.0 / tail_power), point ** (1.0 / tail_power)
    details = {**details, "tail_power": float(tail_power)}
    return ThresholdEstimate(value=value, method="gpd", confidence=confidence, point=point, details=details, **common)
