"""Co-simulation master, fault scenarios, CSV, SSP export and CLI (issue 5, sections 2-3).

The plant FMU integrates x' = -a x + b (u + f) exactly for inputs held over a step, so its
samples are known in closed form (``plant_exact``); the consumer FMU samples its input ``y`` in
``doStep`` (z = 2 y, acc += h y), which makes the one-step delay of the Jacobi order visible.
Values that pass through the same floating-point operations on both sides are compared
exactly; where the test recomputes a value with another operation order the tolerance is
1e-12 (a few ulps of numbers of order 1, accumulated over at most 20 steps).
"""
from __future__ import annotations

import argparse
import math
import shutil

import numpy as np
import pytest

from cosim_fmus import (build_consumer, build_failing, build_fmi3_plant, build_plant, fmi3_headers,
                        plant_exact)
from fmu_fdi.cosim import (CoSimulation, CoSimulationError, Fault, InputSignals, Result, SimulationFailed,
                           format_fault, parse_fault, ssp_parameter_set)
from fmu_fdi.cosim import cli

H = 0.1
N = 20
T = [k * H for k in range(N + 1)]
TOL = 1e-12  # a few ulps at magnitude 1, over <= 20 steps of recomputation in another order


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fmus")
    return {"plant": build_plant(tmp), "consumer": build_consumer(tmp)}


def sim(fmus, **kw):
    kw.setdefault("step", H)
    kw.setdefault("stop", N * H)
    return CoSimulation({"plant": fmus["plant"], "diag": fmus["consumer"]}, **kw)


# ---- orders and exactness -------------------------------------------------------------------

def test_gauss_seidel_is_the_exact_discrete_solution(fmus):
    r = sim(fmus).run()
    assert r.names == ("time", "plant.y", "diag.z", "diag.acc", "diag.w", "diag.count", "diag.high")
    assert r["time"].tolist() == T
    y = np.array(plant_exact(H, N))
    np.testing.assert_allclose(r["plant.y"], y, rtol=0, atol=TOL)
    # the consumer's step to t_k+1 reads y(t_k+1): no delay
    np.testing.assert_array_equal(r["diag.z"][1:], 2 * r["plant.y"][1:])
    np.testing.assert_allclose(r["diag.acc"], np.concatenate([[0], np.cumsum(H * y[1:])]), atol=TOL)
    assert r["diag.count"].dtype == np.int64 and r["diag.count"].tolist() == list(range(N + 1))
    assert r["diag.high"].dtype == np.bool_
    np.testing.assert_array_equal(r["diag.high"][1:], r["plant.y"][1:] > 0.5)


def test_jacobi_delays_every_connection_by_exactly_one_step(fmus):
    gs = sim(fmus).run()
    ja = sim(fmus, order="jacobi").run()
    np.testing.assert_array_equal(ja["plant.y"], gs["plant.y"])  # the plant reads nothing
    np.testing.assert_array_equal(ja["diag.z"][1:], 2 * ja["plant.y"][:-1])
    np.testing.assert_array_equal(ja["diag.z"][1:], gs["diag.z"][:-1])
    y = gs["plant.y"]
    np.testing.assert_allclose(ja["diag.acc"][1:], np.cumsum(H * y[:-1]), atol=TOL)
    assert not np.array_equal(ja["diag.z"], gs["diag.z"])


def test_parameters_are_set_before_initialisation(fmus):
    r = sim(fmus, parameters={"plant.a": 2.0, "plant.b": 3.0, "plant.u": 0.5}).run()
    np.testing.assert_allclose(r["plant.y"], plant_exact(H, N, a=2.0, b=3.0, u=[0.5] * N), atol=TOL)


def test_two_instances_of_one_fmu_keep_separate_states(fmus):
    r = CoSimulation({"p1": fmus["plant"], "p2": fmus["plant"]}, connections=None, step=H, stop=N * H,
                     parameters={"p2.a": 2.0}).run()
    np.testing.assert_allclose(r["p1.y"], plant_exact(H, N), atol=TOL)
    np.testing.assert_allclose(r["p2.y"], plant_exact(H, N, a=2.0), atol=TOL)


def test_explicit_connections_and_none(fmus):
    s = sim(fmus, connections=[("plant.y", "diag.u")])
    assert s.connections == [("plant.y", "diag.u")]
    r = s.run()
    np.testing.assert_array_equal(r["diag.w"][1:], r["plant.y"][1:])
    np.testing.assert_array_equal(r["diag.z"], 0.0)  # diag.y is left at its start value 0
    assert sim(fmus, connections=None).connections == []


# ---- external inputs ----------------------------------------------------------------------------

def test_input_signals_zoh_and_linear_between_samples():
    s = InputSignals([0.0, 1.0, 1.0, 2.0], {"u": [0.0, 1.0, 5.0, 7.0]})
    assert [s.value("u", t) for t in (-1, 0.5, 0.999, 1.0, 1.5, 2.0, 9)] == [0, 0, 0, 5, 5, 7, 7]
    lin = InputSignals(s.time, s.values, interpolation="linear")
    assert [lin.value("u", t) for t in (-1, 0.5, 1.0, 1.5, 2.0, 9)] == [0, 0.5, 5, 6, 7, 7]
    with pytest.raises(CoSimulationError, match="must not decrease: sample 2"):
        InputSignals([0, 2, 1], {"u": [0, 0, 0]})


