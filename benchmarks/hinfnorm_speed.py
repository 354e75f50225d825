"""Time of ``LTI.hinfnorm`` (AB13DD, then the Hamiltonian-pencil certificate) against main's (AB13DD alone), same
run, one BLAS thread both ways, on realistic systems:

* the audit's internal forms: every system the approximate designs hand to ``hinfnorm`` on
  ``test_approximate_random.noisy_case(seed)`` — ``afdi_bank`` on the rows ``check_case`` picks and
  ``nullspace_design`` (recorded once, with the new hinfnorm, then timed both ways);
* random stable systems n 5–80 (``tests/test_hinfnorm_certified.modal_system``'s family at fixed orders, m, p
  1–3, continuous and discrete).

Each system is timed ``--repeat`` times each way, interleaved. Prints per class the summed times, their ratio
(new / main), the largest state order, and how many norms changed (relative difference above 1e-8) with the
largest change — the local peaks main returned. With ``--designs`` the designs themselves (``nullspace_design``
and ``afdi_bank`` on each seed) are timed once each way too, main's hinfnorm patched in for the baseline.

With ``--base REF`` the baseline is ``LTI.hinfnorm`` as ``fmu_fdi/lti.py`` is at git REF (run beside this tree's, same
caches) instead of AB13DD alone; norms that differ by less than 1e-8 are counted apart, "by rounding".

Run: python benchmarks/hinfnorm_speed.py [--repeat K] [--designs] [--seeds S …] [--base REF]
(default: K 3, seeds 176 3, baseline AB13DD alone)

Measured (27 Nov, 2 shared cores, one run, --designs, defaults): the designs on seeds 176 and 3 4.18 s -> 5.21 s
(1.25); the 60 audit systems (n <= 78) 2.42 s -> 4.81 s (1.99), 2 changed: seed 176's order-77 fs1 slice
0.83528817 -> 1.0118477 (main's local peak, 17 %) and an order-78 slice 0.083153878 -> 0.085074299; random n 5-10
0.028 -> 0.063 s (2.27), n 20-40 0.183 -> 0.300 s (1.64), n 80 0.750 -> 1.173 s (1.56); all 3.38 -> 6.35 s (1.88).
The 14 random norms that changed (1e-8 … 4.1e-7) are AB13DD figures that are not the gain at AB13DD's own frequency:
numpy reads the new value there (and the same, to 1e-11, on the TB01ID-balanced realisation), e.g. n 20
5931.1848777 -> 5931.1873019, n 40 3313.8158363 -> 3313.8154884 (AB13DD above the peak). The certificate costs one
QZ of order 2n + m + p, about one AB13DD.

hinf18 (28 Nov, ``--base 253b4cb --designs``, one BLAS thread, load 7–10 from five sessions): every crossing kept
(no √eps merge) and the light-mode readings (lti._LightModes) cost nothing measurable. Final code: hinfnorm calls
7.72 s -> 7.62 s (0.99; audit 0.99, random n 5-10 1.28 — 0.4 ms a call, the light-mode set-up on 48 calls of
~2 ms —, n 20-40 0.97, n 80 0.97), designs 6.43 -> 6.17 s (0.96). With the first commit (merge removed, refusal
only): run 1 calls 1.04, designs 1.02; run 2 calls 0.96, its designs 7.25 -> 29.15 s a load burst (other runs of
mine beside it), re-timed alone twice: 7.26 -> 7.22 s, 6.80 -> 7.18 s, no refusal raised in 180 certificates.
No norm moved by 1e-8; four by rounding: one audit system 2.2e-16, random n 40 (continuous, discrete) 4.1e-12 and
1.55e-11, n 80 1.8e-12 — the gain evaluated at a neighbouring point (in the first the frequency moved by one ulp);
numpy's refined peak is nearer the new value in two of the three random ones.
"""
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # before numpy: one BLAS thread both ways

import argparse  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from test_hinfnorm_certified import modal_system  # noqa: E402

from fmu_fdi.linalg import EPS  # noqa: E402
from fmu_fdi.lti import LTI  # noqa: E402


def main_hinfnorm(G: LTI) -> tuple[float, float]:
    """main's ``LTI.hinfnorm`` (ae569eb): the same early returns, then AB13DD's tuple as returned."""
    if G.m == 0 or G.p == 0:
        return 0.0, 0.0
    if G.n == 0 or not np.any(G.B) or not np.any(G.C):
        return float(np.linalg.norm(G.D, 2)), float("inf")
    import slycot

    poles = G.poles()
    boundary = np.abs(np.abs(poles) - 1.0) if G.is_discrete else np.abs(poles.real)
    if np.any(boundary < 1e3 * EPS * max(1.0, float(np.max(np.abs(poles))))):
        return float("inf"), 0.0
    g, f = slycot.ab13dd("D" if G.is_discrete else "C", "I", "N", "D", G.n, G.m, G.p, G.A.copy(), np.eye(G.n),
                         G.B.copy(), G.C.copy(), G.D.copy())
    f = float(f) / G.dt if G.is_discrete and np.isfinite(f) else float(f)
    return float(g), f


def run_designs(seeds) -> None:
    """nullspace_design and afdi_bank (on check_case's rows) on noisy_case(seed) for each seed."""
    from test_approximate_random import noisy_case

    from fmu_fdi.design import afdi_bank, nullspace_design
    from fmu_fdi.design.problems.achievable import achievable_structure
    from fmu_fdi.errors import DesignError

    for seed in seeds:
        model = noisy_case(seed)
        names = model.fault_names
        try:
            nullspace_design(model)
        except DesignError:
            pass
        listed = np.asarray(achievable_structure(model), int).reshape(-1, len(names))
        if len(listed):
            rng = np.random.default_rng(seed)  # check_case's choice of rows
            rows = listed if len(listed) <= 3 else listed[np.sort(rng.choice(len(listed), 3, False))]
            try:
                afdi_bank(model, rows)
            except DesignError:
                pass


