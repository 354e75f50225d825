"""Counts ok / refused / broken of the approximate designs on the seeded ill-scaled random models with
noise, judged independently (tests/test_approximate_random.py: numpy frequency responses of
R = Q·[Gu Gd Gw Gf; I 0 0 0], rows normalised to fault gain 1 (β = 1 for model detection),
‖R_u‖, ‖R_d‖ ≤ 1e-7, R stable by PBH, Q nonzero, the reported gap / matching error / MDgap equal to
numpy's refined peaks within the file's FIG_RTOL / ERR_RTOL; a matching error no worse than Q = 0 and
than the exact detection row it takes as reference).

Calls per model: nullspace_design (AFD), afdi_bank on up to 3 rows achievable_structure lists,
approximate_model_matching with Mr = an exact detection row's fault response and with Mr = I,
approximate_model_detection_bank on a three-model set (stable plants only). "broken": a returned
design failing the judge, another exception than DesignError, an achievable AFD/AFDI request refused
(or a detection-row reference whose matching is refused: Q_ref itself is admissible).

Run: python benchmarks/approximate_random_judged.py [N] [first_seed] [-v] [--timeout=SECONDS]
(a call that gives no answer within the timeout counts as "timeout", none by default)
(seeds first_seed … first_seed + N − 1; default 20 models from seed 0)
"""
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_approximate_random  # noqa: E402
from test_approximate_random import check_case, noisy_case  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthesis_random_judged import KINDS, _kind as _kind_exact  # noqa: E402


def _kind(detail: str) -> str:
    """A short class of a breakage for the totals (the exact audit's classes and the figures' mismatches)."""
    return _kind_exact(detail, KINDS + (("gap: reported", "gap mismatch"), ("MDgap|MDperf", "MD figure mismatch"),
                                        ("matching error: reported", "error mismatch"),
                                        ("above", "error above a known filter's")))


def run(N: int = 20, first: int = 0, verbose: bool = False):
    totals: dict[str, Counter] = {}
    kinds: Counter = Counter()
    times = []
    t0 = time.perf_counter()
    for seed in range(first, first + N):
        t = time.perf_counter()
        res = check_case(seed)
        times.append(time.perf_counter() - t)
        m = noisy_case(seed)
        desc = f"n={m.n} p={m.ny} m={m.nu} nd={m.nd} nw={m.nw} nf={m.nf} {'disc' if m.dt else 'cont'}"
        for what, status, detail in res:
            totals.setdefault(what, Counter())[status] += 1
            if status == "broken":
                kinds[_kind(detail)] += 1
            if verbose or status == "broken":
                print(f"seed {seed:3d} {desc:40s} {what:34s} {status:8s} {detail[:220]}", flush=True)
    print("\ncounts per call (ok / refused / broken):")
    for key, c in totals.items():
        print(f"  {key:34s} {c['ok']:4d} {c['refused']:4d} {c['broken']:4d}" + (f"  ({c['timeout']} timed out)"
                                                                              if c['timeout'] else ""))
    allc = sum(totals.values(), Counter())
    print(f"  {'total':34s} {allc['ok']:4d} {allc['refused']:4d} {allc['broken']:4d}")
    print("breakage kinds:", dict(kinds))
    print(f"time per model: median {sorted(times)[len(times) // 2]:.2f} s, max {max(times):.2f} s, "
          f"total {time.perf_counter() - t0:.1f} s")
    return allc


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "-v" and not a.startswith("--timeout=")]
    for a in sys.argv[1:]:
        if a.startswith("--timeout="):
            test_approximate_random.CALL_TIMEOUT = int(a.split("=", 1)[1])
    run(int(args[0]) if args else 20, int(args[1]) if len(args) > 1 else 0, "-v" in sys.argv)
