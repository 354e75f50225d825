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
25-state pair with one or two inputs would need gains far above the data's norm.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ..errors import DesignError
from ..linalg import EPS
from ..lti import LTI
from ..model import FDIModel


@dataclass
class PencilBasis:
    """A proper left null-space basis ``Nl(λ)`` of ``[Gu Gd; I 0]`` acting on ``[y; u]``."""

    N: LTI
    degrees: list[int]
    rank_d: int
    info: dict = field(default_factory=dict)


def _rank(s: np.ndarray, tol: float) -> int:
    return int(np.sum(s > tol))


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
        U, s, _ = sla.svd(blk, full_matrices=True)
        tau = _rank(s, tol)
        if tau == 0:
            break
        # rotate the remaining coordinates so that the first tau rows carry the block
        Z = np.eye(n)
        Z[start:, start:] = U
        a = Z.T @ a @ Z
        T = T @ Z
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
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            res = place_poles(a, b, np.array(out[: a.shape[0]]), method="YT")
        except ValueError as exc:
            from .postconditions import NumericalDesignError

            raise NumericalDesignError(f"pencil null space: the poles cannot be assigned ({exc}); pass other "
                                       f"poles/sdeg") from None
    return -res.gain_matrix


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


def assign_poles(a: np.ndarray, b: np.ndarray, dt: float, choose, good) -> tuple[np.ndarray, int]:
    """State feedback F for the controllable pair ``(a, b)`` moving every eigenvalue outside the
    region ``good(re, im)`` to the targets ``choose(bad_eigenvalues)``: ``(F, moved)``.

    Schur method (Varga 1981, as in Varga's ``saloc``/``glcf``): an ordered real Schur form puts
    one bad 1×1 or 2×2 block last; a feedback acting on its coordinates alone moves it and leaves
    the other eigenvalues where they are; repeat. Each step solves a 1- or 2-state problem, so
    the gains stay small where a full placement of a high-order, few-input pair would not.
    """
    n = a.shape[0]
    F = np.zeros((b.shape[1], n))
    if n == 0:
        return F, 0
    eig = np.linalg.eigvals(a)
    bad = eig[~np.array([good(z.real, z.imag) for z in eig])]
    if bad.size == 0:
        return F, 0
    targets = list(np.asarray(choose(bad), complex))
    last = targets[-1] if targets else complex(0.5 if dt else -1.0)
    spare = abs(last) if dt else last.real  # a 2×2 block may need one target more than counted
    moved = 0
    for _ in range(n):
        T, Z, kgood = sla.schur(a + b @ F, output="real", sort=good)
        if kgood == n:
            break
        size = 2 if n - kgood >= 2 and abs(T[n - 1, n - 2]) > 0 else 1
        blk, B2 = T[n - size:, n - size:], (Z.T @ b)[n - size:]
        tg = _pop_targets(targets, size, dt, spare)
        if size == 1:
            nb = float(np.sum(B2 ** 2))
            if nb <= 0:
                break  # uncontrollable: cannot happen on the controllable part
            F2 = (tg[0].real - blk[0, 0]) * B2.T / nb  # minimum-norm gain: blk + B2 F2 = target
        else:
            F2 = _place(blk, B2, tg)
        F = F + F2 @ Z[:, n - size:].T
        moved += size
    return F, moved


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
    """``bad eigenvalues ↦ targets``: the plant's stabilised eigenvalues spread from slow to fast
    (``_basis.pole_chooser``) with neither poles nor sdeg; else the given poles first and the
    rest mirrored about ``sdeg`` (default -1, or 0.5 in discrete time)."""
    from ._basis import pole_chooser

    if poles is None and sdeg is None:
        chooser = pole_chooser(model, None, None)
        return lambda bad: chooser(bad.size)
    beta = float(sdeg) if sdeg is not None else (0.5 if model.dt else -1.0)
    given_all = np.zeros(0, complex) if poles is None else np.atleast_1d(np.asarray(poles, complex))

    def choose(bad):
        given = given_all[: bad.size]
        if given.size and abs(given[-1].imag) > 0 and (given.size < 2 or given[-2] != np.conj(given[-1])):
            given = given[:-1]  # do not split a pair
        if given.size < given_all.size:
            warnings.warn(f"poles {given_all[given.size:].tolist()} not used: the pencil basis has only {bad.size} "
                          f"eigenvalues outside the stability region to move", UserWarning, stacklevel=6)
        return np.concatenate([given, mirror(bad, beta, bool(model.dt))])[: max(bad.size, given.size)]

    return choose


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
        The basis' eigenvalues outside the stability region (``Re λ < smarg``, and ``< sdeg`` when
        given; moduli in discrete time) are moved to ``poles`` first, then to their mirror image
        about ``sdeg`` (default -1, or 0.5 in discrete time; :func:`mirror`); the others stay, as
        with Varga's ``sdeg`` in ``glcf``. With neither, the moved ones go to the plant's
        stabilised eigenvalues (``_basis.pole_chooser``).
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
    from .postconditions import NumericalDesignError, default_smarg

    p, m, md = model.ny, model.nu, model.nd
    G = model.lti("u", "d")
    if G.n and G.m:
        G = G.minreal()  # a minimal realisation of [Gu Gd] makes the basis minimal (Varga, glnull)
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
    degrees = conjugate_partition(taus, k)
    choose = _targets(model, poles, sdeg)
    margin = default_smarg(model.dt) if smarg is None else float(smarg)
    # the stability region: strictly inside the margin, and at sdeg or better (the targets
    # themselves sit on sdeg; 1e-9 relative lets them count as placed)
    limit = np.inf if sdeg is None else float(sdeg) + 1e-9 * max(1.0, abs(float(sdeg)))
    if model.dt:
        good = lambda re, im: np.hypot(re, im) < margin and np.hypot(re, im) <= limit  # noqa: E731
    else:
        good = lambda re, im: re < margin and re <= limit  # noqa: E731
    Fw, moved = assign_poles(ac, bc, model.dt, choose, good)
    if Fw.size:
        ac, Fc = ac + bc @ Fw, Fc + K @ Fw
        fnorm = max(fnorm, float(np.linalg.norm(Fw, 2)))
    Cu = -(Bu.T @ Pc + Du.T @ Fc)  # Nuᵀ = -(Buᵀ X + Duᵀ N)
    Dl = np.hstack([K.T, -(Du.T @ K).T]) if m else K.T
    Bl = np.hstack([Fc.T, Cu.T]) if m else Fc.T
    N = LTI(ac.T, Bl, bc.T, Dl, model.dt)
    rank_d = normal_rank(model.lti("d"), rtol=None) if md else 0
    if k != p - rank_d:
        raise NumericalDesignError(
            f"pencil null space: {k} basis rows where p - rank Gd = {p} - {rank_d} = {p - rank_d} are required; "
            f"the rank decisions (tolerance {tol:.3g} = max(atol, rtol·||[A B; C D]||)) disagree with the normal "
            f"rank of Gd — pass other rtol/atol")
    info = {"rank_tol": tol, "feedback_norm": fnorm, "moved_poles": moved, "order": nc,
            "controllable_order": n, "staircase": taus}
    return PencilBasis(N, degrees, rank_d, info)
