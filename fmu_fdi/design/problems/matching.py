"""Exact model matching (EMMP): a residual generator whose fault response is a given reference.

Find a proper stable ``Q`` with

    Q(λ) [Gu Gd Gf; I 0 0](λ) = [0 0 Mr(λ)]

(Varga 2017, sec. 5.6, Procedure EMM; FaultDetectionTools.jl ``emmsyn``) — u and d
decoupled and the fault-to-residual map equal to the reference ``Mr``.

**Least order, row by row** (``emmsyn``'s default ``minimal = true``: ``glsol(…; mindeg =
true)`` then a coprime factor per row), on the one synthesis core (:mod:`..toolkit.pencil`).
A row ``Q_i`` solves ``Q_i Ge = [0 0 Mr_i]`` iff ``[Q_i,y  −1  Q_i,u]`` is a left annihilator of
the augmented system ``[Gu Gd Gf; 0 0 Mr_i; I 0 0]`` — the plant with the output ``z = Mr_i f``
appended and f treated as an unknown input. The core's proper minimal basis of that null space,
made simple by Type 1 minimum dynamic covers (one row ``N_j`` per left minimal index ``ν_j``),
has the predictable degree property, so the least McMillan degree of a solution is the least
``ν_j`` whose row has a nonzero z-entry, and ``Q_i = −N_z^{-1} [N_y N_u]`` of that row reaches it
(:mod:`..toolkit.least_solve`; a reference's poles need not be the filter's: ``Mr = Gf`` is
matched by the static ``Q = [I 0]``). Its poles are the zeros of ``N_z``. When this least-order
row is unstable or improper:

- ``updating=False``: a stable proper solution exists iff the Mr-column ``N_z`` of the whole
  basis (stable, proper, without zeros) has no zero outside the stability region and none at
  infinity; then ``Q_i = −(Y N)_{y,u}`` with the observer-based stable left inverse Y of
  ``N_z`` (:func:`..toolkit.least_solve.stable_solution`), otherwise a DesignError names the
  zeros (every exact solution has them as poles). That stable row is then lowered where it can
  be (``row_methods`` 'least stable order'): ``Q_i' = X1 + Y N_b`` with ``N_b`` the null-space basis
  of ``[Gu Gd Gf; I 0 0]`` and X1 the least-order (unstable) row when it is proper, else the stable
  one, by a stable minimum dynamic cover (:func:`..toolkit.covers.stable_left_cover`: the least k
  whose admissible closed-loop characteristic polynomials contain a stable one, the free poles at
  ``poles``/``sdeg``); a lowered row is taken only if its ``R = Q Ge`` agrees with the stable
  solution's to ``mm_tol`` on a grid. What is guaranteed is stated there: least among stable
  solutions when the admissible set at each lower order is one polynomial or all of them;
- ``updating=True`` (Procedure EMM step 3; ``emmsyn``'s ``info.M``): the reference is matched
  up to a diagonal updating factor, ``Q Ge = [0 0 M Mr]``. For an unstable but proper least
  row, ``[Q_i  m_i Mr_i] = m_i [Q0  Mr_i]`` is a stable left coprime factorisation of the
  whole row (output injection moving only the poles outside the stability region, as
  ``glcf(…; mindeg = true)``; :func:`..toolkit.pencil.assign_poles`), so that both the filter and its
  fault response ``m_i Mr_i`` are stable; for an improper one, the least-degree null row itself,
  ``(Q_i, m_i) = ([N_y N_u], −N_z)``, with its ν poles placed by output injection at the chosen
  poles. ``m_i`` is normalised to unit zpk gain (the first nonzero Markov parameter,
  ``normalize='gain'``, as in Varga's Example 5.13) or to unit H∞ norm (``'infnorm'``).

Numerics. Each reference row is solved at unit peak gain and scaled back (a row of gain
1e-8 beside rows of gain 1 keeps its own accuracy); modes of its realisation with Hankel
singular values at or below ``mm_tol`` (plant modes a product ``Q Ge`` cancels only to ~1e-12)
are dropped (:func:`_drop_cancelled`), so that no row pays an order for them; the plant modes
outside the stability region are made to cancel exactly in ``R = Q Ge`` by a minimum-norm
correction of Q's y-input part (:func:`_cancel_plant_modes`). Every returned row is verified
on an independent grid: the relative matching error of each row must not exceed
``sqrt(mm_tol)`` and the post-conditions (:mod:`..toolkit.postconditions`) must hold. ``atol``
is the absolute rank tolerance of the core's rank decisions and of the minimal realisations.

The approximate problem (AMMP, H∞/H2 optimal) is :mod:`.approximate_matching`.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import ordered_schur, single_blas_thread
from ...lti import LTI, blockdiag, frequency_grid, vstack
from ...model import FDIModel
from ..toolkit._basis import check_poles, pole_chooser
from .reference import reference
from ..toolkit.postconditions import DEC_TOL, _values, check_generator, default_smarg
from ..toolkit.notes import keeps_notes, silenced
from ..toolkit.least_solve import least_row, stable_solution
from ...margin import margin_limit


@keeps_notes
@single_blas_thread
def model_matching(model: FDIModel, Mr, *, poles=None, sdeg: float | None = None, max_degree: int | None = None,
                   mm_tol: float = 1e-9, smarg: float | None = None, dec_tol: float = DEC_TOL,
                   updating: bool = False, normalize: str = "gain", atol: float = 0.0) -> ResidualGenerator:
    """Exact model matching ``Q Ge = [0 0 Mr]`` by a stable proper Q whose rows have least order.

    Parameters
    ----------
    model : FDIModel
    Mr : LTI, python-control system or matrix
        Reference fault-to-residual map: (residuals × fault columns). Stable unless
        ``updating=True`` (then the updating factor also stabilises ``M Mr``).
    poles, sdeg : optional
        Poles given to the filter where they are free (as in
        :func:`~fmu_fdi.design.problems.nullspace.nullspace_design`): the core basis' poles, the
        poles the stable left inverse assigns, and the poles moved by the updating factor. The
        least-order row's poles are the zeros of its basis row's Mr-entry, not free.
    max_degree : int, optional
        Largest McMillan degree of a returned row (default: no bound); a row that needs more
        is refused with a DesignError naming its least degree.
    mm_tol : float
        Relative threshold of the matching's rank decisions: a reference row's Hankel singular
        values and a basis row's Mr-entry (Markov parameters, and its feedthrough for
        properness) at or below ``mm_tol`` of the row's size are zero; a returned row's
        relative matching error must be ≤ ``sqrt(mm_tol)``.
    smarg, dec_tol : float, optional
        Stability margin and decoupling tolerance of the post-conditions.
    updating : bool
        Allow a diagonal stable updating factor M: ``Q Ge = [0 0 M Mr]`` (``emmsyn``'s
        ``info.M``); needed when the least-order solution is improper or unstable.
    normalize : {'gain', 'infnorm'}
        Normalisation of each ``m_i`` with ``updating=True``: unit zpk gain or unit H∞ norm.
    atol : float
        Absolute rank tolerance (Varga's ``atol``): singular values of the model's and the
        reference's realisations below it are zero in the minimal realisations of ``Mr_i``
        and of each row, and the rank decisions of the core's pencil basis (Varga's ``atol``).

    Returns
    -------
    ResidualGenerator
        ``info``: ``row_orders`` (McMillan degree of each row), ``degree`` (their largest),
        ``order``, ``row_methods`` ('least order', 'stable solution', 'least stable order',
        'coprime factor', 'updating'), ``left_minimal_indices`` (per row, of the augmented system),
        ``matching_error`` (grid peak of ``||Rf − M Mr||`` relative to ``||M Mr||``),
        ``postconditions``, ``poles``, ``plant_mode_cancellation`` (whether the exact cancellation of the
        plant's unstable modes in R was applied — only when it keeps the match within ``mm_tol`` or improves
        it — with the errors before and after, :func:`_cancel_plant_modes`); with ``updating=True`` ``M``
        (LTI, diagonal),
        ``row_degrees`` (order of each ``m_i``) and ``M_zeros``.

    Raises
    ------
    DesignError
        Mr has the wrong shape, a zero row, or is unstable (without ``updating``), or no
        stable proper row (of degree ≤ ``max_degree``) matches a row of it: the message names
        the condition (no null row with a nonzero Mr-entry; the zeros that every exact
        solution has as poles; an improper least solution).
    """
    if normalize not in ("gain", "infnorm"):
        raise DesignError(f"normalize must be 'gain' or 'infnorm', got {normalize!r}")
    if not (np.isfinite(atol) and atol >= 0):
        raise DesignError(f"atol must be a finite non-negative number, got {atol!r}")
    if not (0 < mm_tol < 1):
        raise DesignError(f"mm_tol must lie in (0, 1), got {mm_tol!r}")
    if max_degree is not None and not (isinstance(max_degree, (int, np.integer)) and max_degree >= 0):
        raise DesignError(f"max_degree must be a non-negative integer, got {max_degree!r}")
    Mr = reference(model, Mr, stable=False, minimal=False)
    check_poles(poles, model.dt)
    chooser = pole_chooser(model, poles, sdeg)

    def choose(count):  # "poles not used" is no news for the internal reference denominators
        with silenced():
            return chooser(count)

    margin = default_smarg(model.dt) if smarg is None else float(smarg)
    lim = margin_limit(margin)  # the stability region, inclusive (Re λ ≤ smarg, |λ| ≤ smarg), as the peer's
    good = (lambda re, im: np.hypot(re, im) <= lim) if model.dt else (lambda re, im: re <= lim)  # noqa: E731
    rows, ms, methods, degs, index_degrees = [], [], [], [], []
    for i in range(Mr.p):
        # each row is solved at unit peak gain (a row of gain 1e-8 next to rows of gain 1 would
        # otherwise lose its dynamics to the others' rank tolerance) and scaled back
        scale = _peak(model, Mr[i, :])
        if not scale > 0:
            raise DesignError(f"row {i + 1} of Mr is zero: the only match is the zero filter, which detects no fault")
        Mi = _drop_cancelled((Mr[i, :] * (1.0 / scale)).minreal(atol), margin, max(atol, mm_tol))
        if not updating and not _stable(Mi, margin, model.dt):
            bad = Mi.poles()
            worst, what = (float(np.max(np.abs(bad))), "largest |pole|") if model.dt else \
                (float(np.max(bad.real)), "largest Re(pole)")
            raise DesignError(f"row {i + 1} of Mr is not stable ({what} = {worst:.6g}, stability margin "
                              f"{margin:.3g}): the fault response Rf = Mr would be; pass updating=True (the "
                              f"updating factor M makes M Mr stable) or a stable reference")
        top = np.inf if max_degree is None else int(max_degree)
        lr = least_row(model, Mi, tol=mm_tol, atol=atol, poles=poles, sdeg=sdeg, smarg=smarg, good=good,
                       choose=choose)
        if lr is None:
            raise DesignError(f"row {i + 1} of Mr is not achievable without an updating factor, nor with one: no "
                              f"filter that decouples u and d has a fault response proportional to it (every left "
                              f"annihilator of [Gu Gd Gf; 0 0 Mr_{i + 1}; I 0 0] has a zero Mr-entry)")
        index_degrees.append(lr.indices)
        if lr.degree > top:
            raise DesignError(f"row {i + 1} of Mr: its least-order solution has degree {lr.degree} > max_degree = "
                              f"{max_degree} (left minimal indices of [Gu Gd Gf; 0 0 Mr_{i + 1}; I 0 0]: "
                              f"{lr.indices}); pass a larger max_degree")
        Q0 = lr.solution(atol) if lr.dz > 0 else None
        if Q0 is not None and _stable(Q0, margin, model.dt) and _stable(Mi, margin, model.dt):
            rows.append(Q0), ms.append(LTI.static(np.ones((1, 1)), model.dt))
            methods.append("least order"), degs.append(0)
        elif updating and Q0 is not None:
            Qi, mi = _coprime_row(model, Q0, Mi, choose, good, margin, atol)
            sc = _markov_gain(mi) if normalize == "gain" else mi.hinfnorm()[0] * np.sign(_markov_gain(mi))
            rows.append(Qi * (1.0 / sc)), ms.append(mi * (1.0 / sc))
            methods.append("coprime factor"), degs.append(int(mi.n))
        elif updating:
            Qi, mi = lr.pair(choose, atol)
            sc = _markov_gain(mi) if normalize == "gain" else mi.hinfnorm()[0] * np.sign(_markov_gain(mi))
            rows.append(Qi * (1.0 / sc)), ms.append(mi * (1.0 / sc))
            methods.append("updating"), degs.append(int(mi.n))
        else:
            try:
                Qi = stable_solution(lr, choose, good, mm_tol, atol)
            except DesignError as exc:
                why = ("its least-order solution is unstable" if Q0 is not None else
                       "its least-degree solution (degree %d) is improper" % lr.degree)
                raise DesignError(f"row {i + 1} of Mr: {why}, and {exc}") from None
            how = "stable solution"
            low = _lowered_stable(model, [Q0, Qi], Qi, good, choose, atol, mm_tol, smarg)
            if low is not None:
                Qi, how = low, "least stable order"
            if Qi.n > top:
                raise DesignError(f"row {i + 1} of Mr: the stable solution has degree {Qi.n} > max_degree = "
                                  f"{max_degree}: pass a larger max_degree, or updating=True")
            rows.append(Qi), ms.append(LTI.static(np.ones((1, 1)), model.dt))
            methods.append(how), degs.append(0)
        rows[-1] = rows[-1] * scale
    M = blockdiag(ms)
    Q, cancel_note = _cancel_plant_modes(model, vstack(rows) if len(rows) > 1 else rows[0], margin, M @ Mr, mm_tol)
    gen = ResidualGenerator(Q, model, "model_matching")
    check_generator(gen, decouple=("u", "d"), faults=[], smarg=smarg, dec_tol=dec_tol)
    err = _matching_error(model, gen, M @ Mr)
    if not err <= np.sqrt(mm_tol):
        raise DesignError(f"model matching: the returned filter's fault response differs from the reference by "
                          f"{err:.3g} (relative) > sqrt(mm_tol) = {np.sqrt(mm_tol):.3g}: the realisation lost "
                          f"accuracy; pass other poles/sdeg")
    gen.info.update({"row_orders": [int(r.n) for r in rows], "degree": int(max(r.n for r in rows)),
                     "order": int(Q.n), "row_methods": methods, "matching_error": err,
                     "left_minimal_indices": index_degrees, "plant_mode_cancellation": cancel_note,
                     "poles": np.asarray(Q.poles()).tolist()})
    if updating:
        gen.info.update({"M": M, "row_degrees": degs, "M_zeros": [np.asarray(_zeros(m)).tolist() for m in ms]})
    return gen


def _lowered_stable(model: FDIModel, starts, Qs: LTI, good, choose, atol: float, mm_tol: float, smarg):
    """The lowest-order stable row ``X = X1 + Y N`` below the stable solution ``Qs``'s order
    (:func:`..toolkit.least_solve.lowered_stable_rows`) whose internal form agrees with ``Qs``'s on a grid,
    ``max ||(X − Qs) [Gu Gd Gf; I 0 0]|| ≤ mm_tol · max ||Qs [Gu Gd Gf; I 0 0]||``; None when there is none."""
    from ..toolkit.least_solve import lowered_stable_rows

    if not Qs.n:
        return None
    Ge = _internal_form(model)
    for X in lowered_stable_rows(model, starts, Qs.n, good, choose, atol, smarg):
        lam = _grid_points(model, [Qs, X])
        Gv = _values(Ge, lam)
        ref = np.einsum("kij,kjl->kil", _values(Qs, lam), Gv)
        dev = np.einsum("kij,kjl->kil", _values(X, lam), Gv) - ref
        ok = np.all(np.isfinite(dev), axis=(1, 2)) & np.all(np.isfinite(ref), axis=(1, 2))
        if ok.any() and np.max(np.abs(dev[ok])) <= mm_tol * max(float(np.max(np.abs(ref[ok]))), 1e-300):
            return X
    return None


def _internal_form(model: FDIModel) -> LTI:
    """``Ge = [Gu Gd Gf; I 0 0]`` (from ``[u; d; f]`` to ``[y; u]``), on the plant's states."""
    G = model.lti("u", "d", "f")
    low = np.zeros((model.nu, G.m))
    low[:, :model.nu] = np.eye(model.nu)
    return LTI(G.A, G.B, np.vstack([G.C, np.zeros((model.nu, G.n))]), np.vstack([G.D, low]), model.dt)


