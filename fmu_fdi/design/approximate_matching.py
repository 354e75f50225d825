"""Approximate model matching (AMMP): the residual generator whose fault response is nearest a reference.

Find a stable proper ``Q`` that decouples u and d exactly and minimises

    γ = || Q(λ) [Gf Gw; 0 0](λ) − [Mr(λ) 0] ||,     Q(λ) [Gu Gd; I 0](λ) = 0,        (1)

in the H∞ or the H2 norm (Varga 2017, sec. 5.7, Procedure AMMS; FaultDetectionTools.jl
``ammsyn``). The steps:

1. a proper stable left null-space basis ``Q0`` of ``[Gu Gd; I 0]`` — without d,
   ``[I  −Gu]`` when Gu is stable (``Q = [X  −X Gu]`` is stable iff X is) and the left
   coprime factor ``[M̂  −N̂]`` of an observer otherwise (every admissible Q is then
   ``Y Q0`` with ``Y ∈ RH∞``); with d, the full minimal basis of
   :func:`~fmu_fdi.design.nullspace.nullspace_design`; the reduced system is
   ``G1 = Q0 [Gf Gw; 0 0]`` and (1) becomes ``min_{Y ∈ RH∞} ||Y G1 − F||``, ``F = [Mr 0]``;
2. zeros of ``G1`` at infinity (a strictly proper plant gives them) make (1) *non-standard*: its infimum is approached only by improper Y. With ``k_i`` the
   relative degree of row i of ``G1`` and ``m(s) = a/(s + a)`` (``a = −sdeg``), the rows are
   regularised, ``Ĝ = diag(m^{−k_i}) G1`` (proper, full-row-rank feedthrough), and
   ``γopt0 = min_Ŷ ||Ŷ Ĝ − F||`` is the infimum of (1). The stable proper filter
   ``Q = Ŷ diag(m^{k−k_i}) Q0`` (``k = max k_i``) then matches the updated reference
   ``M Mr`` with the diagonal updating factor ``M = m^k I`` (Varga's ``M``, normalised to
   unit DC gain, or to unit zpk gain with ``normalize='gain'``; in discrete time ``m = 1/z``,
   ``Ĝ_i = z^{k_i} G1_i``, and M is the all-pass delay ``z^{−k}``, so ``γsub = γopt0``):
   ``Q G1 − M F = M (Ŷ Ĝ − F)``, whose norm is ``γsub`` (Varga's ``gammasub``);
   ``γopt = min_Ŷ ||Ŷ Ĝ − M F||`` is the optimum of the updated problem (``gammaopt``);
3. the standard problem ``min_{Y ∈ RH∞} ||Y Ĝ − F||`` is the model-matching form of the
   general control problem with ``P = [−F  I; Ĝ  0]`` (open-loop stable, ``P22 = 0``, so a
   controller is internally stabilising iff it is stable). H∞: γ-iteration by bisection
   on the solvability of the two Riccati equations of Glover and Doyle (1988) (SLICOT
   SB10FD, SB10DD in discrete time); the central controller at the smallest feasible γ is
   Y, and its measured error equals γopt to the bisection tolerance ``reltol``. H2: the
   optimal controller (SLICOT SB10HD) after removing the feedthrough with
   ``Y0 = D_F D̂⁺`` (finite H2 norm needs ``D_F (I − D̂⁺ D̂) = 0``); H2 optimal, exact.

This is Varga's Procedure AMMS with the Nehari/least-distance step (quasi-co-outer–co-inner
factorisation, 2-block γ-iteration) replaced by the equivalent standard H∞/H2 problem on
the regularised reduced system, which SLICOT solves with orthogonal (Schur) Riccati
solvers. The optimum does not depend on the basis Q0: ``Q0`` spans every admissible filter.

Rows of ``Q0`` that see neither faults nor noise (``G1`` of normal rank below its rows,
e.g. more basis rows than fault and noise columns) are dropped by an orthonormal
compression when ``G1``'s column space is constant (:func:`compress_rows`).

Not covered: zeros of ``G1`` on the imaginary axis / unit circle, infinite zeros that are
not row-aligned (a rank-deficient leading-coefficient matrix after row regularisation —
it would need an interactor matrix), a rank-deficient ``G1`` whose column space varies
with frequency, and
H2 in discrete time (SLICOT SB10ED is not wrapped by slycot): each is refused with a
:class:`~fmu_fdi.errors.DesignError` that names it.

References
----------
A. Varga, *Solving Fault Diagnosis Problems*, Springer 2017, sec. 5.7 (Procedure AMMS),
Examples 5.14–5.17. A. Varga, Integrated computational algorithm for solving H∞-optimal
FDI problems, IFAC World Congress 2011. K. Glover and J. C. Doyle, State-space formulae for
all stabilizing controllers that satisfy an H∞-norm bound, Systems & Control Letters 11,
1988. K. Zhou, J. C. Doyle and K. Glover, *Robust and Optimal Control*, 1996, chs. 14, 17.
"""
from __future__ import annotations

