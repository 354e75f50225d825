"""Decision logic end to end: structure-matrix isolation, directional isolation, χ² tests."""
import numpy as np
import pytest

import published as pub
from fmu_fdi import Diagnoser, FDIModel, dedicated_bank, fault_detection_filter, generalized_bank, kalman
from simulate import plant_outputs

N = 300


def _step_fault(model, name, size, k0):
    f = np.zeros((N, model.nf))
    f[k0:, model.fault(name).columns] = size
    return f


@pytest.mark.parametrize("bank", [dedicated_bank, generalized_bank])
def test_sensor_bank_isolates_each_sensor_fault(bank):
    model = pub.three_tank_like(1.0, leak=False)
    gen = bank(model, "sensor")
    dg = Diagnoser(gen, evaluation={"kind": "rms", "window": 5}, thresholds=0.05,
                   decision={"persistence": [3, 5]})
    assert dg.design["decision"]["isolation"] == "structure"
    rng = np.random.default_rng(0)
    u = np.repeat(rng.uniform(0, 50, (N // 30, 2)), 30, axis=0)
    t = np.arange(N) * 1.0
    for j, name in enumerate(["s1", "s2", "s3"]):
        y = plant_outputs(model, N, u=u, f=_step_fault(model, name, 1.0, 100))
        out = dg.run(t, u, y)
        assert not out["fault_detected"][:100].any()
        k = np.argmax(out["fault_detected"])
        assert out["fault_detected"][k:].all()
        j = model.fault_names.index(name) + 1
        isolated = out["isolated_fault"][k:]
        # while the residuals settle the pattern may match no column (-1), never another fault;
        # once settled (the second half of the faulty part) it is the injected one
        assert set(np.unique(isolated)) <= {-1, j}, f"{name}: mis-isolated as {np.unique(isolated)}"
        assert np.all(out["isolated_fault"][(N + 100) // 2:] == j)


def test_fault_detection_filter_isolates_by_direction_with_margin():
    base = pub.three_tank_like(leak=False)
    model = FDIModel.from_matrices(base.A, base.Bu, base.C, u_names=base.u_names, y_names=base.y_names,
                                   faults=[f for f in base.faults if f.kind == "actuator"])
    model = model.discretize(1.0)  # designed on the sampled plant: exact at the samples
    gen = fault_detection_filter(model, poles=[0.9, 0.8, 0.7])
    dg = Diagnoser(gen, evaluation={"kind": "norm"}, thresholds=0.01)
    assert dg.design["decision"]["isolation"] == "direction"
    u = np.full((N, 2), 20.0)
    for j, name in enumerate(model.fault_names):
        y = plant_outputs(model, N, u=u, f=_step_fault(model, name, 5.0, 50))
        dg.reset()
        rows = [dg.step(u[k], y[k]) for k in range(N)]
        late = rows[80:]
        assert all(r["isolated_fault"] == j + 1 for r in late)
        # the residual moves in the fault's fixed direction, so the margin is the angle
        # between the two fault directions (1e-6 rad covers the filter's eigenvector conditioning)
        d = [np.asarray(gen.info["fault_directions"][nm]) for nm in model.fault_names]
        between = np.arccos(abs(d[0] @ d[1]) / np.linalg.norm(d[0]) / np.linalg.norm(d[1]))
        assert all(abs(r["isolation_margin"] - between) < 1e-6 for r in late)


def test_chi2_on_kalman_innovations_uses_the_whitening():
    base = pub.three_tank_like(1.0, leak=False)
    model = FDIModel.from_matrices(base.A, base.Bu, base.C, Bw=0.05 * np.eye(3), dt=1.0, u_names=base.u_names,
                                   y_names=base.y_names, faults=base.faults)
    gen = kalman(model, Qw=np.eye(3), Rv=0.01 * np.eye(3))
    dg = Diagnoser(gen, evaluation={"kind": "chi2", "window": 20}, thresholds=1e9)
    W = np.asarray(dg.design["evaluation"][0]["evaluator"]["W"])
    Sigma = np.asarray(gen.info["innovation_covariance"])
    assert np.allclose(W @ Sigma @ W.T, np.eye(3), atol=1e-10)
