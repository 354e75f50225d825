"""The one judge of a residual generator: its normalised internal form (issue 13, issue 17).

A residual generator ``Q`` acting on ``[y; u]`` has the internal form

    R(λ) = Q(λ) Ge(λ),   Ge = [Gu Gd Gw Gf; I 0 0 0],   R = [Ru Rd Rw Rf],

the transfer from every plant input to the residual the user sees. Every figure below is a
peak over one frequency grid Λ per residual row group — the group's own, so a row reads the same alone and in a
bank (:func:`_figures_by_group`) — (:func:`_eval_points`: log-spaced two decades beyond every
pole scale of the plant and the row's filter, plus 0, the resonances of lightly damped poles, two gaps
beside every pole on the stability boundary (:func:`_beside_boundary_freqs`) and, discrete, Nyquist; without points below
1e-9 of its top (capped at 1e-2 of the slowest pole scale that is no rounding of s = 0 / z = 1), within 1e-9, relative, of a pole of either realisation, or within
``BOUNDARY_GAP·||A||`` of one on the stability boundary: :func:`_beside_boundary_poles`, or of a stable plant pole
within that gap of the boundary that the row cancels to rounding: :func:`_beside_cancelled`) of values computed
point by point, ``R(λ) = Q(λ) Ge(λ)`` from balanced realisations (no general minimal realisation or
rank decision; one exception: a plant mode on the stability boundary that a row cancels, or an input column does
not excite, to the rounding of its eigen-direction — or a stable one within the gap of the boundary, so that a pole
reads the same on both sides of the margin — is removed from that row and column, and the value kept there is
the most accurate of three readings with derived error bounds, clipped to their enclosure and never above R_i itself,
:func:`_without_cancelled_modes`). :func:`internal_figures`
computes them once; ``leakage()``,
``structure_matrix()`` (:mod:`fmu_fdi.analysis`) and :func:`check_generator` all read them,
so ``gen.info['postconditions']`` is what ``leakage(gen)`` and ``structure_matrix(gen)``
report for the returned object.

:func:`check_generator` first *normalises* every residual row group i (Varga 2017, sec. 5.2,
the scaling of ``efdsyn``/``efdisyn``: unit minimum fault gain; the H∞− index of the row)

    R_i ← R_i / min_{j: S_ij = 1} max_{λ ∈ Λ} ||R_fj,i(λ)||_2,

i.e. the gain used is the grid estimate of ``||R_fj,i||∞`` (peak over Λ of the block's
2-norm), and the returned ``Q`` carries the scaling. It then requires, on the normalised form:

- decoupling, *absolute*: ``max_λ ||R_X,i(λ)|| ≤ dec_tol`` for X = u, d (and w when w is
  decoupled) and for every fault with ``S_ij = 0`` (``structure``). Every block a row decouples (u, d, a decoupled
  w, an excluded fault) whose plain reading is not far below its fault gains is read on the filter as stored, the
  product ``(λI − A_q)^{-1}(B_q Ge)`` first, with solves refined in extended precision and a derived error bound e
  per block (:func:`_decoupled_blocks`, :func:`_decoupled_reading`: the same reading whatever the row's scale and
  diagonal state scaling, where the plain values of Q then Q·Ge read 1.2e-7 … 4.3e-7 of a filter that leaks
  2.0e-8, and an excluded fault leaking 9e-10 at 1.18e-7 or 7.5e-8 depending on the state scaling); the verdict is
  the reading's (``decoupling_error`` / ``structure_leak_error``, e, is reported beside it: a worst-case bound,
  above a true leak of 2.5e-6 on a non-normal plant, so not subtracted; ``decoupling_sensitivity`` /
  ``structure_leak_sensitivity``: what rounding of the realisation's entries may move it, e.g. a double-precision
  evaluation of an ill-conditioned realisation). Absolute on the normalised
  row means: the residual moves with u at most ``dec_tol`` times as much as with the weakest
  required fault (the relative-to-``|Q||Ge|`` measure of issue 13 passed filters whose
  residual moved with u 2.5e-3 times as much as with a fault);
- stability of every block of R with the margin ``smarg`` (inclusive, as the peer toolbox:
  ``Re p ≤ smarg`` continuous, ``|p| ≤ smarg`` discrete): the eigenvalues of Q's realisation
  (the filter that runs) and the poles of R (:func:`_r_poles`): a simple plant mode on or beyond the stability
  boundary, or (``R_w``, ``R_f``) one that breaks a user ``smarg`` anywhere (:func:`user_margin_decisions`), is a
  pole of ``R_i``'s column c unless its residue is within its derived rounding bound —
  ``||Q_i(p) c_p|| ≤ δ_i`` or ``|y_pᴴ b_c| ≤ δ_c``, the grid's own decision (:func:`mode_decisions`) — and
  the other margin-violating modes (Q's, and plant modes the table cannot decide: repeated, clustered) are those
  of the series realisation ``Q·Ge`` that are both controllable and observable;
- a required fault is no rounding noise in its row: the cosine
  ``γ_j = max_λ ||R_fj(λ)|| / (||Q_y(λ)|| ||Gf_j(λ)||) ≥ FDtol`` (scale free, over the points
  where the bound is at least 1e-6 of its median, away from zeros of ``Gf_j``), and the row
  is not numerically zero (``max_λ ||Q_i(λ)|| ||Ge(λ)|| > ZERO_TOL`` = 1e-13 before scaling, a
  positive finite weakest fault gain, a positive finite peak gain after it);
- strong visibility at ``freqs``: ``||R_fj,i(jω)|| ≥ FDGainTol`` on the normalised row
  (Varga's ``fdisspec`` with its absolute ``FDGainTol`` applied to the unit-gain row).

A failure raises :class:`~fmu_fdi.errors.DesignError` (:class:`NumericalDesignError` for the
numerical ones) naming the condition, the numbers and the option that may help. Reference:
A. Varga, *Solving Fault Diagnosis Problems*, Springer 2017, sec. 5.1-5.2 (the conditions of
the EFDP/EFDIP and the unit-gain normalisation), and FaultDetectionTools.jl ``efdsyn``.
"""
from __future__ import annotations

import warnings
from collections import OrderedDict
from types import SimpleNamespace

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...freqresp import content_key, recall, remember, transfer_values
from ...linalg import EPS, single_blas_thread
from ...lti import (LTI, RationalPoints, _pole_scales, dd_add, dd_refined_solves, frequency_grid,
                   stack_times_dd, structurally_observed)
from ...margin import R_POLE_TOL, _reachable, default_smarg, margin_reduced, near_poles, outside_margin  # noqa: F401
from .plant_modes import BOUNDARY_GAP, EIGVEC_BOUND, boundary_gap, leading_schur  # noqa: F401  (BOUNDARY_GAP: here)
from .plant_modes import boundary_mode_table as _boundary_modes
from .plant_modes import merged_tables as _merged_tables
from .plant_modes import user_margin_table as _user_margin_table


class NumericalDesignError(DesignError):
    """A design broke a numerical post-condition (decoupling, basis rank, stability of the
    realisation): other rank tolerances may succeed where the problem itself is solvable."""


#: default decoupling tolerance, absolute on the normalised internal form (unit weakest fault
#: gain). Measured on the published cases of tests/ with this judge (nullspace_design, and
#: structured_bank over every achievable row): Ex. 5.3/5.4 ~1e-15, Xiong-Saif, Yuan 1e-13 …
#: 1e-11, Niemann 2e-10, Boeing 747 detector 1.5e-9 and its rows up to 8.1e-8 (the order-3
#: row [1 1 0 0 0]), the aircraft loop's 20-row bank 1.9e-8: a residual that moves with u at
#: most ~1e-7 as much as with its weakest fault. The broken designs leak 1.3e-6 (the sampled
#: row of random seed 18, checked independently), 1e-6 … 3e-3 (the 16 filters of issue 17),
#: 0.17 (a Boeing 747 row of the polynomial basis). 1e-7 sits between the two, closer to the
#: exact side (Boeing's order-3 row has a factor 1.2 of headroom).
DEC_TOL = 1e-7



#: :func:`check_generator`: a row group whose normalising scale is within this of 1 is left as it is — normalised
#: already, to the rounding of reading its weakest fault gain again (≤ 4.8e-13 measured on re-judged bank members;
#: 1e-10 leaves a factor 200); a figure relative to that gain moves by at most this fraction
NORMALISED_RTOL = 1e-10


#: a row whose every output ``max_λ ||Q_i(λ)|| ||Ge(λ)||`` stays below this is a zero filter
#: (the 2.9e-16 static "filter" of issue 17): the rounding of a unit-scale basis row
#: (~500 eps); it is refused, not normalised into a gain-1e13 amplifier of rounding noise.
ZERO_TOL = 1e-13


