"""Fault analysis by parameter estimation: recursive least squares on the model's equation.

Frank (section 6; Isermann 1984) detects faults as changes of physical model parameters:
estimate the parameters θ of a linear-in-parameters model from the measured u and y and
compare them with their nominal values θ0. Here the model of output i is its MISO
difference (or differential) equation with the common denominator of row i of Gu,

    y(t) + a_1 y^(n-1)(t) + ... + a_n y(t)  =  Σ_j Σ_l b_{j,l} u_j^(n-l)(t)          (continuous)
    y[k] + a_1 y[k-1] + ... + a_n y[k-n]    =  Σ_j Σ_l b_{j,l} u_j[k-l]              (discrete, ARX)

written ``ψ = φᵀ θ + e`` with ``θ = [a_1..a_n, b_{1,0..n}, ..., b_{m,0..n}]``; ``b_{j,0}`` is
kept only where ``Du[i, j] ≠ 0`` (a strictly proper channel has ``b_{j,0} = 0``).

*Discrete models*: ψ = y[k], φ = [-y[k-1..k-n], u_j[k-l]] — shift registers.

*Continuous models*: the derivatives are taken through the state-variable filter (SVF)
``F(s) = (λ/(s+λ))^n`` (Young 1981): ``ψ = (s/λ)^n F y``, ``φ = [-(s/λ)^{n-k} F y,
(s/λ)^{n-l} F u_j]``. The normalised derivatives (s/λ)^k keep the regression well scaled;
the physical coefficients are ``a_k = λ^k θ_{a_k}``, ``b_{j,l} = λ^l θ_{b_{j,l}}``. At run
time the SVF is an LTI prefilter discretised exactly with a zero-order hold at ``Ts``.
Because the plant input is held as well, the sampled signals satisfy *exactly* one linear
relation ``ψ[k] = φ[k]ᵀ θ_s`` (both sides are rational in z with the ZOH plant's
denominator); ``θ_s`` differs from the continuous coefficients ``θ_c`` by O(Ts) (the
ZOH-held y lags the true y by about half a sample). The nominal θ0 the residual refers to
is ``θ_s``, the value a fault-free plant makes the estimator converge to; ``θ_c`` and the
difference (the SVF discretisation bias) are reported in ``info``.

Both θ0 are computed the same way, from the model: along the cascade ``[ψ; φ] = Π(λ) [G_i;
I] u`` (Π the prefilter) the identity ``ψ = φᵀ θ`` must hold for every frequency, so θ is
the solution of an overdetermined, consistent linear system of frequency-response samples;
its residual confirms the structure and its conditioning confirms identifiability.

MIMO models: one MISO estimator per output (each with its own prefilter, θ̂ and P); each
forms one residual group, named ``<y>.a1``, ``<y>.b1_0``, ... (plain ``a1``, ``b1_0`` when one
output is estimated). Unknown inputs d and noise w are not modelled: they enter the
equation error. Least squares is consistent for white *equation* error; white
*measurement* noise on y makes the equation error coloured and biases the estimates by
O(noise/signal power) (Ljung 1999, ch. 7) — the thresholds must absorb that bias.

References
----------
Frank, P.M. (2009). Fault diagnosis for linear systems, EOLSS, section 6.
Isermann, R. (1984). Process fault detection based on modelling and estimation methods.
Automatica 20, 387-404.
Ljung, L. (1999). *System Identification: Theory for the User*, 2nd ed., ch. 7, 11.
Young, P. (1981). Parameter estimation for continuous-time models — a survey. Automatica 17, 23-39.
Garnier, H., Mensler, M., Richard, A. (2003). Continuous-time model identification from
sampled data. Int. J. Control 76(13), 1337-1357.
"""
from __future__ import annotations

import math
from math import comb

import numpy as np

from ...errors import DesignError
from ...lti import LTI, blockdiag, frequency_grid
from ...model import FDIModel

_POLICIES = (None, "none", "floor", "periodic")


