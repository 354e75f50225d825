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


def _demo_table(stdout: str) -> list[str]:
    lines = stdout.splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("scenario"))
    return [ln for ln in lines[start:] if ln.strip()][:7]


@pytest.mark.slow
def test_demo_detects_and_isolates(tmp_path):
    """The main job, with both diagnostic FMU targets: no false alarm fault-free; every sensor
    bias detected and isolated as itself; the leak detected (a sensor bank cannot name it);
    table and PNG written. The native FMU runs the same per-sample semantics (docs/semantics.md,
    agreement to 1e-12), so its table must be the pythonfmu one, line for line."""
    tables = {}
    for target in ("pythonfmu", "native"):
        res = cli("demo", "--out", tmp_path / target, "--target", target)
        assert res.returncode == 0, res.stderr[-3000:]
        lines = {ln.split("  ")[0]: ln for ln in res.stdout.splitlines()}
        assert lines["no fault"].split()[2] == "no"
        for h in ("h1", "h2", "h3"):
            row = next(ln for key, ln in lines.items() if key.startswith(f"sensor {h}"))
            assert " yes " in row and f"sensor_{h}" in row
        leak = next(ln for key, ln in lines.items() if key.startswith("leak"))
        assert " yes " in leak
        if "unknown" in leak:  # the table says why a sensor bank cannot name the leak
            assert "'unknown' is the correct verdict" in res.stdout
        assert (tmp_path / target / "dts200_sensor_h2.png").exists()
        tables[target] = _demo_table(res.stdout)
    assert tables["native"] == tables["pythonfmu"]


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


# --- what a new user trips over (issue 11) and hostile arguments (issue 12, item 4) ----------------
# In-process through main(): the same code path as the console script, without a Python start-up.

def run_main(capsys, *args):
    """(exit status, stdout, stderr) of ``fmu-fdi ARGS``; argparse errors exit 2 as well."""
    from fmu_fdi.cli import main

    try:
        code = main([str(a) for a in args])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code, err, *fragments):
    assert code == 2, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert "error:" in last, err
    for f in fragments:
        assert f in last, (f, last)


@pytest.fixture(scope="module")
def tank_files(tmp_path_factory):
    """The README's three-tank design and diagnostic FMU (built once), plus a plant FMU."""
    from fmu_fdi import Diagnoser, FDIModel, build_fmu, dedicated_bank
    from plant_builds import python_plant

    tmp = tmp_path_factory.mktemp("tanks")
    model = FDIModel.from_file(PLANT_MODEL)
    dg = Diagnoser(dedicated_bank(model, "sensor", noise="ignore"), Ts=1.0,
                   evaluation={"kind": "rms", "window": 20}, thresholds=0.4, decision={"persistence": [3, 5]})
    return {"design": dg.save(tmp / "dos.json"), "fmu": build_fmu(dg, tmp / "dos.fmu"),
            "plant": python_plant("dts200"), "dg": dg}


def test_version(capsys):
    from fmu_fdi import __version__

    code, out, _ = run_main(capsys, "--version")
    assert code == 0 and out.strip() == f"fmu-fdi {__version__}"


def test_misspelled_method_suggests_the_close_match(capsys, tmp_path):
    code, _, err = run_main(capsys, "design", PLANT_MODEL, "--method", "nulspace", "--ts", "1", "-o", tmp_path / "d.json")
    assert_one_line_error(code, err, "unknown method 'nulspace'", "did you mean 'nullspace'?")
    assert not (tmp_path / "d.json").exists()


@pytest.mark.parametrize("ts", ["0", "-1", "nan", "inf", "abc"])
def test_design_refuses_a_sample_time_that_is_no_positive_finite_number(capsys, tmp_path, ts):
    code, _, err = run_main(capsys, "design", PLANT_MODEL, "--method", "dos", "--ts", ts, "-o", tmp_path / "d.json")
    assert_one_line_error(code, err, "--ts")
    assert "positive finite time" in err or "is not a number" in err


@pytest.mark.parametrize("value", ["abc", "3", "0/5", "6/5", "1.5/3"])
def test_design_refuses_a_malformed_persistence(capsys, tmp_path, value):
    code, _, err = run_main(capsys, "design", PLANT_MODEL, "--method", "dos", "--ts", "1", "--persistence", value,
                            "-o", tmp_path / "d.json")
    assert_one_line_error(code, err, "--persistence", "must read K/N")


