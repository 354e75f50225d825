"""Speed and size of the native diagnostic FMU (issue 8, "Measure"), all ratios from one run.

The benchmark design of benchmarks/fmu_speed.py: a 10-state Luenberger residual generator (2
inputs, 3 outputs, 3 residuals), rms over 10 samples and a fixed threshold per residual.

1. fmpy ``FMU2Slave`` loop (fresh ``python -I``, the worker of fmu_speed.py; one step =
   setReal + doStep + getReal + getBoolean + getInteger): the native FMU against a trivial C
   FMU with the same variables and value references whose step copies inputs to outputs
   (benchmarks/trivial_fmu2.c): the floor set by fmpy's ctypes calls. Target: <= 1.2. The
   pythonfmu diagnostic FMU of the same design for comparison.
2. A plain C host (benchmarks/native_speed_host.c, dlopen, the same five calls per step):
   steps per second of the native FMU (target >= 2 million), of the trivial FMU, and of a
   plain C loop that only does the generator's matrix-vector product per sample,
   [r; x+] = [[C, D], [A, B]] [x; v], 13 x 15 multiply-adds, with the same input rows.
3. The size of the FMU files (target < 100 kB).
All timings are process CPU time (C: CLOCK_PROCESS_CPUTIME_ID, fmpy: time.process_time): on a
machine shared with other jobs the wall clock also counts the time a process waits for a core.

    python benchmarks/native_speed.py [--steps 5000] [--repeat 5] [--c-steps 2000000]
"""
from __future__ import annotations

import argparse
import hashlib
import os
import statistics
import subprocess
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent

PLAIN_LOOP = r"""
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
static const double M[__ROWS__ * __COLS__] = {__M__};
int main(int argc, char **argv) {
    long steps = atol(argv[1]), k;
    int i, j, nx = __NX__, nv = __NV__, nr = __NR__;
    double xv[__COLS__] = {0}, z[__ROWS__], *data = malloc(sizeof(double) * 1024 * __NV__), sum = 0, t0, t1;
    unsigned long long seed = 12345u;
    struct timespec ts;
    for (j = 0; j < 1024 * nv; j++) {
        seed ^= seed << 13; seed ^= seed >> 7; seed ^= seed << 17;
        data[j] = (double)(seed >> 11) / 4503599627370496.0 - 1.0;
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    t0 = ts.tv_sec + 1e-9 * ts.tv_nsec;
    for (k = 0; k < steps; k++) {
        const double *v = &data[(k & 1023) * nv];
        for (j = 0; j < nv; j++) xv[nx + j] = v[j];
        for (i = 0; i < __ROWS__; i++) {
            double s = 0.0;
            for (j = 0; j < __COLS__; j++) s += M[i * __COLS__ + j] * xv[j];
            z[i] = s;
        }
        for (i = 0; i < nx; i++) xv[i] = z[nr + i];
        sum += z[0];
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    t1 = ts.tv_sec + 1e-9 * ts.tv_nsec;
    printf("%.6g %.17g\n", (t1 - t0) / (double)steps, sum);
    free(data);
    return 0;
}
"""


def _cc() -> str:
    from fmu_fdi.native.build import find_compiler

    return " ".join(find_compiler())


def trivial_fmu(design: dict, dest: Path) -> Path:
    """The trivial C FMU: the native FMU's modelDescription (same variables), trivial_fmu2.c inside."""
    import fmpy

    from fmu_fdi.native.build import model_description, variables

    n_in = sum(v["causality"] == "input" for v in variables(design))
    n_out = sum(v["causality"] == "output" for v in variables(design))
    ident = "trivial_" + hashlib.sha256(design["name"].encode()).hexdigest()[:8]
    token = "{" + str(uuid.UUID(hashlib.sha256(ident.encode()).hexdigest()[:32])) + "}"
    with tempfile.TemporaryDirectory() as tmp:
        lib = Path(tmp, f"{ident}.so")
        subprocess.run([*_cc().split(), "-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror",
                        f"-DN_IN={n_in}", f"-DN_OUT={n_out}", f'-DGUID="{token}"',
                        f"-I{Path(fmpy.__file__).parent / 'c-code'}", str(HERE / "trivial_fmu2.c"), "-o", str(lib)],
                       check=True)
        with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", model_description(design, ident, token, 2, ["trivial_fmu2.c"]))
            zf.write(lib, f"binaries/linux64/{ident}.so")
            zf.write(HERE / "trivial_fmu2.c", "sources/trivial_fmu2.c")
    return dest


