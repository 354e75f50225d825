"""The plant's modes on or beyond the stability boundary: one table for the judge and the factoriser (issue 17).

The judge (:mod:`.postconditions`: which plant modes a row cancels, to what rounding, and which are poles of R) and
the stable factoriser (:mod:`.stable_factor`: which plant modes of the internal form ``[Q R]`` to move, and where
M's zeros go) locate the same modes — the eigenvalues of the plant ``Ge = [Gu Gd Gw Gf; I 0 0 0]`` outside the
margin — in the ordered Schur form of one realisation, the balanced one (SLICOT TB01ID on the whole ``Ge``,
:func:`balanced_plant`). Both read them here, so a mode the factoriser moves is, to the last bit, the mode the
judge then tests: two balancings (the factoriser's of the w and f columns only, the judge's of all of Ge) put
random seed 3's unstable mode at 1.1051709180756502 and …464, and M's zero 3.8e-15 from the judge's p read as a
residue of 3.8e-15 times the row's slope.

- :func:`balanced_plant`: the realisation ``(A, B, Ce, De)``;
- :func:`leading_schur`: its ordered Schur form with chosen eigenvalues first (complex, or real as
  :func:`fmu_fdi.linalg.ordered_schur`);
- :func:`boundary_mode_table`: per simple mode outside the default margin (and, for the judge, those inside it within
  the grid's gap of the boundary, :func:`beside_boundary`), what the judge tests it by;
- :func:`user_margin_table`: the stable modes a user ``smarg`` tighter than the default forbids beyond that gap,
  decided by the same tests for the poles of R (the judge and the factoriser alike); :func:`merged_tables`.

Reference: A. Varga, *Solving Fault Diagnosis Problems*, Springer 2017, sec. 5.1 (the stability of the internal
form) and 7.6 (the left coprime factorisation moving the plant's poles); Golub & Van Loan, *Matrix
Computations*, 4th ed., sec. 7.2 (eigenvalue and eigenvector perturbation).
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla

from ...linalg import EPS, ordered_schur
from ...lti import LTI
from ...margin import default_smarg, outside_margin

#: GVL's constant in the non-asymptotic eigenvector bound ``||δv|| ≤ 4 ||E|| / sep`` (valid for ``||E|| ≤ sep/5``;
#: Golub & Van Loan, *Matrix Computations*, 4th ed., Thm. 7.2.4); :func:`.postconditions._without_cancelled_modes`
EIGVEC_BOUND = 4.0

#: the judge reads no point closer than this, relative to ``max(1, ||A||)`` of the balanced realisation, to a pole of
#: the plant or the filter on (or beyond) the stability boundary, nor to a plant pole inside the margin but within
#: this gap of the boundary that the row cancels (:func:`.postconditions._beside_boundary_poles`, :func:`beside_boundary`)
BOUNDARY_GAP = 1e-6


def boundary_gap(A: np.ndarray) -> float:
    """``BOUNDARY_GAP·max(1, ||A||_2)``: the judge's distance to a boundary pole of a (balanced) realisation with A."""
    return BOUNDARY_GAP * max(1.0, float(np.linalg.norm(A, 2))) if A.size else BOUNDARY_GAP


def beside_boundary(ev: np.ndarray, dt: float, gap: float) -> np.ndarray:
    """Mask of the eigenvalues ``ev`` inside the default margin (stable) but within ``gap`` of the stability boundary:
    ``|Re p| ≤ gap`` (continuous) or ``1 − |p| ≤ gap`` (discrete) — the poles the judge's grid can come within the gap
    of although they are no boundary poles. A row that cancels such a mode to rounding reads its residue ρ as ``ρ/δ``
    at the distance δ the grid comes (δ → the margin as the pole nears it), then, across the margin, not at all (the
    mode removed, the grid kept ``gap`` away): the judge treats them as it treats the boundary poles
    (:func:`boundary_mode_table` with ``beside=True``)."""
    ev = np.asarray(ev)
    dist = (1.0 - np.abs(ev)) if dt else -ev.real
    return ~outside_margin(ev, dt, default_smarg(dt)) & (dist <= gap)


def balanced_plant(model) -> LTI:
    """``Ge = [Gu Gd Gw Gf; I 0 0 0]`` (:meth:`FDIModel.augmented`) balanced by a diagonal similarity (TB01ID): the
    one realisation whose eigenvalues and Schur vectors the judge and the factoriser use."""
    G = model.augmented()
    return G.balanced()[0] if G.n and G.m and G.p else G


def leading_schur(A: np.ndarray, select, real: bool = False) -> tuple[np.ndarray, np.ndarray, int]:
    """``(T, U, k)``: Schur form ``A = U T Uᴴ`` with the k eigenvalues ``select(λ)`` accepts leading.

    Complex (LAPACK ``gees`` with its sort) by default; ``real=True`` the real form of
    :func:`fmu_fdi.linalg.ordered_schur` (membership decided once, pairs kept together), ``select`` then called with
    the complex eigenvalue of the block."""
    if real:
        return ordered_schur(A, lambda re, im: bool(select(complex(re, im))))
    return sla.schur(np.asarray(A).astype(complex), output="complex", sort=select)


