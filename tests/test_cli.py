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
    assert res.returncode == 2 and "columns ['y2'] are missing" in res.stderr
