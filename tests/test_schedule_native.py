"""The native FMU (FMI 2.0 and 3.0) and the pythonfmu FMU of a scheduled design run the schedule of
docs/semantics.md §12 exactly as the Python runtime (ScheduledDiagnoser.run): judged to 1e-12
as tests/test_native_conformance.py judges plain designs, on a scenario that sweeps the
scheduling signal back and forth across the members (many switches, both directions), with
invalid samples, an overflowing sample, re-discretised and refused steps, threshold_scale
changes, FMU-state save/restore (serialised too) and resets (each re-arms the warm start)."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fmu_fdi import build_fmu
from fmu_fdi.modelset import ModelSet
from fmu_fdi.runtime.engine import output_type
from fmu_fdi.runtime.schedule import ScheduledRuntime
from native_scenario import compare, python_outputs
from test_schedule import TS, _design, _member

RUNNER = Path(__file__).parent / "native_fmu_runner.py"
RTOL = 1e-12  # docs/semantics.md §1


def _scenario(rng, n=1500):
    ops, k = [], np.arange(n)
    u = 2.0 + 1.6 * np.sin(2 * np.pi * k / 300) + 0.05 * rng.standard_normal(n)  # sweeps members 1..3
    y = np.column_stack([1.0 + 0.5 * np.sin(k / 17), 1.2 + 0.4 * np.cos(k / 23)]) + 0.02 * rng.standard_normal((n, 2))
    y[400:404, 0] = np.nan          # an invalid burst (the schedule holds)
    y[700, 1] = 1e300               # overflows inside: numeric reset of every member
    steps = {200: 3 * TS, 201: TS, 500: 0.37 * TS, 520: TS, 800: TS / 40, 801: 20001 * TS}
    for i in range(n):
        if i in (300, 900):
            ops.append(["save", f"s{i}"])
        if i == 1000:
            ops.append(["restore", "s300"])
        if i in (600, 1200):
            ops.append(["scale", 0.5 if i == 600 else 1.0])
        if i == 1100:
            ops.append(["reset"])
        ops.append(["step", [float(u[i])], [float(y[i, 0]), float(y[i, 1])], steps.get(i, TS)])
    return ops


def _python(design, ops):
    rt = ScheduledRuntime(design)
    return python_outputs(design, ops, rt), rt.names


def test_native_fmus_equal_the_python_schedule(tmp_path):
    mset = ModelSet([_member(1.0 + 0.5 * k, float(k + 1)) for k in range(3)], ["u0"])
    design = json.loads(json.dumps(_design(mset, hysteresis=0.3).design))
    ops = _scenario(np.random.default_rng(19))
    # thresholds scaled to the median evaluation, so that alarms come and go (decisions of
    # different members are shown across switches)
    first, names = _python(design, ops)
    ev = np.array([r[names.index("evaluation_1")] / r[names.index("threshold_1")] for r in first if r != "discard"])
    scale = float(np.median(ev))
    ops = [["scale", scale]] + [["scale", op[1] * scale] if op[0] == "scale" else op for op in ops]
    ref, names = _python(design, ops)
    jobs = []
    for fmi in (2, 3):
        path = build_fmu(design, tmp_path / f"s{fmi}.fmu", target="native", fmi_version=fmi)
        jobs.append({"fmu": str(path), "fmi": fmi, "ops": ops})
    # the pythonfmu FMU too (the same Python runtime inside: its FMU state codec and step logic)
    jobs.append({"fmu": str(build_fmu(design, tmp_path / "py.fmu")), "fmi": 2, "ops": ops})
    (tmp_path / "jobs.json").write_text(json.dumps(jobs), encoding="utf-8")
    proc = subprocess.run([sys.executable, str(RUNNER), str(tmp_path / "jobs.json"), str(tmp_path / "res.json")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    types = [output_type(n) for n in names]
    for fmi, res in zip(("2", "3", "2 (pythonfmu)"), json.loads((tmp_path / "res.json").read_text(encoding="utf-8"))):
        assert res["names"] == names
        worst, bad = compare(names, types, ref, res["outputs"], rtol=RTOL)
        assert not bad, f"FMI {fmi}:\n" + "\n".join(bad)
        print(f"FMI {fmi}: max deviation {worst:.3g}")
    # the scenario exercised what it is meant to
    rows = np.array([r for r in ref if r != "discard"])
    active = rows[:, names.index("active_member")]
    assert set(active.tolist()) == {0.0, 1.0, 2.0, 3.0} or set(active.tolist()) == {1.0, 2.0, 3.0}
    assert np.count_nonzero(np.diff(active)) >= 10  # switches both ways, several times
    assert rows[:, -2].any() and rows[:, -1].any() and sum(r == "discard" for r in ref) == 2
    assert 0.1 < rows[:, names.index("fault_detected")].mean() < 0.9
