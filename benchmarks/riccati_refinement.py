"""The Kalman filter's Riccati solve with Newton refinement against a baseline revision without it, same run.

Problems: tests/test_kalman_riccati.py's seeded ill-scaled ones (``_problem(seed, trial)``: random models, process
noise of rank ⌈n/3⌉ with rows scaled over eight decades, R = r·I, r ∈ [1e-6, 1e2]), seeds 0–59 × trials 0–2 by
default. Each is solved by ``filter_riccati`` of the current code and of the baseline (``toolkit/approximate.py`` and
``observers/_observer.py`` as of REV, default ``main``, loaded from ``git show`` as sibling modules; the baseline
observer module calls the baseline ``spectral_riccati``). Every returned ``P`` is judged by numpy — the relative
residual of the full equation (the test file's ``_relative_residual``), ``P ⪰ 0`` and the closed loop ``A − L C``
stable; a DesignError is a refusal. Where a reference is reliable (:func:`reference`: the diagonally balanced
problem solved by scipy, its residual ≤ 1e-13), the forward error ``‖P − P_ref‖_F / ‖P_ref‖_F`` of each designed
``P`` is read too (a residual is a backward measure; on these ill-scaled equations a small one does not bound the
error of ``P``). Prints the problems where the two differ, the counts designed / refused /
wrong per side, and the time per solve: the geometric mean of the ratios current / baseline over the problems both
design, and the ratio of the total times (best of ``R`` calls each).

Run: python benchmarks/riccati_refinement.py [SEEDS] [REV] [R]

27 Nov, newton (same session, loaded 2-core machine, R = 3): main 134 designed / 46 refused / 0 wrong →
- Newton refinement (toolkit.riccati_newton) alone, 0c32678: 151 / 29 / 0 (17 designed, residuals 7.8e-12 … 4.1e-8);
  time per solve on the 134 both design: geometric mean 0.994, total 1.04;
- and the reduced equation in the caller's coordinates where nothing is deflated: 175 / 5 / 0 (the 5: innovation
  covariance not numerically positive definite, seeds 11/0, 27/2, 43/0, 43/1, 51/0); geometric mean 0.960, total 0.928.
  Without the refinement the coordinates alone give 167 / 13 / 0 and refuse two that main designs (4/1, 52/1: the direct
  answers 2–6e-8 there; Newton brings them within RICCATI_RTOL). On the 134 both design the residuals move both ways
  (16 lower, 12 higher by more than 10×), the largest 1.4e-8 → 5.3e-9.
  Final code (e7660c3 + this reading), R = 3: main 134 / 46 / 0, now 175 / 5 / 0; forward error against the balanced
  reference (where kept): main max 1.7e-2 (seed 15/0, residual 5.1e-11), 4 of 73 above 1e-6 → now max 2.8e-6
  (47/1), 1 of 76; time per solve geometric mean 1.011 on the 134, total 0.934.
"""
import importlib.util
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from fmu_fdi.design.observers import _observer as new  # noqa: E402
from fmu_fdi.errors import DesignError  # noqa: E402
from test_kalman_riccati import _problem, _relative_residual  # noqa: E402


def _module_at(rev: str, path: str, name: str, package: str):
    """The module ``path`` as of ``rev``, loaded as ``package.name`` (its relative imports resolve there)."""
    src = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:{path}"], check=True, capture_output=True,
                         text=True).stdout
    spec = importlib.util.spec_from_loader(f"{package}.{name}", loader=None)
    mod = importlib.util.module_from_spec(spec)
    mod.__package__ = package
    sys.modules[spec.name] = mod  # dataclasses look their module up there
    exec(compile(src, f"{rev}:{path}", "exec"), mod.__dict__)
    return mod


def baseline(rev: str):
    approx = _module_at(rev, "fmu_fdi/design/toolkit/approximate.py", "_approximate_baseline", "fmu_fdi.design.toolkit")
    obs = _module_at(rev, "fmu_fdi/design/observers/_observer.py", "_observer_baseline", "fmu_fdi.design.observers")
    obs.spectral_riccati = approx.spectral_riccati
    return obs


