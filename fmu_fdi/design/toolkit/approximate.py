"""Approximate decoupling of noise: co-outer–co-inner factorisation and the gap.

When the noise inputs w cannot be decoupled exactly, the residual should see the faults
much more than the noise. The figure of merit is the fault-to-noise gap
``min_j ||Rf_j||∞ / ||Rw||∞`` (Varga 2017, sec. 5.3; acceptance A4/A5). Following
Varga's Procedure AFD we

1. split the exact (u, d)-decoupling residuals into ``Q2`` (also w-free) and ``Q1`` whose
   noise response ``Rw1`` has full normal row rank;
2. factor ``Rw1 = Ro Ri`` with ``Ri`` co-inner (``Ri Ri~ = I``) and ``Ro`` square, stable
   and minimum phase, and replace ``Q1 ← Ro^{-1} Q1`` so that ``||h1 Rw1||∞ = ||h1||``;
3. choose the combination ``h = [h1 h2]`` that maximises the gap.

The factorisation is the transpose of the inner–outer factorisation of Zhou, Doyle and
Glover (*Robust and Optimal Control*, Thm. 13.34; discrete analogue via the DARE). It
needs a full-row-rank feedthrough and no zeros on the stability boundary; otherwise
step 2 is skipped (the filter poles then set the frequency weighting, as in Varga's
Example 5.11 with its poles at −3).
"""
from __future__ import annotations

import functools
import inspect
from contextvars import ContextVar
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...linalg import inv_sqrtm_pd, rank, sqrtm_psd
from ...lti import LTI, hstack


def coouter_inverse(G: LTI) -> tuple[LTI, LTI] | None:
    """For stable ``G = Ro Ri``: return ``(Ro^{-1}, Ri)``, or None if the standard
    conditions fail (feedthrough not of full row rank, zeros on the stability boundary)."""
    if G.n == 0:
        return None
    Gt = G.transpose()  # tall: inner–outer of Gt = Gi Go gives G = Go^T Gi^T
    A, B, C, D = Gt.A, Gt.B, Gt.C, Gt.D
    if rank(D) < D.shape[1]:
        return None
    try:
        if G.is_discrete:
            X = sla.solve_discrete_are(A, B, C.T @ C, D.T @ D, s=C.T @ D)
            Rk = D.T @ D + B.T @ X @ B
            F = -np.linalg.solve(Rk, B.T @ X @ A + D.T @ C)
        else:
            X = sla.solve_continuous_are(A, B, C.T @ C, D.T @ D, s=C.T @ D)
            Rk = D.T @ D
            F = -np.linalg.solve(Rk, B.T @ X + D.T @ C)
        Rh, Rhi = sqrtm_psd(Rk), inv_sqrtm_pd(Rk)
    except (np.linalg.LinAlgError, ValueError):
        return None
    Acl = A + B @ F
    closed = LTI(Acl, B @ Rhi, C + D @ F, D @ Rhi, G.dt)
    if not closed.is_stable(margin=1e-9):
        return None
    Go_inv = LTI(Acl, B @ Rhi, F, Rhi, G.dt)
    _ = Rh  # Go = (A, B, -Rh F, Rh); only its inverse is needed
    return Go_inv.transpose(), closed.transpose()


def gap_objective(Rf: list[np.ndarray], Rw: np.ndarray):
    """Grid estimate of the gap of a combination ``h``.

    ``Rf[j]``: (points, rows, cols_j) responses to fault j; ``Rw``: (points, rows, mw).
    Rows whose noise response is exactly zero by construction must carry exact zeros in
    ``Rw`` (not rounding noise), or the ratio rewards vanishing combinations.
    """

    def objective(h: np.ndarray) -> float:
        fault = min(np.max(np.linalg.norm(np.einsum("r,krc->kc", h, F), axis=1)) for F in Rf)
        noise = np.max(np.linalg.norm(np.einsum("r,krc->kc", h, Rw), axis=1))
        if noise == 0.0:
            return 1e12 if fault > 0 else 0.0
        return float(fault / noise)

    return objective


