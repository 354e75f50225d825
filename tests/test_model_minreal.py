"""Minimal realisation where models are built (issue 13, item 2): the ``minimal`` /
``minreal_tol`` options of the constructors, model files, model-set interconnections and
the command line, with a relative tolerance and a record of what was removed.

The test plant has a mode (s = -3) that u reaches through 1e-10 next to entries of size 1:
kept by the default tolerance n²·eps ≈ 2e-15 and removed by 1e-8 (Varga's relative rank
decision on the staircase of the data scaled to unit norm).
"""
import json

import numpy as np
import pytest

from fmu_fdi import FDIModel, ModelError, actuator_fault, component_fault, parametric_fault, sensor_fault
from fmu_fdi.identify import model_from_fmu
from fmu_fdi.lti import LTI
from fmu_fdi.modelset import series

WEAK = 1e-10
POINTS = np.array([0.05, 0.7, 4.0, 30.0])


def _plant(scale_b=1.0, scale_c=1.0, scale_a=1.0, **kw):
    A = scale_a * np.array([[-1.0, 0.2, 0.0], [0.0, -2.0, 0.0], [0.0, 0.0, -3.0]])
    Bu = scale_b * np.array([[1.0, 0.0], [0.5, 1.0], [WEAK, 0.0]])
    C = scale_c * np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    return FDIModel.from_matrices(A, Bu, C, u_names=["u1", "u2"], y_names=["y1", "y2"],
                                  faults=[actuator_fault("fa", "u2"), sensor_fault("fs", "y1"),
                                          component_fault("fc", [[1.0], [0.0], [0.0]])], **kw)


def _gap(m1, m2):
    """Largest difference of the frequency responses [u d w f] -> y over POINTS."""
    return float(np.max(np.abs(m1.lti().freqresp(POINTS) - m2.lti().freqresp(POINTS))))


def test_weak_mode_kept_by_default_and_removed_by_tolerance(caplog):
    full = _plant()
    assert full.n == 3 and full.reduction is None and "minreal_order" not in full.provenance
    kept = _plant(minimal=True)
    assert kept.n == 3 and kept.provenance["minreal_order"] == [3, 3]
    with caplog.at_level("INFO", logger="fmu_fdi"):
        cut = _plant(minreal_tol=1e-8)
    assert cut.n == 2 and cut.reduction == (3, 2, 1e-8)
    assert cut.provenance["minreal_order"] == [3, 2] and cut.provenance["minreal_tol_used"] == 1e-8
    assert "removed 1 of 3 states" in caplog.text
    assert sorted(np.linalg.eigvals(cut.A).real) == pytest.approx([-2.0, -1.0], rel=1e-12)
    # the removed mode carried |WEAK * c / (jw + 3)| <= WEAK / 3 * ||c||: the maps barely change
    assert _gap(full, cut) <= WEAK
    assert _gap(full, kept) <= 1e-13  # orthogonal transformation only: rounding of O(1) data
    # every fault still acts as it did (actuator and component columns transformed with x)
    assert cut.fault_names == ["fa", "fs", "fc"] and cut.fault("fa").kind == "actuator"


def test_tolerance_is_relative_to_the_data():
    # states, inputs and outputs in other units (B x 1e6, C x 1e-4, time x 1e3): same decisions
    ref = _plant(minreal_tol=1e-8)
    for kw in ({"scale_b": 1e6}, {"scale_c": 1e-4}, {"scale_a": 1e3, "scale_b": 1e3}):
        assert _plant(minreal_tol=1e-8, **kw).n == ref.n == 2
        assert _plant(minimal=True, **kw).n == 3


