"""Approximate model matching (AMMP): the residual generator whose fault response is nearest a reference.

Find a stable proper ``Q`` that decouples u and d exactly and minimises

    γ = || Q(λ) [Gf Gw; 0 0](λ) − [Mr(λ) 0] ||,     Q(λ) [Gu Gd; I 0](λ) = 0,        (1)

in the H∞ or the H2 norm (Varga 2017, sec. 5.7, Procedure AMMS; FaultDetectionTools.jl
``ammsyn``). The steps:

1. a proper stable left null-space basis ``Q0`` of ``[Gu Gd; I 0]`` — without d,
   ``[I  −Gu]`` when Gu is stable (``Q = [X  −X Gu]`` is stable iff X is) and the left
   coprime factor ``[M̂  −N̂]`` of an observer otherwise (every admissible Q is then
   ``Y Q0`` with ``Y ∈ RH∞``); with d, the full minimal basis of
   :func:`~fmu_fdi.design.problems.nullspace.nullspace_design` (the options ``nullspace``,
   ``simple`` and ``HDesign`` choose another basis, or ``H·Q0``); the reduced system is
   ``G1 = Q0 [Gf Gw; 0 0]`` and (1) becomes ``min_{Y ∈ RH∞} ||Y G1 − F||``, ``F = [Mr 0]``;
2. zeros of ``G1`` at infinity (a strictly proper plant gives them) make (1) *non-standard*:
   its infimum is approached only by improper Y. Silverman's structure algorithm
   (:func:`interactor`) compresses the rows of the feedthrough by an orthogonal ``T_j`` and
   multiplies the rows with zero feedthrough by ``n = 1/m``, ``m(s) = a/(s + a)``
   (``a = −sdeg``; ``m = 1/z`` in discrete time), until the feedthrough has full row rank:
   ``Φ G1 = m^K Ĝ`` with ``Φ = Π diag(m I, I) T_j`` stable and proper and ``Ĝ`` standard,
   and ``γopt0 = min_Ŷ ||Ŷ Ĝ − F||`` is the infimum of (1). The stable proper filter
   ``Q = Ŷ Φ Q0`` then matches the updated reference ``M Mr`` with the diagonal updating
   factor ``M = m^K I`` — or, where the rows of the improper optimum ``Ŷ Φ Q0 / m^K`` have different
   orders of infinite poles ``k_i``, ``M = diag(m^{k_i})``, each row's least (:func:`row_shifts`; the
   peer builds M from the ``glcf`` of each row) — (Varga's ``M``, normalised to unit DC gain, or to unit zpk gain with
   ``normalize='gain'``; in discrete time M is the all-pass delay ``z^{−K}``, so
   ``γsub = γopt0`` in H∞; with ``poles`` or a discrete ``sdeg`` M has those poles,
   :func:`placed_factor`): ``Q G1 − M F = M (Ŷ Ĝ − F)``, whose norm is ``γsub`` (Varga's
   ``gammasub``); ``γopt = min_Ŷ ||Ŷ Ĝ − M F||`` is the optimum of the updated problem
   (``gammaopt``, a lower bound of ``γsub``). Rows of ``Q0`` that see neither faults nor
   noise (``G1`` of normal rank ρ below its rows, e.g. more basis rows than fault and noise
   directions) are dropped where they are identically zero; those that no shift separates
   once the feedthrough has rank ρ get fictitious noise ε (the smallest of 1e-6 … 1e-3
   ``||Ĝ||∞`` that SLICOT solves; ``info['regularisation_eps']``), so ``γopt0`` is then the
   optimum of the regularised problem, above the infimum by O(ε ||Y||);
3. the standard problem ``min_{Y ∈ RH∞} ||Y Ĝ − F||`` is the model-matching form of the
   general control problem with ``P = [−F  I; Ĝ  0]`` (open-loop stable, ``P22 = 0``, so a
   controller is internally stabilising iff it is stable). H∞: γ-iteration by bisection
   on the solvability of the two Riccati equations of Glover and Doyle (1988) (SLICOT
   SB10FD, SB10DD in discrete time; every level above ``||F||∞`` is feasible, Y = 0 meeting it); the
   central controller of least measured error is Y, within the bisection tolerance of
   the highest infeasible level (half of ``reltol``, :func:`iteration_reltol`: the stages after it
   have the other half — each held to the one limit ``γ_lo (1 + reltol)``, :class:`ErrorBudget`).
   H2: the optimal controller (SLICOT SB10HD) after removing the feedthrough with
   ``Y0 = D_F D̂⁺`` (finite H2 norm needs ``D_F (I − D̂⁺ D̂) = 0``; when it fails the
   reference is first updated by the low-pass ``m``, which becomes a factor of M, as in
   ``ammsyn``; ``info['reference_lowpass']``); in discrete time the
   Kalman filter estimating ``F v`` from ``Ĝ v`` (:func:`_h2_discrete`); H2 optimal, exact.

This is Varga's Procedure AMMS with the Nehari/least-distance step (quasi-co-outer–co-inner
factorisation, 2-block γ-iteration) replaced by the equivalent standard H∞/H2 problem on
the regularised reduced system, which SLICOT solves with orthogonal (Schur) Riccati
solvers. The optimum does not depend on the basis Q0: ``Q0`` spans every admissible filter.

Before it returns, the error response of the returned filter, ``Q(λ) [Gf Gw; 0 0](λ) −
M(λ) [Mr 0](λ)``, is compared point by point with the designed ``M (Ŷ Ĝ − F)`` (every
factor evaluated from its own balanced realisation: norms of the product realisations,
with near-cancelling modes, lost every digit on nearly exact matches); a difference above the
rounding bound of that comparison (each factor's componentwise GEPP bound times the other factors'
gains, :func:`_evaluation_rounding`), or above 1e-3 of the error's size, is refused — unless the realisation's own
error is the designed one's within ``reltol`` (the factors' construction errors, which no evaluation bound covers:
:func:`_shipped_filter`). ``error``/``gamma_sub`` are the H∞ peak of that
response on a refined grid (H2: Gauss–Legendre quadrature).

**Least order** (``mindeg=True``, as ``ammsyn(…; mindeg = true)``, which solves the approximate
equation with ``glasol(…; mindeg = true)``). The error depends on Q only through
``R = Q [Gu Gd Gf Gw; I 0 0 0] = [0 0 Rf Rw]``: every filter of the affine set
``Q + Z Nl`` (``Nl`` a left null-space basis of the whole ``Ge = [Gu Gd Gf Gw; I 0 0 0]``) has the
same error. After the optimal Q is found, each row is replaced by the least-order stable proper
solution ``Q_i'`` of the linear rational equation

    Q_i'(λ) Ge(λ) = [0  0  Rf_i(λ)  Rw_i(λ)],                                              (2)

the minimum-degree solution of ``glasol``/``glsol`` with ``mindeg = true`` (Varga 2017, sec. 5.7,
Procedure AMMS with the least-order option; the peer finds it as ``X0 + Z XN``, ``XN`` a left
null-space basis of Ge, by a Type 2 minimum dynamic cover, sec. 7.9 and 10.4.2). Candidates per row:
``Q_i + Y N`` with ``N`` the pencil basis of the whole Ge and Y from Type 2 minimum dynamic covers
(:func:`~fmu_fdi.design.toolkit.covers.left_cover2`) — the same fault and noise response by
construction, without forming a reference — at a few relative rank tolerances (``MINDEG_RTOLS``: the
optimal rows carry modes that cancel only to the filter's accuracy), and the least-order exact solve
of (2) from the reference ``Q_i [Gf Gw]`` (:func:`~fmu_fdi.design.problems.matching.model_matching`
on the model whose faults are ``[f w]``: it reaches rows built on another basis than N, which the
compound ``[Q_i; N]`` does not). Each candidate's numerator is refitted to ``Q_i Ge`` on the design's
points, its near-cancelled modes (Hankel singular values below ``HANKEL_RTOL`` of its largest) are
truncated as a further candidate, and a candidate with more significant modes than the row is
dropped. Stable candidates are taken, lowest order first (all rows at once, then row by row), only if
the filter passes its post-conditions and its re-measured error is no worse than the optimal one
within ``reltol`` (``info['mindeg']`` says what was done, and why not when a row cannot be lowered:
already least order, an unstable least-order row, a refused candidate).

**References no filter approaches** (refused). At every point λ of the closed right half plane (``|z| ≥ 1``) the
admissible responses ``Y G1(λ)`` lie in the row space of ``G1(λ)``, so every admissible H∞ error is at least the
distance ``||F(λ) (I − P_{G1(λ)})||`` of ``F(λ) = [Mr 0](λ)`` to it (maximum modulus off the axis), and at least
``σ_{r+1}(Mr(λ))``, r the normal rank of ``Q0 [Gf; 0]`` (Weyl); where the supremum of these reaches ``||Mr||∞`` —
Q = 0's error: ``Mr = I`` on more faults than the decoupled residuals reach, ``Mr = [I_r 0]`` whose fault columns the
admissible response loses at an unstable or marginal fault-only plant mode — the optimum is the zero filter, no fault
detection filter, and the design is refused before the γ-iteration with the reading and both figures
(:func:`_unapproachable_reference`; in H2 only for r = 0, the H2 rank bound being below ``||Mr||₂`` otherwise); the
γ-iteration's certified lower bound reaching ``||[Mr 0]||∞`` is refused too (:func:`_certified_at_zero_filter`).

Not covered: zeros of ``G1`` on the imaginary axis / unit circle (the optimum is not
attained by a stable filter): refused with a :class:`~fmu_fdi.errors.DesignError` that
names them.

References
----------
A. Varga, *Solving Fault Diagnosis Problems*, Springer 2017, sec. 5.7 (Procedure AMMS),
Examples 5.14–5.17. A. Varga, Integrated computational algorithm for solving H∞-optimal
FDI problems, IFAC World Congress 2011. K. Glover and J. C. Doyle, State-space formulae for
all stabilizing controllers that satisfy an H∞-norm bound, Systems & Control Letters 11,
1988. K. Zhou, J. C. Doyle and K. Glover, *Robust and Optimal Control*, 1996, chs. 14, 17.
A. Varga, Reliable algorithms for computing minimal dynamic covers, IEEE CDC 2003 (least order,
``mindeg``); DescriptorSystems.jl ``glasol``/``glsol`` and FaultDetectionTools.jl ``ammsyn``.
"""
from __future__ import annotations

from dataclasses import dataclass

import warnings

import numpy as np
import scipy.linalg as sla
from slycot.exceptions import SlycotError

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import EPS, default_rtol, single_blas_thread
from ...lti import HINF_RTOL, LTI, blockdiag, frequency_grid, hstack, vstack
from ...model import FDIModel
from ..toolkit._basis import check_poles, pick_poles
from ..toolkit.approximate import drop_negligible_unstable_modes, transmission_zeros
from ..toolkit.postconditions import (DEC_TOL, _eval_points, _nrm, _resonances, row_system, _values,
                                      check_generator, resolvent_pair)
from ..toolkit.notes import keeps_notes, note, silenced
from .reference import reference


@keeps_notes
@single_blas_thread
def approximate_model_matching(model: FDIModel, Mr, *, norm: str = "inf", sdeg: float | None = None,
                               normalize: str = "dcgain", reltol: float = 1e-4, smarg: float | None = None,
                               dec_tol: float = DEC_TOL, atol: float = 0.0, mindeg: bool = False, poles=None,
                               HDesign=None, simple: bool = False,
                               nullspace: bool | None = None) -> ResidualGenerator:
    """H∞ or H2 optimal approximate model matching: ``min ||Q [Gf Gw; 0 0] − [Mr 0]||`` with ``Q [Gu Gd; I 0] = 0``.

    Parameters
    ----------
    model : FDIModel
    Mr : LTI, python-control system or array_like
        Reference fault-to-residual map (residuals × fault columns), proper and stable; a
        matrix is a constant reference.
    norm : {'inf', '2'}
        H∞ (default) or H2 norm of the model-matching error (noise response included).
    sdeg : float, optional
        Pole of the updating factor ``M`` used when the reduced system has zeros at infinity
        (the filter's freely placed poles; FaultDetectionTools.jl ``ammsyn``'s ``sdeg``, which its
        ``glcf`` step assigns to the poles that replace the optimal filter's infinite ones):
        continuous time ``M = (a/(s + a))^K I``, ``sdeg = −a < 0`` (default −1); discrete time
        ``M = ((1 − ρ)/(z − ρ))^K I``, ``sdeg = ρ`` with ``|ρ| < 1`` (default 0: the delay
        ``z^{−K}``, all-pass, so ``γsub = γopt0`` in H∞). Also the pole of the H2 reference
        low-pass (``info['reference_lowpass']``), as the peer's ``Mib``. Refused (DesignError)
        outside the stability region.
    poles : array_like, optional
        Poles of the updating factor ``M`` (a conjugate-closed set in the stability region, within
        ``smarg``; FaultDetectionTools.jl ``ammsyn``'s ``poles``): its ``K`` poles are the given
        ones first (a complex pole with its conjugate), the rest at ``sdeg``
        (:func:`..toolkit._basis.pick_poles`); ``M = μ I``, ``μ = c/∏(λ − p_j)``. The filter is
        ``Q = μ Q∞``, ``Q∞`` the (improper) optimal filter, so its poles include every placed
        one; ``info['updating_poles']`` lists them. A standard problem (``K = 0``) has no free
        pole: the poles are then not used and a note says so, as are given poles beyond ``K``.
    normalize : {'dcgain', 'gain', 'infnorm'}
        ``M(0) = I`` (default; ``M(1) = I`` in discrete time; for real poles also ``||M||∞ = 1``),
        unit zpk gain ``1/∏(λ − p_j)`` (Varga's ``normalize = "gain"``) or ``||M||∞ = 1``
        (``"infnorm"``, the peer's default; it differs from ``"dcgain"`` only for complex or, in
        discrete time, negative poles).
    reltol : float
        Relative accuracy of the returned H∞ error (Varga's ``reltol``): the returned filter's measured error is
        at most ``base·(1 + reltol)`` (plus 1e-9 ``||M Mr||``), ``base`` the optimum the γ-iteration certified —
        its infeasible level in the standard H∞ problem, else the designed filter's error
        (:class:`ErrorBudget`, ``info['error_budget']``); every stage after the iteration (the shipped
        realisation, the corrections, the least-order rows) is held to that one limit, not to ``reltol`` of the
        stage before it. The γ-iteration takes half of it (:func:`iteration_reltol`: its best filter's measured
        error within ``1 + r_γ`` of its infeasible level, ``(1 + r_γ)² = 1 + reltol``), leaving the rest to the
        stages after it (a level above ``||M [Mr 0]||∞`` is never infeasible: Q = 0 meets it).
    nullspace : bool, optional
        The left null-space basis ``Q0`` of step 1 (FaultDetectionTools.jl ``ammsyn``'s
        ``nullspace``). None (default): chosen as the module docstring says — without d the
        full-order ``[I  −Gu]`` (Gu stable) or the observer-based ``[M̂  −N̂]``, with d the minimal
        proper basis. True: the minimal proper basis of
        :func:`~fmu_fdi.design.problems.nullspace.nullspace_design` (the peer's default) also
        without d. False: the full-order observer-based basis (the peer's ``nullspace = false``);
        it exists only without disturbance inputs (refused with d). Every choice spans all
        admissible filters, so the optimum is the same; the order and realisation of Q differ.
        ``info['nullspace_basis']`` is the basis used (LTI), ``info['basis']`` its kind.
    simple : bool
        A simple minimal basis (FaultDetectionTools.jl ``glnull(…; simple = true)``): basis row i of
        McMillan degree its left minimal index ν_i
        (:func:`~fmu_fdi.design.problems.hdesign.basis_rows`; ``info['basis_row_orders']``). It is a
        minimal basis too (no zeros), so the optimum does not change. Implies the minimal-basis
        path; refused with ``nullspace=False`` (an observer-based basis has no simple form).
    HDesign : array_like, optional
        A full-row-rank design matrix ``H`` with as many rows as Mr (the residuals) and at most
        ``k = p − rank Gd`` columns (fewer: the leading basis rows, as the peer): ``H·Q0`` is the
        annihilator instead of ``Q0`` (FaultDetectionTools.jl ``ammsyn``'s ``HDesign``), so every
        returned row lies in the span of the rows of ``H·Q0``: ``Q = Y H Q0`` with a square stable
        ``Y``. ``Q0`` is the basis ``nullspace``/``simple`` select; on the minimal-basis path it is
        the one :func:`~fmu_fdi.design.problems.nullspace.nullspace_design` multiplies by its own
        ``HDesign`` (:mod:`.hdesign`), so one ``H`` means the same in both. A restriction: the
        error is at least the optimum without it (equal for a square invertible H). Validated by
        :func:`~fmu_fdi.design.problems.hdesign.design_matrix`; ``info['HDesign']`` is the (padded) H.
    smarg, dec_tol : float, optional
        Stability margin and decoupling tolerance of the post-conditions (:mod:`..toolkit.postconditions`).
    atol : float
        Absolute rank tolerance (Varga's ``atol``), passed to the null-space basis
        (:func:`~fmu_fdi.design.problems.nullspace.nullspace_design`) and to the minimal realisations of
        Mr, of the reduced system and of the filter (SLICOT's default when 0).
    mindeg : bool
        Least-order synthesis (FaultDetectionTools.jl ``ammsyn``'s ``mindeg``): each row of the
        optimal filter is replaced by the least-order stable proper solution of
        ``Q_i Ge = [0 0 Rf_i Rw_i]`` (equation (2) of the module docstring), which has the same
        error; the McMillan degree of every row is then the least among the filters with this
        fault and noise response. Kept only if the error measured on the returned filter is the
        optimal one within ``reltol``. The total order can exceed that of the default filter when
        its rows share poles that the least-order rows do not.

    Returns
    -------
    ResidualGenerator
        ``info``: ``norm``, ``gamma_opt`` (optimum of the problem solved: (1) if standard,
        the updated problem with ``M Mr`` if not), ``gamma_opt0`` (infimum of (1)),
        ``gamma_sub`` and ``error`` (the error norm measured on the returned filter against
        ``M Mr``; equal to ``gamma_opt0`` in the standard case, within ``reltol`` for H∞),
        ``gamma_bracket`` (H∞: the bisection's last infeasible and feasible levels),
        ``updating_poles`` (the poles of M: K of the interactor, placed by ``poles``/``sdeg``, then
        the H2 low-pass's; of the row with most shifts), ``row_shifts`` (each row's k_i, all K unless
        the rows differ) and ``row_updating_poles`` (the poles of each M_i), ``basis`` (``'identity'``, ``'[I -Gu]'``, ``'observer'``, ``'minimal'``
        or ``'simple'``), ``nullspace_basis`` (``Q0``, LTI; ``H·Q0`` with ``HDesign``), ``HDesign``
        and ``basis_row_orders`` (with ``simple``),
        ``standard``, ``M`` (LTI, the identity if standard), ``interactor_steps`` (K),
        ``dropped_rows``, ``regularised_rows``, ``regularisation_eps``, ``reference_lowpass``
        (H2: Mr updated by ``a/(s + a)`` to make the H2 norm finite), ``order``, ``row_orders``
        (McMillan degree of each row), ``poles``, ``postconditions``, ``zero_filter_error`` (``||M [Mr 0]||``, the error of Q = 0: the returned error
        exceeds it only within ``reltol``, and a note then says so, :func:`_zero_filter_error`), ``rank_bound``
        (``rank``: the normal rank r of the admissible filters' fault response ``Q0 [Gf; 0]``, ``reference_rows``;
        H∞: ``bound``, a lower bound of every admissible error — the larger of the readings ``sup σ_{r+1}(Mr)``
        (``reading = 'rank'``) and the distance of ``[Mr 0]`` to the admissible responses at a point of the closed
        right half plane (``'distance'``), ``at`` its point —, ``zero_filter_error`` = ``||Mr||∞`` and the tolerance
        ``rtol`` of their comparison; :func:`_unapproachable_reference`), ``plant_mode_cancellation`` (the exact
        cancellation of the plant's boundary modes in R, :func:`_plant_mode_cancellation`), ``ud_redecoupling``
        (the u/d leak on the normalised form — rows at unit weakest required fault gain, a fault required where the
        row of Mr is nonzero — and, where it exceeded ``dec_tol``, the numerator's refit: ``refined``,
        ``leak_before``/``leak_after`` (the judge's reading plus the realisation's sensitivity, the worst row),
        ``row_leaks``, ``error_before``/``error_after``, ``realisation`` (of the kept candidate: ``'shipped'``,
        ``'minimal balanced'`` or ``'per row'`` with ``row_realisations``), ``reason``;
        :func:`_ud_redecoupling`);
        with ``mindeg=True``,
        ``mindeg``: ``{'lowered', 'reason', 'row_orders_before', 'row_orders', 'order_before',
        'order', 'error_before', 'error', 'error_limit', 'row_methods'}`` (``error_before``: the
        optimal filter's measured error; ``error_limit``: the design's one limit, ``info['error_budget']['limit']``
        (:class:`ErrorBudget`) — the least-order filter is returned only if its error is below it);
        where a filter was lowered also ``leak`` (its normalised u/d leak, read as ``ud_redecoupling`` reads it),
        ``plant_mode_cancellation`` and ``ud_redecoupling`` (the optimal filter's two corrections, run again on
        the lowered one: a lowered row is kept only if the lowered filter meets ``dec_tol``).

    Raises
    ------
    DesignError
        Mr of the wrong shape, sample time, unstable or improper; no residual decouples u
        and d; a reference no admissible filter approaches better than Q = 0 — H∞: the admissible fault response
        has normal rank r and ``sup σ_{r+1}(Mr) = ||Mr||∞``, or ``[Mr 0]`` is at distance ``||Mr||∞`` from the
        admissible responses at a point of the closed right half plane (:func:`_unapproachable_reference`; H2: only
        r = 0, the H2 rank bound being below ``||Mr||₂`` otherwise), or the γ-iteration certifies an infimum at
        ``||[Mr 0]||∞`` (:func:`_certified_at_zero_filter`) — naming the rank or the point, the bound and
        ``||Mr||∞``; zeros of the reduced
        system on the stability boundary; SLICOT's Riccati solvers failing at every level/regularisation; a returned
        filter whose error response is not the designed one (realisation accuracy: beyond the evaluation's rounding
        bound, and its own error above the designed one's by more than ``reltol``) or that fails its post-conditions,
        among them a u/d leak on the normalised form (rows at unit weakest required fault gain) above ``dec_tol`` as a
        double-precision evaluation of the returned realisation can show it — the judge's reading plus the realisation's
        sensitivity — where no refit or better-conditioned realisation meets it (:func:`_ud_leak_refused`: row, reading,
        sensitivity, that gain, dec_tol); a returned filter whose error
        exceeds ``info['error_budget']``'s limit (the certified optimum times ``1 + reltol``), or the zero
        filter's ``||M [Mr 0]||`` by more than ``reltol`` (:func:`_zero_filter_error`: both errors);
        an option's bad value,
        each naming it: ``HDesign`` (shape, rank,
        finiteness), ``nullspace = False`` with d, ``simple`` with ``nullspace = False``,
        ``poles``/``sdeg`` outside the stability region (``poles`` also outside ``smarg``).

    Notes
    -----
    Options of ``ammsyn`` not taken, and why: ``regmin`` — the peer first compresses the basis to
    ``rdim`` rows (a least-order selection by minimum dynamic covers with ``regmin = true``, plain
    rows without) and optimises only over their combinations; here ``Y`` acts on every basis row
    (rank-deficient rows dropped or regularised, step 2), so no selection is made, the optimum is
    over all admissible filters, and least order comes after the optimum from ``mindeg``. ``freq``
    (the random test frequency of that selection's admissibility check) has no selection to
    check; our solvability tests use fixed points. ``tcond`` only warns about the peer's
    non-orthogonal transformations (ours are orthogonal, :func:`interactor`), ``offset`` is our
    ``smarg`` default, ``fast`` (QR or SVD rank decisions) is always SVD here, ``atol1..3``/``rtol``
    are ``atol``; ``H2syn`` is ``norm='2'``.
    """
    _check_options(norm, normalize, reltol, atol, mindeg)
    _check_basis_options(nullspace, simple)
    Mr = reference(model, Mr, atol=atol)
    dt = model.dt
    sdeg = _check_placement(poles, sdeg, dt, smarg)
    Q0, G1, basis = reduced_system(model, atol, nullspace=nullspace, simple=simple, HDesign=HDesign, rows=Mr.p,
                                   smarg=smarg)
    Q0, G1 = stable_reduced_system(model, Q0, G1, smarg, atol)
    rank_bound = _unapproachable_reference(model, G1, Mr, norm, HDesign is not None)
    F = hstack([Mr, LTI.zero(Mr.p, model.nw, dt)]) if model.nw else Mr
    a = 1.0 if dt else -sdeg  # (discrete time: the interactor's shift is 1/z, M's pole sdeg is placed below)
    Gh, Phi, K, dropped, left = interactor(G1, a, atol)
    # continuous H2 with an error feedthrough no filter cancels (D_F outside the row space of
    # Ĝ's feedthrough): every error has infinite H2 norm. As Varga's ammsyn does, the reference
    # is updated by the low-pass m = a/(s + a), which enters M (Kb = 1)
    Kb = 0
    if norm == "2" and not dt and F.D.size and np.any(F.D):
        _, sv, Vt = np.linalg.svd(Gh.D)
        Vr = Vt[:int(np.sum(sv > 1e-12 * max(sv.max(initial=0.0), 1e-300)))]
        Kb = int(np.linalg.norm(F.D - F.D @ Vr.T @ Vr) > 1e-9 * np.linalg.norm(F.D))
    F = lowpass_power(a, 1, Mr.p, dt) @ F if Kb else F
    standard = K == 0 and left == 0 and Kb == 0
    # rank-deficient rows: fictitious noise ε on them makes the problem standard; its optimum
    # exceeds the infimum by O(ε ||Y||) (the returned error is measured without it). The
    # smallest ε of 1e-6, 1e-5, 1e-4, 1e-3 times ||Ĝ||∞ whose Riccati equations SLICOT solves
    Y, info, eps = _solve_regularised(Gh, F, left, norm, iteration_reltol(reltol))
    if norm == "inf" and not left:  # (regularised: the bracket certifies the problem with the fictitious noise)
        _certified_at_zero_filter(info)
    if left:  # the error without the fictitious noise
        E0 = Y @ Gh - F
        gamma_opt0 = _h2_quad(lambda L: _values(E0, L), [Gh, Y, F], dt) if norm == "2" else \
            _refined_peak(lambda L: _values(E0, L), _points([Gh, Y, F], dt), dt)
    else:
        gamma_opt0 = info["gamma"]
    # each row's own number of shifts (the peer's glcf of each row of the improper optimum): row i of
    # Q∞ = Y Φ Q0 / m^K needs k_i = K − d_i, d_i the factors m its row of Y Φ Q0 already has
    Qs = Y @ Phi @ Q0
    Qr, shifts = row_shifts(Qs, K, a, dt)
    placing = K and (poles is not None or (dt and sdeg != 0.0))
    per_row = len(set(shifts)) > 1
    if per_row:  # M = diag(M_i), each the least that makes its row proper
        M, Qfull, MF, factor, placed, row_poles = _per_row_factors(Qr, F, shifts, Kb, a, poles, sdeg, normalize, dt,
                                                                  placing, atol)
        scale = factor if factor is not None else np.array([a ** -(k + Kb) if normalize == "gain" and not dt
                                                            else 1.0 for k in shifts])
    else:  # one factor for every row: M = m^K I (as before; also where every row could take fewer shifts)
        shifts, scale, M, Qfull, MF, factor, placed, row_poles = _uniform_factor(Qs, F, K, Kb, a, poles, sdeg,
                                                                                 normalize, dt, placing, atol)
    if poles is not None and not K:
        note(f"poles {np.atleast_1d(poles).tolist()} not used: the problem is standard (no zeros at infinity), "
             f"the optimal filter has no freely placed pole")
    fnm = fault_noise_map(model)
    # the error as shipped, Q(λ) [Gf Gw; 0 0](λ) − M(λ) [Mr 0](λ), must be the designed one,
    # scale m(λ)^K (Y(λ) Ĝ(λ) − F(λ)), compared factor by factor at the same points (each
    # factor from a balanced realisation): the minimal realisation of Q is kept only if it
    # passes (with a large gain of Y, near-cancelling modes that SLICOT's staircase removes
    # can matter), else the non-minimal Y Φ Q0 is returned
    def budget_of(factor, scale, shifts, MF):  # the one error limit of every stage below (:class:`ErrorBudget`)
        return error_budget(model, Y, Gh, F, Mr, MF, factor, scale, a, shifts, norm, reltol, info, standard)

    budget, shipped = budget_of(factor, scale, shifts, MF), {}
    try:
        # (per row: on the rounding estimate alone — the uniform K shifts below are the next candidate before the
        # worst-case bound is admitted, :func:`_shipped_filter`)
        Q, lam = _shipped_filter(model, Mr, Y, Gh, F, Qfull, MF, fnm, scale, a, shifts, atol, factor,
                                 estimate_only=per_row, norm=norm, budget=budget, record=shipped, smarg=smarg,
                                 dec_tol=dec_tol)
    except DesignError:
        if not per_row:
            raise
        # a row divided by m^{d_i} on a feedthrough that was small, not zero (row_shifts' 1e-9 test): its response is
        # not the designed one; every row takes the K shifts instead (random H2 seed 5: a row's |d| = 1.1e-9 of its
        # [c d] dropped moved an error of 4.9e-11 by 6.7e-6; with K shifts on both rows it is reproduced)
        shifts, scale, M, Qfull, MF, factor, placed, row_poles = _uniform_factor(Qs, F, K, Kb, a, poles, sdeg,
                                                                                 normalize, dt, placing, atol)
        budget = budget_of(factor, scale, shifts, MF)
        Q, lam = _shipped_filter(model, Mr, Y, Gh, F, Qfull, MF, fnm, scale, a, shifts, atol, factor, norm=norm,
                                 budget=budget, record=shipped, smarg=smarg, dec_tol=dec_tol)
    budget0, required = budget, required_faults(model, Mr, lam)
    Q, cancelled, redecoupled, budget = _mended(model, Q, shipped.get("gap"), budget0, fnm, MF, lam, norm,
                                                [model.lti(), Y, Mr], required, smarg, dec_tol)
    if not redecoupled["leak_after"] <= dec_tol:  # (or NaN) the realisations within dec_tol, least leak first
        for S, x, gap, what in shipped.get("within_dec_tol", ()):
            mended = _mended(model, S, gap, budget0, fnm, MF, lam, norm, [model.lti(), Y, Mr], required, smarg,
                             dec_tol)
            if mended[2]["leak_after"] <= dec_tol:
                note(f"the {what} realisation (order {S.n}) is shipped: the one the response comparison took "
                     f"(order {Q.n}) leaks u/d {redecoupled['leak_after']:.3g} (reading + sensitivity, the worst "
                     f"row) > dec_tol = {dec_tol:g} after its re-decoupling ({redecoupled['reason']}), and this one, of "
                     f"least leak ({x:.3g} as read beside it) among those whose error is as admissible, meets "
                     f"dec_tol ({mended[2]['leak_after']:.3g} after its stages)")
                Q, cancelled, redecoupled, budget = mended
                break
    _ud_leak_refused(redecoupled.pop("figures"), dec_tol, redecoupled["row_leaks"])
    gen = ResidualGenerator(Q, model, "approximate_model_matching")
    check_generator(gen, decouple=("u", "d"), faults=[], smarg=smarg, dec_tol=dec_tol)
    err = _judged_error(model, Q, fnm, MF, lam, norm, [model.lti(), Y, Mr])
    least = None
    if mindeg:
        gen, least = _least_order(model, gen, fnm, MF, lam, norm, [model.lti(), Y, Mr], err, budget, smarg,
                                  dec_tol, atol, required=required)
        Q, err = gen.Q, least["error"]
    if not err <= budget.limit:  # the post-condition every stage was held to (:class:`ErrorBudget`)
        raise DesignError(f"approximate_model_matching: the returned filter's error {err:.9g} exceeds the "
                          f"{budget.says()}: the realised filter is not within reltol of the optimum")
    _below_certified_refused(err, info, standard, norm, budget)
    zero_error = _zero_filter_error(model, err, MF, lam, norm, [model.lti(), Y, Mr], reltol)
    if K == 0:  # (with Kb = 1 the problem solved is the one with M Mr already)
        gamma_opt = gamma_opt0
    else:
        Yu = solve_standard(*_regularised(Gh, MF, left, eps), norm, reltol)[0]
        gamma_opt = _h2_quad(lambda L: _values(Yu @ Gh - MF, L), [Gh, Yu, MF], dt) if norm == "2" else \
            _refined_peak(lambda L: _values(Yu @ Gh - MF, L), lam, dt)
    gen.info.update({
        "norm": norm, "standard": bool(standard), "gamma_opt": float(gamma_opt), "gamma_opt0": float(gamma_opt0),
        "gamma_sub": float(err), "error": float(err), "M": M, "interactor_steps": int(K),
        "row_shifts": [int(k) for k in shifts],
        "row_updating_poles": [[complex(x) if complex(x).imag else float(complex(x).real) for x in r]
                               for r in row_poles],
        "order": int(Q.n), "row_orders": least["row_orders"] if least else row_orders(Q, atol),
        "poles": np.asarray(Q.poles()).tolist(),
        "reduced_rows": int(G1.p),
        "dropped_rows": int(dropped), "regularised_rows": int(left), "regularisation_eps": eps,
        "reference_lowpass": bool(Kb),
        "updating_poles": [complex(x) if complex(x).imag else float(complex(x).real) for x in placed + [-a] * Kb],
        **basis,
    })
    gen.info["zero_filter_error"] = zero_error
    gen.info["rank_bound"] = rank_bound
    gen.info["error_budget"] = budget.as_info()
    gen.info["plant_mode_cancellation"] = cancelled
    gen.info["ud_redecoupling"] = redecoupled
    if "bracket" in info:
        gen.info["gamma_bracket"] = [float(x) for x in info["bracket"]]
    if least is not None:
        gen.info["mindeg"] = least
    return gen


