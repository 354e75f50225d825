"""The double-double readings on a host whose longdouble is double (simulated: tests/test_double_host.PATCH before
fmu_fdi is imported), a baseline's (``--base``, default main) against this tree's, in one process, one BLAS thread:

1. light-mode H∞ readings (``lti._double_double_gains``; the baseline's loaded from ``git show BASE:fmu_fdi/lti.py`` as
   a sibling module, and swapped into ``lti`` by name): each of benchmarks/double_host_hinf_speed.py's cases'
   ``hinfnorm`` timed (best of R) with each, the norms' relative difference; the gains both read at 13 points across
   each resonance (``ζ·ωn`` apart) against a 50-digit decimal evaluation of the stored data (SISO cases:
   tests/test_hinfnorm_damping.decimal_gain2), worst relative error of each;
2. the judge's refined reading (``postconditions._dd_refined_values``; the baseline's from its postconditions.py) on
   random H∞ matching seeds 4 and 7 (benchmarks/ammp_random_set.py's models, ``norm='inf'``): the design timed with
   each routine swapped in (the design's own judgements read through it; the two alternate, best of R), then
   ``check_generator`` of the returned filter with each (caches cleared, best of R); figures compared. Every refined
   reading made in the first design and the final judgement (candidates of higher order among them) is read by both
   routines; printed: the largest ``|new − base|`` in units of the judge's bound ``3N·2^-64·err`` at that entry, and
   on 3 points of the largest call both against a 50-digit decimal evaluation (Gaussian elimination with partial
   pivoting in :mod:`decimal`, the real 2n form of each complex solve) in the same unit.

Measured 28 Nov (dd23, base = main 7bc7918, one BLAS thread, load 5-7 from other sessions: ratios from one run):

* light modes, R = 2: every case 5.8-9.5x faster (geometric mean 7.84; totals 1.59 s / 0.21 s), the ten norms
  identical (relative difference 0), the 130 readings against 50 digits 1.5e-16 … 2.2e-16 relative both (the final
  rounding to double);
* H∞ matching seed 4, R = 2: design 12.44 s -> 7.67 s (1.62), judge 0.40 -> 0.15 s (2.61), figures identical;
  |this − base| ≤ 2.7e-15 × bound; 50 digits: base ≤ 5.8e-16, this ≤ 5.3e-17 × bound;
* seed 7, R = 2: design 41.99 -> 17.91 s (2.34), judge 1.49 -> 0.50 s (2.96), figures identical (order 29 both);
  R = 1 with the design's readings: 33.70 -> 18.69 s (1.80), 23 refined readings (up to the order-87 candidate)
  |this − base| ≤ 3.9e-14 × bound, 50 digits at 3 points of the order-87 one: base ≤ 1.5e-15, this ≤ 3.2e-16 × bound.

Run: OPENBLAS_NUM_THREADS=1 python benchmarks/double_host_dd_speed.py [--reps=R] [--base=REF] [--seeds 4 7]
"""
import numpy  # noqa: I001  (the simulated host before fmu_fdi is imported)

numpy.longdouble = numpy.float64
numpy.clongdouble = numpy.complex128

import copy  # noqa: E402
import importlib.util  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from decimal import Decimal, localcontext  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "benchmarks")]

from fmu_fdi import freqresp, lti  # noqa: E402
from fmu_fdi.design.toolkit import postconditions as pc  # noqa: E402


def base_module(ref: str, path: str, name: str):
    """``ref``'s module at ``path``, loaded beside this tree's (its relative imports read this tree's modules)."""
    src = subprocess.check_output(["git", "show", f"{ref}:{path}"], cwd=ROOT, text=True)
    spec = importlib.util.spec_from_loader(name, loader=None)
    mod = importlib.util.module_from_spec(spec)
    mod.__package__ = name.rsplit(".", 1)[0]
    sys.modules[name] = mod
    exec(compile(src, f"{ref}:{path}", "exec"), mod.__dict__)
    return mod


def best(f, reps):
    out, t = None, float("inf")
    for _ in range(reps):
        freqresp.clear_caches()
        pc._UD_CACHE.clear()
        t0 = time.perf_counter()
        out = f()
        t = min(t, time.perf_counter() - t0)
    return t, out


