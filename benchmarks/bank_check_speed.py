"""What the bank's own check (the last ``check_generator`` of ``structured_bank``) could save by reusing its members'
readings of their decoupled blocks, measured on exact audit seeds.

Each member is judged in its own design on its row model (``model.with_disturbances(excluded faults)``: the
excluded faults are columns of d there); the bank's check judges every group again on the bank's model, each group on
its own member's states and grid (postconditions._figures_by_group). The accurate reading of the decoupled blocks
(postconditions._decoupled_reading: per point a Hessenberg LU and, near a decision, refinement in extended precision)
is kept per (row filter, grid, columns of Ge, block partition) in postconditions._UD_CACHE — so the bank's reading
of a group is a hit only where it asks for the same columns with the same partition as the member did.

Per seed (tests/test_synthesis_random.py's ``random_case``; ``structured_bank`` on every row ``achievable_structure``
lists, as benchmarks/synthesis_random_judged.py calls it), one BLAS thread, best of ``--reps`` (default 3) designs:
the design time, the bank check's time, the time of its decoupled readings, and how many of these readings a member's
reading of the same design covers: the same row filter (content of its realisation) and the same points λ, read
already on a superset of the columns (by content: the same A, C and the same B, D columns of Ge). Those are the
readings a reuse could skip — the saving's ceiling ("ceiling ratio" = design time / (design time − covered
readings' time)).

Measured 27 Nov (audit17, 2-core machine shared with three other sessions, load ~3; ``--reps=3``):

    seed rows design s | check s readings      s covered      s | ceiling: check design
     379    6     3.58 |    0.69        5   0.39       5   0.39 |           2.32   1.12
     403   16     7.11 |    2.36       10   1.10      10   1.10 |           1.88   1.18
     412   11     8.58 |    2.37        4   0.44       4   0.44 |           1.23   1.05
     382   26     9.55 |    2.29        2   0.27       2   0.27 |           1.13   1.03

The rest of the bank check (cProfile of seed 382's, 2.7 s): the stability of the stacked filter 0.70 s
(postconditions._r_poles → margin.margin_reduced: an ordered Schur form of the block-diagonal stack of 26 members,
whose blocks were each judged in their member's design), the per-group grids and values 0.66 s (judge_points), the
cancelled boundary modes 0.48 s (_without_cancelled_modes), the decoupled readings 0.28 s.

Every bank reading is covered (the members' grids and filters are the bank's groups'), but the columns differ: the
member reads u and [d, excluded faults] as two blocks of one Ge; the bank reads u, d and each excluded fault as its
own block, and only those whose plain reading is near a decision (often u alone, or one fault). The kept reading's
key is the partition too, and a reading of fewer columns balances another realisation of Ge and refines other
points, so it is no cache hit. The reuse needed postconditions.py (audit17's note): keep per (Q_i, λ) the last
reading's Ge
columns with their unrefined values, bounds and refined points, and serve a request for a subset of those columns
from them where every point its own blocks' rule would refine was refined.

Reuse (judge18): :func:`postconditions._decoupled_values` keeps each reading per column (plain values, bounds, refined
values where refined) per (row filter, plant realisation, points), and serves a request whose columns were all read
from them, refining only the points its own blocks need that were not refined for those columns
(postconditions.plant_realisation gives every column one realisation per plant, whichever model lists it).
``--compare`` designs each seed with the bank check's readings served (this tree) and with them fresh (the store
emptied for the bank check: what main computed), alternating after a warm-up design, best of ``--reps``
each, one BLAS thread; prints both bank check times and the design times, their ratios, how many of the bank's
readings were served, and the largest
difference of the bank's figures (decoupling_rows, structure_leak) between the two relative to the reading's own
error bound (decoupling_row_errors, structure_leak_error).

Measured 27 Nov (judge18, ``--compare --reps=3`` at 81acf02, 2-core machine shared with four other sessions, load
7-8: the design times are noisy, the check times are the ratio's; figures compared bit for bit):

    seed rows | check: fresh served ratio | design: fresh served ratio | readings computed | max |d|/e same verdicts
     379    6 |         1.49   0.47  3.15 |          6.09   4.91  1.24 |        5        0 |  0.00e+00 True
     403   16 |         3.46   1.29  2.68 |         12.76  12.42  1.03 |       10        0 |  0.00e+00 True
     412   11 |         4.20   1.14  3.68 |         15.04   8.84  1.70 |        4        0 |  0.00e+00 True
     382   26 |         4.36   3.89  1.12 |         20.25  19.76  1.02 |        2        0 |  0.00e+00 True

Other seeds, ``--compare --reps=1 33 57 9 17`` (ddfb6c6, same day, lower load):

       33   15 |         0.90   0.53  1.68 |          9.37   8.62  1.09 |       10        0 |  4.10e-03 True
       57   26 |         1.26   0.79  1.59 |          7.15   6.46  1.11 |        9        0 |  0.00e+00 True
        9   16 |         0.40   0.34  1.16 |          1.94   2.09  0.93 |        1        0 |  0.00e+00 True
       17    6 |         0.25   0.20  1.27 |          1.79   1.81  0.99 |        1        0 |  0.00e+00 True

Every reading of the bank's check is served (none computes a new plain reading) and the bank's figures are the fresh
check's to the bit, except seed 33's, within 4.1e-3 of their own error bound (a last-bit difference of BLAS sums
beside other columns, postconditions._decoupled_values). The check ratios exceed audit17's ceilings above (measured
at load ~3 in another run): the
readings' share of the check is larger at this load. 412's design ratio is the load's (its check saves 3 s of 15).

28 Nov (judge23: the plain bound measures each reading's residual, so a served and a fresh reading's bounds differ by
their own solves' rounding), ``--compare --reps=1``: seeds 379 / 403 / 412 / 382 readings computed 0, max |d|/e
0.00e+00, same verdicts (check ratios 1.36 / 1.98 / 1.42 / 1.22 beside another benchmark).

Run: python benchmarks/bank_check_speed.py [--reps=N] [--compare] [SEED ...]   (default seeds 379 403 412 382)
"""
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from fmu_fdi import freqresp  # noqa: E402
from fmu_fdi.design.toolkit import postconditions as pc  # noqa: E402
from fmu_fdi.freqresp import content_key  # noqa: E402


