"""Fault-injection campaigns (issue 10): the campaign file, the runner on every back end, the
aggregates' exact binomial intervals, the threshold sweep, the report, and fmu_fdi.testing.

The campaign: the DTS200 plant FMU with two diagnostic FMUs — a dedicated observer bank for the
level sensors (rms over 20 s, analytic thresholds, persistence 3 of 5;
fmu_fdi.campaign.example) and a Kalman filter whose innovation
norm has the analytic threshold of a 1e-2 false-alarm probability per sample (a white sequence
for the linear model: nearly independent samples, which is what the binomial intervals assume).
Runs are short (300 s at 1 s) so the whole module stays within its time budget.
"""
from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binom

from fmu_fdi.campaign import CampaignError, CampaignSpec, aggregate, clopper_pearson, run_campaign
from fmu_fdi.campaign.example import write_campaign
from fmu_fdi.cli import main
from fmu_fdi.testing import (DiagnosisAssertionError, assert_detected, assert_false_alarm_rate,
                             assert_no_false_alarm, run_scenario, samples_needed)

@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """The plant FMU, the sensor bank and a Kalman-filter diagnoser, built once."""
    from fmu_fdi import Diagnoser, FDIModel, analytic_threshold, build_fmu, kalman
    from fmu_fdi.campaign.example import build_fmus
    import plant_fmus

    out = tmp_path_factory.mktemp("campaign")
    build_fmus(out)
    m = FDIModel.from_file(plant_fmus.model_path("dts200")).discretize(1.0)
    gen = kalman(m, Qw=1.0, Rv=0.0)
    ev = {"kind": "norm"}
    th = analytic_threshold(gen, ev, 1e-2, noise_cov=np.eye(m.nw), group=0)
    build_fmu(Diagnoser(gen, evaluation=ev, thresholds=[th], name="dts200_kalman"), out / "kalman.fmu")
    return out


def write(folder, name, *, fault_free=2, seed_base=1, kalman=False, parameters=None,
          targets=("plant.f_sensor_h1", "plant.f_sensor_h2")) -> Path:
    """A 300 s campaign: faults of 0.4 and 1.5 cm from 150 s, scored from 60 s, target rate 1e-2."""
    return write_campaign(folder, name, stop=300.0, fault_free=fault_free, seed_base=seed_base, targets=targets,
                          magnitudes=(0.4, 1.5), onset=150.0, rate=0.01, scales=(0.8, 1.6, 41), zone=60.0,
                          extra_fmus={"kalman": "kalman.fmu"} if kalman else None, parameters=parameters)


def outcome(records) -> list:
    """What a run's record says about the diagnosis (not when or where it ran)."""
    return [(r["run"], r["status"], r.get("diagnosers")) for r in sorted(records, key=lambda r: r["run"]["index"])]


def lines(path) -> list:
    return [json.loads(x) for x in Path(path).read_text().splitlines()[1:] if x.strip()]