def test_design_output_is_checked_before_the_design_runs(capsys, tmp_path):
    code, _, err = run_main(capsys, "design", PLANT_MODEL, "--method", "dos", "--ts", "1", "-o", tmp_path / "e.txt")
    assert_one_line_error(code, err, "must end in .json")
    blocker = tmp_path / "file"
    blocker.write_text("")
    code, _, err = run_main(capsys, "design", PLANT_MODEL, "--method", "dos", "--ts", "1", "-o", blocker / "d.json")
    assert_one_line_error(code, err, "is a file, not a folder")
    code, _, err = run_main(capsys, "design", PLANT_MODEL, "--method", "dos", "--ts", "1",
                            "-o", tmp_path / "new" / "d.json")  # a missing folder is created
    assert code == 0, err and (tmp_path / "new" / "d.json").exists()


def test_binary_files_and_fmus_where_text_belongs_give_one_line_errors(capsys, tmp_path, tank_files):
    fmu = tank_files["fmu"]
    for cmd in (["analyze", fmu], ["design", fmu, "--method", "dos", "--ts", "1", "-o", tmp_path / "d.json"]):
        code, _, err = run_main(capsys, *cmd)
        assert_one_line_error(code, err, "is a diagnostic FMU", "not a model file", "design.json")
    code, _, err = run_main(capsys, "build", fmu, "-o", tmp_path / "x.fmu")
    assert_one_line_error(code, err, "is a diagnostic FMU", "not a design file", "design.json")
    code, _, err = run_main(capsys, "analyze", tank_files["plant"])  # a plant FMU: model it first
    assert_one_line_error(code, err, "is an FMU (a zip archive), not a model file", "fmu-fdi model")
    utf16 = tmp_path / "m.toml"
    utf16.write_text('format = "fmu-fdi-model/1"\n', encoding="utf-16")
    code, _, err = run_main(capsys, "analyze", utf16)
    assert_one_line_error(code, err, "UTF-16")
    blob = tmp_path / "blob.csv"
    blob.write_bytes(bytes(range(256)) * 4)
    code, _, err = run_main(capsys, "diagnose", blob, "--design", tank_files["design"], "-o", tmp_path / "o.csv")
    assert_one_line_error(code, err, "binary file")
    code, _, err = run_main(capsys, "simulate", "--plant", tank_files["plant"], "--stop", "2", "--step", "1",
                            "--input", blob, "-o", tmp_path / "o.csv")
    assert_one_line_error(code, err, "binary file")
    assert not (tmp_path / "o.csv").exists()


def test_plot_on_missing_files(capsys, tmp_path, tank_files):
    code, _, err = run_main(capsys, "plot", tmp_path / "nothere.csv", "-o", tmp_path / "p.png")
    assert_one_line_error(code, err, "result CSV", "nothere.csv", "does not exist")
    csv = tmp_path / "r.csv"
    csv.write_text("time,fault_detected,isolated_fault\n0,0,0\n")
    code, _, err = run_main(capsys, "plot", csv, "--design", tmp_path / "nothere.json", "-o", tmp_path / "p.png")
    assert_one_line_error(code, err, "design file", "nothere.json", "does not exist")
    assert not (tmp_path / "p.png").exists()


def test_build_refuses_a_folder_before_writing(capsys, tmp_path, tank_files):
    code, _, err = run_main(capsys, "build", tank_files["design"], "-o", tmp_path)
    assert_one_line_error(code, err, "is a folder; give a file name")
    assert list(tmp_path.iterdir()) == []


def test_simulate_checks_its_output_before_the_run_and_refuses_unfed_diagnoser_inputs(capsys, tmp_path, tank_files):
    blocker = tmp_path / "file"
    blocker.write_text("")
    sim = ["simulate", "--plant", tank_files["plant"], "--diagnoser", tank_files["fmu"], "--stop", "5", "--step", "1"]
    code, _, err = run_main(capsys, *sim, "-o", blocker / "run.csv")
    assert_one_line_error(code, err, "is a file, not a folder")
    # the plant's outputs feed h1..h3, but nothing feeds the diagnoser's Q1, Q2
    code, _, err = run_main(capsys, *sim, "-o", tmp_path / "run.csv")
    assert_one_line_error(code, err, "diagnoser inputs Q1, Q2 are neither connected nor fed", "--allow-unconnected")
    assert not (tmp_path / "run.csv").exists()


