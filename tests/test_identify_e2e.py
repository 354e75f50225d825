"""End to end from the DTS200 plant FMU alone: fmu-fdi model → design → build → co-simulation."""
from __future__ import annotations

import numpy as np
import pytest

from fmu_fdi import FDIModel
from fmu_fdi.cli import main
from fmu_fdi.demo import SCENARIOS, T_END, T_FAULT, TS, pump_schedule


def _runs(plant, diagnosers, model):
    """The demo's fault-free run and its three level-sensor biases, every diagnoser on the same plant."""
    from fmu_fdi.cosim import CoSimulation, Fault, InputSignals

    t = np.arange(0.0, T_END + TS / 2, TS)
    q = pump_schedule(model, t)
    sig = InputSignals(t, {n: q[:, j] for j, n in enumerate(model.u_names)})
    out = {}
    for k, (label, var, size, name) in enumerate(SCENARIOS[:4]):
        faults = [Fault.abrupt(f"plant.{var}", T_FAULT, size)] if var else []
        res = CoSimulation({"plant": plant, **diagnosers}, "auto", sig, step=TS, stop=T_END, order="jacobi",
                           faults=faults, parameters={"plant.seed": 100 + k}).run()
        out[name] = (t, res)
    return out


def _check(out, prefix, faults):
    t, res = out[None]
    assert not res[f"{prefix}.fault_detected"].any(), f"{prefix}: false alarm in the fault-free run"
    for name, (t, res) in out.items():
        if name is None:
            continue
        after = t >= T_FAULT
        assert not res[f"{prefix}.fault_detected"][~after].any(), (prefix, name)
        assert res[f"{prefix}.fault_detected"][after].any(), (prefix, name)
        iso = res[f"{prefix}.isolated_fault"][after]
        named = iso[iso > 0]
        assert named.size and np.bincount(named).argmax() == faults.index(name) + 1, (prefix, name, np.unique(iso))


@pytest.mark.slow
def test_dts200_from_plant_fmu_alone(tmp_path):
    import plant_fmus

    plant = plant_fmus.build("dts200", tmp_path)
    model, log = tmp_path / "dts200.toml", tmp_path / "log.csv"
    # the model: identified with the plant's measurement noise off (a simulation model lets you)
    assert main(["model", str(plant), "--inputs", "Q1", "Q2", "--outputs", "h1", "h2", "h3",
                 "--at", "noise_enable=false", "--sensor-faults", "all", "-o", str(model)]) == 0
    m = FDIModel.from_file(model)
    assert m.provenance["order"] == 3 and min(m.provenance["fit_percent"]) > 95
    # a dedicated observer bank designed on it; threshold: half the steady response to a 1.5 cm bias
    assert main(["design", str(model), "--method", "dos", "--ts", "1", "--evaluation", "rms:20",
                 "--threshold", "fault-size:1.5", "--persistence", "3/5", "-o", str(tmp_path / "dos.json")]) == 0
    assert main(["build", str(tmp_path / "dos.json"), "-o", str(tmp_path / "dos.fmu")]) == 0
    # no model in the filter: predictors identified from a fault-free, noisy log (the model file supplies
    # names, faults and operating point; same evaluation and threshold rule). 6000 samples: with 3000
    # the slow mode's gain (τ ≈ 520 s) is estimated too loosely against 0.1 cm of sensor noise
    assert main(["model", str(plant), "--inputs", "Q1", "Q2", "--outputs", "h1", "h2", "h3", "--signal", "prbs",
                 "--period", "20", "--amplitude", "Q1=3", "Q2=5", "--samples", "6000", "--record", str(log),
                 "-o", str(tmp_path / "noisy.toml")]) == 0
    assert main(["design", str(model), "--method", "data", "--calibrate", str(log), "--evaluation", "rms:20",
                 "--threshold", "fault-size:1.5", "--persistence", "3/5", "-o", str(tmp_path / "data.json")]) == 0
    assert main(["build", str(tmp_path / "data.json"), "-o", str(tmp_path / "data.fmu")]) == 0
    out = _runs(plant, {"dos": tmp_path / "dos.fmu", "data": tmp_path / "data.fmu"}, m)
    _check(out, "dos", m.fault_names)
    _check(out, "data", m.fault_names)
