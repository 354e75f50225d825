"""The Kalman filter's Riccati solve accepted by a forward measure, against a baseline revision accepting by the
residual.

Problems: tests/test_kalman_riccati.py's seeded ill-scaled ones (``_problem``) and tests/test_riccati_forward.py's
deflated ones (``deflated_problem``: the process noise reaches only an invariant subspace), seeds 0–SEEDS−1 × trials
0–2 each. Each is solved by ``filter_riccati`` of the current code and of REV (default ``main``; loaded from
``git show`` as benchmarks/riccati_refinement.py does). Every returned ``(P, L)`` is judged by the independent forward
measure of tests/test_riccati_forward.py (``forward_error``: scipy's Lyapunov of the filter run with ``L``, P_K = P to
first order iff P is the stabilising solution) and the relative residual; a DesignError is a refusal. Prints the
problems where the sides differ, per side and family: designed / refused, the designs with a forward error above 1e-6
and 1e-5, the largest; and the time per solve (best of R calls; run with OPENBLAS_NUM_THREADS=1): the geometric mean
of current/baseline over the problems both design, and the ratio of the totals.

Run: OPENBLAS_NUM_THREADS=1 python benchmarks/riccati_forward.py [SEEDS] [REV] [R]

27 Nov, kalman17 (60 seeds, baseline ae569eb, R = 3, one BLAS thread, 2-core machine shared with other
runs), final code:
- filter_riccati full:     ae569eb 175 designed / 5 refused, forward error > 1e-6: 10, > 1e-5: 5, max 0.81 (54/2,
  residual 2e-11) → 175 / 5, > 1e-6: 1 (58/2, 1.4e-6: the judge's own floor; the design's correction reads below
  1e-6), max 1.4e-6;
- filter_riccati deflated: ae569eb 172 / 8, > 1e-6: 32, > 1e-5: 18, max 1.2e-2 → 172 / 8, 0 above 1e-6, max 7.7e-7;
  time per solve current/baseline: geometric mean 1.375 over the 347 both design, total 2.70 s / 2.03 s = 1.33
  (a Schur form of the closed loop and the long-double residual: milliseconds per solve at n ≤ 30);
- spectral_riccati (factored control form) full: 178 / 2 both; > 1e-6: 3 → 1 (51/0, 7.5e-6 where Σ's condition is
  1.6e16: the judge's gain floor), max 4.9e-6 → 7.5e-6; deflated 180 / 0 both, max 9.2e-7 both; time geometric mean
  1.54, total 1.58 s / 1.05 s = 1.51.
  With the correction's residual in double (dda05bc) 3 more filters were refused (43/2, 47/0, 51/1: its floor 1e-6 …
  6e-5 where the judge reads 1e-11 … 1.5e-7).

27 Nov, kalman18 (60 seeds, baseline 253b4cb, R = 1, one BLAS thread, machine shared with four sessions; a third
family, ``scaled``: tests/test_riccati_failure_messages.py's random problems scaled over nine decades), final code —
Q̄'s rank in its graded scaling, deflation and reduced solve in Ā's balanced coordinates:
- filter_riccati full:     175 / 5 both (Σ not positive definite); > 1e-6: 1 → 0 (58/2 1.4e-6 → 2.1e-7), max 1.40e-6
  → 6.99e-7;
- filter_riccati deflated: 172 / 8 → 180 / 0 (2/0–2, 15/0–2, 54/0–1 refused as 'no stabilising solution' before;
  now forward errors 2.3e-12 … 8.9e-8); 0 above 1e-6 both; max 7.72e-7 → 5.97e-7;
- filter_riccati scaled:   171 / 9 → 180 / 0; 0 above 1e-6 both; max 8.65e-7 → 1.37e-7;
  time per solve current/baseline: geometric mean 1.071 over the 518 both design, total 5.03 s / 4.77 s = 1.053 (an
  earlier run of the first two families, same code: 1.043, 0.981);
- spectral_riccati (unchanged code): 178 / 2 and 180 / 0 both, figures identical; time 1.025 / 1.065 (noise).
"""
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from fmu_fdi.design.observers import _observer as new  # noqa: E402
from fmu_fdi.design.toolkit import approximate as new_approximate  # noqa: E402
from riccati_refinement import baseline, timed_filter  # noqa: E402
from test_kalman_riccati import _problem  # noqa: E402
from test_riccati_forward import deflated_problem, filter_gain, forward_error  # noqa: E402
from test_riccati_failure_messages import scaled_random_case  # noqa: E402


def scaled_problem(seed: int, trial: int):
    """tests/test_riccati_failure_messages.py's random problems scaled over nine decades (A, C, Qx and R in the scaled
    coordinates), numbered ``3·seed + trial``."""
    return scaled_random_case(3 * seed + trial)[:5]


