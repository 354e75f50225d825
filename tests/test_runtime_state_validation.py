"""Issue 22 in the Python runtime (the pythonfmu FMU restores its state through it): a state is
accepted only if a run of the design can produce it (docs/semantics.md §10), the same rules as
the native runtime's. Each case edits one item of a state taken from a real run, expects a
ValueError naming it, and the runtime exactly as it was; the states of real runs (with
overflows, invalid samples and step-size changes) are all accepted.
"""
import copy
import math

import numpy as np
import pytest

from fmu_fdi.runtime.engine import DiagnoserRuntime
from native_designs import feature_designs, rls_designs
from native_scenario import make_scenario


@pytest.fixture(scope="module")
def designs():
    out = dict(feature_designs())
    out.update(rls_designs())
    return out


@pytest.fixture(scope="module")
def runs(designs):
    """name -> (runtime after the run, every state it passed)."""
    return {name: _run(d) for name, d in designs.items()}


def _run(design, n=200, seed=5):
    """A runtime after n scenario calls (NaN bursts, overflows, odd steps), and every state it passed."""
    rt = DiagnoserRuntime(design)
    Ts = float(design["generator"]["dt"])
    states = []
    for op in make_scenario(design, np.random.default_rng(seed), n, [Ts, 2 * Ts, 0.5 * Ts]):
        if op[0] == "step":
            try:
                rt.advance(op[1], op[2], op[3])
            except ValueError:  # a refused step size changes nothing
                pass
            states.append(rt.get_state())
    return rt, states


@pytest.mark.parametrize("name", ["rms_peak_ewrms_adaptive_structure", "narendra_norm_majorant_direction",
                                  "chi2_cusum_glr_none", "norm_direction_structure_latch", "rls_periodic",
                                  "rls_floor"])
def test_every_state_of_a_run_is_accepted(designs, runs, name):
    rt, states = runs[name]
    fresh = DiagnoserRuntime(designs[name])
    for s in states[::7]:
        fresh.set_state(s)
        assert fresh.get_state() == s


def _refused(rt, state, match):
    before = rt.get_state()
    with pytest.raises(ValueError, match=match):
        rt.set_state(state)
    assert rt.get_state() == before


def test_peak_counter_beyond_2_53_and_a_forged_deque_are_refused(runs):
    """k = 2^62 made the loop that drops old samples endless in C (k and k - N the same double);
    in Python it emptied the deque and raised IndexError inside the step."""
    rt, _ = runs["rms_peak_ewrms_adaptive_structure"]
    g = [e.kind for e in rt.evaluators].index("peak")
    for edit in (lambda p: p.update(k=2 ** 62), lambda p: p.update(k=p["k"] + 5),
                 lambda p: p["deque"].reverse(), lambda p: p["deque"][0].__setitem__(0, 0.5),
                 lambda p: p["deque"].append([float(p["k"]), 0.0])):
        s = rt.get_state()
        edit(s["evaluators"][g])
        _refused(rt, s, "peak state")


@pytest.mark.parametrize("what, edit, match", [
    ("isolated_fault 1e10", lambda s, rt: s["outputs"].__setitem__(-3, 1e10), "outputs do not fit"),
    ("an alarm output 0.37", lambda s, rt: s["outputs"].__setitem__(rt.n_residuals + 2 * rt.n_groups, 0.37),
     "outputs do not fit"),
    ("input_invalid 2", lambda s, rt: s["outputs"].__setitem__(-2, 2.0), "outputs do not fit"),
    ("a negative evaluation", lambda s, rt: s["outputs"].__setitem__(rt.n_residuals, -1.0), "outputs do not fit"),
    ("numeric resets > samples", lambda s, rt: s.update(n_numeric_resets=s["n_samples"] + 1), "sample counters"),
    ("samples 2^60", lambda s, rt: s.update(n_samples=2 ** 60), "sample counters"),
    ("decision isolated 7", lambda s, rt: s["decision"].update(isolated=7), "decision state"),
    ("alarm against its raw tests", lambda s, rt: s["decision"]["alarms"].__setitem__(
        0, not s["decision"]["alarms"][0]), "decision state"),
    ("ring count/index", lambda s, rt: s["evaluators"][0]["ring"].update(i=(s["evaluators"][0]["ring"]["i"] + 1)
                                                                           % len(s["evaluators"][0]["ring"]["buf"]),
                                                                           count=1), "ring state"),
    ("rms value", lambda s, rt: s["evaluators"][0].update(value=s["evaluators"][0]["value"] + 1.0), "does not fit"),
    ("adaptive threshold value", lambda s, rt: s["thresholds"][1].update(value=s["thresholds"][1]["value"] * 2 + 1),
     "does not fit its evaluator"),
])
def test_a_state_no_run_can_produce_is_refused(runs, what, edit, match):
    rt, _ = runs["rms_peak_ewrms_adaptive_structure"]
    s = copy.deepcopy(rt.get_state())
    edit(s, rt)
    _refused(rt, s, match)


@pytest.mark.parametrize("field, value", [("updates", 3), ("resets", 10 ** 6), ("k", 2 ** 60)])
def test_rls_counts_are_bound_to_the_sample_counter(runs, field, value):
    rt, _ = runs["rls_periodic"]
    s = rt.get_state()
    if field == "k":
        s["generator"]["k"] = value
    else:
        s["generator"]["estimators"][0][field] = value
    _refused(rt, s, "rls state")
    s = rt.get_state()
    P = np.array(s["generator"]["estimators"][0]["P"])
    P[0, 1] = math.nextafter(P[0, 1], math.inf)  # no longer exactly symmetric
    s["generator"]["estimators"][0]["P"] = P.tolist()
    _refused(rt, s, "not symmetric")