# ------------------------------------------------------------------ the non-standard case (nonstd)
#: FaultDetectionTools.jl ``afdsyn``'s ``nonstd`` choices for a noise response ``Rw`` without an invertible
#: co-outer factor (zeros at infinity — a strictly proper Rw — or on the stability boundary)
NONSTD = {
    1: "quasi-co-outer–co-inner factorisation, the boundary and infinite zeros of the factor moved by the "
       "stabilising factor (to poles/sdeg)",
    2: "modified co-outer–co-inner factorisation of [Rw  ε I] (regularisation parameter epsreg)",
    3: "Wiener–Hopf type co-outer–co-inner factorisation",
    4: "Wiener–Hopf type factorisation with the boundary and infinite zeros shifted by sdegzer",
    5: "Wiener–Hopf type factorisation with the non-minimum-phase factor regularised by epsreg",
}

#: a zero of the co-outer factor within this relative distance of the boundary counts as on it: double
#: roots of the spectral numerator come out of ``np.roots`` ~sqrt(eps) apart
ZERO_BOUNDARY_RTOL = 1e-5

_OPTIONS: ContextVar = ContextVar("fmu_fdi_nonstd", default=None)


@dataclass(frozen=True)
class NonstandardOptions:
    """The validated ``nonstd``/``epsreg``/``sdegzer`` of one approximate design (``nonstd=None``: the
    peer's default 1, falling back to 2 — with a note — where 1 is not available here)."""

    nonstd: int | None = None
    epsreg: float = 0.1
    sdegzer: float | None = None

    @classmethod
    def validated(cls, nonstd=None, epsreg=0.1, sdegzer=None) -> "NonstandardOptions":
        if nonstd is not None and (isinstance(nonstd, bool) or nonstd not in NONSTD):
            raise DesignError(f"nonstd must be one of {sorted(NONSTD)} (FaultDetectionTools.jl afdsyn), got {nonstd!r}")
        if not (np.isfinite(epsreg) and epsreg > 0):
            raise DesignError(f"epsreg must be a positive regularisation parameter, got {epsreg!r}")
        if sdegzer is not None and not np.isfinite(sdegzer):
            raise DesignError(f"sdegzer must be finite, got {sdegzer!r}")
        return cls(None if nonstd is None else int(nonstd), float(epsreg), None if sdegzer is None else float(sdegzer))


def with_nonstandard_options(design):
    """Decorator of a design function with the keywords ``nonstd``, ``epsreg``, ``sdegzer``: validates them
    (:meth:`NonstandardOptions.validated`) and makes them the options :func:`noise_normalizer` uses during
    the call (the synthesis stages between need not pass them on)."""
    sig = inspect.signature(design)

    @functools.wraps(design)
    def wrapper(*args, **kwargs):
        bound = sig.bind_partial(*args, **kwargs)
        get = lambda name: bound.arguments.get(name, sig.parameters[name].default)  # noqa: E731
        opts = NonstandardOptions.validated(get("nonstd"), get("epsreg"), get("sdegzer"))
        token = _OPTIONS.set(opts)
        try:
            return design(*args, **kwargs)
        finally:
            _OPTIONS.reset(token)

    return wrapper


def active_options() -> NonstandardOptions | None:
    """The options of the design in progress (:func:`with_nonstandard_options`), None outside one."""
    return _OPTIONS.get()