def filter_forward(module, data, repeats: int):
    """``(forward error or None if refused, seconds)`` of ``module.filter_riccati`` on ``data = (A, C, Qx, R, dt)``."""
    A, C, Qx, R, dt = data
    out, best = timed_filter(module, A, C, Qx, R, dt, repeats)
    return (None if out is None else forward_error(A, C, Qx, R, dt, out.P, out.L)), best


def factored(problem):
    """The seeded problem as spectral_riccati's factored control-form equation: ``(Aᵀ, Cᵀ)``, ``Q = HᵀH`` with
    ``H = [Gᵀ; 0]`` (``Qx = GGᵀ`` by an eigendecomposition), ``R = DᵀD``, ``D = [0; √R]``."""
    def make(seed, trial):
        A, C, Qx, R, dt = problem(seed, trial)
        lam, V = np.linalg.eigh(Qx)
        G = V * np.sqrt(np.clip(lam, 0, None))
        n, p = A.shape[0], R.shape[0]
        H = np.vstack([G.T, np.zeros((p, n))])
        D = np.vstack([np.zeros((n, p)), np.sqrt(R)])
        return A, C, H.T @ H, R, dt, H, D
    return make


def spectral_forward(module, data, repeats: int):
    """``(forward error or None, best seconds)`` of ``module.spectral_riccati`` on ``(Aᵀ, Cᵀ, H, D)`` of ``data``
    (:func:`factored`), judged with the gain it implies."""
    A, C, Q, R, dt, H, D = data
    best, X = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        with np.errstate(all="ignore"):
            X = module.spectral_riccati(A.T.copy(), C.T.copy(), H, D, dt)
        best = min(best, time.perf_counter() - t0)
    if X is None:
        return None, best
    try:
        return forward_error(A, C, Q, R, dt, X, filter_gain(A, C, R, X, dt)), best
    except (np.linalg.LinAlgError, ValueError):
        return np.inf, best


def compare(label: str, families, run, old, new, seeds: int, rev: str, repeats: int) -> None:
    """Both sides of ``run(module, data, repeats)`` on every problem of ``families``: counts, forward errors, times."""
    ratios, t_old, t_new = [], 0.0, 0.0
    show = lambda e: "refused" if e is None else f"{e:.1e}"  # noqa: E731
    for family, problem in families:
        fw = {"baseline": [], "current": []}
        refused = {"baseline": 0, "current": 0}
        for seed in range(seeds):
            for trial in range(3):
                data = problem(seed, trial)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    eo, so = run(old, data, repeats)
                    en, sn = run(new, data, repeats)
                for side, e in (("baseline", eo), ("current", en)):
                    if e is None:
                        refused[side] += 1
                    else:
                        fw[side].append(e)
                t_old, t_new = t_old + so, t_new + sn
                if eo is not None and en is not None:
                    ratios.append(sn / so)
                if (eo is None) != (en is None) or max(eo or 0, en or 0) > 1e-6:
                    print(f"{label} {family:>8s} {seed:3d}/{trial}  n={data[0].shape[0]:2d} dt={data[4]:g}  forward "
                          f"{rev}: {show(eo):>8s} ({so:.3f} s)  current: {show(en):>8s} ({sn:.3f} s)", flush=True)
        for side in ("baseline", "current"):
            e = np.array(fw[side])
            print(f"{label} {family:>8s} {side:>8s}: {e.size} designed / {refused[side]} refused; "
                  f"forward error > 1e-6: "
                  f"{int(np.sum(e > 1e-6))}, > 1e-5: {int(np.sum(e > 1e-5))}, max {e.max() if e.size else np.nan:.2e}")
    print(f"{label} time per solve current/baseline: geometric mean {np.exp(np.mean(np.log(ratios))):.3f} over the "
          f"{len(ratios)} problems both design; total {t_new:.2f} s / {t_old:.2f} s = {t_new / t_old:.3f}")


def main(seeds: int = 60, rev: str = "main", repeats: int = 1) -> None:
    old = baseline(rev)
    compare("filter_riccati", (("full", _problem), ("deflated", deflated_problem), ("scaled", scaled_problem)),
            filter_forward, old, new, seeds, rev, repeats)
    # spectral_riccati alone (approximate.coouter_inverse, approximate_matching's filter DARE): the factored
    # control-form equations of both families, judged by the same closed-loop covariance of the gain it implies
    compare("spectral_riccati", (("full", factored(_problem)), ("deflated", factored(deflated_problem))),
            spectral_forward, old, new_approximate, seeds, rev, repeats)


if __name__ == "__main__":
    args = sys.argv[1:]
    main(int(args[0]) if args else 60, args[1] if len(args) > 1 else "main", int(args[2]) if len(args) > 2 else 1)