def _columns(Ge) -> list:
    """Each column of Ge by content: (A, C) once, then each (B column, D column)."""
    return [content_key(Ge.B[:, c], Ge.D[:, c]) for c in range(Ge.m)]


def measured_design(seed: int) -> dict:
    """One ``structured_bank`` design of the seed with every decoupled reading recorded (phase, row filter and
    points, Ge's columns by content, seconds) and the bank check timed."""
    from fmu_fdi.design import structured_bank
    from fmu_fdi.design.problems import banks
    from fmu_fdi.design.problems.achievable import achievable_structure
    from test_synthesis_random import random_case

    model = random_case(seed)
    listed = np.asarray(achievable_structure(model), int).reshape(-1, len(model.faults))
    log, phase, bank_time = [], ["row"], [0.0]
    reading, check = pc._decoupled_reading, banks.check_generator

    def recorded_reading(model_, Q, g, lam, blocks, R, peaks, i):
        Qi = pc.row_system(Q, g) if Q.n else Q
        cols = np.concatenate([blocks[x] for x in blocks]) if blocks else np.zeros(0, int)
        Ge = model_.augmented()[:, cols]
        t = time.perf_counter()
        out = reading(model_, Q, g, lam, blocks, R, peaks, i)
        log.append({"phase": phase[0], "filter": content_key(Qi.A, Qi.B, Qi.C, Qi.D, lam),
                    "plant": content_key(Ge.A, Ge.C), "columns": _columns(Ge), "t": time.perf_counter() - t})
        return out

    def timed_check(gen, **kw):
        phase[0] = "bank"
        t = time.perf_counter()
        try:
            return check(gen, **kw)
        finally:
            bank_time[0] += time.perf_counter() - t
            phase[0] = "row"

    freqresp.clear_caches()
    pc._UD_CACHE.clear()
    pc._decoupled_reading, banks.check_generator = recorded_reading, timed_check
    try:
        t = time.perf_counter()
        with threadpool_limits(limits=1, user_api="blas"):
            structured_bank(model, listed)
        design = time.perf_counter() - t
    finally:
        pc._decoupled_reading, banks.check_generator = reading, check
    rows = [e for e in log if e["phase"] == "row"]
    bank = [e for e in log if e["phase"] == "bank"]

    def covered(b):
        return any(r["filter"] == b["filter"] and r["plant"] == b["plant"] and set(b["columns"]) <= set(r["columns"])
                   for r in rows)

    return {"rows": len(listed), "design": design, "check": bank_time[0], "readings": len(bank),
            "reading_s": sum(b["t"] for b in bank), "covered": sum(map(covered, bank)),
            "covered_s": sum(b["t"] for b in bank if covered(b))}


