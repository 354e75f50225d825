"""What a new user hits (issue 21): silent wrong plots and reports, advice that points the wrong
way, and interruptions. The CLI runs in a subprocess, as a user runs it.

Set-up (built once): the README's three-tank sensor bank (design file and diagnostic FMU), the
DTS200 plant FMU, the pump flows at the operating point, a 60 s co-simulation log with a bias
of 2 cm on h2 from 30 s, and a design of another plant (the lateral aircraft).
"""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest


def cli(*args, timeout=300, cwd=None):
    """``fmu-fdi ARGS`` in a subprocess, as a user runs it."""
    return subprocess.run([sys.executable, "-m", "fmu_fdi", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)


def cli_here(*args):
    """``fmu-fdi ARGS`` in this process (the same ``main``; no start-up cost): for many calls."""
    import contextlib
    import io

    from fmu_fdi.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:
            code = exc.code
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def one_line_error(r, *fragments):
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "error:" in lines[0], r.stderr
    for f in fragments:
        assert f in lines[0], (f, lines[0])


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    import plant_fmus
    from plant_fmus.dts200 import dts200_physics as phys

    from fmu_fdi.campaign.example import build_fmus

    tmp = tmp_path_factory.mktemp("guidance")
    fmus = build_fmus(tmp)
    _, q = phys.operating_point()
    pumps = tmp / "pumps.csv"
    pumps.write_text(f"time,Q1,Q2\n0,{float(q[0])!r},{float(q[1])!r}\n")
    design = tmp / "dos.json"
    assert cli_here("design", plant_fmus.model_path("dts200"), "--method", "dos", "--ts", "1", "--evaluation",
                    "rms:20", "--persistence", "3/5", "-o", design).returncode == 0
    bank = tmp / "dos.fmu"
    assert cli_here("build", design, "-o", bank).returncode == 0
    log = tmp / "run.csv"
    r = cli_here("simulate", "--plant", fmus["plant"], "--diagnoser", bank, "--input", pumps, "--stop", "60",
                 "--step", "1", "--order", "jacobi", "--fault", "abrupt:plant.f_sensor_h2:30:2", "-o", log)
    assert r.returncode == 0, r.stderr
    other = tmp / "lateral.json"
    assert cli_here("design", plant_fmus.model_path("lateral_aircraft"), "--method", "nullspace", "--ts", "0.1",
                    "-o", other).returncode == 0
    return {"dir": tmp, "plant": fmus["plant"], "bank": bank, "design": design, "pumps": pumps, "log": log,
            "other": other, "model": plant_fmus.model_path("dts200")}


def test_plot_refuses_the_design_of_another_plant(files, tmp_path):
    cli = cli_here  # the same main, without a second of start-up per call
    r = cli("plot", files["log"], "--design", files["other"], "-o", tmp_path / "p.png")
    one_line_error(r, "is not the design of the diagnosis in", "h1")
    assert not (tmp_path / "p.png").exists()
    ok = cli("plot", files["log"], "--design", files["design"], "-o", tmp_path / "ok.png")
    assert ok.returncode == 0 and "isolated as: sensor_h2" in ok.stdout, ok.stderr


def test_plot_without_design_calls_a_fixed_threshold_fixed_from_row_one(files):
    """Row 0 holds no diagnosis (threshold 0): the label and the line start at row 1."""
    import matplotlib

    matplotlib.use("Agg")
    from fmu_fdi.recorded import read_result
    from fmu_fdi.report import diagnosis_figure

    res = read_result(files["log"])
    fig = diagnosis_figure(res, prefix="diagnoser.")
    for g in (1, 2, 3):
        th = np.asarray(res[f"diagnoser.threshold_{g}"], float)
        assert th[0] == 0 and np.ptp(th[1:]) == 0  # the precondition: a fixed threshold, 0 at row 0
        (ln,) = [ln for ln in fig.axes[g].get_lines() if "threshold" in str(ln.get_label())]
        assert "fixed" in ln.get_label() and "adaptive" not in ln.get_label(), ln.get_label()
        assert np.min(ln.get_ydata()) == th[1]  # never drawn rising from 0
        assert ln.get_xdata()[0] == res["time"][1]


def test_no_alarm_is_said_in_words(files, tmp_path):
    cli = cli_here  # the same main, without a second of start-up per call
    quiet = tmp_path / "quiet.csv"
    r = cli("simulate", "--plant", files["plant"], "--diagnoser", files["bank"], "--input", files["pumps"], "--stop",
            "20", "--step", "1", "--order", "jacobi", "-o", quiet)
    assert r.returncode == 0, r.stderr
    d = cli("diagnose", quiet, "--design", files["design"], "-o", tmp_path / "d.csv")
    assert d.returncode == 0 and "no alarm" in d.stdout and "t = -" not in d.stdout, d.stdout


def test_advice_for_files_taken_for_others(files, tmp_path):
    cli = cli_here  # the same main, without a second of start-up per call
    one_line_error(cli("diagnose", files["log"], "--design", files["bank"], "-o", tmp_path / "d.csv"),
                   "is a diagnostic FMU", "design.json")
    r = cli("build", files["model"], "-o", tmp_path / "x.fmu")
    one_line_error(r, "is a model file", "fmu-fdi design")
    r = cli("simulate", "--plant", files["bank"], "--diagnoser", files["plant"], "--input", files["pumps"], "--stop",
            "5", "--step", "1", "-o", tmp_path / "s.csv")
    one_line_error(r, "swapped")


def test_output_over_input_is_refused_and_the_input_kept(files, tmp_path):
    cli = cli_here  # the same main, without a second of start-up per call
    log = tmp_path / "log.csv"
    log.write_bytes(files["log"].read_bytes())
    one_line_error(cli("diagnose", log, "--design", files["design"], "-o", log), "is the input file")
    assert log.read_bytes() == files["log"].read_bytes()
    pumps = tmp_path / "p.csv"
    pumps.write_bytes(files["pumps"].read_bytes())
    one_line_error(cli("simulate", "--plant", files["plant"], "--input", pumps, "--stop", "5", "--step", "1",
                       "-o", pumps), "is the input file")
    assert pumps.read_bytes() == files["pumps"].read_bytes()


def test_values_are_never_silently_changed(files, tmp_path):
    """In this process (many calls); test_cli_fuzz covers the same cases among its tries."""
    cli = cli_here
    base = ["simulate", "--plant", files["plant"], "--diagnoser", files["bank"], "--input", files["pumps"],
            "--stop", "5", "--step", "1", "-o", tmp_path / "s.csv"]
    one_line_error(cli(*base, "--param", "plant.seed=4294967303"), "outside the range of Integer")
    for word in ("no", "off", "maybe", "1"):
        one_line_error(cli(*base, "--param", f"plant.noise_enable={word}"), "not a Boolean", "true or false")
    one_line_error(cli(*base[:-6], "--stop", "1e308", "--step", "1", "-o", tmp_path / "s.csv"), "steps is more than")
    one_line_error(cli(*base[:-6], "--stop", "10", "--step", "1e308", "-o", tmp_path / "s.csv"), "no step at all")
    m = ["model", files["plant"], "--method", "identify", "--inputs", "Q1", "Q2", "--outputs", "h1", "h2", "h3",
         "-o", tmp_path / "m.toml"]
    one_line_error(cli(*m, "--at", "uu=5"), "'uu' is not a variable")
    one_line_error(cli(*m, "--amplitude", "x=1"), "'x' is not an excited input")
    one_line_error(cli(*m, "--min-fit", "nan"), "--min-fit")
    for opt, value in (("--ts", "0"), ("--ts", "nan"), ("--ts", "inf"), ("--settle", "1e12"), ("--seed", "-1")):
        one_line_error(cli(*m, opt, value), opt)


def test_python_cosimulation_refuses_unconnected_diagnoser_inputs_like_the_cli(files):
    from fmu_fdi.cosim import CoSimulation, CoSimulationError

    with pytest.raises(CoSimulationError, match="neither connected nor fed") as info:
        CoSimulation({"plant": files["plant"], "diagnoser": files["bank"]}, step=1.0, stop=5.0)
    assert "Q1" in str(info.value) and "allow_unconnected" in str(info.value)
    sim = CoSimulation({"plant": files["plant"], "diagnoser": files["bank"]}, step=1.0, stop=2.0,
                       allow_unconnected=True)
    r = sim.run()
    assert any("diagnoser.Q1" in w and "start value" in w for w in r.warnings), r.warnings


@pytest.mark.slow
def test_ctrl_c_in_simulate_exits_130_with_one_line(files, tmp_path):
    out = tmp_path / "long.csv"
    proc = subprocess.Popen([sys.executable, "-m", "fmu_fdi", "simulate", "--plant", str(files["plant"]),
                             "--diagnoser", str(files["bank"]), "--input", str(files["pumps"]), "--stop", "1000000",
                             "--step", "1", "-o", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not (out.exists() and out.stat().st_size > 20000):
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert len(err.strip().splitlines()) == 1 and "interrupted" in err, err
    assert out.read_text().rstrip().splitlines()[-1].startswith("# incomplete")


def _guids(paths) -> set:
    import xml.etree.ElementTree as ET

    out = set()
    for p in paths:
        with zipfile.ZipFile(p) as z:
            root = ET.fromstring(z.read("modelDescription.xml"))
        out.add(root.get("guid") or root.get("instantiationToken"))
    return out


@pytest.mark.slow
def test_interrupted_campaign_report_says_partial_and_records_its_settings(files, tmp_path):
    from fmu_fdi.campaign.example import write_campaign

    spec = write_campaign(files["dir"], "partial", stop=200.0, fault_free=30, targets=("plant.f_sensor_h1",),
                          magnitudes=(1.5,), onset=100.0, rate=0.01, scales=(0.8, 1.6, 5), zone=20.0)
    out = tmp_path / "partial"
    proc = subprocess.Popen([sys.executable, "-m", "fmu_fdi", "campaign", str(spec), "-o", str(out), "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        f = out / "runs.jsonl"
        if f.exists() and len(f.read_text().splitlines()) >= 3:
            break
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    stdout, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    done = len((out / "runs.jsonl").read_text().splitlines()) - 1
    assert 2 <= done < 31
    assert f"{done} of 31 planned runs" in stdout
    html = (out / "report.html").read_text()
    assert "Partial campaign" in html and f"{done} of 31 planned runs" in html
    assert "Settings" in html and "stop 200 s" in html and "onsets (s)" in html and "1.5" in html
    for guid in _guids([files["dir"] / "dts200.fmu", files["dir"] / "dts200_sensor_dos.fmu"]):
        assert guid in html, guid
    assert (out / "runs.csv").read_text().count("\n") == done + 1


def test_sweep_plot_draws_zero_rates_at_zero_and_the_band_to_the_one_sided_bound(monkeypatch):
    """The rate curve is drawn at its values (0 at 0, no floor) and the band ends at the table's
    one-sided upper bound, row by row."""
    import matplotlib

    matplotlib.use("Agg")
    import importlib

    agg = importlib.import_module("fmu_fdi.campaign.aggregate")  # the package exports a function of that name
    report = importlib.import_module("fmu_fdi.campaign.report")

    N = 3000
    rows = []
    for s, k in ((0.5, 40), (1.0, 3), (2.0, 0), (4.0, 0)):
        rows.append({"scale": s, "samples": N, "fa_samples": k, "fa_onsets": k, "rate": k / N,
                     "upper": agg.clopper_pearson(k, N, 0.95, "upper")[1], "interval": agg.clopper_pearson(k, N),
                     "faulty_runs": 4, "detected": 4, "detection": 1.0})
    d = agg.DiagnoserFigures("bank", {}, [], [], {}, rows, {"scale": 1.0}, [])
    figs = agg.CampaignFigures("c", 1, [], 1.0, 0.95, 1e-3, {"bank": d})
    seen = {}
    monkeypatch.setattr(report, "_png", lambda fig: seen.setdefault("fig", fig) and "")
    report._sweep_plot(d, figs)
    ax = seen["fig"].axes[0]
    rate = next(ln for ln in ax.get_lines() if "rate per sample" in ln.get_label())
    assert list(rate.get_ydata()) == [r["rate"] for r in rows]  # zeros at 0, not at a floor
    band = ax.collections[0].get_paths()[0].vertices
    for r in rows:  # the band's top at each scale is the one-sided bound the table prints
        top = band[np.isclose(band[:, 0], r["scale"]), 1].max()
        assert np.isclose(top, r["upper"], rtol=1e-12), (r["scale"], top, r["upper"])
    assert ax.get_yscale() == "symlog" and ax.get_ylim()[0] == 0.0


def test_heartbeat_names_the_campaign_stage_and_count(files, tmp_path):
    import io

    from fmu_fdi.campaign import CampaignSpec, run_campaign
    from fmu_fdi.campaign.example import write_campaign
    from fmu_fdi.progress import Heartbeat

    spec = CampaignSpec.load(write_campaign(files["dir"], "beat", stop=120.0, fault_free=6,
                                            targets=("plant.f_sensor_h1",), magnitudes=(1.5,), onset=60.0, rate=0.01,
                                            scales=(0.8, 1.6, 5), zone=20.0))
    buf = io.StringIO()
    with Heartbeat(first=0.01, every=0.01, stream=buf):
        run_campaign(spec, tmp_path / "beat", progress=False)
    lines = buf.getvalue().splitlines()
    assert lines and any("campaign beat:" in ln and "of 7 runs done" in ln for ln in lines), lines[:5]
    assert not any(ln.endswith(": working") for ln in lines)


@pytest.mark.slow
def test_campaign_example_runs_as_the_readme_says(tmp_path):
    r = cli("campaign", "--example", "campaign", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    toml = tmp_path / "campaign" / "dts200.toml"
    assert toml.exists() and (tmp_path / "campaign" / "dts200.fmu").exists()
    r = cli("campaign", "campaign/dts200.toml", "-o", "results", "--dry-run", cwd=tmp_path)
    assert r.returncode == 0 and "8 runs" in r.stdout, r.stderr
    r = subprocess.run([sys.executable, "-m", "fmu_fdi.campaign.example", str(tmp_path / "again")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and (tmp_path / "again" / "dts200.toml").exists(), r.stderr


def test_a_warning_that_dates_itself_is_not_dated_twice(files):
    from fmu_fdi.cosim.instance import FMUInstance

    inst = FMUInstance("diagnoser", files["bank"])
    inst.now = 0.0
    inst._record(1, "t=0: step size changed from 1 s to 2 s")
    inst.now = 3.0
    inst._record(1, "threshold_scale must be a finite number >= 0")
    lines = inst.warning_summary()
    assert lines == ["FMU 'diagnoser': t=0: step size changed from 1 s to 2 s",
                     "FMU 'diagnoser' at t=3: threshold_scale must be a finite number >= 0"], lines
