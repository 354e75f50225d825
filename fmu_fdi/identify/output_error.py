"""Prediction-error refinement of a subspace model: the output-error fit over the whole record.

PO-MOESP (:mod:`fmu_fdi.identify.subspace`) reads the dynamics through a window of s block
rows. On a stiff plant — time scales 138 s and 1/50 s in one record, the wind turbine's drive
train — the window (11 samples of 0.03 s) is a quarter of a percent of the slow mode: its pole
z = e^{−ts/τ} is read from 1 − z ≈ 2e-4 across a window that barely sees it move, with a
variance the budget's record length does not bring down (drive train, PO-MOESP alone:
validation fit of ω_g 93 % against a floor of 99.8 %). The prediction-error method has no
window: it fits the model's simulated response to the whole record (Ljung 1999, ch. 7 and sec. 10.2; Verhaegen & Verdult 2007,
ch. 7, output-error parametric model estimation, started from the subspace estimate as their
ch. 10 recommends).

Model structure (output error, continuous time, zero-order hold): the subspace model's
continuous form ``(A, B, C)`` (D = 0: a co-simulation record reads y_k before u_k acts) in
modal coordinates, one complex mode per real pole or conjugate pair:

    ξ_i' = λ_i ξ_i + β_iᵀ u,    y = Σ_i c_i ξ_i (real λ_i),  + Σ_i 2 Re(γ_i ξ_i) (pairs),

sampled exactly with u held over each step of ts: ξ_i[k+1] = z_i ξ_i[k] + ((z_i − 1)/λ_i) β_iᵀ
u[k], z_i = e^{λ_i ts}, ξ_i[0] = 0 (the record starts settled at the operating point). Each
mode is one first-order recursion (scipy.signal.lfilter), so a simulation of the whole record
costs O(N n). Parameters: log(−Re λ_i) (the modes stay stable: the structure is for a plant
that settles, as the experiment design has checked), Im λ_i, β_i and γ_i, with each mode's
largest input coefficient fixed at its initial value (the scale ξ_i → a ξ_i is not
identifiable), and a constant per output: the record's operating point y0 is the mean of a
short settle phase, and its error (the noise over that phase) would otherwise be fitted by the
slow modes as a spurious coupling (Ljung 1999, sec. 14.1: offsets estimated with the model; it
is the mean output error at each θ, so it adds no iteration). The criterion is the sum of
squared output errors, each output weighted by
1/σ_j (its noise level: the Gaussian maximum-likelihood criterion for white sensor noise
independent between outputs, Ljung 1999, sec. 7.4), minimised by the
Levenberg–Marquardt iteration of :func:`scipy.optimize.least_squares` (Ljung 1999,
sec. 10.2). Output error is consistent for any noise colour in open loop (Ljung 1999, ch. 8:
the noise model fixed, G still converges to the truth), so it is not used for a plant in its
own loop.

References
----------
L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall 1999.
M. Verhaegen and V. Verdult, *Filtering and System Identification*, Cambridge 2007.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.linalg as sla
from scipy.optimize import least_squares
from scipy.signal import lfilter

from ..lti import LTI
from .errors import IdentificationError

#: a conjugate pair is a pole with |Im λ| above this fraction of |λ|
_PAIR_TOL = 1e-9


class _Modal:
    """The modal output-error structure of a continuous (A, B, C) (module docstring)."""

    def __init__(self, A, B, C):
        lam, V = np.linalg.eig(A)
        if np.linalg.cond(V) > 1e8:
            raise IdentificationError(f"the model's modes are nearly repeated (eigenvector condition "
                                      f"{np.linalg.cond(V):.3g} > 1e8): no modal structure")
        if np.any(lam.real >= 0):
            raise IdentificationError(f"the model has poles {lam[lam.real >= 0].tolist()} in the closed right "
                                      f"half-plane: the output-error refinement is for a plant that settles")
        keep = lam.imag >= -_PAIR_TOL * np.abs(lam)
        Vinv_B = np.linalg.solve(V, B)
        CV = C @ V
        self.lam = lam[keep]
        self.pair = self.lam.imag > _PAIR_TOL * np.abs(self.lam)
        self.beta = Vinv_B[keep]
        self.gamma = CV[:, keep].T
        # real modes: real coefficients (eig gives them real up to a phase; rotate it out)
        for i in np.flatnonzero(~self.pair):
            k = int(np.argmax(np.abs(self.beta[i])))
            ph = self.beta[i, k] / abs(self.beta[i, k]) if abs(self.beta[i, k]) > 0 else 1.0
            self.beta[i] /= ph
            self.gamma[i] *= ph
        self.lam[~self.pair] = self.lam[~self.pair].real
        self.beta[~self.pair] = self.beta[~self.pair].real
        self.gamma[~self.pair] = self.gamma[~self.pair].real
        self.fixed = np.argmax(np.abs(self.beta), axis=1)   # the coefficient that fixes each mode's scale
        self.m, self.p = B.shape[1], C.shape[0]

    def theta(self) -> np.ndarray:
        out = []
        for i, lam in enumerate(self.lam):
            out.append(np.log(-lam.real))
            if self.pair[i]:
                out.append(lam.imag)
            free = np.delete(self.beta[i], self.fixed[i])
            out += list(free.real) + (list(free.imag) if self.pair[i] else [])
            out += list(self.gamma[i].real) + (list(self.gamma[i].imag) if self.pair[i] else [])
        return np.array(out, float)

    def set(self, theta) -> None:
        pos = 0

        def take(n):
            nonlocal pos
            pos += n
            return np.asarray(theta[pos - n:pos], float)

        for i in range(len(self.lam)):
            cplx = self.pair[i]
            re = -np.exp(take(1)[0])
            self.lam[i] = re + 1j * take(1)[0] if cplx else re
            free = take(self.m - 1) + (1j * take(self.m - 1) if cplx else 0)
            self.beta[i] = np.insert(free.astype(complex), self.fixed[i], self.beta[i, self.fixed[i]])
            self.gamma[i] = take(self.p) + (1j * take(self.p) if cplx else 0)

    def simulate(self, u, ts) -> np.ndarray:
        """Output of the zero-order-hold sampled model for inputs u (N × m) from rest."""
        y = np.zeros((len(u), self.p))
        for lam, beta, gamma, cplx in zip(self.lam, self.beta, self.gamma, self.pair):
            b = np.expm1(lam * ts) / lam * beta
            z = np.exp(lam * ts)
            if cplx:
                drive = u @ b.real + 1j * (u @ b.imag)
                xi = lfilter([0.0, 1.0], [1.0, -z], drive)
                y += np.outer(2.0 * xi.real, gamma.real) - np.outer(2.0 * xi.imag, gamma.imag)
            else:
                xi = lfilter([0.0, 1.0], [1.0, -z.real], u @ b.real)
                y += np.outer(xi, gamma.real)
        return y

    def realisation(self):
        """Real block-diagonal ``(A, B, C)``: a pair's state (Re ξ, Im ξ)."""
        blocks, Bs, Cs = [], [], []
        for lam, beta, gamma, cplx in zip(self.lam, self.beta, self.gamma, self.pair):
            if cplx:
                blocks.append(np.array([[lam.real, -lam.imag], [lam.imag, lam.real]]))
                Bs += [beta.real, beta.imag]
                Cs += [2 * gamma.real, -2 * gamma.imag]
            else:
                blocks.append(np.array([[lam.real]]))
                Bs.append(beta.real)
                Cs.append(gamma.real)
        return sla.block_diag(*blocks), np.array(Bs), np.array(Cs).T


