"""FMI 3 array inputs and outputs as vectors of signals ``name[i]`` (fmu_fdi/cosim/elements.py), on a C99
FMI 3 FMU (model exchange and co-simulation, tests/array_io_fmus.py) whose input ``u`` and output ``y`` are
arrays sized by a structural parameter: the instance, the linearisation, the model file, and the whole
command line ``model`` → ``design`` → ``build`` → ``simulate`` with a fault on one element."""
from __future__ import annotations

import json
import subprocess
import sys
import tomllib

import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi import FDIModel
from fmu_fdi.cli import main
from fmu_fdi.cosim.errors import CoSimulationError
from fmu_fdi.cosim.instance import FMUInstance
from fmu_fdi.identify import IdentificationError, linearise

import array_io_fmus as P
from cosim_fmus import fmi3_headers

pytestmark = pytest.mark.skipif(fmi3_headers() is None, reason="fmpy's FMI 3 headers are needed to build the FMU")


@pytest.fixture(scope="module")
def plant(tmp_path_factory):
    return P.build_array_io_fmu(tmp_path_factory.mktemp("arrays"))


def test_instance_reads_and_writes_array_elements(plant):
    fmu = FMUInstance("plant", plant)
    assert fmu.names("input") == ["u[1]", "u[2]"] and fmu.names("output") == ["y[1]", "y[2]"]
    assert fmu.kind("y[2]") == "real" and fmu.kind("y") is None and fmu.start_value("u[2]") == P.U_START[1]
    fmu.start(0.0, 1.0, {"u[2]": 0.7})  # one element set before initialisation: u[1] keeps its start
    try:
        y, u = fmu.accessor(["y[1]", "y[2]"]), fmu.accessor(["u[1]", "u[2]"])
        u0 = np.array([P.U_START[0], 0.7])
        assert u.read() == u0.tolist()
        # y = C x + D u at the start state (the C code's arithmetic: a few ulps)
        assert np.allclose(y.read(), P.C @ P.X_START + P.D @ u0, rtol=0, atol=1e-15)
        fmu.accessor(["u[1]"]).write([2.0])  # the array is set whole: u[2] keeps 0.7
        assert u.read() == [2.0, 0.7]
        h = 0.05
        fmu.do_step(0.0, h)
        # independent: the exact step of x' = A x + B u with u held, [x; u] propagated by expm of the
        # augmented matrix; the FMU's 50 RK4 sub-steps err by ≈ (h/50)^5 |A|^5 / 120 per sub-step < 1e-16
        M = sla.expm(np.block([[P.A, P.B], [np.zeros((2, 4))]]) * h)
        x1 = M[:2, :2] @ P.X_START + M[:2, 2:] @ np.array([2.0, 0.7])
        assert np.allclose(y.read(), P.C @ x1 + P.D @ np.array([2.0, 0.7]), rtol=0, atol=1e-13)
    finally:
        fmu.close()


def test_array_signals_are_linearised_per_element(plant):
    lin = linearise(plant)
    assert lin.input_names == ["u[1]", "u[2]"] and lin.output_names == ["y[1]", "y[2]"]
    assert lin.state_names == ["x[1]", "x[2]"]
    # central differences on a linear plant: truncation is zero, rounding eps/h ≈ 2e-16/6e-6 ≈ 4e-11 per unit
    # of the values (|x|, |u| ≤ 1.25): 1e-9 is twenty times that
    for got, want in ((lin.A, P.A), (lin.B, P.B), (lin.C, P.C), (lin.D, P.D)):
        assert np.allclose(got, want, rtol=0, atol=1e-9), (got, want)
    assert np.allclose(lin.x0, P.X_START, atol=1e-12) and np.allclose(lin.v0, P.U_START)
    # one element a model input, the other held at a value of --at: the trim sees both
    lin = linearise(plant, inputs=["u[1]"], at={"u[2]": 1.5})
    assert lin.input_names == ["u[1]"] and np.allclose(lin.B, P.B[:, :1], atol=1e-9)
    assert np.allclose(lin.x0, np.linalg.solve(P.A, -P.B @ np.array([1.0, 1.5])), atol=1e-9)


