"""Fixed thresholds from a false-alarm probability, for Gaussian residuals.

Under H0 the residual of a linear generator driven by white Gaussian noise is a
stationary Gaussian sequence with autocovariance ``Γ(k)`` (:mod:`.covariance`). The
quadratic evaluators of :mod:`fmu_fdi.runtime.evaluation` are then functions of a
Gaussian quadratic form

    Q(k) = Σ_{i≥0} c_i ||M r(k−i)||²,

with ``J = sqrt(Q)`` for ``norm`` (c_0 = 1), ``rms`` (c_i = 1/N, i < N) and ``ewrms``
(c_i = (1−λ) λ^i), and ``J = Q`` for ``chi2`` (c_i = 1, i < N, M = W). Its moments are
exact:

    E Q   = tr(M Γ(0) Mᵀ) Σ_i c_i,
    Var Q = 2 Σ_{i,j} c_i c_j ||M Γ(i−j) Mᵀ||_F²
          = 2 [ ||Γ_M(0)||_F² Σ_i c_i² + 2 Σ_{k≥1} ||Γ_M(k)||_F² Σ_i c_i c_{i+k} ],

(for ``ewrms`` the lag sum is ``(1−λ)²/(1−λ²) [||Γ_M(0)||² + 2 Σ_k λ^k ||Γ_M(k)||²]``, in
closed form through a discrete Lyapunov equation), and the threshold is the upper α
quantile of Q mapped through J.

The per-sample false-alarm probability ``P(J(k) ≥ J_th) = α`` holds in the stationary
regime. From zero initial states (generator and evaluator) the covariance of the
stacked window grows monotonically to its stationary value, so by Anderson's theorem
(1955) the transient false-alarm probability is lower. The bound is per residual group;
with several groups ``P(fault_detected) ≤ Σ α_i``, and persistence (k of n) lowers it
further.
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy import stats

from ..runtime.evaluation import Evaluator
from .covariance import ResidualCovariance, discrete_generator, group_rows, residual_covariance
from .quadform import imhof_quantile, scaled_chi2_quantile

METHODS = ("auto", "exact", "satterthwaite")
MAX_EXACT_SIZE = 2000  # stacked window length (samples × dim) for the exact eigen-decomposition
_EWRMS_TAIL = 1e-6  # weight left out when the exponential window is truncated for "exact"


def _weights_of(ev: Evaluator, truncate: bool = False) -> np.ndarray | None:
    """Window weights c_i of a quadratic evaluator.

    The infinite ``ewrms`` window gives None, or with ``truncate`` its first K weights,
    ``λ^K ≤ _EWRMS_TAIL``.
    """
    if ev.kind == "norm":
        return np.ones(1)
    if ev.kind == "rms":
        return np.full(ev.n, 1.0 / ev.n)
    if ev.kind == "chi2":
        return np.ones(ev.n)
    if not truncate:
        return None
    return (1.0 - ev.lam) * ev.lam ** np.arange(int(np.ceil(np.log(_EWRMS_TAIL) / np.log(ev.lam))))


def _moments(cov: ResidualCovariance, ev: Evaluator) -> tuple[float, float]:
    """Exact mean and variance of the evaluator's quadratic form Q."""
    fro2 = lambda X: float(np.sum(X * X))  # noqa: E731
    c = _weights_of(ev)
    if c is None:  # ewrms
        lam = ev.lam
        g0 = fro2(cov.Gamma0)
        mean = float(np.trace(cov.Gamma0))
        var = 2.0 * (1.0 - lam) / (1.0 + lam) * (g0 + 2.0 * cov.discounted_energy(lam))
        return mean, var
    N = c.size
    G = cov.lags(N - 1)
    lag_weight = np.correlate(c, c, mode="full")[N - 1:]  # Σ_i c_i c_{i+k}, k = 0..N-1
    energy = np.array([fro2(g) for g in G])
    mean = float(np.trace(cov.Gamma0) * c.sum())
    var = 2.0 * (lag_weight[0] * energy[0] + 2.0 * float(np.dot(lag_weight[1:], energy[1:])))
    return mean, var


