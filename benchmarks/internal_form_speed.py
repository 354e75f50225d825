"""Time of reading one block of a generator's internal form (``gen.Rf``, ``gen.Ru``, ``gen.Rd``, ``gen.Rw``),
old and new in the same run, on the exact audit's random models (tests/test_synthesis_random.py).

Baseline (main before the tenth session, kept below as :func:`old_block`): every property read built all four
blocks, ``{g: R[:, cols(g)].minreal() for g in 'udwf'}``, and returned one. New: ``ResidualGenerator._block``
reduces only the block asked for, once, and keeps it (``scale_rows`` forgets it). The one realisation
``gen._R`` is built before timing (common to both). Prints per model the time of reading Rf, then Ru, Rd, Rw
once each (four property reads) both ways (the best of 5 repetitions, each on a fresh generator whose
``_R`` is built first), the ratio, and the largest difference of Rf's frequency response
(the same computation: 0).

Measured 27 Nov (tenth session, 2 shared cores under load 11): seeds 2, 6, 13, 379 (n(R) 2, 4, 18, 34):
0.8 -> 0.2 ms (3.5), 1.0 -> 0.2 (4.2), 1.5 -> 0.4 (3.8), 2.2 -> 0.6 (3.4); Rf identical (difference 0).

Run: python benchmarks/internal_form_speed.py [SEED …]   (default 2 6 11 13)
"""
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_synthesis_random import random_case  # noqa: E402

from fmu_fdi.design import nullspace_design  # noqa: E402
from fmu_fdi.generator import ResidualGenerator  # noqa: E402


def old_block(gen, group):
    sl = gen.model.group_slices()
    return {g: gen._R[:, sl[g]].minreal() for g in sl}[group]


def main(seeds):
    print(f"{'seed':>4s} {'n(R)':>5s} {'old s':>8s} {'new s':>8s} {'ratio':>6s} {'|ΔRf(jω)|':>10s}")
    for seed in seeds:
        design = nullspace_design(random_case(seed))
        t_old = t_new = np.inf
        for _ in range(5):
            gen = ResidualGenerator(design.Q, design.model, design.method)
            gen._R
            t = time.perf_counter()
            new = [gen.Rf, gen.Ru, gen.Rd, gen.Rw]
            t_new = min(t_new, time.perf_counter() - t)
            t = time.perf_counter()
            old = [old_block(gen, g) for g in "fudw"]
            t_old = min(t_old, time.perf_counter() - t)
        w = np.logspace(-2, 2, 7)
        diff = float(np.max(np.abs(old[0].freqresp(w) - new[0].freqresp(w)), initial=0.0))
        print(f"{seed:4d} {gen._R.n:5d} {t_old:8.4f} {t_new:8.4f} {t_old / t_new:6.1f} {diff:10.1e}", flush=True)


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [2, 6, 11, 13])
