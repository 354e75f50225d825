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
    # (--noise none, the identification's explicit "no noise inputs", is accepted on a grid too)
    assert main(["model", str(me_fmu), "--at-grid", "u1=0.5:2:3", "--schedule-on", "y1", "--noise", "none",
                 "-o", str(out)]) == 0
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
    # (a progress note "still working after 10 s" may precede the error on a loaded machine)
    err = "".join(ln for ln in capsys.readouterr().err.splitlines(True) if not ln.startswith("fmu-fdi: still working"))
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


def test_settle_noise_is_measured_about_a_settling_transient():
    """A member identified away from where the FMU starts settles from there: a noise-free run's
    settle phase still holds the tail of that transient, which is no noise (issue 19: members 2-5
    of the DTS200 envelope gained an innovation noise model from it, and their designs, thresholds
    1/30 of member 1's, alarmed at the first switch)."""
    from fmu_fdi.identify.validation import settle_noise_std

    k = np.arange(1250.0)
    rng = np.random.default_rng(19)
    # two modes (z = 0.996 ~ tau 500 s at ts 2 s, z = 0.9), no noise: the plain std is the transient's
    transient = 40.0 + 0.03 * 0.996 ** k + 0.01 * 0.9 ** k
    z = np.column_stack([transient, 40.0 + 0.0 * k])
    assert transient.std() > 1e-3
    # an order-10 recursion predicts a 2-mode transient exactly: round-off, far below the 1e-9 of the
    # output level that counts as noise (fmu_model: noise above round-off)
    assert np.all(settle_noise_std(z) < 1e-9 * 40.0)
    # white noise dominating: its plain std (computed here by numpy), whatever the recursion finds
    # (to the round-off of the offset 40: 40 eps / 0.1 ~ 1e-13 relative)
    white = rng.standard_normal((1250, 2)) * 0.1
    assert np.allclose(settle_noise_std(40.0 + white), white.std(axis=0), rtol=1e-12, atol=0)
    # coloured noise (AR(1), pole 0.95): its one-step error is sqrt(1 - 0.95²) = 31 % of its std, so
    # the noise dominates and its size is the plain std (the innovation would understate it 3-fold)
    from scipy.signal import lfilter

    coloured = lfilter([1.0], [1.0, -0.95], rng.standard_normal(1250)) * 0.01
    assert np.isclose(settle_noise_std(coloured[:, None])[0], coloured.std(), rtol=1e-12, atol=0)
    # a transient with white noise 1e-5 about it: the noise, not the transient's spread. The least
    # squares recursion's error is at least the innovation σ (less the (p+1)/N in-sample fit, which
    # the N - 2p - 1 degrees of freedom restore; ± 2 % sampling) and at most that of the exact 2-mode
    # recursion a = (λ1 + λ2, -λ1 λ2) = (1.896, -0.8964), σ sqrt(1 + 1.896² + 0.8964²) = 2.33 σ
    sigma = 1e-5
    noisy = transient + sigma * rng.standard_normal(1250)
    est = settle_noise_std(noisy[:, None])[0]
    assert 0.9 * sigma < est < 2.5 * sigma, est


def test_members_with_and_without_a_noise_model_are_refused(monkeypatch):
    """The default noise='auto' decides per point; a set whose members disagree would get designs of
    different kinds (issue 19's DTS200 regression), so it is refused naming them."""
    from fmu_fdi.identify import envelope

    def fake(path, inputs, outputs, disturbances=(), *, at, **options):
        noisy = at["u1"] > 1.0  # member 2 "found" noise, member 1 did not
        kw = {"Bw": [[0.1]], "Dw": [[0.2]]} if noisy else {}
        return FDIModel.from_matrices([[-1.0]], [[1.0]], [[1.0]], operating_point={"u": [at["u1"]], "y": [1.0]},
                                      u_names=["u1"], provenance={}, **kw)

    monkeypatch.setattr(envelope.fmu_model, "model_from_fmu", fake)
    with pytest.raises(ModelError, match=r"members \[2\] were identified with a noise model and members \[1\]"):
        model_set_from_fmu("plant.fmu", at=[{"u1": 1.0}, {"u1": 2.0}])
    monkeypatch.setattr(envelope.fmu_model, "model_from_fmu",
                        lambda *a, at, **k: fake(*a, at={"u1": at["u1"] + 5.0}, **k))
    assert len(model_set_from_fmu("plant.fmu", at=[{"u1": 1.0}, {"u1": 2.0}])) == 2  # all with one: accepted


@pytest.mark.slow  # one designed identification of the native DTS200 (~10 s of CPU)
def test_a_member_away_from_the_start_is_identified_at_its_steady_state(tmp_path):
    from scipy.optimize import fsolve

    import plant_fmus
    from plant_fmus.dts200 import dts200_physics as phys
    from plant_fmus.native_build import build_native

    nominal = FDIModel.from_file(plant_fmus.model_path("dts200"))
    q = nominal.u0 * np.array([1.2, 0.8])
    # the steady state by Powell's method on the plant's own equations (the FMU integrates them)
    h = fsolve(lambda x: phys.derivative(x, q), nominal.y0, xtol=1e-13)
    m = model_from_fmu(build_native("dts200", tmp_path), ["Q1", "Q2"], ["h1", "h2", "h3"],
                       at={"Q1": float(q[0]), "Q2": float(q[1]), "noise_enable": False}, method="identify")
    # settled within 1 % of the way from the start (|y0_start - h| ~ 2-5 cm): 0.05 cm
    assert np.max(np.abs(m.y0 - h)) < 0.05, (m.y0, h)
