"""Tail probabilities of Gaussian quadratic forms ``Q = zᵀ M z = Σ_j λ_j χ²_1``.

For ``z ~ N(0, Σ)`` and ``M ⪰ 0``, Q is a weighted sum of independent χ²_1 variables with
weights ``λ_j`` the eigenvalues of ``Σ^{1/2} M Σ^{1/2}``; its mean is ``tr(MΣ) = Σλ_j``
and its variance ``2 tr((MΣ)²) = 2 Σλ_j²``.

- :func:`scaled_chi2_quantile`: Satterthwaite (1946) / Welch (1938) moment matching,
  ``Q ≈ g χ²_h`` with ``g = Var/(2E)`` and ``h = 2E²/Var``; exact when all nonzero ``λ_j``
  are equal, otherwise an approximation whose tail error grows as α shrinks and as the
  weights spread (Box 1954).
- :func:`imhof_sf` / :func:`imhof_quantile`: exact inversion of the characteristic
  function (Imhof 1961),

      P(Q > x) = 1/2 + (1/π) ∫_0^∞ sin θ(u) / (u ρ(u)) du,
      θ(u) = ½ Σ arctan(λ_j u) − ½ x u,   ρ(u) = Π (1 + λ_j² u²)^{1/4},

  integrated adaptively on ``[0, U]`` and, for the slowly decaying oscillating tail,
  with QUADPACK's Fourier-integral rule (QAWF) on ``[U, ∞)``.

References
----------
J. P. Imhof, "Computing the distribution of quadratic forms in normal variables",
Biometrika 48 (1961) 419-426. F. E. Satterthwaite, Biometrics Bulletin 2 (1946) 110-114.
G. E. P. Box, Ann. Math. Statist. 25 (1954) 290-302.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import integrate, optimize, stats


def scaled_chi2_quantile(mean: float, var: float, alpha: float) -> float:
    """Upper α quantile of ``g χ²_h`` with the given mean and variance (Satterthwaite)."""
    if not (mean > 0 and var > 0):
        raise ValueError(f"the quadratic form has mean {mean:.3g} and variance {var:.3g}: the residual is zero "
                         "under the given noise, so no threshold is needed")
    g, h = var / (2.0 * mean), 2.0 * mean * mean / var
    return float(g * stats.chi2.isf(alpha, h))


def _weights(lam) -> np.ndarray:
    lam = np.asarray(lam, dtype=float).ravel()
    if lam.size == 0 or not np.all(np.isfinite(lam)) or lam.max() <= 0:
        raise ValueError("the quadratic form needs at least one positive finite weight")
    if lam.min() < -1e-10 * lam.max():
        raise ValueError(f"quadratic-form weights must be >= 0 (M and Σ positive semidefinite), min {lam.min():.3g}")
    return lam[lam > 1e-13 * lam.max()]


def imhof_sf(x: float, lam) -> float:
    """``P(Σ λ_j χ²_1 > x)`` (Imhof 1961); raises if the quadrature error exceeds max(1e-9, 1e-3 P)."""
    lam = _weights(lam)
    if x <= 0:
        return 1.0
    if np.ptp(lam) <= 1e-12 * lam.max():
        return float(stats.chi2.sf(x / lam.mean(), lam.size))
    scale = lam.max()
    lam, x = lam / scale, x / scale  # scale-free: integrand frequencies O(1)
    half_x = 0.5 * x

    def phi(u):
        return 0.5 * np.sum(np.arctan(lam * u))

    def log_amp(u):  # log of 1/(u ρ(u)): ρ itself overflows far out in u when there are many weights
        return -math.log(u) - 0.25 * float(np.sum(np.log1p((lam * u) ** 2)))

    def amp(u):
        return math.exp(log_amp(u))

    def head(u):
        if u == 0.0:
            return 0.5 * (lam.sum() - x)
        return math.sin(phi(u) - half_x * u) * amp(u)

    U = 8.0 * math.pi / x  # four periods of the x-oscillation before switching to QAWF
    opts = dict(epsabs=1e-13, epsrel=1e-10, limit=500, full_output=1)
    # Many weights: ρ grows like exp(Σλ²u²/4), so the integrand dies within a few dozen
    # periods, while sin φ(u) oscillates as fast as the QAWF weight (φ' ≈ Σλ/2 near x/2) and
    # QAWF fails silently. Integrate directly up to u_end, where the amplitude is below e^-40
    # and still falls by e^-10 to 2 u_end (the rest is then below 2 e^-40 u_end).
    u_end = U
    while log_amp(u_end) > -40.0 and u_end < 1e6 * U:
        u_end *= 2.0
    periods = (half_x + 0.5 * lam.sum()) * u_end / (2.0 * math.pi)
    direct = log_amp(u_end) <= -40.0 and log_amp(2.0 * u_end) <= log_amp(u_end) - 10.0 and periods <= 200
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        if direct:
            i0, e0, *_ = integrate.quad(head, 0.0, u_end, **dict(opts, limit=2000))
            p, err = 0.5 + i0 / math.pi, e0 / math.pi
            if err > max(1e-9, 1e-3 * abs(p)):
                raise ArithmeticError(f"Imhof integration did not converge (P = {p:.3g} ± {err:.2g})")
            return float(min(max(p, 0.0), 1.0))
        i0, e0, *_ = integrate.quad(head, 0.0, U, **opts)
        # sin(φ − xu/2) = sin φ cos(xu/2) − cos φ sin(xu/2): smooth amplitudes times pure waves
        i1, e1, *_ = integrate.quad(lambda u: math.sin(phi(u)) * amp(u), U, np.inf, weight="cos", wvar=half_x,
                                    **{k: v for k, v in opts.items() if k != "epsrel"})
        i2, e2, *_ = integrate.quad(lambda u: math.cos(phi(u)) * amp(u), U, np.inf, weight="sin", wvar=half_x,
                                    **{k: v for k, v in opts.items() if k != "epsrel"})
    p = 0.5 + (i0 + i1 - i2) / math.pi
    err = (e0 + e1 + e2) / math.pi
    if err > max(1e-9, 1e-3 * abs(p)):
        raise ArithmeticError(f"Imhof integration did not converge (P = {p:.3g} ± {err:.2g})")
    return float(min(max(p, 0.0), 1.0))


def imhof_quantile(alpha: float, lam) -> float:
    """The x with ``P(Σ λ_j χ²_1 > x) = α`` (exact, by root finding on :func:`imhof_sf`)."""
    lam = _weights(lam)
    if np.ptp(lam) <= 1e-12 * lam.max():
        return float(lam.mean() * stats.chi2.isf(alpha, lam.size))
    x0 = scaled_chi2_quantile(lam.sum(), 2.0 * np.sum(lam * lam), alpha)

    def f(x):
        return math.log(max(imhof_sf(x, lam), 1e-300)) - math.log(alpha)

    lo, hi = x0 / 1.5, x0 * 1.5
    while f(lo) < 0:
        lo /= 1.5
    while f(hi) > 0:
        hi *= 1.5
    return float(optimize.brentq(f, lo, hi, xtol=1e-12 * x0, rtol=1e-10))
