"""Recursive least squares with forgetting at run time: one sample in, residuals out.

numpy and the standard library only (bundled into the FMU as it is). The design side,
:func:`fmu_fdi.design.problems.rls.rls_estimator`, writes the spec this module reads.

Each *estimator* (one per estimated output) owns a linear prefilter, discrete and exact,

    x[k+1] = A x[k] + B w[k],    [ψ[k]; φ[k]] = C x[k] + D w[k],    w = v[inputs],

that turns the samples ``w = [y_i; u]`` into the target ψ and the regressor φ of the
linear-in-parameters equation ``ψ[k] = φ[k]ᵀ θ + e[k]``: shift registers for an ARX
model, a state-variable filter for a continuous model. The parameters are tracked by
recursive least squares with exponential forgetting μ (Ljung 1999, sec. 11.2;
Isermann & Münchhof 2011):

    ε    = ψ - φᵀ θ̂                       a priori equation error
    s    = μ + φᵀ P φ
    K    = P φ / s
    θ̂   ← θ̂ + K ε
    P    ← [(I - K φᵀ) P (I - K φᵀ)ᵀ + μ K Kᵀ] / μ      (Joseph form)

The Joseph form equals the textbook ``(P - K φᵀ P)/μ`` in exact arithmetic but is a sum
of positive semidefinite terms, so rounding cannot make P indefinite; P is then
symmetrised. Safeguards:

- *trace bound*: without excitation (φ = 0) forgetting divides P by μ every sample and
  P would grow without bound ("estimator wind-up"); whenever ``trace P > trace_max``
  P is scaled down to ``trace P = trace_max``, which keeps its shape (and hence the
  directions that are excited) and keeps it positive definite;
- *covariance reset* (optional): ``P ← P0 I`` when ``trace P < trace_min``
  (policy ``"floor"``, re-awakens an estimator whose gain has shrunk, typically with
  μ = 1) or every ``period`` updates (policy ``"periodic"``).

The equation-error variance is estimated recursively from the normalised a priori
error (whose variance is σ_e² under the RLS/Kalman interpretation of forgetting),

    σ̂_e² ← σ̂_e² + γ (min(ε² μ / s, c² σ²) - σ̂_e²),     γ = max(1/n, 1 - μ_σ),

with n the number of updates (a plain running mean until the window 1/(1-μ_σ) is
full). Its memory is longer than the parameters' (default μ_σ = 1 - (1-μ)/10) and, once
one parameter memory 1/(1-μ) has passed, errors are clipped at c = ``sigma_clip``
floored standard deviations σ (below): the large errors of the estimator's transient
after a parameter change are evidence of the change, and counting them as noise would
inflate σ̂ and mask it (for Gaussian noise the 3σ clip lowers σ̂_e² by 0.5 %). The
residual of parameter i is the deviation from nominal in units of the estimated
standard deviation,

    r_i = (θ̂_i - θ0_i) / sqrt(P_ii σ²),    σ² = max(σ̂_e², σ_floor², (ρ ψ_rms)²),

where ψ_rms is a forgetting RMS of the target. The floor σ_floor comes from the
design's measurement-noise level, and the relative floor ρ (default √eps) keeps a
noise-free plant, whose equation error is pure rounding, from dividing by zero. For
stationary data the covariance of θ̂ is about ``σ_e² P/(1 + μ)`` (weights μ^j in P⁻¹,
μ^{2j} in the covariance), so ``r_i`` has a standard deviation near ``1/sqrt(1+μ)`` ≤ 1:
the scaling is conservative for μ < 1.

Start-up: θ̂ starts at θ0 and P at ``P0 I``. The first ``skip`` samples only fill the
prefilter (no update: the regressor is not yet defined by data); the residual is exactly
0 until ``warmup`` samples have been seen (the regressor has not yet been excited in
every direction, so the estimates and their deviations mean nothing yet).

References
----------
Ljung, L. (1999). *System Identification: Theory for the User*, 2nd ed., ch. 11.
Isermann, R., Münchhof, M. (2011). *Identification of Dynamic Systems*. Springer.
Young, P. (1981). Parameter estimation for continuous-time models — a survey.
Automatica 17(1), 23-39 (state-variable filters).
"""
from __future__ import annotations