def c_host_seconds(exe: Path, fmu: Path, steps: int, repeat: int) -> float:
    """Median seconds per step of ``fmu`` in the C benchmark host."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu))
    by = {"in": [], "Real": [], "Boolean": [], "Integer": []}
    for v in md.modelVariables:
        if v.causality == "input":
            by["in"].append(v.valueReference)
        elif v.causality == "output":
            by[v.type].append(v.valueReference)
    with tempfile.TemporaryDirectory() as tmp:
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(tmp)
        runs = []
        for _ in range(repeat):
            out = subprocess.run([str(exe), tmp, md.coSimulation.modelIdentifier, md.guid, str(steps),
                                  repr(float(md.defaultExperiment.stepSize)),
                                  *(",".join(map(str, by[k])) for k in ("in", "Real", "Boolean", "Integer"))],
                                 capture_output=True, text=True, check=True).stdout
            runs.append(float(out.split()[0]))
    return statistics.median(runs)


def plain_loop_seconds(design: dict, folder: Path, steps: int, repeat: int) -> float:
    """Median seconds per sample of the bare generator matrix-vector product."""
    import numpy as np

    g = design["generator"]["discrete"]
    A, B, C, D = (np.atleast_2d(np.asarray(g[k], float)) for k in ("A", "B", "C", "D"))
    M = np.block([[C, D], [A, B]])
    src = (PLAIN_LOOP.replace("__ROWS__", str(M.shape[0])).replace("__COLS__", str(M.shape[1]))
           .replace("__NX__", str(A.shape[0])).replace("__NV__", str(B.shape[1])).replace("__NR__", str(C.shape[0]))
           .replace("__M__", ", ".join(float(x).hex() for x in M.ravel())))
    (folder / "plain.c").write_text(src)
    exe = folder / "plain"
    subprocess.run([*_cc().split(), "-std=c99", "-O2", str(folder / "plain.c"), "-o", str(exe)], check=True)
    runs = [float(subprocess.run([str(exe), str(steps)], capture_output=True, text=True, check=True).stdout.split()[0])
            for _ in range(repeat)]
    return statistics.median(runs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000, help="steps per fmpy run")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--c-steps", type=int, default=2_000_000, help="steps per C host run")
    args = ap.parse_args()
    sys.path.insert(0, str(HERE.parent))  # run from a checkout too
    sys.path.insert(0, str(HERE))
    import fmpy

    from fmu_speed import _host, benchmark_diagnoser

    from fmu_fdi import build_fmu
    from fmu_fdi.fmu.builder import _design_of

    dg = benchmark_diagnoser()
    design = _design_of(dg)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        native2 = build_fmu(dg, tmp / "bench_native2.fmu", target="native", fmi_version=2)
        native3 = build_fmu(dg, tmp / "bench_native3.fmu", target="native", fmi_version=3)
        trivial = trivial_fmu(design, tmp / "trivial.fmu")
        t_trivial = _host(trivial, args.steps, args.repeat, "process_time")
        t_native = _host(native2, args.steps, args.repeat, "process_time")
        t_python = _host(build_fmu(dg, tmp / "bench_pythonfmu.fmu"), args.steps, args.repeat, "process_time")
        exe = tmp / "native_speed_host"
        subprocess.run([*_cc().split(), "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror",
                        f"-I{Path(fmpy.__file__).parent / 'c-code'}", str(HERE / "native_speed_host.c"),
                        "-o", str(exe), "-ldl"], check=True)
        c_native = c_host_seconds(exe, native2, args.c_steps, args.repeat)
        c_trivial = c_host_seconds(exe, trivial, args.c_steps, args.repeat)
        c_plain = plain_loop_seconds(design, tmp, args.c_steps, args.repeat)
        sizes = {p.name: os.path.getsize(p) for p in (native2, native3)}
        with zipfile.ZipFile(native2) as zf:
            so = next(i for i in zf.infolist() if i.filename.endswith(".so"))
    print(f"benchmark design: 10-state generator, 3 residuals, rms:10; medians of {args.repeat} runs")
    print(f"fmpy FMU2Slave loop, {args.steps} steps per run (setReal + doStep + getReal/Boolean/Integer), CPU time:")
    print(f"  trivial C FMU (same interface)   {t_trivial:8.2f} us/step   1.00")
    print(f"  native diagnostic FMU            {t_native:8.2f} us/step   {t_native / t_trivial:4.2f}  (target <= 1.2)")
    print(f"  pythonfmu diagnostic FMU         {t_python:8.2f} us/step   {t_python / t_trivial:4.2f}")
    print(f"C host (dlopen, same five calls), {args.c_steps} steps per run, CPU time:")
    print(f"  plain C loop, matrix-vector only {c_plain * 1e9:8.1f} ns/step   1.00   {1 / c_plain / 1e6:6.1f} M steps/s")
    print(f"  trivial C FMU                    {c_trivial * 1e9:8.1f} ns/step   {c_trivial / c_plain:4.2f}   "
          f"{1 / c_trivial / 1e6:6.1f} M steps/s")
    print(f"  native diagnostic FMU            {c_native * 1e9:8.1f} ns/step   {c_native / c_plain:4.2f}   "
          f"{1 / c_native / 1e6:6.1f} M steps/s  (target >= 2 M steps/s)")
    print(f"size: {', '.join(f'{k} {v / 1000:.1f} kB' for k, v in sizes.items())} (target < 100 kB); "
          f"the FMI 2 binary {so.file_size / 1000:.1f} kB ({so.compress_size / 1000:.1f} kB compressed)")


if __name__ == "__main__":
    main()
