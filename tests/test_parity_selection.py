"""Which parity relations a parity design keeps when fewer than all are asked for (issue 13's
recorded regression: the choice moved with the operator scaling ρ of the parity data).

With noise inputs w the exact design keeps the relations of largest steady-state
fault-to-noise ratio ``|r_ss| / std(r)`` (a generalised eigenvalue problem on the parity
space): properties any such choice must have, on a plant with two redundant sensors.
"""
import numpy as np
import pytest
import scipy.linalg as sla

from fmu_fdi import FDIModel, sensor_fault
from fmu_fdi.design import parity_space

SIGMA = 0.2  # sensor noise std
S = 4  # parity order: a window of 5 samples


def _plant(scale=1.0):
    """x+ = 0.9 x + 0.1 u (state in units of 1/scale), y1 = y2 = x + noise; fault on y1."""
    return FDIModel.from_matrices([[0.9]], [[0.1 * scale]], [[1.0 / scale], [1.0 / scale]], dt=0.01,
                                  Bw=np.zeros((1, 2)), Dw=SIGMA * np.eye(2), y_names=["y1", "y2"],
                                  faults=[sensor_fault("f", "y1")])


def _noise_cov(gen) -> np.ndarray:
    """Per-sample covariance of r for unit white w (FIR: the sum of its taps' outer products)."""
    Rw = gen.internal_form()["w"]
    P = sla.solve_discrete_lyapunov(Rw.A, Rw.B @ Rw.B.T) if Rw.n else np.zeros((0, 0))
    return Rw.C @ P @ Rw.C.T + Rw.D @ Rw.D.T


def _ratio(gen, h=None) -> float:
    """Steady-state fault-to-noise ratio of the residual combination h (default: the first)."""
    h = np.eye(gen.n_residuals)[0] if h is None else h
    return float(abs(h @ gen.Rf.evalfr(1.0 + 0j)[:, 0]) / np.sqrt(h @ _noise_cov(gen) @ h))


def test_kept_relation_is_at_least_the_averaged_sensor_difference():
    gen = parity_space(_plant(), S, rdim=1)
    assert gen.info["selection"] == "steady-state fault-to-noise ratio"
    # sum_k (y1 - y2)(k) over the window: gain S+1, noise std SIGMA sqrt(2 (S+1))
    averaged = (S + 1) / (SIGMA * np.sqrt(2 * (S + 1)))
    assert _ratio(gen) >= averaged * (1 - 1e-9)
    assert abs(_ratio(gen) - gen.info["fault_to_noise"][0]) <= 1e-9 * averaged


def test_no_combination_of_all_relations_does_better():
    best = _ratio(parity_space(_plant(), S, rdim=1))
    every = parity_space(_plant(), S)  # all relations of order S
    rng = np.random.default_rng(3)
    for h in rng.standard_normal((200, every.n_residuals)):
        assert _ratio(every, h) <= best * (1 + 1e-9)


def test_choice_independent_of_state_units_and_noise_white():
    a, b = parity_space(_plant(), S, rdim=2), parity_space(_plant(1e3), S, rdim=2)
    # the parity space is the same; its computed basis is not (balancing, SVD): same figures
    # (one fault: one direction of nonzero ratio; the second's ratio is rounding, ~1e-7)
    ra, rb = a.info["fault_to_noise"], b.info["fault_to_noise"]
    assert abs(ra[0] - rb[0]) <= 1e-9 * ra[0] and max(ra[1], rb[1]) <= 1e-6 * ra[0]
    # generalised eigenvectors: unit noise variance per sample, uncorrelated residuals
    assert np.allclose(_noise_cov(a), np.eye(2), atol=1e-9)


def test_atol_is_the_absolute_rank_tolerance():
    """atol (Varga's absolute rank tolerance) reaches the parity-vector rank decisions: a tiny one
    changes nothing; one above every singular value of the column-normalised [O_s H_d,s] (≤ its
    column count) declares the whole space "parity" and the design is refused (exact: its u
    leakage fails the post-condition; robust: no fault reaches a zero-dimensional parity space)."""
    from fmu_fdi import DesignError

    a, b = parity_space(_plant(), S, rdim=1), parity_space(_plant(), S, rdim=1, atol=1e-12)
    assert np.allclose(a.Q.D, b.Q.D) and np.allclose(a.Q.C, b.Q.C)
    with pytest.raises(DesignError, match="decoupling"):
        parity_space(_plant(), S, robust=False, atol=1e6)
    with pytest.raises(DesignError, match="no fault reaches"):
        parity_space(_plant(), S, robust=True, atol=1e6)
    with pytest.raises(DesignError, match="atol"):
        parity_space(_plant(), S, atol=-1.0)