def noise_normalizer(Rw: LTI, *, smarg: float | None = None, poles=None, sdeg: float | None = None,
                     options: NonstandardOptions | None = None) -> tuple[LTI | None, str]:
    """``(Ro⁻¹, how)``: the left factor that normalises the stable noise response ``Rw`` (Procedure AFD,
    step 2), or ``(None, how)`` when ``Rw`` has no dynamics to normalise.

    Standard case (every ``nonstd``): ``Rw = Ro Ri``, ``Ri`` co-inner, ``Ro`` invertible with a stable
    inverse (:func:`coouter_inverse`). Non-standard (zeros of ``Rw`` at infinity or on the stability
    boundary, where ``Ro⁻¹`` would be improper or marginally stable), as FaultDetectionTools.jl ``afdsyn``:

    - ``nonstd = 1`` (default): the quasi-co-outer factor ``Ro`` (zeros in the closed stability region) and
      the stable left factor the peer's ``glcf`` applies after it, in one: ``Ro_m⁻¹`` with
      ``Ro_m = Ro ∏(λ−t_b)/(λ−z_b) ∏(λ−t_∞)``, every boundary zero ``z_b`` replaced by a stable ``t_b`` and
      every zero at infinity by a stable ``t_∞`` (from ``poles`` first, then ``sdeg``, else ``-0.7|z_b|``,
      and for ``λ = 0`` and infinity the speed of ``Rw``'s poles). Exact for one noise-facing row in
      continuous time (a scalar spectral factor).
    - ``nonstd = 2``: the co-outer factor of ``[Rw  ε I]``, ``ε = epsreg·||Rw||∞`` (relative, so that the
      choice does not depend on the scaling of the basis rows; the peer's ε is absolute on its rows),
      ``Ro Ro~ = Rw Rw~ + ε² I``.
    - ``nonstd = 4``: as 1 with the peer's zero shifting: ``t_b = z_b + sdegzer`` and ``t_∞ = 1/sdegzer``
      (``sdegzer`` default -0.05).
    - ``nonstd = 3, 5`` need the Wiener–Hopf separation of the boundary zeros (the peer's ``gcrange``),
      which this toolkit does not have: refused (DesignError) in the non-standard case.

    Without ``nonstd`` (None): 1 where it applies, else 2, else no normalisation (the filter poles weight
    the noise), the fallback said in ``how`` (``info['noise']``). A chosen option that cannot handle the case raises
    a DesignError naming it.
    """
    from ...margin import default_smarg

    opts = options or _OPTIONS.get() or NonstandardOptions()
    if Rw.n == 0:
        return None, "weighted by the filter poles (static noise response)"
    fac = coouter_inverse(Rw)
    margin = default_smarg(Rw.dt) if smarg is None else smarg
    if fac is not None and _clear_of_boundary(fac[0].poles(), Rw.dt, margin):
        return fac[0], "co-outer normalised"
    job = opts.nonstd if opts.nonstd is not None else 1
    if job in (3, 5):
        raise DesignError(f"nonstd = {job} ({NONSTD[job]}) is not available: the noise response Rw has zeros at "
                          f"infinity or on the stability boundary and its Wiener–Hopf split is not implemented here; "
                          f"use nonstd = 1, 2 or 4")
    if job in (1, 4):
        why = None if (Rw.p == 1 and not Rw.dt) else (
            f"it is implemented for one noise-facing residual row in continuous time (here {Rw.p} rows, "
            f"{'discrete' if Rw.dt else 'continuous'} time)")
        if why is None:
            try:
                inv, text = _scalar_shifted_inverse(Rw, job, poles=poles, sdeg=sdeg, sdegzer=opts.sdegzer)
                return inv, f"quasi-co-outer normalised (nonstd = {job}): {text}"
            except (np.linalg.LinAlgError, ValueError, DesignError) as exc:
                why = f"the scalar spectral factor failed: {exc}"
        if opts.nonstd is not None:
            raise DesignError(f"nonstd = {job} ({NONSTD[job]}) cannot handle this non-standard noise response: {why}; "
                              f"use nonstd = 2")
        fallback = f"; nonstd = 1 (the default) does not apply ({why})"
    else:
        fallback = ""
    peak = Rw.hinfnorm()[0]
    eps = opts.epsreg * peak
    reg = coouter_inverse(hstack([Rw, LTI.static(eps * np.eye(Rw.p), Rw.dt)])) if 0 < peak < np.inf else None
    if reg is None:
        if opts.nonstd is None:  # the default: the filter poles weight the noise, as before the option existed
            return None, (f"weighted by the filter poles: the noise response has no invertible co-outer factor and "
                          f"neither nonstd = 1 nor 2 applied (||Rw||∞ = {peak:.3g}){fallback}")
        raise DesignError(f"nonstd = 2: the co-outer factor of [Rw  ε I] (ε = {eps:.3g}) could not be computed "
                          f"(the Riccati equation has no stabilising solution)")
    return reg[0], f"regularised co-outer normalised (nonstd = 2, ε = {eps:.3g} = epsreg·||Rw||∞){fallback}"


#: a co-outer inverse pole within this relative distance of the stability boundary counts as on it
BOUNDARY_RTOL = 1e-6


def _clear_of_boundary(poles: np.ndarray, dt: float, margin: float) -> bool:
    """Every pole inside the margin and at least :data:`BOUNDARY_RTOL` (relative to its modulus, at
    least 1) away from the boundary itself."""
    poles = np.asarray(poles, complex)
    if dt:
        return bool(np.all(np.abs(poles) <= min(margin, 1.0 - BOUNDARY_RTOL)))
    return bool(np.all(poles.real <= np.minimum(margin, -BOUNDARY_RTOL * np.maximum(1.0, np.abs(poles)))))


