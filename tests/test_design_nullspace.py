"""Properties any correct null-space / parity-space / bank design must have.

Residuals are checked on an exact simulation of plant + filter (tests/simulate.py):
without faults and noise they are rounding noise. Bound: 1e-9 relative to the output
signal size — the cascade has O(10) states of O(1) norm, so rounding after N = 300
steps is ~N * eps * cond ≈ 1e-12; 1e-9 leaves three digits for conditioning.
"""
import numpy as np
import pytest

import published as pub
from published import three_tank_like
from fmu_fdi import (DesignError, FDIModel, component_fault, dedicated_bank, generalized_bank,
                     leakage, nullspace_design, sensor_fault, structure_matrix, structured_bank)
from fmu_fdi.design.problems.parity import parity_space
from simulate import cascade_residual, plant_outputs

RESIDUAL_REL = 1e-9
N = 300


CASES = {
    "ex5_3": (pub.ex5_3, 0.05),
    "ex5_4_unstable": (pub.ex5_4, 0.01),  # 3 s horizon: plant growth e^(3t) stays ~1e4
    "tanks_continuous": (lambda: three_tank_like(), 1.0),
    "tanks_discrete": (lambda: three_tank_like(1.0), None),
}


def _signals(model, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((N, model.nu))
    d = rng.standard_normal((N, model.nd))
    return u, d


def _check_fault_free_and_faults(gen, Ts, structure_required=None):
    model = gen.model
    u, d = _signals(model)
    r = cascade_residual(gen, N, Ts, u=u, d=d)
    y = plant_outputs(model, N, Ts, u=u, d=d)
    # relative to the output size: for an unstable plant the outputs (and the rounding
    # of the cancellation inside the cascade) grow together
    scale = np.abs(y).max()
    assert np.abs(r).max() <= RESIDUAL_REL * scale
    weak = structure_matrix(gen)
    for j, spec in enumerate(model.faults):
        f = np.zeros((N, model.nf))
        f[N // 3:, spec.columns] = 1.0  # a step fault of unit size in each of its columns
        rf = cascade_residual(gen, N, Ts, u=u, d=d, f=f)
        moved = np.abs(rf).max() > 1e3 * RESIDUAL_REL * scale
        assert moved == bool(weak[:, j].any()), f"fault {spec.name}: structure {weak[:, j]} vs simulation"
    if structure_required is not None:
        assert weak.tolist() == structure_required


@pytest.mark.parametrize("case", sorted(CASES))
def test_nullspace_design_decouples_and_detects(case):
    build, Ts = CASES[case]
    model = build()
    gen = nullspace_design(model, poles=None if model.dt else [-1.0])
    assert leakage(gen) < 1e-9
    assert gen.Q.is_stable()
    _check_fault_free_and_faults(gen, Ts, structure_required=[[1] * len(model.faults)])


@pytest.mark.parametrize("case", sorted(CASES))
def test_parity_space_decouples_and_detects(case):
    build, Ts = CASES[case]
    model = build()
    gen = parity_space(model, 2, Ts=Ts if not model.dt else None)
    assert gen.info["mode"] == "exact"
    assert np.all(gen.Q.poles() == 0)  # finite memory: a pure delay line
    assert leakage(gen) < 1e-9
    _check_fault_free_and_faults(gen, Ts if not model.dt else None)


def test_parity_robust_when_exact_is_impossible():
    """Order 0 cannot remove the state of a plant with d everywhere: LWV vector instead."""
    model = three_tank_like(1.0)
    gen = parity_space(model, 1, robust=True)
    assert gen.info["mode"] == "robust"
    assert gen.info["robustness_ratio"] >= 0
    with pytest.raises(DesignError, match="no parity vector of order 0 removes the state"):
        parity_space(model, 0, robust=True)


def _degree_two_model():
    """Gd = Gu: the residual must annihilate Gu itself, a degree-2 row (Varga's A5b row 1)."""
    G = pub.tfm([[pub.GU[0], pub.GU[0]], [pub.GU[1], pub.GU[1]]], ["u", "d"])
    return FDIModel.from_control(G, u=["u"], d=["d"], faults=[sensor_fault("s1", "y1"), sensor_fault("s2", "y2")])


@pytest.mark.parametrize("poles", [[-2.0, -5.0], [-1 + 1j, -1 - 1j]])
def test_requested_poles_are_assigned(poles):
    gen = nullspace_design(_degree_two_model(), poles=poles)
    assert gen.Q.n == 2
    assert np.allclose(np.sort_complex(gen.Q.poles()), np.sort_complex(np.array(poles, complex)), atol=1e-9)
    assert leakage(gen) < 1e-9


def test_missing_poles_take_sdeg_and_unusable_poles_warn():
    gen = nullspace_design(_degree_two_model(), poles=[-2.0], sdeg=-7.0)
    assert np.allclose(np.sort(gen.Q.poles().real), [-7.0, -2.0], atol=1e-9)
    gen = nullspace_design(three_tank_like(), poles=[-1 + 1j, -1 - 1j], sdeg=-3.0)  # degree 1: no room
    assert any("not used" in text for text in gen.info["notes"])  # a note, not a warning (issue 17)


def test_rdim_all_gives_whole_basis():
    model = three_tank_like()
    gen = nullspace_design(model, rdim="all", poles=[-1.0])
    assert gen.n_residuals == model.ny - 1  # p - rank Gd
    assert leakage(gen) < 1e-9


def test_sensor_banks_isolate():
    model = three_tank_like(leak=False)  # with the leak as d, two decoupled sensors leave no residual
    dos = dedicated_bank(model, "sensor", poles=[-1.0])
    S = structure_matrix(dos)[:, :3]
    assert S.tolist() == np.eye(3, dtype=int).tolist()
    gos = generalized_bank(model, "sensor", poles=[-1.0])
    assert structure_matrix(gos)[:, :3].tolist() == (1 - np.eye(3, dtype=int)).tolist()
    assert leakage(dos) < 1e-9 and leakage(gos) < 1e-9
    with pytest.raises(DesignError, match="row 1 .*normal rank of Gd = 3 = number of outputs 3"):
        dedicated_bank(three_tank_like(leak=True), "sensor")


def test_structured_bank_names_impossible_rows():
    model = pub.ex5_3()  # 2 outputs, 1 input, 1 disturbance: only one residual direction
    with pytest.raises(DesignError) as err:
        structured_bank(model, [[1, 0], [0, 1]])
    msg = str(err.value)
    # decoupling one sensor fault on top of d leaves no output direction for either row
    assert "row 1 [1, 0]" in msg and "row 2 [0, 1]" in msg
    assert "normal rank of Gd = 2 = number of outputs 2" in msg


def test_invalid_inputs_raise_clear_errors():
    model = three_tank_like()
    with pytest.raises(DesignError, match="not stable"):
        nullspace_design(model, poles=[1.0])
    with pytest.raises(DesignError, match="rdim"):
        nullspace_design(model, rdim=0)
    with pytest.raises(DesignError, match="only 2 basis vectors"):
        nullspace_design(model, rdim=5)
    with pytest.raises(DesignError, match="pass Ts"):
        parity_space(model, 2)
    with pytest.raises(DesignError, match="non-negative integer"):
        parity_space(model, -1, Ts=1.0)
    with pytest.raises(DesignError, match="structure matrix must have 5 columns"):
        structured_bank(model, [[1, 0]])
    with pytest.raises(DesignError, match="no residual generator exists"):
        # three independent disturbances on three outputs leave nothing to detect with
        FDIModel.from_matrices(model.A, model.Bu, model.C, Bd=np.eye(3), Dd=np.eye(3)) and \
            nullspace_design(FDIModel.from_matrices(model.A, model.Bu, model.C, Bd=np.eye(3), Dd=np.eye(3),
                                                    faults=[component_fault("c", [[1], [0], [0]])]))
