"""Exact model matching (design/problems/matching.py) against FaultDetectionTools.jl test/test_emmsyn.jl.

Example 5.4c: emmsyn with the reference Rf of efdsyn(sdeg = -3) returns efdsyn's Q itself,
Q = [0, (s-3)/(s+3), -(s+2)/(s+3)] (Varga 2017, Example 5.4); compared to 1e-6 (printed
digits). Niemann (1998): emmsyn with the references of the efdisyn bank gives order-1 rows.
"""
import numpy as np
import pytest

import published as pub
from fmu_fdi import DesignError, leakage, nullspace_design, structured_bank
from fmu_fdi.design.problems.matching import model_matching
from fmu_fdi.lti import LTI


def test_example_5_4c_reproduces_efdsyn_filter():
    model = pub.ex5_4()
    ref = nullspace_design(model, rdim=1, poles=[-3])
    Mr = ref.Rf
    gen = model_matching(model, Mr)
    assert gen.info["matching_error"] < 1e-9 and gen.Q.n == 1
    for w in (0.0, 1.3, 7.0):
        assert np.allclose(gen.Q.freqresp([w])[0], ref.Q.freqresp([w])[0], atol=1e-6)
    assert leakage(gen) < 1e-9


def test_niemann_bank_references_give_order_one_rows():
    from test_synthesis_published import niemann

    model = niemann()
    bank = structured_bank(model, [[1, 1], [0, 1], [1, 0]])
    for g in bank.members:
        mm = model_matching(model, g.Rf)
        assert mm.Q.n == 1 and mm.info["matching_error"] < 1e-7


def test_unachievable_reference_is_refused():
    model = pub.ex5_3()
    # a fault response with a zero where every exact Rf_fa has (s+2)/(s+3): not matchable with added poles
    Mr = LTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), np.array([[1.0, 0.0]]))
    with pytest.raises(DesignError, match="not achievable without an updating factor"):
        model_matching(model, Mr, max_degree=2)
