"""DAMADICS detection / isolation figures on hand-built runs with known answers.

Every expected value is a ratio of hand-counted durations: the outputs are step
signals held from one time stamp to the next (the last one for one more step), so the
answers are exact up to float rounding (compared with 1e-12).
"""
import math

import numpy as np
import pytest

from fmu_fdi.metrics import DiagnosisMetrics, metrics

T = np.arange(10.0)  # samples at 0..9, the record spans [0, 10)


def run(alarm_times=(), iso=None, t=T, **extra):
    a = np.isin(t, alarm_times)
    out = {"time": t, "fault_detected": a, "isolated_fault": np.zeros(t.size, int) if iso is None else iso}
    out.update(extra)
    return out


def close(a, b):
    return a == pytest.approx(b, rel=1e-12, abs=1e-12)


def test_reference_run_every_figure():
    # fault 2 on at t = 4; a one-sample false alarm at 1; alarm from 6 on; isolation:
    # 6 unknown, 7 correct, 8 another fault, 9 correct
    iso = np.array([0, 0, 0, 0, 0, 0, -1, 2, 3, 2])
    m = metrics(run([1, 6, 7, 8, 9], iso), t_on=4.0, fault=2)
    assert (m.t_from, m.t_hor, m.fault_free_time, m.faulty_time) == (0.0, 10.0, 4.0, 6.0)
    assert m.t_dt == 2.0 and m.missed_detection is False and m.alarm_at_onset is False
    assert close(m.r_fd, 1 / 4) and close(m.r_td, 4 / 6)
    assert m.t_it == 3.0
    assert close(m.r_ti, 2 / 6) and close(m.r_mi, 1 / 6) and close(m.r_ui, 1 / 6) and m.r_fi == 0.0
    assert m.false_alarms == 1 and m.mtbfa == 4.0


def test_no_alarm_at_all_is_a_missed_detection():
    m = metrics(run(), t_on=4.0, fault=1)
    assert m.missed_detection is True
    assert math.isinf(m.t_dt) and math.isinf(m.t_it)
    assert m.r_td == 0.0 and m.r_ti == 0.0 and m.r_fd == 0.0
    assert m.false_alarms == 0 and math.isinf(m.mtbfa)


@pytest.mark.parametrize("schedule", [{}, {"t_on": 10.0}, {"t_on": 25.0, "t_off": 30.0}])
def test_fault_never_switched_on_scores_a_fault_free_run(schedule):
    m = metrics(run([2, 3, 7]), fault=1, **schedule)
    assert m.faulty_time == 0.0 and m.fault_free_time == 10.0
    assert math.isnan(m.t_dt) and math.isnan(m.r_td) and math.isnan(m.t_it) and math.isnan(m.r_ti)
    assert m.missed_detection is None and m.alarm_at_onset is None
    assert close(m.r_fd, 3 / 10)
    assert m.false_alarms == 2 and m.mtbfa == 5.0  # rising edges at 2 and 7


def test_alarm_raised_before_onset_gives_zero_detection_time_and_says_so():
    m = metrics(run([2, 3, 4, 5]), t_on=4.0)
    assert m.t_dt == 0.0 and m.alarm_at_onset is True
    assert close(m.r_fd, 2 / 4) and close(m.r_td, 2 / 6)
    assert m.false_alarms == 1  # the run starting at 2 is a false alarm; it is not counted again
    # a rising edge exactly at t_on is a detection, not a carried-over alarm
    m = metrics(run([4, 5]), t_on=4.0)
    assert m.t_dt == 0.0 and m.alarm_at_onset is False and m.false_alarms == 0


def test_zone_boundaries_clip_every_duration():
    # zone [2.5, 7.5): fault-free [2.5, 4), faulty [4, 7.5)
    m = metrics(run([2, 7, 8]), t_on=4.0, zone=(2.5, 7.5))
    assert close(m.fault_free_time, 1.5) and close(m.faulty_time, 3.5)
    assert close(m.r_fd, 0.5 / 1.5)  # sample 2 holds over [2, 3): 0.5 of it in the zone
    assert close(m.r_td, 0.5 / 3.5)  # sample 7 holds over [7, 8): 0.5 of it in the zone
    assert m.t_dt == 3.0
    # an alarm already up at t_from counts as one false-alarm onset
    assert m.false_alarms == 1 and close(m.mtbfa, 1.5)


def test_zone_may_start_on_a_carried_over_alarm():
    m = metrics(run([1, 2, 3]), zone=(2.0, 10.0))
    assert m.false_alarms == 1 and close(m.r_fd, 2 / 8) and m.mtbfa == 8.0


