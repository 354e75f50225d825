"""One validation for design dicts and strict model files (issue 12 items 3, 4; issue 11 loader messages).

Every design mutation below is refused identically by ``Diagnoser.load``, ``build_fmu``
and the run-time constructor (which the FMU runs on instantiation); every model-file
mistake is a one-line ``ModelError`` naming the key.
"""
import copy
import json
import math
import zipfile

import numpy as np
import pytest

import published as pub
from fmu_fdi import Diagnoser, FDIModel, ModelError, sensor_fault
from fmu_fdi.designfile import DesignFileError, load_design, validate_design
from fmu_fdi.fmu.builder import build_fmu
from fmu_fdi.runtime.design_check import MAX_SAMPLES, DesignCheckError
from fmu_fdi.runtime.engine import DiagnoserRuntime

TS = 0.1


@pytest.fixture(scope="module")
def design():
    """A small LTI design (three-tank plant, nullspace bank) as saved JSON data."""
    from fmu_fdi.design.problems.nullspace import nullspace_design

    m = pub.three_tank_like()
    m = FDIModel.from_matrices(m.A, m.Bu, m.C, u_names=m.u_names, y_names=m.y_names,
                               faults=[sensor_fault("s1", m.y_names[0]), sensor_fault("s2", m.y_names[1])])
    gen = nullspace_design(m)
    dg = Diagnoser(gen, Ts=TS, thresholds=1.0)
    return json.loads(json.dumps(dg.design))


def _ev(d, i=0):
    return d["evaluation"][i]


