"""Issue 12 item 1: a finite but huge sample must not switch diagnosis off (S1, S2 of
docs/semantics.md): the non-finite value is caught at the sample it appears, flagged on
``numeric_reset`` and ``input_invalid`` and counted as fault evidence (issue 21, §8), the
stages restart and a later fault is still detected.

Plant: Ex 5.3 (tests/published.py) simulated exactly (tests/simulate.py), Ts = 0.01 s, the
sensor fault fs2 (an additive bias on y2) of 0.05 ("5 cm") from sample K0.
"""
import math
import warnings

import numpy as np
import pytest

import published as pub
from fmu_fdi import Diagnoser, FDIModel, nullspace_design, rls_estimator
from fmu_fdi.designfile import DesignFileError, validate_design
from fmu_fdi.runtime.engine import DiagnoserRuntime
from simulate import plant_outputs

TS = 0.01
N, K0, GLITCH = 500, 300, 50
NARENDRA = {"kind": "narendra", "alpha": 0.0, "beta": 10.0, "gamma": 0.9}
KINDS = [{"kind": "norm"}, {"kind": "rms", "window": 10}, {"kind": "ewrms", "lambda": 0.9},
         {"kind": "peak", "window": 10}, NARENDRA, {"kind": "chi2", "window": 10, "sigma": 0.01},
         {"kind": "cusum", "delta": 1.0, "sigma": 0.01}, {"kind": "glr", "window": 10, "sigma": 0.01}]


@pytest.fixture(scope="module")
def record():
    gen = nullspace_design(pub.ex5_3(), poles=[-3])
    t = np.arange(N) * TS
    u = np.sin(2 * np.pi * t)[:, None]
    d = np.random.default_rng(0).standard_normal((N, 1))
    f = np.zeros((N, 2))
    f[K0:, 1] = 0.05
    return {"gen": gen, "t": t, "u": u, "y": plant_outputs(pub.ex5_3(), N, TS, u=u, d=d, f=f),
            "y_clean": plant_outputs(pub.ex5_3(), N, TS, u=u, d=d)}


def _threshold(rec, ev):
    """Half the evaluation the bias reaches at the end of the record: the bias is detectable."""
    probe = Diagnoser(rec["gen"], Ts=TS, evaluation=ev, thresholds=1e150).run(rec["t"], rec["u"], rec["y"])
    return 0.5 * float(probe["evaluation_1"][-1])


def _real_columns(out):
    return [n for n in out.dtype.names if out.dtype[n] == np.float64 and n != "time"]


@pytest.mark.parametrize("ev", [NARENDRA, {"kind": "rms", "window": 10}], ids=["narendra", "rms"])
def test_bias_after_a_1e300_glitch_is_still_detected(record, ev):
    """The issue's case: one y = 1e300 sample (finite, so not input_invalid) made every later
    evaluation NaN and a 5 cm bias was never detected."""
    dg = Diagnoser(record["gen"], Ts=TS, evaluation=ev, thresholds=_threshold(record, ev))
    t, u, y = record["t"], record["u"], record["y"]
    clean = dg.run(t, u, y)
    yg = y.copy()
    yg[GLITCH, 1] = 1e300
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the overflow is handled, not merely tolerated by numpy
        out = dg.run(t, u, yg)
    assert list(np.flatnonzero(out["numeric_reset"])) == [GLITCH]
    # §8: the overflow is said in the outputs: an unusable sample, and evidence (persistence 1/1: alarm)
    assert list(np.flatnonzero(out["input_invalid"])) == [GLITCH] and out["fault_detected"][GLITCH]
    for name in _real_columns(out):
        assert np.all(np.isfinite(out[name])), name
        assert out[name][GLITCH] == out[name][GLITCH - 1], name  # the discarded sample holds every real output
    # the restarted generator's transient decays (pole -3: e^{-3·2.5} < 1e-3 by K0); then the
    # diagnosis is the glitch-free one: the bias is detected at the same sample
    first = np.flatnonzero(clean["fault_detected"][K0:])[0] + K0
    assert not clean["fault_detected"][:K0].any()
    assert out["fault_detected"][first] and np.array_equal(out["fault_detected"][K0:], clean["fault_detected"][K0:])
    assert out["fault_detected"][-1]


