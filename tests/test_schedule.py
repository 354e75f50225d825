"""Scheduled diagnosers (issue 19, part 2): one design per member of a model set, the
nearest-member rule with hysteresis, warm start, files, CLI. The rule is judged against
its closed form on a ramp; the members against standalone diagnosers and a direct
simulation of their filters (independent of the scheduled runtime)."""
import json

import numpy as np
import pytest

from fmu_fdi import Diagnoser, FDIModel, dedicated_bank, sensor_fault
from fmu_fdi.cli import main
from fmu_fdi.designfile import DesignFileError
from fmu_fdi.modelset import ModelSet
from fmu_fdi.runtime.engine import StepSizeError
from fmu_fdi.runtime.schedule import nearest
from fmu_fdi.schedule import ScheduledDiagnoser, load_diagnoser

TS = 0.1
EVAL = {"kind": "rms", "window": 5}


def _member(a: float, u0: float):
    """x' = -a x + u, y = [x; x]: steady state y0 = u0 / a (a plant whose gain moves with a)."""
    return FDIModel.from_matrices([[-a]], [[1.0]], [[1.0], [1.0]],
                                  faults=[sensor_fault("s0", "y0"), sensor_fault("s1", "y1")],
                                  operating_point={"u": [u0], "y": [u0 / a, u0 / a]}, name=f"m{u0:g}")


@pytest.fixture(scope="module")
def mset():
    return ModelSet([_member(1.0 + 0.5 * k, float(k + 1)) for k in range(3)], ["u0"])


@pytest.fixture(scope="module")
def good_design(mset):
    return json.dumps(_design(mset).design)


def _design(mset, **kw):
    return ScheduledDiagnoser.design(mset, dedicated_bank, kind="sensor", Ts=TS, evaluation=EVAL, thresholds=0.05,
                                     **kw)


def _ramp(N=300):
    t = np.arange(N) * TS
    u = np.linspace(0.5, 3.5, N)[:, None]  # passes all three members (u0 = 1, 2, 3)
    y = np.column_stack([np.sin(t), np.cos(t)]) + 1.0
    return t, u, y


def test_hysteresis_band_in_one_dimension():
    # points 0 and 1, unit scale: d_0 - d_1 = 2 s - 1 for s in [0, 1], so the switch up needs
    # 2 s - 1 > eta (s > 0.6 for eta = 0.2) and back down 1 - 2 s > eta (s < 0.4)
    pts, sc = [[0.0], [1.0]], [1.0]
    assert nearest(pts, sc, [0.55], -1, 0.2) == 1  # no member active yet: plain nearest
    assert nearest(pts, sc, [0.59], 0, 0.2) == 0 and nearest(pts, sc, [0.61], 0, 0.2) == 1
    assert nearest(pts, sc, [0.41], 1, 0.2) == 1 and nearest(pts, sc, [0.39], 1, 0.2) == 0
    assert nearest(pts, sc, [0.5], -1, 0.0) == 0  # a tie goes to the lower index
    # the scale is the unit: with scale 10 the band is ten times wider in s
    assert nearest([[0.0], [10.0]], [10.0], [6.1], 0, 0.2) == 1 and nearest([[0.0], [10.0]], [10.0], [5.9], 0, 0.2) == 0


def test_members_run_every_sample_and_the_active_one_is_shown(mset):
    sd = _design(mset, warm_start=False, hysteresis=0.4)
    t, u, y = _ramp()
    out = sd.run(t, u, y)
    # closed form of the rule on a ramp through points 1, 2, 3 (scale 1): switch up once u
    # exceeds the midpoint by eta/2
    expect = np.where(u[:, 0] > 2.7, 3, np.where(u[:, 0] > 1.7, 2, 1))
    assert np.array_equal(out["active_member"], expect)
    alone = [Diagnoser.from_design(m).run(t, u, y) for m in sd.design["members"]]
    for name in alone[0].dtype.names:
        shown = np.choose(expect - 1, [a[name] for a in alone])
        assert np.array_equal(out[name], shown), name  # bit for bit: the same runtime per member


def test_warm_start_is_the_steady_state_of_each_filter(mset):
    sd = _design(mset)
    t, u, y = _ramp(50)
    sd.run(t, u, y)
    for k, m in enumerate(sd.design["members"]):
        g = m["generator"]["discrete"]
        A, B, C, D = (np.asarray(g[key], float) for key in "ABCD")
        v0 = np.concatenate([y[0] - m["operating_point"]["y"], u[0] - m["operating_point"]["u"]])
        x = np.linalg.lstsq(np.eye(len(A)) - A, B @ v0, rcond=None)[0]  # independent: least squares
        r = []
        for uk, yk in zip(u, y):
            v = np.concatenate([yk - m["operating_point"]["y"], uk - m["operating_point"]["u"]])
            r.append(C @ x + D @ v)
            x = A @ x + B @ v
        # member k's residuals from the scheduled runtime's member k: rounding only (n = 1..2
        # states, 50 steps of a stable filter: 1e-12 relative to the residual size)
        member = sd.runtime.members[k]
        member.reset()
        sd.runtime.reset()
        rows = np.array([sd.runtime.advance(uk, yk) and member.outputs[:2] for uk, yk in zip(u, y)])
        assert np.allclose(rows, np.array(r), rtol=1e-12, atol=1e-12 * np.abs(r).max())