def _internal_error(model: FDIModel, Q: LTI, MMr: LTI) -> float:
    """Largest over the rows of the grid peak of ``||Q_i Ge − [0 0 (M Mr)_i]||`` relative to the peak of
    ``||(M Mr)_i||`` (:func:`_grid_points` of the model, Q and M Mr): decoupling and matching in one number."""
    lam = _grid_points(model, [MMr, Q])
    T = _values(MMr, lam)
    R = np.einsum("kij,kjl->kil", _values(Q, lam), _values(_internal_form(model), lam))
    R[:, :, R.shape[2] - T.shape[2]:] -= T
    ok = np.all(np.isfinite(R), axis=(1, 2)) & np.all(np.isfinite(T), axis=(1, 2))
    num = np.max(np.linalg.norm(R[ok], axis=2), axis=0, initial=0.0)
    top = np.max(np.linalg.norm(T[ok], axis=2), axis=0, initial=0.0)
    return float(np.max(num / np.maximum(top, 1e-300)))


def _drop_cancelled(sys: LTI, margin: float, tol: float) -> LTI:
    """``sys`` (a reference row of unit peak gain) without the modes whose contribution is at
    rounding level: the modes of a product realisation that a filter cancels only to ~1e-12 (SLICOT's
    rank tolerance ~1e-14 keeps them), which are no poles of the reference — a row must not pay an
    order for them (the least order of :mod:`..toolkit.least_solve` is the order of the reference's
    minimal realisation plus what the plant adds).

    Additive stable/unstable decomposition (Varga's ``gsdec``): an ordered real Schur form puts
    the modes inside the region first, a Sylvester equation ``A11 X − X A22 = −A12`` decouples the
    blocks. The unstable part ``(A22, B2, C2)`` is dropped when the largest singular value of its
    Hankel matrix ``[C2 (A22/ρ)^k] [(A22/ρ)^k B2]`` (ρ = max(1, ||A22||)) is ≤ ``tol``; the stable
    part is truncated to its Hankel singular values above ``tol`` (square-root balance & truncate,
    SLICOT AB09AD: the error is at most twice the sum of the dropped ones).
    """
    n = sys.n
    if not n:
        return sys
    good = (lambda re, im: np.hypot(re, im) < margin) if sys.dt else (lambda re, im: re < margin)
    T, Z, k = ordered_schur(sys.A, good)
    A11, A12, A22 = T[:k, :k], T[:k, k:], T[k:, k:]
    X = sla.solve_sylvester(A11, -A22, -A12) if 0 < k < n else np.zeros((k, n - k))
    Bt, Ct = Z.T @ sys.B, sys.C @ Z
    B1, B2 = Bt[:k] - X @ Bt[k:], Bt[k:]
    C1, C2 = Ct[:, :k], Ct[:, :k] @ X + Ct[:, k:]
    if k < n:
        rho = max(1.0, float(np.linalg.norm(A22, 2)))
        Ap = [np.linalg.matrix_power(A22 / rho, j) for j in range(n - k)]
        H = np.vstack([C2 @ P for P in Ap]) @ np.hstack([P @ B2 for P in Ap])
        if float(np.linalg.norm(H, 2)) <= tol:
            A22, B2, C2 = A22[:0, :0], B2[:0], C2[:, :0]
    if k:
        from slycot.exceptions import SlycotError

        try:
            part = LTI(A11, B1, C1, np.zeros((sys.p, sys.m)), sys.dt).balanced_truncation(tol=tol)[0]
        except SlycotError:
            part = None  # AB09AD refuses a mode too close to the boundary: keep the stable part as it is
        if part is not None and part.n < k:
            A11, B1, C1 = part.A, part.B, part.C
    return LTI(sla.block_diag(A11, A22), np.vstack([B1, B2]), np.hstack([C1, C2]), sys.D, sys.dt)