from math import comb

import numpy as np
import scipy.linalg as sla

from ..errors import DesignError
from ..generator import ResidualGenerator
from ..linalg import EPS, single_blas_thread
from ..lti import LTI, blockdiag, hstack
from ..model import FDIModel
from .postconditions import DEC_TOL, check_generator


@single_blas_thread
def approximate_model_matching(model: FDIModel, Mr, *, norm: str = "inf", sdeg: float | None = None,
                               normalize: str = "dcgain", reltol: float = 1e-4, smarg: float | None = None,
                               dec_tol: float = DEC_TOL) -> ResidualGenerator:
    """H∞ or H2 optimal approximate model matching: ``min ||Q [Gf Gw; 0 0] − [Mr 0]||`` with ``Q [Gu Gd; I 0] = 0``.

    Parameters
    ----------
    model : FDIModel
    Mr : LTI or python-control system
        Reference fault-to-residual map (residuals × fault columns), proper and stable.
    norm : {'inf', '2'}
        H∞ (default) or H2 norm of the model-matching error (noise response included).
    sdeg : float, optional
        Pole ``−a`` of the updating factor ``M = (a/(s + a))^k I`` used when the reduced
        system has zeros at infinity (default −1).
    normalize : {'dcgain', 'gain'}
        ``M(0) = I`` (default; then also ``||M||∞ = 1``) or unit zpk gain ``1/(s + a)^k``
        (Varga's ``normalize = "gain"``).
    reltol : float
        Relative accuracy of the H∞ γ-iteration: the returned filter's error is within
        ``[γ_lo, γ_lo (1 + reltol)]`` where γ_lo is infeasible.
    smarg, dec_tol : float, optional
        Stability margin and decoupling tolerance of the post-conditions (:mod:`.postconditions`).

    Returns
    -------
    ResidualGenerator
        ``info``: ``norm``, ``gamma_opt`` (optimum of the problem solved: (1) if standard,
        the updated problem with ``M Mr`` if not), ``gamma_opt0`` (infimum of (1)),
        ``gamma_sub`` and ``error`` (the error norm measured on the returned filter against
        ``M Mr``), ``gamma_bracket`` (H∞: the bisection's infeasible/feasible levels),
        ``standard``, ``M`` (LTI, identity if standard), ``row_degrees`` (``k_i``), ``order``,
        ``postconditions``.

    Raises
    ------
    DesignError
        Mr of the wrong shape, sample time, unstable or improper; no residual decouples u
        and d; a non-standard problem outside the covered cases; an H2 problem whose
        error has a feedthrough no filter can cancel (infinite H2 norm); a design that
        fails its post-conditions.
    """
    if norm not in ("inf", "2"):
        raise DesignError(f"norm must be 'inf' or '2', got {norm!r}")
    if normalize not in ("dcgain", "gain"):
        raise DesignError(f"normalize must be 'dcgain' or 'gain', got {normalize!r}")
    if not (0 < reltol < 1):
        raise DesignError(f"reltol must lie in (0, 1), got {reltol!r}")
    Mr = reference(model, Mr)
    dt = model.dt
    if norm == "2" and dt:
        raise DesignError("norm='2' is implemented for continuous-time models only (the discrete H2 synthesis, "
                          "SLICOT SB10ED, is not available through slycot): use norm='inf'")
    sdeg = -1.0 if sdeg is None else float(sdeg)
    if not dt and not (np.isfinite(sdeg) and sdeg < 0):
        raise DesignError(f"sdeg must be negative (the pole of the updating factor M), got {sdeg!r}")
    Q0, G1 = reduced_system(model)
    Q0, G1 = compress_rows(Q0, G1)
    q, mfw = G1.p, G1.m
    F = hstack([Mr, LTI.zero(Mr.p, model.nw, dt)]) if model.nw else Mr
    a = -float(sdeg)
    Gh, k = regularise(G1, a)
    standard = not np.any(k)
    _check_boundary_zeros(Gh)
    kmax = int(max(k, default=0))
    Y, info = solve_standard(Gh, F, norm, reltol)
    gamma_opt0 = info["gamma"]
    scale = a ** -kmax if normalize == "gain" and not dt else 1.0
    if standard:
        M = LTI.static(np.eye(Mr.p), dt)
        Q = (Y @ Q0)
    else:
        M = scale * lowpass_power(a, kmax, Mr.p, dt)
        Q = scale * (Y @ blockdiag([lowpass_power(a, kmax - int(ki), 1, dt) for ki in k]) @ Q0)
    Q = Q.minreal()
    gen = ResidualGenerator(Q, model, "approximate_model_matching")
    check_generator(gen, decouple=("u", "d"), faults=[], smarg=smarg, dec_tol=dec_tol)
    MF = M @ F if M.n else M.D @ F
    err = _norm((Q @ fault_noise_map(model) - MF).minreal(), norm)
    if standard:
        gamma_opt = gamma_opt0
        expected = gamma_opt0
    else:
        gamma_opt = solve_standard(Gh, MF, norm, reltol)[1]["gamma"]
        expected = scale * _norm((lowpass_power(a, kmax, Mr.p, dt) @ (Y @ Gh - F)).minreal(), norm)
    # the error of the returned filter must be the one the design computed: rounding of the
    # realisations (minreal, products of order ≤ 3n) is ~1e-9 relative; anything larger is a bug
    tol = 1e-6 * max(expected, float(_norm(MF, norm)), 1e-300)
    if abs(err - expected) > tol:
        raise DesignError(f"approximate_model_matching: the returned filter's error {err:.9g} differs from the "
                          f"designed {expected:.9g} by more than {tol:.3g}: the realisation lost accuracy")
    gen.info.update({
        "norm": norm, "standard": bool(standard), "gamma_opt": float(gamma_opt), "gamma_opt0": float(gamma_opt0),
        "gamma_sub": float(err), "error": float(err), "M": M, "row_degrees": [int(x) for x in k],
        "order": int(Q.n), "poles": np.asarray(Q.poles()).tolist(), "reduced_rows": int(q), "reduced_inputs": mfw,
    })
    if "bracket" in info:
        gen.info["gamma_bracket"] = [float(x) for x in info["bracket"]]
    return gen


