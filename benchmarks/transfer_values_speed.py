"""Time of ``fmu_fdi.freqresp.transfer_values`` on the calls a real design makes: main's code against this tree's,
measured in the same run on the same arguments, with one BLAS thread both ways (threadpoolctl, as the designs run).

The workload is recorded, not invented: the design calls of a case are run once with ``transfer_values`` wrapped so
that every call's ``(A, B, C, D, points)`` is kept (cases: the exact audit's random seed 412 — nullspace_design and
structured_bank on every listed row, tests/test_synthesis_random.py — and the approximate audit's afdi_bank seed 78,
tests/test_approximate_random.py, the rows benchmarks/judge_speed.py picks). Main's module is
``git show main:fmu_fdi/freqresp.py`` loaded beside the package. Each implementation then evaluates every recorded
call with its caches cleared before each call (a kept value would time nothing), best of ``--reps`` (default 3).
Printed per case: the calls and points below ``SCHUR_MIN_ORDER`` (the dense path) and above, both times, their ratio
(main / this tree), and whether every value is bit for bit the same (the arrays' bytes).

Profile of seed 412's design calls (cProfile, one BLAS thread, load ~9 on the shared 2-core machine): 42.1 s, of which
``transfer_values`` 9.7 s over 330 calls — 28 794 dense LU solves of orders 8–55 (``numpy.linalg.solve`` 6.8 s, the
per-point Python loop 2.7 s). A Hessenberg form per matrix and a banded LU per point (Laub 1981, the path above
order 64) took 3.1 s against 8.0 s for the dense loop on the same recorded calls, but its values differ from the dense
solves' at rounding level — up to 3.6 times the value itself at the residue checks ``Q(p)·c_p`` on a marginal pole
(|G| ~ 1e-14 … 1e-16, where the designs compare against a rounding bound δ_i): not the same results, so not taken here.

Measured 27 Nov (audit11, load ~8 on the shared 2-core machine: times indicative, ratios same run), ``--reps=3``
against main (ccd3d32):

    case                                dense calls/pts  large calls/pts   main s  this s  ratio identical
    exact seed 412 (nullspace + bank)     330/42519          0/0            10.04    7.16   1.40      True
    afdi_bank seed 78                      77/9753           0/0             2.35    1.87   1.26      True

(stacked solves alone, λI − A formed as ``λ·I − A`` per stack: 1.19 and 1.07 — the complex product with the identity
was a third of the stacked path's time; now −A with λ added on the diagonal, the same sums.)

Run: python benchmarks/transfer_values_speed.py [--reps=N] [--base=REF]
"""
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from fmu_fdi import freqresp  # noqa: E402


def base_module(ref: str = "main"):
    """``ref``'s freqresp module, loaded from ``git show`` as a sibling of this tree's (riccati_refinement's loader)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from riccati_refinement import _module_at

    return _module_at(ref, "fmu_fdi/freqresp.py", "_freqresp_base", "fmu_fdi")


def recorded(design) -> list[tuple]:
    """The ``(A, B, C, D, points)`` of every ``transfer_values`` call ``design()`` makes (copies)."""
    import fmu_fdi.design.toolkit.postconditions as pc

    calls, orig = [], freqresp.transfer_values

    def spy(A, B, C, D, lams):
        calls.append(tuple(np.array(x) for x in (A, B, C, D, np.atleast_1d(lams))))
        return orig(A, B, C, D, lams)

    old_pc = pc.transfer_values
    freqresp.transfer_values = pc.transfer_values = spy
    try:
        freqresp.clear_caches()
        with threadpool_limits(limits=1, user_api="blas"):
            design()
    finally:
        freqresp.transfer_values, pc.transfer_values = orig, old_pc
    return calls


def cases():
    from fmu_fdi.design import afdi_bank, nullspace_design, structured_bank
    from fmu_fdi.design.problems.achievable import achievable_structure
    from test_approximate_random import noisy_case
    from test_synthesis_random import random_case

    model = random_case(412)
    listed = np.asarray(achievable_structure(model), int).reshape(-1, len(model.faults))
    yield "exact seed 412 (nullspace + bank)", recorded(lambda: (nullspace_design(model),
                                                                structured_bank(model, listed)))
    model78 = noisy_case(78)
    listed = np.asarray(achievable_structure(model78), int).reshape(-1, len(model78.faults))
    rng = np.random.default_rng(78)
    rows = listed if len(listed) <= 3 else listed[np.sort(rng.choice(len(listed), 3, False))]
    yield "afdi_bank seed 78", recorded(lambda: afdi_bank(model78, rows))


def timed(mod, calls) -> tuple[float, list]:
    out, total = [], 0.0
    with threadpool_limits(limits=1, user_api="blas"):
        for A, B, C, D, lams in calls:
            mod.clear_caches()
            t = time.perf_counter()
            out.append(mod.transfer_values(A, B, C, D, lams))
            total += time.perf_counter() - t
    return total, out


def run(reps: int = 3, ref: str = "main") -> None:
    base = base_module(ref)
    print(f"baseline: {ref}'s freqresp.py; one BLAS thread both ways; best of {reps}")
    print(f"{'case':34s} {'dense calls/pts':>16s} {'large calls/pts':>16s} {ref + ' s':>8s} {'this s':>7s} "
          f"{'ratio':>6s} {'identical':>9s}")
    for label, calls in cases():
        small = [c for c in calls if c[0].shape[0] < freqresp.SCHUR_MIN_ORDER]
        large = [c for c in calls if c[0].shape[0] >= freqresp.SCHUR_MIN_ORDER]
        t_old, t_new, same = [], [], True
        for _ in range(reps):
            t, v_old = timed(base, calls)
            t_old.append(t)
            t, v_new = timed(freqresp, calls)
            t_new.append(t)
            same &= all(a.tobytes() == b.tobytes() for a, b in zip(v_old, v_new))
        print(f"{label:34s} {len(small):>6d}/{sum(c[4].size for c in small):<9d} "
              f"{len(large):>6d}/{sum(c[4].size for c in large):<9d} {min(t_old):8.2f} {min(t_new):7.2f} "
              f"{min(t_old) / min(t_new):6.2f} {str(same):>9s}", flush=True)


if __name__ == "__main__":
    args = dict(a.lstrip("-").split("=", 1) for a in sys.argv[1:] if "=" in a)
    run(int(args.get("reps", 3)), args.get("base", "main"))
