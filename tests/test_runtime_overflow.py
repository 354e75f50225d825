"""Issue 21, first bullet: a sensor that fails to a huge finite value is detected (docs/semantics.md §8).

README's DOS design (``fmu-fdi design dts200.toml --method dos --ts 1 --evaluation rms:20
--threshold fault-size:1 --persistence 3/5``) at the operating point with 1 mm sensor noise, a
bias on h2 from sample 200. Before §8 counted an overflow as evidence, a bias of 1e155 or more
overflowed the square of the residual on every sample: ``numeric_reset`` every sample and no
alarm, ever. Now an overflowed sub-sample fires the raw test of the groups whose evaluation
overflowed, and flags the sample ``input_invalid``: with persistence 3/5 the alarm must rise at
the third biased sample, in the Python runtime and in the C runtime alike.
"""
import numpy as np
import pytest

from fmu_fdi.cli import main
from fmu_fdi.runtime.engine import DiagnoserRuntime
from native_runtime import CRuntime, compile_runtime

PLANT = "plant_fmus/dts200/dts200.toml"
N, K0 = 260, 200
FINITE_BIASES = [1.5, 1e3, 1e153]                                    # squares stay finite: data
OVERFLOWING = [1e155, 1e160, 1e200, 1e300, 1.7e308, -1e200, -1.7e308]  # squares overflow


@pytest.fixture(scope="module")
def dos(tmp_path_factory):
    import json
    from pathlib import Path

    folder = tmp_path_factory.mktemp("dos")
    path = folder / "dos.json"
    root = Path(__file__).parent.parent
    assert main(["design", str(root / PLANT), "--method", "dos", "--ts", "1", "--evaluation", "rms:20",
                 "--threshold", "fault-size:1", "--persistence", "3/5", "-o", str(path)]) == 0
    design = json.loads(path.read_text(encoding="utf-8"))
    return design, compile_runtime(design, folder / "c")


def _record(design, bias):
    rng = np.random.default_rng(21)
    op = design["operating_point"]
    u = np.tile(op["u"], (N, 1))
    y = np.asarray(op["y"]) + 1e-3 * rng.standard_normal((N, 3))
    y[K0:, 1] += bias
    return u, y


def _both(design, lib, u, y):
    py, c = DiagnoserRuntime(design), CRuntime(lib)
    rows, crows = [], []
    for uk, yk in zip(u, y):
        rows.append(py.advance(uk, yk))
        st, out, why = c.advance(uk, yk, 1.0)
        assert st == 0, why
        crows.append(out)
    return py.names, np.array(rows), np.array(crows)


@pytest.mark.parametrize("bias", FINITE_BIASES + OVERFLOWING)
def test_a_sensor_failing_to_a_huge_value_is_detected_in_both_runtimes(dos, bias):
    design, lib = dos
    names, py, c = _both(design, lib, *_record(design, bias))
    col = {n: i for i, n in enumerate(names)}
    fd, inv, nres = py[:, col["fault_detected"]], py[:, col["input_invalid"]], py[:, col["numeric_reset"]]
    assert not fd[:K0].any() and not inv[:K0].any() and not nres[:K0].any()  # fault-free: silent
    # persistence 3/5: the third firing sample is K0 + 2 at the earliest (an overflow fires at
    # once; 1.5 m needs the 20-sample rms to grow past 0.43 first); the bias stays, so does the alarm
    first = np.flatnonzero(fd)[0]
    assert (first == K0 + 2 if bias in OVERFLOWING else K0 + 2 <= first <= K0 + 4) and fd[first:].all(), first
    if bias in OVERFLOWING:
        assert inv[K0:].all() and nres[K0:].all()  # said in the outputs: an unusable sample ...
        for name in names:  # ... whose real outputs hold their last finite values
            assert np.all(np.isfinite(py[:, col[name]])), name
    else:
        assert not inv.any() and not nres.any()
    # the C runtime: the same decisions exactly, the same numbers to 1e-12 (docs/semantics.md §1)
    for name in names:
        i = col[name]
        if name.startswith(("residual", "evaluation", "threshold")):
            scale = np.maximum(1.0, np.abs(py[:, i]))
            assert np.all(np.abs(py[:, i] - c[:, i]) <= 1e-12 * scale), name
        else:
            assert np.array_equal(py[:, i], c[:, i]), name


def _identity_design(isolation):
    """r = y (two sensors, a state that stays 0), one norm group per residual, threshold 1."""
    dec = {"persistence": [1, 1], "isolation": isolation}
    if isolation == "structure":
        dec["structure"] = [[1, 0], [0, 1]]
    else:
        dec["directions"] = [[1.0, 0.0], [0.0, 1.0]]
    return {"format": "fmu-fdi-design/1", "name": "identity", "signals": {"u": [], "y": ["y1", "y2"]},
            "faults": [{"name": "s1"}, {"name": "s2"}],
            "generator": {"method": "synthetic", "dt": 1.0, "residual_names": ["r1", "r2"], "groups": [[0], [1]],
                          "discrete": {"kind": "lti", "A": [[0.0]], "B": [[0.0, 0.0]], "C": [[0.0], [0.0]],
                                       "D": [[1.0, 0.0], [0.0, 1.0]]}},
            "evaluation": [{"evaluator": {"kind": "norm"}, "threshold": {"kind": "fixed", "value": 1.0}}] * 2,
            "decision": dec}


@pytest.mark.parametrize("isolation, isolated", [("structure", 2), ("direction", -1)])
def test_an_overflow_fires_only_the_groups_it_reaches(tmp_path, isolation, isolated):
    """y2 = 1e200: r2's square overflows, r1 = 0.5 is judged on its own evaluation (0.5 < 1).
    Structure isolation names the fault of the pattern [0, 1]; the direction of a residual that
    overflowed is unknown (-1). The next ordinary sample clears the alarm (persistence 1/1)."""
    design = _identity_design(isolation)
    y = np.array([[0.5, 0.2], [0.5, 1e200], [0.5, 0.2]])
    names, py, c = _both(design, compile_runtime(design, tmp_path), np.zeros((3, 0)), y)
    col = {n: i for i, n in enumerate(names)}
    assert np.array_equal(py, c)
    assert py[1, col["alarm_1"]] == 0 and py[1, col["alarm_2"]] == 1 and py[1, col["isolated_fault"]] == isolated
    assert py[1, col["input_invalid"]] == 1 and py[1, col["numeric_reset"]] == 1
    assert py[1, col["evaluation_2"]] == py[0, col["evaluation_2"]] == 0.2  # held, finite
    assert not py[2, col["fault_detected"]] and not py[2, col["input_invalid"]]
