"""Native C benchmark plants (plant_fmus.native_build; issue 20, item 4).

The pythonfmu plants are the reference. Both FMUs of a plant are run by tests/fmu_runner.py in
one subprocess (fmpy's FMU2Slave, as a co-simulation host loads them), noise off, with the same
inputs, parameters and step, and faults switched on mid-run; every output is compared.

Tolerance (1e-10, the issue's): the C code repeats the Python arithmetic in the same order
(np_support.c), so the adaptive DTS200 integrator takes the very same steps (``ode_steps`` is
compared exactly) and the states differ only where a library call or a matrix product sums in
another order: a few ulps of the largest term per step, |y| <= 1.6e2 (omega_g) ->
~1e-13 per step, damped by the stable (closed) loops; measured 2.3e-13 at most. The wind
turbine's 3e4 Nm torque output is an exact copy of a state fed by a matrix row with one
non-zero, so it too stays far inside 1e-10.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import plant_fmus
from plant_builds import native_plant, python_plant
from plant_fmus.native_build import build_native

HERE = Path(__file__).parent
RUNNER = HERE / "fmu_runner.py"
TOL = 1e-10
NOISE_OFF = {"noise_enable": False}


def switch(steps, k0, after, before=0.0):
    """A signal that is ``before`` until step k0, then ``after``."""
    return [float(before)] * k0 + [float(after)] * (steps - k0)


#: plant -> (steps, inputs): commands moved at the start, faults switched on mid-run
SCENARIOS = {
    "dts200": (150, {"Q1": switch(150, 20, 40.0, 21.37266), "f_leak_T1": switch(150, 40, 0.1),
                     "f_sensor_h2": switch(150, 60, 0.5), "f_clog_32": switch(150, 80, 0.3),
                     "gain_Q2": switch(150, 100, 0.8, 1.0), "stuck_h3": switch(150, 120, 1.0),
                     "stuck_value_h3": 10.0, "f_pump_Q1": switch(150, 130, -5.0)}),
    "dr300": (300, {"speed_ref": 10.0, "load_torque": switch(300, 100, 0.5),
                    "f_sensor_speed": switch(300, 150, 0.2), "f_actuator_voltage": switch(300, 200, 1.0),
                    "gain_speed": switch(300, 250, 0.9, 1.0)}),
    "vtol": (300, {"ref_collective": 0.5, "ref_cyclic": switch(300, 50, -0.2), "f_actuator_cyclic": switch(300, 100, 0.3),
                   "f_sensor_q": switch(300, 150, 0.02), "stuck_collective": switch(300, 200, 1.0),
                   "stuck_value_collective": 0.1}),
    "wind_turbine": (300, {"beta_ref_1": 2.0, "beta_ref_2": 1.5, "beta_ref_3": 1.0,
                           "f_pitch_2_pressure_drop": switch(300, 60, 0.7), "f_pitch_3_air_in_oil": switch(300, 120, 0.5),
                           "f_converter_offset": switch(300, 100, 100.0), "gain_omega_r_m2": switch(300, 150, 1.1, 1.0),
                           "f_drive_train_efficiency": switch(300, 200, -0.05),
                           "stuck_beta_1_m1": switch(300, 250, 1.0), "stuck_value_beta_1_m1": 5.0}),
    "lateral_aircraft": (300, {"u1": 0.1, "u2": -0.2, "f_loe_u1": switch(300, 100, 0.5), "gamma_2": switch(300, 50, 0.3),
                               "f_sensor_phi": switch(300, 150, 0.01), "gain_u2": switch(300, 200, 0.5, 1.0),
                               "stuck_r": switch(300, 250, 1.0), "stuck_value_r": 0.3}),
}


@pytest.fixture(scope="module")
def fmus():
    """{plant: (pythonfmu FMU, native FMU)}; the native one takes the reference's variables
    (built once per process, tests/plant_builds.py)."""
    return {name: (python_plant(name), native_plant(name)) for name in plant_fmus.PLANTS}


def outputs(fmu):
    from fmpy import read_model_description

    return [v.name for v in read_model_description(fmu).modelVariables if v.causality == "output"]


def run(jobs, tmp_path):
    """Run ``[(fmu, [run, ...]), ...]`` in one fresh process (tests/fmu_runner.py)."""
    jobs_file, result_file = tmp_path / "jobs.json", tmp_path / "results.json"
    jobs_file.write_text(json.dumps([{"fmu": str(f), "runs": runs} for f, runs in jobs]))
    env = {k: v for k, v in os.environ.items() if k != "FMU_FDI_TEST_HEAP_PAD"}
    proc = subprocess.run([sys.executable, str(RUNNER), str(jobs_file), str(result_file)],
                          capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(result_file.read_text())


#: plant -> non-default parameters of the conformance runs (the parameter plumbing is compared too)
PARAMETERS = {
    "dts200": {"h3_start": 30.0, "az2": 0.55},
    "dr300": {"T2": 0.04, "k_c": 1.5},
    "vtol": {"delta_a32": 0.1, "delta_a34": -0.05, "delta_b21": 0.1, "vh_start": 0.2, "theta_start": 0.05},
    "wind_turbine": {"omega_r_op": 1.5, "tau_g_op": 2.5e4, "beta_op": 1.0},
    "lateral_aircraft": {"beta_start": 0.01, "phi_start": 0.02},
}


def declared_starts(fmu):
    """Every Real parameter and input at its declared start value. The runs set them all, as a
    master does: pythonfmu writes start values with 16 significant digits (pythonfmu/variables.py,
    ``f"{value:.16g}"``), so a pythonfmu plant left alone starts from its internal value, which can
    differ from the declared one by an ulp (DTS200: Q2 = 53.797551106127884, declared
    53.79755110612788); the native plant starts from the declared value (docs/native-plants.md)."""
    from fmpy import read_model_description

    return {v.name: float(v.start) for v in read_model_description(str(fmu)).modelVariables
            if v.type == "Real" and v.causality in ("parameter", "input") and v.start is not None}


def scenario_run(name, params=NOISE_OFF, fmu=None):
    steps, inputs = SCENARIOS[name]
    return {"dt": plant_fmus.PLANTS[name].step, "steps": steps,
            "params": {**declared_starts(fmu), **PARAMETERS[name], **params}, "inputs": inputs,
            "outputs": outputs(fmu)}


def arrays(res):
    assert res["status"] == "ok", (res.get("message"), res.get("log"))
    return {n: np.array(v, dtype=float) for n, v in res["outputs"].items()}


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_native_plant_passes_fmpy_validate_with_the_reference_variables(fmus, name):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    ref, native = fmus[name]
    assert validate_fmu(str(native)) == []
    mr, mn = read_model_description(ref), read_model_description(native)

    def table(md):
        return [(v.name, v.valueReference, v.type, v.causality, v.variability, v.start, v.unit, v.description)
                for v in md.modelVariables]

    assert table(mn) == table(mr)
    assert mn.guid != mr.guid and mn.coSimulation.modelIdentifier != mr.coSimulation.modelIdentifier
    assert not mn.coSimulation.needsExecutionTool
    with zipfile.ZipFile(native) as zf:
        members = zf.namelist()
    assert f"binaries/linux64/{mn.coSimulation.modelIdentifier}.so" in members
    assert {f"sources/{name}.c", "sources/np_support.c", "sources/fmi2_plant.c", "sources/np_vars.h"} <= set(members)
    assert not [m for m in members if m.endswith(".py")]  # no Python in the FMU


def test_native_plants_conform_to_the_python_plants_noise_free(fmus, tmp_path):
    jobs = []
    for name, (ref, native) in fmus.items():
        jobs += [(ref, [scenario_run(name, fmu=ref)]), (native, [scenario_run(name, fmu=native)])]
    results = run(jobs, tmp_path)
    worst = {}
    for i, name in enumerate(fmus):
        py, c = arrays(results[2 * i][0]), arrays(results[2 * i + 1][0])
        assert py.keys() == c.keys()
        np.testing.assert_array_equal(c["ode_steps"], py["ode_steps"])  # same integrator steps
        for out in py:
            err = float(np.max(np.abs(c[out] - py[out])))
            worst[f"{name}.{out}"] = err
            assert err <= TOL, f"{name}: output {out} differs by {err:.3g} > {TOL} from the Python plant"
        # the scenario moves the plant, and every fault switch changes it: the comparison is not vacuous
        moved = max(float(np.ptp(py[o])) for o in py if o not in ("ode_steps", "overflow", "empty"))
        assert moved > 1e-2, f"{name}: the scenario hardly moves the outputs ({moved:.3g})"
    print("max |native - python| per output:", {k: f"{v:.2g}" for k, v in worst.items()})


def test_native_dts200_conforms_at_its_limits_with_many_integrator_steps(fmus, tmp_path):
    """Tight tolerances (several accepted and rejected Dormand-Prince steps per communication step,
    the step proposal carried over), tank 1 overflowing (state clipped at h_max) and tank 2
    draining to empty (clipped at 0, through the regularised root below D_LAM): the native plant
    takes the very same integrator steps and agrees to 1e-10."""
    n = 200
    spec = {"dt": 1.0, "steps": n, "params": {**declared_starts(fmus["dts200"][0]), **NOISE_OFF, "rtol": 1e-10,
                                              "atol": 1e-12},
            "inputs": {"Q1": 100.0, "Q2": switch(n, 10, 0.0, 53.79755), "f_clog_32": switch(n, 10, 1.0),
                       "f_leak_T2": switch(n, 10, 0.3), "f_clog_13": switch(n, 5, 0.5)},
            "outputs": outputs(fmus["dts200"][0])}
    py, c = (arrays(r[0]) for r in run([(fmus["dts200"][0], [spec]), (fmus["dts200"][1], [spec])], tmp_path))
    assert py["overflow"].any() and py["empty"].any()  # the scenario reaches both limits
    assert py["ode_steps"][-1] > 1.5 * n  # more than one integrator step per communication step
    np.testing.assert_array_equal(c["ode_steps"], py["ode_steps"])
    for out in py:
        err = float(np.max(np.abs(c[out] - py[out])))
        assert err <= TOL, f"output {out} differs by {err:.3g} > {TOL} from the Python plant"


def test_native_noise_is_seeded_standard_normal_with_the_configured_std(fmus, tmp_path):
    """DTS200 at its equilibrium (the levels do not move): the measurement noise is what moves
    the outputs. Same seed -> the same run; another seed -> another run; mean 0 and std
    std_h within sampling bounds; a fixed number of draws per step, so changing one sensor's
    std leaves the other sensors' noise unchanged."""
    _, native = fmus["dts200"]
    n = 400
    base = {"dt": 1.0, "steps": n, "outputs": ["h1", "h2", "h3"]}
    runs = [dict(base, params={"seed": 7}), dict(base, params={"seed": 7}), dict(base, params={"seed": 8}),
            dict(base, params={"seed": 7, "std_h1": 0.5}), dict(base, params=NOISE_OFF),
            dict(base, params={"seed": 7, "std_w_Q1": 2.0})]
    r = [arrays(res) for res in run([(native, runs)], tmp_path)[0]]
    clean = r[4]
    for y in ("h1", "h2", "h3"):
        np.testing.assert_array_equal(r[0][y], r[1][y])
        assert not np.array_equal(r[0][y], r[2][y])
        z = (r[0][y] - clean[y]) / 0.1  # unit normal draws if the generator is right
        # mean of n draws: sd 1/sqrt(n) = 0.05 -> |mean| < 5 sd; sample std: sd ~ 1/sqrt(2n) = 0.035 -> 5 sd
        assert abs(z.mean()) < 5 / math.sqrt(n + 1), (y, z.mean())
        assert abs(z.std() - 1.0) < 5 / math.sqrt(2 * (n + 1)), (y, z.std())
    for y in ("h2", "h3"):
        np.testing.assert_array_equal(r[3][y], r[0][y])
    np.testing.assert_allclose((r[3]["h1"] - clean["h1"]) / 0.5, (r[0]["h1"] - clean["h1"]) / 0.1, atol=1e-9)
    # process noise on the pump flow moves the levels themselves (on top of the same sensor draws)
    assert np.max(np.abs(r[5]["h1"] - r[0]["h1"])) > 1e-3