#: the error limits' absolute floor, this fraction of ``||M [Mr 0]||`` (exactly matchable references: two readings of
#: an error of rounding size differ by rounding) — :func:`_shipped_filter`, :func:`_correction_refused`, the row
#: lowering's guard and the mindeg acceptance
ZERO_ERROR_FLOOR = 1e-9



@dataclass(frozen=True)
class ErrorBudget:
    """The one error limit of a design, ``limit = base·(1 + reltol) + floor``, that every stage's filter meets.

    ``base`` is the optimum the γ-iteration certified: in the standard H∞ problem (no interactor shift, no updating
    factor, no fictitious noise: the returned error *is* ``||Y Ĝ − F||∞``) the lower end of its bracket, a level at
    which no admissible filter exists (or, where a measured error fell below it, that error), so ``base ≤ γ_opt`` —
    where the iteration stopped on it (its filter within ``1 + r_γ`` of it; not on an exact match or its level
    floor, which leave a weak lower end); otherwise (H2: the optimum is the Riccati solution's, exact;
    non-standard or regularised H∞: the iteration certifies ``||Y Ĝ − F||``, not the returned
    ``||M (Y Ĝ − F)||``) the designed filter's own error ``e_d``, read from its factors as the returned figure is
    read (:func:`_designed_error`). Where the shipped realisation was taken on the rounding test alone (its error above
    the limit: nearly exactly matchable problems, whose error is of the size of the product's rounding), its error
    becomes the base (:func:`_shipped_budget`: the base moves by a rounding gap, never by a ``reltol``).
    ``floor`` is :data:`ZERO_ERROR_FLOOR` of ``||M [Mr 0]||`` (exactly matchable references: errors of rounding
    size).

    Derivation. A user asking ``reltol`` must get ``e ≤ γ_opt (1 + reltol)``. Before, the iteration's filter was
    within ``1 + r_γ`` of its level (:func:`iteration_reltol`) and every later stage — the shipped realisation
    (:func:`_shipped_filter`), the cancellation and re-decoupling corrections (:func:`_correction_refused`), the
    least-order acceptance (:func:`_verified`) — was allowed ``reltol`` of the filter before it: k such stages
    compound to ``(1 + r_γ)(1 + reltol)^k``, and only ``_zero_filter_error`` (against Q = 0's error, which can be far
    above γ_opt) bounded the total. Now each stage's candidate is accepted iff its own measured error is at most
    ``limit``, and the returned filter's error is checked against it once more at the end
    (:func:`approximate_model_matching`): ``e ≤ base (1 + reltol) + floor ≤ γ_opt (1 + reltol) + floor`` whatever
    the number of stages — no per-stage share to choose, no product to compound. The iteration keeps ``r_γ``
    (``(1 + r_γ)² = 1 + reltol``), so its filter leaves at least ``base (reltol − r_γ) ≈ base·reltol/2`` of room
    for the stages after it."""
    base: float
    reltol: float
    floor: float
    certified_by: str
    designed: float = np.nan  # (the designed filter's error e_d, :func:`_designed_error`)

    @property
    def limit(self) -> float:
        return float(self.base * (1.0 + self.reltol) + self.floor)

    def says(self) -> str:
        return (f"limit {self.limit:.9g} = {self.certified_by} {self.base:.9g}·(1 + reltol = {self.reltol:g}) "
                f"+ {self.floor:.3g}")

    def as_info(self) -> dict:
        return {"base": float(self.base), "certified_by": self.certified_by, "reltol": float(self.reltol),
                "floor": float(self.floor), "limit": self.limit, "designed": float(self.designed)}


def _design_points(model, Y: LTI, Mr: LTI, factor) -> np.ndarray:
    """The design's comparison points (:func:`_points` over the plant, Y, Mr and the placed factors)."""
    return _points([model.lti(), Y, Mr] + (list(factor) if isinstance(factor, list) else [factor] if factor is not None
                                           else []), model.dt)


def _factor_values(L, factor, scale, shifts, a: float, dt: float) -> np.ndarray:
    """``(points, rows)``: each row's updating factor (:func:`row_shifts`), ``s_i m(λ)^{k_i}`` or the placed
    ``μ_i(λ)``."""
    if factor is None:
        return np.stack([sc * _mk(L, a, k, dt) for sc, k in zip(np.broadcast_to(scale, len(shifts)), shifts)], 1)
    return np.stack([_values(f, L)[:, 0, 0] for f in (factor if isinstance(factor, list) else
                                                      [factor] * len(shifts))], 1)


def _designed_error(model, Y, Gh, F, Mr, factor, scale, a, shifts, norm, lam) -> float:
    """The designed error ``||M (Y Ĝ − F)||`` read from the factors on ``lam`` (H∞ refined peak, H2 quadrature)."""
    dt = model.dt

    def designed_at(L):
        return (np.einsum("kij,kjl->kil", _values(Y, L), _values(Gh, L)) - _values(F, L)) \
            * _factor_values(L, factor, scale, shifts, a, dt)[:, :, None]

    return float(_refined_peak(designed_at, lam, dt) if norm == "inf"
                 else _h2_quad(designed_at, [model.lti(), Y, Mr], dt))


def error_budget(model, Y, Gh, F, Mr, MF, factor, scale, a, shifts, norm, reltol, info, standard) -> ErrorBudget:
    """The design's :class:`ErrorBudget` for the chosen updating factors (module docstring, :class:`ErrorBudget`)."""
    lam = _design_points(model, Y, Mr, factor)
    floor = ZERO_ERROR_FLOOR * max(float(np.nanmax(_nrm(_values(MF, lam)), initial=0.0)), 1e-300)
    e_d = _designed_error(model, Y, Gh, F, Mr, factor, scale, a, shifts, norm, lam)
    # the bracket's lower end certifies only where the iteration stopped on it (its filter within 1 + r_γ of it); it
    # also stops on an exact match or on its level floor, its lower end then a weak bound (||D_F − Y0 D̂||, or
    # 1e-9 of the upper end: approximate audit seed 115's 0 beside an error 1) — the designed error is the base then
    lo = float(info["bracket"][0]) if norm == "inf" and standard and "bracket" in info else None
    if lo is not None and lo > 0 and float(info["gamma"]) <= lo * (1 + iteration_reltol(reltol)):
        return ErrorBudget(lo, reltol, floor, "the γ-iteration's infeasible level", e_d)
    return ErrorBudget(e_d, reltol, floor, "the designed filter's error", e_d)


def _mended(model, Q, gap, budget, fnm, MF, lam, norm, systems, required, smarg, dec_tol):
    """The stages of :func:`approximate_model_matching` after :func:`_shipped_filter` on its realisation ``Q``:
    ``(Q', info['plant_mode_cancellation'], info['ud_redecoupling'] with the judge's 'figures', the budget)`` — the
    budget moved to Q's error where Q was taken on the rounding test (``gap``, :func:`_shipped_budget`), the plant modes
    cancelled (:func:`_plant_mode_cancellation`), u, d re-decoupled where its leak exceeds dec_tol
    (:func:`_ud_redecoupling`). Where the cancellation's filter still leaks above dec_tol after that and Q re-decoupled
    without it meets dec_tol, that one is returned (a note says so; the R-stability post-condition judges its
    cancellation as it is): approximate audit seed 240, H2, ``Mr = I`` (one admissible row, a plant integrator): the
    correction (relative 1.9e-3 of ``[B_q; D_q]``, decoupling kept on 2·unknowns real equations of thinned points)
    leaked 5.4e-7 of the weakest required fault's gain at 7.4 rad/s and no refit mended it — refused; the filter
    before it leaks 2.9e-10 and passes every post-condition, R-stability included."""
    budget = _shipped_budget(budget, float(_judged_error(model, Q, fnm, MF, lam, norm, systems)), gap, norm)
    Qc, cancelled = _plant_mode_cancellation(model, Q, fnm, MF, lam, norm, systems, budget, smarg, dec_tol)
    Qr, redecoupled = _ud_redecoupling(model, Qc, required, fnm, MF, lam, norm, systems, budget, smarg, dec_tol)
    if cancelled["corrected"] and not redecoupled["leak_after"] <= dec_tol:
        # the exact cancellation keeps u, d decoupled on thinned points only, and may leak between them: where the
        # corrected filter still leaks after its re-decoupling, the filter before it is re-decoupled instead and
        # kept if that meets dec_tol (the R-stability post-condition then judges its cancellation as it is)
        Qu, plain = _ud_redecoupling(model, Q, required, fnm, MF, lam, norm, systems, budget, smarg, dec_tol)
        if plain["leak_after"] <= dec_tol:
            note(f"the exact cancellation of the plant modes {cancelled['modes']} (relative change "
                 f"{cancelled['correction']:.3g} of [B_q; D_q]) leaks u/d {redecoupled['leak_after']:.3g} > dec_tol = "
                 f"{dec_tol:g} after its re-decoupling; the filter before it, which meets dec_tol "
                 f"({plain['leak_after']:.3g}), is kept")
            return Qu, {**cancelled, "corrected": False, "reason": (
                f"the corrected filter leaked u/d {redecoupled['leak_after']:.3g} > dec_tol = {dec_tol:g} (the "
                f"correction keeps u, d decoupled on the design's thinned points only); the filter before it "
                f"({plain['leak_after']:.3g}) kept")}, plain, budget
    return Qr, cancelled, redecoupled, budget


def _shipped_budget(budget: ErrorBudget, e_s: float, gap: float | None, norm: str) -> ErrorBudget:
    """The budget after :func:`_shipped_filter`: unchanged where the shipped filter's error ``e_s`` is within it;
    else, where that filter was taken on the rounding test (``gap``: its largest pointwise distance from the designed
    error response, within the comparison's rounding bound β or β_w and ``SHIPPED_ACCURACY`` of the error's size), it
    is the designed filter to that rounding and its error is the base of the stages after it — in H∞ only if
    ``e_s ≤ e_d + 2·gap + floor`` (the triangle inequality at the peak, with a factor 2 for the refined points
    between those the gap is read on; a filter further off is not that realisation) — and
    otherwise the budget stands (the returned filter is then refused by it). ammp_random_set H∞ seeds 2 and 3, nearly
    exactly matchable: designed 1.8e-6 and 5.5e-10, shipped 3.06e-6 and 8.9e-8, the rounding of the product
    ``Y Φ Q0`` read on its own values. Not compounding: the base moves by the rounding gap only, never by a
    ``reltol``."""
    if e_s <= budget.limit or gap is None:
        return budget
    if norm == "inf" and not e_s <= budget.designed + 2.0 * gap + budget.floor:  # (×2: the peaks are refined
        # between the points the gap is read on)
        return budget
    return ErrorBudget(float(e_s), budget.reltol, budget.floor,
                       f"the shipped realisation's error (the designed filter's to rounding, gap {gap:.3g}; "
                       f"{budget.certified_by} {budget.base:.9g})", budget.designed)


def _unapproachable_reference(model, G1: LTI, Mr: LTI, norm: str, restricted: bool = False) -> dict:
    """Stage of :func:`approximate_model_matching`, before the γ-iteration: refuse a reference that no admissible
    filter approaches better than Q = 0 does. Returns the figures (``info['rank_bound']``).

    Every admissible filter is ``Q = Y Q0`` with Y stable (step 1; ``Y H Q0`` with ``HDesign``; improper Y too where
    the infimum of (1) is approached only by them, step 2), so its error is ``E = Y G1 − F``, ``G1 = Q0 [Gf Gw; 0 0]``
    (stable), ``F = [Mr 0]`` (w is not decoupled: its columns only add). At every point λ where Y, G1 and F are finite
    the rows of ``Y(λ) G1(λ)`` lie in the row space of ``G1(λ)``, so with ``P(λ)`` the orthogonal projector onto it
    (``X G1 P = X G1``) and any X,

        (X G1 − F)(X G1 − F)ᴴ = (X G1 − F P)(X G1 − F P)ᴴ + F (I − P) Fᴴ  ⪰  F (I − P) Fᴴ,

    (the cross terms vanish: ``(I − P) Pᴴ = 0``), hence ``||X G1(λ) − F(λ)|| ≥ d(λ) = ||F(λ) (I − P(λ))||``, with
    equality at ``X = F G1⁺``: ``d(λ)`` is the distance of ``F(λ)`` to the set ``{X G1(λ)}``. ``E`` is in H∞ (Ŷ Ĝ − F of
    the standard problem is; Φ and ``m^K`` are invertible at every finite λ of the closed right half plane), and a
    bounded analytic function's norm at a point of the closed right half plane (``|z| ≥ 1`` in discrete time) is at
    most its H∞ norm (maximum modulus, applied to each ``uᴴ E v``; Zhou, Doyle and Glover, *Robust and Optimal
    Control*, sec. 4.3), so for every admissible filter

        ||Q [Gf Gw; 0 0] − [Mr 0]||∞ ≥ β = sup_{λ ∈ closed RHP} d(λ) ≥ sup_λ σ_{r+1}(Mr(λ)),                       (3)

    the last the rank reading (Weyl's ``σ_{i+j−1}(A + B) ≤ σ_i(A) + σ_j(B)`` with ``B = X G1f`` of rank ≤ r, the
    normal rank of ``G1f = Q0 [Gf; 0]``; Eckart–Young–Mirsky, Golub and Van Loan, *Matrix Computations*, 4th ed.,
    Thm 2.4.8), which needs no projector. Q = 0's error is ``||Mr||∞``; where ``β`` reaches it the optimum *is* Q = 0's
    error: no filter does better than none, and a returned "optimal" filter would be an arbitrary one within
    ``reltol`` of zero's error (approximate audit seeds 26, 240, 270, 282 with ``Mr = I`` on 5 faults and 2, 1, 3, 2
    admissible rows — the rank reading — were refused for numerical reasons that were not the cause; seeds 2, 6, 8, 12,
    16 with ``Mr = [I_r 0]``, r their admissible rank, returned errors 1.00001 … 1.00003 against Q = 0's 1 with a note:
    the first r fault columns of G1 lose rank at the fault-only plant mode s = 1, 1, ±2j, 1 and at s = 0 (seed 16), so
    ``d = 1`` there — on the axis for 8 and 16, inside the right half plane for 2, 6, 12, where no boundary grid sees
    it: on the axis their ``d`` peaks at 0.99894, 0.99530, 0.99997, 0.99300 for seeds 2, 6, 8, 12). Refused
    (DesignError) with the reading, ``β`` and ``||Mr||∞``. Where ``β < ||Mr||∞`` the design proceeds (its optimum lies
    in ``[β, ||Mr||∞]``), and the γ-iteration's certificate is checked against Q = 0 once more
    (:func:`_certified_at_zero_filter`).

    Readings; each can only under-read (3), so neither the points chosen nor rounding cause a false refusal:

    - points: the design's grid of the plant, G1 and Mr (:func:`_points`), Mr's own peak frequency
      (:meth:`LTI.hinfnorm`, which gives ``||Mr||∞``), λ = 0 (z = ±1), and the zeros in the closed right half plane of
      ``G1f V1``, V1 the right singular vectors of Mr's largest singular values at its peak (there ``d`` reaches
      ``||Mr(λ)||`` where ``G1f V1`` drops column rank: a unit ``x = V1 c`` with ``G1 x = 0`` has ``P x = 0``) moved
      onto the closed half plane (a computed zero ``−1e-15 ± 2j``: onto the axis). Any point of the closed half plane
      gives a lower bound (a supremum over a subset); the rank reading also at ω → ∞ (Mr's feedthrough; by continuity);
      ``d`` not there (an improper Y acts at ∞);
    - ``d(λ)``: P from the top ``r_G`` right singular vectors ``V̂`` of the computed ``Ĝ1(λ)``, ``r_G`` the normal
      rank of the whole G1 (:func:`_normal_rank`, the interactor's rule: rank ``G1(λ) ≤ r_G`` at every λ). The SVD
      is exact for ``G1(λ) + E``, ``||E|| ≤ ε = η_G + default_rtol·σ̂_1`` (η_G: the worst-case first-order rounding
      of the value, :func:`_evaluation_rounding`; the SVD's backward error), so by Wedin's theorem (Stewart and Sun,
      *Matrix Perturbation Theory*, Thm V.4.4; ``σ_{r_G+1}(G1(λ)) = 0``) ``V̂`` spans, within the angle
      ``sin θ ≤ ε/σ̂_{r_G}``, an ``r_G``-dimensional subspace containing the row space of ``G1(λ)``; its projector
      ``P'`` has ``||F (I − P)|| ≥ ||F (I − P')|| ≥ ||F (I − P̂)|| − ||F|| sin θ``, and Mr's rounding η_F moves the
      norm by at most η_F. The reading is ``d̂ − ||F̂|| ε/σ̂_{r_G} − η_F`` where ``σ̂_{r_G} > 2ε`` (else none);
      a point whose ``σ̂_{r_G+1}`` exceeds ε contradicts the rank decision and gives no reading;
    - rank reading: ``σ_{r+1}(Mr(λ)) − η_F`` (Weyl: a singular value moves by at most the perturbation's norm).

    Refused iff ``β ≥ ||Mr||∞ (1 − τ)``, ``τ = 2·HINF_RTOL + default_rtol`` of F's shape (the norm's reading, within
    2·HINF_RTOL of the peak; the rounding of the last product and norm). For ``Mr = I`` and ``r < nf``, ``β = 1``
    exactly.

    H2 (``norm='2'``): Q = 0's error is ``||[Mr 0]||₂`` (updated by the low-pass where the reference is), and the
    bound of (3) in the Frobenius norm, ``||E||₂² ≥ (1/2π) ∫ Σ_{i>r} σ_i(Mr(λ))² dω``, is *below* it whenever r ≥ 1
    and Mr ≠ 0 — each direction matched lowers the H2 error, so the H2 problem with a rank-deficient ``G1f`` has an
    optimum better than Q = 0's and is designed. The refusal is then made only where ``r = 0`` (no admissible filter
    sees a fault: ``||E||₂² = ||Mr||₂² + ||Q Gw||₂²``, the optimum is Q = 0 in every norm)."""
    r = _normal_rank(G1[:, :model.nf]) if model.nf and G1.p else 0
    out = {"rank": int(r), "reference_rows": int(Mr.p)}
    if norm == "2" and r > 0:
        return out  # (the H2 bound is below Q = 0's error)
    dt = model.dt
    peak, w_peak = Mr.hinfnorm()
    if not peak > 0:
        return {**out, "bound": 0.0, "zero_filter_error": float(peak)}
    lam = _points([model.lti(), G1, Mr], dt)
    at_peak = np.exp(1j * w_peak * dt) if dt else 1j * w_peak
    extra = [np.array([1.0, -1.0] if dt else [0.0], complex)]
    if np.isfinite(w_peak) and w_peak >= 0:
        extra.append(np.array([at_peak]))
    if norm == "inf" and G1.p and model.nf:
        extra.append(_closed_rhp_zeros(G1[:, :model.nf], Mr, at_peak if np.isfinite(w_peak) else None, dt))
    lam = np.unique(np.concatenate([lam] + extra))
    values = _values(Mr, lam)
    eta_f = _evaluation_rounding(Mr, lam, worst=True)
    ok = np.all(np.isfinite(values), axis=(1, 2)) & np.isfinite(eta_f)
    lam, values, eta_f = lam[ok], values[ok], eta_f[ok]
    ranked, ranked_eta = values, eta_f
    if not dt:  # (ω → ∞: Mr's feedthrough, for the rank reading; its rounding u·||D||)
        ranked = np.concatenate([values, Mr.D[None].astype(complex)])
        ranked_eta = np.append(eta_f, EPS / 2 * float(np.linalg.norm(Mr.D, 2)) if Mr.D.size else 0.0)
    sv = np.linalg.svd(ranked, compute_uv=False)
    rank_reading = sv[:, r] - ranked_eta if r < min(Mr.p, Mr.m) else np.zeros(ranked.shape[0])
    k = int(np.argmax(rank_reading))
    bound, where, how = float(rank_reading[k]), complex(lam[k]) if k < lam.size else complex(np.inf), "rank"
    if norm == "inf":
        dist = _distance_readings(G1, values, eta_f, lam, model.nw)
        j = int(np.argmax(dist)) if dist.size else -1
        if j >= 0 and dist[j] > bound:
            bound, where, how = float(dist[j]), complex(lam[j]), "distance"
    tau = 2 * HINF_RTOL + default_rtol((Mr.p, Mr.m + model.nw))
    out.update(bound=bound, zero_filter_error=float(peak), rtol=float(tau), reading=how, at=where)
    if bound >= peak * (1 - tau):
        who = "filter Y·H·Q0 (HDesign) that decouples u and d" if restricted else "filter that decouples u and d"
        if how == "rank":
            why = (f"their fault response Q·Gf has normal rank {r} (that of Q0·[Gf; 0]) of Mr's {Mr.p} rows, so every "
                   f"admissible Q has ||Q [Gf Gw; 0 0] − [Mr 0]||∞ ≥ sup_λ σ_{r + 1}(Mr(λ)) = {bound:.9g}")
            hint = (f"choose Mr with at most {r} independent row{'s' if r != 1 else ''} (σ_{r + 1}(Mr) below ||Mr||∞ "
                    f"at its peak), or fewer faults to match")
        else:
            at = f"s = {where:.6g}" if not dt else f"z = {where:.6g}"
            why = (f"at {at} (closed {'right half plane' if not dt else 'exterior of the unit disc'}) [Mr 0] is at "
                   f"distance {bound:.9g} from every X·Q0·[Gf Gw; 0 0] (the row space of the admissible fault and "
                   f"noise response, normal rank {r} in the faults), so every admissible Q has "
                   f"||Q [Gf Gw; 0 0] − [Mr 0]||∞ ≥ {bound:.9g} (maximum modulus)")
            hint = ("choose Mr whose largest directions the admissible fault response reaches there (e.g. Mr small "
                    "where Q0·[Gf; 0] loses rank), or fewer faults to match")
        raise DesignError(
            f"approximate_model_matching: Mr cannot be approached by any {who}: {why}, which reaches ||Mr||∞ = "
            f"{peak:.9g} (within {tau:.2g}), the error of Q = 0: no filter does better than none"
            f"{' in either norm' if norm == '2' else ''}; {hint}")
    return out


def _closed_rhp_zeros(G1f: LTI, Mr: LTI, at_peak: complex | None, dt: float) -> np.ndarray:
    """Points of :func:`_unapproachable_reference`'s reading (3): the finite zeros of ``G1f V1`` in the closed right
    half plane (``|z| ≥ 1``), within 1e-7 (relative) of it moved onto it, V1 the right singular vectors of ``Mr`` at
    its peak (``at_peak``; None: at ω → ∞) whose singular values are within 1e-6 of the largest. Any point of the
    closed half plane is a valid point of (3): these are where ``d`` can reach ``||Mr||∞`` off the boundary."""
    Mp = Mr.evalfr(at_peak) if Mr.n and at_peak is not None else Mr.D.astype(complex)  # (a peak at ω → ∞: D)
    _, s, Vh = np.linalg.svd(Mp)
    V1 = Vh[:int(np.sum(s >= s[0] * (1 - 1e-6)))].conj().T
    if not V1.shape[1] or V1.shape[1] > G1f.p:  # (more directions than rows: the rank reading decides)
        return np.zeros(0, complex)
    V1 = V1.real if np.allclose(V1.imag, 0.0) else None
    if V1 is None:  # (a complex direction has no real system to take zeros of)
        return np.zeros(0, complex)
    try:
        z = transmission_zeros(G1f @ LTI.static(V1, dt))
    except (SlycotError, ValueError, np.linalg.LinAlgError):  # (the points are optional: the grid's reading stands)
        return np.zeros(0, complex)
    if dt:
        keep = np.abs(z) >= 1 - 1e-7
        return np.where(np.abs(z) < 1, z / np.maximum(np.abs(z), 1e-300), z)[keep]
    keep = z.real >= -1e-7 * np.maximum(1.0, np.abs(z))
    return (np.maximum(z.real, 0.0) + 1j * z.imag)[keep]


def _distance_readings(G1: LTI, Mv: np.ndarray, eta_f: np.ndarray, lam: np.ndarray, nw: int) -> np.ndarray:
    """Per point λ, the certified reading of ``d(λ) = ||F (I − P_{G1(λ)})||`` of :func:`_unapproachable_reference`
    (its docstring derives it): ``d̂ − ||F̂|| ε/σ̂_{r_G} − η_F``, −∞ where σ̂_{r_G} ≤ 2ε or ``σ̂_{r_G+1} > ε`` — and −∞
    at the points whose plain reading ``d̂`` (an upper end of the certified one) is below the largest certified one:
    the rounding bound ε (a resolvent per point, most of the stage's cost) is computed at the points of the largest
    ``d̂`` first, then wherever ``d̂`` still exceeds the best certified reading, so the maximum is the same."""
    rG = _normal_rank(G1) if G1.p else 0
    if not rG:  # (no admissible row, or none that sees a fault or noise: d = ||F||)
        return _nrm(Mv) - eta_f
    Gv = _values(G1, lam)
    out = np.full(lam.size, -np.inf)
    ok = np.flatnonzero(np.all(np.isfinite(Gv), axis=(1, 2)))
    if not ok.size:
        return out
    F = np.concatenate([Mv, np.zeros(Mv.shape[:2] + (nw,))], axis=2) if nw else Mv
    _, s, Vh = np.linalg.svd(Gv[ok])  # (batched: one LAPACK call per point)
    Vr = np.conj(np.swapaxes(Vh[:, :rG], 1, 2))
    Fo = F[ok]
    d = _nrm(Fo - (Fo @ Vr) @ np.conj(np.swapaxes(Vr, 1, 2)))
    todo = d >= d.max() - 1e-6 * float(np.max(_nrm(Fo)))
    seen = np.zeros(ok.size, bool)
    while np.any(todo):
        k = ok[todo]
        eps = _evaluation_rounding(G1, lam[k], worst=True) + default_rtol(Gv.shape[1:]) * s[todo, 0]
        reading = d[todo] - _nrm(Fo[todo]) * eps / s[todo, rG - 1] - eta_f[k]
        beyond = s[todo, rG] > eps if s.shape[1] > rG else np.zeros(k.size, bool)
        out[k] = np.where((s[todo, rG - 1] > 2 * eps) & ~beyond & np.isfinite(eps), reading, -np.inf)
        seen |= todo
        todo = ~seen & (d > np.max(out))  # (only a larger d̂ can beat the best certified reading)
    return out


