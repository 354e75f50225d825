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
import scipy.linalg as sla


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


def validate(model, u, y, t=None, continuous_poles=None, output_names=None) -> ValidationReport:
    """Compare a :class:`~fmu_fdi.identify.subspace.SubspaceModel` with a record of deviations."""
    A, B, C, D = model.A, model.B, model.C, model.D
    u = np.asarray(u, float).reshape(len(u), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    N, n = len(u), A.shape[0]
    poles = np.linalg.eigvals(A)
    if np.all(np.abs(poles) < 1.0):
        y0 = model.simulate(u)
        # free response rows C A^k, stacked: least-squares initial state
        O = np.empty((N * C.shape[0], n))
        M = C.copy()
        for k in range(N):
            O[k * C.shape[0]:(k + 1) * C.shape[0]] = M
            M = M @ A
        x0 = np.linalg.lstsq(O, (y - y0).ravel(), rcond=None)[0]
        y_hat = model.simulate(u, x0)
        kind = "simulation"
    else:
        P = sla.solve_discrete_are(A.T, C.T, np.eye(n), np.eye(C.shape[0]))
        K = A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + np.eye(C.shape[0]))
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
