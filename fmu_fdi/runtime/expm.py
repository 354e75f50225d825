"""Matrix exponential and exact zero-order-hold discretisation in numpy only.

Scaling and squaring with the [13/13] Padé approximant (Higham, *The scaling and
squaring method for the matrix exponential revisited*, SIAM J. Matrix Anal. Appl. 26,
2005): ``e^A = (e^{A/2^s})^{2^s}`` with ``||A/2^s||_1 ≤ θ13 = 5.37``. The FMU bundles this
module, so it may not use scipy.
"""
from __future__ import annotations

import numpy as np

_B13 = (64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
        129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
        40840800.0, 960960.0, 16380.0, 182.0, 1.0)
_THETA13 = 5.371920351148152


def expm(A: np.ndarray) -> np.ndarray:
    A = np.asarray(A, float)
    n = A.shape[0]
    if n == 0:
        return np.zeros((0, 0))
    norm = np.abs(A).sum(axis=0).max()
    s = max(0, int(np.ceil(np.log2(norm / _THETA13)))) if norm > _THETA13 else 0
    A = A / 2.0**s
    I = np.eye(n)
    A2 = A @ A
    A4 = A2 @ A2
    A6 = A4 @ A2
    b = _B13
    U = A @ (A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2) + b[7] * A6 + b[5] * A4 + b[3] * A2 + b[1] * I)
    V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 + b[0] * I
    E = np.linalg.solve(V - U, V + U)
    for _ in range(s):
        E = E @ E
    return E


def zoh(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``Ad = e^{A h}``, ``Bd = ∫_0^h e^{A t} dt B`` from one exponential of ``[[A, B], [0, 0]] h``."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A * h
    M[:n, n:] = B * h
    E = expm(M)
    return E[:n, :n], E[:n, n:]