@pytest.mark.parametrize("ev", KINDS, ids=[e["kind"] for e in KINDS])
def test_every_evaluation_recovers_from_an_overflow(record, ev):
    """y = 1e308 overflows the square of the residual (and any whitened statistic) in every
    evaluation kind: reset at that sample only, finite outputs, and 150 samples after the bias
    starts the alarms are those of the glitch-free run."""
    dg = Diagnoser(record["gen"], Ts=TS, evaluation=ev, thresholds=_threshold(record, ev))
    t, u, y = record["t"], record["u"], record["y"]
    clean = dg.run(t, u, y)
    yg = y.copy()
    yg[GLITCH, 1] = 1e308
    out = dg.run(t, u, yg)
    assert list(np.flatnonzero(out["numeric_reset"])) == [GLITCH]
    for name in _real_columns(out):
        assert np.all(np.isfinite(out[name])), name
    assert np.array_equal(out["fault_detected"][K0 + 150:], clean["fault_detected"][K0 + 150:])
    assert out["fault_detected"][-1]


def test_threshold_states_and_input_norm_overflow(record):
    """u = 1e200 is finite but ||u - u0|| overflows: an adaptive threshold (and its input
    evaluator) would turn Inf; the call is a numeric reset and the runtime goes on."""
    thr = {"kind": "adaptive", "a": 0.5, "J0": 0.01, "evaluation": {"kind": "narendra", "beta": 1.0}}
    dg = Diagnoser(record["gen"], Ts=TS, evaluation={"kind": "rms", "window": 10}, thresholds=thr)
    t, u, y = record["t"], record["u"].copy(), record["y_clean"]
    ref = dg.run(t, u, y)
    u[GLITCH] = 1e200
    out = dg.run(t, u, y)
    assert list(np.flatnonzero(out["numeric_reset"])) == [GLITCH]
    for name in _real_columns(out):
        assert np.all(np.isfinite(out[name])), name
    assert np.allclose(out["threshold_1"][-50:], ref["threshold_1"][-50:], rtol=1e-6)


def test_decision_latch_survives_a_numeric_reset(record):
    """S1 keeps persistence counters and latches: an alarm latched before the glitch stays up."""
    ev = {"kind": "rms", "window": 10}
    dg = Diagnoser(record["gen"], Ts=TS, evaluation=ev, thresholds=_threshold(record, ev),
                   decision={"latch": True, "persistence": [2, 3]})
    y = record["y"].copy()
    y[K0 + 100, 1] = 1e308
    out = dg.run(record["t"], record["u"], y)
    assert out["numeric_reset"][K0 + 100] and out["alarm_1"][K0 + 99:].all()


def test_rls_generator_recovers_from_an_overflow():
    m = FDIModel.from_matrices([[0.9]], [[0.5]], [[1.0]], dt=TS, u_names=["u"], y_names=["y1"])
    dg = Diagnoser(rls_estimator(m, warmup=5), thresholds=3.0)
    rng = np.random.default_rng(1)
    n = 400
    u = rng.standard_normal((n, 1))
    y = np.zeros((n, 1))
    for k in range(1, n):
        y[k] = 0.9 * y[k - 1] + 0.5 * u[k - 1] + 1e-3 * rng.standard_normal()
    t = np.arange(n) * TS
    ref = dg.run(t, u, y)
    yg = y.copy()
    yg[100] = 1e300  # the prefilter and the estimator's P and θ̂ overflow
    out = dg.run(t, u, yg)
    resets = np.flatnonzero(out["numeric_reset"])
    assert resets.size >= 1 and resets[0] == 100 and resets[-1] <= 102
    for name in _real_columns(out):
        assert np.all(np.isfinite(out[name])), name
    assert np.isfinite(dg.runtime.generator.theta).all()
    # restarted from θ0 with fresh data: the residuals are again of the glitch-free run's size
    assert np.abs(out["residual_1"][-50:]).max() < 10 * max(np.abs(ref["residual_1"][-50:]).max(), 1e-3)