class RLSEstimator:
    """Recursive least-squares parameter estimator with residuals ``(θ̂ - θ0)/σ̂_θ``.

    Not an LTI filter, so not a :class:`~fmu_fdi.generator.ResidualGenerator`; it has the
    attributes a Diagnoser reads from one. Build it with :func:`rls_estimator`.

    Attributes
    ----------
    model : FDIModel
        The design model (continuous or discrete).
    method : str
        ``"rls"``.
    dt : float
        Sample time of the runtime (``Ts``; the model's ``dt`` for a discrete model).
    input_names : list of str
        The model's y names then u names: the order of the samples ``v`` fed to the runtime.
    residual_names : list of str
        One per parameter.
    groups : list of list of int
        One residual group per estimated output.
    info : dict
        θ0 and regressor definition per output, and the tuning (see :func:`rls_estimator`).
    """

    method = "rls"

    def __init__(self, model: FDIModel, spec: dict, residual_names: list[str], groups: list[list[int]],
                 info: dict):
        self.model = model
        self._spec = spec
        self.residual_names = list(residual_names)
        self.groups = [list(g) for g in groups]
        self.info = info

    @property
    def dt(self) -> float:
        return self._spec["dt"]

    @property
    def input_names(self) -> list[str]:
        return list(self.model.y_names) + list(self.model.u_names)

    @property
    def n_residuals(self) -> int:
        return len(self.residual_names)

    def __repr__(self) -> str:
        outs = [e["output"] for e in self._spec["estimators"]]
        return (f"RLSEstimator(outputs={outs}, parameters={self.n_residuals}, dt={self.dt:g}, "
                f"forgetting={self._spec['forgetting']:g})")

    def runtime_spec(self) -> dict:
        """The JSON-serialisable spec of kind ``"rls"`` read by :class:`fmu_fdi.runtime.rls.RLSStep`."""
        import copy

        return copy.deepcopy(self._spec)

    def simulate(self, y, u, return_estimates: bool = False):
        """Residuals for sampled ``y`` (N×ny) and ``u`` (N×nu), through the runtime's own step.

        With ``return_estimates=True`` also returns θ̂ after every sample (N × parameters,
        physical coordinates).
        """
        from ...runtime.rls import RLSStep

        N = len(y)
        V = np.hstack([np.asarray(y, float).reshape(N, -1), np.asarray(u, float).reshape(N, -1)])
        run = RLSStep(self._spec)
        if not return_estimates:
            return run.run(V)
        R = np.empty((N, self.n_residuals))
        TH = np.empty((N, self.n_residuals))
        for k in range(N):
            R[k] = run.step(V[k])
            TH[k] = run.theta
        return R, TH

    # The analysis functions read the internal form of an LTI generator; say clearly why
    # there is none instead of failing somewhere inside them.
    def internal_form(self):
        raise TypeError(
            "RLS is not an LTI generator: the residual (θ̂ - θ0)/σ̂ is a nonlinear function of the data, "
            "so it has no internal form R = Q Ge (structure matrices, gaps and leakage do not apply)"
        )

    @property
    def Ru(self):
        return self.internal_form()

    Rd = Rw = Rf = Ru

    def fault_response(self, fault):
        return self.internal_form()


