"""Noise models for identified models: output-error covariance or the Kalman innovation form.

Two opt-in models of what the identification saw besides the input response, both with w
unit white noise (``E[w wᵀ] = I``), sample time ``dt`` of the experiment:

``measurement``
    w enters the outputs only: ``Bw = 0``, ``Dw = L`` with ``L Lᵀ = Σ_ε``, the sample
    covariance of the output error ``ε = y − ŷ`` of the model on the *validation* run
    (independent of the estimation run). All the misfit is taken as white sensor noise;
    coloured (process) noise is therefore over- or under-weighted at some frequencies.

``innovation``
    The steady-state Kalman predictor (innovation) form of the identified model,

        x[k+1] = A x + B u + K e,    y = C x + D u + e,    E[e eᵀ] = Re,

    so ``Bw = K Lₑ``, ``Dw = Lₑ`` with ``Lₑ Lₑᵀ = Re`` (Cholesky). Estimated the standard
    subspace way from the *estimation* run (Van Overschee & De Moor 1996, sec. 4.3 and 6.1;
    Verhaegen & Verdult 2007, sec. 9.6): with the identified (A, B, C, D),

    1. the state sequence ``X̂ = O_s⁺ Π_{Z_p}(Y_f − H_s U_f)`` — the future outputs freed of
       the future inputs' response, projected on the row space of the past data Z_p = [U_p; Y_p]
       (the future noise is uncorrelated with the past); its columns are the states' linear
       estimates from the s past samples (a bank of Kalman filters of horizon s);
    2. the least-squares residuals of the state and output equations,
       ``ρ_w = X̂⁺ − A X̂ − B U``, ``ρ_v = Y − C X̂ − D U``, and their joint sample covariance
       ``[[Q, S], [Sᵀ, R]]``;
    3. the filter Riccati equation (:func:`fmu_fdi.design.observers._observer.filter_riccati`) for
       (A, C, Q, R, S): ``P = A P Aᵀ + Q − (A P Cᵀ + S) Re⁻¹ (…)ᵀ``, ``Re = C P Cᵀ + R``,
       ``K = (A P Cᵀ + S) Re⁻¹`` — the stabilising steady-state gain even when the horizon-s
       estimates are not yet steady (for steady ones, P = 0, K = S R⁻¹, Re = R).

    The predictor's innovations on the validation run (steady filter, initial state zero,
    the first 2 s·n samples dropped) give an independent check of Re (``validation_covariance``).

References
----------
P. Van Overschee and B. De Moor, *Subspace Identification for Linear Systems*, Kluwer 1996.
M. Verhaegen and V. Verdult, *Filtering and System Identification*, Cambridge 2007.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import IdentificationError

NOISE_MODELS = ("innovation", "measurement")


@dataclass
class NoiseModel:
    """``Bw``, ``Dw`` (w unit white) of a discrete identified model and the figures behind them.

    Attributes
    ----------
    kind : {'innovation', 'measurement'}
    Bw, Dw : ndarray
        n×p and p×p: the noise enters as ``Bw w`` and ``Dw w``, ``E[w wᵀ] = I``.
    covariance : ndarray
        p×p: Re (innovation) or Σ_ε (measurement), ``= Dw Dwᵀ``.
    K : ndarray
        n×p predictor gain (zeros for 'measurement').
    run : str
        Which record the covariance was estimated on.
    samples : int
        Number of residual samples it was estimated from.
    validation_covariance : ndarray or None
        Innovation form: sample covariance of the predictor's innovations on the validation run.
    """

    kind: str
    Bw: np.ndarray
    Dw: np.ndarray
    covariance: np.ndarray
    K: np.ndarray
    run: str
    samples: int
    validation_covariance: np.ndarray | None = None

    def provenance(self, output_names) -> dict:
        """Flat provenance fields (covariances row-major, p×p in the order of the outputs)."""
        p = len(output_names)
        out = {"noise_model": self.kind, "noise_inputs": [f"w_{n}" for n in output_names],
               "noise_run": self.run, "noise_samples": int(self.samples),
               "noise_covariance": [float(v) for v in self.covariance.ravel()]}
        if self.kind == "innovation":
            out["noise_gain"] = [float(v) for v in self.K.ravel()]
            if self.validation_covariance is not None:
                out["noise_covariance_validation"] = [float(v) for v in self.validation_covariance.ravel()]
        out["noise_covariance_shape"] = [p, p]
        return out


def check_noise_option(noise) -> None:
    """One-line refusal of a noise option other than None, 'innovation' or 'measurement'."""
    if noise is not None and noise not in NOISE_MODELS:
        raise IdentificationError(f"noise must be one of {NOISE_MODELS} or None (no noise inputs), got {noise!r}")


def measurement_noise(model, y_val, y_hat, kind: str = "simulation") -> NoiseModel:
    """``Dw = chol(cov(y − ŷ))`` on the validation run, ``Bw = 0`` (module docstring).

    ``kind`` says what ŷ is (:func:`~fmu_fdi.identify.validation.validate`: 'simulation', or for
    an unstable model 'one-step predictor'); it is recorded with the run."""
    eps = np.asarray(y_val, float) - np.asarray(y_hat, float)
    cov = np.cov(eps, rowvar=False).reshape(eps.shape[1], eps.shape[1])
    Dw = _chol(cov, "the output error y − ŷ on the validation run", y_val)
    n, p = model.A.shape[0], Dw.shape[0]
    return NoiseModel("measurement", np.zeros((n, p)), Dw, cov, np.zeros((n, p)), f"validation ({kind})", len(eps))


def innovation_noise(model, u, y, u_val=None, y_val=None, horizon: int | None = None) -> NoiseModel:
    """Steady-state Kalman innovation form of ``model`` from its estimation record (module docstring).

    Parameters
    ----------
    model : SubspaceModel
        The identified discrete model (A, B, C, D, dt).
    u, y : array_like, (N, m) and (N, p)
        The estimation record (deviations), the one the model was identified from.
    u_val, y_val : array_like, optional
        An independent record: the predictor's innovation covariance on it is reported.
    horizon : int, optional
        s, block rows of the past used for the state estimates (default
        ``max(model.block_rows, 2 n + 2, 10)``).
    """
    import scipy.linalg as sla

    from ..design.toolkit._basis import _block_toeplitz
    from ..design.observers._observer import filter_riccati
    from ..design.problems.datadriven import block_hankel
    from ..errors import DesignError

    A, B, C, D = model.A, model.B, model.C, model.D
    u = np.asarray(u, float).reshape(len(u), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    N, m = u.shape
    n, p = A.shape[0], C.shape[0]
    s = int(horizon or max(model.block_rows, 2 * n + 2, 10))
    j = N - 2 * s + 1
    rows = s * (m + p)
    if j < 4 * rows:
        raise IdentificationError(f"too little data for the noise model: {N} samples give {max(j, 0)} columns for "
                                  f"{rows} past rows (s = {s}); record at least {4 * rows + 2 * s - 1} samples")
    # extended observability matrix O_s and the block Toeplitz matrix H_s of the Markov parameters
    O = np.empty((s * p, n))
    M = C.copy()
    for i in range(s):
        O[i * p:(i + 1) * p] = M
        M = M @ A
    H = _block_toeplitz([D] + [O[i * p:(i + 1) * p] @ B for i in range(s - 1)], s - 1)
    su = np.sqrt(np.mean(u * u, axis=0)) + np.finfo(float).tiny
    sy = np.sqrt(np.mean(y * y, axis=0)) + np.finfo(float).tiny
    Zp = np.vstack([block_hankel(u / su, 0, s, j), block_hankel(y / sy, 0, s, j)])  # row scaling: same projection
    G = block_hankel(y, s, s, j) - H @ block_hankel(u, s, s, j)
    # Π_{Z_p} Gᵀ = Q Qᵀ Gᵀ, Q an orthonormal basis of Z_pᵀ's column space: the projection without the
    # least-squares coefficients (an SVD of j × s(m+p) is 5× dearer). Householder QR; when a |R_ii| falls
    # below 1e-12 of the largest (Z_p rank-deficient), the column-pivoted QR, truncated there
    Qz, Rz = sla.qr(Zp.T, mode="economic")
    d = np.abs(np.diag(Rz))
    if d.size and not np.all(d > 1e-12 * d.max()):
        Qz, Rz, _ = sla.qr(Zp.T, mode="economic", pivoting=True)
        d = np.abs(np.diag(Rz))
        Qz = Qz[:, : int(np.count_nonzero(d > 1e-12 * d[0]))] if d[0] > 0 else Qz[:, :0]
    X = np.linalg.lstsq(O, (Qz @ (Qz.T @ G.T)).T, rcond=None)[0]     # n × j: x̂ at times s … s + j − 1
    uk, yk = u[s:s + j].T, y[s:s + j].T
    rho_w = X[:, 1:] - A @ X[:, :-1] - B @ uk[:, :-1]
    rho_v = yk[:, :-1] - C @ X[:, :-1] - D @ uk[:, :-1]
    rho = np.vstack([rho_w, rho_v])
    cov = rho @ rho.T / rho.shape[1]
    Q, S, R = cov[:n, :n], cov[:n, n:], cov[n:, n:]
    try:
        kf = filter_riccati(A, C, Q, R, S, model.dt, what="the innovation noise model")
    except DesignError as exc:
        raise IdentificationError(str(exc)) from None
    Re = kf.Sigma  # filter_riccati returns it symmetrised, (Σ + Σᵀ)/2
    Le = _chol(Re, "the innovation covariance Re", y)
    K = kf.L
    val = None
    if u_val is not None:
        val = predictor_innovations(model, K, u_val, y_val, drop=2 * s * max(n, 1))
        val = np.cov(val, rowvar=False).reshape(p, p)
    return NoiseModel("innovation", K @ Le, Le, Re, K, "estimation", rho.shape[1], val)


def output_error_noise(model, u, y, u_val=None, y_val=None) -> NoiseModel:
    """The innovation form of an output-error model (:mod:`fmu_fdi.identify.output_error`): K = 0,
    ``Re`` the covariance of its output error ``y − ŷ`` (mean removed: the fitted offsets) on the
    estimation run. For a plant whose noise is white sensor noise, with no process noise, the
    steady-state Kalman gain is zero and this is its exact innovation form (Ljung 1999, sec. 4.2,
    the output-error structure: H(q) = I); the subspace estimate of K then holds only the
    finite-horizon state estimates' errors (:func:`innovation_noise`)."""
    u = np.asarray(u, float).reshape(len(u), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    e = y - model.simulate(u)
    e -= e.mean(axis=0)
    cov = e.T @ e / len(e)
    Le = _chol(cov, "the output error y − ŷ on the estimation run", y)
    n, p = model.A.shape[0], cov.shape[0]
    val = None
    if u_val is not None:
        ev = predictor_innovations(model, np.zeros((n, p)), u_val, y_val, drop=len(u_val) // 10)
        val = np.cov(ev, rowvar=False).reshape(p, p)
    return NoiseModel("innovation", np.zeros((n, p)), Le, cov, np.zeros((n, p)), "estimation (output error)",
                      len(e), val)


def predictor_innovations(model, K, u, y, drop: int = 0) -> np.ndarray:
    """``e[k] = y[k] − C x̂[k] − D u[k]``, ``x̂[k+1] = A x̂ + B u + K e`` from x̂[0] = 0, first ``drop`` left out."""
    A, B, C, D = model.A, model.B, model.C, model.D
    u = np.asarray(u, float).reshape(len(u), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    # x̂⁺ = (A − K C) x̂ + (B − K D) u + K y: the data's push per step formed once for the whole record
    x = np.zeros(A.shape[0])
    F = A - K @ C
    drive = u @ (B - K @ D).T + y @ K.T
    X = np.empty((len(u), A.shape[0]))
    step = F.dot
    for k in range(len(u)):
        X[k] = x
        x = step(x) + drive[k]
    e = y - X @ C.T - u @ D.T
    return e[min(drop, len(e) // 2):]


def _chol(cov, what: str, y) -> np.ndarray:
    """Lower Cholesky factor of a covariance, refused (with its eigenvalues) when not positive definite:
    an eigenvalue below 1e-12 of the largest, or a noise std below 1e3·eps of the outputs' RMS (round-off)."""
    cov = (cov + cov.T) / 2
    lam = np.linalg.eigvalsh(cov)
    floor = (1e3 * np.finfo(float).eps) ** 2 * float(np.max(np.mean(np.square(y), axis=0)))
    if not np.all(np.isfinite(lam)) or lam[0] <= max(1e-12 * lam[-1], floor, np.finfo(float).tiny):
        raise IdentificationError(f"the covariance of {what} is not positive definite (eigenvalues "
                                  f"{np.round(lam, 12).tolist()}): an output is noise-free or the outputs are "
                                  f"linearly dependent; identify without a noise model")
    return np.linalg.cholesky(cov)