import math

import numpy as np

POLICIES = ("none", "floor", "periodic")


def _matrix(value, rows: int, cols: int, what: str) -> np.ndarray:
    M = np.asarray(value, float)
    if M.size == 0 and rows * cols == 0:
        return np.zeros((rows, cols))
    if M.shape != (rows, cols):
        raise ValueError(f"rls spec: {what} must have shape ({rows}, {cols}), got {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ValueError(f"rls spec: {what} contains NaN or Inf")
    return M


def _dot(a, b) -> float:
    """Σ a_i b_i from 0.0, in index order (the C runtime's order)."""
    acc = 0.0
    for x, y in zip(a, b):
        acc += x * y
    return acc


def _mv(M, x) -> list:
    """M x (M a list of rows), every row summed from 0.0 in column order (fdi_matvec)."""
    return [_dot(row, x) for row in M]


def _trace(P) -> float:
    acc = 0.0
    for r in range(len(P)):
        acc += P[r][r]
    return acc


class _Estimator:
    """The constant data of one estimator (prefilter, nominal parameters, counts)."""

    def __init__(self, spec: dict, n_inputs: int, P0: float, index: int):
        where = f"estimator {index}"
        self.inputs = np.asarray(spec["inputs"], dtype=int).ravel()
        if self.inputs.size == 0 or self.inputs.min() < 0 or self.inputs.max() >= n_inputs:
            raise ValueError(f"rls spec: {where} inputs {self.inputs.tolist()} must index 0..{n_inputs - 1}")
        self.theta0 = np.asarray(spec["theta0"], float).ravel()
        npar = self.theta0.size
        if npar == 0 or not np.all(np.isfinite(self.theta0)):
            raise ValueError(f"rls spec: {where} theta0 must be a non-empty finite vector")
        m = self.inputs.size
        nx = len(spec["A"])
        self.A = _matrix(spec["A"], nx, nx, f"{where} A")
        self.B = _matrix(spec["B"], nx, m, f"{where} B")
        self.C = _matrix(spec["C"], npar + 1, nx, f"{where} C")
        self.D = _matrix(spec["D"], npar + 1, m, f"{where} D")
        self.scale = np.asarray(spec.get("scale", np.ones(npar)), float).ravel()
        if self.scale.shape != (npar,) or not np.all(self.scale > 0):
            raise ValueError(f"rls spec: {where} scale must be {npar} positive numbers")
        self.skip = int(spec.get("skip", 0))
        self.warmup = int(spec.get("warmup", self.skip + npar))
        if not 0 <= self.skip <= self.warmup:
            raise ValueError(f"rls spec: {where} needs 0 <= skip <= warmup, got {self.skip}, {self.warmup}")
        self.sigma_floor = float(spec.get("sigma_floor", 0.0))
        if not (self.sigma_floor >= 0 and math.isfinite(self.sigma_floor)):
            raise ValueError(f"rls spec: {where} sigma_floor must be a finite number >= 0")
        self.trace_max = float(spec.get("trace_max", npar * P0))
        if not (self.trace_max > 0 and math.isfinite(self.trace_max)):
            raise ValueError(f"rls spec: {where} trace_max must be a finite positive number, got {self.trace_max!r}")
        self.trace_min = float(spec.get("trace_min", 0.0))
        if not 0 <= self.trace_min < self.trace_max:
            raise ValueError(f"rls spec: {where} trace_min must be in [0, trace_max), got {self.trace_min!r}")
        self.npar, self.nx = npar, nx
        # row lists for the sequential sums of the prefilter (docs/semantics.md §4.2)
        self.Al, self.Bl, self.Cl, self.Dl = (M.tolist() for M in (self.A, self.B, self.C, self.D))


class RLSStep:
    """Residuals of recursive least-squares parameter estimation, one sample at a time.

    Implements the runtime generator interface of :mod:`.generators` (``step``,
    ``get_state``, ``set_state``, ``reset``) for specs of kind ``"rls"``. See the module
    docstring for the equations and :func:`fmu_fdi.design.problems.rls.rls_estimator` for the
    spec's keys.
    """

    kind = "rls"

    def __init__(self, spec: dict):
        if spec.get("kind") != "rls":
            raise ValueError(f"RLSStep needs a spec of kind 'rls', got {spec.get('kind')!r}")
        self.n_inputs = int(spec["n_inputs"])
        if self.n_inputs < 1:
            raise ValueError(f"rls spec: n_inputs must be >= 1, got {spec['n_inputs']!r}")
        mu = float(spec["forgetting"])
        if not 0.0 < mu <= 1.0:
            raise ValueError(f"rls spec: forgetting must be in (0, 1], got {mu!r}")
        self.mu = mu
        self.P0 = float(spec["P0"])
        if not (self.P0 > 0 and math.isfinite(self.P0)):
            raise ValueError(f"rls spec: P0 must be a finite positive number, got {spec['P0']!r}")
        ests = spec.get("estimators") or []
        if not ests:
            raise ValueError("rls spec: 'estimators' must list at least one estimator")
        self.estimators = [_Estimator(e, self.n_inputs, self.P0, i) for i, e in enumerate(ests)]
        reset = dict(spec.get("reset") or {"policy": "none"})
        self.policy = reset.get("policy", "none")
        if self.policy not in POLICIES:
            raise ValueError(f"rls spec: reset policy must be one of {POLICIES}, got {self.policy!r}")
        self.period = int(reset.get("period", 0))
        if self.policy == "floor" and not all(e.trace_min > 0 for e in self.estimators):
            raise ValueError("rls spec: reset policy 'floor' needs trace_min > 0 in every estimator")
        if self.policy == "periodic" and self.period < 1:
            raise ValueError(f"rls spec: reset period must be a positive number of updates, got {self.period!r}")
        self.sigma_rel = float(spec.get("sigma_rel", math.sqrt(np.finfo(float).eps)))
        self.mu_sigma = float(spec.get("noise_forgetting", 1.0 - (1.0 - mu) / 10.0))
        if not 0.0 < self.mu_sigma <= 1.0:
            raise ValueError(f"rls spec: noise_forgetting must be in (0, 1], got {self.mu_sigma!r}")
        self.clip = float(spec.get("sigma_clip", 3.0))
        if not self.clip >= 0:
            raise ValueError(f"rls spec: sigma_clip must be >= 0 (0: no clipping), got {self.clip!r}")
        # One parameter memory 1/(1-μ) (rounded, so μ = 0.98 gives 50); never with μ = 1,
        # where σ̂ is a running mean over all updates and a fault is diluted anyway.
        self.clip_after = round(1.0 / (1.0 - mu)) if mu < 1.0 else math.inf
        self.n_outputs = sum(e.npar for e in self.estimators)
        self.reset()

    # ---------------------------------------------------------------- state
    def reset(self) -> None:
        """Back to the state right after construction: θ̂ = θ0, P = P0 I, no samples seen."""
        self.k = 0
        self._x = [np.zeros(e.nx) for e in self.estimators]
        self._theta = [e.theta0.copy() for e in self.estimators]
        self._P = [self.P0 * np.eye(e.npar) for e in self.estimators]
        self._sigma2 = [0.0 for _ in self.estimators]
        self._psi2 = [0.0 for _ in self.estimators]
        self._updates = [0 for _ in self.estimators]
        self._resets = [0 for _ in self.estimators]

    def get_state(self) -> dict:
        """Everything that evolves, as JSON-serialisable lists (exact float round trip)."""
        return {
            "k": self.k,
            "estimators": [
                {"x": x.tolist(), "theta": th.tolist(), "P": P.tolist(), "sigma2": s2, "psi2": q2,
                 "updates": nu, "resets": nr}
                for x, th, P, s2, q2, nu, nr in zip(self._x, self._theta, self._P, self._sigma2, self._psi2,
                                                    self._updates, self._resets)
            ],
        }

    def set_state(self, state: dict) -> None:
        """Restore a state from :meth:`get_state`; shapes are checked before anything changes."""
        items = state.get("estimators", [])
        if len(items) != len(self.estimators):
            raise ValueError(f"rls state has {len(items)} estimators, this generator has {len(self.estimators)}")
        new = []
        k = int(state["k"])
        if not 0 <= k < 2 ** 53:
            raise ValueError(f"rls state: sample counter {k} outside [0, 2^53)")
        for i, (est, item) in enumerate(zip(self.estimators, items)):
            x = np.array(item["x"], float).reshape(-1)
            th = np.array(item["theta"], float).reshape(-1)
            P = np.array(item["P"], float)
            if x.shape != (est.nx,) or th.shape != (est.npar,) or P.shape != (est.npar, est.npar):
                raise ValueError(
                    f"rls state of estimator {i}: expected x ({est.nx},), theta ({est.npar},), "
                    f"P ({est.npar}, {est.npar}); got {x.shape}, {th.shape}, {P.shape}"
                )
            entry = (x, th, P, float(item["sigma2"]), float(item["psi2"]), int(item["updates"]), int(item["resets"]))
            if not (all(np.isfinite(a).all() for a in entry[:3]) and math.isfinite(entry[3])
                    and math.isfinite(entry[4])):
                raise ValueError(f"rls state of estimator {i} holds NaN or Inf")
            self._check_counts(i, est, k, *entry)
            new.append(entry)
        self.k = k
        (self._x, self._theta, self._P, self._sigma2, self._psi2, self._updates,
         self._resets) = (list(t) for t in zip(*new))

    def _check_counts(self, i, est, k, x, th, P, sigma2, psi2, updates, resets) -> None:
        """A state as a run from reset leaves it (docs/semantics.md §10): every sample from ``skip``
        on updates, resets as the policy makes them, P exactly symmetric (symmetrised every
        update), the noise estimates >= 0."""
        want = max(0, k - est.skip)
        policy_ok = (resets == updates // self.period if self.policy == "periodic"
                     else resets <= updates if self.policy == "floor" else resets == 0)
        if updates != want or not 0 <= resets <= updates or not policy_ok:
            raise ValueError(f"rls state of estimator {i}: {updates} updates and {resets} resets after {k} samples "
                             f"(expected {want} updates, resets by the '{self.policy}' policy)")
        if not (sigma2 >= 0.0 and psi2 >= 0.0 and np.array_equal(P, P.T)):
            raise ValueError(f"rls state of estimator {i}: P not symmetric or a negative noise estimate")

    def finite(self) -> bool:
        """Every entry of the state (x, θ̂, P, σ̂², ψ²_ms of every estimator) is finite."""
        return (all(bool(np.isfinite(a).all()) for arrays in (self._x, self._theta, self._P) for a in arrays)
                and all(map(math.isfinite, self._sigma2)) and all(map(math.isfinite, self._psi2)))

    # ----------------------------------------------------------------- step
    def step(self, v) -> np.ndarray:
        """Feed one sample ``v = [y; u]``; returns the residual vector (one entry per parameter).

        Raises ValueError, without changing the state, when ``v`` has the wrong length or a
        NaN/Inf entry: one bad sample would otherwise corrupt θ̂ and P for good.
        """
        v = np.asarray(v, float).reshape(-1)
        if v.shape != (self.n_inputs,):
            raise ValueError(f"rls step: expected {self.n_inputs} values [y; u], got {v.shape[0]}")
        bad = ~np.isfinite(v)
        if bad.any():
            raise ValueError(f"rls step: input sample contains NaN or Inf at {np.flatnonzero(bad).tolist()}")
        with np.errstate(over="ignore", invalid="ignore"):  # overflow → inf/NaN, caught by finite() (S1)
            out = [self._step_one(i, est, v[est.inputs]) for i, est in enumerate(self.estimators)]
        self.k += 1
        return np.concatenate(out)

    def run(self, V) -> np.ndarray:
        """:meth:`step` over the rows of ``V`` (N × inputs); returns the residuals (N × outputs)."""
        V = np.asarray(V, float)
        out = np.empty((V.shape[0], self.n_outputs))
        for k in range(V.shape[0]):
            out[k] = self.step(V[k])
        return out

    def _step_one(self, i: int, est: _Estimator, w: np.ndarray) -> np.ndarray:
        x, wl = self._x[i].tolist(), w.tolist()
        z = [a + b for a, b in zip(_mv(est.Cl, x), _mv(est.Dl, wl))]
        self._x[i] = np.array([a + b for a, b in zip(_mv(est.Al, x), _mv(est.Bl, wl))])
        if self.k < est.skip:
            return np.zeros(est.npar)
        self._update(i, z[0], z[1:])
        if self.k + 1 < est.warmup:
            return np.zeros(est.npar)
        return self._residual(i, est)

    def _update(self, i: int, psi: float, phi: list) -> None:
        """One RLS update, every sum sequential in index order (docs/semantics.md §4.2): the
        recursion amplifies last-bit differences of a summation order, so both runtimes use
        this one (the C runtime's fdi_rls.c does the same operations in the same order)."""
        est = self.estimators[i]
        mu, n_p = self.mu, est.npar
        P = self._P[i].tolist()
        theta = self._theta[i].tolist()
        Pphi = _mv(P, phi)
        s = mu + _dot(phi, Pphi)
        K = [a / s for a in Pphi]
        err = psi - _dot(phi, theta)
        self._theta[i] = np.array([t + k * err for t, k in zip(theta, K)])
        J = [[(1.0 if r == c else 0.0) - K[r] * phi[c] for c in range(n_p)] for r in range(n_p)]
        JP = [[_dot(row, [P[q][c] for q in range(n_p)]) for c in range(n_p)] for row in J]
        Pn = [[(_dot(JP[r], J[c]) + mu * (K[r] * K[c])) / mu for c in range(n_p)] for r in range(n_p)]
        P = [[0.5 * (Pn[r][c] + Pn[c][r]) for c in range(n_p)] for r in range(n_p)]
        tr = _trace(P)
        if tr > est.trace_max:
            f = est.trace_max / tr
            P = [[v * f for v in row] for row in P]
        n = self._updates[i] = self._updates[i] + 1
        if (self.policy == "floor" and _trace(P) < est.trace_min) or (
                self.policy == "periodic" and n % self.period == 0):
            P = [[self.P0 if r == c else 0.0 for c in range(n_p)] for r in range(n_p)]
            self._resets[i] += 1
        self._P[i] = np.array(P)
        gamma = max(1.0 / n, 1.0 - self.mu_sigma)
        e2 = err * err * mu / s
        if self.clip and n > self.clip_after:
            # Errors beyond clip·σ are fault evidence, not noise: letting them in would inflate
            # σ̂ and mask the very change the residual must show. Not before one parameter
            # memory has passed: σ̂ is not yet a reference then.
            sig = self._sigma(i, est)
            e2 = min(e2, (self.clip * self.clip) * (sig * sig))  # products: ** raises OverflowError
        self._sigma2[i] += gamma * (e2 - self._sigma2[i])
        self._psi2[i] += gamma * (psi * psi - self._psi2[i])

    def _sigma(self, i: int, est: _Estimator) -> float:
        """σ = sqrt(max(σ̂_e², σ_floor², ρ² ψ_ms)), the floored equation-error std."""
        return math.sqrt(max(self._sigma2[i], est.sigma_floor * est.sigma_floor,
                             (self.sigma_rel * self.sigma_rel) * self._psi2[i]))

    def _residual(self, i: int, est: _Estimator) -> np.ndarray:
        dev = self._theta[i] - est.theta0
        # sqrt taken separately so that a tiny σ² cannot underflow the product P_ii σ².
        den = np.sqrt(np.diag(self._P[i])) * self._sigma(i, est)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(den > 0, dev / np.where(den > 0, den, 1.0), 0.0)
        return r

    # ------------------------------------------------------------ estimates
    @property
    def theta(self) -> np.ndarray:
        """Current estimates in the design's physical coordinates, all estimators stacked."""
        return np.concatenate([th * e.scale for th, e in zip(self._theta, self.estimators)])

    @property
    def theta_std(self) -> np.ndarray:
        """``sqrt(P_ii σ²)`` in physical coordinates (the residual's denominators)."""
        out = []
        for i, est in enumerate(self.estimators):
            out.append(np.sqrt(np.diag(self._P[i])) * self._sigma(i, est) * est.scale)
        return np.concatenate(out)

    @property
    def P_traces(self) -> list[float]:
        """``trace P`` of every estimator (in the estimator's internal coordinates)."""
        return [float(np.trace(P)) for P in self._P]