def test_measurement_noise_has_the_configured_std_per_sensor_in_both_languages(fmus, tmp_path):
    """Open-loop plants (the measurement noise does not feed back), process noise off: the
    difference to the noise-free run, divided by the sensor's std parameter, is a standard normal
    sample for every sensor, in the Python and in the native plant alike (the two streams
    differ, docs/native-plants.md, their distribution does not). Checks the per-sensor mapping of
    the std parameters (wind turbine: 0.2 deg, 0.025 rad/s, 0.05 rad/s, 90 Nm)."""
    from fmpy import read_model_description

    n, jobs, stds = 300, [], {}
    for name in ("dts200", "wind_turbine", "lateral_aircraft"):
        var = {v.name: v for v in read_model_description(str(fmus[name][0])).modelVariables}
        quiet = {k: 0.0 for k in var if k.startswith("std_w_")}
        sensors = list(plant_fmus.PLANTS[name].sensors)
        stds[name] = {y: float(var[f"std_{y}"].start) for y in sensors}
        base = {"dt": plant_fmus.PLANTS[name].step, "steps": n, "outputs": sensors}
        runs = [dict(base, params={**quiet, "seed": 11}), dict(base, params={**quiet, "noise_enable": False})]
        jobs += [(fmus[name][0], runs), (fmus[name][1], runs)]
    results = run(jobs, tmp_path)
    for i, name in enumerate(stds):
        for lang, (noisy, clean) in (("python", results[2 * i]), ("native", results[2 * i + 1])):
            noisy, clean = arrays(noisy), arrays(clean)
            for y, sd in stds[name].items():
                z = (noisy[y][1:] - clean[y][1:]) / sd
                # n draws: |mean| < 5/sqrt(n), |std - 1| < 5/sqrt(2n) (5 standard errors; seeds fixed)
                assert abs(z.mean()) < 5 / math.sqrt(n), (lang, name, y, z.mean())
                assert abs(z.std() - 1.0) < 5 / math.sqrt(2 * n), (lang, name, y, z.std())