def test_file_round_trip_invalid_samples_and_refused_steps(mset, tmp_path):
    sd = _design(mset, hysteresis=0.3)
    t, u, y = _ramp()
    out = sd.run(t, u, y)
    back = load_diagnoser(sd.save(tmp_path / "s.json"))
    assert isinstance(back, ScheduledDiagnoser)
    again = back.run(t, u, y)
    assert all(np.array_equal(out[n], again[n]) for n in out.dtype.names)
    assert back.design["report"]["design_seconds"] and len(back.design["schedule"]["warm"]) == 3
    rt = back.runtime
    rt.reset()
    for k in range(150):
        rt.advance(u[k], y[k])
    held = json.loads(json.dumps(rt.get_state()))
    bad = rt.advance([np.nan], y[150])
    assert bad[-2] == 1.0 and bad[rt.names.index("active_member")] == out["active_member"][149]
    before = json.dumps(rt.get_state())  # an invalid sample changes the input_invalid flag only
    def inner(state):  # everything but the outputs (whose input_invalid flag is the one change)
        return state["active"], [{k: v for k, v in m.items() if k != "outputs"} for m in state["members"]]
    assert inner(json.loads(before)) == inner(held)
    with pytest.raises(StepSizeError):
        rt.advance(u[150], y[150], TS / 100)  # below Ts/16: refused by every member (semantics §9)
    assert json.dumps(rt.get_state()) == before  # the refusal changed nothing
    rt.advance(u[150], y[150], 3 * TS)  # members adopt a plan of 3 sub-steps ...
    with pytest.raises(StepSizeError):
        rt.advance(u[151], y[151], TS / 100)  # ... and a refusal leaves them on it
    assert rt.h == 3 * TS and all(m.h == 3 * TS for m in rt.members)
    rt.set_state(json.loads(before))
    assert rt.advance(u[150], y[150])[:2] == list(out[150][["residual_1", "residual_2"]].tolist())


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["schedule"].update(signals=["y9"]), "must be one or more of the inputs"),
    (lambda d: d["schedule"].update(points=[[1.0], [1.0], [3.0]]), "same scheduling point"),
    (lambda d: d["schedule"].update(scale=[0.0]), "scale"),
    (lambda d: d["schedule"].update(hysteresis=-1.0), "hysteresis"),
    (lambda d: d["schedule"]["warm"][1][0].__setitem__(0, 9.0), "not the steady-state gain"),
    (lambda d: d["members"][2]["generator"].update(residual_names=["a", "b"]), "residual_names"),
    (lambda d: d["schedule"].update(rule="linear"), "rule"),
    (lambda d: d.update(extra=1), "unknown keys"),
])
def test_malformed_scheduled_designs_are_refused(good_design, edit, message):
    d = json.loads(good_design)
    edit(d)
    with pytest.raises(DesignFileError, match=message):
        ScheduledDiagnoser.from_design(d)


def test_cli_designs_a_model_set_and_diagnoses_a_log(mset, tmp_path, capsys):
    path = mset.to_file(tmp_path / "set.json")
    out = tmp_path / "sched.json"
    assert main(["design", str(path), "--method", "dos", "--ts", str(TS), "--evaluation", "rms:5",
                 "--threshold", "fixed:0.05", "--hysteresis", "0.3", "-o", str(out)]) == 0
    assert "3 members scheduled on ['u0']" in capsys.readouterr().out
    sd = load_diagnoser(out)
    assert sd.design["schedule"]["hysteresis"] == 0.3 and sd.design["schedule"]["signals"] == ["u0"]
    t, u, y = _ramp()
    log = tmp_path / "log.csv"
    np.savetxt(log, np.column_stack([t, u, y]), delimiter=",", header="time,u0,y0,y1", comments="")
    assert main(["diagnose", str(log), "--design", str(out), "-o", str(tmp_path / "d.csv")]) == 0
    got = np.genfromtxt(tmp_path / "d.csv", delimiter=",", names=True)
    assert np.array_equal(got["active_member"], sd.run(t, u, y)["active_member"])
    assert main(["design", str(path), "--method", "data", "--ts", "0.1", "-o", str(out)]) == 2
    assert main(["plot", str(tmp_path / "d.csv"), "--design", str(out), "-o", str(tmp_path / "d.png")]) == 0
    assert main(["build", str(out), "-o", str(tmp_path / "s.fmu")]) == 0 and (tmp_path / "s.fmu").is_file()


def test_pythonfmu_fmu_runs_the_schedule_as_scheduled_diagnoser_run(mset, tmp_path):
    from fmu_fdi import build_fmu
    from fmu_fdi.fmu import hosts

    sd = _design(mset, hysteresis=0.3)
    t, u, y = _ramp(120)
    u[:, 0] = np.linspace(0.5, 3.5, 120) + 0.4 * np.sin(t * 3)  # back and forth across the boundaries
    y[40] = np.nan  # an invalid sample: the schedule holds
    ref = sd.run(t, u, y)
    fmu = build_fmu(sd, tmp_path / "sched.fmu")
    inputs = np.zeros(t.size, dtype=[("time", "f8"), ("u0", "f8"), ("y0", "f8"), ("y1", "f8")])
    inputs["time"], inputs["u0"], inputs["y0"], inputs["y1"] = t, u[:, 0], y[:, 0], y[:, 1]
    names = sd.output_names
    res = hosts.run_fmu2slave(fmu, inputs, step=TS, outputs=names)["result"]
    # the FMU reports row k after doStep k, i.e. in row k + 1 (docs/semantics.md §2); the same
    # runtime code runs inside, so the numbers agree exactly
    for nm in names:
        assert np.array_equal(np.asarray(res[nm][1:], float), np.asarray(ref[nm][:-1], float)), nm
    assert len(set(ref["active_member"].tolist())) == 3