def boundary_mode_table(model, beside: bool = False, smarg: float | None = None,
                        only_user: bool = False) -> dict | None:
    """The simple plant modes on or beyond the stability boundary whose cancellation the judge can decide, with
    what :func:`.postconditions._without_cancelled_modes` tests them by (None when there are none).

    ``beside``: also the stable modes within the gap of the boundary (:func:`beside_boundary`, ``gap`` =
    :func:`boundary_gap` of the balanced A), decided by the same tests — the judge's table
    (:func:`.postconditions.mode_decisions`), so that a pole reads the same on both sides of the margin; the
    factoriser and the refinement (:mod:`.stable_factor`, :mod:`.refine`) move and cancel only the modes outside
    the margin and read the default table. ``outside``: per mode, whether it violates the default margin; ``gap``.

    ``smarg``: also every simple stable mode that breaks this (user) margin, wherever it lies — the table of the
    poles of R with the user's margin (:func:`user_margin_table`); ``only_user``: only those the default table
    with ``beside`` does not hold.

    Balanced ``Ge = (A, B, Ce, De)`` (:func:`balanced_plant`); for each simple eigenvalue p outside the default
    margin with ``sep_p = σ_min(T22 − pI)`` of the ordered Schur form ``[p t; 0 T22]`` (:func:`leading_schur`):
    ``dirs`` ``c_p = Ce v_p`` (unit right eigenvector), ``seps``, ``conds`` (``||[1 z]|| = 1/|y_pᴴ v_p|``, the
    eigenvalue's condition), and per input column c of Ge whether the column *excites* p: with the unit left
    eigenvector ``y_p`` (``[1 z]`` in Schur coordinates, ``p z − z T22 = t``), the coupling ``|y_pᴴ b_c|``
    (``coupling``) against its rounding ``δ_c = n·eps·(4||A||/sep_p + 1)·||b_c||`` (``coupling_tol``) — the
    perturbation theorem of the row test (:data:`EIGVEC_BOUND`) applied to the left eigenvector of ``A + E``,
    ``||E|| ≤ n·eps·||A||``, plus the rounding of the product. A column at or below ``δ_c`` does not excite p as far
    as the data can tell (``unexcited``; the u, d and w of the random set's fault-only modes: 1e-14 … 1e-13 of
    ``||b_c||`` against ``δ_c`` ≈ 4e-12; random seeds 73 and 111 read a leak 7.9e-7 and a pole of R from that
    rounding), and p is removed from that column of R. Where the bound is void (``n·eps·||A|| > sep_p/5``) the mode
    is left alone. ``delta_c``: δ_c on the unnormalised left vector ``[1 z]``."""
    if not model.n:
        return None
    bal = balanced_plant(model)
    A, Bp, Ce, De = bal.A, bal.B, bal.C, bal.D
    n = A.shape[0]
    ev = np.linalg.eigvals(A)
    gap = boundary_gap(A)
    out_m = outside_margin(ev, model.dt, default_smarg(model.dt))
    base = out_m | beside_boundary(ev, model.dt, gap) if beside else out_m
    user = outside_margin(ev, model.dt, smarg) if smarg is not None else np.zeros(ev.size, bool)
    cand = np.flatnonzero((user & ~base) if only_user else (base | user))
    if not cand.size:
        return None
    nA, nC = float(np.linalg.norm(A, 2)), float(np.linalg.norm(Ce, 2))  # ||A||, not max(1, ·): scale-free
    near = lambda x, y: bool(abs(x - y) <= 1e-8 * max(1.0, abs(y)))  # noqa: E731
    nb = np.linalg.norm(Bp, axis=0)
    poles, dirs, seps, unexcited, delta_c, couplings, coupling_tol, conds = [], [], [], [], [], [], [], []
    for j in cand:
        T, U, k = leading_schur(A, lambda x: near(x, ev[j]))
        if k != 1:
            continue  # repeated (a Jordan block, or a cluster within 1e-8): not decided here
        # n = 1: the eigen-directions are exact (sep = ∞, the first terms of δ_i and δ_c vanish)
        sep = float(np.linalg.svd(T[1:, 1:] - ev[j] * np.eye(n - 1), compute_uv=False)[-1]) if n > 1 else np.inf
        if n * EPS * nA > sep / 5:
            continue
        z = np.linalg.solve((ev[j] * np.eye(n - 1) - T[1:, 1:]).T, T[0, 1:]) if n > 1 else np.zeros(0)
        Bt = U.conj().T @ Bp
        cond = float(np.sqrt(1.0 + float(np.linalg.norm(z)) ** 2))
        coupling = np.abs(Bt[0] + z @ Bt[1:]) / cond
        d_c = n * EPS * (EIGVEC_BOUND * nA / sep + 1.0) * nb
        unexcited.append(coupling <= d_c)
        couplings.append(coupling); coupling_tol.append(d_c); conds.append(cond)
        delta_c.append(d_c * cond)  # on [1 z]: the coupling B̃1 of _without_cancelled_modes' pole part
        poles.append(ev[j]); dirs.append(Ce @ _refined_eigenvector(A, ev[j], U[:, 0])); seps.append(sep)
    if not poles:
        return None
    return {"A": A, "B": Bp, "Ce": Ce, "De": De, "nA": nA, "nC": nC, "poles": np.array(poles), "dirs": dirs,
            "seps": seps, "unexcited": np.array(unexcited), "delta_c": np.array(delta_c), "coupled": nb > 0,
            "coupling": np.array(couplings), "coupling_tol": np.array(coupling_tol), "conds": np.array(conds),
            "outside": outside_margin(np.array(poles), model.dt, default_smarg(model.dt)), "gap": gap}