# ---------------------------------------------------------------------------- design
def rls_estimator(model: FDIModel, *, output=None, order=None, Ts: float | None = None,
                  forgetting: float = 0.98, P0: float = 1e3, reset: str | None = None,
                  reset_trace: float | None = None, reset_period: int | None = None,
                  trace_max: float | None = None, svf_bandwidth: float | None = None,
                  noise_std=None, noise_forgetting: float | None = None, sigma_clip: float = 3.0,
                  warmup: int | None = None) -> RLSEstimator:
    """Residuals from recursive least-squares estimation of the model's equation coefficients.

    The estimator tracks ``θ`` in ``ψ[k] = φ[k]ᵀ θ + e[k]`` (module docstring: ARX for a
    discrete model, SVF for a continuous one) by RLS with exponential forgetting μ,

        θ̂ ← θ̂ + K (ψ - φᵀ θ̂),  K = P φ / (μ + φᵀ P φ),  P ← (I - K φᵀ) P / μ  (Joseph form),

    and outputs ``r_i = (θ̂_i - θ0_i) / sqrt(P_ii σ̂_e²)``, σ̂_e² a forgetting estimate of
    the equation-error variance (see :mod:`fmu_fdi.runtime.rls`). Without a fault r_i has a
    standard deviation of about ``1/sqrt(1 + μ)``; a parametric fault moves the residuals
    of the coefficients it changes.

    Parameters
    ----------
    model : FDIModel
        Needs at least one known input u. d, w and the faults are not used.
    output : str or list of str, optional
        The outputs to estimate (default all); one MISO estimator and residual group each.
    order : int or list of int, optional
        The model order n of each estimated output. It must equal the McMillan degree of
        the row ``Gu[i, :]`` (the default): a lower order cannot represent the plant, so
        θ0 does not exist; a higher one has a pole-zero cancellation and the parameters
        are not unique (the estimate drifts along the cancellation, a false alarm).
    Ts : float
        Runtime sample time; required for a continuous model, must be absent or equal to
        ``model.dt`` for a discrete one.
    forgetting : float
        μ in (0, 1]: the estimator's memory is about ``1/(1 - μ)`` samples.
    P0 : float
        Initial covariance ``P0 I`` (and the value a reset returns to). The prior weight
        of θ0 is ``1/P0`` against ``Σ φφᵀ``: large for fast start-up. For a continuous
        model θ is in the normalised (s/λ) coordinates.
    reset : {None, "none", "floor", "periodic"}
        Covariance reset policy: ``"floor"`` sets ``P = P0 I`` whenever ``trace P <
        reset_trace`` (re-awakens an estimator whose gain has vanished, useful with
        μ = 1); ``"periodic"`` every ``reset_period`` updates. Default none: with μ < 1 the
        gain never vanishes, and every reset makes the residuals blind for a while
        (σ̂_θ jumps up with P).
    reset_trace : float, optional
        Floor of ``trace P`` for ``reset="floor"`` (default ``1e-6 · n_θ · P0``).
    reset_period : int, optional
        Updates between resets for ``reset="periodic"``.
    trace_max : float, optional
        Bound on ``trace P`` (default ``n_θ · P0``, the initial trace): without excitation
        forgetting would grow P as μ^-k; it is scaled back to this trace instead.
    svf_bandwidth : float, optional
        λ of the SVF in rad/s (continuous models only). Default: the largest pole
        magnitude of the estimated outputs (Garnier et al. 2003 recommend λ at or a
        little above the plant bandwidth), or ``0.2/Ts`` if all poles are at 0.
    noise_std : float or list of float, optional
        Standard deviation of white measurement noise on each estimated output (one
        value or one per output). It sets the floor of σ̂_e to the equation-error std it
        causes, ``noise_std · ||E||_2`` with ``E`` the filter from y to the equation
        error. Without it the floor is ``√eps`` times the RMS of ψ, which only keeps a
        noise-free plant from dividing by zero.
    noise_forgetting : float, optional
        Forgetting factor μ_σ of the equation-error variance estimate σ̂_e² (default
        ``1 - (1 - μ)/10``: a memory ten times the parameters', so that the errors of the
        estimator's transient after a fault do not inflate σ̂_e and mask the fault).
    sigma_clip : float
        Once one parameter memory ``1/(1-μ)`` has passed, errors beyond ``sigma_clip · σ``
        enter σ̂_e² as ``sigma_clip · σ`` (0: no clipping). For Gaussian noise the 3σ clip
        lowers σ̂_e² by 0.5 %.
    warmup : int, optional
        Samples after start or ``reset()`` during which the residual is 0 (default
        ``n + 2 n_θ``: n samples to fill the regressor, n_θ equations to determine θ,
        n_θ more for the variance estimate).

    Returns
    -------
    RLSEstimator

    Raises
    ------
    DesignError
        Naming the argument or output that fails: no inputs, order mismatch, forgetting
        outside (0, 1], non-finite or non-positive tuning, Ts missing or inconsistent.

    Notes
    -----
    Isolation: a parametric fault moves the residuals of the coefficients it changes. In
    the first ~1/(1-μ) samples after an abrupt change the estimator's memory holds data of
    two plants, and the least-squares estimate of mixed data is a *matrix*-weighted mean of
    the two parameter vectors: the other coefficients move transiently too. Read the
    pattern of residuals once that transient has passed (the tests use 5/(1-μ)).

    Runtime spec (``runtime_spec()``, kind ``"rls"``, version 1): ``dt``, ``n_inputs``
    (ny + nu), ``forgetting``, ``P0``, ``reset`` (``{"policy"}`` plus ``"period"`` for
    ``"periodic"``), ``noise_forgetting``, ``sigma_clip``, ``sigma_rel`` (relative floor of
    σ), and ``estimators``: one dict per output with ``output``, ``inputs`` (indices into
    [y; u]), the prefilter ``A, B, C, D`` (outputs ``[ψ; φ]``), ``theta0`` and ``scale``
    (internal → physical), ``names``, ``skip``, ``warmup``, ``sigma_floor``,
    ``trace_max`` and, for ``"floor"``, ``trace_min``.

    Examples
    --------
    >>> import numpy as np
    >>> from fmu_fdi import FDIModel
    >>> m = FDIModel.from_matrices([[0.9]], [[0.5]], [[1.0]], dt=0.1, u_names=["u"], y_names=["y"])
    >>> est = rls_estimator(m)
    >>> est.residual_names, {k: round(v, 12) for k, v in est.info["theta0"].items()}
    (['a1', 'b1_1'], {'a1': -0.9, 'b1_1': 0.5})
    """
    mu, P0, Ts, outputs, orders, noises, mu_sigma, sigma_clip = _arguments(
        model, forgetting, P0, Ts, output, order, noise_std, svf_bandwidth, reset, noise_forgetting, sigma_clip)

    rows = [_minimal_row(model, i, n) for i, n in zip(outputs, orders)]
    lam = _svf_bandwidth(model, rows, Ts, svf_bandwidth)
    estimators, names, groups, metas = [], [], [], []
    multi = len(outputs) > 1
    for i, G, sigma_y in zip(outputs, rows, noises):
        est, meta = _estimator(model, i, G, Ts, lam)
        prefix = f"{model.y_names[i]}." if multi else ""
        start = len(names)
        names += [prefix + nm for nm in meta["names"]]
        groups.append(list(range(start, len(names))))
        est.update(_estimator_tuning(G.n, len(meta["names"]), meta["noise_gain"], sigma_y, P0, reset,
                                     reset_trace, trace_max, warmup))
        estimators.append(est)
        metas.append(meta)

    reset_spec = _reset_spec(reset, reset_period)
    spec = {
        "kind": "rls", "version": 1, "dt": Ts, "n_inputs": model.ny + model.nu, "forgetting": mu, "P0": P0,
        "reset": reset_spec, "noise_forgetting": mu_sigma, "sigma_clip": sigma_clip,
        "sigma_rel": math.sqrt(np.finfo(float).eps), "estimators": estimators,
    }
    info = _info(model, outputs, rows, metas, Ts, lam, mu, mu_sigma, P0, reset_spec)
    return RLSEstimator(model, spec, names, groups, info)


