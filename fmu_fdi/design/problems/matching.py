"""Exact model matching (EMMP): a residual generator whose fault response is a given reference.

Find a proper stable ``Q`` with

    Q(λ) [Gu Gd Gf; I 0 0](λ) = [0 0 Mr(λ)]

(Varga 2017, sec. 5.6, Procedure EMM; FaultDetectionTools.jl ``emmsyn``) — u and d
decoupled and the fault-to-residual map equal to the reference ``Mr``.

**Least order, row by row** (``emmsyn``'s default ``minimal = true``: ``glsol(…; mindeg =
true)`` then a coprime factor per row). Each row ``Q_i`` of the solution is designed on its
own, so its McMillan degree — the degree δ of the least common denominator of a row — is
the least of any row solving ``Q_i Ge = [0 0 Mr_i]``. A row of degree ≤ δ is
``Q_i = n(λ)/d(λ)`` with a polynomial row n and polynomial d of degree ≤ δ, and the matching
equation ``n Ge = d [0 0 Mr_i]`` is *linear and homogeneous* in the pair ``(n, d)`` — the
denominator is an unknown, not a guess (a reference's poles need not be the filter's:
``Mr = Gf`` is matched by the static ``Q = [I 0]``). Both are written over a reference
denominator e of degree δ with stable, well-separated roots,
``Q̃_i = n/e = C (λI − A)^{-1} B + D`` and ``m_i = d/e`` (same ``(A, C)``, :func:`cascade`),
so that the equation ``Q̃_i(λ_k) Ge(λ_k) − m_i(λ_k) [0 0 Mr_i(λ_k)] = 0`` at K grid points
(K far above the degrees involved, so a rational identity holding there holds everywhere)
is a linear system in ``(B, D, b_m, d_m)``. Its null space, read from an SVD with
the relative threshold ``mm_tol``, is non-trivial with ``m_i ≠ 0`` first at the least
degree δ; then ``Q_i = m_i^{-1} Q̃_i`` (biproper ``m_i``, ``d_m ≠ 0``) has the realisation

    Q_i = (A − b_m C / d_m,  B − b_m D / d_m,  C / d_m,  D / d_m)      (order δ),

whose poles are the zeros of ``m_i``. When this least-order row is unstable or improper:

- ``updating=False``: rows with a *fixed* stable denominator (the stable poles of ``Mr_i``
  plus ν chosen poles, ν = 0, 1, …; the numerator from the same sampled equations, now
  inhomogeneous) — a stable Q of higher order if one exists;
- ``updating=True`` (Procedure EMM step 3; ``emmsyn``'s ``info.M``): the reference is matched
  up to a diagonal updating factor, ``Q Ge = [0 0 M Mr]``. For an unstable but proper least
  row, ``[Q_i  Mr_i] = m_i^{-1} [Q̃_i  R̃_i]`` is a stable left coprime factorisation of the
  whole row (output injection moving only the poles outside the stability region, as
  ``glcf(…; mindeg = true)``; :func:`..toolkit.pencil.assign_poles`), so that both the filter and its
  fault response ``m_i Mr_i`` are stable; for an improper one, the least ν for which
  ``Q_i Ge = m_i [0 0 Mr_i]`` has a solution with both ``Q_i`` and ``m_i`` over ν chosen
  stable poles. ``m_i`` is normalised to unit zpk gain (the first nonzero Markov parameter,
  ``normalize='gain'``, as in Varga's Example 5.13) or to unit H∞ norm (``'infnorm'``).

Numerics. Each reference row is solved at unit peak gain and scaled back (a row of gain
1e-8 beside rows of gain 1 keeps its own accuracy); unstable or marginal modes of its
realisation with a Hankel size at rounding level (plant modes a product ``Q Ge`` cancels only
to ~1e-12) are dropped (:func:`_drop_cancelled`); the plant modes outside the stability region
are made to cancel exactly in ``R = Q Ge`` by a minimum-norm correction of Q's y-input part
(:func:`_cancel_plant_modes`). Every returned row is verified on an independent grid: the
relative matching error of each row must not exceed ``sqrt(mm_tol)`` and the post-conditions
(:mod:`..toolkit.postconditions`) must hold. ``atol`` is the absolute rank tolerance of the minimal
realisations and of the properness decision.

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
        Poles given to the filter where they are free: the reference denominators of the
        sampled equations, the fixed-denominator rows, and the poles moved by the updating
        factor (as in :func:`~fmu_fdi.design.problems.nullspace.nullspace_design`).
    max_degree : int, optional
        Largest row degree tried (default ``n + order(Mr_i) + 1``); for the fixed-denominator
        rows, the largest number of poles added to those of ``Mr_i``.
    mm_tol : float
        Relative singular-value threshold of the sampled matching equations (the rank
        decision); a returned row's relative matching error must be ≤ ``sqrt(mm_tol)``.
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
        and of each row, and ``|d_m| ≤ atol`` makes a least-order row improper.

    Returns
    -------
    ResidualGenerator
        ``info``: ``row_orders`` (McMillan degree of each row), ``degree`` (their largest),
        ``order``, ``row_methods`` ('least order', 'fixed denominator', 'coprime factor',
        'updating'), ``matching_error`` (grid peak of ``||Rf − M Mr||`` relative to
        ``||M Mr||``), ``postconditions``, ``poles``; with ``updating=True`` ``M`` (LTI,
        diagonal), ``row_degrees`` (order of each ``m_i``) and ``M_zeros``.

    Raises
    ------
    DesignError
        Mr has the wrong shape, a zero row, or is unstable (without ``updating``), or no
        stable proper row of degree ≤ ``max_degree`` matches a row of it.
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
    eq = _Equations(model, choose)
    rows, ms, methods, degs = [], [], [], []
    for i in range(Mr.p):
        # each row is solved at unit peak gain (a row of gain 1e-8 next to rows of gain 1 would
        # otherwise lose its dynamics to the others' rank tolerance) and scaled back
        scale = _peak(model, Mr[i, :])
        if not scale > 0:
            raise DesignError(f"row {i + 1} of Mr is zero: the only match is the zero filter, which detects no fault")
        Mi = _drop_cancelled(_minimal(Mr[i, :] * (1.0 / scale), atol), margin, max(atol, CANCEL_TOL))
        if not updating and not _stable(Mi, margin, model.dt):
            bad = Mi.poles()
            worst, what = (float(np.max(np.abs(bad))), "largest |pole|") if model.dt else \
                (float(np.max(bad.real)), "largest Re(pole)")
            raise DesignError(f"row {i + 1} of Mr is not stable ({what} = {worst:.6g}, stability margin "
                              f"{margin:.3g}): the fault response Rf = Mr would be; pass updating=True (the "
                              f"updating factor M makes M Mr stable) or a stable reference")
        top = model.n + Mi.n + 1 if max_degree is None else int(max_degree)
        Q0, low = _least_order_row(eq, Mi, top, mm_tol, atol)
        if Q0 is not None and _stable(Q0, margin, model.dt) and _stable(Mi, margin, model.dt):
            rows.append(Q0), ms.append(LTI.static(np.ones((1, 1)), model.dt))
            methods.append("least order"), degs.append(0)
        elif updating and Q0 is not None:
            Qi, mi = _coprime_row(model, Q0, Mi, choose, margin, atol)
            sc = _markov_gain(mi) if normalize == "gain" else mi.hinfnorm()[0] * np.sign(_markov_gain(mi))
            rows.append(Qi * (1.0 / sc)), ms.append(mi * (1.0 / sc))
            methods.append("coprime factor"), degs.append(int(mi.n))
        elif updating:
            Qi, mi, nu = _updating_row(eq, Mi, top, mm_tol, i, low)
            sc = _markov_gain(mi) if normalize == "gain" else mi.hinfnorm()[0] * np.sign(_markov_gain(mi))
            rows.append(_minimal(Qi * (1.0 / sc), atol)), ms.append(mi * (1.0 / sc))
            methods.append("updating"), degs.append(nu)
        else:
            why = ("its least-order solution is unstable" if Q0 is not None else
                   "it has no proper solution of degree ≤ %d" % top)
            rows.append(_fixed_row(eq, Mi, top, mm_tol, margin, atol, i, why, low))
            ms.append(LTI.static(np.ones((1, 1)), model.dt))
            methods.append("fixed denominator"), degs.append(0)
        rows[-1] = rows[-1] * scale
    Q = _cancel_plant_modes(model, vstack(rows) if len(rows) > 1 else rows[0], margin)
    M = blockdiag(ms)
    gen = ResidualGenerator(Q, model, "model_matching")
    check_generator(gen, decouple=("u", "d"), faults=[], smarg=smarg, dec_tol=dec_tol)
    err = _matching_error(model, gen, M @ Mr)
    if not err <= np.sqrt(mm_tol):
        raise DesignError(f"model matching: the returned filter's fault response differs from the reference by "
                          f"{err:.3g} (relative) > sqrt(mm_tol) = {np.sqrt(mm_tol):.3g}: the realisation lost "
                          f"accuracy; pass other poles/sdeg")
    gen.info.update({"row_orders": [int(r.n) for r in rows], "degree": int(max(r.n for r in rows)),
                     "order": int(Q.n), "row_methods": methods, "matching_error": err,
                     "poles": np.asarray(Q.poles()).tolist()})
    if updating:
        gen.info.update({"M": M, "row_degrees": degs, "M_zeros": [np.asarray(_zeros(m)).tolist() for m in ms]})
    return gen


def _minimal(sys: LTI, atol: float) -> LTI:
    """Minimal realisation with the absolute rank tolerance ``atol`` (SLICOT's default when 0)."""
    return sys.minreal(tol=atol if atol > 0 else None) if sys.n else sys


#: Hankel size (on a reference row of unit peak gain) below which an unstable or marginal mode of
#: the reference's realisation is a plant mode that the product Q·Ge cancels only to rounding
#: (a residue ~1e-12 that SLICOT's rank tolerance ~1e-14 keeps), not a pole of the reference
CANCEL_TOL = 1e-9


def _drop_cancelled(sys: LTI, margin: float, tol: float) -> LTI:
    """``sys`` without the modes outside the stability region whose contribution is negligible.

    Additive stable/unstable decomposition (Varga's ``gsdec``): an ordered real Schur form puts
    the modes inside the region first, a Sylvester equation ``A11 X − X A22 = −A12`` decouples the
    blocks, and the unstable part ``(A22, B2, C2)`` is dropped when the largest singular value of
    its Hankel matrix ``[C2 (A22/ρ)^k] [(A22/ρ)^k B2]`` (ρ = max(1, ||A22||)) is ≤ ``tol``.
    """
    n = sys.n
    if not n or _stable(sys, margin, sys.dt):
        return sys
    good = (lambda re, im: np.hypot(re, im) < margin) if sys.dt else (lambda re, im: re < margin)
    T, Z, k = ordered_schur(sys.A, good)
    if k == n:
        return sys
    A11, A12, A22 = T[:k, :k], T[:k, k:], T[k:, k:]
    X = sla.solve_sylvester(A11, -A22, -A12) if k else np.zeros((0, n - k))
    Bt, Ct = Z.T @ sys.B, sys.C @ Z
    B1, B2 = Bt[:k] - X @ Bt[k:], Bt[k:]
    C1, C2 = Ct[:, :k], Ct[:, :k] @ X + Ct[:, k:]
    rho = max(1.0, float(np.linalg.norm(A22, 2)))
    Ap = [np.linalg.matrix_power(A22 / rho, j) for j in range(n - k)]
    H = np.vstack([C2 @ P for P in Ap]) @ np.hstack([P @ B2 for P in Ap])
    if float(np.linalg.norm(H, 2)) > tol:
        return sys
    return LTI(A11, B1, C1, sys.D, sys.dt)


def _cancel_plant_modes(model: FDIModel, Q: LTI, margin: float, tol: float = 1e-6) -> LTI:
    """Q with its y-input part corrected (least squares, relative size ≤ ``tol``) so that the plant
    modes outside the stability region cancel *exactly* in ``R = Q Ge``.

    A plant mode with invariant subspace ``V_u`` (``A V_u = V_u A_u``, ordered real Schur form)
    is not a pole of R iff ``Q_y(A_u) C V_u = 0``, i.e. ``Cq Y + Dq_y C V_u = 0`` with
    ``Aq Y − Y A_u = −Bq_y C V_u`` (a Sylvester equation): linear in ``(Bq_y, Dq_y)`` for fixed
    ``(Aq, Cq)``. Every exact match satisfies it (its R = M Mr is stable), but a row from sampled
    equations does so only to ~1e-13, which leaves the unstable plant pole in R with a residue of
    that size. The minimum-norm correction makes the cancellation exact; a correction above
    ``tol`` means the condition does not hold for this Q (then Q is returned unchanged and the
    post-conditions judge it).
    """
    n, p = model.n, model.ny
    if not n or not p:
        return Q
    good = (lambda re, im: np.hypot(re, im) < margin) if model.dt else (lambda re, im: re < margin)
    T, Z, k = ordered_schur(model.A, lambda re, im: not good(re, im))
    if k == 0:
        return Q
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
    if not np.linalg.norm(dx) <= tol * max(np.linalg.norm(x), 1e-300):
        return Q
    x = x + dx
    B, D = Q.B.copy(), Q.D.copy()
    B[:, :p], D[:, :p] = x[:nq * p].reshape(nq, p), x[nq * p:].reshape(r, p)
    return LTI(Q.A, B, Q.C, D, Q.dt)


def _stable(sys: LTI, margin: float, dt: float) -> bool:
    if not sys.n:
        return True
    p = sys.poles()
    return bool(np.max(np.abs(p)) < margin if dt else np.max(p.real) < margin)


class _Equations:
    """The sampled matching equations of one model: grid, values of ``Ge`` (u, d, f columns), the
    per-point weights ``1/||Ge(λ_k)||`` and the basis values of a denominator, cached per pole set."""

    def __init__(self, model: FDIModel, choose):
        self.model, self.choose = model, choose
        sl = model.group_slices()
        self.ud = np.r_[np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)]
        self.cols = np.r_[self.ud, np.arange(sl["f"].start, sl["f"].stop)]
        self.Ge = model.augmented()
        self.q = model.ny + model.nu

    def sample(self, Mi: LTI, den: np.ndarray):
        """``(A, C, λ, Mr_i(λ) padded with zeros for u, d, w_k, Φ(λ), E)`` for the denominator roots
        ``den``: ``E[k, c, j, a] = w_k Φ_k,j Ge_k[a, cols[c]]`` are the coefficients of ``Q̃ Ge``."""
        model = self.model
        A, C = cascade(den)
        K = max(160, 3 * (model.n + Mi.n + den.size) + 40)
        omega = frequency_grid([model.lti(), Mi], num=K, poles=den)
        lam = np.exp(1j * omega * model.dt) if model.dt else 1j * omega
        G, T = _values(self.Ge, lam)[:, :, self.cols], _values(Mi, lam)[:, 0, :]
        ok = np.all(np.isfinite(G), axis=(1, 2)) & np.all(np.isfinite(T), axis=1)
        G, T, lam = G[ok], T[ok], lam[ok]
        if lam.size < 2 * (model.n + Mi.n + den.size) + 4:
            raise DesignError(f"model matching: only {lam.size} grid points where the model and Mr are finite")
        w = 1.0 / np.maximum(np.linalg.norm(G, 2, axis=(1, 2)), 1e-300)
        tgt = np.concatenate([np.zeros((lam.size, self.ud.size)), T], axis=1) * w[:, None]
        Phi = _basis_values(A, C, lam)
        E = np.einsum("kj,kac->kcja", Phi * w[:, None], G)
        return A, C, lam, tgt, Phi, E


