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