# ----------------------------------------------------------------------------- inputs
def reference(model: FDIModel, Mr) -> LTI:
    """Mr as an LTI in the model's time base, validated (shape, proper, stable)."""
    if not isinstance(Mr, LTI):
        try:
            Mr = LTI.from_control(Mr)
        except ValueError as exc:
            raise DesignError(f"Mr must be a proper system: {exc}") from None
        except TypeError as exc:
            raise DesignError(f"Mr: {exc}") from None
    if Mr.m != model.nf:
        raise DesignError(f"Mr must have {model.nf} inputs (the fault columns {model.fault_names}), got {Mr.m}")
    if Mr.p < 1:
        raise DesignError("Mr must have at least one output (residual)")
    if Mr.n and abs(Mr.dt - model.dt) > 1e-12 * max(1.0, model.dt):
        raise DesignError(f"Mr has sample time {Mr.dt} but the model has {model.dt}")
    Mr = LTI(Mr.A, Mr.B, Mr.C, Mr.D, model.dt)
    if Mr.n:
        Mr = Mr.minreal()
        if not Mr.is_stable():
            bad = Mr.poles()
            worst = float(np.max(np.abs(bad))) if model.dt else float(np.max(bad.real))
            what = "largest |pole|" if model.dt else "largest Re(pole)"
            raise DesignError(f"Mr must be stable ({what} = {worst:.6g}): every filter's fault response Q Gf is")
    return Mr


