"""Shared machinery of the observer-based designs: gains, Riccati filters, the residual filter.

Every observer-based residual generator of :mod:`fmu_fdi.design` is an output observer

    x̂' = A x̂ + Bu u + L (y − C x̂ − Du u),        r = W (y − C x̂ − Du u)

(a forward shift instead of the derivative in discrete time), i.e. the LTI filter from
``[y; u]``

    Q = (A − L C,  [L,  Bu − L Du],  −W C,  [W,  −W Du]),

whose internal form has ``Ru = 0`` exactly: the error ``e = x − x̂`` obeys
``e' = (A − L C) e + (Bd − L Dd) d + (Bw − L Dw) w + (Bf − L Df) f`` and
``r = W (C e + Dd d + Dw w + Df f)`` (Frank, section 5; Chen & Patton 1999, ch. 2).
The methods differ only in how ``L`` and ``W`` are chosen, so they share this module:

- :func:`observer_gain` — pole placement by orthogonal methods on the dual pair.
  ``(A, C)`` is split by an orthogonal observability staircase into its observable
  part, whose eigenvalues are assigned, and its unobservable part, whose eigenvalues
  no gain can move and which must therefore be stable (detectability).
- :func:`filter_riccati` — the steady-state Kalman filter (CARE/DARE) with correlated
  noise; also the normalised left coprime factorisation.
- :func:`output_observer` / :func:`observer_generator` — the filter above and the
  :class:`~fmu_fdi.generator.ResidualGenerator` around it.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import EPS, default_rtol, ordered_schur
from ...lti import LTI
from ...model import FDIModel
from ..toolkit.approximate import RICCATI_RTOL, spectral_riccati
from ..toolkit.riccati_newton import (FORWARD_RTOL, DiagonalBalancing, boundary_gap, forward_refined,
                                      riccati_residual)
from ..toolkit.pencil import controllable_staircase


# ------------------------------------------------------------------------ formatting
def fmt_modes(values) -> str:
    """Eigenvalues as a short readable list: ``[-1, 0.5±2j]``."""
    values = np.asarray(values, complex)
    out, skip = [], set()
    for i, v in enumerate(values):
        if i in skip:
            continue
        if abs(v.imag) > 1e-12 * max(1.0, abs(v)):
            j = next((k for k in range(i + 1, values.size) if k not in skip
                      and abs(values[k] - np.conj(v)) <= 1e-9 * max(1.0, abs(v))), None)
            if j is not None:
                skip.add(j)
                out.append(f"{v.real:.6g}±{abs(v.imag):.6g}j")
                continue
            out.append(f"{v:.6g}")
        else:
            out.append(f"{v.real:.6g}")
    return "[" + ", ".join(out) + "]"


def unstable(values, dt: float, scale: float = 1.0) -> np.ndarray:
    """The eigenvalues on or outside the stability boundary.

    A margin of ``1e3 eps`` times the data scale keeps an integrator that rounding moved
    to ``-1e-17`` from counting as stable.
    """
    values = np.asarray(values, complex)
    margin = 1e3 * EPS * max(1.0, scale)
    if dt:
        return values[np.abs(values) >= 1.0 - margin]
    return values[values.real >= -margin]


# ---------------------------------------------------------------------- pole sets
def check_pole_set(poles, dt: float, count: int | None = None, what: str = "poles") -> np.ndarray:
    """Validate a requested pole set: finite, stable, closed under conjugation, ``count`` long."""
    try:
        p = np.atleast_1d(np.asarray(poles, dtype=complex))
    except (TypeError, ValueError):
        raise DesignError(f"{what} must be a list of numbers, got {poles!r}") from None
    if p.ndim != 1:
        raise DesignError(f"{what} must be a 1-D list of numbers, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise DesignError(f"{what} must be finite numbers, got {p.tolist()}")
    bad = unstable(p, dt)
    if bad.size:
        region = "inside the unit circle (|z| < 1)" if dt else "in the open left half-plane (Re s < 0)"
        raise DesignError(f"{what} {fmt_modes(bad)} are not stable: observer poles must lie {region}")
    if not _conjugate_closed(p):
        raise DesignError(f"{what} {fmt_modes(p)} are not closed under complex conjugation: a real gain "
                          f"places every complex pole together with its conjugate")
    if count is not None and p.size != count:
        raise DesignError(f"{count} {what} are needed, got {p.size}")
    return p


def _conjugate_closed(p: np.ndarray) -> bool:
    rest = list(p[np.abs(p.imag) > 1e-12 * np.maximum(1.0, np.abs(p))])
    while rest:
        v = rest.pop()
        j = np.argmin([abs(w - np.conj(v)) for w in rest]) if rest else None
        if j is None or abs(rest[j] - np.conj(v)) > 1e-9 * max(1.0, abs(v)):
            return False
        rest.pop(j)
    return True


def default_poles(count: int, dt: float, A: np.ndarray) -> np.ndarray:
    """Distinct poles twice as fast as the plant's own (stabilised) modes.

    The plant's eigenvalues, mirrored into the stability region and spread from slow to
    fast (:func:`fmu_fdi.design.toolkit._basis.plant_pole_pool`), are made twice as fast (``2 λ``
    in continuous time, ``λ²`` in discrete time) — the usual rule for an observer — and
    nudged apart by a few per cent where they coincide, so the placement has no Jordan
    blocks. Tied to the plant's modes rather than to ``||A||``, they stay assignable for
    stiff models whose matrix norm dwarfs their dynamics.
    """
    from ..toolkit._basis import plant_pole_pool, spread_poles

    if count <= 0:
        return np.zeros(0, complex)
    base = spread_poles(plant_pole_pool(A, dt), count) if A.size else np.full(count, -1.0 + 0j)
    fast = base**2 if dt else 2.0 * base

    def nudged(q, k):  # k-th variant of q: a few per cent faster, still stable
        if dt:
            return q * (1 - 0.05 * k) if abs(q) > 0 else complex(0.05 * k, 0.0)
        return q * (1 + 0.05 * k)

    out: list[complex] = []
    for q in fast:
        k = 0
        while any(abs(nudged(q, k) - o) <= 1e-9 * max(1.0, abs(q)) for o in out):
            k += 1
        out.append(nudged(q, k))
    return np.array(out, complex)


def pole_error(achieved, requested) -> float:
    """Largest distance between achieved and requested poles after nearest matching."""
    rest = list(np.asarray(achieved, complex))
    worst = 0.0
    for t in np.asarray(requested, complex):
        j = int(np.argmin([abs(v - t) for v in rest]))
        worst = max(worst, abs(rest.pop(j) - t))
    return worst


# ------------------------------------------------------------------- staircase
def observable_staircase(A: np.ndarray, C: np.ndarray, tol: float | None = None,
                         atol: float = 0.0) -> tuple[np.ndarray, int]:
    """Orthogonal ``Z`` and the observable order ``n_o`` of ``(A, C)``.

    In the coordinates ``x = Z ξ``,

        Zᵀ A Z = [Ao 0; A21 Auo],     C Z = [Co 0],

    with ``(Co, Ao)`` observable (n_o states) and ``Auo`` the unobservable dynamics. This is
    the dual of the controllability staircase (Van Dooren 1981; Varga 1981): each step
    compresses the current output block by an SVD, so only orthogonal transformations are
    used and a rank decision compares singular values with ``tol`` (default ``1e3 max(n, p)
    eps ||[A; C]||₂``), or ``atol`` when larger (Varga's absolute rank tolerance).
    """
    n, p = A.shape[0], C.shape[0]
    if n == 0:
        return np.eye(n), 0
    if tol is None:
        tol = default_rtol((n, n + p)) * max(float(np.linalg.norm(np.vstack([A, C]), 2)), np.finfo(float).tiny)
    tol = max(tol, float(atol))
    # the controllability staircase of the dual pair (Aᵀ, Cᵀ): its T is Z, its blocks sum to n_o
    Z, taus = controllable_staircase(A.T, C.T, tol)
    return Z, sum(taus)


# -------------------------------------------------------------------- placement
@dataclass
class ObserverGain:
    """Result of :func:`observer_gain`: ``L`` with ``eig(A − L C) = poles ∪ fixed``."""

    L: np.ndarray
    poles: np.ndarray   # the assigned eigenvalues
    fixed: np.ndarray   # the unobservable (stable) eigenvalues no gain moves
    method: str         # which placement algorithm ran


def detectable_split(A: np.ndarray, C: np.ndarray, dt: float, *, what: str = "(A, C)",
                     fixed_reason: str = "", atol: float = 0.0) -> tuple[np.ndarray, int, np.ndarray]:
    """Staircase ``(Z, n_o, unobservable eigenvalues)``; a DesignError naming the
    unobservable modes that are unstable when ``(A, C)`` is not detectable (``atol``: the staircase's
    absolute rank tolerance)."""
    n = A.shape[0]
    Z, n_o = observable_staircase(A, C, atol=atol)
    At = Z.T @ A @ Z
    fixed = np.linalg.eigvals(At[n_o:, n_o:]) if n_o < n else np.zeros(0, complex)
    bad = unstable(fixed, dt, float(np.linalg.norm(A, 2)) if n else 1.0)
    if bad.size:
        region = "|z| ≥ 1" if dt else "Re ≥ 0"
        raise DesignError(
            f"{what} is not detectable: the modes {fmt_modes(bad)} are unobservable from the outputs and "
            f"unstable ({region}), so no observer gain can stabilise the estimation error"
            + (f"; {fixed_reason}" if fixed_reason else ""))
    return Z, n_o, fixed


def observer_gain(A: np.ndarray, C: np.ndarray, poles, dt: float, *, what: str = "(A, C)",
                  fixed_reason: str = "", atol: float = 0.0) -> ObserverGain:
    """Output-injection gain ``L`` placing the observable eigenvalues of ``A − L C``.

    The pair is split by :func:`observable_staircase`; the ``n_o`` observable eigenvalues
    are assigned to ``poles`` (exactly ``n_o`` of them, or ``None`` for
    :func:`default_poles`) and the unobservable ones stay where they are, which requires
    them to be stable (``(A, C)`` detectable). Placement on the dual pair uses the robust
    method of Kautsky, Nichols and Van Dooren (1985) with Tits–Yang updates
    (``scipy.signal.place_poles``), which maximises the conditioning of the closed-loop
    eigenvectors; when a pole is repeated more often than ``rank C`` (e.g. a deadbeat
    observer with one output), where that method does not apply, Varga's Schur method
    (SLICOT SB01BD) is used instead.

    The result is checked on the loop the model runs: the eigenvalues of the whole ``A − L C`` (numpy) must be the
    requested poles and the fixed modes within the placement's own tolerance (below), and stable. Where the answer
    in the caller's coordinates fails that (or its staircase refuses the pair), the pair is read once more in
    :func:`balanced_pair`'s coordinates ``(T⁻¹AT, N C T)`` (exact scalings; ``L = T L̃ N``): on states scaled over
    decades the staircase's rank decisions in the caller's coordinates read another pair — 27 of 300 random pairs
    scaled over nine decades came back with ``A − L C`` unstable, 23 refused as 'not detectable'; none now
    (tests/test_observer_scaled_pairs.py). The caller's coordinates come first so that every placement they get
    right is unchanged (KNV's gain for the same poles depends on the coordinates).

    Raises
    ------
    DesignError
        Unstable unobservable modes (named, with ``fixed_reason`` appended); a pole count
        that differs from the number of observable modes; a placement that misses the
        requested poles (in either coordinates).
    """
    try:
        gain = _observer_gain_unbalanced(A, C, poles, dt, what=what, fixed_reason=fixed_reason, atol=atol)
    except DesignError as exc:
        gain, first = None, exc
    else:
        first = _placement_missed(A, C, gain, dt, what)
        if first is None:
            return gain
    bal, r = balanced_pair(A, C, atol)
    if bal.trivial and np.all(r == 1.0):
        raise first
    gain = _observer_gain_unbalanced(bal.similar(A), bal.right(C) * r[:, None], poles, dt, what=what,
                                     fixed_reason=fixed_reason, atol=atol)
    # A − L C = T (Ã − L̃ C̃) T⁻¹ with L = T L̃ N
    gain = ObserverGain(bal.left(gain.L) * r[None, :], gain.poles, gain.fixed, gain.method)
    missed = _placement_missed(A, C, gain, dt, what)
    if missed is not None:
        raise missed
    return gain


def _placement_missed(A: np.ndarray, C: np.ndarray, gain: "ObserverGain", dt: float, what: str) -> DesignError | None:
    """None if the eigenvalues of the whole loop ``A − L C`` (numpy) are ``gain.poles ∪ gain.fixed`` within the
    tolerance :func:`_observer_gain_unbalanced` uses for the observable block (Bauer–Fike: ``max(1e3·eps·κ, √eps)``
    of the loop's size, both read after the loop's diagonal balancing, ``κ`` its eigenvector condition;
    ``1e3·eps^(1/k)`` for a pole of multiplicity ``k``) and stable; else the DesignError naming what it missed."""
    n = A.shape[0]
    if n == 0:
        return None
    # read in the loop's own diagonal balancing (exact; the eigenvalues are the loop's): in the caller's coordinates
    # ‖A‖ of a pair scaled over decades (1e7) would make the tolerance as large as the poles themselves
    Acl = A - gain.L @ C
    Acl = DiagonalBalancing.of(Acl).similar(Acl)
    ev, X = np.linalg.eig(Acl)
    target = np.concatenate([np.asarray(gain.poles, complex), np.asarray(gain.fixed, complex)])
    bad = unstable(ev, dt, max(1.0, float(np.linalg.norm(Acl, 2))))
    mult = max(int(np.sum(np.abs(target - q) <= 1e-12 * max(1.0, abs(q)))) for q in target)
    size = max(1.0, float(np.linalg.norm(Acl, 2)))
    kappa = np.linalg.cond(X) if mult == 1 else np.inf
    tol = (max(1e3 * EPS * kappa, np.sqrt(EPS)) if np.isfinite(kappa) else 1e3 * EPS ** (1.0 / mult)) * size
    err = pole_error(ev, target) if ev.size == target.size else np.inf
    if bad.size or not err <= tol:
        return DesignError(f"pole placement for {what} gives a loop A − L C whose eigenvalues miss the requested poles "
                           f"and fixed modes by {err:.3g} (tolerance {tol:.3g})"
                           + (f", the modes {fmt_modes(bad)} unstable" if bad.size else "")
                           + ": the pair is too badly scaled or too close to unobservable; rescale the states")
    return None


def balanced_pair(A: np.ndarray, C: np.ndarray, atol: float = 0.0) -> tuple[DiagonalBalancing, np.ndarray]:
    """``(T, r)``: ``A``'s diagonal balancing ``T`` (:class:`~fmu_fdi.design.toolkit.riccati_newton.DiagonalBalancing`,
    powers of 2: exact) and the scaling ``N = diag(r)`` normalising the rows of ``C T`` — the coordinates
    ``(T⁻¹AT, N C T)`` in which the observability staircase's rank decisions (relative to ``‖[A; C]‖``) read the pair
    the model describes. Observability, detectability and the closed-loop eigenvalues of ``A − L C`` with
    ``L = T L̃ N`` are invariant under both; in the caller's coordinates, on 300 random pairs scaled over nine decades
    (tests/test_riccati_failure_messages.py's ``scaled_random_case``) the staircase refused 23 detectable ones as 'not
    detectable' and ``observer_gain`` returned 27 gains whose ``A − L C`` was unstable (its check read the observable
    block only). ``T = I``, ``N = I`` where a caller's absolute rank tolerance ``atol`` refers to its own coordinates,
    or there are no states."""
    n = A.shape[0]
    if n == 0 or atol > 0:
        return DiagonalBalancing(np.ones(n)), np.ones(C.shape[0])
    bal = DiagonalBalancing.of(A)
    r = 1.0 / np.maximum(np.linalg.norm(bal.right(C), axis=1), np.finfo(float).tiny)
    return bal, r


def observable_order(A: np.ndarray, C: np.ndarray, dt: float, *, what: str = "(A, C)", fixed_reason: str = "",
                     atol: float = 0.0) -> int:
    """The observable order ``n_o`` of the staircase :func:`observer_gain` reads first (the caller's coordinates),
    or, where that refuses the pair as not detectable, of :func:`balanced_pair`'s coordinates ``(T⁻¹AT, N C T)``; a
    DesignError naming the unstable unobservable modes (:func:`detectable_split`) where ``(A, C)`` is not detectable in
    either — the detectability test of the observer designs (detectability is invariant under both scalings).

    In the caller's coordinates alone the staircase's rank decisions are relative to ``‖[A; C]‖``, and on states
    scaled over decades they read another pair: 23 of 300 random detectable problems scaled over nine decades
    (tests/test_riccati_failure_messages.scaled_random_case) were refused by ``kalman`` as 'not detectable', a stable
    mode read as an unobservable one at +0.24. A caller's absolute rank tolerance ``atol`` refers to its own
    coordinates: with it the pair is read there only."""
    try:
        return detectable_split(A, C, dt, what=what, fixed_reason=fixed_reason, atol=atol)[1]
    except DesignError:
        bal, r = balanced_pair(A, C, atol)
        if bal.trivial and np.all(r == 1.0):
            raise
    return detectable_split(bal.similar(A), bal.right(C) * r[:, None], dt, what=what, fixed_reason=fixed_reason,
                            atol=atol)[1]


def _observer_gain_unbalanced(A: np.ndarray, C: np.ndarray, poles, dt: float, *, what: str = "(A, C)",
                              fixed_reason: str = "", atol: float = 0.0) -> ObserverGain:
    """:func:`observer_gain` in the coordinates it is given (the staircase, the placement and its check there)."""
    n = A.shape[0]
    Z, n_o, fixed = detectable_split(A, C, dt, what=what, fixed_reason=fixed_reason, atol=atol)
    At = Z.T @ A @ Z
    Ct = C @ Z
    scale = max(1.0, float(np.linalg.norm(A, 2)) if n else 1.0)
    if poles is None:
        poles = default_poles(n_o, dt, A)
    poles = check_pole_set(poles, dt)
    if poles.size != n_o:
        fixed_txt = (f"; the {n - n_o} unobservable modes {fmt_modes(fixed)} are fixed (stable)"
                     if n_o < n else "")
        raise DesignError(f"{poles.size} poles given but {what} has {n_o} observable (assignable) modes"
                          f"{fixed_txt}: give exactly {n_o} poles")
    if n_o == 0:
        return ObserverGain(np.zeros((n, C.shape[0])), poles, fixed, "none")
    Ao, Co = At[:n_o, :n_o], Ct[:, :n_o]
    Lo, method = _place_dual(Ao, Co, poles, dt)
    Acl = Ao - Lo @ Co
    achieved, X = np.linalg.eig(Acl)
    # Bauer–Fike: rounding of size eps ||Acl|| moves a simple eigenvalue by at most
    # cond(X) eps ||Acl||, but the gain itself is computed through X, so the achieved error
    # can be a few digits above that; sqrt(eps) relative still separates a correct placement
    # from a failed one (nearly unobservable pairs miss by orders of magnitude more). A pole
    # of multiplicity k sits in a Jordan block and moves by O((eps ||Acl||)^(1/k)).
    mult = max(int(np.sum(np.abs(poles - q) <= 1e-12 * max(1.0, abs(q)))) for q in poles)
    size = max(scale, float(np.linalg.norm(Acl, 2)))
    kappa = np.linalg.cond(X) if mult == 1 else np.inf
    tol = (max(1e3 * EPS * kappa, np.sqrt(EPS)) if np.isfinite(kappa) else 1e3 * EPS ** (1.0 / mult)) * size
    err = pole_error(achieved, poles)
    if err > tol:
        raise DesignError(f"pole placement for {what} missed the requested poles by {err:.3g} (tolerance {tol:.3g}): "
                          f"the pair is too close to unobservable for the poles {fmt_modes(poles)}; "
                          f"choose poles nearer the plant's modes or rescale the model")
    L = Z[:, :n_o] @ Lo
    return ObserverGain(L, poles, fixed, method)


def _place_dual(Ao: np.ndarray, Co: np.ndarray, poles: np.ndarray, dt: float) -> tuple[np.ndarray, str]:
    """``Lo`` with ``eig(Ao − Lo Co) = poles`` for an observable pair."""
    from scipy.signal import place_poles

    rank_c = np.linalg.matrix_rank(Co)
    if rank_c < Co.shape[0]:
        # Redundant sensors (dependent rows of C): place_poles needs a full-rank input
        # matrix, so place through the row space, Co = U_r U_rᵀ Co, and map the gain back:
        # Ao − L_r (U_rᵀ Co) = Ao − (L_r U_rᵀ) Co.
        Ur = sla.svd(Co)[0][:, :rank_c]
        Lr, method = _place_dual(Ao, Ur.T @ Co, poles, dt)
        return Lr @ Ur.T, method
    mult = max(int(np.sum(poles == q)) for q in poles)
    if mult <= rank_c:
        try:
            with warnings.catch_warnings():
                # "convergence not reached" only means the eigenvector conditioning could be
                # improved further; the poles themselves are placed exactly (checked by the caller).
                warnings.simplefilter("ignore", UserWarning)
                res = place_poles(Ao.T, Co.T, _ordered(poles), method="YT")
            return res.gain_matrix.T, "KNV/YT (scipy place_poles)"
        except (ValueError, np.linalg.LinAlgError):
            pass  # scipy judged the pair uncontrollable numerically: try the Schur method
    import slycot

    n_o, p = Co.shape[1], Co.shape[0]
    eig = np.linalg.eigvals(Ao)
    # SB01BD leaves eigenvalues with Re < alpha (|z| < alpha) alone: put alpha below them all.
    alpha = 0.0 if dt else float(np.min(eig.real)) - 1.0
    w = _ordered(poles)
    try:
        _, _, _, nap, nup, F, _ = slycot.sb01bd(n_o, p, n_o, alpha, Ao.T.copy(), Co.T.copy(), w.copy(),
                                                "D" if dt else "C")
    except Exception as exc:  # slycot raises its own error types
        raise DesignError(f"pole placement failed for the poles {fmt_modes(poles)}: {exc}; the pair is "
                          f"numerically close to unobservable — rescale the model or choose other poles") from None
    if nap != n_o:
        raise DesignError(f"Schur pole placement assigned only {nap} of {n_o} poles ({nup} modes detected "
                          f"as unobservable): the pair is too close to unobservable")
    return -F.T, "Schur (SLICOT SB01BD)"


def _ordered(poles: np.ndarray) -> np.ndarray:
    """Real poles first, then complex pairs with the conjugates adjacent."""
    real = [complex(q.real, 0.0) for q in poles if abs(q.imag) <= 1e-12 * max(1.0, abs(q))]
    upper = sorted((q for q in poles if q.imag > 1e-12 * max(1.0, abs(q))), key=lambda q: (q.real, q.imag))
    out = real[:]
    for q in upper:
        out.extend([q, np.conj(q)])
    return np.array(out, complex)


# ----------------------------------------------------------------------- Riccati
@dataclass
class RiccatiFilter:
    """Steady-state Kalman filter data (see :func:`filter_riccati`)."""

    P: np.ndarray      # prior (predicted) error covariance; the CARE solution in continuous time
    L: np.ndarray      # observer gain of the predictor form: eig(A − L C) stable
    Kf: np.ndarray     # filter (measurement-update) gain, discrete time; equals L in continuous time
    Sigma: np.ndarray  # innovation covariance (discrete) or intensity (continuous)
    #: the forward measure the answer was accepted by: ``forward`` = ‖P_K − P‖_F / scale (P_K the error covariance of
    #: the filter run with L, by its Lyapunov/Stein equation; scale = max(‖P‖_F, ‖Qx‖_F/(2‖A‖_F)), discrete
    #: ‖Qx‖_F/(1 + ‖A‖_F²): riccati_newton.solution_scale), at most FORWARD_RTOL; ``newton_steps`` taken to get
    #: there; ``gain_forward`` = ‖ΔL‖_F / ‖L‖_F, L's forward error to first order (ΔL from P_K − P; stated, not bounded)
    accuracy: dict = field(default_factory=dict)


def filter_riccati(A, C, Qx, R, S, dt: float, what: str = "the Kalman filter") -> RiccatiFilter:
    """Stabilising solution of the filter Riccati equation and the gains built from it.

    Continuous time (CARE), with ``Σ = R``:

        A P + P Aᵀ − (P Cᵀ + S) R⁻¹ (C P + Sᵀ) + Qx = 0,     L = (P Cᵀ + S) R⁻¹.

    Discrete time (DARE), ``P`` the covariance of ``x_k − x̂_{k|k−1}``:

        P = A P Aᵀ + Qx − (A P Cᵀ + S) Σ⁻¹ (A P Cᵀ + S)ᵀ,    Σ = C P Cᵀ + R,
        K_f = P Cᵀ Σ⁻¹,    L = A K_f + S Σ⁻¹ = (A P Cᵀ + S) Σ⁻¹.

    ``Qx``, ``R``, ``S`` are the covariances of the process noise, the measurement noise and
    their cross-covariance. The states no noise reaches and whose modes are stable are
    deflated first (:func:`_deflated_riccati`: the stabilising solution is zero on them,
    exactly); the rest is solved, scaled, by the Schur/QZ methods of ``scipy.linalg``
    (Laub 1979; Arnold & Laub 1984), then SLICOT SB02OD, then Newton's method from their answer
    (:func:`~fmu_fdi.design.toolkit.approximate.spectral_riccati`). Those raise for most problems without a stabilising
    solution but can return a non-stabilising one, so the closed loop is checked as well. The answer is accepted by a
    forward measure on this (caller's) equation, not only by its residual: the filter run with ``L`` has the error
    covariance ``P_K`` of its Lyapunov (Stein) equation, ``P_K − P`` is ``P``'s forward error to first order, and it
    must be within ``FORWARD_RTOL`` = 1e-6 of ``‖P‖`` — refined by Newton's steps where it is not, a DesignError
    naming the correction, the closed loop's separation and the rounding floor where they cannot bring it there
    (:func:`~fmu_fdi.design.toolkit.riccati_newton.forward_refined`); ``accuracy`` holds the figure.
    A stabilising solution exists iff ``(A, C)`` is detectable and ``(A − S R⁻¹ C,
    Qx − S R⁻¹ Sᵀ)`` has no uncontrollable mode on the stability boundary (Chan, Goodwin &
    Sin 1984); such modes are named in the error.
    """
    n = A.shape[0]

    def no_solution(detail: str) -> DesignError:
        return DesignError(
            f"{what}: the filter Riccati equation has no stabilising solution ({detail}). It needs (A, C) "
            f"detectable and no mode on the stability boundary that the process noise cannot reach "
            f"(the pair (A − S R⁻¹ C, Qx − S R⁻¹ Sᵀ) must have no uncontrollable mode with "
            f"{'|z| = 1' if dt else 'Re s = 0'})")

    def failed(detail: str) -> DesignError:
        """A solve that failed after the deflation: non-existence or a numerical failure, decided by the data."""
        exists, why = riccati_existence(A, C, Qx, R, S, dt)
        if exists is False:
            return no_solution(f"{why}; {detail}")
        if exists:
            return DesignError(
                f"{what}: the filter Riccati equation has a stabilising solution — {why} — but it was not computed "
                f"to the accuracy a gain needs, a numerical failure: {detail}. States scaled over many decades or "
                f"modes the outputs hardly see cause this: rescale the states")
        return DesignError(f"{what}: the filter Riccati equation was not solved ({detail}); whether a stabilising "
                           f"solution exists was not decided ({why})")

    P = _deflated_riccati(A, C, Qx, R, S, dt, no_solution, failed)
    Sigma = _innovation_covariance(C, P, R, dt, what)
    accuracy = {"forward": 0.0, "newton_steps": 0}
    if n:
        P = _forward_checked(A, C, Qx, R, S, P, dt, failed, what, accuracy)
        Sigma = _innovation_covariance(C, P, R, dt, what)
    if dt:
        Kf = sla.solve(Sigma, C @ P, assume_a="pos").T
        L = sla.solve(Sigma, (A @ P @ C.T + S).T, assume_a="pos").T
    else:
        L = sla.solve(Sigma, (P @ C.T + S).T, assume_a="pos").T
        Kf = L
    poles = np.linalg.eigvals(A - L @ C) if n else np.zeros(0)
    bad = unstable(poles, dt, max(1.0, float(np.linalg.norm(A, 2)) if n else 1.0))
    if bad.size:
        raise failed(f"the solver's solution leaves the modes {fmt_modes(bad)} of A − L C unstable")
    # the gain's forward error to first order, from P's correction Δ = P_K − P: continuous ΔL = Δ Cᵀ R⁻¹; discrete
    # (L = (A P Cᵀ + S) Σ⁻¹, Σ = C P Cᵀ + R) ΔL = (A Δ Cᵀ − L C Δ Cᵀ) Σ⁻¹
    D = accuracy.pop("correction", None)
    if D is not None and n:
        dL = (sla.solve(Sigma, (A @ D @ C.T - L @ (C @ D @ C.T)).T, assume_a="pos").T if dt
              else sla.solve(Sigma, (D @ C.T).T, assume_a="pos").T)
        accuracy["gain_forward"] = float(np.linalg.norm(dL) / max(float(np.linalg.norm(L)), np.finfo(float).tiny))
    return RiccatiFilter(P, L, Kf, Sigma, accuracy)


def _innovation_covariance(C, P, R, dt: float, what: str) -> np.ndarray:
    """``Σ = C P Cᵀ + R`` (discrete) or ``R`` (continuous), symmetrised; a DesignError where it is not numerically
    positive definite."""
    Sigma = C @ P @ C.T + R if dt else R
    Sigma = (Sigma + Sigma.T) / 2
    # Σ > 0 in exact arithmetic (P ⪰ 0, R > 0); in floating point R can lie below the rounding of C P Cᵀ, and then
    # no gain computed from Σ has any accuracy: refused where Σ's condition exceeds 1/(p·eps)
    ev = np.linalg.eigvalsh(Sigma) if Sigma.size else np.ones(1)
    if not ev[0] > Sigma.shape[0] * EPS * ev[-1]:
        raise DesignError(
            f"{what}: the innovation covariance Σ = {'C P Cᵀ + R' if dt else 'R'} is not numerically positive "
            f"definite (eigenvalues {ev[0]:.3g} … {ev[-1]:.3g}; R's smallest eigenvalue "
            f"{float(np.linalg.eigvalsh((R + R.T) / 2)[0]):.3g} is below the rounding of the predicted output "
            f"covariance): the gain is not computable to any accuracy; scale the outputs or raise R")
    return Sigma


def _deflated_riccati(A, C, Qx, R, S, dt: float, no_solution, failed) -> np.ndarray:
    """Stabilising ``P`` of the filter Riccati equation, the states no noise reaches deflated.

    Removing the cross-covariance (Anderson & Moore 1979, sec. 5.5) gives the equivalent
    equation with ``S = 0`` for ``Ā = A − S R⁻¹ C`` and ``Q̄ = Qx − S R⁻¹ Sᵀ = G Gᵀ`` (``G`` from
    :func:`noise_factor`: the rank decided in ``Q̄``'s graded scaling). All that follows runs in the
    coordinates of ``Ā``'s diagonal balancing (exact; the caller's coordinates below mean those), and ``P``
    is mapped back. An orthogonal controllability staircase of ``(Ā, G)`` (:func:`observable_staircase` on the
    dual, ``G`` normalised so the rank decision is relative to ``||Ā||`` and 1) and an
    ordered real Schur form of its uncontrollable block give orthogonal ``T = [T₁ T₂]`` with

        Tᵀ Ā T = [Ā₁₁ Ā₁₂; 0 Ā₂₂],     Tᵀ G = [G₁; 0],     eig(Ā₂₂) stable.

    The states ``T₂ᵀ x`` see no noise and their error decays by itself, so ``P = T₁ P₁₁ T₁ᵀ``
    with ``P₁₁`` the stabilising solution of the reduced equation ``(Ā₁₁, C T₁, G₁ G₁ᵀ, R)``
    (substitute: every term of the (1,2) and (2,2) blocks vanishes), and
    ``eig(A − L C) = eig(closed loop of the reduced problem) ∪ eig(Ā₂₂)``. Where nothing is
    deflated (``T₂`` empty) ``T₁ = I``: the staircase basis would only mix the caller's
    coordinates, and on badly scaled models (states over eight decades) the direct solvers'
    answers in mixed coordinates miss ``RICCATI_RTOL`` where those in the caller's do not
    (tests/test_kalman_riccati.py's seeded problems, benchmarks/riccati_refinement.py: 151 of
    180 designed with the mixing, 175 without, both with the Newton refinement). Where something is
    deflated the staircase basis still mixes them, and that cost accuracy: on the deflated seeded problems
    of tests/test_riccati_forward.py 32 of 172 answers had forward errors above 1e-6 in the caller's
    coordinates (up to 1.2e-2) with residuals within RICCATI_RTOL; the answer is therefore judged, and
    refined, on the caller's whole equation (its Qx, S, coordinates) after the reduced solve — 0 of 172
    above 1e-6 (benchmarks/riccati_forward.py). The balancing (kalman18) then designed the 8 deflated problems
    of that set refused before, and 18 of 300 random problems scaled over nine decades
    (tests/test_riccati_failure_messages.py), without Newton steps. Without the deflation,
    scipy's solvers reject e.g. ``Qx = 0`` with a slow stable mode (the solution ``P = 0``
    makes their relative symmetry check on ``U₁₁ᴴ U₂₁`` compare rounding with rounding).
    Uncontrollable modes on the stability boundary admit no stabilising solution and are
    named; the reduced problem is solved after the scalar scaling ``P = γ P̃`` (``Q̄/γ``,
    ``R/γ``, ``γ = sqrt(||Q̄₁₁|| / ||C₁ᵀ R⁻¹ C₁||)``), which balances the two quadratic
    terms of the pencil.
    """
    n = A.shape[0]
    if n == 0:
        return np.zeros((0, 0))
    SRi = sla.solve(R, S.T, assume_a="pos").T if S.size else np.zeros((n, R.shape[0]))
    Ab = A - SRi @ C
    M = SRi @ S.T
    Qb = Qx - M
    Qb = (Qb + Qb.T) / 2
    G = noise_factor(Qx, (M + M.T) / 2, Qb)
    # the deflation and the reduced solve run in the coordinates of Ā's diagonal balancing, x = T x̃ (LAPACK GEBAL,
    # T = diag(t) of powers of 2: exact): Ã = T⁻¹ĀT, C̃ = CT, Q̃ = T⁻¹Q̄T⁻¹, G̃ = T⁻¹G, P = T P̃ T. In the caller's
    # coordinates the staircase's rank decisions (relative to ‖[Ā; G]‖) and the direct solvers' subspaces met states
    # scaled over decades: the staircase took a noise direction of relative size 2e-8 for none where ‖Ā‖ = 1.5e7, and
    # the reduced answer, within RICCATI_RTOL, did not stabilise the caller's loop
    # (tests/test_riccati_failure_messages.py: 18 of 300 random scaled problems; tests/test_riccati_forward.py
    # deflated 8 of 180 refused) — none of them now.
    # The graded rank decision of noise_factor is invariant under T (d_i and H scale together).
    bal = DiagonalBalancing.of(Ab)
    Ab, C, Qb, G = bal.similar(Ab), bal.right(C), bal.inv_congruent(Qb), bal.inv_left(G)
    scale = max(1.0, float(np.linalg.norm(Ab, 2)))
    if G.shape[1]:
        Z, n_c = observable_staircase(Ab.T, (G / np.linalg.norm(G, 2)).T)
    else:
        Z, n_c = np.eye(n), 0
    if n_c < n:
        Au = Z[:, n_c:].T @ Ab @ Z[:, n_c:]
        margin = 1e3 * EPS * scale
        if dt:
            out = (lambda re, im: abs(complex(re, im)) >= 1.0 - margin)
        else:
            out = (lambda re, im: re >= -margin)
        Tu, U, n_u = ordered_schur(Au, out)
        modes = np.linalg.eigvals(Tu[:n_u, :n_u]) if n_u else np.zeros(0)
        edge = modes[np.abs(np.abs(modes) - 1.0) <= margin] if dt else modes[np.abs(modes.real) <= margin]
        if edge.size:
            raise no_solution(f"the modes {fmt_modes(edge)} lie on the stability boundary and no process "
                              f"noise reaches them")
        Z = np.hstack([Z[:, :n_c], Z[:, n_c:] @ U])
        n_c += n_u
    if n_c == 0:
        return np.zeros((n, n))
    T1 = Z[:, :n_c] if n_c < n else np.eye(n)  # nothing deflated: the caller's coordinates, not the staircase's
    A1, C1 = T1.T @ Ab @ T1, C @ T1
    Q1 = T1.T @ Qb @ T1
    Q1 = (Q1 + Q1.T) / 2
    W = C1.T @ sla.solve(R, C1, assume_a="pos") if R.size else np.zeros((n_c, n_c))
    q, w = float(np.linalg.norm(Q1, 2)), float(np.linalg.norm(W, 2))
    gamma = np.sqrt(q / w) if q > 0 and w > 0 else 1.0
    # the dual of the spectral factorisation's equation on factors (Q̄₁₁/γ = HᵀH, R/γ = DᵀD, cross term HᵀD = 0):
    # scipy's QZ solver, then SLICOT SB02OD, each answer kept only if its residual is within RICCATI_RTOL, else refined
    # by Newton's method from one with a stable closed loop (toolkit.riccati_newton) — scipy's solver can return,
    # without an error, a P with a residual of the order of its terms (random discrete H2 seed 9 of
    # approximate_matching._filter_dare: an indefinite P of norm 1e14, relative residual 0.75)
    lq, vq = np.linalg.eigh(Q1 / gamma)
    H = np.sqrt(np.clip(lq, 0.0, None))[:, None] * vq.T
    Rf = sla.cholesky(R / gamma) if R.size else np.zeros((0, 0))
    Cf = np.vstack([H, np.zeros((Rf.shape[0], n_c))])
    Df = np.vstack([np.zeros((n_c, Rf.shape[1])), Rf])
    with np.errstate(all="ignore"), warnings.catch_warnings():  # SB02OD's wrapper divides α/β at infinite eigenvalues
        warnings.simplefilter("ignore", RuntimeWarning)
        P1 = spectral_riccati(A1.T.copy(), C1.T.copy(), Cf, Df, dt, forward=False)
    if P1 is None:
        raise failed(_refusal("the reduced filter Riccati equation", {}))
    P = T1 @ (gamma * (P1 + P1.T) / 2) @ T1.T
    P = bal.congruent(P)
    P = (P + P.T) / 2
    return P


def noise_factor(Qx: np.ndarray, M: np.ndarray, Qb: np.ndarray) -> np.ndarray:
    """``G`` with ``G Gᵀ = Q̄ = Qx − M`` (``M = S R⁻¹ Sᵀ``) on the directions the data can tell from zero.

    The rank of ``Q̄`` is decided in the graded scaling ``H = D⁻¹ Q̄ D⁻¹``, ``D = diag(d)``,
    ``d_i = √max(Qx_ii, M_ii)`` — not relative to ``‖Qx‖``. Derivation: ``Q̄`` is formed from ``Qx`` (itself formed
    as ``Bw Qw Bwᵀ``) and ``M`` by sums of products, whose rounding is componentwise, ``|δQ̄_ij| ≤ c·eps·(|Qx|_ij +
    |M|_ij)`` (``c`` the inner dimensions); both terms are positive semidefinite, ``|Qx_ij| ≤ √(Qx_ii Qx_jj)`` and
    likewise ``M``, so ``|δQ̄_ij| ≤ 2c·eps·d_i d_j``: ``H``'s rounding ``E`` has ``|E_ij| ≤ 2c·eps``,
    ``‖E‖₂ ≤ 2c·n·eps``
    against terms ``D⁻¹QxD⁻¹``, ``D⁻¹MD⁻¹`` of unit diagonal at most. An eigenvalue of ``H`` below
    ``default_rtol = 1e3·n·eps`` times their norm is therefore indistinguishable from rounding (a cancellation
    ``Qx ≈ M``: fully correlated noise), while the noise of a state scaled by ``s`` — intensity ``s²`` of ``‖Qx‖`` —
    is a unit diagonal entry of ``H`` and kept at every ``s`` (the data is exact; what it says about that state is
    not rounding). The decision relative to ``‖Qx‖`` (before) dropped it below ``s ≈ 1e-7``: for an integrator (a
    random walk) that noise drives, the filter was refused as having no stabilising solution, for a slow mode
    (``−1e-6``) refused as too ill-conditioned (tests/test_kalman_noise_rank.py). The eigenvalues of ``H`` are
    computed by ``eigh`` to ``eps·‖H‖`` (``‖H‖ ≤ n``), so the decision is as accurate as the data; ``G = D V Λ^½``
    on the kept ones. States with ``d_i = 0`` see no noise exactly (``Q̄``'s row is zero)."""
    n = Qb.shape[0]
    d = np.sqrt(np.clip(np.maximum(np.diag(Qx), np.diag(M)), 0.0, None))
    on = d > 0
    if not np.any(on):
        return np.zeros((n, 0))
    di = d[on]
    H = Qb[np.ix_(on, on)] / di[:, None] / di[None, :]
    terms = max(float(np.linalg.norm(Qx[np.ix_(on, on)] / di[:, None] / di[None, :], 2)),
                float(np.linalg.norm(M[np.ix_(on, on)] / di[:, None] / di[None, :], 2)))
    lam, V = sla.eigh((H + H.T) / 2)
    keep = lam > default_rtol(H.shape) * terms
    G = np.zeros((n, int(np.sum(keep))))
    G[on] = di[:, None] * V[:, keep] * np.sqrt(lam[keep])
    return G


def _forward_checked(A, C, Qx, R, S, P, dt: float, failed, what: str, accuracy: dict) -> np.ndarray:
    """``P`` (or its Newton refinement) accepted by the forward measure on the caller's filter equation, else a
    DesignError naming the figures; ``accuracy`` receives ``forward``, ``newton_steps`` and the ``correction``."""
    # The forward measure is read on the caller's equation — its coordinates and its Qx, S — not on the reduced one:
    # the reduced equation is in the staircase's orthogonal basis where something is deflated, which mixes states
    # scaled over decades, and its factor H (Q̄₁₁/γ = HᵀH by an eigendecomposition) is exact only to eps·‖Q̄‖, which
    # on rows scaled over eight decades is another equation for the small states (tests/test_kalman_riccati.py seed
    # 54 trial 2: forward error 3.7e-9 on the factored equation, 0.81 on the caller's, the residual 2e-11 on both).
    # Refined there by Newton's full steps (toolkit.riccati_newton.forward_refined) where it is not within
    # FORWARD_RTOL; measured in benchmarks/riccati_forward.py.
    full: dict = {}
    refined = forward_refined(A.T.copy(), C.T.copy(), Qx, R, S, P, dt, FORWARD_RTOL, figures=full)
    if refined is None:
        if np.isfinite(full.get("forward", np.inf)):
            raise DesignError(f"{what}: {_refusal('the filter Riccati equation', full)}")
        # the reduced equation was solved within RICCATI_RTOL, but its answer's gain does not stabilise the caller's
        # loop: a residual (backward) line passed another matrix than the stabilising solution — name its figures
        res = riccati_residual(A.T, C.T, Qx, R, S, P, dt)
        loop = ""
        if res is not None:
            ev = np.linalg.eigvals(A + res[1].T @ C)
            worst = ev[np.argmax(np.abs(ev))] if dt else ev[np.argmax(ev.real)]
            loop = (f"; its relative residual on this equation is {res[0]:.3g} and its gain leaves the filter's loop "
                    f"with the mode {fmt_modes([worst])}")
        raise failed(f"the reduced equation's answer, accepted by its residual, is not the stabilising solution{loop} "
                     f"(no stabilising start for Newton's refinement)")
    accuracy.update(forward=float(full["forward"]), newton_steps=int(full["steps"]), correction=full["correction"])
    return refined


def riccati_existence(A, C, Qx, R, S, dt: float) -> tuple[bool | None, str]:
    """``(exists, why)``: whether the filter Riccati equation of :func:`filter_riccati` (data ``A, C, Qx, R, S`` in
    filter form) has a stabilising solution, decided by the data — ``(A, C)`` detectable (:func:`observable_order`)
    and the Hamiltonian (symplectic) pencil's eigenvalues off the
    stability boundary by more than the tolerance of :func:`~fmu_fdi.design.toolkit.riccati_newton.boundary_gap`
    (``√(N·eps)·‖pencil‖``: a boundary eigenvalue is a double one and moves by that much under rounding) —
    ``exists = None`` where the pencil's eigenvalues could not be computed. Read only for a failure's message
    (:func:`filter_riccati`'s, approximate_matching's filter DARE)."""
    try:
        observable_order(A, C, dt)
    except DesignError as exc:
        return False, str(exc)
    gap = boundary_gap(A.T.copy(), C.T.copy(), Qx, R, S, dt)
    if gap is None:
        return None, "the Hamiltonian pencil's eigenvalues could not be computed"
    where = "unit circle" if dt else "imaginary axis"
    if gap["distance"] <= gap["tol"]:
        return False, (f"the Hamiltonian pencil has the eigenvalue {fmt_modes([gap['nearest']])}, "
                       f"{gap['distance']:.3g} from the {where}, within the tolerance {gap['tol']:.3g} (√(N·eps) times "
                       f"the pencil's norm, how far rounding moves a double eigenvalue): a mode on the stability "
                       f"boundary that the noise does not reach or the outputs do not see, to working accuracy")
    return True, (f"(A, C) is detectable and the Hamiltonian pencil's eigenvalues lie at least {gap['distance']:.3g} "
                  f"from the {where}, beyond the tolerance {gap['tol']:.3g}")


#: a refused answer's correction this many times the rounding floor (riccati_newton._condition: SB03MD's sep is an
#: estimate, within a factor ~n of the separation, and the floor a first-order bound) is not held up by rounding: the
#: iteration had not converged — a numerical failure of the method, not the equation's conditioning
NOT_CONVERGED_FACTOR = 1e2


def _refusal(what: str, got: dict) -> str:
    """The reason no answer of ``what`` was accepted, with the figures of the closest one."""
    fwd = got.get("forward", np.inf)
    if np.isfinite(fwd):
        head = (f"the stabilising solution exists (a solver's answer has a relative residual within RICCATI_RTOL = "
                f"{RICCATI_RTOL:g} and a stabilising gain) but the closest answer's closed-loop correction ‖P_K − P‖_F "
                f"(P_K the error covariance of the filter run with its gain: the forward error of P to first order) is "
                f"{fwd:.3g} of ‖P‖_F, above FORWARD_RTOL = {FORWARD_RTOL:g} ({got.get('why', '')})")
        if "sep" not in got:
            return (f"{what} was not solved to the accuracy a gain needs: {head}. Nearly unobservable or undetectable "
                    f"modes, or states scaled over many decades, cause this: rescale the states")
        fb = got.get("forward_balanced", fwd)
        cond = (f"; in the coordinates of the diagonal balancing of the closed loop its Lyapunov separation is "
                f"sep = {got['sep']:.3g} against the residual's terms {got['size']:.3g}, so the rounding of the "
                f"residual alone can move P there by up to {got['floor']:.3g} of its scale (the correction there: "
                f"{fb:.3g})")
        if fb > NOT_CONVERGED_FACTOR * got["floor"]:
            return (f"{what} was not solved to the accuracy a gain needs, a numerical failure: {head}{cond} — the "
                    f"correction is far above that floor, so it is not the equation's conditioning that stops it but "
                    f"Newton's iteration from the solvers' answer, which did not converge in the steps allowed (a slow "
                    f"mode the noise hardly reaches, or states scaled over many decades, cause this: rescale the "
                    f"states)")
        return (f"{what} is too ill-conditioned for an accurate gain: {head}{cond}. Nearly unobservable or "
                f"undetectable modes, or states scaled over many decades, cause this: rescale the states or remove "
                f"the modes the outputs hardly see")
    return (f"no solution of {what} with a residual within RICCATI_RTOL = {RICCATI_RTOL:g} of its terms and a "
            f"stabilising gain (scipy's QZ solver, SLICOT SB02OD, Newton's method from an answer of theirs with a "
            f"stable closed loop)")


# ------------------------------------------------------------------------ filters
def output_observer(model: FDIModel, L: np.ndarray, W: np.ndarray | None = None) -> LTI:
    """The filter ``r = W (y − C x̂ − Du u)`` of the observer with gain ``L``, from ``[y; u]``."""
    A, Bu, C, Du = model.A, model.Bu, model.C, model.Du
    W = np.eye(model.ny) if W is None else np.asarray(W, float)
    return LTI(A - L @ C, np.hstack([L, Bu - L @ Du]), -W @ C, np.hstack([W, -W @ Du]), model.dt)


def residual_names(model: FDIModel, W: np.ndarray | None = None) -> list[str] | None:
    """``r_<output>`` when residual i is the output error of output i, else the default names."""
    return [f"r_{y}" for y in model.y_names] if W is None else None


def observer_generator(model: FDIModel, Q: LTI, method: str, info: dict, names=None) -> ResidualGenerator:
    """Wrap an observer residual filter; the residual vector is one group.

    ``info['detected_faults']`` lists the faults whose response ``Rf_j`` is not identically
    zero (weak structure of the whole residual vector, :func:`~fmu_fdi.analysis.structure_matrix`).
    """
    from ...analysis import structure_matrix

    gen = ResidualGenerator(Q, model, method, names, groups=[list(range(Q.p))], info=info)
    if model.faults:
        seen = structure_matrix(gen)[0]
        gen.info["detected_faults"] = [nm for nm, s in zip(model.fault_names, seen) if s]
    else:
        gen.info["detected_faults"] = []
    from ..toolkit.postconditions import check_generator

    # an observer residual decouples u (the UIO also d); it promises no fault structure
    check_generator(gen, decouple=("u", "d") if method == "unknown_input_observer" else ("u",), faults=[],
                    block=True)
    return gen


def as_matrix(X, what: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    """A finite 2-D float matrix of the given shape, or a DesignError naming ``what``."""
    try:
        M = np.asarray(X, dtype=float)
    except (TypeError, ValueError):
        raise DesignError(f"{what} must be a numeric matrix, got {X!r}") from None
    if M.ndim != 2:
        raise DesignError(f"{what} must be a 2-D matrix, got shape {M.shape}")
    if (rows is not None and M.shape[0] != rows) or (cols is not None and M.shape[1] != cols):
        want = f"{rows if rows is not None else 'k'}x{cols if cols is not None else 'k'}"
        raise DesignError(f"{what} must be {want}, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise DesignError(f"{what} contains NaN or Inf")
    return M
