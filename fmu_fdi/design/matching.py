"""Exact model matching (EMMP): a residual generator whose fault response is a given reference.

Find a proper stable ``Q`` with

    Q(λ) [Gu Gd Gf; I 0 0](λ) = [0 0 Mr(λ)]

(Varga 2017, sec. 5.6, Procedure EMM; FaultDetectionTools.jl ``emmsyn``) — u and d
decoupled and the fault-to-residual map equal to the reference ``Mr``. Q is sought with a
fixed denominator: the poles of Mr (every solution's denominator must hold them, Mr being
``Q Ge``) plus ν further stable poles, ν = 0, 1, ... until the equations — linear in Q's
numerator, sampled on a frequency grid as in :mod:`.sampled` — hold exactly (relative
residual ``≤ mm_tol``). Least squares gives the minimum-norm numerator when several exist.

With ``updating=True`` (Varga 2017, Procedure EMM step 3; ``emmsyn``'s ``info.M``) the
reference may be matched only up to a diagonal updating factor: when the exact solution
``Q0`` of ``Q0 Ge = [0 0 Mr]`` is improper or unstable, the returned filter is
``Q = M Q0``, stable and proper, with

    Q(λ) Ge(λ) = [0  0  M(λ) Mr(λ)],     M = diag(m_1, …, m_r),

each ``m_i`` stable with poles at the ν added poles (``sdeg``/``poles``; numerator free).
Row i is the least ν for which the homogeneous equations
``Q_i Ge − m_i [0 0 Mr_i] = 0`` (linear in the numerators of ``Q_i`` and ``m_i``, sampled
on the grid) have a solution with ``m_i ≠ 0``: the null vector of the stacked equations
(SVD) with the largest ``m_i`` part. ``m_i`` is normalised to unit zpk gain (the first
nonzero Markov parameter, ``normalize='gain'``, as in Varga's Example 5.13) or to unit
H∞ norm (``'infnorm'``, ``emmsyn``'s default).

The approximate problem (AMMP, H∞/H2 optimal) is :mod:`.approximate_matching`.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..errors import DesignError
from ..generator import ResidualGenerator
from ..linalg import single_blas_thread
from ..lti import LTI, blockdiag, frequency_grid, vstack
from ..model import FDIModel
from ._basis import check_poles, pole_chooser
from .postconditions import DEC_TOL, _values, check_generator
from .sampled import _basis_values, cascade


@single_blas_thread
def model_matching(model: FDIModel, Mr, *, poles=None, sdeg: float | None = None, max_degree: int | None = None,
                   mm_tol: float = 1e-9, smarg: float | None = None, dec_tol: float = DEC_TOL,
                   updating: bool = False, normalize: str = "gain") -> ResidualGenerator:
    """Exact model matching: ``Q Ge = [0 0 Mr]`` with a stable proper Q of least added order.

    Parameters
    ----------
    model : FDIModel
    Mr : LTI or python-control system
        Reference fault-to-residual map: (residuals × fault columns), stable.
    poles, sdeg : optional
        Filter poles added to those of Mr (as in :func:`~fmu_fdi.design.nullspace.nullspace_design`).
    max_degree : int, optional
        Largest number of added poles tried (default n + 1).
    mm_tol : float
        Largest relative matching residual on the grid accepted as exact.
    updating : bool
        Allow a diagonal stable updating factor M: ``Q Ge = [0 0 M Mr]`` (``emmsyn``'s
        ``info.M``); needed when the exact solution is improper or unstable.
    normalize : {'gain', 'infnorm'}
        Normalisation of each ``m_i`` with ``updating=True``: unit zpk gain or unit H∞ norm.

    Returns
    -------
    ResidualGenerator
        ``info``: ``degree`` (added poles), ``order``, ``matching_error`` (grid peak of
        ``||Rf − M Mr||`` relative to ``||M Mr||``), ``postconditions``, and with
        ``updating=True`` ``M`` (LTI, diagonal) and ``M_zeros`` (zeros of each ``m_i``).

    Raises
    ------
    DesignError
        Mr has the wrong shape or is unstable, or no Q with up to ``max_degree`` added poles
        matches it (the reference is then not achievable without an updating factor).
    """
    if normalize not in ("gain", "infnorm"):
        raise DesignError(f"normalize must be 'gain' or 'infnorm', got {normalize!r}")
    Mr = Mr if isinstance(Mr, LTI) else LTI.from_control(Mr)
    if Mr.m != model.nf:
        raise DesignError(f"Mr must have {model.nf} inputs (the fault columns {model.fault_names}), got {Mr.m}")
    if Mr.n and abs(Mr.dt - model.dt) > 1e-12:
        raise DesignError(f"Mr has sample time {Mr.dt} but the model has {model.dt}")
    Mr = LTI(Mr.A, Mr.B, Mr.C, Mr.D, model.dt)
    if Mr.n and not Mr.is_stable():
        raise DesignError("Mr must be stable: every residual generator's fault response Q Gf has Q's poles")
    check_poles(poles, model.dt)
    mr_poles = Mr.minreal().poles() if Mr.n else np.zeros(0, complex)
    choose = pole_chooser(model, poles, sdeg)
    Ge = model.augmented()
    q = model.ny + model.nu
    sl = model.group_slices()
    ud = np.r_[np.arange(sl["u"].start, sl["u"].stop), np.arange(sl["d"].start, sl["d"].stop)]
    cols = np.r_[ud, np.arange(sl["f"].start, sl["f"].stop)]
    max_degree = model.n + 1 if max_degree is None else max_degree
    sample = _sampler(model, Ge, Mr, mr_poles, choose, cols)
    if updating:
        return _updating(model, Mr, sample, ud, cols, q, max_degree, mm_tol, smarg, dec_tol, normalize)
    best = np.inf
    for nu in range(max_degree + 1):
        _, A, C, lam, T, Phi, w, E = sample(nu)
        # unknown X (r, q): Q = Φ X; equations Φ_k X G_k[:, cols] = [0 Mr_k] for each residual row
        L = E.reshape(-1, Phi.shape[1] * q)
        L = np.vstack([L.real, L.imag])
        rows, err = [], 0.0
        for i in range(Mr.p):
            tgt = np.concatenate([np.zeros((lam.size, ud.size)), T[:, i, :]], axis=1) * w[:, None]
            b = np.concatenate([tgt.real.ravel(), tgt.imag.ravel()])
            x, *_ = sla.lstsq(L, b, lapack_driver="gelsy")
            err = max(err, float(np.linalg.norm(L @ x - b) / max(np.linalg.norm(b), 1e-300)))
            X = x.reshape(Phi.shape[1], q)
            rows.append(LTI(A, X[:-1], C, X[-1:], model.dt))
        best = min(best, err)
        if err > mm_tol:
            continue
        Q = (vstack(rows) if len(rows) > 1 else rows[0]).minreal()
        gen = ResidualGenerator(Q, model, "model_matching")
        check_generator(gen, decouple=("u", "d"), faults=[], smarg=smarg, dec_tol=dec_tol)
        H = _values(gen.Rf, lam) - T
        gen.info.update({"degree": nu, "order": int(Q.n), "matching_error":
                         float(np.max(np.linalg.norm(H, 2, axis=(1, 2))) / max(np.max(np.linalg.norm(T, 2, axis=(1, 2))), 1e-300)),
                         "poles": np.asarray(Q.poles()).tolist()})
        return gen
    raise DesignError(f"no stable proper Q with up to {max_degree} poles added to those of Mr matches Mr exactly "
                      f"(smallest relative matching residual {best:.3g} > mm_tol = {mm_tol:g}): the reference is not "
                      f"achievable without an updating factor (pass updating=True), or pass a larger max_degree")


def _sampler(model, Ge, Mr, mr_poles, choose, cols):
    """``ν ↦ (extra, A, C, λ, Mr(λ), Φ(λ), w, E)``, cached per ν: the ν added poles, the filter
    denominator's cascade ``(A, C)`` (poles of Mr and the added ones), the grid points where Ge
    and Mr are finite, the reference's values, the basis values, the point weights
    ``1/||Ge(λ)[:, cols]||`` and the coefficients ``E[k, c, i, a] = w_k Φ_k,i Ge_k[a, cols[c]]``
    of the equations ``Φ_k X Ge_k[:, cols]`` in the numerator X."""
    cache = {}

    def sample(nu):
        if nu not in cache:
            extra = np.asarray(choose(nu), complex) if nu else np.zeros(0, complex)
            allp = np.concatenate([mr_poles, extra])
            A, C = cascade(allp)
            K = max(160, 3 * (model.n + allp.size) + 40)
            omega = frequency_grid([model.lti(), Mr], num=K, poles=allp)
            lam = np.exp(1j * omega * model.dt) if model.dt else 1j * omega
            G, T = _values(Ge, lam), _values(Mr, lam)
            ok = np.all(np.isfinite(G), axis=(1, 2)) & np.all(np.isfinite(T), axis=(1, 2))
            G, T, lam = G[ok], T[ok], lam[ok]
            Phi = _basis_values(A, C, lam)
            w = 1.0 / np.maximum(np.linalg.norm(G[:, :, cols], 2, axis=(1, 2)), 1e-300)  # scale each point
            E = np.einsum("ki,kac->kcia", Phi * w[:, None], G[:, :, cols])
            cache[nu] = (extra, A, C, lam, T, Phi, w, E)
        return cache[nu]

    return sample


def _updating(model, Mr, sample, ud, cols, q, max_degree, mm_tol, smarg, dec_tol, normalize):
    """Rows ``Q_i`` and factors ``m_i`` with ``Q_i Ge = [0 0 m_i Mr_i]`` of least added degree ν."""
    rows, ms, degs = [], [], []
    factor = {}  # ν ↦ the cascade of the ν added poles (m_i's denominator) and its basis values
    for i in range(Mr.p):
        found, low = None, np.inf
        for nu in range(max_degree + 1):
            extra, A, C, lam, T, Phi, w, E = sample(nu)
            if nu not in factor:
                Am, Cm = cascade(extra)
                factor[nu] = (Am, Cm, _basis_values(Am, Cm, lam))
            Am, Cm, Phm = factor[nu]
            # Φ_k X G_k[:, cols] − φm_k x_m [0 Mr_i,k] = 0 for the unknowns (X, x_m)
            Lq = E.reshape(lam.size, cols.size, -1)
            tgt = np.concatenate([np.zeros((lam.size, ud.size)), T[:, i, :]], axis=1) * w[:, None]
            Lm = -np.einsum("kj,kc->kcj", Phm, tgt)
            L = np.concatenate([Lq, Lm], axis=2).reshape(lam.size * cols.size, -1)
            L = np.vstack([L.real, L.imag])
            cn = np.linalg.norm(L, axis=0)
            cn[cn == 0] = 1.0
            _, sv, Vt = np.linalg.svd(L / cn, full_matrices=True)
            sv = np.concatenate([sv, np.zeros(Vt.shape[0] - sv.size)])
            Z = (Vt[sv <= mm_tol * sv[0]].T) / cn[:, None]  # null vectors (column scaling undone)
            nq = Phi.shape[1] * q
            if Z.shape[1]:
                # the null vector with the largest m_i part (Q_i Ge = 0 with m_i = 0 is no solution)
                Zn = Z / np.linalg.norm(Z, axis=0)
                _, sm, Wt = np.linalg.svd(Zn[nq:], full_matrices=False)
                if sm.size and sm[0] > 1e-6:
                    x = Zn @ Wt[0]
                    found = (nu, A, C, Am, Cm, x[:nq].reshape(Phi.shape[1], q), x[nq:])
                    break
            low = min(low, float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0)
        if found is None:
            raise DesignError(f"residual {i + 1}: no stable proper Q_i and m_i ≠ 0 with up to {max_degree} added poles "
                              f"give Q_i Ge = [0 0 m_i Mr_i] (smallest relative residual {low:.3g} > mm_tol = "
                              f"{mm_tol:g}): the reference row is not achievable (pass a larger max_degree)")
        nu, A, C, Am, Cm, X, xm = found
        Qi = LTI(A, X[:-1], C, X[-1:], model.dt)
        mi = LTI(Am, xm[:-1, None], Cm, xm[-1:, None], model.dt)
        sc = _markov_gain(mi) if normalize == "gain" else mi.hinfnorm()[0] * np.sign(_markov_gain(mi))
        rows.append(Qi * (1.0 / sc))
        ms.append(mi * (1.0 / sc))
        degs.append(nu)
    Q = (vstack(rows) if len(rows) > 1 else rows[0]).minreal()
    M = blockdiag(ms)
    gen = ResidualGenerator(Q, model, "model_matching")
    check_generator(gen, decouple=("u", "d"), faults=[], smarg=smarg, dec_tol=dec_tol)
    omega = frequency_grid([model.lti(), Mr], num=200)
    lam = np.exp(1j * omega * model.dt) if model.dt else 1j * omega
    MMr = _values(M @ Mr, lam)
    H = _values(gen.Rf, lam) - MMr
    ok = np.all(np.isfinite(H), axis=(1, 2))
    gen.info.update({"degree": int(max(degs)), "row_degrees": degs, "order": int(Q.n), "M": M,
                     "M_zeros": [np.asarray(_zeros(m)).tolist() for m in ms],
                     "matching_error": float(np.max(np.linalg.norm(H[ok], 2, axis=(1, 2)))
                                             / max(np.max(np.linalg.norm(MMr[ok], 2, axis=(1, 2))), 1e-300)),
                     "poles": np.asarray(Q.poles()).tolist()})
    return gen


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