def _cancel_plant_modes(model: FDIModel, Q: LTI, margin: float, MMr: LTI, mm_tol: float,
                        tol: float = 1e-6) -> tuple[LTI, dict]:
    """``(Q', note)``: Q with its y-input part corrected (least squares, relative size ≤ ``tol``) so that the plant
    modes outside the stability region cancel *exactly* in ``R = Q Ge``, when that does not worsen the match.

    A plant mode with invariant subspace ``V_u`` (``A V_u = V_u A_u``, ordered real Schur form)
    is not a pole of R iff ``Q_y(A_u) C V_u = 0``, i.e. ``Cq Y + Dq_y C V_u = 0`` with
    ``Aq Y − Y A_u = −Bq_y C V_u`` (a Sylvester equation): linear in ``(Bq_y, Dq_y)`` for fixed
    ``(Aq, Cq)``. Every exact match satisfies it (its R = M Mr is stable), but a row from sampled
    equations does so only to ~1e-13, which leaves the unstable plant pole in R with a residue of
    that size. The minimum-norm correction makes the cancellation exact; a correction above
    ``tol`` means the condition does not hold for this Q (then Q is returned unchanged and the
    post-conditions judge it).

    The correction is minimal in the parameters, not in the response: where the mode is weakly observable
    (``||C V_u||`` small) a parameter change of 1e-6 can move ``Q Ge`` by far more than the residue it
    removes. So the match :func:`_internal_error` (decoupling and ``M Mr`` together, relative per row) is
    measured before and after, and the corrected Q is kept only if its error is at most ``mm_tol`` or no
    larger than before — otherwise the given Q (the better match) is returned. ``note`` (``info
    ['plant_mode_cancellation']``) records ``corrected``, ``error_before``/``error_after``, the relative
    ``correction`` and the ``reason``."""
    n, p = model.n, model.ny
    note = {"corrected": False, "error_before": None, "error_after": None, "correction": 0.0}
    if not n or not p:
        return Q, {**note, "reason": "no plant states or outputs"}
    good = (lambda re, im: np.hypot(re, im) < margin) if model.dt else (lambda re, im: re < margin)
    T, Z, k = ordered_schur(model.A, lambda re, im: not good(re, im))
    if k == 0:
        return Q, {**note, "reason": "no plant mode outside the stability region"}
    CV, Au = model.C @ Z[:, :k], T[:k, :k]
    nq, r = Q.n, Q.p

    def condition(By, Dy):
        out = Dy @ CV
        if nq:
            out = out + Q.C @ sla.solve_sylvester(Q.A, -Au, -By @ CV)
        return out.ravel()

    size = nq * p + r * p
    L = np.empty((r * k, size))
    for j in range(size):
        e = np.zeros(size)
        e[j] = 1.0
        L[:, j] = condition(e[:nq * p].reshape(nq, p), e[nq * p:].reshape(r, p))
    x = np.concatenate([Q.B[:, :p].ravel(), Q.D[:, :p].ravel()])
    dx = -np.linalg.lstsq(L, L @ x, rcond=None)[0]
    rel = float(np.linalg.norm(dx) / max(np.linalg.norm(x), 1e-300))
    note["correction"] = rel
    if not rel <= tol:
        return Q, {**note, "reason": f"the correction ({rel:.3g} relative) exceeds {tol:g}: the condition does not "
                                     f"hold for this Q; left to the post-conditions"}
    x = x + dx
    B, D = Q.B.copy(), Q.D.copy()
    B[:, :p], D[:, :p] = x[:nq * p].reshape(nq, p), x[nq * p:].reshape(r, p)
    Qc = LTI(Q.A, B, Q.C, D, Q.dt)
    before, after = _internal_error(model, Q, MMr), _internal_error(model, Qc, MMr)
    note.update({"error_before": before, "error_after": after})
    if after <= mm_tol or after <= before:
        return Qc, {**note, "corrected": True, "reason": "the plant modes outside the region cancel exactly in R"}
    return Q, {**note, "reason": f"the exact cancellation would worsen the match from {before:.3g} to {after:.3g} "
                                 f"(> mm_tol = {mm_tol:g}): Q kept as designed"}


