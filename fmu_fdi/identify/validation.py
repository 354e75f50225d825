"""Validation of an identified model on an independent record: fit, poles, a PNG.

Fit per output (the normalised root-mean-square error as a percentage, as in Ljung's
``compare``):

    fit_j = 100 (1 − ||y_j − ŷ_j|| / ||y_j − mean(y_j)||),

100 % for a perfect model, 0 % for one no better than the output's mean. ŷ is the model's
simulation from the measured inputs with the initial state fitted by least squares to the
record (the experiment starts from a settled but not exactly known state). For a model with
an unstable pole (a plant that runs in its own loop), open-loop simulation diverges, so ŷ is
the one-step-ahead prediction of the steady-state Kalman predictor with unit process and
measurement noise covariances (stated in the report as ``predictor``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class ValidationReport:
    """Fit per output (%), the discrete and continuous poles, and what ŷ was."""

    output_names: list
    fit: np.ndarray
    poles_discrete: np.ndarray
    poles_continuous: np.ndarray
    kind: str
    y: np.ndarray = field(repr=False, default=None)
    y_hat: np.ndarray = field(repr=False, default=None)
    t: np.ndarray = field(repr=False, default=None)

    def summary(self) -> str:
        fits = ", ".join(f"{n} {f:.1f} %" for n, f in zip(self.output_names, self.fit))
        return f"fit ({self.kind}) on the validation run: {fits}"

    def plot(self, path) -> Path:
        """PNG: measured and predicted outputs, one panel per output."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        p = len(self.output_names)
        fig, axes = plt.subplots(p, 1, figsize=(9, 1.9 * p + 0.6), sharex=True, squeeze=False)
        for j, ax in enumerate(axes[:, 0]):
            ax.plot(self.t, self.y[:, j], lw=1.0, label="measured")
            ax.plot(self.t, self.y_hat[:, j], lw=1.0, ls="--", label=f"model ({self.kind})")
            ax.set_ylabel(self.output_names[j])
            ax.set_title(f"fit {self.fit[j]:.1f} %", fontsize=8, loc="right")
        axes[0, 0].legend(fontsize=8, loc="upper left")
        axes[-1, 0].set_xlabel("time (s)")
        fig.tight_layout()
        path = Path(path)
        fig.savefig(path, dpi=90)
        plt.close(fig)
        return path


def nrmse_fit(y, y_hat) -> np.ndarray:
    """100 (1 − ||y − ŷ|| / ||y − mean y||) per column."""
    y, y_hat = np.asarray(y, float), np.asarray(y_hat, float)
    den = np.linalg.norm(y - y.mean(axis=0), axis=0)
    num = np.linalg.norm(y - y_hat, axis=0)
    return 100.0 * (1.0 - num / np.where(den > 0, den, np.inf))


def simulated(model, u, y) -> np.ndarray:
    """The model's simulation from the inputs ``u``, its initial state fitted to ``y`` by weighted least
    squares (the free-response rows C A^k stacked), each output weighted by the inverse of its error
    std (feasible generalised least squares: the weights from a first fit weighted by 1/RMS of each
    output). Unweighted, an output in large units or with a poor signal/noise (a torque in Nm with
    2 % noise beside speeds in rad/s with 0.2 %) would buy a sliver of its own fit with a free
    response that ruins the others' (the wind turbine's drive train: ω_g's error 0.05 → 1.4 rad/s
    for 0.01 % of τ_g's)."""
    A, C = model.A, model.C
    y = np.asarray(y, float)
    N, n, p = len(u), A.shape[0], C.shape[0]
    y0 = model.simulate(u)
    O = np.empty((N, p, n))
    M = C.copy()
    for k in range(N):
        O[k] = M
        M = M @ A
    tiny = np.finfo(float).tiny
    x0 = np.zeros(n)
    scale = np.sqrt(np.mean(y ** 2, axis=0))
    for _ in range(2):
        w = 1.0 / np.where(scale > tiny, scale, 1.0)
        x0 = np.linalg.lstsq((O * w[None, :, None]).reshape(N * p, n), ((y - y0) * w).ravel(), rcond=None)[0]
        scale = (y - y0 - (O @ x0)).std(axis=0)
    return model.simulate(u, x0)