def test_csv_input_feeds_same_named_inputs_of_every_fmu(fmus, tmp_path):
    csv = tmp_path / "u.csv"
    lines = ['"time","u"'] + [f"{t!r},{1.0 + (k % 3)!r}" for k, t in enumerate(T)]
    csv.write_text("\n".join(lines) + "\n")
    u = [1.0 + (k % 3) for k in range(N)]
    r = sim(fmus, inputs=csv).run()
    np.testing.assert_allclose(r["plant.y"], plant_exact(H, N, u=u), atol=TOL)
    # the consumer's u is fed too, sampled at the start of each step
    np.testing.assert_array_equal(r["diag.w"][1:], u)
    lin = InputSignals.from_csv(csv, interpolation="linear")
    assert lin.value("u", 0.05) == pytest.approx(1.5, abs=TOL)


def test_qualified_signal_feeds_one_fmu_only(fmus):
    data = np.zeros(2, dtype=[("time", float), ("plant.u", float)])
    data["time"] = [0, 10]
    data["plant.u"] = 2.0
    r = sim(fmus, inputs=data).run()
    np.testing.assert_allclose(r["plant.y"], plant_exact(H, N, u=[2.0] * N), atol=TOL)
    np.testing.assert_array_equal(r["diag.w"], 0.0)


# ---- results as CSV ---------------------------------------------------------------------------

def test_result_csv_round_trip_is_exact(fmus, tmp_path):
    r = sim(fmus, faults=[Fault.gain("plant.y", 0.5, 0.9)]).run()
    path = r.to_csv(tmp_path / "out.csv")
    header = path.read_text().splitlines()[0]
    assert header == ('"time","plant.y","diag.z","diag.acc","diag.w","diag.count","diag.high",'
                      '"fault.gain_plant_y","fault.gain_plant_y.active"')
    back = Result.from_csv(path)
    assert back.names == r.names
    for name in r.names:
        np.testing.assert_array_equal(back[name], r[name].astype(float))
    from fmpy.util import read_csv  # the FMI cross-check reader sees the same numbers
    np.testing.assert_array_equal(read_csv(str(path))["plant.y"], r["plant.y"])


# ---- fault scenarios ------------------------------------------------------------------------------

ON, OFF = 0.5, 1.5  # onset and end of the windowed faults


def window(t):
    return ON - 1e-9 <= t < OFF - 1e-9


CONNECTION_FAULTS = {
    # kind: (fault on plant.y, expected faulty value from (k, t, y))
    "abrupt": (Fault.abrupt("plant.y", ON, 0.3, end=OFF), lambda k, t, y: y[k] + 0.3 * window(t)),
    "gain": (Fault.gain("plant.y", ON, 0.5, end=OFF), lambda k, t, y: y[k] * (0.5 if window(t) else 1)),
    "stuck": (Fault.stuck("plant.y", ON, end=OFF), lambda k, t, y: y[5] if window(t) else y[k]),
    "stuck_value": (Fault.stuck("plant.y", ON, 7.0, end=OFF), lambda k, t, y: 7.0 if window(t) else y[k]),
    "drift": (Fault.drift("plant.y", ON, 0.5), lambda k, t, y: y[k] + 0.5 * max(0.0, t - ON)),
    "incipient": (Fault.incipient("plant.y", ON, 1.0, ramp=0.5),
                  lambda k, t, y: y[k] + (min(1.0, (t - ON) / 0.5) if t >= ON - 1e-9 else 0.0)),
    "intermittent": (Fault.intermittent("plant.y", 0.3, 1.0, period=0.4, duty=0.5, end=OFF),
                     lambda k, t, y: y[k] + (k in (3, 4, 7, 8, 11, 12))),
    "parameter": (Fault.parameter("plant.y", ON, -1.0, end=OFF), lambda k, t, y: -1.0 if window(t) else y[k]),
}


@pytest.mark.parametrize("kind", list(CONNECTION_FAULTS))
def test_fault_on_a_connection_has_its_shape(fmus, kind):
    fault, expected = CONNECTION_FAULTS[kind]
    r = sim(fmus, faults=[fault]).run()
    y = r["plant.y"]
    np.testing.assert_allclose(y, plant_exact(H, N), atol=TOL)  # the true output is recorded
    faulty = np.array([expected(k, t, y) for k, t in enumerate(T)])
    # Gauss-Seidel: the consumer's step to t_k reads the faulty y(t_k)
    np.testing.assert_allclose(r["diag.z"][1:], 2 * faulty[1:], rtol=0, atol=TOL)
    np.testing.assert_allclose(r[f"fault.{fault.name}"], faulty - y, rtol=0, atol=TOL)
    active = [fault.onset - 1e-9 <= t < (fault.end or 99) - 1e-9 for t in T]
    if kind == "intermittent":
        active = [k in (3, 4, 7, 8, 11, 12) for k in range(N + 1)]
    assert r[f"fault.{fault.name}.active"].tolist() == active


