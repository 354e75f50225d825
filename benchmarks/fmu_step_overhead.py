"""The co-simulation master's own cost per step over a bare fmpy loop on the same FMUs (issue 20, item 3).

A DTS200 plant FMU and its sensor-bank diagnoser FMU (the example campaign's pair,
:mod:`fmu_fdi.campaign.example`) are stepped together, Jacobi order, the pumps fed from
external signals, for ``--steps`` communication steps, three ways in one process:

* ``fmpy``: a bare loop on fmpy's ``FMU2Slave`` (``FMU3Slave``) calls — per step and FMU
  ``setReal`` of the inputs (the pumps at their operating flows, the bank's levels from the
  plant), ``doStep``, then ``getReal``/``getInteger``/``getBoolean`` of every output (what
  :class:`~fmu_fdi.cosim.CoSimulation` exchanges), the values kept in Python lists;
* ``ctypes``: the same calls on ctypes objects prepared once, the C functions called without
  argument conversion (no Python object per call): the floor of a Python master on these FMUs;
* ``CoSimulation``: the master, with a fault on a sensor connection (a campaign run's set-up),
  recording every row.

CPU time of this process (robust on a shared machine). Start-up is left out of every figure: each is the difference between a run of ``2 N`` and one
of ``N`` steps, divided by ``N`` (best of ``--repeat``). With ``--plant native --diagnoser
native`` (the default) the FMUs are C, so the FMUs' own cost does not mask the master's; the
pythonfmu ones are measured with ``--plant pythonfmu --diagnoser pythonfmu``.

    python benchmarks/fmu_step_overhead.py [--steps 5000] [--repeat 5] [--plant native|pythonfmu]
                                           [--diagnoser native|pythonfmu] [--fmi 2|3]

Everything is measured in the same invocation; on a shared machine the ratios are what to read.

Measured 2026-11-26 on the shared 2-vCPU machine (load average 12-17), CPU microseconds per step:

- native plant + native bank, FMI 2 (3000 steps, best of 5, two invocations): bare fmpy loop
  13.7 / 15.0, prepared ctypes 5.1 / 2.2, CoSimulation 8.7 / 9.0, i.e. the master 5-6 us *below*
  the bare fmpy loop (ratio 0.60-0.63; before this loop it was ~65 us above it);
- native, FMI 3: fmpy 33.2, ctypes 5.4, CoSimulation 7.3 (ratio 0.22: fmpy's FMI 3 calls are slow);
- pythonfmu plant + pythonfmu bank (2000 steps, best of 3): fmpy 124, CoSimulation 48 (0.38).
  (The prepared-ctypes loop measured 89 there, above the master: the pythonfmu FMUs' own cost
  varies between instances more than the loop costs.)
"""
from __future__ import annotations

import argparse
import ctypes
import json
import sys
import tempfile
import time
import zipfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout too


def build(folder: Path, plant: str, diagnoser: str, fmi: int) -> dict:
    """The example campaign's plant and bank FMUs in the asked flavours; ``{instance: path}``."""
    from fmu_fdi.campaign.example import build_fmus
    from fmu_fdi.fmu import build_fmu
    from plant_fmus.native_build import build_native

    fmus = build_fmus(folder)
    if fmi == 3 and "pythonfmu" in (plant, diagnoser):
        raise SystemExit("FMI 3 needs --plant native --diagnoser native")
    if plant == "native":
        fmus["plant"] = build_native("dts200", folder, reference=fmus["plant"], fmi_version=fmi)
    if diagnoser == "native":
        with zipfile.ZipFile(fmus["bank"]) as z:
            design = json.loads(z.read(next(n for n in z.namelist() if n.endswith("/design.json"))))
        fmus["bank"] = build_fmu(design, folder / f"bank_native{fmi}.fmu", target="native", fmi_version=fmi)
    return fmus