def test_native_errors_match_the_python_plant(fmus, tmp_path):
    """A non-finite input fails the step (fmi2Discard, reason logged) and every later one; an
    invalid parameter fails initialisation (fmi2Error) - in both languages."""
    bad_input = {"dt": 1.0, "steps": 10, "inputs": {"Q1": [1.0, 2.0, 3.0] + [float("nan")] * 7},
                 "outputs": ["h1"]}
    bad_param = {"dt": 1.0, "steps": 3, "params": {"std_h1": -1.0}, "outputs": ["h1"]}
    ref, native = fmus["dts200"]
    py, c = run([(ref, [bad_input, bad_param]), (native, [bad_input, bad_param])], tmp_path)
    for res in (py[0], c[0]):
        assert res["status"] == "error" and len(res["t"]) == 4, res
        assert any("input Q1 is nan" in m for _, _, m in res["log"]), res["log"]
    assert c[0]["code"] == 2  # fmi2Discard, as pythonfmu reports a failed step
    assert c[1]["status"] == "error" and c[1]["code"] == 3
    assert any("std_h1 must be >= 0" in m for _, _, m in c[1]["log"]), c[1]["log"]
    assert any("std_h1 must be >= 0" in m for _, _, m in py[1]["log"]), py[1]["log"]


def run_fmi3(fmu, run_spec):
    """One run of an FMI 3.0 native FMU in a fresh process (see test_native_glue_refuses_misuse)."""
    code = ("import json, sys; sys.path.insert(0, sys.argv[1]); import test_native_plants as t; "
            "r = t.run_fmi3_here(sys.argv[2], json.loads(sys.argv[3])); "
            "print(json.dumps({k: v.tolist() for k, v in r.items()}))")
    proc = subprocess.run([sys.executable, "-c", code, str(HERE), str(fmu), json.dumps(run_spec)], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return {n: np.array(v) for n, v in json.loads(proc.stdout.strip().splitlines()[-1]).items()}


def run_fmi3_here(fmu, run_spec):
    """One run of an FMI 3.0 native FMU in this process (no pythonfmu here), as fmu_runner.py
    runs an FMI 2.0 one: inputs of step k set before doStep k, outputs recorded after it."""
    from fmpy import extract, read_model_description
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(fmu))
    var = {v.name: v for v in md.modelVariables}
    unzip = extract(str(fmu))
    s = FMU3Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier)
    try:
        s.instantiate()
        s.enterInitializationMode(startTime=0.0)
        steps, dt = run_spec["steps"], run_spec["dt"]
        inputs = {k: v if isinstance(v, list) else [v] * steps for k, v in run_spec["inputs"].items()}

        def setv(name, value):
            v = var[name]
            {"Float64": s.setFloat64, "Int32": s.setInt32, "Boolean": s.setBoolean}[v.type]([v.valueReference], [value])

        for k, v in run_spec["params"].items():
            setv(k, v)
        for k, v in inputs.items():
            setv(k, v[0])
        s.exitInitializationMode()
        get = {"Float64": s.getFloat64, "Int32": s.getInt32, "Boolean": s.getBoolean}
        rows = {n: [] for n in run_spec["outputs"]}

        def record():
            for n in rows:
                rows[n].append(float(get[var[n].type]([var[n].valueReference])[0]))

        record()
        for k in range(steps):
            for name, v in inputs.items():
                setv(name, v[k])
            s.doStep(currentCommunicationPoint=k * dt, communicationStepSize=dt)
            record()
        assert s.getFloat64([var["time"].valueReference])[0] == pytest.approx(steps * dt, rel=1e-12)
        s.terminate()
        s.freeInstance()
    finally:
        shutil.rmtree(unzip, ignore_errors=True)
    return {n: np.array(v) for n, v in rows.items()}