def _resonances(poles: np.ndarray, dt: float) -> np.ndarray:
    """Frequencies where a lightly damped pole peaks: ``ω = |Im s|`` and ``ω ± |Re s|/2`` for the
    continuous-time equivalent ``s`` of each complex pole (``s = log(z)/dt``), whose peak a
    log-spaced grid (10 % steps) misses when ``|Re s| ≪ ω``."""
    if not poles.size:
        return np.zeros(0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.log(poles.astype(complex)) / dt if dt else poles.astype(complex)
    s = s[np.isfinite(s) & (np.abs(s.imag) > 0)]
    w, sig = np.abs(s.imag), np.abs(s.real)
    out = np.concatenate([w, w + sig / 2, np.where(w > sig, w - sig / 2, w)])
    return out[np.isfinite(out) & (out > 0)] if not dt else out[(out > 0) & (out <= np.pi / dt)]


def _eval_points(model, Q: LTI, freqs=None, beside=None) -> tuple[np.ndarray, np.ndarray]:
    """``(ω, λ)``: the judge's grid (module docstring). ``beside``: ``[(poles, gap)]`` of stable plant modes within
    the gap of the boundary (:func:`.plant_modes.beside_boundary`), whose two-gaps-beside points are added too
    (:func:`_internal_figures` removes the points within the gap of those a row cancels)."""
    extra = [] if freqs is None else [np.atleast_1d(np.asarray(freqs, float))]
    extra.append(_resonances(np.concatenate([model.lti().poles(), Q.poles()]), model.dt))
    extra.append(_beside_boundary_freqs([model.lti(), Q], model.dt))
    if beside:
        extra.append(_two_gaps_beside(beside, model.dt))
    omega = frequency_grid([model.lti(), Q] if Q.n else [model.lti()], num=120, extra=np.concatenate(extra))
    omega = omega[np.isfinite(omega)]
    # no points below 1e-9 of the top (1e-7 of the largest pole scale): a pole at 1e-17 (an
    # integrator after rounding) would put points at 1e-19, where the realisation's 1e-16 junk
    # is the response and the product Q·Ge (~1/ω) is rounding noise of size eps/ω
    top = float(np.max(omega, initial=0.0))
    floor = 1e-9 * max(1.0, top)
    # ... but never above 1e-2 of the slowest pole scale that is no rounding of s = 0 / z = 1 (scale > 1e3·eps·
    # max scale, discrete 1e3·eps/dt): a filter pole at 1.4e7 (approximate matching's order-3 row of random
    # seed 32) put the floor at 1.4 rad/s, above every plant pole (0.16 … 2.2), and the judge read the u leak
    # 8e-8 where numpy reads its peak 1.5e-7 (0.94 rad/s)
    scales = _pole_scales(np.concatenate([model.lti().poles(), Q.poles()]), model.dt)
    thr = 1e3 * EPS * (1.0 / model.dt if model.dt else float(np.max(scales, initial=0.0)))
    scales = scales[np.isfinite(scales) & (scales > thr)]
    if scales.size:
        floor = min(floor, 1e-2 * float(np.min(scales)))
    omega = omega[(omega == 0) | (omega >= floor)]
    lam = np.exp(1j * omega * model.dt) if model.dt else 1j * omega
    # a point within 1e-9 (relative) of a pole is that pole: ω = 0 next to an integrator that
    # rounding put at -9e-17 would read the realisation's junk as the response there
    poles = np.concatenate([model.lti().poles(), Q.poles()])
    if poles.size:
        near = np.min(np.abs(lam[:, None] - poles[None, :]), axis=1) <= 1e-9 * max(1.0, float(np.max(np.abs(poles))))
        near |= _beside_boundary_poles(lam, [model.lti(), Q], model.dt)
        omega, lam = omega[~near], lam[~near]
    return omega, lam


def _beside_boundary_poles(lam: np.ndarray, systems, dt: float) -> np.ndarray:
    """Mask of the points ``lam`` within :data:`BOUNDARY_GAP` ``· max(1, ||A_bal||)`` of a pole of one of
    ``systems`` that lies outside the default margin (an integrator computed at ±1e-17, an undamped pair
    1e-24 off the axis, z = 1, an unstable pole).

    At a distance δ from such a pole ``p`` the plant's values are ``~|res|/δ`` and carry the rounding
    ``eps·||A||/δ`` relative (the condition of ``λI − A``). A decoupling row cancels p by its zero, exactly
    only up to rounding: its residue ρ (1e-15 … 1e-14 of the weakest fault gain on the random set) reads as a
    leak ``ρ/δ``, plus evaluation rounding of the same kind. On a grid reaching δ = 1e-9 rad/s (the 1e-9·top
    floor next to an integrator computed at 1e-17) that is 1e-7 … 1e-6: random seeds 10 and 26 were refused
    for it, and the value seed 10 read depended on the solver (a dense LU solve passed, the Schur-form solve
    of larger models failed). At δ ≥ 1e-6·||A|| such a residue reads ≤ 1e-8, while a cancellation off by
    1e-12 of the fault gain still reads ≥ 2.5e-7 > dec_tol two gaps beside it, where the grid has points
    (:func:`_beside_boundary_freqs`; tests/test_synthesis_random.py); a residue above its rounding bound δ_i is
    refused as a pole of R (:func:`_r_poles`) whatever the grid.
    """
    mask = np.zeros(lam.size, bool)
    for p, gap in boundary_poles(systems, dt):
        mask |= np.min(np.abs(lam[:, None] - p[None, :]), axis=1) <= gap
    return mask


def boundary_poles(systems, dt: float) -> list:
    """``(poles outside the default margin, BOUNDARY_GAP·max(1, ||A_bal||))`` of each of ``systems`` that has any."""
    out = []
    for S in systems:
        if not S.n:
            continue
        p = S.poles()
        p = p[outside_margin(p, dt, default_smarg(dt))]
        if p.size:
            bal = S.balanced()[0] if S.m and S.p else S
            out.append((p, boundary_gap(bal.A)))
    return out


def _beside_boundary_freqs(systems, dt: float) -> np.ndarray:
    """Frequencies two gaps beside every pole on the stability boundary (``ω0 ± 2·gap``, discrete ``(θ0 ± 2·gap)/dt``;
    :func:`_beside_boundary_poles`): the judge reads every boundary mode a row keeps at the same distance, so a
    residue ρ of a mode the row does not cancel to rounding (:func:`_without_cancelled_modes`) reads ``ρ/(2·gap)``
    at s = 0 and z = 1 as at an undamped pair or e^{jθ}, whose neighbourhood a log-spaced grid (10 % steps) never
    reaches (ε = 1e-11 at ±2j read 7.8e-11 and passed)."""
    return _two_gaps_beside(boundary_poles(systems, dt), dt)


def _two_gaps_beside(pairs, dt: float) -> np.ndarray:
    """:func:`_beside_boundary_freqs` of ``[(poles, gap)]``: ``ω0 ± 2·gap`` of those within the gap of the boundary."""
    out = []
    for p, gap in pairs:
        if dt:
            on = p[np.abs(np.abs(p) - 1.0) <= gap]
            w0, off = np.abs(np.angle(on)) / dt, 2.0 * gap / dt
        else:
            on = p[np.abs(p.real) <= gap]
            w0, off = np.abs(on.imag), 2.0 * gap
        out.append(np.concatenate([w0 - off, w0 + off]))
    w = np.concatenate(out) if out else np.zeros(0)
    return w[(w > 0) & (w <= np.pi / dt)] if dt else w[w > 0]


def _values(sys: LTI, lam: np.ndarray) -> np.ndarray:
    """Values at the points ``lam`` from a balanced realisation (non-finite where λ is a pole);
    one Schur form of its A serves every point and every later call (:mod:`fmu_fdi.freqresp`)."""
    if sys.n:
        bal, _ = sys.balanced()
        sys = bal
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return transfer_values(sys.A, sys.B, sys.C, sys.D, lam)


def row_system(Q: LTI, g) -> LTI:
    """Row group ``g`` of Q on the states it sees (:func:`...lti.structurally_observed`: its C's nonzero columns,
    closed under A's coupling): inside a stacked bank, that row's own member filter."""
    if not Q.n:
        return LTI(Q.A, Q.B, Q.C[g, :], Q.D[g, :], Q.dt)
    st = structurally_observed(Q.A, Q.C[g, :])
    return LTI(Q.A[np.ix_(st, st)], Q.B[st, :], Q.C[np.ix_(g, st)], Q.D[g, :], Q.dt)


def _values_by_row(Q: LTI, groups, lam: np.ndarray) -> np.ndarray:
    """Q's values at ``lam`` with each row group read from its own states (:func:`row_system`). A bank stacks
    members that share poles (the plant's, the placed ones); one Schur form of the stack mixes their states
    within each cluster, so a row would read the rounding of a member 1e3 times its gain (random seed 33's
    15-row bank: row [1 0 1 0] read ``|Q_i(1) c| = 5.5e-8`` stacked, 1.4e-13 alone)."""
    subs = [(g, row_system(Q, g)) for g in groups] if Q.n else []
    covered = sorted(i for g, sub in subs if sub.n < Q.n for i in np.atleast_1d(np.arange(Q.p)[g]))
    if not Q.n or covered != list(range(Q.p)):  # some row reads the whole realisation
        out = _values(Q, lam)
    else:  # every row group has its own states: the stacked bank need not be evaluated as well
        out = np.empty((lam.size, Q.p, Q.m), complex)
    for g, sub in subs:
        if sub.n < Q.n:
            out[:, g, :] = _values(sub, lam)
    return out


def _sep(A: np.ndarray, B: np.ndarray) -> float:
    """``sep(A, B) = σ_min`` of the Sylvester operator ``X ↦ A X − X B`` (its Kronecker matrix ``I ⊗ A − Bᵀ ⊗ I``;
    Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., sec. 16.1); ∞ for an empty operator."""
    if not A.shape[0] or not B.shape[0]:
        return np.inf
    M = np.kron(np.eye(B.shape[0]), A) - np.kron(B.T, np.eye(A.shape[0]))
    return float(np.linalg.svd(M, compute_uv=False)[-1])


def _sylvester(A: np.ndarray, B: np.ndarray, C: np.ndarray, gamma: float) -> tuple[np.ndarray, float]:
    """``X`` solving ``A X − X B = C`` (Bartels–Stewart, scipy) and a bound on ``||X − X̂||_F``.

    Higham (2nd ed., sec. 16.2–16.3): the computed ``X̂`` has a small residual, not a small backward error, and the
    forward error is bounded by the residual over the separation, ``||X − X̂||_F ≤ ||C − (A X̂ − X̂ B)||_F / sep(A, B)``
    (eq. (16.15) with the computed residual in place of its a-priori bound). The residual is evaluated here, in
    floating point: its own rounding, ``≤ γ (||A||_F ||X̂||_F + ||X̂||_F ||B||_F + ||C||_F)`` (γ = N·eps, the
    judge's p(N)), is added to it. ``sep`` is computed (:func:`_sep`), not estimated: the operators are small (the
    removed modes times a row's filter, or times the rest of the plant)."""
    if not A.shape[0] or not B.shape[0]:
        return np.zeros((A.shape[0], B.shape[0]), complex), 0.0
    X = sla.solve_sylvester(A, -B, C)
    nf = np.linalg.norm
    res = float(nf(C - (A @ X - X @ B)))
    return X, (res + gamma * (float(nf(A)) * float(nf(X)) + float(nf(X)) * float(nf(B)) + float(nf(C)))) / _sep(A, B)


def _row_cancels(modes: dict, Qi: LTI, qpk: float, N: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per mode of ``modes``: does the row ``Q_i`` cancel it to the rounding of the design, ``||Q_i(p) c_p|| ≤ δ_i``
    (:func:`_without_cancelled_modes`)? And δ_i (∞ where undecidable) and the residue ``||Q_i(p) c_p||`` (∞ where Q_i
    is not finite at p). ``qpk``: the row's peak gain on the grid; N: the order of plant and row."""
    Qv_p = _values(Qi, modes["poles"])
    out = np.zeros(len(modes["poles"]), bool)
    delta = np.full(len(out), np.inf)
    residue = np.full(len(out), np.inf)
    if not np.all(np.isfinite(Qv_p)):
        return out, delta, residue
    for k in range(len(out)):
        residue[k] = float(np.linalg.norm(Qv_p[k] @ modes["dirs"][k]))
        if N * EPS * modes["nA"] > modes["seps"][k] / 5:
            continue  # the perturbation bound does not hold: nothing is decidable
        kappa, slope = _row_sensitivity(Qi, modes["poles"][k], modes["dirs"][k])
        tol = N * EPS * (EIGVEC_BOUND * modes["nA"] / modes["seps"][k] * float(np.linalg.norm(Qv_p[k], 2)) * modes["nC"]
                         + modes["nA"] * modes["conds"][k] * slope
                         + qpk * float(np.linalg.norm(modes["dirs"][k])) + kappa)
        delta[k] = tol
        out[k] = residue[k] <= tol
    return out, delta, residue


def _row_sensitivity(S: LTI, p: complex, c: np.ndarray) -> tuple[float, float]:
    """``(κ, ||S'(p) c||)`` for the row's residue ``S(p) c`` at a plant mode p (:func:`_row_cancels`).

    ``κ = || (|D| + |C||X| + |Y||B| + |Y||A||X|) |c| ||``, ``X = (pI − A)⁻¹ B``, ``Y = C (pI − A)⁻¹``: the
    componentwise condition of ``S(p) c`` in S's data as stored. Relative perturbations ``|δA| ≤ ε|A|`` (and of B,
    C, D) move ``S(p) c`` by at most ``ε κ`` to first order (``δS = δD + δC X + Y δB + Y δA X``; Higham, *Accuracy
    and Stability of Numerical Algorithms*, 2nd ed., sec. 7.2, componentwise perturbation), so ``N·eps·κ`` is both
    the residue floating-point data of this realisation can reach and the error of evaluating it (a backward-stable
    solve). Invariant under the diagonal scalings of balancing. A row of Q whose zero cancels p through terms
    larger than its gain carries it: the noise-pencil row of ``Gf = 1/s, Gw = 1/(s² + 4)`` (order 3, gain ~3.6)
    computes ``Q(0) = D − C A⁻¹ B`` from terms of size 15, exact value of its floating-point data 1.17e-14
    (rational arithmetic), where the peak-gain term alone gave δ_i = 4.9e-15.

    ``S'(p) c = −Y X c``: the slope of the residue along λ, which turns the distance of the row's zero from p into a
    residue (:func:`_without_cancelled_modes`, the eigenvalue term of δ_i). ``(∞, ∞)`` where S is not finite at p."""
    c = np.asarray(c)
    if not S.n:
        return float(np.linalg.norm(np.abs(S.D) @ np.abs(c))), 0.0
    with np.errstate(all="ignore"):
        XY = resolvent_pair(S, np.array([p]))
        if XY is None:
            return np.inf, np.inf
        X, Y = XY[0][0], XY[1][0]
        M = np.abs(S.D) + np.abs(S.C) @ np.abs(X) + np.abs(Y) @ np.abs(S.B) + np.abs(Y) @ np.abs(S.A) @ np.abs(X)
        k, d = float(np.linalg.norm(M @ np.abs(c))), float(np.linalg.norm(Y @ (X @ c)))
    return (k, d) if np.isfinite(k) and np.isfinite(d) else (np.inf, np.inf)


def resolvent_pair(S: LTI, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(X, Y)`` per point λ of ``lam``: ``X = (λI − A)⁻¹ B`` and ``Y = C (λI − A)⁻¹`` of S's realisation as stored
    (shapes (points, n, m) and (points, p, n); LAPACK's GEPP, one LU per point and system), the two solves of every
    componentwise bound on ``S(λ) = C X + D`` (:func:`_row_sensitivity`, the perturbation of S's data;
    :func:`..problems.approximate_matching._evaluation_rounding`, GEPP's rounding). None where ``λI − A`` is
    exactly singular at some point."""
    L = lam[:, None, None] * np.eye(S.n) - S.A
    try:
        X = np.linalg.solve(L, np.broadcast_to(S.B, (lam.size,) + S.B.shape))
        Y = np.linalg.solve(L.transpose(0, 2, 1), np.broadcast_to(S.C.T, (lam.size,) + S.C.T.shape)).transpose(0, 2, 1)
    except np.linalg.LinAlgError:
        return None
    return X, Y


def mode_decisions(model, Q: LTI, groups, qpeaks, beside: bool = False, modes=False) -> dict | None:
    """The one decision on the plant's boundary modes (:func:`_boundary_modes`) per row group and input column of
    Ge, read by the grid (:func:`_without_cancelled_modes`) and by the poles of R (:func:`_r_poles`) alike: mode p
    is removed from ``R_i``'s column c where the row cancels it (``||Q_i(p) c_p|| ≤ δ_i``, :func:`_row_cancels`) or
    the column does not excite it (``|y_pᴴ b_c| ≤ δ_c``), or the column has no coupling to the states at all;
    everywhere else it is a pole of ``R_i``'s column c. ``qpeaks``: each group's peak gain ``max_λ ||Q_i(λ)||`` on
    the grid. Returns None without boundary modes, else ``modes`` (the table), ``residue``, ``delta_i``
    (modes × groups) and ``removed`` (modes × groups × columns). ``beside``: the judge's table, with the stable modes
    within the gap of the boundary (:func:`.plant_modes.boundary_mode_table`); ``modes``: that table if already
    computed (None: there is none)."""
    if modes is False:
        modes = _boundary_modes(model, beside=beside)
    if modes is None:
        return None
    P, m = len(modes["poles"]), modes["B"].shape[1]
    out = {"modes": modes, "residue": np.full((P, len(groups)), np.inf), "delta_i": np.full((P, len(groups)), np.inf),
           "removed": np.zeros((P, len(groups), m), bool)}
    for i, g in enumerate(groups):
        Qi = row_system(Q, g)  # the row's own filter: a bank's other members add nothing but their rounding
        cancels, out["delta_i"][:, i], out["residue"][:, i] = _row_cancels(modes, Qi, float(qpeaks[i]), model.n + Qi.n)
        out["removed"][:, i, :] = (cancels[:, None] | modes["unexcited"]) | ~modes["coupled"][None, :]
    return out


def user_margin_decisions(model, Q: LTI, groups, qpeaks, smarg: float, decisions: dict | None) -> dict | None:
    """``decisions`` (:func:`mode_decisions` on the judge's table, the grid's) with the plant modes a user margin
    ``smarg`` tighter than the default adds (:func:`.plant_modes.user_margin_table`: stable modes breaking it beyond
    the grid's gap) decided by the same rule, for the poles of R (:func:`_r_poles`) — so that a mode the user's margin
    forbids is a pole of R exactly where its residue exceeds its derived rounding (``||Q_i(p) c_p|| > δ_i`` and
    ``|y_pᴴ b_c| > δ_c``), whatever its distance to the boundary. The decision is per mode, so the merged table's
    entries for the judge's own modes are the grid's, unchanged. ``decisions`` itself (the same object) where the
    margin adds no mode: every design with the default margin. ``groups``, ``qpeaks``: as the grid's decisions
    (the judged row groups and their peak gains on the grid)."""
    extra = _user_margin_table(model, smarg)  # (None without states or with a margin no tighter than the default)
    if extra is None:
        return decisions
    more = mode_decisions(model, Q, groups, qpeaks, modes=extra)
    if decisions is None:
        return more
    return {"modes": _merged_tables(decisions["modes"], extra),
            **{k: np.concatenate([decisions[k], more[k]], axis=0) for k in ("residue", "delta_i", "removed")}}


def _without_cancelled_modes(model, Q: LTI, groups, lam: np.ndarray, R: np.ndarray, Qv: np.ndarray,
                             Ge: np.ndarray, decisions: dict | None = None) -> list:
    """``R = Q·Ge`` at the points ``lam`` with, in each row group i and input column c, the plant's boundary modes
    that Q_i cancels or that column c does not excite, to the rounding of the design and the data, removed: the
    values of the minimal realisation of ``R_i``, as the peer toolbox (FaultDetectionTools.jl) reduces with
    ``gminreal`` before it evaluates. ``Qv``, ``Ge``: Q and Ge at ``lam`` (R = Qv·Ge).

    **Which modes.** A simple pole ``p`` of the balanced ``Ge = (A, B, Ce, De)`` on or beyond the stability
    boundary (those the grid keeps ``BOUNDARY_GAP`` from) with unit eigenvector ``v_p`` is unobservable in ``R_i``
    iff ``Q_i(p) c_p = 0``, ``c_p = Ce v_p``. A design computed in floating point with backward-stable steps
    (balancing, orthogonal staircases, Schur forms, Sylvester equations) on a realisation of order
    ``N = n + n_q,i`` (the plant and the row's own filter) is the exact design of data perturbed by
    ``||E|| ≤ N·eps·||A||`` (the usual ``p(N) = N`` of Householder-based algorithms; Higham, *Accuracy and
    Stability of Numerical Algorithms*, 2nd ed., ch. 19), so it places its zero on an eigen-direction of
    ``A + E``. That direction differs from ``v_p`` by ``||δv|| ≤ 4||E||/sep_p`` (:data:`EIGVEC_BOUND`;
    ``sep_p = σ_min(T22 − p I)``, the separation of p from the rest of the ordered Schur form ``[p t; 0 T22]``,
    which is the distance to the nearest other eigenvalue when A is normal and smaller when it is not); its
    eigenvalue, where the row puts its zero, differs from p by ``|δp| ≤ cond_p ||E||`` (``cond_p = 1/|y_pᴴ v_p|
    = ||[1 z]||``, the eigenvalue's condition; Golub & Van Loan, 4th ed., sec. 7.2.2), which the row's slope
    ``||Q_i'(p) c_p||`` turns into a residue (two balancings of random seed 3's plant put z = e^0.1 at
    1.1051709180756502 and …464, 3.8e-15 apart against cond_p·N·eps·||A|| = 6.5e-15; the factoriser now places its
    zeros at the judge's own eigenvalues, :mod:`.plant_modes`). And the row's value ``Q_i(p)``
    carries its own rounding ``N·eps·max_λ ||Q_i(λ)||`` and that of its realisation's data, ``N·eps·κ_i(p)``
    (:func:`_row_sensitivity`: the componentwise condition of ``Q_i(p) c_p``, large when the zero is a cancellation
    of terms larger than the gain). So the zero of a row is decidable only to

        δ_i = N·eps·( 4·||A||/sep_p · ||Q_i(p)|| ||Ce||  +  ||A||·cond_p·||Q_i'(p) c_p||
                      +  max_λ ||Q_i(λ)|| · ||c_p||  +  κ_i(p) ),

    and a mode with ``||Q_i(p) c_p|| ≤ δ_i`` is removed from row i: it is unobservable in ``R_i`` as far as the
    data can tell. Scale-free: a row scaling, a time scaling ``A → αA`` and the state scaling balancing undoes
    change both sides alike. Where the bound is void (``N·eps·||A|| > sep_p/5``: a repeated or clustered pole)
    nothing is removed. Measured (issue 17): the rows of random seed 33's 15-row bank that decouple fc (mode
    z = 1, 3.9e-3 from the plant pole 0.9961, n = 18, rows of order 8 … 17) cancel it to 3e-5 … 0.11 δ_i
    (``|Q_i(1) c| / (||Q_i(1)|| ||c||)`` = 1e-16 … 3e-12); the leaks ε = 1e-13 and 1e-12 of
    tests/test_synthesis_random.py are 11 and 113 δ_i and stay (ε ≤ 1e-15 is removed, 1e-14 sits at 0.5 … 1.3
    δ_i at s = 0, ±2j, z = ±1, e^{±0.5j}). The dual test on the columns (a mode the column does not excite to
    the rounding of its left eigen-direction, ``δ_c``) is :func:`_boundary_modes`'.

    **Three readings of R_i' and their errors.** With the ordered Schur form ``A = U T Uᴴ``, the removed modes
    first (``T11``, ``T12``, ``T22``; ``C1 = Ce U1``, ``C2 = Ce U2``, ``[B1; B2] = Uᴴ B``) and ``Z`` solving
    ``T11 Z − Z T22 = T12`` (the block-diagonalising ``[I Z; 0 I]``),

        Ge = C1 (λI − T11)⁻¹ B̃1 + Ge'(λ),   B̃1 = B1 + Z B2,   Ge' = (C2 − C1 Z)(λI − T22)⁻¹ B2 + De,

    and with Y solving ``A_q Y − Y T11 = −B_q C1`` (the row's balanced filter ``(A_q, B_q, C_q, D_q)``),
    ``Q_i C1 (λI − T11)⁻¹ = K (λI − T11)⁻¹ − Φ(λ) Y``, ``K = D_q C1 + C_q Y``, ``Φ = C_q (λI − A_q)⁻¹``. The pole
    part of ``R_i`` at the removed modes is ``K W``, ``W = (λI − T11)⁻¹ B̃1`` (one mode: ``K = Q_i(p) c_p``, the
    residue tested), and R_i' is read three ways, each with a bound e on its distance to R_i', per point and
    column (2-norm over the group's rows; γ = N·eps):

    - R_i itself: ``e = ||(λI − T11)⁻¹|| min(||K|| + d_K, k_ρ)(||B̃1_c|| + d_B)`` — the pole part it still holds,
      with ``k_ρ = ||V⁻¹|| (Σ_k (ρ_k + δ_i,k)²)^½`` a second bound on the true ``||K||`` from the residues ρ_k the
      removal test read (:func:`_pole_part_gain`; it does not pass through Y: approximate-matching seed 32's
      stiff simple-basis row, e_K = 309 against ρ = 1.4e-11, read R_i's bound as 3.9e3 and kept the mode-free
      reading, 1.2e-4 … 3.1e-4 off the exact rational R(0), where R_i is ≤ 2.8e-7 off it);
    - ``R_i − K W``: ``e = ||(λI − T11)⁻¹|| (d_K' (||B̃1_c|| + d_B) + ||K|| d_B)`` — R_i's pole part, as its own
      evaluation forms it, is known only to the rounding of the row's zero and of the column's coupling, so
      ``d_K = max(e_K, δ_i)`` and ``d_B = e_B̃1 + δ_c ||[1 z]||`` (the removal tests' bounds; random seed 73: the
      subtracted reading read 1.1e-6 beside z = 1 with e_K, e_B̃1 alone ~1e-15, the mode-free one 1.4e-9);
      ``d_K' = min(d_K, ||K|| + k_ρ)``;
    - the mode-free realisation ``Q_i Ge' − Φ Y B̃1`` (no pole at p is formed):
      ``e = γ(||Q_i|| ||Ge'_c|| + ||Φ|| ||Y|| ||B̃1_c||) + ||Q_i|| e_Ge' + ||Φ|| (e_Y ||B̃1_c|| + ||Y|| e_B̃1)``,

    with the Sylvester solutions' forward errors ``e_Y``, ``e_Z`` (:func:`_sylvester`: residual over sep; ``Y ~
    1/sep(A_q, T11)`` and ``Z ~ ||T12||/sep(T11, T22)``, which a non-normal plant makes large), ``e_K = ||C_q|| e_Y +
    γ(||D_q|| ||C1|| + ||C_q|| ||Y||)``, ``e_B̃1 = e_Z ||B2_c|| + γ(||B1_c|| + ||Z|| ||B2_c||)`` and ``e_Ge' =
    ||C1|| e_Z ||X2_c|| + γ((||C2|| + ||C1|| ||Z||) ||X2_c|| + ||De_c||)``, ``X2 = (λI − T22)⁻¹ B2`` (the terms
    that cancel in each sum round to γ times their sizes). Not in e: the rounding every value of the judge
    carries, that of the Schur forms and solves of the realisation itself (R_i's own, accepted everywhere else).

    **The value kept** at a point and column. Every reading r with its bound e encloses R_i':
    ``L = max_r (||r|| − e) ≤ ||R_i'|| ≤ U = min_r (||r|| + e)``. The value kept is the most accurate reading (the
    smallest e), clipped into ``[L, U]`` and never above R_i itself (the reading scaled to that size):

    - the smallest-e reading, not a bound: where every reading's e exceeds its size the enclosure does not decide
      the value, and an undecided value may neither certify decoupling nor erase a fault gain. The previous rule
      (the largest lower bound, 0 there) did both: Boeing 747's row [0 0 0 0 1] candidate (filter peak 5.2e5,
      cancelling the pole 3.1e-5 only to δ_i = 2.3e-5: bounds 0.27 beside it) was returned with ``decoupling`` 0
      and a u leak numpy reads at 5.5e-7; random seed 149's row [1 1 0 0 1] read its fault fc, R_u and R_d as 0
      and was refused as numerically zero (numpy: fc 3.2e-2); the non-normal plant of tests/test_synthesis_random.py
      read the true leak of a floating-point "exact" row, 4.7e-9 … 4.7e-6 (q·C formed exactly), as 2e-16 … 0;
    - raised to L: a reading proven larger than the most accurate one says is at least that large (a leak
      beside p that the mode-free reading shows and R_i's pole part hides);
    - lowered to U and never above R_i as it runs: the removal discounts the pole part of a mode the row cancels
      to rounding; it may not *add* a leak to the residual the user sees. VTOL's DOS bank at 0.01 s (its two
      poles at z ≈ 1, δ_i = 5.6 against a residue ||K|| = 0.08: "cancelled" only because δ_i is void) read its
      mode-free R_u at 21 ± 2e-8 where R_i, what the FMU computes, reads 8e-12: R_i − R_i' is that pole part,
      not rounding.

    Where the mode-free reading carries ``Y ~ 1/sep`` and cancellation (VTOL: u leak 3.9e-7 by it, 6.6e-12 by
    R_i) its bound is large and R_i, whose bound is the small pole part, is the most accurate.

    Returns the removals: ``[(p, mask)]``, mask (groups × input columns of Ge) marking where p was removed from the
    values; R is changed in place. ``decisions``: :func:`mode_decisions` on the same groups (computed here when not
    given), the decision :func:`_r_poles` reads too.
    """
    removed: list = []
    if not lam.size:
        return removed
    if decisions is None:
        decisions = mode_decisions(model, Q, groups, [float(np.max(_nrm(Qv[:, g, :]))) for g in groups])
    if decisions is None:
        return removed
    modes = decisions["modes"]
    A, Bp, Ce, De = modes["A"], modes["B"], modes["Ce"], modes["De"]
    poles = modes["poles"]
    masks = np.zeros((len(poles), len(groups), Bp.shape[1]), bool)
    nrm = lambda X: np.linalg.norm(X, axis=-2)  # noqa: E731  (K, r, c) -> (K, c): 2-norm over the rows
    for i, g in enumerate(groups):
        Qi = row_system(Q, g)  # the row's own filter: a bank's other members add nothing but their rounding
        N = model.n + Qi.n
        gam = N * EPS
        Qg = Qv[:, g, :]
        qn = _nrm(Qg)
        delta_i = decisions["delta_i"][:, i]
        rem = decisions["removed"][:, i, :] & modes["coupled"][None, :]  # (modes, columns)
        masks[:, i, :] = rem | ~modes["coupled"][None, :]  # a column without coupling to the states has no pole
        Qb = Qi.balanced()[0] if Qi.n else Qi
        schur_q = None
        # the columns that lose the same modes are read together
        for pattern in {tuple(r) for r in rem.T if any(r)}:
            cols = np.flatnonzero(np.all(rem.T == np.array(pattern), axis=1))
            keep = poles[np.array(pattern)]
            sel = lambda x: bool(np.min(np.abs(keep - x)) <= 1e-8 * max(1.0, abs(x)))  # noqa: E731
            T, U, kk = leading_schur(A, sel)
            if kk != keep.size:
                masks[np.ix_(np.flatnonzero(pattern), [i], cols)] = False  # not removed: R_i keeps its values
                continue
            T11, T12, T22 = T[:kk, :kk], T[:kk, kk:], T[kk:, kk:]
            Bt = U.conj().T @ Bp[:, cols]
            C1, C2 = Ce @ U[:, :kk], Ce @ U[:, kk:]
            Zs, eZ = _sylvester(T11, T22, T12, gam)
            B1t = Bt[:kk] + Zs @ Bt[kk:]
            nB2 = np.linalg.norm(Bt[kk:], axis=0)
            eB1 = eZ * nB2 + gam * (np.linalg.norm(Bt[:kk], axis=0) + float(np.linalg.norm(Zs, 2)) * nB2)
            X2 = shifted_triangular_solve(T22, lam, Bt[kk:])
            Gf = (C2 - C1 @ Zs) @ X2 + De[:, cols]                                # Ge' at the points
            nX2 = nrm(X2)
            eG = float(np.linalg.norm(C1, 2)) * eZ * nX2 + gam * (
                (float(np.linalg.norm(C2, 2)) + float(np.linalg.norm(C1, 2)) * float(np.linalg.norm(Zs, 2))) * nX2
                + np.linalg.norm(De[:, cols], axis=0)[None, :])
            Inv11 = shifted_triangular_solve(T11, lam, np.eye(kk))
            W = Inv11 @ B1t                                                        # (K, kk, cols)
            nInv11 = np.linalg.norm(Inv11, 2, axis=(1, 2))
            if Qb.n:
                Y, eY = _sylvester(Qb.A.astype(complex), T11, -(Qb.B @ C1), gam)
                K = Qb.D @ C1 + Qb.C @ Y                                           # Q_i(p) c_p for one mode
                eK = float(np.linalg.norm(Qb.C, 2)) * eY + gam * (float(np.linalg.norm(Qb.D, 2)) * float(np.linalg.norm(C1, 2))
                                                                  + float(np.linalg.norm(Qb.C, 2)) * float(np.linalg.norm(Y, 2)))
                if schur_q is None:  # the row's filter in Schur form once for all its patterns: A_q = U_q T_q U_qᴴ
                    schur_q = sla.schur(Qb.A.astype(complex), output="complex")
                Tq, Uq = schur_q
                # Φ U_q = C_q U_q (λI − T_q)⁻¹ at every point (the unitary U_q keeps every 2-norm)
                Phi = shifted_triangular_solve(Tq, lam, Qb.C @ Uq, left=True)     # (K, rows, n_q)
                nPhi, nY = np.linalg.norm(Phi, 2, axis=(1, 2)), float(np.linalg.norm(Y, 2))
                free = Qg @ Gf - Phi @ (Uq.conj().T @ (Y @ B1t))
                e_free = (gam * (qn[:, None] * nrm(Gf) + nPhi[:, None] * nY * np.linalg.norm(B1t, axis=0)[None, :])
                          + qn[:, None] * eG + nPhi[:, None] * (eY * np.linalg.norm(B1t, axis=0)[None, :] + nY * eB1[None, :]))
            else:
                K = Qb.D @ C1
                eK = gam * float(np.linalg.norm(Qb.D, 2)) * float(np.linalg.norm(C1, 2))
                free = Qg @ Gf                                                     # a static row: Q_i Ge' exactly
                e_free = gam * qn[:, None] * nrm(Gf) + qn[:, None] * eG
            raw = R[:, g][:, :, cols]
            sub = raw - K @ W
            # the pole part K W as R_i holds it is known to the rounding of the row's zero and of the column's
            # coupling (δ_i, δ_c of the removal tests), not only to that of K and B̃1 computed here
            pat = np.array(pattern)
            dK = max(eK, float(np.linalg.norm(np.where(np.isfinite(delta_i[pat]), delta_i[pat], 0.0))))
            dB = eB1 + np.linalg.norm(modes["delta_c"][pat][:, cols], axis=0)
            nK, nB1 = float(np.linalg.norm(K, 2)), np.linalg.norm(B1t, axis=0)
            # ||K|| of the data as stored, also from the removal test's own residues (docstring, "Three readings")
            kres = _pole_part_gain(T11, decisions["residue"][pat, i], delta_i[pat])
            kb, dKs = min(nK + dK, kres), min(dK, nK + kres)
            readings = np.stack([raw, sub, free])                                  # (3, K, rows, cols)
            errs = np.stack([nInv11[:, None] * kb * (nB1 + dB)[None, :],
                             nInv11[:, None] * (dKs * (nB1 + dB) + nK * dB)[None, :], e_free])
            if not (np.all(np.isfinite(readings)) and np.all(np.isfinite(errs))):
                masks[np.ix_(np.flatnonzero(pattern), [i], cols)] = False
                continue
            size = np.linalg.norm(readings, axis=2)                                 # (3, K, cols)
            # the most accurate reading (smallest e) clipped to the enclosure [L, U] of all readings and never
            # above R_i as it runs: an undecided value (every reading dominated by its e) stays what the most
            # accurate reading says, not 0 (docstring, "The value kept")
            low = np.max(np.maximum(size - errs, 0.0), axis=0)                     # (K, cols)
            best = np.argmin(errs, axis=0)                                         # (K, cols)
            zero = (np.take_along_axis(size, best[None], axis=0)[0] == 0) & (low > 0)
            best[zero] = np.argmax(size - errs, axis=0)[zero]                      # a zero cannot carry the bound
            pick = np.take_along_axis(readings, best[None, :, None, :], axis=0)[0]
            psize = np.take_along_axis(size, best[None], axis=0)[0]
            high = np.min(size + errs, axis=0)                                     # R_i' ≤ every ||r|| + e
            kept = np.minimum(np.maximum(low, np.minimum(psize, high)), size[0])  # never above R_i as it runs
            factor = np.divide(kept, psize, out=np.ones_like(psize), where=psize > 0)
            vals = R[:, g, :]
            vals[:, :, cols] = pick * factor[:, None, :]
            R[:, g, :] = vals
    for k, p in enumerate(poles):
        if np.any(masks[k] & modes["coupled"][None, :]):
            removed.append((p, masks[k]))
    return removed


def _pole_part_gain(T11: np.ndarray, residue: np.ndarray, delta: np.ndarray) -> float:
    """A bound on ``||K||``, ``K = Q_i C1`` on the removed modes' invariant subspace (:func:`_without_cancelled_modes`:
    the pole part of ``R_i`` is ``K (λI − T11)⁻¹ B̃1``), from the residues the removal test evaluated directly.

    With ``T11 V = V diag(p_k)`` (V: unit eigenvectors of the triangular T11, so ``U1 V_k = v_k``, the unit eigenvector
    of A, and ``C1 V_k = c_k``), ``K V_k = Q_i(p_k) c_k`` exactly, hence ``K = [Q_i(p_k) c_k] V⁻¹`` and

        ||K||₂ ≤ ||V⁻¹||₂ · ( Σ_k (ρ_k + δ_i,k)² )^½,

    ρ_k = ``||Q_i(p_k) c_k||`` as :func:`_row_cancels` read it and δ_i,k its derived rounding bound (the true residue of
    the stored data is within ρ_k + δ_i,k to first order). ∞ where a residue or bound is not finite. This bound does
    not pass through the Sylvester solution Y of K's evaluation ``D_q C1 + C_q Y``, whose forward error bound
    ``||C_q|| e_Y`` is void on a stiff realisation of the row: approximate-matching seed 32's simple-basis filter
    (poles −1.4e7 … −2.2e-4) has ``e_K`` = 309 where its residue at the plant pair 0.3 ± 0.78j is 1.4e-11 ± 1.3e-8
    (50-digit evaluation of the stored data: 2.1e-11)."""
    rho = np.asarray(residue, float) + np.asarray(delta, float)
    if not rho.size or not np.all(np.isfinite(rho)):
        return np.inf
    V = np.linalg.eig(T11)[1]
    smin = float(np.linalg.svd(V, compute_uv=False)[-1])
    return float(np.linalg.norm(rho)) / smin if smin > 0 else np.inf


def shifted_triangular_solve(T: np.ndarray, lam: np.ndarray, B: np.ndarray, left: bool = False) -> np.ndarray:
    """``X_k = (λ_k I − T)⁻¹ B`` (``left``: ``B (λ_k I − T)⁻¹``) for an upper triangular T (a Schur form) at all the
    points ``lam`` at once: shape (K, n, c) (left: (K, r, n)); non-finite where ``λ_k`` is a diagonal entry of T.

    One back substitution (left: forward substitution on ``(λI − T)ᵀ``) carried over every point and column
    together, O(n² K c) with n steps in Python: after the one Schur form (O(n³)) each point costs O(n²) per column,
    where a dense LU solve per point costs O(n³) (and ``n`` columns more for an inverse). Componentwise backward
    stable at each point: the computed X_k solves ``(λ_k I − T + ΔT_k) X_k = B`` with ``|ΔT_k| ≤ γ_n |λ_k I − T|``
    (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Thm 8.5); the Schur form adds its own
    normwise backward error O(n·eps·||A||), that of every Schur-based frequency response (Laub 1981)."""
    T = np.asarray(T, complex)
    n = T.shape[0]
    K = lam.size
    if left:
        B = np.asarray(B).T
        L = T.T                                                    # (λI − T)ᵀ Xᵀ = Bᵀ, lower triangular
    Bk = np.broadcast_to(np.asarray(B, complex), (K,) + np.shape(B)[-2:]).transpose(1, 0, 2)  # (n, K, c)
    X = np.empty(Bk.shape, complex)
    d = lam[None, :] - np.diag(T)[:, None]                         # (n, K): the diagonal of λI − T
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for j in (range(n) if left else range(n - 1, -1, -1)):
            rest = (np.tensordot(L[j, :j], X[:j], axes=(0, 0)) if left
                    else np.tensordot(T[j, j + 1:], X[j + 1:], axes=(0, 0)))
            X[j] = (Bk[j] + rest) / d[j][:, None]
    X = X.transpose(1, 0, 2)                                       # (K, n, c)
    return X.transpose(0, 2, 1) if left else X


def _nrm(X: np.ndarray) -> np.ndarray:
    """2-norms of a stack of matrices (K, p, m) -> (K,)."""
    if X.shape[1] == 0 or X.shape[2] == 0:
        return np.zeros(X.shape[0])
    return np.linalg.norm(X, ord=2, axis=(1, 2))


def _cosine(resp: np.ndarray, bound: np.ndarray, floor: float = 1e-6) -> float:
    """``max_λ ||R_f(λ)|| / (||Q_y(λ)|| ||Gf(λ)||)`` over the points where the bound is at least
    ``floor`` times its median over the grid: pointwise, so an integrator's huge low-frequency
    gain does not hide a fault seen elsewhere; transmission zeros of Gf (bound → 0, a 0/0) are
    left out. (The median, not the peak: a pole of Gf at ~1e-17 from the axis puts grid points
    at ω ~ 1e-19 where ||Gf|| ~ 1e19, and a peak reference would leave only those.)"""
    if not bound.size:
        return 0.0
    ref = float(np.median(bound))
    top = float(np.max(bound))
    if top <= 0:
        return 0.0
    keep = bound >= floor * (ref if ref > 0 else top)
    return float(np.max(resp[keep] / bound[keep]))


def _freq_values(model, Q: LTI, freqs) -> tuple[np.ndarray, np.ndarray]:
    """``(Ge, Q)`` values at the frequencies ``freqs`` (rad/s). At a pole of the plant on the
    axis (an integrator at ω = 0), where ``Q Ge`` is ∞·0, the limit along the axis is taken
    at ``ω + 1e-7·max(1, |ω|)`` (error O(1e-7) of a unit-gain row, rounding ~eps/1e-7)."""
    omega = np.atleast_1d(np.asarray(freqs, float))
    pts = lambda w: np.exp(1j * w * model.dt) if model.dt else 1j * w  # noqa: E731
    Ge, Qv = _values(model.augmented(), pts(omega)), _values(Q, pts(omega))
    bad = ~(np.all(np.isfinite(Ge), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2)))
    # on a pole computed 1e-16…1e-24 off the axis Ge (or Q) is finite but huge, and Q·Ge is rounding
    # there (a zero of Q at the pole gives exactly 0): within 1e-9 (relative) of a pole the limit is taken
    poles = np.concatenate([np.linalg.eigvals(model.A) if model.n else np.zeros(0, complex), Q.poles()])
    bad |= near_poles(pts(omega), poles)
    if np.any(bad):
        w2 = omega[bad] + 1e-7 * np.maximum(1.0, np.abs(omega[bad]))
        Ge[bad], Qv[bad] = _values(model.augmented(), pts(w2)), _values(Q, pts(w2))
    return Ge, Qv


def _r_poles(model, Q: LTI, smarg: float, decisions: dict | None = None) -> tuple[np.ndarray, list]:
    """Poles of ``R = Q Ge`` outside the margin that are plant modes (Q's own are judged on Q), and for those the
    judge decided by their residue, why: ``(poles, reasons)``.

    The blocks ``R_w``, ``R_f`` are judged against ``smarg`` (they are the internal form the design
    factorises, :func:`.stable_factor.internal_form_realisation`). The decoupled blocks ``R_u``, ``R_d``
    are judged by their leakage (≤ ``dec_tol``) and, for their poles, only against the stability
    boundary itself (:func:`default_smarg`, or ``smarg`` if looser): a stable plant mode slower
    than ``smarg`` that only u or d excite decays with a coupling below ``dec_tol`` (CS2: a static
    row decoupling u and d exactly was refused for the plant's pair at -0.0023 ± 0.052j with
    smarg = -0.05, and a higher-order row returned), while an unstable or marginal one would make
    even a rounding-size coupling diverge or drift.

    **Unstable and marginal plant modes are decided as the grid decides them** (``decisions``,
    :func:`mode_decisions`): a simple plant mode p on or beyond the stability boundary is removed from row i and
    column c only where its residue is within its derived rounding bound — ``||Q_i(p) c_p|| ≤ δ_i`` or
    ``|y_pᴴ b_c| ≤ δ_c`` — and is a pole of R wherever it is not, whatever a rank decision with a fixed tolerance
    says. The staircase of :func:`margin_reduced` (tolerance :data:`R_POLE_TOL` on the part's data over the norms of
    the whole balanced series realisation) missed couplings far above rounding when Q is large: approximate-matching
    seed 32's order-3 row (a filter pole at -1.4e7, ||A|| = 1.4e7, ||C|| = 350) kept the plant's pair 0.3 ± 0.78j in
    R_u with ``||Q(p) c_p|| = 8.4e-9`` against δ_i = 2.6e-14 — an R_u that diverges — and the staircase read its
    output coupling 2.5e-9 as 7e-12 of ||C||: a row whose u-leak stayed under dec_tol would have passed
    (tests/test_synthesis_judge.py, a row with ``||Q(p) c_p|| = 1e-9``, 1e6 δ_i). And conversely (random seed 111:
    z = 1.105 coupled to u, d and fa1 at 1e-15 of ||b_c|| against δ_c = 2e-12; tests/test_synthesis_matching_order.py's
    unstable seed 23: s = 0.688 cancelled by a static row to 5.6e-17, δ_i = 1.7e-15) a mode cancelled to rounding
    is no pole, as the grid reads those rows without it. The same holds for every simple stable plant mode that
    breaks a user ``smarg`` in R_w, R_f (``decisions`` of :func:`user_margin_decisions`): nothing in δ_i or δ_c
    depends on where p lies, only on ``sep_p``, ``cond_p``, ``||A||`` and the row, so one rule decides a mode
    at s = −1e-2, −1e-4 and −1e-6 alike (tests/test_judge_beside_smarg.py: a fault coupled at 1e-10 of its column,
    numpy's residue 1.9e-11 of the weakest fault's peak, was no pole by the staircase beyond the grid's gap and a
    pole inside it). The staircase still decides Q's own poles and a plant mode the table cannot decide (repeated,
    clustered or with a void bound: δ_i = ∞ for some row).
    """
    Ge = model.augmented()
    if not Ge.n or not np.any(outside_margin(Ge.poles(), model.dt, smarg)):
        return np.zeros(0, complex), []
    sl = model.group_slices()
    names = _column_names(model)
    found, reasons = [], []
    for cols, margin in ((np.arange(sl["w"].start, sl["f"].stop), smarg),
                         (np.arange(sl["u"].start, sl["d"].stop), max(smarg, default_smarg(model.dt)))):
        if not (cols.size and np.any(outside_margin(Ge.poles(), model.dt, margin))):
            continue
        kept = margin_reduced(Q @ Ge[:, cols], margin, parts=True)[1]
        if decisions is not None:
            modes = decisions["modes"]
            for k, p in enumerate(modes["poles"]):
                if not outside_margin(np.array([p]), model.dt, margin)[0]:
                    continue
                rem = decisions["removed"][k][:, cols]
                if not np.all(np.isfinite(decisions["delta_i"][k])) and not np.all(rem):
                    continue  # a row cannot decide its zero: the staircase's decision stands
                kept = kept[np.abs(kept - p) > 1e-6 * max(1.0, abs(p))]
                if np.all(rem):
                    continue
                kept = np.append(kept, p)
                i, j = (int(x[0]) for x in np.nonzero(~rem))
                c = int(cols[j])
                reasons.append(f"{_mode_kind(p, model.dt)} plant mode {_fmt(np.array([p]))} "
                               f"in R_{_group_of(sl, c)} of residual {i + 1}: residue ||Q_{i + 1}(p) c_p|| = "
                               f"{decisions['residue'][k, i]:.3g} > δ_i = {decisions['delta_i'][k, i]:.3g} (its rounding "
                               f"bound) and input '{names[c]}' excites it (|y_pᴴ b| = {modes['coupling'][k][c]:.3g} > "
                               f"δ_c = {modes['coupling_tol'][k][c]:.3g})")
        found.append(kept)
    return (np.concatenate(found) if found else np.zeros(0, complex)), reasons


def _mode_kind(p: complex, dt: float) -> str:
    """'unstable' (:func:`_beyond`), 'marginal' (outside the default margin) or 'slow' (a stable mode that breaks a
    user ``smarg``: within the gap of the boundary, :func:`.plant_modes.beside_boundary`, or beyond it,
    :func:`.plant_modes.user_margin_table`)."""
    if _beyond(p, dt):
        return "unstable"
    return "marginal" if outside_margin(np.array([p]), dt, default_smarg(dt))[0] else "slow"


def _beyond(p: complex, dt: float) -> bool:
    """Is p strictly beyond the stability boundary (|z| > 1 or Re s > 0, by more than the default margin)?"""
    return bool(outside_margin(np.array([p]), dt, 1.0 + np.sqrt(EPS) if dt else np.sqrt(EPS))[0])


def _group_of(sl: dict, c: int) -> str:
    """The input group ('u', 'd', 'w', 'f') of Ge's column c."""
    return next(g for g in ("u", "d", "w", "f") if sl[g].start <= c < sl[g].stop)


def _column_names(model) -> list:
    """Names of Ge's input columns: u, d, w, then each fault's name on its columns."""
    fault = [""] * model.nf
    for f in model.faults:
        for j in np.atleast_1d(np.arange(model.nf)[f.columns]):
            fault[int(j)] = f.name
    return list(model.u_names) + list(model.d_names) + list(model.w_names) + fault


#: unit roundoff of the extended type the u/d reading refines its residuals in (:func:`_decoupled_reading`): 2^-64 where
#: numpy's longdouble is the x87 80-bit format, EPS/2 where it is double (the reading is then the plain one)
EXT_UNIT = float(np.finfo(np.longdouble).eps) / 2
#: whether the refined reading is formed in double-double (:func:`_dd_refined_values`) instead of longdouble: where
#: longdouble is double (Windows, ARM macOS)
DD_READING = EXT_UNIT >= EPS / 2
#: the unit the refined reading's bound is charged at (``u_x`` of :func:`_decoupled_reading`): :data:`EXT_UNIT` where
#: longdouble is extended; 2^-64 (x87's) in double-double, an upper bound on its residual's unit derived in
#: :func:`_dd_refined_values`, so the same points are refined and proven as on x86
REFINED_UNIT = 2.0 ** -64 if DD_READING else EXT_UNIT


def _refined_solves(A: np.ndarray, lam: np.ndarray, rhs: np.ndarray, left: np.ndarray, refine=None, steps: int = 2,
                    with_left: bool = False):
    """Per point λ_k: ``X_k = (λ_k I − A)^{-1} rhs_k`` (rhs: (K, n, c) in the extended type) and ``W_k = left·(λ_k I −
    A)^{-1}``, in double; at the points of the mask ``refine`` (default none) X_k refined in the extended type and W_k
    not computed unless ``with_left`` (then from the same LU, bit for bit the plain pass's W_k). Non-finite where
    ``λ_k I − A`` is singular. (Where longdouble is double the judge refines in double-double instead:
    :func:`_dd_refined_values`.)

    Each point: the LU factorisation with partial pivoting of ``λI − H`` (``A = U H Uᵀ``, the Hessenberg form of
    :func:`fmu_fdi.freqresp.hessenberg_form`, O(n²) per point); refined: ``steps`` steps of iterative refinement whose
    residual ``rhs − (λI − A) X`` is formed with the stored A in the extended type (Higham, *Accuracy and Stability
    of Numerical Algorithms*, 2nd ed., ch. 12: refinement with any solver whose error contracts, ``u·||A||·||(λI −
    A)^{-1}|| ≪ 1``, converges to the solution of the stored system to the residual's precision)."""
    from ...freqresp import hessenberg_form

    K, n, c = rhs.shape
    X = np.full((K, n, c), np.nan, np.clongdouble if refine is not None else complex)
    W = np.full((K, left.shape[0], n), np.nan, complex)
    H, U = hessenberg_form(A)
    Ax = A.astype(np.longdouble)
    low, up = min(1, n - 1), n - 1
    i, j = np.triu_indices(n, -low)
    band = np.zeros((2 * low + up + 1, n), complex, order="F")
    band[low + up + i - j, j] = -np.asarray(H, float)[i, j]
    gbtrf, gbtrs = sla.get_lapack_funcs(("gbtrf", "gbtrs"), (band,))
    Ut, leftT = U.T, np.asarray(left, complex).T
    pts = range(K) if refine is None else np.flatnonzero(refine)
    for k in pts:
        lk = complex(lam[k])
        ab = band.copy(order="F")
        ab[low + up] += lk
        lu, piv, info = gbtrf(ab, low, up)
        if info != 0:
            continue

        def solve(r, trans=0):
            return U @ gbtrs(lu, low, up, np.asarray(Ut @ r, complex), piv, trans=trans)[0]

        b = rhs[k]
        x = solve(b.astype(complex))
        if refine is None or with_left:
            W[k] = solve(leftT, trans=1).T
        if refine is None:
            X[k] = x
            continue
        x = x.astype(np.clongdouble)
        for _ in range(steps):  # (A real: its products with the real and imaginary parts, no complex copy of A;
            # np.dot, whose longdouble loop is ~10x numpy's generic matmul loop for that type: 0.04 ms against 0.36 ms
            # for an order-87 filter's five columns)
            Ar = np.dot(Ax, np.concatenate([x.real, x.imag], axis=1))
            Axx = Ar[:, :c] + 1j * Ar[:, c:]
            x = x + solve((b - (np.clongdouble(lk) * x - Axx)).astype(complex))
        X[k] = x
    return X, W


#: :func:`_decoupled_blocks`: a reading of a decoupled block below this fraction of the row's weakest fault gain
#: (normalised: 1e-3 of the default dec_tol) decides nothing and is not re-read
UD_REREAD = 1e-3 * DEC_TOL
#: :func:`_decoupled_blocks`: fault gains below this fraction of the row's ``max ||Q_i|| ||Ge||`` are rounding, not a
#: fault the row can be normalised on (a required fault there fails the visibility test, FDtol ≥ 1e-10 here)
UD_FAULT_FLOOR = 1e-10
#: :func:`_decoupled_blocks`: a w or fault block whose plain reading is above this fraction of the row's strongest
#: fault gain is no block the row decouples (a required fault, a noise the design does not decouple, or a leak far
#: above every decision: 1e3·dec_tol of the strongest fault, where the plain reading's error is ~1e-7 of the weakest
#: on the ill-scaled filters of the random sets) and is read plainly
REREAD_CEIL = 1e3 * DEC_TOL


def _decoupled_blocks(Ri: np.ndarray, Qi: np.ndarray, Ge: np.ndarray, sl: dict, fcols: list) -> dict:
    """The blocks of row group i the judge may decide to be zero and whose plain reading could decide it — the
    columns :func:`_decoupled_reading` re-reads: ``{label: columns of Ge}``, labels 'u', 'd', 'w' and fault indices j.

    The reading cannot know the structure or which groups a caller decouples (``leakage()`` and ``structure_matrix()``
    read the same figures without them), so it decides from the values, scale free (a row scaling changes nothing):

    - u and d (always decoupled) where their plain peak is above :data:`UD_REREAD` of the row's weakest fault gain
      (per column, among those above :data:`UD_FAULT_FLOOR` of the row's ``max ||Q_i|| ||Ge||``), or there is no
      such fault column to compare with. Exact designs read 1e-16 … 1e-10 there and are not re-read.
    - w and each fault block j where its plain peak is within ``(UD_REREAD · g_low, REREAD_CEIL · g_top]``: g_low the
      weakest of the *other* fault columns (as above), g_top the strongest fault block. That contains every
      decoupled w and excluded fault whose verdict the plain reading's error could move (the decision is at
      ``dec_tol`` times the weakest required gain ≤ g_top), and no required fault of a row whose faults are within
      1e4 of each other; a weaker required fault is re-read too (harmless: the reading is the more accurate).

    The accurate reading costs a factorisation per point (shared by all the row's re-read columns) and, near a
    decision, iterative refinement; a row with nothing to re-read costs nothing more."""
    out: dict = {}
    if not Ri.shape[0]:
        return out
    peak = lambda c: float(np.max(_nrm(Ri[:, :, c]), initial=0.0))  # noqa: E731
    bound = float(np.max(_nrm(Qi) * _nrm(Ge), initial=0.0))
    fall = np.concatenate(fcols) if fcols else np.zeros(0, int)
    colgain = np.max(np.abs(Ri[:, :, fall]), axis=(0, 1)) if fall.size else np.zeros(0)
    visible = colgain > UD_FAULT_FLOOR * bound

    def low_other(cols):
        g = colgain[visible & ~np.isin(fall, cols)]
        return float(np.min(g)) if g.size else None

    ud = {x: np.arange(sl[x].start, sl[x].stop) for x in ("u", "d")}
    both = np.r_[ud["u"], ud["d"]]
    leak = peak(both) if both.size else 0.0
    if leak > 0:
        low = low_other(np.zeros(0, int))
        if low is None or leak > UD_REREAD * low:
            out.update({x: c for x, c in ud.items() if c.size})
    top = max((peak(c) for c in fcols), default=0.0)
    cand = [("w", np.arange(sl["w"].start, sl["w"].stop))] + list(enumerate(fcols))
    for label, cols in cand:
        if not cols.size:
            continue
        r = peak(cols)
        low = low_other(cols)
        if 0 < r <= REREAD_CEIL * top and low is not None and r > UD_REREAD * low:
            out[label] = cols
    return out


def _decoupled_reading(model, Q: LTI, g, lam: np.ndarray, blocks: dict, R: np.ndarray, peaks: dict, i: int) -> None:
    """The blocks ``blocks`` (:func:`_decoupled_blocks`: u, d, a decoupled w, excluded faults) of row group g,
    ``R_X = Q_g·Ge_X``, read on the filter as stored, with each block's error bound and the realisation's
    sensitivity; writes the values into ``R[:, g, cols]`` and the bounds into ``peaks['ud_error'][i]``,
    ``peaks['ud_sensitivity'][i]`` (u and d together), ``peaks['w_error'][i]``, ``peaks['w_sensitivity'][i]`` and
    ``peaks['f_error'][i, j]``, ``peaks['f_sensitivity'][i, j]`` (fault j).

    **Why.** A decoupling row is a cancellation: ``|Q_g|·|Ge|`` is up to 1e7 times its weakest fault gain
    (benchmarks/ammp_random_set.py H∞ seed 4: 4e6, seed 7: 3.4e7), so 1e-7 of that gain is ~1e-14 of the terms. The
    values ``Q_g(λ)`` then ``Q_g(λ)·Ge(λ)`` in double (a Hessenberg form above order 64, the balanced realisation)
    read the stored filter's leak with an error of that size, which depends on the realisation: seed 4's shipped
    filter (order 70), whose u/d leak is 2.0e-8 of its weakest fault (this reading), read 4.3e-7 (Hessenberg,
    balanced), 1.9e-7 (dense LU, balanced), 1.2e-7 (dense LU as stored); seed 7's (order 87, 3.8e-8) 7.8e-8,
    4.5e-8, 4.1e-8. The error is in the solve, not in the sums (with the solve refined, ``C X + D`` in double is off
    by 1e-14): the componentwise condition of ``Q_g(λ)`` is 2e6 ``|Q_g(λ)|`` there. An excluded fault or a decoupled
    w is the same cancellation, read the same way (tests/test_judge_ud_reading.py, the excluded-fault test).

    **The reading.** The product first: ``Z = (λI − A_q)^{-1} (B_q G)``, ``R_X = C_q Z + D_q G``, ``G`` the re-read
    columns of Ge (Q_g balanced by TB01ID, Ge by :func:`plant_realisation`: diagonal similarities by powers of 2,
    the same data), each
    solve refined in the extended type (:func:`_refined_solves`, :data:`EXT_UNIT`; in double-double where longdouble
    is double, :func:`_dd_refined_values`) and the sums formed there. Its
    error, to first order (GEPP's componentwise backward error ``|ΔL| ≤ γ_3N |L|`` of each system, refined to the
    extended precision; Higham Thm 9.3 and ch. 12):

        e(λ) = 3N·u_x·( |W||λI − A_q||Z| + |W||B_q||G| + |C_q||Z| + |D_q||G| + |Q_g(λ)| E_G ),
        E_G = |W_e||λI − A_e||X_e| + |C_e||X_e|,   W = C_q (λI − A_q)^{-1},

    (``W_e``, ``X_e`` Ge's resolvents, N the larger order, u_x = :data:`REFINED_UNIT`; Frobenius norm over the block);
    at a point left at its double reading (:func:`_refine_mask`) the same with u for u_x, plus the a-posteriori term
    ``|W r̂|`` of that reading's residual ``r̂ = B_q G − (λI − A_q) Z`` against the stored A_q (:func:`_plain_values`:
    the solve's backward error is the Hessenberg reduction's, normwise, not GEPP's componentwise one; the other terms
    pay for ``r̂``'s rounding; at a refined point the term enters scaled by u_x/u, a small over-statement). A block's
    bound is that of
    its peak ``P = max_k r_k``: the largest point bound ``e_k`` among the points with ``r_k + e_k ≥ P`` (the true
    peak lies in ``[P − e_p, max_k (r_k + e_k)]``, p the peak's point). **Invariance:** a diagonal state scaling by
    powers of 2 leaves the data and this reading exactly as they are; an output scaling of the row by c rounds
    ``C_q``, ``D_q`` by ``u`` relative and moves the normalised reading by at most ``u·(|C_q||Z| + |D_q||G|)/g``; any
    other similarity T (computed in floating point) is new data, whose leak differs from this one's by at most the two
    realisations'
    **sensitivities** ``u·( |W||A_q||Z| + |W||B_q||G| + |C_q||Z| + |D_q||G| )`` (first order in relative
    perturbations u of every entry of the stored data), plus T's own rounding: the leak a double-precision
    evaluation or simulation of this realisation can show beside the stored filter's (seed 4's shipped filter:
    5.5e-7 of its weakest fault, against its leak 2.0e-8).
    """
    if not lam.size or not blocks:
        return
    rows = np.atleast_1d(np.arange(Q.p)[g])
    Qi = row_system(Q, g) if Q.n else LTI(Q.A, Q.B, Q.C[rows, :], Q.D[rows, :], Q.dt)
    labels = list(blocks)
    cols = np.concatenate([blocks[x] for x in labels])
    at = np.cumsum([0] + [blocks[x].size for x in labels])
    local = {x: np.arange(at[k], at[k + 1]) for k, x in enumerate(labels)}  # each block's columns in G
    Geb = plant_realisation(model.augmented())[:, cols]
    val, err, sens, refined = _decoupled_values(Qi, Geb, lam, list(local.values()), True)
    fine = np.all(np.isfinite(val), axis=(1, 2)) & np.all(np.isfinite(err), axis=(1, 2))
    if not np.any(fine):
        return
    block = R[:, g, :]
    block[np.ix_(fine, np.arange(rows.size), cols)] = val[fine]
    R[:, g, :] = block
    # each point's bound as it was read: 3N·u_x·||err|| refined, 3N·u·||err|| at its double reading
    unit = 3 * max(Qi.n, Geb.n, 1) * np.where(refined, REFINED_UNIT, EPS / 2)[fine]
    peak = lambda X, c: float(np.max(np.linalg.norm(X[fine][:, :, c], axis=(1, 2)), initial=0.0))  # noqa: E731

    def error(c):  # the bound on the block's peak P = max r_k: max e_k over the points with r_k + e_k ≥ P
        r, e = np.linalg.norm(val[fine][:, :, c], axis=(1, 2)), unit * np.linalg.norm(err[fine][:, :, c], axis=(1, 2))
        return float(np.max(e[r + e >= np.max(r)], initial=0.0))

    ud = [local[x] for x in ("u", "d") if x in local]
    if ud:
        peaks["ud_error"][i] = max(error(c) for c in ud)
        peaks["ud_sensitivity"][i] = EPS / 2 * peak(sens, np.concatenate(ud))
    for x in labels:
        if x in ("u", "d"):
            continue
        e, s = error(local[x]), EPS / 2 * peak(sens, local[x])
        if x == "w":
            peaks["w_error"][i], peaks["w_sensitivity"][i] = e, s
        else:
            peaks["f_error"][i, x], peaks["f_sensitivity"][i, x] = e, s


def plant_realisation(Ge: LTI) -> LTI:
    """The realisation of ``Ge`` (all its columns) the decoupled readings use: balanced by TB01ID
    (:meth:`~fmu_fdi.lti.LTI.balanced`, a diagonal similarity by powers of 2: the same data) with the columns of
    ``[B; D]`` in an order fixed by their content, so that the scaling is one per plant whatever the order of its
    inputs — a bank's model (u, d, w, f) and a member's row model (u, [d, excluded faults], w, required faults) give
    each column the same realisation, and a reading of some columns is the reading of those columns of another
    (:func:`_decoupled_values`). Read on a column subset, the realisation is then no longer the subset's own
    balancing: the readings' bounds are invariant under a diagonal similarity (``|W_e T||T⁻¹(λI − A_e)T||T⁻¹X_e|``
    = ``|W_e||λI − A_e||X_e|`` for T diagonal positive) and their values are those of the same transfer function."""
    if not Ge.n or not Ge.m or not Ge.p:
        return Ge
    order = sorted(range(Ge.m), key=lambda c: (Ge.B[:, c].tobytes(), Ge.D[:, c].tobytes()))
    bal = LTI(Ge.A, Ge.B[:, order], Ge.C, Ge.D[:, order], Ge.dt).balanced()[0]
    B = np.empty_like(bal.B)
    B[:, order] = bal.B
    return LTI(bal.A, B, bal.C, Ge.D, Ge.dt)


#: :func:`_decoupled_values`' kept readings, per (row filter, plant realisation, points): each column's plain
#: reading and, where refined, its refined value — the same filter is read by check_generator, then by report on the
#: same object; a bank's check reads each member's filter on the same points again, on subsets of the columns the
#: member read (u, d and each excluded fault alone, where the member read u and [d, excluded faults]). Entries: a
#: 26-row bank's members and the candidates of their designs (each entry ~48 bytes per point, row and column).
_UD_CACHE: OrderedDict = OrderedDict()
UD_CACHE_SIZE = 64


def _decoupled_values(Qi: LTI, Geb: LTI, lam: np.ndarray, blocks: list, with_refined: bool = False):
    """:func:`_decoupled_reading`'s values ``(R_X, the error matrix, the sensitivity matrix)`` (points × rows ×
    columns; the last two before their factors — 3N·u_x at a refined point, 3N·u at a double reading — and u) of the
    row ``Qi`` on the columns ``Geb`` (of :func:`plant_realisation`), and with ``with_refined`` the mask of the
    refined points; ``blocks``: the column indices of each block, whose peak decides where a point is refined
    (:func:`_refine_mask`, repeated with the refined values until no point left at its double reading can reach a
    block's peak: a double reading that over-states its value sets the first peak, is refined and falls, and the
    points it masked are tested again — approximate audit seed 206, tests/test_judge_refine_to_peak.py).

    Every figure is a function of its column alone (the plain reading :func:`_plain_values`, and the refined value
    of a column at a point), except where a point is refined, which depends on the blocks. So the reading is kept
    per column (``_UD_CACHE``): a request whose columns were all read before on the same filter, plant realisation
    and points takes their plain values and bounds, decides its own refined points from them by its own blocks, as
    a fresh reading would, and refines only the points not refined before for those columns. Served and fresh
    readings are the same computation on the same data; they differ only where BLAS sums a column's products in
    another order beside other columns, each within its bound of the stored filter's value, hence within the sum of
    the two bounds of each other; the bounds themselves differ by their measured residual terms (each reading's own
    solve's rounding, :func:`_plain_values`: ≤ 5.3e-3 relative on exact seed 17's bank), so a point within that of
    the refinement's threshold could be refined by one and not the other — each reading within its own bound either
    way (tests/test_judge_ud_reuse.py; on the banks of exact seeds 379, 403, 412, 382 every figure of
    info['postconditions'] the same to the bit, before judge23 and after, benchmarks/bank_check_speed.py --compare)."""
    Qb = Qi.balanced()[0] if Qi.n else Qi
    if not Qb.n:  # a static row: nothing to refine
        out = _plain_values(Qb, Geb, lam)
        return (*out, np.zeros(lam.size, bool)) if with_refined else out
    key = content_key(Qb.A, Qb.B, Qb.C, Qb.D, Geb.A, Geb.C, lam)
    ckeys = [content_key(Geb.B[:, c], Geb.D[:, c]) for c in range(Geb.m)]
    entry = recall(_UD_CACHE, key)
    if entry is None:
        K, r = lam.size, Qb.p
        entry = SimpleNamespace(cols={}, val=np.zeros((K, r, 0), complex), err=np.zeros((K, r, 0)),
                                sens=np.zeros((K, r, 0)), refined=np.zeros((K, 0), bool),
                                rval=np.zeros((K, r, 0), complex))
    # a kept entry is never changed: a reading that adds to it keeps a new one (another thread may be reading it)
    new = [c for c, k in enumerate(ckeys) if k not in entry.cols and ckeys.index(k) == c]  # each column once
    if new:
        v, e, s = _plain_values(Qb, Geb[:, new], lam)
        base = entry.val.shape[2]
        entry = SimpleNamespace(cols={**entry.cols, **{ckeys[c]: base + k for k, c in enumerate(new)}},
                                val=np.concatenate([entry.val, v], axis=2), err=np.concatenate([entry.err, e], axis=2),
                                sens=np.concatenate([entry.sens, s], axis=2),
                                refined=np.concatenate([entry.refined, np.zeros((lam.size, len(new)), bool)], axis=1),
                                rval=np.concatenate([entry.rval, np.full(v.shape, np.nan, complex)], axis=2))
    idx = np.array([entry.cols[k] for k in ckeys], int)
    val, err, sens = entry.val[:, :, idx].copy(), entry.err[:, :, idx], entry.sens[:, :, idx]
    need = np.zeros(lam.size, bool)
    while REFINED_UNIT < EPS / 2:
        more = _refine_mask(val, err, blocks, max(Qb.n, Geb.n, 1), need)
        if not np.any(more):
            break
        todo = more & ~np.all(entry.refined[:, idx], axis=1)
        if np.any(todo):
            sub = np.unique(idx)
            pos = [int(np.flatnonzero(idx == s_)[0]) for s_ in sub]  # a request column of each stored one
            rval, refined = entry.rval.copy(), entry.refined.copy()
            rval[np.ix_(todo, np.arange(Qb.p), sub)] = _refined_values(Qb, Geb[:, pos], lam[todo])
            refined[np.ix_(todo, sub)] = True
            entry = SimpleNamespace(**{**vars(entry), "rval": rval, "refined": refined})
        val[more] = entry.rval[more][:, :, idx]
        need |= more
    remember(_UD_CACHE, key, entry, UD_CACHE_SIZE)
    return (val, err, sens, need) if with_refined else (val, err, sens)


def _plant_values(Geb: LTI, lam: np.ndarray, Xe=None) -> np.ndarray:
    """``Ge(λ) = C_e X_e + D_e``, ``X_e = (λI − A_e)^{-1} B_e`` (``Xe``: given), at the points λ in the extended
    type, the solves refined at every point (the plant's order: cheap)."""
    if not Geb.n:
        return np.broadcast_to(Geb.D.astype(np.clongdouble), (lam.size,) + Geb.D.shape)
    if Xe is None:
        B = np.broadcast_to(Geb.B.astype(np.clongdouble), (lam.size,) + Geb.B.shape)
        Xe = _refined_solves(Geb.A, lam, B, Geb.C, refine=np.ones(lam.size, bool) if EXT_UNIT < EPS / 2 else None)[0]
    return Geb.C.astype(np.longdouble) @ Xe + Geb.D.astype(np.longdouble)


def _plant_reading(Geb: LTI, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(G, E_G)``: :func:`_plant_values` and its error matrix ``E_G = |W_e||λI − A_e||X_e| + |C_e||X_e|``
    (:func:`_decoupled_reading`) at the points λ."""
    if not Geb.n:
        return _plant_values(Geb, lam), np.zeros((lam.size, Geb.p, Geb.m))
    B = np.broadcast_to(Geb.B.astype(np.clongdouble), (lam.size,) + Geb.B.shape)
    if EXT_UNIT < EPS / 2:  # X_e refined in the extended type, W_e from the same LU per point
        Xe, We = _refined_solves(Geb.A, lam, B, Geb.C, refine=np.ones(lam.size, bool), with_left=True)
    else:
        Xe, We = _refined_solves(Geb.A, lam, B, Geb.C)
    aX = np.abs(Xe.astype(complex))
    EG = np.abs(We) @ (np.abs(Geb.A) @ aX) + np.abs(lam)[:, None, None] * (np.abs(We) @ aX) + np.abs(Geb.C) @ aX
    if EXT_UNIT >= EPS / 2:  # X_e at its double reading: its solve's backward error measured (:func:`_plain_values`)
        n = max(Geb.n, 1)
        EG = EG + _residual_term(Geb.A, lam, Xe, We, B.astype(complex), 3 * n, 3 * n) / (3 * n * EPS / 2)
    return _plant_values(Geb, lam, Xe), EG


def _residual_term(A: np.ndarray, lam: np.ndarray, X: np.ndarray, W: np.ndarray, b: np.ndarray, paid_A: float,
                   paid_lam: float) -> np.ndarray:
    """The a-posteriori part of a plain reading's bound (:func:`_plain_values`): ``|W r̂| + u·(max(0, n + 4 −
    paid_A)·|W||A||X| + max(0, 7 − paid_lam)·|λ||W||X|)``, ``r̂ = fl(b − (λX − AX))`` the residual of the computed
    solutions ``X ≈ (λI − A)^{-1} b`` against the *stored* A, in double, and ``W ≈ C(λI − A)^{-1}`` (points ×
    rows × columns). ``r̂``'s rounding is ``|r̂ − r| ≤ (n + 2)u|A||X| + (2 + 2√2)u|λ||X| + 2u|b|`` to first order
    (real inner products of length n, Higham 2nd ed. §3.1; a complex product ``√2·γ_2``, Lemma 3.5; two
    subtractions), and ``|b| ≤ (|λ| + |A|)|X|`` to first order: ``(n + 4)u`` on ``|W||A||X|``, ``7u`` on
    ``|λ||W||X|``, of which the caller's own terms charge ``paid_A·u`` and ``paid_lam·u``; the rest is added here."""
    lam3 = lam[:, None, None]
    r = b - (lam3 * X - A @ X)
    aW, aX = np.abs(W), np.abs(X)
    out = np.abs(W @ r)
    n = A.shape[0]
    more_A, more_lam = max(0.0, n + 4 - paid_A), max(0.0, 7 - paid_lam)
    if more_A:
        out = out + more_A * EPS / 2 * (aW @ (np.abs(A) @ aX))
    if more_lam:
        out = out + more_lam * EPS / 2 * np.abs(lam3) * (aW @ aX)
    return out


def _plain_values(Qb: LTI, Geb: LTI, lam: np.ndarray):
    """The plain (double) reading ``R_X = C_q Z + D_q G``, ``Z = (λI − A_q)^{-1}(B_q G)``, of the balanced row
    ``Qb`` on the columns ``Geb``, with its error and sensitivity matrices (:func:`_decoupled_reading`); ``G``
    refined (:func:`_plant_values`). The error matrix ``err`` is such that ``3N·u·err`` (u = EPS/2, N = max(n_q, n_e,
    1)) bounds the reading's error entrywise to first order:

    **Why a residual.** :func:`_refined_solves` factors ``λI − H``, ``A_q = U H Uᵀ`` (Householder, dgehrd). GEPP's
    componentwise backward error ``|ΔM| ≤ γ_3n|L||U|`` (Higham, *Accuracy and Stability*, 2nd ed., Thm 9.3) is on
    ``λI − H``; mapped back, ``U ΔH Uᵀ`` and the reduction's own error (``Ĥ = Uᵀ(A_q + E)U``, ``||E||_2 ≤
    c·n²·u·||A_q||_2`` with c a modest constant: Golub & Van Loan, *Matrix Computations*, 4th ed., §7.4.3, after
    Wilkinson, *The Algebraic Eigenvalue Problem*, p. 351; Higham Lemma 19.3 for a product of Householder
    reflections; the applications of U and Uᵀ per point add ``γ_n``-normwise terms) are *normwise*: spread over
    every entry of a graded A_q (a balanced filter's entries span 1e-5 … 1e4), they exceed ``u·|A_q|`` at its small
    entries, and the componentwise charge ``3N·u·|W||λI − A_q||Z|`` alone was exceeded 13× (random H∞ matching seed
    4; 34.8× on its design's candidate, tests/test_judge_plain_bound.py). No constant c
    has to be trusted here: the backward error the solve made is *measured*. With ``b̂`` the right-hand side rounded
    to double, ``r = b̂ − (λI − A_q) Ẑ`` exactly, ``Ẑ − Z = −(λI − A_q)^{-1} r + (λI − A_q)^{-1}(b̂ − B_q G)``, so

        R̂_X − R_X = −W r + W (b̂ − B_q G) + Q_g(λ) δG + (rounding of C_q Ẑ + D_q G),     W = C_q (λI − A_q)^{-1},

    exactly but for those roundings. ``r`` is computed in double (:func:`_residual_term`, ``r̂``); replacing W by the
    computed ``Ŵ`` changes ``W r`` at second order (two first-order quantities), the order the bound is derived to
    (as every term of :func:`_decoupled_reading`'s bound uses the computed W and Z). Hence, to first order,

        |R̂_X − R_X| ≤ |Ŵ r̂| + |Ŵ||r̂ − r| + u|Ŵ||B_q||G| + |Q_g(λ)||δG| + γ_{n+1}|C_q||Ẑ| + γ_{m+1}|D_q||G|,

    ``|r̂ − r| ≤ (n + 4)u|A_q||Ẑ| + 7u|λ||Ẑ|`` (:func:`_residual_term`, with ``|b̂| ≤ (|λ| + |A_q|)|Ẑ|``), the
    last term ``(m + 2)u`` with G rounded to double (m = Ge's rows): the terms of :func:`_decoupled_reading`'s bound
    at ``3N·u`` pay for every rounding where ``3N ≥ n + 4``, ``3N ≥ 7`` and ``3N ≥ m + 2`` (where not, the
    difference is added here and in :func:`_residual_term`), and ``|Ŵ r̂|`` for the solve's backward error,
    whatever its structure. The bound is then as sharp as the first-order error itself where the reduction's error
    dominates (seed 4: within 0.94 of it) and grows little elsewhere (median 1.0–1.3× the componentwise one on seeds
    4, 206). ``G``'s own error ``δG`` is :func:`_plant_reading`'s ``E_G`` (its double reading measured the same way
    where longdouble is double)."""
    G, EG = _plant_reading(Geb, lam)
    aG = np.abs(G.astype(complex))
    if not Qb.n:
        err = np.abs(Qb.D) @ aG + np.abs(Qb.D) @ EG
        return (Qb.D.astype(np.longdouble) @ G).astype(complex), err, err
    rhs = Qb.B.astype(np.longdouble) @ G
    Z, W = _refined_solves(Qb.A, lam, rhs, Qb.C)
    aW, aB, aC, aD, aZ = np.abs(W), np.abs(Qb.B), np.abs(Qb.C), np.abs(Qb.D), np.abs(Z)
    WAZ = (aW @ np.abs(Qb.A)) @ aZ
    common = aW @ aB @ aG + aC @ aZ + aD @ aG
    # |λI − A| ≤ |λ| I + |A| entrywise
    # Ge's rounding enters as Q(λ)·δG: |Q(λ)| (W·B_q + D_q, to first order), not |W||B_q|, which is 1e4 times
    # larger where Q's value is a cancellation (random matching seed 4)
    err = WAZ + np.abs(lam)[:, None, None] * (aW @ aZ) + common + np.abs(W @ Qb.B + Qb.D) @ EG
    N = max(Qb.n, Geb.n, 1)
    err = err + _residual_term(Qb.A, lam, Z, W, rhs.astype(complex), 3 * N, 3 * N) / (3 * N * EPS / 2)
    if Qb.m + 2 > 3 * N:  # D_q G's rounding beyond what its term pays at 3N·u
        err = err + (Qb.m + 2 - 3 * N) / (3 * N) * (aD @ aG)
    sens = WAZ + common
    val = Qb.C @ Z + Qb.D @ G.astype(complex)
    return val, err, sens


def _refine_mask(val: np.ndarray, err: np.ndarray, blocks: list, N: int, refined=None) -> np.ndarray:
    """The points a reading refines next, among those not ``refined`` (default none): where a double reading's own
    bound ``3N·u·err`` could move a block's peak (by more than 1e-3 of the value); elsewhere it is within that of the
    stored filter's value already. The peak's lower end ``max_k (r_k − e_k)`` is taken with each point's bound as it
    was read (3N·u_x·err where refined), so a call with the refined values returns the points the refinement
    unmasked, none once no double reading can reach the refined peak (:func:`_decoupled_values`' loop)."""
    done = np.zeros(val.shape[0], bool) if refined is None else np.asarray(refined, bool)
    unit = 3 * N * np.where(done, REFINED_UNIT, EPS / 2)
    need = np.zeros(val.shape[0], bool)
    for idx in blocks:
        if not idx.size:
            continue
        r = np.linalg.norm(val[:, :, idx], axis=(1, 2))
        e = unit * np.linalg.norm(err[:, :, idx], axis=(1, 2))
        ok = np.isfinite(r) & np.isfinite(e)
        top = float(np.max(np.where(ok, r - e, -np.inf), initial=-np.inf))
        need |= ok & ~done & (e > 1e-3 * r) & (r + e >= top)
    return need


def _refined_values(Qb: LTI, Geb: LTI, lam: np.ndarray, dd: bool = DD_READING) -> np.ndarray:
    """``R_X`` of the row ``Qb`` on the columns ``Geb`` at the points λ with the row's solves refined in the
    extended type (:func:`_refined_solves`); with ``dd`` (default where longdouble is double) in double-double
    (:func:`_dd_refined_values`). Two steps converge on the ill-scaled cases measured against a 40–50-digit truth
    from the stored data (tests/test_judge_refined_bound.py: H∞ matching seed 4, order 22; audit seed 338, order
    125): error ≤ 4.0e-3 resp. 1.6e-3 of the refined bound ``3N·u_x·||err||`` at every point measured, the same
    at 1, 3 or 5 steps."""
    if dd:
        return _dd_refined_values(Qb, Geb, lam)
    G = _plant_values(Geb, lam)
    Zr = _refined_solves(Qb.A, lam, Qb.B.astype(np.longdouble) @ G, Qb.C, refine=np.ones(lam.size, bool))[0]
    return (Qb.C.astype(np.longdouble) @ Zr + Qb.D.astype(np.longdouble) @ G).astype(complex)


def _dd_refined_values(Qb: LTI, Geb: LTI, lam: np.ndarray, steps: int = 3) -> np.ndarray:
    """:func:`_refined_values` in double-double, on every host: ``X_e = (λI − A_e)^{-1} B_e``, ``G = C_e X_e + D_e``,
    ``Z = (λI − A_q)^{-1}(B_q G)``, ``R_X = C_q Z + D_q G`` at all the points at once — each solve by
    :func:`fmu_fdi.lti.dd_refined_solves` (the LU of ``λI − H`` on the Hessenberg form, as :func:`_refined_solves`,
    then ``steps`` steps of :func:`fmu_fdi.lti.refine_dd`), each product by :func:`fmu_fdi.lti.stack_times_dd` and each
    sum by :func:`fmu_fdi.lti.dd_add`; the value rounded to double at the end.

    **Its unit.** Each refined solve converges (contraction ``~3N·u·|| |(λI − A)^{-1}| |λI − A| ||`` per step, as in
    :func:`_refined_solves`) to the solution of the stored system to its residual's error, ``c_n·u²`` times ``|b| +
    |λI − A||x|`` (:func:`fmu_fdi.lti.refine_dd`; ``c_n = 1968 + 3n + 4⌈log₂ n⌉``, :func:`fmu_fdi.lti.residual_unit`,
    the 1960 a worst case of the exact slice products' Sum2 — measured ≤ 1.4 against fractions); the products and sums
    add ``(c_n − 4)·u²`` times ``|C_q||Z| + |D_q||G|`` and ``|B_q||G|`` (:func:`fmu_fdi.lti.stack_times_dd`'s
    ``(1962 + 3n + 4⌈log₂ n⌉)·u²``, TwoSum's renormalisation ``2u²``): the error terms of :func:`_decoupled_reading`'s
    bound, each with the factor ``c_N·u² ≤ 3N·2^-64`` for every N ≥ 1 (``u² = 2^-106``: the ratio 2^42·3N/c_N is ≥
    2^42·3/1971 > 2^32 ≫ 1, room for the refinement's remaining contraction ``(3N·u·κ)^steps`` with ``κ`` the
    componentwise condition up to 1e8 at ``steps = 3``). So the reading is charged at :data:`REFINED_UNIT` = 2^-64, as
    x87's — the same points are refined and proven as on x86. The final rounding to double, ``u·|R_X|``, is relative
    to the value itself (the bound on x86 leaves out its own the same way)."""
    K = lam.size
    pts = RationalPoints.of(lam)
    Gh = np.broadcast_to(np.asarray(Geb.D, float).astype(complex), (K,) + Geb.D.shape).copy()
    Gl = np.zeros_like(Gh)
    if Geb.n:
        B = np.broadcast_to(np.asarray(Geb.B, float).astype(complex), (K,) + Geb.B.shape)
        Xh, Xl, _ = dd_refined_solves(Geb.A, pts, B, None, steps)
        Gh, Gl = dd_add(*stack_times_dd(Geb.C, Xh, Xl), Gh, Gl)
    Rh, Rl = stack_times_dd(Qb.D, Gh, Gl)
    if Qb.n:
        Zh, Zl, _ = dd_refined_solves(Qb.A, pts, *stack_times_dd(Qb.B, Gh, Gl), steps)
        Rh, Rl = dd_add(*stack_times_dd(Qb.C, Zh, Zl), Rh, Rl)
    return Rh + Rl


@single_blas_thread  # as the designs: small matrices, where threaded BLAS spin-waits on a loaded machine
def internal_figures(gen, groups=None, freqs=None, accurate: bool = True) -> dict:
    """The peaks of the internal form of ``gen`` per residual group, on the judge's grid.

    Returns a dict with, for the groups ``groups`` (default ``gen.groups``):
    ``peaks``: ``{'u', 'd', 'w': (G,), 'f': (G, faults), 'Q': (G,)}`` — ``max_λ ||R_X,i(λ)||_2``
    (faults: one column block per named fault, in ``model.fault_names`` order; ``Q``: the
    row group's own peak gain ``max_λ ||Q_i(λ)||``; ``bound``: ``max_λ ||Q_i(λ)|| ||Ge(λ)||``,
    the scale of everything the row can output); ``cosine``: (G, faults), the γ_j of the
    module docstring; ``at_freqs``: (len(freqs), G, faults) gains ``||R_fj,i(jω)||`` or None;
    ``finite``: False when the filter or the model cannot be evaluated on the grid; ``reread``: whether some row has
    a block :func:`_decoupled_blocks` re-reads (with ``accurate=False`` the blocks are chosen, not re-read: the plain
    figures, for check_generator's scales, which are fault gains the plain reading reads to rounding).
    """
    return _internal_figures(gen, groups, freqs, accurate)


def _internal_figures(gen, groups=None, freqs=None, accurate: bool = True, modes=False) -> dict:
    """:func:`internal_figures` without its BLAS thread limit: the judge's own calls (check_generator and report
    limit it already; threadpoolctl's limit costs ~8 ms a call, it reads every loaded library). ``modes``: the
    plant's mode table (:func:`judge_points`) where the caller has it — a bank's groups share one."""
    model, Q = gen.model, gen.Q
    groups = gen.groups if groups is None else groups
    nf = len(model.faults)
    G = len(groups)
    out = _blank_figures(G, nf, None, False)
    if not all(np.all(np.isfinite(X)) for X in (Q.A, Q.B, Q.C, Q.D)):
        out["finite"] = False
        return out
    if G > 1:
        return _figures_by_group(gen, groups, freqs, accurate)
    pts = judge_points(model, Q, groups, modes)
    if pts is None:
        out["finite"] = False
        return out
    lam, Ge, Qv, out["decisions"] = pts
    sl = model.group_slices()
    fsl = sl["f"]
    fcols = [np.arange(fsl.start, fsl.stop)[f.columns] for f in model.faults]
    R = np.einsum("kiq,kqc->kic", Qv, Ge)
    # the blocks each row decouples, read on the filter as stored where the plain reading may decide
    blocks = [_decoupled_blocks(R[:, g, :], Qv[:, g, :], Ge, sl, fcols) if model.n + Q.n else {} for g in groups]
    out["reread"] = any(bool(b) for b in blocks)
    state = (model, Q, groups, freqs, lam, R, Qv, Ge, blocks)
    if out["reread"] and not accurate:  # kept for :func:`accurate_figures`
        out["_state"] = state[:5] + (R.copy(),) + state[6:]
    return _figures_from(out, state, accurate)


def judge_points(model, Q: LTI, groups, modes=False):
    """``(λ, Ge, Qv, decisions)``: the points one row group is read at, the plant's and the filter's values there
    (where both are finite) and the decisions on the plant's boundary modes (:func:`mode_decisions` on the judge's
    table, :func:`.plant_modes.boundary_mode_table` with ``beside``); None where no point is finite. The grid of
    :func:`_eval_points` with the two-gaps-beside points of the stable modes within the gap of the boundary, then
    without the points within the gap of those the row removes (:func:`_beside_cancelled`). ``modes``: the table,
    if already computed (a bank's groups share it)."""
    if modes is False:
        modes = _boundary_modes(model, beside=True) if model.n else None
    near = modes is not None and not np.all(modes["outside"])
    lam = _eval_points(model, Q, beside=[(modes["poles"][~modes["outside"]], modes["gap"])] if near else None)[1]
    Ge = _values(model.augmented(), lam)
    Qv = _values_by_row(Q, groups, lam)
    ok = np.all(np.isfinite(Ge), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2))
    if not np.any(ok):
        return None
    Ge, Qv, lam = Ge[ok], Qv[ok], lam[ok]
    decisions = mode_decisions(model, Q, groups, [float(np.max(_nrm(Qv[:, g, :]))) for g in groups], modes=modes)
    if near:
        keep = ~_beside_cancelled(decisions, lam)
        if np.any(keep):
            Ge, Qv, lam = Ge[keep], Qv[keep], lam[keep]
    return lam, Ge, Qv, decisions


def _beside_cancelled(decisions: dict, lam: np.ndarray) -> np.ndarray:
    """Mask of the points ``lam`` within the gap of a stable plant mode beside the boundary
    (:func:`.plant_modes.beside_boundary`) that the one row group of ``decisions`` removes from every column it
    couples to (cancelled to rounding, or not excited): the grid keeps the same distance from it as from a
    boundary pole (:func:`_beside_boundary_poles`), so that a pole reads the same on both sides of the margin.

    A mode the row does not cancel keeps the points beside it: its peak ``ρ/δ`` at the distance δ of the pole
    from the axis (ω = Im p, on the grid as 0 or a resonance) is what the user's residual shows — a slow but
    stable leak, not rounding — and is read there (a boundary pole the row keeps is refused as a pole of R
    instead, :func:`_r_poles`)."""
    modes = decisions["modes"]
    mask = np.zeros(lam.size, bool)
    for k in np.flatnonzero(~modes["outside"]):
        if np.all(decisions["removed"][k][:, modes["coupled"]]):
            mask |= np.abs(lam - modes["poles"][k]) <= modes["gap"]
    return mask


def _figures_from(out: dict, state: tuple, accurate: bool) -> dict:
    """The rest of :func:`internal_figures` (one row group) from its plain values ``state``: the decoupled blocks
    re-read (``accurate``), the cancelled boundary modes removed, the peaks; fills and returns ``out``. R (in
    ``state``) is changed in place."""
    model, Q, groups, freqs, lam, R, Qv, Ge, blocks = state
    sl = model.group_slices()
    p, G, nf = model.ny, len(groups), len(model.faults)
    fsl = sl["f"]
    fcols = [np.arange(fsl.start, fsl.stop)[f.columns] for f in model.faults]
    if accurate:
        for i, g in enumerate(groups):
            if blocks[i]:
                _decoupled_reading(model, Q, g, lam, blocks[i], R, out["peaks"], i)
    out["removed"] = _without_cancelled_modes(model, Q, groups, lam, R, Qv, Ge, out["decisions"])
    Gf_n = [_nrm(Ge[:, :p, c]) for c in fcols]
    nGe = _nrm(Ge)
    for i, g in enumerate(groups):
        Ri = R[:, g, :]
        for x in ("u", "d", "w"):
            out["peaks"][x][i] = float(np.max(_nrm(Ri[:, :, sl[x]])))
        nQ = _nrm(Qv[:, g, :])
        out["peaks"]["Q"][i] = float(np.max(nQ))
        out["peaks"]["bound"][i] = float(np.max(nQ * nGe))
        nQy = _nrm(Qv[:, g, :p])
        for j, c in enumerate(fcols):
            Rn = _nrm(Ri[:, :, c])
            out["peaks"]["f"][i, j] = float(np.max(Rn))
            out["cosine"][i, j] = _cosine(Rn, nQy * Gf_n[j])
    if freqs is not None:
        Gs, Qs = _freq_values(model, Q, freqs)
        Rs = np.einsum("kiq,kqc->kic", Qs, Gs)
        at = np.zeros((Rs.shape[0], G, nf))
        for i, g in enumerate(groups):
            for j, c in enumerate(fcols):
                at[:, i, j] = _nrm(Rs[:, g][:, :, c])
        out["at_freqs"] = at
    return out


def accurate_figures(fj: dict) -> dict:
    """The figures :func:`internal_figures` returns with ``accurate=True``, from those it returned with
    ``accurate=False`` (the same grid values and mode decisions, kept): the decoupled blocks re-read. ``fj`` itself
    where nothing is re-read."""
    if "_parts" in fj:
        return _stacked([accurate_figures(f) for f in fj["_parts"]], fj["_groups"], fj["_freqs"])
    if "_state" not in fj:
        return fj
    state = fj["_state"]
    G, nf = len(state[2]), len(state[0].faults)
    out = _blank_figures(G, nf, fj["decisions"], True)
    return _figures_from(out, state[:5] + (state[5].copy(),) + state[6:], True)


def _blank_figures(G: int, nf: int, decisions, reread: bool) -> dict:
    """:func:`internal_figures`' figures of G row groups and nf faults before anything is read: zero peaks, the
    decoupled blocks' error bounds and sensitivities (:func:`_decoupled_reading`) zero."""
    out = {"finite": True, "peaks": {g: np.zeros(G) for g in ("u", "d", "w", "Q", "bound")},
           "cosine": np.zeros((G, nf)), "at_freqs": None, "removed": [], "decisions": decisions, "reread": reread}
    out["peaks"]["f"] = np.zeros((G, nf))
    for x in ("ud", "w"):
        out["peaks"][x + "_error"], out["peaks"][x + "_sensitivity"] = np.zeros(G), np.zeros(G)
    out["peaks"]["f_error"], out["peaks"]["f_sensitivity"] = np.zeros((G, nf)), np.zeros((G, nf))
    return out


def _figures_by_group(gen, groups, freqs, accurate: bool = True) -> dict:
    """:func:`internal_figures` of several row groups, each read alone: on its own filter (:func:`row_system`: a
    bank member's own states) and on the grid of its own poles and the plant's (:func:`_eval_points`), then stacked.

    A row is read the same whether it stands alone or in a bank. One grid for the whole bank (built from every
    member's poles) sampled each row at other points than the row alone: random seed 218's 16-row bank (n = 25,
    members of order 9 … 25 with pole scales over many decades) read row 11's excluded fault fc — the plant's
    integrator s = 3e-16, cancelled by the row to a residue 5.9e-13 against δ_i = 1.9e-7 — at 1.18e-7 at the bank
    grid's lowest point ω = 2.07e-5, where the row's own grid (lowest point 1.81e-5) reads 3.3e-8: the same row,
    refused in the bank and designed alone (values there are the rounding of Q_i·Ge next to a pole computed 3e-16
    off the axis, which moves from point to point). Per group, every figure of the row is a function of the row's
    data and the plant's alone."""
    model, Q = gen.model, gen.Q
    rows = np.arange(Q.p)
    parts = []
    modes = _boundary_modes(model, beside=True) if model.n else None  # the plant's: once for every group
    for g in groups:
        idx = np.atleast_1d(rows[g])
        sub = row_system(Q, g) if Q.n else LTI(Q.A, Q.B, Q.C[idx, :], Q.D[idx, :], Q.dt)
        view = SimpleNamespace(model=model, Q=sub, groups=[list(range(idx.size))])  # what internal_figures reads
        parts.append(_internal_figures(view, view.groups, freqs, accurate, modes))
    out = _stacked(parts, groups, freqs)
    if not accurate and out["reread"]:  # kept for :func:`accurate_figures`
        out.update({"_parts": parts, "_groups": groups, "_freqs": freqs})
    return out


def _stacked(parts: list, groups, freqs) -> dict:
    """The figures of row groups read alone (:func:`_figures_by_group`), stacked."""
    out = {"finite": all(f["finite"] for f in parts), "at_freqs": None, "decisions": None, "removed": [],
           "reread": any(f.get("reread", False) for f in parts)}
    out["peaks"] = {k: np.concatenate([f["peaks"][k] for f in parts])
                    for k in ("u", "d", "w", "Q", "bound", "f", "ud_error", "ud_sensitivity", "w_error",
                              "w_sensitivity", "f_error", "f_sensitivity")}
    out["cosine"] = np.concatenate([f["cosine"] for f in parts])
    if freqs is not None and all(f["at_freqs"] is not None for f in parts):
        out["at_freqs"] = np.concatenate([f["at_freqs"] for f in parts], axis=1)
    decs = [f["decisions"] for f in parts]
    if all(d is not None for d in decs):  # the table is the plant's: all None or none
        out["decisions"] = {"modes": decs[0]["modes"], **{k: np.concatenate([d[k] for d in decs], axis=1)
                                                           for k in ("residue", "delta_i", "removed")}}
    for i, f in enumerate(parts):
        for p, mask in f["removed"]:
            full = np.zeros((len(groups),) + mask.shape[1:], bool)
            full[i] = mask[0]
            out["removed"].append((p, full))
    return out


#: what to try when a post-condition fails, by condition (check_generator's ``hints`` add to it)
_ADVICE = {
    "finite": "the design produced NaN/Inf: the model data is singular for this method",
    "decoupling": "the null-space/rank decisions are ill-conditioned for this model: pass atol/rtol (rank "
                  "tolerances), balance or rescale the model's states, or ask for a smaller structure",
    "structure": "a fault marked 0 leaks into its residual: loosen/tighten atol/rtol, or check the structure "
                 "against fmu_fdi.isolability(model)",
    "visibility": "a required fault is rounding noise in its residual: it is not detectable once the 0-faults "
                  "and d are decoupled (lower FDtol only if the fault really is this weak)",
    "zero": "the filter is numerically zero: no residual sees the required faults",
    "strong": "pass other freqs, or lower FDGainTol",
    "stability": "pass stable poles / a smaller sdeg, or relax smarg",
    "R stability": "the residual keeps a plant mode outside the margin (no stable R exists with this filter): "
                   "the design must cancel it (a coprime factorisation of [Q R]), or relax smarg",
}


@single_blas_thread  # as the designs: small matrices, where threaded BLAS spin-waits on a loaded machine
def check_generator(gen, *, decouple=("u", "d"), structure=None, faults=None, block: bool = False,
                    freqs=None, FDtol: float = 1e-4, FDGainTol: float = 0.01, smarg: float | None = None,
                    dec_tol: float = DEC_TOL, hints: dict | None = None, raise_error: bool = True,
                    normalize: bool = True) -> dict:
    """Normalise a residual generator's rows and judge its contract; return the figures or raise.

    The rows of ``gen.Q`` (and of a bank's members) are scaled in place to unit weakest
    required fault gain (module docstring); the figures, stored in ``gen.info['postconditions']``,
    are those of the returned, normalised object.

    Parameters
    ----------
    gen : ResidualGenerator
    decouple : sequence of {'u', 'd', 'w'}
        Input groups that must be decoupled (absolute ``dec_tol`` on the normalised form).
    structure : array_like of 0/1, optional
        One row per residual group (or one row for ``block=True``); columns are ``faults``.
        1: the fault must be visible; 0: it must be decoupled. Default: every fault visible.
    faults : list of str, optional
        Fault names of the structure's columns (default: all faults). Others are don't-care.
        ``faults=[]``: no fault is required and the rows are not scaled (model matching).
    block : bool
        Judge all residual outputs as one group (detection designs with ``rdim > 1``): one
        scale for the whole filter.
    freqs : array_like, optional
        Frequencies (rad/s) at which every required fault must be strongly visible.
    FDtol, FDGainTol, smarg, dec_tol : float
        Thresholds; see the module docstring.
    hints : dict, optional
        ``condition -> advice`` overriding the default advice in the error message.
    raise_error : bool
        With False, return the figures with ``'failures'`` instead of raising.
    normalize : bool
        With False (a method whose rows carry a scaling of their own, e.g. the parity
        space's unit noise variance), the same tests are made on a scaled copy and ``gen``
        keeps its rows; ``leakage``/``structure_matrix`` are still those of ``gen`` itself.

    Returns
    -------
    dict
        ``decoupling`` (peak of the decoupled groups over the judged rows), ``leakage``
        (``max(||Ru||, ||Rd||)`` over the generator's groups, what :func:`fmu_fdi.analysis.leakage`
        reports), ``structure_matrix`` (weak, threshold ``dec_tol``: what
        :func:`fmu_fdi.analysis.structure_matrix` reports), ``structure_leak``,
        ``fault_visibility`` (the smallest cosine γ_j), ``fault_gain`` (smallest normalised
        required gain, 1), ``scales`` (the factor applied to each judged group),
        ``filter_peak_gain``, ``pole_extreme``/``smarg``, ``R_poles`` (R's poles outside the
        margin), with ``freqs`` ``strong_gain_ratio`` (smallest normalised gain at ``freqs``)
        and ``strong_structure_matrix``.
    """
    model = gen.model
    names = list(model.fault_names if faults is None else faults)
    judged = [list(range(gen.Q.p))] if block else gen.groups
    S = np.ones((len(judged), len(names)), dtype=int) if structure is None else np.atleast_2d(structure).astype(int)
    if S.shape != (len(judged), len(names)):
        raise DesignError(f"structure has shape {S.shape}, expected {(len(judged), len(names))}")
    for g in decouple:
        if g not in ("u", "d", "w"):
            raise DesignError(f"decouple names input groups 'u', 'd', 'w'; got {g!r}")
    adv = dict(_ADVICE)
    adv.update(hints or {})
    fig: dict = {"dec_tol": dec_tol, "FDtol": FDtol}
    failures: list[tuple[str, str]] = []
    if smarg is None:
        smarg = default_smarg(model.dt)
    fig["smarg"] = smarg
    all_names = model.fault_names
    col = [all_names.index(nm) for nm in names]

    # the plain figures first (the scales are fault gains, read to rounding without the decoupled blocks' accurate
    # reading, which is made once, on the normalised rows: it costs a factorisation per point and refinement)
    fj = _internal_figures(gen, judged, freqs, accurate=False)
    if not fj["finite"]:
        failures.append(("finite", "the filter or the model cannot be evaluated on the frequency grid "
                                   "(NaN/Inf in the filter's matrices or at every grid point)"))
        return _finish(fig, failures, adv, gen, raise_error)

    scales = _visibility(fj, judged, names, all_names, col, S, FDtol, fig, failures)
    # a group whose weakest required gain already reads 1 to rounding (rows an earlier judgement normalised: a bank's
    # members, each judged in its own design, read 1 ± 4.8e-13 on the bank's model, random exact seed 379) keeps its
    # rows: scaling them by 1 + 1e-13 would change the filter by rounding and cost a second reading of everything
    # (the figures must be those of the returned object, bit for bit what leakage() reads of it)
    scales[np.abs(scales - 1.0) <= NORMALISED_RTOL] = 1.0
    if failures:
        if fj["reread"]:  # the figures of a refusal are the accurate ones too
            fj = accurate_figures(fj)
            failures.clear()
            _visibility(fj, judged, names, all_names, col, S, FDtol, fig, failures)
        return _finish(fig, failures, adv, gen, raise_error)
    own_gen = gen
    if not np.any(scales != 1.0):
        fj = accurate_figures(fj)  # unscaled rows: the same grid values and decisions (kept), the blocks re-read
    else:
        row_scale = np.ones(gen.Q.p)
        for i, g in enumerate(judged):
            row_scale[g] = scales[i]
        if not normalize:
            from ...generator import ResidualGenerator

            gen = ResidualGenerator(gen.Q, model, gen.method, gen.residual_names, gen.groups)
        gen.scale_rows(row_scale)
        fj = _internal_figures(gen, judged, freqs)
        if not fj["finite"]:
            failures.append(("finite", f"the normalised filter (scales {scales.tolist()}) cannot be evaluated"))
            return _finish(fig, failures, adv, own_gen, raise_error)
    fig["scales"] = scales.tolist()

    decisions = user_margin_decisions(model, gen.Q, judged, fj["peaks"]["Q"], smarg, fj["decisions"])
    _stability(model, gen.Q, smarg, fig, failures, decisions)
    _decoupling(model, fj, judged, names, col, S, decouple, dec_tol, fig, failures)
    _strong_visibility(fj["at_freqs"], judged, names, col, S, freqs, FDGainTol, fig, failures)

    # 5. what leakage() and structure_matrix() report for this object (the generator's own groups): the figures just
    # read where they are of that object and its groups (the normalised rows, judged as the generator groups them)
    if own_gen is gen and [list(np.atleast_1d(np.arange(gen.Q.p)[g])) for g in judged] == \
            [list(np.atleast_1d(np.arange(gen.Q.p)[g])) for g in gen.groups]:
        own = _reported(fj, gen, freqs, FDGainTol, dec_tol)
    else:
        own = report(own_gen, freqs=freqs, FDGainTol=FDGainTol, dec_tol=dec_tol)
    fig["leakage"] = own["leakage"]
    fig["structure_matrix"] = own["structure_matrix"]
    if freqs is not None:
        fig["strong_structure_matrix"] = own["strong_structure_matrix"]
    return _finish(fig, failures, adv, own_gen, raise_error)


def _visibility(fj, judged, names, all_names, col, S, FDtol, fig, failures) -> np.ndarray:
    """Stage 1 of :func:`check_generator`: no required fault is rounding noise in its row and no
    row is numerically zero; returns each judged group's normalising scale (1 / its weakest
    required fault gain) and adds to ``fig`` and ``failures``."""
    # 1. no rounding noise, then the normalisation (Varga: unit minimum fault gain per row)
    scales = np.ones(len(judged))
    vis = []
    for i in range(len(judged)):
        req = [col[j] for j in range(len(names)) if S[i, j]]
        if not req:
            continue
        gains = fj["peaks"]["f"][i, req]
        cos = fj["cosine"][i, req]
        vis.append(float(np.min(cos)))
        qpk, bound = fj["peaks"]["Q"][i], fj["peaks"]["bound"][i]
        low = float(np.min(gains))
        if not (np.isfinite(bound) and bound > ZERO_TOL and np.isfinite(low) and low > 0):
            failures.append(("zero", f"residual {i + 1}: the row is numerically zero (peak gain {qpk:.3g}, "
                                     f"peak ||Q_i|| ||Ge|| = {bound:.3g} ≤ {ZERO_TOL:g}, weakest required fault "
                                     f"gain {low:.3g}): nothing to normalise"))
            continue
        for j, c in zip(req, cos):
            if not c >= FDtol:
                failures.append(("visibility", f"residual {i + 1}: fault '{all_names[j]}' has relative gain "
                                               f"{c:.3g} < FDtol = {FDtol:.3g}"))
        scales[i] = 1.0 / low
    fig["fault_visibility"] = min(vis, default=float("inf"))
    return scales


def _stability(model, Q, smarg, fig, failures, decisions=None) -> None:
    """Stage 2 of :func:`check_generator`: stability with margin of Q's realisation, then R's own
    poles (the plant modes it keeps; ``decisions``: :func:`mode_decisions`); adds to ``fig`` and ``failures``."""
    # 2. stability with margin: Q's realisation, then R's own poles (plant modes it keeps)
    worst_of = (lambda p: float(np.max(np.abs(p)))) if model.dt else (lambda p: float(np.max(p.real)))
    what = "largest |pole|" if model.dt else "largest Re(pole)"
    if Q.n:
        poles = Q.poles()
        fig["pole_extreme"] = worst_of(poles)
        if np.any(outside_margin(poles, model.dt, smarg)):
            failures.append(("stability", f"filter: {what} = {fig['pole_extreme']:.6g} > the stability margin "
                                          f"smarg = {smarg:.6g}"))
    try:
        rp, why = _r_poles(model, Q, smarg, decisions)
    except (np.linalg.LinAlgError, ValueError) as exc:
        rp, why = np.zeros(0, complex), []
        failures.append(("R stability", f"the poles of R = Q·Ge cannot be decided ({exc})"))
    fig["R_poles"] = [complex(z) for z in rp]
    if rp.size:
        failures.append(("R stability", f"R = Q·Ge keeps the plant pole(s) {_fmt(rp)} ({what} = {worst_of(rp):.6g} "
                                        f"> smarg = {smarg:.6g})" + (": " + "; ".join(why[:3]) if why else "")
                                        + (f"; … {len(why) - 3} more" if len(why) > 3 else "")))


def _decoupling(model, fj, judged, names, col, S, decouple, dec_tol, fig, failures) -> None:
    """Stage 3 of :func:`check_generator`: decoupling and structure, absolute on the normalised
    form; adds to ``fig`` and ``failures``."""
    # 3. decoupling and structure, absolute on the normalised form
    labels = [g for g in decouple if model.group_slices()[g].stop > model.group_slices()[g].start]
    pk = fj["peaks"]
    decs, errs, sens, zero_leaks, zero_errs, zero_sens, low_gain = [], [], [], [], [], [], []
    for i in range(len(judged)):
        d = max((pk[g][i] for g in labels), default=0.0)
        # each block's error bound (:func:`_decoupled_reading`; 0 where the plain reading was far from any decision),
        # reported beside the reading; the verdict is the reading's: the worst-case bound can exceed a true leak
        # (tests/test_synthesis_random.py's non-normal plant, eigenvector condition 2.8e8: a leak > 2.5e-6 read 2.4e-5
        # with a bound above that), so "above only where provably so" would pass it
        kinds = {"ud" if g in ("u", "d") else g for g in labels}
        e = max((float(pk[k + "_error"][i]) for k in kinds), default=0.0)
        decs.append(d)
        errs.append(e)
        sens.append(max((float(pk[k + "_sensitivity"][i]) for k in kinds), default=0.0))
        if not d <= dec_tol:
            failures.append(("decoupling", f"residual {i + 1}: {'+'.join(labels)} leak {d:.3g} (± {e:.2g}) × the "
                                           f"weakest fault gain > dec_tol = {dec_tol:.3g}"))
        zl, ze, zs = 0.0, 0.0, 0.0
        for j, nm in enumerate(names):
            v = pk["f"][i, col[j]]
            if S[i, j]:
                low_gain.append(v)
            else:
                ej = float(pk["f_error"][i, col[j]])
                zl, ze, zs = max(zl, v), max(ze, ej), max(zs, float(pk["f_sensitivity"][i, col[j]]))
                if not v <= dec_tol:
                    failures.append(("structure", f"residual {i + 1}: fault '{nm}' must be decoupled (S = 0) but "
                                                  f"leaks {v:.3g} (± {ej:.2g}) × the weakest required fault gain > "
                                                  f"dec_tol = {dec_tol:.3g}"))
        zero_leaks.append(zl)
        zero_errs.append(ze)
        zero_sens.append(zs)
    fig.update({"decoupling": max(decs, default=0.0), "decoupling_error": max(errs, default=0.0),
                "decoupling_sensitivity": max(sens, default=0.0), "decoupling_rows": decs, "decoupling_row_errors": errs,
                "decoupling_row_sensitivities": sens,
                "structure_leak": max(zero_leaks, default=0.0), "structure_leak_error": max(zero_errs, default=0.0),
                "structure_leak_sensitivity": max(zero_sens, default=0.0),
                "fault_gain": min(low_gain, default=float("inf")),
                "filter_peak_gain": float(np.max(fj["peaks"]["Q"], initial=0.0))})
    if not (np.isfinite(fig["filter_peak_gain"]) and fig["filter_peak_gain"] > 0):
        failures.append(("zero", f"the returned filter's peak gain is {fig['filter_peak_gain']:.3g}"))


def _strong_visibility(fs, judged, names, col, S, freqs, FDGainTol, fig, failures) -> None:
    """Stage 4 of :func:`check_generator`: strong visibility at ``freqs`` on the normalised rows (``fs``: their
    gains there, :func:`internal_figures`' ``at_freqs``); adds to ``fig`` and ``failures``."""
    # 4. strong visibility at freqs on the normalised rows
    if freqs is not None:
        strong = []
        for i in range(len(judged)):
            for j, nm in enumerate(names):
                if not S[i, j]:
                    continue
                for k, w in enumerate(np.atleast_1d(np.asarray(freqs, float))):
                    v = float(fs[k, i, col[j]])
                    strong.append(v)
                    if not v >= FDGainTol:
                        failures.append(("strong", f"residual {i + 1}: fault '{nm}' has gain {v:.3g} (unit-gain "
                                                   f"row) at ω = {w:g} rad/s < FDGainTol = {FDGainTol:.3g}"))
        fig["strong_gain_ratio"] = min(strong, default=float("inf"))


@single_blas_thread  # as the designs: small matrices, where threaded BLAS spin-waits on a loaded machine
def report(gen, freqs=None, FDGainTol: float = 0.01, dec_tol: float = DEC_TOL, groups=None) -> dict:
    """What the judge reads off a generator as it is (no scaling), per ``groups`` (default ``gen.groups``):
    ``leakage = max_i max(||Ru,i||, ||Rd,i||)`` (grid peaks), the weak structure matrix
    ``peak ||R_fj,i|| > dec_tol`` (absolute, on a design's unit-gain rows) and, with ``freqs``,
    the strong one ``||R_fj,i(jω)|| ≥ FDGainTol`` at every ω. :func:`fmu_fdi.analysis.leakage`
    and :func:`fmu_fdi.analysis.structure_matrix` return these numbers."""
    return _reported(_internal_figures(gen, groups, freqs), gen, freqs, FDGainTol, dec_tol)


def _reported(fj: dict, gen, freqs, FDGainTol: float, dec_tol: float) -> dict:
    """:func:`report`'s figures from :func:`internal_figures`' ``fj`` of ``gen`` (its groups, ``freqs``)."""
    if not fj["finite"]:
        raise DesignError(f"{gen.method} generator cannot be evaluated on the frequency grid (NaN/Inf)")
    pk = fj["peaks"]
    out = {"leakage": float(max(np.max(pk["u"], initial=0.0), np.max(pk["d"], initial=0.0))),
           "structure_matrix": (pk["f"] > dec_tol).astype(int).tolist(), "peaks": pk}
    if freqs is not None:
        out["strong_structure_matrix"] = np.all(fj["at_freqs"] >= FDGainTol, axis=0).astype(int).tolist()
    return out


def _fmt(z: np.ndarray) -> str:
    return "[" + ", ".join(f"{complex(x).real:.4g}{complex(x).imag:+.4g}j" if abs(complex(x).imag) > 0
                           else f"{complex(x).real:.4g}" for x in z[:6]) + (", ..." if z.size > 6 else "") + "]"


def _finish(fig: dict, failures, adv: dict, gen, raise_error: bool) -> dict:
    if failures and raise_error:
        kinds = list(dict.fromkeys(k for k, _ in failures))
        shown = [m for _, m in failures[:6]] + ([f"... {len(failures) - 6} more"] if len(failures) > 6 else [])
        numerical = {"decoupling", "structure", "stability", "finite", "R stability"}
        cls = NumericalDesignError if set(kinds) & numerical else DesignError
        exc = cls(f"{gen.method} design fails its post-conditions ({', '.join(kinds)}): " + "; ".join(shown)
                  + ". " + " ".join(f"[{k}] {adv[k]}." for k in kinds))
        exc.conditions = kinds  # the failed conditions, for a caller deciding by them (nullspace._approximate_pencil)
        raise exc
    if failures:
        fig["failures"] = [m for _, m in failures]
        fig["failed_conditions"] = [k for k, _ in failures]  # the condition of each failure, in order
    gen.info["postconditions"] = fig
    return fig