def setup(fmus: dict):
    """The master's set-up: the pumps from signals, a sensor fault on the bank's h1 connection."""
    from fmu_fdi.cosim import Fault, InputSignals
    from plant_fmus.dts200 import dts200_physics as phys

    _, q = phys.operating_point()
    signals = InputSignals([0.0], {"Q1": [float(q[0])], "Q2": [float(q[1])]})
    return signals, [Fault.abrupt("plant.h1", onset=1.0, magnitude=0.5)]


def cosim_seconds(fmus, steps: int) -> float:
    from fmu_fdi.cosim import CoSimulation

    signals, faults = setup(fmus)
    sim = CoSimulation(fmus, inputs=signals, step=1.0, stop=float(steps), order="jacobi", faults=faults)
    tic = time.process_time()
    sim.run()
    return time.process_time() - tic


class Bare:
    """Plant then bank on fmpy's classes, Jacobi order, every output read each step."""

    def __init__(self, fmus: dict, prepared: bool):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        from fmpy.fmi3 import FMU3Slave

        self.prepared = prepared
        self.units = []
        for name, path in fmus.items():
            md = read_model_description(str(path))
            cls = FMU2Slave if md.fmiVersion == "2.0" else FMU3Slave
            s = cls(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=name)
            outs = {}
            for v in md.modelVariables:
                if v.causality == "output":
                    outs.setdefault(_call(v, md), []).append(v.valueReference)
            ins = [v for v in md.modelVariables if v.causality == "input" and v.name in ("Q1", "Q2", "h1", "h2", "h3")]
            real = [v.name for v in md.modelVariables if v.causality == "output" and _call(v, md) in ("Real", "Float64")]
            self.units.append({"slave": s, "md": md, "outs": outs, "ins": [v.valueReference for v in ins],
                               "in_names": [v.name for v in ins], "real_outs": real, "fmi": int(md.fmiVersion[0])})
        # the inputs the master gives: the pumps at their operating flows, the bank's levels from
        # the plant's outputs (index of the level in the plant's Real outputs, or None)
        from plant_fmus.dts200 import dts200_physics as phys

        _, q = phys.operating_point()
        plant_real = self.units[0]["real_outs"]
        for u in self.units:
            u["in_values"] = [float(q[0]) if n == "Q1" else float(q[1]) if n == "Q2" else 0.0 for n in u["in_names"]]
            u["in_from"] = [(i, plant_real.index(n)) for i, n in enumerate(u["in_names"]) if n in plant_real]

    def start(self):
        for u in self.units:
            s = u["slave"]
            s.instantiate()
            if u["fmi"] == 2:
                s.setupExperiment(startTime=0.0)
                s.enterInitializationMode()
            else:
                s.enterInitializationMode(startTime=0.0)
            s.exitInitializationMode()
        if self.prepared:
            self._prepare()

    def _prepare(self):
        """Every call bound to ctypes objects made once (the C functions called without argument
        conversion, as :mod:`fmu_fdi.cosim.port` does): the least a Python loop can do."""
        import functools

        from ctypes import c_bool, c_double, c_int, c_size_t, c_uint, c_void_p

        for u in self.units:
            s, v = u["slave"], u["fmi"]
            comp = c_void_p(s.component)
            ct = {"Real": c_double, "Float64": c_double, "Integer": c_int, "Int32": ctypes.c_int32,
                  "Boolean": c_int if v == 2 else c_bool}

            def fn(name):
                f = s.dll[name]
                f.argtypes, f.restype = None, c_int
                return f

            calls = []
            for call, vrs in list(u["outs"].items()) + [("in", u["ins"])]:
                n = c_size_t(len(vrs))
                arr = (c_uint * len(vrs))(*vrs)
                if call == "in":
                    val = u["in_buf"] = (c_double * len(vrs))(*u["in_values"])
                    f = fn(f"fmi{v}Set{'Real' if v == 2 else 'Float64'}")
                else:
                    val = (ct[call] * len(vrs))()
                    f = fn(f"fmi{v}Get{call}")
                    if ct[call] is c_double:
                        u["real_buf"] = val
                args = (comp, arr, n, val) + ((n,) if v == 3 else ())
                calls.append(functools.partial(f, *args))
            u["get"], u["set"] = calls[:-1], calls[-1]
            u["t"] = c_double()
            flags = [c_bool() for _ in range(3)] + [c_double()]
            extra = (c_int(1),) if v == 2 else (c_bool(True), *(ctypes.byref(x) for x in flags))
            u["do"] = functools.partial(fn(f"fmi{v}DoStep"), comp, u["t"], c_double(1.0), *extra)

    def run(self, steps: int) -> float:
        tic = time.process_time()
        t = 0.0
        units = self.units
        plant = units[0]
        if not self.prepared:
            real_call = "Real" if plant["fmi"] == 2 else "Float64"
            levels = getattr(plant["slave"], "get" + real_call)(plant["outs"][real_call])
            for _ in range(steps):
                for u in units:
                    values = list(u["in_values"])
                    for i, j in u["in_from"]:
                        values[i] = levels[j]
                    u["slave"].setReal(u["ins"], values) if u["fmi"] == 2 else u["slave"].setFloat64(u["ins"], values)
                for u in units:
                    u["slave"].doStep(t, 1.0)
                for u in units:
                    s = u["slave"]
                    u["values"] = {call: getattr(s, "get" + call)(vrs) for call, vrs in u["outs"].items()}
                levels = plant["values"][real_call]
                t += 1.0
        else:
            for u in units:
                u["copies"] = [(i, j) for i, j in u["in_from"]]
            levels = plant["real_buf"]
            for g in plant["get"]:
                g()
            for _ in range(steps):
                for u in units:
                    buf = u["in_buf"]
                    for i, j in u["copies"]:
                        buf[i] = levels[j]
                    u["set"]()
                for u in units:
                    u["t"].value = t
                    u["do"]()
                for u in units:
                    for get in u["get"]:
                        get()
                t += 1.0
        return time.process_time() - tic

    def close(self):
        for u in self.units:
            u["slave"].terminate()
            u["slave"].freeInstance()


