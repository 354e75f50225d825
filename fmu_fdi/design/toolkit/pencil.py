"""Proper stable left null-space basis of ``G(λ) = [Gu Gd; I 0]`` from the system pencil.

The polynomial (parity) basis of :mod:`._basis` works with powers ``C A^k`` and loses
precision at degrees 10-20; this module never forms a power of A. It follows Varga's
``glnull`` (Varga 2017, sec. 7.4 and 10.3.2; DescriptorSystems.jl): every left annihilator
of ``G`` is ``Nl = [Nd  -Nd Gu]`` with ``Nd`` a left null-space basis of ``Gd``, and a
row ``[w(λ) v(λ)]`` annihilates the system pencil of ``Gd``,

    [w v] [A - λI  Bd; C  Dd] = 0,    w = v C (λI - A)^{-1},    v Gd = 0,

so that ``Nu = -(w Bu + v Du)``. We work on the dual (transposed) pencil, whose right
null vectors ``[X(λ); U(λ)]`` are the state and input trajectories of
``x' = Aᵀ x + Cᵀ u`` that keep the output ``Bdᵀ x + Ddᵀ u`` identically zero: the
output-nulling subspace V* and its friend ``u = F x + K w`` (Morse 1973; Wonham, ch. 4).
It is computed by orthogonal deflation (SVD at every step, rank decisions with
``max(atol, rtol·||[A B; C D]||)`` as Varga's ``atol``/``rtol``):

- a feedthrough of rank r fixes r input directions: ``w₁ = -Σ₁⁻¹ U₁ᵀ c x``;
- an output map c of rank ρ with no feedthrough forces ``x`` into ``ker c`` (ρ states
  fewer), and keeping it there is the next output: ``c ← W₁ᵀ a W₂``, ``d ← W₁ᵀ b``;
- it stops when no constraint is left. The controllable part of ``(a_f, b_f)`` (an
  orthogonal staircase) is the reachability subspace R*; its dimension is the sum of the
  left minimal indices of ``G`` and the staircase block sizes give the indices themselves
  (the controllability indices of the pair on R*; Morse 1973) — the degrees of a minimal
  polynomial basis, without forming it.

Transposing back gives ``Nl(λ) = Cl (λI - Al)^{-1} Bl + Dl`` with ``Al = a_fᵀ`` — a
proper basis of McMillan degree Σ indices (minimal when the realisation of ``[Gu Gd]``
is). Its poles are free (state feedback on the controllable pair = a left coprime
factor ``M⁻¹``): eigenvalues outside the stability region (margin, ``sdeg``) are moved,
one Schur block at a time, leaving the others in place (Varga 1981); a full placement of a
25-state pair with one or two inputs would need gains far above the data's norm. The basis is
realised in the Schur coordinates of that closed loop (:func:`schur_feedback`): a weakly
controllable pole needs a large gain by any method, and ``a + bF`` formed in other coordinates
would lose its eigenvalues to cancellation.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ...compression import RowCompression, nonzero_spans, staircase_zeros
from ...errors import DesignError
from ...freqresp import eigenvalues
from ...linalg import EPS, ordered_schur
from ...lti import LTI
from ...model import FDIModel


@dataclass
class PencilBasis:
    """A proper left null-space basis ``Nl(λ)`` of ``[Gu Gd; I 0]`` acting on ``[y; u]``."""

    N: LTI
    degrees: list[int]
    rank_d: int
    info: dict = field(default_factory=dict)
    #: ``(a, b, c, d)``: realisation of ``Nlᵀ`` (dual, input w = the k basis rows) before the poles are moved
    dual: tuple | None = None
    #: ``(choose, good, full)`` of :func:`assign_poles` as used for ``N``
    placement: tuple | None = None
    rank_tol: float = 0.0


def _rank(s: np.ndarray, tol: float) -> int:
    return int(np.sum(s > tol))


def _rotate(U: np.ndarray, sl: slice, a: np.ndarray, rows=(), cols=()) -> None:
    """In place, with ``Z`` the identity whose block ``(sl, sl)`` is ``U``: ``a ← Zᵀ a Z``,
    each of ``rows`` ``← Zᵀ X``, each of ``cols`` ``← X Z`` — only the rows/columns in ``sl``
    change, so a staircase step costs O(n²·|sl|) instead of two dense n × n products."""
    a[sl, :] = U.T @ a[sl, :]
    a[:, sl] = a[:, sl] @ U
    for X in rows:
        X[sl, :] = U.T @ X[sl, :]
    for X in cols:
        X[:, sl] = X[:, sl] @ U


def controllable_staircase(a: np.ndarray, b: np.ndarray, tol: float):
    """Orthogonal controllability staircase of ``(a, b)``: ``(T, taus)``.

    ``Tᵀ a T`` is block upper Hessenberg with sub-diagonal blocks of full row rank
    ``taus[0] ≥ taus[1] ≥ ...``; the first ``sum(taus)`` columns of T span the controllable
    subspace. Ranks by SVD with the absolute threshold ``tol``.
    """
    n = a.shape[0]
    T = np.eye(n)
    a = a.copy()
    taus: list[int] = []
    start = 0
    blk = b.copy()
    while start < n and blk.size:
        cmp = RowCompression(blk)
        tau = _rank(cmp.s, tol)
        if tau == 0:
            break
        # rotate the remaining coordinates so that the first tau rows carry the block
        # (Z = diag(I, U): only the trailing rows/columns change, O(n²·|blk|) by reflections)
        cmp.rotate(start, a, rows=(), cols=(T,))
        taus.append(tau)
        blk = a[start + tau:, start:start + tau]
        start += tau
    return T, taus


def conjugate_partition(taus: list[int], k: int) -> list[int]:
    """Controllability indices from staircase block sizes: index i is the number of blocks
    with more than i columns; ``k - taus[0]`` indices are 0 (ascending order)."""
    idx = [sum(1 for t in taus if t > i) for i in range(taus[0])] if taus else []
    return sorted([0] * (k - len(idx)) + idx)


def _output_nulling(a, b, c, d, tol):
    """Output-nulling deflation of ``x' = a x + b u, 0 = c x + d u``.

    Returns ``(P, af, bf, F, K, fnorm)``: every trajectory keeping the output zero is
    ``x = P ξ``, ``u = F ξ + K w``, ``ξ' = af ξ + bf w`` with free w.
    """
    n, p = b.shape
    P, af, bf = np.eye(n), a.copy(), b.copy()
    F, K = np.zeros((p, n)), np.eye(p)
    cc, dc = c.copy(), d.copy()
    fnorm = 0.0
    for _ in range(2 * (n + p) + 2):
        if dc.size and cc.shape[0]:
            U, s, Vh = sla.svd(dc, full_matrices=True)
            r = _rank(s, tol)
            if r:
                V1, V2 = Vh[:r].T, Vh[r:].T
                G = -(V1 / s[:r]) @ (U[:, :r].T @ cc)  # w = G ξ + V2 w2 solves the r pivot rows
                fnorm = max(fnorm, float(np.linalg.norm(G, 2)) if G.size else 0.0)
                af = af + bf @ G
                F = F + K @ G
                bf, K = bf @ V2, K @ V2
                cc = U[:, r:].T @ cc
                dc = np.zeros((cc.shape[0], K.shape[1]))
        if cc.shape[0] == 0 or cc.shape[1] == 0:
            break
        _, s, Wh = sla.svd(cc, full_matrices=True)
        rho = _rank(s, tol)
        if rho == 0:
            break
        W1, W2 = Wh[:rho].T, Wh[rho:].T
        cc, dc = W1.T @ af @ W2, W1.T @ bf
        af, bf = W2.T @ af @ W2, W2.T @ bf
        P, F = P @ W2, F @ W2
    else:  # pragma: no cover - each pass removes states or constraints
        raise DesignError("pencil null space: the output-nulling deflation did not terminate")
    return P, af, bf, F, K, fnorm


def _place(a: np.ndarray, b: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Gain F with ``eig(a + b F) = targets`` (scipy's robust KNV/YT method); targets of a
    multiplicity above rank b are spread by a relative 1e-3 so the method applies."""
    from scipy.signal import place_poles

    targets = np.asarray(targets, complex)
    if a.shape[0] == 0:
        return np.zeros((b.shape[1], 0))
    rb = max(1, np.linalg.matrix_rank(b))
    if a.shape[0] == 2 and rb == 1 and abs(targets[0] - targets[1]) <= 1e-9 * max(1.0, abs(targets[0])):
        return _place_double(a, b, targets[0].real)
    t = targets.copy()
    for i in range(t.size):  # spread repeats of the *requested* values (conjugate pairs move together)
        j = int(np.sum(np.abs(targets[:i] - targets[i]) <= 1e-9 * max(1.0, abs(targets[i]))))
        if j >= rb:
            step = 1e-3 * (j - rb + 1)
            t[i] = targets[i] * (1 + step) if targets[i] != 0 else step
    # conjugate closure after spreading: rebuild pairs from the upper half-plane members
    out = [z for z in t if abs(z.imag) <= 1e-12 * max(1.0, abs(z))]
    for z in t:
        if z.imag > 1e-12 * max(1.0, abs(z)):
            out += [z, np.conj(z)]
    # a rank-deficient b (two input columns, one direction: random seed 237's augmented null space) is
    # placed on its rank-rb column space b V1 (SVD), F = V1 F1: scipy's KNV/YT needs full column rank
    V1 = np.linalg.svd(b)[2][:rb].T if rb < b.shape[1] else np.eye(b.shape[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            res = place_poles(a, b @ V1, np.array(out[: a.shape[0]]), method="YT")
        except ValueError as exc:
            from .postconditions import NumericalDesignError

            raise NumericalDesignError(f"pencil null space: the poles cannot be assigned ({exc}); pass other "
                                       f"poles/sdeg") from None
    return -V1 @ res.gain_matrix


def _place_double(a: np.ndarray, b: np.ndarray, target: float) -> np.ndarray:
    """Gain F with the double eigenvalue ``target`` of ``a + b F`` (2 × 2, one input direction):
    Ackermann's formula ``F = -v e₂ᵀ [b v, a b v]⁻¹ (a - t I)²`` on the dominant input direction v
    (exact, where KNV/YT needs distinct targets for a single input)."""
    from .postconditions import NumericalDesignError

    _, _, Vh = np.linalg.svd(b)
    v = Vh[0]
    bv = b @ v
    ctrb = np.column_stack([bv, a @ bv])
    if np.linalg.cond(ctrb) > 1e12:
        raise NumericalDesignError(f"pencil null space: the 2 × 2 block is not controllable from its input "
                                   f"(condition {np.linalg.cond(ctrb):.2e}); pass other poles/sdeg")
    P = (a - target * np.eye(2)) @ (a - target * np.eye(2))
    k = np.linalg.solve(ctrb, P)[1]
    return -np.outer(v, k)


def _pop_targets(targets: list, size: int, dt: float, spare: float) -> np.ndarray:
    """Take ``size`` (1 or 2) targets for one Schur block: a real one, or a conjugate pair / two reals
    (``spare`` when the list has run out)."""
    if not targets:
        return np.full(size, spare, complex)
    real = [i for i, z in enumerate(targets) if abs(z.imag) <= 1e-12 * max(1.0, abs(z))]
    if size == 1:
        if real:
            return np.array([targets.pop(real[0]).real])
        z = targets.pop(0)  # a pair's member: take its speed as a real pole, drop its conjugate
        targets[:] = [w for w in targets if abs(w - np.conj(z)) > 1e-9 * max(1.0, abs(z))] + [z]
        return np.array([abs(z) if dt else z.real])
    pair = [i for i, z in enumerate(targets) if z.imag > 1e-12 * max(1.0, abs(z))]
    if pair:
        z = targets.pop(pair[0])
        k = next((i for i, w in enumerate(targets) if abs(w - np.conj(z)) <= 1e-9 * max(1.0, abs(z))), None)
        if k is not None:
            targets.pop(k)
        return np.array([z, np.conj(z)])
    return np.concatenate([_pop_targets(targets, 1, dt, spare), _pop_targets(targets, 1, dt, spare)])


def assign_poles(a: np.ndarray, b: np.ndarray, dt: float, choose, good, full: bool = False) -> tuple[np.ndarray, int]:
    """State feedback F for the controllable pair ``(a, b)`` moving every eigenvalue outside the
    region ``good(re, im)`` to the targets ``choose(bad_eigenvalues)``: ``(F, moved)``. ``full``: every
    eigenvalue is moved, to ``choose(all eigenvalues)`` (given filter poles: Varga's ``evals``).

    The gain of :func:`schur_feedback` in the original coordinates, ``F = F_Z Zᵀ``. A caller that forms the
    closed loop should take :func:`schur_feedback`'s ``T = Zᵀ(a + bF)Z`` instead of forming ``a + bF``: where the
    gain is large (a weakly controllable bad mode) the latter loses the closed loop's eigenvalues to cancellation.
    """
    T, Z, Fz, moved = schur_feedback(a, b, dt, choose, good, full)
    return Fz @ Z.T, moved


def schur_feedback(a: np.ndarray, b: np.ndarray, dt: float, choose, good,
                   full: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """State feedback for the controllable pair ``(a, b)`` moving every eigenvalue outside the region
    ``good(re, im)`` to ``choose(bad_eigenvalues)`` (``full``: every eigenvalue, to ``choose(all)``), with the
    closed loop computed in Schur coordinates: ``(T, Z, F_Z, moved)``, Z orthogonal,

        Zᵀ (a + b F) Z = T  (quasi-upper triangular),    F = F_Z Zᵀ.

    Schur method (Varga 1981, as in Varga's ``saloc``/``glcf``): an ordered real Schur form puts one bad
    1×1 or 2×2 block last; a feedback acting on its coordinates alone moves it and leaves the other
    eigenvalues where they are; repeat, on the closed loop's Schur form (every step is an orthogonal
    reordering of T and one update of the moved block's columns ``T[:, moved] += (Zᵀb) F₂``).

    *The gain is the least possible; the coordinates carry the accuracy.* For a 1×1 block λ with unit left
    eigenvector w (the last Schur vector), ``wᵀ(a + bF − λI) = (wᵀb) F``, so ``σ_min(a + bF − λI) ≤ ‖wᵀb‖‖F‖``,
    while Bauer–Fike gives ``σ_min(a + bF − λI) ≥ dist(λ, Λ(a + bF)) / κ(V)`` (V the closed loop's eigenvectors):

        ‖F‖ · κ(V) ≥ dist(λ, Λ(a + bF)) / ‖wᵀb‖          for every F, by any method.

    The block step's minimum-norm gain ``(t − λ) B₂ᵀ/‖B₂‖²`` (``B₂ = wᵀb``) has ``‖F₂‖ = |t − λ| / ‖wᵀb‖``: the
    bound with κ = 1. A whole-set placement (KNV/YT, moving the kept eigenvalues too, other targets) can
    only trade gain for eigenvector conditioning — and with one input F is fixed by the targets alone.
    Random seed 207's w-decoupling basis row (order 12, one input): λ = 48.04, ‖wᵀb‖ = 2.07e-4, every target
    in the unit disc: ‖F‖·κ ≥ 47/2.07e-4 = 2.3e5; the block method's ‖F‖ = 2.45e5 for any targets (measured
    for six target pairs; placing all twelve at 0.3…0.6 "with gain 505" left 48 where it was). What the gain
    costs is accuracy, and that depends on where ``a + bF`` is formed. In the original coordinates its entries are
    ``‖b‖‖F‖`` and the closed loop's eigenvalues (of the data's size) emerge from their cancellation: a perturbation
    eps·‖b‖‖F‖ in every entry, amplified by the closed loop's eigenvalue condition, which itself grows with F —
    an error of second order in the gain (seed 207's row leaked 7e-7 … 2.6e-6 of its weakest fault gain; a
    closed-form pair with ‖F‖ = 4.8e4 and 4.8e8, tests/test_synthesis_pencil.py: transfer function off by 3.3e-6
    and 1.0). In Schur coordinates the kept blocks are only reordered (backward error eps·‖a‖), the moved block is
    set to its targets, and the update's rounding is a perturbation ≤ 2·eps·‖b‖‖F‖ of the moved columns only: the
    realisation is backward stable, its error first order in the gain (8.4e-14 and 5.6e-10 on that pair; seed 207's
    row leaks 1.4e-9). So the closed loop is returned in those coordinates, and the callers realise their factors
    there.
    """
    n, m = a.shape[0], b.shape[1]
    Fz = np.zeros((m, n))
    if n == 0:
        return np.asarray(a, float).copy(), np.eye(0), Fz, 0
    eig = eigenvalues(a)  # kept for the basis Nl, whose A is aᵀ when no pole moves (freqresp)
    bad = eig if full else eig[~np.array([good(z.real, z.imag) for z in eig])]
    if bad.size == 0:
        return np.asarray(a, float).copy(), np.eye(n), Fz, 0
    targets = list(np.asarray(choose(bad), complex))
    placed: list[complex] = []
    if full:  # the blocks already moved lead the ordered Schur form; every other block is moved next
        def good(re, im):
            return any(abs(complex(re, im) - t) <= 1e-6 * max(1.0, abs(t)) for t in placed)
    last = targets[-1] if targets else complex(0.5 if dt else -1.0)
    spare = abs(last) if dt else last.real  # a 2×2 block may need one target more than counted
    moved = 0
    T, Z, bz = np.asarray(a, float), np.eye(n), np.asarray(b, float)
    for _ in range(n):
        Ti, Zi, kgood = ordered_schur(T, good)  # T is the closed loop in the coordinates Z (quasi-triangular after step 1)
        T, Z, bz, Fz = Ti, Z @ Zi, Zi.T @ bz, Fz @ Zi
        if kgood == n:
            break
        size = 2 if n - kgood >= 2 and abs(T[n - 1, n - 2]) > 0 else 1
        if full and size == 1 and n - kgood >= 2 and (n == 2 or T[n - 2, n - 3] == 0) and targets and \
                abs(targets[0].imag) > 1e-12 * max(1.0, abs(targets[0])):
            size = 2  # a conjugate pair for two real eigenvalues: the trailing 2 × 2 of the Schur form
        blk, B2 = T[n - size:, n - size:], bz[n - size:]
        # never a target already placed (a pair's speed taken for two real blocks, the spare reused, a block moved
        # again): a repeated eigenvalue of a pair with few inputs is defective and scatters by ~eps^(1/2), which
        # broke the margin and the realisation (random seed 207's row [1 1 0 1 0]: two blocks sent to 0.999 split
        # to 1.0009 ± 0.0038j, were moved 15 times, feedback 2.4e5, eigenvector condition 5e12, leak 2e-6)
        tg = _distinct(np.r_[placed, _pop_targets(targets, size, dt, spare)], bool(dt))[len(placed):]
        placed.extend(tg)
        if size == 1:
            nb = float(np.sum(B2 ** 2))
            if nb <= 0:
                break  # uncontrollable: cannot happen on the controllable part
            F2 = (tg[0].real - blk[0, 0]) * B2.T / nb  # minimum-norm gain: blk + B2 F2 = target
        else:
            F2 = _place(blk, B2, tg)
        T = T.copy()
        T[:, n - size:] += bz @ F2
        if size == 1:
            T[n - 1, n - 1] = tg[0].real  # the target itself, not its rounding
        Fz[:, n - size:] += F2
        moved += size
    return T, Z, Fz, moved


def mirror(eig: np.ndarray, beta: float, dt: bool) -> np.ndarray:
    """Eigenvalues reflected into the region ``Re < β`` (``2β - Re``) or ``|z| < β`` (``β²/|z|``,
    angle kept): distinct eigenvalues stay distinct, which a common target (a defective cluster
    whose computed eigenvalues scatter by eps^(1/multiplicity)) would not."""
    eig = np.asarray(eig, complex)
    if dt:
        r = np.maximum(np.abs(eig), 1e-300)
        return np.where(r > beta, eig / r * beta**2 / r, eig)
    return np.where(eig.real > beta, (2 * beta - eig.real) + 1j * eig.imag, eig)


def _targets(model: FDIModel, poles, sdeg):
    """``eigenvalues to move ↦ targets``: the plant's stabilised eigenvalues spread from slow to fast
    (``_basis.pole_chooser``) with neither poles nor sdeg; with ``poles`` (every eigenvalue moves:
    :func:`pencil_basis`) the given ones first and the rest at ``sdeg`` (default -1, or 0 in discrete
    time: ``_basis.pick_poles``, as the filter's poles are documented); with ``sdeg`` alone the
    eigenvalues slower than it mirrored about it (:func:`mirror`)."""
    from ._basis import pole_chooser

    if poles is None and sdeg is None:
        chooser = pole_chooser(model, None, None)
        return lambda bad: chooser(bad.size)
    if poles is not None:
        chooser = pole_chooser(model, poles, sdeg)
        return lambda eig: _distinct(chooser(eig.size), bool(model.dt))
    return lambda bad: mirror(bad, float(sdeg), bool(model.dt))


#: relative step between repeated targets of a full assignment (:func:`_distinct`)
REPEAT_STEP = 0.05


def _distinct(targets: np.ndarray, dt: bool) -> np.ndarray:
    """Targets made distinct, in order: a value already taken moves to the first free one of
    ``t·(1 + 0.05 j)`` (continuous: faster), ``t·0.95^j`` (discrete: closer to 0; ``0.5·(1 − 0.95^j)``
    for t = 0), j = 1, 2, … A cluster of equal targets assigned to a pair with one or two inputs is
    defective: its computed eigenvalues scatter by ~eps^(1/multiplicity) (7e-6 for five at -2 on a
    15-state basis), so the Schur method could no longer tell the moved blocks from the others; 5 %
    apart they stay accurate to rounding, and every one stays at least as fast as ``sdeg``."""
    out: list[complex] = []
    for z in np.asarray(targets, complex):
        c, j = z, 0
        while any(abs(c - w) <= 1e-9 * max(1.0, abs(w)) for w in out):
            j += 1
            c = ((0.5 * (1 - (1 - REPEAT_STEP) ** j) if z == 0 else z * (1 - REPEAT_STEP) ** j) if dt
                 else z * (1 + REPEAT_STEP * j))
        out.append(c)
    return np.array(out, complex)


def _without_exact_boundary_modes(G: LTI) -> LTI:
    """``G`` without its modes on or beyond the stability boundary that are uncontrollable or unobservable
    to rounding (:func:`fmu_fdi.margin.margin_reduced` at :data:`~fmu_fdi.margin.EXACT_RTOL`): TB01PD's staircase
    keeps such a mode when stable poles cluster next to it (random seed 21: a fault-only z = 1, PBH 6.5e-17,
    beside poles within 5e-3), and the basis then carries it as one state above the least order."""
    from ...margin import EXACT_RTOL, default_smarg, margin_reduced

    red = margin_reduced(G, default_smarg(G.dt), tol=EXACT_RTOL)
    return red if red.n < G.n else G


def pencil_basis(model: FDIModel, *, rtol: float | None = None, atol: float = 0.0, poles=None,
                 sdeg: float | None = None, smarg: float | None = None) -> PencilBasis:
    """Proper stable left null-space basis ``Nl`` of ``[Gu Gd; I 0]`` of ``model`` (acts on ``[y; u]``).

    Parameters
    ----------
    model : FDIModel
    rtol, atol : float, optional
        Rank decisions count singular values above ``max(atol, rtol·||[A B; C D]||_2)``
        (default ``rtol = (n + 1)·1e3·eps``) of the balanced minimal realisation of ``[Gu Gd]``.
    poles, sdeg : optional
        With ``poles`` every eigenvalue of the basis is placed: at the given poles first, the rest at
        ``sdeg`` (default -1, or 0 in discrete time) — the filter's poles are the requested ones where
        its order allows. Without ``poles``, the basis' eigenvalues outside the stability region
        (``Re λ > smarg``, or ``> sdeg`` when given; moduli in discrete time) are moved to their mirror
        image about ``sdeg`` (:func:`mirror`) and the others stay, as with Varga's ``sdeg`` in ``glcf``;
        with neither, the moved ones go to the plant's stabilised eigenvalues (``_basis.pole_chooser``).
    smarg : float, optional
        Stability margin of the basis poles (default just inside the stability boundary).

    Returns
    -------
    PencilBasis
        ``N``: realisation of order ``sum(degrees)`` (the left minimal indices of G, i.e. the
        degrees of a minimal polynomial basis); ``info``: rank tolerance, feedback norms, the
        number of moved poles.
    """
    from ._basis import normal_rank
    from ...margin import margin_limit
    from .postconditions import NumericalDesignError, default_smarg

    p, m, md = model.ny, model.nu, model.nd
    G = model.lti("u", "d")
    if G.n and G.m:
        G = G.minreal()  # a minimal realisation of [Gu Gd] makes the basis minimal (Varga, glnull)
        G = _without_exact_boundary_modes(G)
    if not G.m:
        G = LTI.static(G.D, G.dt)  # no u, no d: the basis is the identity
    if G.n:
        G, _ = G.balanced()
    n = G.n
    A, C = G.A, G.C
    Bu, Bd = G.B[:, :m], G.B[:, m:]
    Du, Dd = G.D[:, :m], G.D[:, m:]
    norm = float(np.linalg.norm(np.block([[A, G.B], [C, G.D]]), 2)) if (n + p) * (n + G.m) else 0.0
    if rtol is None:
        rtol = (n + 1) * 1e3 * EPS
    tol = max(atol, rtol * norm)
    # dual: x' = Aᵀ x + Cᵀ u, output Bdᵀ x + Ddᵀ u must vanish
    P, af, bf, F, K, fnorm = _output_nulling(A.T, C.T, Bd.T, Dd.T, tol)
    k = K.shape[1]
    T, taus = controllable_staircase(af, bf, tol)
    nc = sum(taus)
    T1 = T[:, :nc]
    ac, bc, Fc, Pc = T1.T @ af @ T1, T1.T @ bf, F @ T1, P @ T1
    staircase_zeros(ac, bc, taus)  # exact zeros below the staircase: chain_ordered's staircase on it is O(n² k)
    degrees = conjugate_partition(taus, k)
    choose = _targets(model, poles, sdeg)
    margin = default_smarg(model.dt) if smarg is None else float(smarg)
    # the stability region: at or inside the margin (inclusive, as the peer), at sdeg or better (the targets
    # themselves sit on sdeg; 1e-9 relative lets them count as placed)
    limit = np.inf if sdeg is None else float(sdeg) + 1e-9 * max(1.0, abs(float(sdeg)))
    if model.dt:
        good = lambda re, im: np.hypot(re, im) <= margin_limit(margin) and np.hypot(re, im) <= limit  # noqa: E731
    else:
        good = lambda re, im: re <= margin_limit(margin) and re <= limit  # noqa: E731
    # the dual realisation (ac, bc, Cz, Dz) of Nlᵀ before any pole is moved: the rows' covers start here
    Cz = np.vstack([Fc, -(Bu.T @ Pc + Du.T @ Fc)]) if m else Fc  # Nuᵀ = -(Buᵀ X + Duᵀ N)
    Dz = np.vstack([K, -(Du.T @ K)]) if m else K
    dual = (ac.copy(), bc.copy(), Cz.copy(), Dz.copy())
    full = poles is not None
    # state feedback w = Fw ξ + v on the dual (a right coprime factor), realised in the closed loop's Schur
    # coordinates ξ = Z ζ (schur_feedback: accurate where the gain is large)
    ac, Z, Fw, moved = schur_feedback(ac, bc, model.dt, choose, good, full)
    bc, Cz = Z.T @ bc, Cz @ Z + Dz @ Fw
    if Fw.size:
        fnorm = max(fnorm, float(np.linalg.norm(Fw, 2)))
    N = LTI(ac.T, Cz.T, bc.T, Dz.T, model.dt)
    rank_d = normal_rank(model.lti("d"), rtol=None) if md else 0
    if k != p - rank_d:
        raise NumericalDesignError(
            f"pencil null space: {k} basis rows where p - rank Gd = {p} - {rank_d} = {p - rank_d} are required; "
            f"the rank decisions (tolerance {tol:.3g} = max(atol, rtol·||[A B; C D]||)) disagree with the normal "
            f"rank of Gd — pass other rtol/atol")
    info = {"rank_tol": tol, "feedback_norm": fnorm, "moved_poles": moved, "order": nc,
            "controllable_order": n, "staircase": taus}
    return PencilBasis(N, degrees, rank_d, info, dual, (choose, good, full), tol)


def chain_ordered(a: np.ndarray, b: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Orthogonal ``(T, V, indices)`` putting the controllable pair ``(a, b)`` into a staircase whose
    sub-diagonal blocks are ``[0 R]`` with R upper triangular, and ordering the inputs ``b V`` by
    ascending controllability index.

    In ``Tᵀ a T``, ``Tᵀ b V``, the first ``τ_j - τ_{j+1}`` columns of block j reach no further block (chain
    ends of length j) and column ``τ_j - τ_{j+1} + l`` of block j reaches rows ``≤ l`` of block j+1 only; so
    input column i of ``b V`` starts a chain of length ``indices[i]`` (the conjugate partition of the block
    sizes, ascending) — the ordering in which a Type 1 minimum dynamic cover of column i by the other
    columns has order ``indices[i]`` (Varga 2017, sec. 10.4.2; Van Dooren's upper-triangular staircase).
    """
    n, k = b.shape
    T, taus = controllable_staircase(a, b, tol)
    at, bt = T.T @ a @ T, T.T @ b
    starts = np.cumsum([0] + taus)
    for j in range(len(taus) - 2, -1, -1):  # RQ of A_{j+1,j} = [0 R] Qᵀ, block j rotated by Q, backwards
        rows, cols = slice(starts[j + 1], starts[j + 2]), slice(starts[j], starts[j + 1])
        _, Q = sla.rq(at[rows, cols], mode="full")
        _rotate(Q.T, cols, at, rows=(bt,), cols=(T,))
    V = np.eye(k)
    if taus:
        _, Q = sla.rq(bt[: taus[0]], mode="full")  # b_1 = [0 R] Q: inputs Qᵀ, the k - τ_1 static ones first
        V = Q.T
    return T, V, conjugate_partition(taus, k)


def row_cover(a, b, c, d, i: int, tol: float):
    """Type 1 minimum dynamic cover of input column i of the dual basis by the other columns.

    Finds the least-order ``N_i + N_rest Y(λ)`` (a row of the null space; Varga 2003, "Reliable
    algorithms for computing minimal dynamic covers", as ``grmcover1``): an orthogonal staircase of
    ``(a, [b_i  b_rest])`` that compresses the ``b_i`` part before the ``b_rest`` part at every step; the
    ``b_i``-blocks x1 are then made invariant by a non-orthogonal elimination of the ``b_rest``-block rows
    (column operations with the full-row-rank sub-diagonal ``b_rest``-blocks) and a feedback of
    ``b_rest`` on the first of them. Returns ``(a1, b1, c1, d1, cond)``: the realisation of order
    ``dim x1`` and the largest norm of the non-orthogonal transformations and the feedback (``cond``).
    """
    n, k = b.shape
    a, c = a.copy(), c.copy()
    bb = np.hstack([b[:, [i]], np.delete(b, i, axis=1)])
    dd = np.hstack([d[:, [i]], np.delete(d, i, axis=1)])
    blocks: list[tuple[int, int, bool]] = []  # (start, size, is_b1)
    r0 = 0
    # the current "inputs" of the staircase step: columns of bb (step 0), then of a (the last two blocks)
    src1, src2 = ("b", np.arange(1)), ("b", np.arange(1, k))
    while r0 < n:
        step = []
        for (which, cols), is_b1 in ((src1, True), (src2, False)):
            part = (bb if which == "b" else a)[r0:, cols]
            rho = 0
            if part.size:
                cmp = RowCompression(part)
                rho = _rank(cmp.s, tol)
                if rho:  # rotate rows/cols ≥ r0 only: the source columns (< r0 for a) are not touched
                    cmp.rotate(r0, a, rows=(bb,), cols=(c,))
            step.append((r0, rho, is_b1))
            r0 += rho
        if step[0][1] + step[1][1] == 0:
            break
        blocks += step
        src1 = ("a", np.arange(step[0][0], step[0][0] + step[0][1]))
        src2 = ("a", np.arange(step[1][0], step[1][0] + step[1][1]))
    odd = [blk for blk in blocks if blk[2]]
    even = [blk for blk in blocks if not blk[2]]
    idx = lambda blks: np.concatenate([np.arange(s0, s0 + sz) for s0, sz, _ in blks]) if blks else np.zeros(0, int)  # noqa: E731
    x1 = idx(odd)
    # the coordinates permuted to [x1 (odd blocks) | even blocks | the rest]: every block, and the odd blocks
    # from any l on, is a contiguous slice (views, no gathered copies in the elimination below)
    perm = np.concatenate([x1, idx(even), np.arange(r0, n)])
    a, c, bb = a[np.ix_(perm, perm)], c[:, perm], bb[perm, :]
    n1 = x1.size
    e0 = np.cumsum([n1] + [sz for _, sz, _ in even])  # even block l at e0[l]:e0[l + 1]
    o0 = np.cumsum([0] + [sz for _, sz, _ in odd])  # odd blocks l, l+1, ... at o0[l]:n1
    cond = 1.0
    # eliminate the rows of even block l+1 in the x1 columns of the odd blocks from l+1 on, with even block l
    for l in range(len(even) - 1, 0, -1):
        if even[l][1] == 0:
            continue
        ic1 = slice(o0[min(l, len(odd))], n1)
        ir2, ic2 = slice(e0[l], e0[l + 1]), slice(e0[l - 1], e0[l])
        X = -np.linalg.lstsq(a[ir2, ic2], a[ir2, ic1], rcond=None)[0]
        cond = max(cond, float(np.linalg.norm(X, 2)) if X.size else 0.0)
        for rs in nonzero_spans(a[:, ic2], 0, n1):  # (the rows/columns that are exactly zero add nothing)
            a[rs, ic1] += a[rs, ic2] @ X   # a T with T = I + E (E: X at rows ic2, columns ic1)
        c[:, ic1] += c[:, ic2] @ X
        for cs in nonzero_spans(a[ic1, :].T, 0, n1):
            a[ic2, cs] -= X @ a[ic1, cs]   # T⁻¹ = I - E
        bb[ic2, :] -= X @ bb[ic1, :]
    f2 = np.zeros((k - 1, n1))
    if even and even[0][1] and n1:
        ir = slice(e0[0], e0[1])
        f2 = -np.linalg.lstsq(bb[ir, 1:], a[ir, :n1], rcond=None)[0]
        cond = max(cond, float(np.linalg.norm(f2, 2)))
    a1 = a[:n1, :n1] + bb[:n1, 1:] @ f2
    c1 = c[:, :n1] + dd[:, 1:] @ f2
    return a1, bb[:n1, :1], c1, dd[:, :1], cond


#: a cover whose non-orthogonal transformations exceed this norm is retried with another input direction of
#: the same index (the accuracy lost is about cond·eps: 1e6 keeps ~1e-10 of the 1e-16 working precision)
COVER_COND = 1e6
#: covers beyond this are left out (cond·eps ~ 1e-8: a row must decouple far below dec_tol = 1e-6 pointwise)
COVER_COND_MAX = 1e8


def simple_rows(pb: PencilBasis, dt: float) -> list[tuple[LTI, int, float]]:
    """Each basis row on its own, at its left minimal index: ``[(N_i, ν_i, cond_i)]``, ascending in ν_i.

    A *simple* basis (Varga's ``glnull(simple=true)``): the dual pair is put in chain order
    (:func:`chain_ordered`), each input column i is covered by the others (:func:`row_cover`) — a row
    ``N_i + Y N_rest`` of McMillan degree ``ν_i`` — and its poles outside the stability region are moved
    by single-input state feedback as for the whole basis (:func:`assign_poles`). When the cover's
    transformations exceed ``COVER_COND``, fixed-seed rotations within the inputs of the same index are
    tried and the best conditioned cover kept; one still above ``COVER_COND_MAX`` is left out (two
    intertwined chains of equal length can need transformations of norm 1e13 to separate). A cover
    whose order is
    not the index (a rank decision the cover's staircase made differently), or whose poles cannot be
    moved (an ordered Schur form that fails to converge), is left out.
    """
    a, b, c, d = pb.dual
    choose, good, full = pb.placement
    T, V, idx = chain_ordered(a, b, pb.rank_tol)
    a, b, c, d = T.T @ a @ T, T.T @ b @ V, c @ T, d @ V
    # exact zeros below the staircase (block sizes from the indices): the covers' staircases rotate only what they reach
    staircase_zeros(a, b, [sum(v > j for v in idx) for j in range(max(idx, default=0))])
    out = []
    idx_arr = np.asarray(idx)
    rng = np.random.default_rng(0)
    for i, nu in enumerate(idx):
        group = np.flatnonzero(idx_arr == nu)  # inputs of the same index: any combination of them has index ν
        best = None
        for trial in range(4 if group.size > 1 else 1):
            W = np.eye(len(idx))
            if trial:  # a fixed-seed rotation within the group, when the chain-ordered column covers badly
                Qg, _ = np.linalg.qr(rng.standard_normal((group.size, group.size)))
                W[np.ix_(group, group)] = Qg
            try:
                cov = row_cover(a, b @ W, c, d @ W, i, pb.rank_tol)
            except np.linalg.LinAlgError:
                continue
            if cov[0].shape[0] == nu and (best is None or cov[4] < best[4]):
                best = cov
            if best is not None and best[4] <= COVER_COND:
                break
        if best is None or best[4] > COVER_COND_MAX:
            continue  # no cover of order ν (a rank decision made differently), or too ill-conditioned: left out
        a1, b1, c1, d1, cond = best
        try:
            a1, Z, F, _ = schur_feedback(a1, b1, dt, choose, good, full)
        except (np.linalg.LinAlgError, DesignError):  # an ordered Schur form / placement that fails: row left out
            continue
        b1, c1 = Z.T @ b1, c1 @ Z + d1 @ F
        out.append((LTI(a1.T, c1.T, b1.T, d1.T, dt), nu, max(cond, float(np.linalg.norm(F, 2)) if F.size else 0.0)))
    return out
