"""Default thresholds (issue 18): from the model's noise model when it has one, judged by the closed form of the
Gaussian tail; fault-size:1 without one
or for an evaluation without a closed-form tail."""
from __future__ import annotations

import numpy as np
from scipy import stats

from fmu_fdi import LTI, FDIModel, ResidualGenerator
from fmu_fdi.evaluation import default_thresholds
from fmu_fdi.evaluation.defaults import DEFAULT_RATE
from fmu_fdi.faults import sensor_fault


def _open_loop_observer(noise: bool, a=0.9):
    """x+ = a x + u (+ w), y = x (+ sensor fault); r = y − ŷ with ŷ the noise-free model: with noise r is AR(1),
    r+ = a r + w, of stationary variance 1/(1 − a²); its settled response to a unit sensor bias is 1."""
    m = FDIModel.from_matrices([[a]], [[1.0]], [[1.0]], Bw=[[1.0]] if noise else None, dt=1.0,
                               faults=[sensor_fault("s", "y")], y_names=["y"], u_names=["u"])
    Q = LTI([[a]], [[0.0, 1.0]], [[-1.0]], [[1.0, 0.0]], 1.0)
    return ResidualGenerator(Q, m, "open-loop observer")


def test_with_a_noise_model_the_default_is_its_false_alarm_quantile():
    th, why = default_thresholds(_open_loop_observer(True), {"kind": "norm"})
    sigma = 1 / np.sqrt(1 - 0.9 ** 2)
    # |r| ≥ J with r ~ N(0, σ²): P = 2 Φ(−J/σ) = DEFAULT_RATE
    assert np.isclose(th[0], sigma * stats.norm.isf(DEFAULT_RATE / 2), rtol=1e-6), th
    assert "noise" in why[0]


def test_without_a_noise_model_or_a_quantile_the_default_is_fault_size_one():
    th, why = default_thresholds(_open_loop_observer(False), {"kind": "rms", "window": 5})
    assert np.isclose(th[0], 0.5) and why[0].startswith("fault-size:1")  # half the settled unit-bias response
    # Narendra's J = α|r| + β·(γ-filtered |r|) has no closed-form tail: fault size, its settled gain α + β/(1 − γ) = 2
    th, why = default_thresholds(_open_loop_observer(True), {"kind": "narendra", "alpha": 0.0, "beta": 1.0,
                                                             "gamma": 0.5})
    assert np.isclose(th[0], 0.5 * 2.0) and "narendra" in why[0]
