"""Innovation residual of the steady-state Kalman filter (Frank, section 5; Mehra & Peschon 1971).

Noise model assumed (w are the model's noise inputs, v an extra measurement noise):

    continuous:  x' = A x + Bu u + Bw w,           y = C x + Du u + Dw w + v,
                 w, v zero-mean white, E[w(t) w(τ)ᵀ] = Qw δ(t−τ), E[v(t) v(τ)ᵀ] = Rv δ(t−τ),
    discrete:    x[k+1] = A x[k] + Bu u[k] + Bw w[k],   y[k] = C x[k] + Du u[k] + Dw w[k] + v[k],
                 w, v zero-mean white sequences, E[w wᵀ] = Qw, E[v vᵀ] = Rv,

with w and v uncorrelated and both uncorrelated with the initial state. Hence the process
noise ``Bw w`` and the measurement noise ``Dw w + v`` have covariances
``Qx = Bw Qw Bwᵀ``, ``R = Dw Qw Dwᵀ + Rv`` and cross-covariance ``S = Bw Qw Dwᵀ``.
Unknown inputs d and faults f are zero in the nominal model; d is not decoupled (move it
to w to treat it as noise, or use the unknown-input observer).

Discrete time, filter form (not python-control's ``dlqe``, which returns the predictor
gain; python-control issue 1173): with ``x̂⁻[k] = x̂[k|k−1]``

    e[k]     = y[k] − C x̂⁻[k] − Du u[k]                       (innovation, the residual)
    x̂[k|k]  = x̂⁻[k] + K_f e[k],                K_f = P Cᵀ Σ⁻¹
    x̂⁻[k+1] = A x̂[k|k] + Bu u[k] + S Σ⁻¹ e[k]     (the last term: E[Bw w[k] | e[k]])

so ``x̂⁻[k+1] = A x̂⁻[k] + Bu u[k] + L e[k]`` with ``L = A K_f + S Σ⁻¹``, and the innovation
is white with covariance ``Σ = C P Cᵀ + R`` (P the prior error covariance, DARE). In
continuous time the innovation ``e = y − C x̂ − Du u`` is white with *intensity* ``Σ = R``
(Kailath 1968): the term ``C P Cᵀ`` has no continuous-time counterpart.

For χ² tests ``info`` holds ``Σ`` and ``Σ^{-1/2}``: ``‖Σ^{-1/2} e[k]‖²`` is χ²(p) under
the noise model.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import EPS, inv_sqrtm_pd
from ...model import FDIModel
from ._observer import filter_riccati, observable_order, observer_generator, output_observer, residual_names


def kalman(model: FDIModel, Qw=None, Rv=None, *, atol: float = 0.0) -> ResidualGenerator:
    """Innovation residual ``e = y − C x̂ − Du u`` of the steady-state Kalman filter.

    Parameters
    ----------
    model : FDIModel
        Continuous (CARE) or discrete (DARE, designed directly in discrete time).
    Qw : array_like or float, optional
        Covariance (discrete) or intensity (continuous) of the noise inputs w, nw×nw,
        symmetric positive semidefinite. A scalar means ``Qw·I``, a vector a diagonal.
        May be omitted when the model has no noise inputs.
    Rv : array_like or float
        Covariance (intensity) of the additional measurement noise v, p×p, symmetric
        positive semidefinite, with ``R = Dw Qw Dwᵀ + Rv`` positive definite. Scalar or
        vector as for Qw.
    atol : float
        Absolute rank tolerance of the observability staircase (Varga's ``atol``): singular values at or
        below ``max(rtol·||[A; C]||, atol)`` count as zero (default 0: relative only).

    Returns
    -------
    ResidualGenerator
        Filter from ``[y; u]`` to e (one residual group). ``info``: ``gain`` (L of the
        predictor form above), ``filter_gain`` K_f, ``P``, ``innovation_covariance`` Σ,
        ``whitening`` Σ^{-1/2}, ``innovation_kind`` ('covariance' or 'intensity'),
        ``noise_model``, ``poles``, ``detected_faults``; ``riccati_accuracy``: ``forward`` = ‖P_K − P‖_F/scale, P_K
        the error covariance of the filter run with the returned gain (its Lyapunov/Stein equation) — the forward
        error of P to first order, scale = max(‖P‖_F, the Lyapunov lower bound from Qx; riccati_newton.solution_scale),
        at most ``FORWARD_RTOL`` = 1e-6 — the ``newton_steps`` taken to get there, and
        ``gain_forward``, the gain's relative forward error to first order (from the same correction).

    Raises
    ------
    DesignError
        Qw or Rv of the wrong shape, not finite, not symmetric or not positive
        semidefinite; R singular; ``(A, C)`` not detectable (the unstable unobservable
        modes are named); no stabilising Riccati solution; an equation too ill-conditioned for the returned gain
        to be the stabilising solution's to ``FORWARD_RTOL`` (the correction, the closed loop's separation and the
        rounding floor are named).

    References
    ----------
    R. K. Mehra and J. Peschon, An innovations approach to fault detection and diagnosis in
    dynamic systems, Automatica 7, 1971.
    B. D. O. Anderson and J. B. Moore, *Optimal Filtering*, Prentice Hall 1979, ch. 3 and 5
    (correlated process and measurement noise).
    T. Kailath, An innovations approach to least-squares estimation, IEEE TAC 13, 1968.
    """
    n, p, nw = model.n, model.ny, model.nw
    if Rv is None:
        raise DesignError("Rv (measurement noise covariance, p×p) is required")
    if Qw is None:
        if nw:
            raise DesignError(f"Qw (noise covariance, {nw}x{nw}) is required: the model has noise inputs "
                              f"{model.w_names}")
        Qw = np.zeros((0, 0))
    Qw = _covariance(Qw, nw, "Qw", f"the noise inputs w {model.w_names}")
    Rv = _covariance(Rv, p, "Rv", f"the outputs {model.y_names}")
    Qx = model.Bw @ Qw @ model.Bw.T
    R = model.Dw @ Qw @ model.Dw.T + Rv
    S = model.Bw @ Qw @ model.Dw.T
    R = (R + R.T) / 2
    lam = sla.eigvalsh(R)
    if lam[0] <= 1e3 * EPS * p * max(lam[-1], np.finfo(float).tiny):
        raise DesignError(
            f"the measurement noise covariance R = Dw Qw Dwᵀ + Rv is singular (eigenvalues {lam.tolist()}): "
            f"the steady-state Kalman filter needs every output direction to be noisy; make Rv positive definite")
    observable_order(model.A, model.C, model.dt, what="(A, C)",
                     fixed_reason="no Kalman filter (no observer at all) has a stable error", atol=atol)
    kf = filter_riccati(model.A, model.C, Qx, R, S, model.dt, what="kalman")
    Q = output_observer(model, kf.L)
    info = {
        "gain": kf.L.tolist(), "filter_gain": kf.Kf.tolist(), "P": kf.P.tolist(),
        "innovation_covariance": kf.Sigma.tolist(), "whitening": inv_sqrtm_pd(kf.Sigma).tolist(),
        "innovation_kind": "covariance" if model.dt else "intensity",
        "noise_model": ("x[k+1] = A x + Bu u + Bw w, y = C x + Du u + Dw w + v; E[w wᵀ] = Qw, E[v vᵀ] = Rv, "
                        "w, v white and uncorrelated" if model.dt else
                        "x' = A x + Bu u + Bw w, y = C x + Du u + Dw w + v; w, v white with intensities Qw, Rv, "
                        "uncorrelated"),
        "Qw": Qw.tolist(), "Rv": Rv.tolist(),
        "poles": np.linalg.eigvals(model.A - kf.L @ model.C).tolist() if n else [],
        "riccati_accuracy": dict(kf.accuracy),
    }
    return observer_generator(model, Q, "kalman", info, residual_names(model))


def _covariance(X, k: int, what: str, of: str) -> np.ndarray:
    """A symmetric PSD k×k matrix from a scalar, a vector (diagonal) or a matrix."""
    try:
        M = np.asarray(X, dtype=float)
    except (TypeError, ValueError):
        raise DesignError(f"{what} must be a number, a vector of variances or a {k}x{k} matrix, got {X!r}") from None
    if M.ndim == 0:
        M = float(M) * np.eye(k)
    elif M.ndim == 1:
        if M.size != k:
            raise DesignError(f"{what} has {M.size} variances but there are {k} ({of})")
        M = np.diag(M)
    if M.ndim != 2 or M.shape != (k, k):
        raise DesignError(f"{what} must be {k}x{k} (one row and column for each of {of}), got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise DesignError(f"{what} contains NaN or Inf")
    if k == 0:
        return M
    norm = max(float(np.max(np.abs(M))), np.finfo(float).tiny)
    if np.max(np.abs(M - M.T)) > 1e3 * EPS * k * norm:
        raise DesignError(f"{what} is not symmetric (largest |{what} − {what}ᵀ| entry "
                          f"{np.max(np.abs(M - M.T)):.3g}): a covariance matrix must be")
    lam = sla.eigvalsh((M + M.T) / 2)
    if lam[0] < -1e3 * EPS * k * norm:
        raise DesignError(f"{what} is not positive semidefinite (smallest eigenvalue {lam[0]:.6g}): "
                          f"a covariance matrix must be")
    return (M + M.T) / 2