# ---------------------------------------------------------------------- design stages
def _arguments(model, forgetting, P0, Ts, output, order, noise_std, svf_bandwidth, reset, noise_forgetting,
               sigma_clip) -> tuple:
    """The checked arguments of :func:`rls_estimator`: ``(μ, P0, Ts, outputs, orders,
    noise_stds, μ_σ, sigma_clip)``, or a DesignError naming the first that fails."""
    if not isinstance(model, FDIModel):
        raise DesignError(f"rls_estimator needs an FDIModel, got {type(model).__name__}")
    if model.nu == 0:
        raise DesignError(f"model '{model.name}' has no known inputs u: RLS estimates the u→y equation and "
                          f"needs at least one input")
    mu = _number(forgetting, "forgetting")
    if not 0.0 < mu <= 1.0:
        raise DesignError(f"forgetting must be in (0, 1], got {forgetting!r}")
    P0 = _number(P0, "P0", positive=True)
    Ts = _sample_time(model, Ts)
    outputs = _outputs(model, output)
    orders = _per_output(order, outputs, "order")
    noises = _per_output(noise_std, outputs, "noise_std")
    if model.is_discrete and svf_bandwidth is not None:
        raise DesignError("svf_bandwidth applies to continuous models only; this model is discrete")
    if reset not in _POLICIES:
        raise DesignError(f"reset must be one of {_POLICIES}, got {reset!r}")
    mu_sigma = 1.0 - (1.0 - mu) / 10.0 if noise_forgetting is None else _number(noise_forgetting,
                                                                                "noise_forgetting")
    if not 0.0 < mu_sigma <= 1.0:
        raise DesignError(f"noise_forgetting must be in (0, 1], got {noise_forgetting!r}")
    sigma_clip = _number(sigma_clip, "sigma_clip")
    return mu, P0, Ts, outputs, orders, noises, mu_sigma, sigma_clip