def _null(L: np.ndarray, tol: float) -> tuple[np.ndarray, float]:
    """Null vectors of the complex equations ``L x = 0`` in real unknowns (columns scaled to unit
    norm for the rank decision, the scaling undone): ``(Z, σ_min/σ_max)``."""
    L = np.vstack([L.real, L.imag])
    cn = np.linalg.norm(L, axis=0)
    cn[cn == 0] = 1.0
    # thin SVD of the tall system (only V is needed; a full U would be K·cols squared)
    _, sv, Vt = np.linalg.svd(L / cn, full_matrices=L.shape[0] < L.shape[1])
    sv = np.concatenate([sv, np.zeros(Vt.shape[0] - sv.size)])
    Z = Vt[sv <= tol * sv[0]].T / cn[:, None] if sv[0] > 0 else Vt.T / cn[:, None]
    return Z, float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0


def _least_order_row(eq: _Equations, Mi: LTI, top: int, mm_tol: float, atol: float):
    """The least-degree row ``Q_i = n/d`` with ``Q_i Ge = [0 0 Mr_i]``: ``(Q_i, low)``, ``Q_i`` None when
    no proper one of degree ≤ ``top`` exists (``low``: smallest relative singular value seen)."""
    model, low = eq.model, np.inf
    for delta in range(top + 1):
        den = np.asarray(eq.choose(delta), complex) if delta else np.zeros(0, complex)
        A, C, lam, tgt, Phi, E = eq.sample(Mi, den)
        nb = Phi.shape[1]
        Lm = -np.einsum("kj,kc->kcj", Phi, tgt)
        L = np.concatenate([E.reshape(lam.size, eq.cols.size, -1), Lm], axis=2).reshape(lam.size * eq.cols.size, -1)
        Z, s = _null(L, mm_tol)
        low = min(low, s)
        nq = nb * eq.q
        if not Z.shape[1]:
            continue
        Zn = Z / np.linalg.norm(Z, axis=0)
        if np.max(np.linalg.norm(Zn[nq:], axis=0), initial=0.0) <= 1e-6:
            continue  # only annihilators of the whole Ge (m_i = 0): no match at this degree
        # the null vector with the largest feedthrough d_m of m_i (a biproper m_i: a proper Q_i)
        g = Zn[-1]
        x = Zn @ g / max(np.linalg.norm(g), 1e-300)
        X, xm = x[:nq].reshape(nb, eq.q), x[nq:]
        dm = xm[-1]
        if abs(dm) <= max(atol, 1e-8 * np.linalg.norm(xm)):
            return None, low  # the least-degree solution is improper
        bm = xm[:-1, None]
        Q0 = LTI(A - bm @ C / dm, X[:-1] - bm @ X[-1:] / dm, C / dm, X[-1:] / dm, model.dt)
        return _minimal(Q0, atol), low
    return None, low


