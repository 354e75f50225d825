"""Microseconds per communication step of a trivial pass-through pythonfmu FMU, hosted by fmpy.

Baseline for the diagnostic FMU: what pythonfmu + fmpy cost before any diagnosis happens.
Two pass-through slaves (``y = u``, one Real in, one Real out) are built:

* ``plain``:    a bare ``pythonfmu.Fmi2Slave`` (pythonfmu's own cost);
* ``fdislave``: on ``fmu_fdi.fmu.slave_base.FdiSlave`` (catch-all callbacks, lazy outputs).

Each is stepped in an fmpy ``FMU2Slave`` loop in a fresh ``python -I`` process; one step is
``setReal([u]) + doStep + getReal([y])``, and the three calls are also timed alone. The
median over ``--repeat`` runs of ``--steps`` steps is printed.

    python benchmarks/pythonfmu_step_overhead.py [--steps 20000] [--repeat 5]
"""
import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PLAIN = '''
from pythonfmu import Fmi2Slave, Fmi2Causality, Real


class PassThrough(Fmi2Slave):
    """y = u"""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input, description="input"))
        self.register_variable(Real("y", causality=Fmi2Causality.output, description="output"))

    def do_step(self, current_time, step_size):
        self.y = self.u
        return True
'''

FDI = '''
from pythonfmu import Fmi2Causality, Real

from .slave_base import FdiSlave


class PassThrough(FdiSlave):
    """y = u"""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input, description="input"))
        self.register_variable(Real("y", causality=Fmi2Causality.output, description="output"))

    def update_outputs(self):
        self.y = self.u

    def step(self, current_time, step_size):
        return True
'''


def worker(fmu_path, steps, repeat):
    """Runs in the benchmark process: fmpy only."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(fmu_path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu_path), modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="bench")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    u, y, h = [vr["u"]], [vr["y"]], 1e-3
    result = {"step": [], "setReal": [], "doStep": [], "getReal": []}
    t = 0.0
    for _ in range(repeat):
        t0 = time.perf_counter()
        for k in range(steps):
            fmu.setReal(u, [float(k)])
            fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            out = fmu.getReal(y)
            t += h
        result["step"].append((time.perf_counter() - t0) / steps * 1e6)
        assert out[0] == float(steps - 1)
        for name, call in (("setReal", lambda: fmu.setReal(u, [1.0])),
                           ("doStep", lambda: fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)),
                           ("getReal", lambda: fmu.getReal(y))):
            t0 = time.perf_counter()
            for _ in range(steps):
                call()
            if name == "doStep":
                t += steps * h
            result[name].append((time.perf_counter() - t0) / steps * 1e6)
    fmu.terminate()
    fmu.freeInstance()
    print(json.dumps(result))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout too
    import numpy as np
    from fmu_fdi.fmu.packaging import build_slave_fmu

    with tempfile.TemporaryDirectory() as tmp:
        fmus = {
            "plain": build_slave_fmu({"passthrough.py": PLAIN}, "passthrough:PassThrough", Path(tmp, "plain.fmu")),
            "fdislave": build_slave_fmu({"passthrough.py": FDI}, "passthrough:PassThrough", Path(tmp, "fdi.fmu")),
        }
        print(f"fmpy FMU2Slave loop, {args.steps} steps x {args.repeat} runs, median microseconds per call")
        print(f"{'slave':10s} {'set+step+get':>13s} {'setReal':>9s} {'doStep':>9s} {'getReal':>9s}")
        for name, fmu in fmus.items():
            proc = subprocess.run([sys.executable, "-I", __file__, "--worker", str(fmu), str(args.steps),
                                   str(args.repeat)], capture_output=True, text=True, check=True)
            res = json.loads(proc.stdout.strip().splitlines()[-1])
            med = {k: float(np.median(v)) for k, v in res.items()}
            print(f"{name:10s} {med['step']:13.1f} {med['setReal']:9.1f} {med['doStep']:9.1f} {med['getReal']:9.1f}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
    else:
        main()
