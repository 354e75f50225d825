"""Counts ok / refused / broken of the exact synthesis on the seeded ill-scaled random models,
judged independently (tests/test_synthesis_random.py: numpy frequency responses of R = Q·Ge, rows
normalised to smallest required fault peak 1, ‖R_u‖, ‖R_d‖ ≤ 1e-7, R stable by PBH, Q nonzero).

Per design call (nullspace_design, structured_bank on the rows achievable_structure lists,
dedicated/generalized banks): "ok" (returned and meets the judge), "refused" (DesignError on a
request the rank test says is not achievable), "broken" (a returned design that fails the judge,
an achievable request refused, another exception than DesignError, or a model that cannot be
built). Prints the totals per call kind, the kinds of breakage, and the design time per model.

Run: python benchmarks/synthesis_random_judged.py [N] [first_seed] [-v]
"""
import re
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_synthesis_random import _describe, check_case  # noqa: E402


def _kind(detail: str) -> str:
    """A short class of a breakage for the totals."""
    for pat, name in (("instead of DesignError", "crash"), ("achievable request refused", "achievable refused"),
                      ("cannot be built", "model not built"), ("unstable/marginal pole", "unstable R/Q"),
                      ("numerically zero", "zero Q"), ("invisible", "fault invisible"),
                      (r"‖R_(u|d|w)‖", "u/d/w leakage"), ("excluded fault", "excluded-fault leakage")):
        if re.search(pat, detail):
            return name
    return "other"


def run(N: int = 40, first: int = 0, verbose: bool = False):
    totals: dict[str, Counter] = {}
    kinds: Counter = Counter()
    times = []
    t0 = time.perf_counter()
    for seed in range(first, first + N):
        t = time.perf_counter()
        res = check_case(seed, max_rows=None)
        times.append(time.perf_counter() - t)
        for what, status, detail in res:
            key = what.split("(")[0]
            totals.setdefault(key, Counter())[status] += 1
            if status == "broken":
                kinds[_kind(detail)] += 1
            if verbose or status == "broken":
                print(f"seed {seed:3d} {_describe(seed)[:60]:60s} {what:28s} {status:8s} {detail[:160]}")
    print("\ncounts per call (ok / refused / broken):")
    for key, c in totals.items():
        print(f"  {key:22s} {c['ok']:4d} {c['refused']:4d} {c['broken']:4d}")
    allc = sum(totals.values(), Counter())
    print(f"  {'total':22s} {allc['ok']:4d} {allc['refused']:4d} {allc['broken']:4d}")
    print("breakage kinds:", dict(kinds))
    print(f"time per model: median {sorted(times)[len(times) // 2]:.2f} s, max {max(times):.2f} s, "
          f"total {time.perf_counter() - t0:.1f} s")
    return allc


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "-v"]
    run(int(args[0]) if args else 40, int(args[1]) if len(args) > 1 else 0, "-v" in sys.argv)