def _fixed_row(eq: _Equations, Mi: LTI, top: int, mm_tol: float, margin: float, atol: float, i: int, why: str,
               low: float) -> LTI:
    """A stable row with the fixed denominator: the stable poles of ``Mr_i`` and ν chosen ones."""
    model = eq.model
    mp = Mi.poles() if Mi.n else np.zeros(0, complex)
    mp = mp[np.abs(mp) < margin] if model.dt else mp[mp.real < margin]
    best = np.inf
    for nu in range(top + 1):
        den = np.concatenate([mp, np.asarray(eq.choose(nu), complex) if nu else np.zeros(0, complex)])
        A, C, lam, tgt, Phi, E = eq.sample(Mi, den)
        L = E.reshape(lam.size * eq.cols.size, -1)
        L = np.vstack([L.real, L.imag])
        b = np.concatenate([tgt.real.ravel(), tgt.imag.ravel()])
        x, *_ = sla.lstsq(L, b, lapack_driver="gelsy")
        err = float(np.linalg.norm(L @ x - b) / max(np.linalg.norm(b), 1e-300))
        best = min(best, err)
        if err <= mm_tol:
            X = x.reshape(Phi.shape[1], eq.q)
            return _minimal(LTI(A, X[:-1], C, X[-1:], model.dt), atol)
    raise DesignError(f"row {i + 1} of Mr: {why}, and no stable proper row with up to {top} poles added to the "
                      f"stable poles of Mr_{i + 1} matches it (smallest relative matching residual {best:.3g} > "
                      f"mm_tol = {mm_tol:g}): the reference is not achievable without an updating factor (pass "
                      f"updating=True), or pass a larger max_degree")