def test_incipient_ramp_slope_and_drift_rate(fmus):
    r = sim(fmus, faults=[Fault.incipient("plant.y", ON, 1.0, ramp=0.5, name="ramp"),
                          Fault.drift("diag.u", ON, 0.25, name="drift")]).run()
    ramp = r["fault.ramp"]
    np.testing.assert_allclose(np.diff(ramp[5:11]), 1.0 / 0.5 * H, atol=TOL)  # slope 2 per second
    assert ramp[:5].tolist() == [0] * 5
    # recorded as (y + 1) - y: exact to one ulp of y + 1
    np.testing.assert_allclose(ramp[10:], 1.0, rtol=0, atol=TOL)
    # a fault on an unconnected input acts on its start value (0): w = 0.25 (t - onset)
    np.testing.assert_allclose(r["diag.w"][1:], [0.25 * max(0, t - ON) for t in T[:-1]], atol=TOL)


def test_stuck_freezes_the_value_at_the_first_point_after_onset(fmus):
    r = sim(fmus, faults=[Fault.stuck("plant.y", 0.45, name="s")]).run()
    y = r["plant.y"]
    np.testing.assert_array_equal(r["diag.z"][5:], 2 * y[5])
    np.testing.assert_array_equal(r["diag.z"][1:5], 2 * y[1:5])


def test_fault_on_the_plants_own_fault_input(fmus):
    f = Fault.intermittent("plant.f", 0.3, 2.0, period=0.4, end=OFF, name="leak")
    r = sim(fmus, faults=[f]).run()
    u = [1.0 + 2.0 * (k in (3, 4, 7, 8, 11, 12)) for k in range(N)]
    np.testing.assert_allclose(r["plant.y"], plant_exact(H, N, u=u), atol=TOL)
    np.testing.assert_array_equal(r["fault.leak"], [2.0 * (k in (3, 4, 7, 8, 11, 12)) for k in range(N + 1)])


def test_actuator_fault_on_an_input_fed_by_a_signal(fmus):
    data = np.zeros(1, dtype=[("time", float), ("u", float)])
    data["u"] = 2.0
    r = sim(fmus, inputs=data, faults=[Fault.gain("plant.u", ON, 0.5)]).run()
    u = [2.0 * (0.5 if t >= ON - 1e-9 else 1.0) for t in T[:-1]]
    np.testing.assert_allclose(r["plant.y"], plant_exact(H, N, u=u), atol=TOL)
    np.testing.assert_array_equal(r["diag.w"][1:], 2.0)  # the consumer's u is not faulty


def test_parameter_faults_tunable_during_the_run_fixed_before_initialisation(fmus):
    r = sim(fmus, faults=[Fault.parameter("plant.a", ON, 3.0, end=OFF)]).run()
    y = [0.0]
    for t in T[:-1]:
        a = 3.0 if window(t) else 1.0
        y.append(math.exp(-a * H) * y[-1] + (1 - math.exp(-a * H)) / a)
    np.testing.assert_allclose(r["plant.y"], y, atol=TOL)
    np.testing.assert_allclose(r["fault.parameter_plant_a"], [2.0 * window(t) for t in T], atol=0)
    fixed = sim(fmus, faults=[Fault.gain("plant.b", 0.0, 2.0)]).run()
    np.testing.assert_allclose(fixed["plant.y"], plant_exact(H, N, b=2.0), atol=TOL)
    np.testing.assert_array_equal(fixed["fault.gain_plant_b"], 1.0)
    with pytest.raises(CoSimulationError, match="plant.b is fixed"):
        sim(fmus, faults=[Fault.gain("plant.b", ON, 2.0)])


def test_faults_compose_source_before_input(fmus):
    r = sim(fmus, faults=[Fault.gain("plant.y", 0, 2.0, name="g"), Fault.abrupt("diag.y", 0, 1.0, name="a")]).run()
    y = r["plant.y"]
    np.testing.assert_allclose(r["diag.z"][1:], 2 * (2 * y[1:] + 1), atol=TOL)
    np.testing.assert_allclose(r["fault.g"], y, atol=TOL)
    np.testing.assert_allclose(r["fault.a"], 1.0, rtol=0, atol=TOL)  # (v + 1) - v: one ulp


# ---- fault SPEC mini-language -------------------------------------------------------------------

@pytest.mark.parametrize("spec, fault", [
    ("abrupt:plant.h1:10:0.5", Fault("abrupt", "plant.h1", 10, 0.5)),
    ("bias:plant.h1:10:20:0.5", Fault("abrupt", "plant.h1", 10, 0.5, end=20)),
    ("gain:plant.h1:10:20:0.8", Fault.gain("plant.h1", 10, 0.8, end=20)),
    ("stuck:plant.h1:10:hold", Fault.stuck("plant.h1", 10)),
    ("stuck:plant.h1:10:20:5", Fault.stuck("plant.h1", 10, 5.0, end=20)),
    ("incipient:plant.h1:10:2,ramp=50", Fault.incipient("plant.h1", 10, 2.0, ramp=50)),
    ("ramp:plant.h1:10:60:2", Fault.incipient("plant.h1", 10, 2.0, end=60)),
    ("drift:plant.h1:10::0.01", Fault.drift("plant.h1", 10, 0.01)),
    ("drift:plant.h1:10:inf:0.01", Fault.drift("plant.h1", 10, 0.01)),
    ("intermittent:plant.h1:10:60:1,period=4,duty=0.25",
     Fault.intermittent("plant.h1", 10, 1.0, period=4, duty=0.25, end=60)),
    ("parameter:plant.eta_dt:4000:4200:0.92,name=efficiency",
     Fault.parameter("plant.eta_dt", 4000, 0.92, end=4200, name="efficiency")),
])
def test_fault_spec_parses_and_formats_back(spec, fault):
    assert parse_fault(spec) == fault
    assert parse_fault(format_fault(fault)) == fault