def test_non_uniform_time_integrates_the_held_signals():
    t = np.array([0.0, 1.0, 3.0, 3.5, 6.0, 10.0])  # last sample holds for 4: record ends at 14
    a = np.array([0, 1, 0, 1, 0, 1])
    iso = np.array([0, 1, 0, 1, 0, 2])
    m = metrics({"time": t, "fault_detected": a, "isolated_fault": iso}, t_on=3.2, fault=1)
    assert m.t_hor == 14.0
    assert close(m.fault_free_time, 3.2) and close(m.faulty_time, 10.8)
    assert close(m.r_fd, 2.0 / 3.2)  # sample at 1 holds over [1, 3)
    assert close(m.r_td, (2.5 + 4.0) / 10.8)
    assert close(m.t_dt, 0.3) and close(m.t_it, 0.3)
    assert close(m.r_ti, 2.5 / 10.8) and close(m.r_mi, 4.0 / 10.8)
    assert close(m.r_fi, 2.0 / 3.2)  # fault 1 named while none was present


def test_switch_off_makes_later_alarms_false_but_lingering_alarms_no_new_onset():
    m = metrics(run([5, 6, 7, 9]), t_on=4.0, t_off=7.0)
    assert m.faulty_time == 3.0 and m.fault_free_time == 7.0
    assert close(m.r_td, 2 / 3) and close(m.r_fd, 2 / 7)
    assert m.false_alarms == 1 and m.mtbfa == 7.0


def test_fault_indicator_column_gives_the_schedule():
    ind = ((T >= 4) & (T < 7)).astype(float)
    rec = np.zeros(T.size, dtype=[("time", float), ("fault_detected", float), ("isolated_fault", float),
                                  ("fault.leak_T1", float), ("fault.pump_Q1", float)])
    rec["time"], rec["fault.leak_T1"] = T, ind
    rec["fault_detected"] = np.isin(T, [5, 6, 7, 9])
    from_indicator = metrics(rec)
    explicit = metrics(run([5, 6, 7, 9]), t_on=4.0, t_off=7.0)
    assert from_indicator.to_dict() == explicit.to_dict()
    # explicit t_on wins over the column
    assert metrics(rec, t_on=6.0).t_on == 6.0
    # an indicator that never switches on means a fault-free run
    assert metrics(run([3], **{"fault.x": np.zeros(10)})).faulty_time == 0.0


def test_float_outputs_as_an_fmu_writes_them():
    a = np.isin(T, [6, 7, 8, 9]).astype(float)
    m = metrics({"time": T, "fault_detected": a, "isolated_fault": np.where(a > 0, 1.0, 0.0)}, t_on=4.0, fault=1)
    assert m.t_dt == 2.0 and m.t_it == 2.0 and close(m.r_ti, 4 / 6)


def test_without_fault_index_the_true_isolation_figures_are_undefined():
    m = metrics(run([6], np.where(T == 6, 1, 0)), t_on=4.0)
    assert math.isnan(m.t_it) and math.isnan(m.r_ti) and math.isnan(m.r_mi)
    assert close(m.r_ui, 0.0) and m.r_fi == 0.0


def test_report_helpers():
    m = metrics(run([6, 7]), t_on=4.0, fault=1)
    d = m.to_dict()
    assert d["t_dt"] == 2.0 and d["fault"] == 1 and set(DiagnosisMetrics.COLUMNS) <= set(d)
    head, row = DiagnosisMetrics.table_header(), m.table_row("case A")
    assert len(head) == len(row) and row.startswith("case A")
    assert row.split()[2:] == ["2", "0.000", "0.333", "inf", "0.000", "0.000", "0.000", "inf"]
    assert metrics(run(), t_on=20.0).table_row().split()[0] == "-"  # NaN shows as '-'


@pytest.mark.parametrize("kwargs, data, message", [
    ({}, {"time": T, "fault_detected": np.zeros(10)}, "no field 'isolated_fault'"),
    ({}, {"fault_detected": np.zeros(10), "isolated_fault": np.zeros(10)}, "no 'time' field"),
    ({}, run(t=np.array([0.0, 1.0, 1.0, 2.0])), "strictly increasing"),
    ({}, run(t=np.array([0.0, np.nan])), "NaN"),
    ({}, {"time": T, "fault_detected": np.zeros(9), "isolated_fault": np.zeros(10)}, "9 samples"),
    ({}, run(iso=np.full(10, 0.5)), "integers >= -1"),
    ({"zone": (-1.0, 5.0)}, run(), "not inside the record"),
    ({"zone": (5.0, 11.0)}, run(), "not inside the record"),
    ({"zone": (5.0, 5.0)}, run(), "t_from < t_hor"),
    ({"zone": (1.0, 2.0, 3.0)}, run(), "pair"),
    ({"t_on": 1.0, "zone": (2.0, 9.0)}, run(), "start the zone at or before t_on"),
    ({"t_on": 4.0, "t_off": 4.0}, run(), "must come after t_on"),
    ({"t_off": 4.0}, run(), "t_off given without t_on"),
    ({"fault": 0}, run(), "1-based"),
    ({"fault": True}, run(), "1-based"),
    ({}, run(t=np.array([3.0])), "one-sample record"),
    ({}, run(**{"fault.a": np.ones(10), "fault.b": np.ones(10)}), "several fault indicator"),
    ({}, run(**{"fault.a": (T % 4 == 0).astype(float)}), "switches on 3 times"),
])
def test_bad_arguments_say_which_condition_failed(kwargs, data, message):
    with pytest.raises((ValueError, KeyError), match=message):
        metrics(data, **kwargs)