def _stable(sys: LTI, margin: float, dt: float) -> bool:
    """Every pole at or inside the margin (inclusive, as the peer's ``smarg``; :func:`~fmu_fdi.margin.margin_limit`)."""
    if not sys.n:
        return True
    p = sys.poles()
    lim = margin_limit(margin)
    return bool(np.max(np.abs(p)) <= lim if dt else np.max(p.real) <= lim)


def _coprime_row(model: FDIModel, Q0: LTI, Mi: LTI, choose, good, margin: float, atol: float) -> tuple[LTI, LTI]:
    """``[Q_i  R_i] = m_i [Q0  Mr_i]`` stable: a left coprime factorisation of the row ``[Q0 Mr_i]``
    by output injection L moving the eigenvalues outside the region (``Re λ < margin``, ``|λ| <
    margin``), one Schur block at a time (:func:`..toolkit.pencil.assign_poles` on the dual pair):
    ``Ã = A + L C``, ``[Q_i R_i] = (Ã, B + L D, C, D)``, ``m_i = (Ã, L, C, 1)``."""
    from ..toolkit.pencil import assign_poles

    row = LTI(sla.block_diag(Q0.A, Mi.A), sla.block_diag(Q0.B, Mi.B), np.hstack([Q0.C, Mi.C]),
              np.hstack([Q0.D, Mi.D]), model.dt).minreal(atol)
    F, _ = assign_poles(row.A.T, row.C.T, model.dt, lambda bad: choose(bad.size), good)
    Lg = F.T
    At = row.A + Lg @ row.C
    eig = np.linalg.eigvals(At) if row.n else np.zeros(0)
    worst = float(np.max(np.abs(eig) if model.dt else eig.real, initial=-np.inf))
    if worst >= margin:
        what = "largest |pole|" if model.dt else "largest Re(pole)"
        raise DesignError(f"model matching: the updating factor cannot move every pole of the least-order row "
                          f"[Q_i Mr_i] into the stability region ({what} left = {worst:.6g} ≥ smarg = {margin:.6g}: "
                          f"an unobservable unstable mode)")
    full = LTI(At, row.B + Lg @ row.D, row.C, row.D, model.dt)
    q = Q0.m
    return full[:, :q].minreal(atol), LTI(At, Lg, row.C, np.ones((1, 1)), model.dt).minreal(atol)


