"""The library judge's cost inside bank designs: every ``check_generator`` call ``structured_bank`` makes (the per-row
checks of ``nullspace._pencil_combine``/``_design`` and the bank's own check), replayed with main's judge and this
tree's in the same run.

Per exact audit seed (tests/test_synthesis_random.py's ``random_case``; ``structured_bank`` on every row
``achievable_structure`` lists, as benchmarks/synthesis_random_judged.py calls it): the bank is designed once with this
tree's code while every ``check_generator`` call of nullspace.py and banks.py is recorded (a deep copy of the generator
as passed, and the arguments). Each recorded call is then replayed on a fresh deep copy with main's module
(``git show main:fmu_fdi/design/toolkit/postconditions.py``, benchmarks/judge_speed.py's ``main_module``) and with
this tree's, one BLAS thread both ways (threadpoolctl; the designs run on one), the caches the judges read through
cleared before each call; best of ``--reps`` (default 2) of the sum over the seed's calls. Printed per seed: the
design time, the number of calls, both judges' times (per-row checks, the bank's check, total), their ratios (main /
this), whether every call's verdict (failed conditions) is the same, and the largest relative difference of the
figures (every numeric entry both return: decoupling, structure_leak, leakage, fault_visibility, fault_gain, scales,
filter_peak_gain, …; differences below 1e-300 absolute ignored).

Measured 27 Nov (judge11, ``--reps=2`` against main 183d15d+ccd3d32, 2-core machine shared with other sessions and a
test run: times indicative, ratios same run):

    seed rows design s calls | rows: main  this ratio | bank: main  this ratio | total ratio  same max rel diff
     403   16     27.3    21 |       8.97  8.68  1.03 |       6.74  5.95  1.13 |        1.07  True     2.44e-03
     412   11     20.0    17 |       6.70  7.11  0.94 |       6.73  4.61  1.46 |        1.15  True     2.35e-02
     382   26     28.3    31 |      10.93 10.51  1.04 |       9.52  6.17  1.54 |        1.23  True     5.21e-03
     379    6     12.9    13 |       6.17  6.38  0.97 |       3.28  2.75  1.19 |        1.04  True     7.50e-04
    total judge time: main 59.05 s, this 52.15 s, ratio 1.13

What the bank's check gains: its groups already read unit weakest gain (1 ± 5e-13: the members were normalised by
their own designs' judgements) and are no longer rescaled by that rounding, which cost a second reading of every group
(postconditions.NORMALISED_RTOL); the plant's mode table is computed once per bank, not per group. Every verdict is
main's; the figures that moved are plain u/d readings of ~1e-13 … 5e-10 (rounding: the rows not rescaled by 1 ± 1e-13).
The library judge already read each group of a bank on its own states (``_figures_by_group``/``row_system``, judge10):
the whole stack is not solved at any point. What is left is per group and per row: the accurate reading of the
decoupled blocks (``_decoupled_values``: per-point Hessenberg LU and longdouble refinement, ~40 % of the judge's
time under cProfile) and the per-row design checks, each a plain and a scaled pass (nullspace normalises rows by
another measure than the judge: the row checks rescale by ~200 … 1800).

Run: python benchmarks/judge_bank_speed.py [--reps=N] [--base=REF] [-v] [SEED ...]   (default seeds 403 412 382 379;
``-v``: each call's figure that differs most, where above 1e-6) | --profile SEED (this tree's judge, cProfile)
"""
import copy
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from fmu_fdi import freqresp  # noqa: E402
from fmu_fdi.design.toolkit import postconditions as new  # noqa: E402
from judge_speed import main_module, rel  # noqa: E402


def recorded_bank(seed: int):
    """``(design seconds, [(where, generator copy, kwargs)])``: the check_generator calls of one bank design."""
    from fmu_fdi.design import structured_bank
    from fmu_fdi.design.problems import banks, nullspace
    from fmu_fdi.design.problems.achievable import achievable_structure
    from test_synthesis_random import random_case

    model = random_case(seed)
    listed = np.asarray(achievable_structure(model), int).reshape(-1, len(model.faults))
    calls = []

    def recorder(where, original):
        def check(gen, **kw):
            calls.append((where, copy.deepcopy(gen), dict(kw)))
            return original(gen, **kw)
        return check

    saved = nullspace.check_generator, banks.check_generator
    nullspace.check_generator = recorder("row", saved[0])
    banks.check_generator = recorder("bank", saved[1])
    try:
        t = time.perf_counter()
        with threadpool_limits(limits=1, user_api="blas"):
            structured_bank(model, listed)
        return time.perf_counter() - t, calls, len(listed)
    finally:
        nullspace.check_generator, banks.check_generator = saved


