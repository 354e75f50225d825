"""approximate_model_matching(mindeg=True): the Type 2 cover against the re-solve it replaced, same run.

The baseline is approximate_matching.py as of a git revision (default 19b534a, the last whose mindeg
re-solved each row by exact model matching of the reference ``Q_i [Gf Gw]``), loaded from ``git show`` as a
sibling module of the current one (its imports resolve to the current package, so both stand on the same
core, including least_solve's balanced tolerance). Cases: tests/test_mindeg.py's (Varga 2017 Examples
5.11, 5.14-5.17, 5.16 at 0.1 s, Niemann at 1 ms, seed 14), Niemann's continuous model and the
non-standard seed 6. Per case: the design time without mindeg, the mindeg stage's time of old and new
(each module's ``_least_order`` called on the same optimal filter and grid, captured from one design, the
two alternating ``R`` times, best kept) and their ratio, the row orders (optimal → lowered) of each; then
the geometric mean of the stage ratios.
Run: python benchmarks/mindeg_time.py [R] [REV]

``--seeds A-B`` (or a list ``A,B,C``) instead: the random H∞ family of tests/test_synthesis_ammp.py (reltol 1e-6),
the mindeg stage of the current module with and without its re-solve candidate (``_resolved_row``), and the
baseline's (REV, default f08e977) without it, each called on the same optimal filter and grid: row orders
(optimal → lowered) and stage times per seed, the seeds where the re-solve still lowers further than the covers
alone (now and in the baseline), and the geometric means of the time ratios cover-only / both and cover-only
now / baseline.
Run: python benchmarks/mindeg_time.py --seeds 0-29 [REV]
"""
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from matching_time import baseline  # noqa: E402
from test_mindeg import CASES, static  # noqa: E402
from test_synthesis_ammp import _random_case  # noqa: E402
from test_synthesis_published import niemann  # noqa: E402

from fmu_fdi.design.problems import approximate_matching as new  # noqa: E402
from fmu_fdi.linalg import single_blas_thread  # noqa: E402


def best(fn, reps):
    out, t = None, np.inf
    for _ in range(reps):
        t0 = time.perf_counter()
        out = fn()
        t = min(t, time.perf_counter() - t0)
    return out, t


def _covers_only(mod, args):
    """``mod._least_order(*args)`` with its re-solve candidate switched off: ``(info, seconds)``."""
    real = mod._resolved_row
    mod._resolved_row = lambda *a, **k: (None, "")
    try:
        (_, info), t = best(single_blas_thread(lambda: mod._least_order(*args)), 1)
    finally:
        mod._resolved_row = real
    return info, t


def seeds(which, rev: str = "f08e977"):
    real_lo = new._least_order
    old = baseline(rev, "approximate_matching")
    wins, wins_old, ratios, ratios_old = [], [], [], []
    print(f"{'seed':>4s} {'optimal':>12s} {'covers+re-solve':>16s} {'s':>7s} {'covers only':>12s} {'s':>7s} "
          f"{'baseline covers only':>21s} {'s':>7s}")
    for seed in which:
        model, Mr = _random_case(seed)
        captured = {}

        def spy(*args):
            captured["args"] = args
            return real_lo(*args)

        new._least_order = spy
        try:
            new.approximate_model_matching(model, Mr, mindeg=True, reltol=1e-6)
        except Exception as exc:  # noqa: BLE001 - a design refused before the stage: reported, not timed
            print(f"{seed:4d} design refused: {type(exc).__name__}: {str(exc)[:80]}")
            continue
        finally:
            new._least_order = real_lo
        args = captured["args"]
        (_, both), t_both = best(single_blas_thread(lambda: real_lo(*args)), 1)
        alone, t_alone = _covers_only(new, args)
        before, t_before = _covers_only(old, args)
        if sum(both["row_orders"]) < sum(alone["row_orders"]):
            wins.append(seed)
        if sum(both["row_orders"]) < sum(before["row_orders"]):
            wins_old.append(seed)
        ratios.append(t_alone / t_both)
        ratios_old.append(t_alone / t_before)
        print(f"{seed:4d} {str(both['row_orders_before']):>12s} {str(both['row_orders']):>16s} {t_both:7.2f} "
              f"{str(alone['row_orders']):>12s} {t_alone:7.2f} {str(before['row_orders']):>21s} {t_before:7.2f}")
    print(f"seeds where the re-solve lowers further than the covers alone: {wins} (baseline {rev}: {wins_old})")
    print(f"geometric mean of the stage time ratio covers-only / covers+re-solve: "
          f"{float(np.exp(np.mean(np.log(ratios)))):.2f}")
    print(f"geometric mean of the stage time ratio covers-only / baseline covers-only: "
          f"{float(np.exp(np.mean(np.log(ratios_old)))):.2f}")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--seeds":
        spec = sys.argv[2] if len(sys.argv) > 2 else "0-29"
        if "-" in spec:
            lo, hi = (int(v) for v in spec.split("-"))
            which = list(range(lo, hi + 1))
        else:
            which = [int(v) for v in spec.split(",")]
        return seeds(which, *sys.argv[3:4])
    reps = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    rev = sys.argv[2] if len(sys.argv) > 2 else "19b534a"
    old = baseline(rev, "approximate_matching")
    cases = dict(CASES)
    cases["niemann"] = (niemann, static([[1.0, 0.0]]), dict(sdeg=-5, reltol=1e-5))
    cases["seed6"] = (lambda: _random_case(6)[0], _random_case(6)[1], {})
    ratios = []
    print(f"{'case':10s} {'design s':>9s} {'old stage s':>11s} {'new stage s':>11s} {'new/old':>8s}  old orders → "
          f"new orders")
    for name, (make, Mr, kw) in sorted(cases.items()):
        model = make()
        captured = {}
        real = new._least_order

        def spy(*args):
            captured["args"] = args
            return real(*args)

        new._least_order = spy
        try:
            t0 = time.perf_counter()
            new.approximate_model_matching(model, Mr, mindeg=True, **kw)
            t0 = time.perf_counter() - t0
        finally:
            new._least_order = real
        args = captured["args"]
        s_old = s_new = np.inf
        for _ in range(reps):  # alternating: the machine's load falls on both alike
            # one BLAS thread, as inside approximate_model_matching
            (_, io), t = best(single_blas_thread(lambda: old._least_order(*args)), 1)
            s_old = min(s_old, t)
            (_, inew), t = best(single_blas_thread(lambda: new._least_order(*args)), 1)
            s_new = min(s_new, t)
        ratios.append(s_new / s_old)
        print(f"{name:10s} {t0:9.3f} {s_old:11.3f} {s_new:11.3f} {s_new / s_old:8.2f}  "
              f"{io['row_orders_before']} → {io['row_orders']}   {inew['row_orders_before']} → {inew['row_orders']}")
    print(f"geometric mean of the mindeg stage ratio new/old: {float(np.exp(np.mean(np.log(ratios)))):.2f}")


if __name__ == "__main__":
    main()