def test_simulate_records_plant_inputs_and_diagnose_reruns_the_log(capsys, tmp_path, tank_files):
    """The README's worked example, shortened: the pump flows from a CSV feed the plant and the
    diagnoser; the result records them, and `fmu-fdi diagnose` on that result (prefixed columns)
    and on a plain log gives the diagnosis of Diagnoser.run on the same samples."""
    import numpy as np

    from fmu_fdi.cosim import Result

    pumps = EXAMPLES / "dts200_pumps.csv"
    run = tmp_path / "run.csv"
    code, out, err = run_main(capsys, "simulate", "--plant", tank_files["plant"], "--diagnoser", tank_files["fmu"],
                              "--stop", "300", "--step", "1", "--order", "jacobi", "--input", pumps,
                              "--fault", "abrupt:plant.f_sensor_h2:250:1.5", "-o", run)
    assert code == 0, err
    res = Result.from_csv(run)
    t = res["time"]
    q1 = np.where(t >= 200, 23.5099213338309, 21.37265575802809)  # examples/dts200_pumps.csv, zero-order hold
    np.testing.assert_array_equal(res["plant.Q1"], q1)
    np.testing.assert_array_equal(res["diagnoser.Q1"], q1)
    # the fault input the master set is recorded; the diagnoser read the plant's (biased) h2
    np.testing.assert_array_equal(res["plant.f_sensor_h2"], np.where(t >= 250, 1.5, 0.0))
    np.testing.assert_array_equal(res["diagnoser.h2"], res["plant.h2"])

    diag = tmp_path / "diag.csv"
    code, out, err = run_main(capsys, "diagnose", run, "--design", tank_files["design"], "-o", diag)
    assert code == 0, err
    assert "Q1 <- diagnoser.Q1" in out and "h2 <- diagnoser.h2" in out
    dg = tank_files["dg"]
    y = np.column_stack([res[f"diagnoser.{n}"] for n in ("h1", "h2", "h3")])
    u = np.column_stack([res["diagnoser.Q1"], res["diagnoser.Q2"]])
    ref = dg.run(t, u, y)
    got = Result.from_csv(diag)
    for name in ("evaluation_2", "isolated_fault", "fault_detected"):
        np.testing.assert_array_equal(got[name], ref[name].astype(float))
    assert got["isolated_fault"][-1] == 2  # sensor_h2
    # Jacobi: the FMU's row k+1 is Diagnoser.run's row k (docs: timing)
    np.testing.assert_allclose(res["diagnoser.evaluation_2"][1:], ref["evaluation_2"][:-1], rtol=1e-9, atol=1e-12)

    plain = tmp_path / "plain.csv"
    names = ["time", "Q1", "Q2", "h1", "h2", "h3"]
    np.savetxt(plain, np.column_stack([t, u, y]), delimiter=",", header=",".join(names), comments="")
    code, out, err = run_main(capsys, "diagnose", plain, "--design", tank_files["design"], "-o", tmp_path / "d2.csv")
    assert code == 0, err and "columns used: time, Q1, Q2, h1, h2, h3" in out
    np.testing.assert_array_equal(Result.from_csv(tmp_path / "d2.csv")["evaluation_2"], got["evaluation_2"])

    # plant.h2 and diagnoser.h2 both exist: without diagnoser outputs in the log, that is ambiguous
    both = tmp_path / "both.csv"
    cols = ["time", "plant.Q1", "plant.Q2", "plant.h1", "plant.h2", "plant.h3", "fdi.h1", "fdi.h2", "fdi.h3"]
    np.savetxt(both, np.column_stack([t, u, y, y]), delimiter=",", header=",".join(cols), comments="")
    code, _, err = run_main(capsys, "diagnose", both, "--design", tank_files["design"], "-o", tmp_path / "d3.csv")
    assert_one_line_error(code, err, "signal 'h1' is in several columns (plant.h1, fdi.h1)", "--prefix")
    code, out, err = run_main(capsys, "diagnose", both, "--design", tank_files["design"], "--prefix", "plant.",
                              "-o", tmp_path / "d3.csv")
    assert code == 0, err

    png = tmp_path / "run.png"
    code, out, err = run_main(capsys, "plot", run, "--design", tank_files["design"], "-o", png)
    assert code == 0, err and png.stat().st_size > 10_000


def test_help_states_every_default_and_has_no_sphinx_markup():
    import argparse
    import re

    from fmu_fdi.cli import build_parser

    def parsers(p):
        yield p
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    yield from parsers(sub)

    markup = re.compile(r"``|:(class|func|mod|meth|attr|data):`|::\s*$", re.M)
    for p in parsers(build_parser()):
        text = p.format_help()
        assert not markup.search(text), (p.prog, markup.search(text).group())
        for a in p._actions:
            if not a.option_strings or a.help in (None, argparse.SUPPRESS) or a.dest in ("help", "version"):
                continue
            if a.required:
                continue
            assert "default" in a.help, f"{p.prog} {a.option_strings[0]}: help does not state the default"
    design = next(p for p in parsers(build_parser()) if p.prog.endswith(" design")).format_help()
    from fmu_fdi.cli import METHODS

    for name, (fn, _, _) in METHODS.items():  # every method explained next to its API function
        assert re.search(rf"^  {name}\s+{fn}\(\)$", design, re.M), name