def repeated(calls) -> int:
    """How many calls judge a filter (same Q, same model, same arguments) an earlier call of the design judged."""
    seen, n = set(), 0
    for _, gen, kw in calls:
        key = (tuple(np.asarray(X).tobytes() for X in (gen.Q.A, gen.Q.B, gen.Q.C, gen.Q.D)),
               tuple(np.asarray(X).tobytes() for X in (gen.model.A, gen.model.C)), tuple(gen.model.fault_names),
               tuple(gen.model.d_names), repr(sorted((k, repr(v)) for k, v in kw.items())))
        n += key in seen
        seen.add(key)
    return n


def replay(mod, calls):
    """Per call: (seconds, figures) of ``mod.check_generator`` on a fresh copy, caches cleared first."""
    out = []
    for _, gen, kw in calls:
        freqresp.clear_caches()
        new._UD_CACHE.clear()
        if hasattr(mod, "_UD_CACHE"):
            mod._UD_CACHE.clear()
        g = copy.deepcopy(gen)
        with threadpool_limits(limits=1, user_api="blas"):
            t = time.perf_counter()
            fig = mod.check_generator(g, **dict(kw, raise_error=False))
            out.append((time.perf_counter() - t, fig))
    return out


def figure_diff(a: dict, b: dict, key: bool = False):
    """Largest relative difference over the numeric entries both figure dicts hold (``key``: and which entry)."""
    worst, which = 0.0, None
    for k in sorted(set(a) & set(b)):
        try:
            x, y = np.asarray(a[k], float), np.asarray(b[k], float)
        except (TypeError, ValueError):
            continue
        if x.shape == y.shape and x.size and rel(x, y) > worst:
            worst, which = rel(x, y), (k, a[k], b[k])
    return (worst, which) if key else worst


def run(seeds, reps: int, ref: str) -> None:
    old = main_module(ref)
    print(f"baseline: {ref}'s postconditions.py; one BLAS thread both ways; best of {reps}")
    print(f"{'seed':>5s} {'rows':>4s} {'design s':>8s} {'calls':>5s} | {'rows: main':>10s} {'this':>6s} {'ratio':>5s} | "
          f"{'bank: main':>10s} {'this':>6s} {'ratio':>5s} | {'total ratio':>11s} {'same':>5s} {'max rel diff':>12s}")
    tot = np.zeros(2)
    for seed in seeds:
        t_design, calls, nrows = recorded_bank(seed)
        best = {}
        for _ in range(reps):
            for name, mod in (("main", old), ("this", new)):
                res = replay(mod, calls)
                split = tuple(sum(t for (t, _), (w, _, _) in zip(res, calls) if w == kind) for kind in ("row", "bank"))
                if name not in best or sum(split) < sum(best[name][0]):
                    best[name] = (split, [f for _, f in res])
        (rm, bm), fm = best["main"]
        (rt, bt), ft = best["this"]
        same = all(a.get("failed_conditions", []) == b.get("failed_conditions", []) for a, b in zip(fm, ft))
        diff = max((figure_diff(a, b) for a, b in zip(fm, ft)), default=0.0)
        if "-v" in sys.argv:
            for (w, _, _), a, b in zip(calls, fm, ft):
                d, which = figure_diff(a, b, key=True)
                if d > 1e-6:
                    print(f"      {w}: {which[0]} main {which[1]} this {which[2]}")
        print(f"      {repeated(calls)} of the {len(calls)} calls judge a filter an earlier call judged (same Q, "
              f"model and arguments)")
        tot += (rm + bm, rt + bt)
        print(f"{seed:5d} {nrows:4d} {t_design:8.1f} {len(calls):5d} | {rm:10.2f} {rt:6.2f} {rm / rt:5.2f} | "
              f"{bm:10.2f} {bt:6.2f} {bm / max(bt, 1e-9):5.2f} | {(rm + bm) / (rt + bt):11.2f} {str(same):>5s} "
              f"{diff:12.2e}")
    print(f"total judge time: main {tot[0]:.2f} s, this {tot[1]:.2f} s, ratio {tot[0] / tot[1]:.2f}")


def profile(seed: int) -> None:
    """cProfile of this tree's judge on the seed's recorded calls, top 30 by internal time."""
    import cProfile
    import pstats

    calls = recorded_bank(seed)[1]
    pr = cProfile.Profile()
    pr.enable()
    replay(new, calls)
    pr.disable()
    pstats.Stats(pr).sort_stats("tottime").print_stats(30)


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--profile" in args:
        profile(int(args[args.index("--profile") + 1]))
        sys.exit()
    reps = next((int(a.split("=")[1]) for a in args if a.startswith("--reps=")), 2)
    ref = next((a.split("=", 1)[1] for a in args if a.startswith("--base=")), "main")
    seeds = [int(a) for a in args if a.isdigit()] or [403, 412, 382, 379]
    run(seeds, reps, ref)