def _grid_points(model: FDIModel, systems) -> np.ndarray:
    """A grid over the model's and the systems' pole scales, leaving out scales below 1e-8 of the
    largest: those are modes of a non-minimal product realisation cancelled only to rounding
    (an integrator of Gf that a row cancels), whose values near λ = 0 are rounding noise."""
    poles = np.concatenate([np.zeros(0, complex)] + [np.asarray(s.poles(), complex) for s in systems if s.n])
    scale = np.abs(np.log(np.where(poles == 0, 1.0, poles))) / model.dt if model.dt else np.abs(poles)
    keep = scale >= 1e-8 * max(float(np.max(scale, initial=0.0)), 1e-300)
    omega = frequency_grid([model.lti()], num=200, poles=poles[keep])
    lam = np.exp(1j * omega * model.dt) if model.dt else 1j * omega
    # and the points next to a pole (λ = 0 beside an integrator cancelled to rounding evaluates
    # to a finite but meaningless value)
    dist = np.min(np.abs(lam[:, None] - poles[None, :]), axis=1, initial=np.inf) if poles.size else np.inf
    return lam[dist > 1e-6 * np.maximum(1.0, np.abs(lam))]


def _peak(model: FDIModel, sys: LTI) -> float:
    """Grid peak of ``||sys(λ)||`` (finite points only)."""
    V = _values(sys, _grid_points(model, [sys]))
    V = V[np.all(np.isfinite(V), axis=(1, 2))]
    return float(np.max(np.linalg.norm(V, 2, axis=(1, 2)), initial=0.0))