def _scalar_shifted_inverse(Rw: LTI, job: int, *, poles, sdeg, sdegzer) -> tuple[LTI, str]:
    """``Ro_m⁻¹`` of :func:`noise_normalizer` for a stable one-row continuous ``Rw = [n_1 … n_m]/a``:
    the spectral numerator ``P(s) = Σ_j n_j(s) n_j(−s)`` (even) has its roots in pairs ``±r``; ``Ro`` takes
    the stable one of each pair, one of each double boundary root, ``c = sqrt|lead P|``, and ``deg a − deg P/2``
    zeros at infinity (Youla's scalar spectral factorisation)."""
    import scipy.signal as ssig

    A, B, C, D = Rw.A, Rw.B, Rw.C, Rw.D
    a = np.real(np.poly(np.linalg.eigvals(A)))
    P = np.zeros(1)
    for j in range(Rw.m):  # n_j = C adj(sI − A) B_j + D_j a = det(sI − A + B_j C) − a + D_j a
        nj = np.real(np.poly(np.linalg.eigvals(A - np.outer(B[:, j], C[0])))) - a + D[0, j] * a
        nj = np.trim_zeros(np.where(np.abs(nj) > 1e-13 * np.max(np.abs(nj), initial=0.0), nj, 0.0), "f")
        if nj.size:
            mirror_nj = nj * (-1.0) ** np.arange(nj.size - 1, -1, -1)
            P = np.polyadd(P, np.polymul(nj, mirror_nj))
    P = np.trim_zeros(P, "f")
    if P.size == 0:
        raise DesignError("the noise response Rw is identically zero: nothing to normalise")
    roots = np.roots(P)
    scale = np.maximum(1.0, np.abs(roots))
    on = np.abs(roots.real) <= ZERO_BOUNDARY_RTOL * scale  # a double boundary root splits ~sqrt(eps) apart
    stable = roots[(~on) & (roots.real < 0)]
    bnd = roots[on][np.argsort(roots[on].imag)]
    if bnd.size % 2 or stable.size + bnd.size // 2 != (P.size - 1) // 2:
        raise DesignError(f"nonstd = {job}: the spectral numerator of the noise response has roots {roots.tolist()} "
                          f"that do not pair as ±r (numerically ill-conditioned factorisation); use nonstd = 2")
    bnd = np.array([complex(0.0, 0.5 * (bnd[i].imag + bnd[i + 1].imag)) for i in range(0, bnd.size, 2)])
    n_inf = (a.size - 1) - (P.size - 1) // 2
    ref = float(np.median(np.abs(np.linalg.eigvals(A)))) if A.size else 1.0
    ref = ref if ref > 0 else 1.0
    given = list(np.atleast_1d(np.asarray(poles, complex))) if poles is not None else []

    def target(z):
        if job == 4:
            dz = -0.05 if sdegzer is None else sdegzer
            return z + dz if np.isfinite(z) else complex(1.0 / dz)
        if given:
            return given.pop(0)
        if sdeg is not None:
            return complex(sdeg, z.imag if np.isfinite(z) else 0.0)
        if not np.isfinite(z) or abs(z) == 0:
            return complex(-ref)
        return complex(-0.7 * abs(z), z.imag)

    moved = [target(z) for z in bnd] + [target(complex(np.inf)) for _ in range(n_inf)]
    if any(t.real >= 0 for t in moved):
        raise DesignError(f"nonstd = {job}: the replacement zeros {moved} of the noise factor are not stable "
                          f"(sdegzer/sdeg must be negative)")
    c = np.sqrt(abs(P[0]))
    den = c * np.real(np.poly(np.concatenate([stable, np.array(moved, complex)])))
    Ai, Bi, Ci, Di = ssig.tf2ss(a, den)
    text = (f"{bnd.size} zero(s) on the boundary {np.round(bnd, 6).tolist()} and {n_inf} at infinity replaced by "
            f"{np.round(np.array(moved), 6).tolist()}")
    return LTI(Ai, Bi, Ci, Di, 0.0), text