@pytest.mark.parametrize("spec, message", [
    ("abrupt:plant.h1:0.5", "expected KIND:TARGET:ONSET"),
    ("leak:plant.h1:10:0.5", "kind 'leak' is unknown"),
    ("abrupt:h1:10:0.5", "must read 'fmu.variable'"),
    ("abrupt:plant.h1:ten:0.5", "ONSET 'ten' is not a number"),
    ("abrupt:plant.h1:10:5:0.5", "end 5 must be after onset 10"),
    ("gain:plant.h1:10:hold", "gain fault on plant.h1 needs a magnitude"),
    ("incipient:plant.h1:10:2", "needs ramp > 0"),
    ("intermittent:plant.h1:10:2", "needs period > 0"),
    ("intermittent:plant.h1:10:2,period=1,duty=2", "must lie in"),
    ("abrupt:plant.h1:10:2,ramp=1", "'ramp' applies to incipient"),
    ("abrupt:plant.h1:10:2,speed=1", "option 'speed=1' is not one of"),
])
def test_bad_fault_specs_say_what_is_wrong(spec, message):
    with pytest.raises(CoSimulationError, match=message):
        parse_fault(spec)


# ---- set-up errors and failures -----------------------------------------------------------------

@pytest.mark.parametrize("kwargs, error, message", [
    (dict(connections=[("plant.yy", "diag.y")]), CoSimulationError, r"no variable 'yy' \(did you mean 'y'"),
    (dict(connections=[("pump.y", "diag.y")]), CoSimulationError, "no FMU named 'pump'"),
    (dict(connections=[("diag.high", "plant.u")]), CoSimulationError, r"types differ \(Boolean -> Real\)"),
    (dict(connections=[("plant.u", "diag.y")]), CoSimulationError, "plant.u is not an output"),
    (dict(connections=[("plant.y", "diag.y"), ("diag.z", "diag.y")]), CoSimulationError, "connected twice"),
    (dict(step=0.0), CoSimulationError, "step must be positive"),
    (dict(step=-0.1), CoSimulationError, "step must be positive"),
    (dict(step=0.3), CoSimulationError, "not a whole number of steps"),
    (dict(order="parallel"), CoSimulationError, "order 'parallel'"),
    (dict(faults=[Fault.abrupt("plant.q", 1, 1)]), CoSimulationError, "FMU 'plant' has no variable 'q'"),
    (dict(faults=[Fault.abrupt("diag.count", 1, 1)]), CoSimulationError, "faults act on Real"),
    (dict(faults=[Fault.abrupt("diag.z", 1, 1)]), CoSimulationError, "feeds no input"),
    (dict(faults=[Fault.abrupt("plant.y", 1, 1), Fault.gain("plant.y", 1, 1, name="abrupt_plant_y")]),
     CoSimulationError, "two faults are named"),
    (dict(parameters={"plant.y": 1.0}), CoSimulationError, "only parameters and inputs"),
    (dict(parameters={"plant.a": "fast"}), CoSimulationError, r"plant.a: 'fast' is not a number \(Real\)"),
    (dict(inputs=InputSignals([0], {"v": [1]})), CoSimulationError, "'v' matches no unconnected input"),
    (dict(inputs=InputSignals([0], {"diag.y": [1]})), CoSimulationError, "already connected"),
])
def test_setup_errors_name_the_failing_item(fmus, kwargs, error, message):
    with pytest.raises(error, match=message):
        sim(fmus, **kwargs)


def test_failed_initialisation_names_the_fmu_and_frees_the_others(fmus, tmp_path):
    bad = build_failing(tmp_path, at=-1.0, how="error")
    s = CoSimulation({"plant": fmus["plant"], "valve": bad}, step=H, stop=N * H)
    with pytest.raises(SimulationFailed, match="FMU 'valve' failed to initialise at t=0") as info:
        s.run()
    assert len(info.value.result) == 0 and any("cannot initialise" in m for m in info.value.log)
    assert len(CoSimulation({"plant": fmus["plant"]}, step=H, stop=N * H).run()) == N + 1


def test_fmi2_messages_reach_the_instance_that_logged_them(fmus, tmp_path):
    """fmpy's FMI 2 log proxy keeps one logger per process (the last registered): the failing FMU is
    started BEFORE the plant here, so its traceback would have been routed to the plant's log (and,
    once that instance was freed, to freed memory). Its own log must hold it."""
    bad = build_failing(tmp_path, at=0.5, how="error")
    s = CoSimulation({"valve": bad, "plant": fmus["plant"]}, step=H, stop=N * H)
    with pytest.raises(SimulationFailed, match="FMU 'valve' doStep") as info:
        s.run()
    assert any("broken valve model" in line for line in info.value.log), info.value.log


def test_missing_fmu_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="FMU 'plant': no such file"):
        CoSimulation({"plant": tmp_path / "nope.fmu"}, step=1, stop=2)


