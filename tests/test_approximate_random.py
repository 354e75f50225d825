"""Seeded audit of the approximate designs over ill-scaled random models with noise (issue 17, "Show").

The models are those of :func:`test_synthesis_random.random_case` (continuous and discrete, n = 0–30,
m > p, unknown inputs d, unstable/marginal fault-only modes, eight decades of state scaling) with a
noise input w added where the model has none (:func:`noisy_case`). Every approximate design call —

* ``nullspace_design`` (Procedure AFD: u, d decoupled, fault-to-noise gap maximised),
* ``afdi_bank`` on the rows ``achievable_structure`` lists (Procedure AFDI),
* ``approximate_model_matching`` with the reference ``Mr`` = the fault response of an exact detection
  row, and ``Mr = I`` on the faults (isolation of every fault),
* ``approximate_model_detection_bank`` on a set of three models (stable plants only: the function's
  contract) —

is judged by an independent numpy computation (``test_synthesis_random``'s frequency responses and PBH
tests, nothing of fmu_fdi's analysis): ``R = Q·[Gu Gd Gw Gf; I 0 0 0]`` on a dense grid, each row (group)
normalised so that its required fault gain is 1, ``‖R_u‖, ‖R_d‖ ≤ 1e-7`` (and ``‖R_w‖`` when the design
says w is decoupled exactly), R stable (PBH), Q not numerically zero, and the figure the function reports
(the gap, the matching error, the model-detection gap) equal to numpy's within a stated tolerance. A
matching error must also be at most that of the two filters any user has at hand: Q = 0 (error ‖M·Mr‖∞)
and, for the detection-row reference, the exact row itself (error ‖Q_ref·Gw‖∞, when M = I).

``benchmarks/approximate_random_judged.py`` prints the counts ok / refused / broken over any seed range.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi.design import (afdi_bank, approximate_model_detection_bank, approximate_model_matching,
                            nullspace_design)
from fmu_fdi.design.problems.achievable import achievable_structure
from test_synthesis_random import (DEC_TOL, VIS_TOL, ZERO_Q, _call, _extended, _freqresp, _pbh_poles, _peak,
                                   random_case, row_violations, verdict)

# A reported figure (gap, error) agrees with numpy's when their ratio is within 1 ± FIG_RTOL. The
# library's figures are peaks read on its own grid (200–400 points, refined around the top for the
# matching error); numpy's below are refined peaks (dense grid, then 3 rounds of local 21-point
# refinement: the relative error of a refined peak of a resonance of damping ζ ≥ 1e-3 is below 1e-6).
# A 200-point log grid over the plant's band steps 4.7 % in ω; at a resonance of damping ζ the peak read
# on such a grid can be low by (Δω/ω)²/(8ζ²) — a few percent for ζ ≳ 0.1, so FIG_RTOL = 5e-2 lets a
# grid estimate pass and catches a figure of another filter or another norm (factors, not percent).
FIG_RTOL = 5e-2
# The H∞ matching error of approximate_model_matching is refined and its γ-iteration stops within
# reltol = 1e-4: the error measured on the returned filter must agree to ERR_RTOL (reltol plus
# the grid refinement's 1e-6, with margin for the realisation's rounding).
ERR_RTOL = 1e-3

N_SLOW = 8  # benchmarks/approximate_random_judged.py runs any number (the audit: 40 and more)


# ------------------------------------------------------------------------------------------ models
def noisy_case(seed: int):
    """``random_case(seed)`` with one noise input where it has none: ``Bw`` in the stable invariant
    subspace of A (ordered real Schur form of the balanced A), so w, like u and d, does not excite the
    fault-only unstable/marginal modes; ``Dw`` nonzero in half of the cases (always for a static plant)."""
    model = random_case(seed)
    if model.nw:
        return model
    rng = np.random.default_rng(20_000 + seed)
    n, p = model.n, model.ny
    Dw = rng.standard_normal((p, 1)) * (n == 0 or rng.random() < 0.5)
    if n:
        A = model.A
        _, (scale, _) = sla.matrix_balance(A, permute=False, separate=True)
        Ab = (A * scale[None, :]) / scale[:, None]
        if model.dt:
            T, Z, k = sla.schur(Ab, output="real", sort=lambda re, im: re * re + im * im < (1 - 1e-6) ** 2)
        else:
            T, Z, k = sla.schur(Ab, output="real", sort=lambda re, im: re < -1e-6)
        Bw = (Z[:, :k] @ rng.standard_normal((k, 1))) * scale[:, None]  # back to the unbalanced state
        Bw *= np.linalg.norm(model.Bu) / max(np.linalg.norm(Bw), 1e-300) if model.nu else 1.0
    else:
        Bw = np.zeros((0, 1))
    return model._replace(Bw=Bw, Dw=Dw, w_names=["w1"])


# ------------------------------------------------------------------------------------------- numpy
def _points(model, filters=()) -> np.ndarray:
    """Evaluation points on the stability boundary covering every pole scale of the plant and the
    filters (continuous: ω from min(1e-4, |p|min/100) to max(1e4, 100|p|max)), plus points at relative
    distances 1e-6 … 1e-1 beside every pole on or next to the boundary (an H∞ peak of a row that cancels
    a marginal fault mode while keeping a stable pole at 0.999 lies there), keeping ≥ 1e-7 relative away
    from every pole (a cancelled boundary pole is 0·∞ at the pole itself; at distance δ the product's
    rounding is ~eps·‖Q‖‖Ge‖/δ — 1e-9 of the gains at δ = 1e-7 for the models' gains ≤ 1e4)."""
    poles = [np.linalg.eigvals(model.A)] if model.n else []
    poles += [np.linalg.eigvals(F.A) for F in filters if F.A.shape[0]]
    allp = np.concatenate(poles) if poles else np.zeros(0)
    near = np.logspace(-6, -1, 60)
    if model.dt:
        th = [np.linspace(0.0, np.pi, 1500)]
        for p_ in allp[np.abs(np.abs(allp) - 1) < 0.1]:
            a = abs(np.angle(p_))
            th += [a + near, a - near]
        th = np.concatenate(th)
        lam = np.exp(1j * np.unique(th[(th >= 0) & (th <= np.pi)]))
    else:
        mags = np.abs(allp[np.abs(allp) > 1e-9]) if allp.size else np.zeros(0)
        lo = min(1e-4, mags.min() / 100) if mags.size else 1e-4
        hi = max(1e4, mags.max() * 100) if mags.size else 1e4
        om = [np.r_[0.0, np.logspace(np.log10(lo), np.log10(hi), 1500)]]
        for p_ in allp[np.abs(allp.real) < 0.1 * np.maximum(1.0, np.abs(allp))]:
            b = abs(p_.imag)
            om += [b + near * max(1.0, b), b - near * max(1.0, b)]
        om = np.concatenate(om)
        lam = 1j * np.unique(om[om >= 0])
    if allp.size:
        dist = np.min(np.abs(lam[:, None] - allp[None, :]), axis=1)
        lam = lam[dist > 1e-7 * np.maximum(1.0, np.abs(lam))]
    return lam


def _away(model, lam: np.ndarray) -> np.ndarray:
    """Mask of the points ≥ 1e-3 (relative) away from the plant's poles, where the decoupling is read
    (as test_synthesis_random's judge reads it: nearer, the rounding of a cancelled boundary mode of the
    plant, eps·‖Q‖‖Ge‖/δ, is no longer below DEC_TOL)."""
    if not model.n:
        return np.ones(lam.shape, bool)
    ev = np.linalg.eigvals(model.A)
    return np.min(np.abs(lam[:, None] - ev[None, :]), axis=1) > 1e-3 * np.maximum(1.0, np.abs(lam))


def _refined_peak(fun, lam: np.ndarray, dt: float, poles=(), where: list | None = None) -> float:
    """The largest 2-norm of ``fun(points)`` (shape (k, p, m)) over the boundary: grid maximum, then
    three rounds of 21 points between the neighbours of the best point (refined H∞ norm); the refined
    points keep ``_points``' distance ≥ 1e-7 (relative) from ``poles`` (the plant's and the filters'). Without
    that guard the refinement between two grid points on either side of a cancelled boundary mode reads the
    rounding-level residue r of the cancellation over the distance δ: approximate audit seed 110 (Mr = I,
    plant pole ±2j, ||Q(2j) c|| = 1.9e-12 within the balanced realisation's evaluation bound 2.9e-12) read
    1.00171 at δ ≈ 1e-9 for an error of 1.00008 (r/δ: 8.5e-5 at 1e-8, 9.6e-3 at 1e-10; 8.6e-6 at 1e-7).
    ``where``: a list the point of the peak is appended to."""
    poles = np.asarray(poles, complex).ravel()

    def guarded(pts):
        if not poles.size:
            return pts
        dist = np.min(np.abs(pts[:, None] - poles[None, :]), axis=1)
        return pts[dist > 1e-7 * np.maximum(1.0, np.abs(pts))]

    vals = np.linalg.norm(fun(lam), 2, axis=(1, 2))
    best = float(vals.max(initial=0.0))
    if not vals.size:
        return 0.0
    at = lam[int(np.argmax(vals))]
    x = np.angle(lam) if dt else lam.imag
    for k in np.argsort(vals)[-3:]:
        a, b = x[max(k - 1, 0)], x[min(k + 1, len(x) - 1)]
        for _ in range(3):
            xs = np.linspace(a, b, 21)
            pts = np.exp(1j * xs) if dt else 1j * xs
            keep = np.flatnonzero(np.isin(pts, guarded(pts)))
            if not keep.size:
                break
            v = np.linalg.norm(fun(pts[keep]), 2, axis=(1, 2))
            j = int(keep[int(np.argmax(v))])
            if float(v.max()) > best:
                best, at = float(v.max()), pts[j]
            a, b = xs[max(j - 1, 0)], xs[min(j + 1, 20)]
    if where is not None:
        where.append(at)
    return best


def _ge_values(model, lam):
    A, B, Ce, De = _extended(model)
    return _freqresp(A, B, Ce, De, lam)


def _cols(model):
    nu, nd, nw = model.nu, model.nd, model.nw
    f0 = nu + nd + nw
    return {"u": slice(0, nu), "d": slice(nu, nu + nd), "w": slice(nu + nd, f0),
            **{f.name: f0 + np.arange(model.nf)[f.columns] for f in model.faults}}


def _row_checks(Q, rows, model, lam, Rv, Qv, scale: float, w_decoupled: bool, tag: str,
                excluded=()) -> list[str]:
    """Decoupling (normalised by ``scale``) of u, d (w when decoupled exactly, the ``excluded`` faults), Q nonzero
    and R stable for the rows ``rows`` of Q: test_synthesis_random's :func:`row_violations` on the points away
    from the plant's poles (:func:`_away`)."""
    cols = _cols(model)
    keep = _away(model, lam)
    Rv, Qv = Rv[keep], Qv[keep]
    if _peak(Qv[:, rows, :]) < ZERO_Q:
        return [f"{tag}: Q is numerically zero (peak {_peak(Qv[:, rows, :]):.2e})"]
    blocks = [(what, cols[what]) for what in ("u", "d") + (("w",) if w_decoupled else ())]
    blocks += [(f"excluded fault {nm}", cols[nm]) for nm in excluded]
    return row_violations(Q, rows, model, Rv, scale, blocks, tag)


def _agree(what: str, reported: float, numpy_fig: float, rtol: float, atol: float = 0.0) -> list[str]:
    if np.isinf(reported) and np.isinf(numpy_fig):
        return []
    if not (np.isfinite(reported) and abs(reported - numpy_fig) <= max(rtol * abs(numpy_fig), atol, 1e-300)):
        return [f"{what}: reported {reported:.6g}, numpy {numpy_fig:.6g} (rtol {rtol:g})"]
    return []


# ------------------------------------------------------------------------------------------ judges
def judge_afd(gen, model, S, names) -> list[str]:
    """An AFD generator or AFDI bank: per group, decoupling of u, d (w when exact) normalised by the
    smallest required fault peak, R stable, Q nonzero, required faults visible, and the reported gap
    ``min_{S_ij=1} ‖Rf_ij‖∞ / ‖Rw_i‖∞`` (``info['gap_estimate']`` of a generator, ``info['gaps']`` of a
    bank) equal to numpy's within FIG_RTOL."""
    S = np.atleast_2d(np.asarray(S, int))
    members = getattr(gen, "members", [gen])
    Q = gen.Q
    lam = _points(model, [Q])
    Gv = _ge_values(model, lam)
    Qv = _freqresp(Q.A, Q.B, Q.C, Q.D, lam)
    Rv = Qv @ Gv
    cols = _cols(model)
    out = [f"Q has the unstable/marginal pole {p:.4g}" for p in _pbh_poles(Q.A, Q.B, Q.C, model.dt)]
    reported = gen.info.get("gaps") if hasattr(gen, "members") else [gen.info.get("gap_estimate")]
    for i, g in enumerate(gen.groups):
        exact_w = members[i].info.get("noise") == "decoupled exactly"
        req = [nm for nm, s in zip(names, S[i]) if s]
        fpk = {nm: _refined_peak(lambda L, nm=nm: _freqresp(Q.A, Q.B, Q.C[g], Q.D[g], L)
                                 @ _ge_values(model, L)[:, :, cols[nm]], lam, model.dt) for nm in req}
        gmin = min(fpk.values()) if fpk else 0.0
        if gmin <= 0:
            out.append(f"group {i}: a required fault is invisible ({fpk})")
            continue
        out += _row_checks(Q, g, model, lam, Rv, Qv, 1.0 / gmin, exact_w, f"group {i}",
                           excluded=[nm for nm, s in zip(names, S[i]) if not s])
        wpk = _refined_peak(lambda L: _freqresp(Q.A, Q.B, Q.C[g], Q.D[g], L) @ _ge_values(model, L)[:, :, cols["w"]],
                            lam, model.dt)
        gap = np.inf if wpk <= DEC_TOL * gmin else gmin / wpk
        if exact_w and np.isfinite(gap):
            out.append(f"group {i}: 'decoupled exactly' but ‖R_w‖/fault = {wpk / gmin:.2e}")
        rep = reported[i] if reported is not None and i < len(reported) else None
        if rep is None:
            out.append(f"group {i}: no gap reported")
        else:
            out += _agree(f"group {i}: gap", float(rep), gap, FIG_RTOL)
    return out


def judge_amm(gen, model, Mr, ref_noise: float | None) -> list[str]:
    """An approximate model-matching filter: u, d decoupled relative to ‖M·Mr‖∞, R and Q stable, Q
    nonzero, the reported error ‖Q [Gf Gw; 0 0] − M [Mr 0]‖∞ equal to numpy's within ERR_RTOL, and no
    worse than Q = 0 (‖M Mr‖∞) nor, when ``ref_noise`` is given and M = I, than the reference row itself."""
    Q, M = gen.Q, gen.info["M"]
    lam = _points(model, [Q, M, Mr])
    Gv = _ge_values(model, lam)
    Qv = _freqresp(Q.A, Q.B, Q.C, Q.D, lam)
    Rv = Qv @ Gv
    cols = _cols(model)
    fcol = np.r_[[c for f in model.faults for c in cols[f.name]]].astype(int)

    def target(L):
        MMr = _freqresp(M.A, M.B, M.C, M.D, L) @ _freqresp(Mr.A, Mr.B, Mr.C, Mr.D, L)
        return np.concatenate([MMr, np.zeros(MMr.shape[:2] + (model.nw,))], axis=2)

    def error(L):
        R = _freqresp(Q.A, Q.B, Q.C, Q.D, L) @ _ge_values(model, L)
        return np.concatenate([R[:, :, fcol], R[:, :, cols["w"]]], axis=2) - target(L)

    poles = np.concatenate([np.linalg.eigvals(X) for X in (model.A, Q.A, M.A, Mr.A) if X.shape[0]] + [np.zeros(0)])
    top = _refined_peak(target, lam, model.dt, poles)
    out = [f"Q has the unstable/marginal pole {p:.4g}" for p in _pbh_poles(Q.A, Q.B, Q.C, model.dt)]
    if top <= 0:
        return out + ["‖M·Mr‖ = 0"]
    out += _row_checks(Q, list(range(Q.C.shape[0])), model, lam, Rv, Qv, 1.0 / top, False, "filter")
    where: list = []
    err = _refined_peak(error, lam, model.dt, poles, where)
    # An exact match's error is the rounding of evaluating Q·[Gf Gw] − M·[Mr 0]: each reading carries ≲ VIS_TOL of
    # the gains compared (test_synthesis_random's derivation), ‖M·Mr‖ = top for a matched row, so two readings of
    # it agree within 2·VIS_TOL·top (audit seed 129, an exact match: reported 2.0186e-13, numpy 1.9970e-13 of
    # top = 8.07 — 2.7e-16 of it apart, refused by the relative 1e-3 alone). Beside a boundary mode of the plant
    # that R cancels (fault-only, [Gf](λ) ≈ c/(λ − p)), the reading of Q(λ)·[Gf Gw](λ) carries Q's evaluation error
    # times ‖[Gf Gw](λ)‖ ~ ‖c‖/δ, whatever |Q(λ)| (Q has a zero at p): GEPP on λI − A_Q errs by ≲ γ_{3n}|λI − A_Q|
    # componentwise (Higham, 2nd ed., Thm 9.3), so the reading's floor at the peak λ* is γ_{3n_Q}·‖Q‖·‖[Gf Gw](λ*)‖
    # (‖Q‖ its peak on the grid). Audit seed 159 (discrete, exact match of ‖Mr‖ = 129, plant pair e^{±0.2j} of
    # eigenvalue condition 4.6e5, ‖c‖ = 4.39): |Q(p) c| = 7.2e-14 = 7.8 u·‖Q‖‖c‖, so numpy read η/δ = 4.16e-7 at
    # δ = 1e-7 (4.0e-8 at 1e-6, 1.2e-10 at 1e-2 ≈ the designed 1.28e-10) and the design 6.96e-9 at its 2e-6: two
    # readings of rounding/δ; the floor there is 4.95e-6 (3.8e-8 of ‖Mr‖)
    n_q = 3 * max(Q.A.shape[0], 1)
    u = np.finfo(float).eps / 2
    Gs = _ge_values(model, np.asarray(where[:1], complex)) if where else np.zeros((1, 0, 0))
    g_star = _peak(np.concatenate([Gs[:, :, fcol], Gs[:, :, cols["w"]]], axis=2)) if where else 0.0
    floor = n_q * u / (1 - n_q * u) * _peak(Qv) * g_star
    out += _agree("matching error", float(gen.info["error"]), err, ERR_RTOL, atol=2 * VIS_TOL * top + floor)
    if err > top * (1 + ERR_RTOL):
        out.append(f"matching error {err:.6g} above that of Q = 0 ({top:.6g})")
    M_is_I = M.A.shape[0] == 0 and np.allclose(M.D, np.eye(M.D.shape[0]))
    if ref_noise is not None and M_is_I and err > ref_noise * (1 + ERR_RTOL) + 1e-9 * top + floor:
        out.append(f"matching error {err:.6g} above the reference row's own ‖Q_ref Gw‖∞ = {ref_noise:.6g}")
    return out


def model_set(model):
    """Three models for approximate model detection: the plant without faults and with its first
    known-input column moved by 30 % and 60 % of a random direction (same A, C, d, w)."""
    rng = np.random.default_rng(30_000 + model.n)
    base = model._replace(faults=[])
    dB = rng.standard_normal(model.Bu.shape) * np.linalg.norm(model.Bu) / max(1.0, np.sqrt(model.Bu.size))
    dD = rng.standard_normal(model.Du.shape) * (np.linalg.norm(model.Du) if np.any(model.Du) else 0.0)
    return [base._replace(Bu=model.Bu + k * 0.3 * dB, Du=model.Du + k * 0.3 * dD, name=f"m{k}") for k in range(3)]


def judge_amd(bank, models) -> list[str]:
    """Filter i: exact for u and d of model i relative to β_i = min_{j≠i} ‖Q_i [Gu_j; I]‖∞ (which the
    function scales to 1), R stable, Q nonzero, and the reported ``MDperf`` row and ``MDgap`` = β/γ
    (γ = ‖Q_i [Gw_i; 0]‖∞) equal to numpy's within FIG_RTOL."""
    out = []
    for i, (member, mi) in enumerate(zip(bank.members, models)):
        Q = member.Q
        lam = _points(mi, [Q])
        dist = []
        for mj in models:
            def Ruj(L, mj=mj):
                Ge = _ge_values(mj, L)
                return _freqresp(Q.A, Q.B, Q.C, Q.D, L) @ Ge[:, :, :mj.nu]
            dist.append(_refined_peak(Ruj, lam, mi.dt))
        beta = min(d for j, d in enumerate(dist) if j != i)
        if not beta > 0:
            out.append(f"filter {i}: β = 0")
            continue
        Gv = _ge_values(mi, lam)
        Qv = _freqresp(Q.A, Q.B, Q.C, Q.D, lam)
        exact_w = member.info.get("noise") in ("decoupled exactly", "no noise inputs")
        out += _row_checks(Q, list(range(Q.C.shape[0])), mi, lam, Qv @ Gv, Qv, 1.0 / beta, exact_w and mi.nw,
                           f"filter {i}")
        for j, d in enumerate(dist):
            out += _agree(f"filter {i}: MDperf[{j}]", float(bank.info["MDperf"][i][j]), d, FIG_RTOL) if j != i else []
        cw = _cols(mi)["w"]
        gam = _refined_peak(lambda L: _freqresp(Q.A, Q.B, Q.C, Q.D, L) @ _ge_values(mi, L)[:, :, cw], lam, mi.dt)
        gap = np.inf if gam <= DEC_TOL * beta else beta / gam
        out += _agree(f"filter {i}: MDgap", float(bank.info["MDgap"][i]), gap, FIG_RTOL)
    return out


# ------------------------------------------------------------------------------------------ driver
def _detection_reference(model):
    """An exact detection row (noise ignored) and its fault response as an LTI (the reference Mr), and
    ‖Q_ref·Gw‖∞ read by numpy — or None when no such row exists."""
    st, ref = _call(lambda: nullspace_design(model, noise="ignore"))
    if st != "ok":
        return None
    Q = ref.Q
    Rf = ref.Rf  # the internal form's fault block as a user reads it (unstable cancelled modes removed)
    lam = _points(model, [Q])
    cw = _cols(model)["w"]
    noise = _refined_peak(lambda L: _freqresp(Q.A, Q.B, Q.C, Q.D, L) @ _ge_values(model, L)[:, :, cw], lam, model.dt)
    return Rf, noise


def check_case(seed: int, max_rows: int = 3, calls=("afd", "afdi", "amm_ref", "amm_eye", "amd")):
    """Every approximate design call on ``noisy_case(seed)``: (call, 'ok'|'refused'|'broken', detail).
    'broken': a returned design that fails its judge, another exception than DesignError; a refusal of
    AFD/AFDI where ``achievable_structure`` lists the row is broken too (w is noise, never decoupled
    required, so exact achievability of (u, d) decoupling with the row's faults suffices)."""
    out = []
    model = noisy_case(seed)
    names = model.fault_names
    st, listed = _call(lambda: achievable_structure(model))
    listed = np.asarray(listed, int).reshape(-1, len(names)) if st == "ok" else np.zeros((0, len(names)), int)
    if st == "crash":
        out.append(("achievable_structure", "broken", f"{type(listed).__name__}"))

    def record(what, status, res, judge, achievable):
        out.append((what,) + verdict(status, res, achievable, judge))

    ones = np.ones((1, len(names)), int)
    listed_set = {tuple(r) for r in listed}
    if "afd" in calls and names:
        st, res = _call(lambda: nullspace_design(model))
        record("nullspace_design(AFD)", st, res, lambda g: judge_afd(g, model, ones, names),
               tuple(ones[0]) in listed_set)
    if "afdi" in calls and len(listed):
        rng = np.random.default_rng(seed)
        rows = listed if len(listed) <= max_rows else listed[np.sort(rng.choice(len(listed), max_rows, False))]
        st, res = _call(lambda: afdi_bank(model, rows))
        record("afdi_bank", st, res, lambda g: judge_afd(g, model, rows, names), True)
    if "amm_ref" in calls and names:
        ref = _detection_reference(model)
        if ref is not None:
            Mr, noise = ref
            st, res = _call(lambda: approximate_model_matching(model, Mr))
            record("amm(Mr=detection row)", st, res, lambda g: judge_amm(g, model, Mr, noise), True)
    if "amm_eye" in calls and names:
        from fmu_fdi.lti import LTI

        Mr = LTI.static(np.eye(model.nf), model.dt)
        st, res = _call(lambda: approximate_model_matching(model, Mr))
        record("amm(Mr=I)", st, res, lambda g: judge_amm(g, model, Mr, None), False)
    if "amd" in calls and model.nu:
        ev = np.linalg.eigvals(model.A) if model.n else np.zeros(0)
        stable = np.all(np.abs(ev) < 1 - 1e-6) if model.dt else np.all(ev.real < -1e-6)
        if stable:
            models = model_set(model)
            st, res = _call(lambda: approximate_model_detection_bank(models))
            record("approximate_model_detection_bank", st, res, lambda b: judge_amd(b, models), False)
    return out


def _assert_case(seed: int, calls):
    res = check_case(seed, calls=calls)
    broken = [f"{what}: {detail}" for what, st, detail in res if st == "broken"]
    assert not broken, f"seed {seed}:\n" + "\n".join(broken)


CALLS = ("afd", "afdi", "amm_ref", "amm_eye", "amd")
#: (seed, call) pairs the audit found broken, with the cause (owner's file); strict: a fix makes the test XPASS
KNOWN_BROKEN: dict[tuple[int, str], str] = {
    # (audit of seeds 88-111: seeds 98 and 102 'amm_ref' moved to FIXED)
    # audit of seeds 112-135 (approximate_matching.py): _shipped_filter refused a filter that is the designed one to
    # 1.4e-9 / 2.5e-8 / 1.5e-9 of the error's size because the gap was 10.4 / 2.78 / 1.01 times its "rounding bound",
    # whose inner-product constant _gamma(n) = sqrt(n)·u is the probabilistic estimate at λ = 1 (Higham-Mary Thm 2.4:
    # exceeded with probability up to 2·exp(-1/2) > 1, i.e. no bound). Seeds 120, 131: fixed (FIXED) by the
    # worst-case first-order bound; seed 119's gap exceeds that bound too (shipped10) — fixed by amm11 (FIXED)
    # amm11 (same session, numpy judge): seeds 136-159 main 104 ok / 0 refused / 1 broken (159 amm_ref: the judge,
    # FIXED) → 105 / 0 / 0; seeds 112-135 re-run on the branch 106 / 1 / 0 — the refusal is seed 122 amm(Mr=I) (not
    # broken: Mr = I need not be reachable): γ-iteration 1.0000777 within reltol of its bracket [1, 1.0000777], the
    # shipped filter's own error 1.000102 (a plant mode at 0 beside which it is read; the exact cancellation would make
    # it 1.0156) exceeds Q = 0's 1 by more than reltol — fixed by amm12 (FIXED: the iteration takes half the budget)
}
#: approximate_model_matching (noisec) refused "the returned filter's error response differs from the designed one"
#: on every model whose fault-only mode is an integrator or z = 1: _shipped_filter compared the two on points that
#: included ω = 0 (z = 1), where [Gf Gw] is ~1/δ and Q·Gf (which cancels the mode) is rounding/δ (seed 16: 11.4,
#: relative 0.685; seed 18: 3.57, relative 0.099). Fixed: approximate_matching._points moves every point off the
#: systems' poles (BESIDE_POLE); seeds 16 and 18 are designed and pass this judge (FIXED). The same refusal on seeds
#: 10, 20, 23, 26, 30, 31 is fixed too (REALISATION_FIXED, at the end), and with it seed 2's R-stability failure (residue
#: ||Q_1(1) c_p|| = 6.78e-12 > its rounding bound 5.5e-13: Y's peak gain 3.6e5 on the full-observer basis, 11.9 on
#: the glcf one). Seed 13's R-stability failure (residue 3.03e-11 > its rounding bound 1.6e-11 at z = 1) is fixed by
#: the stage cancelling the plant's boundary modes exactly in R (refine.cancel_residues)


def _params(seeds, calls=CALLS):
    return [pytest.param(s, c, marks=pytest.mark.xfail(strict=True, reason="issue 17: " + KNOWN_BROKEN[(s, c)]))
            if (s, c) in KNOWN_BROKEN else pytest.param(s, c) for s in seeds for c in calls]


# -------------------------------------------------------------------------------------------- tests
def test_noisy_models_have_noise_that_spares_the_fault_only_modes():
    """Every model has a noise input; w (like u and d) does not excite the unstable/marginal
    fault-only modes: PBH controllability of those modes from w is at rounding level."""
    for seed in range(12):
        m = noisy_case(seed)
        assert m.nw >= 1
        if not m.n:
            continue
        for lam in np.linalg.eigvals(m.A):
            if (abs(lam) >= 1 - 1e-6) if m.dt else lam.real >= -1e-6:
                M = np.hstack([lam * np.eye(m.n) - m.A, m.Bw / np.linalg.norm(m.Bw)])
                # the balanced data of the PBH test of test_synthesis_random: a rounding-level singular value
                assert _pbh_poles(m.A, m.Bw, np.eye(m.n), m.dt).size == 0 or np.linalg.svd(
                    M, compute_uv=False)[-1] < 1e-6 * max(1.0, np.linalg.norm(m.A))


def test_judges_can_fail():
    """The judges refuse a wrong gap, a wrong error, a filter worse than Q = 0 and a leaking filter."""
    from fmu_fdi import FDIModel, sensor_fault
    from fmu_fdi.lti import LTI

    # y = u/(s+1) + w/(s+2) + f: the exact row r = y − u/(s+1) has Rf = 1, Rw = 1/(s+2): gap 2
    model = FDIModel.from_matrices(np.diag([-1.0, -2.0]), [[1.0], [0.0]], [[1.0, 1.0]], Bw=[[0.0], [1.0]],
                                   faults=[sensor_fault("f", "y1")], y_names=["y1"], u_names=["u1"])
    Q = LTI(np.array([[-1.0]]), np.array([[0.0, -1.0]]), np.array([[1.0]]), np.array([[1.0, 0.0]]))

    g = type("G", (), {"Q": Q, "groups": [[0]], "info": {"gap_estimate": 2.0, "noise": "co-outer"}})()
    assert judge_afd(g, model, [[1]], ["f"]) == []
    g.info["gap_estimate"] = 2.3
    assert any("gap" in x for x in judge_afd(g, model, [[1]], ["f"]))
    leaky = type("G", (), {"Q": LTI.static(np.array([[1.0, 0.0]])), "groups": [[0]],
                           "info": {"gap_estimate": 2.0}})()
    assert any("R_u" in x for x in judge_afd(leaky, model, [[1]], ["f"]))
    # matching Mr = 1: Q as above has error ‖[0  1/(s+2)]‖ = 0.5; Q = 2·(row) has error ‖[1 2/(s+2)]‖ = √2
    Mr = LTI.static(np.eye(1))
    good = type("G", (), {"Q": Q, "info": {"M": LTI.static(np.eye(1)), "error": 0.5}})()
    assert judge_amm(good, model, Mr, 0.5) == []
    bad = type("G", (), {"Q": 2.0 * Q, "info": {"M": LTI.static(np.eye(1)), "error": np.sqrt(2.0)}})()
    msgs = judge_amm(bad, model, Mr, 0.5)
    assert any("Q = 0" in x for x in msgs) and any("reference row" in x for x in msgs)
    good.info["error"] = 0.6
    assert any("matching error: reported" in x for x in judge_amm(good, model, Mr, None))


#: the default run: three small models (continuous n = 5; static; discrete n = 7), the calls that cost < 3 s each
FAST = [(0, "afd"), (0, "amm_ref"), (4, "amd"), (4, "afdi"), (7, "amm_eye"), (7, "amd"),
        # the AFD gap estimate read R_fc at z = 1, the fault-only mode's pole (rounding/δ: 1.2e5 for its peak 1.0),
        # and reported 1.28 for the true gap 0.373 (fixed: nullspace._noise_combination keeps 1e-6 off plant poles)
        (13, "afd")]


#: found broken by the audit and fixed, beyond the slow range: (seed, call) → what was wrong
FIXED = {(129, "amm_ref"): "an exact match (error 2e-13 of ‖M·Mr‖ = 8.07): the judge compared the two readings of "
                          "rounding (reported 2.0186e-13, numpy 1.9970e-13) with the relative 1e-3 alone; the test "
                          "judge's fault — judge_amm now admits 2·VIS_TOL·‖M·Mr‖ absolute",
         (20, "afd"): "n = 30, a resonance at 7.8 rad/s: the AFD gap was reported from a 200-point grid, 0.488 "
                      "for the filter's 1.87 (nullspace._noise_combination now reports fault_noise_gap's)",
         **{(s_, "amm_ref"): "approximate_model_matching refused 'error response differs from the designed one by "
                             f"{d}': read at the fault-only integrator, rounding/δ (approximate_matching._points now "
                             "keeps off the systems' poles)" for s_, d in {16: "11.4 (relative 0.685)",
                                                                           18: "3.57 (relative 0.099)"}.items()},
         (1, "amm_ref"): "Mr = the exact detection row's Rf (the plant has a fault-only pair e^{±0.2j}, kept in the "
                         "basis Q0 itself): 'H∞ synthesis failed even at γ = 362.448 > ||Mr||∞ ... Riccati equations "
                         "ill-conditioned' (fixed: approximate_matching.stable_reduced_system, the stable coprime "
                         "factorisation of [Q0 G1], as the peer's ammsyn)",
         (21, "amm_ref"): "fault-only z = 1 kept by the basis Q0 and G1: 'H∞ synthesis failed even at γ = 74.3207 > "
                          "||Mr||∞' (with Mr = I too: 'γ = 1.01'); fixed as seed 1",
         (83, "amm_ref"): "audit of seeds 76-87: discrete, n = 28, p = 4, m = 6; matching the exact detection row was "
                          "refused, 'u leak 1.9e-07 × the weakest fault gain' at ω = 4.0e-3 rad/s (order-65 filter "
                          "Y·Φ·Q0, no boundary mode); designed since the factors are realised in the Schur coordinates "
                          "of their closed loops (pencil.schur_feedback: glcf, the pencil basis), not by forming A + LC",
         # audit of seeds 88-111 (benchmarks/approximate_random_judged.py 24 88 --timeout=120)
         **{(s_, "amm_ref"): "refused 'the returned filter's error response differs from the designed one by "
                             f"{d}': approximate_matching.stable_reduced_system factored G1 = [Gf Gw] = M2⁻¹ N_G "
                             "(glcf) on its raw realisation, ill-scaled, the boundary mode weakly observed in it; "
                             f"N_G differed from M2 Q0 [Gf Gw] by {g} relative (seed 102: the integrator's residue "
                             "kept by M2·G1, 3.9e-5/ω); fixed: glcf of G1's minimal realisation (‖A‖ 11.5, |C v| "
                             f"2.3), gap {g2}; the error {e} is within the reference row's noise {r}"
             for s_, d, g, g2, e, r in ((98, "3.44e-7 (2.6e4 times its rounding bound)", "1.7e-7", "1.4e-13",
                                         "5.526", "27.24"),
                                        (102, "24.2 (relative 5.87)", "0.995 (raw ‖A‖ 1.3e7, |C v| 5.4e-4)",
                                         "1.7e-9", "1.154", "1.296"))},
         # audit of seeds 112-135 (benchmarks/approximate_random_judged.py)
         **{(s_, "amm_ref"): "refused 'the returned filter's error response differs from the designed one by "
                             f"{d}': {x} times _shipped_filter's rounding β, whose constants √n·u are Higham-Mary's "
                             "probabilistic estimate at λ = 1 (no bound); fixed: where no candidate is within β, the "
                             "first within the worst-case first-order bound β_w (deterministic γ_n = n·u/(1 − n·u)) "
                             f"and 1e-3 of the error is taken: the product realisation Y·Φ·Q0 at {w} β_w (its minimal "
                             f"realisation: {wm}); error {e} (reference row's noise {r}), order {o}"
             for s_, d, x, w, wm, e, r, o in ((120, "8.64e-7 (relative 2.49e-8)", 2.78, 0.445, 5.14, "7.5709", "8.1615",
                                               119),
                                              (131, "2.39e-7 (relative 1.46e-9)", 1.01, 0.964, 1.34, "87.096", "112.29",
                                               78))},
         (119, "amm_ref"): "achievable reference refused: shipped-response gap 1.57e-6 (relative 1.43e-9) = 10.4 times "
                           "_shipped_filter's probabilistic rounding estimate and 1.14 times its worst-case first-order "
                           "bound β_w (the minimal candidate: 8.77), beside z = 1 — the factors' construction errors, "
                           "which no evaluation bound covers; fixed: where no candidate is within β_w, the one nearest "
                           "the designed response whose own error is the designed one's within reltol is shipped "
                           "(error 170.410907, limit 170.427949; gap 6.05e-6 = 1.08 β_w after the γ-iteration's "
                           "change), numpy judge ok (reference row's noise 175.39, order 86)",
         (159, "amm_ref"): "audit of seeds 136-159: discrete n 5, an exact match (designed error 1.28e-10, ‖Mr‖ 129) "
                           "beside the plant's fault-only pair e^{±0.2j} (eigenvalue condition 4.6e5) that R cancels: "
                           "numpy read 4.16e-7 at 1e-7 from the pole for the reported 6.96e-9 (read at 2e-6) — both "
                           "|Q(p) c|/δ with |Q(p) c| = 7.2e-14 = 7.8 u·‖Q‖‖c‖, the rounding of Q's evaluation; the "
                           "test judge's fault — judge_amm's floor now includes γ_{3n_Q}·‖Q‖·‖[Gf Gw](λ*)‖ at the "
                           "peak (4.95e-6 here)",
         (122, "amm_eye"): "refused, not broken: Mr = I on nf = 5 faults, p = 4 (γ_opt = ||F||∞ = 1): the γ-iteration "
                           "spent the whole reltol (1.0000777 in [1, 1.0000777]) and the shipped order-21 filter, read "
                           "beside the plant integrator it cancels to a residue 1.6e-12, added 2.4e-5 (1.000102): "
                           "worse than Q = 0 by more than reltol = 1e-4. Fixed: the iteration takes r_γ, (1 + r_γ)² = "
                           "1 + reltol (approximate_matching.iteration_reltol): bracket [1, 1.0000389], error 1.0000954, "
                           "numpy judge ok (tests/test_amm_reltol_budget.py)",
         (110, "amm_eye"): "Mr = I on nf = 5 faults, p = 3: numpy read 1.00171 for the reported 1.00008 — its "
                           "refinement read the cancelled plant pair ±2j's rounding residue 1.9e-12 at 1e-9 from the "
                           "pole (the judge's refinement now keeps _points' 1e-7); and the error above Q = 0's (1, "
                           "the optimum: rank Q·Gf ≤ 3 < 5) within reltol is now said in a note "
                           "(approximate_matching._zero_filter_error, tests/test_amm_zero_filter.py)"}


@pytest.mark.parametrize("seed, call", FAST)
def test_approximate_designs_meet_the_judge(seed, call):
    _assert_case(seed, (call,))


@pytest.mark.slow
@pytest.mark.parametrize("seed, call", [p for p in _params(range(N_SLOW)) if tuple(p.values) not in FAST]
                         + [p for p in _params(sorted({s for s, _ in KNOWN_BROKEN} | {s for s, _ in FIXED}))
                            if tuple(p.values) in set(KNOWN_BROKEN) | set(FIXED) and p.values[0] >= N_SLOW])
def test_approximate_designs_meet_the_judge_slow(seed, call):
    _assert_case(seed, (call,))


# ------------------------------------- issue 17: the reduced problem's realisations (approximate_model_matching)
#: approximate_model_matching refused these solvable problems (Mr = an exact detection row's Rf, so that row is
#: admissible) with "the returned filter's error response differs from the designed one"; fixed, they pass the judge:
#: (seed, call) → what was wrong
REALISATION_FIXED = {
    **{(s_, "amm_ref"): "the observer-based basis Q0 = [M̂ −N̂] of this plant without d placed every pole: its balanced "
                        f"A − LC had norm {a} (the plant's A: {b}), G1 and the interactor's Ĝ lost digits and the "
                        f"γ-iteration's Y had peak gain {y}; fixed: approximate_matching._observer_basis moves only the "
                        f"poles outside the margin (glcf): Y's peak gain {y2}"
        for s_, a, b, y, y2 in ((10, "72", "11.5", "2.1e6", "202"), (20, "6.2e9", "24", "4.2e3", "7.9"),
                                (23, "2.2e7", "5.0", "3.2e6", "41"), (30, "2.1e8", "36", "1.3e8", "16"),
                                (31, "6.1e7", "4.7", "2.0e7", "2.2"))},
    (26, "amm_ref"): "a fault-only integrator (pole 1.3e-16): the shipped error was read as Q(λ)·[Gf Gw](λ) 7e-9 rad/s "
                     "from it, the filter's rounding-level residue (4.7e-12, within the R-stability bound 2.8e-9) "
                     "over the distance, 7e-5 of the error's size; fixed: approximate_matching._fault_noise_response "
                     "reads R as the post-conditions do (the modes a row cancels to rounding removed): 1.3e-10"}


def _relative_gap(X: np.ndarray, Y: np.ndarray) -> float:
    """``max_λ ||X(λ) − Y(λ)|| / max_λ ||Y(λ)||``."""
    return float(np.max(np.linalg.norm(X - Y, 2, axis=(1, 2))) / max(_peak(Y), 1e-300))


@pytest.mark.parametrize("seed", [20, 23, 30, 31])
def test_reduced_problem_realisations_agree_with_their_factors(seed):
    """On ill-scaled plants without d and with unstable Gu (eight decades of state scaling, one output; seeds 20, 30
    continuous, 23, 31 discrete, all with unstable or marginal fault-only modes), the reduced problem's realisations are the
    products they stand for, read by numpy on a grid ≥ 1e-3 (relative) off the plant's poles:
    ``G1(λ) = Q0(λ) [Gf Gw; 0 0](λ)`` and ``m(λ)^K Ĝ(λ) = Φ(λ) G1(λ)`` (Silverman's interactor, m = 1/(s + 1) or
    1/z), each to 1e-9 of its peak. Tolerance: realisations of order N ≤ 60 computed by backward-stable steps are
    exact for data perturbed by N·eps·||A|| (balanced); a well-conditioned one (eigenvector condition ≤ 1e3) turns
    that into ≤ 1e-10 of its values (measured: ≤ 8e-13). The full-observer basis (eigenvector condition 1e9 … 1e10,
    balanced ||A − LC|| 2e7 … 6e9 for the plants' 5 … 36) gave Ĝ 1.7e-4, 1.2e-2, 8e-2 off (seeds 30, 23, 31) and G1,
    after the coprime factorisation its unstable G1 then needed, 0.99 off (seed 20). The basis is the plant's stable
    left coprime factorisation that moves only the poles outside the stability region (as the peer's ``glcf``): Q0 is
    stable and keeps every stable plant pole (to 1e-9 relative; eigenvalues of a realisation of condition ≤ 1e3 move
    by ≤ 1e3·N·eps·||A||, measured ≤ 5e-14)."""
    from fmu_fdi.design.problems.approximate_matching import interactor, reduced_system, stable_reduced_system
    from test_synthesis_random import _grid

    model = noisy_case(seed)
    Q0, G1, _ = reduced_system(model)
    Q0, G1 = stable_reduced_system(model, Q0, G1)
    ev, q = np.linalg.eigvals(model.A), np.linalg.eigvals(Q0.A)
    assert np.all(np.abs(q) < 1) if model.dt else np.all(q.real < 0)
    kept = ev[(np.abs(ev) < 1 - 1e-6) if model.dt else (ev.real < -1e-6)]
    assert kept.size and all(np.min(np.abs(q - p)) <= 1e-9 * max(1.0, abs(p)) for p in kept)
    Gh, Phi, K, _, _ = interactor(G1, 1.0)
    lam = _grid(model)
    cols = _cols(model)
    fw = np.r_[[c for f in model.faults for c in cols[f.name]], np.arange(model.nu + model.nd,
                                                                           model.nu + model.nd + model.nw)]
    fr = lambda S: _freqresp(S.A, S.B, S.C, S.D, lam)  # noqa: E731
    G1v = fr(G1)
    assert _relative_gap(G1v, fr(Q0) @ _ge_values(model, lam)[:, :, fw]) <= 1e-9
    m = 1.0 / lam if model.dt else 1.0 / (lam + 1.0)
    assert _relative_gap((m ** K)[:, None, None] * fr(Gh), fr(Phi) @ G1v) <= 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("seed, call", sorted(REALISATION_FIXED))
def test_approximate_matching_realisation_seeds_meet_the_judge(seed, call):
    _assert_case(seed, (call,))


def test_shipped_response_is_read_without_the_modes_a_filter_cancels():
    """``approximate_matching._fault_noise_response`` reads ``Q(λ) [Gf Gw; 0 0](λ)`` as the post-conditions read R:
    a fault-only integrator that the filter cancels exactly is not read as its rounding over the distance to it.

    ``y = f/s + (u + w)/(s + 2)`` and ``Q = [q  0]``, ``q = (s + ε)/(s + 1)`` realised as ``1 + (ε − 1)/(s + 1)``.
    ε = 0: the exact response is ``[1/(s + 1), s/((s + 1)(s + 2))]`` (closed form, numpy): read by the function to
    1e-12 of its peak at ω = 1e-12 … 1e-4 rad/s (measured 1.2e-16), while the product of values ``q(λ)·Gf(λ)``
    carries q's rounding over |λ| (measured 1e-8). ε = 1e-6 (a residue ~1e10 times the rounding bound of this
    order-3 design): the pole stays, the value is the closed form ``(λ + ε)/((λ + 1) λ)`` (1e6 at the lowest point)
    to 1e-9 (measured 2.9e-11)."""
    from fmu_fdi import FDIModel, component_fault
    from fmu_fdi.design.problems.approximate_matching import _fault_noise_response
    from fmu_fdi.design.toolkit.postconditions import _values
    from fmu_fdi.lti import LTI

    model = FDIModel.from_matrices(np.diag([0.0, -2.0]), [[0.0], [1.0]], [[1.0, 1.0]], Bw=[[0.0], [1.0]],
                                   faults=[component_fault("f", [[1.0], [0.0]])], y_names=["y1"], u_names=["u1"])
    lam = 1j * np.logspace(-12, -4, 9)
    Ge = _values(model.augmented(), lam)
    fw = [model.nu + model.nd + model.nw, model.nu + model.nd]  # the columns of f, then w
    for eps, rtol in ((0.0, 1e-12), (1e-6, 1e-9)):
        Q = LTI(np.array([[-1.0]]), np.array([[1.0, 0.0]]), np.array([[eps - 1.0]]), np.array([[1.0, 0.0]]))
        exact = np.stack([(lam + eps) / ((lam + 1) * lam), (lam + eps) / ((lam + 1) * (lam + 2))], axis=1)[:, None, :]
        read = _fault_noise_response(model, Q, lam, Ge)[0]
        assert _relative_gap(read, exact) <= rtol
        if eps == 0.0:  # the naive product misses by q's rounding over |λ|: the reading above is needed
            assert _relative_gap((_values(Q, lam) @ Ge)[:, :, fw], exact) > 1e3 * rtol
