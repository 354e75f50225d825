"""Cost of the H∞ light-mode readings on a host whose longdouble is double (double-double,
``lti._double_double_gains``) against the native x86 longdouble readings (``lti._extended_gains``), same run.

Cases: tests/test_hinfnorm_damping.py's sections (ζ = 1e-8, 1e-9, 1e-10 at ωn = 1, 37), ``mixed`` systems (ζ 1e-9,
1e-10) and Tustin images (ζ 1e-9, 1e-10) — peaks both hosts read. Each case's ``hinfnorm`` is timed (best of R calls)
in this process (native) and in a subprocess simulating the double host (tests/test_double_host.PATCH before fmu_fdi
is imported); prints both times, their ratio and the two norms' relative difference; then the geometric mean of
the ratios and the ratio of the totals. Run with OPENBLAS_NUM_THREADS=1.

Run: python benchmarks/double_host_hinf_speed.py [R]

Measured 28 Nov (host20, R = 2, one BLAS thread, load ~6-8): every case 10.2-14.5x slower on the simulated double host
(0.05 s -> 0.47-0.74 s a norm; geometric mean 12.72, totals 6.39 s / 0.50 s = 12.77): per point the double-double
residual is ~40 numpy calls on arrays of a few entries, for ~190 points per light mode (the scan of
``_LightModes.settle``); the norms agree to 1.4e-10 (both within TOL of the decimal judge). Only systems with a
light mode (eps·s_A/d > rtol) take this path; the x86 path is unchanged.

28 Nov (dd23: the residual of all points at once, its products exact BLAS slice products, ``lti.sliced_dot``), R = 2,
one BLAS thread, load ~5-7: geometric mean double/native 0.89 (0.55-1.14 per case; totals 0.22 s / 0.21 s); the norms
agree to 1.4e-10. Before/after on the simulated host in one run: benchmarks/double_host_dd_speed.py.
"""
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from test_double_host import PATCH  # noqa: E402

_CASES = """
import numpy as np
import test_hinfnorm_damping as th
CASES = ([(f"section z={z:g} wn={wn:g}", lambda z=z, wn=wn: th.light(z, wn)) for z in (1e-8, 1e-9, 1e-10)
          for wn in (1.0, 37.0)]
         + [(f"mixed z={z:g} seed={s}", lambda z=z, s=s: th.mixed(z, s, False)) for z, s in ((1e-9, 7), (1e-10, 1))]
         + [(f"tustin z={z:g}", lambda z=z: th.tustin(th.light(z, 1.0), 0.5)) for z in (1e-9, 1e-10)])
"""

_TIME = """
import json, sys, time
R = int(sys.argv[1])
out = []
for name, make in CASES:
    G, best = make(), float("inf")
    for _ in range(R):
        t0 = time.perf_counter()
        g = G.hinfnorm()[0]
        best = min(best, time.perf_counter() - t0)
    out.append([name, best, g])
print(json.dumps(out))
"""


def run(repeats: int):
    env_path = str(ROOT) + ":" + str(ROOT / "tests")
    import os

    env = dict(os.environ, PYTHONPATH=env_path + ":" + os.environ.get("PYTHONPATH", ""))
    res = {}
    for host, head in (("native", ""), ("double", PATCH + "\n")):
        proc = subprocess.run([sys.executable, "-c", head + _CASES + _TIME, str(repeats)], capture_output=True,
                              text=True, env=env, cwd=str(ROOT / "tests"))
        if proc.returncode:
            raise SystemExit(proc.stderr[-2000:])
        res[host] = {name: (t, g) for name, t, g in json.loads(proc.stdout.strip().splitlines()[-1])}
    import math

    print(f"{'case':26s} {'native s':>9s} {'double s':>9s} {'ratio':>7s} {'rel diff':>9s}")
    logs, tn, td = [], 0.0, 0.0
    for name, (t_n, g_n) in res["native"].items():
        t_d, g_d = res["double"][name]
        logs.append(math.log(t_d / t_n))
        tn, td = tn + t_n, td + t_d
        print(f"{name:26s} {t_n:9.3f} {t_d:9.3f} {t_d / t_n:7.2f} {abs(g_d - g_n) / g_n:9.1e}")
    print(f"geometric mean double/native {math.exp(sum(logs) / len(logs)):.2f}; totals {td:.2f} s / {tn:.2f} s = "
          f"{td / tn:.2f}")


if __name__ == "__main__":
    t0 = time.perf_counter()
    run(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
    print(f"({time.perf_counter() - t0:.0f} s)")
