"""Residual evaluation and decision: A7 of acceptance.md, adaptive thresholds, Diagnoser.

Plant outputs come from the exact zero-order-hold simulation of the model (tests/simulate.py),
so the nominal residual of an exact design is rounding noise (< 1e-12 here).
"""
import json

import numpy as np
import pytest

import published as pub
from fmu_fdi import Diagnoser, DesignError, FDIModel, nullspace_design, sensor_gain_plants, threshold_selector
from fmu_fdi.designfile import DesignFileError
from simulate import plant_outputs

TS = 0.01
NARENDRA = {"kind": "narendra", "alpha": 0.0, "beta": 10.0, "gamma": 0.9}  # A7's evaluation filter


def a7_signals(seed=0):
    """A7: t in [0, 1], u = sin(2πt), d ~ N(0, 1) per sample, faults 0.5 from t = 0.05."""
    t = np.arange(0, 1 + TS / 2, TS)
    N = t.size
    u = np.sin(2 * np.pi * t)[:, None]
    d = np.random.default_rng(seed).standard_normal((N, 1))
    f = np.zeros((N, 2))
    f[int(round(0.05 / TS)):] = 0.5
    return t, u, d, f


@pytest.fixture(scope="module")
def a7_generator():
    return nullspace_design(pub.ex5_3(), rdim=1, poles=[-3])


def _alarms(dg, t, u, y):
    out = dg.run(t, u, y)
    return out["alarm_1"], out["fault_detected"]


def test_a7_nominal_no_alarm_then_detection(a7_generator):
    model = pub.ex5_3()
    t, u, d, f = a7_signals()
    dg = Diagnoser(a7_generator, Ts=TS, evaluation=NARENDRA, thresholds=1.0)
    y0 = plant_outputs(model, t.size, TS, u=u, d=d)
    alarm, detected = _alarms(dg, t, u, y0)
    assert not alarm.any() and not detected.any()
    y1 = plant_outputs(model, t.size, TS, u=u, d=d, f=f)
    alarm, detected = _alarms(dg, t, u, y1)
    assert detected.any() and alarm[-1]
    assert t[np.argmax(detected)] >= 0.05  # no alarm before the faults start


def _sensor_error_cases(rng, n_random=8):
    vertices = [np.array(v) for v in [(-.2, -.2), (-.2, .2), (.2, -.2), (.2, .2)]]
    return vertices + [rng.uniform(-0.2, 0.2, 2) for _ in range(n_random)]


def test_a7_with_20_percent_measurement_error(a7_generator):
    """±20 % gain errors on y: a fixed τ = 1 raises false alarms, the adaptive threshold
    from the threshold selector (ℓ∞ majorant for the Narendra evaluation) never does and
    still detects the A7 faults."""
    model = pub.ex5_3()
    t, u, d, f = a7_signals()
    thr = threshold_selector(a7_generator, NARENDRA, J0=0.01, plants=sensor_gain_plants(model, 0.2), Ts=TS)
    adaptive = Diagnoser(a7_generator, Ts=TS, evaluation=NARENDRA, thresholds=thr)
    fixed = Diagnoser(a7_generator, Ts=TS, evaluation=NARENDRA, thresholds=1.0)
    y0 = plant_outputs(model, t.size, TS, u=u, d=d)
    y1 = plant_outputs(model, t.size, TS, u=u, d=d, f=f)
    fixed_false = 0
    for eps in _sensor_error_cases(np.random.default_rng(1)):
        gain = 1 + eps
        assert not _alarms(adaptive, t, u, y0 * gain)[1].any(), f"false alarm with gain error {eps}"
        assert _alarms(adaptive, t, u, y1 * gain)[1].any(), f"fault missed with gain error {eps}"
        fixed_false += _alarms(fixed, t, u, y0 * gain)[1].any()
    assert fixed_false > 0  # the fixed threshold of the nominal design is not robust


def _perturbed_ex5_3(a, b):
    s = pub.s
    G = pub.tfm([[pub.GU[0], (s - 1) / (s + 2)], [(s + 2 * a) / (s + 3 * b), 0]], ["u", "d"])
    from fmu_fdi import actuator_fault, sensor_fault

    return FDIModel.from_control(G, u=["u"], d=["d"], faults=[actuator_fault("fa", "u"), sensor_fault("fs2", "y2")])


def test_a7_with_uncertain_plant_parameters(a7_generator):
    """Gu2 = (s + 2a)/(s + 3b), a, b in [0.9, 1.1]: a 5x5 grid of the box designs the
    threshold (margin 1.1 for plants between grid points); fresh random plants from the
    box raise no false alarm, and the faults are detected."""
    grid = [(a, b) for a in np.linspace(0.9, 1.1, 5) for b in np.linspace(0.9, 1.1, 5)]
    thr = threshold_selector(a7_generator, NARENDRA, J0=0.01, plants=[_perturbed_ex5_3(a, b) for a, b in grid],
                             Ts=TS, margin=1.1)
    dg = Diagnoser(a7_generator, Ts=TS, evaluation=NARENDRA, thresholds=thr)
    rng = np.random.default_rng(7)
    t, u, d, f = a7_signals()
    for _ in range(8):
        plant = _perturbed_ex5_3(*rng.uniform(0.9, 1.1, 2))
        assert not _alarms(dg, t, u, plant_outputs(plant, t.size, TS, u=u, d=d))[1].any()
        assert _alarms(dg, t, u, plant_outputs(plant, t.size, TS, u=u, d=d, f=f))[1].any()