def fault_noise_map(model: FDIModel) -> LTI:
    """``[Gf Gw; 0 0]``: from [f; w] to [y; u] (the columns of F = [Mr 0])."""
    Ge = model.augmented()
    sl = model.group_slices()
    cols = np.r_[np.arange(sl["f"].start, sl["f"].stop), np.arange(sl["w"].start, sl["w"].stop)]
    return Ge[:, cols]


def reduced_system(model: FDIModel) -> tuple[LTI, LTI]:
    """``(Q0, G1)``: a proper stable left null-space basis of ``[Gu Gd; I 0]`` and ``Q0 [Gf Gw; 0 0]``."""
    dt = model.dt
    if model.nd == 0 and (model.nu == 0 or LTI(model.A, model.Bu, model.C, model.Du, dt).is_stable()):
        # Gu stable: Q0 = [I  −Gu] (Q = [X  −X Gu] is stable iff X is), the identity without u
        if model.nu == 0:
            Q0 = LTI.static(np.eye(model.ny), dt)
        else:
            Q0 = LTI(model.A, np.hstack([np.zeros((model.n, model.ny)), model.Bu]), -model.C,
                     np.hstack([np.eye(model.ny), -model.Du]), dt)
        return Q0, model.lti("f", "w")
    if model.nd == 0:
        from .coprime import _factor_filter

        try:
            Q0, _ = _factor_filter(model, None, False)
        except DesignError as exc:
            raise DesignError(f"approximate_model_matching: no observer-based basis: {exc}") from None
        # output error e = x − x̂ of the observer: G1 = (A − LC, [Bf − L Df, Bw − L Dw], C, [Df Dw])
        L = Q0.B[:, :model.ny]
        B = np.hstack([model.Bf, model.Bw])
        D = np.hstack([model.Df, model.Dw])
        return Q0, LTI(Q0.A, B - L @ D, model.C, D, dt)
    from .nullspace import nullspace_design

    try:
        basis = nullspace_design(model, rdim="all", noise="ignore", FDtol=0.0)
    except DesignError as exc:
        raise DesignError(f"approximate_model_matching: no residual decouples u and d: {exc}") from None
    Q0 = basis.Q
    return Q0, (Q0 @ fault_noise_map(model)).minreal()


