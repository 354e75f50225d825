"""Residual generators at run time: one sample in, residuals out (numpy only).

Every generator kind implements the same small interface so that the Diagnoser and the
FMU never care which design method made it:

- ``step(v)``: ``v`` is one sample of ``[y; u]`` (1-D float array); returns the residual
  vector r of that sample (1-D array, length ``n_outputs``);
- ``get_state()`` / ``set_state(state)``: the complete internal state as a dict of
  JSON-serialisable values (lists of floats), so a host can roll back exactly;
- ``reset()``: back to the state right after construction.

``make_generator(spec)`` builds one from its design-file dict, whose ``kind`` selects
the class (``"lti"`` here; ``"rls"`` in :mod:`.rls`).
"""
from __future__ import annotations

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
        self.x = np.zeros(n)

    def step(self, v: np.ndarray) -> np.ndarray:
        r = self.C @ self.x + self.D @ v
        self.x = self.A @ self.x + self.B @ v
        return r

    def get_state(self) -> dict:
        return {"x": self.x.tolist()}

    def set_state(self, state: dict) -> None:
        self.x = np.array(state["x"], float)

    def reset(self) -> None:
        self.x = np.zeros(self.A.shape[0])


def make_generator(spec: dict):
    kind = spec.get("kind")
    if kind == "lti":
        return LTIStep(spec)
    if kind == "rls":
        from .rls import RLSStep

        return RLSStep(spec)
    raise ValueError(f"unknown generator kind {kind!r}")
