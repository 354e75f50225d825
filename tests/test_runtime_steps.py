"""Issue 12 item 2: communication step sizes (S3, S4 of docs/semantics.md).

No step size may hang, exhaust memory or break the runtime for the steps after it; step
sizes equal within rounding are one step size; a multiple of Ts is sub-stepped without
restarting the evaluation.
"""
import numpy as np
import pytest

import published as pub
from fmu_fdi import Diagnoser, nullspace_design, parity_space
from fmu_fdi.runtime.engine import CACHE_SIZE, MAX_SUBSTEPS, StepSizeError

TS = 0.01
RMS = {"kind": "rms", "window": 7}


@pytest.fixture(scope="module")
def dg():
    return Diagnoser(nullspace_design(pub.ex5_3(), poles=[-3]), Ts=TS, evaluation=RMS, thresholds=0.02)


def signals(n, h, seed=0):
    t = np.arange(n) * h
    rng = np.random.default_rng(seed)
    u = np.sin(2 * np.pi * t)[:, None]
    y = np.c_[np.cos(t), 0.5 * np.sin(3 * t)] + 0.01 * rng.standard_normal((n, 2))
    return t, u, y


def accumulated_steps(h, n):
    """Step sizes as fmpy passes them: differences of accumulated time points."""
    points = np.array([k * h for k in range(n + 1)])  # fmpy: next point = start + n_steps * interval
    return np.diff(points)


HOSTILE = [1e300, 1e7 * TS, 1e-6, 1e-9, 1e-300, float("nan"), float("inf"), -TS, 0.0,
           (MAX_SUBSTEPS + 1) * TS, (MAX_SUBSTEPS + 0.6) * TS, TS / 17]


@pytest.mark.parametrize("h", HOSTILE, ids=[repr(h) for h in HOSTILE])
def test_refused_step_leaves_the_runtime_exactly_as_before(dg, h):
    t, u, y = signals(80, TS)
    ref = dg.run(t, u, y)
    rt = dg.runtime
    rt.reset()
    rows = []
    for k in range(80):
        if k in (10, 40):
            before = rt.get_state()
            with pytest.raises(StepSizeError):
                rt.advance(u[k], y[k], h)
            assert rt.get_state() == before
        rows.append(rt.advance(u[k], y[k], TS))
    assert np.array_equal(np.array(rows), np.array([list(r)[1:] for r in ref.tolist()]))


def test_refusal_reasons_name_the_limit(dg):
    rt = dg.runtime
    with pytest.raises(StepSizeError, match="more than 10000 sub-steps per call"):
        rt.advance([0.0], [0.0, 0.0], 1e300)
    with pytest.raises(StepSizeError, match=r"outside the re-discretisation range \[Ts/16, 10000 Ts\]"):
        rt.advance([0.0], [0.0, 0.0], 1e-6)
    with pytest.raises(StepSizeError, match="positive finite number"):
        rt.advance([0.0], [0.0, 0.0], float("nan"))
    parity = Diagnoser(parity_space(pub.ex5_3().discretize(TS), 1), thresholds=1.0).runtime
    with pytest.raises(StepSizeError, match="exists only in discrete time"):
        parity.advance([0.0], [0.0, 0.0], 0.013)
    parity.advance([0.0], [0.0, 0.0], MAX_SUBSTEPS * TS)  # the largest multiple is served


def test_re_discretisation_cache_is_bounded(dg):
    """A step size per call (as a variable-step master would pass) kept every re-discretisation."""
    rt = dg.runtime
    rt.reset()
    for k in range(60):
        rt.advance([0.1], [0.2, 0.3], TS * (1.5 + 0.01 * k))
        assert len(rt._plans) <= CACHE_SIZE


@pytest.mark.parametrize("h", [0.013, 3 * TS, TS], ids=["not-a-multiple", "multiple", "Ts"])
def test_accumulated_step_sizes_are_one_step_size(dg, h):
    """fmpy at an output interval passes step sizes that differ in their last bits; the diagnosis
    must be Diagnoser.run's on the same log (it differed by 65 % when each was a new step)."""
    n = 300
    steps = accumulated_steps(h, n)
    assert len(set(steps.tolist())) > 1  # the premise: the step sizes do differ in their last bits
    t, u, y = signals(n, h)
    ref = dg.run(t, u, y)
    rt = dg.runtime
    rt.reset()
    rows = np.array([rt.advance(u[k], y[k], float(steps[k])) for k in range(n)])
    for j, name in enumerate(rt.names):
        r = ref[name].astype(float)
        # same operations on step sizes 1e-16 apart: the re-discretisation differs by rounding only
        assert np.allclose(rows[:, j], r, rtol=0, atol=1e-12 * max(1.0, np.abs(r).max())), name


