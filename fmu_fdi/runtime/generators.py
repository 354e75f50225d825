"""Residual generators at run time: one sample in, residuals out (numpy only).

Every generator kind implements the same small interface so that the Diagnoser and the
FMU never care which design method made it:

- ``step(v)``: ``v`` is one sample of ``[y; u]`` (1-D float array); returns the residual
  vector r of that sample (1-D array, length ``n_outputs``);
- ``get_state()`` / ``set_state(state)``: the complete internal state as a dict of
  JSON-serialisable values (lists of floats), so a host can roll back exactly;
- ``reset()``: back to the state right after construction;
- ``finite()``: every entry of the state is finite (docs/semantics.md §8).

``make_generator(spec)`` builds one from its design-file dict, whose ``kind`` selects
the class (``"lti"`` here; ``"rls"`` in :mod:`.rls`).
"""
from __future__ import annotations

import math

import numpy as np


class LTIStep:
    """``r[k] = C x[k] + D v[k]``, ``x[k+1] = A x[k] + B v[k]`` (Frank, eq. 8 in discrete time)."""

    kind = "lti"

    def __init__(self, spec: dict):
        self.A = np.asarray(spec["A"], float).reshape(len(spec["A"]), -1) if len(spec["A"]) else np.zeros((0, 0))
        n = self.A.shape[0]
        self.D = np.atleast_2d(np.asarray(spec["D"], float))
        p, m = self.D.shape
        self.B = np.asarray(spec["B"], float).reshape(n, m)
        self.C = np.asarray(spec["C"], float).reshape(p, n)
        self.n_inputs, self.n_outputs = m, p
        # one product per sample: [r; x+] = [[C, D], [A, B]] [x; v], with [x; v] kept in a buffer
        self.M = np.block([[self.C, self.D], [self.A, self.B]])
        self._xv = np.zeros(n + m)
        self._n = n

    @property
    def x(self) -> np.ndarray:
        return self._xv[: self._n]

    def step(self, v) -> np.ndarray:
        xv = self._xv
        xv[self._n:] = v
        z = self.M.dot(xv)
        p = self.n_outputs
        xv[: self._n] = z[p:]
        return z[:p]

    def get_state(self) -> dict:
        return {"x": self.x.tolist()}

    def set_state(self, state: dict) -> None:
        x = np.array(state["x"], float)
        if x.shape != (self._n,):
            raise ValueError(f"generator state must have {self._n} entries, got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError("generator state holds NaN or Inf")
        self._xv[: self._n] = x

    def finite(self) -> bool:
        """The state x is finite (S1; the residual is checked by the caller)."""
        return all(map(math.isfinite, self._xv[: self._n].tolist()))

    def reset(self) -> None:
        self._xv[:] = 0.0


def make_generator(spec: dict):
    kind = spec.get("kind")
    if kind == "lti":
        return LTIStep(spec)
    if kind == "rls":
        from .rls import RLSStep

        return RLSStep(spec)
    raise ValueError(f"unknown generator kind {kind!r}")
