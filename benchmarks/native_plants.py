"""Native C plant FMUs against the pythonfmu plants (issue 20, item 4): steps per second.

Every plant is built both ways from this tree (the native FMU takes the pythonfmu FMU's
variables) and stepped by fmpy's FMU2Slave in a fresh process, noise on, from its default
operating point, at rest and with its first command input stepping by 10 % every 10 steps;
CPU microseconds per ``doStep + getReal`` of the Real outputs, best of 5
(:func:`campaign_speed.step_cost`, the loop of the plant-cost benchmark), and the ratio.
Both are measured in the same invocation; on a shared machine read the ratios.

    python benchmarks/native_plants.py [--steps 2000] [--plants dts200 vtol ...]

Of the native figure in fmpy, most is fmpy's ctypes call overhead (a few us per FMI call). The
native plants are also stepped at rest by benchmarks/native_speed_host.c (dlopen, no Python:
doStep + get of every output per step), which shows the C step itself.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from campaign_speed import step_cost  # noqa: E402


HOST = Path(__file__).resolve().parent / "native_speed_host.c"


def c_host_us(exe: Path, fmu: str, steps: int) -> float:
    """CPU us per step of ``fmu`` at rest in the C host (no inputs set; every output read)."""
    from fmpy import read_model_description

    md = read_model_description(fmu)
    by = {"Real": [], "Boolean": [], "Integer": []}
    for v in md.modelVariables:
        if v.causality == "output":
            by[v.type].append(str(v.valueReference))
    with tempfile.TemporaryDirectory() as tmp:
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(tmp)
        best = min(float(subprocess.run([str(exe), tmp, md.coSimulation.modelIdentifier, md.guid, str(steps),
                                         repr(float(md.defaultExperiment.stepSize)), "",
                                         *(",".join(by[k]) for k in ("Real", "Boolean", "Integer"))],
                                        capture_output=True, text=True, check=True).stdout.split()[0])
                   for _ in range(5))
    return best * 1e6


def main(argv=None) -> int:
    import plant_fmus
    from plant_fmus.native_build import build_native

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--plants", nargs="*", default=list(plant_fmus.PLANTS))
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="native_plants_bench_") as tmp:
        pairs = {}
        for name in args.plants:
            ref = plant_fmus.build(name, Path(tmp, "ref"))
            pairs[name] = (str(ref), str(build_native(name, Path(tmp, "native"), reference=ref)))
        import fmpy

        exe = Path(tmp, "native_speed_host")
        subprocess.run([os.environ.get("CC", "gcc"), "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror",
                        f"-I{Path(fmpy.__file__).parent / 'c-code'}", str(HOST), "-o", str(exe), "-ldl"], check=True)
        print(f"CPU us per doStep + getReal ({args.steps} steps, best of 5), pythonfmu vs native C:")
        for excite in ("rest", "excited"):
            print(f" {excite}:")
            for name, (ref, native) in pairs.items():
                py, c = step_cost(ref, args.steps, excite), step_cost(native, args.steps, excite)
                print(f"  {name:18s} pythonfmu {py:7.1f} us ({1e6 / py:8.0f} steps/s)   native {c:6.2f} us "
                      f"({1e6 / c:9.0f} steps/s)   ratio {py / c:6.1f}x", flush=True)
        print(f"native plants at rest in a plain C host ({100 * args.steps} steps, best of 5):")
        for name, (_, native) in pairs.items():
            us = c_host_us(exe, native, 100 * args.steps)
            print(f"  {name:18s} {us:7.3f} us/step ({1e6 / us:10.0f} steps/s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
