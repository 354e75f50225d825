"""Residual generators in the frequency-domain factorised form (Frank, eqs. 10-11).

Every residual generator of the output-equation form ``r = Q(p) [y − Gu(p) u]`` (eq. 10)
can be written, with a left coprime factorisation ``Gu = M̂⁻¹ N̂`` over RH∞ and
``Q = R M̂``, as

    r = R(p) [M̂(p) y − N̂(p) u]                                   (Frank, eq. 11)

with a free stable post-filter ``R ∈ RH∞`` (the parameterisation of all residual
generators; Ding & Frank 1990). ``M̂ y − N̂ u`` is the output error of an observer: for a
gain L with ``A − L C`` stable (Zhou, Doyle & Glover 1996, Thm 5.9)

    M̂ = W (A − L C, −L, C, I),        N̂ = W (A − L C, Bu − L Du, C, Du),

so ``M̂ y − N̂ u = W (y − C x̂ − Du u)``. The factorisation is built on the model's whole
state, so ``M̂ [Gu Gd Gw Gf]`` is stable even for plant modes that u does not reach.

- ``normalized=False``: L by pole placement (``W = I``), as in
  :func:`~fmu_fdi.design.observers.output_observer.luenberger`.
- ``normalized=True``: the normalised factorisation, ``M̂ M̂~ + N̂ N̂~ = I`` on the
  stability boundary. It is the innovation filter of ``y = Gu u + v`` with u and v unit
  white noise: L from the filter Riccati equation with ``Qx = Bu Buᵀ``, ``S = Bu Duᵀ``,
  ``R = I + Du Duᵀ`` (ZDG Thm 13.37 in continuous time, ``W = R^{-1/2}``; in discrete
  time the innovation covariance ``Σ = C P Cᵀ + R`` gives ``W = Σ^{-1/2}``).
"""
from __future__ import annotations

import numpy as np

from ...errors import DesignError
from ...generator import ResidualGenerator
from ...linalg import inv_sqrtm_pd
from ...lti import LTI
from ...model import FDIModel
from ..observers._observer import (as_matrix, filter_riccati, fmt_modes, observer_gain, observer_generator,
                                   output_observer, residual_names, unstable)


def factorized(model: FDIModel, poles=None, normalized: bool = False, post_filter=None, *,
               atol: float = 0.0) -> ResidualGenerator:
    """Residual ``r = R [M̂ y − N̂ u]`` from a left coprime factorisation ``Gu = M̂⁻¹ N̂``.

    Parameters
    ----------
    model : FDIModel
        Continuous or discrete (factorised directly in discrete time).
    poles : array_like, optional
        Poles of the factors (eigenvalues of ``A − L C``; as many as ``(A, C)`` has
        observable modes). Default: distinct poles twice as fast as the plant's modes. Not
        allowed with ``normalized=True``, which fixes them.
    normalized : bool
        Use the normalised left coprime factorisation (``M̂ M̂~ + N̂ N̂~ = I``).
    post_filter : LTI, python-control system or array_like, optional
        The free stable filter ``R(p)`` with p inputs (default the identity). A static
        matrix is a constant R; a python-control system with an unspecified time base
        (``dt=True`` or ``None``) takes the model's sample time.
    atol : float
        Absolute rank tolerance of the observability staircase (Varga's ``atol``): singular values at or
        below ``max(rtol·||[A; C]||, atol)`` count as zero (default 0: relative only).

    Returns
    -------
    ResidualGenerator
        ``Q = R [M̂  −N̂]`` from ``[y; u]``, one residual group. ``info``: ``gain`` L,
        ``poles``, ``normalized``, ``W`` (the constant left factor of M̂ and N̂),
        ``post_filter_order``, ``fixed_modes``, ``detected_faults``.

    Raises
    ------
    DesignError
        ``(A, C)`` not detectable (modes named); poles invalid or given together with
        ``normalized=True``; no stabilising Riccati solution (normalised case); a
        post-filter of the wrong input size, unstable, zero, or with another sample time.

    References
    ----------
    P. M. Frank, Fault diagnosis for linear systems, EOLSS, eqs. (10)-(11).
    X. Ding and P. M. Frank, Fault detection via factorization approach, Systems & Control
    Letters 14, 1990.
    K. Zhou, J. C. Doyle and K. Glover, *Robust and Optimal Control*, 1996, secs. 5.4 and 13.8.
    """
    R = _post_filter(post_filter, model)
    Q0, info = _factor_filter(model, poles, normalized, atol)
    Q = Q0 if R is None else R @ Q0
    info["post_filter_order"] = 0 if R is None else int(R.n)
    names = residual_names(model) if R is None and not normalized else None
    return observer_generator(model, Q, "factorized", info, names)