# (mutation, substring of the message) -- each switches detection off or breaks a host if accepted
BAD = {
    "changed generator.dt": (lambda d: d["generator"].update(dt=2 * TS), "generator.dt"),
    "null design name": (lambda d: d.update(name=None), "name must be a non-empty string"),
    "NaN residual name": (lambda d: d["generator"]["residual_names"].__setitem__(0, math.nan), "residual_names[0]"),
    "cusum delta NaN": (lambda d: _ev(d).update(evaluator={"kind": "cusum", "delta": math.nan}), "delta"),
    "cusum delta null": (lambda d: _ev(d).update(evaluator={"kind": "cusum", "delta": None}), "delta"),
    "cusum delta 0": (lambda d: _ev(d).update(evaluator={"kind": "cusum", "delta": 0}), "delta"),
    "cusum delta Inf": (lambda d: _ev(d).update(evaluator={"kind": "cusum", "delta": math.inf}), "delta"),
    "narendra alpha NaN": (lambda d: _ev(d).update(evaluator={"kind": "narendra", "alpha": math.nan}), "alpha"),
    "narendra all zero": (lambda d: _ev(d).update(evaluator={"kind": "narendra", "alpha": 0, "beta": 0}),
                          "alpha + beta > 0"),
    "chi2 sigma 0": (lambda d: _ev(d).update(evaluator={"kind": "chi2", "window": 5, "sigma": 0}), "sigma"),
    "chi2 sigma Inf": (lambda d: _ev(d).update(evaluator={"kind": "chi2", "window": 5, "sigma": math.inf}),
                       "sigma"),
    "chi2 W zero": (lambda d: _ev(d).update(evaluator={"kind": "chi2", "window": 5, "W": [[0.0]]}),
                    "nonsingular"),
    "chi2 W NaN": (lambda d: _ev(d).update(evaluator={"kind": "chi2", "window": 5, "W": [[math.nan]]}), "W"),
    "majorant taps NaN": (lambda d: _ev(d).update(threshold={"kind": "majorant", "taps": [math.nan]}), "taps"),
    "majorant taps empty": (lambda d: _ev(d).update(threshold={"kind": "majorant", "taps": []}), "taps"),
    "majorant tail null": (lambda d: _ev(d).update(threshold={"kind": "majorant", "taps": [1.0], "tail": None}),
                           "tail"),
    "majorant tail Inf": (lambda d: _ev(d).update(threshold={"kind": "majorant", "taps": [1.0],
                                                             "tail": math.inf}), "tail"),
    "fixed threshold Inf": (lambda d: _ev(d).update(threshold={"kind": "fixed", "value": math.inf}), "value"),
    "window 1e10": (lambda d: _ev(d).update(evaluator={"kind": "rms", "window": 10**10}), "[1, 100000]"),
    "window 100001": (lambda d: _ev(d).update(evaluator={"kind": "rms", "window": MAX_SAMPLES + 1}), "window"),
    "window 2.5": (lambda d: _ev(d).update(evaluator={"kind": "peak", "window": 2.5}), "integer"),
    "window string": (lambda d: _ev(d).update(evaluator={"kind": "rms", "window": "10"}), "integer"),
    "persistence 1e9": (lambda d: d["decision"].update(persistence=[1, 10**9]), "persistence n"),
    "persistence k > n": (lambda d: d["decision"].update(persistence=[3, 2]), "k <= n"),
    "adaptive window 1e9": (lambda d: _ev(d).update(threshold={"kind": "adaptive", "a": 1.0, "evaluation": {
        "kind": "rms", "window": 10**9}}), "evaluation.window"),
    "latch string": (lambda d: d["decision"].update(latch="yes"), "latch must be true or false"),
    "dt string": (lambda d: d["generator"].update(dt="0.1"), "generator.dt must be a number"),
    "dt Boolean": (lambda d: d["generator"].update(dt=True), "generator.dt must be a number"),
    "matrix entry string": (lambda d: d["generator"]["discrete"]["D"][0].__setitem__(0, "1e-3"), "must be a number"),
    "ragged matrix": (lambda d: d["generator"]["discrete"]["D"][-1].append(0.0), "row"),
    "huge integer": (lambda d: d["generator"]["discrete"]["D"][0].__setitem__(0, 10**400), "floating-point range"),
    "entry 1e300": (lambda d: d["generator"]["discrete"]["D"][0].__setitem__(0, 1e300), "larger in magnitude"),
    "groups overlap": (lambda d: d["generator"]["groups"].append([0]), "partition"),
    "evaluator typo": (lambda d: _ev(d).update(evaluator={"kind": "rms", "windwo": 5}), "unknown keys"),
    "signal names reserved": (lambda d: d["signals"]["y"].__setitem__(0, "alarm_1"), "collide"),
    "faults null": (lambda d: d.update(faults=None), "faults must be a list"),
    "structure not 0/1": (lambda d: d["decision"].update(isolation="structure",
                                                         structure=[[2, 0]] * len(d["generator"]["groups"])),
                          "only 0 and 1"),
    "valid_range reversed": (lambda d: d["signals"].update(valid_range={d["signals"]["y"][0]: [5, 1]}), "lo <= hi"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_every_entry_point_refuses_the_same_design(tmp_path, design, case):
    mutate, message = BAD[case]
    d = copy.deepcopy(design)
    mutate(d)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(d))  # NaN/Infinity as JSON extensions, as another tool might write
    with pytest.raises(DesignFileError, match=None) as load_err:
        Diagnoser.load(path)
    assert message in str(load_err.value) and "\n" not in str(load_err.value)
    with pytest.raises(DesignFileError) as build_err:
        build_fmu(path, tmp_path / "bad.fmu")
    assert str(build_err.value) == str(load_err.value)
    assert not (tmp_path / "bad.fmu").exists()
    # the run-time (what the FMU runs when instantiated) applies the same rule itself
    with pytest.raises(DesignCheckError, match=None) as rt_err:
        DiagnoserRuntime(json.loads(path.read_text()))
    assert message in str(rt_err.value)


@pytest.mark.parametrize("evaluator, threshold", [
    ({"kind": "rms", "window": MAX_SAMPLES}, {"kind": "fixed", "value": 1.0}),
    ({"kind": "cusum", "delta": 0.5, "sigma": 2.0}, {"kind": "fixed", "value": 10.0}),
    ({"kind": "narendra", "alpha": 0.0, "beta": 1.0, "gamma": 0.5}, {"kind": "majorant", "taps": [0.0, 1.0]}),
    ({"kind": "ewrms", "lambda": 0.9}, {"kind": "adaptive", "J0": 0.1, "a": 0.0}),
])
def test_valid_limits_are_accepted_and_run(design, evaluator, threshold):
    d = copy.deepcopy(design)
    d["evaluation"][0] = {"evaluator": evaluator, "threshold": threshold}
    d["decision"]["persistence"] = [MAX_SAMPLES, MAX_SAMPLES]
    validate_design(d)
    rt = DiagnoserRuntime(d)
    out = rt.step([0.0] * rt.nu, [0.0] * rt.ny)
    assert all(map(math.isfinite, out))


def test_the_fmu_bundles_the_same_validation(tmp_path, design):
    """The FMU's runtime package holds design_check.py byte for byte (one routine, not a copy)."""
    from fmu_fdi.runtime import design_check, schema

    fmu = build_fmu(design, tmp_path / "d.fmu")
    with zipfile.ZipFile(fmu) as z:
        bundled = {n.rsplit("/", 1)[-1]: z.read(n) for n in z.namelist() if n.startswith("resources/")}
    for mod in (design_check, schema):
        with open(mod.__file__, "rb") as fh:
            assert bundled[mod.__file__.rsplit("/", 1)[-1]] == fh.read()


# ------------------------------------------------------------------ model files
GOOD_TOML = """format = "fmu-fdi-model/1"
name = "m"
dt = 0.0
units = {y1 = "cm"}
[signals]
u = ["u1"]
y = ["y1", "y2"]
[matrices]
A = [[-1.0, 0.0], [0.0, -2.0]]
Bu = [[1.0], [1.0]]
C = [[1.0, 0.0], [0.0, 1.0]]
[[faults]]
name = "s1"
kind = "sensor"
output = "y1"
"""


def _model_error(tmp_path, text, suffix=".toml") -> str:
    path = tmp_path / f"m{suffix}"
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    with pytest.raises(ModelError) as err:
        FDIModel.from_file(path)
    msg = str(err.value)
    assert "\n" not in msg and str(path) in msg
    return msg


def test_good_model_file_loads(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(GOOD_TOML)
    m = FDIModel.from_file(path)
    assert m.fault_names == ["s1"] and m.units == {"y1": "cm"}


@pytest.mark.parametrize("old, new, message", [
    ('dt = 0.0', 'dt = "0.5"', "dt must be a number, got the string '0.5'"),
    ('dt = 0.0', 'dt = true', "dt must be a number, got a Boolean"),
    ('dt = 0.0', 'dt = nan', "dt must be a finite number"),
    ('Bu = [[1.0], [1.0]]', 'Bu = [["1e-3"], [1.0]]', "matrix Bu[1][1] must be a number, got the string '1e-3'"),
    ('Bu = [[1.0], [1.0]]', 'Bu = [[1e308], [1.0]]', "matrix Bu[1][1] = 1e+308 is larger in magnitude"),
    ('Bu = [[1.0], [1.0]]', 'Bu = [[' + "9" * 400 + '], [1.0]]', "beyond the floating-point range"),
    ('A = [[-1.0, 0.0], [0.0, -2.0]]', 'A = 5', "matrix A must be a list, got the number 5"),
    ('A = [[-1.0, 0.0], [0.0, -2.0]]', 'A = [[-1.0, 0.0], [0.0]]', "matrix A must have 2 columns: row 2 has 1 entries"),
    ('C = [[1.0, 0.0], [0.0, 1.0]]', 'C = [[1.0, 0.0]]', "matrix C must be 2x2, got 1 rows"),
    ('units = {y1 = "cm"}', 'units = "cm"', "units must be a table/object"),
    ('units = {y1 = "cm"}', 'units = {y1 = 5}', "units.y1 must be a string"),
    ('kind = "sensor"', 'kind = ["sensor"]', "fault 's1': kind must be a non-empty string"),
    ('y = ["y1", "y2"]', 'y = "y1"', "signals.y must be a list"),
    ('y = ["y1", "y2"]', 'y = ["y1", 2]', "signals.y[1] must be a non-empty string"),
    ('name = "m"', 'name = 7', "name must be a non-empty string"),
])
def test_model_values_are_typed_not_coerced(tmp_path, old, new, message):
    assert old in GOOD_TOML
    assert message in _model_error(tmp_path, GOOD_TOML.replace(old, new))


def test_model_file_wrong_fault_types(tmp_path):
    d = {"format": "fmu-fdi-model/1", "signals": {"y": ["y1"]}, "matrices": {"A": [[-1.0]], "C": [[1.0]]}}
    for faults, message in ((5, "faults must be a list, got the number 5"), (None, "faults must be a list, got null"),
                            ([5], "faults[0] must be a table/object")):
        assert message in _model_error(tmp_path, json.dumps({**d, "faults": faults}), ".json")


def test_unreadable_model_files_say_what_they_are(tmp_path):
    assert "UTF-16" in _model_error(tmp_path, GOOD_TOML.encode("utf-16"))
    flipped = bytes(b ^ 0xFF for b in GOOD_TOML.encode())
    assert "not UTF-8 text" in _model_error(tmp_path, flipped)
    assert "binary file" in _model_error(tmp_path, b"\x00\x01\x02" * 50)
    assert "nesting too deep" in _model_error(tmp_path, "[" * 100_000 + "]" * 100_000, ".json")
    assert "nesting too deep" in _model_error(tmp_path, "x = " + "[" * 100_000 + "]" * 100_000)
    assert "not valid JSON" in _model_error(tmp_path, '{"format": ', ".json")


def test_an_fmu_given_as_model_or_design_points_to_the_model_command(tmp_path):
    fmu = tmp_path / "plant.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", "<fmiModelDescription/>")
    with pytest.raises(ModelError) as err:
        FDIModel.from_file(fmu)
    msg = str(err.value)
    assert "is an FMU" in msg and f"fmu-fdi model {fmu} -o model.toml" in msg and "\n" not in msg
    with pytest.raises(DesignFileError, match="is an FMU .*fmu-fdi model"):
        load_design(fmu)
    with pytest.raises(DesignFileError, match="binary file, not a design file"):
        (tmp_path / "d.json").write_bytes(np.arange(256, dtype=np.uint8).tobytes())
        load_design(tmp_path / "d.json")


def test_cli_prints_one_line_for_a_binary_model(tmp_path):
    import subprocess
    import sys

    fmu = tmp_path / "plant.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", "<fmiModelDescription/>")
    res = subprocess.run([sys.executable, "-m", "fmu_fdi", "analyze", str(fmu)], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert res.stderr.count("\n") == 1 and f"fmu-fdi model {fmu} -o model.toml" in res.stderr


def test_a_tampered_fmu_refuses_its_design_as_shipped(tmp_path, design):
    """The FMU runs the same check when instantiated: an FMU whose bundled design.json was
    edited (window 1e10) fails to start in a host process and says which rule failed."""
    import subprocess
    import sys

    fmu = build_fmu(design, tmp_path / "d.fmu")
    bad = tmp_path / "tampered.fmu"
    with zipfile.ZipFile(fmu) as zi, zipfile.ZipFile(bad, "w", zipfile.ZIP_DEFLATED) as zo:
        for item in zi.infolist():
            data = zi.read(item.filename)
            if item.filename.endswith("/design.json"):
                d = json.loads(data)
                d["evaluation"][0]["evaluator"] = {"kind": "rms", "window": 10**10}
                data = json.dumps(d).encode()
            zo.writestr(item, data)
    res = subprocess.run([sys.executable, "-m", "fmu_fdi", "simulate", "--plant", str(bad), "--stop", "0.5",
                          "--step", str(TS), "--allow-unconnected", "-o", str(tmp_path / "out.csv")],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 1, res.stderr
    assert "failed to initialise" in res.stderr
    assert "evaluation[0].evaluator.window must be an integer in [1, 100000]" in res.stderr
    assert (tmp_path / "out.csv").read_text().splitlines()[-1].startswith("# incomplete")