def _coprime_row(model: FDIModel, Q0: LTI, Mi: LTI, choose, margin: float, atol: float) -> tuple[LTI, LTI]:
    """``[Q_i  R_i] = m_i [Q0  Mr_i]`` stable: a left coprime factorisation of the row ``[Q0 Mr_i]``
    by output injection L moving the eigenvalues outside the region (``Re λ < margin``, ``|λ| <
    margin``), one Schur block at a time (:func:`..toolkit.pencil.assign_poles` on the dual pair):
    ``Ã = A + L C``, ``[Q_i R_i] = (Ã, B + L D, C, D)``, ``m_i = (Ã, L, C, 1)``."""
    from ..toolkit.pencil import assign_poles

    row = _minimal(LTI(sla.block_diag(Q0.A, Mi.A), sla.block_diag(Q0.B, Mi.B), np.hstack([Q0.C, Mi.C]),
                       np.hstack([Q0.D, Mi.D]), model.dt), atol)
    if model.dt:
        good = lambda re, im: np.hypot(re, im) < margin  # noqa: E731
    else:
        good = lambda re, im: re < margin  # noqa: E731
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
    return _minimal(full[:, :q], atol), _minimal(LTI(At, Lg, row.C, np.ones((1, 1)), model.dt), atol)


def _updating_row(eq: _Equations, Mi: LTI, top: int, mm_tol: float, i: int, low0: float):
    """``(Q_i, m_i, ν)``: the least ν with ``Q_i Ge = m_i [0 0 Mr_i]``, both over ν chosen stable poles."""
    model, low = eq.model, low0
    for nu in range(top + 1):
        den = np.asarray(eq.choose(nu), complex) if nu else np.zeros(0, complex)
        A, C, lam, tgt, Phi, E = eq.sample(Mi, den)
        nb, nq = Phi.shape[1], Phi.shape[1] * eq.q
        Lm = -np.einsum("kj,kc->kcj", Phi, tgt)
        L = np.concatenate([E.reshape(lam.size, eq.cols.size, -1), Lm], axis=2).reshape(lam.size * eq.cols.size, -1)
        Z, s = _null(L, mm_tol)
        low = min(low, s)
        if Z.shape[1]:
            Zn = Z / np.linalg.norm(Z, axis=0)
            _, sm, Wt = np.linalg.svd(Zn[nq:], full_matrices=False)
            if sm.size and sm[0] > 1e-6:  # the null vector with the largest m_i part (m_i = 0 is no solution)
                x = Zn @ Wt[0]
                X, xm = x[:nq].reshape(nb, eq.q), x[nq:]
                return (LTI(A, X[:-1], C, X[-1:], model.dt), LTI(A, xm[:-1, None], C, xm[-1:, None], model.dt), nu)
    raise DesignError(f"residual {i + 1}: no stable proper Q_i and m_i ≠ 0 with up to {top} poles give Q_i Ge = "
                      f"[0 0 m_i Mr_i] (smallest relative residual {low:.3g} > mm_tol = {mm_tol:g}): the reference "
                      f"row is not achievable (pass a larger max_degree)")


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