SLOW_FMI3 = {"dr300", "vtol", "lateral_aircraft"}  # the same glue and linear step as wind_turbine's


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_FMI3 else n
                                  for n in SCENARIOS])
def test_fmi3_native_plant_validates_and_equals_its_fmi2_build(fmus, tmp_path, name):
    """The FMI 3.0 build runs the same C code: fmpy validates it, it has the FMI 2.0 build's
    variables (+ time), and its outputs are bit-identical to the FMI 2.0 build's over the
    conformance scenario (so it conforms to the Python plant as the FMI 2.0 build does)."""
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    ref, native = fmus[name]
    fmi3 = native_plant(name, 3)  # build_native(name, ..., reference=ref, fmi_version=3)
    assert validate_fmu(str(fmi3)) == []
    m2, m3 = read_model_description(native), read_model_description(fmi3)
    types = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
    assert [(v.name, v.valueReference, types[v.type], v.causality, v.variability, v.start)
            for v in m2.modelVariables] == [(v.name, v.valueReference, v.type, v.causality, v.variability, v.start)
                                             for v in m3.modelVariables if v.name != "time"]
    two = arrays(run([(native, [scenario_run(name, fmu=native)])], tmp_path)[0][0])
    three = run_fmi3(fmi3, scenario_run(name, fmu=native))
    for out in two:
        np.testing.assert_array_equal(three[out], two[out], err_msg=f"{name}.{out}")


