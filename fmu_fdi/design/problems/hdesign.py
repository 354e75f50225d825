"""A residual built from a user-given design matrix: ``Q = M·H·N`` (FaultDetectionTools.jl ``HDesign``).

Every proper residual generator that decouples u and d is a combination of the rows of a
proper stable left null-space basis ``N(λ)`` of ``[Gu Gd; I 0]`` (Varga 2017, Procedure EFD,
step 2). Instead of letting the design choose the constant combination, the user gives it:
a full-row-rank ``H`` (``q × k``, ``k = p − rank Gd`` the number of basis rows) forms the
``q`` residuals

    Q(λ) = M(λ) H N(λ),    R(λ) = Q(λ) [Gu Gd Gw Gf; I 0 0 0] = [0 0 Rw Rf],

``N`` the basis of :func:`..toolkit.pencil.pencil_basis` (the same tolerances and poles as the
design), ``M`` the stable left factor that moves only the poles of ``[Q R]`` outside the
stability margin (``glcf``; identity when there are none) and the row scaling to unit peak
fault gain. As the peer, an ``H`` with fewer columns than ``k`` combines the leading rows
(its missing columns are zero); more columns than ``k`` cannot refer to the basis and are
refused, as are a rank-deficient ``H`` and an ``H`` whose rows together miss a fault.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import rank
from ...model import FDIModel


def design_matrix(H, k: int, *, rows: int | None = None, what: str = "HDesign") -> np.ndarray:
    """``H`` as a ``q × k`` float array (zero columns appended when it has fewer than ``k``), or a
    DesignError naming the failed condition: not a finite 2-D matrix, more than ``k`` columns, ``rows``
    given and not its row count, not of full row rank (singular values relative to its norm)."""
    try:
        Hm = np.asarray(H, dtype=float)
    except (TypeError, ValueError):
        raise DesignError(f"{what} must be a real matrix, got {H!r}") from None
    Hm = Hm[None, :] if Hm.ndim == 1 else Hm
    if Hm.ndim != 2 or Hm.shape[0] == 0 or not np.all(np.isfinite(Hm)):
        raise DesignError(f"{what} must be a finite nonempty 2-D matrix, got shape {np.shape(H)}")
    if Hm.shape[1] > k:
        raise DesignError(f"{what} has {Hm.shape[1]} columns but the left null space of [Gu Gd; I 0] has only "
                          f"{k} basis rows (p − rank Gd): its columns must number at most {k}")
    if rows is not None and Hm.shape[0] != rows:
        raise DesignError(f"{what} has {Hm.shape[0]} rows but rdim = {rows} residuals were requested")
    r = rank(Hm)
    if r < Hm.shape[0]:
        s = np.linalg.svd(Hm, compute_uv=False)
        raise DesignError(f"{what} must have full row rank: rank {r} < {Hm.shape[0]} rows (singular values "
                          f"{np.array2string(s, precision=3)})")
    return np.hstack([Hm, np.zeros((Hm.shape[0], k - Hm.shape[1]))])


def basis_rows(model: FDIModel, *, simple: bool, tol, atol, poles, sdeg, smarg):
    """``(N, pb, orders)``: the proper stable left null-space basis of ``[Gu Gd; I 0]`` the design matrix
    multiplies — :func:`..toolkit.pencil.pencil_basis` itself, or with ``simple`` its simple form (each row
    ``N_i`` of McMillan degree ``ν_i``, its left minimal index, ascending; Varga's ``glnull(simple = true)``,
    :func:`..toolkit.pencil.simple_rows`); ``orders`` the rows' degrees (simple) or None."""
    from ...lti import vstack
    from ..toolkit._basis import no_residual_error
    from ..toolkit.pencil import pencil_basis, simple_rows

    pb = pencil_basis(model, rtol=tol, atol=atol, poles=poles, sdeg=sdeg, smarg=smarg)
    k = pb.N.p
    if k == 0:
        raise no_residual_error(model, pb.rank_d)
    if not simple or k == 1:
        return pb.N, pb, ([int(pb.degrees[0])] if simple else None)
    rows = simple_rows(pb, model.dt)
    if len(rows) < k:
        raise DesignError(f"simple = True: only {len(rows)} of the {k} basis rows have a simple form (a minimum "
                          f"dynamic cover of order ν_i; the others need transformations above the conditioning "
                          f"bound); left minimal indices {pb.degrees}")
    return vstack([r[0] for r in rows]), pb, [int(r[1]) for r in rows]