def test_model_file_keeps_element_names(plant, tmp_path):
    for ext in ("toml", "json"):
        path = tmp_path / f"m.{ext}"
        assert main(["model", str(plant), "--sensor-faults", "all", "-o", str(path)]) == 0
        m = FDIModel.from_file(path)
        assert m.u_names == ["u[1]", "u[2]"] and m.y_names == ["y[1]", "y[2]"]
        # fault names are identifiers made of the element names; they act on the element
        assert [(f.name, f.output) for f in m.faults] == [("sensor_y_1", "y[1]"), ("sensor_y_2", "y[2]")]
        assert m.units == {"u[1]": "N", "u[2]": "N", "y[1]": "m", "y[2]": "m"}
    # the TOML is TOML (an independent parser): element names are quoted keys
    with open(tmp_path / "m.toml", "rb") as fh:
        d = tomllib.load(fh)
    assert d["signals"]["y"] == ["y[1]", "y[2]"] and d["units"]["y[2]"] == "m"
    assert d["declared_types"] == {"u[1]": "Force", "u[2]": "Force", "y[1]": "Position", "y[2]": "Position"}


def test_variable_dimension_is_refused_in_one_line(tmp_path, capsys):
    fmu = P.build_array_io_fmu(tmp_path, tunable_dimension=True)
    with pytest.raises(IdentificationError, match="structural parameter 'n' is tunable"):
        linearise(fmu, outputs=["y[1]"])
    assert main(["model", str(fmu), "-o", str(tmp_path / "m.toml")]) != 0
    err = capsys.readouterr().err
    assert "'n' is tunable" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    with pytest.raises(CoSimulationError, match="'y\\[2\\]' cannot be a signal: .*variable dimension"):
        FMUInstance("plant", fmu).variable("y[2]")


