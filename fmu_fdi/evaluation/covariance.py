"""Stationary autocovariance of a residual driven by white noise (and random disturbances).

Under H0 (no fault, known inputs decoupled) a discrete residual generator's internal form
leaves ``r = Rd(z) d + Rw(z) w``. With ``v = [d; w]`` a white Gaussian sequence of
covariance ``V = diag(Σd, Σw)`` and ``(A, B, C, D)`` a stable realisation of ``[Rd Rw]`` (and of ``Qy``
for a measurement noise outside the model),
the stationary state covariance solves the discrete Lyapunov equation

    P = A P Aᵀ + B V Bᵀ,

and the residual autocovariance ``Γ(k) = E[r(t+k) r(t)ᵀ]`` is

    Γ(0) = C P Cᵀ + D V Dᵀ,        Γ(k) = C A^{k-1} G,  G = A P Cᵀ + B V Dᵀ   (k ≥ 1),

with ``Γ(−k) = Γ(k)ᵀ`` (Söderström, *Discrete-time Stochastic Systems*, 2002, ch. 5).
A continuous generator is first discretised with a zero-order hold of every input: the
noise is then a piecewise-constant signal whose samples are independent with the given
covariance *per sample* (not a continuous white noise of that intensity).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..generator import ResidualGenerator
from ..lti import LTI


@dataclass(frozen=True)
class ResidualCovariance:
    """``Γ(0)`` and the factorisation ``Γ(k) = C A^{k-1} G`` (k ≥ 1) of a stationary residual."""

    A: np.ndarray
    G: np.ndarray
    C: np.ndarray
    Gamma0: np.ndarray

    @property
    def dim(self) -> int:
        return self.Gamma0.shape[0]

    def lags(self, max_lag: int) -> np.ndarray:
        """``Γ(0), ..., Γ(max_lag)`` stacked: shape (max_lag + 1, p, p)."""
        out = np.zeros((max_lag + 1, self.dim, self.dim))
        out[0] = self.Gamma0
        X = self.G
        for k in range(1, max_lag + 1):
            if X.size == 0:
                break
            out[k] = self.C @ X
            X = self.A @ X
        return out

    def weighted(self, W: np.ndarray) -> "ResidualCovariance":
        """The autocovariance of ``W r``."""
        return ResidualCovariance(self.A, self.G @ W.T, W @ self.C, W @ self.Gamma0 @ W.T)

    def discounted_energy(self, lam: float) -> float:
        """``Σ_{k≥1} λ^k ||Γ(k)||_F² = λ tr(Gᵀ X G)`` with ``X = λ Aᵀ X A + Cᵀ C``."""
        if self.A.shape[0] == 0:
            return 0.0
        X = sla.solve_discrete_lyapunov(np.sqrt(lam) * self.A.T, self.C.T @ self.C, method="bilinear")
        return float(lam * np.trace(self.G.T @ X @ self.G))


def _covariance(S, n: int, name: str) -> np.ndarray:
    S = np.asarray(S, dtype=float)
    if S.ndim == 0:
        S = S * np.eye(n)
    elif S.ndim == 1:
        S = np.diag(S)
    if S.shape != (n, n):
        raise ValueError(f"{name} must be a scalar, a length-{n} variance vector or a {n}x{n} matrix, got shape "
                         f"{S.shape}")
    if not np.all(np.isfinite(S)) or not np.allclose(S, S.T, rtol=1e-10, atol=0.0):
        raise ValueError(f"{name} must be a finite symmetric matrix")
    if n and np.linalg.eigvalsh(S).min() < -1e-12 * max(1.0, np.abs(S).max()):
        raise ValueError(f"{name} must be positive semidefinite (smallest eigenvalue "
                         f"{np.linalg.eigvalsh(S).min():.3g})")
    return S


def discrete_generator(gen: ResidualGenerator, Ts: float | None) -> ResidualGenerator:
    """``gen`` itself when discrete (checking ``Ts``), else its zero-order-hold discretisation."""
    if not isinstance(gen, ResidualGenerator):
        raise TypeError(f"expected a ResidualGenerator, got {type(gen).__name__}")
    if gen.dt == 0:
        if Ts is None:
            raise ValueError("the generator is continuous: give the sample time Ts of the evaluation")
        return gen.to_discrete(Ts)
    if Ts is not None and abs(float(Ts) - gen.dt) > 1e-9 * gen.dt:
        raise ValueError(f"Ts = {Ts} differs from the discrete generator's sample time {gen.dt}")
    return gen


def group_rows(gen: ResidualGenerator, group: int | None) -> list[int]:
    """Residual indices of one evaluation group (the only one when ``group`` is None)."""
    if group is None:
        if len(gen.groups) != 1:
            raise ValueError(f"the generator has {len(gen.groups)} residual groups: choose one with group=")
        return list(gen.groups[0])
    if not 0 <= int(group) < len(gen.groups):
        raise ValueError(f"group must be in 0..{len(gen.groups) - 1}, got {group}")
    return list(gen.groups[int(group)])


def residual_covariance(gen: ResidualGenerator, *, noise_cov=None, disturbance_cov=None, measurement_cov=None,
                        Ts: float | None = None, group: int | None = None) -> ResidualCovariance:
    """Stationary autocovariance (factorised) of one residual group under H0.

    See :func:`residual_autocovariance` for the parameters.
    """
    gen = discrete_generator(gen, Ts)
    rows = group_rows(gen, group)
    model = gen.model
    sl = model.group_slices()
    cols, covs = [], []
    for key, S, k, label in (("d", disturbance_cov, model.nd, "disturbance_cov"),
                             ("w", noise_cov, model.nw, "noise_cov")):
        if S is None:
            continue
        if k == 0:
            raise ValueError(f"{label} given but the model has no {'disturbance' if key == 'd' else 'noise'} inputs")
        cols.extend(range(sl[key].start, sl[key].stop))
        covs.append(_covariance(S, k, label))
    # measurement noise v outside the model (y + v): extra plant inputs with D = [I; 0]
    aug = model.augmented()
    if measurement_cov is not None:
        extra = np.vstack([np.eye(model.ny), np.zeros((model.nu, model.ny))])
        aug = LTI(aug.A, np.hstack([aug.B, np.zeros((model.n, model.ny))]), aug.C, np.hstack([aug.D, extra]), aug.dt)
        cols.extend(range(aug.m - model.ny, aug.m))
        covs.append(_covariance(measurement_cov, model.ny, "measurement_cov"))
    if not cols:
        raise ValueError("give noise_cov, disturbance_cov and/or measurement_cov: the residual's covariance comes "
                         "from them")
    # Only the plant modes the noise reaches belong in R: composing the whole plant and leaving
    # minreal to cancel the rest failed for unstable modes (an open-loop unstable plant with
    # measurement noise only was called "not stable").
    R = (gen.Q[rows, :] @ aug[:, cols].minreal(job="C")).minreal()
    V = sla.block_diag(*covs)
    if R.n and np.max(np.abs(R.poles())) >= 1.0:
        raise ValueError(f"the residual's response to the noise is not stable (largest pole modulus "
                         f"{np.max(np.abs(R.poles())):.6g}): it has no stationary covariance")
    if R.n:
        # Schur-based (bilinear transform, Bartels–Stewart) whatever the size: scipy's default
        # below 10 states solves the Kronecker system, which lost 1.2 % on the non-normal
        # realisation of poles clustered near z = 1 (a VTOL DOS residual, eigenvector
        # condition 4e8; the Schur route: 1.2e-3)
        P = sla.solve_discrete_lyapunov(R.A, R.B @ V @ R.B.T, method="bilinear")
        P = 0.5 * (P + P.T)
        G = R.A @ P @ R.C.T + R.B @ V @ R.D.T
    else:
        P, G = np.zeros((0, 0)), np.zeros((0, R.p))
    Gamma0 = R.C @ P @ R.C.T + R.D @ V @ R.D.T
    return ResidualCovariance(R.A, G, R.C, 0.5 * (Gamma0 + Gamma0.T))


def residual_autocovariance(gen: ResidualGenerator, max_lag: int, *, noise_cov=None, disturbance_cov=None,
                            measurement_cov=None, Ts: float | None = None, group: int | None = None) -> np.ndarray:
    """Autocovariance ``Γ(k) = E[r(t+k) r(t)ᵀ]``, k = 0..max_lag, of a stationary residual.

    Parameters
    ----------
    gen : ResidualGenerator
        Discrete, or continuous with ``Ts`` (zero-order-hold discretisation).
    max_lag : int
        Largest lag returned.
    noise_cov : float, (nw,) or (nw, nw) array_like, optional
        Covariance per sample of the white noise inputs w.
    disturbance_cov : float, (nd,) or (nd, nd) array_like, optional
        Covariance per sample of the disturbances d when they are treated as white noise
        (omit for disturbances the design decouples or that are absent).
    measurement_cov : float, (ny,) or (ny, ny) array_like, optional
        Covariance per sample of a white noise v added to the measured outputs beyond the
        model's w (``y + v``; e.g. the ``Rv`` of :func:`~fmu_fdi.design.kalman`).
    Ts : float, optional
        Sample time (required for a continuous generator).
    group : int, optional
        Residual group (0-based); may be omitted for a single-group generator.

    Returns
    -------
    ndarray, shape (max_lag + 1, p, p)

    Notes
    -----
    ``Γ(0) = C P Cᵀ + D V Dᵀ`` and ``Γ(k) = C A^{k-1}(A P Cᵀ + B V Dᵀ)`` for the
    realisation ``(A, B, C, D)`` of ``[Rd Rw]`` restricted to the group, with ``P`` the
    stationary solution of ``P = A P Aᵀ + B V Bᵀ``. Known inputs are assumed decoupled
    (``Ru = 0``): their contribution is deterministic and not part of the covariance.
    """
    if int(max_lag) < 0:
        raise ValueError(f"max_lag must be >= 0, got {max_lag}")
    cov = residual_covariance(gen, noise_cov=noise_cov, disturbance_cov=disturbance_cov,
                              measurement_cov=measurement_cov, Ts=Ts, group=group)
    return cov.lags(int(max_lag))