def hdesign_generator(model: FDIModel, H, *, rdim, poles, sdeg, freqs, FDtol, FDGainTol, smarg, dec_tol, tol,
                      atol, place: dict, finish, gains, simple: bool = False,
                      normalize_noise: bool = False) -> ResidualGenerator:
    """``Q = M·H·N`` (module docstring), judged as every null-space design
    (:func:`..toolkit.postconditions.check_generator`, u and d decoupled, every fault visible).

    ``rdim``: 1 (the default of :func:`.nullspace.nullspace_design`, which then means "as many as H has
    rows") or the row count of H. ``H = None``: the whole basis (``H = I``; with ``simple`` the simple
    basis, row i of order ``ν_i``). ``info['HDesign']`` is the (padded) matrix used,
    ``info['left_minimal_indices']`` the degrees of the basis it multiplies, ``info['simple_orders']`` the
    orders of the simple rows (with ``simple``). ``normalize_noise`` (noise to optimise): as the peer's
    ``afdsyn`` with ``HDesign``, the rows' internal form is made stable and their noise response ``Rw``
    normalised by the (quasi-)co-outer factor, ``Q ← Ro⁻¹·M·H·N`` (:func:`..toolkit.approximate.noise_normalizer`,
    ``nonstd``; ``info['noise']`` says how) — the same residual space, the noise weighted flat. ``finish``, ``gains``: the null-space design's last stage
    (stable internal form, rows normalised) and its per-row fault gains (:func:`.nullspace._finish`,
    :func:`.nullspace._pencil_gains`; passed in, as :mod:`.nullspace` calls this module)."""
    from ..toolkit.postconditions import check_generator

    N, pb, orders = basis_rows(model, simple=simple, tol=tol, atol=atol, poles=poles, sdeg=sdeg, smarg=smarg)
    k = N.p
    Hm = np.eye(k) if H is None else design_matrix(H, k, rows=None if rdim in (1, None) else rdim)
    HN = N if H is None else Hm @ N
    if model.faults:
        seen = gains(model, HN, freqs, FDtol)  # per row of H·N, relative gain (cosine) to every fault
        missed = [j for j in range(len(model.faults)) if seen[:, j].max() < FDtol]
        if missed:
            basis_gains = gains(model, N, freqs, FDtol)
            why = "; ".join(
                f"fault '{model.faults[j].name}': largest relative gain of the rows H·N {seen[:, j].max():.2e} "
                f"< FDtol = {FDtol:g} (of the basis rows: {basis_gains[:, j].max():.2e})" for j in missed)
            raise DesignError(f"the residuals formed by {'HDesign' if H is not None else 'the basis'} do not see "
                              f"every required fault: {why}")
    Q = HN.minreal()
    how = None
    if normalize_noise and model.nw:
        from ..toolkit.approximate import noise_normalizer
        from ..toolkit.stable_factor import stable_internal_form

        Q, _ = stable_internal_form(model, Q, **place)  # the co-outer factor needs a stable Rw
        Rw = (Q @ model.augmented())[:, model.group_slices()["w"]].minreal()
        fac, how = noise_normalizer(Rw, **{k: place.get(k) for k in ("smarg", "poles", "sdeg")})
        Q = Q if fac is None else (fac @ Q).minreal()
    info = {"order": int(Q.n), "rdim": int(Hm.shape[0]), "combination": Hm.tolist(), "HDesign": Hm.tolist(),
            "basis": "pencil", "left_minimal_indices": pb.degrees, "pencil": pb.info}
    if orders is not None:
        info["simple_orders"] = orders
    if how is not None:
        info["noise"] = how
    gen = finish(model, Q, SimpleNamespace(rho=1.0), "nullspace", info, pb.degrees, place=place)
    check_generator(gen, decouple=("u", "d"), block=True, freqs=freqs, FDtol=FDtol, FDGainTol=FDGainTol,
                    smarg=smarg, dec_tol=dec_tol)
    return gen
