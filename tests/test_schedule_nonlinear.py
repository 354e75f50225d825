"""A second plant whose linearisation changes markedly over its range (issue 19, "Show"): the
nonlinear model-exchange test FMU of tests/me_fmus.py, x1' = u1 - a sqrt(x1),
x2' = a sqrt(x1) - b x2² + c u2 x1, y = [x2, x1 x2 + e u1], whose steady state x1 = (u1/a)²
moves sixteenfold as u1 goes from 0.5 to 2. The scheduled diagnoser is built from the FMU
alone (linearised at 9 points of u1); the plant is simulated here independently (RK4 of the
equations, 20 sub-steps per sample, inputs held) along a ramp of u1 over the whole range.
"""
import math

import numpy as np
import pytest

from fmu_fdi import Diagnoser, dedicated_bank
from fmu_fdi.identify import model_from_fmu
from fmu_fdi.evaluation import fault_size_thresholds
from fmu_fdi.schedule import ScheduledDiagnoser
from me_fmus import build_me_fmu, equilibrium

TS = 0.5
A, B, C, E = 0.5, 0.2, 0.1, 0.3  # tests/me_fmus.py NONLINEAR
BIAS = (0.5, 5.0)                # sensor biases of y1 (~2..5) and y2 (~3..80), and the fault sizes
ONSET = 550.0


def _f(x, u):
    s = math.sqrt(max(x[0], 0.0))
    return [u[0] - A * s, A * s - B * x[1] * x[1] + C * u[1] * x[0]]


def _simulate(u, bias=None, sub=20, seed=5, onset=ONSET):
    x = list(equilibrium("nonlinear", list(u[0])))
    rng, h, ys = np.random.default_rng(seed), TS / sub, []
    for k, uk in enumerate(u):
        y = [x[1], x[0] * x[1] + E * uk[0]]
        if bias is not None and k * TS >= onset:
            y[bias] += BIAS[bias]
        ys.append(y)
        for _ in range(sub):
            k1 = _f(x, uk)
            k2 = _f([x[i] + h / 2 * k1[i] for i in range(2)], uk)
            k3 = _f([x[i] + h / 2 * k2[i] for i in range(2)], uk)
            k4 = _f([x[i] + h * k3[i] for i in range(2)], uk)
            x = [x[i] + h / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]) for i in range(2)]
    return np.array(ys) + 0.005 * rng.standard_normal((len(u), 2))  # sensor noise


def scheduled_design(folder, points=9):
    """The scheduled sensor DOS bank of the nonlinear FMU linearised at ``points`` values of u1 over
    [0.5, 2] (also benchmarks/envelope_scheduled.py's second plant)."""
    fmu = build_me_fmu(folder, "nonlinear", 2, True)
    mset = model_from_fmu(fmu, ["u1", "u2"], ["y1", "y2"],
                          at=[{"u1": float(v)} for v in np.linspace(0.5, 2, points)],
                          sensor_faults="all")  # u2 at its start value 0.5

    def thresholds(gen, evaluation):  # each residual sized for its own sensor's bias
        return [fault_size_thresholds(gen, evaluation, size)[i] for i, size in enumerate(BIAS)]

    return ScheduledDiagnoser.design(mset, dedicated_bank, kind="sensor", Ts=TS,
                                     evaluation={"kind": "rms", "window": 20}, thresholds=thresholds,
                                     decision={"persistence": [3, 5]})


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    sd = scheduled_design(tmp_path_factory.mktemp("me"))
    t = np.arange(0.0, 600.0, TS)
    u = np.column_stack([0.5 + 1.5 * np.clip((t - 50.0) / 400.0, 0.0, 1.0), np.full(t.size, 0.5)])
    single = Diagnoser.from_design(sd.design["members"][0])  # the same design at the start point only
    return t, u, single, sd


def test_single_point_false_alarms_scheduled_does_not(setup):
    t, u, single, sd = setup
    y = _simulate(u)
    assert single.run(t, u, y)["fault_detected"].any()
    out = sd.run(t, u, y)
    assert not out["fault_detected"].any()
    assert max(np.max(out[f"evaluation_{g}"] / out[f"threshold_{g}"]) for g in (1, 2)) < 0.75
    assert out["active_member"][0] == 1 and out["active_member"][-1] == 9
    assert np.all(np.diff(out["active_member"]) >= 0)  # a monotone ramp: the schedule only moves up


@pytest.mark.parametrize("j", [0, 1])
def test_scheduled_detects_and_isolates_at_the_far_end(setup, j):
    t, u, _, sd = setup
    out = sd.run(t, u, _simulate(u, bias=j))
    alarms = np.flatnonzero(out["fault_detected"])
    assert alarms.size and ONSET <= t[alarms[0]] <= ONSET + 5.0
    iso = out["isolated_fault"][t >= ONSET]
    assert set(iso[iso != 0].tolist()) == {j + 1}
