"""The command line as a user runs it: `python -m fmu_fdi` in a subprocess."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).parent.parent / "examples"


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "fmu_fdi", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


def test_analyze_prints_detectability_table():
    res = cli("analyze", EXAMPLES / "varga_ex5_4.toml")
    assert res.returncode == 0, res.stderr
    assert "fa" in res.stdout and "fs2" in res.stdout and "detectable" in res.stdout


@pytest.mark.parametrize("method, extra", [("nullspace", []), ("parity", []),
                                           ("nullspace", ["--evaluation", "narendra:0,10,0.9"])])
def test_design_writes_a_loadable_design_file(tmp_path, method, extra):
    out = tmp_path / "d.json"
    res = cli("design", EXAMPLES / "varga_ex5_4.toml", "--method", method, "--ts", "0.01", "-o", out, *extra)
    assert res.returncode == 0, res.stderr
    d = json.loads(out.read_text())
    assert d["format"] == "fmu-fdi-design/1" and d["generator"]["dt"] == 0.01
    from fmu_fdi import Diagnoser

    assert Diagnoser.load(out).output_names[0] == "residual_1"


def test_cli_errors_are_clear_and_exit_2(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('format = "fmu-fdi-model/1"\n[signals]\ny = ["y1"]\n[matrices]\nA = [[1.0, 2.0]]\nC = [[1.0]]\n')
    res = cli("analyze", bad)
    assert res.returncode == 2 and "matrix A must have 1 columns" in res.stderr
    res = cli("design", EXAMPLES / "varga_ex5_4.toml", "--method", "nullspace", "-o", tmp_path / "x.json")
    assert res.returncode == 2 and "--ts" in res.stderr
    res = cli("design", EXAMPLES / "varga_ex5_4.toml", "--method", "nullspace", "--ts", "0.01",
              "--threshold", "bogus", "-o", tmp_path / "x.json")
    assert res.returncode == 2 and "cannot read threshold" in res.stderr
    assert not (tmp_path / "x.json").exists()


def test_build_writes_a_valid_fmu_and_refuses_a_bad_design(tmp_path):
    design = tmp_path / "d.json"
    assert cli("design", EXAMPLES / "varga_ex5_4.toml", "--method", "nullspace", "--ts", "0.01",
               "-o", design).returncode == 0
    res = cli("build", design, "-o", tmp_path / "fdi.fmu")
    assert res.returncode == 0, res.stderr
    val = subprocess.run([sys.executable, "-m", "fmpy", "validate", str(tmp_path / "fdi.fmu")], capture_output=True,
                         text=True)
    assert "No problems found" in val.stdout
    d = json.loads(design.read_text())
    d["generator"]["dt"] = -1
    design.write_text(json.dumps(d))
    res = cli("build", design, "-o", tmp_path / "bad.fmu")
    assert res.returncode == 2 and "generator.dt must be a positive sample time" in res.stderr
    assert not (tmp_path / "bad.fmu").exists()


def test_design_with_statistical_thresholds(tmp_path):
    """analytic:ALPHA and data:RATE (calibrated on a fault-free CSV record) both give a fixed
    positive threshold; the calibration record must have the model's columns."""
    import numpy as np

    import published as pub
    from simulate import plant_outputs

    model = pub.a4_model()
    N = 2000
    rng = np.random.default_rng(0)
    u, w = rng.standard_normal((N, 1)), rng.standard_normal((N, 1))
    y = plant_outputs(model, N, 0.01, u=u, w=w)
    rec = tmp_path / "rec.csv"
    np.savetxt(rec, np.c_[np.arange(N) * 0.01, u, y], delimiter=",", header="time,u,y1,y2", comments="")
    for threshold, extra in (("analytic:0.001", []), ("data:0.001", ["--calibrate", rec])):
        out = tmp_path / "d.json"
        res = cli("design", EXAMPLES / "varga_a4_noise.toml", "--method", "nullspace", "--ts", "0.01",
                  "--threshold", threshold, *extra, "-o", out)
        assert res.returncode == 0, res.stderr
        thr = json.loads(out.read_text())["evaluation"][0]["threshold"]
        assert thr["kind"] == "fixed" and thr["value"] > 0
    bad = tmp_path / "bad.csv"
    bad.write_text("time,u,y1\n0,0,0\n")
    res = cli("design", EXAMPLES / "varga_a4_noise.toml", "--method", "nullspace", "--ts", "0.01",
              "--threshold", "data:0.01", "--calibrate", bad, "-o", tmp_path / "x.json")
    assert res.returncode == 2 and "no column for y2" in res.stderr


