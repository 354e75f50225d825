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
    conditions fail (continuous time: feedthrough not of full row rank; zeros on the stability
    boundary). In discrete time a rank-deficient feedthrough (zeros at infinity, outside the unit
    circle) is standard, as in the peer's ``goifac``: the DARE's ``DᵀD + BᵀXB`` must be invertible."""
    if G.n == 0:
        return None
    Gt = G.transpose()  # tall: inner–outer of Gt = Gi Go gives G = Go^T Gi^T
    A, B, C, D = Gt.A, Gt.B, Gt.C, Gt.D
    if not G.is_discrete and rank(D) < D.shape[1]:
        return None
    try:
        if G.is_discrete:
            X = sla.solve_discrete_are(A, B, C.T @ C, D.T @ D, s=C.T @ D)
            Rk = D.T @ D + B.T @ X @ B
            if rank(Rk) < Rk.shape[0]:
                return None
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
    - ``nonstd = 3, 4, 5``: the Wiener–Hopf split ``Rwo = Rwoe·Rwouz`` of the quasi-co-outer factor
      (:func:`wiener_hopf_split`; ``Rwouz`` holds the zeros on the boundary and, in continuous time, at
      infinity — in discrete time a proper ``Rw`` has no boundary zero at infinity, as the peer's ``gcrange``
      counts it): 3 ``Ro⁻¹ = Rwoe⁻¹/||Rwoe⁻¹Rw||∞``; 4 ``Ro⁻¹ = Rwouz(g(λ))⁻¹·Rwoe⁻¹`` with the peer's
      zero-shifting map ``g`` (:func:`zero_shift_map`, ``sdegzer`` default -0.05, discrete 0.95); 5
      ``Ro⁻¹ = Ro5⁻¹·Rwoe⁻¹``, ``Ro5`` the co-outer factor of ``[Rwouz  ε I]``, ``ε = epsreg·||Rwouz||∞``
      (``Ro5 Ro5~ = Rwouz Rwouz~ + ε² I``). Any number of noise-facing rows, continuous or discrete time.

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
    if job in (3, 4, 5):
        return wiener_hopf_normalizer(Rw, job, opts, sdeg)[:2]
    if job == 1:
        why = None if (Rw.p == 1 and not Rw.dt) else (
            f"it is implemented for one noise-facing residual row in continuous time (here {Rw.p} rows, "
            f"{'discrete' if Rw.dt else 'continuous'} time)")
        if why is None:
            try:
                inv, text = _scalar_shifted_inverse(Rw, job, poles=poles, sdeg=sdeg)
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


def _scalar_shifted_inverse(Rw: LTI, job: int, *, poles, sdeg) -> tuple[LTI, str]:
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
                          f"(sdeg must be negative)")
    c = np.sqrt(abs(P[0]))
    den = c * np.real(np.poly(np.concatenate([stable, np.array(moved, complex)])))
    Ai, Bi, Ci, Di = ssig.tf2ss(a, den)
    text = (f"{bnd.size} zero(s) on the boundary {np.round(bnd, 6).tolist()} and {n_inf} at infinity replaced by "
            f"{np.round(np.array(moved), 6).tolist()}")
    return LTI(Ai, Bi, Ci, Di, 0.0), text


# ------------------------------------------------------------ the Wiener–Hopf split (nonstd = 3, 4, 5)
@dataclass(frozen=True)
class WienerHopfSplit:
    """``Rwo = Rwoe·Rwouz`` of a stable full-row-rank noise response ``Rw = Rwo·Ri`` (``Ri`` co-inner).

    ``Rwo`` is the quasi-co-outer factor (square, stable, zeros in the closed stability region);
    ``Rwouz`` (square, stable, proper) holds exactly its zeros on the stability boundary (``boundary``)
    and, in continuous time, at infinity (``n_inf``); ``Rwoe`` is stable with a stable proper inverse
    (``Rwoe_inv``), so ``Rwoe⁻¹·Rw = Rwouz·Ri`` — the Wiener–Hopf type co-outer–co-inner factorisation
    of FaultDetectionTools.jl ``afdsyn`` (its ``goifac`` then ``gcrange(Rwo, zeros = "s-unstable")``).
    """

    Rwoe_inv: LTI
    Rwouz: LTI
    boundary: np.ndarray
    n_inf: int


def _rank_tol(*mats) -> float:
    scale = max([float(np.linalg.norm(M, 2)) for M in mats if M.size] + [1.0])
    return 1e-10 * scale


def _on_boundary(z: np.ndarray, dt: float) -> np.ndarray:
    """Zeros on the stability boundary, :data:`ZERO_BOUNDARY_RTOL` relative to their modulus (at least 1)."""
    z = np.asarray(z, complex)
    scale = np.maximum(1.0, np.abs(z))
    return np.abs(np.abs(z) - 1.0) <= ZERO_BOUNDARY_RTOL if dt else np.abs(z.real) <= ZERO_BOUNDARY_RTOL * scale


def _left_infinite_step(G: LTI, t: float, tol: float) -> tuple[LTI, LTI] | None:
    """One step of the extraction of zeros at infinity: ``G = L·G'`` with ``V`` an orthonormal basis of the
    left null space of ``D`` (``VᵀG`` strictly proper), ``L = (I − VVᵀ) + V·c/(s − t)·Vᵀ`` and
    ``G' = (I − VVᵀ)G + VVᵀG·(s − t)/c`` = ``(A, B, (I−VVᵀ)C + V Vᵀ(CA − tC)/c, (I−VVᵀ)D + VVᵀCB/c)`` —
    the same states, no cancellation. None when ``D`` has full row rank."""
    U, sv, _ = np.linalg.svd(G.D) if G.D.size else (np.eye(G.p), np.zeros(0), None)
    r = int(np.sum(sv > tol))
    if r == G.p:
        return None
    V = U[:, r:]
    c = abs(t)
    P = np.eye(G.p) - V @ V.T
    C2 = P @ G.C + V @ (V.T @ (G.C @ G.A - t * G.C)) / c
    D2 = P @ G.D + V @ (V.T @ (G.C @ G.B)) / c
    k = V.shape[1]
    L = LTI(t * np.eye(k), V.T, c * V, P, G.dt)
    return L, LTI(G.A, G.B, C2, D2, G.dt)


def _left_boundary_step(G: LTI, targets, tol: float) -> tuple[LTI, LTI, np.ndarray] | None:
    """One step of the extraction of finite boundary zeros (``D`` of full row rank): the left zeros of
    ``[A − λI  B; C  D]`` are the uncontrollable modes of ``(A − B D⁺C, B·D_⊥)`` (orthogonal staircase, then an
    ordered real Schur form puts one boundary eigenvalue block ``Λ`` first): ``WᵀA + VᵀC = ΛWᵀ``, ``WᵀB + VᵀD = 0``
    with ``Vᵀ = −WᵀB D⁺``. Then ``L⁻¹ = I + X(λI − Λ)⁻¹Vᵀ`` gives ``G' = L⁻¹G = (A, B, C − XWᵀ, D)`` (the same
    states) and ``L = (Λ − VᵀX, Vᵀ, −X, I)``: zeros ``eig Λ`` (on the boundary), poles ``eig(Λ − VᵀX)`` = targets.
    Returns ``(L, G', eig Λ)`` or None when ``G`` has no boundary zero."""
    from .pencil import _place, controllable_staircase

    A, B, C, D = G.A, G.B, G.C, G.D
    U, sv, Vh = np.linalg.svd(D)
    Dp = np.linalg.pinv(D, rcond=tol / max(sv[0], tol))
    A0 = A - B @ Dp @ C
    Dnull = Vh[G.p:].T
    T, taus = controllable_staircase(A0, B @ Dnull, tol)
    nc = int(sum(taus))
    if nc == G.n:
        return None
    Tu = T[:, nc:]
    A22 = Tu.T @ A0 @ Tu
    inside = (lambda re, im: _on_boundary(np.array([re + 1j * im]), G.dt)[0])
    S, Us, k = sla.schur(A22.T, output="real", sort=lambda re, im: bool(inside(re, im)))
    if k == 0:
        return None
    k = 2 if (k >= 2 and abs(S[1, 0]) > 0) else 1  # one real eigenvalue or one complex pair
    Lam = S[:k, :k].T
    Wt = Us[:, :k].T @ Tu.T
    Vt = -Wt @ B @ Dp
    X = -_place(Lam, Vt, np.asarray(targets[:k], complex))  # eig(Λ + Vᵀ(−X)) = targets
    L = LTI(Lam - Vt @ X, Vt, -X, np.eye(G.p), G.dt)
    return L, LTI(A, B, C - X @ Wt, D, G.dt), np.linalg.eigvals(Lam)


def _left_zero_factor(G: LTI, targets: list, what: str) -> tuple[list[LTI], LTI, list, int]:
    """``G = L₁⋯L_k·G'`` (stable full-row-rank ``G``): the ``L_i`` hold the zeros of ``G`` at infinity (continuous
    time) and on the stability boundary; ``G'`` has neither (its new zeros are the ``L_i``'s poles, at ``targets``).
    Returns ``(Ls, G', boundary zeros, number of infinite zeros)``."""
    Ls, found, n_inf = [], [], 0
    tol = _rank_tol(np.block([[G.A, G.B], [G.C, G.D]]))
    for _ in range(2 * (G.n + G.p) + 2):
        if not G.dt:
            step = _left_infinite_step(G, targets[0].real, tol)
            if step is not None:
                Ls.append(step[0])
                n_inf += step[0].n
                G = step[1]
                continue
        elif rank(G.D) < G.p:
            raise DesignError(f"{what}: the discrete noise response has a feedthrough of row rank {rank(G.D)} < {G.p} "
                              f"together with zeros on the unit circle; this Wiener–Hopf split needs a full row rank "
                              f"feedthrough in discrete time")
        step = _left_boundary_step(G, targets, tol)
        if step is None:
            return Ls, G, found, n_inf
        Ls.append(step[0])
        found += list(step[2])
        G = step[1]
    raise DesignError(f"{what}: the extraction of the boundary zeros of the noise response did not terminate "
                      f"(order {G.n}, {G.p} rows)")


def coouter_inverse_or_static(G: LTI) -> tuple[LTI, LTI | None] | None:
    """:func:`coouter_inverse`, and for a static ``G`` of full row rank ``Ro⁻¹ = (D Dᵀ)^{-1/2}``."""
    if G.n:
        return coouter_inverse(G)
    if rank(G.D) < G.p:
        return None
    return LTI.static(inv_sqrtm_pd(G.D @ G.D.T), G.dt), None


def _product(Ls: list[LTI], p: int, dt: float) -> LTI:
    out = LTI.static(np.eye(p), dt)
    for L in Ls:
        out = out @ L
    return out


def _biproper_inverse(G: LTI, what: str) -> LTI:
    """``G⁻¹ = (A − B D⁻¹C, B D⁻¹, −D⁻¹C, D⁻¹)`` of a square biproper ``G``; a DesignError if ``D`` is singular."""
    sv = np.linalg.svd(G.D, compute_uv=False)
    if sv.size == 0 or sv[-1] <= 1e-12 * max(1.0, sv[0]):
        raise DesignError(f"{what}: the factor to invert is not biproper (feedthrough singular values "
                          f"{np.round(sv, 14).tolist()})")
    Di = np.linalg.inv(G.D)
    return LTI(G.A - G.B @ Di @ G.C, G.B @ Di, -Di @ G.C, Di, G.dt)


def _split_targets(Rw: LTI, sdeg) -> list:
    """Stable poles for the extraction factors: ``sdeg`` if given, else the speed of Rw's poles (continuous), or
    0.5 (discrete); distinct values so that a complex pair gets two."""
    if Rw.dt:
        base = 0.5
        return [complex(base), complex(0.9 * base)]
    if sdeg is not None and sdeg < 0:
        base = float(sdeg)
    else:
        eig = np.abs(np.linalg.eigvals(Rw.A)) if Rw.n else np.ones(1)
        base = -max(float(np.median(eig)), 1e-3)
    return [complex(base), complex(1.1 * base)]


def wiener_hopf_split(Rw: LTI, *, sdeg: float | None = None, what: str = "nonstd") -> WienerHopfSplit:
    """The Wiener–Hopf split :class:`WienerHopfSplit` of a stable ``Rw`` of full row rank.

    1. ``Rw = L_b·Rw'`` (:func:`_left_zero_factor`): ``L_b`` holds the boundary and infinite zeros, ``Rw'`` has a
       full-row-rank feedthrough and no boundary zero, so its co-outer factor ``Ro'`` exists (:func:`coouter_inverse`,
       Riccati); ``Rwo = L_b·Ro'`` is the quasi-co-outer factor (``Rw Rw~ = Rwo Rwo~``).
    2. The same extraction on ``Rwoᵀ`` gives the right factor: ``Rwoᵀ = Rwouzᵀ·Rwoeᵀ``.
    """
    targets = _split_targets(Rw, sdeg)
    lam = 0.37 + 0.91j if not Rw.dt else 0.3 + 0.4j  # a point off the boundary and away from typical zeros
    if Rw.p > Rw.m or rank(Rw.evalfr(lam)) < Rw.p:
        raise DesignError(f"{what}: the noise response must have full row rank (here {Rw.p} rows, {Rw.m} noise inputs, "
                          f"rank {rank(Rw.evalfr(lam)) if Rw.p <= Rw.m else Rw.m} at λ = {lam})")
    Lb, Rw1, _, _ = _left_zero_factor(Rw, targets, what)
    fac = coouter_inverse_or_static(Rw1)
    if fac is None:
        raise DesignError(f"{what}: the noise response without its boundary zeros has no co-outer factor (the "
                          f"Riccati equation has no stabilising solution; order {Rw1.n}, {Rw1.p} rows)")
    Ro1 = _biproper_inverse(fac[0], what)
    Rwo = (_product(Lb, Rw.p, Rw.dt) @ Ro1).minreal()
    Lt, Et, zb, n_inf = _left_zero_factor(Rwo.transpose(), targets, what)
    Rwouz = _product(Lt, Rw.p, Rw.dt).transpose()
    Rwoe_inv = _biproper_inverse(Et.transpose(), what)
    if not Rwoe_inv.is_stable(margin=0.0) or not Rwouz.is_stable(margin=0.0):
        raise DesignError(f"{what}: the Wiener–Hopf factors are not stable (poles of Rwoe⁻¹ "
                          f"{np.round(Rwoe_inv.poles(), 6).tolist()}); the zeros of the noise response are too close "
                          f"to the stability boundary to separate")
    return WienerHopfSplit(Rwoe_inv, Rwouz, np.asarray(zb, complex), n_inf)


def bilinear_substitution(G: LTI, a: float, b: float, c: float, d: float) -> LTI:
    """``G(g(δ))`` for ``λ = g(δ) = (aδ + b)/(cδ + d)`` (the peer's ``gbilin``): with ``M = (aI − cA)⁻¹`` and
    ``Ã = M(dA − bI)``, ``G(g(δ)) = (Ã, B, C M (cÃ + dI), D + c C M B)``; a zero ``λ₀`` of G becomes
    ``g⁻¹(λ₀) = (dλ₀ − b)/(a − cλ₀)``. A DesignError if ``a/c`` is a pole of G."""
    n = G.n
    K = a * np.eye(n) - c * G.A
    if n and np.linalg.cond(K) > 1e12:
        raise DesignError(f"bilinear substitution: λ = {a}/{c} is a pole of the factor (cond {np.linalg.cond(K):.3g})")
    M = np.linalg.inv(K) if n else np.zeros((0, 0))
    At = M @ (d * G.A - b * np.eye(n))
    return LTI(At, G.B, G.C @ M @ (c * At + d * np.eye(n)), G.D + c * G.C @ M @ G.B, G.dt)


def zero_shift_map(dt: float, sdegzer: float, finite: bool, infinite: bool) -> tuple[float, float, float, float]:
    """``(a, b, c, d)`` of the peer's zero-shifting map ``λ = g(δ)``: discrete ``z/δ₀``; continuous the product of
    ``s − δ₀`` (finite boundary zeros) and ``1/(1 − δ₀ s)`` (infinite zeros), so that a boundary zero ``jω`` moves
    to ``g⁻¹(jω)`` and infinity to ``1/δ₀``."""
    if dt:
        return 1.0 / sdegzer, 0.0, 0.0, 1.0
    if finite and infinite:
        return 1.0, -sdegzer, -sdegzer, 1.0
    if infinite:
        return 0.0, 1.0, -sdegzer, 1.0
    return 1.0, -sdegzer, 0.0, 1.0


def wiener_hopf_normalizer(Rw: LTI, job: int, opts: NonstandardOptions | None = None,
                           sdeg: float | None = None) -> tuple[LTI, str, dict]:
    """``(N, how, parts)`` for ``nonstd = job`` in (3, 4, 5) (see :func:`noise_normalizer`): the normaliser ``N``
    (``Q ← N·Q``), the text for ``info['noise']`` and the pieces it is made of — ``split``
    (:class:`WienerHopfSplit`) and ``gamma`` (3), ``sdegzer``, ``map`` ``(a, b, c, d)`` and ``shifted`` (4),
    ``eps`` (5) — so that a caller can check the defining property of each choice."""
    opts = opts or NonstandardOptions(nonstd=job)
    what = f"nonstd = {job} ({NONSTD[job]})"
    split = wiener_hopf_split(Rw, sdeg=sdeg, what=what)
    where = (f"{split.boundary.size} zero(s) on the boundary {np.round(split.boundary, 6).tolist()}"
             + (f" and {split.n_inf} at infinity" if split.n_inf else ""))
    if job == 3:
        gamma = (split.Rwoe_inv @ Rw).hinfnorm()[0]
        if not (0 < gamma < np.inf):
            raise DesignError(f"{what}: ||Rwoe⁻¹·Rw||∞ = {gamma:.3g} is not a positive finite number")
        return (split.Rwoe_inv * (1.0 / gamma), f"Wiener–Hopf normalised (nonstd = 3): {where} kept, γ = {gamma:.3g}",
                {"split": split, "gamma": gamma})
    if job == 4:
        dz = opts.sdegzer if opts.sdegzer is not None else (0.95 if Rw.dt else -0.05)
        if (Rw.dt and not 0 < dz < 1) or (not Rw.dt and not dz < 0):
            raise DesignError(f"{what}: sdegzer must be {'in (0, 1)' if Rw.dt else 'negative'} for a "
                              f"{'discrete' if Rw.dt else 'continuous'} noise response, got {dz}")
        a, b, c, d = zero_shift_map(Rw.dt, dz, split.boundary.size > 0, split.n_inf > 0)
        shifted = bilinear_substitution(split.Rwouz, a, b, c, d)
        inv = _biproper_inverse(shifted, what)
        if not inv.is_stable(margin=0.0):
            raise DesignError(f"{what}: the shifted factor's zeros {np.round(inv.poles(), 6).tolist()} are not stable")
        return ((inv @ split.Rwoe_inv), f"Wiener–Hopf normalised (nonstd = 4): {where} shifted by sdegzer = {dz}",
                {"split": split, "sdegzer": dz, "map": (a, b, c, d), "shifted": shifted})
    peak = split.Rwouz.hinfnorm()[0]
    eps = opts.epsreg * peak
    reg = coouter_inverse_or_static(hstack([split.Rwouz, LTI.static(eps * np.eye(Rw.p), Rw.dt)])) \
        if 0 < peak < np.inf else None
    if reg is None:
        raise DesignError(f"{what}: the co-outer factor of [Rwouz  ε I] (ε = {eps:.3g}, ||Rwouz||∞ = {peak:.3g}) could "
                          f"not be computed")
    return ((reg[0] @ split.Rwoe_inv), (f"Wiener–Hopf normalised (nonstd = 5): {where} regularised, ε = {eps:.3g} = "
                                        f"epsreg·||Rwouz||∞"), {"split": split, "eps": eps})
