"""Model-set tools (issue 13): series, feedback, parallel interconnections and the
robustness of one filter over a list of models.

Interconnections are checked against the transfer-matrix formulas at a random complex
point; tolerance 1e-10 relative (O(10) states, well conditioned, rounding ~1e-14).
"""
import numpy as np

from fmu_fdi import FDIModel, actuator_fault, sensor_fault
from fmu_fdi.lti import LTI
from fmu_fdi.modelset import feedback, parallel, series
from fmu_fdi.robustness import robustness

LAM = 0.3 + 1.7j


def _plant():
    rng = np.random.default_rng(4)
    A = -np.diag([1.0, 2.0, 3.0]) + 0.3 * rng.standard_normal((3, 3))
    return FDIModel.from_matrices(A, rng.standard_normal((3, 2)), rng.standard_normal((2, 3)),
                                  Bd=rng.standard_normal((3, 1)), u_names=["u1", "u2"], y_names=["y0", "y1"],
                                  faults=[actuator_fault("fa", "u1"), sensor_fault("fs", "y1")], name="p")


def test_series_is_product():
    m = _plant()
    P = LTI(-np.diag([5.0, 8.0]), np.diag([5.0, 8.0]), np.eye(2), np.zeros((2, 2)))
    ms = series(m, P)
    assert np.allclose(ms.lti("u").evalfr(LAM), m.lti("u").evalfr(LAM) @ P.evalfr(LAM), rtol=1e-10)
    # faults and d act where they did
    assert np.allclose(ms.lti("d", "f").evalfr(LAM), m.lti("d", "f").evalfr(LAM), rtol=1e-10)


def test_feedback_closed_loop_formulas():
    m = _plant()
    K = LTI(np.array([[-1.0]]), np.array([[1.0, 0.5]]), np.array([[0.7], [-0.2]]), np.array([[0.3, 0.0], [0.1, 0.4]]))
    mc = feedback(m, K)
    G, Kv = m.lti("u").evalfr(LAM), K.evalfr(LAM)
    S = np.linalg.inv(np.eye(2) + G @ Kv)  # output sensitivity
    assert np.allclose(mc.lti("u").evalfr(LAM), S @ G, rtol=1e-10)
    assert np.allclose(mc.lti("d", "f").evalfr(LAM), S @ m.lti("d", "f").evalfr(LAM), rtol=1e-10)
    assert mc.u_names == ["r_u1", "r_u2"] and mc.fault_names == m.fault_names


def test_parallel_stacks_outputs():
    a = _plant()
    b = a._replace(name="q", y_names=["z1", "z2"], d_names=["e"], faults=[sensor_fault("gs", "z1")])
    mp = parallel(a, b)
    assert np.allclose(mp.lti("u").evalfr(LAM), np.vstack([a.lti("u").evalfr(LAM), b.lti("u").evalfr(LAM)]))
    assert mp.fault_names == ["fa", "fs", "gs"]


def test_robustness_over_actuator_variations():
    from fmu_fdi import structured_bank

    m = _plant()
    P = lambda tau: LTI(-np.diag([1 / tau, 1 / tau]), np.diag([1 / tau, 1 / tau]), np.eye(2), np.zeros((2, 2)))  # noqa: E731
    nominal = series(m, P(0.1), name="nominal")
    bank = structured_bank(nominal, [[1, 1]])
    rep = robustness(bank, [nominal, series(m, P(0.12), name="slow")])
    nom, slow = rep["models"]
    assert nom["decoupling"] < 1e-7  # exact on its design model
    assert slow["decoupling"] > 1e-4  # a 20 % slower actuator leaks u into r
    assert rep["worst_decoupling"] == slow["decoupling"]
    assert rep["worst_hinf_minus"] > 0


def test_model_methods_delegate():
    m = _plant()
    P = LTI.static(np.eye(2))
    assert np.allclose(m.series(P).lti("u").evalfr(LAM), m.lti("u").evalfr(LAM))
    assert m.feedback(np.zeros((2, 2))).n == m.n