def test_adaptive_threshold_under_large_inputs(a7_generator):
    """Ex 5.3 plant with ±10 % sensor gain errors, inputs of size 100, sensor noise 0.01.

    The fixed threshold tuned on the nominal plant (1.5 x the largest nominal ewrms over
    noisy runs) raises false alarms on plants of the set; the adaptive threshold (exact
    ℓ2 bound with forgetting λ = 0.99 > the squared plant pole modulus 0.98²; J0 = the
    same tuned value) raises none. A sensor fault of the documented minimal size
    f_min = 2 max_k J_th(k) / |Rf(1)| is detected: at steady state the fault's ewrms is
    |Rf(1)| f, the uncertainty's is at most max J_th, so their difference exceeds J_th.
    """
    model = pub.ex5_3()
    ev = {"kind": "ewrms", "lambda": 0.99}
    N = 1500
    rng = np.random.default_rng(3)
    u = np.repeat(rng.uniform(-100, 100, (N // 50, 1)), 50, axis=0)
    d = rng.standard_normal((N, 1))
    t = np.arange(N) * TS
    noise = 0.01
    y_nom = plant_outputs(model, N, TS, u=u, d=d)
    peaks = [Diagnoser(a7_generator, Ts=TS, evaluation=ev, thresholds=1e9).run(
        t, u, y_nom + noise * np.random.default_rng(10 + s).standard_normal(y_nom.shape))["evaluation_1"].max()
        for s in range(3)]
    J0 = 1.5 * max(peaks)
    fixed = Diagnoser(a7_generator, Ts=TS, evaluation=ev, thresholds=J0)
    thr = threshold_selector(a7_generator, ev, J0=J0, plants=sensor_gain_plants(model, 0.1), Ts=TS)
    adaptive = Diagnoser(a7_generator, Ts=TS, evaluation=ev, thresholds=thr)
    false_fixed, max_thr = 0, 0.0
    cases = [np.array([-0.1, -0.1]), np.array([0.1, 0.1]), np.array([0.1, -0.1])] + \
        [rng.uniform(-0.1, 0.1, 2) for _ in range(7)]
    for k, eps in enumerate(cases):
        y = y_nom * (1 + eps) + noise * np.random.default_rng(100 + k).standard_normal(y_nom.shape)
        out = adaptive.run(t, u, y)
        assert not out["fault_detected"].any(), f"adaptive false alarm with sensor gains {1 + eps}"
        max_thr = max(max_thr, out["threshold_1"].max())
        false_fixed += fixed.run(t, u, y)["fault_detected"].any()
    assert false_fixed > 0
    j = model.fault_names.index("fs2")
    gain = abs(a7_generator.fault_response(j).dcgain()[0, 0])
    f_min = 2 * max_thr / gain
    f = np.zeros((N, model.nf))
    f[N // 2:, model.fault("fs2").columns] = 1.05 * f_min
    y = plant_outputs(model, N, TS, u=u, d=d, f=f) * 1.1 + noise * rng.standard_normal(y_nom.shape)
    out = adaptive.run(t, u, y)
    assert out["fault_detected"][N // 2:].any() and not out["fault_detected"][: N // 2].any()


def test_step_and_run_agree_bitwise_and_save_load(tmp_path, a7_generator):
    t, u, d, f = a7_signals()
    y = plant_outputs(pub.ex5_3(), t.size, TS, u=u, d=d, f=f)
    dg = Diagnoser(a7_generator, Ts=TS, evaluation={"kind": "rms", "window": 7}, thresholds=0.2,
                   decision={"persistence": [2, 3], "latch": True})
    out = dg.run(t, u, y)
    dg.reset()
    steps = [dg.step(u[k], y[k]) for k in range(t.size)]
    for nm in dg.output_names:
        assert np.array_equal(out[nm], np.array([s[nm] for s in steps], dtype=out[nm].dtype)), nm
    path = dg.save(tmp_path / "d.json")
    again = Diagnoser.load(path).run(t, u, y)
    for nm in out.dtype.names:
        assert np.array_equal(out[nm], again[nm]), nm


def test_save_refuses_a_path_it_could_not_load_and_keeps_the_previous_file(tmp_path, a7_generator, monkeypatch):
    dg = Diagnoser(a7_generator, Ts=TS, thresholds=1.0)
    for bad in ("d.txt", "d", "sub"):
        (tmp_path / "sub").mkdir(exist_ok=True)
        with pytest.raises(DesignFileError, match="design file"):
            dg.save(tmp_path / bad)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sub"]
    path = dg.save(tmp_path / "d.json")
    before = path.read_bytes()
    # a failure while writing (here: the disk is full) leaves the previous file whole
    def full(self, *args, **kwargs):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(type(path), "write_text", full)
    with pytest.raises(OSError, match="No space"):
        Diagnoser(a7_generator, Ts=TS, thresholds=2.0).save(path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.json", "sub"]


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.update(format="fmu-fdi-design/9"), "unsupported design format"),
    (lambda d: d.pop("generator"), "missing keys"),
    (lambda d: d["generator"]["discrete"].update(B=[[1.0]]), "generator.discrete.B must be"),
    (lambda d: d["evaluation"][0].update(evaluator={"kind": "bogus"}), "unknown evaluation kind"),
    (lambda d: d["evaluation"][0].update(threshold={"kind": "fixed", "value": -1}), "fixed threshold"),
    (lambda d: d.update(extra=1), "unknown keys"),
    (lambda d: d["generator"].update(dt=0), "positive sample time"),
])
def test_design_file_errors_name_the_item(tmp_path, a7_generator, mutate, message):
    dg = Diagnoser(a7_generator, Ts=TS, thresholds=1.0)
    path = dg.save(tmp_path / "d.json")
    d = json.loads(path.read_text())
    mutate(d)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    with pytest.raises(DesignFileError, match=message):
        Diagnoser.load(bad)


def test_invalid_samples_hold_outputs_and_do_not_poison_state(a7_generator):
    t, u, d, f = a7_signals()
    y = plant_outputs(pub.ex5_3(), t.size, TS, u=u, d=d)
    dg = Diagnoser(a7_generator, Ts=TS, thresholds=1.0)
    clean = dg.run(t, u, y)
    y_bad = y.copy()
    y_bad[40:45, 1] = np.nan
    y_bad[50, 0] = np.inf
    bad = dg.run(t, u, y_bad)
    assert bad["input_invalid"][40:45].all() and bad["input_invalid"][50] and bad["input_invalid"].sum() == 6
    assert np.array_equal(bad["residual_1"][40:45], np.full(5, bad["residual_1"][39]))
    assert np.all(np.isfinite(bad["residual_1"])) and np.all(np.isfinite(bad["evaluation_1"]))
    assert not bad["fault_detected"].any() and not clean["fault_detected"].any()


def test_diagnoser_argument_errors(a7_generator):
    with pytest.raises(DesignError, match="thresholds are required"):
        Diagnoser(a7_generator, Ts=TS)
    with pytest.raises(DesignError, match="give the diagnosis sample time Ts"):
        Diagnoser(a7_generator, thresholds=1.0)
    with pytest.raises(DesignError, match="J0 must be a positive"):
        threshold_selector(a7_generator, NARENDRA, J0=0.0, plants=[pub.ex5_3()], Ts=TS)
    dg = Diagnoser(a7_generator, Ts=TS, thresholds=1.0)
    with pytest.raises(ValueError, match="u must be N x 1"):
        dg.run(np.arange(3) * TS, np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="uniformly spaced"):
        dg.run(np.array([0, 0.01, 0.03]), np.zeros((3, 1)), np.zeros((3, 2)))


def test_rls_estimator_runs_in_a_diagnoser_and_round_trips(tmp_path):
    """A parameter-estimation diagnoser: the RLS runtime behind the same Diagnoser/design file."""
    from fmu_fdi import parametric_fault, rls_estimator

    A = np.array([[1.5, 1.0], [-0.7, 0.0]])
    model = FDIModel.from_matrices(A, [[1.0], [0.5]], [[1.0, 0.0]], dt=1.0, u_names=["u"], y_names=["y"],
                                   faults=[parametric_fault("gain", dB=[[0.2], [0.1]])])
    est = rls_estimator(model, noise_std=0.01)
    # |r_i| is a deviation in standard deviations: 6 keeps the per-sample false-alarm
    # probability of a Gaussian below 2e-9 (Bonferroni over 4 parameters x 400 samples: < 4e-6)
    dg = Diagnoser(est, evaluation={"kind": "norm"}, thresholds=6.0)
    rng = np.random.default_rng(0)
    N = 400
    u = rng.standard_normal((N, 1))
    x = np.zeros(2)
    y = np.empty((N, 1))
    for k in range(N):
        y[k] = x[0] + 0.01 * rng.standard_normal()
        x = A @ x + np.array([1.0, 0.5]) * u[k, 0]
    t = np.arange(N) * 1.0
    out = dg.run(t, u, y)
    assert not out["fault_detected"].any()
    again = Diagnoser.load(dg.save(tmp_path / "rls.json")).run(t, u, y)
    for nm in out.dtype.names:
        assert np.array_equal(out[nm], again[nm]), nm


def test_evaluator_record_and_sample_shapes():
    from fmu_fdi.runtime.evaluation import Evaluator

    assert np.array_equal(Evaluator({"kind": "norm"}, 1).run(np.array([1.0, -2.0, 3.0])), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"shape \(1,\)"):
        Evaluator({"kind": "rms", "window": 2}, 1).step(np.array([3.0, 4.0]))
