"""Campaign workers keep their FMU instances between runs (issue 20, item 5): a run in a reused
instance (``fmi2Reset``/``fmi3Reset`` and a new initialisation) must give what a run in a fresh
instance (extracted, loaded and instantiated anew) gives. The fresh instance is the reference:
it shares no state with the runs before.

The plant and the diagnoser are the native (C) builds of the example campaign's pair, so the
runs take milliseconds; FMI 2 and FMI 3 reset through different calls, both are checked.
"""
from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from fmu_fdi.campaign import CampaignSpec
from fmu_fdi.campaign.example import write_campaign
from fmu_fdi.campaign.execute import PooledInstance, Worker, decide, decide_scaled
from fmu_fdi.campaign.runner import payload
from fmu_fdi.cosim import CoSimulation, Fault, InputSignals
from fmu_fdi.cosim.instance import FMUInstance

# The runs are deterministic given their seeds, and a reset instance runs the same C code on the
# same inputs from the same initial state as a fresh one: the traces agree to the last bit. 1e-12
# (relative to each column's size) is the tolerance, far below the 1e-3 cm sensor noise.
RTOL = 1e-12


@pytest.fixture(scope="module")
def native(tmp_path_factory):
    """The example campaign's plant and sensor bank as native FMUs, FMI 2 and FMI 3."""
    from fmu_fdi.campaign.example import build_fmus
    from fmu_fdi.fmu import build_fmu
    from fmu_fdi.native.build import NativeBuildError
    from plant_fmus.native_build import build_native

    out = tmp_path_factory.mktemp("reuse")
    try:
        fmus = build_fmus(out, native=True)
        with zipfile.ZipFile(fmus["bank"]) as z:
            design = json.loads(z.read(next(n for n in z.namelist() if n.endswith("/design.json"))))
        fmi3 = {"plant": build_native("dts200", out, reference=None, fmi_version=3),
                "bank": build_fmu(design, out / "bank3.fmu", target="native", fmi_version=3)}
    except NativeBuildError as exc:
        pytest.skip(f"no C compiler: {exc}")
    return out, {2: fmus, 3: fmi3}


def _sim(instances, fault, seed):
    from plant_fmus.dts200 import dts200_physics as phys

    _, q = phys.operating_point()
    signals = InputSignals([0.0, 40.0], {"Q1": [float(q[0]), float(q[0]) * 1.05], "Q2": [float(q[1])] * 2})
    return CoSimulation(instances, inputs=signals, step=1.0, stop=120.0, order="jacobi",
                        faults=[fault] if fault else [], parameters={"plant.seed": seed})


SCENARIOS = [(None, 1), (Fault.stuck("plant.h1", onset=30.0), 2), (Fault.abrupt("plant.f_sensor_h2", 50.0, 1.0), 3),
             (Fault.incipient("plant.Q1", onset=20.0, magnitude=3.0, ramp=30.0), 4), (None, 1)]


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_run_in_a_reused_instance_equals_one_in_a_fresh_instance(native, fmi):
    _, fmus = native
    pooled = {name: PooledInstance(name, path) for name, path in fmus[fmi].items()}
    try:
        for fault, seed in SCENARIOS:
            reused = _sim(pooled, fault, seed).run()
            fresh = _sim({name: FMUInstance(name, path) for name, path in fmus[fmi].items()}, fault, seed).run()
            assert reused.dtype == fresh.dtype and len(reused) == 121
            for col in fresh.dtype.names:
                a, b = fresh[col].astype(float), reused[col].astype(float)
                np.testing.assert_allclose(b, a, rtol=0, atol=RTOL * max(1.0, np.abs(a).max()), err_msg=col)
        # the instances really were kept: one extraction each for the five runs
        assert all(inst._slave is not None for inst in pooled.values())
    finally:
        for inst in pooled.values():
            inst.dispose()


def test_worker_records_do_not_depend_on_the_runs_before(native):
    folder, _ = native
    spec = CampaignSpec.load(write_campaign(folder, "reuse", stop=200.0, fault_free=2, replicates=1, onset=80.0,
                                            zone=30.0))
    runs = spec.runs()
    worker = Worker(payload(spec))
    try:
        kept = [worker.run(r.to_dict()) for r in runs + runs[:2]]
    finally:
        worker.close()
    assert [r["reused"] for r in kept] == [False] + [True] * (len(kept) - 1)
    # the native diagnoser carries its design: the worker knows its decision rule and fault names
    assert all(r["diagnosers"]["bank"]["sweep_exact"] for r in kept)
    assert {r["diagnosers"]["bank"].get("isolated_as") for r in kept if r["run"]["fault"]} <= \
        {"sensor_h1", "sensor_h2", "sensor_h3", "none", "unknown"}
    for i, r in enumerate(runs):
        alone = Worker(payload(spec))
        try:
            ref = alone.run(r.to_dict())
        finally:
            alone.close()
        assert not ref["reused"] and ref["status"] == kept[i]["status"] == "ok"
        assert ref["diagnosers"] == kept[i]["diagnosers"], r.index
    assert kept[-2]["diagnosers"] == kept[0]["diagnosers"] and kept[-1]["diagnosers"] == kept[1]["diagnosers"]


def _decide_by_hand(J, th, k, n, latch):
    """The decision rule sample by sample (raw test, k of the last n, latch), as the runtime states it."""
    alarms, history, latched = [], [], False
    for i in range(J.shape[0]):
        raw = [False] * J.shape[1] if i == 0 else [bool(J[i, g] >= th[i, g]) for g in range(J.shape[1])]
        history.append(raw)
        window = history[-n:]
        fired = [sum(w[g] for w in window) >= k for g in range(J.shape[1])]
        latched = latched or any(fired)
        alarms.append(latched if latch else any(fired))
    return np.array(alarms)


@pytest.mark.parametrize("persistence, latch", [((1, 1), False), ((3, 5), False), ((2, 4), True)])
def test_the_sweep_over_all_scales_at_once_is_the_rule_at_each_scale(persistence, latch):
    rng = np.random.default_rng(7)
    J = rng.chisquare(2, size=(60, 3))
    th = np.full((60, 3), 2.5)
    scales = np.linspace(0.5, 2.0, 7)
    got = decide_scaled(J, th, scales, persistence, latch)
    for s, row in zip(scales, got):
        np.testing.assert_array_equal(row, _decide_by_hand(J, s * th, *persistence, latch))
    np.testing.assert_array_equal(decide(J, th, persistence, latch), _decide_by_hand(J, th, *persistence, latch))