def test_loader_errors_reach_the_user_as_one_line(capsys, tmp_path):
    """A matrix row of the wrong length (the loader's message, whatever its wording) is one
    line on stderr with exit 2, and no design file is written."""
    bad = tmp_path / "ragged.toml"
    bad.write_text('format = "fmu-fdi-model/1"\n[signals]\nu = ["u"]\ny = ["y1"]\n[matrices]\n'
                   'A = [[1.0, 2.0], [3.0]]\nBu = [[1.0], [0.0]]\nC = [[1.0, 0.0]]\n')
    for cmd in (["analyze", bad], ["design", bad, "--method", "nullspace", "--ts", "1", "-o", tmp_path / "d.json"]):
        code, _, err = run_main(capsys, *cmd)
        assert_one_line_error(code, err, "matri")
        assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "d.json").exists()


def test_calibration_reads_a_log_with_instance_prefixed_columns(capsys, tmp_path):
    """`design --calibrate` takes a log as `fmu-fdi simulate` writes it (plant.Q1, plant.h1, ...)."""
    import numpy as np

    from fmu_fdi import FDIModel
    from simulate import plant_outputs

    model = FDIModel.from_file(PLANT_MODEL)
    N = 4000
    rng = np.random.default_rng(3)
    du = 0.5 * rng.standard_normal((N, model.nu))
    y = model.y0 + plant_outputs(model, N, 1.0, u=du, w=rng.standard_normal((N, model.nw)))
    cols = ["time"] + [f"plant.{n}" for n in model.u_names + model.y_names]
    log = tmp_path / "run.csv"
    np.savetxt(log, np.column_stack([np.arange(N), model.u0 + du, y]), delimiter=",", header=",".join(cols),
               comments="")
    code, out, err = run_main(capsys, "design", PLANT_MODEL, "--method", "dos", "--ts", "1", "--threshold",
                              "data:0.01", "--calibrate", log, "-o", tmp_path / "d.json")
    assert code == 0, err
    assert "h2 <- plant.h2" in out and "Q1 <- plant.Q1" in out


def test_an_unwritable_output_folder_is_refused_before_the_run(capsys, tmp_path, monkeypatch):
    """The write test the check makes (a temporary file in the folder) fails as it would for a
    user without write permission (root, which runs CI, may write anywhere)."""
    from fmu_fdi import outpath

    def refused(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(outpath.tempfile, "TemporaryFile", refused)
    code, _, err = run_main(capsys, "design", PLANT_MODEL, "--method", "dos", "--ts", "1", "-o", tmp_path / "d.json")
    assert_one_line_error(code, err, f"folder {tmp_path} is not writable (Permission denied)")


def test_design_valid_range_rejects_out_of_range_samples_like_nan(tmp_path):
    """--valid-range NAME:LO:HI reaches the design file; a sample outside (a glitch of 1e300) is
    then input_invalid in the runtime, one inside is not. Bad arguments are refused before the
    design work, and no file is written."""
    import numpy as np

    from fmu_fdi import Diagnoser

    out = tmp_path / "d.json"
    res = cli("design", PLANT_MODEL, "--method", "dos", "--ts", "1", "-o", out,
              "--valid-range", "h1:0:0.7", "--valid-range", "Q1::1e-4")
    assert res.returncode == 0, res.stderr
    dg = Diagnoser.load(out)
    assert dg.design["signals"]["valid_range"] == {"h1": [0.0, 0.7], "Q1": [None, 1e-4]}
    u0, y0 = np.zeros(len(dg.design["signals"]["u"])), np.zeros(len(dg.design["signals"]["y"]))
    assert not dg.step(u0, y0)["input_invalid"]
    y_bad = y0.copy()
    y_bad[dg.design["signals"]["y"].index("h1")] = 1e300
    assert dg.step(u0, y_bad)["input_invalid"]
    for arg, message in [("h9:0:1", "not an input or output"), ("h1:1:0", "lo <= hi"), ("h1:a:1", "NAME:LO:HI"),
                         ("h1:0", "NAME:LO:HI")]:
        bad = tmp_path / "bad.json"
        res = cli("design", PLANT_MODEL, "--method", "dos", "--ts", "1", "-o", bad, "--valid-range", arg)
        assert res.returncode == 2 and message in res.stderr and not bad.exists(), (arg, res.stderr)