def audit_systems(seeds) -> list[LTI]:
    """The systems the designs of :func:`run_designs` pass to hinfnorm."""
    seen: list[LTI] = []
    shipped = LTI.hinfnorm

    def record(self, *a, **k):
        if self.n:
            seen.append(LTI(self.A.copy(), self.B.copy(), self.C.copy(), self.D.copy(), self.dt))
        return shipped(self, *a, **k)

    LTI.hinfnorm = record
    try:
        run_designs(seeds)
    finally:
        LTI.hinfnorm = shipped
    return seen


def design_times(seeds, base=None) -> tuple[float, float]:
    """run_designs' time with main's hinfnorm patched in, then as shipped (fresh models each time), after one
    warm-up run (the content-keyed caches, e.g. of eigenvalues, then serve both alike)."""
    run_designs(seeds)
    shipped = LTI.hinfnorm
    LTI.hinfnorm = lambda self, *a, **k: (base or main_hinfnorm)(self)
    try:
        t0 = time.perf_counter()
        run_designs(seeds)
        t_main = time.perf_counter() - t0
    finally:
        LTI.hinfnorm = shipped
    t0 = time.perf_counter()
    run_designs(seeds)
    return t_main, time.perf_counter() - t0


def random_systems() -> list[LTI]:
    """modal_system's family at orders 5, 10, 20, 40, 80 (four seeds each), continuous and discrete."""
    return [modal_system(1000 * n + seed, discrete, order=n) for n in (5, 10, 20, 40, 80) for seed in range(4)
            for discrete in (False, True)]


def base_hinfnorm(ref: str):
    """``LTI.hinfnorm`` as ``fmu_fdi/lti.py`` is at git ``ref`` (run as a module of the package beside this tree's,
    sharing its caches): a function of an LTI of this tree."""
    import types

    src = subprocess.check_output(["git", "show", f"{ref}:fmu_fdi/lti.py"], cwd=ROOT, text=True)
    mod = types.ModuleType("fmu_fdi._lti_base")
    mod.__package__ = "fmu_fdi"
    sys.modules[mod.__name__] = mod  # dataclasses looks the module up
    exec(compile(src, f"{ref}:fmu_fdi/lti.py", "exec"), mod.__dict__)
    return lambda G: mod.LTI.hinfnorm(G)


def timed(systems, repeat, base):
    t_main = t_new = 0.0
    changed = []
    for G in systems:
        for _ in range(repeat):
            t0 = time.perf_counter()
            gm = base(G)[0]
            t1 = time.perf_counter()
            gn = G.hinfnorm()[0]
            t2 = time.perf_counter()
            t_main += t1 - t0
            t_new += t2 - t1
        if np.isfinite(gm) and abs(gn - gm) > 1e-8 * max(abs(gn), 1e-300):
            changed.append((G.n, gm, gn))
        elif gn != gm:
            changed.append((G.n, gm, gn, "rounding"))
    return t_main, t_new, changed


def report(name, systems, repeat, base, label):
    t_main, t_new, changed = timed(systems, repeat, base)
    big = [c for c in changed if len(c) == 3]
    worst = max((abs(gn - gm) / gn for _, gm, gn in big), default=0.0)
    small = max((abs(c[2] - c[1]) / abs(c[2]) for c in changed if len(c) == 4), default=0.0)
    print(f"{name:<28} {len(systems):>4} systems, n <= {max(G.n for G in systems):>3}: {label} {t_main:8.3f} s, "
          f"new {t_new:8.3f} s, ratio {t_new / t_main:5.2f}; {len(big)} changed (largest {worst:.3g}), "
          f"{len(changed) - len(big)} by rounding (largest {small:.3g})")
    for n, gm, gn in big:
        print(f"    n {n:>3}: {label} {gm:.8g} -> {gn:.8g}")
    return t_main, t_new


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seeds", type=int, nargs="*", default=[176, 3])
    ap.add_argument("--designs", action="store_true")
    ap.add_argument("--base", default=None, help="time lti.py at this git ref instead of AB13DD alone")
    a = ap.parse_args()
    base, label = (base_hinfnorm(a.base), a.base) if a.base else (lambda G: main_hinfnorm(G), "main")
    if a.designs:
        tm, tn = design_times(a.seeds, base)
        print(f"designs on seeds {a.seeds}: {label}'s hinfnorm {tm:.2f} s, new {tn:.2f} s, ratio {tn / tm:.2f}")
    t0 = time.perf_counter()
    audit = audit_systems(a.seeds)
    print(f"recorded {len(audit)} audit systems (seeds {a.seeds}) in {time.perf_counter() - t0:.1f} s")
    rnd = random_systems()
    totals = [report(f"audit seeds {a.seeds}", audit, a.repeat, base, label)]
    for lo, hi in ((5, 10), (20, 40), (80, 80)):
        part = [G for G in rnd if lo <= G.n <= hi]
        totals.append(report(f"random n {lo}-{hi}", part, a.repeat, base, label))
    tm, tn = (sum(t) for t in zip(*totals))
    print(f"{'all':<28} {label} {tm:8.3f} s, new {tn:8.3f} s, ratio {tn / tm:5.2f}")


if __name__ == "__main__":
    main()
