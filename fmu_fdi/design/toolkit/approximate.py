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
needs a full-row-rank feedthrough (continuous time) and no zeros on the stability boundary;
otherwise the peer's ``nonstd`` choices apply (:func:`noise_normalizer`; default: the
quasi-co-outer factor followed by a stable left coprime factor, ``nonstd = 1``).
"""
from __future__ import annotations

import functools
import inspect
from contextvars import ContextVar
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ...errors import DesignError
from ...linalg import inv_sqrtm_pd, ordered_schur, rank, sqrtm_psd
from ...lti import LTI, hstack
from .riccati_newton import FORWARD_RTOL, forward_refined, newton_refined, riccati_residual


def coouter_inverse(G: LTI) -> tuple[LTI, LTI] | None:
    """For stable ``G = Ro Ri``: return ``(Ro^{-1}, Ri)``, or None if the standard
    conditions fail (continuous time: feedthrough not of full row rank; zeros on the stability
    boundary, as :func:`_on_boundary` counts them; no stabilising Riccati solution, :func:`spectral_riccati`). In discrete time a rank-deficient feedthrough (zeros at infinity, outside the unit
    circle) is standard, as in the peer's ``goifac``: the DARE's ``DᵀD + BᵀXB`` must be invertible."""
    if G.n == 0:
        return None
    Gt = G.transpose()  # tall: inner–outer of Gt = Gi Go gives G = Go^T Gi^T
    A, B, C, D = Gt.A, Gt.B, Gt.C, Gt.D
    if not G.is_discrete and rank(D) < D.shape[1]:
        return None
    X = spectral_riccati(A, B, C, D, G.dt)
    if X is None:
        return None
    try:
        if G.is_discrete:
            Rk = D.T @ D + B.T @ X @ B
            if rank(Rk) < Rk.shape[0]:
                return None
            F = -np.linalg.solve(Rk, B.T @ X @ A + D.T @ C)
        else:
            Rk = D.T @ D
            F = -np.linalg.solve(Rk, B.T @ X + D.T @ C)
        Rh, Rhi = sqrtm_psd(Rk), inv_sqrtm_pd(Rk)
    except (np.linalg.LinAlgError, ValueError):
        return None
    Acl = A + B @ F
    closed = LTI(Acl, B @ Rhi, C + D @ F, D @ Rhi, G.dt)
    # the closed-loop poles are G's zeros (reflected into the stability region): one within ZERO_BOUNDARY_RTOL of
    # the boundary is a boundary zero that the solver perturbed (a double Hamiltonian eigenvalue moves by
    # ~sqrt(eps·||H||)), for which no stabilising solution exists — the split's case, as it counts zeros there
    if not closed.is_stable(margin=1e-9) or np.any(_on_boundary(np.linalg.eigvals(Acl), G.dt)):
        return None
    Go_inv = LTI(Acl, B @ Rhi, F, Rhi, G.dt)
    _ = Rh  # Go = (A, B, -Rh F, Rh); only its inverse is needed
    return Go_inv.transpose(), closed.transpose()


#: a Riccati solution is accepted when its residual is within this fraction of the size of the equation's terms:
#: a backward-stable solver leaves ~n·eps·cond (1e-13 at the orders met here, cond ≤ 1e3); 1e-8 (≈ sqrt(eps)
#: less a margin for the condition) separates that from a solution of another equation (a wrong subspace)
RICCATI_RTOL = 1e-8


def spectral_riccati(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, dt: float, *,
                     figures: dict | None = None, forward: bool = True) -> np.ndarray | None:
    """The stabilising solution ``X`` of the Riccati equation of the inner–outer factorisation of the tall
    ``(A, B, C, D)`` (Zhou, Doyle & Glover, Thm. 13.34; discrete: Thm. 21.26), or None when none is found:

    - continuous: ``AᵀX + XA − (XB + CᵀD)(DᵀD)⁻¹(BᵀX + DᵀC) + CᵀC = 0``;
    - discrete: ``AᵀXA − X − (AᵀXB + CᵀD)(DᵀD + BᵀXB)⁻¹(BᵀXA + DᵀC) + CᵀC = 0``.

    scipy's QZ solver of the extended pencil (Van Dooren; balanced) first. It refuses ("eigenvalues too close
    to the imaginary axis") whenever ``U₁ᴴU₂`` is not symmetric to a tenth of its own norm — a relative test
    that fails when the solution is zero to rounding: a square minimum-phase factor (``X = 0``, the factor
    its own co-outer part) whose realisation carries near pole–zero cancellations, so that the rounding of
    ``U₂`` exceeds ``spacing(1000)`` (random_case(22)'s bank rows, order 43–45, Hamiltonian eigenvalues no
    closer to the axis than 0.047). Where it refuses or its residual is off, SLICOT SB02OD (deflating
    subspaces of the same pencil) on the factored data ``C, D``. Either answer is kept only if its residual
    (:func:`.riccati_newton.riccati_residual`) is within :data:`RICCATI_RTOL` of the size of the terms. Where
    neither is, but one is finite with a stable closed loop, it is refined by Newton's method (defect correction:
    Kleinman 1968, Hewer 1971, Mehrmann & Tan 1988; exact line search, Benner & Byers 1998 —
    :func:`.riccati_newton.newton_refined`, in the coordinates of a diagonal balancing of ``A``), and the iterate
    kept only if its residual falls within :data:`RICCATI_RTOL` with the closed loop stable and ``X ⪰ 0`` to
    :data:`RICCATI_RTOL` of its norm.

    A small residual is a backward measure: on an ill-conditioned equation it can hide a large error of ``X``
    (the Kalman filter's seeded problems of tests/test_kalman_riccati.py: relative residual 2e-11, ``P`` wrong by 0.8
    of its norm — there through a factor of ``Qx`` exact only to ``eps·‖Qx‖``, which is another equation for the
    states scaled 1e-4; tests/test_riccati_forward.py).
    So an answer within :data:`RICCATI_RTOL` is also judged by a forward measure
    (:func:`.riccati_newton.forward_refined`): the loop closed with its gain ``F(X)`` has the cost ``X_F`` (filter
    form: the error covariance of the filter run with that gain), ``X_F − X`` is the forward error to first order,
    and it must be within :data:`.riccati_newton.FORWARD_RTOL` of ``X``'s scale — else Newton's full steps
    ``X ← X_F`` from it while the correction keeps reaching a new least value (:func:`.riccati_newton.forward_refined`);
    an answer they cannot bring within the line is not returned.
    ``figures`` (if given) receives the returned answer's ``residual``, ``forward`` and ``steps`` — or, on None, the
    best ``forward`` met and ``why``. ``forward=False`` leaves the forward measure to a caller that reads it on another
    form of the equation (the Kalman filter's, on its unfactored ``Qx`` in its own coordinates). That the returned
    closed loop is stable with the caller's margin (that ``X`` is the stabilising solution) is the caller's check."""
    Q, R, S = C.T @ C, D.T @ D, C.T @ D

    starts = []  # (relative residual, answer) of the direct solvers' answers outside RICCATI_RTOL
    figures = {} if figures is None else figures
    best = {"forward": np.inf}  # the refused answer closest to the forward line, for the caller's message

    def accepted(X):
        """``X`` (or its Newton refinement) if within both lines, else None."""
        got: dict = {}
        if not forward:
            return X
        X = forward_refined(A, B, Q, R, S, X, dt, FORWARD_RTOL, figures=got)
        if X is None:
            if got.get("forward", np.inf) <= best["forward"]:
                best.clear()
                best.update(got)
            return None
        res = riccati_residual(A, B, Q, R, S, X, dt)
        if res is None or not res[0] <= RICCATI_RTOL:  # a Newton step cannot raise it past the line; checked
            return None
        figures.clear()
        figures.update(got, residual=res[0])
        return X

    def residual_ok(X) -> bool:
        res = riccati_residual(A, B, Q, R, S, X, dt)
        if res is not None and not res[0] <= RICCATI_RTOL:
            starts.append((res[0], X))
        return res is not None and res[0] <= RICCATI_RTOL

    def refused():
        figures.clear()
        figures.update(best)
        return None

    try:
        X = (sla.solve_discrete_are if dt else sla.solve_continuous_are)(A, B, Q, R, s=S)
    except (np.linalg.LinAlgError, ValueError):
        X = None
    if residual_ok(X) and (X := accepted(X)) is not None:
        return X
    import slycot
    from slycot.exceptions import SlycotError

    try:
        X = slycot.sb02od(A.shape[0], B.shape[1], A.copy(), B.copy(), C.copy(), D.copy(), "D" if dt else "C",
                          p=C.shape[0], L=S.copy(), fact="B")[0]
        X = (X + X.T) / 2
    except (SlycotError, ValueError, np.linalg.LinAlgError):
        X = None
    if residual_ok(X) and (X := accepted(X)) is not None:
        return X
    # neither within both lines: Newton's method from each answer with a stable closed loop, the closer first
    for _, X0 in sorted(starts, key=lambda rx: rx[0]):
        X = newton_refined(A, B, Q, R, S, X0, dt, RICCATI_RTOL)
        if X is not None and (X := accepted(X)) is not None:
            return X
    return refused()


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

    - ``nonstd = 1`` (default): the quasi-co-outer factor ``Rwo`` (``Rw = Rwo Ri``, zeros in the closed stability
      region) followed by the stable left coprime factor the peer's ``glcf`` applies after ``Rwo⁻¹``: with the
      Wiener–Hopf split ``Rwo = Rwoe·Rwouz`` (:func:`wiener_hopf_split`), ``Rwouz`` holding exactly the zeros of
      ``Rwo`` on the boundary, outside the margin ``smarg`` and (continuous time) at infinity, and its poles placed
      at the targets of :func:`moved_zero_targets` (``poles``, then ``sdeg`` as the peer's ``eigselect``, else the
      speed of the zero), ``Ro⁻¹ = Rwoe⁻¹ = Rwouz·Rwo⁻¹`` — stable and proper, its poles the kept zeros of ``Rwo``
      and the targets, and ``Ro⁻¹Rw = Rwouz·Ri``. Any number of noise-facing rows, continuous or discrete time.
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

    Without ``nonstd`` (None): 1, falling back to 2 — said in ``how`` (``info['noise']``) with the reason — only
    where 1 cannot be computed: ``Rw`` without full row rank (more noise-facing rows than independent noise
    directions), a Riccati equation without a stabilising solution, zeros too close to the boundary to separate
    (unstable Wiener–Hopf factors) or a normaliser whose poles break the margin; if 2 fails too, no normalisation
    (the filter poles weight the noise). A chosen option that cannot handle the case raises a DesignError naming it.
    First the modes of ``Rw``'s realisation on or beyond the boundary that its transfer function does not have
    (uncontrollable, unobservable or cancelled to rounding: a plant mode the noise does not excite) are dropped
    (:func:`drop_negligible_unstable_modes`) and the rest reduced to a balanced minimal realisation
    (:func:`balanced_minimal`); every factor above is of that realisation.
    """
    from ...margin import default_smarg

    opts = options or _OPTIONS.get() or NonstandardOptions()
    if Rw.n == 0:
        return None, "weighted by the filter poles (static noise response)"
    Rw = balanced_minimal(drop_negligible_unstable_modes(Rw))
    margin = default_smarg(Rw.dt) if smarg is None else smarg
    # the standard case only without zeros on the boundary, decided on Rw's own zeros: a zero of multiplicity k
    # is computed to ~eps^(1/k), the Riccati closed loop's (a 2k-fold Hamiltonian eigenvalue) only to
    # ~eps^(1/2k) — a double axis pair came back 1e-4 off the axis and passed as a stable co-outer inverse
    fac = None if np.any(_on_boundary(transmission_zeros(Rw), Rw.dt)) else coouter_inverse(Rw)
    if fac is not None and _clear_of_boundary(fac[0].poles(), Rw.dt, margin):
        return fac[0], "co-outer normalised"
    job = opts.nonstd if opts.nonstd is not None else 1
    fallback = ""
    if job != 2:
        try:
            return wiener_hopf_normalizer(Rw, job, opts, sdeg, poles=poles, smarg=margin)[:2]
        except DesignError as exc:
            if opts.nonstd is not None:
                raise
            fallback = f"; nonstd = 1 (the default) does not apply: {exc}"
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


#: Hankel singular values below this fraction of the largest are dropped by :func:`balanced_minimal`
HSV_RTOL = 1e-12


def balanced_minimal(G: LTI) -> LTI:
    """A balanced realisation of the stable ``G`` without the states whose Hankel singular values are below
    :data:`HSV_RTOL` of the largest (SLICOT AB09AD, square-root method): the error is at most twice their sum,
    ``||G − G_r||∞ ≤ 2n·1e-12·||G||_H`` — rounding. A staircase (TB01PD) does not see near pole–zero cancellations
    in the middle of the spectrum (random_case(22)'s noise responses: order 43–46, Hankel values falling to 1e-24
    and below 1e-12 of the largest from the 16th–20th on); every normaliser built on the realisation carries its
    order. ``G`` as it is when it is static or SLICOT refuses (a mode on the boundary)."""
    if not G.n or not G.m or not G.p:
        return G
    from slycot.exceptions import SlycotError

    try:
        hsv = G.balanced_truncation()[1]
        if not hsv.size or not hsv[0] > 0:
            return G
        red, _ = G.balanced_truncation(tol=HSV_RTOL * float(hsv[0]))
    except (SlycotError, ValueError, np.linalg.LinAlgError):
        return G
    return red if red.n < G.n else G


def transmission_zeros(G: LTI) -> np.ndarray:
    """The finite invariant zeros of ``G`` (SLICOT AB08ND on the scaled system pencil ``[A − λI  B; C  D]``: the
    eigenvalues of the reduced regular pencil)."""
    if G.n == 0 or G.m == 0 or G.p == 0:
        return np.zeros(0, complex)
    import slycot

    n, m, q = G.n, G.m, G.p
    # workspace of SLICOT AB08ND's documentation (slycot's default is too small for some shapes)
    ldwork = max(1, min(q, m) + max(3 * m - 1, n), min(q, n) + max(3 * q - 1, n + q, n + m),
                 min(m, n) + max(3 * m - 1, n + m)) * 4
    out = slycot.ab08nd(n, m, q, G.A.copy(), G.B.copy(), G.C.copy(), G.D.copy(), equil="S", ldwork=ldwork)
    nu, Af, Bf = out[0], out[-2], out[-1]
    if nu == 0:
        return np.zeros(0, complex)
    z = sla.eigvals(Af[:nu, :nu], Bf[:nu, :nu])
    return z[np.isfinite(z)]


#: a co-outer inverse pole within this relative distance of the stability boundary counts as on it
BOUNDARY_RTOL = 1e-6


def _clear_of_boundary(poles: np.ndarray, dt: float, margin: float) -> bool:
    """Every pole inside the margin and at least :data:`BOUNDARY_RTOL` (relative to its modulus, at
    least 1) away from the boundary itself."""
    poles = np.asarray(poles, complex)
    if dt:
        return bool(np.all(np.abs(poles) <= min(margin, 1.0 - BOUNDARY_RTOL)))
    return bool(np.all(poles.real <= np.minimum(margin, -BOUNDARY_RTOL * np.maximum(1.0, np.abs(poles)))))


#: a group of modes outside the stability region is negligible when its residue ``||C₁||·||B₁'||`` is within this
#: fraction of ``||C||·||B||`` (the balanced realisation's): see :func:`drop_negligible_unstable_modes`
NEGLIGIBLE_RESIDUE_RTOL = 1e-6


def drop_negligible_unstable_modes(G: LTI, rtol: float = NEGLIGIBLE_RESIDUE_RTOL) -> LTI:
    """``G`` without its modes on or beyond the stability boundary when their part of ``G`` is negligible.

    The realisation is balanced (SLICOT TB01ID) and the modes on or beyond the boundary (real part
    ``≥ −BOUNDARY_RTOL·max(1, |λ|)``; discrete ``|λ| ≥ 1 − BOUNDARY_RTOL``) put first by an ordered real Schur
    form (:func:`~fmu_fdi.linalg.ordered_schur`), then decoupled by the Sylvester equation
    ``T₁₁X − XT₂₂ = −T₁₂`` (the similarity ``[I X; 0 I]``): ``G = C₁(λI − T₁₁)⁻¹B₁' + G_s`` with ``B₁' = B₁ − XB₂``
    and ``G_s = (T₂₂, B₂, C₁X + C₂, D)``. The first term goes when its residue bound ``||C₁||·||B₁'||`` is at most
    ``rtol·||C||·||B||`` — one test for a mode the input does not excite (``B₁' = 0``: a marginal plant mode the
    noise does not reach, random_case(22)'s ±2j) and for one that does not reach the output (``C₁ = 0``), and for a
    mode cancelled to rounding (both small). Otherwise ``G`` is returned as it is.

    Why ``rtol = 1e-6``: these modes are cancelled by the design, exactly in theory, to the accuracy of the
    computed zeros that cancel them — the backward error ``eps·||data||`` times the zeros' condition; a zero of
    condition up to ``1/sqrt(eps)`` (beyond it no zero is computable in double precision) leaves a residue up to
    ``sqrt(eps) ≈ 1.5e-8`` of the system's scale, and the null-space bases of approximate model matching leave
    1e-9 … 1e-7 (measured). 1e-6 is ten times the largest measured; a mode that is really there is coupled at the
    scale of the data (a residue ≥ 1e-6 of it makes ``G`` unstable in any sense that matters, and is kept)."""
    if not G.n or not G.m or not G.p:
        return G
    bal, _ = G.balanced()
    if G.dt:
        outside = lambda re, im: bool(np.hypot(re, im) >= 1.0 - BOUNDARY_RTOL)  # noqa: E731
    else:
        outside = lambda re, im: bool(re >= -BOUNDARY_RTOL * max(1.0, np.hypot(re, im)))  # noqa: E731
    T, Z, k = ordered_schur(bal.A, outside)
    if k == 0:
        return G
    B, C = Z.T @ bal.B, bal.C @ Z
    X = sla.solve_sylvester(T[:k, :k], -T[k:, k:], -T[:k, k:]) if k < G.n else np.zeros((k, 0))
    B1 = B[:k] - X @ B[k:]
    size = float(np.linalg.norm(bal.C, 2) * np.linalg.norm(bal.B, 2))
    if float(np.linalg.norm(C[:, :k], 2) * np.linalg.norm(B1, 2)) > rtol * max(size, np.finfo(float).tiny):
        return G
    return LTI(T[k:, k:], B[k:], C[:, :k] @ X + C[:, k:], G.D, G.dt)


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


def _left_infinite_step(G: LTI, choose, tol: float) -> tuple[LTI, LTI] | None:
    """One step of the extraction of zeros at infinity: ``G = L·G'`` with ``V`` an orthonormal basis of the
    left null space of ``D`` (``VᵀG`` strictly proper), ``T = diag(t_i) = choose(∞, …, ∞)`` (stable, real),
    ``c_i = |t_i|``, ``L = (I − VVᵀ) + V·c(sI − T)⁻¹·Vᵀ`` and ``G' = (I − VVᵀ)G + V·c⁻¹(s − T)·VᵀG`` =
    ``(A, B, (I−VVᵀ)C + V c⁻¹(VᵀCA − T VᵀC), (I−VVᵀ)D + V c⁻¹VᵀCB)`` — the same states, no cancellation.
    None when ``D`` has full row rank."""
    U, sv, _ = np.linalg.svd(G.D) if G.D.size else (np.eye(G.p), np.zeros(0), None)
    r = int(np.sum(sv > tol))
    if r == G.p:
        return None
    V = U[:, r:]
    k = V.shape[1]
    t = np.real(np.asarray(choose(np.full(k, np.inf, complex)), complex))[:k]
    c = np.abs(t)
    P = np.eye(G.p) - V @ V.T
    VtC = V.T @ G.C
    C2 = P @ G.C + V @ ((VtC @ G.A - t[:, None] * VtC) / c[:, None])
    D2 = P @ G.D + V @ ((VtC @ G.B) / c[:, None])
    L = LTI(np.diag(t), V.T, V * c, P, G.dt)
    return L, LTI(G.A, G.B, C2, D2, G.dt)


def _left_boundary_step(G: LTI, choose, tol: float, bad=None) -> tuple[LTI, LTI, np.ndarray] | None:
    """One step of the extraction of finite boundary zeros (``D`` of full row rank): the left zeros of
    ``[A − λI  B; C  D]`` are the uncontrollable modes of ``(A − B D⁺C, B·D_⊥)`` (orthogonal staircase, then an
    ordered real Schur form puts one boundary eigenvalue block ``Λ`` first): ``WᵀA + VᵀC = ΛWᵀ``, ``WᵀB + VᵀD = 0``
    with ``Vᵀ = −WᵀB D⁺``. Then ``L⁻¹ = I + X(λI − Λ)⁻¹Vᵀ`` gives ``G' = L⁻¹G = (A, B, C − XWᵀ, D)`` (the same
    states) and ``L = (Λ − VᵀX, Vᵀ, −X, I)``: zeros ``eig Λ`` (on the boundary), poles ``eig(Λ − VᵀX)`` = targets.
    ``bad`` (a mask of an array of zeros; default :func:`_on_boundary`) says which zeros are extracted; the
    targets are ``choose(eig Λ)``. An uncontrollable mode of ``(A, B)`` (``σ_min[A − λI  B] ≤ tol``, PBH) is a
    left zero too (an input decoupling zero, ``Vᵀ = 0``) but no zero of the transfer function, and no output
    injection moves it: it is never extracted (it was, again at every step, with ``L = I`` and a growing ``C − XWᵀ``,
    and the factors picked up spurious zeros near ``±5·10⁶j`` — random_case(22)'s marginal plant mode ±2j that
    the noise does not excite). Returns ``(L, G', eig Λ)`` or None when ``G`` has no such zero."""
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
    bad = bad or (lambda z: _on_boundary(z, G.dt))
    AB = np.hstack([A, B])

    def transmission(lam: complex) -> bool:  # not an uncontrollable mode of (A, B): PBH, rank at tol
        return bool(np.linalg.svd(AB - lam * np.eye(G.n, G.n + G.m), compute_uv=False)[-1] > tol)

    inside = (lambda re, im: bool(bad(np.array([re + 1j * im]))[0]) and transmission(re + 1j * im))
    S, Us, k = sla.schur(A22.T, output="real", sort=lambda re, im: bool(inside(re, im)))
    if k == 0:
        return None
    k = 2 if (k >= 2 and abs(S[1, 0]) > 0) else 1  # one real eigenvalue or one complex pair
    Lam = S[:k, :k].T
    Wt = Us[:, :k].T @ Tu.T
    Vt = -Wt @ B @ Dp
    zeros = np.linalg.eigvals(Lam)
    X = -_place(Lam, Vt, np.asarray(choose(zeros), complex)[:k])  # eig(Λ + Vᵀ(−X)) = targets
    L = LTI(Lam - Vt @ X, Vt, -X, np.eye(G.p), G.dt)
    return L, LTI(A, B, C - X @ Wt, D, G.dt), zeros


def _left_zero_factor(G: LTI, choose, what: str, bad=None) -> tuple[list[LTI], LTI, list, int]:
    """``G = L₁⋯L_k·G'`` (stable full-row-rank continuous-time ``G``): the ``L_i`` hold the zeros of ``G`` at
    infinity and the finite ones ``bad`` marks (default: on the imaginary axis); ``G'`` has neither (its new zeros
    are the ``L_i``'s poles, ``choose(zeros)`` — :func:`_left_infinite_step`, :func:`_left_boundary_step`).
    Returns ``(Ls, G', the finite zeros extracted, number of infinite zeros)``."""
    Ls, found, n_inf = [], [], 0
    tol = _rank_tol(np.block([[G.A, G.B], [G.C, G.D]]))
    for _ in range(2 * (G.n + G.p) + 2):
        step = _left_infinite_step(G, choose, tol)
        if step is not None:
            Ls.append(step[0])
            n_inf += step[0].n
            G = step[1]
            continue
        step = _left_boundary_step(G, choose, tol, bad)
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
    """``G⁻¹ = (A − B D⁻¹C, B D⁻¹, −D⁻¹C, D⁻¹)`` of a square biproper ``G``; a DesignError if ``D`` is singular.
    ``D⁻¹`` is applied through ``D = QR`` (triangular solves; ``B D⁻¹ = (Q R⁻ᵀ Bᵀ)ᵀ``), never formed by ``inv``."""
    sv = np.linalg.svd(G.D, compute_uv=False)
    if sv.size == 0 or sv[-1] <= 1e-12 * max(1.0, sv[0]):
        raise DesignError(f"{what}: the factor to invert is not biproper (feedthrough singular values "
                          f"{np.round(sv, 14).tolist()})")
    Qd, Rd = np.linalg.qr(G.D)
    DiC = sla.solve_triangular(Rd, Qd.T @ G.C)
    BDi = (Qd @ sla.solve_triangular(Rd, G.B.T, trans="T")).T
    Di = sla.solve_triangular(Rd, Qd.T)
    return LTI(G.A - G.B @ DiC, BDi, -DiC, Di, G.dt)


def _split_targets(Rw: LTI, sdeg):
    """``choose`` of the extraction factors of :func:`wiener_hopf_split` (continuous time): every zero to ``sdeg``
    if given, else to the speed of Rw's poles, a complex pair to two distinct values."""
    if sdeg is not None and sdeg < 0:
        base = float(sdeg)
    else:
        eig = np.abs(np.linalg.eigvals(Rw.A)) if Rw.n else np.ones(1)
        base = -max(float(np.median(eig)), 1e-3)

    def choose(zeros):
        zeros = np.asarray(zeros, complex)
        if zeros.size == 2 and np.isfinite(zeros[0]) and abs(zeros[0].imag) > 0:
            return np.array([base, 1.1 * base], complex)  # a complex pair: two distinct real values
        return np.full(zeros.size, base, complex)

    return choose


#: the Cayley map between the unit disc and the left half plane (z = −1 ↔ s = ∞), with its inverse
CAYLEY_TO_S = (1.0, -1.0, 1.0, 1.0)   # s = (z − 1)/(z + 1), as (a, b, c, d) of bilinear_substitution: z = g(s)
CAYLEY_TO_Z = (1.0, 1.0, -1.0, 1.0)   # z = (1 + s)/(1 − s)


def _z_of_s(s) -> np.ndarray:
    s = np.asarray(s, complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isinf(s), -1.0 + 0j, (1.0 + s) / (1.0 - s))


def _s_of_z(z) -> np.ndarray:
    z = np.asarray(z, complex)
    return (z - 1.0) / (z + 1.0)


def wiener_hopf_split(Rw: LTI, *, sdeg: float | None = None, what: str = "nonstd", choose=None,
                      bad=None) -> WienerHopfSplit:
    """The Wiener–Hopf split :class:`WienerHopfSplit` of a stable ``Rw`` of full row rank.

    1. ``Rw = L_b·Rw'`` (:func:`_left_zero_factor`): ``L_b`` holds the boundary and infinite zeros, ``Rw'`` has a
       full-row-rank feedthrough and no boundary zero, so its co-outer factor ``Ro'`` exists (:func:`coouter_inverse`,
       Riccati); ``Rwo = L_b·Ro'`` is the quasi-co-outer factor (``Rw Rw~ = Rwo Rwo~``; the poles of ``L_b`` cancel).
    2. The same extraction on ``Rwoᵀ`` gives the right factor: ``Rwoᵀ = Rwouzᵀ·Rwoeᵀ``; the poles of ``Rwouz`` —
       the zeros of ``Rwoe`` that replace the extracted ones — are ``choose(zeros)`` (default
       :func:`_split_targets`), and ``bad`` (a mask of an array of zeros) says which finite zeros of ``Rwo`` go to
       ``Rwouz`` (default: those on the boundary, :func:`_on_boundary`).

    Discrete time: steps 1–2 on the continuous-time image ``Rw((1 + s)/(1 − s))`` (the Cayley map takes the unit
    circle to the imaginary axis and the disc to the left half plane, so co-inner, co-outer and stable factors
    stay so), the factors mapped back with ``s = (z − 1)/(z + 1)``: a rank-deficient feedthrough (zeros at
    ``z = ∞``, outside the disc) needs no special case, and a zero at ``z = −1`` is the image's zero at infinity
    (reported among ``boundary``; ``n_inf = 0``). ``choose`` and ``bad`` then act on ``z``.
    """
    lam = 0.37 + 0.91j if not Rw.dt else 0.3 + 0.4j  # a point off the boundary and away from typical zeros
    if Rw.p > Rw.m or rank(Rw.evalfr(lam)) < Rw.p:
        raise DesignError(f"{what}: the noise response must have full row rank (here {Rw.p} rows, {Rw.m} noise inputs, "
                          f"rank {rank(Rw.evalfr(lam)) if Rw.p <= Rw.m else Rw.m} at λ = {lam})")
    if Rw.dt:
        image = bilinear_substitution(Rw, *CAYLEY_TO_Z)
        image = LTI(image.A, image.B, image.C, image.D, 0.0)
        ch = None if choose is None else (lambda s: _s_of_z(choose(_z_of_s(s))))
        bd = None if bad is None else (lambda s: _on_boundary(s, 0.0) | np.asarray(bad(_z_of_s(s)), bool))
        sp = wiener_hopf_split(image, what=what, choose=ch, bad=bd)
        back = [bilinear_substitution(LTI(X.A, X.B, X.C, X.D, Rw.dt), *CAYLEY_TO_S) for X in (sp.Rwoe_inv, sp.Rwouz)]
        zb = np.concatenate([_z_of_s(sp.boundary), -np.ones(sp.n_inf, complex)])
        return WienerHopfSplit(back[0], back[1], zb, 0)
    internal = _split_targets(Rw, sdeg)
    Lb, Rw1, _, _ = _left_zero_factor(Rw, internal, what)
    fac = coouter_inverse_or_static(Rw1)
    if fac is None:
        raise DesignError(f"{what}: the noise response without its boundary zeros has no co-outer factor (the "
                          f"Riccati equation has no stabilising solution; order {Rw1.n}, {Rw1.p} rows)")
    Ro1 = _biproper_inverse(fac[0], what)
    Rwo = (_product(Lb, Rw.p, Rw.dt) @ Ro1).minreal()
    Lt, Et, zb, n_inf = _left_zero_factor(Rwo.transpose(), choose or internal, what, bad)
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


def moved_zero_targets(Rw: LTI, *, poles=None, sdeg: float | None = None, smarg: float | None = None):
    """``choose(zeros) ↦ targets`` of ``nonstd = 1``: where the stable left coprime factor after ``Rwo⁻¹`` puts the
    poles that ``Rwo``'s boundary, margin-violating and (continuous time) infinite zeros give ``Rwo⁻¹`` — the
    rule of the peer's ``glcf`` (DescriptorSystems.jl ``eigselect1``/``eigselect2``). ``zeros``: one real zero,
    one complex pair, or ``k`` zeros at infinity (``inf``).

    - ``poles`` given: the nearest unused one of them (a real one for a real or infinite zero — the reference
      for infinity is ``sdeg`` —, a conjugate pair for a pair), as long as any is left;
    - ``sdeg`` given: a real or infinite zero to ``sdeg``, a pair to ``sdeg ± j·Im z`` (continuous) or to
      ``sdeg·z/|z|`` (discrete);
    - neither: the speed of the zero — ``-max(|Re z|, ζ|z|) + j Im z`` with ``ζ =`` :data:`.stable_factor.MOVED_DAMPING`
      (continuous; in discrete time through ``s = ln(z)/dt``), and for ``z = 0``, ``z = 1`` and infinity the median
      speed of Rw's poles, a target outside the margin moved onto ``smarg`` less 1e-3 — the rule the project's own
      :func:`.stable_factor.moved_pole_targets` applies without ``sdeg``. The peer's default is its ``sdeg = -0.05``
      (``0.95`` discrete), which puts a lightly damped pole ``-0.05 ± j·Im z`` in the filter whatever the plant's
      speed; pass ``sdeg=-0.05`` for it (it trades that ringing for a larger gap when ``Rw`` has axis zeros).

    A given ``poles``/``sdeg`` target outside the margin is a DesignError naming it.
    """
    from ...margin import default_smarg, outside_margin
    from .stable_factor import MOVED_DAMPING

    dt = float(Rw.dt)
    margin = default_smarg(dt) if smarg is None else float(smarg)
    pool = list(np.atleast_1d(np.asarray(poles, complex))) if poles is not None else []
    bad_given = [p for p in pool if outside_margin(np.array([p]), dt, margin)[0]]
    if bad_given or (sdeg is not None and outside_margin(np.array([sdeg]), dt, margin)[0]):
        raise DesignError(f"nonstd = 1: the targets of the moved zeros of the noise factor (poles {bad_given}, sdeg = "
                          f"{sdeg}) must lie inside the stability margin smarg = {margin:g}")
    eig = np.linalg.eigvals(Rw.A).astype(complex) if Rw.n else np.zeros(0, complex)
    speeds = np.abs(np.log(eig[np.abs(eig) > 0]) / dt) if dt else np.abs(eig)
    speeds = speeds[speeds > 1e-6 * max(1.0, float(np.max(speeds, initial=0.0)))]
    ref = float(np.median(speeds)) if speeds.size else 1.0
    beta = margin * (1 - 1e-3) if dt else margin - 1e-3 * max(1.0, abs(margin))

    def speed_rule(z: complex) -> complex:  # continuous-time s
        if not np.isfinite(z) or abs(z) <= 1e-9 * ref:
            return complex(-ref)
        return complex(-max(abs(z.real), MOVED_DAMPING * abs(z)), z.imag)

    def rule(z: complex) -> complex:
        if sdeg is not None:
            if dt:
                return complex(sdeg) if z.imag == 0 else complex(sdeg * z / abs(z))
            return complex(sdeg, 0.0 if not np.isfinite(z) else z.imag)
        if not dt:
            t = speed_rule(z)
            return complex(min(t.real, beta), t.imag)
        st = speed_rule(complex(np.log(complex(z))) / dt)
        t = complex(np.sign(z.real) * np.exp(st.real * dt)) if z.imag == 0 else complex(np.exp(st * dt))
        return t if abs(t) <= beta else t * beta / abs(t)

    def nearest(ref_point: complex, real: bool):
        cands = [i for i, p in enumerate(pool) if (p.imag == 0) == real and (real or p.imag > 0)]
        if not cands:
            return None
        i = min(cands, key=lambda j: abs(pool[j] - ref_point))
        t = pool.pop(i)
        if not real:
            pool.pop(min((j for j, p in enumerate(pool) if p.imag < 0), key=lambda j: abs(pool[j] - np.conj(t))))
        return t

    def choose(zeros) -> np.ndarray:
        zeros = np.asarray(zeros, complex)
        if zeros.size == 2 and np.isfinite(zeros[0]) and abs(zeros[0].imag) > 0:
            z = zeros[0] if zeros[0].imag > 0 else zeros[1]
            t = nearest(z, real=False)
            t = rule(z) if t is None else t
            return np.array([t, np.conj(t)] if zeros[0].imag > 0 else [np.conj(t), t], complex)
        out = []
        for z in zeros:
            z = complex(z)
            t = nearest(z.real if np.isfinite(z) else rule(z), real=True)
            out.append(rule(z) if t is None else t)
        return np.array(out, complex)

    return choose


def wiener_hopf_normalizer(Rw: LTI, job: int, opts: NonstandardOptions | None = None, sdeg: float | None = None,
                           *, poles=None, smarg: float | None = None) -> tuple[LTI, str, dict]:
    """``(N, how, parts)`` for ``nonstd = job`` in (1, 3, 4, 5) (see :func:`noise_normalizer`): the normaliser ``N``
    (``Q ← N·Q``), the text for ``info['noise']`` and the pieces it is made of — ``split``
    (:class:`WienerHopfSplit`; for 1 with ``Rwouz``'s poles at :func:`moved_zero_targets`, ``targets``), ``gamma``
    (3), ``sdegzer``, ``map`` ``(a, b, c, d)`` and ``shifted`` (4), ``eps`` (5) — so that a caller can check the
    defining property of each choice."""
    from ...margin import default_smarg, outside_margin

    opts = opts or NonstandardOptions(nonstd=job)
    what = f"nonstd = {job} ({NONSTD[job]})"
    Rw = drop_negligible_unstable_modes(Rw)  # (idempotent; noise_normalizer has done it already)
    if job == 1:
        margin = default_smarg(Rw.dt) if smarg is None else float(smarg)
        split = wiener_hopf_split(Rw, sdeg=sdeg, what=what,
                                  choose=moved_zero_targets(Rw, poles=poles, sdeg=sdeg, smarg=margin),
                                  bad=lambda z: _on_boundary(z, Rw.dt) | outside_margin(z, Rw.dt, margin))
        N, moved = split.Rwoe_inv, np.sort_complex(split.Rwouz.poles())
        if not _clear_of_boundary(N.poles(), Rw.dt, margin):
            raise DesignError(f"{what}: the normaliser's poles {np.round(N.poles(), 6).tolist()} break the margin "
                              f"smarg = {margin:g}")
        where = (f"{split.boundary.size} zero(s) on or beyond the margin {np.round(split.boundary, 6).tolist()}"
                 + (f" and {split.n_inf} at infinity" if split.n_inf else ""))
        return N, (f"quasi-co-outer normalised (nonstd = 1): {where} replaced by {np.round(moved, 6).tolist()}"), \
            {"split": split, "targets": moved}
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
