"""Microseconds per step of the diagnostic FMU next to a trivial pythonfmu FMU (issue 4, §6).

The diagnostic FMU: a 10-state Luenberger residual generator on a 10-state plant with 2
inputs and 3 outputs (3 residuals), one windowed-RMS evaluation (10 samples) and a fixed
threshold per residual, no isolation. The trivial FMU: a plain ``pythonfmu.Fmi2Slave``
with the *same interface* (5 Real inputs; the same Real, Boolean and Integer outputs) whose
step copies inputs to outputs, so both move the same values through FMI each step and the
ratio isolates the cost of the diagnosis. Both run in an fmpy ``FMU2Slave`` loop in a fresh
``python -I`` process; one step is ``setReal + doStep + getReal + getBoolean + getInteger``.
``Diagnoser.step`` (the same runtime, no FMI) is timed in this process. All in one run;
medians over ``--repeat`` runs of ``--steps`` steps; target: diagnostic / trivial <= 1.5.

    python benchmarks/fmu_speed.py [--steps 5000] [--repeat 5]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TRIVIAL = '''
from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

INPUTS = __INPUTS__
REALS = __REALS__
BOOLS = __BOOLS__
INTS = __INTS__


class Trivial(Fmi2Slave):
    """Pass-through with the diagnostic FMU's interface."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name in INPUTS:
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in REALS:
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.output))
        for name in BOOLS:
            setattr(self, name, False)
            self.register_variable(Boolean(name, causality=Fmi2Causality.output, variability=Fmi2Variability.discrete))
        for name in INTS:
            setattr(self, name, 0)
            self.register_variable(Integer(name, causality=Fmi2Causality.output, variability=Fmi2Variability.discrete))

    def do_step(self, current_time, step_size):
        v = [getattr(self, n) for n in INPUTS]
        for k, name in enumerate(REALS):
            setattr(self, name, v[k % len(v)])
        for name in BOOLS:
            setattr(self, name, v[0] > 0.0)
        for name in INTS:
            setattr(self, name, int(v[0] > 0.0))
        return True
'''


def benchmark_diagnoser():
    """The benchmark design: 10-state Luenberger generator, 3 residuals each evaluated by rms:10."""
    import numpy as np

    from fmu_fdi import Diagnoser, FDIModel, luenberger, sensor_fault

    rng = np.random.default_rng(1)
    Qo, _ = np.linalg.qr(rng.standard_normal((10, 10)))
    A = Qo @ np.diag(rng.uniform(0.5, 0.95, 10)) @ Qo.T
    model = FDIModel.from_matrices(A, rng.standard_normal((10, 2)), rng.standard_normal((3, 10)), dt=0.01,
                                   faults=[sensor_fault(f"s{i}", f"y{i}") for i in range(3)], name="bench")
    gen = luenberger(model, poles=np.linspace(0.1, 0.5, 10))
    dg = Diagnoser(gen, evaluation={"kind": "rms", "window": 10}, thresholds=[1.0, 1.0, 1.0], groups="each",
                   decision={"isolation": "none"})
    assert gen.Q.n == 10 and gen.n_residuals == 3 and len(dg.design["generator"]["groups"]) == 3
    return dg


def worker(fmu_path: str, steps: int, repeat: int, clock: str = "perf_counter") -> None:
    """The benchmark host: fmpy only. ``clock``: a function of :mod:`time` (``process_time``:
    CPU time of this process, robust on a machine shared with other jobs)."""
    import numpy as np
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(fmu_path)
    by_type: dict[str, list[int]] = {"Real": [], "Boolean": [], "Integer": []}
    inputs = []
    for v in md.modelVariables:
        if v.causality == "input":
            inputs.append(v.valueReference)
        elif v.causality == "output":
            by_type[v.type].append(v.valueReference)
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu_path), modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="bench")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    h = float(md.defaultExperiment.stepSize) if md.defaultExperiment and md.defaultExperiment.stepSize else 0.01
    rng = np.random.default_rng(0)
    data = rng.standard_normal((steps, len(inputs))).tolist()
    times = []
    t = 0.0
    now = getattr(time, clock)
    for _ in range(repeat):
        t0 = now()
        for row in data:
            fmu.setReal(inputs, row)
            fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            fmu.getReal(by_type["Real"])
            fmu.getBoolean(by_type["Boolean"])
            fmu.getInteger(by_type["Integer"])
            t += h
        times.append((now() - t0) / steps * 1e6)
    fmu.terminate()
    fmu.freeInstance()
    print(json.dumps(times))


def _host(fmu: Path, steps: int, repeat: int, clock: str = "perf_counter") -> float:
    import numpy as np

    proc = subprocess.run([sys.executable, "-I", __file__, "--worker", str(fmu), str(steps), str(repeat), clock],
                          capture_output=True, text=True, check=True)
    return float(np.median(json.loads(proc.stdout.strip().splitlines()[-1])))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout too
    import numpy as np

    from fmu_fdi import build_fmu
    from fmu_fdi.fmu.packaging import build_slave_fmu

    dg = benchmark_diagnoser()
    model = dg.generator.model
    rng = np.random.default_rng(1)
    names = dg.output_names
    reals = [n for n in names if n.startswith(("residual_", "evaluation_", "threshold_"))]
    bools = [n for n in names if n.startswith("alarm_") or n in ("fault_detected", "input_invalid")]
    ints = ["isolated_fault"]
    inputs = list(model.u_names) + list(model.y_names)
    with tempfile.TemporaryDirectory() as tmp:
        fdi_fmu = build_fmu(dg, Path(tmp, "bench_fdi.fmu"))
        src = (TRIVIAL.replace("__INPUTS__", repr(inputs)).replace("__REALS__", repr(reals))
               .replace("__BOOLS__", repr(bools)).replace("__INTS__", repr(ints)))
        trivial_fmu = build_slave_fmu({"trivial.py": src}, "trivial:Trivial", Path(tmp, "trivial.fmu"),
                                      default_experiment={"startTime": 0.0, "stepSize": 0.01})
        t_trivial = _host(trivial_fmu, args.steps, args.repeat)
        t_fdi = _host(fdi_fmu, args.steps, args.repeat)
    data = rng.standard_normal((args.steps, 5))
    runs = []
    for _ in range(args.repeat):
        dg.reset()
        t0 = time.perf_counter()
        for row in data:
            dg.runtime.advance(row[:2], row[2:])
        runs.append((time.perf_counter() - t0) / args.steps * 1e6)
    t_py = float(np.median(runs))
    print(f"per step, median of {args.repeat} runs x {args.steps} steps (10-state generator, 3 residuals, rms:10)")
    print(f"  trivial pythonfmu FMU (same interface)  {t_trivial:8.1f} us   1.00")
    print(f"  diagnostic FMU                          {t_fdi:8.1f} us   {t_fdi / t_trivial:4.2f}  (target <= 1.5)")
    print(f"  Diagnoser.step runtime (no FMI)         {t_py:8.1f} us   {t_py / t_trivial:4.2f}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), *sys.argv[5:6])
    else:
        main()