# pythonfmu answers a do_step returning False with Discard and an exception with Fatal
@pytest.mark.parametrize("how, status", [("discard", "discard"), ("error", "fatal")])
def test_failing_fmu_stops_the_run_with_partial_result(fmus, tmp_path, how, status):
    bad = build_failing(tmp_path, at=0.5, how=how)
    s = CoSimulation({"plant": fmus["plant"], "valve": bad}, step=H, stop=N * H)
    with pytest.raises(SimulationFailed, match=rf"FMU 'valve' doStep from t=0.5 .*status \d \({status}\)") as info:
        s.run()
    exc = info.value
    assert exc.fmu == "valve" and exc.time == pytest.approx(0.5)
    assert exc.result["time"].tolist() == T[:6]  # rows up to the last completed point
    np.testing.assert_allclose(exc.result["valve.y"], T[:6], atol=TOL)
    if how == "error":
        assert any("broken valve model" in line for line in exc.log)
    s2 = CoSimulation({"plant": fmus["plant"]}, step=H, stop=N * H)  # FMUs were freed: runs again
    assert len(s2.run()) == N + 1


# ---- SSP ----------------------------------------------------------------------------------------------

def test_ssp_export_runs_in_fmpy_with_the_same_results(fmus, tmp_path):
    from fmpy.ssp.simulation import simulate_ssp

    # dyadic step: both masters then reach exactly the same communication points
    h, n = 0.125, 16
    s = sim(fmus, order="jacobi", step=h, stop=n * h, parameters={"plant.a": 2.0})
    ours = s.run()
    path = s.export_ssp(tmp_path / "system.ssp")
    theirs = simulate_ssp(str(path), stop_time=n * h, step_size=h, parameter_set=ssp_parameter_set(path))
    assert len(theirs) == n
    # fmpy labels the row computed over [t_k, t_k+1] with t_k and starts connectors at 0 (= y(0)
    # here), so its row k is our row k+1. Same binaries, same inputs, same order of calls: equal.
    for name in ours.names[1:]:
        np.testing.assert_array_equal(theirs[name], ours[name][1:], err_msg=name)
    np.testing.assert_allclose(ours["plant.y"], plant_exact(h, n, a=2.0), atol=TOL)


def test_ssp_export_carries_signals_and_refuses_faults(fmus, tmp_path):
    import zipfile

    from fmpy.ssp.ssd import read_ssd

    s = sim(fmus, inputs=InputSignals([0], {"u": [2.0]}), faults=[Fault.abrupt("plant.y", 1, 1)])
    with pytest.raises(CoSimulationError, match="cannot express the fault scenarios abrupt_plant_y"):
        s.export_ssp(tmp_path / "x.ssp")
    path = s.export_ssp(tmp_path / "x.ssp", drop_faults=True)
    ssd = read_ssd(str(path))  # validates against the SSP 1.0 schema
    assert [c.name for c in ssd.system.connectors] == ["u"]
    conns = {(c.startElement, c.startConnector, c.endElement, c.endConnector) for c in ssd.system.connections}
    assert conns == {("plant", "y", "diag", "y"), (None, "u", "plant", "u"), (None, "u", "diag", "u")}
    assert sorted(zipfile.ZipFile(path).namelist()) == ["SystemStructure.ssd", "resources/diag.fmu",
                                                        "resources/plant.fmu"]


# ---- FMI 3 -------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def fmi3_plant(tmp_path_factory):
    if shutil.which("gcc") is None or fmi3_headers() is None:
        pytest.skip("needs gcc and fmpy's FMI 3 headers to build the FMI 3 test FMU")
    return build_fmi3_plant(tmp_path_factory.mktemp("fmi3"))


def test_fmi3_plant_with_fmi2_consumer(fmi3_plant, fmus):
    from fmpy import read_model_description

    md = read_model_description(str(fmi3_plant), validate=True)  # a schema-valid FMI 3 FMU
    assert md.fmiVersion == "3.0" and md.coSimulation is not None
    s = CoSimulation({"plant": fmi3_plant, "diag": fmus["consumer"]}, step=H, stop=N * H,
                     faults=[Fault.abrupt("plant.u", ON, 1.0, end=OFF, name="act")],
                     parameters={"plant.a": 2.0})
    assert s.fmus["plant"].fmi_version == 3
    r = s.run()
    assert r.names[:4] == ("time", "plant.y", "plant.steps", "plant.positive")
    u = [1.0 + window(t) for t in T[:-1]]
    np.testing.assert_allclose(r["plant.y"], plant_exact(H, N, a=2.0, u=u), atol=TOL)
    assert r["plant.steps"].tolist() == list(range(N + 1))
    assert r["plant.positive"].tolist() == [False] + [True] * N
    np.testing.assert_array_equal(r["diag.z"][1:], 2 * r["plant.y"][1:])
    ja = CoSimulation({"plant": fmi3_plant, "diag": fmus["consumer"]}, step=H, stop=N * H,
                      order="jacobi").run()
    np.testing.assert_array_equal(ja["diag.z"][1:], 2 * ja["plant.y"][:-1])


def test_fmi3_plant_agrees_with_fmpys_own_master(fmi3_plant):
    import fmpy

    theirs = fmpy.simulate_fmu(str(fmi3_plant), stop_time=N * H, output_interval=H,
                               start_values={"a": 2.0}, output=["y"])
    ours = CoSimulation({"plant": fmi3_plant}, step=H, stop=N * H, parameters={"plant.a": 2.0}).run()
    np.testing.assert_allclose(theirs["time"], ours["time"], rtol=0, atol=TOL)
    # fmpy derives its step sizes from its own time grid, ulps away from H: ulp-level differences
    np.testing.assert_allclose(theirs["y"], ours["plant.y"], rtol=0, atol=TOL)


