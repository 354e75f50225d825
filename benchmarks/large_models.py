"""Cost of analysis and design for large models (issue 12 item 7), stage by stage.

For random stable plants with n states (2 inputs, 4 sensors, 4 sensor faults and one
actuator fault) it times each stage the CLI runs, and prints it both in seconds and as a
ratio to one dense eigenvalue problem of size n (``numpy.linalg.eigvals(A)``, measured in
the same run): that ratio is the machine-independent cost (the stages are sums of O(n³)
dense factorisations), so the seconds for another n or machine follow from one
eigenvalue timing.

    python benchmarks/large_models.py [n ...]        (default: 500 1000)

The model and design files are written and read (both keep the matrices of a large model in a
binary ``.npz`` sidecar) and the diagnostic FMU is built for both targets (the native one compiles
the runtime's own units once per machine into its object cache, :mod:`fmu_fdi.native.objcache`:
a first build after a change of the C sources costs a few seconds more). The model file is read three ways: the default ``to_file`` (TOML with its matrices in a
binary ``.npz`` sidecar above ``fmu_fdi.sidecar.SIDECAR_MIN_ENTRIES`` numbers), all-text
JSON and all-text TOML (the last two are the old formats, for comparison; the all-text TOML
is skipped above n = 500, where it takes tens of seconds in Python's TOML parser).

Under ``nullspace design`` the indented lines are its parts, timed inside that one run: the pencil
basis (output-nulling deflation and controllability staircase, ``pencil.pencil_basis``), the simple
rows (chain order and Type 1 covers, ``pencil.simple_rows``), the rows' fault gains on the design
grid (``nullspace._pencil_gains``) and the judge (``postconditions.check_generator``). The kept
Schur forms, spectra and values of :mod:`fmu_fdi.freqresp` are forgotten before every stage, so each
stage costs what it costs in a process of its own (as the CLI runs ``analyze`` and ``design``).

BLAS runs single-threaded unless OPENBLAS_NUM_THREADS is set: on a loaded machine the
threaded BLAS was 100-300x slower for these sizes (eigvals of 100 x 100: 2.7 ms with one
thread, 741 ms with two threads on 2 busy cores), which would hide the scaling.
"""
from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np  # noqa: E402


def plant(n: int, seed: int = 1):
    from fmu_fdi import FDIModel, actuator_fault, sensor_fault

    rng = np.random.default_rng(seed)
    A = -2 * np.eye(n) + rng.standard_normal((n, n)) / np.sqrt(n)  # spectrum in the disc |s + 2| <~ 1
    B, C = rng.standard_normal((n, 2)), rng.standard_normal((4, n))
    return FDIModel.from_matrices(A, B, C, u_names=["u1", "u2"], y_names=[f"y{i}" for i in range(4)],
                                  faults=[sensor_fault(f"s{i}", f"y{i}") for i in range(4)]
                                  + [actuator_fault("a1", "u1")], name=f"random{n}")


def timed(fn, *args, **kw):
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t0


def fresh() -> None:
    """Forget the factorisations kept across calls (each stage timed as in a process of its own)."""
    try:
        from fmu_fdi.freqresp import clear_caches
    except ImportError:  # the code before fmu_fdi.freqresp (the 'before' figures)
        return
    clear_caches()


@contextmanager
def parts():
    """Time the parts of nullspace_design inside one run: ``{part: seconds}`` (module attributes wrapped)."""
    import fmu_fdi.design.problems.nullspace as ns
    import fmu_fdi.design.toolkit.pencil as pe

    spent: dict = {}
    targets = [(pe, "pencil_basis", "pencil basis (staircase)"), (pe, "simple_rows", "simple rows (covers)"),
               (ns, "_pencil_gains", "row gains (design grid)"), (ns, "check_generator", "judge (post-conditions)")]
    saved = [(mod, name, getattr(mod, name)) for mod, name, _ in targets]

    def wrap(fn, label):
        def inner(*args, **kw):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kw)
            finally:
                spent[label] = spent.get(label, 0.0) + time.perf_counter() - t0
        return inner

    for (mod, name, fn), (_, _, label) in zip(saved, targets):
        setattr(mod, name, wrap(fn, label))
    try:
        yield spent
    finally:
        for mod, name, fn in saved:
            setattr(mod, name, fn)