def _call(v, md) -> str:
    if md.fmiVersion == "2.0":
        return {"Enumeration": "Integer"}.get(v.type, v.type)
    return v.type


def per_step(run, steps: int, repeat: int) -> float:
    """Microseconds per step of ``run(n)`` (seconds for n steps) without its start-up: best of
    ``repeat`` of ``(run(2 N) − run(N)) / N``."""
    best = float("inf")
    for _ in range(repeat):
        best = min(best, (run(2 * steps) - run(steps)) / steps)
    return best * 1e6


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--plant", choices=("native", "pythonfmu"), default="native")
    ap.add_argument("--diagnoser", choices=("native", "pythonfmu"), default="native")
    ap.add_argument("--fmi", type=int, choices=(2, 3), default=2)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="step_overhead_") as tmp:
        fmus = build(Path(tmp), args.plant, args.diagnoser, args.fmi)

        def bare(prepared):
            def run(n):
                b = Bare(fmus, prepared)
                b.start()
                try:
                    return b.run(n)
                finally:
                    b.close()
            return run

        us = {"fmpy": per_step(bare(False), args.steps, args.repeat),
              "ctypes": per_step(bare(True), args.steps, args.repeat),
              "CoSimulation": per_step(lambda n: cosim_seconds(fmus, n), args.steps, args.repeat)}
    print(f"DTS200 plant ({args.plant}) + sensor bank ({args.diagnoser}), FMI {args.fmi}, Jacobi, "
          f"{args.steps} steps, best of {args.repeat}: microseconds per step (start-up excluded)")
    for name, value in us.items():
        print(f"  {name:13s} {value:8.1f} us")
    print(f"  CoSimulation over the bare fmpy loop: {us['CoSimulation'] - us['fmpy']:+.1f} us/step "
          f"(ratio {us['CoSimulation'] / us['fmpy']:.2f}; target <= +10 us)")
    print(f"  CoSimulation over prepared ctypes calls: {us['CoSimulation'] - us['ctypes']:+.1f} us/step "
          f"(ratio {us['CoSimulation'] / us['ctypes']:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