def test_builder_refuses_cleanly(tmp_path, monkeypatch):
    from fmu_fdi.native.build import NativeBuildError

    with pytest.raises(KeyError, match="unknown plant 'nope'"):
        build_native("nope", tmp_path)
    monkeypatch.setenv("CC", "no-such-compiler-xyz")
    with pytest.raises(NativeBuildError, match="no-such-compiler-xyz"):
        build_native("dts200", tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_native_plant_in_a_plain_c_host_under_valgrind(fmus, tmp_path):
    """No Python in the process: tests/hosts/c_host.c (dlopen) drives the native DTS200 with a
    leak switched on mid-run; valgrind finds no memory error and no leak; the outputs equal a
    run of the same FMU in fmpy (same noise stream: same seed, same draws)."""
    from fmu_fdi.fmu import hosts

    valgrind = shutil.which("valgrind")
    if not valgrind or not shutil.which("gcc"):
        pytest.skip("valgrind or gcc not installed")
    exe = hosts.compile_c_host(HERE / "hosts" / "c_host.c", tmp_path / "c_host")
    n = 40
    data = np.zeros(n, dtype=[("time", float), ("Q1", float), ("f_leak_T1", float)])
    data["time"], data["Q1"] = np.arange(n) * 1.0, 30.0
    data["f_leak_T1"][20:] = 0.2
    csv = hosts.write_csv(tmp_path / "in.csv", data)
    unzip = tmp_path / "u"
    with zipfile.ZipFile(fmus["dts200"][1]) as zf:
        zf.extractall(unzip)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "LD_PRELOAD"))}
    cmd = [valgrind, "-q", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=all",
           str(exe), str(unzip), str(csv), str(tmp_path / "out.csv"), "1.0"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    out = hosts.read_csv(tmp_path / "out.csv")
    # the C host reads row k before doStep k; fmu_runner records after it: shift by one
    res = arrays(run([(fmus["dts200"][1], [{"dt": 1.0, "steps": n - 1, "outputs": ["h1", "h2", "h3"],
                                            "inputs": {"Q1": 30.0, "f_leak_T1": data["f_leak_T1"][:n - 1].tolist()}}])],
                     tmp_path)[0][0])
    for y in ("h1", "h2", "h3"):
        np.testing.assert_array_equal(out[y], res[y])


_MISUSE = r"""
import shutil, sys
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave


def refused(call):
    try:
        call()
    except FMICallException:
        return True
    return False


native = sys.argv[1]
md = read_model_description(native)
vr = {v.name: v.valueReference for v in md.modelVariables}
unzip = extract(native)
try:
    bad = FMU2Slave(guid="{wrong}", unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier)
    try:
        bad.instantiate()
    except Exception:
        pass
    else:
        raise AssertionError("a wrong GUID was instantiated")
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier)
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setReal([vr["area"]], [100.0])  # a fixed parameter, before initialisation ends: fine
    s.exitInitializationMode()
    calls = {"an output": lambda: s.setReal([vr["h1"]], [1.0]),
             "a fixed parameter, too late": lambda: s.setReal([vr["area"]], [154.0]),
             "an Integer, set as Real": lambda: s.setReal([vr["seed"]], [1.0]),
             "no such value reference": lambda: s.getReal([len(md.modelVariables)]),
             "all or nothing": lambda: s.setReal([vr["Q1"], vr["h1"]], [5.0, 1.0])}
    for what, call in calls.items():
        assert refused(call), what
    assert s.getReal([vr["area"], vr["Q1"]]) == [100.0, float(md.modelVariables[vr["Q1"]].start)]
    s.doStep(currentCommunicationPoint=0.0, communicationStepSize=1.0)
    assert refused(lambda: s.doStep(currentCommunicationPoint=1.0, communicationStepSize=0.0)), "zero step"
    s.terminate()
    s.freeInstance()
finally:
    shutil.rmtree(unzip, ignore_errors=True)
print("ok")
"""


def test_native_glue_refuses_misuse(fmus):
    """FMI calls out of the rules return fmi2Error and change nothing. Run in a fresh process, as
    every FMU test here: a process that has loaded and dropped other FMUs may be handed one of
    their still-loaded libraries by the dynamic loader (same inode of a deleted file reused)."""
    proc = subprocess.run([sys.executable, "-c", _MISUSE, str(fmus["dts200"][1])], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("ok"), proc.stdout[-2000:] + proc.stderr[-2000:]


def test_plants_cli_refuses_an_unknown_plant_in_one_line(tmp_path):
    bad = subprocess.run([sys.executable, "-m", "plant_fmus", "build", "--native", "nope", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert bad.stderr.strip().splitlines() == ["error: unknown plant 'nope'; plants are "
                                               "['dr300', 'dts200', 'lateral_aircraft', 'vtol', 'wind_turbine']"]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_plants_cli_builds_native_fmi2_and_fmi3(tmp_path):
    for fmi, stem in ((2, "lateral_aircraft_native"), (3, "lateral_aircraft_native_fmi3")):
        ok = subprocess.run([sys.executable, "-m", "plant_fmus", "build", "--native", "--fmi", str(fmi),
                             "lateral_aircraft", "--out", str(tmp_path)], capture_output=True, text=True, timeout=300)
        assert ok.returncode == 0, ok.stderr
        assert ok.stdout.strip() == str(tmp_path / f"{stem}.fmu")


def test_fmi3_native_plant_in_a_plain_c_host_under_valgrind(fmus, tmp_path):
    """FMI 3.0 without Python in the process: tests/hosts/plant_fmi3_host.c drives the native
    wind turbine (FMI 3.0) with the converter offset switched on mid-run; valgrind finds no memory
    error and no leak; a wrong token and an unknown value reference are refused; the outputs are
    bit-identical to the FMI 2.0 build's in fmpy."""
    import fmpy
    from fmpy import read_model_description

    valgrind, cc = shutil.which("valgrind"), shutil.which("gcc") or shutil.which("cc")
    if not valgrind or not cc:
        pytest.skip("valgrind or a C compiler not installed")
    exe = tmp_path / "plant_fmi3_host"
    subprocess.run([cc, "-std=c99", "-O1", "-g", "-Wall", "-Wextra", "-Werror", "-pedantic",
                    f"-I{Path(fmpy.__file__).parent / 'c-code'}", str(HERE / "hosts" / "plant_fmi3_host.c"),
                    "-o", str(exe), "-ldl"], check=True, capture_output=True, timeout=120)
    ref, native = fmus["wind_turbine"]
    fmi3 = native_plant("wind_turbine", 3)  # the FMI 3.0 build test_fmi3_native_plant_validates... checks
    md = read_model_description(str(fmi3))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    outs = ["omega_r_m1", "omega_g_m1", "tau_g_m", "beta_1_m1"]
    n, k0 = 60, 20
    unzip = tmp_path / "u3"
    with zipfile.ZipFile(fmi3) as zf:
        zf.extractall(unzip)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "LD_PRELOAD"))}
    cmd = [valgrind, "-q", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=all", str(exe),
           str(unzip), md.coSimulation.modelIdentifier, md.guid, str(n), "0.01", str(vr["f_converter_offset"]),
           str(k0), "100.0", ",".join(str(vr[o]) for o in outs)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    log = [ln for ln in proc.stdout.splitlines() if ln.startswith("LOG")]
    assert any("instantiationToken does not match" in ln for ln in log), log
    assert any("no variable with value reference 100000" in ln for ln in log), log
    rows = np.array([[float(x) for x in ln.split()[1:]] for ln in proc.stdout.splitlines() if not ln.startswith("LOG")])
    two = arrays(run([(native, [{"dt": 0.01, "steps": n, "outputs": outs,
                                 "inputs": {"f_converter_offset": switch(n, k0, 100.0)}}])], tmp_path)[0][0])
    for j, o in enumerate(outs):
        np.testing.assert_array_equal(rows[:, j], two[o][1:], err_msg=o)
    assert np.ptp(two["tau_g_m"]) > 50  # the offset (100 Nm) shows: the run is not trivial