# ------------------------------------------------------------------- regularisation
def compress_rows(Q0: LTI, G1: LTI) -> tuple[LTI, LTI]:
    """Drop the residual directions of ``Q0`` that see neither faults nor noise.

    When ``G1`` has normal rank ``r`` below its ``q`` rows, the errors ``Y G1`` depend only on
    the column space of ``G1``. If that space is constant — the real stack
    ``[G1(λ1) … G1(λk)]`` at points off the axes has rank r too — an orthonormal ``T`` (r × q)
    spanning it gives ``G1 = Tᵀ T G1``, so ``{Y G1} = {Y' (T G1)}`` exactly and the problem
    keeps its optimum with the full-row-rank ``T G1`` and the basis ``T Q0``. Ranks: singular
    values above ``1e-10`` times the largest.
    """
    rng = np.random.default_rng(7)
    lam = (np.exp(1j * rng.uniform(0.3, 2.8, 4)) * 0.7 if G1.dt else rng.uniform(0.3, 2, 4) * (1 + 1j))
    vals = [G1.evalfr(l) for l in lam]
    r = max(_rank(V) for V in vals)
    if r == G1.p:
        return Q0, G1
    if r == 0:
        raise DesignError("the reduced system Q0 [Gf Gw] is zero: no residual that decouples u and d sees the "
                          "faults or the noise")
    stack = np.hstack([np.hstack([V.real, V.imag]) for V in vals])
    U, sv, _ = np.linalg.svd(stack)
    rs = _rank(stack)
    if rs > r:
        raise DesignError(f"the reduced system Q0 [Gf Gw] has normal rank {r} < {G1.p} rows and a column space "
                          f"that varies with frequency (rank {rs} over several points): this rank-deficient "
                          f"case is not covered")
    T = U[:, :r].T
    return T @ Q0, (T @ G1).minreal()


def _rank(V: np.ndarray) -> int:
    s = np.linalg.svd(V, compute_uv=False)
    return int(np.sum(s > 1e-10 * max(s[0], 1e-300))) if s.size else 0


def regularise(G1: LTI, a: float) -> tuple[LTI, np.ndarray]:
    """``(Ĝ, k)`` with ``Ĝ_i = ((s + a)/a)^{k_i} G1_i`` proper, ``k_i`` the relative degree of row i.

    ``s^j G_i = (A, B, c_i A^j, c_i A^{j−1} B)`` when the Markov parameters ``c_i A^l B``
    vanish for ``l < j − 1``; a Markov parameter is zero when it is below ``1e-10`` times
    ``||c_i|| ||A||^l ||B||`` (the size of its terms). In discrete time the factor is the
    forward shift ``z^{k_i}`` (``m = 1/z``, the updating factor a delay).
    """
    q = G1.p
    k = np.zeros(q, int)
    if G1.n == 0:
        return G1, k
    G, _ = G1.balanced()
    A, B, C, D = G.A, G.B, G.C, G.D
    nA, nB = max(np.linalg.norm(A, 2), 1e-300), max(np.linalg.norm(B, 2), 1e-300)
    scaleD = max(np.linalg.norm(D, 2), 1e-300)
    Cn, Dn = C.copy(), D.copy()
    for i in range(q):
        ci = C[i]
        nc = max(np.linalg.norm(ci), 1e-300)
        if np.linalg.norm(D[i]) > 1e-10 * max(scaleD, nc * nB):
            continue
        row = ci.copy()
        for j in range(1, G.n + 1):
            mk = row @ B  # c_i A^{j-1} B
            if np.linalg.norm(mk) > 1e-10 * nc * nA ** (j - 1) * nB:
                k[i] = j
                break
            row = row @ A
        else:
            raise DesignError(f"row {i + 1} of the reduced system Q0 [Gf Gw] is identically zero: that residual "
                              f"sees neither faults nor noise")
        powers = [ci]
        for _ in range(k[i]):
            powers.append(powers[-1] @ A)
        if G.dt:
            Cn[i], Dn[i] = powers[k[i]], powers[k[i] - 1] @ B
            continue
        Cn[i] = sum(comb(int(k[i]), j) * a ** -j * powers[j] for j in range(k[i] + 1))
        Dn[i] = comb(int(k[i]), k[i]) * a ** -int(k[i]) * (powers[k[i] - 1] @ B)
    return LTI(A, B, Cn, Dn, G.dt), k