def left_coprime_factors(model: FDIModel, poles=None, normalized: bool = False, *,
                         atol: float = 0.0) -> tuple[LTI, LTI]:
    """The factors ``(M̂, N̂)`` of ``Gu = M̂⁻¹ N̂`` used by :func:`factorized` (same options)."""
    Q0, _ = _factor_filter(model, poles, normalized, atol)
    p = model.ny
    return Q0[:, :p], -Q0[:, p:]


def _factor_filter(model: FDIModel, poles, normalized: bool, atol: float = 0.0) -> tuple[LTI, dict]:
    """``[M̂  −N̂]`` as one filter from ``[y; u]`` (shared states), and its design data."""
    if not isinstance(normalized, (bool, np.bool_)):
        raise DesignError(f"normalized must be True or False, got {normalized!r}")
    A, C = model.A, model.C
    if normalized:
        if poles is not None:
            raise DesignError("poles cannot be given with normalized=True: the normalised factorisation fixes "
                              "the poles (the filter Riccati equation decides them)")
        p = model.ny
        Bu, Du = model.Bu, model.Du
        kf = filter_riccati(A, C, Bu @ Bu.T, np.eye(p) + Du @ Du.T, Bu @ Du.T, model.dt,
                            what="the normalised coprime factorisation")
        L, W, fixed = kf.L, inv_sqrtm_pd(kf.Sigma), np.zeros(0)
        placed = np.linalg.eigvals(A - L @ C) if model.n else np.zeros(0)
        method = "filter Riccati equation"
    else:
        gain = observer_gain(A, C, poles, model.dt, what="(A, C)",
                             fixed_reason="no coprime factorisation over the model's state exists", atol=atol)
        L, W, fixed, placed, method = gain.L, np.eye(model.ny), gain.fixed, gain.poles, gain.method
    info = {"gain": L.tolist(), "poles": np.asarray(placed).tolist(), "fixed_modes": np.asarray(fixed).tolist(),
            "normalized": bool(normalized), "W": W.tolist(), "placement": method}
    return output_observer(model, L, W), info


def _post_filter(post, model: FDIModel) -> LTI | None:
    """The post-filter as an LTI with the model's time base, validated, or None for I."""
    if post is None:
        return None
    p, dt = model.ny, model.dt
    if isinstance(post, LTI):
        R = post
    elif hasattr(post, "dt") and hasattr(post, "ninputs"):  # a python-control system
        if post.dt is True and not dt:
            raise DesignError("post_filter is discrete with an unspecified sample time (dt=True) but the "
                              "model is continuous")
        if (post.dt is True or post.dt is None) and dt:  # unspecified time base: take the model's
            import control

            post = control.ss(post)
            post = control.ss(post.A, post.B, post.C, post.D, dt)
        try:
            R = LTI.from_control(post)
        except (TypeError, ValueError) as exc:
            raise DesignError(f"post_filter: {exc}") from None
    else:
        R = LTI.static(as_matrix(np.atleast_2d(post) if np.ndim(post) < 2 else post, "post_filter", cols=p), dt)
    if R.n == 0 and R.dt != dt:
        R = LTI.static(R.D, dt)  # a constant has no time base
    if abs(R.dt - dt) > 1e-12 * max(1.0, dt):
        kind = lambda t: f"discrete with dt={t:g}" if t else "continuous"  # noqa: E731
        raise DesignError(f"post_filter is {kind(R.dt)} but the model is {kind(dt)}")
    if R.m != p:
        raise DesignError(f"post_filter must have {p} inputs (one per output {model.y_names}), got {R.m}")
    if not R.is_stable():
        bad = unstable(R.poles(), dt)
        raise DesignError(f"post_filter must be stable (R ∈ RH∞): its poles {fmt_modes(bad)} are not "
                          f"{'inside the unit circle' if dt else 'in the open left half-plane'}")
    if not np.any(R.D) and not (np.any(R.B) and np.any(R.C)):
        raise DesignError("post_filter is zero: the residual would be identically zero")
    return R