def test_fmi3_tunable_parameter_fault(fmi3_plant):
    r = CoSimulation({"plant": fmi3_plant}, step=H, stop=N * H,
                     faults=[Fault.parameter("plant.a", ON, 3.0)]).run()
    y = [0.0]
    for t in T[:-1]:
        a = 3.0 if t >= ON - 1e-9 else 1.0
        y.append(math.exp(-a * H) * y[-1] + (1 - math.exp(-a * H)) / a)
    np.testing.assert_allclose(r["plant.y"], y, atol=TOL)


# ---- command line ---------------------------------------------------------------------------------

def parse(argv):
    parser = argparse.ArgumentParser(prog="fmu-fdi")
    cli.add_parser(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def test_cli_simulate_writes_the_result(fmus, tmp_path, capsys):
    out = tmp_path / "out.csv"
    csv = tmp_path / "u.csv"
    csv.write_text('"time","u"\n0,2\n')
    args = parse(["simulate", "--plant", str(fmus["plant"]), "--diagnoser", str(fmus["consumer"]),
                  "--stop", "2", "--step", "0.1", "--input", str(csv), "--fault", "stuck:plant.y:0.5:hold",
                  "--fault", "abrupt:plant.f:1:0.5,name=pump", "--ssp", str(tmp_path / "s.ssp"), "-o", str(out)])
    assert args.func(args) == 0
    assert (tmp_path / "s.ssp").is_file()
    r = Result.from_csv(out)
    assert "fault.pump" in r.names and "diagnoser.z" in r.names
    u = [2.0 + 0.5 * (t >= 1 - 1e-9) for t in T[:-1]]
    np.testing.assert_allclose(r["plant.y"], plant_exact(H, N, u=u), atol=TOL)
    np.testing.assert_array_equal(r["diagnoser.z"][5:], 2 * r["plant.y"][5])
    printed = capsys.readouterr()
    assert "21 rows" in printed.out and "describes the fault-free system" in printed.err


def test_cli_exit_codes(fmus, tmp_path, capsys):
    out = tmp_path / "out.csv"
    base = ["simulate", "--plant", str(fmus["plant"]), "--stop", "2", "--step", "0.1", "-o", str(out)]
    args = parse(base + ["--fault", "abrupt:plant.y:1"])
    assert args.func(args) == 2
    assert "expected KIND:TARGET:ONSET" in capsys.readouterr().err
    bad = build_failing(tmp_path, at=1.0, how="discard")
    args = parse(base + ["--plant", f"valve={bad}", "--param", "plant.a=2"])
    assert args.func(args) == 1
    assert "FMU 'valve' doStep from t=1" in capsys.readouterr().err
    assert len(Result.from_csv(out)) == 11


# ---- reliability (issue 12 items 4 and 6) ---------------------------------------------------------

def test_streamed_run_writes_the_same_csv_as_the_in_memory_run(fmus, tmp_path):
    ref = sim(fmus).run()
    ref.to_csv(tmp_path / "ref.csv")
    last = sim(fmus).run(csv=tmp_path / "s.csv", chunk_rows=3)  # 21 rows in chunks of 3
    assert (tmp_path / "s.csv").read_text() == (tmp_path / "ref.csv").read_text()
    np.testing.assert_array_equal(last["time"], ref["time"][-len(last):])


def test_long_runs_allocate_nothing_before_the_first_step(fmus, tmp_path):
    import tracemalloc

    tracemalloc.start()
    s = sim(fmus, stop=1e8, step=0.01)  # 1e10 steps: a list of times alone would need 80 GB
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert s.n_steps == 10**10 and peak < 10 * 2**20
    with pytest.raises(CoSimulationError, match=r"GiB in memory; stream it to a file"):
        s.run()


def test_streamed_memory_does_not_grow_with_the_run_length(fmus, tmp_path):
    import tracemalloc

    peaks = []
    for n in (100, 1000):
        s = sim(fmus, stop=n * H)
        tracemalloc.start()
        s.run(csv=tmp_path / f"r{n}.csv", chunk_rows=64)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        assert len(Result.from_csv(tmp_path / f"r{n}.csv")) == n + 1
    # ten times the rows, the same buffers: allow 50 % for allocator noise, far below 10x
    assert peaks[1] < 1.5 * peaks[0], peaks


def test_unwritable_output_fails_before_any_fmu_runs(fmus, tmp_path):
    with pytest.raises(CoSimulationError, match="cannot write the result to .*No such file or directory"):
        sim(fmus).run(csv=tmp_path / "missing" / "out.csv")
    assert not (tmp_path / "missing").exists()


def test_failed_streamed_run_marks_the_csv_incomplete_with_the_fmus_message(fmus, tmp_path):
    bad = build_failing(tmp_path, at=0.5, how="error")
    s = CoSimulation({"plant": fmus["plant"], "valve": bad}, step=H, stop=N * H)
    out = tmp_path / "out.csv"
    with pytest.raises(SimulationFailed) as info:
        s.run(csv=out)
    exc = info.value
    assert exc.rows_written == 6 and exc.log and "broken valve model" in str(exc)
    lines = out.read_text().splitlines()
    assert len(lines) == 1 + 6 + 1 and lines[-1].startswith("# incomplete: the run stopped after 6 of 21 rows")
    assert "broken valve model" in lines[-1]
    assert Result.from_csv(out)["time"].tolist() == T[:6]  # the marker is a comment for readers


def test_silent_failure_says_the_fmu_gave_no_message(fmus, tmp_path):
    bad = build_failing(tmp_path, at=0.5, how="discard")
    with pytest.raises(SimulationFailed, match="The FMU logged no message"):
        CoSimulation({"valve": bad}, step=H, stop=N * H).run()


@pytest.mark.parametrize("fault, message", [
    (Fault.abrupt("plant.u", onset=N * H + 1, magnitude=1.0), "after the stop time"),
    (Fault.abrupt("plant.u", onset=-1.0, magnitude=1.0), "before the start time"),
])
def test_fault_onsets_outside_the_run_are_refused(fmus, fault, message):
    with pytest.raises(CoSimulationError, match=message):
        sim(fmus, faults=[fault])


def test_non_finite_fault_magnitudes_are_refused():
    for bad in ("nan", "inf", "-inf", "1e400"):
        with pytest.raises(CoSimulationError, match="must be finite"):
            parse_fault(f"abrupt:plant.y:1:{bad}")


def test_binary_input_csv_is_a_one_line_error(tmp_path):
    path = tmp_path / "in.csv"
    path.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(CoSimulationError, match="binary file, not a CSV file"):
        InputSignals.from_csv(path)
    path.write_text("time,u\n0,1\n", encoding="utf-16")
    with pytest.raises(CoSimulationError, match="UTF-16"):
        InputSignals.from_csv(path)


@pytest.fixture(scope="module")
def diagnostic_fmu(tmp_path_factory):
    """A diagnoser reading the test plant's y and u (first-order model, one sensor fault)."""
    from fmu_fdi import Diagnoser, FDIModel, sensor_fault
    from fmu_fdi.design.problems.nullspace import nullspace_design
    from fmu_fdi.fmu.builder import build_fmu

    m = FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], u_names=["u"], y_names=["y"],
                               faults=[sensor_fault("fy", "y")])
    dg = Diagnoser(nullspace_design(m), Ts=H, thresholds=1.0)
    return build_fmu(dg, tmp_path_factory.mktemp("diag") / "diag.fmu")