def lowpass_power(a: float, k: int, size: int, dt: float = 0.0) -> LTI:
    """``(a/(s + a))^k I_size``, in discrete time the delay ``z^{-k} I_size`` (the identity for k = 0)."""
    if k == 0:
        return LTI.static(np.eye(size), dt)
    if dt:
        A = np.diag(np.ones(k - 1), -1)
        a = 1.0
    else:
        A = -a * np.eye(k) + np.diag(np.full(k - 1, a), -1)
    b = np.zeros((k, 1))
    b[0, 0] = a
    c = np.zeros((1, k))
    c[0, -1] = 1.0
    m = LTI(A, b, c, np.zeros((1, 1)), dt)
    return blockdiag([m] * size)


def _check_boundary_zeros(Gh: LTI) -> None:
    """Refuse zeros of Ĝ at infinity (rank-deficient D) or on the stability boundary."""
    q = Gh.p
    s = np.linalg.svd(Gh.D, compute_uv=False) if Gh.D.size else np.zeros(0)
    scale = max(Gh.scale_of(), 1e-300)
    rk = int(np.sum(s > 1e-10 * scale))
    if rk < q:
        where = "on the unit circle's outside at z = ∞" if Gh.dt else "at infinity"
        raise DesignError(f"non-standard problem not covered: after row regularisation the reduced system's "
                          f"feedthrough has rank {rk} < {q} (zeros {where} that are not row-aligned; smallest "
                          f"singular value {s.min() if s.size else 0.0:.3g} vs data size {scale:.3g})")
    if Gh.n == 0:
        return
    import slycot

    n, m = Gh.n, Gh.m
    out = slycot.ab08nd(n, m, q, Gh.A.copy(), Gh.B.copy(), Gh.C.copy(), Gh.D.copy(), equil="S")
    nu, Af, Bf = out[0], out[-2], out[-1]
    if nu == 0:
        return
    z = sla.eigvals(Af[:nu, :nu], Bf[:nu, :nu])
    z = z[np.isfinite(z)]
    dist = np.abs(np.abs(z) - 1.0) if Gh.dt else np.abs(z.real)
    bad = z[dist < 1e-7 * max(1.0, float(np.max(np.abs(z), initial=0.0)))]
    if bad.size:
        where = "on the unit circle" if Gh.dt else "on the imaginary axis"
        raise DesignError(f"non-standard problem not covered: the reduced system Q0 [Gf Gw] has zeros {where} "
                          f"({', '.join(f'{x:.4g}' for x in bad[:4])}); the optimum is not attained by a stable "
                          f"filter")


# ------------------------------------------------------------------ standard problem
def _norm(E: LTI, norm: str) -> float:
    return float(E.hinfnorm()[0]) if norm == "inf" else float(E.h2norm())


def _plant(Gh: LTI, F: LTI):
    """Generalised plant ``P = [−F  I; Ĝ  0]`` (inputs [v; r], outputs [z; y])."""
    r, q, m1 = F.p, Gh.p, F.m
    nF, nG = F.n, Gh.n
    A = sla.block_diag(F.A, Gh.A) if nF + nG else np.zeros((0, 0))
    B = np.hstack([np.vstack([F.B, Gh.B]), np.zeros((nF + nG, r))])
    C = np.vstack([np.hstack([-F.C, np.zeros((r, nG))]), np.hstack([np.zeros((q, nF)), Gh.C])])
    D = np.block([[-F.D, np.eye(r)], [Gh.D, np.zeros((q, r))]])
    return A, B, C, D, nF + nG, m1 + r, r + q, r, q