def light_modes(old_gains, reps):
    import test_hinfnorm_damping as th

    new_gains = lti._double_double_gains
    cases = ([(f"section z={z:g} wn={wn:g}", th.light(z, wn), z, wn) for z in (1e-8, 1e-9, 1e-10) for wn in (1.0, 37.0)]
             + [(f"mixed z={z:g} seed={s}", th.mixed(z, s, False), z, 1.0) for z, s in ((1e-9, 7), (1e-10, 1))]
             + [(f"tustin z={z:g}", th.tustin(th.light(z, 1.0), 0.5), z, 1.0) for z in (1e-9, 1e-10)])
    print(f"{'light-mode case':24s} {'base s':>7s} {'this s':>7s} {'ratio':>6s} {'norm rel diff':>13s} "
          f"{'base err':>9s} {'this err':>9s}")
    logs, tb, tn = [], 0.0, 0.0
    for name, G, z, wn in cases:
        times, norms = {}, {}
        for label, fn in (("base", old_gains), ("this", new_gains)):
            lti._double_double_gains = fn
            times[label], norms[label] = best(lambda: G.hinfnorm()[0], reps)
        lti._double_double_gains = new_gains
        # the readings themselves at 13 points across the resonance, on the stored data (powers-of-2 scaling apart)
        w = wn * (1.0 + z * np.linspace(-3.0, 3.0, 13))
        if G.dt:
            w = 2.0 * np.arctan(w * G.dt / 2.0)  # Tustin: the image of the continuous resonance, rad/sample
        errs = {}
        for label, fn in (("base", old_gains), ("this", new_gains)):
            g = fn(G.A, G.B, G.C, G.D, bool(G.dt), w)[0]
            with localcontext() as ctx:
                ctx.prec = 50
                truth = [float(th.decimal_gain2(G, np.tan(x / 2.0) if G.dt else x).sqrt()) for x in w]
            errs[label] = float(np.max(np.abs(g - truth) / np.abs(truth)))
        tb, tn = tb + times["base"], tn + times["this"]
        logs.append(np.log(times["base"] / times["this"]))
        print(f"{name:24s} {times['base']:7.3f} {times['this']:7.3f} {times['base'] / times['this']:6.2f} "
              f"{abs(norms['this'] - norms['base']) / norms['base']:13.1e} {errs['base']:9.1e} {errs['this']:9.1e}")
    print(f"light modes: geometric mean base/this {np.exp(np.mean(logs)):.2f}; totals {tb:.2f} s / {tn:.2f} s = "
          f"{tb / tn:.2f}")


def _dec_solve(A, lam, rhs):
    """``(λI − A)^{-1} rhs`` (rhs: list of complex Decimal pairs per column) in decimal, the real 2n form."""
    n = A.shape[0]
    lr, li = Decimal(float(lam.real)), Decimal(float(lam.imag))
    Ad = [[Decimal(float(a)) for a in row] for row in A]
    cols = len(rhs)
    N = 2 * n
    M = [[Decimal(0)] * (N + cols) for _ in range(N)]
    for i in range(n):
        for k in range(n):
            M[i][k] = M[n + i][n + k] = (lr if i == k else 0) - Ad[i][k]
        M[i][n + i], M[n + i][i] = -li, li
        for j, (re, im) in enumerate(rhs):
            M[i][N + j], M[n + i][N + j] = re[i], im[i]
    from test_hinfnorm_damping import decimal_eliminate

    return [(x[:n], x[n:]) for x in decimal_eliminate(M, N, cols)]


def _dec_times(M, cols):
    Md = [[Decimal(float(a)) for a in row] for row in np.atleast_2d(M)]
    return [([sum(m * x for m, x in zip(row, re)) for row in Md], [sum(m * x for m, x in zip(row, im)) for row in Md])
            for re, im in cols]


def decimal_reading(Qb, Geb, lam):
    """``R_X = C_q (λI − A_q)^{-1} B_q G + D_q G``, ``G = C_e (λI − A_e)^{-1} B_e + D_e``, at one point, 50 digits."""
    with localcontext() as ctx:
        ctx.prec = 50
        Be = [([Decimal(float(v)) for v in Geb.B[:, j]], [Decimal(0)] * Geb.n) for j in range(Geb.m)]
        G = _dec_times(Geb.C, _dec_solve(Geb.A, lam, Be)) if Geb.n else [([Decimal(0)] * Geb.p,) * 2] * Geb.m
        G = [([g + Decimal(float(d)) for g, d in zip(re, Geb.D[:, j])], im) for j, (re, im) in enumerate(G)]
        Z = _dec_solve(Qb.A, lam, _dec_times(Qb.B, G)) if Qb.n else None
        R = [([a + b for a, b in zip(zr, gr)], [a + b for a, b in zip(zi, gi)]) for (zr, zi), (gr, gi) in
             zip(_dec_times(Qb.C, Z) if Z else [([Decimal(0)] * Qb.p,) * 2] * Geb.m, _dec_times(Qb.D, G))]
        return np.array([[float(R[j][0][i]) + 1j * float(R[j][1][i]) for j in range(Geb.m)] for i in range(Qb.p)])