def test_plot_reads_fmpy_and_cosim_csvs(tmp_path):
    """`fmu-fdi plot` on a CSV as fmpy writes it (Booleans as True/False, no prefix)."""
    import numpy as np

    import published as pub
    from fmu_fdi import Diagnoser, nullspace_design
    from simulate import plant_outputs

    dg = Diagnoser(nullspace_design(pub.ex5_3(), poles=[-3]), Ts=0.01, thresholds=0.1)
    t = np.arange(200) * 0.01
    u = np.sin(t)[:, None]
    f = np.zeros((200, 2))
    f[100:, 1] = 1.0
    out = dg.run(t, u, plant_outputs(pub.ex5_3(), 200, 0.01, u=u, f=f))
    csv_path = tmp_path / "diag.csv"
    with open(csv_path, "w") as fh:
        fh.write(",".join(f'"{n}"' for n in out.dtype.names) + "\n")
        for row in out:
            fh.write(",".join(str(bool(v)) if isinstance(v, np.bool_) else repr(v.item()) for v in row) + "\n")
    design = dg.save(tmp_path / "d.json")
    res = cli("plot", csv_path, "--design", design, "-o", tmp_path / "p.png")
    assert res.returncode == 0, res.stderr
    assert "first alarm at t = 1.0" in res.stdout and "isolated as" in res.stdout
    assert (tmp_path / "p.png").stat().st_size > 10_000


@pytest.mark.slow
def test_demo_detects_and_isolates(tmp_path):
    """The main job: no false alarm fault-free; every sensor bias detected and isolated as
    itself; the leak detected (a sensor bank cannot name it); table and PNG written."""
    res = cli("demo", "--out", tmp_path / "demo")
    assert res.returncode == 0, res.stderr[-3000:]
    lines = {ln.split("  ")[0]: ln for ln in res.stdout.splitlines()}
    assert lines["no fault"].split()[2] == "no"
    for h in ("h1", "h2", "h3"):
        row = next(ln for key, ln in lines.items() if key.startswith(f"sensor {h}"))
        assert " yes " in row and f"sensor_{h}" in row
    leak = next(ln for key, ln in lines.items() if key.startswith("leak"))
    assert " yes " in leak
    assert (tmp_path / "demo" / "dts200_sensor_h2.png").exists()


PLANT_MODEL = Path(__file__).parent.parent / "plant_fmus" / "dts200" / "dts200.toml"


@pytest.mark.parametrize("method, extra", [
    ("nullspace", []), ("parity", []), ("luenberger", []), ("kalman", ["--Rv", "0.01", "0.01", "0.01"]),
    ("uio", []), ("factorized", []), ("dos", []), ("gos", []), ("rls", []),
    ("structured", ["--structure", "0,1,1;1,0,1;1,1,0", "--faults", "sensor_h1", "sensor_h2", "sensor_h3"]),
])
def test_design_every_method_on_a_plant_model_file(tmp_path, method, extra):
    out = tmp_path / "d.json"
    res = cli("design", PLANT_MODEL, "--method", method, "--ts", "1", "-o", out, *extra)
    assert res.returncode == 0, res.stderr
    from fmu_fdi import Diagnoser

    assert Diagnoser.load(out).design["generator"]["method"] in (method, "unknown_input_observer",
                                                                 "fault_detection_filter", "rls")


def test_fdf_on_the_tanks_names_the_faults_it_cannot_separate(tmp_path):
    """The Beard–Jones filter needs mutually detectable state faults: the two pumps are (one
    direction each in 3 outputs); adding all three leaks exceeds the three outputs."""
    res = cli("design", PLANT_MODEL, "--method", "fdf", "--faults", "pump_Q1", "pump_Q2", "--ts", "1",
              "-o", tmp_path / "ok.json")
    assert res.returncode == 0, res.stderr
    res = cli("design", PLANT_MODEL, "--method", "fdf", "--ts", "1", "-o", tmp_path / "bad.json")
    assert res.returncode == 2 and "acts on the measurements directly" in res.stderr
    res = cli("design", PLANT_MODEL, "--method", "fdf", "--faults", "pump_Q1", "pump_Q2", "leak_T1", "leak_T2",
              "--ts", "1", "-o", tmp_path / "bad.json")
    assert res.returncode == 2 and "not mutually detectable" in res.stderr
