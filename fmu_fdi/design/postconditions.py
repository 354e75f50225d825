"""Post-conditions every synthesis function checks before it returns (issue 13).

A residual generator ``Q`` with internal form ``R(λ) = Q(λ) Ge(λ)`` is judged point by
point on a frequency grid Λ (no minimal realisation, no rank decision), with figures that
are relative to the data so that rounding of an exact design is ~1e-12 whatever the
scaling of the model:

- decoupling of a group X of inputs (u, d, and w for exact designs; faults with
  ``S[i, j] = 0`` for structured rows):
  ``δ_X = max_λ ||R_X(λ)|| / max_λ (||Q(λ)|| ||Ge_X(λ)||)`` must be ``≤ dec_tol``
  (the backward-error scale of the product ``Q Ge``; peaks, not a pointwise ratio, which
  is 0/0 at a transmission zero of ``Ge_X``);
- visibility of a required fault j: the cosine
  ``γ_j = max_λ ||R_fj(λ)|| / (||Q_y(λ)|| ||Gf_j(λ)||)`` (over the points where the bound is
  not negligible, i.e. away from zeros of ``Gf_j``) must exceed ``FDtol``; a row whose
  fault gain is rounding noise against its own gain (``γ_j ~ 1e-16``) is refused instead
  of being "normalised" into a filter with gain ~1e12;
- strong detectability at frequencies Ω: ``||R_fj(jω)|| > FDGainTol · max_λ ||R_fj(λ)||``;
- stability with margin: ``max Re p < smarg`` (continuous) or ``max |p| < smarg`` (discrete),
  by default just inside the stability boundary (Varga's ``smarg``).

The achieved figures go into ``gen.info['postconditions']``; a failure raises
:class:`~fmu_fdi.errors.DesignError` naming the condition, the numbers and the option that
may help. Reference: A. Varga, *Solving Fault Diagnosis Problems*, Springer 2017, sec. 5.1
(the conditions of the EFDP/EFDIP), and the checks of FaultDetectionTools.jl's tests.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import DesignError
from ..linalg import EPS
from ..lti import LTI, frequency_grid

class NumericalDesignError(DesignError):
    """A design broke a numerical post-condition (decoupling, basis rank, stability of the
    realisation): other rank tolerances may succeed where the problem itself is solvable."""


#: default decoupling tolerance: the relative leakage an exact design may show. Rounding of
#: the product Q·Ge is ~n·cond·eps ≈ 1e-12 for well-conditioned data, but least-order rows of
#: degree 3-10 on real plants (the VTOL sensor bank: 1e-7 - 2.4e-7) carry the accuracy of
#: their parity vectors, ~1e-7; the broken bases this check exists for leaked 7e-6 … 1 (the
#: random set of issue 13). 1e-6 sits between the two.
DEC_TOL = 1e-6


def default_smarg(dt: float) -> float:
    """Stability margin just inside the boundary: ``-sqrt(eps)`` or ``1 - sqrt(eps)``."""
    return 1.0 - np.sqrt(EPS) if dt else -np.sqrt(EPS)


def _eval_points(model, Q: LTI, freqs) -> tuple[np.ndarray, np.ndarray]:
    extra = () if freqs is None else np.atleast_1d(np.asarray(freqs, float))
    omega = frequency_grid([model.lti(), Q] if Q.n else [model.lti()], num=120, extra=extra)
    omega = omega[np.isfinite(omega)]
    lam = np.exp(1j * omega * model.dt) if model.dt else 1j * omega
    return omega, lam


def _values(sys: LTI, lam: np.ndarray) -> np.ndarray:
    """Values at the points ``lam`` from a balanced realisation (non-finite where λ is a pole)."""
    if sys.n:
        bal, _ = sys.balanced()
        sys = bal
    out = np.full((lam.size, sys.p, sys.m), np.nan, complex)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k, l in enumerate(lam):
            try:
                out[k] = sys.evalfr(l)
            except np.linalg.LinAlgError:
                pass
    return out


def _nrm(X: np.ndarray) -> np.ndarray:
    """2-norms of a stack of matrices (K, p, m) -> (K,)."""
    if X.shape[1] == 0 or X.shape[2] == 0:
        return np.zeros(X.shape[0])
    return np.linalg.norm(X, ord=2, axis=(1, 2))


def _rel(resp: np.ndarray, bound: np.ndarray) -> float:
    """``max_λ ||R_X(λ)|| / max_λ ||Q(λ)|| ||Ge_X(λ)||``: peaks over the grid, not a pointwise
    ratio, which is 0/0 — any number — at a transmission zero of ``Ge_X``."""
    top = float(np.max(bound)) if bound.size else 0.0
    return float(np.max(resp)) / top if top > 0 else 0.0


def _cosine(resp: np.ndarray, bound: np.ndarray, floor: float = 1e-6) -> float:
    """``max_λ ||R_f(λ)|| / (||Q_y(λ)|| ||Gf(λ)||)`` over the points where the bound is at least
    ``floor`` times its peak: pointwise, so an integrator's huge low-frequency gain does not
    hide a fault seen elsewhere; transmission zeros of Gf (bound → 0, a 0/0) are left out."""
    top = float(np.max(bound)) if bound.size else 0.0
    if top <= 0:
        return 0.0
    keep = bound >= floor * top
    return float(np.max(resp[keep] / bound[keep]))


def check_generator(gen, *, decouple=("u", "d"), structure=None, faults=None, block: bool = False,
                    freqs=None, FDtol: float = 1e-4, FDGainTol: float = 0.01, smarg: float | None = None,
                    dec_tol: float = DEC_TOL, hints: dict | None = None, raise_error: bool = True) -> dict:
    """Check a residual generator's contract; return its figures or raise :class:`DesignError`.

    Parameters
    ----------
    gen : ResidualGenerator
    decouple : sequence of {'u', 'd', 'w'}
        Input groups that must be decoupled exactly.
    structure : array_like of 0/1, optional
        One row per residual group (or one row for ``block=True``); columns are ``faults``.
        1: the fault must be visible; 0: it must be decoupled. Default: every fault visible.
    faults : list of str, optional
        Fault names of the structure's columns (default: all faults). Others are don't-care.
    block : bool
        Judge all residual outputs as one group (detection designs with ``rdim > 1``).
    freqs : array_like, optional
        Frequencies (rad/s) at which every required fault must be strongly visible.
    FDtol, FDGainTol, smarg, dec_tol : float
        Thresholds; see the module docstring.
    hints : dict, optional
        ``condition -> advice`` overriding the default advice in the error message.
    raise_error : bool
        With False, return the figures with ``'failures'`` instead of raising.
    """
    model, Q = gen.model, gen.Q
    names = list(model.fault_names if faults is None else faults)
    groups = [list(range(Q.p))] if block else gen.groups
    S = np.ones((len(groups), len(names)), dtype=int) if structure is None else np.atleast_2d(structure).astype(int)
    if S.shape != (len(groups), len(names)):
        raise ValueError(f"structure has shape {S.shape}, expected {(len(groups), len(names))}")
    adv = {
        "finite": "the design produced NaN/Inf: the model data is singular for this method",
        "decoupling": "the null-space/rank decisions are ill-conditioned for this model: pass atol/rtol (rank "
                      "tolerances), balance or rescale the model's states, or ask for a smaller structure",
        "structure": "a fault marked 0 leaks into its residual: loosen/tighten atol/rtol, or check the structure "
                     "against fmu_fdi.isolability(model)",
        "visibility": "a required fault is rounding noise in its residual: it is not detectable once the 0-faults "
                      "and d are decoupled (lower FDtol only if the fault really is this weak)",
        "strong": "pass other freqs, or lower FDGainTol",
        "stability": "pass stable poles / a smaller sdeg, or relax smarg",
    }
    adv.update(hints or {})
    fig: dict = {"dec_tol": dec_tol, "FDtol": FDtol}
    failures: list[tuple[str, str]] = []
    if not (np.all(np.isfinite(Q.A)) and np.all(np.isfinite(Q.B)) and np.all(np.isfinite(Q.C))
            and np.all(np.isfinite(Q.D))):
        failures.append(("finite", "the filter's state-space matrices contain NaN or Inf"))
        return _finish(fig, failures, adv, gen, raise_error)

    # stability with margin
    poles = Q.poles()
    if smarg is None:
        smarg = default_smarg(model.dt)
    if poles.size:
        worst = float(np.max(np.abs(poles))) if model.dt else float(np.max(poles.real))
        fig["pole_extreme"] = worst
        fig["smarg"] = smarg
        if worst >= smarg:
            what = "largest |pole|" if model.dt else "largest Re(pole)"
            failures.append(("stability", f"{what} = {worst:.6g} is not below the stability margin smarg = {smarg:.6g}"))

    omega, lam = _eval_points(model, Q, freqs)
    Ge = _values(model.augmented(), lam)
    Qv = _values(Q, lam)
    ok = np.all(np.isfinite(Ge), axis=(1, 2)) & np.all(np.isfinite(Qv), axis=(1, 2))
    if not np.any(ok):
        failures.append(("finite", "the filter or the model cannot be evaluated on the frequency grid"))
        return _finish(fig, failures, adv, gen, raise_error)
    omega, lam, Ge, Qv = omega[ok], lam[ok], Ge[ok], Qv[ok]
    sl = model.group_slices()
    p = model.ny
    fsl = sl["f"]
    fcols = {f.name: np.arange(fsl.start, fsl.stop)[f.columns] for f in model.faults}
    dec_cols = np.concatenate([np.arange(sl[g].start, sl[g].stop) for g in decouple]) if decouple else np.zeros(0, int)
    dec_label = "+".join(g for g in decouple if sl[g].stop > sl[g].start)

    decs, zero_leaks, vis, strong = [], [], [], []
    for i, g in enumerate(groups):
        Qi = Qv[:, g, :]
        nQ = _nrm(Qi)
        nQy = _nrm(Qi[:, :, :p])
        R = np.einsum("kiq,kqc->kic", Qi, Ge)
        if dec_cols.size:
            d = _rel(_nrm(R[:, :, dec_cols]), nQ * _nrm(Ge[:, :, dec_cols]))
            decs.append(d)
            if d > dec_tol:
                failures.append(("decoupling", f"residual {i + 1}: {dec_label} leak with relative size {d:.3g} > "
                                               f"dec_tol = {dec_tol:.3g}"))
        row_vis, row_strong, zl = [], [], 0.0
        for j, nm in enumerate(names):
            c = fcols[nm]
            Rn = _nrm(R[:, :, c])
            if S[i, j]:
                gam = _cosine(Rn, nQy * _nrm(Ge[:, :p, c]))
                row_vis.append(gam)
                if gam <= FDtol:
                    failures.append(("visibility", f"residual {i + 1}: fault '{nm}' has relative gain {gam:.3g} "
                                                   f"≤ FDtol = {FDtol:.3g}"))
                if freqs is not None:
                    peak = float(np.max(Rn))
                    for w in np.atleast_1d(np.asarray(freqs, float)):
                        k = np.argmin(np.abs(omega - w))
                        ratio = float(Rn[k] / peak) if peak > 0 else 0.0
                        row_strong.append(ratio)
                        if ratio <= FDGainTol:
                            failures.append(("strong", f"residual {i + 1}: fault '{nm}' has gain {ratio:.3g} × its "
                                                       f"peak at ω = {w:g} rad/s ≤ FDGainTol = {FDGainTol:.3g}"))
            else:
                z = _rel(Rn, nQ * _nrm(Ge[:, :, c]))
                zl = max(zl, z)
                if z > dec_tol:
                    failures.append(("structure", f"residual {i + 1}: fault '{nm}' must be decoupled (S = 0) but "
                                                  f"leaks with relative size {z:.3g} > dec_tol = {dec_tol:.3g}"))
        zero_leaks.append(zl)
        vis.append(min(row_vis, default=float("inf")))
        strong.append(min(row_strong, default=float("inf")))
    fig.update({"decoupling": max(decs, default=0.0), "structure_leak": max(zero_leaks, default=0.0),
                "fault_visibility": min(vis, default=float("inf")),
                "filter_peak_gain": float(np.max(_nrm(Qv)))})
    if freqs is not None:
        fig["strong_gain_ratio"] = min(strong, default=float("inf"))
    return _finish(fig, failures, adv, gen, raise_error)


def _finish(fig: dict, failures, adv: dict, gen, raise_error: bool) -> dict:
    if failures and raise_error:
        kinds = list(dict.fromkeys(k for k, _ in failures))
        shown = [m for _, m in failures[:6]] + ([f"... {len(failures) - 6} more"] if len(failures) > 6 else [])
        cls = NumericalDesignError if set(kinds) & {"decoupling", "structure", "stability", "finite"} else DesignError
        raise cls(f"{gen.method} design fails its post-conditions ({', '.join(kinds)}): " + "; ".join(shown)
                          + ". " + " ".join(f"[{k}] {adv[k]}." for k in kinds))
    if failures:
        fig["failures"] = [m for _, m in failures]
    gen.info["postconditions"] = fig
    return fig