def _cli(*args):
    r = subprocess.run([sys.executable, "-m", "fmu_fdi", *map(str, args)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0 and "Traceback" not in r.stderr, (args, r.stdout, r.stderr)
    return r.stdout


def _read(path):
    import csv

    with open(path, newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    return {name: np.array([float(r[j]) for r in rows[1:]]) for j, name in enumerate(rows[0])}


@pytest.mark.slow  # about 15 s: 2 builds, 4 co-simulations and a 3-run campaign in subprocesses
def test_model_design_build_simulate_a_fault_on_one_element(plant, tmp_path):
    """The command line in subprocesses: the model of the array plant, a dedicated observer bank, the native
    FMU (FMI 2 and 3), co-simulated with the plant: plant y[2] feeds diagnoser y[2] by
    name; no alarm fault-free, and a bias on one element detected and isolated as that element's fault."""
    model, design = tmp_path / "m.toml", tmp_path / "d.json"
    _cli("model", plant, "--sensor-faults", "all", "-o", model)
    # threshold: fault-size 1 → half the steady response to a unit bias (no noise in this plant)
    _cli("design", model, "--method", "dos", "--ts", 0.05, "--evaluation", "rms:20", "--persistence", "3/5",
         "-o", design)
    t = np.arange(0.0, 10.0 + 1e-9, 0.05)
    inputs = tmp_path / "in.csv"
    inputs.write_text("time,u[1],u[2]\n" + "".join(f"{a:.17g},{1 + 0.3 * np.sin(0.7 * a):.17g},{0.5 + 0.2 * np.sin(1.3 * a):.17g}\n"
                                                   for a in t))
    fmus = {}
    # (the pythonfmu target with element names: test_declared_types_reach_the_diagnostic_fmu builds and validates it)
    for label, extra in (("native2", ("--target", "native")), ("native3", ("--target", "native", "--fmi", "3"))):
        fmus[label] = tmp_path / f"{label}.fmu"
        _cli("build", design, *extra, "-o", fmus[label])
    faults = FDIModel.from_file(model).fault_names
    runs = {"native2": (None, "y[2]", "y[1]"), "native3": ("y[2]",)}
    for label, fdi in fmus.items():
        for k, y in enumerate(runs[label]):
            res = tmp_path / f"{label}_{k}.csv"
            extra = ["--fault", f"abrupt:plant.{y}:5::1"] if y else []
            _cli("simulate", "--plant", f"plant={plant}", "--diagnoser", f"fdi={fdi}", "--stop", 10, "--step", 0.05,
                 "--input", inputs, "--order", "jacobi", *extra, "-o", res)
            r = _read(res)
            # the diagnoser read the plant's elements (connected by name), not its start values
            assert np.array_equal(r["fdi.y[2]"][1:], r["plant.y[2]"][:-1] + (r["time"][:-1] >= 5) * (y == "y[2]")) \
                or np.array_equal(r["fdi.y[2]"], r["plant.y[2]"] + (r["time"] >= 5) * (y == "y[2]")), label
            alarm, iso, before = r["fdi.fault_detected"] > 0.5, r["fdi.isolated_fault"].astype(int), r["time"] < 5
            assert not alarm[before].any(), (label, y, "false alarm")
            if y is None:
                assert not alarm.any(), label
                continue
            assert alarm[~before].any(), (label, y, "not detected")
            named = iso[~before][iso[~before] > 0]
            assert named.size and np.bincount(named).argmax() == faults.index(f"sensor_{y[0]}_{y[2]}") + 1, \
                (label, y, np.unique(iso[~before], return_counts=True))

    # the same through a campaign: pooled instances (each run restarts them: the arrays' stored values
    # go back to their start values), element targets and labels
    (tmp_path / "camp.toml").write_text(f"""format = "fmu-fdi-campaign/1"
name = "arrays"
[simulation]
step = 0.05
stop = 10.0
order = "jacobi"
[fmus]
plant = "{plant}"
fdi = "{fmus['native2']}"
[inputs]
file = "{inputs}"
[labels]
"plant.y[1]" = "sensor_y_1"
"plant.y[2]" = "sensor_y_2"
[sample]
method = "grid"
fault_free = 1
[sample.fault]
kind = ["abrupt"]
target = ["plant.y[1]", "plant.y[2]"]
magnitude = [1.0]
onset = [5.0]
""")
    _cli("campaign", tmp_path / "camp.toml", "-o", tmp_path / "camp", "--no-progress")
    lines = [json.loads(x) for x in (tmp_path / "camp" / "runs.jsonl").read_text().splitlines()[1:]]
    assert [x["status"] for x in lines] == ["ok"] * 3
    for x in lines:
        fdi, fault = x["diagnosers"]["fdi"], x["run"]["fault"]
        assert fdi["false_alarms"] == 0, x
        if fault is not None:
            assert fdi["detected"] and fdi["isolated_as"] == fault["label"], x



@pytest.mark.slow  # about 6 s: the experiment design's pre-test and three runs
def test_identification_drives_and_reads_array_elements(plant, tmp_path):
    """``fmu-fdi model --method identify`` (co-simulation experiments): the excitation is written to u[1], u[2]
    (whole-array sets) and y[1], y[2] are read; on this noise-free linear plant the identified static gain
    equals the plant's, −C A⁻¹ B + D (independent numpy), to 1e-6 of its size (a fit of 100 %: the
    identification's error is far below; the bound only guards against an element read or set wrongly, an
    error of the order of the gain itself)."""
    path = tmp_path / "mi.toml"
    assert main(["model", str(plant), "--method", "identify", "--inputs", "u[1]", "u[2]", "--outputs", "y[1]",
                 "y[2]", "-o", str(path)]) == 0
    m = FDIModel.from_file(path)
    assert m.u_names == ["u[1]", "u[2]"] and m.y_names == ["y[1]", "y[2]"]
    gain = -m.C @ np.linalg.solve(m.A, m.Bu) + m.Du
    want = -P.C @ np.linalg.solve(P.A, P.B) + P.D
    assert np.allclose(gain, want, rtol=0, atol=1e-6 * np.abs(want).max()), (gain, want)

# ---- declaredTypes: model file [declared_types] → the diagnostic FMU's TypeDefinitions, every target ---------
def test_declared_types_reach_the_diagnostic_fmu(tmp_path):
    """Read back with ElementTree (not our writer) and fmpy: each declaredType of the model's signals is a
    Real type in TypeDefinitions (FMI 2 SimpleType/Real, FMI 3 Float64Type) named on its variables; a type
    whose variables share a unit carries it, one whose variables differ (m, mm) carries none and the units
    stay on the variables; fmpy reads the description with validation and finds nothing to report."""
    import zipfile
    from xml.etree import ElementTree as ET

    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    from fmu_fdi.faults import sensor_fault
    from fmu_fdi.fmu.builder import build_fmu

    types = {"u[1]": "Force", "y[1]": "Position", "y[2]": "Position"}
    units = {"u[1]": "N", "y[1]": "m", "y[2]": "mm"}
    m = FDIModel(P.A, P.B[:, :1], P.C, P.D[:, :1], u_names=["u[1]"], y_names=["y[1]", "y[2]"], units=units,
                 declared_types=types, faults=[sensor_fault("sensor_y_1", "y[1]"), sensor_fault("sensor_y_2", "y[2]")])
    m.to_file(tmp_path / "m.toml")
    assert main(["design", str(tmp_path / "m.toml"), "--method", "dos", "--ts", "0.05", "-o",
                 str(tmp_path / "d.json")]) == 0
    for target, fmi in (("pythonfmu", 2), ("native", 2), ("native", 3)):
        fmu = build_fmu(tmp_path / "d.json", tmp_path / f"{target}{fmi}.fmu", target=target, fmi_version=fmi)
        with zipfile.ZipFile(fmu) as zf:
            root = ET.fromstring(zf.read("modelDescription.xml"))
        if fmi == 2:
            defs = {t.get("name"): t.find("Real").get("unit") for t in root.findall("TypeDefinitions/SimpleType")}
            declared = {sv.get("name"): sv.find("Real").get("declaredType")
                        for sv in root.findall("ModelVariables/ScalarVariable") if sv.find("Real") is not None}
            own_unit = {sv.get("name"): sv.find("Real").get("unit")
                        for sv in root.findall("ModelVariables/ScalarVariable") if sv.find("Real") is not None}
        else:
            defs = {t.get("name"): t.get("unit") for t in root.findall("TypeDefinitions/Float64Type")}
            declared = {v.get("name"): v.get("declaredType") for v in root.findall("ModelVariables/Float64")}
            own_unit = {v.get("name"): v.get("unit") for v in root.findall("ModelVariables/Float64")}
        assert defs == {"Force": "N", "Position": None}, (target, fmi, defs)
        assert {k: v for k, v in declared.items() if v} == types, (target, fmi)
        assert all(own_unit[k] == units[k] for k in units), (target, fmi)
        assert validate_fmu(str(fmu)) == [], (target, fmi)
        md = read_model_description(str(fmu), validate=True)
        assert {v.name: v.declaredType.name for v in md.modelVariables if v.declaredType} == types


@pytest.mark.parametrize("name, ident", [("y[2]", "y_2"), ("A[1,2]", "A_1_2"), ("plant.y[2]", "plant_y_2"),
                                         ("y", "y"), ("y_", "y_"), ("_y__", "_y__")])
def test_derived_names_keep_identifiers_as_they_are(name, ident):
    # fault names are made from signal names: 'y' and 'y_' are two signals and must give two faults
    # (an identifier's own trailing underscores were stripped, so both gave 'sensor_y')
    from fmu_fdi.faults import identifier_of

    assert identifier_of(name) == ident
