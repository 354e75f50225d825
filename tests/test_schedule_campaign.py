"""The campaign tool sweeps the operating envelope (issue 19, item 4).

A campaign over three operating points of the DTS200 (the README's direction: Q1 up to +40 %,
Q2 down to -40 %; each run holds its point, the native plant FMU started at that point's
steady state) runs the README's single-point DOS bank and a scheduled DOS diagnoser side by
side as native FMUs on the same runs. The report's per-point figures (checked here against
sums of the run records and scipy's beta quantiles, not the aggregation code) show the
single-point bank false-alarming at the far edge, with a 95 % lower bound far above the
scheduled diagnoser's 95 % upper bound of zero alarms, and the scheduled one detecting and
isolating the level-sensor biases at every point.

The members are the plant's own Jacobian linearisations at the points (numerical derivatives
of plant_fmus' physics, the equations the FMU integrates): this test is about the campaign;
the scheduled diagnoser built from the FMU alone is tests/test_schedule_dts200.py's.
"""
import hashlib
import json
import math

import numpy as np
import pytest
from scipy.optimize import fsolve
from scipy.stats import beta

import plant_fmus
from fmu_fdi import FDIModel, build_fmu
from fmu_fdi.campaign import CampaignError, CampaignSpec, aggregate, run_campaign, write_report
from fmu_fdi.campaign.spec import Run, _operating_points
from fmu_fdi.cli import main
from fmu_fdi.cosim import InputSignals
from fmu_fdi.modelset import ModelSet
from plant_fmus.dts200 import dts200_physics as phys

DESIGN = ["--method", "dos", "--ts", "1", "--evaluation", "rms:20", "--threshold", "fault-size:1",
          "--persistence", "3/5"]  # the README's worked example
FRACTIONS = (0.0, 0.5, 1.0)  # of the way to Q1 +40 %, Q2 -40 %
CONFIDENCE = 0.95


def _linearised(model: FDIModel, q) -> FDIModel:
    """``model`` with A, Bu and the operating point of the physics at pump flows ``q``: the
    steady state by Powell's method from the nominal levels, the Jacobians by central differences
    (step 1e-6 of the value: truncation ~1e-12 relative, round-off ~1e-10, far below the
    linearisation error the test is about)."""
    q = np.asarray(q, float)
    h = fsolve(lambda x: phys.derivative(x, q), model.y0, xtol=1e-13)
    assert np.max(np.abs(phys.derivative(h, q))) < 1e-10

    def jac(f, x):
        cols = []
        for i in range(len(x)):
            d = 1e-6 * max(abs(x[i]), 1.0)
            e = np.zeros(len(x))
            e[i] = d
            cols.append((f(x + e) - f(x - e)) / (2 * d))
        return np.column_stack(cols)

    A = jac(lambda x: phys.derivative(x, q), h)
    Bu = jac(lambda v: phys.derivative(h, v), q)
    return model._replace(A=A, Bu=Bu, operating_point={"u": q, "y": h})


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    from plant_fmus.native_build import build_native

    tmp = tmp_path_factory.mktemp("envelope_campaign")
    nominal = FDIModel.from_file(plant_fmus.model_path("dts200"))
    q1, q2 = map(float, nominal.u0)
    members = [_linearised(nominal, [q1 * (1 + 0.4 * f), q2 * (1 - 0.4 * f)]) for f in FRACTIONS]
    ModelSet(members, ["Q1", "Q2"], name="dts200").to_file(tmp / "set.json")
    assert main(["design", str(tmp / "set.json"), *DESIGN, "-o", str(tmp / "scheduled.json")]) == 0
    assert main(["design", str(plant_fmus.model_path("dts200")), *DESIGN, "-o", str(tmp / "single.json")]) == 0
    build_fmu(tmp / "scheduled.json", tmp / "scheduled.fmu", target="native")
    build_fmu(tmp / "single.json", tmp / "single.fmu", target="native")
    plant = build_native("dts200", tmp)
    points = {"Q1": [float(m.u0[0]) for m in members], "Q2": [float(m.u0[1]) for m in members]}
    for i in range(3):  # each run starts at its point's steady state
        points[f"plant.h{i + 1}_start"] = [float(m.y0[i]) for m in members]
    data = {"format": "fmu-fdi-campaign/1", "name": "dts200-envelope",
            "simulation": {"step": 1.0, "stop": 600.0, "order": "jacobi"},
            "fmus": {"plant": plant.name, "single": "single.fmu", "scheduled": "scheduled.fmu"},
            "sample": {"method": "grid", "fault_free": 2, "seeds": ["plant.seed"],
                       "fault": {"target": ["plant.f_sensor_h1", "plant.f_sensor_h3"], "magnitude": [1.5],
                                 "onset": [300.0]},
                       "operating_points": {"mode": "path", **points}},
            # a native FMU carries no design file: its fault names and decision rule are given here
            "diagnosers": {name: {"faults": [f.name for f in nominal.faults], "persistence": [3, 5]}
                           for name in ("single", "scheduled")},
            "analysis": {"confidence": CONFIDENCE, "zone_start": 60.0}}  # the rms window and persistence
    spec = CampaignSpec.from_dict(data, tmp)
    results = run_campaign(spec, tmp / "out")
    figures = aggregate(results)
    files = write_report(figures, tmp / "report")
    return spec, results, figures, files