def _minimal_row(model: FDIModel, i: int, n) -> LTI:
    """The minimal realisation of row ``Gu[i, :]``, checked against the requested order n."""
    G = LTI(model.A, model.Bu, model.C[[i]], model.Du[[i]], model.dt).minreal()
    if G.n == 0 and not np.any(G.D):
        raise DesignError(f"output '{model.y_names[i]}' does not depend on the known inputs: nothing to estimate")
    if n is not None:
        n = _integer(n, f"order of '{model.y_names[i]}'")
        if n != G.n:
            raise DesignError(
                f"order {n} of output '{model.y_names[i]}' {'exceeds' if n > G.n else 'is below'} its minimal "
                f"order {G.n} (McMillan degree of Gu[{model.y_names[i]}, :]): "
                + ("the parameters are not unique (pole-zero cancellation)" if n > G.n
                   else "the equation cannot represent the plant")
            )
    return G


def _svf_bandwidth(model: FDIModel, rows: list[LTI], Ts: float, svf_bandwidth) -> float | None:
    """λ of the SVF: None for a discrete model; else the given one, or the largest pole
    magnitude of the estimated rows (``0.2/Ts`` if all poles are at 0)."""
    if model.is_discrete:
        return None
    if svf_bandwidth is not None:
        return _number(svf_bandwidth, "svf_bandwidth", positive=True)
    mags = np.concatenate([np.abs(G.poles()) for G in rows])
    return float(mags.max()) if mags.size and mags.max() > 0 else 0.2 / Ts


def _estimator_tuning(n: int, npar: int, noise_gain: float, sigma_y, P0: float, reset, reset_trace,
                      trace_max, warmup) -> dict:
    """The per-estimator runtime entries ``skip``, ``warmup``, ``sigma_floor``, ``trace_max``
    and ``trace_min`` of an output of order n with npar parameters (defaults: see
    :func:`rls_estimator`)."""
    out = {"skip": n, "warmup": n + 2 * npar if warmup is None else _integer(warmup, "warmup", low=n)}
    if sigma_y is not None:
        out["sigma_floor"] = _number(sigma_y, "noise_std", positive=False) * noise_gain
    out["trace_max"] = npar * P0 if trace_max is None else _number(trace_max, "trace_max", positive=True)
    if reset == "floor":
        out["trace_min"] = (1e-6 * npar * P0 if reset_trace is None
                            else _number(reset_trace, "reset_trace", positive=True))
        if out["trace_min"] >= out["trace_max"]:
            raise DesignError(f"reset_trace {out['trace_min']:g} must be below trace_max {out['trace_max']:g}")
    return out


def _reset_spec(reset, reset_period) -> dict:
    """The runtime's ``reset`` entry: ``{"policy"}``, plus ``"period"`` for ``"periodic"``."""
    policy = reset or "none"
    reset_spec: dict = {"policy": policy}
    if policy == "periodic":
        if reset_period is None:
            raise DesignError("reset='periodic' needs reset_period (updates between resets)")
        reset_spec["period"] = _integer(reset_period, "reset_period", low=1)
    return reset_spec


def _info(model: FDIModel, outputs, rows, metas, Ts, lam, mu, mu_sigma, P0, reset_spec) -> dict:
    """The estimator's ``info``: the tuning, θ0 and the regressors (θ_c and the SVF bias for a
    continuous model)."""
    multi = len(outputs) > 1
    info = {
        "form": "ARX" if model.is_discrete else "SVF",
        "outputs": [model.y_names[i] for i in outputs],
        "order": [G.n for G in rows],
        "Ts": Ts,
        "svf_bandwidth": lam,
        "forgetting": mu,
        "noise_forgetting": mu_sigma,
        "P0": P0,
        "reset": reset_spec,
        "theta0": _merge(metas, "theta0", multi, outputs, model),
        "regressor": {model.y_names[i]: m["regressor"] for i, m in zip(outputs, metas)},
        "unmodelled_inputs": list(model.d_names) + list(model.w_names),
    }
    if not model.is_discrete:
        info["theta_continuous"] = _merge(metas, "theta_continuous", multi, outputs, model)
        info["svf_bias"] = {k: info["theta0"][k] - info["theta_continuous"][k] for k in info["theta0"]}
    return info


# ------------------------------------------------------------------------- prefilters
def _shift_taps(n: int, dt: float) -> LTI:
    """Discrete taps ``[s[k], s[k-1], ..., s[k-n]]`` of one signal s (shift register)."""
    A = np.eye(n, k=-1)
    B = np.zeros((n, 1))
    if n:
        B[0, 0] = 1.0
    C = np.vstack([np.zeros((1, n)), np.eye(n)])
    D = np.zeros((n + 1, 1))
    D[0, 0] = 1.0
    return LTI(A, B, C, D, dt)


