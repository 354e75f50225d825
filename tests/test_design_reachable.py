"""Issue 22: a design whose thresholds can never be reached is refused by the one validator
(fmu_fdi/runtime/design_check.py), with a message naming the group and the bound.

README's DOS design (rms evaluations) with every threshold at 1e308 was accepted and could never
alarm: an rms evaluation squares the residual, so it is at most sqrt(DBL_MAX) = 1.34e154 (a
larger residual overflows, docs/semantics.md §8). The bound per kind is derived in
``evaluation_max``; here it is checked against the runtime itself and the refusal end to end.
"""
import copy
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from fmu_fdi.cli import main
from fmu_fdi.designfile import DesignFileError, validate_design
from fmu_fdi.runtime.design_check import NORM_EVALUATION_MAX, DesignCheckError
from fmu_fdi.runtime.engine import DiagnoserRuntime

DBL_MAX = sys.float_info.max


@pytest.fixture(scope="module")
def dos(tmp_path_factory):
    from pathlib import Path

    path = tmp_path_factory.mktemp("dos") / "dos.json"
    plant = Path(__file__).parent.parent / "plant_fmus" / "dts200" / "dts200.toml"
    assert main(["design", str(plant), "--method", "dos", "--ts", "1", "--evaluation", "rms:20",
                 "--threshold", "fault-size:1", "--persistence", "3/5", "-o", str(path)]) == 0
    return path, json.loads(path.read_text(encoding="utf-8"))


def _with(design, evaluator=None, threshold=None, groups=None):
    d = copy.deepcopy(design)
    for i, e in enumerate(d["evaluation"]):
        if groups is None or i in groups:
            if evaluator is not None:
                e["evaluator"] = dict(evaluator)
            if threshold is not None:
                e["threshold"] = dict(threshold)
    return d


@pytest.mark.parametrize("value", [1e308, DBL_MAX, 1e155])
def test_a_design_that_can_never_alarm_is_refused(dos, value):
    _, design = dos
    bad = _with(design, threshold={"kind": "fixed", "value": value})
    with pytest.raises(DesignFileError, match=r"evaluation\[0\]\.threshold: fixed threshold .* can never be reached: "
                                              r"a rms evaluation is at most 1\.34e\+154"):
        validate_design(bad)
    with pytest.raises(DesignCheckError, match="can never be reached"):
        DiagnoserRuntime(bad)


def test_one_group_that_can_never_alarm_is_refused_too(dos):
    _, design = dos
    bad = _with(design, threshold={"kind": "adaptive", "a": 1.0, "J0": 1e200}, groups=[2])
    with pytest.raises(DesignFileError, match=r"evaluation\[2\]\.threshold: adaptive threshold 1e\+200 can never"):
        validate_design(bad)


def test_the_cli_refuses_it_in_one_line(dos, tmp_path):
    _, design = dos
    path = tmp_path / "never.json"
    path.write_text(json.dumps(_with(design, threshold={"kind": "fixed", "value": 1e308})), encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "fmu_fdi", "build", str(path), "-o", str(tmp_path / "x.fmu")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode != 0 and "can never be reached" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "x.fmu").exists()


@pytest.mark.parametrize("evaluator, reachable", [
    ({"kind": "rms", "window": 20}, NORM_EVALUATION_MAX),
    ({"kind": "chi2", "window": 3}, 1e308),                        # sums of squares: up to DBL_MAX
    ({"kind": "narendra", "alpha": 0.0, "beta": 1.0, "gamma": 0.5}, 2.0 * NORM_EVALUATION_MAX),
])
def test_every_reachable_threshold_is_accepted(dos, evaluator, reachable):
    _, design = dos
    validate_design(_with(design, evaluator=evaluator, threshold={"kind": "fixed", "value": reachable}))


def test_the_bound_is_what_the_runtime_produces(dos):
    """Independent of the derivation: feed the rms/peak runtime ever larger residuals; the
    largest evaluation it ever reports stays within sqrt(DBL_MAX), and it does reach 1e154."""
    _, design = dos
    for ev in ({"kind": "rms", "window": 1}, {"kind": "peak", "window": 3}, {"kind": "ewrms", "lambda": 0.5}):
        rt = DiagnoserRuntime(_with(design, evaluator=ev, threshold={"kind": "fixed", "value": 1.0}))
        op = design["operating_point"]
        top = 0.0
        for big in np.geomspace(1e150, 1e160, 400):
            out = rt.advance(op["u"], [op["y"][0], op["y"][1] + big, op["y"][2]])
            top = max(top, max(out[rt.n_residuals:rt.n_residuals + rt.n_groups]))
        assert 1e150 < top <= NORM_EVALUATION_MAX and math.isfinite(top), (ev, top)