def reference(A, C, Qx, R, dt):
    """A reference solution for the forward error: scipy's solver on the problem balanced by the diagonal similarity
    of LAPACK GEBAL on ``A`` (powers of 2, exact), mapped back; kept only where its own relative residual in the
    original coordinates is at most 1e-13 (else None)."""
    import scipy.linalg as sla

    t = sla.matrix_balance(A, permute=False, separate=True)[1][0]
    try:
        Pb = (sla.solve_discrete_are if dt else sla.solve_continuous_are)(
            (A * t[None, :] / t[:, None]).T, (C * t[None, :]).T, Qx / t[:, None] / t[None, :], R)
        P = Pb * t[:, None] * t[None, :]
        return P if _relative_residual(A, C, Qx, R, P, dt) <= 1e-13 else None
    except (np.linalg.LinAlgError, ValueError):
        return None


def timed_filter(module, A, C, Qx, R, dt, repeats: int):
    """``(filter or None if refused, best seconds of `repeats` calls)`` of ``module.filter_riccati`` (S = 0)."""
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        try:
            out = module.filter_riccati(A, C, Qx, R, np.zeros((A.shape[0], C.shape[0])), dt)
        except DesignError:
            out = None
        best = min(best, time.perf_counter() - t0)
    return out, best


def judged(module, A, C, Qx, R, dt, repeats: int):
    """``(verdict, residual, seconds, P)``: 'ok' (residual ≤ 1e-7, P ⪰ 0, A − LC stable), 'refused' or 'wrong'."""
    out, best = timed_filter(module, A, C, Qx, R, dt, repeats)
    if out is None:
        return "refused", np.nan, best, None
    res = _relative_residual(A, C, Qx, R, out.P, dt)
    psd = np.linalg.eigvalsh((out.P + out.P.T) / 2)[0] >= -1e-8 * max(np.linalg.norm(out.P, 2), 1.0)
    ev = np.linalg.eigvals(A - out.L @ C)
    stable = np.all(np.abs(ev) < 1.0) if dt else np.all(ev.real < 0.0)
    return ("ok" if res <= 1e-7 and psd and stable else "wrong"), res, best, out.P


def main(seeds: int = 60, rev: str = "main", repeats: int = 1) -> None:
    old = baseline(rev)
    count = {"baseline": {}, "current": {}}
    forward = {"baseline": [], "current": []}  # ||P − P_ref||_F / ||P_ref||_F where the reference is kept
    ratios, t_old, t_new = [], 0.0, 0.0
    print(f"{'seed':>4s} {'trial':>5s} {'n':>3s} {'dt':>4s}  {'baseline ' + rev:>24s}  {'current':>24s}")
    for seed in range(seeds):
        for trial in range(3):
            A, C, Qx, R, dt = _problem(seed, trial)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                vo, ro, so, Po = judged(old, A, C, Qx, R, dt, repeats)
                vn, rn, sn, Pn = judged(new, A, C, Qx, R, dt, repeats)
                Pr = reference(A, C, Qx, R, dt)
            if Pr is not None:
                for side, v, P in (("baseline", vo, Po), ("current", vn, Pn)):
                    if v == "ok":
                        forward[side].append(float(np.linalg.norm(P - Pr) / np.linalg.norm(Pr)))
            for side, v in (("baseline", vo), ("current", vn)):
                count[side][v] = count[side].get(v, 0) + 1
            t_old, t_new = t_old + so, t_new + sn
            if vo == "ok" and vn == "ok":
                ratios.append(sn / so)
            if vo != vn or (vo == "ok" and not (rn <= 1e-8) and ro <= 1e-8):
                print(f"{seed:4d} {trial:5d} {A.shape[0]:3d} {dt:4g}  {vo:>8s} {ro:8.1e} {so:6.3f}s  "
                      f"{vn:>8s} {rn:8.1e} {sn:6.3f}s", flush=True)
    total = seeds * 3
    for side in ("baseline", "current"):
        c = count[side]
        print(f"{side:>8s}: {c.get('ok', 0)} designed / {c.get('refused', 0)} refused / {c.get('wrong', 0)} wrong "
              f"of {total}; forward error against the balanced reference (where its residual ≤ 1e-13, "
              f"{len(forward[side])} designed): max {max(forward[side], default=np.nan):.1e}, "
              f"{sum(e > 1e-6 for e in forward[side])} above 1e-6")
    print(f"time per solve current/baseline: geometric mean {np.exp(np.mean(np.log(ratios))):.3f} over the "
          f"{len(ratios)} problems both design; total {t_new:.2f} s / {t_old:.2f} s = {t_new / t_old:.3f}")


if __name__ == "__main__":
    args = sys.argv[1:]
    main(int(args[0]) if args else 60, args[1] if len(args) > 1 else "main", int(args[2]) if len(args) > 2 else 1)