# ------------------------------------------------------------------------------- end to end
def test_cli_dry_run_run_kill_resume_and_report(folder, tmp_path, capsys):
    spec_path = write(folder, "e2e", fault_free=3)
    n = len(CampaignSpec.load(spec_path).runs())
    assert n == 3 + 2 * 2  # fault-free runs plus targets x magnitudes
    assert main(["campaign", str(spec_path), "-o", str(tmp_path / "dry"), "--dry-run"]) == 0
    listing = capsys.readouterr().out.splitlines()
    assert len(listing) == n + 1 and "fault-free" in listing[0] and "f_sensor_h2 1.5 from 150 s" in listing[-2]
    assert not (tmp_path / "dry" / "runs.jsonl").exists()

    ref = tmp_path / "ref"
    assert main(["campaign", str(spec_path), "-o", str(ref), "--no-progress", "--traces"]) == 0
    reference = lines(ref / "runs.jsonl")
    traces = sorted((ref / "traces").glob("run_*.csv"))
    assert len(traces) == n and "bank.fault_detected" in traces[-1].read_text().splitlines()[0]
    assert len(reference) == n and all(r["status"] == "ok" for r in reference)
    # the threshold sweep at factor 1 reproduces each FMU's own alarms (bank: persistence 3 of 5)
    assert all(d["sweep_exact"] for r in reference for d in r["diagnosers"].values())
    for name in ("report.html", "false_alarms.csv", "detection.csv", "delays.csv", "sweep.csv", "confusion_bank.csv"):
        assert (ref / name).stat().st_size > 0, name
    html = (ref / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 3 and "Clopper" in html
    # nothing is overwritten without --resume
    assert main(["campaign", str(spec_path), "-o", str(ref), "--no-progress"]) == 2

    # kill a campaign mid-way (SIGKILL: no chance to clean up), then resume it
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "fmu_fdi", "campaign", str(spec_path), "-o", str(out),
                             "--no-progress"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "runs.jsonl").exists() and len(lines(out / "runs.jsonl")) >= 2:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    kept = lines(out / "runs.jsonl")
    assert 2 <= len(kept) < n, f"the kill came too late to test a resume ({len(kept)} of {n} runs)"
    assert main(["campaign", str(spec_path), "-o", str(out), "--resume", "--no-progress"]) == 0
    assert "from before" in capsys.readouterr().out
    resumed = lines(out / "runs.jsonl")
    assert len(resumed) == n and len({r["run"]["key"] for r in resumed}) == n  # no run twice
    assert outcome(resumed) == outcome(reference)
    assert (out / "report.html").exists()

    # Ctrl-C: no new run starts, the finished ones stay, exit status 130; --resume completes it
    out = tmp_path / "interrupted"
    proc = subprocess.Popen([sys.executable, "-m", "fmu_fdi", "campaign", str(spec_path), "-o", str(out),
                             "--no-progress"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    while time.monotonic() < deadline + 120 and proc.poll() is None:
        if (out / "runs.jsonl").exists() and len(lines(out / "runs.jsonl")) >= 1:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    kept = lines(out / "runs.jsonl")
    assert proc.returncode == 130 and "--resume" in err and all(r["status"] == "ok" for r in kept), err
    assert main(["campaign", str(spec_path), "-o", str(out), "--resume", "--no-progress"]) == 0
    assert outcome(lines(out / "runs.jsonl")) == outcome(reference)


def test_process_pool_and_dask_give_the_serial_results(folder, tmp_path):
    spec = CampaignSpec.load(write(folder, "parallel", fault_free=2, kalman=True))
    serial = run_campaign(spec, tmp_path / "serial", progress=False)
    pool = run_campaign(spec, tmp_path / "pool", workers=2, progress=False)
    dask = run_campaign(spec, tmp_path / "dask", workers=2, scheduler="local", progress=False)
    assert not serial.failed and len(serial.records) == len(spec.runs())
    # every worker instantiates its FMUs once and resets them for each later run
    assert sum(not r["reused"] for r in serial.records) == 1
    assert sum(not r["reused"] for r in pool.records) <= 2
    assert outcome(pool.records) == outcome(serial.records)
    assert outcome(dask.records) == outcome(serial.records)


def test_faults_are_detected_and_isolated_and_aggregated(folder, tmp_path):
    res = run_campaign(write(folder, "agg", fault_free=2), tmp_path, progress=False)
    fig = aggregate(res).diagnosers["bank"]
    # a 1.5 cm bias (15 sigma) on a level sensor: every run detects it and the bank names it
    big = [r for r in fig.detection if r["magnitude"] == 1.5]
    assert len(big) == 2 and all(r["probability"] == 1.0 for r in big)
    c = fig.confusion
    for label in ("sensor_h1", "sensor_h2"):
        row = dict(zip(c["columns"], c["counts"][c["rows"].index(label)]))
        assert row.get(label, 0) >= 1, (label, row)
    assert fig.false_alarms["samples"] == 2 * 241 + 4 * 90  # t = 60..300 fault-free, 60..149 before the onsets


# ------------------------------------------------------------------------------ statistics
@pytest.mark.parametrize("k, n", [(0, 10), (1, 10), (5, 10), (10, 10), (0, 3000), (7, 12345), (1, 1)])
def test_clopper_pearson_is_exact(k, n):
    c = 0.95
    lo, hi = clopper_pearson(k, n, c)
    # the defining tail equations: P(X >= k | lo) = P(X <= k | hi) = (1 - c)/2, binomial X
    if k > 0:
        assert binom.sf(k - 1, n, lo) == pytest.approx(0.025, rel=1e-8)
    else:
        assert lo == 0.0
    if k < n:
        assert binom.cdf(k, n, hi) == pytest.approx(0.025, rel=1e-8)
    else:
        assert hi == 1.0
    if k == 0:  # closed form 1 - (alpha/2)^(1/n)
        assert hi == pytest.approx(1 - 0.025 ** (1 / n), rel=1e-12)
    up = clopper_pearson(k, n, c, "upper")[1]
    if k < n:
        assert binom.cdf(k, n, up) == pytest.approx(0.05, rel=1e-8)


def test_clopper_pearson_tabulated_value():
    # k = 1 of n = 10 at 95 %: [0.00252858, 0.44501612] (Clopper & Pearson's charts; any CP table)
    lo, hi = clopper_pearson(1, 10, 0.95)
    assert (round(lo, 8), round(hi, 8)) == (0.00252858, 0.44501612)
    with pytest.raises(ValueError, match="0 <= k <= n"):
        clopper_pearson(3, 2)


def test_threshold_sweep_choice_holds_on_fresh_seeds(folder, tmp_path):
    calib = run_campaign(write(folder, "calib", fault_free=30, seed_base=1000, kalman=True, targets=()),
                         tmp_path / "calib", progress=False)
    choice = aggregate(calib).diagnosers["kalman"].choice
    assert choice["scale"] is not None, choice["reason"]
    assert choice["upper"] <= 0.01 and choice["interval"][0] <= choice["rate"] <= choice["interval"][1]
    fresh = run_campaign(write(folder, "fresh", fault_free=30, seed_base=5000, kalman=True, targets=(),
                               parameters={"kalman.threshold_scale": choice["scale"]}),
                         tmp_path / "fresh", progress=False)
    fa = aggregate(fresh).diagnosers["kalman"].false_alarms
    lo, hi = choice["interval"]
    assert lo <= fa["rate"] <= hi, (fa, choice)
    assert all(r["diagnosers"]["kalman"]["sweep_exact"] for r in calib.records + fresh.records)


# ------------------------------------------------------------------------------ campaign file
def test_campaign_file_errors_name_the_key(folder, tmp_path):
    text = write(folder, "bad").read_text()
    for broken, message in ((text.replace('order = "jacobi"', 'order = "sideways"'), "order 'sideways'"),
                            (text.replace("confidence = 0.95", "confidence = 1.5"), "confidence"),
                            (text.replace("magnitude = [0.4, 1.5]", "magnitude = {min = 0.1, max = 1}"), "grid"),
                            (text.replace('format = "fmu-fdi-campaign/1"', 'format = "x/2"'), "format"),
                            (text.replace("onset = [150.0]", "onset = [10.0]"), "zone_start"),
                            (text + "\n[extra]\n", "unknown key"),
                            (text.replace('seeds = ["plant.seed"]', 'seeds = ["plant.sead"]'), "did you mean 'seed'"),
                            (text.replace('"plant.f_sensor_h2"', '"plant.f_sensor_h4"'), "f_sensor_h4")):
        p = tmp_path / "broken.toml"
        p.write_text(broken)
        (tmp_path / "dts200.fmu").write_bytes((folder / "dts200.fmu").read_bytes())
        (tmp_path / "dts200_sensor_dos.fmu").write_bytes((folder / "dts200_sensor_dos.fmu").read_bytes())
        with pytest.raises(CampaignError, match=message):
            CampaignSpec.load(p)


def test_random_sample_is_reproducible_with_distinct_seeds(folder):
    data = {"format": "fmu-fdi-campaign/1", "name": "rnd", "simulation": {"step": 1.0, "stop": 100.0},
            "fmus": {"plant": "dts200.fmu"},
            "sample": {"method": "random", "runs": 50, "seed": 3, "fault_free": 5, "seeds": ["plant.seed"],
                       "fault": {"target": ["plant.f_sensor_h1", "plant.f_leak_T1"],
                                 "magnitude": {"min": 0.01, "max": 1.0, "scale": "log"}, "onset": {"min": 10, "max": 50},
                                 "duration": [20.0, math.inf]},
                       "parameters": {"plant.az1": {"min": 0.44, "max": 0.48}}}}
    a, b = (CampaignSpec.from_dict(data, folder).runs() for _ in range(2))
    assert a == b and len(a) == 55
    assert len({r.parameters["plant.seed"] for r in a}) == 55
    mags = [r.fault["magnitude"] for r in a if r.fault]
    assert min(mags) >= 0.01 and max(mags) <= 1.0
    assert {r.fault["duration"] for r in a if r.fault} == {20.0, None}
    assert all(0.44 <= r.parameters["plant.az1"] <= 0.48 for r in a)


# ------------------------------------------------------------------------------ fmu_fdi.testing
def test_testing_helpers_pass_and_fail_with_evidence(folder):
    from fmu_fdi.cosim import Fault, InputSignals
    from plant_fmus.dts200 import dts200_physics as phys

    _, q = phys.operating_point()
    res = run_scenario({"plant": folder / "dts200.fmu", "bank": folder / "dts200_sensor_dos.fmu"},
                       inputs=InputSignals([0.0], {"Q1": [q[0]], "Q2": [q[1]]}), step=1.0, stop=300.0,
                       faults=[Fault.abrupt("plant.f_sensor_h2", 150.0, 1.5)], parameters={"plant.seed": 11})
    names = ["sensor_h1", "sensor_h2", "sensor_h3"]
    assert_no_false_alarm(res, until=150.0)
    m = assert_detected(res, onset=150.0, within=30.0, isolated_as="sensor_h2", fault_names=names)
    with pytest.raises(DiagnosisAssertionError, match=r"not isolated as 'sensor_h1'(.|\n)*sensor_h2 for"):
        assert_detected(res, onset=150.0, within=30.0, isolated_as="sensor_h1", fault_names=names)
    with pytest.raises(DiagnosisAssertionError, match=r"not detected within(.|\n)*t_dt = "):
        assert_detected(res, onset=150.0, within=m.t_dt - 1.0)
    with pytest.raises(DiagnosisAssertionError, match=r"alarmed sample\(s\)(.|\n)*alarm episodes: \[1"):
        assert_no_false_alarm(res)
    # zero alarms in N samples show rate p at confidence c exactly when (1 - p)^N <= 1 - c
    n = samples_needed(1e-3, 0.95)
    assert (1 - 1e-3) ** n <= 0.05 < (1 - 1e-3) ** (n - 1)
    assert_false_alarm_rate((0, n), rate=1e-3, confidence=0.95)
    with pytest.raises(DiagnosisAssertionError, match=f"{n} samples would show it"):
        assert_false_alarm_rate((0, n - 1), rate=1e-3, confidence=0.95)


@pytest.mark.parametrize("persistence, latch", [((1, 1), False), ((3, 5), False), ((2, 3), True), ((4, 4), False)])
def test_sweep_decision_is_the_runtime_decision(persistence, latch):
    from fmu_fdi.campaign.execute import decide
    from fmu_fdi.runtime.decision import Decision

    rng = np.random.default_rng(0)
    for n in (2, 7, 60):  # records shorter than the persistence window too
        J, th = rng.random((n, 2)), np.full((n, 2), 0.6)
        d = Decision({"persistence": list(persistence), "latch": latch}, 2, 0)
        ref = [False]  # row 0: no diagnosis yet
        for i in range(1, n):
            d.step(J[i].tolist(), th[i].tolist(), np.zeros(2))
            ref.append(any(d.alarms))
        assert decide(J, th, persistence, latch).tolist() == ref
