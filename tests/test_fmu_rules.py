"""Issues 21 and 22: one rule in both diagnostic FMUs (native FMI 2.0 and pythonfmu), run through
the same fmpy contract (tests/hosts/scenarios.py, a process of its own):

- ``threshold_scale`` −1, NaN, +Inf are refused, the scale kept; 0 and 2 are accepted
  (docs/semantics.md §6). The native FMU answers fmi2Error; the pythonfmu FMU, which cannot,
  logs the error and discards the following doSteps until a valid value is set;
- a non-finite time (``doStep(t = NaN)``, ``t + h`` overflowing, ``startTime = ±Inf``) is refused
  and changes nothing (§9), so the FMU keeps accepting its own saved state;
- both log the same warnings under the same categories (step size changed, invalid input,
  overflow), with no ``t=`` prefix of their own (a host adds the time: "at t=0: t=0: ..." was
  doubled).
"""
import numpy as np
import pytest

from fmu_fdi import Diagnoser, FDIModel, build_fmu, nullspace_design
from fmu_fdi.faults import sensor_fault
from test_diagnostic_fmu import _errors, contract  # the fmpy contract runner (a process of its own)

H = 0.1
ROW = {"u": 0.3, "y": 0.1}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    m = FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], u_names=["u"], y_names=["y"],
                               faults=[sensor_fault("fy", "y")])
    dg = Diagnoser(nullspace_design(m), Ts=H, thresholds=0.05)
    folder = tmp_path_factory.mktemp("rules")
    return {"native": build_fmu(dg, folder / "native.fmu", target="native"),
            "python": build_fmu(dg, folder / "python.fmu")}


def _both(tmp_path, fmus, actions):
    return {kind: contract(tmp_path, {"f": fmus[kind]}, actions) for kind in ("native", "python")}


INIT = [["instantiate", "a", "f"], ["setup", "a"], ["enter", "a"], ["exit", "a"]]


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_a_bad_threshold_scale_is_refused_by_both(tmp_path, fmus, bad):
    actions = INIT + [["scale", "a", 2.0], ["step", "a", H, ROW], ["scale", "a", bad], ["step", "a", H, ROW],
                      ["scale", "a", 0.0], ["step", "a", H, ROW], ["scale", "a", 2.0], ["step", "a", H, ROW]]
    for kind, (done, names) in _both(tmp_path, fmus, actions).items():
        thr = names.index("threshold_1")
        ok2, set_bad, after_bad, set0, ok0, set2, ok2b = done[5:12]
        assert "threshold_scale" in _errors(set_bad), (kind, set_bad)
        if kind == "native":
            assert set_bad["status"] == 3 and after_bad["status"] == 0  # Error; the instance goes on
            assert after_bad["values"][thr] == ok2["values"][thr]        # at the scale it kept (2)
        else:  # pythonfmu cannot return Error from a setter: the next step is discarded, with the reason
            assert set_bad["status"] == 0 and after_bad["status"] == 2 and "threshold_scale" in _errors(after_bad)
        assert set0["status"] == ok0["status"] == 0 and ok0["values"][thr] == 0.0  # 0 is a valid scale
        assert set2["status"] == ok2b["status"] == 0 and ok2b["values"][thr] == ok2["values"][thr] == 2 * 0.05


def test_non_finite_times_are_refused_and_the_saved_state_stays_usable(tmp_path, fmus):
    actions = [["instantiate", "a", "f"], ["setup", "a", float("inf")], ["setup", "a", 0.0], ["enter", "a"],
               ["exit", "a"], ["step", "a", H, ROW],
               ["step_at", "a", float("nan"), H, ROW], ["step_at", "a", 1e308, 1e308, ROW],
               ["step", "a", H, ROW], ["get_state", "a", "s"], ["serialize", "a", "b", "s"],
               ["deserialize", "a", "s2", "b"], ["set_state", "a", "s2"], ["step", "a", H, ROW]]
    for kind, (done, _) in _both(tmp_path, fmus, actions).items():
        _, setup_inf, setup0, _, _, first, nan_t, overflow_t, after, *_, set_, last = done
        assert "startTime" in _errors(setup_inf) and setup0["status"] == 0, kind
        assert setup_inf["status"] == (3 if kind == "native" else 0), kind
        for refused in (nan_t, overflow_t):
            assert refused["status"] == (3 if kind == "native" else 2), (kind, refused)
            assert "the time must be a finite number" in _errors(refused), (kind, refused)
            assert refused["values"] == first["values"]  # nothing changed
        # the FMU takes its own saved state back (a NaN time used to be stored, then refused)
        assert after["status"] == 0 and set_["status"] == 0 and not _errors(set_), (kind, set_)
        assert last["status"] == 0 and not _errors(last), (kind, last)


def test_both_fmus_log_the_same_warnings_in_the_same_categories(tmp_path, fmus):
    """Step size changed (a continuous design at Ts/2 re-discretises and restarts the evaluation),
    an invalid (NaN) sample, an overflowing one (1e300, §8)."""
    actions = INIT + [["step", "a", H, ROW], ["step", "a", H / 2, ROW], ["step", "a", H / 2, {"u": float("nan")}],
                      ["step", "a", H / 2, {"u": 0.3, "y": 1e300}], ["step", "a", H / 2, {"u": 0.3, "y": 0.1}]]
    logs = {}
    for kind, (done, _) in _both(tmp_path, fmus, actions).items():
        assert [a["status"] for a in done[4:]] == [0] * 5, kind
        logs[kind] = [[(s, c, m) for s, c, m in a["log"] if s == 1] for a in done[4:]]  # warnings
    assert logs["native"] == logs["python"], logs
    changed, invalid, overflow = logs["native"][1:4]
    assert [c for _, c, _ in changed] == ["logStatusWarning"] and "step size changed from 0.1 s to 0.05 s" in \
        changed[0][2]
    assert [c for _, c, _ in invalid] == ["logFdiInput"] and [c for _, c, _ in overflow] == ["logFdiNumeric"]
    assert not any(m.startswith("t=") for a in logs["native"] for _, _, m in a)  # the host adds the time


def test_isolated_fault_reaches_fmi2_get_integer_in_range(tmp_path, fmus):
    """Every Integer output is an int in -1..n_faults (a state's isolated_fault slot of 1e10 used to
    reach fmi2GetInteger as INT_MIN: now such a state is refused and the getter clamps)."""
    actions = INIT + [["step", "a", H, {"u": 0.3, "y": 5.0}], ["step", "a", H, ROW]]
    for kind, (done, names) in _both(tmp_path, fmus, actions).items():
        iso = names.index("isolated_fault")
        values = [a["values"][iso] for a in done[4:]]
        assert all(v in (-1.0, 0.0, 1.0) for v in values) and np.isfinite(values).all(), (kind, values)
