"""Exact model matching (EMMP): a residual generator whose fault response is a given reference.

Find a proper stable ``Q`` with

    Q(λ) [Gu Gd Gf; I 0 0](λ) = [0 0 Mr(λ)]

(Varga 2017, sec. 5.6, Procedure EMM; FaultDetectionTools.jl ``emmsyn``) — u and d
decoupled and the fault-to-residual map equal to the reference ``Mr``. Q is sought with a
fixed denominator: the poles of Mr (every solution's denominator must hold them, Mr being
``Q Ge``) plus ν further stable poles, ν = 0, 1, ... until the equations — linear in Q's
numerator, sampled on a frequency grid as in :mod:`.sampled` — hold exactly (relative
residual ``≤ mm_tol``). Least squares gives the minimum-norm numerator when several exist.

Not covered (see the issue-13 report): the updating factor M of ``emmsyn`` (a stable
diagonal factor that makes an improper/unstable exact solution ``Q = M Q0`` admissible),
and the approximate problem (AMMP, H∞/H2 optimal).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..errors import DesignError
from ..generator import ResidualGenerator
from ..linalg import single_blas_thread
from ..lti import LTI, frequency_grid, vstack
from ..model import FDIModel
from ._basis import check_poles, pole_chooser
from .postconditions import DEC_TOL, _values, check_generator
from .sampled import _basis_values, cascade


@single_blas_thread
def model_matching(model: FDIModel, Mr, *, poles=None, sdeg: float | None = None, max_degree: int | None = None,
                   mm_tol: float = 1e-9, smarg: float | None = None, dec_tol: float = DEC_TOL) -> ResidualGenerator:
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

    Returns
    -------
    ResidualGenerator
        ``info``: ``degree`` (added poles), ``order``, ``matching_error`` (grid peak of
        ``||Rf − Mr||`` relative to ``||Mr||``) and ``postconditions``.

    Raises
    ------
    DesignError
        Mr has the wrong shape or is unstable, or no Q with up to ``max_degree`` added poles
        matches it (the reference is then not achievable without an updating factor).
    """
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
    best = np.inf
    for nu in range(max_degree + 1):
        extra = np.asarray(choose(nu), complex) if nu else np.zeros(0, complex)
        allp = np.concatenate([mr_poles, extra])
        A, C = cascade(allp)
        K = max(160, 3 * (model.n + allp.size) + 40)
        omega = frequency_grid([model.lti()] + ([Mr] if Mr.n else []), num=K, poles=allp)
        lam = np.exp(1j * omega * model.dt) if model.dt else 1j * omega
        G = _values(Ge, lam)
        T = _values(Mr, lam)
        ok = np.all(np.isfinite(G), axis=(1, 2)) & np.all(np.isfinite(T), axis=(1, 2))
        G, T, lam = G[ok], T[ok], lam[ok]
        Phi = _basis_values(A, C, lam)
        w = 1.0 / np.maximum(np.linalg.norm(G[:, :, cols], 2, axis=(1, 2)), 1e-300)  # scale each point
        # unknown X (r, q): Q = Φ X; equations Φ_k X G_k[:, cols] = [0 Mr_k] for each residual row
        L = np.einsum("ki,kac->kcia", Phi * w[:, None], G[:, :, cols]).reshape(-1, Phi.shape[1] * q)
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
                      f"achievable without an updating factor (not implemented), or pass a larger max_degree")
