"""Ding's unified H−/H∞ solution (design/problems/unified.py) on the shipped lateral aircraft (Varga 2017,
Ex. 6.2 noise: process noise on every state, measurement noise on every output).

Properties from Ding (2013), Theorem 7.14: the noise response is co-inner (||Rw||∞ = 1), and
any other u-decoupling filter scaled to ||Rw||∞ = 1 has every fault gain at most the unified
one's, frequency by frequency. Tolerance 1e-6 relative: Riccati-based factors carry ~1e-10.
"""
import numpy as np

from fmu_fdi import factorized, kalman, nullspace_design
from fmu_fdi.design.problems.unified import unified_observer
from fmu_fdi.lti import frequency_grid
from plant_fmus.lateral_aircraft import linear_model


def _fault_gains(gen, w):
    Rw = gen.Rw
    scale = Rw.hinfnorm()[0]
    H = gen.Rf.freqresp(w) / scale
    m = gen.model
    return np.stack([np.linalg.norm(H[:, :, m.fault(nm).columns], 2, axis=(1, 2)) for nm in m.fault_names], axis=1)


def test_unified_is_coinner_and_dominates_other_designs():
    model = linear_model()
    opt = unified_observer(model)
    assert abs(opt.info["noise_hinf"] - 1.0) < 1e-6
    w = frequency_grid([model.lti()], num=60)
    best = _fault_gains(opt, w)
    for other in (factorized(model), kalman(model, Qw=np.eye(model.nw), Rv=np.eye(model.ny)), nullspace_design(model)):
        assert np.all(_fault_gains(other, w) <= best * (1 + 1e-6))


def test_atol_accepted_and_validated():
    import pytest

    from fmu_fdi import DesignError

    model = linear_model()
    assert abs(unified_observer(model, atol=1e-12).info["noise_hinf"] - 1.0) < 1e-6
    with pytest.raises(DesignError, match="atol"):
        unified_observer(model, atol=-1.0)