def refine_output_error(sub, u, y, sigma, *, max_nfev: int = 200):
    """The subspace model ``sub`` refined by the output-error criterion on the record (u, y)
    (module docstring). ``sigma``: each output's noise level (the weights; a zero is replaced by
    the output's RMS). Returns ``(model, info)``: a :class:`~fmu_fdi.identify.subspace.SubspaceModel`
    at the same sample time (its discrete matrices the exact sampling of the refined continuous
    model) and a dict with the criterion before and after, the number of evaluations and the
    estimated output ``offset`` (p values: the correction of the record's operating point y0).

    Raises
    ------
    IdentificationError
        When ``sub`` has no modal structure (repeated modes, a pole that does not settle).
    """
    u = np.asarray(u, float).reshape(len(u), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    ts = sub.dt
    A, B, C, D = sub.to_continuous()
    if np.any(D != 0):
        raise IdentificationError("the output-error structure has no feedthrough (D = 0)")
    modal = _Modal(A, B, C)
    w = np.asarray(sigma, float)
    rms = np.sqrt(np.mean(y * y, axis=0))
    w = 1.0 / np.where(w > 0, w, np.where(rms > 0, rms, 1.0))

    def residual(theta):
        modal.set(theta)
        e = y - modal.simulate(u, ts)
        return ((e - e.mean(axis=0)) * w).ravel()

    theta0 = modal.theta()
    cost0 = 0.5 * float(np.sum(residual(theta0) ** 2))
    fit = least_squares(residual, theta0, method="lm", x_scale="jac", max_nfev=max_nfev)
    modal.set(fit.x)
    Ac, Bc, Cc = modal.realisation()
    zoh = LTI(Ac, Bc, Cc, np.zeros((Cc.shape[0], Bc.shape[1])), 0.0).to_discrete(ts)
    out = replace(sub, A=zoh.A, B=zoh.B, C=Cc, D=np.zeros_like(sub.D), info=dict(sub.info, refined="output error"))
    offset = (y - modal.simulate(u, ts)).mean(axis=0)
    return out, {"cost_before": cost0, "cost_after": float(fit.cost), "evaluations": int(fit.nfev),
                 "status": fit.message, "offset": offset}