def warm_native_cache() -> None:
    """Build a small native FMU (FMI 2 and 3) untimed: the runtime's objects, compiled once per machine
    and source change (:mod:`fmu_fdi.native.objcache`), are then in the cache as for any later build."""
    from fmu_fdi import Diagnoser
    from fmu_fdi.design.problems.nullspace import nullspace_design
    from fmu_fdi.fmu.builder import build_fmu

    dg = Diagnoser(nullspace_design(plant(6)), Ts=0.1, thresholds=1.0)
    with tempfile.TemporaryDirectory() as tmp:
        for fmi in (2, 3):
            build_fmu(dg, Path(tmp) / f"w{fmi}.fmu", target="native", fmi_version=fmi)


def measure(n: int) -> dict:
    from fmu_fdi import Diagnoser, FDIModel
    from fmu_fdi.analysis import detectability, isolability
    from fmu_fdi.design.problems.nullspace import nullspace_design
    from fmu_fdi.fmu.builder import build_fmu

    warm_native_cache()
    m = plant(n)
    base = min(timed(np.linalg.eigvals, m.A)[1] for _ in range(3))
    out = {"eigvals (unit)": base}
    with tempfile.TemporaryDirectory() as tmp:
        path, out["save model (sidecar)"] = timed(m.to_file, Path(tmp) / "m.toml")  # the default at this size
        m, out["load model (sidecar)"] = timed(FDIModel.from_file, path)
        _, out["load model (JSON text)"] = timed(FDIModel.from_file, m.to_file(Path(tmp) / "t.json", sidecar=False))
        if n <= 500:
            _, out["load model (TOML text)"] = timed(FDIModel.from_file,
                                                     m.to_file(Path(tmp) / "t.toml", sidecar=False))
        fresh()
        _, out["detectability"] = timed(detectability, m)
        fresh()
        _, out["isolability"] = timed(isolability, m)
        fresh()
        with parts() as part:
            gen, out["nullspace design"] = timed(nullspace_design, m)
        out.update({f"  {k}": t for k, t in part.items()})
        fresh()
        gen, out["discretise (Ts = 0.1)"] = timed(gen.to_discrete, 0.1)
        dg, out["diagnoser (validate)"] = timed(Diagnoser, gen, thresholds=1.0)
        _, out["save design file"] = timed(dg.save, Path(tmp) / "d.json")
        _, out["load design file"] = timed(Diagnoser.load, Path(tmp) / "d.json")
        for target, fmi in (("pythonfmu", 2), ("native", 2), ("native", 3)):
            _, out[f"build FMU ({target}, FMI {fmi})"] = timed(build_fmu, Path(tmp) / "d.json", Path(tmp) / "d.fmu",
                                                               target=target, fmi_version=fmi)
    # the unit again at the end: on a shared machine the smaller of the two is the machine's
    out["eigvals (unit)"] = min(base, min(timed(np.linalg.eigvals, m.A)[1] for _ in range(3)))
    return out


def main(sizes):
    for n in sizes:
        res = measure(n)
        base = res["eigvals (unit)"]
        print(f"n = {n}: one eigvals(A) = {base * 1e3:.3g} ms (load average {os.getloadavg()[0]:.2f})")
        for stage, t in res.items():
            if stage != "eigvals (unit)":
                print(f"  {stage:<28} {t:9.3f} s   {t / base:9.1f} x eigvals"
                      + ("   (comparison, not in the total)" if "text" in stage else "")
                      + ("   (part of the design)" if stage.startswith(" ") else ""))
        total = sum(t for k, t in res.items() if k != "eigvals (unit)" and "text" not in k and not k.startswith(" "))
        analyze = res["load model (sidecar)"] + res["detectability"] + res["isolability"]
        design = res["load model (sidecar)"] + res["nullspace design"]
        print(f"  {'total':<28} {total:9.3f} s   {total / base:9.1f} x eigvals")
        both = analyze + design
        print(f"  {'analyze + design (CLI)':<28} {both:9.3f} s   {both / base:9.1f} x eigvals", flush=True)


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [500, 1000])