def test_fmu_warnings_reach_the_user(fmus, diagnostic_fmu, tmp_path, capsys):
    # u = 1e300: ||u - u0||^2 overflows on every sample, a warning the FMU logs each step (§8)
    s = CoSimulation({"plant": fmus["plant"], "diagnoser": diagnostic_fmu}, step=H, stop=N * H,
                     parameters={"diagnoser.u": 1e300}, allow_unconnected=True)
    r = s.run()
    assert any("the sample overflowed the evaluation" in w and "diagnoser" in w for w in r.warnings)
    assert r.warnings == s.warnings
    args = argparse.Namespace(plant=[str(fmus["plant"])], diagnoser=str(diagnostic_fmu), stop=N * H, step=H,
                              start=0.0, input=None, interpolation="zoh", fault=[], connect=None,
                              param=["diagnoser.u=1e300"], order="gauss-seidel", ssp=None,
                              output=str(tmp_path / "o.csv"), allow_unconnected=True)  # u: a start value
    assert cli.run(args) == 0
    err = capsys.readouterr().err
    assert "warning: FMU 'diagnoser' at t=0: the sample overflowed the evaluation" in err  # one time prefix
    # a threshold_scale that is not a finite number >= 0 is refused, not run at another scale (§6)
    args.param, args.output = ["diagnoser.threshold_scale=-1"], str(tmp_path / "o2.csv")
    assert cli.run(args) != 0
    assert "threshold_scale must be a finite number >= 0" in capsys.readouterr().err


def test_result_from_csv_refuses_broken_files_in_one_line(tmp_path):
    cases = {"missing.csv": None, "bin.csv": bytes(range(256)), "ragged.csv": b'"time","y"\n0,1\n0.1\n',
             "text.csv": b'"time","y"\n0,abc\n', "notime.csv": b'"t","y"\n0,1\n', "empty.csv": b""}
    for name, data in cases.items():
        if data is not None:
            (tmp_path / name).write_bytes(data)
        with pytest.raises(CoSimulationError) as info:
            Result.from_csv(tmp_path / name)
        assert str(tmp_path / name) in str(info.value) and "\n" not in str(info.value), name


def test_master_guards_the_pythonfmu_fmus_it_loads(fmus, tmp_path):
    """A raw pythonfmu FMU (one not built by fmu-fdi, so without its own exit guard) run by
    the master must not abort the host process at exit: pythonfmu 0.7 releases its
    interpreter handle twice then, and whether that corrupts the heap fatally depends only on
    the heap layout (fmu_fdi/fmu/exit_guard.py). The environment is copied onto the heap, so
    environments of different sizes give different layouts: every one must exit 0, with the
    FMU's library guarded by the master."""
    import os
    import subprocess
    import sys

    script = tmp_path / "host.py"
    script.write_text(
        "from fmu_fdi.cosim import CoSimulation\n"
        "from fmu_fdi.fmu import exit_guard\n"
        f"sims = [CoSimulation({{'plant': {str(fmus['plant'])!r}, 'diag': {str(fmus['consumer'])!r}}}, "
        f"step={H!r}, stop={5 * H!r}) for _ in range(2)]\n"
        "for s in sims:\n"
        "    s.run()\n"
        "assert len(exit_guard._GUARDED) == 4, exit_guard._GUARDED\n")  # 2 runs x 2 FMUs, each extracted anew
    for pad in range(0, 2400, 300):  # 8 layouts
        env = dict(os.environ, FMU_FDI_TEST_HEAP_PAD="x" * pad)
        proc = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, (pad, proc.stderr[-2000:])


