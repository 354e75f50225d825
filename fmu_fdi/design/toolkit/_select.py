"""Choosing linear combinations of null-space basis rows.

A least-order scalar residual is a constant combination ``h N(μ) / d(μ)`` of the basis
rows of degree ≤ ν (Varga 2003). Among the combinations, we pick the one with the best
*fault sensitivity condition* — the smallest fault gain over the largest, both measured
as peak gains on a frequency grid — which also keeps every fault visible, and, with
frequencies Ω for strong detectability, the smallest gain at Ω counts too. The search is
deterministic (fixed seed): a spread of starting directions, then Nelder–Mead on the
unit sphere for small dimensions.
"""
from __future__ import annotations

from typing import Callable

import numpy as np


def _normalize(h: np.ndarray) -> np.ndarray:
    nrm = np.linalg.norm(h)
    return h / nrm if nrm > 0 else h


def maximize_on_sphere(objective: Callable[[np.ndarray], float], k: int, seed: int = 0,
                       starts: int = 48, extra_starts=(), refine_dim: int = 12,
                       spread: float | None = None) -> tuple[np.ndarray, float]:
    """Maximise a scale-invariant objective over unit vectors in R^k: the 4 best starts refined by
    Nelder-Mead; with ``spread``, the 4 best of which no two are closer than ``|cos| > spread``
    (so that several optima of equal value, e.g. mirror images, are all reached)."""
    if k == 1:
        h = np.ones(1)
        return h, objective(h)
    rng = np.random.default_rng(seed)
    cands = [np.eye(k)[i] for i in range(k)] + [np.ones(k) / np.sqrt(k)]
    cands += [_normalize(np.asarray(c, float)) for c in extra_starts]
    cands += [_normalize(rng.standard_normal(k)) for _ in range(starts)]
    scored = sorted(((objective(c), i, c) for i, c in enumerate(cands)), key=lambda t: -t[0])
    best_val, _, best = scored[0]
    if k <= refine_dim:
        picked = [c for _, _, c in scored]
        if spread is not None:
            picked = []
            for _, _, c in scored:
                if all(abs(c @ q) <= spread for q in picked):
                    picked.append(c)
                if len(picked) == 4:
                    break
        # (imported here: scipy.optimize costs 0.16-0.4 s at ``import fmu_fdi.design``, whose other modules do not
        # need it; the first pole placement imports it anyway, through scipy.signal → scipy.stats)
        import scipy.optimize as sopt

        for c in picked[:4]:
            res = sopt.minimize(lambda x: -objective(_normalize(x)), c, method="Nelder-Mead",
                                options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 400 * k, "maxfev": 400 * k})
            h = _normalize(res.x)
            val = objective(h)
            if val > best_val:
                best_val, best = val, h
    return best, best_val


class _RowResponses:
    """The responses ``h P_j`` of a combination ``h`` to every fault j at once: the per-fault blocks
    ``P_j`` (points, rows, cols_j) stacked as one (rows, points·cols) matrix, so that one product
    ``h @ M`` and one segment sum give ``||h P_j(λ_k)||`` for every k and j (the objectives below run
    inside Nelder–Mead: thousands of evaluations, where per-fault ``einsum``/``norm`` calls cost more
    than the arithmetic)."""

    def __init__(self, P: list[np.ndarray]):
        self.points = P[0].shape[0] if P else 0
        cols = [Pj.shape[2] for Pj in P]
        self.starts = np.cumsum([0] + cols[:-1])
        self.M = (np.concatenate([Pj.transpose(1, 0, 2) for Pj in P], axis=2).reshape(P[0].shape[1], -1)
                  if P else None)
        self.width = int(sum(cols))

    def norms(self, h: np.ndarray) -> np.ndarray:
        """(points, faults): ``||h P_j(λ_k)||``."""
        hp = (h @ self.M).reshape(self.points, self.width)
        return np.sqrt(np.add.reduceat(hp.real ** 2 + hp.imag ** 2, self.starts, axis=1))