# --------------------------------------------------------------------------- S2: valid ranges
def test_valid_range_rejects_a_glitch_like_nan(record):
    dg = Diagnoser(record["gen"], Ts=TS, evaluation=NARENDRA, thresholds=1.0,
                   valid_range={"y2": (-10.0, 10.0), "u": (-np.inf, 5.0)})
    assert dg.design["signals"]["valid_range"] == {"y2": [-10.0, 10.0], "u": [None, 5.0]}
    t, u, y = record["t"], record["u"].copy(), record["y"].copy()
    y_nan = y.copy()
    y[GLITCH, 1] = 1e300
    y[GLITCH + 5, 1] = 10.0 + 1e-9
    u[GLITCH + 9] = 6.0
    y_nan[GLITCH, 1] = y_nan[GLITCH + 5, 1] = np.nan
    u_nan = record["u"].copy()
    u_nan[GLITCH + 9] = np.nan
    out, ref = dg.run(t, u, y), dg.run(t, u_nan, y_nan)
    assert list(np.flatnonzero(out["input_invalid"])) == [GLITCH, GLITCH + 5, GLITCH + 9]
    assert not out["numeric_reset"].any()
    for name in out.dtype.names:  # exactly a NaN sample: same outputs, same states afterwards
        assert np.array_equal(out[name], ref[name]), name
    # bounds are inclusive
    rt = dg.runtime
    rt.reset()
    assert not rt.advance([5.0], [0.0, 10.0])[-2]


@pytest.mark.parametrize("ranges, message", [
    ({"y9": [0, 1]}, "'y9', which is not a signal"),
    ({"y1": [1.0, 0.0]}, "needs lo <= hi"),
    ({"y1": [0.0]}, "must be \\[lo, hi\\]"),
    ({"y1": [0.0, float("nan")]}, "hi must be a finite number or null"),
    ({"y1": [True, 2.0]}, "lo must be a finite number or null"),
    ({"y1": ["0", 2.0]}, "lo must be a finite number or null"),
    ([0, 1], "must map signal names"),
])
def test_malformed_valid_range_is_refused(record, ranges, message):
    dg = Diagnoser(record["gen"], Ts=TS, evaluation=NARENDRA, thresholds=1.0)
    design = dict(dg.design, signals=dict(dg.design["signals"], valid_range=ranges))
    with pytest.raises(ValueError, match=message):
        DiagnoserRuntime(design)
    with pytest.raises(DesignFileError, match=message):
        validate_design(design)


def test_runtime_state_round_trip_is_validated(record):
    """set_state refuses states that do not fit (shapes, NaN) and leaves the runtime as it was."""
    dg = Diagnoser(record["gen"], Ts=TS, evaluation={"kind": "rms", "window": 10}, thresholds=0.1)
    rt = dg.runtime
    for k in range(20):
        rt.advance(record["u"][k], record["y"][k])
    good = rt.get_state()
    bad_states = []
    s = rt.get_state()
    s["evaluators"][0]["ring"]["buf"] = [0.0] * 3
    bad_states.append(s)
    s = rt.get_state()
    s["generator"]["x"] = [math.nan] * len(s["generator"]["x"])
    bad_states.append(s)
    s = rt.get_state()
    s["outputs"] = s["outputs"][:-1]
    bad_states.append(s)
    s = rt.get_state()
    s["decision"]["raw_hist"] = []
    bad_states.append(s)
    s = rt.get_state()
    s["h"] = 1e300
    bad_states.append(s)
    for bad in bad_states:
        with pytest.raises(ValueError):
            rt.set_state(bad)
        assert rt.get_state() == good
    rest = [rt.advance(record["u"][k], record["y"][k]) for k in range(20, 60)]
    ref = dg.run(record["t"][:60], record["u"][:60], record["y"][:60])
    assert np.array_equal(np.array(rest)[:, 1], ref["evaluation_1"][20:60])