def _matching_error(model: FDIModel, gen: ResidualGenerator, MMr: LTI) -> float:
    """Largest over the rows of the grid peak of ``|Rf_i − (M Mr)_i|`` relative to the peak of
    ``|(M Mr)_i|`` (a grid of its own; row by row, so that a row of small gain is judged too)."""
    lam = _grid_points(model, [MMr, gen.Q])
    T = _values(MMr, lam)
    H = _values(gen.Rf, lam) - T
    ok = np.all(np.isfinite(H), axis=(1, 2))
    num = np.max(np.linalg.norm(H[ok], 2, axis=2), axis=0, initial=0.0)
    top = np.max(np.linalg.norm(T[ok], 2, axis=2), axis=0, initial=0.0)
    return float(np.max(num / np.maximum(top, 1e-300)))


def _markov_gain(m: LTI) -> float:
    """The zpk gain of a SISO system: its first nonzero Markov parameter (D, CB, CAB, ...)."""
    scale = max(m.scale_of(), 1e-300)
    if abs(m.D[0, 0]) > 1e-12 * scale:
        return float(m.D[0, 0])
    v = m.B[:, 0]
    for _ in range(m.n):
        g = float(m.C[0] @ v)
        if abs(g) > 1e-12 * scale ** 2:
            return g
        v = m.A @ v
    raise DesignError("the updating factor m_i is zero")


def _zeros(m: LTI) -> np.ndarray:
    """Zeros of a SISO system ``(A, b, c, d)``: eigenvalues of the pencil ``[A b; c d] − λ[I 0; 0 0]``."""
    if m.n == 0:
        return np.zeros(0)
    n = m.n
    P = np.block([[m.A, m.B], [m.C, m.D]])
    E = sla.block_diag(np.eye(n), np.zeros((1, 1)))
    z = sla.eigvals(P, E)
    return z[np.isfinite(z) & (np.abs(z) < 1e12)]