def test_structured_array_and_mapping_agree():
    rec = np.zeros(10, dtype=[("time", float), ("fault_detected", bool), ("isolated_fault", np.int32)])
    rec["time"] = T
    rec["fault_detected"] = T >= 5
    rec["isolated_fault"] = np.where(T >= 6, 1, 0)
    d = {k: rec[k] for k in rec.dtype.names}
    assert metrics(rec, t_on=3.0, fault=1).to_dict() == metrics(d, t_on=3.0, fault=1).to_dict()


def test_scores_a_diagnoser_run():
    """End to end: a Diagnoser with an analytic threshold diagnoses a sensor bias; metrics reads its output."""
    from fmu_fdi import Diagnoser, FDIModel, LTI, ResidualGenerator, sensor_fault
    from fmu_fdi.evaluation import analytic_threshold

    model = FDIModel.from_matrices([[0.9]], [[1.0]], [[1.0]], Bw=[[1.0, 0.0]], Dw=[[0.0, 1.0]], dt=1.0,
                                   u_names=["u"], y_names=["y"], faults=[sensor_fault("bias_y", "y")])
    gen = ResidualGenerator(LTI([[0.9]], [[0.0, 1.0]], [[-1.0]], [[1.0, 0.0]], 1.0), model, "open-loop observer")
    spec = {"kind": "rms", "window": 10}
    thr = analytic_threshold(gen, spec, 1e-4, noise_cov=[1.0, 0.5])
    dg = Diagnoser(gen, evaluation=spec, thresholds=thr, decision={"isolation": "structure", "structure": [[1]]})
    rng = np.random.default_rng(2)
    # bias 20 ≈ 8.5 σ of the residual: two faulty samples lift the rms of 10 above the
    # threshold (≈ 7.8), and the AR part (s.d. of a window mean ≈ 1.8) never pulls it back
    n, k_on, bias = 3000, 2000, 20.0
    u, w = rng.standard_normal(n), rng.standard_normal((n, 2)) * [1.0, np.sqrt(0.5)]
    x, y = 0.0, np.empty(n)
    for k in range(n):
        y[k] = x + w[k, 1] + (bias if k >= k_on else 0.0)
        x = 0.9 * x + u[k] + w[k, 0]
    m = metrics(dg.run(np.arange(n, dtype=float), u, y), t_on=float(k_on), fault=1)
    assert m.missed_detection is False and m.t_dt <= 3 and m.t_it == m.t_dt
    assert m.r_td == 1.0 - m.t_dt / 1000 and m.r_ti == m.r_td and m.r_mi == 0.0
    # α = 1e-4 per sample over 2000 fault-free samples: a false alarm is unlikely (≈ 0.2
    # alarmed samples expected); a rate above 1 % would mean a wrong threshold
    assert m.r_fd < 0.01


def test_reads_a_co_simulation_result():
    """Columns as CoSimulation records them: <instance>.<output>, fault.<name>, fault.<name>.active."""
    rec = np.zeros(10, dtype=[("time", float), ("plant.y", float), ("fdi.fault_detected", bool),
                              ("fdi.isolated_fault", np.int64), ("fault.stuck", float), ("fault.stuck.active", bool)])
    rec["time"] = T
    rec["fault.stuck.active"] = T >= 4
    rec["fault.stuck"] = np.where(T >= 6, 0.3, 0.0)  # stuck at the nominal value at first: zero offset
    rec["fdi.fault_detected"] = T >= 6
    rec["fdi.isolated_fault"] = np.where(T >= 7, 1, 0)
    m = metrics(rec, fault=1)
    assert m.t_on == 4.0 and m.t_dt == 2.0 and m.t_it == 3.0
    assert metrics(rec, indicator="stuck", fault=1).to_dict() == m.to_dict()
    assert metrics(rec, indicator="fault.stuck", fault=1).t_on == 6.0  # the value column, when asked for
    two = {**{k: rec[k] for k in rec.dtype.names}, "fdi2.fault_detected": rec["fdi.fault_detected"]}
    with pytest.raises(ValueError, match="several alarm fields"):
        metrics(two)
    assert metrics(two, alarm="fdi2.fault_detected").t_dt == 2.0
    with pytest.raises(KeyError, match="no indicator column 'leak'"):
        metrics(rec, indicator="leak")


def test_docstring_examples():
    import doctest
    import importlib

    # the package exports the function metrics(), which shadows the module attribute
    module = importlib.import_module("fmu_fdi.metrics")
    assert doctest.testmod(module).failed == 0