def _eigenvalues(cov: ResidualCovariance, ev: Evaluator) -> np.ndarray:
    """Weights λ_j of ``Q = Σ λ_j χ²_1``: eigenvalues of ``C^{1/2} Σ_z C^{1/2}``."""
    c = _weights_of(ev, truncate=True)
    N, p = c.size, cov.dim
    if N * p > MAX_EXACT_SIZE:  # eigvalsh is O((N p)^3): ~1 s at the limit
        raise ValueError(f"method='exact' needs a {N * p}x{N * p} eigen-decomposition (limit {MAX_EXACT_SIZE}); "
                         "use method='satterthwaite'")
    G = cov.lags(N - 1)
    # block (i, j) = E[r(k−i) r(k−j)ᵀ] = Γ(j − i), with Γ(−k) = Γ(k)ᵀ
    lag = np.arange(N)[None, :] - np.arange(N)[:, None]
    blocks = np.where((lag >= 0)[:, :, None, None], G[np.abs(lag)], G[np.abs(lag)].transpose(0, 1, 3, 2))
    S = blocks.transpose(0, 2, 1, 3).reshape(N * p, N * p)
    s = np.repeat(np.sqrt(c), p)
    return np.linalg.eigvalsh(s[:, None] * S * s[None, :])


def _quantile(cov: ResidualCovariance, ev: Evaluator, alpha: float, method: str) -> float:
    if method == "auto":
        size = _weights_of(ev, truncate=True).size * cov.dim
        if size <= MAX_EXACT_SIZE:
            method = "exact"
        else:
            warnings.warn(f"the '{ev.kind}' window spans {size} values, too many for the exact "
                          "distribution: using the Satterthwaite approximation, whose threshold is low (false-alarm "
                          "rate above alpha) for coloured residuals", RuntimeWarning, stacklevel=3)
            method = "satterthwaite"
    if method == "exact":
        return imhof_quantile(alpha, _eigenvalues(cov, ev))
    return scaled_chi2_quantile(*_moments(cov, ev), alpha)