def _svf_taps(n: int, lam: float) -> LTI:
    """Continuous taps ``[(s/λ)^n F, ..., (s/λ) F, F]`` of one signal, ``F = (λ/(s+λ))^n``.

    Companion realisation in the normalised operator σ = s/λ: state ``z_j = σ^{j-1} F s``,
    ``σ z_n = σ^n F s = -Σ_k C(n,k) z_{k+1} + s`` from ``(σ+1)^n = Σ_k C(n,k) σ^k``.
    """
    c = np.array([comb(n, k) for k in range(n)], float)
    A = np.eye(n, k=1)
    if n:
        A[-1, :] = -c
    B = np.zeros((n, 1))
    if n:
        B[-1, 0] = 1.0
    C = np.vstack([A[-1:] if n else np.zeros((1, 0)), np.eye(n)[::-1]])
    D = np.zeros((n + 1, 1))
    D[0, 0] = 1.0
    return LTI(lam * A, lam * B, C, D, 0.0)


def _estimator(model: FDIModel, i: int, G: LTI, Ts: float, lam: float | None) -> tuple[dict, dict]:
    """Spec and metadata of the MISO estimator of output i (G: its minimal row of Gu)."""
    n, m = G.n, model.nu
    y = model.y_names[i]
    feed = [bool(G.D[0, j] != 0) for j in range(m)]
    # Parameter layout: a_1..a_n on taps 1..n of y; b_{j,l} on tap l of u_j.
    sel = [(0, 0, +1.0)] + [(0, k, -1.0) for k in range(1, n + 1)]
    names = [f"a{k}" for k in range(1, n + 1)]
    scale = [lam ** k if lam else 1.0 for k in range(1, n + 1)]
    for j in range(m):
        for l in range(0 if feed[j] else 1, n + 1):
            sel.append((1 + j, l, +1.0))
            names.append(f"b{j + 1}_{l}")
            scale.append(lam ** l if lam else 1.0)
    S = np.zeros((len(sel), (1 + m) * (n + 1)))
    for r, (sig, tap, sign) in enumerate(sel):
        S[r, sig * (n + 1) + tap] = sign

    def prefilter(taps: LTI) -> LTI:
        return S @ blockdiag([taps] * (1 + m))  # the same taps on y_i, u_1, ..., u_m

    if model.is_discrete:
        taps = _shift_taps(n, Ts)
        Gd = G
    else:
        taps_c = _svf_taps(n, lam)
        taps = taps_c.to_discrete(Ts)
        Gd = G.to_discrete(Ts)
    Pi = prefilter(taps)
    theta = _nominal(Pi, Gd, y)
    meta = {"names": names}
    sc = np.array(scale)
    meta["theta0"] = dict(zip(names, (theta * sc).tolist()))
    if not model.is_discrete:
        theta_c = _nominal(prefilter(taps_c), G, y)
        meta["theta_continuous"] = dict(zip(names, (theta_c * sc).tolist()))
    # Equation error caused by white noise on y: E = taps_0 + Σ_k θ_{a_k} taps_k, from y.
    E = np.concatenate([[1.0], theta[:n]])[None, :] @ taps
    meta["noise_gain"] = E.h2norm()
    meta["regressor"] = _describe(y, model.u_names, sel, n, lam)
    est = {
        "output": y, "inputs": [i] + [model.ny + j for j in range(m)],
        "A": Pi.A.tolist(), "B": Pi.B.tolist(), "C": Pi.C.tolist(), "D": Pi.D.tolist(),
        "theta0": theta.tolist(), "scale": sc.tolist(), "names": names,
    }
    return est, meta


