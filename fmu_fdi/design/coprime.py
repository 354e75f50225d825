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
  :func:`~fmu_fdi.design.output_observer.luenberger`.
- ``normalized=True``: the normalised factorisation, ``M̂ M̂~ + N̂ N̂~ = I`` on the
  stability boundary. It is the innovation filter of ``y = Gu u + v`` with u and v unit
  white noise: L from the filter Riccati equation with ``Qx = Bu Buᵀ``, ``S = Bu Duᵀ``,
  ``R = I + Du Duᵀ`` (ZDG Thm 13.37 in continuous time, ``W = R^{-1/2}``; in discrete
  time the innovation covariance ``Σ = C P Cᵀ + R`` gives ``W = Σ^{-1/2}``).
"""
from __future__ import annotations

import numpy as np

from ..errors import DesignError
from ..freqresp import eigenvalues
from ..generator import ResidualGenerator
from ..linalg import inv_sqrtm_pd
from ..lti import LTI
from ..model import FDIModel
from ._observer import (as_matrix, filter_riccati, fmt_modes, observer_gain, observer_generator, output_observer,
                        residual_names, unstable)


def factorized(model: FDIModel, poles=None, normalized: bool = False, post_filter=None) -> ResidualGenerator:
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
    Q0, info = _factor_filter(model, poles, normalized)
    Q = Q0 if R is None else R @ Q0
    info["post_filter_order"] = 0 if R is None else int(R.n)
    names = residual_names(model) if R is None and not normalized else None
    return observer_generator(model, Q, "factorized", info, names)


def left_coprime_factors(model: FDIModel, poles=None, normalized: bool = False) -> tuple[LTI, LTI]:
    """The factors ``(M̂, N̂)`` of ``Gu = M̂⁻¹ N̂`` used by :func:`factorized` (same options)."""
    Q0, _ = _factor_filter(model, poles, normalized)
    p = model.ny
    return Q0[:, :p], -Q0[:, p:]


def _factor_filter(model: FDIModel, poles, normalized: bool) -> tuple[LTI, dict]:
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
                             fixed_reason="no coprime factorisation over the model's state exists")
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


def glcf(sys: LTI, choose, good) -> tuple[LTI, LTI, int]:
    """Stable left coprime factorisation ``sys = M⁻¹ N`` moving only the poles outside ``good``.

    For ``sys = (A, B, C, D)`` and an output injection L,

        M = (A + L C, L, C, I),        N = (A + L C, B + L D, C, D),        M⁻¹ N = sys,

    (Zhou, Doyle & Glover 1996, Thm 5.9). L is the transpose of the state feedback that
    :func:`~fmu_fdi.design.pencil.assign_poles` computes for the dual pair ``(Aᵀ, Cᵀ)``: an
    ordered real Schur form moves one 1×1 or 2×2 block outside ``good(re, im)`` at a time to
    ``choose(bad_eigenvalues)`` and leaves every other eigenvalue where it is (Varga 1981; the
    method of Varga's ``glcf``). ``M`` is biproper (D = I), so ``M·X`` is zero only where X is.
    ``sys`` must be observable in its bad modes (pass a minimal realisation): an unobservable bad
    mode cannot be moved and is reported as not moved. Returns ``(N, M, moved)``.
    """
    from .pencil import assign_poles

    if sys.n == 0:
        return sys, LTI.static(np.eye(sys.p), sys.dt), 0
    F, moved = assign_poles(sys.A.T, sys.C.T, sys.dt, choose, good)
    L = F.T
    A = sys.A + L @ sys.C
    N = LTI(A, sys.B + L @ sys.D, sys.C, sys.D, sys.dt)
    M = LTI(A, L, sys.C, np.eye(sys.p), sys.dt)
    return N, M, moved


#: damping ratio given to a moved pole on (or next to) the stability boundary: a marginal mode
#: (an integrator, an undamped oscillation) would otherwise ring or drift in the residual
MOVED_DAMPING = 0.7


def moved_pole_targets(model: FDIModel, poles=None, sdeg: float | None = None, smarg: float | None = None):
    """``bad eigenvalues ↦ targets`` for the poles a stable factorisation of the internal form moves.

    - ``poles`` given: they are used first (conjugate pairs kept together);
    - ``sdeg`` given: the rest are mirrored into ``Re λ ≤ sdeg`` (``|z| ≤ sdeg``; as the pencil
      basis, :func:`~fmu_fdi.design.pencil.mirror`: distinct eigenvalues stay distinct);
    - neither: an unstable pole is mirrored about the boundary (``-Re λ + j Im λ``, the plant's
      own speed) and a pole on or near it gets the real part ``-ζ ω₀`` with ``ζ =``
      :data:`MOVED_DAMPING` and ``ω₀ = |λ|``, or for λ = 0 the median speed of the plant's other
      poles (1 rad/s without any) — in discrete time through ``s = ln(z)/dt``.

    A target that still breaks the margin ``smarg`` is mirrored about it.
    """
    from .pencil import mirror
    from .postconditions import default_smarg

    dt = float(model.dt)
    margin = default_smarg(dt) if smarg is None else float(smarg)
    given_all = np.zeros(0, complex) if poles is None else np.atleast_1d(np.asarray(poles, complex))
    eig = eigenvalues(model.A) if model.n else np.zeros(0, complex)
    speeds = np.abs(np.log(eig[np.abs(eig) > 0]) / dt) if dt else np.abs(eig)
    speeds = speeds[speeds > 1e-6 * max(1.0, float(np.max(speeds, initial=0.0)))]
    ref = float(np.median(speeds)) if speeds.size else 1.0

    def continuous_rule(s: complex) -> complex:
        w0 = abs(s) if abs(s) > 1e-9 * ref else ref
        return complex(-max(abs(s.real), MOVED_DAMPING * w0), s.imag)

    def rule(z: complex) -> complex:
        if sdeg is not None:
            return complex(mirror(np.array([z]), float(sdeg), bool(dt))[0]) if not (
                (abs(z) <= sdeg) if dt else (z.real <= sdeg)) else z
        if not dt:
            return continuous_rule(z)
        if abs(z) == 0:
            return z
        s = complex(np.log(complex(z))) / dt
        st = continuous_rule(s)
        if abs(z.imag) <= 1e-12 * max(1.0, abs(z)):
            return complex(np.sign(z.real) * np.exp(st.real * dt))
        return complex(np.exp(st * dt))

    def inside(z: complex) -> bool:
        return abs(z) < margin if dt else z.real < margin

    def choose(bad: np.ndarray) -> np.ndarray:
        bad = np.asarray(bad, complex)
        given = given_all[: bad.size]
        if given.size and abs(given[-1].imag) > 0 and (given.size < 2 or given[-2] != np.conj(given[-1])):
            given = given[:-1]  # do not split a pair
        # every bad eigenvalue's own target after the given poles (conjugate-closed as the bad set
        # is): assign_poles takes what each Schur block needs, pairs for 2×2 blocks
        beta = margin - 1e-3 * (margin if dt else max(1.0, abs(margin)))
        out = []
        for z in (rule(complex(z)) for z in bad):
            out.append(z if inside(z) else complex(mirror(np.array([z]), beta, bool(dt))[0]))
        return np.concatenate([given, np.array(out, complex)])

    return choose


def internal_form_realisation(model: FDIModel, Q: LTI) -> tuple[LTI, int]:
    """``[Q  R_w  R_f]`` on one state vector (Q's states and the plant's), with ``R = Q·Ge``.

    With ``Q = (Aq, Bq, Cq, Dq)`` and ``Ge = (A, Bg, Cg, Dg)`` (:meth:`FDIModel.augmented`) the
    series connection has ``A = [A 0; Bq Cg Aq]``, ``C = [Dq Cg  Cq]``; Q itself is the same
    realisation driven through ``[0; Bq]`` (the plant's states are not reached from Q's inputs).
    The decoupled blocks ``R_u``, ``R_d`` are zero and left out, so that a plant mode only u or d
    excite does not count as a pole of R. Returns the realisation and the number of Q's inputs.
    """
    sl = model.group_slices()
    cols = np.arange(sl["w"].start, sl["f"].stop)
    Ge = model.augmented()
    S = Q @ Ge[:, cols]  # states [x_plant; x_Q]
    BQ = np.vstack([np.zeros((model.n, Q.m)), Q.B])
    return LTI(S.A, np.hstack([BQ, S.B]), S.C, np.hstack([Q.D, S.D]), Q.dt), Q.m


#: relative rank tolerance of the minimal realisation of ``[Q R]``: above the rounding of an exact
#: cancellation in the series connection ``Q·Ge`` (cond·eps, ~1e-12 on the published examples: the
#: Xiong–Saif integrators stay as modes of that size with the default n²·eps), far below dec_tol
#: (1e-6), the leakage a design may show anyway
CANCEL_RTOL = 1e-10


def stable_internal_form(model: FDIModel, Q: LTI, *, poles=None, sdeg: float | None = None,
                         smarg: float | None = None, keep_stable_poles: bool = True) -> tuple[LTI, dict]:
    """Replace Q by ``M·Q`` so that the whole internal form ``R = Q·Ge`` is stable with the margin.

    A decoupling filter Q may be stable while ``R_f = Q·Gf`` (or ``R_w``) keeps an unstable or
    marginal pole of the plant (``Gf = [1/(s−1); 1/(s+2)]``: the basis is static and ``Q·Gf``
    has the pole at +1), and the residual the runtime computes then diverges or rings. As
    Varga's ``efdsyn`` (Varga 2017, Procedure EFD step 3; FaultDetectionTools.jl ``glcf``), a
    stable left coprime factorisation of the joint ``[Q R] = M⁻¹ [N_Q N_R]``
    (:func:`internal_form_realisation`, reduced to a minimal realisation, then :func:`glcf`)
    moves only the poles violating the margin ``smarg`` — and, with ``keep_stable_poles=False``
    and ``sdeg`` given, the stable ones slower than ``sdeg`` — to the targets of
    :func:`moved_pole_targets`. ``Q ← N_Q = M·Q`` and ``R ← M·R``: M is square, stable and
    biproper with a stable inverse's poles cancelling exactly, so the decoupled blocks stay zero
    and every fault that was visible stays visible (``M(λ)`` is invertible except at the moved
    poles). Q is returned unchanged (the same object) when nothing violates the region.

    Returns ``(Q, info)``; ``info`` is empty when nothing moved, else ``moved_poles`` (the poles
    of ``[Q R]`` that were moved), ``moved`` (their count) and ``order_before`` (Q's order).
    """
    from .postconditions import default_smarg

    dt = float(model.dt)
    margin = default_smarg(dt) if smarg is None else float(smarg)
    limit = np.inf if (sdeg is None or keep_stable_poles) else float(sdeg) + 1e-9 * max(1.0, abs(float(sdeg)))
    if dt:
        good = lambda re, im: np.hypot(re, im) < margin and np.hypot(re, im) <= limit  # noqa: E731
    else:
        good = lambda re, im: re < margin and re <= limit  # noqa: E731
    # the poles of [Q R] are among those of Q and of the plant: decided on each block's own
    # eigenvalues (the joint matrix couples Q's poles, often the plant's own, to the plant's, and
    # its computed eigenvalues can leave a cluster by far more than rounding)
    eig = np.concatenate([Q.poles(), eigenvalues(model.A) if model.n else np.zeros(0)])
    if all(good(z.real, z.imag) for z in eig):
        return Q, {}
    J, q = internal_form_realisation(model, Q)
    # a plant pole that Q's zero cancels (an integrator the decoupling row annihilates) is left by a
    # series connection as a mode observable only through the cancellation error, ~1e-12 relative:
    # the rank decisions of the minimal realisation take CANCEL_RTOL of the balanced data's norm
    Jb, _ = J.balanced()
    nrm = float(np.linalg.norm(np.block([[Jb.A, Jb.B], [Jb.C, Jb.D]]), 2))
    Jm = Jb.minreal(tol=CANCEL_RTOL * nrm)
    eig = Jm.poles()
    bad = eig[~np.array([good(z.real, z.imag) for z in eig], bool)] if eig.size else eig
    if bad.size == 0:
        return Q, {}
    N, _, moved = glcf(Jm, moved_pole_targets(model, poles, sdeg, smarg), good)
    Qn = N[:, :q].minreal()
    left = [z for z in N.poles() if not good(z.real, z.imag)]
    if left:
        from .postconditions import NumericalDesignError

        raise NumericalDesignError(
            f"the internal form R = Q·Ge keeps the poles {np.round(np.asarray(left), 6).tolist()} outside the "
            f"stability region (stability margin smarg = {margin:.6g}) after its stable left coprime "
            f"factorisation: the poles of [Q R] are too ill-conditioned to be moved — pass other poles/sdeg or "
            f"rank tolerances")
    return Qn, {"moved_poles": np.asarray(bad).tolist(), "moved": int(moved), "order_before": int(Q.n)}