def sensitivity_objective(P: list[np.ndarray], strong: list[np.ndarray] | None = None):
    """Fault sensitivity condition of a combination ``h`` of rows.

    ``P[j]`` has shape (points, rows, cols_j): the responses of every row to fault j on
    a frequency grid; ``strong[j]`` the same at the strong-detectability frequencies.
    """
    grid = _RowResponses(P)
    at = _RowResponses(strong) if strong else None

    def objective(h: np.ndarray) -> float:
        return _condition(grid.norms(h), at.norms(h) if at is not None else None)

    return objective


def _condition(resp: np.ndarray, lows: np.ndarray | None) -> float:
    """Smallest fault peak (and strong-frequency gain) over the largest fault peak; ``resp`` and
    ``lows`` are (points, faults) gains on the grid and at the strong frequencies."""
    peaks = resp.max(axis=0)
    top = peaks.max()
    if top <= 0:
        return 0.0
    worst = peaks.min()
    if lows is not None:
        worst = min(worst, lows.min())
    return float(worst / top)


def visibility_gated(P: list[np.ndarray], Y: np.ndarray, G: np.ndarray, fcols: list, gate: float,
                     strong: list[np.ndarray] | None = None):
    """:func:`sensitivity_objective` ``(P, strong)`` restricted to combinations that keep every fault visible.

    The fault sensitivity condition is a ratio of fault gains and cannot tell a combination
    whose fault responses are rounding noise (``h`` in the rows' common fault-free direction:
    noise over noise ≈ 1) from a good one. The post-condition's cosine
    ``γ_j(h) = max_λ ||h P_j(λ)|| / (||h Y(λ)|| ||Gf_j(λ)||)`` (``Y``: the rows' y-part,
    (points, rows, p); ``Gf_j = G[:, :p, fcols[j]]``: the plant's values on the same points,
    :func:`.postconditions._cosine`) must reach ``gate`` (FDtol, inclusive as the judge); below it the value is
    ``min_j γ_j - 1 < 0``, under every admissible one. The objective's value is computed from the
    same products.
    With ``strong`` (gains at given frequencies in the objective, whose ratio to the peak a
    near-degenerate combination also inflates) the value is ``min(objective, min_j γ_j)``, so the
    optimum stays away from the gate instead of sitting on it.
    """
    if not P:
        return sensitivity_objective(P, strong)
    grid = _RowResponses(P)
    at = _RowResponses(strong) if strong else None
    K, rows, p = Y.shape
    Ym = Y.transpose(1, 0, 2).reshape(rows, K * p)
    Gn = np.stack([np.linalg.norm(G[:, :p, c], 2, axis=(1, 2)) for c in fcols], axis=1)  # (K, faults): ||Gf_j(λ)||

    def gated(h: np.ndarray) -> float:
        resp = grid.norms(h)  # (K, faults): ||h P_j(λ)||
        hy = (h @ Ym).reshape(K, p)
        bound = np.sqrt((hy.real ** 2 + hy.imag ** 2).sum(axis=1))[:, None] * Gn
        top = bound.max(axis=0)
        keep = bound >= 1e-6 * top  # as postconditions._cosine: zeros of Gf_j are left out
        ratio = np.where(keep, resp / np.where(keep, bound, 1.0), 0.0).max(axis=0)
        g = float(np.min(np.where(top > 0, ratio, 0.0)))
        if g < gate:  # inclusive, as the judge: γ_j = FDtol is visible
            return g - 1.0
        value = _condition(resp, at.norms(h) if at is not None else None)
        return min(value, g) if at is not None else value

    return gated


def greedy_combinations(objective: Callable[[np.ndarray], float], k: int, rdim: int,
                        seed: int = 0) -> np.ndarray:
    """``rdim`` orthonormal combination rows, each the best in the orthogonal complement
    of the previous ones (``objective`` acts on a full combination vector in R^k)."""
    if rdim >= k:
        return np.eye(k)
    H = np.zeros((0, k))
    Z = np.eye(k)
    for _ in range(rdim):
        c, _ = maximize_on_sphere(lambda x: objective(x @ Z), Z.shape[0], seed)
        H = np.vstack([H, c @ Z])
        _, _, Vh = np.linalg.svd(H, full_matrices=True)
        Z = Vh[H.shape[0]:]
    return H