def _nominal(Pi: LTI, G: LTI, y: str) -> np.ndarray:
    """θ with ``ψ = φᵀ θ`` along ``[ψ; φ] = Π [G; I] u`` at every frequency (least squares).

    The system is consistent by construction when the order is the minimal one; the
    relative residual and the condition number (after column scaling) are checked so
    that a wrong structure fails here, with its name, rather than as a false alarm.
    """
    m = G.m
    cascade = Pi @ LTI(G.A, G.B, np.vstack([G.C, np.zeros((m, G.n))]), np.vstack([G.D, np.eye(m)]), G.dt)
    w = frequency_grid([cascade], num=200)
    w = w[w > 0]  # integrators: G is infinite at ω = 0
    H = cascade.freqresp(w)
    ok = np.all(np.isfinite(H), axis=(1, 2))
    H = H[ok]
    psi = H[:, 0, :].reshape(-1)
    phi = np.transpose(H[:, 1:, :], (0, 2, 1)).reshape(-1, H.shape[1] - 1)
    M = np.vstack([phi.real, phi.imag])
    h = np.concatenate([psi.real, psi.imag])
    colnorm = np.linalg.norm(M, axis=0)
    if np.any(colnorm == 0):
        raise DesignError(f"output '{y}': a regressor column has no response; the parameters are not identifiable")
    Ms = M / colnorm
    s = np.linalg.svd(Ms, compute_uv=False)
    cond = s[0] / s[-1] if s[-1] > 0 else np.inf
    if cond > 1e10:
        raise DesignError(f"output '{y}': the regression is singular (condition {cond:.2g}); "
                          f"the parameters are not identifiable")
    sol, *_ = np.linalg.lstsq(Ms, h, rcond=None)
    theta = sol / colnorm
    rel = np.linalg.norm(M @ theta - h) / max(np.linalg.norm(h), np.finfo(float).tiny)
    # Exact in theory; rounding gives ~eps·cond. 1e-6 leaves a wide margin yet still
    # catches a structural misfit, which is O(1).
    if rel > 1e-6:
        raise DesignError(f"output '{y}': the equation does not hold exactly for the model "
                          f"(relative equation error {rel:.2g})")
    return theta


def _describe(y: str, u_names, sel, n: int, lam: float | None) -> dict:
    names = [y] + list(u_names)

    def tap(sig: int, l: int) -> str:
        s = names[sig]
        if lam is None:
            return f"{s}[k-{l}]" if l else f"{s}[k]"
        k = n - l
        return f"(s/λ)^{k} F {s}" if k else f"F {s}"

    terms = [("-" if sign < 0 else "") + tap(sig, l) for sig, l, sign in sel]
    out = {"target": terms[0], "phi": terms[1:]}
    if lam is not None:
        out["F"] = f"(λ/(s+λ))^{n}, λ = {lam:g} rad/s, ZOH at Ts"
    return out


def _merge(metas, key, multi, outputs, model) -> dict:
    out = {}
    for i, meta in zip(outputs, metas):
        for nm, val in meta[key].items():
            out[(f"{model.y_names[i]}." if multi else "") + nm] = val
    return out


# ------------------------------------------------------------------------ validation
def _number(value, name: str, positive: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise DesignError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x):
        raise DesignError(f"{name} must be finite, got {value!r}")
    if positive and x <= 0:
        raise DesignError(f"{name} must be positive, got {value!r}")
    if not positive and x < 0:
        raise DesignError(f"{name} must be >= 0, got {value!r}")
    return x


def _integer(value, name: str, low: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise DesignError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def _sample_time(model: FDIModel, Ts) -> float:
    if model.is_discrete:
        if Ts is not None and abs(_number(Ts, "Ts", positive=True) - model.dt) > 1e-12 * model.dt:
            raise DesignError(f"Ts={Ts!r} differs from the discrete model's dt={model.dt!r}; omit Ts")
        return model.dt
    if Ts is None:
        raise DesignError("Ts (the runtime sample time) is required for a continuous model")
    return _number(Ts, "Ts", positive=True)


def _outputs(model: FDIModel, output) -> list[int]:
    if output is None:
        return list(range(model.ny))
    names = [output] if isinstance(output, str) else list(output)
    if not names:
        raise DesignError("output must name at least one output")
    out = []
    for nm in names:
        if nm not in model.y_names:
            raise DesignError(f"output {nm!r} is not an output of the model {model.y_names}")
        if model.y_names.index(nm) in out:
            raise DesignError(f"output {nm!r} is listed twice")
        out.append(model.y_names.index(nm))
    return out


def _per_output(value, outputs: list[int], name: str) -> list:
    if value is None or np.isscalar(value):
        return [value] * len(outputs)
    values = list(value)
    if len(values) != len(outputs):
        raise DesignError(f"{name} has {len(values)} entries for {len(outputs)} estimated outputs")
    return values
