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


def timed(tree: Path, code: str) -> float:
    """Seconds printed by ``code`` run in a fresh interpreter with ``tree`` first on the path."""
    out = subprocess.check_output([sys.executable, "-c", code], cwd=tree, env={"PYTHONPATH": str(tree)}, text=True)
    return float(out.split()[-1])


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


if __name__ == "__main__":
    args = sys.argv[1:]
    run(next((int(a.split("=")[1]) for a in args if a.startswith("--reps=")), 7),
        next((a.split("=", 1)[1] for a in args if a.startswith("--base=")), "ae569eb"))