def test_steps_within_rounding_of_a_multiple_are_sub_stepped(dg):
    """h = 3 Ts (1 ± 5e-10) is 3 sub-steps with the inputs held: identical to three Ts steps."""
    rt = dg.runtime
    t, u, y = signals(40, 3 * TS)
    rt.reset()
    coarse = [rt.advance(u[k], y[k], 3 * TS * (1 + (-1) ** k * 5e-10)) for k in range(40)]
    rt.reset()
    fine = []
    for k in range(40):
        for _ in range(3):
            out = rt.advance(u[k], y[k], TS)
        fine.append(out)
    assert np.array_equal(np.array(coarse), np.array(fine))


def test_change_of_step_size_s4(dg):
    """S4: the generator state carries over; the evaluation restarts only when the effective
    sample time changes (a multiple of Ts keeps it), and the decision is kept."""
    rt = dg.runtime
    rt.reset()
    t, u, y = signals(30, TS)
    for k in range(20):
        rt.advance(u[k], y[k], TS)
    ring = rt.evaluators[0].get_state()["ring"]
    rt.advance(u[20], y[20], 2 * TS)  # multiple: the window goes on (two more pushes)
    assert rt.evaluators[0].get_state()["ring"]["count"] == ring["count"] and rt._ratio == 1.0
    x = rt.generator.get_state()["x"]
    rt.set_step(0.013)  # other effective sample time: windows restart, x carries over
    assert rt.generator.get_state()["x"] == x
    assert rt.evaluators[0].get_state()["ring"]["count"] == 0
    assert rt.evaluators[0].n == round(7 / 1.3)
    rt.set_step(0.013 * (1 + 1e-12))  # the same step: nothing restarts
    assert rt.h == 0.013


def test_runtime_with_a_re_discretised_plan_round_trips_through_the_fmu_state_codec(dg):
    """The FMU state is the whole runtime object, cache included: encode → decode must give a
    runtime that continues bit for bit (an OrderedDict cache was silently emptied)."""
    from fmu_fdi.fmu.slave_state import decode_state, encode_state

    rt = dg.runtime
    rt.reset()
    t, u, y = signals(60, 0.013)
    for k in range(30):
        rt.advance(u[k], y[k], 0.013)
    copy = decode_state(encode_state({"rt": rt}))["rt"]
    assert copy._plans.keys() == rt._plans.keys()
    a = [rt.advance(u[k], y[k], 0.013) for k in range(30, 60)]
    b = [copy.advance(u[k], y[k], 0.013) for k in range(30, 60)]
    assert a == b


@pytest.mark.parametrize("edit, message", [
    (lambda c: c.update(A=[row + [0.0] for row in c["A"]] + [[0.0] * (len(c["A"]) + 1)],
                        B=c["B"] + [[0.0] * len(c["B"][0])], C=[row + [0.0] for row in c["C"]]), "has order"),
    (lambda c: c["A"][0].__setitem__(0, c["A"][0][0] * (1 + 1e-6)), "discrete.A is not the zero-order hold"),
    (lambda c: c["C"][0].__setitem__(0, -c["C"][0][0]), "discrete.C is not the zero-order hold"),
])
def test_a_continuous_generator_that_is_not_the_discrete_ones_filter_is_refused(dg, edit, message):
    """generator.continuous serves steps of another size with the discrete state carried over, so
    it must be the same filter: its zero-order hold at dt equals generator.discrete (to 1e-8
    relative). Another order, an edited entry (1e-6 relative) or another sign is refused by the
    one validator, before any step could fail in one runtime and not the other."""
    import copy

    from fmu_fdi.designfile import DesignFileError

    assert dg.design["generator"].get("continuous") is not None
    Diagnoser.from_design(dg.design)  # the design as made passes
    bad = copy.deepcopy(dg.design)
    edit(bad["generator"]["continuous"])
    with pytest.raises(DesignFileError, match=message):
        Diagnoser.from_design(bad)