def _refined_eigenvector(A: np.ndarray, p: complex, v: np.ndarray) -> np.ndarray:
    """The unit eigenvector ``v_p`` after one step of inverse iteration from the Schur vector ``v``:
    ``(A − pI) x = v``, ``v_p = x/||x||`` (Golub & Van Loan, *Matrix Computations*, 4th ed., sec. 7.6.1). The Schur
    vector is accurate normwise (``eps·||A||/sep``) but the complex QR iterations spread that error over every
    component: CS1's integrator (p = −9.8e-17) read components of 1e-13 … 2.4e-12 where the eigenvector has 1e-16 …
    8.6e-15, and a refinement that made R cancel the mode along that direction could not also keep the u, d
    decoupling beside it (CS1_1 row 1 leaked 7.0e-7 > dec_tol). The solve with the nearly singular ``A − pI``
    amplifies exactly the eigen-direction, so the step leaves the error of a backward-stable solve, ``eps`` times
    the eigenvector's condition, in each component. Kept only if its residual ``||(A − pI) v_p||`` is not larger."""
    M = A - p * np.eye(A.shape[0])
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", sla.LinAlgWarning)  # A − pI is singular to working precision: wanted
            x = sla.solve(M, v.astype(complex), check_finite=False)
    except (np.linalg.LinAlgError, ValueError):
        return v
    nx = float(np.linalg.norm(x))
    if not np.isfinite(nx) or nx == 0.0:
        return v
    x = x / nx
    x = x * (np.vdot(x, v) / abs(np.vdot(x, v))) if abs(np.vdot(x, v)) > 0 else x  # v's phase
    return x if np.linalg.norm(M @ x) <= np.linalg.norm(M @ v) else v


def user_margin_table(model, smarg: float) -> dict | None:
    """The simple plant modes a user margin ``smarg`` tighter than the default makes poles of R that the judge's table
    (:func:`boundary_mode_table` with ``beside``) does not hold: stable modes with ``smarg < Re p`` (``|p|``) that lie
    farther than the grid's gap from the boundary — with the same entries and tests (δ_c per column; the row's δ_i
    is :func:`.postconditions.mode_decisions`'). None when there are none (always with the default margin or a
    looser one). Read for the poles of R only, by the judge (:func:`.postconditions.user_margin_decisions`) and
    the factoriser (:func:`.stable_factor._judged_plant_poles`), so that every mode the user's margin forbids is
    decided by one rule, its residue against the derived rounding, whatever its distance to the boundary: the
    staircase's fixed :data:`~fmu_fdi.margin.R_POLE_TOL` of the data read a fault coupled at 1e-10 of its column
    to s = −1e-4 as none, while the same coupling at −1e-6 (inside the gap) was moved
    (tests/test_judge_beside_smarg.py). The grid and the figures do not read these modes: the grid never comes
    within the gap of them (``|Re p|`` > gap), so what the user's residual shows beside them is read as it runs,
    and ``leakage()`` stays independent of ``smarg``."""
    if smarg is None or not model.n or float(smarg) >= default_smarg(model.dt):
        return None  # a margin no tighter than the default forbids no mode the default table lacks (no work)
    return boundary_mode_table(model, beside=True, smarg=smarg, only_user=True)


def merged_tables(a: dict | None, b: dict | None) -> dict | None:
    """Two mode tables of the same plant (:func:`boundary_mode_table`) as one: the per-mode entries of ``b`` after
    those of ``a``; None when both are."""
    if a is None or b is None:
        return a if b is None else b
    out = dict(a)
    for key in ("poles", "unexcited", "delta_c", "coupling", "coupling_tol", "conds", "outside"):
        out[key] = np.concatenate([a[key], b[key]])
    for key in ("dirs", "seps"):
        out[key] = list(a[key]) + list(b[key])
    return out