def analytic_threshold(gen, evaluation: dict, alpha: float, *, noise_cov=None, disturbance_cov=None,
                       measurement_cov=None, Ts: float | None = None, group: int | None = None,
                       method: str = "auto") -> float:
    """Fixed threshold ``J_th`` with per-sample false-alarm probability α under Gaussian noise.

    Parameters
    ----------
    gen : ResidualGenerator
        The residual generator (a continuous one is discretised with ``Ts``, zero-order
        hold of every input).
    evaluation : dict
        Evaluator spec as in the design file (``{"kind": "rms", "window": 20}``, ...).
    alpha : float
        Target ``P(J(k) ≥ J_th)`` in fault-free stationary operation, ``0 < α < 1``.
    noise_cov : float, (nw,) or (nw, nw) array_like, optional
        Covariance per sample of the white noise inputs w (for a continuous generator:
        the covariance of each held sample, the noise being piecewise constant).
    disturbance_cov : float, (nd,) or (nd, nd) array_like, optional
        Treat the disturbances d as white noise of this covariance per sample.
    measurement_cov : float, (ny,) or (ny, ny) array_like, optional
        Covariance per sample of a white noise added to the measured outputs beyond the
        model's w (e.g. the ``Rv`` of a :func:`~fmu_fdi.design.kalman` design).
    Ts : float, optional
        Sample time; required for a continuous generator, checked for a discrete one.
    group : int, optional
        Residual group evaluated (0-based); may be omitted for a single group.
    method : {"auto", "exact", "satterthwaite"}
        How the quantile of the quadratic form is obtained (see Notes). ``"auto"``:
        exact when the stacked window has at most ``MAX_EXACT_SIZE`` (2000) values,
        otherwise Satterthwaite with a RuntimeWarning.

    Returns
    -------
    float
        The threshold, in the evaluator's units.

    Raises
    ------
    ValueError
        For ``narendra``, ``cusum`` and ``glr`` (no closed-form distribution: use
        :func:`~fmu_fdi.evaluation.data_driven_threshold`), for missing covariances,
        unstable noise responses or invalid arguments.

    Notes
    -----
    ``chi2`` without any covariance: the evaluator's ``W`` is taken to
    whiten the residual exactly (``W r`` white with unit covariance, e.g. Kalman
    innovations), so ``Q ~ χ²_{N·dim}`` and ``J_th = χ²_{N·dim}(1 − α)`` exactly. With
    covariances given, the actual autocovariance of ``W r`` is used instead.

    ``norm`` of a scalar residual: ``J_th = σ z_{1−α/2}`` exactly (both methods).

    ``rms``, ``ewrms``, ``chi2`` with covariances, vector ``norm``, with
    ``method="exact"``: Q is distributed as ``Σ λ_j χ²_1`` with the λ_j the eigenvalues
    of the weighted stacked window covariance ``c^{1/2} Σ_z c^{1/2}`` (``ewrms``
    truncated where the left-out weight is 1e-6, which lowers Q by less than that
    relative amount); its upper α quantile is found by inverting the characteristic
    function (Imhof 1961).

    ``method="satterthwaite"``: the exact mean and variance of Q (module docstring)
    are matched by ``g χ²_h`` (Satterthwaite–Welch), ``g = Var/(2E)``, ``h = 2E²/Var``.
    Exact for equal λ_j (a white isotropic residual and a flat window: ``norm``,
    ``rms``, ``chi2``); otherwise, in every case measured, the matched χ² tail is
    lighter than Q's, so the threshold is too low.
    Measured false-alarm probability over α (exact tail at the Satterthwaite
    threshold), residual ``r`` = AR(1) with pole 0.9 plus white noise of half the
    driving variance, or white:

    ==================  ========  =========  =========  =========
    evaluator           residual  α = 1e-2   α = 1e-3   α = 1e-4
    ==================  ========  =========  =========  =========
    rms, N = 20         AR(1)     1.41       2.62       5.27
    ewrms, λ = 0.9      AR(1)     1.49       2.96       6.39
    ewrms, λ = 0.9      white     1.27       1.86       3.02
    ==================  ========  =========  =========  =========

    so it is offered for windows too long for the exact route and for quick estimates.

    ``peak``: ``P(max_{i<N} ||r(k−i)|| ≥ c) ≤ N P(||r|| ≥ c)`` (union bound), with the
    marginal quantile exact; the threshold is *conservative* — its false-alarm
    probability is at most α, close to α for a white residual and much lower for a
    strongly correlated one.

    References
    ----------
    F. E. Satterthwaite (1946); J. P. Imhof (1961); T. W. Anderson, "The integral of a
    symmetric unimodal function over a symmetric convex set", Proc. AMS 6 (1955) 170-176.

    Examples
    --------
    >>> from fmu_fdi import FDIModel, LTI, ResidualGenerator
    >>> m = FDIModel.from_matrices([[0.9]], [[1.0]], [[1.0]], Bw=[[1.0]], dt=1.0)
    >>> Q = LTI([[0.9]], [[0.0, 1.0]], [[-1.0]], [[1.0, 0.0]], 1.0)  # r = y - model output
    >>> gen = ResidualGenerator(Q, m, "open-loop observer")
    >>> round(analytic_threshold(gen, {"kind": "norm"}, 0.05, noise_cov=1.0), 4)  # 1.96 σ, σ² = 1/(1 - 0.9²)
    4.4965
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; use one of {METHODS}")
    alpha = float(alpha)
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be a probability in (0, 1), got {alpha}")
    if not isinstance(evaluation, dict):
        raise TypeError(f"evaluation must be an evaluator spec dict, got {type(evaluation).__name__}")
    dgen = discrete_generator(gen, Ts)
    rows = group_rows(dgen, group)
    ev = Evaluator(evaluation, len(rows))  # validates the spec exactly as the runtime does
    if ev.kind in ("narendra", "cusum", "glr"):
        raise ValueError(f"no analytic threshold for the '{ev.kind}' evaluator (its distribution under H0 has no "
                         "closed form): use data_driven_threshold on fault-free evaluation records")
    if ev.kind == "chi2" and noise_cov is None and disturbance_cov is None and measurement_cov is None:
        return float(stats.chi2.isf(alpha, ev.n * ev.dim))
    cov = residual_covariance(dgen, noise_cov=noise_cov, disturbance_cov=disturbance_cov,
                              measurement_cov=measurement_cov, group=group)
    if ev.kind == "peak":
        norm = Evaluator({"kind": "norm"}, ev.dim)
        return float(np.sqrt(imhof_quantile(alpha / ev.n, _eigenvalues(cov, norm))))
    if ev.kind == "chi2":
        return _quantile(cov.weighted(ev.W), ev, alpha, method)
    return float(np.sqrt(_quantile(cov, ev, alpha, method)))