def run(seeds, reps: int) -> None:
    print(f"one BLAS thread; best of {reps} designs (by design time)")
    print(f"{'seed':>5s} {'rows':>4s} {'design s':>8s} | {'check s':>7s} {'readings':>8s} {'s':>6s} {'covered':>7s} "
          f"{'s':>6s} | {'ceiling: check':>14s} {'design':>6s}")
    for seed in seeds:
        best = min((measured_design(seed) for _ in range(reps)), key=lambda r: r["design"])
        c, d, s = best["check"], best["design"], best["covered_s"]
        print(f"{seed:5d} {best['rows']:4d} {d:8.2f} | {c:7.2f} {best['readings']:8d} {best['reading_s']:6.2f} "
              f"{best['covered']:7d} {s:6.2f} | {c / max(c - s, 1e-9):14.2f} {d / (d - s):6.2f}")


def compared_design(seed: int, served: bool) -> dict:
    """One ``structured_bank`` design of the seed, the bank check timed; ``served=False``: the bank check reads on
    an empty store (every reading fresh, as main), the members' readings put back after it."""
    from fmu_fdi.design import structured_bank
    from fmu_fdi.design.problems import banks
    from fmu_fdi.design.problems.achievable import achievable_structure
    from test_synthesis_random import random_case

    model = random_case(seed)
    listed = np.asarray(achievable_structure(model), int).reshape(-1, len(model.faults))
    check, bank_time, counts = banks.check_generator, [0.0], {"readings": 0, "fresh": 0}
    values = pc._plain_values

    def counted_plain(*a):
        counts["fresh"] += 1
        return values(*a)

    def timed_check(gen, **kw):
        kept = pc._UD_CACHE.copy()
        if not served:
            pc._UD_CACHE.clear()
        reading = pc._decoupled_values

        def counted(*a):
            counts["readings"] += 1
            return reading(*a)

        pc._decoupled_values, pc._plain_values = counted, counted_plain
        t = time.perf_counter()
        try:
            return check(gen, **kw)
        finally:
            bank_time[0] += time.perf_counter() - t
            pc._decoupled_values, pc._plain_values = reading, values
            if not served:
                pc._UD_CACHE.clear()
                pc._UD_CACHE.update(kept)

    freqresp.clear_caches()
    pc._UD_CACHE.clear()
    banks.check_generator = timed_check
    try:
        t = time.perf_counter()
        with threadpool_limits(limits=1, user_api="blas"):
            bank = structured_bank(model, listed)
        design = time.perf_counter() - t
    finally:
        banks.check_generator = check
    return {"rows": len(listed), "design": design, "check": bank_time[0], "pc": bank.info["postconditions"], **counts}


def _figure_gap(a: dict, b: dict) -> float:
    """The largest difference of the decoupled readings between two bank figures, relative to their error bound."""
    out = 0.0
    for x, e in (("decoupling_rows", "decoupling_row_errors"), ("structure_leak", "structure_leak_error")):
        d = np.abs(np.asarray(a[x], float) - np.asarray(b[x], float))
        bound = np.maximum(np.asarray(a[e], float), np.asarray(b[e], float))
        out = max(out, float(np.max(np.where(d > 0, d / np.maximum(bound, 1e-300), 0.0), initial=0.0)))
    return out


def compare(seeds, reps: int) -> None:
    print(f"one BLAS thread; best of {reps} designs each way, alternating")
    print(f"{'seed':>5s} {'rows':>4s} | {'check: fresh':>12s} {'served':>6s} {'ratio':>5s} | {'design: fresh':>13s} "
          f"{'served':>6s} {'ratio':>5s} | {'readings':>8s} {'computed':>8s} | {'max |d|/e':>9s} same verdicts")
    for seed in seeds:
        runs = {True: [], False: []}
        compared_design(seed, True)  # warm-up: imports, the first calls' setup
        for _ in range(reps):
            for served in (False, True):
                runs[served].append(compared_design(seed, served))
        f = min(runs[False], key=lambda r: r["check"])
        s = min(runs[True], key=lambda r: r["check"])
        fd = min(r["design"] for r in runs[False])
        sd = min(r["design"] for r in runs[True])
        same = all(np.array_equal(np.asarray(f["pc"]["structure_matrix"]), np.asarray(r["pc"]["structure_matrix"]))
                   for r in runs[True] + runs[False])
        gap = max(_figure_gap(f["pc"], r["pc"]) for r in runs[True])
        print(f"{seed:5d} {f['rows']:4d} | {f['check']:12.2f} {s['check']:6.2f} {f['check'] / s['check']:5.2f} | "
              f"{fd:13.2f} {sd:6.2f} {fd / sd:5.2f} | {s['readings']:8d} {s['fresh']:8d} | {gap:9.2e} {same}")


if __name__ == "__main__":
    args = sys.argv[1:]
    reps = next((int(a.split("=")[1]) for a in args if a.startswith("--reps=")), 3)
    seeds = [int(a) for a in args if a.isdigit()] or [379, 403, 412, 382]
    (compare if "--compare" in args else run)(seeds, reps)
