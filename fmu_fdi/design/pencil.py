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
factor ``M⁻¹``): eigenvalues that break the stability margin are moved by a Schur
method that leaves the others in place (Varga 1981), or all are placed when the caller
gives ``poles``/``sdeg``.
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


def _bad(eig: np.ndarray, dt: float, margin: float) -> np.ndarray:
    return np.abs(eig) >= margin if dt else eig.real >= margin


def _place(a: np.ndarray, b: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Gain F with ``eig(a + b F) = targets`` (scipy's robust KNV/YT method); targets of a
    multiplicity above rank b are spread by a relative 1e-3 so the method applies."""
    from scipy.signal import place_poles

    targets = np.asarray(targets, complex)
    if a.shape[0] == 0:
        return np.zeros((b.shape[1], 0))
    rb = np.linalg.matrix_rank(b)
    t = targets.copy()
    for i in range(t.size):  # spread repeats (conjugate pairs move together)
        same = np.nonzero(np.abs(t[:i] - t[i]) <= 1e-9 * max(1.0, abs(t[i])))[0]
        if same.size >= rb:
            t[i] = t[i] * (1 + 1e-3 * (same.size - rb + 1)) if t[i] != 0 else 1e-3 * (same.size - rb + 1)
    # conjugate closure after spreading: rebuild pairs from the upper half-plane members
    out = [z for z in t if abs(z.imag) <= 1e-12 * max(1.0, abs(z))]
    for z in t:
        if z.imag > 1e-12 * max(1.0, abs(z)):
            out += [z, np.conj(z)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = place_poles(a, b, np.array(out[: a.shape[0]]), method="YT")
    return -res.gain_matrix


def assign_poles(a: np.ndarray, b: np.ndarray, dt: float, choose, margin: float, all_poles: bool):
    """State feedback F for the controllable pair ``(a, b)``: ``(F, moved)``.

    ``all_poles``: every eigenvalue goes to ``choose(n)``. Otherwise only the eigenvalues
    that break the margin (``Re λ ≥ margin`` or ``|λ| ≥ margin``) move, to ``choose(k)``:
    an ordered real Schur form puts them in a trailing block, and a feedback acting on
    that block's coordinates alone leaves the others where they are.
    """
    n = a.shape[0]
    if n == 0:
        return np.zeros((b.shape[1], 0)), 0
    if all_poles:
        return _place(a, b, choose(n)), n
    sort = (lambda re, im: np.hypot(re, im) < margin) if dt else (lambda re, im: re < margin)
    T, Z, kgood = sla.schur(a, output="real", sort=sort)
    nb = n - kgood
    if nb == 0:
        return np.zeros((b.shape[1], n)), 0
    B2 = (Z.T @ b)[kgood:]
    F2 = _place(T[kgood:, kgood:], B2, choose(nb))
    return F2 @ Z[:, kgood:].T, nb


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
        Poles for the whole basis (conjugate-closed; missing ones at ``sdeg``); with neither,
        only eigenvalues that break ``smarg`` are moved, to the plant's stabilised eigenvalues.
    smarg : float, optional
        Stability margin of the basis poles (default just inside the stability boundary).

    Returns
    -------
    PencilBasis
        ``N``: realisation of order ``sum(degrees)`` (the left minimal indices of G, i.e. the
        degrees of a minimal polynomial basis); ``info``: rank tolerance, feedback norms, the
        number of moved poles.
    """
    from ._basis import normal_rank, pole_chooser
    from .postconditions import NumericalDesignError, default_smarg

    p, m, md = model.ny, model.nu, model.nd
    G = model.lti("u", "d")
    if G.n and G.m:
        G = G.minreal()
    if G.n and G.m:
        G, _ = G.balanced()
    n = G.n
    A, C = G.A, G.C
    Bu, Bd = G.B[:, :m], G.B[:, m:]
    Du, Dd = G.D[:, :m], G.D[:, m:]
    norm = float(np.linalg.norm(np.block([[A, G.B], [C, G.D]]), 2)) if (n or G.D.size) else 0.0
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
    choose = pole_chooser(model, poles, sdeg)
    margin = default_smarg(model.dt) if smarg is None else float(smarg)
    Fw, moved = assign_poles(ac, bc, model.dt, choose, margin, poles is not None or sdeg is not None)
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
