"""Discrete LTI filter update ``x+ = A x + B v``, ``r = C x + D v`` (numpy only)."""
from __future__ import annotations

import numpy as np


def simulate_lti(A, B, C, D, v, x0=None) -> np.ndarray:
    """Run the filter over the rows of ``v`` (N × inputs); returns r (N × outputs)."""
    A, B, C, D = (np.asarray(M, float) for M in (A, B, C, D))
    v = np.asarray(v, float)
    x = np.zeros(A.shape[0]) if x0 is None else np.array(x0, float)
    out = np.empty((v.shape[0], C.shape[0]))
    for k in range(v.shape[0]):
        out[k] = C @ x + D @ v[k]
        x = A @ x + B @ v[k]
    return out