def test_single_point_false_alarms_at_the_edge_the_scheduled_one_does_not(campaign):
    spec, results, figures, files = campaign
    assert len(results.records) == spec.run_count() == 3 * (2 + 2) and not results.failed
    # the recorded decision rule is the FMUs' own (the sweep's factor 1 reproduces fault_detected)
    assert all(s["sweep_exact"] for r in results.records for s in r["diagnosers"].values())
    points = spec.sample["operating_points"]
    assert figures.points == [f"Q1={p['Q1']:.4g}, Q2={p['Q2']:.4g}" for p in points]
    # independent tally of the records per point and diagnoser
    tally = {}
    for r in results.records:
        j = points.index(r["run"]["operating_point"])
        for name, s in r["diagnosers"].items():
            t = tally.setdefault((name, j), {"N": 0, "k": 0, "n": 0, "d": 0, "iso": 0})
            t["N"] += s["samples"]
            t["k"] += s["alarm_samples"]
            if r["run"]["fault"] is not None:
                t["n"] += 1
                t["d"] += bool(s["detected"])
                t["iso"] += s["isolated_as"] == r["run"]["fault"]["label"]
    for (name, j), t in tally.items():
        row = figures.diagnosers[name].by_point[j]
        assert (row["samples"], row["alarm_samples"], row["faulty_runs"], row["detected"], row["isolated"]) == \
               (t["N"], t["k"], t["n"], t["d"], t["iso"])
        lo = 0.0 if t["k"] == 0 else beta.ppf((1 - CONFIDENCE) / 2, t["k"], t["N"] - t["k"] + 1)
        hi = 1.0 if t["k"] == t["N"] else beta.ppf(1 - (1 - CONFIDENCE) / 2, t["k"] + 1, t["N"] - t["k"])
        assert np.allclose(row["interval"], (lo, hi), rtol=1e-9, atol=0)
    sched, single = figures.diagnosers["scheduled"].by_point, figures.diagnosers["single"].by_point
    # the scheduled diagnoser: no false alarm at any point; with N >= 1500 fault-free samples per point
    # its rate is below 2.5e-3 per sample at 95 % (two-sided exact bound: 1 - 0.025^(1/N) ~ 3.7/N)
    for row in sched:
        assert row["alarm_samples"] == 0 and row["samples"] >= 1500 and row["interval"][1] < 2.5e-3
    # the single-point bank: none at its own point, and at the far edge alarms so often that its 95 %
    # lower bound is more than a hundred times the scheduled one's upper bound
    assert single[0]["alarm_samples"] == 0
    assert single[2]["interval"][0] > 100 * sched[2]["interval"][1]
    # detection and isolation of every 1.5 cm level-sensor bias at every point by the scheduled one
    for row in sched:
        assert row["detected"] == row["faulty_runs"] == 2 and row["isolated"] == 2
    # the report: the section, the plot and the CSV (one row per diagnoser and point)
    html = files["report"].read_text()
    assert "Across the operating envelope" in html and html.count("data:image/png") >= 1
    lines = files["operating_points"].read_text().splitlines()
    assert len(lines) == 1 + 2 * 3 and "rate_upper" in lines[0] and "detection_lower" in lines[0]


def test_operating_points_as_a_campaign_dimension():
    pts = _operating_points({"Q1": [1.0, 2.0], "Q2": [5.0, 6.0], "plant.h1_start": [40.0, 41.0]})
    assert pts == [{"Q1": 1.0, "Q2": 5.0, "plant.h1_start": 40.0}, {"Q1": 2.0, "Q2": 6.0, "plant.h1_start": 41.0}]
    assert len(_operating_points({"mode": "product", "a": [1.0, 2.0], "b": [3.0, 4.0, 5.0]})) == 6
    for bad, message in (({"a": [1.0], "b": [1.0, 2.0]}, "same K"), ({"a": [1.0, 1.0]}, "twice"),
                         ({"a": ["x"]}, "number"), ({"mode": "zigzag", "a": [1.0]}, "mode"),
                         ({"a": [math.inf]}, "finite"), ({}, "names no")):
        with pytest.raises(CampaignError, match=message):
            _operating_points(bad)
    # a point's signals are held over the run (replacing or adding to [inputs]); its parameters are
    # the run's; the key of a run without a point is what it was before points existed
    base = InputSignals([0.0, 10.0], {"Q1": [1.0, 2.0], "u": [3.0, 4.0]}, "linear")
    r = Run(0, None, {"plant.h1_start": 40.0}, {"Q1": 7.0, "Q2": 8.0, "plant.h1_start": 40.0})
    sig = r.input_signals(base)
    assert sig.interpolation == "linear" and sig.values["Q1"].tolist() == [7.0, 7.0]
    assert sig.values["Q2"].tolist() == [8.0, 8.0] and sig.values["u"].tolist() == [3.0, 4.0]
    alone = r.input_signals(None, 5.0)
    assert alone.time.tolist() == [5.0] and alone.value("Q1", 100.0) == 7.0 and "plant.h1_start" not in alone.values
    plain = Run(3, None, {"plant.seed": 7})
    assert plain.input_signals(base) is base and "operating_point" not in plain.to_dict()
    assert plain.key == hashlib.sha256(json.dumps({"fault": None, "parameters": {"plant.seed": 7}},
                                                  sort_keys=True).encode()).hexdigest()[:16]
    assert r.key != Run(0, None, {"plant.h1_start": 40.0}, {"Q1": 7.5, "Q2": 8.0, "plant.h1_start": 40.0}).key
