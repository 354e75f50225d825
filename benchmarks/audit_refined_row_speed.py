"""Cost of ``least_solve._refined_row`` (the least-order matching row's numerator refitted to the matching equation)
in ``model_matching``: the seeded matching families of tests/test_synthesis_matching_order.py (stable, and unstable
with updating), each design timed with the refit and without it (``_refined_row`` replaced by the identity) in the
same run, interleaved, one BLAS thread; prints total times, their ratio, and the designs whose verdict differs.

Run: OMP_NUM_THREADS=1 python benchmarks/audit_refined_row_speed.py [N] [first_seed]
"""
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import fmu_fdi.design.toolkit.least_solve as ls  # noqa: E402
from fmu_fdi.design.problems.matching import model_matching  # noqa: E402
from fmu_fdi.errors import DesignError  # noqa: E402
from test_synthesis_matching_order import _detection_reference  # noqa: E402


def _design(model, ref, unstable):
    t = time.perf_counter()
    try:
        model_matching(model, ref.Rf, updating=unstable)
        ok = "ok"
    except DesignError as exc:
        ok = f"refused: {str(exc)[:80]}"
    return time.perf_counter() - t, ok


def main(N: int = 100, first: int = 0) -> None:
    refit, plain = ls._refined_row, (lambda model, Mi, N, p, good, tol=0.0: N)
    tot = {"refit": 0.0, "plain": 0.0}
    for seed in range(first, first + N):
        for unstable in (False, True):
            try:
                model, ref = _detection_reference(seed, unstable)
            except DesignError:
                continue
            res = {}
            for name, fn in (("plain", plain), ("refit", refit)):
                ls._refined_row = fn
                dt, res[name] = _design(model, ref, unstable)
                tot[name] += dt
            if res["plain"] != res["refit"]:
                print(f"seed {seed} {'unstable' if unstable else 'stable'}: without {res['plain']}; "
                      f"with {res['refit']}", flush=True)
    ls._refined_row = refit
    print(f"total: without the refit {tot['plain']:.1f} s, with it {tot['refit']:.1f} s, "
          f"ratio {tot['refit'] / tot['plain']:.3f}")


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:]]
    main(*args)