# ---- the loop's fault evaluation and signal sampling against their definitions -------------------

@pytest.mark.parametrize("fault", [
    Fault.abrupt("p.x", onset=3.05, magnitude=0.5, end=12.0),
    Fault.incipient("p.x", onset=2.0, magnitude=1.5, ramp=4.3),
    Fault.intermittent("p.x", onset=1.0, magnitude=-2.0, period=0.7, duty=0.3, end=15.0),
    Fault.stuck("p.x", onset=4.0), Fault.stuck("p.x", onset=4.0, value=7.5),
    Fault.gain("p.x", onset=0.3, factor=1.25), Fault.drift("p.x", onset=5.5, rate=0.2),
    Fault.parameter("p.x", onset=9.9, value=3.0),
])
def test_fault_channel_on_the_grid_is_the_fault_definition(fault):
    """FaultChannel (what the loop runs: a step at a time, and a chunk of rows at once) against
    Fault.active and Fault.apply at every grid point; the values must agree exactly."""
    from fmu_fdi.cosim.faults import FaultChannel

    start, step, n = 0.3, 0.1, 180
    rng = np.random.default_rng(3)
    v = rng.normal(size=n + 1)
    times = [start + j * step for j in range(n + 1)]
    active = [fault.active(t) for t in times]
    first = active.index(True)
    want = [fault.apply(t, x, v[first]) for t, x in zip(times, v)]  # stuck freezes the first active value
    stepwise = FaultChannel(fault, start, step, n)
    assert [stepwise.at(j, t, x) for j, (t, x) in enumerate(zip(times, v))] == want
    rows = np.arange(n + 1)
    chunked = FaultChannel(fault, start, step, n)
    assert chunked.active_rows(rows).tolist() == active
    got = np.concatenate([chunked.values(rows[a:a + 50], v[a:a + 50]) for a in range(0, n + 1, 50)])
    assert got.tolist() == want


@pytest.mark.parametrize("interpolation", ["zoh", "linear"])
def test_signal_samples_on_arrays_are_the_pointwise_values(interpolation):
    s = InputSignals([0.0, 1.0, 1.0, 2.5, 4.0], {"u": [1.0, 2.0, -1.0, 3.5, 0.25]}, interpolation)
    t = np.linspace(-1.0, 5.0, 241)
    assert s.sample("u", t).tolist() == [s.value("u", float(x)) for x in t]


INT_ECHO = '''
from pythonfmu import Fmi2Slave, Fmi2Causality, Integer, Boolean


class {cls}(Fmi2Slave):
    """Samples its integer and Boolean inputs in do_step: twice = 2 steps, neg = not positive, kk = k."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.steps = 0
        self.positive = False
        self.k = 0
        self.twice = 0
        self.neg = False
        self.kk = 0
        self.register_variable(Integer("steps", causality=Fmi2Causality.input))
        self.register_variable(Boolean("positive", causality=Fmi2Causality.input))
        self.register_variable(Integer("k", causality=Fmi2Causality.input))
        self.register_variable(Integer("twice", causality=Fmi2Causality.output))
        self.register_variable(Boolean("neg", causality=Fmi2Causality.output))
        self.register_variable(Integer("kk", causality=Fmi2Causality.output))

    def do_step(self, t, h):
        self.twice = 2 * self.steps
        self.neg = not self.positive
        self.kk = self.k
        return True
'''


def test_integer_and_boolean_values_cross_fmi_versions_and_come_from_signals(fmi3_plant, tmp_path):
    """FMI 3 Int32/Boolean outputs into FMI 2 Integer/Boolean inputs, and a Real signal into an
    Integer input (truncated, as int() does): the loop's integer bus and its conversions."""
    from cosim_fmus import _pythonfmu

    echo = _pythonfmu(tmp_path, INT_ECHO, "intecho")
    sig = InputSignals([0.0, 0.5], {"k": [2.7, -3.9]})
    r = CoSimulation({"plant": fmi3_plant, "echo": echo}, inputs=sig, step=H, stop=N * H,
                     parameters={"plant.u": -1.0}, record_inputs=True).run()
    # Gauss-Seidel: in the step from t_k the echo reads the plant's outputs at t_{k+1}
    assert r["plant.steps"].tolist() == list(range(N + 1))
    assert r["echo.twice"][1:].tolist() == [2 * s for s in r["plant.steps"][1:]]
    assert r["echo.neg"][1:].tolist() == [not p for p in r["plant.positive"][1:]]
    assert r["echo.kk"][1:].tolist() == [2 if t < 0.5 - 1e-12 else -3 for t in T[:-1]]
    assert r["echo.steps"].tolist() == r["plant.steps"].tolist()
    assert r["echo.k"].tolist() == [2 if t < 0.5 - 1e-12 else -3 for t in T]
    assert r.dtype["echo.twice"] == np.int64 and r.dtype["echo.neg"] == np.bool_
