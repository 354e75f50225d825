"""FDIModel: constructors, files, validation and the parametric-fault transformation."""
import json

import control as ct
import numpy as np
import pytest

import published as pub
from fmu_fdi import (FDIModel, ModelError, actuator_fault, component_fault, parametric_fault, sensor_fault)


def tanks():
    return pub.three_tank_like()


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_file_round_trip_is_exact(tmp_path, suffix):
    m = tanks()
    m2 = FDIModel.from_matrices(m.A, m.Bu, m.C, Bd=m.Bd, u_names=m.u_names, y_names=m.y_names, d_names=m.d_names,
                                units={"h1": "cm"}, operating_point={"u": [21.37, 53.8], "y": [41, 32, 36.6]},
                                faults=m.faults + [component_fault("leak1", [[-0.01], [0], [0]]),
                                                   parametric_fault("clog", dA=0.1 * np.eye(3))], name="t")
    path = m2.to_file(tmp_path / f"m{suffix}")
    m3 = FDIModel.from_file(path)
    for key in ("A", "Bu", "C", "Du", "Bd", "Dd", "Bf", "Df", "u0", "y0"):
        assert np.array_equal(getattr(m2, key), getattr(m3, key)), key
    assert m3.fault_names == m2.fault_names and m3.units == {"h1": "cm"}


def test_from_control_groups_by_name_and_index():
    G = pub.tfm([[pub.GU[0], 1 / (pub.s + 2), 1], [pub.GU[1], 0, 0]], ["u", "d", "f"])
    m = FDIModel.from_control(G, u=["u"], d=[1], f=["f"], faults=[sensor_fault("s2", "y2")])
    assert m.u_names == ["u"] and m.d_names == ["d"] and m.fault_names == ["f", "s2"]
    # the model reproduces the transfer matrix it came from
    w = [0.0, 0.7, 5.0]
    H = ct.frequency_response(G, w)
    for k, om in enumerate(w):
        assert np.allclose(m.lti("u", "d", "f")[:, [0, 1, 2]].freqresp([om])[0], H.complex[:, :, k], atol=1e-12)
    with pytest.raises(ModelError, match="in no group"):
        FDIModel.from_control(G, u=["u"], d=["d"])
    with pytest.raises(ModelError, match="assigned to both"):
        FDIModel.from_control(G, u=["u"], d=["u"])
    with pytest.raises(ModelError, match="not an input of the system"):
        FDIModel.from_control(G, u=["nope"], ignore=["d", "f", "u"])


@pytest.mark.parametrize("kwargs, message", [
    (dict(A=[[1.0, 0.0]]), "A must be square"),
    (dict(C=[[1.0, 0.0]]), "C must have 3 columns"),
    (dict(A=[[np.nan, 0, 0], [0, 1, 0], [0, 0, 1]]), "A contains NaN or Inf"),
    (dict(dt=-1), "dt must be 0"),
    (dict(dt="x"), "dt must be a number"),
    (dict(u_names=["a", "a"]), "used twice"),
    (dict(y_names=["h1", "h2"]), "2 names given for y"),
    (dict(faults=[sensor_fault("s", "nope")]), "refers to output 'nope'"),
    (dict(faults=[actuator_fault("act", "nope")]), "refers to input 'nope'"),
    (dict(faults=[sensor_fault("s", "h1"), sensor_fault("s", "h2")]), "fault name 's' is already used"),
    (dict(faults=[component_fault("c", [[1.0], [2.0]])]), "Bf must have 3 rows"),
    (dict(faults=[component_fault("c", np.zeros((3, 1)))]), "both zero"),
    (dict(units={"zz": "cm"}), "unknown signal 'zz'"),
    (dict(u_names=["1bad", "b"]), "not valid"),
])
def test_validation_names_the_offending_item(kwargs, message):
    base = dict(A=np.diag([-1.0, -2, -3]), Bu=np.ones((3, 2)), C=np.eye(3), u_names=["a", "b"],
                y_names=["h1", "h2", "h3"])
    base.update(kwargs)
    with pytest.raises(ModelError, match=message):
        FDIModel.from_matrices(**base)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(format="fmu-fdi-model/3"), "unsupported format"),
    (lambda d: d.pop("format"), "missing key 'format'"),
    (lambda d: d.update(colour="red"), "unknown keys"),
    (lambda d: d["matrices"].update(Bx=[[1]]), "unknown matrices"),
    (lambda d: d["matrices"].pop("A"), "matrix A is required"),
    (lambda d: d["faults"].append({"name": "f", "kind": "sensor"}), "needs 'output'"),
    (lambda d: d["faults"].append({"name": "f", "kind": "magic"}), "kind must be one of"),
    (lambda d: d["faults"].append({"name": "f", "kind": "sensor", "output": "h1", "gain": 2}), "unknown keys"),
])
def test_malformed_model_files(tmp_path, edit, message):
    d = tanks().to_dict()
    edit(d)
    path = tmp_path / "m.json"
    path.write_text(json.dumps(d))
    with pytest.raises(ModelError, match=message):
        FDIModel.from_file(path)