def _certified_at_zero_filter(info: dict) -> None:
    """Stage of :func:`approximate_model_matching`, after the H∞ γ-iteration on the unregularised problem: refuse
    where the iteration certifies that no filter beats Q = 0. Its lower bound ``γ_lo`` (``info['lower_bound']``: the
    error at s = ∞ no Y can change, ``||D_F − D_F D̂⁺ D̂||`` in continuous time, or a level SLICOT refused; none where a
    measured error fell below a refused level) bounds the infimum of (1) from below — every admissible ``Y G1`` is a
    ``Ŷ Ĝ`` of the reduced problem (``Ŷ = Y Φ⁻¹ m^K``, stable: each row of Φ⁻¹ has at most K factors ``1/m``), so the
    reduced problem's infimum is at most (1)'s — and Q = 0 (Ŷ = 0) has the error ``||F||∞ = ||[Mr 0]||∞``. Refused
    (DesignError) iff ``γ_lo ≥ ||F||∞ (1 − HINF_F_RTOL)``: the iteration itself does not tell levels within
    ``HINF_F_RTOL`` of ``||F||∞`` apart (above it a refusal is numerical, :func:`solve_standard`; the norm is read
    within 2·HINF_RTOL). The rank bound (:func:`_unapproachable_reference`) catches the cases it names before the
    iteration; this one catches the others (noise whose decoupling costs every fault direction, a supremum (3) the
    grid missed). Not applied with fictitious noise (its bracket certifies the regularised problem, whose infimum is
    above (1)'s by O(ε ||Y||)) nor in H2 (no bracket; the H2 optimum is exact)."""
    lb, fnorm = float(info.get("lower_bound", 0.0)), float(info.get("fnorm", 0.0))
    if fnorm > 0 and lb >= fnorm * (1 - HINF_F_RTOL):
        raise DesignError(
            f"approximate_model_matching: Mr cannot be approached by any filter that decouples u and d: the "
            f"γ-iteration certifies every admissible filter's error at least {lb:.9g} (its lower bound: a level with "
            f"no solution, or the error at infinity), which reaches ||[Mr 0]||∞ = {fnorm:.9g} (within HINF_F_RTOL = "
            f"{HINF_F_RTOL:g}), the error of Q = 0: no filter does better than none; choose Mr in the directions the "
            f"decoupled residuals reach (Q0·[Gf; 0]), or a smaller noise weight")


#: :func:`_zero_filter_error`: an error above Q = 0's by more than ``reltol`` plus this fraction of it (the rounding of
#: two refined peaks read on the same points, ~1e-12 of the error, with margin) is refused
ZERO_FILTER_SLACK = 1e-9


def _zero_filter_error(model, err, MF, lam, norm, systems, reltol) -> float:
    """Stage of :func:`approximate_model_matching`: the error of the zero filter, ``||M [Mr 0]||`` (its error is
    ``−M [Mr 0]``; H∞ refined peak or H2 quadrature, as :func:`_shipped_error` reads the returned filter's), compared
    with the returned filter's error ``err``. Q = 0 is admissible (it decouples u and d), so the optimum γ_opt0 is at
    most this, and a filter within ``reltol`` of the optimum has ``err ≤ (1 + reltol)·||M [Mr 0]||``:

    - above that (plus :data:`ZERO_FILTER_SLACK`) the design missed its optimum: DesignError, naming both errors;
    - above ``||M [Mr 0]||`` but within ``reltol`` of it: the optimum is within ``reltol`` of Q = 0's error, and the
      returned filter, optimal within ``reltol``, is worse than Q = 0 by less than ``reltol``. It is returned with a
      note saying so. Where the optimum *is* Q = 0's error the design never gets here: the rank bound
      (:func:`_unapproachable_reference`, e.g. ``Mr = I`` on more faults than the decoupled residuals reach) and the
      γ-iteration's certificate (:func:`_certified_at_zero_filter`) refuse it (before amm21, approximate audit seed
      110, nf = 5, p = 3, Mr = I, was returned here with the error 1.0000777 against Q = 0's 1)."""
    def values(L):
        return -_values(MF, L)

    zero = float(_refined_peak(values, lam, model.dt) if norm == "inf" else _h2_quad(values, systems, model.dt))
    if err > zero * (1 + reltol + ZERO_FILTER_SLACK):
        raise DesignError(f"approximate_model_matching: the returned filter's error {err:.6g} exceeds that of Q = 0, "
                          f"||M [Mr 0]|| = {zero:.6g}, by more than reltol = {reltol:g}: the optimum was not reached")
    if err > zero:
        note(f"the returned filter's error {err:.6g} exceeds that of Q = 0 (||M [Mr 0]|| = {zero:.6g}) by "
             f"{err / zero - 1:.3g}, within reltol = {reltol:g}: the optimum is within reltol of Q = 0's error")
    return zero


def _uniform_factor(Qs: LTI, F: LTI, K: int, Kb: int, a: float, poles, sdeg: float, normalize: str, dt: float,
                    placing, atol: float):
    """Stage of :func:`approximate_model_matching`: one updating factor for every row, ``M = m^K I`` (``μ I`` with
    placed poles), and the filter ``M Q∞`` of ``Qs = Y Φ Q0``; returns ``(shifts, scale, M, Q, M F, μ or None, the
    poles placed, [the poles of each row's factor])`` (with placed poles ``Q`` is the pair of :func:`_shipped_filter`)."""
    p = Qs.p
    scale = a ** -(K + Kb) if normalize == "gain" and not dt else 1.0
    M = scale * lowpass_power(a, K + Kb, p, dt)
    Qfull = scale * Qs
    MF = scale * lowpass_power(a, K, p, dt) @ F if K else scale * F  # = M [Mr 0]
    factor, placed = None, [complex(-a if not dt else 0.0)] * K
    if placing:  # M's poles placed: M = μ I
        M, Qfull, MF, factor, placed = placed_factor(Qs.minreal(atol), F, K, Kb, a, poles, sdeg, normalize, dt)
        Qfull = (Qfull, placed_factor(Qs, F, K, Kb, a, poles, sdeg, normalize, dt)[1])  # (the last resort)
    return [K] * p, scale, M, Qfull, MF, factor, placed, [list(placed) + [complex(-a)] * Kb] * p


#: :func:`_plant_mode_cancellation`: the fewest of the design's points at which its correction keeps the u, d
#: decoupling, and the most unknowns ``(n_q + rows)·(p + m)`` it solves for (an SVD of ~4× as many rows: ~1 s)
CANCEL_POINTS, CANCEL_UNKNOWNS = 100, 2000


