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


# ---- issue 18, "Show": from the plant FMU alone, noise on, every default --------------------------------------
# The command line in subprocesses, as a user runs it: `fmu-fdi model` with default options (the experiment it
# designs itself, the noise model it learns), `design` without --threshold (the default sized by that noise model,
# fmu_fdi/evaluation/defaults.py), `build --target native`, and `simulate` of the FMUs as shipped, fault-free and
# with a bias on each sensor. Figures (wall time per step, thresholds, delays) are printed (pytest -s).

def _cli(*args, timeout=600):
    """``fmu-fdi ARGS`` in a subprocess; (stdout, wall seconds); a failure shows its stderr."""
    import subprocess
    import sys
    import time

    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "fmu_fdi", *map(str, args)], capture_output=True, text=True,
                       timeout=timeout)
    wall = time.perf_counter() - t0
    assert r.returncode == 0, (args, r.stdout, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    return r.stdout + r.stderr, wall


def _read_csv(path):
    import csv

    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return {name: np.array([float(r[j]) for r in rows[1:]]) for j, name in enumerate(rows[0])}


def _from_fmu_alone(tmp_path, plant, inputs, outputs, *, inputs_csv, stop, t_fault, biases, evaluation="rms:20",
                    experiment=(), start=None):
    """model → design (defaults) → build native → simulate fault-free and each bias; returns the figures and
    asserts: no alarm in the fault-free run nor before any fault; every bias detected and isolated as its
    sensor (the most frequent named verdict after onset). ``start(model)``: the plant's start values
    (``--param``) from the identified model, so the plant starts at the diagnoser's operating point."""
    import re

    figures = {}
    model = tmp_path / "model.toml"
    out, figures["model_s"] = _cli("model", plant, "--inputs", *inputs, "--outputs", *outputs,
                                   "--sensor-faults", "all", *experiment, "-o", model)
    m = FDIModel.from_file(model)
    assert m.nw == len(outputs), "the identified model carries its noise model by default"
    # units of the plant FMU's variables carried into the model file (independent: the FMU's modelDescription)
    from fmpy import read_model_description

    md = {v.name: v for v in read_model_description(str(plant)).modelVariables}
    assert m.units == {n: md[n].unit for n in list(inputs) + list(outputs) if md[n].unit}
    ts = m.provenance["sample_time"]  # design at the identification's sample time: the noise model's
    design = tmp_path / "design.json"
    out, figures["design_s"] = _cli("design", model, "--method", "dos", "--ts", ts, "--evaluation", evaluation,
                                    "--persistence", "3/5", "-o", design)
    figures["thresholds"] = [float(x) for x in re.findall(r"default threshold ([0-9.eE+-]+) from the model's noise",
                                                          out)]
    assert len(figures["thresholds"]) == len(outputs), out
    assert "lies within the noise" not in out, out
    fdi = tmp_path / "fdi.fmu"
    _, figures["build_s"] = _cli("build", design, "--target", "native", "-o", fdi)
    faults = m.fault_names
    starts = [f"--param=plant.{k}={v!r}" for k, v in (start(m) if start else {}).items()]
    runs = [(None, 0.0)] + list(biases.items())
    figures["simulate_s"], figures["detect_s"], figures["isolate_s"], figures["false_alarms"] = [], {}, {}, 0
    for k, (y, size) in enumerate(runs):
        res = tmp_path / f"run{k}.csv"
        extra = ["--fault", f"abrupt:plant.{y}:{t_fault}::{size}"] if y else []
        _, wall = _cli("simulate", "--plant", f"plant={plant}", "--diagnoser", f"fdi={fdi}", "--stop", stop,
                       "--step", ts, "--input", inputs_csv, "--order", "jacobi", "--param", f"plant.seed={100 + k}",
                       *[a for n in outputs for a in ("--connect", f"plant.{n}=fdi.{n}")], *starts, *extra, "-o", res)
        figures["simulate_s"].append(wall)
        r = _read_csv(res)
        t, alarm, iso = r["time"], r["fdi.fault_detected"] > 0.5, r["fdi.isolated_fault"].astype(int)
        before = t < t_fault - 1e-9 if y else np.ones(t.size, bool)
        figures["false_alarms"] += int(alarm[before].sum())
        assert not alarm[before].any(), f"{y or 'fault-free'}: false alarm at t = {t[before][alarm[before]][:3]}"
        if y is None:
            continue
        after = ~before
        assert alarm[after].any(), f"bias {size} on {y} not detected"
        want = faults.index(f"sensor_{y}") + 1
        named = iso[after][iso[after] > 0]
        assert named.size and np.bincount(named).argmax() == want, (y, np.unique(iso[after], return_counts=True))
        figures["detect_s"][y] = float(t[after][alarm[after]][0] - t_fault)
        figures["isolate_s"][y] = float(t[after][iso[after] == want][0] - t_fault)
    print(f"\n{plant.name}: {figures}")
    return figures


@pytest.mark.slow
def test_dts200_from_plant_fmu_alone_noise_on_default_thresholds(tmp_path):
    """Show (issue 18): the worked example of docs/plant-fmu.md from the DTS200 FMU alone, sensor noise on, every
    option at its default: each level-sensor bias of the demo's size (fmu_fdi/demo.py SCENARIOS: ±1.5 cm at
    900 s, under the demo's pump schedule examples/dts200_pumps.csv) is detected and isolated, no false alarm."""
    from pathlib import Path

    import plant_fmus

    plant = plant_fmus.build("dts200", tmp_path)
    pumps = Path(__file__).resolve().parents[1] / "examples" / "dts200_pumps.csv"
    biases = {name.removeprefix("sensor_"): size for _, var, size, name in SCENARIOS[1:4]}
    assert sorted(biases) == ["h1", "h2", "h3"]
    _from_fmu_alone(tmp_path, plant, ["Q1", "Q2"], ["h1", "h2", "h3"], inputs_csv=pumps, stop=T_END,
                    t_fault=T_FAULT, biases=biases)


@pytest.mark.slow
def test_lateral_aircraft_from_plant_fmu_alone_noise_on_default_thresholds(tmp_path):
    """Show (issue 18): the same for the lateral aircraft FMU (process and sensor noise on) at its trim point
    with aileron and rudder doublets of ±0.1 (a tenth of the identification's amplitude, so the identified
    model's error stays below the noise: a larger manoeuvre needs a threshold that covers model error, e.g.
    data:RATE from a log of it). Bias 0.05 rad (rad/s) on each sensor from 15 s: like the demo's 1.5 cm
    against 0.1 cm of level noise, over ten times each output's noise std at trim (0.001-0.008)."""
    import plant_fmus

    plant = plant_fmus.build("lateral_aircraft", tmp_path)
    doublets = tmp_path / "doublets.csv"
    doublets.write_text("time,u1,u2\n0,0,0\n5,0.1,0\n6,-0.1,0\n7,0,0\n10,0,0.1\n11,0,-0.1\n12,0,0\n")
    # the aircraft at trim is neutrally stable in roll (phi integrates p): its operating point is where the
    # identification found it (phi -0.006 rad after the settle phase's noise), so the plant starts there, through
    # its start-value parameters <y>_start (C = I: the states are the outputs); started at 0 instead, the bank
    # sees a 0.006 rad step in phi at its first sample and alarms for the 20 samples of its RMS window
    def start(m):
        return {f"{y}_start": float(v) for y, v in zip(m.y_names, m.y0)}

    _from_fmu_alone(tmp_path, plant, ["u1", "u2"], ["beta", "phi", "p", "r"], inputs_csv=doublets, stop=30.0,
                    t_fault=15.0, biases={"beta": 0.05, "phi": 0.05, "p": 0.05, "r": -0.05}, start=start)


def test_docs_print_the_worked_example_these_tests_run():
    """docs/plant-fmu.md's worked example is the pipeline the slow tests above run (same options, no --threshold,
    native target, the diagnoser's step = the identification's ts of 4 s the DTS200 experiment chooses)."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "plant-fmu.md").read_text(encoding="utf-8")
    assert "fmu-fdi model PLANT.fmu --inputs Q1 Q2 --outputs h1 h2 h3 --sensor-faults all -o plant.toml" in text
    assert ("fmu-fdi design plant.toml --method dos --ts 4 --evaluation rms:20 --persistence 3/5 -o dos.json"
            in text)
    assert "fmu-fdi build dos.json --target native -o dos.fmu" in text
    sim = text[text.index("fmu-fdi simulate --plant plant=PLANT.fmu"):]
    sim = sim[:sim.index("```")]
    for option in ("--diagnoser fdi=dos.fmu", "--stop 1500", "--step 4", "--input pumps.csv", "--order jacobi",
                   "--fault abrupt:plant.h2:900::1.5"):
        assert option in sim, option