def test_unreadable_and_unparsable_files(tmp_path):
    with pytest.raises(ModelError, match="cannot read model file"):
        FDIModel.from_file(tmp_path / "missing.toml")
    (tmp_path / "x.toml").write_text("this is = = not toml")
    with pytest.raises(ModelError, match="not valid TOML"):
        FDIModel.from_file(tmp_path / "x.toml")
    (tmp_path / "x.yaml").write_text("a: 1")
    with pytest.raises(ModelError, match=r"end in \.json or \.toml"):
        FDIModel.from_file(tmp_path / "x.yaml")


def test_parametric_fault_acts_as_additive_fault_with_time_varying_coefficient():
    """x' = (A + θ dA) x + (B + θ dB) u equals the nominal plant driven through the
    fault's additive columns by f = θ R [x; u] (exactly, in discrete time)."""
    dA = np.array([[0.0, 0.01, 0.0], [0, 0, 0], [0.02, 0, -0.01]])
    dB = np.array([[0.1, 0.0], [0, 0], [0, 0.05]])
    m = FDIModel.from_matrices(np.diag([0.9, 0.8, 0.7]), np.ones((3, 2)), np.eye(3), dt=0.1,
                               faults=[parametric_fault("p", dA=dA, dB=dB)])
    spec = m.fault("p")
    rng = np.random.default_rng(0)
    u = rng.standard_normal((50, 2))
    theta = np.linspace(0, 1.5, 50)
    x1 = np.zeros(3)
    x2 = np.zeros(3)
    for k in range(50):
        x1 = (m.A + theta[k] * dA) @ x1 + (m.Bu + theta[k] * dB) @ u[k]
        f = spec.parametric_signal(theta[k], x2, u[k])
        x2 = m.A @ x2 + m.Bu @ u[k] + m.Bf @ f
    assert np.allclose(x1, x2, rtol=0, atol=1e-12 * np.abs(x1).max())
    assert m.nf == np.linalg.matrix_rank(np.block([[dA, dB], [np.zeros((3, 3)), np.zeros((3, 2))]]))


def test_discretize_keeps_names_and_resolves_faults():
    m = tanks()
    md = m.discretize(1.0)
    assert md.dt == 1.0 and md.fault_names == m.fault_names
    assert np.allclose(md.Bf[:, md.fault("p1").columns], md.Bu[:, [0]])
    with pytest.raises(ModelError, match="already discrete"):
        md.discretize(1.0)


def test_freqresp_on_a_pole_warns_once_with_the_count():
    """A grid through a pole (here an uncontrollable integrator a non-minimal realisation
    carries) gives one LinAlgWarning for the call, naming how many frequencies were singular,
    not one per frequency; the other frequencies are exact."""
    import warnings

    import scipy.linalg as sla

    from fmu_fdi.lti import LTI

    # the mode at -1e-18 is singular to working precision at omega = 0 (rcond ~1e-18 < eps)
    G = LTI(np.diag([-1e-18, -1.0]), np.array([[0.0], [1.0]]), np.array([[1.0, 1.0]]), np.zeros((1, 1)))
    omega = np.array([0.0, 0.0, 0.0, 1.0])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        H = G.freqresp(omega)
    lin = [c for c in caught if issubclass(c.category, sla.LinAlgWarning)]
    assert len(lin) == 1 and "at 3 of 4 frequencies" in str(lin[0].message)
    assert abs(H[3, 0, 0] - 1 / (1j + 1)) < 1e-15