def _plant_mode_cancellation(model, Q, fnm, MF, lam, norm, systems, budget, smarg, dec_tol) -> tuple[LTI, dict]:
    """Stage of :func:`approximate_model_matching`: ``(Q', info['plant_mode_cancellation'])``, the shipped filter with
    its numerator corrected so that every plant mode on or beyond the stability boundary that some input of Ge
    excites is cancelled exactly in ``R = Q·Ge`` — the modes and directions of the judge's table
    (:func:`..toolkit.refine.boundary_residues` with ``every_mode``, :func:`..toolkit.plant_modes.boundary_mode_table`),
    the correction the change of ``[B_q; D_q]`` (of Q's balanced realisation) that zeroes the residues exactly and
    changes ``Q·[Gu Gd; I 0]`` on the design's points least (:func:`..toolkit.refine.cancel_residues`).

    Why: the basis ``Q0`` (or its stable factor) cancels a fault-only boundary mode p to rounding, ``Q0(p) c_p ~
    eps``, and ``Q = Y Φ Q0`` multiplies that residue by Y's gain: random seed 2's ``||Q(1) c_p|| = 6.8e-12``
    against the judge's rounding bound δ_i = 5.5e-13 (s = 1), seed 13's 3.0e-11 against 1.6e-11 (z = 1) — an R_f
    that grows as ``e^t·residue`` in a running FMU, refused by the R-stability post-condition. A stable R needs
    ``Q(p) c_p = 0`` exactly, so the correction of a filter that is right up to that residue moves it by the
    residue's size. As :func:`.matching._cancel_plant_modes`, the correction is
    minimal in the parameters, not in the response, so it is kept only if the error measured on the corrected
    filter (:func:`_shipped_error`, on the same points) is within the design's one limit (:class:`ErrorBudget`: the
    certified optimum times ``1 + reltol``, plus 1e-9 of
    ``||M Mr||`` for exactly matchable references) and the corrected filter passes the post-conditions; otherwise
    the shipped filter goes on to be judged as it is. The note has matching's keys: ``corrected``,
    ``error_before``/``error_after``, ``correction`` (relative change of ``[B_q; D_q]``), ``reason``, and here the
    ``modes`` corrected."""
    from ..toolkit.refine import boundary_residues, cancel_residues

    out = {"corrected": False, "error_before": None, "error_after": None, "correction": 0.0, "modes": []}
    residues = boundary_residues(model, every_mode=True)
    if not residues:
        return Q, {**out, "reason": "no plant mode on or beyond the stability boundary that R must cancel"}
    unknowns, nud = (Q.n + Q.p) * Q.m, model.nu + model.nd
    if unknowns > CANCEL_UNKNOWNS:
        return Q, {**out, "reason": f"the correction has {unknowns} unknowns (> {CANCEL_UNKNOWNS}): Q kept as designed"}
    # the u, d decoupling kept on the design's points, thinned to twice as many real equations as unknowns
    k = min(lam.size, max(CANCEL_POINTS, -(-unknowns // max(Q.p * nud, 1)))) if nud else 0
    pts = lam[np.unique(np.linspace(0, lam.size - 1, k).round().astype(int))]
    Qc, rel = cancel_residues(Q, residues, pts, _values(model.augmented(), pts)[:, :, :nud])
    out.update({"correction": rel, "modes": [complex(p) if complex(p).imag else float(complex(p).real)
                                             for p, _ in residues]})
    if Qc is Q:
        return Q, {**out, "reason": "Q's resolvent cannot be evaluated at the modes or points: Q kept as designed"}
    before, after, why = _correction_refused(model, Q, Qc, "the exact cancellation", fnm, MF, lam, norm, systems,
                                             budget, smarg, dec_tol)
    out.update({"error_before": before, "error_after": after})
    if why:
        return Q, {**out, "reason": f"{why}: Q kept as designed"}
    return Qc, {**out, "corrected": True, "reason": "the plant modes on or beyond the boundary cancel exactly in R"}


def _correction_refused(model, Q, Qc, what, fnm, MF, lam, norm, systems, budget, smarg, dec_tol):
    """The acceptance of a correction ``Qc`` of the shipped filter ``Q`` (:func:`_plant_mode_cancellation`,
    :func:`_ud_redecoupling`): ``(error of Q, error of Qc, None or why it is refused)`` — refused where the error
    measured on Qc (:func:`_shipped_error`, the same points) exceeds the design's one limit ``budget.limit``
    (:class:`ErrorBudget`: the certified optimum times ``1 + reltol`` plus :data:`ZERO_ERROR_FLOOR` of ``||M Mr||``;
    not ``reltol`` of Q's own error, which let every stage add its ``reltol``), or Qc fails the post-conditions."""
    e0 = float(_shipped_error(model, Q, fnm, MF, lam, norm, systems))
    e1 = float(_shipped_error(model, Qc, fnm, MF, lam, norm, systems))
    if not e1 <= budget.limit:
        return e0, e1, f"{what} would worsen the match from {e0:.6g} to {e1:.6g} ({budget.says()})"
    try:
        check_generator(ResidualGenerator(Qc, model, "approximate_model_matching"), decouple=("u", "d"), faults=[],
                        smarg=smarg, dec_tol=dec_tol)
    except DesignError as exc:
        return e0, e1, f"the corrected filter fails its post-conditions ({exc})"
    return e0, e1, None


#: a fault is required by a matching row where that row of Mr has a peak on the design's points above this fraction of
#: the row's peak: the nonzero entries of Mr (a structural zero evaluates to 0 exactly; a realisation's rounding to
#: ~eps·cond, far below)
REQUIRED_RTOL = 1e-10


def required_faults(model, Mr: LTI, lam: np.ndarray) -> np.ndarray:
    """``(rows, faults)`` booleans: fault j is required by residual i where row i of Mr is not zero in fault j's
    columns (peak of ``|Mr_ij(λ)|`` on the points above :data:`REQUIRED_RTOL` of the row's peak)."""
    Mv = np.abs(_values(Mr, lam))
    peak = np.max(Mv, axis=0, initial=0.0)  # rows × fault columns
    by_fault = np.stack([np.max(peak[:, np.arange(model.nf)[f.columns]], axis=1, initial=0.0) for f in model.faults],
                        axis=1) if model.faults else np.zeros((Mr.p, 0))
    top = np.max(peak, axis=1, initial=0.0)[:, None]
    return (by_fault > REQUIRED_RTOL * top) & (top > 0)


def normalised_leak(model, Q: LTI, required: np.ndarray, smarg, dec_tol: float) -> dict:
    """The post-condition judge's figures of the matching filter Q on Varga's normalised form: each row scaled so that
    its weakest required fault (:func:`required_faults`) has unit gain — :func:`..toolkit.postconditions.check_generator`
    with that structure, ``normalize=False`` (Q keeps its rows: they match M·Mr), ``FDtol = 0`` (a matching row's
    faults need no relative visibility) and ``raise_error=False``. ``fig['decoupling']`` is the largest normalised
    u/d leak; its failures ``'decoupling'`` name the rows above ``dec_tol`` (the ``'structure'`` ones, faults Mr's
    row does not require, are no condition of matching and are not read)."""
    gen = ResidualGenerator(Q, model, "approximate_model_matching")
    return check_generator(gen, decouple=("u", "d"), structure=required.astype(int), faults=model.fault_names,
                           FDtol=0.0, smarg=smarg, dec_tol=dec_tol, raise_error=False, normalize=False)


def _leak_of(fig: dict) -> float:
    """The u/d leak of a :func:`normalised_leak` figure set as a double-precision evaluation of the filter's
    realisation can show it: the judge's reading ``decoupling`` (the stored filter's value,
    :func:`..toolkit.postconditions._decoupled_reading`, the same whatever the row scaling and diagonal state scaling) plus
    ``decoupling_sensitivity`` (the first-order change of that leak under rounding u of every entry of the
    realisation: what a double-precision evaluation or simulation of this realisation may add; the rule and its
    derivation: :func:`_ud_leak_refused`). The rows' largest reading plus their largest sensitivity: per row,
    :func:`_row_leaks`. Random H∞ seed 4's shipped filter (order 70, non-minimal: Hankel singular values down to
    1e-25 of the largest) reads 2.0e-8 of its weakest required fault with a sensitivity 3.4e-7, and numpy's plain
    evaluation read it at 1.8e-7."""
    return float(fig.get("decoupling", np.nan) + fig.get("decoupling_sensitivity", 0.0))


def _row_leaks(fig: dict, p: int) -> list[float]:
    """Per row (p of them), :func:`_leak_of` of that row: its reading (``fig['decoupling_rows']``) plus its own
    realisation's sensitivity (``fig['decoupling_row_sensitivities']``: the judge reads each row on the states it
    sees, :func:`..toolkit.postconditions.row_system`) — not the rows' largest sensitivity: a random H∞ seed 17 lowered
    filter ([5, 8] rows, mindeg) read its order-5 row at 2.6e-7 … 5.0e-7 with the other row's sensitivity. No row
    figures (the judge stopped before its decoupling stage): ``[_leak_of(fig)]`` for every row."""
    reads = [float(d) for d in fig.get("decoupling_rows", [])]
    own = fig.get("decoupling_row_sensitivities")
    if len(reads) != p or own is None:
        return [_leak_of(fig)] * p
    return [d + float(s) for d, s in zip(reads, own)]


#: :func:`_ud_redecoupling`: the most numerator unknowns ``(n_q + rows)·(p + m)`` it solves for (a dense least-squares
#: problem on every column of Ge, ~8·unknowns³ flops: 2000 unknowns took minutes on the realisation seeds); a row's
#: own refit (:func:`_row_redecoupling`) has ``(n_i + 1)·(p + m)``
REDECOUPLE_UNKNOWNS = 1000
#: :func:`_ud_redecoupling`'s real equations per unknown (its points thinned to that many)
REDECOUPLE_ROWS = 8
#: :func:`_ud_redecoupling`: the Hankel singular values below this fraction of the largest are dropped by the
#: minimal balanced realisation it refits on (the error is at most twice their sum; the candidate is kept only if its
#: matching error is within the design's error budget, :class:`ErrorBudget`)
REDECOUPLE_HSV_RTOL = 1e-12


def _ud_redecoupling(model, Q, required, fnm, MF, lam, norm, systems, budget, smarg, dec_tol,
                     fig0=None, rows=None) -> tuple[LTI, dict]:
    """Stage of :func:`approximate_model_matching`: ``(Q', info['ud_redecoupling'])``, the shipped filter realised
    again or with its numerator refitted so that ``Q·[Gu Gd; I 0]`` is zero on the design's points while ``Q·[Gf Gw; 0
    0]`` is kept (:func:`_decoupling_refit`) — run only where a row's u/d leak on the normalised form, as a
    double-precision evaluation of its realisation can show it (:func:`normalised_leak`, :func:`_row_leaks`: the
    judge's reading plus the realisation's sensitivity; the rule: :func:`_ud_leak_refused`), exceeds ``dec_tol``.

    Why: ``Q = Y·Φ·Q0`` decouples u, d to the rounding of Q0 times Y's gain, and a matching row's weakest required
    fault can be small beside its error response (benchmarks/ammp_random_set.py, H∞ seeds 2 and 10: normalised u/d
    leaks 1.83e-7 and 3.63e-7, returned before; refitted 1.3e-8 and 1.5e-8, errors 1.84821e-6 → 1.84822e-6 and
    1.36527e-8 → 1.36691e-8). And the shipped realisation can be so ill-conditioned that its leak, small as stored,
    is not what an evaluation in double reads: seed 4 (order 70, Hankel singular values down to 1e-25 of the largest)
    leaks 2.0e-8 with a sensitivity 3.4e-7 (numpy's plain evaluation: 1.8e-7); its refit on its own realisation keeps
    that sensitivity. So the candidates (:func:`_redecoupling_candidates`), the first that passes kept: the refit of
    Q's realisation, then the minimal balanced realisation of Q (Hankel singular values above
    :data:`REDECOUPLE_HSV_RTOL` of the largest; seed 4: order 22, sensitivity 4.6e-11, leak 4.1e-7) refitted to Q's
    own fault/noise response (the truncation moves ``Q·[Gf Gw]``: at reltol 1e-6 seed 10's order-33 truncation, its
    dropped values below 1e-12 of the largest, moved the error from 3.47e-8 to 2.5e-4 — its u/d refit alone kept
    that; refitted to Q's response: error 3.2e-9, leak 2.9e-8, sensitivity 2.2e-10, numpy 2.8e-8 where the shipped
    filter read 1.7e-8 with a sensitivity 9.9e-7 and numpy 2.4e-7). A candidate is kept only if every row's leak
    plus sensitivity is ``dec_tol`` or below, the error measured on it (:func:`_shipped_error`, the same points) is
    within the design's one limit (:class:`ErrorBudget`; plus 1e-9 of ``||M Mr||`` for exactly matchable references,
    as
    :func:`_plant_mode_cancellation`) and it passes the post-conditions. Where none does and Q has several rows,
    the rows are re-decoupled one by one (:func:`_row_redecoupling`). Bounded to :data:`REDECOUPLE_UNKNOWNS`
    unknowns per refit; the points (the design's and the judge's grid, :func:`..toolkit.postconditions._eval_points`)
    are thinned to :data:`REDECOUPLE_ROWS` real equations per unknown.
    The note: ``refined``, ``leak_before``/``leak_after`` (normalised, reading plus sensitivity, the worst row),
    ``row_leaks`` (each row's, of the returned filter), ``error_before``/``error_after``, ``unknowns``,
    ``realisation`` (of the kept candidate: ``'shipped'`` (its refit), ``'minimal balanced'``, ``'balanced'``,
    ``'balanced Schur'``, ``'Schur'`` (their refits to Q's response) or ``'per row'`` with ``row_realisations``),
    ``reason``; ``figures``: the judge's normalised figures of the returned Q (:func:`normalised_leak`). ``fig0``: those
    figures of Q where the caller has read them already; ``rows``: Q's rows, each on its own realisation, where the
    caller has them (:func:`_verified`: the lowered rows Q stacks), for :func:`_row_redecoupling`."""
    nud = model.nu + model.nd
    if fig0 is None:
        fig0 = normalised_leak(model, Q, required, smarg, dec_tol)
    rows0 = _row_leaks(fig0, Q.p)
    before = float(max(rows0, default=_leak_of(fig0)))
    out = {"refined": False, "leak_before": before, "leak_after": before, "row_leaks": rows0, "error_before": None,
           "error_after": None, "unknowns": int((Q.n + Q.p) * Q.m), "realisation": None,
           "figures": fig0}
    if not before > dec_tol:
        return Q, {**out, "reason": f"the normalised u/d leak {before:.3g} is within dec_tol = {dec_tol:g}"
                                    if np.isfinite(before) else "the normalised u/d leak cannot be read"}
    if not nud:
        return Q, {**out, "reason": "no u or d to decouple"}
    reasons = []
    for what, S in _redecoupling_candidates(model, Q, lam):
        if isinstance(S, str):
            reasons.append(f"{what}: {S}")
            continue
        fig = normalised_leak(model, S, required, smarg, dec_tol)
        leaks = _row_leaks(fig, S.p)
        after = float(max(leaks, default=_leak_of(fig)))
        out.update({"leak_after": after, "unknowns": int((S.n + S.p) * S.m)})
        if not after <= dec_tol:
            reasons.append(f"{what}: the refined filter still leaks {after:.3g} > dec_tol = {dec_tol:g}")
            continue
        e0, e1, why = _correction_refused(model, Q, S, "the refinement", fnm, MF, lam, norm, systems, budget, smarg,
                                          dec_tol)
        out.update({"error_before": e0, "error_after": e1})
        bad = [f"{c}: {m}" for c, m in zip(fig.get("failed_conditions", ()), fig.get("failures", ())) if c != "structure"]
        if bad:
            why = why or f"the refined filter fails its post-conditions ({'; '.join(bad)})"
        if why:
            reasons.append(f"{what}: {why}")
            continue
        return S, {**out, "refined": True, "realisation": what, "figures": fig, "row_leaks": leaks,
                   "reason": f"u, d re-decoupled on the normalised form ({what} realisation)"}
    if Q.p > 1:
        S, note = _row_redecoupling(model, Q, required, rows0, fnm, MF, lam, norm, systems, budget, smarg, dec_tol,
                                    rows)
        if S is not None:
            return S, {**out, **note, "refined": True, "realisation": "per row",
                       "reason": f"u, d re-decoupled on the normalised form row by row ({note['reason']}; "
                                 f"the whole filter: {'; '.join(reasons)})"}
        reasons.append(f"per row: {note['reason']}")
    return Q, {**out, "leak_after": before, "reason": "; ".join(reasons) + ": Q kept"}


def _refit_points(model, S: LTI, lam: np.ndarray) -> np.ndarray:
    """The refit's points: the design's and the judge's grid of ``S`` (:func:`..toolkit.postconditions._eval_points`),
    thinned to :data:`REDECOUPLE_ROWS` times as many real equations (2·p·columns per point) as unknowns: the
    least-squares solve costs ~REDECOUPLE_ROWS·unknowns³ (1000 unknowns: ~1 s)."""
    unknowns = int((S.n + S.p) * S.m)
    pts = np.concatenate([lam, _eval_points(model, S)[1]])
    pts = pts[np.argsort(np.angle(pts) if model.dt else pts.imag)]
    k = min(pts.size, -(-REDECOUPLE_ROWS * unknowns // (2 * S.p * model.augmented().m)))
    return pts[np.unique(np.linspace(0, pts.size - 1, k).round().astype(int))]


def _redecoupling_candidates(model, Q: LTI, lam: np.ndarray):
    """The candidates :func:`_ud_redecoupling` judges, in order, lazily: ``(what, filter or why not)`` — the refit of Q's
    own realisation (``'shipped'``), then Q's minimal balanced realisation (SLICOT AB09AD's square-root balanced
    truncation at the Hankel singular values above :data:`REDECOUPLE_HSV_RTOL` of the largest; skipped where SLICOT
    refuses it or it drops nothing) refitted so that its u/d response is zero and its fault/noise response Q's
    (``'minimal balanced'``; ``'balanced'`` where the truncation drops nothing: Q's balanced coordinates), then that
    realisation in the coordinates of its real Schur form (``'balanced Schur'``), then Q's in its own Schur form
    (``'Schur'``) — each refitted to Q's fault/noise response: the realisation's rounding sensitivity, which the rule
    charges, depends on the coordinates (:func:`_schur_realisation`). A refit above :data:`REDECOUPLE_UNKNOWNS`
    unknowns is not made (its why instead).

    The truncation alone is not a candidate: its error, at most twice the dropped Hankel values (≤ 1e-12 of the
    largest each), is absolute in Q, and the u/d block is a cancellation ``|Q||Ge|`` up to 1e7 times the weakest fault
    gain — random H∞ seed 10 at reltol 1e-6: the order-33 truncation of the order-51 filter leaks 18.6 of its weakest
    fault (numpy 14.2) and moves the error from 3.47e-8 to 2.5e-4; refitted on its own response, the leak is 6e-10 and
    the error still 2.5e-4; refitted to Q's response, the leak 2.9e-8 and the error 3.2e-9."""
    yield "shipped", _refit_or_why(model, Q, lam)
    if not Q.n:
        return
    try:
        hsv = Q.balanced_truncation(order=Q.n)[1]
        Qm = Q.balanced_truncation(tol=REDECOUPLE_HSV_RTOL * float(np.max(hsv, initial=0.0)))[0]
    except (SlycotError, ValueError, np.linalg.LinAlgError):
        Qm = Q
    # the shipped and the minimal balanced realisation first (where they pass, their filter is the one returned),
    # then the other coordinates, the lower order first (random H2 seed 7: the Schur realisation first kept its
    # optimal filter at 87 states where the minimal balanced one has 30)
    if 0 < Qm.n < Q.n:
        yield "minimal balanced", _refit_or_why(model, Qm, lam, ref=Q)
    elif Qm.n == Q.n and Qm is not Q:  # nothing dropped: Q's balanced coordinates (:func:`_schur_realisation`'s why)
        yield "balanced", _refit_or_why(model, Qm, lam, ref=Q)
    if 0 < Qm.n <= Q.n and Qm is not Q:
        yield "balanced Schur", _refit_or_why(model, _schur_realisation(Qm), lam, ref=Q)
    yield "Schur", _refit_or_why(model, _schur_realisation(Q), lam, ref=Q)


def _schur_realisation(S: LTI) -> LTI:
    """``S`` in the coordinates of the real Schur form of its A: ``(Uᵀ A U, Uᵀ B, C U, D)``, ``U`` orthogonal
    (LAPACK dgees through :func:`scipy.linalg.schur`; A quasi-upper-triangular).

    **Why** (:func:`_redecoupling_candidates`). The rule (:func:`_ud_leak_refused`) charges a realisation its
    sensitivity ``u·(|W||A||Z| + |W||B||G| + |C||Z| + |D||G|)`` (``W = C(λI − A)^{-1}``, ``Z = (λI − A)^{-1}B G``),
    which depends on the coordinates: invariant under a diagonal similarity (``|W D⁻¹||D A D⁻¹||D Z| = |W||A||Z|``:
    TB01ID's balancing changes nothing), not under any other. Entry by entry ``|x|ᵀ|M||y| ≤ ‖x‖₂ ‖ |M| ‖₂ ‖y‖₂ ≤
    √n ‖x‖₂‖M‖₂‖y‖₂``, and the 2-norms of ``W, A, Z, B, C`` are invariant under an orthogonal similarity: in Schur
    coordinates the sensitivity is within √n of the norm products of the realisation it came from, whatever
    alignment of signs and magnitudes that one's entries have — a bound, not a minimum (the other coordinates the
    candidates try: the balanced realisation, whose input-to-state and state-to-output maps have the least
    ``tr P + tr Q``, Mullis & Roberts 1976's minimum-roundoff-noise structures). The form is computed backward stably
    (the realisation of data perturbed by ``~n·u·‖A‖₂``): its response differs from S's by about that, which the
    refit that follows (:func:`_decoupling_refit` to S's fault/noise response) and the judge (reading of the stored
    filter) account for. Measured: random H∞ seed 7 at reltol 1e-6, the optimal filter (order 87, two rows): as
    shipped, row 1 reads 6.5e-8 with a sensitivity 4.1e-8 (refit: 7.1e-8 + 4.1e-8 = 1.12e-7 > dec_tol, so main
    shipped the rows apart, 174 states); in Schur coordinates the sensitivity is 2.4e-9 and the refit reads 2.2e-9
    (sum 4.5e-9), order 87."""
    T, U = sla.schur(S.A, output="real")
    return LTI(T, U.T @ S.B, S.C @ U, S.D, S.dt)


def _refit_or_why(model, S: LTI, lam: np.ndarray, ref: LTI | None = None):
    """:func:`_decoupling_refit` of ``S`` on :func:`_refit_points` (``ref``: the filter whose fault/noise response it
    keeps, default S's own), or why it is not made (above :data:`REDECOUPLE_UNKNOWNS` unknowns)."""
    unknowns = int((S.n + S.p) * S.m)
    if unknowns > REDECOUPLE_UNKNOWNS:
        return f"the correction has {unknowns} unknowns (> {REDECOUPLE_UNKNOWNS})"
    return _decoupling_refit(model, S, _refit_points(model, S, lam), ref=ref)


def _row_redecoupling(model, Q, required, leaks, fnm, MF, lam, norm, systems, budget, smarg, dec_tol, rows=None,
                      weighted=False):
    """:func:`_ud_redecoupling` row by row, where the whole filter's candidates failed: ``(Q' or None, note)``. Each
    row on its own realisation (``rows``, default its minimal realisation :func:`_minimal_row`; Q' stacks them,
    ``vstack``: a row's states are its own; a lowered filter's minimal realisation mixes its rows' states: seed 7's
    order-26 row read on all 113);
    a row whose leak (``leaks``, :func:`_row_leaks`) exceeds ``dec_tol`` takes the first of its minimal realisation as
    it is, then :func:`_redecoupling_candidates` of it (refits of ``(n_i + 1)·(p + m)`` unknowns, not the whole
    filter's ``(n + rows)·(p + m)``) whose own leak plus sensitivity is at most ``dec_tol`` and with which the whole
    filter passes :func:`_correction_refused` (error within the design's budget, post-conditions). Q' is then judged
    whole:
    every row's leak at most ``dec_tol``. Why: a lowered row of ``mindeg`` is a new realisation beside the optimal
    rows; random H∞ seed 7's whole filter (order 113 after stacking an order-26 row on an order-87 one) has 1035
    unknowns (> :data:`REDECOUPLE_UNKNOWNS`), its lowered row 243. ``weighted``: a row's candidates are instead its
    own realisation refitted with the u/d equations weighted (:func:`_weighted_row_refits`; the last stage of
    :func:`_weighted_redecoupling`). Note: ``row_realisations`` (per row: ``'kept'``,
    ``'minimal'``, ``'shipped'``, ``'minimal balanced'``), ``row_leaks``, ``error_before``/``error_after``,
    ``leak_after``, ``figures``, ``reason``."""
    rows = list(rows) if rows is not None else [_minimal_row(Q[i, :]) for i in range(Q.p)]
    kinds, why, e01 = ["kept"] * Q.p, [], (None, None)
    for i in np.flatnonzero(np.asarray(leaks) > dec_tol):
        tried = []
        cands = _weighted_row_refits(model, rows[i], lam) if weighted else \
            [("minimal", rows[i]), *_redecoupling_candidates(model, rows[i], lam)]
        for what, S in cands:
            if isinstance(S, str):
                tried.append(f"{what}: {S}")
                continue
            leak = _leak_of(normalised_leak(model, S, required[i:i + 1], smarg, dec_tol))
            if not leak <= dec_tol:
                tried.append(f"{what} (order {S.n}): leaks {leak:.3g}")
                continue
            trial = vstack(rows[:i] + [S] + rows[i + 1:])
            e0, e1, bad = _correction_refused(model, Q, trial, f"row {i + 1}'s {what} realisation", fnm, MF, lam,
                                              norm, systems, budget, smarg, dec_tol)
            if bad:
                tried.append(f"{what} (order {S.n}): {bad}")
                continue
            rows[i], kinds[i], e01 = S, what, (e0, e1)
            break
        else:
            return None, {"reason": f"row {i + 1} (leak {leaks[i]:.3g}): " + "; ".join(tried)}
        why.append(f"row {i + 1}: {what} (order {rows[i].n})")
    S = vstack(rows)
    fig = normalised_leak(model, S, required, smarg, dec_tol)
    after = _row_leaks(fig, S.p)
    if not max(after) <= dec_tol:
        return None, {"reason": f"the rows stacked leak {', '.join(f'{x:.3g}' for x in after)}"}
    return S, {"row_realisations": kinds, "row_leaks": after, "leak_after": float(max(after)), "figures": fig,
               "error_before": e01[0], "error_after": e01[1], "unknowns": int(max((r.n + 1) * Q.m for r in rows)),
               "reason": "; ".join(why)}


def _ud_leak_refused(fig: dict, dec_tol: float, leaks=None) -> None:
    """The post-condition of :func:`approximate_model_matching` on the normalised u/d leak: no row of the returned
    filter may leak u/d above ``dec_tol`` of its weakest required fault's gain as a double-precision evaluation of the
    returned realisation can show it — the judge's reading of the stored filter (:func:`normalised_leak`,
    :func:`..toolkit.postconditions._decoupled_reading`, its error bound named beside it) plus the realisation's
    sensitivity (``leaks``: per row, :func:`_row_leaks`; default each row's reading plus the rows' largest
    sensitivity); else a DesignError naming the row, the reading, the sensitivity, that gain and dec_tol.

    **The rule and why.** The user's residual is computed in double from the shipped realisation (the FMU simulates
    ``x' = A_q x + B_q y``, ``r = C_q x + D_q y``). To first order, what a double-precision evaluation computes is the
    exact response of data whose every entry is perturbed by a relative ``δ``, ``|δ| ≤ u`` (componentwise backward
    stability of each product and of the solve with ``λI − A_q``, Higham 2nd ed. ch. 3, 9), so its u/d block is
    ``R_ud + ΔR``, ``|ΔR| ≤ u·(|W||A_q||Z| + |W||B_q||G| + |C_q||Z| + |D_q||G|)`` — the judge's
    ``decoupling_sensitivity`` (``W = C_q(λI − A_q)^{-1}``, ``Z = (λI − A_q)^{-1}B_q G``, ``G = [Gu Gd; I 0]``). The
    shipped realisation meets ``dec_tol`` as a double evaluation can show it iff reading + sensitivity ≤ dec_tol. The
    reading alone (before) returned random H∞ seed 10 at reltol 1e-6 (order 51: reading 1.7e-8, sensitivity 9.9e-7,
    numpy's plain evaluation 2.4e-7 of its weakest required fault) while the re-decoupling had refused its refits on
    reading + sensitivity: one rule now, and :func:`_ud_redecoupling` first looks for a realisation that meets it.
    The bound is worst-case in the signs of the roundings: numpy's dense-LU evaluation read 0.24 (seed 10) and 0.53
    (seed 4) of it."""
    scales = fig.get("scales") or []
    reads = [float(d) for d in fig.get("decoupling_rows", [])]
    top = float(fig.get("decoupling_sensitivity", 0.0))
    leaks = [d + top for d in reads] if leaks is None else leaks
    bad = []
    for i, (d, e, x) in enumerate(zip(reads, fig.get("decoupling_row_errors", []), leaks)):
        if x > dec_tol:
            gain = 1.0 / scales[i] if i < len(scales) and scales[i] else float("nan")
            bad.append(f"residual {i + 1}: u/d leak {d:.3g} (± {e:.2g}) plus the realisation's rounding sensitivity "
                       f"{x - d:.2g} = {x:.3g} of its weakest required fault's gain {gain:.3g} > dec_tol = "
                       f"{dec_tol:.3g}")
    if bad:
        raise DesignError("approximate_model_matching: the returned filter leaks u/d above dec_tol on the normalised "
                          "form (rows at unit weakest required fault gain, Varga's normalisation) as a double-"
                          "precision evaluation of its realisation can show it: " + "; ".join(bad)
                          + ". [decoupling] the optimal filter decouples u and d only to the rounding of its basis "
                          "times the gain of Y, and no refit or better-conditioned realisation of it met dec_tol: a "
                          "larger dec_tol, or an Mr whose rows require only faults the row sees strongly")


def _decoupling_refit(model, Q: LTI, pts: np.ndarray, w_ud: float = 1.0, ref: LTI | None = None) -> LTI:
    """Q with ``[B_q; D_q]`` corrected so that, on the points, ``Q·[Gu Gd; I 0]`` is zero and ``Q·[Gf Gw; 0 0]`` is
    unchanged (``ref``: equal to ``ref·[Gf Gw; 0 0]``, the response of the filter Q realises again), in the
    least-squares sense on Q's rows at unit weakest fault gain.

    With ``(A_q, C_q)`` fixed, ``Q(λ) = K(λ) Θ`` is linear in ``Θ = [B_q; D_q]``; the correction Δ solves
    ``K(λ_k) Δ Ge(λ_k) = [−R_ud(λ_k)  R'_fw(λ_k) − R_fw(λ_k)]`` (``R'`` ref's response, zero without ref;
    :func:`..toolkit.least_solve.numerator_fit` on the correction, so its accuracy is relative to the leak and the
    mismatch, not to Θ). The rows are weighted by ``s_i = 1/g_i`` (``g_i`` row i's weakest fault peak on the points,
    of the response kept): the fit is made for ``diag(s) Q`` — ``C_q`` and ``D_q`` scaled, B shared — and its D part
    scaled back. A fault response kept, not a null vector's minimum-norm change
    (:func:`..toolkit.refine.refine_decoupling`), which moved random seed 10's matching error 1.4e-8 → 1.8e-4."""
    from ..toolkit.least_solve import numerator_fit

    nud = model.nu + model.nd
    pts, Gv, R, s = _kept_response(model, Q, pts, ref)
    Qn = LTI(Q.A, Q.B, s[:, None] * Q.C, s[:, None] * Q.D, Q.dt)
    Qn = Qn.balanced()[0] if Qn.n else Qn
    Rn = np.einsum("kiq,kqc->kic", _values(Qn, pts), Gv)
    keep = np.zeros_like(Rn[:, :, nud:]) if ref is None else s[None, :, None] * R[:, :, nud:] - Rn[:, :, nud:]
    target = np.concatenate([-w_ud * Rn[:, :, :nud], keep], axis=2)
    Gw = np.concatenate([w_ud * Gv[:, :, :nud], Gv[:, :, nud:]], axis=2)
    Delta = numerator_fit(Qn.A, Qn.C, Q.dt, pts, target, Gw)[0]
    return LTI(Qn.A, Qn.B + Delta[:Q.n], Qn.C / s[:, None], (Qn.D + Delta[Q.n:]) / s[:, None], Q.dt)


def _kept_response(model, Q: LTI, pts: np.ndarray, ref: LTI | None = None):
    """The response a refit keeps, on the points where Q, ``ref`` and Ge are finite: ``(points, Ge values, R, s)``,
    ``R = ref·Ge`` (``ref`` default Q) and ``s_i = 1/g_i``, ``g_i`` row i's weakest fault peak in R (its largest fault
    entry where no fault is seen): the rows' weights of Varga's normalised form."""
    fsl = model.group_slices()["f"]
    Gv = _values(model.augmented(), pts)
    Qv = _values(Q, pts)
    Kv = Qv if ref is None else _values(ref, pts)
    ok = np.all(np.isfinite(Gv), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2)) & \
        np.all(np.isfinite(Kv), axis=(1, 2))
    pts, Gv, Kv = pts[ok], Gv[ok], Kv[ok]
    R = np.einsum("kiq,kqc->kic", Kv, Gv)
    g = np.array([min((float(np.max(np.linalg.norm(R[:, i, fsl][:, np.arange(model.nf)[f.columns]], axis=1)))
                       for f in model.faults), default=0.0) for i in range(Q.p)])
    s = 1.0 / np.where(g > 0, g, np.maximum(np.max(np.abs(R[:, :, fsl]), initial=0.0), 1e-300))
    return pts, Gv, R, s


def _shipped_error(model, Q, fnm, MF, lam, norm, systems) -> float:
    """Stage of :func:`approximate_model_matching`: the H∞ (refined grid peak) or H2 (quadrature) norm of
    ``Q [Gf Gw; 0 0] − M [Mr 0]`` from the returned filter's own values."""
    def values(L):
        return np.einsum("kij,kjl->kil", _values(Q, L), _values(fnm, L)) - _values(MF, L)

    if norm == "inf":
        return _refined_peak(values, lam, model.dt)
    return _h2_quad(values, systems, model.dt)


def _judged_error(model, Q, fnm, MF, lam, norm, systems) -> float:
    """Stage of :func:`approximate_model_matching`: the returned filter's error ``||Q [Gf Gw; 0 0] − M [Mr 0]||``
    (H∞ refined peak, H2 quadrature, as :func:`_shipped_error`) with ``Q [Gf Gw; 0 0]`` read as the post-conditions
    read R (:func:`_fault_noise_response`: each row without the plant's boundary modes it cancels to its rounding
    bound δ_i) — the reading the shipped realisation was compared in (:func:`_shipped_filter`) and the R-stability
    post-condition that passed it (a row that does not cancel a mode to δ_i keeps it, and is read with it).

    Why not the plain product of values: beside such a mode p the product reads the row's rounding-level residue r
    over the distance, r/|λ − p|, and the design's grid goes as near as ``BESIDE_POLE`` of the pole's scale.
    Approximate audit seed 158 (``Mr = I``, a plant integrator at −8.8e-16, Y's slowest pole 7.9e-5 so the grid's
    lowest point is 8.8e-11 rad/s): the shipped filter's residue ||Q(p) c|| = 3.5e-12 (δ_i: the judge removes it)
    read 1.000425 there, 1.000054 at 1e-9, 1.0000389 = the designed error from 1e-8 up — refused as 4.2e-4 above
    Q = 0's error 1 (limit 1.0001). The figure at 8.8e-11 is the grid's distance, not the filter: at 1e-14 rad/s the
    same product reads 7.6. The exact cancellation cannot lower it (:func:`_plant_mode_cancellation`): Q's values at
    p carry an evaluation rounding ~u·||C_q|| ||(pI − A_q)^{-1}|| ||B_q|| (~1e-6 here), so the corrected filter read
    2.3e-8 there and 3.38 at 8.8e-11. Corrections (:func:`_correction_refused`) and the mindeg candidates are still
    judged on the plain product: a correction whose own residue the reading would remove looked free in amm12's
    trial (seed 122: numpy read 1.0046 at 1e-6 rad/s)."""
    def values(L):
        read = _fault_noise_response(model, Q, L, _values(model.augmented(), L))[0]
        return read - _values(MF, L)

    if norm == "inf":  # (with every lightly damped peak's points, :func:`_resonance_points`)
        return _refined_peak(values, np.unique(np.concatenate([lam, _resonance_points(systems, model.dt)])),
                             model.dt, climb=True)
    return _h2_quad(values, systems, model.dt)


#: :func:`_below_certified_refused`: a reading this far below a certified infeasible level (relative) is a reading
#: that missed the peak. A level SLICOT's SB10FD/SB10DD refuse is infeasible to the accuracy of their Riccati
#: solutions (~1e-6, the slack :func:`_hinf_at` allows its certificate ``||Y Ĝ − F||∞ < γ``); a peak that is a
#: lightly damped resonance is read by :func:`_refined_peak` with 60 points between its half-power points
#: (:func:`_points`), so up to half a step, x = 1/118 of its half-width, from the top of ``1/|1 + j x|``: at most
#: x²/2 = 3.6e-5 low. 5e-5 covers both; the misses it is for are 1.7 % (audit seed 268) and 0.18 % (seed 277)
HINF_CERTIFICATE_RTOL = 5e-5


def _below_certified_refused(err: float, info: dict, standard: bool, norm: str, budget: ErrorBudget) -> None:
    """Post-condition of :func:`approximate_model_matching` on its own reading of the returned error: in the standard
    H∞ problem (the returned error *is* ``||Y Ĝ − F||∞`` for the filter's Y) no admissible filter's error is below a
    level the γ-iteration found infeasible, the lower end ``γ_lo`` of its bracket. A reading below
    ``γ_lo (1 − HINF_CERTIFICATE_RTOL) − floor`` (the certificate's accuracy and the refined reading's resolution;
    ``floor``: :data:`ZERO_ERROR_FLOOR` of ``||M [Mr 0]||``, the rounding of exact matches) proves the reading
    missed the error's peak — the returned figure would be silently wrong, and the true error may exceed the limit
    unseen (approximate audit seed 268: read 4.63869 below the infeasible 4.71833; numpy 4.72841, above the limit
    4.71880) — so it is refused. A bracket whose ends are equal
    was set to a measured error (the last refusal numerical, :func:`solve_standard`) and certifies nothing."""
    if norm != "inf" or not standard or "bracket" not in info:
        return
    lo, hi = (float(x) for x in info["bracket"])
    if not lo < hi or err >= lo * (1.0 - HINF_CERTIFICATE_RTOL) - budget.floor:
        return
    raise DesignError(f"approximate_model_matching: the returned filter's error was read as {err:.9g}, below the "
                      f"γ-iteration's certified infeasible level {lo:.9g} (bracket [{lo:.9g}, {hi:.9g}]) by "
                      f"{(lo - err) / lo:.3g} relative (more than {HINF_CERTIFICATE_RTOL:g} + floor "
                      f"{budget.floor:.3g}): the frequency grid missed the error's peak, the figure cannot be trusted")


def row_orders(Q: LTI, atol: float = 0.0) -> list[int]:
    """McMillan degree of each row of Q (the order of its minimal realisation, :func:`_minimal_row`)."""
    return [int(_minimal_row(Q[i, :], atol).n) for i in range(Q.p)]


def _minimal_row(Qi: LTI, atol: float = 0.0) -> LTI:
    """Minimal realisation of one row: the observable part first (for a row of a stacked realisation
    the other rows' states are exactly unobservable), then the controllable part. SLICOT TB01PD's
    ``job='M'`` (controllable part first) kept one state too many on a row of two stacked order-2 rows
    sharing a pole (Example 5.16): the controllability staircase mixed the rows' states. The observability
    staircase mixes them too where the rows share poles (random H∞ seed 7: row 2 of two order-87 rows stacked, each
    minimal, kept 174 states), so the row is first restricted to the states it sees structurally (C's nonzero columns
    closed under A's coupling, the judge's :func:`..toolkit.postconditions.row_system`): in a stack, its own."""
    return row_system(Qi, [0]).minreal(atol, job="O").minreal(atol, job="C") if Qi.n and Qi.p == 1 else \
        Qi.minreal(atol, job="O").minreal(atol, job="C")


def _least_order(model, gen, fnm, MF, lam, norm, systems, err, budget, smarg, dec_tol, atol, *, required=None):
    """Stage of :func:`approximate_model_matching` with ``mindeg=True``: ``(generator, info['mindeg'])``.

    Row i of the optimal Q is replaced by a lower-order solution of (2) (the module docstring): candidates
    ``Q_i + Y N`` from Type 2 minimum dynamic covers (:func:`..toolkit.covers.left_cover2`; ``N`` the proper
    stable left null-space basis of the whole ``Ge = [Gu Gd Gf Gw; I 0 0 0]``) at ``MINDEG_RTOLS`` and the
    re-solve of (2) from its reference (:func:`_resolved_row`), stable ones only (an unstable least-order row
    is not taken and ``reason`` says so), numerators refitted, near-cancelled modes truncated; the rows are tried
    jointly at their j-th candidate, then one by one, each only below the order it has (the optimal row's balanced
    truncations, a row's last resort, in the one-by-one pass only). The result is
    kept only if its measured error is within ``reltol`` of the optimal filter's (an absolute floor of 1e-9
    ``||M Mr||`` for exactly matchable references) and, after the optimal filter's corrections, its post-conditions
    hold and — with ``required`` (:func:`required_faults`, what ``approximate_model_matching`` passes) — its u/d leak
    on the normalised form (rows at unit weakest required fault gain) is at most ``dec_tol`` (:func:`_verified`);
    a row whose candidates all fail keeps its optimal row. In the one-by-one pass a candidate whose u/d leak read on the
    row alone is certainly above ``dec_tol`` (:func:`_row_leak_alone`) is refused without building the stacked
    filter (random H∞ seed 13: six candidates beside an order-84 row). When no row can be lowered the optimal filter is
    returned unchanged; ``reason`` says why, candidate by candidate. A lowered filter's ``leak`` and its corrections' notes
    (``plant_mode_cancellation``, ``ud_redecoupling``) are in the returned info."""
    from ...margin import margin_limit
    from ..toolkit.postconditions import default_smarg

    Q, dt = gen.Q, model.dt
    before = row_orders(Q, atol)
    out = {"lowered": False, "row_orders_before": before, "row_orders": before, "order_before": int(Q.n),
           "order": int(Q.n), "error_before": float(err), "error": float(err), "row_methods": ["kept"] * Q.p}
    if not any(before):
        out["reason"] = "every row is static (order 0): already least order"
        return gen, out
    try:
        N = _whole_null_basis(model, smarg, atol)
        basis_note = []
    except DesignError as exc:  # the rows are then lowered only by their near-cancellations (N empty)
        N = LTI.zero(0, Q.m, dt)
        basis_note = [f"the null-space basis of [Gu Gd Gf Gw; I 0 0 0] failed ({exc}): rows lowered by their "
                      f"near-cancelled modes only"]
    lim = margin_limit(default_smarg(dt) if smarg is None else float(smarg))
    rows = [_minimal_row(Q[i, :], atol) for i in range(Q.p)]
    optimal, targets = list(rows), []
    methods, why, best = ["kept"] * Q.p, [], None
    # the numerator refit's points: the design's grid, thinned to REFIT_POINTS (a few unknowns per row)
    pts = lam[np.unique(np.linspace(0, lam.size - 1, min(lam.size, REFIT_POINTS)).round().astype(int))]
    Ge = _values(model.augmented(), pts)
    ok = np.all(np.isfinite(Ge), axis=(1, 2))
    pts, Ge = pts[ok], Ge[ok]
    cands, truncations, notes = [], [], []
    fw = _faults_and_noise_as_faults(model)
    # the free poles of a stable cover: model_matching's default sdeg (at 0 discrete, −1 continuous); the plant's own
    # (its default without sdeg) left seed 17's least-squares point of the admissible set unstable at every order
    choose = lambda count: pick_poles(None, 0.0 if dt else -1.0, count)  # noqa: E731
    # half the guard's allowance (:func:`_verified`): a candidate whose response is already that close to the row's
    # needs no pole refit
    slack = 0.5 * max(budget.limit - float(err), budget.floor)  # (the room the optimal filter leaves in the budget)
    for i, Qi in enumerate(rows):
        cs, ns = _row_candidates(Qi, N, lim, dt, atol, choose) if Qi.n else ([], [])
        if Qi.n:
            Xr, why_r = _resolved_row(fw, Qi, fnm, smarg, dec_tol, atol)
            if Xr is not None and Xr.n < Qi.n:  # first among equal orders: a cover of its order may fail the guard
                cs = sorted([("re-solve", Xr)] + cs, key=lambda c: c[1].n)
            elif why_r:
                ns.append(why_r)
        target = np.einsum("kij,kjl->kil", _values(Qi, pts), Ge)  # Q_i Ge on the points
        targets.append(target)
        h0, kept = _hankel_order(Qi) if Qi.n else 0, []
        for rtol, Xi in cs:
            Xi = _refit_numerator(Xi, Qi, target, Ge, pts, slack)
            h = _hankel_order(Xi)
            if h > h0:  # fewer states, more significant modes: not lower
                ns.append(f"its order-{Xi.n} solution of (2) ({rtol if isinstance(rtol, str) else f'rtol {rtol}'}) "
                          f"has {h} Hankel singular values above {HANKEL_RTOL:g} of its largest, the optimal row {h0}")
                continue
            if h < Xi.n:  # its near-cancelled modes truncated (then refitted) first, the row itself next
                Xt = _truncated(Xi, h)
                if Xt is not None:
                    kept.append((rtol, _refit_numerator(Xt, Qi, target, Ge, pts, slack)))
            kept.append((rtol, Xi))
        kept.sort(key=lambda c: c[1].n)
        last = []
        for order in _truncation_orders(Qi):
            # last, where every cover and the re-solve fail: the optimal row itself balanced-truncated to its Hankel
            # order and a few orders above it (the modes below HANKEL_RTOL … 1e-6·HANKEL_RTOL of its largest: the
            # central controller's near-cancellations), its numerator refitted so that its u/d response is zero and its
            # fault/noise response the row's, on the normalised form (:func:`_refit_or_why`). Random H2 seed 13 row 1
            # (order 84, 19 significant Hankel singular values; its covers unstable or leaking, the re-solve leaking
            # 1.8e-3): the order-19 truncation leaks 6.3e-5 of its weakest fault after the refit, order 24 … is
            # decoupled. Judged as every candidate by :func:`_verified` (post-conditions, error within the design's
            # budget, :class:`ErrorBudget`, the normalised u/d leak rule), lowest order first
            Xt = _truncated(Qi, order)
            Xd = _refit_or_why(model, Xt, lam, ref=Qi) if Xt is not None else None
            if isinstance(Xd, LTI):
                last.append((f"the optimal row's balanced truncation to order {order}", Xd))
        cands.append(kept)
        truncations.append(last)
        notes.append(ns)
    # every row at its j-th lowest cover or re-solve candidate (j = 0, 1, …), verified jointly; the first that
    # passes is kept, and the rows then go one by one, lowest order first (the error of the whole filter decides,
    # not each row's). The truncations stay out of the joint pass: they are the last resort of a row whose other
    # candidates fail, and a joint trial at an index beyond a row's covers took that row's highest truncation —
    # random H∞ seed 17 accepted an intermediate [18, 24] (row 2 at its order-24 truncation; one verification the
    # stage's slowest, 59 of 190 s under cProfile) before the row pass lowered it to [5, 8], the result without it
    if sum(1 for c in cands if c) > 1:
        for j in range(max(len(c) for c in cands)):
            trial = [c[min(j, len(c) - 1)][1] if c else r for c, r in zip(cands, rows)]
            cand, verdict = _verified(model, gen, trial, fnm, MF, lam, norm, systems, err, budget, smarg, dec_tol,
                                      atol, required)
            if cand is not None:
                rows, best = trial, (cand, verdict)
                methods = ["least order" if c else "kept" for c in cands]
                cands = [c[:min(j, len(c) - 1)] for c in cands]  # the lower ones, tried one by one
                break
    proper = norm == "2" and not dt  # (:func:`_verified` changes a continuous H2 filter's D: not the row alone)
    # then row by row: its covers, then its truncations, each below the order the row has now (lowest order first;
    # an equal or higher order is no lowering — main's row pass replaced seed 1's accepted order-14 row by an
    # order-15 cover that came before it in the list)
    cands = [[x for x in c + last if x[1].n < r.n] for c, last, r in zip(cands, truncations, rows)]
    for i, Qi in enumerate(rows):
        if not cands[i]:
            if methods[i] == "kept" and Qi.n:
                why += [f"row {i + 1}: {t}" for t in notes[i]] or \
                    [f"row {i + 1}: its minimal realisation (order {Qi.n}) is already least order"]
            continue
        for rtol, Xi in cands[i]:  # lowest order first; the first whose filter passes the guard is taken
            src = rtol if isinstance(rtol, str) else f"cover at rtol {rtol}"
            alone = _row_leak_alone(model, Xi, smarg, dec_tol) if len(rows) > 1 and not proper else None
            if alone is not None:  # certain to fail the stacked filter's post-conditions: not built, not verified
                notes[i].append(f"row {i + 1}: the order-{Xi.n} candidate ({src}) is refused: {alone}")
                continue
            trial = rows[:i] + [Xi] + rows[i + 1:]
            cand, verdict = _verified(model, gen, trial, fnm, MF, lam, norm, systems, err, budget, smarg, dec_tol,
                                      atol, required)
            if cand is None and "error_limit" in verdict and REFIT_POLES_MAX < Xi.n ** 2 <= REFIT_POLES_LATE:
                # refused for its error alone: its poles refitted too (too costly up front for every candidate)
                Xp = _refit_numerator(Xi, optimal[i], targets[i], Ge, pts, slack, REFIT_POLES_LATE)
                if not np.array_equal(Xp.A, Xi.A):
                    trial = rows[:i] + [Xp] + rows[i + 1:]
                    cand, verdict = _verified(model, gen, trial, fnm, MF, lam, norm, systems, err, budget, smarg,
                                              dec_tol, atol, required)
            if cand is not None:
                rows, methods[i], best = trial, "least order", (cand, verdict)
                break
            notes[i].append(f"row {i + 1}: the order-{Xi.n} candidate ({src}) is refused: {verdict['reason']}")
        else:
            if methods[i] == "kept":
                why += [f"row {i + 1}: {t}" if not t.startswith("row ") else t for t in notes[i]]
        if methods[i] != "kept":  # lowered, but lower candidates were refused: those refusals, not "least order"
            # (random H2 seed 17: row 1 at 19, its order-5 covers leaking 2.9e-5 and 2.0e-4 of dec_tol's unit)
            head = f"row {i + 1}: the order-"
            why += [f"row {i + 1} lowered to order {rows[i].n} only: the order-{t[len(head):]}" for t in notes[i]
                    if t.startswith(head) and int(t[len(head):].split()[0]) < rows[i].n]
    why = basis_note + why
    if best is None:
        out["reason"] = "; ".join(why) or "no row can be lowered"
        return gen, out
    cand, verdict = best
    out.update({"lowered": True, "row_orders": [int(r.n) for r in rows], "order": int(cand.Q.n),
                "row_methods": methods, **verdict,
                "reason": "; ".join(why) if why else "every non-static row lowered to the least order of (2)"})
    return cand, out


#: the row pass's pre-check (:func:`_row_leak_alone`) refuses a candidate row only where its u/d reading, less the
#: reading's error bound, exceeds this many times ``dec_tol``: the stacked filter's row is the same transfer function
#: in another realisation (its rounding moves the reading by the error bound, 1e-13 … 3e-9 on random H∞ seed 13), so
#: a refusal is certain by a margin; a candidate within it goes to the full verification (:func:`_verified`)
ROW_LEAK_MARGIN = 10.0


def _row_leak_alone(model, Xi: LTI, smarg, dec_tol: float) -> str | None:
    """Why a one-row change ``Xi`` of the row pass of :func:`_least_order` cannot pass :func:`_verified`'s
    post-conditions, judged on the row alone — or None (not decided: the full verification decides).

    The post-conditions (``check_generator(decouple=('u', 'd'), faults=[])``: the rows unscaled) read each row of a
    stacked filter alone (:func:`..toolkit.postconditions._figures_by_group`): its u/d peak on the grid of its own
    poles and the plant's, a lower bound of the row's ``‖[Q_i Gu  Q_i Gd; Q_i 0]‖∞`` — a function of the row's
    transfer function. The stacked filter's row i *is* ``Xi`` (``vstack`` keeps each row's transfer function; its
    ``minreal`` removes only modes within ``atol``), so a reading of ``Xi`` alone above ``dec_tol`` at a point is a
    value the stacked row takes there too: that filter leaks above ``dec_tol`` (where its own grid missed that point,
    accepting it would pass a real leak). Only a certain refusal is returned: the reading less its error bound (the
    realisation's rounding) above :data:`ROW_LEAK_MARGIN` ``· dec_tol``; never an acceptance. Random H∞ seed 13: the
    row pass verified six row-1 candidates beside the unlowered order-84 row 2 (0.36 … 0.47 s each), all refused for
    row 1's leak 6.7e-6 … 1.13, the same readings as the joint pass's."""
    fig = check_generator(ResidualGenerator(Xi, model, "approximate_model_matching"), decouple=("u", "d"), faults=[],
                          smarg=smarg, dec_tol=dec_tol, raise_error=False)
    d = (fig.get("decoupling_rows") or [0.0])[0]
    e = (fig.get("decoupling_row_errors") or [0.0])[0]
    if np.isfinite(d) and d - e > ROW_LEAK_MARGIN * dec_tol:
        return (f"its u+d leak read on the row alone is {d:.3g} (± {e:.2g}), above {ROW_LEAK_MARGIN:g} dec_tol = "
                f"{ROW_LEAK_MARGIN * dec_tol:.3g}: the stacked filter's row is the same transfer function")
    return None


#: relative rank tolerances of the covers tried by ``mindeg`` (working precision first): the optimal filter's
#: rows carry modes that cancel only to its accuracy (Hankel singular values 1e-11 … 1e-8 of the row's largest,
#: left by the γ-iteration's central controller; the fault/noise response decides, not Q's own scale), which
#: the working-precision tolerance counts as states. Every candidate is verified (post-conditions, error
#: within reltol of the optimum) and the lowest-order one that passes is taken
MINDEG_RTOLS = (None, 1e-11, 1e-10, 1e-9, 1e-8, 1e-7, 1e-6)
#: points of the numerator refit (:func:`_refit_numerator`): unknowns (order + 1)·(p + m), a few dozen at most
REFIT_POINTS = 120


#: a pole of the cover within this relative distance of a pole of the row it lowers is that pole: the cover's
#: rank decisions at rtol move a pole by about cond·rtol (Niemann's model: −5.00000004 for M's −5 at rtol 1e-9)
SNAP_RTOL = 1e-6


def _snapped(X: LTI, Qi: LTI) -> LTI:
    """``X`` in real modal coordinates with each pole within ``SNAP_RTOL`` of a pole of ``Q_i`` replaced by it
    (``X`` unchanged when its A is defective, ill-conditioned modal basis, or no pole is that close). The
    numerator is refitted afterwards (:func:`_refit_numerator`); the guard judges the result."""
    if not X.n or not Qi.n:
        return X
    out = _real_modal(X, Qi.poles())
    return X if out is None else out


def _real_modal(X: LTI, ref: np.ndarray) -> LTI | None:
    """``X`` in real modal coordinates (1×1 blocks and ``[[a, b], [−b, a]]`` pairs on the diagonal of A), each pole
    within ``SNAP_RTOL`` of one of ``ref`` replaced by it; None when A is defective or the modal basis is
    ill-conditioned (condition above 1e8)."""
    n = X.n
    ev, V = np.linalg.eig(X.A)
    if np.linalg.cond(V) > 1e8:
        return None
    A, cols, done = np.zeros((n, n)), [], np.zeros(n, bool)
    k = 0
    for j in np.argsort(-ev.imag):  # a pair's member with positive imaginary part first
        if done[j]:
            continue
        lam = ev[j]
        d = np.abs(ref - lam)
        near = ref[np.argmin(d)] if d.size and d.min() <= SNAP_RTOL * max(1.0, abs(lam)) else lam
        if abs(lam.imag) > 1e-12 * max(1.0, abs(lam)):
            dist = np.where(done | (np.arange(n) == j), np.inf, np.abs(ev - np.conj(lam)))
            mate = int(np.argmin(dist))
            if not np.isfinite(dist[mate]) or k + 2 > n:
                return None
            done[[j, mate]] = True
            v = V[:, j]
            cols += [v.real, v.imag]
            a, b = near.real, abs(near.imag)
            A[k:k + 2, k:k + 2] = [[a, b], [-b, a]]  # A [Re v, Im v] = [Re v, Im v] [[a, b], [-b, a]]
            k += 2
        else:
            if k + 1 > n:
                return None
            done[j] = True
            cols.append(V[:, j].real)
            A[k, k] = near.real
            k += 1
    T = np.column_stack(cols)
    if k != n or np.linalg.cond(T) > 1e8:
        return None
    return LTI(A, np.linalg.solve(T, X.B), X.C @ T, X.D, X.dt)


def _refit_numerator(X: LTI, Qi: LTI, target: np.ndarray, Ge: np.ndarray, pts: np.ndarray,
                     slack: float = 0.0, poles_max: int = 0) -> LTI:
    """Of ``X`` and its numerator refits (with the cover's poles, and with those :func:`_snapped` to ``Q_i``'s),
    the one with the least largest mismatch ``||X(λ_k) Ge(λ_k) − Q_i(λ_k) Ge(λ_k)||`` (``target``) on the points.

    The cover's rank decisions are relative to the compound ``[Q_i; N]``, whose gain can exceed the fault
    gain by 1e4 (Niemann's model at 1 ms): its rounding, small for Q_i, is not small for ``R = Q_i Ge``. With
    ``(A, C)`` fixed, ``X(λ) = K(λ) Θ`` with ``K = [C (λI − A)^{-1}  1]`` and ``Θ = [B; D]`` is linear in Θ:
    ``(Ge(λ_k)ᵀ ⊗ K(λ_k)) vec Θ = vec(target_k)``, stacked over the points (real and imaginary parts), solved
    in the least-squares sense (:func:`..toolkit.least_solve.numerator_fit`, the step the exact matching's
    refit shares). The cover's rank decisions also move its poles by about their tolerance (random seed 9, row 1:
    the order-3 cover at rtol 1e-9 has the least row's poles to ~1e-9 and misses the optimal error 1e-11 by
    4.7e-9), so for a small order (``n² ≤ REFIT_POLES_MAX``, or ``poles_max`` when larger: :func:`_least_order`
    passes ``REFIT_POLES_LATE`` for a candidate the guard refused for its error alone) whose best refit is not exact to ``REFIT_EXACT`` of the
    target, nor within ``slack`` (half the guard's allowance), but within ``REFIT_NEAR`` (poles moved by a rank
    decision, not a different response), ``A`` is refitted too (:func:`..toolkit.least_solve.pole_refit`, the
    exact matching's step)."""
    from ..toolkit.least_solve import numerator_fit, pole_refit

    def refit(S):
        Theta = numerator_fit(S.A, S.C, S.dt, pts, target, Ge)[0]
        return LTI(S.A, Theta[:S.n], S.C, Theta[S.n:], S.dt)

    def mismatch(S):
        return float(np.max(np.linalg.norm(np.einsum("kij,kjl->kil", _values(S, pts), Ge) - target, axis=(1, 2))))

    snapped = _snapped(X, Qi)
    options = [X, refit(X)] + ([refit(snapped)] if snapped is not X else [])
    best = min(options, key=mismatch)
    top = float(np.max(np.linalg.norm(target, axis=(1, 2)), initial=0.0))
    miss = mismatch(best)
    if 0 < best.n and best.n ** 2 <= max(REFIT_POLES_MAX, poles_max) and max(REFIT_EXACT * top, slack) < miss <= REFIT_NEAR * top:
        # in real modal coordinates the poles are the diagonal blocks' entries (about 2n unknowns, not n²)
        M = _real_modal(best, np.zeros(0))
        free = None if M is None else (np.abs(M.A) > 0) | np.eye(M.n, dtype=bool)
        S = best if M is None else M
        out = pole_refit(S.A, S.C, S.dt, pts, target, Ge, free=free)
        if out is not None and np.all(np.isfinite(out[1])):
            A, Theta, _ = out
            options.append(LTI(A, Theta[:best.n], S.C, Theta[best.n:], best.dt))
            best = min(options, key=mismatch)
    return best


#: largest n² of a cover candidate whose poles :func:`_refit_numerator` refits (Gauss–Newton, n² unknowns)
REFIT_POLES_MAX = 36
#: largest n² whose poles are refitted after the guard refused the candidate for its error alone (random seed 5,
#: row 1: the order-7 cover, its poles moved by step (i)'s decisions at 1e-6, misses the optimal error 9.1e-10 by
#: 2.3e-8 and meets it refitted; up front for every candidate this cost 5 s of the seed's 6)
REFIT_POLES_LATE = 64
#: a refit mismatch at or below this fraction of the target's peak is exact (rounding of the response); above
#: REFIT_NEAR it is another response, which a local refit of the poles does not mend (random seed 6: 17 s of
#: refits of truncated candidates, none passing)
REFIT_EXACT = 1e-12
REFIT_NEAR = 1e-6


def _row_candidates(Qi: LTI, N: LTI, lim: float, dt: float, atol: float, choose=None):
    """The distinct lower orders of ``Q_i + Y N`` (:func:`..toolkit.covers.left_cover2` at each of
    ``MINDEG_RTOLS``), from the row and basis as realised and from their balanced minimal realisations
    (:func:`_balanced_minimal`), stable ones only (poles at or inside ``lim``), lowest order first:
    ``([(source, X_i)], notes)`` — the notes say why a cover was not a candidate.

    Why both: the optimal row's realisation (the γ-iteration's central controller) holds states whose Hankel
    singular values are ≤ 1e-13 of the largest (random seed 9: 18 of 33), which the cover's minimal
    realisation of the compound ``[Q_i; N]`` (TB01PD on TB01ID-scaled data) keeps at every tolerance up to 1e-6 —
    the compound is then not minimal, the premise of the cover's least order fails, and no injection lowers the
    row (33 → 33, where the least is 3). Truncated to its Hankel-significant part the row is lowered there
    (to 3 on row 2); the rank decisions on either compound stay sensitive to the tolerance, so both are tried
    and the guard (:func:`_verified`) decides.

    On the last pair (the balanced one when there is one) the cover is also run with the staircase at working
    precision and its step (i) — the removal of the states an output injection through N makes uncontrollable —
    at each of ``MINDEG_VSTAR_RTOLS`` (mode by mode, PBH): those states are known only to the row's accuracy, and
    when step (i) keeps them the staircase has nothing to lower (random seed 5: the balanced compound of order 41
    has 20 such modes at PBH ≤ 2e-9 of its norm, which the deflation at working precision does not remove; kept,
    both rows stop at an unstable order 13, removed, they reach the re-solve's 7; seed 26: 25 → 18; seed 17,
    row 2: 52 → 8; :func:`..toolkit.covers.left_cover2`'s ``vrtol``)."""
    from ..toolkit.covers import left_cover2

    found, notes, unstable = {}, [], []
    pairs = [(Qi, N, "")]
    Qb, Nb = _balanced_minimal(Qi), (_balanced_minimal(N) if N.n else N)
    if Qb.n < Qi.n or Nb is not N:
        pairs.append((Qb, Nb, "balanced "))
    for k, (X1, X2, src) in enumerate(pairs):
        tols = [(rtol, None) for rtol in MINDEG_RTOLS]
        if k == len(pairs) - 1 and X2.p:
            tols += [(None, vr) for vr in MINDEG_VSTAR_RTOLS]
        for rtol, vr in tols:
            at = f"rtol {rtol}" if vr is None else f"rtol {rtol}, step (i) at {vr:g}"
            try:
                Xi = left_cover2(X1, X2, rtol=rtol, atol=atol, vrtol=vr).X
            except (np.linalg.LinAlgError, DesignError, SlycotError, ValueError) as exc:
                notes.append(f"the {src}minimum dynamic cover at {at} failed ({exc})")
                continue
            if Xi.n >= Qi.n or (src, vr, Xi.n) in found:
                continue
            poles = Xi.poles()
            worst = float(np.max(np.abs(poles)) if dt else np.max(poles.real)) if Xi.n else -np.inf
            if worst > lim:
                notes.append(f"its least-order solution of (2) at {at} (order {Xi.n}, {src}cover) is unstable "
                             f"(largest {'|pole|' if dt else 'Re(pole)'} {worst:.6g})")
                unstable.append(Xi.n)
                continue
            found[(src, vr, Xi.n)] = (rtol if not src and vr is None else f"{src}cover at {at}", Xi)
    low = min([X.n for _, X in found.values()] + [Qi.n])
    if choose is not None and X2.p and unstable and min(unstable) < low:  # a lower cover exists, but not stable
        _stable_covers(X1, X2, lim, dt, atol, choose, found, notes, min(low, STABLE_COVER_MAX + 1))
    return sorted(found.values(), key=lambda c: c[1].n), notes


def _stable_covers(X1: LTI, X2: LTI, lim: float, dt: float, atol: float, choose, found: dict, notes: list,
                   top: int) -> None:
    """Into ``found``: the stable covers ``X1 + Y X2`` of order below ``top`` whose free poles are chosen
    (:func:`..toolkit.covers.stable_left_cover` at ``STABLE_COVER_RTOLS`` × ``MINDEG_VSTAR_RTOLS``; its free
    characteristic polynomial at ``choose``, else the admissible one nearest to it). :func:`_row_candidates` asks for
    them only when a cover below its lowest stable candidate was unstable, below that candidate's order and at most
    ``STABLE_COVER_MAX`` (tried on every row, it made the stage 2.4 … 5 times slower on random seeds 4, 9, 10 and lowered nothing there).

    :func:`..toolkit.covers.left_cover2` fixes the cover's free parameters by least squares, which can leave the
    least-order cover unstable where a stable one of that order exists: random seed 17, row 1 — its order-5 cover
    (step (i) at 3e-7) has |pole| 2.16, the order-4 one 1.80, and the covers stopped at the optimal 52; with its
    free poles chosen (deadbeat) the order-5 cover is stable and passes the guard, the re-solve's order. Seed 26
    (not asked: its lowest stable candidate is an order-1 cover that leaks): tried there, stable covers of order
    12 … 14 appear, but step (i) at 3e-7 … 3e-6 removes states the row needs (its PBH values have no gap) and the
    guard (:func:`_verified`) refuses them (u leaks 1.1e-3 … 4.7e-3 of the weakest fault gain)."""
    from ..toolkit.covers import stable_left_cover

    good = (lambda re, im: np.hypot(re, im) <= lim) if dt else (lambda re, im: re <= lim)  # noqa: E731
    for rtol in STABLE_COVER_RTOLS:
        for vr in MINDEG_VSTAR_RTOLS:
            try:
                cv = stable_left_cover(X1, X2, good, choose, rtol=rtol, atol=atol, max_order=top - 1, vrtol=vr)
            except (np.linalg.LinAlgError, DesignError, SlycotError, ValueError) as exc:
                notes.append(f"the stable cover at rtol {rtol}, step (i) at {vr:g} failed ({exc})")
                continue
            if cv is not None and cv.X.n < top:
                found[("stable", rtol, vr, cv.X.n)] = (f"stable cover at rtol {rtol}, step (i) at {vr:g}", cv.X)


#: relative rank tolerances of :func:`_stable_covers` (random seeds 17 and 26: orders 5 and 11 … 13 at 1e-8, 1e-10
#: and 1e-9; none lower at the others of ``MINDEG_RTOLS``)
STABLE_COVER_RTOLS = (None, 1e-10, 1e-8)
#: the highest order :func:`_stable_covers` tries (the Krylov conditions of :func:`..toolkit.covers.stable_left_cover`
#: are meant for low orders)
STABLE_COVER_MAX = 20


#: relative thresholds of the covers' step (i) alone (:func:`_row_candidates`, staircase at working precision;
#: on random seeds 0-29 (benchmarks/mindeg_time.py --seeds) they lower seeds 5, 17 and 26 where no other cover does)
MINDEG_VSTAR_RTOLS = (3e-7, 3e-6)


#: Hankel singular values at or below this fraction of the largest are a realisation's rounding (a row's or the
#: basis' states that a minimal realisation should not have): :func:`_balanced_minimal` drops them
BALANCED_RTOL = 1e-12


def _balanced_minimal(S: LTI) -> LTI:
    """The stable ``S`` balanced and truncated to its Hankel singular values above ``BALANCED_RTOL`` of the largest
    (:meth:`LTI.balanced_truncation`; the error is at most twice the sum of the dropped ones), or ``S`` itself
    when SLICOT refuses (a mode at the boundary)."""
    if not S.n:
        return S
    try:
        hsv = S.balanced_truncation(S.n)[1]
        if not (hsv.size and hsv.max() > 0):
            return S
        return S.balanced_truncation(tol=BALANCED_RTOL * float(hsv.max()))[0]
    except SlycotError:
        return S


#: Hankel singular values above this fraction of the largest count as a row's significant modes
HANKEL_RTOL = 1e-7


def _truncated(S: LTI, order: int) -> LTI | None:
    """``S`` (stable) balanced and truncated to ``order`` states (:meth:`LTI.balanced_truncation`; the error is
    at most twice the sum of the dropped Hankel singular values, here below ``HANKEL_RTOL`` of the largest each),
    or None when SLICOT refuses."""
    try:
        return S.balanced_truncation(order)[0]
    except SlycotError:
        return None


#: :func:`_truncation_orders`: the Hankel thresholds (fractions of the largest value) whose orders are offered
TRUNCATION_RTOLS = (HANKEL_RTOL, 1e-2 * HANKEL_RTOL, 1e-4 * HANKEL_RTOL, 1e-6 * HANKEL_RTOL)


def _truncation_orders(S: LTI) -> list[int]:
    """The distinct orders below ``S.n`` of ``S``'s Hankel singular values above each of :data:`TRUNCATION_RTOLS` of the
    largest (ascending; empty when they cannot be computed): the balanced truncations :func:`_least_order` offers
    last for a row (its Hankel order first)."""
    if S.n == 0:
        return []
    try:
        hsv = S.balanced_truncation(S.n)[1]
    except SlycotError:
        return []
    if not hsv.size or not hsv.max() > 0:
        return []
    return sorted({k for k in (int(np.sum(hsv > r * hsv.max())) for r in TRUNCATION_RTOLS) if 0 < k < S.n})


def _hankel_order(S: LTI) -> int:
    """Number of Hankel singular values of the stable row ``S`` above ``HANKEL_RTOL`` of the largest
    (:meth:`LTI.balanced_truncation`): a candidate with fewer states but more significant modes than the row it
    replaces is not lower (a cover at a loose tolerance can trade cancelled modes for real ones); S.n when
    the singular values cannot be computed."""
    if S.n == 0:
        return 0
    try:
        hsv = S.balanced_truncation(S.n)[1]
    except SlycotError:
        return S.n
    return int(np.sum(hsv > HANKEL_RTOL * hsv.max())) if hsv.size and hsv.max() > 0 else 0


#: :func:`_verified`: a lowered filter whose normalised u/d leak exceeds this multiple of ``dec_tol`` is refused without
#: the re-decoupling refits (they lowered random seed 17's leaks by a factor 14 … 85 where they helped, and moved
#: leaks of 0.6 … 178 by less than a factor 3)
LEAK_REFIT_MAX = 1e3


def _verified(model, gen, rows, fnm, MF, lam, norm, systems, err, budget, smarg, dec_tol, atol, required=None):
    """The filter of the lowered ``rows`` if its post-conditions hold, its measured error is within ``reltol`` of the
    optimal filter's (an absolute floor of 1e-9 ``||M Mr||`` for exactly matchable references) and — with
    ``required`` (:func:`required_faults`) — after the corrections the optimal filter goes through, its u/d leak on
    the normalised form is at most ``dec_tol`` (a corrected filter is judged again: post-conditions, error):
    ``(generator or None, {'error', 'error_limit', 'leak', 'plant_mode_cancellation', 'ud_redecoupling',
    'reason'})``. Post-conditions first, then the error, then the leak: the cheapest refusal of most candidates
    first (the error and the corrections on every candidate made the stage 3.7 times slower on random seed 0).

    The corrections are the optimal filter's, in its order: :func:`_plant_mode_cancellation` (the plant's boundary
    modes cancelled exactly in R) and :func:`_ud_redecoupling` (the numerator refitted where the normalised leak
    exceeds ``dec_tol``), then, if that refit is not kept, :func:`_weighted_redecoupling`; each kept only on its own
    acceptance; none where the leak exceeds ``LEAK_REFIT_MAX`` times ``dec_tol``. Why: a lowered row is a new
    realisation — its numerator fitted to ``Q_i Ge`` on points (:func:`_refit_numerator`), its states chosen by a
    cover's rank decisions — so its u/d leak on the normalised form is not the optimal row's; before, it was judged
    only unnormalised (``faults=[]``): random seeds 0-29 (``benchmarks/mindeg_time.py --judged``) returned lowered
    filters leaking 1.4e-7 … 3.0e-5 of their weakest required fault (H∞ seeds 7, 13, 17; H2 seeds 7, 12, 17)."""
    dt = model.dt
    stacked = vstack(rows) if len(rows) > 1 else rows[0]
    proper = norm == "2" and not dt  # (continuous H2: the error must be strictly proper, :func:`_proper_error`)
    Qm = _proper_error(model, stacked.minreal(atol), MF) if proper else stacked.minreal(atol)

    def post_refused(S, out):  # (the judged generator: check_generator records its figures in its info)
        cand = ResidualGenerator(S, model, "approximate_model_matching")
        try:
            check_generator(cand, decouple=("u", "d"), faults=[], smarg=smarg, dec_tol=dec_tol)
        except DesignError as exc:
            return cand, {**out, "reason": f"the least-order filter fails its post-conditions ({exc}): the optimal "
                                           f"filter is returned"}
        return cand, None

    cand, refused = post_refused(Qm, {})  # (first: the cheapest refusal of most candidates)
    if refused:
        return None, refused
    # on the optimal filter's points and the new filter's poles, against the design's one limit (:class:`ErrorBudget`:
    # the certified optimum, not the optimal filter's error, times 1 + reltol; the absolute floor serves exactly
    # matchable references, errors at rounding level ~1e-12)
    lam2 = np.concatenate([lam, _points([Qm], dt, 100)])
    limit = float(budget.limit)

    def error_refused(S, out):
        e = _shipped_error(model, S, fnm, MF, lam2, norm, systems + [S])
        if e <= limit:
            return e, None
        return e, {**out, "error_limit": limit,
                   "reason": f"the least-order filter's error {e:.6g} exceeds the optimal filter's {err:.6g} "
                             f"beyond the design's budget ({budget.says()}): the optimal filter is returned"}

    err2, refused = error_refused(Qm, {})
    if refused:
        return None, refused
    out = {}
    if required is not None:
        Qm, out["plant_mode_cancellation"] = _plant_mode_cancellation(model, Qm, fnm, MF, lam, norm, systems, budget,
                                                                      smarg, dec_tol)
        fig = normalised_leak(model, Qm, required, smarg, dec_tol)
        out["leak"] = _leak_of(fig)
        if out["leak"] > dec_tol * LEAK_REFIT_MAX or not np.isfinite(out["leak"]):
            return None, {**out, "reason": f"the least-order filter's u/d leak on the normalised form (rows at unit "
                                           f"weakest required fault gain) is {out['leak']:.3g}, above "
                                           f"{LEAK_REFIT_MAX:g} dec_tol: the optimal row is kept"}
        own = None if out["plant_mode_cancellation"]["corrected"] else rows  # (each lowered row's own realisation)
        Qm, note = _ud_redecoupling(model, Qm, required, fnm, MF, lam, norm, systems, budget, smarg, dec_tol, fig,
                                    own)
        if not note["refined"] and note["leak_before"] > dec_tol:
            Qm, note = _weighted_redecoupling(model, Qm, required, fnm, MF, lam, norm, systems, budget, smarg,
                                              dec_tol, note, own)
        out.update({"ud_redecoupling": {k: v for k, v in note.items() if k != "figures"},  # (the judge's figures:
                    "leak": float(note["leak_after"] if note["refined"] else note["leak_before"])})  # not in info)
        if not out["leak"] <= dec_tol:
            return None, {**out, "reason": f"the least-order filter's u/d leak on the normalised form (rows at unit "
                                           f"weakest required fault gain) is {out['leak']:.3g} > dec_tol = "
                                           f"{dec_tol:g} ({note['reason']}): the optimal row is kept"}
        if note["refined"] or out["plant_mode_cancellation"]["corrected"]:  # corrected: judged again
            Qm = _proper_error(model, Qm, MF) if proper else Qm  # (a refit's D is fitted on finite points)
            cand, refused = post_refused(Qm, out)
            if not refused:
                err2, refused = error_refused(Qm, out)
            if refused:
                return None, refused
    return cand, {**out, "error": float(err2), "error_limit": limit}


def _proper_error(model, Q: LTI, MF: LTI) -> LTI:
    """Continuous H2: Q with its feedthrough corrected so that ``R = Q·Ge`` has exactly the feedthrough the design
    requires — zero on the u/d columns, ``D_MF`` (of ``M [Mr 0]``) on the fault/noise ones: ``D_Q·D_G = T``. A
    continuous error ``E = Q [Gf Gw; 0 0] − M [Mr 0]`` with a feedthrough has an infinite H2 norm (white noise gives
    a residual error of infinite variance), and a u/d feedthrough a leak at every frequency. The least change (in
    Frobenius norm) is ``ΔD = (T − D_Q D_G)·D_G⁺`` (the minimum-norm least-squares solution, an SVD:
    ``numpy.linalg.lstsq``); it is made only where T lies in the row space of ``D_G`` (else Q is returned as it is:
    the guard's judges decide). Why: a lowered row's numerator is fitted on finite points
    (:func:`_refit_numerator`, :func:`_decoupling_refit`), which leaves ``D_Q`` free to a fit error: random
    continuous H2 seeds 0, 6 (``benchmarks/mindeg_time.py --judged``): feedthroughs 1.1e-11 and 1.4e-12 of the
    error where the optimal filter's is exactly 0 (``|D_Q||D_fw|`` 0.33 and 4.3e-11)."""
    if not Q.p:
        return Q
    G = model.augmented()
    cols = _fault_noise_columns(model)
    T = np.zeros((Q.p, G.m))
    T[:, cols] = MF.D
    X = T - Q.D @ G.D
    if not np.any(X):
        return Q
    dD = np.linalg.lstsq(G.D.T, X.T, rcond=None)[0].T
    if np.linalg.norm(X - dD @ G.D) > 1e-12 * max(np.linalg.norm(X), np.linalg.norm(Q.D) * np.linalg.norm(G.D)):
        return Q
    return LTI(Q.A, Q.B, Q.C, Q.D + dD, Q.dt)


#: :func:`_weighted_redecoupling`: the weights of the u/d equations against the fault/noise ones, tried in turn
LOWERED_UD_WEIGHTS = (10.0, 100.0)


def _weighted_points(model, S: LTI, lam: np.ndarray) -> np.ndarray:
    """The design's points ``lam`` thinned to :data:`REDECOUPLE_ROWS` real equations per unknown of a weighted refit of
    ``S`` (:func:`_decoupling_refit`: ``(n + rows)·(p + m)`` unknowns, ``2·rows·columns`` equations a point)."""
    unknowns = int((S.n + S.p) * S.m)
    k = min(lam.size, -(-REDECOUPLE_ROWS * unknowns // (2 * S.p * model.augmented().m)))
    return lam[np.unique(np.linspace(0, lam.size - 1, k).round().astype(int))]


def _weighted_row_refits(model, S: LTI, lam: np.ndarray):
    """The candidates of one row ``S`` (on its own realisation) for :func:`_row_redecoupling` in the weighted stage:
    ``(what, refit or why not)`` — :func:`_decoupling_refit` with the u/d equations weighted by each of
    :data:`LOWERED_UD_WEIGHTS`, lazily."""
    unknowns = int((S.n + S.p) * S.m)
    for w in LOWERED_UD_WEIGHTS:
        if unknowns > REDECOUPLE_UNKNOWNS:
            yield f"weighted {w:g}", f"the correction has {unknowns} unknowns (> {REDECOUPLE_UNKNOWNS})"
            continue
        yield f"weighted {w:g}", _decoupling_refit(model, S, _weighted_points(model, S, lam), w)


def _weighted_redecoupling(model, Q, required, fnm, MF, lam, norm, systems, budget, smarg, dec_tol, note,
                           rows=None):
    """For a lowered filter that :func:`_ud_redecoupling` could not bring to ``dec_tol``: ``(Q', note')``, the refit
    of :func:`_decoupling_refit` with the u/d equations weighted by each of ``LOWERED_UD_WEIGHTS`` in turn (the
    design's points ``lam``, thinned to ``REDECOUPLE_ROWS`` real equations per unknown), the first whose normalised
    leak (:func:`_leak_of`) is at most ``dec_tol`` and that :func:`_correction_refused` accepts (error within
    the design's :class:`ErrorBudget`, post-conditions); then, with several rows, each leaking row refitted so on its
    own realisation (``rows``, :func:`_row_redecoupling` with ``weighted``); else ``(Q, note)`` with the weighted
    refits' figures added.

    Why: a lowered row's numerator was fitted to ``Q_i Ge`` on all columns alike (:func:`_refit_numerator`), so its
    fit error sits in the u/d columns as much as in the fault ones; a fault response kept to ``reltol`` of the optimum
    leaves room to move it out of u/d. Random H∞ seed 17 (``benchmarks/mindeg_time.py --judged``): row 2's order-8
    cover leaks 4.7e-7 of its weakest fault, the unweighted refit 1.08e-7, weighted by 10 5.5e-9 (error 2.06520e-7 →
    2.06517e-7); row 1's order-5 re-solve 1.14e-6, 1.8e-7 and 8.0e-8 as the judge read them before it added the
    realisation's sensitivity (:func:`_leak_of`) — read so, every refit of its own realisation stays at 2.6e-7 …
    5.0e-7 (its sensitivity alone is 3.4e-7); its balanced realisation (sensitivity 3.0e-8, refit reading 5.1e-8) is
    what lowers it now, row by row (:func:`_row_redecoupling`, tests/test_mindeg_leak.py)."""
    unknowns = int((Q.n + Q.p) * Q.m)
    if not model.nu + model.nd:
        return Q, note
    pts = _weighted_points(model, Q, lam)
    tried = []
    for w in LOWERED_UD_WEIGHTS if unknowns <= REDECOUPLE_UNKNOWNS else ():
        Qr = _decoupling_refit(model, Q, pts, w)
        leak = _leak_of(normalised_leak(model, Qr, required, smarg, dec_tol))
        tried.append(f"weight {w:g}: {leak:.3g}")
        if not leak <= dec_tol:
            continue
        e0, e1, why = _correction_refused(model, Q, Qr, "the weighted refinement", fnm, MF, lam, norm, systems,
                                          budget, smarg, dec_tol)
        if why:
            tried[-1] += f" ({why})"
            continue
        return Qr, {**note, "refined": True, "leak_after": leak, "error_before": e0, "error_after": e1,
                    "ud_weight": w, "reason": f"u, d re-decoupled on the normalised form with the u/d equations "
                                              f"weighted by {w:g} ({note['reason']} unweighted)"}
    if unknowns > REDECOUPLE_UNKNOWNS:
        tried.append(f"the whole filter's correction has {unknowns} unknowns (> {REDECOUPLE_UNKNOWNS})")
    if Q.p > 1:
        # last, each leaking row weighted on its own realisation: the whole filter's refit mixes the rows' states
        # (its minimal realisation) and can stall — random H2 seed 17, row 1's order-19 truncation beside the optimal
        # order-52 row 2: the whole order-71 filter's weighted refits read row 1 at 1.75e-7, 1.0e-7, 1.0e-7 (weights
        # 10, 100, 1000; plus its sensitivity 9.3e-9), the row alone (order 19) 1.7e-7, 1.7e-9, 4.4e-10 (plus 7.1e-9)
        fig0 = note.get("figures") or normalised_leak(model, Q, required, smarg, dec_tol)
        S, row_note = _row_redecoupling(model, Q, required, _row_leaks(fig0, Q.p), fnm, MF, lam, norm, systems,
                                        budget, smarg, dec_tol, rows, weighted=True)
        if S is not None:
            return S, {**note, **row_note, "refined": True, "realisation": "per row, weighted",
                       "reason": f"u, d re-decoupled on the normalised form row by row with the u/d equations "
                                 f"weighted ({row_note['reason']}; {note['reason']} unweighted; weighted refits of "
                                 f"the whole filter leak {', '.join(tried)})"}
        tried.append(f"per row: {row_note['reason']}")
    return Q, {**note, "reason": f"{note['reason']}; weighted refits leak {', '.join(tried)}"}


def _resolved_row(fw: FDIModel, Qi: LTI, fnm: LTI, smarg, dec_tol: float, atol: float):
    """The least-order exact solution of (2) from the reference ``[Rf_i Rw_i] = Q_i [Gf Gw]`` (exact model
    matching on the model whose faults are ``[f w]``, :func:`.matching.model_matching`; Varga's ``glsol`` on
    the augmented system): ``(row or None, why)``. A second candidate beside the covers: the reference is
    known only to Q_i's rounding, but the augmented pencil works on the plant's and the reference's minimal
    states, where the covers' rank decisions on the compound ``[Q_i; N]`` (its orders jump with the tolerance:
    seed 9's balanced compound 5, 7, 5, 3, 15, 15, 3 at ``MINDEG_RTOLS``) can miss the least order: no cover
    candidate of the re-solve's order appears at all. Random H∞ family, seeds 0-29 at reltol 1e-6
    (``benchmarks/mindeg_time.py --seeds 0-29``): since the covers' step (i) also runs mode by mode at its own
    tolerance (:func:`_row_candidates`) they reach the re-solve's [7, 7] on seed 5 (before: [21, 21]) and lower
    seed 17's row 2 to 8 (before 52, the re-solve's too), and with the stable covers (:func:`_stable_covers`) seed
    17's row 1 to the re-solve's 5; it still lowers further on seed 26 (13 vs 18, before 25: exact to 8e-13; the
    compound's PBH values have no gap, from 7e-12 to 1e-2 of its norm, and the unique ``Y`` with
    ``X_r = Q_i + Y N`` has McMillan degree 94, 36 of its poles 1.4e-4 or more from every pole of the compound's 81
    states), so it is kept."""
    from .matching import model_matching

    try:
        with silenced():
            return model_matching(fw, Qi @ fnm, smarg=smarg, dec_tol=dec_tol, atol=atol).Q, ""
    except DesignError as exc:
        return None, f"the least-order solve of Q_i Ge = [0 0 Rf_i Rw_i] failed ({exc})"


def _faults_and_noise_as_faults(model: FDIModel) -> FDIModel:
    """The model with one component fault whose columns are ``[Bf Bw; Df Dw]`` and no noise: the
    exact matching of ``[Rf_i Rw_i]`` on it solves equation (2)."""
    from ...faults import FaultSpec

    spec = FaultSpec(name="fault_and_noise", kind="component", Bf=np.hstack([model.Bf, model.Bw]),
                     Df=np.hstack([model.Df, model.Dw]))
    return FDIModel(model.A, model.Bu, model.C, model.Du, Bd=model.Bd, Dd=model.Dd, faults=[spec], dt=model.dt,
                    u_names=model.u_names, y_names=model.y_names, d_names=model.d_names)


def _whole_null_basis(model: FDIModel, smarg, atol: float) -> LTI:
    """The proper stable left null-space basis of ``[Gu Gd Gf Gw; I 0 0 0]`` (acting on ``[y; u]``)."""
    from ..toolkit.least_solve import solution_basis

    return solution_basis(model, noise=True, atol=atol, smarg=smarg)


def _check_options(norm, normalize, reltol, atol, mindeg=False) -> None:
    """Stage of :func:`approximate_model_matching`: the options' values."""
    if not isinstance(mindeg, (bool, np.bool_)):
        raise DesignError(f"mindeg must be True or False, got {mindeg!r}")
    if norm not in ("inf", "2"):
        raise DesignError(f"norm must be 'inf' or '2', got {norm!r}")
    if normalize not in ("dcgain", "gain", "infnorm"):
        raise DesignError(f"normalize must be 'dcgain', 'gain' or 'infnorm', got {normalize!r}")
    if not (0 < reltol < 1):
        raise DesignError(f"reltol must lie in (0, 1), got {reltol!r}")
    if not (np.isfinite(atol) and atol >= 0):
        raise DesignError(f"atol must be a finite non-negative number, got {atol!r}")


def iteration_reltol(reltol: float) -> float:
    """The γ-iteration's share ``r_γ`` of the user's ``reltol``: ``(1 + r_γ)² = 1 + reltol`` (≈ reltol/2).

    Derivation. Q = 0 is admissible, so the optimum γ_opt ≤ ``||M [Mr 0]||`` and a filter within ``reltol`` of the
    optimum has an error ``e ≤ γ_opt (1 + reltol)`` — the test :func:`_zero_filter_error` makes. The returned error is
    ``e = e_γ (1 + ρ)``: ``e_γ ≤ γ_lo (1 + r_γ) ≤ γ_opt (1 + r_γ)`` the iteration's figure (its stopping rule, γ_lo
    an infeasible level), ``ρ`` what the stages after it add — the shipped realisation read from its own values
    rather than from the factors (beside a plant mode the filter cancels to rounding, its residue over the distance)
    and the corrections. Both within ``r_γ`` gives ``e ≤ γ_opt (1 + r_γ)² = γ_opt (1 + reltol)``. With the whole
    ``reltol`` given to the iteration the two added up: approximate audit seed 122 (``Mr = I``, 5 faults, p = 4,
    γ_opt = ||F||∞ = 1), e_γ = 1.0000777 in the bracket [1, 1.0000777], read 1.000102 on the shipped order-21
    filter (ρ = 2.4e-5 at ω = 5.7e-7 rad/s, beside the plant integrator it cancels to a residue 1.6e-12) and
    refused as worse than Q = 0 by more than reltol = 1e-4; with r_γ: bracket [1, 1.0000389], returned 1.0000954.

    ρ is not itself limited to r_γ (seed 122's is 5.6e-5 > r_γ = 5e-5; the sum fits because the iteration stopped at
    3.9e-5): what bounds the sum is :class:`ErrorBudget` — every stage after the iteration (the shipped realisation's
    error tier, the corrections, the mindeg acceptance) and the returned filter are held to ``γ_lo (1 + reltol)``
    (the certified level, not the filter before them), so the stages share ``γ_lo (reltol − r_γ)`` whatever their
    number; r_γ only decides how that room is split between the iteration and the rest."""
    return float(np.sqrt(1.0 + reltol) - 1.0)


def _solve_regularised(Gh, F, left, norm, reltol):
    """Stage of :func:`approximate_model_matching`: the standard problem solved, with the
    smallest fictitious noise ε of the ladder (times ||Ĝ||∞) on the ``left`` rank-deficient rows
    whose Riccati equations SLICOT solves; returns ``(Y, solver info, ε)``."""
    ladder = [1e-6, 1e-5, 1e-4, 1e-3] if left else [0.0]
    gsize = float(Gh.hinfnorm()[0]) if left else 0.0
    for k_eps, factor in enumerate(ladder):
        eps = factor * gsize
        G2, F2 = _regularised(Gh, F, left, eps)
        _check_boundary_zeros(G2)
        try:
            Y, info = solve_standard(G2, F2, norm, reltol)
            break
        except DesignError:
            if k_eps == len(ladder) - 1:
                raise
    return Y, info, eps


def _shipped_filter(model, Mr, Y, Gh, F, Qfull, MF, fnm, scale, a, shifts, atol, factor=None, estimate_only=False,
                    norm: str = "inf", budget: ErrorBudget | None = None, record: dict | None = None, smarg=None,
                    dec_tol: float = DEC_TOL):
    """Stage of :func:`approximate_model_matching`: the realisation of ``Q = Y Φ Q0`` whose error
    response is the designed one (the minimal one if it passes, else the non-minimal one);
    returns ``(Q, the comparison points)``. Row i of ``Y Ĝ − F`` is multiplied by ``scale_i m^{k_i}``
    (``shifts`` = the k_i; ``scale`` a number or one per row). ``factor``: the scalar ``μ`` of placed poles
    (:func:`placed_factor`; a list, one per row, when the rows' shifts differ) that multiplies ``Y Ĝ − F``,
    instead of ``scale m^K``; then ``Qfull`` is
    the pair (``μ/m^K`` times the minimal realisation of ``Y Φ Q0``, times ``Y Φ Q0`` itself), the
    second tried last. The shipped response ``Q [Gf Gw; 0 0]`` is read from the plant as the post-conditions read R
    (:func:`_fault_noise_response`), not as the product of Q's and ``fnm``'s values.

    A candidate is taken where, at every point, the gap between the two responses is within the rounding of the
    comparison itself, to first order

        β(λ) = δQ ||Gfw|| + ||Q|| δGfw + γ_m ||Q|| ||Gfw|| + |m^k| (δY ||Ĝ|| + ||Y|| δĜ + γ_q ||Y|| ||Ĝ|| + δF) + δ(MF)
               + ||the removal of the modes each row cancels to δ_i||,

    ``δS`` the evaluation bound of each factor (:func:`_evaluation_rounding`), ``γ_m`` of the products — and that
    gap is at most ``SHIPPED_ACCURACY`` of the error's size (a bound of the error's size decides nothing).
    The fixed 1e-6 it replaces refused discrete H2 random seeds 7, 9, 17, 21, 27 (gaps 1.3e-6 … 1.7e-5 of the error,
    0.0007 … 0.7 of β; Y's gain 9e3 … 4e7): their filters are the designed ones, and the judge then refuses them
    for what is wrong with them — u/d leaks of 2e-6 … 3.5e-4 of the weakest fault gain (Y's gain times the rounding of
    ``Q0 [Gu Gd; I 0] = 0``; numpy confirms seed 9's 3e-6 against fault gains ~1). Seed 13 (gain of Y 2.4e8) differs
    by 1.13 of the error, 21 β: refused here. (Those gains came from wrong Riccati solutions, :func:`_filter_dare`:
    solved by SB02OD the six are designed with gains of Y 14 … 464; numpy leaks ≤ 2.4e-8 of the weakest fault,
    seed 7's 3.4e-7 of it, 1.6e-8 of its strongest.) And the bound is tighter than 1e-6 where the error is small against
    ``M [Mr 0]``: continuous H∞ seeds 4, 28 took the minimal realisation (gaps 1.15, 4.6 β) that the judge refused for
    u+d leaks of 9e-7, 4.9e-7; the product realisation (0.03, 0.008 β) passes it.

    β is an estimate, not a bound: its constants are Higham and Mary's probabilistic ``γ̃_n = √n·u`` at λ = 1
    (:func:`_gamma`), which the rounding exceeds with probability up to 2 exp(−1/2) > 1. So the candidates are tried in
    order against β first (the test that keeps seeds 4, 28 on their product realisation), and only where none passes
    it, the first whose gap is within ``β_w`` — the same first-order sum with the deterministic ``γ_n = n·u/(1 − n·u)``
    in every term (Higham, Thm 3.4 for the products, Thm 9.3 for GEPP's solves in :func:`_evaluation_rounding`; every
    constant grows by ``√n/(1 − n·u)`` ≥ 1, the ``u|S|`` terms and the removed modes not at all, so ``β ≤ β_w``) — and
    within ``SHIPPED_ACCURACY`` of the error's size is taken. A gap above ``β_w`` is more than any rounding of the
    comparison (to first order): the realisation is another filter and it is refused. One within ``β_w`` but above
    β may still be the worse of two realisations (seeds 4, 28's minimal ones), which is why β decides first; the
    filter taken by ``β_w`` is then judged, as every returned filter, by the post-conditions that follow (the u/d leak
    on reading + sensitivity, :func:`_ud_leak_refused`; the error; the zero filter). Approximate audit seeds 120, 131
    (``amm_ref``, tests/test_approximate_random.py; gaps 2.78, 1.01 β, 2.5e-8, 1.5e-9 of the error) are within β_w.

    β_w bounds the *evaluation* of the factors; it does not bound their *construction*: the realisations of Y, Ĝ, Φ, Q0
    (coprime factorisation, minimal realisation, series products) each carry a backward error of their own, normwise
    ~n·u·||A|| (Higham, 2nd ed., Lemma 19.3 and Thm 19.4 for the staircase's Householder steps; Golub and Van Loan,
    4th ed., sec. 7.5.6 for the real Schur forms; Varga 2017, sec. 10.1), which
    the product ``Y Φ Q0`` and the designed ``Y Ĝ − F`` carry differently — no first-order evaluation term covers it,
    and a bound of it would be a normwise ``n·u·||A||/dist(λ, poles)`` per factor, orders above the gaps β_w meets. So
    where no candidate is within β_w, the test is the one the user's residual asks: the shipped realisation is
    another filter, admissible by construction (``Q0`` annihilates u, d; the decoupling of the shipped realisation is
    judged after, on reading + sensitivity); it is shipped if its own error — read from its own realisation as the
    returned figure is (:func:`_shipped_error`: refined H∞ peak, H2 quadrature) — is the designed filter's error
    ``e_d`` (read from the factors, same reading) within ``reltol``, ``e_s ≤ e_d (1 + reltol) + ZERO_ERROR_FLOOR·||M
    [Mr 0]||`` (the limit every later correction meets, :func:`_correction_refused`), and its gap is within
    ``SHIPPED_ACCURACY``; of those the nearest to the designed response in β_w, with a note naming gap, both errors
    and the limit. A realisation whose error exceeds that limit is refused, the message naming the errors (a
    realisation off by 5e-4 of Q: tests/test_amm_shipped_error.py). Seed 119 (candidates at 8.77 and 1.14 β_w, beside
    z = 1 where the designed side's terms dominate; refused before; 1.08 β_w since the γ-iteration's change): its
    error 170.410907 is the designed 170.410907 to nine digits (limit 170.427949), numpy's judge passes it; seed 131, accepted by β_w at 0.964 of it, meets this
    test too (87.0955351 against the designed 87.0955351, measured with β_w's tier bypassed): a rounding that tips
    it over β_w no longer refuses it.
    Whichever tier takes a candidate, its u/d block (which no tier compares) is read: where it leaks above
    :data:`SHIPPED_LEAK_MARGIN` of ``dec_tol``, another candidate leaking within that and as admissible by its error is
    shipped instead (:func:`_decoupled_candidate`; approximate audit seeds 173, 199). ``smarg``, ``dec_tol``: the
    design's (the judge's reading of the leak).
    ``estimate_only``: β alone (the per-row shifts, whose next candidate is the uniform K shifts). ``record``: a dict
    that receives ``'gap'`` where the filter was taken on the rounding test (β or β_w), for
    :func:`_shipped_budget` — only where the taken realisation is shipped (a replacement is admissible by β or by the
    budget on its own; the base is then not moved)."""
    dt = model.dt
    if record is not None:  # (a second call, after the per-row shifts failed: its own candidates)
        record.pop("within_dec_tol", None)
    Qfull, last = Qfull if isinstance(Qfull, tuple) else (Qfull, None)
    lam = _design_points(model, Y, Mr, factor)
    mk = _factor_values(lam, factor, scale, shifts, a, dt)  # each row's factor: s_i m(λ)^{k_i}, or the placed μ_i(λ)
    Yv, Ghv = _values(Y, lam), _values(Gh, lam)
    designed = (np.einsum("kij,kjl->kil", Yv, Ghv) - _values(F, lam)) * mk[:, :, None]
    mfv, Ge = _values(MF, lam), _values(model.augmented(), lam)
    size = max(float(np.nanmax(_nrm(mfv))), float(np.nanmax(_nrm(designed))), 1e-300)
    cands = (Qfull.minreal(atol), Qfull) + ((last,) if last is not None else ())
    labels = ("minimal", "Y Φ Q0" if last is None else "μ/m^K times the minimal Y Φ Q0", "Y Φ Q0")
    if factor is not None and Qfull.n:
        # μ/m^K cancels the K-fold poles of m^K (at 0 in discrete time: nilpotent, its cancellation moves
        # them by ~√eps); a staircase at √eps of the data's size is tried first, kept only if it is the
        # same filter to 1e-9 of its peak (its u/d response too — the error check below sees only f, w)
        loose = np.sqrt(EPS) * max(float(np.linalg.norm(X, 2)) for X in (Qfull.A, Qfull.B, Qfull.C))
        Ql, qv = Qfull.minreal(max(atol, loose)), _values(Qfull, lam)
        fin = np.all(np.isfinite(qv), axis=(1, 2))
        if np.max(_nrm(_values(Ql, lam)[fin] - qv[fin])) <= 1e-9 * max(float(np.max(_nrm(qv[fin]))), 1e-300):
            cands, labels = (Ql,) + cands, ("minimal at √eps",) + labels
    # the designed side's rounding: |m^k| (δY ||Ĝ|| + ||Y|| δĜ + γ_q ||Y|| ||Ĝ|| + δF) + δ(M F) (:func:`_evaluation_rounding`)
    nY, nGh = _nrm(Yv), _nrm(Ghv)
    fv = _nrm(_values(fnm, lam))

    def fixed_rounding(worst):  # (the designed side's rounding, δ(fnm)): with the estimated or the worst-case γ
        return (np.max(np.abs(mk), axis=1) * (_evaluation_rounding(Y, lam, worst) * nGh
                                              + nY * _evaluation_rounding(Gh, lam, worst)
                                              + _gamma(Y.m, worst) * nY * nGh + _evaluation_rounding(F, lam, worst))
                + _evaluation_rounding(MF, lam, worst), _evaluation_rounding(fnm, lam, worst))

    def compare(Q, shipped, nQ, removed, fixed, worst):  # (gap, excess over the bound, the bound's peak)
        bound = _evaluation_rounding(Q, lam, worst) * fv + nQ * fixed[1] + _gamma(Q.m, worst) * nQ * fv + fixed[0] \
            + removed
        ok = np.all(np.isfinite(shipped), axis=(1, 2)) & np.all(np.isfinite(designed), axis=(1, 2)) \
            & np.isfinite(bound)
        diff = _nrm(shipped[ok] - designed[ok])
        if not diff.size:  # no point where both responses and the bound are finite: nothing is shown
            return np.inf, np.inf, np.inf
        return float(np.max(diff)), float(np.max(diff / bound[ok])), float(np.max(bound[ok]))

    def read(Q):  # (Q, its shipped error response, ||Q||, the modes' removal) at the points
        read, Qv, product = _fault_noise_response(model, Q, lam, Ge)
        shipped = read - mfv
        # (+ what reading R without the plant modes each row cancels to its rounding bound δ_i changed: that
        # decision is the judge's derived one, and the correction δ_i/|λ − p| is rounding by it — 4.6e-16 at
        # λ = 44j, 2e-21 at 1e7 j against a product bound of 3e-27 where m^K = 1e-12 scales all that is designed:
        # tests/test_approximate_matching_options.py, unstable_actuator_model with its pole at +0.5)
        return Q, shipped, _nrm(Qv), _nrm(shipped + mfv - product)

    fixed, tried = fixed_rounding(False), []

    def decoupled(k, fixed=fixed):  # cands[k] or one within the leak margin, its error as admissible (β: estimate)
        return _decoupled_candidate(model, Mr, cands, k, tried, read, lam, size, fixed, compare, fnm, MF, norm,
                                     Y, budget, smarg, dec_tol, record, labels)

    for Q in cands:
        tried.append(read(Q))
        gap, excess, worst = compare(*tried[-1], fixed, False)
        if excess <= 1.0 and gap <= SHIPPED_ACCURACY * size:
            S = decoupled(len(tried) - 1)
            if record is not None and S is Q:  # (taken on the rounding test: :func:`_shipped_budget`)
                record["gap"] = gap
            return S, lam
    # no candidate within the estimate: the first within the worst-case first-order bound (and SHIPPED_ACCURACY)
    fixed, excess_w, gaps_w = None if estimate_only else fixed_rounding(True), [], []
    for cand in ([] if estimate_only else tried):
        gap_w, ew, _ = compare(*cand, fixed, True)
        excess_w.append(ew)
        gaps_w.append(gap_w)
        if ew <= 1.0 and gap_w <= SHIPPED_ACCURACY * size:
            S = decoupled(len(excess_w) - 1)
            if record is not None and S is cand[0]:
                record["gap"] = gap_w
            return S, lam
    # none within β_w either: the candidate nearest the designed response (in β_w) whose own error is within the
    # design's one limit (:class:`ErrorBudget`), as the corrections after it are judged (:func:`_correction_refused`)
    errors, why = [], ""
    if not estimate_only and budget is not None:
        systems = [model.lti(), Y, Mr]
        e_d = _designed_error(model, Y, Gh, F, Mr, factor, scale, a, shifts, norm, lam)
        limit, reltol = budget.limit, budget.reltol
        for k in np.argsort(excess_w, kind="stable"):
            if not gaps_w[k] <= SHIPPED_ACCURACY * size:
                continue
            e_s = float(_shipped_error(model, tried[k][0], fnm, MF, lam, norm, systems))
            errors.append(e_s)
            if e_s <= limit:
                note(f"the shipped realisation (order {tried[k][0].n}) differs from the designed error response by "
                     f"{gaps_w[k]:.3g} (relative {gaps_w[k] / size:.3g}), {excess_w[k]:.3g} times its worst-case "
                     f"first-order evaluation bound: its own error {e_s:.9g} (the designed {e_d:.9g}) is within "
                     f"reltol of the certified optimum ({budget.says()}), so it is taken")
                return decoupled(int(k)), lam
        why = (f"; their errors {', '.join(f'{e:.9g}' for e in errors)} exceed the designed {e_d:.9g} by more than "
               f"reltol = {reltol:g} of the certified optimum ({budget.says()})" if errors else "")
    raise DesignError(f"approximate_model_matching: the returned filter's error response differs from the "
                      f"designed one by {gap:.3g} (relative {gap / size:.3g}, limit {SHIPPED_ACCURACY:g}; "
                      f"{excess:.3g} times its rounding estimate, at most {worst / size:.3g} of the error's size"
                      + (f"; the candidates' gaps are {', '.join(f'{e:.3g}' for e in excess_w)} times their "
                         f"worst-case first-order rounding bound" if excess_w else "") + why + "): the "
                      f"realisation of Q = Y Φ Q0 lost accuracy (peak gain of Y {float(np.nanmax(nY)):.3g}; "
                      f"an ill-conditioned, nearly exactly matchable problem: try model_matching, or another sdeg)")


#: :func:`_shipped_filter`: the taken realisation is shipped without reading the other candidates' u/d leak where its own
#: (reading + sensitivity, the worst row) is at most this fraction of ``dec_tol``, and replaced only by one whose own
#: is; derivation: :func:`_decoupled_candidate`
SHIPPED_LEAK_MARGIN = 0.1


def _decoupled_candidate(model, Mr, cands, k, tried, read, lam, size, fixed, compare, fnm, MF, norm, Y, budget, smarg,
                          dec_tol, record=None, labels=None):
    """:func:`_shipped_filter`'s choice among its realisations of ``Y Φ Q0``: the one its response tiers took,
    ``cands[k]``, unless its normalised u/d leak as a double-precision evaluation can show it (reading + sensitivity,
    the worst row: :func:`_row_leaks`, the rule of the final check :func:`_ud_leak_refused`) exceeds
    :data:`SHIPPED_LEAK_MARGIN` of ``dec_tol``; then the first other candidate (in ``cands``' order) whose leak is
    within that margin and whose error is as admissible — within the rounding estimate β of the designed response
    (``compare``, estimated γ) or, where the design has its error limit, within ``SHIPPED_ACCURACY`` of the error's
    size with its own error (:func:`_shipped_error`) within ``budget.limit`` (the tests of :func:`_shipped_filter`'s
    first and last tiers). None: the taken one, for the re-decoupling stage (:func:`_ud_redecoupling`) to mend;
    then ``record['within_dec_tol']`` (where ``record`` is given) lists the other candidates as admissible by their
    error whose leak is within ``dec_tol`` but not the margin, ``(S, leak, gap or None, its name in labels)``, least
    leak first (``labels``: the candidates' names, for the note):
    :func:`approximate_model_matching` ships the first of them that meets the final rule after its own stages where
    the taken one, re-decoupled, does not — rather than refuse an achievable request (approximate audit seed 327,
    discrete n 25, Mr = an exact detection row's Rf: the minimal realisation leaks 9.13e-8 + sensitivity 1.2e-7 =
    2.07e-7 and no refit of it met dec_tol = 1e-7; the product ``Y Φ Q0``, order 115, 8.98e-9 + 3.45e-8 = 4.4e-8 —
    numpy's refined evaluation 1.09e-8 — was refused before because it is not within 0.1·dec_tol).
    ``tried``: the candidates read so far (``read(Q)`` reads another).

    **Why.** The candidates are realisations of one filter, and the response tiers compare only its fault/noise
    response ``Q [Gf Gw; 0 0]``: the u/d block ``Q [Gu Gd; I 0]`` is zero only as a cancellation of size ``|Q||Ge|``,
    which Y's gain multiplies, and a realisation in other coordinates (the minimal one: SLICOT's staircase and the
    placed factor's products) keeps it only to its own construction's rounding times that gain. Approximate audit
    seeds 173, 199 (discrete n 28, Mr = an exact detection row's Rf, peak gain of Y 5.4e5 for 173): the minimal
    realisation, taken by β, leaks 9.46e-5 and 9.17e-8 (read 1.21e-7 at the final check) of the weakest required
    fault where the product realisation ``Y Φ Q0`` leaks 1.28e-9 and 4.5e-10 (its gap 0.008, 0.0013 β), and the
    re-decoupling refits of the minimal one still leak 2.29e-5 (173): an achievable request was refused.

    **The margin** (both ways: the taken one is kept without reading the others where its leak is within it, another
    replaces it only if its own is). The leak read here is an estimate of what the user's evaluation reads, twice
    removed from it: (i) the shipped filter is judged again after :func:`_plant_mode_cancellation` (which realises it
    again without the plant modes it cancels) — seed 199's minimal realisation reads 9.17e-8 here (≤ dec_tol = 1e-7)
    and 1.21e-7 at the final check, a factor 1.32; (ii) the sensitivity is first order and componentwise, and a dense
    LU evaluation of a non-normal realisation can exceed reading + sensitivity — random H∞ seed 7
    (benchmarks/ammp_random_set.py): its product realisation reads 4.05e-8 (within dec_tol) and numpy's plain
    evaluation 1.5e-7, a factor 3.7, where the taken minimal one (1.28e-7) is mended by the re-decoupling (its Schur
    realisation, 4.5e-9). A decade (0.1·dec_tol) covers both factors (1.32·3.7 = 4.9) with room, so a replacement is a
    sure improvement and never a worse start for the re-decoupling than the taken one. Cost: one judge reading of the
    taken candidate (the one :func:`_ud_redecoupling` makes next) where its leak is within the margin, the common
    case: benchmarks/ammp_random_set.py 30, 51 of 60 shipped filters (9 read the other candidates, 2 replaced, every
    verdict as before); approximate audit seeds 136-151, 24 of 32 (1 above, 7 unreadable — NaN, the judge stops before
    its decoupling stage, as :func:`_ud_redecoupling` then does: the taken one, no other read).
    """
    Q = cands[k]
    if not model.nu + model.nd:
        return Q
    required = required_faults(model, Mr, lam)

    def leak(S):
        fig = normalised_leak(model, S, required, smarg, dec_tol)
        return float(max(_row_leaks(fig, S.p), default=_leak_of(fig)))

    first = leak(Q)
    if not first > SHIPPED_LEAK_MARGIN * dec_tol:  # (within the margin, or NaN: the judge cannot read it)
        return Q
    systems, within = [model.lti(), Y, Mr], []
    for j, S in enumerate(cands):
        if j == k:
            continue
        x = leak(S)
        if not x <= dec_tol:
            continue
        while len(tried) <= j:
            tried.append(read(cands[len(tried)]))
        gap, excess, _ = compare(*tried[j], fixed, False)
        if not gap <= SHIPPED_ACCURACY * size:
            continue
        if not excess <= 1.0 and (budget is None or
                                  not float(_shipped_error(model, S, fnm, MF, lam, norm, systems)) <= budget.limit):
            continue
        if not x <= SHIPPED_LEAK_MARGIN * dec_tol:  # within dec_tol only: the taken one's stages go first
            within.append((S, x, gap if excess <= 1.0 else None, labels[j] if labels else f"candidate {j + 1}"))
            continue
        note(f"the realisation of order {S.n} is shipped: its normalised u/d leak (reading + sensitivity) {x:.3g} is "
             f"within {SHIPPED_LEAK_MARGIN:g}·dec_tol where the one its response comparison took first (order {Q.n}) "
             f"leaks {first:.3g}, and its error is as admissible")
        return S
    if record is not None:
        record["within_dec_tol"] = sorted(within, key=lambda c: c[1])
    return Q


#: :func:`_shipped_filter`: the largest gap, relative to the error's size, between the shipped and the designed error
#: response, whatever the rounding bound: the H2 contract of the reported error (tests/test_synthesis_ammp.py,
#: ``check_contract``: 1e-3). The bound alone does not decide where it is itself of the error's size — random H2 seed
#: 13's minimal Q, a gap 1.39 of the error at 1.06 of its bound 24 times the error; the bound is that large, harmlessly,
#: beside poles (approximate audit seeds 10, 26: bounds 0.08, 5.5 of the error, gaps 1.6e-13, 2.9e-10)
SHIPPED_ACCURACY = 1e-3


def _gamma(n: int, worst: bool = False) -> float:
    """``γ̃_n = √n·u``: the probabilistic constant of an n-term inner product's rounding (Higham and Mary, A new approach
    to probabilistic rounding error analysis, SIAM J. Sci. Comput. 41(5), 2019, Thm 2.4: the worst case ``n·u`` is
    exceeded by ``λ√n·u`` with probability ≤ 2 exp(−λ²(1 − u)²/2)); λ = 1 taken with n → 3n for GEPP. At λ = 1 that
    probability bound is 2 exp(−1/2) = 1.21: an estimate of the typical rounding, not a bound.
    ``worst``: the deterministic ``γ_n = n·u/(1 − n·u)`` (Higham, *Accuracy and Stability of Numerical Algorithms*,
    2nd ed., Lemma 3.1 and Thm 3.4 for the inner product, Thm 9.3 for GEPP), a bound whatever the rounding's signs."""
    n, u = max(n, 1), EPS / 2
    return n * u / (1.0 - n * u) if worst else float(np.sqrt(n)) * u


def _evaluation_rounding(S: LTI, lam: np.ndarray, worst: bool = False) -> np.ndarray:
    """Per point λ, a bound of the rounding of ``S(λ) = C (λI − A)^{-1} B + D`` as :func:`_values` computes it (from
    the balanced realisation, Gaussian elimination with partial pivoting on ``λI − A``): GEPP's computed ``X̂`` solves
    ``(λI − A + ΔA) X̂ = B`` with ``|ΔA| ≤ γ_{3n} |L̂||Û| ≈ γ_{3n} |λI − A|`` (Higham, *Accuracy and Stability of
    Numerical Algorithms*, 2nd ed., Thm 9.3, no growth), so to first order

        |Ŝ − S| ≤ γ_{3n} (|W| |λI − A| |X| + |C| |X|) + u |S|,   X = (λI − A)^{-1} B,  W = C (λI − A)^{-1},

    returned as the 2-norm of that matrix, with ``γ_{3n}`` the probabilistic ``√(3n)·u`` (:func:`_gamma`; the worst
    case 3n·u overestimates random seeds 7, 9's gaps 1e3 … 1e4-fold). The componentwise form matters: the normwise
    ``||W|| ||λI − A|| ||X||`` exceeds the gaps of the same seeds 1e4 … 1e6-fold. ``worst``: with the deterministic
    ``γ_{3n}`` (:func:`_gamma`), the first-order bound itself."""
    if not S.n:
        return np.full(lam.size, EPS / 2 * float(np.linalg.norm(S.D, 2)) if S.D.size else 0.0)
    S = S.balanced()[0]
    n = S.n
    M = lam[:, None, None] * np.eye(n) - S.A
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        XW = resolvent_pair(S, lam)
        if XW is None:
            return np.full(lam.size, np.inf)
        X, W = XW
        E = np.abs(W) @ np.abs(M) @ np.abs(X) + np.abs(S.C) @ np.abs(X)
        return _gamma(3 * n, worst) * _nrm(E) + EPS / 2 * _nrm(S.C @ X + S.D)


def _fault_noise_response(model: FDIModel, Q: LTI, lam: np.ndarray, Ge: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(read, Q(λ), product)``: ``read`` = ``Q(λ) [Gf Gw; 0 0](λ)`` at the points ``lam`` as the post-conditions read
    the residual (``Ge``: the values of ``[Gu Gd Gw Gf; I 0 0 0]`` there), ``product`` the plain product of values
    (what the reading removed is their difference). The reading: each row without the plant's boundary modes it cancels to the rounding bound
    δ_i of its design (:func:`..toolkit.postconditions._without_cancelled_modes`, the reading of the R-stability
    post-condition that follows). Beside such a mode, a product of values reads the row's rounding-level residue
    divided by the distance δ to the pole: approximate audit seed 26 (a fault-only integrator at 1.3e-16; filter
    Y Φ Q0 of order 120, its residue 4.7e-12 within δ_i = 2.8e-9) read 7e-5 of the error's size at 7e-9 rad/s,
    refused as a realisation that lost accuracy; read without the mode it agrees to 1.3e-10. A row that
    does not cancel the mode to δ_i keeps it (the minimal realisation of the same filter: residue 3.3e-8, 0.3)."""
    from ..toolkit.postconditions import _without_cancelled_modes

    cols = _fault_noise_columns(model)
    Qv = _values(Q, lam)
    R = np.einsum("kij,kjl->kil", Qv, Ge)
    product = R[:, :, cols]  # (a copy: fancy indexing)
    ok = np.all(np.isfinite(R), axis=(1, 2))
    if np.any(ok) and model.n:
        Rk = R[ok]
        _without_cancelled_modes(model, Q, [[i] for i in range(Q.p)], lam[ok], Rk, Qv[ok], Ge[ok])
        R[ok] = Rk
    return R[:, :, cols], Qv, product


# ----------------------------------------------------------------------------- inputs
def fault_noise_map(model: FDIModel) -> LTI:
    """``[Gf Gw; 0 0]``: from [f; w] to [y; u] (the columns of F = [Mr 0])."""
    return model.augmented()[:, _fault_noise_columns(model)]


def _fault_noise_columns(model: FDIModel) -> np.ndarray:
    """The columns of f, then w, in ``Ge = [Gu Gd Gw Gf; I 0 0 0]`` (:meth:`FDIModel.augmented`)."""
    sl = model.group_slices()
    return np.r_[np.arange(sl["f"].start, sl["f"].stop), np.arange(sl["w"].start, sl["w"].stop)]


def _check_basis_options(nullspace, simple) -> None:
    """Stage of :func:`approximate_model_matching`: ``nullspace`` (None, True, False) and ``simple`` (bool),
    and not both ``simple`` and ``nullspace = False``."""
    if not isinstance(simple, (bool, np.bool_)):
        raise DesignError(f"simple must be True or False, got {simple!r}")
    if not (nullspace is None or isinstance(nullspace, (bool, np.bool_))):
        raise DesignError(f"nullspace must be True, False or None (automatic), got {nullspace!r}")
    if simple and nullspace is False:
        raise DesignError("simple = True asks for a simple minimal basis, nullspace = False for the full-order "
                          "observer-based one (which has no simple form): choose one")


def reduced_system(model: FDIModel, atol: float = 0.0, *, nullspace: bool | None = None, simple: bool = False,
                   HDesign=None, rows: int | None = None, smarg: float | None = None) -> tuple[LTI, LTI, dict]:
    """``(Q0, G1, info)``: a proper stable left null-space basis of ``[Gu Gd; I 0]``, ``Q0 [Gf Gw; 0 0]``
    and the ``info`` entries that describe the basis (``basis``, ``nullspace_basis``, ``HDesign``,
    ``basis_row_orders``). ``nullspace``, ``simple``, ``HDesign`` as in :func:`approximate_model_matching`
    (``rows``: the residuals, Mr's rows, that H must have; ``smarg``: the margin the observer-based basis's
    poles keep, :func:`_observer_basis`)."""
    from .hdesign import design_matrix

    dt = model.dt
    if nullspace is False and model.nd:
        raise DesignError(f"nullspace = False (a full-order observer-based basis) needs a model without "
                          f"disturbance inputs: this one has {model.nd}; use nullspace = True or None")
    Hm = None
    if HDesign is not None:  # one validation of H (rows = Mr's, at most p − rank Gd columns, full row rank)
        from ..toolkit._basis import normal_rank

        k = model.ny - (normal_rank(model.lti("d"), atol=atol) if model.nd else 0)
        Hm = design_matrix(HDesign, k, rows=rows)
    info: dict = {}
    if model.nd == 0 and not simple and nullspace is not True:
        if model.nu == 0 or model.lti("u").is_stable():
            # Gu stable: Q0 = [I  −Gu] (Q = [X  −X Gu] is stable iff X is), the identity without u
            if model.nu == 0:
                Q0 = LTI.static(np.eye(model.ny), dt)
            else:
                Q0 = hstack([LTI.static(np.eye(model.ny), dt), -model.lti("u")])
            G1, kind = model.lti("f", "w"), "[I -Gu]" if model.nu else "identity"
        else:
            Q0, G1 = _observer_basis(model, smarg)
            kind = "observer"
        if Hm is not None:
            Q0, G1 = Hm @ Q0, Hm @ G1
            info["HDesign"] = Hm.tolist()
        info.update(basis=kind, nullspace_basis=Q0)
        return Q0, G1, info
    from .nullspace import nullspace_design

    try:  # with H: M·H·N on the basis N nullspace_design's HDesign multiplies (.hdesign.basis_rows)
        basis = nullspace_design(model, rdim="all" if Hm is None else 1, HDesign=Hm, simple=bool(simple),
                                 noise="ignore", FDtol=0.0, atol=atol)
    except DesignError as exc:
        what = "no residual decouples u and d" if not simple and Hm is None else \
            f"the {'simple ' if simple else ''}basis{' times HDesign' if Hm is not None else ''} fails"
        raise DesignError(f"approximate_model_matching: {what}: {exc}") from None
    Q0 = basis.Q
    info.update(basis="simple" if simple else "minimal", nullspace_basis=Q0)
    if Hm is not None:
        info["HDesign"] = basis.info.get("HDesign", Hm.tolist())
    if simple:
        info["basis_row_orders"] = basis.info.get("simple_orders")
    # no minimal realisation here: the basis cancels plant modes only to its own accuracy
    # (~1e-7), and removing them would make G1 differ from Q0 [Gf Gw] by that much divided
    # by the distance of those poles to the boundary; the interactor keeps only the
    # controllable part, which is exact. The plant modes outside the stability region, which the
    # basis cancels too (its internal form is stable), are the exception: kept, G1 is unstable
    # and no stable Y exists (SLICOT refuses every level)
    return Q0, drop_negligible_unstable_modes(Q0 @ fault_noise_map(model)), info


def _observer_basis(model: FDIModel, smarg: float | None = None) -> tuple[LTI, LTI]:
    """``(Q0, G1) = ([M̂  −N̂_u], [N̂_f  N̂_w])``: the observer-based basis of a model without d, from the stable
    left coprime factorisation ``[Gu Gf Gw] = M̂⁻¹ [N̂_u N̂_f N̂_w]`` that moves only the plant's poles outside the
    margin (:func:`..toolkit.stable_factor.glcf` on the TB01ID-balanced plant, :func:`moved_pole_targets`'s
    places; FaultDetectionTools.jl ``ammsyn`` with ``nullspace = false`` takes ``[I  −Gu]`` and stabilises the
    whole ``[Q R]`` by ``glcf`` the same way). ``M̂ = (A + LC, L, C, I)``, ``N̂ = (A + LC, B + LD, C, D)``:
    every block on the plant's own states, ``G1 = M̂ [Gf Gw]`` exact by construction.

    Why not a full observer (every pole placed, :func:`.coprime._factor_filter`): on ill-scaled plants with few
    outputs its gain made ``A − LC`` of balanced norm 2e7 … 6e9 (plant: 5 … 36) with an eigenvector condition
    1e9 … 1e10 (approximate audit seeds 20, 23, 30, 31): read by numpy, the interactor's ``m^K Ĝ`` was 1.7e-4 … 8e-2
    off ``Φ G1`` (seeds 30, 23, 31) and seed 20's G1, after the coprime factorisation its unstable G1 then needed,
    0.99 off ``Q0 [Gf Gw]``; the γ-iteration's Y had peak gains 4e3 … 1.3e8 and the returned filter's error was
    not the designed one (refused). On this basis: ≤ 8e-13, Y's peak gains 2 … 200, all designed
    (tests/test_approximate_random.py). The full observer remains the fallback where this factorisation does not
    stabilise (an unobservable bad mode: :func:`.coprime._factor_filter` then names it)."""
    from ..toolkit.stable_factor import _stability_region, glcf, moved_pole_targets

    nu, ny, dt = model.nu, model.ny, model.dt
    good = _stability_region(model, None, smarg, True)
    P, _ = model.lti("u", "f", "w").balanced()  # diagonal similarity by powers of 2: exact
    try:
        N, M, _ = glcf(P, moved_pole_targets(model, None, None, smarg), good)
    except DesignError:
        N = None
    if N is not None and all(good(float(z.real), float(z.imag)) for z in N.poles()):
        Q0 = LTI(N.A, np.hstack([M.B, -N.B[:, :nu]]), N.C, np.hstack([np.eye(ny), -N.D[:, :nu]]), dt)
        return Q0, LTI(N.A, N.B[:, nu:], N.C, N.D[:, nu:], dt)
    from .coprime import _factor_filter

    try:
        Q0, _ = _factor_filter(model, None, False)
    except DesignError as exc:
        raise DesignError(f"approximate_model_matching: no observer-based basis: {exc}") from None
    # output error e = x − x̂ of the observer: G1 = (A − LC, [Bf − L Df, Bw − L Dw], C, [Df Dw])
    L = Q0.B[:, :ny]
    B = np.hstack([model.Bf, model.Bw])
    D = np.hstack([model.Df, model.Dw])
    return Q0, LTI(Q0.A, B - L @ D, model.C, D, dt)


def stable_reduced_system(model: FDIModel, Q0: LTI, G1: LTI, smarg=None, atol: float = 0.0) -> tuple[LTI, LTI]:
    """``(N_Q, N_G)``, stable, with ``[N_Q N_G] = M [Q0 G1]`` for a stable M: the stable left coprime factorisation
    (:func:`..toolkit.stable_factor.glcf`, moving only the poles outside the margin ``smarg``, to
    :func:`moved_pole_targets`'s places) of Q0's minimal realisation, ``Q0 = M1⁻¹ N_Q`` (G1 becomes ``M1 G1``
    without the modes it cancels), then of G1 if still unstable, ``G1 = M2⁻¹ N_G`` (Q0 becomes ``M2 N_Q``);
    ``(Q0, G1)`` when both are stable or when the factorisation does not stabilise them (the synthesis then
    refuses with its own reason).

    The basis Q0 and G1 = Q0 [Gf Gw] can keep a plant mode on or beyond the stability boundary (approximate
    audit seeds 1 and 21: the pair e^{±0.2j}, z = 1, in Q0 itself). The admissible filters are ``Q = X Q0`` with
    ``X Q0`` and ``X G1`` stable; by coprimeness (a Bezout identity) these are exactly ``Q = Y N_Q`` with Y
    stable, and then ``X G1 = Y N_G``: the problem over stable Y on the stable pair is the same problem with no
    mode for Y to cancel (without it SLICOT's Riccati equations failed at every level). FaultDetectionTools.jl
    ``ammsyn`` does the same: its basis ``glnull(...; sdeg)`` is the stable factor of the whole ``[Q R]``.

    Both factorisations are of minimal realisations (:func:`..toolkit.stable_factor.glcf` asks for one): G1 as the
    model gives it (``[Gf Gw]`` on the plant's states) can be ill-scaled, its boundary mode weakly observed, and the
    output injection then loses the identity ``N_G = M2 G1``, so that the filters ``Y (M2 Q0)`` have another error
    than the one designed on ``N_G`` — approximate audit seed 102 (an integrator; raw ‖A‖ = 1.3e7, ``|C v|`` =
    5.4e-4, cond of the eigenvectors 1e7): ``N_G`` and ``M2 Q0 [Gf Gw]`` differed by 0.995 relative and the design
    was refused; seed 98 (±2j): by 1.7e-7, refused at 2.6e4 times the realisation's rounding bound. On the
    minimal (balanced) realisation (‖A‖ = 11.5, ``|C v|`` = 2.3) the gaps are 1.7e-9 and 1.4e-13
    (tests/test_amm_stable_factor.py)."""
    from ..toolkit.stable_factor import _stability_region, glcf, moved_pole_targets

    Q0_in, G1_in = Q0, G1
    good = _stability_region(model, None, smarg, True)

    def stable(S: LTI) -> bool:
        return all(good(float(p.real), float(p.imag)) for p in S.poles()) if S.n else True

    if stable(Q0) and stable(G1):
        return Q0, G1
    targets = moved_pole_targets(model, None, None, smarg)
    try:
        if not stable(Q0):  # Q0 = M1⁻¹ N_Q: the filters X Q0 with X Q0 stable are Y N_Q, and X G1 = Y (M1 G1)
            NQ, M1, _ = glcf(Q0.minreal(atol), targets, good)
            Q0, G1 = NQ, drop_negligible_unstable_modes(M1 @ G1)
        if not stable(G1):  # G1 = M2⁻¹ N_G: then Y (M2 Q0), Y N_G
            NG, M2, _ = glcf(G1.minreal(atol), targets, good)
            Q0, G1 = M2 @ Q0, NG
    except DesignError:
        return Q0_in, G1_in
    return (Q0, G1) if stable(Q0) and stable(G1) else (Q0_in, G1_in)


# ------------------------------------------------------------------- regularisation
def interactor(G1: LTI, a: float, atol: float = 0.0) -> tuple[LTI, LTI, int, int, int]:
    """Silverman's structure algorithm: ``(Ĝ, Φ, K, dropped, left)`` with ``Φ G1 = m^K Ĝ``.

    ``Ĝ`` is proper with a full-row-rank feedthrough (no zeros at infinity), ``Φ`` stable and
    proper (poles at −a, or delays in discrete time), ``m = a/(s + a)`` (``1/z``). Each step
    splits the rows by an orthogonal ``T`` from the SVD of the feedthrough: rows in its range
    stay, rows with zero feedthrough are multiplied by ``n = 1/m`` (``n·(A, B, c, 0) =
    (A, B, (c A + a c)/a, c B/a)``, or ``(A, B, c A, c B)``), and combinations that are
    identically zero (``c = 0`` in a controllable realisation) are dropped — they are the
    residual directions that see neither faults nor noise (``G1`` rank-deficient), which loses
    nothing: ``Y G1`` does not depend on them. The step factor is
    ``Φ_j = diag(m I, I) T_j`` (kept rows), so ``Φ_K ⋯ Φ_1 G1 = m^K Ĝ``. Rows of ``[C D]``
    are kept at unit norm (a row scaling folded into T) so that one relative tolerance
    serves every step: the feedthrough's singular values count above ``1e-9 ||B||``, a row
    combination is identically zero when its ``c`` is below 1e-9.

    When ``G1`` has normal rank ``ρ`` below its rows and the feedthrough reaches rank ρ, the
    ``left`` remaining zero-feedthrough rows are rational combinations of the others that
    no shift makes independent: they stay, last, with zero feedthrough (see
    :func:`approximate_model_matching`, which regularises them).

    Reference: L. M. Silverman, Inversion of multivariable linear systems, IEEE TAC 14, 1969;
    the interactor of W. A. Wolovich and P. L. Falb, SIAM J. Control 14, 1976.
    """
    dt = G1.dt
    G = G1.minreal(atol, job="C")
    if G.n:
        G, _ = G.balanced()
    w0 = 1.0 / np.maximum(np.linalg.norm(np.hstack([G.C, G.D]), axis=1), 1e-300)
    G = LTI(G.A, G.B, G.C * w0[:, None], G.D * w0[:, None], dt)
    A, B, C, D = G.A, G.B, G.C, G.D
    nB = max(float(np.linalg.norm(B, 2)) if B.size else 0.0, 1e-300)
    Phi = LTI.static(np.diag(w0), dt)
    rank_n = _normal_rank(G)
    K = dropped = left = 0
    for _ in range(G.n + G.p + 1):
        # rows of [C D] are kept at unit norm (a constant row scaling folded into T), so one
        # relative tolerance serves every step: D is rank-deficient below 1e-9·||B||, a row
        # combination is identically zero below 1e-9 (its c, controllable realisation)
        U, sv, _ = np.linalg.svd(D) if D.size else (np.eye(D.shape[0]), np.zeros(0), None)
        r = int(np.sum(sv > max(1e-9 * max(nB, 1.0), atol)))
        if r == D.shape[0]:
            break
        Ct, Dt = U.T @ C, U.T @ D
        Cb = Ct[r:]
        U2, s2, _ = np.linalg.svd(Cb) if Cb.size else (np.eye(Cb.shape[0]), np.zeros(0), None)
        rc = int(np.sum(s2 > max(1e-9, atol)))
        dropped += Cb.shape[0] - rc
        T = np.vstack([U.T[:r], (U2.T @ U.T[r:])[:rc]])
        Cm = (U2.T @ Cb)[:rc]
        if r + rc == 0:
            raise DesignError("the reduced system Q0 [Gf Gw] is zero: no residual that decouples u and d sees the "
                              "faults or the noise")
        if rc and r >= rank_n:
            # rank-deficient rest: combinations of the first r rows that shifting never separates
            C, D = np.vstack([Ct[:r], Cm]), np.vstack([Dt[:r], np.zeros((rc, D.shape[1]))])
            left = rc
            w = 1.0 / np.maximum(np.linalg.norm(np.hstack([C, D]), axis=1), 1e-300)
            C, D = C * w[:, None], D * w[:, None]
            Phi = LTI.static(np.diag(w) @ T, dt) @ Phi
            break
        if rc:
            if dt:
                Cn, Dn = Cm @ A, Cm @ B
            else:
                Cn, Dn = (Cm @ A + a * Cm) / a, (Cm @ B) / a
            C, D = np.vstack([Ct[:r], Cn]), np.vstack([Dt[:r], Dn])
            K += 1
            step = blockdiag([lowpass_power(a, 1, r, dt), LTI.static(np.eye(rc), dt)]) if r else \
                LTI.static(np.eye(rc), dt)
        else:
            C, D = Ct[:r], Dt[:r]
            step = LTI.static(np.eye(r), dt)  # only drops: Φ_j = T_j (kept rows), no shift
        w = 1.0 / np.maximum(np.linalg.norm(np.hstack([C, D]), axis=1), 1e-300)
        C, D = C * w[:, None], D * w[:, None]
        # rows kept unshifted take m when the others are shifted: Φ_j = diag(w) diag(m I_r, I_rc) T_j
        step = np.diag(w) @ step
        Phi = (step @ T) @ Phi
    else:
        raise DesignError(f"no full-row-rank feedthrough after {G.n + G.p + 1} interactor steps: the reduced system "
                          f"Q0 [Gf Gw] is numerically rank-deficient at infinity (relative tolerance 1e-9)")
    return LTI(A, B, C, D, dt), Phi, K, dropped, left


def _normal_rank(G: LTI) -> int:
    """Largest rank of G at four points off the axes (singular values above 1e-9 × the largest)."""
    rng = np.random.default_rng(7)
    lam = np.exp(1j * rng.uniform(0.3, 2.8, 4)) * 0.7 if G.dt else rng.uniform(0.3, 2, 4) * (1 + 1j)
    out = 0
    for l in lam:
        sv = np.linalg.svd(G.evalfr(l), compute_uv=False)
        out = max(out, int(np.sum(sv > 1e-9 * max(sv[0] if sv.size else 0.0, 1e-300))))
    return out


def _regularised(Gh: LTI, F: LTI, left: int, eps: float) -> tuple[LTI, LTI]:
    """``[Ĝ  ε E]`` and ``[F  0]``: fictitious noise ε on the ``left`` last (rank-deficient) rows."""
    if not left:
        return Gh, F
    E = np.zeros((Gh.p, left))
    E[-left:, :] = eps * np.eye(left)
    return hstack([Gh, LTI.static(E, Gh.dt)]), hstack([F, LTI.zero(F.p, left, F.dt)])


def lowpass_power(a: float, k: int, size: int, dt: float = 0.0) -> LTI:
    """``(a/(s + a))^k I_size``, in discrete time the delay ``z^{-k} I_size`` (the identity for k = 0)."""
    if k == 0:
        return LTI.static(np.eye(size), dt)
    if dt:
        A = np.diag(np.ones(k - 1), -1)
        a = 1.0
    else:
        A = -a * np.eye(k) + np.diag(np.full(k - 1, a), -1)
    b = np.zeros((k, 1))
    b[0, 0] = a
    c = np.zeros((1, k))
    c[0, -1] = 1.0
    m = LTI(A, b, c, np.zeros((1, 1)), dt)
    return blockdiag([m] * size)


def _check_placement(poles, sdeg, dt: float, smarg: float | None) -> float:
    """Stage of :func:`approximate_model_matching`: ``sdeg`` (default −1, or 0 — the delay — in discrete
    time) as a float, refused outside the stability region, and ``poles`` refused unless stable and within
    ``smarg`` (:func:`..toolkit._basis.check_poles`, the check every design's ``poles`` passes)."""
    if sdeg is None:
        sdeg = 0.0 if dt else -1.0
    try:
        sdeg = float(sdeg)
        check_poles([sdeg], dt)
    except (TypeError, ValueError, DesignError) as exc:
        region = "a real number of modulus below 1" if dt else "a negative real number"
        raise DesignError(f"sdeg (the pole of the updating factor M) must be {region}, got {sdeg!r}"
                          f"{f' ({exc})' if isinstance(exc, DesignError) else ''}") from None
    if poles is not None:
        try:
            np.atleast_1d(np.asarray(poles, complex))
        except (TypeError, ValueError):
            raise DesignError(f"poles must be numbers (the poles of the updating factor M), got {poles!r}") from None
        check_poles(poles, dt, smarg)
    return sdeg


def placed_factor(Qs: LTI, F: LTI, K: int, Kb: int, a: float, poles, sdeg: float, normalize: str, dt: float):
    """``(M, Q, M F, μ, placed)``: the updating factor with placed poles, ``M = μ m^Kb I``.

    The optimal filter of the non-standard problem is the improper ``Q∞ = Y Φ Q0 / m^K``
    (``Qs = Y Φ Q0``, ``m = a/(s + a)`` or ``1/z``, :func:`interactor`); any stable scalar ``μ``
    of relative degree K makes ``μ Q∞`` stable and proper, with the error
    ``μ Q∞ G1 − μ F = μ (Y Ĝ − F)``. Here ``μ = c/∏(λ − p_j)`` with the K poles ``p_j``
    (``poles`` first, the rest at ``sdeg``: :func:`..toolkit._basis.pick_poles`), as the peer's
    ``glcf(…; evals = poles, sdeg)`` gives the rows of its improper optimum; ``c`` by ``normalize``
    (``μ(0) = 1``, ``μ(1) = 1`` in discrete time; 1; ``||μ||∞ = 1``). ``Q = (μ/m^K) Qs``, with
    ``μ/m^K = c a^{−K} ∏ (λ − ζ)/(λ − p_j)`` (ζ = −a, or 0 and no ``a^{−K}`` in discrete time) realised
    as a chain of first- and second-order biproper sections; ``F`` carries the H2 low-pass ``m^Kb``
    already (its gain ``a^{−Kb}`` with ``normalize='gain'``)."""
    placed = pick_poles(poles, sdeg, K)
    zeta = 0.0 if dt else -a
    mus, ratios, i = [], [], 0
    while i < len(placed):
        z = complex(placed[i])
        if abs(z.imag) > 0:  # a conjugate pair: 1/(λ² − 2σλ + r²) and (λ − ζ)²/(λ² − 2σλ + r²)
            sig, r2 = z.real, abs(z) ** 2
            A = np.array([[0.0, 1.0], [-r2, 2 * sig]])
            B = np.array([[0.0], [1.0]])
            mus.append(LTI(A, B, np.array([[1.0, 0.0]]), np.zeros((1, 1)), dt))
            ratios.append(LTI(A, B, np.array([[zeta ** 2 - r2, 2 * sig - 2 * zeta]]), np.ones((1, 1)), dt))
            i += 2
        else:  # 1/(λ − p) and (λ − ζ)/(λ − p) = 1 + (p − ζ)/(λ − p)
            pr = z.real
            mus.append(LTI(np.array([[pr]]), np.ones((1, 1)), np.ones((1, 1)), np.zeros((1, 1)), dt))
            ratios.append(LTI(np.array([[pr]]), np.ones((1, 1)), np.array([[pr - zeta]]), np.ones((1, 1)), dt))
            i += 1
    mu, ratio = mus[0], ratios[0]
    for x, y in zip(mus[1:], ratios[1:]):
        mu, ratio = x @ mu, y @ ratio
    if normalize == "gain":
        c = 1.0
    elif normalize == "infnorm":
        c = 1.0 / float(mu.hinfnorm()[0])
    else:  # unit DC gain: 1/∏(−p_j), or 1/∏(1 − p_j) in discrete time (positive: conjugate-closed, stable)
        c = float(np.real(np.prod((1.0 if dt else 0.0) - np.asarray(placed))))
    mu = c * mu
    ratio = (c * (1.0 if dt else a ** -K)) * ratio
    sb = a ** -Kb if normalize == "gain" and not dt else 1.0
    p = F.p
    M = blockdiag([mu] * p) @ (sb * lowpass_power(a, Kb, p, dt))
    return M, blockdiag([ratio] * Qs.p) @ (sb * Qs), blockdiag([mu] * p) @ (sb * F), sb * mu, list(placed)


def row_shifts(Qs: LTI, K: int, a: float, dt: float) -> tuple[LTI, list[int]]:
    """``(Q', [k_i])``: the least number of shifts ``k_i`` each row of the improper optimum ``Q∞ = Qs/m^K``
    needs (``Qs = Y Φ Q0``, :func:`interactor`; ``m = a/(s + a)`` or ``1/z``), and ``Q' = diag(m^{k_i − K}) Qs``.

    Row i of ``Qs`` is ``m^{d_i}`` times a proper row when its first ``d_i`` Markov parameters in ``n = 1/m`` vanish:
    with the row ``(A, B, c, d)`` of the balanced realisation scaled to ``||[c d]|| = 1``, ``d`` counts as zero below
    ``1e-9·max(||B||, 1)`` (the interactor's own test), and then ``n·(A, B, c, 0) = (A, B, (cA + ac)/a, cB/a)``
    (discrete ``(A, B, cA, cB)``) is again a proper row on the same states; ``d_i`` (at most K) such steps give
    ``k_i = K − d_i``, the order of the infinite poles of row i of ``Q∞`` (in discrete time the delays it lacks) —
    the degree of the peer's ``glcf(…; mininf = true)`` factor of that row. ``Q'`` shares ``Qs``'s states; when no
    row divides (every ``k_i = K``) ``Qs`` is returned as it is."""
    if K == 0 or Qs.n == 0:
        return Qs, [K] * Qs.p
    bal, _ = Qs.balanced()
    A, B = bal.A, bal.B
    tol = 1e-9 * max(float(np.linalg.norm(B, 2)), 1.0)
    C, D = bal.C.copy(), bal.D.copy()
    shifts = []
    for i in range(Qs.p):
        c, d = C[i], D[i]
        k = K
        while k > 0:
            w = float(np.linalg.norm(np.r_[c, d]))
            if w == 0.0 or np.linalg.norm(d) > tol * w:
                break
            c, d = (c @ A, c @ B) if dt else ((c @ A + a * c) / a, (c @ B) / a)
            k -= 1
        C[i], D[i] = c, d
        shifts.append(k)
    if all(k == K for k in shifts):
        return Qs, shifts
    return LTI(A, B, C, D, Qs.dt), shifts


def _per_row_factors(Qs: LTI, F: LTI, shifts: list[int], Kb: int, a: float, poles, sdeg: float, normalize: str,
                     dt: float, placing: bool, atol: float):
    """Stage of :func:`approximate_model_matching` when the rows' shifts differ (:func:`row_shifts`): the diagonal
    updating factor ``M = diag(M_i)``, ``M_i = s_i m^{k_i + Kb}`` (``s_i = a^{−k_i−Kb}`` with ``normalize='gain'``,
    else 1), or with placed poles ``M_i = μ_i m^Kb`` of relative degree ``k_i`` (:func:`placed_factor` on the row),
    ``M_i = 1`` where ``k_i = 0`` — as the peer's ``ammsyn`` builds ``M`` from the ``glcf`` of each row.
    Returns ``(M, Q, M F, [μ_i] or None, the poles of the row with most shifts, [the poles of each M_i])``."""
    rows, Ms, MFs, mus, row_poles = [], [], [], [], []
    for i, k in enumerate(shifts):
        Qi, Fi = Qs[[i], :], F[[i], :]
        if placing and k:
            Mi, Qi, MFi, mu, placed = placed_factor(Qi.minreal(atol), Fi, k, Kb, a, poles, sdeg, normalize, dt)
        else:
            si = a ** -(k + Kb) if normalize == "gain" and not dt else 1.0
            Mi, Qi = si * lowpass_power(a, k + Kb, 1, dt), si * Qi
            MFi = si * lowpass_power(a, k, 1, dt) @ Fi
            placed, mu = [complex(-a if not dt else 0.0)] * k, LTI.static(np.array([[si]]), dt)
        rows.append(Qi)
        Ms.append(Mi)
        MFs.append(MFi)
        mus.append(mu)
        row_poles.append(list(placed) + [complex(-a)] * Kb)
    # without placed poles every row is its row of Qs scaled: one realisation on Qs's states (stacking the rows
    # would repeat them, and the staircase does not always find the repeats again)
    Q = vstack(rows) if placing else LTI(Qs.A, Qs.B, np.vstack([r.C for r in rows]), np.vstack([r.D for r in rows]),
                                         dt)
    return blockdiag(Ms), Q, vstack(MFs), mus if placing else None, row_poles[int(np.argmax(shifts))], row_poles


def _check_boundary_zeros(Gh: LTI) -> None:
    """Refuse transmission zeros of Ĝ on the stability boundary (SLICOT AB08ND); its zeros at
    infinity are gone (:func:`interactor` gives a full-row-rank feedthrough)."""
    z = transmission_zeros(Gh)
    dist = np.abs(np.abs(z) - 1.0) if Gh.dt else np.abs(z.real)
    bad = z[dist < 1e-7 * max(1.0, float(np.max(np.abs(z), initial=0.0)))]
    if bad.size:
        where = "on the unit circle" if Gh.dt else "on the imaginary axis"
        raise DesignError(f"non-standard problem not covered: the reduced system Q0 [Gf Gw] has zeros {where} "
                          f"({', '.join(f'{x:.4g}' for x in bad[:4])}); the optimum is not attained by a stable "
                          f"filter")


# ------------------------------------------------------------------ evaluation
#: relative distance (to ``max(|p|, ω_lo)``, ω_lo the grid's lowest positive frequency; to 1 in discrete time)
#: under which a grid point counts as on a system's pole and is moved beside it (:func:`_points`)
BESIDE_POLE = 1e-6


def _points(systems, dt: float, num: int = 400, resonances: bool = False) -> np.ndarray:
    """Points λ of a frequency grid over every system's poles (and ω → ∞ in continuous time), none on a
    pole of the systems: a point within ``BESIDE_POLE`` (relative) of one is moved ``2·BESIDE_POLE`` aside
    along the boundary.

    Every function read on these points (the error ``Q [Gf Gw] − M [Mr 0]``, ``Y Ĝ − F``) is stable, hence
    analytic on the boundary, but its factors are not: at a plant pole on the boundary (a fault-only
    integrator, z = 1), computed a rounding δ off, ``[Gf Gw]`` is ~ρ/δ and the product that cancels the pole
    is rounding/δ (approximate audit seeds 10–23: 3.6 … 3.9e8 for errors ~1). At the distance ``2·BESIDE_POLE``
    relative the rounding is amplified by eps/δ ≈ 1e-10 only, while the moved value differs from the one at
    the pole by ~1e-6 of the function's variation on its pole scale (below the grid's own resolution).

    ``resonances``: the points of :func:`_resonance_points` too (the readings of an H∞ peak: :func:`_hinf_at`)."""
    poles = _poles_of(systems)
    omega = frequency_grid(systems, num=num)
    omega = omega[np.isfinite(omega)]
    if not dt:
        omega = np.append(omega, 1e4 * max(omega.max(), 1.0))
    if resonances:
        omega = np.unique(np.concatenate([omega, _resonances(poles, dt)]))
    return _off_poles(omega, poles, dt)


def _resonance_points(systems, dt: float) -> np.ndarray:
    """Every complex pole's resonance frequencies as points λ (moved off the poles as :func:`_points` moves its own):
    the judge's own, :func:`.postconditions._resonances` — ``|Im s|`` and ``|Im s| ± |Re s|/2``, the peak and its
    half-power ends. Added to the grid where an H∞ peak is read (:func:`_hinf_at`, :func:`_judged_error`): a log grid
    of 200-400 points over the poles' decades has steps of a few per cent (4.7 % over approximate audit seed 268's
    systems), which straddle a lightly damped peak of half-width ``|Re s|/|Im s|`` (ζ = 0.016 there: values 2.6 and
    3.6 at ±2 % of the peak 4.728); :func:`_refined_peak` then refines between the peak's two half-power points,
    which bracket it. Approximate audit seeds 268 and 277: the returned error read 4.63869 and 11.8347, below the
    γ-iteration's certified infeasible levels 4.71833 and 11.85619, where numpy's refined peak reads 4.72841 and
    11.8606. Not added to the design's comparison and refit points (:func:`_design_points`): there they moved random
    H∞ seed 10's (reltol 1e-6) re-decoupling refit to a realisation refused for its rounding sensitivity 1.1e-6."""
    poles = _poles_of(systems)
    return _off_poles(_resonances(poles, dt), poles, dt)


def _poles_of(systems) -> np.ndarray:
    return np.concatenate([np.ravel(np.asarray(s.poles(), complex)) for s in systems] + [np.zeros(0)])


def _off_poles(omega: np.ndarray, poles: np.ndarray, dt: float) -> np.ndarray:
    """The points λ of the frequencies ω, a point within ``BESIDE_POLE`` of a pole moved ``2·BESIDE_POLE`` aside
    (:func:`_points`)."""
    lam = np.exp(1j * omega * dt) if dt else 1j * omega
    if poles.size:
        from ...freqresp import beside_poles  # the one "on a pole" test, with its scale per pole (in λ; discrete: θ)

        on, radius = beside_poles(lam, poles, dt, BESIDE_POLE)
        if np.any(on):
            step = 2.0 * radius[on]  # ω (continuous) or θ = ω dt (discrete, |p| ≈ 1 on the circle)
            theta = omega * dt if dt else omega.copy()
            top = np.pi if dt else np.inf
            # toward the interior: down at Nyquist (z = −1), up elsewhere
            theta[on] = np.where(theta[on] + step < top, theta[on] + step, theta[on] - step)
            lam = np.unique(np.exp(1j * theta) if dt else 1j * theta)
    return lam


def _mk(lam: np.ndarray, a: float, K: int, dt: float) -> np.ndarray:
    """``m(λ)^K`` with ``m = a/(s + a)`` or ``1/z``."""
    return (1.0 / lam) ** K if dt else (a / (lam + a)) ** K


#: :func:`_refined_peak` with ``climb``: grid points reading within this fraction of the highest one count as its
#: plateau, and the bracket refined reaches past them to the nearest points reading lower. The plateau it is for:
#: approximate audit seed 500's judged error read 15.687039 (8 digits) at four grid points all at 0.3237 rad/s (4
#: digits; a lightly damped pole's resonance points). A bracket widened past points 1e-9 lower still holds a peak at
#: least as high (both its ends read lower than a point inside).
PEAK_PLATEAU_RTOL = 1e-9


def _refined_peak(values, lam: np.ndarray, dt: float, climb: bool = False) -> float:
    """Peak of ``σ_max`` of ``values(λ)`` on the grid, refined by 60 points around the 3 highest.

    ``climb`` (the returned filter's judged error, :func:`_judged_error`): then twice more, 60 points between the
    nearest points left and right of the highest reading so far (grid and refined points together) that read below
    it by more than :data:`PEAK_PLATEAU_RTOL` — a bracket of a local maximum at least as high (its ends read lower
    than a point inside). Without it, the 3 highest grid points can all lie in one cluster of near-equal points (the
    resonance points of :func:`_resonance_points` around a pole the error does not peak at), and their neighbours'
    intervals never reach the peak beside the cluster: approximate audit seed 500 (``Mr`` = a detection row) read
    15.6870387 (cluster at 0.3237 rad/s) for numpy's 15.6884809 at 0.32558 (= γ_opt), below the γ-iteration's
    certified infeasible level 15.6881036, and :func:`_below_certified_refused` refused the design."""
    w = np.angle(lam) / dt if dt else lam.imag
    sig = _nrm(values(lam))
    sig[~np.isfinite(sig)] = 0.0
    best = float(np.max(sig))
    order = np.argsort(w)
    w, sig = w[order], sig[order]
    seen_w, seen_s = [w], [sig]

    def refined(lo, hi):  # the peak of 60 points in [lo, hi], kept with the points seen
        ww = np.linspace(lo, hi, 60)
        v = _nrm(values(np.exp(1j * ww * dt) if dt else 1j * ww))
        v[~np.isfinite(v)] = 0.0
        seen_w.append(ww)
        seen_s.append(v)
        return float(np.max(v, initial=0.0))

    for i in np.argsort(sig)[-3:]:
        best = max(best, refined(w[max(i - 1, 0)], w[min(i + 1, w.size - 1)]))
    for _ in range(2 if climb else 0):
        aw, as_ = np.concatenate(seen_w), np.concatenate(seen_s)
        order = np.argsort(aw, kind="stable")
        aw, as_ = aw[order], as_[order]
        i = int(np.argmax(as_))
        lower = as_ < as_[i] * (1.0 - PEAK_PLATEAU_RTOL)
        left, right = np.flatnonzero(lower[:i]), np.flatnonzero(lower[i + 1:])
        lo = aw[left[-1]] if left.size else aw[0]
        hi = aw[i + 1 + right[0]] if right.size else aw[-1]
        if not lo < hi:
            break
        best = max(best, refined(lo, hi))
    return best


def _h2_quad(values, systems, dt: float) -> float:
    """H2 norm of a stable system given by its values: ``(1/π) ∫_0^Ω ||E(λ(ω))||_F² dω`` with
    Gauss–Legendre rules (16 nodes) on log-spaced panels, 4 per decade, from 1e-4 times the
    slowest to 1e4 times the fastest pole scale (Ω = π/dt in discrete time, where the rule
    runs on a linear grid below the slowest scale), plus the tail ``f(ω_end) ω_end`` of an
    integrand decaying like 1/ω² (continuous time, strictly proper).

    Used instead of the Gramian formula ``tr(C P Cᵀ)`` on the product realisations, where the
    output cancels much larger states and the trace loses every digit (a matched error of
    ~1e-8 came out as 0.05)."""
    omega = frequency_grid(systems, num=8)
    omega = omega[np.isfinite(omega) & (omega > 0)]
    lo, hi = omega.min() * 1e-2, omega.max() * 1e2
    if dt:
        hi = np.pi / dt
    edges = np.logspace(np.log10(lo), np.log10(hi), max(int(4 * np.log10(hi / lo)), 1) + 1)
    edges = np.concatenate([[0.0], edges])
    x, wq = np.polynomial.legendre.leggauss(16)
    a0, b0 = edges[:-1, None], edges[1:, None]
    w = (0.5 * (b0 - a0) * x + 0.5 * (b0 + a0)).ravel()  # (every panel's nodes in one call: a reading with
    # per-call set-up — the post-conditions' mode-free reading, a Schur form and Sylvester solves per call — cost 20 of
    # approximate audit seed 240's 35 s H2 design as 98 calls of 16 points)
    f = np.sum(np.abs(values(np.exp(1j * w * dt) if dt else 1j * w)) ** 2, axis=(1, 2)).reshape(-1, x.size)
    total = 0.0
    for k in range(f.shape[0]):  # (the panels summed in order, as before)
        total += 0.5 * float(edges[k + 1] - edges[k]) * float(np.sum(wq * f[k]))
    if dt:
        return float(np.sqrt(total * dt / np.pi))
    L = np.array([1j * hi])
    total += float(np.sum(np.abs(values(L)) ** 2)) * hi
    return float(np.sqrt(total / np.pi))


# ------------------------------------------------------------------ standard problem
def _plant(Gh: LTI, F: LTI):
    """Generalised plant ``P = [−F  I; Ĝ  0]`` (inputs [v; r], outputs [z; y])."""
    r, q, m1 = F.p, Gh.p, F.m
    nF, nG = F.n, Gh.n
    A = sla.block_diag(F.A, Gh.A) if nF + nG else np.zeros((0, 0))
    B = np.hstack([np.vstack([F.B, Gh.B]), np.zeros((nF + nG, r))])
    C = np.vstack([np.hstack([-F.C, np.zeros((r, nG))]), np.hstack([np.zeros((q, nF)), Gh.C])])
    D = np.block([[-F.D, np.eye(r)], [Gh.D, np.zeros((q, r))]])
    return A, B, C, D, nF + nG, m1 + r, r + q, r, q


def solve_standard(Gh: LTI, F: LTI, norm: str, reltol: float) -> tuple[LTI, dict]:
    """``Y ∈ RH∞`` minimising ``||Y Ĝ − F||`` (Ĝ stable with full-row-rank feedthrough)."""
    dt = Gh.dt
    U, sv, Vt = np.linalg.svd(Gh.D, full_matrices=True)
    q = Gh.p
    Dpinv = Vt[:q].T @ np.diag(1.0 / sv[:q]) @ U.T
    Y0 = F.D @ Dpinv  # best constant at infinity: min ||Y0 D̂ − D_F|| (Parrott with full-row-rank D̂)
    dres = F.D - Y0 @ Gh.D
    if norm == "2" and dt:
        return _h2_discrete(Gh, F)
    if norm == "2":
        if np.linalg.norm(dres) > 1e-9 * max(np.linalg.norm(F.D), np.linalg.norm(Gh.D) * np.linalg.norm(Y0), 1e-300):
            raise DesignError(f"the H2 problem has no solution: the error's feedthrough D_F − Y D_G cannot vanish "
                              f"(smallest reachable size {np.linalg.norm(dres, 2):.3g}): use a strictly proper Mr "
                              f"(e.g. Mr·a/(s+a)) or norm='inf'")
        F1 = (F - Y0 @ Gh).minreal() if F.n or Gh.n else LTI.static(np.zeros(F.shape), dt)
        F1 = LTI(F1.A, F1.B, F1.C, np.zeros(F1.D.shape), dt)
        if F1.n == 0:
            return LTI.static(Y0, dt), {"gamma": 0.0}
        import slycot

        A, B, C, D, n, m, np_, ncon, nmeas = _plant(Gh, F1)
        try:
            Ak, Bk, Ck, Dk, _ = slycot.sb10hd(n, m, np_, ncon, nmeas, A, B, C, D)
        except (SlycotError, ValueError, np.linalg.LinAlgError) as exc:  # SLICOT's info text
            raise DesignError(f"H2 synthesis (SLICOT SB10HD) failed: {exc}") from None
        Y = LTI(Ak, Bk, Ck, Dk, dt) + LTI.static(Y0, dt)
        E = Y @ Gh - F
        return Y, {"gamma": _h2_quad(lambda L: _values(E, L), [Gh, Y, F], dt)}
    lo = float(np.linalg.norm(dres, 2)) if not dt else 0.0
    fnorm = float(F.hinfnorm()[0])
    hi = 1.01 * fnorm + 1e-12
    if F.n + Gh.n == 0:  # (a constant error: ||D_F − Y0 D̂|| is its least value, in either time domain)
        return LTI.static(Y0, dt), {"gamma": lo, "bracket": (lo, lo), "fnorm": fnorm,
                                    "lower_bound": float(np.linalg.norm(dres, 2))}
    hi0 = hi
    bound = lo  # a certified lower bound of the infimum: the error at s = ∞ (Parrott), then each refused level
    lo = max(lo, hi * 1e-9)
    best = _hinf_at(Gh, F, hi)
    if best is None or best[2] is False:
        raise DesignError(f"H∞ synthesis failed even at γ = {hi:.6g} > ||Mr||∞ (where Q = 0 is feasible): the "
                          f"Riccati equations of the reduced problem are ill-conditioned")
    Ybest, ebest, _ = best
    # bisection on the level; the controller kept is the one with the smallest measured error
    # (near γopt the central controller loses accuracy, and far below ||F|| SLICOT's conditioning
    # checks refuse levels that are feasible: an exactly matchable reference reached 3e-11 at
    # γ = 1e-3 but 1.6e-6 at the smallest accepted level). A level above ||F||∞ (1 + HINF_F_RTOL) is
    # feasible — Y = 0 has error ||F||∞ — so a refusal there is the central controller's accuracy, never
    # infeasibility: the level moves the upper end and its controller, if SLICOT returned one, competes by its
    # measured error (approximate audit seed 120, Mr = I on 4 faults and one residual row, γopt = ||F||∞ = 1:
    # the central controllers at 1.0014 … 1.00005 measured γ·(1 + 1.7e-6), above SB10FD's certificate by more
    # than 1e-6, so those levels were called infeasible, the bracket stopped at [1.00148, 1.00156] and the
    # filter's 1.00155 was refused as worse than Q = 0's 1 by more than reltol). It stops when both the feasible
    # level and the kept controller's measured error are within reltol of the infeasible level (the figure
    # returned, not only the level: the two differ by the controllers' accuracy), when the levels are within
    # HINF_LEVEL_FLOOR·reltol (the controllers' inaccuracy, not the bracket, then limits the figure), or when a
    # measured error is already
    # below the infeasible level (then that level was a numerical refusal, and the error — an upper bound of
    # γopt — is the answer)
    while ((hi > lo * (1 + reltol) or ebest > lo * (1 + reltol)) and hi > lo * (1 + HINF_LEVEL_FLOOR * reltol)
           and ebest > lo and ebest > 1e-12 * hi0):
        mid = np.sqrt(lo * hi)
        got = _hinf_at(Gh, F, mid)
        feasible = got is not None and got[2]
        if not feasible and mid > fnorm * (1 + HINF_F_RTOL):
            feasible = True  # (Y = 0 proves it: the refusal is numerical)
        if not feasible:
            lo = bound = mid
            continue
        hi = mid
        if got is not None and got[1] < ebest:
            Ybest, ebest = got[:2]
    if ebest < lo:  # the last refusal was numerical: the measured error bounds γopt from above
        lo = hi = ebest
        bound = 0.0  # (no refusal is a certificate then)
    else:  # SB10's certificate ||E|| < γ holds to the accuracy of its Riccati solutions (~1e-6)
        hi = max(hi, ebest)
    # ``lower_bound``: the infimum is at least this (0 where nothing certifies one); ``fnorm``: ||F||∞, Y = 0's error
    return Ybest, {"gamma": ebest, "bracket": (lo, hi), "lower_bound": float(bound), "fnorm": fnorm}


#: :func:`solve_standard`: a level above ``||F||∞·(1 + HINF_F_RTOL)`` is feasible (Y = 0; SLICOT AB13DD's norm is
#: accurate to ~2·1e-10 relative, its default tolerance, so 1e-8 leaves a margin)
HINF_F_RTOL = 1e-8
#: :func:`solve_standard`: the γ-iteration stops once its levels are within this fraction of ``reltol`` (four more
#: halvings of the bracket's logarithm than ``reltol``) even if the measured error is not yet within ``reltol`` of
#: the infeasible level
HINF_LEVEL_FLOOR = 1.0 / 16


def _h2_discrete(Gh: LTI, F: LTI) -> tuple[LTI, dict]:
    """Discrete-time H2: ``Y`` is the minimum-variance causal estimator of ``s = F v`` from
    ``y = Ĝ v`` (v unit white noise), a Kalman filter with the current measurement.

    With ``x⁺ = A x + B v``, ``y = C2 x + D21 v``, ``s = C1 x + D11 v`` (the states of F and Ĝ),
    ``P`` solves the filter DARE with ``R = D21 D21ᵀ`` (positive definite: Ĝ is standard) and
    ``S = B D21ᵀ``; ``Σ = C2 P C2ᵀ + R``, ``L = (A P C2ᵀ + S) Σ⁻¹``, ``Kd = (C1 P C2ᵀ + D11 D21ᵀ) Σ⁻¹``
    and ``Y = (A − L C2, L, C1 − Kd C2, Kd)``. It minimises ``E‖ŝ − s‖²`` = ``‖Y Ĝ − F‖₂²``
    (Anderson & Moore, *Optimal Filtering*, 1979, ch. 5; the role of SLICOT SB10ED, which
    slycot does not wrap).

    The DARE is solved by :func:`_filter_dare` (scipy, then SLICOT SB02OD on the factors ``B``, ``D21``; checked);
    scipy's ``solve_discrete_are`` on the formed ``B Bᵀ``, ``D21 D21ᵀ`` returned, without an error, an indefinite
    ``P`` of norm 1e14 with a relative residual 0.75 on random discrete H2 seed 9 (an exactly matchable problem: the
    optimum is 0, reached by a Y of peak gain 32.5); the filter built on it had error 0.49 and gain 7e7, and Y's
    gain times the rounding of ``Q0 [Gu Gd; I 0] = 0`` leaked u into the residual (refused by the judge).
    """
    dt = Gh.dt
    A = sla.block_diag(F.A, Gh.A) if F.n + Gh.n else np.zeros((0, 0))
    B = np.vstack([F.B, Gh.B])
    C1 = np.hstack([F.C, np.zeros((F.p, Gh.n))])
    C2 = np.hstack([np.zeros((Gh.p, F.n)), Gh.C])
    D11, D21 = F.D, Gh.D
    R = D21 @ D21.T
    n = A.shape[0]
    if n == 0:
        Kd = np.linalg.solve(R, D21 @ D11.T).T
        Y = LTI.static(Kd, dt)
    else:
        S = B @ D21.T
        P = _filter_dare(A, B, C2, D21)
        Sig = C2 @ P @ C2.T + R
        L = np.linalg.solve(Sig, (A @ P @ C2.T + S).T).T
        Kd = np.linalg.solve(Sig, (C1 @ P @ C2.T + D11 @ D21.T).T).T
        Y = LTI(A - L @ C2, L, C1 - Kd @ C2, Kd, dt)
    E = Y @ Gh - F
    return Y, {"gamma": _h2_quad(lambda lam: _values(E, lam), [Gh, Y, F], dt)}


def _filter_dare(A: np.ndarray, B: np.ndarray, C2: np.ndarray, D21: np.ndarray) -> np.ndarray:
    """The stabilising solution ``P = Pᵀ ≥ 0`` of the filter DARE of :func:`_h2_discrete`,

        P = A P Aᵀ − (A P C2ᵀ + S)(C2 P C2ᵀ + R)⁻¹(A P C2ᵀ + S)ᵀ + B Bᵀ,   R = D21 D21ᵀ,  S = B D21ᵀ,

    the dual of the spectral factorisation's DARE, solved by :func:`..toolkit.approximate.spectral_riccati` on
    ``(Aᵀ, C2ᵀ, Bᵀ, D21ᵀ)``: scipy's QZ solver, then SLICOT SB02OD on the factors (``R⁻¹``, of condition 1/ε² with
    the fictitious noise ε of regularised rows, never formed; Van Dooren, SIAM J. Sci. Stat. Comput. 2, 1981), then
    Newton's method from a stabilising answer of either (:mod:`..toolkit.riccati_newton`), an answer kept only if its
    residual is within ``RICCATI_RTOL`` of the terms' size and its closed-loop correction within ``FORWARD_RTOL``.
    Here also: P positive semidefinite (to ``RICCATI_RTOL`` of ``max(||P||, ||B||²)``: an exactly estimable state has
    P = 0 to rounding) and ``A − L C2`` stable (the stabilising solution); else DesignError (the regularisation ladder
    then tries the next ε). scipy's solution of random seed 9's equation, taken unchecked before, was indefinite with
    norm 1e14 and a relative residual 0.75; SB02OD's residual there is 3e-14 (P = 0: the problem is exactly matchable).

    A closed loop ``A − L C2`` with an eigenvalue within ``ZERO_BOUNDARY_RTOL`` of the unit circle is accepted only if
    the equation has a stabilising solution by the data (below): its eigenvalues are the noise channel's zeros
    reflected inside, and a zero on the circle (``Ĝ = (0.5, 0.5, 1, −1)``: zero at 1) leaves ``P = 0`` with the loop at
    ``1 − 1e-16`` — the maximal solution, not a stabilising one — which was returned as one.

    The refusal says why (:func:`..observers._observer.riccati_existence`, on the equation's data in filter form:
    ``(A, C2)`` detectable and the symplectic pencil's eigenvalues off the unit circle by more than
    :func:`~fmu_fdi.design.toolkit.riccati_newton.boundary_gap`'s tolerance — its ``(A, B, Q, R, S)`` are the control
    form's ``(Aᵀ, C2ᵀ, BBᵀ, D21D21ᵀ, BD21ᵀ)``, the same dual as ``spectral_riccati``'s here): "no stabilising
    solution" with the mode that prevents it, or "a stabilising solution exists" and a numerical failure with the
    figures — the forward line's correction where an answer with a stabilising gain was refused by it (before, every
    refusal said "no stabilising solution")."""
    from ..observers._observer import riccati_existence
    from ..toolkit import approximate
    from ..toolkit.approximate import RICCATI_RTOL, ZERO_BOUNDARY_RTOL, spectral_riccati

    n = A.shape[0]
    figures: dict = {}
    # (slycot's SB02OD wrapper computes the closed-loop spectrum as α/β, dividing by β = 0 at the pencil's infinite
    # eigenvalues: not used here)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        P = spectral_riccati(A.T.copy(), C2.T.copy(), B.T.copy(), D21.T.copy(), 1.0, figures=figures)
    exists = None

    def existence():
        return riccati_existence(A, C2, B @ B.T, D21 @ D21.T, B @ D21.T, 1.0)

    fwd = figures.get("forward", np.inf)
    if P is not None:
        Sig = C2 @ P @ C2.T + D21 @ D21.T
        try:
            L = np.linalg.solve(Sig, (A @ P @ C2.T + B @ D21.T).T).T
        except np.linalg.LinAlgError:
            L = None
        low = float(np.linalg.eigvalsh(P).min()) if n else 0.0
        scale = max(float(np.linalg.norm(P, 2)), float(np.linalg.norm(B, 2)) ** 2, 1e-300)
        rho = float(np.max(np.abs(np.linalg.eigvals(A - L @ C2)))) if L is not None and n else np.inf
        if low >= -RICCATI_RTOL * scale and rho < 1.0:
            if rho < 1.0 - ZERO_BOUNDARY_RTOL:
                return P
            exists = existence()
            if exists[0] is not False:
                return P
        detail = (f"the answer (relative residual {figures.get('residual', np.nan):.3g}, closed-loop correction "
                  f"{fwd:.3g} of its scale) is not the stabilising solution: smallest eigenvalue of P {low:.3g} "
                  f"(||P|| = {float(np.linalg.norm(P, 2)):.3g}), spectral radius of A − L C2 {rho:.6g} "
                  f"(1 − ρ = {1.0 - rho:.3g})")
    elif np.isfinite(fwd):
        # refused by the forward line: a solver's answer within RICCATI_RTOL with a stabilising gain, whose
        # closed-loop correction Newton's steps did not bring within the line
        detail = (f"the closest answer's closed-loop correction ‖P_K − P‖_F (the forward error of P to first order) is "
                  f"{fwd:.3g} of its scale after {figures.get('steps', 0)} Newton steps, above FORWARD_RTOL = "
                  f"{approximate.FORWARD_RTOL:g} ({figures.get('why', '')}"
                  + (f"; closed-loop separation {figures['sep']:.3g}, rounding floor {figures['floor']:.3g}"
                     if "sep" in figures else "") + ")")
    else:
        detail = ("no answer with a residual within RICCATI_RTOL and a stabilising gain (scipy, SLICOT SB02OD, "
                  "Newton's method from either)" + (f": {figures['why']}" if figures.get("why") else ""))
    ok, why = exists if exists is not None else existence()
    head = "discrete H2 synthesis: the filter Riccati equation"
    if ok is False:
        raise DesignError(f"{head} has no stabilising solution ({why}); {detail}")
    if ok:
        raise DesignError(f"{head} has a stabilising solution — {why} — but it was not computed to the accuracy the "
                          f"filter needs, a numerical failure: {detail}")
    raise DesignError(f"{head} was not solved ({detail}); whether a stabilising solution exists was not decided "
                      f"({why})")


def _hinf_at(Gh: LTI, F: LTI, gamma: float):
    """The central controller for level γ, its measured error and whether that error is within SB10's
    certificate ``< γ`` (to 1e-6) — or None if SLICOT returns no stable controller at γ."""
    import slycot

    A, B, C, D, n, m, np_, ncon, nmeas = _plant(Gh, F)
    Y = None
    # SLICOT's default tolerance (√eps) on the conditioning of the Riccati solutions refuses
    # levels far below ||F|| that are feasible (exactly matchable references: γopt = 0); a
    # level refused with it is tried once more with 1e3·eps, the measured error deciding
    for tol in (0.0, 1e3 * EPS):
        try:
            if Gh.dt:
                Ak, Bk, Ck, Dk = slycot.sb10dd(n, m, np_, ncon, nmeas, gamma, A, B, C, D, tol=tol)[1:5]
            else:
                Ak, Bk, Ck, Dk, _ = slycot.sb10fd(n, m, np_, ncon, nmeas, gamma, A, B, C, D, tol=tol)
        except (SlycotError, ValueError, np.linalg.LinAlgError):  # infeasible level, or a
            continue  # numerically singular Riccati solution at it: the next tolerance decides
        Y = LTI(Ak, Bk, Ck, Dk, Gh.dt)
        break
    if Y is None:
        return None
    if not np.all(np.isfinite(Y.A)) or not Y.is_stable():
        return None
    # SB10FD/SB10DD certify ||Y Ĝ − F||∞ < γ; a refined grid peak checks it (H∞ norms of the
    # product realisation, order 2 (nF + nĜ), lose digits when Y's gain is large)
    E = Y @ Gh - F
    e = _refined_peak(lambda L: _values(E, L), _points([Gh, Y, F], Gh.dt, 200, resonances=True), Gh.dt)
    if not np.isfinite(e):
        return None
    return Y, e, bool(e <= gamma * (1 + 1e-6))