def judge_cases(old_pc, seeds, reps):
    from fmu_fdi.design import approximate_model_matching
    from ammp_random_set import reference
    from synthesis_models import random_model

    new_values = pc._dd_refined_values
    calls = []

    def capturing(Qb, Geb, lam, steps=3):
        calls.append((Qb, Geb, np.array(lam)))
        return new_values(Qb, Geb, lam, steps)

    print(f"\n{'judge case':24s} {'base s':>7s} {'this s':>7s} {'ratio':>6s}  figures (decoupling, error) base / this")
    tot = {"base": 0.0, "this": 0.0}
    for seed in seeds:
        model = random_model(seed)
        ref = reference(model, seed)
        rows = {}
        for _ in range(reps):  # base and this alternate, best of reps each (a loaded machine drifts)
            for label, fn in (("base", old_pc._dd_refined_values), ("this", new_values)):
                pc._dd_refined_values = capturing if label == "this" and not calls else fn
                t, gen = best(lambda: approximate_model_matching(model, ref, norm="inf"), 1)
                if f"design {label}" not in rows or t < rows[f"design {label}"][0]:
                    rows[f"design {label}"] = (t, gen)
        pc._dd_refined_values = new_values
        gen = rows["design this"][1]
        S = np.ones((len(gen.groups), model.nf), int)
        for label, fn in (("base", old_pc._dd_refined_values), ("this", new_values)):
            pc._dd_refined_values = fn
            rows[f"judge {label}"] = best(lambda: pc.check_generator(copy.deepcopy(gen), structure=S,
                                                                       raise_error=False), reps)
        pc._dd_refined_values = capturing
        pc._UD_CACHE.clear()
        freqresp.clear_caches()
        pc.check_generator(copy.deepcopy(gen), structure=S, raise_error=False)
        pc._dd_refined_values = new_values
        for kind in ("design", "judge"):
            tb, tn = rows[f"{kind} base"][0], rows[f"{kind} this"][0]
            tot["base"] += tb
            tot["this"] += tn
            figs = [(f"{rows[f'{kind} {lab}'][1].info['postconditions']['decoupling']:.6g}"
                     if kind == "design" else f"{rows[f'{kind} {lab}'][1]['decoupling']:.6g}")
                    for lab in ("base", "this")]
            extra = (f" order {rows['design base'][1].Q.n if hasattr(rows['design base'][1], 'Q') else '?'} / "
                     f"{gen.Q.n if hasattr(gen, 'Q') else '?'}" if kind == "design" else "")
            print(f"{kind + f' seed {seed}':24s} {tb:7.2f} {tn:7.2f} {tb / tn:6.2f}  {figs[0]} / {figs[1]}{extra}")
        # every refined reading of the judge's final check, by both routines, in units of the judge's bound
        worst, big = 0.0, None
        for Qb, Geb, lam in calls:
            new = new_values(Qb, Geb, lam)
            old = old_pc._dd_refined_values(Qb, Geb, lam)
            err = pc._plain_values(Qb, Geb, lam)[1]
            unit = 3 * max(Qb.n, Geb.n, 1) * 2.0 ** -64 * err
            with np.errstate(divide="ignore", invalid="ignore"):
                worst = max(worst, float(np.nanmax(np.abs(new - old) / unit)))
            if big is None or lam.size * Qb.n > big[2].size * big[0].n:
                big = (Qb, Geb, lam, new, old, unit)
        line = f"  seed {seed}: {len(calls)} refined readings, |this − base| ≤ {worst:.2e} × bound"
        if big is not None:
            Qb, Geb, lam, new, old, unit = big
            pick = np.linspace(0, lam.size - 1, 3).astype(int)
            e_new = e_old = 0.0
            for k in pick:
                truth = decimal_reading(Qb, Geb, lam[k])
                e_new = max(e_new, float(np.max(np.abs(new[k] - truth) / unit[k])))
                e_old = max(e_old, float(np.max(np.abs(old[k] - truth) / unit[k])))
            line += (f"; 50-digit truth at 3 points (order {Qb.n}, plant {Geb.n}): base ≤ {e_old:.2e}, this ≤ "
                     f"{e_new:.2e} × bound")
        print(line)
        calls.clear()
    print(f"judge totals base {tot['base']:.2f} s / this {tot['this']:.2f} s = {tot['base'] / tot['this']:.2f}")


if __name__ == "__main__":
    reps = next((int(a.split("=")[1]) for a in sys.argv[1:] if a.startswith("--reps=")), 2)
    ref = next((a.split("=", 1)[1] for a in sys.argv[1:] if a.startswith("--base=")), "main")
    seeds = [4, 7]
    if "--seeds" in sys.argv:
        seeds = [int(a) for a in sys.argv[sys.argv.index("--seeds") + 1:] if a.isdigit()]
    assert np.finfo(np.longdouble).eps == np.finfo(float).eps and pc.DD_READING and lti.DOUBLE_DOUBLE
    old_lti = base_module(ref, "fmu_fdi/lti.py", "fmu_fdi._lti_base")
    old_pc = base_module(ref, "fmu_fdi/design/toolkit/postconditions.py", "fmu_fdi.design.toolkit._postconditions_base")
    print(f"baseline: {ref}; simulated double host (longdouble eps {np.finfo(np.longdouble).eps:.3g}), one BLAS thread")
    with threadpool_limits(limits=1, user_api="blas"):
        if "--judge-only" not in sys.argv:
            light_modes(old_lti._double_double_gains, reps)
        judge_cases(old_pc, seeds, reps)
