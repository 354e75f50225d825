"""Where the slow exact-audit models spend their time, and what reading each residual group on the states
its rows observe would save — measured on the audit's own judge (tests/test_synthesis_random.py), in one run.

The audit (benchmarks/synthesis_random_judged.py) judges every returned bank by numpy: frequency responses
of the stacked filter Q on ~600 points (``_freqresp``: one dense solve of Q's order per point) and, per
residual group, PBH tests on the series realisation of ``Q[rows]·Ge`` (``row_violations`` → ``_series`` →
``_pbh_poles``: eigenvalues and SVDs of order n(Q) + n). A bank's Q is the block-diagonal stack of its
members (``lti.vstack``), so both costs grow with the cube of the *whole* bank's order for every group,
although a group's rows observe only its own member's states. Profiled (cProfile, seed 412, structured
bank of 11 rows, Q order 439, series order 468; 2 shared cores under load 11): check_case 481 s, of which
the judge 437 s (``_pbh_poles`` 272 s, ``_freqresp`` 163 s) and the design calls 44 s.

New (the test's judge since the tenth session; the old way is patched back in here as the baseline): the same judge with ``_freqresp`` solving,
for each set of output rows observing the same states, on those states only, and ``_series`` built from
the states the group's rows observe — both by the exact zero pattern of (A, C) (a state with no path to
the rows' outputs is unobservable whatever the values; no rank decision, no tolerance). The transfer
functions are the same; the grid is the same (Q's poles still steer it).

Prints per seed: judge time old and new, their ratio, and whether every verdict and detail string of
check_case (figures to 3 digits) is the same both ways. The designs are computed once per way (seeded,
deterministic); only the judge's time is counted.

Measured 27 Nov (tenth session, 2 shared cores, load ~11; one run each): seed 379 judge 39.2 s -> 5.9 s (6.7),
seed 412 577.6 s -> 7.5 s (76.8); seeds 403, 382 in a second run: 229.3 -> 8.6 s (26.7), 498.3 -> 11.6 s (42.8);
every verdict and detail string the same both ways. The slow models of seeds 379-408 (one per model,
tests/test_synthesis_random.check_case, same session): 382 520 s (its structured bank's judge 474 s, the
design 39 s), 403 495 s (judge 382 s, design 86 s), 392 299 s (judges 229 s), 406 123 s, 379 63 s.
Those runs had the judge on OpenBLAS's default threads, which spin-wait on a loaded 2-core machine (most of the old
times). With one BLAS thread on both ways (the judge's own limit since audit10, the baseline wrapped the same), beside a
CI run: seed 379 3.9 s -> 4.2 s (0.9: no bank large enough to matter), seed 412 57.4 s -> 8.4 s (6.9).

Run: python benchmarks/audit_judge_speed.py SEED …   (e.g. 379 412)
"""
import sys
import time
from contextlib import contextmanager
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_synthesis_random as T  # noqa: E402


@contextmanager
def whole_order():
    """The judge as it was (the baseline): ``_freqresp`` and ``_series`` on every state of the stacked filter."""
    freqresp, series = T._freqresp, T._series
    T._freqresp, T._series = T._one_blas_thread(T._freqresp_dense), T._series_whole
    try:
        yield
    finally:
        T._freqresp, T._series = freqresp, series


def _judged(seed):
    judge, spent = T.judge, [0.0]

    def timed(*a, **k):
        t = time.perf_counter()
        try:
            return judge(*a, **k)
        finally:
            spent[0] += time.perf_counter() - t

    T.judge = timed
    try:
        res = T.check_case(seed, max_rows=None)
    finally:
        T.judge = judge
    return res, spent[0]


def main(seeds):
    print(f"{'seed':>4s} {'judge old s':>11s} {'judge new s':>11s} {'ratio':>6s}  same verdicts and details")
    for seed in seeds:
        with whole_order():
            old, t_old = _judged(seed)
        new, t_new = _judged(seed)
        same = old == new
        print(f"{seed:4d} {t_old:11.1f} {t_new:11.1f} {t_old / t_new:6.1f}  {same}", flush=True)
        if not same:
            for a, b in zip(old, new):
                if a != b:
                    print("   old:", a, "\n   new:", b)


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [379])