@pytest.mark.parametrize("kw, message", [
    ({"minreal_tol": -1e-8}, "minreal_tol must be in [0, 1), got -1e-08"),
    ({"minreal_tol": float("nan")}, "minreal_tol must be a finite number, got nan"),
    ({"minreal_tol": "1e-8"}, "minreal_tol must be a number, got the string"),
    ({"minreal_tol": 1.0}, "minreal_tol must be in [0, 1)"),
    ({"minimal": "yes"}, "minimal must be true or false"),
    ({"minimal": False, "minreal_tol": 1e-8}, "minreal_tol = 1e-08 is given but minimal is false"),
])
def test_bad_options_refused_in_one_line(kw, message):
    with pytest.raises(ModelError) as exc:
        _plant(**kw)
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_parametric_fault_refuses_reduction():
    with pytest.raises(ModelError, match="parametric fault.*'fp'.*act on the full state"):
        FDIModel.from_matrices(-np.eye(2), [[1.0], [0.0]], [[1.0, 0.0]],
                               faults=[parametric_fault("fp", dA=[[0.1, 0.0], [0.0, 0.0]])], minimal=True)


def test_model_file_keys(tmp_path):
    d = _plant().to_dict()
    assert "minimal" not in d and "minreal_tol" not in d
    old = tmp_path / "old.json"
    old.write_text(json.dumps(d))
    assert FDIModel.from_file(old).n == 3  # files without the keys read as before
    assert FDIModel.from_file(old, minreal_tol=1e-8).n == 2
    new = tmp_path / "new.json"
    new.write_text(json.dumps({**d, "minreal_tol": 1e-8}))
    m = FDIModel.from_file(new)
    assert m.n == 2 and FDIModel.from_file(new, minimal=False).n == 3  # arguments override the file
    # written back: reduced matrices, the record in provenance, no key that would reduce again
    back = FDIModel.from_file(m.to_file(tmp_path / "back.toml"))
    assert back.n == 2 and back.reduction is None and back.provenance["minreal_order"] == [3, 2]
    assert _gap(back, m) == 0.0
    for value, message in (("-1", "minreal_tol must be in [0, 1), got -1.0"),
                           ("NaN", "minreal_tol must be a finite number, got nan"),
                           ('"1e-8"', "minreal_tol must be a number, got the string")):
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps(d)[:-1] + f', "minreal_tol": {value}}}')
        with pytest.raises(ModelError) as exc:
            FDIModel.from_file(bad)
        assert str(exc.value).startswith(f"{bad}: {message}")


def test_series_with_redundant_actuator_state_is_reduced():
    m = _plant()
    # actuator model with a second state that drives nothing the plant sees
    P = LTI(np.diag([-10.0, -20.0, -5.0]), np.array([[10.0, 0.0], [0.0, 20.0], [1.0, 1.0]]),
            np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), np.zeros((2, 2)))
    full = series(m, P)
    red = m.series(P, minimal=True)
    assert (full.n, red.n) == (6, 5) and red.reduction[:2] == (6, 5)
    assert _gap(full, red) <= 1e-13  # exactly unobservable: only rounding of O(10) data


def test_cli_minreal_options(tmp_path, capsys):
    from test_cli import assert_one_line_error, run_main

    path = _plant().to_file(tmp_path / "plant.toml")
    code, out, err = run_main(capsys, "analyze", path, "--minreal-tol", "1e-8")
    assert code == 0, err
    assert "minimal realisation removed 1 of 3 states (relative tolerance 1e-08)" in out and "n=2" in out
    code, out, _ = run_main(capsys, "analyze", path, "--minimal")
    assert code == 0 and "removed 0 of 3 states" in out and "n=3" in out
    for value, fragment in (("nan", "minreal_tol must be a finite number"), ("-1e-8", "must be in [0, 1)"),
                            ("abc", "invalid float value")):
        assert_one_line_error(*run_main(capsys, "analyze", path, f"--minreal-tol={value}")[::2], fragment)


def test_from_fmu_checks_the_option_before_the_fmu(tmp_path):
    with pytest.raises(ModelError, match="minreal_tol must be a number, got the string"):
        model_from_fmu(tmp_path / "absent.fmu", minreal_tol="1e-8")
