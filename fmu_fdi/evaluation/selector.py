"""The threshold selector: adaptive thresholds from model uncertainty (Frank, section 7).

With plant uncertainty ``Gu → Gu + ΔGu`` an exact residual generator
(``Qy Gu + Qu = 0``) produces ``r = Qy ΔGu u`` without any fault (Frank, eq. 12). A
fixed threshold tuned on the nominal plant either misses faults or raises false alarms
when u is large. Frank's adaptive threshold grows with the input:

    J_th(k) = J_th,0 + a · ||u||_(window)(k).

Given the uncertainty as a set of plants ``{G_i}`` (vertices and/or samples of a
parameter box, or measurement gain errors), ``H_i = Qy (G_i - G)`` is known for each,
and the selector picks the bound that matches the residual's evaluation function:

``ewrms`` (exponentially weighted RMS, forgetting λ) — rigorous ℓ2 bound.
    With ``r̃(k) = λ^{-k/2} r(k)``, ``ũ(k) = λ^{-k/2} u(k)`` the system is
    ``H̃(z) = H(√λ z)``, so ``Σ λ^{k-i} ||r(i)||² ≤ ||H̃||∞² Σ λ^{k-i} ||u(i)||²`` from zero
    initial state, for every k: ``a = max_i sup_{|z|=√λ} σ̄(H_i(z))`` and
    ``J_th = J0 + a · ewrms(||u||)`` never lets ``ewrms(r)`` of any plant in the set exceed it.
    (Requires every pole of ``H_i`` inside radius √λ.)
``rms`` (sliding window of N samples) — Frank's frequency-domain bound
    ``a = max_i sup_ω σ̄(H_i(e^{jω}))`` (or ``sup_ω σ̄(Qy) δ_u(ω)`` for a frequency bound
    δ_u). Inputs of the last N+M samples are covered exactly (``||(H u_R)_W|| ≤ a ||u_R||``),
    so the input window is extended by the settling length M of ``H_i``; the response to
    older inputs, at most ``tail_tol`` of the impulse response's ℓ1 norm, is neglected.
``norm``, ``peak``, ``narendra`` — rigorous ℓ∞ majorant.
    ``||r(k)|| ≤ Σ_{j<M} m_j ||u(k-j)|| + t · max_{i≤k-M} ||u(i)||`` with
    ``m_j = max_i ||h_i(j)||`` and the tail ``t = max_i Σ_{j≥M} ||h_i(j)||``; these
    evaluators are monotone (and the Narendra filter linear with non-negative weights),
    so evaluating the majorant with the same function bounds the evaluation of r.

The guarantee holds for the plants in the set. For an uncertainty that enters affinely
(e.g. sensor gain errors ``y_m = (I + Δ) y``, ``|Δ_ii| ≤ δ``) the norms are convex in
the parameters and the vertices suffice; for other parameter boxes the set must be
dense enough, and ``margin`` (default 1) multiplies the bound. ``J0`` must cover the
unknown inputs and noise (and the rounding of an exact design): any positive number
for an exact, noise-free design.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import DesignError
from ..generator import ResidualGenerator
from ..lti import LTI, frequency_grid
from ..model import FDIModel


@dataclass
class ThresholdDesign:
    """A threshold for the runtime plus what it guarantees."""

    spec: dict
    bound: str
    guarantee: str
    details: dict = field(default_factory=dict)


def _discrete_plant(p, Ts: float) -> LTI:
    G = p.lti("u") if isinstance(p, FDIModel) else p
    if not isinstance(G, LTI):
        G = LTI.from_control(G)
    if G.is_discrete:
        if abs(G.dt - Ts) > 1e-12 * Ts:
            raise DesignError(f"plant sample time {G.dt} differs from the diagnoser's {Ts}")
        return G
    return G.to_discrete(Ts)


def sensor_gain_plants(model: FDIModel, delta) -> list[LTI]:
    """The 2^p vertex plants ``(I + Δ) Gu`` of measurement gain errors ``|Δ_ii| ≤ delta_i``."""
    delta = np.broadcast_to(np.asarray(delta, float), (model.ny,))
    G = model.lti("u")
    out = []
    for signs in np.array(np.meshgrid(*[[-1.0, 1.0]] * model.ny)).reshape(model.ny, -1).T:
        out.append(np.diag(1.0 + signs * delta) @ G)
    return out


def _power_sum_bound(A: np.ndarray) -> float:
    """Rigorous ``Σ_{j≥0} ||A^j||_2`` for a stable A via the Lyapunov function of
    ``Aᵀ P A - P = -I``: ``||A^j|| ≤ sqrt(κ(P)) q^j`` with ``q = sqrt(1 - 1/λmax(P))``."""
    import scipy.linalg as sla

    P = sla.solve_discrete_lyapunov(A.T, np.eye(A.shape[0]))
    w = np.linalg.eigvalsh((P + P.T) / 2)
    q = np.sqrt(max(0.0, 1.0 - 1.0 / w[-1]))
    return float(np.sqrt(w[-1] / w[0]) / (1.0 - q))


def impulse_norms(H: LTI, tail_tol: float, max_taps: int) -> tuple[np.ndarray, float]:
    """``||h(j)||_2`` for j < M and a rigorous bound on ``Σ_{j≥M} ||h(j)||``.

    M is the settling length: the shortest prefix holding all but ``tail_tol`` of the
    impulse response's ℓ1 norm. Beyond the simulated horizon K the tail is bounded by
    ``||C|| Σ_j ||A^j|| ||A^K B||`` (:func:`_power_sum_bound`).
    """
    n = H.n
    if n and np.max(np.abs(H.poles())) >= 1.0:
        raise DesignError(f"Qy ΔG has a pole of modulus {np.max(np.abs(H.poles())):.6g} >= 1: "
                          f"the uncertain plant is not stable")
    norms = [np.linalg.norm(H.D, 2)]
    if n:
        S = _power_sum_bound(H.A)
        Cn = np.linalg.norm(H.C, 2)
        X = H.B.copy()
        far = 0.0
        running = norms[0]  # sum(norms) in the same order, kept as it grows (not re-added per tap: O(K²))
        taps, chunk, done = 0, 64, False
        while taps < max_taps and not done:
            # the taps C A^j B and the states A^(j+1) B of a chunk, then their 2-norms in one batched SVD
            # (the same LAPACK call per matrix as one norm at a time); stop at the same tap as tap by tap
            k = min(chunk, max_taps - taps)
            dtype = np.result_type(H.A, H.B, H.C)
            hs, xs = np.empty((k, *H.D.shape), dtype), np.empty((k, *X.shape), dtype)
            for i in range(k):
                hs[i] = H.C @ X
                X = H.A @ X
                xs[i] = X
            hn, xn = np.linalg.norm(hs, 2, axis=(1, 2)), np.linalg.norm(xs, 2, axis=(1, 2))
            for i in range(k):
                norms.append(hn[i])
                running += hn[i]
                far = Cn * S * xn[i]
                if far <= 1e-3 * tail_tol * running:
                    done = True
                    break
            taps, chunk = taps + k, min(2 * chunk, 1024)
    else:
        far = 0.0
    norms = np.array(norms)
    total = norms.sum() + far
    csum = np.cumsum(norms[::-1])[::-1] + far  # csum[j] bounds Σ_{i≥j} ||h(i)||
    inside = np.flatnonzero(csum <= tail_tol * total)
    M = int(inside[0]) if inside.size else len(norms)
    tail = float(csum[M]) if M < len(norms) else float(far)
    return norms[:M], tail


def threshold_selector(gen: ResidualGenerator, evaluation: dict, *, J0: float, plants=None, delta_u=None,
                       Ts: float | None = None, margin: float = 1.0, tail_tol: float = 1e-3,
                       max_taps: int = 5000, bound: str = "auto") -> ThresholdDesign:
    """Adaptive threshold ``J_th = J0 + a ||u||`` covering every plant in an uncertainty set.

    Parameters
    ----------
    gen : ResidualGenerator
        An exact generator (continuous generators are discretised with ``Ts``).
    evaluation : dict
        The evaluator spec of the residual group (see :mod:`fmu_fdi.runtime.evaluation`).
    J0 : float
        Offset covering noise, unknown inputs and rounding (> 0).
    plants : list of FDIModel / LTI / python-control systems, optional
        The uncertainty set (transfer from u to y), e.g. :func:`sensor_gain_plants`.
    delta_u : float or callable ω ↦ bound, optional
        A frequency-domain bound ``||ΔGu(e^{jωTs})|| ≤ δ_u(ω)`` instead of plants (ℓ2
        evaluators only).
    margin : float
        Multiplies the bound (≥ 1) to cover plants between the samples of a non-convex set.
    bound : {'auto', 'l2', 'linf'}
        'auto': the ℓ2 bounds for ``ewrms``/``rms``, the majorant for the others. 'linf':
        the ℓ∞ majorant for any norm-based evaluation — also valid for ``rms``/``ewrms``
        (monotone and subadditive) and much tighter when the uncertain dynamics are slow
        compared with the window, where the windowed ℓ2 bound pays ``sqrt((N+M)/N)``.

    Returns
    -------
    ThresholdDesign
        ``spec`` for the runtime, the bound used and the guarantee in words.
    """
    if not (J0 > 0 and np.isfinite(J0)):
        raise DesignError(f"J0 must be a positive number (the comparison is J >= J_th), got {J0!r}")
    if margin < 1:
        raise DesignError(f"margin must be >= 1, got {margin}")
    if (plants is None) == (delta_u is None):
        raise DesignError("give the uncertainty either as plants=[...] or as delta_u=...")
    if not gen.dt:
        if Ts is None:
            raise DesignError("a continuous generator needs Ts")
        gen = gen.to_discrete(Ts)
    Ts = gen.dt
    model = gen.model
    Qy = gen.Q[:, : model.ny]
    kind = evaluation.get("kind")
    if bound not in ("auto", "l2", "linf"):
        raise DesignError(f"bound must be 'auto', 'l2' or 'linf', got {bound!r}")
    if bound == "l2" and kind not in ("rms", "ewrms"):
        raise DesignError(f"an l2 bound needs an rms or ewrms evaluation, not {kind!r}")
    if bound == "linf" and kind not in ("norm", "peak", "narendra", "rms", "ewrms"):
        raise DesignError(f"an l-infinity majorant needs a norm-based evaluation, not {kind!r}")
    G0 = model.lti("u")
    H = [] if plants is None else [(Qy @ (_discrete_plant(p, Ts) - G0)).minreal() for p in plants]

    if kind == "ewrms" and bound != "linf":
        lam = float(evaluation["lambda"])
        if delta_u is not None:
            raise DesignError("the ewrms guarantee needs the plants (a bound on the circle |z| = sqrt(lambda))")
        r = np.sqrt(lam)
        a = 0.0
        for Hi in H:
            poles = Hi.poles()
            if poles.size and np.max(np.abs(poles)) >= r:
                raise DesignError(
                    f"forgetting factor lambda={lam} too small: the ewrms bound needs every pole of Qy ΔG inside "
                    f"radius sqrt(lambda)={r:.6g}, but one has modulus {np.max(np.abs(poles)):.6g}; choose "
                    f"lambda > {np.max(np.abs(poles)) ** 2:.6g}")
            a = max(a, LTI(Hi.A / r, Hi.B / r, Hi.C, Hi.D, Ts).hinfnorm()[0] if Hi.n else np.linalg.norm(Hi.D, 2))
        a *= margin
        spec = {"kind": "adaptive", "J0": J0, "a": a, "evaluation": {"kind": "ewrms", "lambda": lam}}
        return ThresholdDesign(spec, "l2-exponential",
                               "ewrms(r) <= J0 + a ewrms(||u||) at every sample for every plant in the set "
                               "(zero initial state); J0 covers noise and unknown inputs",
                               {"a": a, "plants": len(H)})
    if kind == "rms" and bound != "linf":
        N = int(evaluation["window"])
        if H:
            a = max(Hi.hinfnorm()[0] for Hi in H)
            M = max(impulse_norms(Hi, tail_tol, max_taps)[0].size for Hi in H)
        else:
            grid = frequency_grid([Qy], num=600)
            gains = np.linalg.norm(Qy.freqresp(grid), ord=2, axis=(1, 2))
            bound = np.array([float(delta_u(w)) for w in grid]) if callable(delta_u) else float(delta_u)
            a = float(np.max(gains * bound))
            M = impulse_norms(Qy, tail_tol, max_taps)[0].size
        a *= margin
        scale = np.sqrt((N + M) / N)
        spec = {"kind": "adaptive", "J0": J0, "a": a * scale, "evaluation": {"kind": "rms", "window": N + M}}
        return ThresholdDesign(spec, "l2-window",
                               f"rms_N(r) <= J0 + a sqrt((N+M)/N) rms_(N+M)(||u||) for inputs within the last "
                               f"N+M = {N + M} samples; older inputs contribute at most {tail_tol:g} of the "
                               f"impulse response's l1 norm", {"a": a, "settling": M, "plants": len(H)})
    if kind in ("norm", "peak", "narendra", "rms", "ewrms"):
        if not H:
            raise DesignError(f"the '{kind}' evaluation needs the plants: a frequency bound gives no pointwise bound")
        taps_list, tails = zip(*(impulse_norms(Hi, tail_tol, max_taps) for Hi in H))
        M = max(t.size for t in taps_list)
        taps = np.zeros(max(M, 1))
        for t in taps_list:
            taps[: t.size] = np.maximum(taps[: t.size], t)
        tail = max(tails)
        spec = {"kind": "majorant", "J0": J0, "taps": (margin * taps).tolist(), "tail": margin * tail}
        return ThresholdDesign(spec, "linf-majorant",
                               f"||r(k)|| <= sum_j m_j ||u(k-j)|| + t max_(i<=k-M) ||u(i)|| for every plant in the "
                               f"set, evaluated with the residual's own {kind} evaluation",
                               {"taps": int(taps.size), "tail": tail, "plants": len(H)})
    raise DesignError(f"no threshold selector for the '{kind}' evaluation: use ewrms, rms, norm, peak or narendra")
