"""One-time import costs of the designs: ``import fmu_fdi.design`` in a fresh interpreter, this tree against a
baseline ref (``git archive REF`` unpacked in a temporary directory), alternating, best of ``--reps`` (default 7);
then, in this tree, what the first design adds: ``from scipy.signal import place_poles`` after the import (the
first pole placement, toolkit.pencil._place, imports it inside the function).

Where the time goes (``python -X importtime``, 27 Nov): ``import fmu_fdi`` does not load fmu_fdi.design. At
``import fmu_fdi.design``, toolkit._select's module-level ``import scipy.optimize`` cost 0.16 s unloaded (one
Nelder–Mead call in one function uses it) — now imported there. The first design that places poles imports
scipy.signal (0.35 s unloaded, ~1.0 s at load 4–7): its package init (_support_alternative_backends →
_signal_api) loads scipy.stats (0.22 s, through _peak_finding; scipy.stats loads scipy.optimize),
scipy.ndimage (_signaltools) and scipy.interpolate (_ltisys), of which place_poles needs none. A submodule import
runs the package init first, so no import style avoids it; only a placement outside scipy.signal does (SLICOT
SB01BD through slycot, already loaded for AB13DD, is another method and moves every design; scipy's KNV/YT code
copied into the tree keeps every design bit for bit, ~300 lines).

Measured 27 Nov (audit17, 2-core machine shared with three other sessions, load ~8; ``--reps=7`` against ae569eb):

    import fmu_fdi.design: ae569eb 1.372 s, this 0.886 s, ratio 1.55 (best of 7, alternating fresh interpreters)
    then from scipy.signal import place_poles (the first pole placement): 1.572 s

hinf18 (28 Nov, load ~8, ``--reps=5 --base=253b4cb``; this tree's import is main's): import fmu_fdi.design 0.713 s
vs 0.716 s; from scipy.signal import place_poles after it 1.247 s; the first design (nullspace_design, two states)
1.708 s, the second 0.208 s, the first with scipy.signal imported before the clock 0.233 s — scipy.signal's package
setup is 86 % of the first design. ``-X importtime`` of that first design: scipy.signal 1.56 s cumulative, of which
scipy.stats 0.69 s (through _peak_finding), _signaltools 0.53 s (ndimage, spatial), _ltisys 0.31 s (interpolate,
which loads optimize, sparse.linalg/ARPACK), windows 0.18 s; the design itself also first loads threadpoolctl
(15 ms, fmu_fdi.linalg). place_poles needs numpy and scipy.linalg only: its code (scipy/signal/_ltisys.py:
place_poles, _valid_inputs, _order_complex_poles, _KNV0, _KNV0_loop, _YT_real, _YT_complex, _YT_loop; BSD-3) run
as a module of its own imports in 0.3 ms and gave bit for bit scipy 1.17.1's gain on 478 of 478 random placements
(n 1–8, YT and KNV0) — the change proposed for toolkit/pencil.py, observers/_observer.py and
problems/datadriven.py (not this benchmark's owner's files). At ``import fmu_fdi.design`` the largest part is
scipy.linalg's own (0.5–0.6 s under load): its vendored array_api_compat clones the numpy namespace, which loads
every lazy numpy submodule, numpy.f2py and numpy.testing among them (~0.25 s under load) — upstream, not ours.

Run: python benchmarks/import_speed.py [--reps=N] [--base=REF]
"""
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IMPORT = "import time; t = time.perf_counter(); import fmu_fdi.design; print(time.perf_counter() - t)"
SIGNAL = ("import time, fmu_fdi.design; t = time.perf_counter(); from scipy.signal import place_poles; "
          "print(time.perf_counter() - t)")
#: the first and the second design after ``import fmu_fdi.design`` (a two-state plant, a sensor and an actuator fault:
#: nullspace_design places poles), optionally with scipy.signal imported before the clock starts; prints
#: "signal-import first second" seconds
FIRST = """import sys, time, numpy as np
from fmu_fdi import FDIModel, sensor_fault, actuator_fault
import fmu_fdi.design as D
t0 = time.perf_counter()
if sys.argv[1] == "pre":
    from scipy.signal import place_poles  # noqa: F401
t1 = time.perf_counter()
times = []
for _ in range(2):
    m = FDIModel.from_matrices(np.array([[-1.0, 1.0], [0.0, -2.0]]), [[0.0], [1.0]], np.eye(2),
                               faults=[sensor_fault("s0", "y0"), actuator_fault("a0", "u0")])
    t = time.perf_counter()
    D.nullspace_design(m)
    times.append(time.perf_counter() - t)
print(t1 - t0, *times)"""


def timed(tree: Path, code: str, *args: str) -> float | list[float]:
    """Seconds printed by ``code`` run in a fresh interpreter with ``tree`` first on the path (the last figure, or
    all when there are several)."""
    out = subprocess.check_output([sys.executable, "-c", code, *args], cwd=tree, env={"PYTHONPATH": str(tree)},
                                  text=True).split()
    return float(out[-1]) if len(out) == 1 else [float(x) for x in out]


def first_design(reps: int) -> None:
    """The first design's time, cold and with scipy.signal imported first (alternating, best of ``reps``)."""
    cold, pre = [], []
    for _ in range(reps):
        cold.append(timed(ROOT, FIRST, "cold"))
        pre.append(timed(ROOT, FIRST, "pre"))
    c1, c2 = min(c[1] for c in cold), min(c[2] for c in cold)
    s, p1 = min(p[0] for p in pre), min(p[1] for p in pre)
    print(f"first design after import fmu_fdi.design: {c1:.3f} s (second {c2:.3f} s); with scipy.signal imported "
          f"before it ({s:.3f} s): {p1:.3f} s — the package setup is {(c1 - p1) / c1:.0%} of the first design")


def run(reps: int, ref: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        archive = subprocess.check_output(["git", "archive", ref, "fmu_fdi"], cwd=ROOT)
        subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)
        this, main = [], []
        for _ in range(reps):
            this.append(timed(ROOT, IMPORT))
            main.append(timed(base, IMPORT))
        print(f"import fmu_fdi.design: {ref} {min(main):.3f} s, this {min(this):.3f} s, ratio "
              f"{min(main) / min(this):.2f} (best of {reps}, alternating fresh interpreters)")
        sig = min(timed(ROOT, SIGNAL) for _ in range(max(2, reps // 2)))
        print(f"then from scipy.signal import place_poles (the first pole placement): {sig:.3f} s")
    first_design(max(2, reps // 2))


if __name__ == "__main__":
    args = sys.argv[1:]
    run(next((int(a.split("=")[1]) for a in args if a.startswith("--reps=")), 7),
        next((a.split("=", 1)[1] for a in args if a.startswith("--base=")), "ae569eb"))