def cascade(poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(A_m, C_m)`` holding the poles exactly: real first-order sections (real poles) and
    rotation blocks ``[a b; −b a]`` (pairs). Distinct poles: modal form, output the sum of
    the sections' first states (observable as the poles differ). Repeated poles: a cascade,
    each section driven by the previous section's first state, output the last section's
    (observable when no section's zero cancels a later pole)."""
    poles = np.asarray(poles, complex)
    units, used = [], np.zeros(poles.size, bool)
    for i, z in enumerate(poles):
        if used[i]:
            continue
        used[i] = True
        if abs(z.imag) > 1e-12 * max(1.0, abs(z)):
            j = next((k for k in range(poles.size) if not used[k] and abs(poles[k] - np.conj(z)) <= 1e-9 * max(1.0, abs(z))), None)
            if j is None:
                raise DesignError(f"pole {z} has no conjugate: filter poles must be closed under conjugation")
            used[j] = True
            units.append(np.array([[z.real, abs(z.imag)], [-abs(z.imag), z.real]]))
        else:
            units.append(np.array([[z.real]]))
    nu = sum(u.shape[0] for u in units)
    A = np.zeros((nu, nu))
    # distinct poles: a modal (partial-fraction) form, output the sum of the sections — its
    # basis functions 1/(λ - p_i) are far better conditioned than the cascade's products
    eig = np.array([complex(u[0, 0], u[0, 1] if u.shape[0] == 2 else 0.0) for u in units])
    gaps = np.abs(eig[:, None] - eig[None, :])
    np.fill_diagonal(gaps, np.inf)
    modal = eig.size <= 1 or np.min(gaps) > 1e-6 * max(1.0, float(np.max(np.abs(eig))))
    k, prev = 0, None
    C = np.zeros((1, nu))
    for u in units:
        d = u.shape[0]
        A[k:k + d, k:k + d] = u
        if modal:
            C[0, k] = 1.0
        elif prev is not None:
            A[k, prev] = 1.0  # input of this section = output (first state) of the previous one
        prev = k
        k += d
    if nu and not modal:
        C[0, prev] = 1.0
    return A, C


def _basis_values(A: np.ndarray, C: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """``[C (λI − A)^{-1}, 1]`` at every point: (K, ν + 1)."""
    nu = A.shape[0]
    out = np.ones((lam.size, nu + 1), complex)
    if nu:
        eye = np.eye(nu)
        for k, l in enumerate(lam):
            out[k, :nu] = sla.solve((l * eye - A).T, C.ravel().astype(complex))
    return out