def solve_standard(Gh: LTI, F: LTI, norm: str, reltol: float) -> tuple[LTI, dict]:
    """``Y ∈ RH∞`` minimising ``||Y Ĝ − F||`` (Ĝ stable with full-row-rank feedthrough)."""
    dt = Gh.dt
    U, sv, Vt = np.linalg.svd(Gh.D, full_matrices=True)
    q = Gh.p
    Dpinv = Vt[:q].T @ np.diag(1.0 / sv[:q]) @ U.T
    Y0 = F.D @ Dpinv  # best constant at infinity: min ||Y0 D̂ − D_F|| (Parrott with full-row-rank D̂)
    dres = F.D - Y0 @ Gh.D
    if norm == "2":
        if np.linalg.norm(dres) > 1e-9 * max(np.linalg.norm(F.D), np.linalg.norm(Gh.D) * np.linalg.norm(Y0), 1e-300):
            raise DesignError(f"the H2 problem has no solution: the error's feedthrough D_F − Y D_G cannot vanish "
                              f"(smallest reachable size {np.linalg.norm(dres, 2):.3g}): use a strictly proper Mr "
                              f"(e.g. Mr·a/(s+a)) or norm='inf'")
        F1 = (F - Y0 @ Gh).minreal() if F.n or Gh.n else LTI.static(np.zeros(F.shape), dt)
        F1 = LTI(F1.A, F1.B, F1.C, np.zeros(F1.D.shape), dt)
        if F1.n == 0:
            return LTI.static(Y0, dt), {"gamma": 0.0}
        import slycot

        A, B, C, D, n, m, np_, ncon, nmeas = _plant(Gh, F1)
        try:
            Ak, Bk, Ck, Dk, _ = slycot.sb10hd(n, m, np_, ncon, nmeas, A, B, C, D)
        except Exception as exc:  # slycot raises its own error classes with SLICOT's info text
            raise DesignError(f"H2 synthesis (SLICOT SB10HD) failed: {exc}") from None
        Y = LTI(Ak, Bk, Ck, Dk, dt) + LTI.static(Y0, dt)
        return Y, {"gamma": _norm((Y @ Gh - F).minreal(), "2")}
    lo = float(np.linalg.norm(dres, 2)) if not dt else 0.0
    hi = 1.01 * float(F.hinfnorm()[0]) + 1e-12
    if F.n + Gh.n == 0:
        return LTI.static(Y0, dt), {"gamma": lo, "bracket": (lo, lo)}
    lo = max(lo, hi * 1e-9)
    best = _hinf_at(Gh, F, hi)
    if best is None:
        raise DesignError(f"H∞ synthesis failed even at γ = {hi:.6g} > ||Mr||∞ (where Q = 0 is feasible): the "
                          f"Riccati equations of the reduced problem are ill-conditioned")
    Ybest, ebest = best
    hi = min(hi, ebest * (1 + 1e-9))
    while hi > lo * (1 + reltol):
        mid = np.sqrt(lo * hi)
        got = _hinf_at(Gh, F, mid)
        if got is None:
            lo = mid
        else:
            Ybest, ebest = got
            hi = min(mid, ebest * (1 + 1e-9))
    return Ybest, {"gamma": ebest, "bracket": (min(lo, hi), hi)}


def _hinf_at(Gh: LTI, F: LTI, gamma: float):
    """The central controller for level γ and its measured error, or None if γ is infeasible."""
    import slycot

    A, B, C, D, n, m, np_, ncon, nmeas = _plant(Gh, F)
    try:
        if Gh.dt:
            Ak, Bk, Ck, Dk = slycot.sb10dd(n, m, np_, ncon, nmeas, gamma, A, B, C, D)[1:5]
        else:
            Ak, Bk, Ck, Dk, _ = slycot.sb10fd(n, m, np_, ncon, nmeas, gamma, A, B, C, D)
    except Exception:  # infeasible level (or a numerically singular Riccati solution at it)
        return None
    Y = LTI(Ak, Bk, Ck, Dk, Gh.dt)
    if not np.all(np.isfinite(Y.A)) or not Y.is_stable():
        return None
    e = _norm(Y @ Gh - F, "inf")
    if not np.isfinite(e) or e > gamma * (1 + 1e-6):
        return None
    return Y, e