def validate(model, u, y, t=None, continuous_poles=None, output_names=None, kind: str | None = None) -> ValidationReport:
    """Compare a :class:`~fmu_fdi.identify.subspace.SubspaceModel` with a record of deviations.

    ``kind``: what ŷ is called; given, ŷ is the simulation whatever the poles (the closed-loop
    model of a plant in its own loop, :mod:`fmu_fdi.identify.closed_loop`, may hold a marginal
    integrator that a record of finite length simulates without harm)."""
    A, B, C, D = model.A, model.B, model.C, model.D
    u = np.asarray(u, float).reshape(len(u), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    N, n = len(u), A.shape[0]
    poles = np.linalg.eigvals(A)
    if kind is not None or np.all(np.abs(poles) < 1.0):
        y_hat = simulated(model, u, y)
        kind = kind or "simulation"
    else:
        # the steady-state predictor gain K = A P Cᵀ (C P Cᵀ + I)⁻¹ of unit process and measurement noise: the
        # observers' checked filter Riccati solve (a model whose unstable modes C does not see has no predictor)
        from ..design.observers._observer import filter_riccati

        K = filter_riccati(A, C, np.eye(n), np.eye(C.shape[0]), np.zeros((n, C.shape[0])), model.dt,
                           what="the one-step predictor of the identified model").L
        x = np.zeros(n)
        y_hat = np.empty_like(y)
        for k in range(N):
            y_hat[k] = C @ x + D @ u[k]
            x = A @ x + B @ u[k] + K @ (y[k] - y_hat[k])
        kind = "one-step predictor"
    fit = nrmse_fit(y, y_hat)
    names = list(output_names) if output_names is not None else [f"y{j}" for j in range(y.shape[1])]
    return ValidationReport(names, fit, poles, np.asarray(continuous_poles if continuous_poles is not None
                                                          else [], complex), kind, y, y_hat,
                            np.arange(N) * model.dt if t is None else np.asarray(t))


# ---- judging against the noise floor (Ljung 1999, sec. 16.6) ----------------------------------------

@dataclass
class NoiseFloor:
    """The validation fit set against what the plant's noise allows.

    A repeat of the validation input with another noise realisation gives the noise-only
    mismatch ``v = (y_val − y_rep)/√2`` (the input response cancels; two independent
    realisations differ by √2 times one). With the model error ``e = y_val − ŷ``:

    - ``floor`` — the best fit any model can reach on this run, ``100 (1 − ||v|| / ||y − ȳ||)``;
    - ``fit_noise_free`` — the fit to the noise-free response,
      ``100 (1 − sqrt(max(||e||² − ||v||², 0)) / sqrt(max(||y − ȳ||² − ||v||², tiny)))``:
      the misfit beyond the noise, relative to the response beyond the noise (100 % for a
      model whose error is noise alone; equals the plain fit on a noise-free plant); NaN when
      the response is within 1 % of the noise power (nothing to fit beyond it).
    - ``source`` — 'repeat' (noise from the repeated run) or 'settle' (the repeat came out
      identical — deterministic noise — so ||v||² = N σ² from the settle phase's std σ).
    """

    floor: np.ndarray
    fit_noise_free: np.ndarray
    noise_rms: np.ndarray
    source: str


def noise_floor(y, y_hat, y_rep, sigma_settle=None) -> NoiseFloor:
    """:class:`NoiseFloor` of a validation run ``y`` (deviations), the model's ``y_hat`` and the repeat ``y_rep``."""
    y, y_hat, y_rep = (np.asarray(a, float) for a in (y, y_hat, y_rep))
    N = len(y)
    v2 = np.sum((y - y_rep) ** 2, axis=0) / 2.0
    source = "repeat"
    if not np.any(v2 > 0) and sigma_settle is not None:
        v2 = N * np.asarray(sigma_settle, float) ** 2
        source = "settle"
    tot2 = np.sum((y - y.mean(axis=0)) ** 2, axis=0)
    e2 = np.sum((y - y_hat) ** 2, axis=0)
    tiny = np.finfo(float).tiny
    floor = 100.0 * (1.0 - np.sqrt(v2 / np.maximum(tot2, tiny)))
    with np.errstate(divide="ignore", invalid="ignore"):
        fit = 100.0 * (1.0 - np.sqrt(np.maximum(e2 - v2, 0.0) / (tot2 - v2)))
    fit = np.where(tot2 - v2 > 0.01 * tot2, fit, np.nan)  # no response beyond the noise: undefined
    return NoiseFloor(floor, fit, np.sqrt(v2 / N), source)


def settle_noise_std(z, order: int = 10) -> np.ndarray:
    """Std per output of the noise in a settle record ``z`` (samples × outputs, constant inputs).

    A settling transient of at most ``order`` modes under a constant input is predicted exactly
    by the linear recursion ``z_k = c + Σ_{i=1..p} a_i z_{k−i}`` (Prony's method: p damped modes
    obey a recursion of order p; Kay & Marple 1981), noise is not. With ``e`` the RMS one-step
    error of the least-squares recursion (p = order, fewer on a short record; N − p equations, p + 1
    coefficients: N − 2p − 1 degrees of freedom): a record whose ``e`` is below 1 % of
    its std is a deterministic transient, and its noise is ``e`` (round-off on a noise-free
    plant, the measurement noise around a transient otherwise); else the noise dominates and
    its size is the plain std (coloured noise included, whose one-step error would understate
    it). The plain std alone would count a noise-free plant still settling as noise.
    """
    z = np.asarray(z, float).reshape(len(z), -1)
    N = len(z)
    std = z.std(axis=0)
    p = min(int(order), (N - 1) // 3 - 1)
    if p < 1:
        return std
    out = std.copy()
    for j in range(z.shape[1]):
        x = z[:, j] - z[:, j].mean()
        X = np.column_stack([np.ones(N - p)] + [x[p - i - 1:N - i - 1] for i in range(p)])
        coef = np.linalg.lstsq(X, x[p:], rcond=None)[0]
        e = float(np.sqrt(np.sum((x[p:] - X @ coef) ** 2) / (N - 2 * p - 1)))
        if e < 0.01 * std[j]:
            out[j] = e
    return out


@dataclass
class ResidualTests:
    """Ljung's residual tests (Ljung 1999, sec. 16.6) at lags up to ``lags``, risk 1 % per test.

    - whiteness: the normalised autocorrelation of the predictor innovations ε_j,
      ``N Σ_{τ=1..M} r_ε(τ)²`` against χ²(M);
    - independence: the cross-correlation of the output error e_j (simulation) with each
      input u_i at lags 0..M, ``r_eu(τ)``, against its standard deviation under independence
      ``sqrt(Σ_k ρ_e(k) ρ_u(k) / N)`` (Bartlett; e and u may each be coloured).

    ``whiteness`` and ``independence`` hold the largest statistic relative to its 99 % bound
    (≤ 1 passes) per output."""

    lags: int
    whiteness: np.ndarray
    independence: np.ndarray

    @property
    def white(self) -> bool:
        return bool(np.all(self.whiteness <= 1.0))

    @property
    def independent(self) -> bool:
        return bool(np.all(self.independence <= 1.0))


def _acf(x, lags):
    """Sample autocorrelation ``Σ_t x_t x_{t+k} / Σ_t x_t²`` (mean removed) at lags 0..lags, by FFT."""
    x = np.asarray(x, float) - np.mean(x)
    d = float(x @ x)
    if d <= 0:
        return np.zeros(lags + 1)
    n = 1 << int(np.ceil(np.log2(2 * len(x))))
    f = np.fft.rfft(x, n)
    return np.fft.irfft(f * np.conj(f), n)[: lags + 1] / d


def whiteness(eps, lags: int = 25) -> np.ndarray:
    """Ljung's whiteness statistic per output of innovations ``eps`` (N×p): ``N Σ_{τ=1..M} r_ε(τ)²``
    relative to the 99 % point of χ²(M) (≤ 1 passes; :class:`ResidualTests`)."""
    from scipy.stats import chi2

    eps = np.asarray(eps, float)
    M = int(min(lags, len(eps) // 5))
    bound = chi2.ppf(0.99, M)
    out = np.zeros(eps.shape[1])
    for j in range(eps.shape[1]):
        r = _acf(eps[:, j], M)[1:]
        out[j] = len(eps) * float(r @ r) / bound
    return out


def residual_tests(eps, e, u, lags: int = 25) -> ResidualTests:
    """:class:`ResidualTests` of innovations ``eps`` (N×p, may be None) and output error ``e`` vs inputs ``u``."""
    from scipy.stats import norm

    e = np.asarray(e, float)
    u = np.asarray(u, float).reshape(len(u), -1)
    N, p = e.shape
    M = int(min(lags, N // 5))
    white = whiteness(eps, M) if eps is not None else np.zeros(p)
    # two-sided 1 % per test, Bonferroni over the M + 1 lags and the inputs
    z = norm.ppf(1 - 0.005 / ((M + 1) * max(u.shape[1], 1)))
    indep = np.zeros(p)
    K = min(N // 4, 10 * M + 50)
    rus = [_acf(u[:, i], K) for i in range(u.shape[1])]
    for j in range(p):
        ej = e[:, j] - e[:, j].mean()
        re = _acf(e[:, j], K)
        for i in range(u.shape[1]):
            ui = u[:, i] - u[:, i].mean()
            den = np.sqrt(float(ej @ ej) * float(ui @ ui))
            if den == 0:
                continue
            ru = rus[i]
            sd = np.sqrt(max(re[0] * ru[0] + 2 * float(re[1:] @ ru[1:]), 1.0 / N) / N)
            r = np.array([float(ej[k:] @ ui[: N - k]) for k in range(M + 1)]) / den
            indep[j] = max(indep[j], float(np.max(np.abs(r))) / (z * sd))
    return ResidualTests(M, white, indep)
