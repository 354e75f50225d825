"""Model sets over the operating envelope (issue 19, part 1): one linear model per operating
point of a plant FMU, written as one versioned file with the scheduling signals named.

Judged against the analytic Jacobians of the test FMU (tests/me_fmus.py), computed
independently of the linearisation code."""
import json

import numpy as np
import pytest

from fmu_fdi import FDIModel
from fmu_fdi.identify import model_from_fmu, model_set_from_fmu
from fmu_fdi.cli import main
from fmu_fdi.errors import ModelError
from fmu_fdi.modelset import MODEL_SET_FORMAT, ModelSet, grid_points, parse_grid
from me_fmus import analytic, build_me_fmu, equilibrium


@pytest.fixture(scope="module")
def me_fmu(tmp_path_factory):
    return build_me_fmu(tmp_path_factory.mktemp("me"), "nonlinear", 2, True)


def test_members_are_the_linearisations_at_their_points(me_fmu, tmp_path):
    pts = [{"u1": 0.5}, {"u1": 1.0}, {"u1": 2.0}]
    ms = model_from_fmu(me_fmu, ["u1", "u2"], ["y1", "y2"], at=pts, sensor_faults="all")
    assert isinstance(ms, ModelSet) and ms.schedule == ["u1"] and len(ms) == 3
    assert ms.points[:, 0].tolist() == [0.5, 1.0, 2.0]
    for m, p in zip(ms.members, pts):
        u = [p["u1"], 0.5]  # u2 at its start value 0.5
        x = equilibrium("nonlinear", u)
        _, g, J = analytic("nonlinear", x, u)
        # directional derivatives of the FMU are the analytic ones at the trimmed state; the trim
        # tolerance 1e-9 (relative) bounds the state error, the Jacobian is smooth there
        assert np.allclose(m.A, J[:2, :2], rtol=1e-7, atol=1e-9)
        assert np.allclose(m.Bu, J[:2, 2:], rtol=1e-7, atol=1e-9)
        assert np.allclose(m.y0, g, rtol=1e-7)
        assert m.provenance["requested_point"] == [f"u1={p['u1']!r}"] and m.provenance["set_size"] == 3
    # the set spans a plant whose linearisation changes: the slow pole moves with u1
    poles = [np.sort(np.linalg.eigvals(m.A).real) for m in ms.members]
    assert abs(poles[0][-1] - poles[-1][-1]) > 0.1
    path = ms.to_file(tmp_path / "set.json")
    back = ModelSet.from_file(path)
    assert json.loads(path.read_text())["format"] == MODEL_SET_FORMAT
    assert back.schedule == ms.schedule and back.requested == pts
    for a, b in zip(back.members, ms.members):
        assert np.array_equal(a.A, b.A) and np.array_equal(a.y0, b.y0) and a.provenance == b.provenance


def test_cli_grid_product_path_and_output_schedule(me_fmu, tmp_path, capsys):
    out = tmp_path / "p.json"
    assert main(["model", str(me_fmu), "--at-grid", "u1=0.5:2:4", "u2=0.2:0.8:2", "--sensor-faults", "all",
                 "-o", str(out)]) == 0
    ms = ModelSet.from_file(out)
    assert len(ms) == 8 and ms.schedule == ["u1", "u2"]
    assert sorted(map(tuple, ms.points.tolist())) == [(a, b) for a in (0.5, 1.0, 1.5, 2.0) for b in (0.2, 0.8)]
    assert "member 8/8" in capsys.readouterr().out
    assert main(["model", str(me_fmu), "--at-grid", "u1=0.5:2:4", "u2=0.2:0.8:4", "--grid-mode", "path",
                 "-o", str(out)]) == 0
    assert ModelSet.from_file(out).points.tolist() == [[0.5, 0.2], [1.0, 0.4], [1.5, 0.6000000000000001], [2.0, 0.8]]
    # scheduled on a measured output: the member's place is the steady state y1 the trim found
    assert main(["model", str(me_fmu), "--at-grid", "u1=0.5:2:3", "--schedule-on", "y1", "-o", str(out)]) == 0
    ms = ModelSet.from_file(out)
    y1 = [analytic("nonlinear", equilibrium("nonlinear", [u, 0.5]), [u, 0.5])[1][0] for u in (0.5, 1.25, 2.0)]
    assert ms.schedule == ["y1"] and np.allclose(ms.points[:, 0], y1, rtol=1e-7)


@pytest.mark.parametrize("argv, message", [
    (["--at-grid", "u1=0.5:2"], "NAME=LO:HI:K"),
    (["--at-grid", "u1=1:1:3"], "NAME=LO:HI:K"),
    (["--at-grid", "u1=0.5:2:3", "--schedule-on", "x1"], "not measured"),
    (["--at-grid", "u1=0.5:2:3", "u2=0:1:2", "--grid-mode", "path"], "same K"),
    (["--at-grid", "u1=0.5:2:3", "--at", "u1=1"], "both in --at and --at-grid"),
    (["--at-grid", "u1=0.5:2:3", "--record", "log.csv"], "one operating point"),
])
def test_bad_grids_are_one_line_errors(me_fmu, tmp_path, capsys, argv, message):
    assert main(["model", str(me_fmu), *argv, "-o", str(tmp_path / "s.json")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and not (tmp_path / "s.json").exists()


def test_grid_helpers_and_set_consistency():
    assert parse_grid("Q1=10:30:5")[1].tolist() == [10.0, 15.0, 20.0, 25.0, 30.0]
    assert grid_points([("a", np.array([1.0, 2.0])), ("b", np.array([5.0]))]) == [{"a": 1.0, "b": 5.0},
                                                                                 {"a": 2.0, "b": 5.0}]
    m1 = FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], operating_point={"u": [1.0], "y": [1.0]})
    m2 = FDIModel.from_matrices([[-2.0]], [[1.0]], [[1.0]], operating_point={"u": [1.0], "y": [0.5]})
    with pytest.raises(ModelError, match="same scheduling point"):
        ModelSet([m1, m2], ["u0"])
    assert ModelSet([m1, m2], ["y0"]).points[:, 0].tolist() == [1.0, 0.5]
    with pytest.raises(ModelError, match="point 2 lacks"):
        model_set_from_fmu("none.fmu", at=[{"u1": 1.0, "u2": 0.5}, {"u1": 2.0}])
    m3 = FDIModel.from_matrices([[-2.0]], [[1.0]], [[1.0], [1.0]])
    with pytest.raises(ModelError, match="same signals"):
        ModelSet([m1, m3], ["u0"])
